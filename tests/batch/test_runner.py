"""Dask machinery with a stand-in per-shot pipeline (no video decoding: fast).

The stand-in "video" is a small JSON file; its pipeline logs every call, so skipping
and redoing are counted exactly.  The real track + fit path is in test_batch_videos.py.
"""

from __future__ import annotations

import json
import socket
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from curltrack.batch import BatchOptions, run_batch
from curltrack.batch.shot import MANIFEST
from curltrack.errors import InputError
from curltrack.rig import default_rig

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE))
from standin import calls, make_folder, standin_pipeline  # noqa: E402


def shot_id(rel: str) -> str:
    return rel.replace("/", "__").removesuffix(".mp4")


@pytest.fixture(scope="module")
def client():
    from curltrack.batch import open_client

    with open_client(workers=2) as c:
        c.run(sys.path.insert, 0, str(HERE))  # workers import the stand-in by name
        yield c


@pytest.mark.parametrize("seed", [1, 2])
def test_batch_records_resumes_and_skips(tmp_path, client, seed):
    rng = np.random.default_rng(seed)
    truth = make_folder(tmp_path / "in", rng)
    out = tmp_path / "out"
    s1 = run_batch(tmp_path / "in", default_rig(), out, client=client,
                   pipeline=standin_pipeline)
    assert (s1.done, s1.skipped, s1.failed) == (len(truth), 0, 1)
    table = pd.read_parquet(out / "campaign.parquet")
    assert sorted(table["file"]) == sorted([*truth, "broken.avi"])
    for _, row in table.iterrows():
        if row["file"] == "broken.avi":
            assert row["status"] == "failed" and "not a video" in row["error"]
            assert row["error_type"] == "TrackingError" and pd.isna(row["lambda_y"])
        else:
            spec = truth[row["file"]]
            assert row["status"] == "done" and row["lambda_y"] == spec["lam"]
            assert row["shot_type"] == spec["shot_type"]
            assert row["track_n_frames"] == spec["n"] and row["warnings"] == "w1; w2"
    csv = pd.read_csv(out / "campaign.csv")
    assert list(csv.columns) == list(table.columns) and len(csv) == len(table)
    n_calls = len(calls(out))
    assert n_calls == len(truth) + 1

    # Second run: everything finished (the broken video too: its failure is an input error).
    s2 = run_batch(tmp_path / "in", default_rig(), out, client=client,
                   pipeline=standin_pipeline)
    assert (s2.done, s2.skipped, s2.failed) == (0, len(truth) + 1, 0)
    assert len(calls(out)) == n_calls
    pd.testing.assert_frame_equal(pd.read_parquet(out / "campaign.parquet"), table)

    # A changed video, a lost manifest (= interrupted mid-shot) and --retry-failed redo work.
    changed = sorted(truth)[0]
    spec = dict(truth[changed], lam=1.01)
    (tmp_path / "in" / changed).write_text(json.dumps(spec))
    lost = sorted(truth)[-1]
    lost_id = shot_id(lost)
    (out / lost_id / MANIFEST).unlink()
    s3 = run_batch(tmp_path / "in", default_rig(), out, client=client,
                   options=BatchOptions(retry_failed=True), pipeline=standin_pipeline)
    assert (s3.done, s3.failed) == (2, 1)
    assert sorted(calls(out)[n_calls:]) == sorted(["broken", shot_id(changed), lost_id])
    t3 = pd.read_parquet(out / "campaign.parquet").set_index("file")
    assert t3.loc[changed, "lambda_y"] == 1.01


def test_internal_error_is_recorded_and_retried(tmp_path, client):
    (tmp_path / "in").mkdir()
    (tmp_path / "in" / "a.mp4").write_text(json.dumps({"crash": True}))
    out = tmp_path / "out"
    for _ in range(2):
        s = run_batch(tmp_path / "in", default_rig(), out, client=client,
                      pipeline=standin_pipeline)
        assert s.failed == 1 and "ZeroDivisionError" in s.records[0]["error"]
    assert len(calls(out)) == 2  # an internal error is not taken as a finished shot
    assert not (out / "a" / "FIT.json").exists()


def test_shots_csv_metadata_joined(tmp_path, client):
    rng = np.random.default_rng(3)
    truth = make_folder(tmp_path / "in", rng, n=3)
    (tmp_path / "in" / "shots.csv").write_text(
        "file,Ice Surface,date,thrower,notes\n"
        "v0.mp4,pebbled,2003-01-02,A,\n"
        "s2/v1.mp4,flooded,2003-01-03,B,\"swept, once\"\n"
        "missing.mp4,pebbled,2003-01-04,C,not in the folder\n")
    out = tmp_path / "out"
    s = run_batch(tmp_path / "in", default_rig(), out, client=client,
                  pipeline=standin_pipeline, report=True)
    assert s.report_path == out / "report.html" and "3 fitted, 1 failed" in s.report_path.read_text()
    t = pd.read_parquet(out / "campaign.parquet").set_index("file")
    assert t.loc["v0.mp4", "ice_surface"] == "pebbled"
    assert t.loc["s2/v1.mp4", "ice_surface"] == "flooded"
    assert t.loc["s2/v1.mp4", "notes"] == "swept, once"
    assert pd.isna(t.loc["v2.mp4", "ice_surface"]) and len(truth) == 3


@pytest.mark.parametrize("text, where", [
    ("name,date\na.mp4,x\n", "header"),
    ("file,date\na.mp4,x\na.mp4,y\n", "row 3"),
    ("file,date\n,x\n", "row 2"),
])
def test_bad_shots_csv_is_one_clear_error(tmp_path, text, where):
    (tmp_path / "a.mp4").write_text("{}")
    (tmp_path / "shots.csv").write_text(text)
    with pytest.raises(InputError, match="shots.csv") as err:
        run_batch(tmp_path, default_rig(), tmp_path / "out", client=object())
    assert where in str(err.value)


def test_empty_folder_and_missing_folder(tmp_path):
    with pytest.raises(InputError, match="no videos"):
        run_batch(tmp_path, default_rig(), tmp_path / "out", client=object())
    with pytest.raises(InputError, match="not a folder"):
        run_batch(tmp_path / "nope", default_rig(), tmp_path / "out", client=object())


def test_unreachable_scheduler_is_one_clear_error():
    from curltrack.batch import open_client

    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(InputError, match="cannot connect"):
        with open_client(scheduler=f"tcp://127.0.0.1:{port}", timeout_s=1):
            pass


def test_cli_all_failed_exits_1_with_one_line(tmp_path):
    from typer.testing import CliRunner

    from curltrack.cli import app

    (tmp_path / "in").mkdir()
    (tmp_path / "in" / "a.mp4").write_text("not a video")
    (tmp_path / "rig.toml").write_text(default_rig().to_toml())
    r = CliRunner().invoke(app, ["batch", str(tmp_path / "in"), "--rig",
                                 str(tmp_path / "rig.toml"), "-o", str(tmp_path / "out"),
                                 "--workers", "1"])
    assert r.exit_code == 1
    assert "0 done, 0 skipped (already done), 1 failed" in r.output
    assert r.output.strip().splitlines()[-1].startswith("curltrack: error: all 1 shot(s) failed")
    assert "Traceback" not in r.output
    assert pd.read_csv(tmp_path / "out" / "campaign.csv")["status"].tolist() == ["failed"]
    assert (tmp_path / "out" / "report.html").exists()  # campaign plots by default


def test_metadata_rows_per_split_shot(tmp_path):
    from curltrack.batch.table import build_table, read_shot_metadata

    (tmp_path / "shots.csv").write_text("file,shot,thrower\nsess.mp4,,Anna\n"
                                        "sess.mp4,2,Ben\nsub/other.mp4,,Cy\n")
    meta = read_shot_metadata(tmp_path)
    recs = [{"shot": {"shot_id": f"sess__shot0{i}", "file": "sess.mp4", "shot_index": i},
             "status": "done", "fit": {"v0": 0.1 * i}} for i in (1, 2, 3)]
    recs.append({"shot": {"shot_id": "sub__other", "file": "sub/other.mp4"},
                 "status": "failed", "error": "x"})
    t = build_table(recs, meta).set_index("shot_id")
    assert t["thrower"].to_dict() == {"sess__shot01": "Anna", "sess__shot02": "Ben",
                                      "sess__shot03": "Anna", "sub__other": "Cy"}
    assert t.loc["sess__shot02", "v0"] == pytest.approx(0.2)
