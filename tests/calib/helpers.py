"""Helpers for the calibration tests."""

import numpy as np


def align(est, truth, sx, sy, free_offset=False):
    """Error of ``est`` against ``truth`` after the lattice's symmetries.

    The lattice frame may differ from the truth frame by a multiple of 90 deg (equal
    spacings) and by a whole number of cells (origin choice; any offset with
    ``free_offset``).  Returns (rms, errors (N, 2), quarter turns).
    """
    best = None
    for k in range(4):
        if k % 2 and not np.isclose(sx, sy):
            continue
        c, s = np.round(np.cos(k * np.pi / 2)), np.round(np.sin(k * np.pi / 2))
        e2 = est @ np.array([[c, -s], [s, c]]).T
        d = (truth - e2).mean(axis=0)
        off = d if free_offset else np.round(d / (sx, sy)) * (sx, sy)
        err = e2 + off - truth
        rms = float(np.sqrt((err ** 2).sum(axis=1).mean()))
        if best is None or rms < best[0]:
            best = (rms, err, k)
    return best


def short_shot(v0=3.0, seconds=1.2, fps=30.0, omega0=1.5, lam=1.9, t_F=10.0):
    """The first ``seconds`` of a closed-form draw with initial speed ``v0`` (m/s)."""
    from curltrack.physics.closed_form import decel_position
    from curltrack.series import Series, make_meta
    import pandas as pd

    t = np.arange(int(round(seconds * fps)) + 1) / fps
    y = decel_position(t, v0 * t_F / lam, lam, t_F)
    theta = decel_position(t, omega0 * t_F / lam, lam, t_F)
    data = pd.DataFrame(dict(frame=np.arange(len(t)), t=t, x=np.zeros_like(t), y=y,
                             theta=theta, ok=1))
    return Series(data, make_meta(fps, len(t)))


def rock_mask(shape, u, v, radius_px):
    """uint8 mask (nonzero = ignore) of a disc around the rock."""
    import cv2

    m = np.zeros(shape[:2], np.uint8)
    cv2.circle(m, (int(round(u)), int(round(v))), int(np.ceil(radius_px)), 255, -1)
    return m


def track_rendered(video, truth, rig, mask=True):
    """Calibrate on frame 0, follow the grid; return (ice points of the true rock centre
    through each pose (N, 2), ok flags (N,), poses)."""
    from curltrack.calib import GridTracker, calibrate_frame
    from curltrack.video import iter_frames

    tracker, est, oks, poses = None, [], [], []
    for fr in iter_frames(video):
        row = truth.iloc[fr.index]
        if tracker is None:
            cal = calibrate_frame(fr.image, rig)
            tracker = GridTracker(cal, rig)
        m = None
        if mask:
            r_px = 0.5 * rig.rock_diameter_m / cal.metres_per_px() * 1.3
            m = rock_mask(fr.image.shape, row.u_top_px, row.v_top_px, r_px)
        pose = tracker.update(fr.image, fr.index, m)
        est.append(pose.image_to_ice([[row.u_px, row.v_px]])[0])
        oks.append(pose.ok)
        poses.append(pose)
    return np.array(est), np.array(oks), poses


class FrameMatch:
    """The rigid map (quarter turns + offset) from the lattice frame to a truth frame,
    fixed on a first frame, then applied unchanged (a cell jump later shows as a
    spacing-sized error)."""

    def __init__(self, est, truth, sx, sy):
        _, _, self.k = align(est, truth, sx, sy)
        self.R = self._rot(self.k)
        d = (truth - est @ self.R.T).mean(axis=0)
        self.off = np.round(d / (sx, sy)) * (sx, sy)

    @staticmethod
    def _rot(k):
        c, s = np.round(np.cos(k * np.pi / 2)), np.round(np.sin(k * np.pi / 2))
        return np.array([[c, -s], [s, c]])

    def error(self, est, truth):
        """Largest error (m) of ``est`` mapped to the truth frame."""
        return float(np.abs(est @ self.R.T + self.off - truth).max())
