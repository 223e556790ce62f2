"""The paper's closed forms: against numerical integration and the paper's own numbers."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from curltrack.physics import closed_form as cf
from curltrack.rig import G

R, r = 0.14, 0.0625


@pytest.mark.parametrize("phi", [-0.82, -0.707, -0.19, 0.0, 0.3])
def test_pure_rotation_matches_equation_of_motion(phi):
    """I dω/dt = -r α (rω)^φ M g with I = M R²/2, integrated numerically."""
    alpha, omega0 = 0.0094, 6.0
    t_F = cf.stop_time_rotation(omega0, phi, alpha, R, r)

    def rhs(t, s):
        w = max(s[1], 0.0)
        return [w, -2 * r * alpha * (r * w) ** phi * G / R**2 if w > 0 else 0.0]

    t = np.linspace(0, 0.999 * t_F, 400)
    sol = solve_ivp(rhs, (0, t[-1]), [0.0, omega0], t_eval=t, rtol=1e-12, atol=1e-14,
                    method="DOP853")
    lam = cf.lambda_from_phi(phi)
    theta_F = (1 - phi) / (2 - phi) * omega0 * t_F
    closed = cf.decel_position(t, theta_F, lam, t_F)
    np.testing.assert_allclose(sol.y[0][1:], closed[1:], rtol=1e-6)
    np.testing.assert_allclose(cf.initial_rate(theta_F, lam, t_F), omega0, rtol=1e-12)


@pytest.mark.parametrize("phi", [-0.5, -0.19, 0.0, 0.2])
def test_pure_translation_matches_equation_of_motion(phi):
    """dv/dt = -α v^φ g."""
    alpha, v0 = 0.0076, 2.1
    t_F = cf.stop_time_translation(v0, phi, alpha)
    t = np.linspace(0, 0.999 * t_F, 400)
    sol = solve_ivp(lambda _, s: [s[1], -alpha * max(s[1], 0) ** phi * G],
                    (0, t[-1]), [0.0, v0], t_eval=t, rtol=1e-12, atol=1e-14, method="DOP853")
    y_F = (1 - phi) / (2 - phi) * v0 * t_F
    closed = cf.decel_position(t, y_F, cf.lambda_from_phi(phi), t_F)
    np.testing.assert_allclose(sol.y[0][1:], closed[1:], rtol=1e-6)
    np.testing.assert_allclose(cf.alpha_translation(v0, phi, t_F), alpha, rtol=1e-12)


@pytest.mark.parametrize("lam", [1.3, 1.6, 1.897, 1.99995, 2.0, 2.00003, 2.27])
def test_curl_is_double_integral_of_paper_acceleration(lam):
    """x(t) integrates the paper's a_x(t), including through the λ = 2 limit."""
    t_F, a_T = 20.0, 4.6e-3
    t = np.linspace(0, t_F, 400001)
    ax = cf.curl_acceleration(t, a_T, lam, t_F)
    v = np.concatenate([[0], np.cumsum((ax[1:] + ax[:-1]) / 2 * np.diff(t))])
    x = np.concatenate([[0], np.cumsum((v[1:] + v[:-1]) / 2 * np.diff(t))])
    pick = slice(20000, 380001, 20000)  # a_x is integrably singular at t_F for λ < 2
    np.testing.assert_allclose(x[pick], cf.curl_position(t[pick], a_T, lam, t_F), rtol=2e-6)
    assert cf.curl_position(t_F, a_T, lam, t_F) == pytest.approx(cf.curl_distance(a_T, lam, t_F),
                                                                  rel=1e-9)


def test_dry_limit_is_continuous():
    s = np.linspace(0, 1, 101)
    at2 = cf.curl_shape(s, 2.0)
    for d in (1e-3, 2e-4, 1.01e-4, 0.99e-4, 1e-6):
        np.testing.assert_allclose(cf.curl_shape(s, 2.0 + d), at2, atol=3 * d)
        np.testing.assert_allclose(cf.curl_shape(s, 2.0 - d), at2, atol=3 * d)
    # and the exact value at lambda = 2: x = (a_T t_F^2 / 2) [s^2 + ...] has x_F = a_T t_F^2/4
    assert cf.curl_shape(1.0, 2.0) == pytest.approx(0.5, abs=1e-15)


def test_paper_numbers():
    assert cf.phi_from_lambda(1.586) == pytest.approx(-0.707, abs=1e-3)  # paper: ±0.003
    assert cf.phi_from_lambda(1.84) == pytest.approx(-0.19, abs=5e-3)
    assert cf.phi_from_lambda(1.55) == pytest.approx(-0.82, abs=5e-3)
    assert cf.phi_from_lambda(1.66) == pytest.approx(-0.52, abs=5e-3)
    assert cf.lambda_from_phi(0.0) == 2.0
    assert cf.c_omega(1.455, 1.897, R, r) == pytest.approx(2.54, abs=0.01)  # paper truncates: 2.545
    assert cf.c_y(1.569, 2.268, R, r) == pytest.approx(1.77, abs=0.01)  # paper truncates: 1.7765
    assert cf.phi_from_lambda(1.569) == pytest.approx(-0.7575, abs=5e-4)
    lam = np.linspace(1.2, 2.9, 18)
    np.testing.assert_allclose(cf.c_omega(lam, 1.9) * cf.c_y(lam, 1.9), 4.0)
    np.testing.assert_allclose(cf.lambda_from_phi(cf.phi_from_lambda(lam)), lam)
