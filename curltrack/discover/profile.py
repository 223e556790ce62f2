"""Profile likelihood of an extension's parameters: the estimate and its honest error.

An extension's coefficient shares a curved valley with the friction laws (a spin
coupling with phi_theta, a friction law's bend with phi_y).  There the joint fit stops on
the valley's floor short of the minimum (its trust region shrinks to steps below xtol),
and the covariance from the Jacobian, which assumes a quadratic bowl, understates the
error along the valley: one spin coupling was reported as -0.1390 +- 0.0004 for a true
-0.15, and holding it at +-0.008 from there (everything else refitted) lowered the
chi-square by 32.  Half the extension cases had the truth outside 2 sigma.

Here each of the extension's parameters is held at a few values, everything else is
refitted (a well-conditioned problem once the valley's direction is held), and a
parabola through the profile's chi-square walks to its minimum; the error is where the
profile rises by one unit of the candidate's own noise, measured on both sides and
taken from the flatter one.  When the profile's minimum beats the fit, the joint fit is
restarted from there.
"""

from __future__ import annotations

import copy

import numpy as np

from ..errors import CurltrackError

#: first offsets of the profile in units of the covariance's sigma
FIRST_STEP = 2.0
#: parabola steps towards the profile's minimum
MAX_STEPS = 4
#: a step never goes further than this many times the spread of the points so far
MAX_REACH = 4.0
#: iterations of each profile refit (warm-started at the nearest point already fitted)
PROFILE_NFEV = 15
#: chi-square by which the profile must beat the fit before the fit is restarted
MOVE_CHI2 = 0.5


class _Profile:
    """chi-square of one parameter held at values, everything else refitted."""

    def __init__(self, model, fit, name, scale):
        self.model, self.name, self.scale = model, name, scale
        self.free = [f for f in fit.free if f != name]
        self.points = {float(fit.values[name]): (self.chi2(fit), dict(fit.values))}
        # the valley's direction in the covariance: how the others move per unit of
        # ``name`` (the Gaussian conditional mean), so each refit starts on the valley
        # floor instead of crawling to it
        i = fit.free.index(name)
        c = np.where(np.isfinite(fit.cov[:, i]), fit.cov[:, i], 0.0)
        self.slope = {f: float(c[k] / c[i]) if c[i] > 0 else 0.0
                      for k, f in enumerate(fit.free) if f != name}

    def chi2(self, fit) -> float:
        return float(np.sum((fit.r * self.scale) ** 2))

    def at(self, value: float) -> float:
        value = float(value)
        if value in self.points:
            return self.points[value][0]
        near = min(self.points, key=lambda q: abs(q - value))
        m = copy.copy(self.model)
        m.values = dict(self.points[near][1])
        m.values[self.name] = value
        for f, k in self.slope.items():
            lo, hi = self.model.bounds.get(f, (None, None))
            v = m.values[f] + k * (value - near)
            if _inside(v, lo, hi):
                m.values[f] = v
        m.free = list(self.free)
        m.bounds = dict(self.model.bounds)
        try:
            f = m.fit(max_nfev=PROFILE_NFEV, tol=1e-8)
        except CurltrackError:
            return np.inf
        self.points[value] = (self.chi2(f), dict(f.values))
        return self.points[value][0]

    def best(self) -> float:
        return min(self.points, key=lambda q: self.points[q][0])


def _inside(v, lo, hi) -> bool:
    return (lo is None or v > lo) and (hi is None or v < hi)


def _parabola_vertex(points: dict, around: float):
    """Vertex and curvature (chi2 = a (q - q_v)^2 + c) through the 3 points nearest
    ``around`` (None when they do not bracket a minimum)."""
    qs = sorted(points, key=lambda q: abs(q - around))[:3]
    if len(qs) < 3:
        return None, None
    x = np.array(qs)
    y = np.array([points[q][0] for q in qs])
    if not np.isfinite(y).all():
        return None, None
    a, b, _ = np.polyfit(x - around, y, 2)
    if a <= 0:
        return None, None
    return around - b / (2 * a), a


def profile_parameter(model, fit, name, scale, unit):
    """Walk the profile of ``name`` to its minimum and measure its width.

    Returns
    -------
    dict or None
        ``value`` (the profile's minimum), ``sigma`` (where the profile rises by
        ``unit``, flatter side), ``sigma_cov``, ``shift`` (chi-square by which the
        minimum beats the fit), ``values`` (every parameter at the minimum) and
        ``n_points`` (profile refits); None when the covariance gives no error to start.
    """
    s0 = fit.err(name)
    if not (np.isfinite(s0) and s0 > 0):
        return None
    lo, hi = model.bounds.get(name, (None, None))
    prof = _Profile(model, fit, name, scale)
    q0 = float(fit.values[name])
    chi0 = prof.points[q0][0]
    for v in (q0 - FIRST_STEP * s0, q0 + FIRST_STEP * s0):
        if _inside(v, lo, hi):
            prof.at(v)
    for _ in range(MAX_STEPS):
        qb = prof.best()
        spread = max(prof.points) - min(prof.points)
        qv, _ = _parabola_vertex(prof.points, qb)
        if qv is None:   # no minimum bracketed: step downhill
            others = [q for q in prof.points if q != qb]
            if not others:  # (both first steps outside the bounds: nothing to walk on)
                break
            qv = qb + (qb - min(others, key=lambda q: abs(q - qb)))
        qv = float(np.clip(qv, qb - MAX_REACH * spread, qb + MAX_REACH * spread))
        if not _inside(qv, lo, hi) or abs(qv - qb) < 0.1 * s0:
            break
        prof.at(qv)
    qb = prof.best()
    _, a = _parabola_vertex(prof.points, qb)
    sig = max(float(np.sqrt(unit / a)) if a else FIRST_STEP * s0, s0)
    # the width where it is measured, from the flatter side: each side's nearest point
    # within reach says sigma = distance / sqrt(rise); a side with none is evaluated
    widths = []
    for sg in (-1.0, 1.0):
        side = [q for q in prof.points if sg * (q - qb) > 0 and abs(q - qb) <= 4.0 * sig]
        if not side and _inside(qb + sg * sig, lo, hi):
            prof.at(qb + sg * sig)
            side = [qb + sg * sig]
        if side:
            q = min(side, key=lambda v: abs(v - qb))
            rise = prof.points[q][0] - prof.points[qb][0]
            if np.isfinite(rise):
                widths.append(abs(q - qb) / np.sqrt(max(rise, 1e-3 * unit) / unit))
    if widths:
        spread = max(prof.points) - min(prof.points)
        sig = float(np.clip(max(widths), s0, 10.0 * spread + s0))
    return {"value": qb, "sigma": sig, "sigma_cov": float(s0),
            "shift": float(chi0 - prof.points[qb][0]), "values": prof.points[qb][1],
            "n_points": len(prof.points) - 1}


def profile_errors(model, fit, names, scale) -> dict:
    """Profile each of ``names`` (the extension's parameters) in turn.

    Parameters
    ----------
    model : JointModel
        The candidate's model (baseline + extension) as fitted.
    fit : FitOut
        Its fit.
    names : list of str
    scale : (n,) array
        Per-residual factor of the candidate's own noise (1 / sqrt(inflation), see
        :func:`.search.rescore`): chi-square differences are measured in its units; a
        misfit beyond it (reduced chi-square > 1) widens the interval.

    Returns
    -------
    dict
        name -> :func:`profile_parameter`'s result.
    """
    chi0 = float(np.sum((fit.r * scale) ** 2))
    unit = max(1.0, chi0 / max(fit.n - fit.k, 1))
    out = {}
    for name in names:
        if name in fit.free:
            res = profile_parameter(model, fit, name, scale, unit)
            if res is not None:
                out[name] = res
    return out


def corrected_cov(fit, errors: dict) -> np.ndarray:
    """``fit.cov`` with the profiled parameters' rows and columns rescaled to their
    profile sigma (correlations kept): for the delta-method band of the fitted function."""
    d = np.ones(len(fit.free))
    for name, e in errors.items():
        if name in fit.free:
            d[fit.free.index(name)] = e["sigma"] / max(e["sigma_cov"], 1e-300)
    return fit.cov * d[:, None] * d[None, :]
