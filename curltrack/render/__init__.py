"""Synthetic overhead video of a shot, with its ground truth (``curltrack render``).

Pipeline: :mod:`trajectory` (series placed on the ice, truth frame) ->
:mod:`motion` (how the camera is held) -> :mod:`scene` (ice, threads, rock, broom,
pre-rendered once) -> :mod:`compositor` (per-frame warps, blur, distortion, noise) ->
:mod:`video` (the loop, the writer, the truth).  Pixel and world conventions are in
:mod:`curltrack.render.camera`.
"""

from .camera import Camera
from .motion import CameraConfig, CameraPath
from .scene import IceStyle
from .video import RenderConfig, render_video

__all__ = ["Camera", "CameraConfig", "CameraPath", "IceStyle", "RenderConfig", "render_video"]
