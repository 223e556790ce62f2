"""Discovery beyond its vocabulary: hidden terms outside the named effects are found,
described in physical terms with numbers that agree with the truth, and kept out of
clean shots.

The worlds come from an independent integrator (``_world.integrate``: solve_ivp of the
paper's equations + the hidden term, written here, not taken from the code under test).
Strengths, places, signs, shots and seeds are drawn at random; the seed of every case is
in the assertion message.  "Moderate" strengths (``MODERATE``) are ~3x the strength
where ``scripts/bench_extend.py`` starts detecting the family every time.
"""

import math
import re

import numpy as np
import pytest

from discover._world import (FAMILIES, NOISE_M, NOISE_RAD, G, V_STOP, _alpha_theta,
                             curve_pulls, draw_ice, integrate, make_peer_law_world,
                             make_world)
from curltrack.discover import discover
from curltrack.physics import Effect, ShotModel, simulate

#: moderate strengths per family (see scripts/bench_extend.py and the README table)
MODERATE = {
    "friction_field": (0.02, 0.04),          # relative amplitude, wavelength 2-5 m
    "spin_coupling": (0.1, 0.2),             # |c| s/m
    "translation_coupling": (0.05, 0.1),     # |c| s/rad
    "curl_spin_dependence": (0.8, 1.2),      # p
    "friction_law": (0.1, 0.2),              # |dphi_low|, knee 0.25-0.8 m/s
}


def _seed():
    return int(np.random.SeedSequence().entropy % 2**31)


@pytest.mark.parametrize("family", FAMILIES)
def test_simulator_terms_agree_with_independent_integrator(family):
    """The physics core's extension terms integrate the same equations as the test's own
    solve_ivp (different state variables, different code) to 1/40 of the noise (5e-5 m,
    1.3e-4 rad; the core runs extensions at rtol 1e-8: ~1e-5 m over a 25 m draw)."""
    seed = _seed()
    rng = np.random.default_rng(seed)
    ice = draw_ice(rng)
    v0, w0 = float(rng.uniform(1.5, 2.3)), float(rng.choice([-1, 1]) * rng.uniform(1, 2.5))
    a_th = _alpha_theta(v0, w0, ice, float(rng.uniform(0.6, 1.0)))
    lam, a, b = float(rng.uniform(1.0, 5.0)), float(rng.uniform(-0.2, 0.2)), float(rng.uniform(-0.2, 0.2))
    c, p, w_ref = float(rng.uniform(-0.3, 0.5)), float(rng.uniform(-1.5, 2.0)), float(rng.uniform(0.5, 2))
    d, u_k = float(rng.uniform(-0.8, 0.8)), float(rng.uniform(0.1, 1.0))
    field = lambda y, v, w: 1 + a * math.cos(2 * math.pi * y / lam) + b * math.sin(2 * math.pi * y / lam)  # noqa: E731
    hidden, eff = {
        "friction_field": ({"fric": field, "spin": field},
                           Effect("friction_field", {"wavelength_m": lam, "amp_cos": a, "amp_sin": b})),
        "spin_coupling": ({"spin": lambda y, v, w: 1 + c * v}, Effect("spin_coupling", {"c_s_per_m": c})),
        "translation_coupling": ({"fric": lambda y, v, w: 1 + c * w},
                                 Effect("translation_coupling", {"c_s_per_rad": c})),
        "curl_spin_dependence": ({"curl": lambda v, w: ((w * w + 0.05**2) / w_ref**2) ** (p / 2)},
                                 Effect("curl_spin_dependence", {"p": p, "omega_ref_rad_per_s": w_ref})),
        "friction_law": ({"fric": lambda y, v, w: (1 + u_k**2 / (v * v + 1e-300)) ** (d / 2)
                          * (1 + 0.02**2 / (v * v + 1e-300)) ** (-d / 2)},
                         Effect("friction_law", {"dphi_low": d, "u_knee_m_per_s": u_k})),
    }[family]
    t, x, y, th, t_tr, t_rot = integrate(v0, w0, ice["phi_y"], ice["alpha_y"], ice["phi_t"],
                                         a_th, ice["a_T"], hidden)
    m = ShotModel(v0=v0, omega0=w0, phi_y=ice["phi_y"], alpha_y=ice["alpha_y"],
                  phi_theta=ice["phi_t"], alpha_theta=a_th, a_T=ice["a_T"])
    tr = simulate(m, [eff], t=t)
    # each coordinate to 1/40 of its noise: 5e-5 m, 1.3e-4 rad (theta's last ~1e-4 s of
    # spin, where omega^phi_theta diverges, differs by ~5e-5 rad between the two)
    err = max(np.abs(tr.x - x).max(), np.abs(tr.y - y).max()) / NOISE_M
    err = max(err, np.abs(tr.theta - th).max() / NOISE_RAD)
    assert err < 1 / 40, (seed, family, err)
    # stop times to 1e-4 s, or 5e-6 of a long slide's duration (its final approach is flat:
    # 32 s slides differed by 1.4e-4 s between the two integrators' stop events), or twice
    # the time the test's integrator leaves out by stopping at V_STOP (a friction law
    # that falls towards low speed decelerates the last 1e-5 m/s slowly: 8e-4 s)
    fric = hidden.get("fric", lambda *a: 1.0)
    a_stop = ice["alpha_y"] * G * V_STOP ** ice["phi_y"] * fric(0.0, V_STOP, 0.0)
    tol_tr = max(1e-4, 5e-6 * t_tr, 2.0 * V_STOP / a_stop)
    tol_rot = max(1e-4, 5e-6 * t_rot)
    assert (abs(tr.t_stop_translation - t_tr) < tol_tr
            and abs(tr.t_stop_rotation - t_rot) < tol_rot), seed


def _numbers(summary):
    return [float(v) for v in re.findall(r"-?\d+\.\d+", summary)]


def _check_case(family, seed, n_boot=300):
    """(ok, message): verdict extended, right kind, the numbers within 2 sigma of truth
    and printed in the summary."""
    rng = np.random.default_rng(seed)
    strength = float(rng.uniform(*MODERATE[family]))
    shots, truth = make_world(family, strength, rng)
    rep = discover(shots, seed=seed, n_boot=n_boot)
    ext = rep.get("extension")
    msg = (f"seed {seed} {family} strength {strength:.3g} truth {truth}: verdict "
           f"{rep['verdict']} extension {ext and ext['summary']}")
    if rep["verdict"] != "extended" or ext["kind"] != family:
        return False, msg
    d = ext["derived"]
    keys = {"friction_field": [("amplitude", "amplitude"), ("wavelength_m", "wavelength_m")],
            "spin_coupling": [("c_s_per_m", "c_s_per_m")],
            "translation_coupling": [("c_s_per_rad", "c_s_per_rad")],
            "curl_spin_dependence": [("p", "p")],
            "friction_law": [("dphi_low", "dphi_low")]}[family]
    nums = _numbers(ext["summary"])
    for key, tkey in keys:
        est, err = d[key], d[f"{key}_err"]
        scale = 100.0 if key == "amplitude" else 1.0   # printed in %
        if not (np.isfinite(err) and err > 0 and abs(est - truth[tkey]) <= 2 * err):
            return False, msg + f"; {key} {est:.4g} +- {err:.2g}, truth {truth[tkey]:.4g}"
        if not any(abs(n - scale * est) <= 0.06 * scale * err + 1e-9 for n in nums):
            return False, msg + f"; {key} = {est} not in the summary"
    if family == "friction_law":   # the mu(u) curve within its 2-sigma band
        cp = curve_pulls(ext, truth)
        if not np.abs(cp).max() <= 2.0:
            return False, msg + f"; mu(u) off the truth by {np.abs(cp).max():.2f} sigma"
    f = ext["function"]
    assert len(f["x"]) == len(f["value"]) == len(f["band_lo"]) == len(f["band_hi"]) > 10
    assert np.all(np.asarray(f["band_lo"]) <= np.asarray(f["value"]) + 1e-12)
    assert ext["heldout_rmse_after"] < ext["heldout_rmse_before"]
    assert ext["delta_bic"] > ext["threshold"]
    return True, msg


@pytest.mark.slow
@pytest.mark.parametrize("family", ["friction_field", "translation_coupling"])
def test_hidden_term_is_described(family):
    """One random case per family: extended, right kind, numbers within 2 sigma of the
    truth.  Slow, not in the default suite: measured 6/12 accurate and 10/12 right kind
    (README), and a translation coupling of 0.058 s/rad was once named ``pick``
    (seed 1822338106) - a random case fails too often to gate the suite."""
    ok, msg = _check_case(family, _seed())
    assert ok, msg


@pytest.mark.slow
@pytest.mark.parametrize("family", FAMILIES)
def test_hidden_term_recovered_in_80_percent(family):
    """10 random cases per family at moderate strength: right kind and numbers within 2
    sigma in >= 80 % of them."""
    seed0 = _seed()
    results = [_check_case(family, seed0 + i, n_boot=200) for i in range(10)]
    good = sum(ok for ok, _ in results)
    assert good >= 8, [m for ok, m in results if not ok]


@pytest.mark.slow
def test_clean_worlds_stay_none():
    """20 clean shots of the independent integrator, the real-data issue's noise classes
    in turn (white, ar1, steps, heavy): verdict none in >= 19."""
    from curltrack.instrument import NOISE_CLASSES

    seed0 = _seed()
    bad = []
    for i in range(20):
        rng = np.random.default_rng(seed0 + i)
        shots, _ = make_world("none", 0.0, rng, noise=NOISE_CLASSES[i % len(NOISE_CLASSES)])
        rep = discover(shots, seed=seed0 + i, n_boot=200)
        if rep["verdict"] != "none":
            bad.append((seed0 + i, NOISE_CLASSES[i % len(NOISE_CLASSES)], rep["verdict"],
                        (rep.get("extension") or {}).get("kind")))
    assert len(bad) <= 1, bad


@pytest.mark.slow
def test_peer_friction_law_is_a_friction_law():
    """Two draws (slow and fast spin) whose friction is a constant plus a term falling
    as u^(-1/2) (a peer simulator's law, integrated by the test's own solve_ivp, not
    discovery's bent power law): verdict extended with kind friction_law - not a patch,
    a slope, a pick or a spin coupling - and
    the fitted mu(u) within 3 sigma of the true law where the draw weighs it (the family
    only approximates this law: 3, not 2)."""
    seed = _seed()
    rng = np.random.default_rng(seed)
    shots, truth = make_peer_law_world(rng)
    rep = discover(shots, seed=seed, n_boot=300)
    ext = rep.get("extension")
    assert rep["verdict"] == "extended" and ext["kind"] == "friction_law", \
        (seed, rep["verdict"], [(f["effect"], f["delta_bic"]) for f in rep["findings"]])
    f = ext["function"]
    u = np.asarray(f["x"])
    sel = (u >= 0.15) & (u <= 0.8 * u.max())
    band = 0.5 * (np.asarray(f["band_hi"]) - np.asarray(f["band_lo"]))[sel]
    pull = (np.asarray(f["value"])[sel] - truth["mu"](u[sel])) / band
    assert np.abs(pull).max() <= 3.0, (seed, np.abs(pull).max(), ext["summary"])
