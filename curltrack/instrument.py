"""How an instrument samples a shot and how it errs: noise classes, sampling, sessions.

Kept beside the simulator (:mod:`curltrack.simulate`) so that tests and ``curltrack
simulate`` can make series that look like what other instruments record, not only like
our tracker's output.  Every generator takes a numpy ``Generator`` (seeded by the caller).

Noise classes (:data:`NOISE_CLASSES`), each with a 1-sigma scale ``sigma`` (m or rad):

``white``
    Independent Gaussian errors, sigma each.
``ar1``
    Tracker-like correlated errors: a stationary Ornstein-Uhlenbeck process (exact on
    irregular times) of standard deviation sigma and correlation time ``corr_time_s``
    (default 0.05 s: lag-1 correlation 0.51 at 30 Hz, like tracked video, 0.14 at 10 Hz).
``steps``
    Step-like instrument errors (LiDAR/radar fixes that jump and then hold): the error
    holds a level for 0.5-3 s (uniform), then jumps to a new level; levels are
    +-U(0.5, 1.5) sigma, so jumps are 0-3 sigma (3-15 cm for sigma = 5 cm); with white
    jitter of sigma/5 on top the lag-1 correlation at 10 Hz is ~0.91 (0.94 without it).
``heavy``
    Heavy-tailed errors: Student t with 3 degrees of freedom scaled to a standard
    deviation of sigma, and 1 % outliers at 10 sigma (2 cm for sigma = 2 mm) of random sign.

More (:data:`OTHER_NOISE_CLASSES`): errors of video trackers, and errors that swing
faster than any motion of the rock, for testing that discovery does not take them for
physics:

``tracked``
    A video tracker's errors as measured against the truth of 67 clips rendered through
    real cameras' artefacts (session 39): white noise plus a slowly varying part (an
    Ornstein-Uhlenbeck process) whose standard deviation is ``r`` times the white part's,
    ``r`` log-uniform in :data:`TRACKED_RATIO` (measured: 0.55-4 from the 10th to the 90th
    percentile, median 1.4), holding for a correlation time log-uniform in
    :data:`TRACKED_TAU_S` (measured: 0.05-0.07 s to tens of seconds - a drift over the
    clip -, median 0.25-0.35 s); sigma in all.  Each coordinate draws its own.  A series
    of this class says so (``noise_persists``), as the tracker's do.

``vibration``
    A camera on a pole or boom that vibrates: a sinusoid of 1.5-6 Hz (uniform, random
    phase) of standard deviation 0.9 sigma, plus white noise (0.44 sigma): sigma in all.
``quantised``
    A file that rounds its values (a track written in centimetres): white noise of
    sigma / 2, then rounding to a quantum of sigma sqrt(12) (1 cm for sigma = 2.9 mm):
    1.1 sigma in all (the rounding's sigma and the noise's sigma / 2).  The error then
    depends on the value: it holds while the rock moves by less than a quantum, and
    sweeps a sawtooth while it moves on.

Sampling (:class:`Sampling`): any rate, Gaussian timestamp jitter, gaps (stretches with
no rows, up to ``max_gap_s``), and a first row after release (``start_s``).  The
``frame`` column counts nominal sample slots, so a gap shows as a jump in ``frame``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import ParameterError

NOISE_CLASSES = ("white", "ar1", "steps", "heavy")
OTHER_NOISE_CLASSES = ("tracked", "vibration", "quantised")
#: noise classes whose errors persist over many rows, as their instruments say in the
#: series' sidecar (``noise_persists``)
PERSISTING_NOISE_CLASSES = ("tracked",)
ALL_NOISE_CLASSES = NOISE_CLASSES + OTHER_NOISE_CLASSES
#: typical scales (position m, angle rad) of each class: a tracked video's 2 mm / 0.3
#: degrees; a position instrument's steps of 3-15 cm (an angle instrument's ~3 degrees);
#: values written to the centimetre (and to the degree)
TYPICAL_SCALE = {"white": (0.002, 0.005), "ar1": (0.002, 0.005), "steps": (0.05, 0.05),
                 "heavy": (0.002, 0.005), "tracked": (0.002, 0.005),
                 "vibration": (0.002, 0.005),
                 "quantised": (0.01 / math.sqrt(12.0), math.radians(1.0) / math.sqrt(12.0))}
#: steps: how long an error level holds (s) and its size range in units of sigma
STEP_HOLD_S = (0.5, 3.0)
STEP_LEVEL = (0.5, 1.5)
#: heavy: Student-t degrees of freedom, outlier fraction and size (in sigma)
HEAVY_DOF = 3.0
OUTLIER_FRACTION = 0.01
OUTLIER_SIGMA = 10.0
#: tracked: the slow part's standard deviation over the white part's, and its
#: correlation time (s): ranges of log-uniform draws
TRACKED_RATIO = (0.5, 4.0)
TRACKED_TAU_S = (0.05, 5.0)
#: vibration: frequency range (Hz) and the sinusoid's share of the variance
VIBRATION_HZ = (1.5, 6.0)
VIBRATION_SHARE = 0.81


def _check_class(kind: str) -> str:
    if kind not in ALL_NOISE_CLASSES:
        raise ParameterError(f"unknown noise class {kind!r}; expected one of "
                             f"{', '.join(ALL_NOISE_CLASSES)}", where="noise_class")
    return kind


def draw_noise(kind: str, t, sigma: float, rng: np.random.Generator,
               corr_time_s: float = 0.05, values=None) -> np.ndarray:
    """Measurement errors of one coordinate at times ``t`` (s).

    Parameters
    ----------
    kind : {"white", "ar1", "steps", "heavy", "tracked", "vibration", "quantised"}
        The noise class (see the module docstring).
    t : array of float
        Increasing sample times (s); irregular spacing is honoured.
    sigma : float
        Scale (1 sigma, same unit as the coordinate).
    rng : numpy Generator
    corr_time_s : float
        ``ar1`` only: correlation time (s).
    values : array of float, optional
        ``quantised`` only (required): the true values the errors are added to.

    Returns
    -------
    ndarray
        One error per sample.
    """
    _check_class(kind)
    t = np.asarray(t, dtype=float)
    n = t.size
    if sigma <= 0 or n == 0:
        return np.zeros(n)
    if kind == "white":
        return rng.normal(0.0, sigma, n)
    if kind == "ar1":
        return _ornstein_uhlenbeck(t, sigma, corr_time_s, rng)
    if kind == "tracked":
        r = math.exp(rng.uniform(*np.log(TRACKED_RATIO)))
        tau = math.exp(rng.uniform(*np.log(TRACKED_TAU_S)))
        white = sigma / math.sqrt(1.0 + r * r)
        return rng.normal(0.0, white, n) + _ornstein_uhlenbeck(t, r * white, tau, rng)
    if kind == "steps":
        span = float(t[-1] - t[0]) + STEP_HOLD_S[1]
        holds = rng.uniform(*STEP_HOLD_S, int(span / STEP_HOLD_S[0]) + 2)
        edges = t[0] - rng.uniform(0.0, holds[0]) + np.concatenate([[0.0], np.cumsum(holds)])
        levels = rng.choice([-1.0, 1.0], holds.size) * rng.uniform(*STEP_LEVEL, holds.size)
        idx = np.clip(np.searchsorted(edges, t, side="right") - 1, 0, holds.size - 1)
        return sigma * levels[idx] + rng.normal(0.0, sigma / 5.0, n)
    if kind == "vibration":
        f = rng.uniform(*VIBRATION_HZ)
        phase = rng.uniform(0, 2 * np.pi)
        wave = math.sqrt(2.0 * VIBRATION_SHARE) * np.sin(2 * np.pi * f * t + phase)
        return sigma * (wave + rng.normal(0.0, math.sqrt(1.0 - VIBRATION_SHARE), n))
    if kind == "quantised":
        if values is None or np.shape(values) != t.shape:
            raise ParameterError("the quantised class needs the true values, one per time",
                                 where="values")
        q = sigma * math.sqrt(12.0)
        v = np.asarray(values, dtype=float)
        return np.round((v + rng.normal(0.0, sigma / 2.0, n)) / q) * q - v
    # heavy: t with 3 dof has variance 3; rescale to sigma
    out = rng.standard_t(HEAVY_DOF, n) * sigma / math.sqrt(HEAVY_DOF / (HEAVY_DOF - 2.0))
    bad = rng.random(n) < OUTLIER_FRACTION
    out[bad] += rng.choice([-1.0, 1.0], int(bad.sum())) * OUTLIER_SIGMA * sigma
    return out


def _ornstein_uhlenbeck(t, sigma: float, corr_time_s: float, rng) -> np.ndarray:
    """A stationary Ornstein-Uhlenbeck process of standard deviation ``sigma`` and
    correlation time ``corr_time_s`` (s) at times ``t`` (exact on irregular times)."""
    n = t.size
    out = np.empty(n)
    out[0] = rng.normal(0.0, sigma)
    rho = np.exp(-np.diff(t) / corr_time_s)
    e = rng.normal(0.0, 1.0, n - 1) * sigma * np.sqrt(1.0 - rho * rho)
    for i in range(1, n):  # a recursion: no closed vector form on irregular times
        out[i] = rho[i - 1] * out[i - 1] + e[i - 1]
    return out


@dataclass(frozen=True)
class Sampling:
    """When an instrument records the rock.

    Attributes
    ----------
    rate_hz : float
        Nominal sample rate (samples/s).
    jitter_s : float
        1-sigma Gaussian timestamp jitter (s), kept below a third of the sample period so
        that times stay increasing.
    start_s : float
        Time of the first row after release (s); the series' t is still time since
        release (the paper's forms hold from any start).
    n_gaps : int
        Number of gaps (stretches with no rows).
    max_gap_s : float
        Longest gap (s); each gap's length is uniform in [2 periods, max_gap_s].
    """

    rate_hz: float = 30.0
    jitter_s: float = 0.0
    start_s: float = 0.0
    n_gaps: int = 0
    max_gap_s: float = 2.0

    def __post_init__(self):
        for name in ("rate_hz", "jitter_s", "start_s", "max_gap_s"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise ParameterError(f"must be a finite number >= 0, got {v!r}", where=name)
        if self.rate_hz <= 0:
            raise ParameterError(f"must be > 0, got {self.rate_hz!r}", where="rate_hz")
        if int(self.n_gaps) != self.n_gaps or self.n_gaps < 0:
            raise ParameterError(f"must be an integer >= 0, got {self.n_gaps!r}",
                                 where="n_gaps")

    @property
    def regular(self) -> bool:
        return self.jitter_s == 0 and self.start_s == 0 and self.n_gaps == 0

    def times(self, end_s: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """Sample slots ``frame`` (int) and times ``t`` (s) from ``start_s`` to ``end_s``.

        Gaps never touch the first or last second, so a series keeps its start and stop.
        """
        dt = 1.0 / self.rate_hz
        n = int(math.floor((end_s - self.start_s) * self.rate_hz + 1e-9)) + 1
        frame = np.arange(max(n, 0))
        t = self.start_s + frame * dt
        if self.jitter_s > 0:
            t = t + np.clip(rng.normal(0.0, self.jitter_s, t.size), -dt / 3, dt / 3)
            t[0] = max(t[0], self.start_s)
        keep = np.ones(t.size, bool)
        lo, hi = t[0] + 1.0, t[-1] - 1.0 if t.size else 0.0
        placed: list[tuple[float, float]] = []
        for _ in range(int(self.n_gaps)):
            if hi - lo <= self.max_gap_s:
                break
            length = rng.uniform(min(2 * dt, self.max_gap_s), self.max_gap_s)
            for _try in range(50):  # gaps apart by >= 2 periods: two never merge into one
                a = rng.uniform(lo, hi - length)
                if all(a + length + 2 * dt < a0 or a > b0 + 2 * dt for a0, b0 in placed):
                    break
            else:
                continue
            placed.append((a, a + length))
            keep &= ~((t > a) & (t < a + length))
        return frame[keep], t[keep]


#: relative 1-sigma spread of alpha between shots of one session (log-normal).  The
#: paper's pure rotations on one sheet span lambda_theta 1.55-1.66; alpha sets the
#: stopping time at a given speed, and 5 % is the spread of t_F between throws of
#: one speed that draws show on one sheet (the weight a skip calls, "2 s of hog-to-hog").
SESSION_ALPHA_SPREAD = 0.05


def session_models(base_model, n_shots: int, rng: np.random.Generator,
                   alpha_spread: float = SESSION_ALPHA_SPREAD, v0_range=(1.2, 2.2),
                   omega0_range=(0.8, 3.0), both_spins: bool = True) -> list:
    """Shots of one session: shared ice (phi, a_T, R, r), per-shot alpha, speed and spin.

    Parameters
    ----------
    base_model : ShotModel
        The session's ice; its v0/omega0 are replaced per shot.
    n_shots : int
    rng : numpy Generator
    alpha_spread : float
        Relative 1-sigma spread of alpha_y and alpha_theta per shot (one log-normal factor
        for both: the same ice under the same rock).
    v0_range, omega0_range : (float, float)
        Uniform ranges of the initial speed (m/s) and spin size (rad/s).
    both_spins : bool
        Alternate in-turns and out-turns (random order); else all counter-clockwise.

    Returns
    -------
    list of ShotModel
    """
    from dataclasses import replace

    out = []
    signs = rng.permutation([1.0 if i % 2 == 0 else -1.0 for i in range(n_shots)]) \
        if both_spins else np.ones(n_shots)
    for i in range(n_shots):
        f = float(np.exp(rng.normal(0.0, alpha_spread))) if alpha_spread > 0 else 1.0
        kw = dict(v0=float(rng.uniform(*v0_range)),
                  omega0=float(signs[i] * rng.uniform(*omega0_range)),
                  alpha_y=base_model.alpha_y * f)
        # a tied alpha_theta stays tied: each draw's rotation stops with its translation,
        # as the paper observed on pebbled ice, so alpha_theta differs from shot to shot
        # (with v0 and omega0) -- a session's baseline must allow that
        if base_model.alpha_theta is not None:
            kw["alpha_theta"] = base_model.alpha_theta * f
        out.append(replace(base_model, **kw))
    return out
