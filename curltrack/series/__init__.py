"""The measured shot as data: the layer between tracking and the analyses.

``fit`` and ``discover`` depend on this package and on :mod:`curltrack.physics` only.

* :mod:`.io`      -- SHOT.csv / SHOT.parquet + sidecar SHOT.json: :class:`Series`
  (immutable), :func:`read_series`, :func:`write_series`, validation;
* :mod:`.noise`   -- the measurement noise of a coordinate, from the data
  (:func:`estimate_noise`: the one estimator ``fit`` and ``discover`` weight by);
* :mod:`.stops`   -- stop times of translation and rotation below one frame
  (:func:`detect_stops`);
* :mod:`.segment` -- a long series (a session video) cut into shots
  (:func:`segment_motion`).
"""

from .io import (COLUMNS, OPTIONAL_COLUMNS, SIDECAR_KEYS, Series, make_meta, read_series,
                 sample_index, sidecar_path, validate, write_series)
from .noise import Noise, estimate_noise, robust_sigma, white_sigma
from .segment import ShotSegment, segment_motion
from .stops import StopTimes, detect_stops, series_stops

__all__ = ["COLUMNS", "OPTIONAL_COLUMNS", "SIDECAR_KEYS", "Series", "make_meta",
           "read_series", "sample_index", "sidecar_path", "validate", "write_series", "Noise",
           "estimate_noise", "robust_sigma", "white_sigma", "ShotSegment",
           "segment_motion", "StopTimes", "detect_stops", "series_stops"]
