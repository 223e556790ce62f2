"""Lattice frame -> shot frame and the cumulative angle."""

import numpy as np

from curltrack.track.shotframe import choose_axes, to_shot_frame, unwrap_angle


def test_unwrap_through_gaps_and_fast_spin():
    rng = np.random.default_rng(1)
    t = np.arange(0, 5, 1 / 30)
    theta = 12.0 * t - 0.8 * t**2  # up to ~2.3 rad per 3-frame gap
    keep = np.sort(rng.choice(t.size, t.size // 2, replace=False))
    keep = keep[np.diff(np.r_[-1, keep]) <= 3]
    keep = np.r_[0, 1, 2, keep[keep > 2]]
    wrapped = np.angle(np.exp(1j * theta[keep]))
    assert np.allclose(unwrap_angle(t[keep], wrapped) - wrapped[0] + theta[0], theta[keep])


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
