"""Shot segmentation: simulated sessions (rest / held -> shot -> rest, repeated)."""

from __future__ import annotations

import numpy as np
import pytest

from curltrack.series.segment import segment_motion
from curltrack.physics import ShotModel
from curltrack.simulate import simulate_series

FPS = 30.0


def session(rng, n_shots, noise_m=0.002, noise_rad=0.01, held_s=0.5):
    """Concatenated shots; returns t, xy, theta, found and the true release/stop indices."""
    xs, ths, found, releases, stops = [], [], [], [], []
    pos, ang = np.zeros(2), 0.0

    def rest(seconds, visible=True):
        k = int(seconds * FPS)
        xs.append(np.repeat(pos[None], k, axis=0))
        ths.append(np.full(k, ang))
        found.append(np.full(k, visible))

    for _ in range(n_shots):
        rest(rng.uniform(0.8, 2.0))
        rest(held_s, visible=False)  # a hand on the rock while it is set going
        kind = rng.integers(3)
        v0 = 0.0 if kind == 0 else rng.uniform(0.15, 0.8)
        w0 = rng.choice([-1, 1]) * rng.uniform(1.0, 6.0)
        sim = simulate_series(ShotModel(v0=v0, omega0=w0, alpha_theta=rng.uniform(5e-4, 2e-3) if v0 == 0
                                        else None), fps=FPS, tail_s=0.0).data
        releases.append(sum(len(a) for a in ths))
        heading = rng.uniform(0, 2 * np.pi)
        c, s = np.cos(heading), np.sin(heading)
        xy = sim[["x", "y"]].to_numpy() @ np.array([[c, s], [-s, c]]) + pos
        xs.append(xy)
        ths.append(sim["theta"].to_numpy() + ang)
        found.append(np.ones(len(sim), bool))
        stops.append(releases[-1] + len(sim) - 1)
        pos, ang = xy[-1], ths[-1][-1]
    rest(rng.uniform(1.5, 2.5))
    xy = np.concatenate(xs) + noise_m * rng.standard_normal((sum(map(len, ths)), 2))
    th = np.concatenate(ths) + noise_rad * rng.standard_normal(len(xy))
    f = np.concatenate(found)
    xy[~f], th[~f] = np.nan, np.nan
    return np.arange(len(th)) / FPS, xy, th, f, releases, stops


@pytest.mark.parametrize("seed", range(4))
def test_segments_match_simulated_sessions(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 4))
    t, xy, th, found, releases, stops = session(rng, n)
    shots = segment_motion(t, xy, th, found)
    assert len(shots) == n, shots
    for s, rel, stop in zip(shots, releases, stops):
        assert abs(s.start_frame - rel) <= 2, (s, rel)
        assert s.end_frame >= stop - 2, (s, stop)   # the whole motion is inside
        assert s.end_frame <= stop + int(1.2 * FPS)


def test_rest_and_noise_only_give_no_shot():
    rng = np.random.default_rng(7)
    n = 300
    xy = 0.002 * rng.standard_normal((n, 2))
    th = 0.01 * rng.standard_normal(n)
    assert segment_motion(np.arange(n) / FPS, xy, th, np.ones(n, bool)) == []


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 1])
def test_split_and_batch_split_on_a_rendered_session(tmp_path, seed):
    """Two shots in one rendered video (ladder camera): found, then tracked and fitted."""
    import pandas as pd

    from curltrack.batch import BatchOptions, run_batch
    from curltrack.batch.split import split_video
    from curltrack.render import RenderConfig, render_video
    from curltrack.rig import default_rig
    from curltrack.series import Series, make_meta

    rng = np.random.default_rng(seed)
    parts, truth, pos, ang, frame = [], [], np.zeros(2), 0.0, 0
    for _ in range(2):
        k = int(rng.uniform(0.8, 1.5) * FPS)
        parts.append(np.column_stack([np.repeat(pos[None], k, 0), np.full(k, ang)]))
        frame += k
        model = ShotModel(v0=float(rng.uniform(0.2, 0.4)),
                          omega0=float(rng.choice([-1, 1]) * rng.uniform(1.5, 4.0)))
        sim = simulate_series(model, fps=FPS, tail_s=0.0).data
        xyz = sim[["x", "y", "theta"]].to_numpy() + (*pos, ang)
        truth.append((frame, frame + len(sim) - 1, model))
        parts.append(xyz)
        frame += len(sim)
        pos, ang = xyz[-1, :2], xyz[-1, 2]
    k = int(1.5 * FPS)
    parts.append(np.column_stack([np.repeat(pos[None], k, 0), np.full(k, ang)]))
    q = np.concatenate(parts)
    data = pd.DataFrame({"frame": np.arange(len(q)), "t": np.arange(len(q)) / FPS,
                         "x": q[:, 0], "y": q[:, 1], "theta": q[:, 2], "ok": 1})
    series = Series(data, make_meta(FPS, len(q)))
    rig = default_rig()
    videos = tmp_path / "videos"
    render_video(series, rig, videos / "session.mp4", seed=seed,
                 config=RenderConfig(width=640, height=360, stopped_tail_s=0.0))
    shots = split_video(videos / "session.mp4", rig)
    assert len(shots) == 2, shots
    for s, (rel, stop, _) in zip(shots, truth):
        assert abs(s.start_frame - rel) <= 2 and s.end_frame >= stop
    (tmp_path / "rig.toml").write_text(rig.to_toml())
    summary = run_batch(videos, tmp_path / "rig.toml", tmp_path / "out", workers=2,
                        options=BatchOptions(split=True))
    table = pd.read_parquet(tmp_path / "out" / "campaign.parquet")
    assert list(table["status"]) == ["done", "done"], table["error"].tolist()
    for (_, row), (_, _, model) in zip(table.iterrows(), truth):
        assert row["omega0"] == pytest.approx(model.omega0, rel=0.1)
        assert row["v0"] == pytest.approx(model.v0, rel=0.1)
    assert summary.done == 2


def test_shots_joined_by_a_cut_are_split_at_it(tmp_path):
    """Two shots joined in an editor (a hard cut, the camera elsewhere): split put the
    second shot's start frames off the cut and read its release across it (omega
    15 rad/s for 2; a helper's finding).  No shot or velocity spans a cut now."""
    import cv2

    from curltrack.batch.split import split_video
    from curltrack.render import CameraConfig, RenderConfig, render_video
    from curltrack.rig import default_rig

    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    rig = default_rig()
    frames, n, spins = [], [], []
    for name in ("a.mp4", "b.mp4"):   # two short draws released at their first frame
        spins.append(float(rng.choice([-1, 1]) * rng.uniform(1.0, 2.5)))
        sim = simulate_series(ShotModel(v0=rng.uniform(0.3, 0.45), omega0=spins[-1]), fps=30)
        render_video(sim, rig, tmp_path / name, seed=int(rng.integers(1 << 30)),
                     config=RenderConfig(width=480, height=270, blur_subframes=2,
                                         camera=CameraConfig(motion="ladder")))
        cap = cv2.VideoCapture(str(tmp_path / name))
        k0 = len(frames)
        while (got := cap.read())[0]:
            frames.append(got[1])
        n.append(len(frames) - k0)
    joined = tmp_path / "joined.mp4"
    out = cv2.VideoWriter(str(joined), cv2.VideoWriter_fourcc(*"mp4v"), 30,
                          frames[0].shape[1::-1])
    for f in frames:
        out.write(f)
    out.release()
    shots = split_video(joined, rig)
    what = (f"seed {seed}: {n} frames, spins {np.round(spins, 2)}, shots "
            f"{[(s.start_frame, s.end_frame, round(s.peak_omega_rad_s, 2)) for s in shots]}")
    # (what is held: the cut.  Where split finds each shot's release on these 480x270
    # clips is another matter, not met: its marker search can miss a clip's first
    # second or more, and a late start reads a wrong spin - seed 4112469887: a shot of
    # 23 frames after the cut at +4.3 rad/s for -1.3)
    assert shots and not any(s.start_frame < n[0] <= s.end_frame for s in shots), what
