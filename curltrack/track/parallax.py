"""Parallax: the markers ride ``h`` above the ice; the grid homography maps the ice plane.

A point at height ``h`` seen by a camera whose lens is ``H`` above the ice at the nadir
``N`` (the ice point straight below the lens) projects onto the ice plane at

    P = N + (M - N) * H / (H - h),

so in the lattice frame the apparent marker layout is the true one scaled by
``s = H / (H - h)`` about ``N``, and the rock axis is at ``C = N + k (P_c - N)`` with the
parallax factor ``k = (H - h)/H = 1/s``.  ``s`` is measured in every frame from the
apparent size of the marker layout (a similarity fit), and combined robustly over the
whole video (one frame's spacing is ill-conditioned: 1 mm of spacing error is ~10 % of
H).  The nadir follows from the frame's homography once the focal length is known, and
the focal length follows from ``H`` and the homography's scale; a 3 deg tilt moves ``N``
~0.1 m, which would move the rock by ``0.1 m * h/H`` ~ 5 mm if ignored.

Units: metres in the lattice frame, pixels in the undistorted image (origin at the
centre of the top-left pixel).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._stats import robust_sigma

__all__ = ["similarity_fit", "camera_centre", "focal_for_height", "HeightEstimate",
           "estimate_height", "correct_parallax", "layout_scale_mismatch", "mirrored_layout",
           "ICE_REFRACTIVE_INDEX", "LAYOUT_SPAN_BIAS_PX"]

#: Threads under ``depth`` of ice look ``depth / n`` deep (paraxial refraction).
ICE_REFRACTIVE_INDEX = 1.31
# The plausible range of the markers' apparent layout scale against the grid,
# s = H / (H - h) (1.01-1.3 for a lens 0.5-10 m above 0.114 m markers), is the rig's
# TrackingSettings layout_scale_min..layout_scale_max (0.7-1.6).  A marker layout a few
# tens of % off in the rig only loses the parallax correction (a warning: the grid is the
# ruler); far outside, the grid's metric scale itself contradicts the rig - a wrong
# spacing, or every other thread invisible - and every position would be scaled wrong.


def mirrored_layout(layout, pts) -> bool:
    """Whether the markers ``pts`` (m, on the ice) are the mirror image of the rig's
    ``layout``: it fits them at less than a quarter of the residual and a plausible
    scale (0.5-2), where the layout itself does not.  Two markers (or collinear ones)
    look alike mirrored: False."""
    L = np.asarray(layout, float)
    if len(L) < 3 or np.linalg.matrix_rank(L[1:] - L[0], tol=1e-6) < 2:
        return False
    _, _, s, rms = similarity_fit(L, pts)
    _, _, sm, rms_m = similarity_fit(L * np.array([-1.0, 1.0]), pts)
    return bool(rms_m < 0.25 * rms and 0.5 < sm < 2.0)


def layout_scale_mismatch(scale: float, rig, mirrored: float = 0.0) -> str:
    """Why the apparent layout scale ``scale`` (median over frames) contradicts the rig,
    or "" when it is plausible (``rig.tracking.layout_scale_min`` .. ``_max``).
    ``mirrored``: the share of frames whose markers are the rig layout's mirror image
    (:func:`mirrored_layout`; over half names that as the cause)."""
    lo, hi = rig.tracking.layout_scale_min, rig.tracking.layout_scale_max
    if lo <= scale <= hi:
        return ""
    if mirrored > 0.5:
        return (f"the markers are the mirror image of the rig's [[markers]] layout in "
                f"{100 * mirrored:.0f} % of the frames (their scale against the grid "
                f"{scale:.2f}x, expected {lo:g}-{hi:g}): the video is mirrored (filmed via "
                "a mirror, or flipped in an editor: flip it back), or the rig's marker "
                "positions are mirrored (x is to the right of +y, seen from above)")
    hint = (": is every other thread invisible (a thread colour like the ice)? Then give "
            "the spacing and colour of the threads that show" if scale < 0.65 else "")
    return (f"the markers measure {scale:.2f}x their rig layout against the grid (expected "
            f"{lo:g}-{hi:g}): the rig's grid spacing ({rig.spacing_x_m:g} x "
            f"{rig.spacing_y_m:g} m) or marker positions do not match the video{hint}")


def similarity_fit(layout: np.ndarray, pts: np.ndarray):
    """Least-squares similarity ``pts ~ c + s R(phi) layout`` (Umeyama, no reflection).

    Parameters
    ----------
    layout : (M, 2) array
        Points in the rock's frame (m), origin = rock axis.
    pts : (M, 2) array
        Observed points (m).  M >= 2.

    Returns
    -------
    (c, phi, s, rms) : ((2,) array, float rad, float, float m)
        ``c`` is where the layout's origin lands; ``phi`` CCW; ``rms`` the residual.
    """
    L = np.asarray(layout, float)
    P = np.asarray(pts, float)
    Lm, Pm = L.mean(axis=0), P.mean(axis=0)
    A, B = L - Lm, P - Pm
    # complex form: B ~ z A with z = s e^{i phi}
    a = A[:, 0] + 1j * A[:, 1]
    b = B[:, 0] + 1j * B[:, 1]
    z = np.vdot(a, b) / np.vdot(a, a).real
    s, phi = float(abs(z)), float(np.angle(z))
    zl = z * (Lm[0] + 1j * Lm[1])
    c = Pm - np.array([zl.real, zl.imag])
    res = b - z * a
    rms = float(np.sqrt(np.mean(np.abs(res) ** 2)))
    return c, phi, s, rms


def _rt_from_h(A: np.ndarray, f, pp) -> tuple[np.ndarray, np.ndarray]:
    """Rotation (..., 3, 3) and camera centre (..., 3) from ice->image homographies
    (..., 3, 3) and focal lengths ``f`` (px, scalar or (...)); principal point ``pp``."""
    A = np.asarray(A, float)
    f = np.asarray(f, float)[..., None]
    # K^-1 A, row by row: (A_0 - pp_x A_2) / f, (A_1 - pp_y A_2) / f, A_2
    M = np.stack([(A[..., 0, :] - pp[0] * A[..., 2, :]) / f,
                  (A[..., 1, :] - pp[1] * A[..., 2, :]) / f, A[..., 2, :]], axis=-2)
    norms = np.sqrt(np.sum(M[..., :, :2] ** 2, axis=-2))  # |M[:, 0]|, |M[:, 1]|
    lam = (2.0 / (norms[..., 0] + norms[..., 1]))[..., None]
    r1, r2, t = M[..., :, 0] * lam, M[..., :, 1] * lam, M[..., :, 2] * lam
    C = -(r1 * t).sum(-1), -(r2 * t).sum(-1), -(np.cross(r1, r2) * t).sum(-1)
    C = np.stack(C, axis=-1)
    # the camera is above the ice: where z < 0 the solution is (-r1, -r2, r3, -t)
    flip = np.where(C[..., 2:] < 0, -1.0, 1.0)
    r1, r2 = r1 * flip, r2 * flip
    C = C * np.concatenate([np.ones_like(flip), np.ones_like(flip), flip], axis=-1)
    R = np.stack([r1, r2, np.cross(r1, r2)], axis=-1)
    return R, C


def _local(H_img2ice: np.ndarray, pp) -> tuple[np.ndarray, np.ndarray]:
    """(ice->image homographies of the ice frame moved to the point under the principal
    point, that point (..., 2) in the given frame).

    The decomposition of :func:`_rt_from_h` is exact for a pinhole view, but a homography
    that is not quite one (a rolling shutter's shear while the camera shakes, a lens
    model's misfit: a few 1e-3 of non-orthogonality) moves its camera centre by that
    times the distance of the frame's origin: metres away when the camera has followed
    the rock from the lattice origin.  About the point under the principal point that
    lever is the tilt's few cm.  (Rendered hand-held action clips, k1 = -0.27/-0.33,
    rolling shutter 10-13 ms: the nadir's error 7.7/6.0 mm -> 1.0/1.4 mm RMS in x.)
    """
    H = np.asarray(H_img2ice, float)
    p = np.append(np.asarray(pp, float), 1.0)
    c = H @ p
    c0 = c[..., :2] / c[..., 2:]
    T = np.zeros(H.shape)
    T[..., 0, 0] = T[..., 1, 1] = T[..., 2, 2] = 1.0
    T[..., :2, 2] = -c0
    return np.linalg.inv(T @ H), c0


def camera_centre(H_img2ice: np.ndarray, f, pp) -> np.ndarray:
    """Lens centre (x, y, z) in the lattice frame (m) for focal ``f`` (px) and principal
    point ``pp`` (px); (x, y) is the nadir, z the height above the homography's plane.
    ``H_img2ice`` may be a stack (..., 3, 3), with ``f`` a scalar or one per homography.
    (Decomposed about the point under the principal point: :func:`_local`.)"""
    A, c0 = _local(H_img2ice, pp)
    C = _rt_from_h(A, f, pp)[1]
    return np.concatenate([C[..., :2] + c0, C[..., 2:]], axis=-1)


def focal_for_height(H_img2ice: np.ndarray, height_m: float, pp, f0: float = 1000.0):
    """Focal length (px) that puts the lens ``height_m`` above the plane (z grows ~ f);
    NaN where the plane is not below the lens.  A stack (..., 3, 3) gives (...) focals."""
    A = _local(H_img2ice, pp)[0]
    f = np.full(A.shape[:-2], float(f0))
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        for _ in range(6):
            z = _rt_from_h(A, f, pp)[1][..., 2]
            f = np.where(np.isfinite(z) & (z > 0), f * height_m / np.where(z > 0, z, 1.0),
                         np.nan)
    return float(f) if f.ndim == 0 else f


@dataclass(frozen=True)
class HeightEstimate:
    """Camera height from the apparent marker-layout scale over many frames.

    Attributes
    ----------
    height_m, height_err_m : float
        Lens height above the homography plane and its 1 sigma (m).
    k, k_err : float
        Parallax factor (H - h)/H and its 1 sigma.
    n_frames : int
        Frames used.
    from_rig : bool
        True when the rig gave the height (then the errors are 0).
    """

    height_m: float
    height_err_m: float
    k: float
    k_err: float
    n_frames: int
    from_rig: bool = False


#: The marker layout's apparent span is biased by about this much (px, 1 sigma) in
#: every frame alike - the markers' centroids on a few pixels, blurred, subsampled and
#: compressed - so no number of frames measures the camera height better than this
#: allows.  Measured on rendered clips of the camera sweep (640x360 to 960x540;
#: hand-held, ladder, pole, still and interlaced cameras): on 9, the span's bias implied
#: by the height's error was 0.02-0.26 px, RMS 0.14, while the frames' scatter /
#: sqrt(n) gave the height 3-10x too small a sigma (a still camera: 2.29 +- 0.08 m for
#: 2.00 m, and every row 1 % of its distance from the nadir off: 14 mm at 1.4 m); on
#: 19 fresh ones, with 0.15 px, the height's error / sigma was -1.4 to +1.8, RMS 0.71
#: (~0.11 px).  Pooled over the 28: 0.12 px.
LAYOUT_SPAN_BIAS_PX = 0.12


def estimate_height(scales: np.ndarray, h_m: float, weights: np.ndarray | None = None,
                    floor_rel: float = 0.0) -> HeightEstimate | None:
    """Combine per-frame apparent layout scales ``s = H/(H - h)`` into H and k.

    Robust: a weighted mean after clipping at 4 MADs; the error is the scatter over
    sqrt(n) (the frames' independent errors) and ``floor_rel`` x the scale (the
    relative error they share: :data:`LAYOUT_SPAN_BIAS_PX` over the layout's span in
    px), in quadrature.

    Returns
    -------
    HeightEstimate or None
        None when fewer than 3 usable frames or the scale does not exceed 1 (the
        markers would be at or above the lens).
    """
    s = np.asarray(scales, float)
    w = np.ones_like(s) if weights is None else np.asarray(weights, float)
    good = np.isfinite(s) & np.isfinite(w) & (w > 0)
    s, w = s[good], w[good]
    if s.size < 3:
        return None
    med = np.median(s)
    mad = robust_sigma(s, centre=med) or 1e-12
    keep = np.abs(s - med) < 4 * mad
    s, w = s[keep], w[keep]
    mean = float(np.sum(w * s) / np.sum(w))
    scatter = float(np.sqrt(np.sum(w * (s - mean) ** 2) / np.sum(w)))
    err = scatter / np.sqrt(s.size)
    if mean <= 1.0 + 3 * err or mean <= 1.0:
        return None
    # (the shared bias widens the error, not the test above: the frames do show a
    # layout magnified above the ice; how much is what the bias leaves unsure)
    err = float(np.hypot(err, floor_rel * mean))
    H = h_m * mean / (mean - 1.0)
    H_err = h_m * err / (mean - 1.0) ** 2
    k = 1.0 / mean
    return HeightEstimate(float(H), float(H_err), k, float(err / mean**2), int(s.size))


def correct_parallax(p_app: np.ndarray, nadir: np.ndarray, k: float) -> np.ndarray:
    """True horizontal position ``N + k (P - N)`` of a point seen at ``p_app`` (m)."""
    p_app = np.asarray(p_app, float)
    nadir = np.asarray(nadir, float)
    return nadir + k * (p_app - nadir)
