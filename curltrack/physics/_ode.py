"""General path of the paper model: ``solve_ivp`` with stop events.

Used when ``ice_slope`` couples speed and heading, or an extension multiplier
(:class:`.terms.Extension`) couples friction to position, speed or spin.  The
state is (x, y, w, psi, theta, q) with w = v^(1 - phi_y) and q = |omega|^(1 - phi_theta):
in these variables the friction terms are constants (dw/dt = -(1 - phi_y) alpha_y g f(y)
plus the slope term, dq/dt = -(1 - phi_theta) k_theta f(y)), so the right-hand side stays
bounded up to the stop although mu = alpha u^phi diverges there for phi < 0, and the stop
is the root of a smooth function (located by the event finder, not frame-quantised).
Patch edges are terminal events and the friction factor is held constant within a piece:
the step function in y is never seen by an RK stage on the wrong side of an edge.  After a stop
the motion stays stopped (static friction holds the rock on a slope).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp

from .terms import heading_rate, patch_factor, transverse_gain

RTOL, ATOL = 1e-10, 1e-12
#: extension multipliers (:class:`.terms.Extension`) are fitted by discover with many simulations; 1e-8
#: keeps finite-difference Jacobians smooth (jumps ~3e-7 m against responses of metres
#: per unit) at half the cost of a periodic friction field at 1e-10
RTOL_EXT, ATOL_EXT = 1e-8, 1e-10
_V_FLOOR = 1e-12


class OdeSegment:
    """Motion between t0 and t1 (next pick or the horizon) from (x, y, vx, vy, theta, omega)."""

    def __init__(self, model, terms, t0: float, state, t1: float):
        x0, y0, vx0, vy0, th0, w0 = (float(s) for s in state)
        self.model, self.terms, self.t0, self.t1 = model, terms, t0, t1
        self.py, self.pt = model.phi_y, model.phi_theta
        self.k_y, self.k_t = model.decel_y(), model.decel_theta()
        v0 = math.hypot(vx0, vy0)
        psi0 = math.atan2(-vx0, vy0) if v0 > 0 else 0.0
        self.sgn = math.copysign(1.0, w0) if w0 != 0 else 0.0
        z0 = np.array([x0, y0, v0 ** (1 - self.py), psi0, th0, abs(w0) ** (1 - self.pt)])
        self.edges = sorted({e for p in terms.patches for e in p[:2]})
        self.t_stop_translation = t0 if v0 == 0 else math.inf
        self.t_stop_rotation = t0 if w0 == 0 else math.inf
        self.pieces = []  # (ta, tb, dense solution or constant state)
        self._solve(t0, z0)

    def _rhs(self, moving, spinning, f):
        """Right-hand side for one piece; ``f`` is the friction factor of the patch the
        piece runs in (constant: pieces end at patch edges, so no stage of an RK step ever
        sees the other side of an edge)."""
        m, ax, ay = self.model, *self.terms.slope_accel
        py, pt, k_y, k_t = self.py, self.pt, self.k_y, self.k_t
        late, v_c, a_T, sgn = self.terms.late_curl, m.v_taper, m.a_T, self.sgn
        ext = self.terms.extension

        e_y, e_t = 1.0 / (1.0 - py), 1.0 / (1.0 - pt)
        c_y, c_t = (1.0 - py) * k_y, (1.0 - pt) * k_t

        def rhs(t, z):  # scalar math on purpose: called ~1000 times per shot
            x, y, w, psi, th, q = z.tolist()
            d = [0.0] * 6
            v = w ** e_y if moving and w > 0 else 0.0
            om = q ** e_t if spinning and q > 0 else 0.0
            if moving:
                c, s = math.cos(psi), math.sin(psi)
                a_par = -ax * s + ay * c          # slope along v_hat = (-sin, cos)
                a_left = -ax * c - ay * s         # slope along the left normal
                a_T_now = 0.0
                if spinning:
                    a_T_now = sgn * a_T * transverse_gain(v, late)
                    if ext is not None:
                        a_T_now *= ext.curl_gain(om)
                a_perp = a_left + a_T_now
                f_y = f if ext is None else f * ext.friction(y, om, v)
                d[0], d[1] = -v * s, v * c
                d[2] = -c_y * f_y + (1.0 - py) * max(v, _V_FLOOR) ** (-py) * a_par
                d[3] = heading_rate(a_perp, v, v_c)
            if spinning:
                d[4] = sgn * om
                d[5] = -c_t * (f if ext is None else f * ext.spin_friction(y, v))
            return d

        return rhs

    def _solve(self, t, z):
        skip_edge = None
        while t < self.t1:
            moving, spinning = z[2] > 0, z[5] > 0
            if not moving and not spinning:
                break
            events, kinds = [], []
            if moving:
                events.append(lambda _t, zz: zz[2]); kinds.append("translation")
                for e in self.edges:
                    if e != skip_edge:
                        events.append(lambda _t, zz, e=e: zz[1] - e); kinds.append(e)
            if spinning:
                events.append(lambda _t, zz: zz[5]); kinds.append("rotation")
            for ev in events:
                ev.terminal = True
            f = 1.0
            if self.terms.patches:  # the side of the edge the rock is heading into
                heading_y = math.cos(z[3]) if moving else 0.0
                f = float(patch_factor(z[1] + 1e-9 * heading_y, self.terms.patches))
            ext = self.terms.extension is not None
            sol = solve_ivp(self._rhs(moving, spinning, f), (t, self.t1), z, method="DOP853",
                            rtol=RTOL_EXT if ext else RTOL, atol=ATOL_EXT if ext else ATOL,
                            events=events, dense_output=True)
            if sol.status == -1:
                from ..errors import ParameterError
                raise ParameterError(f"the equations of motion could not be integrated "
                                     f"({sol.message})", where=f"t = {sol.t[-1]:.3f} s")
            t_new, z_new = sol.t[-1], sol.y[:, -1].copy()
            self.pieces.append((t, t_new, sol.sol, moving, spinning))
            skip_edge = None
            if sol.status == 1:
                k = next(i for i, te in enumerate(sol.t_events) if len(te))
                kind = kinds[k]
                if kind == "translation":
                    z_new[2] = 0.0
                    self.t_stop_translation = t_new
                elif kind == "rotation":
                    z_new[5] = 0.0
                    self.t_stop_rotation = t_new
                else:
                    skip_edge = kind
                    z_new[1] = kind   # exactly on the edge
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
