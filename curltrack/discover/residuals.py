"""Tests for structure in whitened residuals (what a model gets wrong, and where).

Every function takes residuals that have been divided by the measurement noise and
AR(1)-whitened (:mod:`curltrack.series.noise`), so that under a correct model they are
close to independent unit-variance noise.  Tests:

* positive autocorrelation up to ``h`` lags (variance-ratio form; one-sided, since a
  misfit correlates residuals positively -- :func:`ljung_box` is kept for reports),
* Wald-Wolfowitz runs test on the signs (one-sided: too few runs),

  both on the means of :data:`SMOOTH_S` stretches (:func:`smooth_means`),
* binned means against a covariate (time, position along the sheet, speed): the sum of
  ``n_b * mean_b**2`` over bins is chi-square with ``n_bins`` degrees of freedom,
  and the worst bin says where the misfit sits,
* spin direction (several shots): do the mean lateral residuals of clockwise and
  counter-clockwise shots differ?

:func:`structure_tests` runs all of them on every (shot, coordinate) segment and combines
the p-values with a Bonferroni correction.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage, stats

from ..series.noise import CORRELATED_TAU
from .shots import stated_sigma_rows

#: family-wise level at which residuals are called structured
STRUCTURE_LEVEL = 0.01
#: the autocorrelation and runs tests read means over this span (s): a misfit of the
#: rock's motion is smooth over it, while an instrument's errors that swing faster (a
#: camera vibrating at a few Hz, values rounded to a centimetre while the rock moves) do
#: not survive the mean.  Sample by sample, such errors made long runs of one sign and
#: positive autocorrelation that no physics makes (2 clean shots in 10 'unexplained'
#: under each; 0/40 and 1/40 with the means)
SMOOTH_S = 0.2
#: lags of those means the autocorrelation test sums: 1 s (the samples' 20 lags had the
#: same power for a smooth misfit, and 19 % false alarms under a 1.5-6 Hz vibration)
SMOOTH_LAGS = 5


def _acf(r, h):
    """(n, h, autocorrelations at lags 1..h) of ``r``; acf None when ``r`` is too short
    (n < 3h) or constant.  Default h = min(20, n // 5)."""
    r = np.asarray(r, dtype=float)
    n = r.size
    h = int(h or max(1, min(20, n // 5)))
    c = r - r.mean()
    denom = float(np.dot(c, c))
    if n < 3 * h or denom == 0.0:
        return n, h, None
    return n, h, np.array([np.dot(c[k:], c[:-k]) / denom for k in range(1, h + 1)])


def ljung_box(r, h: int | None = None) -> tuple[float, float]:
    """Ljung-Box Q statistic and p-value for autocorrelation up to ``h`` lags.

    Parameters
    ----------
    r : array
        Whitened residuals (unit variance under the null), in time order.
    h : int, optional
        Number of lags; default ``min(20, n // 5)``.
    """
    n, h, acf = _acf(r, h)
    if acf is None:
        return 0.0, 1.0
    q = n * (n + 2) * float(np.sum(acf**2 / (n - np.arange(1, h + 1))))
    return q, float(stats.chi2.sf(q, h))


def variance_ratio(r, h: int | None = None) -> tuple[float, float]:
    """One-sided test for positive autocorrelation: ``z = sqrt(n) sum_{k<=h} acf_k / sqrt(h)``.

    A smooth misfit makes all low-lag autocorrelations positive (z >> 0); an imperfect
    noise model (over-whitening) makes them negative, which is not a misfit and is not
    flagged.  Returns (z, p) with p = P(Z > z).
    """
    n, h, acf = _acf(r, h)
    if acf is None:
        return 0.0, 1.0
    z = float(np.sqrt(n) * acf.sum() / np.sqrt(h))
    return z, float(stats.norm.sf(z))


def runs_test(r) -> tuple[float, float]:
    """Wald-Wolfowitz runs test on the signs of ``r``: (z, one-sided p of too few runs).

    Too few runs (long stretches of one sign) is what a smooth misfit produces; too
    many runs only says the noise model over-whitens, and is not flagged.
    """
    s = np.asarray(r) > 0
    n1, n2 = int(s.sum()), int((~s).sum())
    n = n1 + n2
    if n1 == 0 or n2 == 0:
        return -np.inf, 0.0
    runs = 1 + int(np.count_nonzero(s[1:] != s[:-1]))
    mu = 2.0 * n1 * n2 / n + 1.0
    var = 2.0 * n1 * n2 * (2.0 * n1 * n2 - n) / (n * n * (n - 1.0))
    z = (runs - mu) / np.sqrt(var) if var > 0 else 0.0
    return float(z), float(stats.norm.cdf(z))


def binned_means(r, key, n_bins: int = 10, noise_dof: float = np.inf) -> dict:
    """Chi-square of bin means of ``r`` against a covariate ``key`` (equal-count bins).

    ``noise_dof``: the degrees of freedom of the noise level ``r`` was scaled by.  A level
    measured from few independent stretches (an instrument's errors that persist for
    seconds: a 20 s shot holds a handful) is itself uncertain, and the statistic over
    ``n_bins`` is then F(n_bins, noise_dof)-distributed, not chi-square: its p-value is
    the F's (the same chi2 and z are reported).

    Returns
    -------
    dict
        ``chi2``, ``dof``, ``p``, and the worst bin: ``lo``, ``hi`` (range of ``key``),
        ``z`` (its mean in units of its standard error).
    """
    r = np.asarray(r, dtype=float)
    key = np.asarray(key, dtype=float)
    n_bins = int(max(1, min(n_bins, r.size // 8)))
    order = np.argsort(key, kind="stable")
    chunks = np.array_split(order, n_bins)
    z = np.array([r[c].sum() / np.sqrt(len(c)) for c in chunks])
    chi2 = float(np.sum(z**2))
    worst = int(np.argmax(np.abs(z)))
    p = (float(stats.chi2.sf(chi2, n_bins)) if not np.isfinite(noise_dof) else
         float(stats.f.sf(chi2 / n_bins, n_bins, max(noise_dof, 1.0))))
    return {"chi2": chi2, "dof": n_bins, "p": p,
            "lo": float(key[chunks[worst]].min()), "hi": float(key[chunks[worst]].max()),
            "z": float(z[worst])}


@dataclass
class Segment:
    """Whitened residuals of one coordinate of one shot with their covariates.

    Attributes
    ----------
    shot : int
        Index of the shot.
    coord : str
        ``"x"``, ``"y"`` or ``"theta"``.
    r : array
        Whitened residuals (dimensionless), in time order.
    t, y, speed : array
        Time (s), model position along the sheet (m) and model speed (m/s) of each row.
    spin : int
        Sign of the shot's spin (+1 counter-clockwise).
    """

    shot: int
    coord: str
    r: np.ndarray
    t: np.ndarray
    y: np.ndarray
    speed: np.ndarray
    spin: int = 1
    #: correlation time (samples) the noise itself leaves in ``r`` (see
    #: :func:`curltrack.series.noise.residual_structure`)
    tau: float = 1.0
    #: degrees of freedom of the noise level ``r`` is scaled by (inf: the AR(1) model's,
    #: from every second difference; a persisting noise's: :func:`noise_dof`)
    noise_dof: float = np.inf


def noise_dof(t, tau: float) -> float:
    """Degrees of freedom of a persisting noise's level measured on times ``t`` (s).

    For ``tau`` <= :data:`~curltrack.series.noise.CORRELATED_TAU` (the AR(1) model whitened
    the noise) inf.  Else the level is :func:`~curltrack.series.noise.residual_structure`'s
    median of window sums over ``WINDOW_S``: about ``T / WINDOW_S`` independent windows,
    and a median of chi-square(1) values is as precise as a variance estimate with 0.37
    times as many degrees of freedom (its asymptotic relative variance, 5.4 / m, against
    2 / nu).
    """
    from ..series.noise import WINDOW_S

    if tau <= CORRELATED_TAU or len(t) < 2:
        return np.inf
    return max(1.0, 0.37 * float(np.ptp(t)) / WINDOW_S)


@dataclass
class StructureResult:
    """Outcome of :func:`structure_tests`.

    Attributes
    ----------
    p_min_adjusted : float
        Smallest p-value times the number of tests (Bonferroni), capped at 1.
    structured : bool
        ``p_min_adjusted < level``.
    tests : list of dict
        One entry per test: shot, coord, test, statistic, p, and for binned tests where.
    where : dict or None
        The most significant binned misfit: shot, coordinate, time and position range.
    """

    p_min_adjusted: float
    structured: bool
    tests: list = field(default_factory=list)
    where: dict | None = None

    def as_dict(self) -> dict:
        return {"p_min_adjusted": self.p_min_adjusted, "structured": self.structured,
                "where": self.where, "tests": self.tests}


def smooth_means(r, t) -> np.ndarray:
    """Means of ``r`` over consecutive stretches of :data:`SMOOTH_S` (in samples, from
    the median spacing of the times ``t``, s), times the square root of their length:
    independent unit-variance values stay so.  The last partial stretch is dropped."""
    r = np.asarray(r, dtype=float)
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 0.0
    b = int(max(1, round(SMOOTH_S / dt))) if dt > 0 else 1
    if b == 1:
        return r
    return r[: r.size // b * b].reshape(-1, b).mean(axis=1) * np.sqrt(b)


def structure_tests(segments, level: float = STRUCTURE_LEVEL) -> StructureResult:
    """Run every structure test on every segment; Bonferroni-combine.

    Parameters
    ----------
    segments : list of Segment
    level : float
        Family-wise significance level.
    """
    tests = []
    for seg in segments:
        if seg.r.size < 20:
            continue
        base = {"shot": seg.shot, "coord": seg.coord}
        if seg.tau <= CORRELATED_TAU:
            # noise that is itself correlated (an instrument's persisting errors) makes
            # these fire whatever the model; then the binned means below, whose
            # residuals are scaled by the noise's long-scale variance, carry the test
            rs = smooth_means(seg.r, seg.t)
            z, p = variance_ratio(rs, SMOOTH_LAGS)
            tests.append({**base, "test": "autocorrelation", "stat": z, "p": p})
            z, p = runs_test(rs)
            tests.append({**base, "test": "runs", "stat": z, "p": p})
        for cov, key in (("time", seg.t), ("position_y", seg.y), ("speed", seg.speed)):
            if np.ptp(key) <= 0:
                continue
            b = binned_means(seg.r, key, noise_dof=seg.noise_dof)
            tests.append({**base, "test": f"binned_{cov}", "stat": b["chi2"], "p": b["p"],
                          "lo": b["lo"], "hi": b["hi"], "z": b["z"]})
    lateral = [s for s in segments if s.coord == "x" and s.r.size >= 20]
    spins = {s.spin for s in lateral}
    if len(spins) == 2:
        means = {sp: np.concatenate([s.r for s in lateral if s.spin == sp]) for sp in spins}
        a, b = means[1], means[-1]
        z = (a.mean() - b.mean()) / np.sqrt(1.0 / a.size + 1.0 / b.size)
        tests.append({"shot": None, "coord": "x", "test": "spin_direction", "stat": float(z),
                      "p": float(2 * stats.norm.sf(abs(z)))})
    if not tests:
        return StructureResult(1.0, False, [], None)
    p_adj = min(1.0, min(t["p"] for t in tests) * len(tests))
    binned = [t for t in tests if t["test"] == "binned_time"]
    where = None
    if binned:
        w = min(binned, key=lambda t: t["p"])
        seg = next(s for s in segments if s.shot == w["shot"] and s.coord == w["coord"])
        sel = (seg.t >= w["lo"]) & (seg.t <= w["hi"])
        where = {"shot": w["shot"], "coord": w["coord"], "t_from_s": w["lo"],
                 "t_to_s": w["hi"], "y_from_m": float(seg.y[sel].min()),
                 "y_to_m": float(seg.y[sel].max()), "z": w["z"], "p": w["p"]}
    return StructureResult(float(p_adj), bool(p_adj < level), tests, where)


#: a coordinate's baseline residuals this many times the rows' own scatter (RMS over
#: the rows' median sigma) are a misfit no noise model of the rows explains ...
#: (clean shots of every class but steps stay under 1.1; a peer simulator's draws
#: missed no coordinate by 3x in 3 of 111, 2.5-2.7x there, and said ``none``; 3 until
#: session 31)
SMOOTH_MISFIT_RATIO = 2.0
#: ... when their increments do not jump: the one-sided kurtosis test of the residuals'
#: first differences, less their running mean over :data:`JUMP_WINDOW_S`, does not
#: reject a Gaussian at this level (an instrument's step-like errors are jumps: p < 1e-6
#: on every step-noise segment of 140 clean cases that reached the size gate)
JUMP_LEVEL = 1e-3
#: the running mean taken off the increments before the jump test (s, at least 5 rows):
#: a misfit of the rock's motion changes its residuals' slope over a second or more,
#: an instrument's step in one row
JUMP_WINDOW_S = 1.0
#: increments this close to a stop (s) are left out of the jump test: the model ends the
#: motion sharply there, and a stop it places or shapes differently from the rock's
#: leaves a few large increments of one sign (a peer simulator's spin, held to the stop,
#: left six rows of 4-5 sigma after it: p 4e-9 on the raw increments, verdict ``none``)
JUMP_STOP_MARGIN_S = 0.5


def jump_p_value(r, t, stops=()) -> float:
    """p-value that residuals ``r`` at times ``t`` (s) change by jumps (heavy-tailed
    increments) rather than smoothly.

    The one-sided kurtosis test of their first differences less the differences'
    running mean over :data:`JUMP_WINDOW_S` (a linear filter: Gaussian increments stay
    Gaussian, while a jump in one row keeps all but 1/window of its size), leaving out
    the increments within :data:`JUMP_STOP_MARGIN_S` of any of ``stops`` (s).
    """
    t = np.asarray(t, dtype=float)
    d = np.diff(np.asarray(r, dtype=float))
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    window = max(5, int(round(JUMP_WINDOW_S / dt)) | 1) if dt > 0 else 5
    d = d - ndimage.uniform_filter1d(d, size=min(window, d.size), mode="nearest")
    mid = 0.5 * (t[1:] + t[:-1])
    keep = np.ones(d.size, bool)
    for stop in stops:
        keep &= np.abs(mid - stop) > JUMP_STOP_MARGIN_S
    if keep.sum() < 20:     # (the test needs 20 values; a short segment is judged whole)
        keep[:] = True
    return float(stats.kurtosistest(d[keep], alternative="greater").pvalue)


def _stated(shot, c: str) -> float:
    """The median 1-sigma the instrument states for coordinate ``c``'s rows of ``shot``,
    where it says its errors persist (0 otherwise): a tracker's includes the slow parts
    of its errors, which the rows' scatter does not show (measured on 67 clips through
    real cameras: 0.5-4x the white part, median 1.4x)."""
    v = stated_sigma_rows(shot, c)
    if v is None:
        return 0.0
    v = v[np.isfinite(v) & (v > 0)]
    return float(np.median(v)) if v.size else 0.0


def smooth_misfit(model, fit) -> list[dict]:
    """The (shot, coordinate) segments whose baseline misfit is the model's, not noise.

    Persisting residuals are either an instrument's errors (step-like fixes that jump
    and hold: the noise treatment scales every threshold up by them) or a model that
    does not describe the shot.  Told apart by how they change: an instrument's steps
    jump between rows, so the residuals' first differences are heavy-tailed, while a
    misfit of the rock's motion is smooth, and its first differences are the rows'
    Gaussian noise.  A segment is listed when its residual RMS exceeds
    :data:`SMOOTH_MISFIT_RATIO` times its rows' scatter (their median sigma, or the
    residuals' first differences' standard deviation over sqrt 2, or - an instrument
    whose errors persist - the sigma it states for its rows, whichever is most)
    and its increments, their slow changes taken off, are not told from Gaussian
    (:func:`jump_p_value` above :data:`JUMP_LEVEL`, the rows about the stops left out)
    - nor are those of half or more of the analysis's segments (one instrument).  (An
    independently written simulator - a friction law that is not a power law, a curl
    that grows as the rock slows - left x residuals 3.7-7.3 times the 2 mm noise on 6
    of 6 draws, read as an instrument's persisting errors: verdict ``none``.)

    Parameters
    ----------
    model : JointModel
    fit : FitOut
        The baseline's fit.

    Returns
    -------
    list of dict
        ``shot``, ``coord``, ``rms`` and ``sigma`` (m or rad), ``ratio``, ``p_jumps``
        (the kurtosis test's p-value).
    """
    out, p_all = [], []
    for j, c, sl in model.segments:
        s = model.shots[j]
        r = np.asarray(fit.r_raw[sl], dtype=float)
        if r.size < 21:
            continue
        stops = [v for v in (s.t_stop_translation, s.t_stop_rotation) if v is not None]
        p = jump_p_value(r, s.t[s.use[c]], stops)
        p_all.append(p)
        # the rows' scatter: their sigma, or what their residuals' steps show where that
        # is more (values rounded to a centimetre scatter 2.9 mm about the path where
        # the noise estimate, from rows that repeat a value, said 0.5 mm)
        sig = max(float(np.median(s.sigma[c][s.use[c]])),
                  float(np.std(np.diff(r))) / np.sqrt(2.0), _stated(s, c))
        if not sig > 0:
            continue
        rms = float(np.sqrt(np.mean(r * r)))
        if rms > SMOOTH_MISFIT_RATIO * sig and p > JUMP_LEVEL:
            out.append({"shot": int(j), "coord": c, "rms": rms, "sigma": sig,
                        "ratio": rms / sig, "p_jumps": p})
    # the shots of one analysis come from one instrument: where half or more of its
    # segments jump, its errors are jumps, and a segment whose few jumps the test did
    # not see is the instrument's too (clean step-noise sessions: one segment in ~50 read
    # p 0.001-0.34 beside five at 1e-9 to 1e-40, and was listed as a misfit)
    if out and np.mean(np.asarray(p_all) <= JUMP_LEVEL) >= 0.5:
        return []
    return out
