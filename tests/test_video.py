"""The frame reader: exact indices and container times, ranges, and clear errors."""

import io
from fractions import Fraction
from pathlib import Path

import cv2
import numpy as np
import pytest

from curltrack.errors import VideoError
from curltrack.render.encode import X264_PARAMS
from curltrack.video import iter_frames, probe_video, read_frame


def _write(path, n, fps, size=(160, 96)):
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, size)
    assert w.isOpened()
    for i in range(n):
        img = np.zeros((size[1], size[0], 3), np.uint8)
        img[:, :] = 10 + 10 * i  # frame identity in the grey level (n <= 24)
        w.write(img)
    w.release()
    return path


def _identity(img):
    """Frame number written by :func:`_write` (lossy codec: nearest grey level)."""
    return int(round((float(img[40:60, 60:100].mean()) - 10) / 10))


@pytest.fixture(scope="module", params=[(30000 / 1001, 23), (25.0, 17)],
            ids=["29.97fps", "25fps"])
def clip(request, tmp_path_factory):
    fps, n = request.param
    return _write(tmp_path_factory.mktemp("v") / "clip.mp4", n, fps), fps, n


def test_probe_reports_the_container(clip):
    path, fps, n = clip
    info = probe_video(path)
    assert (info.n_frames, info.width, info.height) == (n, 160, 96)
    assert info.fps == pytest.approx(fps, rel=1e-4)
    assert info.codec and info.duration_s == pytest.approx(n / fps, rel=1e-4)
    # the rig's fps never overrides the container's: agreeing (<= 0.5 %) it is not used,
    # disagreeing it is an error naming the rig's field
    assert probe_video(path, fps_override=fps * 1.003).fps == pytest.approx(fps, rel=1e-4)
    with pytest.raises(VideoError, match=r"\[camera\]\.fps"):
        probe_video(path, fps_override=50.0)


def test_frames_have_exact_indices_and_container_times(clip):
    path, fps, n = clip
    frames = list(iter_frames(path))
    assert [f.index for f in frames] == list(range(n))
    np.testing.assert_allclose([f.t for f in frames], np.arange(n) / fps, atol=1e-6)
    assert [_identity(f.image) for f in frames] == list(range(n))


def test_start_end_exclude_and_fps_override(clip):
    path, fps, n = clip
    frames = list(iter_frames(path, start=5, end=12, exclude=(7, 8)))
    assert [f.index for f in frames] == [5, 6, 9, 10, 11]
    # t = 0 at the start frame, from the container's clock
    np.testing.assert_allclose([f.t for f in frames], (np.array([5, 6, 9, 10, 11]) - 5) / fps,
                               atol=1e-6)
    over = list(iter_frames(path, start=2, end=6, fps_override=fps * 0.997))
    np.testing.assert_allclose([f.t for f in over], np.arange(4) / fps, atol=1e-6)
    with pytest.raises(VideoError, match=r"\[camera\]\.fps"):
        list(iter_frames(path, start=2, end=6, fps_override=10.0))
    assert _identity(read_frame(path, 9)) == 9
    assert [_identity(f.image) for f in frames] == [5, 6, 9, 10, 11]


def test_still_image(tmp_path):
    p = tmp_path / "a.png"
    cv2.imwrite(str(p), np.full((20, 30, 3), 77, np.uint8))
    assert read_frame(p).shape == (20, 30, 3)
    with pytest.raises(VideoError, match="still image"):
        read_frame(p, 3)


@pytest.mark.parametrize("kind", ["missing", "empty", "text", "directory", "truncated"])
def test_bad_files_give_one_clear_error(kind, tmp_path, clip):
    path = tmp_path / "bad.mp4"
    if kind == "empty":
        path.write_bytes(b"")
    elif kind == "text":
        path.write_text("this is not a video\n" * 50)
    elif kind == "directory":
        path.mkdir()
    elif kind == "truncated":
        data = clip[0].read_bytes()
        path.write_bytes(data[: len(data) // 2])
    with pytest.raises(VideoError) as exc:
        probe_video(path)
        list(iter_frames(path))  # (if the container still opens, decoding must fail)
    msg = str(exc.value)
    assert str(path) in msg and "\n" not in msg


class _Pipe(io.RawIOBase):
    """A file written as a stream (no seeking back): a live capture, a browser's
    recording - the muxer cannot go back to write the duration."""

    def __init__(self, f):
        self.f = f

    def writable(self):
        return True

    def write(self, b):
        return self.f.write(b)


def _write_av(path, n, fps, fmt=None, start_s=0.0, size=(160, 96), live=False,
              preview=False, times_s=None):
    """:func:`_write`'s frames as H.264 through FFmpeg (one keyframe: a stream that cannot
    be seeked to its end), in container ``fmt``, the first frame at ``start_s``;
    ``live``: written as a stream, with no duration in the header; ``preview``: after a
    first video stream of black frames at half the size (a camera's preview);
    ``times_s``: the frames' own times instead (n of them; irregular ones kept)."""

    import av

    rate = Fraction(fps).limit_denominator(1001)
    with open(path, "wb") as fh, av.open(_Pipe(fh) if live else fh, "w", format=fmt) as out:
        small = None
        if preview:
            small = out.add_stream("libx264", rate=rate)
            small.width, small.height, small.pix_fmt = size[0] // 2, size[1] // 2, "yuv420p"
            small.codec_context.thread_count = 1
        st = out.add_stream("libx264", rate=rate)
        st.width, st.height, st.pix_fmt = *size, "yuv420p"
        # (x264 on several threads: bytes that depend on the process's history)
        st.codec_context.thread_count = 1
        st.options = {"crf": "10", "g": "1000", "x264-params": X264_PARAMS}
        if times_s is not None:
            # (the encoder keeps each frame's own time only in a time base that fine)
            st.codec_context.time_base = Fraction(1, 90000)
        else:
            times_s = start_s + np.arange(n) / rate
        for i in range(n):
            fr = av.VideoFrame.from_ndarray(np.full((size[1], size[0], 3),
                                                    (10 + 10 * i) % 250, np.uint8),
                                            format="rgb24")
            fr.time_base = Fraction(1, 90000)
            fr.pts = int(round(float(times_s[i]) * 90000))
            for pkt in st.encode(fr):
                out.mux(pkt)
            if small is not None:
                for pkt in small.encode(av.VideoFrame.from_ndarray(
                        np.zeros((size[1] // 2, size[0] // 2, 3), np.uint8), format="rgb24")):
                    out.mux(pkt)
        for stream in (st, small) if small is not None else (st,):
            for pkt in stream.encode():
                out.mux(pkt)
    return path


@pytest.mark.parametrize("kind", ["mpegts", "matroska-offset", "matroska-live",
                                  "preview-first"])
def test_containers_cameras_and_editors_write(kind, tmp_path):
    """MPEG-TS (AVCHD camcorders, broadcast recorders: OpenCV cannot seek in it) and a
    Matroska part cut from a longer recording (its first frame seconds after 0: OpenCV
    counts the offset as frames) were refused as truncated, a Matroska file written live
    (no duration in its header: OpenCV counts -2.8e17 frames) as having no frames; a
    file whose first video stream is a small preview had the preview measured.  Every
    frame of the main stream is read, t from 0; a truncated copy of the part is still
    refused."""
    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    fps = float(rng.choice([25.0, 30000 / 1001, 30.0]))
    n = int(rng.integers(18, 24))
    start = float(rng.uniform(2.0, 90.0)) if kind == "matroska-offset" else 0.0
    suffix = {"mpegts": ".ts", "preview-first": str(rng.choice([".mkv", ".mp4"]))}.get(
        kind, ".mkv")
    path = _write_av(tmp_path / f"clip{suffix}", n, fps, start_s=start,
                     fmt={".ts": "mpegts", ".mkv": "matroska", ".mp4": "mp4"}[suffix],
                     live=kind == "matroska-live", preview=kind == "preview-first")
    what = f"seed {seed}, {kind}: {n} frames at {fps:.3f} fps from {start:.2f} s"
    info = probe_video(path)
    assert info.n_frames == n, f"{what}: {info.n_frames} frames"
    assert (info.width, info.height) == (160, 96), what
    assert ("stream 1 of 2" in info.describe()) is (kind == "preview-first"), what
    frames = list(iter_frames(path, decoder=info.decoder))
    assert [f.index for f in frames] == list(range(n)), what
    np.testing.assert_allclose([f.t for f in frames], np.arange(n) / fps, atol=2e-3)
    assert [_identity(f.image) for f in frames] == list(range(n)), what
    k = int(rng.integers(1, n))
    assert _identity(read_frame(path, k)) == k, what
    if kind == "matroska-offset":
        cut = tmp_path / "cut.mkv"
        data = path.read_bytes()
        cut.write_bytes(data[: len(data) * 3 // 5])
        with pytest.raises(VideoError, match="truncated|cannot decode"):
            probe_video(cut)


def test_range_errors(clip):
    path, fps, n = clip
    with pytest.raises(VideoError, match="beyond the last frame"):
        list(iter_frames(path, start=n + 5))
    with pytest.raises(VideoError, match="not after"):
        list(iter_frames(path, start=4, end=4))
    with pytest.raises(VideoError, match="out of range"):
        read_frame(path, n)


def _woven_clip(path, rng, n=30, size=(320, 240), shift_px=None, order="tff", colour=None):
    """Frames of a textured scene panning by ``shift_px`` (x, y) per field: woven from two
    exposures (``order`` "tff"/"bff") or one (``order`` None), written as progressive
    H.264 with no field flags.  Grey, or with ``colour`` a coloured scene whose 4:2:0
    colour is subsampled per field ("field": each field's own colour rows) or across the
    woven frame ("frame": rows shared by the fields)."""
    av = pytest.importorskip("av")
    w, h = size
    shape = (h + 200, w + 200) + ((3,) if colour else ())
    big = cv2.GaussianBlur(rng.uniform(0, 255, shape).astype(np.float32), (0, 0), 2)
    out = av.open(str(path), "w")
    st = out.add_stream("libx264", rate=30)
    st.width, st.height, st.pix_fmt = w, h, "yuv420p"
    st.options = {"crf": "16", "x264-params": X264_PARAMS}
    st.codec_context.thread_count = 1  # (one clip per seed, whatever ran before)

    def view(k):  # the scene at exposure k (half frames)
        M = np.float32([[1, 0, -50 - k * shift_px[0]], [0, 1, -50 - k * shift_px[1]]])
        return cv2.warpAffine(big, M, (w, h), flags=cv2.INTER_CUBIC)

    for i in range(n):
        if order is None:
            img = view(2 * i)
        else:
            first, second = view(2 * i), view(2 * i + 1)
            img = first.copy()
            top, bottom = (first, second) if order == "tff" else (second, first)
            img[0::2], img[1::2] = top[0::2], bottom[1::2]
        img = np.clip(img, 0, 255).astype(np.uint8)
        if colour is None:
            frame = av.VideoFrame.from_ndarray(cv2.cvtColor(img, cv2.COLOR_GRAY2BGR),
                                               format="bgr24")
        elif colour == "frame":
            frame = av.VideoFrame.from_ndarray(cv2.cvtColor(img, cv2.COLOR_BGR2YUV_I420),
                                               format="yuv420p")
        else:   # each field's own 4:2:0 rows: chroma row j belongs to field j % 2
            Y, U, V = (np.empty((h, w), np.uint8), np.empty((h // 2, w // 2), np.uint8),
                       np.empty((h // 2, w // 2), np.uint8))
            for par in (0, 1):
                yuv = cv2.cvtColor(np.ascontiguousarray(img[par::2]), cv2.COLOR_BGR2YUV_I420)
                Y[par::2] = yuv[:h // 2]
                U[par::2] = yuv[h // 2:h // 2 + h // 8].reshape(h // 4, w // 2)
                V[par::2] = yuv[h // 2 + h // 8:].reshape(h // 4, w // 2)
            frame = av.VideoFrame.from_ndarray(
                np.vstack([Y, U.reshape(h // 4, w), V.reshape(h // 4, w)]), format="yuv420p")
        for p in st.encode(frame):
            out.mux(p)
    for p in st.encode():
        out.mux(p)
    out.close()


def test_interlaced_content_in_a_progressive_stream_is_found(tmp_path):
    """Fields woven from two exposures are found whatever the flags say, with their
    order; one exposure per frame, or a still camera, is not taken for them."""
    from curltrack.video import field_motion

    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    # px per field, in a random direction (2.4-7 per frame)
    speed = rng.uniform(1.2, 3.5)
    a = rng.uniform(0, 2 * np.pi)
    shift = (speed * np.cos(a), speed * np.sin(a))
    order = str(rng.choice(["tff", "bff"]))
    what = f"seed {seed}: {order}, shift {shift[0]:.2f}, {shift[1]:.2f} px per field"
    _woven_clip(tmp_path / "woven.mp4", rng, shift_px=shift, order=order)
    fm = field_motion(tmp_path / "woven.mp4")
    # A steady pan with no sideways part (under 0.1 px per field) leaves only the
    # fields' vertical shift, which one exposure's fixed offset (-0.6 to 0.1 line) can
    # also give: bottom field first, that is so up to ~1.8 px per field (draw 2026 of a
    # 40-draw sweep of near-vertical pans: 1.61 px).  There, never the wrong
    # order; everywhere else, the right one.
    if order == "bff" and abs(shift[0]) < 0.1 and abs(shift[1]) < 1.8:
        assert fm.order in (order, None), (what, fm)
        return
    assert fm.woven and fm.order == order, (what, fm)
    assert 0.2 < abs(fm.slope) < 0.6, (what, fm)   # 0.5, less under vertical motion
    info = probe_video(tmp_path / "woven.mp4")
    assert info.interlaced and info.fields_from_content, (what, info)
    assert info.top_field_first == (order == "tff") and info.decoder == "pyav", what
    assert "flagged progressive" in info.describe(), what
    fr = list(iter_frames(tmp_path / "woven.mp4", end=2, fields=True, field_order=order))
    assert [(f.index, f.field) for f in fr] == [(0, 0), (0, 1), (1, 0), (1, 1)], what
    _woven_clip(tmp_path / "one.mp4", rng, shift_px=shift, order=None)
    fm = field_motion(tmp_path / "one.mp4")
    assert not fm.woven and abs(fm.slope) < 0.1, (what, fm)   # (-0.06 seen, vertical)
    assert not probe_video(tmp_path / "one.mp4").interlaced, what
    _woven_clip(tmp_path / "still.mp4", rng, shift_px=(0.0, 0.0), order=order)
    assert not probe_video(tmp_path / "still.mp4").interlaced, what


@pytest.mark.slow
def test_own_colour_rate_within_30_degrees(tmp_path):
    """Woven fields that kept their own 4:2:0 colour rows, panned within 30 deg of the
    rows at 1.2-3.5 px per field: read as own colour in >= 36 of 40 draws (38 of 40
    measured, session 20; the two misses, at 1.66 and 1.68 px, read as shared - the
    safe way, sigma wide)."""
    from curltrack.video import field_motion

    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    own = 0
    for i in range(40):
        order = str(rng.choice(["tff", "bff"]))
        speed = rng.uniform(1.2, 3.5)
        a = rng.uniform(-np.pi / 6, np.pi / 6) + np.pi * rng.integers(2)
        _woven_clip(tmp_path / f"{i}.mp4", rng, shift_px=(speed * np.cos(a), speed * np.sin(a)),
                    order=order, colour="field")
        own += field_motion(tmp_path / f"{i}.mp4").colour_per_field
    assert own >= 36, f"seed {seed}: {own}/40 read as own colour"


def test_colour_layout_of_woven_fields_is_read_from_the_content(tmp_path):
    """Interlacing found in a progressive stream: whether each field kept its own 4:2:0
    colour rows (a re-encoding that copied the planes) or shares rows subsampled across
    the woven frame (one that converted the pixel format) is read from how the colour
    planes' rows move; with no colour to see, shared - the reading whose sigma is wider.
    Shared colour is never read as the fields' own, whatever the pan; own colour is read
    as such under pans within 30 deg of the rows in most draws (38 of 40, session 20;
    the slow test holds the rate).  A field's colour rows
    are 4 frame lines apart, and under steeper pans their shift aliases: own colour read
    as shared - the safe way - in 11 of 60 draws over all directions (CI seed 1462948293:
    a pan of 0.79, 1.45 px per field)."""
    from curltrack.video import field_motion

    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    order = str(rng.choice(["tff", "bff"]))
    for colour, steep in (("field", False), ("frame", True)):
        speed = rng.uniform(1.2, 3.5)
        a = (rng.uniform(0, 2 * np.pi) if steep
             else rng.uniform(-np.pi / 6, np.pi / 6) + np.pi * rng.integers(2))
        shift = (speed * np.cos(a), speed * np.sin(a))
        what = f"seed {seed}: {order}, {colour} colour, shift {shift[0]:.2f}, {shift[1]:.2f}"
        _woven_clip(tmp_path / f"{colour}.mp4", rng, shift_px=shift, order=order,
                    colour=colour)
        fm = field_motion(tmp_path / f"{colour}.mp4")
        assert fm.woven and fm.order == order, (what, fm)
        # shared colour is never read as the fields' own; own colour mostly is - a rate,
        # test_own_colour_rate_within_30_degrees (CI seed 2808773033: read as shared,
        # the safe way, at 1.18, -0.40 px per field)
        if colour == "frame":
            assert not fm.colour_per_field, (what, fm)
        info = probe_video(tmp_path / f"{colour}.mp4")
        assert info.colour_per_field is fm.colour_per_field, (what, info)
    _woven_clip(tmp_path / "grey.mp4", rng, shift_px=shift, order=order)
    assert not probe_video(tmp_path / "grey.mp4").colour_per_field, what


def test_millisecond_timestamps_are_read_to_the_frame_rate():
    """Matroska rounds times to 1 ms, which put a constant-rate stream's frames up to
    0.5 ms off theirs (1 mm at 2 m/s).  A constant rate (25-60 fps, frames dropped or
    not, the first frame at 0 or later) is read back exactly, by the decoder ``track``
    uses and by FFmpeg; times that jitter
    by more than the rounding (a phone's variable rate) are kept to the millisecond."""
    import tempfile

    from curltrack.video import iter_frames, probe_video

    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    with tempfile.TemporaryDirectory() as tmp:
        for jitter in (False, True):
            fps = float(rng.choice([25.0, 30000 / 1001, 30.0, 50.0, 60000 / 1001, 60.0]))
            k = np.arange(int(rng.integers(40, 90)))
            k = np.sort(np.unique(np.r_[0, k[rng.random(k.size) > rng.uniform(0, 0.1)]]))
            true = float(rng.choice([0.0, rng.uniform(0, 2)])) + k / fps
            if jitter:
                true = true + rng.choice([-1, 1], k.size) * rng.uniform(1.5e-3, 3e-3, k.size)
            # (Matroska stores the times to the millisecond)
            path = _write_av(Path(tmp) / f"t{int(jitter)}.mkv", k.size, fps, fmt="matroska",
                             size=(64, 48), times_s=true)
            info = probe_video(path)
            what = f"seed {seed}, {fps:.3f} fps, jitter {jitter}: {info.describe()}"
            assert info.time_tick_s == pytest.approx(1e-3) and info.times_on_grid != jitter, what
            for decoder in {info.decoder, "pyav"}:  # (what track reads it with, and FFmpeg)
                t = np.array([f.t for f in iter_frames(path, decoder=decoder)])
                # (every frame read: frames dropped from the grid are not a truncated
                # file's missing end)
                assert t.size == k.size, (what, decoder, t.size)
                err = np.abs(t - (true - true[0]))
                if jitter:  # (each time and the first rounded: 1 ms at most)
                    assert err.max() <= 1e-3 + 1e-9, (what, decoder, err.max())
                else:
                    assert err.max() < 1e-6, (what, decoder, err.max())


def test_a_format_that_keeps_each_fields_colour_says_so():
    """DV, and pixel formats with colour on every line (4:1:1, 4:2:2, 4:4:4), give each
    interlaced field its own colour by construction - the content check, which reads
    4:2:0 planes only, is not asked; 4:2:0 and grey say nothing."""
    av = pytest.importorskip("av")
    from curltrack.video import field_colour_kept

    for codec, fmt, kept in (("h264", "yuv411p", True), ("prores", "yuv422p10le", True),
                             ("h264", "yuv444p", True), ("h264", "yuv420p", False),
                             ("mpeg2video", "nv12", False), ("dvvideo", "yuv420p", True),
                             ("h264", "gray", False)):
        assert bool(field_colour_kept(codec, av.VideoFormat(fmt, 720, 480))) is kept, (codec, fmt)
