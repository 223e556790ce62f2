"""Grid calibration and tracking accuracy and speed per set-up (rendered shots vs truth).

    python scripts/bench_calib.py [--quick]

``bench_grid(...)`` returns a dict for one set-up (used by scripts/bench.py): the error of
the per-frame image -> ice mapping at the true rock centre (RMS and max, mm, after the
lattice-to-truth rigid fit), the fraction of frames with a trusted grid, the lens
recovery (k1 relative error, distortion-centre error px), and the speed: grid-only
ms/frame, decode-only ms/frame and their ratio decode / (decode + grid) in the same run.
"""

from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

SETUPS = {
    "ladder_2m_0.15": dict(motion="ladder", height_m=2.0, spacing=(0.15, 0.15), v0=2.2),
    "ladder_3m_0.3_tilt3": dict(motion="ladder", height_m=3.0, spacing=(0.3, 0.3), v0=2.2,
                                tilt_deg=3.0),
    "handheld_1.5m_0.1": dict(motion="handheld", height_m=1.5, spacing=(0.1, 0.1), v0=2.5,
                              k1=-0.06),
    "ladder_3colour_0.1x0.2": dict(motion="ladder", height_m=2.5, spacing=(0.1, 0.2), v0=2.0,
                                   colors=("#d02020", "#2040d0", "#20a040")),
    "handheld_fast_3mps": dict(motion="handheld", height_m=1.6, spacing=(0.15, 0.15), v0=3.0),
    "ladder_nocolour": dict(motion="ladder", height_m=2.0, spacing=(0.15, 0.15), v0=2.0,
                            colors=()),
}


def _align(est, truth):
    """RMS / max error after the best quarter-turn rotation and offset (m)."""
    best = None
    for k in range(4):
        c, s = np.round(np.cos(k * np.pi / 2)), np.round(np.sin(k * np.pi / 2))
        e = est @ np.array([[c, -s], [s, c]]).T
        err = e + (truth - e).mean(axis=0) - truth
        r = np.hypot(*err.T)
        if best is None or np.sqrt(np.mean(r ** 2)) < best[0]:
            best = (float(np.sqrt(np.mean(r ** 2))), float(r.max()))
    return best


def bench_grid(name="ladder_2m_0.15", seconds=3.0, seed=0, workdir=None, **over):
    """Render one set-up, follow its grid, compare with truth; return the figures."""
    from curltrack.calib import GridTracker, calibrate_frame
    from curltrack.physics.closed_form import decel_position
    from curltrack.render import RenderConfig, render_video
    from curltrack.render.motion import CameraConfig
    from curltrack.rig import Rig
    from curltrack.series import Series, make_meta
    from curltrack.video import iter_frames
    import cv2
    import pandas as pd

    s = {**SETUPS[name], **over}
    rig = Rig(spacing_x_m=s["spacing"][0], spacing_y_m=s["spacing"][1],
              **({"grid_colors": s["colors"]} if "colors" in s else {}))
    fps, lam, t_F = 30.0, 1.9, 12.0
    t = np.arange(int(seconds * fps) + 1) / fps
    y = decel_position(t, s["v0"] * t_F / lam, lam, t_F)
    th = decel_position(t, 1.5 * t_F / lam, lam, t_F)
    series = Series(pd.DataFrame(dict(frame=np.arange(len(t)), t=t, x=0 * t, y=y, theta=th,
                                      ok=1)), make_meta(fps, len(t)))
    cam = CameraConfig(motion=s["motion"], height_m=s["height_m"],
                       tilt_deg=s.get("tilt_deg", 1.5), k1=s.get("k1", -0.08))
    work = Path(workdir or tempfile.mkdtemp(prefix="bench_calib_"))
    video = work / f"{name}.mp4"
    truth = render_video(series, rig, video, config=RenderConfig(camera=cam), seed=seed).data
    meta = json.loads(video.with_suffix(".render.json").read_text())
    t0 = time.perf_counter()
    n = sum(1 for _ in iter_frames(video))
    dec = (time.perf_counter() - t0) / n
    tracker, est, ok, t_grid = None, [], [], 0.0
    for fr in iter_frames(video):
        row = truth.iloc[fr.index]
        if tracker is None:
            cal = calibrate_frame(fr.image, rig)
            tracker = GridTracker(cal, rig)
        mask = np.zeros(fr.image.shape[:2], np.uint8)
        r_px = 0.65 * rig.rock_diameter_m / cal.metres_per_px()
        cv2.circle(mask, (int(row.u_top_px), int(row.v_top_px)), int(r_px), 255, -1)
        t1 = time.perf_counter()
        pose = tracker.update(fr.image, fr.index, mask)
        t_grid += time.perf_counter() - t1
        est.append(pose.image_to_ice([[row.u_px, row.v_px]])[0])
        ok.append(pose.ok)
    est, ok = np.array(est), np.array(ok)
    rms, mx = _align(est[ok], truth[["x", "y"]].to_numpy()[ok]) if ok.any() else (np.nan,) * 2
    k1_true = meta["camera"]["k1"] * (cal.K[0, 0] / meta["f_px"]) ** 2
    grid = t_grid / n
    return {"setup": name, "frames": n, "ok_fraction": float(ok.mean()),
            "pos_rms_mm": 1e3 * rms, "pos_max_mm": 1e3 * mx,
            "k1_rel_err": float(abs(cal.dist[0] / k1_true - 1)),
            "centre_err_px": float(np.hypot(cal.K[0, 2] - meta["cx_px"],
                                            cal.K[1, 2] - meta["cy_px"])),
            "grid_ms": 1e3 * grid, "decode_ms": 1e3 * dec,
            "speed_ratio": dec / (dec + grid)}


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    quick = "--quick" in argv
    names = list(SETUPS)[:2] if quick else list(SETUPS)
    print(f"{'setup':26s} {'ok':>5s} {'rms mm':>7s} {'max mm':>7s} {'k1 err':>7s} "
          f"{'c px':>5s} {'grid ms':>8s} {'dec ms':>7s} {'ratio':>6s}")
    for name in names:
        r = bench_grid(name, seconds=1.5 if quick else 3.0)
        print(f"{r['setup']:26s} {r['ok_fraction']:5.2f} {r['pos_rms_mm']:7.3f} "
              f"{r['pos_max_mm']:7.3f} {r['k1_rel_err']:7.3f} {r['centre_err_px']:5.1f} "
              f"{r['grid_ms']:8.1f} {r['decode_ms']:7.1f} {r['speed_ratio']:6.2f}")


if __name__ == "__main__":
    main()
