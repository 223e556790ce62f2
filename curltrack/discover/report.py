"""The report (:class:`~.results.DiscoveryReport`), the verdict, and the figure."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .._atomic import atomic_path, write_json
from .extend import choose as choose_extension
from .extend import extension_object
from .residuals import binned_means, smooth_misfit
from .scoring import support_level
from .search import heldout_log_ratio, heldout_worse_p, instrument_step, judged_like
from .results import DiscoveryReport, Finding
from .shots import COORDS

#: a candidate is named only if its delta-BIC beats every other candidate's by at least
#: this much (and fit better than every credible rival, see :func:`rivals`).  Delta-BIC differences are on the 2 ln(Bayes factor) scale: below 6 the
#: evidence for one over the other is at most "positive", not "strong" (odds < 20:1,
#: Kass & Raftery 1995).  Near the detection threshold a weak patch and a pick in y, or
#: a weak pick and late curl, fit equally well; a wrong name is worse than saying so,
#: so the verdict is then ``unexplained`` with the rivals listed (``ambiguous``).
AMBIGUITY_MARGIN = 6.0


#: a coordinate's RMS this much above the baseline's counts as made worse (below it,
#: the joint fit's trade between coordinates is within noise)
WORSE_TOLERANCE = 1.02
#: ... and its held-out RMS this much: an extrapolation over 5 time blocks, which moves
#: by a few % between two fits that agree in-sample (theta's went 0.00565 -> 0.00579,
#: +2.5 %, under a friction law that does not act on theta, its in-sample RMS unchanged)
HELDOUT_WORSE_TOLERANCE = 1.05
#: ... and significantly so: one-sided p of the paired test over held-out folds
#: (:func:`~curltrack.discover.search.heldout_worse_p`) below this
HELDOUT_WORSE_LEVEL = 0.05


def at_bound(fit, bounds: dict, names=None) -> list:
    """Free parameters of ``fit`` within 1e-6 of a bound, relative to the bound's own
    size (1 for a bound at 0) and never more than 1e-6 of their span: a friction
    coefficient of 1e-7 is not at a lower bound of 1e-15."""
    out = []
    for k in (fit.free if names is None else [n for n in names if n in fit.free]):
        lo, hi = bounds.get(k, (None, None))
        v = fit.values[k]
        span = (hi - lo) if lo is not None and hi is not None else np.inf
        for b in (lo, hi):
            tol = 1e-6 * min(span, abs(b) if b else 1.0) if b is not None else 0.0
            if b is not None and abs(v - b) <= tol:
                out.append(f"{k} = {v:.4g} at its bound {b:.4g}")
    return out


def _blockers(f, cand_bounds, heldout_p=None) -> list:
    """Why a supported candidate must not be named (empty: nothing against it).

    ``heldout_p`` maps a coordinate to the p-value that its held-out error got worse
    (:func:`~curltrack.discover.search.heldout_worse_p`); a held-out RMS above the
    tolerance blocks the name only when that is below :data:`HELDOUT_WORSE_LEVEL` (or
    cannot be computed)."""
    heldout_p = heldout_p or {}
    out = [f"parameter {b}" for b in cand_bounds]
    for key, before, after, tol in (
            ("RMS", f["rms_before"], f["rms_after"], WORSE_TOLERANCE),
            ("held-out RMS", f["heldout_before_by_coord"], f["heldout_after_by_coord"],
             HELDOUT_WORSE_TOLERANCE)):
        for c in COORDS:
            b, a = (before or {}).get(c), (after or {}).get(c)
            if b is None or a is None or a <= tol * b:
                continue
            p = heldout_p.get(c, np.nan) if key == "held-out RMS" else np.nan
            if np.isfinite(p) and p >= HELDOUT_WORSE_LEVEL:
                continue
            out.append(f"{key} of {c} worse ({b:.3g} -> {a:.3g}"
                       + (f", p = {p:.2g})" if np.isfinite(p) else ")"))
    return out


def _at_bound(finding) -> bool:
    """Whether a blocked finding has a parameter at its bound among its blockers (and no
    instrument's jump left in its residuals: a patch of factor 0.05, at its bound,
    fitted to a centimetre jump of the position is the jump, not something stronger
    than the patch's range)."""
    why = finding.not_named_because or ()
    return (any(b.startswith("parameter ") for b in why)
            and not any(b.startswith(JUMP_LEFT) for b in why))


def _rms_by_coord(model, r_raw) -> dict:
    out = {}
    for c in COORDS:
        parts = [r_raw[sl] for j, cc, sl in model.segments if cc == c]
        out[c] = float(np.sqrt(np.mean(np.concatenate(parts) ** 2))) if parts else None
    return out


def _baseline_params(fit) -> tuple[dict, dict]:
    vals = {k: float(v) for k, v in fit.values.items()}
    errs = {k: fit.err(k) for k in fit.free}
    return vals, errs


def _unexplained_gain(model, fit) -> tuple[float, int]:
    """chi-square captured by a free mean in each of 10 time bins of every segment (a
    model-free 'something is here'), and its number of parameters."""
    gain, k = 0.0, 0
    for j, c, sl in model.segments:
        r = fit.r[sl]
        if r.size < 20:
            continue
        b = binned_means(r, model.shots[j].t[model.shots[j].use[c]])
        gain += b["chi2"]
        k += b["dof"]
    return gain, k


def _evidence(sc, h0) -> str:
    thr = sc.threshold
    if sc.fit is None:
        return (f"linearised delta-BIC {sc.delta_bic_linear:.1f} is far below the "
                f"look-elsewhere threshold {thr['threshold']:.1f} "
                f"({thr['level']:.0%} false alarms, {thr['n_boot']} bootstrap replicates)")
    after = sc.structure_after
    return (f"adding {sc.name} lowers chi-square by {sc.chi2_gain:.1f} for "
            f"{sc.k} parameter(s): delta-BIC {sc.delta_bic:.1f} against a bootstrap "
            f"look-elsewhere threshold of {thr['threshold']:.1f} ({thr['level']:.0%} false "
            f"alarms, {thr['n_boot']} replicates); held-out RMS {h0['scalar']:.3f} -> "
            f"{sc.heldout['time']['scalar']:.3f} noise units; residual structure after: "
            f"Bonferroni p = {after.p_min_adjusted:.2g}")


def rivals(best, scores, margin: float = AMBIGUITY_MARGIN, r0=None) -> list:
    """Names of the other candidates the data cannot tell from ``best``.

    A rival either comes within ``margin`` of ``best``'s delta-BIC, or fits at least as
    well (chi-square gain >= ``best``'s) while clearing its own look-elsewhere threshold:
    then only the BIC's parameter count prefers ``best`` (a weak patch whose extent
    the noise hides is an impulse, a pick with one parameter fewer).  A ``best`` that
    fits better *and* has fewer parameters keeps its name (late curl against a lateral
    kick late in the shot).  A rival's own
    threshold is not required in the first case: it speaks of chance under the baseline,
    not of how well the rival competes on these data.  A rival known only linearly
    (never refitted) is compared by that delta-BIC.  With the baseline's whitened
    residuals ``r0``, a refitted rival's gain and delta-BIC are taken under the noise
    level ``best`` is judged by (:func:`.search.judged_like`).
    """
    out = []
    for o in scores:
        if o is best or not np.isfinite(o.delta_bic):
            continue
        gain, dbic = judged_like(best, o, r0)
        close_bic = dbic > best.delta_bic - margin
        close_fit = (gain is not None and best.chi2_gain is not None
                     and gain >= best.chi2_gain
                     and o.delta_bic > o.threshold["threshold"] and o.linear_clears
                     and o.robust_clears and o.beyond_stated)
        if close_bic or close_fit:
            out.append(o.name)
    return sorted(out)


def _all_supported(names, findings) -> bool:
    """Whether every candidate named in ``names`` is itself supported, and not blocked
    for a reason of its own (a bound, a worse coordinate, an instrument's jump)."""
    by_name = {f.effect: f for f in findings}
    return all(n in by_name and by_name[n].supported and not by_name[n].not_named_because
               for n in names)


JUMP_LEFT = "an instrument's jump is left in what it leaves"


def _jump_left(sc, base, base_jump) -> str | None:
    """Why candidate ``sc`` is not told from an instrument's jump, or None: a jump of
    one position coordinate stays in its fit's residuals at the 1 % look-elsewhere level
    (:func:`~curltrack.discover.search.instrument_step`) - the data jumped, and the
    candidate only smoothed it - and a jump explains the baseline's misfit as well as
    the candidate does (``base_jump``: the jump scored on the baseline's fit).  (A true
    ice slope whose fit left a box-shaped misfit beside the kink of a curl's end, while a
    jump explained much less of the misfit than the slope, is left to the other rules.)"""
    if sc.fit is None or base_jump is None or base_jump["delta_bic"] < sc.delta_bic:
        return None
    jump = instrument_step(base, sc.fit)
    if jump is None or not jump["found"]:
        return None
    held = (f"held {jump['t_to_s'] - jump['t_from_s']:.1f} s" if jump["t_to_s"] is not None
            else "to the end")
    return (f"{JUMP_LEFT} (shot {jump['shot']}, {jump['coord']} between t = "
            f"{jump['t_before_s']:.2f} and {jump['t_from_s']:.2f} s, {held}: chi-square "
            f"{jump['gain']:.1f} over the "
            f"{jump['threshold']:.1f} a jump reaches by chance); a rock's position cannot "
            f"jump, an instrument's can")


def _finding(sc, rms0, h0, h0_loso, base, cand_bounds, base_jump=None) -> Finding:
    """The finding of one scored candidate (supported or not; a supported one lists what
    blocks its name, ``cand_bounds`` being its parameters at a bound, ``base_jump`` the
    instrument's jump on the baseline's fit: :func:`_jump_left`)."""
    thr = sc.threshold["threshold"]
    kw = dict(effect=sc.name, delta_bic=sc.delta_bic, delta_bic_linear=sc.delta_bic_linear,
              threshold=thr, bootstrap=sc.threshold, location_start=sc.location,
              rms_before=rms0, rms_after=None, heldout_rmse_before=h0["scalar"],
              heldout_rmse_after=None, heldout_before_by_coord={c: h0[c] for c in COORDS},
              params=sc.params, params_err=sc.params_err, note=sc.note + sc.remark,
              nfev=sc.nfev,
              evidence=_evidence(sc, h0), fit=sc.fit, detection_limit=sc.limits,
              extension=True if getattr(sc, "extension", None) else None)
    if sc.fit is None:
        return Finding(**kw)
    kw.update(rms_after=_rms_by_coord(base, sc.fit.r_raw),
              delta_bic_without_few_rows=sc.delta_bic_without_few_rows,
              path_change_stated=sc.path_change_stated,
              heldout_rmse_after=sc.heldout["time"]["scalar"],
              heldout_after_by_coord={c: sc.heldout["time"][c] for c in COORDS},
              structure_after={"p_min_adjusted": sc.structure_after.p_min_adjusted,
                               "structured": sc.structure_after.structured,
                               "where": sc.structure_after.where})
    ok_cv = heldout_log_ratio(h0, sc.heldout["time"]) < 0
    if h0_loso is not None and "shot" in sc.heldout:
        kw.update(loso_rmse_before=h0_loso["scalar"],
                  loso_rmse_after=sc.heldout["shot"]["scalar"])
        # an effect of one shot (a pick) says nothing about the shots left out: a
        # leave-one-shot-out gain is then the refit's noise, not prediction
        if not sc.per_shot:
            ok_cv = ok_cv or kw["loso_rmse_after"] < kw["loso_rmse_before"]
    kw["supported"] = bool(sc.delta_bic > support_level(thr) and sc.linear_clears
                           and sc.robust_clears and sc.beyond_stated and ok_cv)
    if kw["supported"]:
        kw["not_named_because"] = _blockers(
            kw, cand_bounds, {c: heldout_worse_p(h0, sc.heldout["time"], c) for c in COORDS})
        left = _jump_left(sc, base, base_jump)
        if left:
            kw["not_named_because"].append(left)
        if kw["not_named_because"]:
            kw["evidence"] += "; not named: " + "; ".join(kw["not_named_because"])
    return Finding(**kw)


def _smooth_left(sc, smooth) -> list:
    """The smooth misfits (:func:`~curltrack.discover.residuals.smooth_misfit`) that
    candidate ``sc``'s refit still leaves, where the baseline had some (``smooth``).

    A baseline that misses the shots smoothly (the model's misfit, not noise) is
    explained by a named effect or an extension only if it takes that misfit away: a
    peer simulator's physics, none of the vocabulary, missed theta 3.7 times its rows'
    scatter after a "pick" of 0.02 m/s at the stop that took the largest part
    (delta-BIC 6221; 2 of 40 draws, a late curl once).
    """
    if not smooth or sc._model is None or sc.fit is None:
        return []
    return smooth_misfit(sc._model, sc.fit)


def _smooth_unexplained(sc, left) -> dict:
    """``unexplained`` of a verdict whose best candidate ``sc`` leaves the smooth
    misfits ``left`` (:func:`_smooth_left`)."""
    return dict(shot=left[0]["shot"], coord=left[0]["coord"], after_model=sc.name,
                smooth_misfit=left)


def build_report(shots, base, fit0, before, h0, h0_loso, scores, cand_bounds=None,
                 not_tested=None, warnings=(), smooth=()) -> DiscoveryReport:
    """Assemble the report and decide the verdict (rule in :mod:`curltrack.discover`).

    ``cand_bounds`` maps a candidate's name to its parameters at a bound (list of str);
    ``warnings`` come first in the report's (the input's: units, thinning); ``smooth``:
    the baseline's smooth misfits (:func:`~curltrack.discover.residuals.smooth_misfit`),
    which make a verdict that names nothing ``unexplained``, not ``none``.
    """
    n = fit0.n
    rms0 = _rms_by_coord(base, fit0.r_raw)
    vals, errs = _baseline_params(fit0)
    for j, s in enumerate(shots):  # (offsets in the series' own frame)
        for name, o in zip(("x0", "y0", "theta0"), s.origin):
            if o and f"{name}[{j}]" in vals:
                vals[f"{name}[{j}]"] += o
    cand_bounds = cand_bounds or {}
    base_bound = at_bound(fit0, base.bounds)
    bound_warnings = [f"baseline ({base.baseline}) parameter {b}: the baseline does not "
                      f"describe these shots within its range; no cause is named"
                      for b in base_bound]
    base_jump = instrument_step(base, fit0)
    findings = [_finding(sc, rms0, h0, h0_loso, base, cand_bounds.get(sc.name, []), base_jump)
                for sc in scores]
    supported = [(sc, f) for sc, f in zip(scores, findings) if f.supported]
    blocked = [(sc, f) for sc, f in supported if f.not_named_because]
    supported = [(sc, f) for sc, f in supported if not f.not_named_because]
    verdict, unexplained, extension = "none", None, None
    best_fit, best_model_name, best_params = fit0, None, {}
    ambiguous = []
    # a data-driven extension speaks only when it beats every named effect (discover.extend)
    ext = None if base_bound else choose_extension(supported, scores, AMBIGUITY_MARGIN,
                                                   r0=fit0.r)
    named = [sc for sc in scores if not sc.extension]
    supported_named = [(sc, f) for sc, f in supported if not sc.extension]
    # (an extension too must take the baseline's smooth misfit away: a peer's physics
    # was 'extended' by a periodic friction field that left theta 7.8x its scatter)
    ext_smooth = _smooth_left(ext, smooth) if ext is not None else []
    if ext_smooth:
        verdict = "unexplained"
        best_fit, best_model_name = ext.fit, ext.name
        unexplained = _smooth_unexplained(ext, ext_smooth)
    elif ext is not None:
        verdict = "extended"
        best_fit, best_model_name, best_params = ext.fit, ext.name, ext.params
        extension = extension_object(ext, next(f for sc, f in supported if sc is ext).summary(),
                                     shots, h0, h0_loso)
    elif supported_named:
        sc, f = max(supported_named, key=lambda p: p[0].delta_bic)
        best_fit, best_model_name, best_params = sc.fit, sc.name, sc.params
        ambiguous = rivals(sc, named, r0=fit0.r)
        # extensions that explain the data clearly better than any named effect but
        # not one of them alone (choose() found them alike): the named effect must not
        # take the verdict for them (a hidden translation coupling was named a pick and
        # a patch once a friction law explained it alike)
        better = sorted(o.name for o, _ in supported if o.extension
                        and judged_like(sc, o, fit0.r)[1] >= sc.delta_bic + AMBIGUITY_MARGIN)
        if better:
            ambiguous = better
        smooth_after = _smooth_left(sc, smooth)
        if base_bound:
            verdict = "unexplained"
            unexplained = dict(sc.structure_after.where or {}, after_model=sc.name,
                               baseline_at_bound=base_bound)
        elif smooth_after:
            verdict = "unexplained"
            unexplained = _smooth_unexplained(sc, smooth_after)
        elif sc.structure_after.structured:
            verdict = "unexplained"
            unexplained = dict(sc.structure_after.where or {}, after_model=sc.name)
        elif ambiguous and (before.structured or better or smooth
                            or _all_supported(ambiguous, findings)):
            # (rivals each supported on their own - clearing their own look-elsewhere
            # threshold, predicting held-out data better - agree the baseline misses
            # something and differ only on what: CI seed 825132790, a lateral slope
            # under two position-only shots, its pick rival at delta-BIC 212 against a
            # threshold of 3.8, was 'none')
            verdict = "unexplained"
            unexplained = dict(sc.structure_after.where or {}, after_model=sc.name,
                               ambiguous=([] if better else [sc.name]) + ambiguous)
        elif ambiguous:
            # a candidate that clears its threshold but is not told from a rival, on
            # residuals that look like noise, names nothing and claims nothing missing:
            # 'unexplained' there was a false alarm (a 10 Hz clean draw: a pick at
            # delta-BIC 0.7 alike an unsupported late_curl, seed 3536223930180992943)
            best_fit, best_model_name, best_params = fit0, None, {}
            # (each says so: a supported finding under a 'none' with no reason reads as
            # a contradiction)
            alike = {sc.name: ambiguous, **{a: [sc.name] for a in ambiguous}}
            for i, g in enumerate(findings):
                if g.supported and g.effect in alike:
                    why = (f"not told from {' or '.join(alike[g.effect])}: the data fit "
                           f"them alike (delta-BIC within {AMBIGUITY_MARGIN:g}, or a fit "
                           f"at least as good)")
                    findings[i] = replace(g, not_named_because=list(g.not_named_because or
                                                                    []) + [why],
                                          evidence=g.evidence + "; not named: " + why)
        else:
            verdict = sc.name
    elif before.structured or base_bound or smooth or any(_at_bound(f) for _, f in blocked):
        # an extension that clears its threshold but is not chosen (its residuals stay
        # structured, or another explains it alike) does not turn residuals that look
        # like noise into 'unexplained': under the real-data noise classes that would
        # add false alarms; it stays listed among the findings.  Nor does a candidate
        # blocked only because it fits some coordinate worse (evidence against it:
        # under step-like noise 1 clean shot in 40 was 'unexplained' that way); one
        # blocked at a parameter bound (something stronger than its range) does.
        # (a baseline at a bound does not describe the shots at all - a mirrored shot's
        # curl against its spin held a_T at 0 with 10 cm residuals, which the persisting-
        # noise scale then took for the instrument's: 'none' was a confident wrong answer)
        verdict = "unexplained"
        unexplained = dict(before.where or {}, after_model="baseline")
        if smooth:
            unexplained["smooth_misfit"] = list(smooth)
            if not before.structured:
                unexplained.update(shot=smooth[0]["shot"], coord=smooth[0]["coord"])
        if base_bound:
            unexplained["baseline_at_bound"] = base_bound
        if len(supported) > 1:   # extensions that explain it alike: no one description
            unexplained["ambiguous"] = [sc.name for sc, _ in supported]
        if blocked:
            unexplained["not_named"] = {sc.name: f.not_named_because for sc, f in blocked}
    if verdict == "unexplained":
        gain, k = _unexplained_gain(base, best_fit)
        w = unexplained
        where_txt = (f"shot {w.get('shot')}, {w.get('coord')}, t = {w.get('t_from_s', 0):.1f}-"
                     f"{w.get('t_to_s', 0):.1f} s, y = {w.get('y_from_m', 0):.2f}-"
                     f"{w.get('y_to_m', 0):.2f} m") if w else "not localised"
        if unexplained.get("ambiguous"):
            alike = [next(o for o in scores if o.name == a) for a in unexplained["ambiguous"]]
            evidence = ("the baseline's misfit is explained about equally well by " +
                        " and ".join(f"{o.name} (delta-BIC {o.delta_bic:.1f})" for o in alike)
                        + f": they differ by less than {AMBIGUITY_MARGIN:g} (2 ln Bayes "
                          f"factor), too little to name one")
        elif unexplained.get("smooth_misfit") and best_model_name is not None:
            evidence = "; ".join(
                f"with {best_model_name} added, the model still misses shot {m['shot']}'s "
                f"{m['coord']} by {m['rms']:.3g} RMS, {m['ratio']:.1f} times its rows' "
                f"scatter ({m['sigma']:.3g}), smoothly"
                for m in unexplained["smooth_misfit"]) + (
                f" (m or rad): {best_model_name} explains part of the baseline's misfit, "
                "not the shot")
        elif unexplained.get("smooth_misfit") and not before.structured:
            evidence = "; ".join(
                f"the baseline misses shot {m['shot']}'s {m['coord']} by {m['rms']:.3g} RMS, "
                f"{m['ratio']:.1f} times its rows' scatter ({m['sigma']:.3g}), smoothly"
                for m in unexplained["smooth_misfit"]) + (
                " (m or rad): the residuals do not jump as an instrument's errors do, so the "
                "model does not describe the shot, and no candidate explains it")
        else:
            evidence = (f"residuals of the {best_model_name or 'baseline'} model stay "
                        f"structured (a free mean in 10 time bins per series gains "
                        f"chi-square {gain:.1f} for {k} parameters); the largest misfit "
                        f"sits at {where_txt}")
        findings.append(Finding(
            effect="unexplained", delta_bic=float(gain - k * np.log(n)), rms_before=rms0,
            rms_after=_rms_by_coord(base, best_fit.r_raw), heldout_rmse_before=h0["scalar"],
            heldout_rmse_after=None, params={}, params_err={}, where=unexplained,
            evidence=evidence, fit=best_fit))
    findings.sort(key=lambda f: -np.inf if f.delta_bic is None else -f.delta_bic)
    return DiscoveryReport(
        verdict=verdict, findings=tuple(findings),
        baseline={"model": base.baseline, "params": vals, "params_err": errs,
                  "rms": rms0, "bic": fit0.bic,
                  "chi2": fit0.chi2, "n_points": n, "k": fit0.k,
                  "heldout_rmse": h0["scalar"],
                  "heldout_by_coord": {c: h0[c] for c in COORDS},
                  "loso_rmse": h0_loso["scalar"] if h0_loso else None},
        extension=extension, unexplained=unexplained,
        structure_before={"p_min_adjusted": before.p_min_adjusted,
                          "structured": before.structured, "where": before.where,
                          "tests": before.tests},
        noise=[{"file": s.name, **{c: s.noise[c].as_dict() for c in COORDS}} for s in shots],
        shots=[{"file": s.name, "spin": s.spin, "translates": s.translates,
                "spins": s.spins, "t_stop_translation": s.t_stop_translation,
                "t_stop_rotation": s.t_stop_rotation,
                "rink_heading_deg": float(np.degrees(s.heading_rad))} for s in shots],
        warnings=[*warnings, *(w for s in shots for w in s.warnings), *bound_warnings],
        not_tested=dict(not_tested or {}),
        shot_data=list(shots), model=base, fit0=fit0, best_fit=best_fit,
        extended=best_model_name, best_params=best_params)


def write_json_report(report: DiscoveryReport, path) -> None:
    """Write REPORT.json atomically (NaN/inf become null)."""
    write_json(path, report.summary())


def plot_report(report: DiscoveryReport, path, max_shots: int = 2) -> None:
    """Data, baseline, extended model, and residuals before/after, per coordinate.

    One block of two rows per shot (at most ``max_shots``): the top row shows the data
    (dots), the baseline (line) and the extended model (dashed) for x, y (m) and theta
    (rad) against time; the bottom row their residuals (mm, mm, degrees) before (grey)
    and after (colour) the extension.  With a data-driven extension (verdict
    ``extended``) a last row shows its fitted function with the 1-sigma band.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    shots, model, ext = report.shot_data, report.model, report.extended
    fit0, fit1 = report.fit0, report.best_fit
    ns = min(len(shots), max_shots)
    ext_obj = report.extension
    fig, axes = plt.subplots(2 * ns + bool(ext_obj), 3, squeeze=False,
                             figsize=(13, 4.2 * ns + (3.2 if ext_obj else 0.0)))
    scale = {"x": 1e3, "y": 1e3, "theta": np.degrees(1.0)}
    unit = {"x": "mm", "y": "mm", "theta": "deg"}
    for j in range(ns):
        s = shots[j]
        for k, c in enumerate(COORDS):
            top, bot = axes[2 * j, k], axes[2 * j + 1, k]
            use = s.use[c]
            t = s.t[use]
            top.plot(t, s.obs[c][use], ".", ms=2, color="k", alpha=0.5, label="data")
            if len(t) == 0:  # not fitted (position-only theta): no model curve to show
                top.text(0.5, 0.5, "not used", transform=top.transAxes, ha="center")
                continue
            top.plot(s.t, fit0.predictions[j][c], "-", color="C0", lw=1.2,
                     label=f"baseline ({model.baseline})")
            if ext:
                top.plot(s.t, fit1.predictions[j][c], "--", color="C3", lw=1.2,
                         label=f"+ {ext}")
            top.set_ylabel(f"{c} ({'rad' if c == 'theta' else 'm'})")
            r0 = (s.obs[c] - fit0.predictions[j][c])[use] * scale[c]
            bot.plot(t, r0, ".", ms=2, color="0.6", label="baseline")
            if ext:
                r1 = (s.obs[c] - fit1.predictions[j][c])[use] * scale[c]
                bot.plot(t, r1, ".", ms=2, color="C3", label=f"+ {ext}")
            bot.axhline(0, color="k", lw=0.6)
            bot.set_ylabel(f"residual {c} ({unit[c]})")
            if len(t) == 0:
                top.text(0.5, 0.5, "not used", transform=top.transAxes, ha="center")
            _mark_effect(top, bot, ext, report.best_params, s, fit1.predictions[j], j)
        axes[2 * j, 0].set_title(str(s.name).split("/")[-1], loc="left", fontsize=9)
        axes[2 * j, 0].legend(fontsize=7, loc="best")
        axes[2 * j + 1, 0].legend(fontsize=7, loc="best")
    for ax in axes[2 * ns - 1]:
        ax.set_xlabel("t (s)")
    if ext_obj:  # the fitted function of the extension with its band, full width
        from .extend import plot_function

        for ax in axes[-1]:
            ax.remove()
        plot_function(fig.add_subplot(axes[0, 0].get_gridspec()[-1, :]), ext_obj)
    fig.suptitle(f"verdict: {report.verdict}", fontsize=11)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)


def _mark_effect(top, bot, ext, params, shot, pred, j):
    """Shade where the named effect acts (its definition's marks: a patch's stretch in
    time, a pick's instant)."""
    from ..physics.effects import EFFECTS

    if ext not in EFFECTS:
        return
    for mark in EFFECTS[ext].marks(params, j, shot.t, pred):
        for ax in (top, bot):
            if mark[0] == "span":
                ax.axvspan(mark[1], mark[2], color="C2", alpha=0.12, lw=0)
            else:
                ax.axvline(mark[1], color="C2", lw=1, ls=":")
