"""The fit core against series with known parameters (closed forms + seeded noise)."""

import json
from dataclasses import replace

import numpy as np
import pytest

from curltrack.errors import FitError
from curltrack.fit import fit_series
from synth import closed_form_series

NOISE = dict(noise_m=0.002, noise_rad=np.radians(0.3))


def _cases(n, seed):
    """Draw/RRSS-like shots with parameters drawn from the paper's observed ranges."""
    rng = np.random.default_rng(seed)
    for _ in range(n):
        yield dict(lam_theta=rng.uniform(1.2, 1.7), lam_y=rng.uniform(1.75, 2.3),
                   t_F=rng.uniform(12, 26), theta_F=rng.uniform(6, 30),
                   y_F=rng.uniform(3, 28), a_T=rng.choice([-1, 1]) * rng.uniform(2e-3, 8e-3),
                   skew_deg=rng.uniform(-2.5, 2.5), seed=int(rng.integers(1 << 30)))


@pytest.mark.parametrize("case", list(_cases(10, seed=11)))
def test_exact_recovery_without_noise(case):
    res = fit_series(closed_form_series(**case))
    v = res.values
    assert v["lambda_theta"] == pytest.approx(case["lam_theta"], abs=0.002)
    assert v["lambda_y"] == pytest.approx(case["lam_y"], abs=0.002)
    assert v["lambda_x"] == pytest.approx(case["lam_y"], abs=0.002)
    assert v["a_T"] == pytest.approx(case["a_T"], rel=1e-3)
    assert v["skew_deg"] == pytest.approx(-case["skew_deg"], abs=1e-3)
    assert v["t_FS"] == pytest.approx(case["t_F"], abs=1e-3)


@pytest.mark.parametrize("case", list(_cases(4, seed=12)))
def test_recovery_with_noise(case):
    res = fit_series(closed_form_series(**case, **NOISE))
    v = res.values
    assert v["lambda_theta"] == pytest.approx(case["lam_theta"], abs=0.01)
    assert v["lambda_y"] == pytest.approx(case["lam_y"], abs=0.01)
    # honest rms: the noise that was put in
    assert v["rms_theta"] == pytest.approx(NOISE["noise_rad"], rel=0.15)
    assert v["rms_y"] == pytest.approx(NOISE["noise_m"], rel=0.15)


def test_free_lambda_curl_recovered():
    """x(t) generated with its own λ (the paper's Fig. 5: λ = 1.43 vs λy = 1.897)."""
    s = closed_form_series(lam_x=1.43, a_T=-4.6e-3, **NOISE, seed=3)
    v = fit_series(s).values
    assert v["lambda_x"] == pytest.approx(1.43, abs=0.03)
    assert v["a_T_free"] == pytest.approx(-4.6e-3, rel=0.03)
    assert v["lambda_y"] == pytest.approx(1.897, abs=0.01)


def test_fixed_stop_uses_sidecar_stop_and_reports_detected():
    s = closed_form_series(**NOISE).with_meta(t_stop_translation=23.9)
    res = fit_series(s, fixed_stop=True)
    assert res.values["t_FS"] == 23.9
    assert res.to_dict()["t_FS_detected"] == 23.9
    assert res.errors["t_FS"] is None or res.errors["t_FS"] == 0


def test_jointly_fitted_stop_removes_early_detection_bias():
    """A stop detected 4 frames early biases λ with --fixed-stop, not with t_F free."""
    s = closed_form_series(lam_y=1.85, **NOISE, seed=5).with_meta(
        t_stop_translation=24.0 - 4 / 30, t_stop_rotation=24.0 - 4 / 30)
    free = fit_series(s).values
    assert free["t_FS"] == pytest.approx(24.0, abs=1 / 30)
    assert free["lambda_y"] == pytest.approx(1.85, abs=0.01)


@pytest.mark.parametrize("kind, lam_theta, lam_y, theta_F, y_F, expect", [
    ("pure rotation", 1.586, 2.0, 65.0, 0.0, "pure_rotation"),
    ("rrss", 1.569, 2.268, 280.0, 1.5, "rrss"),
    ("draw", 1.455, 1.897, 17.0, 25.0, "draw"),
])
def test_shot_types_and_null_keys(kind, lam_theta, lam_y, theta_F, y_F, expect):
    s = closed_form_series(lam_theta=lam_theta, lam_y=lam_y, theta_F=theta_F, y_F=y_F,
                           a_T=-2e-3 if y_F else 0.0, **NOISE)
    d = fit_series(s).to_dict()
    assert d["shot_type"] == expect
    if expect == "pure_rotation":
        assert d["lambda_y"] is None and d["v0"] is None and d["C_omega"] is None
        assert d["phi_theta"] == pytest.approx(-0.707, abs=0.01)
    if expect == "rrss":
        assert d["C_omega"] is None and d["C_y"] == pytest.approx(1.77, abs=0.03)
        assert d["phi_theta"] == pytest.approx(-0.7575, abs=0.01)
    if expect == "draw":
        assert d["C_y"] is None and d["phi_theta"] is None
        assert d["C_omega"] == pytest.approx(2.54, abs=0.03)
    json.dumps(d, allow_nan=False)  # strictly valid JSON


def test_never_stopping_shot_is_fitted_with_a_warning():
    s = closed_form_series(**NOISE)
    cut = s.data["t"] < 20.0
    s = replace(s, data=s.data[cut]).with_meta(t_stop_translation=None, t_stop_rotation=None)
    res = fit_series(s)
    assert any("no stop within the series" in w for w in res.warnings)
    assert res.values["lambda_y"] == pytest.approx(1.897, abs=0.03)
    with pytest.raises(FitError, match="never stopped"):
        fit_series(s, fixed_stop=True)


def test_too_few_points_is_a_clear_error():
    s = closed_form_series()
    s = replace(s, data=s.data.iloc[:8])
    with pytest.raises(FitError, match="too few"):
        fit_series(s)


@pytest.mark.slow
def test_uncertainties_are_honest():
    """Truth inside 2σ in >= 90% of 60 seeded noisy trials, for each λ."""
    hits = {"lambda_theta": 0, "lambda_y": 0, "a_T": 0}
    cases = list(_cases(60, seed=99))
    for case in cases:
        res = fit_series(closed_form_series(**case, **NOISE))
        truth = {"lambda_theta": case["lam_theta"], "lambda_y": case["lam_y"],
                 "a_T": case["a_T"]}
        for k in hits:
            hits[k] += abs(res.values[k] - truth[k]) <= 2 * res.errors[k]
    for k, n in hits.items():
        assert n / len(cases) >= 0.90, (k, n)


def test_series_is_not_changed_and_a_second_fit_warns_again():
    """fit_series never edits the series it is given: without a sidecar's stop times
    both calls detect them and say so."""
    s = closed_form_series(**NOISE)
    meta = {k: v for k, v in s.meta.items() if not k.startswith("t_stop")}
    s = replace(s, meta=meta)
    before = json.dumps(s.meta, sort_keys=True, default=str)
    data = s.data.copy()
    w1, w2 = fit_series(s).warnings, fit_series(s).warnings
    assert any("no sidecar with stop times" in w for w in w1) and w1 == w2
    assert json.dumps(s.meta, sort_keys=True, default=str) == before
    assert s.data.equals(data)


def test_weights_are_the_measured_noise_not_the_claimed_one():
    """A tracker that claims 3x its real noise (sigma_xy column) does not make the fit
    look 9x too good: the level comes from the data (as discover weighs the shot), the
    column only shapes it from frame to frame."""
    entropy = np.random.SeedSequence().entropy
    rng = np.random.default_rng(entropy)
    case = next(_cases(1, int(rng.integers(1 << 30))))
    s = closed_form_series(**case, **NOISE)
    data = s.data.assign(sigma_xy=3 * NOISE["noise_m"], sigma_theta=3 * NOISE["noise_rad"])
    extra = fit_series(replace(s, data=data)).to_dict()
    for key in ("chisqr_reduced_xy", "chisqr_reduced_theta"):
        assert 0.75 < extra[key] < 1.3, (key, extra[key], f"entropy {entropy}")


# --- honest on data we did not make (issue 18) -------------------------------------------

def _entropy():
    return int(np.random.SeedSequence().entropy % (1 << 32))


@pytest.mark.parametrize("noise_class,noise_m,min_hits", [("white", 0.002, 15),
                                                          ("steps", 0.05, 14)])
def test_position_only_10hz_clockwise_draw_from_1s(noise_class, noise_m, min_hits):
    """A 10 Hz x, y series (no theta) of a clockwise draw whose first row is 1 s after
    release, simulated (curved path, tapered a_T): lambda_y within its 2 sigma."""
    from curltrack.instrument import Sampling
    from curltrack.physics import ShotModel
    from curltrack.simulate import simulate_series

    seed = _entropy()
    rng = np.random.default_rng(seed)
    hits = 0
    for _ in range(20):
        m = ShotModel(v0=rng.uniform(1.5, 2.2), omega0=-rng.uniform(0.8, 3.0))
        s = simulate_series(m, noise_m=noise_m, noise_class=noise_class,
                            seed=int(rng.integers(1 << 30)), theta_measured=False,
                            sampling=Sampling(rate_hz=10, jitter_s=0.003, start_s=1.0,
                                              n_gaps=1))
        assert s.data["theta"].isna().all() and s.meta["theta_measured"] is False
        res = fit_series(s)
        v, e = res.values, res.errors
        assert v["lambda_theta"] is None and v["omega0"] is None, seed
        assert any("position-only" in w for w in res.warnings), seed
        assert v["a_T"] > 0, seed  # clockwise spin curls to +x
        hits += abs(v["lambda_y"] - m.lambda_y) <= 2 * e["lambda_y"]
    # 20 draws. White noise: 2 sigma holds for 96.3 % (289/300 draws, pull SD 1.00), so
    # P(< 15 hits) = 0.006 % (0.03 % at a nominal 95 %); the bound was 16, and CI drew
    # 15/20 (seed 196456212, a 0.07 % tail at the measured coverage).  Under an
    # instrument's persisting steps (~10 effective points per coordinate) the measured
    # coverage is 90 % (135/150 draws, with fit.small_sample_factor; 85 % without it):
    # P(< 14 hits | 90 %) = 0.2 %, while 70 % coverage fails 4 runs in 10.
    assert hits >= min_hits, f"seed {seed}: lambda_y within 2 sigma in {hits}/20"


def test_curl_errors_cover_the_small_angle_approximation():
    """The paper's x(t) is small-angle; a rock's a_T turns with its heading.  On shots of
    the paper's model (exact heading) at 0.5-2 mm, 10 or 30 Hz, its fit read |a_T| ~0.13 %
    low and lambda_x ~0.006 high: pull SDs 5.6 (a_T) and 4.1 (lambda_x) over 30 draws,
    up to 20 sigma - the errors had only the noise.  With the approximation's own error
    (forward-simulated at the fitted values) in them: SDs 0.9 and 0.5-0.7."""
    from curltrack.physics import ShotModel
    from curltrack.simulate import simulate_series

    seed = _entropy()
    rng = np.random.default_rng(seed)
    pulls = {"a_T": [], "a_T_free": [], "lambda_x": []}
    for _ in range(12):
        m = ShotModel(v0=rng.uniform(1.5, 2.6), omega0=rng.choice([-1, 1]) * rng.uniform(0.8, 3),
                      a_T=rng.uniform(0.003, 0.008))
        s = simulate_series(m, noise_m=float(rng.choice([0.0005, 0.001, 0.002])),
                            noise_rad=0.005, seed=int(rng.integers(1 << 30)),
                            fps=float(rng.choice([10.0, 30.0])))
        res = fit_series(s)
        a_T = -np.sign(m.omega0) * m.a_T
        for k, truth in (("a_T", a_T), ("a_T_free", a_T), ("lambda_x", m.lambda_y)):
            pulls[k].append((res.values[k] - truth) / res.errors[k])
    for k, z in pulls.items():
        z = np.abs(z)
        # (12 draws: a calibrated pull exceeds 3 in 3 % of runs; the old errors, 12 in 12)
        assert np.sqrt(np.mean(z ** 2)) < 1.6 and z.max() < 4.0, \
            f"seed {seed}: {k} pulls {np.round(z, 1)}"


def test_a_series_that_ends_at_the_stop():
    """An instrument that stops recording when the rock stops: no rows at rest, so no
    stop is detected, and t_F was bounded below by the last row - held there, lambda_y
    pulls up to 3.5 and t_F's up to 44 over 30 draws cut within 0.3 s of the stop
    (a helper's finding).  Now t_F is free below the last row: pulls rms 0.8-0.9."""
    from curltrack.physics import ShotModel
    from curltrack.simulate import simulate_series

    seed = _entropy()
    rng = np.random.default_rng(seed)
    pulls = []
    for _ in range(12):
        m = ShotModel(v0=rng.uniform(1.4, 2.4), omega0=rng.choice([-1, 1]) * rng.uniform(0.8, 2.5))
        s = simulate_series(m, noise_m=0.002, noise_rad=0.005, seed=int(rng.integers(1 << 30)),
                            fps=float(rng.choice([10.0, 30.0])))
        t_stop = s.meta["t_stop_translation"]
        d = s.data[s.data.t <= t_stop + rng.uniform(-0.3, 0.3)].reset_index(drop=True)
        meta = {k: v for k, v in s.meta.items() if not k.startswith(("t_stop", "stop_frame"))}
        res = fit_series(replace(s, data=d, meta=meta))
        v, e = res.values, res.errors
        pulls.append([(v["lambda_y"] - m.lambda_y) / e["lambda_y"],
                      (v["t_FS"] - t_stop) / e["t_FS"]])
    z = np.abs(pulls)
    assert z.max() < 4.0 and np.sqrt(np.mean(z ** 2)) < 1.6, f"seed {seed}: {np.round(z, 1)}"


def test_a_series_from_another_origin_fits_alike():
    """Any origin and a turn the skew takes: the fit's offsets started at (0, 0), and a
    shot 30 m off and turned 9 deg converged to v0 = -0.0006 m/s and was refused (found
    through discover's starting values).  They start at the rock's own origin now."""
    from curltrack.physics import ShotModel
    from curltrack.simulate import simulate_series

    seed = _entropy()
    rng = np.random.default_rng(seed)
    for _ in range(10):   # (the old start failed ~1 draw in 20)
        s = simulate_series(ShotModel(v0=rng.uniform(1.5, 2.2),
                                      omega0=rng.choice([-1, 1]) * rng.uniform(0.8, 2.5)),
                            noise_m=0.002, noise_rad=0.005, seed=int(rng.integers(1 << 30)))
        dx, dy = rng.choice([-1, 1], 2) * rng.uniform(1.5, 40.0, 2)
        turn = np.radians(rng.uniform(-12.0, 12.0))
        c, sn = np.cos(turn), np.sin(turn)
        d = s.data
        moved = replace(s, data=d.assign(x=dx + c * d.x - sn * d.y, y=dy + sn * d.x + c * d.y,
                                         theta=d.theta + rng.uniform(-50, 50)))
        a, b = fit_series(s).values, fit_series(moved).values
        for k in ("lambda_y", "lambda_theta", "v0", "a_T", "omega0"):
            assert b[k] == pytest.approx(a[k], rel=1e-3, abs=1e-6), (seed, k, a[k], b[k])


def test_failed_secondary_fit_is_a_warning_with_null_keys(monkeypatch):
    import curltrack.fit as fit_mod

    real = fit_mod.fit_translation

    def flaky(*args, **kw):
        if (len(args) > 5 and args[5]) or kw.get("free_lambda"):
            raise FitError("translation (lambda free) fit did not converge (test)",
                           path="s.csv")
        return real(*args, **kw)

    monkeypatch.setattr(fit_mod, "fit_translation", flaky)
    res = fit_series(closed_form_series(**NOISE, seed=_entropy()))
    d = res.to_dict()
    for k in ("a_T_free", "lambda_x", "x_F_free"):
        assert d[k] is None and d[f"{k}_err"] is None
    assert d["lambda_y"] is not None and d["a_T"] is not None
    assert any("lambda free" in w and "null" in w for w in res.warnings)


def test_misfit_is_warned_and_errors_scaled():
    """A strong friction patch under the paper's fit: a warning naming the misfit and
    pointing to discover; the errors grow with the residuals' correlation."""
    from curltrack.physics import Effect, ShotModel
    from curltrack.simulate import simulate_series

    seed = _entropy()
    rng = np.random.default_rng(seed)
    m = ShotModel(v0=rng.uniform(1.6, 2.0), omega0=rng.uniform(1.0, 2.0))
    a = rng.uniform(4.0, 8.0)
    s = simulate_series(m, [Effect("friction_patch", {"y_start_m": a, "y_end_m": a + 3,
                                                     "factor": 1.6})],
                        noise_m=0.001, noise_rad=0.003, seed=seed)
    res = fit_series(s)
    assert any("misfit" in w and "discover" in w for w in res.warnings), (seed, res.warnings)
    assert res.extra["error_inflation_xy"] > 2, seed
    clean = fit_series(simulate_series(m, noise_m=0.001, noise_rad=0.003, seed=seed))
    assert not any("misfit" in w for w in clean.warnings), (seed, clean.warnings)
    assert clean.extra["error_inflation_xy"] < 1.5, seed


def test_noise_free_draws_are_no_misfit_but_a_noise_free_effect_is():
    """What the closed forms miss of the model they approximate (the small-angle x,
    ~0.1 mm) is no misfit, even where the noise is nil (a noise-free draw of
    ``simulate`` read 300x its numerical noise before); a friction patch in the same
    noise-free draw still is."""
    from curltrack.physics import Effect, ShotModel
    from curltrack.simulate import simulate_series

    seed = _entropy()
    rng = np.random.default_rng(seed)
    m = ShotModel(v0=rng.uniform(1.6, 2.4), omega0=rng.choice([-1, 1]) * rng.uniform(0.5, 2.5),
                  phi_y=rng.uniform(-0.4, 0.0))
    clean = fit_series(simulate_series(m, seed=seed))
    assert clean.values["rms_x"] < 1e-3, seed   # the closed forms' own residual: tiny
    assert not any("misfit" in w for w in clean.warnings), (seed, clean.warnings)
    a = rng.uniform(4.0, 8.0)
    patch = fit_series(simulate_series(
        m, [Effect("friction_patch", {"y_start_m": a, "y_end_m": a + 3, "factor": 1.3})],
        seed=seed))
    assert any("misfit" in w for w in patch.warnings), (seed, patch.warnings)


def test_plot_curves_in_the_points_frame(monkeypatch, tmp_path):
    """A 3-5 degree off-line throw with a lambda-free curl: the lambda-free curve of the
    x panel lies on its points (that fit has its own deskew angle)."""
    import curltrack.plots as plots

    seed = _entropy()
    rng = np.random.default_rng(seed)
    s = closed_form_series(lam_x=1.5, a_T=-5e-3, skew_deg=rng.choice([-1, 1]) *
                           rng.uniform(3, 5), noise_m=0.0005, noise_rad=0.002, seed=seed)
    res = fit_series(s)
    figs = []
    monkeypatch.setattr(plots, "save", lambda fig, path: figs.append(fig))
    plots.plot_fit(s, res, tmp_path / "f.png")
    ax = figs[0].axes[0]  # x panel
    pts = next(ln for ln in ax.lines if ln.get_linestyle() == "None")
    tp, xp = pts.get_data()
    # the lambda-free curve is the model that made the data: it must sit on the points
    # (the tied curve need not: lambda_x differs from lambda_y here)
    for ln in [ln for ln in ax.lines if "free" in str(ln.get_label())]:
        tc, xc = ln.get_data()
        off = np.abs(np.interp(tp, tc, xc) - xp)
        assert np.median(off) < 0.003, (seed, ln.get_label(), float(np.median(off)))


def test_position_only_misfit_names_a_curl_that_ends_early():
    """Position-only draws whose spin stops at 40-70 % of the slide (the curl ends with
    it): the misfit warning says the misfit is across the path and what looks like it;
    a friction patch (a misfit along the path) is not given that cause."""
    from curltrack.instrument import Sampling
    from curltrack.physics import Effect, ShotModel
    from curltrack.physics import closed_form as cf
    from curltrack.simulate import simulate_series

    seed = _entropy()
    rng = np.random.default_rng(seed)
    m = ShotModel(v0=float(rng.uniform(1.6, 2.2)), omega0=1.0)
    t_tr = cf.stop_time_translation(m.v0, m.phi_y, m.alpha_y)
    t_rot = float(rng.uniform(0.4, 0.7)) * t_tr
    unit = cf.stop_time_rotation(1.0, m.phi_theta, m.alpha_theta_value)
    w0 = float(rng.choice([-1, 1])) * (t_rot / unit) ** (1.0 / (1.0 - m.phi_theta))
    sampling = Sampling(rate_hz=float(rng.choice([10.0, 30.0])))
    s = simulate_series(ShotModel(v0=m.v0, omega0=w0, alpha_theta=m.alpha_theta_value),
                        noise_m=0.002, seed=int(rng.integers(1 << 30)),
                        theta_measured=False, sampling=sampling)
    said = [w for w in fit_series(s).warnings if "misfit" in w]
    assert len(said) == 1 and "curl that ends before the rock stops" in said[0], \
        (seed, said)
    a = float(rng.uniform(4.0, 8.0))
    patch = simulate_series(ShotModel(v0=m.v0, omega0=float(rng.uniform(1.0, 2.0))),
                            [Effect("friction_patch", {"y_start_m": a, "y_end_m": a + 3,
                                                       "factor": 1.6})],
                            noise_m=0.002, seed=int(rng.integers(1 << 30)),
                            theta_measured=False, sampling=sampling)
    said = [w for w in fit_series(patch).warnings if "misfit" in w]
    assert len(said) == 1 and "curl that ends" not in said[0], (seed, said)
