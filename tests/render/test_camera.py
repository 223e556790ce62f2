"""The camera model and how it is held."""

from __future__ import annotations

import numpy as np
import pytest

from curltrack.errors import ParameterError
from curltrack.render import Camera, CameraConfig, CameraPath
from curltrack.render.camera import base_rotation, rotation_matrix


def _camera(rng):
    tilt = rng.uniform(0, np.deg2rad(3), 2)
    R = rotation_matrix([*tilt, 0]) @ base_rotation(rng.uniform(0, 2 * np.pi))
    return Camera(rng.uniform(400, 900), 480 + rng.uniform(-20, 20), 270 + rng.uniform(-12, 12),
                  960, 540, R=R, C=np.r_[rng.uniform(-5, 5, 2), rng.uniform(1.5, 3.0)],
                  k1=rng.uniform(-0.2, 0.05), k2=rng.uniform(-0.02, 0.02))


@pytest.mark.parametrize("seed", range(5))
def test_undistort_inverts_distort(seed):
    rng = np.random.default_rng(seed)
    cam = _camera(rng)
    xy = rng.uniform(-0.9, 0.9, (200, 2))
    assert np.allclose(cam.undistort(cam.distort(xy)), xy, atol=1e-9)


@pytest.mark.parametrize("seed", range(5))
def test_plane_homography_matches_projection(seed):
    rng = np.random.default_rng(seed)
    cam = _camera(rng)
    z = rng.uniform(-0.01, 0.2)
    XY = cam.C[:2] + rng.uniform(-1, 1, (100, 2))
    p = np.c_[XY, np.ones(100)] @ cam.plane_homography(z).T
    und = p[:, :2] / p[:, 2:]
    xy = (und - [cam.cx, cam.cy]) / cam.f_px
    direct = cam.project(np.c_[XY, np.full(100, z)])
    assert np.allclose(cam.distort(xy) * cam.f_px + [cam.cx, cam.cy], direct, atol=1e-9)


def test_looking_down_conventions():
    """Image right = yaw direction, image up = 90 deg CCW from it; parallax pushes
    raised points away from the principal point."""
    cam = Camera(600.0, 479.5, 269.5, 960, 540, R=base_rotation(0.0), C=np.array([0, 0, 2.0]))
    u0, v0 = cam.project([[0, 0, 0]])[0]
    assert (u0, v0) == pytest.approx((479.5, 269.5))
    right = cam.project([[0.1, 0, 0]])[0]
    up = cam.project([[0, 0.1, 0]])[0]
    assert right[0] > u0 and right[1] == pytest.approx(v0)
    assert up[1] < v0 and up[0] == pytest.approx(u0)
    low, high = cam.project([[0.5, 0, 0], [0.5, 0, 0.114]])
    assert high[0] - u0 == pytest.approx((low[0] - u0) * 2.0 / (2.0 - 0.114))


def _path(cfg, rock_xy, duration=4.0, seed=0):
    return CameraPath(cfg.resolved(), 960, 540, rock_xy, 0.0, duration, np.pi / 2,
                      np.random.default_rng(seed))


def test_ladder_follows_with_lag_fixed_orientation():
    v = 1.5
    rock = lambda t: np.column_stack([0 * np.asarray(t), v * np.asarray(t)])  # noqa: E731
    for seed in range(3):
        path = _path(CameraConfig(motion="ladder"), rock, seed=seed)
        t = np.linspace(2.0, 4.0, 50)
        lag = (rock(t)[:, 1] - path.centre(t)[:, 1]) / v
        assert 0.1 < lag.mean() < 0.6  # behind the rock by about its time constant
        R = [path.rotation(tt) for tt in t]
        ang = [np.degrees(np.arccos(np.clip((np.trace(R[0].T @ r) - 1) / 2, -1, 1))) for r in R]
        assert max(ang) < 0.3  # orientation fixed up to a small wobble
        assert np.all(np.abs(path.centre(t)[:, 2] - 2.0) < 0.02)


def test_handheld_yaw_wanders_a_degree_or_two():
    still = lambda t: np.zeros((len(np.atleast_1d(t)), 2))  # noqa: E731
    spreads = []
    for seed in range(6):
        path = _path(CameraConfig(motion="handheld"), still, duration=20.0, seed=seed)
        yaw = path.yaw_deg(np.linspace(0, 20, 400))
        spreads.append(np.ptp(yaw))
        assert path.cfg.height_m == 1.6
    assert 1.0 < np.median(spreads) < 8.0


@pytest.mark.parametrize("field,value", [("motion", "drone"), ("height_m", 0.1),
                                         ("tilt_deg", 45.0), ("k1", 2.0), ("view_m", 30.0)])
def test_bad_camera_settings(field, value):
    with pytest.raises(ParameterError, match=field if field != "motion" else "motion"):
        CameraConfig(**{field: value}).resolved()
