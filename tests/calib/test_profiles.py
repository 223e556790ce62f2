"""Thread profiles, the per-frame fit and the motion prediction, against known lattices.

Ground truth: synthetic frames of a lattice under a known pinhole camera
(:func:`curltrack.calib.artificial.draw_lattice`) and the plain forms of the fast paths.
"""

import numpy as np
import pytest

from curltrack.calib import GridTracker, calibrate_frame
from curltrack.calib.artificial import PinholeCamera, draw_lattice
from curltrack.calib.grid import cells_from_metric
from curltrack.calib.lattice import fit_points, periods_px
from curltrack.calib.lens import apply_h
from curltrack.calib.profiles import sample_threads
from curltrack.rig import Rig


@pytest.fixture(scope="module")
def frame_and_calibration():
    cam = PinholeCamera(f=760, position=(0.03, -0.02, 2.0), yaw=np.radians(12), k1=-0.12,
                        tilt_x=np.radians(1.5))
    rig = Rig()
    img = draw_lattice(cam, rig.spacing_x_m, rig.spacing_y_m, seed=3, noise=3.0)
    return img, calibrate_frame(img, rig), rig


def _px_error(Hc_a, Hc_b, f):
    """Largest disagreement (px) of two lattice homographies over the image."""
    q = np.stack(np.meshgrid(np.linspace(-0.45, 0.45, 7), np.linspace(-0.25, 0.25, 5)),
                 -1).reshape(-1, 2)
    return float((np.abs(apply_h(Hc_a, q) - apply_h(Hc_b, q)) * periods_px(Hc_b, f)).max())


@pytest.mark.parametrize("budget", [None, 640, 300])
def test_profile_budget_keeps_the_homography(frame_and_calibration, budget):
    """From a prediction 0.06 cell (~3.4 px) off, the threads found on a budget of
    profiles give the calibrated homography back to better than 0.1 px everywhere in
    the image (the calibration itself is good to a few hundredths), with about that
    many profiles (one to two per point: a thread's end stretches are kept, short or
    not)."""
    img, cal, rig = frame_and_calibration
    Hc = cells_from_metric(cal.H, cal.K, rig.spacing_x_m, rig.spacing_y_m)
    start = np.array([[1, 0, 0.06], [0, 1, -0.06], [0, 0, 1.0]]) @ Hc
    obs = sample_threads(img, start, cal.K, cal.dist, cal.colour_model, (7.0, 7.0),
                         step_px=18.0, gap_px=(5.0, 5.0), max_profiles=budget)
    assert min(obs.found) > 0.9
    if budget is not None:
        assert 0.3 * budget < 2 * obs.n_profiles and obs.n_profiles < 0.65 * budget
    fit, info = fit_points(obs.xy, obs.w, obs.fam, obs.idx, start, cal.K, cal.dist, q=obs.q)
    assert _px_error(fit, Hc, cal.K[0, 0]) < 0.1
    # the undistorted points handed to the fit are the observed points, undistorted (to
    # first order in the offset from the predicted thread: 0.01 px at k1 = -0.12)
    from curltrack.calib.lens import undistort

    q = (undistort(obs.xy, cal.K, cal.dist) - cal.K[:2, 2]) / cal.K[0, 0]
    np.testing.assert_allclose(obs.q, q, rtol=0, atol=0.01 / cal.K[0, 0])


def test_anchor_moves_the_prediction_onto_the_markers(frame_and_calibration):
    """The prediction is moved so that the anchor's pixels land on their predicted ice
    positions; a move beyond the settings' anchor_max_cells is ignored (a wrong anchor
    must not set the cell index)."""
    _, cal, rig = frame_and_calibration
    tracker = GridTracker(cal, rig)
    from curltrack.calib.lens import undistort

    px = undistort(np.array([[430.0, 250.0], [520.0, 290.0]]), cal.K, cal.dist)
    seen = apply_h(cal.H, px)
    shift = np.array([0.012, -0.02])  # m: a shaking camera, ~0.1 cell
    moved = tracker._anchored(cal.H, px, seen + shift)
    np.testing.assert_allclose(apply_h(moved, px), seen + shift, atol=1e-9)
    far = seen + (rig.tracking.anchor_max_cells + 0.1) * rig.spacing_x_m * np.array([1.0, 0.0])
    np.testing.assert_array_equal(tracker._anchored(cal.H, px, far), cal.H)


def test_apply_h_opencv_path_is_the_formula():
    """From 32 points on apply_h goes through OpenCV; it must give the plain formula's
    values, and its infinities on the horizon (w = 0) rather than OpenCV's zeros."""
    rng = np.random.default_rng(5)
    H = np.array([[1.1, 0.2, 3.0], [-0.1, 0.9, -2.0], [2e-3, -1e-3, 1.0]])
    p = rng.uniform(-500, 900, (200, 2))
    w = H[2, 0] * p[:, 0] + H[2, 1] * p[:, 1] + H[2, 2]
    plain = np.column_stack([(H[0, 0] * p[:, 0] + H[0, 1] * p[:, 1] + H[0, 2]) / w,
                             (H[1, 0] * p[:, 0] + H[1, 1] * p[:, 1] + H[1, 2]) / w])
    np.testing.assert_allclose(apply_h(H, p), plain, rtol=1e-12, atol=1e-9)
    Hh = np.array([[1.0, 0, 0], [0, 1.0, 0], [1.0, 0, 0]])  # w = x: the line x = 0
    ph = np.column_stack([np.r_[0.0, rng.uniform(1, 5, 40)], rng.uniform(1, 5, 41)])
    with np.errstate(divide="ignore", invalid="ignore"):
        out = apply_h(Hh, ph)
    assert not np.isfinite(out[0]).any()
    assert np.isfinite(out[1:]).all()


def test_degenerate_prediction_samples_nothing(frame_and_calibration):
    """A diverged fit whose horizon crosses the frame (seen after a lost grid: a coarse
    snap onto a few wrong points) is not sampled - it maps the frame onto ~10^5 threads."""
    img, cal, rig = frame_and_calibration
    Hc = cells_from_metric(cal.H, cal.K, rig.spacing_x_m, rig.spacing_y_m)
    bad = Hc.copy()
    bad[2] = (-1.55 * Hc[2, 2], -2.08 * Hc[2, 2], Hc[2, 2])  # w = 0 inside the frame
    assert sample_threads(img, bad, cal.K, cal.dist, cal.colour_model, (5.0, 5.0),
                          max_profiles=640) is None
    steep = Hc.copy()
    steep[2] = (1.8 * Hc[2, 2], 0.0, Hc[2, 2])  # w from ~0.2 to ~1.8: near the horizon
    assert sample_threads(img, steep, cal.K, cal.dist, cal.colour_model, (5.0, 5.0)) is None


def test_more_profiles_than_one_remap_takes(frame_and_calibration):
    """Over 32767 profiles (a dense coarse search at high resolution) are sampled in
    pieces (one OpenCV remap takes fewer), and give the homography back."""
    img, cal, rig = frame_and_calibration
    Hc = cells_from_metric(cal.H, cal.K, rig.spacing_x_m, rig.spacing_y_m)
    args = (img, Hc, cal.K, cal.dist, cal.colour_model, (5.0, 5.0))
    dense = sample_threads(*args, step_px=0.4, seg_px=0.4, gap_px=(5.0, 5.0))
    assert dense.n_profiles > 32767
    assert min(dense.found) > 0.9
    fit, _ = fit_points(dense.xy, dense.w, dense.fam, dense.idx, Hc, cal.K, cal.dist,
                        q=dense.q)
    assert _px_error(fit, Hc, cal.K[0, 0]) < 0.1


def test_profiles_a_cell_apart_sample_both_families_wherever_the_frame_edge_falls(
        frame_and_calibration):
    """Profiles one cell apart along the threads (the coarse snap's 40 px on 40 px cells)
    all sit at one phase between the crossing threads.  Counted from the frame's edge,
    that phase put every profile of a family on a crossing for some views - nothing
    sampled, the grid "not followed" until the camera had moved (issue 19: the first 16
    fields of an interlaced clip).  The frame's edge is moved here over a whole cell
    (the image and its principal point shifted together: the lattice in normalised
    coordinates unchanged): both families are sampled and found every time."""
    import cv2

    img, cal, rig = frame_and_calibration
    Hc = cells_from_metric(cal.H, cal.K, rig.spacing_x_m, rig.spacing_y_m)
    period = np.array(periods_px(Hc, cal.K[0, 0]))
    h, w = img.shape[:2]
    for frac in np.linspace(0.0, 1.0, 16, endpoint=False):
        t = frac * period  # px
        moved = cv2.warpAffine(img, np.float32([[1, 0, t[0]], [0, 1, t[1]]]), (w, h),
                               flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
        K = cal.K.copy()
        K[:2, 2] += t
        obs = sample_threads(moved, Hc, K, cal.dist, cal.colour_model, 0.45 * period,
                             step_px=float(period.mean()), gap_px=(5.0, 5.0))
        assert obs is not None, frac
        assert min(np.bincount(obs.fam, minlength=2)) >= 6, frac
        assert min(obs.found) > 0.9, (frac, obs.found)


def test_a_budget_of_profiles_measures_the_threads_direction():
    """The tracker samples a budget of ~640 profiles.  Chosen by stretch index, the same
    for every thread, the selection aliased with the gaps left at the crossing threads
    (22 px cells, 18 px steps, 40 px stretches: the random scale test's seed 102) and
    kept one band across a whole family: the threads' direction was not measured, the
    tracked lattice sheared a little more each frame, and the rock's travel was read
    11 % long (rows 37 mm off at 50 sigma, ok = 1).  On random views - cells of 10-60 px,
    any yaw, three frame sizes - each family's points must spread along its threads as
    the view does, and a fit from a slightly sheared prediction must find the lattice."""
    from curltrack.calib.response import ColourModel

    seed = np.random.SeedSequence().entropy
    rng = np.random.default_rng(seed)
    colour_blind = ColourModel(ice_bgr=np.zeros(3), directions=None)
    for case in range(8):
        w, h = [(640, 360), (960, 540), (480, 270)][rng.integers(3)]
        f, cell_px = rng.uniform(0.8, 1.4) * w, rng.uniform(10.0, 60.0)
        spacing = cell_px * 2.4 / f
        cam = PinholeCamera(width=w, height=h, f=f, position=(*rng.uniform(-0.1, 0.1, 2), 2.4),
                            yaw=rng.uniform(0, 2 * np.pi), k1=rng.uniform(-0.1, 0.0),
                            tilt_x=np.radians(rng.uniform(-2, 2)))
        img = draw_lattice(cam, spacing, spacing, seed=int(rng.integers(2**31)), noise=2.0)
        K, dist = cam.K, cam.dist
        Hc = cells_from_metric(cam.undistorted_to_plane_h(), K, spacing, spacing)
        period = min(periods_px(Hc, f))
        obs = sample_threads(img, Hc, K, dist, colour_blind, (min(5.0, 0.4 * period),) * 2,
                             step_px=max(18.0, period / 2.5), gap_px=(5.0, 5.0),
                             max_profiles=640)
        label = f"seed {seed} case {case}: {w}x{h}, {cell_px:.1f} px cells, yaw {cam.yaw:.2f}"
        assert obs is not None and min(obs.found) > 0.9, label
        # the view's spread along each family's threads, from its pixels
        grid = np.stack(np.meshgrid(np.linspace(0, w - 1, 24), np.linspace(0, h - 1, 14)),
                        -1).reshape(-1, 2)
        from curltrack.calib.lens import undistort

        view = apply_h(Hc, (undistort(grid, K, dist) - K[:2, 2]) / f)
        seen = apply_h(Hc, obs.q)
        for fam in (0, 1):
            spread = np.std(seen[obs.fam == fam, 1 - fam])
            assert spread > 0.5 * np.std(view[:, 1 - fam]), (label, fam, spread)
        sheared = np.array([[1.0, 0.005, 0], [0, 1.0, -0.005], [0, 0, 1]]) @ Hc
        obs = sample_threads(img, sheared, K, dist, colour_blind,
                             (min(5.0, 0.4 * period),) * 2, step_px=max(18.0, period / 2.5),
                             gap_px=(5.0, 5.0), max_profiles=640)
        fit, _ = fit_points(obs.xy, obs.w, obs.fam, obs.idx, sheared, K, dist, q=obs.q)
        assert _px_error(fit, Hc, f) < 0.15, (label, _px_error(fit, Hc, f))


def test_threads_measured_in_one_band_leave_the_lattice_free_in_its_sigma(
        frame_and_calibration):
    """When one family's points all lie in one band across its threads (what the
    aliased profile budget did), the threads' direction is not measured: the fit's
    covariance must say so away from the band - the tracker refuses such frames
    (max_grid_sigma_cells) - while the same points spread along the threads fix it to
    a few thousandths of a cell."""
    from curltrack.calib.lattice import position_sigma_at

    img, cal, rig = frame_and_calibration
    Hc = cells_from_metric(cal.H, cal.K, rig.spacing_x_m, rig.spacing_y_m)
    obs = sample_threads(img, Hc, cal.K, cal.dist, cal.colour_model, (7.0, 7.0),
                         step_px=18.0, gap_px=(5.0, 5.0))
    ab = apply_h(Hc, obs.q)
    f = cal.K[0, 0]
    band = (obs.fam == 1) | (np.abs(ab[:, 1] - np.median(ab[obs.fam == 0, 1])) < 0.3)
    off_band = np.array([[0.0, 0.15], [0.2, -0.15]])  # normalised image points
    sig = {}
    for name, sel in (("spread", np.ones(len(obs.fam), bool)), ("band", band)):
        _, info = fit_points(obs.xy[sel], obs.w[sel], obs.fam[sel], obs.idx[sel], Hc,
                             cal.K, cal.dist, q=obs.q[sel])
        px = max(position_sigma_at(Hc, info["cov"], q, f)[0] for q in off_band)
        sig[name] = px / min(periods_px(Hc, f))  # cells
    assert sig["spread"] < 0.01 and sig["band"] > 0.05, sig
