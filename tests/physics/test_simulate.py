"""simulate_series and the ``curltrack simulate`` command."""

import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from curltrack.cli import app
from curltrack.errors import ParameterError
from curltrack.physics import Effect, ShotModel, simulate
from curltrack.series import read_series, write_series
from curltrack.simulate import simulate_series

runner = CliRunner()


@pytest.mark.parametrize("fps", [30.0, 29.97, 60.0])
def test_series_rows_stop_frames_and_tail(fps):
    m = ShotModel(v0=1.8, omega0=-2.0)
    s = simulate_series(m, fps=fps, tail_s=1.5)
    t = s.data["t"].to_numpy()
    np.testing.assert_allclose(np.diff(t), 1 / fps)
    meta = s.meta
    t_stop = meta["t_stop_translation"]
    assert t_stop == pytest.approx(m.stop_times()[0], rel=1e-9)
    assert t[-1] >= max(t_stop, meta["t_stop_rotation"]) + 1.5 - 1 / fps
    k = meta["stop_frame_translation"]
    assert t[k] >= t_stop > t[k - 1]
    assert meta["n_frames"] == len(t) and meta["fps"] == fps
    assert list(s.data.columns[:6]) == ["frame", "t", "x", "y", "theta", "ok"]
    assert s.data["x"].iloc[-1] > 0                   # clockwise spin curls to +x
    exact = simulate(m, t=t)
    np.testing.assert_allclose(s.data["y"], exact.y)


def test_noise_is_seeded_and_has_the_requested_size():
    m = ShotModel(v0=2.0, omega0=1.5)
    a = simulate_series(m, noise_m=0.002, noise_rad=0.005, seed=11)
    b = simulate_series(m, noise_m=0.002, noise_rad=0.005, seed=11)
    clean = simulate_series(m)
    np.testing.assert_array_equal(a.data["x"], b.data["x"])
    dx = (a.data["x"] - clean.data["x"]).to_numpy()
    dth = (a.data["theta"] - clean.data["theta"]).to_numpy()
    n = len(dx)
    assert np.std(dx) == pytest.approx(0.002, rel=4 / math.sqrt(n))
    assert np.std(dth) == pytest.approx(0.005, rel=4 / math.sqrt(n))
    assert (a.data["sigma_xy"] == 0.002).all()


def test_series_round_trip(tmp_path):
    s = simulate_series(ShotModel(v0=2.0, omega0=1.5),
                        (Effect("ice_slope", {"slope_x_mm_per_m": 1.0}),), seed=1)
    write_series(tmp_path / "sim.csv", s)
    back = read_series(tmp_path / "sim.csv")
    np.testing.assert_allclose(back.data["x"], s.data["x"], rtol=1e-8, atol=1e-12)
    assert back.meta["simulation"]["effects"][0]["effect"] == "ice_slope"
    again = ShotModel.from_dict(back.meta["simulation"]["params"])
    assert again == ShotModel(v0=2.0, omega0=1.5)


@pytest.mark.parametrize("kw", [dict(fps=0.0), dict(noise_m=-1.0), dict(tail_s=math.nan)])
def test_series_invalid_options(kw):
    with pytest.raises(ParameterError):
        simulate_series(ShotModel(v0=2.0, omega0=1.5), **kw)


def test_series_rock_that_never_stops():
    m = ShotModel(v0=2.0, omega0=0.0, phi_y=0.0, alpha_y=0.001)   # friction < slope
    with pytest.raises(ParameterError, match="does not stop"):
        simulate_series(m, (Effect("ice_slope", {"slope_y_mm_per_m": -5.0}),))


def test_cli_default_draw(tmp_path):
    out = tmp_path / "sim.csv"
    res = runner.invoke(app, ["simulate", "--v0", "2.0", "--omega0", "1.5", "-o", str(out)])
    assert res.exit_code == 0, res.output
    s = read_series(out)
    meta = json.loads((tmp_path / "sim.json").read_text())
    assert 23 < meta["t_stop_translation"] < 28
    assert s.data["x"].iloc[-1] < -0.5


def test_cli_effects_and_overrides(tmp_path):
    out = tmp_path / "sim.parquet"
    res = runner.invoke(app, [
        "simulate", "--v0", "2.0", "--omega0", "-1.0", "--phi", "-0.3", "--alpha-y", "0.008",
        "--a-T", "0.004", "--effect", "pick", "--param", "t_s=5", "--param",
        "domega_rad_per_s=0.5", "--effect", "ice_slope", "--param", "slope_x_mm_per_m=1",
        "--effect", "pick", "--param", "t_s=9", "--param", "dvx_m_per_s=0.01",
        "--noise-m", "0.001", "--seed", "4", "--fps", "25", "-o", str(out)])
    assert res.exit_code == 0, res.output
    meta = read_series(out).meta
    sim = meta["simulation"]
    assert [e["effect"] for e in sim["effects"]] == ["pick", "ice_slope", "pick"]
    assert sim["effects"][2]["params"]["t_s"] == 9 and sim["effects"][2]["params"]["dvx_m_per_s"] == 0.01
    assert sim["params"]["phi_theta"] == -0.3 and sim["params"]["alpha_y"] == 0.008
    assert meta["fps"] == 25


@pytest.mark.parametrize("args,code,text", [
    (["--effect", "bogus"], 2, "unknown effect"),
    (["--effect", "pick", "--param", "k=1"], 2, "not a parameter"),
    (["--effect", "pick", "--param", "t_s"], 2, "KEY=VALUE"),
    (["--param", "t_s=1"], 2, "not a parameter"),
    (["--alpha", "-0.01"], 1, "alpha"),
    (["--phi", "1.0"], 1, "phi"),
    (["--a-T", "-0.01"], 1, "a-T"),
    (["--effect", "friction_patch", "--param", "y_start_m=5", "--param", "y_end_m=2",
      "--param", "factor=2"], 1, "y_end_m"),
    (["--model", "other"], 2, "paper or segment"),
])
def test_cli_errors(tmp_path, args, code, text):
    out = tmp_path / "sim.csv"
    res = runner.invoke(app, ["simulate", "--v0", "2", "--omega0", "1.5", *args, "-o", str(out)])
    assert res.exit_code == code, res.output
    assert text in res.output
    assert "Traceback" not in res.output
    assert not out.exists()


def test_cli_nan_is_an_error(tmp_path):
    res = runner.invoke(app, ["simulate", "--v0", "nan", "--omega0", "1", "-o",
                              str(tmp_path / "s.csv")])
    assert res.exit_code == 1 and "v0" in res.output
