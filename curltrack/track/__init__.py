"""Tracking: markers -> rock centre and angle per frame (parallax-corrected) -> stops.

Public API::

    series = track_video(video_path, rig, start_frame=None, end_frame=None,
                         exclude_frames=(), overlay_path=None, progress=False)
    stops = detect_stops(data, fps)      # StopTimes (curltrack.series.stops)

Modules: :mod:`markers` (colour model, sub-pixel centroids, identities),
:mod:`parallax` (camera height, nadir), :mod:`shotframe` (lattice -> shot frame),
:mod:`pipeline` (the per-frame loop), :mod:`results` (records -> Series),
:mod:`overlay` (annotated video).
"""

from ..series.stops import StopTimes, detect_stops

__all__ = ["StopTimes", "detect_stops", "track_video"]


def __getattr__(name):
    # track_video itself (its real signature and docstring), imported on first use:
    # it needs OpenCV, which the stop detector re-exported here does not
    if name == "track_video":
        from .pipeline import track_video

        return track_video
    raise AttributeError(f"module 'curltrack.track' has no attribute {name!r}")
