"""`curltrack track`: video -> SHOT.csv (x, y, theta per frame) + SHOT.json (+ overlay)."""

from __future__ import annotations

from pathlib import Path

import typer

from ._app import app, check_outputs, guarded


def parse_frame_list(text: str | None) -> list[int]:
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
                                 where="--exclude-frames") from None
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

    check_outputs([video, rig], [("-o", output), ("-o (its sidecar)", sidecar_path(output)),
                                 ("--overlay", overlay)])
    r = load_rig(rig)
    excl = parse_frame_list(exclude_frames)
    series = track_video(video, r, start_frame=start_frame, end_frame=end_frame,
                         exclude_frames=excl, overlay_path=overlay,
                         progress=not no_progress and sys.stderr.isatty())
    series = series.with_meta(rig=str(rig))
    side = write_series(output, series)
    if not quiet:
        m = series.meta
        n_ok = int(series.data["ok"].sum())

        def fmt(v, unit="s"):
            return "none" if v is None else f"{v:.3f} {unit}"

        h = m.get("camera_height_m")
        typer.echo(f"{n_ok}/{len(series.data)} frames measured; stop: translation "
                   f"{fmt(m['t_stop_translation'])} (frame {m['stop_frame_translation']}), "
                   f"rotation {fmt(m['t_stop_rotation'])} (frame {m['stop_frame_rotation']});"
                   f" camera height {fmt(h, 'm')}")
        for w in m.get("warnings", [])[:5]:
            typer.echo(f"warning: {w}", err=True)
        typer.echo(f"wrote {output} and {side}" + (f" and {overlay}" if overlay else ""))
