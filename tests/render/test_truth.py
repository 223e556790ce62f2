"""Truth and image agree: the truth, projected through the renderer's camera, lands on
the drawn markers (< 0.1 px), and the truth is the input shot in the contract's frame."""

from __future__ import annotations

import numpy as np
import pytest

from render.shots import closed_form_shot, marker_centroid
from curltrack.rig import default_rig, rig_from_dict
from curltrack.render import CameraConfig, Production, RenderConfig

CLEAN = dict(read_noise=0.0, shot_noise_gain=0.0, jpeg_quality=None, stopped_tail_s=0.0)


def _rot(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s], [s, c]])


def _markers_from_truth(row, meta, rig):
    """World positions (N, 3) of the markers from a truth row and the render record."""
    r = meta["render"]
    centre = _rot(np.deg2rad(r["truth_rotation_deg"])) @ [row["x"], row["y"]]
    psi = np.deg2rad(r["psi0_deg"]) + row["theta"]
    out = [np.r_[centre + _rot(psi) @ [m.x_m, m.y_m], rig.rock_height_m] for m in rig.markers]
    return np.array(out)


def _random_camera(rng):
    return CameraConfig(motion=str(rng.choice(["ladder", "handheld"])),
                        height_m=float(rng.uniform(1.5, 3.0)), tilt_deg=float(rng.uniform(0, 3)),
                        k1=float(rng.uniform(-0.15, 0.0)), view_m=float(rng.uniform(1.5, 2.5)))


THREE_MARKERS = {
    "grid": {"spacing_x_m": 0.1, "spacing_y_m": 0.2, "colors": ["#20a040", "#e020c0", "#2040d0"]},
    "rock": {"diameter_m": 0.29, "height_m": 0.12},
    "markers": [{"color": "#ffd000", "x_m": 0.07, "y_m": 0.02},
                {"color": "#00c0ff", "x_m": -0.05, "y_m": 0.06},
                {"color": "#ff8000", "x_m": -0.02, "y_m": -0.075}],
}


@pytest.mark.parametrize("case", range(4))
@pytest.mark.parametrize("blur", [1, 5])
def test_truth_projects_onto_drawn_markers(case, blur):
    rng = np.random.default_rng(100 + case)
    rig = default_rig() if case % 2 == 0 else rig_from_dict(THREE_MARKERS)
    shot = closed_form_shot(y_F=rng.uniform(0.3, 2.0), t_F=rng.uniform(1.5, 3.0),
                            theta_F=rng.uniform(-4, 4), a_T=rng.uniform(-0.05, 0.05),
                            duration=0.3)
    cfg = RenderConfig(camera=_random_camera(rng), blur_subframes=blur,
                       heading_deg=float(rng.uniform(-40, 40)), **CLEAN)
    prod = Production(shot, rig, cfg, seed=case)
    truth = prod.truth()
    projected = [prod.cams[k].project(_markers_from_truth(truth.data.iloc[k], truth.meta, rig))
                 for k in range(prod.n_frames)]
    worst = 0.0
    for img, info in prod.frames():
        k = info.index
        expected = projected[k]
        assert info.camera is prod.cams[k]
        # image velocity (px/frame) from the neighbouring frames' truth -> the streak
        lo, hi = max(k - 1, 0), min(k + 1, prod.n_frames - 1)
        smear = (projected[hi] - projected[lo]) / (hi - lo) * cfg.shutter
        for i, uv in enumerate(expected):
            got = marker_centroid(img, uv, smear=smear[i] if blur > 1 else (0, 0))
            worst = max(worst, np.abs(got - uv).max())
        row = truth.data.iloc[k]  # the truth's own image columns: the same projection
        assert np.allclose(expected[:, 0], [row[f"marker{i}_u_px"] for i in range(len(expected))])
    assert worst < 0.1, f"drawn marker {worst:.3f} px away from the projected truth"


@pytest.mark.parametrize("heading_deg", [-30.0, 0.7, 20.0, 60.0, 130.0, -100.0])
def test_truth_is_the_shot_in_the_grid_frame(heading_deg):
    shot = closed_form_shot(y_F=1.2, t_F=2.0, theta_F=3.0, a_T=-0.08, duration=2.5)
    cfg = RenderConfig(heading_deg=heading_deg, **CLEAN)
    prod = Production(shot, default_rig(), cfg, seed=1)
    truth = prod.truth()
    d = truth.data
    # +y = the grid axis closest to the travel: the shot turned by heading minus k * 90 deg
    k = np.round(heading_deg / 90.0)
    assert truth.meta["render"]["truth_rotation_deg"] == pytest.approx(90.0 * k)
    expect = shot.data[["x", "y"]].to_numpy() @ _rot(np.deg2rad(heading_deg - 90.0 * k)).T
    n = len(shot.data)
    assert np.allclose(d[["x", "y"]].to_numpy()[:n], expect, atol=1e-9)
    assert np.allclose(d["theta"].to_numpy()[:n], shot.data["theta"], atol=1e-12)
    assert d["x"].iloc[0] == 0 and d["y"].iloc[0] == 0 and d["theta"].iloc[0] == 0
    assert (d["ok"] == 1).all() and (d["in_view"] == 1).all()


def test_pure_rotation_truth_axis_follows_image_up():
    shot = closed_form_shot(y_F=0.0, t_F=1.0, theta_F=6.0, t_Ftheta=1.0, duration=1.0)
    for yaw in (3.0, 80.0, 185.0, -95.0):
        cfg = RenderConfig(camera=CameraConfig(yaw_deg=yaw), **CLEAN)
        prod = Production(shot, default_rig(), cfg, seed=2)
        meta = prod.truth().meta
        # image up = image right + 90 deg; truth +y = the closest grid axis to it
        assert meta["render"]["truth_rotation_deg"] == pytest.approx(90.0 * np.round(yaw / 90.0))
        assert np.allclose(prod.truth().data[["x", "y"]], 0.0)


def test_stop_times_and_tail():
    shot = closed_form_shot(y_F=0.5, t_F=1.0, theta_F=1.0, t_Ftheta=1.2)
    prod = Production(shot, default_rig(), RenderConfig(stopped_tail_s=1.0), seed=0)
    truth = prod.truth()
    m = truth.meta
    assert m["t_stop_translation"] == pytest.approx(1.0)
    assert m["t_stop_rotation"] == pytest.approx(1.2)
    assert m["stop_frame_translation"] == 30 and m["stop_frame_rotation"] == 36
    t = truth.data["t"].to_numpy()
    assert t[-1] == pytest.approx(2.2, abs=1 / 30)  # one second of rest after the last stop
    tail = truth.data[t >= 1.2]
    assert np.ptp(tail["x"]) < 1e-12 and np.ptp(tail["y"]) < 1e-12 and np.ptp(tail["theta"]) < 1e-12
