"""General path of the paper model: a compiled DOP853 integrator with stop events.

Used when ``ice_slope`` couples speed and heading, or an extension multiplier
(:class:`.terms.Extension`) couples friction to position, speed or spin.  The
state is (x, y, w, psi, theta, q) with w = v^(1 - phi_y) and q = |omega|^(1 - phi_theta):
in these variables the friction terms are constants (dw/dt = -(1 - phi_y) alpha_y g f(y)
plus the slope term, dq/dt = -(1 - phi_theta) k_theta f(y)), so the right-hand side stays
bounded up to the stop although mu = alpha u^phi diverges there for phi < 0, and the stop
is the root of a smooth function (located on the step's interpolant, not frame-quantised).
Patch edges are terminal events and the friction factor is held constant within a piece:
the step function in y is never seen by an RK stage on the wrong side of an edge.  After a stop
the motion stays stopped (static friction holds the rock on a slope).

The integrator is SciPy's ``solve_ivp(method="DOP853", dense_output=True, events=...)``
step for step -- the same Butcher tableau (read from SciPy), error norm, step-size
control, initial step, 7th-order dense output and Brent root finding of terminal events
-- compiled with Numba together with the right-hand side: discover fits extension terms
with thousands of simulations, and SciPy's per-step Python overhead and a Python
right-hand side made ~10 ms of each (now ~0.1 ms).  Tests check it against ``solve_ivp``
on the same equations.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from scipy.integrate._ivp import dop853_coefficients as _dop

from . import terms as _terms
from .terms import patch_factor

RTOL, ATOL = 1e-10, 1e-12
#: extension multipliers (:class:`.terms.Extension`) too: discover fits them from
#: finite-difference Jacobians, and a step accepted at one parameter value and rejected
#: at the next moves the solution by about the tolerance -- at 1e-8 that noise (~4e-4 m
#: per unit of v0) sent one spin-coupling fit to a chi-square 49 worse (c 0.126 +- 0.004
#: for a true 0.15); compiled, 1e-10 costs ~5 % more than 1e-8
RTOL_EXT, ATOL_EXT = RTOL, ATOL
_V_FLOOR = 1e-12

_jit = njit(cache=True, nogil=True)
# the physics of the multipliers lives in .terms (plain math on floats); compiled here
_field_gain = _jit(_terms.field_gain)
_coupling_gain = _jit(_terms.coupling_gain)
_curl_gain = _jit(_terms.curl_gain)
_speed_law = _jit(_terms.speed_law_kernel)
_transverse = _jit(_terms.transverse_kernel)
_heading = _jit(_terms.heading_kernel)

# SciPy's DOP853 tableau
_NS, _NSX, _NP = _dop.N_STAGES, _dop.N_STAGES_EXTENDED, _dop.INTERPOLATOR_POWER
# (its C is not needed: the right-hand side does not depend on t)
_A, _B, _E3, _E5, _D = (np.ascontiguousarray(a) for a in (_dop.A, _dop.B, _dop.E3, _dop.E5,
                                                           _dop.D))
_SAFETY, _MIN_STEP_FACTOR, _MAX_STEP_FACTOR = 0.9, 0.2, 10.0
_ERR_EXPONENT = -1.0 / 8.0          # DOP853's error estimator is of order 7
_EPS = np.finfo(float).eps
#: a piece needing more steps than this is refused (a shot takes ~10-100)
_MAX_STEPS = 100_000

# layout of the parameter vector the kernel reads (see OdeSegment._params)
_P_PY, _P_PT, _P_KY, _P_KT, _P_AX, _P_AY, _P_AT, _P_VC, _P_SGN, _P_F = range(10)
_P_LATE = 10          # flag, k, v_ref, v_min
_P_EXT = 14           # flag, then Extension.packed() (14 floats)
_N_P = _P_EXT + 1 + 14


@njit(cache=True, nogil=True)
def _rhs(z, p, moving, spinning, out):
    """dz/dt of the state (x, y, w, psi, theta, q) into ``out``."""
    py, pt = p[_P_PY], p[_P_PT]
    y, w, psi, q = z[1], z[2], z[3], z[5]
    v = w ** (1.0 / (1.0 - py)) if moving and w > 0 else 0.0
    om = q ** (1.0 / (1.0 - pt)) if spinning and q > 0 else 0.0
    ext = p[_P_EXT] > 0
    e = _P_EXT + 1   # Extension.packed(): field (flag, k, a, b), spin_c, trans_c,
    #                  curl (flag, p, w_ref, w_min), law (flag, dphi, u_k, u_f)
    field = 1.0
    if ext and p[e] > 0:
        field = _field_gain(y, p[e + 1], p[e + 2], p[e + 3])
    for i in range(6):
        out[i] = 0.0
    if moving:
        ax, ay, f = p[_P_AX], p[_P_AY], p[_P_F]
        c, s = math.cos(psi), math.sin(psi)
        a_par = -ax * s + ay * c          # slope along v_hat = (-sin, cos)
        a_left = -ax * c - ay * s         # slope along the left normal
        a_t_now = 0.0
        if spinning:
            gain = 1.0
            if p[_P_LATE] > 0:
                gain = _transverse(v, p[_P_LATE + 1], p[_P_LATE + 2], p[_P_LATE + 3])
            a_t_now = p[_P_SGN] * p[_P_AT] * gain
            if ext and p[e + 6] > 0:
                a_t_now *= _curl_gain(om, p[e + 7], p[e + 8], p[e + 9])
        f_y = f
        if ext:
            f_y = f * field
            if p[e + 5] != 0.0:
                f_y *= _coupling_gain(p[e + 5], om)
            if p[e + 10] > 0:
                f_y *= _speed_law(v, p[e + 11], p[e + 12], p[e + 13])
        out[0] = -v * s
        out[1] = v * c
        out[2] = -(1.0 - py) * p[_P_KY] * f_y + (1.0 - py) * max(v, _V_FLOOR) ** (-py) * a_par
        out[3] = _heading(a_left + a_t_now, v, p[_P_VC])
    if spinning:
        f_t = p[_P_F]
        if ext:
            f_t *= field
            if p[e + 4] != 0.0:
                f_t *= _coupling_gain(p[e + 4], v)
        out[4] = p[_P_SGN] * om
        out[5] = -(1.0 - pt) * p[_P_KT] * f_t


@njit(cache=True, nogil=True)
def _dense_eval(t, t_old, h, y_old, F, out):
    """SciPy's Dop853DenseOutput at one time."""
    x = (t - t_old) / h
    for j in range(6):
        acc = 0.0
        for i in range(_NP):
            acc += F[_NP - 1 - i, j]
            acc *= x if i % 2 == 0 else 1.0 - x
        out[j] = acc + y_old[j]


@njit(cache=True, nogil=True)
def _dense_many(t, ts, y_olds, Fs):
    """:func:`_dense_eval` at each of the times ``t``, each on its step's interpolant
    (SciPy's OdeSolution: the step whose start is the last one before t): (6, len(t))."""
    out = np.empty((6, t.shape[0]))
    row = np.empty(6)
    last = y_olds.shape[0] - 1
    for k in range(t.shape[0]):
        i = min(max(np.searchsorted(ts, t[k]) - 1, 0), last)
        _dense_eval(t[k], ts[i], ts[i + 1] - ts[i], y_olds[i], Fs[i], row)
        out[:, k] = row
    return out


@njit(cache=True, nogil=True)
def _event_value(kind, edge, z):
    if kind == 0:
        return z[2]
    if kind == 1:
        return z[5]
    return z[1] - edge


@njit(cache=True, nogil=True)
def _brentq(kind, edge, t_a, t_b, t_old, h, y_old, F, tmp):
    """Root of the event on the step's interpolant (SciPy's brentq, xtol = rtol = 4 eps)."""
    xtol = rtol = 4.0 * _EPS
    xpre, xcur = t_a, t_b
    _dense_eval(xpre, t_old, h, y_old, F, tmp)
    fpre = _event_value(kind, edge, tmp)
    _dense_eval(xcur, t_old, h, y_old, F, tmp)
    fcur = _event_value(kind, edge, tmp)
    if fpre == 0.0:
        return xpre
    if fcur == 0.0:
        return xcur
    xblk, fblk, spre, scur = 0.0, 0.0, 0.0, 0.0
    for _ in range(100):
        if fpre != 0.0 and fcur != 0.0 and (fpre < 0) != (fcur < 0):
            xblk, fblk = xpre, fpre
            spre = scur = xcur - xpre
        if abs(fblk) < abs(fcur):
            xpre, xcur, xblk = xcur, xblk, xcur
            fpre, fcur, fblk = fcur, fblk, fcur
        delta = (xtol + rtol * abs(xcur)) / 2.0
        sbis = (xblk - xcur) / 2.0
        if fcur == 0.0 or abs(sbis) < delta:
            return xcur
        if abs(spre) > delta and abs(fcur) < abs(fpre):
            if xpre == xblk:
                stry = -fcur * (xcur - xpre) / (fcur - fpre)      # interpolate
            else:                                                 # extrapolate
                dpre = (fpre - fcur) / (xpre - xcur)
                dblk = (fblk - fcur) / (xblk - xcur)
                stry = -fcur * (fblk * dblk - fpre * dpre) / (dblk * dpre * (fblk - fpre))
            if 2.0 * abs(stry) < min(abs(spre), 3.0 * abs(sbis) - delta):
                spre, scur = scur, stry
            else:
                spre, scur = sbis, sbis
        else:
            spre, scur = sbis, sbis
        xpre, fpre = xcur, fcur
        if abs(scur) > delta:
            xcur += scur
        else:
            xcur += delta if sbis > 0 else -delta
        _dense_eval(xcur, t_old, h, y_old, F, tmp)
        fcur = _event_value(kind, edge, tmp)
    return xcur


@njit(cache=True, nogil=True)
def _stage(s, y, h, K, p, moving, spinning, tmp):
    """Stage ``s`` of a step of size ``h`` from ``y``: K[s] = f(y + h sum_m A[s, m] K[m])."""
    for j in range(y.shape[0]):
        acc = 0.0
        for m in range(s):
            acc += K[m, j] * _A[s, m]
        tmp[j] = y[j] + acc * h
    _rhs(tmp, p, moving, spinning, K[s])


@njit(cache=True, nogil=True)
def _rms(v):
    s = 0.0
    for i in range(v.shape[0]):
        s += v[i] * v[i]
    return math.sqrt(s / v.shape[0])


@njit(cache=True, nogil=True)
def _integrate(p, z0, t0, t1, moving, spinning, ev_kind, ev_edge, rtol, atol):
    """DOP853 from ``t0`` towards ``t1`` until the first terminal event.

    Returns (ts, y_olds, Fs, t_end, z_end, status, event): the steps' start times (and the
    last end), their start states and dense-output coefficients, where the piece ended,
    status 0 (reached t1), 1 (event ``event``, an index into ``ev_kind``) or -1 (step too
    small, not a number, or more than :data:`_MAX_STEPS` steps).
    """
    n, n_ev = 6, ev_kind.shape[0]
    cap = 64
    ts = np.empty(cap + 1)
    y_olds = np.empty((cap, n))
    Fs = np.empty((cap, _NP, n))
    K = np.zeros((_NSX, n))
    y = z0.copy()
    f = np.empty(n)
    _rhs(y, p, moving, spinning, f)
    tmp, y_new, f_new, scale = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    g = np.empty(n_ev)
    for k in range(n_ev):
        g[k] = _event_value(ev_kind[k], ev_edge[k], y)
    # initial step (scipy.integrate._ivp.common.select_initial_step)
    span = t1 - t0
    for i in range(n):
        scale[i] = atol + abs(y[i]) * rtol
        tmp[i] = y[i] / scale[i]
    d0 = _rms(tmp)
    for i in range(n):
        tmp[i] = f[i] / scale[i]
    d1 = _rms(tmp)
    h0 = 1e-6 if (d0 < 1e-5 or d1 < 1e-5) else 0.01 * d0 / d1
    h0 = min(h0, span)
    for i in range(n):
        y_new[i] = y[i] + h0 * f[i]
    _rhs(y_new, p, moving, spinning, f_new)
    for i in range(n):
        tmp[i] = (f_new[i] - f[i]) / scale[i]
    d2 = _rms(tmp) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / 8.0)
    h_abs = min(100.0 * h0, h1, span)

    t, n_steps, status, event = t0, 0, 0, -1
    ts[0] = t0
    while True:
        min_step = 10.0 * abs(np.nextafter(t, np.inf) - t)
        if h_abs < min_step:
            h_abs = min_step
        rejected = False
        while True:
            if not h_abs >= min_step or n_steps >= _MAX_STEPS:   # (also a NaN step)
                status = -1
                break
            t_new = t + h_abs
            if t_new - t1 > 0:
                t_new = t1
            h = t_new - t
            h_abs = abs(h)
            # one RK step (scipy rk_step)
            for j in range(n):
                K[0, j] = f[j]
            for s in range(1, _NS):
                _stage(s, y, h, K, p, moving, spinning, tmp)
            for j in range(n):
                acc = 0.0
                for m in range(_NS):
                    acc += K[m, j] * _B[m]
                y_new[j] = y[j] + h * acc
            _rhs(y_new, p, moving, spinning, f_new)
            for j in range(n):
                K[_NS, j] = f_new[j]
            # DOP853's error norm
            e5, e3 = 0.0, 0.0
            for j in range(n):
                sc = atol + max(abs(y[j]), abs(y_new[j])) * rtol
                a5, a3 = 0.0, 0.0
                for m in range(_NS + 1):
                    a5 += K[m, j] * _E5[m]
                    a3 += K[m, j] * _E3[m]
                e5 += (a5 / sc) ** 2
                e3 += (a3 / sc) ** 2
            if e5 == 0.0 and e3 == 0.0:
                err = 0.0
            else:
                err = abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * n)
            if err < 1.0:
                if err == 0.0:
                    factor = _MAX_STEP_FACTOR
                else:
                    factor = min(_MAX_STEP_FACTOR, _SAFETY * err ** _ERR_EXPONENT)
                if rejected:
                    factor = min(1.0, factor)
                h_abs *= factor
                break
            h_abs *= max(_MIN_STEP_FACTOR, _SAFETY * err ** _ERR_EXPONENT)
            rejected = True
        if status == -1:
            break
        # dense output of the accepted step
        for s in range(_NS + 1, _NSX):
            _stage(s, y, h, K, p, moving, spinning, tmp)
        if n_steps == cap:
            cap *= 2
            ts2, y2, F2 = np.empty(cap + 1), np.empty((cap, n)), np.empty((cap, _NP, n))
            ts2[:n_steps + 1] = ts[:n_steps + 1]
            y2[:n_steps] = y_olds[:n_steps]
            F2[:n_steps] = Fs[:n_steps]
            ts, y_olds, Fs = ts2, y2, F2
        F = Fs[n_steps]
        for j in range(n):
            dy = y_new[j] - y[j]
            F[0, j] = dy
            F[1, j] = h * K[0, j] - dy
            F[2, j] = 2.0 * dy - h * (f_new[j] + K[0, j])
            for r in range(_NP - 3):
                acc = 0.0
                for m in range(_NSX):
                    acc += _D[r, m] * K[m, j]
                F[3 + r, j] = h * acc
        y_olds[n_steps] = y
        t_old = t
        n_steps += 1
        ts[n_steps] = t_new
        # terminal events: the earliest root in the step (solve_ivp's handle_events)
        t_ev = np.inf
        for k in range(n_ev):
            gk = _event_value(ev_kind[k], ev_edge[k], y_new)
            if (g[k] <= 0 and gk >= 0) or (g[k] >= 0 and gk <= 0):
                root = _brentq(ev_kind[k], ev_edge[k], t_old, t_new, t_old, h, y, F, tmp)
                if root < t_ev:
                    t_ev, event = root, k
            g[k] = gk
        t = t_new
        for j in range(n):
            y[j] = y_new[j]
            f[j] = f_new[j]
        if event >= 0:
            status = 1
            _dense_eval(t_ev, t_old, h, y_olds[n_steps - 1], F, y)
            t = t_ev
            break
        if t == t1:
            break
    return ts[:n_steps + 1], y_olds[:n_steps], Fs[:n_steps], t, y, status, event


class DenseSolution:
    """A piece's continuous solution: DOP853's interpolant per step (vectorised)."""

    def __init__(self, ts, y_olds, Fs):
        self.ts, self.y_olds, self.Fs = ts, y_olds, Fs

    def __call__(self, t):
        """State columns (6, len(t)) at times ``t`` within the piece."""
        return _dense_many(np.asarray(t, dtype=float), self.ts, self.y_olds, self.Fs)


class OdeSegment:
    """Motion between t0 and t1 (next pick or the horizon) from (x, y, vx, vy, theta, omega)."""

    def __init__(self, model, terms, t0: float, state, t1: float):
        x0, y0, vx0, vy0, th0, w0 = (float(s) for s in state)
        self.model, self.terms, self.t0, self.t1 = model, terms, t0, t1
        self.py, self.pt = model.phi_y, model.phi_theta
        v0 = math.hypot(vx0, vy0)
        psi0 = math.atan2(-vx0, vy0) if v0 > 0 else 0.0
        self.sgn = math.copysign(1.0, w0) if w0 != 0 else 0.0
        z0 = np.array([x0, y0, v0 ** (1 - self.py), psi0, th0, abs(w0) ** (1 - self.pt)])
        self.edges = sorted({e for p in terms.patches for e in p[:2]})
        self.t_stop_translation = t0 if v0 == 0 else math.inf
        self.t_stop_rotation = t0 if w0 == 0 else math.inf
        self.pieces = []  # (ta, tb, dense solution or constant state, moving, spinning)
        self._solve(t0, z0)

    def patch_factor_at(self, z, moving: bool) -> float:
        """Friction factor of the patch a piece starting at state ``z`` runs in: the
        side of an edge the rock is heading into."""
        if not self.terms.patches:
            return 1.0
        heading_y = math.cos(z[3]) if moving else 0.0
        return float(patch_factor(z[1] + 1e-9 * heading_y, self.terms.patches))

    def _params(self, f: float) -> np.ndarray:
        """The kernel's parameter vector for a piece of friction factor ``f`` (the patch
        the piece runs in: pieces end at patch edges, so no stage of an RK step ever
        sees the other side of an edge)."""
        m, t = self.model, self.terms
        p = np.zeros(_N_P)
        p[:_P_LATE] = (self.py, self.pt, m.decel_y(), m.decel_theta(), *t.slope_accel,
                       m.a_T, m.v_taper, self.sgn, f)
        if t.late_curl is not None:
            p[_P_LATE:_P_EXT] = (1.0, *t.late_curl)
        if t.extension is not None:
            p[_P_EXT] = 1.0
            p[_P_EXT + 1:] = t.extension.packed()
        return p

    def _solve(self, t, z):
        skip_edge = None
        ext = self.terms.extension is not None
        rtol, atol = (RTOL_EXT, ATOL_EXT) if ext else (RTOL, ATOL)
        while t < self.t1:
            moving, spinning = bool(z[2] > 0), bool(z[5] > 0)
            if not moving and not spinning:
                break
            kinds, edges = [], []
            if moving:
                kinds.append(0); edges.append(0.0)
                for e in self.edges:
                    if e != skip_edge:
                        kinds.append(2); edges.append(e)
            if spinning:
                kinds.append(1); edges.append(0.0)
            ts, y_olds, Fs, t_new, z_new, status, event = _integrate(
                self._params(self.patch_factor_at(z, moving)), np.asarray(z, dtype=float),
                float(t), float(self.t1),
                moving, spinning, np.array(kinds, dtype=np.int64), np.array(edges),
                rtol, atol)
            if status == -1:
                from ..errors import ParameterError
                raise ParameterError("the equations of motion could not be integrated "
                                     "(the step size fell below the spacing of numbers, "
                                     "or became not a number)", where=f"t = {t_new:.3f} s")
            z_new = z_new.copy()
            self.pieces.append((t, t_new, DenseSolution(ts, y_olds, Fs), moving, spinning))
            skip_edge = None
            if status == 1:
                kind = kinds[event]
                if kind == 0:
                    z_new[2] = 0.0
                    self.t_stop_translation = t_new
                elif kind == 1:
                    z_new[5] = 0.0
                    self.t_stop_rotation = t_new
                else:
                    skip_edge = edges[event]
                    z_new[1] = skip_edge   # exactly on the edge
            t, z = t_new, z_new
        self.pieces.append((t, math.inf, z, z[2] > 0, z[5] > 0))
        self.z_end = z

    def _to_state(self, z, moving, spinning):
        x, y, w, psi, th, q = z
        v = np.maximum(w, 0.0) ** (1.0 / (1.0 - self.py)) if moving else np.zeros_like(x)
        om = self.sgn * np.maximum(q, 0.0) ** (1.0 / (1.0 - self.pt)) if spinning else np.zeros_like(x)
        return {"x": x, "y": y, "vx": -v * np.sin(psi), "vy": v * np.cos(psi),
                "theta": th, "omega": om}

    def evaluate(self, t):
        """State at times ``t`` (t0 <= t <= t1): dict of x, y, vx, vy, theta, omega."""
        t = np.asarray(t, dtype=float)
        out = {k: np.empty(t.shape[0]) for k in ("x", "y", "vx", "vy", "theta", "omega")}
        for ta, tb, sol, moving, spinning in self.pieces:
            sel = (t >= ta) & (t <= tb)
            if not sel.any():
                continue
            z = sol(t[sel]) if callable(sol) else np.repeat(np.asarray(sol)[:, None], sel.sum(), 1)
            for k, v in self._to_state(z, moving, spinning).items():
                out[k][sel] = v
        return out
