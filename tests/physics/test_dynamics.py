"""The paper model against the paper's closed forms, and its numerical behaviour."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from curltrack.errors import ParameterError
from curltrack.physics import Effect, ShotModel, simulate
from curltrack.physics import closed_form as cf

RNG = np.random.default_rng(20040101)
METHODS = ("closed", "ode")


def _cases(n, **ranges):
    """n parameter sets drawn uniformly from the given (lo, hi) ranges (seeded)."""
    return [{k: float(RNG.uniform(*v)) for k, v in ranges.items()} for _ in range(n)]


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("p", _cases(4, omega0=(0.5, 15.0), phi=(-1.2, 0.6),
                                     alpha=(0.003, 0.02)))
def test_pure_rotation_matches_closed_form(p, method):
    m = ShotModel(v0=0.0, omega0=p["omega0"], phi_theta=p["phi"], alpha_theta=p["alpha"])
    t_F = cf.stop_time_rotation(p["omega0"], p["phi"], p["alpha"], m.R, m.r)
    lam = cf.lambda_from_phi(p["phi"])
    theta_F = p["omega0"] * t_F / lam
    t = np.linspace(0.0, 1.2 * t_F, 301)
    tr = simulate(m, t=t, method=method)
    assert tr.t_stop_rotation == pytest.approx(t_F, rel=1e-4)
    assert tr.t_stop_translation == 0.0
    expected = cf.decel_position(t, theta_F, lam, t_F)
    np.testing.assert_allclose(tr.theta, expected, rtol=0, atol=1e-4 * theta_F)
    np.testing.assert_allclose(tr.omega, cf.decel_rate(t, theta_F, lam, t_F),
                               rtol=0, atol=1e-4 * p["omega0"])
    assert np.all(tr.x == 0) and np.all(tr.y == 0)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("p", _cases(4, v0=(0.3, 4.0), phi=(-0.8, 0.6), alpha=(0.004, 0.03)))
def test_pure_translation_matches_closed_form(p, method):
    m = ShotModel(v0=p["v0"], omega0=0.0, phi_y=p["phi"], alpha_y=p["alpha"])
    t_F = cf.stop_time_translation(p["v0"], p["phi"], p["alpha"])
    lam = cf.lambda_from_phi(p["phi"])
    y_F = p["v0"] * t_F / lam
    t = np.linspace(0.0, 1.1 * t_F, 301)
    tr = simulate(m, t=t, method=method)
    assert tr.t_stop_translation == pytest.approx(t_F, rel=1e-4)
    np.testing.assert_allclose(tr.y, cf.decel_position(t, y_F, lam, t_F), rtol=0,
                               atol=1e-4 * y_F)
    np.testing.assert_allclose(tr.vy, cf.decel_rate(t, y_F, lam, t_F), rtol=0,
                               atol=1e-4 * p["v0"])
    assert np.abs(tr.x).max() < 1e-12


@pytest.mark.parametrize("p", _cases(5, v0=(1.5, 3.0), omega0=(0.5, 4.0), phi=(-0.6, 0.0),
                                     a_T=(1e-5, 1e-4)))
def test_small_curl_draw_matches_paper_x(p):
    """For small curl angles the exact model reduces to the paper's x(t) (Eq. x(t))."""
    m = ShotModel(v0=p["v0"], omega0=p["omega0"], phi_y=p["phi"], a_T=p["a_T"])
    t_F = m.stop_times()[0]
    lam = m.lambda_y
    t = np.linspace(0.0, 1.05 * t_F, 400)
    tr = simulate(m, t=t)
    x_paper = cf.curl_position(t, -p["a_T"], lam, t_F)     # CCW -> -x
    x_F = cf.curl_distance(p["a_T"], lam, t_F)
    assert np.abs(tr.x - x_paper).max() < 1e-4 * x_F
    assert tr.x[-1] == pytest.approx(-x_F, rel=1e-4)


def test_curl_deviation_is_second_order_in_the_curl_angle():
    """The paper linearises in psi ~ a_T: the relative error at t < 0.95 t_F grows as a_T^2."""
    devs = []
    for a_T in (1e-3, 2e-3):
        m = ShotModel(v0=2.0, omega0=1.5, a_T=a_T)
        t_F = m.stop_times()[0]
        t = np.linspace(0, 0.95 * t_F, 200)
        dev = simulate(m, t=t).x - cf.curl_position(t, -a_T, m.lambda_y, t_F)
        devs.append(np.abs(dev).max() / cf.curl_distance(a_T, m.lambda_y, t_F))
    assert devs[1] / devs[0] == pytest.approx(4.0, rel=0.05)


def test_default_draw_is_paper_like():
    tr = simulate(ShotModel(v0=2.0, omega0=1.5))
    assert 23 < tr.t_stop_translation < 28
    assert tr.t_stop_rotation == pytest.approx(tr.t_stop_translation, rel=1e-9)
    assert -1.2 < tr.x[-1] < -0.6
    assert 25 < tr.y[-1] < 32


@pytest.mark.parametrize("omega0", [1.5, -1.5])
def test_curl_follows_spin_and_mirrors(omega0):
    m = ShotModel(v0=2.0, omega0=omega0)
    t = np.linspace(0, 30, 91)
    tr = simulate(m, t=t)
    mirror = simulate(ShotModel(v0=2.0, omega0=-omega0), t=t)
    assert np.sign(tr.x[-1]) == -np.sign(omega0)   # CCW curls to -x
    np.testing.assert_allclose(tr.x, -mirror.x, atol=1e-12)
    np.testing.assert_allclose(tr.theta, -mirror.theta, atol=1e-12)
    np.testing.assert_allclose(tr.y, mirror.y, atol=1e-12)


@pytest.mark.parametrize("phi_y", [0.0, 0.3, 0.6])
def test_heading_stays_finite_for_lambda_at_or_above_two(phi_y):
    """a_T / v is not integrable at the stop for lambda_y >= 2; the taper keeps it finite."""
    m = ShotModel(v0=2.0, omega0=1.5, phi_y=phi_y, alpha_y=0.01, a_T=5e-3)
    for method in METHODS:
        tr = simulate(m, t=np.linspace(0, 60, 200), method=method)
        for arr in (tr.x, tr.y, tr.vx, tr.vy):
            assert np.isfinite(arr).all()
        assert abs(tr.x[-1]) < 5.0


@pytest.mark.parametrize("p", _cases(4, v0=(1.0, 3.0), omega0=(0.5, 3.0), a_T=(1e-3, 2e-2),
                                     k=(0.0, 1.0), t_s=(2.0, 12.0), dw=(-0.4, 0.4),
                                     dvx=(-0.05, 0.05), sign=(-1, 1), y1=(2.0, 20.0),
                                     dy=(0.5, 8.0), f=(0.5, 2.0)))
def test_closed_and_ode_paths_agree(p):
    p["omega0"] *= np.sign(p["sign"])
    effects = (Effect("late_curl", {"k": p["k"]}),
               Effect("friction_patch", {"y_start_m": p["y1"], "y_end_m": p["y1"] + p["dy"],
                                         "factor": p["f"]}),
               Effect("pick", {"t_s": p["t_s"], "dvx_m_per_s": p["dvx"],
                               "domega_rad_per_s": p["dw"]}))
    m = ShotModel(v0=p["v0"], omega0=p["omega0"], a_T=p["a_T"])
    t = np.linspace(0, 40, 241)
    a = simulate(m, effects, t=t, method="closed")
    b = simulate(m, effects, t=t, method="ode")
    for k in ("x", "y", "theta", "vx", "vy", "omega"):
        np.testing.assert_allclose(getattr(a, k), getattr(b, k), atol=1e-6, err_msg=k)
    assert a.t_stop_translation == pytest.approx(b.t_stop_translation, abs=1e-6)
    assert a.t_stop_rotation == pytest.approx(b.t_stop_rotation, abs=1e-6)


# alpha_theta = 3e-5 stops the spin (and with it a_T) before the translation: x'' jumps
# there, so x is C1 (not C2) in alpha_theta and the difference quotients agree to O(h) only.
@pytest.mark.parametrize("name,value,h,out,tol", [
    ("a_T", 5e-3, 1e-5, "x", 1e-3), ("v0", 2.0, 1e-3, "x", 1e-3), ("v0", 2.0, 1e-3, "y", 1e-3),
    ("omega0", 1.5, 1e-3, "theta", 1e-3), ("phi_y", -0.19, 1e-3, "x", 1e-3),
    ("phi_theta", -1.2, 1e-3, "theta", 1e-3), ("alpha_theta", 3e-5, 1e-7, "x", 1e-2)])
def test_smooth_in_parameters(name, value, h, out, tol):
    """Central differences at two step sizes agree: no frame-quantised steps."""
    t = np.arange(0, 27, 1 / 30)

    def x_at(v):
        return getattr(simulate(ShotModel(**{"v0": 2.0, "omega0": 1.5, name: v}), t=t), out)

    d1 = (x_at(value + h) - x_at(value - h)) / (2 * h)
    d2 = (x_at(value + h / 2) - x_at(value - h / 2)) / h
    scale = np.abs(d1).max()
    assert scale > 0
    assert np.abs(d1 - d2).max() < tol * scale


def test_smooth_in_pick_time():
    t = np.arange(0, 27, 1 / 30)

    def x_at(ts):
        return simulate(ShotModel(v0=2.0, omega0=1.5),
                        (Effect("pick", {"t_s": ts, "domega_rad_per_s": -1.0}),), t=t).x[-1]

    h = 1e-3
    d1 = (x_at(8.0 + h) - x_at(8.0 - h)) / (2 * h)
    d2 = (x_at(8.0 + h / 2) - x_at(8.0 - h / 2)) / h
    assert abs(d1) > 1e-4 and d1 == pytest.approx(d2, rel=1e-3)


@pytest.mark.parametrize("key,value", [("y_start_m", 8.0), ("factor", 1.5)])
def test_smooth_in_patch_parameters(key, value):
    t = np.arange(0, 30, 1 / 30)

    def y_at(v):
        params = {"y_start_m": 8.0, "y_end_m": 12.0, "factor": 1.5, key: v}
        return simulate(ShotModel(v0=2.0, omega0=1.5),
                        (Effect("friction_patch", params),), t=t).y

    h = 1e-3
    d1 = (y_at(value + h) - y_at(value - h)) / (2 * h)
    d2 = (y_at(value + h / 2) - y_at(value - h / 2)) / h
    assert np.abs(d1).max() > 0.1
    assert np.abs(d1 - d2).max() < 2e-3 * np.abs(d1).max()


@pytest.mark.parametrize("effects", [
    (Effect("late_curl", {"k": -2.0}),),   # a_T x 25: the heading turns 1.1 rad in 7 s
    (Effect("friction_patch", {"y_start_m": 0.0, "y_end_m": 0.0, "factor": 1.0}),),
])
def test_fast_turning_long_shot_regressions(effects):
    """Found by the property test: a slow-decelerating shot (t_FS ~ 4000 s) that turns fast
    and crosses its start line many times; both solvers must agree over the horizon."""
    m = ShotModel(v0=5.0, omega0=14.0, phi_y=-2.0, alpha_y=0.001, phi_theta=0.0,
                  alpha_theta=0.03125, a_T=0.03125)
    t = np.linspace(0, 40, 81)
    a, b = simulate(m, effects, t=t), simulate(m, effects, t=t, method="ode")
    np.testing.assert_allclose(a.x, b.x, atol=1e-6)
    np.testing.assert_allclose(a.y, b.y, atol=1e-6)


def test_times_in_any_order_and_deterministic():
    m = ShotModel(v0=2.0, omega0=1.5)
    t = np.array([20.0, 0.0, 5.5, 26.0, 30.0])
    a, b = simulate(m, t=t), simulate(m, t=np.sort(t))
    np.testing.assert_array_equal(a.x[np.argsort(t)], b.x)
    np.testing.assert_array_equal(simulate(m, t=t).x, a.x)


@pytest.mark.parametrize("kw", [dict(alpha_y=-0.01), dict(alpha_y=0.0), dict(phi_y=1.0),
                                dict(phi_theta=1.5), dict(v0=-1.0), dict(v0=math.nan),
                                dict(omega0=math.inf), dict(a_T=math.nan),
                                dict(alpha_theta=-1e-5), dict(R=0.0), dict(r=-0.06),
                                dict(v_taper=0.0), dict(phi_y="abc")])
def test_invalid_parameters_raise(kw):
    base = dict(v0=2.0, omega0=1.5)
    base.update(kw)
    with pytest.raises(ParameterError) as err:
        ShotModel(**base)
    assert next(iter(kw)) in str(err.value)


@pytest.mark.parametrize("t", [[0.0, math.nan], [-1.0, 2.0], [math.inf]])
def test_invalid_times_raise(t):
    with pytest.raises(ParameterError):
        simulate(ShotModel(v0=2.0, omega0=1.5), t=t)


def test_from_rig_takes_radii():
    from curltrack.rig import Rig

    m = ShotModel.from_rig(Rig(band_radius_m=0.06, inertia_radius_m=0.15), v0=1.0, omega0=1.0)
    assert (m.R, m.r) == (0.15, 0.06)


_EFFECTS = {
    "none": lambda d: (),
    "ice_slope": lambda d: (Effect("ice_slope", {
        "slope_x_mm_per_m": d.draw(st.floats(-60, 60)),
        "slope_y_mm_per_m": d.draw(st.floats(-60, 60))}),),
    "friction_patch": lambda d: (lambda a, b: (Effect("friction_patch", {
        "y_start_m": a, "y_end_m": a + b, "factor": d.draw(st.floats(0.05, 20))}),))(
        d.draw(st.floats(-1, 40)), d.draw(st.floats(0, 10))),
    "late_curl": lambda d: (Effect("late_curl", {"k": d.draw(st.floats(-3, 3))}),),
    "pick": lambda d: (Effect("pick", {
        "t_s": d.draw(st.floats(0, 40)), "dvx_m_per_s": d.draw(st.floats(-2, 2)),
        "dvy_m_per_s": d.draw(st.floats(-2, 2)),
        "domega_rad_per_s": d.draw(st.floats(-10, 10))}),),
}


@settings(max_examples=60, deadline=None, derandomize=True)
@given(st.data())
def test_finite_output_for_any_valid_parameters(data):
    """Over the ranges discover fits in: finite, and both solvers agree (never a NaN series)."""
    kw = dict(v0=data.draw(st.floats(0, 6)), omega0=data.draw(st.floats(-60, 60)),
              phi_y=data.draw(st.floats(-3, 0.9)), alpha_y=data.draw(st.floats(1e-3, 1.0)),
              phi_theta=data.draw(st.floats(-3, 0.9)),
              alpha_theta=data.draw(st.floats(1e-6, 1.0)), a_T=data.draw(st.floats(0, 0.05)))
    effects = _EFFECTS[data.draw(st.sampled_from(sorted(_EFFECTS)))](data)
    t = np.linspace(0, 40, 121)
    tr = simulate(ShotModel(**kw), effects, t=t)
    for k in ("x", "y", "vx", "vy", "theta", "omega"):
        assert np.isfinite(getattr(tr, k)).all(), k
    for stop in (tr.t_stop_translation, tr.t_stop_rotation):
        assert stop >= 0
    ode = simulate(ShotModel(**kw), effects, t=t, method="ode")   # the other solver agrees
    scale = max(1.0, np.abs(ode.y).max())
    assert np.abs(tr.x - ode.x).max() < 1e-3 * scale
    assert np.abs(tr.y - ode.y).max() < 1e-3 * scale
