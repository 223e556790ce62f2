"""Values written in steps (rounded to a centimetre, a degree, the digits a file keeps)
carry at least step / sqrt(12) of error per row, which second differences of rows that
repeat a value do not show."""

import numpy as np

from curltrack.series.noise import estimate_noise, resolution


def test_rounded_values_are_floored_at_their_step():
    seed = int(np.random.SeedSequence().entropy % (1 << 32))
    rng = np.random.default_rng(seed)
    step = float(rng.choice([0.01, 0.001, np.radians(1.0)]))
    t = np.arange(0.0, 20.0, 1.0 / float(rng.choice([10, 30])))
    # a rock that slows to rest: late rows repeat a value once rounded
    truth = rng.uniform(1.5, 2.2) * t - 0.05 * t ** 2
    truth = np.where(t < 15.0, truth, truth[t < 15.0][-1])
    q = truth + rng.normal(0.0, step / 4.0, t.size)
    rounded = np.round(q / step) * step
    assert np.isclose(resolution(rounded), step, rtol=1e-6), (seed, step)
    noise = estimate_noise(np.arange(t.size), rounded, t=t)
    assert noise.sigma >= 0.999 * step / np.sqrt(12.0), (seed, step, noise)
    # and never under the rounded values' real error (step/4 of noise, then rounding)
    real = float(np.std(rounded - truth))
    assert noise.sigma > 0.6 * real, (seed, step, noise.sigma, real)
    # measured in floating point, nothing repeats: no step, no floor
    assert resolution(q) == 0.0, seed
