"""The per-frame fast paths give the answers of the plain forms they replace."""

import numpy as np
import pytest

from curltrack.calib import lattice
from curltrack.calib._stats import median
from curltrack.calib.lens import apply_h, camera_matrix, distort


@pytest.mark.parametrize("seed", range(5))
def test_median_is_numpys(seed):
    rng = np.random.default_rng(seed)
    shape = tuple(rng.integers(1, 40, rng.integers(1, 4)))
    a = rng.normal(size=shape).astype(rng.choice([np.float32, np.float64]))
    axis = None if rng.random() < 0.3 else int(rng.integers(0, a.ndim))
    np.testing.assert_allclose(median(a, axis=axis), np.median(a, axis=axis), rtol=1e-6)


@pytest.mark.parametrize("seed", range(4))
def test_lattice_jacobian_matches_finite_differences(seed):
    """Homography and lens columns of the calibration fit, against central differences."""
    rng = np.random.default_rng(seed)
    w, h = [(960, 540), (1920, 1080), (640, 480), (1280, 720)][seed]
    K = camera_matrix(w, h)
    lens = np.array([rng.uniform(-0.3, 0.1), rng.uniform(-0.05, 0.05),
                     K[0, 2] + rng.uniform(-20, 20), K[1, 2] + rng.uniform(-20, 20)])
    xs = rng.uniform([0, 0], [w - 1, h - 1], (300, 2))
    Hc = np.array([[rng.uniform(4, 9), rng.uniform(-.5, .5), rng.uniform(-1, 1)],
                   [rng.uniform(-.5, .5), rng.uniform(4, 9), rng.uniform(-1, 1)],
                   [rng.uniform(-.05, .05), rng.uniform(-.05, .05), 1.0]])
    q = lattice._normalised(xs, K, lens)
    fa = rng.random(len(xs)) < 0.5
    ab = apply_h(Hc, q)
    ia, ib = np.round(ab[:, 0]), np.round(ab[:, 1])
    pa, pb = lattice.periods_px(Hc, K[0, 0])

    def rows(Hc, lens, free=(0, 1, 2, 3)):
        q = lattice._normalised(xs, K, lens)
        return lattice._rows(Hc, q, xs, apply_h(Hc, q), fa, ~fa, ia, ib, pa, pb, K, lens,
                             free)

    r, J, order = rows(Hc, lens)
    np.testing.assert_array_equal(order, np.r_[np.flatnonzero(fa), np.flatnonzero(~fa)])
    for j in range(12):  # h0..h7 (Hc[2, 2] = 1 fixed), then k1, k2, cx, cy
        e = [1e-6] * 10 + [1e-3] * 2
        Hp, Hm, lp, lm = Hc.copy(), Hc.copy(), lens.copy(), lens.copy()
        if j < 8:
            Hp.flat[j] += e[j]
            Hm.flat[j] -= e[j]
        else:
            lp[j - 8] += e[j]
            lm[j - 8] -= e[j]
        num = (rows(Hp, lp, ())[0] - rows(Hm, lm, ())[0]) / (2 * e[j])
        np.testing.assert_allclose(J[:, j], num, atol=1e-6 * np.abs(num).max())


@pytest.mark.parametrize("seed", range(4))
def test_fit_points_recovers_the_lattice(seed):
    """Thread points of a known lattice (0.05 px noise), a start 0.1 cell off: the fit
    lands on the true homography (to ~0.01 px over the image)."""
    rng = np.random.default_rng(seed)
    K = camera_matrix(960, 540)
    dist = (rng.uniform(-0.2, 0.0), 0.0)
    Hc = np.array([[rng.uniform(5, 8), rng.uniform(-.3, .3), rng.uniform(-.5, .5)],
                   [rng.uniform(-.3, .3), rng.uniform(5, 8), rng.uniform(-.5, .5)],
                   [rng.uniform(-.02, .02), rng.uniform(-.02, .02), 1.0]])
    n = 600
    fam = rng.integers(0, 2, n)
    ab = rng.uniform(-2.5, 2.5, (n, 2))
    idx = np.round(ab[np.arange(n), fam]).astype(int)
    ab[np.arange(n), fam] = idx
    und = K[:2, 2] + K[0, 0] * apply_h(np.linalg.inv(Hc), ab)
    xy = distort(und, K, dist) + rng.normal(0, 0.05, (n, 2))
    start = np.array([[1, 0, 0.1], [0, 1, -0.1], [0, 0, 1.0]]) @ Hc
    fit, info = lattice.fit_points(xy, np.ones(n), fam, idx, start, K, dist)
    grid = (np.stack(np.meshgrid(np.linspace(-0.3, 0.3, 5), np.linspace(-0.2, 0.2, 5)), -1)
            .reshape(-1, 2))
    err_cells = np.abs(apply_h(fit, grid) - apply_h(Hc, grid))
    err_px = err_cells * np.array(lattice.periods_px(Hc, K[0, 0]))
    assert err_px.max() < 0.03
    assert 0.02 < info["rms_px"] < 0.1  # the 0.05 px per axis noise, projected


def test_position_sigma_at_matches_the_scatter_off_centre():
    """One family's points all near the middle of the view (threads averaged whole under
    motion blur): the lattice's error at a point 0.15 f off the centre is many times the
    centre's sigma_px, and position_sigma_at predicts it (Monte Carlo over 200 fits)."""
    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    K = camera_matrix(960, 540)
    dist = (0.0, 0.0)
    Hc = np.array([[6.0, 0.1, 0.2], [-0.1, 6.0, -0.3], [0.01, -0.01, 1.0]])
    # family A: 17 threads, 2 points each across the view; family B: 9 threads, one
    # point each near x = 0
    ia = np.repeat(np.arange(-8, 9), 2)
    ab_a = np.column_stack([ia, np.tile([-1.0, 1.0], 17)])
    ib = np.arange(-4, 5)
    ab_b = np.column_stack([rng.uniform(-0.2, 0.2, 9), ib])
    ab = np.vstack([ab_a, ab_b]).astype(float)
    fam = np.r_[np.zeros(len(ia), int), np.ones(9, int)]
    idx = np.r_[ia, ib]
    und = K[:2, 2] + K[0, 0] * apply_h(np.linalg.inv(Hc), ab)
    q_off = np.array([[0.15, 0.02]])
    err, pred, centre = [], [], []
    for _ in range(200):
        xy = und + rng.normal(0, 0.1, und.shape)
        fit, info = lattice.fit_points(xy, np.ones(len(xy)), fam, idx, Hc, K, dist)
        e_cells = apply_h(fit, q_off)[0] - apply_h(Hc, q_off)[0]
        err.append(np.hypot(*(e_cells * lattice.periods_px(Hc, K[0, 0]))))
        pred.append(lattice.position_sigma_at(fit, info["cov"], q_off, K[0, 0])[0])
        centre.append(info["sigma_px"])
        np.testing.assert_allclose(
            lattice.position_sigma_at(fit, info["cov"], [[0.0, 0.0]], K[0, 0])[0],
            info["sigma_px"], rtol=1e-6)
    rms = float(np.sqrt(np.mean(np.square(err))))
    assert rms > 3 * np.median(centre), f"seed {seed}"
    assert 0.7 < rms / np.median(pred) < 1.4, f"seed {seed}: {rms} vs {np.median(pred)}"


def test_the_threads_covariance_holds_the_error_their_shared_misfit_makes():
    """Each thread's points share its own misfit of the model (a lens's residual, a
    thread laid not quite straight), which the independent points' covariance counts as
    many looks: at a point beyond the threads' coverage (a hand-held camera lagging a
    fast rock) the lattice's error is several times what it says, and the per-thread
    covariance (``cov_threads``, cluster-robust by thread) predicts it (Monte Carlo over
    200 fits: error / sigma 2.0-3.0 independent, 0.93-1.06 by thread over 8 seeds;
    test_wrong_cell seed 3543473112: a row 10 mm off at 3.6 sigma)."""
    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    K = camera_matrix(960, 540)
    Hc = np.array([[6.0, 0.1, 0.2], [-0.1, 6.0, -0.3], [0.01, -0.01, 1.0]])
    per = int(rng.integers(10, 30))                  # points along each thread
    lines = np.arange(-6, 7)                         # 13 threads per family, 26 in all
    fam = np.repeat([0, 1], lines.size * per)
    idx = np.tile(np.repeat(lines, per), 2)
    along = rng.uniform(-1.2, 1.2, fam.size)         # the middle of the view only
    ab = np.where(fam[:, None] == 0, np.column_stack([idx, along]),
                  np.column_stack([along, idx])).astype(float)
    und = K[:2, 2] + K[0, 0] * apply_h(np.linalg.inv(Hc), ab)
    normal = np.where(fam[:, None] == 0, [1.0, 0.0], [0.0, 1.0])
    q_off = np.array([[rng.uniform(0.3, 0.4), rng.uniform(-0.2, 0.2)]])
    shared, own = rng.uniform(0.1, 0.3), 0.05          # px: per thread, per point
    err, indep, threads = [], [], []
    for _ in range(200):
        off = rng.normal(0, shared, 2 * lines.size)[(fam * lines.size + idx - lines[0])]
        xy = und + normal * (off + rng.normal(0, own, fam.size))[:, None]
        fit, info = lattice.fit_points(xy, np.ones(fam.size), fam, idx, Hc, K, (0.0, 0.0))
        e_cells = apply_h(fit, q_off)[0] - apply_h(Hc, q_off)[0]
        err.append(np.hypot(*(e_cells * lattice.periods_px(Hc, K[0, 0]))))
        indep.append(lattice.position_sigma_at(fit, info["cov"], q_off, K[0, 0])[0])
        threads.append(lattice.position_sigma_at(fit, info["cov_threads"], q_off, K[0, 0])[0])
    rms = float(np.sqrt(np.mean(np.square(err))))
    what = f"seed {seed}: {per} points per thread, error RMS {rms:.3f} px"
    # (the premise: the independent points' sigma is well under the error - 1.7x at the
    # fewest points per thread and the smallest shared misfit drawn, CI seed 163644630)
    assert rms > 1.5 * np.median(indep), f"{what}, independent sigma {np.median(indep):.3f}"
    assert 0.75 < rms / np.median(threads) < 1.3, f"{what}, by thread {np.median(threads):.3f}"
    # too few threads for an 8 x 8 sandwich: none
    keep = np.isin(idx, [-1, 0, 1])
    _, info = lattice.fit_points(xy[keep], np.ones(keep.sum()), fam[keep], idx[keep], Hc, K,
                                 (0.0, 0.0))
    assert info["cov_threads"] is None
