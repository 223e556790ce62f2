"""Test worlds that hide effects OUTSIDE discovery's vocabulary.

The truth is integrated here, independently of the code under test: ``solve_ivp`` of the
paper's equations (Jensen & Shegelski 2004; state x, y, vx, vy, theta, omega in plain
Cartesian form) plus one hidden term, then sampled at 30 fps with Gaussian noise into a
contract series.  Families (``FAMILIES``), each with its strength's meaning:

* ``friction_field`` -- friction multiplied by 1 + A sin(2 pi y / wavelength + phase)
  along the sheet (A = strength, wavelength 2-5 m, random phase; the response in
  position grows as wavelength^2, a 1.5 m field of 2.3 % was missed);
* ``spin_coupling`` -- d|omega|/dt multiplied by 1 + c v (c = +-strength, s/m);
* ``translation_coupling`` -- dv/dt multiplied by 1 + c |omega| (c = +-strength, s/rad);
* ``curl_spin_dependence`` -- a_T multiplied by (|omega| / omega_ref)^p (p = strength;
  the spin is made to stop before the translation, so the curl fades with it);
* ``friction_law`` -- the translational friction law bends below a knee speed u_k
  (0.25-0.8 m/s): its log-log slope changes by -dphi (dphi = +-strength) from
  phi above the knee, written here as exp of half dphi times the log-ratio of
  (v^2 + u_k^2) and (v^2 + 0.02^2).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from scipy.integrate import solve_ivp

from curltrack.series import Series, make_meta

G = 9.81
R, R_BAND = 0.14, 0.0625
V_STOP, W_STOP = 1e-5, 1e-4   # m/s, rad/s
V_C = 0.01          # the paper model's low-speed taper of the transverse acceleration
NOISE_M = 0.002
NOISE_RAD = float(np.radians(0.3))

FAMILIES = ("friction_field", "spin_coupling", "translation_coupling",
            "curl_spin_dependence", "friction_law")

#: the truth key of each family that the extension's params must recover
KEYS = {"friction_field": ("amplitude", "wavelength_m"), "spin_coupling": ("c_s_per_m",),
        "translation_coupling": ("c_s_per_rad",), "curl_spin_dependence": ("p",),
        "friction_law": ("dphi_low",)}


def integrate(v0, omega0, phi_y, alpha_y, phi_t, alpha_t, a_T, hidden=None, fps=30.0,
              tail_s=1.0):
    """The paper's equations + ``hidden`` multipliers, sampled at ``fps``.

    ``hidden`` may give ``fric(y, v, w)`` (translation friction multiplier),
    ``spin(y, v, w)`` (rotation friction multiplier) and ``curl(v, w)`` (a_T multiplier);
    |omega| = w.  Returns (t, x, y, theta, t_stop_translation, t_stop_rotation).
    """
    hidden = hidden or {}
    one = lambda *a: 1.0  # noqa: E731
    fric, spin, curl = (hidden.get(k, one) for k in ("fric", "spin", "curl"))
    k_y = alpha_y * G
    k_t = 2.0 * G * alpha_t * R_BAND ** (1.0 + phi_t) / R ** 2
    sgn = math.copysign(1.0, omega0)

    def rhs(t, z, moving, spinning):
        x, y, vx, vy, th, w = z
        v = math.hypot(vx, vy) if moving else 0.0
        w = max(w, 0.0) if spinning else 0.0
        d = np.zeros(6)
        if moving and v > 0:
            ux, uy = vx / v, vy / v
            dec = k_y * max(v, 1e-9) ** phi_y * fric(y, v, w)
            lat = sgn * a_T * (1.0 - math.exp(-(v / V_C) ** 2)) * curl(v, w) if spinning else 0.0
            d[0], d[1] = vx, vy
            d[2] = -dec * ux - lat * uy    # left normal of (ux, uy) is (-uy, ux)
            d[3] = -dec * uy + lat * ux
        if spinning:
            d[4] = sgn * w
            d[5] = -k_t * max(w, 1e-9) ** phi_t * spin(y, v, w)
        return d

    # thresholds of the stop events: the time left from there is < 1e-8 s, the distance
    # and angle left < 1e-12 (the decay laws' own stop; smaller thresholds make the
    # step size underflow as omega^phi_theta diverges)
    stop_v = lambda t, z, *a: math.hypot(z[2], z[3]) - V_STOP  # noqa: E731
    stop_w = lambda t, z, *a: z[5] - W_STOP  # noqa: E731
    stop_v.terminal = stop_w.terminal = True
    stop_v.direction = stop_w.direction = -1
    z = np.array([0.0, 0.0, 0.0, v0, 0.0, abs(omega0)])
    moving, spinning, t0 = True, True, 0.0
    stops = {}
    pieces = []
    while True:
        # a motion within the event's threshold of its stop at a piece's start has stopped
        if moving and math.hypot(z[2], z[3]) <= V_STOP:
            moving, z[2], z[3] = False, 0.0, 0.0
            stops["v"] = t0
        if spinning and z[5] <= W_STOP:
            spinning, z[5] = False, 0.0
            stops["w"] = t0
        if not (moving or spinning):
            break
        ev = ([stop_v] if moving else []) + ([stop_w] if spinning else [])
        sol = solve_ivp(rhs, (t0, 300.0), z, method="DOP853", rtol=1e-10, atol=1e-12,
                        events=ev, dense_output=True, args=(moving, spinning))
        assert sol.status == 1, sol.message
        t1 = sol.t[-1]
        pieces.append((t0, t1, sol.sol, moving, spinning))
        z = sol.y[:, -1].copy()
        hit = [i for i, te in enumerate(sol.t_events) if len(te)]
        kinds = (["v"] if moving else []) + (["w"] if spinning else [])
        for i in hit:
            if kinds[i] == "v":
                moving = False
                z[2] = z[3] = 0.0
                stops["v"] = t1
            else:
                spinning = False
                z[5] = 0.0
                stops["w"] = t1
        t0 = t1
    end = max(stops.values())
    n = int(math.floor((end + tail_s) * fps)) + 1
    t = np.arange(n) / fps
    out = np.empty((6, n))
    for ta, tb, sol, *_ in pieces:
        sel = (t >= ta) & (t <= tb)
        if sel.any():
            out[:, sel] = sol(t[sel])
    sel = t > t0
    out[:, sel] = z[:, None]
    theta = out[4]
    return t, out[0], out[1], theta, stops["v"], stops["w"]


def as_series(t, x, y, theta, t_tr, t_rot, rng, fps=30.0, noise="white") -> Series:
    """A noisy contract series with the true stops in the sidecar.

    ``noise``: a class of :data:`curltrack.instrument.NOISE_CLASSES` (the real-data
    issue's: white, ar1, steps, heavy) at 2 mm / 0.3 deg scale.
    """
    from curltrack.instrument import draw_noise

    n = t.size
    data = pd.DataFrame({"frame": np.arange(n), "t": t,
                         "x": x + draw_noise(noise, t, NOISE_M, rng),
                         "y": y + draw_noise(noise, t, NOISE_M, rng),
                         "theta": theta + draw_noise(noise, t, NOISE_RAD, rng),
                         "ok": np.ones(n, int), "sigma_xy": NOISE_M, "sigma_theta": NOISE_RAD})
    sf = lambda ts: int(np.searchsorted(t, ts - 1e-9)) if ts < t[-1] else None  # noqa: E731
    meta = make_meta(fps, n, t_stop_translation=float(t_tr), t_stop_rotation=float(t_rot),
                     stop_frame_translation=sf(t_tr), stop_frame_rotation=sf(t_rot))
    return Series(data, meta, None)


def draw_ice(rng) -> dict:
    """Paper-like pebbled ice (as tests/discover/_synth.ice)."""
    return dict(phi_y=float(rng.uniform(-0.4, 0.0)), alpha_y=float(rng.uniform(0.006, 0.01)),
                phi_t=float(rng.uniform(-1.4, -0.9)), a_T=float(rng.uniform(3e-3, 7e-3)))


def _alpha_theta(v0, omega0, ice, ratio=1.0):
    """alpha_theta that stops the spin at ``ratio`` times the translation's stop time
    (closed forms of the paper's decay law, no hidden term)."""
    phi_y, phi_t = ice["phi_y"], ice["phi_t"]
    t_fs = v0 ** (1 - phi_y) / ((1 - phi_y) * ice["alpha_y"] * G)
    t_rot = ratio * t_fs
    k_t = abs(omega0) ** (1 - phi_t) / ((1 - phi_t) * t_rot)
    return k_t * R ** 2 / (2.0 * G * R_BAND ** (1.0 + phi_t))


#: families whose worlds are sessions by default: (shots, spin ranges (rad/s) in turn).
#: On one draw the spin falls with the speed, so a friction law and a translation decay
#: scaled by 1 + c |omega| are aliases; a slow and a fast spin tell them apart.
SESSIONS = {"friction_law": (2, ((0.6, 1.2), (2.4, 3.5))),
            "translation_coupling": (2, ((0.6, 1.2), (2.4, 3.5)))}
SPINS = ((1.2, 2.5),)


def make_world(family: str, strength: float, rng, n_shots: int | None = None, ice=None,
               noise: str = "white"):
    """Shots on one sheet with a hidden ``family`` term of the given strength
    (``n_shots`` default: :data:`SESSIONS`, else one).

    Returns
    -------
    shots : list of Series
    truth : dict
        The hidden term's parameters in the extension's names.
    """
    ice = ice or draw_ice(rng)
    sign = float(rng.choice([-1.0, 1.0]))
    truth, hidden = {"family": family}, {}
    ratio = 1.0
    if family == "friction_field":
        lam, ph = float(rng.uniform(2.0, 5.0)), float(rng.uniform(0, 2 * np.pi))
        f = lambda y, v, w: 1.0 + strength * math.sin(2 * math.pi * y / lam + ph)  # noqa: E731
        hidden = {"fric": f, "spin": f}
        truth.update(amplitude=strength, wavelength_m=lam, phase_rad=ph)
    elif family == "spin_coupling":
        c = sign * strength
        hidden = {"spin": lambda y, v, w: 1.0 + c * v}
        truth["c_s_per_m"] = c
    elif family == "translation_coupling":
        c = sign * strength
        hidden = {"fric": lambda y, v, w: 1.0 + c * w}
        truth["c_s_per_rad"] = c
    elif family == "curl_spin_dependence":
        ratio = float(rng.uniform(0.55, 0.8))
        truth["p"] = strength
    elif family == "friction_law":
        d, u_k = sign * strength, float(rng.uniform(0.25, 0.8))
        hidden = {"fric": lambda y, v, w: math.exp(
            0.5 * d * (math.log(v * v + u_k * u_k) - math.log(v * v + 0.02 ** 2)))}
        truth.update(dphi_low=d, u_knee_m_per_s=u_k, phi_y=ice["phi_y"], alpha_y=ice["alpha_y"])
    elif family != "none":
        raise ValueError(family)
    shots = []
    default_n, spins = SESSIONS.get(family, (1, SPINS))
    for i in range(default_n if n_shots is None else n_shots):
        v0 = float(rng.uniform(1.6, 2.2))
        omega0 = float(rng.choice([-1, 1]) * rng.uniform(*spins[i % len(spins)]))
        a_th = _alpha_theta(v0, omega0, ice, ratio)
        if family == "curl_spin_dependence":
            w_ref, p = abs(omega0), strength
            hidden = {"curl": lambda v, w, w_ref=w_ref: ((w * w + 0.05 ** 2) / w_ref ** 2) ** (0.5 * p)}
            truth["omega_ref_rad_per_s"] = w_ref
        t, x, y, th, t_tr, t_rot = integrate(v0, omega0, ice["phi_y"], ice["alpha_y"],
                                             ice["phi_t"], a_th, ice["a_T"], hidden)
        shots.append(as_series(t, x, y, th, t_tr, t_rot, rng, noise=noise))
    return shots, truth


def true_mu(truth, u):
    """The hidden friction law mu(u) of a ``friction_law`` world (m/s in, no unit out)."""
    u = np.asarray(u, dtype=float)
    d, u_k = truth["dphi_low"], truth["u_knee_m_per_s"]
    return truth["alpha_y"] * u ** truth["phi_y"] * np.exp(
        0.5 * d * (np.log(u * u + u_k * u_k) - np.log(u * u + 0.02 ** 2)))


def curve_pulls(ext, truth, lo=0.15, hi_frac=0.8):
    """(fitted - true mu(u)) / its 1-sigma band over lo <= u <= hi_frac * u_max, where a
    draw's data weigh the law (below ~0.15 m/s a draw spends its last second)."""
    f = ext["function"]
    u = np.asarray(f["x"])
    sel = (u >= lo) & (u <= hi_frac * u.max())
    val = np.asarray(f["value"])[sel]
    band = 0.5 * (np.asarray(f["band_hi"]) - np.asarray(f["band_lo"]))[sel]
    return (val - true_mu(truth, u[sel])) / band


def make_peer_law_world(rng, noise: str = "white", n_shots: int = 2):
    """Draws under a friction law written as a peer simulator would: a constant plus
    a term that falls with speed, mu(u) = mu_c + mu_1 (u / 1 m/s)^(-1/2) (not a power
    law, and not the bent power law of discovery's ``friction_law`` either).

    Shots of one session with a slow and a fast spin (:data:`SESSIONS`): on one draw
    the two aliases explained a peer-law draw alike, delta-BIC 1161 and 1154.

    Returns (shots, truth) with ``truth["mu"]`` the law as a function of u (m/s).
    """
    ice = draw_ice(rng)
    mu1 = float(rng.uniform(0.006, 0.01))
    frac = float(rng.uniform(0.3, 0.7))     # share of the constant at 1 m/s
    mu_c, mu_1 = frac * mu1, (1.0 - frac) * mu1
    law = lambda u: mu_c + mu_1 / np.sqrt(np.maximum(u, 1e-9))  # noqa: E731
    # the integrator's law is alpha_y v^phi_y times the hidden factor: divide it out
    fric = lambda y, v, w: float(law(v)) / (ice["alpha_y"] * max(v, 1e-9) ** ice["phi_y"])  # noqa: E731
    shots = []
    spins = SESSIONS["friction_law"][1]
    for i in range(n_shots):
        v0 = float(rng.uniform(1.6, 2.2))
        omega0 = float(rng.choice([-1, 1]) * rng.uniform(*spins[i % len(spins)]))
        a_th = _alpha_theta(v0, omega0, ice)
        t, x, y, th, t_tr, t_rot = integrate(v0, omega0, ice["phi_y"], ice["alpha_y"],
                                             ice["phi_t"], a_th, ice["a_T"], {"fric": fric})
        shots.append(as_series(t, x, y, th, t_tr, t_rot, rng, noise=noise))
    return shots, {"family": "friction_law", "mu_c": mu_c, "mu_1": mu_1, "mu": law}


def make_peer_physics_world(rng, noise: str = "white"):
    """One shot as a peer simulator with physics of its own would draw it - none of the
    paper's laws: friction a constant plus a term that decays with speed, mu(u) = mu_0 +
    mu_1 exp(-u / u_0); a curl that grows as the rock slows, k / (u + 0.3 m/s); a spin
    that decays as |omega|^0.4 / (u + 0.2 m/s) (integrated here, 30 fps, to the stop
    and 1 s on, the spin held where the slide ends).

    Returns (series, truth).
    """
    v0 = float(rng.uniform(1.9, 2.3))
    w0 = float(rng.choice([-1, 1]) * rng.uniform(0.8, 2.5))
    mu0, mu1, u0 = rng.uniform(0.006, 0.009), rng.uniform(0.002, 0.006), rng.uniform(0.3, 0.8)
    k = float(rng.uniform(0.002, 0.005))

    def rhs(t, z):
        x, y, vx, vy, th, w = z
        u = math.hypot(vx, vy)
        if u < 1e-4:
            return [0.0, 0.0, 0.0, 0.0, w, 0.0]
        a = G * (mu0 + mu1 * math.exp(-u / u0))
        lat = -math.copysign(k / (u + 0.3), w) if abs(w) > 1e-3 else 0.0
        ex, ey = vx / u, vy / u
        dw = -math.copysign(0.02 * abs(w) ** 0.4 / (u + 0.2), w) if abs(w) > 1e-3 else 0.0
        return [vx, vy, -a * ex + lat * ey, -a * ey - lat * ex, w, dw]

    stop = lambda t, z: math.hypot(z[2], z[3]) - 1e-3  # noqa: E731
    stop.terminal, stop.direction = True, -1
    sol = solve_ivp(rhs, (0.0, 120.0), [0.0, 0.0, 0.0, v0, 0.0, w0], events=stop,
                    dense_output=True, rtol=1e-9, atol=1e-11)
    t_end = float(sol.t[-1])
    t = np.arange(int((t_end + 1.0) * 30.0) + 1) / 30.0
    z = sol.sol(np.minimum(t, t_end))
    return (as_series(t, z[0], z[1], z[4], t_end, t_end, rng, noise=noise),
            {"v0": v0, "omega0": w0, "mu0": mu0, "mu1": mu1, "u0": u0, "k": k})
