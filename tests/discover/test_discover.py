"""Hidden effects are found, clean shots are left alone, unknown effects stay unexplained.

Cases are simulated with ``curltrack.simulate.simulate_series`` (2 mm / 0.3 deg noise);
strengths, locations, signs, shots and seeds are drawn at random (seeded) from fixed
ranges.  "Moderate" strength = about 3x the strength detected 90 % of the time
(``scripts/bench_discover.py``; table in the README), so detection and false alarms
pull against each other honestly.
"""

import functools

import numpy as np
import pytest
from scipy import stats

from discover._synth import make_case
from curltrack.discover import discover

#: moderate strengths: ~3x the 90 %-detection strength at 2 mm noise (bench_discover.py,
#: re-measured after names were withheld when a rival candidate fits about as well)
MODERATE = {
    "pick": (0.005, 0.007),                       # |dvx| m/s; 90 % at 0.002
    "late_curl": (0.6, 0.8),                      # |k|; 90 % at ~0.23
    "friction_patch": (0.2, 0.28),                # |factor - 1| over 3-5 m; 90 % ~0.08
    "ice_slope": (0.015, 0.02),                   # |slope_x| mm/m, two shots; 90 % ~0.0054
    "velocity_dependent_friction": (0.009, 0.011),  # -phi, dry baseline; 90 % ~0.0032
}
N_SHOTS = {"ice_slope": 2}


@functools.lru_cache(maxsize=None)  # the coverage test reuses the draws of this process
def _case(effect, seed):
    rng = np.random.default_rng(seed)
    strength = float(rng.uniform(*MODERATE[effect]))
    shots, truth = make_case(effect, strength, rng, n_shots=N_SHOTS.get(effect, 1))
    rep = discover(shots, baseline=truth["baseline"], seed=seed, n_boot=300)
    return rep, truth


def _finding(rep, effect):
    return next(f for f in rep["findings"] if f["effect"] == effect)


def _pull(f, truth, key):
    """(estimate - truth) / reported 1-sigma error."""
    est, err = f["params"][key], f["params_err"][key]
    assert np.isfinite(err) and err > 0, (key, err)
    return (est - truth[key]) / err


def _within_2sigma(f, truth, key):
    assert abs(_pull(f, truth, key)) <= 2, (key, f["params"][key], f["params_err"][key],
                                            truth[key])


CHECKS = {
    "pick": ["dvx_m_per_s"],
    "late_curl": ["k"],
    "friction_patch": ["factor"],
    "ice_slope": ["slope_x_mm_per_m"],
    "velocity_dependent_friction": ["phi_y", "phi_theta"],
}


#: A calibrated 1-sigma error puts the truth outside 2 sigma in 4.6 % of draws, so every
#: single draw is held to 3 sigma (0.27 % by chance) and the 2-sigma coverage is tested
#: over all draws together (test_effect_sizes_within_2sigma_over_all_draws).  (The
#: late_curl draw of seed 12 lies 2.8 sigma out: its fit is converged from any start, the
#: profile likelihood agrees with the covariance, and 40 noise draws of the same shot
#: give pulls with mean -0.18, sd 0.99.)
PULL_MAX = 3.0


def _check_effect(effect, seed):
    rep, truth = _case(effect, seed)
    assert rep["verdict"] == effect, (rep["verdict"], truth)
    f = _finding(rep, effect)
    assert rep["findings"][0]["effect"] == effect
    for key in CHECKS[effect]:
        pull = _pull(f, truth, key)
        assert abs(pull) <= PULL_MAX, (key, f["params"][key], f["params_err"][key],
                                       truth[key], pull)
    if effect == "pick":
        assert abs(f["params"]["t_s"] - truth["t_s"]) < 0.5
    if effect == "friction_patch":
        mid = 0.5 * (f["params"]["y_start_m"] + f["params"]["y_end_m"])
        assert abs(mid - 0.5 * (truth["y_start_m"] + truth["y_end_m"])) < 0.5
    # the gain: the extended model fits and predicts better than the baseline
    assert f["heldout_rmse_after"] < f["heldout_rmse_before"]
    assert f["delta_bic"] > f["threshold"]
    assert not f["structure_after"]["structured"]


# --- default suite: one random draw of the fastest effect, clean shots ------------------

def test_hidden_effect_found_quick():
    """One random pick (the fastest effect); every effect over several draws is slow."""
    _check_effect("pick", seed=101)


def test_clean_shots_give_none():
    """Small version of the false-alarm test: 4 clean shots, at most one alarm (the
    family-wise levels are ~1 % each; the full 40-shot version is slow-marked)."""
    verdicts = []
    for seed in range(7, 11):
        rep, _ = _case_clean(seed)
        verdicts.append(rep["verdict"])
        # the noise is estimated from the data, not assumed
        nz = rep["noise"][0]
        assert nz["x"]["sigma"] == pytest.approx(0.002, rel=0.15)
        assert nz["theta"]["sigma"] == pytest.approx(np.radians(0.3), rel=0.15)
    assert sum(v != "none" for v in verdicts) <= 1, verdicts


def test_close_rivals_make_the_evidence_ambiguous():
    """A name needs delta-BIC ahead of every other candidate by the margin (2 ln B = 6)."""
    from curltrack.discover.report import AMBIGUITY_MARGIN, rivals
    from curltrack.discover.search import CandidateScore

    ln_n = np.log(2000)

    def sc(name, dbic, k, thr=0.0):
        out = CandidateScore(name, dbic, dbic, {"threshold": thr}, None, {}, k=k)
        out.chi2_gain = dbic + k * ln_n
        return out

    patch, pick, late = sc("friction_patch", 1557.4, 3), sc("pick", 1555.8, 2), sc("late_curl", -7.0, 1)
    assert rivals(patch, [patch, pick, late]) == ["pick"]
    far = sc("pick", patch.delta_bic - AMBIGUITY_MARGIN - 0.1, 2)
    assert rivals(patch, [patch, far, late]) == []
    assert rivals(patch, [patch, sc("pick", -np.inf, 2)]) == []
    # the same fit with one parameter more: behind by ln n in delta-BIC, still a rival
    # when it clears its own threshold, not when it does not
    pick = sc("pick", 3.6, 2)
    assert rivals(pick, [pick, sc("friction_patch", 3.6 - ln_n + 0.3, 3, thr=-11.0)]) == \
        ["friction_patch"]
    assert rivals(pick, [pick, sc("friction_patch", 3.6 - ln_n + 0.3, 3, thr=5.0)]) == []
    # fewer parameters and a better fit: the name stands (late curl, lateral kick)
    late, kick = sc("late_curl", 157.8, 1), sc("pick", 144.4, 2, thr=12.0)
    assert late.chi2_gain - kick.chi2_gain == pytest.approx(13.4 - ln_n)
    assert rivals(late, [late, kick]) == []


def test_rivals_are_compared_under_one_noise_level():
    """Each candidate's own delta-BIC is its gain over the level its own residuals
    show; a rival is judged under the best's level.  Two fits that take the same
    chi-square off the baseline are rivals even when the other's residuals read 20 %
    noisier (its own delta-BIC 34 lower)."""
    from curltrack.discover.report import rivals
    from curltrack.discover.search import CandidateScore

    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    n = 1000
    noise = rng.normal(0, 1, n)
    r0 = noise + np.linspace(-1.5, 1.5, n)   # the baseline's misfit: chi-square ~750
    fits = {}
    for name in ("pick", "ice_slope"):
        # the same raw gain: both take the misfit out and leave the noise
        fits[name] = type("Fit", (), {"r": noise.copy(), "n": n})()
    raw = float(np.sum(r0 ** 2) - np.sum(noise ** 2))
    out = []
    for name, level in (("pick", 1.0), ("ice_slope", 1.2)):
        gain = raw / level
        sc = CandidateScore(name, gain - 2 * np.log(n), gain - 2 * np.log(n),
                            {"threshold": 10.0}, fits[name], {}, k=2)
        sc.chi2_gain = gain
        sc._scale = np.full(n, level ** -0.5)
        out.append(sc)
    pick, slope = out
    assert pick.delta_bic - slope.delta_bic > 6, f"seed {seed}"
    assert rivals(pick, out) == [], f"seed {seed}: without r0, own units"
    assert rivals(pick, out, r0=r0) == ["ice_slope"], f"seed {seed}"


def test_ice_slope_is_tested_on_position_only_shots_that_curl_both_ways():
    """Position-only shots whose curls go both ways beyond doubt are spins of both
    sides: a lateral slope is tested (and found) on them; a curl that does not tell its
    side leaves it untested."""
    from curltrack.discover.candidates import untested
    from curltrack.discover.shots import shot_from_series

    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    strength = float(rng.uniform(0.02, 0.04))
    inst = {"noise_class": "white", "rate_hz": 30.0, "theta": False}
    shots, truth = make_case("ice_slope", strength, rng, n_shots=2, instrument=inst)
    data = [shot_from_series(s, None) for s in shots]
    assert all(d.curl_side_sure for d in data) and {d.spin for d in data} == {-1, 1}
    assert "ice_slope" not in untested(data, "paper"), f"seed {seed}"
    data[1].curl_side_sure = False
    assert "ice_slope" in untested(data, "paper"), f"seed {seed}"
    rep = discover(shots, baseline="paper", seed=seed % 1000, n_boot=200)
    found = {f.effect: f for f in rep.findings}["ice_slope"]
    # (named in 8 of 9 draws tried; in one - CI, seed 3337378772 - the slope's drift
    # read as a curl that ends 17 s before the slide, a pick and the slope both fitted
    # it, and the verdict was unexplained: the candidate's estimate there was 19 % off.
    # What must hold: never another name, and a named slope is right.  'none' only where
    # the slope is not told from an instrument's jump, and says so - CI seed 2513568008:
    # a jump explained the baseline's misfit as well and stayed in the slope's residuals
    # - or where the slope is not supported at all: a miss, which these strengths (1-2x
    # the white class's 90 % strength of 0.019 mm/m, README: 5 of 10 named at 2x) allow;
    # CI seed 3489633401: the slope's drift read as a curl ending at 14.6 s, the slope
    # not supported on held-out data, a pick blocked by the jump it leaves)
    jump = any("instrument's jump" in b for b in found.not_named_because or ())
    assert rep.verdict in ("ice_slope", "unexplained") or (
        rep.verdict == "none" and (jump or not found.supported)), \
        f"seed {seed}: {rep.verdict}"
    if rep.verdict == "ice_slope":
        est, err = found.params["slope_x_mm_per_m"], found.params_err["slope_x_mm_per_m"]
        assert abs(est - truth["slope_x_mm_per_m"]) < 3 * err + 0.1 * strength, \
            f"seed {seed}: {est} +- {err} vs {truth}"


def test_every_position_only_curl_that_ends_early_is_fitted():
    """Two clean position-only shots of one sheet whose spins stop before their slides:
    one early (0.3-0.5 of the slide), the other late (0.75-0.88).  The late one's end
    shows only once the early one's is fitted; nothing is named, the early end is
    fitted, and the late one too where the drift it leaves (0.5 a_T dt^2 over the slide
    after it) is over 20 mm, 10x the noise.  (Fitted in one pass, that drift was what
    the candidates competed for: an ice slope drawn with such shots, 28 mm of drift,
    was named 33 % off at 14 sigma - farm seed 89027544.  A smaller one the refit of
    its spin may not earn: 10 mm after a weak curl, BIC +6.7.)"""
    from dataclasses import replace

    from discover._synth import draw_model, ice, make_series
    from curltrack.physics import closed_form as cf

    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    ice_kw = ice(rng)
    shots, drift = [], []
    for spin, frac in ((1, rng.uniform(0.3, 0.5)), (-1, rng.uniform(0.75, 0.88))):
        m = draw_model(rng, spin=spin, ice_kw=ice_kw)
        t_fs = cf.stop_time_translation(m.v0, m.phi_y, m.alpha_y)
        unit = cf.stop_time_rotation(1.0, m.phi_theta, m.alpha_theta_value)
        w = (frac * t_fs / unit) ** (1.0 / (1.0 - m.phi_theta))
        shots.append(make_series(replace(m, omega0=spin * w), (), rng,
                                 instrument={"noise_class": "white", "rate_hz": 10.0,
                                             "theta": False}))
        drift.append(0.5 * m.a_T * ((1.0 - frac) * t_fs) ** 2)
    rep = discover(shots, baseline="paper", seed=seed % 1000, n_boot=100)
    ends = [w for w in rep.warnings if "the curl ends at" in w]
    assert rep.verdict == "none", f"seed {seed}: {rep.verdict}, drift {drift}, {ends}"
    assert len(ends) == (2 if drift[1] > 0.02 else len(ends)) and len(ends) >= 1, \
        f"seed {seed}: drift {drift}: {ends}"


def _case_clean(seed):
    rng = np.random.default_rng(seed)
    shots, truth = make_case("none", 0.0, rng)
    return discover(shots, seed=seed, n_boot=300), truth


# --- slow: every effect over several random draws ---------------------------------------

SEEDS = [11, 12, 13]


@pytest.mark.slow
@pytest.mark.parametrize("effect", sorted(MODERATE))
@pytest.mark.parametrize("seed", SEEDS)
def test_hidden_effect_found(effect, seed):
    _check_effect(effect, seed)


@pytest.mark.slow
def test_effect_sizes_within_2sigma_over_all_draws():
    """The recovered sizes of all draws above: within their reported 2 sigma as often as
    calibrated errors allow (at most the 99 % binomial quantile of misses at 4.55 %)."""
    pulls = []
    for effect in sorted(MODERATE):
        for seed in SEEDS:
            rep, truth = _case(effect, seed)
            if rep["verdict"] != effect:
                continue  # test_hidden_effect_found fails for it
            f = _finding(rep, effect)
            pulls += [(effect, seed, key, _pull(f, truth, key)) for key in CHECKS[effect]]
    assert len(pulls) >= 10
    misses = [p for p in pulls if abs(p[3]) > 2]
    allowed = int(stats.binom.ppf(0.99, len(pulls), 2 * stats.norm.sf(2)))
    assert len(misses) <= allowed, (misses, allowed, len(pulls))


@pytest.mark.slow
@pytest.mark.parametrize("effect", ["late_curl", "pick", "friction_patch"])
def test_reported_errors_are_calibrated(effect):
    """One draw's shot simulated again with 20 fresh noise realisations: the pulls
    (estimate - truth) / error of the effect size have mean ~0 and sd ~1."""
    from curltrack.physics import Effect, ShotModel
    from curltrack.simulate import simulate_series
    from discover._synth import NOISE_M, NOISE_RAD

    rng = np.random.default_rng(77)
    strength = float(rng.uniform(*MODERATE[effect]))
    shots, truth = make_case(effect, strength, rng)
    sim = shots[0].meta["simulation"]
    fields = ("v0", "omega0", "phi_y", "alpha_y", "phi_theta", "alpha_theta", "a_T")
    model = ShotModel(**{k: sim["params"][k] for k in fields})
    effects = [Effect(e["effect"], e["params"]) for e in sim["effects"]]
    key = CHECKS[effect][0]
    pulls = []
    for i in range(20):
        s = simulate_series(model, effects, noise_m=NOISE_M, noise_rad=NOISE_RAD, seed=500 + i)
        rep = discover(s, seed=i, n_boot=50, effects=[effect])
        pulls.append(_pull(_finding(rep, effect), truth, key))
    pulls = np.array(pulls)
    # 20 draws: the mean scatters by 0.22 and the sd by ~0.16 around 1
    assert abs(pulls.mean()) < 0.7, pulls
    assert 0.6 < pulls.std(ddof=1) < 1.5, pulls


@pytest.mark.slow
@pytest.mark.parametrize("seed", [21, 22])
def test_dry_baseline_finds_the_papers_friction_law(seed):
    """The paper's own conclusion: phi ~ -0.7 against dry friction."""
    rng = np.random.default_rng(seed)
    phi = float(rng.uniform(-0.8, -0.6))
    shots, truth = make_case("velocity_dependent_friction", -phi, rng)
    rep = discover(shots, baseline="dry", seed=seed, n_boot=300)
    assert rep["verdict"] == "velocity_dependent_friction"
    f = _finding(rep, "velocity_dependent_friction")
    for key in ("phi_y", "phi_theta"):
        _within_2sigma(f, truth, key)
    assert f["params"]["phi"] == pytest.approx(truth["phi_y"], abs=2 * f["params_err"]["phi"])


@pytest.mark.slow
@pytest.mark.parametrize("seed", [31, 32, 33])
def test_effect_outside_the_list_is_unexplained(seed):
    """Friction that ripples along the ice (six alternating 1.25 m stretches over 7.5 m)
    is not one patch: either unexplained (with where), or a periodic friction field with
    the ripple's period (2.5 m) when the data-driven extension explains it."""
    rng = np.random.default_rng(seed)
    shots, _ = make_case("ripple", float(rng.uniform(0.08, 0.15)), rng)
    rep = discover(shots, seed=seed, n_boot=300)
    assert rep["verdict"] in ("unexplained", "extended"), rep["verdict"]
    if rep["verdict"] == "extended":
        assert rep["extension"]["kind"] == "friction_field"
        assert abs(rep["extension"]["derived"]["wavelength_m"] - 2.5) < 0.3
    else:
        assert rep["unexplained"] is not None
        assert "t_from_s" in rep["unexplained"]


@pytest.mark.slow
def test_false_alarm_rate_on_clean_series():
    """>= 40 clean simulated series: verdict != none at most 5 % of the time."""
    bad = []
    for seed in range(40):
        rep, _ = _case_clean(9000 + seed)
        if rep["verdict"] != "none":
            bad.append(rep["verdict"])
    assert len(bad) <= 2, bad


def test_reused_jacobian_columns_are_the_recomputed_ones():
    """The fit keeps the last Jacobian's columns (a column depends only on the parameter
    values): its final Jacobian, and the first of a fit continued with one more
    parameter free, equal a fresh model's to the last bit."""
    from curltrack.discover.model import JointModel
    from curltrack.discover.shots import shot_from_series

    seed = int(np.random.default_rng().integers(2**31))
    rng = np.random.default_rng(seed)
    shots, _ = make_case("none", 0.0, rng)
    m = JointModel([shot_from_series(s) for s in shots])
    held = m.free.pop(m.free.index("a_T"))
    f1 = m.fit(max_nfev=40)
    fresh = JointModel(m.shots)
    fresh.free = list(m.free)
    assert np.array_equal(f1.J_raw, fresh.jacobian_raw(f1.values)), f"seed {seed}"
    m.free.append(held)
    n_cols = {"n": 0}
    sim = m._simulate

    def counted(*a, **k):
        n_cols["n"] += 1
        return sim(*a, **k)

    m._simulate = counted
    J = m.jacobian_raw(m.values)
    fresh.free = list(m.free)
    assert np.array_equal(J, fresh.jacobian_raw(m.values)), f"seed {seed}"
    assert n_cols["n"] <= 1, f"seed {seed}: only a_T's column is new"


def test_a_patch_refit_widens_a_narrow_deep_start():
    """A strong, wide patch whose refit started narrow and deep (the linear scan ranks
    wide stretches poorly far from the null: factor 0.68 over 3 m under heavy noise
    was refitted as 0.051 over 0.86 m and a pick named, seed 2026112750) ends at the
    truth: the refit is also started from the same deficit spread 2-4x wider
    (:attr:`EffectDef.respread`).  Random patch, noise class and rate per run.  (A
    refit stopped at 3.6 m of a 4.6 m patch, 122 over the truth's chi-square, seed
    1341393448: started 1.5x wider too, it ends at the truth.)"""
    from curltrack.discover.candidates import build_candidates
    from curltrack.discover.model import JointModel
    from curltrack.discover.search import FIT_MAX_NFEV, _respread
    from curltrack.discover.shots import shot_from_series

    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    inst = {"noise_class": str(rng.choice(["white", "heavy"])),
            "rate_hz": float(rng.choice([10.0, 30.0])), "theta": bool(rng.random() < 0.5)}
    f = 2.0
    while f >= 1.0:   # a slippery stretch: its narrow deep twin reaches the bound
        shots, truth = make_case("friction_patch", float(rng.uniform(0.25, 0.35)), rng,
                                 instrument=inst)
        a, b, f = truth["y_start_m"], truth["y_end_m"], truth["factor"]
    sh = [shot_from_series(s) for s in shots]
    base = JointModel(sh, "paper")
    fit0 = base.fit(max_nfev=80)
    cand = next(c for c in build_candidates(sh, "paper") if c.name == "friction_patch")
    # a narrow deep start at the patch's centre: its whole deficit where the factor is
    # at its bound (0.05), the case that stuck
    lower = next(p.lower for p in cand.size if p.name == "factor")
    mid, w = 0.5 * (a + b), (1.0 - f) * (b - a) / (1.0 - 1.02 * lower)
    m = JointModel(sh, "paper", cand)
    m.values.update(fit0.values)
    m.values.update(y_start_m=mid - w / 2, y_end_m=mid + w / 2, factor=1.02 * lower)
    # as the refit does: the location held first, then freed
    free = list(m.free)
    m.free = [p for p in free if p not in ("y_start_m", "y_end_m")]
    m.fit(max_nfev=FIT_MAX_NFEV)
    m.free = free
    fit1 = m.fit(max_nfev=FIT_MAX_NFEV)
    fit2, m2 = _respread(cand, base, fit1, m, "<test>")
    what = f"seed {seed} {inst}: truth {a:.2f}-{b:.2f} m x{f:.3f}"
    assert fit2.chi2 <= fit1.chi2, what
    got = sorted((fit2.values["y_start_m"], fit2.values["y_end_m"]))
    # as low as the fit at the truth's place (the rest fitted), within the 99 % level of
    # chi-square with 3 dof: a patch's ends and factor trade against each other, and
    # where the data hardly tell them apart (4 in chi-square for ends 0.3-0.4 m inside
    # the truth's, seed 2456930937) no fixed tolerance in metres is honest
    mt = JointModel(sh, "paper", cand)
    mt.values.update(fit2.values)
    mt.values.update(y_start_m=a, y_end_m=b, factor=f)
    mt.free = [p for p in free if p not in ("y_start_m", "y_end_m", "factor")]
    at_truth = mt.fit(max_nfev=FIT_MAX_NFEV)
    assert fit2.chi2 <= at_truth.chi2 + 11.34, (what, got, fit2.values["factor"],
                                                 fit2.chi2, at_truth.chi2)
    # and not the narrow deep twin it started from: its width at least half-way (in log)
    # from the start's to the truth's - where the data hardly tell ends from depth, a
    # fixed band is not honest either (seed 1134046439, heavy noise, 10 Hz, no theta:
    # 0.53 over 1.95 m for 0.68 over 3.14 m, within the chi-square level above; the
    # start was 0.34 of the width)
    start = w / (b - a)
    ratio = (got[1] - got[0]) / (b - a)
    assert abs(np.log(ratio)) < 0.5 * abs(np.log(start)) and ratio < 1.4, (
        what, got, fit2.values["factor"], start)


def test_a_strong_wide_patch_under_heavy_noise_is_not_named_a_pick():
    """The case that found it (bench_discover, heavy class at 4x its 90 % strength,
    seed 2026112750: factor 0.68 over 10.9-13.9 m, 10 Hz, theta measured): its refit
    stopped at 0.051 over 11.9-12.8 m and the verdict was ``pick``."""
    rng = np.random.default_rng(2026112750)
    inst = {"noise_class": "heavy", "rate_hz": float(rng.choice([10.0, 30.0])),
            "theta": bool(rng.random() < 0.5)}
    shots, truth = make_case("friction_patch", 0.32, rng, instrument=inst)
    rep = discover(shots, baseline=truth["baseline"], seed=2026112750)
    assert rep["verdict"] == "friction_patch", rep.summary()
    f = next(f for f in rep.findings if f.effect == "friction_patch")
    assert abs(f.params["factor"] - truth["factor"]) < 0.05, f.params
