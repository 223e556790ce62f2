"""Strong wide-angle lenses (action cameras): the calibration converges for k1 down to
-0.35 with k2 and an off-centre principal point, or says where it cannot."""

import numpy as np
import pytest

from curltrack.calib import calibrate_frame
from curltrack.calib.artificial import PinholeCamera, draw_lattice
from curltrack.calib.lens import camera_matrix, distort, fold_radius, undistort
from curltrack.errors import TrackingError
from curltrack.rig import Rig

from calib.helpers import align


def _folds(f, k1, k2, width=960, height=540, offset=(0.0, 0.0)):
    """Whether the lens folds over before the farthest image corner."""
    rf = fold_radius(k1, k2)
    corner = (np.hypot(width / 2 + abs(offset[0]), height / 2 + abs(offset[1]))) / f
    return rf * (1 + rf * rf * (k1 + k2 * rf * rf)) <= corner


def action_camera(rng):
    """An action camera over the ice: the renderer's sweep ranges (f from a height of
    1.5-3 m and a view of 1.2-1.8 m on 540 rows; k1 -0.35..-0.12, k2 0.02-0.08;
    principal point up to 3 % off centre), drawn until the lens does not fold over
    inside the image (as the renderer requires)."""
    h = rng.uniform(1.5, 3.0)
    f = h * 540 / rng.uniform(1.2, 1.8)
    off = tuple(rng.uniform(-1, 1, 2) * 0.03 * np.array([960, 540]))
    while True:
        k1, k2 = rng.uniform(-0.35, -0.12), rng.uniform(0.02, 0.08)
        if not _folds(f, k1, k2, offset=off):
            break
    return PinholeCamera(f=f, position=(rng.uniform(-1, 1), rng.uniform(-1, 1), h),
                         yaw=rng.uniform(-np.pi, np.pi), tilt_x=np.radians(rng.uniform(-3, 3)),
                         tilt_y=np.radians(rng.uniform(-3, 3)), k1=k1, k2=k2,
                         principal_offset=off)


def test_strong_lenses_calibrate_to_a_tenth_of_a_pixel():
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    vp = np.column_stack([rng.uniform(0, 959, 600), rng.uniform(0, 539, 600)])
    for i in range(4):
        cam = action_camera(rng)
        s = float(rng.choice([0.1, 0.15, 0.2]))
        rig = Rig(spacing_x_m=s, spacing_y_m=s)
        img = draw_lattice(cam, s, s, noise=3.0, seed=i)
        k1_ref = cam.k1 * (960 / cam.f) ** 2
        what = f"seed {seed} camera {i}: f {cam.f:.0f} px, k1 {cam.k1:.3f}, k2 {cam.k2:.3f}"
        try:
            cal = calibrate_frame(img, rig)
        except TrackingError as exc:  # allowed, but only naming the lens
            assert "lens" in str(exc), (what, str(exc))
            continue
        inside = cal.in_checked_lens(vp)
        # a refusal of the periphery is for threads squeezed together: only for the
        # strongest lenses (k1 in the reference focal length below -0.45)
        assert inside.mean() > 0.6 or k1_ref < -0.45, (what, inside.mean())
        if cal.lens_radius_px is None:
            assert inside.all()
        rms, err, _ = align(cal.image_to_ice(vp[inside]), cam.image_to_plane(vp[inside]), s, s)
        m_per_px = cam.position[2] / cam.f
        # 0.1 px RMS and 0.4 px at worst over the view, as for mild lenses (test_grid)
        assert rms < 0.1 * m_per_px, (what, rms / m_per_px)
        assert np.abs(err).max() < 0.4 * m_per_px, (what, np.abs(err).max() / m_per_px)
        # the checked corners of the image (where the distortion is largest) on the ice
        corner = np.array([[0.0, 0.0], [959.0, 539.0], [0.0, 539.0], [959.0, 0.0]])
        corner = corner[cal.in_checked_lens(corner)]
        if len(corner):
            d = align(cal.image_to_ice(corner), cam.image_to_plane(corner), s, s)[0]
            assert d < 0.5 * m_per_px, (what, d / m_per_px)


@pytest.mark.parametrize("k1,k2", [(-0.9, 0.4), (-0.35, 0.05), (-1.2, 0.6), (0.1, 0.0)])
def test_undistort_inverts_strong_lenses(k1, k2):
    K = camera_matrix(960, 540)
    K[:2, 2] += (20.0, -12.0)
    rf = fold_radius(k1, k2)
    # undistorted points up to the fold (or beyond the image when there is none)
    r = np.linspace(0.0, min(0.999 * rf, 1.5), 300)
    a = np.linspace(0, 2 * np.pi, 300)
    q = np.column_stack([r * np.cos(a), r * np.sin(a)])
    p = K[:2, 2] + K[0, 0] * q
    d = distort(p, K, (k1, k2))
    np.testing.assert_allclose(undistort(d, K, (k1, k2)), p, atol=1e-4)


def test_fold_radius():
    assert fold_radius(-0.3, 0.0) == pytest.approx(np.sqrt(1 / 0.9))
    assert fold_radius(0.1, 0.0) == 4.0  # never folds (up to the limit)
    # monotonic at the root only: 1 + 3 k1 u + 5 k2 u^2 with a double root
    k1 = -1.0
    k2 = (3 * k1) ** 2 / 20
    assert fold_radius(k1, k2) == pytest.approx(np.sqrt(-3 * k1 / (10 * k2)), rel=1e-4)
