"""Stream video frames with exact indices and times; check the file up front.

Conventions
-----------
* ``Frame.index`` is the 0-based index of the frame in the file (decode order).
* ``Frame.t`` (s) is the frame's presentation time from the container's timestamps,
  relative to the first frame yielded at index ``start`` (so 29.97 fps and variable
  frame rates are honoured), always.  The rig's ``[camera].fps`` is only used when the
  container gives no frame rate; one that disagrees with the container's by more than
  :data:`FPS_TOLERANCE` is an error, never a silent override.
* ``Frame.image`` is BGR uint8, shape (height, width, 3).

Still images (PNG, JPEG, ...) are accepted by :func:`read_frame` so that ``calibrate``
works on a single photograph.

Frames are decoded one at a time; no function here holds more than one frame.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import VideoError

# FFmpeg's own log lines (e.g. "moov atom not found") must not reach the user's terminal:
# errors are reported once, as a VideoError.  Read when OpenCV first opens a video.
os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")

#: Largest relative difference between the rig's ``[camera].fps`` and the container's
#: frame rate (29.97 vs 30 is 0.1 %); beyond it every time would be scaled wrong.
FPS_TOLERANCE = 0.005

IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp"}


@dataclass(frozen=True)
class VideoInfo:
    """What the container says about a video (checked by :func:`probe_video`).

    Attributes
    ----------
    path : str
    n_frames : int
        Number of frames.
    fps : float
        Frames per second (the override when one was given, else the container's).
    width, height : int
        Frame size (px).
    codec : str
        FourCC code (e.g. ``"avc1"``, ``"FMP4"``).
    duration_s : float
        ``n_frames / fps``.
    """

    path: str
    n_frames: int
    fps: float
    width: int
    height: int
    codec: str
    duration_s: float


@dataclass(frozen=True)
class Frame:
    """One decoded frame: ``index`` (0-based in the file), ``t`` (s), ``image`` (BGR uint8)."""

    index: int
    t: float
    image: np.ndarray


def decoder_threads() -> int:
    """Threads of the video decoder (and of OpenCV in tracking): ``CURLTRACK_THREADS``.

    Default 1 per process, so that batch workers (one process per video) do not fight
    over the cores; set ``CURLTRACK_THREADS=0`` to let OpenCV/FFmpeg choose.
    """
    raw = os.environ.get("CURLTRACK_THREADS", "1").strip() or "1"
    try:
        return max(0, int(raw))
    except ValueError:
        raise VideoError(f"CURLTRACK_THREADS must be a whole number, got {raw!r}",
                         where="environment") from None


def _usable_fps(fps: float) -> bool:
    return bool(np.isfinite(fps) and 0 < fps <= 1000)


def check_rig_fps(container_fps: float, rig_fps: float | None, path=None) -> None:
    """Raise :class:`VideoError` when the rig's fps contradicts the container's.

    Parameters
    ----------
    container_fps : float
        Frames per second announced by the container (ignored when unusable).
    rig_fps : float or None
        The rig's ``[camera].fps``.
    """
    if rig_fps is None or not _usable_fps(container_fps):
        return
    if abs(rig_fps - container_fps) > FPS_TOLERANCE * container_fps:
        raise VideoError(
            f"the rig's fps = {rig_fps:g} disagrees with the video's {container_fps:.4g} "
            f"frames/s (by {abs(rig_fps / container_fps - 1) * 100:.1f} %): every time "
            "would be scaled wrong; remove [camera].fps from the rig (time comes from the "
            "video's timestamps) or check the video", path=path, where="[camera].fps")


def _open(path):
    import cv2

    p = Path(path)
    if not p.exists():
        raise VideoError("no such file", path=p)
    if p.is_dir():
        raise VideoError("is a directory, expected a video file", path=p)
    if p.stat().st_size == 0:
        raise VideoError("file is empty", path=p)
    cap = cv2.VideoCapture(str(p), cv2.CAP_ANY, [cv2.CAP_PROP_N_THREADS, decoder_threads()])
    if not cap.isOpened():
        cap.release()
        raise VideoError("cannot open as a video (unknown format or corrupt container)", path=p)
    return cap


def probe_video(path, fps_override: float | None = None, check_end: bool = True) -> VideoInfo:
    """Open a video and check codec, frame count, frame size and fps up front.

    Parameters
    ----------
    path : str or Path
    fps_override : float, optional
        The rig's ``[camera].fps``: used only when the container gives no frame rate,
        and checked against it otherwise (:func:`check_rig_fps`).
    check_end : bool
        Also decode the last frame, so a truncated file is reported here rather than
        halfway through tracking.

    Returns
    -------
    VideoInfo

    Raises
    ------
    VideoError
        File missing, empty, not a video, zero frames, no frame rate, undecodable or
        truncated; the message names the file.
    """
    import cv2

    cap = _open(path)
    try:
        n = int(round(cap.get(cv2.CAP_PROP_FRAME_COUNT)))
        fps = float(cap.get(cv2.CAP_PROP_FPS))
        w = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH))
        h = int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
        fourcc = int(cap.get(cv2.CAP_PROP_FOURCC))
        codec = "".join(chr((fourcc >> (8 * i)) & 0xFF) for i in range(4)).strip("\x00 ")
        if n <= 0:
            raise VideoError("video has no frames (empty or unreadable stream)", path=path)
        if w <= 0 or h <= 0:
            raise VideoError(f"invalid frame size {w}x{h}", path=path)
        ok, img = cap.read()
        if not ok or img is None:
            raise VideoError(f"cannot decode the first frame (codec {codec or '?'})",
                             path=path, where="frame 0")
        if fps_override is not None:
            if not np.isfinite(fps_override) or fps_override <= 0:
                raise VideoError(f"invalid fps override {fps_override!r}", path=path)
            check_rig_fps(fps, fps_override, path)
            if not _usable_fps(fps):
                fps = float(fps_override)
        elif not _usable_fps(fps):
            raise VideoError(f"container gives no usable frame rate ({fps!r}); set "
                             "[camera].fps in the rig", path=path)
        if check_end and n > 1:
            cap.set(cv2.CAP_PROP_POS_FRAMES, n - 1)
            ok, img = cap.read()
            if not ok or img is None:
                # A variable frame rate makes the frame -> time conversion of the seek
                # (and the announced count) approximate: seek by time near the end.
                cap.set(cv2.CAP_PROP_POS_MSEC, max(0.0, (n - 3) * 1000.0 / fps))
                ok, img = cap.read()
            if not ok or img is None:
                raise VideoError(f"video is truncated: the container announces {n} frames "
                                 "but the last one cannot be decoded", path=path,
                                 where=f"frame {n - 1}")
    finally:
        cap.release()
    return VideoInfo(str(path), n, fps, w, h, codec, n / fps)


def iter_frames(path, start: int = 0, end: int | None = None, exclude=(),
                fps_override: float | None = None):
    """Yield :class:`Frame` objects one at a time, from ``start`` up to ``end`` (exclusive).

    Parameters
    ----------
    path : str or Path
    start : int
        First frame to yield (0-based index in the file); frames before it are skipped
        without being converted.
    end : int, optional
        Stop before this frame index (default: the end of the video).
    exclude : iterable of int
        Frame indices to skip (not yielded; the caller decides whether to record them).
    fps_override : float, optional
        The rig's ``[camera].fps``: the time is ``(index - start) / fps_override`` only
        when the container gives no frame rate (checked by :func:`check_rig_fps`
        otherwise).

    Raises
    ------
    VideoError
        If the file cannot be opened, ``start``/``end`` are out of range, or decoding
        stops before the announced end (truncated file); names the file and frame.
    """
    import cv2

    start = int(start)
    if start < 0:
        raise VideoError(f"start frame {start} is negative", path=path)
    if end is not None and int(end) <= start:
        raise VideoError(f"end frame {end} is not after start frame {start}", path=path)
    exclude = {int(i) for i in exclude}
    cap = _open(path)
    try:
        n = int(round(cap.get(cv2.CAP_PROP_FRAME_COUNT)))
        fps = float(cap.get(cv2.CAP_PROP_FPS))
        check_rig_fps(fps, fps_override, path)
        if _usable_fps(fps):
            fps_override = None  # time from the container, always
        elif fps_override is not None:
            fps = float(fps_override)
        if n > 0 and start >= n:
            raise VideoError(f"start frame {start} is beyond the last frame ({n - 1})",
                             path=path)
        stop = n if end is None else min(int(end), n) if n > 0 else int(end)
        t0_ms = None
        prev_ms = -np.inf
        index = 0
        while stop <= 0 or index < stop:
            if index < start or index in exclude:
                ok = cap.grab()
                ms = cap.get(cv2.CAP_PROP_POS_MSEC)
                img = None
            else:
                ok, img = cap.read()
                ms = cap.get(cv2.CAP_PROP_POS_MSEC)
            if not ok:
                # (with a variable frame rate the announced count is duration x mean rate:
                # ending within ~2 frames of the container's duration is the real end)
                at_end = np.isfinite(prev_ms) and prev_ms >= (n - 3.5) * 1000.0 / fps
                if stop > 0 and index < stop and not (end is None and at_end):
                    raise VideoError(f"video is truncated or corrupt: decoding stopped at "
                                     f"frame {index} of {n}", path=path, where=f"frame {index}")
                break
            # Container timestamps where meaningful (strictly increasing); else index/fps.
            if not np.isfinite(ms) or ms <= prev_ms:
                ms = prev_ms + 1000.0 / fps if np.isfinite(prev_ms) else index * 1000.0 / fps
            prev_ms = ms
            if index == start:
                t0_ms = ms
            if img is not None:
                if fps_override is not None:
                    t = (index - start) / float(fps_override)
                else:
                    t = (ms - t0_ms) / 1000.0
                yield Frame(index, float(t), img)
            index += 1
    finally:
        cap.release()


def read_frame(path, index: int = 0) -> np.ndarray:
    """Return one frame (BGR uint8) of a video, or the image itself for a still image.

    Raises
    ------
    VideoError
        If the file cannot be read or ``index`` is out of range.
    """
    import cv2

    p = Path(path)
    if p.suffix.lower() in IMAGE_SUFFIXES:
        if not p.exists():
            raise VideoError("no such file", path=p)
        img = cv2.imread(str(p), cv2.IMREAD_COLOR)
        if img is None:
            raise VideoError("cannot read as an image", path=p)
        if index not in (0, None):
            raise VideoError(f"frame {index} requested but a still image has only frame 0",
                             path=p)
        return img
    info = probe_video(p, check_end=False)
    if not 0 <= index < info.n_frames:
        raise VideoError(f"frame {index} is out of range (video has {info.n_frames} frames)",
                         path=p)
    for fr in iter_frames(p, start=index, end=index + 1):
        return fr.image
    raise VideoError("cannot decode frame", path=p, where=f"frame {index}")
