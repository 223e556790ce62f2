#!/usr/bin/env python
"""Render the README gallery: single frames of different set-ups -> docs/gallery/*.png.

What the tracker faces: a draw under the ladder camera (motion blur, lens distortion,
tilt), a pure rotation filmed handheld at shoulder height, a broom crossing over the
rock, and another rig (0.1 x 0.2 m three-colour lattice, three markers, 2.5 m).  Each
PNG is a half-size view of the whole frame beside a full-resolution crop around the
rock; colours are quantised to keep the files small.

Usage: python scripts/make_gallery.py [--out docs/gallery]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np

from curltrack.physics import ShotModel
from curltrack.render import CameraConfig, IceStyle, Production, RenderConfig
from curltrack.rig import default_rig, load_rig
from curltrack.simulate import simulate_series

ROOT = Path(__file__).resolve().parent.parent


def _shots():
    rig = default_rig()
    other = load_rig(ROOT / "fixtures" / "rig_three_markers.toml")
    draw = simulate_series(ShotModel.from_rig(rig, v0=2.0, omega0=1.5), tail_s=0.0)
    spin = simulate_series(ShotModel.from_rig(rig, v0=0.0, omega0=6.0), tail_s=0.0)
    slow = simulate_series(ShotModel.from_rig(other, v0=1.0, omega0=-2.0), tail_s=0.0)
    return [
        ("draw_ladder", "draw, ladder camera at 2.0 m, t = 1.0 s (v = 1.9 m/s)", draw, rig,
         RenderConfig(), 30),
        ("rotation_handheld", "pure rotation, handheld at 1.6 m, omega = 5 rad/s", spin, rig,
         RenderConfig(camera=CameraConfig(motion="handheld")), 25),
        ("occluded", "broom head crossing over the rock", draw, rig,
         RenderConfig(occlusion=True, occlusion_t_s=2.0), 58),
        ("other_rig", "another rig: 0.1 x 0.2 m lattice, three markers, camera at 2.5 m",
         slow, other, RenderConfig(), 45),
        ("house", "end of the draw over the painted house and sheet lines", draw, rig,
         RenderConfig(ice=IceStyle(house_at_m=26.8, sheet_lines=True), heading_deg=0.5),
         len(draw.data) - 45),
    ]


def _parts(img, uv, crop=200):
    """Half-size frame and a full-resolution crop around ``uv`` (px), same height."""
    small = cv2.resize(img, None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)
    u, v = (int(round(c)) for c in uv)
    h, w = img.shape[:2]
    u = min(max(u, crop // 2), w - crop // 2)
    v = min(max(v, crop // 2), h - crop // 2)
    patch = img[v - crop // 2:v + crop // 2, u - crop // 2:u + crop // 2]
    patch = cv2.resize(patch, (small.shape[0], small.shape[0]), interpolation=cv2.INTER_NEAREST)
    return small, patch


def _save_png(path, parts, colors=127):
    """Side-by-side PNG with one palette per part (a shared one drops the small markers)."""
    from PIL import Image

    indices, palette, offset = [], [], 0
    for part in parts:
        q = Image.fromarray(cv2.cvtColor(part, cv2.COLOR_BGR2RGB)).quantize(
            colors=colors, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE)
        pal = q.getpalette()[:3 * colors]
        palette += pal + [0] * (3 * colors - len(pal))
        indices.append(np.asarray(q, dtype=np.uint8) + offset)
        indices.append(np.full((part.shape[0], 4), 2 * colors, np.uint8))  # separator
        offset += colors
    palette = palette[:6 * colors] + [255, 255, 255]  # index 2 * colors: white
    out = Image.fromarray(np.hstack(indices[:-1]), mode="P")
    out.putpalette(palette)
    out.save(path, optimize=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "gallery")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    lines = []
    for name, caption, series, rig, cfg, k in _shots():
        prod = Production(series, rig, cfg, seed=11)
        img, info = next(prod.frames(k, k + 1))
        row = prod.truth().data.iloc[k]
        path = args.out / f"{name}.png"
        _save_png(path, _parts(img, (row["u_top_px"], row["v_top_px"])))
        lines.append(f"| ![{name}](docs/gallery/{name}.png) | {caption} (frame {k}) |")
        print(f"wrote {path} ({path.stat().st_size // 1024} KB)")
    print("\n| frame (half size, and a full-resolution crop) | set-up |\n|---|---|")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
