"""Named, bounded model parameters and their least-squares bookkeeping, shared by ``fit``
and ``discover``.

One :class:`Param` describes a parameter wherever it is fitted: the paper's closed-form
fits (:mod:`curltrack.fit`, through lmfit with :func:`to_lmfit`), the joint model of
``discover`` (:data:`SHOT_MODEL`) and an effect's own parameters (the registry,
:mod:`curltrack.physics.effects`).  :func:`covariance` and :func:`bound_warnings` are
the one way both report uncertainties and parameters stuck at a bound.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Param:
    """One parameter: name, unit, default, bounds and finite-difference step.

    Attributes
    ----------
    name : str
        Contract name (units in the name where it has some).
    default : float, None or REQUIRED
        Value when not given; :data:`REQUIRED` if it must be given, None if optional.
    unit : str
        For messages and reports.
    null : float
        Value at which an effect vanishes (an effect's size parameters: the fit starts
        there).
    lower, upper : float or None
        Bounds in fits (None: unbounded).
    step : float or None
        Finite-difference step of a numerical Jacobian (None: relative 1e-4).
    """

    name: str
    default: object = None
    unit: str = ""
    null: float = 0.0
    lower: float | None = None
    upper: float | None = None
    step: float | None = None

    def bounds(self) -> tuple[float, float]:
        """(lower, upper) with None as -inf / inf."""
        return (-np.inf if self.lower is None else self.lower,
                np.inf if self.upper is None else self.upper)


REQUIRED = object()

#: the shot model's parameters as ``discover`` fits them: shared by the shots of a
#: session (friction laws, a_T) or per shot (launch, and the offsets of the measured frame)
SHOT_MODEL = {p.name: p for p in (
    Param("phi_y", lower=-3.0, upper=0.9, step=1e-4),
    Param("alpha_y", unit="(m/s)^-phi_y", lower=1e-6, upper=5.0),
    # (a draw's rotation: the paper's lambda_theta 1.20-1.50, phi_theta -4 to -1; at
    # phi_theta -3.5 alpha_theta is ~1e-7, at -5 ~1e-9 - bounds of -3 and 1e-6 held
    # clean draws at them, verdict unexplained)
    Param("phi_theta", lower=-10.0, upper=0.9, step=1e-4),
    Param("alpha_theta", unit="(m/s)^-phi_theta", lower=1e-15, upper=5.0),
    Param("a_T", unit="m/s^2", lower=0.0, upper=1.0, step=2e-6),
    Param("v0", unit="m/s", lower=0.0, upper=20.0, step=1e-5),
    Param("omega0", unit="rad/s", lower=-60.0, upper=60.0, step=1e-5),
    Param("x0", unit="m", lower=-1.0, upper=1.0, step=1e-5),
    Param("y0", unit="m", lower=-1.0, upper=1.0, step=1e-5),
    Param("theta0", unit="rad", lower=-1.0, upper=1.0, step=1e-5),
    Param("skew", unit="rad", lower=-0.5, upper=0.5, step=1e-5),
)}

#: the exponent lambda of the paper's closed forms q_F [1 - (1 - t/t_F)^lambda]
#: (lambda > 1: the rock stops; lambda = 1 is a constant speed up to an abrupt stop)
LAMBDA = Param("lambda", lower=1.0001, upper=6.0)
#: the deskew angle of the translation fit (rad)
DESKEW = Param("psi", unit="rad", lower=-0.5, upper=0.5)


def to_lmfit(params, spec: Param, name: str | None = None, value: float = 0.0,
             vary: bool = True, **bounds):
    """Add ``spec`` to lmfit ``params`` under ``name`` (default: its own) at ``value``.

    ``bounds`` (``min``, ``max``) override the spec's.
    """
    lo, hi = spec.bounds()
    params.add(name or spec.name, value=value, vary=vary,
               **{"min": lo, "max": hi, **bounds})
    return params


def covariance(J) -> np.ndarray:
    """(J^T J)^-1 of a whitened Jacobian, computed on unit-norm columns (parameters
    differ by 10 orders of magnitude in scale).

    Parameters that move along a direction the data do not determine (singular value
    below 1e-10 of the largest) get an infinite variance and NaN covariances; a failed
    decomposition gives NaN everywhere.
    """
    d = np.linalg.norm(J, axis=0)
    d = np.where(d > 0, d, 1.0)
    try:
        u, s, vt = np.linalg.svd(J / d, full_matrices=False)
    except np.linalg.LinAlgError:
        return np.full((J.shape[1],) * 2, np.nan)
    if s.size == 0:
        return np.zeros((J.shape[1],) * 2)
    ok = s > 1e-10 * s[0]
    c = (vt[ok].T / s[ok] ** 2) @ vt[ok]
    # parameters that move along a singular direction are not determined: infinite error
    loose = (vt[~ok] ** 2).sum(axis=0) > 1e-6
    c[loose, :] = np.nan
    c[:, loose] = np.nan
    c[loose, loose] = np.inf
    return c / d[:, None] / d[None, :]


def bound_warnings(items, label: str) -> list[str]:
    """Warnings for fitted parameters that ended at a bound.

    Parameters
    ----------
    items : iterable of (name, value, lower, upper)
        The varied parameters (None or inf: no bound on that side).
    label : str
        Which fit, for the message.
    """
    out = []
    for name, value, lo, hi in items:
        lo = -np.inf if lo is None else lo
        hi = np.inf if hi is None else hi
        span = (hi - lo) if np.isfinite(hi - lo) else abs(value) + 1.0
        if min(abs(value - lo), abs(hi - value)) < 1e-6 * span:
            out.append(f"{label} fit: parameter {name} = {value:.6g} is at its bound")
    return out
