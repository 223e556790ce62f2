"""The camera sweep: random set-ups of real cameras' artefacts, rendered, tracked, scored.

    python scripts/sweep_cameras.py [--n 10] [--seed S] [--scale 0.5] [--out DIR]
                                    [--table FILE.md] [--no-track] [--random-kind]
                                    [--physics closed|model] [--discover]

Each set-up is drawn by :func:`curltrack.render.sweep.draw_setup` (kinds in turn:
camcorder, phone, action, ladder, handheld; every other choice at random from the seed),
rendered with its truth and rig beside it in DIR, then tracked with
:func:`curltrack.track.track_video` and scored against the truth:

- ``pos_rms_mm`` / ``theta_rms_deg``: RMS error of the rows with ``ok`` = 1;
- ``measured``: fraction of rows with ``ok`` = 1;
- ``max_mm``: the largest position error of an ``ok`` row;
- ``z_xy`` / ``z_theta``: standard deviation of error / reported sigma (x and y errors
  over ``sigma_xy``; theta over ``sigma_theta``) - 1 when the sigmas are honest and no
  error is shared by every row;
- ``rms_z_xy``: the RMS of the same (the shot's shared error counted: the origin's error
  is one draw per shot, and ``sigma_xy`` covers it); ``shared_mm``: that shared error,
  the length of the mean (x, y) error of the ``ok`` rows.  The table ends with the
  pooled RMS of error / sigma over the progressive and over the interlaced set-ups;
- ``stop_err``: tracked minus true translation stop frame;
- ``z_height``: the camera height's error over its reported sigma, when it was
  measured from the marker layout (within +-2 when honest);
- ``wrong``: ``ok`` rows off by both more than 10 mm and more than 5 sigma (the
  issue's wrong row: 0 is the aim);
- ``verdict`` (``--discover``): what ``discover`` says of the tracked series alone.
  With ``--physics model`` the shot is the physics core's own (no effect hidden), so
  anything but ``none`` is a false alarm of the whole chain, camera to verdict.

Interlaced video: a tracked series with a ``field`` column is compared field by field;
one without (one row per frame) against the truth of each frame's first field (the
frame's timestamp).  A failed track is reported with its one-line error.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from curltrack.render.sweep import KINDS, draw_model_shot, draw_setup  # noqa: E402


def score(series, truth) -> dict:
    """Errors of a tracked series against the renderer's truth (see the module doc)."""
    s, t = series.data, truth.data
    if "field" in t.columns and "field" not in s.columns:
        t = t[t["field"] == 0]
    keys = ["frame", "field"] if "field" in s.columns else ["frame"]
    m = s.merge(t[keys + ["x", "y", "theta"]], on=keys, suffixes=("", "_t"))
    ok = (m["ok"] == 1) & np.isfinite(m[["x", "y"]]).all(axis=1)
    dx, dy = (m.x - m.x_t)[ok], (m.y - m.y_t)[ok]
    e = np.hypot(dx, dy)
    dth = (m.theta - m.theta_t)[ok]
    out = dict(rows=len(m), measured=float(ok.mean()) if len(m) else 0.0)
    if ok.any():
        out.update(pos_rms_mm=1e3 * float(np.sqrt(np.mean(e ** 2))),
                   theta_rms_deg=float(np.degrees(np.sqrt(np.nanmean(dth ** 2)))),
                   max_mm=1e3 * float(e.max()))
        if "sigma_xy" in m.columns:
            sig = m["sigma_xy"][ok]
            z = np.r_[dx / sig, dy / sig]
            out["z_xy"] = float(np.nanstd(z))
            # (the std leaves out the error every row shares - the origin's, one draw per
            # shot - which sigma_xy covers too: the RMS is the honest measure of sigma,
            # the shared offset says how much of the difference it is)
            out["rms_z_xy"] = float(np.sqrt(np.nanmean(z * z)))
            out["shared_mm"] = 1e3 * float(np.hypot(dx.mean(), dy.mean()))
            # the "wrong row": an ok row both > 10 mm and > 5 sigma off
            out["wrong"] = int(((e > 0.010) & (e > 5 * sig)).sum())
        if "sigma_theta" in m.columns:
            out["z_theta"] = float(np.nanstd(dth / m["sigma_theta"][ok]))
    a, b = series.meta.get("stop_frame_translation"), truth.meta.get("stop_frame_translation")
    if a is not None and b is not None:
        out["stop_err"] = int(a) - int(b)
    H, H_err = series.meta.get("camera_height_m"), series.meta.get("camera_height_err_m")
    if (series.meta.get("camera_height_source") == "markers" and H is not None and H_err
            and "camera_height_m" in t.columns):
        # (the lens above the ice, as the truth gives it: the sweep's rigs have no depth)
        out["z_height"] = (float(H) - float(np.median(t["camera_height_m"]))) / float(H_err)
    return out


def run(i: int, seed: int, n: int, scale: float, out: Path, track: bool,
        random_kind: bool, physics: str = "closed", with_discover: bool = False) -> dict:
    from curltrack.errors import CurltrackError
    from curltrack.render import render_video
    from curltrack.rig import default_rig, load_rig

    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(n)[i])
    kind = None if random_kind else KINDS[i % len(KINDS)]
    setup = draw_setup(rng, kind, scale)
    if physics == "model":  # (the same camera set-up; the shot from the physics core)
        from dataclasses import replace

        setup = replace(setup, shot=draw_model_shot(np.random.default_rng(setup.seed)))
    video = out / f"setup{i:02d}_{setup.kind}{setup.suffix}"
    t0 = time.process_time()
    row = dict(i=i, **setup.summary)
    try:
        truth = render_video(setup.shot, default_rig(), video,
                             video.with_suffix(".truth.csv"), setup.config, seed=setup.seed)
    except CurltrackError as exc:
        # a set-up the renderer cannot draw (a lens that folds over where a moving
        # camera looks) is a row of the table, not the end of the sweep
        row.update(error="render: " + str(exc).splitlines()[0][:150])
        return row
    row.update(frames=truth.meta["n_frames"], render_cpu_s=round(time.process_time() - t0, 1))
    if not track:
        return row
    from curltrack.track import track_video

    t0 = time.process_time()
    try:
        series = track_video(video, load_rig(video.with_suffix(".rig.toml")))
    except CurltrackError as exc:
        row.update(error=str(exc).splitlines()[0][:160])
        return row
    finally:
        row["track_cpu_s"] = round(time.process_time() - t0, 1)
    row.update(score(series, truth))
    row["warnings"] = len(series.meta.get("warnings", []))
    if with_discover:
        from curltrack.discover import discover

        try:
            rep = discover(series, seed=0)
            row["verdict"] = rep["verdict"]
            if rep["verdict"] != "none" and rep["findings"]:
                f = rep["findings"][0]
                row["verdict"] += f" ({f['effect']} ΔBIC {f['delta_bic']:.0f})"
        except CurltrackError as exc:
            row["verdict"] = "error: " + str(exc).splitlines()[0][:100]
    return row


COLS = [("i", "#", "{}"), ("kind", "kind", "{}"), ("size", "size", "{}"),
        ("fps", "fps", "{}"), ("motion", "motion", "{}"), ("lens", "lens", "{}"),
        ("scan", "scan", "{}"), ("readout_ms", "RS ms", "{}"), ("vfr", "VFR", "{}"),
        ("codec", "codec", "{}"), ("artefacts", "artefacts", "{}"),
        ("measured", "measured", "{:.0%}"), ("pos_rms_mm", "pos RMS mm", "{:.2f}"),
        ("theta_rms_deg", "θ RMS °", "{:.3f}"), ("max_mm", "max ok err mm", "{:.1f}"),
        ("wrong", "wrong rows", "{}"), ("z_xy", "std e/σ xy", "{:.2f}"),
        ("rms_z_xy", "RMS e/σ xy", "{:.2f}"), ("shared_mm", "shared mm", "{:.2f}"),
        ("z_theta", "std e/σ θ", "{:.2f}"),
        ("z_height", "height e/σ", "{:+.1f}"), ("stop_err", "stop Δframe", "{:+d}"),
        ("verdict", "discover", "{}"), ("error", "error", "{}")]


def pooled_rms_z(rows) -> dict:
    """Pooled RMS of error / sigma_xy (the RMS of the set-ups' RMS) over the progressive
    and over the interlaced set-ups that were tracked: ``{scan: (value, n)}``."""
    out = {}
    for scan in ("progressive", "interlaced"):
        v = [r["rms_z_xy"] for r in rows if r.get("scan") == scan and r.get("rms_z_xy") is not None]
        if v:
            out[scan] = (float(np.sqrt(np.mean(np.square(v)))), len(v))
    return out


def table(rows) -> str:
    """The markdown table of the rows, and the pooled RMS of error / sigma under it."""
    lines = ["| " + " | ".join(h for _, h, _ in COLS) + " |",
             "|" + "---|" * len(COLS)]
    for r in rows:
        cells = []
        for key, _, fmt in COLS:
            v = r.get(key)
            cells.append("" if v is None else fmt.format(v))
        lines.append("| " + " | ".join(cells) + " |")
    pooled = pooled_rms_z(rows)
    if pooled:
        lines.append("")
        lines.append("Pooled RMS e/σ xy: " + "; ".join(
            f"{scan} {v:.2f} ({n} set-ups)" for scan, (v, n) in pooled.items()))
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=10)
    ap.add_argument("--seed", type=int, default=None, help="default: a fresh one (printed)")
    ap.add_argument("--scale", type=float, default=1.0)
    ap.add_argument("--out", type=Path, default=Path("sweep_cameras"))
    ap.add_argument("--table", type=Path, default=None, help="write the markdown table here")
    ap.add_argument("--no-track", action="store_true")
    ap.add_argument("--random-kind", action="store_true", help="kinds at random, not in turn")
    ap.add_argument("--physics", choices=("closed", "model"), default="closed",
                    help="the shot: the paper's closed forms with independent stops (the "
                    "tracker's test), or the physics core's model (a clean shot for "
                    "discover)")
    ap.add_argument("--discover", action="store_true",
                    help="also run discover on each tracked series (a 'verdict' column: "
                    "anything but none on a --physics model sweep is a false alarm)")
    ap.add_argument("--only", type=str, default=None,
                    help="comma-separated set-up indices to run (the same set-ups as in the "
                    "full sweep: several processes can share one)")
    a = ap.parse_args(argv)
    seed = a.seed if a.seed is not None else int(np.random.SeedSequence().entropy % 2**32)
    a.out.mkdir(parents=True, exist_ok=True)
    print(f"sweep seed {seed}, {a.n} set-ups, scale {a.scale}", file=sys.stderr)
    rows = []
    todo = range(a.n) if a.only is None else [int(v) for v in a.only.split(",")]
    for i in todo:
        rows.append(run(i, seed, a.n, a.scale, a.out, not a.no_track, a.random_kind,
                        a.physics, a.discover))
        print(rows[-1], file=sys.stderr, flush=True)
        text = (f"Camera sweep: seed {seed}, scale {a.scale}, "
                f"`python scripts/sweep_cameras.py --n {a.n} --seed {seed} "
                f"--scale {a.scale}" + (f" --only {a.only}" if a.only else "")
                + (" --physics model" if a.physics == "model" else "")
                + (" --discover" if a.discover else "") + "`\n\n"
                + table(rows) + "\n")
        if a.table:
            a.table.write_text(text)
    print(table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
