"""``render_video``: a series + a rig -> an overhead mp4 and its ground truth.

Frame k of the video is exposed around t_k = k / fps after release (frame 0 = the
series' first row); the truth series gives, for every frame, the rock's true centre and
angle in the contract's SHOT.csv frame (origin = rock centre at t = 0, +y = the grid
axis closest to the initial direction of travel, theta against the lattice).
"""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

from .._atomic import atomic_path, verify_video, write_json, write_text
from ..rig import Rig
from ..series import Series, write_series
from .config import RenderConfig
from .encode import open_writer
from .production import Production


def render_video(series: Series, rig: Rig, video_path, truth_path=None,
                 config: RenderConfig | None = None, seed: int = 0,
                 progress: bool = False) -> Series:
    """Render an overhead video of a shot and return (and optionally write) its truth.

    Parameters
    ----------
    series : Series
        The shot in the SHOT.csv frame (``t`` s, ``x``, ``y`` m, ``theta`` rad); rows
        with ``ok`` = 1 are used.  Its sidecar's stop times are copied to the truth.
    rig : Rig
        Grid, rock and markers (and the frame rate / camera height, when given).
    video_path : path
        Output mp4 (written atomically).  Beside it: ``<stem>.rig.toml`` (the rig; no
        frame rate: the container has it) and ``<stem>.render.json`` (every setting and
        random choice).
    truth_path : path, optional
        Where to write the truth series (CSV or Parquet + sidecar JSON).
    config : RenderConfig, optional
    seed : int
        Every random choice (placement, camera path, ice, noise) derives from it.
    progress : bool
        A progress bar on stderr (when it is a terminal).

    Returns
    -------
    Series
        Truth, one row per video frame (per field when interlaced: then a ``field``
        column, 0 = exposed first, and ``t`` = that field's time), ``t`` the frame's
        capture time = its container timestamp (with a rolling shutter: the time of the
        image's centre row): the contract columns plus ``u_px``, ``v_px``
        (rock centre on the ice, in the image, at mid-exposure), ``u_top_px``,
        ``v_top_px`` (rock axis at the marker plane), ``marker<i>_u_px``/``_v_px``,
        ``camera_x_m``, ``camera_y_m`` (lens centre in the truth frame),
        ``camera_height_m``, ``camera_yaw_deg`` (image +u direction, CCW from the truth
        +x), ``in_view`` and ``occluded`` (fraction of the rock's top hidden by the broom);
        with a rolling shutter ``u_drawn_px``, ``v_drawn_px`` (where the centre is drawn:
        its path seen at its own row's time); with auto exposure / white balance
        ``gain_b``, ``gain_g``, ``gain_r``.  Pixel positions are those of the stored
        frames (before any rotation tag).

    Raises
    ------
    ParameterError
        Bad settings, or the rock outside the view for the whole shot.
    VideoError
        The video cannot be written.

    Examples
    --------
    >>> from curltrack import ShotModel, default_rig, render, simulate_series
    >>> truth = render(simulate_series(ShotModel(v0=1.5, omega0=1.5)), default_rig(),
    ...                "shot.mp4", truth_path="truth.csv", seed=7)  # doctest: +SKIP
    """
    from threadpoolctl import threadpool_limits

    # BLAS on one thread, as in track_video: its threads change the order of the sums
    # in the renderer's products and so the frames' last bits, which an encoder turns
    # into different files (a 960x540 H.264 clip: from frame 7 on, up to 31 grey levels
    # apart with OPENBLAS_NUM_THREADS 1 or 2)
    with threadpool_limits(limits=1, user_api="blas"):
        return _render_video(series, rig, video_path, truth_path, config, seed, progress)


def _render_video(series, rig, video_path, truth_path, config, seed, progress) -> Series:
    """:func:`render_video`'s work."""
    prod = Production(series, rig, config or RenderConfig(), seed)
    video_path = Path(video_path)
    with atomic_path(video_path) as tmp:
        sen = prod.sensor
        writer = open_writer(tmp, prod.fps, (prod.cfg.width, prod.cfg.height),
                             prod.cfg.encoding,
                             sen.field_order if sen.interlaced and prod.cfg.encoding.interlace_flags
                             else None,
                             prod.cam_cfg.pixel_aspect)
        written = 0
        from ..progress import progress_bar

        try:
            with progress_bar("render", prod.n_frames,
                              enabled=progress and sys.stderr.isatty()) as advance:
                for img, info in prod.frames():
                    writer.write(img, info.t)
                    written += 1
                    advance()
        finally:
            writer.close()
        verify_video(tmp, written, video_path)
    truth = prod.truth()
    if truth_path is not None:
        write_series(truth_path, truth)
        truth = replace(truth, path=Path(truth_path))
    stem = video_path.with_suffix("")
    # no [camera].fps: time comes from the container (a rig's fps that disagrees with
    # a re-encoded copy of the video would be an error, not a silent override)
    write_text(f"{stem}.rig.toml", replace(rig, fps=None, source=None).to_toml())
    write_json(f"{stem}.render.json", truth.meta["render"])
    return truth
