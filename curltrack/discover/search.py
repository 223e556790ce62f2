"""Score one candidate against the fitted baseline: scan, calibrate, refit, predict.

1. Effect columns: the whitened change of the model per unit of each *size* parameter at
   every scan location (effect size 0, the baseline's fit otherwise).
2. Linear scan: the chi-square gain of each location on the baseline residuals, with
   the baseline's own directions projected out (:func:`scoring.effect_bases`); the best
   location starts the nonlinear fit (coarse-to-fine).
3. Threshold: parametric block bootstrap of the same maximum (:func:`scoring.bootstrap_threshold`).
4. Nonlinear fit of baseline + candidate jointly (all parameters free) when the linear
   gain is anywhere near the threshold; otherwise the linear gain is reported.
5. Held-out prediction: blocked cross-validation in time (5 blocks per shot), and
   leave-one-shot-out (the held-out shot keeps its first fifth, which fixes its initial
   conditions) when there are several shots.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import CurltrackError
from . import scoring
from .model import FitOut, JointModel
from .residuals import structure_tests
from .shots import COORDS, stated_sigma_rows

N_TIME_BLOCKS = 5
#: candidates whose linear delta-BIC is this far below threshold skip the nonlinear fit
NONLINEAR_MARGIN = 3.0
#: the candidate fit runs to convergence (relative chi-square change 1e-6, ~0.002 on 2000
#: points, far below any decision scale); the cap only guards against a runaway fit.  A
#: strong effect needs many iterations: the baseline has bent itself to mimic it and
#: must be walked back (a 1.6x patch on tracked video: ~100 evaluations from a poor
#: start, ~25 from a good one).  A fit stopped at the cap is reported as not converged.
FIT_MAX_NFEV = 200
FIT_TOL = 1e-6
#: a scanned candidate is fitted from the best few distinct scan locations with the
#: location held fixed (a smooth problem that converges reliably; the location's own
#: derivative is that of a moving kink), and the best is finished with the location
#: free: with a strong effect the baseline is pulled far from the truth and the linear
#: scan can rank the right location below a wrong one
N_STARTS = 3
#: ... plus the best location of each of this many regions (along the sheet for a patch,
#: in time per shot for a pick) that the first starts do not cover
N_REGIONS = 4
START_NFEV = 15
#: an extension's coefficient lies in a curved valley with the friction laws (a spin
#: coupling with phi_theta): at 1e-6 the fit can stop on the valley's floor short of
#: the minimum (c = 0.148 +- 0.004 for a true 0.170), so it runs to 1e-10
EXTENSION_FIT_TOL = 1e-10
#: starts finished with the location free
N_FINISH = 2

@dataclass
class CandidateScore:
    """Everything measured about one candidate."""

    name: str
    delta_bic: float
    delta_bic_linear: float
    threshold: dict
    fit: FitOut | None
    location: dict
    params: dict = field(default_factory=dict)
    params_err: dict = field(default_factory=dict)
    heldout: dict = field(default_factory=dict)
    structure_after: object = None
    note: str = ""
    #: what reading the fitted parameters needs (the effect's ``remark``; after ``note``)
    remark: str = ""
    k: int = 0
    nfev: tuple | None = None
    chi2_gain: float | None = None
    noise: list | None = None
    extension: bool = False
    #: the effect acts on one shot (a pick): leaving that shot out cannot test it
    per_shot: bool = False
    #: whether the data's linearised delta-BIC -- the statistic the bootstrap threshold
    #: calibrates -- clears the threshold too (set by :func:`rescore` under persisting
    #: noise; True elsewhere, where near the null the two coincide)
    linear_clears: bool = True
    #: the delta-BIC left once the :data:`~.scoring.FEW_ROWS` rows that carry most of
    #: the gain are taken out of it, and whether that still clears the level chance
    #: reaches so (set by :func:`rescore`; :func:`_judge_few_rows`)
    delta_bic_without_few_rows: float | None = None
    robust_clears: bool = True
    #: the largest change the candidate makes to the fitted path, in units of the sigma
    #: the instrument states for its rows (None: some coordinate has no stated sigma or
    #: its noise does not persist), and whether it moves the path beyond that error
    #: (set by :func:`rescore`; :func:`_judge_stated`)
    path_change_stated: float | None = None
    beyond_stated: bool = True
    #: profile-likelihood errors of an extension's parameters (:mod:`.profile`) and the
    #: fit's covariance rescaled to them (None: not profiled)
    profile: dict | None = None
    cov_profile: np.ndarray | None = None
    #: per size parameter: the median, least and largest over the scan's locations of
    #: the smallest size its threshold lets be seen (:func:`scoring.detection_limits`)
    limits: dict | None = None
    _scale: np.ndarray | None = None
    #: the refitted model (with :attr:`fit`; None when the candidate was not refitted)
    _model: JointModel | None = None
    _refine: tuple | None = None
    _scan: tuple | None = None
    _blocks: list | None = None


def folds_time(model: JointModel, k: int = N_TIME_BLOCKS) -> np.ndarray:
    """Fold of each residual row: its time block (0..k-1) from the release to its own
    coordinate's last row of its shot.

    Each coordinate's span is cut alike, so each has ``k`` held-out units: cut over the
    shot's whole span, a rock spinning for 49 s after it stopped at 20 s left y two
    blocks, one of them the first 14 s extrapolated back to the release, and a late
    curl at delta-BIC 615 was blocked on y's held-out error, untestable on two units.
    """
    out = np.empty(model.n, int)
    for j, c, sl in model.segments:
        s = model.shots[j]
        t = s.t[s.use[c]]
        if t.size == 0:
            continue
        out[sl] = np.minimum((k * t / max(float(t.max()), 1e-9)).astype(int), k - 1)
    return out


def folds_shot(model: JointModel, keep_frac: float = 0.2) -> np.ndarray:
    """Leave-one-shot-out folds; each shot's first ``keep_frac`` of time stays in training."""
    out = np.empty(model.n, int)
    for j, c, sl in model.segments:
        s = model.shots[j]
        t = s.t[s.use[c]]
        out[sl] = np.where(t > keep_frac * float(s.t.max()), j, -1)
    return out


def heldout(fit: FitOut, folds: np.ndarray, model: JointModel, fixed=()) -> dict:
    """Held-out RMS: ``scalar`` (in units of the noise) and per coordinate (m, rad).

    ``fixed`` parameters (a scanned location: a pick's time, a patch's edges) are held at
    their full-data values in the refits: their derivative is that of a kink, which a
    single Gauss-Newton step cannot follow.  Columns are scaled to unit norm before the
    least-squares step (parameters span ten orders of magnitude).
    """
    r = np.full(fit.n, np.nan)
    raw = np.full(fit.n, np.nan)
    cols = [i for i, name in enumerate(fit.free) if name not in set(fixed)]
    J, J_raw = fit.J[:, cols], fit.J_raw[:, cols]
    d = np.linalg.norm(J, axis=0)
    d = np.where(d > 0, d, 1.0)
    for f in np.unique(folds[folds >= 0]):
        test = folds == f
        # directions the training rows cannot determine (singular value < 1e-4 of the
        # largest, e.g. a pick's impulse against the launch once the start is held out)
        # keep their full-data values instead of being extrapolated wildly
        dp, *_ = np.linalg.lstsq(J[~test] / d, fit.r[~test], rcond=1e-4)
        dp = dp / d
        r[test] = fit.r[test] - J[test] @ dp
        raw[test] = fit.r_raw[test] - J_raw[test] @ dp
    out = {"scalar": float(np.sqrt(np.nanmean(r**2))), "units": {}}
    for c in COORDS:
        rows = np.concatenate([np.arange(sl.start, sl.stop) for j, cc, sl in model.segments
                               if cc == c] or [np.empty(0, int)])
        vals = raw[rows]
        vals = vals[np.isfinite(vals)]
        out[c] = float(np.sqrt(np.mean(vals**2))) if vals.size else None
        # mean square per held-out (shot, fold): the units whose errors are independent
        # (one refit each), in a fixed order, for :func:`heldout_worse_p`
        out["units"][c] = np.array([np.mean(raw[sl][folds[sl] == f] ** 2)
                                    for j, cc, sl in model.segments if cc == c
                                    for f in np.unique(folds[sl][folds[sl] >= 0])])
    return out


def heldout_log_ratio(before: dict, after: dict) -> float:
    """Mean log ratio of ``after``'s to ``before``'s held-out mean squared error over the
    (shot, coordinate, fold) units of :func:`heldout` (< 0: ``after`` predicts better).

    Every unit counts alike, relatively: the pooled RMS is ruled by the worst-predicted
    fold, the first one extrapolated back to the release, which neither model predicts
    (a true pick: x's first fold 972 -> 1331 mm^2 while the three after it went 36, 51,
    212 -> 4, 4, 5 mm^2 -- the pooled RMS rose 5.14 -> 5.33 and the pick, delta-BIC 4080
    over a threshold of 384, was not supported).
    """
    logs = [np.log(a / b) for c in before["units"]
            for b, a in zip(before["units"][c], after["units"].get(c, ()))
            if b > 0 and a > 0]
    return float(np.mean(logs)) if logs else float("nan")


def heldout_worse_p(before: dict, after: dict, coord: str) -> float:
    """One-sided p-value that ``after``'s held-out error in ``coord`` is larger than
    ``before``'s (:func:`heldout` of two fits on the same folds), or nan when untestable.

    A paired t-test on the held-out (shot, fold) units' mean squared errors (the
    Diebold-Mariano comparison of predictive accuracy, with the folds as its blocks: the
    rows of one fold share one refit's error and are far from independent).  An
    extrapolated fold moves by tens of per cent between two fits that agree in-sample
    (a true pick in x: y's held-out RMS 0.00207 -> 0.00233 m, all of it in the last of
    five time blocks), which is not a worse prediction of the data.
    """
    from scipy import stats

    b, a = before["units"].get(coord), after["units"].get(coord)
    if b is None or a is None or b.size != a.size or b.size < 3:
        return float("nan")
    d = a - b
    sd = float(np.std(d, ddof=1))
    if sd == 0.0:
        return 0.0 if d.mean() > 0 else 1.0
    return float(stats.t.sf(d.mean() / (sd / np.sqrt(d.size)), d.size - 1))


def _candidate_model(base: JointModel, cand, values: dict) -> JointModel:
    """The baseline's shots and model with candidate ``cand``, from ``values``."""
    m = JointModel(base.shots, base.baseline, cand, rig=base.rig,
                   phi_per_shot=base.phi_per_shot)
    m.values.update(values)
    return m


def effect_columns(base: JointModel, fit0: FitOut, cand, loc: dict) -> np.ndarray:
    """Whitened d(model)/d(size params) at effect size 0 and location ``loc``."""
    m = _candidate_model(base, cand, fit0.values)
    m.cand_fixed = dict(loc)
    for p in cand.location:
        m.values[p.name] = loc[p.name]
    base_vec, _ = m._model_vector(m.values)
    cols = []
    for p in cand.size:
        step = 1e-3 * max(abs(p.upper - p.lower), 1e-3) / 10.0
        v2 = dict(m.values)
        v2[p.name] = p.null + step
        try:
            vec, _ = m._model_vector(v2)
        except CurltrackError:
            vec, _ = m._model_vector({**v2, p.name: p.null - step})
            step = -step
        cols.append((vec - base_vec) / step)
    return m.whiten(np.column_stack(cols)) if cols else np.zeros((m.n, 0))


def scan_columns(base: JointModel, fit0: FitOut, cand, locs) -> list:
    """Effect columns at every scan location (the effect's own shortcut if it has one,
    e.g. a patch's from half-infinite patches)."""
    return cand.effect.scan_columns(lambda loc: effect_columns(base, fit0, cand, loc), locs)


def score_candidate(base: JointModel, fit0: FitOut, cand, rng,
                    n_boot: int = scoring.N_BOOT) -> CandidateScore:
    """Scan and calibrate one candidate (linear); :func:`refine_candidate` refits it.

    The bootstrap's noise and its blocks are :func:`null_noise`'s: the residuals the
    candidate's best linear fit leaves where it took most of a misfit and left white
    noise, the baseline's elsewhere.
    """
    locs = cand.grid or [{}]
    cols = scan_columns(base, fit0, cand, locs)
    subsets = cand.subsets or [tuple(range(len(cand.size)))]
    n = fit0.n
    keys, sub_cols, ks = [], [], []
    for i, c in enumerate(cols):
        for sub in subsets:
            keys.append((i, sub))
            sub_cols.append(c[:, list(sub)])
            ks.append(len(cand.location) + len(sub))
    bases = scoring.effect_bases(fit0.J, sub_cols)
    stats = scoring.scan_gain(bases, fit0.r) - np.array(ks) * np.log(n)
    best = int(np.argmax(stats))
    i_loc, sub = keys[best]
    k = ks[best]
    lin = float(stats[best])
    r_alt = fit0.r - bases[best] @ (bases[best].T @ fit0.r)
    blocks, r_null = null_noise(base, fit0.r, r_alt)
    thr = scoring.bootstrap_threshold(bases, r_null, blocks, ks, n, rng,
                                      level=_level(cand), n_boot=n_boot,
                                      groups=row_groups(base), J0=fit0.J)
    loc = dict(locs[i_loc])
    score = CandidateScore(cand.name, lin, lin, thr, None, loc, note=cand.note, k=k,
                           extension=cand.extension, per_shot=cand.per_shot)
    score._scan = (sub_cols, ks)  # for the threshold under the candidate's own noise
    if not cand.extension and cand.size:
        lim = np.array(scoring.detection_limits(fit0.J, cols, thr["threshold"],
                                                len(cand.location) + 1, n))
        score.limits = {}
        for j, p in enumerate(cand.size):
            v = lim[:, j][np.isfinite(lim[:, j])]
            if v.size:
                score.limits[p.name] = {"median": float(np.median(v)), "min": float(v.min()),
                                        "max": float(v.max()), "unit": p.unit,
                                        "null": float(p.null)}
    score._blocks = [b for _, b in blocks]
    if sum(b.shape[1] for b in bases) == 0:
        score.note += "; not identifiable with these shots (degenerate with the baseline)"
        score.delta_bic = score.delta_bic_linear = -np.inf
        return score
    # starts for the nonlinear fit: the best few distinct locations, then the best of
    # each region of the sheet / of the shot's time not yet covered.  The linear gain is
    # exact near the null but far from it can rank a wrong place first by a wide margin
    # (a 3 % patch at 9.5-12.8 m: linear delta-BIC 59 there, 83 at 17.9-18.3 m;
    # nonlinear 465 and 170), so the starts must not all sit in one place.
    order = np.argsort(-stats)
    starts = []
    tol = _close_tol(locs)

    def add(idx):
        i2, sub2 = keys[idx]
        loc2 = dict(locs[i2])
        if not any(_close(loc2, st[1], tol) for st in starts):
            starts.append((cols[i2][:, list(sub2)], loc2, sub2, ks[idx]))

    for idx in order:
        add(int(idx))
        if len(starts) >= (cand.n_starts or (N_STARTS if cand.location else 1)):
            break
    if cand.location and cand.n_starts is None:
        region = _regions(locs, N_REGIONS)
        seen = set()
        for idx in order:
            rg = region[keys[idx][0]]
            if rg not in seen:
                seen.add(rg)
                add(int(idx))
    score._refine = (cand, starts)
    return score


#: a coordinate's long-scale variance that the candidate's best linear fit leaves, as a
#: fraction of the baseline's, below which its persistence is taken for the candidate's
#: misfit, not for noise (an order of magnitude)
MISFIT_EXPLAINED = 0.1
#: ... and at least this fraction of it left, with white residuals, for the candidate's
#: residuals to be the bootstrap's noise (:func:`null_noise`)
MISFIT_HALF = 0.5
#: a correlation time (samples) whose 3 tau outlasts the shortest bootstrap block
BLOCK_FRAMES_TAU = scoring.BLOCK_FRAMES / 3.0


def null_noise(base: JointModel, r0, r_alt) -> tuple[list, np.ndarray]:
    """The noise a candidate's threshold is calibrated on: (blocks, residuals to resample).

    ``r0`` are the baseline's whitened residuals, ``r_alt`` the candidate's (its best
    linear location's projection taken out, or its nonlinear refit's).  Per segment:

    * *how long* the noise persists (the blocks, :func:`block_lengths`) is measured on
      ``r_alt`` where the candidate took the bulk of the segment's long-scale variance,
      else on ``r0``.  A strong effect's smooth misfit reads as noise persisting for the
      longest window measured (a 1.27x patch: 9 s blocks put the misfit itself into the
      null, threshold 130062 over the scan's 124116); there the alternative's residuals
      are the noise's estimate (Hall & Wilson 1991), and the candidate explains all but
      0.1-2 % of y's long-scale variance (seven of eight strong patches).  With no effect
      its columns can still take up an instrument's step -- 80 % of a 10 Hz coordinate's
      long-scale variance, in one of 40 clean shots -- and blocks measured on what is
      left cut the steps up: there the baseline's own persistence stands unless the fit
      explains more than ``1 - MISFIT_EXPLAINED`` of it.
    * *what* is resampled is ``r_alt`` where the candidate took at least half of the
      segment's long-scale variance (``MISFIT_HALF``) and left white noise (correlation
      time <= ``CORRELATED_TAU``; for x and y, one position fix, neither's AR(1) rho at
      its bound): an effect's misfit, resampled, is a null that grows with the effect
      (a 6 mm/s pick at 10 Hz under white noise: delta-BIC 224 under a threshold of 288
      from the baseline's residuals, -6.5 from its own), while what the candidate left
      is the noise.  Elsewhere ``r0``: under noise that persists a candidate's columns
      absorb steps - a friction field took 96 % of a clean 10 Hz shot's y variance under
      step noise, and its threshold from what was left (16 against the baseline's 315)
      named it - and on noise it barely changes, ``r0`` is the noise.
    """
    from ..series.noise import CORRELATED_TAU, at_rho_bound

    own = residual_noise(base, r0, pool=False)
    left = residual_noise(base, r_alt, pool=False)
    bound = {j for j, c, _ in base.segments if c in POSITION
             and at_rho_bound(base.shots[j].noise[c])}
    took = [b[0] <= MISFIT_EXPLAINED * a[0] for a, b in zip(own, left)]
    # x and y are one position fix: where what the candidate left of one still persists
    # beyond a bootstrap block, the instrument's errors persist, and the other's noise
    # stays the baseline's too (a friction field took y's steps, x's stayed: y's
    # residuals resampled in 10-frame blocks, threshold 0.9 against a delta-BIC of 85
    # on a clean 10 Hz shot)
    persists = bound | {j for (j, c, _), b, t in zip(base.segments, left, took)
                        if c in POSITION and not t and b[1] > BLOCK_FRAMES_TAU}
    took = [t and not (c in POSITION and j in persists)
            for (j, c, _), t in zip(base.segments, took)]
    # (an instrument whose errors persist, as it says: its slow errors are what a
    # candidate takes, so only one that took the bulk of them - as a strong effect's
    # misfit is taken - has its residuals resampled; a spin impulse that took 83 % of a
    # clean tracked shot's slow theta error had its threshold set at 64 by what was
    # left, 96 by the baseline's residuals, and its delta-BIC of 89 named it)
    misfit = [b[1] <= CORRELATED_TAU and not (c in POSITION and j in persists)
              and b[0] <= (MISFIT_EXPLAINED if base.shots[j].noise_persists
                           else MISFIT_HALF) * a[0]
              for (j, c, _), a, b in zip(base.segments, own, left)]
    r = np.array(r0, dtype=float, copy=True)
    for (_, _, sl), m in zip(base.segments, misfit):
        if m:
            r[sl] = r_alt[sl]
    blocks = block_lengths(base, [b if t else a for a, b, t in zip(own, left, took)])
    return blocks, r


#: an instrument's jump of one position coordinate - from a row to the end of the
#: series, or held for one of these durations (s) and back (:func:`instrument_step`)
STEP_HOLD_S = (0.5, 1.0, 2.0, 3.0)
#: rows a jump may start at, per segment (evenly spread)
STEP_STARTS = 120
#: look-elsewhere level of the largest jump scanned, at which a jump is found
STEP_LEVEL = 0.01
#: rows a jump holds at least (fewer are an outlier's)
STEP_MIN_ROWS = 3
#: sign-flip draws of the residuals that set the chance level of the largest jump
STEP_DRAWS = 400


def _jump_starts(m: int) -> np.ndarray:
    """Rows a jump is scanned from, of ``m`` (:data:`STEP_STARTS`, evenly spread)."""
    return np.unique(np.linspace(1, m - 1, min(STEP_STARTS, m - 1)).astype(int))


def _is_jump(t: np.ndarray, a: int, b: int) -> bool:
    """Whether rows ``a`` to ``b - 1`` (``b`` = ``t.size``: to the end) of rows at times
    ``t`` can be an instrument's jump.

    A jump holds at least the shortest hold and :data:`STEP_MIN_ROWS` rows, and starts
    at least the shortest hold after the first row: a shorter box - one row at either
    end of a series, or a hold across a gap - is an outlier, not a jump, and fitting
    one takes the outlier out of the residuals the chance level is drawn from (clean
    heavy-tailed shots showed a "jump" on their last row at chi-square 168 over 56).
    """
    m, hold = t.size, STEP_HOLD_S[0]
    if t[a] - t[0] < hold or b - a < STEP_MIN_ROWS or b > m:
        return False
    return bool(t[-1] - t[a] >= hold if b == m else t[b] >= t[a] + hold)


def _jump_shapes(t: np.ndarray) -> list[tuple[int, int]]:
    """(first row, row after the last) of every jump scanned on rows at times ``t``:
    from each of :func:`_jump_starts` to the end, or held for each of
    :data:`STEP_HOLD_S` (:func:`_is_jump`)."""
    m = t.size
    shapes = []
    for a in _jump_starts(m):
        holds = [int(b) for b in np.unique(np.searchsorted(t, t[a] + np.array(STEP_HOLD_S)))
                 if b < m]
        shapes += [(int(a), b) for b in (m, *holds) if _is_jump(t, a, b)]
    return shapes


def _jump_columns(base: JointModel, i: int, Q0s: np.ndarray, shapes, m: int):
    """Whitened columns ``E`` of the jumps ``(first row, row after the last)`` of
    segment ``i`` (of ``m`` rows) and their squared norms off the fit's directions
    ``Q0s`` (the fit's orthonormal Jacobian basis on the segment's rows; inf where a
    jump lies in them)."""
    raw = np.zeros((m, len(shapes)))
    for k, (a, b) in enumerate(shapes):
        raw[a:b, k] = 1.0
    E = base.whiten_segment(i, raw)
    proj = Q0s.T @ E
    norm2 = np.sum(E * E, axis=0) - np.sum(proj * proj, axis=0)
    return E, np.where(norm2 > 1e-8 * np.sum(E * E, axis=0), norm2, np.inf)


def _refined_jump(base, i, Q0s, r_perp, t, a, b) -> tuple[int, int]:
    """The jump ``(a, b)`` found on the scan's grid of starts, moved to the best row
    nearby: every start between the grid's neighbours of ``a`` and, for a hold, every
    end within the shortest hold of ``b`` (the grid scans every other row of a 24 s
    10 Hz series - a jump at 14.40 s was placed at 12.56 s, across a gap)."""
    m, hold = t.size, STEP_HOLD_S[0]
    grid = _jump_starts(m)
    k = int(np.searchsorted(grid, a))
    lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]
    ends = ([m] if b == m else range(int(np.searchsorted(t, t[b] - hold)),
                                     int(np.searchsorted(t, t[b] + hold, side="right"))))
    shapes = [(a2, int(b2)) for a2 in range(int(lo), int(hi) + 1) for b2 in ends
              if _is_jump(t, a2, int(b2))]
    gains = []
    for k in range(0, len(shapes), 256):   # (bounded memory)
        E, norm2 = _jump_columns(base, i, Q0s, shapes[k:k + 256], m)
        gains.append((E.T @ r_perp) ** 2 / norm2)
    return shapes[int(np.argmax(np.concatenate(gains)))] if shapes else (a, b)


def instrument_step(base: JointModel, fit: FitOut, seed: int = 0) -> dict | None:
    """The largest jump of one position coordinate in a fit's residuals.

    Position fixes of real instruments jump by centimetres and hold the new error for
    seconds (the issue's LiDAR tracks).  A rock's position cannot jump: a pick, a patch
    or a friction field fitted to such a jump smooths it and leaves a jump's shape
    behind, where a real effect leaves noise.  Every start row (up to
    :data:`STEP_STARTS` per segment) and hold (:data:`STEP_HOLD_S`, or to the end) of
    each position segment is scored by its chi-square gain against ``fit`` (exact: a
    jump's size enters linearly; its columns are projected off the fit's Jacobian).

    The chance level is that of the largest gain over every jump scanned, read off
    :data:`STEP_DRAWS` draws of the whitened residuals - the best jump's share taken
    out - with each row's sign flipped at random (a wild bootstrap), and never under
    the Gaussian Bonferroni level over the jumps scanned.  The draws keep
    the residuals' own spread and tails: a short hold over one outlier of heavy-tailed
    noise (t3 plus 1 % outliers) reached chi-square 50-125 in 4 of 8 clean shots,
    over the 19.7 of a Gaussian Bonferroni level even after scaling by the residuals'
    variance.

    Parameters
    ----------
    base, fit
        The model and one fit of it (the baseline's or a candidate's).
    seed
        Seed of the sign flips (the result is deterministic for a given seed).

    Returns
    -------
    dict or None
        ``gain`` (chi-square), ``delta_bic`` (less ``k ln n`` for its size and
        location(s), as the candidates'), ``threshold`` (the largest gain reached by
        chance at :data:`STEP_LEVEL`: the flips' or Bonferroni's, whichever is larger;
        Bonferroni's alone when the gain does not clear it, the flips then not drawn),
        ``variance`` (the segment's whitened residuals' variance without the jump, at
        least 1: for the record), ``found`` (gain above the threshold), ``shot``,
        ``coord``, ``t_from_s`` (the first row that jumped), ``t_before_s`` (the row
        before it: the jump happened between the two, which a gap in the rows can set
        seconds apart), ``t_to_s`` (the first row back; None: to the end),
        ``n_scanned``; None without position segments.  The jump found on the scan's
        grid is placed on the best row nearby (:func:`_refined_jump`); ``gain`` and
        ``found`` are the grid's, whose chance level the draws measure.
    """
    from scipy import stats

    Q0 = scoring.orth_basis(fit.J)
    r_perp = fit.r - Q0 @ (Q0.T @ fit.r)
    best, scans = None, []
    for i, (j, c, sl) in enumerate(base.segments):
        if c not in POSITION:
            continue
        t = base.shots[j].t[base.shots[j].use[c]]
        m = t.size
        if m < 8:
            continue
        shapes = _jump_shapes(t)
        if not shapes:
            continue
        E, norm2 = _jump_columns(base, i, Q0[sl], shapes, m)
        scans.append((sl, E, norm2))
        proj_r = E.T @ r_perp[sl]
        gain = proj_r ** 2 / norm2
        q = int(np.argmax(gain))
        if best is None or gain[q] > best["gain"]:
            a, b = shapes[q]
            jump = (sl, E[:, q] * (proj_r[q] / norm2[q]))
            dof = m * (fit.n - len(fit.free)) / fit.n - 1.0
            var = max((float(np.sum(r_perp[sl] ** 2)) - gain[q]) / max(dof, 1.0), 1.0)
            best = {"gain": float(gain[q]), "shot": j, "coord": c,
                    "delta_bic": float(gain[q] - (2 if b == m else 3) * np.log(fit.n)),
                    "variance": var}
            where = (i, sl, t, a, b)
    if best is None:
        return None
    i, sl, t, a, b = where
    a, b = _refined_jump(base, i, Q0[sl], r_perp[sl], t, a, b)
    best.update(t_before_s=float(t[a - 1]), t_from_s=float(t[a]),
                t_to_s=float(t[b]) if b < t.size else None)
    best["n_scanned"] = int(sum(E.shape[1] for _, E, _ in scans))
    bonferroni = float(stats.chi2.isf(STEP_LEVEL / best["n_scanned"], 1))
    if best["gain"] <= bonferroni:   # not found whatever the flips say: not drawn
        best.update(threshold=bonferroni, found=False)
        return best
    # the best jump's fitted share (projected off the fit's directions) taken out of
    # the residuals the chance level is drawn from
    col = np.zeros_like(r_perp)
    col[jump[0]] = jump[1]
    r_null = r_perp - (col - Q0 @ (Q0.T @ col))
    rng = np.random.default_rng(seed)
    top = []
    for n_draws in np.diff(np.r_[0:STEP_DRAWS:100, STEP_DRAWS]):   # (bounded memory)
        flips = rng.choice([-1.0, 1.0], size=(r_null.size, n_draws)) * r_null[:, None]
        flips -= Q0 @ (Q0.T @ flips)
        top.append(np.max([np.max((E.T @ flips[sl]) ** 2 / norm2[:, None], axis=0)
                           for sl, E, norm2 in scans], axis=0))
    top = np.concatenate(top)
    # never under the Gaussian Bonferroni level: where the noise model holds that bound
    # is the one to keep (the flips alone put 4 of 60 clean AR(1) shots' jumps over
    # it at chi-square 17-23, where Bonferroni's 19.7 put 1)
    best["threshold"] = max(float(np.quantile(top, 1.0 - STEP_LEVEL)), bonferroni)
    best["found"] = bool(best["gain"] > best["threshold"])
    return best


def _centre(loc: dict) -> float:
    """Where a scan location sits: the mean of its location values (a patch's midpoint,
    a pick's time)."""
    vals = [v for k, v in loc.items() if k != "shot"]
    return float(np.mean(vals)) if vals else 0.0


def _regions(locs, n: int) -> np.ndarray:
    """Region (0..n-1) of each scan location: equal-count bins of its centre, per shot."""
    key = np.array([(loc.get("shot", 0), _centre(loc)) for loc in locs])
    out = np.zeros(len(locs), int)
    for j in np.unique(key[:, 0]):
        idx = np.flatnonzero(key[:, 0] == j)
        ranks = np.argsort(np.argsort(key[idx, 1], kind="stable"), kind="stable")
        out[idx] = int(j) * n + ranks * n // max(idx.size, 1)
    return out


def _close(a: dict, b: dict, tol: float = 1.0) -> bool:
    """Two scan locations closer than ``tol`` (s or m) in every value: the same start."""
    if a.get("shot") != b.get("shot"):
        return False
    return all(abs(a[k] - b[k]) < tol for k in a if k != "shot")


def _close_tol(locs) -> float:
    """1 s or 1 m, but at most a tenth of the scanned time / stretch (a 2 m shot)."""
    vals = [v for loc in locs for k, v in loc.items() if k != "shot"]
    if not vals:
        return 1.0
    span = max(vals) - min(vals)
    return float(min(1.0, 0.1 * span)) if span > 0 else 1.0


def _start_model(base, fit0, cand, E, loc, sub) -> JointModel:
    """Baseline + candidate at scan location ``loc``, sizes from the linear solution."""
    coef, *_ = np.linalg.lstsq(np.column_stack([fit0.J, E]), fit0.r, rcond=None)
    m = _candidate_model(base, cand, fit0.values)
    m.cand_fixed = {k2: v for k2, v in loc.items() if k2 == "shot"}
    for p in cand.location:
        m.values[p.name] = loc[p.name]
    for j, c in zip(sub, coef[fit0.J.shape[1]:]):
        p = cand.size[j]
        m.values[p.name] = float(np.clip(p.null + c, p.lower + 1e-6, p.upper - 1e-6))
    if cand.extension:
        # the whole Gauss-Newton step, the baseline's part too: an extension term is
        # correlated with the friction laws (a spin coupling with phi_theta), and from
        # the baseline's values the fit crawls along that valley and stops early (a
        # spin coupling c = -0.1 stopped at -0.063 after 61 evaluations; from the full
        # step it reached -0.1016 in 12)
        for name, c in zip(fit0.free, coef[:fit0.J.shape[1]]):
            lo, hi = m.bounds[name]
            lo = -np.inf if lo is None else lo
            hi = np.inf if hi is None else hi
            m.values[name] = float(np.clip(fit0.values[name] + c, lo + 1e-9 * (abs(lo) + 1),
                                           hi - 1e-9 * (abs(hi) + 1)))
    # size parameters outside the chosen sub-model stay at their null values
    dropped = [p.name for j, p in enumerate(cand.size) if j not in sub]
    m.free = [f for f in m.free if f not in dropped]
    m.bounds.update(cand.effect.location_bounds(loc, base.shots))
    return m


def refine_candidate(score: CandidateScore, base: JointModel, fit0: FitOut,
                     name: str = "<shots>") -> CandidateScore:
    """Nonlinear fit of baseline + candidate from the best scan locations (in place)."""
    cand, starts = score._refine
    loc_names = [p.name for p in cand.location]
    tried = []
    for E, loc, sub, k in starts:
        m = _start_model(base, fit0, cand, E, loc, sub)
        if len(starts) > 1:
            m.free = [f for f in m.free if f not in loc_names]
        try:
            f = m.fit(max_nfev=START_NFEV if len(starts) > 1 else FIT_MAX_NFEV, name=name,
                      tol=EXTENSION_FIT_TOL if cand.extension else FIT_TOL)
        except CurltrackError as exc:
            score.note += f"; nonlinear fit failed ({exc})"
            continue
        tried.append((f, m, loc, k))
    if not tried:
        return score
    tried.sort(key=lambda q: q[0].chi2)
    if len(starts) > 1:
        # finish the best N_FINISH starts with their locations free: a few iterations
        # with the location fixed do not rank them reliably (the right place may still
        # be walking the baseline back)
        done = []
        for f, m, loc, k in tried[:N_FINISH]:
            nfev0 = m.nfev
            m.free = m.free + [p for p in loc_names if p not in m.free]
            try:
                f = m.fit(max_nfev=FIT_MAX_NFEV, name=name, tol=FIT_TOL)
            except CurltrackError as exc:
                score.note += f"; nonlinear fit failed ({exc})"
                continue
            m.nfev = (nfev0[0] + m.nfev[0], nfev0[1] + m.nfev[1])
            done.append((f, m, loc, k))
        if not done:
            return score
        tried = sorted(done, key=lambda q: q[0].chi2)
    fit1, m, loc, k = tried[0]
    fit1, m = _respread(cand, base, fit1, m, name)
    if not fit1.success:
        score.note += (f"; the nonlinear fit did not converge ({fit1.message}): its "
                       f"numbers are where it stopped")
    score.k = k
    score.location = loc
    score.nfev = getattr(m, "nfev", None)
    _adopt(score, fit1, m, fit0)
    return score


def _continued(m: JointModel, fit: FitOut, name: str) -> FitOut:
    """``fit`` (of ``m``, whose values it holds) run once more from where it stopped
    when its evaluation budget stopped it, not convergence (a 0.73 patch over 4.7 m
    ended 0.26 m inside its ends, 17 over the chi-square the next run reaches, and no
    spread start beat it: seed 56303773 of test_a_patch_refit_widens_a_narrow_deep_start).
    The lower of the two; ``m`` holds its values and both runs' evaluations."""
    if fit.success:
        return fit
    spent = m.nfev
    try:
        again = m.fit(max_nfev=FIT_MAX_NFEV, name=name, tol=FIT_TOL)
    except CurltrackError:
        again = None
    m.nfev = (spent[0] + m.nfev[0], spent[1] + m.nfev[1]) if again is not None else spent
    if again is not None and again.chi2 < fit.chi2:
        return again
    m.values.update(fit.values)
    return fit


def _respread(cand, base: JointModel, fit1: FitOut, m: JointModel, name: str):
    """The refit also started from the effect's size spread differently over its
    location (:attr:`~curltrack.physics.registry.EffectDef.respread`), location free:
    each start runs :data:`START_NFEV` evaluations, and the best is finished when it is
    already below ``fit1``.  Returns the (fit, model) that ends lowest."""
    fit1 = _continued(m, fit1, name)
    starts = cand.effect.respread(fit1.values, base.shots) if cand.effect else []
    best = None
    for start in starts:
        m2 = _candidate_model(base, cand, {**fit1.values, **start})
        m2.cand_fixed = dict(m.cand_fixed) if m.cand_fixed is not None else None
        m2.free, m2.bounds = list(m.free), dict(m.bounds)
        try:
            f2 = m2.fit(max_nfev=START_NFEV, name=name, tol=FIT_TOL)
        except CurltrackError:
            continue
        if f2.chi2 < fit1.chi2 and (best is None or f2.chi2 < best[0].chi2):
            best = (f2, m2)
    if best is None:
        return fit1, m
    m2 = best[1]
    nfev0 = m2.nfev
    try:
        f2 = m2.fit(max_nfev=FIT_MAX_NFEV, name=name, tol=FIT_TOL)
    except CurltrackError:
        return fit1, m
    f2 = _continued(m2, f2, name)
    m2.nfev = (m.nfev[0] + nfev0[0] + m2.nfev[0], m.nfev[1] + nfev0[1] + m2.nfev[1])
    return (f2, m2) if f2.chi2 < fit1.chi2 else (fit1, m)


def _adopt(score: CandidateScore, fit1: FitOut, m: JointModel, fit0: FitOut) -> None:
    """Make ``fit1`` (of model ``m``) the candidate's fit: gain, parameters, structure."""
    cand = score._refine[0]
    score.fit, score._model = fit1, m
    score.chi2_gain = float(fit0.chi2 - fit1.chi2)
    score.delta_bic = float(score.chi2_gain - score.k * np.log(fit0.n))
    score.params, score.params_err = cand.effect.finish(
        {p.name: fit1.values[p.name] for p in cand.params},
        {p.name: fit1.err(p.name) for p in cand.params}, fit1.values, fit1.err,
        score.location)
    score.remark = cand.effect.remark(score.params, m.shots)
    score.structure_after = structure_tests(segments_of(m, fit1))


def segments_of(model: JointModel, fit: FitOut, noise=None):
    """Residual segments with covariates (time, model y, model speed) for the tests.

    ``noise`` (one ``(inflation, tau)`` per segment, :func:`residual_noise`) scales the
    residuals by the noise the AR(1) model left in them."""
    from .residuals import Segment, noise_dof

    out = []
    noise = noise or [(1.0, 1.0)] * len(model.segments)
    for (j, c, sl), (infl, tau) in zip(model.segments, noise):
        s = model.shots[j]
        use = s.use[c]
        pred = fit.predictions[j]
        t = s.t
        vx = np.gradient(pred["x"], t) if t.size > 1 else np.zeros_like(t)
        vy = np.gradient(pred["y"], t) if t.size > 1 else np.zeros_like(t)
        speed = np.hypot(vx, vy)
        out.append(Segment(j, c, fit.r[sl] / np.sqrt(infl), t[use], pred["y"][use],
                           speed[use], s.spin, tau=tau, noise_dof=noise_dof(t[use], tau)))
    return out


#: coordinates measured together by one position fix: their noise persists alike, and
#: its correlation time is measured on both (:func:`residual_noise`)
POSITION = ("x", "y")


def residual_noise(model: JointModel, r, pool: bool = True) -> list:
    """``(inflation, tau)`` of each segment's whitened residuals ``r``
    (:func:`.noise.residual_structure`).

    ``inflation`` is each segment's own (x, y and theta have their own noise levels);
    ``tau``, how long the noise persists, is a property of the instrument, and x and y
    of a shot come from one position fix: their ``tau`` is measured on both together
    (summed long-scale variance over summed variance).  Each alone rests on the median
    of the ~7 independent windows of a 20 s shot: under step-like instrument noise
    at 10 Hz one coordinate in three came out <= 1.5 (taken for whitened noise, so that
    the white-noise tests fired on the steps), both together one shot in eight, while
    white, AR(1) and heavy-tailed noise pass as often as before (87, 80-85, 85-88 %;
    300 pure-noise series each).  And where the AR(1) model's rho is at its bound
    (:func:`~curltrack.series.noise.at_rho_bound`) the noise is counted as persisting
    (``tau`` just above :data:`~curltrack.series.noise.CORRELATED_TAU`): with both, step
    noise at 10 Hz passed for whitened in 1 % of 400 pure-noise shots (10.5 % with the
    pooled tau alone), the other classes as often as before.  A session's shots share
    one instrument (:func:`_instrument_wide`): where most persist, all do, each at no
    less than the session's median ``inflation`` per coordinate.  ``pool=False``: each
    segment's own values (the bootstrap's blocks, :func:`block_lengths`: a misfit in one
    coordinate must not lengthen the other's).
    """
    from ..series.noise import CORRELATED_TAU, residual_structure

    out = [residual_structure(r[sl], model.shots[j].t[model.shots[j].use[c]])
           for j, c, sl in model.segments]
    if not pool:
        return out
    out = _pooled_tau(model, out)
    _, persists, session = _persisting(model, out)
    # its long-scale variance is the instrument's too: a shot whose few windows missed
    # its steps is held to the session's median level (else a patch fitted to one such
    # step cleared its threshold)
    for c in session:
        idx = [i for i, (_, cc, _) in enumerate(model.segments) if cc == c]
        level = float(np.median([out[i][0] for i in idx]))
        for i in idx:
            out[i] = (max(out[i][0], level), out[i][1])
    for i, (j, c, _) in enumerate(model.segments):
        if (j, c) in persists:
            out[i] = (out[i][0], max(out[i][1], float(np.nextafter(CORRELATED_TAU, np.inf))))
    return out


def _pooled_tau(model: JointModel, noise) -> list:
    """``noise`` with x's and y's ``tau`` of each shot measured on both together (summed
    long-scale variance over summed variance): one position fix."""
    out = list(noise)
    for j in {j for j, _, _ in model.segments}:
        idx = [i for i, (jj, c, _) in enumerate(model.segments)
               if jj == j and c in POSITION]
        if len(idx) < 2:
            continue
        infl = sum(out[i][0] for i in idx)
        var = sum(out[i][0] / out[i][1] for i in idx)
        tau = float(infl / var) if var > 0 else 1.0
        for i in idx:
            out[i] = (out[i][0], max(1.0, tau))
    return out


def _persisting(model: JointModel, pooled) -> tuple[set, set, set]:
    """Segments ``(shot, coord)`` whose noise persists, from ``pooled`` (``(inflation,
    tau)`` per segment, x's and y's tau pooled: :func:`_pooled_tau`): (those whose AR(1)
    model sits at its rho bound or whose instrument says so, those whose noise persists - that, or tau above
    :data:`~curltrack.series.noise.CORRELATED_TAU`, widened by :func:`_instrument_wide` -
    and the coordinates where it holds session-wide).

    An AR(1) model at its bound (rho = RHO_MAX) did not whiten the noise, whatever the
    few windows say: the noise persists (for x and y together, one position fix).  So
    does every coordinate of a shot whose instrument says so
    (:attr:`~curltrack.discover.shots.ShotData.noise_persists`)."""
    from ..series.noise import CORRELATED_TAU, at_rho_bound

    bound = {(j, c) for j, c, _ in model.segments if at_rho_bound(model.shots[j].noise[c])}
    flagged = bound | {(j, c) for (j, c, _), (_, tau) in zip(model.segments, pooled)
                       if tau > CORRELATED_TAU}
    persists, session = _instrument_wide(model, flagged)
    # (and every coordinate of a shot whose instrument says its errors persist, in both
    # sets, though not in the session's majority: a single tracked shot's few windows
    # rarely show it - 3 of 45 clean shots through real cameras were 'unexplained' by
    # its binned means, z 3.4-4.9 - and 10-frame bootstrap blocks cut up errors that
    # hold for 0.05 s to the whole clip, median ~0.3 s)
    declared = {(j, c) for j, c, _ in model.segments if model.shots[j].noise_persists}
    return bound | declared, persists | declared, session


def _instrument_wide(model: JointModel, flagged: set) -> tuple[set, set]:
    """Segments ``(shot, coord)`` whose noise persists, given those ``flagged`` by their
    own evidence, and the coordinates where that holds session-wide.

    x and y of a shot come from one position fix: one flagged flags both, and its theta,
    measured by the same instrument on the same frames, with them (theta alone is one
    segment of ~7 windows: step-like errors in it passed for white noise and its
    binned-mean test named a clean 10 Hz shot 'unexplained').  The shots of
    one analysis come from one instrument: when the noise persists in most of three or
    more shots it persists in all, and a shot whose few windows said otherwise (one in
    eight under step noise) is not held to the white-noise tests or cut into short
    bootstrap blocks - in sessions of 3-8 such shots that alone made 3 in 20
    'unexplained'.  Returns (the segments, the coordinates flagged session-wide).
    """
    out = set(flagged)
    segments = {(j, c) for j, c, _ in model.segments}
    out |= {(j, q) for j, c in flagged if c in POSITION for q in (*POSITION, "theta")
            if (j, q) in segments}
    session = set()
    for kind in (POSITION, ("theta",)):
        shots = sorted({j for j, c, _ in model.segments if c in kind})
        held = [j for j in shots if any((j, c) in out for c in kind)]
        if len(shots) >= 3 and 2 * len(held) > len(shots):
            out |= {(j, c) for j in shots for c in kind}
            session |= {c for _, c, _ in model.segments if c in kind}
    return out, session


def _level(cand) -> float:
    """False-alarm level of a candidate's threshold (an extension's own, see
    :mod:`curltrack.physics.extensions`)."""
    return cand.level or scoring.CANDIDATE_LEVEL


def block_lengths(model: JointModel, noise) -> list:
    """Bootstrap blocks per segment: >= 3 correlation times of the residuals, and where
    the AR(1) model's rho is at its bound (:func:`~curltrack.series.noise.at_rho_bound`,
    x and y together) as long as the longest stretch the residual-noise model counts as
    noise (:data:`~curltrack.series.noise.HIGHPASS_S`).

    A block bootstrap keeps the noise's correlations only within its blocks: blocks
    shorter than an instrument's steps (held 0.5-3 s) cut them up and leave the
    replicates a fraction of the data's low-frequency noise, which is what a smooth
    effect's chi-square gain is made of.  tau itself is an integrated correlation time
    from a median over a few windows, often 2-5x low under such noise, so 3 tau is no
    measure of how long the errors hold (one clean 10 Hz position-only shot under step
    noise: the 99 % point of a pick's null delta-BIC was 90 with 1 s blocks, 175 with
    6 s blocks; the data's 161 had named a pick).  But tau also grows with a real
    effect's misfit, and long blocks then carry the misfit into the replicates (a
    moderate ice slope's threshold rose 750 -> 3500, undetected); the second
    differences' rho is the evidence a smooth misfit cannot give - or a session whose
    noise persists in most of its shots (:func:`_instrument_wide`): a misfit would have
    to be in most of them, and blocks of 3 tau there set a clean 8-shot session's patch
    threshold at 50 (its delta-BIC 51) where 6 s blocks set it at 75.
    """
    from ..series.noise import HIGHPASS_S

    # (a session whose noise persists in most shots: long blocks in every shot)
    bound, _, session = _persisting(model, _pooled_tau(model, noise))
    bound, _ = _instrument_wide(model, bound)
    bound |= {(j, c) for j, c, _ in model.segments if c in session}
    out = []
    for (j, c, sl), (_, tau) in zip(model.segments, noise):
        b = max(scoring.BLOCK_FRAMES, int(np.ceil(3 * tau)))
        if (j, c) in bound:
            s = model.shots[j]
            t = s.t[s.use[c]]
            dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
            if dt > 0:
                b = max(b, int(round(HIGHPASS_S / dt)))
        out.append((sl, b))
    return out


def rescore(score: CandidateScore, base: JointModel, fit0: FitOut, rng,
            n_boot: int = scoring.N_BOOT) -> None:
    """Judge a refitted candidate under the noise its own residuals show.

    The AR(1) model of second differences misses an instrument's persisting errors and
    heavy tails.  The candidate's residuals are what is left once it explains what it
    can: their long-scale variance per segment (``inflation``) is the noise against which
    its chi-square gain, its look-elsewhere threshold (block bootstrap of
    :func:`null_noise`'s residuals, blocks >= 3 correlation times, never shorter than
    the scan's: see :func:`_no_shorter`) and the structure after it are measured.
    Under the baseline (no effect) the candidate's residuals carry the instrument's
    noise and the gain shrinks with it; with a real effect they are noise-like and
    nothing changes.  The threshold calibrates the linearised scan, so where the scale
    is not 1 the data's linearised delta-BIC under it must clear the threshold as well
    (``linear_clears``).  And the evidence must stand without the few rows that carry
    most of it (:func:`_judge_few_rows`), and move the path beyond the errors a
    persisting instrument states for its rows (:func:`_judge_stated`).
    """
    if score.fit is None:
        return
    noise = residual_noise(base, score.fit.r)
    score.noise = noise
    noise_raw = residual_noise(base, score.fit.r, pool=False)
    scale = np.empty(fit0.n)
    for (_, _, sl), (infl, _) in zip(base.segments, noise):
        scale[sl] = 1.0 / np.sqrt(infl)
    score._scale = scale
    _judge_stated(score, base, fit0)
    groups = row_groups(base)
    if np.all(scale == 1.0):
        _judge_few_rows(score, fit0, scale, groups)
        return
    gain = float(np.sum((fit0.r * scale) ** 2) - np.sum((score.fit.r * scale) ** 2))
    n = fit0.n
    score.chi2_gain = gain
    score.delta_bic = float(gain - score.k * np.log(n))
    sub_cols, ks = score._scan
    bases = scoring.effect_bases(fit0.J * scale[:, None], [c * scale[:, None] for c in sub_cols])
    _, r_null = null_noise(base, fit0.r, score.fit.r)
    score.threshold = scoring.bootstrap_threshold(bases, r_null * scale,
                                                  _no_shorter(block_lengths(base, noise_raw),
                                                              score._blocks), ks, n, rng,
                                                  level=_level(score._refine[0]),
                                                  n_boot=n_boot, groups=groups,
                                                  J0=fit0.J * scale[:, None])
    # the threshold is a quantile of the *linearised* scan's best delta-BIC (exact near
    # the null).  Noise that persists is far from that: its excursions are many AR(1)
    # sigmas, and a nonlinear refit with its locations free can gain more on them than
    # the linearisation at the scan's places.  The data are judged by the statistic
    # the null calibrates too: their linearised delta-BIC under the same scale must
    # clear the threshold as well as the refit's.
    lin = float((scoring.scan_gain(bases, fit0.r * scale)
                 - np.asarray(ks, float) * np.log(n)).max()) if bases else -np.inf
    score.delta_bic_linear = lin
    score.linear_clears = bool(lin > score.threshold["threshold"])
    if not score.linear_clears and score.delta_bic > score.threshold["threshold"]:
        score.note += (f"; its linearised delta-BIC {lin:.1f} (the statistic the threshold "
                       f"calibrates) does not clear the threshold: not supported")
    score.structure_after = structure_tests(segments_of(score._model, score.fit, noise))
    _judge_few_rows(score, fit0, scale, groups)


#: a candidate that moves the fitted path by no more than this many times the sigma the
#: instrument states for its rows, where it says its errors persist, is not told from
#: those errors: each row's stated sigma is its whole error, slow parts included, and
#: a slow error moves a stretch of rows together within that band
STATED_Z = 2.0


def _judge_stated(score: CandidateScore, base: JointModel, fit0: FitOut) -> None:
    """Whether ``score``'s refit moves the path beyond the errors its instrument states
    (:data:`STATED_Z`).  Only where every coordinate of every shot has them and says its
    errors persist (a tracker's sidecar does); elsewhere the rule does not apply.

    Clean shots tracked through real cameras: picks of 0.004 m/s and 0.04-0.06 rad/s
    cleared their thresholds by fitting a tracker's slow wander of 0.5-2 mm, under its
    stated sigma_xy of 0.9-5 mm."""
    worst = 0.0
    for j, c, sl in base.segments:
        v = stated_sigma_rows(base.shots[j], c)
        if v is None or not np.all(np.isfinite(v) & (v > 0)):
            return
        change = np.abs(fit0.r_raw[sl] - score.fit.r_raw[sl])
        worst = max(worst, float(np.max(change / v)) if change.size else 0.0)
    score.path_change_stated = worst
    score.beyond_stated = worst > STATED_Z
    if not score.beyond_stated:
        score.note += (f"; it moves the fitted path by at most {worst:.2g} times the sigma "
                       f"the instrument states for its rows, whose errors persist: not told "
                       f"from them, not supported")


def row_groups(model: JointModel) -> np.ndarray:
    """The row (one frame of one shot) of each of ``model``'s residuals, as an int."""
    size = max((s.t.size for s in model.shots), default=0)
    out = [j * size + np.flatnonzero(model.shots[j].use[c]) for j, c, _ in model.segments]
    return np.concatenate(out) if out else np.zeros(0, dtype=int)


def _judge_few_rows(score: CandidateScore, fit0: FitOut, scale, groups) -> None:
    """Whether ``score``'s evidence stands without the rows that carry most of it
    (:func:`.scoring.without_few_rows`): its delta-BIC without them must clear the level
    that chance reaches so (the bootstrap's ``threshold_few_rows``).

    Tracked footage: 5 of 8 picks that cleared their look-elsewhere thresholds on clean
    shots through real cameras drew half their chi-square gain from 1 to 4 rows within
    0.15 s of the release (the tracker's first rows), fitted by an 'impulse' before
    them.  The bootstrap cannot hold such errors: it resamples the noise as if the
    same everywhere, and the first rows' are not.  ``groups``: the row of each residual
    (:func:`row_groups`)."""
    share = (fit0.r * scale) ** 2 - (score.fit.r * scale) ** 2
    # (and the baseline refitted without them: rows far off pull its fit, and a candidate
    # that takes them away gains on the other rows too)
    J0 = fit0.J * scale[:, None]
    Q0 = scoring.orth_basis(J0)
    r0 = fit0.r * scale
    gain, rows = scoring.few_rows(share[:, None], groups)
    refit = scoring.refit_gain_without(Q0, r0 - Q0 @ (Q0.T @ r0), rows[0])
    dbic = float(gain[0]) - refit - score.k * np.log(fit0.n)
    thr = score.threshold
    # (calibrated as the data's statistic is; the absolute floor of strong evidence,
    # :func:`.scoring.support_level`, is the whole gain's: without its best rows a real
    # effect's gain near the threshold falls by the few largest noise terms, 5-7)
    level = thr.get("threshold_few_rows", thr["threshold"])
    score.delta_bic_without_few_rows = float(dbic)
    score.robust_clears = bool(dbic > level)
    if not score.robust_clears and score.delta_bic > scoring.support_level(thr["threshold"]):
        score.note += (f"; without the {scoring.FEW_ROWS} rows that carry most of its gain "
                       f"its delta-BIC is {dbic:.1f}, under the {level:.1f} chance reaches so: "
                       f"the evidence rests on a few rows (an instrument's glitch looks like "
                       f"that, an effect on the rock's motion does not): not supported")


def judged_like(best, o, r0) -> tuple:
    """(chi-square gain, delta-BIC) of the refitted rival ``o`` under the noise level
    ``best`` is judged by (:func:`rescore`'s per-segment scale), or ``o``'s own
    when either was not refitted or no baseline residuals ``r0`` are given.

    Each candidate's own delta-BIC divides its gain by the level its own residuals show,
    a median over a few windows: under white noise 1 to ~1.3 by chance.  Rivals are
    compared in one unit: two shots with a lateral ice slope (10 Hz, 2 mm) - the slope
    and a pick in one shot took chi-square 238.7 and 237.4 off the baseline's, but the
    slope's residuals read 20 % noisier, and the pick was named ahead of it by 34.
    """
    if r0 is None or best._scale is None or o.fit is None or best.fit is None:
        return o.chi2_gain, o.delta_bic
    scale = best._scale
    gain = float(np.sum((r0 * scale) ** 2) - np.sum((o.fit.r * scale) ** 2))
    return gain, gain - o.k * np.log(r0.size)


def _no_shorter(blocks, initial) -> list:
    """``blocks`` (slice, length) lengthened to the scan's ``initial`` lengths.

    A refit candidate's residuals are the noise's estimate once it explains what it can,
    but with no effect it explains the instrument's largest steps, and its residuals'
    correlation time drops with them: blocks re-measured on them would calibrate the
    data's own steps against replicates that cut them up."""
    if not initial:
        return blocks
    return [(sl, max(b, b0)) for (sl, b), b0 in zip(blocks, initial)]


def best_extension(scores) -> CandidateScore | None:
    """The extension that could be reported: the largest delta-BIC among the refitted
    extensions above their threshold (None: none is)."""
    ext = [sc for sc in scores if sc.extension and sc.fit is not None
           and sc.delta_bic > scoring.support_level(sc.threshold["threshold"])]
    return max(ext, key=lambda q: q.delta_bic) if ext else None


def profile_extension(sc: CandidateScore, fit0: FitOut, name: str = "<shots>") -> bool:
    """Profile-likelihood estimate and errors of an extension's parameters
    (:mod:`.profile`), in place: ``params_err``, ``profile``, ``cov_profile``.

    When a parameter's profile reaches a lower chi-square than the joint fit (which
    stopped short along a valley), the joint fit is restarted from there and adopted.
    Returns whether the fit changed (held-out errors and the rescoring are then stale).
    """
    import copy

    from .profile import MOVE_CHI2, corrected_cov, profile_errors

    cand = sc._refine[0]
    scale = sc._scale if sc._scale is not None else np.ones(sc.fit.n)
    errs = profile_errors(sc._model, sc.fit, [p.name for p in cand.params], scale)
    moved = False
    best = max(errs.values(), key=lambda e: e["shift"], default=None)
    if best is not None and best["shift"] > MOVE_CHI2:
        m = copy.copy(sc._model)
        m.values = dict(best["values"])
        m.free = list(sc.fit.free)
        m.bounds = dict(sc._model.bounds)
        try:
            f = m.fit(max_nfev=FIT_MAX_NFEV, name=name, tol=EXTENSION_FIT_TOL)
        except CurltrackError:
            f = None
        chi = (lambda q: float(np.sum((q.r * scale) ** 2)))
        if f is not None and chi(f) < chi(sc.fit) - MOVE_CHI2:
            _adopt(sc, f, m, fit0)
            moved = True
            for pname, e in errs.items():  # the widths stand; the covariance is the new fit's
                e["sigma_cov"] = f.err(pname)
                e["sigma"] = max(e["sigma"], e["sigma_cov"])
    for e in errs.values():
        e.pop("values", None)
    sc.profile = errs
    sc.cov_profile = corrected_cov(sc.fit, errs)
    for pname, e in errs.items():
        if pname in sc.params_err:
            sc.params_err[pname] = e["sigma"]
    return moved
