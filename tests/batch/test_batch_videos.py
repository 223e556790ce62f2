"""Batch on rendered short videos: same results as track + fit one by one, a broken video
recorded as failed, an interrupted batch resumed without redoing finished shots, and a
separately started dask scheduler + worker driven by address.

Videos are tiny (640x360, ~2-3 s short draws with spin) and rendered once per module.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from curltrack.cli import app

VENV_BIN = Path(sys.executable).parent
N_GOOD = 3


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """Three rendered shots (random v0, spin of either sign), one truncated video, a rig."""
    from curltrack.physics import ShotModel
    from curltrack.render import RenderConfig, render_video
    from curltrack.rig import default_rig
    from curltrack.simulate import simulate_series

    root = tmp_path_factory.mktemp("season")
    videos = root / "videos"
    videos.mkdir()
    rig = default_rig()
    rig_path = root / "rig.toml"
    rig_path.write_text(rig.to_toml())
    rng = np.random.default_rng(20040101)
    cfg = RenderConfig(width=640, height=360, stopped_tail_s=0.3, blur_subframes=2)
    for i in range(N_GOOD):
        model = ShotModel(v0=float(rng.uniform(0.15, 0.3)),
                          omega0=float(rng.choice([-1, 1]) * rng.uniform(1.5, 4.0)))
        sim = simulate_series(model, fps=30.0, tail_s=0.3)
        render_video(sim, rig, videos / f"shot{i}.mp4", config=cfg, seed=i)
    data = (videos / "shot0.mp4").read_bytes()
    (videos / "zz_truncated.mp4").write_bytes(data[: len(data) // 3])
    (videos / "shots.csv").write_text("file,ice_surface,thrower\nshot0.mp4,pebbled,A\n"
                                      "shot1.mp4,flooded,B\n")
    return root


def _manifests(out: Path) -> dict[str, tuple[int, bytes]]:
    return {p.parent.name: (p.stat().st_mtime_ns, p.read_bytes())
            for p in out.glob("*/DONE.json")}


def _env():
    return dict(os.environ, CURLTRACK_DEBUG="0", PYTHONUNBUFFERED="1")


def test_interrupted_batch_resumes_and_matches_track_fit(folder, tmp_path):
    from curltrack.batch import open_client

    out = tmp_path / "out"
    videos, rig = folder / "videos", folder / "rig.toml"
    # 1. A batch on one worker, interrupted (Ctrl-C) once its first shot is finished.
    proc = subprocess.Popen([str(VENV_BIN / "curltrack"), "batch", str(videos), "--rig",
                             str(rig), "-o", str(out), "--workers", "1", "--quiet"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=_env(),
                            text=True)
    deadline = time.monotonic() + 180
    while not _manifests(out) and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.2)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    before = _manifests(out)
    assert before, f"no shot finished before the interrupt: {err}"
    if len(before) < N_GOOD + 1:  # it was interrupted mid-batch (not already finished)
        assert proc.returncode == 130 and err.strip().endswith("interrupted"), err
    assert not (out / "campaign.parquet").exists() or len(before) == N_GOOD + 1

    # 2. Resumed: finished shots are skipped (manifests untouched), the rest are done.
    with open_client(workers=2) as client:
        _resume_and_compare(client, videos, rig, out, before, tmp_path)


def _resume_and_compare(client, videos, rig, out, before, tmp_path):
    from curltrack.batch import run_batch

    s = run_batch(videos, rig, out, client=client)
    outcomes = {r["shot"]["shot_id"]: r["outcome"] for r in s.records}
    assert {k for k, v in outcomes.items() if v == "skipped"} == set(before)
    assert all(_manifests(out)[k] == before[k] for k in before)
    assert s.total == N_GOOD + 1
    table = pd.read_parquet(out / "campaign.parquet").set_index("shot_id")
    assert table.loc["zz_truncated", "status"] == "failed"
    assert "truncated" in table.loc["zz_truncated", "error"]
    good = table.drop(index="zz_truncated")
    assert (good["status"] == "done").all(), good["error"].to_dict()
    assert table.loc["shot0", "ice_surface"] == "pebbled"
    assert table.loc["shot1", "thrower"] == "B" and pd.isna(table.loc["shot2", "thrower"])

    # 3. The same per-shot results as `curltrack track` + `curltrack fit` one by one.
    cli = CliRunner()
    for i in range(N_GOOD):
        shot_csv = tmp_path / f"s{i}.csv"
        r = cli.invoke(app, ["track", str(videos / f"shot{i}.mp4"), "--rig", str(rig), "-o",
                             str(shot_csv), "--quiet", "--no-progress"])
        assert r.exit_code == 0, r.output
        r = cli.invoke(app, ["fit", str(shot_csv), "--rig", str(rig), "-o",
                             str(tmp_path / f"fit{i}.json"), "--quiet"])
        assert r.exit_code == 0, r.output
        pd.testing.assert_frame_equal(pd.read_csv(out / f"shot{i}" / "SHOT.csv"),
                                      pd.read_csv(shot_csv))
        mine = json.loads((out / f"shot{i}" / "FIT.json").read_text())
        ref = json.loads((tmp_path / f"fit{i}.json").read_text())
        assert mine.keys() == ref.keys()
        for k, v in ref.items():
            if isinstance(v, float):
                assert mine[k] == pytest.approx(v, rel=1e-9, abs=1e-12), k
            else:
                assert mine[k] == v, k
            if k in table.columns and isinstance(v, (int, float)) and v is not None:
                assert table.loc[f"shot{i}", k] == pytest.approx(v, rel=1e-9, abs=1e-12), k
        assert table.loc[f"shot{i}", "track_frac_measured"] > 0.9

    # 4. Run again: nothing left to do; the table is rebuilt identically.
    s2 = run_batch(videos, rig, out, client=client)
    assert (s2.done, s2.skipped, s2.failed) == (0, N_GOOD + 1, 0)
    pd.testing.assert_frame_equal(pd.read_parquet(out / "campaign.parquet").set_index(
        "shot_id"), table)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def scheduler_address():
    """A `dask scheduler` and one `dask worker` started as separate processes."""
    port = _free_port()
    addr = f"tcp://127.0.0.1:{port}"
    dask = str(VENV_BIN / "dask")
    procs = [subprocess.Popen([dask, "scheduler", "--host", "127.0.0.1", "--port", str(port),
                               "--no-dashboard"], stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL, env=_env())]
    try:
        procs.append(subprocess.Popen([dask, "worker", addr, "--nthreads", "1", "--nworkers",
                                       "1", "--no-dashboard"], stdout=subprocess.DEVNULL,
                                      stderr=subprocess.DEVNULL, env=_env()))
        from distributed import Client

        with Client(addr, timeout="60s") as c:
            c.wait_for_workers(1, timeout=60)
        yield addr
    finally:
        for p in reversed(procs):
            p.send_signal(signal.SIGINT)
        for p in reversed(procs):
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


def test_batch_on_a_separately_started_scheduler(folder, tmp_path, scheduler_address):
    from curltrack.rig import default_rig
    from curltrack.track import track_video

    videos = tmp_path / "videos"
    videos.mkdir()
    shutil.copy(folder / "videos" / "shot2.mp4", videos / "remote.mp4")
    (videos / "broken.mp4").write_text("not a video")
    out = tmp_path / "out"
    r = CliRunner().invoke(app, ["batch", str(videos), "--rig", str(folder / "rig.toml"), "-o",
                                 str(out), "--scheduler", scheduler_address, "--quiet"])
    assert r.exit_code == 0, r.output
    table = pd.read_parquet(out / "campaign.parquet").set_index("shot_id")
    assert list(table["status"]) == ["failed", "done"]
    worker_pid = int(table.loc["remote", "worker"].rsplit(":", 1)[1])
    assert worker_pid != os.getpid()  # it ran on the separately started worker
    ref = track_video(videos / "remote.mp4", default_rig())
    got = pd.read_csv(out / "remote" / "SHOT.csv")
    np.testing.assert_allclose(got[["x", "y", "theta"]].to_numpy(),
                               ref.data[["x", "y", "theta"]].to_numpy(), rtol=1e-7,
                               atol=1e-9, equal_nan=True)


@pytest.mark.slow
def test_batch_discover_writes_reports(folder, tmp_path):
    """--discover: REPORT.json per shot; a clean simulated shot has nothing to find."""
    from curltrack.batch import BatchOptions, run_batch

    videos = tmp_path / "videos"
    videos.mkdir()
    shutil.copy(folder / "videos" / "shot0.mp4", videos / "clean.mp4")
    out = tmp_path / "out"
    run_batch(videos, folder / "rig.toml", out, workers=1,
              options=BatchOptions(discover=True))
    report = json.loads((out / "clean" / "REPORT.json").read_text())
    assert report["verdict"] == "none"
    table = pd.read_parquet(out / "campaign.parquet")
    assert table["discover_verdict"].tolist() == ["none"]


def test_batch_progress_counts_frames_from_the_workers(folder, tmp_path, monkeypatch):
    """With progress, the workers report frames tracked; the bar ends at every frame of
    every tracked shot (the videos' own frame counts)."""
    from curltrack.batch import run_batch, runner
    from curltrack.video import probe_video

    videos = tmp_path / "videos"
    videos.mkdir()
    for name in ("shot0.mp4", "shot1.mp4"):
        shutil.copy(folder / "videos" / name, videos / name)
    events = []
    real = runner._Progress.frames

    def spy(self, event):
        events.append(event[1])
        real(self, event)
    monkeypatch.setattr(runner._Progress, "frames", spy)
    bars = []
    real_init = runner._Progress.__init__

    def keep(self, *a, **k):
        real_init(self, *a, **k)
        bars.append(self)
    monkeypatch.setattr(runner._Progress, "__init__", keep)
    s = run_batch(videos, folder / "rig.toml", tmp_path / "out", workers=1, progress=True)
    assert s.done == 2, s.records
    n = {p.stem: probe_video(p).n_frames for p in videos.glob("*.mp4")}
    assert {e["shot"] for e in events} == set(n), events
    for shot, frames in n.items():
        mine = [e for e in events if e["shot"] == shot]
        # (the last report may reach the client after the shot's result: not required)
        assert all(e["total"] == frames and 0 < e["done"] <= frames for e in mine), mine
        assert all(a["done"] <= b["done"] for a, b in zip(mine, mine[1:])), mine
    assert bars[0].shot_frames == {k: (v, v) for k, v in n.items()}
