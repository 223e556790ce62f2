"""`curltrack doctor`: the checklist on good and bad rendered videos."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from curltrack.rig import Marker
from hardening.badinputs import edit_video, hide_grid, other_colour_rig


def _status(data) -> dict:
    return {c["name"]: c["status"] for c in data["checks"]}


@pytest.fixture(scope="module")
def good_report(cli, hdir, rig_file, good_clip):
    """One doctor run on the good clip: (text on stdout, JSON written with -o)."""
    out = hdir / "doctor_good.json"
    res = cli.succeeds("doctor", good_clip[0], "--rig", rig_file, "-o", out)
    return res.stdout, json.loads(out.read_text())


def test_good_video_is_ready(good_report, good_clip):
    text, data = good_report
    video, truth, _ = good_clip
    assert data["ok"] is True
    st = _status(data)
    assert all(st[k] == "ok" for k in ("video", "fps", "markers", "grid", "rock_size",
                                       "camera_height", "camera_turn")), st
    checks = {c["name"]: c["values"] for c in data["checks"]}
    assert checks["video"]["n_frames"] == len(truth.data)
    assert checks["fps"]["fps"] == pytest.approx(truth.meta["fps"])
    assert checks["grid"]["spacing_px"] == pytest.approx(truth.meta["grid_spacing_px"], rel=0.05)
    assert np.isfinite(checks["grid"]["residual_px"]) and checks["grid"]["residual_px"] < 1.0
    H = float(truth.data["camera_height_m"].iloc[0])
    # one-frame parallax estimates (markers 16 cm apart): a plausibility check, ~10 %
    assert checks["camera_height"]["camera_height_m"] == pytest.approx(H, rel=0.12)
    yaw = truth.data["camera_yaw_deg"].to_numpy()
    assert checks["camera_turn"]["max_turn_deg_per_frame"] < np.abs(np.diff(yaw)).max() + 0.2
    # the scale check's resolution, as track records it: a warning when coarser than 3 %
    res = checks["grid_scale"]["resolution"]
    assert res is None or 0 < res < 0.3, res
    assert st["grid_scale"] == ("ok" if res is not None and res <= 0.03 else "warn"), checks
    assert "✓ markers" in text and "ready to track" in text


def test_wrong_colours_are_fatal(cli, hdir, good_clip):
    video, _, rig = good_clip
    other = hdir / "doctor_other.toml"
    other.write_text(other_colour_rig(rig).to_toml())
    line = cli.fails("doctor", video, "--rig", other, names=[video, "markers"])
    assert other_colour_rig(rig).markers[0].color in line
    res = cli("doctor", video, "--rig", other, "--json")
    assert res.exit_code == 1 and _status(json.loads(res.stdout))["markers"] == "fail"


def test_a_video_without_colour_is_named(cli, hdir, rig_file, good_clip):
    """A monochrome camera or a black-and-white export: track and doctor said no marker
    of the rig's colours was seen and told the user to check the rig's colours; both
    now say the video has no colour."""
    import cv2

    video, _, _ = good_clip
    grey = edit_video(video, hdir / "doctor_grey.mp4", lambda k, img: cv2.cvtColor(
        cv2.cvtColor(img, cv2.COLOR_BGR2GRAY), cv2.COLOR_GRAY2BGR))
    line = cli.fails("track", grey, "--rig", rig_file, "-o", hdir / "grey.csv",
                     output=hdir / "grey.csv", names=[grey, "no colour"])
    assert "markers" in line
    res = cli("doctor", grey, "--rig", rig_file, "--json")
    checks = {c["name"]: c for c in json.loads(res.stdout)["checks"]}
    assert res.exit_code == 1 and checks["markers"]["status"] == "fail"
    assert "no colour" in checks["markers"]["advice"], checks["markers"]


def test_hidden_grid_is_fatal(cli, hdir, rig_file, good_clip):
    video, truth, _ = good_clip
    tr = truth.data
    v = edit_video(video, hdir / "doctor_nogrid.mp4",
                   lambda k, img: hide_grid(img, (tr.u_top_px[k], tr.v_top_px[k]), 42))
    cli.fails("doctor", v, "--rig", rig_file, names=[v, "grid"])


def test_unreadable_video_is_fatal(cli, hdir, rig_file, good_clip):
    v = hdir / "doctor_trunc.mp4"
    v.write_bytes(good_clip[0].read_bytes()[:5000])
    res = cli("doctor", v, "--rig", rig_file, "--json")
    assert res.exit_code == 1
    assert _status(json.loads(res.stdout)) == {"video": "fail"}


@pytest.mark.parametrize("factor", [1.3, 0.7])
def test_wrong_marker_layout_is_fatal(cli, hdir, good_clip, factor):
    """Markers placed 30 % off in the rig: the parallax would scale every position wrong
    (it was a warning); the rock's outline agrees with the grid, so the markers are
    named."""
    video, _, rig = good_clip
    bad = replace(rig, markers=tuple(Marker(m.color, m.x_m * factor, m.y_m * factor)
                                     for m in rig.markers))
    p = hdir / f"doctor_layout{factor}.toml"
    p.write_text(bad.to_toml())
    res = cli("doctor", video, "--rig", p, "--json", "--samples", "3")
    data = json.loads(res.stdout)
    assert res.exit_code == 1 and _status(data)["camera_height"] == "fail"
    assert _status(data)["markers"] == "ok"
    check = next(c for c in data["checks"] if c["name"] == "camera_height")
    assert "[[markers]]" in check["detail"], check


def test_rig_camera_height_disagreeing_is_fatal(cli, hdir, good_clip):
    video, truth, rig = good_clip
    H = float(truth.data["camera_height_m"].iloc[0])
    p = hdir / "doctor_height.toml"
    p.write_text(replace(rig, camera_height_m=round(2.5 * H, 2)).to_toml())
    res = cli("doctor", video, "--rig", p, "--json", "--samples", "3")
    data = json.loads(res.stdout)
    assert res.exit_code == 1 and _status(data)["camera_height"] == "fail"
    check = next(c for c in data["checks"] if c["name"] == "camera_height")
    assert "[camera].height_m" in check["detail"], check


@pytest.mark.parametrize("band,status", [((0.1, 0.6), "ok"), ((2.0, 4.0), "warn"),
                                         ((12.0, 20.0), "fail")])
def test_camera_turn_rate(cli, hdir, rig_file, wide_clip, band, status):
    """A camera turning steadily at a rate drawn from the band: measured and judged."""
    from hardening.badinputs import read_frames, rotate_crop, write_frames

    video, truth, _ = wide_clip
    rate = float(np.random.default_rng(int(band[0] * 10)).uniform(*band))
    v = write_frames(hdir / f"doctor_turn{band[0]:g}.mp4",
                     (rotate_crop(img, rate * k, (400, 224))
                      for k, img in enumerate(read_frames(video))), truth.meta["fps"])
    res = cli("doctor", v, "--rig", rig_file, "--json", "--samples", "3")
    data = json.loads(res.stdout)
    turn = next(c for c in data["checks"] if c["name"] == "camera_turn")
    assert turn["status"] == status, turn
    assert turn["values"]["max_turn_deg_per_frame"] == pytest.approx(rate, abs=0.1, rel=0.03)
    assert res.exit_code == (1 if status == "fail" else 0)
