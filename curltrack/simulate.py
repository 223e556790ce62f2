"""Simulated shots as contract series (SIM.csv): the forward model sampled at a frame rate.

:func:`simulate_series` runs :func:`curltrack.physics.simulate` (or the segment-level
model) and returns a :class:`curltrack.series.Series` in the SHOT.csv frame (origin at
the start, +y along the initial velocity, theta(0) = 0 counter-clockwise), with the true
stop times in the sidecar and optional Gaussian measurement noise.
"""

from __future__ import annotations

import math
from dataclasses import asdict

import numpy as np
import pandas as pd

from .errors import ParameterError
from .physics.dynamics import MAX_DURATION_S
from .instrument import PERSISTING_NOISE_CLASSES, Sampling, _check_class, draw_noise
from .physics.effects import as_effects
from .series import Series, make_meta


def _positive(value, name, allow_zero=True):
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"expected a number, got {value!r}", where=name) from None
    if not math.isfinite(value) or value < 0 or (value == 0 and not allow_zero):
        raise ParameterError(f"must be a finite number {'>=' if allow_zero else '>'} 0, "
                             f"got {value!r}", where=name)
    return value


def stop_frame(t: np.ndarray, t_stop: float) -> int | None:
    """First frame index with t >= t_stop (None if the series ends before)."""
    if not math.isfinite(t_stop):
        return None
    i = int(np.searchsorted(t, t_stop - 1e-9, side="left"))
    return i if i < len(t) else None


def simulate_series(model, effects=(), fps: float = 30.0, noise_m: float = 0.0,
                    noise_rad: float = 0.0, seed: int | None = None,
                    tail_s: float = 1.0, noise_class: str = "white",
                    sampling: Sampling | None = None,
                    theta_measured: bool = True) -> Series:
    """Simulate a shot and sample it like a tracked video.

    Parameters
    ----------
    model : ShotModel or SegmentModel
        The shot (paper model, or the segment-level model of
        :mod:`curltrack.physics.segment`, which takes no effects).
    effects : sequence of Effect
        Extension terms (paper model only).
    fps : float
        Frame rate (frames/s); rows at t = frame / fps (unless ``sampling`` is given).
    noise_m, noise_rad : float
        1-sigma noise scale of x, y (m) and theta (rad); for white noise the values are
        also written as the ``sigma_xy`` / ``sigma_theta`` columns when non-zero (other
        classes leave the instrument's noise to be estimated from the data).
    seed : int, optional
        Seed of the noise generator (numpy default_rng).
    tail_s : float
        Seconds of rest recorded after both motions have stopped.
    noise_class : {"white", "ar1", "steps", "heavy", "tracked", "vibration", "quantised"}
        How the instrument errs (:mod:`curltrack.instrument`).
    sampling : Sampling, optional
        Irregular sampling (rate, jitter, gaps, first row after release); overrides
        ``fps``.  Default: regular at ``fps`` from t = 0.
    theta_measured : bool
        False: a position-only instrument (theta column empty, ``theta_measured`` false
        in the sidecar).

    Returns
    -------
    Series
        Columns frame, t, x, y, theta, ok (+ sigma columns); sidecar with fps, n_frames,
        the true t_stop_* and stop_frame_*, and the simulation parameters.

    Raises
    ------
    ParameterError
        Invalid parameters, or a rock that does not stop within 600 s.

    Examples
    --------
    >>> from curltrack import Effect, ShotModel, simulate_series
    >>> s = simulate_series(ShotModel(v0=2.0, omega0=1.5),
    ...                     [Effect("pick", {"t_s": 8.0, "dvx_m_per_s": 0.01})], seed=1)
    >>> list(s.data.columns[:6]), round(s.meta["t_stop_translation"], 2)
    (['frame', 't', 'x', 'y', 'theta', 'ok'], 25.71)
    """
    fps = _positive(fps, "fps", allow_zero=False)
    noise_m, noise_rad = _positive(noise_m, "noise_m"), _positive(noise_rad, "noise_rad")
    tail_s = _positive(tail_s, "tail_s")
    _check_class(noise_class)
    effects = as_effects(effects)
    if hasattr(model, "friction_direction"):  # the segment-level model
        from .physics.segment import simulate_segment

        if effects:
            raise ParameterError("effects are available with the paper model only",
                                 where="effects")
        full = simulate_segment(model)  # 30 fps until the stop; re-sampled below
        stops = (full.t_stop_translation, full.t_stop_rotation)
        sample = lambda t: simulate_segment(model, t=t)  # noqa: E731
        kind = "segment"
    else:
        from .physics.dynamics import evaluate, solve

        segments, *stops = solve(model, effects)
        sample = lambda t: evaluate(segments, t)  # noqa: E731
        kind = "paper"
    end = max(stops)
    if not math.isfinite(end) or end > MAX_DURATION_S:
        raise ParameterError(f"the rock does not stop within {MAX_DURATION_S:.0f} s "
                             f"(friction too small, or a slope it cannot hold)",
                             where="model")
    rng = np.random.default_rng(seed)
    if sampling is None or (sampling.regular and sampling.rate_hz == fps):
        n = int(math.floor((end + tail_s) * fps + 1e-9)) + 1
        frame, t = np.arange(n), np.arange(n) / fps
    else:
        fps = sampling.rate_hz
        frame, t = sampling.times(end + tail_s, rng)
        n = t.size
        if n < 2:
            raise ParameterError(f"no rows: the first sample ({sampling.start_s:g} s) is "
                                 f"after the end of the shot", where="start_s")
    traj = sample(t)
    traj = traj if isinstance(traj, dict) else traj.__dict__
    x, y, theta = (np.array(traj[k], dtype=float) for k in ("x", "y", "theta"))
    if noise_class == "white":  # the draw order of earlier versions: same series per seed
        if noise_m > 0:
            x += rng.normal(0.0, noise_m, n)
            y += rng.normal(0.0, noise_m, n)
        if noise_rad > 0:
            theta += rng.normal(0.0, noise_rad, n)
    else:
        x += draw_noise(noise_class, t, noise_m, rng, values=x)
        y += draw_noise(noise_class, t, noise_m, rng, values=y)
        theta += draw_noise(noise_class, t, noise_rad, rng, values=theta)
    if not theta_measured:
        theta[:] = np.nan
    data = pd.DataFrame({"frame": frame, "t": t, "x": x, "y": y, "theta": theta,
                         "ok": np.ones(n, dtype=int)})
    # (what the instrument states: a white one's sigma, a tracker's - errors that
    # persist - its rows' whole error)
    stated = noise_class in ("white", *PERSISTING_NOISE_CLASSES)
    if noise_m > 0 and stated:
        data["sigma_xy"] = noise_m
    if noise_rad > 0 and stated and theta_measured:
        data["sigma_theta"] = noise_rad
    extra = {} if theta_measured else {"theta_measured": False}
    if noise_class in PERSISTING_NOISE_CLASSES:
        extra["noise_persists"] = True
    meta = make_meta(
        fps, int(frame[-1]) + 1,
        t_stop_translation=float(stops[0]),
        t_stop_rotation=float(stops[1]),
        stop_frame_translation=_stop_row(frame, t, stops[0]),
        stop_frame_rotation=_stop_row(frame, t, stops[1]),
        simulation={"model": kind, "params": model.to_dict(),
                    "effects": [e.to_dict() for e in effects],
                    "noise_m": noise_m, "noise_rad": noise_rad, "seed": seed,
                    "tail_s": tail_s, "noise_class": noise_class,
                    **({} if sampling is None else {"sampling": asdict(sampling)})},
        **extra,
    )
    return Series(data, meta, None)


def _stop_row(frame, t, t_stop):
    i = stop_frame(t, t_stop)
    return None if i is None else int(frame[i])
