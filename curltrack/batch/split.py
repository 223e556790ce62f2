"""Shots in a session video (``curltrack split``): a light pass over the video, then
:func:`curltrack.series.segment.segment_motion`.

The pass (frames downscaled to at most :data:`MAX_WIDTH` px wide) measures, per frame,
the rock's markers (the tracker's colour model,
:class:`~curltrack.track.markers.MarkerDetector`) and the image shift of the ice and
thread background (an ECC fit against a key frame, the rock masked), so that a camera
that slides or pans along with the rock is allowed for: the rock's motion on the ice is
its image motion minus the background's.  The rules that turn that motion into shots
(release, stop, tail) are in :mod:`curltrack.series.segment`.

Frame indices are 0-based and ``end_frame`` is inclusive (as ``track --end-frame``).
"""

from __future__ import annotations

from dataclasses import asdict, replace
from pathlib import Path

import numpy as np

from .._atomic import atomic_path, write_json
from ..errors import TrackingError
from ..series.segment import ShotSegment, segment_motion

MAX_WIDTH = 640          # px: frames are downscaled to at most this width
#: a frame whose grey levels (downscaled 4x) change by over this many times the median
#: change from the frame before (over the last CUT_WINDOW_FRAMES) is a cut (an edited
#: session: shots joined, the camera elsewhere): no shot spans it.  Rendered and filmed shots change 1-6 levels a
#: frame; a cut between two of one rig's shots changed 15.9 against a median of 1.7
CUT_RATIO = 6.0
CUT_MIN_LEVELS = 4.0
#: ... the median over this many frames before it: the camera's own pace changes over a
#: shot (a cut after a slow stretch changed 9.8 levels against 1.0 in the frames before
#: and 1.68 over the whole video so far - ratio 5.83, missed; CI seed 1462310305)
CUT_WINDOW_FRAMES = 30


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
    layout = rig.layout_m
    dist = np.linalg.norm(layout[:, None] - layout[None], axis=2)
    i, j = np.unravel_index(np.argmax(dist), dist.shape)
    rock_per_sep = 0.75 * rig.rock_diameter_m / dist[i, j]  # masked radius / separation
    n = info.n_frames
    t, shift = np.zeros(n), np.zeros((n, 2))
    pts = np.full((n, M, 2), np.nan)
    bg = _BackgroundShift(0.5 if scale * info.width > 400 else 1.0)
    pred, count = None, 0
    change, prev, cuts = np.zeros(n), None, []
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
        small = cv2.resize(gray, None, fx=0.25, fy=0.25, interpolation=cv2.INTER_AREA)
        if prev is not None and prev.shape == small.shape:
            change[k] = float(np.abs(small - prev).mean())
        prev = small
        recent = change[max(1, k + 1 - CUT_WINDOW_FRAMES):k + 1]
        if k and change[k] > max(CUT_RATIO * np.median(recent), CUT_MIN_LEVELS) and k > 5:
            bg = _BackgroundShift(bg.scale)   # (a new scene: a new key frame)
            pred = None
            cuts.append(k)
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
            "px_per_m": px_per_m, "index0": 0, "cuts": cuts}


def split_video(video, rig) -> list[ShotSegment]:
    """Find the shots in a session video (see the module docstring).

    Raises
    ------
    VideoError, TrackingError
        Unreadable video; the rock never seen.
    """
    m = measure_motion(video, rig)
    # (cuts: each scene on its own - no shot, and no velocity, spans one)
    edges = [0, *m["cuts"], len(m["t"])]
    shots: list[ShotSegment] = []
    for a, b in zip(edges[:-1], edges[1:]):
        for sh in segment_motion(m["t"][a:b], m["xy_m"][a:b], m["theta"][a:b],
                                 m["found"][a:b], inertia_radius_m=rig.inertia_radius_m,
                                 start_index=m["index0"] + a):
            shots.append(replace(sh, shot=len(shots) + 1))
    return shots


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
