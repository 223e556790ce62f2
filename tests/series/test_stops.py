"""Stop detection against simulated series with known stop times (closed forms + noise)."""

import numpy as np
import pandas as pd
import pytest

from curltrack.physics import closed_form as cf
from curltrack.series.noise import white_sigma
from curltrack.series.stops import detect_stops

FPS = 30.0
NOISE_M = 0.002
NOISE_RAD = np.radians(0.3)


def _draw_series(rng, fps=FPS, still_moving=False):
    """A curling draw + rotation from the paper's closed forms with noise; truth too."""
    t_FS = rng.uniform(4.0, 18.0)
    lam_y = rng.uniform(1.4, 2.3)
    y_F = rng.uniform(3.0, 28.0)
    a_T = rng.uniform(0.01, 0.05) * rng.choice([-1, 1])
    t_Ft = t_FS * rng.uniform(0.7, 1.4)
    lam_t = rng.uniform(1.4, 2.3)
    theta_F = rng.uniform(3.0, 60.0) * rng.choice([-1, 1])
    t_end = (min(t_FS, t_Ft) * 0.8) if still_moving else max(t_FS, t_Ft) + rng.uniform(1.0, 3.0)
    t = np.arange(0.0, t_end, 1.0 / fps) + rng.uniform(0, 0.2 / fps)
    t -= t[0]
    n = t.size
    data = pd.DataFrame({
        "frame": np.arange(n) + 7,
        "t": t,
        "x": cf.curl_position(t, a_T, lam_y, t_FS) + rng.normal(0, NOISE_M, n),
        "y": cf.decel_position(t, y_F, lam_y, t_FS) + rng.normal(0, NOISE_M, n),
        "theta": cf.decel_position(t, theta_F, lam_t, t_Ft) + rng.normal(0, NOISE_RAD, n),
        "ok": 1,
    })
    return data, t_FS, t_Ft


@pytest.mark.parametrize("seed", range(6))
def test_stops_within_one_frame_on_noisy_draws(seed):
    rng = np.random.default_rng(100 + seed)
    data, t_FS, t_Ft = _draw_series(rng)
    # A few lost frames must not matter.
    lost = rng.choice(len(data) - 10, 5, replace=False)
    data.loc[lost, "ok"] = 0
    data.loc[lost, ["x", "y", "theta"]] = np.nan
    s = detect_stops(data, FPS)
    assert s.t_stop_translation is not None and s.t_stop_rotation is not None
    assert abs(s.t_stop_translation - t_FS) * FPS < 1.5
    assert abs(s.t_stop_rotation - t_Ft) * FPS < 1.5
    # stop_frame_* = the first frame with t >= t_stop_*
    for t_stop, frame in ((s.t_stop_translation, s.stop_frame_translation),
                          (s.t_stop_rotation, s.stop_frame_rotation)):
        row = data[data["frame"] == frame].iloc[0]
        assert row["t"] >= t_stop
        assert (data.loc[data["frame"] == frame - 1, "t"] < t_stop).all()
    assert s.t_stop_translation_err is not None and s.t_stop_translation_err < 2.0 / FPS


def test_stops_beat_a_noise_threshold():
    """The fit must be less biased than 'last frame 3 sigma from rest' (which fires early)."""
    rng = np.random.default_rng(7)
    fit_err, thr_err = [], []
    for _ in range(5):
        data, t_FS, _ = _draw_series(rng)
        s = detect_stops(data, FPS)
        fit_err.append(s.t_stop_translation - t_FS)
        y = data["y"].to_numpy()
        rest = np.median(y[-5:])
        i = np.flatnonzero(np.abs(y - rest) > 3 * NOISE_M)[-1]
        thr_err.append(data["t"].iloc[i] - t_FS)
    assert np.median(thr_err) < -2.0 / FPS  # the threshold is early by frames ...
    assert abs(np.mean(fit_err)) < 0.5 / FPS  # ... the fit is not


def test_no_stop_when_still_moving_or_not_moving():
    rng = np.random.default_rng(3)
    data, _, _ = _draw_series(rng, still_moving=True)
    s = detect_stops(data, FPS)
    assert s.t_stop_translation is None and s.stop_frame_translation is None
    assert s.t_stop_rotation is None
    assert any("still moving" in n for n in s.notes)
    # pure rotation: translation never moves -> stopped at t = 0 (as the simulator says)
    t = np.arange(0, 10, 1 / FPS)
    n = t.size
    data = pd.DataFrame({"frame": np.arange(n), "t": t, "x": rng.normal(0, NOISE_M, n),
                         "y": rng.normal(0, NOISE_M, n),
                         "theta": cf.decel_position(t, 20.0, 1.6, 7.3) + rng.normal(0, NOISE_RAD, n),
                         "ok": 1})
    s = detect_stops(data, None)
    assert s.t_stop_translation == 0.0 and s.stop_frame_translation == 0  # never moved
    assert any("no motion" in n for n in s.notes)
    assert abs(s.t_stop_rotation - 7.3) * FPS < 1.5


def test_white_sigma_recovers_white_noise():
    rng = np.random.default_rng(0)
    t = np.linspace(0, 10, 600)
    q = cf.decel_position(t, 20.0, 1.8, 12.0) + rng.normal(0, 0.003, t.size)
    assert white_sigma(q) == pytest.approx(0.003, rel=0.15)


def test_one_outlying_frame_at_rest_is_not_motion():
    rng = np.random.default_rng(11)
    data, t_FS, t_Ft = _draw_series(rng)
    for col, noise in (("y", NOISE_M), ("theta", NOISE_RAD)):
        data.loc[len(data) - 2, col] -= 5 * noise * np.sign(data[col].iloc[-1] or 1.0)
    s = detect_stops(data, FPS)
    assert abs(s.t_stop_translation - t_FS) * FPS < 1.5
    assert abs(s.t_stop_rotation - t_Ft) * FPS < 1.5
