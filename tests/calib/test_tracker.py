"""GridTracker: per-frame homographies with a continuous cell index.

Ground truth: rendered videos (``curltrack.render``, the camera follows a fast rock,
handheld or on a ladder) and synthetic frames with an exactly known camera.
"""

import numpy as np
import pytest

from curltrack.calib import GridTracker, calibrate_frame
from curltrack.calib.artificial import PinholeCamera, draw_lattice
from curltrack.render import RenderConfig, render_video
from curltrack.render.motion import CameraConfig
from curltrack.rig import Marker, Rig

from calib.helpers import FrameMatch, align, short_shot, track_rendered

SETUPS = {
    # fast takeout (3 m/s: ~0.1 m per frame, more than half a 0.15 m cell), handheld
    "handheld_fast": dict(rig=Rig(), v0=3.0, seed=11, tol_m=0.7e-3,
                          camera=CameraConfig(motion="handheld", height_m=1.6, k1=-0.1)),
    # three thread colours, unequal 0.1 x 0.2 m cells, higher ladder, tilt 3 deg
    "ladder_3colour": dict(
        rig=Rig(spacing_x_m=0.1, spacing_y_m=0.2, grid_colors=("#d02020", "#2040d0", "#20a040"),
                markers=(Marker("#ffd000", 0.08, 0.0), Marker("#00c0ff", -0.08, 0.0))),
        v0=2.0, seed=12, tol_m=0.4e-3,
        camera=CameraConfig(motion="ladder", height_m=2.6, tilt_deg=3.0, k1=-0.05)),
}


@pytest.fixture(scope="session", params=sorted(SETUPS))
def rendered(request, tmp_path_factory):
    s = SETUPS[request.param]
    out = tmp_path_factory.mktemp(request.param)
    video = out / "v.mp4"
    truth = render_video(short_shot(v0=s["v0"], seconds=1.1), s["rig"], video,
                         config=RenderConfig(camera=s["camera"]), seed=s["seed"])
    return request.param, video, truth.data, s["rig"], s["tol_m"]


def test_rendered_video_homography_accuracy(rendered):
    name, video, truth, rig, tol = rendered
    est, ok, poses = track_rendered(video, truth, rig)
    assert ok.all(), [p.message for p in poses if not p.ok]
    # the lattice frame equals the truth frame up to quarter turns and an offset
    rms, err, _ = align(est, truth[["x", "y"]].to_numpy(), rig.spacing_x_m, rig.spacing_y_m,
                        free_offset=True)
    # ice position of the rock centre, whole clip (the budget of the grid in the ~1 mm
    # of the rock's position; heavy motion blur across one family costs a little)
    assert rms < tol, name
    assert np.abs(err).max() < 5 * tol, name  # never a jump by a cell (0.1-0.2 m)
    assert all(np.isfinite(p.sigma_px) for p in poses)


def test_rendered_video_lens_recovered(rendered):
    """k1 and the distortion centre of the renderer's camera, from the first frame."""
    name, video, truth, rig, _ = rendered
    from curltrack.video import read_frame

    cal = calibrate_frame(read_frame(video, 0), rig)
    meta = truth.attrs.get("render") or rendered_meta(video)
    k1_true = meta["camera"]["k1"] * (cal.K[0, 0] / meta["f_px"]) ** 2
    assert cal.dist[0] == pytest.approx(k1_true, rel=0.1), name
    # the distortion itself (k1 and k2 trade off a little): radial shift at the corners
    r = np.hypot(480, 270) / cal.K[0, 0]
    shift = cal.K[0, 0] * r * (cal.dist[0] * r ** 2 + cal.dist[1] * r ** 4)
    assert shift == pytest.approx(cal.K[0, 0] * r * k1_true * r ** 2, abs=0.5), name
    if abs(k1_true) > 0.15:  # (weak distortion barely defines its centre, nor needs it)
        assert np.hypot(cal.K[0, 2] - meta["cx_px"], cal.K[1, 2] - meta["cy_px"]) < 4.0


def rendered_meta(video):
    import json

    return json.loads(video.with_suffix(".render.json").read_text())


def _moving_cameras(n, step_m, yaw_rate, seed, jump_at=None, jump_m=0.0):
    rng = np.random.default_rng(seed)
    yaw0, f, h = rng.uniform(-np.pi, np.pi), rng.uniform(500, 700), rng.uniform(1.6, 2.8)
    cams = []
    for i in range(n):
        y = step_m * i + (jump_m if jump_at is not None and i >= jump_at else 0.0)
        cams.append(PinholeCamera(f=f, position=(0.01 * i, y, h), yaw=yaw0 + yaw_rate * i,
                                  tilt_x=0.02, k1=-0.08))
    return cams


def test_cell_index_survives_a_release_at_full_speed():
    """No velocity history on frame 1 and 0.1 m/frame (2/3 of a cell): colours decide."""
    rig = Rig()
    cams = _moving_cameras(5, 0.1, 0.004, seed=3)
    cal = calibrate_frame(draw_lattice(cams[0], seed=0), rig)
    tr = GridTracker(cal, rig)
    pts = np.array([[200.0, 150.0], [760.0, 400.0], [480.0, 270.0]])
    match = None
    for i, cam in enumerate(cams):
        pose = tr.update(draw_lattice(cam, seed=i), i)
        assert pose.ok, pose.message
        est, truth = pose.image_to_ice(pts), cam.image_to_plane(pts)
        match = match or FrameMatch(est, truth, 0.15, 0.15)
        assert match.error(est, truth) < 0.5e-3, i  # same absolute cell in every frame


@pytest.mark.parametrize("colours, jump_m", [
    (True, 0.09), (False, 0.06),
    pytest.param(True, 0.075, marks=pytest.mark.slow),
    pytest.param(False, 0.09, marks=pytest.mark.slow)])
def test_unexplained_jump_is_flagged_not_followed(colours, jump_m):
    """The view jumps by 0.4-0.6 cell more than the smooth motion predicts: no guess
    without colours; with them, the colour sequence tells which way it went."""
    rig = Rig() if colours else Rig(grid_colors=())
    cams = _moving_cameras(5, 0.03, 0.0, seed=4, jump_at=4, jump_m=jump_m)
    col = ((208, 32, 32), (32, 64, 208)) if colours else ((60, 60, 60),)
    cal = calibrate_frame(draw_lattice(cams[0], colors=col, seed=0), rig)
    tr = GridTracker(cal, rig)
    poses = [tr.update(draw_lattice(c, colors=col, seed=i), i) for i, c in enumerate(cams)]
    assert all(p.ok for p in poses[:4])
    last = poses[4]
    if colours:  # the colour sequence resolves it: the measured pose follows the camera
        p = np.array([[200.0, 150.0], [760.0, 400.0], [480.0, 270.0]])
        match = FrameMatch(poses[0].image_to_ice(p), cams[0].image_to_plane(p), 0.15, 0.15)
        assert last.ok, last.message
        assert match.error(last.image_to_ice(p), cams[4].image_to_plane(p)) < 0.5e-3
    else:
        assert not last.ok and "ambiguous" in last.message


def test_lost_frame_is_reported_and_tracking_recovers():
    rig = Rig()
    cams = _moving_cameras(6, 0.04, 0.002, seed=5)
    cal = calibrate_frame(draw_lattice(cams[0], seed=0), rig)
    tr = GridTracker(cal, rig)
    for i, cam in enumerate(cams):
        img = draw_lattice(cam, seed=i)
        if i == 3:
            img[:] = 128  # camera covered
        pose = tr.update(img, i)
        assert pose.ok == (i != 3), (i, pose.message)
        if i == 3:
            assert "not visible" in pose.message


def test_wrong_frame_size_is_a_clear_error():
    from curltrack.errors import TrackingError

    cal = calibrate_frame(draw_lattice(PinholeCamera(k1=-0.05)), Rig())
    with pytest.raises(TrackingError, match="frame 7: frame size"):
        GridTracker(cal, Rig()).update(np.zeros((100, 100, 3), np.uint8), 7)
