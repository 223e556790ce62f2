"""`curltrack calibrate`: the thread grid on one frame -> CALIB.json (+ annotated PNG)."""

from __future__ import annotations

from pathlib import Path

import typer

from ._app import app, check_outputs, guarded


@app.command()
@guarded
def calibrate(
    source: Path = typer.Argument(..., help="Video (or a still image) of the ice seen from "
                                  "above with the thread grid in view."),
    rig: Path = typer.Option(..., "--rig", help="Rig TOML: thread spacings (and colours)."),
    output: Path = typer.Option(..., "-o", "--output", help="CALIB.json to write."),
    frame: int = typer.Option(0, "--frame", min=0, help="Frame to calibrate on (0-based)."),
    overlay: Path = typer.Option(None, "--overlay", help="PNG: the frame with the fitted "
                                 "threads, origin and axes drawn."),
    debug_dir: Path = typer.Option(None, "--debug-dir", help="Folder for a PNG of what was "
                                   "found on the frame (threads, markers, track's verdict), "
                                   "written also when the frame is refused."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="Do not print the summary."),
):
    """Find the thread lattice, lens distortion and image -> ice homography on one frame.

    The frame is judged as `track` judges it (the rock masked by its markers, the rig's
    [tracking] thresholds): a frame `track` would give ok = 0 is refused with track's
    reason (exit 1).  Units: metres on the ice, pixels in the image (origin at the centre of the top-left
    pixel).  The homography maps undistorted pixels to the lattice frame (axes along the
    threads, origin at a thread crossing, x, y, up right-handed).
    """
    from .._atomic import atomic_path, write_json
    from ..errors import TrackingError
    from ..rig import load_rig
    from ..track.check import check_frames
    from ..video import read_frame

    check_outputs([source, rig], [("-o", output), ("--overlay", overlay)])
    r = load_rig(rig)
    image = read_frame(source, frame)  # (a frame out of range: the reader's error)
    verdict, = check_frames(source, [frame], r, fps_override=r.fps)
    if debug_dir is not None:
        from ..track.overlay import write_verdict_frame

        debug_dir.mkdir(parents=True, exist_ok=True)
        write_verdict_frame(debug_dir, image, verdict, r)
    cal = verdict.calibration
    if cal is None:  # (the grid is what calibrate needs; markers only mask the rock)
        why = verdict.grid_status
        if why.startswith("grid not found ("):  # calibrate's own words for it
            why = "no grid found: " + why[len("grid not found ("):-1]
        elif not why.startswith("grid"):  # a blank frame
            why = f"no grid found: {why}"
        raise TrackingError(why, path=source, where=f"frame {frame}")
    if not verdict.ok and not quiet:
        typer.echo(f"note: track would give this frame ok = 0: {verdict.status}", err=True)
    data = {"source": str(source), "frame": frame, "calibrated_on_frame": verdict.calibrated_on,
            "track_verdict": verdict.status or "ok", **cal.to_dict()}
    write_json(output, data)
    if overlay:
        import cv2

        from ..calib.overlay import draw_grid

        img = draw_grid(image, cal)
        with atomic_path(overlay) as tmp:
            if not cv2.imwrite(str(tmp), img):
                raise TrackingError("cannot write the overlay image", path=overlay)
    if not quiet:
        nx, ny = cal.n_threads
        typer.echo(f"grid: {nx} x {ny} threads, spacing {cal.spacing_px:.1f} px, residual "
                   f"{cal.residual_px:.3f} px, k1 = {cal.dist[0]:+.4f}, colours "
                   f"{'identified' if cal.colors_resolved else 'not identified'}")
        typer.echo(f"wrote {output}" + (f" and {overlay}" if overlay else ""))
