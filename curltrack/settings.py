"""The tracker's thresholds in one place: :class:`TrackingSettings`.

Every number by which ``track`` (and ``doctor``, ``calibrate``) accepts or refuses a
frame, a grid fit, a cell index or a whole shot is a field here, with its unit, its
default and the evidence the default rests on.  The rig's ``[tracking]`` table overrides
any of them (:func:`settings_from_table`); the settings a series was measured with are
written to its sidecar (SHOT.json ``tracking_settings``).  The stages read them from
``rig.tracking`` - no module constant is read while tracking.

This module sits beside :mod:`curltrack.rig` (below the stages): ``calib`` and ``track``
both read it.

Examples
--------
>>> from dataclasses import replace
>>> from curltrack.settings import TrackingSettings
>>> strict = replace(TrackingSettings(), poor_fit_min_px=0.3)
>>> strict.poor_fit_min_px
0.3
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields

__all__ = ["TrackingSettings", "settings_from_table", "describe_settings"]


def _f(default, unit: str, lo, hi, why: str):
    """A settings field: ``default`` with its unit, plausible range and evidence."""
    return field(default=default, metadata={"unit": unit, "range": (lo, hi), "why": why})


@dataclass(frozen=True)
class TrackingSettings:
    """Thresholds of the tracker (frozen; ``dataclasses.replace`` makes a variant).

    Each field's unit, plausible range and the evidence for its default are in
    ``dataclasses.fields(TrackingSettings)[i].metadata`` (``unit``, ``range``, ``why``)
    and in the rig reference (docs/rig.md, "The [tracking] table").  Integer fields take
    integers only.
    """

    # -- the grid, frame to frame (calib.tracker.GridTracker) ----------------------------
    ambiguous_cells: float = _f(
        0.35, "cells", 0.05, 0.5,
        "a snap that moves the lattice this far beyond the motion prediction, unconfirmed "
        "by the thread colours, could be a whole-cell slip: the frame is refused (ok = 0); "
        "right snaps stay within ~0.15 cell of the prediction")
    anchor_max_cells: float = _f(
        0.3, "cells", 0.0, 1.0,
        "largest move of the grid's prediction by the rock's markers: a shaking hand moves "
        "the view by a few px to ~0.2 cell per frame; more is rather a wrong anchor")
    anchor_max_cells_stale: float = _f(
        1.5, "cells", 0.0, 5.0,
        "the same after stale_frames frames without a grid, when the rock's path is the "
        "better guide than the camera's stale motion")
    stale_frames: int = _f(
        3, "frames", 1, 30,
        "frames without a grid after which the camera's motion prediction is held still "
        "and a re-found cell index starts a new segment (placed on the rock's path)")
    poor_fit_factor: float = _f(
        2.5, "x typical", 1.0, 100.0,
        "a frame whose threads miss the fitted lattice by more than this times the "
        "typical residual of the last poor_fit_frames frames is refused: on rendered "
        "handheld shots with a broom and a faint thread colour such fits (1.0-1.4 px "
        "against 0.3 typical) put the rock 4-24 mm off")
    poor_fit_min_px: float = _f(
        0.6, "px", 0.05, 100.0,
        "... and by more than this (px): steady frames' residuals are 0.1-0.4 px")
    poor_fit_frames: int = _f(
        30, "frames", 5, 1000,
        "accepted frames whose median residual is the typical one (1 s at 30 fps)")
    min_found_snap: float = _f(
        0.5, "fraction", 0.0, 1.0,
        "a coarse snap is trusted only when this fraction of its profiles (per family) "
        "found a thread: right snaps find >= 0.9, snaps onto the wrong lattice alignment "
        "after a sudden camera turn 0.1-0.3 (erratic turns of +-30 deg)")
    min_found_fine: float = _f(
        0.8, "fraction", 0.0, 1.0,
        "a fine measurement from the prediction is kept only above this fraction found, "
        "else a coarse snap is made first: a handheld jolt showed ~0.75 found and a fit "
        "~1 px off (2.6 mm); steady frames find >= 0.9")
    min_found_fallback: float = _f(
        0.6, "fraction", 0.0, 1.0,
        "a fine measurement above this fraction is kept when the snap does worse "
        "(threads of a colour faint against the ice are found by the fine profiles only)")
    max_grid_sigma_cells: float = _f(
        0.05, "cells", 0.001, 1.0,
        "a frame whose homography is this uncertain at the rock (1 sigma from the thread "
        "points' fit) is refused: the threads measured do not fix the lattice there "
        "(profiles in one band across a family left its direction free: 0.45 cell, rows "
        "37 mm off at 50 sigma, a 640x360 render); the test suite's 5680 measured "
        "frames: median 0.0015, 99.9 % under 0.013, largest 0.02 cell")
    # -- the per-frame loop (track.pipeline) ----------------------------------------------
    give_up_frames: int = _f(
        90, "frames", 1, 100000,
        "frames from the start without markers (or grid) after which the video is "
        "declared unusable (3 s at 30 fps)")
    blank_std: float = _f(
        3.0, "grey levels", 0.0, 255.0,
        "a frame whose grey levels vary less than this (std, 0-255) shows nothing (black, "
        "a flat fade-in): skipped at the start, ok = 0 later; sensor noise alone is ~2")
    anchor_max_gap_frames: int = _f(
        12, "frames", 1, 1000,
        "largest gap over which the rock's ice position is extrapolated to anchor the "
        "grid's prediction: 0.4 s at 30 fps, where a rock's deceleration moves it < 1 cm "
        "from its constant-velocity path")
    # -- the shot (track.results, track.shotframe, track.parallax) ------------------------
    min_measured_frames: int = _f(
        8, "frames", 2, 100000,
        "fewest measured frames a shot must have (fewer: an error, no series)")
    scale_outlier_sigma: float = _f(
        6.0, "robust sigma", 1.0, 100.0,
        "frames whose apparent marker layout scale is this many robust sigmas off the "
        "video's are refused (a wrong marker identity or a bad homography changes it)")
    sigma_outlier_factor: float = _f(
        3.0, "x median sigma_xy", 1.5, 1000.0,
        "a frame whose sigma_xy exceeds this many times the video's median is refused: its "
        "own fit says it is unsure (a grid fit just inside the poor-fit limit, half-hidden "
        "markers); on the wrong-cell test's fast handheld shots the one such frame was 14 mm "
        "off (sigma 3.6 mm against 0.9 typical), on 5 camera-sweep set-ups no frame came "
        "above 2.1x; frames measured from clicks are exempt")
    layout_scale_min: float = _f(
        0.7, "x layout", 0.1, 1.0,
        "the markers' apparent layout scale against the grid below which the rig's "
        "spacing or marker layout contradicts the video (an error): a lens 0.5-10 m above "
        "0.114 m markers gives 1.01-1.3")
    layout_scale_max: float = _f(
        1.6, "x layout", 1.0, 10.0,
        "... and above which (e.g. a rig spacing 2x off, every other thread invisible)")
    max_origin_sigma_m: float = _f(
        0.010, "m", 1e-4, 1.0,
        "largest 1 sigma of the origin (a fit to the first frames, extrapolated back to "
        "t = 0 when the first measured frame is late); beyond it tracking stops and asks "
        "for --start-frame")
    max_deceleration_m_s2: float = _f(
        0.3, "m/s^2", 0.01, 10.0,
        "largest deceleration of a sliding rock (mu g, mu <= 0.03 at the slowest speeds of "
        "the paper's law): bounds a straight line's error extrapolated back to t = 0")
    min_travel_m: float = _f(
        0.05, "m", 0.001, 1.0,
        "a rock that moves less is taken not to translate (shot axes from the image's up)")
    turn_warn_deg_per_frame: float = _f(
        1.0, "deg/frame", 0.01, 90.0,
        "camera turn above which SHOT.json and doctor warn: position RMS 1.5-1.9 mm up to "
        "1 deg/frame, 2.5-3.3 mm from 1.5 to 4.5 (640x360 rendered draw, steady turns)")
    shutter_slide_warn_m: float = _f(
        0.020, "m", 0.0, 1.0,
        "with a rolling shutter, how far the ice may slide under the image during the "
        "readout before SHOT.json warns that the image's shear is not modelled: a 55 mm "
        "slide left 2.3 mm RMS in quadrature on a rendered 960x540 pole clip (29 ms "
        "readout), so 20 mm is where it reaches ~1 mm")
    turn_fail_deg_per_frame: float = _f(
        8.0, "deg/frame", 0.1, 90.0,
        "camera turn above which doctor says track will fail (the cell index is lost from "
        "~10 deg/frame)")
    # -- the cell index across a loss (track.segments) ------------------------------------
    segment_window_s: float = _f(
        1.0, "s", 0.1, 10.0,
        "seconds of the rock's path fitted on each side of a grid loss")
    segment_min_side_frames: int = _f(
        4, "frames", 3, 1000,
        "fewest measured frames on each side for that fit")
    segment_max_gap_s: float = _f(
        2.0, "s", 0.0, 60.0,
        "longest loss across which the path is extrapolated to re-anchor the cell index: "
        "the step's error was at most 13.4 mm over 40-frame gaps on 150 simulated shots")
    segment_max_fraction: float = _f(
        0.25, "cells", 0.0, 0.5,
        "the path's step must be this close to a whole number of cells")
    segment_max_sigma_cells: float = _f(
        0.15, "cells", 0.01, 0.5,
        "... with a 1 sigma at most this (the nearest wrong integer is then > 5 sigma off)")
    # -- the scale self-check (track.outline) ---------------------------------------------
    scale_check_sigma: float = _f(
        5.0, "sigma", 1.0, 100.0,
        "the grid's scale against the rock's rulers may disagree by this many sigma of "
        "their scatter (or the floors below) before tracking stops")
    scale_min_layout_discrepancy: float = _f(
        0.012, "fraction", 0.0, 1.0,
        "floor of the markers' discrepancy (placed by hand to ~1 mm over ~0.16 m)")
    scale_min_outline_discrepancy: float = _f(
        0.03, "fraction", 0.0, 1.0,
        "floor of the outline's: its edge is found to ~1-2 mm of the striking band "
        "(+0.7 to +1.3 % measured on rendered set-ups with a right rig)")
    scale_resolution_warn: float = _f(
        0.03, "fraction", 0.001, 1.0,
        "a grid scale the rock's rulers can check only to worse than this is warned about "
        "in SHOT.json: every position, speed and alpha carry such an error whole; 3 % is "
        "the scale error issue 20 asks the check to catch (without the camera height the "
        "check resolves 4-7 %, with it ~2 %, on 4 rendered set-ups)")
    rig_height_rel_err: float = _f(
        0.05, "fraction", 0.0, 1.0,
        "uncertainty of a rig's [camera].height_m (tape-measured)")
    max_camera_height_m: float = _f(
        8.0, "m", 0.5, 100.0,
        "highest plausible camera: markers that look less than h / this larger than "
        "their layout contradict the grid's scale")

    def __post_init__(self):
        for f in fields(self):
            value = getattr(self, f.name)
            msg = _check_value(f, value)
            if msg:
                raise ValueError(f"{f.name}: {msg}")
        if self.layout_scale_min >= self.layout_scale_max:
            raise ValueError("layout_scale_min must be below layout_scale_max")

    def summary(self) -> dict:
        """Every field as a JSON-ready dict (SHOT.json ``tracking_settings``)."""
        return asdict(self)

    def changed(self) -> dict:
        """The fields that differ from the defaults (name -> value)."""
        base = TrackingSettings()
        return {k: v for k, v in asdict(self).items() if getattr(base, k) != v}


def _check_value(f, value) -> str:
    """Why ``value`` is not acceptable for settings field ``f``, or ""."""
    want_int = f.type in ("int", int)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return f"expected {'an integer' if want_int else 'a number'}, got {value!r}"
    if want_int and not isinstance(value, int):
        return f"expected an integer, got {value!r}"
    if not math.isfinite(value):
        return f"expected a finite number, got {value!r}"
    lo, hi = f.metadata["range"]
    if not lo <= value <= hi:
        return f"{value!r} is outside the plausible range [{lo:g}, {hi:g}] {f.metadata['unit']}"
    return ""


def settings_from_table(table) -> TrackingSettings:
    """The rig's ``[tracking]`` table -> :class:`TrackingSettings` (defaults elsewhere).

    Raises
    ------
    ValueError
        ``(key, message)`` as its args for an unknown key, a wrong type or an
        implausible value (the rig reader names the file and ``[tracking].key``).
    """
    if not isinstance(table, dict):
        raise ValueError(None, "expected a table")
    known = {f.name: f for f in fields(TrackingSettings)}
    unknown = sorted(set(table) - set(known))
    if unknown:
        import difflib

        near = difflib.get_close_matches(unknown[0], known, n=1)
        hint = f"did you mean {near[0]!r}?" if near else "the keys are listed in docs/rig.md"
        raise ValueError(unknown[0], f"unknown key {unknown[0]!r}: {hint}")
    values = {}
    for key, value in table.items():
        msg = _check_value(known[key], value)
        if msg:
            raise ValueError(key, msg)
        values[key] = value if known[key].type in ("int", int) else float(value)
    try:
        return TrackingSettings(**values)
    except ValueError as exc:
        raise ValueError("layout_scale_min", str(exc)) from None


def describe_settings() -> list[dict]:
    """One row per field: ``key, unit, default, range, why`` (the rig reference's table)."""
    return [{"key": f.name, "unit": f.metadata["unit"], "default": f.default,
             "range": f.metadata["range"], "why": f.metadata["why"]}
            for f in fields(TrackingSettings)]
