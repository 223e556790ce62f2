"""Calibrate the thread grid on one frame: lattice, lens distortion, homography.

Lattice frame (the reference for position and angle): metres on the ice plane, axes
along the two thread families, right-handed seen from above (x, y, up).  ``x`` grows
across the threads that run along ``y`` (spacing ``rig.spacing_x_m``).  When the two
spacings are equal, ``+y`` is the family closest to the image's up direction in the
calibration frame.  Origin: a thread crossing near the image centre; with rig colours,
one whose two threads both have the first colour (thread ``i`` of a family has colour
``colors[(sign * i) % n]``, ``sign`` = ``Calibration.color_signs``: which way the rig's
colour order runs is learnt from the frame).

The homographies map to the plane of the threads.  With ``[grid].depth_m`` > 0 that plane
lies ``depth_m / 1.31`` (refraction by the ice) below the surface, so a point on the
surface is seen as if (H + depth_m / 1.31) / H further from the nadir; the parallax
correction of the rock (tracking) accounts for the marker plane the same way.

Steps: thread response (matched colour filter, :mod:`.response`) -> two periodic
families from the spectrum and the autocorrelation (:func:`.lattice.initial_lattice`,
paired by the rig's cell ratio) -> robust fit of the lattice homography to every thread
pixel with k1, k2 and the distortion centre, growing from the image centre
(:func:`.lattice.fit_lattice`) -> axes, colours, origin (:func:`_to_metric`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import TrackingError
from .lattice import (LENS_PARAMS, MIN_PERIOD_PX, assign_families, centre_jacobian,
                      fit_lattice, initial_lattice, per_line_offsets, periods_px)
from .lens import apply_h, camera_matrix, corners_px, distort, fold_radius, undistort
from .response import ColourModel, candidate_pixels, local_contrast, thread_response


def image_yaw_deg(H, K, dist, pt_px=None):
    """Direction (deg, CCW from the lattice's +x) of the image's +u axis at ``pt_px``
    (observed px; default the principal point), through the image -> ice homography
    ``H`` (undistorted px -> m) and the lens ``K``, ``dist``.  A stack of homographies
    (..., 3, 3) gives one direction each (an array)."""
    c = K[:2, 2] if pt_px is None else np.asarray(pt_px, float)
    ends = np.c_[undistort(np.array([c, c + (20.0, 0.0)]), K, dist), np.ones(2)]
    a, b = np.moveaxis(np.einsum("...ij,kj->...ki", np.asarray(H, float), ends), -2, 0)
    d = b[..., :2] / b[..., 2:] - a[..., :2] / a[..., 2:]
    yaw = np.degrees(np.arctan2(d[..., 1], d[..., 0]))
    return float(yaw) if yaw.ndim == 0 else yaw


def lattice_turn_deg(yaw_from_deg, yaw_to_deg):
    """Turn (deg) between two yaws modulo the lattice's 90 deg symmetry (a square
    lattice looks the same turned by a quarter): in [-45, 45)."""
    return (np.asarray(yaw_to_deg) - yaw_from_deg + 45.0) % 90.0 - 45.0


class PlaneMap:
    """Mixin: image <-> ice plane through ``self.H`` (undistorted px -> m), ``K``, ``dist``."""

    def image_to_ice(self, pts_px) -> np.ndarray:
        """Observed pixel coordinates (N, 2) -> ice-plane lattice-frame metres (N, 2)."""
        p = np.atleast_2d(np.asarray(pts_px, float))
        return apply_h(self.H, undistort(p, self.K, self.dist))

    def ice_to_image(self, pts_m) -> np.ndarray:
        """Ice-plane lattice-frame metres (N, 2) -> observed pixel coordinates (N, 2)."""
        p = np.atleast_2d(np.asarray(pts_m, float))
        return distort(apply_h(np.linalg.inv(self.H), p), self.K, self.dist)

    def yaw_deg(self, pt_px=None) -> float:
        """Direction (deg, CCW from the lattice's +x) of the image's +u axis at an image
        point (default the principal point): the camera's turn against the grid."""
        return image_yaw_deg(self.H, self.K, self.dist, pt_px)

    def metres_per_px(self, pt_px=None) -> float:
        """Local scale (m/px) of the ice plane at an image point (default the centre)."""
        c = self.K[:2, 2] if pt_px is None else np.asarray(pt_px, float)
        return pixel_scale(self.image_to_ice(pixel_steps(c)))


def pixel_steps(pt_px) -> np.ndarray:
    """A point and its neighbours one pixel along +u and +v, (3, 2) px."""
    return np.asarray(pt_px, float) + np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])


def pixel_scale(steps_m) -> float:
    """Local scale (m/px) from :func:`pixel_steps` mapped to the ice: sqrt of the area
    (m^2) of one pixel."""
    (x0, y0), (x1, y1), (x2, y2) = np.asarray(steps_m, float)
    return float(np.sqrt(abs((x1 - x0) * (y2 - y0) - (y1 - y0) * (x2 - x0))))


@dataclass
class Calibration(PlaneMap):
    """The grid found on one frame.

    Attributes
    ----------
    width, height : int
        Image size (px).
    K : (3, 3) ndarray
        Camera matrix; ``f`` is a reference scale (max(w, h)) unless known, the principal
        point is the image centre (see :mod:`curltrack.calib.lens`).
    dist : tuple
        OpenCV distortion ``(k1, k2, 0, 0, 0)`` relative to ``K``.
    H : (3, 3) ndarray
        Undistorted px -> lattice-frame metres on this frame.
    spacing_x_m, spacing_y_m : float
        Thread spacings (m).
    spacing_px : float
        Mean thread spacing at the image centre (px).
    n_threads : (int, int)
        Threads fitted (x family, y family).
    residual_px : float
        RMS offset of the individual threads from the fitted lattice (px).
    colour_model : ColourModel
    colors_resolved : bool
        Whether the thread colour sequence was identified (fixes the cell index modulo
        the number of colours).
    n_colors : int
    color_signs : (int, int)
        Direction of the colour sequence along +x and +y of the lattice frame: thread
        ``i`` has colour ``(sign * i) mod n_colors``.
    thread_width_px : float
        Weighted RMS width of thread pixels about their line (px).
    camera_height_m : float or None
        Not derivable from one frame without a known focal length: None, with a note.
    notes : list of str
    lens_radius_px : float or None
        Distance from the principal point (observed px) within which the threads confirm
        the lens model (:func:`checked_lens_radius`); None = the whole image.
    """

    width: int
    height: int
    K: np.ndarray
    dist: tuple
    H: np.ndarray
    spacing_x_m: float
    spacing_y_m: float
    spacing_px: float
    n_threads: tuple
    residual_px: float
    colour_model: ColourModel
    colors_resolved: bool = False
    n_colors: int = 0
    color_signs: tuple = (1, 1)
    thread_width_px: float = 1.0
    camera_height_m: float | None = None
    notes: list = field(default_factory=list)
    lens_radius_px: float | None = None

    def in_checked_lens(self, pts_px) -> np.ndarray:
        """Whether observed pixels (N, 2) lie where the lens model is confirmed."""
        return within_radius(pts_px, self.K, self.lens_radius_px)

    def to_dict(self) -> dict:
        """JSON-ready dict (CALIB.json)."""
        return {
            "image_width": self.width, "image_height": self.height,
            "camera_matrix": self.K.tolist(), "dist_coeffs": list(self.dist),
            "k1": self.dist[0], "k2": self.dist[1],
            "homography_image_to_ice": self.H.tolist(),
            "homography_note": "undistorted px -> lattice-frame metres on the ice plane",
            "spacing_x_m": self.spacing_x_m, "spacing_y_m": self.spacing_y_m,
            "spacing_px": self.spacing_px, "n_threads": list(self.n_threads),
            "residual_px": self.residual_px, "thread_width_px": self.thread_width_px,
            "colour_model": self.colour_model.to_dict(),
            "colors_resolved": self.colors_resolved, "n_colors": self.n_colors,
            "color_signs": list(self.color_signs),
            "camera_height_m": self.camera_height_m, "notes": list(self.notes),
            "lattice_y_axis_deg": self.y_axis_deg(),
            "lens_radius_px": self.lens_radius_px,
        }

    def y_axis_deg(self) -> float:
        """Direction of the lattice's +y axis in the image at the principal point (deg,
        counter-clockwise from the image's up direction)."""
        c = self.K[:2, 2]
        o, e = self.ice_to_image(self.image_to_ice(c[None]) + [[0.0, 0.0], [0.0, 0.05]])
        d = e - o
        return float(np.degrees(np.arctan2(-d[0], -d[1])))

    @classmethod
    def from_dict(cls, d) -> "Calibration":
        return cls(width=int(d["image_width"]), height=int(d["image_height"]),
                   K=np.asarray(d["camera_matrix"], float), dist=tuple(d["dist_coeffs"]),
                   H=np.asarray(d["homography_image_to_ice"], float),
                   spacing_x_m=float(d["spacing_x_m"]), spacing_y_m=float(d["spacing_y_m"]),
                   spacing_px=float(d["spacing_px"]), n_threads=tuple(d["n_threads"]),
                   residual_px=float(d["residual_px"]),
                   colour_model=ColourModel.from_dict(d["colour_model"]),
                   colors_resolved=bool(d.get("colors_resolved", False)),
                   n_colors=int(d.get("n_colors", 0)),
                   color_signs=tuple(int(v) for v in d.get("color_signs", (1, 1))),
                   thread_width_px=float(d.get("thread_width_px", 1.0)),
                   camera_height_m=d.get("camera_height_m"), notes=list(d.get("notes", [])),
                   lens_radius_px=d.get("lens_radius_px"))


def normaliser(K) -> np.ndarray:
    """N with q = N p: pixel -> normalised coordinates ``(p - c) / f``."""
    f, c = K[0, 0], K[:2, 2]
    return np.array([[1 / f, 0, -c[0] / f], [0, 1 / f, -c[1] / f], [0, 0, 1.0]])


def cells_from_metric(H, K, spacing_x_m, spacing_y_m) -> np.ndarray:
    """Undistorted px -> metres homography  ->  normalised coords -> cells homography."""
    # (the normaliser's inverse is K itself: K = [[f, 0, cx], [0, f, cy], [0, 0, 1]])
    Hc = (H @ K) * np.array([[1 / spacing_x_m], [1 / spacing_y_m], [1.0]])
    return Hc / Hc[2, 2]


def metric_from_cells(Hc, K, spacing_x_m, spacing_y_m) -> np.ndarray:
    """Inverse of :func:`cells_from_metric`."""
    H = (Hc @ normaliser(K)) * np.array([[spacing_x_m], [spacing_y_m], [1.0]])
    return H / H[2, 2]


def _rig_colours(rig):
    from ..rig import parse_color

    return [parse_color(c) for c in rig.grid_colors]


def line_colours(contrast, xs, ab, fam, idx, col, model: ColourModel):
    """Best-matching rig colour index of each thread: {index: colour index}."""
    if model.directions is None or not fam.any():
        return {}
    xi = xs[fam].astype(int)
    vec = contrast[xi[:, 1], xi[:, 0]]  # (n, 3) contrast of the thread pixels
    score = vec @ model.directions.T  # (n, k)
    ids, inv = np.unique(idx[fam], return_inverse=True)
    out = {}
    for j, i in enumerate(ids):
        s = score[inv == j].sum(axis=0)
        out[int(i)] = int(np.argmax(s))
    return out


def colour_phase(colours: dict, n: int, sign: int | None = None):
    """Phase and direction of the colour sequence over a family's threads.

    Thread ``i`` has colour ``(sign * (i - p)) mod n``: the rig lists the colours in the
    order they repeat, but which way the lattice index runs is not known in advance.

    Returns
    -------
    p, agree, sign : int, float, int
        Phase, fraction of threads agreeing, direction (+1 / -1; the given one if any).
    """
    if n < 2 or len(colours) < 2:
        return 0, 0.0, 1 if sign is None else sign
    i, c = np.array(list(colours)), np.array(list(colours.values()))
    best = (-1.0, 0, 1)
    for sg in ((1, -1) if sign is None else (sign,)):
        for p in range(n):
            a = float(np.mean((sg * (i - p)) % n == c))
            if a > best[0] + 1e-9:
                best = (a, p, sg)
    return best[1], best[0], best[2]


def _family_coords(pts, Hc, K, dist, family: int):
    """Lattice coordinate (cells) of observed pixels ``pts`` across a family's threads,
    and whether each is clear (> 4 px) of the other family's threads."""
    f, c = K[0, 0], K[:2, 2]
    ab = apply_h(Hc, (undistort(pts, K, dist) - c) / f)
    other = ab[:, 1 - family] - np.round(ab[:, 1 - family])
    return ab[:, family], np.abs(other) * periods_px(Hc, f)[1 - family] > 4.0


def _check_period(xs, w, Hc, K, dist, family: int):
    """Thread response half-way between fitted threads of a family -> the period was 2x."""
    a, away = _family_coords(xs, Hc, K, dist, family)
    frac = a - np.floor(a)
    on = np.sum(w[away & ((frac < 0.08) | (frac > 0.92))])
    mid = np.sum(w[away & (np.abs(frac - 0.5) < 0.08)])
    return mid > 0.35 * on


#: A fitted thread "carries no thread" when its background-subtracted response per px of
#: length is below this fraction of the typical fitted thread's (:func:`_spurious_threads`).
EMPTY_THREAD_RATIO = 0.25
#: The steepest view accepted (deg from straight down), read from the shape of the
#: lattice's cells at the principal point (:func:`lattice_tilt_deg`).  Filming asks for
#: a few degrees; cells that contradict the rig's shape beyond this are not the threads
#: (a family fitted at half its period looks like a view 60 deg from straight down).
MAX_TILT_DEG = 30.0


def lattice_tilt_deg(Hc, spacings) -> float:
    """Camera tilt (deg from straight down) implied by the shape of the lattice's cells
    at the principal point: a pinhole tilted by t sees the plane stretched by 1/cos t
    along the tilt there, whatever the lens and the focal length.

    Parameters
    ----------
    Hc : (3, 3) ndarray
        Homography normalised undistorted px -> cells (families a, b).
    spacings : (float, float)
        Thread spacings (m) of families a and b.
    """
    J = centre_jacobian(np.asarray(Hc, float) / Hc[2, 2])
    s = np.linalg.svd(np.diag(spacings) @ J, compute_uv=False)
    return float(np.degrees(np.arccos(np.clip(s[1] / s[0], 0.0, 1.0))))


def _family_spacings(Hc, f, rig):
    """(spacing of family a, of family b) (m) as :func:`_to_metric` assigns them, and
    whether family a is the lattice's x."""
    pa, pb = periods_px(Hc, f)
    J = centre_jacobian(Hc)
    sx, sy = rig.spacing_x_m, rig.spacing_y_m
    if abs(sx - sy) / max(sx, sy) > 0.08:
        # Spacings differ: the family with the larger px period has the larger spacing.
        x_is_a = (pa > pb) == (sx > sy)
    else:
        # Equal spacings: y is the family whose gradient is closest to the image vertical.
        x_is_a = abs(J[1, 1]) / np.linalg.norm(J[1]) > abs(J[0, 1]) / np.linalg.norm(J[0])
    return ((sx, sy) if x_is_a else (sy, sx)), x_is_a


def _spurious_threads(xs, w, Hc, K, dist, family: int, width: int, height: int):
    """``(m, r)`` when only the fitted threads of a family with index ``r`` mod ``m``
    (m = 2, 3) carry thread response - the fit took a harmonic of the period, threads
    every m-th line - else None.

    Each fitted thread's response per px of its length in view (an image-wide pixel
    grid mapped the same way gives the length), less the response between the threads,
    is compared with the typical thread's; crossings with the other family are left out.
    """
    step = max(1, int(round(np.hypot(width, height) / 500)))
    gy, gx = np.mgrid[step / 2:height:step, step / 2:width:step]
    grid = np.column_stack([gx.ravel(), gy.ravel()])

    def per_thread(pts, weights):
        a, away = _family_coords(pts, Hc, K, dist, family)
        ok = np.isfinite(a) & away
        idx, frac = np.round(a[ok]), np.abs(a[ok] - np.round(a[ok]))
        on, between = frac < 0.08, (frac > 0.25) & (frac < 0.45)
        return idx, on, between, weights[ok]

    idx_g, on_g, bw_g, _ = per_thread(grid, np.ones(len(grid)))
    idx_c, on_c, bw_c, w_c = per_thread(xs, w)
    if len(idx_g) == 0:
        return None
    lo = int(min(idx_g.min(), idx_c.min(initial=idx_g.min())))
    n = int(max(idx_g.max(), idx_c.max(initial=idx_g.max()))) - lo + 1
    ig, ic = (idx_g - lo).astype(int), (idx_c - lo).astype(int)
    len_on = np.bincount(ig[on_g], minlength=n).astype(float)
    len_bw = np.bincount(ig[bw_g], minlength=n).astype(float)
    resp_on = np.bincount(ic[on_c], w_c[on_c], minlength=n)
    resp_bw = np.bincount(ic[bw_c], w_c[bw_c], minlength=n)
    judged = (len_on >= 0.25 * len_on.max()) & (len_bw > 0)
    if judged.sum() < 4:
        return None
    support = resp_on[judged] / len_on[judged] - resp_bw[judged] / len_bw[judged]
    index = np.arange(lo, lo + n)[judged]
    for m in (2, 3):
        for r in range(m):
            cls = index % m == r
            if cls.sum() < 2 or cls.all():
                continue
            typical = np.median(support[cls])
            if typical > 0 and support[~cls].max() < EMPTY_THREAD_RATIO * typical:
                return m, r
    return None


#: Thread pixels (at most) of the calibration frame: a seeded subsample when there are
#: more, as in a sharp 1080p frame.  The subsample's own scatter sets how well k2 and the
#: distortion centre extrapolate into the image corners: 50k of a 960x540 frame's 180k
#: gave up to 0.84 px at a corner of a strong lens (k1 -0.39 in the reference focal
#: length; k2 0.041 for 0.035) that all of them put at 0.14 px - over 65 random action
#: cameras the worst error over the view fell from 0.26 to 0.12 px (mean 0.10 -> 0.03),
#: for about 0.6 s more once per clip.
CALIBRATION_PIXELS = 200_000
#: Thread pixels used by the region-growing stages of the calibration (the last stage
#: uses all of them).
COARSE_PIXELS = 25_000
#: Region-growing schedules of the lens fit, tried in turn: radii (fractions of the
#: half-diagonal), the lens parameters free while growing, and from which fraction of
#: the radius on.  Wide-angle first: steps of 0.1, k1 free from 0.3, k2 and the centre
#: from 0.5 - with steps of 0.2 and only k1 free beyond 0.5 a wide-angle lens (k1 < -0.4
#: in the reference focal length, e.g. an action camera's k1 = -0.27, k2 = 0.04 at
#: f = 660 px on 960x540) bends the outer threads by a whole cell past the stage's
#: extrapolation and the fit lands a cell off (57 mm RMS over the view; 0.08 mm now;
#: measured on 90 random artificial frames, k1 -0.35..-0.12).  k2 and the centre wait
#: until 0.5: freed at 0.3 of a small image's radius (a 400x224 crop) k2 diverged to -38
#: and 3 frames found no grid.  The mild schedule (as before) is the fall-back where the
#: wide one fails.
LENS_SCHEDULES = (
    ((0.25, 0.35, 0.45, 0.55, 0.65, 0.75, 0.85), LENS_PARAMS,
     {"k1": 0.3, "k2": 0.5, "cx": 0.5, "cy": 0.5}),
    ((0.3, 0.5, 0.7), ("k1",), 0.5),
)
#: Lens check (:func:`checked_lens_radius`): a thread pixel within this of a fitted
#: thread is explained (px); an annulus explained less than this fraction as often as
#: the centre ends the lens's checked radius (good fits: 0.97-1.03 in every annulus;
#: a squeezed periphery 0.15); a checked radius under this fraction of the
#: half-diagonal is a calibration that failed.
COVERAGE_BAND_PX = 2.0
COVERAGE_BIN = 0.05
COVERAGE_RATIO_MIN = 0.6
LENS_RADIUS_MIN = 0.5
#: pairs of thread families tried after the strongest when its fit fails (a square
#: lattice's diagonals through the crossings can be as periodic as its threads)
LATTICE_ALTERNATIVES = 2


def calibrate_frame(image_bgr, rig, mask=None) -> Calibration:
    """Find the thread lattice on one frame.

    Parameters
    ----------
    image_bgr : (H, W, 3) uint8
    rig : Rig
        Thread spacings and (optional) colours.
    mask : (H, W) uint8, optional
        Nonzero = ignore (e.g. the rock and a broom).

    Returns
    -------
    Calibration

    Raises
    ------
    TrackingError
        "no grid found" when fewer than two periodic thread families are visible or the
        fit does not hold together.

    Examples
    --------
    >>> import cv2
    >>> from curltrack import calibrate_frame, load_rig
    >>> rig = load_rig("fixtures/rig.toml")                  # doctest: +SKIP
    >>> cal = calibrate_frame(cv2.imread("frame.png"), rig)   # doctest: +SKIP
    >>> cal.to_dict()["k1"], cal.spacing_px                   # doctest: +SKIP
    """
    img = np.asarray(image_bgr)
    if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
        raise TrackingError(f"expected a BGR uint8 image, got {img.dtype} {img.shape}")
    h, w = img.shape[:2]
    K = camera_matrix(w, h)
    f, c = K[0, 0], K[:2, 2]
    model = ColourModel.from_image(img, _rig_colours(rig), mask)
    contrast = local_contrast(img)
    resp = thread_response(img, model, contrast)
    if mask is not None:
        resp = np.where(mask == 0, resp, 0).astype(np.float32)
    xs, wt = candidate_pixels(resp, mask, max_n=CALIBRATION_PIXELS)
    if len(xs) < 200:
        raise TrackingError("no grid found: almost no thread-like pixels in the frame")
    guesses = initial_lattice(resp, xs, wt, c, rig.spacing_x_m / rig.spacing_y_m,
                              n_guesses=1 + LATTICE_ALTERNATIVES)
    if not guesses:
        raise TrackingError("no grid found: no two periodic thread families in the frame")
    first = None
    for A in guesses:   # the strongest pair of families first; the next where it fails
        Hc = np.array([[A[0, 0] * f, A[0, 1] * f, A[0, 2]],
                       [A[1, 0] * f, A[1, 1] * f, A[1, 2]], [0.0, 0.0, 1.0]])
        try:
            Hc, K_fit, dist, info, lens_radius = _fit_lens_schedules(xs, wt, Hc, K, w, h, rig)
            # (the threads' colours, origin and residual from the checked lens only)
            sel = within_radius(xs, K_fit, lens_radius)
            cal = _to_metric(img, rig, model, contrast, xs[sel], wt[sel], Hc, K_fit, dist,
                             info)
            break
        except TrackingError as exc:
            first = first or exc
    else:
        raise first
    if lens_radius is not None:
        cal.lens_radius_px = float(lens_radius)
        cal.notes.append(f"wide-angle lens (k1 = {dist[0]:.3f}, k2 = {dist[1]:.3f} at the "
                         f"reference focal length {cal.K[0, 0]:.0f} px): the "
                         f"threads confirm the lens model only within {lens_radius:.0f} px "
                         f"of the principal point; the rock is not measured beyond")
    return cal


def within_radius(pts_px, K, radius) -> np.ndarray:
    """Whether pixels (N, 2) lie within ``radius`` (px; None: anywhere) of the principal
    point of camera matrix ``K``: the checked lens (:func:`checked_lens_radius`)."""
    p = np.atleast_2d(np.asarray(pts_px, float))
    if radius is None:
        return np.ones(len(p), bool)
    return np.hypot(*(p - K[:2, 2]).T) <= radius


def _fit_lens_schedules(xs, wt, Hc, K, w, h, rig):
    """:func:`_fit_lens` with the wide-angle schedule, then the mild one (as before
    2026-11-24) where it fails; the first schedule's error when both do."""
    first = None
    for schedule in LENS_SCHEDULES:
        try:
            return _fit_lens(xs, wt, Hc, K, w, h, rig, *schedule)
        except TrackingError as exc:
            first = first or exc
    raise first


def _fit_lens(xs, wt, Hc, K, w, h, rig, growing, free, free_from):
    """Region growing from the spectrum's lattice ``Hc`` with the lens parameters
    ``free`` (from ``free_from`` of the radius on), then the final fit on every pixel
    and the lens check: (Hc, K, dist, info, checked radius), or TrackingError."""
    half_diag = np.hypot(w, h) / 2
    radii = radii0 = [v * half_diag for v in growing] + [None]
    dist, K0 = (0.0, 0.0), K
    # The region growing only has to land in the right basin: a fixed subsample of the
    # thread pixels does that at a fraction of the cost; the final fit uses them all.
    sub = np.sort(np.random.default_rng(0).permutation(len(xs))[:COARSE_PIXELS])
    for _attempt in range(3):
        Hc, K, dist, info = fit_lattice(xs[sub], wt[sub], Hc, K, dist, free=free,
                                        radii=radii, band_px=3.0, free_from=free_from)
        halved = False
        for fam in (0, 1):
            if _check_period(xs[sub], wt[sub], Hc, K, dist, fam):
                Hc[fam] *= 2.0  # the spectrum picked a sub-harmonic: threads every half cell
                halved = True
        if halved:
            radii = [0.5 * half_diag, None]
            continue
        dropped, Hc = _drop_spurious_threads(xs[sub], wt[sub], Hc, K, dist, w, h, rig)
        if not dropped:
            break
        K, dist, radii = K0, (0.0, 0.0), radii0  # the lens bent to the wrong lattice: regrow
    Hc, K, dist, info = fit_lattice(xs, wt, Hc, K, dist, free=LENS_PARAMS,
                                    radii=(None,), band_px=2.5, iterations=12)
    if not info or info["lines_a"] < 3 or info["lines_b"] < 3:
        raise TrackingError("no grid found: fewer than 3 threads in a family could be fitted")
    lens_radius = checked_lens_radius(xs, wt, Hc, K, dist, w, h)
    if lens_radius is not None:
        # the threads beyond the checked radius (squeezed together, or wrongly indexed
        # there) must not bend the fit of those within it: refit on those
        inner = within_radius(xs, K, lens_radius)
        fit = fit_lattice(xs[inner], wt[inner], Hc, K, dist, free=LENS_PARAMS,
                          radii=(None,), band_px=2.5, iterations=12)
        if fit[3] and min(fit[3]["lines_a"], fit[3]["lines_b"]) >= 3:
            Hc, K, dist, info = fit
            lens_radius = checked_lens_radius(xs, wt, Hc, K, dist, w, h)
    if lens_radius is not None and lens_radius < LENS_RADIUS_MIN * half_diag:
        raise TrackingError(
            f"no grid found: the lens could not be calibrated - the fitted radial "
            f"distortion (k1 = {dist[0]:.3f}, k2 = {dist[1]:.3f} at f = {K[0, 0]:.0f} px) "
            f"explains the threads only within {lens_radius:.0f} px of the image centre "
            f"({lens_radius / half_diag:.0%} of the half-diagonal); a lens this wide (a "
            f"fisheye?) is not modelled")
    return Hc, K, dist, info, lens_radius


def _drop_spurious_threads(xs, wt, Hc, K, dist, w, h, rig):
    """(True, corrected Hc) when a family was fitted at a harmonic of its period
    (:func:`_spurious_threads`) and taking its every m-th line as the threads brings
    the cells' shape clearly closer to the rig's; else (False, Hc).  A thread colour
    much weaker than the other also leaves every second line empty: doubling a right
    period stretches the cells 2:1, and doubling both families' keeps their shape - a
    lattice whose shape agrees with the rig is left as it is."""
    f = K[0, 0]
    new = Hc.copy()
    for fam in (0, 1):
        found = _spurious_threads(xs, wt, Hc, K, dist, fam, w, h)
        if found is not None:
            m, r = found
            new[fam] = (Hc[fam] - r * Hc[2]) / m  # line r + m i of the fit -> thread i
    if np.array_equal(new, Hc):
        return False, Hc
    before = lattice_tilt_deg(Hc, _family_spacings(Hc, f, rig)[0])
    after = lattice_tilt_deg(new, _family_spacings(new, f, rig)[0])
    if after > before - 2.0:
        return False, Hc
    return True, new


def checked_lens_radius(xs, wt, Hc, K, dist, width: int, height: int):
    """Radius (px, from the principal point) within which the fitted lattice and lens
    explain the thread pixels; None when they do over the whole image.

    In annuli of :data:`COVERAGE_BIN` of the half-diagonal, the weighted fraction of the
    candidate thread pixels ``xs`` (weights ``wt``) that lie within
    :data:`COVERAGE_BAND_PX` of a fitted thread is compared with the central disc's
    (inside 40 % of the half-diagonal).  A lens model that does not hold (a fit in a
    wrong basin, or threads squeezed below the resolution in a strong wide-angle
    lens's periphery) leaves an outer annulus's pixels between the fitted threads; the
    radius ends at the first annulus below :data:`COVERAGE_RATIO_MIN` of the centre's,
    or where the lens squeezes the threads radially below :data:`.lattice.MIN_PERIOD_PX`
    apart (at the latest at its fold, :func:`.lens.fold_radius`) if that is nearer.
    """
    f, c = K[0, 0], K[:2, 2]
    ab = apply_h(Hc, (undistort(xs, K, dist) - c) / f)
    pa, pb = periods_px(Hc, f)
    off = np.minimum(np.abs(ab[:, 0] - np.round(ab[:, 0])) * pa,
                     np.abs(ab[:, 1] - np.round(ab[:, 1])) * pb)
    on = off < COVERAGE_BAND_PX
    half_diag = np.hypot(width, height) / 2
    rr = np.hypot(*(xs - c).T) / half_diag
    centre = rr < 0.4
    ref = np.sum(wt[centre & on]) / max(np.sum(wt[centre]), 1e-12)
    edges = np.arange(0.4, rr.max() + COVERAGE_BIN, COVERAGE_BIN)
    k = np.clip(np.searchsorted(edges, rr, side="right") - 1, -1, len(edges) - 1)
    total = np.bincount(k[~centre], wt[~centre], minlength=len(edges))
    hit = np.bincount(k[~centre & on], wt[~centre & on], minlength=len(edges))
    limit = None
    for i in range(len(edges)):
        # (an annulus with little evidence - mostly outside the image - is not judged)
        if total[i] > 0.005 * wt.sum() and hit[i] < COVERAGE_RATIO_MIN * ref * total[i]:
            limit = edges[i] * half_diag
            break
    # where the lens squeezes the threads radially closer than the shortest spacing
    # looked for (or folds over), they no longer check it: r_d'(r) < MIN_PERIOD / period
    k1, k2 = dist[:2]
    r = np.linspace(0.0, fold_radius(k1, k2), 2001)
    squeeze = 1.0 + r * r * (3.0 * k1 + 5.0 * k2 * r * r)
    low = squeeze < MIN_PERIOD_PX / min(pa, pb)
    if low.any():
        r0 = r[np.argmax(low)]
        rd0 = f * r0 * (1.0 + r0 * r0 * (k1 + k2 * r0 * r0))
        if rd0 < np.hypot(*(corners_px(width, height) - c).T).max():
            limit = min(limit if limit is not None else np.inf, float(rd0))
    return limit


def _to_metric(img, rig, model, contrast, xs, wt, Hc, K, dist, info) -> Calibration:
    """Choose the lattice axes, signs and origin; express the homography in metres."""
    h, w = img.shape[:2]
    f, c = K[0, 0], K[:2, 2]
    J = centre_jacobian(Hc)  # d(a, b)/dq at the centre
    sx, sy = rig.spacing_x_m, rig.spacing_y_m
    notes = []
    spacings, x_is_a = _family_spacings(Hc, f, rig)
    tilt = lattice_tilt_deg(Hc, spacings)
    if tilt > MAX_TILT_DEG:
        raise TrackingError(
            f"no grid found: the lattice fitted has cells of another shape than the rig's "
            f"({sx:g} x {sy:g} m) - as from a camera {tilt:.0f} deg from straight down "
            f"(a few degrees expected): probably not the threads' own spacing (a harmonic, "
            f"with few cells in view?)")
    P = np.eye(3) if x_is_a else np.array([[0.0, 1, 0], [1, 0, 0], [0, 0, 1]])
    Hc = P @ Hc
    J = P[:2, :2] @ J
    # +y grows towards the image's up (-y_img); then x by right-handedness
    sgn_y = -1.0 if J[1, 1] > 0 else 1.0
    Jy = sgn_y * J[1]
    sgn_x = 1.0 if (J[0, 0] * Jy[1] - J[0, 1] * Jy[0]) < 0 else -1.0
    Hc = np.diag([sgn_x, sgn_y, 1.0]) @ Hc
    # Colours of the threads and the origin crossing.
    q = (undistort(xs, K, dist) - c) / f
    ab = apply_h(Hc, q)
    lines = per_line_offsets(xs, wt, Hc, K, dist)
    pa, pb = periods_px(Hc, f)
    fam_a, fam_b, ia, ib = assign_families(ab[:, 0], ab[:, 1], pa, pb, 2.5, 3.5)
    if model.directions is None:
        # No rig colours: learn the threads' contrast against the ice from the fitted
        # threads (a signed matched filter then, as with colours, for tracking)
        on = fam_a | fam_b
        xi = xs[on].astype(int)
        v = (contrast[xi[:, 1], xi[:, 0]] * wt[on, None]).sum(axis=0)
        if np.linalg.norm(v) > 0:
            model = ColourModel(model.ice_bgr, (v / np.linalg.norm(v))[None, :])
            notes.append("no thread colours in the rig: thread contrast learnt from the "
                         "frame; cell index from the motion only")
    n = len(rig.grid_colors)
    resolved = False
    signs = (1, 1)
    ab0 = apply_h(Hc, np.zeros((1, 2)))[0]
    shift = np.round(ab0)
    if model.directions is not None and n >= 2:
        ca = line_colours(contrast, xs, ab, fam_a, ia, 0, model)
        cb = line_colours(contrast, xs, ab, fam_b, ib, 1, model)
        (p_a, agree_a, s_a), (p_b, agree_b, s_b) = colour_phase(ca, n), colour_phase(cb, n)
        signs = (s_a, s_b)
        resolved = min(agree_a, agree_b) >= 0.8 and min(len(ca), len(cb)) >= n + 1
        if resolved:
            # origin index congruent to the phase, nearest the image centre
            shift = np.array([p_a + n * np.round((ab0[0] - p_a) / n),
                              p_b + n * np.round((ab0[1] - p_b) / n)])
        else:
            notes.append(f"thread colour sequence not identified (agreement "
                         f"{agree_a:.2f}, {agree_b:.2f}): cell index modulo {n} from motion only")
    D = np.array([[sx, 0.0, -sx * shift[0]], [0.0, sy, -sy * shift[1]], [0.0, 0.0, 1.0]])
    N = np.array([[1 / f, 0, -c[0] / f], [0, 1 / f, -c[1] / f], [0, 0, 1.0]])
    H = D @ Hc @ N
    H /= H[2, 2]
    notes.append("camera_height_m: not derivable from the grid alone (focal length unknown); "
                 "track estimates it from the marker layout")
    return Calibration(
        width=w, height=h, K=K, dist=(float(dist[0]), float(dist[1]), 0.0, 0.0, 0.0), H=H,
        spacing_x_m=sx, spacing_y_m=sy, spacing_px=float(np.sqrt(pa * pb)),
        n_threads=(info["lines_a"], info["lines_b"]) if x_is_a else (info["lines_b"],
                                                                      info["lines_a"]),
        residual_px=lines["rms_px"], colour_model=model, colors_resolved=bool(resolved),
        n_colors=n, color_signs=tuple(int(v) for v in signs),
        thread_width_px=float(info["rms_px"]), notes=notes)
