"""Discovery beyond the named effects: data-driven extensions of the equations of motion.

When no named effect explains the baseline's residuals, discovery tries a library of
smooth, switchable terms in the equations of motion, each a multiplier with a few
coefficients (registry entries in :mod:`curltrack.physics.extensions`, their math in
:class:`curltrack.physics.terms.Extension`, integrated by the one simulator):

* ``friction_field`` -- friction varies periodically along the sheet (wavelength scanned
  on a grid, cosine and sine amplitudes linear);
* ``spin_coupling`` -- the spin decays faster (slower) at higher translation speed;
* ``translation_coupling`` -- the translation decays faster (slower) at higher spin;
* ``curl_spin_dependence`` -- the curl follows the spin, a_T (|omega| / omega_ref)^p;
* ``friction_law`` -- the translational friction law is not a power law: alpha u^phi
  bent to u^(phi - dphi_low) below a knee speed (scanned), reported as the fitted mu(u)
  with its band.

They enter the search as nested candidates exactly like the named effects (linear scan
on the Jacobian around the baseline, parametric-bootstrap look-elsewhere threshold,
nonlinear refit in the simulator, blocked and leave-one-shot-out held-out error), at a
false-alarm level of ``physics.extensions.EXTENSION_LEVEL`` each so that the five of them together add
at most 2.5 % to the false alarms.  :func:`choose` keeps one only when it explains the
residuals (they then look like noise), no other extension comes close (in delta-BIC, or
fits at least as well), and it beats
every named effect by :data:`report.AMBIGUITY_MARGIN` in delta-BIC: a named effect that
explains the data about as well, with its (usually fewer) parameters, keeps its name.
The summary sentence and the plotted function with its 1-sigma band are computed from
the fitted coefficients and their covariance (delta method), rescaled to the
profile-likelihood errors of :mod:`.profile`.
"""

from __future__ import annotations

import math

import numpy as np

from ..physics.extensions import omega_ref
from ..physics.terms import speed_law_gain
from .scoring import support_level
from .search import heldout_log_ratio, judged_like

#: kind -> the term added to the equations, for REPORT.json ``terms``
FORMULAS = {
    "friction_field": "alpha_y, alpha_theta -> alpha [1 + amp_cos cos(2 pi y / wavelength)"
                      " + amp_sin sin(2 pi y / wavelength)]",
    "spin_coupling": "d|omega|/dt -> d|omega|/dt (1 + c_s_per_m v)",
    "translation_coupling": "dv/dt -> dv/dt (1 + c_s_per_rad |omega|)",
    "curl_spin_dependence": "a_T -> a_T ((omega^2 + omega_min^2) / omega_ref^2)^(p/2)",
    "friction_law": "mu(u) = alpha_y u^phi_y -> alpha_y u^phi_y ((u^2 + u_knee^2) / "
                    "(u^2 + u_floor^2))^(dphi_low/2)",
}


# --- the fitted function, its band and the sentence ---------------------------------
def _band(func, theta, cov, x):
    """Function values and 1-sigma band at ``x`` by the delta method."""
    f0 = func(theta, x)
    grads = []
    for i in range(len(theta)):
        h = 1e-6 * max(abs(theta[i]), 1.0)
        t2 = np.array(theta, dtype=float)
        t2[i] += h
        grads.append((func(t2, x) - f0) / h)
    g = np.array(grads)
    var = np.einsum("ix,ij,jx->x", g, cov, g) if g.size else np.zeros_like(f0)
    return f0, np.sqrt(np.maximum(var, 0.0))


def _cov_of(fit, names, cov=None) -> np.ndarray:
    """Covariance of ``names`` (0 for a parameter held fixed)."""
    cov = fit.cov if cov is None else cov
    idx = [fit.free.index(n) if n in fit.free else -1 for n in names]
    c = cov[np.ix_([max(i, 0) for i in idx], [max(i, 0) for i in idx])].copy()
    fixed = [k for k, i in enumerate(idx) if i < 0]
    c[fixed, :] = 0.0
    c[:, fixed] = 0.0
    return np.where(np.isfinite(c), c, 0.0)


def _friction_law(fit, p, translating, cov):
    """The fitted mu(u) of translation, its band, the sentence and derived numbers."""
    from ..physics.extensions import U_FLOOR_M_PER_S

    j = next(i for i, s in enumerate(translating))
    alpha = "alpha_y" if "alpha_y" in fit.free else f"alpha_y[{j}]"
    phi_key = f"phi_y[{j}]" if f"phi_y[{j}]" in fit.free else "phi_y"
    keys = [alpha, phi_key, "dphi_low", "u_knee_m_per_s"]
    c = _cov_of(fit, keys, cov)
    th = np.array([fit.values[k] for k in keys])

    def mu(t, u):
        return t[0] * u ** t[1] * speed_law_gain(u, t[2], t[3], U_FLOOR_M_PER_S)

    u_max = max(float(s.start.get("v0", 2.0)) for s in translating)
    x = np.geomspace(0.05, u_max, 120)
    vals, err = _band(mu, th, c, x)
    phi, dphi, uk = float(th[1]), float(th[2]), float(th[3])
    phi_e, dphi_e, uk_e = (float(np.sqrt(max(c[i, i], 0.0))) for i in (1, 2, 3))
    lo_e = float(np.sqrt(max(c[1, 1] + c[2, 2] - 2 * c[1, 2], 0.0)))
    how = ("rises more steeply than a power law as the rock slows" if dphi > 0 else
           "rises less steeply than a power law as the rock slows (towards a constant)")
    # the bend where it is measured: mu against the power law at a third of the knee
    u_low = max(uk / 3.0, 0.05)
    bend, bend_e = _band(lambda t, u: speed_law_gain(u, t[2], t[3], U_FLOOR_M_PER_S) - 1.0,
                         th, c, np.array([u_low]))
    summary = (f"the friction law is not a power law: below u = {_pm(uk, uk_e)} m/s "
               f"mu ~ u^(phi - dphi) with dphi = {_pm(dphi, dphi_e)} (phi = "
               f"{_pm(phi, phi_e)} above the knee, {_pm(phi - dphi, lo_e)} below): friction "
               f"{how}; at {u_low:.2f} m/s mu is {_pm(100 * bend[0], 100 * bend_e[0])} % "
               f"off the power law")
    derived = {"dphi_low": dphi, "dphi_low_err": dphi_e, "u_knee_m_per_s": uk,
               "u_knee_m_per_s_err": uk_e, "phi_high": phi, "phi_high_err": phi_e,
               "phi_low": phi - dphi, "phi_low_err": lo_e, "alpha": float(th[0])}
    fx = {"x_name": "u_m_per_s", "quantity": "friction coefficient mu(u)", "log": True,
          "power_law": (th[0] * x ** phi).tolist()}
    return x, vals, err, summary, derived, fx


def _pm(v, e) -> str:
    """``v +- e`` with the error to two significant digits (and v to the same place)."""
    if not (np.isfinite(e) and e > 0):
        return f"{v:.3g} (error unknown)"
    d = int(min(max(1 - math.floor(math.log10(e)), 0), 6))
    return f"{v:.{d}f} +- {e:.{d}f}"


def describe(sc, shots) -> dict:
    """The REPORT.json ``extension`` object's physics: terms, summary, function, band."""
    fit, p, name = sc.fit, sc.params, sc.name
    translating = [s for s in shots if s.translates]
    pcov = getattr(sc, "cov_profile", None)   # profile-likelihood errors (.profile)

    if name == "friction_law":
        x, vals, err, summary, derived, fx = _friction_law(fit, p, translating, pcov)
    elif name == "friction_field":
        keys = ["amp_cos", "amp_sin", "wavelength_m"]
        cov = _cov_of(fit, keys, pcov)
        th = np.array([p[k] for k in keys])

        def func(t, y):
            return 1.0 + t[0] * np.cos(2 * np.pi * y / t[2]) + t[1] * np.sin(2 * np.pi * y / t[2])

        amp = float(np.hypot(th[0], th[1]))
        g = np.array([th[0], th[1], 0.0]) / max(amp, 1e-12)
        amp_err = float(np.sqrt(max(g @ cov @ g, 0.0)))
        lam, lam_err = float(th[2]), float(np.sqrt(max(cov[2, 2], 0.0)))
        y_max = max(float(np.nanmax(s.obs["y"][s.use["y"]])) for s in translating)
        x = np.linspace(0.0, y_max, 200)
        vals, err = _band(func, th, cov, x)
        # where friction is highest: phase of the cosine at its first maximum
        y_peak = float((math.atan2(th[1], th[0]) / (2 * math.pi)) % 1.0 * lam)
        summary = (f"friction along the sheet varies periodically: wavelength "
                   f"{_pm(lam, lam_err)} m, amplitude {_pm(100 * amp, 100 * amp_err)} % "
                   f"(highest at y = {y_peak:.2f} m + n x {lam:.2f} m; seen over "
                   f"y = 0-{y_max:.1f} m)")
        derived = {"amplitude": amp, "amplitude_err": amp_err, "wavelength_m": lam,
                   "wavelength_m_err": lam_err, "y_peak_m": y_peak}
        fx = {"x_name": "y_m", "quantity": "friction multiplier alpha(y) / alpha"}
    elif name in ("spin_coupling", "translation_coupling"):
        key = "c_s_per_m" if name == "spin_coupling" else "c_s_per_rad"
        cov = _cov_of(fit, [key], pcov)
        th = np.array([p[key]])
        c, ce = float(th[0]), float(np.sqrt(cov[0, 0]))
        if name == "spin_coupling":
            x = np.linspace(0.0, max(s.start.get("v0", 2.0) for s in translating), 100)
            faster = "faster" if c > 0 else "slower"
            summary = (f"the spin decays {faster} at higher speed: d|omega|/dt scales by "
                       f"1 + ({_pm(c, ce)}) v (v in m/s)")
            fx = {"x_name": "v_m_per_s", "quantity": "spin-decay multiplier"}
        else:
            x = np.linspace(0.0, max(abs(s.start.get("omega0", 2.0)) for s in shots), 100)
            more = "more" if c > 0 else "less"
            summary = (f"the rock decelerates {more} while it spins faster: dv/dt scales by "
                       f"1 + ({_pm(c, ce)}) |omega| (omega in rad/s)")
            fx = {"x_name": "omega_rad_per_s", "quantity": "translation-decay multiplier"}
        vals, err = _band(lambda t, xx: 1.0 + t[0] * xx, th, cov, x)
        derived = {key: c, f"{key}_err": ce}
    elif name == "curl_spin_dependence":
        cov = _cov_of(fit, ["p"], pcov)
        th = np.array([p["p"]])
        w_ref = omega_ref(shots)
        w_min = 0.05
        x = np.linspace(0.0, max(abs(s.start.get("omega0", 2.0)) for s in shots), 100)
        vals, err = _band(lambda t, w: ((w * w + w_min ** 2) / w_ref ** 2) ** (0.5 * t[0]),
                          th, cov, x)
        pe = float(np.sqrt(cov[0, 0]))
        how = ("fades as the spin decays" if th[0] > 0 else "grows as the spin decays")
        summary = (f"the curl follows the spin: a_T scales as (|omega| / {w_ref:.2f} "
                   f"rad/s)^({_pm(float(th[0]), pe)}), so it {how} (the baseline keeps a_T "
                   f"until the spin stops)")
        derived = {"p": float(th[0]), "p_err": pe, "omega_ref_rad_per_s": w_ref}
        fx = {"x_name": "omega_rad_per_s", "quantity": "a_T multiplier"}
    else:  # pragma: no cover - every extension candidate is described above
        raise ValueError(name)
    fx.update(x=x.tolist(), value=np.asarray(vals).tolist(),
              band_lo=(np.asarray(vals) - err).tolist(), band_hi=(np.asarray(vals) + err).tolist())
    return {"kind": name, "terms": [FORMULAS[name]], "summary": summary, "derived": derived,
            "function": fx}


def choose(supported, scores, margin: float, r0=None):
    """The extension that the verdict should report, or None.

    Parameters
    ----------
    supported : list of (CandidateScore, finding)
        Every supported candidate (named and extension).
    scores : list of CandidateScore
    margin : float
        delta-BIC by which the extension must beat every named effect and every other
        extension (2 ln Bayes factor).
    """
    ext = [sc for sc, _ in supported if sc.extension]
    if not ext:
        return None
    best = max(ext, key=lambda sc: sc.delta_bic)
    if best.structure_after is None or best.structure_after.structured:
        return None
    for o in scores:
        if o is best or not np.isfinite(o.delta_bic):
            continue
        # (with the baseline's residuals r0: every rival under the best's noise level)
        gain, dbic = judged_like(best, o, r0)
        if o.extension and dbic > best.delta_bic - margin:
            return None      # two extensions explain it alike: not one description
        if o.extension and gain is not None and best.chi2_gain is not None and \
                gain >= best.chi2_gain and o.delta_bic > support_level(o.threshold["threshold"]):
            # fits at least as well: only the parameter count would decide.  On one draw
            # the spin falls with the speed, so a translation coupling 1 + c |omega| is a
            # friction law in disguise (a bent law: chi-square gain 634 against the
            # coupling's 633, delta-BIC 618 and 625)
            return None
        if not o.extension and dbic > best.delta_bic - margin and \
                o.delta_bic > support_level(o.threshold["threshold"]):
            return None      # a named effect explains it about as well: it keeps the name
        if not o.extension and o.fit is not None and o.heldout and best.heldout and \
                o.delta_bic > support_level(o.threshold["threshold"]) and \
                heldout_log_ratio(best.heldout["time"], o.heldout["time"]) < 0:
            # a named effect that clears its threshold and predicts held-out data better:
            # the extension does not speak for it (a 1.9x patch under step noise, found
            # at its place but not supported, was reported as a spin coupling whose
            # held-out error was 26 % above the patch's)
            return None
    return best


def extension_object(sc, finding, shots, h0, h0_loso) -> dict:
    """REPORT.json ``extension`` for the chosen extension score."""
    out = describe(sc, shots)
    out.update(params=sc.params, params_err=sc.params_err, delta_bic=sc.delta_bic,
               threshold=sc.threshold["threshold"], bootstrap=sc.threshold, k=sc.k,
               rms_before=finding["rms_before"], rms_after=finding["rms_after"],
               heldout_rmse_before=h0["scalar"], heldout_rmse_after=sc.heldout["time"]["scalar"],
               loso_rmse_before=h0_loso["scalar"] if h0_loso else None,
               loso_rmse_after=sc.heldout["shot"]["scalar"] if "shot" in sc.heldout else None,
               structure_after=finding.get("structure_after"),
               errors=("profile likelihood" if sc.profile else "covariance"),
               profile=sc.profile)
    return out


def plot_function(ax, ext: dict) -> None:
    """The fitted function with its 1-sigma band."""
    f = ext["function"]
    x = np.asarray(f["x"])
    ax.fill_between(x, f["band_lo"], f["band_hi"], color="C3", alpha=0.25, lw=0,
                    label="1-sigma band")
    ax.plot(x, f["value"], "-", color="C3", lw=1.5, label="fitted")
    if "power_law" in f:   # a friction law: its power-law part, on log-log axes
        ax.plot(x, f["power_law"], "--", color="0.4", lw=0.8,
                label="alpha u^phi (the law above the knee)")
        ax.set_xscale("log")
        ax.set_yscale("log")
    else:
        ax.axhline(1.0, color="0.4", lw=0.8, ls="--", label="baseline")
    ax.set_xlabel(f["x_name"].replace("_m_per_s", " (m/s)").replace("_rad_per_s", " (rad/s)")
                  .replace("_m", " (m)"))
    ax.set_ylabel(f["quantity"])
    ax.set_title(ext["summary"], fontsize=8, loc="left", wrap=True)
    ax.legend(fontsize=7, loc="best")
