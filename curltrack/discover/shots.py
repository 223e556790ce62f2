"""The measured shots as discovery sees them: rows, noise, stops, starting values."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import SeriesError
from ..rig import default_rig
from ..series import Series, sample_index, series_stops
from ..series.noise import Noise, row_sigma

COORDS = ("x", "y", "theta")
#: rows kept after a stop (s): they pin the stop and the final position
REST_MARGIN_S = 0.5
MIN_ROWS = 30


@dataclass
class ShotData:
    """One shot's measured rows and what discovery needs to know about them.

    Attributes
    ----------
    name : str
        The file (for messages).
    t, frame : array
        Time (s) and frame index of the measured rows with t >= 0.
    obs : dict
        ``x``, ``y`` (m), ``theta`` (rad) at those rows.
    use : dict
        Per coordinate, the rows that enter the fits (t <= stop + 0.5 s).
    sigma : dict
        Per coordinate, the 1-sigma noise of each row (m or rad): the data-estimated
        level, modulated by the tracker's per-frame ``sigma_xy``/``sigma_theta`` if given.
    noise : dict of Noise
    heading_rad : float
        Direction of +y in the session's common frame (``rink_heading_deg``; 0 if absent).
    translates, spins : bool
        Whether the rock moves / turns measurably.
    spin : int
        +1 counter-clockwise, -1 clockwise; for a position-only shot, the side its curl
        says (a counter-clockwise spin curls to -x).
    theta_measured : bool
        False for a position-only series: theta does not enter the fits, the spin's
        size is not known (only its side, from the curl) and no candidate may change it.
    t_stop_translation, t_stop_rotation : float or None
    start : dict
        Starting values from the paper's closed-form fit (``curltrack.fit``).
    """

    name: str
    t: np.ndarray
    frame: np.ndarray
    obs: dict
    use: dict
    sigma: dict
    noise: dict
    heading_rad: float = 0.0
    translates: bool = True
    spins: bool = True
    spin: int = 1
    theta_measured: bool = True
    #: position-only shots: the fitted spin's start value (rad/s, signed) when the curl
    #: ends before the slide does (:func:`curltrack.discover.curl_end_from_positions`);
    #: None - the spin lasts the slide
    omega0_curl_end: float | None = None
    #: position-only shots: the curl says the spin's side beyond 2 sigma
    curl_side_sure: bool = False
    t_stop_translation: float | None = None
    t_stop_rotation: float | None = None
    start: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)
    #: the instrument's errors persist over many rows (the sidecar's ``noise_persists``;
    #: a series tracked from video, whose sidecar names it, unless it says otherwise):
    #: every coordinate's noise is judged as persisting (:func:`.search.residual_noise`)
    noise_persists: bool = False
    #: per coordinate, the instrument's own 1-sigma of each row (``sigma_xy``,
    #: ``sigma_theta``; NaN where not given): a tracker's includes its errors' slow parts
    stated_sigma: dict = field(default_factory=dict)
    #: what was taken off x, y (m) and theta (rad) of a series measured from another
    #: origin (:func:`_recentre`); the report gives the offsets in the series' frame
    origin: tuple = (0.0, 0.0, 0.0)

    @property
    def curls(self) -> bool:
        """Whether the transverse acceleration acts (sliding with a spin, measured or,
        for a position-only shot, assumed: its side comes from the curl)."""
        return self.translates and (self.spins or not self.theta_measured)

    def coords(self):
        """Coordinates that enter the fits."""
        return [c for c in COORDS if self.use[c].any()]

    @property
    def y_max_m(self) -> float:
        """Largest measured y (m) among the rows that enter the fits."""
        return float(np.nanmax(self.obs["y"][self.use["y"]]))

    @property
    def t_end_s(self) -> float:
        """End of the time an effect can act in (s): the first stop, or the last row."""
        return min(v for v in (self.t_stop_translation, self.t_stop_rotation, self.t[-1])
                   if v)


def shot_from_series(series: Series, rig=None) -> ShotData:
    """Prepare one series for discovery.

    ``rig`` supplies the rock's radii to the starting values (contract defaults).

    Raises
    ------
    SeriesError
        Too few measured rows, or too few consecutive frames to estimate the noise.
    """
    from ..fit import MIN_ROTATION_RAD, PURE_ROTATION_MAX_TRAVEL_M

    d = series.measured
    d = d[d["t"] >= 0]
    name = series.name
    if len(d) < MIN_ROWS:
        raise SeriesError(f"too few measured rows with t >= 0 ({len(d)}; need {MIN_ROWS})",
                          path=name, where=f"rows 2-{len(series.data) + 1}")
    t = d["t"].to_numpy(float)
    frame = sample_index(d)  # (exposures: fields of interlaced video count alike)
    obs = {c: d[c].to_numpy(float) for c in COORDS}
    t_tr, t_rot, warnings = series_stops(series)
    obs, origin = _recentre(t, obs, name, warnings)
    travel = float(np.nanmax(np.hypot(obs["x"] - obs["x"][0], obs["y"] - obs["y"][0])))
    has_theta = np.isfinite(obs["theta"])
    theta_measured = bool(series.theta_measured and has_theta.sum() >= MIN_ROWS)
    if not theta_measured:
        has_theta[:] = False
        warnings.append(f"{name}: theta not measured (position-only series): the spin's "
                        "side is taken from the curl, its size is not modelled (only when"
                        " the spin stops, if the curl ends before the slide)")
    th = obs["theta"][has_theta]
    turn = float(np.max(np.abs(th - th[0]))) if th.size else 0.0
    translates = travel >= PURE_ROTATION_MAX_TRAVEL_M
    spins = turn >= MIN_ROTATION_RAD
    use, noise, sigma, stated = {}, {}, {}, {}
    for c in COORDS:
        t_stop = t_rot if c == "theta" else t_tr
        moving = spins if c == "theta" else translates
        use[c] = (t <= t_stop + REST_MARGIN_S) if (t_stop is not None) else np.ones(t.size, bool)
        if not moving:
            use[c] = np.zeros(t.size, bool)
        if c == "theta":
            use[c] &= has_theta
            if not has_theta.any():
                noise[c] = Noise(1.0, 0.0, 0)  # never used: no theta row enters a fit
                sigma[c] = np.ones(t.size)
                continue
        rows = has_theta if c == "theta" else np.ones(t.size, bool)
        col = "sigma_theta" if c == "theta" else "sigma_xy"
        if col in d.columns:
            stated[c] = d[col].to_numpy(float)
        noise[c], s_rows = row_sigma(
            frame[rows], obs[c][rows], t=t[rows], t_stop=t_stop, name=name, field=c,
            weights=stated[c][rows] if c in stated else None,
            floor=1e-6 if c == "theta" else 1e-5)
        sigma[c] = np.full(t.size, noise[c].sigma)
        sigma[c][rows] = s_rows
    if not any(u.any() for u in use.values()):
        raise SeriesError("the rock neither moves nor turns measurably; nothing to model",
                          path=name)
    heading = series.meta.get("rink_heading_deg")
    spin = 1 if th.size == 0 or (th[-1] - th[0]) >= 0 else -1
    shot = ShotData(name, t, frame, obs, use, sigma, noise,
                    heading_rad=math.radians(float(heading)) if heading is not None else 0.0,
                    translates=translates, spins=spins, spin=spin,
                    theta_measured=theta_measured,
                    t_stop_translation=t_tr, t_stop_rotation=t_rot, warnings=warnings,
                    origin=origin,
                    noise_persists=bool(series.meta.get("noise_persists",
                                                        bool(series.meta.get("video")))),
                    stated_sigma=stated)
    shot.start = _starting_values(series, shot, rig or default_rig())
    if not theta_measured and translates:
        # the side of the spin from the data: the curl's (a_T < 0 in the fit's frame is
        # a counter-clockwise spin); a curl within 2 sigma of zero does not say
        a, e = shot.start.get("a_T_signed"), shot.start.get("a_T_err")
        if a is None:
            warnings.append(f"{name}: the curl could not be measured; spin side taken as "
                            "counter-clockwise")
        else:
            shot.spin = -1 if a > 0 else 1
            shot.curl_side_sure = e is not None and abs(a) >= 2 * e
            if not shot.curl_side_sure:
                warnings.append(f"{name}: the curl ({a:.2g} m/s^2) does not tell the "
                                "spin's side within 2 sigma; taken from its sign")
    return shot


def stated_sigma_rows(shot, c: str):
    """The sigma the instrument states for coordinate ``c``'s rows of ``shot`` that enter
    the fits (m or rad; NaN where not given), where it says its errors persist; else
    None (nothing stated, or noise that does not persist: the rows' scatter is then the
    whole of their error)."""
    v = shot.stated_sigma.get(c) if shot.noise_persists else None
    return None if v is None else v[shot.use[c]]


#: an origin (the rock at t = 0) further than this from the series' zero (m, rad) is
#: taken off before fitting: half the bounds of the offsets x0, y0, theta0
#: (:mod:`curltrack.physics.params`)
RECENTRE_BEYOND = 0.5
#: the first this many seconds of rows (at least 5) place the origin
#: (:func:`curltrack._stats.value_at_zero`)
RECENTRE_WINDOW_S = 1.0


def _recentre(t, obs, name, warnings):
    """``obs`` measured from the rock's own origin, and what was taken off (x, y, theta).

    The contract allows any origin (docs/files.md), and ``fit`` fits one; the joint
    model's per-shot offsets are bounded to +-1 m / rad.  A shot in rink coordinates
    (2 m and -6 m off) held them at their bounds: every baseline parameter at a bound,
    verdict ``unexplained`` and a warning blaming the instrument.  Where the rock at
    t = 0 (a quadratic through the first second, extrapolated) lies beyond
    :data:`RECENTRE_BEYOND` of zero, it is taken off; the report adds it back to the
    offsets."""
    from .._stats import value_at_zero

    finite = {c: np.isfinite(obs[c]) for c in COORDS}
    x0, y0, th0 = (value_at_zero(t[finite[c]], obs[c][finite[c]], RECENTRE_WINDOW_S)
                   if finite[c].any() else 0.0 for c in COORDS)
    if max(abs(x0), abs(y0)) <= RECENTRE_BEYOND:
        x0 = y0 = 0.0
    if abs(th0) <= RECENTRE_BEYOND:
        th0 = 0.0
    if not (x0 or y0 or th0):
        return obs, (0.0, 0.0, 0.0)
    warnings.append(f"{name}: measured from another origin (the rock at t = 0 at x "
                    f"{x0:.3g} m, y {y0:.3g} m, theta {th0:.3g} rad): taken off for the "
                    "fit; the offsets x0, y0, theta0 are reported in the series' frame")
    return {"x": obs["x"] - x0, "y": obs["y"] - y0, "theta": obs["theta"] - th0}, \
        (x0, y0, th0)


def _starting_values(series: Series, shot: ShotData, rig) -> dict:
    """Closed-form fit of the paper (``curltrack.fit``) as a starting point, with crude
    fallbacks when it fails (the discovery fit does not depend on it being good)."""
    from ..errors import CurltrackError
    from ..fit import fit_series
    from ..physics import closed_form as cf

    R, r = rig.inertia_radius_m, rig.band_radius_m
    out = {"v0": 0.0, "omega0": 0.0, "phi_y": 0.0, "phi_theta": 0.0, "a_T": 0.0,
           "skew": 0.0, "alpha_y": 0.01, "alpha_theta": 0.01}
    t_tr = shot.t_stop_translation or float(shot.t[-1])
    t_rot = shot.t_stop_rotation or float(shot.t[-1])
    if shot.translates:
        y_f = float(np.median(shot.obs["y"][-5:]))
        out["v0"] = 2.0 * abs(y_f) / t_tr
        out["alpha_y"] = cf.alpha_translation(out["v0"], 0.0, t_tr)
    if shot.spins:
        th_f = float(np.median(shot.obs["theta"][-5:]))
        out["omega0"] = 2.0 * th_f / t_rot
        out["alpha_theta"] = cf.alpha_rotation(abs(out["omega0"]), 0.0, t_rot, R, r)
    try:
        fitted = fit_series(series, rig)
    except CurltrackError:
        return out
    fr = fitted.values
    for k in ("v0", "omega0", "phi_y", "alpha_y", "phi_theta", "alpha_theta"):
        v = fr.get(k)
        if v is not None and np.isfinite(v):
            out[k] = float(v)
    lam_th = fr.get("lambda_theta")
    if out["phi_theta"] == 0.0 and lam_th is not None and np.isfinite(lam_th) and lam_th != 1:
        out["phi_theta"] = float(cf.phi_from_lambda(lam_th))
        out["alpha_theta"] = float(cf.alpha_rotation(abs(out["omega0"]), out["phi_theta"],
                                                     fr.get("t_Ftheta") or t_rot, R, r))
    if fr.get("a_T") is not None and np.isfinite(fr["a_T"]):
        out["a_T"] = abs(float(fr["a_T"]))
        out["a_T_signed"] = float(fr["a_T"])
        out["a_T_err"] = fitted.errors.get("a_T")
    if fr.get("skew_deg") is not None and np.isfinite(fr["skew_deg"]):
        out["skew"] = -math.radians(float(fr["skew_deg"]))  # fit: skew_deg = -psi
    return out
