"""``curltrack render``: a simulated shot -> synthetic overhead video + ground truth."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from ._app import app, check_outputs, fail, guarded

_HELP = """Render a synthetic overhead video of a shot (mp4, mp4v codec) with its ground truth.

Input: a series (SIM.csv from `curltrack simulate`, or any SHOT.csv-format file), or
initial conditions directly (--v0 and --omega0, with the simulator's defaults for the
rest).  Writes VIDEO.mp4, TRUTH.csv (+ TRUTH.json sidecar: the rock's true centre and
angle in the SHOT.csv frame for every video frame, plus the camera and image positions),
VIDEO.rig.toml (the rig used, with the frame rate) and VIDEO.render.json (every setting).
Rendering is deterministic from --seed.  Defaults: 960x540, ladder camera at 2.0 m
(handheld: 1.6 m) with 1.5 deg tilt, barrel distortion k1 = -0.08, 5 blur sub-frames.

Real cameras' artefacts, each off by default: interlaced fields (--scan interlaced; the
truth then has a row per field with a `field` column and each field's own t), non-square
pixels, chroma subsampling, a rolling shutter (truth at the centre row's time; the
rock's drawn position in u_drawn_px, v_drawn_px), strong or fisheye lenses, frame-time
jitter and dropped frames (t = the container's timestamps), auto exposure / white
balance, H.264 / HEVC at a target bitrate, a rotation tag.
"""


@app.command(help=_HELP)
@guarded
def render(
    series_path: Optional[Path] = typer.Argument(None, metavar="[SIM.csv]",
                                                 help="Series to render (SHOT.csv format)."),
    rig: Optional[Path] = typer.Option(None, "--rig", help="Rig TOML (default: the "
                                       "contract's example rig)."),
    output: Path = typer.Option(..., "-o", "--output", help="Video to write (.mp4)."),
    truth: Optional[Path] = typer.Option(None, "--truth", help="Truth series (.csv/.parquet); "
                                         "default VIDEO.truth.csv."),
    seed: int = typer.Option(0, "--seed", help="Seed of every random choice."),
    camera: str = typer.Option("ladder", "--camera", help="ladder | handheld | static | "
                               "pole."),
    camera_height_m: Optional[float] = typer.Option(None, "--camera-height-m",
                                                    help="Lens height above the ice (m)."),
    width: int = typer.Option(960, "--width", help="Image width (px)."),
    height: int = typer.Option(540, "--height", help="Image height (px)."),
    fps: Optional[float] = typer.Option(None, "--fps", help="Frame rate (default: rig, "
                                        "series, 30)."),
    view_m: float = typer.Option(1.8, "--view-m", help="Ice covered by the image height (m)."),
    tilt_deg: float = typer.Option(1.5, "--tilt-deg", help="Camera tilt from vertical (deg)."),
    yaw_deg: Optional[float] = typer.Option(None, "--yaw-deg", help="Image +u direction, CCW "
                                            "from grid +X (deg); default along the travel."),
    k1: float = typer.Option(-0.08, "--distortion", "--k1", help="Radial distortion k1 "
                             "(< 0 barrel)."),
    heading_deg: Optional[float] = typer.Option(None, "--heading-deg", help="Travel direction "
                                                "vs the grid's +Y, CCW (deg); default "
                                                "random within 2.5 deg."),
    blur_subframes: int = typer.Option(5, "--blur-subframes", help="Sub-frames per frame "
                                       "(1 = no motion blur)."),
    shutter: float = typer.Option(0.5, "--shutter", help="Exposure / frame period."),
    noise: float = typer.Option(2.0, "--noise", help="Sensor read noise (0-255 levels)."),
    jpeg_quality: int = typer.Option(85, "--quality", help="Extra JPEG compression quality "
                                     "1-100 before the mp4v encoder; 0 = off."),
    occlusion: bool = typer.Option(False, "--occlusion/--no-occlusion",
                                   help="A broom head crosses over the rock."),
    occlusion_t_s: Optional[float] = typer.Option(None, "--occlusion-t", help="When (s)."),
    stopped_tail_s: float = typer.Option(1.0, "--stopped-tail-s", help="Rest shown after "
                                         "the stop (s)."),
    house_at_m: Optional[float] = typer.Option(None, "--house-at-m", help="Paint the house "
                                               "with its tee this far along the travel (m)."),
    sheet_lines: bool = typer.Option(False, "--sheet-lines/--no-sheet-lines",
                                     help="Paint the centre (and tee, hog) lines."),
    v0: Optional[float] = typer.Option(None, "--v0", help="Without SIM.csv: initial speed "
                                       "(m/s)."),
    omega0: Optional[float] = typer.Option(None, "--omega0", help="Without SIM.csv: initial "
                                           "spin (rad/s, > 0 CCW)."),
    phi: Optional[float] = typer.Option(None, "--phi", help="Without SIM.csv: phi (both)."),
    alpha: Optional[float] = typer.Option(None, "--alpha", help="Without SIM.csv: alpha."),
    a_T: Optional[float] = typer.Option(None, "--a-T", "--a-t", help="Without SIM.csv: a_T."),
    k2: float = typer.Option(0.0, "--k2", help="Distortion k2 (r^4 term; fisheye: a^4)."),
    lens: str = typer.Option("radial", "--lens", help="radial | fisheye (equidistant, "
                             "OpenCV's cv2.fisheye model)."),
    principal_offset: Optional[str] = typer.Option(None, "--principal-offset-px",
                                                   help="Principal point minus the image "
                                                   "centre, 'DU,DV' (px); default random."),
    pixel_aspect: float = typer.Option(1.0, "--pixel-aspect", help="Pixel width / height "
                                       "(NTSC DV: 0.9090909 = 10/11)."),
    scan: str = typer.Option("progressive", "--scan", help="progressive | interlaced (two "
                             "fields per frame, 1/(2 fps) apart; truth per field)."),
    field_order: str = typer.Option("bff", "--field-order", help="bff (NTSC DV: odd rows "
                                    "first) | tff."),
    chroma: str = typer.Option("444", "--chroma", help="444 | 422 | 420 | 411: colour "
                               "resolution recorded."),
    readout_ms: float = typer.Option(0.0, "--rolling-shutter-ms", help="Rolling shutter "
                                     "readout time, first to last row (ms); 0 = global."),
    frame_jitter_ms: float = typer.Option(0.0, "--frame-jitter-ms", help="RMS capture-time "
                                          "jitter (ms): variable frame rate."),
    drop_rate: float = typer.Option(0.0, "--drop-rate", help="Probability of a dropped "
                                    "frame."),
    auto_exposure: float = typer.Option(0.0, "--auto-exposure", help="RMS relative drift "
                                        "of the exposure gain (auto exposure), 0 = off."),
    white_balance: float = typer.Option(0.0, "--white-balance", help="RMS relative drift "
                                        "of the red/blue gains (auto white balance)."),
    codec: str = typer.Option("mp4v", "--codec", help="mp4v (OpenCV) | mpeg4 | h264 | hevc "
                              "(PyAV) | dv (DV25 in QuickTime: --width 720 --height 480 "
                              "--fps 29.97 or 576 / 25, --scan interlaced --field-order "
                              "bff)."),
    bitrate: Optional[float] = typer.Option(None, "--bitrate", help="Target bitrate (bit/s; "
                                            "PyAV codecs)."),
    rotation: int = typer.Option(0, "--rotation", help="Display rotation tag (deg: 0, 90, "
                                 "180, 270; PyAV codecs)."),
    interlace_flags: bool = typer.Option(True, "--interlace-flags/--no-interlace-flags",
                                         help="--scan interlaced: flag the stream "
                                         "interlaced (PyAV codecs), or write the woven "
                                         "frames as progressive (a re-encoding that "
                                         "lost the flags)."),
    field_colour: str = typer.Option("shared", "--field-colour", help="--scan interlaced, "
                                     "flagged: 'shared' 4:2:0 colour converted from the "
                                     "woven frame (a transcode, each colour row the mean "
                                     "of both fields'), 'top' (the top field's lines "
                                     "alone) or each field's 'own' (a camera's original "
                                     "file)."),
    shadow: float = typer.Option(0.0, "--shadow", help="Depth (0-0.9) of a person's soft "
                                 "shadow walking beside the rock; 0 = none."),
    glare: float = typer.Option(10.0, "--glare", help="Peak level (0-255) of the lamps' "
                                "reflections sliding over the ice (specular: 80-200)."),
    glare_spread: float = typer.Option(0.12, "--glare-spread-rad", help="Their angular "
                                       "spread (rad; specular: 0.03-0.06)."),
    quiet: bool = typer.Option(False, "--quiet", help="No progress output."),
):
    from ..render import (CameraConfig, EncodingConfig, IceStyle, RenderConfig, SensorConfig,
                          render_video)
    from ..rig import default_rig, load_rig

    wanted = ".mov" if codec == "dv" else ".mp4"   # (DV is written in QuickTime)
    if output.suffix.lower() != wanted:
        fail(f"{output}: the video must be a {wanted} file"
             + (" (DV is written in QuickTime)" if codec == "dv" else ""), code=2)
    if (series_path is None) == (v0 is None and omega0 is None):
        fail("give either a series (SIM.csv) or --v0 and --omega0", code=2)
    from ..series import sidecar_path

    truth_path = truth or output.with_suffix(".truth.csv")
    stem = output.with_suffix("")
    check_outputs([series_path, series_path and sidecar_path(series_path), rig],
                  [("-o", output), ("--truth", truth_path),
                   ("--truth (its sidecar)", sidecar_path(truth_path)),
                   ("-o (the rig beside it)", f"{stem}.rig.toml"),
                   ("-o (the settings beside it)", f"{stem}.render.json")])
    the_rig = load_rig(rig) if rig else default_rig()
    if series_path is not None:
        from ..series import read_series

        series = read_series(series_path)
    else:
        if v0 is None or omega0 is None:
            fail("--v0 and --omega0 go together", code=2)
        from ..physics import ShotModel
        from ..simulate import simulate_series

        kw = {k: v for k, v in dict(phi_y=phi, alpha_y=alpha, phi_theta=phi,
                                    alpha_theta=alpha, a_T=a_T).items() if v is not None}
        shot = ShotModel.from_rig(the_rig, v0=v0, omega0=omega0, **kw)
        # the rest after the stop is part of the shot: without it the video ended a frame
        # before the stop and `fit` pinned t_F at its limit
        series = simulate_series(shot, fps=fps or the_rig.fps or 30.0, tail_s=stopped_tail_s)
    offset = None
    if principal_offset is not None:
        try:
            offset = tuple(float(v) for v in principal_offset.split(","))
            assert len(offset) == 2
        except (ValueError, AssertionError):
            fail(f"--principal-offset-px: expected 'DU,DV', got {principal_offset!r}", code=2)
    cam = CameraConfig(motion=camera, height_m=camera_height_m, view_m=view_m,
                       tilt_deg=tilt_deg, yaw_deg=yaw_deg, k1=k1, k2=k2, lens=lens,
                       pixel_aspect=pixel_aspect, principal_offset_px=offset)
    sensor = SensorConfig(scan=scan, field_order=field_order, chroma=chroma,
                          readout_s=readout_ms / 1e3, frame_jitter_s=frame_jitter_ms / 1e3,
                          drop_rate=drop_rate, auto_exposure=auto_exposure,
                          white_balance=white_balance)
    enc = EncodingConfig(codec=codec, bitrate_bps=bitrate, rotation_deg=rotation,
                         interlace_flags=interlace_flags, field_colour=field_colour)
    ice = IceStyle(house_at_m=house_at_m, sheet_lines=sheet_lines)
    cfg = RenderConfig(width=width, height=height, fps=fps, camera=cam, heading_deg=heading_deg,
                       blur_subframes=blur_subframes, shutter=shutter, read_noise=noise,
                       jpeg_quality=jpeg_quality or None, occlusion=occlusion,
                       occlusion_t_s=occlusion_t_s, stopped_tail_s=stopped_tail_s, ice=ice,
                       sensor=sensor, encoding=enc, shadow=shadow, glare=glare,
                       glare_spread_rad=glare_spread)
    result = render_video(series, the_rig, output, truth_path, config=cfg, seed=seed,
                          progress=not quiet)
    m = result.meta
    for w in m.get("warnings", []):
        typer.echo(f"warning: {w}", err=True)
    typer.echo(f"wrote {output} ({m['n_frames']} frames at {m['fps']:g} fps), {truth_path}, "
               f"{stem}.rig.toml, {stem}.render.json")
