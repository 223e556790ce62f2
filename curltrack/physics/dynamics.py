"""Forward model of a shot: :func:`simulate` integrates the paper model with effects.

The equations are documented in :mod:`curltrack.physics.shot` (baseline) and
:mod:`curltrack.physics.effects` (extension terms).  One set of equations, two solvers
chosen here in one place:

* closed forms + quadrature (:mod:`._quadrature`) unless the ice is tilted: baseline,
  ``late_curl``, ``velocity_dependent_friction``, and piecewise for ``pick`` (cut at t_s)
  and ``friction_patch`` (cut where y(t) crosses an edge, found by root finding on the
  interpolant; alpha scaled inside): ~1 ms for a draw;
* a compiled DOP853 integrator with stop events (:mod:`._ode`, SciPy's ``solve_ivp``
  step for step) for ``ice_slope``, which couples the speed to the heading, and the
  extension multipliers: ~0.4 ms a draw.

Both evaluate at the requested times exactly and locate stops analytically or by event
root finding, so the output is smooth in every parameter (finite-difference Jacobians
work) and deterministic.  ``method="ode"`` forces the general solver (tests check that
the two agree).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..errors import ParameterError
from .effects import gather
from .terms import patch_factor
from .shot import ShotModel, Trajectory

#: Integration horizon (s) when the caller gives no times: a rock still moving after
#: this long (a slope steeper than friction can hold) is reported as not stopping.
MAX_DURATION_S = 600.0


def _check_times(t) -> np.ndarray:
    t = np.asarray(t, dtype=float).reshape(-1)
    if t.size and not np.isfinite(t).all():
        raise ParameterError("times must be finite", where="t")
    if t.size and t.min() < 0:
        raise ParameterError(f"times must be >= 0 (got {t.min()})", where="t")
    return t


def solve(model: ShotModel, effects=(), horizon: float | None = None, method: str = "auto"):
    """Integrate a shot once; return ``(segments, t_stop_translation, t_stop_rotation)``.

    ``segments`` is a list of ``(t_start, t_end, segment)`` whose ``evaluate(t)`` gives
    the state for ``0 <= t <= horizon`` (s; default :data:`MAX_DURATION_S`); nothing is
    integrated beyond it, picks after it are ignored and stops after it are ``inf``.
    """
    if not isinstance(model, ShotModel):
        raise ParameterError(f"expected a ShotModel, got {type(model).__name__}", where="model")
    terms = gather(effects)
    if terms.overrides:
        model = dataclasses.replace(model, **terms.overrides)
    if method not in ("auto", "ode", "closed"):
        raise ParameterError(f"unknown method {method!r}; expected auto, ode or closed",
                             where="method")
    if method == "closed" and terms.needs_ode:
        raise ParameterError("a constant acceleration (ice_slope) or an extension "
                             "multiplier needs method 'ode'", where="method")
    use_ode = method == "ode" or terms.needs_ode
    horizon = MAX_DURATION_S if horizon is None else float(horizon)
    segments = (_ode_segments(model, terms, horizon) if use_ode
                else _closed_segments(model, terms, horizon))
    stops = [_stop_time(segments, a) for a in ("t_stop_translation", "t_stop_rotation")]
    # both solvers report a stop beyond the horizon alike: not stopped (inf)
    stops = [s if s <= horizon else math.inf for s in stops]
    return segments, stops[0], stops[1]


def _after_pick(end: dict, pick) -> tuple:
    _, dvx, dvy, dw = pick
    return (end["x"][0], end["y"][0], end["vx"][0] + dvx, end["vy"][0] + dvy,
            end["theta"][0], end["omega"][0] + dw)


def _ode_segments(model, terms, horizon):
    from ._ode import OdeSegment

    state = (0.0, 0.0, 0.0, model.v0, 0.0, model.omega0)
    picks = [p for p in terms.picks if p[0] <= horizon]   # later ones are never seen
    bounds = [0.0] + [p[0] for p in picks]
    segments = []
    for i, t0 in enumerate(bounds):
        t1 = max(bounds[i + 1] if i + 1 < len(bounds) else horizon, t0)
        seg = OdeSegment(model, terms, t0, state, t1)
        segments.append((t0, t1, seg))
        if i + 1 < len(bounds):
            state = _after_pick(seg.evaluate(np.array([t1])), picks[i])
    return segments


def _closed_segments(model, terms, horizon):
    """Closed-form pieces, cut at picks and where the rock crosses a patch edge.

    Inside a piece the friction factor f of the patch under the rock is constant, so the
    motion is the closed form with alpha_y f and alpha_theta f from the piece's start.
    """
    from ._quadrature import ClosedSegment

    edges = sorted({e for p in terms.patches for e in p[:2]})
    alpha_theta = model.alpha_theta_value
    state = (0.0, 0.0, 0.0, model.v0, 0.0, model.omega0)
    t0, picks, segments = 0.0, [p for p in terms.picks if p[0] <= horizon], []
    for _ in range(10000):  # a circling rock may cross an edge many times
        t_pick = picks[0][0] if picks else math.inf
        m = model
        if edges:
            ahead = state[1] + 1e-9 * math.copysign(1.0, state[3])
            f = patch_factor(ahead, terms.patches)
            if f != 1.0:
                m = dataclasses.replace(model, alpha_y=model.alpha_y * f,
                                        alpha_theta=alpha_theta * f)
        seg = ClosedSegment(m, terms.late_curl, t0, state, max(t_pick, t0), horizon)
        t_cross, edge = _first_crossing(seg, edges) if edges else (math.inf, None)
        if t_cross < t_pick:
            segments.append((t0, t_cross, seg))
            end = seg.evaluate(np.array([t_cross]))
            state = tuple(end[k][0] for k in ("x", "y", "vx", "vy", "theta", "omega"))
            state = (state[0], edge) + state[2:]   # exactly on the edge: not crossed again
            t0 = t_cross
            continue
        segments.append((t0, max(t_pick, t0), seg))
        if not picks:
            return segments
        state = _after_pick(seg.evaluate(np.array([max(t_pick, t0)])), picks.pop(0))
        t0 = max(t_pick, t0)
    raise ParameterError("too many patch-edge crossings", where="friction_patch")


def _first_crossing(seg, edges) -> tuple[float, float | None]:
    """First (time, edge) after the piece's start at which y(t) crosses an edge."""
    if seg.nodes is None:
        return math.inf, None
    from scipy.optimize import brentq

    tn, yn = seg.nodes, seg.pos[:, 1]
    best, where = math.inf, None
    for e in edges:
        d = yn - e   # a piece that starts on the edge (d[0] = 0) has not crossed it yet
        hit = np.flatnonzero((d[:-1] * d[1:] < 0) | (d[1:] == 0))
        if not hit.size:
            continue
        j = hit[0]
        if d[j + 1] == 0:
            t_e = tn[j + 1]
        else:
            t_e = brentq(lambda tt: seg.y_in_interval(j, tt) - e, tn[j], tn[j + 1],
                         xtol=1e-13, rtol=1e-15)
        if t_e < best:
            best, where = t_e, e
    return best, where


def _stop_time(segments, attr) -> float:
    """When the motion finally ends: the stop inside the segment where it ended."""
    stop = None
    for i, (t0, t1, seg) in enumerate(segments):
        s = getattr(seg, attr)
        if s > t0:  # moving in this segment: stops inside it, or a pick comes first
            stop = s if (s <= t1 or i == len(segments) - 1) else None
        elif stop is None:  # at rest from the segment's start (a pick stopped it)
            stop = t0
    return float(stop)


def evaluate(segments, t) -> dict:
    """State at times ``t`` from :func:`solve`'s segments (each t from its own segment)."""
    t = _check_times(t)
    out = {k: np.empty(t.shape[0]) for k in ("x", "y", "vx", "vy", "theta", "omega")}
    for i, (t0, t1, seg) in enumerate(segments):
        last = i == len(segments) - 1
        sel = (t >= t0) & ((t < t1) | last)
        if sel.any():
            for k, v in seg.evaluate(t[sel]).items():
                out[k][sel] = v
    return out


def simulate(model: ShotModel, effects=(), t=None, method: str = "auto") -> Trajectory:
    """Simulate one shot and sample it at times ``t``.

    Parameters
    ----------
    model : ShotModel
        Initial conditions and friction laws.
    effects : sequence of Effect
        Extension terms (:mod:`curltrack.physics.effects`); ``(name, params)`` pairs work too.
    t : array_like, optional
        Times (s, >= 0, any order).  Default: 30 fps from 0 until both motions stopped
        plus 1 s.
    method : {"auto", "ode", "closed"}
        Solver; "auto" picks closed forms + quadrature unless an effect needs the ODE.

    Returns
    -------
    Trajectory
        x, y, vx, vy, theta, omega at ``t`` and the stop times (``inf`` for a motion
        still going at max(t): nothing is integrated beyond the requested times).

    Raises
    ------
    ParameterError
        Invalid effects, times or solver failure.

    Examples
    --------
    >>> traj = simulate(ShotModel(v0=2.0, omega0=1.5), t=[0.0, 10.0])
    >>> bool(traj.x[1] < 0)   # counter-clockwise spin curls to -x
    True
    """
    horizon = None
    if t is not None:
        t = _check_times(t)
        horizon = float(t.max()) if t.size else 0.0
    segments, t_tr, t_rot = solve(model, effects, horizon, method)
    if t is None:
        end = max(t_tr, t_rot)
        if not math.isfinite(end):
            raise ParameterError(f"the rock does not stop within {MAX_DURATION_S:.0f} s; "
                                 f"give the times explicitly", where="t")
        t = np.arange(int(math.floor((end + 1.0) * 30.0)) + 1) / 30.0
    s = evaluate(segments, t)
    for k, v in s.items():
        if not np.isfinite(v).all():
            raise ParameterError(f"simulation produced non-finite {k} (parameters outside "
                                 f"the model's range?)", where="simulate")
    return Trajectory(t=t, t_stop_translation=t_tr, t_stop_rotation=t_rot, **s)
