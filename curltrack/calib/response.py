"""Thread response: how much each pixel looks like a fine coloured thread.

A thread of colour ``c`` covering a fraction ``alpha`` of a pixel of ice ``b`` shifts the
pixel by ``alpha (c - b)``.  With the rig's colours the response is the largest
projection of (pixel - local background) on the unit vectors ``(c - b) / |c - b|``
(a matched colour filter, insensitive to ice shading); without colours it is the length
of (pixel - local background).  Negative projections are clipped to zero.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._stats import robust_sigma
BG_SIGMA_PX = 3.0  # local background scale; threads are a few px wide at most


@dataclass(frozen=True)
class ColourModel:
    """Contrast directions of the thread colours against the ice (BGR unit vectors).

    Attributes
    ----------
    ice_bgr : (3,) float
        Typical ice colour.
    directions : (k, 3) float or None
        One unit vector per rig colour (in the rig's order); None = colour-agnostic.
    """

    ice_bgr: np.ndarray
    directions: np.ndarray | None

    @classmethod
    def from_image(cls, image_bgr, colors_rgb=(), mask=None) -> "ColourModel":
        """Estimate the ice colour from an image and build the contrast directions."""
        sub = image_bgr[::4, ::4].reshape(-1, 3).astype(float)
        if mask is not None:
            keep = mask[::4, ::4].ravel() == 0
            if keep.sum() > 100:
                sub = sub[keep]
        ice = np.median(sub, axis=0)
        if not colors_rgb:
            return cls(ice, None)
        dirs = []
        for rgb in colors_rgb:
            d = np.asarray(rgb[::-1], float) - ice
            n = np.linalg.norm(d)
            dirs.append(d / n if n > 1e-6 else np.zeros(3))
        return cls(ice, np.array(dirs))

    def to_dict(self) -> dict:
        return {"ice_bgr": self.ice_bgr.tolist(),
                "directions": None if self.directions is None else self.directions.tolist()}

    @classmethod
    def from_dict(cls, d) -> "ColourModel":
        dirs = d.get("directions")
        return cls(np.asarray(d["ice_bgr"], float), None if dirs is None else np.asarray(dirs))


def local_contrast(image_bgr, sigma_px: float = BG_SIGMA_PX) -> np.ndarray:
    """Pixel minus its local background (float32, H x W x 3)."""
    import cv2

    img = image_bgr.astype(np.float32)
    return img - cv2.GaussianBlur(img, (0, 0), sigma_px)


def thread_response(image_bgr, model: ColourModel, contrast=None) -> np.ndarray:
    """Per-pixel thread response (float32, H x W, >= 0, grey levels)."""
    import cv2

    diff = local_contrast(image_bgr) if contrast is None else contrast
    if model.directions is None:
        return cv2.magnitude(cv2.magnitude(diff[:, :, 0], diff[:, :, 1]), diff[:, :, 2])
    proj = cv2.transform(diff, model.directions.astype(np.float32))
    if proj.ndim == 2:
        return np.maximum(proj, 0.0)
    # (numpy's max over a short last axis is slow; reduce channel by channel)
    return np.maximum(np.maximum.reduce([proj[:, :, i] for i in range(proj.shape[2])]), 0.0)


def noise_threshold(resp, mask=None, n_sigma: float = 3.0) -> float:
    """A response level that noise rarely reaches: median + n_sigma x robust sigma."""
    sub = resp[::3, ::3]
    if mask is not None:
        sub = sub[mask[::3, ::3] == 0]
    med = float(np.median(sub))
    mad = robust_sigma(sub, centre=med)
    return med + n_sigma * max(mad, 0.5)


def candidate_pixels(resp, mask=None, thr=None, max_n: int = 120_000, seed: int = 0):
    """Pixels above the noise threshold: (N, 2) float coords (x, y) and weights (N,).

    Weights are the response above the threshold.  At most ``max_n`` pixels are kept
    (a fixed, seeded subsample) so the cost per frame is bounded.
    """
    if thr is None:
        thr = noise_threshold(resp, mask)
    good = resp > thr
    if mask is not None:
        good &= mask == 0
    ys, xs = np.nonzero(good)
    w = resp[ys, xs] - thr
    if len(xs) > max_n:
        sel = np.random.default_rng(seed).choice(len(xs), max_n, replace=False)
        xs, ys, w = xs[sel], ys[sel], w[sel]
    return np.column_stack([xs, ys]).astype(float), w.astype(float)
