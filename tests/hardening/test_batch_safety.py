"""Batch safety: unique shot ids, one batch per output folder, schedulers that do not
speak Dask."""

from __future__ import annotations

import json
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from curltrack.batch import run_batch
from curltrack.batch.jobs import plan_jobs, video_ids
from curltrack.batch.runner import LOCK_NAME, folder_lock
from curltrack.errors import InputError
from curltrack.rig import default_rig

HERE = Path(__file__).parent.parent / "batch"


def test_names_mapping_to_one_id_get_unique_ids(tmp_path):
    """``s1/a b.mp4`` and ``s1/a_b.mp4`` (and ``A_B.mp4``, for case-insensitive file
    systems) once became one shot; ids are unique, stable, and the table says why."""
    rng = np.random.default_rng(int(np.random.SeedSequence().entropy % 2**32))
    names = ["s1/a b.mp4", "s1/a_b.mp4", "s1/a__b.mp4", "s1/A_B.mp4", "s1/a+b.mp4",
             "s1/a_b.avi", "s2/x.mp4", "s1__a_b.mp4"]
    rng.shuffle(names)
    for n in names:
        (tmp_path / n).parent.mkdir(exist_ok=True)
        (tmp_path / n).write_text("x")
    jobs = plan_jobs(tmp_path)
    ids = [j.shot_id.lower() for j in jobs]
    assert len(set(ids)) == len(jobs) == len(names), (names, ids)
    assert {j.shot_id for j in plan_jobs(tmp_path)} == {j.shot_id for j in jobs}  # stable
    by_file = {j.file: j for j in jobs}
    assert by_file["s2/x.mp4"].shot_id == "s2__x" and by_file["s2/x.mp4"].id_note is None
    assert "s1/a_b.mp4" in by_file["s1/a b.mp4"].id_note
    # more colliding names than any fixed suffix list would cover
    many = [Path(tmp_path / f"m{'_' * k}.mp4") for k in range(1, 4)] + \
        [Path(tmp_path / f"m{' ' * k}.mp4") for k in range(1, 4)]
    assert len(set(video_ids(tmp_path, many).values())) == len(many)


def test_colliding_names_are_two_shots_in_the_table(tmp_path):
    sys.path.insert(0, str(HERE))
    from standin import standin_pipeline

    from curltrack.batch import open_client

    src = tmp_path / "in"
    (src / "s1").mkdir(parents=True)
    for name, lam in (("a b.mp4", 1.5), ("a_b.mp4", 2.1)):
        (src / "s1" / name).write_text(json.dumps({"shot_type": "draw", "lam": lam,
                                                   "n": 50}))
    out = tmp_path / "out"
    with open_client(workers=1) as c:
        c.run(sys.path.insert, 0, str(HERE))
        s = run_batch(src, default_rig(), out, client=c, pipeline=standin_pipeline)
    assert s.done == 2
    table = pd.read_csv(out / "campaign.csv")
    assert sorted(table["file"]) == ["s1/a b.mp4", "s1/a_b.mp4"]
    assert table["shot_id"].nunique() == 2
    assert table["shot_id_note"].notna().all()
    lam = dict(zip(table["file"], table["lambda_y"]))
    assert lam == {"s1/a b.mp4": 1.5, "s1/a_b.mp4": 2.1}


def test_second_batch_into_one_folder_is_refused(cli, tmp_path):
    """A lock held by another process (here: a child holding it): refused, with who."""
    out = tmp_path / "out"
    out.mkdir()
    holder = subprocess.Popen(
        [sys.executable, "-c", "import sys, time; from curltrack.batch.runner import "
         "folder_lock\nwith folder_lock(sys.argv[1]):\n print('held', flush=True); "
         "time.sleep(60)", str(out)], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        src = tmp_path / "in"
        src.mkdir()
        (src / "v.mp4").write_text("x")
        rig = tmp_path / "rig.toml"
        rig.write_text(default_rig().to_toml())
        line = cli.fails("batch", src, "--rig", rig, "-o", out, "--workers", "1", "-q",
                         names=[out, "another batch", f"pid {holder.pid}"])
        assert "choose another -o" in line
        assert not (out / "campaign.csv").exists()
    finally:
        holder.kill()
        holder.wait()
    with folder_lock(out):  # released when its holder died (even by SIGKILL)
        assert (out / LOCK_NAME).exists()


def test_lock_is_held_in_process_too(tmp_path):
    with folder_lock(tmp_path):
        with pytest.raises(InputError, match="another batch"):
            with folder_lock(tmp_path):
                pass


class _FakeServer:
    """A TCP port that accepts and then says nothing, or sends garbage."""

    def __init__(self, mode: str):
        self.srv = socket.socket()
        self.srv.bind(("127.0.0.1", 0))
        self.srv.listen(8)
        self.port = self.srv.getsockname()[1]
        self.mode, self.conns = mode, []
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self):
        while True:
            try:
                c, _ = self.srv.accept()
            except OSError:
                return
            self.conns.append(c)
            if self.mode == "garbage":
                rng = np.random.default_rng(len(self.conns))
                try:
                    c.sendall(b"HTTP/1.1 200 OK\r\n\r\n" + rng.bytes(4096))
                except OSError:
                    pass

    def close(self):
        for c in self.conns:
            c.close()
        self.srv.close()


@pytest.mark.parametrize("mode,cause", [("silent", "did not answer"),
                                        ("garbage", "not the Dask protocol")])
def test_scheduler_that_does_not_speak_dask(cli, tmp_path, mode, cause):
    srv = _FakeServer(mode)
    try:
        src = tmp_path / "in"
        src.mkdir()
        (src / "v.mp4").write_text("x")
        rig = tmp_path / "rig.toml"
        rig.write_text(default_rig().to_toml())
        t0 = time.perf_counter()
        line = cli.fails("batch", src, "--rig", rig, "-o", tmp_path / "out", "-q",
                         "--scheduler", f"tcp://127.0.0.1:{srv.port}",
                         "--scheduler-timeout", "2",
                         names=[f"tcp://127.0.0.1:{srv.port}", cause])
        assert time.perf_counter() - t0 < 20, line
        assert "out of memory" not in line
    finally:
        srv.close()
