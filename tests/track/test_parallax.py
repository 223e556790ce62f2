"""Parallax geometry against cameras with known height, tilt and nadir."""

import numpy as np
import pytest

from curltrack.calib.artificial import PinholeCamera
from curltrack.track.parallax import (camera_centre, correct_parallax, estimate_height,
                                      focal_for_height, similarity_fit)


@pytest.mark.parametrize("seed", range(5))
def test_rock_centre_from_apparent_markers(seed):
    rng = np.random.default_rng(seed)
    H, h = rng.uniform(1.5, 3.0), 0.114
    cam = PinholeCamera(f=rng.uniform(500, 1000), position=(*rng.uniform(-1, 1, 2), H),
                        yaw=rng.uniform(0, 6.3), tilt_x=np.radians(rng.uniform(-3, 3)),
                        tilt_y=np.radians(rng.uniform(-3, 3)))
    Hm = cam.undistorted_to_plane_h()
    pp = cam.K[:2, 2]
    f = focal_for_height(Hm, H, pp)
    assert f == pytest.approx(cam.f, rel=1e-5)
    C = camera_centre(Hm, f, pp)
    assert np.allclose(C, cam.position, atol=1e-5)
    layout = np.array([[0.08, 0.0], [-0.08, 0.0], [0.0, 0.06]])
    centre, angle = rng.uniform(-0.6, 0.6, 2), rng.uniform(-3, 3)
    R = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    true = centre + layout @ R.T
    apparent = cam.image_to_plane(cam.plane_to_image(true, z=h))
    c_app, phi, s, rms = similarity_fit(layout, apparent)
    assert s == pytest.approx(H / (H - h), rel=1e-6)
    assert np.angle(np.exp(1j * (phi - angle))) == pytest.approx(0, abs=1e-6)
    assert np.allclose(correct_parallax(c_app, C[:2], 1 / s), centre, atol=1e-6)
    # ignoring the tilt (nadir = the image centre's ice point) would be mm-wrong
    assert rms < 1e-9


def test_height_estimate_and_its_error_bar():
    rng = np.random.default_rng(0)
    h = 0.114
    z = []
    for _ in range(20):
        H = rng.uniform(1.5, 3.0)
        s_true = H / (H - h)
        scales = s_true * (1 + rng.normal(0, 0.004, 200))
        scales[:5] = 1.3  # a few wrong frames must not matter
        est = estimate_height(scales, h)
        assert abs(est.k - (H - h) / H) / ((H - h) / H) < 0.01
        z.append((est.height_m - H) / est.height_err_m)
    assert 0.5 < np.std(z) < 1.6  # the error bar means what it says
    assert estimate_height(np.ones(10), h) is None
