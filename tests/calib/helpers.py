"""Helpers for the calibration tests."""

import numpy as np


def align(est, truth, sx, sy, free_offset=False):
    """Error of ``est`` against ``truth`` after the lattice's symmetries.

    The lattice frame may differ from the truth frame by a multiple of 90 deg (equal
    spacings) and by a whole number of cells (origin choice; any offset with
    ``free_offset``).  Returns (rms, errors (N, 2), quarter turns).
    """
    best = None
    for k in range(4):
        if k % 2 and not np.isclose(sx, sy):
            continue
        c, s = np.round(np.cos(k * np.pi / 2)), np.round(np.sin(k * np.pi / 2))
        e2 = est @ np.array([[c, -s], [s, c]]).T
        d = (truth - e2).mean(axis=0)
        off = d if free_offset else np.round(d / (sx, sy)) * (sx, sy)
        err = e2 + off - truth
        rms = float(np.sqrt((err ** 2).sum(axis=1).mean()))
        if best is None or rms < best[0]:
            best = (rms, err, k)
    return best
