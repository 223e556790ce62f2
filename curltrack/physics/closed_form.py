"""The paper's closed forms (Jensen & Shegelski 2004, section "Background Theory").

With mu = alpha u^phi the decelerating motion in one coordinate has the form

    q(t) = q_F [1 - (1 - t/t_F)^lambda],   lambda = (2 - phi)/(1 - phi),

for ``theta`` (pure rotation) and ``y`` (draw), and the curl under a constant transverse
acceleration ``a_T`` (paper's Eq. for x(t)).  Times in s, lengths in m, angles in rad.
Every formula is written so that lambda = 2 (dry friction, phi = 0), where (2 - lambda)
appears in a denominator, is evaluated through its analytic limit.  All functions are
vectorised over ``t`` and hold the final value for t >= t_F.

The derived-quantity functions accept plain floats or ``uncertainties`` numbers, so the
fit propagates its covariance through exactly these formulas.
"""

from __future__ import annotations

import numpy as np

from ..rig import BAND_RADIUS_M, G, INERTIA_RADIUS_M

#: |lambda - 2| below which the curl formula uses its Taylor expansion about lambda = 2.
LAMBDA_DRY_EPS = 1e-4


def _s(t, t_F):
    """Normalised time s = t/t_F clipped to [0, 1]."""
    return np.clip(np.asarray(t, dtype=float) / t_F, 0.0, 1.0)


def decel_position(t, q_F, lam, t_F):
    """q(t) = q_F [1 - (1 - t/t_F)^lam]: the paper's theta(t) and y(t)."""
    return q_F * (1.0 - (1.0 - _s(t, t_F)) ** lam)


def decel_rate(t, q_F, lam, t_F):
    """dq/dt = (q_F lam / t_F) (1 - t/t_F)^(lam - 1): omega(t) and v_y(t)."""
    return q_F * lam / t_F * (1.0 - _s(t, t_F)) ** (lam - 1.0)


def _pow_log(one_minus_s, lam):
    """((1-s)^lam, ln(1-s) (1-s)^lam) with the second -> 0 at s = 1."""
    p = one_minus_s ** lam
    with np.errstate(divide="ignore", invalid="ignore"):
        pl = np.where(one_minus_s > 0, np.log(np.where(one_minus_s > 0, one_minus_s, 1.0)) * p, 0.0)
    return p, pl


def curl_shape(s, lam):
    """Dimensionless curl X(s) with x(t) = 1/2 a_T t_F^2 X(t/t_F).

    X(s) = s^2 - g(lam, s)/(2 - lam), g = (1 - lam) s^2 + 2 s - (2/lam)(1 - (1-s)^lam),
    which is 0/0 at lam = 2; there the Taylor series -g'(2) - g''(2)(lam-2)/2 is used.
    """
    s = np.asarray(s, dtype=float)
    u = 1.0 - s
    if abs(lam - 2.0) > LAMBDA_DRY_EPS:
        p, _ = _pow_log(u, lam)
        g = (1.0 - lam) * s**2 + 2.0 * s - (2.0 / lam) * (1.0 - p)
        return s**2 - g / (2.0 - lam)
    lam0 = 2.0
    p, pl = _pow_log(u, lam0)
    L2p = np.where(u > 0, np.log(np.where(u > 0, u, 1.0)) ** 2 * p, 0.0)
    g1 = -s**2 + 2.0 / lam0**2 * (1.0 - p) + 2.0 / lam0 * pl
    g2 = -4.0 / lam0**3 * (1.0 - p) - 4.0 / lam0**2 * pl + 2.0 / lam0 * L2p
    return s**2 + g1 + 0.5 * g2 * (lam - lam0)


def curl_position(t, a_T, lam, t_F):
    """The paper's x(t) for a constant transverse acceleration ``a_T`` (m/s^2).

    x_F = x(t_F) = a_T t_F^2 / (2 lam).
    """
    return 0.5 * a_T * t_F**2 * curl_shape(_s(t, t_F), lam)


def curl_acceleration(t, a_T, lam, t_F):
    """a_x(t) = a_T [1 - (1-lam)/(2-lam) (1 - (1-s)^(lam-2))], through its limit at lam = 2."""
    s = np.clip(np.asarray(t, dtype=float) / t_F, 0.0, 1.0 - 1e-12)
    k = lam - 2.0
    L = np.log1p(-s)
    if abs(k) > LAMBDA_DRY_EPS:
        ratio = -np.expm1(k * L) / (-k)  # (1 - (1-s)^k)/(2 - lam)
    else:
        ratio = L * (1.0 + 0.5 * k * L)  # limit, first order in k
    return a_T * (1.0 - (1.0 - lam) * ratio)


# --- derived quantities (the paper's inversions); work on floats or ufloats -----------

def phi_from_lambda(lam):
    """phi = (2 - lambda)/(1 - lambda)."""
    return (2.0 - lam) / (1.0 - lam)


def lambda_from_phi(phi):
    """lambda = (2 - phi)/(1 - phi)."""
    return (2.0 - phi) / (1.0 - phi)


def initial_rate(q_F, lam, t_F):
    """omega_0 = theta_F lambda / t_F (or v_0 = y_F lambda_y / t_FS)."""
    return q_F * lam / t_F


def alpha_rotation(omega0, phi, t_F, R=INERTIA_RADIUS_M, r=BAND_RADIUS_M, g=G):
    """alpha = omega0^(1-phi) R^2 / (2 (1-phi) r^(1+phi) g t_Ftheta), (m/s)^(-phi)."""
    return omega0 ** (1.0 - phi) * R**2 / (2.0 * (1.0 - phi) * r ** (1.0 + phi) * g * t_F)


def alpha_translation(v0, phi, t_F, g=G):
    """alpha = v0^(1-phi) / ((1-phi) g t_FS), (m/s)^(-phi)."""
    return v0 ** (1.0 - phi) / ((1.0 - phi) * g * t_F)


def stop_time_rotation(omega0, phi, alpha, R=INERTIA_RADIUS_M, r=BAND_RADIUS_M, g=G):
    """t_Ftheta = omega0^(1-phi) R^2 / (2 (1-phi) r^(1+phi) alpha g)  (s)."""
    return omega0 ** (1.0 - phi) * R**2 / (2.0 * (1.0 - phi) * r ** (1.0 + phi) * alpha * g)


def stop_time_translation(v0, phi, alpha, g=G):
    """t_FS = v0^(1-phi) / ((1-phi) alpha g)  (s)."""
    return v0 ** (1.0 - phi) / ((1.0 - phi) * alpha * g)


def c_omega(lambda_theta, lambda_y, R=INERTIA_RADIUS_M, r=BAND_RADIUS_M):
    """C_omega = (lambda_theta - 1)/(lambda_y - 1) (R/r)^2 (draw shots)."""
    return (lambda_theta - 1.0) / (lambda_y - 1.0) * (R / r) ** 2


def c_y(lambda_theta, lambda_y, R=INERTIA_RADIUS_M, r=BAND_RADIUS_M):
    """C_y = 4 (r/R)^2 (lambda_y - 1)/(lambda_theta - 1) (RRSS shots); C_omega C_y = 4."""
    return 4.0 * (r / R) ** 2 * (lambda_y - 1.0) / (lambda_theta - 1.0)


def curl_distance(a_T, lam, t_F):
    """x_F = a_T t_F^2 / (2 lambda)  (m)."""
    return 0.5 * a_T * t_F**2 / lam
