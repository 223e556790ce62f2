#!/usr/bin/env python
"""Rendering speed on one core (target >= 15 frames/s at 960x540 with motion blur).

    python scripts/bench_render.py [-n 60] [--threads 1]

Times ``curltrack.render.render_benchmark``: the fast start of the paper's draw (ladder
camera and rock both at ~2 m/s), 5 blur sub-frames, noise, JPEG pass and mp4v encoding,
against plain mp4v encoding of as many ready frames in the same run.  Wall-clock figures
depend on what else the machine runs; the CPU-time figures give one free core.
"""

from __future__ import annotations

import argparse

from curltrack.render import RenderConfig, render_benchmark


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-n", type=int, default=60, help="frames to time")
    ap.add_argument("--threads", type=int, default=1, help="OpenCV threads")
    args = ap.parse_args()
    for label, cfg in (("blur 5 sub-frames", RenderConfig()),
                       ("no blur", RenderConfig(blur_subframes=1))):
        r = render_benchmark(args.n, cfg, threads=args.threads)
        print(f"{label:18s} render {r['render_fps']:6.1f} fps wall, {r['render_fps_cpu']:6.1f} "
              f"fps CPU | plain encoding {r['encode_fps']:6.1f} fps wall, "
              f"{r['encode_fps_cpu']:6.1f} fps CPU | ratio {r['ratio']:.3f} "
              f"(CPU {r['render_fps_cpu'] / r['encode_fps_cpu']:.3f}) | setup {r['setup_s']:.1f} s")


if __name__ == "__main__":
    main()
