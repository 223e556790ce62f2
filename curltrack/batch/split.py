"""Shots in a session video: rest (or held) -> released -> stopped (``curltrack split``).

A light pass over the video (frames downscaled to at most :data:`MAX_WIDTH` px wide)
measures, per frame, the rock's markers (the tracker's colour model,
:class:`~curltrack.track.markers.MarkerDetector`) and the image shift of the ice and
thread background (phase correlation), so that a camera that slides or pans along
with the rock is allowed for: the rock's motion on the ice is its image motion minus the
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
        Speed and spin at release (local-fit estimates).
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
        e = energy[a:b + 1]
        if e.max() < 0:
            continue
        # First frame near the peak energy: a released rock only slows down, and near
        # the release the energy is too flat for its argmax to be stable under noise.
        rel = a + int(np.argmax(e >= 0.8 * e.max()))
        nxt = kept[i + 1][0] if i + 1 < len(kept) else n
        end = min(n - 1, nxt - 1, b + int(round(TAIL_S / dt)))
        shots.append(ShotSegment(len(shots) + 1, int(start_index + rel),
                                 int(start_index + end), float(t[rel]), float(t[end]),
                                 int(start_index + b),
                                 float(v[rel]), float(omega[rel])))
    return shots


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) indices of the runs of True."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1))


def measure_motion(video, rig, progress: bool = False) -> dict:
    """One light pass over a video: rock position on the ice (m) and angle per frame.

    Returns
    -------
    dict
        ``t`` (s), ``xy_m`` (N, 2), ``theta`` (rad), ``found`` (bool), ``fps``,
        ``px_per_m`` (at the marker plane, downscaled frames), ``index0``.

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
    n = info.n_frames
    t, shift = np.zeros(n), np.zeros((n, 2))
    pts = np.full((n, M, 2), np.nan)
    prev, window, pred, count = None, None, None, 0
    for k, fr in enumerate(iter_frames(video, fps_override=rig.fps)):
        img = fr.image if scale == 1.0 else cv2.resize(fr.image, None, fx=scale, fy=scale,
                                                       interpolation=cv2.INTER_AREA)
        gray = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY).astype(np.float32)
        if window is None:
            window = cv2.createHanningWindow(gray.shape[::-1], cv2.CV_32F)
        if prev is not None:
            (dx, dy), _ = cv2.phaseCorrelate(prev, gray, window)
            shift[k] = shift[k - 1] + (dx, dy)
        prev = gray
        mf = None
        if pred is not None:
            r = 0.4 * np.ptp(pred, axis=0).max() + 30
            lo, hi = pred.min(axis=0) - r, pred.max(axis=0) + r
            mf = det.detect(img, predicted=pred, roi=(lo[0], lo[1], hi[0], hi[1]))
        if mf is None or not mf.found.all():
            mf = det.detect(img)
        t[k] = fr.t
        if mf.found.all():
            pts[k] = mf.xy_px
            pred = mf.xy_px
        count = k + 1
    t, shift, pts = t[:count], shift[:count], pts[:count]
    found = np.isfinite(pts).all(axis=(1, 2))
    if found.sum() < 3:
        raise TrackingError("the rock's markers are never seen together (check the rig's "
                            "marker colours)", path=video)
    layout = np.array([[m.x_m, m.y_m] for m in rig.markers])
    i, j = np.unravel_index(np.argmax(np.linalg.norm(layout[:, None] - layout[None], axis=2)),
                            (M, M))
    sep_px = np.linalg.norm(pts[found, i] - pts[found, j], axis=1)
    px_per_m = float(np.median(sep_px) / np.linalg.norm(layout[i] - layout[j]))
    centre = pts.mean(axis=1) - shift
    d = pts[:, j] - pts[:, i]
    ang = -np.arctan2(d[:, 1], d[:, 0])  # image y is down: CCW seen from above
    theta = np.full(count, np.nan)
    theta[found] = np.unwrap(ang[found])
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
