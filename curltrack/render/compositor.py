"""Per-frame image formation: warp the ice and the rock, blur, distort, light, noise.

The scene is warped onto an *undistorted* canvas (a pinhole image slightly larger than
the output, so that barrel distortion has pixels to pull in).  Motion blur averages
sub-frames: the ice as one warp convolved with the sub-frames' shift kernel when the
camera translates (or several warps when it turns), the box around the rock as every
sub-frame exactly.  Then one fixed ``cv2.remap`` applies the lens distortion, then lamp
glare, vignetting, flicker and sensor noise, then optional JPEG-style compression.
"""

from __future__ import annotations

import cv2
import numpy as np

from .camera import Camera
from .ice import Texture
from .sensor import row_time_offset
from .sprites import Sprite


def _translate(dx: float, dy: float) -> np.ndarray:
    return np.array([[1, 0, dx], [0, 1, dy], [0, 0, 1.0]])


def pose_matrix(x: float, y: float, psi: float | None) -> np.ndarray:
    """3x3 map from an object's local plane coordinates to world (X, Y) (m, rad)."""
    if psi is None:
        return _translate(x, y)
    c, s = np.cos(psi), np.sin(psi)
    return np.array([[c, -s, x], [s, c, y], [0, 0, 1.0]])


class Compositor:
    """Renders frames for one camera intrinsics / image size.

    Parameters
    ----------
    camera : Camera
        Any pose; only the intrinsics and distortion are used here.
    vignetting : float
        Relative brightness loss at the image corners (0-1).
    read_noise : float
        RMS of the signal-independent sensor noise (0-255 levels).
    shot_noise_gain : float
        Shot noise variance per level of signal (levels): sigma^2 = read^2 + gain * I.
    jpeg_quality : int or None
        Extra per-frame JPEG compression (0-100), None = off.
    rng : numpy.random.Generator
        Draws the noise bank; each frame's noise and flicker come from a generator
        seeded by (a number drawn here, frame index), so any frame renders alike alone.
    glare : (lamps (N, 3) m, peak levels, spread rad), optional
        Diffuse reflections of the lamps in the ice: each lamp's mirror image (below the
        ice, so it moves against the lattice as the camera moves) as a broad Gaussian.
    flicker : float
        Relative RMS of the frame-to-frame brightness (lamp flicker, auto exposure).
    demosaic : bool
        Sample through a Bayer colour filter (B at even rows and columns, R at odd ones),
        add the noise per photosite, and demosaic (OpenCV bilinear), as a colour sensor
        does; otherwise add slightly blurred noise to each channel.
    readout_s : float
        Rolling shutter readout time (s), 0 = global shutter (see :mod:`~.sensor`).
    shadow : callable, optional
        ``(t, XY (N, 2) world m) -> transmitted fraction (N,)``: a shadow on the ice.
    """

    def __init__(self, camera: Camera, vignetting: float, read_noise: float,
                 shot_noise_gain: float, jpeg_quality: int | None, rng: np.random.Generator,
                 glare=None, flicker: float = 0.0, demosaic: bool = False,
                 readout_s: float = 0.0, shadow=None):
        self.cam = camera
        W, H = camera.width, camera.height
        uu, vv = np.meshgrid(np.arange(W, dtype=float), np.arange(H, dtype=float))
        xd = camera.to_normalized(np.stack([uu, vv], -1).reshape(-1, 2))
        pu = camera.to_pixels(camera.undistort(xd)).reshape(H, W, 2)
        lo = np.floor(pu.reshape(-1, 2).min(0)) - 3
        hi = np.ceil(pu.reshape(-1, 2).max(0)) + 3
        self.offset = -lo  # canvas px = undistorted px + offset
        self.canvas_size = (int(hi[0] - lo[0]) + 1, int(hi[1] - lo[1]) + 1)  # (w, h)
        self.T = _translate(*self.offset)
        m = (pu + self.offset).astype(np.float32)
        self.map1, self.map2 = cv2.convertMaps(m[..., 0], m[..., 1], cv2.CV_16SC2)
        r2 = ((uu - camera.cx) ** 2 + (vv - camera.cy) ** 2)
        self.vignette = (1.0 - vignetting * (r2 / r2.max()) ** 1.25).astype(np.float32)
        self.vignette3 = np.repeat(self.vignette[..., None], 3, axis=2)
        self.read_noise, self.gain = float(read_noise), float(shot_noise_gain)
        self.jpeg_quality = jpeg_quality
        self.rng = rng
        self.max_step_px = 1.5
        pad = 32
        self.demosaic = bool(demosaic)
        if self.demosaic:
            self._bank = [rng.standard_normal((H + pad, W + pad), dtype=np.float32)
                          for _ in range(4)]
        else:  # the blur stands for demosaicing's correlation; 1.6 restores unit RMS
            self._bank = [cv2.GaussianBlur(rng.standard_normal((H + pad, W + pad, 3),
                                                               dtype=np.float32), (0, 0), 0.5)
                          * 1.6 for _ in range(4)]
        self._pad = pad
        self.acc = np.zeros((self.canvas_size[1], self.canvas_size[0], 3), np.float32)
        self.glare = glare
        self.flicker = float(flicker)
        self._flicker_phase = rng.uniform(0, 2 * np.pi)
        self._frame_seed = int(rng.integers(2**63))
        self.readout_s = float(readout_s)
        self.shadow = shadow
        n_knots = int(np.ceil(self.readout_s / 0.002)) + 1 if self.readout_s > 0 else 2
        self._knots = np.linspace(-0.5, 0.5, n_knots) * self.readout_s
        self._gains, self._compress = None, True

    def ice_homography(self, cam: Camera, tex: Texture) -> np.ndarray:
        """Texture (col, row) -> canvas px at pose ``cam``."""
        return self.T @ cam.plane_homography(tex.z_m) @ tex.affine

    def sprite_homography(self, cam: Camera, sprite: Sprite, pose: np.ndarray) -> np.ndarray:
        """Sprite (col, row) -> canvas px for an object at world ``pose`` (3x3)."""
        return self.T @ cam.plane_homography(sprite.z_m) @ pose @ sprite.affine

    def _sprite_boxes(self, cam: Camera, layers):
        """Homographies of ``layers`` at ``cam`` and their canvas bounding box."""
        homs, boxes = [], []
        for sprite, pose in layers:
            Hs = self.sprite_homography(cam, sprite, pose)
            h, w = sprite.rgba.shape[:2]
            corners = np.array([[0, 0, 1], [w - 1, 0, 1], [0, h - 1, 1], [w - 1, h - 1, 1.0]])
            p = corners @ Hs.T
            if (p[:, 2] <= 0).any():
                continue
            p = p[:, :2] / p[:, 2:]
            homs.append((sprite, Hs))
            boxes.append(np.r_[p.min(0), p.max(0)])
        return homs, boxes

    def _bg_motion(self, cam_first: Camera, cam_last: Camera, tex: Texture):
        """How the ice moves in the canvas over the exposure.

        Returns ``(n, d, uniform)``: background sub-frames needed for steps of at most
        ``max_step_px``, the displacement at the canvas centre (px), and whether the
        motion is a translation over the whole canvas to 0.25 px or 6 % (tilt and wobble
        make it slightly uneven); then the average of shifted copies stands for the
        average of warps (the blur length is right to that tolerance).
        """
        w, h = self.canvas_size
        pts = np.array([[0, 0, 1], [w, 0, 1], [0, h, 1], [w, h, 1], [w / 2, h / 2, 1.0]])
        M = self.ice_homography(cam_last, tex) @ np.linalg.inv(self.ice_homography(cam_first, tex))
        q = pts @ M.T
        disp = q[:, :2] / q[:, 2:] - pts[:, :2]
        n = int(np.ceil(np.hypot(*disp.T).max() / self.max_step_px)) + 1
        spread = np.hypot(*(disp - disp[-1]).T).max()
        uniform = spread < max(0.25, 0.06 * np.hypot(*disp[-1]))
        return n, disp[-1], uniform

    @staticmethod
    def _shift_kernel(offsets):
        """Correlation kernel averaging bilinear copies shifted by ``offsets`` (k, 2) px."""
        s = -np.asarray(offsets, dtype=float)
        half = int(np.ceil(np.abs(s).max())) + 1
        K = np.zeros((2 * half + 1, 2 * half + 1), np.float32)
        for sx, sy in s:
            ax, ay = int(np.floor(sx)), int(np.floor(sy))
            fx, fy = sx - ax, sy - ay
            for dy, wy in ((0, 1 - fy), (1, fy)):
                for dx, wx in ((0, 1 - fx), (1, fx)):
                    K[half + ay + dy, half + ax + dx] += wx * wy / len(s)
        rows, cols = np.flatnonzero(K.any(1)), np.flatnonzero(K.any(0))
        K = K[rows[0]:rows[-1] + 1, cols[0]:cols[-1] + 1]
        return K, (half - cols[0], half - rows[0])

    def frame(self, times, cam_at, layers_at, tex: Texture, index: int = 0, gains=None,
              compress: bool = True) -> np.ndarray:
        """Render one frame exposed over the sub-frame ``times`` (s).

        The ice: when the camera translates (the ice moves alike over the whole view,
        see :meth:`_bg_motion`) the sub-frame average is one warp convolved with the kernel of the
        sub-frames' shifts; otherwise enough warps that consecutive ones differ by at most
        ``max_step_px`` are averaged.  The box around the rock (and broom) is averaged
        over every sub-frame, with the ice warped into the box for each, so the moving
        rock's blur is the exact sub-frame average.  With a rolling shutter every pixel
        is drawn as seen at its sensor row's own time (see :mod:`~.sensor`).

        Parameters
        ----------
        times : array
            Sub-frame times (s), in order (of the reference row, with a rolling shutter).
        cam_at : callable
            t -> Camera.
        layers_at : callable
            t -> list of (Sprite, world pose 3x3), bottom to top.
        tex : Texture
        index : int
            Exposure index: seeds this exposure's noise and flicker.
        gains : (3,) array, optional
            Multipliers of the B, G, R channels (auto exposure, white balance).
        compress : bool
            Apply the configured JPEG pass (False: the caller compresses later).
        """
        self.rng = np.random.default_rng((self._frame_seed, int(index)))
        cams = [cam_at(t) for t in times]
        n = len(times)
        self._t_mid = 0.5 * (times[0] + times[-1])
        self._cam_mid = cam_at(self._t_mid)
        self._gains = None if gains is None else np.asarray(gains, np.float32)
        self._compress = compress
        size = self.canvas_size
        n_bg, d, uniform = self._bg_motion(cams[0], cams[-1], tex) if n > 1 else (1, 0, True)
        if n_bg <= 1 or (uniform and n_bg > 1 and np.abs(d).max() < 24):
            # one warp at mid-exposure; a camera translating over the ice shifts the
            # whole canvas alike, so the sub-frame average is a small shift kernel
            bg = self._ice(self._t_mid, self._cam_mid, cam_at, tex)
            if n_bg <= 1:
                self.acc[:] = bg
            else:
                frac = np.linspace(-0.5, 0.5, n)[:, None]
                K, anchor = self._shift_kernel(frac * np.asarray(d)[None, :])
                cv2.filter2D(bg.astype(np.float32), -1, K, dst=self.acc, anchor=anchor,
                             borderType=cv2.BORDER_REFLECT)
        else:
            bg_times = times if n_bg >= n else np.linspace(times[0], times[-1], n_bg)
            bg_cams = cams if n_bg >= n else [cam_at(t) for t in bg_times]
            self.acc[:] = 0.0
            for t, c in zip(bg_times, bg_cams):
                cv2.accumulate(self._ice(t, c, cam_at, tex), self.acc)
            self.acc *= 1.0 / len(bg_cams)
        if self.readout_s > 0:
            per_sub = [self._sprite_boxes(cam_at(t + k), layers_at(t + k))
                       for t in times for k in self._knots[[0, -1]]]
        else:
            per_sub = [self._sprite_boxes(c, layers_at(t)) for c, t in zip(cams, times)]
        boxes = [b for _, bx in per_sub for b in bx]
        if not boxes:
            return self._finish()
        b = np.array(boxes)
        x0 = int(max(0, np.floor(b[:, 0].min()) - 1))
        y0 = int(max(0, np.floor(b[:, 1].min()) - 1))
        x1 = int(min(size[0], np.ceil(b[:, 2].max()) + 2))
        y1 = int(min(size[1], np.ceil(b[:, 3].max()) + 2))
        if x1 <= x0 or y1 <= y0:
            return self._finish()
        box = (x1 - x0, y1 - y0)
        Troi = _translate(-x0, -y0)
        roi = np.zeros((box[1], box[0], 3), np.float32)
        for i, (c, t) in enumerate(zip(cams, times)):
            if self.readout_s > 0:
                roi += self._box_rolling(t, (x0, y0), box, cam_at, layers_at, tex)
                continue
            comp = cv2.warpPerspective(tex.image, Troi @ self.ice_homography(c, tex), box,
                                       flags=cv2.INTER_LINEAR,
                                       borderMode=cv2.BORDER_REFLECT).astype(np.float32)
            for sprite, Hs in per_sub[i][0]:
                warped = cv2.warpPerspective(sprite.rgba, Troi @ Hs, box, flags=cv2.INTER_LINEAR,
                                             borderMode=cv2.BORDER_CONSTANT, borderValue=0)
                comp *= 1.0 - warped[..., 3:4]
                comp += warped[..., :3]
            roi += comp
        self.acc[y0:y1, x0:x1] = roi * (1.0 / n)
        return self._finish()

    # --- rolling shutter ------------------------------------------------------------

    def _ice(self, t: float, cam: Camera, cam_at, tex: Texture) -> np.ndarray:
        """The ice on the canvas at time ``t`` (each row at its own time if rolling)."""
        if self.readout_s <= 0:
            return cv2.warpPerspective(tex.image, self.ice_homography(cam, tex),
                                       self.canvas_size, flags=cv2.INTER_LINEAR,
                                       borderMode=cv2.BORDER_REFLECT)
        return self._ice_rolling(t, (0, 0), self.canvas_size, cam_at, tex)

    def _ice_rolling(self, t, origin, box, cam_at, tex: Texture) -> np.ndarray:
        """The ice in the canvas block ``box`` (w, h) at ``origin``, rows at their times."""
        mx, my = self._coarse_maps(
            lambda X, Y: self._rolling_map(t, X, Y, lambda c, _: self.ice_homography(c, tex),
                                           cam_at, lambda _: None), *origin, *box)
        return cv2.remap(tex.image, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)

    def _row_offset(self, X, Y) -> np.ndarray:
        """Canvas px -> its sensor row's exposure time minus the reference (s)."""
        cam = self.cam
        und = np.stack(np.broadcast_arrays(X - self.offset[0], Y - self.offset[1]), -1)
        v = cam.to_pixels(cam.distort(cam.to_normalized(und)))[..., 1]
        return row_time_offset(self.readout_s, cam.height, v)

    def _rolling_map(self, t, X, Y, hom_at, cam_at, state_at):
        """Source coordinates of canvas points (X, Y), each seen at its row's time.

        ``hom_at(camera, state)`` is the source -> canvas homography at a knot time,
        ``state_at(time)`` what else it needs there.  Piecewise-linear in time between
        the knots (``_knots``, ~2 ms apart: the motion's curvature over one step is far
        below a micrometre).
        """
        tau = self._row_offset(X, Y)
        kn = self._knots
        dk = kn[1] - kn[0]
        f = np.clip((tau - kn[0]) / dk, 0, len(kn) - 1 - 1e-9)
        i = np.floor(f).astype(int)
        w = (f - i)[..., None]
        lo, hi = int(i.min()), int(i.max()) + 1
        P = np.stack(np.broadcast_arrays(X, Y, np.ones_like(X)), -1).astype(float)
        src = []
        for k in kn[lo:hi + 1]:
            G = np.linalg.inv(hom_at(cam_at(t + k), state_at(t + k)))
            q = P @ G.T
            src.append(q[..., :2] / q[..., 2:])
        src = np.stack(src)  # (knots, ...)
        idx = (i - lo)[None, ..., None]
        a = np.take_along_axis(src, idx, 0)[0]
        b = np.take_along_axis(src, idx + 1, 0)[0]
        out = a + w * (b - a)
        return out[..., 0], out[..., 1]

    @staticmethod
    def _coarse_maps(fn, x0: int, y0: int, w: int, h: int, step: int = 4):
        """``fn(X, Y) -> (mapx, mapy)`` evaluated every ``step`` px and bilinearly
        upsampled to the ``w x h`` block whose top-left canvas px is ``(x0, y0)``: the
        maps are smooth, so this is exact to far below a pixel and 16x cheaper."""
        nx, ny = -(-w // step) + 2, -(-h // step) + 2
        # cv2.resize (x step) puts coarse sample k at fine px step k + (step - 1) / 2
        X = x0 - step + step * np.arange(nx) + (step - 1) / 2
        Y = y0 - step + step * np.arange(ny) + (step - 1) / 2
        mx, my = fn(X[None, :], Y[:, None])
        up = cv2.resize(np.dstack([mx, my]).astype(np.float32), (nx * step, ny * step),
                        interpolation=cv2.INTER_LINEAR)
        up = up[step:step + h, step:step + w]
        return np.ascontiguousarray(up[..., 0]), np.ascontiguousarray(up[..., 1])

    def _box_rolling(self, t, origin, box, cam_at, layers_at, tex) -> np.ndarray:
        """The box around the rock at sub-frame ``t``, each row at its own time."""
        comp = self._ice_rolling(t, origin, box, cam_at, tex).astype(np.float32)
        for sprite, pose_t in layers_at(t):
            def pose(tk, sprite=sprite, pose_t=pose_t):
                # (a layer that leaves at a knot, the broom far off, keeps its pose at t)
                found = [p for s, p in layers_at(tk) if s is sprite]
                return found[0] if found else pose_t
            mx, my = self._coarse_maps(
                lambda X, Y: self._rolling_map(
                    t, X, Y, lambda c, p: self.sprite_homography(c, sprite, p), cam_at, pose),
                *origin, *box)
            warped = cv2.remap(sprite.rgba, mx, my, cv2.INTER_LINEAR,
                               borderMode=cv2.BORDER_CONSTANT, borderValue=0)
            comp *= 1.0 - warped[..., 3:4]
            comp += warped[..., :3]
        return comp

    def _glare_image(self, cam: Camera):
        """The lamps' diffuse reflections seen by ``cam``: (H, W, 3) levels, or None.

        Each is a broad Gaussian around the (distorted) image of the lamp's mirror point.
        """
        lamps, peak, spread = self.glare
        pc = cam.to_camera(lamps)
        front = pc[:, 2] > 0
        if not front.any() or peak <= 0:
            return None
        uv = cam.to_pixels(cam.distort(pc[front, :2] / pc[front, 2:]))
        sigma = spread * cam.f_px  # (the glare is broad: its small anisotropy is ignored)
        W, H = cam.width, cam.height
        near = ((uv[:, 0] > -4 * sigma) & (uv[:, 0] < W + 4 * sigma)
                & (uv[:, 1] > -4 * sigma) & (uv[:, 1] < H + 4 * sigma))
        if not near.any():
            return None
        uv = uv[near]
        # on a grid 8x coarser (the field is smooth), then resized: cv2.resize puts
        # coarse sample k at pixel 8 k + 3.5
        cu = np.arange((W + 7) // 8) * 8 + 3.5
        cv = np.arange((H + 7) // 8) * 8 + 3.5
        gx = np.exp(-0.5 * ((cu[:, None] - uv[:, 0]) / sigma) ** 2)
        gy = peak * np.exp(-0.5 * ((cv[:, None] - uv[:, 1]) / sigma) ** 2)
        g = np.einsum("vi,ui->vu", gy, gx).astype(np.float32)  # no BLAS threads
        g = cv2.resize(g, (len(cu) * 8, len(cv) * 8), interpolation=cv2.INTER_LINEAR)
        return np.repeat(g[:H, :W, None], 3, axis=2)

    def _shadow_image(self, cam: Camera, t: float) -> np.ndarray:
        """Transmitted light (H, W, 3) under a person's soft shadow on the ice at ``t``:
        ``1 - depth * s`` with ``s`` the shadow's profile on the ice plane (see
        :meth:`~.production.Production.shadow_at`), seen through ``cam``."""
        W, H = cam.width, cam.height
        n = 4  # a grid n px coarse (the penumbra is smooth), resized: sample k at n k + 1.5
        cu = np.arange((W + n - 1) // n) * n + (n - 1) / 2
        cv = np.arange((H + n - 1) // n) * n + (n - 1) / 2
        uv = np.stack(np.meshgrid(cu, cv), -1).reshape(-1, 2)
        pu = cam.to_pixels(cam.undistort(cam.to_normalized(uv)))
        q = np.c_[pu, np.ones(len(pu))] @ np.linalg.inv(cam.plane_homography(0.0)).T
        XY = q[:, :2] / q[:, 2:]
        s = self.shadow(t, XY).reshape(len(cv), len(cu)).astype(np.float32)
        s = cv2.resize(s, (len(cu) * n, len(cv) * n), interpolation=cv2.INTER_LINEAR)
        return np.repeat(s[:H, :W, None], 3, axis=2)

    @staticmethod
    def _mosaic(img: np.ndarray) -> np.ndarray:
        """The photosite values of a Bayer sensor: B G / G R in each 2x2 cell."""
        mos = np.empty(img.shape[:2], np.float32)
        mos[0::2, 0::2] = img[0::2, 0::2, 0]
        mos[0::2, 1::2] = img[0::2, 1::2, 1]
        mos[1::2, 0::2] = img[1::2, 0::2, 1]
        mos[1::2, 1::2] = img[1::2, 1::2, 2]
        return mos

    def _finish(self) -> np.ndarray:
        """Glare, distort, vignette and flicker, noise; the final BGR uint8 frame."""
        img = cv2.remap(self.acc, self.map1, self.map2, cv2.INTER_LINEAR)
        if self.shadow is not None:
            cv2.multiply(img, self._shadow_image(self._cam_mid, self._t_mid), dst=img)
        glare = self._glare_image(self._cam_mid) if self.glare is not None else None
        if glare is not None:
            cv2.add(img, glare, dst=img)
        gain = 1.0
        if self.flicker > 0:
            gain += self.flicker * (np.sin(2 * np.pi * 0.7 * self._t_mid + self._flicker_phase)
                                    * np.sqrt(0.5) + 0.5 * self.rng.standard_normal())
        if self._gains is not None:
            cv2.multiply(img, self.vignette3 * self._gains, dst=img, scale=gain)
        else:
            cv2.multiply(img, self.vignette3, dst=img, scale=gain)
        if self.demosaic:
            img = self._mosaic(img)
        if self.read_noise > 0 or self.gain > 0:
            H, W = img.shape[:2]
            bank = self._bank[int(self.rng.integers(len(self._bank)))]
            oy, ox = self.rng.integers(0, self._pad, 2)
            noise = bank[oy:oy + H, ox:ox + W]
            # sigma^2 = read^2 + gain * signal (shot noise), signal clipped at 0
            var = cv2.max(img, 0.0)
            cv2.addWeighted(var, self.gain, var, 0.0, self.read_noise**2, dst=var)
            cv2.sqrt(var, dst=var)
            cv2.multiply(var, noise, dst=var)
            cv2.add(img, var, dst=img)
        out = cv2.convertScaleAbs(cv2.max(img, 0.0))  # rounds, saturates at 255
        if self.demosaic:
            out = cv2.cvtColor(out, cv2.COLOR_BayerRG2BGR)  # OpenCV's name for this layout
        return self.compress(out) if self._compress else out

    def compress(self, out: np.ndarray) -> np.ndarray:
        """The configured extra JPEG pass (blocking and ringing), if any."""
        if self.jpeg_quality:
            ok, buf = cv2.imencode(".jpg", out, [cv2.IMWRITE_JPEG_QUALITY, int(self.jpeg_quality)])
            out = cv2.imdecode(buf, cv2.IMREAD_COLOR)
        return out
