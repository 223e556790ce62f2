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


def row_time_offsets(pts_px, shape, readout_s: float, rotation_deg: int = 0,
                     decoded_rotated: bool = True) -> np.ndarray:
    """Time (s) at which each point was exposed, relative to the frame's time: the
    readout time at its sensor row (:func:`sensor_row_fraction`) minus the centre row's."""
    frac = sensor_row_fraction(pts_px, shape, rotation_deg, decoded_rotated)
    return readout_s * (frac - 0.5)


def to_one_instant(points, dt, velocity, omega: float, centre) -> np.ndarray:
    """Points on the rock, each seen at its own time offset, moved to offset 0.

    The markers of one frame lie on different sensor rows: a rock that translates or
    spins during the readout is seen sheared - two markers 70 rows apart, read 1.2 ms
    apart while the rock crosses the image at 1.4 m/s, turn the pair by ~0.6 deg.

    Parameters
    ----------
    points : (M, 2) array
        Marker positions on the ice (m), marker ``i`` as seen at offset ``dt[i]`` (s).
    dt : (M,) array
        Exposure time of each point relative to the wanted instant (s).
    velocity : (2,) array
        The rock's velocity on the ice (m/s).
    omega : float
        Its rate of turn (rad/s, counter-clockwise as the points' frame).
    centre : (2,) array
        Its axis at the wanted instant (m).

    Returns
    -------
    (M, 2) ndarray
    """
    p = np.asarray(points, float)
    dt = np.asarray(dt, float)
    rel = p - np.asarray(centre, float) - np.outer(dt, velocity)
    a = -omega * dt  # undo the turn made in dt
    ca, sa = np.cos(a), np.sin(a)
    back = np.column_stack([ca * rel[:, 0] - sa * rel[:, 1], sa * rel[:, 0] + ca * rel[:, 1]])
    return back + np.asarray(centre, float)
