"""Fixtures for the calibration tests: synthetic lattice frames with a known camera."""

import numpy as np
import pytest

from curltrack.rig import Rig


@pytest.fixture
def rig():
    return Rig()


@pytest.fixture
def view_points():
    """Image points spread over the whole 960 x 540 view (px)."""
    rng = np.random.default_rng(7)
    return np.column_stack([rng.uniform(0, 959, 400), rng.uniform(0, 539, 400)])
