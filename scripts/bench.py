#!/usr/bin/env python
"""curltrack benchmark: speed, accuracy and scale, measured against the targets in one run.

Renders its own inputs deterministically (seeds), then measures

* render: frames/s at 960x540 with motion blur on one core, and ÷ plain mp4v encoding;
* simulate: ms per typical draw (target < 50 ms);
* fit: ms per shot, and λ recovery error against noise level;
* track: per set-up position RMS/max (mm), θ RMS (deg), stop-frame errors, parallax
  factor error (%), camera height, and speed as track fps ÷ decode-only fps of the same
  video in the same run (960x540 and 1920x1080);
* discover: s per shot, detection rate against effect strength, false-alarm rate;
* batch: throughput with 1 and 2 Dask workers;
* memory: peak RSS of tracking against video length (must be flat), when available.

Usage::

    python scripts/bench.py [--quick] [--json OUT.json] [--only track,fit]

Prints a human table on stderr and one JSON document on stdout (and to --json).
Decoder threads: OpenCV is set to 1 thread (cv2.setNumThreads(1)) for every timed
section, so ratios compare like with like on one core; set CURLTRACK_BENCH_THREADS to
change it.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import tempfile
import time
import traceback
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))

THREADS = int(os.environ.get("CURLTRACK_BENCH_THREADS", "1"))


def _median_ms(fn, n):
    fn()
    runs = []
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        runs.append(time.perf_counter() - t0)
    return 1e3 * statistics.median(runs)


def machine() -> dict:
    import cv2

    return {"platform": platform.platform(), "python": platform.python_version(),
            "cpus": os.cpu_count(), "opencv": cv2.__version__, "numpy": np.__version__,
            "opencv_threads": THREADS,
            "decoder_threads": f"cv2.setNumThreads({THREADS}); FFmpeg backend default"}


def bench_simulate(quick: bool) -> dict:
    from curltrack.physics import ShotModel, simulate
    from curltrack.simulate import simulate_series

    model = ShotModel(v0=2.0, omega0=1.5)
    t = np.arange(0, 27.0, 1 / 30)
    n = 10 if quick else 40
    return {"draw_ms": _median_ms(lambda: simulate(model, t=t), n),
            "draw_series_ms": _median_ms(lambda: simulate_series(model), n),
            "target_ms": 50.0}


def bench_fit(quick: bool) -> dict:
    from curltrack.fit import fit_series
    from synth import closed_form_series

    out = {"per_noise": []}
    trials = 5 if quick else 25
    rng = np.random.default_rng(2024)
    for noise_mm in (0.0, 1.0, 2.0, 5.0):
        errs_t, errs_y, times = [], [], []
        for _ in range(trials):
            lt, ly = rng.uniform(1.3, 1.7), rng.uniform(1.75, 2.2)
            s = closed_form_series(lam_theta=lt, lam_y=ly, t_F=rng.uniform(14, 26),
                                   y_F=rng.uniform(5, 28), noise_m=noise_mm / 1e3,
                                   noise_rad=np.radians(0.3 * noise_mm / 2),
                                   seed=int(rng.integers(1 << 30)))
            t0 = time.perf_counter()
            v = fit_series(s).values
            times.append(time.perf_counter() - t0)
            errs_t.append(abs(v["lambda_theta"] - lt))
            errs_y.append(abs(v["lambda_y"] - ly))
        out["per_noise"].append({
            "noise_mm": noise_mm, "noise_deg": 0.3 * noise_mm / 2,
            "lambda_theta_err_rms": float(np.sqrt(np.mean(np.square(errs_t)))),
            "lambda_y_err_rms": float(np.sqrt(np.mean(np.square(errs_y)))),
            "lambda_err_max": float(max(max(errs_t), max(errs_y))),
            "ms_per_shot": 1e3 * float(np.median(times))})
    return out


def bench_render(quick: bool) -> dict:
    from curltrack.render.benchmark import render_benchmark

    return render_benchmark(n_frames=30 if quick else 90, threads=THREADS)


def bench_track(quick: bool) -> dict:
    import bench_track as bt

    setups = bt.SETUPS[:2] if quick else bt.SETUPS
    rows = []
    for s in setups:
        try:
            rows.append(bt.bench_setup(**s))
        except Exception as exc:  # one failed set-up is a result, not the end of the run
            rows.append({**s, "error": f"{type(exc).__name__}: {exc}"})
    out = {"setups": rows}
    if hasattr(bt, "bench_speed_1080p") and not quick:
        out["speed_1080p"] = bt.bench_speed_1080p()
    return out


def bench_discover(quick: bool) -> dict:
    import bench_discover as bd

    trials = 3 if quick else 10
    effects = ["pick", "friction_patch"] if quick else None
    table = bd.detection_table(effects=effects, trials=trials, log=lambda *a, **k: None)
    fa = bd.false_alarm_rate(n=6 if quick else 40, log=lambda *a, **k: None)
    return {"detection": table, "false_alarms": fa}


def bench_batch(quick: bool) -> dict:
    import bench_batch as bb

    return bb.throughput(n_videos=4 if quick else 8) if hasattr(bb, "throughput") else {}


def bench_memory(quick: bool) -> dict:
    import bench_memory as bm

    return bm.memory_vs_length(quick=quick) if hasattr(bm, "memory_vs_length") else {}


SECTIONS = {"simulate": bench_simulate, "fit": bench_fit, "render": bench_render,
            "track": bench_track, "discover": bench_discover, "batch": bench_batch,
            "memory": bench_memory}


def _fmt(v):
    if isinstance(v, float):
        return f"{v:.3g}"
    return "—" if v is None else str(v)


def table(doc: dict) -> str:
    """A human table of the headline figures."""
    lines = [f"curltrack benchmark — {doc['machine']['platform']}, "
             f"{doc['machine']['cpus']} cores, OpenCV {doc['machine']['opencv']}, "
             f"{doc['machine']['decoder_threads']}"]
    r = doc.get("render", {})
    if "render_fps" in r:
        lines.append(f"render   {r['render_fps']:.1f} frames/s wall ({r.get('render_fps_cpu', 0):.1f}"
                     f" per CPU-s) at {r['width']}x{r['height']}, blur {r.get('blur_subframes')}"
                     f" sub-frames; ÷ plain encoding = {r['ratio']:.3f}  (target ≥ 15 frames/s)")
    s = doc.get("simulate", {})
    if "draw_ms" in s:
        lines.append(f"simulate {s['draw_ms']:.1f} ms per 27 s draw (target < 50 ms)")
    f = doc.get("fit", {})
    for row in f.get("per_noise", []):
        lines.append(f"fit      noise {row['noise_mm']:.0f} mm/{row['noise_deg']:.2f}°: "
                     f"λθ err rms {row['lambda_theta_err_rms']:.4f}, λy err rms "
                     f"{row['lambda_y_err_rms']:.4f}, {row['ms_per_shot']:.0f} ms/shot")
    for row in doc.get("track", {}).get("setups", []):
        if "error" in row:
            lines.append(f"track    {row.get('motion')} … FAILED: {row['error']}")
            continue
        lines.append(
            f"track    {row['motion']:8s} H={row['height_m']} m tilt={row['tilt_deg']}° "
            f"k1={row['k1']} grid={row['spacing_m']} m occl={row['occlusion']}: pos RMS "
            f"{row['pos_rms_mm']:.2f} mm (max {row['pos_max_mm']:.2f}), θ RMS "
            f"{row['theta_rms_deg']:.3f}°, stop err {_fmt(row['stop_err_translation_frames'])}/"
            f"{_fmt(row['stop_err_rotation_frames'])} fr, parallax {row['parallax_err_pct']:+.2f} %,"
            f" speed {row['speed_ratio']:.2f}× decode")
    d = doc.get("discover", {})
    if d:
        lines.append(f"discover {json.dumps(d.get('false_alarms'), default=str)[:200]}")
        for eff, rows in (d.get("detection") or {}).items():
            lines.append(f"discover {eff}: {json.dumps(rows, default=str)[:200]}")
    for key in ("batch", "memory"):
        if doc.get(key):
            lines.append(f"{key:8s} {json.dumps(doc[key], default=str)[:300]}")
    for key, sec in doc.items():
        if isinstance(sec, dict) and "error" in sec and key != "machine":
            lines.append(f"{key:8s} FAILED: {sec['error']}")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small sample sizes (minutes)")
    ap.add_argument("--json", type=Path, help="also write the JSON document here")
    ap.add_argument("--only", default="", help="comma-separated sections: " + ",".join(SECTIONS))
    args = ap.parse_args(argv)
    import cv2

    cv2.setNumThreads(THREADS)
    os.environ.setdefault("MPLBACKEND", "Agg")
    wanted = [s for s in (args.only.split(",") if args.only else SECTIONS) if s]
    doc = {"machine": machine(), "quick": args.quick,
           "date": time.strftime("%Y-%m-%d %H:%M:%S")}
    for name in wanted:
        print(f"[bench] {name} …", file=sys.stderr, flush=True)
        t0 = time.perf_counter()
        try:
            doc[name] = SECTIONS[name](args.quick)
        except Exception as exc:
            doc[name] = {"error": f"{type(exc).__name__}: {exc}",
                         "traceback": traceback.format_exc(limit=3)}
        doc[name]["section_seconds"] = time.perf_counter() - t0
    print(table(doc), file=sys.stderr)
    text = json.dumps(doc, indent=2, default=str)
    print(text)
    if args.json:
        from curltrack._atomic import write_text

        write_text(args.json, text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
