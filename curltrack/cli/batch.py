"""`curltrack batch`: track + fit every video of a folder in parallel (Dask)."""

from __future__ import annotations

from pathlib import Path

import typer

from ._app import app, check_outputs, fail, guarded


@app.command()
@guarded
def batch(
    directory: Path = typer.Argument(..., help="Folder of videos (searched recursively); an "
                                     "optional shots.csv there (file, ice_surface, date, "
                                     "thrower, notes, ...) is joined into the table."),
    rig: Path = typer.Option(..., "--rig", help="Rig TOML of the recording session."),
    output: Path = typer.Option(..., "-o", "--output", help="Output folder: <shot>/SHOT.csv, "
                                "SHOT.json, FIT.json per shot; campaign.parquet + .csv."),
    workers: int = typer.Option(None, "--workers", "-j", min=1,
                                help="Local worker processes (default: one per core)."),
    scheduler: str = typer.Option(None, "--scheduler", help="Address of a running Dask "
                                  "scheduler (tcp://host:8786) instead of a local cluster; "
                                  "workers must see the same paths."),
    scheduler_timeout: float = typer.Option(15.0, "--scheduler-timeout", min=0.1,
                                            help="Longest wait for --scheduler to answer "
                                            "(s)."),
    split: bool = typer.Option(False, "--split", help="Find the shots in each video "
                               "(rest -> release -> stop) and process each on its own."),
    report: bool = typer.Option(True, "--report/--no-report", help="Write the campaign "
                                "plots (report/*.png) and report.html (default on)."),
    discover: bool = typer.Option(False, "--discover", help="Also run discover on each shot "
                                  "(REPORT.json)."),
    plots: bool = typer.Option(False, "--plots", help="Write FIT.png for each shot."),
    fixed_stop: bool = typer.Option(False, "--fixed-stop", help="Fit with t_F held at the "
                                    "detected stops (as fit --fixed-stop)."),
    retry_failed: bool = typer.Option(False, "--retry-failed", help="Redo shots recorded "
                                      "as failed (normally skipped while unchanged)."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar or summary."),
):
    """Track and fit every video in DIRECTORY in parallel, resumably.

    A shot already finished with the same inputs (video bytes, rig, options) and the same
    curltrack version is skipped; a shot that fails is recorded (status, error) and the
    batch goes on.  Interrupt and re-run at will.  Exit status 0 when the batch ran (even
    with some failed shots, listed in the summary and the table), 1 when nothing could
    be processed (bad folder/rig/shots.csv, no videos, every shot failed).
    """
    from ..batch import BatchOptions, run_batch

    # before any work: -o naming a file, or outputs over the rig / shots.csv
    check_outputs([rig, directory / "shots.csv"],
                  [("-o", output / name) for name in ("campaign.parquet", "campaign.csv")])
    options = BatchOptions(fixed_stop=fixed_stop, discover=discover, split=split,
                           retry_failed=retry_failed, plots=plots)
    summary = run_batch(directory, rig, output, workers=workers, scheduler=scheduler,
                        options=options, report=report, progress=not quiet,
                        scheduler_timeout_s=scheduler_timeout)
    if not quiet:
        typer.echo(str(summary), err=True)
        typer.echo(f"wrote {summary.table_path} and {summary.csv_path}"
                   + (f" and {summary.report_path}" if summary.report_path else ""), err=True)
    if summary.total and summary.failed == summary.total:
        first = next(r for r in summary.records if r.get("status") == "failed")
        fail(f"all {summary.total} shot(s) failed; first: {first['shot']['shot_id']}: "
             f"{first.get('error')}")
