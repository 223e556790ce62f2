"""Closed-form shot series with known parameters, for tests of the fit core."""

from __future__ import annotations

import numpy as np
import pandas as pd

from curltrack.fit import shot_frame_model
from curltrack.physics import closed_form as cf
from curltrack.series import Series, make_meta


def closed_form_series(lam_theta=1.455, lam_y=1.897, t_F=24.0, theta_F=2.7 * 2 * np.pi,
                       y_F=25.0, a_T=-5.5e-3, lam_x=None, skew_deg=0.0, t_Ftheta=None,
                       noise_m=0.0, noise_rad=0.0, seed=0, fps=30.0, tail_s=1.0) -> Series:
    """theta(t), y(t), x(t) from the paper's formulas, rotated by ``skew_deg``, + noise."""
    rng = np.random.default_rng(seed)
    t_Ftheta = t_F if t_Ftheta is None else t_Ftheta
    t = np.arange(0.0, max(t_F, t_Ftheta) + tail_s, 1.0 / fps)
    th = cf.decel_position(t, theta_F, lam_theta, t_Ftheta)
    # the fit's translation model: the paper's forms, y shortened by the curl's heading
    X, Y = shot_frame_model({"a_T": a_T, "lambda_y": lam_y, "y_F": y_F, "t_FS": t_F,
                             "lambda_x": lam_y if lam_x is None else lam_x}, t)
    ps = np.radians(skew_deg)
    x = np.cos(ps) * X - np.sin(ps) * Y
    y = np.sin(ps) * X + np.cos(ps) * Y
    n = len(t)
    df = pd.DataFrame(dict(frame=np.arange(n), t=t,
                           x=x + noise_m * rng.standard_normal(n),
                           y=y + noise_m * rng.standard_normal(n),
                           theta=th + noise_rad * rng.standard_normal(n), ok=1))
    meta = make_meta(fps, n, t_stop_translation=t_F, t_stop_rotation=t_Ftheta)
    return Series(df, meta)
