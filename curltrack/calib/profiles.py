"""Measure thread positions only where the threads are predicted: short cross profiles.

For every visible thread of the predicted lattice, points are spaced along it (avoiding
crossings); at each point the image is sampled (bilinear) on a short segment across the
thread.  The local background is the straight line through the segment's ends; the
thread signal is the background-subtracted profile projected on the thread's expected
colour contrast.  Consecutive profiles over ~40 px of a thread are averaged; the
centroid of the averaged signal (above 30 % of its peak, so a motion-blurred box profile
is centred as well as a sharp one) is a sub-pixel point on the thread, at the profiles'
mean position.

This reads well under 1 % of a frame's pixels (~300 points of two 15-sample profiles
each, a budget the caller sets), one ``cv2.remap`` for all of them.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np

from .._stats import median, robust_sigma
from .lattice import centre_jacobian
from .lens import apply_h, project, undistort


BOX = 0.25
#: A predicted lattice whose homogeneous scale varies over the frame by more than this
#: factor (a horizon in or near the view: a camera tilted ~60 deg, or a diverged fit)
#: is not sampled.
MAX_PERSPECTIVE = 0.25
_REMAP_COLUMNS = 32000


def _box(a, k):
    """Moving average of width ``k`` samples along axis 1 (same length, edges shrink)."""
    c = np.cumsum(np.pad(a, ((0, 0), (1, 0))), axis=1)
    n = a.shape[1]
    lo = np.clip(np.arange(n) - k // 2, 0, n)
    hi = np.clip(np.arange(n) + (k - k // 2), 0, n)
    return (c[:, hi] - c[:, lo]) / (hi - lo)


@functools.lru_cache(maxsize=8)
def _frame_edge(w, h, K_flat, dist):
    """Points along the frame's border, undistorted and normalised (the same every
    frame of a video, hence cached)."""
    K = np.reshape(K_flat, (3, 3))
    corners = np.array([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]], float)
    edge = np.concatenate([np.linspace(corners[i], corners[(i + 1) % 4], 16)
                           for i in range(4)])
    q = (undistort(edge, K, dist) - K[:2, 2]) / K[0, 0]
    q.setflags(write=False)
    return q


def _group_columns(a, starts):
    """Sums of consecutive columns of ``a`` (S, N) from each of ``starts`` to the next,
    transposed: a C-contiguous float32 (G, S) array."""
    return np.ascontiguousarray(np.add.reduceat(a, starts, axis=1, dtype=np.float32).T)


@functools.lru_cache(maxsize=8)
def _unit_steps(n):
    """``n`` evenly spaced float32 values from 0 to 1 (read-only; cached)."""
    out = np.linspace(0.0, 1.0, n, dtype=np.float32)
    out.setflags(write=False)
    return out


def _lattice_to_px(Hc_inv, K, dist, ab):
    """Lattice coordinates (cells) -> (undistorted normalised q, observed px)."""
    q = apply_h(Hc_inv, ab)
    return q, project(q, K, dist)


def _across(Hc_inv, K, dist, ab, fam, cells=0.02):
    """Points on the threads and the way across them, from lattice coordinates.

    Returns ``q`` (N, 2) undistorted normalised coordinates, ``px`` (N, 2) observed
    pixels, ``u`` (N, 2) the unit image direction in which the thread index grows,
    ``dq`` (N, 2) the change of ``q`` per observed pixel along ``u`` (all NaN-free:
    points that do not map are returned far outside the image), and ``finite`` (N,).
    """
    n = len(ab)
    ab2 = np.concatenate([ab, ab])
    ab2[np.arange(n, 2 * n), fam] += cells
    q2, px2 = _lattice_to_px(Hc_inv, K, dist, ab2)
    q, px = q2[:n], px2[:n]
    d = px2[n:] - px
    norm = np.hypot(d[:, 0], d[:, 1])[:, None]
    finite = np.isfinite(norm[:, 0]) & (norm[:, 0] > 0)  # (a point that did not map, too)
    if finite.all():
        return q, px, d / norm, (q2[n:] - q) / norm, finite
    norm = np.where(finite[:, None], norm, 1.0)
    u = np.where(finite[:, None], d / norm, 0.0)
    dq = np.where(finite[:, None], (q2[n:] - q) / norm, 0.0)
    q, px = np.where(finite[:, None], q, 0.0), np.where(finite[:, None], px, -1e6)
    return q, px, u, dq, finite


@dataclass
class ThreadPoints:
    """Sub-pixel thread points of one frame (one per averaged stretch of thread).

    Attributes
    ----------
    xy : (N, 2) ndarray
        Observed thread points (px).
    q : (N, 2) ndarray
        The same points undistorted and normalised, ``(x_u - c) / f``.
    w : (N,) ndarray
        Weights (signal area).
    fam, idx : (N,) int ndarray
        Thread family (0/1) and index.
    noise : float
        Robust noise of the detection signal.
    n_profiles : int
        Stretches of thread sampled (found or not).
    found : list of float
        Fraction of the sampled stretches of family 0 / 1 where a thread was found.
    """

    xy: np.ndarray
    q: np.ndarray
    w: np.ndarray
    fam: np.ndarray
    idx: np.ndarray
    noise: float
    n_profiles: int
    found: list
    _colour_of: object = field(default=None, repr=False)
    _stretches: tuple = field(default=(), repr=False)  # (fam, line, found) of every stretch

    def found_best_class(self, n: int) -> list:
        """As ``found``, for the threads of one class of index modulo ``n`` - the class
        whose threads were found most often: with ``n`` thread colours in sequence, the
        fraction of the best-seen colour (one colour may be faint against the ice)."""
        if n < 2 or not self._stretches:
            return self.found
        fam, line, hit = self._stretches
        cls = np.mod(line, n).astype(np.intp) + n * fam
        rate = (np.bincount(cls, hit, minlength=2 * n)
                / np.maximum(np.bincount(cls, minlength=2 * n), 1)).reshape(2, n)
        return rate.max(axis=1).tolist()

    @functools.cached_property
    def colour(self):
        """(N, k) contrast at each point projected on each thread colour's direction
        (None without a colour model); computed on first use."""
        return None if self._colour_of is None else self._colour_of()


def _positions_along(lo, hi, step, gap):
    """Profile positions (cells of the crossing family) along the threads, from ``lo``
    to ``hi``: about one per ``step`` cells, each in the clear part of its cell (more
    than ``gap`` cells from the crossing threads), locked to the lattice.

    Positions stepped from an origin drift against the crossings when the step is not a
    whole number of cells (18 px steps on 17.6 px cells: half the thread's length fell
    on crossings and was never sampled), and counted from the frame's edge they can all
    fall on crossings (the coarse snap's 40 px on 40 px cells).
    """
    clear = 1.0 - 2.0 * gap
    cells = np.arange(np.floor(lo), hi)
    if clear <= 0:
        return cells[:0]
    if step >= 1.0:  # one mid-cell profile every so many cells
        every = int(round(step))
        return cells[np.mod(cells, every) == 0] + 0.5
    n = max(1, int(round(1.0 / step)))  # this many per cell, spread over its clear part
    return (cells[:, None] + gap + (np.arange(n) + 0.5) * clear / n).ravel()


#: Candidate profiles per family, in units of the budget, beyond which positions along
#: the threads are thinned evenly before being projected through the lens.
PRE_THIN = 4

#: Fewest stretches (or, on a thread averaged whole, profiles) kept along each thread
#: when the frame holds more profiles than wanted: both ends and the middle, so that
#: every thread's direction is measured, not only its offset.
MIN_SPREAD = 3


def _line_starts(fam, line):
    """True where a new thread starts in profiles ordered by family and thread."""
    return np.concatenate(([True], (fam[1:] != fam[:-1]) | (line[1:] != line[:-1])))


def _rank_within(first):
    """(rank, size) of each element within its run, runs starting where ``first``."""
    start = np.flatnonzero(first)
    size = np.diff(np.append(start, len(first)))
    return np.arange(len(first)) - np.repeat(start, size), np.repeat(size, size)


def _spread_evenly(fam, line, along, seg_cells, whole, usable, max_profiles):
    """Which profiles to sample when the frame holds more than ``max_profiles``.

    On every thread, an evenly spread selection of its usable stretches of
    ``seg_cells`` (of its single profiles when ``whole``) that always includes both
    ends of what it shows and at least :data:`MIN_SPREAD` of them.  A selection by
    stretch index alone, the same for every thread, can alias with the gaps left at
    the crossing threads and keep one band across a family: then the threads'
    direction is not measured, and the lattice's shear drifts from frame to frame
    (a 640x360 view of 22 px cells read the travel 11 % long).

    Profiles come ordered by family, thread and position along it; returns a mask
    over all of them (False where not ``usable``).
    """
    keep = usable.copy()
    n_usable = int(np.count_nonzero(usable))
    if not max_profiles or n_usable <= max_profiles:
        return keep
    idx = np.flatnonzero(usable)
    f, ln, al = fam[idx], line[idx], along[idx]
    unit = np.where(whole[f], np.arange(len(idx), dtype=float),
                    np.floor(al / seg_cells[f]))
    first_of_line = _line_starts(f, ln)
    new_unit = first_of_line | np.concatenate(([True], unit[1:] != unit[:-1]))
    unit_id = np.cumsum(new_unit) - 1
    first_unit = first_of_line[new_unit]  # (a thread's first unit)
    rank, n_units = _rank_within(first_unit)
    m = np.minimum(n_units, np.maximum(MIN_SPREAD,
                                       np.rint(max_profiles / n_usable * n_units)))
    # a fine lattice, more threads in view than the budget holds at MIN_SPREAD each:
    # every so many threads of each family (any of them measures its direction)
    expected = float(m[first_unit].sum()) * len(idx) / len(first_unit)  # (profiles)
    every = int(np.ceil(expected / max_profiles)) if expected > 1.25 * max_profiles else 1
    if every > 1:
        m = np.where(np.mod(ln[new_unit], every) == 0, m, 0)
    # m points from both ends inclusive: rank r is one of them when rounding it to the
    # nearest of the m and back gives r (steps over 1, so each r maps to one point)
    step = (n_units - 1) / np.maximum(m - 1, 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        chosen = np.rint(np.rint(rank / step) * step) == rank
    chosen = (chosen | (n_units == 1)) & (m > 0)
    keep[idx] = chosen[unit_id]
    return keep


def _segment_of(fam, line, along, seg_cells, whole):
    """Segment index of each profile along its thread: stretches of ``seg_cells``; on a
    thread averaged whole (a family blurred across), its two halves (by profile count),
    so that such a thread still gives two points and its direction is measured."""
    seg = np.floor(along / seg_cells[fam])
    if not whole.any():
        return seg
    rank, size = _rank_within(_line_starts(fam, line))
    return np.where(whole[fam], (2 * rank >= size).astype(float), seg)


def sample_threads(image_bgr, Hc, K, dist, model, half_px, step_px: float = 10.0,
                   mask=None, margin_px: float = 3.0,
                   gap_px=(4.0, 4.0), blur_px=(0.0, 0.0), seg_px: float = 40.0,
                   max_profiles: int | None = None, max_radius_px: float | None = None):
    """Sub-pixel thread points of a frame near the predicted lattice ``Hc``.

    Parameters
    ----------
    image_bgr : (H, W, 3) uint8
    Hc : (3, 3)
        Predicted homography normalised-undistorted px -> cells.
    K, dist :
        Lens model.
    model : ColourModel
        Thread contrast directions (None = colour-agnostic).
    half_px : (float, float)
        Half-length (px) of the cross profiles of family A / B (prediction error plus
        blur plus thread width).
    step_px : float
        Spacing of the profiles along a thread (px).
    gap_px : (float, float)
        No profile closer than this (px) to a thread of family A / B crossing it
        (thread width plus motion blur).
    blur_px : (float, float)
        Expected motion-blur length across the threads of family A / B (px): the
        threads are found on profiles smoothed by a box a quarter this long, and
        averaged over each half of a thread when it exceeds 6 px (a smeared thread
        is faint; two points, so that its direction is still measured).
    seg_px : float
        Length (px) of thread over which consecutive profiles are averaged into one
        point.
    max_profiles : int, optional
        About the largest number of profiles wanted: when the frame holds more, only an
        evenly spread fraction of each thread's segments is sampled (fewer points, each
        as good), or of the profiles of a thread averaged by halves; always both ends
        of every thread (:func:`_spread_evenly`).
    mask : (H, W) uint8, optional
        Nonzero = ignore.
    max_radius_px : float, optional
        Only profiles within this distance (px) of the principal point (the part of a
        wide-angle lens the calibration confirmed, ``Calibration.lens_radius_px``).

    Returns
    -------
    ThreadPoints or None
        None when the prediction maps no thread into the image.
    """
    import cv2

    h, w = image_bgr.shape[:2]
    f = K[0, 0]
    q_edge = _frame_edge(w, h, tuple(K.ravel()), tuple(dist))
    # the homogeneous scale over the frame: a horizon in (or near) the view means a
    # degenerate prediction (a diverged fit) that would map the frame onto endless threads
    w_edge = q_edge @ Hc[2, :2] + Hc[2, 2]
    if not (w_edge.min() * w_edge.max() > 0
            and np.abs(w_edge).min() > MAX_PERSPECTIVE * np.abs(w_edge).max()):
        return None
    ab_edge = apply_h(Hc, q_edge)
    if not np.all(np.isfinite(ab_edge)):
        return None  # a degenerate prediction (the view folds over): nothing to sample
    lo, hi = ab_edge.min(axis=0), ab_edge.max(axis=0)
    if np.any(hi - lo > 1000):
        return None
    Hc_inv = np.linalg.inv(Hc)
    J = centre_jacobian(Hc)
    p_cell = f / np.linalg.norm(J, axis=1)  # px per cell, families A, B
    # Profiles: on every thread line in view, every step_px along it (clear of the
    # crossing threads), ordered by family, thread, position along the thread.
    whole = np.asarray(blur_px) >= 6.0
    seg_cells = seg_px / p_cell[::-1]  # (along each family)
    step_cells = step_px / p_cell[::-1]  # profile spacing along each family's threads
    pts, fams = [], []
    for fam in (0, 1):
        other = 1 - fam
        lines = np.arange(np.ceil(lo[fam]), np.floor(hi[fam]) + 1)
        along = _positions_along(lo[other], hi[other], step_cells[fam],
                                 gap_px[other] / p_cell[other])
        if max_profiles and len(lines) * len(along) > PRE_THIN * max_profiles:
            # (a fine lattice in a large frame: every n-th position and both ends
            # before the lens projection, which the budget below thins again)
            n = len(along)
            stride = int(np.ceil(len(lines) * n / (PRE_THIN * max_profiles)))
            along = along[np.unique(np.r_[np.arange(0, n, stride), n - 1])]
        ab = np.empty((len(lines), len(along), 2))
        ab[:, :, fam] = lines[:, None]
        ab[:, :, other] = along
        pts.append(ab.reshape(-1, 2))
        fams.append(np.full(len(pts[-1]), fam))
    ab = np.concatenate(pts)
    if len(ab) == 0:
        return None
    fam = np.concatenate(fams)
    _, centre, dirv, _, finite = _across(Hc_inv, K, dist, ab, fam)
    half = np.asarray(half_px, float)[fam]
    lim = half + margin_px
    inside = finite & (centre[:, 0] > lim) & (centre[:, 0] < w - 1 - lim) \
        & (centre[:, 1] > lim) & (centre[:, 1] < h - 1 - lim)
    if max_radius_px is not None:  # (where the lens model is confirmed)
        inside &= np.hypot(centre[:, 0] - K[0, 2], centre[:, 1] - K[1, 2]) < max_radius_px
    if mask is not None:
        rows_in = np.flatnonzero(inside)
        ci = np.rint(centre[rows_in]).astype(np.intp)  # (inside the image)
        inside[rows_in] = mask[ci[:, 1], ci[:, 0]] == 0
    line, along = np.where(fam, ab[:, 1], ab[:, 0]), np.where(fam, ab[:, 0], ab[:, 1])
    inside &= _spread_evenly(fam, line, along, seg_cells, whole, inside, max_profiles)
    ab, fam, centre = ab[inside], fam[inside], centre[inside]
    dirv, half, line, along = dirv[inside], half[inside], line[inside], along[inside]
    if len(ab) == 0:
        return None
    dt_px = max(1.0, max(half_px) / 10.0)  # <= 21 samples per profile
    n_s = int(np.ceil(max(half_px) / dt_px)) * 2 + 1
    frac = _unit_steps(n_s)
    t = (2.0 * frac - 1.0) * half[:, None].astype(np.float32)  # px along the profile
    # (sample-major: remap is much faster on a few long rows than on many short ones)
    c32, d32, tT = centre.astype(np.float32).T, dirv.astype(np.float32).T, t.T
    mx, my = c32[0] + tT * d32[0], c32[1] + tT * d32[1]
    # (S, N, 3) uint8; OpenCV's remap takes maps under 32767 columns
    prof = np.concatenate([cv2.remap(image_bgr, mx[:, i:i + _REMAP_COLUMNS],
                                     my[:, i:i + _REMAP_COLUMNS], cv2.INTER_LINEAR)
                           for i in range(0, mx.shape[1], _REMAP_COLUMNS)], axis=1)
    # Consecutive profiles of a thread are averaged over segments (longer when blurred:
    # a smeared thread is faint in any one profile but straight over a long stretch).
    # The profiles come ordered by family, thread and position along it.
    # (|line| < 1000 cells and segment indices are small integers: one exact float key)
    key = (fam * 4096.0 + line) * 2.0 ** 24 + _segment_of(fam, line, along, seg_cells, whole)
    starts = np.flatnonzero(np.concatenate(([True], key[1:] != key[:-1])))
    ends = np.append(starts[1:], len(key))
    counts = ends - starts
    inv_counts = (1.0 / counts).astype(np.float32)[:, None]
    # The thread signal: the profile less the straight line through its two ends.
    if model.directions is None:
        pf = prof.astype(np.float32)
        base = pf[:2].mean(axis=0)
        diff = pf - base - (pf[-2:].mean(axis=0) - base) * frac[:, None, None]
        sig = _group_columns(np.sqrt(np.einsum("snc,snc->sn", diff, diff)), starts)
        sig *= inv_counts
    else:
        # One linear projection on the mean contrast direction of the thread colours for
        # finding the threads (the colours are told apart later, at the peaks only);
        # linear, so the members are averaged first.
        d = model.directions.mean(axis=0)
        raw = cv2.transform(prof.astype(np.float32), (d / np.linalg.norm(d))[None])
        sig = _group_columns(raw, starts) * inv_counts
        b0 = 0.5 * (sig[:, 0] + sig[:, 1])
        sig -= b0[:, None] + (0.5 * (sig[:, -1] + sig[:, -2]) - b0)[:, None] * frac
    # The averaged profile measures the thread's offset at the members' mean position:
    # that point of the predicted thread (a straight line in lattice coordinates).
    cum = np.concatenate(([0.0], np.cumsum(along)))
    fam, t, line = fam[starts], t[starts], line[starts]
    rows = np.arange(len(starts))
    ab_g = np.empty((len(starts), 2))
    ab_g[rows, fam] = line
    ab_g[rows, 1 - fam] = (cum[ends] - cum[starts]) / counts
    q_g, centre, dirv, dq, _ = _across(Hc_inv, K, dist, ab_g, fam)
    # Find the thread on a copy smoothed by the blur length (merges the ghosts of a
    # smeared thread), take the centroid of the unsmoothed signal over the run found.
    n_a = int(np.searchsorted(fam, 1))  # (rows ordered by family: A, then B)
    fam_rows = (slice(0, n_a), slice(n_a, None))
    det = sig.copy()
    for j in (0, 1):
        k = int(round(BOX * blur_px[j] * (n_s - 1) / (2.0 * half_px[j])))
        rows_j = fam_rows[j]
        if k >= 2 and len(sig[rows_j]):
            det[rows_j] = _box(sig[rows_j], k)
    kpk = det.argmax(axis=1)
    peak = det[rows, kpk]
    # the contiguous run above 30 % of the peak that contains the peak
    above = det >= 0.3 * peak[:, None]
    run = np.cumsum(~above, axis=1)
    keep = above & (run == run[rows, kpk][:, None])
    # noise of the detection signal away from the run found (and from the window ends,
    # which define the baseline)
    kw = max(3, min(9, n_s // 4))
    away = cv2.boxFilter(keep.astype(np.float32), -1, (kw, 1), normalize=False,
                         borderType=cv2.BORDER_CONSTANT) == 0
    away[:, :2] = away[:, -2:] = False
    # (windows too short to see background beside the thread: no noise criterion; the
    # relative one below still drops occluded and empty stretches)
    noise = np.zeros(2)
    rel_floor = np.zeros(2)
    for j in (0, 1):
        rows_j = fam_rows[j]
        if len(peak[rows_j]):
            aj = away[rows_j]
            if np.count_nonzero(aj) > 0.1 * aj.size:
                noise[j] = robust_sigma(det[rows_j][aj], centre=0.0) + 1e-3
            rel_floor[j] = 0.25 * median(peak[rows_j])
    floor = 0.3 * sig.max(axis=1, where=keep, initial=0.0)
    s = np.where(keep, np.maximum(sig - floor[:, None], 0.0), 0.0)
    s_sum = s.sum(axis=1)
    off = (s * t).sum(axis=1) / np.maximum(s_sum, 1e-9)
    sel = (peak > np.maximum(4.0 * noise, rel_floor)[fam]) & (kpk > 1) & (kpk < n_s - 2)
    colour_of = None
    if model.directions is not None:
        def colour_of():
            # contrast (BGR) of each member profile at its group's peak, projected on
            # each thread colour's direction, summed over the group
            pk = prof[np.repeat(kpk, counts), np.arange(prof.shape[1])].astype(np.float32)
            ends = 0.25 * (prof[:2].sum(axis=0, dtype=np.float32)
                           + prof[-2:].sum(axis=0, dtype=np.float32))
            c = np.add.reduceat((pk - ends) @ model.directions.T.astype(np.float32), starts)
            return c[sel]

    found = np.bincount(fam, sel, minlength=2) / np.maximum(np.bincount(fam, minlength=2), 1)
    return ThreadPoints(xy=(centre + off[:, None] * dirv)[sel],
                        q=(q_g + off[:, None] * dq)[sel],
                        w=(s_sum * counts)[sel], fam=fam[sel], idx=line[sel].astype(int),
                        noise=float(np.max(noise)), n_profiles=int(len(sel)),
                        found=found.tolist(), _colour_of=colour_of,
                        _stretches=(fam, line, sel))
