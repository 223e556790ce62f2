"""The overlay video draws the trail only where the rock has been, in H.264."""

import numpy as np
import pytest

from curltrack.physics.shot import ShotModel
from curltrack.rig import default_rig
from curltrack.simulate import simulate_series


def _path_distance(p, path):
    """Distance (m) of points p (N, 2) to the polyline ``path`` (M, 2)."""
    a, b = path[:-1], path[1:]
    ab = b - a
    t = np.clip(np.einsum("nmi,mi->nm", p[:, None] - a, ab) / np.maximum((ab ** 2).sum(1), 1e-18),
                0, 1)
    d = p[:, None] - (a + t[..., None] * ab)
    return np.sqrt((d ** 2).sum(-1)).min(axis=1)


def test_overlay_trail_stays_on_the_truth_path(tmp_path, monkeypatch):
    """A ladder shot whose trail leaves the image, through a strong barrel lens (where
    the lens polynomial folds far points back into view): every trail pixel of every
    overlay frame, taken back to the ice through that frame's homography, lies within
    5 mm of where the rock has truly been up to that frame."""
    from curltrack.calib.lens import apply_h, undistort
    from curltrack.render import CameraConfig, RenderConfig, render_video
    from curltrack.track import overlay, track_video

    seed = int(np.random.SeedSequence().entropy % 2**31)
    rng = np.random.default_rng(seed)
    rig = default_rig()
    v0, k1 = rng.uniform(0.8, 1.0), rng.uniform(-0.16, -0.10)
    sim = simulate_series(ShotModel(v0=v0, omega0=rng.choice([-1, 1]) * 1.2, alpha_y=0.015),
                          fps=30)
    truth = render_video(sim, rig, tmp_path / "v.mp4", config=RenderConfig(
        width=800, height=450, blur_subframes=1, camera=CameraConfig(k1=k1, view_m=1.2)),
        seed=seed)  # 2.7 mm per pixel
    seen = {}
    real = overlay.write_overlay

    def spy(video, path, records, series, loop_info, rig, **kw):
        seen.update(records={r.frame: r for r in records}, calib=loop_info["calib"],
                    meta=series.meta)
        return real(video, path, records, series, loop_info, rig, **kw)

    def keep_trail(path, frames, fps, size, progress=None):
        seen["trail"] = {i: np.argwhere((img == overlay.TRAIL_BGR).all(axis=2))[:, ::-1]
                         for i, img in frames}
        path.write_bytes(b"")
        return 0

    monkeypatch.setattr(overlay, "write_overlay", spy)
    monkeypatch.setattr(overlay, "_encode", keep_trail)
    monkeypatch.setattr(overlay, "verify_video", lambda *a: None)
    series = track_video(tmp_path / "v.mp4", rig, overlay_path=tmp_path / "o.mp4")
    msg = f"seed {seed}, v0 {v0:.2f} m/s, k1 {k1:.3f}"
    m, cal = seen["meta"], seen["calib"]
    o = np.asarray(m["frame_origin_lattice_m"])
    R = np.array([m["frame_x_axis_lattice"], m["frame_y_axis_lattice"]])
    tr = truth.data.set_index("frame")[["x", "y"]]
    worst, n_px, left_view = 0.0, 0, 0
    for frame, px in seen["trail"].items():
        rec = seen["records"].get(frame)
        if len(px) == 0 or rec is None or rec.H is None:
            continue
        ice = apply_h(rec.H, undistort(px.astype(float), cal.K, cal.dist))
        shot = (ice - o) @ R.T  # lattice -> shot frame (R's rows are the shot axes)
        d = _path_distance(shot, tr.loc[:frame].to_numpy())
        worst, n_px = max(worst, d.max()), n_px + len(px)
        left_view += np.linalg.norm(tr.loc[frame].to_numpy() - tr.iloc[0].to_numpy()) > 0.8
    assert n_px > 1000 and left_view > 10, msg  # a trail was drawn, also out of view
    assert worst < 0.005, f"trail {worst * 1000:.1f} mm off the true path ({msg})"
    assert series.data["ok"].mean() > 0.9, msg


def test_overlay_is_h264_and_plays(tmp_path):
    import av

    from curltrack.track.overlay import encode_h264

    rng = np.random.default_rng()
    frames = ((i, rng.integers(0, 255, (91, 121, 3), dtype=np.uint8)) for i in range(12))
    encode_h264(tmp_path / "a.mp4", frames, 29.97, (121, 91))
    with av.open(str(tmp_path / "a.mp4")) as c:
        s = c.streams.video[0]
        assert s.codec_context.name == "h264" and s.codec_context.pix_fmt == "yuv420p"
        assert sum(1 for _ in c.decode(video=0)) == 12
        assert abs(float(s.average_rate) - 29.97) < 0.01


def test_trail_points_beyond_the_lens_model_are_not_drawn():
    """With barrel distortion the lens polynomial folds points far outside the image
    back into it (what drew trail lines ahead of the rock in the demo's overlay): such
    points are dropped, points in view are projected as before."""
    from types import SimpleNamespace

    from curltrack.calib.lens import distort
    from curltrack.track.overlay import _Pose

    rng = np.random.default_rng()
    f, w, h = 600.0, 960, 540
    K = np.array([[f, 0, w / 2], [0, f, h / 2], [0, 0, 1]])
    dist = np.array([rng.uniform(-0.15, -0.08), 0.0])
    ppm = f / 2.0  # camera 2 m above the lattice
    H = np.linalg.inv(np.array([[ppm, 0, w / 2], [0, ppm, h / 2], [0, 0, 1]]))  # px -> m
    pose = _Pose(H, SimpleNamespace(K=K, dist=dist), default_rig(), (w, h))
    far = np.column_stack([np.linspace(-12, -3.0, 400), np.zeros(400)])  # behind, on the axis
    raw = pose.ice_to_image(far)
    folded = (raw[:, 0] >= 0) & (raw[:, 0] < w)
    assert folded.any(), dist  # the fold is real for this lens
    assert np.isnan(pose.ice_to_image(far, visible_only=True)[folded]).all()
    near = rng.uniform([-1.2, -0.6], [1.2, 0.6], (50, 2))
    np.testing.assert_allclose(pose.ice_to_image(near, visible_only=True),
                               distort(near * ppm + (w / 2, h / 2), K, dist))


def test_debug_frames_show_what_was_found(tmp_path):
    """`track --frames N,M --debug-dir DIR`: one PNG per frame; the centre drawn on it (red
    cross) is where the renderer put the rock (truth projected into the image)."""
    import cv2

    from curltrack.render import RenderConfig, render_video
    from curltrack.track import track_video

    seed = int(np.random.SeedSequence().entropy % 2**31)
    rng = np.random.default_rng(seed)
    rig = default_rig()
    sim = simulate_series(ShotModel(v0=rng.uniform(0.4, 0.6), omega0=1.0, alpha_y=0.03), fps=30)
    truth = render_video(sim, rig, tmp_path / "v.mp4", config=RenderConfig(
        width=640, height=360, blur_subframes=1), seed=seed).data.set_index("frame")
    frames = sorted(rng.choice(np.arange(5, len(truth) - 5), 3, replace=False).tolist())
    track_video(tmp_path / "v.mp4", rig, debug_frames=frames, debug_dir=tmp_path / "dbg")
    for f in frames:
        img = cv2.imread(str(tmp_path / "dbg" / f"frame_{f:06d}.png"))
        assert img.shape == (360, 640, 3), f
        red = np.argwhere((img == (0, 0, 255)).all(axis=2))[:, ::-1]
        centre = red.mean(axis=0)
        err = np.hypot(*(centre - truth.loc[f, ["u_px", "v_px"]].to_numpy(float)))
        assert len(red) > 10 and err < 2.0, f"frame {f}: cross {err:.1f} px off (seed {seed})"


def test_debug_frames_written_when_the_video_is_refused(tmp_path):
    """A video track refuses (here: the rig names a marker colour the rock does not carry,
    so no frame is measured) still gets its `--debug-dir` PNGs - calibrate's picture of
    each asked frame with track's reason - before the error."""
    from dataclasses import replace

    import cv2

    from curltrack.errors import TrackingError
    from curltrack.render import RenderConfig, render_video
    from curltrack.rig import Marker
    from curltrack.track import track_video

    seed = int(np.random.SeedSequence().entropy % 2**31)
    rng = np.random.default_rng(seed)
    rig = default_rig()
    sim = simulate_series(ShotModel(v0=rng.uniform(0.4, 0.6), omega0=1.0, alpha_y=0.03), fps=30)
    render_video(sim, rig, tmp_path / "v.mp4", config=RenderConfig(
        width=480, height=270, blur_subframes=1), seed=seed)
    m0 = rig.markers[0]
    wrong = replace(rig, markers=(Marker("#ff00ff", m0.x_m, m0.y_m),) + rig.markers[1:])
    frames = sorted(rng.choice(np.arange(0, 20), 2, replace=False).tolist())
    with pytest.raises(TrackingError):
        track_video(tmp_path / "v.mp4", wrong, debug_frames=frames, debug_dir=tmp_path / "dbg")
    for f in frames:
        img = cv2.imread(str(tmp_path / "dbg" / f"frame_{f:06d}.png"))
        assert img is not None and img.shape == (270, 480, 3), (seed, f)
