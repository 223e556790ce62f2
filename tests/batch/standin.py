"""A stand-in for the per-shot pipeline, importable by Dask workers by name.

The stand-in "video" is a small JSON file (``shot_type``, ``lam``, ``n``); its pipeline
logs every call to ``OUTDIR/calls.log``, so skipping and redoing are counted exactly.
"""

from __future__ import annotations

import json
from pathlib import Path

from curltrack._atomic import write_json
from curltrack.errors import TrackingError


def standin_pipeline(job, rig, shot_dir, options):
    """Read the 'video' (JSON), log the call, write FIT.json; raise for bad input."""
    with open(Path(shot_dir).parent / "calls.log", "a") as fh:
        fh.write(job.shot_id + "\n")
    try:
        spec = json.loads(Path(job.video).read_text())
    except ValueError:
        raise TrackingError("not a video", path=job.video, where="frame 0") from None
    if spec.get("crash"):
        raise ZeroDivisionError("bug")
    fit = {"shot_type": spec["shot_type"], "lambda_y": spec["lam"],
           "lambda_y_err": 0.01, "warnings": ["w1", "w2"]}
    write_json(Path(shot_dir) / "FIT.json", fit)
    return {"fit": fit, "quality": {"n_frames": spec["n"], "frac_measured": 1.0}}


def make_folder(root: Path, rng, n=5) -> dict:
    """``n`` stand-in videos (some in a sub-folder), a broken one and a non-video file."""
    root.mkdir()
    truth = {}
    for i in range(n):
        spec = {"shot_type": str(rng.choice(["draw", "rrss", "pure_rotation"])),
                "lam": float(rng.uniform(1.4, 2.3)), "n": int(rng.integers(30, 300))}
        sub = root / ("s2" if i % 2 else "")
        sub.mkdir(exist_ok=True)
        (sub / f"v{i}.mp4").write_text(json.dumps(spec))
        truth[f"v{i}.mp4" if i % 2 == 0 else f"s2/v{i}.mp4"] = spec
    (root / "broken.avi").write_text("garbage")
    (root / "notes.txt").write_text("not a video")
    return truth


def calls(out: Path) -> list[str]:
    """Shot ids the stand-in pipeline was called for, in order."""
    log = out / "calls.log"
    return log.read_text().split() if log.exists() else []
