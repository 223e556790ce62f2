"""The rock and the broom as planar sprites: premultiplied float32 BGRA (colour times
alpha) images of a plane at a known height, in the object's own frame, pre-rendered once
and warped per (sub)frame by the homography of their plane.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..rig import Rig
from .ice import bgr


@dataclass
class Sprite:
    """A premultiplied BGRA image of a plane at height ``z_m`` in an object's frame.

    ``local = ((col - c0) / ppm, (c0 - row) / ppm)`` (m): rows run towards local -y so
    that the sprite is the object seen from above.  ``attached`` sprites turn with the
    rock; others keep their world orientation (the shadow).
    """

    rgba: np.ndarray
    ppm: float
    z_m: float
    attached: bool = True

    @property
    def affine(self) -> np.ndarray:
        """3x3 map from (col, row, 1) to local (x, y, 1) (m)."""
        c0 = (self.rgba.shape[1] - 1) / 2.0
        s = 1.0 / self.ppm
        return np.array([[s, 0, -c0 * s], [0, -s, c0 * s], [0, 0, 1.0]])


def _grid(half_m: float, ppm: float):
    n = int(np.ceil(2 * half_m * ppm)) | 1  # odd: the centre is a texel centre
    c = (np.arange(n) - (n - 1) / 2.0) / ppm
    return np.meshgrid(c, -c)


def _disc(x, y, cx, cy, radius, aa_m):
    """Coverage (0-1) of a disc with an edge ramp ``aa_m`` wide (m): one image pixel,
    so that the warped edge is box-filtered like a camera pixel, not aliased."""
    return np.clip(0.5 + (radius - np.hypot(x - cx, y - cy)) / aa_m, 0, 1).astype(np.float32)


def _granite(shape, rng, tone, contrast, ppm):
    g = rng.standard_normal(shape, dtype=np.float32)
    coarse = cv2.GaussianBlur(g, (0, 0), max(0.004 * ppm, 0.8))
    coarse /= coarse.std() + 1e-9
    grain = cv2.GaussianBlur(rng.standard_normal(shape, dtype=np.float32), (0, 0), 0.8)
    grain /= grain.std() + 1e-9
    spots = (rng.random(shape) < 0.01).astype(np.float32)
    spots = cv2.GaussianBlur(spots, (0, 0), max(0.0015 * ppm, 0.6)) * 40
    return tone + contrast * (0.6 * coarse + 0.4 * grain) - 30 * np.clip(spots, 0, 1)


def _premul(color_bgr, alpha):
    return np.dstack([color_bgr * alpha[..., None], alpha]).astype(np.float32)


# Rock profile (fraction of rig height, fraction of rig diameter/2) from the running band
# up to the top: widest at the striking band.
_PROFILE = ((0.25, 0.91), (0.48, 1.0), (0.7, 0.97), (0.88, 0.89))
TOP_RADIUS_FRACTION = 0.81


def rock_sprites(rig: Rig, ppm: float, rng: np.random.Generator, pixel_m: float,
                 marker_diameter_m: float = 0.025, handle_color: str = "#1c1c22",
                 shadow_strength: float = 0.45, light_dir=(0.3, -0.5)) -> list[Sprite]:
    """The rock as planar slices, bottom to top: shadow, body slices, top (markers), handle.

    The top slice lies at ``rig.rock_height_m`` (the marker plane) and carries the
    markers (discs of ``marker_diameter_m``).  The handle is a dark bar 2.5 cm above it,
    through the axis, turned to keep clear of the markers.  ``ppm`` is the
    sprites' resolution (texels/m), ``pixel_m`` the size of an image pixel on the rock
    (m): edges are ramped over it.
    """
    R = rig.rock_diameter_m / 2
    h = rig.rock_height_m
    mk = rig.layout_m
    half = max(R, np.hypot(mk[:, 0], mk[:, 1]).max() + marker_diameter_m) + 0.03
    x, y = _grid(half, ppm)
    sprites = []
    # shadow on the ice: soft, slightly offset away from the light; does not turn
    ld = np.asarray(light_dir, dtype=float)
    sh = _disc(x, y, -0.012 * ld[0], -0.012 * ld[1], R * 1.02, pixel_m)
    sh = cv2.GaussianBlur(sh, (0, 0), 0.012 * ppm) * shadow_strength
    sprites.append(Sprite(_premul(np.zeros(3, np.float32), sh), ppm, 0.0, attached=False))
    r = np.hypot(x, y)
    granite = _granite(x.shape, rng, 118.0, 16.0, ppm)
    tint = np.array([1.0, 0.98, 0.95], np.float32)  # slightly warm grey
    for zf, rf in _PROFILE:
        a = _disc(x, y, 0, 0, R * rf, pixel_m)
        # the side is seen at grazing incidence: darker towards the rim
        shade = 0.55 + 0.35 * np.clip(1 - (r / (R * rf)) ** 4, 0, 1)
        col = (granite * shade)[..., None] * tint
        sprites.append(Sprite(_premul(col, a), ppm, zf * h))
    top_r = R * TOP_RADIUS_FRACTION
    a = _disc(x, y, 0, 0, top_r, pixel_m)
    # polished top: brighter, a light towards the light direction, a faint cup ring
    lit = 1.0 + 0.12 * (x * ld[0] + y * ld[1]) / R
    ring = 1.0 - 0.25 * np.exp(-0.5 * ((r - 0.72 * top_r) / (0.004)) ** 2)
    col = (_granite(x.shape, rng, 140.0, 20.0, ppm) * lit * ring)[..., None] * tint
    for m in rig.markers:
        ma = _disc(x, y, m.x_m, m.y_m, marker_diameter_m / 2, pixel_m)
        mcol = bgr(m.color) * (0.92 + 0.08 * lit[..., None])
        col = col * (1 - ma[..., None]) + mcol * ma[..., None]
        a = np.maximum(a, ma)  # a marker stuck near the rim may overhang the top
    sprites.append(Sprite(_premul(col, a), ppm, h))
    # handle: through the axis, turned to stay as far as possible from every marker
    length, width = min(0.19, 1.3 * top_r), 0.035
    along = _handle_direction(mk, length)
    base = np.array([along[1], -along[0]])
    s = x * along[0] + y * along[1]
    q = x * base[0] + y * base[1]
    cov = (np.clip(0.5 + (length / 2 - np.abs(s)) / pixel_m, 0, 1)
           * np.clip(0.5 + (width / 2 - np.abs(q)) / pixel_m, 0, 1)).astype(np.float32)
    hl = bgr(handle_color) * (1.0 + 0.8 * np.exp(-0.5 * (q / 0.006) ** 2))[..., None]
    sprites.append(Sprite(_premul(hl, cov), ppm, h + 0.025))
    return sprites


def _handle_direction(markers_xy, length):
    """Unit vector of the handle bar (through the axis) that keeps the largest clearance
    from the markers, as an experimenter sticks markers where the handle leaves room."""
    angles = np.deg2rad(np.arange(0.0, 180.0, 1.0))
    u = np.column_stack([np.cos(angles), np.sin(angles)])          # (A, 2)
    along = markers_xy @ u.T                                         # (M, A)
    across = np.abs(markers_xy @ np.column_stack([-u[:, 1], u[:, 0]]).T)
    beyond = np.clip(np.abs(along) - length / 2, 0, None)
    clearance = np.hypot(across, beyond).min(axis=0)
    return u[int(np.argmax(clearance))]


def broom_sprite(ppm: float, rng: np.random.Generator, head_m=(0.28, 0.09),
                 color: str = "#202020") -> Sprite:
    """A broom head seen from above (local x along the head), with a stub of its shaft."""
    half = 0.5 * max(head_m) + 0.6
    x, y = _grid(half, ppm)
    head = (np.clip(0.5 + (head_m[0] / 2 - np.abs(x)) * ppm, 0, 1)
            * np.clip(0.5 + (head_m[1] / 2 - np.abs(y)) * ppm, 0, 1)).astype(np.float32)
    shaft = (np.clip(0.5 + (0.015 - np.abs(x)) * ppm, 0, 1)
             * (y < -head_m[1] / 2 + 0.01)).astype(np.float32)
    fibre = cv2.GaussianBlur(rng.standard_normal(x.shape, dtype=np.float32), (0, 0), 1.0)
    col_head = bgr(color) + 25 * fibre[..., None]
    col = np.where(shaft[..., None] > head[..., None], np.array([40, 70, 110], np.float32),
                   col_head)
    return Sprite(_premul(col, np.maximum(head, shaft)), ppm, 0.0, attached=True)
