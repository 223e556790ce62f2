"""Per-frame records -> the contract's Series: parallax, shot frame, sigmas, stops, sidecar."""

from __future__ import annotations

import numpy as np
import pandas as pd

from .. import __version__
from .._stats import robust_sigma
from ..errors import StartFrameError, TrackingError
from ..rig import Rig
from ..series import Series, make_meta
from .outline import scale_check, scale_check_resolution
from .parallax import (ICE_REFRACTIVE_INDEX, HeightEstimate, camera_centre, correct_parallax,
                       LAYOUT_SPAN_BIAS_PX, estimate_height, focal_for_height,
                       layout_scale_mismatch)
from .scatter import CLIP as PATH_CLIP
from .shotframe import (WINDOW_S, initial_state, leading_strays, origin_weights, row_weights,
                        theta0_fit, to_shot_frame)
from ..series.stops import detect_stops
from ..sanity import speed_rise

__all__ = ["build_series", "frame_ranges"]

# The thresholds (largest origin sigma, layout-scale outliers, fewest measured frames,
# the grid-scale resolution warning, the rolling shutter's slide warning, the
# camera-turn warning) are the rig's
# TrackingSettings (curltrack.settings).
# Camera turn: measured on a 640x360 rendered draw turned steadily about the image
# centre: position RMS 1.5-1.9 mm (max 3.2) from 0 to 1.0 deg/frame, 2.5-3.3 mm (max 5-6)
# from 1.5 to 4.5 deg/frame; at 4.9 the grid was lost for 16 frames and re-found turned
# by 90 deg.  Slow turns (12-20 deg/s at 30 fps = 0.4-0.67 deg/frame) are as accurate as
# a still camera and must not warn.  ``doctor`` uses the same limit.


#: The reported sigmas are calibrated on each video (:func:`calibrate_sigma`): the
#: random part's scale is measured from the rows' own scatter about a smooth path.
#: The two scales below give the a-priori per-frame sigma, which is used (1) to tell a
#: doubtful frame from the video's others (its ratio to their median, so its scale
#: does not matter) and (2) as the reported sigma where the scatter cannot be measured
#: (fewer than :data:`MIN_SIGMA_DOF` degrees of freedom):
#: sigma_xy (per coordinate) = k x hypot(SIGMA_STAT_SCALE x the pixel-noise sigma of the
#: markers and the homography, SIGMA_MISFIT_SCALE x the thread points' RMS miss of the
#: fitted lattice, in m at the rock), fitted by maximum likelihood on 6 random rendered
#: set-ups (ladder/handheld, 2026-11): 1.40 and 0.32.  No pair of constants fits every
#: camera kind (the random part alone is 0.87-1.6x the pixel noise from one kind to the
#: next), hence the per-video calibration.
SIGMA_STAT_SCALE = 1.40
SIGMA_MISFIT_SCALE = 0.32
#: Variance of a row's slowly varying error (what a smooth path through the rows
#: cannot see: a lattice misfit the rock crosses over a second, the error at t = 0
#: that every row shares through the origin) in units of the random variance (the
#: shot's median of it).  Measured against rendered truth (the truth error split into
#: its part on the same smooth path and the rest), 2026-11-26: 0.55-2.0 on the 5 bench
#: set-ups tracked to < 1 mm (action, action-strong, action-fisheye, phone, ladder);
#: see the README ("Per-frame sigma").
SIGMA_SLOW_RATIO = 1.0
#: The angle's slowly varying error where theta0 is fitted, which theta0's own fit
#: (white / AR(1) frame noise) cannot see, as a fraction of the shot's median random
#: angle variance: every angle is taken from theta0, so it is every row's.  Measured
#: against the truth on rendered 720x480 draws (ladder and hand-held, 2 s at 59.94 Hz):
#: the mean angle error's variance left over theta0's sigma was 0.15 x (23 interlaced
#: draws measured per field) and 0.2 x (24 progressive) the random variance; theta0's
#: sigma alone was 1.4-1.6x too small (one draw 4.6 sigma off).  (Those interlaced
#: draws had theta0's noise estimated over the interleaved fields, 2.4x too small; it
#: is now estimated field by field - :func:`~.shotframe._frame_noise` - and over 79
#: draws the mean angle error over theta0's sigma has RMS 1.17, the mean of the rows'
#: own error included; the per-row part left unseen on a camera that follows
#: the rock, std of error over the random sigma 1.2-1.3, is what this term still holds.)
THETA0_SLOW_RATIO = 0.2
#: A rock that speeds up (:func:`~curltrack.sanity.speed_rise`) where at least this
#: share of the frames up to the rise lost the grid was measured through a grid
#: followed wrongly, not from before its release (:func:`build_series`' message)
GRID_LOST_SHARE = 0.25
#: An origin (the rock at t = 0) whose fit is uncertain by more than this (m) is warned
#: about, and its fit's own error is then every row's (the bench hand-held: its first
#: frames disagree by ~3 mm and bend the origin 5 mm; sigma without it 1.7 mm)
ORIGIN_WARN_M = 1e-3
#: Fewest rows in the first :data:`~.shotframe.WINDOW_S` of a segment for it to give the
#: origin on its own (the initial quadratic's least)
ORIGIN_MIN_ROWS = 8
#: Fewest degrees of freedom (rows - spline parameters, x and y counted apart) for a
#: video's own sigma scale; with fewer the scales above are used.
MIN_SIGMA_DOF = 30



#: a frame is refused when its markers' layout-scale agreement (1, 0.6 at 3 robust
#: sigma) times their contrast against the video's typical (at most 1) is under this:
#: the first defocused frame of the wrong-cell test (seed 2197322920: -4.3 sigma, a
#: third of the contrast: 0.11) was 5.5 mm off at sigma 1.0 mm, ok = 1
DOUBTFUL_MARKERS = 0.15


def _refuse(records, ok, shot, mask, why):
    """Frames ``mask`` refused after the shot frame is built: each record's status
    ``why(i)``, and (ok, shot) without them (their x, y, theta NaN)."""
    for i in np.flatnonzero(mask):
        records[i].status = why(i)
    return ok & ~mask, {k: (np.where(mask, np.nan, v) if k in ("x", "y", "theta") else v)
                        for k, v in shot.items()}

def _unmeasure(data, ok, mask, frame, warnings, why: str):
    """Rows ``mask`` of the written table made ``ok`` = 0 (their values emptied) and
    ``why`` (a format string for their frames) said; returns ``ok`` without them."""
    if not mask.any():
        return ok
    data.loc[mask, ["x", "y", "theta", "sigma_xy", "sigma_theta", "quality"]] = np.nan
    data.loc[mask, "ok"] = 0
    warnings.append(why.format(frame_ranges(frame[mask])))
    return ok & ~mask


def _refit_theta0(shot: dict, t, field, angles, lean: bool = False) -> None:
    """theta0 fitted again (:func:`~.shotframe.theta0_fit`, its window and rows as
    before) to ``angles`` ((N,) rad from the old theta0, NaN at rows not used), and
    ``shot``'s angles, theta0 and its uncertainty updated in place.

    ``lean``: the angles were mended (the fields' difference taken off) and theta0 is
    kept: the new fit's distance from it, ``shot["theta0_lean_rad"]``, is added to its
    sigma.  Otherwise theta0 moves by the new fit's change beyond that lean (rows left
    out), the lean still in its sigma."""
    use = np.isfinite(angles)
    fields = (field >= 0).any()
    again = theta0_fit(t[use], angles[use], field[use] if fields else None,
                       shot["theta0_window_s"])
    th0 = again.pop("theta0")
    if lean:
        shot["theta0_lean_rad"] = th0
    else:
        move = th0 - shot["theta0_lean_rad"]
        shot["theta"] = shot["theta"] - move
        shot["theta0_rows"] = angles - move
        shot["theta0"] = shot["theta0"] + move
    again["theta0_sigma_rad"] = float(np.hypot(again["theta0_sigma_rad"],
                                               shot["theta0_lean_rad"]))
    shot.update(again)


def calibrate_sigma(t, xy, theta, ok, field, stops, pix_xy, pix_theta, sys_xy, sys_theta,
                    origin_sigma, theta0_sigma, origin_shared: float = 0.0,
                    origin_row_sigma=None) -> dict:
    """Per-row sigma_xy / sigma_theta whose random part is scaled on the video itself.

    ``pix_xy`` (N,; m per coordinate) and ``pix_theta`` (rad) are the rows' pixel-noise
    sigmas - their shape over the shot; their scale is measured by
    :func:`curltrack.track.scatter.path_scatter` (the rows' scatter about a smooth path
    in t, per interlaced field, knots at the stops).  ``sigma_xy`` is then the hypot of
    that random part, the slowly varying part the scatter cannot see
    (:data:`SIGMA_SLOW_RATIO` x the shot's median random variance), the origin (the
    white part of its fit's value at t = 0, from the calibrated rows, weighted as the
    fit by ``origin_row_sigma`` (N,) when given; ``origin_sigma`` when given: a late
    first frame's extrapolation; each first row's ``sys_xy`` in it too), ``sys_xy``
    (parallax, the fields' offset, the lattice's local misfit at the rock: what its
    correction leaves) and
    ``origin_shared`` (m: the error the origin's first rows share,
    :func:`~.shotframe.origin_check`; not counted where a row is judged against the
    path through the others, which it moves alike).
    ``sigma_theta``: the random part, ``theta0_sigma`` with the slow error it cannot see
    (:data:`THETA0_SLOW_RATIO` x the median random variance) and ``sys_theta``.  Scales are NaN (the caller keeps
    its own sigmas) with fewer than :data:`MIN_SIGMA_DOF` degrees of freedom.
    ``off_path`` ((N,) bool): rows the path through the others misses by more than
    :data:`~curltrack.track.scatter.CLIP` times their ``sigma_xy`` (wrong rows, for
    the caller to refuse); ``off_path_theta`` likewise for the angle (wrong angles;
    ``miss_theta`` (N,): by how much the path misses them, rad, 0 elsewhere);
    ``n_wrong``: the rows left out of the scale; ``unchecked`` ((N,) bool): rows amid
    refused frames too few rows around could check
    (:func:`~curltrack.track.scatter.path_scatter`; the caller refuses them too).
    """
    from .scatter import path_scatter

    n = len(t)
    out = dict(scale_xy=np.nan, scale_theta=np.nan, sigma_xy=np.full(n, np.nan),
               sigma_theta=np.full(n, np.nan), n_wrong=0, off_path=np.zeros(n, bool),
               off_path_theta=np.zeros(n, bool), miss_theta=np.zeros(n),
               unchecked=np.zeros(n, bool))
    tt = np.where(ok, t, np.nan)
    br = [b for b in (stops.t_stop_translation,) if b]
    c = path_scatter(tt, xy, pix_xy, runs=field, breaks=br)
    if c["dof"] >= MIN_SIGMA_DOF:
        fast = c["scale"] * pix_xy
        idx = np.flatnonzero(ok & np.isfinite(xy).all(axis=1))
        if origin_sigma is None:
            # the origin: shotframe.initial_state's fit to the first rows
            m, p0 = origin_weights(t[idx], None if origin_row_sigma is None
                                   else row_weights(np.asarray(origin_row_sigma)[idx]))
            first = idx[:m]
            # (each first row's own systematic error too: a handle over the threads
            # beside the rock, test_scale seed 2952236499)
            sys_first = np.broadcast_to(np.asarray(sys_xy, float), (n,))[first]
            origin_sigma = float(np.sqrt(np.sum(p0 ** 2 * (fast[first] ** 2
                                                           + sys_first ** 2))))
        slow2 = SIGMA_SLOW_RATIO * float(np.median(fast[idx])) ** 2
        sigma_xy = np.sqrt(fast ** 2 + slow2 + origin_sigma ** 2 + np.asarray(sys_xy) ** 2)
        # a row off the path (out of the scale) by more than CLIP of its own whole sigma
        # is one that sigma cannot describe; a row merely noisier than its neighbours -
        # an encoder's starved first frames, the first row beside noisier ones - is
        # off their path by less than its sigma, which carries the slow errors too
        with np.errstate(invalid="ignore"):
            wrong = c["off_path"] & (c["miss"] > PATH_CLIP * sigma_xy)
        out.update(scale_xy=c["scale"], n_wrong=int(c["clipped"]), off_path=wrong,
                   unchecked=c["unchecked"],
                   sigma_xy=np.hypot(sigma_xy, origin_shared))
    brt = [b for b in (stops.t_stop_rotation,) if b]
    c = path_scatter(tt, theta, pix_theta, runs=field, breaks=brt)
    if c["dof"] >= MIN_SIGMA_DOF:
        fast = c["scale"] * pix_theta
        measured = ok & np.isfinite(theta)
        slow2 = THETA0_SLOW_RATIO * float(np.median(fast[measured])) ** 2 if measured.any() else 0.0
        sigma_theta = np.sqrt(fast ** 2 + theta0_sigma ** 2 + slow2
                              + np.asarray(sys_theta) ** 2)
        with np.errstate(invalid="ignore"):
            wrong = c["off_path"] & (c["miss"] > PATH_CLIP * sigma_theta)
        out.update(scale_theta=c["scale"], sigma_theta=sigma_theta, off_path_theta=wrong,
                   miss_theta=np.where(wrong, c["miss"], 0.0))
    return out


#: the running median (s) over which fields that share their colour are taken to pull
#: each other alike (:func:`field_offset_along`)
FIELD_PULL_WINDOW_S = 0.5


def _field_differences(t, q, field, ok):
    """(rows of field 1 compared, their differences (n, k)): each measured field-1 row
    against field 0 interpolated linearly to its time, where field 0 has rows on both
    sides; None when there are fewer than 4."""
    a, b = ok & (field == 0), ok & (field == 1)
    if a.sum() < 4 or b.sum() < 4:
        return None
    ta, tb = t[a], t[b]
    inside = (tb > ta.min()) & (tb < ta.max())
    if inside.sum() < 4:
        return None
    rows = np.flatnonzero(b)[inside]
    d = np.column_stack([q[rows, j] - np.interp(t[rows], ta, q[a, j])
                         for j in range(q.shape[1])])
    return rows, d


def field_offset(t, q, field, ok) -> np.ndarray:
    """Median offset of field 1's values from field 0's at the same time (per column).

    Each measured field-1 row is compared with field 0 interpolated linearly to its time
    (rows of both fields within one frame period).  A smooth motion measured right has
    no offset; NaN-free zeros when there are too few pairs.
    """
    out = np.zeros(q.shape[1])
    got = _field_differences(t, q, field, ok)
    if got is None:
        return out
    d = got[1]
    for j in range(q.shape[1]):
        out[j] = float(np.median(d[:, j])) if np.isfinite(d[:, j]).all() else 0.0
    return out


#: A share of the image's motion that fields read with their own colour differ by is
#: taken off (:func:`build_series`) when it is this many sigmas from 0
#: (:func:`field_share_sure`).
FIELD_SHARE_Z = 5.0


def field_share_sure(share, share_sigma, z: float = FIELD_SHARE_Z) -> bool:
    """Whether the fields' share of the image's motion (:func:`field_motion_share`) is
    sure: its diagonal terms' inverse-variance mean over ``z`` of its sigmas from 0.

    Colour that one exposure lends the other moves its markers by one share of the
    image's motion, along either coordinate alike, so each diagonal term measures that
    one share - as well as the image moves along its coordinate.  A camera that pans
    along the sheet hardly moves the image across it, and that term's sigma is wide: a
    ladder clip whose colour was the top field's read -0.95 +- 0.007 along and
    -0.53 +- 0.12 across, 4.4 sigma, and demanding both terms sure left its fields
    unmoved and out of sigma (every row 7 mm off under a 3 mm sigma, e/sigma RMS 1.76).
    Their mean weighs each term as it is measured; own-colour fields' terms that differ
    in sign (a woven render's +0.05 +- 0.03, -0.45 +- 0.08) mean nothing sure.
    """
    d, e = np.diag(share), np.diag(share_sigma)
    use = np.isfinite(d) & np.isfinite(e) & (e > 0)
    if not use.any():
        return False
    w = 1.0 / e[use] ** 2
    return bool(abs(np.sum(w * d[use])) / np.sum(w) > z / np.sqrt(np.sum(w)))


def _median_size(t, window_s: float) -> int:
    """Odd running-median length (rows) spanning ``window_s`` (s) of rows at times ``t``."""
    dt = float(np.median(np.diff(t))) if t.size > 1 else 1.0
    return int(max(1, min(t.size, round(window_s / max(dt, 1e-6))))) | 1


def _motion_share(d, m) -> tuple[np.ndarray, np.ndarray]:
    """(share (k, k), its 1 sigma (k, k)) of field differences ``d`` (n, k) that follow
    the image's motion ``m`` (n, k): least squares with an intercept, one 3-sigma pass;
    zeros and infinite sigmas with too few finite pairs."""
    k = d.shape[1]
    share, sig = np.zeros((k, k)), np.full((k, k), np.inf)
    fit = np.isfinite(d).all(axis=1) & np.isfinite(m).all(axis=1)
    if fit.sum() < 8 * (k + 1):
        return share, sig
    A = np.column_stack([np.ones(fit.sum()), m[fit]])
    keep = np.ones(fit.sum(), bool)
    for _ in range(2):
        coef, *_ = np.linalg.lstsq(A[keep], d[fit][keep], rcond=None)
        r = d[fit] - A @ coef
        keep = np.all(np.abs(r) <= 3 * np.maximum(robust_sigma(r, axis=0), 1e-9), axis=1)
    if keep.sum() <= k + 1:
        return share, sig
    r = (d[fit] - A @ coef)[keep]
    X = A[keep]
    bread = np.linalg.pinv(X.T @ X)
    # (the sandwich with the residuals' lag-1 products: neighbouring differences share
    # the other field's row that both are interpolated from - lag-1 correlation ~1/6,
    # no further - and the image's motion is smooth, so plain least squares understated
    # the share's sigma: seed 4265661770's unit draw, 2000 noise draws on one motion,
    # the poorly measured term's error over sigma RMS ~1.3 -> 1.10, over 4 sigma 0.1 %)
    # ... and never under the same variance with the residuals' own scale and lag-1
    # correlation (a model, but one read on all the rows): the sandwich's meat rests on
    # few effective rows where the motion is slow, and its noise put its pulls at RMS
    # 1.11 with 20x a Gaussian's 4-sigma tail (3000 draws: the unit test failed 2.75 %
    # of its runs, CI seed 3812700248); the larger of the two: 1.03, 5x.
    n_keep = int(keep.sum())
    free = max(n_keep - k - 1, 1)   # (the residuals' degrees of freedom)
    xx, xx1 = X.T @ X, X[:-1].T @ X[1:]
    sig = np.empty((k, k))
    for j in range(k):
        xr = X * r[:, j:j + 1]
        meat = xr.T @ xr
        lag = xr[:-1].T @ xr[1:]
        meat = meat + lag + lag.T
        s2 = float(r[:, j] @ r[:, j])
        rho1 = float(r[:-1, j] @ r[1:, j]) / max(s2, 1e-300)
        model = s2 / free * (xx + rho1 * (xx1 + xx1.T))
        sig[j] = np.sqrt(np.maximum(np.maximum(np.diag(bread @ meat @ bread) * n_keep / free,
                                               np.diag(bread @ model @ bread))[1:], 0.0))
    return coef[1:].T, sig


def field_motion_share(t, q, field, ok, motion) -> tuple[np.ndarray, np.ndarray]:
    """How far field 1's offset from field 0 follows the image's motion between them
    (:func:`_motion_share` of :func:`_field_differences`): (share (k, k), 1 sigma)."""
    got = _field_differences(t, q, field, ok)
    k = q.shape[1]
    if got is None:
        return np.zeros((k, k)), np.full((k, k), np.inf)
    rows, d = got
    return _motion_share(d, np.asarray(motion, float)[rows])


def field_offset_along(t, q, field, ok, window_s: float = FIELD_PULL_WINDOW_S,
                       motion=None) -> np.ndarray:
    """Field 1's offset from field 0 as it changes over the shot, at every row (n, k).

    :func:`field_offset`'s differences, smoothed by a running median over ``window_s``
    (s) and interpolated to every row's time: two fields that share their colour pull
    each other by a share of the image's motion between them, which follows the rock's
    and the camera's speed (a rendered clip: 20 mm apart at release, 5 mm at 3 s).
    ``motion`` (n, k; m): the image's motion between the fields at each row
    (:func:`image_velocity` times the field period) - the offset's share of it
    (a k x k matrix, least squares with one 3-sigma pass) is fitted first and the
    running median smooths only the rest: a camera that shakes moves the image faster
    than any median follows (a rendered PAL camcorder: each field 0.4-0.5 of the
    image's motion across the rink off, residuals 1.2 mm per coordinate, 0.7 after).
    Zeros where there are too few pairs.
    """
    from scipy.ndimage import median_filter

    out = np.zeros((t.size, q.shape[1]))
    got = _field_differences(t, q, field, ok)
    if got is None:
        return out
    rows, d = got
    share = np.zeros((q.shape[1], q.shape[1]))
    if motion is not None:
        m = np.asarray(motion, float)
        share = _motion_share(d, m[rows])[0]
        m_all = np.where(np.isfinite(m), m, 0.0)
        d = d - m_all[rows] @ share.T
    size = _median_size(t[rows], window_s)
    for j in range(q.shape[1]):
        good = np.isfinite(d[:, j])
        if good.sum() < 4:
            continue
        sm = median_filter(d[good, j], size=size, mode="nearest")
        out[:, j] = np.interp(t, t[rows][good], sm)
    if motion is not None:
        out = out + m_all @ share.T
    return out


#: the running median (s) over which the rock's speed across the image is read
#: (:func:`image_speed`): a camera on a ladder or a pole follows the rock in jerks
IMAGE_SPEED_WINDOW_S = 0.2


def _field_pairs(records, field, usable) -> np.ndarray:
    """Rows ``a`` whose next row is the same frame's other field (field 0 then field 1),
    both ``usable`` ((N,) bool)."""
    frame = np.array([r.frame for r in records])
    return np.flatnonzero((field[:-1] == 0) & (field[1:] == 1) & (frame[:-1] == frame[1:])
                          & usable[:-1] & usable[1:])


def image_velocity(records, t, field, ok) -> np.ndarray:
    """The rock's velocity across the image at every measured row (n, 2), in ice
    metres per second along the lattice's x, y; NaN where it cannot be read.

    Where both fields of a frame are measured, it is their displacement over the field
    period: the grid's own motion between the two exposures at the rock (each field's
    homography, fitted to the threads) plus the rock's slide on the ice between them
    (the same field's rows' smooth path) - the markers' own image positions are what
    the colour one field lends the other pulls together, and a camera that shakes moves
    the image faster than a difference over the same field's rows, 1/15-1/12 s apart,
    follows (16 random draws of the DV field test's set-up: position RMS 0.52-1.81 ->
    0.49-1.50 mm, median 1.12 -> 0.84; four sweep camcorders within -0.3 / +0.5 mm;
    e/sigma RMS 0.74 -> 0.76 over all 24).  Elsewhere: the apparent rock axis of each row
    (``centre_app``, lattice m) taken back into the image through the row's own
    homography, differentiated over the rows of the same field (second-order at the
    ends too: a ladder camera starting to follow changes it fastest there) and mapped
    back to the ice by the homography's local derivative.  A camera that follows the
    rock leaves a fraction of its speed on the ice (a rendered ladder camera: 0.02-0.9
    m/s for a rock sliding at 0.8-2.2 m/s); a shaking one adds its own.
    """
    from ..calib.lens import apply_h

    n = len(t)
    px = np.full((n, 2), np.nan)
    ctr = np.full((n, 2), np.nan)
    inv_h = [None] * n
    jac = np.full((n, 2, 2), np.nan)
    for i in np.flatnonzero(ok):
        r = records[i]
        if r.H is not None and r.centre_app is not None:
            ctr[i] = np.asarray(r.centre_app, float)
            with np.errstate(all="ignore"):
                inv_h[i] = np.linalg.inv(r.H)
                p = apply_h(inv_h[i], ctr[i][None])[0]
                a = apply_h(r.H, np.vstack([p, p + (1.0, 0.0), p + (0.0, 1.0)]))
            px[i], jac[i] = p, np.column_stack([a[1] - a[0], a[2] - a[0]])
    out = np.full((n, 2), np.nan)
    slide = np.full((n, 2), np.nan)
    fld = np.asarray(field)
    for f in np.unique(fld):
        rows = np.flatnonzero(ok & (fld == f) & np.isfinite(px).all(axis=1)
                              & np.isfinite(jac).all(axis=(1, 2)))
        if rows.size >= 3:
            v = np.gradient(px[rows], t[rows], axis=0, edge_order=2)
            out[rows] = np.einsum("nij,nj->ni", jac[rows], v)
            slide[rows] = np.gradient(ctr[rows], t[rows], axis=0, edge_order=2)
    pair = _field_pairs(records, fld, np.isfinite(out).all(axis=1))
    for a in pair:
        b = a + 1
        dt = t[b] - t[a]
        if not dt > 0:
            continue
        with np.errstate(all="ignore"):
            at_b = apply_h(inv_h[b], (ctr[a] + 0.5 * (slide[a] + slide[b]) * dt)[None])[0]
        d = (at_b - px[a]) / dt
        if np.isfinite(d).all():
            out[a], out[b] = jac[a] @ d, jac[b] @ d
    return out


def image_turn(records, t, field, ok, theta, calib) -> np.ndarray:
    """The rock's turn rate in the image at every measured row (rad/s; NaN where it
    cannot be read): its spin on the ice (``theta``, rad, differentiated over the rows
    of the same field) less the camera's own turn, the grid's yaw in the image
    (:func:`~curltrack.calib.grid.image_yaw_deg`, each row's homography) - between a
    frame's two fields where both are measured, over the same field's rows elsewhere.

    Colour that one field lends the other turns its marker pair towards the other
    exposure's as it moves it: the fields' angles differ by a share of this turn over
    the field period (rendered DV on hand-held and pole cameras: their difference
    follows the camera's yaw between the fields with a coefficient 0.8-1.0, as their
    positions follow the image's motion 0.9-1.0).  Its share taken off before the
    fields' remaining difference is smoothed: 20 DV renders and 4 camcorders, theta
    RMS median 0.262 -> 0.250 deg, 17 of 24 lower, none more than 0.006 deg higher.
    """
    from ..calib.grid import image_yaw_deg, lattice_turn_deg

    n = len(t)
    fld = np.asarray(field)
    th = np.asarray(theta, float)
    yaw = np.full(n, np.nan)
    use = np.flatnonzero(ok & np.array([r.H is not None for r in records]))
    if use.size:
        yaw[use] = np.radians(image_yaw_deg(np.array([records[i].H for i in use]),
                                            calib.K, calib.dist))
    out = np.full(n, np.nan)
    spin = np.full(n, np.nan)
    for f in np.unique(fld):
        rows = np.flatnonzero(ok & (fld == f) & np.isfinite(th) & np.isfinite(yaw))
        if rows.size >= 3:
            spin[rows] = np.gradient(th[rows], t[rows], edge_order=2)
            # (the yaw unwrapped over the lattice's quarter turns, as lattice_turn_deg)
            turns = np.radians(lattice_turn_deg(np.degrees(yaw[rows][:-1]),
                                                np.degrees(yaw[rows][1:])))
            cam = np.r_[0.0, np.cumsum(turns)]
            out[rows] = spin[rows] - np.gradient(cam, t[rows], edge_order=2)
    pair = _field_pairs(records, fld, np.isfinite(out))
    dt = t[pair + 1] - t[pair]
    cam = np.radians(lattice_turn_deg(np.degrees(yaw[pair]), np.degrees(yaw[pair + 1])))
    rate = 0.5 * (spin[pair] + spin[pair + 1]) - cam / np.where(dt > 0, dt, np.nan)
    good = np.isfinite(rate)
    out[pair[good]], out[pair[good] + 1] = rate[good], rate[good]
    return out


def image_speed(t, velocity, window_s: float = IMAGE_SPEED_WINDOW_S) -> np.ndarray:
    """|:func:`image_velocity`| (m/s) smoothed by a running median over ``window_s`` (s)
    and interpolated to every row; NaN everywhere when fewer than 3 rows have one."""
    from scipy.ndimage import median_filter

    speed = np.hypot(velocity[:, 0], velocity[:, 1])
    good = np.flatnonzero(np.isfinite(speed))
    if good.size < 3:
        return np.full(len(t), np.nan)
    return np.interp(t, t[good], median_filter(speed[good], size=_median_size(t[good], window_s),
                                               mode="nearest"))


def colour_mixing_sigma(t, shot, ok, dt_fields: float,
                        speed=None) -> tuple[np.ndarray, np.ndarray]:
    """Per-row 1 sigma (per coordinate, m; and rad) of a field measured from colour that
    both of its frame's exposures share.

    How the colour was shared is not seen in the video.  FFmpeg's conversion makes each
    colour row the mean of a line of each field: both fields' markers are pulled
    towards each other alike, which :func:`field_offset_along` takes off (woven
    renders, 2026-11-26: 0.5-1.1 mm from a ladder, 2.6-2.7 mm hand-held).  OpenCV's
    samples the top field's line alone: the other field's colour is the top field's
    exposure, and after the same correction both fields are off alike by 0.28-0.5 of
    the rock's travel between them (6-13 mm), which their disagreement cannot show.  So
    half the travel ``speed x dt_fields`` (the field period, s) is taken as the error's
    scale - along the motion, so / sqrt(2) per coordinate - and half the turn
    ``|omega| x dt_fields`` for the angle: honest for both, wide for FFmpeg's.  The
    travel is across the image - the colour is the image's - so ``speed`` (m/s per
    row, :func:`image_speed`) is the rock's speed across it where given (finite);
    elsewhere the measured rows' speed on the ice (``shot``'s x, y against ``t``),
    interpolated to the rest.  Spins: ``shot``'s theta.  (The caller scales it by
    the share of the travel the fields' markers show mixed,
    :func:`colour_mixing_share`: all of it when both fields see one colour.)
    """
    use = ok & np.isfinite(shot["x"]) & np.isfinite(shot["y"])
    n = len(t)
    if use.sum() < 3:
        return np.zeros(n), np.zeros(n)
    tu = t[use]
    on_ice = np.hypot(np.gradient(shot["x"][use], tu), np.gradient(shot["y"][use], tu))
    th = shot["theta"][use]
    fin = np.isfinite(th)
    omega = (np.abs(np.gradient(th[fin], tu[fin])) if fin.sum() >= 3 else np.zeros(0))
    speed_ice = np.interp(t, tu, on_ice)
    speed = speed_ice if speed is None else np.where(np.isfinite(speed), speed, speed_ice)
    omega = np.interp(t, tu[fin], omega) if omega.size else np.zeros(n)
    return 0.5 * speed * dt_fields / np.sqrt(2.0), 0.5 * omega * dt_fields


def colour_mixing_share(share, share_sigma) -> float:
    """The share (0-1) of the image's motion between two fields that their colour
    mixes, from the fields' markers (:func:`field_motion_share`: their difference's
    share of that motion, negative where they come closer than their luma): its
    largest diagonal term, 2 sigma out, at most 1; 1 where it is not measured (a
    camera that does not move the image).

    Fields read from colour they share come closer by that share.  Mixed alike (a
    conversion that averages both fields' lines), each is pulled by half of it and
    half their difference puts both back; mixed one-sidedly (one field's lines for
    both), both stay off alike by half of it, which their difference cannot show.
    Which of the two was done the video does not say: :func:`colour_mixing_sigma`
    times this share is the error's scale (a fields' colour of their own reads 0: a
    PAL clip rendered so, read as shared, e/sigma 0.26 with the whole travel).
    """
    d, e = np.abs(np.diag(share)), np.diag(share_sigma)
    if not np.all(np.isfinite(e)):
        return 1.0
    return float(min(1.0, np.max(d + 2.0 * e)))


#: Farthest (in field periods) the other field's two rows a row is judged against in
#: :func:`fields_disagree` may be from it (a frame's two fields, or across a lost one).
FIELD_PAIR_SPAN = 6.0


def fields_disagree(t, xy, field, ok, sigma, clip: float = PATH_CLIP) -> np.ndarray:
    """Rows of an interlaced series that the other field's path misses by more than
    ``clip`` times their combined 1 sigma (per coordinate).

    The two fields of a frame are two exposures of one path 1/60 s apart: each row is
    compared with the straight line through the other field's rows just before and just
    after it (at the series' ends, its two nearest; each within :data:`FIELD_PAIR_SPAN`
    field periods), the fields' median offset taken off.  Where the rock crosses the still image fast (the camera
    not yet following) a frame's fields can disagree by 15-20 mm, each off by half, at
    the start of a series where a path through one field's rows cannot judge them (a
    0.95 Mbit/s camcorder: two ``ok`` rows 10-15 mm off under a 1.9 mm sigma).

    Parameters
    ----------
    t : (N,) array
        Times (s).
    xy : (N, 2) array
        Positions (m).
    field : (N,) int array
        0/1 per row (-1: not a field).
    ok : (N,) bool array
    sigma : (N,) array
        Each row's 1 sigma per coordinate (m).

    Returns
    -------
    (N,) bool array

    Notes
    -----
    Rows found are left out and the others judged again (up to three passes): two
    split frames side by side judge each other's rows by their own wrong partners (a
    frame split 14 sigma beside another split the other way was missed, farm seed
    3851155372 of ``test_a_frame_whose_two_fields_disagree_is_refused``).
    """
    out = np.zeros(len(t), bool)
    for _ in range(3):
        new = _fields_disagree_once(t, xy, field, np.asarray(ok, bool) & ~out, sigma, clip)
        if not new.any():
            break
        out |= new
    return out


def _fields_disagree_once(t, xy, field, ok, sigma, clip: float) -> np.ndarray:
    """One pass of :func:`fields_disagree` over the rows ``ok``."""
    n = len(t)
    out = np.zeros(n, bool)
    use = np.asarray(ok, bool) & (np.asarray(field) >= 0) & np.isfinite(xy).all(axis=1) \
        & np.isfinite(sigma)
    if use.sum() < 8 or len(np.unique(np.asarray(field)[use])) < 2:
        return out
    step = float(np.median(np.diff(t[use])))
    res = np.full((n, 2), np.nan)
    var = np.full(n, np.nan)
    for f in (0, 1):
        mine = np.flatnonzero(use & (field == f))
        other = np.flatnonzero(use & (field == 1 - f))
        if other.size < 2:
            continue
        # (the other field's rows on either side; at the series' ends, the two nearest
        # on one side - the first row is where a path through one field cannot judge)
        k = np.clip(np.searchsorted(t[other], t[mine]) - 1, 0, other.size - 2)
        a, b = other[k], other[k + 1]
        span = t[b] - t[a]
        near = np.maximum(np.abs(t[mine] - t[a]), np.abs(t[mine] - t[b])) <= FIELD_PAIR_SPAN * step
        mine, a, b, span = mine[near], a[near], b[near], span[near]
        w = ((t[mine] - t[a]) / np.maximum(span, 1e-12))[:, None]
        res[mine] = xy[mine] - ((1 - w) * xy[a] + w * xy[b])
        var[mine] = sigma[mine] ** 2 + ((1 - w[:, 0]) * sigma[a]) ** 2 + (w[:, 0] * sigma[b]) ** 2
        if mine.size:  # (the fields' systematic offset is sigma's, not a wrong row's)
            res[mine] -= np.median(res[mine], axis=0)
    judged = np.isfinite(var)
    out[judged] = np.max(np.abs(res[judged]), axis=1) > clip * np.sqrt(var[judged])
    return out


def misfit_gain(misfit, sigma) -> tuple[np.ndarray, np.ndarray]:
    """How much of the lattice's local misfit at the rock to take off, per frame and
    axis, and the 1 sigma (per coordinate) of what is left.

    ``misfit`` (N, 2) is each measured frame's misfit at the rock (m, lattice x, y: the
    smooth field of the threads' misfit around the rock, :func:`curltrack.calib.lattice.
    misfit_field`), ``sigma`` (N, 2) its 1 sigma from the threads' scatter.  Per axis,
    the shot's mean square misfit is signal plus noise (frames whose field is > 3x the
    median sigma unsure are left out of that sum): the signal variance
    ``s2 = mean(misfit^2 - sigma^2)`` (>= 0), each frame's gain
    ``s2 / (s2 + sigma^2)`` (0 when the field is no larger than its noise, as on a
    narrow lens's clean footage; near 1 where it stands far above it) and the misfit's
    posterior variance gain x sigma^2 what remains uncertain (empirical Bayes).
    Returns (gain (N, 2), sigma (N,) per coordinate, m).
    """
    m, s = np.asarray(misfit, float), np.asarray(sigma, float)
    if len(m) == 0:
        return np.zeros((0, 2)), np.zeros(0)
    s2 = np.zeros(2)
    for j in range(2):
        use = s[:, j] <= 3.0 * np.median(s[:, j])
        s2[j] = max(float(np.mean(m[use, j] ** 2 - s[use, j] ** 2)), 0.0)
    var = s * s
    gain = np.divide(s2, s2 + var, out=np.zeros_like(var), where=(s2 + var) > 0)
    return gain, np.sqrt(np.mean(gain * var, axis=1))


#: the running median (s) of the lattice's misfit at the rock that a frame's own
#: misfit is judged against (:func:`misfit_departure`)
MISFIT_SMOOTH_S = 0.5


def misfit_departure(t, misfit, sigma, window_s: float = MISFIT_SMOOTH_S) -> np.ndarray:
    """1 sigma (per coordinate, m; (N,)) of each frame's misfit at the rock beyond its
    running median and its own noise.

    The lattice's misfit at the rock (``misfit`` (N, 2), its 1 sigma ``sigma``; frames
    at times ``t``, increasing) changes slowly as the rock crosses the image: a frame
    whose misfit departs from its neighbours' by more than 3x its noise (its sigma, or
    the departures' robust scatter where that is larger) was read off
    threads something disturbed there (a broom's handle over the threads beside the
    rock), and its correction cannot be trusted by more than that departure.
    """
    from scipy.ndimage import median_filter

    m, s = np.asarray(misfit, float), np.asarray(sigma, float)
    if len(m) < 3:
        return np.zeros(len(m))
    size = _median_size(np.asarray(t, float), window_s)
    med = np.column_stack([median_filter(m[:, j], size=size, mode="nearest")
                           for j in range(m.shape[1])])
    d = m - med
    # the misfit's noise as its departures show it where its sigma says less (the
    # threads' residuals are not independent: an action camera's wide lens, misfits
    # scattering 3x their sigma from frame to frame, 91 of 203 frames over 3 sigma -
    # noise of every frame, which the rows' own scatter holds already)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = d / s
    k = np.ones(d.shape[1])
    for j in range(d.shape[1]):
        finite = np.isfinite(ratio[:, j])   # (a frame without a misfit field: sigma 0)
        if finite.sum() >= 3:
            k[j] = max(1.0, float(robust_sigma(ratio[finite, j], centre=0.0)))
    noise2 = (k * s) ** 2
    # (beyond 3 sigma only: noise alone would add 0.7 of its sigma to every row)
    return np.sqrt(np.mean(np.where(d ** 2 > 9.0 * noise2, d ** 2 - noise2, 0.0), axis=1))


def frame_ranges(frames) -> str:
    """[1, 2, 3, 7] -> "1-3, 7"."""
    frames = sorted({int(f) for f in frames})
    out, i = [], 0
    while i < len(frames):
        j = i
        while j + 1 < len(frames) and frames[j + 1] == frames[j] + 1:
            j += 1
        out.append(str(frames[i]) if i == j else f"{frames[i]}-{frames[j]}")
        i = j + 1
    return ", ".join(out)


def reason_groups(records) -> list[tuple[str, list[int], str]]:
    """Lost frames grouped by kind of reason, most frequent first.

    Returns ``(kind, frames, reason)`` where ``kind`` is the reason without its per-frame
    detail ("grid: cell index ambiguous" for "grid: cell index ambiguous: the grid moved
    0.42 cells ...") and ``reason`` the full reason when every frame of the group has the
    same one, else ``kind``.
    """
    groups: dict[str, list] = {}
    for r in records:
        if r.status:
            kind = ": ".join(r.status.split(" (")[0].split(": ")[:2])
            g = groups.setdefault(kind, [[], set()])
            g[0].append(r.frame)
            g[1].add(r.status)
    out = [(k, frs, next(iter(st)) if len(st) == 1 else k) for k, (frs, st) in groups.items()]
    return sorted(out, key=lambda g: (-len(g[1]), g[1][0]))


def shutter_slide(records, calib, readout_s: float) -> tuple[int, float]:
    """How far (m) the ice slides under the image during a rolling shutter's readout:
    the speed of the ice point at the principal point (from consecutive measured frames'
    homographies; running median of 3 against a cell jump) times ``readout_s``.
    Returns (frame of the largest, its slide in m); (-1, 0.0) with < 3 measured frames.
    """
    from ..calib.lens import undistort

    used = [r for r in records if r.status == "" and r.H is not None]
    if len(used) < 3 or readout_s <= 0:
        return -1, 0.0
    pp = undistort(calib.K[:2, 2][None], calib.K, calib.dist)[0]
    H = np.array([r.H for r in used])
    c = np.einsum("nij,j->ni", H, np.append(pp, 1.0))
    c = c[:, :2] / c[:, 2:]
    t = np.array([r.t for r in used])
    speed = np.hypot(*np.diff(c, axis=0).T) / np.maximum(np.diff(t), 1e-6)
    speed = np.median(np.lib.stride_tricks.sliding_window_view(speed, 3), axis=1)
    i = int(np.argmax(speed))
    return int(used[i + 2].frame), float(speed[i] * readout_s)


def camera_turn(records, calib) -> tuple[np.ndarray, np.ndarray]:
    """Frame-to-frame turn of the grid in the image (deg/frame) between measured frames.

    The yaw of the image's +u direction at the principal point in the lattice frame
    (:func:`~curltrack.calib.grid.image_yaw_deg`), from each measured frame's homography,
    differenced modulo 90 deg (:func:`~curltrack.calib.grid.lattice_turn_deg`) and
    divided by the frame gap.  Returns (frame of the later record, rate).
    """
    from ..calib.grid import image_yaw_deg, lattice_turn_deg

    used = [r for r in records if r.status == "" and r.H is not None]
    if len(used) < 2:
        return np.zeros(0, int), np.zeros(0)
    frames = np.array([r.frame + 0.5 * (r.field or 0) for r in used])  # (fields: halves)
    yaw = image_yaw_deg(np.array([r.H for r in used]), calib.K, calib.dist)
    rate = np.abs(lattice_turn_deg(yaw[:-1], yaw[1:])) / np.diff(frames)
    if rate.size >= 3:
        # running median of 3: the max of raw rates is biased up by the homography's
        # angle noise (~0.05 deg/frame on a still camera); a steady turn is unchanged
        rate = np.median(np.lib.stride_tricks.sliding_window_view(
            np.r_[rate[0], rate, rate[-1]], 3), axis=1)
    return frames[1:], rate


def _marker_error_shift(rig: Rig) -> float:
    """The rock's centre moves by up to this times a marker error's angle (m/rad).

    One marker of M off by d across its radius r_i (from the markers' centroid) turns
    the layout's similarity fit by d r_i / sum(r^2) and moves the markers' centroid by
    d / M: by the angle's error times sum(r^2) / (M r_i), largest for the marker
    nearest the centroid (of those that turn it); the rock's axis, at a distance from
    that centroid, turns about it too.  Two markers 80 mm either side of the axis:
    80 mm per rad (a DV field's angle 4.4 deg off: its position 5.1 mm off, the bound
    6.2 mm).
    """
    L = rig.layout_m
    r = np.hypot(*(L - L.mean(0)).T)
    if len(r) < 2 or not r.max() > 0:
        return 0.0
    return float(np.sum(r ** 2) / (len(r) * r[r > 0.1 * r.max()].min())
                 + np.hypot(*L.mean(0)))


def _layout_lever(rig: Rig) -> float:
    """The marker layout's lever (m): the root of the markers' summed squared distances
    from their centre (an angle's error is a marker's over it)."""
    L = rig.layout_m
    return float(np.sqrt(np.sum((L - L.mean(0)) ** 2)))


def _height(records, ok, rig: Rig, depth_eff: float, warnings: list) -> HeightEstimate:
    h_eff = rig.rock_height_m + depth_eff
    if rig.camera_height_m is not None:
        H = rig.camera_height_m + depth_eff
        return HeightEstimate(H, 0.0, (H - h_eff) / H, 0.0, 0, from_rig=True)
    rows = np.flatnonzero(ok)
    scales = np.array([records[i].scale for i in rows])
    sig = np.array([records[i].sigma_m for i in rows])
    # the layout's span in px (its markers' RMS distance from their centre, twice, at
    # the apparent scale): the frames' shared bias of LAYOUT_SPAN_BIAS_PX over it
    span_m = 2.0 * _layout_lever(rig) / np.sqrt(len(rig.markers))
    span_px = np.nan
    if rows.size:
        px_per_m = (np.nanmedian([records[i].spacing_px for i in rows])
                    / (0.5 * (rig.spacing_x_m + rig.spacing_y_m)))
        span_px = span_m * float(np.nanmedian(scales)) * float(px_per_m)
    floor = LAYOUT_SPAN_BIAS_PX / span_px if np.isfinite(span_px) and span_px > 0 else 0.0
    est = estimate_height(scales, h_eff, weights=1.0 / np.maximum(sig, 1e-6) ** 2,
                          floor_rel=floor)
    if est is None:
        warnings.append("camera height could not be estimated from the marker layout "
                        "(set [camera].height_m in the rig); no parallax correction applied")
        return HeightEstimate(np.inf, np.inf, 1.0, np.inf, 0)
    return est


def _nadir_and_k(Hs, height_m: float, k0: float, h_eff: float, pp):
    """(focal px, nadir (n, 2) m, parallax factor (n,)) of the frames' homographies
    ``Hs`` for a camera ``height_m`` above the ice: NaN focal and nadirs, and ``k0`` for
    every frame, when the height is not known."""
    nadir = np.full((len(Hs), 2), np.nan)
    k = np.full(len(Hs), k0)
    if not np.isfinite(height_m) or len(Hs) == 0:
        return np.nan, nadir, k
    # (the focal is one number: its median over <= 60 frames spread over the shot)
    fs = focal_for_height(Hs[::max(1, len(Hs) // 60)], height_m, pp)
    f_px = float(np.nanmedian(fs)) if np.isfinite(fs).any() else np.nan
    if np.isfinite(f_px):
        lens = camera_centre(Hs, f_px, pp)
        nadir = lens[:, :2]
        # each frame's own height (a handheld camera bobs by centimetres: 1 cm at 1.5 m
        # is 0.05 % of k, 0.5 mm at a rock 1 m from the nadir); the homography's scale
        # measures it, the video's estimate fixes the focal
        k = np.where(np.isfinite(lens[:, 2]) & (lens[:, 2] > 2 * h_eff),
                     1.0 - h_eff / np.where(lens[:, 2] > 0, lens[:, 2], 1.0), k0)
    return f_px, nadir, k


def _parallax_sigma(Hs, est: HeightEstimate, h_eff: float, pp, app, centre, t) -> np.ndarray:
    """Each measured row's 1 sigma (m) from the video-wide camera height's: the rows
    corrected again for a height one sigma higher (the focal, each frame's nadir and its
    parallax factor all follow it), less the shift of the origin (its fit to the first
    rows, :func:`~.shotframe.initial_state`: x, y are displacements from it)."""
    if not (np.isfinite(est.height_m) and np.isfinite(est.height_err_m)) or len(Hs) == 0:
        return np.zeros(len(Hs))
    H2 = est.height_m + est.height_err_m
    _, nadir2, k2 = _nadir_and_k(Hs, H2, (H2 - h_eff) / H2, h_eff, pp)
    nd2 = np.where(np.isfinite(nadir2).all(axis=1, keepdims=True), nadir2, app)
    shift = correct_parallax(app, nd2, k2[:, None]) - centre
    good = np.isfinite(shift).all(axis=1)
    if good.sum() < 3:
        return np.zeros(len(Hs))
    shift = shift - initial_state(t[good], shift[good])[0]
    return np.nan_to_num(np.hypot(*shift.T))


def _resolve_cells(records, t, centre, ok, calib, warnings, path, settings):
    """Put every grid segment in one cell index (:mod:`.segments`), in place.

    ``centre`` and the records' homographies of re-anchored segments are moved by whole
    cells; frames of segments the rock's path cannot place become ``ok`` = 0 (``ok``
    and ``centre`` updated), and so do those of a segment placed in whole cells whose
    path step still misses by more than :data:`~.segments.MISFIT_Z` sigma (its
    lattice is not the reference's: a phone's first 5 frames 12.4 +- 2.8 mm off, every
    row of the shot 13 mm off through the origin they placed).  Returns the measured
    frames' indices.
    """
    from .segments import MISFIT_Z, resolve_segments

    seg = np.array([r.segment for r in records])
    spacing = (calib.spacing_x_m, calib.spacing_y_m)
    shift, unresolved, notes, misfit = resolve_segments(t, centre, seg, ok, spacing,
                                                        settings=settings, misfit=True)
    first = int(np.flatnonzero(ok)[0]) if ok.any() else None
    if first is not None and unresolved[first]:
        # the release's segment could not be put in the largest one's cell index: the
        # origin (the rock at t = 0) is then extrapolated back over the lost frames.
        # Where that is too uncertain to give (a hand-held action clip: 34 frames, the
        # grid lost for 0.9 s, the whole video refused as "the first measured frame is at
        # 2.03 s") and the release's segment holds an origin window of its own, that
        # segment is the reference and the later frames wait for --start-frame.
        from .shotframe import _origin_sigma

        kept = np.flatnonzero(ok & ~unresolved)
        own = np.flatnonzero(ok & (seg == seg[first]))
        refused = kept.size == 0 or _origin_sigma(
            t[kept], centre[kept] + shift[kept], settings.max_deceleration_m_s2,
            extrapolated=True) > settings.max_origin_sigma_m
        if refused and np.count_nonzero(t[own] <= t[first] + WINDOW_S) >= ORIGIN_MIN_ROWS:
            shift, unresolved, notes, misfit = resolve_segments(
                t, centre, seg, ok, spacing, settings=settings, reference=seg[first],
                misfit=True)
            later = np.flatnonzero(unresolved)
            if later.size:
                notes.append(
                    f"frames {records[later[0]].frame}-{records[later[-1]].frame}: on a "
                    "lattice the rock's path cannot place against the release's (frames "
                    f"{records[own[0]].frame}-{records[own[-1]].frame}, which give the "
                    f"origin): ok = 0; --start-frame {records[later[0]].frame} measures "
                    "them on their own")
    for i in np.flatnonzero(np.any(shift != 0, axis=1)):
        centre[i] += shift[i]
        records[i].H = np.array([[1.0, 0, shift[i, 0]], [0, 1.0, shift[i, 1]],
                                 [0, 0, 1]]) @ records[i].H
        records[i].centre_app = records[i].centre_app + shift[i]
    for i in np.flatnonzero(unresolved):
        records[i].status = ("grid: cell index not certain (the grid was lost and the "
                             "rock's path across the gap does not fix it)")
    ok &= ~unresolved
    centre[unresolved] = np.nan
    warnings.extend(f"{path}: {n}" for n in notes)
    # a segment placed in whole cells whose path still misses by more than MISFIT_Z: its
    # lattice is off the reference's by that much, an error its frames share - where
    # they are the first (the release's), every row through the origin they place
    off = ok & np.any(misfit > 0, axis=1)
    for i in np.flatnonzero(off):
        records[i].status = (
            f"grid: a stretch of its own between losses of the grid, "
            f"{1e3 * float(np.hypot(*misfit[i])):.1f} mm off the rock's path through the "
            f"others (beyond {MISFIT_Z:g} sigma of a whole number of cells): a lattice "
            "not theirs")
    ok &= ~off
    centre[off] = np.nan
    return np.flatnonzero(ok)


def place_origin(shot_frame, t, centre, ok, sigma, max_sigma_m: float, gross_m: float):
    """``shot_frame(ok)`` (:func:`~.shotframe.to_shot_frame` of the rows ``ok``), or the
    same without its first rows that the path of the rows after them misses by over
    :data:`PATH_CLIP` sigmas (:func:`~.shotframe.leading_strays`: wrong lattice poses,
    a marker taken for another): always those it misses by over ``gross_m`` (m; a
    lattice slip's size), the others where they make the origin - where it cannot be
    placed with them (sigma over ``max_sigma_m``, m) and can without, or its sigma
    without them is under half of it with them (they hold 3/4 of its variance).

    A path's first rows depart from the later rows' quadratic by millimetres, so right
    first rows are called strays too (23 of 44 rendered sweep clips, misses up to
    ~4 mm); leaving them out only lengthens the origin's extrapolation, which never
    halved its sigma there.  The one clip where it did had first rows 8-35 mm off the
    truth (sigma 1.5-1.9 mm; origin sigma 7.3 -> 1.4 mm), and a 0.39 Mbit/s camcorder
    refused whole had three fields 13-21 cm off.

    They are also left out where the origin moves without them by more than the two
    fits' difference in variance allows (:func:`strays_shift_origin`): an error those
    rows share, which their scatter cannot show (a 640x360 hand-held camera starting to
    follow: rows 1-3 8-14 mm off the later path, the origin bent 9 mm under a 2.2 mm
    sigma, every row of the shot ~9 mm off).

    Returns ``(ok, shot, left_out)``: the rows kept, their shot frame and the indices
    of the rows left out (empty when none are).
    """
    idx = np.flatnonzero(ok)
    stray, miss = leading_strays(t[idx], centre[idx], np.asarray(sigma)[idx], PATH_CLIP)
    gross = idx[stray & (miss > gross_m)]
    ok = ok.copy()
    ok[gross] = False
    shot = shot_frame(ok)
    rest = idx[stray & (miss <= gross_m)]
    if rest.size:
        ok_left = ok.copy()
        ok_left[rest] = False
        shot_left = shot_frame(ok_left)
        with_them, without = shot["origin_sigma_m"], shot_left["origin_sigma_m"]
        if without <= max_sigma_m and (with_them > max_sigma_m or without <= 0.5 * with_them
                                       or strays_shift_origin(shot, shot_left)):
            return ok_left, shot_left, np.sort(np.r_[gross, rest])
    return ok, shot, gross


#: chi-square (2 degrees of freedom) beyond which the origin's move without the leading
#: strays says they share an error: p = 0.003, a normal variable's 3 sigma
STRAY_SHIFT_CHI2 = 11.6
#: ... over a variance of at least this share of the origin's own (its sigma is a
#: fit's with floors: where the two sigmas nearly agree their difference is not the
#: difference's variance)
STRAY_SHIFT_FLOOR = 0.5


def strays_shift_origin(with_them: dict, without: dict) -> bool:
    """Whether leaving the leading strays out moves the origin by more than chance
    allows: a Hausman test of the two fits (:func:`~.shotframe.to_shot_frame`'s
    results with and without them).  The fit without them is the less precise, and
    where the strays are right the two differ by a variable of variance
    ``without**2 - with_them**2`` per coordinate (the rows both fits share cancel);
    a move beyond :data:`STRAY_SHIFT_CHI2` of it is an error the strays share.  Not
    testable (False) where the origin's sigma does not grow without them (its floors
    and the rows' own scatter then set it, not the rows left out).

    Measured on 70 rendered sweep and bench clips (session 38): 23 had leading strays;
    the origin moved beyond chance on 2, both placed nearer the truth without them
    (shared error 8.8 -> 2.1 mm, 4.5 -> 1.7 mm).  On clean simulated shots (white and
    persisting noise) right rows move it beyond chance in ~1 % of draws; without the
    floor (:data:`STRAY_SHIFT_FLOOR`) in 3-5 %.
    """
    var = without["origin_sigma_m"] ** 2 - with_them["origin_sigma_m"] ** 2
    if not var > 0:
        return False
    var = max(var, STRAY_SHIFT_FLOOR * with_them["origin_sigma_m"] ** 2)
    # ... and the two fits' different bias under the path's cubic term: their rows
    # start at different times (a 60 fps action camera whose rock stopped at 1.8 s,
    # decelerating at 0.45 m/s^2: the right first four rows left out moved the origin
    # 1.6 mm - 0.6 mm of it the cubic's - and every row of the shot was 2.5 mm off)
    cubic = max(with_them["origin_cubic_m_s3"], without["origin_cubic_m_s3"])
    var += (cubic * (with_them["origin_cubic_moment_s3"]
                     - without["origin_cubic_moment_s3"])) ** 2
    d = np.asarray(without["origin"], float) - np.asarray(with_them["origin"], float)
    return bool(float(d @ d) / var > STRAY_SHIFT_CHI2)


def build_series(records, rig: Rig, info, start: int, loop_info: dict, path=None) -> Series:
    """Assemble the Series (see :func:`curltrack.track.track_video` for the columns)."""
    n = len(records)
    st = rig.tracking
    warnings: list[str] = []
    frame = np.array([r.frame for r in records])
    t = np.array([r.t for r in records], float)
    ok = np.array([r.status == "" for r in records])
    # Reject frames whose apparent layout scale disagrees with the video's (a wrong
    # marker identity or a bad homography changes it).
    scale = np.array([r.scale for r in records])
    scale_resolution = np.inf
    if ok.sum() >= 5:
        med = np.median(scale[ok])
        mad = robust_sigma(scale[ok], centre=med) or 1e-9
        bad = ok & (np.abs(scale - med) > st.scale_outlier_sigma * max(mad, 1e-4))
        for i in np.flatnonzero(bad):
            records[i].status = "marker layout inconsistent with the rest of the video"
        ok &= ~bad
        # every position would be scaled wrong: stop instead of writing them
        rulers = (scale[ok],  # the grid against the rock's rulers
                  np.array([r.outline_m for r in records])[ok] / (rig.rock_diameter_m / 2),
                  rig, rig.rock_height_m + rig.grid_depth_m / ICE_REFRACTIVE_INDEX,
                  rig.grid_depth_m / ICE_REFRACTIVE_INDEX)
        mirrored = float(np.mean([records[i].mirrored for i in np.flatnonzero(ok)]))
        mismatch = (layout_scale_mismatch(float(np.median(scale[ok])), rig, mirrored)
                    or scale_check(*rulers))
        if mismatch:
            raise TrackingError(mismatch, path=path, where=f"frames {frame[0]}-{frame[-1]}")
        scale_resolution = scale_check_resolution(*rulers)
        if scale_resolution > st.scale_resolution_warn:
            hint = ("" if rig.camera_height_m is not None else
                    ": give [camera].height_m (tape-measured) to check it more finely")
            warnings.append(
                f"{path}: the grid's metric scale could be checked against the rock only to "
                + (f"+-{100 * scale_resolution:.1f} %" if np.isfinite(scale_resolution)
                   else "no useful precision")
                + " (a grid spacing off by less is not caught: every position, speed and "
                f"the friction's alpha would be off by as much){hint}")
    if ok.sum() < st.min_measured_frames:
        span = f"frames {frame[0]}-{frame[-1]}" if n else None
        if n < st.min_measured_frames:
            what = "the video has" if n == info.n_frames else "the tracked range has"
            raise TrackingError(f"{what} only {n} frame{'s' * (n != 1)}; a shot needs at "
                                f"least {st.min_measured_frames} measured frames", path=path, where=span)
        lost = "; ".join(f"{kind}: {len(frs)} frame{'s' * (len(frs) != 1)}"
                         for kind, frs, _ in reason_groups(records))
        raise TrackingError(f"the rock could be measured in only {int(ok.sum())} of {n} "
                            f"frames ({lost})", path=path, where=span)
    depth_eff = rig.grid_depth_m / ICE_REFRACTIVE_INDEX
    h_eff = rig.rock_height_m + depth_eff
    est = _height(records, ok, rig, depth_eff, warnings)
    calib = loop_info["calib"]
    pp = calib.K[:2, 2]
    idx = np.flatnonzero(ok)
    nadir = np.full((n, 2), np.nan)
    Hs = np.array([records[i].H for i in idx])
    f_px, nadir[idx], k = _nadir_and_k(Hs, est.height_m, est.k, h_eff, pp)
    centre = np.full((n, 2), np.nan)
    phi = np.full(n, np.nan)
    app = np.array([records[i].centre_app for i in idx]).reshape(-1, 2)
    # the lattice's local misfit at the rock (track_frames), taken off as far as the shot
    # shows it above its noise; the rest of its variance goes into sigma
    misfit = np.array([records[i].misfit_m for i in idx]).reshape(-1, 2)
    msig = np.array([records[i].misfit_sigma_m for i in idx]).reshape(-1, 2)
    gain, sig_l = misfit_gain(misfit, msig)
    app = app + gain * misfit
    sig_misfit = np.zeros(n)
    sig_misfit[idx] = sig_l
    # and what the shot-wide gain leaves of a frame's misfit beyond its noise: a
    # disturbance of that frame's own (a broom's handle over the threads beside the
    # rock: misfits of 1-1.8 mm under 0.5-1 mm of noise for 15 frames, every one of
    # them ~3 mm off under a sigma_xy of 1.1 mm; 480x270, test_scale seed 1416438734)
    sig_local = np.zeros(n)
    sig_local[idx] = np.hypot(sig_l, np.sqrt(np.mean(
        np.maximum(misfit ** 2 - msig ** 2, 0.0) * (1.0 - gain) ** 2, axis=1)))
    # ... and a frame's misfit that departs from its neighbours' beyond its noise (the
    # handle over the threads beside the rock for 4 frames: misfits of 3-4.7 mm amid
    # -1.6 to 0.6 under 0.6-0.9 mm of noise, those rows 4-6 mm off under sigma_xy
    # 1.3-1.9 mm; 480x270, test_scale seed 2952236499)
    sig_depart = np.zeros(n)
    sig_depart[idx] = misfit_departure(t[idx], misfit, msig)
    sig_local = np.hypot(sig_local, sig_depart)
    nd = np.where(np.isfinite(nadir[idx]).all(axis=1, keepdims=True), nadir[idx], app)
    centre[idx] = correct_parallax(app, nd, k[:, None])
    sigma_parallax = np.zeros(n)
    sigma_parallax[idx] = _parallax_sigma(Hs, est, h_eff, pp, app, centre[idx], t[idx])
    measured = ok.copy()
    idx = _resolve_cells(records, t, centre, ok, calib, warnings, path, st)
    # (a frame whose cell index is not certain still gives the rock's angle)
    uncertain_cell = measured & ~ok
    phi[idx] = [records[i].phi for i in idx]
    phi[uncertain_cell] = [records[i].phi for i in np.flatnonzero(uncertain_cell)]
    # image up direction in the lattice frame (first measured frame), for a still rock
    r0 = records[idx[0]]
    from ..calib.lens import apply_h, undistort

    p0 = undistort(np.nanmean(r0.markers_px, axis=0)[None], calib.K, calib.dist)
    a, b = apply_h(r0.H, np.vstack([p0, p0 + (0.0, -10.0)]))
    fld = np.array([r.field if r.field is not None else -1 for r in records])
    shared_colour = not getattr(info, "colour_per_field", True) and bool((fld >= 0).any())
    if (fld >= 0).any():
        # each field moved by half the fields' difference, the image's motion between
        # them (the field period's)
        half = np.where(fld == 0, 0.5, np.where(fld == 1, -0.5, 0.0))[:, None]
        v_image = image_velocity(records, t, fld, ok)
        motion = v_image * (0.5 / info.fps)
    # how much of the image's motion between the fields their markers' colour mixes
    # (0: none, 1: both fields see one colour), as far as it may be one-sided - the
    # share of colour_mixing_sigma that sigma carries (see colour_mixing_share)
    mixing = 0.0
    moved_by_share = False   # (the fields' own colour, each moved by half a sure share)
    colour_kept = getattr(info, "colour_kept", "")
    if shared_colour:
        # a stream coded progressive shares its 4:2:0 colour between the two fields: the
        # colours each field is measured by are the two exposures' mean, and pull both
        # towards it alike - their mean is free of it.  The pull follows the image's
        # motion between the fields (a rendered clip: 20 mm at release, 5 mm at 3 s), so
        # it is taken off as it changes, before the origin is fitted to the first rows
        mixing = colour_mixing_share(*field_motion_share(t, centre, fld, ok, motion))
        pull_xy = field_offset_along(t, centre, fld, ok, motion=motion)
        centre = centre + half * pull_xy
    elif (fld >= 0).any():
        # fields read with their own colour can still differ by a share of the image's
        # motion between them (rendered PAL camcorders read as own colour: -0.3 to -0.5
        # of it, +-0.03; a converter that point-sampled the top field's colour reads
        # so too; rendered DV: 0.9-1.0, its quantised colour): where that share is sure
        # (5 sigma), each field takes half of it off (three such clips: 1.69 -> 1.20,
        # 2.79 -> 2.09, 3.21 -> 2.06 mm per coordinate; the worst, a first row 11.6 mm
        # off at 5.1 sigma, 8.2 mm)
        share, share_sigma = field_motion_share(t, centre, fld, ok, motion)
        if field_share_sure(share, share_sigma):
            centre = centre + half * (np.where(np.isfinite(motion), motion, 0.0) @ share.T)
            moved_by_share = True
            if not colour_kept:
                # ... which a colour shared one-sidedly (one field's lines for both)
                # leaves in both alike, where their disagreement cannot show it: a
                # rendered PAL stream of shared colour read as own, 4.5 mm off under a
                # 1.8 mm sigma (e/sigma 2.45)
                mixing = colour_mixing_share(share, share_sigma)
            warnings.append(
                f"{path}: the two fields differ by {-np.mean(np.diag(share)):.2f} of the "
                "image's motion between them, as fields whose colour "
                + (f"the codec mixed alike do ({colour_kept})" if colour_kept
                   else "is shared do") + ": each was moved by half of it (and by half "
                "their angles' difference)")
    # 1 sigma: markers (averaged over the layout) and the homography, scaled by k
    M = loop_info["n_markers"]
    lever = _layout_lever(rig)
    sig_m = np.array([r.sigma_m for r in records])
    sig_g = np.array([r.grid_sigma_m for r in records])
    sig_r = np.array([r.grid_residual_m for r in records])
    sig_r = np.where(np.isfinite(sig_r), sig_r, 0.0)
    # (a frame's own sigma: with its misfit's departure, which weighs it less in the
    # origin's fit - test_scale seed 2952236499's four disturbed rows, at the far end of
    # the origin's window after a gap, had bent it by 2 mm)
    sigma_xy = np.sqrt(est.k ** 2 * (SIGMA_STAT_SCALE ** 2 * (sig_m ** 2 / M + sig_g ** 2)
                                     + (SIGMA_MISFIT_SCALE * sig_r) ** 2 + sig_misfit ** 2)
                       + sigma_parallax ** 2 + sig_depart ** 2)
    # a rock sliding freely only slows: a video whose rock speeds up begins before the
    # release (at rest, or still pushed), and every t and the origin would be wrong
    rise = speed_rise(t[ok], centre[ok])
    if rise is not None:
        k0 = int(np.flatnonzero(ok & (t >= rise["t_release"]))[0])
        # ... or the grid followed wrongly, its motion mistaken by whole cells: frames
        # lost for the grid on the way say so (a 0.33 Mbit/s 640x360 hand-held under
        # glare: every other frame "cell index ambiguous", the rock "sped up" from 1.5
        # to 2.3 m/s - not a start-frame problem)
        upto = t <= rise["t_to"]
        grid_lost = np.array([r.status.startswith("grid") for r in records]) & upto
        if grid_lost.sum() >= GRID_LOST_SHARE * upto.sum():
            lost = reason_groups([r for r, g in zip(records, grid_lost) if g])
            raise TrackingError(
                f"the measured rock speeds up from {rise['u_from']:.2f} m/s (t = "
                f"{rise['t_from']:.2f} s) to {rise['u_to']:.2f} m/s (t = "
                f"{rise['t_to']:.2f} s), which a sliding rock cannot, while the grid was "
                f"lost in {int(grid_lost.sum())} of those {int(upto.sum())} frames (most: "
                f"{lost[0][0]}): the grid's motion was most likely followed wrongly, so "
                f"no position here can be trusted; if the rock is still pushed at first, "
                f"--start-frame {frame[k0]} measures from its release",
                path=path, where=f"frames {frame[0]}-{frame[np.flatnonzero(upto)[-1]]}")
        raise StartFrameError(
            f"the rock speeds up from {rise['u_from']:.2f} m/s (t = {rise['t_from']:.2f} s) "
            f"to {rise['u_to']:.2f} m/s (t = {rise['t_to']:.2f} s), and a rock sliding freely "
            f"only slows: the video begins before the release (the rock at rest, or still "
            f"pushed): give --start-frame at the release, about frame {frame[k0]}",
            path=path, where=f"frames {frame[0]}-{frame[k0]}")
    # (the origin's fit weighs each row by its own sigma)
    def shot_frame(ok):
        return to_shot_frame(t, centre, phi, ok, up_direction=b - a, settings=st,
                             angle_rows=uncertain_cell & np.isfinite(phi),
                             field=fld if (fld >= 0).any() else None, sigma=sigma_xy)

    ok, shot, stray = place_origin(shot_frame, t, centre, ok, sigma_xy, st.max_origin_sigma_m,
                                   st.ambiguous_cells * min(calib.spacing_x_m,
                                                            calib.spacing_y_m))
    if stray.size:
        why = (f"off the path of the rows after them by more than {PATH_CLIP:g} times "
               "sigma_xy (a lattice or marker error)")
        for i in stray:
            records[i].status = why
        warnings.append(f"{path}: frame(s) {frame_ranges(frame[stray])}: the first measured "
                        f"rows, {why}: left out, the origin placed without them (ok = 0)")
    if shot["origin_sigma_m"] > st.max_origin_sigma_m:
        how = (f"the first measured frame is at t = {t[ok][0]:.2f} s and the origin (the "
               "rock at t = 0) cannot be extrapolated back to it" if shot["origin_extrapolated"]
               else "the first measured frames disagree: the origin (the rock at t = 0) "
               "cannot be placed from them")
        # (what the rows are: a 0.49 Mbit/s camcorder's copy measured in 22 of 212
        # fields, 5-9 cm off one another - the start frame is not what would mend it)
        lost = reason_groups(records)
        seen = (f" ({int(ok.sum())} of {n} {'fields' if (fld >= 0).any() else 'frames'} "
                f"measured" + (f"; most lost: {lost[0][0]}, {len(lost[0][1])}" if lost else "")
                + ")")
        size = (f"better than ~{1e3 * shot['origin_sigma_m']:.0f} mm"
                if shot["origin_sigma_m"] < 1.0 else "to within a metre")
        raise TrackingError(f"{how} {size}{seen}: "
                            "give --start-frame at a frame where the rock and the grid are "
                            "seen", path=path, where=f"frames 0-{frame[ok][0]}")
    # the origin's error is every row's (a fit to the first frames, extrapolated or not);
    # a frame's own sigma (sigma_own) is what tells a doubtful frame, below
    sigma_own = sigma_xy
    origin_shared = shot["origin_check_sigma_m"]
    sigma_xy = np.sqrt(sigma_xy ** 2 + shot["origin_sigma_m"] ** 2 + origin_shared ** 2)
    if origin_shared > 0:
        warnings.append(
            f"{path}: the first frames' path misses the later frames' at t = 0 by "
            f"{1e3 * shot['origin_check_difference_m']:.1f} mm, more than their scatter "
            f"allows: the origin (the rock at t = 0) rests on frames that share an error "
            f"(the camera starting to follow, the encoder's first frames), uncertain by "
            f"~{1e3 * origin_shared:.1f} mm (included in sigma_xy)")
    origin_doubtful = bool(shot["origin_sigma_m"] > ORIGIN_WARN_M)
    if origin_doubtful:
        how = (f"the first measured frame is at t = {t[ok][0]:.2f} s: the origin (the rock "
               "at t = 0) is extrapolated back to it" if shot["origin_extrapolated"] else
               "the origin (the rock at t = 0, fitted to the first frames) rests on frames "
               "that disagree")
        warnings.append(f"{path}: {how}, uncertain by ~{1e3 * shot['origin_sigma_m']:.0f} mm "
                        "(included in sigma_xy)")
    pull_th = None
    shot["theta0_lean_rad"] = 0.0
    if (fld >= 0).any() and (shared_colour or moved_by_share):
        # the fields' angles differ as their positions did (their markers' colour mixed,
        # by a share of the image's turn between them): half of it taken off each, as it
        # changes over the shot - theta is cumulative only here (a rendered DV clip's
        # fields 1.5 deg apart, theta 1.21 deg RMS) - and theta0 fitted again to the
        # angles so mended, for its sigma: read with the fields apart, their difference
        # was an error persisting within each field (a DV bench clip: theta0 0.30 deg off
        # under a 3.1 deg sigma).  Its value is kept, the new one's distance from it
        # added to its sigma: the fields' difference is least sure at the release, where
        # the image moves fastest (the mended angles' theta0 was 0.30 -> 0.06 deg off on
        # that clip, but 0.31 -> 0.49 and 0.82 -> 1.56 on two sweep camcorders)
        turn = image_turn(records, t, fld, ok, shot["theta"], calib) * (0.5 / info.fps)
        pull_th = field_offset_along(t, shot["theta"][:, None], fld, ok,
                                     motion=turn[:, None])[:, 0]
        shot["theta"] = shot["theta"] + half[:, 0] * pull_th
        shot["theta0_rows"] = shot["theta0_rows"] + half[:, 0] * pull_th
        _refit_theta0(shot, t, fld, shot["theta0_rows"], lean=True)
    theta0_sigma = float(np.hypot(shot["theta0_sigma_rad"], shot["theta0_check_sigma_rad"]))
    if shot["theta0_check_sigma_rad"] > 0:
        warnings.append(
            f"{path}: the first frames' angles miss the later frames' turn at t = 0 by "
            f"{np.degrees(shot['theta0_check_difference_rad']):.1f} deg, more than their "
            f"scatter allows: theta0 (every angle is taken from it) rests on frames that "
            f"share an error (blurred or coded at the rock's fastest), uncertain by "
            f"~{np.degrees(shot['theta0_check_sigma_rad']):.1f} deg (included in "
            "sigma_theta)")
    sigma_theta = np.hypot(sig_m / max(lever, 1e-6), theta0_sigma)
    if shot["theta_unsure"].any():
        # an angle off by an unknown whole turn is not given (contract: x, y kept)
        sigma_theta = np.where(shot["theta_unsure"], np.nan, sigma_theta)
        warnings.append(f"{path}: frame(s) {frame_ranges(frame[shot['theta_unsure']])}: "
                        "the rock's turns across a gap of unmeasured frames cannot be "
                        "counted for certain from the spin on either side: theta left "
                        "empty (x, y kept)")
    off_xy, off_theta = 0.0, 0.0
    if any(r.field is not None for r in records):
        # the two fields disagree systematically (mis-registration, aliasing, chroma):
        # half their offset is an error of every row that the pixel noise does not show
        if shared_colour:
            moved = np.hypot(*pull_xy[fld >= 0].T)
            warnings.append(
                f"{path}: the two fields disagree by {1e3 * np.median(moved):.1f} mm "
                f"(median; up to {1e3 * moved.max():.1f}) and "
                f"{np.degrees(np.median(np.abs(pull_th[fld >= 0]))):.2f} deg, as fields that "
                "share their colour do: each was moved by half of it, as it changed over "
                "the shot")
            off = np.zeros(3)
        else:
            off = field_offset(t, np.column_stack([shot["x"], shot["y"], shot["theta"]]),
                               fld, ok)
            off_xy, off_theta = 0.5 * np.hypot(off[0], off[1]) / np.sqrt(2), 0.5 * abs(off[2])
        if mixing > 0:
            # (what is left is not in their disagreement: colour_mixing_sigma, the share
            # of it the fields' own disagreement shows)
            mix_xy, mix_theta = (mixing * v for v in colour_mixing_sigma(
                t, shot, ok, 0.5 / info.fps, image_speed(t, v_image)))
            off_xy, off_theta = np.hypot(off_xy, mix_xy), np.hypot(off_theta, mix_theta)
            # ... and it follows the rock's speed, slowly: over the origin's first rows,
            # where the rock is fastest, it is one error, which the origin passes to
            # every row (a rendered 1.5 Mbit/s camcorder: every row ~4.6 mm off in y,
            # late rows under a 0.9 mm sigma)
            idx_ok = np.flatnonzero(ok & np.isfinite(mix_xy))
            if idx_ok.size >= 2:
                m_w, p0 = origin_weights(t[idx_ok], row_weights(sigma_own[idx_ok]))
                first = idx_ok[:m_w]
                origin_pull = abs(float(p0 @ mix_xy[first]))
                origin_shared = float(np.hypot(origin_shared, origin_pull))
                sigma_xy = np.hypot(sigma_xy, origin_pull)
            warnings.append(
                f"{path}: each field's colour mixes both exposures ("
                + ("colour subsampled across the woven frame" if shared_colour else
                   "the fields' markers differ by a share of the image's motion") +
                f", {mixing:.2f} of it at most): the markers locate the rock only within "
                f"that share of its travel between the fields (up to "
                f"{1e3 * np.nanmax(mix_xy) * 2 * np.sqrt(2):.0f} mm; half of it is included "
                "in sigma_xy / sigma_theta, which is wide where the conversion averaged the "
                "fields' colour - and so is the origin's share of it, which every row "
                "carries): the camera's original file measures better")
        sigma_xy = np.hypot(sigma_xy, off_xy)
        sigma_theta = np.hypot(sigma_theta, off_theta)
        if np.hypot(off[0], off[1]) > 2e-3 or abs(off[2]) > np.radians(0.5):
            warnings.append(
                f"{path}: the two fields disagree by {1e3 * off[0]:+.1f}, {1e3 * off[1]:+.1f} mm"
                f" and {np.degrees(off[2]):+.2f} deg (field 1 - field 0, over the shot): "
                "included in sigma_xy / sigma_theta")
    # a frame whose own fit is far less sure than the video's others is not measured
    # (frames measured from a user's clicks carry the click precision: theirs to judge)
    clicked = np.array([r.clicked for r in records], bool)
    sure = ok & np.isfinite(sigma_own)
    if sure.sum() >= st.min_measured_frames:
        pool = sigma_own[sure & ~clicked] if (sure & ~clicked).any() else sigma_own[sure]
        # (the median of the rows that are not themselves outliers: in a clip measured
        # in a few frames half of them may be doubtful, and their median let a row with
        # 8x the good rows' sigma through, 18 mm off - test_wrong_cell seed 61122235)
        typical = float(np.median(pool))
        typical = float(np.median(pool[pool <= st.sigma_outlier_factor * typical]))
        unsure = sure & ~clicked & (sigma_own > st.sigma_outlier_factor * typical)
        ok, shot = _refuse(records, ok, shot, unsure, lambda i: (
            f"uncertain: sigma_xy over {st.sigma_outlier_factor:g}x the video's typical "
            f"{1e3 * typical:.1f} mm (a doubtful grid or marker fit)"))
    contrast = np.array([r.contrast for r in records])
    med = np.median(scale[ok])
    spread = robust_sigma(scale[ok], centre=med) or 1e-9
    # a frame whose markers are both off the video's layout scale and faint (against
    # the video's own contrast) is doubtful beyond what its sigma says
    layout_term = np.exp(-0.5 * ((scale - med) / (3 * max(spread, 1e-4))) ** 2)
    typical_contrast = float(np.nanmedian(contrast[ok])) if ok.any() else np.nan
    doubt = layout_term * np.clip(contrast / typical_contrast, 0.0, 1.0)
    ok, shot = _refuse(records, ok, shot, ok & (doubt < DOUBTFUL_MARKERS), lambda i: (
        f"uncertain: markers off the video's layout scale ({(scale[i] - med) / spread:+.1f} "
        f"robust sigma) and faint (contrast {contrast[i]:.0f}, the video's "
        f"{typical_contrast:.0f})"))
    # 1 for a frame whose marker layout agrees with the video's (3 robust sigmas -> 0.6)
    quality = layout_term * np.clip(contrast / 40.0, 0.0, 1.0)
    fields = any(r.field is not None for r in records)
    data = pd.DataFrame({
        "frame": frame, **({"field": [r.field for r in records]} if fields else {}),
        "t": t, "x": shot["x"], "y": shot["y"], "theta": shot["theta"],
        "ok": ok.astype(int),
        "sigma_xy": np.where(ok, sigma_xy, np.nan),
        "sigma_theta": np.where(ok, sigma_theta, np.nan),
        "quality": np.where(ok, quality, np.nan),
    })
    # warnings for lost frames, grouped by kind of reason
    for _, frs, reason in sorted(reason_groups(records), key=lambda g: g[1][0]):
        warnings.append(f"{path}: frame(s) {frame_ranges(frs)}: {reason} (ok = 0)")
    turn_frames, turn = camera_turn(records, calib)
    turn_max = float(turn.max()) if turn.size else None
    turn_warn = st.turn_warn_deg_per_frame
    if turn_max is not None and turn_max > turn_warn:
        n_fast = int((turn > turn_warn).sum())
        warnings.append(f"{path}: frame {int(turn_frames[np.argmax(turn)])}: the camera turns "
                        f"{turn_max:.1f} deg/frame ({turn_max * info.fps:.0f} deg/s; "
                        f"{n_fast} frame(s) above {turn_warn:g}): positions "
                        "lose accuracy and the grid can be lost; turn the camera more "
                        "slowly")
    if rig.rolling_shutter_ms:
        slide_frame, slide = shutter_slide(records, calib, 1e-3 * rig.rolling_shutter_ms)
        if slide > st.shutter_slide_warn_m:
            warnings.append(
                f"{path}: frame {slide_frame}: the ice slides {1e3 * slide:.0f} mm under "
                f"the image during the rolling shutter's {rig.rolling_shutter_ms:g} ms "
                "readout (camera motion): rows are timed where the rock was seen, but "
                "the image's shear under a shaking or turning camera is not modelled - "
                "positions may be off by a few per cent of it, not included in sigma_xy")
    if getattr(info, "fields_from_content", ""):
        warnings.append(f"{path}: the stream is flagged progressive, but "
                        f"{info.fields_from_content}: interlaced video whose flags were lost (a re-encoding): each "
                        f"frame was measured as its two fields, "
                        f"{'top' if info.top_field_first else 'bottom'} first")
    if getattr(info, "content_note", ""):
        warnings.append(f"{path}: the stream is {info.content_note}")
    if abs(getattr(info, "pixel_aspect", 1.0) - 1.0) > 1e-3:
        warnings.append(f"{path}: the video's pixels are not square (aspect "
                        f"{info.pixel_aspect:.4g}): frames were resampled to square pixels "
                        "before measuring (grid_spacing_px is in those pixels)")
    stops = detect_stops(data, info.fps * (2 if fields else 1))
    # the reported sigmas: the random part's scale measured on this video (sigma_xy,
    # sigma_theta above stay where it cannot be measured)
    def calibrate(theta0_sigma, stops):
        return calibrate_sigma(
            t, np.column_stack([shot["x"], shot["y"]]), shot["theta"], ok,
            fld, stops,
            pix_xy=est.k * np.sqrt(sig_m ** 2 / M + sig_g ** 2),
            pix_theta=sig_m / max(lever, 1e-6),
            sys_xy=np.sqrt(sigma_parallax ** 2 + off_xy ** 2 + sig_local ** 2),
            origin_shared=origin_shared,
            sys_theta=off_theta,
            # (the origin's own fit error where it is extrapolated or its frames
            # disagree: what the warning above says sigma_xy includes)
            origin_sigma=(shot["origin_sigma_m"]
                          if shot["origin_extrapolated"] or origin_doubtful else None),
            theta0_sigma=theta0_sigma, origin_row_sigma=sigma_own)

    cal = calibrate(theta0_sigma, stops)
    # an angle the rock's smooth path through the others misses by more than CLIP times
    # its own sigma_theta: a marker mislocated, the row's position still right (a DV
    # bench clip: five fields 4.8-5.8 deg off at a 0.5 deg sigma, the rock at rest) -
    # left empty, and theta0, its sigma and the angles' scale read again without it
    wrong_theta = np.asarray(cal["off_path_theta"], bool) & ok & np.isfinite(shot["theta"])
    if wrong_theta.any():
        warnings.append(f"{path}: frame(s) {frame_ranges(frame[wrong_theta])}: the rock's "
                        f"angle is off its smooth path through the other rows by more "
                        f"than {PATH_CLIP:g} times sigma_theta (a marker error): theta "
                        "left empty (x, y kept, sigma_xy widened by the centre's share of "
                        "that error)")
        shot["theta"] = np.where(wrong_theta, np.nan, shot["theta"])
        _refit_theta0(shot, t, fld, np.where(wrong_theta, np.nan, shot["theta0_rows"]))
        theta0_sigma = float(np.hypot(shot["theta0_sigma_rad"],
                                      shot["theta0_check_sigma_rad"]))
        data["theta"] = np.where(np.isfinite(data["theta"]), shot["theta"], np.nan)
        sigma_theta = np.where(wrong_theta, np.nan, sigma_theta)
        stops = detect_stops(data, info.fps * (2 if fields else 1))
        cal.update({k: v for k, v in calibrate(theta0_sigma, stops).items()
                    if k in ("scale_theta", "sigma_theta")})
    if np.isfinite(cal["scale_xy"]):
        # (a row whose angle shows a marker error: its centre moved with that marker -
        # by up to the angle's miss times the layout's shift per radian)
        shift = np.where(wrong_theta, cal["miss_theta"] * _marker_error_shift(rig), 0.0)
        data["sigma_xy"] = np.where(ok, np.hypot(cal["sigma_xy"], shift), np.nan)
    if np.isfinite(cal["scale_theta"]):
        data["sigma_theta"] = np.where(ok & np.isfinite(sigma_theta), cal["sigma_theta"], np.nan)
    # a row the rock's smooth path through the others misses by more than CLIP times
    # its own sigma_xy is a wrong measurement that sigma does not describe: refused (CI
    # seed 1744272862: a lattice walked ~5 px off under a broom while the markers were
    # hidden, the first frame they were found again 14.7 mm off under 1.1 mm, 13 sigma)
    ok = _unmeasure(data, ok, np.asarray(cal["off_path"], bool) & ok, frame, warnings,
                    f"{path}: frame(s) {{}}: off the rock's smooth path through the other "
                    f"rows by more than {PATH_CLIP:g} times sigma_xy (a lattice or marker "
                    "error) (ok = 0)")
    # ... and a row amid refused frames that too few rows around it can check: a wrong
    # marker or cell would not be seen (a 0.41 Mbit/s camcorder under auto exposure and
    # a broom, sweep 2026113040 set-up 7: runs of 5-10 fields ~80 mm off, the centre
    # placed from a marker mistaken for the other, between refused frames, ok = 1)
    # (not a frame the user clicked: the clicks say which marker is which)
    ok = _unmeasure(data, ok, np.asarray(cal["unchecked"], bool) & ok & ~clicked, frame,
                    warnings,
                    f"{path}: frame(s) {{}}: measured amid or after frames that were not, "
                    "with too few measured rows around them to check them against the rock's path "
                    "(a marker or cell error would not be seen) (ok = 0)")
    # ... and a row of one field that the other field's path misses so (the fields of
    # a frame exposed 1/60 s apart disagree where the rock crosses a still image fast)
    if (fld >= 0).any():
        split = fields_disagree(t, data[["x", "y"]].to_numpy(float), fld, ok,
                                data["sigma_xy"].to_numpy(float))
        ok = _unmeasure(data, ok, split, frame, warnings,
                        f"{path}: frame(s) {{}}: the other field's rows miss this field's by "
                        f"more than {PATH_CLIP:g} times sigma_xy (the two fields of a frame "
                        "disagree) (ok = 0)")
    for note in stops.notes:
        warnings.append(f"stops: {note}")
    cam_h = est.height_m - depth_eff if np.isfinite(est.height_m) else None
    spacing = np.array([r.spacing_px for r in records], float)
    meta = make_meta(info.fps, n, start_frame=start, **stops.to_meta())
    meta.update(
        camera_height_m=cam_h,
        camera_height_err_m=(est.height_err_m if np.isfinite(est.height_err_m) else None),
        camera_height_source="rig" if est.from_rig else "markers",
        scale_check_resolution=(round(float(scale_resolution), 4)
                                if np.isfinite(scale_resolution) else None),
        parallax_factor=est.k, parallax_factor_err=est.k_err,
        focal_px=f_px,
        grid_spacing_px=float(np.nanmedian(spacing)) if np.isfinite(spacing).any() else None,
        frames_lost=int((~ok).sum()), warnings=warnings, version=__version__,
        camera_turn_max_deg_per_frame=turn_max,
        video=str(path) if path is not None else None,
        n_frames_video=info.n_frames, codec=info.codec, **({"fields": True} if fields else {}),
        video_format=getattr(info, "describe", lambda: None)(),
        frame_origin_lattice_m=shot["origin"].tolist(),
        origin_shared_err_m=origin_shared,
        origin_sigma_m=float(shot["origin_sigma_m"]),
        frame_x_axis_lattice=shot["x_hat"].tolist(),
        frame_y_axis_lattice=shot["y_hat"].tolist(),
        frame_axis_source=shot["direction_source"],
        theta0_lattice_rad=shot["theta0"],
        theta0_shared_err_rad=float(shot["theta0_check_sigma_rad"]),
        # (the part of every row's sigma_theta that all rows share: theta0's error)
        theta0_sigma_rad=float(theta0_sigma),
        tracking_settings=st.summary(),
        sigma_scale_xy=(round(cal["scale_xy"], 4) if np.isfinite(cal["scale_xy"]) else None),
        sigma_scale_theta=(round(cal["scale_theta"], 4) if np.isfinite(cal["scale_theta"])
                           else None),
        sigma_rows_off_path=cal["n_wrong"],
        # a tracker's errors (the lattice's fit as the camera moves, the markers' blur
        # and glare) vary slowly: measured against the truth of 67 clips through real
        # cameras, a slowly varying part at least half the rows' white scatter, held
        # for ~10 rows (median), in 85-91 % of x, y and theta
        noise_persists=True,
    )
    if rig.rolling_shutter_ms:
        meta["rolling_shutter_ms"] = float(rig.rolling_shutter_ms)
    if calib is not None:
        meta["lens_k1"], meta["lens_k2"] = float(calib.dist[0]), float(calib.dist[1])
        meta["lens_focal_ref_px"] = float(calib.K[0, 0])
        if calib.lens_radius_px is not None:
            meta["lens_radius_px"] = float(calib.lens_radius_px)
    return Series(data, meta, None)
