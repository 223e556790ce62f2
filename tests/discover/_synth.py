"""Synthetic shots for the discovery tests: the simulator + Gaussian noise, as Series.

Kept independent of ``curltrack.simulate`` (being written in parallel): the series
format is the contract's, stop times come from the simulator's trajectory.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from curltrack.physics import Effect, ShotModel, simulate
from curltrack.series import Series, make_meta

NOISE_M = 0.002
NOISE_RAD = np.radians(0.3)


def draw_model(rng, v0=(1.6, 2.2), spin=None, **kw) -> ShotModel:
    """A draw shot with parameters drawn from ranges (paper-like pebbled ice)."""
    sgn = spin if spin is not None else rng.choice([-1, 1])
    base = dict(v0=float(rng.uniform(*v0)), omega0=float(sgn * rng.uniform(1.0, 2.5)),
                phi_y=float(rng.uniform(-0.4, 0.0)), alpha_y=float(rng.uniform(0.006, 0.01)),
                phi_theta=float(rng.uniform(-1.4, -0.9)), alpha_theta=None,
                a_T=float(rng.uniform(3e-3, 7e-3)))
    base.update(kw)
    m = ShotModel(**base)
    return ShotModel(**{**base, "alpha_theta": m.alpha_theta_value})


def make_series(model, effects=(), rng=None, fps=30.0, noise_m=NOISE_M, noise_rad=NOISE_RAD,
                tail_s=1.0, heading_deg=None) -> Series:
    """Simulate, sample at ``fps`` until ``tail_s`` after both stops, add noise."""
    rng = rng or np.random.default_rng(0)
    eff = tuple(Effect(n, p) for n, p in effects)
    tr = simulate(model, effects=eff, t=np.array([0.0]))
    t_end = max(v for v in (tr.t_stop_translation, tr.t_stop_rotation) if np.isfinite(v))
    t = np.arange(0.0, t_end + tail_s, 1.0 / fps)
    tr = simulate(model, effects=eff, t=t)
    n = t.size
    data = pd.DataFrame({
        "frame": np.arange(n), "t": t,
        "x": tr.x + rng.normal(0, noise_m, n), "y": tr.y + rng.normal(0, noise_m, n),
        "theta": tr.theta + rng.normal(0, noise_rad, n), "ok": np.ones(n, int)})
    meta = make_meta(fps, n, t_stop_translation=float(tr.t_stop_translation),
                     t_stop_rotation=float(tr.t_stop_rotation))
    if heading_deg is not None:
        meta["rink_heading_deg"] = heading_deg
    return Series(data, meta, None)
