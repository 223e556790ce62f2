"""The rows' scatter about a smooth path: a video's own measure of its frame-to-frame noise.

A rock's acceleration changes over seconds (friction, curl), so over a few tenths of a
second its path in the lattice frame is a cubic polynomial to far below the tracker's
noise; what a tracked row misses such a path by is that row's frame-to-frame (random)
error.  :func:`path_scatter` fits a cubic B-spline in ``t`` (knots every
:data:`KNOT_S`, or every :data:`MIN_ROWS_PER_KNOT` rows at low frame rates; double
knots at the stops, where the acceleration jumps), weighted by each row's predicted
sigma, separately per run of rows without a gap and per interlaced field (the fields'
offset is a systematic error of its own), and returns the scale by which those
sigmas must be multiplied for the normalized residuals to have unit variance - with
each residual's leverage taken off (``E[r_i^2] = s^2 sigma_i^2 (1 - h_ii)``) and
residuals over :data:`CLIP` robust sigmas left out (a wrong row is not noise).

Errors that vary slowly (a lattice misfit the rock crosses over a second, the origin,
the parallax factor) are invisible to it: they belong to other terms.
"""

from __future__ import annotations

import numpy as np

from .._stats import robust_sigma

__all__ = ["path_scatter", "KNOT_S", "MIN_ROWS_PER_KNOT", "CLIP", "GAP_S"]

#: Knot spacing of the smooth path (s): several times shorter than the time over which
#: the rock's acceleration changes, long enough to hold a dozen rows at 30 fps.
KNOT_S = 0.4
#: At least this many rows per knot interval (low frame rates): keeps the leverage small.
MIN_ROWS_PER_KNOT = 8
#: Residuals over this many robust sigmas are not noise (a wrong row): left out.
CLIP = 5.0
#: A gap (s) longer than this splits the rows into runs fitted separately.
GAP_S = 0.25
#: A run too short for its own spline (a frame or a few measured between refused ones)
#: is checked against the path through the fitted rows within this time (s) of it on
#: both sides, on the same side of any stop: a polynomial in t, whose own error at the
#: run is included.  (Not from one side: a line through the 8 rows after a 0.3 s gap
#: missed a clip's first 12 right rows by 36-120 mm.)
NEIGHBOUR_S = 0.6
#: ... with at least this many rows on each side.  So is such a run inside a spline's
#: run, between gaps each a little shorter than GAP_S: the spline bends to it.
NEIGHBOUR_ROWS = 4


#: A fitted row whose leverage in the path's spline is over this is set by its own value
#: more than by the rows around it: the path through the others predicts it only to
#: 1 / sqrt(1 - h) > 3 times its own sigma.  (A run's first and last rows reach ~0.6-0.9
#: without any gap; only rows of short parts past a gap are judged by it.)
UNCHECKED_LEVERAGE = 0.9


def _knots(t0: float, t1: float, step: float, breaks) -> np.ndarray:
    n = max(1, int(round((t1 - t0) / step)))
    inner = list(np.linspace(t0, t1, n + 1)[1:-1])
    for b in breaks:
        if t0 + 0.5 * step < b < t1 - 0.5 * step:
            # two knots at a stop: the path stays C1 there, its acceleration may jump
            inner = [k for k in inner if abs(k - b) > 0.3 * step] + [b, b]
    inner = np.sort(inner)
    return np.r_[[t0] * 4, inner, [t1] * 4]


def _fit(t, q, sig, knots, keep):
    """Weighted LS of q (n, m) on the spline basis over the rows ``keep``: normalized
    residuals (n, m) and leverages (n,)."""
    from scipy.interpolate import BSpline

    B = BSpline.design_matrix(np.clip(t, knots[0], knots[-1]), knots, 3).toarray()
    A = B / sig[:, None]
    Ak = A[keep]
    # the basis functions no kept row touches are left out (a run's end trimmed)
    cols = np.flatnonzero(np.abs(Ak).sum(axis=0) > 0)
    Ak, A = Ak[:, cols], A[:, cols]
    Q, R = np.linalg.qr(Ak)
    d = np.abs(np.diag(R))
    if Q.shape[0] <= Q.shape[1] or d.min() < 1e-10 * d.max():
        return None
    coef = np.linalg.solve(R, Q.T @ (q[keep] / sig[keep, None]))
    z = q / sig[:, None] - A @ coef
    # each row's leverage (a left-out row's: as if it were one of the fitted ones)
    G = np.linalg.solve(R.T, A.T)          # R^-T A^T
    h = np.sum(G * G, axis=0)
    return z, h, len(cols)


def path_scatter(t, q, sigma, runs=None, breaks=(), fps: float | None = None) -> dict:
    """Scale of the rows' scatter about a smooth path, in units of their ``sigma``.

    Parameters
    ----------
    t : (N,) array
        Row times (s).
    q : (N, m) array
        Values whose scatter is pooled (e.g. the x and y of the shot frame, m; or
        theta, rad).  Rows with any NaN, or with ``sigma`` not finite and > 0, are
        not used.
    sigma : (N,) array
        Each row's predicted 1 sigma of its frame-to-frame error (the shape; the
        scale is what is measured).
    runs : (N,) int array, optional
        Rows of different labels are fitted separately (interlaced fields).
    breaks : sequence of float
        Times where the path's acceleration may jump (stops): double knots there.
    fps : float, optional
        Row rate (rows/s) for the knot spacing's floor; from ``t`` when None.

    Returns
    -------
    dict
        ``scale`` (sqrt of sum z^2 / sum (1 - h) over the kept rows; NaN when too few
        rows), ``dof`` (the degrees of freedom behind it: rows - spline parameters,
        summed over columns), ``n`` (rows used), ``clipped`` (rows left out as wrong)
        and ``off_path`` ((N,) bool: those rows); ``miss`` ((N,) array, the units of
        ``q``): each used row's largest miss of the path over the columns (a left-out
        row's: of the path through the others), NaN for rows not used; ``unchecked``
        ((N,) bool): rows that too few rows around them could judge: short runs amid
        the fitted ones (after the first, before the last of their label), and a long
        run's short last part past a gap, which its spline's end bends through.
    """
    t = np.asarray(t, float)
    q = np.asarray(q, float).reshape(len(t), -1)
    sig = np.asarray(sigma, float)
    use = np.isfinite(t) & np.isfinite(q).all(axis=1) & np.isfinite(sig) & (sig > 0)
    runs = np.zeros(len(t), int) if runs is None else np.asarray(runs)
    off_path = np.zeros(len(t), bool)
    miss = np.full(len(t), np.nan)
    unchecked = np.zeros(len(t), bool)
    out = dict(scale=np.nan, dof=0.0, n=0, clipped=0, off_path=off_path, miss=miss,
               unchecked=unchecked)
    num = den = 0.0
    n_used = clipped = 0
    fitted_rows = np.zeros(len(t), bool)
    spline_z = np.full(len(t), np.nan)
    spline_miss = np.full(len(t), np.nan)
    short = []
    for lab in np.unique(runs[use]):
        rows = np.flatnonzero(use & (runs == lab))
        rows = rows[np.argsort(t[rows])]
        if len(rows) < 2:
            continue
        dt_row = np.median(np.diff(t[rows])) if fps is None else 1.0 / fps
        step = max(KNOT_S, MIN_ROWS_PER_KNOT * dt_row)
        cut = np.flatnonzero(np.diff(t[rows]) > max(GAP_S, 3 * dt_row)) + 1
        # the rows a spline will fit: runs long enough, less their short parts between
        # gaps of a few frames (what judges a short part: see below)
        spline_rows = np.zeros(len(t), bool)
        for seg in np.split(rows, cut):
            if len(seg) >= 2 * MIN_ROWS_PER_KNOT:
                for part, is_short in _parts(t[seg], dt_row):
                    spline_rows[seg[part]] = not is_short
        t_fit = t[spline_rows]
        for seg in np.split(rows, cut):
            if len(seg) < 2 * MIN_ROWS_PER_KNOT:
                short.append((lab, seg))
                continue
            ts, qs, ss = t[seg], q[seg], sig[seg]
            # a few rows between gaps shorter than GAP_S: the spline would bend to
            # them, so they are judged by their neighbours - and, where rows on both
            # sides can judge them, left out of its fit and of the scale (4 rows 25-60
            # sigma off beside a 0.17 s gap, fitted, made the scale ~5x and hid
            # themselves - test seed 1957155334)
            short_part = np.zeros(len(seg), bool)
            alone = np.zeros(len(seg), bool)
            for part, is_short in _parts(ts, dt_row):
                if is_short:
                    short.append((lab, seg[part]))
                    short_part[part] = True
                    # (only where fitted rows on both sides can judge it: left out
                    # otherwise, it would be judged by the spline's extrapolation or
                    # across a hole - a clip whose strict layout test refused every few
                    # frames lost 45 of 70 clean rows that way, a broom clip 5 rows
                    # amid 0.7 s of hidden ones)
                    alone[part] = _judged_by_neighbours(t_fit, ts[part[0]], ts[part[-1]],
                                                        breaks)
            if (~alone).sum() < 2 * MIN_ROWS_PER_KNOT:
                alone[:] = False   # (too few rows left for a spline: all fitted, as before)
            main = ts[~alone]
            knots = _knots(main[0], main[-1], step, breaks)
            keep = ~alone
            res = None
            for _ in range(4):
                res = _fit(ts, qs, ss, knots, keep)
                if res is None:
                    break
                fitted = keep
                z, h, p = res
                # a fitted row's residual has variance 1 - h, a left-out row's (its
                # prediction from the others) 1 + h: with 1 - h, a row left out beside
                # a run's end, whose basis no kept row then fixes (h > 1), was judged
                # 10x too far off and never came back
                zn = z / np.sqrt(np.where(keep, np.clip(1 - h, 0.05, None), 1 + h))[:, None]
                s = robust_sigma(zn[keep], centre=0.0)
                new = (np.abs(zn) <= CLIP * max(s, 1e-12)).all(axis=1) & ~alone
                if (new == keep).all():
                    break
                keep = new
                if keep.sum() <= p + 2:
                    res = None
                    break
            if res is None:
                continue
            # (the rows of the last fit: when the clipping has not settled - a run's
            # first rows left out with an outlier among them come back, predicted from
            # no kept row, and go again - a left-out row's leverage is not a kept one's:
            # 633 on CI seed 1876757522, the scale NaN)
            z, h, p = res
            keep = fitted
            m = q.shape[1]
            # a row of a short part that the spline bends through (past a gap at the
            # run's end, or amid gaps that leave no neighbours to judge it): its own
            # value sets the path there, which cannot check it (a DV clip's last field,
            # after three refused frames, 15.7 mm off under 3.2 mm: leverage 0.99, its
            # miss 0.2 mm)
            unchecked[seg[short_part & ~alone & (h > UNCHECKED_LEVERAGE)]] = True
            num += float(np.sum(z[keep] ** 2))
            den += float(m * (np.sum(1 - h[keep])))
            n_used += int(keep.sum())
            clipped += int((~keep & ~alone).sum())
            off_path[seg[~keep & ~alone]] = True
            miss[seg[~alone]] = np.abs(z[~alone]).max(axis=1) * ss[~alone]
            fitted_rows[seg[keep & ~short_part]] = True
            inside = alone & (ts > main[0]) & (ts < main[-1])
            if inside.any():
                # (the spline's own prediction for them, should their neighbours not
                # be enough to judge them after all - the spline's clipping took some:
                # as it judges the rows it left out, where it interpolates)
                # (zn and s: the last fit's, whose kept rows are ``keep``)
                spline_z[seg[inside]] = np.abs(zn[inside]).max(axis=1) / max(s, 1e-12)
                spline_miss[seg[inside]] = np.abs(z[inside]).max(axis=1) * ss[inside]
    if den > 0:
        scale = float(np.sqrt(num / den))
        out.update(scale=scale, dof=den, n=n_used, clipped=clipped)
        for lab, seg in short:
            # (a lone row amid refused frames was never checked: a rendered hand-held
            # clip's frame 87, between 16 refused for their marker layout, 29 mm off
            # under a 1.3 mm sigma, with ok = 1)
            fitted = fitted_rows & (runs == lab)
            z_seg, m_seg = _short_run(t, q, sig * scale, seg, fitted, breaks)
            if z_seg is not None:
                miss[seg] = np.fmax(miss[seg], m_seg)
                off_path[seg[z_seg > CLIP]] = True
            elif np.isfinite(spline_z[seg]).any():
                miss[seg] = spline_miss[seg]
                off_path[seg[spline_z[seg] > CLIP]] = True
            elif fitted.any() and (t[fitted].min() < t[seg].min()
                                   and t[seg].max() < t[fitted].max()):
                unchecked[seg] = True
    return out


def _parts(ts, dt_row: float) -> list:
    """One run's rows (times ``ts``, s) split at gaps of more than three row steps
    ``dt_row``: (indices, whether the part is too short for a spline of its own) each -
    a run without such a gap is one part, never short."""
    inner = np.flatnonzero(np.diff(ts) > 3 * dt_row) + 1
    return [(part, bool(inner.size) and len(part) < 2 * MIN_ROWS_PER_KNOT)
            for part in np.split(np.arange(len(ts)), inner)]


def _judged_by_neighbours(t_fit, t0: float, t1: float, breaks) -> bool:
    """Whether :func:`_short_run` can judge a run from ``t0`` to ``t1`` (s) by rows at
    times ``t_fit``: no stop inside it and, on its side of any stop, at least
    :data:`NEIGHBOUR_ROWS` of them within :data:`NEIGHBOUR_S` before and after it."""
    near = (t_fit >= t0 - NEIGHBOUR_S) & (t_fit <= t1 + NEIGHBOUR_S)
    for b in breaks:
        if t0 < b < t1:
            return False
        near &= (t_fit > b) if b <= t0 else (t_fit < b)
    return min(np.count_nonzero(near & (t_fit < t0)),
               np.count_nonzero(near & (t_fit > t1))) >= NEIGHBOUR_ROWS


def _short_run(t, q, sig, seg, fitted, breaks):
    """How far each row of a short run ``seg`` lies off the path through the ``fitted``
    rows within :data:`NEIGHBOUR_S` of it on either side (a weighted quadratic in t,
    cubic with 16 rows or more; rows across a stop left out): (z (n,), in units of the
    row's ``sig`` and the path's own error at it, worst column; miss (n,), the worst
    column's miss) - or (None, None) with fewer than :data:`NEIGHBOUR_ROWS` rows on a
    side or a stop inside the run."""
    t0, t1 = t[seg].min(), t[seg].max()
    if not _judged_by_neighbours(t[fitted], t0, t1, breaks):
        return None, None
    near = fitted & (t >= t0 - NEIGHBOUR_S) & (t <= t1 + NEIGHBOUR_S)
    for b in breaks:
        near &= (t > b) if b <= t0 else (t < b)
    rows = np.flatnonzero(near)
    tc = 0.5 * (t0 + t1)
    qw = q[rows] / sig[rows, None]
    fits = {}
    for deg in (2, 3) if len(rows) >= 16 else (2,):
        A = np.vander(t[rows] - tc, deg + 1) / sig[rows, None]
        Q, R = np.linalg.qr(A)
        coef = np.linalg.solve(R, Q.T @ qw)
        fits[deg] = (R, coef, float(np.sum((qw - A @ coef) ** 2)))
    deg = 2
    if 3 in fits:
        # the cubic only where the rows show it (F test at 1 %): carried across the hole
        # unneeded, its error there hid a sweep camcorder's run 14-24 mm off under a
        # 3.4 mm sigma (3.4 sigma; the quadratic's 8.5-9.6), rows amid frames refused
        # for a glare over their markers
        from scipy.stats import f as f_dist

        m = q.shape[1]
        dof = m * (len(rows) - 4)
        gain = (fits[2][2] - fits[3][2]) / m / max(fits[3][2] / dof, 1e-300)
        if gain > f_dist.ppf(0.99, m, dof):
            deg = 3
    R, coef, _ = fits[deg]
    X = np.vander(t[seg] - tc, deg + 1)
    G = np.linalg.solve(R.T, X.T)              # its prediction's variance: |R^-T x|^2
    err = np.sqrt(sig[seg] ** 2 + np.sum(G * G, axis=0))
    off = np.abs(q[seg] - X @ coef)
    return (off / err[:, None]).max(axis=1), off.max(axis=1)
