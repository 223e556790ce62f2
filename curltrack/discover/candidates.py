"""The candidate extensions of the baseline: one nested model per registered effect.

Every candidate comes from the effect registry (:mod:`curltrack.physics.effects`): the
effect's definition says when the shots can tell it from the baseline, which parameters
set its *size* (the effect vanishes at their ``null`` values, where the candidate
reduces to the baseline), which set a *location* that must be scanned (a pick's time, a
patch's extent), and how fitted values become the simulator's ``Effect`` objects.  No
effect is named here.

``velocity_dependent_friction`` is not an added term but the release of the baseline's
``phi_y`` and ``phi_theta`` from 0 (the dry baseline) -- the paper's own comparison.
"""

from __future__ import annotations

from ..physics.effects import EFFECTS, Candidate, Param

__all__ = ["Candidate", "Param", "build_candidates", "effects_for", "untested"]


def effects_for(cand: Candidate | None, values: dict, shot_index: int, shots) -> tuple:
    """The simulator's ``Effect`` objects of a candidate for one shot.

    Parameters
    ----------
    cand : Candidate or None
    values : dict
        Current values of the candidate's parameters (and ``shot`` for a per-shot effect).
    shot_index : int
    shots : list of ShotData
        For the shots' headings.
    """
    return () if cand is None else cand.effects(values, shot_index, shots)


def untested(shots, baseline: str) -> dict:
    """Effects that cannot be told from the baseline with these shots, and why."""
    out = {}
    for name, defn in EFFECTS.items():
        reason = defn.unidentifiable(shots, baseline)
        if reason:
            out[name] = reason
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
        In the registry's order, each with its definition attached.
    """
    out = []
    for defn in EFFECTS.values():
        if defn.candidate is None or defn.unidentifiable(shots, baseline):
            continue
        cand = defn.candidate(shots, baseline)
        cand.effect = defn
        out.append(cand)
    return out
