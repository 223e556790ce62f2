"""The compiled DOP853 integrator of the ODE path against SciPy's ``solve_ivp``.

``curltrack.physics._ode`` ports ``solve_ivp(method="DOP853", dense_output=True,
events=...)`` step for step into Numba; here both integrate the same right-hand side (the
kernel's own Python function, ``_rhs.py_func``) from random states, parameters, terms and
events, and must agree on the terminal event, where it happens and the dense output in
between, to the tolerance.  (Not on every step: DOP853's error estimate is a sum of 13
nearly equal stage values, and at rtol 1e-10 the order of that sum -- BLAS's or the
kernel's -- moves it by ~20 %, so step sizes drift apart after a few steps.)
"""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from curltrack.physics import ShotModel, _ode
from curltrack.physics.effects import gather


def _random_terms(rng):
    """A random mix of the terms the ODE path integrates (slope, patch, late curl and
    every extension multiplier)."""
    effects = []
    if rng.random() < 0.5:
        effects.append(("ice_slope", {"slope_x_mm_per_m": rng.uniform(-0.05, 0.05),
                                      "slope_y_mm_per_m": rng.uniform(-0.05, 0.05)}))
    if rng.random() < 0.4:
        y0 = rng.uniform(2, 15)
        effects.append(("friction_patch", {"y_start_m": y0, "y_end_m": y0 + rng.uniform(1, 5),
                                           "factor": rng.uniform(0.6, 1.6)}))
    if rng.random() < 0.3:
        effects.append(("late_curl", {"k": rng.uniform(0.1, 1.0)}))
    ext = rng.choice(["friction_field", "spin_coupling", "translation_coupling",
                      "curl_spin_dependence", "friction_law", None])
    params = {"friction_field": {"wavelength_m": rng.uniform(1, 5),
                                 "amp_cos": rng.uniform(-0.1, 0.1),
                                 "amp_sin": rng.uniform(-0.1, 0.1)},
              "spin_coupling": {"c_s_per_m": rng.uniform(-0.3, 0.3)},
              "translation_coupling": {"c_s_per_rad": rng.uniform(-0.1, 0.1)},
              "curl_spin_dependence": {"p": rng.uniform(0, 2)},
              "friction_law": {"dphi_low": rng.uniform(-0.4, 0.4),
                               "u_knee_m_per_s": rng.uniform(0.2, 0.8)}}
    if ext is not None:
        effects.append((str(ext), params[str(ext)]))
    return effects


@pytest.mark.parametrize("draw", range(12))
def test_kernel_is_scipy_dop853(draw):
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    model = ShotModel(v0=rng.uniform(0.5, 3.0), omega0=rng.choice([-1, 1]) * rng.uniform(0.2, 4),
                      phi_y=-rng.uniform(0, 0.4), phi_theta=-rng.uniform(0, 0.4))
    terms = gather(_random_terms(rng))
    seg = _ode.OdeSegment(model, terms, 0.0, (0, 0, 0, model.v0, 0, model.omega0), 40.0)
    # every piece of the segment, re-integrated by SciPy from the piece's own start
    for ta, tb, sol, moving, spinning in seg.pieces[:-1]:
        z0 = sol(np.array([ta]))[:, 0]
        p = seg._params(seg.patch_factor_at(z0, moving))

        def rhs(t, z, p=p, moving=moving, spinning=spinning):
            out = np.empty(6)
            _ode._rhs.py_func(z, p, moving, spinning, out)
            return out

        events = []
        if moving:
            events.append(lambda t, z: z[2])
            events += [lambda t, z, e=e: z[1] - e for e in seg.edges
                       if abs(z0[1] - e) > 1e-12]      # not the edge it starts on
        if spinning:
            events.append(lambda t, z: z[5])
        for ev in events:
            ev.terminal = True
        ref = solve_ivp(rhs, (ta, 40.0), z0, method="DOP853", rtol=_ode.RTOL,
                        atol=_ode.ATOL, events=events, dense_output=True)
        assert ref.status in (0, 1), seed
        assert ref.t[-1] == pytest.approx(tb, rel=1e-8, abs=1e-9), seed
        if ref.status == 1:   # the same event ended the piece
            hit = [i for i, te in enumerate(ref.t_events) if len(te)]
            ends = [ev(tb, sol(np.array([tb]))[:, 0]) for ev in events]
            assert abs(ends[hit[0]]) < 1e-7, seed
        t = np.sort(rng.uniform(ta, min(tb, ref.t[-1]), 50))
        # (the same tableau and step control, but compiled: the order of floating-point
        # operations differs, and over a 40 s piece their round-off accumulates - two
        # clean-clone runs drew a 58 rad angle 3e-6 rad apart, 5.3e-8 relative; seed
        # 1730327031 a 15.8 rad angle 2.6e-6 rad apart, 1.7e-7 relative.  A wrong right-
        # hand side or event differs by far more; at these tolerances SciPy's RK45 agrees
        # with DOP853 to 1e-7 too, so this compares the solutions, not the tableau)
        np.testing.assert_allclose(sol(t), ref.sol(t), rtol=1e-6, atol=1e-9,
                                   err_msg=f"seed {seed}")


def test_kernel_stops_on_a_right_hand_side_that_is_not_a_number():
    """A parameter that makes the right-hand side NaN ends the integration with status -1
    (a ParameterError in OdeSegment), not an endless loop inside compiled code."""
    seg = _ode.OdeSegment(ShotModel(v0=2.0, omega0=1.5), gather([]), 0.0,
                          (0, 0, 0, 2.0, 0, 1.5), 1.0)
    p = seg._params(1.0)
    p[_ode._P_KY] = np.nan
    z0 = np.array([0.0, 0.0, 2.0, 0.0, 0.0, 1.0])
    out = _ode._integrate(p, z0, 0.0, 30.0, True, True, np.array([0, 1]),
                          np.zeros(2), _ode.RTOL, _ode.ATOL)
    assert out[5] == -1
