"""Rendered action-camera and phone clips: a strong wide-angle lens tracked at mm level,
and a rolling shutter's rows timed where the rock was exposed (slow: video renders)."""

import dataclasses

import numpy as np
import pytest
from scipy.interpolate import CubicSpline

from curltrack.errors import CurltrackError, ParameterError, TrackingError
from curltrack.render import RenderConfig, render_video
from curltrack.render.sensor import SensorConfig
from curltrack.render.sweep import _lens_ok, draw_setup
from curltrack.rig import default_rig, load_rig
from curltrack.track import track_video

pytestmark = pytest.mark.slow


def _errors(series, truth):
    """Position errors (m, (n, 2)), their sigma (m) and theta errors (rad) of the ok rows
    against the truth at each row's own time."""
    s, T = series.data, truth.data.sort_values("t")
    ok = (s.ok == 1).to_numpy()
    t = s.t.to_numpy()[ok]
    e = np.column_stack([s.x.to_numpy()[ok] - CubicSpline(T.t, T.x)(t),
                         s.y.to_numpy()[ok] - CubicSpline(T.t, T.y)(t)])
    dth = s.theta.to_numpy()[ok] - CubicSpline(T.t, T.theta)(t)
    return e, s.sigma_xy.to_numpy()[ok], dth, ok


def test_strong_wide_angle_lens_clip(tmp_path):
    """An action camera at 960x540 with k1 -0.35..-0.2 and k2 (global shutter): tracked
    to the mm, or refused naming the lens - never rows cm-off marked ok."""
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    plain = RenderConfig()  # (the lens alone: no glare, shadow, broom, rolling shutter)
    video = tmp_path / "action.mp4"
    for _ in range(10):  # a set-up whose lens does not fold over inside the image
        st = draw_setup(rng, "action", 0.5)
        cam = dataclasses.replace(st.config.camera, lens="radial",
                                  k1=rng.uniform(-0.35, -0.2), k2=rng.uniform(0.02, 0.08))
        if not _lens_ok(cam, st.config.width, st.config.height):
            continue
        cfg = dataclasses.replace(st.config, camera=cam, sensor=SensorConfig(chroma="420"),
                                  glare=plain.glare, glare_spread_rad=plain.glare_spread_rad,
                                  shadow=plain.shadow, occlusion=False)
        try:
            truth = render_video(st.shot, default_rig(), video, tmp_path / "truth.csv", cfg,
                                 seed=st.seed)
            break
        except ParameterError:  # (folds over once the camera tilts: another draw)
            continue
    else:
        pytest.fail(f"seed {seed}: no renderable wide-angle set-up in 10 draws")
    what = f"seed {seed}: k1 {cam.k1:.3f}, k2 {cam.k2:.3f}, {cam.motion}"
    try:
        series = track_video(video, load_rig(video.with_suffix(".rig.toml")))
    except TrackingError as exc:
        assert "lens" in str(exc), (what, str(exc))
        return
    e, sig, dth, ok = _errors(series, truth)
    err = np.hypot(*e.T)
    assert ok.mean() >= 0.9, (what, ok.mean())
    assert np.sqrt(np.mean(err ** 2)) <= 2e-3, (what, np.sqrt(np.mean(err ** 2)))
    # no ok row cm-off or far outside its own sigma
    assert err.max() <= 10e-3, (what, err.max())
    assert np.abs(e / sig[:, None]).max() <= 5.0, (what, np.abs(e / sig[:, None]).max())


def test_rolling_shutter_rows_timed_at_the_rock(tmp_path):
    """A phone with a rolling shutter (readout 10-30 ms, any rotation tag): with
    [camera].rolling_shutter_ms each row's t is the instant the sensor row of the rock's
    centre was exposed (the renderer's drawn position), within the markers' spread."""
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    st = draw_setup(rng, "phone", 0.5)
    readout = rng.uniform(0.010, min(0.030, 0.9 / st.config.fps))
    cfg = dataclasses.replace(st.config, sensor=dataclasses.replace(
        st.config.sensor, readout_s=readout, frame_jitter_s=0.0, drop_rate=0.0))
    video = tmp_path / "phone.mp4"
    truth = render_video(st.shot, default_rig(), video, tmp_path / "truth.csv", cfg,
                         seed=st.seed)
    rig = dataclasses.replace(load_rig(video.with_suffix(".rig.toml")),
                              rolling_shutter_ms=1e3 * readout)
    what = f"seed {seed}: readout {1e3 * readout:.1f} ms, {st.summary}"
    series = track_video(video, rig)
    s = series.data.merge(truth.data[["frame", "t", "v_drawn_px"]], on="frame",
                          suffixes=("", "_frame"))
    s = s[s.ok == 1]
    expected = readout * ((s.v_drawn_px + 0.5) / cfg.height - 0.5)
    # (the markers' mean is within a few px of the centre's drawn row: 4 px of 540)
    np.testing.assert_allclose(s.t - s.t_frame, expected, atol=readout * 4 / cfg.height,
                               err_msg=what)
    assert series.meta["rolling_shutter_ms"] == pytest.approx(1e3 * readout)


def test_rolling_shutter_theta_as_good_as_a_global_shutter(tmp_path):
    """A pole-mounted phone or action camera with a rolling shutter (readout 8-30 ms),
    the ice sliding under it and the rock crossing it: with [camera].rolling_shutter_ms
    the markers, read on different rows, are moved to one instant with the rock's rate
    before its angle is taken, so theta's frame-to-frame errors over the first 1.5 s
    (where the rock is fast and the camera has not caught up: the RS shear of the
    marker pair, up to ~1 deg, is largest there) are as small as under a global shutter:
    within 0.1 deg RMS plus 3 sigma of the two RMS's sampling scatter.  Measured about
    the shot's median error, since theta's origin (fitted to the first 0.8 s) differs
    between two renders by its own noise.  Whole-shot RMS before -> after: 0.55 -> 0.12
    and 0.73 -> 0.16 deg on the camera bench's action clips, 1.12 -> 0.56 deg on a 29 ms
    phone (0.70 with a global shutter)."""
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    st = draw_setup(rng, str(rng.choice(["phone", "action"])), 0.5)
    plain = RenderConfig()
    readout = rng.uniform(0.008, min(0.030, 0.9 / st.config.fps))
    rms, frac, n = {}, {}, {}
    for r in (0.0, readout):
        cfg = dataclasses.replace(
            st.config, camera=dataclasses.replace(st.config.camera, motion="pole"),
            sensor=dataclasses.replace(st.config.sensor, readout_s=r, frame_jitter_s=0.0,
                                       drop_rate=0.0),
            glare=plain.glare, shadow=plain.shadow, occlusion=False)
        video = tmp_path / f"rs{r:.4f}.mp4"
        try:
            truth = render_video(st.shot, default_rig(), video, tmp_path / "truth.csv", cfg,
                                 seed=st.seed)
        except ParameterError as exc:  # (a lens folding over in this view: not a camera)
            pytest.skip(f"seed {seed}: {exc}")
        rig = dataclasses.replace(load_rig(video.with_suffix(".rig.toml")),
                                  rolling_shutter_ms=1e3 * r if r else None)
        try:
            series = track_video(video, rig)
        except TrackingError as exc:
            if r == 0.0:  # (not this test's subject: the set-up itself)
                pytest.skip(f"seed {seed}: global-shutter render refused: {exc}")
            raise
        _, _, dth, ok = _errors(series, truth)
        if r == 0.0 and ok.mean() < 0.9:  # (not this test's subject: the set-up itself)
            pytest.skip(f"seed {seed}: global-shutter render {ok.mean():.0%} measured")
        early = series.data.t.to_numpy()[ok] < 1.5
        rms[r] = float(np.degrees(np.sqrt(np.mean((dth - np.median(dth))[early] ** 2))))
        frac[r], n[r] = float(ok.mean()), int(early.sum())
    what = (f"seed {seed}: readout {1e3 * readout:.1f} ms, {st.summary}, early theta RMS "
            f"{rms}, measured {frac}")
    # an RMS of n errors scatters by RMS / sqrt(2 n): 3 sigma of the two's difference
    slack = 3 * np.sqrt(sum(rms[r] ** 2 / (2 * n[r]) for r in rms))
    assert rms[readout] <= rms[0.0] + 0.1 + slack, (what, slack)


# Only the trust side is held: sigma too large (conservative) is seen on some draws
# (seed 1367895436: k1 -0.295, k2 0.059, readout 11.6 ms, glare and a broom: std
# e/sigma 0.40 at 0.69 mm RMS), not yet looked into.
def test_wide_angle_action_clip_sigma_honest(tmp_path):
    """A hand-held action camera as drawn for the sweep (rolling shutter, shake, codec)
    with a strong wide-angle lens (k1 -0.35..-0.25, k2): sigma_xy is honest - the std of
    error/sigma (x and y pooled) at most 1.4 (issue #19.6: 1.8-2.3 before the nadir
    was decomposed about the principal point and the lattice's local misfit taken off
    the markers; the aim is 0.8-1.25, the band allows for one clip's few independent
    stretches of a smooth error) - and positions stay at the mm."""
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    video = tmp_path / "action.mp4"
    for _ in range(10):  # a set-up whose lens does not fold over inside the image
        st = draw_setup(rng, "action", 0.5)
        cam = dataclasses.replace(st.config.camera, lens="radial", motion="handheld",
                                  k1=rng.uniform(-0.35, -0.25), k2=rng.uniform(0.02, 0.08))
        if not _lens_ok(cam, st.config.width, st.config.height):
            continue
        cfg = dataclasses.replace(st.config, camera=cam)
        try:
            truth = render_video(st.shot, default_rig(), video, tmp_path / "truth.csv", cfg,
                                 seed=st.seed)
            break
        except CurltrackError:  # (folds over once tilted; the writer refuses a file)
            continue
    else:
        pytest.fail(f"seed {seed}: no renderable wide-angle set-up in 10 draws")
    readout_ms = 1e3 * float(truth.meta.get("readout_s") or 0.0)
    what = (f"seed {seed}: k1 {cam.k1:.3f}, k2 {cam.k2:.3f}, readout {readout_ms:.1f} ms, "
            f"{st.summary}")
    rig = dataclasses.replace(load_rig(video.with_suffix(".rig.toml")),
                              rolling_shutter_ms=readout_ms or None)
    try:
        series = track_video(video, rig)
    except TrackingError as exc:  # (a lens refused by name is honest too)
        assert "lens" in str(exc), (what, str(exc))
        return
    e, sig, _, ok = _errors(series, truth)
    assert ok.mean() >= 0.9, (what, ok.mean())
    rms = float(np.sqrt(np.mean(np.sum(e ** 2, axis=1))))
    assert rms <= 1.5e-3, (what, rms)
    z = float(np.std(np.r_[e[:, 0] / sig, e[:, 1] / sig]))
    assert z <= 1.4, f"{what}: std of position error/sigma {z:.2f} (pos RMS {1e3 * rms:.2f} mm)"


def test_phone_clip_under_auto_exposure_measured_from_the_first_frames(tmp_path):
    """Issue 19: a phone clip under auto exposure and white balance (a cyan marker on
    green-tinted ice, ~40 % of its rig contrast) had one marker not found for its first
    ~0.7-0.9 s (bench seed 20261124: frames 0-19 ok = 0, the origin extrapolated and
    9 mm off).  The marker is now looked for where the layout puts it from the one
    found: the clip is measured from its first frames, and no ok row is cm-off or far
    outside its sigma.  (The 640x360 hand-held clips at a quarter bitrate are not held
    here: their origin, a fit to frames ~3 mm off each, is 2-4 mm off under a ~1.5 mm
    sigma - see the README's Known limitations.)"""
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    for _ in range(50):
        st = draw_setup(rng, "phone", 0.5)
        if "auto_exposure" in st.summary["artefacts"]:
            break
    # (the faint marker alone: no broom over the rock, no person's shadow)
    cfg = dataclasses.replace(st.config, occlusion=False, shadow=RenderConfig().shadow)
    video = tmp_path / "phone.mp4"
    try:
        truth = render_video(st.shot, default_rig(), video, tmp_path / "truth.csv", cfg,
                             seed=st.seed)
    except CurltrackError as exc:  # (a phone's frame timing the writer refuses)
        pytest.skip(f"seed {seed}: not renderable: {exc}")
    readout_ms = 1e3 * float(truth.meta.get("readout_s") or 0.0)
    what = f"seed {seed}: {st.summary}"
    rig = dataclasses.replace(load_rig(video.with_suffix(".rig.toml")),
                              rolling_shutter_ms=readout_ms or None)
    series = track_video(video, rig)
    e, sig, _, ok = _errors(series, truth)
    err = np.hypot(*e.T)
    assert ok.mean() >= 0.9, (what, ok.mean())
    assert series.data.t.to_numpy()[ok].min() <= 0.1, (what, "first measured row late")
    assert err.max() <= 10e-3, (what, err.max())
    assert np.abs(e / sig[:, None]).max() <= 5.0, (what, np.abs(e / sig[:, None]).max())


def test_rolling_shutter_measured_when_not_given(tmp_path):
    """A phone or action camera with a rolling shutter (readout 8-30 ms) tracked with no
    [camera].rolling_shutter_ms: the readout is measured from the lattice's shear under
    the camera's motion (within 25 %: phones measured up to +17 % on the camera sweep),
    said so in the sidecar, and the positions are as good as with the true readout given
    (within 0.3 mm RMS).  The same set-up with a global shutter measures none."""
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    st = draw_setup(rng, str(rng.choice(["phone", "action"])), 0.5)
    readout = rng.uniform(0.008, min(0.030, 0.9 / st.config.fps))
    what = f"seed {seed}: readout {1e3 * readout:.1f} ms, {st.summary}"
    rms = {}
    for r in (readout, 0.0):
        cfg = dataclasses.replace(st.config, sensor=dataclasses.replace(
            st.config.sensor, readout_s=r))
        video = tmp_path / f"rs{r:.4f}.mp4"
        try:
            truth = render_video(st.shot, default_rig(), video, tmp_path / "truth.csv", cfg,
                                 seed=st.seed)
            rig = load_rig(video.with_suffix(".rig.toml"))
            series = track_video(video, rig)
        except (ParameterError, TrackingError) as exc:  # (the set-up itself, not the subject)
            pytest.skip(f"{what}: {exc}")
        meta = series.meta
        if r == 0.0:
            assert "rolling_shutter_ms" not in meta, (what, meta.get("rolling_shutter_ms"))
            break
        assert meta.get("rolling_shutter_source") == "measured from the grid", what
        assert meta["rolling_shutter_ms"] == pytest.approx(1e3 * readout, rel=0.25), \
            (what, meta["rolling_shutter_ms"])
        rms["measured"] = np.sqrt(np.mean(np.sum(_errors(series, truth)[0] ** 2, axis=1)))
        given = track_video(video, dataclasses.replace(rig, rolling_shutter_ms=1e3 * r))
        rms["given"] = np.sqrt(np.mean(np.sum(_errors(given, truth)[0] ** 2, axis=1)))
        assert rms["measured"] <= rms["given"] + 0.3e-3, (what, rms)
        assert not any("disagrees" in w for w in given.meta["warnings"]), what
        # a readout in the rig far from the video's (another mode's spec, a typo) is said
        wrong = track_video(video, dataclasses.replace(rig, rolling_shutter_ms=3e3 * r))
        assert any("rolling_shutter_ms" in w and "disagrees" in w
                   for w in wrong.meta["warnings"]), what
