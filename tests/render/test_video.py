"""The video file, determinism from the seed, occlusion, bad input, the CLI."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from render.shots import closed_form_shot
from curltrack.cli import app
from curltrack.errors import CurltrackError, ParameterError, RigError
from curltrack.rig import default_rig, load_rig, rig_from_dict
from curltrack.render import CameraConfig, IceStyle, Production, RenderConfig, render_video
from curltrack.series import read_series

SMALL = dict(width=480, height=270)


def _frames(path):
    cap = cv2.VideoCapture(str(path))
    out = []
    while True:
        ok, f = cap.read()
        if not ok:
            break
        out.append(f)
    cap.release()
    return out


def test_render_video_writes_video_truth_rig_and_settings(tmp_path):
    shot = closed_form_shot(y_F=0.4, t_F=1.0, theta_F=1.0)
    video, truth_path = tmp_path / "shot.mp4", tmp_path / "truth.csv"
    truth = render_video(shot, default_rig(), video, truth_path, RenderConfig(**SMALL), seed=4)
    frames = _frames(video)
    assert len(frames) == len(truth.data) == 61  # 1 s of motion + 1 s of rest at 30 fps
    assert frames[0].shape == (270, 480, 3)
    cap = cv2.VideoCapture(str(video))
    assert cap.get(cv2.CAP_PROP_FPS) == pytest.approx(30.0)
    back = read_series(truth_path)
    assert np.allclose(back.data[["x", "y", "theta"]], truth.data[["x", "y", "theta"]], atol=1e-8)
    assert back.meta["t_stop_translation"] == pytest.approx(1.0)
    assert back.meta["fps"] == 30.0 and back.meta["n_frames"] == 61
    rig = load_rig(tmp_path / "shot.rig.toml")
    assert rig.fps is None and rig.markers == default_rig().markers  # time: the container
    settings = json.loads((tmp_path / "shot.render.json").read_text())
    assert settings["seed"] == 4 and settings["camera"]["motion"] == "ladder"
    # the video really shows the rock moving: the frames differ around it
    assert np.abs(frames[0].astype(int) - frames[20].astype(int)).mean() > 1.0


def test_same_seed_same_frames_other_seed_other_frames():
    shot = closed_form_shot(y_F=0.3, t_F=1.0, theta_F=1.0, duration=0.2)
    cfg = RenderConfig(camera=CameraConfig(motion="handheld"), **SMALL)

    def run(seed):
        prod = Production(shot, default_rig(), cfg, seed)
        return [img for img, _ in prod.frames()], prod.truth().data

    a, ta = run(7)
    b, tb = run(7)
    c, tc = run(8)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    assert ta.equals(tb)
    # any frame renders the same alone (noise seeded per frame)
    alone = next(Production(shot, default_rig(), cfg, 7).frames(3, 4))[0]
    assert np.array_equal(alone, a[3])
    assert not np.array_equal(a[0], c[0])
    assert not np.allclose(ta["camera_x_m"], tc["camera_x_m"])


def test_broom_occludes_the_rock_when_asked():
    shot = closed_form_shot(y_F=0.3, t_F=1.5, theta_F=1.0, duration=1.5)
    cfg = RenderConfig(occlusion=True, occlusion_t_s=0.5, stopped_tail_s=0.0)
    prod = Production(shot, default_rig(), cfg, seed=3)
    truth = prod.truth().data
    occ = truth["occluded"].to_numpy()
    assert occ.max() > 0.5 and occ[0] == 0 and occ[-1] == 0
    k = int(np.argmax(occ))
    assert abs(truth["t"].iloc[k] - 0.5) < 0.1
    clear = Production(shot, default_rig(), RenderConfig(stopped_tail_s=0.0), seed=3)
    img_occ = next(prod.frames(k, k + 1))[0]
    img_clear = next(clear.frames(k, k + 1))[0]
    u, v = truth["u_top_px"].iloc[k], truth["v_top_px"].iloc[k]
    box = np.s_[int(v) - 20:int(v) + 20, int(u) - 20:int(u) + 20]
    # the broom head is dark: the rock's top gets darker where it passes
    assert img_occ[box].mean() < img_clear[box].mean() - 20


@pytest.mark.parametrize("config,match", [
    (RenderConfig(fps=0.0), "fps"),
    (RenderConfig(fps=-30.0), "fps"),
    (RenderConfig(blur_subframes=0), "blur_subframes"),
    (RenderConfig(shutter=1.5), "shutter"),
    (RenderConfig(ice=IceStyle(ice_color="iceblue")), "ice_color"),
    (RenderConfig(camera=CameraConfig(offset_m=(40.0, 0.0))), "outside the view"),
    (RenderConfig(camera=CameraConfig(motion="static", offset_m=(0.0, -3.0))), "outside the view"),
])
def test_bad_parameters_are_named(config, match):
    shot = closed_form_shot(y_F=0.3, t_F=1.0, theta_F=1.0)
    with pytest.raises(ParameterError, match=match):
        Production(shot, default_rig(), config, seed=0)


def test_unknown_rig_colour_is_a_rig_error():
    with pytest.raises(RigError, match="colour"):
        rig_from_dict({"grid": {"spacing_x_m": 0.15, "spacing_y_m": 0.15, "colors": ["redd"]},
                       "rock": {"diameter_m": 0.29, "height_m": 0.114},
                       "markers": [{"color": "#ffd000", "x_m": 0.08, "y_m": 0},
                                   {"color": "#00c0ff", "x_m": -0.08, "y_m": 0}]})


def test_series_with_too_few_rows_is_an_input_error():
    shot = closed_form_shot(y_F=0.3, t_F=1.0, theta_F=1.0)
    shot.data.loc[1:, "ok"] = 0
    with pytest.raises(CurltrackError, match="two measured rows"):
        Production(shot, default_rig(), RenderConfig(), seed=0)


def test_cli_render_and_its_errors(tmp_path):
    from curltrack.series import write_series

    shot = closed_form_shot(y_F=0.2, t_F=0.5, theta_F=0.5)
    sim = tmp_path / "sim.csv"
    write_series(sim, shot)
    runner = CliRunner()
    video = tmp_path / "v.mp4"
    res = runner.invoke(app, ["render", str(sim), "-o", str(video), "--truth",
                              str(tmp_path / "t.csv"), "--width", "320", "--height", "180",
                              "--camera", "handheld", "--seed", "2", "--quiet"])
    assert res.exit_code == 0, res.output
    assert video.exists() and (tmp_path / "t.csv").exists() and (tmp_path / "t.json").exists()
    assert (tmp_path / "v.rig.toml").exists() and (tmp_path / "v.render.json").exists()
    for args, code, text in [
        ([str(sim), "-o", str(tmp_path / "b.mp4"), "--fps", "0"], 1, "fps"),
        ([str(sim), "-o", str(tmp_path / "b.mp4"), "--camera", "drone"], 1, "motion"),
        ([str(tmp_path / "missing.csv"), "-o", str(tmp_path / "b.mp4")], 1, "missing.csv"),
        ([str(sim), "-o", str(tmp_path / "b.avi")], 2, "mp4"),
        # (DV is written in QuickTime, at DV's own sizes and rates)
        ([str(sim), "-o", str(tmp_path / "b.mp4"), "--codec", "dv"], 2, ".mov"),
        ([str(sim), "-o", str(tmp_path / "b.mov"), "--codec", "dv"], 1, "720x480"),
    ]:
        res = runner.invoke(app, ["render", *args, "--quiet"])
        assert res.exit_code == code, res.output
        assert text in res.output and "Traceback" not in res.output
        assert len(res.output.strip().splitlines()) == 1
        assert not (tmp_path / "b.mp4").exists() and not (tmp_path / "b.mov").exists()


def test_cli_initial_conditions_and_bad_rig(tmp_path):
    runner = CliRunner()
    video = tmp_path / "ic.mp4"
    res = runner.invoke(app, ["render", "--v0", "0.4", "--omega0", "1.0", "-o", str(video),
                              "--width", "320", "--height", "180", "--quiet"])
    assert res.exit_code == 0, res.output
    truth = read_series(tmp_path / "ic.truth.csv")
    assert truth.meta["t_stop_translation"] > 0
    assert truth.data["y"].iloc[-1] > 0.1  # it travelled along +y (within the skew)
    bad = tmp_path / "bad.toml"
    bad.write_text((tmp_path / "ic.rig.toml").read_text().replace("#ffd000", "#ffd00"))
    res = runner.invoke(app, ["render", "--v0", "0.4", "--omega0", "1.0", "--rig", str(bad),
                              "-o", str(tmp_path / "b.mp4"), "--quiet"])
    assert res.exit_code == 1 and "bad.toml" in res.output and "colour" in res.output
    assert "[[markers]][0].color" in res.output
    res = runner.invoke(app, ["render", "-o", str(tmp_path / "b.mp4")])
    assert res.exit_code == 2
