"""The ice sheet: pebbled, unevenly lit, with the thread lattice (and, optionally, the
sheet's painted markings) under its surface, pre-rendered once as a texture in world
metres and only warped per (sub)frame.  Images are BGR (OpenCV).
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
    house_at_m : float, optional
        Paint the house (12-ft blue ring, 4-ft red ring, tee line) with its tee this far
        from the start along the direction of travel (m); default None (no house).
    sheet_lines : bool
        Paint the centre line along the travel through the start (and the tee and hog
        lines with the house); default False.
    paint_contrast : float
        Fraction of the paint colour seen through the ice, default 0.55.
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
    house_at_m: float | None = None
    sheet_lines: bool = False
    paint_contrast: float = 0.55


# The sheet's painted markings (m), as the rules draw them.
RING_12FT, RING_8FT, RING_4FT, BUTTON = 1.829, 1.219, 0.610, 0.152
LINE_W, HOG_W, HOG_FROM_TEE = 0.013, 0.102, 6.40
PAINT = {"blue": "#2a5cc8", "red": "#c8262a", "black": "#202020"}


def sheet_markings(style: IceStyle, start, travel) -> list:
    """Painted markings in world coordinates: ("ring", centre, r_in, r_out, colour) and
    ("line", point, unit direction, width, colour); ``travel`` is a unit vector."""
    start, travel = np.asarray(start, float), np.asarray(travel, float)
    across = np.array([-travel[1], travel[0]])
    out = []
    if style.sheet_lines:
        out.append(("line", start, travel, LINE_W, PAINT["black"]))
    if style.house_at_m is not None:
        tee = start + style.house_at_m * travel
        out += [("ring", tee, RING_8FT, RING_12FT, PAINT["blue"]),
                ("ring", tee, BUTTON, RING_4FT, PAINT["red"])]
        if style.sheet_lines:
            out += [("line", tee, across, LINE_W, PAINT["black"]),
                    ("line", tee - HOG_FROM_TEE * travel, across, HOG_W, PAINT["red"])]
    return out


def _paint(img, light, Xc, Yc, markings, ppm, contrast):
    """Blend painted markings into a strip ``img`` (h, W, 3) at world Xc (W,), Yc (h,)."""
    for kind, p, a, b, color in markings:
        if kind == "ring":
            if (Yc[-1] < p[1] - b or Yc[0] > p[1] + b or Xc[-1] < p[0] - b
                    or Xc[0] > p[0] + b):
                continue
            d = np.hypot(Xc[None, :] - p[0], Yc[:, None] - p[1])
            cov = np.clip(0.5 + (d - a) * ppm, 0, 1) * np.clip(0.5 + (b - d) * ppm, 0, 1)
        else:
            d = np.abs((Xc[None, :] - p[0]) * -a[1] + (Yc[:, None] - p[1]) * a[0])
            cov = np.clip(0.5 + (0.5 * b - d) * ppm, 0, 1)
        if not cov.any():
            continue
        w = (contrast * cov)[..., None].astype(np.float32)
        img *= 1 - w
        img += w * bgr(color) * light[..., None]
    return img


def _thread_profile(coord, positions, width_m, ppm):
    """Anti-aliased coverage (0-1) and nearest-thread index of 1-D texel coordinates."""
    idx = np.clip(np.searchsorted(positions, coord), 1, len(positions) - 1)
    left, right = positions[idx - 1], positions[idx]
    near = np.where(coord - left < right - coord, idx - 1, idx)
    d = np.abs(coord - positions[near])
    return np.clip(0.5 + (0.5 * width_m - d) * ppm, 0.0, 1.0).astype(np.float32), near


def ice_texture(rig: Rig, bounds, ppm: float, phase, style: IceStyle,
                rng: np.random.Generator, markings=(), strip_rows: int = 1024) -> Texture:
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
    markings : list, optional
        Painted markings (see :func:`sheet_markings`), under the threads.

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
        if markings:
            img = _paint(img, light, Xc, Yc[r0:r1], markings, ppm, style.paint_contrast)
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
