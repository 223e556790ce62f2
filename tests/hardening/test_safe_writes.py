"""Outputs that are safe: only regular files replaced, videos checked before the rename,
disk-full named, temporary files removed on SIGTERM and cleaned by the next run.

Special files are made inside the test's temporary folder (a FIFO, or as root a device
node); nothing here touches a system path.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from curltrack.physics.shot import ShotModel
from curltrack.series import write_series
from curltrack.simulate import simulate_series
from curltrack.video import probe_video
from hardening.badinputs import render_clip

#: a short draw at 320x180: ~1.5 s of video
FAST_RENDER = ("--v0", "0.4", "--omega0", "1.5", "--width", "320", "--height", "180",
               "--blur-subframes", "1", "--stopped-tail-s", "0.2", "--quiet")
root_only = pytest.mark.skipif(os.geteuid() != 0, reason="needs root (mknod / mount)")


@pytest.fixture(scope="module")
def shot_csv(hdir) -> Path:
    p = hdir / "safe_shot.csv"
    write_series(p, simulate_series(ShotModel(v0=1.2, omega0=1.5), fps=30, noise_m=0.001,
                                    noise_rad=0.003, seed=5))
    return p


def _special(tmp_path: Path, kind: str) -> Path:
    p = tmp_path / f"special_{kind}"
    if kind == "fifo":
        os.mkfifo(p)
    else:  # a character device with /dev/null's numbers, but inside tmp_path
        os.mknod(p, 0o666 | stat.S_IFCHR, os.makedev(1, 3))
    return p


def _unchanged(p: Path, kind: str) -> None:
    mode = os.lstat(p).st_mode
    assert (stat.S_ISFIFO(mode) if kind == "fifo" else stat.S_ISCHR(mode)), \
        f"{p} was replaced by a {stat.filemode(mode)}"


@pytest.mark.parametrize("kind", ["fifo", pytest.param("device", marks=root_only)])
def test_fit_refuses_to_replace_a_special_file(cli, tmp_path, shot_csv, kind):
    out = _special(tmp_path, kind)
    line = cli.fails("fit", shot_csv, "-o", out, names=[out, "not a regular file"])
    assert ("FIFO" if kind == "fifo" else "character device") in line
    _unchanged(out, kind)
    assert not list(tmp_path.glob(f".{out.stem}.*"))


@pytest.mark.parametrize("kind", ["fifo", pytest.param("device", marks=root_only)])
def test_track_refuses_special_outputs_before_any_work(cli, tmp_path, rig_file, good_clip,
                                                      kind):
    """-o, its sidecar and --overlay: refused before the video is opened (fast)."""
    dev = _special(tmp_path, kind)
    t0 = time.perf_counter()
    cli.fails("track", good_clip[0], "--rig", rig_file, "-o", dev, names=[dev])
    cli.fails("track", good_clip[0], "--rig", rig_file, "-o", tmp_path / "a.csv",
              "--overlay", dev, names=[dev, "--overlay"], output=tmp_path / "a.csv")
    side = tmp_path / "b.json"
    os.rename(dev, side)
    cli.fails("track", good_clip[0], "--rig", rig_file, "-o", tmp_path / "b.csv",
              names=[side], output=tmp_path / "b.csv")
    assert time.perf_counter() - t0 < 10.0
    _unchanged(side, kind)
    assert not (tmp_path / "b.json.json").exists() and not (tmp_path / "special.json").exists()


def test_symlink_loop_is_named(cli, tmp_path, shot_csv):
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    a.symlink_to(b)
    b.symlink_to(a)
    cli.fails("fit", shot_csv, "-o", a, names=[a, "symbolic link loop"])


def test_disk_full_while_writing_json_names_the_file(cli, tmp_path, shot_csv, monkeypatch):
    """ENOSPC simulated (any user): one line naming FIT.json, no file under the name."""
    real = Path.write_text

    def full(self, *a, **k):
        if self.name.startswith(".FIT."):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real(self, *a, **k)

    monkeypatch.setattr(Path, "write_text", full)
    out = tmp_path / "FIT.json"
    cli.fails("fit", shot_csv, "-o", out, output=out, names=[out, "disk full"])


class _DroppingWriter:
    """A cv2.VideoWriter that silently stops writing after ``keep`` frames (what OpenCV
    does when the disk fills: a WARN on stderr, no error)."""

    keep = 10

    def __init__(self, *args):
        import cv2

        self._w = _REAL_WRITER(*args)
        self._n = 0
        del cv2

    def isOpened(self):
        return self._w.isOpened()

    def write(self, img):
        self._n += 1
        if self._n <= self.keep:
            self._w.write(img)

    def release(self):
        self._w.release()


_REAL_WRITER = None


@pytest.fixture
def dropping_writer(monkeypatch):
    global _REAL_WRITER
    import cv2

    _REAL_WRITER = cv2.VideoWriter
    monkeypatch.setattr(cv2, "VideoWriter", _DroppingWriter)


def test_truncated_overlay_never_replaces_a_good_one(cli, tmp_path, rig_file, good_clip,
                                                     monkeypatch):
    from curltrack.track import overlay  # the overlay is H.264 through PyAV, not cv2

    real = overlay._encode

    def dropping(path, frames, *args, **kw):  # an encoder that silently drops frames
        seen = []

        def keep():
            for i, fr in enumerate(frames):
                seen.append(i)
                if i < _DroppingWriter.keep:
                    yield fr

        real(path, keep(), *args, **kw)
        return len(seen)

    monkeypatch.setattr(overlay, "_encode", dropping)
    ov = tmp_path / "ov.mp4"
    ov.write_bytes(b"a good overlay\n")
    out = tmp_path / "s.csv"
    cli.fails("track", good_clip[0], "--rig", rig_file, "-o", out, "--overlay", ov,
              names=[ov, "could not be written completely"])
    assert ov.read_bytes() == b"a good overlay\n"
    assert not list(tmp_path.glob(".ov.*"))


def test_truncated_render_is_refused(cli, tmp_path, rig_file, dropping_writer):
    out = tmp_path / "r.mp4"
    cli.fails("render", *FAST_RENDER, "--rig", rig_file, "-o", out, output=out,
              names=[out, "could not be written completely"])


@contextlib.contextmanager
def _tiny_fs(path: Path, size: str):
    path.mkdir()
    res = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(path)],
                         capture_output=True, text=True)
    if res.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs: {res.stderr.strip()}")
    try:
        yield path
    finally:
        subprocess.run(["umount", str(path)], check=True)


@root_only
def test_disk_full_on_a_real_tiny_filesystem(cli, tmp_path, rig_file, good_clip, shot_csv):
    """A 64 kB tmpfs: render, overlay and CSV each fail with one line naming the file."""
    with _tiny_fs(tmp_path / "fs", "64k") as fs:
        r = fs / "r.mp4"
        cli.fails("render", *FAST_RENDER, "--rig", rig_file, "-o", r, output=r, names=[r])
        ov = fs / "ov.mp4"
        ov.write_bytes(b"old\n")
        cli.fails("track", good_clip[0], "--rig", rig_file, "-o", tmp_path / "s.csv",
                  "--overlay", ov, names=[ov])
        assert ov.read_bytes() == b"old\n"
        (fs / "filler").write_bytes(b"\0" * (fs.stat().st_size * 0 + 60_000))
        big = fs / "big.csv"
        cli.fails("simulate", "--v0", "1.4", "--omega0", "1.5", "-o", big, output=big,
                  names=[big, "disk full"])
        assert not [p for p in fs.iterdir() if p.name.startswith(".")]


def _start(args, cwd):
    # default SIGINT in the child: a pytest-xdist worker ignores SIGINT, and an ignored
    # signal is inherited (Python then installs no KeyboardInterrupt handler)
    return subprocess.Popen([sys.executable, "-m", "curltrack", *map(str, args)], cwd=cwd,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def _wait_for_temp(d: Path, pattern: str, proc, timeout=120.0, min_size=1):
    t0 = time.time()
    while time.time() - t0 < timeout and proc.poll() is None:
        if any(p.stat().st_size >= min_size for p in d.glob(pattern)):
            return True
        time.sleep(0.005)
    return False


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_signal_removes_temporary_files(tmp_path, rig_file, good_clip, sig):
    d = tmp_path
    (d / "ov.mp4").write_text("old\n")
    proc = _start(["track", good_clip[0], "--rig", rig_file, "-o", d / "s.csv",
                   "--overlay", d / "ov.mp4", "--no-progress"], d)
    # (the H.264 muxer buffers: a short overlay's temp file is empty until it is closed)
    if not _wait_for_temp(d, ".ov.*.mp4", proc, min_size=0):
        pytest.skip("the run ended before its overlay was being written")
    os.kill(proc.pid, sig)
    rc = proc.wait(timeout=60)
    if rc == 0:
        # (the temp file lives until the run's last step: a run can end between our
        # seeing it and the signal - CI saw it once)
        assert (d / "ov.mp4").read_bytes() != b"old\n"
        assert not [p.name for p in d.iterdir() if p.name.startswith(".")]
        pytest.skip("the run ended before the signal reached it")
    assert (d / "ov.mp4").read_text() == "old\n"
    left = [p.name for p in d.iterdir() if p.name.startswith(".")]
    if left and rc in (-signal.SIGSEGV, -signal.SIGABRT):
        # FFmpeg crashing on the signal inside an encoder (about 1 run in 150-200,
        # _atomic.signals_after): no clean-up can run in a crashed process; what is
        # promised then is that the next run of that output removes what it left
        from curltrack._atomic import clean_stale

        clean_stale(d / "ov.mp4")
        left = [p.name for p in d.iterdir() if p.name.startswith(".")]
        assert not left, f"temporary files left after a crash on {sig.name}: {left}"
        return
    assert not left, f"temporary files left after {sig.name} (exit {rc}): {left}"


def test_stale_temporary_files_are_cleaned_by_the_next_run(cli, tmp_path, shot_csv):
    """A run killed with SIGKILL (uncatchable) leaves its temp file; the next run of that
    output removes it — and leaves a live process's temp file alone."""
    dead = subprocess.Popen(["true"])
    dead.wait()
    stale = tmp_path / f".FIT.{dead.pid}.abcd1234.json"
    stale.write_text("half")
    live = tmp_path / f".FIT.{os.getppid()}.efgh5678.json"
    live.write_text("being written by a running process")
    out = tmp_path / "FIT.json"
    cli.succeeds("fit", shot_csv, "-o", out)
    assert json.loads(out.read_text())["lambda_theta"] > 0
    assert not stale.exists()
    assert live.exists()


# --------------------------------------------------------------------------------------
# time from the container


@pytest.fixture(scope="module")
def clip60(hdir):
    return render_clip(hdir / "c60.mp4", fps=60, seed=61, v0=0.5)


def _rig_with(rig_file: Path, tmp_path: Path, extra: str) -> Path:
    p = tmp_path / "rig_fps.toml"
    p.write_text(rig_file.read_text() + extra)
    return p


def test_rig_fps_disagreeing_with_the_container_is_an_error(cli, tmp_path, rig_file, clip60):
    """60 fps video, rig fps = 30: would double every t.  track and doctor refuse."""
    rig = _rig_with(rig_file, tmp_path, "[camera]\nfps = 30\n")
    out = tmp_path / "s.csv"
    line = cli.fails("track", clip60[0], "--rig", rig, "-o", out, output=out,
                     names=["[camera].fps", "30", "60"])
    assert "remove [camera].fps" in line
    res = cli("doctor", clip60[0], "--rig", rig, "--json")
    assert res.exit_code == 1
    data = json.loads(res.stdout)
    assert {c["name"]: c["status"] for c in data["checks"]}["fps"] == "fail"


@pytest.mark.parametrize("rig_fps", [60.0, 59.94])
def test_agreeing_rig_fps_keeps_the_container_times(cli, tmp_path, rig_file, clip60, rig_fps):
    rig = _rig_with(rig_file, tmp_path, f"[camera]\nfps = {rig_fps}\n")
    out = tmp_path / "s.csv"
    cli.succeeds("track", clip60[0], "--rig", rig, "-o", out, "-q")
    import pandas as pd

    t = pd.read_csv(out)["t"].to_numpy()
    truth = clip60[1].data["t"].to_numpy()
    assert np.abs(t - truth[:len(t)]).max() < 1.5e-3, np.abs(t - truth[:len(t)]).max()


def test_render_writes_no_fps_into_its_rig(cli, tmp_path, rig_file):
    out = tmp_path / "r.mp4"
    cli.succeeds("render", *FAST_RENDER, "--rig", rig_file, "-o", out, "--fps", "60")
    assert "fps" not in (tmp_path / "r.rig.toml").read_text()
    assert probe_video(out).fps == pytest.approx(60.0)
