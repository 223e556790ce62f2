"""The shot placed on the ice: series -> world trajectory, and the truth in SHOT.csv form.

World frame = the rig's lattice (see :mod:`curltrack.render.camera`), origin at the
rock's centre at t = 0.  The series' +y (its direction of travel) points along world
``(-sin h, cos h)`` for a heading ``h``; the truth is expressed in the frame whose +y is
the grid axis closest to the initial direction of travel (for a rock that does not
translate: closest to the image's up direction at t = 0), as a tracker measuring
against the lattice must report it.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy.interpolate import PchipInterpolator

from ..errors import SeriesError
from ..series import Series, make_meta

STILL_M = 1e-7      # m: a position change below this is "no motion"
STILL_RAD = 1e-7    # rad
TRANSLATING_M = 0.05  # total travel above which the shot counts as translating


def _rot(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s], [s, c]])


def _quarter_turn(angle: float) -> float:
    """The multiple of 90 deg closest to ``angle``, in (-180, 180] deg (as rad)."""
    k = int(np.round(angle / (np.pi / 2))) % 4
    return float((k if k < 3 else -1) * np.pi / 2)


def _derive_stop(t, q, tol):
    """Time of the last change of ``q`` larger than ``tol`` (None if still moving)."""
    moving = np.abs(np.diff(q, axis=0)).reshape(len(q) - 1, -1).max(axis=1) > tol
    if moving[-1] or not moving.any():
        return None if moving[-1] else 0.0
    return float(t[np.flatnonzero(moving)[-1] + 1])


class Trajectory:
    """A series placed on the ice.

    Parameters
    ----------
    series : Series
        Rows with ``ok`` = 1 and finite x, y, theta are used.
    heading_rad : float
        Direction of the series' +y relative to the grid's +Y, counter-clockwise.
    psi0 : float
        The rock's orientation in the world at t = 0 (rad).
    stopped_tail_s : float
        The video shows at least this much stopped rock after the last stop (rows are
        appended when the series' own rest is shorter; only if the series has stopped).
    """

    def __init__(self, series: Series, heading_rad: float, psi0: float,
                 stopped_tail_s: float):
        d = series.data
        d = d[(d["ok"] == 1) & np.isfinite(d[["x", "y", "theta"]]).all(axis=1)]
        if len(d) < 2:
            raise SeriesError("need at least two measured rows (ok = 1) to render",
                              path=series.name)
        t = d["t"].to_numpy(float)
        self.t0 = t[0]
        self.t = t - t[0]
        xy = d[["x", "y"]].to_numpy(float)
        self.xy = xy - xy[0]
        self.theta_rows = d["theta"].to_numpy(float) - d["theta"].iloc[0]
        self.heading = float(heading_rad)
        self.psi0 = float(psi0)
        self.meta = series.meta
        self.warnings: list[str] = []
        self._ixy = PchipInterpolator(self.t, self.xy, axis=0, extrapolate=True)
        self._ith = PchipInterpolator(self.t, self.theta_rows, extrapolate=True)
        self.t_stop_tr = self._stop("t_stop_translation", self.xy, STILL_M)
        self.t_stop_rot = self._stop("t_stop_rotation", self.theta_rows, STILL_RAD)
        still_at_end = all(s is not None and s <= self.t[-1] + 1e-9
                           for s in (self.t_stop_tr, self.t_stop_rot))
        self.stopped = still_at_end
        self.t_end = self.t[-1]
        stops = [s for s in (self.t_stop_tr, self.t_stop_rot) if s]
        self.t_motion_end = max(stops) if stops else self.t_end
        self.duration = self.t_end
        if stopped_tail_s > 0 and not still_at_end:
            self.warnings.append("the series has not stopped at its end: no stopped tail")
        elif stopped_tail_s > 0:  # at least this much rest at the end of the video
            self.duration = max(self.t_end, self.t_motion_end + stopped_tail_s)
        disp = np.hypot(*self.xy.T)
        self.translating = disp.max() > TRANSLATING_M
        if self.translating:
            first = self.xy[np.argmax(disp > 0.5 * TRANSLATING_M)]
            w = _rot(self.heading) @ first
            self.travel_yaw = float(np.arctan2(w[1], w[0]))
            self.truth_rot = _quarter_turn(self.travel_yaw - np.pi / 2)
        else:
            self.travel_yaw = 0.0
            self.truth_rot = 0.0  # set from the camera by align_to_image

    def _stop(self, key, q, tol):
        val = self.meta.get(key)
        if val is not None and np.isfinite(val):
            return float(val) - self.t0
        return _derive_stop(self.t, q, tol)

    def align_to_image(self, image_up_yaw_rad: float) -> None:
        """For a non-translating rock: truth +y = the grid axis closest to image up."""
        if not self.translating:
            self.truth_rot = _quarter_turn(image_up_yaw_rad - np.pi / 2)

    def _clip(self, t):
        """Hold the final state after a stop; a series cut short is extrapolated (the
        last exposure reaches half a shutter beyond its last row)."""
        t = np.asarray(t, dtype=float)
        return np.minimum(t, self.t_end) if self.stopped else t

    def rock_xy(self, t) -> np.ndarray:
        """Rock centre in the world (N, 2) at times ``t`` (m)."""
        return self._ixy(self._clip(np.atleast_1d(t))) @ _rot(self.heading).T

    def theta(self, t) -> np.ndarray:
        """The series' theta (rad, CCW, theta(0) = 0) at times ``t``."""
        return self._ith(self._clip(np.atleast_1d(t)))

    def psi(self, t) -> np.ndarray:
        """Rock orientation in the world (rad, CCW) at times ``t``."""
        return self.psi0 + self.theta(t)

    def to_truth(self, world_xy) -> np.ndarray:
        """World (N, 2) -> truth frame (N, 2) (m)."""
        return np.atleast_2d(world_xy) @ _rot(-self.truth_rot).T

    def sidecar(self, fps: float, n_frames: int, t_frames) -> dict:
        """The truth's sidecar: stop times and frames, plus warnings."""
        def frame_of(ts):
            if ts is None:
                return None
            idx = np.flatnonzero(t_frames >= ts - 1e-9)
            return int(idx[0]) if len(idx) else None

        meta = make_meta(fps, n_frames, 0,
                         stop_frame_translation=frame_of(self.t_stop_tr),
                         stop_frame_rotation=frame_of(self.t_stop_rot),
                         t_stop_translation=self.t_stop_tr, t_stop_rotation=self.t_stop_rot)
        meta["warnings"] = list(self.warnings)
        return meta


def truth_table(traj: Trajectory, rig, path, cams, t_frames, occluded=None) -> pd.DataFrame:
    """One truth row per frame (see :func:`curltrack.render.render_video`)."""
    world = traj.rock_xy(t_frames)
    xy = traj.to_truth(world)
    C = np.array([c.C for c in cams])
    cxy = traj.to_truth(C[:, :2])
    psi = traj.psi(t_frames)
    h = rig.rock_height_m
    cols = {"frame": np.arange(len(t_frames)), "t": t_frames, "x": xy[:, 0], "y": xy[:, 1],
            "theta": traj.theta(t_frames), "ok": np.ones(len(t_frames), int)}
    uv = np.array([c.project(np.r_[p, 0.0])[0] for c, p in zip(cams, world)])
    top = np.array([c.project(np.r_[p, h])[0] for c, p in zip(cams, world)])
    cols.update(u_px=uv[:, 0], v_px=uv[:, 1], u_top_px=top[:, 0], v_top_px=top[:, 1])
    for i, m in enumerate(rig.markers):
        c, s = np.cos(psi), np.sin(psi)
        mx = world[:, 0] + c * m.x_m - s * m.y_m
        my = world[:, 1] + s * m.x_m + c * m.y_m
        muv = np.array([cam.project([[a, b, h]])[0] for cam, a, b in zip(cams, mx, my)])
        cols[f"marker{i}_u_px"], cols[f"marker{i}_v_px"] = muv[:, 0], muv[:, 1]
    cols.update(camera_x_m=cxy[:, 0], camera_y_m=cxy[:, 1], camera_height_m=C[:, 2],
                camera_yaw_deg=path.yaw_deg(t_frames) - np.rad2deg(traj.truth_rot))
    cols["in_view"] = cams[0].in_image(uv).astype(int)
    cols["occluded"] = (np.asarray(occluded, float) if occluded is not None
                        else np.zeros(len(t_frames)))
    return pd.DataFrame(cols)
