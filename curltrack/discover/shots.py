"""The measured shots as discovery sees them: rows, noise, stops, starting values."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import SeriesError
from ..rig import default_rig
from ..series import Series, series_stops
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
        +1 counter-clockwise, -1 clockwise.
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
    t_stop_translation: float | None = None
    t_stop_rotation: float | None = None
    start: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)

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
                          path=name, where="ok")
    t = d["t"].to_numpy(float)
    frame = d["frame"].to_numpy(int)
    obs = {c: d[c].to_numpy(float) for c in COORDS}
    t_tr, t_rot, warnings = series_stops(series)
    travel = float(np.nanmax(np.hypot(obs["x"] - obs["x"][0], obs["y"] - obs["y"][0])))
    turn = float(np.nanmax(np.abs(obs["theta"] - obs["theta"][0])))
    translates = travel >= PURE_ROTATION_MAX_TRAVEL_M
    spins = turn >= MIN_ROTATION_RAD
    use, noise, sigma = {}, {}, {}
    for c in COORDS:
        t_stop = t_rot if c == "theta" else t_tr
        moving = spins if c == "theta" else translates
        use[c] = (t <= t_stop + REST_MARGIN_S) if (t_stop is not None) else np.ones(t.size, bool)
        if not moving:
            use[c] = np.zeros(t.size, bool)
        col = "sigma_theta" if c == "theta" else "sigma_xy"
        noise[c], sigma[c] = row_sigma(
            frame, obs[c], t=t, t_stop=t_stop, name=name, field=c,
            weights=d[col].to_numpy(float) if col in d.columns else None,
            floor=1e-6 if c == "theta" else 1e-5)
    if not any(u.any() for u in use.values()):
        raise SeriesError("the rock neither moves nor turns measurably; nothing to model",
                          path=name)
    heading = series.meta.get("rink_heading_deg")
    spin = 1 if (obs["theta"][-1] - obs["theta"][0]) >= 0 else -1
    shot = ShotData(name, t, frame, obs, use, sigma, noise,
                    heading_rad=math.radians(float(heading)) if heading is not None else 0.0,
                    translates=translates, spins=spins, spin=spin,
                    t_stop_translation=t_tr, t_stop_rotation=t_rot, warnings=warnings)
    shot.start = _starting_values(series, shot, rig or default_rig())
    return shot


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
        fr = fit_series(series, rig).values
    except CurltrackError:
        return out
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
    if fr.get("skew_deg") is not None and np.isfinite(fr["skew_deg"]):
        out["skew"] = -math.radians(float(fr["skew_deg"]))  # fit: skew_deg = -psi
    return out
