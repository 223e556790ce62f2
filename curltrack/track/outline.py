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

from .._stats import robust_sigma

__all__ = ["outline_radius", "scale_check", "scale_check_resolution",
           "OUTLINE_HEIGHT_FRACTION"]

#: Height of the rock's widest circle (the striking band) as a fraction of its height.
OUTLINE_HEIGHT_FRACTION = 0.5
N_DIRECTIONS = 48
#: Radial search band (fractions of the nominal radius) and step (m).
R_BAND = (0.85, 1.25)
R_STEP_M = 0.001
# The check's thresholds - the rig camera height's relative error, the number of sigma,
# the markers' and the outline's discrepancy floors, the highest plausible camera - are
# the rig's TrackingSettings (curltrack.settings: rig_height_rel_err, scale_check_sigma,
# scale_min_layout_discrepancy, scale_min_outline_discrepancy, max_camera_height_m).


def _profiles(image, H_inv, K, dist, centre, radius, n_dir):
    import cv2

    from ..calib.lens import apply_h, distort

    ang = np.linspace(0, 2 * np.pi, n_dir, endpoint=False)
    r = np.arange(R_BAND[0] * radius, R_BAND[1] * radius, R_STEP_M)
    u = np.column_stack([np.cos(ang), np.sin(ang)])
    pts = centre[None, None, :] + r[None, :, None] * u[:, None, :]  # (D, R, 2) lattice m
    px = distort(apply_h(H_inv, pts.reshape(-1, 2)), K, dist).reshape(n_dir, r.size, 2)
    prof = cv2.remap(image, px[..., 0].astype(np.float32), px[..., 1].astype(np.float32),
                     cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    inside = ((px[..., 0] >= 0) & (px[..., 0] <= image.shape[1] - 1)
              & (px[..., 1] >= 0) & (px[..., 1] <= image.shape[0] - 1))
    grey = prof.astype(np.float32).mean(axis=2)
    return ang, r, np.where(inside, grey, np.nan)


def _edges(r, prof):
    """Per direction: the radius of the sharpest outward brightening, and its strength."""
    g = prof[:, 1:] - prof[:, :-1]  # at (r[i] + r[i+1]) / 2
    valid = np.isfinite(g)
    g = np.where(valid, g, -1e9)  # (samples outside the image: never the edge)
    k = np.clip(np.argmax(g, axis=1), 1, g.shape[1] - 2)
    rows = np.arange(prof.shape[0])
    a, b, c = g[rows, k - 1], g[rows, k], g[rows, k + 1]
    usable = valid[rows, k - 1] & valid[rows, k] & valid[rows, k + 1]
    den = np.where(usable, a - 2 * b + c, 0.0)
    off = np.where(den < 0, 0.5 * (a - c) / np.where(den < 0, den, -1.0), 0.0)
    b = np.where(usable, b, np.nan)
    step = r[1] - r[0]
    return r[k] + (0.5 + np.clip(off, -1, 1)) * step, b


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
    c = np.asarray(centre, float)
    ang, r, prof = _profiles(image, np.linalg.inv(H), K, dist, c, radius_m, N_DIRECTIONS)
    edge, strength = _edges(r, prof)
    ok = np.isfinite(strength)
    if ok.sum() < N_DIRECTIONS // 3:
        return np.nan, c
    ok &= strength > 0.5 * strength[ok].max()  # soft edges: motion blur, a broom
    p = c + edge[:, None] * np.column_stack([np.cos(ang), np.sin(ang)])
    for _ in range(2):  # algebraic circle fit, then again without the outliers
        if ok.sum() < N_DIRECTIONS // 4:
            return np.nan, c
        q = p[ok]
        sol, *_ = np.linalg.lstsq(np.column_stack([2 * q, np.ones(len(q))]),
                                  (q ** 2).sum(axis=1), rcond=None)
        centre_fit = sol[:2]
        rad = float(np.sqrt(sol[2] + centre_fit @ centre_fit))
        res = np.hypot(*(p - centre_fit).T) - rad
        mad = robust_sigma(res[ok], centre=0.0) + 1e-5
        ok &= np.abs(res) < 3 * mad
    return rad, centre_fit


def scale_check(layout_scale, outline_scale, rig, h_eff: float, depth_eff: float) -> str:
    """Why the grid's metric scale contradicts the rock's other rulers, or "".

    Each test allows ``scale_check_sigma`` times the measurement's own scatter (frames
    are averaged) or a floor for what scatter does not show (hand-placed markers, the
    outline's edge bias and height), whichever is larger, plus twice the effect of a
    rig camera height ``rig_height_rel_err`` off (``rig.tracking``).

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
    return _verdict(s_m, e_m, s_o, e_o, rig, h_eff, depth_eff)


def scale_check_resolution(layout_scale, outline_scale, rig, h_eff: float,
                           depth_eff: float, largest: float = 0.3) -> float:
    """Smallest relative grid-spacing error :func:`scale_check` would catch here.

    The same measurements with the lattice's metric scale multiplied by ``1 + e`` (what
    a rig spacing off by ``e`` does to both rulers) are put to the same test, for
    ``|e|`` from 0.1 % up; the larger of the two signs' smallest caught ``|e|`` is
    returned (``inf`` when nothing up to ``largest`` is caught, or nothing measured).
    Without the camera height the outline is the only second ruler and this is
    typically 4-8 %; with it, 1-3 %.

    Parameters are those of :func:`scale_check`; ``largest`` is the biggest relative
    error tried.
    """
    s_m, e_m = _robust_mean(layout_scale)
    s_o, e_o = _robust_mean(outline_scale)
    if not np.isfinite(s_m):
        return np.inf
    worst = 0.0
    for sign in (1.0, -1.0):
        for e in np.arange(0.001, largest + 1e-9, 0.001):
            f = 1.0 + sign * e
            if _verdict(s_m * f, e_m * f, s_o * f, e_o * f, rig, h_eff, depth_eff):
                worst = max(worst, e)
                break
        else:
            return np.inf
    return float(worst)


def _verdict(s_m, e_m, s_o, e_o, rig, h_eff, depth_eff) -> str:
    """:func:`scale_check` on the combined rulers (scales and their standard errors)."""
    st = rig.tracking
    n_sigma = st.scale_check_sigma
    if not np.isfinite(s_m):
        return ""
    st = rig.tracking
    n_sigma = st.scale_check_sigma
    z = OUTLINE_HEIGHT_FRACTION * rig.rock_height_m + depth_eff
    spacing = f"{rig.spacing_x_m:g} x {rig.spacing_y_m:g} m"
    head = f"the grid's scale disagrees with the rock: against the rig's grid spacing ({spacing})"
    what = ("check [grid] spacing_x_m/spacing_y_m (measure several cells with a tape), "
            "then [rock].diameter_m and the [[markers]] positions")
    if rig.camera_height_m is not None:
        H = rig.camera_height_m + depth_eff
        dH = st.rig_height_rel_err * H
        tests = [("markers", s_m * (H - h_eff) / H, e_m * (H - h_eff) / H,
                  st.scale_min_layout_discrepancy + 2 * s_m * h_eff / H ** 2 * dH)]
        if np.isfinite(s_o):
            tests.append(("rock outline", s_o * (H - z) / H, e_o * (H - z) / H,
                          st.scale_min_outline_discrepancy + 2 * s_o * z / H ** 2 * dH))
        lim = {name: max(n_sigma * e, floor) for name, _, e, floor in tests}
        bad = [(name, f) for name, f, _, _ in tests if abs(f - 1) > lim[name]]
        if not bad:
            return ""
        where = f"{head} and camera height ({rig.camera_height_m:g} m)"
        if len(bad) == 2 and np.sign(bad[0][1] - 1) == np.sign(bad[1][1] - 1):
            f = bad[0][1]  # (the markers: the more precise ruler)
            return (f"{where} the markers and the rock's outline both measure "
                    f"{(f - 1) * 100:+.1f} % (expected 0 within {lim['markers'] * 100:.1f} %):"
                    f" the grid spacing is likely {(f - 1) * 100:+.1f} % off; {what}")
        name, f = bad[0]
        return (f"{where} the {name} measure{'s' * (name != 'markers')} "
                f"{(f - 1) * 100:+.1f} % (expected 0 within {lim[name] * 100:.1f} %): "
                f"check the grid spacing, [camera].height_m, [rock].diameter_m and the "
                "[[markers]] positions")
    # no camera height: the height the markers imply must be plausible and explain
    # the outline
    least = 1.0 + h_eff / (st.max_camera_height_m + depth_eff)
    if s_m < least - max(n_sigma * e_m, 0.003):
        return (f"{head} the markers measure {(s_m - 1) * 100:+.1f} % of their layout, "
                f"where markers {rig.rock_height_m:g} m above the ice must look at least "
                f"{(least - 1) * 100:.1f} % larger (a camera below {st.max_camera_height_m:g} m):"
                f" the grid spacing is likely too small; {what}")
    if not np.isfinite(s_o) or s_m <= 1.0:
        return ""
    Hm = h_eff * s_m / (s_m - 1.0)
    pred = Hm / (Hm - z)
    dpred_ds = z * h_eff / ((s_m - 1.0) ** 2 * (Hm - z) ** 2)  # d pred / d s_m
    D = s_o / pred - 1.0
    lim = max(n_sigma * np.hypot(e_o, dpred_ds * e_m), st.scale_min_outline_discrepancy)
    if abs(D) <= lim:
        return ""
    # (which ruler is wrong cannot be told without the camera height: both named)
    f = _solve_f(s_m, s_o, h_eff, z)
    likely = ((f"the grid spacing is likely {(f - 1) * 100:+.0f} % off" if np.isfinite(f)
               else "the grid spacing is likely off")
              + " (or the [[markers]] positions are wrong)")
    return (f"{head} the rock's outline measures {s_o * rig.rock_diameter_m:.3f} m across "
            f"where the markers' parallax (camera {Hm:.2f} m up) predicts "
            f"{pred * rig.rock_diameter_m:.3f} m ({D * 100:+.1f} %, expected 0 within "
            f"{lim * 100:.1f} %): {likely}; {what}, or give [camera].height_m")


def _solve_f(s_m, s_o, h, z):
    """Spacing factor f from s_m = f H/(H - h), s_o = f H/(H - z) (nan if no solution)."""
    if s_m <= s_o:
        return np.nan
    H = (s_m * h - s_o * z) / (s_m - s_o)
    return float(s_m * (H - h) / H) if H > h else np.nan


def _robust_mean(v) -> tuple[float, float]:
    v = np.asarray(v, float)
    v = v[np.isfinite(v)]
    if v.size < 2:
        return np.nan, np.nan
    if v.size < 5:  # (doctor's few frames: no scatter to speak of; the floors apply)
        return float(np.median(v)), 0.0
    med = np.median(v)
    mad = robust_sigma(v, centre=med) or 1e-6
    v = v[np.abs(v - med) < 4 * mad]
    return float(v.mean()), float(v.std() / np.sqrt(v.size))
