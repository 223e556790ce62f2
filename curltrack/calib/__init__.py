"""Grid calibration: thread lattice -> lens distortion + per-frame image -> ice homography.

Public API::

    calib = calibrate_frame(image_bgr, rig, mask=None)   # Calibration (to_dict/from_dict)
    tracker = GridTracker(calib, rig)
    pose = tracker.update(image_bgr, index, mask=None)   # GridPose
    pose.image_to_ice(pts_px) / pose.ice_to_image(pts_m)

See :mod:`curltrack.calib.grid` for the lattice frame's definition and
:mod:`curltrack.calib.tracker` for how the absolute cell index is kept.  Modules:
``lens`` (distortion model), ``response`` (thread colour filter), ``lattice`` (periodic
families, lattice fits), ``grid`` (calibrate_frame), ``profiles`` (thread positions on
short cross profiles), ``tracker`` (GridTracker), ``overlay`` (drawing), ``artificial``
(synthetic frames with a known camera, for tests).
"""

from .grid import Calibration, PlaneMap, calibrate_frame
from .tracker import GridPose, GridTracker

__all__ = ["Calibration", "GridPose", "GridTracker", "PlaneMap", "calibrate_frame"]
