"""Tracking accuracy and speed per set-up (rendered shots against their truth).

    python scripts/bench_track.py [--quick]

``bench_setup(...)`` returns a dict of figures for one set-up (used by scripts/bench.py):
position RMS (mm), theta RMS (deg), stop-frame errors (frames), parallax factor error
(%), and the speed ratio tracking fps / decode-only fps measured in the same run.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def decode_fps(video) -> float:
    from curltrack.video import iter_frames

    t0 = time.perf_counter()
    n = sum(1 for _ in iter_frames(video))
    return n / (time.perf_counter() - t0)


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
    print("  ".join(keys))
    for s in setups:
        r = bench_setup(**s)
        print("  ".join(f"{r[k]:.3g}" if isinstance(r[k], float) else str(r[k]) for k in keys),
              flush=True)


if __name__ == "__main__":
    main()
