"""The per-shot work of a batch: ``track`` then ``fit`` (then ``discover``), as the CLI does.

The fit reads the series back from the written ``SHOT.csv``, exactly as
``curltrack fit SHOT.csv`` does, so a batch gives the same numbers as running the
commands one by one.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from .._atomic import write_json
from ..series import Series, read_series, write_series
from .jobs import BatchOptions, ShotJob

#: Tracking-quality figures put in every shot's record (names of the campaign columns).
QUALITY_KEYS = ("n_frames", "n_measured", "frac_measured", "frames_lost",
                "sigma_xy_median_m", "sigma_theta_median_rad", "quality_median",
                "camera_height_m", "grid_spacing_px", "t_stop_translation",
                "t_stop_rotation", "n_warnings", "warnings")


def warm_up() -> None:
    """Import the tracking and fitting stack (a few seconds, once per worker process)."""
    import importlib

    for name in ("curltrack.fit", "curltrack.track.pipeline"):
        importlib.import_module(name)


#: The Dask event topic on which workers report frames tracked:
#: ``{"shot": shot_id, "done": frames, "total": frames}``.
FRAMES_TOPIC = "curltrack-frames"
#: Shortest interval between two reports of one shot (s): a few a second per shot.
FRAMES_EVERY_S = 0.5


def frame_events(shot_id: str):
    """A ``progress(done, total)`` for :func:`~curltrack.track.track_video` that logs
    :data:`FRAMES_TOPIC` events from this Dask worker (None outside a worker)."""
    try:
        from distributed import get_worker

        worker = get_worker()
    except (ImportError, ValueError):
        return None
    last = -np.inf

    def report(done: int, total: int) -> None:
        nonlocal last
        now = time.monotonic()
        if done < total and now - last < FRAMES_EVERY_S:
            return
        last = now
        worker.log_event(FRAMES_TOPIC, {"shot": shot_id, "done": int(done),
                                        "total": int(total)})
    return report


def track_and_fit(job: ShotJob, rig, shot_dir, options: BatchOptions) -> dict:
    """Track ``job.video``, fit it (and optionally discover), write the per-shot files.

    Writes ``SHOT.csv`` + ``SHOT.json``, ``FIT.json`` and with ``options.discover``
    ``REPORT.json``, with ``options.plots`` ``FIT.png`` in ``shot_dir``.

    Returns
    -------
    dict
        ``{"quality": {...}, "fit": FIT.json dict, "discovery": {...} or None}``.

    Raises
    ------
    CurltrackError
        From tracking or fitting; the caller records it.
    """
    from ..fit import fit_series
    from ..track import track_video

    shot_dir = Path(shot_dir)
    report = frame_events(job.shot_id) if options.frame_progress else None
    series = track_video(job.video, rig, start_frame=job.start_frame, end_frame=job.end_frame,
                         progress=report or False)
    shot_csv = shot_dir / "SHOT.csv"
    write_series(shot_csv, series)
    series = read_series(shot_csv)
    fit_result = fit_series(series, rig=rig, fixed_stop=options.fixed_stop)
    fit = fit_result.summary()
    write_json(shot_dir / "FIT.json", fit)
    if options.plots:
        from ..plots import plot_fit

        plot_fit(series, fit_result, shot_dir / "FIT.png")
    discovery = None
    if options.discover:
        discovery = _discover(series, rig, shot_dir / "REPORT.json")
    return {"quality": tracking_quality(series), "fit": fit, "discovery": discovery}


def _discover(series: Series, rig, path: Path) -> dict:
    from ..discover import discover
    from ..discover.report import write_json_report

    report = discover(series, rig=rig)
    write_json_report(report, path)
    best = report.findings[0] if report.findings else None
    return {"verdict": report.verdict, "best_effect": best and best.effect,
            "best_delta_bic": best and best.delta_bic}


def tracking_quality(series: Series) -> dict:
    """How well a shot was measured: coverage, median 1-sigma errors, camera figures.

    Returns
    -------
    dict
        Keys :data:`QUALITY_KEYS`; ``sigma_xy_median_m`` (m), ``sigma_theta_median_rad``
        (rad) and ``quality_median`` are medians over measured frames (None when the
        series has no such column).
    """
    data, meta = series.data, series.meta
    ok = data["ok"].to_numpy() == 1

    def median(col):
        if col not in data.columns or not ok.any():
            return None
        vals = data.loc[ok, col].to_numpy(dtype=float)
        vals = vals[np.isfinite(vals)]
        return float(np.median(vals)) if vals.size else None

    warnings = [str(w) for w in meta.get("warnings") or []]
    return {
        "n_frames": int(len(data)),
        "n_measured": int(ok.sum()),
        "frac_measured": float(ok.mean()) if len(data) else 0.0,
        "frames_lost": meta.get("frames_lost"),
        "sigma_xy_median_m": median("sigma_xy"),
        "sigma_theta_median_rad": median("sigma_theta"),
        "quality_median": median("quality"),
        "camera_height_m": meta.get("camera_height_m"),
        "grid_spacing_px": meta.get("grid_spacing_px"),
        "t_stop_translation": meta.get("t_stop_translation"),
        "t_stop_rotation": meta.get("t_stop_rotation"),
        "n_warnings": len(warnings),
        "warnings": " | ".join(warnings),
    }
