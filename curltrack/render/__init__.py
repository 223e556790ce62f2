"""Synthetic overhead video of a shot, with its ground truth (``curltrack render``).

Pipeline: :mod:`~.trajectory` (the series placed on the ice; the truth frame) ->
:mod:`~.motion` (how the camera is held) -> :mod:`~.ice` and :mod:`~.sprites` (ice and
threads; rock and broom; pre-rendered once) -> :mod:`~.compositor` (per-frame warps,
blur, distortion, noise) ->
:mod:`~.production` (one rendering set up, frames streamed) -> :mod:`~.video` (the mp4
and the truth files).  Pixel and world conventions: :mod:`curltrack.render.camera`.
"""

from .camera import Camera
from .config import RenderConfig
from .motion import CameraConfig, CameraPath
from .production import FrameInfo, Production
from .ice import IceStyle
from .video import render_video
from .benchmark import render_benchmark

__all__ = ["Camera", "CameraConfig", "CameraPath", "FrameInfo", "IceStyle", "Production",
           "RenderConfig", "render_benchmark", "render_video"]
