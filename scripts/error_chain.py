"""Where a tracked render's position error comes from, stage by stage.

``track`` measures the rock through a chain: marker centroids (px) -> the frame's
homography (px -> lattice m) -> the apparent centre on the ice -> the camera's nadir
and parallax factor -> the rock's centre -> the shot frame (origin, axes) -> SHOT.csv.
On a rendered video every link has a truth (the renderer's truth table holds the
markers' and the rock top's pixels and the camera's position), so each stage's error
can be read apart::

    python scripts/error_chain.py VIDEO --rig RIG.toml [--truth VIDEO.truth.csv]
    python scripts/error_chain.py --scale-seed 102 --out /tmp/ec   # the random set-up
                                      # tests/hardening/test_scale.py draws for a seed

Per stage: the RMS error per lattice axis (mm) and its trend (mm per metre of the
rock's travel: a scale-like error that grows along the path, which a smooth path
through the rows cannot see and the rows' sigma_xy does not hold).  Lattice and
truth frames are matched once, by the rigid transform that best maps the homography's
reading of the true rock-top pixel onto its true apparent place on the ice.

A developer's tool: it reads the tracker's per-frame records, not only its output.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]


def _rigid(a: np.ndarray, b: np.ndarray):
    """Rotation R and offset t that best map points ``a`` (n, 2) onto ``b``.
    (Not :func:`curltrack.track.parallax.similarity_fit`: its scale would absorb the
    travel-long error this script measures.)"""
    am, bm = a.mean(0), b.mean(0)
    u, _, vt = np.linalg.svd((a - am).T @ (b - bm))
    r = (u @ vt).T
    if np.linalg.det(r) < 0:  # (a mirrored lattice frame)
        r = (u @ np.diag([1.0, -1.0]) @ vt).T
    return r, bm - r @ am


def _stage(name: str, err_m: np.ndarray, travel_m: np.ndarray) -> dict:
    """RMS (mm, per axis) and trend (mm per m of travel, per axis) of errors (n, 2)."""
    good = np.isfinite(err_m).all(axis=1)
    e = err_m[good] * 1e3
    a = np.column_stack([np.ones(good.sum()), travel_m[good]])
    slope = np.linalg.lstsq(a, e, rcond=None)[0][1] if good.sum() > 2 else [np.nan] * 2
    return dict(stage=name, rows=int(good.sum()), rms_x_mm=np.sqrt(np.mean(e[:, 0] ** 2)),
                rms_y_mm=np.sqrt(np.mean(e[:, 1] ** 2)), trend_x_mm_per_m=slope[0],
                trend_y_mm_per_m=slope[1])


def error_chain(video: Path, rig, truth: pd.DataFrame) -> tuple[pd.DataFrame, dict]:
    """(per-stage table, notes) for ``video`` tracked with ``rig`` against ``truth``."""
    import curltrack.track.pipeline as pipeline
    from curltrack.calib.lens import apply_h, undistort
    from curltrack.track.parallax import ICE_REFRACTIVE_INDEX, correct_parallax
    from curltrack.track.results import _nadir_and_k, misfit_gain

    captured = {}
    original = pipeline.track_frames

    def spy(*args, **kwargs):
        captured["loop"] = original(*args, **kwargs)
        return captured["loop"]

    pipeline.track_frames = spy
    try:
        shot = pipeline.track_video(video, rig)
    finally:
        pipeline.track_frames = original
    records, info = captured["loop"]  # (the last pass: a rolling shutter's second)
    calib = info["calib"]
    recs = [r for r in records if r.H is not None and r.centre_app is not None
            and r.frame < len(truth)]
    fr = np.array([r.frame for r in recs])
    tr = truth.set_index("frame").loc[fr]
    depth = rig.grid_depth_m / ICE_REFRACTIVE_INDEX
    h_eff = rig.rock_height_m + depth
    cam = tr[["camera_x_m", "camera_y_m"]].to_numpy()
    cam_h = tr["camera_height_m"].to_numpy() + depth  # lens above the threads' plane
    rock = tr[["x", "y"]].to_numpy()
    # where the rock's top (the markers' plane) is seen on the threads' plane
    apparent = cam + (rock - cam) * (cam_h / (cam_h - h_eff))[:, None]
    travel = np.hypot(*(rock - rock[0]).T)

    top_px = undistort(tr[["u_top_px", "v_top_px"]].to_numpy(), calib.K, calib.dist)
    through_h = np.array([apply_h(r.H, p[None])[0] for r, p in zip(recs, top_px)])
    rot, off = _rigid(through_h, apparent)

    def to_truth(p):
        return p @ rot.T + off

    stages = [_stage("homography at the rock (true rock-top px)",
                     to_truth(through_h) - apparent, travel)]
    m = len(rig.markers)
    mk_true = np.stack([tr[[f"marker{i}_u_px", f"marker{i}_v_px"]].to_numpy()
                        for i in range(m)], 1)
    mk = np.array([r.markers_px if r.markers_px is not None else np.full((m, 2), np.nan)
                   for r in recs])
    mk_err = np.nanmean(mk - mk_true, axis=1)  # px, image axes
    app = np.array([r.centre_app for r in recs], float)
    misfit = np.array([r.misfit_m for r in recs], float)
    gain, _ = misfit_gain(misfit, np.array([r.misfit_sigma_m for r in recs], float))
    stages.append(_stage("apparent centre (markers through the homography)",
                         to_truth(app) - apparent, travel))
    app = app + gain * misfit
    stages.append(_stage("... with the lattice misfit taken off",
                         to_truth(app) - apparent, travel))
    h_est = shot.meta["camera_height_m"]
    notes = dict(camera_height_est_m=h_est, camera_height_err_m=shot.meta.get(
        "camera_height_err_m"), camera_height_true_m=float(np.median(cam_h - depth)),
        lens=tuple(float(v) for v in calib.dist[:2]),
        lens_focal_ref_px=float(calib.K[0, 0]),  # (k1 at the lens's own f: x (f / this)^2)
        principal_point_px=tuple(float(v) for v in calib.K[:2, 2]),
        marker_px_error_mean=tuple(np.nanmean(mk_err, 0).round(3)),
        marker_px_error_std=tuple(np.nanstd(mk_err, 0).round(3)))
    if h_est is not None:
        hs = np.array([r.H for r in recs])
        _, nadir, k = _nadir_and_k(hs, h_est + depth, shot.meta["parallax_factor"], h_eff,
                                   calib.K[:2, 2])
        stages.append(_stage("camera nadir (x 1 - k: its share in the centre)",
                             (to_truth(nadir) - cam) * (1 - k)[:, None], travel))
        k_true = 1 - h_eff / cam_h
        notes["parallax_factor_error"] = float(np.median(k - k_true))
        centre = correct_parallax(app, nadir, k[:, None])
        stages.append(_stage("rock centre (parallax corrected)", to_truth(centre) - rock,
                             travel))
    data = shot.data.merge(truth[["frame", "x", "y"]], on="frame", suffixes=("", "_t"))
    ok = data["ok"].to_numpy() == 1
    true_xy = data[["x_t", "y_t"]].to_numpy()
    err = (data[["x", "y"]].to_numpy() - true_xy)[ok]
    row_travel = np.hypot(*(true_xy[ok] - true_xy[0]).T)
    stages.append(_stage("SHOT.csv rows (shot frame, ok = 1)", err, row_travel))
    z = np.hypot(*err.T) / data["sigma_xy"].to_numpy()[ok]
    notes.update(rows_error_over_sigma_median=float(np.median(z)),
                 rows_error_over_sigma_p90=float(np.quantile(z, 0.9)),
                 rows_error_over_sigma_max=float(z.max()))
    return pd.DataFrame(stages).set_index("stage"), notes


def _scale_seed_setup(seed: int, out: Path):
    """Render the random set-up tests/hardening/test_scale.py draws first for ``seed``."""
    sys.path.insert(0, str(ROOT / "tests" / "hardening"))
    from dataclasses import replace

    from test_scale import random_setup, render_setup

    from curltrack.rig import default_rig

    setup = random_setup(np.random.default_rng(seed))
    print(f"set-up: {setup}")
    out.mkdir(parents=True, exist_ok=True)
    video, _, _ = render_setup(out / f"scale{seed}.mp4", **setup)
    rig = replace(default_rig(), spacing_x_m=setup["spacing_m"],
                  spacing_y_m=setup["spacing_m"])
    return video, rig


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("video", nargs="?", type=Path)
    ap.add_argument("--rig", type=Path, help="the rig the video was rendered with")
    ap.add_argument("--truth", type=Path, help="truth table (default VIDEO.truth.csv)")
    ap.add_argument("--scale-seed", type=int,
                    help="render test_scale.py's random set-up for this seed instead")
    ap.add_argument("--out", type=Path, default=Path("error_chain_out"),
                    help="where --scale-seed renders (default ./error_chain_out)")
    a = ap.parse_args(argv)
    from curltrack.rig import load_rig

    if a.scale_seed is not None:
        video, rig = _scale_seed_setup(a.scale_seed, a.out)
    elif a.video is None or a.rig is None:
        ap.error("give VIDEO and --rig, or --scale-seed")
    else:
        video, rig = a.video, load_rig(a.rig)
    truth = pd.read_csv(a.truth or video.with_suffix(".truth.csv"))
    table, notes = error_chain(video, rig, truth)
    with pd.option_context("display.width", 160, "display.max_colwidth", 60):
        print(table.round(3).to_string())
    for k, v in notes.items():
        print(f"{k}: {v}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
