#!/usr/bin/env python
"""Benchmark of the forward model per solver path and effect (targets: < 50 ms per draw;
< 20 ms inside fits).  scripts/bench.py measures the baseline draw among everything else.

Times one typical draw (v0 = 2 m/s, omega0 = 1.5 rad/s, ~26 s, ~0.9 m curl) sampled at
30 fps, for each solver path and with each effect, as the median of repeated runs in one
process (first call excluded: imports).  Usage: python scripts/bench_simulate.py [-n 30]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from curltrack.physics import Effect, ShotModel, simulate
from curltrack.physics.segment import SegmentModel, simulate_segment
from curltrack.simulate import simulate_series

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench import _median_ms as _time  # noqa: E402  (scripts/bench.py: the house timer)

CASES = {
    "paper, baseline (closed forms + quadrature)": ((), "auto"),
    "paper, baseline forced through the ODE": ((), "ode"),
    "paper + late_curl": ((Effect("late_curl", {"k": 0.5}),), "auto"),
    "paper + pick": ((Effect("pick", {"t_s": 8.0, "domega_rad_per_s": -0.5}),), "auto"),
    "paper + ice_slope (ODE)": ((Effect("ice_slope", {"slope_x_mm_per_m": 1.0}),), "auto"),
    "paper + friction_patch (piecewise closed)": (
        (Effect("friction_patch", {"y_start_m": 10, "y_end_m": 15, "factor": 1.3}),), "auto"),
}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-n", type=int, default=30, help="repetitions")
    n = ap.parse_args(argv).n
    model = ShotModel(v0=2.0, omega0=1.5)
    t = np.arange(0, 27.0, 1 / 30)
    for name, (effects, method) in CASES.items():
        ms = _time(lambda: simulate(model, effects, t=t, method=method), n)
        print(f"{name:48s} {ms:8.2f} ms")
    ms = _time(lambda: simulate_series(model, noise_m=0.002, noise_rad=0.005, seed=1), n)
    print(f"{'simulate_series (paper, with noise)':48s} {ms:8.2f} ms")
    seg = SegmentModel(v0=2.0, omega0=1.5)
    ms = _time(lambda: simulate_segment(seg, t=t), max(3, n // 10))
    print(f"{'segment model (64 segments, film)':48s} {ms:8.2f} ms")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
