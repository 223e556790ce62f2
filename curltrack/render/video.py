"""``render_video``: a series + a rig -> an overhead mp4 and its ground truth.

Frame k of the video is exposed around t_k = k / fps after release (frame 0 = the
series' first row); the truth series gives, for every frame, the rock's true centre and
angle in the contract's SHOT.csv frame (origin = rock centre at t = 0, +y = the grid
axis closest to the initial direction of travel, theta against the lattice).
"""

from __future__ import annotations

import sys
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import cv2
import numpy as np

from .._atomic import atomic_path, write_json, write_text
from ..errors import ParameterError, VideoError
from ..rig import Rig
from ..series import Series, write_series
from .compositor import Compositor, pose_matrix
from .motion import CameraConfig, CameraPath
from .scene import IceStyle, broom_sprite, ice_texture, rock_sprites
from .trajectory import Trajectory, truth_table

FOURCC = "mp4v"  # the H.264 encoders are absent from the opencv-python wheels


@dataclass(frozen=True)
class RenderConfig:
    """Everything about a rendering except the shot and the rig (documented defaults).

    Parameters
    ----------
    width, height : int
        Image size (px), default 960 x 540.
    fps : float, optional
        Frame rate (frames/s); default the rig's ``[camera].fps``, else the series'
        sidecar ``fps``, else 30.
    camera : CameraConfig
        The camera and how it is held (default: ladder at 2.0 m).
    heading_deg : float, optional
        Direction of travel relative to the grid's +Y axis, counter-clockwise (deg);
        default: random in +-2.5 deg (the paper's skews were < 2.5 deg).
    lattice_phase : (float, float), optional
        Rock start's position within a lattice cell, as fractions of the spacings;
        default: random in [0.15, 0.85] (never on a thread).
    blur_subframes : int
        Sub-frames averaged per frame (motion blur), default 5; 1 = no blur.
    shutter : float
        Exposure time as a fraction of the frame period, default 0.5.
    read_noise, shot_noise_gain : float
        Sensor noise: sigma^2 = read_noise^2 + shot_noise_gain * I (0-255 levels),
        defaults 2.0 and 0.08.
    vignetting : float
        Brightness loss in the image corners, default 0.25.
    jpeg_quality : int, optional
        Extra per-frame JPEG compression before the mp4v encoder (blocking and ringing
        as in consumer video), default 85; None = only the mp4v encoder.
    occlusion : bool
        A broom head crosses the view above the rock, default False.
    occlusion_t_s : float, optional
        When the broom passes over the rock (s); default 40 % of the motion.
    occlusion_speed_m_s : float
        Broom speed across the view (m/s), default 1.2.
    stopped_tail_s : float
        The video ends at least this long after the rock's last stop (s), default 1.0;
        frames are appended when the series' own rest is shorter (only when it stopped).
    marker_diameter_m : float
        Diameter of the marker discs (m), default 0.025.
    ice : IceStyle
        Ice, pebble and thread look.
    texture_oversample : float
        Ice texture resolution relative to the image's px/m, default 1.3.
    """

    width: int = 960
    height: int = 540
    fps: float | None = None
    camera: CameraConfig = field(default_factory=CameraConfig)
    heading_deg: float | None = None
    lattice_phase: tuple[float, float] | None = None
    blur_subframes: int = 5
    shutter: float = 0.5
    read_noise: float = 2.0
    shot_noise_gain: float = 0.08
    vignetting: float = 0.25
    jpeg_quality: int | None = 85
    occlusion: bool = False
    occlusion_t_s: float | None = None
    occlusion_speed_m_s: float = 1.2
    stopped_tail_s: float = 1.0
    marker_diameter_m: float = 0.025
    ice: IceStyle = field(default_factory=IceStyle)
    texture_oversample: float = 1.3

    def validate(self) -> None:
        """Raise ParameterError naming the first bad field."""
        def bad(name, msg):
            raise ParameterError(msg, where=f"render.{name}")
        if not (64 <= self.width <= 8192 and 64 <= self.height <= 8192):
            bad("width", f"image size {self.width}x{self.height} outside 64..8192 px")
        if self.fps is not None and not (np.isfinite(self.fps) and self.fps > 0):
            bad("fps", f"fps must be > 0, got {self.fps!r}")
        if not 1 <= int(self.blur_subframes) <= 64:
            bad("blur_subframes", f"must be 1..64, got {self.blur_subframes!r}")
        if not 0.0 <= self.shutter <= 1.0:
            bad("shutter", f"must be in [0, 1], got {self.shutter!r}")
        for name in ("read_noise", "shot_noise_gain", "stopped_tail_s"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                bad(name, f"must be >= 0, got {v!r}")
        if not 0.0 <= self.vignetting < 1.0:
            bad("vignetting", f"must be in [0, 1), got {self.vignetting!r}")
        if self.jpeg_quality is not None and not 1 <= self.jpeg_quality <= 100:
            bad("jpeg_quality", f"must be 1..100, got {self.jpeg_quality!r}")
        if not 0.005 <= self.marker_diameter_m <= 0.1:
            bad("marker_diameter_m", f"must be 0.005..0.1 m, got {self.marker_diameter_m!r}")
        if self.lattice_phase is not None and not all(0 <= p < 1 for p in self.lattice_phase):
            bad("lattice_phase", "fractions must be in [0, 1)")
        if not 0.5 <= self.texture_oversample <= 4:
            bad("texture_oversample", "must be 0.5..4")
        if self.occlusion_speed_m_s <= 0:
            bad("occlusion_speed_m_s", "must be > 0")


def _texture_bounds(path: CameraPath, times, rock_xy, cam0, height_m):
    """World rectangle seen by the camera over the shot, with a margin (m)."""
    W, H = cam0.width, cam0.height
    border = np.array([[u, v] for u in (0, W / 2, W - 1) for v in (0, H / 2, H - 1)], float)
    xd = (border - [cam0.cx, cam0.cy]) / cam0.f_px
    reach = np.linalg.norm(cam0.undistort(xd), axis=1).max() * height_m * 1.15 + 0.15
    C = path.centre(times)[:, :2]
    lo = np.minimum(C.min(0), rock_xy(times).min(0)) - reach
    hi = np.maximum(C.max(0), rock_xy(times).max(0)) + reach
    return lo[0], lo[1], hi[0], hi[1]


def render_video(series: Series, rig: Rig, video_path, truth_path=None,
                 config: RenderConfig | None = None, seed: int = 0,
                 progress: bool = False) -> Series:
    """Render an overhead video of a shot and return (and optionally write) its truth.

    Parameters
    ----------
    series : Series
        The shot in the SHOT.csv frame (``t`` s, ``x``, ``y`` m, ``theta`` rad); rows
        with ``ok`` = 1 are used.  Its sidecar's stop times are copied to the truth.
    rig : Rig
        Grid, rock and markers (and the frame rate / camera height, when given).
    video_path : path
        Output mp4 (written atomically).  Beside it: ``<stem>.rig.toml`` (the rig, with
        the frame rate) and ``<stem>.render.json`` (the camera and render settings).
    truth_path : path, optional
        Where to write the truth series (CSV or Parquet + sidecar JSON).
    config : RenderConfig, optional
    seed : int
        Every random choice (placement, camera path, ice, noise) derives from it.
    progress : bool
        Print progress to stderr.

    Returns
    -------
    Series
        Truth, one row per video frame: the contract columns plus ``u_px``, ``v_px``
        (rock centre on the ice in the image), ``u_top_px``, ``v_top_px`` (rock axis
        at the marker plane), ``marker<i>_u_px``/``_v_px``, ``camera_x_m``,
        ``camera_y_m`` (in the truth frame), ``camera_height_m``, ``camera_yaw_deg``,
        ``in_view`` and ``occluded`` (fraction of the rock's top hidden by the broom).

    Raises
    ------
    ParameterError
        Bad settings, or the rock outside the view for the whole shot.
    VideoError
        The video cannot be written.
    """
    cfg = config or RenderConfig()
    cfg.validate()
    rng = np.random.default_rng(seed)
    fps = cfg.fps or rig.fps or series.meta.get("fps") or 30.0
    if not (np.isfinite(fps) and fps > 0):
        raise ParameterError(f"fps must be > 0, got {fps!r}", where="render.fps")
    cam_cfg = cfg.camera
    if cam_cfg.height_m is None and rig.camera_height_m is not None:
        cam_cfg = replace(cam_cfg, height_m=rig.camera_height_m)
    cam_cfg = cam_cfg.resolved()
    heading = np.deg2rad(rng.uniform(-2.5, 2.5) if cfg.heading_deg is None else cfg.heading_deg)
    phase = (rng.uniform(0.15, 0.85, 2) if cfg.lattice_phase is None
             else np.asarray(cfg.lattice_phase, dtype=float))
    traj = Trajectory(series, heading, psi0=rng.uniform(0, 2 * np.pi),
                      stopped_tail_s=cfg.stopped_tail_s)
    n_frames = int(np.floor(traj.duration * fps + 1e-9)) + 1
    t_frames = np.arange(n_frames) / fps
    path = CameraPath(cam_cfg, cfg.width, cfg.height, traj.rock_xy, -1.0 / fps,
                      traj.duration + 1.0 / fps, traj.travel_yaw, rng)
    cams = [path.camera(t) for t in t_frames]
    h_mid = 0.5 * rig.rock_height_m
    uv = np.array([c.project(np.r_[p, h_mid])[0] for c, p in zip(cams, traj.rock_xy(t_frames))])
    if not cams[0].in_image(uv).any():
        raise ParameterError("the rock is outside the view for the whole shot (check the "
                             "camera offset, height and view)", where="render.camera")
    # --- scene ---------------------------------------------------------------------
    ppm_img = path.f_px / cam_cfg.height_m
    bounds = _texture_bounds(path, np.linspace(-1 / fps, traj.duration + 1 / fps, 400),
                             traj.rock_xy, cams[0], cam_cfg.height_m)
    area = (bounds[2] - bounds[0]) * (bounds[3] - bounds[1])
    ppm_tex = min(cfg.texture_oversample * ppm_img, np.sqrt(60e6 / area),
                  30000 / max(bounds[2] - bounds[0], bounds[3] - bounds[1]))
    world_phase = (phase[0] * rig.spacing_x_m, phase[1] * rig.spacing_y_m)
    tex = ice_texture(rig, bounds, ppm_tex, world_phase, cfg.ice, rng)
    ppm_rock = 1.5 * path.f_px / (cam_cfg.height_m - rig.rock_height_m)
    sprites = rock_sprites(rig, ppm_rock, rng, marker_diameter_m=cfg.marker_diameter_m)
    broom = broom_sprite(ppm_img * 1.2, rng) if cfg.occlusion else None
    broom_z = rig.rock_height_m + 0.2
    t_occ = (cfg.occlusion_t_s if cfg.occlusion_t_s is not None else 0.4 * traj.t_motion_end)
    comp = Compositor(cams[0], cfg.vignetting, cfg.read_noise, cfg.shot_noise_gain,
                      cfg.jpeg_quality, rng)

    def broom_pose(t):
        """World pose of the broom head: crossing the travel line over the rock at t_occ."""
        P = traj.rock_xy(np.array([t_occ]))[0]
        across = traj.travel_yaw + np.pi / 2
        s = cfg.occlusion_speed_m_s * (t - t_occ)
        return pose_matrix(P[0] + s * np.cos(across), P[1] + s * np.sin(across), across)

    def layers_at(t):
        P = traj.rock_xy(np.array([t]))[0]
        psi = traj.psi(np.array([t]))[0]
        out = [(s, pose_matrix(P[0], P[1], psi if s.attached else None)) for s in sprites]
        if broom is not None and abs(t - t_occ) * cfg.occlusion_speed_m_s < 3.0:
            out.append((replace(broom, z_m=broom_z), broom_pose(t)))
        return out

    # --- frames ----------------------------------------------------------------------
    nsub = int(cfg.blur_subframes)
    offsets = ((np.arange(nsub) + 0.5) / nsub - 0.5) * cfg.shutter / fps
    video_path = Path(video_path)
    with atomic_path(video_path) as tmp:
        writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*FOURCC), float(fps),
                                 (cfg.width, cfg.height))
        if not writer.isOpened():
            raise VideoError(f"cannot open a {FOURCC} video writer", path=video_path)
        try:
            for k, tk in enumerate(t_frames):
                writer.write(comp.frame(tk + offsets, path.camera, layers_at, tex))
                if progress and (k % 30 == 0 or k == n_frames - 1):
                    print(f"\rrender: frame {k + 1}/{n_frames}", end="", file=sys.stderr)
        finally:
            writer.release()
        if progress:
            print(file=sys.stderr)
    # --- truth -----------------------------------------------------------------------
    occ = None
    if broom is not None:
        occ = [_occluded_fraction(c, traj, rig, broom, broom_z, broom_pose(t), t)
               for c, t in zip(cams, t_frames)]
    data = truth_table(traj, rig, path, cams, t_frames, occ)
    meta = traj.sidecar(fps, n_frames, t_frames)
    meta.update(camera_height_m=cam_cfg.height_m,
                grid_spacing_px=float(path.f_px * rig.spacing_x_m
                                      / (cam_cfg.height_m - tex.z_m)),
                render=dict(asdict(replace(cfg, camera=cam_cfg)), seed=int(seed),
                            heading_deg=float(np.rad2deg(heading)),
                            lattice_phase=[float(p) for p in phase],
                            f_px=path.f_px, cx_px=path.cx, cy_px=path.cy,
                            yaw0_deg=float(np.rad2deg(path.yaw0)),
                            truth_rotation_deg=float(np.rad2deg(traj.truth_rot)),
                            texture_ppm=float(ppm_tex), fourcc=FOURCC),
                source=series.name)
    truth = Series(data, meta, Path(truth_path) if truth_path else None)
    if truth_path is not None:
        write_series(truth_path, truth)
    stem = video_path.with_suffix("")
    write_text(f"{stem}.rig.toml", replace(rig, fps=float(fps)).to_toml())
    write_json(f"{stem}.render.json", meta["render"])
    return truth


def _occluded_fraction(cam, traj, rig, broom, broom_z, pose, t) -> float:
    """Fraction of the rock's top (as imaged) covered by the broom head at time ``t``."""
    P = traj.rock_xy(np.array([t]))[0]
    r = 0.5 * rig.rock_diameter_m * 0.8
    g = np.linspace(-r, r, 15)
    gx, gy = np.meshgrid(g, g)
    inside = gx**2 + gy**2 <= r * r
    pts = np.column_stack([gx[inside] + P[0], gy[inside] + P[1],
                           np.full(inside.sum(), rig.rock_height_m)])
    uv = cam.project(pts)
    h, w = broom.rgba.shape[:2]
    # the sprite's alpha decides: map the image points back through the broom's plane
    Hb = cam.plane_homography(broom_z) @ pose @ broom.affine
    pts_u = cam.undistort((uv - [cam.cx, cam.cy]) / cam.f_px) * cam.f_px + [cam.cx, cam.cy]
    src = np.c_[pts_u, np.ones(len(pts_u))] @ np.linalg.inv(Hb).T
    src = src[:, :2] / src[:, 2:]
    col, row = np.round(src).astype(int).T
    ok = (col >= 0) & (col < w) & (row >= 0) & (row < h)
    alpha = np.zeros(len(src))
    alpha[ok] = broom.rgba[row[ok], col[ok], 3]
    return float((alpha > 0.5).mean())
