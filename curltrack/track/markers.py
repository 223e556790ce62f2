"""Find the rock's coloured markers in a frame: colour model, sub-pixel centroids, identity.

Pixel convention (as :mod:`curltrack.calib.lens`): origin at the centre of the top-left
pixel, x to the right, y down; positions are in the observed (distorted) image.

Colour model
------------
Pixels are classified by their nearest *prototype* colour in CIE Lab (lightness
half-weighted, so shading matters less than hue): the rig's marker colours (adapted to
the colours actually seen once markers have been found), the rig's thread colours and
the local background (median of the search window).  A pixel is a marker candidate when
it is nearer its marker's prototype than to every other prototype *and* nearer than half
the way to the background - a threshold relative to the scene, not a fixed number.

Sub-pixel centroid
------------------
Around each candidate blob the marker's coverage of every pixel is estimated by
projecting its RGB value onto the segment background -> marker colour (linear mixing, as
blur and anti-aliasing produce); the centroid is the coverage-weighted mean position, and
its 1 sigma follows from the pixel noise measured in the background ring.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np

from .._stats import median, robust_sigma
from ..rig import Rig, parse_color

__all__ = ["MarkerDetector", "MarkerFrame", "lab_of_rgb"]

_L_WEIGHT = 0.5
_ADAPT = 0.15  # weight of a new observation in the running marker colour
#: An observation teaches the running colour only with at least this fraction of its
#: chroma off the background, and a hue within this angle of it (:meth:`_adaptable`).
_ADAPT_MIN_CHROMA = 0.5
_ADAPT_MAX_HUE_DEG = 60.0
#: A blob is a chromatic marker only with at least this fraction of the colour model's
#: chroma and a hue within this angle of it (a camcorder's cyan, chroma ~15 Lab units,
#: took grey blobs 20-50 px away for the marker: the rock 40 mm, 43 deg off, ok = 1).
_BLOB_MIN_CHROMA = 0.25
_BLOB_MAX_HUE_DEG = 75.0
_WIN = (1.6, 1.5)
_FLOOR = 0.1
_CHROMA_P = np.eye(3) - 1.0 / 3.0  # RGB -> its component off the grey axis
#: Markers at least this large (radius, px) are classified at half resolution (a blob of
#: ~20 px is still a blob there); their sub-pixel centroid is measured at full resolution.
_LOWRES_RADIUS_PX = 5.0
#: Darkest pixel (r + g + b, 0-765) given a chromaticity in the fallback classification:
#: below it 8-bit noise and compression move r/(r+g+b) by more than markers differ.
_CHROMA_MIN_SUM = 60.0
#: Frames at least this large (short side, px) are first searched at half resolution
#: while the marker size is unknown (full resolution when that misses a marker).
_LOWRES_FIRST_MIN_PX = 480
#: Largest region (marker areas) of a marker's colour class searched for a marker-sized
#: core against its own colour (:meth:`MarkerDetector._split_oversized`): the rock's
#: whole top, ~130 marker areas (a 25 mm marker on a 0.29 m rock).
_SPLIT_MAX_AREAS = 150.0
#: :meth:`MarkerDetector.find_missing`: a missing marker is looked for between these
#: multiples of its rig distance from a found marker at the ice's scale - the markers'
#: parallax H / (H - h) is 1.02-1.2 for cameras 0.7-6 m over a 0.114 m rock, and the
#: scale is read at the found marker (a lens and a tilt change it a few % across the
#: rock) - at up to this many blobs, each at least this fraction of the marker colour's
#: chroma off its surroundings (a marker-sized box against one three times as wide).
_PARTNER_RING = (0.9, 1.3)
_PARTNER_TRIES = 4
_PARTNER_MIN_COVER = 0.1
#: ... and around a marker's prediction, within this many marker radii (+2 px).
_PREDICTED_GATE = 3.0


def _keeps_distances(xy, predicted, idx, rel: float) -> bool:
    """Whether the markers ``idx`` keep their predicted mutual distances (px) to
    ``rel`` of each plus 1 px."""
    for a, b in itertools.combinations(idx, 2):
        d_pred = np.hypot(*(predicted[a] - predicted[b]))
        if abs(np.hypot(*(xy[a] - xy[b])) - d_pred) > rel * d_pred + 1.0:
            return False
    return True


def lab_of_rgb(rgb) -> np.ndarray:
    """(R, G, B) 0-255 -> OpenCV 8-bit Lab (float), the space used for classifying;
    any leading shape, ``(..., 3)``."""
    import cv2

    rgb = np.asarray(rgb, np.uint8)
    px = np.ascontiguousarray(rgb.reshape(1, -1, 3)[:, :, ::-1])
    return cv2.cvtColor(px, cv2.COLOR_BGR2Lab).reshape(rgb.shape).astype(float)


def _weigh(lab: np.ndarray) -> np.ndarray:
    out = lab.astype(np.float32, copy=True)
    out[..., 0] *= _L_WEIGHT
    return out


@dataclass
class MarkerFrame:
    """Markers found in one frame, in rig order.

    Attributes
    ----------
    xy_px : (M, 2) array
        Sub-pixel centroids (observed image px); NaN where a marker was not found.
    sigma_px : (M,) array
        1 sigma of each centroid (px, per axis); NaN where not found.
    area_px : (M,) array
        Blob areas (px^2).
    contrast : (M,) array
        Marker-to-background colour distance (Lab units) - a match-quality figure.
    message : str
        Why markers are missing (empty when all were found).
    """

    xy_px: np.ndarray
    sigma_px: np.ndarray
    area_px: np.ndarray
    contrast: np.ndarray
    message: str = ""

    @property
    def found(self) -> np.ndarray:
        return np.isfinite(self.xy_px).all(axis=1)


@dataclass
class MarkerDetector:
    """Detect and identify the rig's markers, adapting the colour model as it goes.

    Parameters
    ----------
    rig : Rig
        Marker colours and layout (m, rock frame); thread colours.

    Examples
    --------
    >>> det = MarkerDetector(rig)                                   # doctest: +SKIP
    >>> mf = det.detect(image_bgr)                  # whole frame, first time
    >>> mf = det.detect(image_bgr, predicted=mf.xy_px, roi=(x0, y0, x1, y1))
    """

    rig: Rig
    colors_lab: np.ndarray = field(init=False)
    area_px: float | None = field(default=None, init=False)
    #: The markers' area (px^2) when first found: the running ``area_px`` stays within a
    #: factor 2 of it (the camera's height changes little during a shot), so that what
    #: hides the rock for a while - a broom head taken for a marker - cannot teach it a
    #: size that excludes the real markers.
    area_ref_px: float | None = field(default=None, init=False)

    def __post_init__(self):
        self.layout_m = self.rig.layout_m
        self.ref_lab = np.array([lab_of_rgb(parse_color(m.color)) for m in self.rig.markers])
        self.colors_lab = self.ref_lab.copy()
        uniq, self.class_of = np.unique(self.ref_lab.round(1), axis=0, return_inverse=True)
        self.class_of = self.class_of.ravel()
        self.n_classes = len(uniq)
        # class means of the (adapting) marker colours as one product: _class_mean @ lab
        member = self.class_of[None, :] == np.arange(self.n_classes)[:, None]
        self._class_mean = member / member.sum(axis=1, keepdims=True)
        self.thread_lab = np.array([lab_of_rgb(parse_color(c)) for c in self.rig.grid_colors]
                                   ).reshape(-1, 3)
        # chromaticities of the marker colour classes, then of the threads (rig colours)
        rgb = np.array([parse_color(c) for c in
                        [self.rig.markers[int(np.flatnonzero(self.class_of == k)[0])].color
                         for k in range(self.n_classes)] + list(self.rig.grid_colors)], float)
        self._chroma_refs = rgb / np.maximum(rgb.sum(axis=1, keepdims=True), 1.0)

    # --- classification --------------------------------------------------------------
    def _prototypes(self, bg_lab: np.ndarray) -> np.ndarray:
        """Weighted Lab prototypes: the marker colour classes, the threads, the
        background ``bg_lab`` (last)."""
        return _weigh(np.vstack([self._class_mean @ self.colors_lab, self.thread_lab,
                                 np.reshape(bg_lab, (1, 3))]))

    def _class_masks(self, lab: np.ndarray, bg_lab: np.ndarray) -> list[np.ndarray]:
        """One boolean mask per marker colour class (nearest-prototype rule)."""
        protos = self._prototypes(bg_lab)
        w = _weigh(lab).reshape(-1, 3)
        # squared distances to every prototype, |w|^2 - 2 w.p + |p|^2, as one product
        d = ((w * w).sum(axis=1)[:, None] - 2.0 * (w @ protos.T)
             + (protos * protos).sum(axis=1)[None]).T.reshape(len(protos), *lab.shape[:2])
        nearest = np.argmin(d, axis=0)
        masks = []
        for c in range(self.n_classes):
            half_to_bg = 0.25 * float(np.sum((protos[c] - protos[-1]) ** 2))
            masks.append((nearest == c) & (d[c] < half_to_bg))
        return masks

    def _chroma_masks(self, patch_bgr: np.ndarray) -> list[np.ndarray]:
        """:meth:`_class_masks` by chromaticity ``rgb / (r + g + b)``, which a shadow or
        an exposure change (a common gain on r, g, b) leaves as it is: the nearest-
        prototype rule over the rig's marker and thread colours and the window's median,
        for pixels bright enough to have a chromaticity (:data:`_CHROMA_MIN_SUM`)."""
        rgb = patch_bgr[..., ::-1].astype(np.float32)
        total = rgb.sum(axis=-1)
        chroma = rgb / np.maximum(total, 1.0)[..., None]
        bg = median(chroma.reshape(-1, 3)[::3], axis=0)
        protos = np.vstack([self._chroma_refs, np.reshape(bg, (1, 3))]).astype(np.float32)
        d = ((chroma[..., None, :] - protos) ** 2).sum(axis=-1)
        nearest = np.argmin(d, axis=-1)
        bright = total > max(_CHROMA_MIN_SUM, 0.2 * float(median(total.ravel()[::3])))
        masks = []
        for c in range(self.n_classes):
            half_to_bg = 0.25 * float(np.sum((protos[c] - bg) ** 2))
            masks.append((nearest == c) & (d[..., c] < half_to_bg) & bright)
        return masks

    def _adaptable(self, obs_lab, bg_lab, i, min_chroma: float = None,
                   max_hue_deg: float = None) -> bool:
        """Whether an observed core colour may teach the model of marker ``i``: its
        chroma (Lab a, b off the grey axis) at least :data:`_ADAPT_MIN_CHROMA` of the
        model's and within :data:`_ADAPT_MAX_HUE_DEG` of its hue (a model with little
        chroma - a grey or black marker - is taught by any observation).  (Off the grey
        axis, not off the ring's median: next to the dark handle that median is itself
        off-grey, and a model's chroma measured from it can look small.)

        A core that is mostly something else - the rock's dark handle next to a
        marker smeared by coarse chroma (4:1:1 camcorder video), a broom - has the
        chroma of neither; learning from it a few frames in a row turned a cyan model
        grey, which then matched the handle and no longer the marker (a rendered
        camcorder shot lost its markers for the second half of the shot).
        """
        m = self.colors_lab[i][1:] - 128.0
        c = np.asarray(obs_lab, float)[1:] - 128.0
        nm, nc = float(np.hypot(*m)), float(np.hypot(*c))
        if nm < 10.0:  # (a marker without much chroma: lightness decides)
            return True
        min_chroma = _ADAPT_MIN_CHROMA if min_chroma is None else min_chroma
        max_hue_deg = _ADAPT_MAX_HUE_DEG if max_hue_deg is None else max_hue_deg
        return (nc >= min_chroma * nm
                and float(c @ m) >= np.cos(np.radians(max_hue_deg)) * nc * nm)

    def _is_class(self, obs_lab, bg_lab, i) -> bool:
        """The nearest-prototype rule of :meth:`_class_masks` for one colour."""
        c = self.class_of[i]
        protos = self._prototypes(bg_lab)
        d = np.sum((protos - _weigh(obs_lab)) ** 2, axis=1)
        return bool(d[c] <= d.min() and d[c] < 0.25 * np.sum((protos[c] - protos[-1]) ** 2))

    # --- public ------------------------------------------------------------------------
    def forget(self) -> None:
        """Back to the first frame's knowledge: the rig's colours and marker size."""
        self.colors_lab = self.ref_lab.copy()
        self.area_px = self.area_ref_px

    def memory(self) -> tuple:
        """What :meth:`forget` drops (the learnt colours and size), for :meth:`recall`."""
        return self.colors_lab.copy(), self.area_px

    def recall(self, memory: tuple) -> None:
        """Back to a :meth:`memory`."""
        self.colors_lab, self.area_px = memory[0].copy(), memory[1]

    def refine_at(self, image_bgr: np.ndarray, predicted: np.ndarray) -> MarkerFrame | None:
        """Markers measured directly around well-predicted positions, or None.

        The sub-pixel step of :meth:`detect` started at the prediction instead of at a
        classified blob (no colour classification of a search window).  Accepted only
        when every marker is found within half a marker radius (+1 px) of where the
        refinement started (the prediction, or once more where that converged; within
        :meth:`detect`'s gate of the prediction), with the expected size and colour
        class, and the markers' mutual distances agree with the prediction's to 3 %
        (+1 px); otherwise None and the caller runs :meth:`detect`.

        Parameters
        ----------
        image_bgr : (H, W, 3) uint8
        predicted : (M, 2) array
            Predicted centroids (observed image px).
        """
        if self.area_px is None or not np.isfinite(predicted).all():
            return None
        M = len(self.rig.markers)
        r = np.sqrt(self.area_px / np.pi)
        xy, sig, area, con = np.full((M, 2), np.nan), np.full(M, np.nan), np.zeros(M), np.zeros(M)
        saved = self.colors_lab.copy()
        for i in range(M):
            start = predicted[i]
            for _ in range(2):  # (a second start where the first one converged to)
                res = self._refine(image_bgr, None, None, start, self.area_px, i,
                                   check_class=True)
                if res is None or np.hypot(*(res[0] - start)) <= 0.5 * r + 1.0:
                    break
                start = res[0]
            if (res is None or np.hypot(*(res[0] - start)) > 0.5 * r + 1.0
                    or np.hypot(*(res[0] - predicted[i])) > 3.0 * r + 10.0  # detect's gate
                    or not 0.5 < res[2] / self.area_px < 2.0):
                self.colors_lab = saved
                return None
            xy[i], sig[i], area[i], con[i] = res
        if not _keeps_distances(xy, predicted, range(M), 0.03):
            self.colors_lab = saved
            return None
        self._learn_area(float(median(area)))
        return MarkerFrame(xy, sig, area, con, "")

    def detect(self, image_bgr: np.ndarray, predicted: np.ndarray | None = None,
               roi: tuple | None = None, gate_px: float | None = None) -> MarkerFrame:
        """Find the markers in ``image_bgr`` (or its ``roi`` = (x0, y0, x1, y1) px).

        Parameters
        ----------
        image_bgr : (H, W, 3) uint8
        predicted : (M, 2) array, optional
            Predicted centroids (px); candidates are taken nearest to these within
            ``gate_px``.  Without it the set most consistent with the rig layout wins.
        roi : tuple of int, optional
            Search window; the whole frame when None.
        gate_px : float, optional
            Largest distance from the prediction (px); default 3 marker radii + 10 px.

        Returns
        -------
        MarkerFrame
        """
        H, W = image_bgr.shape[:2]
        x0, y0, x1, y1 = (0, 0, W, H) if roi is None else roi
        x0, y0 = max(0, int(x0)), max(0, int(y0))
        x1, y1 = min(W, int(x1)), min(H, int(y1))
        M = len(self.rig.markers)
        empty = MarkerFrame(np.full((M, 2), np.nan), np.full(M, np.nan), np.zeros(M),
                            np.zeros(M), "search window outside the image")
        if x1 - x0 < 4 or y1 - y0 < 4:
            return empty
        big = self.area_px is not None and self.area_px >= np.pi * _LOWRES_RADIUS_PX ** 2
        if min(x1 - x0, y1 - y0) < 8:
            steps = (1,)
        elif big:
            steps = (2,)
        elif self.area_px is None and min(H, W) >= _LOWRES_FIRST_MIN_PX:
            steps = (2, 1)  # marker size not known yet: half resolution first
        else:
            steps = (1,)
        for step in steps:
            cands = self._candidates(image_bgr, (x0, y0, x1, y1), step)
            pick = self._assign(cands, predicted, gate_px)
            if all(c_xy is not None for c_xy, _ in pick):
                break
        n_found = sum(c_xy is not None for c_xy, _ in pick)
        if n_found < M and predicted is not None and np.isfinite(predicted).all():
            # Markers darker or paler than their colours (a shadow, the exposure set for
            # bright ice): classify by chromaticity instead, near the prediction only.
            alt = self._assign(self._candidates(image_bgr, (x0, y0, x1, y1), steps[-1],
                                                chromatic=True), predicted, gate_px)
            if sum(c_xy is not None for c_xy, _ in alt) > n_found:
                pick = alt
        xy = np.full((M, 2), np.nan)
        sig = np.full(M, np.nan)
        area = np.zeros(M)
        con = np.zeros(M)
        for i, (c_xy, c_area) in enumerate(pick):
            if c_xy is None:
                continue
            res = self._refine(image_bgr, None, (x0, y0), c_xy, c_area, i)
            # The classified blob can be smaller than the marker (blur, a colour model
            # not yet adapted): then the window cut the marker; redo it at the coverage
            # area found.
            for _ in range(2):
                if res is None or res[2] < 1.2 * c_area:
                    break
                c_xy, c_area = res[0], res[2]
                res = self._refine(image_bgr, None, (x0, y0), c_xy, c_area, i)
            if res is not None:
                xy[i], sig[i], area[i], con[i] = res
        return self._frame(xy, sig, area, con)

    def find_missing(self, image_bgr: np.ndarray, mf: MarkerFrame, m_per_px: float = np.nan,
                     predicted: np.ndarray | None = None) -> MarkerFrame:
        """The markers a search missed, looked for where the rig's layout puts them from
        the markers it found (given the image's scale there), or where they were
        predicted.

        The classification of :meth:`detect` needs a marker's pixels to show more than
        half of its rig colour's contrast against the background.  A small marker
        smeared by the rock's motion and by the video's coarse chroma (a ~3 px marker at
        640x360, 4:2:0, 0.6 Mbit/s) or recoloured by auto white balance (a phone: a cyan
        marker on green-tinted ice) shows 30-50 %: found in no frame until the rock
        slows, while its pixels still stand clearly off the granite.  Here each missing
        marker is looked for only in the annulus where the layout puts it from every
        found marker - the rig distance between them at ``m_per_px`` times the parallax
        factor (:data:`_PARTNER_RING`) - and, with ``predicted``, within
        :data:`_PREDICTED_GATE` marker radii of its prediction, as the strongest
        marker-sized blobs of the marker's chroma off their surroundings; it is accepted
        only where the sub-pixel refinement (:meth:`_refine`, with its contrast and
        chroma checks) converges inside that region, at a size within a factor 2 of the
        found markers' (or the learnt size).  Markers found around a prediction must
        keep the predicted mutual distances (to 5 % + 1 px), as in :meth:`refine_at`.

        Parameters
        ----------
        image_bgr : (H, W, 3) uint8
        mf : MarkerFrame
            What :meth:`detect` found.
        m_per_px : float, optional
            Ice metres per image pixel at the found markers (m/px); NaN: no annulus.
        predicted : (M, 2) array, optional
            Predicted centroids (observed image px).

        Returns
        -------
        MarkerFrame
            ``mf`` with the markers found here filled in (its message updated).
        """
        found = mf.found
        use_scale = bool(found.any() and np.isfinite(m_per_px) and m_per_px > 0)
        use_pred = predicted is not None and bool(np.isfinite(predicted).all())
        if found.all() or not (use_scale or use_pred):
            return mf
        a_ref = float(median(mf.area_px[found])) if found.any() else self.area_px
        if a_ref is None or not a_ref > 0:
            return mf
        r_mk = max(1.0, math.sqrt(a_ref / math.pi))
        xy, sig = mf.xy_px.copy(), mf.sigma_px.copy()
        area, con = mf.area_px.copy(), mf.contrast.copy()
        for i in np.flatnonzero(~found):
            # the region: (centre px, inner and outer radius px) it must lie within
            rings = []
            if use_scale:
                known = np.flatnonzero(np.isfinite(xy[:, 0]))
                dist = np.hypot(*(self.layout_m[known] - self.layout_m[i]).T) / m_per_px
                rings += [(xy[j], _PARTNER_RING[0] * d, _PARTNER_RING[1] * d)
                          for j, d in zip(known, dist)]
            if use_pred:
                rings.append((predicted[i], 0.0, _PREDICTED_GATE * r_mk + 2.0))
            res = self._blob_in(image_bgr, i, rings, a_ref, r_mk)
            if res is not None:
                xy[i], sig[i], area[i], con[i] = res
        new = ~found & np.isfinite(xy[:, 0])
        if use_pred and new.any():
            if not _keeps_distances(xy, predicted, np.flatnonzero(np.isfinite(xy[:, 0])), 0.05):
                xy[new], sig[new], area[new], con[new] = np.nan, np.nan, 0.0, 0.0
        return self._frame(xy, sig, area, con)

    def _blob_in(self, image_bgr, i, rings, a_ref: float, r_mk: float):
        """Marker ``i`` as the strongest marker-sized blob of its chroma off its
        surroundings inside every ring (centre px, r_lo, r_hi) - see :meth:`find_missing`:
        (xy, sigma, area, contrast) from :meth:`_refine`, or None."""
        import cv2

        H, W = image_bgr.shape[:2]
        c, _, hi = min(rings, key=lambda g: g[2])  # (the smallest bounds the window)
        x0, y0 = max(0, int(c[0] - hi - 1)), max(0, int(c[1] - hi - 1))
        x1, y1 = min(W, int(c[0] + hi + 2)), min(H, int(c[1] + hi + 2))
        if x1 - x0 < 4 or y1 - y0 < 4:
            return None
        win = image_bgr[y0:y1, x0:x1, ::-1].astype(np.float32)  # RGB
        gy, gx = np.mgrid[y0:y1, x0:x1].astype(float)
        region = np.ones(win.shape[:2], bool)
        for p, lo, hi in rings:
            rr = np.hypot(gx - p[0], gy - p[1])
            region &= (rr >= lo) & (rr <= hi)
        if not region.any():
            return None
        bg = median(win[region].T, axis=1)
        target = cv2.cvtColor(np.clip(self.colors_lab[i], 0, 255).astype(np.uint8)
                              .reshape(1, 1, 3), cv2.COLOR_Lab2RGB).reshape(3)
        d = target.astype(float) - bg
        d_c = d - d.mean()  # (its chroma: the granite's and the ice's greys do not count)
        den = float(d_c @ d)
        if den <= 0 or float(d_c @ d_c) < 1.0:
            return None
        cover = ((win - bg) @ (d_c / den)).astype(np.float32)
        # a marker-sized blob against its surroundings (a box three times as wide): a
        # stretch of tinted ice or granite scores ~0
        k_sz = 2 * int(round(r_mk)) + 1
        score = cv2.blur(cover, (k_sz, k_sz)) - cv2.blur(cover, (3 * k_sz, 3 * k_sz))
        score[~region] = -np.inf
        for _ in range(_PARTNER_TRIES):
            v, u = np.unravel_index(int(np.argmax(score)), score.shape)
            if not score[v, u] > _PARTNER_MIN_COVER:
                return None
            score[max(0, v - 2 * k_sz):v + 2 * k_sz + 1,
                  max(0, u - 2 * k_sz):u + 2 * k_sz + 1] = -np.inf
            res = self._refine(image_bgr, None, None, (x0 + u, y0 + v), a_ref, i)
            if res is None or not 0.5 < res[2] / a_ref < 2.0:
                continue
            if all(lo <= np.hypot(*(res[0] - p)) <= hi for p, lo, hi in rings):
                return res
        return None

    def _frame(self, xy, sig, area, con) -> MarkerFrame:
        """A search's MarkerFrame: the missing markers named in its message, the running
        marker size learnt from a complete one."""
        missing = [self.rig.markers[i].color for i in range(len(xy)) if not np.isfinite(xy[i, 0])]
        msg = f"marker(s) {', '.join(missing)} not found" if missing else ""
        if not missing:
            self._learn_area(float(np.median(area)))
        return MarkerFrame(xy, sig, area, con, msg)

    def _learn_area(self, area: float) -> None:
        """Fold one frame's marker area (px^2) into the running size (see area_ref_px)."""
        if self.area_px is None or self.area_ref_px is None:
            self.area_px = self.area_ref_px = area
            return
        self.area_px = float(np.clip(0.9 * self.area_px + 0.1 * area,
                                     0.5 * self.area_ref_px, 2.0 * self.area_ref_px))

    def _candidates(self, image_bgr, box, step, chromatic: bool = False):
        """Per colour class: up to 6 blobs (centroids px, areas px^2, full-image units)
        of the window ``box`` = (x0, y0, x1, y1), classified at 1/``step`` resolution
        (in Lab, or with ``chromatic`` by chromaticity: :meth:`_chroma_masks`)."""
        import cv2

        x0, y0, x1, y1 = box
        patch = image_bgr[y0:y1, x0:x1]
        if step == 2:  # pixel (u, v) = the mean of full-res pixels 2u..2u+1, 2v..2v+1
            patch = cv2.resize(patch, ((x1 - x0) // 2, (y1 - y0) // 2),
                               interpolation=cv2.INTER_AREA)
        if chromatic:
            masks = self._chroma_masks(patch)
        else:
            lab = cv2.cvtColor(patch, cv2.COLOR_BGR2Lab).astype(np.float32)
            masks = self._class_masks(lab, median(lab.reshape(-1, 3)[::3], axis=0))
        cands = []
        for c, mask in enumerate(masks):
            n, labels, stats, cents = cv2.connectedComponentsWithStats(mask.view(np.uint8), 8)
            areas = stats[1:, cv2.CC_STAT_AREA].astype(float) * step ** 2
            xy = cents[1:] * step + (0.5 * (step - 1) + x0, 0.5 * (step - 1) + y0)
            if self.area_px is None:
                keep = areas >= 3.0
            else:  # (a marker-coloured patch of ice or broom much larger is not one)
                keep = (areas >= max(3.0, 0.25 * self.area_px)) & (areas <= 4.0 * self.area_px)
            if self.area_px is not None and not chromatic:
                # An oversized region may hold the marker inside a surface of nearly its
                # colour: looked at against that surface, its marker-coloured core
                split = self._split_oversized(patch, labels, stats, c, step, (x0, y0),
                                              areas)
                if split is not None:
                    xy = np.vstack([xy, split[0]])
                    areas = np.concatenate([areas, split[1]])
                    keep = np.concatenate([keep, np.ones(len(split[1]), bool)])
            order = np.argsort(-areas[keep])[:6]
            cands.append((xy[keep][order], areas[keep][order]))
        return cands

    def _split_oversized(self, patch, labels, stats, c, step, origin, areas):
        """Marker-sized cores of the oversized regions of colour class ``c``, or None.

        A region classified as the marker's colour over several marker areas (more than
        the candidates' 4x) is mostly something of nearly that colour: a marker whose
        colour the camera shows washed out (a camcorder's 4:1:1 chroma at a low bitrate:
        a cyan ~15 Lab units off grey) is then not told apart from the rock's surface
        against the frame's background (the ice), and the rock's whole top passes for
        the marker.  Each such region (up to :data:`_SPLIT_MAX_AREAS` marker areas) is
        classified once more against its own median colour - the surface around the
        marker - with the same nearest-prototype rule: a marker-sized blob inside it
        whose colour stands off that surface towards the marker's is a candidate (its
        sub-pixel refinement then checks its core's chroma against the ring around it,
        as for any candidate).  A region of one colour throughout (a patch of ice, a
        broom) leaves no such core.  Returns (xy (K, 2) px, areas (K,) px^2).
        """
        import cv2

        out_xy, out_a = [], []
        big = np.flatnonzero((areas > 4.0 * self.area_px)
                             & (areas <= _SPLIT_MAX_AREAS * self.area_px))
        r_lo = np.sqrt(self.area_px / np.pi) / step  # marker radius at this resolution
        for j in big[:3]:
            x, y, w, h = (int(v) for v in stats[j + 1, :4])
            m = int(np.ceil(r_lo)) + 1
            ya, yb = max(0, y - m), min(patch.shape[0], y + h + m)
            xa, xb = max(0, x - m), min(patch.shape[1], x + w + m)
            region = labels[ya:yb, xa:xb] == j + 1
            lab = cv2.cvtColor(np.ascontiguousarray(patch[ya:yb, xa:xb]),
                               cv2.COLOR_BGR2Lab).astype(np.float32)
            surface = median(lab[region], axis=0)
            sub = self._class_masks(lab, surface)[c] & region
            n, _, st, ce = cv2.connectedComponentsWithStats(sub.view(np.uint8), 8)
            a = st[1:, cv2.CC_STAT_AREA].astype(float) * step ** 2
            ok = (a >= max(3.0, 0.25 * self.area_px)) & (a <= 4.0 * self.area_px)
            if not ok.any():
                continue
            pts = (ce[1:][ok] + (xa, ya)) * step + (0.5 * (step - 1) + origin[0],
                                                     0.5 * (step - 1) + origin[1])
            out_xy.append(pts)
            out_a.append(a[ok])
        if not out_xy:
            return None
        return np.vstack(out_xy), np.concatenate(out_a)

    # --- identity ----------------------------------------------------------------------
    def _assign(self, cands, predicted, gate_px):
        """Choose one candidate blob per marker: by prediction, else by layout."""
        M = len(self.rig.markers)
        options = []
        for i in range(M):
            c_xy, c_area = cands[self.class_of[i]]
            opts = [(j, c_xy[j], c_area[j]) for j in range(len(c_xy))]
            if predicted is not None and np.isfinite(predicted[i]).all():
                r = np.sqrt((self.area_px or 50.0) / np.pi)
                gate = gate_px if gate_px is not None else 3.0 * r + 10.0
                opts = [o for o in opts if np.hypot(*(o[1] - predicted[i])) < gate]
            options.append(opts[:4] + [None])
        best, best_cost = None, np.inf
        for combo in itertools.product(*options):
            used = [(self.class_of[i], o[0]) for i, o in enumerate(combo) if o is not None]
            if len(used) != len(set(used)):
                continue
            cost = self._cost(combo, predicted)
            if cost < best_cost:
                best, best_cost = combo, cost
        return [(None, 0.0) if o is None else (o[1], o[2]) for o in best]

    def _cost(self, combo, predicted) -> float:
        n_missing = sum(o is None for o in combo)
        cost = 1e3 * n_missing
        found = [i for i, o in enumerate(combo) if o is not None]
        if predicted is not None:
            for i in found:
                if np.isfinite(predicted[i]).all():
                    cost += float(np.hypot(*(combo[i][1] - predicted[i])))
        if len(found) >= 2:
            # Layout consistency: image distances proportional to the rig's distances.
            ratios = []
            for a, b in itertools.combinations(found, 2):
                d_img = np.hypot(*(combo[a][1] - combo[b][1]))
                d_rig = np.hypot(*(self.layout_m[a] - self.layout_m[b]))
                ratios.append(d_img / d_rig)
            ratios = np.array(ratios)
            if len(found) >= 3:
                # Handedness: seen from above with the image's y down, the image is a
                # mirror of the (right-handed) rock frame; a swapped pair of same-coloured
                # markers fits a rotation+scale only with a reflection.
                from .parallax import similarity_fit

                pts = np.array([combo[i][1] for i in found]) * (1.0, -1.0)
                lay = self.layout_m[found]
                _, _, sc, rms = similarity_fit(lay, pts)
                cost += 100.0 * rms / max(sc * np.sqrt(np.mean(np.sum(
                    (lay - lay.mean(0)) ** 2, axis=1))), 1e-9)
            spread = float(np.std(ratios) / max(np.mean(ratios), 1e-9)) if len(ratios) > 1 else 0
            # Blobs of one rock: similar sizes and a consistent scale.
            areas = np.array([combo[i][2] for i in found])
            cost += 100.0 * spread + 10.0 * float(np.log(areas.max() / areas.min()))
            if predicted is None:
                cost -= 1e-3 * areas.sum()
        return cost

    # --- sub-pixel -----------------------------------------------------------------------
    def _refine(self, image_bgr, lab, offset, c_xy, c_area, i, check_class=False):
        """Coverage-weighted centroid around a blob; (xy, sigma, area, contrast) or None.

        ``check_class``: also None unless the blob's core colour passes the
        classification rule of :meth:`_class_masks` for marker ``i``.
        """
        H, W = image_bgr.shape[:2]
        r = max(1.5, math.sqrt(c_area / math.pi))
        R_in, R_out = _WIN[0] * r + _WIN[1], 2.4 * r + 3.0
        cx, cy = float(c_xy[0]), float(c_xy[1])
        if min(cx, cy, W - 1 - cx, H - 1 - cy) < R_in:
            return None  # cut by the image border: its centroid would be biased
        xa, xb = max(0, math.floor(cx - R_out)), min(W, math.ceil(cx + R_out) + 1)
        ya, yb = max(0, math.floor(cy - R_out)), min(H, math.ceil(cy + R_out) + 1)
        if xb - xa < 3 or yb - ya < 3:
            return None
        win = image_bgr[ya:yb, xa:xb, ::-1].astype(np.float32)  # RGB
        x = np.arange(xa, xb, dtype=float)
        y = np.arange(ya, yb, dtype=float)
        # squared distances from the centre, (h, w), from the separable parts
        rad2 = ((y - cy) ** 2)[:, None] + ((x - cx) ** 2)[None, :]
        ring = (rad2 > R_in * R_in) & (rad2 <= R_out * R_out)
        core = rad2 <= 0.36 * r * r
        if np.count_nonzero(ring) < 8 or not core.any():
            return None
        win_ring = win[ring].T  # (3, n): each channel contiguous for the medians
        bg = median(win_ring, axis=1)
        col = median(win[core].T, axis=1)
        d = col - bg
        dd = float(d @ d)
        if dd < 25.0:  # < 5 grey levels apart: no usable contrast
            return None
        noise = float(robust_sigma(win_ring, centre=bg[:, None], axis=1).mean())
        # Project on the marker colour's chroma (d without its grey component) when it
        # has one: then shading of a neutral background (a cup ring, a light gradient on
        # grey granite or white ice) does not leak into the coverage and bias the centroid.
        d_c = d - d.mean()
        chroma = float(d_c @ d_c) > 0.25 * dd
        proj = d_c if chroma else d
        den = float(proj @ d)
        # One product gives, per pixel, the coverage s = diff.proj / den and the part of
        # diff off the background -> marker segment, P (diff - s d), P dropping the grey
        # component when projecting on the chroma (P (I - proj d^T / den) = P - proj d_c^T / den).
        L = np.empty((3, 4), np.float32)
        L[:, :3] = (_CHROMA_P if chroma else np.eye(3)) - np.outer(proj, d_c if chroma else d) / den
        L[:, 3] = proj / den
        sr = (win - bg).reshape(-1, 3) @ L
        perp2 = np.einsum("ij,ij->i", sr[:, :3], sr[:, :3]).reshape(rad2.shape)
        s = sr[:, 3].reshape(rad2.shape)
        cover = (np.clip((s - _FLOOR) / (1 - _FLOOR), 0.0, 1.0)
                 * (perp2 < (0.35 * math.sqrt(dd) + 2 * noise) ** 2))
        inside = rad2 <= R_in * R_in
        for _ in range(2):
            wgt = cover * inside
            wx, wy = wgt.sum(axis=0, dtype=float), wgt.sum(axis=1, dtype=float)
            sw = float(wx.sum())
            if sw <= 0.5:
                return None
            cx, cy = float(wx @ x) / sw, float(wy @ y) / sw
            rad2 = ((y - cy) ** 2)[:, None] + ((x - cx) ** 2)[None, :]
            inside = rad2 <= R_in * R_in
        sigma_w = max(noise, 0.5) * math.sqrt(float(proj @ proj)) / den
        r2 = float(rad2[inside].sum())
        sigma = sigma_w * math.sqrt(r2 / 2.0) / sw
        obs_lab, bg_lab = lab_of_rgb(np.clip(np.stack([col, bg]), 0, 255))
        if check_class and not self._is_class(obs_lab, bg_lab, i):
            return None
        if not self._adaptable(obs_lab, bg_lab, i, _BLOB_MIN_CHROMA, _BLOB_MAX_HUE_DEG):
            # a core without the marker's chroma (a grey blob - the handle's edge, a
            # pebble - near a marker whose colour the camera shows weak) is not it
            return None
        # Adapt the colour model to what the camera shows (slowly, and only when sure).
        if self._adaptable(obs_lab, bg_lab, i):
            self.colors_lab[i] = (1 - _ADAPT) * self.colors_lab[i] + _ADAPT * obs_lab
        contrast = float(np.linalg.norm(_weigh(obs_lab) - _weigh(bg_lab)))
        return np.array([cx, cy]), sigma, sw, contrast


#: A frame's colour (max - min of B, G, R per pixel, every 4th pixel) whose 99th
#: percentile is under this many grey levels has none: a monochrome camera or a
#: black-and-white export, where no marker can be found by its colour
COLOURLESS_LEVELS = 6.0
#: what a colourless frame's status says (track's ok = 0 reason, doctor's advice)
NO_COLOUR = ("the image has no colour (grey pixels only, e.g. a monochrome camera or a "
             "black-and-white export): markers are found by their colour - measure the "
             "camera's colour recording")


def colourless(image) -> bool:
    """Whether a BGR frame has no colour (:data:`COLOURLESS_LEVELS`)."""
    if image.ndim < 3 or image.shape[2] < 3:
        return True
    px = image[::4, ::4].astype(np.int16)
    chroma = px.max(axis=2) - px.min(axis=2)
    return float(np.percentile(chroma, 99)) < COLOURLESS_LEVELS
