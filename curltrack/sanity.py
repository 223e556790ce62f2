"""Unit and convention sanity of a series, before ``fit`` or ``discover`` trusts it.

The contract's units are seconds, metres and radians (theta counter-clockwise,
cumulative).  A series in other units still fits — to confidently wrong numbers
(theta in degrees gives omega0 = 57 rad/s, x/y in mm v0 = 500 m/s) — so the physical
ranges of a curling shot are checked first:

=====================  ==========================  ==========================================
quantity               plausible range             the likely mistake outside it
=====================  ==========================  ==========================================
duration (t span)      <= :data:`MAX_DURATION_S`   t in ms (span / 1000 within 1 s and
                                                   the maximum)
t values               < :data:`MAX_T_S`           a clock time (epoch seconds), not t since
                                                   release
speed |d(x, y)/dt|     <= :data:`MAX_SPEED`        x, y in cm, mm, feet or inches (each
                                                   named when it brings speed and travel
                                                   within range, speed >=
                                                   :data:`MIN_UNIT_SPEED`)
travel                 <= :data:`MAX_TRAVEL_M`     a warning naming the units that fit
                                                   (a simulated take-out runs on past the
                                                   boards; feet give a 28 m draw 92 m)
first t while moving   <= :data:`MAX_MOVING_T_S`   t offset (not counted from release)
spin |d theta/dt|      <= :data:`MAX_SPIN`         theta in degrees (spin / 57.3 plausible)
theta steps            no jump of ~2 pi            theta wrapped to [0, 2 pi) or (-pi, pi]
direction of travel    within :data:`MAX_SKEW_DEG` the rink's or an image's frame, not the
                       of +y                       shot frame (+y along the initial velocity)
curl against the spin  never (a warning)           x mirrored (an image's axes, y down) or
                                                   theta clockwise
speed                  never rises (beyond its     t = 0 before the release (a rock at rest,
                       noise, :data:`MIN_SPEEDUP`)  or still pushed, in the first rows)
=====================  ==========================  ==========================================

A delivery leaves the hand at 1-4.5 m/s (a hard take-out) and turns at 0.2-4 rad/s (a
spinner at most ~3 turns/s), and a shot lasts 10-35 s from release to rest.  Speeds and
spins are measured over ~0.1 s (so frame noise does not count) and their 90th
percentile compared.  A unit mistake is a one-line :class:`~curltrack.errors.SeriesError`
naming the column; a value out of range with no unit that explains it is a warning.
"""

from __future__ import annotations

import numpy as np

from .errors import SeriesError

__all__ = ["check_units", "late_stop_warning", "bound_rows", "speed_rise", "MAX_DURATION_S",
           "MAX_T_S", "MAX_SPEED", "MAX_SPIN", "DISCOVER_MAX_ROWS"]

#: Longest series taken as one shot (s): a slow draw lasts ~35 s.
MAX_DURATION_S = 120.0
#: Largest t (s): t counts from the start frame; a clock time is far beyond.
MAX_T_S = 1e5
#: Fastest plausible rock (m/s): a hard take-out leaves the hand at ~4.5 m/s.
MAX_SPEED = 8.0
#: Slowest fastest-speed (m/s, the 90th percentile of a series' speeds) a wrong unit's
#: explanation may give: beyond :data:`MAX_SPEED`, x, y are taken to be in the unit(s)
#: of :data:`LENGTH_UNITS` that bring the speed between this and MAX_SPEED (none: a
#: warning - scaled wrong some other way, or t too fine).
MIN_UNIT_SPEED = 0.25
#: Length units a series' x, y may be in by mistake, and their size in metres.
LENGTH_UNITS = {"centimetres": 0.01, "millimetres": 0.001, "feet": 0.3048,
                "inches": 0.0254}
#: Time units finer than the second a series' t may be in by mistake, and their size
#: in its unit (how many make a second).
FINE_TIME_UNITS = {"milliseconds": 1e3, "microseconds": 1e6, "nanoseconds": 1e9}
#: ... and coarser ones, named when they bring both the speed and the spin into range
#: (t in minutes makes every rate 60x too fast - once read as theta in degrees).
COARSE_TIME_UNITS = {"minutes": 60.0, "hours": 3600.0, "days (a spreadsheet's time)": 86400.0}
#: Longest plausible travel (m): a sheet is 45.72 m from back board to back board.
MAX_TRAVEL_M = 46.0
#: Latest time (s) at which a rock can still move after its release (a slow draw
#: stops by ~35 s): a series that starts moving later has t offset, not from release.
MAX_MOVING_T_S = 60.0
#: Speed (m/s) above which a rock is taken to be moving (for MAX_MOVING_T_S).
MOVING_SPEED = 0.05
#: Latest plausible end of a slide (s after release): the paper's slowest draws stop by
#: ~30 s; a fit that ends later says t may not count from the release (a warning).
MAX_SLIDE_S = 45.0
#: Fastest plausible spin (rad/s): a spinner turns at most ~3 turns/s.
MAX_SPIN = 25.0
#: Most measured rows ``discover`` fits at once (all shots together).  Its memory
#: grows ~0.1 MB per row (2,500 rows: 470 MB peak); beyond this the shots are
#: thinned evenly (every k-th row), which keeps the noise per point and the shape of
#: every residual.  With it, discover stays under 1 GB whatever the input.
DISCOVER_MAX_ROWS = 4000
#: Time over which speeds and spins are measured (s).
RATE_WINDOW_S = 0.1
#: Largest angle (deg) of the initial direction of travel from +y: the fit's deskew
#: angle ``psi`` takes up to 0.5 rad (28.6 deg); a series at 40 deg fitted lambda_y 1.66
#: +- 0.69 for 1.840 (with a misfit warning), at 90 deg (a rink frame) 1.00 at its bound.
MAX_SKEW_DEG = 25.0
#: The initial direction is read over the first this share of the travel (and at
#: least the first 0.3 m): the curl bends a draw by a few degrees over its length.
DIRECTION_SHARE = 0.15
#: A curl against the spin is reported when the rock ends at least this far (m) and
#: this share of its travel off its initial line, having turned at least this (rad)
CURL_MIN_M = 0.1
CURL_MIN_SHARE = 0.02
CURL_MIN_TURN_RAD = 1.5
#: A rock sliding freely only slows: its speed, measured over windows of this length
#: (s, lines through at least :data:`SPEEDUP_MIN_ROWS` rows; long enough that an
#: instrument's 15 cm step moves a window's speed by ~0.15 m/s) ...
SPEEDUP_WINDOW_S = 1.0
SPEEDUP_MIN_ROWS = 4
#: ... must not rise from one of the first :data:`SPEEDUP_FIRST_WINDOWS` windows (a
#: video begun before the release is slow there) to a later one by more than this
#: (m/s) and :data:`SPEEDUP_Z` times the two windows' combined 1 sigma: each window's
#: own (its line's residuals) and the series' (the windows' speeds about a smooth
#: decline, from their second differences: an instrument's steps of 5-10 cm move a
#: window's speed by up to ~0.5 m/s, which no window's residuals show).  A video begun
#: before the release rises by the delivery's speed (1-4.5 m/s) from a rock at rest,
#: by ~1 m/s from one still pushed.
MIN_SPEEDUP = 0.3
SPEEDUP_Z = 5.0
SPEEDUP_FIRST_WINDOWS = 3
#: A rise from a start that is not far slower than the speed reached is only taken
#: when it ends within this time (s) of the first row: a rock still pushed is fastest
#: at the release, and a window further on that reads faster is an instrument's step
#: (10 cm steps: windows 10 s on read 1.3-2 m/s faster than the first, 5 in 200 draws).
SPEEDUP_SPAN_S = 3.0
#: ``check_units`` refuses a series whose speed rises and starts (over its first
#: :data:`RELEASE_WINDOW_S`) under this share of the speed it reaches (a rock at rest,
#: or far slower, at the start: nothing else does that); another rise is a warning (an instrument's 10 cm steps, 2x the
#: steps class's scale, raised speeds from 2.5 to 2.9 and 1.6 to 2.4 m/s once in ~70
#: draws each).
CLEAR_RISE_SHARE = 0.5
#: ... and the short windows (:data:`RELEASE_WINDOW_S`) are looked at only for a start
#: under this share of the speed reached: a rock at rest (a short rest before a slow
#: delivery, which the long windows blur).
REST_SHARE = 0.2
#: The release is placed where the speed over windows of this length (s) first comes
#: within :data:`RELEASE_SHARE` of the risen speed (a hint: where t = 0 belongs).
RELEASE_WINDOW_S = 0.3
RELEASE_SHARE = 0.9


def _window_speeds(t, xy, window_s: float):
    """(centre times, speeds, 1 sigma of the speeds) of lines through the rows of
    windows ``window_s`` long, half a window apart (windows with fewer than
    :data:`SPEEDUP_MIN_ROWS` rows, or whose rows cover less than half the window - a
    gap's time not counted - left out)."""
    out = []
    step = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    for start in np.arange(t[0], t[-1] - 0.5 * window_s + 1e-9, 0.5 * window_s):
        sel = (t >= start) & (t < start + window_s)
        n = int(np.count_nonzero(sel))
        # (a window a gap empties is as short as its rows: a 50 Hz step-noise series'
        # 1 s window held the 0.3 s after a 0.7 s gap, and a 15 cm step there read as a
        # rise from 2.97 to 3.79 m/s - CI seed 2490891148)
        covered = float(np.sum(np.minimum(np.diff(t[sel]), 2.0 * step)))
        if n < SPEEDUP_MIN_ROWS or covered < 0.5 * window_s:
            continue
        tc = t[sel] - t[sel].mean()
        sxx = float(tc @ tc)
        if sxx <= 0:
            continue
        q = xy[sel] - xy[sel].mean(axis=0)
        v = tc @ q / sxx                       # (2,) the line's velocity
        res = q - np.outer(tc, v)
        s2 = float(np.sum(res ** 2)) / max(2 * (n - 2), 1)
        out.append((float(t[sel].mean()), float(np.hypot(*v)), float(np.sqrt(s2 / sxx))))
    return np.array(out).reshape(-1, 3).T


def _rise(t0: float, windows, clear: float):
    """(k, j, tc, u) of the largest rise beyond noise of the speed over ``windows``
    (:func:`_window_speeds`' centres, speeds and their sigmas) from one of the first
    :data:`SPEEDUP_FIRST_WINDOWS` (k) to a later one (j), or None; ``clear`` (> 0): only
    a rise from under that share of the speed reached, else (0) only one that ends
    within :data:`SPEEDUP_SPAN_S` of the first row, at ``t0`` (a rock pushed up to the
    release is fastest there)."""
    tc, u, su = windows
    if tc.size < 2:
        return None
    # (second differences of every other window's speed: windows that do not overlap)
    d2 = np.diff(u[::2], 2)
    if d2.size >= 3:
        # (their upper quartile, not their median: an instrument's steps move a
        # third of the windows or more; a rock at rest then released, one or two)
        series_sigma = float(np.percentile(np.abs(d2 - np.median(d2)), 75)) / 1.15 / np.sqrt(6.0)
        su = np.hypot(su, series_sigma)
    rise = u[None, :] - u[:, None]                        # [k, j]: u_j - u_k
    bar = np.maximum(MIN_SPEEDUP, SPEEDUP_Z * np.hypot(su[:, None], su[None, :]))
    later = np.triu(np.ones(rise.shape, bool), 1)
    later[SPEEDUP_FIRST_WINDOWS:] = False
    if clear:
        later &= u[:, None] < clear * u[None, :]
    else:
        later &= (tc <= t0 + SPEEDUP_SPAN_S)[None, :]
    excess = np.where(later & (rise > bar), rise, -np.inf)
    if not np.isfinite(excess).any():
        return None
    k, j = np.unravel_index(int(np.argmax(excess)), excess.shape)
    return int(k), int(j), tc, u


def speed_rise(t, xy) -> dict | None:
    """The largest rise of a rock's speed from one of its first windows of rows to a
    later one, when it is beyond noise: a rock sliding freely only slows, so a series
    whose speed rises from its start begins before the release (the rock at rest, or
    still pushed).  Windows of :data:`SPEEDUP_WINDOW_S` (steps of an instrument barely
    move them), then of :data:`RELEASE_WINDOW_S` for a rise from under
    :data:`CLEAR_RISE_SHARE` of the speed reached (a short rest before a slow delivery).

    Parameters
    ----------
    t : (N,) array
        Times of the measured rows (s), increasing.
    xy : (N, 2) array
        Their positions (m), in any frame fixed to the ice.

    Returns
    -------
    dict or None
        ``t_from``, ``u_from``, ``t_to``, ``u_to`` (s, m/s: the two windows' centres and
        speeds), ``u_start`` (m/s: the speed over the first :data:`RELEASE_WINDOW_S`
        window) and ``t_release`` (s: where the speed over :data:`RELEASE_WINDOW_S`
        first comes within :data:`RELEASE_SHARE` of ``u_to``, less half that window);
        None when the speed never rises by more than :data:`MIN_SPEEDUP` and
        :data:`SPEEDUP_Z` sigma.  (Windows of at least :data:`SPEEDUP_MIN_ROWS` rows:
        0.3 s is 3 rows at 10 Hz.)
    """
    t = np.asarray(t, float)
    xy = np.asarray(xy, float).reshape(len(t), 2)
    good = np.isfinite(t) & np.isfinite(xy).all(axis=1)
    t, xy = t[good], xy[good]
    if t.size < 2 * SPEEDUP_MIN_ROWS:
        return None
    w_fine = max(RELEASE_WINDOW_S, (SPEEDUP_MIN_ROWS + 0.5) * float(np.median(np.diff(t))))
    # (the short windows only for a rock at rest at first (under REST_SHARE of the
    # speed reached): an instrument's steps move them by more than their second
    # differences show - 7-9 % of step-noise draws rose there by 0.5 m/s from a moving
    # start, and a 5 cm step read a rock's first 0.3 s at 1.0 m/s, a later 0.3 s at 2.1)
    # (a clear rise also starts slow over the first short window: a 30 cm step of an
    # instrument read a moving rock's first 1 s window at 0.15 m/s, not its first 0.3 s)
    windows = {w: _window_speeds(t, xy, w) for w in (SPEEDUP_WINDOW_S, w_fine)}
    tf, uf, _ = windows[w_fine]
    u_start = float(uf[0]) if uf.size else np.inf
    for window_s, clear in ((SPEEDUP_WINDOW_S, CLEAR_RISE_SHARE), (w_fine, REST_SHARE),
                            (SPEEDUP_WINDOW_S, 0.0)):
        found = _rise(float(t[0]), windows[window_s], clear)
        if found is not None and (not clear or u_start < clear * found[3][found[1]]):
            break
    else:
        return None
    k, j, tc, u = found
    reach = np.flatnonzero((tf > tc[k]) & (uf >= RELEASE_SHARE * u[j]))
    t_rel = (float(tf[reach[0]]) - 0.5 * w_fine) if reach.size else float(tc[j])
    return {"t_from": float(tc[k]), "u_from": float(u[k]), "t_to": float(tc[j]),
            "u_to": float(u[j]), "t_release": max(t_rel, float(t[0])),
            "u_start": u_start if uf.size else float(u[0])}


def late_stop_warning(t_stop, name: str) -> list[str]:
    """A warning when a fitted slide ends later than :data:`MAX_SLIDE_S` after t = 0:
    t that counts from some other instant than the release (an instrument's start)
    makes the fit extrapolate v0 and the origin back over the offset."""
    if t_stop is None or not np.isfinite(t_stop) or t_stop <= MAX_SLIDE_S:
        return []
    return [f"{name}: the slide ends {t_stop:.1f} s after t = 0, later than a curling "
            f"shot's (<= {MAX_SLIDE_S:g} s): if t does not count from the release, v0 and "
            f"every value at t = 0 are extrapolated back over the offset"]


def check_units(series) -> list[str]:
    """Check a series against the physical ranges of a curling shot.

    Parameters
    ----------
    series : Series
        The series (``t`` s, ``x``/``y`` m, ``theta`` rad); rows with ``ok`` = 1 are used.

    Returns
    -------
    list of str
        Warnings: values out of range that no unit mistake explains.

    Raises
    ------
    SeriesError
        One line naming the file and the column: t in ms, a clock time or offset,
        x/y in cm, mm, feet or inches, theta in degrees or wrapped.
    """
    d = series.measured
    d = d[np.isfinite(d[["t", "x", "y"]].to_numpy(float)).all(axis=1)]
    path = series.name
    warnings: list[str] = []
    t = d["t"].to_numpy(float)
    if t.size < 3:
        return warnings

    def fail(column, message):
        raise SeriesError(message, path=path, where=f"column '{column}'")

    before = int(np.count_nonzero(t < 0))
    if before:
        warnings.append(f"t: {before} measured row(s) before t = 0 (the release) are not "
                        f"used: t counts from the release, and the rock in the hand is not "
                        f"the shot")
    span = float(t.max() - t.min())
    # (a span of one shot in a finer unit counted from ~0 is that unit, not a clock:
    # microseconds were once called a clock time)
    fine = next(((unit, size) for unit, size in FINE_TIME_UNITS.items()
                 if 1.0 <= span / size <= MAX_DURATION_S and t.min() / size <= MAX_MOVING_T_S),
                None)
    if t.max() > MAX_T_S and fine is None:
        fail("t", f"values up to {t.max():.4g} look like a clock time (e.g. seconds since "
                  "1970), not seconds since the release: subtract the first time")
    if span > MAX_DURATION_S:
        if fine is not None:
            unit, size = fine
            fail("t", f"the series spans {span:.5g} 'seconds' — t looks like {unit} "
                      f"({span / size:.3g} s if divided by {size:g}): the contract's t is in s")
        fail("t", f"the series spans {span:.5g} s, more than one shot "
                  f"(<= {MAX_DURATION_S:g} s): split the recording into shots")
    lag = _lag(t)
    has_theta = np.isfinite(d["theta"].to_numpy(float))
    xy = d[["x", "y"]].to_numpy(float)
    speed = _rate(t, xy, lag)
    if speed > MAX_SPEED:
        th = d["theta"].to_numpy(float)[has_theta]
        for unit, size in COARSE_TIME_UNITS.items():
            ts = t * size   # (rates over RATE_WINDOW_S of the unit's seconds)
            speed_s = _rate(ts, xy, _lag(ts))
            spin_s = _rate(ts[has_theta], th[:, None], _lag(ts[has_theta])) if th.size >= 3 else 0.0
            if (MIN_UNIT_SPEED <= speed_s <= MAX_SPEED and spin_s <= MAX_SPIN
                    and span * size <= MAX_DURATION_S):
                fail("t", f"the rock would move at {speed:.4g} m/s for {span:.4g} 's' — t "
                          f"looks like {unit} ({speed_s:.3g} m/s for {span * size:.3g} s if "
                          f"multiplied by {size:g}): the contract's t is in s")
    if has_theta.sum() >= 3:  # (position-only series have no theta)
        _check_theta(d[has_theta], fail, warnings)
    reach = float(np.percentile(np.hypot(*(xy - xy[0]).T), 90))   # (robust to a wild row)
    # (a file in centimetres was once called millimetres, at 0.18 m/s "if divided by
    # 1000", and one in feet was fitted as a 92 m draw: only a unit that gives a rock's
    # speed and travel is named, and every one that does)
    units = [f"{unit} ({speed * size:.3g} m/s, {reach * size:.3g} m if multiplied by "
             f"{size:g})" for unit, size in LENGTH_UNITS.items()
             if MIN_UNIT_SPEED <= speed * size <= MAX_SPEED and reach * size <= MAX_TRAVEL_M]
    if speed > MAX_SPEED:
        if units:
            fail("x/y", f"the rock would move at {speed:.4g} m/s over {reach:.4g} m — x and "
                        f"y look like {' or '.join(units)}: the contract's x, y are in "
                        f"metres")
        warnings.append(f"x/y: a speed of {speed:.3g} m/s is beyond a curling rock's "
                        f"(<= {MAX_SPEED:g} m/s): check the units of x, y and t")
    elif reach > MAX_TRAVEL_M:
        # a warning, not an error: a simulated take-out runs on past the back boards
        warnings.append(f"x/y: the rock travels {reach:.3g} m, beyond a sheet's length "
                        f"({MAX_TRAVEL_M:g} m): if x, y are not in metres, they may be in "
                        f"{' or '.join(units) or 'another unit'}")
    if t.min() > MAX_MOVING_T_S and speed > MOVING_SPEED:
        fail("t", f"the rock moves at {speed:.3g} m/s at t = {t.min():.5g} s, later than any "
                  f"shot after its release (<= {MAX_MOVING_T_S:g} s): t looks offset - it "
                  f"counts from the release; subtract the release time")
    after = t >= 0   # (rows before t = 0 are not used: said above)
    rise = speed_rise(t[after], xy[after])
    if rise is not None:
        row = int(d.index[min(int(np.searchsorted(t, rise["t_release"])), t.size - 1)]) + 2
        said = (f"the rock speeds up from {rise['u_from']:.2f} m/s at t = "
                f"{rise['t_from']:.2f} s to {rise['u_to']:.2f} m/s at t = {rise['t_to']:.2f} "
                f"s, and a rock sliding freely only slows: the series begins before the "
                f"release (t = 0 is the release; here about t = {rise['t_release']:.2f} s, "
                f"row {row}: subtract it from t, or drop the rows before it)")
        if rise["u_start"] < CLEAR_RISE_SHARE * rise["u_to"]:
            fail("t", said)
        warnings.append(f"t: {said}, or an instrument's errors jump by tens of cm")
    u, travel = _initial_direction(xy)
    if travel >= 0.5:   # (a pure rotation, or too short to say)
        _check_direction(xy, u, fail)   # (after the units: x alone in mm turns it too)
        if has_theta.sum() >= 3:
            _check_curl_side(xy, u, travel, d["theta"].to_numpy(float)[has_theta], warnings)
    return [f"{path}: {w}" if path else w for w in warnings]


def _check_direction(xy, u, fail) -> None:
    """The shot frame: +y along the initial velocity (``u``).  A series in the rink's
    frame or an image's (travel along x, or -y) is an error naming the direction."""
    angle = float(np.degrees(np.arctan2(u[0], u[1])))   # from +y, towards +x
    if abs(angle) > MAX_SKEW_DEG:
        fail("x/y", f"the rock starts along ({u[0]:+.2f}, {u[1]:+.2f}), {abs(angle):.0f} deg "
                    f"from +y (from x, y = {xy[0, 0]:.2f}, {xy[0, 1]:.2f} m): the contract's "
                    f"x, y are in the shot frame (+y along the initial velocity, +x to its "
                    f"right; the fit takes up to {MAX_SKEW_DEG:g} deg of skew): rotate the "
                    f"positions into it")


def _initial_direction(xy):
    """(unit vector, travel m) of the first :data:`DIRECTION_SHARE` of the path."""
    dist = np.hypot(*(xy - xy[0]).T)
    travel = float(dist.max())
    k = int(np.argmax(dist >= max(DIRECTION_SHARE * travel, 0.3)))
    step = xy[k] - xy[0]
    norm = float(np.hypot(*step))
    return (step / norm if norm > 0 else np.array([0.0, 1.0])), travel


def _check_curl_side(xy, u, travel, th, warnings) -> None:
    """Every curling rock curls the way it spins (clockwise to the right): a rock that
    ends well off its initial line ``u`` on the other side says the axes are mirrored.
    ``th``: the measured angles (rad)."""
    lateral = float((xy[-1] - xy[0]) @ np.array([u[1], -u[0]]))   # + right of travel
    turn = float(th[-1] - th[0])
    if (abs(lateral) >= max(CURL_MIN_M, CURL_MIN_SHARE * travel)
            and abs(turn) >= CURL_MIN_TURN_RAD and lateral * turn > 0):
        warnings.append(
            f"x/theta: the rock ends {abs(lateral):.2f} m to the "
            f"{'right' if lateral > 0 else 'left'} of its initial line while it turns "
            f"{'counter-clockwise' if turn > 0 else 'clockwise'} ({turn:+.1f} rad): curling "
            f"rocks curl the way they spin - is x mirrored (the contract's +x is to the "
            f"right of the travel, seen from above) or theta clockwise (the contract's is "
            f"counter-clockwise)? A slope across the sheet can do it too")


def _check_theta(d, fail, warnings) -> None:
    t = d["t"].to_numpy(float)
    lag = _lag(t)
    th = d["theta"].to_numpy(float)
    jumps = np.abs(np.diff(th))
    near_2pi = (jumps > np.pi) & (np.abs(jumps - 2 * np.pi) < 1.0)
    # a turn of ~2 pi across a gap in the rows is the spin's, not a wrap, when the rate
    # each side predicts it better than one turn less (a sweeper over the rock for 2.3 s
    # at 2.4 rad/s: 5.5 rad between two rows, refused as wrapped)
    for k in np.flatnonzero(near_2pi):
        rate = _edge_rates(t, th, k)
        if rate is not None:
            turn = rate * (t[k + 1] - t[k])
            jump = th[k + 1] - th[k]
            near_2pi[k] = abs(jump - turn) > abs(jump - np.sign(jump) * 2 * np.pi - turn)
    # (rows <= 0.5 s apart: a real turn of ~2 pi between rows would be > 10 rad/s;
    # unwrapped, consecutive rows - not those across a gap - step by less than 1 rad)
    dt = np.diff(t)
    regular = dt <= 1.5 * np.median(dt)
    if np.median(dt) <= 0.5 and near_2pi.any() and \
            np.abs(np.diff(np.unwrap(th))[regular]).max(initial=0.0) < 1.0:
        k = int(np.flatnonzero(near_2pi)[0]) + 1
        row = int(d.index[k]) + 2  # the file's line number (header is line 1)
        fail("theta", f"theta jumps by {th[k] - th[k - 1]:+.3f} rad at row {row}: it looks "
                      "wrapped to one turn; the contract's theta is cumulative (unwrap it, "
                      "e.g. numpy.unwrap)")
    spin = _rate(t, th[:, None], lag)
    if spin > MAX_SPIN:
        if spin / np.degrees(1.0) <= MAX_SPIN:
            fail("theta", f"the rock would spin at {spin:.3g} rad/s — theta looks like "
                          f"degrees ({np.radians(spin):.3g} rad/s if converted): the "
                          "contract's theta is in radians")
        warnings.append(f"theta: a spin of {spin:.3g} rad/s is beyond a curling rock's "
                        f"(<= {MAX_SPIN:g} rad/s): check the units of theta and t")


def _edge_rates(t, th, k, span_s: float = 0.5):
    """The mean spin rate (rad/s) of the rows within ``span_s`` before row ``k`` and
    after row ``k + 1`` (lines through each side's rows), or None with fewer than two
    rows on both sides."""
    rates = []
    for sel in ((t >= t[k] - span_s) & (np.arange(t.size) <= k),
                (t <= t[k + 1] + span_s) & (np.arange(t.size) >= k + 1)):
        if sel.sum() >= 2 and np.ptp(t[sel]) > 0:
            # (unwrapped within the side: a series wrapped to one turn must not predict
            # its own wraps)
            rates.append(float(np.polyfit(t[sel], np.unwrap(th[sel]), 1)[0]))
    return float(np.mean(rates)) if rates else None


def _lag(t: np.ndarray) -> int:
    dt = np.median(np.diff(t)) if t.size > 1 else 1.0
    return int(max(1, min(t.size - 1, round(RATE_WINDOW_S / dt)))) if dt > 0 else 1


def _rate(t: np.ndarray, v: np.ndarray, lag: int) -> float:
    """90th percentile of |v(t + lag rows) - v(t)| / dt (units of v per s)."""
    dt = t[lag:] - t[:-lag]
    good = dt > 0
    if not good.any():
        return 0.0
    step = np.linalg.norm(v[lag:] - v[:-lag], axis=1)[good] / dt[good]
    return float(np.percentile(step, 90))


def bound_rows(series_list, max_rows: int = DISCOVER_MAX_ROWS):
    """Thin a list of series evenly to at most ``max_rows`` measured rows in all.

    Returns
    -------
    (list of Series, list of str)
        The series (the same objects when nothing was thinned; new ones otherwise —
        inputs are never changed) and a warning saying what was done.
    """
    from dataclasses import replace

    n = sum(int((s.data["ok"] == 1).sum()) for s in series_list)
    if n <= max_rows:
        return list(series_list), []
    from .series import sample_index

    def thin(d, k):  # exposure // k: consecutive kept rows stay consecutive (the noise
        # model); a field series thinned is one row per kept exposure, fields no more
        kept_rows = d.iloc[::k].assign(frame=sample_index(d)[::k] // k)
        return kept_rows.drop(columns=["field"], errors="ignore").reset_index(drop=True)

    def kept(k):  # (each series keeps its first row: n / k rounded up per series)
        return sum(int((s.data["ok"].iloc[::k] == 1).sum()) for s in series_list)

    k = int(np.ceil(n / max_rows))
    while kept(k) > max_rows:  # (two series of 4001 and 3999 rows, k = 2: 4001 kept)
        k += 1
    out = [replace(s, data=thin(s.data, k)) for s in series_list]
    return out, [f"{n} measured rows is more than discover fits at once ({max_rows}): "
                 f"every {k}th row used (the noise per point and the residuals' shape "
                 "are kept; fewer points make weak effects harder to see)"]
