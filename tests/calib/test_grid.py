"""calibrate_frame against synthetic frames with an exactly known camera."""

import numpy as np
import pytest

from curltrack.calib import Calibration, calibrate_frame
from curltrack.calib.artificial import PinholeCamera, draw_lattice
from curltrack.errors import TrackingError
from curltrack.rig import Rig

from calib.helpers import align


def random_camera(rng):
    """A camera drawn from the range the product must handle."""
    h = rng.uniform(1.5, 3.0)
    return PinholeCamera(  # >= 200 px per metre: threads 0.1 m apart are >= 20 px apart
        f=rng.uniform(max(450, 200 * h), 800), position=(rng.uniform(-1, 1),
                                                         rng.uniform(-1, 1), h),
        yaw=rng.uniform(-np.pi, np.pi), tilt_x=np.radians(rng.uniform(-3, 3)),
        tilt_y=np.radians(rng.uniform(-3, 3)), k1=rng.uniform(-0.2, 0.02),
        principal_offset=tuple(rng.uniform(-1, 1, 2) * (24, 13)))


@pytest.mark.parametrize("seed", range(3))
def test_homography_and_distortion_recovered(seed, view_points):
    rng = np.random.default_rng(100 + seed)
    cam = random_camera(rng)
    s = float(rng.uniform(0.1, 0.3))
    rig = Rig(spacing_x_m=s, spacing_y_m=s)
    img = draw_lattice(cam, s, s, noise=3.0, seed=seed)
    cal = calibrate_frame(img, rig)
    rms, err, _ = align(cal.image_to_ice(view_points), cam.image_to_plane(view_points), s, s)
    # ~0.1-0.2 px over the whole view is needed for ~1 mm rock positions
    m_per_px = cam.position[2] / cam.f
    assert rms < 0.1 * m_per_px, (rms, m_per_px)
    assert np.abs(err).max() < 0.4 * m_per_px
    k1_true = cam.k1 * (cal.K[0, 0] / cam.f) ** 2  # same mapping, our reference f
    assert abs(cal.dist[0] - k1_true) < 0.05 * max(abs(k1_true), 0.05)
    # the distortion itself (k1 and k2 trade off a little): radial shift at the corners
    r = np.hypot(480, 270) / cal.K[0, 0]
    shift = cal.K[0, 0] * r * (cal.dist[0] * r ** 2 + cal.dist[1] * r ** 4)
    assert shift == pytest.approx(cal.K[0, 0] * r ** 3 * k1_true, abs=0.3)
    if abs(cam.k1) > 0.08:  # the distortion centre is only defined by real distortion
        assert np.hypot(*(cal.K[:2, 2] - cam.K[:2, 2])) < 4.0
    assert cal.colors_resolved
    # the origin crossing's threads have the first colour: the truth origin is a crossing
    # of colour-0 threads, so the offset is a whole number of *colour periods*
    est = cal.image_to_ice(view_points)
    _, _, k = align(est, cam.image_to_plane(view_points), 2 * s, 2 * s)


def test_axes_right_handed_and_y_up(rig):
    cam = PinholeCamera(f=600, position=(0.05, 0.02, 2.0), yaw=np.radians(20), k1=-0.05)
    cal = calibrate_frame(draw_lattice(cam), rig)
    c = cal.K[:2, 2]
    o, right, up = cal.image_to_ice(np.array([c, c + (50, 0), c - (0, 50)]))
    ex, ey = right - o, up - o
    assert ex[0] * ey[1] - ex[1] * ey[0] > 0  # image right x image up = +z (up)
    assert ey[1] > abs(ey[0])  # +y is the axis closest to the image's up


def test_unequal_spacings_pick_the_right_axes():
    rig = Rig(spacing_x_m=0.1, spacing_y_m=0.2)
    cam = PinholeCamera(f=600, position=(0.0, 0.0, 2.0), yaw=np.radians(100), k1=-0.05)
    img = draw_lattice(cam, 0.1, 0.2)
    cal = calibrate_frame(img, rig)
    pts = np.array([[300.0, 200.0], [700.0, 400.0], [480, 270], [100, 500]])
    rms, _, _ = align(cal.image_to_ice(pts), cam.image_to_plane(pts), 0.1, 0.2)
    assert rms < 0.5e-3


def test_colour_agnostic_when_rig_has_no_colours():
    rig = Rig(grid_colors=())
    cam = PinholeCamera(f=650, position=(0.0, 0.0, 2.2), yaw=0.4, k1=-0.1)
    cal = calibrate_frame(draw_lattice(cam, colors=((60, 60, 60),)), rig)
    pts = np.array([[100.0, 100.0], [800.0, 450.0], [480, 270]])
    rms, _, _ = align(cal.image_to_ice(pts), cam.image_to_plane(pts), 0.15, 0.15)
    assert rms < 0.5e-3 and not cal.colors_resolved


def test_round_trip_dict(rig):
    cal = calibrate_frame(draw_lattice(PinholeCamera(k1=-0.05)), rig)
    back = Calibration.from_dict(cal.to_dict())
    p = np.array([[10.0, 20.0], [500.0, 300.0]])
    np.testing.assert_allclose(back.image_to_ice(p), cal.image_to_ice(p))
    np.testing.assert_allclose(back.ice_to_image(back.image_to_ice(p)), p, atol=1e-6)


@pytest.mark.parametrize("kind", ["blank", "noise", "stripes"])
def test_no_grid_is_a_clear_error(kind, rig):
    rng = np.random.default_rng(0)
    img = np.full((540, 960, 3), 220, np.uint8)
    if kind == "noise":
        img = rng.integers(0, 255, img.shape).astype(np.uint8)
    elif kind == "stripes":  # one family only
        img[:, ::40] = (40, 40, 200)
    with pytest.raises(TrackingError, match="no grid found"):
        calibrate_frame(img, rig)
