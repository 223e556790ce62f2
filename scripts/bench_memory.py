#!/usr/bin/env python
"""Long runs in bounded memory: peak RSS of `curltrack track` at several video lengths.

A short 1080p shot is rendered once; longer videos are made from it by holding the rock
at rest (its last frame repeated, as when a camera is left running after the stop), so
the frames are cheap to make but every one is decoded and tracked.  Each length is
tracked by the real command in a child process; its peak resident memory comes from the
kernel's accounting of that child (``wait4``).  Memory must not grow with the length:
the frames are streamed, and only a small record per frame is kept.

Usage::

    scripts/bench_memory.py                       # 0.5 and 2 minutes at 1920x1080
    scripts/bench_memory.py --minutes 1 10        # the 10-minute case (slow: ~real time)
    scripts/bench_memory.py --size 960x540 --minutes 0.25 1 --json bench_memory.json
    scripts/bench_memory.py --discover            # discover on 1e5 rows and a 60 s shot

Prints one line per length (frames, wall s, tracked fps, peak RSS MB, and the RSS at 30 %
and 90 % of the run) and the growth of the peak RSS per extra minute of video; exit
status 1 when it grows by more than ``--max-growth-mb-per-min`` (default 8 MB/min).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def render_base(out_dir: Path, size, fps: float, seed: int = 0):
    """A short draw (about 3 s) rendered at ``size``; returns (video, rig path)."""
    from curltrack.physics.shot import ShotModel
    from curltrack.render import RenderConfig, render_video
    from curltrack.rig import default_rig
    from curltrack.simulate import simulate_series

    rig = default_rig()
    sim = simulate_series(ShotModel(v0=0.9, omega0=1.5, alpha_y=0.03), fps=fps, tail_s=0.2)
    video = out_dir / "base.mp4"
    render_video(sim, rig, video, out_dir / "base.truth.csv",
                 config=RenderConfig(width=size[0], height=size[1], fps=fps,
                                     stopped_tail_s=0.2, blur_subframes=2), seed=seed)
    rig_path = out_dir / "rig.toml"
    rig_path.write_text(rig.to_toml())
    return video, rig_path


def make_long(base: Path, out: Path, n_frames: int, fps: float) -> Path:
    """``base`` followed by its last frame held until ``n_frames`` frames (streamed)."""
    import cv2

    cap = cv2.VideoCapture(str(base))
    writer, last, k = None, None, 0
    while k < n_frames:
        ok, img = cap.read()
        if not ok:
            break
        if writer is None:
            h, w = img.shape[:2]
            writer = cv2.VideoWriter(str(out), cv2.VideoWriter_fourcc(*"mp4v"), fps, (w, h))
        writer.write(img)
        last, k = img, k + 1
    cap.release()
    while k < n_frames:
        writer.write(last)
        k += 1
    writer.release()
    return out


#: The child: `curltrack` as `python -m curltrack`, reporting at exit the peak of its own
#: memory (VmHWM, Linux).  The kernel's ru_maxrss of a child is no use here: a child
#: started from a large parent (this benchmark, after other sections) is charged the
#: parent's size, shared until exec (seen: 674 MB reported, ~215 MB sampled).
_CHILD = """\
import atexit, runpy, sys
def _peak():
    try:
        for line in open('/proc/self/status'):
            if line.startswith('VmHWM:'):
                sys.stderr.write('CURLTRACK_VMHWM_KB ' + line.split()[1] + '\\n')
    except OSError:
        pass
atexit.register(_peak)
sys.argv = ['curltrack'] + sys.argv[1:]
runpy.run_module('curltrack', run_name='__main__')
"""


def track_peak_rss(video: Path, rig: Path, out_csv: Path, every_s: float = 0.5) -> dict:
    """Run `curltrack track` in a child; its wall time, peak RSS and RSS over the run (MB)
    (see :func:`command_peak_rss`)."""
    return command_peak_rss(["track", str(video), "--rig", str(rig), "-o", str(out_csv),
                             "--no-progress", "-q"], every_s)


def command_peak_rss(args, every_s: float = 0.5) -> dict:
    """Run ``curltrack ARGS`` in a child; its wall time, peak RSS and RSS over the run (MB).

    ``peak_rss_mb`` is the child's own high-water mark (VmHWM; where the system has
    none, the largest sampled RSS).  The RSS is also sampled every ``every_s``;
    ``rss_early_mb`` / ``rss_late_mb`` are its medians over 25-35 % and 85-95 % of the
    run, so growth during the run is seen even when it stays under the peak.
    """
    import threading

    import numpy as np
    import psutil

    cmd = [sys.executable, "-c", _CHILD, *map(str, args)]
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    samples = []
    done = threading.Event()

    def sample():
        p = psutil.Process(proc.pid)
        while not done.wait(every_s):
            try:
                samples.append((time.perf_counter() - t0, p.memory_info().rss / 2**20))
            except psutil.Error:
                return

    th = threading.Thread(target=sample, daemon=True)
    th.start()
    _, status, usage = os.wait4(proc.pid, 0)
    done.set()
    th.join()
    wall = time.perf_counter() - t0
    err = proc.stderr.read().decode(errors="replace").strip()
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise SystemExit(f"curltrack {' '.join(map(str, args))} failed: {err}")
    ts = np.array([t for t, _ in samples])
    rss = np.array([r for _, r in samples])
    hwm = [int(line.split()[1]) for line in err.splitlines()
           if line.startswith("CURLTRACK_VMHWM_KB ")]
    peak = hwm[-1] / 1024.0 if hwm else float(rss.max()) if rss.size else float("nan")

    def median_in(a, b):
        sel = (ts >= a * wall) & (ts <= b * wall)
        return float(np.median(rss[sel])) if sel.any() else None

    return {"wall_s": wall, "peak_rss_mb": peak,
            "cpu_s": usage.ru_utime + usage.ru_stime,
            "rss_early_mb": median_in(0.25, 0.35), "rss_late_mb": median_in(0.85, 0.95)}


def memory_vs_length(minutes=(0.5, 2.0), size=(1920, 1080), fps: float = 30.0,
                     workdir: Path | None = None, max_growth_mb_per_min: float = 8.0,
                     log=print) -> dict:
    """Peak RSS of ``curltrack track`` for each video length in ``minutes``.

    Returns
    -------
    dict
        ``runs`` (per length: ``minutes``, ``frames``, ``rows``, ``wall_s``,
        ``fps_tracked``, ``peak_rss_mb``, ``rss_early_mb``, ``rss_late_mb``),
        ``growth_mb_per_min`` (peak RSS, longest vs shortest) and ``ok`` (flat within
        ``max_growth_mb_per_min`` and every frame kept as a row).
    """
    import pandas as pd

    if len(minutes) < 2:
        raise ValueError("give at least two lengths")
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(workdir) if workdir else Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        t0 = time.perf_counter()
        base, rig = render_base(work, size, fps)
        log(f"rendered the base shot at {size[0]}x{size[1]} in "
            f"{time.perf_counter() - t0:.1f} s", flush=True)
        rows = []
        for m in sorted(minutes):
            n = int(round(m * 60 * fps))
            video = make_long(base, work / f"long_{n}.mp4", n, fps)
            r = track_peak_rss(video, rig, work / f"long_{n}.csv")
            n_rows = len(pd.read_csv(work / f"long_{n}.csv"))
            r.update(minutes=m, frames=n, rows=n_rows, fps_tracked=n / r["wall_s"])
            rows.append(r)
            early, late = r["rss_early_mb"], r["rss_late_mb"]
            drift = (f"  RSS {early:.0f} MB at 30 % -> {late:.0f} MB at 90 % of the run"
                     if early is not None and late is not None else "")
            log(f"{m:6.2f} min  {n:6d} frames  {r['wall_s']:7.1f} s wall  "
                f"{r['fps_tracked']:6.1f} frames/s  peak RSS {r['peak_rss_mb']:7.1f} MB"
                + drift, flush=True)
            video.unlink()
    a, b = rows[0], rows[-1]
    growth = (b["peak_rss_mb"] - a["peak_rss_mb"]) / max(b["minutes"] - a["minutes"], 1e-9)
    ok = growth <= max_growth_mb_per_min and all(r["rows"] == r["frames"] for r in rows)
    log(f"peak RSS growth: {growth:+.1f} MB per extra minute of video "
        f"({'flat' if ok else 'GROWS'}; limit {max_growth_mb_per_min:g} MB/min)")
    return {"size": list(size), "fps": fps, "runs": rows, "growth_mb_per_min": growth,
            "limit_mb_per_min": max_growth_mb_per_min, "ok": ok}


#: Stated bound of discover's peak memory (MB), whatever the input (see
#: curltrack.sanity.DISCOVER_MAX_ROWS).
DISCOVER_LIMIT_MB = 2048.0


def discover_memory(workdir: Path | None = None, log=print) -> dict:
    """Peak RSS of ``curltrack discover`` on 1e5 rows (a 20 s draw at 5 kHz) and on a
    60 s shot (30 fps, the rock at rest after its stop), each in a child process."""
    from curltrack.physics.shot import ShotModel
    from curltrack.series import write_series
    from curltrack.simulate import simulate_series

    cases = {"1e5 rows": dict(fps=5000.0, tail_s=0.0), "60 s shot": dict(fps=30.0)}
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(workdir) if workdir else Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        for name, kw in cases.items():
            model = ShotModel(v0=1.6, omega0=1.5)
            if name == "60 s shot":
                sim0 = simulate_series(model, fps=kw["fps"], tail_s=0.0)
                kw["tail_s"] = 60.0 - float(sim0.data["t"].iloc[-1])
            sim = simulate_series(model, noise_m=0.001, noise_rad=0.003, seed=1, **kw)
            shot = work / f"{name.replace(' ', '_')}.csv"
            write_series(shot, sim)
            r = command_peak_rss(["discover", shot, "-o", shot.with_suffix(".report.json")])
            r.update(case=name, rows=len(sim.data),
                     duration_s=float(sim.data["t"].iloc[-1]))
            rows.append(r)
            log(f"discover {name:10s} {r['rows']:7d} rows  {r['duration_s']:5.1f} s  "
                f"{r['wall_s']:6.1f} s wall  peak RSS {r['peak_rss_mb']:7.1f} MB", flush=True)
    ok = all(r["peak_rss_mb"] <= DISCOVER_LIMIT_MB for r in rows)
    return {"runs": rows, "limit_mb": DISCOVER_LIMIT_MB, "ok": ok}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--minutes", type=float, nargs="+", default=[0.5, 2.0],
                    help="Video lengths to track (min), at least two.")
    ap.add_argument("--size", default="1920x1080", help="Frame size WxH (px).")
    ap.add_argument("--fps", type=float, default=30.0)
    ap.add_argument("--workdir", type=Path, default=None,
                    help="Keep the videos here (default: a temporary folder).")
    ap.add_argument("--json", type=Path, default=None, help="Write the results as JSON.")
    ap.add_argument("--max-growth-mb-per-min", type=float, default=8.0)
    ap.add_argument("--discover", action="store_true",
                    help="Measure discover's peak memory (1e5 rows; a 60 s shot) instead.")
    args = ap.parse_args(argv)
    if args.discover:
        res = discover_memory(args.workdir)
        if args.json:
            args.json.write_text(json.dumps(res, indent=2))
        return 0 if res["ok"] else 1
    if len(args.minutes) < 2:
        ap.error("give at least two lengths")
    size = tuple(int(v) for v in args.size.lower().split("x"))
    res = memory_vs_length(args.minutes, size, args.fps, args.workdir,
                           args.max_growth_mb_per_min)
    if args.json:
        args.json.write_text(json.dumps(res, indent=2))
    return 0 if res["ok"] else 1


if __name__ == "__main__":
    sys.exit(main())
