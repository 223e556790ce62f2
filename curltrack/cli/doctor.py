"""`curltrack doctor`: what is wrong with a video + rig, before a long run."""

from __future__ import annotations

from pathlib import Path

import typer

from ._app import app, check_outputs, guarded


@app.command()
@guarded
def doctor(
    video: Path = typer.Argument(..., help="Overhead video of a shot."),
    rig: Path = typer.Option(..., "--rig", help="Rig TOML: grid, rock, markers, camera."),
    samples: int = typer.Option(6, "--samples", min=1, max=50,
                                help="Frames examined, spread over the video."),
    frames: str = typer.Option(None, "--frames", help="Examine these frames instead, e.g. "
                               "100,201 or 5-9: each is judged as track judges it."),
    as_json: bool = typer.Option(False, "--json", help="Print the checklist as JSON."),
    output: Path = typer.Option(None, "-o", "--output", help="Also write the JSON here."),
):
    """Check a video and rig before tracking: container and fps, markers of each rig
    colour, the thread grid (spacing px, residual px), the rock's size (px) and the camera
    height implied by the parallax (m).

    Each frame examined is judged by `track`'s own per-frame loop, run from the video's
    start (the same steps and the rig's [tracking] thresholds): the `frames` line says
    which track will give ok = 0, and why.
    Prints a checklist (✓ ok, ! warning, ✗ fatal) with advice.  Exit status 1 when
    something is fatal (track would fail), 0 otherwise.
    """
    import json

    from .._atomic import write_json
    from ..doctor import diagnose
    from ..rig import load_rig

    from .track import parse_frame_list

    check_outputs([video, rig], [("-o", output)])
    chosen = parse_frame_list(frames, where="--frames") if frames else None
    report = diagnose(video, load_rig(rig), n_samples=samples, frames=chosen, progress=None)
    data = report.to_dict()
    if output is not None:
        write_json(output, data)
    if as_json:
        from .._atomic import _finite_or_none

        typer.echo(json.dumps(_finite_or_none(data), indent=2, default=str))
    else:
        typer.echo(report.format())
    if not report.ok:
        bad = next(c for c in report.checks if c.status == "fail")
        if as_json:
            raise typer.Exit(1)
        detail = bad.detail if bad.detail.startswith(str(video)) else f"{video}: {bad.detail}"
        _fail(f"{detail} ({bad.name})")


def _fail(message: str):
    from ._app import fail

    fail(message)
