"""Render settings: every property of a rendering, with its documented default."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import ParameterError, RigError
from ..rig import parse_color
from .encode import EncodingConfig
from .motion import CameraConfig
from .ice import IceStyle
from .sensor import SensorConfig


@dataclass(frozen=True)
class RenderConfig:
    """Everything about a rendering except the shot and the rig (documented defaults).

    Parameters
    ----------
    width, height : int
        Image size (px), default 960 x 540.
    fps : float, optional
        Frame rate (frames/s); default the rig's ``[camera].fps``, else the series'
        sidecar ``fps``, else 30.
    camera : CameraConfig
        The camera and how it is held (default: ladder at 2.0 m).
    heading_deg : float, optional
        Direction of travel relative to the grid's +Y axis, counter-clockwise (deg);
        default: random in +-2.5 deg (the paper's skews were < 2.5 deg).
    lattice_phase : (float, float), optional
        Rock start's position within a lattice cell, as fractions of the spacings;
        default: random in [0.15, 0.85] (never on a thread).
    blur_subframes : int
        Sub-frames averaged per frame (motion blur), default 5; 1 = no blur.
    shutter : float
        Exposure time as a fraction of the frame period, default 0.5.
    read_noise, shot_noise_gain : float
        Sensor noise per photosite: sigma^2 = read_noise^2 + shot_noise_gain * I (0-255
        levels), defaults 2.0 and 0.08.
    vignetting : float
        Brightness loss in the image corners, default 0.25.
    jpeg_quality : int, optional
        Extra per-frame JPEG compression before the mp4v encoder (blocking and ringing
        as in consumer video), default 85; None = only the mp4v encoder.
    optics_blur_px : float
        Lens and sensor softness: Gaussian sigma (px), baked into the ice and the rock,
        default 0.6.
    glare : float
        Peak brightness (0-255 levels) of the lamps' diffuse reflections in the ice,
        which slide against the lattice as the camera moves; default 10; 0 = off.  A
        specular glare: 80-200 with ``glare_spread_rad`` 0.03-0.06.
    lamp_height_m, glare_spread_rad : float
        Height of the lamps above the ice (m), default 6; angular spread of their
        reflection by the pebbled surface (rad), default 0.12.
    flicker : float
        Relative RMS of the frame-to-frame brightness (lamp flicker beating with the
        frame rate, auto exposure), default 0.01.
    demosaic : bool
        Colour sensor: Bayer mosaic, noise per photosite, bilinear demosaicing (colour
        fringes on thin threads and small markers), default True.
    occlusion : bool
        A broom head crosses the view above the rock, default False.
    occlusion_t_s : float, optional
        When the broom passes over the rock (s); default 40 % of the motion.
    occlusion_speed_m_s : float
        Broom speed across the view (m/s), default 1.2.
    shadow : float
        Depth of a person's soft shadow walking beside the rock (fraction of the light
        it takes, 0-0.9), default 0 = none.
    shadow_size_m : float
        Length of that shadow on the ice (m), default 0.9 (its width is half of it).
    stopped_tail_s : float
        The video ends at least this long after the rock's last stop (s), default 1.0;
        frames are appended when the series' own rest is shorter (only when it stopped).
    marker_diameter_m : float
        Diameter of the marker discs (m), default 0.025.
    ice : IceStyle
        Ice, pebble and thread look.
    texture_oversample : float
        Ice texture resolution relative to the image's px/m, default 1.3.
    sensor : SensorConfig
        Interlaced fields, rolling shutter, chroma subsampling, frame timing, auto
        exposure and white balance (default: none of them).
    encoding : EncodingConfig
        Codec, bitrate, rotation tag (default: OpenCV's mp4v).
    """

    width: int = 960
    height: int = 540
    fps: float | None = None
    camera: CameraConfig = field(default_factory=CameraConfig)
    heading_deg: float | None = None
    lattice_phase: tuple[float, float] | None = None
    blur_subframes: int = 5
    shutter: float = 0.5
    read_noise: float = 2.0
    shot_noise_gain: float = 0.08
    vignetting: float = 0.25
    jpeg_quality: int | None = 85
    optics_blur_px: float = 0.6
    glare: float = 10.0
    lamp_height_m: float = 6.0
    glare_spread_rad: float = 0.12
    flicker: float = 0.01
    demosaic: bool = True
    occlusion: bool = False
    occlusion_t_s: float | None = None
    occlusion_speed_m_s: float = 1.2
    shadow: float = 0.0
    shadow_size_m: float = 0.9
    stopped_tail_s: float = 1.0
    marker_diameter_m: float = 0.025
    ice: IceStyle = field(default_factory=IceStyle)
    texture_oversample: float = 1.3
    sensor: SensorConfig = field(default_factory=SensorConfig)
    encoding: EncodingConfig = field(default_factory=EncodingConfig)

    def validate(self) -> None:
        """Raise ParameterError naming the first bad field."""
        def bad(name, msg):
            raise ParameterError(msg, where=f"render.{name}")
        if not (64 <= self.width <= 8192 and 64 <= self.height <= 8192):
            bad("width", f"image size {self.width}x{self.height} outside 64..8192 px")
        if self.fps is not None and not (np.isfinite(self.fps) and self.fps > 0):
            bad("fps", f"fps must be > 0, got {self.fps!r}")
        if not 1 <= int(self.blur_subframes) <= 64:
            bad("blur_subframes", f"must be 1..64, got {self.blur_subframes!r}")
        if not 0.0 <= self.shutter <= 1.0:
            bad("shutter", f"must be in [0, 1], got {self.shutter!r}")
        for name in ("read_noise", "shot_noise_gain", "stopped_tail_s", "glare",
                     "optics_blur_px", "flicker"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                bad(name, f"must be >= 0, got {v!r}")
        if not 0.0 <= self.vignetting < 1.0:
            bad("vignetting", f"must be in [0, 1), got {self.vignetting!r}")
        if self.jpeg_quality is not None and not 1 <= self.jpeg_quality <= 100:
            bad("jpeg_quality", f"must be 1..100, got {self.jpeg_quality!r}")
        if not 0.005 <= self.marker_diameter_m <= 0.1:
            bad("marker_diameter_m", f"must be 0.005..0.1 m, got {self.marker_diameter_m!r}")
        if self.lattice_phase is not None and not all(0 <= p < 1 for p in self.lattice_phase):
            bad("lattice_phase", "fractions must be in [0, 1)")
        if not 0.5 <= self.texture_oversample <= 4:
            bad("texture_oversample", "must be 0.5..4")
        if not (0 <= self.optics_blur_px <= 5 and 0 <= self.flicker <= 0.5):
            bad("optics_blur_px", "optics_blur_px must be 0..5 px and flicker 0..0.5")
        if not (1.0 <= self.lamp_height_m <= 50 and 0.01 <= self.glare_spread_rad <= 1):
            bad("lamp_height_m", "lamp_height_m must be 1..50 m, glare_spread_rad 0.01..1")
        if not (0 <= self.shadow <= 0.9 and 0.1 <= self.shadow_size_m <= 5):
            bad("shadow", "shadow must be in [0, 0.9] and shadow_size_m in [0.1, 5] m")
        if self.occlusion_speed_m_s <= 0:
            bad("occlusion_speed_m_s", "must be > 0")
        self.encoding.validate()
        sen = self.sensor
        if self.encoding.codec == "mp4v" and (sen.frame_jitter_s > 0 or sen.drop_rate > 0):
            bad("encoding", "irregular frame times need a PyAV codec (mpeg4, h264, hevc), "
                "not OpenCV's mp4v")
        try:
            parse_color(self.ice.ice_color, where="render.ice.ice_color")
        except RigError as exc:
            raise ParameterError(exc.message, where=exc.where) from None
