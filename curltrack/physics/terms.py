"""The kinds of term an effect can add to the equations of motion, and their math.

The solvers (:mod:`._quadrature`, :mod:`._ode`) know these five kinds and nothing about
effect names; an effect (:mod:`curltrack.physics.effects`) says which of them it adds:

``accel``
    A constant acceleration ``(a_x, a_y)`` (m/s^2) in the shot frame; contributions add.
    Couples the speed to the heading: integrated by the ODE path.
``patch``
    ``(y_start, y_end, factor)``: both friction coefficients multiplied by ``factor``
    while ``y_start <= y < y_end`` (m); overlapping patches multiply.
``transverse_gain``
    ``(k, v_ref, v_min)``: a_T multiplied by ((v^2 + v_min^2) / v_ref^2)^(-k/2); at most one.
``impulse``
    ``(t, dvx, dvy, domega)``: a jump of velocity (m/s) and spin (rad/s) at time t (s),
    applied in time order.
``friction_law``
    ``{ShotModel field: value}``: replaces the model's friction law (phi_y, alpha_y,
    phi_theta, alpha_theta).

Smooth multipliers of the data-driven extensions (``discover``'s library beyond the
named effects; definitions in :mod:`curltrack.physics.extensions`), integrated by the
ODE path, each at most once, gathered into :class:`Extension`:

``friction_field``
    ``(k, a, b)``: both friction coefficients multiplied by 1 + a cos(k y) + b sin(k y)
    (k = 2 pi / wavelength, 1/m).
``spin_coupling``
    ``c`` (s/m): the rotational friction multiplied by 1 + c v.
``translation_coupling``
    ``c`` (s/rad): the translational friction multiplied by 1 + c |omega|.
``curl_spin``
    ``(p, omega_ref, omega_min)``: a_T multiplied by ((omega^2 + omega_min^2) /
    omega_ref^2)^(p/2).
``speed_law``
    ``(dphi, u_knee, u_floor)``: the translational friction multiplied by
    :func:`speed_law_gain` -- mu(u) = alpha u^phi above the knee speed u_knee,
    ~ u^(phi - dphi) below it (down to u_floor, where it levels off again).

Every multiplier is clipped at :data:`MIN_FACTOR`, so friction never changes sign.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..rig import G

#: the term kinds, in the order :class:`Terms` holds them (the last four: its extension)
KINDS = ("accel", "patch", "transverse_gain", "impulse", "friction_law",
         "friction_field", "spin_coupling", "translation_coupling", "curl_spin", "speed_law")
EXTENSION_KINDS = KINDS[5:]
#: multipliers of friction never fall below this (a fitted coefficient far off the data
#: must not make friction push the rock)
MIN_FACTOR = 0.05


class Terms(NamedTuple):
    """Effects gathered for the equations of motion (see :func:`effects.gather`)."""

    slope_accel: tuple[float, float]        # (a_x, a_y) in m/s^2
    patches: tuple[tuple[float, float, float], ...]   # (y_start, y_end, factor)
    late_curl: tuple[float, float, float] | None   # (k, v_ref, v_min) of the transverse gain
    picks: tuple[tuple[float, float, float, float], ...]  # (t, dvx, dvy, domega), sorted
    overrides: dict                         # ShotModel field -> value
    extension: "Extension | None" = None    # smooth multipliers (ODE path)

    @property
    def needs_ode(self) -> bool:
        """Slopes and extension multipliers couple speed, spin and position."""
        return self.slope_accel != (0.0, 0.0) or self.extension is not None


class Extension(NamedTuple):
    """The extension multipliers of one shot (None/0 when absent)."""

    field: tuple[float, float, float] | None = None    # (k = 2 pi / wavelength, a, b)
    spin_c: float = 0.0                                # s/m
    trans_c: float = 0.0                               # s/rad
    curl: tuple[float, float, float] | None = None     # (p, omega_ref, omega_min)
    law: tuple[float, float, float] | None = None      # (dphi, u_knee, u_floor)

    @classmethod
    def from_terms(cls, kinds: dict) -> "Extension | None":
        """From ``{kind: value}`` of :data:`EXTENSION_KINDS` (None when empty)."""
        if not kinds:
            return None
        return cls(field=kinds.get("friction_field"), spin_c=kinds.get("spin_coupling", 0.0),
                   trans_c=kinds.get("translation_coupling", 0.0), curl=kinds.get("curl_spin"),
                   law=kinds.get("speed_law"))

    def packed(self) -> tuple:
        """The multipliers as the flat tuple of floats the ODE kernel reads
        (:mod:`._ode`; an absent term is a flag 0 and neutral values)."""
        k, a, b = self.field if self.field is not None else (0.0, 0.0, 0.0)
        p, w_ref, w_min = self.curl if self.curl is not None else (0.0, 1.0, 0.0)
        dphi, u_k, u_f = self.law if self.law is not None else (0.0, 1.0, 1.0)
        return (float(self.field is not None), k, a, b, self.spin_c, self.trans_c,
                float(self.curl is not None), p, w_ref, w_min,
                float(self.law is not None), dphi, u_k, u_f)


# Scalar kernels: plain ``math`` on floats (the arithmetic ones broadcast over arrays
# too), so that the ODE's right-hand side (:mod:`._ode`) can compile these same
# functions; the array functions below call them.

def field_gain(y, k, a, b):
    """Friction multiplier 1 + a cos(k y) + b sin(k y) of a periodic field at ``y`` (m),
    clipped at :data:`MIN_FACTOR`."""
    return max(1.0 + a * math.cos(k * y) + b * math.sin(k * y), MIN_FACTOR)


def coupling_gain(c, u):
    """Friction multiplier 1 + c u of a coupling to ``u`` (a speed or a spin), clipped at
    :data:`MIN_FACTOR`."""
    return max(1.0 + c * u, MIN_FACTOR)


def curl_gain(omega_abs, p, w_ref, w_min):
    """Multiplier ((|omega|^2 + w_min^2) / w_ref^2)^(p/2) of a_T (rad/s)."""
    return ((omega_abs * omega_abs + w_min * w_min) / (w_ref * w_ref)) ** (0.5 * p)


def speed_law_kernel(u, dphi, u_knee, u_floor):
    """:func:`speed_law_gain` of a float (or an array)."""
    u2 = u * u
    return ((u2 + u_knee * u_knee) / (u2 + u_floor * u_floor)) ** (0.5 * dphi)


def transverse_kernel(v, k, v_ref, v_min):
    """:func:`transverse_gain` of a float (or an array) with a gain term
    ``(k, v_ref, v_min)``."""
    return ((v * v + v_min * v_min) / (v_ref * v_ref)) ** (-0.5 * k)


def heading_kernel(a_perp, v, v_c):
    """:func:`heading_rate` of floats."""
    return a_perp * -math.expm1(-(v / v_c) ** 2) / v if v > 0 else 0.0


def speed_law_gain(u, dphi: float, u_knee: float, u_floor: float):
    """Multiplier of mu = alpha u^phi that bends the friction law below a knee speed.

    g(u) = ((u^2 + u_knee^2) / (u^2 + u_floor^2))^(dphi/2): 1 for u >> u_knee, about
    (u_knee/u)^dphi for u_floor << u << u_knee (the law's exponent phi - dphi there), and
    bounded by (u_knee/u_floor)^dphi as u -> 0, so the rock still stops in finite time
    and the equations stay smooth.  ``u`` in m/s (scalar or array).
    """
    return speed_law_kernel(u if isinstance(u, float) else np.asarray(u, dtype=float),
                            dphi, u_knee, u_floor)


def slope_acceleration(slope_mm_per_m: float, g: float = G) -> float:
    """Downhill acceleration (m/s^2) along an axis that rises ``slope`` mm per m."""
    return -g * math.sin(math.atan(slope_mm_per_m * 1e-3))


def patch_factor(y, patches) -> np.ndarray | float:
    """Friction multiplier at position(s) ``y`` (m): product of the patches covering y."""
    f = np.ones_like(np.asarray(y, dtype=float))
    for y0, y1, factor in patches:
        f = np.where((y >= y0) & (y < y1), f * factor, f)
    return f if f.ndim else float(f)


def transverse_gain(v, late_curl):
    """Multiplier of a_T at speed ``v`` (m/s), before the low-speed taper.

    1 without a gain term; with ``(k, v_ref, v_min)`` it is ((v^2 + v_min^2) /
    v_ref^2)^(-k/2), i.e. (v/v_ref)^(-k) for v >> v_min, bounded by (v_min/v_ref)^(-k)
    as v -> 0.
    """
    if late_curl is None:
        return np.ones_like(v) if isinstance(v, np.ndarray) else 1.0
    return transverse_kernel(v, *late_curl)


def taper(v, v_c: float):
    """h(v) = 1 - exp(-(v/v_c)^2): 1 to within 1e-4 for v > 3 v_c, -> (v/v_c)^2 at v -> 0."""
    if isinstance(v, float):  # the ODE's right-hand side: keep scalar calls cheap
        return -math.expm1(-(v / v_c) ** 2)
    z = np.asarray(v, dtype=float) / v_c
    h = -np.expm1(-z * z)
    return h if h.ndim else float(h)


def heading_rate(a_perp, v, v_c: float):
    """Rate of turn of the velocity (rad/s) for a transverse acceleration ``a_perp``.

    Every transverse acceleration is tapered by h(v) = 1 - exp(-(v/v_c)^2) (see
    :func:`taper`), so it vanishes with the speed and the direction of a vanishing velocity
    is held instead of swinging round; the turn rate a_perp h(v) / v -> a_perp v / v_c^2
    stays finite at every v and is exactly a_perp / v above a few v_c.  Without the taper
    the heading integral of a_T / v diverges at the stop for lambda_y >= 2 (dry friction
    included); with v_c = 1 cm/s it changes a draw's curl by ~1e-5 relative.
    """
    if isinstance(v, float):
        return heading_kernel(a_perp, v, v_c)
    v = np.asarray(v, dtype=float)
    safe = np.where(v > 0, v, 1.0)
    rate = np.where(v > 0, a_perp * taper(safe, v_c) / safe, 0.0)
    return rate if rate.ndim else float(rate)
