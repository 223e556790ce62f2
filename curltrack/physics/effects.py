"""Extension terms of the shot model: named, switchable causes with their own parameters.

Each :class:`Effect` is one candidate cause that ``discover`` can add to the baseline and
that tests hide in simulated data.  Names and parameter names are the contract's
(``shared/contract.md``); all quantities are in the shot frame (x across, y along the
direction of travel, SI units).

``velocity_dependent_friction`` (``phi``, ``alpha``; optional ``phi_theta``, ``alpha_theta``)
    Replaces the translational friction law mu = alpha v^phi of the model (the paper's
    result against a dry-friction, phi = 0, baseline); the rotational law is replaced too
    when ``phi_theta``/``alpha_theta`` are given.
``ice_slope`` (``slope_x_mm_per_m``, ``slope_y_mm_per_m``)
    The sheet rises by that many mm per m along +x / +y; the rock feels the constant
    downhill acceleration a = -g sin(atan(slope)) per axis (m/s^2).
``friction_patch`` (``y_start_m``, ``y_end_m``, ``factor``)
    Both friction coefficients (alpha_y and alpha_theta) are multiplied by ``factor`` while
    the rock centre is in y_start_m <= y < y_end_m (swept, frosted or worn ice); equal
    ends make an empty patch (no effect), so fits may start from one.
``late_curl`` (``k``, ``v_ref_m_per_s`` = 1.0; optional ``v_min_m_per_s`` = 0.05)
    The transverse acceleration grows as the rock slows: a_T (v_eff / v_ref)^(-k) with
    v_eff = sqrt(v^2 + v_min^2), so the gain is (v/v_ref)^(-k) for v >> v_min and stays
    below (v_min/v_ref)^(-k) (20 for k = 1) as v -> 0; the model's taper then fades it.
``pick`` (``t_s``, ``dvx_m_per_s`` = 0, ``dvy_m_per_s`` = 0, ``domega_rad_per_s`` = 0)
    An impulsive change of velocity and spin at time t_s (debris under the running band).
    It is applied whatever the state (a pick after the stop sets a resting rock moving).

The data-driven extension terms (``friction_field``, ``spin_coupling``,
``translation_coupling``, ``curl_spin_dependence``) are registered here too; their
equations are in :mod:`curltrack.physics.terms`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping, NamedTuple

import numpy as np

from ..errors import ParameterError
from ..rig import G
from .terms import TERMS, check_term, gather_terms

_REQUIRED = object()

#: name -> {parameter: default (or required)}
EFFECTS: dict[str, dict[str, object]] = {
    "velocity_dependent_friction": {"phi": _REQUIRED, "alpha": _REQUIRED,
                                    "phi_theta": None, "alpha_theta": None},
    "ice_slope": {"slope_x_mm_per_m": 0.0, "slope_y_mm_per_m": 0.0},
    "friction_patch": {"y_start_m": _REQUIRED, "y_end_m": _REQUIRED, "factor": _REQUIRED},
    "late_curl": {"k": _REQUIRED, "v_ref_m_per_s": 1.0, "v_min_m_per_s": 0.05},
    "pick": {"t_s": _REQUIRED, "dvx_m_per_s": 0.0, "dvy_m_per_s": 0.0,
             "domega_rad_per_s": 0.0},
    **{name: {k: (_REQUIRED if v is None else v) for k, v in spec.items()}
       for name, spec in TERMS.items()},
}

#: |slope| above this (mm/m, i.e. 10 %) is taken for a unit mistake.
MAX_SLOPE_MM_PER_M = 100.0


def effect_parameters(name: str) -> dict[str, object]:
    """Parameters of effect ``name`` with their defaults (``"required"`` when none)."""
    if name not in EFFECTS:
        raise ParameterError(f"unknown effect {name!r}; expected one of {sorted(EFFECTS)}",
                             where="effect")
    return {k: ("required" if v is _REQUIRED else v) for k, v in EFFECTS[name].items()}


@dataclass(frozen=True)
class Effect:
    """One extension term: a contract effect name and its parameters.

    Parameters
    ----------
    name : str
        One of :data:`EFFECTS` (``ice_slope``, ``friction_patch``, ``late_curl``, ``pick``,
        ``velocity_dependent_friction``).
    params : mapping of str to float
        The effect's parameters (units in their names; see the module docstring).
        Missing optional ones take their defaults.

    Raises
    ------
    ParameterError
        Unknown name or parameter, missing required parameter, non-finite or
        out-of-range value.

    Examples
    --------
    >>> Effect("ice_slope", {"slope_x_mm_per_m": 1.0}).params["slope_y_mm_per_m"]
    0.0
    """

    name: str
    params: Mapping[str, float] = field(default_factory=dict, hash=False)

    def __post_init__(self):
        spec = effect_parameters(self.name)
        where = f"effect {self.name}"
        unknown = sorted(set(self.params) - set(spec))
        if unknown:
            raise ParameterError(f"unknown parameter(s) {unknown}; expected some of "
                                 f"{sorted(spec)}", where=where)
        clean: dict[str, float | None] = {}
        for key, default in spec.items():
            if key not in self.params or self.params[key] is None:
                if default == "required":
                    raise ParameterError(f"missing required parameter {key!r}", where=where)
                clean[key] = default
                continue
            value = self.params[key]
            try:
                value = float(value)
            except (TypeError, ValueError):
                raise ParameterError(f"{key}: expected a number, got {value!r}",
                                     where=where) from None
            if not math.isfinite(value):
                raise ParameterError(f"{key}: expected a finite number, got {value!r}",
                                     where=where)
            clean[key] = value
        _check_ranges(self.name, clean, where)
        object.__setattr__(self, "params", clean)

    def to_dict(self) -> dict:
        """JSON-ready ``{"effect": name, "params": {...}}``."""
        return {"effect": self.name, "params": dict(self.params)}


def _check_ranges(name: str, p: dict, where: str) -> None:
    def bad(msg):
        raise ParameterError(msg, where=where)

    if name == "velocity_dependent_friction":
        for phi_key, alpha_key in (("phi", "alpha"), ("phi_theta", "alpha_theta")):
            if p[phi_key] is not None and p[phi_key] >= 1.0:
                bad(f"{phi_key} must be < 1 (got {p[phi_key]}); mu = alpha u^phi")
            if p[alpha_key] is not None and p[alpha_key] <= 0.0:
                bad(f"{alpha_key} must be > 0 (got {p[alpha_key]})")
    elif name == "ice_slope":
        for key in ("slope_x_mm_per_m", "slope_y_mm_per_m"):
            if abs(p[key]) > MAX_SLOPE_MM_PER_M:
                bad(f"{key} = {p[key]} mm/m is steeper than {MAX_SLOPE_MM_PER_M} mm/m "
                    f"(slopes are in mm per m)")
    elif name == "friction_patch":
        if p["factor"] <= 0.0:
            bad(f"factor must be > 0 (got {p['factor']})")
        if p["y_end_m"] < p["y_start_m"]:   # equal: an empty patch (no effect), fine in fits
            bad(f"y_end_m ({p['y_end_m']}) must not be less than y_start_m ({p['y_start_m']})")
    elif name == "late_curl":
        for key in ("v_ref_m_per_s", "v_min_m_per_s"):
            if p[key] <= 0.0:
                bad(f"{key} must be > 0 (got {p[key]})")
        if abs(p["k"]) > 5.0:
            bad(f"k = {p['k']} is outside [-5, 5]")
    elif name == "pick":
        if p["t_s"] < 0.0:
            bad(f"t_s must be >= 0 (got {p['t_s']})")
    elif name in TERMS and (msg := check_term(name, p)) is not None:
        bad(msg)


def as_effects(effects) -> tuple[Effect, ...]:
    """Accept Effect objects, ``(name, params)`` pairs or ``{"effect":..., "params":...}``."""
    out = []
    for e in effects or ():
        if isinstance(e, Effect):
            out.append(e)
        elif isinstance(e, Mapping):
            out.append(Effect(e.get("effect", e.get("name")), e.get("params", {})))
        else:
            name, params = e
            out.append(Effect(name, params))
    return tuple(out)


class Terms(NamedTuple):
    """Effects gathered for the equations of motion (see :func:`gather`)."""

    slope_accel: tuple[float, float]        # (a_x, a_y) in m/s^2
    patches: tuple[tuple[float, float, float], ...]   # (y_start, y_end, factor)
    late_curl: tuple[float, float, float] | None   # (k, v_ref, v_min)
    picks: tuple[tuple[float, float, float, float], ...]  # (t, dvx, dvy, domega), sorted
    overrides: dict                         # ShotModel field -> value
    extension: object = None                # terms.Extension or None

    @property
    def needs_ode(self) -> bool:
        """Slope, patch and extension terms couple speed, spin and position: no closed
        form."""
        return self.slope_accel != (0.0, 0.0) or bool(self.patches) or \
            self.extension is not None


def slope_acceleration(slope_mm_per_m: float, g: float = G) -> float:
    """Downhill acceleration (m/s^2) along an axis that rises ``slope`` mm per m."""
    return -g * math.sin(math.atan(slope_mm_per_m * 1e-3))


def gather(effects) -> Terms:
    """Collect effects into the terms the equations of motion use.

    Slopes add; patches multiply where they overlap; picks are applied in time order;
    ``late_curl`` and ``velocity_dependent_friction`` may each appear once.
    """
    effects = as_effects(effects)
    ax = ay = 0.0
    patches, picks, overrides, late = [], [], {}, None
    seen = set()
    for e in effects:
        p = e.params
        if e.name in ("late_curl", "velocity_dependent_friction") or e.name in TERMS:
            if e.name in seen:
                raise ParameterError("may be given only once", where=f"effect {e.name}")
            seen.add(e.name)
        if e.name == "ice_slope":
            ax += slope_acceleration(p["slope_x_mm_per_m"])
            ay += slope_acceleration(p["slope_y_mm_per_m"])
        elif e.name == "friction_patch":
            patches.append((p["y_start_m"], p["y_end_m"], p["factor"]))
        elif e.name == "late_curl":
            late = (p["k"], p["v_ref_m_per_s"], p["v_min_m_per_s"])
        elif e.name == "pick":
            picks.append((p["t_s"], p["dvx_m_per_s"], p["dvy_m_per_s"], p["domega_rad_per_s"]))
        elif e.name == "velocity_dependent_friction":
            overrides.update(phi_y=p["phi"], alpha_y=p["alpha"])
            if p["phi_theta"] is not None:
                overrides["phi_theta"] = p["phi_theta"]
            if p["alpha_theta"] is not None:
                overrides["alpha_theta"] = p["alpha_theta"]
    picks.sort(key=lambda q: q[0])
    ext = gather_terms((e.name, e.params) for e in effects if e.name in TERMS)
    return Terms((ax, ay), tuple(patches), late, tuple(picks), overrides, ext)


def patch_factor(y, patches) -> np.ndarray | float:
    """Friction multiplier at position(s) ``y`` (m): product of the patches covering y."""
    f = np.ones_like(np.asarray(y, dtype=float))
    for y0, y1, factor in patches:
        f = np.where((y >= y0) & (y < y1), f * factor, f)
    return f if f.ndim else float(f)


def transverse_gain(v, late_curl):
    """Multiplier of a_T at speed ``v`` (m/s), before the low-speed taper.

    1 without ``late_curl``; with it ((v^2 + v_min^2) / v_ref^2)^(-k/2), i.e.
    (v/v_ref)^(-k) for v >> v_min, bounded by (v_min/v_ref)^(-k) as v -> 0.
    """
    if late_curl is None:
        return np.ones_like(v) if isinstance(v, np.ndarray) else 1.0
    k, v_ref, v_min = late_curl
    return ((v * v * 1.0 + v_min * v_min) / (v_ref * v_ref)) ** (-0.5 * k)


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
        return a_perp * -math.expm1(-(v / v_c) ** 2) / v if v > 0 else 0.0
    v = np.asarray(v, dtype=float)
    safe = np.where(v > 0, v, 1.0)
    rate = np.where(v > 0, a_perp * taper(safe, v_c) / safe, 0.0)
    return rate if rate.ndim else float(rate)
