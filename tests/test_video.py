"""The frame reader: exact indices and container times, ranges, and clear errors."""

import cv2
import numpy as np
import pytest

from curltrack.errors import VideoError
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


def test_range_errors(clip):
    path, fps, n = clip
    with pytest.raises(VideoError, match="beyond the last frame"):
        list(iter_frames(path, start=n + 5))
    with pytest.raises(VideoError, match="not after"):
        list(iter_frames(path, start=4, end=4))
    with pytest.raises(VideoError, match="out of range"):
        read_frame(path, n)
