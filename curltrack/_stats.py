"""Small robust statistics shared by every stage (finite data).

The lowest module of the package: ``calib``, ``track`` and ``series`` import it, it
imports nothing of curltrack.  ``np.median`` spends most of its time in argument
handling when it is called on a few hundred numbers, many times per frame;
:func:`median` is the same value from one ``np.partition``.  :func:`robust_sigma` is
the one robust spread (1.4826 x the median absolute deviation).
:func:`value_at_zero` is a series' value at t = 0 from its first rows.
"""

from __future__ import annotations

import numpy as np

__all__ = ["median", "robust_sigma", "value_at_zero", "MAD_TO_SIGMA"]

#: sigma / MAD of a normal distribution, 1 / Phi^-1(3/4)
MAD_TO_SIGMA = 1.482602218505602


def median(a, axis=None):
    """Median of finite data along ``axis`` (None = all), as ``np.median``.

    NaNs are not propagated (unlike ``np.median``): pass finite data.
    """
    a = np.asarray(a)
    if axis is None:
        a, axis = a.ravel(), 0
    n = a.shape[axis]
    if n == 0:
        return np.median(a, axis=axis)  # (numpy's empty-input behaviour and warning)
    k = n // 2
    if n % 2:
        return np.partition(a, k, axis=axis).take(k, axis=axis)
    p = np.partition(a, (k - 1, k), axis=axis)
    return 0.5 * (p.take(k - 1, axis=axis) + p.take(k, axis=axis))


def robust_sigma(v, centre=None, axis=None):
    """1 sigma of normal noise from the median absolute deviation about ``centre``
    (default: the median along ``axis``) - a spread that a few outliers do not move.

    Parameters
    ----------
    v : array
        Data (a NaN gives NaN for ``axis=None``, as ``np.median``; finite along an axis).
    centre : float or array, optional
        Broadcast against ``v``.
    axis : int, optional
        None: one number (float) for all of ``v``; else an array along ``axis``.
    """
    v = np.asarray(v, dtype=float)
    if axis is None:
        if np.isnan(v).any():  # (as np.median)
            return float("nan")
        c = median(v) if centre is None else centre
        return MAD_TO_SIGMA * float(median(np.abs(v - c)))
    c = np.expand_dims(median(v, axis=axis), axis) if centre is None else centre
    return MAD_TO_SIGMA * median(np.abs(v - c), axis=axis)


def value_at_zero(t, v, window_s: float = 1.0, min_rows: int = 5) -> float:
    """The value at t = 0 of a quadratic through the first ``window_s`` seconds of
    ``(t, v)`` (at least ``min_rows`` rows; a line or the first value with fewer):
    where a shot's series starts, whatever its origin and first row's time.

    Parameters
    ----------
    t, v : arrays
        Times (s, increasing) and values, finite.
    """
    t, v = np.asarray(t, float), np.asarray(v, float)
    first = t <= t[0] + window_s
    first[:min_rows] = True
    deg = min(2, int(first.sum()) - 1)
    return float(np.polyval(np.polyfit(t[first], v[first], deg), 0.0)) if deg >= 1 \
        else float(v[0])
