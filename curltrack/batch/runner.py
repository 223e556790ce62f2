"""Dask orchestration of a batch: one task per shot, on a local or a remote cluster.

The same code path serves both: :func:`open_client` makes a
``dask.distributed.LocalCluster`` (one single-threaded worker process per core) or
connects to an existing scheduler by address; :func:`run_batch` submits one
:func:`~curltrack.batch.shot.process_shot` per shot, follows them with
``distributed.as_completed`` (feeding a progress bar), then writes the campaign table.
Workers need the videos and the output folder at the same paths (one machine, or a
shared file system).
"""

from __future__ import annotations

import contextlib
import logging
import os
import threading
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

from ..errors import CurltrackError, InputError
from ..rig import Rig, load_rig
from .jobs import BatchOptions, ShotJob, plan_jobs, split_jobs
from .shot import THREAD_ENV, process_shot


@dataclass
class BatchSummary:
    """What a batch did.

    Attributes
    ----------
    done, skipped, failed : int
        Shots processed in this run, found finished by an earlier run, failed.
    records : list of dict
        Every shot's record, sorted by ``shot_id``.
    table_path, csv_path : Path
        ``campaign.parquet`` and its ``campaign.csv`` copy.
    report_path : Path or None
        The HTML report (``--report``).
    elapsed_s : float
        Wall time (s).
    """

    done: int = 0
    skipped: int = 0
    failed: int = 0
    records: list = field(default_factory=list)
    table_path: Path | None = None
    csv_path: Path | None = None
    report_path: Path | None = None
    elapsed_s: float = 0.0

    @property
    def total(self) -> int:
        return self.done + self.skipped + self.failed

    def __str__(self) -> str:
        text = (f"{self.total} shot(s): {self.done} done, {self.skipped} skipped "
                f"(already done), {self.failed} failed in {self.elapsed_s:.1f} s")
        fails = [r for r in self.records if r.get("status") == "failed"]
        for r in fails[:10]:
            text += f"\n  failed {r['shot']['shot_id']}: {r.get('error')}"
        if len(fails) > 10:
            text += f"\n  ... and {len(fails) - 10} more (see {self.csv_path})"
        return text


def default_workers() -> int:
    """One worker per core available to this process."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


@contextlib.contextmanager
def open_client(workers: int | None = None, scheduler: str | None = None,
                timeout_s: float = 15.0):
    """A ``distributed.Client``: to ``scheduler`` (an address) or to a new LocalCluster.

    The local cluster has ``workers`` processes (default: one per core) with one thread
    each and BLAS/OpenMP capped at one thread (:data:`~curltrack.batch.shot.THREAD_ENV`),
    so that the workers do not fight over the cores.

    ``timeout_s`` bounds the wait for the scheduler (s).

    Raises
    ------
    InputError
        The scheduler cannot be reached.
    """
    from distributed import Client, LocalCluster

    if scheduler:
        client = _connect(scheduler, timeout_s)
        with client:
            yield client
        return
    if workers is not None and workers < 1:
        raise InputError(f"--workers must be >= 1, got {workers}", where="--workers")
    with LocalCluster(n_workers=workers or default_workers(), threads_per_worker=1,
                      processes=True, silence_logs=logging.ERROR, env=dict(THREAD_ENV),
                      dashboard_address=":0",
                      ) as cluster, Client(cluster) as client:
        yield client


#: The lock file of a batch output folder (held while a batch writes there).
LOCK_NAME = ".curltrack-batch.lock"


@contextlib.contextmanager
def folder_lock(outdir):
    """Hold ``OUTDIR/.curltrack-batch.lock`` (an ``flock``, released when the process
    ends, even when killed): two batches writing one folder would race on its shots
    and its table.

    Raises
    ------
    InputError
        Another batch holds the folder (its PID and start time named).
    """
    import fcntl

    path = Path(outdir) / LOCK_NAME
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as exc:
        raise InputError(f"cannot lock the output folder ({exc.strerror})",
                         path=outdir) from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            holder = os.pread(fd, 200, 0).decode(errors="replace").strip() or "?"
            raise InputError(f"another batch is writing to this folder ({holder}); wait for "
                             "it to finish or choose another -o", path=outdir) from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"pid {os.getpid()}, started "
                      f"{time.strftime('%Y-%m-%d %H:%M:%S')}".encode(), 0)
        yield path
    finally:
        os.close(fd)  # (releases the lock)


def _connect(scheduler: str, timeout_s: float):
    """``Client(scheduler)`` with a hard time limit and a message naming the cause.

    distributed's own ``timeout`` bounds the TCP connection only: a port that accepts
    and never answers (a firewall's tarpit, a stopped process) hangs the handshake for
    minutes, and one that answers in another protocol makes it allocate what the garbage
    announces ("out of memory").
    """
    from distributed import Client

    box: dict = {}

    def attempt():
        try:
            box["client"] = Client(scheduler, timeout=f"{timeout_s}s")
        except BaseException as exc:  # handed to the caller's thread
            box["error"] = exc

    th = threading.Thread(target=attempt, name="curltrack-connect", daemon=True)
    th.start()
    th.join(timeout_s + 2.0)
    if th.is_alive():
        raise InputError(f"the scheduler accepts connections but did not answer within "
                         f"{timeout_s + 2.0:g} s: is a Dask scheduler listening on that port "
                         "(not its dashboard or another service)?", path=scheduler)
    exc = box.get("error")
    if isinstance(exc, (MemoryError, ValueError, TypeError, KeyError)) or (
            exc is not None and type(exc).__module__.startswith(("msgpack", "struct"))):
        raise InputError("the scheduler answered with something that is not the Dask "
                         f"protocol ({type(exc).__name__}): is a Dask scheduler listening on "
                         "that port (not its dashboard or another service)?", path=scheduler)
    if isinstance(exc, (OSError, TimeoutError)):
        raise InputError(f"cannot connect to the Dask scheduler ({exc})".splitlines()[0],
                         path=scheduler)
    if exc is not None:
        raise exc
    return box["client"]


def run_batch(directory, rig, outdir, *, workers: int | None = None,
              scheduler: str | None = None, client=None,
              options: BatchOptions = BatchOptions(), report: bool = False,
              progress: bool = False, pipeline=None,
              scheduler_timeout_s: float = 15.0) -> BatchSummary:
    """Process every video in ``directory`` in parallel and write the campaign table.

    Parameters
    ----------
    directory : path
        Folder of videos (searched recursively); an optional ``shots.csv`` there holds
        per-video metadata joined into the table.
    rig : Rig or path
        The recording set-up (a rig TOML path or a :class:`~curltrack.rig.Rig`).
    outdir : path
        Output folder: ``<shot_id>/`` per shot (``SHOT.csv``, ``SHOT.json``,
        ``FIT.json``, ``DONE.json``), ``campaign.parquet``, ``campaign.csv``.
    workers : int, optional
        Local worker processes (default one per core); ignored with ``scheduler``.
    scheduler : str, optional
        Address of a running ``dask scheduler`` (e.g. ``tcp://host:8786``).
    client : distributed.Client, optional
        Use this client instead of making one.
    options : BatchOptions
        Processing options.
    report : bool
        Also write the campaign plots and ``report.html``.
    progress : bool
        Show a progress bar on stderr.
    pipeline : callable, optional
        Replaces the per-shot work (see :func:`~curltrack.batch.shot.process_shot`).
    scheduler_timeout_s : float
        Longest wait for ``scheduler`` to answer (s).

    Returns
    -------
    BatchSummary

    Raises
    ------
    CurltrackError
        Bad folder, rig or ``shots.csv``, no videos, unreachable scheduler.  A shot that
        fails does not raise: it is recorded and the batch goes on.

    Examples
    --------
    >>> from curltrack import load_rig, run_batch
    >>> summary = run_batch("videos/", load_rig("fixtures/rig.toml"), "campaign/",
    ...                     workers=2)                                      # doctest: +SKIP
    """
    from .table import read_shot_metadata, write_campaign

    t0 = time.perf_counter()
    directory, outdir = Path(directory).resolve(), Path(outdir).resolve()
    rig = rig if isinstance(rig, Rig) else load_rig(rig)
    jobs = plan_jobs(directory)
    if not jobs:
        raise InputError("no videos found in the folder", path=directory)
    metadata = read_shot_metadata(directory)
    outdir.mkdir(parents=True, exist_ok=True)
    with folder_lock(outdir):
        if client is not None:
            records = _run(client, jobs, rig, outdir, options, progress, pipeline)
        else:
            with open_client(workers, scheduler, scheduler_timeout_s) as cl:
                records = _run(cl, jobs, rig, outdir, options, progress, pipeline)
    records.sort(key=lambda r: r["shot"]["shot_id"])
    summary = BatchSummary(records=records)
    for r in records:
        outcome = r.get("outcome", r.get("status"))
        setattr(summary, outcome, getattr(summary, outcome) + 1)
    summary.table_path, summary.csv_path, table = write_campaign(records, metadata, outdir)
    if report:
        from .report import write_report

        summary.report_path = write_report(table, outdir)
    summary.elapsed_s = time.perf_counter() - t0
    return summary


def _run(client, jobs: list[ShotJob], rig: Rig, outdir: Path, options: BatchOptions,
         progress: bool, pipeline) -> list[dict]:
    from distributed import as_completed

    rig_text = rig.to_toml()
    if progress and not options.frame_progress:
        options = replace(options, frame_progress=True)
    pending = {}
    if pipeline is None:  # import the stack on every worker at once, not shot by shot
        from .pipeline import warm_up

        with contextlib.suppress(Exception):
            client.run(warm_up)

    def submit_shot(job):
        fut = client.submit(process_shot, job, rig, rig_text, outdir, options, pipeline,
                            pure=False, key=f"shot-{job.shot_id}-{os.urandom(4).hex()}")
        pending[fut] = ("shot", job)
        return fut

    def submit_split(job):
        from .split import split_task

        fut = client.submit(split_task, job, rig, outdir, pure=False,
                            key=f"split-{job.shot_id}-{os.urandom(4).hex()}")
        pending[fut] = ("split", job)
        return fut

    # Longest first (file size as the proxy for frames): the last shots to finish are
    # short ones, so the workers run out of work at about the same time.
    first = [(submit_split if options.split else submit_shot)(j)
             for j in sorted(jobs, key=_video_bytes, reverse=True)]
    records: list[dict] = []
    bar = _Progress(len(jobs), enabled=progress)  # with split: grows as videos are split
    queue = as_completed(first)
    try:
        with bar, _frame_events(client, bar):
            for fut in queue:
                kind, job = pending.pop(fut)
                try:
                    result = fut.result()
                except Exception as exc:  # a split failed or a worker died: record it
                    result = _crash_record(job, exc)
                if kind == "split" and isinstance(result, list):
                    shots = split_jobs(job, result)
                    if not shots:
                        records.append(_crash_record(job, None, "no shot found in the video"))
                        bar.advance(records[-1])
                    bar.add(max(0, len(shots) - 1))
                    for sj in shots:
                        queue.add(submit_shot(sj))
                    continue
                records.append(result)
                bar.advance(result)
    except BaseException:
        client.cancel(list(pending))
        raise
    return records


@contextlib.contextmanager
def _frame_events(client, bar):
    """Feed the workers' frame reports (:data:`~.pipeline.FRAMES_TOPIC`) to ``bar``."""
    if not bar.enabled:
        yield
        return
    from .pipeline import FRAMES_TOPIC

    client.subscribe_topic(FRAMES_TOPIC, bar.frames)
    try:
        yield
    finally:
        with contextlib.suppress(Exception):
            client.unsubscribe_topic(FRAMES_TOPIC)


def _video_bytes(job: ShotJob) -> int:
    try:
        return os.path.getsize(job.video)
    except OSError:
        return 0


def _crash_record(job: ShotJob, exc, message: str | None = None) -> dict:
    if message is None:
        message = f"task failed ({type(exc).__name__}: {exc})".replace("\n", " ")
    if isinstance(exc, CurltrackError):
        message = str(exc)
    return {"shot": job.to_dict(), "status": "failed", "error": message,
            "error_type": type(exc).__name__ if exc is not None else "SplitError",
            "outcome": "failed"}


class _Progress:
    """Rich progress bars on stderr (no-op if disabled): shots done / skipped / failed,
    and the frames tracked so far in the shots being worked on."""

    def __init__(self, total: int, enabled: bool):
        self.enabled, self.counts = enabled, {"done": 0, "skipped": 0, "failed": 0}
        self.shot_frames: dict[str, tuple[int, int]] = {}  # shot id -> (done, total)
        if enabled:
            from rich.console import Console
            from rich.progress import (BarColumn, MofNCompleteColumn, Progress, TextColumn,
                                       TimeElapsedColumn, TimeRemainingColumn)

            self.bar = Progress(TextColumn("{task.fields[label]}"), BarColumn(),
                                MofNCompleteColumn(), TextColumn("{task.description}"),
                                TimeElapsedColumn(), TimeRemainingColumn(),
                                console=Console(stderr=True))
            self.task = self.bar.add_task(self._text(), total=total, label="batch")
            self.frame_task = self.bar.add_task("in the shots started", total=None,
                                                label="frames", visible=False)

    def frames(self, event) -> None:
        """A worker's report ``(timestamp, {"shot", "done", "total"})``."""
        msg = event[1]
        self.shot_frames[msg["shot"]] = (msg["done"], msg["total"])
        self._show_frames()

    def _show_frames(self) -> None:
        done = sum(d for d, _ in self.shot_frames.values())
        total = sum(t for _, t in self.shot_frames.values())
        self.bar.update(self.frame_task, completed=done, total=total, visible=True)

    def _text(self) -> str:
        c = self.counts
        return f"{c['done']} done, {c['skipped']} skipped, {c['failed']} failed"

    def add(self, n: int) -> None:
        if self.enabled and n:
            self.bar.update(self.task, total=self.bar.tasks[0].total + n)

    def advance(self, record: dict) -> None:
        outcome = record.get("outcome", record.get("status"))
        self.counts[outcome] = self.counts.get(outcome, 0) + 1
        if self.enabled:
            self.bar.update(self.task, advance=1, description=self._text())
            shot = record.get("shot", {}).get("shot_id")
            if shot in self.shot_frames:  # (a failed shot stops short: count it whole)
                self.shot_frames[shot] = (self.shot_frames[shot][1],) * 2
                self._show_frames()

    def __enter__(self):
        if self.enabled:
            self.bar.__enter__()
        return self

    def __exit__(self, *exc):
        if self.enabled:
            self.bar.__exit__(*exc)
