"""One least-squares layer for ``fit`` and ``discover``: named, bounded parameters
(lmfit ``Parameters`` built from :class:`~curltrack.physics.params.Param` specs) ->
``lmfit`` solve -> one error mapping; the covariance and at-bound rules are
:func:`~curltrack.physics.params.covariance` and
:func:`~curltrack.physics.params.bound_warnings`.

``fit`` solves the paper's closed forms with Levenberg-Marquardt (``method="leastsq"``,
MINPACK, numerical Jacobian); ``discover`` solves the joint model of all shots with a
trust-region method inside the bounds and its own Jacobian (``method="least_squares"``,
``jac=``, ``max_nfev`` counted as SciPy counts function evaluations).  Both hand lmfit
their parameters by name and read the solution back by name; what is solved and how
the result is reported is their own.

Placed below ``fit`` and ``discover`` (imports only :mod:`curltrack.physics.params`
and :mod:`curltrack.errors`).
"""

from __future__ import annotations

import re

import lmfit
import numpy as np

from .errors import FitError
from .physics.params import Param, bound_warnings, covariance, to_lmfit

__all__ = ["lmfit_name", "parameters", "vector", "solve", "covariance", "bound_warnings"]


def lmfit_name(name: str) -> str:
    """A parameter name as lmfit accepts it (a Python identifier): ``"v0[2]"`` ->
    ``"v0_2_"``."""
    return re.sub(r"\W", "_", name)


def parameters(items) -> lmfit.Parameters:
    """lmfit ``Parameters`` from ``(name, spec, value)`` items, in that order.

    ``spec`` is a :class:`Param` (its bounds are used) or a ``(lower, upper)`` pair (None
    = unbounded); ``name`` may be any string (:func:`lmfit_name` makes it lmfit's).
    """
    params = lmfit.Parameters()
    for name, spec, value in items:
        if not isinstance(spec, Param):
            spec = Param(name, lower=spec[0], upper=spec[1])
        to_lmfit(params, spec, lmfit_name(name), float(value))
    return params


def vector(params, names) -> np.ndarray:
    """The values of ``names`` (their own spelling) in ``params``, as an array."""
    return np.array([params[lmfit_name(n)].value for n in names], dtype=float)


def solve(residual, params, method: str = "leastsq", label: str = "fit", path=None,
          max_nfev: int | None = None, jac=None, nan_policy: str = "raise", **solver_kws):
    """Minimise ``sum(residual(params)**2)`` over the varied ``params``.

    Parameters
    ----------
    residual : callable
        ``residual(params) -> (n,) array`` (whitened residuals).
    params : lmfit.Parameters
        Starting values and bounds (:func:`parameters`).
    method : {"leastsq", "least_squares"}
        Levenberg-Marquardt (MINPACK; ``max_nfev`` as lmfit counts it) or SciPy's
        trust-region reflective inside the bounds (``max_nfev`` as SciPy counts it).
    label : str
        Which fit, for messages (``"rotation fit"``, ``"model fit"``).
    path : optional
        Named in a :class:`FitError`.
    jac : callable, optional
        ``jac(params) -> (n, k)`` Jacobian of the residuals (``least_squares`` only).
    nan_policy : str
        lmfit's: "raise" stops at a NaN residual, "propagate" leaves it to the solver.
    **solver_kws
        Passed to the solver (``x_scale``, ``ftol``, ...).

    Returns
    -------
    lmfit.MinimizerResult

    Raises
    ------
    FitError
        The solver failed (the model left its domain, a singular step, ...).
    """
    if method not in ("leastsq", "least_squares"):
        raise ValueError(f"unknown method {method!r}")
    try:
        if method == "leastsq":
            return lmfit.minimize(residual, params, method="leastsq", max_nfev=max_nfev,
                                  nan_policy=nan_policy, **solver_kws)
        mini = lmfit.Minimizer(residual, params, nan_policy=nan_policy, **solver_kws)
        # SciPy's own max_nfev (lmfit's abort count, higher by default, is not reached)
        if max_nfev is not None:
            mini.kws["max_nfev"] = max_nfev
        if jac is not None:
            mini.kws["jac"] = jac
        return mini.least_squares()
    except (ValueError, FloatingPointError, ZeroDivisionError, np.linalg.LinAlgError) as exc:
        if "NaN" in str(exc):  # lmfit's long FAQ message: the model left its domain
            raise FitError(f"{label}: the fitted parameters are outside the model's range "
                           "(the model gave NaN)", path=path) from None
        raise FitError(f"{label} failed ({exc})".splitlines()[0], path=path) from None
