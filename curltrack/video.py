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
rotation tag.  A stream flagged progressive at a camcorder's frame rate is also checked
for interlaced content (:func:`field_motion`: fields woven from two exposures, flags
lost in a re-encoding), and measured as fields when its fields move apart.  With
``fields=True`` an interlaced frame is yielded as its two fields, each its own exposure
(``Frame.field`` 0 = the field exposed first, ``Frame.t`` that field's time: the
frame's plus half a frame period for the second), each resampled to the frame's full
height with its lines where they were on the sensor.

Frames are decoded one at a time; no function here holds more than one frame.
"""

from __future__ import annotations

import functools
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import VideoError

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
    fields_from_content : str
        "" when the scan is the stream's flags; else why a stream flagged progressive is
        measured as interlaced (:func:`field_motion`).
    colour_per_field : bool
        Each field has its own colour rows, as :attr:`FieldMotion.colour_per_field`
        shows (True when the content shows nothing: a still camera).  Each field is
        then measured from its own colour, else from colour the two share.
    colour_kept : str
        Why the stream's format itself gives each field its own colour
        (:func:`field_colour_kept`: DV, colour on every line), "" when it does not say.
    content_note : str
        "" when a stream flagged interlaced is measured as flagged; else what its
        content showed and what was done (order reversed, one exposure, shared colour).
    streams : str
        "" for a file with one video stream; else which of its video streams is measured
        (:func:`main_stream`: the largest picture).
    time_tick_s : float
        The resolution of the container's timestamps (s; its stream time base), 0 when
        unknown.  Over :data:`COARSE_TICK_S` the frame times are read by
        :class:`FrameClock` (Matroska and WebM store milliseconds).
    times_on_grid : bool
        Such coarse timestamps are a constant frame rate's, rounded: the frames' times
        are put back on its grid (:func:`_time_grid`).
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
    fields_from_content: str = ""
    colour_per_field: bool = True
    colour_kept: str = ""
    content_note: str = ""
    streams: str = ""
    time_tick_s: float = 0.0
    times_on_grid: bool = False

    @property
    def content_field_order(self) -> str | None:
        """"tff"/"bff" when the field order was found in the content (the frames' flags
        say progressive, or another order, so :func:`iter_frames` must be told it), else
        None."""
        if not (self.fields_from_content or self.content_note):
            return None
        return "tff" if self.top_field_first else "bff"

    @property
    def reading(self) -> dict:
        """:func:`iter_frames` keyword arguments that read the video as ``track``
        measures it: with this decoder, an interlaced video (flagged, or found in its
        content) as its fields, each with the colour it has."""
        return dict(decoder=self.decoder, fields=self.interlaced,
                    field_order=self.content_field_order,
                    colour_per_field=self.colour_per_field)

    def describe(self) -> str:
        """One line: format, size, rate, scan and what will be done with it."""
        scan = (f"interlaced ({'top' if self.top_field_first else 'bottom'} field first)"
                if self.interlaced else "progressive")
        if self.fields_from_content:
            scan += f" (flagged progressive: {self.fields_from_content})"
        if self.content_note:
            scan += f" ({self.content_note})"
        if self.interlaced and self.colour_kept:
            scan += f", each field its own colour ({self.colour_kept})"
        rot = f", rotation tag {self.rotation_deg} deg" if self.rotation_deg else ""
        if abs(self.pixel_aspect - 1.0) > 1e-3:
            rot += (f", non-square pixels ({self.pixel_aspect:.4g}: resampled to square "
                        "pixels before measuring)")
        if self.streams:
            rot += f"; {self.streams}"
        if self.time_tick_s > COARSE_TICK_S:
            rot += (f"; timestamps in {1e3 * self.time_tick_s:.3g} ms steps ("
                    + ("a constant frame rate's, rounded: times put back on its grid)"
                       if self.times_on_grid else
                       "not on one frame rate's grid: kept as they are, to that step)"))
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


def main_stream(container):
    """The video stream a shot is measured on: the largest picture (a camera's or an
    editor's small preview or thumbnail stream may come first; cover art is left out),
    the first of equals.  OpenCV reads the first video stream only, so a file whose main
    stream is not the first is read through PyAV (:func:`probe_video`)."""
    streams = [st for st in container.streams.video
               if not getattr(st.disposition, "attached_pic", False)] \
        or list(container.streams.video)
    return max(streams, key=lambda st: (st.codec_context.width or 0)
               * (st.codec_context.height or 0) * 2 - st.index)


#: Timestamps stored in steps coarser than this (s) are rounded by the container, not
#: measured: Matroska and WebM store whole milliseconds, which put a constant 30 fps
#: stream's frames up to 0.5 ms off their times (1 mm at 2 m/s).  MP4 and MPEG-TS
#: (1/90000 s, 1/15360 s...) keep them to a few microseconds.
COARSE_TICK_S = 1e-4


class FrameClock:
    """Frame times (s) from a container's timestamps, read to their resolution.

    Where the timestamps are rounded to a coarse tick (``tick_s`` over
    :data:`COARSE_TICK_S`), a frame whose timestamp lies within half a tick of the frame
    rate's grid (``phase_s`` + whole frame periods ``1 / fps``) is given the grid's time:
    the rounding is undone and a constant rate's frames are exactly on its grid.  A
    frame farther off than the rounding explains (a variable frame rate's) keeps its own
    timestamp.  Fine ticks, or no phase, pass the timestamps through unchanged.

    Parameters
    ----------
    fps : float
        The container's frame rate (frames/s).
    tick_s : float
        The timestamps' resolution (s); 0 when unknown.
    phase_s : float or None
        The grid's phase (s): a time on it (:func:`_time_grid`).
    """

    def __init__(self, fps: float, tick_s: float, phase_s: float | None):
        self.period = 1.0 / float(fps) if fps and fps > 0 else 0.0
        on = tick_s > COARSE_TICK_S and phase_s is not None and self.period > 0
        self.half = 0.5 * float(tick_s) + 1e-9 if on else 0.0
        self.tick = float(tick_s) if on else 0.0
        self.phase = float(phase_s) if on else 0.0

    def __call__(self, raw: float) -> float:
        t = float(raw)
        if self.half > 0:
            grid = self.phase + round((t - self.phase) / self.period) * self.period
            if abs(t - grid) <= self.half:
                return grid
        return t

    def anchor(self, raw: float) -> None:
        """Move the grid to the decoder's origin where the first frame's time ``raw``
        (s) is off it: a decoder that counts from the first frame's stored time (OpenCV:
        a Matroska stream whose first frame is at 29.22 ms, stored as 29, read 0, 34,
        67 ms for 0, 33.37, 66.73 - kept to the millisecond, 0.7 ms off).  The grid's
        phase (the first packet's time, :func:`_time_grid`) is then that time's
        rounding, from ``raw``; times relative to the first frame are exact again."""
        if self.half > 0 and self(raw) == float(raw):
            self.phase = float(raw) + self.phase - self.tick * round(self.phase / self.tick)


#: packets whose timestamps place the frame rate's grid (:func:`_time_grid`)
GRID_PACKETS = 600


@functools.lru_cache(maxsize=32)
def _time_grid(path: str, size: int, mtime_ns: int) -> tuple[float, float | None]:
    """(tick, phase) of the main video stream's timestamps: the time base (s; 0 without
    PyAV or when unreadable) and, for a coarse one (:data:`COARSE_TICK_S`), the phase
    of the frame rate's grid that its first :data:`GRID_PACKETS` packets' times are
    rounded from (s; None when they are not all within half a tick of one grid: a
    variable frame rate)."""
    try:
        import av
    except ImportError:
        return 0.0, None
    try:
        with av.open(path) as c:
            st = main_stream(c)
            tick = float(st.time_base) if st.time_base else 0.0
            rate = float(st.average_rate or st.guessed_rate or 0)
            if tick <= COARSE_TICK_S or rate <= 0:
                return tick, None
            times = []
            for pkt in c.demux(st):
                if pkt.pts is not None:
                    times.append(float(pkt.pts * st.time_base))
                if len(times) >= GRID_PACKETS:
                    break
    except Exception:  # noqa: BLE001 - OpenCV's own checks report an unreadable file
        return 0.0, None
    if len(times) < 3:
        return tick, None
    times = np.sort(times)
    period = 1.0 / rate
    r = times - times[0]
    r = r - np.round(r / period) * period
    phase = times[0] + 0.5 * (r.max() + r.min())
    # (rounded from one grid: every time within half a tick of it)
    return tick, (float(phase) if np.ptp(r) <= tick + 1e-9 else None)


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
            st = main_stream(c)
            cc = st.codec_context
            for fr in c.decode(st):
                img = fr.to_ndarray(format="gray")
                # AVFieldOrder: 2 TT, 3 BB, 4 TB (top coded first, bottom shown first),
                # 5 BT; frames flagged interlaced with an unknown order: top first
                order = int(getattr(cc, "field_order", 0) or 0)
                sar = st.sample_aspect_ratio or cc.sample_aspect_ratio
                return {"container": c.format.name, "codec_name": cc.name,
                        "stream": (list(c.streams.video).index(st), len(c.streams.video),
                                   st.index == c.streams.video[0].index),
                        "size": (fr.width, fr.height),
                        "fps": float(st.average_rate or st.guessed_rate or 0) or None,
                        "first_time": float(fr.time) if fr.time is not None else 0.0,
                        "pixel_aspect": float(sar) if sar else 1.0,
                        "interlaced": bool(fr.interlaced_frame),
                        "top_field_first": order not in (3, 5),
                        "colour_kept": field_colour_kept(cc.name, fr.format),
                        "rotation_deg": int(round(getattr(fr, "rotation", 0) or 0)) % 360,
                        "peak": int(img.max())}
    except Exception:  # noqa: BLE001 - any FFmpeg failure: OpenCV's checks report it
        return {}
    return {}


#: frames a stream flagged progressive is checked over for interlaced content
FIELD_CHECK_FRAMES = 90
#: frames whose image moves by at least this (field px) from one frame to the next say
#: how the fields move; at least FIELD_MIN_MOVING of them are needed
FIELD_MOTION_PX = 1.0
FIELD_MIN_MOVING = 5
#: ... and motions over this (px per frame) are left out (a lattice moved by over half
#: its cell reads as another shift; such pairs mostly correlate weakly, too)
FIELD_MAX_SHIFT_PX = 24.0
#: woven fields move by half the image's motion per frame (slope +-0.5; measured 0.26-0.53,
#: less where the motion is vertical: half-height fields alias and pull phase
#: correlation's vertical shift towards whole lines); one exposure's do not move
#: (|slope| <= 0.005 on every progressive clip of the camera sweep).  Read as woven at
#: |slope| >= this and 5 standard errors
FIELD_SLOPE = 0.15
#: phase correlation's peak (0-1) below which a frame pair says nothing (a featureless
#: or blank frame: its shift is noise); textured frames of the sweep's clips gave 0.85-1
FIELD_MIN_RESPONSE = 0.5
#: the vertical offset (field lines, phase correlation's sign) of a frame's bottom field
#: from its top one when both are one exposure: -0.5 (half a line lower) for smooth
#: content, towards 0 where thin threads alias (measured -0.37 to -0.53 on textured
#: pans); 0.1 either side for the measurement's own noise
FIELD_OFFSET_LINES = (-0.6, 0.1)


@dataclass(frozen=True)
class FieldMotion:
    """How a frame's two fields move with the image (:func:`field_motion`).

    Attributes
    ----------
    n_frames : int
        Frame pairs examined (textured enough to correlate).
    n_moving : int
        Those whose image moved by :data:`FIELD_MOTION_PX` or more.
    slope : float
        Shift from the top field to the bottom field per shift of the image from one
        frame to the next: +0.5 woven top field first, -0.5 bottom first, 0 one exposure.
    slope_err : float
        Its standard error (inf when not measured).
    chroma_slope, chroma_slope_err : float
        The same for the 4:2:0 colour planes: the shift from their even rows to their
        odd rows per shift of the colour from one frame to the next - :attr:`slope`
        when each field has its own colour rows (interlaced 4:2:0, kept by a
        re-encoding that copied the planes), 0 when the colour was subsampled across
        the woven frame (shared by the fields); error inf when not measured.  (The
        colour's own motion, not the image's: thin threads lose their colour to the
        subsampling, and what is left to see - the rock's markers - moves otherwise.)
    colour_kept : str
        Why the stream's format gives each field its own colour whatever the chroma
        slope shows (:func:`field_colour_kept`: DV, colour on every line), "" when only
        the content can tell.
    """

    n_frames: int
    n_moving: int
    slope: float
    slope_err: float
    chroma_slope: float = 0.0
    chroma_slope_err: float = np.inf
    colour_kept: str = ""

    @property
    def woven(self) -> bool:
        """Two exposures woven into each frame (the fields move apart with the image)."""
        return (self.n_moving >= FIELD_MIN_MOVING and abs(self.slope) >= FIELD_SLOPE
                and abs(self.slope) >= 5.0 * self.slope_err)

    @property
    def one_exposure(self) -> bool:
        """The fields were shown to coincide as the image moved: a progressive picture
        (slope under :data:`FIELD_SLOPE`, and a woven one's 0.5 over 5 standard errors
        away)."""
        return (self.n_moving >= FIELD_MIN_MOVING and abs(self.slope) < FIELD_SLOPE
                and 0.5 - abs(self.slope) >= 5.0 * self.slope_err)

    @property
    def order(self) -> str | None:
        """"tff" or "bff" when :attr:`woven`, else None."""
        return ("tff" if self.slope > 0 else "bff") if self.woven else None

    @property
    def colour_per_field(self) -> bool:
        """Each field has its own colour rows: by the stream's format
        (:attr:`colour_kept`), or the colour planes' rows move apart as the luma's do
        (chroma slope nearer :attr:`slope` than 0, at 5 standard errors).  False -
        colour shared by the fields, the safe reading - when that is not shown."""
        if self.colour_kept:
            return bool(self.woven)
        c = self.chroma_slope * np.sign(self.slope)
        return bool(self.woven and np.isfinite(self.chroma_slope_err)
                    and c >= 0.5 * abs(self.slope) and c >= 5.0 * self.chroma_slope_err)

    def describe(self) -> str:
        colour = ""
        if self.woven and self.colour_kept:
            colour = f"; each field keeps its own colour ({self.colour_kept})"
        elif self.woven:
            colour = (f"; its colour rows move with their fields (chroma {self.chroma_slope:+.2f}"
                      f" +- {self.chroma_slope_err:.2f}): each field keeps its own colour"
                      if self.colour_per_field else
                      "; its colour is shared by the two fields (subsampled across the "
                      "woven frame, or not shown otherwise)")
        return (f"its bottom field is shifted from its top field by {self.slope:+.2f} +- "
                f"{self.slope_err:.2f} of the image's motion per frame over {self.n_moving} "
                f"moving frames (one exposure's fields: 0; woven, "
                f"{'top' if self.slope > 0 else 'bottom'} field first: "
                f"{'+' if self.slope > 0 else '-'}0.5){colour}")


def field_motion(path, n_frames: int = FIELD_CHECK_FRAMES) -> FieldMotion | None:
    """Do a video's frames hold two exposures (interlaced fields), whatever its flags?

    Each frame's even and odd lines are two half-height images (the top and bottom
    fields).  Taken at one instant (progressive) they coincide - up to a fixed vertical
    offset that the image's fine vertical detail sets (half a line for smooth content,
    less where thin threads alias) - whatever the image does.  Woven from two exposures
    half a frame period apart, the second is shifted from the first by half the image's
    motion per frame (a moving camera's).  So the top-to-bottom shift of a frame is
    regressed on the image's motion from its top field to the next frame's (phase
    correlation of a central crop; where the lattice aliases that step, as two steps
    through the bottom field, whose fixed offsets cancel; a vertical intercept takes the
    offset of the top-to-bottom shift): slope +0.5 top field first, -0.5 bottom first,
    0 progressive.  A still camera gives no leverage, and no evidence.  Frame pairs
    whose correlation peak is under :data:`FIELD_MIN_RESPONSE` (nothing to see) are
    left out.

    Returns
    -------
    FieldMotion or None
        None without PyAV or when the file cannot be decoded (the caller's checks then
        report it).
    """
    import cv2

    try:
        import av
    except ImportError:
        return None
    rows = []
    kept = ""
    try:
        with av.open(str(path)) as c:
            st = main_stream(c)
            prev = win = win_c = None
            for i, fr in enumerate(c.decode(st)):
                if i > n_frames:
                    break
                if i == 0:
                    kept = field_colour_kept(st.codec_context.name, fr.format)
                g = fr.to_ndarray(format="gray").astype(np.float32)
                h, w = g.shape
                ch, cw = min(h // 2, 192), min(w, 384)
                if ch < 16 or cw < 16:
                    return None
                r0, c0 = (h // 2 - ch) // 2, (w - cw) // 2
                top = g[0::2][r0:r0 + ch, c0:c0 + cw]
                bottom = g[1::2][r0:r0 + ch, c0:c0 + cw]
                colour = _colour_rows(fr, r0, c0, ch, cw)
                if win is None:
                    win = cv2.createHanningWindow((cw, ch), cv2.CV_32F)
                    if colour is not None:
                        win_c = cv2.createHanningWindow(colour[0].shape[::-1], cv2.CV_32F)
                inner = cv2.phaseCorrelate(top, bottom, win)
                if prev is not None:
                    # the frame's motion top -> next top; where the lattice aliases that
                    # (a weak peak), as two shorter steps through the bottom field
                    d1, r1 = prev[3]
                    d, r = cv2.phaseCorrelate(prev[0], top, win)
                    if r < FIELD_MIN_RESPONSE:
                        d2, r = cv2.phaseCorrelate(prev[1], top, win)
                        d = (d1[0] + d2[0], d1[1] + d2[1])
                    elif inner[1] >= FIELD_MIN_RESPONSE:
                        # the two frames' field shifts, averaged: the noise of the top
                        # field they share with the motion cancels (it enters one shift
                        # with the motion's sign and the other against it)
                        d1 = (0.5 * (d1[0] + inner[0][0]), 0.5 * (d1[1] + inner[0][1]))
                    # the colour's field shift, and its own motion to the next frame
                    dc = dcm = (np.nan, np.nan)
                    if prev[2] is not None and colour is not None:
                        dc, rc = cv2.phaseCorrelate(*prev[2], win_c)
                        dcm, rcm = cv2.phaseCorrelate(prev[2][0], colour[0], win_c)
                        if min(rc, rcm) < FIELD_MIN_RESPONSE:
                            dc = dcm = (np.nan, np.nan)
                    if min(r1, r) >= FIELD_MIN_RESPONSE:
                        rows.append((*d1, *d, *dc, *dcm))
                prev = (top, bottom, colour, inner)
    except Exception:  # noqa: BLE001 - any FFmpeg failure: the caller's checks report it
        return None
    p = np.array(rows).reshape(-1, 8)
    step = np.hypot(p[:, 2], p[:, 3])
    use = (step >= FIELD_MOTION_PX) & (step <= FIELD_MAX_SHIFT_PX)
    n_moving = int(use.sum())
    if n_moving < FIELD_MIN_MOVING:
        return FieldMotion(len(p), n_moving, 0.0, np.inf, colour_kept=kept)
    q = p[use]
    slope, err = _shift_slope(q[:, 2:4], q[:, 0:2])
    # (colour planes have half the pixels each way: half the luma's motion limits)
    cstep = np.hypot(p[:, 6], p[:, 7])
    qc = p[np.isfinite(cstep) & (cstep >= 0.5 * FIELD_MOTION_PX)
           & (cstep <= 0.5 * FIELD_MAX_SHIFT_PX)]
    chroma = (_shift_slope(qc[:, 6:8], qc[:, 4:6]) if len(qc) >= FIELD_MIN_MOVING
              else (0.0, np.inf))
    return FieldMotion(len(p), n_moving, slope, err, *chroma, colour_kept=kept)


def field_colour_kept(codec_name: str, fmt) -> str:
    """Why a stream's format gives each interlaced field its own colour, "" when it
    does not say (4:2:0 coded from a woven frame may share it: :func:`field_motion`
    then reads the content).

    DV (``dvvideo``) is a camera's own recording: its colour is sampled from each
    field's lines (NTSC 4:1:1 on every line, PAL 4:2:0 per field).  A pixel format
    whose colour planes have every line (4:1:1, 4:2:2, 4:4:4) cannot share a colour
    row between the fields.  What a codec's quantisation still mixes between the two
    (rendered DV: the fields' markers 0.9-1.0 of the image's motion closer than their
    luma) mixes both alike, and the fields' own disagreement measures it
    (:func:`curltrack.track.results.field_motion_share`).

    Parameters
    ----------
    codec_name : str
        FFmpeg's codec name.
    fmt : av.VideoFormat
        A decoded frame's pixel format.
    """
    if codec_name == "dvvideo":
        return "DV: each field's colour sampled from its own lines"
    # (PyAV's ``is_chroma`` is the plane's horizontal subsampling shift: 0 for 4:4:4)
    colour = [c for c in fmt.components if not (c.is_luma or c.is_alpha)]
    if fmt.components[0].is_luma and colour and all(c.height == fmt.height for c in colour):
        return f"{fmt.name}: colour on every line"
    return ""


def _colour_rows(fr, r0: int, c0: int, ch: int, cw: int):
    """(even, odd) rows of a 4:2:0 frame's colour strength |U - 128| + |V - 128| over the
    luma fields' crop (rows ``r0:r0 + ch`` of a field, columns ``c0:c0 + cw``), float32;
    None for other pixel formats (whose colour rows are the frame's own lines)."""
    h, w = fr.height, fr.width
    if fr.format.name not in ("yuv420p", "yuvj420p") or h % 4 or w % 2:
        return None
    a = fr.to_ndarray()  # I420: Y (h rows), then U and V (h/4 rows of w each)
    U = a[h:h + h // 4].reshape(h // 2, w // 2).astype(np.float32)
    V = a[h + h // 4:].reshape(h // 2, w // 2).astype(np.float32)
    c = np.abs(U - 128.0) + np.abs(V - 128.0)
    rows, cols = slice(r0 // 2, (r0 + ch) // 2), slice(c0 // 2, (c0 + cw) // 2)
    even, odd = c[0::2][rows, cols], c[1::2][rows, cols]
    return (even, odd) if min(even.shape) >= 8 else None


def _shift_slope(motion, shift) -> tuple[float, float]:
    """(slope, its standard error) of ``shift`` (n, 2) on ``motion`` (n, 2) - the same
    slope on both axes, an intercept on the vertical one within
    :data:`FIELD_OFFSET_LINES` - by least squares, then again without 4-MAD outliers.

    The intercept is the fields' fixed offset, which one exposure per frame gives alone;
    its bounds are what tell the two readings apart under a steady vertical pan, where
    slope and intercept trade off.  So the error is the profile's: the slope over the
    square root of how much worse (in the residuals' variance) the best fit with no
    slope is - infinite when it is as good - and among equal fits the smallest slope is
    reported.
    """
    from scipy.optimize import lsq_linear

    n = len(motion)
    y = np.concatenate([shift[:, 0], shift[:, 1]])
    X = np.zeros((2 * n, 2))
    X[:, 0] = np.concatenate([motion[:, 0], motion[:, 1]])
    X[n:, 1] = 1.0
    lo, hi = FIELD_OFFSET_LINES
    tie = np.array([[1e-3, 0.0]])   # a slight pull to no slope: the smallest among equals

    def best(rows):
        return lsq_linear(np.vstack([X[rows], tie]), np.append(y[rows], 0.0),
                          bounds=([-np.inf, lo], [np.inf, hi])).x

    keep = np.ones(y.size, bool)
    for _ in range(2):
        beta = best(keep)
        res = y - X @ beta
        mad = 1.4826 * np.median(np.abs(res[keep])) + 1e-3
        keep = np.abs(res) <= 4.0 * mad
    beta = best(keep)
    ss = float(np.sum((y - X @ beta)[keep] ** 2))
    vertical = keep & (X[:, 1] > 0)
    offset = np.clip(np.mean(y[vertical]), lo, hi) if vertical.any() else 0.0
    ss0 = float(np.sum((y - X[:, 1] * offset)[keep] ** 2))
    s2 = max(ss / max(int(keep.sum()) - 2, 1), 1e-12)
    z2 = max(ss0 - ss, 0.0) / s2
    slope = float(beta[0])
    return slope, (abs(slope) / np.sqrt(z2) if z2 > 0 else float(np.inf))


def _file_stamp(path) -> tuple[int, int]:
    st = os.stat(path)
    return st.st_size, st.st_mtime_ns


def _av_last_time(path, first: float) -> float | None:
    """The time (s) FFmpeg gives the video's last frame, decoded from a seek to a
    keyframe within 2 s of the container's end (one GOP); None without PyAV, or when
    nothing decodes there (a stream FFmpeg cannot seek in, such as MPEG-TS with one
    keyframe).  ``first`` is the first frame's time (s)."""
    try:
        import av
    except ImportError:
        return None
    last = None
    try:
        with av.open(str(path)) as c:
            st = main_stream(c)
            if c.duration is not None:
                end_s = (c.duration + (c.start_time or 0)) / 1e6
                try:
                    c.seek(int(max(first, end_s - 2.0) / st.time_base), stream=st,
                           backward=True, any_frame=False)
                    for fr in c.decode(st):
                        if fr.time is not None:
                            last = float(fr.time)
                except av.FFmpegError:
                    last = None
    except Exception:  # noqa: BLE001 - any FFmpeg failure: the caller's checks report it
        return None
    return last


#: frame counts above this (a day at 240 fps) are not a count (OpenCV's for a stream
#: with no duration in its header: -2.8e17 or its wrap-around)
MAX_FRAME_COUNT = 24 * 3600 * 240


@functools.lru_cache(maxsize=32)
def _av_frame_count(path: str, size: int, mtime_ns: int) -> int:
    """Frames FFmpeg decodes from the file's :func:`main_stream` (streamed, once per
    file version); 0 when it decodes none or cannot open it."""
    try:
        import av
    except ImportError:
        return 0
    n = 0
    try:
        with av.open(path) as c:
            for _ in c.decode(main_stream(c)):
                n += 1
    except Exception:  # noqa: BLE001 - a stream that stops decoding: what was decoded
        pass
    return n


def _reaches_end(path: str, first: float, fps: float, n: int) -> bool:
    """Whether FFmpeg's last frame of the stream is at the end that ``n`` frames at
    ``fps`` from ``first`` announce (within 1.5 frames)."""
    last = _av_last_time(path, first)
    return last is not None and abs((last - first) * fps + 1 - n) <= 1.5


@functools.lru_cache(maxsize=32)
def _offset_frame_count(path: str, size: int, mtime_ns: int, first: float, fps: float,
                        n: int) -> int | None:
    """The frame count of a stream whose first frame is at ``first`` > 0 s, where
    OpenCV's count ``n`` (the container's end time x fps) counts the offset as frames:
    FFmpeg's last frame time - ``first``, x ``fps``, + 1 - when that, with the offset's
    frames, makes up ``n``; else None (the count stands).  (A Matroska part cut from a
    longer recording, its first frame at 10 s: OpenCV announced 444 frames for 144 and
    the file was refused as truncated.)"""
    last = _av_last_time(path, first)
    if last is None:
        return None
    n_av = int(round((last - first) * fps)) + 1
    return n_av if n_av < n and abs(n_av + first * fps - n) <= 1.5 else None


def _scan_from_content(av_info: dict, fm: "FieldMotion | None") -> tuple[dict, str, str]:
    """The scan to measure by, from the stream's flags and what its fields show.

    Returns ``(av_info, fields_from_content, content_note)``: ``av_info`` with
    ``interlaced``, ``top_field_first`` and ``colour_per_field`` as measured where the
    content shows them; ``fields_from_content`` the evidence when a stream flagged
    progressive is woven; ``content_note`` what was changed on a stream flagged
    interlaced (its field order reversed, its fields one exposure, its colour shared),
    "" when the content agrees with the flags or shows nothing (a still camera).
    """
    if fm is None:
        return av_info, "", ""
    if not av_info["interlaced"]:
        if not fm.woven:
            return av_info, "", ""
        return ({**av_info, "interlaced": True, "top_field_first": fm.order == "tff",
                 "colour_per_field": fm.colour_per_field}, fm.describe(), "")
    flagged = "tff" if av_info["top_field_first"] else "bff"
    if fm.one_exposure:
        # two fields of one exposure timed half a frame apart would put every other
        # row's time off by a field period (PsF, a progressive source flagged so)
        return ({**av_info, "interlaced": False},
                "", f"flagged interlaced ({flagged}), but {fm.describe()}: measured as "
                    "whole frames, one exposure each")
    if not fm.woven:
        return av_info, "", ""
    notes = []
    if fm.order != flagged:
        notes.append(f"flagged {flagged}, but {fm.describe()}: measured {fm.order}")
    elif not fm.colour_per_field:
        notes.append(f"flagged interlaced: {fm.describe()}")
    return ({**av_info, "top_field_first": fm.order == "tff",
             "colour_per_field": fm.colour_per_field}, "", "; ".join(notes))


@functools.lru_cache(maxsize=32)
def _field_motion_of_file(path: str, size: int, mtime_ns: int) -> FieldMotion | None:
    """:func:`field_motion` once per file version (probe_video is called per stage)."""
    return field_motion(path)


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
        counted = False
        if n <= 0 or n > MAX_FRAME_COUNT:
            # no duration in the header (a live capture, a browser's recording, an
            # interrupted one): OpenCV says -2.8e17 frames; FFmpeg counts them
            n, counted = _av_frame_count(str(path), *_file_stamp(path)), True
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
        index, n_video, first_stream = av_info.get("stream", (0, 1, True))
        streams = ""
        if n_video > 1:
            streams = (f"video stream {index} of {n_video} measured (the largest picture)"
                       if not first_stream else
                       f"the first of {n_video} video streams measured (the largest picture)")
        if not first_stream:
            # (OpenCV reads the first video stream, a preview: the main one by FFmpeg)
            n, counted = _av_frame_count(str(path), *_file_stamp(path)), True
            w, h, fps = av_info["size"][0], av_info["size"][1], av_info["fps"] or fps
        black = int(img.max()) < 8 and av_info.get("peak", 0) >= 8
        square = abs(av_info.get("pixel_aspect", 1.0) - 1.0) <= 1e-3
        from_content = content_note = ""
        flagged_interlaced = bool(av_info and av_info["interlaced"])
        if av_info and fps <= 31.0:
            # what the fields show, flagged or not: flags are lost or set wrongly by
            # re-encodings, and how the colour was subsampled is in no flag at all
            fm = _field_motion_of_file(str(path), *_file_stamp(path))
            av_info, from_content, content_note = _scan_from_content(av_info, fm)
        # (OpenCV 5 decodes H.264 flagged interlaced as black frames)
        decoder = ("pyav" if av_info and (flagged_interlaced or av_info["interlaced"]
                                          or black or not square or counted)
                   else "opencv")
        first = av_info.get("first_time", 0.0)
        if first * fps >= 1.0:
            n_offset = _offset_frame_count(str(path), *_file_stamp(path), first, fps, n)
            if n_offset is not None:  # (OpenCV's reading would stop "truncated")
                n, decoder, check_end = n_offset, "pyav", False
        if check_end and n > 1 and not counted:
            cap.set(cv2.CAP_PROP_POS_FRAMES, n - 1)
            ok, img = cap.read()
            if not ok or img is None:
                # A variable frame rate makes the frame -> time conversion of the seek
                # (and the announced count) approximate: seek by time near the end.
                cap.set(cv2.CAP_PROP_POS_MSEC, max(0.0, (n - 3) * 1000.0 / fps))
                ok, img = cap.read()
            if not ok or img is None:
                # OpenCV cannot seek in every container (MPEG-TS: AVCHD camcorders,
                # broadcast recorders): the frames FFmpeg decodes say whether they are
                # all there
                n_av = _av_frame_count(str(path), *_file_stamp(path))
                if 0 < n_av < n - 1 and _reaches_end(str(path), first, fps, n):
                    # a container that stores no frame count (Matroska, WebM) announces
                    # its duration x the rate: frames dropped from that grid are not
                    # missing from the file's end
                    n = n_av
                elif abs(n_av - n) > 1:
                    raise VideoError(f"video is truncated: the container announces {n} "
                                     "frames but the last one cannot be decoded", path=path,
                                     where=f"frame {n - 1}")
    finally:
        cap.release()
    tick, phase = _time_grid(str(path), *_file_stamp(path))
    extra = {k: av_info[k] for k in ("container", "codec_name", "interlaced",
                                     "top_field_first", "rotation_deg", "pixel_aspect",
                                     "colour_per_field", "colour_kept")
             if k in av_info}
    return VideoInfo(str(path), n, fps, w, h, codec, n / fps, decoder=decoder,
                     fields_from_content=from_content, content_note=content_note,
                     streams=streams,
                     time_tick_s=tick, times_on_grid=phase is not None, **extra)


def iter_frames(path, start: int = 0, end: int | None = None, exclude=(),
                fps_override: float | None = None, decoder: str | None = None,
                fields: bool = False, field_order: str | None = None,
                colour_per_field: bool = True):
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
    field_order : {"tff", "bff"}, optional
        With ``fields``: split every frame in this exposure order, whatever its flags
        (a stream flagged progressive whose content is interlaced:
        ``VideoInfo.fields_from_content``).
    colour_per_field : bool
        With ``fields``: each field has its own 4:2:0 colour rows
        (``VideoInfo.colour_per_field``), else the frame's colour is shared by both.

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
        yield from _iter_pyav(path, start, end, exclude, fps_override, fields, field_order,
                              colour_per_field)
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
        clock = FrameClock(fps, *_time_grid(str(path), *_file_stamp(path)))
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
            if not np.isfinite(prev_ms):
                clock.anchor(ms / 1000.0)
            ms = 1000.0 * clock(ms / 1000.0)
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


def _field_halves(fr, per_field_chroma: bool = True) -> dict:
    """{parity: the field's own lines as BGR} of an interlaced PyAV frame.

    4:2:0 chroma of interlaced video is subsampled per field (chroma row j belongs to
    field j % 2): each field is converted from its own luma and chroma rows, so that a
    moving rock's colours are not blended across the two exposures.  Each field's chroma
    rows are first moved to where they were sampled (:func:`_sited_field_chroma`).  A
    frame coded as progressive (``per_field_chroma=False``) shares its chroma rows
    between the fields.
    """
    import cv2

    if (per_field_chroma and fr.format.name in ("yuv420p", "yuvj420p")
            and fr.height % 4 == 0 and fr.width % 2 == 0):
        a = fr.to_ndarray()  # I420: Y (h rows), then U and V (h/4 rows of w each)
        h, w = fr.height, fr.width
        Y = a[:h]
        U = a[h:h + h // 4].reshape(h // 2, w // 2)
        V = a[h + h // 4:].reshape(h // 2, w // 2)
        return {p: cv2.cvtColor(np.vstack([Y[p::2],
                                           _sited_field_chroma(U[p::2], p).reshape(h // 8, w),
                                           _sited_field_chroma(V[p::2], p).reshape(h // 8, w)]),
                                cv2.COLOR_YUV2BGR_I420) for p in (0, 1)}
    img = fr.to_ndarray(format="bgr24")
    return {p: np.ascontiguousarray(img[p::2]) for p in (0, 1)}


def shift_rows(plane: np.ndarray, shift: float) -> np.ndarray:
    """``plane`` (uint8, rows x columns) read ``shift`` rows further down: row k is the
    linear interpolation at row ``k + shift`` (edge rows repeated)."""
    from scipy.ndimage import shift as nd_shift

    out = nd_shift(plane.astype(np.float64), (-shift, 0.0), order=1, mode="nearest",
                   prefilter=False)
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


#: Where interlaced 4:2:0 samples a field's chroma row k, in that field's luma rows past
#: 2k: a quarter of the way to row 2k + 1 in the top field, three quarters in the
#: bottom one (MPEG-2, H.264; both then fall on the frame's progressive chroma grid)
FIELD_CHROMA_SITE = (0.25, 0.75)


def _sited_field_chroma(c: np.ndarray, parity: int) -> np.ndarray:
    """A field's 4:2:0 chroma plane (rows of that field only, uint8) resampled so that
    its row k sits half-way between the field's luma rows 2k and 2k + 1, as an I420
    conversion takes it.

    Interlaced 4:2:0 samples it at :data:`FIELD_CHROMA_SITE` (so does a progressive
    conversion of a woven frame).  Read as centred, the top field's colours land half a
    frame row low and the bottom field's half a row high: markers found by their colour
    put the two fields ~1 frame row apart (a rendered camcorder at 3.75 mm per row:
    3.1 mm).
    """
    return shift_rows(c, 0.5 * (0.5 - FIELD_CHROMA_SITE[parity]))


def _square_pixels(pixel_aspect: float):
    """A function resampling a frame to square pixels (its width scaled by the
    container's sample aspect ratio, its rows - and so its fields - kept), or the identity.

    The lens, parallax and height models take a pixel to be as wide as it is high; a DV
    camcorder's 10:11 pixels otherwise put positions ~1 cm off.
    """
    if abs(pixel_aspect - 1.0) <= 1e-3 or not np.isfinite(pixel_aspect) or pixel_aspect <= 0:
        return lambda img: img
    import cv2

    def square(img):
        h, w = img.shape[:2]
        new_w = int(round(w * pixel_aspect))
        interp = cv2.INTER_AREA if new_w < w else cv2.INTER_CUBIC
        return cv2.resize(img, (new_w, h), interpolation=interp)

    return square


def _iter_pyav(path, start, end, exclude, fps_override, fields, field_order=None,
               colour_per_field=True):
    """:func:`iter_frames` through FFmpeg (PyAV): frames (or fields) with pts times."""
    import av

    _open(path).release()  # (the same up-front checks and messages)
    try:
        container = av.open(str(path))
    except Exception as exc:  # noqa: BLE001
        raise VideoError(f"cannot open as a video ({exc})", path=path) from None
    try:
        st = main_stream(container)
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
        if field_order is not None:
            first = (0, 1) if field_order == "tff" else (1, 0)
        sar = st.sample_aspect_ratio or st.codec_context.sample_aspect_ratio
        square = _square_pixels(float(sar) if sar else 1.0)
        t0 = None
        index = -1
        prev = -np.inf
        clock = FrameClock(fps, *_time_grid(str(path), *_file_stamp(path)))
        try:
            for fr in container.decode(st):
                index += 1
                if end is not None and index >= int(end):
                    break
                t = float(fr.time) if fr.time is not None else np.nan
                if not np.isfinite(t) or t <= prev:
                    t = prev + 1.0 / fps if np.isfinite(prev) else index / fps
                t = clock(t)
                prev = t
                if index < start or index in exclude:
                    if index == start:
                        t0 = t
                    continue
                if t0 is None:
                    t0 = t
                rel = ((index - start) / float(fps_override) if fps_override is not None
                       else t - t0)
                if fields and (fr.interlaced_frame or field_order is not None):
                    period = 1.0 / fps
                    halves = _field_halves(fr, per_field_chroma=colour_per_field)
                    for k, parity in enumerate(first):
                        yield Frame(index, rel + 0.5 * k * period,
                                    square(field_image(halves[parity], parity)), k)
                else:
                    yield Frame(index, rel, square(fr.to_ndarray(format="bgr24")))
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
