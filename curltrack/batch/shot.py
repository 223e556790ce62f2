"""One shot, start to finish, on a worker: the task every batch is made of.

:func:`process_shot` never raises for a bad shot: it returns a *record* (a JSON-ready
dict) with ``status`` ``"done"`` or ``"failed"`` and, for failures, the one-line error.
The record is also written, atomically and last, to ``OUTDIR/<shot_id>/DONE.json`` (the
done-manifest) with the shot's key; a later run that finds the same key skips the shot.
A shot is therefore either finished (all outputs + manifest) or it is redone: killing a
batch at any moment loses at most the shots that were running.

Failures of the input (a :class:`~curltrack.errors.CurltrackError`: a broken video, a
rock that cannot be followed) are deterministic, so they are skipped on re-runs too
(``retry_failed`` forces them); internal errors are retried.
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import time
import traceback
from pathlib import Path

from .._atomic import write_json
from ..errors import CurltrackError
from .jobs import BatchOptions, ShotJob, file_digest, job_key

MANIFEST = "DONE.json"
#: Per-shot outputs (contract names); removed before a shot is redone.
OUTPUTS = ("SHOT.csv", "SHOT.json", "FIT.json", "REPORT.json", "FIT.png")

#: Environment variables that cap the thread pools of BLAS/OpenMP libraries.
THREAD_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
              "NUMEXPR_NUM_THREADS": "1", "VECLIB_MAXIMUM_THREADS": "1"}


def limit_threads() -> None:
    """One compute thread per worker: OpenCV, BLAS and OpenMP pools set to 1.

    Workers share the machine's cores; each library's own pool would otherwise start one
    thread per core in every worker and the workers would fight over the cores.  Env
    variables only act on libraries loaded later, so the pools already loaded are capped
    directly (OpenCV; BLAS through ``threadpoolctl`` when it is installed).
    """
    os.environ.update(THREAD_ENV)
    import cv2

    cv2.setNumThreads(1)
    with contextlib.suppress(ImportError):
        from threadpoolctl import threadpool_limits

        threadpool_limits(1)


def read_manifest(shot_dir) -> dict | None:
    """The done-manifest of a shot folder, or None (missing or unreadable)."""
    try:
        data = json.loads((Path(shot_dir) / MANIFEST).read_text())
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def _finished(manifest: dict | None, key: str, options: BatchOptions) -> bool:
    if not manifest or manifest.get("key") != key:
        return False
    status = manifest.get("record", {}).get("status")
    return status == "done" or (status == "failed" and not manifest.get("retry", True)
                                and not options.retry_failed)


def process_shot(job: ShotJob, rig, rig_text: str, outdir, options: BatchOptions,
                 pipeline=None) -> dict:
    """Track, fit (and optionally discover) one shot unless it is already finished.

    Parameters
    ----------
    job : ShotJob
        The shot.
    rig : Rig
        The recording set-up.
    rig_text : str
        The rig's canonical text (part of the shot's key).
    outdir : path
        Batch output folder; the shot's files go to ``outdir/<shot_id>/``.
    options : BatchOptions
        Processing options.
    pipeline : callable, optional
        ``pipeline(job, rig, shot_dir, options) -> dict`` doing the work and returning
        the record's result fields; default :func:`curltrack.batch.pipeline.track_and_fit`.

    Returns
    -------
    dict
        The shot's record (see :mod:`curltrack.batch.table`), with ``outcome`` =
        ``"done"``, ``"failed"`` or ``"skipped"`` (finished by an earlier run).
    """
    limit_threads()
    t0, c0 = time.perf_counter(), time.process_time()
    shot_dir = Path(outdir) / job.shot_id
    record = {"shot": job.to_dict(), "status": None, "error": None, "error_type": None}
    manifest = read_manifest(shot_dir)
    try:
        digest = file_digest(job.video, cached=(manifest or {}).get("input"))
    except CurltrackError as exc:
        record.update(status="failed", error=str(exc), error_type=type(exc).__name__,
                      outcome="failed")
        return record
    key = job_key(job, digest.sha256, rig_text, options)
    if _finished(manifest, key, options):
        return dict(manifest["record"], outcome="skipped")

    _clear(shot_dir)
    retry = False
    trace = None
    try:
        if pipeline is None:
            from .pipeline import track_and_fit as pipeline
        record.update(pipeline(job, rig, shot_dir, options))
        record["status"] = "done"
    except CurltrackError as exc:
        record.update(status="failed", error=str(exc), error_type=type(exc).__name__)
    except Exception as exc:  # an internal bug: keep going, record it, retry next run
        retry = True
        trace = traceback.format_exc()
        msg = f"internal error ({type(exc).__name__}: {exc})".replace("\n", " ")
        record.update(status="failed", error=msg, error_type=type(exc).__name__)
    if record["status"] == "failed":
        _clear(shot_dir)
    record.update(version=_version(), input_sha256=digest.sha256,
                  elapsed_s=round(time.perf_counter() - t0, 3),
                  cpu_s=round(time.process_time() - c0, 3),
                  worker=f"{socket.gethostname()}:{os.getpid()}")
    write_json(shot_dir / MANIFEST, {"key": key, "retry": retry, "input": digest.__dict__,
                                     "record": record, "traceback": trace})
    return dict(record, outcome=record["status"])


def _version() -> str:
    from .. import __version__

    return __version__


def _clear(shot_dir: Path) -> None:
    """Remove a shot's manifest first (it is not finished any more), then its outputs."""
    for name in (MANIFEST, *OUTPUTS):
        with contextlib.suppress(FileNotFoundError):
            (shot_dir / name).unlink()
