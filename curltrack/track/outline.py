"""The rock's outline as a second ruler: its known diameter measured against the grid.

A curling rock is widest at its striking band, about half-way up (``z_w`` above the
ice).  Seen from a lens ``H`` above the ice, a horizontal circle at height ``z`` maps
onto the ice plane as a circle scaled by ``H / (H - z)`` about the nadir, so in the
lattice frame the outline is a circle of radius

    R_o = f * R * H / (H - z_w),

where ``f`` is the factor by which the rig's grid spacing overstates the true one (1
for a right rig).  The markers' layout gives ``s_m = f * H / (H - h)`` the same way.
Two heights, two rulers: with ``f`` = 1 the camera height the markers imply must also
explain the outline (and the rig's ``[camera].height_m``, when given, both).  A grid
spacing a few % off breaks that agreement; :func:`scale_check` says so.

The outline is found along radial profiles from the rock's apparent centre, in lattice
metres mapped into the image: the edge is the sharpest outward brightening (dark granite
to bright ice) near the nominal radius; directions smeared by motion blur or hidden (a
broom) have soft or missing edges and are left out.  Units: metres (lattice), pixels.
"""

from __future__ import annotations

import numpy as np

__all__ = ["outline_radius", "scale_check", "OUTLINE_HEIGHT_FRACTION"]

#: Height of the rock's widest circle (the striking band) as a fraction of its height.
OUTLINE_HEIGHT_FRACTION = 0.5
#: ... and its uncertainty (fraction of the height): rocks differ, and the outline is
#: the envelope of a curved side.
OUTLINE_HEIGHT_SPREAD = 0.1
N_DIRECTIONS = 64
#: Radial search band (fractions of the nominal radius) and step (m).
R_BAND = (0.85, 1.25)
R_STEP_M = 0.0005
#: Uncertainty of a rig's camera height taken as exact (relative): tape-measured.
RIG_HEIGHT_REL_ERR = 0.05
#: A discrepancy beyond this many sigma (and beyond the floors below) stops tracking.
N_SIGMA = 5.0
#: Smallest relative discrepancy of the markers' scale ever reported (the markers are
#: placed by hand to ~1 mm over ~0.16 m).
MIN_DISCREPANCY = 0.012
#: ... and of the outline's: its edge is found to ~1-2 mm of the striking band (the
#: shadow at its foot, motion blur, the curved side), i.e. ~1 % of the radius: measured
#: +0.7 to +1.3 % on the renderer's set-ups with a right rig.
MIN_OUTLINE_DISCREPANCY = 0.03
#: Highest plausible camera (m): markers that look less than h/MAX_CAMERA_HEIGHT_M larger
#: than their layout contradict the grid's scale.
MAX_CAMERA_HEIGHT_M = 8.0


def _profiles(grey, H_inv, K, dist, centre, radius, n_dir):
    from ..calib.lens import apply_h, distort

    ang = np.linspace(0, 2 * np.pi, n_dir, endpoint=False)
    r = np.arange(R_BAND[0] * radius, R_BAND[1] * radius, R_STEP_M)
    u = np.column_stack([np.cos(ang), np.sin(ang)])
    pts = centre[None, None, :] + r[None, :, None] * u[:, None, :]  # (D, R, 2) lattice m
    px = distort(apply_h(H_inv, pts.reshape(-1, 2)), K, dist).reshape(n_dir, r.size, 2)
    import cv2

    prof = cv2.remap(grey, px[..., 0].astype(np.float32), px[..., 1].astype(np.float32),
                     cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan)
    return ang, r, prof


def _edges(r, prof):
    """Per direction: the radius of the sharpest outward brightening, and its strength."""
    g = np.gradient(prof, axis=1)
    g = np.where(np.isfinite(g), g, -np.inf)
    k = np.clip(np.argmax(g, axis=1), 1, r.size - 2)
    rows = np.arange(prof.shape[0])
    a, b, c = g[rows, k - 1], g[rows, k], g[rows, k + 1]
    with np.errstate(invalid="ignore"):  # profiles off the frame: -inf - -inf, dropped below
        den = a - 2 * b + c
        off = np.where(np.isfinite(den) & (den < 0),
                       0.5 * (a - c) / np.where(den < 0, den, -1), 0.0)
    edge = r[k] + np.clip(off, -1, 1) * (r[1] - r[0])
    return edge, b


def outline_radius(image, H, K, dist, centre, radius_m: float) -> tuple[float, np.ndarray]:
    """Radius (lattice m) and centre of the rock's outline in one frame (nan if unclear).

    Parameters
    ----------
    image : (h, w, 3) uint8
        The frame (BGR).
    H : (3, 3) array
        Undistorted image px -> lattice m.
    K, dist : camera matrix and distortion (see :mod:`curltrack.calib.lens`).
    centre : (2,) array
        The rock's apparent centre (lattice m), within a few cm of the outline's.
    radius_m : float
        The rig's rock radius (m).
    """
    import cv2

    grey = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY).astype(np.float32)
    H_inv = np.linalg.inv(H)
    c = np.asarray(centre, float)
    for it in range(2):  # a circle fit, then profiles again from its centre
        ang, r, prof = _profiles(grey, H_inv, K, dist, c, radius_m, N_DIRECTIONS)
        edge, strength = _edges(r, prof)
        finite = np.isfinite(strength)
        if not finite.any():  # the rock's surroundings are all off the frame
            return np.nan, c
        sharp = finite & (strength > 0.5 * strength[finite].max())
        if sharp.sum() < N_DIRECTIONS // 4:
            return np.nan, c
        p = c + edge[:, None] * np.column_stack([np.cos(ang), np.sin(ang)])
        if it == 0:  # algebraic circle fit on the sharp edges
            q = p[sharp]
            A = np.column_stack([2 * q, np.ones(len(q))])
            sol, *_ = np.linalg.lstsq(A, (q ** 2).sum(axis=1), rcond=None)
            c = sol[:2]
            continue
        half = N_DIRECTIONS // 2
        pair = sharp[:half] & sharp[half:]
        if pair.sum() < 4:
            return np.nan, c
        d = 0.5 * (edge[:half] + edge[half:])[pair]
        med = np.median(d)
        mad = 1.4826 * np.median(np.abs(d - med)) + 1e-5
        return float(np.mean(d[np.abs(d - med) < 3 * mad])), c
    return np.nan, c


def scale_check(layout_scale, outline_scale, rig, h_eff: float, depth_eff: float) -> str:
    """Why the grid's metric scale contradicts the rock's other rulers, or "".

    Parameters
    ----------
    layout_scale, outline_scale : array
        Per-frame apparent scale of the markers' layout and of the rock's outline
        (``R_o / R``) against the grid (nan where not measured).
    rig : Rig
    h_eff : float
        The markers' effective height above the threads (m).
    depth_eff : float
        The threads' apparent depth under the ice surface (m).
    """
    s_m, e_m = _robust_mean(layout_scale)
    s_o, e_o = _robust_mean(outline_scale)
    if not (np.isfinite(s_m) and np.isfinite(s_o)):
        return ""
    z = OUTLINE_HEIGHT_FRACTION * rig.rock_height_m + depth_eff
    dz = OUTLINE_HEIGHT_SPREAD * rig.rock_height_m
    spacing = f"{rig.spacing_x_m:g} x {rig.spacing_y_m:g} m"
    what = ("check [grid] spacing_x_m/spacing_y_m (measure several cells with a tape), "
            "then [rock].diameter_m and the [[markers]] positions")
    if rig.camera_height_m is not None:
        H = rig.camera_height_m + depth_eff
        dH = RIG_HEIGHT_REL_ERR * H
        f_m, f_o = s_m * (H - h_eff) / H, s_o * (H - z) / H
        e_fm = np.hypot(e_m * (H - h_eff) / H, s_m * h_eff / H ** 2 * dH)
        e_fo = np.hypot(np.hypot(e_o * (H - z) / H, s_o * z / H ** 2 * dH), s_o * dz / H)
        bad = [(name, fv, ev, floor) for name, fv, ev, floor in (
            ("markers", f_m, e_fm, MIN_DISCREPANCY),
            ("rock outline", f_o, e_fo, MIN_OUTLINE_DISCREPANCY))
            if abs(fv - 1) > max(N_SIGMA * ev, floor)]
        if len(bad) == 2 and abs(f_m - f_o) < max(N_SIGMA * np.hypot(e_fm, e_fo),
                                                  MIN_OUTLINE_DISCREPANCY):
            f = (f_m / e_fm ** 2 + f_o / e_fo ** 2) / (1 / e_fm ** 2 + 1 / e_fo ** 2)
            return (f"the grid's scale disagrees with the rock: against the rig's grid "
                    f"spacing ({spacing}) and camera height ({rig.camera_height_m:g} m) the "
                    f"markers and the rock's outline both measure {(f - 1) * 100:+.1f} % "
                    f"(expected 0 within {N_SIGMA * np.hypot(e_fm, e_fo) * 100:.1f} %): "
                    f"the grid spacing is likely {(f - 1) * 100:+.1f} % off; {what}")
        if bad:
            name, fv, ev, floor = bad[0]
            return (f"the grid's scale disagrees with the rock: against the rig's grid "
                    f"spacing ({spacing}) and camera height ({rig.camera_height_m:g} m) the "
                    f"{name} measure{'s' * (name != 'markers')} {(fv - 1) * 100:+.1f} % "
                    f"(expected 0 within {max(N_SIGMA * ev, floor) * 100:.1f} %): "
                    f"check [camera].height_m, [grid] spacing_x_m/spacing_y_m, "
                    f"[rock].diameter_m and the [[markers]] positions")
        return ""
    # no camera height: the height the markers imply must be plausible and explain
    # the outline
    least = 1.0 + h_eff / (MAX_CAMERA_HEIGHT_M + depth_eff)
    if s_m < least - max(N_SIGMA * e_m, 0.003):
        return (f"the grid's scale disagrees with the rock: against the rig's grid spacing "
                f"({spacing}) the markers measure {(s_m - 1) * 100:+.1f} % of their layout, "
                f"where markers {rig.rock_height_m:g} m above the ice must look at least "
                f"{(least - 1) * 100:.1f} % larger (a camera below {MAX_CAMERA_HEIGHT_M:g} m):"
                f" the grid spacing is likely too small; {what}")
    Hm = h_eff * s_m / (s_m - 1.0)
    pred = Hm / (Hm - z)
    dpred_ds = z * h_eff / ((s_m - 1.0) ** 2 * (Hm - z) ** 2)  # d pred / d s_m
    e_pred = np.hypot(dpred_ds * e_m, dz / (Hm - z))
    err = np.hypot(e_o, e_pred)
    D = s_o / pred - 1.0
    if abs(D) <= max(N_SIGMA * err, MIN_OUTLINE_DISCREPANCY):
        return ""
    f = _solve_f(s_m, s_o, h_eff, z)
    likely = (f"the grid spacing is likely {(f - 1) * 100:+.0f} % off"
              if np.isfinite(f) else "the grid spacing is likely off")
    return (f"the grid's scale disagrees with the rock: against the rig's grid spacing "
            f"({spacing}) the rock's outline measures {s_o * rig.rock_diameter_m:.3f} m "
            f"across where the markers' parallax (camera {Hm:.2f} m up) predicts "
            f"{pred * rig.rock_diameter_m:.3f} m ({D * 100:+.1f} %, expected 0 within "
            f"{max(N_SIGMA * err, MIN_OUTLINE_DISCREPANCY) * 100:.1f} %): {likely}; {what}, "
            "or give [camera].height_m")


def _solve_f(s_m, s_o, h, z):
    """Spacing factor f from s_m = f H/(H - h), s_o = f H/(H - z) (nan if no solution)."""
    if s_m <= s_o:
        return np.nan
    H = (s_m * h - s_o * z) / (s_m - s_o)
    return float(s_m * (H - h) / H) if H > h else np.nan


def _robust_mean(v) -> tuple[float, float]:
    v = np.asarray(v, float)
    v = v[np.isfinite(v)]
    if v.size < 5:
        return np.nan, np.nan
    med = np.median(v)
    mad = 1.4826 * np.median(np.abs(v - med)) or 1e-6
    v = v[np.abs(v - med) < 4 * mad]
    return float(v.mean()), float(v.std() / np.sqrt(v.size))
