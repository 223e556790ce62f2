"""The final-approach fit's batched grid search is the per-point chi-square it replaces."""

import numpy as np
import pytest

from curltrack.series.stops import _grid_cost, _reduced_residual


@pytest.mark.parametrize("quad, seed", [(True, 0), (False, 1), (True, 2)])
def test_grid_cost_is_the_reduced_chi_square(quad, seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(40, 260))
    tw = np.arange(n) / 30.0
    t_F, lam = rng.uniform(0.4, 0.8) * tw[-1], rng.uniform(1.3, 2.5)
    tau = np.maximum(t_F - tw, 0.0)
    Q = np.column_stack([20.0 - rng.uniform(0.2, 1.0) * tau ** lam,
                         1.5 + 0.05 * tau ** lam - 0.01 * tau ** 2])
    Q = (Q if quad else Q[:, :1]) + rng.normal(0, 1e-3, (n, 2 if quad else 1))
    lam_grid = np.linspace(1.05, 4.0, 24)
    # around the stop, and before the window (tau^lambda all or nearly all zero)
    for tF_grid in (np.arange(t_F - 0.2, t_F + 0.3, 1 / 60), np.arange(-0.1, 0.2, 1 / 60)):
        fast = _grid_cost(tF_grid, lam_grid, tw, Q, quad, 1e-3)
        plain = np.array([[float(r @ r) for r in
                           (_reduced_residual(a, b, tw, Q, quad, 1e-3) for b in lam_grid)]
                          for a in tF_grid])
        np.testing.assert_allclose(fast, plain, rtol=1e-5, atol=1e-6 * plain.max())
        assert np.argmin(fast) == np.argmin(plain)
