"""Fit a lattice of two families of straight threads to thread pixels.

The model maps normalised undistorted pixel coordinates ``q = (undistort(p) - c) / f``
to lattice coordinates in *cells* ``(a, b)`` by a homography ``Hc``: family A threads lie
on integer ``a``, family B threads on integer ``b``.  Every thread pixel (not only the
crossings) enters the fit with its response as weight, so line positions are sub-pixel.

Steps: :func:`initial_lattice` finds the two periodic families in the 2-D spectrum of the
response (robust to faint threads), then :func:`fit_lattice` refines ``Hc`` (and, on a
calibration frame, the radial distortion) by weighted Gauss-Newton with robust weights,
growing the fitted region from the image centre so that perspective and distortion never
make a pixel jump to the neighbouring thread.
"""

from __future__ import annotations

import math

import numpy as np

from .._stats import median, robust_sigma
from .lens import apply_h, undistort

MIN_PERIOD_PX = 16.0  # shortest thread spacing looked for (px)
#: The two families' periods may differ from the rig's cell ratio by this (relative):
#: tilt and perspective change it by a few %.  Further off, the weaker family's period
#: is looked for within this of where the stronger one puts it.
PERIOD_RATIO_TOL = 0.08


def _fundamental_period(rel, w, normal, min_period, max_period, near=None):
    """Period (px) of the threads across ``normal``: first strong autocorrelation peak.

    The weighted histogram of the pixels' positions along the normal (0.5 px bins) of a
    set of parallel threads is periodic; its autocorrelation peaks at the period and its
    multiples.  Returns (period, normalised autocorrelation there), or None without a
    clear peak.  With ``near`` = (lo, hi) px: the strongest peak between those lags.
    """
    s = rel @ normal
    lo, hi = s.min(), s.max()
    if hi - lo < 2 * min_period:
        return None
    n_bins = len(np.arange(lo, hi + 0.5, 0.5)) - 1
    # (the histogram of equal 0.5 px bins from lo, the last one closed, by bincount)
    h = np.bincount(np.minimum(((s - lo) * 2.0).astype(np.intp), n_bins - 1), w,
                    minlength=n_bins)
    h = h - h.mean()
    n = 1 << int(np.ceil(np.log2(2 * len(h))))
    F = np.fft.rfft(h, n)
    ac = np.fft.irfft(F * np.conj(F), n)[:len(h)]
    ac /= np.arange(len(h), 0, -1)  # unbiased: fewer overlapping bins at long lags
    lags = np.arange(len(h)) * 0.5
    ok = (lags >= min_period) & (lags <= min(max_period, 0.5 * (hi - lo)))
    if not ok.any() or ac[0] <= 0:
        return None
    if near is not None:
        ok &= (lags >= near[0]) & (lags <= near[1])
        if ok.sum() < 3:
            return None
    idx = np.nonzero(ok)[0]
    top = ac[idx].max()
    if top < 0.2 * ac[0]:
        return None
    if near is not None:
        i = idx[np.argmax(ac[idx])]
        if i in (idx[0], idx[-1]):  # (a slope, not a peak)
            return None
        den = ac[i - 1] - 2 * ac[i] + ac[i + 1]
        d = 0.5 * (ac[i - 1] - ac[i + 1]) / den if den < 0 else 0.0
        return float((i + d) * 0.5), float(ac[i] / ac[0])
    for i in idx[1:-1]:
        if ac[i] >= 0.6 * top and ac[i] >= ac[i - 1] and ac[i] >= ac[i + 1]:
            # parabolic sub-bin refinement
            den = ac[i - 1] - 2 * ac[i] + ac[i + 1]
            d = 0.5 * (ac[i - 1] - ac[i + 1]) / den if den < 0 else 0.0
            return float((i + d) * 0.5), float(ac[i] / ac[0])
    return None


def _phasors(grid, x):
    """``exp(2 pi i g x)`` for an evenly spaced ``grid`` (n,) and points ``x`` (N,):
    (n, N), from two exponentials and powers of the step's factor."""
    out = np.empty((len(grid), len(x)), complex)
    out[0] = np.exp(2j * np.pi * grid[0] * x)
    if len(grid) > 1:
        step = np.exp(2j * np.pi * (grid[1] - grid[0]) * x)
        for i in range(1, len(grid)):
            np.multiply(out[i - 1], step, out=out[i])
    return out


def _refine_wavevector(xs, w, k, n_steps: int = 5):
    """Refine a wave vector (cycles/px) and its phase by maximising |sum w exp(2 pi i k.x)|."""
    best_z, best_k = -1.0, np.asarray(k, float)
    span = 0.02 * np.linalg.norm(k)
    for _ in range(3):
        kc = best_k
        grid = np.linspace(-span, span, n_steps)
        # all (dx, dy) of the grid at once: exp(2 pi i (k + d).x) factorises into the
        # centre's term times one factor per axis, so the sums are one matrix product
        e0 = w * np.exp(2j * np.pi * (xs @ kc))
        ex, ey = _phasors(grid, xs[:, 0]), _phasors(grid, xs[:, 1])
        Z = np.abs((ex * e0) @ ey.T)  # [dx index, dy index]
        i, j = np.unravel_index(np.argmax(Z), Z.shape)
        if Z[i, j] > best_z:
            best_z, best_k = Z[i, j], kc + (grid[i], grid[j])
        span /= n_steps - 1
    k = best_k
    z = np.sum(w * np.exp(2j * np.pi * (xs @ k)))
    return k, float(np.angle(z) / (2 * np.pi))


def initial_lattice(resp, xs, w, centre, cell_ratio: float = 1.0, n_guesses: int = 1):
    """Affine first guess of the lattice from the response's spectrum.

    Parameters
    ----------
    resp : (H, W) float
        Thread response (masked pixels set to 0).
    xs, w : (N, 2), (N,)
        Candidate thread pixels (distorted px) and weights.
    centre : (2,)
        Image centre (px).
    cell_ratio : float
        spacing_x / spacing_y of the rig: the two families' periods (px) must have about
        this ratio (either way round).
    n_guesses : int
        Pairs of families returned, strongest first (a square lattice's diagonals, a
        stack of crossings, can score as high as its threads: the caller tries the next
        when a fit fails).

    Returns
    -------
    list of (2, 3) float
        Up to ``n_guesses`` lattices whose rows map ``(x - cx, y - cy, 1)`` to cells
        ``a``, ``b``; empty if fewer than two periodic families were found.
    """
    import cv2

    h, wd = resp.shape
    # 16 px: closer threads (1-3 px wide, blurred) are not worth measuring, and image
    # artefacts are periodic at shorter scales (JPEG blocks at 8 px, tiled noise ~11 px)
    min_period, max_period = MIN_PERIOD_PX, min(h, wd) / 3.0
    # The spectrum is read below 1/16 cycles/px only: an image averaged over n x n px
    # blocks (n <= 4, the shortest period still >= 4 samples) has the same peaks at a
    # fraction of the cost; the frequency resolution (1/size of the image) is unchanged.
    n = int(np.clip(min(h, wd) // 256, 1, 4))
    small = resp if n == 1 else cv2.resize(np.asarray(resp, np.float32), (wd // n, h // n),
                                           interpolation=cv2.INTER_AREA)
    hs, ws = small.shape
    r = small - small.mean()
    F = np.fft.fftshift(np.fft.fft2(r * np.outer(np.hanning(hs), np.hanning(ws))))
    mag = np.abs(F)
    fy, fx = np.meshgrid(np.fft.fftshift(np.fft.fftfreq(hs, d=n)),
                         np.fft.fftshift(np.fft.fftfreq(ws, d=n)), indexing="ij")
    fr = np.hypot(fx, fy)
    mag[(fr > 1 / min_period) | (fr < 1 / max_period) | (fy < 0) | ((fy == 0) & (fx < 0))] = 0
    if mag.max() <= 0:
        return []
    bg = np.median(mag[mag > 0])
    rel = xs - centre
    near = np.hypot(*rel.T) < 0.3 * min(h, wd)
    if near.sum() < 50:
        near = np.ones(len(xs), bool)
    # Candidate directions: the strongest spectral peaks.  Each is judged by how periodic
    # the thread pixels are across it (image artefacts such as compression blocks have
    # spectral peaks too, but not a clean periodic stack of lines).
    from scipy.ndimage import maximum_filter

    peaks = (mag == maximum_filter(mag, size=5)) & (mag > 8 * bg)
    order = np.argsort(mag[peaks])[::-1][:12]
    cand = np.column_stack([fx[peaks], fy[peaks]])[order]
    found = []
    for k in cand:
        normal = k / np.linalg.norm(k)
        if any(abs(abs(normal @ n) - 1.0) < 1e-9 for n, _, _ in found):
            continue
        res = _fundamental_period(rel[near], w[near], normal, min_period, max_period)
        if res is None:
            res = _fundamental_period(rel, w, normal, min_period, max_period)
        if res is not None:
            # Exactly along an image axis: most likely the image's own grid (codec blocks,
            # resampling), which a real lattice matches only by chance: half weight.
            axis = min(abs(normal[0]), abs(normal[1])) < 1e-3
            found.append((normal, res[0], res[1] * (0.5 if axis else 1.0)))
    if not found:
        return []
    # A family whose spectral peak was not among the strongest (faint threads, a codec's
    # 16 px blocks stronger along the image axis) is looked for across the strongest
    # family: perpendicular to it, at the period the rig's cell ratio puts it.
    strongest = max(found, key=lambda c: c[2])
    perp = np.array([-strongest[0][1], strongest[0][0]])
    for r in sorted({cell_ratio, 1.0 / cell_ratio}):
        lag = strongest[1] * r
        res = _fundamental_period(rel[near], w[near], perp, min_period, max_period,
                                  (lag * (1 - PERIOD_RATIO_TOL), lag * (1 + PERIOD_RATIO_TOL)))
        if res is not None:
            found.append((perp, res[0], res[1]))
    # The best pair: nearly perpendicular (a rectangular lattice seen from above) with the
    # period ratio of the rig's cell (perspective and tilt change it by a few per cent).
    pairs = []
    for i, c1 in enumerate(found):
        for c2 in found[i + 1:]:
            ang = np.degrees(np.arccos(min(abs(c1[0] @ c2[0]), 1.0)))
            ratio = c1[1] / c2[1]
            if ang < 60.0 or not any(abs(np.log(ratio / r)) < 0.2 for r in
                                     (cell_ratio, 1.0 / cell_ratio)):
                continue
            pairs.append((c1[2] + c2[2], len(pairs), (c1, c2)))
    pairs = [p for _, _, p in sorted(pairs, key=lambda q: (-q[0], q[1]))]
    return [_pair_lattice(pair, rel[near], w[near], cell_ratio, min_period, max_period)
            for pair in pairs[:n_guesses]]


def _pair_lattice(pair, rel, w, cell_ratio, min_period, max_period):
    """The affine lattice (2, 3) of a pair of families (normal, period, score)."""
    # A family of faint threads (a weak colour, thin threads) can give its stack's
    # period a few px off: the rig's cell ratio, within what perspective and tilt change
    # (a few %), says where its period lies from the stronger family's; look there.
    strong, weak = sorted(pair, key=lambda c: -c[2])
    ratio = weak[1] / strong[1]
    target = min((cell_ratio, 1.0 / cell_ratio), key=lambda r: abs(np.log(ratio / r)))
    if abs(np.log(ratio / target)) > PERIOD_RATIO_TOL:
        lag = strong[1] * target
        window = (lag * (1 - PERIOD_RATIO_TOL), lag * (1 + PERIOD_RATIO_TOL))
        res = _fundamental_period(rel, w, weak[0], min_period, max_period, window)
        if res is not None:
            weak = (weak[0], res[0], weak[2])
    rows = []
    for normal, period, _ in (strong, weak):
        k, s = _refine_wavevector(rel, w, normal / period)
        rows.append([k[0], k[1], -s])
    return np.array(rows)


def assign_families(a, b, pa, pb, band_px, cross_px=None):
    """Split pixels into family A / B thread pixels with integer indices; crossings dropped.

    ``band_px`` (and ``cross_px``, default band + 1) may be a pair (family A, family B).
    """
    ba, bb = np.broadcast_to(np.asarray(band_px, float), (2,))
    ca, cb = (ba + 1.0, bb + 1.0) if cross_px is None else np.broadcast_to(
        np.asarray(cross_px, float), (2,))
    ia, ib = np.round(a), np.round(b)
    da, db = np.abs(a - ia) * pa, np.abs(b - ib) * pb
    fam_a = (da < ba) & (db > cb)
    fam_b = (db < bb) & (da > ca)
    return fam_a, fam_b, ia, ib


def centre_jacobian(Hc) -> np.ndarray:
    """d(a, b)/dq at q = 0 of a homography ``Hc`` (normalised undistorted px -> cells,
    ``Hc[2, 2]`` = 1): how the lattice coordinates change at the principal point."""
    Hc = np.asarray(Hc, float)
    return Hc[:2, :2] - np.outer(Hc[:2, 2], Hc[2, :2])


def periods_px(Hc, f):
    """Pixels per cell of families A and B at the image centre."""
    # |rows of J| with J = d(a, b)/dq at q = 0 = Hc[:2, :2] - Hc[:2, 2] Hc[2, :2]^T
    # (scalar arithmetic: called several times per frame on a 3x3)
    (h00, h01, h02), (h10, h11, h12), (h20, h21, _) = np.asarray(Hc, float).tolist()
    return (f / math.hypot(h00 - h02 * h20, h01 - h02 * h21),
            f / math.hypot(h10 - h12 * h20, h11 - h12 * h21))


LENS_PARAMS = ("k1", "k2", "cx", "cy")
STAGE_TOL_PX = 0.1  # a region-growing stage ends once a step moves no pixel this far
FINAL_TOL_PX = 0.01 # the fit on every pixel ends once a step moves none this far
#: (its steps shrink ~2x each: what is left is about the last one, 10x below the
#: 0.1 px the lens is held to)
#: A lens parameter is freed in a region-growing stage only once the region's radius
#: spans this many thread periods (besides ``free_from``'s fraction of the view): the
#: wide-angle schedule's fractions, validated on action cameras at 960x540 (periods of
#: 40-65 px), free k1 at 3-4 periods and k2 and the centre at 4-7; on a view only ~4
#: cells across (480x270, 0.3 m threads from 3 m) the same fractions freed them at 1.3
#: and 2.2 periods, k2 went to 2.1 and the fit landed on a lattice of half the period.
#: (5 periods for k2 held back a strong lens, f 471 px, k1 -0.26 at 63 px periods, one
#: stage too long: 0.77 px RMS, CI seed 2783739926.)
LENS_MIN_PERIODS = {"k1": 3.0, "k2": 4.0, "cx": 4.0, "cy": 4.0}
CENTRE_PRIOR_PX = 30.0  # weak prior: distortion centre within ~30 px of the image centre


def _lens_K(K, lens):
    K2 = K.copy()
    K2[0, 2], K2[1, 2] = lens[2], lens[3]
    return K2


def _normalised(xs, K, lens):
    K2 = _lens_K(K, lens)
    return (undistort(xs, K2, lens[:2]) - K2[:2, 2]) / K2[0, 0]


def _dq_dlens(xs, K, lens, q, which=(0, 1, 2, 3)):
    """d q / d (k1, k2, cx, cy) for normalised undistorted points ``q`` of observed
    pixels ``xs`` (N, 2) under ``lens``, analytic; (N, 2, len(which)) for the
    parameters ``which`` (indices into k1, k2, cx, cy).

    With ``d = (x - c) / f``, ``r_d = |d|`` and ``r (1 + k1 r^2 + k2 r^4) = r_d``:
    ``q = d r / r_d``, ``dr/dk1 = -r^3 / D``, ``dr/dk2 = -r^5 / D``, ``dr/dr_d = 1 / D``
    with ``D = 1 + 3 k1 r^2 + 5 k2 r^4``.
    """
    f = K[0, 0]
    k1, k2, cx, cy = lens
    d = (xs - (cx, cy)) / f
    rd = np.sqrt(np.einsum("ij,ij->i", d, d))
    r2 = np.einsum("ij,ij->i", q, q)
    D = 1.0 + r2 * (3.0 * k1 + 5.0 * k2 * r2)
    D = np.where(np.abs(D) > 1e-6, D, 1e-6)  # (at a fold of the lens: no blow-up)
    out = np.empty((len(xs), 2, len(which)))
    if 2 in which or 3 in which:
        ok = rd > 1e-12
        rs = np.where(ok, rd, 1.0)
        r = np.sqrt(r2)
        s = np.where(ok, r / rs, 1.0)
        ds = np.where(ok, (rd / D - r) / (rs * rs), 0.0)  # d(r / r_d) / d r_d
    for col, j in enumerate(which):
        if j == 0:
            out[:, :, col] = -q * (r2 / D)[:, None]
        elif j == 1:
            out[:, :, col] = -q * (r2 * r2 / D)[:, None]
        else:
            axis = j - 2
            g = d * (ds * d[:, axis] / rs)[:, None]
            g[:, axis] += s
            out[:, :, col] = -g / f
    return out


def _rows(Hc, q, xs, ab, fam_a, fam_b, ia, ib, pa, pb, K, lens, free_idx=()):
    """Residuals (px) of the thread pixels from their lines and the Jacobian, analytic.

    Rows: the pixels of family A (``fam_a``), then of family B, each in pixel order
    (``rows`` gives their indices).  ``ab = apply_h(Hc, q)``; ``ia``, ``ib`` the line
    indices.  Columns: h0..h7 of ``Hc``, then the lens parameters ``free_idx`` (indices
    into k1, k2, cx, cy).

    Returns
    -------
    r, J, rows : (n,), (n, 8 + len(free_idx)), (n,) int
    """
    in_a, in_b = np.flatnonzero(fam_a), np.flatnonzero(fam_b)
    rows = np.concatenate([in_a, in_b])
    n_a = len(in_a)
    qq = q[rows]
    x, y = qq[:, 0], qq[:, 1]
    p = np.empty(len(rows))
    p[:n_a], p[n_a:] = pa, pb
    val = np.concatenate([ab[in_a, 0], ab[in_b, 1]])  # the line coordinate, cells
    r = (val - np.concatenate([ia[in_a], ib[in_b]])) * p
    pw = p / (Hc[2, 0] * x + Hc[2, 1] * y + Hc[2, 2])
    J = np.zeros((len(rows), 8 + len(free_idx)))
    for fam, sl in ((0, slice(0, n_a)), (1, slice(n_a, None))):
        J[sl, 3 * fam] = pw[sl] * x[sl]
        J[sl, 3 * fam + 1] = pw[sl] * y[sl]
        J[sl, 3 * fam + 2] = pw[sl]
    J[:, 6] = -pw * val * x
    J[:, 7] = -pw * val * y
    if len(free_idx):
        # chain rule through q: d(residual)/dq . dq/dlens
        h0, h1 = np.empty(len(rows)), np.empty(len(rows))
        h0[:n_a], h0[n_a:] = Hc[0, 0], Hc[1, 0]
        h1[:n_a], h1[n_a:] = Hc[0, 1], Hc[1, 1]
        gx, gy = pw * (h0 - val * Hc[2, 0]), pw * (h1 - val * Hc[2, 1])
        dq = _dq_dlens(xs[rows], _lens_K(K, lens), lens, qq, tuple(free_idx))
        J[:, 8:] = gx[:, None] * dq[:, 0] + gy[:, None] * dq[:, 1]
    return r, J, rows


def fit_lattice(xs, w, Hc, K, dist=(0.0, 0.0), free=(), centre=None, radii=(None,),
                band_px=3.0, iterations: int = 4, free_from=0.5):
    """Refine the lattice homography (and optionally the lens) by robust Gauss-Newton.

    Parameters
    ----------
    xs, w : (N, 2), (N,)
        Thread pixels (observed px) and weights.
    Hc : (3, 3)
        Starting homography normalised-undistorted px -> cells.
    K : (3, 3)
        Camera matrix (reference focal length, principal point = distortion centre).
    dist : (k1, k2)
        Starting radial distortion.
    free : sequence of {"k1", "k2", "cx", "cy"}
        Lens parameters fitted too (the distortion centre has a weak prior at its
        starting value, so it stays put when the distortion is too weak to locate it).
    centre : (2,), optional
        Centre of the growing region (px); default the principal point.
    radii : sequence of float or None
        Region-growing radii (px); None = all pixels.  Lens parameters are only freed
        once the region reaches ``free_from`` of the farthest pixel's radius and
        :data:`LENS_MIN_PERIODS` thread periods.
    band_px : float or (float, float)
        Half-width (px) of the band around a thread whose pixels belong to it (per family).
    free_from : float or dict
        See ``radii``; a dict gives it per lens parameter (name -> fraction).

    Returns
    -------
    Hc, K, dist, info : ndarray, ndarray, tuple, dict
        ``info``: ``rms_px`` (weighted RMS of pixel-to-thread distances), ``n_a``,
        ``n_b`` (pixels used), ``lines_a``, ``lines_b`` (distinct thread indices).
    """
    f = K[0, 0]
    lens = np.array([*(tuple(dist) + (0.0, 0.0))[:2], K[0, 2], K[1, 2]], float)
    lens0 = lens.copy()
    free_idx = [LENS_PARAMS.index(n) for n in free]
    centre = lens[2:] if centre is None else np.asarray(centre, float)
    rad = np.hypot(*(xs - centre).T)
    q = _normalised(xs, K, lens)
    Hc = Hc / Hc[2, 2]
    bands = np.broadcast_to(np.asarray(band_px, float), (2,))
    last = None
    for stage, radius in enumerate(radii):
        # (the pixels of this stage's region only: the inner stages are small)
        sel = slice(None) if radius is None else np.flatnonzero(rad <= radius)
        xs_s, w_s, q_s = xs[sel], w[sel], q[sel]
        period = max(periods_px(Hc, f))
        stage_free = [j for j in free_idx if radius is None or (radius > (
            free_from.get(LENS_PARAMS[j], 0.5) if isinstance(free_from, dict) else free_from)
            * rad.max() and radius >= LENS_MIN_PERIODS[LENS_PARAMS[j]] * period)]
        for it in range(iterations):
            pa, pb = periods_px(Hc, f)
            ab = apply_h(Hc, q_s)
            fam_a, fam_b, ia, ib = assign_families(ab[:, 0], ab[:, 1], pa, pb, bands)
            if fam_a.sum() < 20 or fam_b.sum() < 20:
                break
            r, J, rows = _rows(Hc, q_s, xs_s, ab, fam_a, fam_b, ia, ib, pa, pb, K, lens,
                               stage_free)
            bw = np.full(len(rows), bands[1])
            bw[:np.count_nonzero(fam_a)] = bands[0]
            ww = w_s[rows] * np.clip(1 - (r / bw) ** 2, 0, None) ** 2  # Tukey biweight
            with np.errstate(over="ignore", invalid="ignore"):
                JW = J * ww[:, None]
                A = J.T @ JW
                g = -JW.T @ r
            if not (np.isfinite(A).all() and np.isfinite(g).all()):
                break  # (diverged: a random set-up's fit, seed 250954702) - ends where it was
            A += 1e-9 * np.trace(A) * np.eye(len(A))
            for col, j in enumerate(stage_free):
                if j >= 2:  # prior on the distortion centre, worth ~100 thread pixels
                    lam = 100.0 * np.mean(ww) / CENTRE_PRIOR_PX ** 2
                    A[8 + col, 8 + col] += lam
                    g[8 + col] -= lam * (lens[j] - lens0[j])
            step = np.linalg.solve(A, g)
            Hc = Hc + np.append(step[:8], 0.0).reshape(3, 3)
            last = (ww, r, fam_a, fam_b, ia, ib, step)
            if stage_free:
                lens[stage_free] += step[8:]
                if stage == len(radii) - 1 and it == iterations - 1:
                    break  # (the pixels' positions are not needed after the last step)
                q_s = _normalised(xs_s, K, lens)
            moved = np.abs(J @ step).max()
            if radius is not None and moved < STAGE_TOL_PX:
                break  # a growing stage has only to land in the basin: the next refines
            if radius is None and moved < FINAL_TOL_PX:
                break
        if stage_free:  # the lens moved: every pixel's normalised position
            q = q_s if radius is None else _normalised(xs, K, lens)
    info = {}
    if last is not None:  # (of the last step made)
        ww, r, fam_a, fam_b, ia, ib, step = last
        info = {"rms_px": float(np.sqrt(np.sum(ww * r * r) / max(ww.sum(), 1e-12))),
                "n_a": int(fam_a.sum()), "n_b": int(fam_b.sum()),
                "lines_a": _n_distinct(ia[fam_a]), "lines_b": _n_distinct(ib[fam_b]),
                "step": float(np.abs(step[:8]).max())}
    return Hc, _lens_K(K, lens), (float(lens[0]), float(lens[1])), info


def per_line_offsets(xs, w, Hc, K, dist, band_px: float = 3.0):
    """Weighted mean offset (px) of each thread's pixels from the fitted line.

    Returns
    -------
    dict with ``rms_px`` over threads and per-family dicts ``{index: (offset_px, weight,
    n)}`` — used for the residual figure and the colour / period checks.
    """
    f, c = K[0, 0], K[:2, 2]
    q = (undistort(xs, K, dist) - c) / f
    ab = apply_h(Hc, q)
    pa, pb = periods_px(Hc, f)
    fam_a, fam_b, ia, ib = assign_families(ab[:, 0], ab[:, 1], pa, pb, band_px)
    out, offs = {}, []
    for name, fam, idx, col, p in (("a", fam_a, ia, 0, pa), ("b", fam_b, ib, 1, pb)):
        lines = {}
        if fam.any():
            ids, inv = np.unique(idx[fam], return_inverse=True)
            r = (ab[fam, col] - idx[fam]) * p
            ws = np.bincount(inv, w[fam])
            rs = np.bincount(inv, w[fam] * r) / np.maximum(ws, 1e-12)
            ns = np.bincount(inv)
            for i, o, ww, n in zip(ids, rs, ws, ns):
                lines[int(i)] = (float(o), float(ww), int(n))
                if n >= 20:
                    offs.append(o)
        out[name] = lines
    out["rms_px"] = float(np.sqrt(np.mean(np.square(offs)))) if offs else float("nan")
    return out


def _n_distinct(v) -> int:
    """Number of distinct values in a 1-d array."""
    return int(np.count_nonzero(np.diff(np.sort(v)))) + (len(v) > 0)


#: The per-thread covariance of :func:`fit_points` is kept with at least this many
#: threads per parameter of the homography (fewer cannot hold an 8 x 8 sandwich).
MIN_THREADS_PER_PARAMETER = 2


def fit_points(xy, w, fam, idx, Hc, K, dist, iterations: int = 3, clip_px: float = 2.0,
               q=None, tol_px: float = 0.05):
    """Refine ``Hc`` on thread points of known family (0/1) and thread index.

    Robust (Tukey, ``clip_px`` scaled by the residuals' spread) weighted Gauss-Newton;
    the lens is fixed.  ``xy`` are observed px; ``q``, when given, the same points
    already undistorted and normalised (``(x_u - c) / f``), which saves undistorting.
    At most ``iterations`` steps; stops after a step that moves no point by more than
    ``tol_px`` (px): from a predicted lattice each step is ~10x smaller than the last
    (the step after a 0.05 px one moves the points by ~0.004 px).

    Returns
    -------
    Hc, info : ndarray, dict
        ``info``: ``rms_px`` (weighted RMS residual), ``n_a``, ``n_b`` (points used),
        ``lines_a``, ``lines_b``, ``sigma_px`` (1-sigma of the lattice position at the
        image centre, from the normal equations), ``cov`` (the (8, 8) covariance of
        ``Hc``'s first eight entries, for :func:`position_sigma_at` elsewhere) and
        ``cov_threads`` (the same, each thread's points one look - cluster-robust by
        thread; None with fewer than :data:`MIN_THREADS_PER_PARAMETER` x 8 threads).
    """
    f, c = K[0, 0], K[:2, 2]
    if q is None:
        q = (undistort(xy, K, dist) - c) / f
    # rows in family order (A then B)
    order = np.argsort(fam, kind="stable")
    row = fam[order].astype(np.intp)
    na = int(np.count_nonzero(row == 0))
    X = np.column_stack([q[order], np.ones(len(order))])  # (x, y, 1)
    io = idx[order].astype(float)
    w0 = w[order]
    parts = (slice(0, na), slice(na, None))
    J = np.zeros((len(order), 8))
    ww = w0
    for it in range(iterations):
        p = np.where(row, *periods_px(Hc, f)[::-1])
        XH = X @ Hc.T  # (a, b, w) homogeneous, per point
        wq = XH[:, 2]
        val = np.where(row, XH[:, 1], XH[:, 0]) / wq
        r = (val - io) * p
        # Tukey weights about each family's median residual (a common shift of a family
        # is the correction sought, not an outlier), scale from the MAD
        u = np.empty_like(r)
        for part in parts:
            rp = r[part]
            if rp.size:
                med = median(rp)
                u[part] = (rp - med) / max(clip_px, 4.5 * robust_sigma(rp, centre=med))
        ww = w0 * np.square(np.maximum(1.0 - u * u, 0.0))
        # d(residual)/d(h0..h7), analytic (as _h_jacobian): h0..h2 or h3..h5 by family
        pw = (p / wq)[:, None]
        J[:na, 0:3] = pw[:na] * X[:na]  # (rows ordered by family: A's h0..h2, B's h3..h5)
        J[na:, 3:6] = pw[na:] * X[na:]
        J[:, 6:] = -(pw * val[:, None]) * X[:, :2]
        JW = J * ww[:, None]
        A = J.T @ JW
        A.flat[::9] += 1e-9 * np.trace(A)
        step = np.linalg.solve(A, -JW.T @ r)
        Hc = Hc.copy()
        Hc.flat[:8] += step
        if np.abs(J @ step).max(initial=0.0) < tol_px:
            break
    used = ww > 0
    chi2 = float(np.sum(ww * r * r))
    pa, pb = periods_px(Hc, f)
    # 1-sigma of the translation terms h2, h5 (cells) -> px at the image centre
    Ainv = np.linalg.inv(A)
    cov = Ainv * chi2 / max(int(used.sum()) - 8, 1)
    # the same by thread (cluster-robust): a thread's points share its misfit of the
    # model (the lens, a rolling shutter's shear), which the independent rows' cov
    # above counts as many independent looks; None with too few threads to hold it
    key = row * 100003 + io.astype(np.int64)
    threads, at = np.unique(key[used], return_inverse=True)
    cov_threads = None
    if threads.size >= MIN_THREADS_PER_PARAMETER * 8:
        score = np.zeros((threads.size, 8))
        np.add.at(score, at, (JW * r[:, None])[used])
        # (the degrees of freedom left by thread: the residuals of a fit to few threads
        # are smaller than their errors - G / (G - 1) alone left the error at a point
        # beyond the threads 1.16-1.27x what it said, 26 threads)
        cov_threads = (Ainv @ (score.T @ score) @ Ainv) * threads.size / (threads.size - 8)
    info = {"rms_px": float(np.sqrt(chi2 / max(ww.sum(), 1e-12))),
            "n_a": int(used[:na].sum()), "n_b": int(used[na:].sum()),
            "lines_a": _n_distinct(io[:na][used[:na]]),
            "lines_b": _n_distinct(io[na:][used[na:]]),
            "sigma_px": float(np.sqrt(cov[2, 2] * pa ** 2 + cov[5, 5] * pb ** 2)),
            "cov": cov, "cov_threads": cov_threads}
    return Hc, info


def position_sigma_at(Hc, cov, q, f) -> np.ndarray:
    """1 sigma (px) of the lattice position at normalised undistorted points ``q``
    (N, 2) under the covariance ``cov`` of :func:`fit_points` (``f``: the focal length
    of ``q``, px): both families' thread offsets there, each in its own px per cell.

    At the image centre this is ``fit_points``' ``sigma_px``; away from it the tilt
    and perspective terms add.  They matter when a family's points cover little of
    the view - its threads each averaged whole under motion blur (one point per
    thread, all about the middle of the view): CI seed 917008783 frame 38, 0.17 mm at
    the centre but 2.4 mm at the rock, 140 px off it, where the lattice was 3.7 mm off.
    """
    q = np.atleast_2d(np.asarray(q, float))
    X = np.column_stack([q, np.ones(len(q))])
    Hc = np.asarray(Hc, float)
    XH = X @ Hc.T
    wq = XH[:, 2:3]
    var = np.zeros(len(q))
    for fam in (0, 1):
        v = XH[:, fam:fam + 1] / wq
        g = np.zeros((len(q), 8))
        g[:, 3 * fam:3 * fam + 3] = X / wq
        g[:, 6:] = -v * q / wq
        # px per cell across the family's threads at q: f / |d(a or b)/dq|
        grad = (Hc[fam, :2] - v * Hc[2, :2]) / wq
        var += np.einsum("ni,ij,nj->n", g, cov, g) * (f / np.hypot(*grad.T)) ** 2
    return np.sqrt(var)


#: Degree of the polynomial (in normalised image coordinates) fitted to the thread
#: points' misfit of a frame's lattice (:func:`misfit_field`): what a homography cannot
#: follow - a rolling shutter's row-by-row shift while the camera shakes, the lens
#: model's misfit - is smooth over the image.  On rendered action clips the field at
#: the rock predicted the lattice's error there along the travel with correlation
#: 0.87 (hand-held, k1 -0.33, 13 ms readout) and 0.87 (fisheye on a pole) at degree 2
#: or 3; on a low-bitrate fisheye clip 0.69 at degree 2 and 0.30 at degree 3 (a cubic
#: flung out to 10-18 mm across the rock's hidden disc in a few frames).
MISFIT_DEGREE = 2


def _poly(q, degree: int) -> np.ndarray:
    """Monomials x^i y^j, i + j <= degree, of normalised points (N, 2) -> (N, n)."""
    x, y = q[:, 0], q[:, 1]
    return np.column_stack([x ** i * y ** j for i in range(degree + 1)
                            for j in range(degree + 1 - i)])


def misfit_field(q, w, fam, idx, Hc, f, degree: int = MISFIT_DEGREE,
                 clip_px: float = 2.0):
    """The smooth part of the thread points' misfit of the lattice ``Hc``, per family.

    Each point's misfit is its lattice coordinate across its thread minus the thread's
    index (cells; > 0: the lattice puts the thread too far along); points off their
    family's median by more than ``clip_px`` (or 4.5 robust sigmas) are left out.  A
    weighted least-squares polynomial of ``degree`` in the normalised image
    coordinates ``q`` is fitted per family (``f``: the focal length of ``q``, px).

    Returns
    -------
    (coef (2, n), cov (2, n, n)) in cells, or None when a family has fewer than three
    points per coefficient.
    """
    XH = np.column_stack([q, np.ones(len(q))]) @ np.asarray(Hc).T
    val = np.where(fam == 1, XH[:, 1], XH[:, 0]) / XH[:, 2]
    r = val - idx
    B = _poly(q, degree)
    n = B.shape[1]
    coefs, covs = [], []
    for fm in (0, 1):
        sel = fam == fm
        if sel.sum() < 3 * n:
            return None
        rp = r[sel]
        med = median(rp)
        # (clip_px in cells: the family's period at the image centre, px; f px)
        keep = np.abs(rp - med) < max(clip_px / periods_px(Hc, f)[fm],
                                      4.5 * robust_sigma(rp, centre=med))
        if keep.sum() < 3 * n:
            return None
        Bf, wf, rf = B[sel][keep], w[sel][keep], rp[keep]
        A = (Bf * wf[:, None]).T @ Bf
        A.flat[::n + 1] += 1e-12 * np.trace(A)
        Ainv = np.linalg.inv(A)
        c = Ainv @ (Bf.T @ (wf * rf))
        res = rf - Bf @ c
        s2 = float(np.sum(wf * res * res)) / max(len(rf) - n, 1)
        coefs.append(c)
        covs.append(Ainv * s2)
    return np.array(coefs), np.array(covs)


def misfit_at(field, q) -> tuple[np.ndarray, np.ndarray]:
    """The misfit field of :func:`misfit_field` at normalised points ``q`` (N, 2):
    (value (N, 2), 1 sigma (N, 2)) in cells, x then y family; zeros without a field."""
    q = np.atleast_2d(np.asarray(q, float))
    if field is None:
        return np.zeros((len(q), 2)), np.zeros((len(q), 2))
    coef, cov = field
    degree = int(round((np.sqrt(8 * coef.shape[1] + 1) - 3) / 2))
    B = _poly(q, degree)
    val = B @ coef.T
    sd = np.sqrt(np.einsum("ni,fij,nj->nf", B, cov, B))
    return val, sd
