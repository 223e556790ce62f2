"""The candidate extensions of the baseline: nested models, one per effect term.

Each candidate names the simulator's effect term (:mod:`curltrack.physics`), the
parameters it adds, which of them set the effect's *size* (the effect vanishes at their
``null`` values, where the candidate reduces to the baseline) and which set a *location*
that must be scanned (a pick's time, a patch's extent).  The physics itself is never
written here: a candidate only turns parameter values into ``Effect`` objects.

``velocity_dependent_friction`` is special: it is not an added term but the release of
the baseline's ``phi_y`` and ``phi_theta`` from 0 (the dry baseline) -- the paper's own
comparison.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: candidate names in the order they are tried
EFFECTS = ("velocity_dependent_friction", "ice_slope", "friction_patch", "late_curl", "pick")


@dataclass(frozen=True)
class Param:
    """One parameter a candidate adds: name, starting/null value, bounds, unit."""

    name: str
    null: float
    lower: float
    upper: float
    unit: str = ""


@dataclass
class Candidate:
    """A nested extension of the baseline.

    Attributes
    ----------
    name : str
        Effect name (contract).
    size : list of Param
        Parameters that set the effect's size; the effect vanishes at their ``null``.
    location : list of Param
        Parameters scanned on a grid (look-elsewhere); empty for global effects.
    grid : list of dict
        Scan locations (values of the ``location`` parameters, and ``shot`` for a pick).
    releases : list of str
        Baseline parameters the candidate frees instead of adding a term.
    note : str
        What is (not) identifiable with the shots given.
    subsets : list of tuple of int, optional
        Sub-models: which size parameters may be free together (indices into ``size``);
        the scan picks the best by delta-BIC, and the bootstrap calibrates that choice.
        Default: all of them at once.
    extension : bool
        A data-driven extension term (:mod:`.extend`), not a named effect.
    to_effects : callable, optional
        ``(values, shot_index, shots) -> tuple of Effect`` for terms not listed here.
    scan : callable, optional
        ``(base, fit0, cand, locs) -> list of column blocks``: a cheaper way to the
        linear scan's effect columns than one simulation per location.
    level : float, optional
        False-alarm level of the candidate's bootstrap threshold (default
        :data:`scoring.CANDIDATE_LEVEL`).
    n_starts : int, optional
        Nonlinear fits started from this many scan locations (default: the search's).
    """

    name: str
    size: list
    location: list = field(default_factory=list)
    grid: list = field(default_factory=lambda: [{}])
    releases: list = field(default_factory=list)
    note: str = ""
    subsets: list | None = None
    extension: bool = False
    to_effects: object = None
    scan: object = None
    level: float | None = None
    n_starts: int | None = None

    @property
    def params(self) -> list:
        return list(self.location) + list(self.size)

    @property
    def k(self) -> int:
        """Number of parameters added (BIC penalty); a pick's shot index is not counted."""
        return len(self.size) + len(self.location)


def _slope_frame(values: dict, heading_rad: float, heading0_rad: float):
    """Slope components in a shot's frame from those in the first shot's frame."""
    sx, sy = values.get("slope_x_mm_per_m", 0.0), values.get("slope_y_mm_per_m", 0.0)
    d = heading_rad - heading0_rad
    c, s = np.cos(d), np.sin(d)
    return sx * c + sy * s, -sx * s + sy * c


def effects_for(cand: Candidate | None, values: dict, shot_index: int, shots) -> tuple:
    """The simulator's ``Effect`` objects of a candidate for one shot.

    Parameters
    ----------
    cand : Candidate or None
    values : dict
        Current values of the candidate's parameters (and ``shot`` for a pick).
    shot_index : int
    shots : list of ShotData
        For the shots' headings.
    """
    from ..physics import Effect

    if cand is None or cand.name == "velocity_dependent_friction":
        return ()
    if cand.to_effects is not None:
        return cand.to_effects(values, shot_index, shots)
    if cand.name == "ice_slope":
        sx, sy = _slope_frame(values, shots[shot_index].heading_rad, shots[0].heading_rad)
        return (Effect("ice_slope", {"slope_x_mm_per_m": float(sx),
                                     "slope_y_mm_per_m": float(sy)}),)
    if cand.name == "friction_patch":
        a, b = sorted((values["y_start_m"], values["y_end_m"]))
        return (Effect("friction_patch", {"y_start_m": float(a), "y_end_m": float(b),
                                          "factor": float(values["factor"])}),)
    if cand.name == "late_curl":
        return (Effect("late_curl", {"k": float(values["k"]), "v_ref_m_per_s": 1.0}),)
    if cand.name == "pick":
        if int(values.get("shot", 0)) != shot_index:
            return ()
        return (Effect("pick", {k: float(values.get(k, 0.0)) for k in
                                ("t_s", "dvx_m_per_s", "dvy_m_per_s", "domega_rad_per_s")}),)
    raise ValueError(f"unknown candidate {cand.name!r}")


def untested(shots, baseline: str) -> dict:
    """Effects that cannot be told from the baseline with these shots, and why."""
    out = {}
    translating = [s for s in shots if s.translates]
    spins = {s.spin for s in translating if s.spins}
    if baseline != "dry":
        out["velocity_dependent_friction"] = ("part of the paper baseline (phi free); "
                                              "tested against --baseline dry")
    if not translating:
        out["ice_slope"] = out["friction_patch"] = out["late_curl"] = "the rock does not slide"
    elif len(spins) < 2:
        out["ice_slope"] = (
            "needs shots of both spin directions in a common frame: with one spin "
            "direction a lateral slope is degenerate with the curl a_T, and a slope "
            "along the sheet with the friction law (alpha, phi) up to a late lateral "
            "term indistinguishable from late_curl")
    return out


def build_candidates(shots, baseline: str) -> list:
    """The candidates that make sense for these shots and this baseline.

    Parameters
    ----------
    shots : list of ShotData
    baseline : {"paper", "dry"}

    Returns
    -------
    list of Candidate
    """
    out = []
    translating = [s for s in shots if s.translates]
    spins = {s.spin for s in translating if s.spins}
    if baseline == "dry":
        rel = []
        if translating:
            rel.append("phi_y")
        if any(s.spins for s in shots):
            rel.append("phi_theta")
        out.append(Candidate("velocity_dependent_friction",
                             [Param(n, 0.0, -3.0, 0.9) for n in rel], releases=rel,
                             note="friction law mu = alpha v^phi against dry friction "
                                  "(phi = 0), per channel"))
    if translating:
        if len(spins) == 2:
            out.append(Candidate(
                "ice_slope", [Param("slope_x_mm_per_m", 0.0, -60.0, 60.0, "mm/m"),
                              Param("slope_y_mm_per_m", 0.0, -60.0, 60.0, "mm/m")],
                note="shots of both spin directions: a lateral slope (the same for both) "
                     "is told from the curl (opposite for them)"))
        y_max = max(float(np.nanmax(s.obs["y"][s.use["y"]])) for s in translating)
        if y_max > 1.0:
            # edges every ~0.4 m (at least 21 nodes): in the linear limit a patch's
            # columns come from one simulation per node (see search.scan_columns)
            nodes = np.linspace(0.0, y_max, max(21, int(np.ceil(y_max / 0.4)) + 1))
            grid = [{"y_start_m": float(a), "y_end_m": float(b)}
                    for i, a in enumerate(nodes) for b in nodes[i + 1:]
                    if b - a <= 0.75 * y_max]
            out.append(Candidate(
                "friction_patch", [Param("factor", 1.0, 0.05, 20.0)],
                location=[Param("y_start_m", 0.0, -1.0, y_max + 1.0, "m"),
                          Param("y_end_m", 0.0, -1.0, y_max + 1.0, "m")],
                grid=grid, note="a stretch of the sheet (along y) where alpha is multiplied "
                                "by factor; extent scanned on a grid, then refined"))
        if spins:
            out.append(Candidate("late_curl", [Param("k", 0.0, -3.0, 3.0)],
                                 note="a_T (v / 1 m/s)^(-k)"))
    grid = []
    for i, s in enumerate(shots):
        t_end = min(v for v in (s.t_stop_translation, s.t_stop_rotation, s.t[-1]) if v)
        for ts in np.linspace(0.0, t_end, 42)[1:-1]:
            grid.append({"shot": i, "t_s": float(ts)})
    size = [Param("dvx_m_per_s", 0.0, -2.0, 2.0, "m/s"),
            Param("dvy_m_per_s", 0.0, -2.0, 2.0, "m/s"),
            Param("domega_rad_per_s", 0.0, -10.0, 10.0, "rad/s")]
    if not translating:
        size = size[2:]
    import itertools

    subsets = [c for r in range(1, len(size) + 1)
               for c in itertools.combinations(range(len(size)), r)]
    out.append(Candidate("pick", size, location=[Param("t_s", 0.0, 0.0, 1e9, "s")],
                         grid=grid, subsets=subsets,
                         note="an impulsive change of velocity and/or spin at t_s (time "
                              "scanned on a grid, then refined; the components kept are "
                              "chosen by delta-BIC)"))
    return out
