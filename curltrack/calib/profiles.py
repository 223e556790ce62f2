"""Measure thread positions only where the threads are predicted: short cross profiles.

For every visible thread of the predicted lattice, points are spaced along it (avoiding
crossings); at each point the image is sampled (bilinear) on a short segment across the
thread.  The local background is the straight line through the segment's ends; the
thread signal is the background-subtracted profile projected on the thread's expected
colour contrast.  Its centroid (above 30 % of its peak, so a motion-blurred box profile
is centred as well as a sharp one) is a sub-pixel point on the thread.

This touches a few percent of the pixels of a frame, which is what makes tracking
cheaper than decoding.
"""

from __future__ import annotations

import functools

import numpy as np

from ._stats import median
from .lens import apply_h, distort, undistort


BOX = 0.25


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


def _lattice_to_px(Hc_inv, K, dist, ab):
    q = apply_h(Hc_inv, ab)
    return distort(K[:2, 2] + K[0, 0] * q, K, dist)


def sample_threads(image_bgr, Hc, K, dist, model, half_px, step_px: float = 10.0,
                   mask=None, margin_px: float = 3.0,
                   gap_px=(4.0, 4.0), blur_px=(0.0, 0.0), seg_px: float = 40.0):
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
        averaged over whole threads when it exceeds 6 px (a smeared thread is faint).
    seg_px : float
        Length (px) of thread over which consecutive profiles are averaged into one
        point.
    mask : (H, W) uint8, optional
        Nonzero = ignore.

    Returns
    -------
    dict with ``xy`` (N, 2) observed thread points (px), ``w`` (N,) weights (signal
    area), ``fam`` (N,) 0/1, ``idx`` (N,) thread index, ``colour`` (N, k) projections of
    the peak's contrast on each colour direction (or None), ``noise`` (robust noise of
    the signal).
    """
    import cv2

    h, w = image_bgr.shape[:2]
    f = K[0, 0]
    Hc_inv = np.linalg.inv(Hc)
    ab_edge = apply_h(Hc, _frame_edge(w, h, tuple(K.ravel()), tuple(dist)))
    if not np.all(np.isfinite(ab_edge)):
        return None  # a degenerate prediction (the view folds over): nothing to sample
    lo, hi = ab_edge.min(axis=0), ab_edge.max(axis=0)
    if np.any(hi - lo > 1000):
        return None
    J = Hc[:2, :2] - np.outer(Hc[:2, 2], Hc[2, :2])
    p_cell = f / np.linalg.norm(J, axis=1)  # px per cell, families A, B
    pts, fams, idxs = [], [], []
    for fam in (0, 1):
        other = 1 - fam
        lines = np.arange(np.ceil(lo[fam]), np.floor(hi[fam]) + 1)
        ds = step_px / p_cell[other]
        along = np.arange(lo[other], hi[other], ds)
        gap = gap_px[other] / p_cell[other]  # stay clear of crossing threads
        along = along[np.abs(along - np.round(along)) > gap]
        if len(lines) == 0 or len(along) == 0:
            continue
        L, A = np.meshgrid(lines, along, indexing="ij")
        ab = np.empty((L.size, 2))
        ab[:, fam], ab[:, other] = L.ravel(), A.ravel()
        pts.append(ab)
        fams.append(np.full(L.size, fam))
        idxs.append(L.ravel())
    if not pts:
        return None
    ab = np.concatenate(pts)
    fam = np.concatenate(fams)
    idx = np.concatenate(idxs).astype(int)
    along = np.where(fam == 0, ab[:, 1], ab[:, 0])
    centre = _lattice_to_px(Hc_inv, K, dist, ab)
    eps = np.zeros_like(ab)
    eps[fam == 0, 0] = 0.02
    eps[fam == 1, 1] = 0.02
    dirv = _lattice_to_px(Hc_inv, K, dist, ab + eps) - centre
    norm = np.linalg.norm(dirv, axis=1, keepdims=True)
    finite = np.isfinite(centre).all(axis=1) & np.isfinite(norm[:, 0]) & (norm[:, 0] > 0)
    centre = np.where(finite[:, None], centre, -1e6)  # (outside the image below)
    dirv = np.where(finite[:, None], dirv / np.where(norm > 0, norm, 1.0), 0.0)
    half = np.where(fam == 0, half_px[0], half_px[1])
    inside = finite & ((centre[:, 0] > half + margin_px) & (centre[:, 0] < w - 1 - half - margin_px)
              & (centre[:, 1] > half + margin_px) & (centre[:, 1] < h - 1 - half - margin_px))
    if mask is not None:
        ok_idx = inside.copy()
        ci = np.clip(np.round(centre), 0, [w - 1, h - 1]).astype(int)
        ok_idx &= mask[ci[:, 1], ci[:, 0]] == 0
        inside = ok_idx
    centre, dirv, fam, idx, half, along = (centre[inside], dirv[inside], fam[inside],
                                           idx[inside], half[inside], along[inside])
    if len(centre) == 0:
        return None
    dt_px = max(1.0, max(half_px) / 10.0)  # <= 21 samples per profile
    n_s = int(np.ceil(max(half_px) / dt_px)) * 2 + 1
    t = np.linspace(-1.0, 1.0, n_s)[None, :] * half[:, None]  # px along the normal
    mx = (centre[:, 0:1] + t * dirv[:, 0:1]).astype(np.float32)
    my = (centre[:, 1:2] + t * dirv[:, 1:2]).astype(np.float32)
    prof = cv2.remap(image_bgr, mx, my, cv2.INTER_LINEAR)  # (N, S, 3) uint8
    frac = np.linspace(0.0, 1.0, n_s, dtype=np.float32)[None, :]
    if model.directions is None:
        pf = prof.astype(np.float32)
        b0, b1 = pf[:, :2].mean(axis=1), pf[:, -2:].mean(axis=1)
        diff = pf - (b0[:, None] * (1 - frac[..., None]) + b1[:, None] * frac[..., None])
        sig = np.sqrt(diff[:, :, 0] ** 2 + diff[:, :, 1] ** 2 + diff[:, :, 2] ** 2)
    else:
        # One linear projection on the mean contrast direction of the thread colours for
        # finding the threads (the colours are told apart later, at the peaks only).
        d = model.directions.mean(axis=0)
        d = (d / np.linalg.norm(d)).astype(np.float32)
        raw = cv2.transform(prof.reshape(-1, 1, 3).astype(np.float32), d[None, :])
        raw = raw.reshape(len(prof), n_s)
        b0, b1 = raw[:, :2].mean(axis=1), raw[:, -2:].mean(axis=1)
        sig = raw - (b0[:, None] * (1 - frac) + b1[:, None] * frac)
    # Average consecutive profiles of a thread over segments (longer when blurred: a
    # smeared thread is faint in any one profile but straight over a long stretch).
    # (a thread smeared over more than a few px is too faint for short segments: whole
    # visible threads then)
    seg_cells = np.array([(seg_px if blur_px[j] < 6.0 else 1e6) / p_cell[1 - j]
                          for j in (0, 1)])
    seg = np.floor(along / seg_cells[fam]).astype(np.int64)
    key = (fam.astype(np.int64) << 40) + ((idx.astype(np.int64) + (1 << 19)) << 20) \
        + (seg - seg.min())
    order = np.argsort(key, kind="stable")
    key_s = key[order]
    starts = np.nonzero(np.r_[True, key_s[1:] != key_s[:-1]])[0]
    counts = np.diff(np.r_[starts, len(key_s)])
    first = order[starts]

    def group(a):
        return np.add.reduceat(a[order], starts, axis=0)

    sig = group(sig) / counts[:, None]
    member_group = np.empty(len(key), np.int64)
    member_group[order] = np.repeat(np.arange(len(starts)), counts)
    # The averaged profile measures the thread's mean offset from the prediction, i.e.
    # the offset at the members' mean position along it: represent the group by the
    # member profile nearest that position (on the predicted, possibly curved, thread).
    mean_along = group(along) / counts
    gap_along = np.abs(along - mean_along[member_group])
    rep = np.lexsort((gap_along, member_group))
    rep = rep[np.r_[0, np.cumsum(counts)[:-1]]]
    centre, dirv = centre[rep], dirv[rep]
    fam, idx, t = fam[first], idx[first], t[first]
    # Find the thread on a copy smoothed by the blur length (merges the ghosts of a
    # smeared thread), take the centroid of the unsmoothed signal over the run found.
    det = sig.copy()
    for j in (0, 1):
        rows = fam == j
        if not rows.any():
            continue
        dtj = 2.0 * half_px[j] / (n_s - 1)
        k = int(round(BOX * blur_px[j] / dtj))
        if k >= 2:
            det[rows] = _box(sig[rows], k)
    peak = det.max(axis=1)
    kpk = det.argmax(axis=1)
    # the contiguous run above 30 % of the peak that contains the peak
    above = det >= 0.3 * peak[:, None]
    run = np.cumsum(~above, axis=1)
    keep = above & (run == run[np.arange(len(kpk)), kpk][:, None])
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
        dj = det[fam == j]
        if dj.size:
            aj = away[fam == j]
            if aj.sum() > 0.1 * aj.size:
                noise[j] = 1.4826 * median(np.abs(dj[aj])) + 1e-3
            rel_floor[j] = 0.25 * median(dj.max(axis=1))
    det = np.maximum(det, 0.0)
    sig = np.maximum(sig, 0.0)
    floor = 0.3 * sig.max(axis=1, where=keep, initial=0.0)
    s = np.where(keep, np.maximum(sig - floor[:, None], 0.0), 0.0)
    area = s.sum(axis=1) * counts
    off = (s * t).sum(axis=1) / np.maximum(s.sum(axis=1), 1e-9)
    edge_peak = (kpk <= 1) | (kpk >= n_s - 2)
    sel = (peak > np.maximum(4.0 * noise, rel_floor)[fam]) & ~edge_peak
    xy = centre + off[:, None] * dirv
    colour = None
    if model.directions is not None:
        # contrast (BGR) of each member profile at its group's peak, projected on each
        # thread colour's direction, summed over the group
        kk = kpk[member_group]
        rows = np.arange(len(prof))
        pk = prof[rows, kk].astype(np.float32)
        ends = 0.5 * (prof[:, :2].astype(np.float32).mean(axis=1)
                      + prof[:, -2:].astype(np.float32).mean(axis=1))
        colour = group((pk - ends) @ model.directions.T.astype(np.float32))
    noise = float(np.max(noise))
    return {"xy": xy[sel], "w": area[sel], "fam": fam[sel], "idx": idx[sel],
            "colour": None if colour is None else colour[sel], "noise": noise,
            "n_profiles": int(len(sel)),
            "found": [float(np.mean(sel[fam == j])) if np.any(fam == j) else 0.0
                      for j in (0, 1)]}
