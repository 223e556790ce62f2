"""The effect registry: a sixth effect is one definition, and every stage sees it.

A toy effect (a sideways kick at an unknown time) is registered with one
:class:`EffectDef`; without any other change it is accepted by ``curltrack simulate
--effect``, becomes one of ``discover``'s candidates, and is scored and reported in
REPORT.json when hidden in a simulated shot.
"""

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from curltrack.cli import app
from curltrack.discover import discover, write_report
from curltrack.discover.candidates import build_candidates, untested
from curltrack.discover.shots import shot_from_series
from curltrack.physics import EFFECTS, Effect, ShotModel, simulate
from curltrack.physics.registry import (REQUIRED, Candidate, EffectDef, Param,
                                        at_a_time_in_one_shot, register, time_grid,
                                        unregister)
from curltrack.series import read_series

TOY = EffectDef(
    "toy_sidekick",
    (Param("t_s", REQUIRED, "s"), Param("dvx_m_per_s", REQUIRED, "m/s")),
    terms=lambda p: {"impulse": (p["t_s"], p["dvx_m_per_s"], 0.0, 0.0)},
    check=lambda p: "t_s must be >= 0" if p["t_s"] < 0 else None,
    candidate=lambda shots, baseline: Candidate(
        "toy_sidekick", [Param("dvx_m_per_s", null=0.0, lower=-1.0, upper=1.0, unit="m/s",
                               step=1e-5)],
        location=[Param("t_s", null=0.0, lower=0.0, upper=1e9, unit="s", step=1e-3)],
        grid=time_grid(shots), note="a sideways kick at t_s"),
    **at_a_time_in_one_shot("toy_sidekick", ("t_s", "dvx_m_per_s")))


@pytest.fixture
def toy():
    register(TOY)
    yield TOY
    unregister(TOY.name)


def test_registry_holds_the_five_contract_effects_in_order():
    assert list(EFFECTS)[:5] == ["velocity_dependent_friction", "ice_slope",
                                 "friction_patch", "late_curl", "pick"]
    for defn in EFFECTS.values():
        assert defn.param_names, defn.name


def test_a_sixth_effect_is_one_definition(toy, tmp_path):
    entropy = np.random.SeedSequence().entropy
    rng = np.random.default_rng(entropy)
    v0, w0 = rng.uniform(1.6, 2.0), rng.choice([-1, 1]) * rng.uniform(1.0, 2.0)
    t_kick, kick = rng.uniform(3.0, 8.0), rng.choice([-1, 1]) * rng.uniform(0.006, 0.01)
    msg = f"entropy {entropy}: v0 {v0:.3f} omega0 {w0:.3f} t {t_kick:.2f} s dvx {kick:.4f}"

    # the simulator: the kick changes vx by dvx at t_s and nothing before
    m = ShotModel(v0=v0, omega0=w0)
    t = np.array([t_kick - 0.1, t_kick + 1e-6, t_kick + 0.5])
    a, b = simulate(m, t=t), simulate(m, [Effect("toy_sidekick", {"t_s": t_kick,
                                                               "dvx_m_per_s": kick})], t=t)
    assert b.x[0] == pytest.approx(a.x[0], abs=1e-9), msg
    assert b.vx[1] - a.vx[1] == pytest.approx(kick, rel=1e-3), msg
    assert b.x[2] - a.x[2] == pytest.approx(0.5 * kick, rel=0.1), msg

    # the command line
    out = tmp_path / "sim.csv"
    res = CliRunner().invoke(app, [
        "simulate", "--v0", f"{v0}", "--omega0", f"{w0}", "--effect", "toy_sidekick",
        "--param", f"t_s={t_kick}", "--param", f"dvx_m_per_s={kick}", "--noise-m", "0.002",
        "--noise-rad", "0.005", "--seed", str(int(rng.integers(2**31))), "-o", str(out)])
    assert res.exit_code == 0, res.output
    series = read_series(out)
    assert series.meta["simulation"]["effects"][0]["effect"] == "toy_sidekick"

    # discovery's candidates, the finding and REPORT.json
    shots = [shot_from_series(series)]
    names = [c.name for c in build_candidates(shots, "paper")]
    assert names[-1] == "toy_sidekick" and "pick" in names, names
    assert "toy_sidekick" not in untested(shots, "paper")
    rep = discover(series, effects=["toy_sidekick"], n_boot=100, seed=1)
    write_report(rep, tmp_path / "REPORT.json")
    saved = json.loads((tmp_path / "REPORT.json").read_text())
    f = next(f for f in saved["findings"] if f["effect"] == "toy_sidekick")
    assert f["evidence"] and "delta_bic" in f and "threshold" in f, f
    # whether it is *named* is discover's decision (thresholds under the measured noise,
    # tested with the contract's effects in tests/discover); when it is supported its
    # parameters are the hidden ones
    if f["supported"]:
        assert f["params"]["t_s"] == pytest.approx(t_kick, abs=0.3), msg
        assert f["params"]["dvx_m_per_s"] == pytest.approx(kick, rel=0.2), msg
        assert f["params"]["shot"] == 0


def test_an_unregistered_effect_is_refused(toy):
    unregister("toy_sidekick")
    res = CliRunner().invoke(app, ["simulate", "--v0", "2", "--omega0", "1", "--effect",
                                   "toy_sidekick", "-o", "x.csv"])
    assert res.exit_code == 2 and "unknown effect 'toy_sidekick'" in res.output
