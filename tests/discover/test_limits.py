"""Detection limits: the smallest effect each candidate's threshold lets be seen.

A ``none`` says nothing about effects below them; an effect a few times above clears
its threshold (it is then named, unless a rival explains the data alike: a 4x pick and a
2.5 m patch of factor 1.011 did, and the verdict was `none` with both supported).
Checked against ground truth: the limit is read off a clean draw, then the same draw
(same noise) gets the effect at a multiple of it.
"""

import numpy as np
import pytest

from curltrack.discover import discover
from curltrack.physics import Effect, ShotModel
from curltrack.physics import closed_form as cf
from curltrack.simulate import simulate_series


def _entropy() -> int:
    return int(np.random.SeedSequence().entropy % (1 << 63))


def _draw(rng):
    m = ShotModel(v0=float(rng.uniform(1.6, 2.2)),
                  omega0=float(rng.choice([-1, 1]) * rng.uniform(0.8, 2.0)))
    noise = dict(noise_m=float(rng.uniform(0.001, 0.004)),
                 noise_rad=float(np.radians(rng.uniform(0.2, 0.6))),
                 seed=int(rng.integers(1 << 30)))
    return m, noise


def _pick_at(rng, m, limit, mult, noise):
    t_stop = cf.stop_time_translation(m.v0, m.phi_y, m.alpha_y)
    t = float(rng.uniform(0.25, 0.6)) * t_stop
    eff = Effect("pick", {"t_s": t, "dvy_m_per_s": -mult * limit})
    return discover(simulate_series(m, [eff], **noise), n_boot=200,
                    seed=int(rng.integers(1 << 30)))


def _pick_supported(rep) -> bool:
    return next(f for f in rep.findings if f.effect == "pick").supported


def _limit(rep, effect, param):
    f = next(f for f in rep.findings if f.effect == effect)
    lim = f.detection_limit[param]
    assert 0 < lim["min"] <= lim["median"] <= lim["max"] < np.inf, lim
    return lim["median"]


def test_a_pick_four_times_its_limit_is_seen():
    """A clean draw's `none` comes with the pick's limit (median over its times; also
    in the JSON summary); the same draw with a pick of 4x that limit in the first 25-60 %
    of the slide clears the pick's threshold.  (Supported - every rule met - is a
    rate: >= 11 of 12 in the slow test below.  One CI draw, seed 1630400194357754300,
    cleared it, delta-BIC 87.5 over 42.5, but its gain at the scan's nearest time was
    36.1: not supported.)"""
    seed = _entropy()
    rng = np.random.default_rng(seed)
    m, noise = _draw(rng)
    clean = discover(simulate_series(m, **noise), n_boot=200, seed=int(rng.integers(1 << 30)))
    limit = _limit(clean, "pick", "dvy_m_per_s")
    text = clean.limits_text()
    assert "pick |dvx_m_per_s|" in text and f"|dvy_m_per_s| {limit:.2g} m/s" in text, text
    assert "detection_limit" in next(f.summary() for f in clean.findings
                                     if f.effect == "pick")
    rep = _pick_at(rng, m, limit, 4.0, noise)
    pick = next(f for f in rep.findings if f.effect == "pick")
    assert pick.delta_bic > pick.threshold, (seed, limit, pick.delta_bic, pick.threshold)


@pytest.mark.slow
def test_limits_separate_seen_from_unseen():
    """Over 12 draws: picks at 4x their limit supported in >= 11; at 0.25x in none
    (the look-elsewhere level allows a pick by chance in ~1 %)."""
    seed = _entropy()
    rng = np.random.default_rng(seed)
    seen = unseen = 0
    for _ in range(12):
        m, noise = _draw(rng)
        clean = discover(simulate_series(m, **noise), n_boot=200,
                         seed=int(rng.integers(1 << 30)))
        limit = _limit(clean, "pick", "dvy_m_per_s")
        seen += _pick_supported(_pick_at(rng, m, limit, 4.0, noise))
        unseen += _pick_supported(_pick_at(rng, m, limit, 0.25, noise))
    assert seen >= 11 and unseen == 0, f"seed {seed}: {seen}/12 seen, {unseen}/12 unseen"


def test_a_series_from_another_origin_gives_the_same_verdict():
    """The contract allows any origin (``fit`` fits one); discovery's per-shot offsets
    are bounded to +-1 m / rad.  A clean shot in rink coordinates (2 m, -6 m off) held
    them at their bounds: verdict ``unexplained``, every baseline parameter at a bound,
    a warning blaming the instrument.  Now the origin is taken off and reported back."""
    from dataclasses import replace

    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    s = simulate_series(ShotModel(v0=rng.uniform(1.5, 2.2),
                                  omega0=rng.choice([-1, 1]) * rng.uniform(0.8, 2.5)),
                        noise_m=0.002, noise_rad=0.005, seed=seed)
    dx, dy = rng.choice([-1, 1], 2) * rng.uniform(1.5, 40.0, 2)
    dth = float(rng.choice([-1, 1]) * rng.uniform(1.0, 50.0))
    turn = np.radians(rng.uniform(-12.0, 12.0))
    c, sn = np.cos(turn), np.sin(turn)
    d = s.data
    moved = replace(s, data=d.assign(x=dx + c * d.x - sn * d.y, y=dy + sn * d.x + c * d.y,
                                     theta=d.theta + dth))
    a, b = discover(s, seed=1, n_boot=200), discover(moved, seed=1, n_boot=200)
    what = f"seed {seed}: offset {dx:.2f}, {dy:.2f} m, {dth:.2f} rad, turned {turn:.3f} rad"
    # (the same verdict from both origins; a clean draw's verdict is none but for the
    # look-elsewhere level's chance alarms - seed 935394457: a 3-sigma pick of 2 mm/s,
    # delta-BIC 2.3 over a 1 % threshold of -0.7, from either origin - which the clean
    # worlds' false-alarm tests count)
    assert a.verdict == b.verdict, (what, a.verdict, b.verdict)
    assert [f.effect for f in a.findings if f.supported] == \
        [f.effect for f in b.findings if f.supported], (what, a.verdict)
    p = b.baseline["params"]
    assert abs(p["x0[0]"] - dx) < 0.01 and abs(p["y0[0]"] - dy) < 0.01, (what, p)
    assert abs(p["theta0[0]"] - dth) < 0.01 and abs(p["skew[0]"] - turn) < 0.005, (what, p)
    assert any("another origin" in w for w in b.warnings), what


def test_draws_with_the_papers_slowest_spin_decay_are_described():
    """The paper's draws have lambda_theta 1.20-1.50 (phi_theta -4 to -1): near 1.2 the
    rotation's alpha_theta is ~1e-7 - 1e-9.  The baseline's bounds (phi_theta >= -3,
    alpha_theta >= 1e-6) held such clean draws at them: verdict unexplained (a helper's
    independent simulator; here at phi_theta -2.8, -3.5 and -5 alike; at -5, lambda_theta
    1.17, beyond the paper's range, one draw in ~20 misfits its end and names a pick)."""
    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    phi = float(rng.uniform(-4.0, -2.5))   # (the paper: lambda_theta 1.20-1.50)
    m = ShotModel(v0=rng.uniform(1.5, 2.2), omega0=rng.choice([-1, 1]) * rng.uniform(0.8, 2.5),
                  phi_theta=phi)
    s = simulate_series(m, noise_m=0.002, noise_rad=0.005, seed=seed)
    rep = discover(s, seed=1, n_boot=200)
    p, e = rep.baseline["params"], rep.baseline["params_err"]
    what = f"seed {seed}: phi_theta {phi:.2f} (lambda_theta {m.lambda_theta:.3f})"
    assert rep.verdict == "none", (what, rep.verdict, rep.warnings)
    assert abs(p["phi_theta"] - phi) < max(4 * e["phi_theta"], 0.02), (what, p["phi_theta"])


def test_an_instruments_glitch_is_left_out_not_explained():
    """A position fix that jumps by 3-15 cm, holds for 0.5-3 s and jumps back, on an
    otherwise clean shot (a helper's independent instrument model: four of seven such
    shots were ``unexplained``).  A rock's position cannot jump: the rows between the
    jumps are left out, x and y together (one fix), with a warning naming it."""
    from dataclasses import replace

    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    rate = float(rng.choice([10.0, 25.0, 30.0]))
    s = simulate_series(ShotModel(v0=rng.uniform(1.5, 2.2),
                                  omega0=rng.choice([-1, 1]) * rng.uniform(0.8, 2.5)),
                        noise_m=float(rng.uniform(0.001, 0.002)), noise_rad=0.005,
                        seed=seed, fps=rate)
    d = s.data.copy()
    t_end = float(s.meta["t_stop_translation"])
    # (glitches of 4-15 cm: >= 10 sigma of the row-to-row noise in their larger
    # component; one at the 6-sigma threshold is found in part, and the rest of it is
    # 'unexplained' - honestly so)
    n_glitch = int(rng.integers(1, 3))
    starts = [float(rng.uniform(1.0, t_end / 2 - 3.0))]
    if n_glitch == 2:   # (apart: each returns before the next)
        starts.append(float(rng.uniform(starts[0] + 3.5, t_end - 4.0)))
    for t0 in starts:
        hold = float(rng.uniform(0.5, 3.0))
        size, ang = rng.uniform(0.04, 0.15), rng.uniform(0, 2 * np.pi)
        box = (d.t >= t0) & (d.t < t0 + hold)
        d.loc[box, "x"] += size * np.cos(ang)
        d.loc[box, "y"] += size * np.sin(ang)
    rep = discover(replace(s, data=d), seed=1, n_boot=200)
    what = f"seed {seed}: {rate:g} Hz, glitches at {np.round(starts, 2)} s"
    assert rep.verdict == "none", (what, rep.verdict, rep.warnings)
    assert sum("instrument's glitch" in w for w in rep.warnings) >= n_glitch, \
        (what, rep.warnings)


def test_a_session_whose_shots_differ_in_friction_exponent_gives_none():
    """The paper measured lambda_y 1.77-1.90 and lambda_theta 1.20-1.50 from shot to shot
    on one sheet.  With phi shared by the session (alpha per shot), clean sessions
    whose phi_y spread by ~0.05 were named a pick, a patch or an extension in 5 of 6
    (and in 5 of 8 of an independent simulator's); each shot now gets its own exponents
    where that fits better (BIC), with a warning."""
    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    shots = []
    for _ in range(int(rng.integers(3, 6))):
        m = ShotModel(v0=rng.uniform(1.5, 2.3), omega0=rng.choice([-1, 1]) * rng.uniform(0.8, 2.5),
                      phi_y=-0.19 + rng.normal(0, 0.05), alpha_y=0.0076 * rng.uniform(0.9, 1.1),
                      phi_theta=-1.2 + rng.normal(0, 0.15))
        shots.append(simulate_series(m, noise_m=0.002, noise_rad=0.005,
                                     seed=int(rng.integers(1 << 30)),
                                     fps=float(rng.choice([10.0, 30.0]))))
    rep = discover(shots, seed=1, n_boot=200)
    assert rep.verdict == "none", (f"seed {seed}", rep.verdict, rep.warnings)


def test_an_instruments_lasting_jump_is_not_named():
    """A position fix that jumps by 3-10 cm in one coordinate and keeps the new error
    to the end (a level an instrument's fix settles on, which the glitch rule - every
    jump returning - leaves in): a pick, a patch or a friction field can be fitted to
    it, but each smooths the jump and leaves its shape in the residuals, so nothing is
    named; the jump is found where it was put.  (Without the rule, 3 of 8 draws had a
    pick or a late curl supported, one of them named.)"""
    from dataclasses import replace

    from curltrack.discover.model import JointModel
    from curltrack.discover.search import instrument_step
    from curltrack.discover.shots import shot_from_series

    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    rate = float(rng.choice([10.0, 30.0]))
    s = simulate_series(ShotModel(v0=rng.uniform(1.5, 2.2),
                                  omega0=rng.choice([-1, 1]) * rng.uniform(0.8, 2.5)),
                        noise_m=0.002, noise_rad=0.005, seed=seed, fps=rate)
    d = s.data.copy()
    t_end = float(s.meta["t_stop_translation"])
    t0 = float(rng.uniform(0.2, 0.8) * t_end)
    coord = str(rng.choice(["x", "y"]))
    size = float(rng.choice([-1, 1]) * rng.uniform(0.03, 0.10))
    d.loc[d.t >= t0, coord] += size
    what = f"seed {seed}: {rate:g} Hz, {coord} jumps {100 * size:+.1f} cm at {t0:.2f} s"
    jumped = replace(s, data=d)
    base = JointModel([shot_from_series(jumped)], "paper")
    jump = instrument_step(base, base.fit(max_nfev=80))
    # (the baseline bends to a lasting jump: what it leaves can be a box with the jump
    # at its far edge - seed 444885932, 10 Hz, 2.0-5.0 s for a jump at 4.91 s)
    edges = [e for e in (jump["t_from_s"], jump["t_to_s"]) if e is not None]
    assert jump["found"] and jump["coord"] == coord and min(abs(e - t0) for e in edges) < 0.5, (
        what, jump)
    rep = discover(jumped, seed=1, n_boot=200)
    assert rep.verdict in ("none", "unexplained"), (what, rep.verdict)
    for f in rep.findings:
        if f.supported:
            assert any("instrument's jump" in b for b in f.not_named_because or ()), (
                what, f.effect, f.not_named_because)


def test_the_jump_scan_keeps_its_level_under_heavy_tails():
    """The instrument-jump scan's chance level holds on heavy-tailed noise (t3 plus 1 %
    outliers): it is read off sign-flipped draws of the residuals, which keep their
    tails, and a box shorter than the shortest hold (an outlier) is not a jump.  Read
    against a Gaussian level, a clean heavy-noise shot had a "jump" in 4 of 6 (and a
    true 0.32 patch, delta-BIC 51404, was blocked by one); scaled by the residuals'
    variance, still 4 of 8 in CI (seed 4365518485154947005: one-row boxes at the
    series' end, 0.5 s boxes over a 10-sigma outlier).  Now at most 2 of 8 clean shots
    show one (the level is 1 %: 0 of 60 measured), and a real lasting jump of 3-10 cm
    is still found where it was put: between the row before and the row it is placed
    at (4 of 28 draws placed it 0.55-1.2 s late when it fell in a gap, or the grid of
    starts skipped the row after one), or as the end of a box the baseline left."""
    import sys
    from dataclasses import replace
    from pathlib import Path

    from curltrack.discover.model import JointModel
    from curltrack.discover.search import instrument_step
    from curltrack.discover.shots import shot_from_series

    sys.path.insert(0, str(Path(__file__).parent))
    from test_real_data import clean_case

    seed = _entropy()
    rng = np.random.default_rng(seed)
    found, missed = [], []
    for i in range(8):
        s = clean_case(rng, "heavy", float(rng.choice([10.0, 30.0])), bool(rng.random() < 0.5))[0]
        base = JointModel([shot_from_series(s)], "paper")
        jump = instrument_step(base, base.fit(max_nfev=80))
        if jump["found"]:
            found.append((i, round(jump["gain"], 1), round(jump["variance"], 2)))
        d = s.data.copy()
        t0 = float(rng.uniform(0.2, 0.8) * s.meta["t_stop_translation"])
        coord = str(rng.choice(["x", "y"]))
        d.loc[d.t >= t0, coord] += float(rng.choice([-1, 1]) * rng.uniform(0.03, 0.10))
        jb = JointModel([shot_from_series(replace(s, data=d))], "paper")
        jj = instrument_step(jb, jb.fit(max_nfev=80))
        # it jumped between two rows, which a gap of the instrument's can set 2 s apart
        # - at the box's start, or at its end: the baseline can take the level after a
        # lasting jump as its own and leave a box that returns at it (CI seed
        # 1908292584367124221: a 4.28 s jump found as a box 1.29-4.37 s)
        # - and a gap can fall there too (CI seed 760772378854954661: a jump at 5.68 s
        # in a gap 5.54-7.25 s found as a box 2.51-7.25 s)
        back = jj.get("t_to_s")
        rows = d.t.to_numpy()
        before_back = None if back is None else float(rows[rows < back].max())
        if not (jj["found"] and jj["coord"] == coord
                and (jj["t_before_s"] - 0.5 < t0 < jj["t_from_s"] + 0.5
                     or (back is not None and before_back - 0.5 < t0 < back + 0.5))):
            missed.append((i, coord, round(t0, 2), jj))
    assert len(found) <= 2, f"seed {seed}: jumps in clean heavy-tailed shots: {found}"
    assert not missed, f"seed {seed}: real jumps not found: {missed}"


def test_a_low_threshold_does_not_lower_the_limit():
    """A finding needs delta-BIC over its threshold and over MIN_DELTA_BIC (strong
    evidence): a threshold below it (a null whose delta-BIC is seldom positive) gives
    the limit of a threshold of MIN_DELTA_BIC, not a smaller one (thresholds of -4 to
    -15 once gave limits near 0)."""
    from curltrack.discover.scoring import MIN_DELTA_BIC, detection_limits

    seed = _entropy()
    rng = np.random.default_rng(seed)
    n, k = 400, 2
    J0 = rng.normal(size=(n, 3))
    E = rng.normal(size=(n, 2))
    floor = detection_limits(J0, [E], MIN_DELTA_BIC, k, n)[0]
    below = detection_limits(J0, [E], MIN_DELTA_BIC - float(rng.uniform(1.0, 30.0)), k, n)[0]
    above = detection_limits(J0, [E], MIN_DELTA_BIC + 10.0, k, n)[0]
    assert np.allclose(below, floor) and np.all(above > floor), (seed, below, floor, above)
    # and it is the size whose noise-free chi-square gain is the floor plus k ln n
    Q, _ = np.linalg.qr(J0)
    Et = E - Q @ (Q.T @ E)
    assert np.allclose(floor ** 2 * np.sum(Et * Et, axis=0), MIN_DELTA_BIC + k * np.log(n)), seed
