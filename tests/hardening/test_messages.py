"""Messages that name the real cause (each once came out as something unrelated), and
the black lead-in that shifted t = 0 away from the release."""

from __future__ import annotations

import copy
import json
import tomllib

import numpy as np
import pandas as pd
import pytest

from curltrack.rig import default_rig
from hardening.badinputs import read_frames, write_frames

def _write_rig(tmp_path, mod):
    d = copy.deepcopy(tomllib.loads(default_rig().to_toml()))
    mod(d)
    lines = []
    for sec in ("grid", "rock", "camera"):
        if sec in d:
            lines.append(f"[{sec}]")
            for k, v in d[sec].items():
                lines.append(f"{k} = {json.dumps(v)}")
    for m in d["markers"]:
        lines.append("[[markers]]")
        lines += [f"{k} = {json.dumps(v)}" for k, v in m.items()]
    p = tmp_path / "rig.toml"
    p.write_text("\n".join(lines) + "\n")
    return p


def _three_same(d):
    import math

    d["markers"] = [dict(color="#ffd000", x_m=0.08 * math.cos(a), y_m=0.08 * math.sin(a))
                    for a in (0.0, 2 * math.pi / 3, 4 * math.pi / 3)]


RIG_CASES = {
    "marker outside the rock": (lambda d: d["markers"][1].update(x_m=-0.2),
                                ["[[markers]][1]", "outside the rock"]),
    "two markers of one colour": (lambda d: d["markers"][1].update(color="#ffd000"),
                                  ["[[markers]]", "ambiguous", "180 deg"]),
    "three of one colour, symmetric": (_three_same, ["[[markers]]", "120 deg"]),
    "a marker the colour of a thread": (lambda d: d["markers"][0].update(color="#d22222"),
                                        ["[[markers]][0].color", "thread colour #d02020"]),
    "two nearly equal colours": (lambda d: d["markers"][1].update(color="#ffd20a"),
                                 ["[[markers]][1].color", "too close"]),
}


@pytest.mark.parametrize("case", list(RIG_CASES))
def test_rig_layout_mistakes_are_named(cli, tmp_path, good_clip, case):
    mod, names = RIG_CASES[case]
    rig = _write_rig(tmp_path, mod)
    out = tmp_path / "s.csv"
    cli.fails("track", good_clip[0], "--rig", rig, "-o", out, output=out, names=[rig, *names])
    cli.fails("doctor", good_clip[0], "--rig", rig, names=[rig, *names])


def test_same_colour_markers_that_no_turn_swaps_are_fine(tmp_path):
    """Two yellow and one cyan marker (tests/track/test_markers.py's layout): valid."""
    from curltrack.rig import load_rig

    def mod(d):
        d["markers"] = [dict(color="#ffd000", x_m=0.08, y_m=0.0),
                        dict(color="#ffd000", x_m=-0.08, y_m=0.0),
                        dict(color="#00c0ff", x_m=0.0, y_m=0.07)]

    assert len(load_rig(_write_rig(tmp_path, mod)).markers) == 3


def test_black_lead_in_is_skipped_and_t0_stays_at_release(cli, tmp_path, rig_file, good_clip):
    """Black frames before the shot: skipped (warned), t = 0 at the first real frame,
    the same numbers as the same frames without them (both re-encoded alike)."""
    video, truth, _ = good_clip
    seed = int(np.random.SeedSequence().entropy % 2**32)
    n_black = int(np.random.default_rng(seed).integers(5, 25))
    frames = list(read_frames(video))
    fps = truth.meta["fps"]
    plain = write_frames(tmp_path / "plain.mp4", frames, fps)
    v = write_frames(tmp_path / "black.mp4", [np.zeros_like(frames[0])] * n_black + frames, fps)
    cli.succeeds("track", plain, "--rig", rig_file, "-o", tmp_path / "p.csv", "-q")
    out = tmp_path / "s.csv"
    cli.succeeds("track", v, "--rig", rig_file, "-o", out, "-q")
    s, p = pd.read_csv(out), pd.read_csv(tmp_path / "p.csv")
    side = json.loads(out.with_suffix(".json").read_text())
    assert s["frame"].iloc[0] == n_black and s["t"].iloc[0] == 0.0, (seed, s.head())
    assert side["start_frame"] == n_black
    assert any(f"frames 0-{n_black - 1}" in w and "black" in w for w in side["warnings"])
    assert len(s) == len(p) and (s["ok"] == p["ok"]).all(), seed
    np.testing.assert_allclose(s["t"], p["t"], atol=1e-3)
    ok = (s["ok"] == 1).to_numpy()
    # (the frames differ only by the encoder's choices around the lead-in)
    assert np.abs(s[["x", "y"]] - p[["x", "y"]]).to_numpy()[ok].max() < 5e-4, seed
    assert np.abs(s["theta"] - p["theta"]).to_numpy()[ok].max() < np.radians(0.3), seed


def test_track_summary_says_when_the_rock_did_not_stop(cli, tmp_path, rig_file, good_clip):
    video, truth, _ = good_clip
    short = write_frames(tmp_path / "moving.mp4", list(read_frames(video))[:20],
                         truth.meta["fps"])
    res = cli.succeeds("track", short, "--rig", rig_file, "-o", tmp_path / "m.csv")
    assert "(frame None)" not in res.stdout and "not within the video" in res.stdout
