"""The paper's analysis of one shot: closed-form fits and derived physics, with 1σ errors.

Three Levenberg–Marquardt fits (lmfit, ``leastsq``) on the measured rows (``ok`` = 1):

* rotation:  theta(t) = theta0 + theta_F [1 - (1 - t/t_Ftheta)^lambda_theta]
* translation, joint in x and y, with the deskew angle:
  (x, y) = (x0, y0) + Rot(psi) (X(t), Y(t)),
  Y = y_F [1 - (1 - t/t_FS)^lambda_y],  X = the paper's curl x(t) with a constant a_T and
  lambda = lambda_y (as in the paper) — and again with lambda free (``lambda_x``).

``t_F`` is fitted jointly by default (a detected stop is typically a few frames early,
which biases lambda by ~0.01); ``fixed_stop=True`` holds it at the sidecar's stop time,
as the paper did.  With ``t_F`` free the rows up to the detected stop + ``STOP_MARGIN_S``
are used so that the fitted stop is constrained from both sides; with it fixed, rows with
0 <= t <= t_F.  The offsets (theta0, x0, y0) absorb the uncertainty of the series'
origin, which is itself estimated from noisy frames.

Derived quantities (phi, alpha, omega0, v0, C_omega, C_y, x_F, ...) are computed by the
formulas of :mod:`curltrack.physics.closed_form` on correlated ``uncertainties`` values
built from each fit's covariance, so their errors are propagated, not guessed.

Shot type (documented rule, in this order):

* ``pure_rotation``: the rock's centre moves less than ``PURE_ROTATION_MAX_TRAVEL_M``
  (0.10 m, a third of its diameter) over the whole series;
* ``rrss`` (rapid rotation, slow sliding): the running band's initial rotation speed
  exceeds the initial translation speed, r |omega0| > v0;
* ``draw``: otherwise (r |omega0| <= v0, translation dominates).
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field

import lmfit
import numpy as np
import pandas as pd
from uncertainties import UFloat

from . import __version__
from ._stats import value_at_zero
from .errors import FitError, SeriesError
from .physics import closed_form as cf
from .fitting import solve
from .physics.params import DESKEW, LAMBDA, bound_warnings, to_lmfit
from .rig import Rig, default_rig
from .sanity import check_units, late_stop_warning
from .series import Series, sample_index, series_stops
from .series.noise import row_sigma

PURE_ROTATION_MAX_TRAVEL_M = 0.10
STOP_MARGIN_S = 0.5
MIN_POINTS = 12
#: Rotation smaller than this (rad) is "no spin": theta is not fitted.
MIN_ROTATION_RAD = 0.2

FIT_KEYS = (
    "shot_type", "skew_deg", "t_FS", "t_Ftheta", "theta_F", "lambda_theta", "omega0",
    "phi_theta", "alpha_theta", "y_F", "lambda_y", "v0", "phi_y", "alpha_y", "x_F", "a_T",
    "a_T_free", "lambda_x", "x_F_free", "x_stop", "n_turns", "C_omega", "C_y", "rms_x",
    "rms_y", "rms_theta", "n_points",
)
#: keys that carry no uncertainty
_NO_ERR = {"shot_type", "rms_x", "rms_y", "rms_theta", "n_points", "x_stop"}


@dataclass(frozen=True)
class FitResult:
    """Result of :func:`fit_series`: flat values, 1σ errors, fit diagnostics.

    Attributes
    ----------
    values : dict
        FIT.json keys (contract) -> value (None where it does not apply).
    errors : dict
        key -> 1σ uncertainty (same units), for every fitted or derived quantity.
    warnings : tuple of str
    fits : dict
        name -> lmfit.MinimizerResult (``"theta"``, ``"xy"``, ``"xy_free"``).
    extra : dict
        FIT.json's further keys (detected stops, radii, reduced chi-squares).

    Examples
    --------
    >>> res = fit_series(read_series("SHOT.csv"))            # doctest: +SKIP
    >>> res.values["lambda_y"], res.errors["lambda_y"]       # doctest: +SKIP
    >>> res.summary()["lambda_y_err"]                        # doctest: +SKIP
    """

    values: dict
    errors: dict
    warnings: tuple = ()
    fits: dict = field(default_factory=dict, compare=False, repr=False)
    extra: dict = field(default_factory=dict)

    @property
    def success(self) -> bool:
        """Every sub-fit converged (a failed one raises :class:`FitError`)."""
        return all(r.success for r in self.fits.values())

    @property
    def message(self) -> str:
        """The sub-fits' messages, one line."""
        return "; ".join(f"{k}: {r.message}" for k, r in self.fits.items())

    @property
    def bic(self) -> dict:
        """BIC of each sub-fit (lmfit's, from its weighted chi-square)."""
        return {k: float(r.bic) for k, r in self.fits.items()}

    @property
    def covar(self) -> dict:
        """Covariance matrix of each sub-fit's varied parameters (``fits[k].var_names``)."""
        return {k: r.covar for k, r in self.fits.items()}

    def summary(self) -> dict:
        """The FIT.json mapping: every key, its ``_err``, extras, warnings, version."""
        out = {}
        for k in FIT_KEYS:
            out[k] = _plain(self.values.get(k))
            if k not in _NO_ERR:
                out[f"{k}_err"] = _plain(self.errors.get(k))
        out.update({k: _plain(v) for k, v in self.extra.items()})
        out["warnings"] = list(self.warnings)
        out["version"] = __version__
        return out

    to_dict = summary

    def report(self) -> str:
        """A short human-readable summary."""
        lines = [f"shot type: {self.values.get('shot_type')}"]
        for k in FIT_KEYS[1:]:
            v = self.values.get(k)
            if v is None or isinstance(v, str):
                continue
            e = self.errors.get(k)
            lines.append(f"  {k:>14s} = {v:.6g}" + (f" ± {e:.2g}" if e is not None else ""))
        lines += [f"warning: {w}" for w in self.warnings]
        return "\n".join(lines)


def _plain(v):
    if v is None or isinstance(v, str):
        return v
    if isinstance(v, (int, np.integer)):
        return int(v)
    v = float(v)
    return v if math.isfinite(v) else None


# ---------------------------------------------------------------------------------------
# residual models

def _theta_model(p, t):
    return p["theta0"] + cf.decel_position(t, p["theta_F"], p["lambda_theta"], p["t_Ftheta"])


#: samples of the path-shortening integral over 0..t_F (its error is < 1e-3 of itself)
_PATH_GRID = 401


def shot_frame_model(p, t):
    """(X, Y) of the translation fit in the deskewed frame (no offset, no rotation).

    The paper's y(t) is the distance travelled along the path; the curl turns the path
    by the heading h = X'/Y', so the rock gets less far along the sheet by
    ``int (1 - cos h) dY ~ int X'^2 / (2 Y') dt`` (second order in h).  That is a few
    mm to cm for a draw that curls ~1 m, and leaving it out biased lambda_y by 3-5
    sigma at 2 mm noise on simulated draws; X needs no correction at this order.
    """
    lam_x = p["lambda_x"] if "lambda_x" in p else p["lambda_y"]
    t_F = p["t_FS"]
    X = cf.curl_position(t, p["a_T"], lam_x, t_F)
    Y = cf.decel_position(t, p["y_F"], p["lambda_y"], t_F)
    tg = np.linspace(0.0, t_F, _PATH_GRID)
    dX = np.gradient(cf.curl_position(tg, p["a_T"], lam_x, t_F), tg)
    dY = cf.decel_rate(tg, p["y_F"], p["lambda_y"], t_F)
    with np.errstate(divide="ignore", invalid="ignore"):
        f = np.where(np.abs(dY) > 0, dX * dX / (2.0 * dY), 0.0)
    short = np.concatenate([[0.0], np.cumsum(0.5 * (f[1:] + f[:-1]) * np.diff(tg))])
    return X, Y - np.interp(t, tg, short)


def deskew(p, x, y):
    """Measured (x, y) -> the deskewed frame of fit parameters ``p`` (offsets removed)."""
    c, s = math.cos(p["psi"]), math.sin(p["psi"])
    dx, dy = np.asarray(x) - p["x0"], np.asarray(y) - p["y0"]
    return c * dx + s * dy, -s * dx + c * dy


def _xy_model(p, t):
    X, Y = shot_frame_model(p, t)
    c, s = math.cos(p["psi"]), math.sin(p["psi"])
    return p["x0"] + c * X - s * Y, p["y0"] + s * X + c * Y


def _values(params: lmfit.Parameters) -> dict:
    return {k: v.value for k, v in params.items()}


def _minimize(resid, params, name, path):
    """Levenberg-Marquardt through the one least-squares layer (:func:`..fitting.solve`)."""
    with np.errstate(all="ignore"):  # trial steps may overflow; judged by the result
        res = solve(resid, params, "leastsq", label=f"{name} fit", path=path, max_nfev=4000)
    if not res.success:
        raise FitError(f"{name} fit did not converge ({res.message})", path=path)
    if not res.errorbars or res.covar is None:
        # MINPACK can stop at an exact optimum without a covariance (noise-free data);
        # a trust-region pass from there computes it from the Jacobian's SVD.
        try:
            with np.errstate(all="ignore"):
                res = solve(resid, res.params, "least_squares", label=f"{name} fit",
                            path=path)
        except FitError:
            pass
    if not res.errorbars or res.covar is None:
        raise FitError(f"{name} fit converged but its uncertainties could not be estimated "
                       "(parameters degenerate or at a bound)", path=path)
    return res


def _at_bound_warnings(res, name) -> list[str]:
    return bound_warnings(((k, p.value, p.min, p.max) for k, p in res.params.items()
                           if p.vary), name)


# ---------------------------------------------------------------------------------------
# the fits

def _window(t, t_stop, fixed_stop, name, coord, path, warnings):
    """Rows used for a fit and the (initial) t_F with its bounds."""
    t_last = float(t[-1])
    if t_stop is None:
        if fixed_stop:
            raise FitError(f"the rock never stopped in {coord} within the series "
                           "(no stop time); --fixed-stop needs one", path=path)
        # (no rows at rest after the stop - or none at all: the rock may have stopped
        # at the series' last rows, as an instrument that stops recording with the rock
        # does; a bound at the last row held t_F there, with lambda_y 4 sigma off)
        warnings.append(f"{name}: no stop within the series (no rows at rest after it); "
                        "t_F is fitted from the motion alone, extrapolated where it lies "
                        "beyond the last row")
        use = t >= 0
        return use, 1.05 * t_last, (0.5 * t_last, 20.0 * t_last + 1.0)
    t_stop = float(t_stop)
    if t_stop <= float(t[0]):
        raise FitError(f"{coord} fit: the stop time (t = {t_stop:g} s) is at the start of "
                       "the series although the rock moves; the series does not look like "
                       "a shot", path=path)
    if fixed_stop:
        return (t >= 0) & (t <= t_stop), t_stop, None
    use = (t >= 0) & (t <= t_stop + STOP_MARGIN_S)
    return use, t_stop, (0.5 * t_stop, t_stop + 2.0 * STOP_MARGIN_S + 1.0)


def _check_points(n, need, what, path):
    if n < max(MIN_POINTS, need + 3):
        raise FitError(f"too few measured points for the {what} fit ({n}; need at least "
                       f"{max(MIN_POINTS, need + 3)})", path=path)


def fit_rotation(t, theta, t_stop, fixed_stop=False, sigma=None, path=None, warnings=None):
    """Fit theta(t) = theta0 + theta_F [1 - (1 - t/t_F)^lambda].

    Parameters
    ----------
    t, theta : ndarray
        Times (s) and cumulative angles (rad) of the measured rows.
    t_stop : float or None
        Detected rotation stop (s).
    fixed_stop : bool
        Hold t_F at ``t_stop``.
    sigma : float or ndarray, optional
        Noise (rad) of every row, or one for all, used to weight the residuals (the
        covariance is scaled by the reduced chi-square in any case).

    Returns
    -------
    lmfit.MinimizerResult
    """
    warnings = [] if warnings is None else warnings
    use, tF, bounds = _window(t, t_stop, fixed_stop, "rotation", "rotation", path, warnings)
    tt, qq = t[use], theta[use]
    _check_points(len(tt), 4 - fixed_stop, "rotation", path)
    sigma = _row_weights(sigma, t)[use]
    p = lmfit.Parameters()
    q_end = float(np.median(qq[-3:]))
    p.add("theta_F", value=q_end if abs(q_end) > 1e-6 else 1e-3)
    to_lmfit(p, LAMBDA, "lambda_theta", 1.6)
    p.add("t_Ftheta", value=tF, vary=bounds is not None,
          **({} if bounds is None else dict(min=bounds[0], max=bounds[1])))
    p.add("theta0", value=0.0)
    res = _minimize(lambda pp: (_theta_model(pp, tt) - qq) / sigma, p, "rotation", path)
    res.raw_residual = _theta_model(res.params, tt) - qq   # rad
    return res


def fit_translation(t, x, y, t_stop, fixed_stop=False, free_lambda=False, sigma=None,
                    path=None, warnings=None, start=None):
    """Joint fit of x(t), y(t) with deskew angle ``psi`` (rad).

    ``free_lambda`` adds ``lambda_x`` (the curl's own exponent) instead of tying it to
    lambda_y.  ``start`` (dict) gives starting values, e.g. the tied fit's.  ``sigma``:
    the noise (m) of x and of y, each one value or one per row.
    """
    warnings = [] if warnings is None else warnings
    use, tF, bounds = _window(t, t_stop, fixed_stop, "translation", "translation", path,
                              warnings)
    tt, xx, yy = t[use], x[use], y[use]
    _check_points(len(tt), 7 + free_lambda - fixed_stop, "translation", path)
    s_x, s_y = (_row_weights(s, t)[use] for s in (sigma if sigma is not None else (None, None)))
    # (the series may be measured from any origin: the start is the rock at t = 0 - a
    # quadratic through the first second, extrapolated - not (0, 0); from (0, 0) a shot
    # 30 m off and turned 9 deg converged to v0 = -0.0006 m/s and was refused)
    x_o, y_o = value_at_zero(tt, xx), value_at_zero(tt, yy)
    y_end = float(np.median(yy[-3:])) - y_o
    x_end = float(np.median(xx[-3:])) - x_o
    start = dict(start or {})
    p = lmfit.Parameters()
    p.add("y_F", value=start.get("y_F", y_end if abs(y_end) > 1e-6 else 1e-3))
    to_lmfit(p, LAMBDA, "lambda_y", start.get("lambda_y", 1.9))
    p.add("t_FS", value=start.get("t_FS", tF), vary=bounds is not None,
          **({} if bounds is None else dict(min=bounds[0], max=bounds[1])))
    p.add("a_T", value=start.get("a_T", 2.0 * 1.9 * x_end / tF**2))
    if free_lambda:
        to_lmfit(p, LAMBDA, "lambda_x", start.get("lambda_x", start.get("lambda_y", 1.9)))
    to_lmfit(p, DESKEW, value=start.get("psi", 0.0))
    p.add("x0", value=start.get("x0", x_o))
    p.add("y0", value=start.get("y0", y_o))

    def resid(pp):
        mx, my = _xy_model(pp, tt)
        return np.concatenate([(mx - xx) / s_x, (my - yy) / s_y])

    name = "translation (lambda free)" if free_lambda else "translation"
    res = _minimize(resid, p, name, path)
    mx, my = _xy_model(res.params, tt)
    res.raw_residual = np.concatenate([mx - xx, my - yy])   # m: x rows, then y rows
    res.row_sigma = np.concatenate([s_x, s_y])               # the rows' weights (m or 1)
    return res


def classify(travel_m: float, v0: float | None, omega0: float | None, r: float) -> str:
    """Shot type by the module's documented rule."""
    if travel_m < PURE_ROTATION_MAX_TRAVEL_M or v0 is None:
        return "pure_rotation"
    if omega0 is not None and r * abs(omega0) > abs(v0):
        return "rrss"
    return "draw"


def _nominal(u):
    return None if u is None else float(getattr(u, "nominal_value", u))


def _stderr(u):
    """1σ of an ``uncertainties`` value; None for a plain number or when it overflows."""
    if u is None:
        return None
    with np.errstate(over="ignore", invalid="ignore"):
        s = getattr(u, "std_dev", None)
    return None if s is None or not math.isfinite(s) else float(s)


def fit_series(series: Series, rig: Rig | None = None, fixed_stop: bool = False) -> FitResult:
    """The paper's fits and derived quantities for one shot.

    Parameters
    ----------
    series : Series
        A validated series (see :func:`curltrack.series.read_series`).
    rig : Rig, optional
        Supplies R (``inertia_radius_m``) and r (``band_radius_m``); contract defaults.
    fixed_stop : bool
        Hold t_F at the sidecar's (or detected) stop times, as the paper did.

    Returns
    -------
    FitResult

    Raises
    ------
    FitError
        Too few points, a fit that does not converge, or no stop with ``fixed_stop``.

    Examples
    --------
    >>> from curltrack import ShotModel, fit_series, simulate_series
    >>> series = simulate_series(ShotModel(v0=2.0, omega0=1.5), noise_m=0.002,
    ...                          noise_rad=0.005, seed=1)
    >>> res = fit_series(series)
    >>> round(res.values["lambda_y"], 2), res.values["shot_type"]
    (1.84, 'draw')
    """
    rig = rig or default_rig()
    R, r = rig.inertia_radius_m, rig.band_radius_m
    path = series.name
    warnings = list(series.meta.get("warnings", []))
    warnings += check_units(series)  # units and conventions (raises on a unit mistake)
    d = series.measured
    d = d[d["t"] >= 0]
    if len(d) < MIN_POINTS:
        raise FitError(f"too few measured points ({len(d)}; need at least {MIN_POINTS})",
                       path=path, where=f"rows 2-{len(series.data) + 1}")
    t = d["t"].to_numpy(float)
    x, y, th = (d[c].to_numpy(float) for c in ("x", "y", "theta"))
    has_theta = np.isfinite(th)
    if not series.theta_measured or not has_theta.any():
        warnings.append(f"{path}: theta not measured (position-only series); translation "
                        "fits only")
        has_theta[:] = False
    t_tr, t_rot, stop_warnings = series_stops(series)
    warnings += stop_warnings
    if not has_theta.any():
        t_rot = None

    vals: dict = {k: None for k in FIT_KEYS}
    errs: dict = {}
    fits: dict = {}
    u: dict = {}

    # turn and travel from the first measured row: a constant offset in theta is no spin
    tq, thq = t[has_theta], th[has_theta]
    spin = float(np.max(np.abs(thq - thq[0]))) if tq.size else 0.0
    travel = float(np.nanmax(np.hypot(x - x[0], y - y[0])))
    if spin < MIN_ROTATION_RAD and travel < PURE_ROTATION_MAX_TRAVEL_M:
        turn = f"turn {spin:.3g} rad < {MIN_ROTATION_RAD:g} rad" if tq.size else \
            "theta not measured"
        raise FitError(f"nothing to fit: the rock does not move (travel {travel:.3g} m < "
                       f"{PURE_ROTATION_MAX_TRAVEL_M:g} m, {turn})", path=path)
    derive = _Deriver(u, warnings, path)

    # --- rotation
    if spin >= MIN_ROTATION_RAD:
        s_th = _noise_rows(d[has_theta], "sigma_theta", "theta", tq, thq, t_rot, path)
        res = fit_rotation(tq, thq, t_rot, fixed_stop, s_th, path, warnings)
        res = _honest_errors(res, s_th, [tq], "rotation", "theta", path, warnings)
        fits["theta"] = res
        warnings += _at_bound_warnings(res, "rotation")
        uv = res.uvars
        u["theta_F"], u["lambda_theta"] = uv["theta_F"], uv["lambda_theta"]
        u["t_Ftheta"] = uv["t_Ftheta"] if "t_Ftheta" in uv else res.params["t_Ftheta"].value
        derive("omega0", cf.initial_rate, "theta_F", "lambda_theta", "t_Ftheta")
        spin_sign = math.copysign(1.0, res.params["theta_F"].value)
        derive("n_turns", lambda q: spin_sign * q / (2 * math.pi), "theta_F")
        vals["rms_theta"] = _rms(res.raw_residual)
    elif tq.size:
        warnings.append(f"{path}: the rock turns less than {MIN_ROTATION_RAD} rad; "
                        "rotation not fitted")

    # --- translation
    if travel >= PURE_ROTATION_MAX_TRAVEL_M:
        # x and y of one position share their noise: the larger level weighs both
        s_x, s_y = (_noise_rows(d, "sigma_xy", c, t, q, t_tr, path)
                    for c, q in (("x", x), ("y", y)))
        s_xy = (None, None) if s_x is None or s_y is None else (np.maximum(s_x, s_y),) * 2
        omega = _nominal(u["omega0"]) if u.get("omega0") is not None else None
        tied = fit_translation(t, x, y, t_tr, fixed_stop, False, s_xy, path, warnings)
        exact = _closed_form_refit(tied, t, t_tr, fixed_stop, False, omega, path)
        tied = _honest_errors(tied, s_xy, [t, t], "translation", "x, y", path, warnings,
                              hint=None if has_theta.any() else _curl_end_hint,
                              expected=_expected_residual(tied, exact))
        tied = _approximation_error(tied, exact)
        fits["xy"] = tied
        try:
            free = fit_translation(t, x, y, t_tr, fixed_stop, True, s_xy, path, warnings,
                                   start=_values(tied.params))
            free = _honest_errors(free, s_xy, [t, t], None, "x, y", path, [])
            free = _approximation_error(
                free, _closed_form_refit(free, t, t_tr, fixed_stop, True, omega, path))
            fits["xy_free"] = free
        except FitError as exc:  # a secondary fit: its keys are null, the rest stands
            free = None
            warnings.append(f"{exc}; a_T_free, lambda_x and x_F_free are null")
        warnings += _at_bound_warnings(tied, "translation")
        uv = tied.uvars
        u["y_F"], u["lambda_y"], u["a_T"] = uv["y_F"], uv["lambda_y"], uv["a_T"]
        u["t_FS"] = uv["t_FS"] if "t_FS" in uv else tied.params["t_FS"].value
        u["skew_deg"] = -uv["psi"] * 180.0 / math.pi
        derive("v0", cf.initial_rate, "y_F", "lambda_y", "t_FS")
        if u["v0"] is not None and _nominal(u["v0"]) <= 0:
            raise FitError(f"the fitted parameters are outside the model's range: v0 = "
                           f"{_nominal(u['v0']):.3g} m/s, the rock would move against +y, the "
                           "series' direction of travel", path=path)
        derive("phi_y", cf.phi_from_lambda, "lambda_y")
        derive("alpha_y", cf.alpha_translation, "v0", "phi_y", "t_FS")
        derive("x_F", cf.curl_distance, "a_T", "lambda_y", "t_FS")
        if free is not None:
            uf = free.uvars
            u["a_T_free"], u["lambda_x"] = uf["a_T"], uf["lambda_x"]
            tfs_free = uf["t_FS"] if "t_FS" in uf else free.params["t_FS"].value
            derive("x_F_free", lambda a, lam: cf.curl_distance(a, lam, tfs_free),
                   "a_T_free", "lambda_x")
        m = tied.raw_residual.size // 2
        vals["rms_x"] = _rms(tied.raw_residual[:m])
        vals["rms_y"] = _rms(tied.raw_residual[m:])
        vals["x_stop"] = _x_stop(t, x, y, tied.params, t_tr)

    shot = classify(travel, _nominal(u.get("v0")), _nominal(u.get("omega0")), r)
    vals["shot_type"] = shot
    if "lambda_theta" in u and "lambda_y" in u:
        if shot == "draw":
            derive("C_omega", lambda lt, ly: cf.c_omega(lt, ly, R, r), "lambda_theta", "lambda_y")
        elif shot == "rrss":
            derive("C_y", lambda lt, ly: cf.c_y(lt, ly, R, r), "lambda_theta", "lambda_y")
    if "lambda_theta" in u and shot != "draw":
        # the paper derives phi, alpha from rotation only when translation does not dominate
        derive("phi_theta", cf.phi_from_lambda, "lambda_theta")
        derive("alpha_theta", lambda w, phi, tf: cf.alpha_rotation(spin_sign * w, phi, tf, R, r),
               "omega0", "phi_theta", "t_Ftheta")
    for k, v in u.items():
        vals[k] = _nominal(v)
        errs[k] = _stderr(v)
    vals["n_points"] = int(len(t))
    warnings += late_stop_warning(vals.get("t_FS"), path)
    extra = {
        "t_FS_detected": t_tr, "t_Ftheta_detected": t_rot, "fixed_stop": bool(fixed_stop),
        "R_m": R, "r_m": r,
        "chisqr_reduced_theta": fits["theta"].redchi if "theta" in fits else None,
        "chisqr_reduced_xy": fits["xy"].redchi if "xy" in fits else None,
        "theta_measured": bool(has_theta.any()),
        **{f"error_inflation_{k}": getattr(fits[k], "error_inflation", None)
           for k in ("theta", "xy") if k in fits},
    }
    return FitResult(vals, errs, tuple(dict.fromkeys(warnings)), fits, extra)


class _Deriver:
    """Derive ``u[key] = func(u[a], u[b], ...)`` where the fitted values allow it.

    A fit that converged may still sit where a derived quantity has no finite real value:
    alpha when lambda is at its lower bound (constant speed, then an abrupt stop), so
    phi -> -inf and v0^(1-phi) over- or underflows.  Then the quantity is reported as null (None)
    with a warning naming it and its inputs, rather than as an internal error or a NaN.
    """

    def __init__(self, u: dict, warnings: list, path):
        self.u, self.warnings, self.path = u, warnings, path

    def __call__(self, key, func, *names):
        args = [self.u.get(n) for n in names]
        missing = [n for n, a in zip(names, args) if a is None]
        if missing:
            return self._null(key, f"needs {', '.join(missing)}, which could not be derived")
        try:
            with np.errstate(all="raise"):
                value = func(*args)
        except OverflowError:
            return self._null(key, f"too large to represent ({self._inputs(names, args)})")
        except (ValueError, ZeroDivisionError, FloatingPointError):
            return self._null(key, f"no finite real value ({self._inputs(names, args)})")
        nominal = _nominal(value)
        if not math.isfinite(nominal):
            return self._null(key, f"no finite real value ({self._inputs(names, args)})")
        if abs(nominal) < sys.float_info.min:  # underflow: none of these is 0 analytically
            return self._null(key, f"too small to represent ({self._inputs(names, args)})")
        if isinstance(value, UFloat) and _stderr(value) is None:
            self.warnings.append(f"{self.path}: the uncertainty of {key} could not be "
                                 f"propagated ({self._inputs(names, args)}); reported as null")
        self.u[key] = value
        return value

    def _null(self, key, reason):
        self.u[key] = None
        self.warnings.append(f"{self.path}: {key} cannot be derived from the fitted "
                             f"parameters: {reason}; reported as null")

    @staticmethod
    def _inputs(names, args) -> str:
        return ", ".join(f"{n} = {_nominal(a):.4g}" for n, a in zip(names, args))


#: a fit whose residuals scatter more than this many times the measured frame-to-frame
#: noise (reduced chi-square) and stay correlated over more than MISFIT_TAU samples is a
#: misfit (or an instrument whose errors persist): warned, and pointed to ``discover``
MISFIT_REDCHI = 4.0
MISFIT_TAU = 3.0


def correlation_time(r) -> float:
    """Integrated autocorrelation time of ``r`` (samples): 1 + 2 sum of its
    autocorrelations up to the first that is not significant (below
    max(0.05, 2 / sqrt(n))); 1 for white residuals.

    Least-squares errors assume independent residuals; with correlated ones the
    effective number of points is n / tau, so the 1-sigma errors grow by sqrt(tau).
    """
    r = np.asarray(r, dtype=float)
    r = r - r.mean()
    n = r.size
    if n < 8 or not np.any(r):
        return 1.0
    f = np.fft.rfft(r, 2 * n)
    acf = np.fft.irfft(f * np.conj(f))[: n // 4] / float(r @ r)
    below = np.flatnonzero(acf[1:] < max(0.05, 2.0 / np.sqrt(n)))  # significant lags only
    m = int(below[0]) if below.size else acf.size - 1
    return float(max(1.0, 1.0 + 2.0 * acf[1:m + 1].sum()))


def small_sample_factor(n: int, p: int, tau: float) -> float:
    """Variance factor for errors estimated from few effective points (``tau`` > 1).

    With residuals correlated over ``tau`` samples the ``n`` rows hold ``n / tau``
    independent points.  Two small-sample effects then make the scaled covariance too
    small: the ``p`` fitted parameters absorb ~``p tau`` rows' worth of the (low-
    frequency) noise, so the residuals' scatter underestimates it by ``(n - p tau) /
    (n - p)``; and an error estimated with ``nu = n / tau - p`` degrees of freedom gives
    Student-t, not normal, pulls (variance ``nu / (nu - 2)``).  Both are undone here
    (capped at 3 each when ``nu`` is tiny).  1 for independent residuals.

    Measured on 10 Hz position-only draws under step-like instrument noise (issue 18):
    the std of (fitted - true) / sigma of lambda_y was 1.47 without, 1.14 with.
    """
    if tau <= 1.0 or n <= p:
        return 1.0
    absorbed = min((n - p) / max(n - p * tau, 1e-9), 3.0)
    nu = n / tau - p
    student = nu / (nu - 2.0) if nu > 3.0 else 3.0
    return float(absorbed * student)


def _honest_errors(res, sigma, times, label, coords, path, warnings, hint=None,
                   expected=None):
    """Scale a fit's covariance for residuals that are correlated (n / tau effective
    points, :func:`small_sample_factor`) and warn when the fit is a misfit against the
    measured noise.

    lmfit already scales the covariance by the reduced chi-square (the residuals'
    scatter, not the assumed noise); correlated residuals (a misfit, or an instrument
    whose errors persist) carry fewer independent points than rows, which this adds.
    ``hint(chunks)`` -> str: a likely cause, from the residuals per coordinate, for the
    misfit warning ("" when none).  ``expected`` (m, as ``res.raw_residual``): the
    residuals the closed forms leave on the model's own path at the fitted parameters
    (:func:`_expected_residual`); the misfit is what the data leave beyond them.
    """
    chunks = np.array_split(res.residual, len(times))  # one block per coordinate
    tau = max(correlation_time(c) for c in chunks)
    inflation = tau * small_sample_factor(res.residual.size, res.nvarys, tau)
    res.error_inflation = float(np.sqrt(inflation))
    if tau > 1.0 and res.covar is not None:
        res.covar = res.covar * inflation
        res.uvars = res.params.create_uvars(covar=res.covar)
        for name, uv in res.uvars.items():
            res.params[name].stderr = uv.std_dev
    if expected is not None:
        # (a noise-free simulated draw: 0.08 mm of small-angle x left by the closed
        # forms on the model's own path read 300x its numerical "noise", a misfit).
        # What is left beyond them is read against the noise and their own size: the
        # refit's parameters are not quite the data's, so a rest well under the closed
        # forms' own error is theirs too (noise-free draws: 6-13x the noise without it)
        scale = np.hypot(res.row_sigma, _rms(expected))
        chunks = np.array_split((res.raw_residual - expected) / scale, len(times))
        tau = max(correlation_time(c) for c in chunks)
    redchi = float(np.mean(np.concatenate(chunks) ** 2))
    if label and redchi > MISFIT_REDCHI and tau > MISFIT_TAU:
        dt = float(np.median(np.diff(times[0]))) if len(times[0]) > 1 else 0.0
        warnings.append(
            f"{path}: {label} fit: misfit -- the residuals in {coords} scatter "
            f"{np.sqrt(redchi):.3g}x the measured frame-to-frame noise "
            f"({_typical(sigma):.3g}; reduced chi-square {redchi:.3g}) and stay correlated over "
            f"~{tau * dt:.2g} s: the paper's model misses something here, or the "
            f"instrument's errors persist; 1-sigma errors are scaled by the residuals' "
            f"scatter and correlation (x{np.sqrt(max(redchi, 1.0) * inflation):.3g} of the "
            f"white-noise errors){hint(chunks) if hint else ''}; run `curltrack discover` "
            "to find what")
    return res


def _closed_form_refit(res, t, t_stop, fixed_stop, free_lambda, omega0, path):
    """The translation fit ``res`` made again on the paper's model's own path at its
    fitted parameters (:func:`curltrack.physics.simulate`, exact heading, the series'
    times, no noise): what the closed forms miss of the model they approximate.

    Returns ``(refit, simulated)`` - the refit and the parameter values simulated - or
    None where the simulation or the refit fails (the misfit warnings then speak).
    """
    from .physics import ShotModel, simulate

    v = {k: q.value for k, q in res.params.items()}
    try:
        lam, t_F, a_T = v["lambda_y"], v["t_FS"], v["a_T"]
        v0 = float(cf.initial_rate(v["y_F"], lam, t_F))
        phi = float(cf.phi_from_lambda(lam))
        alpha = float(cf.alpha_translation(v0, phi, t_F))
        spin = abs(omega0) if omega0 else 1.5
        model = ShotModel(v0=v0, omega0=-math.copysign(spin, a_T), phi_y=phi, alpha_y=alpha,
                          a_T=abs(a_T))
        sim = simulate(model, t=t)
        again = fit_translation(t, sim.x, sim.y, t_stop, fixed_stop, free_lambda, None,
                                path, [], start=v)
    except Exception:  # noqa: BLE001 - no bias estimate; the fit's own errors stand
        return None
    # (the model's curl decelerates with the slide: its lambda_x is lambda_y)
    return again, ({**v, "lambda_x": v["lambda_y"]} if free_lambda else v)


def _expected_residual(res, exact):
    """The residuals (m, as ``res.raw_residual``) that the closed forms leave on the
    model's own path (``exact``, :func:`_closed_form_refit`); None without one."""
    if exact is None or exact[0].raw_residual.shape != res.raw_residual.shape:
        return None
    return exact[0].raw_residual


def _approximation_error(res, exact):
    """Add to a translation fit's errors what the paper's closed forms themselves miss.

    The paper's x(t) is small-angle: a transverse acceleration a_T along x.  A rock's
    a_T is perpendicular to its velocity, which the curl turns (most near the stop), and
    the fit of the closed forms to such a path comes out biased: |a_T| 0.13 % low on a
    30 m draw curling 0.9 m - noise-free, or 5 of its 1-sigma at 1 mm noise, from this
    simulator and from an independent one alike.  The bias is measured at the fitted
    parameters (``exact``, :func:`_closed_form_refit`: the paper's model run at the
    series' times and fitted as the data were); each parameter's difference from the
    values simulated (lambda_x: the model's, lambda_y - the free fit read 1.846 for
    1.840, 3-19 sigma at 0.5-1 mm noise) is added to ``res.uvars`` as one shared error
    (its parts are one bias, fully correlated), so derived quantities carry it too.
    Nothing is added without ``exact``.
    """
    from uncertainties import ufloat

    if exact is None:
        return res
    again, simulated = exact
    z = ufloat(0.0, 1.0, tag="closed-form approximation")
    for k, uv in list(res.uvars.items()):
        if k in again.params and res.params[k].vary:
            res.uvars[k] = uv + (again.params[k].value - simulated[k]) * z
            res.params[k].stderr = res.uvars[k].std_dev
    return res


#: A position-only misfit whose x residuals' mean square is over this many times y's is
#: across the path: the curl, not the slide.
CURL_MISFIT_RATIO = 4.0


def _curl_end_hint(chunks) -> str:
    """The likely cause of a position-only translation misfit that sits in x."""
    mx, my = (float(np.mean(np.square(c))) for c in chunks)
    if mx <= CURL_MISFIT_RATIO * max(my, 1e-300):
        return ""
    return (f". It is in x, across the path ({np.sqrt(mx / max(my, 1e-300)):.2g}x y's "
            "residuals): with no rotation measured, a curl that ends before the rock stops "
            "(a spin that stopped first) looks like this - the paper's x(t) assumes the rock "
            "turns until it stops, and `discover` fits where the curl ends")


def _rms(res) -> float:
    return float(np.sqrt(np.mean(np.square(res)))) if len(res) else float("nan")


def _noise_rows(d: pd.DataFrame, col: str, field: str, t, q, t_stop, path):
    """The 1-sigma noise of every row of coordinate ``q``: the series' noise model
    (:func:`curltrack.series.noise.row_sigma`, as ``discover`` weighs the shot), the
    tracker's ``col`` modulating it per frame; None when the series is too short to
    estimate it (the rows then weigh alike, the covariance scaled by the fit's scatter)."""
    # noise-free (simulated) data: a floor keeps the scaled covariance computable
    floor = 1e-9 * float(np.nanmax(np.abs(q))) + 1e-15
    try:
        return row_sigma(sample_index(d), q, t=t, t_stop=t_stop, name=path,
                         field=field, floor=floor,
                         weights=d[col].to_numpy(float) if col in d else None)[1]
    except SeriesError:
        return None


def _typical(sigma) -> float:
    """One number for a noise given per row (or per coordinate, per row): the median."""
    parts = [np.atleast_1d(np.asarray(1.0 if v is None else v, dtype=float))
             for v in (sigma if isinstance(sigma, tuple) else (sigma,))]
    return float(np.nanmedian(np.concatenate(parts)))


def _row_weights(sigma, t) -> np.ndarray:
    """Per-row sigma from one value, an array, or None (all 1)."""
    s = np.broadcast_to(np.asarray(1.0 if sigma is None else sigma, dtype=float), t.shape)
    return np.where(np.isfinite(s) & (s > 0), s, 1.0)


def _x_stop(t, x, y, params, t_stop) -> float | None:
    """Measured lateral position at rest, in the deskewed frame (m)."""
    xd, _ = deskew(params.valuesdict(), x, y)
    if t_stop is None:
        return float(np.median(xd[-3:]))
    rest = xd[t >= t_stop]
    return float(np.median(rest)) if len(rest) else float(np.median(xd[-3:]))
