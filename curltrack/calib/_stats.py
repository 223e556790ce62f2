"""Small robust statistics for the per-frame loops (finite data only).

``np.median`` spends most of its time in argument handling when it is called on a few
hundred numbers, many times per frame; :func:`median` is the same value from one
``np.partition``.
"""

from __future__ import annotations

import numpy as np


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
