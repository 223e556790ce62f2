"""Interlaced video measured per field.

A shot rendered at 59.94 exposures/s is woven into 29.97 fps frames (top field = the even
lines of the first exposure, bottom field = the odd lines of the next) and written as
interlace-coded H.264 - what OpenCV 5 decodes as black frames.  ``track`` must read it
through FFmpeg (PyAV), measure each field as its own exposure and give a 59.94 Hz series
whose ``t`` is each field's time, with a ``field`` column and ``"fields": true``.
"""

from dataclasses import replace
import numpy as np
import pytest

av = pytest.importorskip("av")

from curltrack.physics.shot import ShotModel  # noqa: E402
from curltrack.rig import default_rig  # noqa: E402
from curltrack.render.encode import X264_PARAMS  # noqa: E402
from curltrack.simulate import simulate_series  # noqa: E402

NTSC = 30000 / 1001


def weave_interlaced(src, dst, top_first=True, crf=18, flagged=True, shared_colour=False,
                     rate=None, flag_order=None, one_exposure=False):
    """Weave pairs of progressive frames of ``src`` into interlaced H.264 frames.

    ``flagged=False`` writes the same woven frames as progressive H.264 with no field
    order: interlaced footage re-encoded by a program that dropped the flags (and copied
    the colour planes, each field's own rows).  ``shared_colour=True`` subsamples the
    colour across the woven frame instead, as a re-encoding that converted the pixel
    format as if progressive does: FFmpeg's conversion, each colour row the mean of a
    line of each field; ``"top"``: OpenCV's, each colour row sampled from the top
    field's line alone.  ``flag_order`` ("tff"/"bff") flags an order other than the
    woven one (a wrong flag); ``one_exposure=True`` weaves both fields of a frame from
    one source frame (a progressive picture flagged interlaced, as PsF).

    Each field line sums two adjacent rows of its exposure (rows 2i + p and 2i + p + 1
    for the field of parity p), as a CCD camcorder in field-integration mode reads its
    sensor: point-sampling every other line of a sharp render instead aliases 1-2 px
    threads by up to half a line, coherently when the thread spacing is an even number
    of lines.  (Both fields' lines then sit half a row lower than their nominal rows:
    one shift of the whole image, the same for the grid and the rock.)
    """
    import cv2

    from curltrack.render.encode import field_i420
    from curltrack.video import iter_frames

    out = av.open(str(dst), "w")
    st = None
    frames = iter_frames(src, decoder="opencv")
    for a in frames:
        b = a if one_exposure else next(frames, None)
        if b is None:
            break
        h, w = a.image.shape[:2]
        Y, U, V = (np.empty((h, w), np.uint8), np.empty((h // 2, w // 2), np.uint8),
                   np.empty((h // 2, w // 2), np.uint8))
        woven = np.empty_like(a.image)
        first, second = (0, 1) if top_first else (1, 0)
        for x, p in ((a.image, first), (b.image, second)):
            rows = x.astype(np.uint16)
            nxt = np.vstack([rows[1:], rows[-1:]])
            half = ((rows[p::2] + nxt[p::2] + 1) // 2).astype(np.uint8)
            woven[p::2] = half
            # 4:2:0 per field, as interlaced video is subsampled and sited
            Y[p::2], U[p::2], V[p::2] = field_i420(half, p)
        img = np.vstack([Y, U.reshape(h // 4, w), V.reshape(h // 4, w)])
        if shared_colour == "top":   # colour rows sampled from the top field's lines only
            img = cv2.cvtColor(woven, cv2.COLOR_BGR2YUV_I420)
        elif shared_colour:   # FFmpeg's conversion: each colour row averages both fields'
            img = av.VideoFrame.from_ndarray(woven, format="bgr24").reformat(
                format="yuv420p").to_ndarray()
        if st is None:
            from fractions import Fraction

            st = out.add_stream("libx264", rate=rate or Fraction(30000, 1001))
            st.height, st.width = h, w
            st.pix_fmt = "yuv420p"
            # (x264 on several threads wrote different bytes from one input depending
            # on what the process had run before: CI and this machine drew different
            # clips from one seed; on one thread the clip is the seed's alone)
            st.codec_context.thread_count = 1
            # (and without the macroblock tree, which read memory it had not written at
            # 720 px: one render woven twice in one process differed by 20-28 levels -
            # the flaky seed 1736667465 - as the renderer's own X264_PARAMS say)
            order = ("tff=1" if (flag_order or ("tff" if top_first else "bff")) == "tff"
                     else "bff=1")
            st.options = ({"flags": "+ilme+ildct", "crf": str(crf),
                           "x264-params": f"{X264_PARAMS}:{order}"} if flagged
                          else {"crf": str(crf), "x264-params": X264_PARAMS})
        for p in st.encode(av.VideoFrame.from_ndarray(img, format="yuv420p")):
            out.mux(p)
    for p in st.encode():
        out.mux(p)
    out.close()


def woven_draw(tmp_path, rng, name, **weave):
    """(truth, video, motion): 120 fields of a random draw (ladder or hand-held camera)
    rendered at 59.94 Hz, 720x480, and woven into ``name`` (:func:`weave_interlaced`)."""
    from curltrack.render import CameraConfig, RenderConfig, render_video

    sim = simulate_series(ShotModel(v0=rng.uniform(0.8, 2.0), omega0=rng.uniform(0.5, 2.5)),
                          fps=2 * NTSC)
    sim = replace(sim, data=sim.data.iloc[:120].reset_index(drop=True))
    motion = str(rng.choice(["ladder", "handheld"]))
    prog = tmp_path / "fields.mp4"
    truth = render_video(sim, default_rig(), prog, config=RenderConfig(
        width=720, height=480, fps=2 * NTSC, camera=CameraConfig(motion=motion)),
        seed=int(rng.integers(1 << 30)))
    video = tmp_path / name
    weave_interlaced(prog, video, **weave)
    return truth, video, motion


def test_interlaced_h264_is_tracked_per_field(tmp_path):
    from curltrack.track import track_video
    from curltrack.video import probe_video

    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    rig = default_rig()
    truth, video, motion = woven_draw(tmp_path, rng, "interlaced.mp4")
    info = probe_video(video)
    what = f"seed {seed}, {motion}: {info.describe()}"
    assert info.interlaced and info.decoder == "pyav", what
    series = track_video(video, rig)
    d = series.data
    assert series.meta.get("fields") is True and "field" in d.columns, what
    assert len(d) == 2 * info.n_frames, what
    # each field's own time: a 59.94 Hz series
    np.testing.assert_allclose(d.t.to_numpy(), np.arange(len(d)) / (2 * NTSC), atol=2e-4)
    tr = truth.data.iloc[2 * d.frame.to_numpy() + d.field.to_numpy()]
    ok = d.ok.to_numpy() == 1
    err = np.hypot(d.x.to_numpy() - tr.x.to_numpy(), d.y.to_numpy() - tr.y.to_numpy())[ok]
    eth = np.degrees(d.theta.to_numpy() - tr.theta.to_numpy())[ok]
    assert ok.mean() >= 0.95, f"{what}: ok {ok.mean():.2f}"
    rms = np.sqrt(np.mean(err ** 2))
    # (the target is 1 mm RMS, never > 2 mm: measured 1.0 mm RMS on a ladder
    # draw, with the two fields ~1 mm apart across the shot - thin horizontal threads
    # alias on every other line; not reached, see footage-notes.md.  Held to the
    # issue's 2 mm: CI seed 1022877939 drew a ladder at 1.68 mm, session 20)
    assert rms < 2e-3 and err.max() < 4e-3, f"{what}: {1e3 * rms:.2f} mm rms"
    # (the target is 0.3 deg; measured 0.37-0.61 deg RMS: at 720x480 a 25 mm
    # marker is ~7 px across and a field has half its lines - not reached, see
    # footage-notes.md; what is held here is that sigma_theta says so)
    assert np.sqrt(np.mean(eth ** 2)) < 1.0, what
    z = eth / np.degrees(d.sigma_theta.to_numpy()[ok])
    zr = np.sqrt(np.mean(z ** 2))  # (the angle origin's error is every row's: RMS)
    # (session 24: with each field's colour read where it was sampled the fields agree
    # and their disagreement no longer widens sigma_theta: over 10 draws (seeds 501-510)
    # zr 0.92-1.18, against 0.69-1.04 before; the one draw found over the old bound of
    # 1.6, seed 133325523, a ladder at 1.73 (1.24 before) - theta0 0.43 deg off, the
    # marker error that persists where a camera follows the rock, README's limitations)
    assert 0.5 < zr < 1.8, f"{what}: RMS of theta error/sigma {zr:.2f}"


def test_each_field_keeps_its_own_colour_where_it_was_sampled(tmp_path):
    """A coloured disc seen at two places by the two exposures of an interlaced frame
    (the renderer's camera-original interlaced 4:2:0, ``field_colour="own"``: colour
    subsampled per field, sited as MPEG-2 and H.264 site it), decoded field by field:
    each field's colour centroid is its own exposure's, where its luma puts it.  (Read
    as centred, the fields' colours were ~1 frame row apart - 3 mm on a rendered
    camcorder; a progressive conversion of the woven frame put both exposures' colour
    half-way between them.)"""
    from curltrack.render.encode import EncodingConfig, open_writer
    from curltrack.video import iter_frames

    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    H, W = 240, 320
    yy, xx = np.mgrid[0:H, 0:W].astype(float)
    for case in range(4):
        order = str(rng.choice(["tff", "bff"]))
        r = rng.uniform(6, 12)
        centres = [np.array([rng.uniform(100, 140), rng.uniform(100, 220)])]
        centres.append(centres[0] + rng.uniform(-12, 12, 2))   # (row, column) px
        colour = np.array([rng.uniform(20, 90), rng.uniform(20, 90), rng.uniform(170, 250)])
        colour = colour[rng.permutation(3)]
        first = (0, 1) if order == "tff" else (1, 0)
        img = np.full((H, W, 3), 200.0)
        for k, parity in enumerate(first):   # exposure k fills its field's rows
            cover = np.clip(r + 0.5 - np.hypot(yy - centres[k][0], xx - centres[k][1]), 0, 1)
            full = 200.0 * (1 - cover[..., None]) + colour * cover[..., None]
            img[parity::2] = full[parity::2]
        path = tmp_path / f"disc{case}.mp4"
        enc = EncodingConfig(codec="h264", bitrate_bps=8_000_000, field_colour="own")
        w = open_writer(path, 30000 / 1001, (W, H), enc, field_order=order)
        for i in range(3):
            w.write(np.clip(np.rint(img), 0, 255).astype(np.uint8), i * 1001 / 30000)
        w.close()
        fields = [f for f in iter_frames(path, fields=True) if f.index == 1]
        assert [f.field for f in fields] == [0, 1], seed
        for f in fields:
            ycc = f.image.astype(float)
            chroma = np.linalg.norm(ycc - ycc.mean(axis=2, keepdims=True)
                                    - (ycc[5, 5] - ycc[5, 5].mean()), axis=2)
            grey = np.abs(ycc.mean(axis=2) - ycc[5, 5].mean())
            c = centres[f.field]
            near = np.hypot(yy - c[0], xx - c[1]) < r + 6
            for name, wgt in (("colour", chroma), ("luma", grey)):
                wgt = np.where(near & (wgt > 0.2 * wgt[near].max()), wgt, 0.0)
                got = np.array([(wgt * yy).sum(), (wgt * xx).sum()]) / wgt.sum()
                off = float(np.hypot(*(got - c)))
                # (a disc of r px sampled on the field's own rows: its centroid within
                # ~0.1-0.2 px; colour read as centred was 0.4-0.5 rows off per field.
                # Over 1200 draws the colour's median 0.075 px, 99.9 % 0.28, max 0.30 -
                # CI seed 1237331972 drew 0.304: the bound sits between the two)
                assert off < 0.35, (f"seed {seed}, case {case} ({order}): field {f.field}'s "
                                   f"{name} centroid {off:.2f} px from its exposure")


def test_square_pixels_resample_width_only():
    from curltrack.video import _square_pixels

    rng = np.random.default_rng()
    aspect = rng.uniform(0.85, 1.2)
    img = rng.integers(0, 255, (48, 72, 3), dtype=np.uint8)
    out = _square_pixels(aspect)(img)
    assert out.shape == (48, int(round(72 * aspect)), 3), aspect
    assert _square_pixels(1.0)(img) is img


@pytest.mark.slow
def test_dv_pixels_10_11_tracked_in_square_pixels(tmp_path):
    """NTSC DV's 10:11 pixels (SAR in the container): positions right, sigma honest -
    measured in anisotropic pixels every ok row was > 10 mm off."""
    from curltrack.physics.shot import ShotModel as Model
    from curltrack.render import (CameraConfig, EncodingConfig, RenderConfig, SensorConfig,
                                  render_video)
    from curltrack.track import track_video

    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    rig = default_rig()
    sim = simulate_series(Model(v0=rng.uniform(0.35, 0.5), omega0=rng.uniform(0.5, 2.5)),
                          fps=NTSC, tail_s=0.3)
    cfg = RenderConfig(width=720, height=480, fps=NTSC,
                       camera=CameraConfig(pixel_aspect=10 / 11, k1=-0.08),
                       sensor=SensorConfig(scan="interlaced", field_order="bff", chroma="420"),
                       encoding=EncodingConfig(codec="h264", bitrate_bps=4e6))
    truth = render_video(sim, rig, tmp_path / "dv.mp4", tmp_path / "dv.truth.csv", cfg,
                         seed=seed)
    s = track_video(tmp_path / "dv.mp4", rig)
    m = s.data.merge(truth.data, on=["frame", "field"], suffixes=("", "_t"))
    ok = m.ok == 1
    err = np.hypot(m.x - m.x_t, m.y - m.y_t)[ok]
    assert ok.mean() > 0.9, seed
    assert err.max() < 0.010, (seed, err.max())
    assert np.sqrt(np.mean(err ** 2)) < 0.004, seed
    assert any("resampled to square pixels" in w for w in s.meta["warnings"]), seed


def test_interlaced_footage_is_measured_as_its_fields_show_whatever_its_flags(tmp_path):
    """The same woven fields written as a re-encoding leaves them: flagged progressive
    (the interlace flags dropped), flagged interlaced in the right order, or in the
    wrong one: measured per field in the order the content shows, warned about where
    the flags say otherwise, and honest.  Its colour is drawn as a re-encoding leaves
    it: each field's own 4:2:0 rows (planes copied) or subsampled across the woven frame
    by a pixel-format conversion (FFmpeg's: both fields' mean; OpenCV's: the top
    field's); own or shared must be read from the content, flags or none (flagged
    interlaced with shared colour, the flags were trusted for the colour too: a rendered
    camcorder at 1.4 Mbit/s had every row 4-8 mm off under a 1 mm sigma).

    Measured (2026-11-26, 8 draws each): own colour 0.9-1.2 mm RMS, max <= 2.9 mm, as
    the flagged file; FFmpeg's shared colour 0.5-2.8 mm once the fields' mutual pull is
    taken off; OpenCV's 6-13 mm (one field's colour is the other exposure's: both come
    out half the travel between them off).  The two shared kinds are not told apart, so
    sigma_xy takes half that travel, times the share of it by which the fields' markers
    come closer than their luma, for both: honest, and wide for FFmpeg's."""
    from curltrack.track import track_video
    from curltrack.video import probe_video

    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    rig = default_rig()
    top_first = bool(rng.random() < 0.5)
    colour = str(rng.choice(["own", "ffmpeg", "opencv"]))
    flags = str(rng.choice(["none", "right", "reversed"]))
    shared = colour != "own"
    order = "tff" if top_first else "bff"
    truth, video, motion = woven_draw(
        tmp_path, rng, "reencoded.mp4", top_first=top_first, flagged=flags != "none",
        flag_order={"tff": "bff", "bff": "tff"}[order] if flags == "reversed" else None,
        shared_colour={"own": False, "ffmpeg": True, "opencv": "top"}[colour])
    info = probe_video(video)
    what = (f"seed {seed}, {motion}, top first {top_first}, {colour} colour, flags "
            f"{flags}: {info.describe()}")
    assert info.interlaced and info.top_field_first == top_first, what
    assert bool(info.fields_from_content) is (flags == "none"), what
    if flags == "reversed":
        assert f"measured {order}" in info.content_note, what
    # shared colour is never read as the fields' own; own colour is (detected in every
    # draw tried), though the safe reading - shared, sigma wide - is allowed where the
    # content does not show it (test_video: steep pans)
    assert not (shared and info.colour_per_field), what
    read_shared = not info.colour_per_field
    series = track_video(video, rig)
    d = series.data
    assert series.meta.get("fields") is True and len(d) == 2 * info.n_frames, what
    warned = {"none": "flagged progressive", "right": None,
              "reversed": f"measured {order}"}[flags]
    assert warned is None or any(warned in w for w in series.warnings), what
    # shared colour read as such always has its mixing in sigma; colour read as the
    # fields' own only where their markers still show a sure share of the motion
    mixing = any("colour mixes both exposures" in w for w in series.warnings)
    assert mixing or not read_shared, what
    assert read_shared or not mixing or any(
        "of the image's motion between them" in w for w in series.warnings), what
    tr = truth.data.iloc[2 * d.frame.to_numpy() + d.field.to_numpy()]
    ok = d.ok.to_numpy() == 1
    err = np.hypot(d.x.to_numpy() - tr.x.to_numpy(), d.y.to_numpy() - tr.y.to_numpy())[ok]
    assert ok.mean() >= (0.6 if colour == "opencv" else 0.95), f"{what}: ok {ok.mean():.2f}"
    z = err / d.sigma_xy.to_numpy()[ok]
    assert err.max() < (0.04 if colour == "opencv" else 0.01) and z.max() < 5, \
        f"{what}: max {1e3 * err.max():.1f} mm, max error/sigma {z.max():.2f}"
    zr = np.sqrt(np.mean(z ** 2)) / np.sqrt(2)   # per coordinate
    # (FFmpeg's shared colour: 0.06-0.36 - sigma wide, as it must be for OpenCV's, which
    # is half the fields' travel: a ladder's, the rock's own, can leave the markers less
    # off than that - CI seed 1965954739: 2.0 mm under a 4.7 mm sigma, 0.30-0.33)
    # (own colour whose fields' markers still come closer than their luma by a sure share
    # of the motion - x264's quantisation mixing their colour, or shared colour misread -
    # carries that share of the travel, which it cannot tell from a one-sided mixing:
    # wide, as shared colour's - a hand-held own-colour draw, 0.20)
    low = 0.2 if colour == "opencv" else 0.4 if not (read_shared or mixing) else 0.02
    assert low < zr < 1.6, f"{what}: error/sigma RMS {zr:.2f}"


def test_a_progressive_picture_flagged_interlaced_is_measured_as_whole_frames(tmp_path):
    """Progressive frames written with interlace flags (PsF, or a re-encoding that set
    them): its two fields are one exposure.  Measured as two fields timed half a frame
    apart, every other row's time would be a field period off (34 mm at 2 m/s); the
    content shows it (the fields do not move apart as the image moves), so each frame is
    measured whole, at its own time, and the note says why."""
    from curltrack.render import CameraConfig, RenderConfig, render_video
    from curltrack.track import track_video
    from curltrack.video import probe_video

    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    sim = simulate_series(ShotModel(v0=rng.uniform(0.8, 2.0), omega0=rng.uniform(0.5, 2.5)),
                          fps=NTSC)
    sim = replace(sim, data=sim.data.iloc[:60].reset_index(drop=True))
    motion = str(rng.choice(["ladder", "handheld"]))
    prog = tmp_path / "frames.mp4"
    truth = render_video(sim, default_rig(), prog, config=RenderConfig(
        width=720, height=480, fps=NTSC, camera=CameraConfig(motion=motion)),
        seed=int(rng.integers(1 << 30)))
    video = tmp_path / "psf.mp4"
    top_first = bool(rng.random() < 0.5)
    weave_interlaced(prog, video, top_first=top_first, one_exposure=True)
    info = probe_video(video)
    what = f"seed {seed}, {motion}, top first {top_first}: {info.describe()}"
    assert not info.interlaced and "one exposure" in info.content_note, what
    assert info.decoder == "pyav", what
    series = track_video(video, default_rig())
    d = series.data
    assert "field" not in d.columns and len(d) == info.n_frames, what
    assert any("one exposure" in w for w in series.warnings), what
    tr = truth.data.iloc[d.frame.to_numpy()]
    np.testing.assert_allclose(d.t.to_numpy(), tr.t.to_numpy(), atol=2e-4)
    ok = d.ok.to_numpy() == 1
    err = np.hypot(d.x.to_numpy() - tr.x.to_numpy(), d.y.to_numpy() - tr.y.to_numpy())[ok]
    assert ok.mean() >= 0.95 and err.max() < 4e-3, \
        f"{what}: ok {ok.mean():.2f}, max {1e3 * err.max():.1f} mm"


def test_doctor_judges_interlaced_frames_by_their_fields(tmp_path):
    """doctor reads an interlaced video as track does - each frame's first field, with
    the colour it has - whether its flags say so or only its content does (judged as
    woven frames, a re-encoded draw of a moving camera was 'no thread grid in any of 6
    sampled frames: track will fail' while track measured every field)."""
    from curltrack.doctor import diagnose

    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    flagged = bool(rng.random() < 0.5)
    truth, video, motion = woven_draw(tmp_path, rng, "woven.mp4", flagged=flagged,
                                      top_first=bool(rng.random() < 0.5))
    report = diagnose(video, default_rig())
    what = f"seed {seed}, {motion}, flagged {flagged}:\n{report.format()}"
    assert report.ok, what
    assert report.check("grid").status == "ok" and report.check("markers").status == "ok", what
    verdicts = report.check("frames").values["verdicts"]
    assert sum(not v for v in verdicts.values()) >= len(verdicts) - 1, what


def test_a_frame_whose_two_fields_disagree_is_refused():
    """Two fields of a frame are two exposures of one path 1/60 s apart: rows that the
    other field's rows miss by over 5 sigma - a frame split 14-24 sigma apart, each
    field off by half, the series' first frame among them - are found, all but at most
    one in 160 that the noise hides (a row off by s is missed by ~0.75 s: its
    neighbours of the other field include its own frame's partner, off the other way);
    on clean fields (with a systematic offset between
    them, and lost rows) at most one row in 1000."""
    from curltrack.track.results import fields_disagree

    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    false, n_rows, missed = 0, 0, 0
    for _ in range(40):
        t = np.arange(0.0, 6.0, 1 / 59.94)
        field = np.arange(t.size) % 2
        v0, decel = rng.uniform(0.5, 3.0), rng.uniform(0.05, 0.3)
        path = np.column_stack([0.01 * t ** 2, v0 * t - 0.5 * decel * t ** 2])
        sigma = rng.uniform(0.5e-3, 3e-3) * rng.uniform(0.8, 1.2, t.size)
        xy = path + rng.normal(0.0, 1.0, (t.size, 2)) * sigma[:, None]
        xy[field == 1] += rng.normal(0.0, 2e-3, 2)  # (a systematic offset between fields)
        ok = rng.random(t.size) > 0.1
        clean = fields_disagree(t, xy, field, ok, sigma)
        false += int(clean.sum())
        n_rows += int(ok.sum())
        frames = np.r_[0, rng.choice(np.arange(1, t.size // 2), 3, replace=False)]
        split = xy.copy()
        for k in frames:
            size = rng.uniform(14, 24) * sigma[2 * k] * rng.choice([-1, 1])
            split[2 * k, 1] += 0.5 * size
            split[2 * k + 1, 1] -= 0.5 * size
        okk = ok.copy()
        okk[2 * frames] = okk[2 * frames + 1] = True
        found = fields_disagree(t, split, field, okk, sigma)
        missed += int(np.count_nonzero(~(found[2 * frames] | found[2 * frames + 1])))
    assert false <= max(1, n_rows // 1000), (seed, false, n_rows)
    # (a split row's miss is ~0.75 of the split over ~1.2-1.5 of its sigma: a 14 sigma
    # split is found unless the three rows' noise takes 3-4 sigma off it - one of the
    # 160 splits was missed so in 11 of 2699 runs, seed 3215016539 - two, never)
    assert missed <= 1, (seed, missed)


def test_the_fields_pull_follows_the_image_motion_a_shaking_camera_makes():
    """Fields that share their colour are pulled by a share of the image's motion
    between them.  A camera that shakes (a few Hz, random amplitude and direction)
    moves the image faster than the 0.5 s running median follows; given that motion,
    the share is fitted and the pull taken off nearly whole, the old median alone
    leaving most of it."""
    from curltrack.track.results import field_offset_along

    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 8.0, 1 / 59.94)
    field = np.arange(t.size) % 2
    dt_f = 1 / 59.94
    # the rock's motion across the image: a slow part and a shake
    f_hz, amp = rng.uniform(2.0, 6.0), rng.uniform(0.2, 0.6)
    v = np.column_stack([0.1 * np.cos(0.3 * t), 0.05 * np.ones_like(t)]) \
        + amp * np.column_stack([np.sin(2 * np.pi * f_hz * t), rng.uniform(-1, 1)
                                 * np.sin(2 * np.pi * f_hz * t + rng.uniform(0, 6))])
    motion = v * dt_f
    share = rng.uniform(0.3, 0.9)                # field 1 - field 0, in image travels
    pull = -share * motion                       # each field half of it, opposite ways
    sigma = rng.uniform(0.2e-3, 1e-3)
    path = np.column_stack([0.02 * t ** 2, 2.0 * t - 0.05 * t ** 2])
    half = np.where(field == 0, -0.5, 0.5)[:, None]
    xy = path + half * pull + rng.normal(0.0, sigma, (t.size, 2))
    ok = rng.random(t.size) > 0.05
    inner = (t > 0.5) & (t < 7.5)
    fitted = field_offset_along(t, xy, field, ok, motion=motion)
    median_only = field_offset_along(t, xy, field, ok)
    err_fit = np.sqrt(np.mean((fitted - pull)[inner] ** 2))
    err_median = np.sqrt(np.mean((median_only - pull)[inner] ** 2))
    size = np.sqrt(np.mean(pull[inner] ** 2))
    assert err_fit < 0.25 * size + 2 * sigma, (seed, err_fit, size, sigma)
    assert err_median > 0.5 * size, (seed, err_median, size)


def test_image_velocity_is_the_rocks_motion_less_the_cameras():
    """The rock's velocity across the image (ice m/s) from each row's homography: a
    camera that follows the rock at part of its speed leaves the rest, read per field;
    the colour's travel between fields follows that, not the rock's speed on the ice."""
    from curltrack.track.pipeline import FrameRecord
    from curltrack.track.results import colour_mixing_sigma, image_speed, image_velocity

    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 4.0, 1 / 59.94)
    field = np.arange(t.size) % 2
    u_rock = np.array([rng.uniform(1.0, 2.5), rng.uniform(-0.1, 0.1)])
    follow = rng.uniform(0.0, 0.95)           # the camera's share of the rock's speed
    m_px = rng.uniform(0.002, 0.004)          # ice m per image px
    yaw = rng.uniform(0, 2 * np.pi)
    R = np.array([[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]])
    records = []
    for k, tk in enumerate(t):
        cam = follow * u_rock * tk
        H = np.eye(3)
        H[:2, :2] = m_px * R
        H[:2, 2] = cam
        records.append(FrameRecord(frame=k // 2, t=float(tk), field=int(field[k]), H=H,
                                   centre_app=u_rock * tk + rng.normal(0, 1e-5, 2),
                                   m_per_px=m_px))
    ok = np.ones(t.size, bool)
    v = image_velocity(records, t, field, ok)
    want = (1.0 - follow) * u_rock
    assert np.allclose(np.nanmedian(v, axis=0), want, atol=0.02 * np.linalg.norm(u_rock)), \
        (seed, np.nanmedian(v, axis=0), want)
    speed = image_speed(t, v)
    shot = {"x": u_rock[0] * t, "y": u_rock[1] * t, "theta": np.zeros_like(t)}
    on_image, _ = colour_mixing_sigma(t, shot, ok, 0.5 / 29.97, speed)
    on_ice, _ = colour_mixing_sigma(t, shot, ok, 0.5 / 29.97)
    ratio = np.median(on_image) / np.median(on_ice)
    assert abs(ratio - (1.0 - follow)) < 0.05, (seed, ratio, follow)


def test_top_field_colour_is_the_top_fields_exposure():
    """The renderer's ``field_colour="top"``: every colour row is the top field's line
    (a converter that point-samples), so the bottom field is shown in the top field's
    colour; luma stays each line's own."""
    from curltrack.render.encode import top_field_colour_i420

    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    h, w = 2 * int(rng.integers(4, 16)), 2 * int(rng.integers(4, 16))
    img = np.zeros((h, w, 3), np.uint8)
    top, bottom = rng.integers(0, 256, 3), rng.integers(0, 256, 3)
    img[0::2], img[1::2] = top, bottom
    out = top_field_colour_i420(img)
    only_top = top_field_colour_i420(np.repeat(img[0::2], 2, axis=0))
    assert np.array_equal(out[h:], only_top[h:]), seed
    assert not np.array_equal(out[:h], only_top[:h]) or np.array_equal(top, bottom), seed


def test_the_fields_share_of_the_image_motion_and_its_sigma():
    """``field_motion_share``: fields that differ by a share of the image's motion
    between them give that share within 4 of its sigmas (and 5 % for the other field's
    interpolation between its rows); fields that do not give a
    share under 5 sigmas (the rule that moves own-colour fields) in nearly every draw."""
    from curltrack.track.results import field_motion_share, field_share_sure

    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 6.0, 1 / 50.0)
    field = np.arange(t.size) % 2
    ok = rng.random(t.size) > 0.05
    flagged = 0
    for k in range(20):
        f_hz = rng.uniform(0.5, 3.0)   # (a pole's sway; faster, the linear interpolation
        # of the other field between its rows blunts the difference: 0.81 of it at 5 Hz)
        v = np.column_stack([0.3 * np.cos(0.5 * t) + 0.3 * np.sin(2 * np.pi * f_hz * t),
                             0.3 * np.sin(2 * np.pi * f_hz * t + rng.uniform(0, 6))])
        if k % 4 >= 2:   # (a camera panning along the sheet: the image hardly moves
            # across it, and the share across is measured poorly - seed 1145952260)
            v[:, 1] = 0.01 * np.sin(2 * np.pi * f_hz * t + 1.0)
        motion = v / 50.0
        path = np.column_stack([0.01 * t ** 2, 2.0 * t - 0.1 * t ** 2])
        noise = rng.normal(0.0, rng.uniform(0.3e-3, 1e-3), (t.size, 2))
        share = rng.uniform(0.3, 0.6) if k % 2 else 0.0
        half = np.where(field == 0, 0.5, -0.5)[:, None]
        xy = path + half * share * motion + noise
        got, sig = field_motion_share(t, xy, field, ok, motion)
        assert np.all(np.abs(np.diag(got) + share) < 4 * np.diag(sig) + 0.05 * share), \
            (seed, k, share, np.diag(got), np.diag(sig))
        if share == 0.0:
            flagged += field_share_sure(got, sig)
        else:
            assert field_share_sure(got, sig), (
                seed, k, share, f_hz, np.diag(got), np.diag(sig))
    assert flagged == 0, (seed, flagged)


def test_colour_read_as_the_fields_own_but_shared_is_still_in_sigma(tmp_path, monkeypatch):
    """Colour shared by the fields (FFmpeg's mean or OpenCV's top-field lines) that the
    content check reads as each field's own - it can (rendered PAL clips read so: a
    4.5 mm error under a 1.8 mm sigma, e/sigma 2.45).  The fields' markers then come
    closer than their luma by a sure share of the image's motion: each field is moved by
    half of it, and sigma carries the share of the travel a one-sided colour would
    leave in both - no row beyond 5 sigma, error/sigma RMS under 1.6."""
    from curltrack.track import track_video
    from curltrack.video import FieldMotion

    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    colour = str(rng.choice(["ffmpeg", "opencv"]))
    truth, video, motion = woven_draw(tmp_path, rng, "misread.mp4",
                                      shared_colour={"ffmpeg": True, "opencv": "top"}[colour])
    # (the content check's verdict on this stream, forced: what is tested is what
    # follows a wrong one)
    monkeypatch.setattr(FieldMotion, "colour_per_field", property(lambda fm: fm.woven))
    series = track_video(video, default_rig())
    what = f"seed {seed}, {motion}, {colour} colour read as own"
    d = series.data
    tr = truth.data.iloc[2 * d.frame.to_numpy() + d.field.to_numpy()]
    ok = d.ok.to_numpy() == 1
    assert ok.mean() >= 0.6, f"{what}: ok {ok.mean():.2f}"
    err = np.hypot(d.x.to_numpy() - tr.x.to_numpy(), d.y.to_numpy() - tr.y.to_numpy())[ok]
    z = err / d.sigma_xy.to_numpy()[ok]
    zr = np.sqrt(np.mean(z ** 2)) / np.sqrt(2)
    assert z.max() < 5 and zr < 1.6, \
        f"{what}: max {1e3 * err.max():.1f} mm, max error/sigma {z.max():.2f}, RMS {zr:.2f}"
    assert any("colour mixes both exposures" in w for w in series.warnings), what


def test_a_dv_camcorders_file_is_tracked_with_each_fields_own_colour(tmp_path, capfd):
    """A DV camcorder's own file - the paper's "small digital video camera": DV25 in
    QuickTime, NTSC (720x480, 4:1:1, every line its own colour) or PAL (720x576, 4:2:0
    per field), bottom field first, drawn at random with the camera's motion.  Its
    format keeps each field's colour (read so without the content check, which cannot
    see 4:1:1 colour), so sigma carries no colour mixing: read as shared, the two
    rendered clips measured 1.0 and 0.5 mm under a 4-5.5 mm sigma (e/sigma 0.19, 0.06);
    read as their own, 0.84 and 0.79.  What DV's quantisation mixes between the fields
    (their markers 0.9-1.0 of the image's motion closer than their luma) mixes both
    alike, and half their difference takes it off."""
    from curltrack.render import render_video
    from curltrack.render.sweep import draw_setup
    from curltrack.rig import load_rig
    from curltrack.track import track_video
    from curltrack.video import probe_video

    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    setup = draw_setup(rng, "camcorder-dv")
    # (the shot's first 2.2 s: enough rows for the sigma scale, half the render; no
    # broom over the rock, whose hidden frames are refused as they must be)
    shot = replace(setup.shot, data=setup.shot.data[setup.shot.data.t <= 2.2])
    video = tmp_path / "dv.mov"
    truth = render_video(shot, default_rig(), video, seed=setup.seed,
                         config=replace(setup.config, stopped_tail_s=0.0, occlusion=False))
    info = probe_video(video)
    what = f"seed {seed}, {setup.summary}: {info.describe()}"
    assert info.codec_name == "dvvideo" and info.interlaced and not info.top_field_first, what
    assert info.colour_per_field and info.colour_kept.startswith("DV"), what
    capfd.readouterr()
    series = track_video(video, load_rig(video.with_suffix(".rig.toml")),
                         debug_dir=tmp_path / "debug", debug_frames=[3])
    # (OpenCV's FFmpeg printed two lines per frame it read of a DV file, decoded right)
    assert "swscaler" not in capfd.readouterr().err, what
    # (the debug picture of an interlaced frame, two records and two rows: it crashed)
    assert (tmp_path / "debug" / "frame_000003.png").is_file(), what
    assert not any("colour mixes both exposures" in w for w in series.warnings), what
    d = series.data
    tr = truth.data.set_index(["frame", "field"]).loc[list(zip(d.frame, d.field))]
    ok = d.ok.to_numpy() == 1
    # (a pole camera that turns 136 deg/s loses the grid for a while, its shadow and
    # spin blur refuse some more: seed 16 measured 62 %, 79 % since the grid's anchor
    # is extrapolated within each field - the measured share is the sweep's to judge;
    # what is judged here are the measured rows)
    assert ok.mean() >= 0.5, f"{what}: ok {ok.mean():.2f}"
    ex, ey = (d.x.to_numpy() - tr.x.to_numpy())[ok], (d.y.to_numpy() - tr.y.to_numpy())[ok]
    err = np.hypot(ex, ey)
    sig = d.sigma_xy.to_numpy()[ok]
    zr = np.sqrt(np.mean(np.r_[ex / sig, ey / sig] ** 2))
    # (no row over 10 mm or 5 sigma; sigma neither a blanket nor a lie)
    assert err.max() < 0.01 and (err / sig).max() < 5, \
        f"{what}: max {1e3 * err.max():.2f} mm, {(err / sig).max():.1f} sigma"
    # the 2 mm RMS - with the error every row shares, the origin's (a fit to the
    # first rows, extrapolated back to t = 0 where a pole camera's first fields blur the
    # markers past finding: 1.3-1.9 mm of seeds 2176694286 and 2281629374's 1.9-2.3),
    # which the rows' sigma carries
    rms = np.sqrt(np.mean(err ** 2))
    shared = np.array([ex.mean(), ey.mean()])
    assert rms < 2e-3, f"{what}: RMS {1e3 * rms:.2f} mm (shared {1e3 * shared} mm)"
    assert np.all(np.abs(shared) < 3 * np.median(sig)), \
        f"{what}: shared error {1e3 * shared} mm, sigma_xy {1e3 * np.median(sig):.2f} mm"
    assert 0.4 < zr < 1.6, f"{what}: error/sigma RMS {zr:.2f}"
    # theta: the fields' angles differ as their positions do and are mended alike;
    # theta0 read with them apart took their difference for an error persisting in
    # each field (the bench DV clip: sigma_theta 3.1 deg for 0.95 deg errors, e/sigma
    # 0.31; sweep DV clips 0.13-0.19), and a mislocated marker's angle 5 deg off at
    # rest stood in an ok row (left empty now)
    th = ok & np.isfinite(d.theta.to_numpy())
    et, st = (d.theta.to_numpy() - tr.theta.to_numpy())[th], d.sigma_theta.to_numpy()[th]
    assert np.abs(et / st).max() < 5, f"{what}: an angle {np.abs(et / st).max():.1f} sigma off"
    # ... judged apart: theta0's error, which every row shares (SHOT.json's
    # theta0_sigma_rad), and each row's own.  One clip draws theta0's error once: a
    # right sigma of 0.45 deg met an error of 0.03 deg (seed 3710033436), and the rows'
    # e/sigma RMS over the whole sigma read 0.35
    sig0 = series.meta["theta0_sigma_rad"]
    shared = float(np.mean(et))
    assert abs(shared) < 4 * sig0, f"{what}: theta0 {np.degrees(shared):.2f} deg off " \
        f"under {np.degrees(sig0):.2f}"
    own = np.sqrt(np.maximum(st ** 2 - sig0 ** 2, 0.0))
    z_own = np.sqrt(np.mean(((et - shared) / own) ** 2))
    assert 0.4 < z_own < 1.8, f"{what}: theta's own error/sigma RMS {z_own:.2f}"


def test_the_grids_anchor_is_extrapolated_within_each_field():
    """The rock's markers anchor the grid's motion prediction (``_anchor``).  Interlaced,
    the fields' markers differ by more than the rock's motion (DV's colour mixed between
    them: 0.9-1.0 of the image's motion): extrapolated across the two fields that
    difference doubles and alternates in sign, and a pole camera's grid was lost for 70
    of 119 frames (camera sweep seed 2026113001, set-up 7: 34 % measured, 93 % now).
    Within each field the extrapolation is the rock's motion alone."""
    from curltrack.track.pipeline import _anchor

    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    v = rng.uniform(-0.05, 0.05, 2)          # m per field
    offset = rng.uniform(-0.02, 0.02, 2)     # m: field 1's markers against field 0's
    layout = rng.uniform(-0.1, 0.1, (2, 2))
    start = int(rng.integers(0, 50))

    def ice(k):   # marker positions measured in field k % 2 of exposure k
        return layout + v * k + offset * (k % 2)

    hist = [(k, ice(k)) for k in range(start, start + 4)]
    for k in range(start + 4, start + 8):
        px = rng.normal(size=(2, 2))
        got = _anchor(hist, px, k, max_gap=10, per_frame=2)
        assert got[0] is px
        np.testing.assert_allclose(got[1], ice(k), atol=1e-12, err_msg=f"seed {seed}")
        # (progressive: the last two, as before)
        prog = _anchor(hist, px, k, max_gap=10)[1]
        np.testing.assert_allclose(prog, hist[-1][1] + (hist[-1][1] - hist[-2][1]) * (k - hist[-1][0]),
                                   atol=1e-12)
        hist = (hist + [(k, ice(k))])[-4:]
    # one field measured alone after a gap: the last two of any field
    assert _anchor(hist[-2:], px, hist[-1][0] + 1, max_gap=10, per_frame=2) is not None
    assert _anchor(hist[-1:], px, hist[-1][0] + 1, max_gap=10, per_frame=2) is None
    assert _anchor(hist, px, hist[-1][0] + 30, max_gap=10, per_frame=2) is None
