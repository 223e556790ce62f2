"""The lattice's cell index across a loss, re-anchored on the rock's path.

The grid tracker keeps the cell index continuous within a *segment*
(:attr:`curltrack.calib.tracker.GridPose.segment`); where it was carried across a gap
(the grid lost for a few frames while camera and rock moved) or fixed by the thread
colours alone (known only modulo the number of colours), a new segment starts and its
positions may be off by whole cells (0.1-0.3 m each).  Here the offset of each segment is
measured from outside the grid: the rock slides smoothly, so one quadratic in time fits
its path over the last ``segment_window_s`` (TrackingSettings) before the gap and the first after it, and the
step between the two sides, in whole cells, is the offset.  A segment whose step is not
an integer number of cells within the evidence, or whose ends are too short to fit, stays
unresolved: its frames are ``ok`` = 0 - a wrong cell never reaches an ``ok`` row.
"""

from __future__ import annotations

import numpy as np

from .._stats import robust_sigma
from ..settings import TrackingSettings

__all__ = ["resolve_segments", "path_step"]

# The window, fewest frames and longest gap of the fit on each side, and the acceptance
# of a step (within ``segment_max_fraction`` of a whole number of cells, 1 sigma at most
# ``segment_max_sigma_cells``: the nearest wrong integer is then > 5 sigma from it) are
# TrackingSettings (curltrack.settings).
#: Floor of the scatter of the rock's (parallax-corrected) positions about a quadratic
#: (m): marker noise and the grid's are 0.3-1 mm per frame.
MIN_SCATTER_M = 1.0e-3
#: How far a curling rock's path departs from one quadratic over the window (m per s^3
#: of span): the deceleration changes with speed (mu = alpha u^phi) and the curl grows.
#: Measured on 150 simulated shots (v0 0.5-3.5 m/s, |omega0| 0.3-3 rad/s, 1 mm noise,
#: 1 s each side): the step's error was at most 3.3 / 7.9 / 13.4 mm (99th percentile
#: 2.8 / 5.7 / 10.8) across gaps of 10 / 25 / 40 frames at 30 fps (spans 2.3-3.3 s), i.e.
#: <= 0.0004 x span^3.
MODEL_JERK_M_S3 = 0.0004


def path_step(t_a, p_a, t_b, p_b, cell_m: float = 0.0):
    """Step (m) between two stretches of one smooth path, and its 1 sigma (m).

    A quadratic in time per coordinate is fitted jointly to ``p_a`` (times ``t_a``) and
    ``p_b + step`` (times ``t_b``).

    Parameters
    ----------
    t_a, t_b : (Na,), (Nb,) arrays
        Times (s).
    p_a, p_b : (Na, 2), (Nb, 2) arrays
        Positions (m).
    cell_m : float
        The lattice's smaller thread spacing (m): one side's rows that scatter more
        than the other's are taken for a lattice that was not right (sigma infinite)
        only when they scatter by :data:`WRONG_LATTICE_SCATTER_CELLS` of it or more
        (:func:`_disagree`); 0: whenever they do.

    Returns
    -------
    step, sigma : (2,) arrays
        ``p_b`` minus the path through ``p_a`` (m); its 1 sigma from the scatter about the
        fit (floored at ``MIN_SCATTER_M``; the noisier side's where the two differ)
        plus a model term ``MODEL_JERK_M_S3 * span**3`` for the path's departure from a
        quadratic over the time spanned.
    """
    t_a, t_b = np.asarray(t_a, float), np.asarray(t_b, float)
    t0 = 0.5 * (t_a.max() + t_b.min())
    tt = np.r_[t_a, t_b] - t0
    X = np.column_stack([np.ones_like(tt), tt, tt ** 2, np.r_[np.zeros(len(t_a)),
                                                                np.ones(len(t_b))]])
    P = np.vstack([p_a, p_b])
    coef, *_ = np.linalg.lstsq(X, P, rcond=None)
    res = P - X @ coef
    dof = max(len(tt) - 4, 1)
    scatter = np.maximum(np.sqrt(np.sum(res ** 2, axis=0) / dof), MIN_SCATTER_M)
    cov = np.linalg.pinv(X.T @ X)
    span = tt.max() - tt.min()
    differ, noisier = _disagree(res[: len(t_a)], res[len(t_a):], len(tt) - dof)
    if differ:
        if noisier >= WRONG_LATTICE_SCATTER_CELLS * cell_m:
            return coef[3], np.full(2, np.inf)
        scatter = np.maximum(scatter, noisier)
    sigma = np.hypot(scatter * np.sqrt(cov[3, 3]), MODEL_JERK_M_S3 * span ** 3)
    return coef[3], sigma


#: Level of the test that one side's positions scatter about the path more than the
#: other's (:func:`_disagree`).
SCATTER_TEST_LEVEL = 1e-3
#: A side whose rows scatter about the path (RMS) by less than this share of a
#: cell, however much more than the other's, is a right lattice with noisier rows: a
#: lattice that is not right puts its rows a fair part of a cell off (a camcorder's
#: first fields: 45, 3, 5 and -43 mm on a 0.15 m cell).  (A hand-held 640x360 clip's
#: side after a 0.4 s loss scattered 2.2 mm against 1.1 mm - 1.5 % of its cell - and its
#: 9 mm step, 0.06 cells, was refused with 70 of its 103 frames.)
WRONG_LATTICE_SCATTER_CELLS = 0.05


def _disagree(res_a, res_b, k: int) -> tuple[bool, float]:
    """Whether one side's residuals scatter about the joint path far more than the
    other's (an F test at :data:`SCATTER_TEST_LEVEL`, both floored at
    :data:`MIN_SCATTER_M`), and the noisier side's RMS scatter (m, per coordinate).

    The two sides are one tracker on one video: rows that scatter (robustly) by centimetres
    where the others keep to a millimetre are not a segment a whole number of cells
    off but a lattice that was not right (a camcorder's first fields at 0.5 Mbit/s: four
    rows 45, 3, 5 and -43 mm off the path, their mean 0.2 cells from a whole one, were
    re-anchored, and the origin fitted through them put every row of the shot 43 mm
    off).  The path's ``k`` parameters are shared out by the sides' sizes.
    """
    from scipy import stats

    na, nb = len(res_a), len(res_b)
    da = max(na - k * na / (na + nb), 1.0)
    db = max(nb - k * nb / (na + nb), 1.0)
    # robust scales (one glitching row is not a wrong lattice: a strong wide-angle
    # clip's segment with one row 9 mm off, the rest at 1 mm, was right to 0.5 mm)
    va = max(robust_sigma(np.ravel(res_a), centre=0.0) ** 2 * na / da, MIN_SCATTER_M ** 2)
    vb = max(robust_sigma(np.ravel(res_b), centre=0.0) ** 2 * nb / db, MIN_SCATTER_M ** 2)
    f = max(va / vb, vb / va)
    d1, d2 = (2 * da, 2 * db) if va > vb else (2 * db, 2 * da)
    # (the size of the noisier side's scatter with its outliers: a lattice that is not
    # right may leave half its rows on the path)
    noisier = float(np.sqrt(max(np.mean(np.square(res_a)), np.mean(np.square(res_b)))))
    return bool(2 * stats.f.sf(f, d1, d2) < SCATTER_TEST_LEVEL), noisier


def _side(t, p, sel_ref, sel_seg, before, st, cell_m: float = 0.0):
    """Reference and segment samples on one side of the segment's gap, or None."""
    tr, ts = t[sel_ref], t[sel_seg]
    if before:
        ref = sel_ref & (t < ts.min())
        if not ref.any():
            return None
        t_near = t[ref].max()
        ref &= t >= t_near - st.segment_window_s
        seg = sel_seg & (t <= ts.min() + st.segment_window_s)
        gap = ts.min() - t_near
    else:
        ref = sel_ref & (t > ts.max())
        if not ref.any():
            return None
        t_near = t[ref].min()
        ref &= t <= t_near + st.segment_window_s
        seg = sel_seg & (t >= ts.max() - st.segment_window_s)
        gap = t_near - ts.max()
    del tr
    n_min = st.segment_min_side_frames
    if ref.sum() < n_min or seg.sum() < n_min or gap > st.segment_max_gap_s:
        return None
    return path_step(t[ref], p[ref], t[seg], p[seg], cell_m)


#: A placed segment whose path step misses a whole number of cells by more than this
#: many of its sigmas (in a coordinate) has a lattice off by that much against the
#: reference's: :func:`resolve_segments` gives it as the segment's ``misfit``
MISFIT_Z = 3.0


def resolve_segments(t, p, segment, ok, spacing_m, settings: TrackingSettings | None = None,
                     reference=None, misfit: bool = False):
    """Whole-cell offsets of the grid's segments, from the rock's path.

    Parameters
    ----------
    t : (N,) array
        Frame times (s).
    p : (N, 2) array
        Rock positions on the ice in the lattice frame (m), NaN where not measured.
    segment : (N,) int array
        Grid segment of each frame (:attr:`GridPose.segment`).
    ok : (N,) bool array
        Measured frames.
    spacing_m : (float, float)
        Thread spacings along the lattice's x and y (m).
    settings : TrackingSettings, optional
        The ``segment_*`` thresholds (default: the defaults).
    reference : int, optional
        The segment whose cell index the others are put in (default: the one with most
        measured frames).
    misfit : bool
        Also return each frame's ``misfit`` (N, 2; m): for the frames of a placed
        segment, how far its path step misses the whole cells it was moved by, in each
        coordinate where that is beyond :data:`MISFIT_Z` sigma (0 elsewhere): its
        lattice is not the reference's (a phone's first 5 frames, then 7 lost: 12.4 +-
        2.8 mm, every later row 13 mm off through the origin those 5 frames placed).

    Returns
    -------
    shift : (N, 2) array
        Add to ``p`` (and to the frame's lattice frame) to put every resolved segment in
        the reference segment's cell index.
    unresolved : (N,) bool array
        Measured frames of segments whose offset the path does not tell.
    notes : list of str
        One line per segment moved or left unresolved.
    misfit : (N, 2) array
        With ``misfit=True`` (see above).
    """
    st = TrackingSettings() if settings is None else settings
    t = np.asarray(t, float)
    p = np.asarray(p, float)
    ok = np.asarray(ok, bool)
    segment = np.asarray(segment)
    s = np.asarray(spacing_m, float)
    shift = np.zeros((len(t), 2))
    miss = np.zeros((len(t), 2))
    ids, counts = np.unique(segment[ok], return_counts=True)
    if len(ids) < 2:
        return (shift, np.zeros(len(t), bool), []) + ((miss,) if misfit else ())
    resolved = {ids[np.argmax(counts)] if reference is None else reference}
    pending = set(ids) - resolved
    notes = []
    q = p.copy()
    progress = True
    while pending and progress:
        progress = False
        sel_ref = ok & np.isin(segment, list(resolved))
        # nearest to the resolved frames first
        order = sorted(pending, key=lambda i: np.min(np.abs(
            t[ok & (segment == i)][:, None] - t[sel_ref][None, :])))
        for sid in order:
            sel_seg = ok & (segment == sid)
            steps = [r for before in (True, False)
                     if (r := _side(t, q, sel_ref, sel_seg, before, st, float(s.min())))
                     is not None]
            if not steps:
                continue
            frames = np.flatnonzero(sel_seg)
            k = None
            for step, sigma in steps:
                cells = -step / s
                kk = np.round(cells)
                if (np.all(np.abs(cells - kk) <= st.segment_max_fraction)
                        and np.all(sigma / s <= st.segment_max_sigma_cells)
                        and (k is None or np.array_equal(k, kk))):
                    k = kk
                else:
                    k = False
                    break
            if k is None or k is False:
                continue
            for step, sigma in steps:
                left = np.abs(step + k * s)   # (the step's miss of the whole cells)
                miss[frames] = np.maximum(miss[frames],
                                          np.where(left > MISFIT_Z * sigma, left, 0.0))
            shift[frames] = k * s
            q[frames] += k * s
            resolved.add(sid)
            pending.discard(sid)
            if np.any(k != 0):
                notes.append(f"frames {t[frames[0]]:.3f}-{t[frames[-1]]:.3f} s: cell index "
                             f"re-anchored on the rock's path by {int(k[0]):+d}, "
                             f"{int(k[1]):+d} cells")
            progress = True
            break
    unresolved = ok & np.isin(segment, list(pending))
    return (shift, unresolved, notes) + ((miss,) if misfit else ())
