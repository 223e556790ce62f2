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
from .encode import frame_rate
from .ice import N_ICE, ice_texture, sheet_markings
from .motion import CameraPath
from .sensor import ColourControl, field_rows, row_time_offset, schedule, subsample_chroma
from .sprites import broom_sprite, rock_sprites
from .trajectory import Trajectory, truth_table

BROOM_ABOVE_TOP_M = 0.2  # the broom head passes this far above the rock's top


@dataclass
class FrameInfo:
    """What was drawn in one frame: its capture time (s; the container's timestamp,
    field 0's time when interlaced) and the camera at that time."""

    index: int
    t: float
    camera: Camera


def _texture_bounds(path: CameraPath, times, rock_xy, cam0: Camera, height_m: float):
    """World rectangle seen by the camera over the shot, with a margin (m)."""
    W, H = cam0.width, cam0.height
    border = np.array([[u, v] for u in (0, W / 2, W - 1) for v in (0, H / 2, H - 1)], float)
    xd = cam0.to_normalized(border)
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
        rng, rng_cam, self._rng_scene, rng_sensor = (
            np.random.default_rng(s) for s in np.random.SeedSequence(int(seed)).spawn(4))
        fps = cfg.fps or rig.fps or series.meta.get("fps") or 30.0
        if not (np.isfinite(fps) and fps > 0):
            raise ParameterError(f"fps must be > 0, got {fps!r}", where="render.fps")
        # an NTSC rate given as 29.97 is 30000/1001 exactly, as the container writes it
        rate = frame_rate(fps)
        self.fps = float(rate) if rate.denominator == 1001 else float(fps)
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
        self.sensor = sen = cfg.sensor
        sen.validate(self.fps)
        self.exp = schedule(sen, self.fps, traj.duration, rng_sensor)
        self.t_frames = self.exp.frame_t
        self.colour = ColourControl(sen, -1.0 / self.fps, traj.duration + 1.0 / self.fps,
                                    rng_sensor)
        self.path = path = CameraPath(cam_cfg, cfg.width, cfg.height, traj.rock_xy,
                                      -1.0 / self.fps, traj.duration + 1.0 / self.fps,
                                      traj.travel_yaw, rng_cam)
        traj.align_to_image(path.yaw0 + np.pi / 2)
        self.cams_exp = [path.camera(t) for t in self.exp.t]
        self.cams = [self.cams_exp[i] for i in np.flatnonzero(self.exp.field == 0)]
        h_mid = 0.5 * rig.rock_height_m
        uv = np.array([c.project(np.r_[p, h_mid])[0]
                       for c, p in zip(self.cams_exp, traj.rock_xy(self.exp.t))])
        if not self.cams[0].in_image(uv).any():
            raise ParameterError("the rock is outside the view for the whole shot (check "
                                 "the camera offset, height and view)", where="render.camera")
        self.ppm_img = path.f_px / cam_cfg.height_m
        self.tex_z_m = -rig.grid_depth_m / N_ICE
        self.t_occ = (cfg.occlusion_t_s if cfg.occlusion_t_s is not None
                      else 0.4 * traj.t_motion_end)
        self._shadow_side = rng_cam.choice([-1.0, 1.0]) if cfg.shadow > 0 else 0.0
        self._drawn = None
        nsub = int(cfg.blur_subframes)
        self.offsets = ((np.arange(nsub) + 0.5) / nsub - 0.5) * cfg.shutter * self.exp.period

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
                               cfg.demosaic, self.sensor.readout_s,
                               self.shadow_at if cfg.shadow > 0 else None)
        self._drawn = True

    @property
    def n_frames(self) -> int:
        return len(self.t_frames)

    def shadow_at(self, t: float, XY) -> np.ndarray:
        """Light transmitted at world points ``XY`` (N, 2) under the walking person's
        shadow at time ``t`` (1 = none): an ellipse (``shadow_size_m`` by half of it)
        beside the rock's path, drifting over it and back (a sweeper's pace), with a
        soft penumbra (a high lamp: edges spread over ~15 % of its size)."""
        tr = self.traj
        P = tr.rock_xy(np.array([t]))[0]
        a, L = tr.travel_yaw, self.cfg.shadow_size_m
        along = np.array([np.cos(a), np.sin(a)])
        across = np.array([-along[1], along[0]])
        # over the rock and off it with a ~3 s period: the shadow crosses the markers
        off = self._shadow_side * L * (0.35 + 0.35 * np.sin(2 * np.pi * t / 3.0))
        d = np.asarray(XY, dtype=float) - (P + across * off + along * 0.1 * L)
        r = np.hypot((d @ along) / (0.5 * L), (d @ across) / (0.25 * L))
        prof = 0.5 * (1 - np.tanh((r - 1.0) / 0.15))
        return 1.0 - self.cfg.shadow * prof

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
        sen = self.sensor
        for k in range(start, stop):
            img = None
            for e in np.flatnonzero(self.exp.frame == k):
                te = self.exp.t[e]
                gains = self.colour.gains(te)[0] if self.colour.on else None
                one = self.comp.frame(te + self.offsets, self.path.camera, self.layers_at,
                                      self.tex, index=e, gains=gains, compress=False)
                if img is None:
                    img = one
                else:  # weave: this field's rows
                    rows = field_rows(sen, int(self.exp.field[e]))
                    img[rows] = one[rows]
            img = self.comp.compress(subsample_chroma(img, sen.chroma, sen.interlaced))
            yield img, FrameInfo(k, float(self.t_frames[k]), self.cams[k])

    def occluded_fraction(self, e: int) -> float:
        """Fraction of the rock's top (as imaged in exposure ``e``: frame ``e``, or a
        field when interlaced) hidden by the broom."""
        if not self.cfg.occlusion:
            return 0.0
        self._scene()
        t, cam, rig = self.exp.t[e], self.cams_exp[e], self.rig
        P = self.traj.rock_xy(np.array([t]))[0]
        r = 0.5 * rig.rock_diameter_m * 0.8
        g = np.linspace(-r, r, 15)
        gx, gy = np.meshgrid(g, g)
        inside = gx**2 + gy**2 <= r * r
        pts = np.column_stack([gx[inside] + P[0], gy[inside] + P[1],
                               np.full(inside.sum(), rig.rock_height_m)])
        # pinhole px of the top's points, mapped back through the broom's plane
        pu = cam.to_pixels(cam.normalized(pts))
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
        exp, sen = self.exp, self.sensor
        occ = [self.occluded_fraction(e) for e in range(len(exp.t))]
        data: pd.DataFrame = truth_table(self.traj, self.rig, self.path, self.cams_exp,
                                         exp.t, occ)
        data["frame"] = exp.frame
        if sen.interlaced:
            data.insert(1, "field", exp.field)
        if sen.readout_s > 0:
            drawn = np.array([self.drawn_px(e) for e in range(len(exp.t))])
            data["u_drawn_px"], data["v_drawn_px"] = drawn[:, 0], drawn[:, 1]
        if self.cfg.shadow > 0:
            centre = self.traj.rock_xy(exp.t)
            data["shadow"] = [1.0 - self.shadow_at(t, c[None])[0] for t, c in zip(exp.t, centre)]
        if self.colour.on:
            g = self.colour.gains(exp.t)
            data["gain_b"], data["gain_g"], data["gain_r"] = g[:, 0], g[:, 1], g[:, 2]
        meta = self.traj.sidecar(self.fps, self.n_frames, self.t_frames)
        if sen.interlaced:
            meta.update(fields=True, field_order=sen.field_order,
                        field_0_rows="odd" if sen.field_order == "bff" else "even")
        meta.update(readout_s=sen.readout_s, pixel_aspect=self.cam_cfg.pixel_aspect,
                    rotation_deg=self.cfg.encoding.rotation_deg,
                    variable_frame_rate=bool(sen.frame_jitter_s > 0 or sen.drop_rate > 0))
        meta.update(camera_height_m=self.cam_cfg.height_m,
                    grid_spacing_px=float(self.path.f_px * self.rig.spacing_x_m
                                          / (self.cam_cfg.height_m - self.tex_z_m)),
                    render=self.settings(), source=self.series_name)
        return Series(data, meta)

    def drawn_px(self, e: int, local_xy=(0.0, 0.0), z_m: float = 0.0) -> np.ndarray:
        """Where a point of the rock is drawn in exposure ``e`` (px): with a rolling
        shutter, the point on its path seen at its own sensor row's time.

        ``local_xy`` is the point in the rock's own frame (m; a marker's ``x_m, y_m``),
        ``z_m`` its height above the ice (m); default the centre on the ice.
        """
        def at(t):
            P = self.traj.rock_xy(np.array([t]))[0]
            psi = self.traj.psi(np.array([t]))[0]
            c, s = np.cos(psi), np.sin(psi)
            X = P + [c * local_xy[0] - s * local_xy[1], s * local_xy[0] + c * local_xy[1]]
            return self.path.camera(t).project([[X[0], X[1], z_m]])[0]

        t = self.exp.t[e]
        uv = at(t)
        for _ in range(30):  # fixed point of v = v(t + tau(v)): contracts fast
            new = at(t + row_time_offset(self.sensor.readout_s, self.cfg.height, uv[1]))
            if np.abs(new - uv).max() < 1e-9:
                return new
            uv = new
        return uv

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
