"""`curltrack split`: find the shots in a session video."""

from __future__ import annotations

from pathlib import Path

import typer

from ._app import app, check_outputs, guarded


@app.command()
@guarded
def split(
    video: Path = typer.Argument(..., help="Session video holding one or more shots."),
    rig: Path = typer.Option(..., "--rig", help="Rig TOML (marker colours and layout)."),
    output: Path = typer.Option(None, "-o", "--output", help="Shots table: .csv or .json "
                                "(default: print only)."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="Do not print the shots."),
):
    """Find each shot (rock at rest or held -> released -> stopped) in VIDEO.

    Writes one row per shot: shot (1-based), start_frame (release), end_frame (last
    frame to track, inclusive, about 1 s after the motion ends), times in s, and speed
    (m/s) and spin (rad/s) at release.  Track each with
    `curltrack track VIDEO --start-frame S --end-frame E`, or use `batch --split`.
    """
    from ..batch.split import split_video, write_segments
    from ..rig import load_rig

    check_outputs([video, rig], [("-o", output)])
    shots = split_video(video, load_rig(rig))
    if output:
        write_segments(output, shots, video=video)
    if not quiet:
        for s in shots:
            typer.echo(f"shot {s.shot}: frames {s.start_frame}-{s.end_frame} "
                       f"(t = {s.t_start_s:.2f}-{s.t_end_s:.2f} s), release v = "
                       f"{s.peak_speed_m_s:.2f} m/s, omega = {s.peak_omega_rad_s:+.2f} rad/s")
        typer.echo(f"{len(shots)} shot(s)" + (f"; wrote {output}" if output else ""))
