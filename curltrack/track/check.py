"""Frames judged by ``track``'s own loop: the verdicts ``doctor`` and ``calibrate`` give.

``track`` follows the markers and the grid from frame to frame: whether a frame is
measured depends on the frames before it (where the markers were predicted, the frame
the grid was first calibrated on - a calibration from scratch fails on many frames of a
moving camera that ``track`` follows -, the cell index carried).  So that ``doctor`` and
``calibrate`` say of a frame exactly what ``track`` says, they do not re-implement its
steps: they run its per-frame loop (:func:`.pipeline.track_frames`, with the rig's
:class:`~curltrack.settings.TrackingSettings`) from the video's start to the last
frame judged - at about the cost of decoding those frames (``track`` costs ~0.3x the
decode) - and read its verdict on each judged frame.

What the loop cannot show is left to ``track``'s whole-series checks: a poor fit against
the typical residual of the shot, a frame whose sigma is an outlier, a marker layout
unlike the rest of the video, the scale check.  A frame refused here is ``ok`` = 0 in
``track``'s output for the same reason; one accepted here is measured by ``track``
unless one of those says no.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..errors import TrackingError
from ..rig import Rig

__all__ = ["FrameVerdict", "check_frames", "frame_reader"]

@dataclass(frozen=True)
class FrameVerdict:
    """What ``track`` makes of one frame.

    Attributes
    ----------
    frame : int
    status : str
        "" when the frame is measured, else why not (``track``'s words).
    grid_status : str
        "" when the grid was measured on the frame, else why not (the grid is followed
        also when the markers are not found, as ``track`` follows it).
    markers_found : tuple of bool
        Per rig marker.
    markers_px : (M, 2) array or None
        Observed marker positions (px) when all were found.
    calibration : Calibration or None
        The grid on this frame (lens and thread colours from ``calibrated_on``); None
        when the grid was not measured.
    calibrated_on : int or None
        The frame the lens and thread colours were calibrated on.
    """

    frame: int
    status: str
    grid_status: str = ""
    markers_found: tuple = ()
    markers_px: np.ndarray | None = None
    calibration: object = None
    calibrated_on: int | None = None

    @property
    def ok(self) -> bool:
        return self.status == ""


def frame_reader(path, n_frames: int | None = None, fps_override=None):
    """``read(i)`` -> frame ``i`` of a video (BGR uint8; the last few decoded are kept),
    None outside it; a still image is frame 0.  An interlaced video's frame is its
    first field (resampled to the frame's height), as ``track`` measures it."""
    from pathlib import Path

    from ..video import IMAGE_SUFFIXES, iter_frames, probe_video, read_frame

    if Path(path).suffix.lower() in IMAGE_SUFFIXES:
        image = read_frame(path, 0)
        return lambda i: image if i == 0 else None
    # (read as track measures it: a woven frame of a moving rock is no image to judge)
    info = probe_video(path, fps_override=fps_override, check_end=False)
    if n_frames is None:
        n_frames = info.n_frames
    cache: dict = {}

    def read(i):
        if not 0 <= i < n_frames:
            return None
        if i not in cache:
            for fr in iter_frames(path, start=int(i), end=int(i) + 1,
                                  fps_override=fps_override, **info.reading):
                cache.setdefault(i, fr.image)
            while len(cache) > 4:  # (bounded memory: doctor reads a few frames twice)
                cache.pop(next(iter(cache)))
        return cache.get(i)

    return read


def _series_rules(records, rig: Rig, video, video_info, loop_info):
    """Give the records the reasons ``track`` finds only over the whole run (a marker
    layout or a sigma far from the video's others, a cell index the path does not fix):
    :func:`curltrack.track.results.build_series` sets them on the records it refuses.
    Its "others" are the frames run, up to the last one judged, where track's are the
    whole video's.  Its errors about the video as a whole are doctor's other checks' to
    report, but one: a video that begins before the release (no other check sees the
    rock's speed) - that :class:`~curltrack.errors.StartFrameError` is returned (else
    None)."""
    from ..errors import CurltrackError, StartFrameError
    from .results import build_series

    try:
        build_series(records, rig, video_info, 0, loop_info, path=video)
    except StartFrameError as exc:
        return exc
    except CurltrackError:
        pass
    return None


def _verdict(rec, calib, calib_frame) -> FrameVerdict:
    found = tuple(rec.markers_found)
    xy = rec.markers_px if found and all(found) else None
    pose = rec.pose
    cal = None
    # (a cell index track does not trust is a refusal of the frame - its status - but
    # the grid itself was measured there: calibrate writes it)
    measured = pose is not None and (pose.ok or pose.message.startswith("cell index"))
    if measured and calib is not None:
        cal = replace(calib, H=pose.H, spacing_px=pose.spacing_px,
                      residual_px=pose.residual_px)
        if calib_frame != rec.frame:
            cal = replace(cal, notes=list(calib.notes) + [
                f"lens and thread colours calibrated on frame {calib_frame}; the grid "
                f"followed onto frame {rec.frame} as track follows it"])
    grid = "" if measured else (rec.grid_status or rec.status)
    return FrameVerdict(rec.frame, rec.status, grid, found, xy, cal,
                        calib_frame if cal is not None else None)


def _past(frames, end: int):
    """``frames``, ending quietly where decoding fails at or after frame ``end`` (the
    window read past the judged frames: a count a frame or two long, as variable frame
    rates announce, is not the judged frames' error)."""
    from ..errors import VideoError

    last = -1
    try:
        for fr in frames:
            last = fr.index
            yield fr
    except VideoError:
        if last < end - 1:
            raise


def check_frames(video, frames, rig: Rig, fps_override=None,
                 progress=None, problems: list | None = None) -> list[FrameVerdict]:
    """Judge frames as ``track`` does, by running its loop from the video's start to the
    last of them.

    Parameters
    ----------
    video : path
        The video (or a still image: frame 0, judged alone).
    frames : iterable of int
        Frames to judge.
    rig : Rig
        Grid, markers and ``rig.tracking`` (the thresholds).
    fps_override : float, optional
        The rig's ``[camera].fps``.
    progress : callable, optional
        Called with 1 per frame run over.
    problems : list, optional
        Appended to: what ``track`` would refuse the run for that no frame's verdict
        says (a :class:`~curltrack.errors.StartFrameError`: the video begins before
        the release).

    Returns
    -------
    list of FrameVerdict
        In the order of ``frames``.

    Raises
    ------
    TrackingError
        A frame outside the video.
    """
    from pathlib import Path

    from ..video import IMAGE_SUFFIXES, Frame, iter_frames, probe_video, read_frame
    from .pipeline import track_frames

    wanted = [int(k) for k in frames]
    if Path(video).suffix.lower() in IMAGE_SUFFIXES:
        bad = [k for k in wanted if k != 0]
        if bad:
            raise TrackingError("frame outside the image (a still is frame 0)",
                                path=video, where=f"frame {bad[0]}")
        runs = [iter([Frame(0, 0.0, read_frame(video, 0))])]
        video_info = None
    else:
        # one run from the video's start: track's verdict on a frame rests on every
        # frame before it (the first calibration, the markers' prediction, the cell index)
        # and on the rock's path for a window after it (a cell index re-anchored across
        # a loss: :mod:`.segments`)
        video_info = probe_video(video, fps_override=fps_override, check_end=False)
        after = int(np.ceil(rig.tracking.segment_window_s * video_info.fps)) + 1
        end = max(wanted, default=-1) + 1
        runs = [_past(iter_frames(video, start=0, end=min(end + after, video_info.n_frames),
                                  fps_override=fps_override, **video_info.reading), end)]
    out = {}
    for frames_run in runs:
        records, info = track_frames(frames_run, rig, path=video, progress=progress,
                                     outline_every=1 << 30, strict=False)
        if video_info is not None:
            late = _series_rules(records, rig, video, video_info, info)
            if late is not None and problems is not None:
                problems.append(late)
        for rec in records:
            # (an interlaced frame: its first field's verdict)
            if rec.frame in wanted and rec.frame not in out:
                out[rec.frame] = _verdict(rec, info["calib"], info["calib_frame"])
    missing = [k for k in wanted if k not in out]
    if missing:
        raise TrackingError("frame outside the video", path=video,
                            where=f"frame {missing[0]}")
    return [out[k] for k in wanted]
