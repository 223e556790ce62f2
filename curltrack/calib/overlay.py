"""Draw the fitted lattice on a frame (for CALIB.png and the tracking overlay video)."""

from __future__ import annotations

import numpy as np


def draw_grid(image_bgr, pose, color=(0, 200, 0), thickness: int = 1, samples: int = 60,
              label: bool = True) -> np.ndarray:
    """Return a copy of ``image_bgr`` with the fitted threads drawn through ``pose``.

    Parameters
    ----------
    image_bgr : (H, W, 3) uint8
    pose : Calibration or GridPose
        Anything with ``image_to_ice``/``ice_to_image`` and ``spacing_x_m``-like spacings
        (``pose.H``'s lattice frame).
    color : BGR
    samples : int
        Points per drawn thread (curved by the lens distortion).
    label : bool
        Mark the origin crossing and the +x / +y axes.
    """
    import cv2

    out = image_bgr.copy()
    h, w = out.shape[:2]
    sx = getattr(pose, "spacing_x_m", None) or pose.sx
    sy = getattr(pose, "spacing_y_m", None) or pose.sy
    corners = np.array([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]], float)
    edge = np.concatenate([np.linspace(corners[i], corners[(i + 1) % 4], 20) for i in range(4)])
    ice = pose.image_to_ice(edge)
    lo, hi = ice.min(axis=0), ice.max(axis=0)
    for fam, (s, s_other) in enumerate(((sx, sy), (sy, sx))):
        for i in range(int(np.floor(lo[fam] / s)) - 1, int(np.ceil(hi[fam] / s)) + 2):
            t = np.linspace(lo[1 - fam] - s_other, hi[1 - fam] + s_other, samples)
            pts = np.empty((samples, 2))
            pts[:, fam], pts[:, 1 - fam] = i * s, t
            px = pose.ice_to_image(pts)
            cv2.polylines(out, [np.round(px * 16).astype(np.int32)], False, color, thickness,
                          cv2.LINE_AA, shift=4)
    if label:
        o, ex, ey = pose.ice_to_image(np.array([[0.0, 0.0], [sx, 0.0], [0.0, sy]]))
        cv2.circle(out, tuple(np.round(o).astype(int)), 5, (0, 0, 255), 2, cv2.LINE_AA)
        for end, name in ((ex, "+x"), (ey, "+y")):
            cv2.arrowedLine(out, tuple(np.round(o).astype(int)), tuple(np.round(end).astype(int)),
                            (0, 0, 255), 2, cv2.LINE_AA, tipLength=0.2)
            cv2.putText(out, name, tuple(np.round(end + 4).astype(int)), cv2.FONT_HERSHEY_SIMPLEX,
                        0.5, (0, 0, 255), 1, cv2.LINE_AA)
    return out
