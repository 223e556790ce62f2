"""Rendering speed, for ``scripts/bench.py``: frames/s against plain encoding, one core."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import cv2
import numpy as np
import pandas as pd

from ..physics.closed_form import curl_position, decel_position
from ..rig import default_rig
from ..series import Series, make_meta
from .config import RenderConfig
from .production import Production
from .encode import open_writer


def _draw(duration_s: float, fps: float) -> Series:
    """The paper's draw (y_F = 26 m, lambda_y = 1.897, t_F = 25 s), its first seconds."""
    t = np.arange(int(duration_s * fps) + 1) / fps
    y = decel_position(t, 26.0, 1.897, 25.0)
    x = curl_position(t, -0.005, 1.897, 25.0)
    th = decel_position(t, 12.0, 1.455, 25.0)
    data = pd.DataFrame(dict(frame=np.arange(len(t)), t=t, x=x, y=y, theta=th, ok=1))
    return Series(data, make_meta(fps, len(t)))


def render_benchmark(n_frames: int = 60, config: RenderConfig | None = None,
                     threads: int = 1, seed: int = 0) -> dict:
    """Time the renderer on the fast start of a draw (the hardest part: the camera and the
    rock both move fastest) and plain mp4v encoding of as many frames.

    Parameters
    ----------
    n_frames : int
        Frames to time (default 60 = 2 s of video).
    config : RenderConfig, optional
        Default: 960x540, ladder camera, 5 blur sub-frames, noise, JPEG pass.
    threads : int
        OpenCV threads during the measurement (default 1: one core).

    Returns
    -------
    dict
        ``render_fps`` (rendered and encoded frames/s, wall clock), ``encode_fps``
        (plain encoding of ready frames), ``ratio`` (render_fps / encode_fps),
        ``render_fps_cpu`` and ``encode_fps_cpu`` (the same per second of this process's
        CPU time: what one free core gives on a shared machine), ``setup_s`` (scene
        preparation, s), ``n_frames``, ``width``, ``height``, ``blur_subframes``.
    """
    cfg = config or RenderConfig()
    shot = _draw((n_frames + 1) / 30.0, 30.0)
    old = cv2.getNumThreads()
    cv2.setNumThreads(threads)
    try:
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            prod = Production(shot, default_rig(), cfg, seed)
            prod._scene()
            setup = time.perf_counter() - t0
            writer = open_writer(Path(tmp) / "render.mp4", prod.fps, (cfg.width, cfg.height))
            t0, c0 = time.perf_counter(), time.process_time()
            frames = []
            for img, info in prod.frames(0, n_frames):
                writer.write(img)
                if info.index % max(n_frames // 8, 1) == 0:
                    frames.append(img)
            render_s, render_cpu = time.perf_counter() - t0, time.process_time() - c0
            writer.close()
            writer = open_writer(Path(tmp) / "plain.mp4", prod.fps, (cfg.width, cfg.height))
            t0, c0 = time.perf_counter(), time.process_time()
            for k in range(n_frames):
                writer.write(frames[k % len(frames)])
            encode_s, encode_cpu = time.perf_counter() - t0, time.process_time() - c0
            writer.close()
    finally:
        cv2.setNumThreads(old)
    render_fps, encode_fps = n_frames / render_s, n_frames / encode_s
    return dict(render_fps=render_fps, encode_fps=encode_fps, ratio=render_fps / encode_fps,
                render_fps_cpu=n_frames / render_cpu, encode_fps_cpu=n_frames / encode_cpu,
                setup_s=setup, n_frames=n_frames, width=cfg.width, height=cfg.height,
                blur_subframes=cfg.blur_subframes)
