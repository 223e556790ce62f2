"""Tracking accuracy and speed per set-up (rendered shots against their truth).

    python scripts/bench_track.py [--quick | --speed]

``bench_setup(...)`` returns a dict of figures for one set-up (used by scripts/bench.py):
position RMS (mm), theta RMS (deg), stop-frame errors (frames), parallax factor error
(%), and the speed ratio tracking fps / decode-only fps measured in the same run.

``bench_speed(width, height, ...)`` (called by scripts/bench.py at 960x540 and
1920x1080) measures tracking against decoding alone on the same rendered video in
one run, with the per-stage milliseconds per frame (decode, grid, markers, other) and
the one-off calibration, and the accuracy against truth on the same frames.

Threads (how the ratio is configured): both the decode-only pass and tracking run with
``CURLTRACK_THREADS`` threads, default 1.  That variable sets the FFmpeg decoder's
thread count (``cv2.CAP_PROP_N_THREADS`` when curltrack.video opens the file, see
``curltrack.video.decoder_threads``) and ``track_video`` sets ``cv2.setNumThreads`` to
it for its own OpenCV calls (restored afterwards); ``bench_speed(threads=N)`` sets both.
One thread per process is how batch runs work (one video per core), and it makes CPU
time a fair measure on a shared machine: speeds are CPU time of the process, the wall
clock ratio is reported beside it (``ratio_wall``).
"""

from __future__ import annotations

import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np


def decode_fps(video) -> float:
    from curltrack.video import iter_frames

    t0 = time.perf_counter()
    n = sum(1 for _ in iter_frames(video))
    return n / (time.perf_counter() - t0)


#: Clock of the speed benchmark: CPU time of this process.  The machines these run on
#: are shared (load averages of several per core): wall time then measures the
#: neighbours; with one thread per process (decoder and OpenCV), CPU time is the work.
_now = time.process_time


class _StageClock:
    """Accumulate wall time spent in a few named callables, in one tracking run.

    The stages are wrapped (not copied): the grid (``GridTracker.update`` plus the
    one-off ``calibrate_frame``), the markers (the follower's ``detect``) and the
    decoder (the frame iterator's ``next``); everything else is "other".
    """

    def __init__(self):
        self.s = {"decode": 0.0, "grid": 0.0, "calibrate": 0.0, "markers": 0.0}
        self._undo = []

    def wrap(self, owner, name, stage):
        orig = getattr(owner, name)
        clock = self.s

        def timed(*a, **k):
            t0 = _now()
            try:
                return orig(*a, **k)
            finally:
                clock[stage] += _now() - t0

        setattr(owner, name, timed)
        self._undo.append((owner, name, orig))

    def wrap_iter(self, owner, name):
        orig = getattr(owner, name)
        clock = self.s

        def timed_iter(*a, **k):
            it = orig(*a, **k)
            while True:
                t0 = _now()
                try:
                    fr = next(it)
                except StopIteration:
                    return
                finally:
                    clock["decode"] += _now() - t0
                yield fr

        setattr(owner, name, timed_iter)
        self._undo.append((owner, name, orig))

    def __enter__(self):
        import curltrack.calib.tracker as tr
        import curltrack.track.pipeline as pl
        import curltrack.video as vid

        self.wrap(tr.GridTracker, "update", "grid")
        self.wrap(pl, "_calibrate", "calibrate")
        self.wrap(pl._Follower, "detect", "markers")
        self.wrap_iter(vid, "iter_frames")
        return self

    def __exit__(self, *exc):
        for owner, name, orig in reversed(self._undo):
            setattr(owner, name, orig)


def bench_speed(width=960, height=540, n_frames=150, seed=0, motion="ladder",
                threads=1, repeats=2, workdir=None, full_draw=False) -> dict:
    """Tracking speed against decoding alone, on one rendered shot, in one run.

    The shot (a short draw, v0 = 1.2 m/s, omega0 = 1.5 rad/s, alpha_y = 0.02; or with
    ``full_draw`` the paper's draw, v0 = 1.8 m/s on its pebbled ice, 24 s to rest, whole)
    is rendered at ``width`` x ``height``; its first ``n_frames`` frames (all of them
    when None) are decoded alone (iterating
    :func:`curltrack.video.iter_frames`) and tracked (:func:`curltrack.track.track_video`
    with ``end_frame``), each ``repeats`` times, alternating, and the fastest run of each
    is kept.  Times are CPU times of this process (:data:`_now`; ``ratio_wall`` is the
    same ratio in wall time, for reference).

    Threads: ``cv2.setNumThreads(threads)`` and ``CURLTRACK_THREADS=threads`` are set
    for both - the decoder and the tracker then use the same thread budget (OpenCV's
    FFmpeg decoder takes its thread count from ``CURLTRACK_THREADS`` through
    :func:`curltrack.video.decoder_threads`, the tracker's own OpenCV calls from
    ``cv2.setNumThreads`` set in ``track_video``).  Default 1 thread per process, as
    batch workers run.

    Returns
    -------
    dict
        ``decode_fps``, ``track_fps``, ``ratio`` (track / decode), per-frame ms of the
        stages measured inside the tracking run (``decode_ms``, ``grid_ms``,
        ``markers_ms``, ``other_ms``; ``calibrate_s`` the one-off calibration), the
        accuracy against truth on the same frames (``pos_rms_mm``, ``theta_rms_deg``),
        and the set-up.
    """
    import os

    import cv2

    from curltrack.physics.shot import ShotModel
    from curltrack.render import CameraConfig, RenderConfig, render_video
    from curltrack.rig import default_rig
    from curltrack.simulate import simulate_series
    from curltrack.track import track_video

    os.environ["CURLTRACK_THREADS"] = str(int(threads))
    cv2.setNumThreads(int(threads))
    rig = default_rig()
    work = Path(workdir or tempfile.mkdtemp(prefix="bench_speed_"))
    model = (ShotModel(v0=1.8, omega0=1.5) if full_draw
             else ShotModel(v0=1.2, omega0=1.5, alpha_y=0.02))
    sim = simulate_series(model, fps=30)
    sim = replace(sim, data=sim.data.iloc[:n_frames].reset_index(drop=True))
    cam = CameraConfig(motion=motion)
    video = work / (f"speed_{width}x{height}_{motion}_{seed}_"
                    f"{'draw' if full_draw else n_frames}.mp4")
    truth_path = video.with_suffix(".truth.csv")
    if video.exists() and truth_path.exists():  # (a workdir given twice: render once)
        from curltrack.series import read_series

        truth = read_series(truth_path)
    else:
        truth = render_video(sim, rig, video, truth_path, seed=seed,
                             config=RenderConfig(camera=cam, width=width, height=height))
    n = len(truth.data)
    best_dec, best_trk, stages, series = np.inf, np.inf, None, None
    wall_dec = wall_trk = np.inf
    for _ in range(max(1, repeats)):
        t0, w0 = _now(), time.perf_counter()
        sum(1 for _ in _iter_frames(video))
        best_dec = min(best_dec, _now() - t0)
        wall_dec = min(wall_dec, time.perf_counter() - w0)
        with _StageClock() as clock:
            t0, w0 = _now(), time.perf_counter()
            series = track_video(video, rig)
            dt = _now() - t0
            wall_trk = min(wall_trk, time.perf_counter() - w0)
        if dt < best_trk:
            best_trk, stages = dt, dict(clock.s)
    m = series.data.merge(truth.data[["frame", "x", "y", "theta"]], on="frame",
                          suffixes=("", "_t"))
    ok = m["ok"] == 1
    e = np.hypot(m.x - m.x_t, m.y - m.y_t)[ok]
    eth = (m.theta - m.theta_t)[ok]
    per = 1e3 / n
    loop = best_trk - stages["calibrate"]
    return {
        "width": width, "height": height, "motion": motion, "frames": n, "threads": threads,
        "full_draw": bool(full_draw), "seconds": float(truth.data["t"].iloc[-1]),
        "decode_fps": n / best_dec, "track_fps": n / best_trk, "ratio": best_dec / best_trk,
        "ratio_excl_calibration": best_dec / loop, "ratio_wall": wall_dec / wall_trk,
        "decode_ms": stages["decode"] * per, "grid_ms": stages["grid"] * per,
        "markers_ms": stages["markers"] * per, "calibrate_s": stages["calibrate"],
        "other_ms": (loop - stages["decode"] - stages["grid"] - stages["markers"]) * per,
        "pos_rms_mm": 1000 * float(np.sqrt(np.mean(e ** 2))),
        "theta_rms_deg": float(np.degrees(np.sqrt(np.mean(eth ** 2)))),
        "ok_fraction": float(ok.mean()),
    }


def _iter_frames(video):
    from curltrack.video import iter_frames

    return iter_frames(video)


def bench_setup(motion="ladder", height_m=2.0, tilt_deg=1.5, k1=-0.08, spacing_m=0.15,
                v0=1.0, omega0=1.5, alpha_y=0.02, occlusion=False, seed=0, workdir=None):
    """Render one shot, track it, compare with truth; return the figures."""
    from dataclasses import replace

    from curltrack.physics.shot import ShotModel
    from curltrack.render import CameraConfig, RenderConfig, render_video
    from curltrack.rig import default_rig
    from curltrack.simulate import simulate_series
    from curltrack.track import track_video

    rig = replace(default_rig(), spacing_x_m=spacing_m, spacing_y_m=spacing_m)
    work = Path(workdir or tempfile.mkdtemp(prefix="bench_track_"))
    sim = simulate_series(ShotModel(v0=v0, omega0=omega0, alpha_y=alpha_y), fps=30)
    cam = CameraConfig(motion=motion, height_m=height_m, tilt_deg=tilt_deg, k1=k1)
    video = work / f"{motion}_{seed}.mp4"
    truth = render_video(sim, rig, video, config=RenderConfig(camera=cam, occlusion=occlusion),
                         seed=seed)
    dec = decode_fps(video)
    t0 = time.perf_counter()
    series = track_video(video, rig)
    trk = len(series.data) / (time.perf_counter() - t0)
    m = series.data.merge(truth.data[["frame", "x", "y", "theta"]], on="frame",
                          suffixes=("", "_t"))
    ok = m["ok"] == 1
    e = np.hypot(m.x - m.x_t, m.y - m.y_t)[ok]
    eth = (m.theta - m.theta_t)[ok]
    H = float(truth.data["camera_height_m"].iloc[0])
    k_true = (H - rig.rock_height_m) / H

    def stop_err(key):
        a, b = series.meta.get(key), truth.meta.get(key)
        return None if a is None or b is None else int(a) - int(b)

    return {
        "motion": motion, "height_m": height_m, "tilt_deg": tilt_deg, "k1": k1,
        "spacing_m": spacing_m, "occlusion": occlusion, "seed": seed,
        "frames": len(m), "ok_fraction": float(ok.mean()),
        "pos_rms_mm": 1000 * float(np.sqrt(np.mean(e**2))),
        "pos_max_mm": 1000 * float(e.max()),
        "theta_rms_deg": float(np.degrees(np.sqrt(np.mean(eth**2)))),
        "stop_err_translation_frames": stop_err("stop_frame_translation"),
        "stop_err_rotation_frames": stop_err("stop_frame_rotation"),
        "parallax_err_pct": 100 * (series.meta["parallax_factor"] - k_true) / k_true,
        "camera_height_m": series.meta["camera_height_m"], "camera_height_true_m": H,
        "speed_ratio": trk / dec, "track_fps": trk, "decode_fps": dec,
    }


SETUPS = [
    dict(motion="ladder"),
    dict(motion="handheld", height_m=1.6, seed=1),
    dict(motion="ladder", height_m=3.0, tilt_deg=3.0, spacing_m=0.3, seed=2),
    dict(motion="ladder", height_m=1.5, spacing_m=0.1, k1=-0.05, seed=3),
    dict(motion="handheld", occlusion=True, seed=4),
]


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    setups = SETUPS[:2] if "--quick" in argv else SETUPS
    keys = ["motion", "height_m", "tilt_deg", "spacing_m", "pos_rms_mm", "theta_rms_deg",
            "stop_err_translation_frames", "stop_err_rotation_frames", "parallax_err_pct",
            "speed_ratio"]
    if "--speed" in argv:
        for w, h, full in ((960, 540, False), (1920, 1080, False), (960, 540, True)):
            r = bench_speed(w, h, n_frames=None if full else 150, full_draw=full)
            print(f"{w}x{h}, {r['frames']} frames: decode {r['decode_fps']:.0f} fps, "
                  f"track {r['track_fps']:.0f} fps,"
                  f" ratio {r['ratio']:.3f} (without calibration "
                  f"{r['ratio_excl_calibration']:.3f}); ms/frame decode {r['decode_ms']:.2f}"
                  f" grid {r['grid_ms']:.2f} markers {r['markers_ms']:.2f} other "
                  f"{r['other_ms']:.2f}; calibration {r['calibrate_s']:.2f} s", flush=True)
        return
    print("  ".join(keys))
    for s in setups:
        r = bench_setup(**s)
        print("  ".join(f"{r[k]:.3g}" if isinstance(r[k], float) else str(r[k]) for k in keys),
              flush=True)


if __name__ == "__main__":
    main()
