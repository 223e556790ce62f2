"""The smooth field of the threads' misfit of a frame's lattice, and how much of it the
tracker takes off (issue #19.6: a rolling shutter's shear and the lens model's misfit
moved the rock by +-1 mm where the homography could not follow)."""

import numpy as np

from curltrack.calib.lattice import misfit_at, misfit_field
from curltrack.track.results import misfit_gain


def _threads(rng, warp, noise_px, f=700.0, period_px=60.0):
    """Thread points of a lattice (cells = q * f / period) over a 960x540 view, each
    moved across its thread by ``warp(q)`` px (family 0: x, 1: y) plus noise."""
    q, fam, idx = [], [], []
    for fm in (0, 1):
        for line in range(-8, 9):
            along = rng.uniform(-0.68, 0.68, 40) if fm == 0 else rng.uniform(-0.38, 0.38, 40)
            across = line * period_px / f
            pts = (np.column_stack([np.full(40, across), along]) if fm == 0
                   else np.column_stack([along, np.full(40, across)]))
            pts = pts[(np.abs(pts[:, 0]) < 0.68) & (np.abs(pts[:, 1]) < 0.38)]
            q.append(pts)
            fam.append(np.full(len(pts), fm))
            idx.append(np.full(len(pts), line))
    q, fam, idx = np.vstack(q), np.concatenate(fam), np.concatenate(idx)
    shift = warp(q)[np.arange(len(q)), fam] + rng.normal(0, noise_px, len(q))
    # the lattice's coordinates of the moved points: off their thread by shift px
    move = np.zeros_like(q)
    move[np.arange(len(q)), fam] = shift / f
    Hc = np.diag([f / period_px, f / period_px, 1.0])
    return q + move, np.ones(len(q)), fam, idx, Hc, f


def test_field_recovers_a_smooth_warp_and_its_noise():
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    a = rng.uniform(-1.5, 1.5, 2)  # px: a quadratic warp a homography cannot follow
    warp = lambda q: np.column_stack([a[0] * (q[:, 1] / 0.38) ** 2, a[1] * q[:, 0] * q[:, 1] / 0.26])
    q, w, fam, idx, Hc, f = _threads(rng, warp, 0.2)
    field = misfit_field(q, w, fam, idx, Hc, f)
    at = rng.uniform(-0.2, 0.2, (5, 2))
    val, sd = misfit_at(field, at)
    expected = warp(at) / 60.0  # cells
    assert np.all(np.abs(val - expected) < 4 * sd + 1e-4), f"seed {seed}: {val - expected}, sd {sd}"
    assert np.all(sd < 0.1 / 60.0), f"seed {seed}: sd {sd * 60} px"


def test_gain_takes_off_a_clear_misfit_and_leaves_noise_alone():
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    n, sd = 300, 1e-4
    sigma = np.full((n, 2), sd)
    noise_only = rng.normal(0, sd, (n, 2))
    gain, s = misfit_gain(noise_only, sigma)
    # a mean square of pure noise is sd^2 within ~3 x sqrt(2 / n) of it
    assert np.all(gain < 0.3), f"seed {seed}: gain {gain} on noise alone"
    assert np.all(s <= sd * np.sqrt(0.3) + 1e-12)
    signal = 5 * sd * np.sin(np.linspace(0, 6, n))[:, None] * [1, -1] + noise_only
    gain, s = misfit_gain(signal, sigma)
    assert np.all(gain > 0.9), f"seed {seed}: gain {gain} on a misfit 5x its noise"
    assert misfit_gain(np.zeros((0, 2)), np.zeros((0, 2)))[0].shape == (0, 2)


def test_a_misfit_departing_from_its_neighbours_is_counted_as_its_error():
    """A frame's misfit at the rock that departs from its neighbours' (threads beside the
    rock disturbed for a few frames) is an error of that frame as large as the departure;
    a misfit that changes smoothly over the shot (the rock crossing a lens's residual)
    adds next to nothing beyond its noise."""
    from curltrack.track.results import misfit_departure

    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    fps = float(rng.choice([25.0, 30.0, 50.0, 60.0]))
    t = np.arange(int(rng.integers(60, 200))) / fps
    sd = rng.uniform(0.2e-3, 1e-3)
    sigma = np.full((t.size, 2), sd)
    smooth = (rng.uniform(-3e-3, 3e-3, 2) * np.sin(rng.uniform(0.3, 1.5) * t[:, None]
                                                   + rng.uniform(0, 6, 2)))
    misfit = smooth + rng.normal(0, sd, (t.size, 2))
    quiet = misfit_departure(t, misfit, sigma)
    # (noise alone: departures beyond 3 sigma in either coordinate, 0.67 % of the rows
    # over 3000 draws, at most 8 rows in one; each counted at ~2-3 sigma)
    n_quiet = int(np.count_nonzero(quiet > 0))
    assert n_quiet <= max(5, 0.05 * t.size) and np.sqrt(np.mean(quiet ** 2)) < 0.6 * sd, (
        f"seed {seed}: {n_quiet} of {t.size} rows, {quiet[quiet > 0] / sd} sigma")
    k = int(rng.integers(5, t.size - 10))
    width = int(rng.integers(1, 5))
    size = rng.choice([-1, 1]) * rng.uniform(8, 12) * sd
    misfit[k:k + width, int(rng.integers(2))] += size
    loud = misfit_departure(t, misfit, sigma)
    hit = loud[k:k + width] / np.sqrt(0.5)   # (per coordinate: one of two disturbed)
    # (within 5 sigma of the size: the row's own noise, and the median the disturbed
    # rows pull - 4 of the 13 a 0.5 s median holds at 25 fps; CI seed 2509088434 drew a
    # disturbed row 2 sigma against it)
    assert np.all(np.abs(hit - abs(size)) < 5 * sd), (
        f"seed {seed}: {width} frames disturbed by {1e3 * size:.2f} mm (noise "
        f"{1e3 * sd:.2f} mm): {1e3 * hit}")
    assert misfit_departure(t[:2], misfit[:2], sigma[:2]).shape == (2,)
