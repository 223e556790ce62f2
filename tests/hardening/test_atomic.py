"""Nothing lost: a killed run never leaves a half file under a final name."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from curltrack.series import read_series
from curltrack.video import probe_video
from hardening.badinputs import render_clip


@pytest.fixture(scope="module")
def long_clip(hdir):
    return render_clip(hdir / "long.mp4", v0=1.1, seed=21, tail_s=0.5)


def _start(args, cwd):
    return subprocess.Popen([sys.executable, "-m", "curltrack", *map(str, args)], cwd=cwd,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            start_new_session=True)


def _kill(proc):
    with pytest.raises(ProcessLookupError):
        while True:  # the group: the command and anything it started
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=30)
            os.killpg(proc.pid, 0)


def _wait_for(pattern_dir: Path, pattern: str, proc, timeout=120.0):
    t0 = time.time()
    while time.time() - t0 < timeout:
        hits = [p for p in pattern_dir.glob(pattern) if p.stat().st_size > 0]
        if hits:
            return hits
        if proc.poll() is not None:
            return []
        time.sleep(0.005)
    return []


def test_track_killed_while_writing_keeps_old_outputs(hdir, rig_file, long_clip):
    """SIGKILL while the overlay is being written: the previous outputs stay intact."""
    video = long_clip[0]
    d = hdir / "killed"
    d.mkdir()
    old = {d / "SHOT.csv": "old csv\n", d / "SHOT.json": "{\"old\": true}\n",
           d / "over.mp4": "old overlay\n"}
    for p, text in old.items():
        p.write_text(text)
    proc = _start(["track", video, "--rig", rig_file, "-o", d / "SHOT.csv", "--overlay",
                   d / "over.mp4", "--no-progress"], d)
    hits = _wait_for(d, ".over.*.mp4", proc)
    if not hits:
        pytest.fail(f"the overlay was never being written ({proc.stderr.read()!r})")
    _kill(proc)
    for p, text in old.items():
        assert p.read_text() == text, f"{p.name} changed by a killed run"
    # a re-run completes and replaces them with whole files
    res = subprocess.run([sys.executable, "-m", "curltrack", "track", str(video), "--rig",
                          str(rig_file), "-o", str(d / "SHOT.csv"), "--overlay",
                          str(d / "over.mp4"), "-q"], capture_output=True, text=True,
                         timeout=300)
    assert res.returncode == 0, res.stderr
    s = read_series(d / "SHOT.csv")
    assert len(s.data) == probe_video(video).n_frames
    assert probe_video(d / "over.mp4").n_frames == len(s.data)


@pytest.mark.parametrize("seed", [0])
def test_track_killed_at_a_random_moment(hdir, rig_file, long_clip, seed):
    """Whatever the moment, each final name is absent or a whole, valid file."""
    video = long_clip[0]
    d = hdir / f"random_kill{seed}"
    d.mkdir()
    proc = _start(["track", video, "--rig", rig_file, "-o", d / "SHOT.csv", "--overlay",
                   d / "over.mp4", "--no-progress"], d)
    time.sleep(np.random.default_rng(seed).uniform(0.5, 4.0))
    _kill(proc)
    if (d / "SHOT.csv").exists():
        read_series(d / "SHOT.csv")
    if (d / "SHOT.json").exists():
        import json

        json.loads((d / "SHOT.json").read_text())
    if (d / "over.mp4").exists():
        probe_video(d / "over.mp4")


@pytest.mark.slow
def test_batch_killed_and_restarted_gives_identical_results(hdir, rig_file, tmp_path):
    """A real batch (3 tiny videos, 1 worker) killed after its first shot, then re-run."""
    vids = tmp_path / "videos"
    vids.mkdir()
    for i in range(3):
        render_clip(vids / f"shot{i}.mp4", v0=0.5 + 0.1 * i, seed=30 + i)
        for extra in vids.glob(f"shot{i}.*"):
            if extra.suffix != ".mp4":
                extra.unlink()
    ref = tmp_path / "ref"
    cmd = ["batch", vids, "--rig", rig_file, "--workers", "1", "-q"]
    res = subprocess.run([sys.executable, "-m", "curltrack", *map(str, cmd), "-o", str(ref)],
                         capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    out = tmp_path / "out"
    proc = _start([*cmd, "-o", out], tmp_path)
    assert _wait_for(out, "*/FIT.json", proc, timeout=300), "no shot finished"
    _kill(proc)
    res = subprocess.run([sys.executable, "-m", "curltrack", *map(str, cmd), "-o", str(out)],
                         capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    a = pd.read_parquet(ref / "campaign.parquet").sort_values("file").reset_index(drop=True)
    b = pd.read_parquet(out / "campaign.parquet").sort_values("file").reset_index(drop=True)
    # time taken and which process did it: not results
    skip = [c for c in a.columns if c in ("elapsed_s", "cpu_s", "worker")
            or any(k in c for k in ("wall", "host", "cpu_time"))]
    pd.testing.assert_frame_equal(a.drop(columns=skip), b.drop(columns=skip))
    assert (b["status"] == "done").all()
    for shot in a["shot_id"]:
        pd.testing.assert_frame_equal(pd.read_csv(ref / shot / "SHOT.csv"),
                                      pd.read_csv(out / shot / "SHOT.csv"))
