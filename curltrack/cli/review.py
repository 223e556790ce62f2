"""`curltrack review`: one self-contained HTML page to check a tracked shot in a browser."""

from __future__ import annotations

from pathlib import Path

import typer

from ._app import app, check_outputs, guarded


@app.command()
@guarded
def review(
    series: Path = typer.Argument(..., help="SHOT.csv (or .parquet) with its sidecar."),
    output: Path = typer.Option(..., "-o", "--output", help="PAGE.html to write."),
    overlay: Path = typer.Option(None, "--overlay",
                                 help="The overlay video from `track --overlay` (H.264 mp4), "
                                 "embedded in the page; default the one the sidecar names."),
    report: Path = typer.Option(None, "--report",
                                help="REPORT.json from `discover`: findings, the effect's "
                                "stretch shaded on the plots."),
    rig: Path = typer.Option(None, "--rig", help="Rig TOML (R and r of the fit)."),
):
    """Write one HTML page (no server, no network needed) to check a track by eye.

    The overlay video synced with plots of x, y (m) and theta (rad) against t (s): click
    a point and the video shows that frame; play the video and a cursor follows on the
    plots.  Also: the paper's fit with its residuals (mm, deg), per-frame quality and
    sigma, discovery findings, and every warning on top.
    """
    from ..review import write_review
    from ..rig import load_rig
    from ..series import sidecar_path

    check_outputs([series, sidecar_path(series), overlay, report, rig], [("-o", output)])
    warnings = write_review(series, output, overlay=overlay, report_path=report,
                            rig=load_rig(rig) if rig else None)
    typer.echo(f"wrote {output}" + (f" ({len(warnings)} warning(s) on top)" if warnings else ""))
