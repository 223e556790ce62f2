"""The paper's semi-phenomenological shot model: parameters and the trajectory it yields.

Equations of motion (Jensen & Shegelski 2004, "Background Theory"; shot frame: x across,
y along the initial velocity, theta counter-clockwise from above).  With speed v, heading
psi (direction of the velocity, counter-clockwise from +y, so v = v (-sin psi, cos psi))
and spin omega:

    dv/dt     = -alpha_y g v^phi_y                         (friction opposite the velocity)
    I dw/dt   = -r alpha_theta (r|w|)^phi_theta M g sign(w),  I = M R^2 / 2  (w = omega)
    dpsi/dt   = sign(w) a_T h(v) / v,   h(v) = 1 - exp(-(v/v_c)^2)
    dx/dt = -v sin(psi),  dy/dt = v cos(psi),  dtheta/dt = w

Translation and rotation decelerate with their own (alpha, phi): one phi cannot give a
draw's lambda_theta ~ 1.45 together with its lambda_y ~ 1.9 (the paper's C_omega).
``a_T`` (m/s^2) is the size of the transverse acceleration, perpendicular to the
instantaneous velocity; a counter-clockwise spin (omega > 0) turns the velocity to the
left of the direction of travel, i.e. curls to -x.  It acts while the rock spins.  The
heading is integrated exactly (no small-angle approximation); the taper h(v) with the
speed v_c (``v_taper``, default 1 cm/s) keeps the heading finite at the stop, where
a_T / v is not integrable for lambda_y >= 2 (see
:func:`curltrack.physics.effects.heading_rate`).  M cancels: all terms are accelerations.

Without effects these give the paper's closed forms exactly: v(t), omega(t), theta(t)
follow q(t) = q_F [1 - (1 - t/t_F)^lambda], and x(t) reduces to the paper's curl formula
when the curl angle is small.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from ..errors import ParameterError
from ..rig import BAND_RADIUS_M, INERTIA_RADIUS_M
from . import closed_form as cf

#: The paper's pebbled-ice draw (their Fig. 5): phi_y = -0.19, alpha_y = 0.0076.
PHI_Y_DRAW = -0.19
ALPHA_Y_DRAW = 0.0076
#: lambda_theta = 1.455 of the same draw -> phi_theta = (2 - 1.455)/(1 - 1.455) = -1.198.
PHI_THETA_DRAW = float(cf.phi_from_lambda(1.455))
A_T_DRAW = 5.0e-3
V_TAPER = 0.01


class _ModelParams:
    """Shared by the shot models: number coercion/validation and radii from a rig."""

    def _coerce_numbers(self, skip=(), optional=()):
        """Every field (but ``skip``) to a finite float; None allowed for ``optional``."""
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name in skip or (value is None and f.name in optional):
                continue
            try:
                value = float(value)
            except (TypeError, ValueError):
                raise ParameterError(f"expected a number, got {value!r}", where=f.name) from None
            if not math.isfinite(value):
                raise ParameterError(f"expected a finite number, got {value!r}", where=f.name)
            object.__setattr__(self, f.name, value)

    @classmethod
    def from_rig(cls, rig, **kw):
        """A model with R and r taken from a :class:`curltrack.rig.Rig`."""
        kw.setdefault("R", rig.inertia_radius_m)
        kw.setdefault("r", rig.band_radius_m)
        return cls(**kw)


@dataclass(frozen=True)
class ShotModel(_ModelParams):
    """Initial conditions and friction laws of one shot (the paper's model).

    Parameters
    ----------
    v0 : float
        Initial speed (m/s) along +y, >= 0.
    omega0 : float
        Initial spin (rad/s); > 0 counter-clockwise seen from above.
    phi_y, alpha_y : float
        Translational friction mu = alpha_y v^phi_y; phi_y < 1, alpha_y > 0 in
        (m/s)^(-phi_y).  Defaults: the paper's pebbled-ice draw (-0.19, 0.0076).
    phi_theta, alpha_theta : float
        Rotational friction mu = alpha_theta (r omega)^phi_theta (the paper's pure-rotation
        law).  Default phi_theta = -1.198 (the draw's lambda_theta = 1.455).
        ``alpha_theta=None`` ties it to the translation: the value for which rotation
        stops when translation does (t_Ftheta = t_FS, as observed for draws on pebbled
        ice); see :attr:`alpha_theta_value`.
    a_T : float
        Size of the transverse acceleration (m/s^2); its side follows the spin
        (negative values curl against the spin).  Default 5e-3 (the paper's draw).
    R, r : float
        Inertia radius (I = M R^2/2) and running-band radius (m).
    v_taper : float
        Speed v_c (m/s) below which transverse accelerations fade out (default 0.01).

    Raises
    ------
    ParameterError
        Non-finite values, v0 < 0, phi >= 1, alpha <= 0, R, r or v_taper <= 0.
    """

    v0: float
    omega0: float
    phi_y: float = PHI_Y_DRAW
    alpha_y: float = ALPHA_Y_DRAW
    phi_theta: float = PHI_THETA_DRAW
    alpha_theta: float | None = None
    a_T: float = A_T_DRAW
    R: float = INERTIA_RADIUS_M
    r: float = BAND_RADIUS_M
    v_taper: float = V_TAPER

    def __post_init__(self):
        self._coerce_numbers(optional=("alpha_theta",))
        if self.v0 < 0:
            raise ParameterError(f"must be >= 0 (got {self.v0}); the shot moves along +y",
                                 where="v0")
        for name in ("phi_y", "phi_theta"):
            if getattr(self, name) >= 1.0:
                raise ParameterError(f"must be < 1 (got {getattr(self, name)}): mu = alpha "
                                     f"u^phi stops the rock only for phi < 1", where=name)
        for name in ("alpha_y", "alpha_theta", "R", "r", "v_taper"):
            value = getattr(self, name)
            if value is not None and value <= 0.0:
                raise ParameterError(f"must be > 0 (got {value})", where=name)
            if value is not None and name.startswith("alpha") and value < 1e-12:
                raise ParameterError(f"{value} is implausibly small (< 1e-12)", where=name)

    @property
    def lambda_y(self) -> float:
        return float(cf.lambda_from_phi(self.phi_y))

    @property
    def lambda_theta(self) -> float:
        return float(cf.lambda_from_phi(self.phi_theta))

    @property
    def alpha_theta_value(self) -> float:
        """alpha_theta in (m/s)^(-phi_theta); when tied, t_Ftheta(omega0) = t_FS(v0)."""
        if self.alpha_theta is not None:
            return self.alpha_theta
        w0 = max(abs(self.omega0), 1e-6) if self.omega0 else 1.0  # no 0 ** (1 - phi)
        t_fs = cf.stop_time_translation(self.v0, self.phi_y, self.alpha_y) if self.v0 else 0.0
        if t_fs <= 0.0:  # pure rotation: no translation to tie to; use the rate law of
            t_fs = cf.stop_time_translation(1.0, self.phi_y, self.alpha_y)  # a 1 m/s draw
        return float(cf.alpha_rotation(w0, self.phi_theta, t_fs, self.R, self.r))

    def decel_y(self) -> float:
        """k_y (m/s^(2 - phi_y)) in dv/dt = -k_y v^phi_y (k_y = alpha_y g)."""
        return 1.0 / ((1.0 - self.phi_y) * cf.stop_time_translation(1.0, self.phi_y,
                                                                     self.alpha_y))

    def decel_theta(self) -> float:
        """k_theta in d|omega|/dt = -k_theta |omega|^phi_theta (= 2 g alpha r^(1+phi)/R^2)."""
        return 1.0 / ((1.0 - self.phi_theta) * cf.stop_time_rotation(
            1.0, self.phi_theta, self.alpha_theta_value, self.R, self.r))

    def stop_times(self) -> tuple[float, float]:
        """(t_FS, t_Ftheta) in s without effects (0 for a motion that never starts)."""
        t_s = cf.stop_time_translation(self.v0, self.phi_y, self.alpha_y) if self.v0 else 0.0
        t_r = (cf.stop_time_rotation(abs(self.omega0), self.phi_theta, self.alpha_theta_value,
                                     self.R, self.r) if self.omega0 else 0.0)
        return float(t_s), float(t_r)

    @classmethod
    def from_dict(cls, d: dict) -> "ShotModel":
        """Inverse of :meth:`to_dict` (derived keys ignored; a tied alpha_theta stays tied)."""
        kw = {f.name: d[f.name] for f in fields(cls) if f.name in d}
        if d.get("alpha_theta_tied"):
            kw["alpha_theta"] = None
        return cls(**kw)

    def to_dict(self) -> dict:
        """JSON-ready parameters (alpha_theta resolved, plus the lambdas)."""
        d = {f.name: getattr(self, f.name) for f in fields(self)}
        d["alpha_theta_tied"] = self.alpha_theta is None
        d["alpha_theta"] = self.alpha_theta_value
        d["lambda_y"], d["lambda_theta"] = self.lambda_y, self.lambda_theta
        return d


@dataclass(frozen=True)
class Trajectory:
    """A simulated shot sampled at times ``t``.

    Attributes
    ----------
    t : ndarray, shape (n,)
        Times (s), as requested.
    x, y : ndarray
        Rock centre (m) in the shot frame.
    vx, vy : ndarray
        Velocity (m/s).
    theta : ndarray
        Orientation (rad), cumulative, counter-clockwise from above, theta(0) = 0.
    omega : ndarray
        Spin (rad/s).
    t_stop_translation, t_stop_rotation : float
        When sliding / spinning ends (s); ``inf`` if not within the horizon.
    """

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    vx: np.ndarray
    vy: np.ndarray
    theta: np.ndarray
    omega: np.ndarray
    t_stop_translation: float
    t_stop_rotation: float

    @property
    def speed(self) -> np.ndarray:
        return np.hypot(self.vx, self.vy)
