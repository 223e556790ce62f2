#!/usr/bin/env python
"""curltrack benchmark: speed, accuracy and scale, measured against the targets in one run.

Renders its own inputs deterministically (seeds), then measures

* render: frames/s at 960x540 with motion blur on one core, and ÷ plain mp4v encoding;
* simulate: ms per typical draw (target < 50 ms);
* fit: ms per shot, and λ recovery error against noise level;
* track: per set-up position RMS/max (mm), θ RMS (deg), stop-frame errors, parallax
  factor error (%), camera height, and speed as track fps ÷ decode-only fps of the same
  video in the same run (960x540 and 1920x1080);
* cameras: per camera kind (camcorder, phone, action camera with a strong wide-angle
  lens or a fisheye, ladder, handheld; ``scripts/bench_cameras.py``) position / θ RMS,
  std of error/σ, frames measured, tracking speed ratio;
* discover: s per shot, detection rate against effect strength, false-alarm rate;
* batch: throughput with 1 and 2 Dask workers;
* memory: peak RSS of tracking against video length (must be flat), when available;
  peak RSS of discover on 1e5 rows and on a 60 s shot (under 2 GB).

Usage::

    python scripts/bench.py [--quick] [--json OUT.json] [--only track,fit]

Prints a human table on stderr and one JSON document on stdout (and to --json).
Threads: every timed section runs with one thread per process (as batch workers do):
CURLTRACK_THREADS=1 sets the FFmpeg decoder's threads (cv2.CAP_PROP_N_THREADS when a
video is opened) and cv2.setNumThreads(1) OpenCV's own; set CURLTRACK_BENCH_THREADS to
change both.  Speeds of the tracking ratio are CPU times of the process (fair on a
shared machine; the wall-clock ratio is reported beside it).

    python scripts/bench.py --readme README.md [--from A.json B.json]

writes the headline table (markdown) between ``<!-- BENCHMARKS -->`` and
``<!-- /BENCHMARKS -->`` in README.md, from this run or from earlier ``--json`` files
(sections of later files win).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import time
import traceback
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))

THREADS = int(os.environ.get("CURLTRACK_BENCH_THREADS", "1"))
os.environ["CURLTRACK_THREADS"] = str(THREADS)  # decoder and tracker threads, per process


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
            "cpus": os.cpu_count(), "cpu_model": _cpu_model(), "opencv": cv2.__version__,
            "numpy": np.__version__, "opencv_threads": THREADS,
            "load_avg": [round(v, 2) for v in os.getloadavg()],
            "decoder_threads": f"CURLTRACK_THREADS={THREADS} (FFmpeg decoder threads via "
                               f"cv2.CAP_PROP_N_THREADS) and cv2.setNumThreads({THREADS})"}


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


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
    # speed: track fps / decode-only fps of the same rendered video, in one run (the same
    # 5 s clips and repeats in --quick: a shorter clip weighs the one-off calibration more
    # and would measure something else than the target's row)
    for w, h in ((960, 540), (1920, 1080)):
        out[f"speed_{h}p"] = bt.bench_speed(w, h, n_frames=150, threads=THREADS, repeats=3)
    if not quick:  # a whole shot, as filmed: the one-off costs spread over ~700 frames
        out["speed_540p_draw"] = bt.bench_speed(960, 540, n_frames=None, full_draw=True,
                                                threads=THREADS, repeats=3)
    return out


def bench_cameras(quick: bool) -> dict:
    import bench_cameras as bc

    kinds = ("ladder", "action-strong") if quick else bc.KINDS
    return {"kinds": [bc.bench_kind(k) for k in kinds]}


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

    # (the 10-minute case: scripts/bench_memory.py --minutes 1 10)
    minutes, size = ((0.25, 1.0), (960, 540)) if quick else ((0.5, 2.0), (1920, 1080))
    out = bm.memory_vs_length(minutes, size, log=lambda *a, **k: None)
    out["discover"] = bm.discover_memory(log=lambda *a, **k: None)
    return out


SECTIONS = {"simulate": bench_simulate, "fit": bench_fit, "render": bench_render,
            "track": bench_track, "cameras": bench_cameras, "discover": bench_discover,
            "batch": bench_batch, "memory": bench_memory}


def _fmt(v):
    if isinstance(v, float):
        return f"{v:.3g}"
    return "—" if v is None else str(v)


def _ok(flag) -> str:
    return "✓" if flag else "✗"


def markdown(doc: dict) -> str:
    """The headline figures as a markdown table (for the README), with the machine."""
    m = doc["machine"]
    out = [f"Measured by `python scripts/bench.py{' --quick' if doc.get('quick') else ''}` on "
           f"{doc.get('date', '?')}: {m.get('cpu_model', '?')}, {m['cpus']} cores, "
           f"{m['platform']}, Python {m['python']}, OpenCV {m['opencv']}; load average "
           f"{m.get('load_avg', ['?'])[0]} at the start. Threads: {m['decoder_threads']}.",
           "", "| stage | measure | result | target | |", "|---|---|---|---|---|"]

    def row(stage, what, result, target="", ok=None):
        out.append(f"| {stage} | {what} | {result} | {target} | "
                   f"{'' if ok is None else _ok(ok)} |")

    s = doc.get("simulate", {})
    if "draw_ms" in s:
        row("simulate", "27 s draw, paper model", f"{s['draw_ms']:.1f} ms", "< 50 ms",
            s["draw_ms"] < 50)
    for r in doc.get("fit", {}).get("per_noise", []):
        row("fit", f"λ error rms at {r['noise_mm']:.0f} mm / {r['noise_deg']:.2f}°",
            f"λθ {r['lambda_theta_err_rms']:.4f}, λy {r['lambda_y_err_rms']:.4f}; "
            f"{r['ms_per_shot']:.0f} ms/shot")
    r = doc.get("render", {})
    if "render_fps" in r:
        row("render", f"{r['width']}x{r['height']}, {r.get('blur_subframes')} blur sub-frames",
            f"{r.get('render_fps_cpu', float('nan')):.1f} frames per CPU-s "
            f"({r['render_fps']:.1f}/s wall); {r['ratio']:.3f}× plain encoding")
    t = doc.get("track", {})
    for r in t.get("setups", []):
        what = (f"{r.get('motion')} H={r.get('height_m')} m tilt={r.get('tilt_deg')}° "
                f"k1={r.get('k1')} grid {r.get('spacing_m')} m"
                + (" broom" if r.get("occlusion") else ""))
        if "error" in r:
            row("track", what, f"FAILED: {r['error']}", "", False)
            continue
        stops = (r["stop_err_translation_frames"], r["stop_err_rotation_frames"])
        ok = (r["pos_rms_mm"] <= 2.0 and r["theta_rms_deg"] <= 0.3
              and all(e is not None and abs(e) <= 2 for e in stops)
              and abs(r["parallax_err_pct"]) <= 1.0)
        row("track", what,
            f"pos {r['pos_rms_mm']:.2f} mm rms ({r['pos_max_mm']:.2f} max), θ "
            f"{r['theta_rms_deg']:.3f}°, stops {_fmt(stops[0])}/{_fmt(stops[1])} frames, "
            f"parallax {r['parallax_err_pct']:+.2f} %, height {r['camera_height_m']:.3f} m "
            f"(true {r['camera_height_true_m']:.3f})",
            "≤ 2 mm, ≤ 0.3°, ±2 frames, 1 %", ok)
    for key in ("speed_540p", "speed_1080p", "speed_540p_draw"):
        r = t.get(key)
        if r:
            clip = (f"whole {r['seconds']:.1f} s draw ({r['frames']} frames)"
                    if r.get("full_draw") else f"{r['frames']} frames")
            row("track speed", f"{r['width']}x{r['height']}, {clip}, {r['threads']} thread",
                f"{r['ratio']:.3f}× decode ({r['track_fps']:.0f} vs {r['decode_fps']:.0f} "
                f"frames/s; {r['ratio_excl_calibration']:.3f}× without the one-off "
                f"{r['calibrate_s']:.2f} s calibration); ms/frame: decode "
                f"{r['decode_ms']:.1f}, grid {r['grid_ms']:.1f}, markers "
                f"{r['markers_ms']:.1f}, other {r['other_ms']:.1f}", "≥ 0.25×",
                r["ratio"] >= 0.25)
    if doc.get("cameras", {}).get("kinds"):
        import bench_cameras as bc

        out.extend(bc.markdown_rows(doc["cameras"]["kinds"]))
    d = doc.get("discover", {})
    fa = d.get("false_alarms")
    if fa:
        row("discover", f"false alarms on {fa['n']} clean shots",
            f"{fa['false_alarms']} ({100 * fa['rate']:.1f} %); "
            f"{fa['cpu_seconds_mean']:.1f} s/shot mean, {fa['cpu_seconds_max']:.1f} max",
            "≤ 5 %; < 30 s", fa["rate"] <= 0.05 and fa["cpu_seconds_max"] < 30)
    for eff, dt in (d.get("detection") or {}).items():
        s90 = dt.get("strength_90")
        rates = ", ".join(f"{x['strength']:g}: {x['rate']:.1f}" for x in dt["rows"])
        row("discover", f"{eff}: detection rate by strength",
            f"{rates}; 90 % at {'> grid' if s90 is None else f'{s90:.3g}'}")
    b = doc.get("batch", {})
    if "speedup" in b:
        med = b["median_shots_per_min"]
        row("batch", f"{b['n_videos']} short videos, 1 vs 2 Dask workers",
            f"{_fmt(med.get(1, med.get('1')))} vs {_fmt(med.get(2, med.get('2')))} "
            f"shots/min: {b['speedup']:.2f}× (load average "
            f"{b['load_avg_before'][0]})", "≥ 1.7×", b["speedup"] >= 1.7)
    mm = doc.get("memory", {})
    if mm.get("runs"):
        runs = ", ".join(f"{r['minutes']:g} min: {r['peak_rss_mb']:.0f} MB" for r in mm["runs"])
        row("memory", f"peak RSS of track at {mm['size'][0]}x{mm['size'][1]}",
            f"{runs}; {mm['growth_mb_per_min']:+.1f} MB per extra minute",
            f"flat (≤ {mm.get('limit_mb_per_min', 8):g} MB/min)", mm["ok"])
    for r in mm.get("discover", {}).get("runs", []):
        row("memory", f"peak RSS of discover, {r['case']}",
            f"{r['peak_rss_mb']:.0f} MB ({r['rows']} rows, {r['duration_s']:.0f} s; "
            f"{r['wall_s']:.0f} s wall)", f"≤ {mm['discover']['limit_mb']:g} MB",
            r["peak_rss_mb"] <= mm["discover"]["limit_mb"])
    return "\n".join(out)


def write_readme(readme: Path, text: str, marker: str = "BENCHMARKS") -> None:
    """Replace the block between the ``marker`` comments of ``readme`` with ``text``."""
    from curltrack._atomic import write_text

    src = readme.read_text(encoding="utf-8")
    begin, end = f"<!-- {marker} -->", f"<!-- /{marker} -->"
    if begin not in src:
        raise SystemExit(f"{readme}: no '{begin}' marker")
    head, rest = src.split(begin, 1)
    tail = rest.split(end, 1)[1] if end in rest else rest
    write_text(readme, f"{head}{begin}\n{text}\n{end}{tail}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small sample sizes (minutes)")
    ap.add_argument("--json", type=Path, help="also write the JSON document here")
    ap.add_argument("--only", default="", help="comma-separated sections: " + ",".join(SECTIONS))
    ap.add_argument("--readme", type=Path,
                    help="write the markdown table into this README between the "
                         "<!-- BENCHMARKS --> markers")
    ap.add_argument("--from", dest="from_json", type=Path, nargs="+",
                    help="no measuring: merge these earlier --json documents (for --readme)")
    args = ap.parse_args(argv)
    if args.from_json:
        doc = {}
        for path in args.from_json:
            doc.update(json.loads(path.read_text()))
        text = markdown(doc)
        print(text)
        if args.readme:
            write_readme(args.readme, text)
        return 0
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
    print(markdown(json.loads(json.dumps(doc, default=str))), file=sys.stderr)
    text = json.dumps(doc, indent=2, default=str)
    print(text)
    if args.json:
        from curltrack._atomic import write_text

        write_text(args.json, text + "\n")
    if args.readme:
        write_readme(args.readme, markdown(json.loads(text)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
