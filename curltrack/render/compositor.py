"""Per-frame image formation: warp the ice and the rock, blur, distort, vignette, noise.

The scene is warped onto an *undistorted* canvas (a pinhole image slightly larger than
the output, so that barrel distortion has pixels to pull in), one warp per sub-frame;
the sub-frames are averaged (motion blur), then one fixed ``cv2.remap`` applies the lens
distortion, then vignetting and sensor noise, then optional JPEG-style compression.
"""

from __future__ import annotations

import cv2
import numpy as np

from .camera import Camera
from .scene import Sprite, Texture


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
    """

    def __init__(self, camera: Camera, vignetting: float, read_noise: float,
                 shot_noise_gain: float, jpeg_quality: int | None, rng: np.random.Generator):
        self.cam = camera
        W, H = camera.width, camera.height
        uu, vv = np.meshgrid(np.arange(W, dtype=float), np.arange(H, dtype=float))
        xd = np.stack([(uu - camera.cx) / camera.f_px, (vv - camera.cy) / camera.f_px], -1)
        xu = camera.undistort(xd.reshape(-1, 2)).reshape(H, W, 2)
        pu = xu * camera.f_px + np.array([camera.cx, camera.cy])
        lo = np.floor(pu.reshape(-1, 2).min(0)) - 3
        hi = np.ceil(pu.reshape(-1, 2).max(0)) + 3
        self.offset = -lo  # canvas px = undistorted px + offset
        self.canvas_size = (int(hi[0] - lo[0]) + 1, int(hi[1] - lo[1]) + 1)  # (w, h)
        self.T = _translate(*self.offset)
        m = (pu + self.offset).astype(np.float32)
        self.map1, self.map2 = cv2.convertMaps(m[..., 0], m[..., 1], cv2.CV_16SC2)
        r2 = ((uu - camera.cx) ** 2 + (vv - camera.cy) ** 2)
        self.vignette = (1.0 - vignetting * (r2 / r2.max()) ** 1.25).astype(np.float32)
        self.read_noise, self.gain = float(read_noise), float(shot_noise_gain)
        self.jpeg_quality = jpeg_quality
        self.rng = rng
        pad = 32
        self._bank = [cv2.GaussianBlur(rng.standard_normal((H + pad, W + pad, 3),
                                                           dtype=np.float32), (0, 0), 0.5) * 1.6
                      for _ in range(4)]
        self._pad = pad
        self.acc = np.zeros((self.canvas_size[1], self.canvas_size[0], 3), np.float32)

    def ice_homography(self, cam: Camera, tex: Texture) -> np.ndarray:
        """Texture (col, row) -> canvas px at pose ``cam``."""
        return self.T @ cam.plane_homography(tex.z_m) @ tex.affine

    def sprite_homography(self, cam: Camera, sprite: Sprite, pose: np.ndarray) -> np.ndarray:
        """Sprite (col, row) -> canvas px for an object at world ``pose`` (3x3)."""
        return self.T @ cam.plane_homography(sprite.z_m) @ pose @ sprite.affine

    def begin(self) -> None:
        self.acc[:] = 0.0
        self._n = 0

    def add_subframe(self, cam: Camera, tex: Texture, layers) -> None:
        """Add one sub-frame: the ice warped for ``cam``, then ``layers`` composited.

        ``layers`` : list of (Sprite, pose 3x3), bottom to top.
        """
        size = self.canvas_size
        bg = cv2.warpPerspective(tex.image, self.ice_homography(cam, tex), size,
                                 flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
        cv2.accumulate(bg, self.acc)
        self._n += 1
        if not layers:
            return
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
        if not boxes:
            return
        b = np.array(boxes)
        x0 = int(max(0, np.floor(b[:, 0].min()) - 1))
        y0 = int(max(0, np.floor(b[:, 1].min()) - 1))
        x1 = int(min(size[0], np.ceil(b[:, 2].max()) + 2))
        y1 = int(min(size[1], np.ceil(b[:, 3].max()) + 2))
        if x1 <= x0 or y1 <= y0:
            return
        roi_bg = bg[y0:y1, x0:x1].astype(np.float32)
        comp = roi_bg.copy()
        Troi = _translate(-x0, -y0)
        for sprite, Hs in homs:
            warped = cv2.warpPerspective(sprite.rgba, Troi @ Hs, (x1 - x0, y1 - y0),
                                         flags=cv2.INTER_LINEAR,
                                         borderMode=cv2.BORDER_CONSTANT, borderValue=0)
            a = warped[..., 3:4]
            comp *= 1.0 - a
            comp += warped[..., :3]
        self.acc[y0:y1, x0:x1] += comp - roi_bg

    def finish(self) -> np.ndarray:
        """Average the sub-frames, distort, vignette, add noise; the final BGR uint8 frame."""
        img = cv2.remap(self.acc, self.map1, self.map2, cv2.INTER_LINEAR)
        img *= (self.vignette / max(self._n, 1))[..., None]
        if self.read_noise > 0 or self.gain > 0:
            H, W = img.shape[:2]
            bank = self._bank[int(self.rng.integers(len(self._bank)))]
            oy, ox = self.rng.integers(0, self._pad, 2)
            noise = bank[oy:oy + H, ox:ox + W]
            sigma = np.sqrt(self.read_noise**2 + self.gain * np.maximum(img, 0.0))
            img += noise * sigma
        np.clip(img, 0, 255, out=img)
        out = (img + 0.5).astype(np.uint8)
        if self.jpeg_quality:
            ok, buf = cv2.imencode(".jpg", out, [cv2.IMWRITE_JPEG_QUALITY, int(self.jpeg_quality)])
            out = cv2.imdecode(buf, cv2.IMREAD_COLOR)
        return out
