"""Annotated video: grid, markers, rock centre, trajectory so far, current x, y, theta.

Written in a second pass over the video from the small per-frame records (the first
pass has to finish before the shot frame - origin and axes from the first frames - and
the parallax factor from the whole video are known), so memory stays bounded.
"""

from __future__ import annotations

import numpy as np

from .._atomic import atomic_path, verify_video
from ..errors import VideoError

__all__ = ["write_overlay"]


def _shot_to_lattice(series, xy):
    m = series.meta
    o = np.asarray(m["frame_origin_lattice_m"])
    xh, yh = np.asarray(m["frame_x_axis_lattice"]), np.asarray(m["frame_y_axis_lattice"])
    return o + xy[:, :1] * xh + xy[:, 1:2] * yh


def write_overlay(video_path, overlay_path, records, series, loop_info, rig, start=0,
                  end=None, exclude=()):
    """Write the annotated mp4 (atomically).

    Parameters
    ----------
    video_path, overlay_path : path
    records : list of FrameRecord
        From the tracking pass (marker pixels and homographies per frame).
    series : Series
        The tracked series (shot frame) with its sidecar.
    """
    import cv2

    from ..calib.lens import apply_h, distort
    from ..calib.overlay import draw_grid
    from ..video import iter_frames, probe_video

    info = probe_video(video_path, check_end=False)
    calib = loop_info["calib"]
    by_frame = {r.frame: r for r in records}
    data = series.data.set_index("frame")
    ok = data["ok"].to_numpy() == 1
    traj_lat = _shot_to_lattice(series, data[["x", "y"]].to_numpy())
    frames_idx = data.index.to_numpy()
    colors = [tuple(int(c) for c in m.rgb[::-1]) for m in rig.markers]

    class _Pose:  # minimal PlaneMap for draw_grid
        def __init__(self, H):
            self.H, self.K, self.dist = H, calib.K, calib.dist
            self.spacing_x_m, self.spacing_y_m = rig.spacing_x_m, rig.spacing_y_m

        def image_to_ice(self, p):
            from ..calib.lens import undistort
            return apply_h(self.H, undistort(np.atleast_2d(p), self.K, self.dist))

        def ice_to_image(self, p):
            return distort(apply_h(np.linalg.inv(self.H), np.atleast_2d(p)), self.K, self.dist)

    with atomic_path(overlay_path, suffix=".mp4") as tmp:
        writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"mp4v"), info.fps,
                                 (info.width, info.height))
        if not writer.isOpened():
            raise VideoError("cannot open the overlay video for writing", path=overlay_path)
        written = 0
        try:
            for fr in iter_frames(video_path, start=start, end=end, exclude=exclude):
                img = fr.image
                rec = by_frame.get(fr.index)
                if rec is not None and rec.H is not None and calib is not None:
                    pose = _Pose(rec.H)
                    img = draw_grid(img, pose, color=(0, 160, 0), label=True)
                    k = int(np.searchsorted(frames_idx, fr.index))
                    past = ok[: k + 1]
                    pts = traj_lat[: k + 1][past]
                    if len(pts) >= 2:
                        px = pose.ice_to_image(pts)
                        cv2.polylines(img, [np.round(px * 16).astype(np.int32)], False,
                                      (255, 0, 255), 2, cv2.LINE_AA, shift=4)
                    if k < len(ok) and ok[k]:
                        c = pose.ice_to_image(traj_lat[k:k + 1])[0]
                        cv2.drawMarker(img, tuple(np.round(c).astype(int)), (0, 0, 255),
                                       cv2.MARKER_CROSS, 14, 2)
                        row = data.loc[fr.index]
                        txt = (f"frame {fr.index}  t={row['t']:.3f}s  x={row['x']:+.4f}m  "
                               f"y={row['y']:+.4f}m  theta={np.degrees(row['theta']):+.1f}deg")
                    else:
                        txt = f"frame {fr.index}: not measured ({rec.status})"
                    cv2.putText(img, txt, (10, 24), cv2.FONT_HERSHEY_SIMPLEX, 0.55,
                                (0, 0, 0), 3, cv2.LINE_AA)
                    cv2.putText(img, txt, (10, 24), cv2.FONT_HERSHEY_SIMPLEX, 0.55,
                                (255, 255, 255), 1, cv2.LINE_AA)
                if rec is not None and rec.markers_px is not None:
                    for p, col in zip(rec.markers_px, colors):
                        if np.isfinite(p).all():
                            cv2.circle(img, tuple(np.round(p).astype(int)), 7, col, 1,
                                       cv2.LINE_AA)
                writer.write(img)
                written += 1
        finally:
            writer.release()
        verify_video(tmp, written, overlay_path)
