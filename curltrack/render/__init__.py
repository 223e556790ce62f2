"""Synthetic overhead video of a shot, with its ground truth (``curltrack render``).

Pipeline: :mod:`~.trajectory` (the series placed on the ice; the truth frame) ->
:mod:`~.motion` (how the camera is held) -> :mod:`~.ice` and :mod:`~.sprites` (ice and
threads; rock and broom; pre-rendered once) -> :mod:`~.compositor` (per-frame warps,
blur, distortion, noise; rolling shutter) -> :mod:`~.sensor` (fields, frame timing,
chroma, auto exposure) -> :mod:`~.production` (one rendering set up, frames streamed) ->
:mod:`~.video` (the mp4 and the truth files, through :mod:`~.encode`: codecs, bitrate,
tags).  Pixel and world conventions: :mod:`curltrack.render.camera`.
"""

from .camera import Camera
from .config import RenderConfig
from .encode import EncodingConfig
from .sensor import SensorConfig
from .motion import CameraConfig, CameraPath
from .production import FrameInfo, Production
from .ice import IceStyle
from .video import render_video
from .benchmark import render_benchmark

__all__ = ["Camera", "CameraConfig", "CameraPath", "EncodingConfig", "FrameInfo", "IceStyle",
           "Production", "RenderConfig", "SensorConfig", "render_benchmark", "render_video"]
