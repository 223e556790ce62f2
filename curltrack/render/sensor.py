"""How the sensor records in time and colour: interlaced fields, rolling shutter, frame
timing (jitter, dropped frames), chroma subsampling, auto exposure and white balance.

Times
-----
Frame ``k`` of a progressive video is captured at ``t_k`` (``k / fps`` plus any timing
jitter; the container's timestamp carries it exactly).  An interlaced frame holds two
fields: field 0 (exposed first) at ``t_k`` and field 1 at ``t_k + 1 / (2 fps)``, each in
its own rows (``bff``, NTSC DV: field 0 = the odd rows 1, 3, 5...; ``tff``: the even
rows).  With a rolling shutter of readout time ``R`` every sensor row ``v`` (of the
recorded, distorted image, 0 at the top) is exposed around
``t + R ((v + 0.5) / H - 0.5)``: the reference time ``t`` (the truth's) is the middle of
the readout, the image's centre line.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..errors import ParameterError

SCANS = ("progressive", "interlaced")
FIELD_ORDERS = ("bff", "tff")
CHROMAS = ("444", "422", "420", "411")
TIME_BASE = 90000  # container ticks per second: every capture time is a multiple of it


@dataclass(frozen=True)
class SensorConfig:
    """Timing and colour of the recording (defaults: progressive, global shutter, full
    colour, regular frames, fixed exposure: the renderer's behaviour before these).

    Parameters
    ----------
    scan : {"progressive", "interlaced"}
        Interlaced: two fields per frame, 1 / (2 fps) apart, woven into the frame's
        alternate rows; the shutter is then a fraction of the field period.
    field_order : {"bff", "tff"}
        Which field is exposed first: ``bff`` (bottom field first, NTSC DV: odd rows)
        or ``tff`` (even rows).
    readout_s : float
        Rolling shutter: time from the first row's exposure to the last's (s); 0 = a
        global shutter.  Phones 10-30 ms, action cameras 5-20 ms.
    chroma : {"444", "422", "420", "411"}
        Colour resolution recorded: 4:2:2 halves it across, 4:2:0 also down (within each
        field when interlaced), 4:1:1 (NTSC DV) quarters it across: thin threads lose
        most of their colour.
    frame_jitter_s : float
        RMS of each frame's capture time about its nominal slot (s), e.g. 0.001; the
        container's timestamps carry the true times (variable frame rate).
    drop_rate : float
        Probability that a frame is dropped (not written; the next timestamp jumps).
    auto_exposure : float
        RMS of the relative exposure-gain drift of auto exposure (e.g. 0.1), 0 = off.
    white_balance : float
        RMS of the relative red and blue gain drift of auto white balance, 0 = off.
    ae_lag_s : float
        Time constant with which exposure and white balance follow their targets (s).
    """

    scan: str = "progressive"
    field_order: str = "bff"
    readout_s: float = 0.0
    chroma: str = "444"
    frame_jitter_s: float = 0.0
    drop_rate: float = 0.0
    auto_exposure: float = 0.0
    white_balance: float = 0.0
    ae_lag_s: float = 0.6

    @property
    def interlaced(self) -> bool:
        return self.scan == "interlaced"

    def validate(self, fps: float) -> None:
        """Raise ParameterError naming the first bad field."""
        def bad(name, msg):
            raise ParameterError(msg, where=f"render.sensor.{name}")
        for name, allowed in (("scan", SCANS), ("field_order", FIELD_ORDERS),
                              ("chroma", CHROMAS)):
            if getattr(self, name) not in allowed:
                bad(name, f"{getattr(self, name)!r} is not one of {list(allowed)}")
        period = 1.0 / fps / (2 if self.interlaced else 1)
        if not (np.isfinite(self.readout_s) and 0 <= self.readout_s <= period):
            bad("readout_s", f"must be in [0, {period:.4g}] s (one frame or field period), "
                f"got {self.readout_s!r}")
        if not (np.isfinite(self.frame_jitter_s) and 0 <= self.frame_jitter_s <= 0.2 / fps):
            bad("frame_jitter_s", f"must be in [0, 0.2 / fps], got {self.frame_jitter_s!r}")
        if not 0 <= self.drop_rate <= 0.5:
            bad("drop_rate", f"must be in [0, 0.5], got {self.drop_rate!r}")
        for name in ("auto_exposure", "white_balance"):
            if not 0 <= getattr(self, name) <= 0.5:
                bad(name, f"must be in [0, 0.5], got {getattr(self, name)!r}")
        if not 0.01 <= self.ae_lag_s <= 10:
            bad("ae_lag_s", f"must be in [0.01, 10] s, got {self.ae_lag_s!r}")


@dataclass(frozen=True)
class Exposures:
    """Every exposure of a video: ``frame`` (index in the file), ``field`` (0/1, or 0
    for progressive video), ``t`` (reference time, s) and ``frame_t`` (each frame's
    capture time = its container timestamp, s); ``period`` is the exposure slot (s)."""

    frame: np.ndarray
    field: np.ndarray
    t: np.ndarray
    frame_t: np.ndarray
    period: float


def schedule(cfg: SensorConfig, fps: float, duration: float,
             rng: np.random.Generator) -> Exposures:
    """The capture times of a recording covering ``[0, duration]`` s.

    Nominal slots ``k / fps`` (frame 0 at t = 0 is always kept), moved by the timing
    jitter and thinned by dropped frames; every time is rounded to the container's
    ``1 / TIME_BASE`` s ticks so that the written timestamps are the truth exactly.
    """
    n = int(np.floor(duration * fps + 1e-9)) + 1
    t = np.arange(n) / fps
    if cfg.frame_jitter_s > 0:
        t[1:] += np.clip(rng.normal(0, cfg.frame_jitter_s, n - 1), -0.3 / fps, 0.3 / fps)
    keep = np.ones(n, bool)
    if cfg.drop_rate > 0:
        keep[1:] = rng.uniform(size=n - 1) >= cfg.drop_rate
    if cfg.frame_jitter_s > 0 or cfg.drop_rate > 0:
        t = np.round(t * TIME_BASE) / TIME_BASE
    t = t[keep]
    nf = len(t)
    if not cfg.interlaced:
        return Exposures(np.arange(nf), np.zeros(nf, int), t.copy(), t, 1.0 / fps)
    half = 0.5 / fps
    return Exposures(np.repeat(np.arange(nf), 2), np.tile([0, 1], nf),
                     (t[:, None] + [0.0, half]).ravel(), t, half)


def field_rows(cfg: SensorConfig, field: int) -> slice:
    """The rows of field ``field`` (0 = exposed first) as a slice."""
    first_odd = cfg.field_order == "bff"
    return slice(1 if first_odd == (field == 0) else 0, None, 2)


def row_time_offset(readout_s: float, height: int, v) -> np.ndarray:
    """Rolling shutter: mid-exposure time of sensor row(s) ``v`` (px, may be fractional)
    minus the frame's (or field's) reference time, s."""
    return readout_s * ((np.asarray(v, dtype=float) + 0.5) / height - 0.5)


def subsample_chroma(img: np.ndarray, chroma: str, interlaced: bool = False) -> np.ndarray:
    """Record ``img`` (BGR uint8) with reduced colour resolution, as the camera does.

    Luma is kept; Cr and Cb are averaged over 2 (4:2:2) or 4 (4:1:1) pixels across and,
    for 4:2:0, 2 rows down (rows of the same field when interlaced), then interpolated
    back to full resolution as a decoder does.
    """
    if chroma == "444":
        return img
    ycc = cv2.cvtColor(img, cv2.COLOR_BGR2YCrCb)
    H, W = img.shape[:2]
    fx = {"422": 2, "420": 2, "411": 4}[chroma]
    fy = 2 if chroma == "420" else 1
    c = ycc[..., 1:].astype(np.float32)
    parts = [c[0::2], c[1::2]] if (interlaced and fy > 1) else [c]
    out = []
    for p in parts:
        h = p.shape[0]
        small = cv2.resize(p, (-(-W // fx), -(-h // fy)), interpolation=cv2.INTER_AREA)
        out.append(cv2.resize(small, (W, h), interpolation=cv2.INTER_LINEAR))
    if len(out) == 2:
        c[0::2], c[1::2] = out
    else:
        c = out[0]
    ycc[..., 1:] = np.clip(np.rint(c), 0, 255).astype(np.uint8)
    return cv2.cvtColor(ycc, cv2.COLOR_YCrCb2BGR)


def _lagged_drift(rng, rms: float, lag_s: float, t0: float, t1: float) -> callable:
    """A drifting relative gain (1 + ...), as a function of time: the target jumps now
    and then (the scene's brightness or colour changes: a lamp, a sheet in view) and
    the camera's control loop follows it with a first-order lag ``lag_s``."""
    dt = 1.0 / 240.0
    tg = np.arange(t0 - 5 * lag_s, t1 + 2 * dt, dt)
    n_jumps = max(2, int(np.ceil((tg[-1] - tg[0]) / 1.5)))
    when = np.sort(rng.uniform(tg[0], tg[-1], n_jumps))
    level = rng.normal(0, rms, n_jumps + 1)
    target = level[np.searchsorted(when, tg)]
    a = dt / (lag_s + dt)
    out = np.empty_like(target)
    acc = target[0]
    for i, v in enumerate(target):  # 240 steps/s of a scalar recursion: cheap
        acc += a * (v - acc)
        out[i] = acc
    return lambda t: 1.0 + np.interp(t, tg, out)


class ColourControl:
    """Auto exposure and white balance: per-exposure gains of the B, G, R channels.

    Parameters
    ----------
    cfg : SensorConfig
    t0, t1 : float
        Time span to cover (s).
    rng : numpy.random.Generator
    """

    def __init__(self, cfg: SensorConfig, t0: float, t1: float, rng: np.random.Generator):
        self.on = cfg.auto_exposure > 0 or cfg.white_balance > 0
        self._ae = _lagged_drift(rng, cfg.auto_exposure, cfg.ae_lag_s, t0, t1)
        self._wb = [_lagged_drift(rng, cfg.white_balance, cfg.ae_lag_s, t0, t1)
                    for _ in range(2)]

    def gains(self, t) -> np.ndarray:
        """(N, 3) multipliers of B, G, R at times ``t`` (s): exposure x white balance."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        g = self._ae(t)
        return np.column_stack([g * self._wb[1](t), g, g * self._wb[0](t)])
