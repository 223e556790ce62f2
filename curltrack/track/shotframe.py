"""Lattice frame -> the contract's shot frame; cumulative angle.

Shot frame (contract): origin = rock centre at t = 0 (from a local fit to the first
frames, not one noisy frame), +y = the lattice axis closest to the initial direction of
travel (for a rock that does not translate: the lattice axis closest to the image's up
direction), +x to the right of +y, theta(0) = 0, CCW seen from above.  The lattice frame
is right-handed seen from above too, so the change of frame is a rotation by a multiple
of 90 deg plus a shift, and angles measured against the lattice carry over unchanged.
"""

from __future__ import annotations

import numpy as np

from .._stats import robust_sigma
from ..sanity import MAX_SPIN
from ..settings import TrackingSettings

__all__ = ["unwrap_angle", "initial_state", "choose_axes", "to_shot_frame"]

# The displacement below which a rock does not translate (``min_travel_m``) and the
# largest deceleration of a sliding rock (``max_deceleration_m_s2``: mu g with mu <= 0.03
# at the slowest speeds of the paper's law) are TrackingSettings (curltrack.settings).
#: Smallest cubic coefficient (m/s^3, jerk / 6) assumed of a rock's path when the
#: quadratic of :func:`initial_state` is extrapolated back to t = 0: the bound measured
#: for a quadratic through a curling rock's path in
#: :data:`curltrack.track.segments.MODEL_JERK_M_S3`.
EXTRAPOLATION_M_S3 = 4e-4
#: Largest |phi| of the friction law mu = alpha u^phi the extrapolation allows for: a
#: deceleration a = mu g at speed u then changes at up to |phi| a^2 / u (m/s^3).  The
#: paper measures phi from -0.82 to -0.52 and cites a calculation giving +0.49.
MAX_ABS_PHI = 1.0
#: Floor of a frame's position scatter about the initial fit (m).
MIN_SCATTER_M = 0.5e-3
#: The same for the angle (rad): 0.06 deg, below the best clips' frame-to-frame scatter
#: (~0.1 deg; a floor only guards a fit through too few frames to show any).
MIN_SCATTER_RAD = 1e-3
#: The rock's largest angular deceleration (rad/s^2) for the angle's origin extrapolated
#: by a straight line: the paper's spins (up to ~4 rad/s) stop over >= ~3 s.
MAX_ANGULAR_DECELERATION = 1.5
#: Smallest cubic coefficient (rad/s^3) of the angle assumed when its quadratic is
#: extrapolated back: the position's bound over the inertia radius (~0.14 m).
EXTRAPOLATION_RAD_S3 = EXTRAPOLATION_M_S3 / 0.14
#: Window (s) of the initial quadratic fit (:func:`initial_state`) that places the
#: origin and the initial velocity.
WINDOW_S = 0.8
#: Longest window (s) of theta0's quadratic, twice the position's: a tracker's angle
#: errors persist over tenths of a second (a marker's sub-pixel bias, an interlaced
#: field's), and over 0.8 s the first rows' share of such an error set every angle off
#: by it (rendered hand-held interlaced 720x480 clips: theta error/sigma RMS up to
#: 1.5-1.8 from that offset alone; over 1.6 s at most ~1.3 on the same errors).
ANGLE_WINDOW_S = 1.6
#: ... but at most this fraction of the time the rock's translation would take to stop
#: at its initial deceleration (speed / deceleration of the positions' fit): a spin
#: slows with the rock, faster and faster near the stop: a quadratic over a window of
#: 0.2 / 0.3 / 0.5 / 0.65 of the real stop time misses theta0 by ~0.01 / 0.05 / 0.25 /
#: 1 deg (simulated draws of 2.5-10 s).  The linear stop time is about twice the real
#: one: 0.15 of it keeps the window under ~0.3 of the stop.
ANGLE_WINDOW_STOP_FRACTION = 0.15


#: A gap: a step between measured frames longer than this many typical frame steps.
GAP_STEPS = 1.5
#: The spin rate each side of a gap is the slope of a line through up to this many
#: measured frames within :data:`RATE_SPAN_S` of the gap.
RATE_FRAMES = 6
RATE_SPAN_S = 0.3
#: A gap's turn count is taken as certain when the nearest branch is closer to the
#: predicted angle than the next by at least twice this many sigmas of the prediction
#: (the measured angle |r| from it: |r| + Z sigma < pi).
TURN_Z = 3.0


def _angle_noise(cum, runs) -> float:
    """1 sigma (rad) of one frame's angle: second differences within runs of
    consecutive frames (robust; floor :data:`MIN_SCATTER_RAD`)."""
    d2 = [np.diff(cum[i:j], 2) for i, j in runs if j - i >= 3]
    d2 = np.concatenate(d2) if d2 else np.empty(0)
    return max(robust_sigma(d2) / np.sqrt(6.0) if d2.size >= 3 else 0.0, MIN_SCATTER_RAD)


def _edge_rate(t, cum, noise, before: bool):
    """(rate rad/s, its 1 sigma, the time it is the rate at) from a line through up to
    :data:`RATE_FRAMES` frames within :data:`RATE_SPAN_S` of one end of ``t``; None from
    fewer than two frames."""
    sel = (t >= t[-1] - RATE_SPAN_S) if before else (t <= t[0] + RATE_SPAN_S)
    tk, qk = t[sel], cum[sel]
    tk, qk = (tk[-RATE_FRAMES:], qk[-RATE_FRAMES:]) if before else (tk[:RATE_FRAMES],
                                                                    qk[:RATE_FRAMES])
    if tk.size < 2:
        return None
    tc = tk - tk.mean()
    sxx = float(tc @ tc)
    return float(tc @ qk) / sxx, noise / np.sqrt(sxx), float(tk.mean())


def unwrap_angle(t: np.ndarray, phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cumulative angle from wrapped angles, and whether each one's turn count is sure.

    Within a run of consecutive frames each step takes the 2 pi branch nearest the
    prediction from the last angular velocity.  Across a gap (a step longer than
    :data:`GAP_STEPS` typical steps) the angle is predicted from the spin rates
    measured on both sides (linear fits near the gap; the rate taken as changing
    linearly between them, so exact at a constant angular deceleration) or, with
    frames on one side only, from the rate before it and a deceleration of up to
    :data:`MAX_ANGULAR_DECELERATION`.  The prediction's 1 sigma holds the rates'
    errors (from the frames' own angle noise), the two ends' noise and the rate's
    unknown course between them (a monotone rate: anywhere between its two ends'
    values, taken as uniform).  When the nearest branch does not win by
    :data:`TURN_Z` of that sigma (|r| + Z sigma >= pi, r the measured angle's offset
    from the prediction), the turn count across the gap is not certain: that row and
    every later one are flagged (their angle is off by an unknown whole turn).

    Parameters
    ----------
    t : (N,) array
        Times (s), increasing, no NaN.
    phi : (N,) array
        Angles (rad), any branch.

    Returns
    -------
    (theta, sure) : (N,) float array (rad), (N,) bool array
    """
    t = np.asarray(t, float)
    out = np.empty_like(phi, dtype=float)
    sure = np.ones(phi.size, bool)
    if phi.size == 0:
        return out, sure
    step = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    gap = np.r_[False, np.diff(t) > GAP_STEPS * step]
    starts = np.flatnonzero(np.r_[True, gap[1:]])
    runs = list(zip(starts, np.r_[starts[1:], phi.size]))
    for i, j in runs:  # each run on its own first (consecutive frames: one-step rate)
        out[i] = phi[i]
        omega = 0.0
        for k in range(i + 1, j):
            pred = out[k - 1] + omega * (t[k] - t[k - 1])
            out[k] = phi[k] + 2 * np.pi * np.round((pred - phi[k]) / (2 * np.pi))
            if t[k] > t[k - 1]:
                omega = (out[k] - out[k - 1]) / (t[k] - t[k - 1])
    noise = _angle_noise(out, runs)
    for (i, j), (k, m) in zip(runs[:-1], runs[1:]):  # then each gap, left to right
        ta, tb = t[j - 1], t[k]
        dt = tb - ta
        a = _edge_rate(t[:j], out[:j], noise, before=True)
        b = _edge_rate(t[k:m], out[k:m], noise, before=False)
        mid = 0.5 * (ta + tb)
        if a is None and b is None:
            # single frames on both sides (rows left out every other frame): no rate,
            # but a rock turns by at most MAX_SPIN dt across the gap - one branch within
            # it where that is under half a turn
            turns = np.round((out[j - 1] - out[k]) / (2 * np.pi))
            out[k:m] += 2 * np.pi * turns
            reach = MAX_SPIN * dt + TURN_Z * np.sqrt(2.0) * noise
            if not (abs(out[k] - out[j - 1]) <= reach < np.pi):
                sure[k:] = False
            continue
        if a is not None and b is not None:
            lam = (mid - a[2]) / max(b[2] - a[2], 1e-9)
            rate = (1 - lam) * a[0] + lam * b[0]
            pred = out[j - 1] + rate * dt
            sig = np.sqrt(dt ** 2 * ((1 - lam) ** 2 * a[1] ** 2 + lam ** 2 * b[1] ** 2)
                          + (abs(a[0] - b[0]) * dt / 2.0) ** 2 / 3.0)
        else:
            (w, sw, tw) = a if a is not None else b
            pred = out[j - 1] + w * dt
            sig = np.sqrt((sw * dt) ** 2
                          + (MAX_ANGULAR_DECELERATION * abs(mid - tw) * dt) ** 2 / 3.0)
        sig = float(np.hypot(sig, np.sqrt(2.0) * noise))
        turns = np.round((pred - out[k]) / (2 * np.pi))
        out[k:m] += 2 * np.pi * turns
        if abs(out[k] - pred) + TURN_Z * sig >= np.pi:
            sure[k:] = False
    return out, sure


def window_rows(t, window_s: float = WINDOW_S, min_points: int = 8) -> tuple[int, int]:
    """(rows, degree) of :func:`initial_state`'s fit: the first ``window_s`` seconds of
    ``t`` (at least ``min_points`` rows), a quadratic - a straight line or a constant
    with too few rows."""
    n = min(max(min_points, int(np.count_nonzero(t <= t[0] + window_s))), len(t))
    return n, (2 if n >= 6 else (1 if n >= 2 else 0))


#: A row whose own sigma is up to this many times the lower quartile of the rows'
#: sigmas weighs fully in the origin's fit (:func:`row_weights`); beyond, as
#: 1 / sigma^2.  A row's sigma tells a doubtful row from the others, not finely which
#: of the good ones to trust most: weighted by 1 / sigma^2 throughout, the camera
#: bench's 0.49 Mbit/s camcorder (origin extrapolated 0.25 s) went from 5.3 to 8.1 mm.
#: (The quartile, not the median: in a clip measured in a few frames half the first
#: rows may be doubtful - ``test_wrong_cell`` seed 61122235.)
FULL_WEIGHT_SIGMA_RATIO = 2.0


def row_weights(sigma) -> np.ndarray | None:
    """Least-squares weights of rows whose own 1 sigma is ``sigma`` (any unit): 1 up to
    :data:`FULL_WEIGHT_SIGMA_RATIO` times the lower quartile of the sigmas, ``(that /
    sigma)^2`` beyond; a row without a finite, positive sigma weighs 1.  None for no
    sigmas.

    The origin is a fit to the first rows: a row whose own fit is far less sure than
    its neighbours' (a doubtful grid, a half-hidden marker) must not move it as much
    (a hand-held clip measured in 9 of 90 frames, ``test_wrong_cell`` seed 61122235:
    three rows 7-20 mm off the others under own sigmas 6-8x theirs bent the unweighted
    quadratic, and every row was 10-13 mm off).
    """
    if sigma is None:
        return None
    s = np.asarray(sigma, float)
    good = np.isfinite(s) & (s > 0)
    if not good.any():
        return None
    w = np.ones(s.shape)
    full = FULL_WEIGHT_SIGMA_RATIO * float(np.percentile(s[good], 25))
    w[good] = np.minimum(1.0, (full / s[good]) ** 2)
    return w


def _intercept_weights(A: np.ndarray, sw: np.ndarray, at: float = 0.0) -> np.ndarray:
    """p0 with the weighted least-squares fit's value at t = ``at`` (s; default 0) =
    ``p0 @ q`` (rows of the design ``A``: 1, t, t^2 ... columns; square-root weights
    ``sw``)."""
    x = float(at) ** np.arange(A.shape[1])
    return x @ np.linalg.pinv(A * sw[:, None]) * sw


def origin_weights(t, weights=None) -> tuple[int, np.ndarray]:
    """(m, p0): :func:`initial_state`'s fit takes its value at t = 0 as ``p0 @ q[:m]``
    of the first ``m`` rows at times ``t`` (before its robust pass; ``weights`` as
    :func:`to_shot_frame`'s) - how an error of those rows reaches the origin."""
    m, deg = window_rows(t)
    sw = np.ones(m) if weights is None else np.sqrt(np.asarray(weights, float)[:m])
    return m, _intercept_weights(np.vander(t[:m], deg + 1, increasing=True), sw)


def _first_late(t) -> bool:
    """Whether the first of the times ``t`` (s) is after t = 0 by more than half a
    frame step: then a value at t = 0 is extrapolated (a rolling shutter times the
    first frame's row a fraction of a millisecond late, which extrapolates nothing)."""
    return bool(len(t) > 0 and t[0] > 0 and (
        len(t) < 2 or t[0] > 0.5 * float(np.median(np.diff(t)))))


def _angle_window(coef) -> float:
    """theta0's window (s) from the positions' initial quadratic ``coef`` (3, 2):
    :data:`ANGLE_WINDOW_S`, shortened to :data:`ANGLE_WINDOW_STOP_FRACTION` of the
    translation's linear stop time, never below the positions' :data:`WINDOW_S`."""
    v, a = coef[1], 2.0 * coef[2]
    speed = float(np.hypot(*v))
    decel = -float(a @ v) / max(speed, 1e-9)
    t_stop = speed / decel if decel > 0 else np.inf
    return float(np.clip(ANGLE_WINDOW_STOP_FRACTION * t_stop, WINDOW_S, ANGLE_WINDOW_S))


def _window_fit(t, q, window_s: float = WINDOW_S, min_points: int = 8, weights=None):
    """The polynomial fit of :func:`initial_state` to the first ``window_s`` seconds.

    A quadratic (a straight line / a constant with too few rows) by least squares -
    weighted by ``weights`` (N,) when given (:func:`row_weights`) - with one robust
    pass: rows more than 3 robust sigmas off the first fit in any column (residuals
    scaled by the square-root weights) are dropped and the fit is made again on the rest.

    Returns
    -------
    (deg, A, coef, res, sw)
        The degree, the design (rows kept, columns 1, t, t^2 up to ``deg``), the
        coefficients (deg + 1, k), the kept rows' residuals (rows, k) and their
        square-root weights (rows,; ones unweighted); ``t``, ``q`` as in
        :func:`initial_state`.
    """
    q = np.asarray(q, float).reshape(len(t), -1)
    n, deg = window_rows(t, window_s, min_points)
    A = np.vander(t[:n], deg + 1, increasing=True)
    qq = q[:n]
    sw = np.ones(n) if weights is None else np.sqrt(np.asarray(weights, float)[:n])
    coef, *_ = np.linalg.lstsq(A * sw[:, None], qq * sw[:, None], rcond=None)
    if n > deg + 4:
        z = (qq - A @ coef) * sw[:, None]
        mad = robust_sigma(z, axis=0)
        keep = np.all(np.abs(z) <= 3 * np.maximum(mad, 1e-12), axis=1)
        if keep.sum() > deg + 2:
            A, qq, sw = A[keep], qq[keep], sw[keep]
            coef, *_ = np.linalg.lstsq(A * sw[:, None], qq * sw[:, None], rcond=None)
    return deg, A, coef, qq - A @ coef, sw


def initial_state(t: np.ndarray, q: np.ndarray, window_s: float = WINDOW_S, min_points: int = 8):
    """Value and rate at t = 0 from a quadratic fit to the first ``window_s`` seconds.

    Parameters
    ----------
    t : (N,) array
        Times of measured frames (s).
    q : (N,) or (N, k) array
        Coordinates.

    Returns
    -------
    (q0, rate0) : arrays of shape (k,)
    """
    deg, _, coef, _, _ = _window_fit(t, q, window_s, min_points)
    return coef[0], (coef[1] if deg >= 1 else np.zeros_like(coef[0]))


def _origin_sigma(t: np.ndarray, q: np.ndarray, max_deceleration_m_s2: float,
                  window_s: float = WINDOW_S, min_points: int = 8, min_scatter=MIN_SCATTER_M,
                  min_cubic=EXTRAPOLATION_M_S3, noise=None, extrapolated=True,
                  weights=None, field=None, scatter: float = 0.0,
                  measure_cubic: bool = True) -> float:
    """1 sigma (m; per coordinate) of the value at t = 0 of :func:`initial_state`'s fit.

    The fit's own variance plus, when the first frame is after t = 0
    (``extrapolated``), a model term: the path's departure from a quadratic
    (``min_cubic``), or for a straight line through too few frames, the deceleration it
    cannot see (``max_deceleration_m_s2``, m/s^2); the cubic is measured on the rows
    after (:func:`path_cubic`) where that is less than its bound.  Infinite when fewer
    than two frames are measured.  ``q`` (N, k) is k coordinates of one point (k = 2: x, y, their
    variances averaged; k = 1 with the angle's ``min_scatter``, ``min_cubic`` and
    deceleration in radians: its origin theta0).

    The fit's variance is, by default, the sandwich of its design with each kept
    frame's own residual, leverage-corrected (HC3, r_i / (1 - h_ii): about the
    delete-one jackknife's variance): it needs no noise model, and a few early frames
    that the fit bends towards - they weigh most on its value at t = 0 - count with
    the error they carry, not with the shot's average scatter - and, extrapolated, at
    least the variance under the residuals' own AR(1) correlation (errors that persist
    from row to row, which an extrapolation multiplies).  ``noise`` (sigma, rho):
    instead, the intercept's variance under that AR(1) frame noise (of the whole
    series; optionally ``(sigma, rho, step_s)``: rho per ``step_s`` seconds, e.g. one
    interlaced field's step, twice the rows'), or under the window's own residuals'
    AR(1) noise where that is larger beyond its own sampling error (errors that persist
    over the first rows more than over the shot: the sweep's phones, blurred and coded
    at their fastest there - 39 renders' theta0 error over its sigma RMS 2.00 -> 1.53,
    over 3 sigma 3 -> 1 of them; ``field``: the rows' interlaced fields,
    :func:`_row_correlation`).  Floor:
    ``min_scatter`` (m or rad) as white noise.  ``weights``: the fit's row weights
    (:func:`row_weights`).  ``scatter``: the value's own error as the same fit shows it
    elsewhere in the shot (:func:`intercept_scatter`), taken where it is larger.
    """
    q = np.asarray(q, float).reshape(len(t), -1)
    deg, A, coef, res, sw = _window_fit(t, q, window_s, min_points, weights)
    if deg == 0:
        return float("inf")
    p0 = _intercept_weights(A, sw)
    floor = min_scatter * float(np.sqrt(p0 @ p0))
    if noise is not None:
        # frames' errors that persist (blur, exposure, the lattice's fit): the
        # intercept's variance under the whole series' AR(1) noise (sigma, rho)
        sig, rho = max(noise[0], min_scatter), noise[1]
        step = noise[2] if len(noise) > 2 else float(np.median(np.diff(t)))
        tk = A[:, 1]
        lag = np.abs(np.subtract.outer(tk, tk)) / max(step, 1e-9)
        stat = sig * float(np.sqrt(max(p0 @ (rho ** lag) @ p0, 0.0)))
        if len(res) >= 12:
            f_w = None if field is None else np.asarray(field)[np.searchsorted(t, tk)]
            res_u = res * sw[:, None]
            rho_w, corr = _row_correlation(res_u, tk, f_w, f_w)
            stat_w = float(np.sqrt(_correlated_variance(res_u, p0 / sw, corr, rho_w,
                                                        A.shape[1])))
            # (only where it is larger beyond its own sampling error, 2 sigma: a few
            # dozen rows' noise read as often too high as too low, and the larger of two
            # readings is biased - clean simulated rows' theta0 error over sigma RMS
            # 0.71 -> 0.67 with the bare maximum)
            n_eff = len(res) * (1 - rho_w) / (1 + rho_w)
            if stat_w > stat * (1.0 + 2.0 / np.sqrt(2.0 * max(n_eff, 1.0))):
                stat = stat_w
    else:
        # (the bench's 640x360 hand-held clip: frames 1-3 read 6 mm across the rink off
        # the rest, the quadratic bent to them and every row was 3.7 mm off; a common
        # white scatter said 0.8 mm, the sandwich says 2.1)
        Aw = A * sw[:, None]
        h = np.einsum("ij,ji->i", Aw, np.linalg.pinv(Aw))
        u = res / np.maximum(1.0 - h, 1e-3)[:, None] if A.shape[0] > A.shape[1] else 0 * res
        stat = float(np.sqrt(np.mean(np.sum(p0[:, None] ** 2 * u ** 2, axis=0))))
        # ... and never under the pooled scatter's: the row at t = 0 carries half the
        # intercept, and its own residual, which the fit bends to, cannot show its error
        # (seed 3618270683: leverage 0.53, residual 0.16 mm for a 3.8 mm error; the
        # origin 4 mm off under 0.46 mm.  300 simulated starts per seed, origin error
        # over sigma RMS over 30 seeds 0.90-1.15 -> 0.85-1.04)
        if A.shape[0] > A.shape[1]:
            res_u = res * sw[:, None]
            pooled = float(np.sum(res_u ** 2)) / (res_u.size - A.shape[1] * res_u.shape[1])
            stat = max(stat, float(np.sqrt(pooled * np.sum((p0 / sw) ** 2))))
        if extrapolated and len(res) >= 12:
            # ... which takes the rows' errors as independent: extrapolated back from
            # rows whose errors persist (a tracker's: rho 0.4-0.6), under the residuals'
            # own AR(1) correlation where that is larger (simulated paths first measured
            # 0.1-0.6 s after release under AR(1) noise of rho 0-0.8: the origin's error
            # over its sigma RMS 1.34 -> 1.00; white noise 0.89 -> 0.84)
            res_u = res * sw[:, None]
            rho_w, corr = _row_correlation(res_u, A[:, 1])
            stat = max(stat, float(np.sqrt(_correlated_variance(res_u, p0 / sw, corr, rho_w,
                                                                 A.shape[1]))))
    stat = max(stat, floor, scatter)
    if not extrapolated:
        return float(stat)
    tk = A[:, 1]
    if deg == 2:
        # the path's cubic term (_cubic_size) times what a cubic does to this fit's
        # intercept
        cubic = _cubic_size(t, q, coef, tk, weights, min_cubic, measure_cubic)
        # (what the extrapolation adds: the fit's own cubic bias at its first row is not
        # counted where the first row is at t = 0 either - a DV field one frame late,
        # 0.04 s, took the bound's whole 1.8 mm for rows 0.5 mm off, e/sigma 0.20)
        t0 = float(t[0])
        p_first = _intercept_weights(A, sw, at=t0)
        model = cubic * abs(float(p0 @ tk ** 3) - (float(p_first @ tk ** 3) - t0 ** 3))
    else:
        model = 0.5 * max_deceleration_m_s2 * float(t[0]) * (float(t[0]) + float(np.ptp(tk)))
    return float(np.hypot(stat, model))


def _linear_stop(coef) -> tuple[float, float, float]:
    """(speed, |acceleration|, time to stop) at t = 0 of a quadratic fit's ``coef``
    (1, t, t^2 terms; per coordinate): the speed at least 0.05, the stop at the speed
    over the deceleration along the motion (infinite where the rock does not slow)."""
    v, a = coef[1], 2.0 * coef[2]
    speed = max(float(np.linalg.norm(v)), 0.05)
    decel = -float(np.sum(a * v)) / speed
    return speed, float(np.linalg.norm(a)), (speed / decel if decel > 0 else np.inf)


#: Span (s, from the first row) over which :func:`path_cubic` measures the path's cubic
#: term, ended before :data:`ORIGIN_CHECK_STOP_FRACTION` of the time to stop.
CUBIC_WINDOW_S = 3.0 * WINDOW_S
#: Fewest rows :func:`path_cubic` fits a cubic to.
CUBIC_MIN_ROWS = 16


def _cubic_size(t, q, coef, tk, weights, min_cubic: float, measure: bool = True) -> float:
    """The path's cubic coefficient (units of ``q`` per s^3) that a quadratic ``coef``
    fitted at times ``tk`` may miss: bounded from its own deceleration and speed (a
    slow rock on keen ice decelerates faster and changes its deceleration faster: a
    640x360 handheld draw first measured 1 s after release was 22 mm off its
    extrapolated origin, against ~3 mm from a fixed bound) - or measured over the rows
    after (:func:`path_cubic`), where that is less (the bound is |phi| <= 1's: the
    sweep's draws, phi -0.1 near their start, had origins 0.5 mm off under 2-8 mm);
    never under ``min_cubic``.  ``measure``: False takes the bound alone."""
    accel = 2.0 * np.linalg.norm(coef[2])
    speed = np.linalg.norm(coef[1] + 2.0 * coef[2] * float(np.mean(tk)))
    cubic = max(min_cubic, MAX_ABS_PHI * accel ** 2 / max(speed, 0.05) / 6.0)
    measured = path_cubic(t, q, coef, weights) if measure else None
    if measured is not None:
        cubic = max(min_cubic, min(cubic, measured))
    return float(cubic)


def origin_cubic_bias(t, q, A, coef, sw, weights=None) -> tuple[float, float]:
    """(moment, cubic) of the origin's quadratic fit (:func:`_window_fit`'s design
    ``A``, coefficients ``coef`` and root weights ``sw`` over the rows ``t``, ``q`` with
    row ``weights``): its value at t = 0 moves by ``cubic * moment`` (m) for a path
    whose cubic coefficient is ``cubic`` (m/s^3, :func:`_cubic_size`); ``moment`` (s^3)
    is the fit's value at t = 0 of t^3."""
    tk = A[:, 1]
    moment = float(_intercept_weights(A, sw) @ tk ** 3)
    return moment, _cubic_size(t, q, coef, tk, weights, EXTRAPOLATION_M_S3)


def path_cubic(t: np.ndarray, q: np.ndarray, coef: np.ndarray, weights=None) -> float | None:
    """The size of the path's cubic coefficient (m/s^3 or rad/s^3; jerk / 6) near its
    start, measured: a cubic through the rows of :data:`CUBIC_WINDOW_S` after the first
    (ended before :data:`ORIGIN_CHECK_STOP_FRACTION` of the time to stop that the
    initial fit's ``coef`` - 1, t, t^2 terms - gives), the root of its squared norm
    plus its variance (under the residuals' own AR(1) correlation from row to row);
    None where no such window has :data:`CUBIC_MIN_ROWS` rows and a quarter of its span
    (a rock that stops within ~2.5 s, a 2.2 s clip: the bound, 3x the cubic measured
    over 0.94 s, put a DV clip's rows under a 0.9 mm sigma for 0.5 mm errors).

    A deceleration that changes with speed (a = k u^phi) makes the path's cubic grow
    as the rock slows (phi a^2 / u, up to 1 / u^2 for phi = -1): the window after the
    first row measures at least the cubic the extrapolation back to t = 0 meets.
    """
    t = np.asarray(t, float)
    q = np.asarray(q, float).reshape(len(t), -1)
    t_stop = _linear_stop(coef)[2]
    end = min(t[0] + CUBIC_WINDOW_S, t[0] + ORIGIN_CHECK_STOP_FRACTION * t_stop)
    sel = (t >= t[0]) & (t <= end) & np.isfinite(q).all(axis=1)
    n = int(np.count_nonzero(sel))
    if n < CUBIC_MIN_ROWS or end - t[0] < 0.25 * CUBIC_WINDOW_S:
        return None
    A = np.vander(t[sel] - t[0], 4, increasing=True)  # (the cubic term is the same)
    sw = np.ones(n) if weights is None else np.sqrt(np.asarray(weights, float)[sel])
    Aw = A * sw[:, None]
    c, *_ = np.linalg.lstsq(Aw, q[sel] * sw[:, None], rcond=None)
    res = (q[sel] - A @ c) * sw[:, None]
    rho = _row_correlation(res, t[sel])[0]
    s2 = np.sum(res ** 2, axis=0) / (n - 4) * (1.0 + rho) / (1.0 - rho)
    var = s2 * float(np.linalg.pinv(Aw.T @ Aw)[3, 3])
    return float(np.sqrt(np.sum(c[3] ** 2 + var)))


#: The origin's check (:func:`origin_check`): the initial quadratic's value at t = 0
#: against a cubic's through later rows, extrapolated back - over each of these windows
#: (start after the first row, span; s): an error the first rows share that fades by
#: ~0.4 s is seen best from the first (its white noise gain at 30 fps ~2.5x a row's
#: sigma, the initial fit's 0.56x), one that lasts longer from the second (~1.8x).
ORIGIN_CHECK_WINDOWS = ((0.5 * WINDOW_S, 2.0 * WINDOW_S), (0.75 * WINDOW_S, 3.0 * WINDOW_S))
#: A window ends before this fraction of the rock's linear stop time L (speed /
#: deceleration of the initial fit): under the steepest law allowed (phi = -1, where
#: the rock stops at L / 2) it still has 45 % of its speed there.  The bounds on the
#: path's next terms are taken at the window's end, at that law's speed and deceleration.
ORIGIN_CHECK_STOP_FRACTION = 0.4
#: The values disagree when their squared difference over its variance (white rows,
#: both fits' bounds on the path's next term) exceeds this in either window: chi^2 with
#: 2 degrees of freedom at 99.5 % (99 % for the two looks together).
ORIGIN_CHECK_CHI2 = 10.6


def origin_check(t: np.ndarray, q: np.ndarray, min_cubic=EXTRAPOLATION_M_S3,
                 windows=ORIGIN_CHECK_WINDOWS, weights=None, field=None) -> dict:
    """The origin's error that its own fit cannot see: its first rows against the rest.

    The first rows of a shot are measured as no others are: the camera starts to
    follow the rock, which crosses the image fastest then, and the stream's encoder
    codes the first frames of a moving scene.  An error those rows share bends the
    initial quadratic with them and leaves no scatter about it (a rendered ladder camera
    coded at 1.4 Mbit/s: its first 10 rows lagged ~3 mm behind the rock - the encoder's
    trailing edge - and every row of the shot was 3.6 mm off under a 0.6 mm
    ``sigma_xy``).  Here a cubic through later rows (``windows``) is extrapolated back
    to t = 0: where the two values differ by more than the rows' white scatter and the
    fits' bounds on the path's next term allow (:data:`ORIGIN_CHECK_CHI2`), the excess
    is the origin's systematic error, which no one can place in either fit.

    The bounds: a deceleration a = k u^phi (|phi| <= :data:`MAX_ABS_PHI`) changes at
    phi a^2 / u (the quadratic's cubic term, as :func:`_origin_sigma`) and that rate at
    phi (2 phi - 1) a^3 / u^2, at most 3 a^3 / u^2 (the cubic's quartic term is a
    twenty-fourth of it).

    What it cannot see: an error under ~3x the check's white noise (~8x a row's sigma
    for the short window), or one that lasts as long as the windows.

    Parameters
    ----------
    t : (N,) array
        Times of the measured rows (s), increasing.
    q : (N, k) array
        Their coordinates (m).
    min_cubic : float
        The path's smallest cubic coefficient assumed (m/s^3), as :func:`_origin_sigma`.
    windows : sequence of (start, span)
        The check's windows (s after the first row, s).
    weights : (N,) array, optional
        Both fits' row weights (:func:`row_weights`; the rows' scatter is then read in
        units of a row of weight 1).
    field : (N,) int array, optional
        Interlaced video: each row's field (0/1).  The rows' correlation is then read
        within each field too (:func:`_row_correlation`).

    Returns
    -------
    dict
        ``sigma`` (per coordinate, m; 0 when they agree or no check is possible),
        ``difference`` (m: the values' distance in the window that disagrees most),
        ``chi2`` (its squared difference over the variance; NaN when no window can be
        fitted: too few rows, or a rock that stops too soon).
    """
    t = np.asarray(t, float)
    q = np.asarray(q, float).reshape(len(t), -1)
    field = None if field is None else np.asarray(field)
    out = {"sigma": 0.0, "difference": 0.0, "chi2": float("nan")}
    if len(t) < 16:
        return out
    w_all = np.ones(len(t)) if weights is None else np.asarray(weights, float)
    deg1, A1, coef1, res1, sw1 = _window_fit(t, q, weights=weights)
    if deg1 < 2:
        return out
    speed, accel, t_stop = _linear_stop(coef1)
    p1 = _intercept_weights(A1, sw1)
    cubic1 = max(min_cubic, MAX_ABS_PHI * accel ** 2 / speed / 6.0)
    for from_s, span_s in windows:
        start = t[0] + from_s
        end = min(start + span_s, t[0] + ORIGIN_CHECK_STOP_FRACTION * t_stop)
        sel = (t >= start) & (t <= end)
        if np.count_nonzero(sel) < 12 or end - start < 0.5 * span_s:
            continue
        # speed and deceleration at the window's end under a = a0 (u0 / u)
        # (phi = -1: u^2 falls linearly), bounding the path's terms over the window
        u_end = speed * np.sqrt(max(1.0 - 2.0 * (end - t[0]) / t_stop, 0.05))
        a_end = accel * speed / u_end
        quartic = 3.0 * MAX_ABS_PHI * a_end ** 3 / u_end ** 2 / 24.0
        A2 = np.vander(t[sel], 4, increasing=True)
        sw2 = np.sqrt(w_all[sel])
        coef2, *_ = np.linalg.lstsq(A2 * sw2[:, None], q[sel] * sw2[:, None], rcond=None)
        p2 = _intercept_weights(A2, sw2)
        # each fit's value at t = 0 is a weighted sum of its rows: the difference's
        # variance from the weights of both on the rows' union (they share some), under
        # the rows' AR(1) noise - its scale the residuals' mean square, not a robust
        # scatter (the few rows noisier than the rest, blur or glare, weigh in the
        # values as in the residuals), its correlation the check's residuals' from row
        # to row (a tracker's errors persist over frames; simulated clean shots under
        # AR(1) noise of rho 0.6 per row: 4 % flagged, 8 % with the residuals' raw
        # correlation and dof)
        times = np.union1d(A1[:, 1], A2[:, 1])
        w = np.zeros(times.size)
        w[np.searchsorted(times, A1[:, 1])] += p1
        w[np.searchsorted(times, A2[:, 1])] -= p2
        # (in units of a row of weight 1: a row's error is its residual times its
        # square-root weight, and it enters the values as w / sqrt(weight))
        sw_u = np.ones(times.size)
        sw_u[np.searchsorted(times, A1[:, 1])] = sw1
        sw_u[np.searchsorted(times, A2[:, 1])] = sw2
        w = w / sw_u
        res2 = (q[sel] - A2 @ coef2) * sw2[:, None]
        res = np.vstack([res1 * sw1[:, None], res2])
        rho, corr = _row_correlation(res2, times, None if field is None else field[sel],
                                     None if field is None else field[np.searchsorted(t, times)])
        white2 = _correlated_variance(res, w, corr, rho, A1.shape[1] + A2.shape[1])
        model2 = ((cubic1 * float(p1 @ A1[:, 1] ** 3)) ** 2
                  + (quartic * float(p2 @ A2[:, 1] ** 4)) ** 2)
        d = coef1[0] - coef2[0]
        chi2 = float(np.sum(d ** 2)) / max(white2 + model2, 1e-30)
        if not chi2 <= out["chi2"]:  # (the first, or a larger one)
            out.update(difference=float(np.linalg.norm(d)), chi2=chi2,
                       sigma=(float(np.sqrt(max(float(np.mean(d ** 2)) - white2 - model2, 0.0)))
                              if chi2 > ORIGIN_CHECK_CHI2 else 0.0))
    return out


def _correlated_variance(res, w, corr, rho, n_params) -> float:
    """Variance of ``w @ errors`` (per coordinate) for rows whose errors have the
    correlation ``corr`` (:func:`_row_correlation`), their scale read from the fits'
    residuals ``res`` (rows, k; in units of a row of weight 1): the residuals' mean
    square over their degrees of freedom - the fits take (1 + rho) / (1 - rho) times
    their ``n_params`` parameters' share of the residuals' variance when the rows'
    errors persist (at least a quarter of the rows left)."""
    dof = max(len(res) - n_params * (1 + rho) / (1 - rho), 0.25 * len(res))
    return float(np.sum(res ** 2)) / dof / res.shape[1] * max(float(w @ corr @ w), 0.0)


def _row_correlation(res, times, field_res=None, field=None):
    """(rho, C): the rows' AR(1) error correlation from one row to the next, read from
    the residuals ``res`` (rows, k) of a fit (a fitted cubic's read about 4 / rows low:
    added back; at most 0.9), and its matrix C over the rows at ``times`` (s; the rows'
    step the residuals' median one).

    Rows of two interlaced fields (``field_res`` of the residuals' rows, ``field`` of
    ``times``; 0/1): each field carries an error of its own that persists from field to
    field, which the interleaved rows' next-row products read as no correlation or a
    negative one (a rendered ladder camcorder's rows: -0.40 from row to row, +0.43 from
    field to field).  The correlation within each field (per field step, two rows) is
    then read too, the one across the fields from neighbouring rows (never negative, at
    most as a single series'), and C is the larger of that and the rows' own at each
    pair (the origin's check on simulated clean shots whose 0.3-2 mm errors persist
    within each field, rho 0-0.8 per field step: 20 % called when read from the next
    rows alone, ~1 % so).  rho is then the larger of the rows' and the square root of
    the fields'.
    """
    den = max(float(np.sum(res ** 2)), 1e-300)
    bias = 4.0 / len(res)
    step = float(np.median(np.diff(times)))
    lag = np.abs(np.subtract.outer(times, times)) / max(step, 1e-12)
    rho = float(np.clip(np.sum(res[1:] * res[:-1]) / den + bias, 0.0, 0.9))
    corr = rho ** lag
    if field_res is None:
        return rho, corr

    def mean_product(pairs, k):
        return float(np.sum((res[k:] * res[:-k])[pairs])) / den * len(res) \
            / max(np.count_nonzero(pairs), 1) + bias

    rho_f = float(np.clip(mean_product(field_res[2:] == field_res[:-2], 2), 0.0, 0.81))
    across = float(np.clip(mean_product(field_res[1:] != field_res[:-1], 1), 0.0,
                           np.sqrt(rho_f)))
    by_field = rho_f ** (0.5 * lag)
    other = np.not_equal.outer(field, field)
    by_field[other] *= across / max(np.sqrt(rho_f), 1e-12)
    return max(rho, float(np.sqrt(rho_f))), np.maximum(corr, by_field)


#: Largest rho (per field step) of an interlaced field's angle noise
#: (:func:`_frame_noise`): its variogram is measured over the noise model's lags of up to
#: 6 steps, and a correlation still above 1/4 at the longest of them is persistence
#: those lags cannot size - sigma and rho then run off together (a rendered ladder
#: draw: rho at the 0.95 bound, sigma 1.33 deg for a field whose angle errors spread
#: by 0.38 deg, theta0's sigma 0.72 deg; 3 of 79 draws had theta error/sigma RMS under
#: 0.5).  Capped there, 79 draws: theta0's error over its sigma RMS 1.17, none under 0.6.
FIELD_RHO_MAX = 0.25 ** (1.0 / 6.0)


def leading_strays(t: np.ndarray, q: np.ndarray, sigma: np.ndarray, clip: float,
                   window_s: float = WINDOW_S) -> tuple[np.ndarray, np.ndarray]:
    """The first rows (the first third of the origin's window) that the path of the
    rows after them misses by more than ``clip`` times their sigma (scaled up by those
    rows' own robust scatter about it when it is larger): ``(stray, miss)``, (N,) bool
    and (N,) the miss (the units of ``q``, largest over its columns).

    A quadratic through the rows of the next window (from a third of a window on) is
    extrapolated back to them.  Its misses are large only for gross errors: a path's
    start departs from the later rows' quadratic by a few millimetres (rendered
    clips' right first rows were called so at 5-21 sigma), so this is for the
    origin that cannot be placed at all - a 0.39 Mbit/s camcorder's first three
    fields 13-21 cm off the rest, their lattice poses wrong, refused the whole clip.
    """
    t = np.asarray(t, float)
    q = np.asarray(q, float).reshape(len(t), -1)
    s = np.asarray(sigma, float)
    lead = t < t[0] + window_s / 3.0
    later = ~lead & (t <= t[0] + window_s * 4.0 / 3.0) & np.isfinite(s) & (s > 0)
    if not lead.any() or np.count_nonzero(later) < 8:
        return np.zeros(len(t), bool), np.zeros(len(t))
    w = 1.0 / s[later]
    A = np.vander(t[later], 3, increasing=True)
    coef = np.linalg.lstsq(A * w[:, None], q[later] * w[:, None], rcond=None)[0]
    scale = max(1.0, robust_sigma(((q[later] - A @ coef) * w[:, None]).ravel()))
    miss = np.abs(q - np.vander(t, 3, increasing=True) @ coef).max(axis=1)
    return lead & (miss > clip * scale * s), np.where(lead, miss, 0.0)


#: Fewest windows behind :func:`intercept_scatter` (fewer: no reading).
MIN_SCATTER_WINDOWS = 4


def intercept_scatter(t: np.ndarray, q: np.ndarray, window_s: float,
                      end: float | None = None, min_points: int = 8) -> float:
    """The error of a quadratic's value at its window's start, as the shot shows it.

    The initial fit's value at t = 0 rests on the first rows alone, fitted from one
    side; its variance under a noise model is only as good as the model.  Here the
    same fit - a quadratic over ``window_s`` from a time ``k`` on - is made at
    times ``k`` across the shot (every eighth of a window, up to ``end``: the motion's
    stop) and its value at ``k`` compared with a cubic's through the rows on both
    sides of ``k`` (``window_s`` each side; its own error is ~1/3 of the one-sided
    fit's under white noise).  The RMS of the differences is the one-sided value's
    error whatever makes it: noise that persists, a lattice's slow bias, the path's
    own departure from a quadratic.  (39 rendered sweep clips and 5 at full
    resolution, with theta0's noise read before the stop: its error over its sigma
    RMS 1.47 -> 1.16, median |z| 0.87 -> 0.68 - a normal variable's 0.67 -, beyond
    2 sigma 7 -> 6 of 44; a window every quarter, sixth or twelfth of its length:
    RMS 1.24, 1.11, 1.13 - the few windows of a short shot read it only roughly.)

    Returns 0 with fewer than :data:`MIN_SCATTER_WINDOWS` windows.
    """
    t = np.asarray(t, float)
    q = np.asarray(q, float).reshape(len(t), -1)
    end = float(t[-1]) if end is None else min(float(end), float(t[-1]))
    starts = np.arange(t[0] + window_s, end - window_s + 1e-9, window_s / 8.0)
    d = []
    for k in starts:
        one = (t >= k) & (t <= k + window_s)
        both = (t >= k - window_s) & (t <= k + window_s)
        if np.count_nonzero(one) < min_points or np.count_nonzero(both) < 12:
            continue
        v1 = np.linalg.lstsq(np.vander(t[one] - k, 3, increasing=True), q[one], rcond=None)[0]
        v2 = np.linalg.lstsq(np.vander(t[both] - k, 4, increasing=True), q[both], rcond=None)[0]
        d.append(v1[0] - v2[0])
    if len(d) < MIN_SCATTER_WINDOWS:
        return 0.0
    return float(np.sqrt(np.mean(np.square(d))))


def _frame_noise(t, q, field=None):
    """(sigma, rho, step_s) of a coordinate's AR(1) frame noise over the whole shot
    (:func:`curltrack.series.noise.estimate_noise`; rho per ``step_s`` seconds), or
    None with too few frames.

    Rows of two interlaced fields (``field`` 0/1) are estimated field by field, each
    field a regular series at half the row rate, and their variances and rhos averaged
    (``step_s`` one field's step): each field carries an error of its own, so the
    interleaved rows' second differences mistake the fields' differences for white
    noise - rendered 720x480 interlaced draws gave rho 0 on 12 of 17, and theta0's
    sigma came out 2.4x too small (RMS of its error over it; field by field, each
    field's rho at most :data:`FIELD_RHO_MAX`: 1.17 over 79 draws).
    """
    from ..errors import SeriesError
    from ..series.noise import RHO_MAX, estimate_noise

    def one(tq, qq, dt, rho_max=RHO_MAX):
        if tq.size < 8:
            return None
        frame = np.round((tq - tq[0]) / max(dt, 1e-9)).astype(int)
        try:
            # (with the rows' times: a rolling shutter's or a clock's jitter times the
            # spin read as noise on a regular clock - theta0's sigma 1.2-1.4x wide on
            # clean simulated rows timed 0-16 ms off the frame grid)
            noise = estimate_noise(frame, qq, t=tq, rho_max=rho_max)
        except SeriesError:
            return None
        return noise.sigma, noise.rho

    if t.size < 8:
        return None
    dt = float(np.median(np.diff(t)))
    if field is not None:
        field = np.asarray(field)
        parts = [one(t[field == k], q[field == k], 2.0 * dt, FIELD_RHO_MAX) for k in (0, 1)]
        if all(p is not None for p in parts) and ((field == 0) | (field == 1)).all():
            return (float(np.sqrt(np.mean([p[0] ** 2 for p in parts]))),
                    float(np.mean([p[1] for p in parts])), 2.0 * dt)
    part = one(t, q, dt)
    return None if part is None else (*part, dt)


def choose_axes(direction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lattice unit axes (x_hat, y_hat) of the shot frame: +y = the lattice axis (of
    +-x, +-y) closest to ``direction``; +x = +y turned 90 deg clockwise."""
    axes = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])
    y_hat = axes[int(np.argmax(axes @ direction))]
    x_hat = np.array([y_hat[1], -y_hat[0]])
    return x_hat, y_hat


def _spin_stop(t, theta):
    """The spin's stop (s, :func:`~curltrack.series.stops.rotation_stop`) read on rows
    ``t``, ``theta``, or None (fewer than 16 rows, or no stop)."""
    from ..series.stops import rotation_stop

    return rotation_stop(t, theta, float(np.median(np.diff(t))))[0] if t.size >= 16 else None


#: Rows on either side of the spin's stop that :func:`_theta0_sigma` leaves out of the
#: angle's noise: the largest lag of the noise's second differences
#: (:func:`curltrack.series.noise.estimate_noise`, 6) and two more.
STOP_MARGIN_ROWS = 8


def _theta0_sigma(t, theta, field, window_s: float, stop, measure_cubic=True) -> float:
    """1 sigma (rad) of theta0 (:func:`_origin_sigma` of the angle): its noise read on the
    rows before the spin stops, :data:`STOP_MARGIN_ROWS` short of it (all rows but
    those about the stop when fewer than 30 are left;
    :func:`~curltrack.series.stops.rotation_stop`; the
    rows of its last approach, whose angle bends faster and faster, read as noise that
    persists: a clean 1280x720 hand-held clip's 0.13 deg white error as 0.41 deg at
    rho 0.93, theta0's sigma 3.6x its rows' own) and at least its window's
    :func:`intercept_scatter` there.  ``stop``: the spin's stop on these rows
    (:func:`_spin_stop`); ``measure_cubic``: :func:`_origin_sigma`'s."""
    end = stop if stop is not None and stop > t[0] else None
    turning = np.ones(t.size, bool)
    margin = STOP_MARGIN_ROWS * float(np.median(np.diff(t))) if t.size > 1 else 0.0
    if end is not None:
        # (and not the rows about the stop, whose lagged second differences span its
        # kink: a ladder clip whose spin stopped from 140 deg/s in 1.3 s read its 0.19
        # deg error as 0.73 deg at rho 0.95 on the 36 rows before the stop, theta0's
        # sigma 0.76 deg for a 0.14 deg error)
        near = np.abs(t - end) <= margin
        turning = (t < end) & ~near
        if np.count_nonzero(turning) < 30:  # (too few to read the noise on: all but those)
            turning = ~near
    if np.count_nonzero(turning) < 30:
        turning[:] = True
    f = None if field is None else np.asarray(field)[turning]
    return _origin_sigma(t, theta, MAX_ANGULAR_DECELERATION, window_s=window_s,
                         min_scatter=MIN_SCATTER_RAD, min_cubic=EXTRAPOLATION_RAD_S3,
                         noise=_frame_noise(t[turning], theta[turning], f),
                         extrapolated=_first_late(t), field=field,
                         # (nor does its scatter's last window end there: 60 fps
                         # action clips' one-sided fits there, their path bending
                         # ever faster, read 0.26 and 0.37 deg for theta0 errors of
                         # 0.04 deg)
                         scatter=intercept_scatter(t, theta, window_s,
                                                   None if end is None else end - margin),
                         measure_cubic=measure_cubic)


#: :func:`_theta0_check`'s later fit: from this fraction of theta0's window after the
#: first row, over this many windows.
THETA0_CHECK_FROM = 0.5
THETA0_CHECK_SPAN = 2.0
#: ... ended before this fraction of the time from the first row to the spin's stop.
THETA0_CHECK_STOP_FRACTION = 0.6
#: Its gate on the two values' squared difference over their summed variances (2
#: sigma: the check only widens theta0's sigma, the safe side).  Clean simulated rows
#: (the paper's law, white or AR(1) angle noise): 5 and 6 of 300, theta0's error over
#: its sigma RMS 0.93-0.95 -> 0.87-0.91; at 6.6 too few of the first rows' shared
#: errors were found (their theta0 4-17 sigma off left so in ~half the draws).
THETA0_CHECK_CHI2 = 4.0


def _theta0_check(t, theta, field, window_s: float, theta0: float, sigma: float, stop):
    """(sigma, difference) (rad) of theta0's error that its first rows share: theta0
    against the same fit to the rows from :data:`THETA0_CHECK_FROM` of its window on,
    over :data:`THETA0_CHECK_SPAN` windows, extrapolated back to t = 0.  Where the two
    differ by more than their sigmas allow (:data:`THETA0_CHECK_CHI2`; some rows are
    in both, so the sum of their variances is the generous side), the excess is the
    error of angles the first rows share, which neither fit's scatter shows (a PAL
    camcorder's first 0.3 s of fields, blurred and coded at the rock's fastest, turned
    slower than the rock: theta0 7.3 deg off under a 1.9 deg sigma, every angle 3.9
    sigma off).  The later fit ends before :data:`THETA0_CHECK_STOP_FRACTION` of the
    time to the spin's stop (a quadratic through it bends: a phone clip's theta0 read
    2 deg off a right one; ``stop``: :func:`_spin_stop` of these rows).  (0, difference)
    when they agree, (0, 0) when too few rows follow, or the spin stops or the rows end
    before the later fit spans one window."""
    if t.size < 16 or not np.isfinite(sigma):
        return 0.0, 0.0
    # (a quadratic through the spin's stop bends: its end well before it, as the
    # origin's check ends before the translation's)
    end = t[0] + (THETA0_CHECK_STOP_FRACTION * (stop - t[0]) if stop is not None else np.inf)
    # ... and where the rows end: a 2 s interlaced clip whose rock still spun left
    # 1.2 s of rows to a fit meant for 3.2, extrapolated back 0.8 s - its slow error
    # (0.3 deg wander) came out 2 deg, and a right theta0 was widened to 2.1 deg
    end = min(end, float(t[-1]))
    start = t[0] + THETA0_CHECK_FROM * window_s
    span = min(THETA0_CHECK_SPAN * window_s, end - start)
    later = t >= start
    tl = t[later]
    if tl.size == 0 or span < window_s or np.count_nonzero(tl <= start + span + 1e-9) < 16:
        return 0.0, 0.0
    theta0_later = float(initial_state(tl, theta[later], span)[0][0])
    f_later = None if field is None else np.asarray(field)[later]
    # (the later fit's extrapolation back takes the path's cubic at its bound: a
    # cubic measured on noisy rows can read short - a DV clip's 0.32 deg/s^3 for the
    # truth's 0.56-0.71 left the later fit 0.75 deg off under a 0.43 deg sigma, and a
    # right theta0 was widened to 0.9 deg)
    var = sigma ** 2 + _theta0_sigma(tl, theta[later], f_later, span,
                                     _spin_stop(tl, theta[later]), measure_cubic=False) ** 2
    d2 = (theta0 - theta0_later) ** 2
    if not d2 > THETA0_CHECK_CHI2 * var:
        return 0.0, float(np.sqrt(d2))
    return float(np.sqrt(d2 - var)), float(np.sqrt(d2))


def to_shot_frame(t: np.ndarray, centre: np.ndarray, phi: np.ndarray, ok: np.ndarray,
                  up_direction: np.ndarray | None = None,
                  settings: TrackingSettings | None = None,
                  angle_rows: np.ndarray | None = None, field: np.ndarray | None = None,
                  sigma: np.ndarray | None = None) -> dict:
    """Convert lattice-frame centres and angles into the shot frame.

    Parameters
    ----------
    t : (N,) array
        Times (s).
    centre : (N, 2) array
        Rock centre in the lattice frame (m); any value where not ``ok``.
    phi : (N,) array
        Rock angle against the lattice (rad, wrapped or not).
    ok : (N,) bool array
    up_direction : (2,) array, optional
        The image's up direction in the lattice frame (used when the rock does not
        translate).
    settings : TrackingSettings, optional
        ``min_travel_m`` and ``max_deceleration_m_s2`` (default: the defaults).
    angle_rows : (N,) bool array, optional
        Rows whose angle is measured even where their position is not (``ok`` false:
        a lattice whose cell index is not certain still gives the rock's angle against
        its threads); they count turns and fix theta0 (default: ``ok``).
    field : (N,) int array, optional
        Interlaced video: each row's field (0/1; -1 for none); theta0's noise is then
        estimated field by field (:func:`_frame_noise`).
    sigma : (N,) array, optional
        Each row's own 1 sigma of position (m; any scale): the origin's fit weighs the
        rows by it (:func:`row_weights`; default: alike).

    Returns
    -------
    dict
        ``x``, ``y``, ``theta`` (N,) with NaN where not ok (``theta`` also where its
        turn count is not certain: ``theta_unsure`` (N,) bool, :func:`unwrap_angle`);
        ``origin`` (2,) and ``x_hat``, ``y_hat`` (lattice-frame unit vectors), ``theta0`` (rad),
        ``direction_source`` ("travel" or "image up"), ``origin_sigma_m``: the origin's
        1 sigma per coordinate (m: its fit's error, plus the extrapolation back to t = 0
        when the first measured frame is later), ``origin_extrapolated``: whether it is
        (bool), ``origin_check_sigma_m`` and ``origin_check_difference_m``: the error
        its first rows share, which its fit cannot see (m per coordinate; 0 when the
        later rows agree) and the two values' distance (m; :func:`origin_check`),
        ``theta0_sigma_rad``, ``theta0_check_sigma_rad``, ``theta0_check_difference_rad``:
        theta0's (rad, likewise: :func:`theta0_fit`), ``theta0_window_s``: its fit's
        window (s), ``theta0_rows`` (N,): the angles it was fitted to, from theta0 (rad;
        ``theta``'s rows and the ``angle_rows``; NaN at others), ``origin_row_weights``:
        the weights of the measured (``ok``) rows in the origin's fit (None: alike),
        ``origin_cubic_moment_s3`` and ``origin_cubic_m_s3``: how far the path's cubic
        term can move the origin (:func:`origin_cubic_bias`).
    """
    st = TrackingSettings() if settings is None else settings
    min_travel = st.min_travel_m
    ok = np.asarray(ok, bool)
    idx = np.flatnonzero(ok)
    tt, cc = t[idx], centre[idx]
    aidx = idx
    th_all, sure_all = unwrap_angle(t[aidx], phi[aidx])
    if angle_rows is not None and (np.asarray(angle_rows, bool) & ~ok).any():
        more = np.flatnonzero(np.asarray(angle_rows, bool) | ok)
        th_more, sure_more = unwrap_angle(t[more], phi[more])
        # (only when they leave every turn count as sure as it was without them)
        if (~sure_more[np.searchsorted(more, idx)]).sum() <= (~sure_all).sum():
            aidx, th_all, sure_all = more, th_more, sure_more
    at_ok = np.searchsorted(aidx, idx)
    th, th_sure = th_all[at_ok], sure_all[at_ok]
    weights = None if sigma is None else row_weights(np.asarray(sigma, float)[idx])
    deg, A0, coef, _, sw0 = _window_fit(tt, cc, weights=weights)
    (x0, y0), (vx, vy) = coef[0], (coef[1] if deg >= 1 else np.zeros(2))
    # theta0 over its own window (_angle_window); angles after a gap whose turns are
    # not counted may be a whole turn off: theta0 from the frames before it alone when
    # the gap is that early; angles measured where positions are not count too
    window = _angle_window(coef) if deg == 2 else WINDOW_S
    ts, ths = t[aidx][sure_all], th_all[sure_all]
    fs = None if field is None else np.asarray(field)[aidx][sure_all]
    angle0 = theta0_fit(ts, ths, fs, window)
    th0 = angle0["theta0"]
    origin = np.array([x0, y0])
    disp = cc - origin
    reach = np.hypot(*disp.T)
    if reach.size and reach.max() > min_travel:
        v = np.array([vx, vy])
        # A rate from 0.5 s of noisy frames may be poor for slow rocks: fall back on the
        # displacement to where the rock first gets min_travel away.
        first_far = disp[int(np.flatnonzero(reach > min_travel)[0])]
        direction = v if np.hypot(*v) * 0.5 > min_travel else first_far
        source = "travel"
    else:
        direction = up_direction if up_direction is not None else np.array([0.0, 1.0])
        source = "image up"
    x_hat, y_hat = choose_axes(np.asarray(direction, float))
    x = np.full(t.shape, np.nan)
    y = np.full(t.shape, np.nan)
    theta = np.full(t.shape, np.nan)
    x[idx], y[idx] = disp @ x_hat, disp @ y_hat
    theta[idx] = np.where(th_sure, th - th0, np.nan)
    theta0_rows = np.full(t.shape, np.nan)
    theta0_rows[aidx[sure_all]] = ths - th0
    late = _first_late(tt)
    # the origin is a fit even when the first frame is at t = 0: its error is every row's
    origin_sigma = _origin_sigma(tt, cc, st.max_deceleration_m_s2, extrapolated=late,
                                 weights=weights)
    # ... and what its first rows share, which its fit cannot see
    f_ok = None if field is None else np.asarray(field)[idx]
    check = origin_check(tt, cc, weights=weights,
                         field=f_ok if f_ok is not None and (f_ok >= 0).all() else None)
    # (the same fit's: (0, 0) where it is no quadratic)
    moment, cubic = (origin_cubic_bias(tt, cc, A0, coef, sw0, weights) if deg == 2
                     else (0.0, 0.0))
    return {"x": x, "y": y, "theta": theta, "origin": origin, "x_hat": x_hat,
            "y_hat": y_hat, "theta0": float(th0), "direction_source": source,
            "origin_sigma_m": float(origin_sigma), "origin_extrapolated": bool(late),
            "origin_check_sigma_m": check["sigma"],
            "origin_check_difference_m": check["difference"],
            "theta_unsure": np.isin(np.arange(t.size), idx[~th_sure]),
            "origin_row_weights": weights, "origin_cubic_moment_s3": moment,
            "origin_cubic_m_s3": cubic, "theta0_window_s": float(window),
            "theta0_rows": theta0_rows,
            **{k: v for k, v in angle0.items() if k != "theta0"}}


def theta0_fit(t, theta, field, window_s: float) -> dict:
    """theta0 (rad: the angle at t = 0 of :func:`initial_state`'s fit over ``window_s``)
    and its uncertainty, from the rows ``t`` (s), cumulative ``theta`` (rad) and their
    interlaced ``field`` (0/1, or None).

    Every angle is taken from theta0, itself a fit: its error is every row's (the
    camcorder bench clip, first field 0.25 s after release: all angles -8 deg off under
    a 0.9 deg sigma).

    Returns
    -------
    dict
        ``theta0``; ``theta0_sigma_rad`` (:func:`_theta0_sigma`; inf without rows);
        ``theta0_check_sigma_rad`` and ``theta0_check_difference_rad``: the error its
        first rows share, which its fit cannot see (:func:`_theta0_check`).
    """
    t, theta = np.asarray(t, float), np.asarray(theta, float)
    if not t.size:
        return {"theta0": 0.0, "theta0_sigma_rad": float("inf"),
                "theta0_check_sigma_rad": 0.0, "theta0_check_difference_rad": 0.0}
    th0 = float(initial_state(t, theta, window_s)[0][0])
    spin_stop = _spin_stop(t, theta)
    sigma = _theta0_sigma(t, theta, field, window_s, spin_stop)
    check = _theta0_check(t, theta, field, window_s, th0, sigma, spin_stop)
    return {"theta0": th0, "theta0_sigma_rad": float(sigma),
            "theta0_check_sigma_rad": check[0], "theta0_check_difference_rad": check[1]}
