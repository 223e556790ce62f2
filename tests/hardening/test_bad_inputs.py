"""The catalogue of bad inputs, each through the real CLI.

Every case either fails cleanly — exit status 1, exactly one stderr line that names the
file and the frame or field at fault, nothing left under the requested output name — or,
when the result is still meaningful, succeeds with the documented warning in SHOT.json /
FIT.json and the frames it could not measure kept as ``ok`` = 0.
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from hardening.badinputs import (cover_rock, edit_video, hide_grid, other_colour_rig,
                                 read_frames, render_clip, rotate_crop, sidecar, write_frames,
                                 write_vfr)

# --------------------------------------------------------------------------------------
# video files that are not (whole) videos


def test_empty_file(cli, hdir, rig_file):
    v = hdir / "empty.mp4"
    v.write_bytes(b"")
    cli.fails("track", v, "--rig", rig_file, "-o", hdir / "e.csv", output=hdir / "e.csv",
              names=[v, "empty"])


@pytest.mark.parametrize("keep", [0.1, 0.5, 0.9])
def test_truncated_file(cli, hdir, rig_file, good_clip, keep):
    v = hdir / f"trunc{keep}.mp4"
    data = good_clip[0].read_bytes()
    v.write_bytes(data[:int(keep * len(data))])
    out = hdir / f"trunc{keep}.csv"
    cli.fails("track", v, "--rig", rig_file, "-o", out, output=out, names=[v])


def test_corrupt_middle_names_the_frame(cli, hdir, rig_file, good_clip):
    rng = np.random.default_rng(5)
    data = bytearray(good_clip[0].read_bytes())
    n = len(data)
    data[n // 4:n // 2] = rng.bytes(n // 2 - n // 4)
    v = hdir / "corrupt_mid.mp4"
    v.write_bytes(bytes(data))
    out = hdir / "corrupt_mid.csv"
    line = cli.fails("track", v, "--rig", rig_file, "-o", out, output=out, names=[v])
    assert "frame" in line


@pytest.mark.parametrize("kind", ["random", "text", "png", "directory"])
def test_not_a_video(cli, hdir, rig_file, good_clip, kind):
    import cv2

    v = hdir / f"notvideo_{kind}.mp4"
    if kind == "random":
        v.write_bytes(np.random.default_rng(1).bytes(30000))
    elif kind == "text":
        v.write_text("frame,t,x\n" * 200)
    elif kind == "png":
        v = v.with_suffix(".png")
        cv2.imwrite(str(v), next(read_frames(good_clip[0])))
    else:
        v.mkdir(exist_ok=True)
    out = hdir / f"nv_{kind}.csv"
    cli.fails("track", v, "--rig", rig_file, "-o", out, output=out, names=[v])


def test_missing_video(cli, hdir, rig_file):
    out = hdir / "missing.csv"
    cli.fails("track", hdir / "nope.mp4", "--rig", rig_file, "-o", out, output=out,
              names=[hdir / "nope.mp4", "no such file"])


def test_zero_frame_video(cli, hdir, rig_file):
    import cv2

    v = hdir / "zero.mp4"
    w = cv2.VideoWriter(str(v), cv2.VideoWriter_fourcc(*"mp4v"), 30, (320, 180))
    w.release()
    out = hdir / "zero.csv"
    cli.fails("track", v, "--rig", rig_file, "-o", out, output=out, names=[v])


def test_one_stderr_line_from_the_real_command(hdir, rig_file, good_clip):
    """The installed entry point, not just the app: FFmpeg's own log must stay quiet."""
    data = good_clip[0].read_bytes()
    v = hdir / "trunc_sub.mp4"
    v.write_bytes(data[:len(data) // 3])
    res = subprocess.run([sys.executable, "-m", "curltrack", "track", str(v), "--rig",
                          str(rig_file), "-o", str(hdir / "ts.csv")], capture_output=True,
                         text=True, timeout=120)
    assert res.returncode == 1
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and str(v) in lines[0], lines


# --------------------------------------------------------------------------------------
# frame rate and length


def test_variable_frame_rate_is_honoured(cli, hdir, rig_file):
    """Frames dropped irregularly from a 60 fps rendering: t from the container's stamps."""
    pytest.importorskip("av")
    v60, truth, _ = render_clip(hdir / "v60.mp4", fps=60, seed=3)
    rng = np.random.default_rng(3)
    n = len(truth.data)
    keep = np.sort(rng.choice(n, size=int(0.55 * n), replace=False))
    keep = np.unique(np.r_[0, keep])
    frames = [img for k, img in enumerate(read_frames(v60)) if k in set(keep)]
    v = write_vfr(hdir / "vfr.mp4", [(img, 1000.0 * k / 60) for img, k in zip(frames, keep)],
                  frames[0].shape[1::-1])
    out = hdir / "vfr.csv"
    cli.succeeds("track", v, "--rig", rig_file, "-o", out)
    s = pd.read_csv(out)
    tt = truth.data.iloc[keep].reset_index(drop=True)
    assert len(s) == len(keep)
    assert np.abs(s["t"] - tt["t"]).max() < 1.5e-3  # ms-resolution container stamps
    ok = s["ok"] == 1
    assert ok.mean() > 0.9
    err = np.hypot(s.x - tt.x, s.y - tt.y)[ok]
    assert np.sqrt(np.mean(err ** 2)) < 0.004


@pytest.mark.parametrize("n", [2, 5])
def test_very_short_video(cli, hdir, rig_file, good_clip, n):
    v = write_frames(hdir / f"short{n}.mp4", [f for _, f in zip(range(n),
                                                                 read_frames(good_clip[0]))], 30)
    out = hdir / f"short{n}.csv"
    cli.fails("track", v, "--rig", rig_file, "-o", out, output=out,
              names=[v, f"frames 0-{n - 1}: the video has only {n} frames", "at least 8"])


def test_short_shot_tracks_but_cannot_be_fitted(cli, hdir, rig_file, good_clip):
    """11 frames: measured (exit 0, 'still moving' warning), but too few to fit."""
    v = write_frames(hdir / "short11.mp4", [f for _, f in zip(range(11),
                                                               read_frames(good_clip[0]))], 30)
    out = hdir / "short11.csv"
    cli.succeeds("track", v, "--rig", rig_file, "-o", out)
    assert any("still moving" in w for w in sidecar(out)["warnings"])
    fit_out = hdir / "short11.fit.json"
    cli.fails("fit", out, "-o", fit_out, output=fit_out, names=[out])


# --------------------------------------------------------------------------------------
# what is in the picture


def _lost(out):
    s = pd.read_csv(out)
    return set(s.loc[s["ok"] == 0, "frame"]), s


def test_rock_leaving_the_view(cli, hdir, rig_file):
    v, truth, _ = render_clip(hdir / "leave.mp4", v0=0.9, motion="static", offset_m=(0, -0.3),
                              seed=4, tail_s=0.0)
    gone = set(truth.data.loc[truth.data["in_view"] < 1, "frame"])
    assert 10 < len(gone) < len(truth.data) - 20  # the case is what it claims
    out = hdir / "leave.csv"
    cli.succeeds("track", v, "--rig", rig_file, "-o", out)
    lost, s = _lost(out)
    assert len(s) == len(truth.data)
    assert gone <= lost | {min(gone)}  # at most the frame where it crosses the edge
    meta = sidecar(out)
    assert meta["frames_lost"] >= len(gone) - 1 and meta["warnings"]
    assert meta["t_stop_translation"] is None  # not seen to stop: not invented


def test_grid_hidden_for_a_stretch(cli, hdir, rig_file, good_clip):
    video, truth, _ = good_clip
    a, b = 12, 12 + int(np.random.default_rng(7).integers(4, 10))
    tr = truth.data

    def edit(k, img):
        if a <= k < b:
            return hide_grid(img, (tr.u_top_px[k], tr.v_top_px[k]), 42)
        return img

    v = edit_video(video, hdir / "gridpart.mp4", edit)
    out = hdir / "gridpart.csv"
    cli.succeeds("track", v, "--rig", rig_file, "-o", out)
    lost, s = _lost(out)
    assert set(range(a, b)) <= lost and len(lost - set(range(a, b))) <= 2
    assert any(f"{a}-{b - 1}" in w and "grid" in w for w in sidecar(out)["warnings"])
    m = s.merge(tr[["frame", "x", "y"]], on="frame", suffixes=("", "_t"))
    ok = m["ok"] == 1
    assert np.sqrt(np.mean(np.hypot(m.x - m.x_t, m.y - m.y_t)[ok] ** 2)) < 0.004


def test_grid_hidden_in_part_of_the_image(cli, hdir, rig_file, good_clip):
    """The top 25-50 % of every frame without threads (a shadow, a board): measured."""
    from hardening.badinputs import flat_fill

    video, truth, _ = good_clip
    tr = truth.data
    frac = float(np.random.default_rng(6).uniform(0.25, 0.5))

    def edit(k, img):
        h, w = img.shape[:2]
        vv, uu = np.mgrid[0:h, 0:w]
        far = np.hypot(uu - tr.u_top_px[k], vv - tr.v_top_px[k]) > 42
        return flat_fill(img, (vv < frac * h) & far)

    v = edit_video(video, hdir / "gridhalf.mp4", edit)
    out = hdir / "gridhalf.csv"
    cli.succeeds("track", v, "--rig", rig_file, "-o", out)
    s = pd.read_csv(out)
    m = s.merge(tr[["frame", "x", "y"]], on="frame", suffixes=("", "_t"))
    ok = m["ok"] == 1
    assert ok.mean() > 0.95
    assert np.sqrt(np.mean(np.hypot(m.x - m.x_t, m.y - m.y_t)[ok] ** 2)) < 0.003


def test_grid_hidden_everywhere(cli, hdir, rig_file, good_clip):
    video, truth, _ = good_clip
    tr = truth.data
    v = edit_video(video, hdir / "gridnone.mp4",
                   lambda k, img: hide_grid(img, (tr.u_top_px[k], tr.v_top_px[k]), 42))
    out = hdir / "gridnone.csv"
    line = cli.fails("track", v, "--rig", rig_file, "-o", out, output=out, names=[v, "grid"])
    assert "frame" in line
    assert line.count("no grid found") == 1, line  # said once, then why


def test_all_markers_occluded_for_a_stretch(cli, hdir, rig_file, good_clip):
    video, truth, _ = good_clip
    a, b = 14, 14 + int(np.random.default_rng(8).integers(5, 12))
    tr = truth.data
    v = edit_video(video, hdir / "occluded.mp4", lambda k, img: cover_rock(
        img, (tr.u_top_px[k], tr.v_top_px[k]), 45) if a <= k < b else img)
    out = hdir / "occluded.csv"
    cli.succeeds("track", v, "--rig", rig_file, "-o", out)
    lost, s = _lost(out)
    assert set(range(a, b)) <= lost
    assert len(lost - set(range(a, b))) <= 6  # recovery after the occlusion is quick
    assert any("markers" in w for w in sidecar(out)["warnings"])
    m = s.merge(tr[["frame", "theta"]], on="frame", suffixes=("", "_t"))
    ok = m["ok"] == 1
    # theta stays cumulative across the gap (no 2 pi slips)
    assert np.abs(m.theta - m.theta_t)[ok].max() < np.radians(5)


def test_wrong_marker_colours(cli, hdir, good_clip):
    video, _, rig = good_clip
    other = hdir / "other_colours.toml"
    other.write_text(other_colour_rig(rig).to_toml())
    out = hdir / "wrongcol.csv"
    line = cli.fails("track", video, "--rig", other, "-o", out, output=out,
                     names=[video, "markers"])
    assert "frame" in line


@pytest.mark.parametrize("factor", [0.5, 2.0])
def test_wrong_grid_spacing_stops_tracking(cli, hdir, good_clip, factor):
    """A rig spacing 2x off scales every position by 2: the markers' layout, measured
    against the grid, shows it; track and doctor fail instead of writing the series."""
    from dataclasses import replace

    video, _, rig = good_clip
    wrong = hdir / f"spacing{factor}.toml"
    wrong.write_text(replace(rig, spacing_x_m=factor * rig.spacing_x_m,
                             spacing_y_m=factor * rig.spacing_y_m).to_toml())
    out = hdir / f"spacing{factor}.csv"
    line = cli.fails("track", video, "--rig", wrong, "-o", out, output=out,
                     names=[video, "rig layout against the grid", "spacing"])
    scale = float(line.split("the markers measure ")[1].split("x")[0])
    assert 0.95 * factor < scale < 1.2 * factor, line  # (H / (H - h) ~ 1.05, times factor)
    res = cli("doctor", video, "--rig", wrong)
    assert res.exit_code == 1 and "rig layout against the grid" in res.stdout


def test_invisible_alternate_threads_are_not_a_finer_grid(cli, hdir):
    """Threads of the second colour as light as the ice: only every other thread shows,
    the grid looks twice as coarse as the rig says - a clear error with the reason."""
    from curltrack.rig import default_rig

    rig = replace_colours(default_rig(), ("#202020", "#e0e0e0"))
    video, _, _ = render_clip(hdir / "white_threads.mp4", rig=rig, seed=21, size=(960, 540))
    rig_path = hdir / "white_threads.toml"
    rig_path.write_text(rig.to_toml())
    out = hdir / "white_threads.csv"
    line = cli.fails("track", video, "--rig", rig_path, "-o", out, output=out,
                     names=[video, "every other thread invisible"])
    scale = float(line.split("the markers measure ")[1].split("x")[0])
    assert 0.45 < scale < 0.6, line


def replace_colours(rig, colours):
    from dataclasses import replace

    return replace(rig, grid_colors=tuple(colours))


@pytest.mark.parametrize("rate_deg_per_s", [12.0, -20.0])
def test_slow_camera_turn_is_measured(cli, hdir, rig_file, wide_clip, rate_deg_per_s):
    video, truth, _ = wide_clip
    fps = truth.meta["fps"]
    v = write_frames(hdir / f"turn{rate_deg_per_s:+.0f}.mp4",
                     (rotate_crop(img, rate_deg_per_s * k / fps, (400, 224))
                      for k, img in enumerate(read_frames(video))), fps)
    out = hdir / f"turn{rate_deg_per_s:+.0f}.csv"
    cli.succeeds("track", v, "--rig", rig_file, "-o", out)
    s = pd.read_csv(out)
    m = s.merge(truth.data[["frame", "x", "y", "theta"]], on="frame", suffixes=("", "_t"))
    ok = m["ok"] == 1
    assert ok.mean() > 0.95
    assert np.degrees(np.sqrt(np.mean((m.theta - m.theta_t)[ok] ** 2))) < 1.5
    assert np.sqrt(np.mean(np.hypot(m.x - m.x_t, m.y - m.y_t)[ok] ** 2)) < 0.003
    assert not any("camera turns" in w for w in sidecar(out)["warnings"])


def test_fast_steady_camera_turn_is_flagged(cli, hdir, rig_file, wide_clip):
    """2.5-5 deg/frame: followed but less accurate -> a warning naming the frame (or
    exit 1); never a silent result."""
    video, truth, _ = wide_clip
    rate = float(np.random.default_rng(10).uniform(2.5, 5.0))
    v = write_frames(hdir / "turn_steady_fast.mp4",
                     (rotate_crop(img, rate * k, (400, 224))
                      for k, img in enumerate(read_frames(video))), truth.meta["fps"])
    out = hdir / "turn_steady_fast.csv"
    res = cli("track", v, "--rig", rig_file, "-o", out)
    if res.exit_code == 1:
        return
    assert res.exit_code == 0, res.stderr
    meta = sidecar(out)
    assert meta["camera_turn_max_deg_per_frame"] == pytest.approx(rate, abs=0.2)
    assert any("camera turns" in w and "frame" in w for w in meta["warnings"])
    # what is reported as measured is right to within the turn's loss of accuracy (not,
    # e.g., the lattice re-acquired a quarter-turn off once the camera turned ~90 deg)
    m = pd.read_csv(out).merge(truth.data[["frame", "x", "y"]], on="frame",
                               suffixes=("", "_t"))
    ok = m["ok"] == 1
    assert np.hypot(m.x - m.x_t, m.y - m.y_t)[ok].max() < 0.010


@pytest.mark.parametrize("seed", [9, 3])
def test_camera_turning_too_fast(cli, hdir, rig_file, wide_clip, seed):
    """Erratic jumps of up to 30 deg between frames: mostly not followable.  Either exit 1
    (too few frames measured), or the frames that could be measured are right, the rest
    ok = 0, and the turning is named in the warnings - never a wrong row marked ok."""
    video, truth, _ = wide_clip
    jumps = np.random.default_rng(seed).uniform(-30, 30, len(truth.data))
    v = write_frames(hdir / f"turnfast{seed}.mp4",
                     (rotate_crop(img, jumps[k], (400, 224))
                      for k, img in enumerate(read_frames(video))), truth.meta["fps"])
    out = hdir / f"turnfast{seed}.csv"
    res = cli("track", v, "--rig", rig_file, "-o", out)
    if res.exit_code == 0:
        m = pd.read_csv(out).merge(truth.data[["frame", "x", "y"]], on="frame",
                                   suffixes=("", "_t"))
        ok = m["ok"] == 1
        assert ok.mean() < 0.6
        assert np.hypot(m.x - m.x_t, m.y - m.y_t)[ok].max() < 0.010
        assert any("camera turns" in w for w in sidecar(out)["warnings"])
        return
    line = cli.fails("track", v, "--rig", rig_file, "-o", out, output=out, names=[v])
    # every kind of reason with its count, none cut off, none repeated with new numbers
    import re

    if "cannot be extrapolated back" in line:  # the first frames lost: no origin
        assert re.search(r"frames 0-\d+: the first measured frame is at t = ", line), line
        return
    if "cannot be placed from them" in line:  # the first frames scattered: no origin
        assert re.search(r"frames 0-\d+: the first measured frames disagree", line), line
        return
    m = re.search(r"only (\d+) of (\d+) frames \((.*)\)$", line)
    assert m, line
    kinds = [k.rsplit(": ", 1) for k in m.group(3).split("; ")]
    assert all(re.fullmatch(r"\d+ frames?", c) for _, c in kinds), kinds
    assert len({k for k, _ in kinds}) == len(kinds), kinds
    assert int(m.group(1)) + sum(int(c.split()[0]) for _, c in kinds) == int(m.group(2))


# --------------------------------------------------------------------------------------
# rig files


_MISSING = [("[grid]", "spacing_x_m", "[grid].spacing_x_m"),
            ("[rock]", "diameter_m", "[rock].diameter_m"),
            ("[rock]", "height_m", "[rock].height_m")]


@pytest.mark.parametrize("section,key,where", _MISSING)
def test_rig_missing_field(cli, hdir, good_clip, section, key, where):
    from hardening.badinputs import RIG_TOML

    text = "\n".join(ln for ln in RIG_TOML.splitlines() if not ln.startswith(f"{key} ="))
    rig = hdir / f"rig_missing_{key}.toml"
    rig.write_text(text)
    out = hdir / "rm.csv"
    cli.fails("track", good_clip[0], "--rig", rig, "-o", out, output=out, names=[rig, where])


@pytest.mark.parametrize("key,where", [("spacing_x_m = 0.15", "[grid].spacing_x_m"),
                                       ("diameter_m = 0.29", "[rock].diameter_m"),
                                       ("height_m = 0.114", "[rock].height_m")])
def test_rig_in_centimetres(cli, hdir, good_clip, key, where):
    from hardening.badinputs import RIG_TOML

    name, value = key.split(" = ")
    rig = hdir / f"rig_cm_{name}.toml"
    rig.write_text(RIG_TOML.replace(key, f"{name} = {float(value) * 100:g}"))
    out = hdir / "rcm.csv"
    line = cli.fails("track", good_clip[0], "--rig", rig, "-o", out, output=out,
                     names=[rig, where])
    assert "metres" in line


@pytest.mark.parametrize("edit,where", [
    (("spacing_y_m = 0.15", "spacing_y_cm = 15"), "[grid]"),
    (("[rock]", "[rock]\nmass_kg = 20"), "[rock]"),
    (("[grid]", "[lights]\nlux = 3\n[grid]"), "top level"),
])
def test_rig_unknown_keys(cli, hdir, good_clip, edit, where):
    from hardening.badinputs import RIG_TOML

    rig = hdir / f"rig_unknown_{where.strip('[] ')}.toml"
    rig.write_text(RIG_TOML.replace(*edit, 1))
    out = hdir / "ru.csv"
    cli.fails("track", good_clip[0], "--rig", rig, "-o", out, output=out, names=[rig, where])


@pytest.mark.parametrize("content", [b"\x00\xff\xfe garbage", b"[grid\nspacing_x_m = 0.15",
                                     b""])
def test_rig_unreadable(cli, hdir, good_clip, content):
    rig = hdir / f"rig_bad{len(content)}.toml"
    rig.write_bytes(content)
    out = hdir / "rb.csv"
    cli.fails("track", good_clip[0], "--rig", rig, "-o", out, output=out, names=[rig])


# --------------------------------------------------------------------------------------
# series files (fit / discover)


def _good_csv_rows(n=40):
    return [f"{i},{i / 30:.5f},{0.001 * i:.5f},{0.02 * i:.5f},{0.05 * i:.5f},1"
            for i in range(n)]


def _write_csv(path, rows, header="frame,t,x,y,theta,ok"):
    path.write_text(header + "\n" + "\n".join(rows) + "\n")
    return path


@pytest.mark.parametrize("drop", ["theta", "t", "ok", "x"])
def test_csv_missing_column(cli, hdir, drop):
    cols = "frame,t,x,y,theta,ok".split(",")
    i = cols.index(drop)
    rows = [",".join(v for j, v in enumerate(r.split(",")) if j != i) for r in _good_csv_rows()]
    p = _write_csv(hdir / f"miss_{drop}.csv", rows, ",".join(c for c in cols if c != drop))
    out = hdir / f"miss_{drop}.fit.json"
    cli.fails("fit", p, "-o", out, output=out, names=[p, drop])


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("kind", ["duplicate", "decreasing", "text", "empty_t", "nan_t",
                                  "bad_ok"])
def test_csv_bad_cell_names_the_row(cli, hdir, kind, seed):
    rows = [r.split(",") for r in _good_csv_rows()]
    i = int(np.random.default_rng(seed).integers(2, len(rows) - 1))  # data row i
    if kind == "duplicate":
        rows[i][1] = rows[i - 1][1]
    elif kind == "decreasing":
        rows[i][1] = f"{float(rows[i - 1][1]) - 0.01:.5f}"
    elif kind == "text":
        rows[i][3] = "1.2.3m"
    elif kind == "empty_t":
        rows[i][1] = ""
    elif kind == "nan_t":
        rows[i][1] = "nan"
    else:
        rows[i][5] = "yes"
    p = _write_csv(hdir / f"bad_{kind}{seed}.csv", [",".join(r) for r in rows])
    out = hdir / f"bad_{kind}{seed}.fit.json"
    line = cli.fails("fit", p, "-o", out, output=out, names=[p, f"row {i + 2}"])
    assert "np.float64" not in line  # plain numbers in messages


def test_csv_nan_position_is_a_documented_warning(cli, hdir):
    """An empty x in an ok = 1 row is meaningful (a lost frame): warning, row ignored."""
    from curltrack.physics.shot import ShotModel
    from curltrack.series import write_series
    from curltrack.simulate import simulate_series

    sim = simulate_series(ShotModel(v0=0.8, omega0=1.5), fps=30, noise_m=0.001,
                          noise_rad=0.003, seed=2)
    rows = np.random.default_rng(2).choice(len(sim.data) - 20, 5, replace=False) + 10
    sim.data.loc[rows, "x"] = np.nan
    p = hdir / "nanx.csv"
    write_series(p, sim)
    out = hdir / "nanx.fit.json"
    cli.succeeds("fit", p, "-o", out)
    import json

    fit = json.loads(out.read_text())
    assert any("treated as ok=0" in w for w in fit["warnings"])
    assert fit["n_points"] <= len(sim.data) - len(rows)


def test_empty_and_header_only_csv(cli, hdir):
    for name, text in [("empty", ""), ("header", "frame,t,x,y,theta,ok\n")]:
        p = hdir / f"{name}_only.csv"
        p.write_text(text)
        out = hdir / f"{name}_only.fit.json"
        cli.fails("fit", p, "-o", out, output=out, names=[p])


def test_shot_that_never_stops(cli, hdir):
    """Cut before the stop: fitted with t_F extrapolated (warning); --fixed-stop refuses."""
    import json

    from curltrack.physics.shot import ShotModel
    from curltrack.series import write_series
    from curltrack.simulate import simulate_series

    rng = np.random.default_rng(4)
    sim = simulate_series(ShotModel(v0=rng.uniform(0.8, 1.2), omega0=rng.uniform(1, 2)),
                          fps=30, noise_m=0.001, noise_rad=0.003, seed=4)
    t_stop = sim.meta["t_stop_translation"]
    cut = sim.data[sim.data["t"] < rng.uniform(0.5, 0.7) * t_stop].reset_index(drop=True)
    meta = dict(sim.meta, t_stop_translation=None, t_stop_rotation=None,
                stop_frame_translation=None, stop_frame_rotation=None)
    p = hdir / "never.csv"
    write_series(p, cut, meta)
    out = hdir / "never.fit.json"
    cli.succeeds("fit", p, "-o", out)
    fit = json.loads(out.read_text())
    assert any("no stop within the series" in w for w in fit["warnings"])
    assert fit["t_FS"] > cut["t"].iloc[-1]
    out2 = hdir / "never_fixed.fit.json"
    cli.fails("fit", p, "-o", out2, "--fixed-stop", output=out2, names=[p, "stop"])


@pytest.mark.parametrize("seed", range(3))
def test_fit_that_cannot_converge(cli, hdir, seed):
    """Pure noise: no deceleration law fits; a FitError, not an internal error."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(40, 90))
    d = pd.DataFrame(dict(frame=range(n), t=np.arange(n) / 30, x=rng.normal(0, 0.3, n),
                          y=rng.normal(0, 0.3, n), theta=rng.normal(0, 3, n), ok=1))
    if seed == 0:  # the case that first showed the overflow
        n = 60
        rng = np.random.default_rng(0)
        d = pd.DataFrame(dict(frame=range(n), t=np.arange(n) / 30, x=rng.normal(0, 0.3, n),
                              y=rng.normal(0, 0.3, n), theta=rng.normal(0, 3, n), ok=1))
    p = hdir / f"noise{seed}.csv"
    d.to_csv(p, index=False)
    out = hdir / f"noise{seed}.fit.json"
    cli.fails("fit", p, "-o", out, output=out, names=[p])


def test_discover_on_one_point(cli, hdir):
    p = _write_csv(hdir / "one.csv", ["0,0,0,0,0,1"])
    out = hdir / "one.report.json"
    cli.fails("discover", p, "-o", out, output=out, names=[p])


# --------------------------------------------------------------------------------------
# frame ranges and single-frame calibration


def test_frame_range_outside_the_video(cli, hdir, rig_file, good_clip):
    video, truth, _ = good_clip
    n = len(truth.data)
    out = hdir / "range.csv"
    cli.fails("track", video, "--rig", rig_file, "-o", out, "--start-frame", n + 5,
              output=out, names=[video, "--start-frame"])
    cli.fails("track", video, "--rig", rig_file, "-o", out, "--start-frame", 20,
              "--end-frame", 10, output=out, names=[video, "--end-frame"])
    cli.fails("track", video, "--rig", rig_file, "-o", out, "--exclude-frames", "3-x",
              output=out, names=["--exclude-frames"])


def test_calibrate_bad_inputs(cli, hdir, rig_file, good_clip):
    video, truth, _ = good_clip
    n = len(truth.data)
    out = hdir / "calib.json"
    cli.fails("calibrate", video, "--rig", rig_file, "-o", out, "--frame", n + 3, output=out,
              names=[video, f"frame {n + 3}"])
    import cv2

    img = next(read_frames(video))
    flat = hdir / "flat.png"
    cv2.imwrite(str(flat), hide_grid(img))
    cli.fails("calibrate", flat, "--rig", rig_file, "-o", out, output=out,
              names=[flat, "frame 0", "grid"])


# --------------------------------------------------------------------------------------
# outputs that would destroy an input


def test_output_over_an_input_is_refused(cli, hdir, rig_file, good_clip):
    import shutil

    from curltrack.physics.shot import ShotModel
    from curltrack.series import write_series
    from curltrack.simulate import simulate_series

    video = hdir / "precious.mp4"
    shutil.copy(good_clip[0], video)
    before = video.read_bytes()
    cli.fails("track", video, "--rig", rig_file, "-o", video, names=[video, "-o"])
    cli.fails("track", video, "--rig", rig_file, "-o", hdir / "p.csv", "--overlay", video,
              names=[video, "--overlay"])
    assert video.read_bytes() == before
    shot = hdir / "precious.csv"
    write_series(shot, simulate_series(ShotModel(v0=1.0, omega0=1.5), fps=30))
    side = shot.with_suffix(".json")
    side_before = side.read_text()
    cli.fails("fit", shot, "-o", side, names=[side, "-o"])  # FIT.json over SHOT.json
    assert side.read_text() == side_before
    cli.fails("discover", shot, "-o", shot, names=[shot, "-o"])
    cli.fails("calibrate", video, "--rig", rig_file, "-o", rig_file, names=[rig_file, "-o"])


def test_every_writing_command_refuses_to_overwrite_an_input(cli, hdir, rig_file, good_clip):
    """simulate, render, doctor, split, batch: refused before any work, inputs intact."""
    import shutil

    rig = hdir / "precious_rig.toml"
    shutil.copy(rig_file, rig)
    video = hdir / "precious2.mp4"
    shutil.copy(good_clip[0], video)
    sim = hdir / "precious_sim.csv"
    cli.succeeds("simulate", "--v0", 1.0, "--omega0", 1.5, "--rig", rig, "-o", sim)
    before = {p: p.read_bytes() for p in (rig, video, sim, sim.with_suffix(".json"))}
    cli.fails("simulate", "--v0", 1.0, "--omega0", 1.5, "--rig", rig, "-o", rig,
              names=[rig, "-o", "would overwrite the input"])
    cli.fails("render", sim, "--rig", rig, "-o", hdir / "r.mp4", "--truth", sim,
              names=[sim, "--truth"])
    again = hdir / "shot.rig.toml"  # the rig a previous render wrote beside shot.mp4
    shutil.copy(rig, again)
    cli.fails("render", sim, "--rig", again, "-o", hdir / "shot.mp4",
              names=[again, "-o (the rig beside it)"])
    assert again.read_bytes() == before[rig]
    cli.fails("doctor", video, "--rig", rig, "-o", video, names=[video, "-o"])
    cli.fails("split", video, "--rig", rig, "-o", rig, names=[rig, "-o"])
    cli.fails("batch", hdir, "--rig", rig, "-o", rig, names=[rig, "not a directory"])
    assert {p: p.read_bytes() for p in before} == before


def test_output_that_is_a_directory(cli, hdir, rig_file, good_clip):
    d = hdir / "an_output_dir"
    d.mkdir(exist_ok=True)
    cli.fails("track", good_clip[0], "--rig", rig_file, "-o", d, names=[d, "directory"])
    shot = hdir / "for_dir.csv"
    shot.write_text("frame,t,x,y,theta,ok\n" + "\n".join(_good_csv_rows()) + "\n")
    cli.fails("fit", shot, "-o", d, names=[d, "directory"])


@pytest.mark.parametrize("seed, theta0", [(0, 0.0), (1, 0.0), (2, 2.5)])
def test_rock_that_neither_moves_nor_turns(cli, hdir, seed, theta0):
    """A still rock (noise only): nothing to fit -> a clear error, not an empty success.
    A constant angle (a rock placed turned) is no rotation either."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(40, 120))
    d = pd.DataFrame(dict(frame=range(n), t=np.arange(n) / 30, x=rng.normal(0, 0.002, n),
                          y=rng.normal(0, 0.002, n), theta=theta0 + rng.normal(0, 0.005, n),
                          ok=1))
    p = hdir / f"still{seed}.csv"
    d.to_csv(p, index=False)
    out = hdir / f"still{seed}.fit.json"
    cli.fails("fit", p, "-o", out, output=out, names=[p, "nothing to fit"])
