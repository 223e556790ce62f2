"""Each extension term against an independent calculation of what it should do."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from curltrack.errors import ParameterError
from curltrack.physics import Effect, ShotModel, simulate
from curltrack.physics.effects import EFFECTS, gather
from curltrack.rig import G

RNG = np.random.default_rng(7)


@pytest.mark.parametrize("slope", RNG.uniform(-5.0, 5.0, 4))
def test_slope_along_y_dry_friction_is_exact(slope):
    """phi = 0, no spin: constant deceleration alpha g + g sin(beta) along y."""
    alpha, v0 = 0.0076, 2.0
    m = ShotModel(v0=v0, omega0=0.0, phi_y=0.0, alpha_y=alpha)
    decel = alpha * G + G * math.sin(math.atan(slope * 1e-3))
    t_F = v0 / decel
    t = np.linspace(0, 1.2 * t_F, 200)
    tr = simulate(m, (Effect("ice_slope", {"slope_y_mm_per_m": slope}),), t=t)
    assert tr.t_stop_translation == pytest.approx(t_F, rel=1e-6)
    tt = np.minimum(t, t_F)
    np.testing.assert_allclose(tr.y, v0 * tt - 0.5 * decel * tt**2, atol=1e-6)
    assert np.abs(tr.x).max() < 1e-9


@pytest.mark.parametrize("sx,sy,phi", [(*RNG.uniform(-4, 4, 2), RNG.uniform(-0.5, 0.3))
                                       for _ in range(3)])
def test_slope_matches_independent_cartesian_integration(sx, sy, phi):
    """Polar (w, psi) equations vs. a plain Cartesian integration of F = -mu M g v_hat + slope."""
    alpha, v0 = 0.008, 2.2
    m = ShotModel(v0=v0, omega0=0.0, phi_y=phi, alpha_y=alpha)
    eff = (Effect("ice_slope", {"slope_x_mm_per_m": sx, "slope_y_mm_per_m": sy}),)
    ax, ay = (-G * math.sin(math.atan(s * 1e-3)) for s in (sx, sy))

    def rhs(_t, z):
        vx, vy = z[2], z[3]
        v = math.hypot(vx, vy)
        f = alpha * G * v**phi
        return [vx, vy, -f * vx / v + ax, -f * vy / v + ay]

    t_end = 0.85 * simulate(m, eff, t=[120.0]).t_stop_translation   # well above the taper
    t = np.linspace(0, t_end, 60)
    ref = solve_ivp(rhs, (0, t_end), [0, 0, 0, v0], t_eval=t, rtol=1e-11, atol=1e-12)
    tr = simulate(m, eff, t=t)
    np.testing.assert_allclose(tr.x, ref.y[0], atol=2e-6)
    np.testing.assert_allclose(tr.y, ref.y[1], atol=2e-6)
    assert abs(tr.x[-1]) > 0.01 or abs(sx) < 0.5   # the slope really moved it sideways


def test_rock_stays_put_on_a_slope_after_stopping():
    eff = (Effect("ice_slope", {"slope_x_mm_per_m": 3.0, "slope_y_mm_per_m": -2.0}),)
    tr = simulate(ShotModel(v0=2.0, omega0=1.5), eff, t=np.linspace(0, 60, 121))
    after = tr.t > tr.t_stop_translation
    assert after.sum() > 10
    assert np.ptp(tr.x[after]) == 0 and np.ptp(tr.y[after]) == 0
    assert np.all(tr.vx[after] == 0)


def test_patch_everywhere_equals_scaled_friction():
    factor = 1.3
    base = ShotModel(v0=2.0, omega0=1.5)
    scaled = ShotModel(v0=2.0, omega0=1.5, alpha_y=base.alpha_y * factor,
                       alpha_theta=base.alpha_theta_value * factor)
    t = np.linspace(0, 30, 181)
    a = simulate(base, (Effect("friction_patch", {"y_start_m": -1, "y_end_m": 100,
                                                  "factor": factor}),), t=t)
    b = simulate(scaled, t=t)
    for k in ("x", "y", "theta"):
        np.testing.assert_allclose(getattr(a, k), getattr(b, k), atol=1e-6)


@pytest.mark.parametrize("y0,length,factor", [(RNG.uniform(3, 12), RNG.uniform(1, 6),
                                               RNG.uniform(0.5, 2.0)) for _ in range(3)])
def test_patch_work_energy_dry_friction(y0, length, factor):
    """phi = 0, no spin: y_F = v0^2 / (2 alpha g) - (factor - 1) L for a crossed patch."""
    alpha, v0 = 0.0076, 2.0
    m = ShotModel(v0=v0, omega0=0.0, phi_y=0.0, alpha_y=alpha)
    eff = (Effect("friction_patch", {"y_start_m": y0, "y_end_m": y0 + length,
                                     "factor": factor}),)
    tr = simulate(m, eff, t=[0.0, 60.0])
    expected = v0**2 / (2 * alpha * G) - (factor - 1) * length
    assert expected > y0 + length            # the case crosses the whole patch
    assert tr.y[-1] == pytest.approx(expected, abs=1e-6)


def test_patch_leaves_motion_before_it_untouched():
    m = ShotModel(v0=2.0, omega0=1.5)
    eff = (Effect("friction_patch", {"y_start_m": 10, "y_end_m": 14, "factor": 2.0}),)
    t = np.linspace(0, 30, 301)
    a, b = simulate(m, eff, t=t), simulate(m, t=t)
    before = b.y < 10 - 1e-9
    np.testing.assert_allclose(a.y[before], b.y[before], atol=1e-8)
    assert a.y[-1] < b.y[-1] - 3.0


def test_late_curl_k0_is_baseline_and_initial_acceleration():
    m = ShotModel(v0=2.0, omega0=1.5, a_T=5e-3)
    t = np.linspace(0, 30, 121)
    base = simulate(m, t=t)
    same = simulate(m, (Effect("late_curl", {"k": 0.0}),), t=t)
    np.testing.assert_allclose(same.x, base.x, atol=1e-12)
    for k, v_ref in [(0.5, 1.0), (1.0, 0.5), (-0.5, 2.0)]:
        te = np.array([0.02, 0.04])
        tr = simulate(m, (Effect("late_curl", {"k": k, "v_ref_m_per_s": v_ref}),), t=te)
        a_x = 2 * tr.x / te**2                   # x = a t^2 / 2 at the start (psi ~ 0)
        v_eff = math.sqrt(2.0**2 + 0.05**2)
        assert a_x[0] == pytest.approx(-5e-3 * (v_eff / v_ref) ** (-k), rel=2e-3)
    grown = simulate(m, (Effect("late_curl", {"k": 1.0, "v_ref_m_per_s": 2.0}),), t=t)
    assert grown.x[-1] < base.x[-1] - 0.1          # v < v_ref throughout: more curl


@pytest.mark.parametrize("method", ["closed", "ode"])
def test_pick_is_an_impulse(method):
    m = ShotModel(v0=2.0, omega0=1.5)
    t_s, dvx, dvy, dw = 7.3, 0.03, -0.1, -3.0
    eff = (Effect("pick", {"t_s": t_s, "dvx_m_per_s": dvx, "dvy_m_per_s": dvy,
                           "domega_rad_per_s": dw}),)
    eps = 1e-7
    tr = simulate(m, eff, t=[t_s - eps, t_s, 30.0, 60.0], method=method)
    assert tr.x[1] == pytest.approx(tr.x[0], abs=1e-6)
    assert tr.theta[1] == pytest.approx(tr.theta[0], abs=1e-6)
    assert tr.vx[1] - tr.vx[0] == pytest.approx(dvx, abs=1e-6)
    assert tr.vy[1] - tr.vy[0] == pytest.approx(dvy, abs=1e-6)
    assert tr.omega[1] - tr.omega[0] == pytest.approx(dw, abs=1e-6)
    # the spin is reversed: the late curl goes to +x; both motions stop afterwards
    base = simulate(m, t=[30.0])
    assert tr.x[2] > base.x[0] + 0.2
    assert t_s < tr.t_stop_rotation < 60 and t_s < tr.t_stop_translation < 60
    assert tr.vx[3] == 0 and tr.omega[3] == 0


@pytest.mark.parametrize("t_s", [0.0, 1e-200, 1e-9])
def test_pick_at_the_start_changes_the_initial_conditions(t_s):
    t = np.linspace(0, 30, 61)
    m = ShotModel(v0=2.0, omega0=1.5)
    tr = simulate(m, (Effect("pick", {"t_s": t_s, "dvy_m_per_s": -0.3,
                                      "domega_rad_per_s": 0.5}),), t=t)
    ref = simulate(ShotModel(v0=1.7, omega0=2.0, alpha_theta=m.alpha_theta_value), t=t)
    np.testing.assert_allclose(tr.y, ref.y, atol=1e-6)
    np.testing.assert_allclose(tr.theta, ref.theta, atol=1e-6)


def test_velocity_dependent_friction_replaces_the_law():
    base = ShotModel(v0=2.0, omega0=1.5, phi_y=0.0, alpha_y=0.01, phi_theta=0.0)
    eff = (Effect("velocity_dependent_friction", {"phi": -0.19, "alpha": 0.0076,
                                                  "phi_theta": -1.2}),)
    t = np.linspace(0, 30, 91)
    a = simulate(base, eff, t=t)
    b = simulate(ShotModel(v0=2.0, omega0=1.5, phi_y=-0.19, alpha_y=0.0076, phi_theta=-1.2),
                 t=t)
    np.testing.assert_allclose(a.y, b.y, atol=1e-12)
    np.testing.assert_allclose(a.theta, b.theta, atol=1e-12)


@pytest.mark.parametrize("name,params,msg", [
    ("bogus", {}, "unknown effect"),
    ("ice_slope", {"slope_z": 1.0}, "unknown parameter"),
    ("friction_patch", {"y_start_m": 1.0, "factor": 2.0}, "missing required"),
    ("friction_patch", {"y_start_m": 5.0, "y_end_m": 3.0, "factor": 2.0}, "less than"),
    ("friction_patch", {"y_start_m": 1.0, "y_end_m": 3.0, "factor": -1.0}, "factor"),
    ("late_curl", {"k": math.nan}, "finite"),
    ("late_curl", {"k": 1.0, "v_ref_m_per_s": 0.0}, "v_ref"),
    ("pick", {"t_s": -1.0}, "t_s"),
    ("pick", {"t_s": "soon"}, "number"),
    ("ice_slope", {"slope_x_mm_per_m": 500.0}, "steeper"),
    ("velocity_dependent_friction", {"phi": 1.0, "alpha": 0.01}, "phi"),
    ("velocity_dependent_friction", {"phi": 0.0, "alpha": -0.01}, "alpha"),
])
def test_invalid_effects_raise(name, params, msg):
    with pytest.raises(ParameterError, match=msg):
        Effect(name, params)


def test_effect_defaults_and_duplicates():
    assert Effect("late_curl", {"k": 1}).params["v_min_m_per_s"] == 0.05
    e = Effect("pick", {"t_s": 3.0})
    assert e.params == {"t_s": 3.0, "dvx_m_per_s": 0.0, "dvy_m_per_s": 0.0,
                        "domega_rad_per_s": 0.0}
    assert set(EFFECTS) == {"velocity_dependent_friction", "ice_slope", "friction_patch",
                            "late_curl", "pick", "friction_field", "spin_coupling",
                            "translation_coupling", "curl_spin_dependence", "friction_law"}
    with pytest.raises(ParameterError, match="once"):
        gather([Effect("late_curl", {"k": 1}), Effect("late_curl", {"k": 2})])
    terms = gather([("ice_slope", {"slope_x_mm_per_m": 1}), ("ice_slope", {"slope_x_mm_per_m": 2})])
    assert terms.slope_accel[0] == pytest.approx(-G * 3e-3, rel=1e-5)


def test_a_patch_that_reaches_an_end_of_the_path_is_read_as_a_step():
    """A fitted patch that reaches the release or the rock's stop changes the friction
    at one edge only: its remark says so, with the complement's factor; a patch inside
    the path has none."""
    from types import SimpleNamespace

    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    remark = EFFECTS["friction_patch"].remark
    y_max = rng.uniform(2.0, 30.0)
    shots = [SimpleNamespace(translates=True, y_max_m=y_max),
             SimpleNamespace(translates=False, y_max_m=0.0)]
    edge, f = rng.uniform(0.2, 0.8) * y_max, rng.uniform(0.3, 3.0)
    # (an edge within the running band's width of the release is at it)
    early = remark({"y_start_m": rng.uniform(-1, 0.1), "y_end_m": edge, "factor": f}, shots)
    late = remark({"y_start_m": edge, "y_end_m": y_max + rng.uniform(-0.1, 1), "factor": f},
                  shots)
    for text, side in ((early, "after"), (late, "before")):
        assert f"step in the friction at y = {edge:.2f} m" in text, (seed, text)
        assert f"factor {1 / f:.3g} on the path {side} it" in text, (seed, text)
    inside = {"y_start_m": 0.1 * y_max, "y_end_m": 0.9 * y_max, "factor": f}
    assert remark(inside, shots) == "", seed
    assert remark(inside, shots[1:]) == "", seed   # (no sliding rock: nothing to read)
