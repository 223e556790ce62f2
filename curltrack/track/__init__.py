"""Tracking: markers -> rock centre and angle per frame (parallax-corrected) -> stops.

Public API::

    series = track_video(video_path, rig, start_frame=None, end_frame=None,
                         exclude_frames=(), overlay_path=None, progress=False)
    stops = detect_stops(data, fps)      # StopTimes (also used by `fit` without sidecar)

Modules: :mod:`markers` (colour model, sub-pixel centroids, identities),
:mod:`parallax` (camera height, nadir), :mod:`shotframe` (lattice -> shot frame),
:mod:`stops`, :mod:`pipeline` (the per-frame loop), :mod:`results` (records -> Series),
:mod:`overlay` (annotated video).
"""

from .stops import StopTimes, detect_stops

__all__ = ["StopTimes", "detect_stops", "track_video"]


def track_video(*args, **kwargs):
    """See :func:`curltrack.track.pipeline.track_video` (imported lazily: OpenCV)."""
    from .pipeline import track_video as _tv

    return _tv(*args, **kwargs)
