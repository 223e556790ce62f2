"""How the camera is held: its configuration and its path through a shot.

``ladder``: a camera on a boom atop a stepladder slid along the ice by an attendant, as
in the paper: fixed orientation, follows the rock with a lag whose time constant varies
(the attendant's changing pace), small wobble.  ``handheld``: held at shoulder height,
more jitter, a slow yaw wander of a degree or two and a bobbing height.  ``static``: a
fixed camera (the rock may leave the view).  ``pole``: on a pole carried by a walker,
higher, with the pole's lightly damped sway (a resonance near 2-4 Hz whose amplitude
beats as the walker's steps excite it).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ..errors import ParameterError
from .camera import LENSES, Camera, base_rotation, rotation_matrix

MOTIONS = ("ladder", "handheld", "static", "pole")

# Per-motion defaults for the parameters left as None in CameraConfig.
_DEFAULTS = {
    "ladder": dict(height_m=2.0, lag_s=0.30, jitter_m=0.0015, jitter_deg=0.03,
                   yaw_wander_deg=0.0, height_wander_m=0.002),
    "handheld": dict(height_m=1.6, lag_s=0.20, jitter_m=0.006, jitter_deg=0.25,
                     yaw_wander_deg=1.5, height_wander_m=0.03),
    "pole": dict(height_m=3.0, lag_s=0.25, jitter_m=0.003, jitter_deg=0.1,
                 yaw_wander_deg=1.0, height_wander_m=0.02, vibration_deg=0.5),
    "static": dict(height_m=2.0, lag_s=0.30, jitter_m=0.0, jitter_deg=0.0,
                   yaw_wander_deg=0.0, height_wander_m=0.0),
}


@dataclass(frozen=True)
class CameraConfig:
    """The camera and how it is held.  ``None`` means "the documented default".

    Parameters
    ----------
    motion : {"ladder", "handheld", "static"}
        How the camera moves (default ``"ladder"``).
    height_m : float, optional
        Lens height above the ice (m), 0.5-20; default 2.0 (ladder, static), 1.6 (handheld).
    view_m : float
        Extent of ice (m) covered by the image's height (the short side) at the ice
        plane; sets the focal length f = height_px * height_m / view_m.  Default 1.8
        (a 0.29 m rock is ~90 px across at 960x540).
    tilt_deg : float
        Constant tilt of the optical axis away from the vertical (deg), default 1.5.
    tilt_azimuth_deg : float, optional
        Direction of the tilt in the image (deg); default: random from the seed.
    yaw_deg : float, optional
        World direction of the image's +u (right) axis, counter-clockwise from the grid's
        +X (deg).  Default: the shot's direction of travel (pure rotation: +X), plus a
        random offset of up to ``yaw_offset_max_deg``.
    yaw_offset_max_deg : float
        Bound of the random yaw offset when ``yaw_deg`` is None (deg), default 3.
    k1, k2 : float
        Lens distortion (r^2 and r^4 terms; for the fisheye, of the angle off the axis,
        see :class:`~.camera.Camera`); default -0.08 (moderate barrel) and 0.  Action
        cameras: k1 down to about -0.35 with k2 > 0.
    lens : {"radial", "fisheye"}
        Brown's radial polynomial (default) or the equidistant fisheye.
    pixel_aspect : float
        Pixel width / height, default 1; NTSC DV 10/11 (fx = f / pixel_aspect).
    principal_offset_px : (float, float), optional
        Principal point minus the image centre (px); default: random, up to 2.5 % of
        the image size, from the seed.
    lag_s : float, optional
        Time constant of the follower (s): ladder 0.30, handheld 0.20.
    speed_variation : float
        Relative variation of the follower's time constant (the attendant's pace), 0.35.
    jitter_m, jitter_deg : float, optional
        RMS of the fast (1.5-8 Hz) position (m) and angle (deg) shake:
        ladder 0.0015 m / 0.03 deg, handheld 0.006 m / 0.25 deg.
    yaw_wander_deg : float, optional
        RMS of the slow (0.05-0.4 Hz) yaw wander (deg): ladder 0, handheld 1.5.
    height_wander_m : float, optional
        RMS of the slow height change (m): ladder 0.002, handheld 0.03.
    vibration_deg : float, optional
        RMS of the pole's resonant sway (deg): pole 0.5, others 0.
    vibration_hz : float
        Resonance of that sway (Hz), default 3.
    offset_m : (float, float)
        Where the camera aims relative to the rock, in the world frame (m), default 0.
    """

    motion: str = "ladder"
    height_m: float | None = None
    view_m: float = 1.8
    tilt_deg: float = 1.5
    tilt_azimuth_deg: float | None = None
    yaw_deg: float | None = None
    yaw_offset_max_deg: float = 3.0
    k1: float = -0.08
    k2: float = 0.0
    lens: str = "radial"
    pixel_aspect: float = 1.0
    principal_offset_px: tuple[float, float] | None = None
    lag_s: float | None = None
    speed_variation: float = 0.35
    jitter_m: float | None = None
    jitter_deg: float | None = None
    yaw_wander_deg: float | None = None
    height_wander_m: float | None = None
    offset_m: tuple[float, float] = (0.0, 0.0)
    vibration_deg: float | None = None
    vibration_hz: float = 3.0

    def resolved(self) -> "CameraConfig":
        """A copy with the motion-dependent ``None`` fields filled in, validated."""
        if self.motion not in MOTIONS:
            raise ParameterError(f"unknown camera motion {self.motion!r}; expected one of "
                                 f"{list(MOTIONS)}", where="camera")
        if self.lens not in LENSES:
            raise ParameterError(f"unknown lens {self.lens!r}; expected one of "
                                 f"{list(LENSES)}", where="camera.lens")
        d = asdict(self)
        for key, val in {"vibration_deg": 0.0, **_DEFAULTS[self.motion]}.items():
            if d[key] is None:
                d[key] = val
        out = CameraConfig(**d)
        checks = [("height_m", 0.5, 20.0), ("view_m", 0.3, 10.0), ("tilt_deg", 0.0, 20.0),
                  ("lag_s", 0.01, 5.0), ("speed_variation", 0.0, 0.9),
                  ("jitter_m", 0.0, 0.1), ("jitter_deg", 0.0, 5.0),
                  ("yaw_wander_deg", 0.0, 20.0), ("height_wander_m", 0.0, 0.3),
                  ("k1", -0.5, 0.5), ("k2", -0.5, 0.5), ("yaw_offset_max_deg", 0.0, 45.0),
                  ("pixel_aspect", 0.5, 2.0), ("vibration_deg", 0.0, 5.0),
                  ("vibration_hz", 0.5, 20.0)]
        for key, lo, hi in checks:
            v = getattr(out, key)
            if not np.isfinite(v) or not lo <= v <= hi:
                raise ParameterError(f"{v!r} is outside [{lo}, {hi}]", where=f"camera.{key}")
        if out.view_m >= out.height_m * 3 and out.lens != "fisheye":
            raise ParameterError("view wider than 3x the camera height needs a fisheye",
                                 where="camera.view_m")
        return out


def _wander(rng, rms: float, f_lo: float, f_hi: float, n: int = 8):
    """A smooth random function of time: n sinusoids with log-uniform frequencies (Hz)."""
    freqs = np.exp(rng.uniform(np.log(f_lo), np.log(f_hi), n))
    phases = rng.uniform(0, 2 * np.pi, n)
    amp = rms * np.sqrt(2.0 / n)

    def f(t):
        t = np.asarray(t, dtype=float)
        return amp * np.sin(2 * np.pi * freqs * t[..., None] + phases).sum(axis=-1)

    return f


class CameraPath:
    """The camera's pose as a function of time through one shot.

    Parameters
    ----------
    cfg : CameraConfig
        Resolved configuration.
    width, height : int
        Image size (px).
    rock_xy : callable
        t (s, array) -> rock centre in the world (N, 2) (m).
    t0, t1 : float
        Time span to cover (s).
    travel_yaw_rad : float
        World direction of the shot's travel (or +X for a pure rotation), rad.
    rng : numpy.random.Generator
        Seeded source of every random choice.
    """

    def __init__(self, cfg: CameraConfig, width: int, height: int, rock_xy, t0: float,
                 t1: float, travel_yaw_rad: float, rng: np.random.Generator):
        self.cfg = cfg
        self.width, self.height = int(width), int(height)
        self.f_px = self.height * cfg.height_m / cfg.view_m
        if cfg.principal_offset_px is None:
            off = rng.uniform(-1, 1, 2) * 0.025 * np.array([self.width, self.height])
        else:
            off = np.asarray(cfg.principal_offset_px, dtype=float)
        self.cx = (self.width - 1) / 2.0 + off[0]
        self.cy = (self.height - 1) / 2.0 + off[1]
        if cfg.yaw_deg is None:
            self.yaw0 = travel_yaw_rad + np.deg2rad(rng.uniform(-1, 1) * cfg.yaw_offset_max_deg)
        else:
            self.yaw0 = np.deg2rad(cfg.yaw_deg)
        az = (rng.uniform(0, 2 * np.pi) if cfg.tilt_azimuth_deg is None
              else np.deg2rad(cfg.tilt_azimuth_deg))
        tilt = np.deg2rad(cfg.tilt_deg)
        self.R_tilt = rotation_matrix([tilt * np.cos(az), tilt * np.sin(az), 0.0])
        jr = np.deg2rad(cfg.jitter_deg)
        self._jit_pos = [_wander(rng, cfg.jitter_m, 1.5, 8.0) for _ in range(2)]
        self._jit_ang = [_wander(rng, jr, 1.5, 8.0) for _ in range(3)]
        self._yaw = _wander(rng, np.deg2rad(cfg.yaw_wander_deg), 0.05, 0.4, 4)
        self._dz = _wander(rng, cfg.height_wander_m, 0.1, 0.8, 4)
        self._pace = _wander(rng, cfg.speed_variation / np.sqrt(2), 0.1, 0.6, 4)
        self._follow(rock_xy, t0, t1)
        if cfg.vibration_deg > 0:  # a narrow band around the resonance: a beating sway
            f0, vr = cfg.vibration_hz, np.deg2rad(cfg.vibration_deg)
            self._jit_ang = [lambda t, a=f, b=_wander(rng, vr, 0.93 * f0, 1.07 * f0, 6):
                             a(t) + b(t) for f in self._jit_ang]

    def _follow(self, rock_xy, t0, t1):
        """Integrate the follower dC/dt = (target - C) / tau(t) on a fine time grid."""
        dt = 1.0 / 240.0
        tg = np.arange(t0 - dt, t1 + 2 * dt, dt)
        target = rock_xy(tg) + np.asarray(self.cfg.offset_m, dtype=float)
        C = np.empty_like(target)
        C[0] = target[0]
        if self.cfg.motion == "static":
            C[:] = target[0]
        else:
            tau = self.cfg.lag_s * np.clip(1.0 + self._pace(tg), 0.2, 3.0)
            for i in range(1, len(tg)):  # 240 steps/s of a scalar recursion: cheap
                a = dt / (tau[i] + dt)  # implicit Euler: stable for any tau
                C[i] = C[i - 1] + a * (target[i] - C[i - 1])
        self._tg, self._C = tg, C

    def centre(self, t) -> np.ndarray:
        """Camera centre(s) (N, 3) in the world at times ``t`` (m)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        x = np.interp(t, self._tg, self._C[:, 0]) + self._jit_pos[0](t)
        y = np.interp(t, self._tg, self._C[:, 1]) + self._jit_pos[1](t)
        z = self.cfg.height_m + self._dz(t)
        return np.column_stack([x, y, np.broadcast_to(z, t.shape)])

    def rotation(self, t: float) -> np.ndarray:
        """World -> camera rotation at time ``t`` (s)."""
        R = self.R_tilt @ base_rotation(self.yaw0 + float(self._yaw(t)))
        shake = np.array([float(f(t)) for f in self._jit_ang])
        if shake.any():
            R = rotation_matrix(shake) @ R
        return R

    def camera(self, t: float) -> Camera:
        """The full :class:`Camera` at time ``t`` (s)."""
        return Camera(self.f_px, self.cx, self.cy, self.width, self.height,
                      R=self.rotation(t), C=self.centre(t)[0], k1=self.cfg.k1, k2=self.cfg.k2,
                      pixel_aspect=self.cfg.pixel_aspect, lens=self.cfg.lens)

    def yaw_deg(self, t) -> np.ndarray:
        """Image +u direction in the world (deg CCW from +X), without the fast shake."""
        return np.rad2deg(self.yaw0 + self._yaw(np.asarray(t, dtype=float)))
