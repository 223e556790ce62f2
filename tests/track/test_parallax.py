"""Parallax geometry against cameras with known height, tilt and nadir."""

import numpy as np
import pytest

from curltrack.calib.artificial import PinholeCamera
from curltrack.track.parallax import (LAYOUT_SPAN_BIAS_PX, camera_centre, correct_parallax,
                                      estimate_height, focal_for_height, similarity_fit)


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


def test_a_bias_every_frame_shares_bounds_the_height_error_bar():
    """Frames whose layout scale shares one bias (the markers' centroids on a few px)
    do not measure the height better with their number: with ``floor_rel`` the error
    bar covers the shared bias (error/sigma std within 0.5-1.6 over random heights,
    biases and frame counts), without it the bar shrinks as 1/sqrt(n) and does not."""
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    h = 0.114
    z_with, z_without = [], []
    for _ in range(40):
        H = rng.uniform(1.4, 3.2)
        span_px = rng.uniform(25, 80)
        floor = LAYOUT_SPAN_BIAS_PX / span_px
        s_true = H / (H - h)
        bias = rng.normal(0, floor)                  # shared by every frame
        n = int(rng.integers(40, 300))
        scales = s_true * (1 + bias + rng.normal(0, 0.004, n))
        for floor_rel, z in ((floor, z_with), (0.0, z_without)):
            est = estimate_height(scales, h, floor_rel=floor_rel)
            z.append((est.height_m - H) / est.height_err_m)
    assert 0.5 < np.std(z_with) < 1.6, f"seed {seed}: {np.std(z_with):.2f}"
    assert np.std(z_without) > 2.0, f"seed {seed}: {np.std(z_without):.2f}"


@pytest.mark.parametrize("seed", range(4))
def test_camera_centre_follows_the_lattice_frame_for_a_sheared_view(seed):
    """A homography that is not quite a pinhole view (a rolling shutter's shear of a few
    1e-3 under a shaking camera) gives nearly the pinhole camera's nadir, and the same
    nadir moved with the lattice frame when the frame's origin is metres away (issue
    #19.6: decomposed about the lattice origin, the nadir moved by the shear times the
    camera's distance from it - 7.7 mm RMS on a rendered hand-held action clip)."""
    rng = np.random.default_rng(seed)
    H = rng.uniform(1.5, 3.0)
    cam = PinholeCamera(f=rng.uniform(500, 1000), position=(*rng.uniform(-0.5, 0.5, 2), H),
                        yaw=rng.uniform(0, 6.3), tilt_x=np.radians(rng.uniform(-3, 3)),
                        tilt_y=np.radians(rng.uniform(-3, 3)))
    pp = cam.K[:2, 2]
    shear = np.eye(3)
    shear[0, 1], shear[1, 0] = rng.uniform(-3e-3, 3e-3, 2)
    # image shear about the principal point, then undistorted px -> ice
    S = np.array([[1, 0, pp[0]], [0, 1, pp[1]], [0, 0, 1.0]]) @ shear @ np.array(
        [[1, 0, -pp[0]], [0, 1, -pp[1]], [0, 0, 1.0]])
    Hm = cam.undistorted_to_plane_h() @ S
    C = camera_centre(Hm, cam.f, pp)
    assert np.hypot(*(C[:2] - cam.position[:2])) < 2e-3 * H, f"seed {seed}: {C - cam.position}"
    far = rng.uniform(-5, 5, 2)  # the same ice, its frame's origin metres away
    T = np.array([[1, 0, far[0]], [0, 1, far[1]], [0, 0, 1.0]])
    Cf = camera_centre(T @ Hm, cam.f, pp)
    assert np.allclose(Cf[:2] - far, C[:2], atol=1e-9), f"seed {seed}: {Cf[:2] - far - C[:2]}"
    assert Cf[2] == pytest.approx(C[2], abs=1e-9)
    assert focal_for_height(T @ Hm, C[2], pp) == pytest.approx(cam.f, rel=1e-6)


def test_a_mirrored_marker_layout_is_recognised():
    """A mirrored video (filmed via a mirror, or flipped in an editor) of a rock with
    three or more markers: they are the rig layout's mirror image, and the error names
    that (it blamed the grid's threads: 'the markers measure 0.01x their rig layout').
    Two markers (or collinear ones) look alike mirrored."""
    from curltrack.rig import default_rig
    from curltrack.track.parallax import layout_scale_mismatch, mirrored_layout

    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    for _ in range(50):
        m = int(rng.integers(3, 6))
        r, a = rng.uniform(0.03, 0.12, m), rng.uniform(0, 2 * np.pi, m)
        L = np.c_[r * np.cos(a), r * np.sin(a)]
        if np.linalg.svd(L - L.mean(0), compute_uv=False)[-1] < 0.02:
            continue   # (nearly collinear: a mirror cannot be seen)
        phi, s = rng.uniform(0, 2 * np.pi), rng.uniform(1.02, 1.3)
        R = np.array([[np.cos(phi), -np.sin(phi)], [np.sin(phi), np.cos(phi)]])
        c = rng.uniform(-5, 5, 2)

        def seen(layout):
            return c + s * layout @ R.T + rng.normal(0, 0.001, layout.shape)

        assert not mirrored_layout(L, seen(L)), (seed, L)
        assert mirrored_layout(L, seen(L * [-1.0, 1.0])), (seed, L)
        assert not mirrored_layout(L[:2], seen(L[:2] * [-1.0, 1.0])), seed
    msg = layout_scale_mismatch(0.01, default_rig(), mirrored=1.0)
    assert "mirror image" in msg and "thread" not in msg
