"""`curltrack calibrate` from the command line: outputs, exit codes, one-line errors."""

import json

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from curltrack.calib import Calibration
from curltrack.calib.artificial import PinholeCamera, draw_lattice
from curltrack.cli import app
from curltrack.rig import Rig

runner = CliRunner()


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    d = tmp_path_factory.mktemp("cal")
    cam = PinholeCamera(f=620, position=(0.02, 0.0, 2.1), yaw=0.2, k1=-0.1)
    img = draw_lattice(cam, seed=1)
    frame = d / "frame.png"
    cv2.imwrite(str(frame), img)
    video = d / "clip.mp4"
    w = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"mp4v"), 30.0, (960, 540))
    for _ in range(3):
        w.write(img)
    w.release()
    rig = d / "rig.toml"
    rig.write_text(Rig().to_toml())
    return d, frame, video, rig, cam


@pytest.mark.parametrize("source", ["frame", "video"])
def test_calibrate_writes_json_and_png(setup, source):
    d, frame, video, rig, cam = setup
    src = frame if source == "frame" else video
    out, png = d / f"{source}.json", d / f"{source}_overlay.png"
    args = ["calibrate", str(src), "--rig", str(rig), "-o", str(out), "--overlay", str(png)]
    if source == "video":
        args += ["--frame", "2"]
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    data = json.loads(out.read_text())
    for key in ("homography_image_to_ice", "camera_matrix", "dist_coeffs", "spacing_px",
                "n_threads", "residual_px", "camera_height_m"):
        assert key in data
    assert data["camera_height_m"] is None and any("camera_height_m" in n for n in data["notes"])
    cal = Calibration.from_dict(data)
    p = np.array([[100.0, 100.0], [850.0, 430.0]])
    # distance between two ice points is frame-independent: check it against the camera
    dm = np.linalg.norm(np.diff(cal.image_to_ice(p), axis=0))
    dt = np.linalg.norm(np.diff(cam.image_to_plane(p), axis=0))
    assert dm == pytest.approx(dt, abs=1e-3)
    assert cv2.imread(str(png)).shape == (540, 960, 3)


@pytest.mark.parametrize("kind, needle", [("grey", "no grid found"), ("missing", "no such file"),
                                          ("text", "cannot")])
def test_bad_input_exit_1_one_line(setup, kind, needle, tmp_path):
    d, frame, video, rig, cam = setup
    src = tmp_path / ("x.png" if kind != "text" else "x.mp4")
    if kind == "grey":
        cv2.imwrite(str(src), np.full((540, 960, 3), 200, np.uint8))
    elif kind == "text":
        src.write_text("not a video")
    out = tmp_path / "c.json"
    res = runner.invoke(app, ["calibrate", str(src), "--rig", str(rig), "-o", str(out)])
    assert res.exit_code == 1
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and needle in lines[0] and str(src) in lines[0]
    assert not out.exists()


def test_bad_rig_names_the_field(setup, tmp_path):
    d, frame, video, rig, cam = setup
    bad = tmp_path / "rig.toml"
    bad.write_text(rig.read_text().replace("spacing_x_m = 0.15\n", ""))
    res = runner.invoke(app, ["calibrate", str(frame), "--rig", str(bad), "-o",
                              str(tmp_path / "c.json")])
    assert res.exit_code == 1 and "spacing_x_m" in res.output
