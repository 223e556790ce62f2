"""Data-driven extension terms of the equations of motion (beyond the named effects).

Each term is a smooth multiplier on one part of the paper's equations
(:mod:`curltrack.physics.shot`) with a few coefficients; ``discover`` fits them when no
named effect explains the residuals (:mod:`curltrack.discover.extend`).  They are
registered as effects (:data:`curltrack.physics.effects.EFFECTS`), so ``simulate
--effect NAME --param KEY=VALUE`` and the tests use the very same equations.  All
multipliers are clipped at :data:`MIN_FACTOR` so that friction never changes sign.

``friction_field`` (``wavelength_m``; ``amp_cos`` = 0, ``amp_sin`` = 0)
    Both friction coefficients vary periodically along the sheet:
    alpha(y) = alpha [1 + amp_cos cos(2 pi y / wavelength) + amp_sin sin(2 pi y / wavelength)]
    (the relative amplitude is hypot(amp_cos, amp_sin)).
``spin_coupling`` (``c_s_per_m``)
    The spin decays faster with the translation speed v (m/s):
    d|omega|/dt = -k_theta |omega|^phi_theta (1 + c v).
``translation_coupling`` (``c_s_per_rad``)
    The translation decays faster with the spin: dv/dt = -k_y v^phi_y (1 + c |omega|).
``curl_spin_dependence`` (``p``; ``omega_ref_rad_per_s`` = 1, ``omega_min_rad_per_s`` = 0.05)
    The transverse acceleration follows the spin:
    a_T ((omega^2 + omega_min^2) / omega_ref^2)^(p / 2), i.e. a_T (|omega|/omega_ref)^p
    above omega_min (p > 0: the curl fades with the spin; the baseline, p = 0, keeps a_T
    until the spin has stopped).
"""

from __future__ import annotations

import math
from typing import NamedTuple

#: name -> {parameter: default}; ``None`` marks a required parameter
TERMS: dict[str, dict[str, float | None]] = {
    "friction_field": {"wavelength_m": None, "amp_cos": 0.0, "amp_sin": 0.0},
    "spin_coupling": {"c_s_per_m": None},
    "translation_coupling": {"c_s_per_rad": None},
    "curl_spin_dependence": {"p": None, "omega_ref_rad_per_s": 1.0,
                             "omega_min_rad_per_s": 0.05},
}

#: multipliers of friction never fall below this (a fitted coefficient far off the data
#: must not make friction push the rock)
MIN_FACTOR = 0.05


def check_term(name: str, p: dict) -> str | None:
    """The reason ``p`` is out of range for term ``name`` (None when fine)."""
    if name == "friction_field":
        if p["wavelength_m"] <= 0.05:
            return f"wavelength_m must be > 0.05 m (got {p['wavelength_m']})"
        if math.hypot(p["amp_cos"], p["amp_sin"]) >= 0.95:
            return "the amplitude hypot(amp_cos, amp_sin) must be < 0.95"
    elif name == "spin_coupling" and abs(p["c_s_per_m"]) > 20.0:
        return f"|c_s_per_m| = {abs(p['c_s_per_m'])} is above 20 s/m"
    elif name == "translation_coupling" and abs(p["c_s_per_rad"]) > 20.0:
        return f"|c_s_per_rad| = {abs(p['c_s_per_rad'])} is above 20 s/rad"
    elif name == "curl_spin_dependence":
        if abs(p["p"]) > 5.0:
            return f"p = {p['p']} is outside [-5, 5]"
        for key in ("omega_ref_rad_per_s", "omega_min_rad_per_s"):
            if p[key] <= 0:
                return f"{key} must be > 0 (got {p[key]})"
    return None


class Extension(NamedTuple):
    """Extension terms gathered for the equations of motion (None/0 when absent)."""

    field: tuple[float, float, float] | None = None    # (k = 2 pi / wavelength, a_cos, a_sin)
    spin_c: float = 0.0                                # s/m
    trans_c: float = 0.0                               # s/rad
    curl: tuple[float, float, float] | None = None     # (p, omega_ref, omega_min)

    def friction(self, y: float, omega_abs: float) -> float:
        """Multiplier of the translational friction at position ``y`` and spin |omega|."""
        f = 1.0
        if self.field is not None:
            k, a, b = self.field
            f += a * math.cos(k * y) + b * math.sin(k * y)
        f = max(f, MIN_FACTOR)
        if self.trans_c:
            f *= max(1.0 + self.trans_c * omega_abs, MIN_FACTOR)
        return f

    def spin_friction(self, y: float, v: float) -> float:
        """Multiplier of the rotational friction at position ``y`` and speed ``v``."""
        f = 1.0
        if self.field is not None:
            k, a, b = self.field
            f = max(1.0 + a * math.cos(k * y) + b * math.sin(k * y), MIN_FACTOR)
        if self.spin_c:
            f *= max(1.0 + self.spin_c * v, MIN_FACTOR)
        return f

    def curl_gain(self, omega_abs: float) -> float:
        """Multiplier of a_T at spin |omega| (rad/s)."""
        if self.curl is None:
            return 1.0
        p, w_ref, w_min = self.curl
        return ((omega_abs * omega_abs + w_min * w_min) / (w_ref * w_ref)) ** (0.5 * p)


def gather_terms(items) -> Extension | None:
    """``Extension`` from ``(name, params)`` pairs of extension terms (None if empty)."""
    kw: dict = {}
    for name, p in items:
        if name == "friction_field":
            kw["field"] = (2.0 * math.pi / p["wavelength_m"], p["amp_cos"], p["amp_sin"])
        elif name == "spin_coupling":
            kw["spin_c"] = p["c_s_per_m"]
        elif name == "translation_coupling":
            kw["trans_c"] = p["c_s_per_rad"]
        elif name == "curl_spin_dependence":
            kw["curl"] = (p["p"], p["omega_ref_rad_per_s"], p["omega_min_rad_per_s"])
    return Extension(**kw) if kw else None
