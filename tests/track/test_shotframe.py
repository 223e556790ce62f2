"""Lattice frame -> shot frame and the cumulative angle."""

import numpy as np
from scipy.stats import binom

from curltrack.track.shotframe import choose_axes, intercept_scatter, to_shot_frame, unwrap_angle


def test_unwrap_through_gaps_and_fast_spin():
    rng = np.random.default_rng(1)
    t = np.arange(0, 5, 1 / 30)
    theta = 12.0 * t - 0.8 * t**2  # up to ~2.3 rad per 3-frame gap
    keep = np.sort(rng.choice(t.size, t.size // 2, replace=False))
    keep = keep[np.diff(np.r_[-1, keep]) <= 3]
    keep = np.r_[0, 1, 2, keep[keep > 2]]
    wrapped = np.angle(np.exp(1j * theta[keep]))
    cum, sure = unwrap_angle(t[keep], wrapped)
    assert sure.all() and np.allclose(cum - wrapped[0] + theta[0], theta[keep])


def test_turns_across_a_gap_are_counted_or_not_given():
    """A gap of unmeasured frames (a broom over the rock, a lost grid) can hide whole
    turns: its angle is predicted from the spin measured on both sides, and when the
    turn count is still not certain the rows after it are flagged - never a row a whole
    turn off given as sure.  A one-frame rate (the old rule) slips on noisy frames."""
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    kept, slipped_old = 0, 0
    n = 200
    for _ in range(n):
        fps = rng.choice([30.0, 60.0])
        t = np.arange(0.0, 6.0, 1 / fps)
        omega0, decel = rng.uniform(0.5, 4.0), rng.uniform(0.0, 0.3)
        theta = omega0 * t - 0.5 * decel * t ** 2
        sig = np.radians(rng.uniform(0.3, 2.5))
        g0 = rng.uniform(0.3, 3.0)
        keep = (t < g0) | (t > g0 + rng.uniform(0.3, 1.5))
        if rng.random() < 0.3:  # a second gap, after the first
            g1 = rng.uniform(g0 + 2.0, 5.5)
            keep &= (t < g1) | (t > g1 + rng.uniform(0.2, 1.0))
        tk = t[keep]
        meas = theta[keep] + rng.normal(0.0, sig, tk.size)
        cum, sure = unwrap_angle(tk, np.angle(np.exp(1j * meas)))
        turns = np.round((cum - theta[keep]) / (2 * np.pi))
        turns -= turns[0]
        off = sure & (turns != 0)
        assert not off.any(), (f"seed {seed}: {off.sum()} rows a whole turn off given as "
                               f"sure (omega0 {omega0:.2f} rad/s, noise "
                               f"{np.degrees(sig):.1f} deg, gap at {g0:.2f} s)")
        assert (np.diff(sure.astype(int)) <= 0).all()  # flagged from a gap to the end
        kept += sure.all()
        # the one-frame rate across the gap, for comparison
        old = np.empty(tk.size)
        old[0], omega = meas[0], 0.0
        wr = np.angle(np.exp(1j * meas))
        for i in range(1, tk.size):
            pred = old[i - 1] + omega * (tk[i] - tk[i - 1])
            old[i] = wr[i] + 2 * np.pi * np.round((pred - wr[i]) / (2 * np.pi))
            omega = (old[i] - old[i - 1]) / (tk[i] - tk[i - 1])
        slipped_old += bool(np.any(np.round((old - theta[keep]) / (2 * np.pi))
                                   != np.round((old[0] - theta[keep][0]) / (2 * np.pi))))
    # gaps of 0.3-1.5 s with a measured spin on both sides are counted almost always
    assert kept >= 0.9 * n, f"seed {seed}: only {kept}/{n} draws counted every turn"
    assert slipped_old >= 0.02 * n, f"seed {seed}: the one-frame rate slipped in {slipped_old}"


def test_turns_across_single_frames_use_the_spins_bound():
    """Rows left out every other frame at the start (leading strays: frames 1 and 3 of
    a hand-held clip) leave single frames, with no spin rate on either side of a gap:
    a rock turns by at most MAX_SPIN dt there, so a one- or two-frame gap keeps its
    turn count (the whole clip's theta was left empty before) - and a step beyond that
    bound is not given as sure."""
    from curltrack.sanity import MAX_SPIN

    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    for _ in range(50):
        fps = float(rng.choice([25.0, 30.0, 50.0, 59.94]))
        t = np.arange(0.0, 4.0, 1 / fps)
        theta = rng.uniform(-4.0, 4.0) * t + rng.uniform(0, 2 * np.pi)
        keep = np.ones(t.size, bool)
        keep[[1, 3]] = False                       # runs [0], [2], [4 ...]
        meas = theta[keep] + rng.normal(0.0, np.radians(0.5), keep.sum())
        cum, sure = unwrap_angle(t[keep], np.angle(np.exp(1j * meas)))
        turns = np.round((cum - theta[keep]) / (2 * np.pi))
        assert sure.all() and (turns == turns[0]).all(), f"seed {seed}: fps {fps}"
    # a jump no rock can turn in two frame steps is not counted as sure
    t = np.arange(0.0, 2.0, 1 / 30)[[0, 2, 4, 5, 6, 7, 8, 9, 10]]
    phi = np.r_[0.0, 0.9 * np.pi, np.full(7, 0.9 * np.pi)]
    assert 0.9 * np.pi > MAX_SPIN * 2 / 30
    _, sure = unwrap_angle(t, phi)
    assert sure[0] and not sure[1:].any()


def test_strays_that_move_the_origin_by_chance_are_kept():
    """The test that leaves the first rows out when the origin moves without them
    beyond chance (``strays_shift_origin``, a 640x360 hand-held clip's rows 1-3 that
    bent every row by 9 mm) leaves right rows in: on clean simulated shots (white or
    persisting noise, 25-60 fps) any 1-4 of the first rows left out move the origin
    beyond its threshold in ~1 % of draws."""
    from curltrack.physics.shot import ShotModel
    from curltrack.simulate import simulate_series
    from curltrack.track.results import strays_shift_origin
    from curltrack.track.shotframe import WINDOW_S

    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    n_draws, fired = 100, 0
    for _ in range(n_draws):
        fps = float(rng.choice([25.0, 30.0, 50.0, 59.94]))
        sim = simulate_series(ShotModel(v0=rng.uniform(1.0, 2.5),
                                        omega0=rng.uniform(0.5, 2.5)), fps=fps).data
        n = min(len(sim), int(5 * fps))
        t = sim.t.to_numpy()[:n]
        sigma = rng.uniform(0.5e-3, 3e-3) * rng.uniform(0.7, 1.4, n)
        rho = rng.choice([0.0, 0.6, 0.9])
        e = rng.normal(0.0, 1.0, (n, 2))
        for i in range(1, n):
            e[i] = rho * e[i - 1] + np.sqrt(1 - rho ** 2) * e[i]
        centre = sim[["x", "y"]].to_numpy()[:n] + e * sigma[:, None]
        phi = sim.theta.to_numpy()[:n]
        lead = np.flatnonzero(t < WINDOW_S / 3)
        left = rng.choice(lead, int(rng.integers(1, min(4, lead.size) + 1)), replace=False)
        ok = np.ones(n, bool)
        without = ok.copy()
        without[left] = False
        fired += strays_shift_origin(to_shot_frame(t, centre, phi, ok, sigma=sigma),
                                     to_shot_frame(t, centre, phi, without, sigma=sigma))
    # (~1 % expected: 5 or more of 100 has a chance of ~0.3 %)
    assert fired <= 5, f"seed {seed}: right first rows left out in {fired} of {n_draws}"


def test_axes_and_origin_follow_the_initial_travel():
    rng = np.random.default_rng(2)
    for _ in range(10):
        heading = rng.uniform(0, 2 * np.pi)
        d = np.array([np.cos(heading), np.sin(heading)])
        t = np.arange(0, 3, 1 / 30)
        s = 1.5 * t - 0.2 * t**2
        start = rng.uniform(-1, 1, 2)
        centre = start + s[:, None] * d + rng.normal(0, 0.001, (t.size, 2))
        phi = np.angle(np.exp(1j * (0.7 + 2.0 * t)))
        out = to_shot_frame(t, centre, phi, np.ones(t.size, bool))
        x_hat, y_hat = choose_axes(d)
        assert np.allclose(out["y_hat"], y_hat) and y_hat @ d > np.cos(np.pi / 4) - 1e-9
        assert x_hat[0] * y_hat[1] - x_hat[1] * y_hat[0] > 0  # +x to the right of +y
        assert np.allclose(out["origin"], start, atol=0.003)
        assert abs(out["theta"][0]) < 0.01
        assert np.allclose(out["theta"], 2.0 * t, atol=0.01)
        assert out["y"][-1] > 0


def test_theta0_sigma_matches_its_error():
    """Every angle is measured from theta0, a fit to the first frames: its reported 1
    sigma must match its error (first frame at or after t = 0, white or correlated
    frame noise, rows on or off the frame grid) - an error shared by every row."""
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    z = {False: [], True: []}
    for i in range(400):
        t0 = float(rng.choice([0.0, rng.uniform(0.05, 0.4)]))
        t = np.arange(t0, 4.0, 1 / 30)
        off_grid = bool(i % 2)  # rows timed off the frame grid (rolling shutter, jitter)
        if off_grid:  # (the rock's image row and the frame's own jitter: 0-16 ms)
            t = t + 0.008 + 0.006 * np.sin(2 * np.pi * t / rng.uniform(0.5, 3.0)
                                           + rng.uniform(0, 2 * np.pi)) \
                + rng.uniform(-0.002, 0.002, t.size)
        omega0, decel = rng.uniform(0.5, 3.0), rng.uniform(0.05, 0.3)
        sig, rho = np.radians(rng.uniform(0.1, 0.6)), rng.uniform(0.0, 0.6)
        e = np.empty(t.size)
        e[0] = rng.normal(0, sig)
        for i in range(1, t.size):
            e[i] = rho * e[i - 1] + rng.normal(0, sig * np.sqrt(1 - rho ** 2))
        phi = omega0 * t - 0.5 * decel * t ** 2 + e
        centre = np.column_stack([np.zeros_like(t), 1.5 * t - 0.1 * t ** 2])
        out = to_shot_frame(t, centre, phi, np.ones(t.size, bool))
        z[off_grid].append(out["theta0"] / out["theta0_sigma_rad"])  # (true theta0 = 0)
    for off_grid, zz in z.items():
        rms = float(np.sqrt(np.mean(np.square(zz))))
        assert 0.75 < rms < 1.3, (f"seed {seed}: rows {'off' if off_grid else 'on'} the "
                                  f"frame grid: RMS of theta0 error / sigma {rms:.2f}")


def _ar1(rng, n, sig, rho):
    e = np.empty(n)
    e[0] = rng.normal(0, sig)
    for i in range(1, n):
        e[i] = rho * e[i - 1] + rng.normal(0, sig * np.sqrt(1 - rho ** 2))
    return e


def test_theta0_sigma_matches_its_error_on_interlaced_fields():
    """Rows of two interlaced fields at 59.94 Hz whose angle errors share a slowly
    varying part and differ by another that each field carries with the opposite sign
    (what rendered 720x480 interlaced clips show: lag-1 correlation 0.4, lag-2 0.6):
    taken as one series, the two fields' difference reads as white noise and theta0's
    sigma came out 2.4x too small on such clips; measured field by field it matches
    its error."""
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    z = {False: [], True: []}
    for _ in range(300):
        n = int(rng.integers(100, 240))
        t = np.arange(n) / 59.94
        field = np.arange(n) % 2
        omega0, decel = rng.uniform(0.5, 3.0), rng.uniform(0.05, 0.3)
        sig = np.radians(rng.uniform(0.1, 0.5))
        # per field step (1/29.97 s): the shared part and the fields' difference
        rho_c, rho_d = rng.uniform(0.3, 0.8, 2)
        common = _ar1(rng, n, sig, rho_c ** 0.5)
        diff = np.repeat(_ar1(rng, (n + 1) // 2, sig, rho_d), 2)[:n]
        phi = omega0 * t - 0.5 * decel * t ** 2 + common + np.where(field == 0, 0.5, -0.5) * diff
        centre = np.column_stack([np.zeros_like(t), 1.5 * t - 0.1 * t ** 2])
        for per_field in (False, True):
            out = to_shot_frame(t, centre, phi, np.ones(n, bool),
                                field=field if per_field else None)
            z[per_field].append(out["theta0"] / out["theta0_sigma_rad"])
    rms = {k: float(np.sqrt(np.mean(np.square(v)))) for k, v in z.items()}
    assert 0.75 < rms[True] < 1.3, f"seed {seed}: RMS of theta0 error / sigma {rms}"
    # (the cause: the interleaved series' noise model)
    assert rms[False] > 1.15 * rms[True], f"seed {seed}: {rms}"


def _noisy_start(rng, worse: float):
    """A quadratic path from the origin (0, 0), its first row at t = 0 or 0.05-0.4 s
    later (``late``), 30 rows/s, white errors of 0.3-2 mm - ``worse`` times that on 15 %
    of the rows.  Returns (late, t, centre (N, 2), sigma (N,))."""
    late = bool(rng.random() < 0.5)
    t = np.arange(rng.uniform(0.05, 0.4) if late else 0.0, 4.0, 1 / 30)
    v0, decel, curl = rng.uniform(0.8, 2.5), rng.uniform(0.05, 0.3), rng.uniform(-0.03, 0.03)
    sig = rng.uniform(0.3e-3, 2e-3) * rng.choice([1.0, worse], size=t.size, p=[0.85, 0.15])
    centre = (np.column_stack([0.5 * curl * t ** 2, v0 * t - 0.5 * decel * t ** 2])
              + rng.normal(0.0, 1.0, (t.size, 2)) * sig[:, None])
    return late, t, centre, sig


def test_origin_sigma_matches_its_error():
    """The origin is a fit to the first frames (extrapolated or not): its error is
    shared by every row, so its reported 1 sigma must match it - also when the frames'
    errors differ from frame to frame (some 3x the others, as blur, glare or a doubtful
    grid fit make them), which a scatter common to the window hides."""
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    z = {False: [], True: []}
    for _ in range(300):
        late, t, centre, _ = _noisy_start(rng, 3.0)
        out = to_shot_frame(t, centre, 2.0 * t, np.ones(t.size, bool))
        assert out["origin_extrapolated"] == late
        z[late].extend(out["origin"] / out["origin_sigma_m"])  # (true origin = 0, 0)
    for late, zz in z.items():
        rms = float(np.sqrt(np.mean(np.square(zz))))
        # (late: the extrapolation's model term holds the path's cubic as measured,
        # which these quadratic paths lack - its error alone; RMS 0.87-0.98 over 20
        # seeds, 0.84-0.96 with the cubic at its bound before session 36)
        assert (0.7 if late else 0.8) < rms < 1.25, \
            f"seed {seed}: first frame {'after' if late else 'at'} t = 0: RMS of origin " \
            f"error / sigma {rms:.2f}"


def test_the_origin_weighs_each_row_by_its_own_sigma():
    """Rows whose own sigma is several times their neighbours' (a doubtful grid, a
    half-hidden marker) move the origin less when the fit is told their sigmas: its
    error is smaller than the unweighted fit's and its reported sigma still matches it.
    Rows of equal sigma give the unweighted origin."""
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    err = {"weighted": [], "alike": []}
    z = []
    # (600 draws: over 300 the RMS below read 0.86-0.94 on 12 seeds, and seed 796792793
    # drew 0.79 - the band's edge is the sampling error's, not the sigma's)
    for _ in range(600):
        late, t, centre, sig = _noisy_start(rng, 8.0)
        ok = np.ones(t.size, bool)
        w = to_shot_frame(t, centre, 2.0 * t, ok, sigma=sig)
        u = to_shot_frame(t, centre, 2.0 * t, ok)
        # (true origin = 0, 0; in units of the draw's good rows' sigma)
        err["weighted"].extend(w["origin"] / sig.min())
        err["alike"].extend(u["origin"] / sig.min())
        if not late:
            z.extend(w["origin"] / w["origin_sigma_m"])
        same = to_shot_frame(t, centre, 2.0 * t, ok, sigma=np.full(t.size, 1e-3))
        assert np.allclose(same["origin"], u["origin"], rtol=0, atol=1e-12), seed
    rms = {k: float(np.sqrt(np.mean(np.square(v)))) for k, v in err.items()}
    # (0.64-0.85 over six seeds: the unweighted fit's robust pass drops the worst rows)
    assert rms["weighted"] < 0.9 * rms["alike"], f"seed {seed}: origin error RMS {rms}"
    rz = float(np.sqrt(np.mean(np.square(z))))
    assert 0.8 < rz < 1.25, f"seed {seed}: weighted origin error / sigma RMS {rz:.2f}"


def test_row_weights_only_take_weight_off_doubtful_rows():
    from curltrack.track.shotframe import FULL_WEIGHT_SIGMA_RATIO, row_weights

    r = FULL_WEIGHT_SIGMA_RATIO
    # (lower quartile of the sigmas: 1)
    w = row_weights(np.array([1.0, 1.0, 1.0, 1.0, 0.9 * r, 2 * r, 0.1, np.nan, 0.0]))
    assert np.array_equal(w[[0, 1, 2, 3, 4, 6]], np.ones(6)), w  # (none weighs more than 1)
    assert w[5] == 0.25, w  # (twice the full weight's sigma: a quarter)
    assert w[7] == 1.0 and w[8] == 1.0  # (no sigma: as the others)
    assert row_weights(None) is None and row_weights(np.full(3, np.nan)) is None


def test_uncounted_turns_leave_theta_empty_not_positions():
    """After a gap whose turns cannot be counted (here: 2 s, and one frame after it to
    measure no spin from), the shot frame gives x and y but no theta there, and theta0
    and its sigma come from the frames before the gap."""
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    t = np.r_[np.arange(0.0, 2.0, 1 / 30), 4.0]
    theta = rng.uniform(1.0, 3.0) * t
    centre = np.column_stack([np.zeros_like(t), 1.5 * t - 0.1 * t ** 2])
    centre += rng.normal(0.0, 5e-4, centre.shape)
    out = to_shot_frame(t, centre, np.angle(np.exp(1j * theta)), np.ones(t.size, bool))
    assert out["theta_unsure"].tolist() == [False] * (t.size - 1) + [True], f"seed {seed}"
    assert np.isnan(out["theta"][-1]) and np.isfinite(out["x"]).all(), f"seed {seed}"
    assert np.allclose(out["theta"][:-1], theta[:-1], atol=1e-6), f"seed {seed}"
    assert np.isfinite(out["theta0_sigma_rad"]), f"seed {seed}"


def test_angles_of_frames_without_a_certain_cell_fix_theta0():
    """Frames whose position is not given (a cell index not certain) still measure the
    rock's angle: given as ``angle_rows`` they fix theta0 from the release instead of an
    extrapolation over the gap, and the angles stay relative to it; the positions and
    the rows given are those of ``ok`` alone."""
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    err = {False: [], True: []}
    # (the ratio of the two RMS over 60 draws: median 0.46, above 0.6 in 1.3 % of 150
    # runs - CI seed 2447014506: 0.67; over 240 draws its spread is half)
    for _ in range(240):
        t = np.arange(0.0, 4.0, 1 / 30)
        omega0, decel = rng.uniform(0.5, 3.0), rng.uniform(0.05, 0.3)
        phi = omega0 * t - 0.5 * decel * t ** 2 + rng.normal(0, np.radians(0.5), t.size)
        centre = np.column_stack([np.zeros_like(t), 1.5 * t - 0.1 * t ** 2])
        first = int(rng.integers(6, 15))      # the first position given
        early = np.zeros(t.size, bool)
        early[:int(rng.integers(2, 5))] = True   # angles measured before a gap
        ok = np.arange(t.size) >= first
        for given in (False, True):
            out = to_shot_frame(t, centre, phi, ok, angle_rows=early if given else None)
            assert np.isnan(out["theta"][~ok]).all() and np.isfinite(out["x"][ok]).all()
            err[given].append(out["theta0"])   # (true theta0 = 0)
    rms = {g: float(np.degrees(np.sqrt(np.mean(np.square(e))))) for g, e in err.items()}
    assert rms[True] < 0.6 * rms[False], f"seed {seed}: theta0 RMS {rms}"


def test_theta0_window_follows_a_spin_that_slows_fast():
    """theta0 is fitted over up to 1.6 s (errors that persist over tenths of a second
    average out), but over less of a short draw, whose spin slows faster and faster:
    noise-free simulated draws sliding 1.7-40 s give theta0 within 0.1 deg (a quadratic
    over 1.6 s of a 2.5 s draw misses it by ~1 deg).  (Never under 0.8 s: slides of
    1.25 / 1.4 / 1.55 s miss by up to 0.18 / 0.13 / 0.10 deg, seed 1250995681 drew one.)"""
    from curltrack.physics.shot import ShotModel
    from curltrack.simulate import simulate_series

    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    for v0, alpha_y in ((rng.uniform(0.65, 0.8), 0.03), (rng.uniform(0.8, 1.2), 0.03),
                        (rng.uniform(1.5, 2.5), None)):
        kw = {} if alpha_y is None else {"alpha_y": alpha_y}
        omega0 = float(rng.choice([-1, 1]) * rng.uniform(0.5, 3.0))
        d = simulate_series(ShotModel(v0=v0, omega0=omega0, **kw), fps=30).data
        t = d.t.to_numpy()
        offset = rng.uniform(-np.pi, np.pi)
        out = to_shot_frame(t, d[["x", "y"]].to_numpy(), d.theta.to_numpy() + offset,
                            np.ones(t.size, bool))
        miss = np.degrees(abs(np.angle(np.exp(1j * (out["theta0"] - offset)))))
        assert miss < 0.1, f"seed {seed}: v0 {v0:.2f}, {t[-1]:.1f} s: theta0 off by {miss:.3f} deg"


def _simulated_rows(rng, fps, sigma_m, rho=0.0):
    """A simulated shot's first 4 s at ``fps`` as tracked rows (t, centre (N, 2), the
    true centres), noise of ``sigma_m`` (m) per coordinate - AR(1) of ``rho`` per row,
    then some rows 3x noisier."""
    from curltrack.physics.shot import ShotModel
    from curltrack.simulate import simulate_series

    model = ShotModel(v0=rng.uniform(0.8, 3.5), omega0=rng.choice([-1, 1]) * rng.uniform(0.3, 3),
                      phi_y=rng.uniform(-0.8, 0.3), alpha_y=0.0076 * rng.uniform(0.7, 1.5))
    d = simulate_series(model, fps=fps).data
    d = d[d.t <= 4.0]
    t, true = d.t.to_numpy(), d[["x", "y"]].to_numpy()
    sig = sigma_m * rng.choice([1.0, 3.0], size=t.size, p=[0.9, 0.1])
    e = rng.normal(0.0, 1.0, true.shape)
    for k in range(1, len(e)):
        e[k] = rho * e[k - 1] + np.sqrt(1.0 - rho * rho) * e[k]
    return t, true + e * sig[:, None], true


def test_origin_check_says_nothing_on_clean_rows():
    """Rows of a simulated shot (the paper's law at random phi, speed, spin; 25-60 fps;
    noise 0.3-2 mm, white or AR(1) up to rho 0.6 per row as a tracker's persists, some
    rows 3x noisier): the first rows and the later ones agree, and the check adds an
    error to the origin in at most 5 % of draws (its chi^2 gate is at 99 % for its two
    windows together; 2.3 % over 3000 draws: 1.7 % white, 2.9 % AR(1)).  The count of
    200 draws must be plausible for a 5 % rate (binomial tail above 0.001: a fixed
    count of 10 fails ~0.7 % of runs at the true rate: seed 4175601778, 12 of 200)."""
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    n, flagged, checked = 200, 0, 0
    for _ in range(n):
        t, centre, _ = _simulated_rows(rng, float(rng.choice([25.0, 30.0, 60.0])),
                                       rng.uniform(0.3e-3, 2e-3),
                                       rho=float(rng.choice([0.0, rng.uniform(0.0, 0.6)])))
        out = to_shot_frame(t, centre, 0.0 * t, np.ones(t.size, bool))
        checked += out["origin_check_difference_m"] > 0
        flagged += out["origin_check_sigma_m"] > 0
    assert checked > 0.8 * n, f"seed {seed}: checked only {checked} of {n}"
    assert binom.sf(flagged - 1, n, 0.05) > 1e-3, (
        f"seed {seed}: {flagged} of {n} clean draws given an origin error")


def test_origin_check_reads_interlaced_fields_errors_field_by_field():
    """Rows of two interlaced fields (50 or 59.94 Hz), each field's error its own and
    persisting from field to field (AR(1), rho 0-0.8 per field step, 0.3-2 mm): read
    from one row to the next, the rows' errors look uncorrelated or anti-correlated, and
    the check called ~20 % of clean draws (a 720x480 ladder draw's 0.8 mm origin 9 mm
    off).  Field by field: at most 5 % of clean draws (~1 % seen; the count plausible
    for 5 %, as above), and an error the
    first rows share (12-30x the noise) is still found in >= 75 % (~88 % seen)."""
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    n, flagged, found = 120, 0, 0
    for _ in range(n):
        t, _, true = _simulated_rows(rng, float(rng.choice([50.0, 2 * 29.97])), 0.0)
        field = np.arange(t.size) % 2
        sigma, rho = rng.uniform(0.3e-3, 2e-3), rng.uniform(0.0, 0.8)
        e = rng.normal(0.0, 1.0, true.shape)
        for f in (0, 1):
            rows = np.flatnonzero(field == f)
            for a, b in zip(rows[:-1], rows[1:]):
                e[b] = rho * e[a] + np.sqrt(1.0 - rho * rho) * e[b]
        centre = true + sigma * e
        out = to_shot_frame(t, centre, 0.0 * t, np.ones(t.size, bool), field=field)
        flagged += out["origin_check_sigma_m"] > 0
        profile = np.clip(2.0 - t / rng.uniform(0.1, 0.35), 0.0, 1.0)
        ang = rng.uniform(0, 2 * np.pi)
        shared = rng.uniform(12, 30) * sigma * np.array([np.cos(ang), np.sin(ang)])
        out = to_shot_frame(t, centre + profile[:, None] * shared, 0.0 * t,
                            np.ones(t.size, bool), field=field)
        found += out["origin_check_sigma_m"] > 0
    assert binom.sf(flagged - 1, n, 0.05) > 1e-3, (
        f"seed {seed}: {flagged} of {n} clean draws given an origin error")
    assert found >= 0.75 * n, f"seed {seed}: a shared error found in {found} of {n}"


def test_origin_check_sizes_an_error_the_first_rows_share():
    """The first 0.1-0.35 s of rows off alike by 12-30x their noise, then fading out
    over as long (a camera starting to follow, an encoder's first frames): the origin's
    fit bends with them and its own sigma does not see it.  The check finds it (in >= 80
    % of draws, 87-96 % seen; under ~8x a row's noise it cannot, see ``origin_check``),
    and the total sigma then covers the origin's error: error over sigma RMS within
    0.6-1.4 (~1.0 seen), where the fit's own sigma alone leaves it many sigma off."""
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    z_found, z_without, n = [], [], 120
    for _ in range(n):
        sigma = rng.uniform(0.3e-3, 1.5e-3)
        t, centre, true = _simulated_rows(rng, float(rng.choice([25.0, 30.0, 60.0])), sigma)
        t_b = rng.uniform(0.1, 0.35)
        profile = np.clip(2.0 - t / t_b, 0.0, 1.0)
        ang = rng.uniform(0, 2 * np.pi)
        shared = rng.uniform(12, 30) * sigma * np.array([np.cos(ang), np.sin(ang)])
        out = to_shot_frame(t, centre + profile[:, None] * shared, 0.0 * t,
                            np.ones(t.size, bool))
        err = out["origin"] - true[0]
        z_without.append(float(np.sqrt(np.mean((err / out["origin_sigma_m"]) ** 2))))
        if out["origin_check_sigma_m"] > 0:
            total = np.hypot(out["origin_sigma_m"], out["origin_check_sigma_m"])
            z_found.append(float(np.sqrt(np.mean((err / total) ** 2))))
    assert np.median(z_without) > 4, f"seed {seed}: not an error the fit misses"
    assert len(z_found) >= 0.8 * n, f"seed {seed}: found in {len(z_found)} of {n}"
    rms = float(np.sqrt(np.mean(np.square(z_found))))
    assert 0.6 < rms < 1.4, f"seed {seed}: origin error / total sigma RMS {rms:.2f}"


def test_theta0_sigma_is_not_widened_by_the_spins_stop():
    """A spin that stops in view (the paper's theta_F - A tau^lambda, lambda ~ 1.5-1.8,
    over the whole turn), its rows white or correlated with a slow wander of their own,
    the rock at rest for a while after the stop or not: theta0's sigma, read on the rows
    before the stop and on the shot's own windows (:func:`intercept_scatter`), matches
    its error.  (A guard of that path: these draws do not show what made a rendered
    1280x720 clip's sigma 3.6x its error - its stop read with its rows' own wander as
    noise at rho 0.93 - and the code before passes them too.)"""
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    z = []
    for _ in range(300):
        T, lam = rng.uniform(2.0, 5.0), rng.uniform(1.5, 1.8)
        t = np.arange(0.0, T + rng.uniform(0.0, 1.5), 1 / 30)
        omega0 = rng.uniform(0.5, 3.0) * rng.choice([-1.0, 1.0])
        tau = np.clip(1.0 - t / T, 0.0, None)
        # white or correlated rows, with a slow wander of their own as a rendered
        # clip's show (a lattice's bias drifting with the rock's place)
        sig, rho = np.radians(rng.uniform(0.1, 0.5)), rng.uniform(0.0, 0.6)
        e = _ar1(rng, t.size, sig, rho) + _ar1(rng, t.size, sig * rng.uniform(0.0, 1.0),
                                              rng.uniform(0.9, 0.97))
        phi = omega0 * T / lam * (1.0 - tau ** lam) + e
        # (the rock slides on a little longer than it turns)
        t_tr, v0 = T * rng.uniform(1.0, 1.2), rng.uniform(1.0, 2.5)
        y = v0 * np.minimum(t, t_tr) - 0.5 * v0 / t_tr * np.minimum(t, t_tr) ** 2
        centre = np.column_stack([np.zeros_like(t), y])
        out = to_shot_frame(t, centre, phi, np.ones(t.size, bool))
        z.append(out["theta0"] / out["theta0_sigma_rad"])  # (true theta0 = 0)
    rms = float(np.sqrt(np.mean(np.square(z))))
    assert 0.75 < rms < 1.3, f"seed {seed}: RMS of theta0 error / sigma {rms:.2f}"


def test_intercept_scatter_reads_a_one_sided_fits_error():
    """On a smooth path under white noise, the shot's own windows give the one-sided
    quadratic's error at its start: sigma times the norm of its intercept weights
    (the centred reference adds ~1/3 of it in quadrature)."""
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    ratios = []
    for _ in range(200):
        fps, window = rng.choice([25.0, 30.0, 50.0, 60.0]), rng.uniform(0.5, 1.2)
        t = np.arange(0.0, rng.uniform(3.0, 6.0), 1 / fps)
        sig = rng.uniform(1e-4, 1e-2)
        q = rng.uniform(0.5, 3.0) * t - rng.uniform(0.05, 0.3) * t ** 2 + rng.normal(0, sig, t.size)
        n = np.count_nonzero(t <= window)
        A = np.vander(t[:n], 3, increasing=True)
        p0 = np.linalg.pinv(A)[0]
        ratios.append(intercept_scatter(t, q, window) / (sig * np.linalg.norm(p0)))
    r = float(np.sqrt(np.mean(np.square(ratios))))
    assert 0.9 < r < 1.25, f"seed {seed}: window scatter / one-sided fit's sigma RMS {r:.2f}"


def test_an_extrapolated_origins_sigma_matches_its_error_under_any_law():
    """A first row after the release: the origin is the initial quadratic extrapolated
    back, and its sigma must hold the path's cubic, which that quadratic leaves out -
    measured over the rows after (:func:`path_cubic`), not bounded by the steepest law
    allowed (|phi| <= 1, the paper's decelerations' whole range: on the sweep's draws,
    phi ~ -0.1 near their start, origins 0.5 mm off under 2-8 mm) - and the rows' errors
    that persist from row to row, which an extrapolation multiplies.  Draws of the
    paper's forms (lambda 1.5-2: phi -1 to 0; short draws and whole shots), first row
    0.05-0.6 s after release at 25-60 fps, white or AR(1) noise (rho up to 0.8): the
    origin's error over its sigma has RMS in 0.7-1.25 (white 0.84, AR(1) 1.00 measured;
    the bound and white rows gave 0.82 and 1.34)."""
    from curltrack.physics.closed_form import curl_position, decel_position
    from curltrack.settings import TrackingSettings
    from curltrack.track.shotframe import _origin_sigma, initial_state

    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    amax = TrackingSettings().max_deceleration_m_s2
    z = {"white": [], "ar1": []}
    for i in range(240):
        short = rng.random() < 0.5
        t_F = rng.uniform(2.5, 4.5) if short else rng.uniform(12.0, 25.0)
        lam = rng.uniform(1.5, 2.0)
        fps = float(rng.choice([25.0, 30000 / 1001, 60000 / 1001]))
        t = np.arange(rng.uniform(0.05, 0.6), t_F, 1 / fps)[:int(5 * fps)]
        q = np.column_stack([curl_position(t, rng.choice([-1, 1]) * rng.uniform(0.02, 0.08),
                                           lam, t_F),
                             decel_position(t, rng.uniform(1.5, 3.5) if short
                                            else rng.uniform(20.0, 35.0), lam, t_F)])
        kind = "white" if i % 2 else "ar1"
        rho = 0.0 if kind == "white" else rng.uniform(0.0, 0.8)
        e = rng.normal(0.0, rng.uniform(0.3e-3, 2e-3), q.shape)
        for k in range(1, len(e)):
            e[k] = rho * e[k - 1] + np.sqrt(1.0 - rho ** 2) * e[k]
        q = q + e
        z[kind].extend(initial_state(t, q)[0] / _origin_sigma(t, q, amax))  # (truth 0)
    for kind, zz in z.items():
        rms = float(np.sqrt(np.mean(np.square(zz))))
        assert 0.7 < rms < 1.25, f"seed {seed}: {kind} noise, origin error / sigma RMS {rms:.2f}"


def test_path_cubic_measures_the_cubic_it_is_given():
    """:func:`path_cubic` on rows of a known cubic path with white noise: the size it
    gives is the cubic's within 4 of its own standard errors (it adds its variance), and
    None where the rock stops before half its window."""
    from curltrack.track.shotframe import _window_fit, path_cubic

    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    for _ in range(20):
        t = np.arange(rng.uniform(0.0, 0.5), 6.0, 1 / 30)
        c = np.array([[0.0, 0.0], [0.1, 2.0], [-0.01, -0.06], rng.normal(0, 0.004, 2)])
        q = np.vander(t, 4, increasing=True) @ c + rng.normal(0, 1e-3, (t.size, 2))
        got = path_cubic(t, q, _window_fit(t, q)[2])
        # (a cubic's coefficient over a 2.4 s window of 72 rows at 1 mm: 4.5e-4 per
        # coordinate; 4 of them, over 20 draws)
        assert got is not None and abs(got - np.linalg.norm(c[3])) < 4 * 5e-4, (seed, got, c[3])
    t = np.arange(0.2, 3.0, 1 / 30)
    q = np.column_stack([np.zeros_like(t), 1.0 * t - 1.0 * t ** 2])   # stops at 0.5 s
    assert path_cubic(t, q, _window_fit(t, q)[2]) is None


def _spinning_rows(rng):
    """A simulated shot's rows (the paper's law at random speed, spin and phi; 25-60 fps;
    first row at release or up to 0.5 s after; 3-8 s): t, centre (m), angle (rad) with
    white or AR(1) noise, and the true angle at t = 0 added to every angle."""
    from curltrack.physics.shot import ShotModel
    from curltrack.simulate import simulate_series

    model = ShotModel(v0=rng.uniform(0.8, 3.5), omega0=rng.choice([-1, 1]) * rng.uniform(0.3, 3),
                      phi_y=rng.uniform(-0.8, 0.3), alpha_y=0.0076 * rng.uniform(0.7, 1.5))
    d = simulate_series(model, fps=float(rng.choice([25.0, 30.0, 60.0]))).data
    late = rng.uniform(0.0, 0.5) if rng.random() < 0.5 else 0.0
    d = d[(d.t >= late) & (d.t <= rng.uniform(3.0, 8.0))]
    t = d.t.to_numpy()
    sig_m, sig_r = rng.uniform(0.3e-3, 2e-3), np.radians(rng.uniform(0.05, 2.0))
    rho = float(rng.choice([0.0, rng.uniform(0.0, 0.7)]))
    e = rng.normal(0.0, 1.0, (t.size, 3))
    for k in range(1, t.size):
        e[k] = rho * e[k - 1] + np.sqrt(1.0 - rho * rho) * e[k]
    theta0 = rng.uniform(0.0, 2.0 * np.pi)
    return (t, d[["x", "y"]].to_numpy() + sig_m * e[:, :2],
            d["theta"].to_numpy() + theta0 + sig_r * e[:, 2], theta0, sig_r)


#: Of the draws whose theta0 the first rows' shared error put over 4 sigma off, the
#: share the check brings back within 4 sigma: 0.75-0.88 over 12 seeds of 100 draws
#: (the rest: errors the later rows' extrapolation cannot tell from the path's own
#: bend).
FOUND_SHARE = 0.6


def test_theta0_check_says_nothing_on_clean_angles_and_finds_what_the_first_share():
    """theta0 against the same fit to the rows from half its window on, extrapolated back
    (``_theta0_check``).  Clean rows (the paper's law, white or AR(1) angle noise of
    0.05-2 deg): it seldom adds anything (5 of 300 draws, twice; the count must be
    plausible for 3 %).  The first 0.2-0.5 s of rows turned 5-20 row sigmas short of the
    rock, fading as it slows (a blurred camcorder's first fields: theta0 7.3 deg off
    under 1.9 deg): where that put theta0 over 4 sigma off, the check brings it back
    within 4 sigma in most draws."""
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    fired_clean, fired, z_before, z_after = 0, 0, [], []
    for _ in range(100):
        t, centre, angle, theta0, sig_r = _spinning_rows(rng)
        ok = np.ones(t.size, bool)
        out = to_shot_frame(t, centre, angle, ok)
        fired_clean += out["theta0_check_sigma_rad"] > 0
        span = rng.uniform(0.2, 0.5)
        lag = rng.uniform(5.0, 20.0) * sig_r * np.clip(1.0 - (t - t[0]) / span, 0.0, 1.0)
        spin = np.sign(np.mean(np.diff(angle)))
        out = to_shot_frame(t, centre, angle - spin * lag, ok)
        err = out["theta0"] - theta0
        fired += out["theta0_check_sigma_rad"] > 0
        z_before.append(err / out["theta0_sigma_rad"])
        z_after.append(err / np.hypot(out["theta0_sigma_rad"], out["theta0_check_sigma_rad"]))
    z_before, z_after = np.abs(z_before), np.abs(z_after)
    msg = f"seed {seed}: clean {fired_clean}, found {fired} of 100"
    assert binom.sf(fired_clean - 1, 100, 0.03) > 1e-3, msg
    big = z_before > 4  # (the draws where the shared error matters)
    assert big.sum() >= 10, msg
    assert np.mean(z_after[big] < 4) >= FOUND_SHARE, (msg, np.round(z_before[big], 1),
                                                      np.round(z_after[big], 1))


def test_theta0_check_needs_a_window_of_later_rows():
    """The check's later fit spans THETA0_CHECK_SPAN windows from THETA0_CHECK_FROM of
    one on; where the rows end before it spans one window (a 2 s interlaced clip whose
    rock still spun: 1.2 s of rows for a fit meant for 3.2 s, extrapolated back 0.8 s,
    its slow error 0.3 deg read as 2 deg and a right theta0 widened to 2.1 deg - CI
    seeds 2913829835, 4079382218), it says nothing; with a window and more it checks."""
    from curltrack.track.shotframe import (THETA0_CHECK_FROM, _spin_stop, _theta0_check,
                                           _theta0_sigma, initial_state)

    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    for _ in range(20):
        t, _, angle, _, _ = _spinning_rows(rng)
        theta = np.unwrap(angle)
        window = rng.uniform(0.5, 1.2)
        start = t[0] + THETA0_CHECK_FROM * window
        for reach, checked in ((rng.uniform(0.3, 0.95), False), (rng.uniform(1.05, 2.0), True)):
            keep = t <= start + reach * window
            tk, qk = t[keep], theta[keep]
            stop = _spin_stop(tk, qk)
            if checked and stop is not None and stop < t[-1]:
                continue  # (the spin's stop ends it sooner: its own rule)
            th0 = float(initial_state(tk, qk, window)[0][0])
            sigma = _theta0_sigma(tk, qk, None, window, stop)
            out = _theta0_check(tk, qk, None, window, th0, sigma, stop)
            what = f"seed {seed}: window {window:.2f} s, rows to {reach:.2f} of one: {out}"
            if not checked:
                assert out == (0.0, 0.0), what
            elif np.count_nonzero(tk >= start) >= 16 and np.isfinite(sigma):
                # (theta0's own sigma infinite - too few rows for its fit - has no check;
                # farm seed 2703459664: 23 rows at 25 fps)
                assert out[1] > 0.0, what
