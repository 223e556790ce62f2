"""The camera sweep's set-ups: every kind drawn valid, its artefacts as the kind says, and
the sweep script's scoring right on a known error."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from curltrack.render import Production
from curltrack.render.sweep import KINDS, draw_setup
from curltrack.rig import default_rig
from curltrack.series import Series, make_meta


def _seed():
    return int(np.random.SeedSequence().entropy % 2**32)


@pytest.mark.parametrize("kind", KINDS)
def test_every_kind_draws_valid_setups_with_its_artefacts(kind):
    seed = _seed()
    rng = np.random.default_rng(seed)
    for _ in range(3):
        s = draw_setup(rng, kind, scale=float(rng.uniform(0.3, 1.0)))
        prod = Production(s.shot, default_rig(), s.config, s.seed)  # validates everything
        cfg, sen = s.config, s.config.sensor
        assert 60 <= prod.n_frames <= 400, (seed, kind, prod.n_frames)
        assert s.shot.meta["t_stop_translation"] < prod.t_frames[-1], (seed, kind)
        if kind == "camcorder":
            assert sen.interlaced and sen.chroma == "411", seed
            assert (cfg.width, cfg.height) == (720, 480) and cfg.camera.pixel_aspect < 1
            assert cfg.encoding.codec == "h264" and cfg.encoding.bitrate_bps <= 2e6, seed
        if kind == "camcorder-pal":
            assert sen.interlaced and sen.chroma == "420" and cfg.fps == 25.0, seed
            assert (cfg.width, cfg.height) == (720, 576) and cfg.camera.pixel_aspect > 1
            assert cfg.encoding.field_colour in ("shared", "top", "own"), seed
        if kind == "phone":
            assert sen.readout_s > 0 and sen.frame_jitter_s > 0, seed
        if kind == "action":
            lens = cfg.camera
            assert lens.lens == "fisheye" or lens.k1 <= -0.2, seed
            assert sen.readout_s > 0, seed


def _sweep_module():
    path = Path(__file__).resolve().parents[2] / "scripts" / "sweep_cameras.py"
    spec = importlib.util.spec_from_file_location("sweep_cameras", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_sweep_score_on_a_known_error():
    seed = _seed()
    rng = np.random.default_rng(seed)
    n = 60
    t = np.arange(n) / 30
    truth = pd.DataFrame(dict(frame=np.repeat(np.arange(n), 2), field=np.tile([0, 1], n),
                              t=np.repeat(t, 2), x=rng.normal(0, 1, 2 * n),
                              y=rng.normal(0, 1, 2 * n), theta=rng.normal(0, 1, 2 * n), ok=1))
    sig = rng.uniform(0.5e-3, 2e-3)
    f0 = truth[truth.field == 0].reset_index(drop=True)
    err = rng.normal(0, sig, (n, 3))
    err[:, :2] += rng.normal(0, sig, 2)     # every row's share: the origin's error
    tracked = pd.DataFrame(dict(frame=np.arange(n), t=t, x=f0.x + err[:, 0], y=f0.y + err[:, 1],
                                theta=f0.theta + err[:, 2], ok=1, sigma_xy=sig,
                                sigma_theta=2 * sig))
    tracked.loc[:9, "ok"] = 0
    out = _sweep_module().score(Series(tracked, make_meta(30.0, n)),
                                Series(truth, make_meta(30.0, n)))
    e = np.hypot(err[10:, 0], err[10:, 1])
    assert out["measured"] == pytest.approx(50 / 60), seed
    assert out["pos_rms_mm"] == pytest.approx(1e3 * np.sqrt(np.mean(e ** 2))), seed
    assert out["max_mm"] == pytest.approx(1e3 * e.max()), seed
    assert out["z_xy"] == pytest.approx(np.std(err[10:, :2]) / sig), seed
    assert out["z_theta"] == pytest.approx(np.std(err[10:, 2]) / (2 * sig)), seed
    assert out["rms_z_xy"] == pytest.approx(np.sqrt(np.mean(err[10:, :2] ** 2)) / sig), seed
    assert out["shared_mm"] == pytest.approx(1e3 * np.hypot(*err[10:, :2].mean(axis=0))), seed


def test_sweep_row_for_a_setup_the_renderer_refuses(tmp_path, monkeypatch):
    """One set-up the renderer cannot draw is a row with its one-line error; the sweep
    goes on."""
    import sys

    import curltrack.render  # noqa: F401  (the package; its name is shadowed by a function)
    from curltrack.errors import ParameterError

    render = sys.modules["curltrack.render"]

    def refuse(*args, **kwargs):
        raise ParameterError("lens distortion folds over inside the image (k1, k2 too "
                             "strong for this field of view)", where="camera.k1")

    monkeypatch.setattr(render, "render_video", refuse)
    seed = _seed()
    row = _sweep_module().run(0, seed, 1, 0.25, tmp_path, track=True, random_kind=True)
    assert row["error"].startswith("render: ") and "folds over" in row["error"], (seed, row)
    assert "kind" in row and "frames" not in row, (seed, row)


def test_sweep_table_pools_rms_z_by_scan():
    mod = _sweep_module()
    rows = [dict(i=0, scan="progressive", rms_z_xy=0.6), dict(i=1, scan="progressive", rms_z_xy=1.4),
            dict(i=2, scan="interlaced", rms_z_xy=2.0), dict(i=3, scan="progressive",
                                                           error="render: refused")]
    pooled = mod.pooled_rms_z(rows)
    assert pooled["progressive"] == (pytest.approx(np.sqrt((0.36 + 1.96) / 2)), 2)
    assert pooled["interlaced"] == (pytest.approx(2.0), 1)
    assert "Pooled RMS e/σ xy: progressive 1.08 (2 set-ups); interlaced 2.00" in mod.table(rows)
