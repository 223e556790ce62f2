"""Measurement noise of a series, estimated from the data itself: the one estimator.

:func:`estimate_noise` (an AR(1) model per coordinate) is what ``fit`` and ``discover``
both weight a shot by; :func:`white_sigma` (lag-1 second differences only) is the quick
scale the stop detector and the shot segmentation compare motion against;
:func:`robust_sigma` is the robust spread (1.4826 x MAD) they are built on.

The rock's motion is smooth on the scale of a frame (accelerations of ~0.1 m/s^2 move the
second difference of x or y by ~0.1 mm at 30 fps), so the second differences of a
coordinate are, to a very good approximation, second differences of its measurement
noise.  We model that noise as stationary AR(1) (1-sigma ``sigma``, lag-1 correlation
``rho``; tracking errors that drift with the camera are positively correlated) and read
both numbers off the variogram of second differences at lags k = 1..6 frames, whose
variance is sigma^2 (6 - 8 rho^k + 2 rho^2k).  Robust scales (median absolute deviation)
keep a pick's velocity jump or the kink at the stop from inflating the estimate.  A
``rho`` below 0.1 is not distinguishable from white noise with a few hundred frames
(its scatter is ~0.05) and is set to 0.  Rows after the stop (where the rock is at
rest) give an independent cross-check, reported but not used.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._stats import MAD_TO_SIGMA, robust_sigma  # noqa: F401  (re-exported)
from ..errors import SeriesError

_RHO_GRID = np.linspace(0.0, 0.95, 96)
#: the largest lag-1 correlation the AR(1) model takes; an estimate there is at its
#: bound: the noise persists longer than the model can say, and whitening with it
#: does not whiten (:func:`at_rho_bound`)
RHO_MAX = float(_RHO_GRID[-1])
_LAGS = (1, 2, 3, 4, 6)
_MIN_DIFFS = 20


def _second_differences(frame, q, k, t=None):
    """Lag-k second differences q[i+k] - 2 q[i] + q[i-k] over gap-free stretches, with
    the smooth signal's own part (a (k dt)^2) removed by a running mean (whose noise part
    telescopes to ~0).

    With the rows' times ``t`` the outer two are weighted by where row i lies between
    them (2 (1 - a) q[i-k] + 2 a q[i+k] - 2 q[i], a = (t[i] - t[i-k]) / (t[i+k] -
    t[i-k]); a = 1/2 on a regular clock): a steady motion cancels whatever the spacing.
    Unweighted, an instrument's timestamp jitter reads as noise of the speed times the
    jitter - 2 m/s x 10 ms, centimetres along the sheet at 10 Hz, where its errors
    were 2 mm: the fit then weighed y twenty times too little and bent it to x.
    """
    if q.size < 2 * k + 1:
        return np.empty(0)
    ok = (frame[2 * k:] - frame[k:-k] == k) & (frame[k:-k] - frame[:-2 * k] == k)
    if t is None:
        a = 0.5
    else:
        t = np.asarray(t, dtype=float)
        span = t[2 * k:] - t[:-2 * k]
        a = np.where(span > 0, (t[k:-k] - t[:-2 * k]) / np.where(span > 0, span, 1.0), 0.5)
    d2 = (2.0 * a * q[2 * k:] - 2.0 * q[k:-k] + 2.0 * (1.0 - a) * q[:-2 * k])[ok]
    if d2.size == 0:
        return d2
    # window >> the 4k-sample reach of the lag-k noise correlation, so that the noise
    # part of the running mean cancels (a shorter window biases rho upwards)
    win = min(10 * k + 1, d2.size)
    kern = np.ones(win) / win
    trend = np.convolve(np.pad(d2, (win // 2, win - 1 - win // 2), mode="edge"), kern, "valid")
    return d2 - trend


@dataclass(frozen=True)
class Noise:
    """Noise model of one coordinate of one shot.

    Attributes
    ----------
    sigma : float
        1-sigma measurement noise (m for x, y; rad for theta).
    rho : float
        Lag-1 correlation of the noise between consecutive frames (AR(1)), in [0, 0.95].
        Where it is high (an AR(1) draw at 60 Hz: 0.72) the second differences pin
        ``sigma_innovation`` far better than ``sigma`` and ``rho`` apart (600 rows: the
        innovation within 0.91-1.17 of the truth in 99 % of draws, ``sigma`` 0.80-2.6).
    n : int
        Number of second differences used.
    sigma_rest : float or None
        Standard deviation of the rows after the stop (cross-check), if there are >= 10.
    """

    sigma: float
    rho: float
    n: int
    sigma_rest: float | None = None
    #: set from the baseline's residuals (:func:`residual_structure`): the variance of
    #: the whitened residuals at long scales (1 when the AR(1) model is the whole story)
    inflation: float = 1.0
    #: correlation time (samples) of the whitened residuals at scales below
    #: ``HIGHPASS_S`` (1 when the AR(1) model whitens them)
    tau: float = 1.0

    @property
    def sigma_innovation(self) -> float:
        """sigma sqrt(1 - rho^2): the part of each row's noise that is new, what the
        AR(1) whitening divides by (= ``sigma`` for white noise)."""
        return self.sigma * float(np.sqrt(1.0 - self.rho ** 2))

    def as_dict(self) -> dict:
        return {"sigma": self.sigma, "rho": self.rho, "sigma_innovation": self.sigma_innovation,
                "n": self.n, "sigma_rest": self.sigma_rest, "inflation": self.inflation,
                "tau": self.tau}


# robust_sigma (1.4826 x MAD, a spread that a few outliers - a pick, a stop - do not
# move) is curltrack._stats's, the one definition (the tracker uses it too).


def white_sigma(q, ok=None, min_diffs: int = 1) -> float:
    """1-sigma white measurement noise of a smooth signal from its lag-1 second differences.

    For white noise of sigma s the second difference has sigma s sqrt(6); the smooth
    motion itself contributes a dt^2, negligible at video rates (~0.1 mm at 30 fps).

    Parameters
    ----------
    q : (N,) array
        Samples at consecutive frames.
    ok : (N,) bool array, optional
        Valid samples; only second differences of three valid samples are used.
    min_diffs : int
        Fewer usable second differences than this give 0.

    Returns
    -------
    float
        Same units as ``q``; 0 when too few samples.
    """
    q = np.asarray(q, dtype=float)
    if q.size < 3:
        return 0.0
    d2 = q[2:] - 2.0 * q[1:-1] + q[:-2]
    if ok is not None:
        ok = np.asarray(ok, bool)
        d2 = d2[ok[2:] & ok[1:-1] & ok[:-2]]
    if d2.size < max(min_diffs, 1):
        return 0.0
    return robust_sigma(d2) / np.sqrt(6.0)


#: share of rows that repeat the previous row's value exactly above which a
#: coordinate is taken to be written in steps (:func:`resolution`)
REPEAT_SHARE = 0.05


def resolution(q) -> float:
    """The step a coordinate's values are written in (m or rad), or 0.

    Measured values repeat exactly only when they are rounded (to a centimetre, to a
    degree, to the digits a file keeps): where more than :data:`REPEAT_SHARE` of the
    rows repeat the previous row's value, the step is the largest of which every change
    between rows is a whole multiple (0 when there is none: repeats, but not rounding).
    Rounding to it is an error of at least step / sqrt(12) per row, which second
    differences of rows that repeat a value do not show (a clean shot rounded to a
    centimetre: x's noise estimated at 1e-5 m, y's at 7 mm, and the baseline fitted x
    alone, y 36 mm off).
    """
    q = np.asarray(q, dtype=float)
    q = q[np.isfinite(q)]
    d = np.abs(np.diff(q))
    if d.size < 10:
        return 0.0
    same = d <= 1e-12 * max(float(np.max(np.abs(q))), 1e-300)
    if same.mean() <= REPEAT_SHARE or same.all():
        return 0.0
    # every change is a whole number of steps; the smallest change seen may be several
    # (a rock at rest whose rounded value never flickered: 9 mm for a 1 mm step)
    d = d[~same]
    for k in range(1, 101):
        step = float(np.min(d)) / k
        if np.all(np.abs(d / step - np.round(d / step)) < 1e-3):
            return step
    return 0.0


def estimate_noise(frame, q, *, t=None, t_stop=None, name="<series>", field="x",
                   floor=0.0, rho_max: float = RHO_MAX) -> Noise:
    """Estimate the AR(1) measurement noise of one coordinate from its second differences.

    Parameters
    ----------
    frame : array of int
        Frame indices of the measured rows (ok = 1), increasing.
    q : array of float
        The coordinate at those rows (m or rad).
    t, t_stop : array, float, optional
        Times (s) and the stop time; rows after ``t_stop`` give ``sigma_rest``.
    name, field : str
        File and column, for the error message.
    floor : float
        Lower bound for ``sigma`` (a perfectly noiseless series would otherwise give
        zero and make every residual infinitely significant); values written in steps
        (:func:`resolution`) have at least step / sqrt(12).
    rho_max : float
        Largest ``rho`` fitted (default :data:`RHO_MAX`).

    Returns
    -------
    Noise

    Raises
    ------
    SeriesError
        Fewer than 20 runs of three consecutive measured frames.
    """
    frame = np.asarray(frame)
    q = np.asarray(q, dtype=float)
    floor = max(float(floor), resolution(q) / np.sqrt(12.0))
    logv = []
    n_used = 0
    for k in _LAGS:
        d2 = _second_differences(frame, q, k, t)
        if d2.size < _MIN_DIFFS:
            if k == 1:
                raise SeriesError(f"too few consecutive measured frames to estimate the "
                                  f"noise of '{field}' ({d2.size} second differences, need "
                                  f"{_MIN_DIFFS})", path=name, where=field)
            break
        n_used = max(n_used, d2.size)
        logv.append(2.0 * np.log(max(robust_sigma(d2), 1e-300)))
    logv = np.array(logv)
    if not np.isfinite(logv).all() or logv[0] < -600:
        return Noise(float(floor), 0.0, n_used, None)
    # variogram of lag-k second differences: s^2 (6 - 8 rho^k + 2 rho^2k); least squares
    # in log over the rho grid, s^2 solved in closed form for each rho.
    k = np.arange(1, len(logv) + 1)[:, None]
    grid = _RHO_GRID[_RHO_GRID <= rho_max + 1e-12]
    logm = np.log(6.0 - 8.0 * grid[None, :] ** k + 2.0 * grid[None, :] ** (2 * k))
    logs2 = (logv[:, None] - logm).mean(axis=0)
    cost = ((logv[:, None] - logm - logs2) ** 2).sum(axis=0)
    best = int(np.argmin(cost)) if len(logv) > 1 else 0
    rho = float(grid[best])
    if rho < 0.1:
        rho = 0.0
        sigma2 = np.exp(logv - np.log(6.0)).mean()
        logs2[best] = np.log(sigma2)
    sigma = max(float(np.exp(0.5 * logs2[best])), floor)
    rest = None
    if t is not None and t_stop is not None:
        after = np.asarray(t) > t_stop + 0.2
        if after.sum() >= 10:
            rest = float(np.std(q[after], ddof=1))
    return Noise(float(sigma), rho, int(n_used), rest)


def at_rho_bound(noise: "Noise") -> bool:
    """Whether the AR(1) model's ``rho`` is at its bound :data:`RHO_MAX`: the variogram
    of second differences kept rising over the lags, as an instrument's errors that
    hold for seconds make it (step-like noise at 10 Hz: x or y of 46 % of 400 pure-noise
    shots; white, AR(1) and heavy-tailed noise at 10 and 30 Hz: none)."""
    return noise.rho >= RHO_MAX - 1e-12


def whiten(v, rho, steps=None):
    """Apply the AR(1) whitening transform along axis 0 of ``v`` (1-D or 2-D).

    ``w_0 = v_0``, ``w_i = (v_i - r_i v_{i-1}) / sqrt(1 - r_i^2)`` with ``r_i = rho^g_i``,
    ``g_i`` the frames from row i-1 to row i (``steps``; 1 without): unit-variance
    AR(1) noise in, unit-variance white noise out, across gaps too.  Taking a gap for
    one frame (``r = rho``) reads two rows whose errors are nearly independent as
    nearly equal: the row after a 2 s gap at 10 Hz under step-like noise (rho at its
    bound, 0.95) carried ~20x the variance the fit gave it.

    Parameters
    ----------
    v : (n,) or (n, k) array
        Values in units of the noise (divided by each row's sigma).
    rho : float
        Lag-one (one frame) correlation of the noise.
    steps : (n-1,) array of int, optional
        Frames between consecutive rows (>= 1).
    """
    v = np.asarray(v, dtype=float)
    if rho == 0.0:
        return v
    out = np.empty_like(v)
    out[0] = v[0]
    r = rho if steps is None else rho ** np.maximum(np.asarray(steps, dtype=float), 1.0)
    if np.ndim(r) and v.ndim == 2:
        r = r[:, None]
    out[1:] = (v[1:] - r * v[:-1]) / np.sqrt(1.0 - r * r)
    return out


def row_sigma(frame, q, *, t=None, t_stop=None, weights=None, name="<series>", field="x",
              floor=0.0) -> tuple[Noise, np.ndarray]:
    """The 1-sigma noise of every row of one coordinate: how ``fit`` and ``discover``
    weight a shot.

    The level is the data's own (:func:`estimate_noise`); a tracker's per-frame estimate
    (``weights``, e.g. the ``sigma_xy`` column) only modulates it from row to row,
    relative to its median (within 0.5-10x), when more than half its rows are usable.

    Parameters
    ----------
    frame, q, t, t_stop, name, field, floor
        As for :func:`estimate_noise`.
    weights : array, optional
        Per-row 1-sigma estimates (same units as ``q``); NaN or <= 0 where unknown.

    Returns
    -------
    (Noise, ndarray)
        The noise model and the per-row sigma (units of ``q``).

    Raises
    ------
    SeriesError
        Too few consecutive measured frames to estimate the noise.
    """
    noise = estimate_noise(frame, q, t=t, t_stop=t_stop, name=name, field=field, floor=floor)
    s = np.full(np.asarray(q).size, noise.sigma)
    if weights is not None:
        w = np.asarray(weights, dtype=float)
        good = np.isfinite(w) & (w > 0)
        if good.sum() > 0.5 * w.size:
            med = float(np.median(w[good]))
            s = noise.sigma * np.where(good, np.clip(w / med, 0.5, 10.0), 1.0)
    return noise, s


#: whitened residuals are high-passed at this scale (s) before their noise is measured:
#: a misfit of the model is mostly smooth over longer stretches
HIGHPASS_S = 6.0
#: windows (s) over which the residuals' sums measure the noise's long-scale variance:
#: they span an instrument's errors that persist for up to ~3 s (LiDAR/radar fixes)
WINDOW_S = 3.0
#: correlation times (samples) above this mean the AR(1) model did not whiten the noise
CORRELATED_TAU = 1.5
_MEDIAN_CHI2_1 = 0.454936423119572


def residual_structure(w, t) -> tuple[float, float]:
    """The noise that the AR(1) model left in whitened residuals: (inflation, tau).

    Real instruments err in ways the AR(1) model of second differences does not see:
    step-like errors that hold for seconds, heavy tails and outliers (a robust scale
    ignores them).  Their trace is in the baseline's whitened residuals ``w``: with ``w``
    high-passed (running mean over ``HIGHPASS_S`` removed, so that a smooth misfit is
    not taken for noise), ``inflation`` is the variance of its sums over ``WINDOW_S``
    windows per sample -- the spectral density at low frequency that a smooth effect's
    chi-square gain is measured against -- taken as the *median* over overlapping
    windows, so that a localized misfit (a pick's kink, a patch) is not taken for noise
    either, since noise is everywhere.  ``tau`` = inflation / variance is the correlation
    time in samples.  For white or AR(1) noise both are ~1.

    Parameters
    ----------
    w : array
        Whitened residuals of one (shot, coordinate), in time order.
    t : array
        Their times (s).

    Returns
    -------
    (float, float)
        ``inflation`` (>= 1) and ``tau`` (samples, >= 1).
    """
    w = np.asarray(w, dtype=float)
    t = np.asarray(t, dtype=float)
    if w.size < 40:
        return 1.0, 1.0
    dt = float(np.median(np.diff(t)))
    win = int(np.clip(round(HIGHPASS_S / max(dt, 1e-6)), 10, w.size))
    trend = np.convolve(np.pad(w, (win // 2, win - 1 - win // 2), mode="reflect"),
                        np.ones(win) / win, "valid")
    hp = w - trend
    L = int(np.clip(round(WINDOW_S / max(dt, 1e-6)), 3, win // 2))
    c = np.concatenate([[0.0], np.cumsum(hp)])
    sums = (c[L:] - c[:-L])[:: max(1, L // 3)]
    if sums.size < 3:
        return 1.0, 1.0
    # the running mean took (L / win) of a window sum's variance with it (white noise)
    infl = float(np.median(sums ** 2)) / L / _MEDIAN_CHI2_1 / (1.0 - L / win)
    var = float(np.mean(hp * hp)) / (1.0 - 1.0 / win)
    tau = infl / var if var > 0 else 1.0
    return float(max(1.0, infl)), float(np.clip(tau, 1.0, L))


#: a row whose residual stands this many robust sigma off the running median of its
#: neighbours is an isolated outlier (a Gaussian error does that once in ~5e8 rows; an
#: instrument's glitch or a mistracked frame far more often)
OUTLIER_K = 6.0
#: rows each side of the running median: misfits and step-like errors that hold for
#: 3 or more rows move the median with them and are never taken for outliers
OUTLIER_HALF_WINDOW = 2
#: robust sigma of (white Gaussian noise - its running median of 5) over the noise's
#: sigma (1e6 rows): the median shares each row's own value, which narrows the core of
#: the differences but not their tails, so their robust sigma is divided by this
_MEDIAN5_SPREAD = 0.728


def isolated_outliers(r, k: float = OUTLIER_K) -> np.ndarray:
    """Rows of ``r`` that are isolated outliers: far from their neighbours, alone.

    Heavy-tailed errors (rare glitches of 10 sigma and more) weigh on every chi-square
    and on the window sums :func:`residual_structure` measures the noise with; a smooth
    misfit (any effect of the physics) or an instrument's step that holds for a few
    samples does not look like them.  A row is an outlier when its residual differs from
    the running median of the ``2 OUTLIER_HALF_WINDOW + 1`` rows around it, and from the
    mean of the two rows on either side, by more than ``k`` sigma of the noise: the
    rows' own (the residuals are in units of the noise :func:`estimate_noise`
    measured), or more if the differences' robust spread says so - not less, since on
    a steep trend the running median is the row itself and the differences vanish.
    Correlated noise is followed by the median, which makes the test only more
    conservative.

    Parameters
    ----------
    r : array
        Residuals (data - model) of one coordinate in units of the rows' noise sigma,
        in time order.
    k : float
        Threshold in sigma of the noise.

    Returns
    -------
    ndarray of bool
        True at the outlier rows.
    """
    from scipy.ndimage import median_filter

    r = np.asarray(r, dtype=float)
    if r.size < 4 * OUTLIER_HALF_WINDOW + 1:
        return np.zeros(r.size, bool)
    d = r - median_filter(r, size=2 * OUTLIER_HALF_WINDOW + 1, mode="mirror")
    scale = max(robust_sigma(d) / _MEDIAN5_SPREAD, 1.0)
    # alone: also as far from the mean of the (up to) two rows on each side.  Next to an
    # instrument's step the running median takes the step's level, and a 3.4-sigma row
    # there stood 6.4 sigma off it; a glitch stands off both sides
    n = r.size
    left, right = d.copy(), d.copy()      # (the ends: one side only)
    left[2:] = r[2:] - 0.5 * (r[:-2] + r[1:-1])
    left[1] = r[1] - r[0]
    right[:-2] = r[:-2] - 0.5 * (r[1:-1] + r[2:])
    right[n - 2] = r[n - 2] - r[n - 1]
    lim = k * scale
    return (np.abs(d) > lim) & (left * d > 0) & (right * d > 0) & \
        (np.abs(left) > lim) & (np.abs(right) > lim)


#: at most this many jumps in one coordinate of a shot for them to be taken as isolated
#: glitches (an instrument whose every fix sits on a step - the ``steps`` class - jumps
#: every 0.5-3 s: a dozen in a shot, left to the noise model)
MAX_GLITCH_STEPS = 4
#: a box's two jumps cancel to within this share of the larger
STEP_RETURN = 0.3


#: a glitch holds at most this long (s): a fix lost for 0.5-3 s; a "box" over most of a
#: shot is the instrument's level, not a glitch (a clean step-noise shot had 172 of its
#: 193 rows, 17 s, left out as one)
MAX_GLITCH_HOLD_S = 5.0


#: share of a white series' differences that :func:`isolated_outliers` flags at half
#: :data:`OUTLIER_K` (measured over 6000 draws of 100-800 rows: 0.32-0.33 %)
WHITE_HALF_RATE = 0.0035


def white_jumps_bound(n: int, p: float = 1e-4) -> int:
    """Most jumps at half :data:`OUTLIER_K` that ``n`` differences of white noise give,
    but with probability ``p`` (binomial at :data:`WHITE_HALF_RATE`).  (It was two and
    1 % of the rows: 800 rows went over it in 0.15 % of draws, 250 in 0.8 % - CI seed
    876457806, a 6 cm glitch on a clean 30 Hz shot with 10 such chance differences at
    795 rows, "unexplained"; and 1 % is loose on long series: 32 at 3000 rows, now 24.)"""
    from scipy.stats import binom

    return int(binom.isf(p, int(n), WHITE_HALF_RATE))


def isolated_steps(r, k: float = OUTLIER_K, known=(), t=None) -> list[tuple[int, int]]:
    """Stretches ``[i, j)`` of ``r`` that a position fix's glitch lifted and let go: a
    jump of many sigma, held, and a jump back.

    A rock's position cannot jump: a kick changes its velocity, and every effect of the
    physics moves the residuals smoothly, so a jump between two rows (an isolated
    outlier of the first differences, :func:`isolated_outliers`) is the instrument's.
    Where one returns - a jump and one of the other sign cancelling to within
    :data:`STEP_RETURN` - the rows between are a glitch (an instrument that lost its fix
    for 0.5-3 s and read 3-15 cm off: four in seven clean shots with one or two such
    glitches on white noise were ``unexplained``).  Only isolated ones: with more than
    :data:`MAX_GLITCH_STEPS` jumps, more others at half the threshold than white noise
    gives (:func:`white_jumps_bound`), or a jump that does not return, the errors are
    the instrument's way of measuring, not glitches, and nothing is returned.

    Parameters
    ----------
    r : array
        Residuals of one coordinate in units of the rows' noise sigma, in time order.
    k : float
        Threshold of a jump, in sigma of the differences' noise.
    known : iterable of int
        Jumps (index ``i``: between rows ``i`` and ``i + 1``) already explained as a
        glitch of the same fix's other coordinate: not counted here.
    t : array, optional
        The rows' times (s): a glitch holds at most :data:`MAX_GLITCH_HOLD_S`.

    Returns
    -------
    list of (int, int)
        Row ranges, end exclusive.
    """
    r = np.asarray(r, dtype=float)
    if r.size < 8:
        return []
    d = np.diff(r)
    z = d / np.sqrt(2.0)   # (in sigma of a difference of two rows)
    jumps = np.flatnonzero(isolated_outliers(z, k))
    # jumps the same fix's other coordinate explains as a glitch of its own (x and y
    # are one position fix: a glitch's jump split between them can leave this
    # coordinate's share under the threshold on one side - CI seed 1014755135, y 4.5
    # sigma up and 5.6 back - and a lone jump would make every other a "level kept")
    known = np.asarray(list(known), int)
    jumps = np.setdiff1d(jumps, known)
    if not 2 <= jumps.size <= MAX_GLITCH_STEPS:
        return []
    # isolated: the rest of the series does not jump too - at half the threshold no
    # more others than white noise gives but once in 10^4 series (an instrument whose
    # every fix sits on a step jumps every few tenths of a second)
    half = np.setdiff1d(np.flatnonzero(isolated_outliers(z, 0.5 * k)), known)
    if half.size - jumps.size > white_jumps_bound(d.size):
        return []
    out, used = [], set()
    for a, b in zip(jumps[:-1], jumps[1:]):
        if a in used or b in used:
            continue
        h1, h2 = d[a], d[b]
        if t is not None and t[b + 1] - t[a + 1] > MAX_GLITCH_HOLD_S:
            continue
        if h1 * h2 < 0 and abs(h1 + h2) <= STEP_RETURN * max(abs(h1), abs(h2)):
            out.append((int(a) + 1, int(b) + 1))
            used |= {a, b}
    if 2 * len(out) < jumps.size:
        # a jump that does not return is a level the instrument moved to and kept (a
        # clean 10 Hz step-noise shot's theta: two jumps paired by chance around a
        # third, a "glitch" taken out and a patch named): then none is a glitch
        return []
    return out
