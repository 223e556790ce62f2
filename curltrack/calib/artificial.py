"""Synthetic overhead frames of the thread lattice with an exactly known camera.

The calibration's counterpart of trackpy's ``artificial.py``: tests draw frames here and
check the recovered homography and distortion against :class:`PinholeCamera`.  (Full
shot videos with a moving rock come from :mod:`curltrack.render`.)

World frame = the lattice frame: metres, x and y along the threads, z up, origin at a
thread crossing whose threads both have colour index 0 (thread ``i`` of either family
has colour ``colors[i % len(colors)]``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .lens import camera_matrix, distort, undistort


def _rot(axis: int, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    R = np.eye(3)
    R[i, i] = R[j, j] = c
    R[i, j], R[j, i] = -s, s
    return R


@dataclass
class PinholeCamera:
    """A camera above the ice looking down.

    Attributes
    ----------
    width, height : int
        Image size (px).
    f : float
        Focal length (px).
    position : (3,) array
        Lens centre in the lattice frame (m); ``position[2]`` is the height above the ice.
    yaw : float
        Rotation about the vertical (rad, CCW seen from above): at 0 the image's right is
        +x and the image's up is +y.
    tilt_x, tilt_y : float
        Small rotations about the world x and y axes (rad).
    k1, k2 : float
        Radial distortion (OpenCV convention, normalised by ``f``).
    principal_offset : (float, float)
        Principal point (= distortion centre) minus the image centre (px).
    """

    width: int = 960
    height: int = 540
    f: float = 800.0
    position: tuple = (0.0, 0.0, 2.0)
    yaw: float = 0.0
    tilt_x: float = 0.0
    tilt_y: float = 0.0
    k1: float = 0.0
    k2: float = 0.0
    principal_offset: tuple = (0.0, 0.0)

    @property
    def K(self) -> np.ndarray:
        K = camera_matrix(self.width, self.height, self.f)
        K[:2, 2] += self.principal_offset
        return K

    @property
    def dist(self) -> tuple:
        return (self.k1, self.k2, 0.0, 0.0, 0.0)

    @property
    def R(self) -> np.ndarray:
        """Camera-to-world rotation (camera axes: x right, y down, z along the view)."""
        looking_down = np.array([[1.0, 0, 0], [0, -1.0, 0], [0, 0, -1.0]])
        return (_rot(2, self.yaw) @ _rot(0, self.tilt_x) @ _rot(1, self.tilt_y)
                @ looking_down)

    def image_to_plane(self, pts_px, z: float = 0.0) -> np.ndarray:
        """Observed (distorted) pixels (N, 2) -> points on the plane at height ``z`` (N, 2) m."""
        q = (undistort(pts_px, self.K, self.dist) - self.K[:2, 2]) / self.f
        rays = np.column_stack([q, np.ones(len(q))]) @ self.R.T
        C = np.asarray(self.position, float)
        s = (z - C[2]) / rays[:, 2]
        return C[:2] + s[:, None] * rays[:, :2]

    def plane_to_image(self, pts_m, z: float = 0.0) -> np.ndarray:
        """Points on the plane at height ``z`` (N, 2) m -> observed (distorted) pixels."""
        p = np.asarray(pts_m, float)
        P = np.column_stack([p, np.full(len(p), z)]) - np.asarray(self.position, float)
        pc = P @ self.R  # world -> camera: R^T applied to row vectors
        q = pc[:, :2] / pc[:, 2:3]
        return distort(self.K[:2, 2] + self.f * q, self.K, self.dist)

    def undistorted_to_plane_h(self) -> np.ndarray:
        """The exact homography: undistorted pixels -> lattice-frame metres (z = 0)."""
        src = np.array([[0.0, 0], [self.width, 0], [self.width, self.height],
                        [0, self.height]])
        from .lens import distort as _d
        dst = self.image_to_plane(_d(src, self.K, self.dist))
        import cv2

        return cv2.getPerspectiveTransform(src.astype(np.float32), dst.astype(np.float32)
                                           ).astype(float)


def draw_lattice(cam: PinholeCamera, spacing_x_m: float = 0.15, spacing_y_m: float = 0.15,
                 colors=((208, 32, 32), (32, 64, 208)), thread_width_m: float = 0.003,
                 ice_rgb=(228, 234, 240), contrast: float = 0.6, blur_px: float = 0.8,
                 noise: float = 2.0, texture: float = 6.0, seed: int = 0,
                 rock=None, supersample: int = 1) -> np.ndarray:
    """Draw one BGR uint8 frame of the lattice seen by ``cam``.

    Parameters
    ----------
    cam : PinholeCamera
    spacing_x_m, spacing_y_m : float
        Thread spacing (m) across x (threads along y) and across y.
    colors : sequence of (R, G, B)
        Thread colours repeating across each family.
    thread_width_m : float
        Thread width (m).
    ice_rgb : (R, G, B)
        Ice colour.
    contrast : float
        Opacity of a thread (0-1); fine threads under ice are faint.
    blur_px, noise, texture : float
        Gaussian blur sigma (px), pixel noise sigma (grey levels), and amplitude of a
        smooth random ice texture fixed to the ice (grey levels).
    seed : int
    rock : dict, optional
        ``{"center": (x, y), "radius": r, "height": h, "angle": a, "markers":
        [((x, y), (R, G, B)), ...]}`` in the lattice frame (m): a grey disc on the plane
        at height h with coloured marker dots (radius 0.02 m).
    supersample : int
        Anti-aliasing factor.

    Returns
    -------
    ndarray (height, width, 3) uint8
    """
    import cv2

    rng = np.random.default_rng(seed)
    ss = supersample
    yy, xx = np.mgrid[0:cam.height * ss, 0:cam.width * ss].astype(float)
    px = np.column_stack([(xx.ravel() + 0.5) / ss - 0.5, (yy.ravel() + 0.5) / ss - 0.5])
    w = cam.image_to_plane(px)
    img = np.tile(np.asarray(ice_rgb, float), (len(px), 1))
    if texture:
        # Smooth texture attached to the ice (moves with it): sum of random sinusoids.
        k = rng.normal(0, 1, (8, 2)) * 8.0
        ph = rng.uniform(0, 2 * np.pi, 8)
        tex = np.zeros(len(w))
        for (kx, ky), p in zip(k, ph):
            tex += np.sin(w[:, 0] * kx + w[:, 1] * ky + p)
        img += (tex * texture / np.sqrt(8))[:, None]
    half = thread_width_m / 2
    px_per_m = cam.f * ss / cam.position[2]
    for fam, (coord, sp) in enumerate(((w[:, 0], spacing_x_m), (w[:, 1], spacing_y_m))):
        idx = np.round(coord / sp)
        d = np.abs(coord - idx * sp)
        # Box-filtered coverage of a pixel by the thread (px per m ~ f / height).
        on = np.clip((half - d) * px_per_m + 0.5, 0.0, 1.0)
        sel = np.nonzero(on > 0)[0]
        col = np.asarray(colors, float)[idx[sel].astype(int) % len(colors)]
        a = contrast * on[sel, None]
        img[sel] = img[sel] * (1 - a) + col * a
    if rock is not None:
        top = cam.image_to_plane(px, z=rock["height"])
        rc = np.asarray(rock["center"], float)
        inside = np.hypot(*(top - rc).T) < rock["radius"]
        img[inside] = (120, 118, 115)
        ca, sa = np.cos(rock.get("angle", 0.0)), np.sin(rock.get("angle", 0.0))
        for (mx, my), rgb in rock.get("markers", ()):
            m = rc + (ca * mx - sa * my, sa * mx + ca * my)
            img[np.hypot(*(top - m).T) < 0.02] = rgb
    img = img.reshape(cam.height * ss, cam.width * ss, 3)
    if ss > 1:
        img = cv2.resize(img, (cam.width, cam.height), interpolation=cv2.INTER_AREA)
    if blur_px > 0:
        img = cv2.GaussianBlur(img, (0, 0), blur_px)
    img = img + rng.normal(0, noise, img.shape)
    return np.clip(img[:, :, ::-1], 0, 255).round().astype(np.uint8)
