"""Test shots built from the paper's closed forms (independent of the simulator)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from curltrack.physics.closed_form import curl_position, decel_position
from curltrack.series import Series, make_meta


def closed_form_shot(y_F=1.0, t_F=3.0, theta_F=2.0, t_Ftheta=None, a_T=-0.02, lam_y=1.9,
                     lam_theta=1.6, fps=30.0, duration=None) -> Series:
    """A draw (or, with y_F = 0, a pure rotation) sampled at ``fps``, stop times in meta."""
    t_Ftheta = t_F if t_Ftheta is None else t_Ftheta
    end = max(t_F, t_Ftheta) if duration is None else duration
    t = np.arange(int(np.floor(end * fps + 1e-9)) + 1) / fps
    y = decel_position(t, y_F, lam_y, t_F)
    x = curl_position(t, a_T, lam_y, t_F) if y_F > 0 else np.zeros_like(t)
    theta = decel_position(t, theta_F, lam_theta, t_Ftheta)
    data = pd.DataFrame(dict(frame=np.arange(len(t)), t=t, x=x, y=y, theta=theta, ok=1))
    meta = make_meta(fps, len(t), t_stop_translation=t_F if y_F > 0 else 0.0,
                     t_stop_rotation=t_Ftheta)
    return Series(data, meta)


def marker_centroid(img, uv, radius=7.0, smear=(0.0, 0.0), min_saturation=60.0):
    """Saturation-weighted centroid (px) of the coloured blob near ``uv`` (pixel centres).

    Pixels count within ``radius`` of the segment ``uv -+ smear / 2`` (a motion-blurred
    marker is a streak along its image velocity times the exposure).
    """
    smear = np.asarray(smear, dtype=float)
    a, b = np.asarray(uv) - smear / 2, np.asarray(uv) + smear / 2
    r = int(np.ceil(radius + np.abs(smear).max() / 2))
    u0, v0 = int(round(uv[0])), int(round(uv[1]))
    win = img[v0 - r:v0 + r + 1, u0 - r:u0 + r + 1].astype(float)
    sat = win.max(axis=2) - win.min(axis=2)
    w = np.clip(sat - min_saturation, 0, None)
    vv, uu = np.mgrid[v0 - r:v0 + r + 1, u0 - r:u0 + r + 1]
    p = np.stack([uu, vv], -1).astype(float)
    ab = b - a
    s = np.clip(((p - a) @ ab) / max(ab @ ab, 1e-12), 0, 1)
    dist = np.linalg.norm(p - (a + s[..., None] * ab), axis=-1)
    w[dist > radius] = 0
    if w.sum() == 0:
        return np.array([np.nan, np.nan])
    return np.array([(w * uu).sum() / w.sum(), (w * vv).sum() / w.sum()])
