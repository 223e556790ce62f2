"""Segment-level model: friction summed over the running band, segment by segment.

Where the paper model (:mod:`.shot`) puts the curl (a_T) and the rotation/translation
coupling (its own alpha, phi per channel; the paper's C_omega, C_y) in by hand, this model
has one friction law mu = alpha u^phi for the whole band and lets them come out.

Formulation
-----------
The band (radius r) is N equal segments at angles beta from the direction of travel f
(l = z x f is the left): position rho = r (cos beta f + sin beta l), ice-relative velocity

    u(beta) = (v - omega r sin beta) f + omega r cos beta l.

Each segment carries Mg/N and feels dF = -(Mg/N) mu(|u|) w(beta) e(beta), with
mu = alpha |u|^phi set by its own sliding speed over the ice, and
M a = sum dF,  (M R^2/2) domega/dt = sum (rho x dF)_z.

* ``friction_direction="ice"``: e = u/|u| (classical dry-friction direction).  With a
  uniform weight w = 1 the lateral force vanishes exactly by the symmetry
  beta -> pi - beta (u_l is odd, |u| even), whatever mu(u) is: no curl.  A front-back
  asymmetry ``asymmetry`` = epsilon, w = 1 - epsilon cos beta (less friction at the
  front, where more melting happens: Johnson 1981, Shegelski et al. 1996, the paper's
  review) gives a curl in the direction of rotation, of size ~ epsilon mu g omega r / v.
* ``friction_direction="film"`` (the paper's thin-film hypothesis, section "Implications
  of Wet Friction"): the leading half slides on fresh ice; the trailing half slides on the
  melt film laid by the leading half.  A trailing segment at beta rides on the track of
  the leading segment with the same lateral coordinate (beta' = pi - beta), and that film
  is taken to move with a fraction kappa (``film_drag``) of the velocity of the segment
  that produced it (it is dragged along by the wetted band).  Friction opposes the motion
  relative to the film:

      e(beta) ~ u(beta) - kappa u(pi - beta)
              = (1 - kappa)(v - omega r sin beta) f + (1 + kappa) omega r cos beta l,

  which tilts the trailing half's friction sideways: the rock curls in the direction of
  rotation even with uniform load.  When the rock hardly translates, every segment rides
  on its predecessor's track along the circle and there is no front or back: kappa and
  epsilon are scaled by s = v / (v + |omega| r), so pure rotation stays symmetric.

Free parameter: kappa.  To first order in omega r / v the draw's torque is 1/(1 - kappa)
+ phi times the Coulomb value, so the paper's C_omega = 2.54 for its draw (phi = -0.19)
gives kappa ~ 0.63 (the default); the lateral acceleration is then
a ~ mu g (omega r / v) 2 kappa / (pi (1 - kappa)) ~ 5e-3 m/s^2 for that draw, the size the
paper fits.  Friction is regularised as |u| -> sqrt(|u|^2 + u_eps^2), u_eps = 0.1 mm/s,
and a motion counts as stopped when its speed (v, or |omega| r) falls below 1 mm/s; the
stop time is extrapolated from there with the current deceleration.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np
from scipy.integrate import solve_ivp

from ..errors import ParameterError
from ..rig import BAND_RADIUS_M, G, INERTIA_RADIUS_M
from .shot import ALPHA_Y_DRAW, PHI_Y_DRAW, Trajectory, _ModelParams

U_EPS = 1e-4      # m/s, friction regularisation
V_STOP = 1e-3     # m/s, below this a motion is taken as stopped
KAPPA_DRAW = 0.63
HORIZON_S = 600.0


@dataclass(frozen=True)
class SegmentModel(_ModelParams):
    """A shot for the segment-level model.

    Parameters
    ----------
    v0, omega0 : float
        Initial speed (m/s, along +y) and spin (rad/s, > 0 counter-clockwise).
    phi, alpha : float
        mu = alpha u^phi for every segment (phi < 1, alpha > 0 in (m/s)^-phi).
    friction_direction : {"film", "ice"}
        Friction opposite the motion relative to the melt film or to the ice.
    film_drag : float
        kappa in [0, 1): film speed as a fraction of the speed of the segment that laid it.
    asymmetry : float
        epsilon in [0, 1): front-back friction asymmetry, weight 1 - epsilon cos(beta).
    R, r : float
        Inertia radius and band radius (m).
    n_segments : int
        Segments on the band (even, >= 8).
    """

    v0: float
    omega0: float
    phi: float = PHI_Y_DRAW
    alpha: float = ALPHA_Y_DRAW
    friction_direction: str = "film"
    film_drag: float = KAPPA_DRAW
    asymmetry: float = 0.0
    R: float = INERTIA_RADIUS_M
    r: float = BAND_RADIUS_M
    n_segments: int = 64

    def __post_init__(self):
        self._coerce_numbers(skip=("friction_direction",))
        if self.n_segments == int(self.n_segments):
            object.__setattr__(self, "n_segments", int(self.n_segments))
        if self.friction_direction not in ("film", "ice"):
            raise ParameterError(f"expected 'film' or 'ice', got {self.friction_direction!r}",
                                 where="friction_direction")
        checks = [("v0", self.v0 >= 0, ">= 0"), ("phi", self.phi < 1, "< 1"),
                  ("alpha", self.alpha > 0, "> 0"), ("film_drag", 0 <= self.film_drag < 1,
                                                     "in [0, 1)"),
                  ("asymmetry", 0 <= self.asymmetry < 1, "in [0, 1)"),
                  ("R", self.R > 0, "> 0"), ("r", self.r > 0, "> 0"),
                  ("n_segments", isinstance(self.n_segments, int) and self.n_segments >= 8
                   and self.n_segments % 2 == 0, "an even integer >= 8")]
        for name, ok, what in checks:
            if not ok:
                raise ParameterError(f"must be {what} (got {getattr(self, name)})", where=name)

    def to_dict(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}


def band_forces(model: SegmentModel, v: float, omega: float):
    """Friction on the band per unit mass, in the travel frame.

    Returns
    -------
    a_f, a_l : float
        Acceleration along the direction of travel and to its left (m/s^2).
    domega : float
        Angular acceleration (rad/s^2).
    """
    n, r = model.n_segments, model.r
    beta = (np.arange(n) + 0.5) * (2 * math.pi / n)
    c, s = np.cos(beta), np.sin(beta)
    u_f, u_l = v - omega * r * s, omega * r * c
    share = v / (v + abs(omega) * r) if v > 0 else 0.0
    weight = 1.0 - model.asymmetry * share * c
    if model.friction_direction == "film":
        kappa = model.film_drag * share * (c < 0)     # trailing half rides on the film
        e_f, e_l = (1 - kappa) * u_f, (1 + kappa) * u_l
    else:
        e_f, e_l = u_f, u_l
    speed = np.sqrt(u_f * u_f + u_l * u_l + U_EPS * U_EPS)
    norm = np.sqrt(e_f * e_f + e_l * e_l + U_EPS * U_EPS)
    mag = G * model.alpha * speed ** model.phi * weight / (n * norm)
    F_f, F_l = -mag * e_f, -mag * e_l
    torque = r * (c * F_l - s * F_f)
    return float(F_f.sum()), float(F_l.sum()), float(torque.sum()) * 2.0 / model.R ** 2


def _time_to_stop(speed_dec, t1: float, t_start: float) -> float:
    """Time (s) from ``t1`` until the speed reaches zero.

    ``speed_dec(t)`` gives (speed, deceleration) along the solution.  Near the stop the
    deceleration scales as a power p of the speed (p = phi of the friction law, also for
    coupled translation and rotation), so speed^(1-p) falls linearly: the time left is
    u / ((1 - p) dec).  p is read from the solution a little earlier (linear
    extrapolation, p = 0, stops a rock with phi > 0 early).
    """
    u1, dec1 = speed_dec(t1)
    if dec1 <= 0:
        return 0.0
    ta = max(t_start, t1 - u1 / dec1)
    ua, deca = speed_dec(ta)
    p = 0.0
    if ta < t1 and deca > 0 and ua > 1.2 * u1:
        p = math.log(deca / dec1) / math.log(ua / u1)
    return u1 / ((1.0 - min(p, 0.9)) * dec1)


def simulate_segment(model: SegmentModel, t=None, rtol: float = 1e-8) -> Trajectory:
    """Integrate the segment-level model and sample it at times ``t`` (s).

    Default times: 30 fps until both motions stopped plus 1 s.  Stop times are located
    by events at 1 mm/s and extrapolated to zero speed.
    """
    if not isinstance(model, SegmentModel):
        raise ParameterError(f"expected a SegmentModel, got {type(model).__name__}",
                             where="model")
    state = np.array([0.0, 0.0, 0.0, model.v0, 0.0, model.omega0])
    moving, spinning = model.v0 > V_STOP, abs(model.omega0) * model.r > V_STOP
    stops = {"translation": 0.0 if not moving else math.inf,
             "rotation": 0.0 if not spinning else math.inf}
    if not moving:
        state[3] = 0.0
    if not spinning:
        state[5] = 0.0
    pieces, t0 = [], 0.0
    while (moving or spinning) and t0 < HORIZON_S:
        def rhs(_t, z, moving=moving, spinning=spinning):
            vx, vy, om = z[2], z[3], z[5]
            v = math.hypot(vx, vy) if moving else 0.0
            fx, fy = (vx / v, vy / v) if v > 0 else (0.0, 1.0)
            a_f, a_l, dom = band_forces(model, v, om if spinning else 0.0)
            d = np.zeros(6)
            if moving:
                d[0], d[1] = vx, vy
                d[2], d[3] = a_f * fx - a_l * fy, a_f * fy + a_l * fx
            if spinning:
                d[4], d[5] = om, dom
            return d

        events = []
        if moving:
            ev = lambda _t, z: math.hypot(z[2], z[3]) - V_STOP  # noqa: E731
            ev.terminal, ev.direction = True, -1
            events.append(("translation", ev))
        if spinning:
            ev = lambda _t, z: abs(z[5]) * model.r - V_STOP  # noqa: E731
            ev.terminal, ev.direction = True, -1
            events.append(("rotation", ev))
        sol = solve_ivp(rhs, (t0, HORIZON_S), state, method="RK45", rtol=rtol, atol=1e-10,
                        events=[e for _, e in events], dense_output=True)
        t1, z1 = sol.t[-1], sol.y[:, -1].copy()
        pieces.append((t0, t1, sol.sol, moving, spinning))
        if sol.status == 1:
            k = next(i for i, te in enumerate(sol.t_events) if len(te))
            kind = events[k][0]
            if kind == "translation":
                def speed_dec(ti):
                    z = sol.sol(ti) if ti < t1 else z1
                    d, v = rhs(ti, z), math.hypot(z[2], z[3])
                    return v, -(z[2] * d[2] + z[3] * d[3]) / max(v, 1e-300)
            else:
                def speed_dec(ti):
                    z = sol.sol(ti) if ti < t1 else z1
                    return abs(z[5]), -np.sign(z[5]) * rhs(ti, z)[5]
            stops[kind] = t1 + _time_to_stop(speed_dec, t1, t0)
            if kind == "translation":
                z1[2] = z1[3] = 0.0
                moving = False
            else:
                z1[5] = 0.0
                spinning = False
        state, t0 = z1, t1
    pieces.append((t0, math.inf, state, False, False))
    if t is None:
        end = max(stops.values())
        if not math.isfinite(end):
            raise ParameterError(f"the rock does not stop within {HORIZON_S:.0f} s",
                                 where="model")
        t = np.arange(int(math.floor((end + 1.0) * 30.0)) + 1) / 30.0
    t = np.asarray(t, dtype=float).reshape(-1)
    if t.size and (not np.isfinite(t).all() or t.min() < 0):
        raise ParameterError("times must be finite and >= 0", where="t")
    out = np.empty((6, t.size))
    for ta, tb, sol, mv, sp in pieces:
        sel = (t >= ta) & (t <= tb)
        if sel.any():
            z = sol(t[sel]) if callable(sol) else np.repeat(np.asarray(sol)[:, None], sel.sum(), 1)
            if not mv:
                z[2:4] = 0.0
            if not sp:
                z[5] = 0.0
            out[:, sel] = z
    return Trajectory(t=t, x=out[0], y=out[1], vx=out[2], vy=out[3], theta=out[4],
                      omega=out[5], t_stop_translation=stops["translation"],
                      t_stop_rotation=stops["rotation"])


def curl_vs_omega(omega0s, v0: float = 2.0, **kw) -> dict:
    """Curl x_F (m), turns and effective lambdas of segment-model shots over spins.

    Parameters
    ----------
    omega0s : sequence of float
        Initial spins (rad/s).
    v0 : float
        Initial speed (m/s), the same for every shot.
    **kw
        Further :class:`SegmentModel` parameters (friction_direction, asymmetry, ...).

    Returns
    -------
    dict of ndarray
        ``omega0``, ``x_F`` (m, signed), ``y_F`` (m), ``turns``, ``t_FS``, ``t_Ftheta``
        (s), ``lambda_y`` = v0 t_FS / d_F and ``lambda_theta`` = omega0 t_Ftheta / theta_F
        (exact for the paper's power laws).
    """
    rows = []
    for w in omega0s:
        tr = simulate_segment(SegmentModel(v0=v0, omega0=w, **kw))
        d_F = math.hypot(tr.x[-1], tr.y[-1])
        rows.append((w, tr.x[-1], tr.y[-1], tr.theta[-1] / (2 * math.pi),
                     tr.t_stop_translation, tr.t_stop_rotation,
                     v0 * tr.t_stop_translation / d_F if d_F else math.nan,
                     abs(w) * tr.t_stop_rotation / abs(tr.theta[-1]) if w else math.nan))
    cols = np.array(rows, dtype=float).T
    keys = ("omega0", "x_F", "y_F", "turns", "t_FS", "t_Ftheta", "lambda_y", "lambda_theta")
    return dict(zip(keys, cols))


def v0_for_length(omega0: float, y_target: float = 28.0, **kw) -> float:
    """Initial speed (m/s) that makes a shot end at y = ``y_target`` (m).

    The paper's spinner series was thrown to finish near the house (roughly fixed length,
    slower release for more turns); this reproduces that protocol.
    """
    from scipy.optimize import brentq

    def miss(v0):
        return simulate_segment(SegmentModel(v0=v0, omega0=omega0, **kw), t=[HORIZON_S]).y[0] \
            - y_target

    lo, hi = 0.2, 1.0
    while miss(hi) < 0:
        lo, hi = hi, hi * 1.5
        if hi > 20:
            raise ParameterError(f"no v0 <= 20 m/s reaches y = {y_target} m", where="v0")
    return float(brentq(miss, lo, hi, xtol=1e-4))
