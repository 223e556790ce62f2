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

The readout need not be given: :func:`estimate_readout` measures it from the grid.  While
the camera moves, the rows read later see the ice moved further, so the lattice's image
is sheared (motion across the rows) or stretched (along them) in proportion to the
image's velocity times the readout - a departure of each frame's homography from a
similarity at the image centre that follows the camera's motion from frame to frame.
"""

from __future__ import annotations

from dataclasses import dataclass

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


#: A readout measured from the grid is used when it is at least this many of its own
#: sigmas from zero and over :data:`MIN_READOUT_S` (a global shutter measured 0.03 +-
#: 0.06 and 0.05 +- 0.17 ms on a ladder and a hand-held clip).
READOUT_Z = 6.0
#: ... and at least this long (s): shorter readouts move a rock under ~0.5 mm.
MIN_READOUT_S = 0.5e-3
#: The estimate's own error beyond its statistical sigma, as a fraction of it: over 13
#: rendered rolling-shutter clips (phones, action cameras; 6.5-26 ms) it was -6 % ... +17 %
#: off (phones high: their rotated, swaying frames), over 14 global-shutter clips
#: 0 within 1.6 sigma.
READOUT_MODEL_FRACTION = 0.1
#: Fewest frame triples (a frame with the grid measured and both neighbours) behind an
#: estimate.
MIN_READOUT_FRAMES = 30


@dataclass(frozen=True)
class ReadoutEstimate:
    """A rolling shutter's readout measured from the grid (:func:`estimate_readout`).

    Attributes
    ----------
    readout_s, sigma_s : float
        The readout time (s) and its 1 sigma (s: statistical, and
        :data:`READOUT_MODEL_FRACTION` of it); NaN with too few frames.
    n_frames : int
        Frames behind it.
    """

    readout_s: float
    sigma_s: float
    n_frames: int

    @property
    def found(self) -> bool:
        """Whether a rolling shutter is shown: :data:`READOUT_Z` sigmas, over
        :data:`MIN_READOUT_S`."""
        return bool(np.isfinite(self.readout_s) and self.readout_s > MIN_READOUT_S
                    and self.readout_s > READOUT_Z * self.sigma_s)


def _anticonformal(A: np.ndarray) -> np.ndarray:
    """The two components of a 2x2 matrix that a similarity has not (N, 2)."""
    return np.stack([(A[..., 0, 0] - A[..., 1, 1]) / 2, (A[..., 0, 1] + A[..., 1, 0]) / 2], -1)


def _through(Hs: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Points ``pts`` (n, k, 2) through their own homography of ``Hs`` (n, 3, 3)."""
    w = np.einsum("nij,nkj->nki", Hs, np.concatenate([pts, np.ones(pts.shape[:2] + (1,))], -1))
    return w[..., :2] / w[..., 2:]


def estimate_readout(times, homographies, centre_px, shape, rotation_deg: int = 0,
                     decoded_rotated: bool = True) -> ReadoutEstimate:
    """The readout time of a rolling shutter, from the lattice's shear under the
    camera's motion.

    With the image moving at ``v`` (px/s) while rows are read over ``R`` seconds, a
    point is displaced by ``v R (f - 1/2)`` (``f``: its sensor row fraction), so each
    frame's image->ice map is the true one times ``I - R v (grad f)^T``: its part that a
    similarity cannot have (at the image centre) is ``-R`` times that of ``v (grad
    f)^T``.  ``R`` is their least-squares slope over the frames, with a constant for the
    lens' and the camera's own fixed departure.

    Parameters
    ----------
    times : (N,) array
        Frame times (s) of frames whose grid was measured, increasing.
    homographies : (N, 3, 3) array
        Their undistorted px -> ice homographies.
    centre_px : (2,) array
        Where to read them: the principal point (undistorted px).
    shape : tuple
        The decoded image's shape (rows, columns).
    rotation_deg, decoded_rotated :
        As :func:`sensor_row_fraction`.

    Returns
    -------
    ReadoutEstimate
    """
    t = np.asarray(times, float)
    Hs = np.asarray(homographies, float)
    c = np.asarray(centre_px, float)
    n = len(t)
    if n < MIN_READOUT_FRAMES + 2:
        return ReadoutEstimate(np.nan, np.nan, 0)
    pts = np.array([c, c + (1.0, 0.0), c + (0.0, 1.0)])
    f = sensor_row_fraction(pts, shape, rotation_deg, decoded_rotated)
    grad = np.array([f[1] - f[0], f[2] - f[0]])
    ice = _through(Hs, np.broadcast_to(pts, (n, 3, 2)))              # (n, 3, 2)
    J = np.stack([ice[:, 1] - ice[:, 0], ice[:, 2] - ice[:, 0]], -1)  # (n, 2, 2)
    # (a lattice whose frame is mirrored against the image's)
    J = np.where((np.linalg.det(J) < 0)[:, None, None], J * np.array([[1.0], [-1.0]]), J)
    p, q, r, s = J[:, 0, 0], J[:, 0, 1], J[:, 1, 0], J[:, 1, 1]
    conf = np.stack([np.stack([p + s, q - r], -1), np.stack([r - q, p + s], -1)], -2) / 2
    M = np.linalg.solve(conf, J)
    # the image's velocity at the centre: where the ice under it is a frame before and after
    Hinv = np.linalg.inv(Hs)
    centre_ice = ice[1:-1, :1]
    at, after = _through(Hinv[:-2], centre_ice)[:, 0], _through(Hinv[2:], centre_ice)[:, 0]
    dt = t[2:] - t[:-2]
    vel = (after - at) / dt[:, None]
    near = dt <= 2.5 * np.median(dt)  # (neighbours across a loss: no velocity)
    y = -_anticonformal(M[1:-1] - np.eye(2))[near]                     # (m, 2)
    x = _anticonformal(vel[:, :, None] * grad[None, None, :])[near]    # (m, 2)
    if len(y) < MIN_READOUT_FRAMES:
        return ReadoutEstimate(np.nan, np.nan, len(y))
    m = len(y)
    X = np.zeros((2 * m, 3))
    X[:, 0] = np.r_[x[:, 0], x[:, 1]]
    X[:m, 1], X[m:, 2] = 1.0, 1.0
    Y = np.r_[y[:, 0], y[:, 1]]
    coef, *_ = np.linalg.lstsq(X, Y, rcond=None)
    res = Y - X @ coef
    # (the frames' misfits persist from frame to frame: the residuals' lag-1
    # correlation widens the sigma as for AR(1) errors)
    rho = float(np.clip(np.corrcoef(res[:m][1:], res[:m][:-1])[0, 1], 0.0, 0.95)) \
        if m > 3 else 0.0
    s2 = float(res @ res) / max(len(Y) - 3, 1) * (1 + rho) / (1 - rho)
    cov = s2 * np.linalg.pinv(X.T @ X)
    return ReadoutEstimate(float(coef[0]), float(np.hypot(np.sqrt(cov[0, 0]),
                                                          READOUT_MODEL_FRACTION * coef[0])), m)
