"""The rules that keep a strong real effect from being judged by its own misfit.

* the look-elsewhere bootstrap's blocks come from the residuals the candidate's best
  linear fit leaves (a strong effect's misfit otherwise reads as noise that persists for
  seconds, and blocks that long put the misfit itself into the null);
* a held-out RMS a little above the baseline's blocks a name only when it is worse
  consistently over the held-out folds, not in one extrapolated block;
* a candidate predicts better when its folds do, relatively, not when the pooled RMS
  (ruled by the fold extrapolated back to the release) drops.
"""

import numpy as np
import pytest

from curltrack.discover.model import JointModel
from curltrack.discover.search import (block_lengths, heldout_log_ratio, heldout_worse_p,
                                       null_noise, residual_noise)
from curltrack.discover.shots import shot_from_series
from discover._synth import make_case


def _units(values):
    return {"units": {"y": np.asarray(values, float)}}


def test_heldout_worse_needs_consistent_folds():
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    before = rng.uniform(3e-6, 5e-6, 5)
    # one extrapolated fold far off, the rest as before (+- 2 %): not significant
    one_fold = before * rng.uniform(0.98, 1.02, 5)
    one_fold[int(rng.integers(5))] *= 1.6
    assert heldout_worse_p(_units(before), _units(one_fold), "y") > 0.05, seed
    # every fold 20-40 % worse: significant
    worse = before * rng.uniform(1.2, 1.4, 5)
    assert heldout_worse_p(_units(before), _units(worse), "y") < 0.01, seed
    # better is never worse
    assert heldout_worse_p(_units(before), _units(before * 0.8), "y") > 0.5, seed
    # too few units to test: nan (the ratio rule alone decides)
    assert np.isnan(heldout_worse_p(_units(before[:2]), _units(worse[:2]), "y"))


def test_heldout_gain_is_not_ruled_by_one_fold():
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    before = {"units": {"x": rng.uniform(30, 200, 5), "y": rng.uniform(3, 6, 5)}}
    # the candidate explains the later folds; the first, extrapolated back to the
    # release and far off for both, gets a little worse and rules the pooled RMS
    after = {"units": {"x": before["units"]["x"] * rng.uniform(0.05, 0.2, 5),
                       "y": before["units"]["y"] * rng.uniform(0.95, 1.05, 5)}}
    gained = float(np.sum(before["units"]["x"][1:] - after["units"]["x"][1:]))
    before["units"]["x"][0] = 1000.0
    after["units"]["x"][0] = 1000.0 + gained * rng.uniform(1.1, 2.0)
    pooled = [np.mean(np.concatenate(list(h["units"].values()))) for h in (before, after)]
    assert pooled[1] > pooled[0], seed          # the premise: pooled, it looks worse
    assert heldout_log_ratio(before, after) < 0, seed
    # a candidate that only adds scatter to every fold does not predict better
    noisy = {"units": {c: v * rng.uniform(1.0, 1.3, v.size) for c, v in before["units"].items()}}
    assert heldout_log_ratio(before, noisy) > 0, seed


def _clean_fit_and_misfit():
    """A clean shot's baseline fit and a smooth misfit's column in one random segment
    (the whole shot, wavering every 7-12 s): (seed, rng, model, fit, segment, column)."""
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    series, _ = make_case("none", 0.0, rng)
    shots = [shot_from_series(s) for s in series]
    base = JointModel(shots, "paper")
    fit0 = base.fit(max_nfev=80)
    j, c, sl = base.segments[int(rng.integers(len(base.segments)))]
    t = shots[j].t[shots[j].use[c]]
    col = np.zeros(fit0.n)
    col[sl] = np.sin(2 * np.pi * t / rng.uniform(7.0, 12.0) + rng.uniform(0, 2 * np.pi))
    return seed, rng, base, fit0, (j, c, sl), col


def test_blocks_come_from_what_the_candidate_leaves():
    """A smooth misfit of random size, phase and period in one coordinate (a strong
    effect the baseline could not fit) reads as noise persisting for seconds: blocks that long would
    put the misfit itself into the null.  Taken out by the candidate's columns, the
    residuals are the noise again, and so are the blocks."""
    from curltrack.discover.scoring import BLOCK_FRAMES

    seed, rng, base, fit0, (j, c, sl), col = _clean_fit_and_misfit()
    col /= np.linalg.norm(col)
    misfit = fit0.r + rng.uniform(100, 300) * col
    clean = [b for _, b in block_lengths(base, residual_noise(base, fit0.r, pool=False))]
    # white noise: short blocks (3 correlation times of ~1 frame, at least BLOCK_FRAMES;
    # the estimate of tau scatters: 11 frames seen, CI seed 688088531)
    assert max(clean) <= 2 * BLOCK_FRAMES, (seed, clean)
    own = [b for _, b in block_lengths(base, residual_noise(base, misfit, pool=False))]
    # (270 frames, the whole segment, in 12 of 12 draws)
    assert own[base.segments.index((j, c, sl))] > 5 * max(clean), (seed, c, own)
    # the candidate's columns take the misfit out: the noise's own blocks again (up to
    # a frame: one direction fewer in the residuals moves tau a little)
    left = misfit - col * (col @ misfit)
    again = [b for _, b in null_noise(base, misfit, left)[0]]
    assert np.abs(np.subtract(again, clean)).max() <= 1, (seed, again, clean)
    # with nothing taken out, the blocks are the baseline's own
    assert [b for _, b in null_noise(base, misfit, misfit)[0]] == own


def test_null_noise_resamples_what_the_candidate_leaves_of_a_misfit():
    """The same smooth misfit, taken out by the candidate's columns: the bootstrap then
    resamples the white residuals left (the misfit itself would make a null that grows
    with the effect), and its threshold is the clean data's within the bootstrap's
    scatter.  Columns that take nothing out leave the baseline's residuals in place."""
    from curltrack.discover.scoring import bootstrap_threshold, effect_bases
    from curltrack.series.noise import CORRELATED_TAU

    seed, rng, base, fit0, (j, c, sl), col = _clean_fit_and_misfit()
    col = effect_bases(fit0.J, [col[:, None]])[0][:, 0]
    r0 = fit0.r - col * (col @ fit0.r)          # clean noise, nothing along the misfit
    misfit = r0 + rng.uniform(100, 300) * col
    r_alt = misfit - col * (col @ misfit)
    blocks, r_null = null_noise(base, misfit, r_alt)
    i = base.segments.index((j, c, sl))
    if residual_noise(base, r_alt, pool=False)[i][1] > CORRELATED_TAU:
        # white noise whose few windows read as persisting (~1 draw in 8): the rule
        # cannot tell it from an instrument's and keeps the conservative null
        assert np.array_equal(r_null[sl], misfit[sl]), seed
        return
    assert np.array_equal(r_null[sl], r_alt[sl]), seed
    # a scan of short bumps across the segment: thresholds from the two noises
    idx = np.flatnonzero(np.arange(fit0.n) >= sl.start)[: sl.stop - sl.start]
    cols = []
    for k in range(0, idx.size - 20, 10):
        e = np.zeros((fit0.n, 1))
        e[idx[k:k + 20], 0] = 1.0
        cols.append(e)
    bases = effect_bases(fit0.J, cols)

    def thr(r):
        return bootstrap_threshold(bases, r, blocks, 1, fit0.n, np.random.default_rng(seed),
                                   n_boot=300)["threshold"]
    assert abs(thr(r_null) - thr(r0)) < 5.0, (seed, thr(r_null), thr(r0))
    assert thr(misfit) > thr(r0) + 20, (seed, thr(misfit), thr(r0))
    # nothing taken out: the baseline's residuals stay
    _, kept = null_noise(base, misfit, misfit)
    assert np.array_equal(kept, misfit), seed


def _session(rng, classes):
    """A clean session at 10 Hz, position only, one shot per entry of ``classes`` (a
    noise class each, at its typical scale): its model, baseline fit and shots."""
    from curltrack.instrument import TYPICAL_SCALE, Sampling, session_models
    from curltrack.physics import ShotModel
    from curltrack.simulate import simulate_series

    base = ShotModel(v0=rng.uniform(1.4, 2.2), omega0=rng.choice([-1, 1]) * rng.uniform(0.8, 3))
    series = [simulate_series(m, noise_m=TYPICAL_SCALE[c][0], noise_rad=TYPICAL_SCALE[c][1],
                              noise_class=c, seed=int(rng.integers(1 << 30)),
                              theta_measured=False, sampling=Sampling(rate_hz=10.0))
              for m, c in zip(session_models(base, len(classes), rng), classes)]
    model = JointModel([shot_from_series(s) for s in series], "paper")
    return model, model.fit(max_nfev=80)


@pytest.mark.parametrize("odd_one, crowd", [("white", "steps"), ("steps", "white")])
def test_one_instrument_one_noise_in_a_session(odd_one, crowd):
    """The shots of one analysis come from one instrument.  Seven shots under one noise
    class and one (at a random place) under the other: the odd shot is judged as the
    crowd's noise - a white shot among step-noise shots gets their persistence (long
    bootstrap blocks, no white-noise tests, at least their median long-scale level),
    a step-noise shot among white ones keeps its own.  (Each step-noise shot shows its
    persistence by itself ~7 times in 8, a white one passes for white as often: the
    crowd's majority is wrong < 1 % of the time.)"""
    from curltrack.discover.scoring import BLOCK_FRAMES
    from curltrack.series.noise import CORRELATED_TAU, HIGHPASS_S

    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    odd = int(rng.integers(8))
    classes = [odd_one if i == odd else crowd for i in range(8)]
    model, fit0 = _session(rng, classes)
    own = residual_noise(model, fit0.r, pool=False)
    pooled = residual_noise(model, fit0.r)
    blocks = [b for _, b in block_lengths(model, own)]
    odd_segments = [i for i, (j, _, _) in enumerate(model.segments) if j == odd]
    long_block = round(HIGHPASS_S / 0.1)
    if crowd == "steps":
        for i in odd_segments:
            c = model.segments[i][1]
            level = np.median([own[k][0] for k, s in enumerate(model.segments) if s[1] == c])
            assert pooled[i][1] > CORRELATED_TAU, (seed, odd, pooled[i])
            assert pooled[i][0] >= level - 1e-9, (seed, odd, c, pooled[i], level)
            assert blocks[i] >= long_block, (seed, odd, blocks)
    else:
        for i in odd_segments:   # its own values, per-shot pooling only
            assert pooled[i][0] == own[i][0], (seed, odd, pooled[i], own[i])
        # the crowd keeps its own blocks (>= 3 of its own tau, BLOCK_FRAMES at least),
        # not the persisting noise's: one white segment in ~20 measures tau ~3.5-3.9 by
        # chance, and 3 tau then passes BLOCK_FRAMES (seeds 2348966391, 228351140)
        crowd_segments = [i for i in range(len(blocks)) if i not in odd_segments]
        assert all(blocks[i] < long_block for i in crowd_segments), (seed, odd, blocks)
        assert all(blocks[i] == max(BLOCK_FRAMES, int(np.ceil(3 * own[i][1])))
                   for i in crowd_segments), (seed, odd, blocks)


def test_theta_persists_with_its_shots_positions():
    """x, y and theta of a shot are one instrument's: where its position noise persists
    (flagged by either coordinate's own evidence) its theta is held to persisting noise
    too - theta alone is one segment of ~7 windows, and step-like errors in it passed
    for white noise (a clean 10 Hz shot named 'unexplained' by theta's binned means).
    A shot whose positions do not persist keeps theta's own evidence."""
    from curltrack.discover.search import _instrument_wide
    from curltrack.instrument import Sampling
    from curltrack.physics import ShotModel
    from curltrack.simulate import simulate_series

    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    series = [simulate_series(ShotModel(v0=rng.uniform(1.4, 2.2), omega0=rng.uniform(0.8, 3)),
                              noise_m=0.002, noise_rad=0.005, seed=int(rng.integers(1 << 30)),
                              sampling=Sampling(rate_hz=10.0)) for _ in range(2)]
    model = JointModel([shot_from_series(s) for s in series], "paper")
    coord = str(rng.choice(["x", "y"]))
    out, session = _instrument_wide(model, {(0, coord)})
    assert {(0, "x"), (0, "y"), (0, "theta")} <= out, (seed, coord, out)
    assert not any(j == 1 for j, _ in out) and not session, (seed, out, session)
    out, _ = _instrument_wide(model, {(1, "theta")})
    assert out == {(1, "theta")}, (seed, out)


def test_a_baseline_at_its_bound_is_never_none():
    """A shot whose curl goes against its spin (x mirrored: an image's axes) holds the
    baseline's a_T at its bound 0 with ~10 cm residuals in x.  The persisting-noise
    scale reads those as the instrument's, so nothing is 'structured' - but a baseline
    that cannot describe the shot is 'unexplained', with the bound, never 'none'."""
    from dataclasses import replace

    from curltrack.discover import discover
    from curltrack.physics import ShotModel
    from curltrack.simulate import simulate_series

    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    s = simulate_series(ShotModel(v0=rng.uniform(1.6, 2.2),
                                  omega0=rng.choice([-1, 1]) * rng.uniform(1.0, 2.5)),
                        noise_m=0.002, noise_rad=0.005, seed=int(rng.integers(1 << 30)))
    d = s.data.copy()
    d["x"] = -d["x"]
    rep = discover([replace(s, data=d)], n_boot=100, seed=1)
    assert rep["verdict"] == "unexplained", (seed, rep["verdict"])
    assert rep["unexplained"]["baseline_at_bound"], seed
    assert any("curl the way they spin" in w for w in rep["warnings"]), seed


def test_a_finding_resting_on_a_few_rows_is_not_named():
    """A tracker's first rows after the release are often off together (the rock still in
    the hand's shadow, the origin extrapolated to them): 2-3 rows 5-9 sigma off, fading.
    A 'pick' just before them fits them away; the bootstrap, which resamples the noise
    as if the same everywhere, let it clear its threshold in 11 of 40 such clean shots
    (and in 5 of 8 picks on clean shots tracked through real cameras).  Judged by its
    gain without the rows that carry most of it, against the same statistic of the null,
    it is not named - while the few-rows statistic itself is right: a mid-shot pick's
    gain is spread over the rows after it.  (Without them the baseline is refitted too:
    CI seed 4124883414 drew rows 8.5, 5.7, 2.8 sigma off, and a pick at 0.15 s, which let
    the baseline's parameters return, gained chi-square 9.6 on the other rows.)"""
    from dataclasses import replace

    from curltrack.discover import discover
    from curltrack.discover.scoring import FEW_ROWS, without_few_rows
    from discover._synth import NOISE_M, draw_model, make_series

    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    share = rng.normal(0.0, 1.0, 200)
    top = np.sort(share)[::-1][:FEW_ROWS]
    assert np.isclose(without_few_rows(share), share.sum() - top[top > 0].sum()), seed
    assert np.allclose(without_few_rows(np.stack([share, -share], 1)),
                       [without_few_rows(share), without_few_rows(-share)]), seed

    named = []
    for _ in range(10):
        s = make_series(draw_model(rng), rng=rng)
        d = s.data.copy()
        rows = d.index[(d.ok == 1) & (d.t > 0)][: int(rng.integers(2, 4))]
        size, angle = rng.uniform(5, 9) * NOISE_M, rng.uniform(0, 2 * np.pi)
        for j, row in enumerate(rows):
            d.loc[row, "x"] += size * np.cos(angle) * (1 - j / 3)
            d.loc[row, "y"] += size * np.sin(angle) * (1 - j / 3)
        rep = discover([replace(s, data=d)], seed=int(rng.integers(1 << 30)))
        refitted = [f for f in rep.summary()["findings"] if "structure_after" in f]
        # (REPORT.json says what each refitted candidate's evidence is without them)
        assert all(np.isfinite(f["delta_bic_without_few_rows"]) for f in refitted), seed
        if rep["verdict"] == "pick":
            named.append(rep.summary()["findings"][0]["params"]["t_s"])
    assert not named, (seed, named)


def test_the_baseline_is_refitted_without_the_few_rows():
    """Rows far off pull the baseline's fit, and a candidate that takes them away gains
    on the other rows too: that gain is the few rows' as well.  ``top_rows`` finds the
    rows (x, y, theta of a frame, in any order of the residuals) that carry most of a
    gain, and ``refit_gain_without`` is the baseline's linear refit without them, as a
    direct least-squares solve gives it - for one residual vector and for a batch."""
    from curltrack.discover.scoring import orth_basis, refit_gain_without, top_rows

    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    n_rows, p, B = int(rng.integers(20, 200)), int(rng.integers(1, 8)), 12
    per_row = rng.integers(1, 4, n_rows)                     # theta measured or not
    groups = rng.permutation(np.repeat(np.arange(n_rows), per_row))
    n = groups.size
    J = rng.normal(size=(n, p)) * rng.uniform(0.1, 10, p)
    Q = orth_basis(J)
    r = rng.normal(size=(n, B))
    r -= Q @ (Q.T @ r)
    share = rng.normal(size=(n, B))
    rows = top_rows(share, groups)
    gain = refit_gain_without(Q, r, rows)
    for j in range(B):
        sums = np.bincount(groups, share[:, j], minlength=n_rows)
        best = np.argsort(-sums)[:3]
        left = rows[j][rows[j] >= 0]
        assert set(groups[left]) == set(best[sums[best] > 0]), seed
        assert np.array_equal(np.sort(left), np.flatnonzero(np.isin(groups, groups[left]))), seed
        keep = np.ones(n, bool)
        keep[left] = False
        b = np.linalg.lstsq(J[keep], r[keep, j], rcond=None)[0]
        direct = np.sum(r[keep, j] ** 2) - np.sum((r[keep, j] - J[keep] @ b) ** 2)
        assert np.isclose(gain[j], direct, rtol=1e-7, atol=1e-9), (seed, j, gain[j], direct)
        assert np.isclose(refit_gain_without(Q, r[:, j], top_rows(share[:, j], groups)),
                          gain[j]), seed


def test_a_change_within_the_stated_errors_of_persisting_noise_is_not_supported():
    """Where every coordinate's instrument says its errors persist and states its rows'
    sigma (a tracker), a candidate that moves the fitted path by no more than
    STATED_Z of those sigma is not told from them; one that moves it further is, and
    where any coordinate states nothing (or its noise does not persist) the rule is
    silent.  (Clean shots tracked through real cameras: picks fitted a 0.5-2 mm wander
    under stated sigma of 0.9-5 mm.)"""
    from types import SimpleNamespace

    from curltrack.discover.search import STATED_Z, CandidateScore, _judge_stated

    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    n = int(rng.integers(60, 200))
    sigma = float(rng.uniform(0.5e-3, 5e-3))
    use = np.ones(n, bool)
    shot = SimpleNamespace(use={"x": use, "y": use}, noise_persists=True,
                           stated_sigma={"x": np.full(n, sigma), "y": np.full(n, sigma)})
    base = SimpleNamespace(shots=[shot], segments=[(0, "x", slice(0, n)),
                                                    (0, "y", slice(n, 2 * n))])
    r0 = rng.normal(0, sigma, 2 * n)

    def judged(z, shot_kw=None):
        change = np.zeros(2 * n)
        change[n + int(rng.integers(n))] = z * sigma * rng.choice([-1, 1])
        sc = CandidateScore("pick", 20.0, 20.0, {"threshold": 10.0}, None, {})
        sc.fit = SimpleNamespace(r_raw=r0 - change)
        b = base if shot_kw is None else SimpleNamespace(
            shots=[SimpleNamespace(**{**vars(shot), **shot_kw})], segments=base.segments)
        _judge_stated(sc, b, SimpleNamespace(r_raw=r0))
        return sc

    inside = judged(rng.uniform(0.2, 0.95) * STATED_Z)
    assert not inside.beyond_stated and "not told" in inside.note, seed
    assert inside.path_change_stated <= STATED_Z, seed
    outside = judged(rng.uniform(1.05, 5) * STATED_Z)
    assert outside.beyond_stated and outside.path_change_stated > STATED_Z, seed
    for kw in ({"noise_persists": False}, {"stated_sigma": {"x": np.full(n, sigma)}},
               {"stated_sigma": {"x": np.full(n, sigma), "y": np.full(n, np.nan)}}):
        silent = judged(0.5 * STATED_Z, kw)
        assert silent.beyond_stated and silent.path_change_stated is None, (seed, kw)
