"""One rendering set up: the shot placed, the camera path, the scene; frames on demand.

:class:`Production` draws every random choice from the seed (independent streams for
the placement, the camera and the scene; each frame's noise seeded by its index), so
that :meth:`Production.frames` streams the video frame by frame, any frame renders the
same alone, and :meth:`Production.truth` gives the ground truth of exactly those frames.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import cv2
import numpy as np
import pandas as pd

from ..errors import ParameterError
from ..rig import Rig
from ..series import Series
from .camera import Camera
from .compositor import Compositor, pose_matrix
from .config import RenderConfig
from .ice import N_ICE, ice_texture, sheet_markings
from .motion import CameraPath
from .sprites import broom_sprite, rock_sprites
from .trajectory import Trajectory, truth_table

BROOM_ABOVE_TOP_M = 0.2  # the broom head passes this far above the rock's top


@dataclass
class FrameInfo:
    """What was drawn in one frame: its time (s) and the camera at mid-exposure."""

    index: int
    t: float
    camera: Camera


def _texture_bounds(path: CameraPath, times, rock_xy, cam0: Camera, height_m: float):
    """World rectangle seen by the camera over the shot, with a margin (m)."""
    W, H = cam0.width, cam0.height
    border = np.array([[u, v] for u in (0, W / 2, W - 1) for v in (0, H / 2, H - 1)], float)
    xd = (border - [cam0.cx, cam0.cy]) / cam0.f_px
    reach = np.linalg.norm(cam0.undistort(xd), axis=1).max() * height_m * 1.15 + 0.15
    C = path.centre(times)[:, :2]
    lo = np.minimum(C.min(0), rock_xy(times).min(0)) - reach
    hi = np.maximum(C.max(0), rock_xy(times).max(0)) + reach
    return lo[0], lo[1], hi[0], hi[1]


class Production:
    """A shot, a rig and settings, prepared for rendering.

    Parameters
    ----------
    series : Series
        The shot in the SHOT.csv frame.
    rig : Rig
    config : RenderConfig
    seed : int

    Raises
    ------
    ParameterError
        Bad settings, or the rock outside the view for the whole shot.
    """

    def __init__(self, series: Series, rig: Rig, config: RenderConfig, seed: int = 0):
        cfg = config
        cfg.validate()
        self.rig, self.cfg, self.seed = rig, cfg, int(seed)
        self.series_name = series.name
        # independent streams: changing the look of the ice does not move the camera
        rng, rng_cam, self._rng_scene = (np.random.default_rng(s)
                                         for s in np.random.SeedSequence(int(seed)).spawn(3))
        fps = cfg.fps or rig.fps or series.meta.get("fps") or 30.0
        if not (np.isfinite(fps) and fps > 0):
            raise ParameterError(f"fps must be > 0, got {fps!r}", where="render.fps")
        self.fps = float(fps)
        cam_cfg = cfg.camera
        if cam_cfg.height_m is None and rig.camera_height_m is not None:
            cam_cfg = replace(cam_cfg, height_m=rig.camera_height_m)
        self.cam_cfg = cam_cfg = cam_cfg.resolved()
        self.heading = np.deg2rad(rng.uniform(-2.5, 2.5) if cfg.heading_deg is None
                                  else cfg.heading_deg)
        self.phase = (rng.uniform(0.15, 0.85, 2) if cfg.lattice_phase is None
                      else np.asarray(cfg.lattice_phase, dtype=float))
        self.traj = traj = Trajectory(series, self.heading, psi0=rng.uniform(0, 2 * np.pi),
                                      stopped_tail_s=cfg.stopped_tail_s)
        n_frames = int(np.floor(traj.duration * self.fps + 1e-9)) + 1
        self.t_frames = np.arange(n_frames) / self.fps
        self.path = path = CameraPath(cam_cfg, cfg.width, cfg.height, traj.rock_xy,
                                      -1.0 / self.fps, traj.duration + 1.0 / self.fps,
                                      traj.travel_yaw, rng_cam)
        traj.align_to_image(path.yaw0 + np.pi / 2)
        self.cams = [path.camera(t) for t in self.t_frames]
        h_mid = 0.5 * rig.rock_height_m
        uv = np.array([c.project(np.r_[p, h_mid])[0]
                       for c, p in zip(self.cams, traj.rock_xy(self.t_frames))])
        if not self.cams[0].in_image(uv).any():
            raise ParameterError("the rock is outside the view for the whole shot (check "
                                 "the camera offset, height and view)", where="render.camera")
        self.ppm_img = path.f_px / cam_cfg.height_m
        self.tex_z_m = -rig.grid_depth_m / N_ICE
        self.t_occ = (cfg.occlusion_t_s if cfg.occlusion_t_s is not None
                      else 0.4 * traj.t_motion_end)
        self._drawn = None
        nsub = int(cfg.blur_subframes)
        self.offsets = ((np.arange(nsub) + 0.5) / nsub - 0.5) * cfg.shutter / self.fps

    def _scene(self):
        """Draw the scene (ice texture, sprites, compositor) once, on first use."""
        if self._drawn is not None:
            return
        cfg, rig, path, traj, rng = self.cfg, self.rig, self.path, self.traj, self._rng_scene
        span = np.linspace(-1 / self.fps, traj.duration + 1 / self.fps, 400)
        bounds = _texture_bounds(path, span, traj.rock_xy, self.cams[0], self.cam_cfg.height_m)
        area = (bounds[2] - bounds[0]) * (bounds[3] - bounds[1])
        self.ppm_tex = float(min(cfg.texture_oversample * self.ppm_img, np.sqrt(60e6 / area),
                                 30000 / max(bounds[2] - bounds[0], bounds[3] - bounds[1])))
        world_phase = (self.phase[0] * rig.spacing_x_m, self.phase[1] * rig.spacing_y_m)
        travel = np.array([np.cos(traj.travel_yaw), np.sin(traj.travel_yaw)])
        if not traj.translating:  # the sheet runs along the grid axis of image up
            travel = np.array([-np.sin(traj.truth_rot), np.cos(traj.truth_rot)])
        marks = sheet_markings(cfg.ice, (0.0, 0.0), travel)
        self.tex = ice_texture(rig, bounds, self.ppm_tex, world_phase, cfg.ice, rng, marks)
        if cfg.optics_blur_px > 0:
            sig = cfg.optics_blur_px * self.ppm_tex / self.ppm_img
            self.tex.image = cv2.GaussianBlur(self.tex.image, (0, 0), sig)
        if abs(np.sin(path.yaw0)) > abs(np.cos(path.yaw0)):  # image rows along world Y
            self.tex = self.tex.transpose()
        ppm_rock = 1.5 * path.f_px / (self.cam_cfg.height_m - rig.rock_height_m)
        self.sprites = rock_sprites(rig, ppm_rock, rng, 1.5 / ppm_rock,
                                    marker_diameter_m=cfg.marker_diameter_m)
        if cfg.optics_blur_px > 0:  # sprites hold 1.5 texels per image pixel
            self.sprites = [replace(s, rgba=cv2.GaussianBlur(s.rgba, (0, 0),
                                                             1.5 * cfg.optics_blur_px))
                            for s in self.sprites]
        self.broom = None
        if cfg.occlusion:
            self.broom = replace(broom_sprite(self.ppm_img * 1.2, rng),
                                 z_m=rig.rock_height_m + BROOM_ABOVE_TOP_M)
        glare = None
        if cfg.glare > 0:  # mirror images of the lamps, below the ice
            lamps = np.c_[self.tex.lamps, np.full(len(self.tex.lamps), -cfg.lamp_height_m)]
            glare = (lamps, cfg.glare, cfg.glare_spread_rad)
        self.comp = Compositor(self.cams[0], cfg.vignetting, cfg.read_noise,
                               cfg.shot_noise_gain, cfg.jpeg_quality, rng, glare, cfg.flicker,
                               cfg.demosaic)
        self._drawn = True

    @property
    def n_frames(self) -> int:
        return len(self.t_frames)

    def broom_pose(self, t: float) -> np.ndarray:
        """World pose of the broom head: crossing the travel line over the rock at t_occ."""
        P = self.traj.rock_xy(np.array([self.t_occ]))[0]
        across = self.traj.travel_yaw + np.pi / 2
        s = self.cfg.occlusion_speed_m_s * (t - self.t_occ)
        # head's long side along the travel, shaft towards the sweeper's side (-across)
        return pose_matrix(P[0] + s * np.cos(across), P[1] + s * np.sin(across),
                           self.traj.travel_yaw)

    def layers_at(self, t: float):
        """(Sprite, world pose) of everything above the ice at time ``t``, bottom to top."""
        P = self.traj.rock_xy(np.array([t]))[0]
        psi = self.traj.psi(np.array([t]))[0]
        out = [(s, pose_matrix(P[0], P[1], psi if s.attached else None)) for s in self.sprites]
        if self.broom is not None and abs(t - self.t_occ) * self.cfg.occlusion_speed_m_s < 3.0:
            out.append((self.broom, self.broom_pose(t)))
        return out

    def frames(self, start: int = 0, stop: int | None = None):
        """Yield ``(image, FrameInfo)`` for frames ``start`` .. ``stop - 1`` (BGR uint8)."""
        self._scene()
        stop = self.n_frames if stop is None else min(stop, self.n_frames)
        for k in range(start, stop):
            tk = self.t_frames[k]
            img = self.comp.frame(tk + self.offsets, self.path.camera, self.layers_at, self.tex,
                                  index=k)
            yield img, FrameInfo(k, float(tk), self.cams[k])

    def occluded_fraction(self, k: int) -> float:
        """Fraction of the rock's top (as imaged in frame ``k``) hidden by the broom."""
        if not self.cfg.occlusion:
            return 0.0
        self._scene()
        t, cam, rig = self.t_frames[k], self.cams[k], self.rig
        P = self.traj.rock_xy(np.array([t]))[0]
        r = 0.5 * rig.rock_diameter_m * 0.8
        g = np.linspace(-r, r, 15)
        gx, gy = np.meshgrid(g, g)
        inside = gx**2 + gy**2 <= r * r
        pts = np.column_stack([gx[inside] + P[0], gy[inside] + P[1],
                               np.full(inside.sum(), rig.rock_height_m)])
        # pinhole px of the top's points, mapped back through the broom's plane
        pu = cam.normalized(pts) * cam.f_px + [cam.cx, cam.cy]
        Hb = cam.plane_homography(self.broom.z_m) @ self.broom_pose(t) @ self.broom.affine
        src = np.c_[pu, np.ones(len(pu))] @ np.linalg.inv(Hb).T
        col, row = np.round(src[:, :2] / src[:, 2:]).astype(int).T
        h, w = self.broom.rgba.shape[:2]
        ok = (col >= 0) & (col < w) & (row >= 0) & (row < h) & (src[:, 2] > 0)
        alpha = np.zeros(len(src))
        alpha[ok] = self.broom.rgba[row[ok], col[ok], 3]
        return float((alpha > 0.5).mean())

    def truth(self) -> Series:
        """The ground truth of every frame, with its sidecar (see ``render_video``)."""
        occ = [self.occluded_fraction(k) for k in range(self.n_frames)]
        data: pd.DataFrame = truth_table(self.traj, self.rig, self.path, self.cams,
                                         self.t_frames, occ)
        meta = self.traj.sidecar(self.fps, self.n_frames, self.t_frames)
        meta.update(camera_height_m=self.cam_cfg.height_m,
                    grid_spacing_px=float(self.path.f_px * self.rig.spacing_x_m
                                          / (self.cam_cfg.height_m - self.tex_z_m)),
                    render=self.settings(), source=self.series_name)
        return Series(data, meta)

    def settings(self) -> dict:
        """Every setting and every random choice (JSON-ready)."""
        p = self.path
        return dict(asdict(replace(self.cfg, camera=self.cam_cfg)), seed=self.seed,
                    heading_deg=float(np.rad2deg(self.heading)),
                    lattice_phase=[float(v) for v in self.phase],
                    psi0_deg=float(np.rad2deg(self.traj.psi0)),
                    truth_rotation_deg=float(np.rad2deg(self.traj.truth_rot)),
                    f_px=float(p.f_px), cx_px=float(p.cx), cy_px=float(p.cy),
                    yaw0_deg=float(np.rad2deg(p.yaw0)),
                    fps_used=self.fps)
