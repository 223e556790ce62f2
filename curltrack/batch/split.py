"""Shots in a session video: rest (or held) -> released -> stopped (``curltrack split``).

A light pass over the video (frames downscaled to at most :data:`MAX_WIDTH` px wide)
measures, per frame, the rock's markers (the tracker's colour model,
:class:`~curltrack.track.markers.MarkerDetector`) and the image shift of the ice and
thread background (an ECC fit against a key frame, the rock masked), so that a camera
that slides or pans along with the rock is allowed for: the rock's motion on the ice is its image motion minus the
background's.  :func:`segment_motion` then turns the per-frame positions and angles into
shots:

- speed v (m/s) and spin omega (rad/s) from local linear fits over :data:`WINDOW_S`;
- a frame is *moving* when v or |omega| exceed max(floor, 4 sigma), the sigmas
  estimated from the data's own frame-to-frame noise; frames where the markers are
  hidden (a hand on the rock) count as moving (held);
- runs of moving frames closer than :data:`MERGE_S` are merged; runs shorter than
  :data:`MIN_SHOT_S` are dropped;
- release = the first frame of the run where the rock's kinetic energy per unit mass,
  v^2 + (R omega)^2 / 2, is within 80 % of its peak (a released rock only slows down);
- the shot's last frame is :data:`TAIL_S` after its motion ends (the tracker needs the
  rest after the stop to time it), or the frame before the next shot.

Frame indices are 0-based and ``end_frame`` is inclusive (as ``track --end-frame``).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from .._atomic import atomic_path, write_json
from ..errors import TrackingError

MAX_WIDTH = 640          # px: frames are downscaled to at most this width
WINDOW_S = 0.25          # s: local-fit window for v and omega
V_FLOOR = 0.02           # m/s: slower than this is rest, whatever the noise
OMEGA_FLOOR = 0.15       # rad/s
MERGE_S = 0.4            # s: pauses shorter than this do not end a shot
MIN_SHOT_S = 0.5         # s: shorter motion is not a shot (a nudge, a hand passing)
TAIL_S = 1.0             # s: rest kept after each shot's motion ends


@dataclass(frozen=True)
class ShotSegment:
    """One shot found in a video.

    Attributes
    ----------
    shot : int
        1-based position in the video.
    start_frame, end_frame : int
        Release frame and last frame to track (inclusive).
    t_start_s, t_end_s : float
        Their times from the start of the video (s).
    motion_end_frame : int
        Last frame in which the rock was seen moving.
    peak_speed_m_s, peak_omega_rad_s : float
        Speed and spin just after release (fits over the first :data:`WINDOW_S`).
    """

    shot: int
    start_frame: int
    end_frame: int
    t_start_s: float
    t_end_s: float
    motion_end_frame: int
    peak_speed_m_s: float
    peak_omega_rad_s: float


def _local_slope(t, q, ok, half):
    """Slope of a straight-line fit of q over +-half samples (NaN where too few points)."""
    n = len(t)
    out = np.full(n, np.nan)
    qq = np.where(ok, q, 0.0)
    w = ok.astype(float)
    # Windowed sums by cumulative sums: vectorised local linear regression.
    def wsum(a):
        c = np.concatenate([[0.0], np.cumsum(a)])
        lo = np.clip(np.arange(n) - half, 0, n)
        hi = np.clip(np.arange(n) + half + 1, 0, n)
        return c[hi] - c[lo]
    tt = t - t[0]
    S, St, Sq = wsum(w), wsum(w * tt), wsum(w * qq)
    Stt, Stq = wsum(w * tt * tt), wsum(w * tt * qq)
    den = S * Stt - St**2
    good = (S >= max(3, half)) & (den > 1e-12)
    out[good] = (S * Stq - St * Sq)[good] / den[good]
    return out


def _noise(q, ok):
    """1-sigma per-frame noise of q from second differences of consecutive good frames."""
    d2 = q[2:] - 2 * q[1:-1] + q[:-2]
    good = ok[2:] & ok[1:-1] & ok[:-2]
    if good.sum() < 5:
        return 0.0
    return float(1.4826 * np.median(np.abs(d2[good])) / np.sqrt(6.0))


def segment_motion(t, xy_m, theta, found, inertia_radius_m: float = 0.14,
                   start_index: int = 0) -> list[ShotSegment]:
    """Shots from per-frame rock positions on the ice and angles.

    Parameters
    ----------
    t : (N,) array
        Frame times (s), increasing.
    xy_m : (N, 2) array
        Rock position on the ice (m, any fixed frame); NaN where not measured.
    theta : (N,) array
        Rock angle (rad, unwrapped); NaN where not measured.
    found : (N,) bool array
        Markers seen in the frame (False = hidden, e.g. held).
    inertia_radius_m : float
        R of I = M R^2 / 2 (m), to weigh spin against speed when finding the release.
    start_index : int
        Frame index of the first sample.

    Returns
    -------
    list of ShotSegment
    """
    t = np.asarray(t, float)
    n = len(t)
    found = np.asarray(found, bool) & np.isfinite(xy_m).all(axis=1) & np.isfinite(theta)
    if n < 5 or found.sum() < 5:
        return []
    dt = float(np.median(np.diff(t)))
    half = max(2, int(round(WINDOW_S / dt / 2)))
    vx, vy = (_local_slope(t, xy_m[:, k], found, half) for k in range(2))
    omega = _local_slope(t, theta, found, half)
    v = np.hypot(vx, vy)
    # Noise of a local slope over 2h+1 samples: sigma_q * sqrt(12 / (m (m^2 - 1))) / dt.
    m = 2 * half + 1
    gain = np.sqrt(12.0 / (m * (m * m - 1))) / dt
    sig_xy = max(_noise(xy_m[:, 0], found), _noise(xy_m[:, 1], found))
    v_thr = max(V_FLOOR, 4.0 * sig_xy * gain * np.sqrt(2.0))
    w_thr = max(OMEGA_FLOOR, 4.0 * _noise(theta, found) * gain)
    known = found & np.isfinite(v) & np.isfinite(omega)
    moving = ~known | (np.nan_to_num(v) > v_thr) | (np.abs(np.nan_to_num(omega)) > w_thr)
    energy = np.where(known, np.nan_to_num(v) ** 2
                      + 0.5 * (inertia_radius_m * np.nan_to_num(omega)) ** 2, -1.0)

    runs = _runs(moving)
    merged: list[list[int]] = []
    for a, b in runs:
        if merged and t[a] - t[merged[-1][1]] <= MERGE_S:
            merged[-1][1] = b
        else:
            merged.append([a, b])
    shots = []
    kept = [(a, b) for a, b in merged if t[b] - t[a] >= MIN_SHOT_S and known[a:b + 1].any()]
    for i, (a, b) in enumerate(kept):
        # Energy from forward-looking fits (frames k .. k + 2h): at the release frame the
        # window holds only free motion, one frame earlier it holds a frame of rest.
        lo = max(0, a - half)
        e = np.full(b + 1 - lo, -1.0)
        e[: max(0, n - half - lo)] = energy[lo + half: b + 1 + half][: len(e)]
        e[~known[lo: b + 1]] = -1.0  # the release frame itself must be seen
        if e.max() < 0:
            continue
        # First frame near the peak: a released rock only slows down, and near the
        # release the energy is too flat for its argmax to be stable under noise.
        rel = lo + int(np.argmax(e >= 0.8 * e.max()))
        nxt = kept[i + 1][0] if i + 1 < len(kept) else n
        end = min(n - 1, nxt - 1, b + int(round(TAIL_S / dt)))
        fwd = min(n - 1, rel + half)
        shots.append(ShotSegment(len(shots) + 1, int(start_index + rel),
                                 int(start_index + end), float(t[rel]), float(t[end]),
                                 int(start_index + b), float(v[fwd]), float(omega[fwd])))
    return shots


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) indices of the runs of True."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1))


def _bandpass(gray: np.ndarray) -> np.ndarray:
    """Keep threads and ice texture; drop shading (vignetting, glare) and codec blocks."""
    import cv2

    return cv2.GaussianBlur(gray, (0, 0), 1.5) - cv2.GaussianBlur(gray, (0, 0), 8.0)


class _BackgroundShift:
    """Image shift of the ice + threads against a key frame (ECC, translation, rock masked).

    Consecutive-frame phase correlation underestimates the ~1 px/frame shifts of a
    following camera (static codec blocks pull it to zero); an ECC fit against a key
    frame, started from the last estimate, does not accumulate that bias.  The key is
    renewed every few percent of the frame's size; a fit that jumps further than a
    camera moves between frames is replaced by the constant-velocity guess.
    """

    def __init__(self, scale: float):
        self.scale, self.key, self.key_off = scale, None, np.zeros(2)
        self.warp = np.eye(2, 3, dtype=np.float32)
        self.step = np.zeros(2, np.float32)

    def update(self, gray: np.ndarray, rock_xy, rock_r) -> np.ndarray:
        import cv2

        g = cv2.resize(gray, None, fx=self.scale, fy=self.scale,
                       interpolation=cv2.INTER_AREA) if self.scale != 1 else gray
        g = _bandpass(g)
        if self.key is None:
            self._rekey(g, rock_xy, rock_r)
            return self.key_off.copy()
        mask = self.mask.copy()
        if rock_xy is not None:  # the rock's current place, seen from the key frame
            c = (np.asarray(rock_xy) - self.key_off) * self.scale
            cv2.circle(mask, (int(c[0]), int(c[1])), int(rock_r * self.scale), 0, -1)
        guess = self.warp.copy()
        guess[:, 2] += self.step  # constant velocity
        try:
            _, warp = cv2.findTransformECC(
                self.key, g, guess.copy(), cv2.MOTION_TRANSLATION,
                (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-4), mask, 1)
        except cv2.error:  # no convergence (a blank or blurred frame)
            warp = guess
        if np.hypot(*(warp[:, 2] - guess[:, 2])) > 0.05 * min(g.shape):
            warp = guess  # a jump no camera makes between frames: ECC slipped
        self.step = warp[:, 2] - self.warp[:, 2]
        self.warp = warp
        shift = self.key_off + self.warp[:, 2] / self.scale
        if np.abs(self.warp[:, 2]).max() > 0.08 * min(g.shape):
            self._rekey(g, rock_xy, rock_r, shift)
        return shift

    def _rekey(self, g, rock_xy, rock_r, offset=None):
        import cv2

        self.key = g
        self.key_off = np.zeros(2) if offset is None else np.asarray(offset, float)
        self.warp = np.eye(2, 3, dtype=np.float32)
        self.mask = np.full(g.shape, 255, np.uint8)
        if rock_xy is not None:
            c = np.asarray(rock_xy) * self.scale
            cv2.circle(self.mask, (int(c[0]), int(c[1])), int(rock_r * self.scale), 0, -1)


def measure_motion(video, rig, progress: bool = False) -> dict:
    """One light pass over a video: rock position on the ice (m) and angle per frame.

    Returns
    -------
    dict
        ``t`` (s), ``xy_m`` (N, 2; image axes, y up, scaled at the marker plane),
        ``theta`` (rad, CCW from above), ``found`` (bool), ``fps``, ``px_per_m``
        (marker plane, downscaled frames), ``index0``.

    Raises
    ------
    VideoError
        Unreadable or truncated video.
    TrackingError
        The rock's markers are never seen together.
    """
    import cv2

    from ..track.markers import MarkerDetector
    from ..video import iter_frames, probe_video

    info = probe_video(video, fps_override=rig.fps)
    scale = min(1.0, MAX_WIDTH / info.width)
    det = MarkerDetector(rig)
    M = len(rig.markers)
    layout = np.array([[m.x_m, m.y_m] for m in rig.markers])
    dist = np.linalg.norm(layout[:, None] - layout[None], axis=2)
    i, j = np.unravel_index(np.argmax(dist), dist.shape)
    rock_per_sep = 0.75 * rig.rock_diameter_m / dist[i, j]  # masked radius / separation
    n = info.n_frames
    t, shift = np.zeros(n), np.zeros((n, 2))
    pts = np.full((n, M, 2), np.nan)
    bg = _BackgroundShift(0.5 if scale * info.width > 400 else 1.0)
    pred, count = None, 0
    for k, fr in enumerate(iter_frames(video, fps_override=rig.fps)):
        img = fr.image if scale == 1.0 else cv2.resize(fr.image, None, fx=scale, fy=scale,
                                                       interpolation=cv2.INTER_AREA)
        mf = None
        if pred is not None:
            r = 0.6 * np.ptp(pred, axis=0).max() + 20
            lo, hi = pred.min(axis=0) - r, pred.max(axis=0) + r
            mf = det.detect(img, predicted=pred, roi=(lo[0], lo[1], hi[0], hi[1]))
        if mf is None or not mf.found.all():
            mf = det.detect(img)
        rock_xy, rock_r = None, 0.0
        if mf.found.all():
            pts[k] = pred = mf.xy_px
            rock_xy = mf.xy_px.mean(axis=0)
            rock_r = rock_per_sep * float(np.linalg.norm(mf.xy_px[i] - mf.xy_px[j]))
        gray = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY).astype(np.float32)
        shift[k] = bg.update(gray, rock_xy, rock_r)
        t[k] = fr.t
        count = k + 1
    t, shift, pts = t[:count], shift[:count], pts[:count]
    found = np.isfinite(pts).all(axis=(1, 2))
    if found.sum() < 3:
        raise TrackingError("the rock's markers are never seen together (check the rig's "
                            "marker colours)", path=video)
    sep_px = np.linalg.norm(pts[found, i] - pts[found, j], axis=1)
    px_per_m = float(np.median(sep_px) / dist[i, j])
    centre = pts.mean(axis=1) - shift
    d = pts[:, j] - pts[:, i]
    theta = np.full(count, np.nan)
    theta[found] = np.unwrap(-np.arctan2(d[found, 1], d[found, 0]))  # image y is down
    xy = centre / px_per_m * (1.0, -1.0)
    return {"t": t, "xy_m": xy, "theta": theta, "found": found, "fps": info.fps,
            "px_per_m": px_per_m, "index0": 0}


def split_video(video, rig) -> list[ShotSegment]:
    """Find the shots in a session video (see the module docstring).

    Raises
    ------
    VideoError, TrackingError
        Unreadable video; the rock never seen.
    """
    m = measure_motion(video, rig)
    return segment_motion(m["t"], m["xy_m"], m["theta"], m["found"],
                          inertia_radius_m=rig.inertia_radius_m, start_index=m["index0"])


def write_segments(path, segments: list[ShotSegment], video=None) -> Path:
    """Write the shots as CSV (``.csv``) or JSON (otherwise), atomically."""
    path = Path(path)
    rows = [asdict(s) for s in segments]
    if path.suffix.lower() == ".csv":
        import pandas as pd

        cols = list(ShotSegment.__dataclass_fields__)
        with atomic_path(path) as tmp:
            pd.DataFrame(rows, columns=cols).to_csv(tmp, index=False, float_format="%.6g")
    else:
        write_json(path, {"video": str(video) if video else None, "shots": rows})
    return path


def split_task(job, rig, outdir) -> list[tuple[int, int]]:
    """Batch task: the (start, end) frames of a video's shots, cached in ``outdir/_split``.

    The cache is keyed like a shot (video bytes, rig, version), so a re-run does not
    read the video again.
    """
    import json

    from .jobs import BatchOptions, file_digest, job_key
    from .shot import limit_threads

    limit_threads()
    cache = Path(outdir) / "_split" / f"{job.shot_id}.json"
    try:
        old = json.loads(cache.read_text())
    except (OSError, ValueError):
        old = {}
    digest = file_digest(job.video, cached=old.get("input"))
    key = job_key(job, digest.sha256, rig.to_toml() + "\n#split", BatchOptions())
    if old.get("key") == key:
        return [tuple(s) for s in old["segments"]]
    segments = [(s.start_frame, s.end_frame) for s in split_video(job.video, rig)]
    write_json(cache, {"key": key, "input": digest.__dict__, "segments": segments})
    return segments


__all__ = ["ShotSegment", "measure_motion", "segment_motion", "split_task", "split_video",
           "write_segments"]
