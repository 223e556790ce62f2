"""One frame judged as ``track`` judges it: the verdict ``doctor`` and ``calibrate`` give.

``track`` follows the grid from frame to frame; ``doctor`` and ``calibrate`` look at a
few frames on their own.  So that they say the same of a frame, both run the tracker's
own per-frame steps and acceptance rules (:class:`~curltrack.settings.TrackingSettings`
from the rig) on it:

1. a frame whose grey levels barely vary shows nothing (:func:`.pipeline.blank_frame`);
2. every marker of the rig must be found (:class:`.markers.MarkerDetector`);
3. the rock is masked as ``track`` masks it (:func:`.pipeline.rock_disc`), the grid
   calibrated on the frame - or, when a calibration from scratch fails on it, on a
   neighbouring frame, else the last one found (or the first frame from the start of
   the video where one works), as ``track`` carries its calibration - and
   measured on the frame by :meth:`curltrack.calib.GridTracker.update`, whose
   refusals (threads not found, a weak snap, ...) are ``track``'s.

What a single frame cannot show is left to ``track``: a poor fit against the typical
residual of the frames before, a cell index that jumped (or that the thread colours
read on this frame alone contradict), a marker layout unlike the rest of the video.  A frame refused here is ``ok`` = 0 in ``track``'s output for the
same reason; one accepted here is measured by ``track`` unless one of those says no.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..errors import TrackingError
from ..rig import Rig

__all__ = ["FrameVerdict", "check_frames", "frame_reader"]

#: Neighbouring frames tried for a calibration when one from scratch fails on a frame.
#: Step (frames) of the search from the video's start for a frame a calibration from
#: scratch works on, when none near the judged frame does (doctor samples few frames).
FIRST_CALIBRATION_STEP = 10
NEIGHBOURS = (-1, 1, -2, 2)


@dataclass(frozen=True)
class FrameVerdict:
    """What ``track`` would make of one frame.

    Attributes
    ----------
    frame : int
    status : str
        "" when the frame is measurable, else why not (``track``'s wording; the first
        reason when there are several).
    grid_status : str
        "" when the grid was measured on the frame, else why not (the grid is measured
        also when the markers are not found, unmasked then, as ``track`` follows it).
    markers_found : tuple of bool
        Per rig marker.
    markers_px : (M, 2) array or None
        Observed marker positions (px) when all were found.
    calibration : Calibration or None
        The grid on this frame (lens and colours from ``calibrated_on``); None when the
        grid was not measured.
    calibrated_on : int or None
        The frame the lens and thread colours were calibrated on.
    """

    frame: int
    status: str
    grid_status: str = ""
    markers_found: tuple = ()
    markers_px: np.ndarray | None = None
    calibration: object = None
    calibrated_on: int | None = None

    @property
    def ok(self) -> bool:
        return self.status == ""


def _mask(image, det, mf, rig):
    """``track``'s rock mask (uint8, nonzero = ignore) from all markers found, or None."""
    import cv2

    from .pipeline import rock_disc

    if mf is None or not mf.found.all():
        return None
    m = np.zeros(image.shape[:2], np.uint8)
    (x, y), rad = rock_disc(det.layout_m, mf.xy_px, rig.rock_diameter_m)
    cv2.circle(m, (x, y), rad, 255, -1)
    return m


def frame_reader(path, n_frames: int | None = None, fps_override=None):
    """``read(i)`` -> frame ``i`` of a video (BGR uint8; each decoded once), None outside
    it; a still image is frame 0."""
    from pathlib import Path

    from ..video import IMAGE_SUFFIXES, iter_frames, probe_video, read_frame

    if Path(path).suffix.lower() in IMAGE_SUFFIXES:
        image = read_frame(path, 0)
        return lambda i: image if i == 0 else None
    if n_frames is None:
        n_frames = probe_video(path, fps_override=fps_override, check_end=False).n_frames
    cache = {}

    def read(i):
        if not 0 <= i < n_frames:
            return None
        if i not in cache:
            for fr in iter_frames(path, start=int(i), end=int(i) + 1,
                                  fps_override=fps_override):
                cache[i] = fr.image
        return cache.get(i)

    return read


def _follow(read, cal, start: int, k: int, image, mask, det, rig: Rig):
    """The grid tracker's pose on frame ``k`` (``image``, ``mask``) after following the
    grid from frame ``start``, where ``cal`` was made, through every frame between."""
    from ..calib import GridTracker
    from .pipeline import blank_frame

    tracker = GridTracker(cal, rig)
    for i in range(start + 1, k):
        other = read(i)
        if other is None or blank_frame(other, rig.tracking):
            continue
        tracker.update(other, i, mask=_mask(other, det, det.detect(other), rig))
    return tracker.update(image, k, mask=mask)


def check_frames(read, frames, rig: Rig, detector=None) -> list[FrameVerdict]:
    """Judge frames one by one as ``track`` would.

    Parameters
    ----------
    read : callable
        ``read(index)`` -> BGR image (uint8), or None past the video's ends.
    frames : iterable of int
        Frames to judge.
    rig : Rig
        Grid, markers and ``rig.tracking`` (the thresholds).
    detector : MarkerDetector, optional
        Shared across calls (it learns the markers' size and colours); a new one by
        default.

    Returns
    -------
    list of FrameVerdict
    """
    from ..calib import GridTracker
    from .markers import MarkerDetector
    from .pipeline import BLANK, _calibrate, blank_frame

    det = detector if detector is not None else MarkerDetector(rig)
    out = []
    carried = None  # (calibration, frame): the last one found, as track carries its own

    def calibrate_near(k):
        for d in NEIGHBOURS:
            other = read(k + d) if k + d >= 0 else None
            if other is not None:
                cal, _ = _calibrate(other, rig, _mask(other, det, det.detect(other), rig))
                if cal is not None:
                    return cal, k + d
        return None, k

    for k in frames:
        k = int(k)
        image = read(k)
        if image is None:
            raise TrackingError("frame outside the video", where=f"frame {k}")
        if blank_frame(image, rig.tracking):
            out.append(FrameVerdict(k, BLANK, BLANK, (False,) * len(rig.markers)))
            continue
        mf = det.detect(image)
        if not mf.found.all():
            # track looks for them where the frames before put them: so does this
            for d in (-1, -2):
                before = read(k + d) if k + d >= 0 else None
                prev = det.detect(before) if before is not None else None
                if prev is not None and prev.found.all():
                    mf = det.detect(image, predicted=prev.xy_px)
                    break
        found = tuple(bool(f) for f in mf.found)
        markers = "" if all(found) else f"markers not found ({mf.message})"
        xy = mf.xy_px if all(found) else None
        mask = _mask(image, det, mf, rig)
        cal, why = _calibrate(image, rig, mask)
        on = k
        if cal is None:
            cal, on = calibrate_near(k)
        if cal is None and carried is None:
            # (track calibrates once, on its first frame where that works, and follows
            # the grid from there: look for such a frame from the start of the video)
            for start in range(0, k, FIRST_CALIBRATION_STEP):
                cal, on = calibrate_near(start)
                if cal is not None:
                    break
        if cal is None and carried is not None:
            cal, on = carried
        if cal is not None:
            carried = (cal, on)
        if cal is None:
            grid = f"grid not found ({why})"
            out.append(FrameVerdict(k, markers or grid, grid, found, xy))
            continue
        pose = GridTracker(cal, rig).update(image, k, mask=mask)
        if not pose.ok and on < k:
            # a calibration from another frame: follow the grid from there to this frame,
            # frame by frame, as track does
            pose = _follow(read, cal, on, k, image, mask, det, rig)
        # A cell index "uncertain" or "ambiguous" on one frame only says that the
        # tracker's colour reading and the calibration's disagree: there is no tracked
        # index to slip from; track carries the index from the frames before.
        if not pose.ok and not pose.message.startswith("cell index"):
            grid = f"grid: {pose.message}"
            out.append(FrameVerdict(k, markers or grid, grid, found, xy, calibrated_on=on))
            continue
        if on != k:  # the grid as measured on this frame, the lens from the other
            cal = replace(cal, H=pose.H, spacing_px=pose.spacing_px,
                          residual_px=pose.residual_px, notes=list(cal.notes) + [
                              f"lens and thread colours calibrated on frame {on} (a "
                              f"calibration from scratch failed on frame {k}: {why}); the "
                              f"grid followed onto frame {k} as track follows it"])
        out.append(FrameVerdict(k, markers, "", found, xy, cal, on))
    return out
