"""Radial lens distortion in OpenCV's convention, vectorised.

Pixel coordinates: origin at the centre of the top-left pixel, x to the right, y down.
A camera matrix ``K = [[f, 0, cx], [0, f, cy], [0, 0, 1]]`` (px) and coefficients
``dist = (k1, k2, p1, p2, k3)`` (only k1, k2 used here; p1 = p2 = k3 = 0) map an
undistorted normalised point ``q = (x_u - c) / f`` to the distorted pixel
``c + f q (1 + k1 r^2 + k2 r^4)``, ``r = |q|``, exactly as ``cv2.projectPoints`` does, so
``cv2.undistortPoints(p, K, dist, P=K)`` inverts :func:`distort` too.

When the focal length is not known, ``f`` is a reference scale (``max(width, height)``):
the pixel-to-pixel mapping depends only on ``k1 / f^2`` and ``k2 / f^4``, so a true
``k1_true`` with focal length ``f_true`` equals ``k1_true * (f / f_true)^2`` here.
"""

from __future__ import annotations

import numpy as np


def camera_matrix(width: int, height: int, f: float | None = None) -> np.ndarray:
    """K with the principal point at the image centre and ``f`` (px; default max(w, h))."""
    f = float(max(width, height) if f is None else f)
    return np.array([[f, 0.0, (width - 1) / 2.0], [0.0, f, (height - 1) / 2.0],
                     [0.0, 0.0, 1.0]])


def distort(pts_px, K, dist) -> np.ndarray:
    """Undistorted pixel coordinates (N, 2) -> distorted (observed) pixel coordinates."""
    return project((np.asarray(pts_px, float) - K[:2, 2]) / K[0, 0], K, dist)


def project(q, K, dist) -> np.ndarray:
    """Undistorted normalised coordinates ``(x_u - c) / f`` (N, 2) -> observed pixels."""
    k1, k2 = (tuple(dist) + (0.0, 0.0))[:2]
    r2 = np.einsum("...i,...i->...", q, q)
    return K[:2, 2] + q * (K[0, 0] * (1.0 + r2 * (k1 + k2 * r2)))[..., None]


def undistort(pts_px, K, dist, iterations: int = 6) -> np.ndarray:
    """Distorted (observed) pixel coordinates (N, 2) -> undistorted pixel coordinates.

    Newton's method on the radius ``r_d = r (1 + k1 r^2 + k2 r^4)`` from the second-order
    series inverse; stops once the largest step is below
    1e-12 (normalised units, ~1e-9 px) or after ``iterations`` steps.  Converges to
    < 1e-6 px for ordinary lenses in two or three steps (quadratic convergence).  Points
    where it has not converged (strong wide-angle lenses, where ``r_d(r)`` flattens
    towards the image corners) are inverted from a table of ``r_d(r)`` up to the lens's
    fold (:func:`fold_radius`) and polished by Newton steps; radii beyond the fold (the
    model is not invertible there) map to the fold.
    """
    p = np.asarray(pts_px, float)
    k1, k2 = (tuple(dist) + (0.0, 0.0))[:2]
    if k1 == 0.0 and k2 == 0.0:
        return p.copy()
    f, cx, cy = K[0, 0], K[0, 2], K[1, 2]
    dx, dy = (p[..., 0] - cx) / f, (p[..., 1] - cy) / f
    rd2 = dx * dx + dy * dy
    rd = np.sqrt(rd2)
    # start from the inverse series r = r_d (1 - k1 r_d^2 + (3 k1^2 - k2) r_d^4): two
    # Newton steps from there reach 1e-12 for ordinary lenses (four from r_d / (...))
    r = rd * np.maximum(1.0 - rd2 * (k1 - (3.0 * k1 * k1 - k2) * rd2), 0.5)
    r = _newton_radius(r, rd, k1, k2, iterations)
    g = r * (1.0 + r * r * (k1 + k2 * r * r)) - rd
    bad = ~(np.abs(g) < 1e-9)
    if bad.any():
        r_max = fold_radius(k1, k2)
        grid = np.linspace(0.0, r_max, 4097)
        rd_grid = grid * (1.0 + grid * grid * (k1 + k2 * grid * grid))
        r[bad] = _newton_radius(np.interp(rd[bad], rd_grid, grid), rd[bad], k1, k2,
                                iterations, r_max)
    s = np.divide(r, rd, out=np.ones_like(rd), where=rd > 0)
    out = np.empty(p.shape)
    out[..., 0] = cx + f * dx * s
    out[..., 1] = cy + f * dy * s
    return out


def _newton_radius(r, rd, k1, k2, iterations, r_max=None):
    """Newton steps on ``r (1 + k1 r^2 + k2 r^4) = rd`` from ``r``, clipped to
    ``[0, r_max]`` when given."""
    r = np.array(r, float)
    for _ in range(iterations):
        r2 = r * r
        g = r * (1.0 + r2 * (k1 + k2 * r2)) - rd
        dg = 1.0 + r2 * (3.0 * k1 + 5.0 * k2 * r2)
        step = g / np.where(np.abs(dg) > 1e-6, dg, 1e-6)
        r -= step
        if r_max is not None:
            np.clip(r, 0.0, r_max, out=r)
        if step.size == 0 or np.abs(step).max() < 1e-12:
            break
    return r


def fold_radius(k1: float, k2: float, r_limit: float = 4.0) -> float:
    """Undistorted normalised radius where ``r_d = r (1 + k1 r^2 + k2 r^4)`` stops
    growing (the lens "folds over"), or ``r_limit`` if it grows all the way there."""
    # d r_d / dr = 1 + 3 k1 u + 5 k2 u^2 with u = r^2: its smallest positive real root
    u = np.roots([5.0 * k2, 3.0 * k1, 1.0])  # (np.roots drops leading zeros)
    u = u[(np.abs(u.imag) < 1e-12) & (u.real > 0)].real
    return float(min(np.sqrt(u.min()), r_limit)) if u.size else float(r_limit)


def corners_px(width: int, height: int) -> np.ndarray:
    """The image's four outer corners (4, 2) px (pixel-centre convention)."""
    return np.array([[-0.5, -0.5], [width - 0.5, -0.5], [-0.5, height - 0.5],
                     [width - 0.5, height - 0.5]])


def apply_h(H, pts) -> np.ndarray:
    """Apply a 3x3 homography to (N, 2) points (any leading shape).

    Points on the homography's horizon (w = 0) come out infinite or NaN.
    """
    p = np.asarray(pts, float)
    if p.ndim == 2 and len(p) >= _CV_MIN_POINTS:
        import cv2

        out = cv2.perspectiveTransform(p.reshape(-1, 1, 2), np.asarray(H, float))
        out = out.reshape(-1, 2)
        # (OpenCV writes 0 where |w| < FLT_EPSILON; say "no point" there, as below)
        w = p @ H[2, :2] + H[2, 2]
        horizon = np.abs(w) < 1.2e-7
        if horizon.any():
            out[horizon] = (np.array([H[0, 0], H[1, 0]]) * p[horizon, :1]
                            + np.array([H[0, 1], H[1, 1]]) * p[horizon, 1:]
                            + H[:2, 2]) / w[horizon, None]
        return out
    x, y = p[..., 0], p[..., 1]
    w = H[2, 0] * x + H[2, 1] * y + H[2, 2]
    return np.stack([(H[0, 0] * x + H[0, 1] * y + H[0, 2]) / w,
                     (H[1, 0] * x + H[1, 1] * y + H[1, 2]) / w], axis=-1)


#: From this many points on, :func:`apply_h` uses OpenCV (fewer numpy calls).
_CV_MIN_POINTS = 32
