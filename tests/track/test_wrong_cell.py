"""The lattice's cell count is never silently lost.

A fast handheld shot whose lattice is lost for 10-40 frames (the camera's focus hunts:
the frames are blurred so that the thin threads vanish, the markers mostly too) while
camera and rock move fast - many cells pass during the gap.  Every ``ok`` = 1 row must
be right (within 5 sigma and 10 mm of the truth); frames whose cell index the tracker
cannot place are ``ok`` = 0.  (Before the grid's segments were re-anchored on the rock's
path, a gap like this put every later frame 1.2 m off with ``ok`` = 1.)
"""

from dataclasses import replace

import numpy as np
import pytest

from curltrack.errors import TrackingError
from curltrack.physics.shot import ShotModel
from curltrack.rig import default_rig
from curltrack.simulate import simulate_series
from curltrack.track.segments import path_step, resolve_segments


def _defocus(src, dst, first, stop, sigma_px):
    """Copy a video, frames ``first`` .. ``stop - 1`` blurred (Gaussian, ``sigma_px``)."""
    import cv2

    cap = cv2.VideoCapture(str(src))
    fps, w, h = cap.get(cv2.CAP_PROP_FPS), int(cap.get(3)), int(cap.get(4))
    out = cv2.VideoWriter(str(dst), cv2.VideoWriter_fourcc(*"mp4v"), fps, (w, h))
    i = 0
    while True:
        ok, im = cap.read()
        if not ok:
            break
        out.write(cv2.GaussianBlur(im, (0, 0), sigma_px) if first <= i < stop else im)
        i += 1
    out.release()
    cap.release()


def _lost_lattice_case(tmp_path, seed, size=(640, 360), n_frames=90):
    from curltrack.render import CameraConfig, RenderConfig, render_video
    from curltrack.track import track_video

    tmp_path.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    # (a 0.1 m lattice is ~20 px at 640x360: too fine to be found at all)
    sp = float(rng.choice([0.15, 0.2] if size[0] < 900 else [0.1, 0.15, 0.2]))
    rig = replace(default_rig(), spacing_x_m=sp, spacing_y_m=sp)
    v0 = rng.uniform(1.8, 3.0)
    sim = simulate_series(ShotModel(v0=v0, omega0=rng.uniform(0.5, 3.0)), fps=30)
    sim = replace(sim, data=sim.data.iloc[:n_frames].reset_index(drop=True))
    cam = CameraConfig(motion="handheld", height_m=rng.uniform(1.4, 2.2),
                       lag_s=rng.uniform(0.15, 0.35), jitter_m=rng.uniform(0.005, 0.02))
    clean = tmp_path / "clean.mp4"
    truth = render_video(sim, rig, clean, config=RenderConfig(
        camera=cam, width=size[0], height=size[1]), seed=int(rng.integers(1 << 30)))
    gap = int(rng.integers(10, 41))
    first = int(rng.integers(15, n_frames - gap - 10))
    video = tmp_path / "lost.mp4"
    _defocus(clean, video, first, first + gap, rng.uniform(3.0, 6.0))
    what = (f"seed {seed}: spacing {sp} m, v0 {v0:.2f} m/s, lattice lost in frames "
            f"{first}-{first + gap - 1}")
    try:
        series = track_video(video, rig)
    except TrackingError as exc:
        raise _Refused(f"{what}: {exc}") from exc
    m = series.data.merge(truth.data[["frame", "x", "y"]], on="frame", suffixes=("", "_t"))
    return m, what


class _Refused(AssertionError):
    """The tracker refused the clip with a one-line error: no row at all, so no wrong
    row - but nothing about the cell count was tested either."""


#: a case measured in fewer frames tests little of the cell count (it is redrawn)
MIN_MEASURED = 10


def _measurable_case(tmp_path, seed, tries: int = 3):
    """A lost-lattice case the tracker measures in >= :data:`MIN_MEASURED` frames,
    redrawn from ``seed``'s stream when it refuses one or measures fewer (a fast
    hand-held shot over a fine lattice can be all but unmeasurable: 'the rock could be
    measured in only 4 of 90 frames' is an honest answer, and 7 of 90 measured frames
    - seed 405632667, a 0.1 m lattice at 2.78 m/s - another).  Every case drawn is held
    to no wrong row; fails after ``tries`` without a measurable one."""
    seeds = np.random.default_rng(seed).integers(1 << 32, size=tries - 1)
    refused = []
    for s in [seed, *map(int, seeds)]:
        try:
            m, what = _lost_lattice_case(tmp_path / str(s), s, size=(960, 540))
        except _Refused as exc:
            refused.append(str(exc))
            continue
        _check_no_wrong_row(m, what)
        if (m["ok"] == 1).sum() >= MIN_MEASURED:
            return m, what
        refused.append(f"{what}: only {int((m['ok'] == 1).sum())} frames measured")
    raise AssertionError(f"no case measurable: {refused}")


def _check_no_wrong_row(m, what):
    # (how many rows are measured is _measurable_case's to judge: a case measured in
    # too few is redrawn there - asserted here, it failed before the redraw, seed
    # 3928683759: 6 of 90 frames measured, none wrong)
    ok = m["ok"] == 1
    err = np.hypot(m.x - m.x_t, m.y - m.y_t)
    bad = ok & ((err > 0.010) | (err > 5 * m.sigma_xy))
    assert not bad.any(), (f"{what}: {int(bad.sum())} ok rows wrong, frames "
                           f"{list(m.frame[bad])[:8]}, errors up to {1e3 * err[bad].max():.0f} mm")


def test_lattice_lost_while_moving_fast_no_wrong_cell(tmp_path):
    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    # (at 640x360 a fast handheld shot is often not measurable at all - an error, not a
    # wrong row - and then tests nothing)
    _check_no_wrong_row(*_measurable_case(tmp_path, seed))


@pytest.mark.slow
@pytest.mark.parametrize("rep", range(6))
def test_lattice_lost_while_moving_fast_no_wrong_cell_many(tmp_path, rep):
    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    _check_no_wrong_row(*_measurable_case(tmp_path, seed))


def test_path_step_measures_a_whole_cell_jump():
    """A segment put 3 cells off across a 1 s gap is moved back; one with too little
    evidence stays unresolved (never guessed)."""
    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    sim = simulate_series(ShotModel(v0=rng.uniform(1.5, 3.0), omega0=rng.uniform(0.5, 2.5)),
                          fps=30).data
    t = sim.t.to_numpy()[:150]
    p = sim[["x", "y"]].to_numpy()[:150] + rng.normal(0, 0.7e-3, (150, 2))
    seg = np.r_[np.zeros(40, int), np.ones(110, int)]
    ok = np.ones(150, bool)
    ok[40:70] = False  # the gap
    s = (0.15, 0.15)
    moved = p.copy()
    moved[70:] += (0.45, -0.15)
    step, sigma = path_step(t[:40], p[:40], t[70:100], moved[70:100])
    assert np.all(np.abs(step - (0.45, -0.15)) < 4 * sigma + 1e-3), f"seed {seed}"
    shift, unresolved, notes = resolve_segments(t, moved, seg, ok, s)
    # the longer segment is the reference: the first one moves by the opposite
    assert np.allclose(shift[:40], (0.45, -0.15)) and not unresolved.any(), f"seed {seed}"
    assert notes
    # a segment of 3 frames is not placed
    seg2 = seg.copy()
    seg2[70:73] = 2
    shift, unresolved, _ = resolve_segments(t, moved, seg2, ok, s)
    assert unresolved[70:73].all() and not unresolved[73:].any(), f"seed {seed}"


def _short_first_segment(rng, n_seg_range, gap_range):
    """A 60 fps shot's first 2 s with 0.5-1.5 mm noise, a short first grid segment
    (``n_seg_range`` frames), then a gap (``gap_range`` frames) and the second:
    ``(t, p, noise, n_seg, seg, ok)``."""
    sim = simulate_series(ShotModel(v0=rng.uniform(1.5, 3.0), omega0=rng.uniform(0.5, 2.5)),
                          fps=60).data
    t = sim.t.to_numpy()[:120]
    noise = rng.uniform(0.5e-3, 1.5e-3)
    p = sim[["x", "y"]].to_numpy()[:120] + rng.normal(0, noise, (120, 2))
    n_seg = int(rng.integers(*n_seg_range))
    seg = np.r_[np.zeros(n_seg, int), np.ones(120 - n_seg, int)]
    ok = np.ones(120, bool)
    ok[n_seg:n_seg + int(rng.integers(*gap_range))] = False   # the gap
    return t, p, noise, n_seg, seg, ok


def test_a_segment_whose_rows_scatter_is_not_placed():
    """A short segment before a gap whose rows scatter by centimetres about the path
    (a lattice that was not right, not one off by whole cells) stays unresolved, however
    close its mean lies to a whole cell, and is never placed at a wrong cell; the same
    rows with the reference's noise, or 3-4 times it (still a small part of a cell), are
    placed.  Over 10 draws: 4-8 rows test their scatter only roughly (400 draws: one
    noisier side not placed, one scattering side placed - at its right cells), so one
    draw of each may go the other way."""
    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    s = (0.15, 0.15)
    noisy_refused, wild_placed = 0, 0
    for _ in range(10):
        t, p, noise, n_seg, seg, ok = _short_first_segment(rng, (4, 9), (5, 15))
        cells = rng.integers(-2, 3, 2) * 0.15
        clean = p.copy()
        clean[:n_seg] += cells
        shift, unresolved, _ = resolve_segments(t, clean, seg, ok, s)
        assert not unresolved.any() and np.allclose(shift[:n_seg], -cells), f"seed {seed}"
        # rows noisier than the reference's but a small part of a cell (a hand-held
        # clip's side after a loss: 2.2 mm against 1.1 mm) are a right lattice: placed
        noisy = clean.copy()
        noisy[:n_seg] += rng.normal(0, rng.uniform(3.0, 4.0) * noise, (n_seg, 2))
        shift, unresolved, _ = resolve_segments(t, noisy, seg, ok, s)
        placed = not unresolved.any()
        assert not placed or np.allclose(shift[:n_seg], -cells), f"seed {seed}"
        noisy_refused += not placed
        wild = clean.copy()
        wild[:n_seg] += rng.normal(0, rng.uniform(0.02, 0.05), (n_seg, 2))
        wild[:n_seg] -= wild[:n_seg].mean(axis=0) - clean[:n_seg].mean(axis=0)  # mean kept
        shift, unresolved, _ = resolve_segments(t, wild, seg, ok, s)
        placed = not unresolved[:n_seg].all()
        assert not placed or np.allclose(shift[:n_seg], -cells), \
            f"seed {seed}: placed at a wrong cell {shift[0]}"
        wild_placed += placed
    assert noisy_refused <= 1, f"seed {seed}: noisier rows not placed in {noisy_refused} of 10"
    assert wild_placed <= 1, f"seed {seed}: scattering rows placed in {wild_placed} of 10"


def test_a_placed_segment_off_the_path_by_millimetres_is_named():
    """A short first segment placed in whole cells whose path still misses by 8-20
    noise sigmas (a lattice 5-15 mm off the reference's, within the quarter cell the
    placement allows: a phone's first 5 frames, 12.4 +- 2.8 mm, bent every row by 13 mm
    through the origin) comes back as ``misfit``; the same segment with only its noise
    has none, in all but a few draws (3 sigma: under 1 % per coordinate)."""
    from curltrack.track.segments import MISFIT_Z

    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    s = (0.15, 0.15)
    false = 0
    for _ in range(20):
        t, p, noise, n_seg, seg, ok = _short_first_segment(rng, (5, 12), (5, 12))
        cells = rng.integers(-2, 3, 2) * 0.15
        clean = p.copy()
        clean[:n_seg] += cells
        _, _, _, miss = resolve_segments(t, clean, seg, ok, s, misfit=True)
        false += bool(miss.any())
        a = rng.uniform(0, 2 * np.pi)
        size = rng.uniform(5e-3, 15e-3)
        off = clean.copy()
        off[:n_seg] += size * np.array([np.cos(a), np.sin(a)])
        step, sigma = path_step(t[n_seg:][ok[n_seg:]][:60], off[n_seg:][ok[n_seg:]][:60],
                                t[:n_seg], off[:n_seg])
        if np.max(size * np.abs([np.cos(a), np.sin(a)]) / sigma) < 2 * MISFIT_Z:
            continue   # (too few rows to tell it: not asked of it)
        shift, unresolved, _, miss = resolve_segments(t, off, seg, ok, s, misfit=True)
        assert not unresolved.any() and np.allclose(shift[:n_seg], -cells), f"seed {seed}"
        assert miss[:n_seg].any(axis=1).all() and not miss[n_seg:].any(), \
            f"seed {seed}: {1e3 * size:.1f} mm off, misfit {miss[0]}"
    assert false <= 2, f"seed {seed}: {false} of 20 clean segments called off the path"


def _records_on_two_lattices(rng, gap_s, first_s, placeable):
    """Records of a 30 fps shot whose grid is lost for ``gap_s`` after ``first_s``: a
    first segment, then a second one whole cells off (or, unless ``placeable``, off by a
    fraction of a cell too, which the rock's path cannot place)."""
    from curltrack.track.pipeline import FrameRecord

    sim = simulate_series(ShotModel(v0=rng.uniform(1.0, 2.5), omega0=rng.uniform(0.5, 2.5)),
                          fps=30).data
    n = min(len(sim), 150)
    t = sim.t.to_numpy()[:n]
    p = sim[["x", "y"]].to_numpy()[:n] + rng.normal(0, 0.7e-3, (n, 2))
    a, b = int(round(first_s * 30)), int(round((first_s + gap_s) * 30))
    off = rng.integers(-2, 3, 2) * 0.15 + (0 if placeable else rng.uniform(0.04, 0.07, 2))
    records = []
    for i in range(n):
        seg = 0 if i < a else 1
        r = FrameRecord(int(i), float(t[i]), status="" if (i < a or i >= b) else "grid: lost")
        r.segment, r.H = seg, np.eye(3)
        r.centre_app = p[i] + (off if seg else 0)
        records.append(r)
    ok = np.array([r.status == "" for r in records])
    centre = np.array([r.centre_app for r in records])
    centre[~ok] = np.nan
    return records, t, centre, ok, a, b


def test_the_release_segment_is_kept_when_the_origin_cannot_be_extrapolated():
    """The grid lost for 0.7-1.2 s after the first 1.0-1.3 s, the later lattice not
    placeable: the release's segment gives the origin and the later frames are ok = 0
    with a note naming --start-frame (not the whole video refused, nor its later frames
    taken as the reference with an origin extrapolated back over seconds).  With the
    first segment too short for an origin of its own, the largest stays the reference."""
    from types import SimpleNamespace

    from curltrack.settings import TrackingSettings
    from curltrack.track.results import _resolve_cells

    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    calib = SimpleNamespace(spacing_x_m=0.15, spacing_y_m=0.15)
    st = TrackingSettings()
    records, t, centre, ok, a, b = _records_on_two_lattices(
        rng, rng.uniform(0.7, 1.2), rng.uniform(1.0, 1.3), placeable=False)
    warnings = []
    idx = _resolve_cells(records, t, centre, ok, calib, warnings, "v.mp4", st)
    assert idx[0] == 0 and idx[-1] == a - 1, f"seed {seed}: kept {idx[0]}-{idx[-1]}"
    assert all("cell index not certain" in r.status for r in records[b:]), f"seed {seed}"
    assert any(f"--start-frame {b}" in w for w in warnings), f"seed {seed}: {warnings}"
    # a first segment of 5 frames cannot give the origin: the largest is the reference
    records, t, centre, ok, a, b = _records_on_two_lattices(
        rng, rng.uniform(0.7, 1.2), 5 / 30, placeable=False)
    idx = _resolve_cells(records, t, centre, ok, calib, [], "v.mp4", st)
    assert idx[0] == b and not ok[:a].any(), f"seed {seed}: kept from {idx[0]}"
    # a placeable later lattice is placed, whichever is the reference
    records, t, centre, ok, a, b = _records_on_two_lattices(
        rng, rng.uniform(0.3, 0.6), rng.uniform(1.0, 1.3), placeable=True)
    idx = _resolve_cells(records, t, centre, ok, calib, [], "v.mp4", st)
    assert len(idx) == a + len(t) - b, f"seed {seed}"


def test_an_origin_is_placed_without_its_grossly_wrong_first_rows():
    """A shot (the simulator's, 25-60 fps, first measured 0.1-0.3 s after release)
    whose first 1-3 measured rows are 8-30 cm off the rest (lattice poses fitted wrong
    while the grid was barely followed: a 0.39 Mbit/s camcorder's first fields, which
    refused the whole clip): those rows are left out and the origin is placed from the
    others, its error over its sigma as the clean shot's (per coordinate: RMS 1.01 with
    every row, 0.97 without the left-out ones, 200 draws).  A clean shot keeps every
    row."""
    from curltrack.settings import TrackingSettings
    from curltrack.track.results import place_origin
    from curltrack.track.shotframe import to_shot_frame

    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    st = TrackingSettings()
    gross = st.ambiguous_cells * 0.15
    z = []
    for _ in range(20):
        fps = float(rng.choice([25.0, 30.0, 50.0, 59.94]))
        sim = simulate_series(ShotModel(v0=rng.uniform(1.0, 2.5), omega0=rng.uniform(0.5, 2.5)),
                              fps=fps).data
        n = min(len(sim), int(5 * fps))
        t = sim.t.to_numpy()[:n]
        true = sim[["x", "y"]].to_numpy()[:n]
        phi = sim.theta.to_numpy()[:n]
        sigma = np.full(n, rng.uniform(0.5e-3, 3e-3))
        centre = true + rng.normal(0, 1.0, (n, 2)) * sigma[:, None]
        ok = np.ones(n, bool)
        ok[:int(rng.uniform(0.1, 0.3) * fps)] = False   # the first 0.1-0.3 s not measured
        first = np.flatnonzero(ok)[0]

        def shot_frame(ok):
            return to_shot_frame(t, centre, phi, ok, sigma=sigma)

        kept, _, left = place_origin(shot_frame, t, centre, ok, sigma, st.max_origin_sigma_m,
                                     gross)
        assert not left.size and (kept == ok).all(), f"seed {seed}: clean rows {left} left out"
        k = int(rng.integers(1, 4))
        wrong = first + np.sort(rng.choice(np.arange(int(0.2 * fps)), k, replace=False))
        a = rng.uniform(0, 2 * np.pi)
        centre[wrong] += rng.uniform(0.08, 0.3) * np.array([np.cos(a), np.sin(a)])
        kept, shot, left = place_origin(shot_frame, t, centre, ok, sigma, st.max_origin_sigma_m,
                                        gross)
        assert set(left) == set(wrong) and not kept[wrong].any(), \
            f"seed {seed}: left out {left}, wrong {wrong}"
        # (its sigma per coordinate with what its first rows share, as build_series
        # gives every row)
        sig = np.hypot(shot["origin_sigma_m"], shot["origin_check_sigma_m"])
        z.append(np.linalg.norm(shot["origin"] - true[0]) / sig / np.sqrt(2))
        assert z[-1] < 5, f"seed {seed}: origin {z[-1]:.1f} sigma off"
    rms = float(np.sqrt(np.mean(np.square(z))))
    assert rms < 1.5, f"seed {seed}: origin error / sigma RMS {rms:.2f}"
