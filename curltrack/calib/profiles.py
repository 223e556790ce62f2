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

import numpy as np

from .lens import apply_h, distort


def _lattice_to_px(Hc_inv, K, dist, ab):
    q = apply_h(Hc_inv, ab)
    return distort(K[:2, 2] + K[0, 0] * q, K, dist)


def sample_threads(image_bgr, Hc, K, dist, model, half_px, step_px: float = 10.0,
                   mask=None, colors_known: bool = False, margin_px: float = 3.0,
                   gap_px=(4.0, 4.0)):
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
    mask : (H, W) uint8, optional
        Nonzero = ignore.
    colors_known : bool
        Project on the colour that thread ``i`` must have (``i mod n``); otherwise on the
        best-matching colour.

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
    corners = np.array([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]], float)
    edge = np.concatenate([np.linspace(corners[i], corners[(i + 1) % 4], 16)
                           for i in range(4)])
    from .lens import undistort

    ab_edge = apply_h(Hc, (undistort(edge, K, dist) - K[:2, 2]) / f)
    lo, hi = ab_edge.min(axis=0), ab_edge.max(axis=0)
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
    centre = _lattice_to_px(Hc_inv, K, dist, ab)
    eps = np.zeros_like(ab)
    eps[fam == 0, 0] = 0.02
    eps[fam == 1, 1] = 0.02
    dirv = _lattice_to_px(Hc_inv, K, dist, ab + eps) - centre
    dirv /= np.linalg.norm(dirv, axis=1, keepdims=True)
    half = np.where(fam == 0, half_px[0], half_px[1])
    inside = ((centre[:, 0] > half + margin_px) & (centre[:, 0] < w - 1 - half - margin_px)
              & (centre[:, 1] > half + margin_px) & (centre[:, 1] < h - 1 - half - margin_px))
    if mask is not None:
        ci = np.round(centre).astype(int)
        ok_idx = inside.copy()
        ci = np.clip(ci, 0, [w - 1, h - 1])
        ok_idx &= mask[ci[:, 1], ci[:, 0]] == 0
        inside = ok_idx
    centre, dirv, fam, idx, half = centre[inside], dirv[inside], fam[inside], idx[inside], half[inside]
    if len(centre) == 0:
        return None
    n_s = int(np.ceil(max(half_px))) * 2 + 1
    t = np.linspace(-1.0, 1.0, n_s)[None, :] * half[:, None]  # px along the normal
    mx = (centre[:, 0:1] + t * dirv[:, 0:1]).astype(np.float32)
    my = (centre[:, 1:2] + t * dirv[:, 1:2]).astype(np.float32)
    prof = cv2.remap(image_bgr, mx, my, cv2.INTER_LINEAR).astype(np.float32)  # (N, S, 3)
    base0 = prof[:, :2].mean(axis=1)
    base1 = prof[:, -2:].mean(axis=1)
    frac = np.linspace(0.0, 1.0, n_s)[None, :, None]
    diff = prof - (base0[:, None] * (1 - frac) + base1[:, None] * frac)
    if model.directions is None:
        sig = np.sqrt(diff[:, :, 0] ** 2 + diff[:, :, 1] ** 2 + diff[:, :, 2] ** 2)
        proj_all = None
    else:
        proj_all = diff @ model.directions.T.astype(np.float32)  # (N, S, k)
        if colors_known:
            sig = proj_all[np.arange(len(idx)), :, idx % model.directions.shape[0]]
        else:
            sig = np.maximum.reduce([proj_all[:, :, i] for i in range(proj_all.shape[2])])
    sig = np.maximum(sig, 0.0)
    peak = sig.max(axis=1)
    kpk = sig.argmax(axis=1)
    # centroid of the contiguous run above 30 % of the peak that contains the peak
    above = sig >= 0.3 * peak[:, None]
    run = np.cumsum(~above, axis=1)
    keep = above & (run == run[np.arange(len(kpk)), kpk][:, None])
    s = np.where(keep, sig - 0.3 * peak[:, None], 0.0)
    area = s.sum(axis=1)
    off = (s * t).sum(axis=1) / np.maximum(area, 1e-9)
    noise = float(np.median(np.abs(diff[:, :2] - diff[:, :2].mean(axis=1, keepdims=True))) * 1.4826
                  + 1e-3)
    edge_peak = (kpk <= 1) | (kpk >= n_s - 2)
    good = (peak > 4.0 * noise) & ~edge_peak
    xy = centre + off[:, None] * dirv
    colour = None
    if proj_all is not None:
        colour = proj_all[np.arange(len(kpk)), kpk]
    sel = good
    return {"xy": xy[sel], "w": area[sel], "fam": fam[sel], "idx": idx[sel],
            "colour": None if colour is None else colour[sel], "noise": noise,
            "n_profiles": int(len(sel)),
            "found": [float(np.mean(sel[fam == j])) if np.any(fam == j) else 0.0
                      for j in (0, 1)]}
