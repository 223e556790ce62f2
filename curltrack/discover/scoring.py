"""Model comparison: BIC, look-elsewhere-calibrated thresholds, held-out prediction.

All quantities work on *whitened* residuals and Jacobians (divided by the noise and
AR(1)-whitened, see :mod:`curltrack.series.noise`), so chi-square is ``sum(r**2)``.

Look-elsewhere calibration
--------------------------
A candidate that scans a location (a pick's time, a patch's extent) gets to choose the
best of many places, and its null (effect size 0) sits on a boundary where the location
is undefined, so its ``delta_bic`` under the baseline is not the textbook chi-square.  We
calibrate each candidate's threshold by a parametric bootstrap of the fitted baseline
with block-resampled residuals (``search.null_noise``: the candidate's where it took
most of a misfit and left white noise, the baseline's elsewhere).  Refitting the nonlinear models hundreds of times would
not fit the time budget, so the refits are done in the linear (Gauss-Newton) limit, exact
as the effect size goes to zero, which is where the null sits: with ``J0`` the baseline's
Jacobian and ``E_s`` the effect's Jacobian at location ``s`` (effect size 0), the gain of
the candidate on residuals ``r`` is ``max_s |Q_s^T r|^2`` where ``Q_s`` spans the part
of ``E_s`` orthogonal to ``J0``.  The threshold is the ``1 - level`` quantile over
replicates of the largest delta-BIC (gain minus penalty) over locations and sub-models.  500 replicates resolve a 1 % quantile
to about +-0.3 % in level.
"""

from __future__ import annotations

import numpy as np
from scipy import sparse

#: Least delta-BIC a candidate needs to be supported, whatever its look-elsewhere
#: threshold: 6 on the 2 ln(Bayes factor) scale is "strong" evidence (Kass & Raftery
#: 1995), below it "positive" at most.  A bootstrap threshold can sit far below it (an
#: extension's at the 0.5 % level: 0.3-4; a pick's under a null that seldom gains:
#: negative), and a tracker's persisting errors are not in that null: a translation
#: coupling at delta-BIC 1.7 over a threshold of 0.6 was "extended" on a tracked
#: camcorder clip whose shot had none (session 38).
MIN_DELTA_BIC = 6.0
#: per-candidate false-alarm level of the bootstrap threshold
CANDIDATE_LEVEL = 0.01
N_BOOT = 500
BLOCK_FRAMES = 10


def support_level(threshold: float) -> float:
    """The delta-BIC a candidate whose look-elsewhere threshold is ``threshold`` must
    exceed to be supported: the larger of the two and :data:`MIN_DELTA_BIC`."""
    return max(float(threshold), MIN_DELTA_BIC)


def orth_basis(a, rel_tol: float = 1e-6):
    """Orthonormal basis of the column space of ``a`` (rank-revealing, via SVD)."""
    if a.shape[1] == 0:
        return a
    u, s, _ = np.linalg.svd(a, full_matrices=False)
    keep = s > rel_tol * max(s[0], 1e-300)
    return u[:, keep]


def effect_bases(J0, effect_cols, rel_tol: float = 1e-4):
    """Orthonormal bases of each scan location's effect columns, orthogonal to ``J0``.

    Parameters
    ----------
    J0 : (n, p) array
        Whitened baseline Jacobian at the fit.
    effect_cols : list of (n, m) arrays
        Whitened Jacobian of the effect's size parameters at each scan location.
    rel_tol : float
        Directions whose norm drops below ``rel_tol`` of the original on projection are
        degenerate with the baseline (not identifiable) and dropped.

    Returns
    -------
    list of (n, m_s) arrays
    """
    Q0 = orth_basis(J0)
    out = []
    for E in effect_cols:
        if E.shape[1] == 0:
            out.append(E)
            continue
        norms = np.linalg.norm(E, axis=0)
        Et = E - Q0 @ (Q0.T @ E)
        # drop directions that were (almost) inside span(J0)
        u, s, _ = np.linalg.svd(Et, full_matrices=False)
        keep = s > rel_tol * max(norms.max(), 1e-300)
        out.append(u[:, keep])
    return out


def detection_limits(J0, effect_cols, threshold: float, k, n: int) -> list:
    """The smallest size of each effect parameter that its threshold lets be seen.

    Alone at a scan location, a size ``s`` of one parameter (its whitened column ``e``
    per unit, the part orthogonal to the baseline ``e_perp``) gains chi-square
    ``s^2 |e_perp|^2`` on noise-free data; its delta-BIC clears ``threshold`` (and 0:
    a finding needs both) from ``s_min = sqrt((max(threshold, 0) + k log n) /
    |e_perp|^2)``.  An effect that size or
    smaller cannot be told from the noise - a ``none`` says nothing about it - and one
    a few times larger clears the threshold in most noise draws (about half at
    ``s_min``).  The bootstrap's threshold and the columns scale alike with the noise,
    so the limit is in the parameter's own units whatever the noise's level.

    Parameters
    ----------
    J0 : (n, p) array
        Whitened baseline Jacobian.
    effect_cols : list of (n, m) arrays
        Whitened effect columns (per unit of each size parameter) at each location.
    threshold : float
        The candidate's delta-BIC threshold.
    k : int
        Parameters one location and one size add (the BIC penalty).

    Returns
    -------
    list of (m,) arrays
        Per location, each parameter's ``s_min`` (inf where the baseline absorbs it).
    """
    Q0 = orth_basis(J0)
    # a finding is supported above support_level(threshold) (report._finding): a
    # threshold below it - the null's delta-BIC seldom positive - does not lower that (a
    # session of three clean shots, thresholds -4 to -15, said a slope of 0 mm/m and a
    # patch of |factor - 1| 4e-6 would have been seen)
    need = support_level(threshold) + k * np.log(n)
    out = []
    for E in effect_cols:
        Et = E - Q0 @ (Q0.T @ E)
        g = np.sum(Et * Et, axis=0)
        # (a direction inside the baseline's span up to round-off is not seen at all)
        g = np.where(g > 1e-8 * np.maximum(np.sum(E * E, axis=0), 1e-300), g, 0.0)
        out.append(np.where(g > 0, np.sqrt(need / np.where(g > 0, g, 1.0)), np.inf))
    return out


#: rows taken out of a candidate's chi-square gain before its evidence is judged robust:
#: the ones that carry most of it.  An effect on the rock's motion (an impulse, a stretch
#: of other friction, a slope) moves every row after it, so its gain is spread over tens
#: to hundreds of rows; an instrument's glitch touches one to a few (a tracker's first
#: rows after the release, a mistracked pair of fields)
FEW_ROWS = 3


def few_rows(share, groups=None, few: int = FEW_ROWS):
    """(the gain without the ``few`` rows that carry most of it, their residuals):
    :func:`without_few_rows` and :func:`top_rows` of an (n, B) ``share`` at once."""
    n = share.shape[0]
    if groups is None:
        table, sums = np.arange(n)[:, None], share
    else:
        labels, row = np.unique(groups, return_inverse=True)
        # (a sparse row-indicator product: reduceat over a sorted copy of (n, 500)
        # bootstrap replicates took a third of discover's time)
        ind = sparse.csr_matrix((np.ones(n), (row, np.arange(n))), shape=(labels.size, n))
        sums = np.asarray(ind @ share)
        order = ind.indices                    # residuals, row by row (csr: row-major)
        lengths = np.diff(ind.indptr)
        table = np.full((labels.size, lengths.max()), -1)
        table[np.repeat(np.arange(labels.size), lengths),
              np.arange(n) - np.repeat(ind.indptr[:-1], lengths)] = order
    if sums.shape[0] <= few:
        return np.zeros(share.shape[1]), np.full((share.shape[1], 0), -1)
    by_col = np.ascontiguousarray(sums.T)                               # (B, rows)
    best = np.argpartition(-by_col, few - 1, axis=1)[:, :few]           # (B, few)
    top = np.take_along_axis(by_col, best, 1)
    gain = by_col.sum(axis=1) - np.clip(top, 0.0, None).sum(axis=1)
    idx = np.where(top[..., None] > 0, table[best], -1)                 # (B, few, L)
    return gain, idx.reshape(idx.shape[0], -1)


def without_few_rows(share, groups=None, few: int = FEW_ROWS):
    """Chi-square gain without the ``few`` rows that carry most of it.

    Parameters
    ----------
    share : (n,) or (n, B) array
        Each residual's part of the gain: its square before the candidate minus after.
    groups : (n,) array of int, optional
        The row (one frame of one shot) of each residual: x, y and theta of a frame are
        one row, taken out together (a tracker's bad frame is bad in all of them).
        Without, each residual is a row.
    few : int

    Returns
    -------
    float or (B,) array
        The sum of ``share``, less the ``few`` largest positive sums over rows.
    """
    share = np.asarray(share, dtype=float)
    gain, _ = few_rows(share[:, None] if share.ndim == 1 else share, groups, few)
    return float(gain[0]) if share.ndim == 1 else gain


def top_rows(share, groups=None, few: int = FEW_ROWS) -> np.ndarray:
    """Indices of the residuals of the ``few`` rows that carry most of ``share`` (the
    rows of :func:`without_few_rows` with a positive sum).

    Parameters
    ----------
    share : (n,) or (n, B) array
    groups : (n,) array of int, optional
    few : int

    Returns
    -------
    (m,) or (B, m) array of int
        Residual indices, -1 where a column has fewer (a row with fewer residuals, or
        fewer rows that gain).
    """
    share = np.asarray(share, dtype=float)
    _, idx = few_rows(share[:, None] if share.ndim == 1 else share, groups, few)
    return idx[0] if share.ndim == 1 else idx


def refit_gain_without(Q0, r, rows):
    """Chi-square the baseline gains when refitted (linearised) without ``rows``.

    A few rows far off pull the baseline's fit towards them, and the rest of the rows
    pay for it; a candidate that takes those rows away lets the baseline's parameters
    return, and so gains on every other row too - gain that is still the few rows'.
    (A clean shot whose first three rows were 8.5, 5.7 and 2.8 sigma off: a pick just
    after them gained chi-square 9.6 on the other 1448 rows, and without the three its
    evidence was judged over chance's 1 % level.)

    Parameters
    ----------
    Q0 : (n, p) array
        Orthonormal basis of the whitened baseline Jacobian.
    r : (n,) or (n, B) array
        Whitened baseline residuals, orthogonal to ``Q0`` (the baseline's fit).
    rows : (m,) or (B, m) array of int
        Residuals left out (:func:`top_rows`; -1 is none).

    Returns
    -------
    float or (B,) array
        ``|r_o|^2 - min_b |r_o - Q0_o b|^2``, ``o`` the residuals kept: with
        ``v = Q0_R^T r_R`` (``R`` those left out, and ``Q0_o^T r_o = -v``),
        ``v^T (I - Q0_R^T Q0_R)^+ v``.
    """
    r = np.asarray(r, dtype=float)
    rows = np.asarray(rows, dtype=int)
    one = r.ndim == 1
    r, rows = (r[:, None], rows[None]) if one else (r, rows)
    if rows.shape[1] == 0 or Q0.shape[1] == 0:
        return 0.0 if one else np.zeros(r.shape[1])
    real = rows >= 0
    safe = np.where(real, rows, 0)
    QR = Q0[safe] * real[..., None]                                     # (B, m, p)
    rR = np.take_along_axis(r.T, safe, 1) * real                        # (B, m)
    v = np.einsum("bmp,bm->bp", QR, rR)
    gram = np.eye(Q0.shape[1]) - np.einsum("bmp,bmq->bpq", QR, QR)
    out = np.einsum("bp,bpq,bq->b", v, np.linalg.pinv(gram, rcond=1e-10, hermitian=True), v)
    out = np.clip(out, 0.0, None)
    return float(out[0]) if one else out


def scan_gain(bases, r):
    """Linearised chi-square gain of each scan location for residual vector(s) ``r``.

    Parameters
    ----------
    bases : list of (n, m_s) arrays (from :func:`effect_bases`)
    r : (n,) or (n, B) array

    Returns
    -------
    (S,) or (S, B) array
    """
    r = np.asarray(r, dtype=float)
    sizes = [b.shape[1] for b in bases]
    big = np.concatenate(bases, axis=1) if sum(sizes) else np.zeros((r.shape[0], 0))
    proj = big.T @ r
    out, i = [], 0
    for m in sizes:
        out.append((proj[i:i + m] ** 2).sum(axis=0))
        i += m
    return np.array(out)


def block_resample(r, segments, rng, n_boot: int = N_BOOT, block: int = BLOCK_FRAMES):
    """Circular block bootstrap of residuals, independently within each segment.

    Parameters
    ----------
    r : (n,) array
        Whitened residuals.
    segments : list of slice, or of (slice, int)
        The (shot, coordinate) stretches of ``r``; blocks never cross them.  With a
        block length per stretch (samples), that one is used instead of ``block``.
    rng : numpy Generator
    Returns
    -------
    (n, n_boot) array
    """
    out = np.empty((r.size, n_boot))
    for item in segments:
        # (slice, block length): the block spans the residuals' own correlation
        sl, b = item if isinstance(item, tuple) else (item, block)
        seg = r[sl]
        m = seg.size
        if m == 0:
            continue
        b = min(b, m)
        n_blocks = -(-m // b)
        starts = rng.integers(0, m, size=(n_blocks, n_boot))
        idx = (starts[:, None, :] + np.arange(b)[None, :, None]) % m
        boot = seg[idx.reshape(-1, n_boot)[:m]]
        # whitened residuals have unit variance by construction (noise from the data);
        # a segment whose residuals happen to scatter less is not allowed to lower the
        # threshold, one that scatters more (structure, heavier noise) raises it
        scale = max(float(np.sqrt(np.mean(seg**2))), 1.0) / max(float(np.sqrt(np.mean(seg**2))), 1e-12)
        out[sl] = boot * scale
    return out


def bootstrap_threshold(bases, r0, segments, k, n: int, rng,
                        level: float = CANDIDATE_LEVEL, n_boot: int = N_BOOT,
                        groups=None, J0=None) -> dict:
    """Look-elsewhere-calibrated delta-BIC threshold for one candidate.

    Parameters
    ----------
    bases : list of arrays
        From :func:`effect_bases` (one per scan location and parameter subset).
    r0 : (n,) array
        Whitened baseline residuals (the bootstrap's noise).
    segments : list of slice
    k : int or array of int
        Parameters each basis adds (its BIC penalty).  The statistic is the largest
        delta-BIC over all bases, exactly as for the data, so sub-model selection (which
        subset of a pick's impulse components) is calibrated too.
    n : int
        Number of data points.
    rng : numpy Generator
    level : float
        False-alarm probability of the threshold.
    groups : (n,) array of int, optional
        The row of each residual (:func:`without_few_rows`).
    J0 : (n, p) array, optional
        Whitened baseline Jacobian: each replicate's baseline is refitted (linearised)
        to it, and without its best fit's few rows (:func:`refit_gain_without`), as the
        data's is judged.

    Returns
    -------
    dict
        ``threshold`` (delta-BIC), ``level``, ``n_boot``, ``n_locations``, ``null_mean``
        (mean of the null's largest delta-BIC) and ``threshold_few_rows``: the same
        quantile of that largest fit's delta-BIC without its :data:`FEW_ROWS` best rows.
    """
    if not bases or sum(b.shape[1] for b in bases) == 0:
        return {"threshold": np.inf, "level": level, "n_boot": 0,
                "n_locations": len(bases), "null_mean": 0.0}
    pen = np.broadcast_to(np.asarray(k, dtype=float), (len(bases),)) * np.log(n)
    star = block_resample(r0, segments, rng, n_boot)
    # the bootstrap's baseline refit removes the part of r* in span(J0); bases are
    # orthogonal to J0 already, so projecting r* directly is the same thing.
    all_stats = scan_gain(bases, star) - pen[:, None]
    best = all_stats.argmax(axis=0)
    stats = all_stats[best, np.arange(n_boot)]
    # the same statistic without the few rows that carry most of each replicate's best
    # fit (:func:`without_few_rows`), as the data's is judged
    Q0 = None if J0 is None else orth_basis(np.asarray(J0, dtype=float))
    if Q0 is not None:
        star = star - Q0 @ (Q0.T @ star)
    share = np.empty_like(star)
    for b in np.unique(best):
        cols = np.flatnonzero(best == b)
        r = star[:, cols]
        f = bases[b] @ (bases[b].T @ r)
        share[:, cols] = r * r - (r - f) ** 2
    robust, rows = few_rows(share, groups)
    robust = robust - pen[best]
    if Q0 is not None:
        robust -= refit_gain_without(Q0, star, rows)
    q = float(np.quantile(stats, 1.0 - level))
    return {"threshold": q, "level": level, "n_boot": n_boot, "n_locations": len(bases),
            "null_mean": float(stats.mean()),
            "threshold_few_rows": float(np.quantile(robust, 1.0 - level))}
