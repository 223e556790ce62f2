"""Builders of bad (and good) inputs for the hardening tests.

Every video here is tiny (480x270 or smaller, about 1-2 s) and made from the renderer,
so its truth is known; damage (hidden grid, covered rock, turning camera, variable
frame rate, truncation...) is applied to the rendered frames afterwards.  Everything is
deterministic from its seed.
"""

from __future__ import annotations

import fractions
from pathlib import Path

import numpy as np

from curltrack.physics.shot import ShotModel
from curltrack.rig import Marker, Rig, default_rig
from curltrack.simulate import simulate_series

SIZE = (480, 270)


def render_clip(out: Path, *, rig: Rig | None = None, v0: float = 0.5, omega0: float = 1.5,
                size=SIZE, fps: float = 30.0, seed: int = 0, motion: str = "ladder",
                tail_s: float = 0.3, occlusion: bool = False, offset_m=(0.0, 0.0),
                view_m: float = 1.2, k1: float = -0.08, tilt_deg: float = 1.5,
                centred: bool = False):
    """Render a short shot; return (video path, truth Series, rig).

    ``centred``: principal point at the image centre (no random offset), so that turning
    the image about its centre is a camera turning about its optical axis.
    """
    from curltrack.render import CameraConfig, RenderConfig, render_video

    rig = rig or default_rig()
    sim = simulate_series(ShotModel.from_rig(rig, v0=v0, omega0=omega0, alpha_y=0.03), fps=fps,
                          tail_s=tail_s)
    cam = CameraConfig(motion=motion, offset_m=tuple(offset_m), view_m=view_m, k1=k1,
                       tilt_deg=tilt_deg, principal_offset_px=(0.0, 0.0) if centred else None)
    cfg = RenderConfig(width=size[0], height=size[1], fps=fps, camera=cam,
                       stopped_tail_s=tail_s, blur_subframes=2, occlusion=occlusion)
    out = Path(out)
    truth = render_video(sim, rig, out, out.with_suffix(".truth.csv"), config=cfg, seed=seed)
    return out, truth, rig


def read_frames(path):
    """Yield the BGR frames of a video (one at a time)."""
    import cv2

    cap = cv2.VideoCapture(str(path))
    try:
        while True:
            ok, img = cap.read()
            if not ok:
                return
            yield img
    finally:
        cap.release()


def write_frames(path, frames, fps: float, size=None) -> Path:
    """Write BGR frames as an mp4 (mp4v) with OpenCV; returns the path."""
    import cv2

    path = Path(path)
    writer = None
    for img in frames:
        if writer is None:
            h, w = img.shape[:2]
            writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, (w, h))
        writer.write(np.ascontiguousarray(img))
    if writer is not None:
        writer.release()
    return path


def edit_video(src, dst, edit, fps: float = 30.0) -> Path:
    """Copy ``src`` to ``dst`` with ``edit(k, image) -> image`` applied to every frame."""
    return write_frames(dst, (edit(k, img) for k, img in enumerate(read_frames(src))), fps)


def flat_fill(img, mask):
    """Paint the masked pixels with the image's median colour (hides threads/markers)."""
    out = img.copy()
    out[mask] = np.median(img.reshape(-1, 3), axis=0).astype(np.uint8)
    return out


def hide_grid(img, keep_centre_px=None, keep_radius_px=0.0):
    """Everything but a disc (the rock) painted flat: no thread is visible."""
    h, w = img.shape[:2]
    mask = np.ones((h, w), bool)
    if keep_centre_px is not None:
        vv, uu = np.mgrid[0:h, 0:w]
        mask &= np.hypot(uu - keep_centre_px[0], vv - keep_centre_px[1]) > keep_radius_px
    return flat_fill(img, mask)


def cover_rock(img, centre_px, radius_px):
    """A flat disc over the rock's top (all markers hidden)."""
    h, w = img.shape[:2]
    vv, uu = np.mgrid[0:h, 0:w]
    return flat_fill(img, np.hypot(uu - centre_px[0], vv - centre_px[1]) <= radius_px)


def rotate_crop(img, angle_deg: float, crop=(240, 136)):
    """Turn the image about its centre by ``angle_deg`` and keep a centred ``crop`` (w, h).

    A camera turning about its optical axis; the crop keeps the corners free of the
    rotation's empty wedges.
    """
    import cv2

    h, w = img.shape[:2]
    M = cv2.getRotationMatrix2D(((w - 1) / 2, (h - 1) / 2), angle_deg, 1.0)
    rot = cv2.warpAffine(img, M, (w, h), flags=cv2.INTER_LINEAR)
    cw, ch = crop
    x0, y0 = (w - cw) // 2, (h - ch) // 2
    return rot[y0:y0 + ch, x0:x0 + cw]


def write_vfr(path, frames_and_times_ms, size) -> Path:
    """Write frames at the given presentation times (ms) with PyAV: a variable frame rate."""
    import av

    path = Path(path)
    with av.open(str(path), "w") as out:
        st = out.add_stream("mpeg4", rate=30)
        st.width, st.height = size
        st.pix_fmt = "yuv420p"
        st.bit_rate = 4_000_000
        tb = fractions.Fraction(1, 1000)
        st.time_base = tb
        st.codec_context.time_base = tb
        for img, t_ms in frames_and_times_ms:
            f = av.VideoFrame.from_ndarray(np.ascontiguousarray(img), format="bgr24")
            f.pts, f.time_base = int(round(t_ms)), tb
            for p in st.encode(f):
                out.mux(p)
        for p in st.encode():
            out.mux(p)
    return path


def other_colour_rig(rig: Rig) -> Rig:
    """The same rig with marker colours the rendered video does not contain."""
    from dataclasses import replace

    cols = ["#e020c0", "#20a040", "#8030c0", "#ff8000"]
    return replace(rig, markers=tuple(Marker(cols[i % len(cols)], m.x_m, m.y_m)
                                      for i, m in enumerate(rig.markers)))


RIG_TOML = """\
[grid]
spacing_x_m = 0.15
spacing_y_m = 0.15
colors = ["#d02020", "#2040d0"]
[rock]
diameter_m = 0.29
height_m = 0.114
[[markers]]
color = "#ffd000"
x_m = 0.08
y_m = 0.0
[[markers]]
color = "#00c0ff"
x_m = -0.08
y_m = 0.0
"""


def sidecar(path) -> dict:
    """The SHOT.json beside a SHOT.csv."""
    import json

    return json.loads(Path(path).with_suffix(".json").read_text())
