"""Velocities from a series: vx, vy, speed, omega with 1 sigma, by local polynomial fits.

Each measured row's derivative is the slope of a least-squares polynomial (degree
``order``) through the ``2 m + 1`` nearest measured rows of the same stretch - a
Savitzky-Golay filter that also takes irregular times (the design uses the real
``t``).  Stretches are split at the stops (translation for vx, vy; rotation for omega)
and at gaps longer than the window, so no window straddles the kink of a stop.

The 1 sigma is the filter's weights applied to the noise: its level and frame-to-frame
correlation (tracked noise is AR(1)-like, rho ~ 0.5) estimated from the data as
``discover`` does, or the series' ``sigma_xy`` / ``sigma_theta`` where they say more.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .errors import ParameterError
from .series import Series, sample_index

__all__ = ["derivatives", "DERIVATIVE_COLUMNS"]

DERIVATIVE_COLUMNS = ("vx", "vy", "speed", "omega", "sigma_vx", "sigma_vy", "sigma_speed",
                      "sigma_omega")


def _stretches(t, t_stop, max_gap):
    """Index arrays of the rows of each stretch: split at ``t_stop`` and long gaps."""
    cut = np.flatnonzero(np.diff(t) > max_gap) + 1
    if t_stop is not None and np.isfinite(t_stop):
        cut = np.union1d(cut, np.searchsorted(t, t_stop))
    return [s for s in np.split(np.arange(len(t)), cut) if len(s)]


#: knot spacing (s) of the smooth path the noise is measured about (:func:`_off_path`):
#: it follows a sliding rock's deceleration, not noise correlated over a few rows
PATH_KNOT_S = 1.0


def _off_path(t, q, stretches):
    """``q`` minus a least-squares cubic spline in ``t`` (knots every
    :data:`PATH_KNOT_S`), fitted per stretch (NaN rows stay NaN)."""
    from scipy.interpolate import make_lsq_spline

    out = np.full(len(q), np.nan)
    for s in stretches:
        s = s[np.isfinite(q[s])]
        if len(s) < 8:
            continue
        ts = t[s]
        inner = np.linspace(ts[0], ts[-1], max(2, int(np.ceil(np.ptp(ts) / PATH_KNOT_S)) + 1))
        n_coef = len(inner) + 2
        if len(s) < 2 * n_coef:
            inner = inner[[0, -1]]
        knots = np.r_[[ts[0]] * 3, inner, [ts[-1]] * 3]
        try:
            out[s] = q[s] - make_lsq_spline(ts, q[s], knots, k=3)(ts)
        except (ValueError, np.linalg.LinAlgError):  # (times not increasing enough)
            out[s] = q[s]
    return out


def _slopes(t, q, half, order):
    """Slope of the local polynomial at every row, and the filter weights (n, window).

    Returns slope (n,), weights W (n, w), the window's row indices J (n, w), residuals
    of each row's own local fit (n,).
    """
    n = len(t)
    w = min(2 * half + 1, n)
    p = min(order, w - 1)
    lo = np.clip(np.arange(n) - w // 2, 0, n - w)  # windows shifted inside at the ends
    J = lo[:, None] + np.arange(w)[None, :]
    dt = t[J] - t[:, None]
    A = dt[..., None] ** np.arange(p + 1)  # (n, w, p+1)
    P = np.linalg.pinv(A)  # (n, p+1, w)
    coef = np.einsum("npw,nw->np", P, q[J])
    fit_here = coef[:, 0]  # the polynomial at the row itself (dt = 0)
    return coef[:, 1] if p >= 1 else np.full(n, np.nan), P[:, 1] if p >= 1 else None, J, \
        q - fit_here


def _derivative(t, q, sigma, rho, stretches, half, order):
    """d q / d t and its 1 sigma over the given stretches (NaN where too few rows).

    ``sigma`` (per row) and ``rho`` (lag-1 correlation between consecutive rows) describe
    the noise; the slope's variance is w^T C w with C_jk = sigma_j sigma_k rho^|j-k|.
    """
    v, s = np.full(len(t), np.nan), np.full(len(t), np.nan)
    for idx in stretches:
        if len(idx) < 3:
            continue
        slope, W, J, _ = _slopes(t[idx], q[idx], half, order)
        C = rho ** np.abs(J[:, :, None] - J[:, None, :])
        Ws = W * sigma[idx][J]
        v[idx] = slope
        s[idx] = np.sqrt(np.einsum("nj,njk,nk->n", Ws, C, Ws))
    return v, s


def derivatives(series: Series, window_s: float = 0.5, order: int = 2) -> pd.DataFrame:
    """The series' rows with ``vx``, ``vy`` (m/s), ``speed`` (m/s), ``omega`` (rad/s)
    and their 1 sigma ``sigma_vx``, ``sigma_vy``, ``sigma_speed``, ``sigma_omega``.

    Parameters
    ----------
    series : Series
        A SHOT.csv series (``ok`` = 0 rows get empty derivatives).
    window_s : float
        Width of the local fit (s); the number of rows it spans is taken at the series'
        median frame interval (at least ``order + 2`` rows).
    order : int
        Degree of the local polynomial (1-4).

    Returns
    -------
    DataFrame
        A copy of ``series.data`` with the eight columns added.
    """
    if not 1 <= int(order) <= 4:
        raise ParameterError(f"order must be 1-4, got {order}", where="--order")
    if not window_s > 0:
        raise ParameterError(f"window must be > 0 s, got {window_s}", where="--window-s")
    from .series.noise import estimate_noise

    data = series.data.copy()
    meas = series.data[series.data["ok"] == 1]
    t = meas["t"].to_numpy(float)
    out = {c: np.full(len(data), np.nan) for c in DERIVATIVE_COLUMNS}
    if len(t) >= 3:
        dt = float(np.median(np.diff(t)))
        half = max(int(round(window_s / dt / 2)), (int(order) + 1) // 2 + 1)
        rows = np.flatnonzero(series.data["ok"].to_numpy() == 1)
        meta = series.meta
        for cols, stop, sig_col in ((("x", "y"), meta.get("t_stop_translation"), "sigma_xy"),
                                    (("theta",), meta.get("t_stop_rotation"), "sigma_theta")):
            stretches = _stretches(t, stop, max(window_s, 3 * dt))
            for c in cols:
                q = meas[c].to_numpy(float)
                good = np.isfinite(q)
                if good.sum() < 3:
                    continue
                # the noise from the data (AR(1): sigma, lag-1 rho, from the variogram of
                # second differences, up to 6 rows apart) about a smooth path - a sliding
                # rock's own second differences over 6 rows (0.1 m/s^2 x (0.2 s)^2 = 4 mm
                # at 30 fps) are no noise; a stated per-row sigma is kept where larger
                noise = estimate_noise(sample_index(meas)[good],
                                       _off_path(t, q, stretches)[good], name=series.name,
                                       field=c, floor=1e-12)
                sigma = np.full(len(q), noise.sigma)
                if sig_col in meas and np.isfinite(meas[sig_col]).any():
                    stated = meas[sig_col].to_numpy(float)
                    stated = np.where(np.isfinite(stated), stated, np.nanmedian(stated))
                    sigma = stated * max(1.0, noise.sigma / np.nanmedian(stated))
                sub = [s[good[s]] for s in stretches]
                v, s = _derivative(t, np.where(good, q, np.nan), sigma, noise.rho, sub, half,
                                   order)
                name = {"x": "vx", "y": "vy", "theta": "omega"}[c]
                out[name][rows], out[f"sigma_{name}"][rows] = v, s
        speed = np.hypot(out["vx"], out["vy"])
        out["speed"] = speed
        with np.errstate(invalid="ignore", divide="ignore"):
            out["sigma_speed"] = np.where(
                speed > 0, np.hypot(out["vx"] * out["sigma_vx"], out["vy"] * out["sigma_vy"])
                / speed, np.hypot(out["sigma_vx"], out["sigma_vy"]))
    for c in DERIVATIVE_COLUMNS:
        data[c] = out[c]
    return data
