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

Two decoders: OpenCV's (``cv2.VideoCapture``, the fast default for progressive video)
and FFmpeg through PyAV, used when the stream is interlaced (OpenCV 5 decodes H.264
flagged interlaced as all-black frames: its scaler refuses interlaced -> progressive)
or OpenCV's first frame is black where PyAV's is not.  :func:`probe_video` says which
(``VideoInfo.decoder``), with the container format, the codec, the field order and the
rotation tag.  With ``fields=True`` an interlaced frame is yielded as its two fields,
each its own exposure (``Frame.field`` 0 = the field exposed first, ``Frame.t`` that
field's time: the frame's plus half a frame period for the second), each resampled to
the frame's full height with its lines where they were on the sensor.

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
    container : str
        Container format as FFmpeg names it (e.g. ``"mov,mp4,m4a,3gp,3g2,mj2"``,
        ``"dv"``), "" without PyAV.
    codec_name : str
        FFmpeg's codec name (``"h264"``, ``"hevc"``, ``"dvvideo"``, ``"mpeg2video"``),
        "" without PyAV.
    interlaced : bool
        The first frame is flagged interlaced (two fields woven, exposed half a frame
        period apart).
    top_field_first : bool
        Field order of an interlaced stream (the field of the even lines first).
    rotation_deg : int
        The container's display rotation tag (deg), 0 when none.
    decoder : str
        ``"opencv"`` or ``"pyav"``: what :func:`iter_frames` will use.
    pixel_aspect : float
        Sample aspect ratio (pixel width / height) the container declares, 1 when none
        (NTSC DV: 10/11).
    """

    path: str
    n_frames: int
    fps: float
    width: int
    height: int
    codec: str
    duration_s: float
    container: str = ""
    codec_name: str = ""
    interlaced: bool = False
    top_field_first: bool = True
    rotation_deg: int = 0
    decoder: str = "opencv"
    pixel_aspect: float = 1.0

    def describe(self) -> str:
        """One line: format, size, rate, scan and what will be done with it."""
        scan = (f"interlaced ({'top' if self.top_field_first else 'bottom'} field first)"
                if self.interlaced else "progressive")
        rot = f", rotation tag {self.rotation_deg} deg" if self.rotation_deg else ""
        if abs(self.pixel_aspect - 1.0) > 1e-3:
            rot += f", non-square pixels ({self.pixel_aspect:.4g}: not modelled)"
        fmt = self.codec_name or self.codec or "?"
        return (f"{fmt} in {self.container.split(',')[0] or '?'}, {self.width}x{self.height},"
                f" {self.fps:.3f} fps, {scan}{rot}; decoded by "
                f"{'FFmpeg (PyAV)' if self.decoder == 'pyav' else 'OpenCV'}"
                + ("; each field measured as its own exposure (2 rows per frame)"
                   if self.interlaced else ""))


@dataclass(frozen=True)
class Frame:
    """One decoded frame: ``index`` (0-based in the file), ``t`` (s), ``image`` (BGR uint8).

    ``field`` is None for a whole frame, else 0/1: the field exposed first/second.
    """

    index: int
    t: float
    image: np.ndarray
    field: int | None = None

    @property
    def sample(self) -> int:
        """Running index of the exposure: the frame index, or 2 x frame + field."""
        return self.index if self.field is None else 2 * self.index + self.field


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


def _av_probe(path) -> dict:
    """What FFmpeg (PyAV) says of the first video frame: format, codec, scan, rotation.

    {} without PyAV or when it cannot decode the file (OpenCV's checks then decide).
    """
    try:
        import av
    except ImportError:
        return {}
    try:
        with av.open(str(path)) as c:
            st = c.streams.video[0]
            cc = st.codec_context
            for fr in c.decode(st):
                img = fr.to_ndarray(format="gray")
                # AVFieldOrder: 2 TT, 3 BB, 4 TB (top coded first, bottom shown first),
                # 5 BT; frames flagged interlaced with an unknown order: top first
                order = int(getattr(cc, "field_order", 0) or 0)
                sar = st.sample_aspect_ratio or cc.sample_aspect_ratio
                return {"container": c.format.name, "codec_name": cc.name,
                        "pixel_aspect": float(sar) if sar else 1.0,
                        "interlaced": bool(fr.interlaced_frame),
                        "top_field_first": order not in (3, 5),
                        "rotation_deg": int(round(getattr(fr, "rotation", 0) or 0)) % 360,
                        "peak": int(img.max())}
    except Exception:  # noqa: BLE001 - any FFmpeg failure: OpenCV's checks report it
        return {}
    return {}


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
        av_info = _av_probe(path)
        black = int(img.max()) < 8 and av_info.get("peak", 0) >= 8
        decoder = "pyav" if av_info and (av_info["interlaced"] or black) else "opencv"
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
    extra = {k: av_info[k] for k in ("container", "codec_name", "interlaced",
                                     "top_field_first", "rotation_deg", "pixel_aspect")
             if k in av_info}
    return VideoInfo(str(path), n, fps, w, h, codec, n / fps, decoder=decoder, **extra)


def iter_frames(path, start: int = 0, end: int | None = None, exclude=(),
                fps_override: float | None = None, decoder: str | None = None,
                fields: bool = False):
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
    decoder : {"opencv", "pyav"}, optional
        Default: what :func:`probe_video` chooses (PyAV for interlaced streams and
        where OpenCV decodes black frames).
    fields : bool
        Yield each interlaced frame as its two fields (PyAV); progressive frames are
        yielded whole.

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
    if decoder is None:
        decoder = probe_video(path, check_end=False).decoder
    if decoder == "pyav" or fields:
        yield from _iter_pyav(path, start, end, exclude, fps_override, fields)
        return
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


def field_image(half, parity: int) -> np.ndarray:
    """One field (its own lines only, BGR), resampled to the frame's full height.

    The field's lines (frame rows ``parity``, ``parity + 2``, ...) keep their place on
    the sensor: output row y samples field row (y - parity) / 2 (linear interpolation).
    """
    import cv2

    h, w = 2 * half.shape[0], half.shape[1]
    M = np.array([[1.0, 0.0, 0.0], [0.0, 0.5, -0.5 * parity]])
    return cv2.warpAffine(half, M, (w, h), flags=cv2.INTER_CUBIC | cv2.WARP_INVERSE_MAP,
                          borderMode=cv2.BORDER_REPLICATE)


def _field_halves(fr) -> dict:
    """{parity: the field's own lines as BGR} of an interlaced PyAV frame.

    4:2:0 chroma of interlaced video is subsampled per field (chroma row j belongs to
    field j % 2): each field is converted from its own luma and chroma rows, so that a
    moving rock's colours are not blended across the two exposures.
    """
    import cv2

    if fr.format.name in ("yuv420p", "yuvj420p") and fr.height % 4 == 0 and fr.width % 2 == 0:
        a = fr.to_ndarray()  # I420: Y (h rows), then U and V (h/4 rows of w each)
        h, w = fr.height, fr.width
        Y = a[:h]
        U = a[h:h + h // 4].reshape(h // 2, w // 2)
        V = a[h + h // 4:].reshape(h // 2, w // 2)
        return {p: cv2.cvtColor(np.vstack([Y[p::2], U[p::2].reshape(h // 8, w),
                                           V[p::2].reshape(h // 8, w)]),
                                cv2.COLOR_YUV2BGR_I420) for p in (0, 1)}
    img = fr.to_ndarray(format="bgr24")
    return {p: np.ascontiguousarray(img[p::2]) for p in (0, 1)}


def _iter_pyav(path, start, end, exclude, fps_override, fields):
    """:func:`iter_frames` through FFmpeg (PyAV): frames (or fields) with pts times."""
    import av

    _open(path).release()  # (the same up-front checks and messages)
    try:
        container = av.open(str(path))
    except Exception as exc:  # noqa: BLE001
        raise VideoError(f"cannot open as a video ({exc})", path=path) from None
    try:
        st = container.streams.video[0]
        st.thread_count = max(decoder_threads(), 1)
        fps = float(st.average_rate or st.guessed_rate or 0)
        check_rig_fps(fps, fps_override, path)
        if _usable_fps(fps):
            fps_override = None  # time from the container, always
        elif fps_override is not None:
            fps = float(fps_override)
        else:
            raise VideoError(f"container gives no usable frame rate ({fps!r}); set "
                             "[camera].fps in the rig", path=path)
        order = int(getattr(st.codec_context, "field_order", 0) or 0)
        first = (1, 0) if order in (3, 5) else (0, 1)  # parities, in exposure order
        t0 = None
        index = -1
        prev = -np.inf
        try:
            for fr in container.decode(st):
                index += 1
                if end is not None and index >= int(end):
                    break
                t = float(fr.time) if fr.time is not None else np.nan
                if not np.isfinite(t) or t <= prev:
                    t = prev + 1.0 / fps if np.isfinite(prev) else index / fps
                prev = t
                if index < start or index in exclude:
                    if index == start:
                        t0 = t
                    continue
                if t0 is None:
                    t0 = t
                rel = ((index - start) / float(fps_override) if fps_override is not None
                       else t - t0)
                if fields and fr.interlaced_frame:
                    period = 1.0 / fps
                    halves = _field_halves(fr)
                    for k, parity in enumerate(first):
                        yield Frame(index, rel + 0.5 * k * period,
                                    field_image(halves[parity], parity), k)
                else:
                    yield Frame(index, rel, fr.to_ndarray(format="bgr24"))
        except av.FFmpegError as exc:
            raise VideoError(f"video is truncated or corrupt: decoding stopped at frame "
                             f"{index + 1} ({exc})", path=path,
                             where=f"frame {index + 1}") from None
        if index < start:
            raise VideoError(f"start frame {start} is beyond the last frame ({index})",
                             path=path)
    finally:
        container.close()


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
