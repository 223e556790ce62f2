"""What the camera sees: the ice with its thread lattice, the rock, a broom.

Everything is pre-rendered once in its own plane's coordinates (a texture of the ice in
world metres, sprites of the rock in the rock's frame) and only warped per (sub)frame.
Images are BGR (OpenCV); sprites are premultiplied float32 BGRA (colour times alpha).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..rig import Rig, parse_color

N_ICE = 1.31  # refractive index of ice: threads at depth d appear at depth d / N_ICE


def bgr(color) -> np.ndarray:
    """'#rrggbb' (or an (R, G, B) tuple) -> float BGR 0-255."""
    rgb = parse_color(color) if isinstance(color, str) else tuple(color)
    return np.array(rgb[::-1], dtype=np.float32)


@dataclass
class Texture:
    """An image of a plane: ``world = (X0 + col / ppm, Y0 + row / ppm)`` (m), or with
    ``transposed`` ``world = (X0 + row / ppm, Y0 + col / ppm)``.

    Storing the texture with its rows along the image's rows keeps the per-frame warp
    reading memory in order (twice as fast when the camera looks along world Y).
    """

    image: np.ndarray
    X0: float
    Y0: float
    ppm: float
    z_m: float = 0.0
    transposed: bool = False
    lamps: np.ndarray | None = None  # (N, 2) world X, Y of the overhead lamps (m)

    @property
    def affine(self) -> np.ndarray:
        """3x3 map from (col, row, 1) to world (X, Y, 1)."""
        s = 1.0 / self.ppm
        if self.transposed:
            return np.array([[0, s, self.X0], [s, 0, self.Y0], [0, 0, 1.0]])
        return np.array([[s, 0, self.X0], [0, s, self.Y0], [0, 0, 1.0]])

    def transpose(self) -> "Texture":
        """The same texture stored the other way round."""
        return Texture(np.ascontiguousarray(self.image.transpose(1, 0, 2)), self.X0, self.Y0,
                       self.ppm, self.z_m, not self.transposed, self.lamps)


@dataclass(frozen=True)
class IceStyle:
    """Look of the ice and the threads (all documented defaults).

    Parameters
    ----------
    ice_color : str
        Base colour of the lit ice ("#rrggbb"), default "#d0d6db" (bluish white, with
        headroom below saturation for the lamp pools and glare).
    illumination : float
        Relative RMS of the uneven illumination (overhead lamps) over the sheet, 0.08.
    pebble_density_per_m2 : float
        Pebbles (frozen droplets) per m^2, default 3000.
    pebble_size_m : float
        Pebble radius (m), default 0.0025.
    pebble_contrast : float
        Pebble brightness (0-255 levels), default 14.
    speckle : float
        RMS of the fine texel speckle (levels), default 4.
    thread_width_m : float
        Visible width of a thread (m), default 0.0035 (~1 px at 300 px/m).
    thread_contrast : float
        Fraction of the thread colour at its core (seen through the ice), default 0.5.
    thread_jitter_m : float
        RMS error of each thread's position in the lattice (laid by hand), default 0.0004.
    scratches_per_m2 : float
        Faint straight scratches (old rock paths, skates), default 0.6 per m^2.
    """

    ice_color: str = "#d0d6db"
    illumination: float = 0.08
    pebble_density_per_m2: float = 3000.0
    pebble_size_m: float = 0.0025
    pebble_contrast: float = 14.0
    speckle: float = 4.0
    thread_width_m: float = 0.0035
    thread_contrast: float = 0.5
    thread_jitter_m: float = 0.0004
    scratches_per_m2: float = 0.6


def _thread_profile(coord, positions, width_m, ppm):
    """Anti-aliased coverage (0-1) and nearest-thread index of 1-D texel coordinates."""
    idx = np.clip(np.searchsorted(positions, coord), 1, len(positions) - 1)
    left, right = positions[idx - 1], positions[idx]
    near = np.where(coord - left < right - coord, idx - 1, idx)
    d = np.abs(coord - positions[near])
    return np.clip(0.5 + (0.5 * width_m - d) * ppm, 0.0, 1.0).astype(np.float32), near


def ice_texture(rig: Rig, bounds, ppm: float, phase, style: IceStyle,
                rng: np.random.Generator, strip_rows: int = 1024) -> Texture:
    """Render the ice sheet with its thread lattice over ``bounds`` (m).

    Parameters
    ----------
    rig : Rig
        Grid spacings, colours and depth.
    bounds : (X0, Y0, X1, Y1)
        World rectangle to cover (m).
    ppm : float
        Texture resolution (texels per metre).
    phase : (float, float)
        World X of a thread running along Y and world Y of a thread running along X (m).
    style : IceStyle
    rng : numpy.random.Generator

    Returns
    -------
    Texture
        Lying at the threads' apparent depth ``-depth_m / N_ICE`` (pebbles, a few mm
        above it in reality, are drawn in the same plane).
    """
    X0, Y0, X1, Y1 = bounds
    W = int(np.ceil((X1 - X0) * ppm)) + 1
    H = int(np.ceil((Y1 - Y0) * ppm)) + 1
    Xc = X0 + np.arange(W) / ppm
    Yc = Y0 + np.arange(H) / ppm

    def lattice(lo, hi, origin, spacing):
        k = np.arange(np.floor((lo - origin) / spacing) - 2, np.ceil((hi - origin) / spacing) + 3)
        pos = origin + k * spacing + rng.normal(0, style.thread_jitter_m, len(k))
        return np.sort(pos), k.astype(int)

    colors = [bgr(c) for c in rig.grid_colors] or [np.array([60, 60, 60], np.float32)]
    posx, kx = lattice(X0, X1, phase[0], rig.spacing_x_m)
    posy, ky = lattice(Y0, Y1, phase[1], rig.spacing_y_m)
    cov_x, near_x = _thread_profile(Xc, posx, style.thread_width_m, ppm)
    cov_y, near_y = _thread_profile(Yc, posy, style.thread_width_m, ppm)
    col_x = np.stack(colors)[kx[near_x] % len(colors)]  # (W, 3)
    col_y = np.stack(colors)[ky[near_y] % len(colors)]  # (H, 3)

    # Uneven illumination: overhead lamps on a jittered grid, each a broad separable
    # Gaussian pool of light -> the field is one matmul per strip.
    lx = np.arange(X0 - 3.0, X1 + 3.0, 2.5)
    ly = np.arange(Y0 - 3.0, Y1 + 3.5, 3.5)
    lamps = np.stack(np.meshgrid(lx, ly), -1).reshape(-1, 2)
    lamps = lamps + rng.uniform(-0.8, 0.8, lamps.shape)
    sig = rng.uniform(0.8, 1.6, lamps.shape)
    amp = rng.uniform(0.6, 1.0, len(lamps))
    gx = np.exp(-0.5 * ((Xc[:, None] - lamps[:, 0]) / sig[:, 0]) ** 2).astype(np.float32)
    gy = (amp * np.exp(-0.5 * ((Yc[:, None] - lamps[:, 1]) / sig[:, 1]) ** 2)).astype(np.float32)
    coarse = gy[::16] @ gx[::16].T
    f_mean, f_std = float(coarse.mean()), float(coarse.std()) + 1e-9
    gy *= style.illumination / f_std
    light_offset = 1.0 - style.illumination * f_mean / f_std

    base = bgr(style.ice_color)
    image = np.empty((H, W, 3), np.uint8)
    sigma = max(style.pebble_size_m * ppm, 0.6)
    p_texel = style.pebble_density_per_m2 / ppm**2
    for r0 in range(0, H, strip_rows):
        r1 = min(H, r0 + strip_rows)
        h = r1 - r0
        light = light_offset + gy[r0:r1] @ gx.T                         # (h, W)
        dots = (rng.random((h, W), dtype=np.float32) < p_texel).astype(np.float32)
        dots *= rng.uniform(0.4, 1.0, (h, W)).astype(np.float32)
        peb = cv2.GaussianBlur(dots, (0, 0), sigma) * (2 * np.pi * sigma**2)
        # a pebble is a lens: bright cap, darker rim on the side away from the light
        peb = peb - 0.5 * np.roll(peb, (1, 1), axis=(0, 1))
        fine = cv2.GaussianBlur(rng.standard_normal((h, W), dtype=np.float32), (0, 0), 0.7)
        shade = style.pebble_contrast * peb + style.speckle * 1.6 * fine
        img = base[None, None, :] * light[..., None] + shade[..., None]
        a = style.thread_contrast * cov_x[None, :, None]
        img = img * (1 - a) + (col_x[None, :, :] * light[..., None]) * a
        a = style.thread_contrast * cov_y[r0:r1, None, None]
        img = img * (1 - a) + (col_y[r0:r1, None, :] * light[..., None]) * a
        image[r0:r1] = np.clip(img, 0, 255).astype(np.uint8)
    n_scr = rng.poisson(style.scratches_per_m2 * (X1 - X0) * (Y1 - Y0))
    for _ in range(int(n_scr)):
        p = rng.uniform([0, 0], [W, H])
        ang, length = rng.uniform(0, np.pi), rng.uniform(0.3, 2.0) * ppm
        d = np.array([np.cos(ang), np.sin(ang)]) * length / 2
        shade = int(rng.uniform(-18, 10))
        tone = tuple(float(np.clip(v + shade, 0, 255)) for v in base)
        a, b = (p - d).astype(int), (p + d).astype(int)
        cv2.line(image, tuple(int(v) for v in a), tuple(int(v) for v in b), tone, 1, cv2.LINE_AA)
    return Texture(image, X0, Y0, ppm, z_m=-rig.grid_depth_m / N_ICE, lamps=lamps)


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
    mk = np.array([[m.x_m, m.y_m] for m in rig.markers])
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
