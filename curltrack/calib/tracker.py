"""Follow the lattice from frame to frame with a continuous absolute cell index.

Per frame: predict the homography from the previous poses (constant velocity of the
view over the ice), snap the fractional lattice phase to the threads (circular mean of
the thread pixels' cell coordinates), refine the homography on all thread pixels, then
check the integer cell index against the thread colour sequence.  When the index
cannot be resolved (the view moved close to half a cell more than predicted and the
colours cannot tell) the pose is returned with ``ok = False`` and a message rather
than silently jumping by a cell.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .grid import (Calibration, PlaneMap, cells_from_metric, colour_phase, line_colours,
                   metric_from_cells)
from .lattice import assign_families, fit_lattice, periods_px
from .lens import apply_h, undistort
from .response import candidate_pixels, local_contrast, thread_response

MAX_PIXELS = 40_000  # thread pixels used per frame (a fixed subsample beyond this)
AMBIGUOUS_CELLS = 0.35  # unexplained jump (cells) beyond which the index is not trusted


@dataclass
class GridPose(PlaneMap):
    """The lattice in one frame.

    Attributes
    ----------
    index : int
        Frame index.
    ok : bool
        Whether the homography is measured and the cell index is trusted.
    message : str
        Why not (or a note), "" when all is well.
    H : (3, 3) ndarray
        Undistorted px -> lattice-frame metres on the ice (thread) plane.
    K, dist :
        Lens model (from the calibration).
    spacing_px : float
        Mean thread spacing at the image centre (px).
    residual_px : float
        Weighted RMS distance of thread pixels from their fitted thread (px).
    n_threads : int
        Threads fitted (both families).
    sigma_px : float
        Rough 1-sigma uncertainty of the homography at the image centre (px).
    jump_cells : (float, float)
        Snap correction relative to the motion prediction (cells, x and y family).
    """

    index: int
    ok: bool
    message: str
    H: np.ndarray
    K: np.ndarray
    dist: tuple
    spacing_px: float = float("nan")
    residual_px: float = float("nan")
    n_threads: int = 0
    sigma_px: float = float("nan")
    jump_cells: tuple = (0.0, 0.0)
    notes: list = field(default_factory=list)


class GridTracker:
    """Per-frame homographies from a :class:`Calibration`.

    Parameters
    ----------
    calib : Calibration
        From :func:`calibrate_frame` on (ideally) the first frame tracked.
    rig : Rig
        For the thread spacings and colours.
    max_pixels : int
        Thread pixels used per frame.
    """

    def __init__(self, calib: Calibration, rig, max_pixels: int = MAX_PIXELS):
        self.calib = calib
        self.rig = rig
        self.max_pixels = int(max_pixels)
        self.K = calib.K
        self.dist = tuple(calib.dist)
        self.sx, self.sy = calib.spacing_x_m, calib.spacing_y_m
        w, h = calib.width, calib.height
        c = calib.K[:2, 2]
        self._ref = c + np.array([[-0.25, -0.25], [0.25, -0.25], [0.25, 0.25],
                                  [-0.25, 0.25]]) * (w, h)
        self._history: list[tuple[int, np.ndarray]] = [(None, calib.H)]

    # -- prediction ------------------------------------------------------------------
    def _predict(self, index: int) -> np.ndarray:
        """Constant-velocity prediction of the homography for frame ``index``."""
        hist = self._history
        if len(hist) < 2 or hist[-2][0] is None:
            return hist[-1][1]
        (i0, H0), (i1, H1) = hist[-2], hist[-1]
        import cv2

        P0, P1 = apply_h(H0, self._ref), apply_h(H1, self._ref)
        P = P1 + (P1 - P0) * (index - i1) / max(i1 - i0, 1)
        return cv2.getPerspectiveTransform(self._ref.astype(np.float32),
                                           P.astype(np.float32)).astype(float)

    def _motion_px(self, H_pred) -> np.ndarray:
        """Predicted image motion (px) of the ice at the image centre since the last pose."""
        c = self.K[:2, 2][None]
        prev = self._history[-1][1]
        return (apply_h(np.linalg.inv(H_pred), apply_h(prev, c)) - c)[0]

    # -- per frame -------------------------------------------------------------------
    def update(self, image_bgr, index: int, mask=None) -> GridPose:
        """Measure the lattice in one frame.

        Parameters
        ----------
        image_bgr : (H, W, 3) uint8
        index : int
            Frame index (frames must come in increasing order; gaps are allowed).
        mask : (H, W) uint8, optional
            Nonzero = ignore (the rock disc and its surroundings, a broom).

        Returns
        -------
        GridPose
            ``ok = False`` with a message when the grid is not visible or the cell index
            is ambiguous; ``H`` is then the motion prediction.
        """
        K, dist = self.K, self.dist
        f, c = K[0, 0], K[:2, 2]
        H_pred = self._predict(index)
        Hc = cells_from_metric(H_pred, K, self.sx, self.sy)
        Hc_pred = Hc.copy()
        contrast = local_contrast(image_bgr)
        resp = thread_response(image_bgr, self.calib.colour_model, contrast)
        xs, w = candidate_pixels(resp, mask, max_n=self.max_pixels, seed=index)

        def failed(msg):
            return GridPose(index, False, msg, H_pred, K, dist)

        if len(xs) < 100:
            return failed("grid not visible (almost no thread pixels)")
        q = (undistort(xs, K, dist) - c) / f
        # Fractional snap: circular mean of the cell coordinates of the thread pixels.
        ab = apply_h(Hc, q)
        za = np.sum(w * np.exp(2j * np.pi * ab[:, 0]))
        zb = np.sum(w * np.exp(2j * np.pi * ab[:, 1]))
        da, db = np.angle(za) / (2 * np.pi), np.angle(zb) / (2 * np.pi)
        Hc = np.array([[1.0, 0, -da], [0, 1.0, -db], [0, 0, 1]]) @ Hc
        # Bands wide enough for motion blur across a family's threads.
        pa, pb = periods_px(Hc, f)
        motion = self._motion_px(H_pred)
        J = Hc[:2, :2] - np.outer(Hc[:2, 2], Hc[2, :2])
        na, nb = J[0] / np.linalg.norm(J[0]), J[1] / np.linalg.norm(J[1])
        bands = (min(3.0 + 0.5 * abs(motion @ na), 0.4 * pa),
                 min(3.0 + 0.5 * abs(motion @ nb), 0.4 * pb))
        Hc, _, _, info = fit_lattice(xs, w, Hc, K, dist, band_px=bands, iterations=3)
        if not info or info["lines_a"] < 2 or info["lines_b"] < 2:
            return failed("grid not visible (fewer than 2 threads in a family)")
        # Integer cell index: jump relative to the prediction at the image centre.
        jump = apply_h(Hc, np.zeros((1, 2)))[0] - apply_h(Hc_pred, np.zeros((1, 2)))[0]
        k, note = self._colour_correction(contrast, xs, w, q, Hc, jump, bands)
        Hc = np.array([[1.0, 0, k[0]], [0, 1.0, k[1]], [0, 0, 1]]) @ Hc
        jump = jump + k
        H = metric_from_cells(Hc, K, self.sx, self.sy)
        pa, pb = periods_px(Hc, f)
        n_lines = info["lines_a"] + info["lines_b"]
        sigma = info["rms_px"] / np.sqrt(max(min(info["n_a"], info["n_b"]), 1) / 50.0)
        pose = GridPose(index, True, note, H, K, dist, spacing_px=float(np.sqrt(pa * pb)),
                        residual_px=info["rms_px"], n_threads=int(n_lines),
                        sigma_px=float(sigma), jump_cells=(float(jump[0]), float(jump[1])))
        if np.max(np.abs(jump)) > AMBIGUOUS_CELLS and not note:
            pose.ok = False
            pose.message = (f"cell index ambiguous: the grid moved {np.max(np.abs(jump)):.2f} "
                            "cells more than predicted and the thread colours cannot tell")
            return pose
        self._history = (self._history + [(index, H)])[-2:]
        return pose

    def _colour_correction(self, contrast, xs, w, q, Hc, jump, bands):
        """Integer cell shift (cells) that makes the thread colours match the sequence."""
        n = self.calib.n_colors
        if not self.calib.colors_resolved or n < 2:
            return np.zeros(2), ""
        f = self.K[0, 0]
        ab = apply_h(Hc, q)
        pa, pb = periods_px(Hc, f)
        fam_a, fam_b, ia, ib = assign_families(ab[:, 0], ab[:, 1], pa, pb, bands)
        model = self.calib.colour_model
        k = np.zeros(2)
        notes = []
        for j, (fam, idx) in enumerate(((fam_a, ia), (fam_b, ib))):
            cols = line_colours(contrast, xs, ab, fam, idx, j, model)
            p, agree = colour_phase(cols, n)
            if agree < 0.8 or len(cols) < n + 1 or p == 0:
                continue
            cands = np.array([-p, n - p, -p - n, 2 * n - p])
            best = cands[np.argmin(np.abs(jump[j] + cands))]
            k[j] = best
            notes.append(f"{'xy'[j]} cell index corrected by {int(best):+d} from the thread "
                         "colours")
        return k, "; ".join(notes)
