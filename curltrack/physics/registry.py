"""The machinery of the effect registry: parameters, definitions, candidates, gathering.

The effects themselves are defined in :mod:`curltrack.physics.effects` (one
:class:`EffectDef` each, added with :func:`register`); this module is what every
definition is made of, and what ``simulate`` (:func:`gather`) and ``discover``
(:class:`Candidate`) read.

The shots that the discovery hooks receive are any objects with ``translates``,
``spins`` (bool), ``spin`` (+1/-1), ``heading_rad`` (direction of +y in the session's
frame), ``t`` (times, s), ``y_max_m`` (largest measured y used, m) and ``t_end_s`` (the
end of the scannable time, s) -- :class:`curltrack.discover.shots.ShotData` is one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Mapping

import numpy as np

from ..errors import ParameterError
from .params import REQUIRED, Param
from .terms import EXTENSION_KINDS, Extension, Terms





@dataclass
class Candidate:
    """One effect as a nested extension of the baseline, for the shots at hand.

    Attributes
    ----------
    name : str
        Effect name (contract).
    size : list of Param
        Parameters that set the effect's size; the effect vanishes at their ``null``.
    location : list of Param
        Parameters scanned on a grid (look-elsewhere); empty for global effects.
    grid : list of dict
        Scan locations (values of the ``location`` parameters, and ``shot`` for an
        effect that acts on one shot).
    releases : list of str
        Baseline parameters the candidate frees instead of adding a term.
    note : str
        What the candidate is, in words.
    subsets : list of tuple of int, optional
        Sub-models: which size parameters may be free together (indices into ``size``);
        the scan picks the best by delta-BIC, and the bootstrap calibrates that choice.
        Default: all of them at once.
    effect : EffectDef
        The definition (its hooks turn fitted values into effects, etc.).
    """

    name: str
    size: list
    location: list = field(default_factory=list)
    grid: list = field(default_factory=lambda: [{}])
    releases: list = field(default_factory=list)
    note: str = ""
    subsets: list | None = None
    effect: "EffectDef | None" = None
    #: a data-driven extension (``discover.extend``), not a named effect
    extension: bool = False
    #: false-alarm level of its bootstrap threshold (None: discover's default)
    level: float | None = None
    #: nonlinear fits started from this many scan locations (None: discover's default)
    n_starts: int | None = None

    @property
    def params(self) -> list:
        return list(self.location) + list(self.size)

    @property
    def k(self) -> int:
        """Number of parameters added (BIC penalty); a pick's shot index is not counted."""
        return len(self.size) + len(self.location)

    @property
    def per_shot(self) -> bool:
        """The effect acts on one shot (its location carries ``shot``)."""
        return bool(self.effect and self.effect.per_shot)

    def effects(self, values: dict, shot_index: int, shots) -> tuple:
        """The simulator's :class:`Effect` objects for shot ``shot_index``."""
        return self.effect.to_effects(values, shot_index, shots) if self.effect else ()


def _none(*_args):
    return None


def _own_columns(columns_at, locs):
    return [columns_at(loc) for loc in locs]


def _unchanged(params, errs, values, err, loc):
    return params, errs


@dataclass(frozen=True)
class EffectDef:
    """Everything about one effect (see the module docstring).

    Attributes
    ----------
    name : str
    params : tuple of Param
        Its parameters as the simulator takes them.
    terms : callable
        ``terms(p) -> {kind: value}`` with kinds of :mod:`curltrack.physics.terms`
        (``accel``, ``patch``, ``transverse_gain``, ``impulse``, ``friction_law``).
    check : callable
        ``check(p) -> message or None`` on the completed parameters.
    once : bool
        At most one per shot.
    unidentifiable : callable
        ``unidentifiable(shots, baseline) -> reason or None``: why ``discover`` cannot
        tell this effect from the baseline with these shots (reported under
        ``not_tested``).
    candidate : callable or None
        ``candidate(shots, baseline) -> Candidate``: what ``discover`` fits.  None: the
        effect is simulated but never a candidate.
    to_effects : callable
        ``to_effects(values, shot_index, shots) -> tuple of Effect`` from the
        candidate's fitted values.
    per_shot : bool
        The effect acts on one shot of a session (a pick), named by ``shot`` in its
        scan location.
    scan_columns : callable
        ``scan_columns(columns_at, locs) -> list of arrays``: the linearised effect
        columns at every scan location (default: ``columns_at`` of each).
    finish : callable
        ``finish(params, errs, values, err, loc) -> (params, errs)``: the reported
        parameters from the fit (``values``: every fitted value, ``err(name)`` its 1σ).
    location_bounds : callable
        ``location_bounds(loc, shots) -> {name: (lo, hi)}`` for the location's refit.
    marks : callable
        ``marks(params, shot_index, t, pred) -> list`` of ``("span", t0, t1)`` or
        ``("instant", t)``: where a figure shades the effect.
    respread : callable
        ``respread(values, shots) -> list of dict``: other starts for the candidate's
        refit, the fitted effect's size spread differently over its location (a patch's
        deficit over a wider stretch); the refit keeps whichever ends lowest.  Default:
        none.
    remark : callable
        ``remark(params, shots) -> str``: what a reader must know to read the reported
        parameters right (a patch that reaches the release or the stop is a step, which
        its complement describes as well); "" for nothing (the default).
    """

    name: str
    params: tuple
    terms: Callable
    check: Callable = _none
    once: bool = False
    doc: str = ""
    unidentifiable: Callable = _none
    candidate: Callable | None = None
    to_effects: Callable = lambda values, i, shots: ()
    per_shot: bool = False
    scan_columns: Callable = _own_columns
    finish: Callable = _unchanged
    location_bounds: Callable = lambda loc, shots: {}
    marks: Callable = lambda params, j, t, pred: []
    respread: Callable = lambda values, shots: []
    remark: Callable = lambda params, shots: ""

    @property
    def param_names(self) -> tuple:
        return tuple(p.name for p in self.params)


#: name -> definition, in the order discovery tries them
EFFECTS: dict[str, EffectDef] = {}


def register(defn: EffectDef) -> EffectDef:
    """Add an effect to the registry (a definition replaces one of the same name)."""
    EFFECTS[defn.name] = defn
    return defn


def unregister(name: str) -> None:
    """Remove an effect from the registry (tests)."""
    EFFECTS.pop(name, None)


def effect_parameters(name: str) -> dict[str, object]:
    """Parameters of effect ``name`` with their defaults (``"required"`` when none)."""
    if name not in EFFECTS:
        raise ParameterError(f"unknown effect {name!r}; expected one of {sorted(EFFECTS)}",
                             where="effect")
    return {p.name: ("required" if p.default is REQUIRED else p.default)
            for p in EFFECTS[name].params}


@dataclass(frozen=True)
class Effect:
    """One extension term: a registered effect name and its parameters.

    Parameters
    ----------
    name : str
        One of :data:`EFFECTS` (``ice_slope``, ``friction_patch``, ``late_curl``, ``pick``,
        ``velocity_dependent_friction``, and any registered later).
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
        msg = EFFECTS[self.name].check(clean)
        if msg:
            raise ParameterError(msg, where=where)
        object.__setattr__(self, "params", clean)

    def to_dict(self) -> dict:
        """JSON-ready ``{"effect": name, "params": {...}}``."""
        return {"effect": self.name, "params": dict(self.params)}


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


def gather(effects) -> Terms:
    """Collect effects into the terms the equations of motion use.

    Accelerations add; patches multiply where they overlap; impulses are applied in time
    order; an effect defined ``once`` may appear once.
    """
    effects = as_effects(effects)
    ax = ay = 0.0
    patches, picks, overrides, gain, ext = [], [], {}, None, {}
    seen = set()
    for e in effects:
        defn = EFFECTS[e.name]
        if defn.once:
            if e.name in seen:
                raise ParameterError("may be given only once", where=f"effect {e.name}")
            seen.add(e.name)
        for kind, value in defn.terms(e.params).items():
            if kind == "accel":
                ax += value[0]
                ay += value[1]
            elif kind == "patch":
                patches.append(value)
            elif kind == "transverse_gain":
                if gain is not None:
                    raise ParameterError("a second transverse gain", where=f"effect {e.name}")
                gain = value
            elif kind == "impulse":
                picks.append(value)
            elif kind == "friction_law":
                overrides.update(value)
            elif kind in EXTENSION_KINDS:
                if kind in ext:
                    raise ParameterError(f"a second {kind} term", where=f"effect {e.name}")
                ext[kind] = value
            else:
                raise ParameterError(f"unknown term kind {kind!r}", where=f"effect {e.name}")
    picks.sort(key=lambda q: q[0])
    return Terms((ax, ay), tuple(patches), gain, tuple(picks), overrides,
                 Extension.from_terms(ext))


# ---------------------------------------------------------------------------------------
# shared pieces of the definitions

def time_grid(shots, n: int = 42) -> list:
    """Scan locations in time for an effect acting on one shot: ``n - 2`` inner times of
    each shot's scannable span, as ``{"shot": i, "t_s": t}``."""
    return [{"shot": i, "t_s": float(ts)} for i, s in enumerate(shots)
            for ts in np.linspace(0.0, s.t_end_s, n)[1:-1]]


def at_a_time_in_one_shot(name: str, keys: tuple) -> dict:
    """The hooks of an effect that acts on one shot of a session at a scanned time
    ``t_s`` (a pick): keyword arguments of :class:`EffectDef`.

    ``keys`` are the effect's parameters taken from the fitted values (absent ones 0).
    Its candidate scans ``t_s`` on :func:`time_grid`; the fitted ``t_s`` stays within
    its shot, and the reported parameters name the shot.
    """
    def to_effects(values, shot_index, shots):
        if int(values.get("shot", 0)) != shot_index:
            return ()
        return (Effect(name, {k: float(values.get(k, 0.0)) for k in keys}),)

    def finish(params, errs, values, err, loc):
        params["shot"] = int(loc["shot"])
        return params, errs

    def marks(params, j, t, pred):
        return [("instant", params["t_s"])] if int(params.get("shot", 0)) == j else []

    return dict(per_shot=True, to_effects=to_effects, finish=finish, marks=marks,
                location_bounds=lambda loc, shots: {
                    "t_s": (0.0, float(shots[loc["shot"]].t.max()))})


def translating(shots) -> list:
    """The shots whose rock slides."""
    return [s for s in shots if s.translates]


def spin_directions(shots) -> set:
    """Spin directions (+1/-1) of the shots whose rock slides and spins, measured (a
    position-only shot's side is read off its curl, so it does not count)."""
    return {s.spin for s in translating(shots)
            if s.spins and getattr(s, "theta_measured", True)}


def curling(shots) -> list:
    """The shots on which the transverse acceleration acts: sliding with a measured
    spin, or position-only (the spin's side then comes from the curl)."""
    return [s for s in translating(shots)
            if s.spins or not getattr(s, "theta_measured", True)]


def theta_measured(shots) -> bool:
    """Whether any shot measured the rotation (none: no candidate may change the spin)."""
    return any(getattr(s, "theta_measured", True) for s in shots)
