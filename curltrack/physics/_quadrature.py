"""Fast path of the paper model: closed forms where they hold, quadrature for the rest.

Without ``ice_slope`` and ``friction_patch`` the speed and the spin decouple from the
heading and from position, so between picks v(t), omega(t) and theta(t) are the paper's
closed forms (:mod:`curltrack.physics.closed_form`) and only the heading psi(t) and the
position need integrating.  They are integrated on a fixed grid in u = 1 - t/t_FS that is
uniform for u > 0.02 and geometric towards the stop (where v ~ u^(lambda_y - 1) is not
smooth in t): 3-point Gauss-Legendre per interval and cubic Hermite interpolation with the
exact derivatives at the nodes.  Results are therefore smooth in every parameter and in t
(no frame-quantised steps) and agree with the ODE path (:mod:`._ode`) to ~1e-7 m.
"""

from __future__ import annotations

import math

import numpy as np

from . import closed_form as cf
from .terms import heading_rate, transverse_gain

_U_NODES = np.concatenate([np.linspace(1.0, 0.02, 400, endpoint=False),
                           np.geomspace(0.02, 1e-12, 160), [0.0]])
MIN_NODES = 200
MAX_DPSI = 0.02    # rad of heading change per interval before it is subdivided
MAX_NODES = 20000
_GL_X = np.array([-math.sqrt(0.6), 0.0, math.sqrt(0.6)])
_GL_W = np.array([5.0, 8.0, 5.0]) / 9.0


def _hermite(h, s, y0, y1, d0, d1):
    """Cubic Hermite on an interval of length h at fraction s (broadcasting)."""
    s2, s3 = s * s, s * s * s
    return ((2 * s3 - 3 * s2 + 1) * y0 + (s3 - 2 * s2 + s) * h * d0
            + (-2 * s3 + 3 * s2) * y1 + (s3 - s2) * h * d1)


class ClosedSegment:
    """Motion between t0 and t1 (next pick) from state (x, y, vx, vy, theta, omega)."""

    def __init__(self, model, late_curl, t0: float, state, t1: float,
                 horizon: float = math.inf):
        x0, y0, vx0, vy0, th0, w0 = (float(s) for s in state)
        self.model, self.late, self.t0, self.t1 = model, late_curl, t0, t1
        self.horizon = horizon  # nothing after this is ever evaluated: not integrated
        self.x0, self.y0, self.th0, self.w0 = x0, y0, th0, w0
        self.v0 = math.hypot(vx0, vy0)
        self.psi0 = math.atan2(-vx0, vy0) if self.v0 > 0 else 0.0
        self.lam_y, self.lam_th = model.lambda_y, model.lambda_theta
        self.T_S = (float(cf.stop_time_translation(self.v0, model.phi_y, model.alpha_y))
                    if self.v0 > 0 else 0.0)
        self.T_R = (float(cf.stop_time_rotation(abs(w0), model.phi_theta,
                                                model.alpha_theta_value, model.R, model.r))
                    if w0 != 0 else 0.0)
        # motions that end within 1e-12 s (spins or speeds ~1e-300) count as none
        self.T_S = self.T_S if self.T_S > 1e-12 else 0.0
        self.T_R = self.T_R if self.T_R > 1e-12 else 0.0
        self.t_stop_translation = t0 + self.T_S
        self.t_stop_rotation = t0 + self.T_R
        self._build()

    # --- closed forms ------------------------------------------------------------------
    def speed(self, t):
        """v(t) (m/s): the paper's v0 (1 - t/t_FS)^(lambda_y - 1)."""
        if self.T_S <= 0:
            return np.zeros_like(np.asarray(t, dtype=float))
        return cf.decel_rate(t - self.t0, self.v0 * self.T_S / self.lam_y, self.lam_y, self.T_S)

    def _turn_rate(self, t, spinning):
        v = self.speed(t)
        a_perp = np.sign(self.w0) * spinning * self.model.a_T * transverse_gain(v, self.late)
        return heading_rate(a_perp, v, self.model.v_taper)

    # --- quadrature of heading and position ---------------------------------------------
    def _build(self):
        self.t_end = min(self.t0 + self.T_S, self.t1)
        if self.T_S <= 0 or self.t_end - self.t0 <= 1e-12 * max(1.0, self.T_S):  # ~empty
            self.nodes = None
            self.x_end, self.y_end, self.psi_end = self.x0, self.y0, self.psi0
            return
        t_grid = min(self.t_end, max(self.horizon, self.t0))
        u_end = max(0.0, 1.0 - (t_grid - self.t0) / self.T_S)
        u = _U_NODES[_U_NODES > u_end]
        extra = [u_end]
        if len(u) < MIN_NODES:  # a horizon short against t_FS: still resolve it
            extra.extend(np.linspace(u_end, 1.0, MIN_NODES))
        u_rot = 1.0 - self.T_R / self.T_S
        if u_end < u_rot < 1.0:
            extra.append(u_rot)
        u = np.unique(np.concatenate([u, extra]))[::-1]  # descending u = ascending t
        tn = self.t0 + self.T_S * (1.0 - u)
        tn[0], tn[-1] = self.t0, t_grid
        tn = tn[np.concatenate([[True], np.diff(tn) > 0])]
        for _ in range(4):  # refine where the heading turns fast (circling rocks)
            self._integrate(tn)
            dpsi = np.abs(np.diff(self.psi))
            if dpsi.max(initial=0.0) <= MAX_DPSI or len(tn) > MAX_NODES:
                break
            k = np.maximum(1, np.ceil(dpsi / MAX_DPSI)).astype(int)
            tn = np.concatenate([np.linspace(a, b, m, endpoint=False)
                                 for a, b, m in zip(tn[:-1], tn[1:], k)] + [tn[-1:]])
        self.x_end, self.y_end = self.pos[-1]
        self.psi_end = self.psi[-1]

    def _integrate(self, tn):
        """Heading and position at the nodes ``tn`` (Gauss-Legendre + Hermite)."""
        h = np.diff(tn)
        t_rot_stop = self.t0 + self.T_R
        spinning = ((tn[:-1] + 0.5 * h) < t_rot_stop).astype(float)  # per interval
        d_left = self._turn_rate(tn[:-1], spinning)
        d_right = self._turn_rate(tn[1:], spinning)
        tg = tn[:-1, None] + h[:, None] * (0.5 + 0.5 * _GL_X)  # (n-1, 3)
        rate_g = self._turn_rate(tg, spinning[:, None])
        psi = self.psi0 + np.concatenate([[0.0], np.cumsum(0.5 * h * (rate_g @ _GL_W))])
        s_g = 0.5 + 0.5 * _GL_X
        psi_g = _hermite(h[:, None], s_g, psi[:-1, None], psi[1:, None],
                         d_left[:, None], d_right[:, None])
        v_g = self.speed(tg)
        vel_g = np.stack([-v_g * np.sin(psi_g), v_g * np.cos(psi_g)], axis=-1)  # (n-1,3,2)
        steps = 0.5 * h[:, None] * np.einsum("ijk,j->ik", vel_g, _GL_W)
        pos = np.vstack([[self.x0, self.y0], [self.x0, self.y0] + np.cumsum(steps, axis=0)])
        v_n = self.speed(tn)
        self.nodes = tn
        self.psi, self.psi_dl, self.psi_dr = psi, d_left, d_right
        self.pos = pos
        self.vel = np.stack([-v_n * np.sin(psi), v_n * np.cos(psi)], axis=-1)

    def y_in_interval(self, j: int, t: float) -> float:
        """y (m) at time ``t`` inside node interval ``j`` (the same interpolant as evaluate)."""
        tn = self.nodes
        h = float(tn[j + 1] - tn[j])
        return float(_hermite(h, (t - tn[j]) / h, self.pos[j, 1], self.pos[j + 1, 1],
                              self.vel[j, 1], self.vel[j + 1, 1]))

    def evaluate(self, t):
        """State at times ``t`` (t0 <= t <= t1): dict of x, y, vx, vy, theta, omega."""
        t = np.asarray(t, dtype=float)
        n = t.shape[0]
        out = {k: np.empty(n) for k in ("x", "y", "vx", "vy")}
        grid_end = self.nodes[-1] if self.nodes is not None else self.t_end
        moving = t < grid_end if self.nodes is not None else np.zeros(n, bool)
        if moving.any():
            tm = t[moving]
            tn = self.nodes
            i = np.clip(np.searchsorted(tn, tm, side="right") - 1, 0, len(tn) - 2)
            h = tn[i + 1] - tn[i]
            s = (tm - tn[i]) / h
            psi = _hermite(h, s, self.psi[i], self.psi[i + 1], self.psi_dl[i], self.psi_dr[i])
            pos = _hermite(h[:, None], s[:, None], self.pos[i], self.pos[i + 1],
                           self.vel[i], self.vel[i + 1])
            v = self.speed(tm)
            out["x"][moving], out["y"][moving] = pos[:, 0], pos[:, 1]
            out["vx"][moving], out["vy"][moving] = -v * np.sin(psi), v * np.cos(psi)
        rest = ~moving
        if rest.any():
            if grid_end < self.t0 + self.T_S:  # cut short by a pick: still moving
                v_end = float(self.speed(grid_end))
                vx_e, vy_e = -v_end * math.sin(self.psi_end), v_end * math.cos(self.psi_end)
            else:
                vx_e = vy_e = 0.0
            out["x"][rest], out["y"][rest] = self.x_end, self.y_end
            out["vx"][rest], out["vy"][rest] = vx_e, vy_e
        if self.T_R > 0:
            sgn = math.copysign(1.0, self.w0)
            q_f = abs(self.w0) * self.T_R / self.lam_th
            out["theta"] = self.th0 + sgn * cf.decel_position(t - self.t0, q_f, self.lam_th,
                                                              self.T_R)
            out["omega"] = sgn * cf.decel_rate(t - self.t0, q_f, self.lam_th, self.T_R)
        else:
            out["theta"], out["omega"] = np.full(n, self.th0), np.zeros(n)
        return out
