"""Annotated video: grid, markers, rock centre, trail, the output's axes, x, y, theta.

Written in a second pass over the video from the small per-frame records (the first
pass has to finish before the shot frame - origin and axes from the first frames - and
the parallax factor from the whole video are known), so memory stays bounded.  Encoded
as H.264 (yuv420p, ``+faststart``) with PyAV, so that browsers play it.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np

from .._atomic import atomic_path, signals_after, verify_video
from ..errors import VideoError

__all__ = ["write_overlay", "overlay_frames", "encode_h264", "write_debug_frames",
           "write_verdict_frame", "TRAIL_BGR"]

#: Trail colour (BGR), drawn without anti-aliasing so that its pixels can be found.
TRAIL_BGR = (255, 0, 255)
#: Trail points more than this many frames apart are not joined (a long loss).
TRAIL_MAX_GAP = 15
#: Length of the drawn +x / +y arrows of the shot frame (m on the ice).
AXIS_LEN_M = 0.25


def _shot_to_lattice(meta, xy):
    o = np.asarray(meta["frame_origin_lattice_m"])
    xh, yh = np.asarray(meta["frame_x_axis_lattice"]), np.asarray(meta["frame_y_axis_lattice"])
    return o + xy[:, :1] * xh + xy[:, 1:2] * yh


class _Pose:
    """Image <-> lattice (m) through one frame's homography and the lens."""

    def __init__(self, H, calib, rig, size):
        self.H, self.K, self.dist = H, calib.K, calib.dist
        self.spacing_x_m, self.spacing_y_m = rig.spacing_x_m, rig.spacing_y_m
        w, h = size
        corners = np.array([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]], float)
        # the lens model is fitted inside the image only; beyond its corners (in
        # undistorted radius) the polynomial can fold far points back into view
        k1, k2 = (tuple(calib.dist) + (0.0, 0.0))[:2]
        s = np.roots([5 * k2, 3 * k1, 1.0])  # r^2 where d r_distorted / d r = 0
        s = s[np.isreal(s) & (s.real > 0)].real
        r_fold = np.sqrt(s.min()) if s.size else np.inf
        self._r_max = min(1.02 * np.max(self._radius(self._undistort(corners))), 0.98 * r_fold)

    def _undistort(self, p):
        from ..calib.lens import undistort

        return undistort(np.atleast_2d(p), self.K, self.dist)

    def _radius(self, und):
        return np.hypot(*((und - self.K[:2, 2]) / self.K[0, 0]).T)

    def image_to_ice(self, p):
        from ..calib.lens import apply_h

        return apply_h(self.H, self._undistort(p))

    def ice_to_image(self, p, visible_only=False):
        """Lattice (m) -> observed pixels; with ``visible_only``, NaN where not in view."""
        from ..calib.lens import apply_h, distort

        und = apply_h(np.linalg.inv(self.H), np.atleast_2d(p))
        px = distort(und, self.K, self.dist)
        if visible_only:
            px[self._radius(und) > self._r_max] = np.nan
        return px


def _runs(px, frames):
    """Polylines of consecutive visible points, split at gaps of > TRAIL_MAX_GAP frames."""
    good = np.isfinite(px).all(axis=1)
    cut = np.ones(len(px), bool)
    cut[1:] = ~good[:-1] | (np.diff(frames) > TRAIL_MAX_GAP)
    out, run = [], []
    for p, g, c in zip(px, good, cut):
        if c and len(run) >= 2:
            out.append(np.array(run))
        if c:
            run = []
        if g:
            run.append(p)
    if len(run) >= 2:
        out.append(np.array(run))
    return out


def _caption(img, text, line=0):
    """One line of white text on a dark box (readable on any ice, one text drawn)."""
    import cv2

    font, scale, th = cv2.FONT_HERSHEY_SIMPLEX, 0.5, 1
    (w, h), base = cv2.getTextSize(text, font, scale, th)
    y0 = 4 + line * (h + base + 12)
    cv2.rectangle(img, (4, y0), (14 + w, y0 + 10 + h + base), (0, 0, 0), -1)
    cv2.putText(img, text, (9, y0 + 5 + h), font, scale, (255, 255, 255), th, cv2.LINE_AA)


def overlay_frames(video_path, records, series, calib, rig, start=0, end=None, exclude=()):
    """Yield ``(frame index, annotated BGR image)`` for every decoded frame.

    Drawn: the fitted threads (green), the trail of the measured centres up to this
    frame (magenta, only where the rock has been and only where it is in view), the
    centre (red cross), the markers found (circles of their colours), the shot frame's
    +x / +y arrows at the rock (yellow, :data:`AXIS_LEN_M` long) and one caption line.
    """
    import cv2

    from ..calib.overlay import draw_grid
    from ..video import iter_frames

    by_frame = {r.frame: r for r in records}
    data = series.data.set_index("frame")
    ok = data["ok"].to_numpy() == 1
    xy = data[["x", "y"]].to_numpy()
    traj_lat = _shot_to_lattice(series.meta, xy) if "frame_origin_lattice_m" in series.meta \
        else None
    frames_idx = data.index.to_numpy()
    colors = [tuple(int(c) for c in m.rgb[::-1]) for m in rig.markers]
    axes = np.array([[AXIS_LEN_M, 0.0], [0.0, AXIS_LEN_M]])
    thick = None
    for fr in iter_frames(video_path, start=start, end=end, exclude=exclude):
        img = fr.image.copy()
        thick = thick or max(1, round(img.shape[1] / 960))  # 1 px at 960 wide, 2 at 1920
        rec = by_frame.get(fr.index)
        k = int(np.searchsorted(frames_idx, fr.index))
        measured = k < len(ok) and frames_idx[k] == fr.index and ok[k]
        if rec is not None and rec.H is not None and calib is not None and traj_lat is not None:
            pose = _Pose(rec.H, calib, rig, (img.shape[1], img.shape[0]))
            img = draw_grid(img, pose, color=(0, 160, 0), label=False)
            past = np.flatnonzero(ok[: k + 1])
            for run in _runs(pose.ice_to_image(traj_lat[past], True), frames_idx[past]):
                cv2.polylines(img, [np.round(run).astype(np.int32)], False, TRAIL_BGR,
                              thick, cv2.LINE_8)
            if measured:
                ends = _shot_to_lattice(series.meta, xy[k] + np.vstack([[0, 0], axes]))
                c, ex, ey = pose.ice_to_image(ends, visible_only=True)
                if np.isfinite(c).all():
                    for end_px, name in ((ex, "+x"), (ey, "+y")):
                        if np.isfinite(end_px).all():
                            a, b = tuple(np.round(c).astype(int)), tuple(np.round(end_px).astype(int))
                            cv2.arrowedLine(img, a, b, (0, 220, 255), 2, cv2.LINE_AA, tipLength=0.15)
                            cv2.putText(img, name, (b[0] + 4, b[1] + 4), cv2.FONT_HERSHEY_SIMPLEX,
                                        0.5, (0, 220, 255), 1, cv2.LINE_AA)
                    cv2.drawMarker(img, tuple(np.round(c).astype(int)), (0, 0, 255),
                                   cv2.MARKER_CROSS, 14, 2)
        if rec is not None and rec.markers_px is not None:
            for p, col in zip(rec.markers_px, colors):
                if np.isfinite(p).all():
                    cv2.circle(img, tuple(np.round(p).astype(int)), 7, col, 1, cv2.LINE_AA)
        if measured:
            row = data.iloc[k]
            text = (f"frame {fr.index}  t {row['t']:.3f} s  x {row['x']:+.4f} m  "
                    f"y {row['y']:+.4f} m  theta {np.degrees(row['theta']):+.1f} deg")
        else:
            why = rec.status if rec is not None and rec.status else "not measured"
            text = f"frame {fr.index}: ok = 0 ({why})"
        _caption(img, text)
        yield fr.index, img


def encode_h264(path, frames, fps, size, crf: int = 23, progress=None):
    """Encode BGR images as H.264 (yuv420p) mp4 at ``path`` with PyAV.

    Parameters
    ----------
    path : path
        Output file (the caller makes it atomic).
    frames : iterable of (index, (H, W, 3) uint8 BGR)
    fps : float
        Frame rate (frames/s).
    size : (width, height)
        px; odd sizes are padded by one pixel (yuv420p needs even ones).
    progress : callable, optional
        Called with 1 per frame written.

    Returns
    -------
    int
        Frames written.
    """
    import av

    w, h = size
    W, H = w + w % 2, h + h % 2
    n = 0
    out = av.open(str(path), "w", format="mp4", options={"movflags": "+faststart"})
    try:
        stream = out.add_stream("libx264", rate=Fraction(fps).limit_denominator(1001))
        stream.width, stream.height, stream.pix_fmt = W, H, "yuv420p"
        stream.options = {"crf": str(crf), "preset": "veryfast"}
        for _, img in frames:
            if (W, H) != (w, h):
                img = np.pad(img, ((0, H - h), (0, W - w), (0, 0)), mode="edge")
            with signals_after():  # (Ctrl-C between frames, never inside the encoder)
                for packet in stream.encode(av.VideoFrame.from_ndarray(img, format="bgr24")):
                    out.mux(packet)
            n += 1
            if progress is not None:
                progress(1)
        with signals_after():
            for packet in stream.encode():
                out.mux(packet)
    finally:
        with signals_after():
            out.close()
    return n


def write_overlay(video_path, overlay_path, records, series, loop_info, rig, start=0,
                  end=None, exclude=(), progress=None):
    """Write the annotated H.264 mp4 (atomically); see :func:`overlay_frames`.

    Parameters
    ----------
    video_path, overlay_path : path
    records : list of FrameRecord
        From the tracking pass (marker pixels and homographies per frame).
    series : Series
        The tracked series (shot frame) with its sidecar.
    progress : callable, optional
        Called with 1 per frame written.
    """
    from ..video import probe_video

    info = probe_video(video_path, check_end=False)
    frames = overlay_frames(video_path, records, series, loop_info["calib"], rig,
                            start=start, end=end, exclude=exclude)
    with atomic_path(overlay_path, suffix=".mp4") as tmp:
        try:
            n = _encode(tmp, frames, info.fps, (info.width, info.height), progress=progress)
        except (ImportError, ValueError) as exc:  # no PyAV / no libx264 in its FFmpeg
            raise VideoError(f"cannot encode the overlay as H.264 ({exc})",
                             path=overlay_path) from None
        verify_video(tmp, n, overlay_path)


def write_debug_frames(video_path, outdir, frames, records, series, calib, rig):
    """PNG of what tracking found on each of ``frames``: the overlay's drawing plus each
    marker's index, and the frame's numbers (status, grid spacing, sigma, quality).

    Returns the paths written (``outdir/frame_NNNNNN.png``).
    """
    from pathlib import Path

    outdir = Path(outdir)
    data = series.data
    written = []
    for f in sorted(set(int(v) for v in frames)):
        # (an interlaced frame has two records and two rows: one per field)
        recs = [r for r in records if r.frame == f]
        if not recs:
            continue
        rows = data[data["frame"] == f]
        for _, img in overlay_frames(video_path, records, series, calib, rig, start=f,
                                     end=f + 1):
            lines = []
            for k, rec in enumerate(recs):
                name = "" if rec.field is None else f"field {rec.field}: "
                found = (0 if rec.markers_px is None
                         else int(np.isfinite(rec.markers_px).all(1).sum()))
                lines += [f"{name}status: {rec.status or 'measured'}",
                          f"{name}grid {'found' if rec.H is not None else 'not found'}; "
                          f"thread spacing {rec.spacing_px:.1f} px; markers found "
                          f"{found}/{len(rig.markers)}"]
                row = rows.iloc[k] if k < len(rows) else None
                if row is not None and row["ok"] == 1 and "sigma_xy" in row:
                    lines.append(f"{name}sigma_xy {row['sigma_xy'] * 1e3:.2f} mm, sigma_theta "
                                 f"{np.degrees(row['sigma_theta']):.2f} deg, quality "
                                 f"{row['quality']:.2f}")
            written.append(_write_debug_png(outdir, f, img, recs[-1].markers_px, lines))
    return written


def _write_debug_png(outdir, frame: int, img, markers_px, lines):
    """Label the markers (m0, m1, ...), caption ``lines`` (from the second line down) and
    write ``outdir/frame_NNNNNN.png`` atomically; returns its path."""
    import cv2
    from pathlib import Path

    if markers_px is not None:
        for i, p in enumerate(markers_px):
            if np.isfinite(p).all():
                cv2.putText(img, f"m{i}", (int(p[0]) + 9, int(p[1]) - 9),
                            cv2.FONT_HERSHEY_SIMPLEX, 0.45, (255, 255, 255), 1, cv2.LINE_AA)
    for k, text in enumerate(lines, start=1):
        _caption(img, text, line=k)
    path = Path(outdir) / f"frame_{frame:06d}.png"
    with atomic_path(path) as tmp:
        if not cv2.imwrite(str(tmp), img):
            raise VideoError("cannot write the debug image", path=path)
    return path


def write_verdict_frame(outdir, image, verdict, rig):
    """PNG of what ``calibrate`` / ``doctor`` found on one frame
    (:class:`curltrack.track.check.FrameVerdict`): the fitted threads, the markers, the
    verdict and the grid's numbers; returns its path (``outdir/frame_NNNNNN.png``)."""
    from ..calib.overlay import draw_grid

    cal = verdict.calibration
    img = draw_grid(image, cal) if cal is not None else image.copy()
    found = sum(verdict.markers_found)
    lines = [f"frame {verdict.frame}: {'measurable' if verdict.ok else verdict.status}",
             f"markers found {found}/{len(rig.markers)}; grid " + (
                 f"spacing {cal.spacing_px:.1f} px, residual {cal.residual_px:.2f} px"
                 + (f" (lens from frame {verdict.calibrated_on})"
                    if verdict.calibrated_on != verdict.frame else "")
                 if cal is not None else verdict.grid_status)]
    _caption(img, "curltrack calibrate", line=0)
    return _write_debug_png(outdir, verdict.frame, img, verdict.markers_px, lines)


_encode = encode_h264
