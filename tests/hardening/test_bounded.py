"""Bounded cost: discover thins inputs beyond a stated size; its memory stays bounded."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import pytest

from curltrack.physics.shot import ShotModel
from curltrack.sanity import DISCOVER_MAX_ROWS, bound_rows
from curltrack.series import write_series
from curltrack.simulate import simulate_series

#: The stated bound of discover's peak memory (README, scripts/bench_memory.py).
LIMIT_MB = 2048


def test_thinning_keeps_the_noise_model_and_never_mutates():
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    fps = float(rng.uniform(300, 1000))
    shots = [simulate_series(ShotModel(v0=rng.uniform(1, 2), omega0=1.5), fps=fps,
                             noise_m=0.001, seed=int(rng.integers(2**31))) for _ in range(2)]
    before = [s.data.copy() for s in shots]
    out, warn = bound_rows(shots)
    n = sum(len(s.data) for s in out)
    assert n <= DISCOVER_MAX_ROWS and n > DISCOVER_MAX_ROWS / 2, (seed, n)
    assert len(warn) == 1 and "every" in warn[0], warn
    for s, b, o in zip(shots, before, out):
        assert s.data.equals(b), seed  # inputs unchanged
        assert (np.diff(o.data["frame"]) == 1).all(), seed  # still consecutive
        assert np.isclose(o.data["t"].iloc[-1], s.data["t"].iloc[-1], atol=0.1), seed
    small = shots[:1]
    small[0] = simulate_series(ShotModel(v0=1.0, omega0=1.5), fps=30)
    same, none = bound_rows(small)
    assert same[0] is small[0] and none == []


@pytest.mark.slow
@pytest.mark.parametrize("case", ["1e5 rows", "60 s shot"])
def test_discover_memory_is_bounded(tmp_path, case):
    """Peak RSS (the child's own VmHWM) of `curltrack discover` under LIMIT_MB."""
    model = ShotModel(v0=1.6, omega0=1.5)
    if case == "1e5 rows":
        sim = simulate_series(model, fps=5000.0, noise_m=0.001, noise_rad=0.003, seed=1)
    else:
        end = float(simulate_series(model, fps=30.0).data["t"].iloc[-1])
        sim = simulate_series(model, fps=30.0, tail_s=60.0 - end, noise_m=0.001,
                              noise_rad=0.003, seed=1)
    shot = tmp_path / "shot.csv"
    write_series(shot, sim)
    sys.path.insert(0, str(Path(__file__).parents[2] / "scripts"))
    from bench_memory import command_peak_rss

    r = command_peak_rss(["discover", shot, "-o", tmp_path / "r.json"])
    assert r["peak_rss_mb"] < LIMIT_MB, (case, len(sim.data), r)
    assert os.path.getsize(tmp_path / "r.json") > 0
