"""The tracker's thresholds: one TrackingSettings, overridable from the rig's [tracking]
table, recorded in SHOT.json - and an override changes what is measured."""

import json
import subprocess
import sys
from dataclasses import fields, replace

import numpy as np
import pytest

from curltrack.errors import RigError
from curltrack.rig import default_rig, load_rig
from curltrack.settings import TrackingSettings


def _rig_file(tmp, tracking: str = "") -> str:
    path = tmp / "rig.toml"
    path.write_text(default_rig().to_toml() + ("\n[tracking]\n" + tracking if tracking else ""))
    return path


@pytest.mark.parametrize("line,where,says", [
    ("poor_fit_min_pxx = 0.4", "[tracking].poor_fit_min_pxx", "did you mean 'poor_fit_min_px'"),
    ("poor_fit_frames = 3.5", "[tracking].poor_fit_frames", "expected an integer"),
    ("give_up_frames = true", "[tracking].give_up_frames", "expected an integer"),
    ("poor_fit_min_px = \"0.4\"", "[tracking].poor_fit_min_px", "expected a number"),
    ("max_origin_sigma_m = 5.0", "[tracking].max_origin_sigma_m", "plausible range"),
    ("layout_scale_min = 0.95\nlayout_scale_max = 0.9", "[tracking].layout_scale_max",
     "plausible range"),
])
def test_bad_tracking_keys_are_refused_naming_file_and_key(tmp_path, line, where, says):
    path = _rig_file(tmp_path, line + "\n")
    with pytest.raises(RigError) as exc:
        load_rig(path)
    text = str(exc.value)
    assert str(path) in text and where in text and says in text, text
    assert "\n" not in text
    # the command line: one line on stderr, exit 1
    proc = subprocess.run([sys.executable, "-m", "curltrack", "doctor", "nothing.mp4",
                           "--rig", str(path)], capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 1 and where in proc.stderr, proc.stderr


def test_settings_round_trip_and_defaults(tmp_path):
    rig = load_rig(_rig_file(tmp_path, "poor_fit_min_px = 1\nstale_frames = 5\n"))
    assert rig.tracking.poor_fit_min_px == 1.0 and isinstance(rig.tracking.poor_fit_min_px, float)
    assert rig.tracking.changed() == {"poor_fit_min_px": 1.0, "stale_frames": 5}
    (tmp_path / "again.toml").write_text(rig.to_toml())
    assert load_rig(tmp_path / "again.toml").tracking == rig.tracking
    assert default_rig().tracking == TrackingSettings() and not TrackingSettings().changed()
    for f in fields(TrackingSettings):
        assert f.metadata["unit"] and f.metadata["why"], f.name
        lo, hi = f.metadata["range"]
        assert lo <= f.default <= hi, f.name
    with pytest.raises(ValueError, match="poor_fit_min_px"):
        replace(TrackingSettings(), poor_fit_min_px=-1.0)


def _clip(tmp, seed):
    from clips import render_clip

    render_clip(tmp / "clip.mp4", np.random.default_rng(seed))
    return tmp / "clip.mp4"


def test_a_stricter_rig_threshold_refuses_frames_the_default_accepts(tmp_path):
    """[tracking] scale_outlier_sigma = 1: frames whose marker layout scale is more than
    1 robust sigma off the video's are refused (a third of them for Gaussian scatter);
    with the default 6 none of these.  The CLI reads the table from the rig file and
    SHOT.json records it."""
    import pandas as pd

    from curltrack.track import track_video

    seed = int(np.random.SeedSequence().entropy % 2**31)
    video = _clip(tmp_path, seed)
    default = track_video(video, default_rig())
    assert default.meta["tracking_settings"] == TrackingSettings().summary()
    rig = _rig_file(tmp_path, "scale_outlier_sigma = 1.0\n")
    out = tmp_path / "strict.csv"
    proc = subprocess.run([sys.executable, "-m", "curltrack", "track", str(video), "--rig",
                           str(rig), "-o", str(out), "-q", "--no-progress"],
                          capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    meta = json.loads(out.with_suffix(".json").read_text())
    assert meta["tracking_settings"] == {**TrackingSettings().summary(),
                                         "scale_outlier_sigma": 1.0}
    strict = pd.read_csv(out)
    ok_def, ok_strict = default.data["ok"].to_numpy(bool), strict["ok"].to_numpy(bool)
    n = len(strict)
    msg = f"seed {seed}: strict {ok_strict.sum()}, default {ok_def.sum()} of {n}"
    # (some draws lose their first frames to the calibration: 27 of 70 once, as before)
    assert ok_def.sum() >= 0.5 * n, msg
    assert not np.any(ok_strict & ~ok_def), msg  # (the same frames, fewer kept)
    assert 0.15 * ok_def.sum() <= ok_def.sum() - ok_strict.sum() <= 0.6 * ok_def.sum(), msg
    assert any("marker layout inconsistent" in w for w in meta["warnings"]), msg


def test_the_grid_tracker_reads_its_thresholds_from_the_rig(tmp_path):
    """poor_fit_factor = 1, poor_fit_min_px = 0.05 (calib.tracker): a frame whose threads
    miss the lattice by more than the median of the last accepted frames is refused -
    most frames; with the defaults (2.5 x typical, at least 0.6 px) hardly any."""
    from curltrack.track.pipeline import track_frames
    from curltrack.video import iter_frames

    seed = int(np.random.SeedSequence().entropy % 2**31)
    video = _clip(tmp_path, seed)
    strict = replace(default_rig(), tracking=replace(
        TrackingSettings(), poor_fit_factor=1.0, poor_fit_min_px=0.05))
    poor = {}
    for name, rig in (("default", default_rig()), ("strict", strict)):
        records, _ = track_frames(iter_frames(video), rig)
        poor[name] = sum("grid fit poor" in r.status for r in records)
    n = len(records)
    # (with the factor 1 a frame is refused when its fit is worse than the running
    # median's: about half of them, correlated frame to frame - 30 % was too close to
    # that, seed 1287064168 refused 20 of 70 - a fifth is still far from the default's)
    assert poor["default"] <= 0.05 * n and poor["strict"] >= 0.2 * n, (seed, poor, n)


def test_a_lattice_the_threads_do_not_fix_at_the_rock_is_refused(tmp_path):
    """max_grid_sigma_cells: a frame whose homography's 1 sigma at the rock exceeds it
    is refused, naming why.  The default (0.05 cell) refuses none of a clean clip's
    frames; a limit under the typical 0.0015 cell refuses most of them."""
    from curltrack.track.pipeline import track_frames
    from curltrack.video import iter_frames

    seed = int(np.random.SeedSequence().entropy % 2**31)
    video = _clip(tmp_path, seed)
    strict = replace(default_rig(), tracking=replace(TrackingSettings(),
                                                     max_grid_sigma_cells=0.001))
    free = {}
    for name, rig in (("default", default_rig()), ("strict", strict)):
        records, _ = track_frames(iter_frames(video), rig)
        free[name] = sum("lattice is not fixed at the rock" in r.status for r in records)
    n = len(records)
    assert free["default"] == 0 and free["strict"] >= 0.5 * n, (seed, free, n)
