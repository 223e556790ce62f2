"""Shots in a long series: rest (or held) -> released -> stopped.

:func:`segment_motion` turns per-frame rock positions on the ice and angles (from a
light pass over a session video, :func:`curltrack.batch.split.measure_motion`, or any
series) into shots:

- speed v (m/s) and spin omega (rad/s) from local linear fits over :data:`WINDOW_S`;
- a frame is *moving* when v or |omega| exceed max(floor, 4 sigma), the sigmas
  estimated from the data's own frame-to-frame noise
  (:func:`curltrack.series.noise.white_sigma`); frames where the markers are hidden
  (a hand on the rock) count as moving (held);
- runs of moving frames closer than :data:`MERGE_S` are merged; runs shorter than
  :data:`MIN_SHOT_S` are dropped;
- release = the first frame of the run where the rock's kinetic energy per unit mass,
  v^2 + (R omega)^2 / 2, is within 80 % of its peak (a released rock only slows down);
- the shot's last frame is :data:`TAIL_S` after its motion ends (the tracker needs the
  rest after the stop to time it), or the frame before the next shot.

Frame indices are 0-based and ``end_frame`` is inclusive (as ``track --end-frame``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..rig import INERTIA_RADIUS_M
from .noise import white_sigma

__all__ = ["ShotSegment", "segment_motion"]

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


def segment_motion(t, xy_m, theta, found, inertia_radius_m: float = INERTIA_RADIUS_M,
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
    sig_xy = max(white_sigma(xy_m[:, 0], found, 5), white_sigma(xy_m[:, 1], found, 5))
    v_thr = max(V_FLOOR, 4.0 * sig_xy * gain * np.sqrt(2.0))
    w_thr = max(OMEGA_FLOOR, 4.0 * white_sigma(theta, found, 5) * gain)
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
