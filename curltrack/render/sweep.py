"""A seeded random "camera sweep": set-ups drawn from the cameras people film curling with
(camcorder, phone, action camera, ladder rig, handheld) and their artefacts, on or off at
random - the tracker's proving ground (``scripts/sweep_cameras.py``).

Camera kinds (each artefact's range from what such cameras do):

``camcorder``
    NTSC DV: 720x480 at 29.97 fps, two interlaced fields (bottom first), 10:11 pixels,
    4:1:1 colour, H.264 flagged interlaced at 0.8-2 Mbit/s, a CCD (global shutter),
    mild barrel distortion; on a ladder, a pole or handheld.
``phone``
    1920x1080 at 30 or 60 fps, rolling shutter (readout 40-90 % of the frame period, up
    to 30 ms), variable frame timing with dropped frames, often a 90 deg rotation tag,
    auto exposure and white balance drifting, H.264 8-20 Mbit/s; handheld or on a pole.
``action``
    1920x1080 at 30/60 fps, wide-angle lens (k1 -0.35..-0.2 with k2, off-centre principal
    point) or a fisheye, rolling shutter 5-15 ms, H.264 or HEVC; on a pole or handheld.
``ladder``
    The paper's rig (the renderer's defaults, 960x540 at 30 fps).
``handheld``
    A consumer camera held over the rock, 1280x720 at 30 fps, H.264.
``camcorder-pal``
    PAL: 720x576 at 25 fps, two interlaced fields (bottom first as DV records them, or
    top first as HDV and broadcast), 59:54 pixels (4:3) or 118:81 (16:9), 4:2:0 colour
    shared by the fields as a transcode leaves it (each colour row both fields' mean, or
    the top field's line alone) or each field's own as the camera's file, H.264 at
    1.5-4 Mbit/s; on a ladder, a pole or handheld.
``camcorder-dv``
    The camcorder's own file, as a DV camera's footage is captured (the paper's "small
    digital video camera"): DV25 in a QuickTime file, NTSC (720x480, 29.97 fps, 4:1:1:
    every line its own colour) or PAL (720x576, 25 fps, 4:2:0 per field), interlaced
    bottom field first, 25 Mbit/s intra-frame, the file's pixel aspect DV's own (8:9,
    16:15) whatever the camera's; on a ladder, a pole or handheld.  No low bitrate.

On top, each at random: specular lamp glare, a person's shadow, a broom over the rock,
auto exposure / white balance, a low bitrate (a quarter of the kind's).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd

from ..errors import ParameterError
from ..physics.closed_form import curl_position, decel_position
from ..series import Series, make_meta
from .camera import Camera
from .config import RenderConfig
from .encode import EncodingConfig
from .motion import CameraConfig
from .sensor import SensorConfig

KINDS = ("camcorder", "phone", "action", "ladder", "handheld", "camcorder-pal", "camcorder-dv")


@dataclass
class Setup:
    """One drawn set-up: its ``kind``, the render ``config``, the ``shot`` (a series in
    the SHOT.csv frame), the render ``seed`` and a flat ``summary`` of the choices."""

    kind: str
    config: RenderConfig
    shot: Series
    seed: int
    summary: dict = field(default_factory=dict)

    @property
    def suffix(self) -> str:
        """The video file's extension: ``.mov`` for DV (QuickTime), else ``.mp4``."""
        return ".mov" if self.config.encoding.codec == "dv" else ".mp4"


def draw_shot(rng: np.random.Generator, fps: float = 240.0) -> Series:
    """The last seconds of a draw from the paper's closed forms: y_F 1.5-3.5 m, t_F
    2.5-4.5 s, a spin of 1-5 rad to its stop either way, a curl of 2-8 cm/s^2."""
    t_F = rng.uniform(2.5, 4.5)
    lam = rng.uniform(1.5, 2.0)
    theta_F = rng.choice([-1, 1]) * rng.uniform(1.0, 5.0)
    t_Ft = t_F * rng.uniform(0.9, 1.1)
    a_T = -np.sign(theta_F) * rng.uniform(0.02, 0.08)
    t = np.arange(int(np.ceil(max(t_F, t_Ft) * fps)) + 2) / fps  # past both stops
    y = decel_position(t, rng.uniform(1.5, 3.5), lam, t_F)
    x = curl_position(t, a_T, lam, t_F)
    th = decel_position(t, theta_F, rng.uniform(1.3, 1.7), t_Ft)
    data = pd.DataFrame(dict(frame=np.arange(len(t)), t=t, x=x, y=y, theta=th, ok=1))
    return Series(data, make_meta(fps, len(t), t_stop_translation=t_F,
                                  t_stop_rotation=t_Ft))


def draw_model_shot(rng: np.random.Generator, fps: float = 240.0) -> Series:
    """A draw of the physics core's own model (:class:`~curltrack.physics.ShotModel`,
    integrated by :func:`~curltrack.simulate.simulate_series`) that stops in ~2.5-5 s:
    v0 1-2.2 m/s, phi_y -0.6..0 with 4-8x the paper's draw's alpha_y, a spin of 1-3
    rad/s either way that stops with the slide, a curl 2-6x the draw's a_T.

    :func:`draw_shot`'s closed forms (independent stops for the slide and the spin, a
    constant curl to the end) are a tracker's test; they are not the world ``discover``
    models (its curl ends with the spin), so a tracked clip of theirs is no clean shot
    for ``discover``.  This one is: what ``discover`` says of it is a false alarm unless
    it is ``none`` (``scripts/sweep_cameras.py --physics model --discover``).
    """
    from ..physics.shot import A_T_DRAW, ALPHA_Y_DRAW, ShotModel
    from ..simulate import simulate_series

    model = ShotModel(v0=rng.uniform(1.0, 2.2),
                      omega0=rng.choice([-1.0, 1.0]) * rng.uniform(1.0, 3.0),
                      phi_y=rng.uniform(-0.6, 0.0), alpha_y=ALPHA_Y_DRAW * rng.uniform(4, 8),
                      a_T=A_T_DRAW * rng.uniform(2, 6))
    return simulate_series(model, fps=fps)


def _lens_ok(cfg: CameraConfig, W: int, H: int) -> bool:
    """Whether the lens maps the whole image monotonically (no fold-over)."""
    r = cfg.resolved()
    f = H * r.height_m / r.view_m
    cam = Camera(f, (W - 1) / 2 + r.principal_offset_px[0], (H - 1) / 2
                 + r.principal_offset_px[1], W, H, k1=r.k1, k2=r.k2, lens=r.lens)
    corners = np.array([[0, 0], [W - 1, 0], [0, H - 1], [W - 1, H - 1.0]])
    try:
        cam.undistort(cam.to_normalized(corners))
    except ParameterError:
        return False
    return True


def _size(w: int, h: int, scale: float) -> dict:
    return dict(width=int(round(w * scale / 2)) * 2, height=int(round(h * scale / 2)) * 2)


def draw_setup(rng: np.random.Generator, kind: str | None = None,
               scale: float = 1.0) -> Setup:
    """Draw one set-up (every choice from ``rng``).

    Parameters
    ----------
    rng : numpy.random.Generator
    kind : str, optional
        One of :data:`KINDS`; default drawn at random.
    scale : float
        Image size factor for phones, action cameras and handhelds (e.g. 0.5 renders
        "1080p" at 960x540 to save time; the artefacts scale with it); the camcorder stays
        720x480 and the ladder 960x540.
    """
    kind = str(rng.choice(KINDS)) if kind is None else kind
    u = rng.uniform
    on = {}
    if kind == "camcorder":
        motion = str(rng.choice(["ladder", "pole", "handheld"]))
        cam = CameraConfig(motion=motion, pixel_aspect=10 / 11, k1=u(-0.08, -0.02))
        base = dict(width=720, height=480, fps=30000 / 1001, camera=cam,
                    sensor=SensorConfig(scan="interlaced", field_order="bff", chroma="411"))
        bitrate = u(0.8e6, 2.0e6)
        codec = "h264"
    elif kind == "camcorder-pal":
        motion = str(rng.choice(["ladder", "pole", "handheld"]))
        aspect = 59 / 54 if u() < 0.7 else 118 / 81
        cam = CameraConfig(motion=motion, pixel_aspect=aspect, k1=u(-0.08, -0.02))
        order = "bff" if u() < 0.5 else "tff"
        base = dict(width=720, height=576, fps=25.0, camera=cam,
                    sensor=SensorConfig(scan="interlaced", field_order=order, chroma="420"))
        bitrate = u(1.5e6, 4.0e6)
        codec = "h264"
        on["field_colour"] = str(rng.choice(["shared", "top", "own"]))
    elif kind == "camcorder-dv":
        motion = str(rng.choice(["ladder", "pole", "handheld"]))
        pal = u() < 0.5
        cam = CameraConfig(motion=motion, pixel_aspect=59 / 54 if pal else 10 / 11,
                           k1=u(-0.08, -0.02))
        base = dict(width=720, height=576 if pal else 480, fps=25.0 if pal else 30000 / 1001,
                    camera=cam, sensor=SensorConfig(scan="interlaced", field_order="bff",
                                                    chroma="420" if pal else "411"))
        bitrate, codec = None, "dv"
    elif kind == "phone":
        fps = float(rng.choice([30.0, 60.0]))
        motion = str(rng.choice(["handheld", "pole"]))
        cam = CameraConfig(motion=motion, k1=u(-0.06, 0.0), view_m=u(1.6, 2.4))
        sen = SensorConfig(readout_s=min(0.03, u(0.4, 0.9) / fps),
                           frame_jitter_s=u(2e-4, 2e-3), drop_rate=u(0.0, 0.05),
                           chroma="420")
        base = dict(**_size(1920, 1080, scale), fps=fps, camera=cam, sensor=sen)
        bitrate = u(8e6, 20e6) * scale ** 2
        codec = "h264"
        on["rotation"] = int(rng.choice([0, 90, 90, 270]))
    elif kind == "action":
        fps = float(rng.choice([30.0, 60.0]))
        motion = str(rng.choice(["pole", "handheld"]))
        fisheye = u() < 0.3
        W, H = _size(1920, 1080, scale).values()
        off = tuple(u(-1, 1, 2) * 0.03 * np.array([W, H]))
        for _ in range(50):  # a lens that does not fold over inside the image
            if fisheye:
                cam = CameraConfig(motion=motion, lens="fisheye", k1=u(-0.03, 0.03), k2=0.0,
                                   view_m=u(1.6, 2.4), principal_offset_px=off)
            else:
                cam = CameraConfig(motion=motion, k1=u(-0.35, -0.2), k2=u(0.02, 0.08),
                                   view_m=u(1.2, 1.8), principal_offset_px=off)
            if _lens_ok(cam, W, H):
                break
        sen = SensorConfig(readout_s=min(u(0.005, 0.015), 0.9 / fps), chroma="420")
        base = dict(width=W, height=H, fps=fps, camera=cam, sensor=sen)
        bitrate = u(10e6, 30e6) * scale ** 2
        codec = str(rng.choice(["h264", "hevc"]))
    elif kind == "ladder":
        base = dict(fps=30.0, camera=CameraConfig(motion="ladder"))
        bitrate, codec = u(3e6, 6e6), "h264"
    elif kind == "handheld":
        base = dict(**_size(1280, 720, scale), fps=30.0, camera=CameraConfig(motion="handheld"),
                    sensor=SensorConfig(chroma="420"))
        bitrate, codec = u(4e6, 10e6) * scale ** 2, "h264"
    else:
        raise ValueError(f"unknown camera kind {kind!r}; expected one of {list(KINDS)}")
    sen = base.pop("sensor", SensorConfig())
    if u() < 0.4:
        sen = replace(sen, auto_exposure=u(0.03, 0.12), white_balance=u(0.02, 0.08))
        on["auto_exposure"] = True
    if u() < 0.3 and bitrate is not None:
        bitrate /= 4
        on["low_bitrate"] = True
    extra = {}
    if u() < 0.3:
        extra.update(glare=u(80, 180), glare_spread_rad=u(0.03, 0.06))
        on["glare"] = True
    if u() < 0.3:
        extra["shadow"] = u(0.2, 0.5)
        on["shadow"] = True
    if u() < 0.3:
        extra["occlusion"] = True
        on["broom"] = True
    enc = EncodingConfig(codec=codec, bitrate_bps=bitrate, rotation_deg=on.get("rotation", 0),
                         field_colour=on.pop("field_colour", "shared"))
    cfg = RenderConfig(**base, **extra, sensor=sen, encoding=enc, stopped_tail_s=0.7)
    cam = cfg.camera
    summary = dict(kind=kind, size=f"{cfg.width}x{cfg.height}",
                   fps=round(cfg.fps or 30.0, 3), motion=cam.motion,
                   lens=f"{cam.lens} k1={cam.k1:.2f} k2={cam.k2:.2f}",
                   scan=sen.scan, readout_ms=round(1e3 * sen.readout_s, 1),
                   vfr=sen.frame_jitter_s > 0,
                   codec=(f"{codec} {bitrate / 1e6:.2g} Mb/s" if bitrate else f"{codec} 25 Mb/s")
                   + ("" if sen.scan != "interlaced" or codec == "dv"
                      else f", {enc.field_colour} colour"),
                   artefacts=",".join(k for k, v in on.items() if v) or "-")
    return Setup(kind, cfg, draw_shot(rng), int(rng.integers(2**31)), summary)
