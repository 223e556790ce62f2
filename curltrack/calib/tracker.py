"""Follow the lattice from frame to frame with a continuous absolute cell index.

Per frame:

1. predict the homography from the last two trusted poses (constant velocity of the
   view over the ice; the camera follows a smoothly decelerating rock), moved so that
   the rock's markers, measured first, land where the rock's smooth motion puts them
   (``anchor``: a handheld camera's shake is then predicted too);
2. measure the threads on short cross profiles where the prediction puts them
   (:func:`.profiles.sample_threads`, ~``MAX_PROFILES`` of them, evenly spread) and
   refit the homography to those points
   (:func:`.lattice.fit_points`).  When the motion has not been smooth (start, after a
   lost frame, a jerk) or the threads are not where predicted, a coarse pass first, with
   profiles spanning almost a whole cell, snaps to the nearest lattice alignment;
3. check the integer cell index: the snap's correction relative to the prediction must
   stay below the settings' ``ambiguous_cells`` unless the thread colour sequence confirms the index
   (or says by how many cells it slipped, when only one shift fits the motion).

Otherwise the pose is returned with ``ok = False`` and a message, never a silent jump by
a cell; the next frames are predicted from the last trusted poses.

The colours tell the index only modulo the number of colours, and a prediction made
across a gap (more than ``stale_frames`` frames without a grid, while camera and rock may
have moved many cells) can be off by whole cells however well the snap fits.  Such a
pose starts a new *segment* (``GridPose.segment``): the cell index is continuous within
a segment, and the offset between segments is left to evidence from outside the grid
(:mod:`curltrack.track.segments`: the rock's path across the gap).  Motion blur across
a family of threads (the camera moves up to ~0.1 m per frame) is handled by longer
profiles, a blur-length detection filter and averaging along whole threads.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import TrackingError
from .grid import Calibration, PlaneMap, cells_from_metric, colour_phase, metric_from_cells
from .lattice import (centre_jacobian, fit_points, misfit_field, periods_px,
                      position_sigma_at)
from .profiles import sample_threads
from .lens import apply_h

PROFILE_STEP_PX = 18.0  # spacing of the cross profiles along each thread (px), at least
PROFILES_PER_CELL = 2.5  # at most this many profiles per cell along a thread: a sharper
# (larger) view measures each profile as well in px, hence better in metres
#: Cross profiles sampled per frame, about (two per point on a thread, or many along a
#: blurred thread averaged whole): the homography is as good from ~300 well-spread
#: points as from all (measured on rendered set-ups with 300-900), and the profiles
#: are most of the per-frame cost.
MAX_PROFILES = 640
COLOUR_CHECK_EVERY = 10  # frames between routine checks of the thread colour sequence
COARSE_STEP_PX = 40.0  # the same for the wide profiles of the coarse snap
FINE_HALF_PX = 5.0  # half-length (px) of the fine profiles before blur: thread + prediction
SHUTTER = 0.5  # assumed exposure (fraction of a frame) for the motion-blur filter
TURN_RETRIES_DEG = (4.0, -4.0, 8.0, -8.0)  # camera turns tried when the grid is lost
# The acceptance thresholds (ambiguous jumps, anchors, poor fits, fractions of threads
# found) are the rig's TrackingSettings (curltrack.settings), read as self.settings.


def poor_fit(rms_px: float, typical_px: float, settings) -> str:
    """Why a grid fit whose threads miss the lattice by ``rms_px`` (RMS, px) is refused
    against ``typical_px`` (the median residual of the last accepted frames), or "".

    Refused above ``settings.poor_fit_factor`` x typical and ``settings.poor_fit_min_px``.
    """
    if not rms_px > max(settings.poor_fit_min_px, settings.poor_fit_factor * typical_px):
        return ""
    return f"grid fit poor (thread residual {rms_px:.2f} px, {typical_px:.2f} px typical)"


def _origin(Hc):
    """Lattice coordinates (cells) of the image centre (the normalised origin)."""
    return Hc[:2, 2] / Hc[2, 2]


def _retry_predictions(Hc_pred):
    """Predictions to try when the threads are not found near the motion prediction.

    First moved by half a cell (threads half a cell off sit at the ends of the coarse
    profiles), then turned about the optical axis by :data:`TURN_RETRIES_DEG` (a camera
    turning faster than predicted, e.g. from the first frame, before its rate is known).
    """
    for da, db in ((0.5, 0.0), (0.0, 0.5), (0.5, 0.5)):
        yield np.array([[1.0, 0, da], [0, 1.0, db], [0, 0, 1]]) @ Hc_pred
    for deg in TURN_RETRIES_DEG:
        c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
        yield Hc_pred @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


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
        Rough 1-sigma uncertainty of the homography at the image centre (px); at other
        points :meth:`sigma_px_at`.
    jump_cells : (float, float)
        Snap correction relative to the motion prediction (cells, x and y family).
    segment : int
        Continuity segment of the cell index: poses of one segment share it; a new
        segment starts where the index was carried over a gap or fixed by the thread
        colours alone (its offset from the others in whole cells is unknown here).
    misfit : tuple or None
        The smooth part of the threads' misfit of ``H`` over the image
        (:func:`.lattice.misfit_field`, cells; read with :func:`.lattice.misfit_at` at
        normalised undistorted points), None when too few threads were measured.
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
    segment: int = 0
    notes: list = field(default_factory=list)
    misfit: tuple | None = None
    #: (the lattice as fitted - before any whole-cell shift -, its (8, 8) covariance,
    #: and the same by thread, :func:`.lattice.fit_points`' ``cov_threads``, or None)
    fit_cov: tuple | None = None

    def sigma_px_at(self, q) -> float:
        """1 sigma (px) of the lattice position at the normalised undistorted point
        ``q`` ((x_u - c) / f): the homography's uncertainty there, which away from the
        image centre can be many times ``sigma_px`` (:func:`.lattice.position_sigma_at`);
        ``sigma_px`` without the covariance.

        The larger of the independent points' and the threads' covariance: a thread's
        points share its misfit of the model, and where the rock lies beyond the
        threads that fix the lattice (a hand-held camera lagging a fast rock) the
        independent points' says too little (test_wrong_cell seed 3543473112: a row
        10 mm off under 2.9 mm, 3.6 sigma; 2.4 sigma by thread)."""
        if self.fit_cov is None:
            return self.sigma_px
        Hc, cov, cov_threads = self.fit_cov
        f = self.K[0, 0]
        sig = float(position_sigma_at(Hc, cov, q, f)[0])
        if cov_threads is not None:
            sig = max(sig, float(position_sigma_at(Hc, cov_threads, q, f)[0]))
        return sig


class GridTracker:
    """Per-frame homographies from a :class:`Calibration`.

    Parameters
    ----------
    calib : Calibration
        From :func:`calibrate_frame` on (ideally) the first frame tracked.
    rig : Rig
        For the thread spacings and colours.
    per_frame : int
        Exposures per video frame in the indices given to :meth:`update`: 2 for the
        fields of interlaced video (index = 2 x frame + field), so that the settings'
        ``stale_frames`` is counted in frames, as it says.
    """

    def __init__(self, calib: Calibration, rig, per_frame: int = 1):
        self.calib = calib
        self.rig = rig
        self.settings = rig.tracking
        #: frames without a grid after which the prediction is stale, in update's indices
        self.stale = int(self.settings.stale_frames) * max(int(per_frame), 1)
        self.K = calib.K
        self.dist = tuple(calib.dist)
        self.sx, self.sy = calib.spacing_x_m, calib.spacing_y_m
        w, h = calib.width, calib.height
        c = calib.K[:2, 2]
        self._ref = c + np.array([[-0.25, -0.25], [0.25, -0.25], [0.25, 0.25],
                                  [-0.25, 0.25]]) * (w, h)
        # trusted poses: (frame, H, the reference points mapped to the ice by H)
        self._history: list[tuple] = [(None, calib.H, apply_h(calib.H, self._ref))]
        self._centre_h = np.append(c, 1.0)  # principal point, homogeneous
        self._pred_err_px = 0.0  # running size of the prediction error (px)
        self._rms_px: list[float] = []  # fit residuals of the last accepted frames (px)
        self.segment = 0  # continuity segment of the cell index (see GridPose.segment)

    # -- prediction ------------------------------------------------------------------
    def _predict(self, index: int) -> np.ndarray:
        """Constant-velocity prediction of the homography for frame ``index``."""
        hist = self._history
        if len(hist) < 2 or hist[-2][0] is None:
            return hist[-1][1]
        (i0, _, P0), (i1, H1, P1) = hist[-2], hist[-1]
        if index - i1 > self.stale:
            return H1  # (a shaking camera's velocity means nothing that far ahead)
        import cv2

        P = P1 + (P1 - P0) * (index - i1) / max(i1 - i0, 1)
        return cv2.getPerspectiveTransform(self._ref.astype(np.float32),
                                           P.astype(np.float32)).astype(float)

    def _anchored(self, H_pred, px_u, ice_pred, max_cells=None) -> np.ndarray:
        """``H_pred`` moved on the ice so that it maps ``px_u`` (undistorted px) onto
        ``ice_pred`` (on average), or unchanged when that move is over ``max_cells``
        (default ``settings.anchor_max_cells``) or not finite."""
        if max_cells is None:
            max_cells = self.settings.anchor_max_cells
        seen = apply_h(H_pred, np.asarray(px_u, float))
        d = np.mean(np.asarray(ice_pred, float) - seen, axis=0)
        cells = np.abs(d) / (self.sx, self.sy)
        if not np.all(np.isfinite(d)) or np.max(cells) > max_cells:
            return H_pred
        return np.array([[1.0, 0.0, d[0]], [0.0, 1.0, d[1]], [0.0, 0.0, 1.0]]) @ H_pred

    def _motion_px(self, H_pred, index) -> np.ndarray:
        """Predicted image motion (px per frame) of the ice at the image centre."""
        i1, prev, _ = self._history[-1]
        gap = 1 if i1 is None else max(index - i1, 1)
        x = np.linalg.solve(H_pred, prev @ self._centre_h)  # (homogeneous image point)
        return (x[:2] / x[2] - self._centre_h[:2]) / gap

    # -- per frame -------------------------------------------------------------------
    def _measure(self, image_bgr, Hc_pred, mask, motion, coarse: bool):
        """Snap (optionally coarse first) and refine on thread profiles.

        Returns (Hc, info, obs); info None when too few thread points were found.
        """
        f = self.K[0, 0]
        Hc = Hc_pred
        J = centre_jacobian(Hc)
        normals = J / np.linalg.norm(J, axis=1, keepdims=True)
        blur = np.abs(normals @ motion)  # px of motion across each family per frame
        gap = np.array([5.0, 5.0])  # thread width + prediction error; blur runs along them
        if coarse:
            # Sparse profiles spanning almost a whole cell find the nearest alignment.
            half = [0.45 * p for p in periods_px(Hc, f)]
            obs = sample_threads(image_bgr, Hc, self.K, self.dist, self.calib.colour_model,
                                 half, step_px=COARSE_STEP_PX, mask=mask, gap_px=gap,
                                 blur_px=SHUTTER * blur,
                                 max_radius_px=self.calib.lens_radius_px)
            if obs is None or np.sum(obs.fam == 0) < 6 or np.sum(obs.fam == 1) < 6:
                return Hc, None, obs
            Hc, _ = fit_points(obs.xy, obs.w, obs.fam, obs.idx, Hc, self.K, self.dist,
                               iterations=2, clip_px=4.0, q=obs.q)
        # Profile half-lengths: prediction error plus motion blur across the threads.
        # (the smear of a thread is shutter x motion long: +-0.25 x motion for a half-open
        # shutter; 0.3 leaves room for a longer exposure)
        base = 5.0 if coarse else FINE_HALF_PX
        periods = periods_px(Hc, f)
        half = [min(base + 0.3 * blur[j], 0.4 * p) for j, p in enumerate(periods)]
        step = max(PROFILE_STEP_PX, min(periods) / PROFILES_PER_CELL)
        obs = sample_threads(image_bgr, Hc, self.K, self.dist, self.calib.colour_model, half,
                             step_px=step, mask=mask, gap_px=gap,
                             blur_px=SHUTTER * blur, max_profiles=MAX_PROFILES,
                             max_radius_px=self.calib.lens_radius_px)
        if obs is None or np.sum(obs.fam == 0) < 10 or np.sum(obs.fam == 1) < 10:
            return Hc, None, obs
        Hc, info = fit_points(obs.xy, obs.w, obs.fam, obs.idx, Hc, self.K, self.dist,
                              iterations=3, q=obs.q)
        info["ok_fraction"] = min(obs.found)
        return Hc, info, obs

    def update(self, image_bgr, index: int, mask=None, anchor=None) -> GridPose:
        """Measure the lattice in one frame.

        Parameters
        ----------
        image_bgr : (H, W, 3) uint8
        index : int
            Frame index (frames must come in increasing order; gaps are allowed).
        mask : (H, W) uint8, optional
            Nonzero = ignore (the rock disc and its surroundings, a broom).
        anchor : ((M, 2), (M, 2)) arrays, optional
            Points seen in this frame (undistorted px, :func:`~.lens.undistort`) and
            where they are predicted on the ice (lattice-frame m): the rock's markers,
            whose motion on the ice is smooth even when the camera's is not.  The motion
            prediction is moved so that it maps the one onto the other (by less than
            the settings' ``anchor_max_cells``, ``anchor_max_cells_stale`` after
            ``stale_frames`` without a grid; else the anchor is ignored), which follows a shaking camera without a
            coarse search and re-finds the grid after a loss.

        Returns
        -------
        GridPose
            ``ok = False`` with a message when the grid is not visible or the cell index
            is ambiguous; ``H`` is then the motion prediction.
        """
        K, dist = self.K, self.dist
        f = K[0, 0]
        shape = getattr(image_bgr, "shape", ())
        if shape[:2] != (self.calib.height, self.calib.width) or len(shape) != 3:
            raise TrackingError(f"frame size {shape} differs from the calibration's "
                                f"{self.calib.width}x{self.calib.height} BGR",
                                where=f"frame {index}")
        st = self.settings
        H_pred = self._predict(index)
        if anchor is not None:
            last = self._history[-1][0]
            stale = last is not None and index - last > self.stale
            H_pred = self._anchored(H_pred, *anchor, max_cells=(
                st.anchor_max_cells_stale if stale else st.anchor_max_cells))
        Hc_pred = cells_from_metric(H_pred, K, self.sx, self.sy)

        def failed(msg):
            return GridPose(index, False, msg, H_pred, K, dist)

        motion = self._motion_px(H_pred, index)
        smooth = (len(self._history) >= 2 and self._history[-2][0] is not None
                  and self._pred_err_px < 4.0)
        fallback = None  # a fine measurement plausible enough to keep if the snap fails
        for attempt in ((False, True) if smooth else (True,)):
            Hc, info, obs = self._measure(image_bgr, Hc_pred, mask, motion, coarse=attempt)
            if info is None or attempt:
                continue
            moved = np.abs(_origin(Hc) - _origin(Hc_pred)) * periods_px(Hc, f)
            # without the coarse snap the profiles see only +-FINE_HALF_PX around it
            if moved.max() < FINE_HALF_PX - 2.0:
                if info["ok_fraction"] > st.min_found_fine:
                    break
                if info["ok_fraction"] > st.min_found_fallback:
                    fallback = Hc, info, obs
        n_col = self.calib.n_colors if self.calib.colors_resolved else 0

        def weak_snap(obs):
            # A snap that found few of the threads it expected has locked onto something
            # else than the lattice (e.g. after a sudden turn) - unless it found the
            # threads of one colour: then the others are just faint (a thread colour
            # close to the ice's, blurred across).
            return min(obs.found_best_class(n_col)) < st.min_found_snap

        if attempt and fallback is not None and (info is None or weak_snap(obs)):
            # the snap found less (faint threads of one colour are missed by the wide
            # profiles, a broom hides some): the fine measurement stands
            (Hc, info, obs), attempt = fallback, False
        if info is None:
            for retry in _retry_predictions(Hc_pred):
                Hc, info, obs = self._measure(image_bgr, retry, mask, motion, coarse=True)
                if info is not None:
                    break
        if info is None:
            return failed("grid not visible (too few thread points)")
        if info["lines_a"] < 2 or info["lines_b"] < 2:
            return failed("grid not visible (fewer than 2 threads in a family)")
        if attempt and weak_snap(obs):
            return failed(f"grid not followed (a snap found only "
                          f"{100 * info['ok_fraction']:.0f} % of the expected threads)")
        typical = float(np.median(self._rms_px)) if len(self._rms_px) >= 5 else None
        if typical is not None and (why := poor_fit(info["rms_px"], typical, st)):
            return failed(why)
        # (before any whole-cell shift: the points' indices are this fit's)
        misfit = misfit_field(obs.q, obs.w, obs.fam, obs.idx, Hc, f)
        fit_cov = (Hc, info["cov"], info.get("cov_threads"))
        jump = _origin(Hc) - _origin(Hc_pred)
        # The colours are read when the index could have slipped (a coarse snap, a large
        # correction) and every COLOUR_CHECK_EVERY frames as a confirmation.
        if attempt or np.abs(jump).max() > 0.15 or index % COLOUR_CHECK_EVERY == 0:
            k, note, ambiguous, confirmed = self._colour_correction(obs, jump, n_col)
        else:
            k, note, ambiguous, confirmed = np.zeros(2), "", False, [False, False]
        Hc = np.array([[1.0, 0, k[0]], [0, 1.0, k[1]], [0, 0, 1]]) @ Hc
        jump = jump + k
        H = metric_from_cells(Hc, K, self.sx, self.sy)
        pa, pb = periods_px(Hc, f)
        pose = GridPose(index, True, note, H, K, dist, spacing_px=float(np.sqrt(pa * pb)),
                        residual_px=info["rms_px"],
                        n_threads=int(info["lines_a"] + info["lines_b"]),
                        sigma_px=info["sigma_px"], jump_cells=(float(jump[0]), float(jump[1])),
                        misfit=misfit, fit_cov=fit_cov)
        if ambiguous:
            pose.ok = False
            pose.message = "cell index uncertain: " + note
            return pose
        unchecked = np.abs(jump) * ~np.array(confirmed)
        if np.max(unchecked) > st.ambiguous_cells:
            pose.ok = False
            pose.message = (f"cell index ambiguous: the grid moved {np.max(unchecked):.2f} "
                            "cells more than predicted and the thread colours cannot tell")
            return pose
        last = self._history[-1][0]
        if ((last is not None and index - last > self.stale) or np.any(k != 0)
                or np.max(np.abs(jump)) > st.ambiguous_cells):
            # the index rests on a stale prediction or on the colours (modulo their
            # number): continuous from here on, but its offset is not known here
            self.segment += 1
        pose.segment = self.segment
        err = float(np.hypot(*(np.asarray(jump) * (pa, pb))))
        self._pred_err_px = 0.5 * self._pred_err_px + 0.5 * err
        self._rms_px = (self._rms_px + [info["rms_px"]])[-st.poor_fit_frames:]
        self._history = (self._history + [(index, H, apply_h(H, self._ref))])[-2:]
        return pose

    def _colour_correction(self, obs, jump, n):
        """Integer cell shift (cells) that makes the thread colours match the sequence.

        Returns (shift, note, ambiguous, confirmed): ambiguous when the colours say the
        index is off but two shifts explain the motion about equally well; confirmed[j]
        when family j's colours were read well enough to check its index (mod n).
        """
        confirmed = [False, False]
        if n < 2 or obs.colour is None:
            return np.zeros(2), "", False, confirmed
        k = np.zeros(2)
        notes = []
        ambiguous = False
        for j in (0, 1):
            sel = obs.fam == j
            ids = obs.idx[sel]
            cols = {}
            for i in np.unique(ids):
                cols[int(i)] = int(np.argmax(obs.colour[sel][ids == i].sum(axis=0)))
            p, agree, _ = colour_phase(cols, n, sign=self.calib.color_signs[j])
            if agree < 0.8 or len(cols) < n + 1:
                continue
            confirmed[j] = True
            if p == 0:
                continue
            if abs(jump[j]) < 0.25:
                # the threads are where the motion put them: a slip is not plausible, the
                # colours are more likely misread -- say so rather than move by a cell
                ambiguous = True
                notes.append(f"{'xy'[j]} thread colours disagree with the tracked cell index")
                continue
            cands = np.array([-p + m * n for m in (-1, 0, 1, 2)])
            cost = np.abs(jump[j] + cands)
            o = np.argsort(cost)
            if cost[o[1]] - cost[o[0]] < 0.3:
                ambiguous = True
                notes.append(f"{'xy'[j]} cell index off by the thread colours, but by "
                             f"{int(cands[o[0]]):+d} or {int(cands[o[1]]):+d}")
                continue
            k[j] = cands[o[0]]
            notes.append(f"{'xy'[j]} cell index corrected by {int(k[j]):+d} from the thread "
                         "colours")
        return k, "; ".join(notes), ambiguous, confirmed
