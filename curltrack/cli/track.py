"""`curltrack track`: video -> SHOT.csv (x, y, theta per frame) + SHOT.json (+ overlay)."""

from __future__ import annotations

from pathlib import Path

import typer

from ._app import app, check_outputs, guarded


def parse_frame_list(text: str | None, where: str = "--exclude-frames") -> list[int]:
    """"1,2,5-9" -> [1, 2, 5, 6, 7, 8, 9]; raises ParameterError naming the bad item."""
    from ..errors import ParameterError

    out: list[int] = []
    for item in (text or "").split(","):
        item = item.strip()
        if not item:
            continue
        try:
            if "-" in item:
                a, b = (int(v) for v in item.split("-", 1))
                if b < a or a < 0:
                    raise ValueError
                out.extend(range(a, b + 1))
            else:
                v = int(item)
                if v < 0:
                    raise ValueError
                out.append(v)
        except ValueError:
            raise ParameterError(f"bad frame or range {item!r} (use e.g. 1,2,5-9)",
                                 where=where) from None
    return out


@app.command()
@guarded
def track(
    video: Path = typer.Argument(..., help="Overhead video of the shot."),
    rig: Path = typer.Option(..., "--rig", help="Rig TOML: grid, rock, markers, camera."),
    output: Path = typer.Option(..., "-o", "--output",
                                help="SHOT.csv (or .parquet); the sidecar SHOT.json is "
                                "written beside it."),
    start_frame: int = typer.Option(None, "--start-frame", min=0,
                                    help="Release frame (t = 0); default the first frame."),
    end_frame: int = typer.Option(None, "--end-frame", min=0,
                                  help="Last frame to track (inclusive); default the last."),
    exclude_frames: str = typer.Option(None, "--exclude-frames",
                                       help="Frames to skip, e.g. 1,2,5-9 (kept as ok = 0)."),
    overlay: Path = typer.Option(None, "--overlay",
                                 help="Annotated video (grid, markers, centre, trajectory, "
                                 "x, y, theta)."),
    frames: str = typer.Option(None, "--frames",
                               help="With --debug-dir: frames to draw, e.g. 100,201 or 5-9."),
    debug_dir: Path = typer.Option(None, "--debug-dir",
                                   help="Folder for PNGs of what was found on --frames "
                                   "(threads, markers, centre, trail, numbers)."),
    corrections: Path = typer.Option(None, "--corrections",
                                     help="JSON of clicked marker positions (px) and "
                                     "excluded frames, e.g. downloaded from `review`."),
    no_progress: bool = typer.Option(False, "--no-progress", help="No progress bar."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="Do not print the summary."),
):
    """Track the rock: x, y (m) and theta (rad, CCW, cumulative) per frame, stop frames.

    Frame: origin = rock centre at t = 0, +y = the grid axis closest to the initial
    direction of travel, +x to its right; positions are on the ice, corrected for the
    markers' height (parallax) and for the camera's motion.  Frames that cannot be
    measured are kept with ok = 0 and a warning in SHOT.json.
    """
    import sys

    from ..rig import load_rig
    from ..series import sidecar_path, write_series
    from ..track import track_video

    check_outputs([video, rig, corrections], [("-o", output), ("-o (its sidecar)", sidecar_path(output)),
                                 ("--overlay", overlay)])
    r = load_rig(rig)
    excl = parse_frame_list(exclude_frames)
    debug = parse_frame_list(frames, where="--frames")
    if (debug_dir is None) != (not debug):
        from ..errors import ParameterError

        raise ParameterError("--frames and --debug-dir go together", where="--debug-dir")
    series = track_video(video, r, start_frame=start_frame, end_frame=end_frame,
                         exclude_frames=excl, overlay_path=overlay,
                         progress=not no_progress and sys.stderr.isatty(),
                         debug_frames=debug, debug_dir=debug_dir, corrections=corrections)
    # (`curltrack review` embeds the overlay)
    series = series.with_meta(rig=str(rig), **({} if overlay is None else
                                                {"overlay": str(overlay)}))
    side = write_series(output, series)
    if not quiet:
        m = series.meta
        n_ok = int(series.data["ok"].sum())

        def fmt(v, unit="s"):
            return "none" if v is None else f"{v:.3f} {unit}"

        h = m.get("camera_height_m")
        def stop(kind):
            t = m[f"t_stop_{kind}"]
            return (f"{kind} not within the video" if t is None else
                    f"{kind} {fmt(t)} (frame {m[f'stop_frame_{kind}']})")

        typer.echo(f"{n_ok}/{len(series.data)} frames measured; stop: {stop('translation')}, "
                   f"{stop('rotation')}; camera height "
                   f"{fmt(h, 'm') if h is not None else 'not measured'}")
        for w in m.get("warnings", [])[:5]:
            typer.echo(f"warning: {w}", err=True)
        typer.echo(f"wrote {output} and {side}" + (f" and {overlay}" if overlay else ""))
