"""Rolling shutter: the instant at which the rock was seen in a frame.

A rolling-shutter sensor (phones, action cameras) exposes its rows one after another:
row ``v`` (0 = top, of ``n`` rows) around ``t + readout_s * ((v + 0.5) / n - 0.5)``,
``t`` being the frame's time (its centre row's, as the container stamps it).  A rock
that moves by 2 m/s while a 30 ms readout sweeps over it is seen up to 30 mm away from
where it is at ``t``; timing each measurement at the rock's row puts it back on its path.

The rows are the *sensor's*: a video with a rotation tag is decoded turned by OpenCV
(not by PyAV), so the sensor's rows are then the decoded image's columns.  Display
rotation tags are counter-clockwise (FFmpeg's display matrix): with 90 deg the decoded
pixel ``(x, y)`` is the sensor's ``(W - 1 - y, x)``, i.e. the sensor row is ``x``.
"""

from __future__ import annotations

import numpy as np


def sensor_row_fraction(pts_px, shape, rotation_deg: int = 0,
                        decoded_rotated: bool = True) -> np.ndarray:
    """Position of decoded pixels along the sensor's readout, in [0, 1] (0 = first row).

    Parameters
    ----------
    pts_px : (N, 2) array
        Pixel positions (x right, y down) in the decoded image.
    shape : tuple
        The decoded image's shape (rows, columns, ...).
    rotation_deg : int
        The container's display rotation tag (deg, counter-clockwise; 0, 90, 180, 270).
    decoded_rotated : bool
        Whether the decoder applied the tag (OpenCV does, PyAV does not).

    Returns
    -------
    (N,) ndarray
        ``(v + 0.5) / n`` of each point's sensor row ``v`` of ``n``.
    """
    p = np.atleast_2d(np.asarray(pts_px, float))
    rows, cols = shape[:2]
    rot = int(rotation_deg) % 360 if decoded_rotated else 0
    if rot == 0:
        return (p[:, 1] + 0.5) / rows
    if rot == 90:
        return (p[:, 0] + 0.5) / cols
    if rot == 180:
        return 1.0 - (p[:, 1] + 0.5) / rows
    if rot == 270:
        return 1.0 - (p[:, 0] + 0.5) / cols
    raise ValueError(f"rotation tag {rotation_deg} deg: expected 0, 90, 180 or 270")


def row_time_offset(pts_px, shape, readout_s: float, rotation_deg: int = 0,
                    decoded_rotated: bool = True) -> float:
    """Time (s) at which points were exposed, relative to the frame's time: the readout
    time at their mean sensor row (:func:`sensor_row_fraction`) minus the centre row's."""
    frac = sensor_row_fraction(pts_px, shape, rotation_deg, decoded_rotated)
    return float(readout_s * (np.mean(frac) - 0.5))
