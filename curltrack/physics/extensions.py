"""The data-driven extensions of the equations of motion, as registry entries.

``discover`` tries these when no named effect explains the residuals (its library beyond
the vocabulary, :mod:`curltrack.discover.extend`); ``simulate --effect NAME`` and the
tests use the very same equations.  Each is a smooth multiplier with a few coefficients
(its math in :class:`curltrack.physics.terms.Extension`):

``friction_field`` (``wavelength_m``; ``amp_cos`` = 0, ``amp_sin`` = 0)
    Both friction coefficients vary periodically along the sheet:
    alpha(y) = alpha [1 + amp_cos cos(2 pi y / wavelength) + amp_sin sin(2 pi y / wavelength)]
    (relative amplitude hypot(amp_cos, amp_sin)).
``spin_coupling`` (``c_s_per_m``)
    The spin decays faster with the translation speed v (m/s):
    d|omega|/dt = -k_theta |omega|^phi_theta (1 + c v).
``translation_coupling`` (``c_s_per_rad``)
    The translation decays faster with the spin: dv/dt = -k_y v^phi_y (1 + c |omega|).
``curl_spin_dependence`` (``p``; ``omega_ref_rad_per_s`` = 1, ``omega_min_rad_per_s`` = 0.05)
    The transverse acceleration follows the spin: a_T ((omega^2 + omega_min^2) /
    omega_ref^2)^(p/2), i.e. a_T (|omega| / omega_ref)^p above omega_min (p > 0: the curl
    fades with the spin; the baseline, p = 0, keeps a_T until the spin has stopped).

``friction_law`` (``dphi_low``, ``u_knee_m_per_s``; ``u_floor_m_per_s`` = 0.02)
    The translational friction law is not a power law: mu(u) = alpha u^phi g(u) with
    g(u) = ((u^2 + u_knee^2) / (u^2 + u_floor^2))^(dphi_low/2), i.e. the baseline's
    alpha u^phi above the knee speed and ~ u^(phi - dphi_low) below it (dphi_low > 0:
    friction rises more steeply as the rock slows; < 0: less steeply, towards a
    constant), levelling off below u_floor so the rock stops in finite time.  The
    rotational law keeps its power law.

Their candidates test at a false-alarm level of :data:`EXTENSION_LEVEL` each (the five
together add at most 2.5 % to discovery's false alarms).
"""

from __future__ import annotations

import math

import numpy as np

from .registry import REQUIRED, Candidate, Effect, EffectDef, Param, register, translating

#: per-term false-alarm level of discovery's bootstrap threshold
EXTENSION_LEVEL = 0.005
#: shortest wavelength scanned (m): a 10 % field of 1 m moves a 2 m/s rock by ~0.05 mm
LAMBDA_MIN_M = 1.0
#: cells (m) of the piecewise-constant field behind the linear scan's columns
CELL_M = 0.25
#: travel (m) needed for a field: two periods of a 2 m wavelength
MIN_TRAVEL_M = 4.0


def _sliding_and_spinning(shots):
    return [s for s in translating(shots) if s.spins]


def _effect(name, keys, extra=None):
    """``to_effects`` of a term: the candidate's values as one Effect."""
    def to_effects(values, shot_index, shots):
        return (Effect(name, {**{k: float(values[k]) for k in keys}, **(extra or {})}),)
    return to_effects


# ---------------------------------------------------------------------------------------
# friction_field

def wavelength_grid(y_max: float, lam_min: float = LAMBDA_MIN_M) -> list:
    """Wavelengths (m) from ``lam_min`` to half the travel, log-spaced so that the phase
    drifts by about a quarter period over the travel between neighbours."""
    lam_max = 0.5 * y_max
    if lam_max <= lam_min:
        return []
    out = [lam_min]
    while out[-1] < lam_max:
        out.append(out[-1] * (1.0 + max(out[-1] / (4.0 * y_max), 0.004)))
    return [float(v) for v in out[:-1]] + [float(lam_max)]


def _field_check(p):
    if p["wavelength_m"] <= 0.05:
        return f"wavelength_m must be > 0.05 m (got {p['wavelength_m']})"
    if math.hypot(p["amp_cos"], p["amp_sin"]) >= 0.95:
        return "the amplitude hypot(amp_cos, amp_sin) must be < 0.95"
    return None


def _field_unidentifiable(shots, baseline):
    if not translating(shots):
        return "the rock does not slide"
    if max(s.y_max_m for s in translating(shots)) < MIN_TRAVEL_M:
        return f"the rock slides less than {MIN_TRAVEL_M:g} m: no period to see"
    return None


def _field_candidate(shots, baseline):
    y_max = max(s.y_max_m for s in translating(shots))
    lams = wavelength_grid(y_max)
    return Candidate(
        "friction_field",
        [Param("amp_cos", null=0.0, lower=-0.6, upper=0.6, step=1e-4),
         Param("amp_sin", null=0.0, lower=-0.6, upper=0.6, step=1e-4)],
        # (the refit may not leave the two periods the scan holds to: a "field" of 8.9 m
        # over 12.9 m of travel - 1.5 periods, one bump - was named `extended` for a
        # friction patch under heavy-tailed noise; at this bound it is not named)
        location=[Param("wavelength_m", null=lams[0], lower=0.5 * lams[0],
                        upper=lams[-1], unit="m", step=1e-3)],
        grid=[{"wavelength_m": v, "y_max_m": y_max} for v in lams],
        extension=True, level=EXTENSION_LEVEL,
        note=f"friction varies periodically along the sheet; wavelength scanned "
             f"{lams[0]:.1f}-{lams[-1]:.1f} m ({len(lams)} values)")


def _field_effects(values, shot_index, shots):
    if "cell_from_m" in values:
        # the linear scan's building block (see _field_columns): extra friction from
        # cell_from_m on, amp_cos its size
        return (Effect("friction_patch", {"y_start_m": float(values["cell_from_m"]),
                                          "y_end_m": float(values["cell_from_m"]) + 1e3,
                                          "factor": 1.0 + float(values["amp_cos"])}),)
    return (Effect("friction_field", {k: float(values[k]) for k in
                                      ("wavelength_m", "amp_cos", "amp_sin")}),)


def _field_columns(columns_at, locs):
    """Linear-scan columns at every wavelength from one set of closed-form simulations.

    In the linear limit the response to a friction multiplier 1 + delta(y) is the sum
    over cells of delta's cell mean times the response to extra friction in that cell,
    and a cell's response is that of extra friction on [a, inf) minus that on [b, inf)
    (closed forms, ~ms each, instead of an ODE per wavelength).  Cells of
    :data:`CELL_M` hold a cosine of the shortest wavelength to within 2 % of its
    amplitude.
    """
    y_max = locs[0]["y_max_m"]
    nodes = np.arange(0.0, y_max + 0.5 + CELL_M, CELL_M)
    half = np.column_stack([columns_at({"cell_from_m": float(a), "wavelength_m": 1.0})[:, 0]
                            for a in nodes])
    cells = half[:, :-1] - half[:, 1:]
    a, b = nodes[:-1], nodes[1:]
    out = []
    for loc in locs:
        k = 2.0 * math.pi / loc["wavelength_m"]
        c = (np.sin(k * b) - np.sin(k * a)) / (k * (b - a))
        s = (np.cos(k * a) - np.cos(k * b)) / (k * (b - a))
        out.append(cells @ np.column_stack([c, s]))
    return out


register(EffectDef(
    "friction_field",
    (Param("wavelength_m", REQUIRED, "m"), Param("amp_cos", 0.0), Param("amp_sin", 0.0)),
    terms=lambda p: {"friction_field": (2.0 * math.pi / p["wavelength_m"], p["amp_cos"],
                                        p["amp_sin"])},
    check=_field_check, once=True, unidentifiable=_field_unidentifiable,
    candidate=_field_candidate, to_effects=_field_effects, scan_columns=_field_columns))


# ---------------------------------------------------------------------------------------
# spin_coupling, translation_coupling

def _coupling_unidentifiable(shots, baseline):
    if not _sliding_and_spinning(shots):
        return "needs a rock that slides and spins"
    return None


def _spin_candidate(shots, baseline):
    v_max = max(float(s.start.get("v0", 0.0)) for s in _sliding_and_spinning(shots)) or 2.0
    return Candidate("spin_coupling", [Param("c_s_per_m", null=0.0, lower=-0.9 / v_max,
                                             upper=5.0, unit="s/m", step=1e-4)],
                     extension=True, level=EXTENSION_LEVEL,
                     note="spin decay scaled by 1 + c v")


def _trans_candidate(shots, baseline):
    w_max = max(abs(float(s.start.get("omega0", 0.0)))
                for s in _sliding_and_spinning(shots)) or 2.0
    return Candidate("translation_coupling", [Param("c_s_per_rad", null=0.0,
                                                    lower=-0.9 / w_max, upper=5.0,
                                                    unit="s/rad", step=1e-4)],
                     extension=True, level=EXTENSION_LEVEL,
                     note="translation decay scaled by 1 + c |omega|")


def _register_coupling(name: str, key: str, unit: str, candidate) -> None:
    register(EffectDef(
        name, (Param(key, REQUIRED, unit),), terms=lambda p: {name: p[key]},
        check=lambda p: (f"|{key}| = {abs(p[key])} is above 20 {unit}"
                         if abs(p[key]) > 20.0 else None),
        once=True, unidentifiable=_coupling_unidentifiable, candidate=candidate,
        to_effects=_effect(name, (key,))))


_register_coupling("spin_coupling", "c_s_per_m", "s/m", _spin_candidate)
_register_coupling("translation_coupling", "c_s_per_rad", "s/rad", _trans_candidate)


# ---------------------------------------------------------------------------------------
# curl_spin_dependence

def omega_ref(shots) -> float:
    """The spin (rad/s) the curl's power law is referred to: the median |omega0|."""
    w = [abs(float(s.start.get("omega0", 0.0))) for s in _sliding_and_spinning(shots)]
    return float(np.median(w)) if w and np.median(w) > 0 else 1.0


def _curl_check(p):
    if abs(p["p"]) > 5.0:
        return f"p = {p['p']} is outside [-5, 5]"
    for key in ("omega_ref_rad_per_s", "omega_min_rad_per_s"):
        if p[key] <= 0:
            return f"{key} must be > 0 (got {p[key]})"
    return None


def _curl_effects(values, shot_index, shots):
    return (Effect("curl_spin_dependence", {"p": float(values["p"]),
                                            "omega_ref_rad_per_s": omega_ref(shots)}),)


register(EffectDef(
    "curl_spin_dependence",
    (Param("p", REQUIRED), Param("omega_ref_rad_per_s", 1.0, "rad/s"),
     Param("omega_min_rad_per_s", 0.05, "rad/s")),
    terms=lambda p: {"curl_spin": (p["p"], p["omega_ref_rad_per_s"], p["omega_min_rad_per_s"])},
    check=_curl_check, once=True, unidentifiable=_coupling_unidentifiable,
    candidate=lambda shots, baseline: Candidate(
        "curl_spin_dependence", [Param("p", null=0.0, lower=-3.0, upper=3.0, step=1e-4)],
        extension=True, level=EXTENSION_LEVEL,
        note=f"a_T scaled by (|omega| / {omega_ref(shots):.2f} rad/s)^p"),
    to_effects=_curl_effects))


# ---------------------------------------------------------------------------------------
# friction_law

#: speed (m/s) below which the bent law levels off (the last ~1 % of a draw's time)
U_FLOOR_M_PER_S = 0.02
#: knee speeds scanned (m/s): from here to half the fastest release speed, log-spaced
U_KNEE_MIN = 0.08
N_KNEES = 12


def knee_grid(v_max: float) -> list:
    """Knee speeds (m/s) of the scan: a knee near the release speed is a change of
    alpha and phi (the baseline's own), one near u_floor acts on a few frames."""
    hi = max(0.5 * v_max, 2.0 * U_KNEE_MIN)
    return [float(v) for v in np.geomspace(U_KNEE_MIN, hi, N_KNEES)]


def _law_check(p):
    if abs(p["dphi_low"]) > 3.0:
        return f"dphi_low = {p['dphi_low']} is outside [-3, 3]"
    if not 0.0 < p["u_floor_m_per_s"] < p["u_knee_m_per_s"]:
        return (f"need 0 < u_floor_m_per_s ({p['u_floor_m_per_s']}) < u_knee_m_per_s "
                f"({p['u_knee_m_per_s']})")
    return None


def _law_unidentifiable(shots, baseline):
    return None if translating(shots) else "the rock does not slide"


def _law_candidate(shots, baseline):
    v_max = max(float(s.start.get("v0", 2.0)) for s in translating(shots))
    knees = knee_grid(v_max)
    return Candidate(
        "friction_law",
        [Param("dphi_low", null=0.0, lower=-1.5, upper=1.5, step=1e-4)],
        location=[Param("u_knee_m_per_s", null=knees[0], lower=0.5 * U_KNEE_MIN,
                        upper=max(v_max, 2.0 * knees[-1]), unit="m/s", step=1e-3)],
        grid=[{"u_knee_m_per_s": v} for v in knees],
        extension=True, level=EXTENSION_LEVEL, n_starts=1,
        note=f"translational friction alpha u^phi bent to u^(phi - dphi_low) below a knee "
             f"speed scanned {knees[0]:.2f}-{knees[-1]:.2f} m/s ({len(knees)} values)")


register(EffectDef(
    "friction_law",
    (Param("dphi_low", REQUIRED), Param("u_knee_m_per_s", REQUIRED, "m/s"),
     Param("u_floor_m_per_s", U_FLOOR_M_PER_S, "m/s")),
    terms=lambda p: {"speed_law": (p["dphi_low"], p["u_knee_m_per_s"], p["u_floor_m_per_s"])},
    check=_law_check, once=True, unidentifiable=_law_unidentifiable,
    candidate=_law_candidate, to_effects=_effect("friction_law",
                                                  ("dphi_low", "u_knee_m_per_s"))))
