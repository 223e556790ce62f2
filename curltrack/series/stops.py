"""Stop times for translation and rotation, estimated below one frame.

A noise threshold ("the last frame that differs from the rest level by 3 sigma") fires
several frames early, because the final approach ``q_F - q ~ (t_F - t)^lambda`` sinks
into the noise well before the rock stops.  Instead the final approach is fitted with
the paper's local form

    q(t) = q_F - c * max(t_F - t, 0)^lambda,      (1)

over a window that ends with the rest level, so that every frame of the approach and of
the rest contributes to ``t_F``.  For translation ``q`` is the position projected onto the
direction of the final approach (the curl's sideways part is of second order there); for
rotation ``q`` is the cumulative angle.

Conventions: ``t`` in s (t = 0 at the start frame), ``x``, ``y`` in m, ``theta`` in rad.
``stop_frame_*`` is the first frame with ``t >= t_stop_*`` (contract).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np
import pandas as pd
from scipy.optimize import least_squares

from .noise import robust_sigma, white_sigma

__all__ = ["StopTimes", "detect_stops", "fit_final_approach", "rotation_stop", "series_stops"]

#: Displacement (in units of the noise sigma) below which a coordinate is "not moving".
MIN_MOTION_SIGMA = 12.0
#: Points of rest needed after the fitted stop to call it a stop (not a cut-off video).
MIN_REST_FRAMES = 3
#: Values of tau^lambda evaluated at once by the final-approach grid search (~8 MB).
GRID_BATCH_VALUES = 1_000_000


@dataclass
class StopTimes:
    """End of motion, separately for translation and rotation.

    Attributes
    ----------
    t_stop_translation, t_stop_rotation : float or None
        End of motion (s since the start frame); None when that motion does not stop
        inside the series (still moving at the end); the first time (0) when it never
        moved above the noise.
    stop_frame_translation, stop_frame_rotation : int or None
        First frame with ``t >= t_stop_*``.
    t_stop_translation_err, t_stop_rotation_err : float or None
        1 sigma of ``t_stop_*`` from the fit (s).
    notes : list of str
        Why a stop is None, in words (for the sidecar's warnings).
    """

    t_stop_translation: float | None = None
    t_stop_rotation: float | None = None
    stop_frame_translation: int | None = None
    stop_frame_rotation: int | None = None
    t_stop_translation_err: float | None = None
    t_stop_rotation_err: float | None = None
    notes: list = field(default_factory=list)

    def to_meta(self) -> dict:
        """The sidecar keys (contract names plus ``*_err``); ``notes`` left out."""
        d = asdict(self)
        d.pop("notes")
        return d


def _reduced_residual(t_F, lam, tw, Qw, quad, sigma):
    """Residuals (flattened, in sigmas) with the linear parameters solved out.

    Given (t_F, lambda) every column is linear in its rest level, amplitude (and tau^2
    coefficient): variable projection leaves a 2-parameter nonlinear problem, which is
    searched on a grid first, so no local minimum is mistaken for the stop.
    """
    tau = np.maximum(t_F - tw, 0.0)
    pw = tau ** lam
    A1 = np.column_stack([np.ones_like(tw), -pw])
    out = []
    for j in range(Qw.shape[1]):
        A = np.column_stack([A1, -tau**2]) if (quad and j > 0) else A1
        coef, *_ = np.linalg.lstsq(A, Qw[:, j], rcond=None)
        out.append(Qw[:, j] - A @ coef)
    return np.concatenate(out) / sigma


def _grid_cost(tF_grid, lam_grid, tw, Qw, quad, sigma):
    """Chi-square of :func:`_reduced_residual` on every (t_F, lambda) of a grid, at once.

    The linear parameters are solved from the normal equations of all grid points in
    one batch (the columns are centred first, which the constant term absorbs);
    ``(len(tF_grid), len(lam_grid))``.
    """
    tau = np.maximum(tF_grid[:, None] - tw[None, :], 0.0)  # (T, n)
    pw = tau[:, None, :] ** lam_grid[None, :, None]  # (T, L, n)
    tau2 = tau * tau
    # Gram matrix of the columns 1, -tau^lambda (and -tau^2), from their sums
    s_p = pw.sum(axis=-1)
    s_pp = np.einsum("tln,tln->tl", pw, pw)
    s_pt2 = np.einsum("tln,tn->tl", pw, tau2)
    s_t2 = np.broadcast_to(tau2.sum(axis=-1)[:, None], s_p.shape)
    s_t4 = np.broadcast_to((tau2 * tau2).sum(axis=-1)[:, None], s_p.shape)
    n = np.full(s_p.shape, float(len(tw)))
    total = np.zeros(s_p.shape)
    for j in range(Qw.shape[1]):
        qj = Qw[:, j] - Qw[:, j].mean()  # (so that the constant's sum with q is 0)
        s_pq = pw @ qj
        if quad and j > 0:
            s_t2q = np.broadcast_to((tau2 @ qj)[:, None], s_p.shape)
            G = np.stack([np.stack([n, -s_p, -s_t2], -1), np.stack([-s_p, s_pp, s_pt2], -1),
                          np.stack([-s_t2, s_pt2, s_t4], -1)], -2)
            b = np.stack([np.zeros_like(s_p), -s_pq, -s_t2q], -1)
        else:
            G = np.stack([np.stack([n, -s_p], -1), np.stack([-s_p, s_pp], -1)], -2)
            b = np.stack([np.zeros_like(s_p), -s_pq], -1)
        # Columns scaled to unit norm (tau^lambda is tiny for t_F near the window's
        # start); an all-zero column (t_F before the window) gets a zero coefficient.
        norm = np.sqrt(np.einsum("tlkk->tlk", G))
        d = np.divide(1.0, norm, out=np.zeros_like(norm), where=norm > 0)
        G = G * d[..., :, None] * d[..., None, :] + 1e-12 * np.eye(G.shape[-1])
        b = b * d
        coef = np.linalg.solve(G, b[..., None])[..., 0]
        total += qj @ qj - np.einsum("tlk,tlk->tl", b, coef)
    return np.maximum(total, 0.0) / sigma ** 2


def _tail_scatter(t: np.ndarray, q: np.ndarray, n: int = 12) -> float:
    """Robust sigma of the last ``n`` points about a straight line (0 if too few)."""
    if q.size < n:
        return 0.0
    tt, qq = t[-n:], q[-n:]
    resid = qq - np.polyval(np.polyfit(tt - tt[0], qq, 1), tt - tt[0])
    return robust_sigma(resid)


def fit_final_approach(t: np.ndarray, q: np.ndarray, dt: float, sigma: float | None = None,
                       quad: bool = False):
    """Fit Eq. (1) to coordinates that move toward a rest level and stay there.

    Parameters
    ----------
    t : (N,) array
        Times (s), increasing.
    q : (N,) or (N, k) array
        Coordinates (one unit, one noise level).  Column 0 is the main one and must
        increase toward its rest level (flip its sign before); further columns (e.g. the
        sideways part of a curling approach) share ``t_F`` and ``lambda`` but have their
        own rest level and signed amplitude.
    dt : float
        Nominal frame period (s).
    sigma : float, optional
        Noise sigma of ``q``; estimated from second differences of column 0 when None
        (:func:`curltrack.series.noise.white_sigma`).
    quad : bool
        Add a ``- b tau^2`` term to the columns after the first.  The paper's curl x(t) near the stop is
        exactly ``x_F + A tau^lambda + B tau^2`` (its linear term cancels), so with this
        term the model is exact for a curling draw and a turning direction of motion
        does not bias ``t_F``.

    Returns
    -------
    (t_F, t_F_err, note) : (float or None, float or None, str)
        ``t_F`` is None when the series does not end at rest; ``note`` says why.
    """
    t = np.asarray(t, dtype=float)
    Q = np.asarray(q, dtype=float)
    Q = Q[:, None] if Q.ndim == 1 else Q
    q = Q[:, 0]
    n = t.size
    if n < 8:
        return None, None, "too few measured frames"
    if sigma is None:
        sigma = white_sigma(q)
    # Tracking errors are partly correlated from frame to frame, so second differences
    # can underestimate the scatter at rest; the detrended tail measures it directly.
    sigma = max(sigma, _tail_scatter(t, q))
    span = float(np.median(q[-5:]) - np.median(q[:3]))
    sigma = max(sigma, 1e-9 * max(1.0, abs(span)))
    if span < MIN_MOTION_SIGMA * sigma:
        return None, None, "no motion above the noise"
    q_rest = float(np.median(q[-5:]))
    # Coarse stop: the last frame clearly below the rest level (fires early in noise);
    # on a running median, so that one outlying frame at rest is not taken for motion.
    from scipy.ndimage import median_filter

    below = np.flatnonzero(median_filter(q, size=5, mode="nearest") < q_rest - 3.0 * sigma)
    i_c = int(below[-1]) if below.size else 0
    if i_c >= n - MIN_REST_FRAMES:
        return None, None, "still moving at the end of the series"
    # Window: from where ~35 % of the motion remains, at least 12 frames before i_c.
    cand = np.flatnonzero(q_rest - q[: i_c + 1] > 0.35 * span)
    i_a = int(cand[-1]) if cand.size else 0
    i_a = max(0, min(i_a, i_c - 12))
    tw, Qw = t[i_a:], Q[i_a:]
    # Grid over (t_F, lambda): t_F from a little before the coarse stop (which fires
    # early) to well after it.
    tF_grid = np.arange(t[i_c] - 3 * dt, min(t[-1], t[i_c] + 40 * dt) + dt / 4, dt / 2)
    lam_grid = np.linspace(1.05, 4.0, 24)

    # (in slices of t_F: the batch holds len(lam_grid) x len(tw) values per t_F, and a
    # rock filmed at rest for minutes makes the window long)
    per = max(1, GRID_BATCH_VALUES // (len(lam_grid) * len(tw)))
    grid = np.concatenate([_grid_cost(tF_grid[k:k + per], lam_grid, tw, Qw, quad, sigma)
                           for k in range(0, len(tF_grid), per)])
    i, j = np.unravel_index(np.argmin(grid), grid.shape)
    lo, hi = [tw[0] + dt, 1.0], [t[-1] + 5 * dt, 4.0]
    p0 = np.clip([tF_grid[i], lam_grid[j]], np.array(lo) + 1e-9, np.array(hi) - 1e-9)
    try:
        best = least_squares(lambda p: _reduced_residual(p[0], p[1], tw, Qw, quad, sigma),
                             p0, bounds=(lo, hi), x_scale=[dt, 0.1], diff_step=[1e-4, 1e-4])
    except ValueError:
        return None, None, "final-approach fit failed"
    t_F = float(best.x[0])
    # The main column must approach from below (a positive amplitude).
    tau = np.maximum(t_F - tw, 0.0)
    coef, *_ = np.linalg.lstsq(np.column_stack([np.ones_like(tw), -tau ** best.x[1]]),
                               Qw[:, 0], rcond=None)
    if coef[1] <= 0:
        return None, None, "final-approach fit failed (no approach to rest)"
    if np.count_nonzero(t > t_F) < MIN_REST_FRAMES:
        return None, None, "still moving at the end of the series"
    t_F_err = None
    try:
        J = best.jac
        n_par = 2 + Qw.shape[1] * 2 + (Qw.shape[1] - 1) * int(quad)
        s2 = 2.0 * best.cost / max(1, Qw.size - n_par)
        cov = np.linalg.pinv(J.T @ J) * s2
        t_F_err = float(np.sqrt(max(cov[0, 0], 0.0)))
    except (np.linalg.LinAlgError, ValueError):
        pass
    return t_F, t_F_err, ""


def _first_frame_at(data: pd.DataFrame, t_stop: float | None) -> int | None:
    if t_stop is None:
        return None
    t = data["t"].to_numpy(dtype=float)
    idx = np.flatnonzero(t >= t_stop - 1e-9)
    return int(data["frame"].to_numpy()[idx[0]]) if idx.size else None


def _translation_coordinate(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Position along and across the initial direction of travel, (N, 2) in m.

    In the paper's model the coordinate along the initial velocity follows Eq. (1)
    exactly and the curl across it is ``x_F + A tau^lambda + B tau^2``, so these are the
    axes in which the final-approach model holds (the direction of the *final* approach
    would mix the curl's tau^2 term into the main coordinate).
    """
    r = np.column_stack([x, y])
    r0 = np.median(r[:3], axis=0)
    d0 = np.hypot(*(r - r0).T)
    total = d0.max()
    if total <= 0:
        return np.zeros((len(r), 2))
    # direction from the start to where ~15 % of the largest excursion is reached
    i_a = int(np.flatnonzero(d0 > 0.15 * total)[0])
    lo, hi = max(0, i_a - 2), min(len(r), i_a + 3)
    u = r[lo:hi].mean(axis=0) - r0
    u = u / np.hypot(*u)
    d = r - r0
    return np.column_stack([d @ u, d @ np.array([-u[1], u[0]])])


def rotation_stop(t: np.ndarray, theta: np.ndarray, dt: float):
    """:func:`fit_final_approach` of an angle (rad, either sense of turn: turned to
    increase by the sign of its last rows against its first): ``(t_stop, err, note)``."""
    theta = np.asarray(theta, float)
    sign = np.sign(np.median(theta[-5:]) - np.median(theta[:3])) or 1.0
    return fit_final_approach(t, theta * sign, dt)


def detect_stops(data: pd.DataFrame, fps: float | None = None) -> StopTimes:
    """Stop times of translation and rotation of a series (contract columns).

    Parameters
    ----------
    data : DataFrame
        Columns ``frame, t, x, y, theta, ok``; rows with ``ok`` = 0 or NaN are ignored.
    fps : float, optional
        Frame rate (frames/s); the median frame period of ``t`` when None.

    Returns
    -------
    StopTimes
        ``t_stop_*`` below one frame from a fit of the final approach; the first
        time (0) when that motion never rises above the noise (e.g. the translation of
        a pure rotation); None (with a note) when it is still going at the end.

    Examples
    --------
    >>> stops = detect_stops(series.data, fps=30.0)      # doctest: +SKIP
    >>> stops.t_stop_translation, stops.stop_frame_translation  # doctest: +SKIP
    """
    ok = (data["ok"].to_numpy() == 1)
    vals = data[["t", "x", "y", "theta"]].to_numpy(dtype=float)
    has_th = np.isfinite(vals).all(axis=1)
    # rows measured with an empty theta (a position-only instrument, or a turn count
    # the tracker could not be sure of after a gap) still place the rock: the
    # translation uses every row with t, x, y; the rotation those with theta too
    ok &= np.isfinite(vals[:, :3]).all(axis=1)
    has_th = has_th[ok]
    t, x, y, th = vals[ok].T
    if fps is not None and fps > 0:
        dt = 1.0 / float(fps)
    elif t.size > 1:
        dt = float(np.median(np.diff(t)))
    else:
        dt = 1.0 / 30.0
    out = StopTimes()
    if t.size < 8:
        out.notes.append("too few measured frames to detect stops")
        return out
    q_tr = _translation_coordinate(x, y)
    sig_xy = max(white_sigma(x), white_sigma(y))
    t_tr, e_tr, note = fit_final_approach(t, q_tr, dt, sig_xy if sig_xy > 0 else None,
                                          quad=True)
    if note:
        out.notes.append(f"translation: {note}")
    tr, th = t[has_th], th[has_th]
    if tr.size < 8:
        t_rot, e_rot, note = None, None, "too few measured frames with theta"
    else:
        t_rot, e_rot, note = rotation_stop(tr, th, dt)
    if note:
        out.notes.append(f"rotation: {note}")
    # A motion that never rises above the noise (pure rotation's translation, a
    # non-spinning rock's rotation) is over from the start: t_stop = 0, as the
    # simulator reports it.
    t_first = float(data["t"].iloc[0])
    if t_tr is None and out.notes and out.notes[0] == "translation: no motion above the noise":
        t_tr, e_tr = t_first, 0.0
    if t_rot is None and any(n == "rotation: no motion above the noise" for n in out.notes):
        t_rot, e_rot = t_first, 0.0
    out.t_stop_translation, out.t_stop_translation_err = t_tr, e_tr
    out.t_stop_rotation, out.t_stop_rotation_err = t_rot, e_rot
    out.stop_frame_translation = _first_frame_at(data, t_tr)
    out.stop_frame_rotation = _first_frame_at(data, t_rot)
    return out


def series_stops(series) -> tuple[float | None, float | None, list[str]]:
    """Stop times of a :class:`~curltrack.series.Series` as ``fit`` and ``discover`` use them.

    The sidecar's ``t_stop_translation`` / ``t_stop_rotation`` when it has them (null:
    that motion did not stop in the video); else detected from the series
    (:func:`detect_stops`), with a warning naming the file.  The series is not changed.

    Returns
    -------
    (t_stop_translation, t_stop_rotation, warnings)
        Times in s (None: no stop) and the warnings to pass on.
    """
    keys = ("t_stop_translation", "t_stop_rotation")
    meta = series.meta
    if all(k in meta for k in keys):
        return meta[keys[0]], meta[keys[1]], []
    found = detect_stops(series.data, meta.get("fps"))
    t_tr = meta.get(keys[0], found.t_stop_translation)
    t_rot = meta.get(keys[1], found.t_stop_rotation)

    def said(t):
        return "none" if t is None else f"{t:.3f} s"

    return t_tr, t_rot, [f"{series.name}: no sidecar with stop times; stops detected from "
                         f"the series (translation {said(t_tr)}, rotation {said(t_rot)})"]
