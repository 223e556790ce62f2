import numpy as np
import pytest


@pytest.fixture(autouse=True)
def _numpy_errors_raise():
    """As in trackpy's tests: silent NaN-producing numpy operations are bugs."""
    with np.errstate(invalid="raise", divide="raise", over="raise"):
        yield
