"""The per-frame loop: video -> grid pose + markers -> rock centre and angle -> Series.

Data flow (one way, streamed; only small per-frame records are kept)::

    iter_frames -> MarkerDetector (rock in the image) -> GridTracker (rock masked; its
      prediction anchored on the markers' smooth motion on the ice)
      -> markers on the ice (lattice frame) -> similarity fit: apparent centre, angle,
         layout scale -> [after the loop] parallax (camera height, nadir)
      -> shot frame -> stops -> Series (SHOT.csv columns + sidecar)

The tracker never reads renderer truth: everything comes from the pixels and the rig.
"""

from __future__ import annotations

from dataclasses import dataclass, field as dc_field, replace

import numpy as np

from ..errors import CurltrackError, TrackingError
from ..rig import Rig
from .markers import NO_COLOUR, MarkerDetector, colourless
from .outline import outline_radius
from .parallax import mirrored_layout, similarity_fit
from .shutter import to_one_instant

__all__ = ["track_video", "FrameRecord"]

#: Full-frame marker search: every frame until the markers are first found and for the
#: first ``FULL_SEARCH_FRAMES`` frames of a loss (as ``doctor`` looks at any frame), then
#: every ``SEARCH_EVERY``-th frame while the loss lasts (a rock that left the view).
SEARCH_EVERY = 5
FULL_SEARCH_FRAMES = 15
#: Largest factor by which the markers' spread in the image may change from one kept
#: frame to the next (a zoom, the rock crossing a wide-angle view change it by a few
#: per cent per frame at most).
LAYOUT_JUMP = 1.25
# Thresholds (frames without markers before giving up, the blank-frame level, the
# anchor's longest gap) are the rig's TrackingSettings (curltrack.settings).

#: The status of a frame that shows nothing (grey std below ``blank_std``: black, or a
#: flat fade-in).  Leading blank frames are skipped (t = 0 at the first real one).
BLANK = "blank frame (no image content)"
#: The status of a frame that repeats the one before (:class:`_FrozenCheck`).
FROZEN = "frozen frame (the image of the frame before again: a dropped frame repeated)"
#: A frame is frozen when its grey levels (1/4 size) differ from the previous frame's by
#: less than ``FROZEN_RATIO`` x the median change of the last ``FROZEN_HISTORY`` frames,
#: and that change is over ``FROZEN_MIN_CHANGE`` (mean absolute grey levels).  Rendered
#: and real clips change by 3-6 levels a frame (noise, camera, rock); a repeated frame
#: re-encoded by 0.05-0.07 (CI seed 1539124920).  A video that does not change at all
#: (no noise, nothing moving) is never judged: a repeat is harmless there.
FROZEN_RATIO = 0.1
FROZEN_MIN_CHANGE = 0.5
FROZEN_HISTORY = 5
#: The rock's outline (~1 ms a frame) is measured on about this many frames of a shot.
OUTLINE_FRAMES = 40
#: Before the grid is calibrated, with only some markers found (the others too faint
#: for the rig's colours: :meth:`MarkerDetector.find_missing` needs the grid's scale),
#: a calibration that fails on the whole frame is tried again without discs of this
#: fraction of the image's short side around the found markers.  Unmasked, the rock's
#: dark rim and handle - a large part of the image's centre at 640x360 - can outweigh
#: faint threads there (a rendered 640x360 handheld clip at 0.57 Mbit/s: no lattice
#: found in its first 28 frames, found in every one with the rock masked).  A quarter
#: of the short side covers the rock's far edge from any marker (<= 0.25 m on the
#: ice) while the view spans at least a metre across it.
PARTIAL_MASK_FRACTION = 0.25


#: A field is measured on an image of twice its lines (:func:`curltrack.video.field_image`):
#: half its pixels are independent, and the interpolated half is smoother, so the noise
#: read from it and the sigmas computed from it are too small by sqrt(2) (half the
#: samples) / 0.905 (the RMS noise of original and cubic-interpolated rows, 1 and 0.8):
#: 1.56.  (Measured before: std of theta error/sigma 1.2-1.6 on rendered interlaced
#: draws.)
FIELD_SIGMA_FACTOR = 1.56


@dataclass
class FrameRecord:
    """What one frame contributed (small; one per frame is kept)."""

    frame: int
    t: float
    status: str = ""
    field: int | None = None  # interlaced video: 0/1 = the field exposed first/second  # "" = measured, else the reason it is not
    markers_px: np.ndarray | None = None  # (M, 2) observed px
    H: np.ndarray | None = None  # undistorted px -> lattice m
    centre_app: np.ndarray | None = None  # apparent rock axis on the ice (m)
    phi: float = np.nan  # angle against the lattice (rad)
    scale: float = np.nan  # apparent layout scale H/(H-h)
    sigma_m: float = np.nan  # 1 sigma of one marker on the ice (m)
    grid_sigma_m: float = np.nan  # 1 sigma of the homography at the rock (m)
    grid_residual_m: float = np.nan  # thread points' RMS miss of the fitted lattice (m)
    # the lattice's local misfit at the rock: how far it moves the apparent centre (m,
    # lattice x, y) and its 1 sigma (m, x, y); applied in build_series
    misfit_m: tuple = (0.0, 0.0)
    misfit_sigma_m: tuple = (0.0, 0.0)
    m_per_px: float = np.nan  # ice metres per image px at the rock
    spacing_px: float = np.nan
    contrast: float = np.nan
    segment: int = 0  # the grid's cell-index segment (GridPose.segment)
    outline_m: float = np.nan  # radius of the rock's outline (m, lattice; track.outline)
    mirrored: bool = False  # the markers are the rig layout's mirror image (parallax)
    notes: list = dc_field(default_factory=list)
    clicked: bool = False  # measured from a corrections file's clicks
    markers_found: tuple = ()  # per rig marker (doctor's checklist)
    pose: object = None  # the grid's GridPose here (track_frames(strict=False) only)
    grid_status: str = ""  # why the grid was not measured here ("" when it was)
    # rolling shutter, a segment's first frames: (markers on the ice, their readout
    # offsets) until the frames after give the rock's rate (_settle_shutter)
    shutter_pending: tuple | None = None


def read_lattice_at_rock(rec: FrameRecord, pose, calib, layout, q, ice, centre) -> float:
    """Set ``rec``'s lattice terms at the rock from the frame's ``pose``: the misfit
    (``misfit_m``, ``misfit_sigma_m``) and the homography's 1 sigma (``grid_sigma_m``).

    ``q`` (M + 3, 2): the markers and :func:`pixel_steps` at their centre, undistorted
    (px); ``ice`` (M, 2) the markers on the ice through ``pose.H`` (m) and ``centre``
    their similarity fit's centre.  Returns the ice metres per image pixel at the rock.
    """
    from ..calib.grid import pixel_scale
    from ..calib.lattice import misfit_at
    from ..calib.lens import apply_h

    M = len(layout)
    if pose.misfit is not None:
        # what the frame's homography misses near the rock (a rolling shutter's shear
        # under a shaking camera, the lens model's misfit), from the threads around
        # it: the centre with it taken off each marker
        spacing = np.array([calib.spacing_x_m, calib.spacing_y_m])
        d, sd = misfit_at(pose.misfit, (q[:M] - calib.K[:2, 2]) / calib.K[0, 0])
        rec.misfit_m = tuple(float(v) for v in
                             similarity_fit(layout, ice - d * spacing)[0] - centre)
        rec.misfit_sigma_m = tuple(float(v) for v in sd.mean(axis=0) * spacing)
    mpp = pixel_scale(apply_h(pose.H, q[M:]))
    # (the homography's uncertainty where the rock is, not at the image centre)
    g_px = pose.sigma_px_at((q[:M].mean(axis=0) - calib.K[:2, 2]) / calib.K[0, 0])
    rec.grid_sigma_m = (g_px if np.isfinite(g_px) else 0.3) * mpp
    return mpp


def rock_in_image(layout_m, markers_px, rock_diameter_m: float):
    """(centre px, radius px) of the rock's top in the image from its markers: the
    layout's origin (the rock's axis) under the similarity that maps the rig's layout
    (m) onto the markers (px)."""
    L, p = np.asarray(layout_m, float), np.asarray(markers_px, float)
    px_per_m = np.hypot(*(p[0] - p[1])) / np.hypot(*(L[0] - L[1]))
    c, _, _, _ = similarity_fit(L, p)
    return c, 0.5 * rock_diameter_m * px_per_m


def rock_disc(layout_m, markers_px, rock_diameter_m: float):
    """The disc hidden from the grid around the rock: ((x, y), radius) in whole px.

    The rock's side shows too under parallax: a generous margin (1.35 radii + 8 px).
    """
    (cx, cy), r = rock_in_image(layout_m, markers_px, rock_diameter_m)
    return (int(round(cx)), int(round(cy))), int(np.ceil(1.35 * r + 8))


def rigid_extrapolation(p0, p1, n: float) -> np.ndarray:
    """The points ``p1`` (M, 2) moved on by ``n`` times the rigid motion (translation
    of their centroid and rotation about it) that took ``p0`` to ``p1``.

    A rock's markers turn together: extrapolated each on its own line, they drift apart
    (the chords of their turn add up: +3 % in size after a turn of 0.24 rad, growing
    with its square), and so would the rock's predicted size and the disc masked from
    the grid around it while the rock is hidden.
    """
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    c0, c1 = p0.mean(axis=0), p1.mean(axis=0)
    z0, z1 = (p0 - c0) @ (1, 1j), (p1 - c1) @ (1, 1j)
    turn = np.angle(np.vdot(z0, z1)) if len(p1) > 1 else 0.0
    z = z1 * np.exp(1j * n * turn)
    return c1 + n * (c1 - c0) + np.column_stack([z.real, z.imag])


class _Follower:
    """Marker prediction and search window from the last measured frames."""

    def __init__(self, det: MarkerDetector, rig: Rig, per_frame: int = 1):
        self.det, self.rig = det, rig
        #: (exposure, (M, 2) px) of the last measured exposures: two of each field
        self.hist: list[tuple[int, np.ndarray]] = []
        self.per_frame = per_frame
        self.lost = 0
        self._mask = None  # reused by mask(): (array, the slice last drawn on)

    def predicted(self, frame: int):
        """The markers (px) predicted at exposure ``frame``: extrapolated from the last
        two measured - of the same field where there are two (``per_frame`` = 2: as
        :func:`_anchor`, the fields' markers differ by more than the rock's motion)."""
        if not self.hist:
            return None
        if len(self.hist) == 1:
            return self.hist[-1][1]
        hist = self.hist
        if self.per_frame > 1:
            same = [(f, p) for f, p in hist if (frame - f) % self.per_frame == 0]
            if len(same) >= 2:
                hist = same
        (f0, p0), (f1, p1) = hist[-2:]
        if abs(frame - f1) > 5:  # lost for a while: the camera follows the rock, hold still
            return p1
        # (backwards too: :class:`_LeadIn`'s exposures come in falling order)
        return rigid_extrapolation(p0, p1, (frame - f1) / (f1 - f0))

    def rock_px(self, frame: int):
        """(centre px, radius px) of the rock's top in the image, or None."""
        p = self.predicted(frame)
        if p is None:
            return None
        return rock_in_image(self.det.layout_m, p, self.rig.rock_diameter_m)

    def detect(self, image, frame):
        pred = self.predicted(frame)
        if pred is None or self.lost > 3:
            if self.hist and self.lost > FULL_SEARCH_FRAMES and self.lost % SEARCH_EVERY:
                self.lost += 1
                return None
            mf = self.det.detect(image)
            if not mf.found.all() and self.lost > 3:
                # Lost for a while: the size and colours learnt may have drifted onto
                # what hid the rock (a broom head passes for a marker of 5x the area,
                # and the real ones are then too small to be candidates): look again
                # as on the first frame - kept only when the rig's colours find more
                # markers than the learnt ones (tried again at every such search): a
                # camera whose colours are far from the rig's (a camcorder's washed-out
                # 4:1:1 chroma) is otherwise left with colours that never find its
                # markers again.
                learnt = self.det.memory()
                self.det.forget()
                again = self.det.detect(image)
                if int(again.found.sum()) > int(mf.found.sum()):
                    mf = again
                else:
                    self.det.recall(learnt)
        elif (mf := self.det.refine_at(image, pred)) is not None:
            pass  # measured where predicted: no search needed
        else:
            # Look only around the predicted markers: the gate (3 radii + 10 px) plus a
            # whole blob (the sub-pixel refinement reads the full image, not this window).
            r_mk = np.sqrt((self.det.area_px or 50.0) / np.pi)
            m = 4.5 * r_mk + 14.0
            lo, hi = pred.min(axis=0) - m, pred.max(axis=0) + m + 1
            mf = self.det.detect(image, predicted=pred, roi=(lo[0], lo[1], hi[0], hi[1]))
            if not mf.found.all():  # a jolt of the camera: retry on the whole rock
                c, r = self.rock_px(frame)
                m = 1.3 * r + 20
                mf = self.det.detect(image, predicted=pred, gate_px=r,
                                     roi=(c[0] - m, c[1] - m, c[0] + m + 1, c[1] + m + 1))
            if not mf.found.all():
                # markers fainter than the rig's colours allow (a small marker smeared at
                # a low bitrate): as marker-sized blobs of their chroma where predicted
                mf = self.det.find_missing(image, mf, predicted=pred)
        if not (mf.found.all() and self._remember(frame, mf.xy_px)):
            self.lost += 1
        return mf

    def _remember(self, frame, xy) -> bool:
        """Keep ``xy`` as the frame's markers for the predictions - unless their spread
        differs from the last kept by more than :data:`LAYOUT_JUMP`: one of them is then
        something else (a broom's head taken for a marker, CI seed 196206450), and
        extrapolated it would fling the predicted rock - and the disc masked from the
        grid around it - across the view.  After :data:`FULL_SEARCH_FRAMES` frames
        without markers the new ones are taken as they are (the camera may have zoomed).
        """
        def spread(p):  # RMS distance of the markers from their centroid (px)
            return np.sqrt(np.mean(np.sum(np.square(p - p.mean(axis=0)), axis=1)))

        xy = np.asarray(xy, float)
        if self.hist and len(xy) > 1 and self.lost <= FULL_SEARCH_FRAMES:
            if not abs(np.log(spread(xy) / spread(self.hist[-1][1]))) < np.log(LAYOUT_JUMP):
                return False
        self.hist = (self.hist + [(frame, xy.copy())])[-2 * self.per_frame:]
        self.lost = 0
        return True

    def complete(self, image, frame, mf, m_per_px: float):
        """``mf`` with the markers :meth:`detect` missed looked for where the layout puts
        them from those it found (:meth:`MarkerDetector.find_missing`; ``m_per_px``:
        ice metres per image px there) - and where predicted, when the last frames give
        a prediction: the layout's distance alone leaves the direction open (a blob on
        the far side of the rock at that distance turns the angle by tens of degrees) -
        taken as this frame's markers when complete."""
        pred = self.predicted(frame) if self.hist and self.lost <= 4 else None
        mf = self.det.find_missing(image, mf, m_per_px, predicted=pred)
        if mf.found.all():
            self._remember(frame, mf.xy_px)
        return mf

    def partial_mask(self, shape, mf):
        """uint8 mask (nonzero = ignore) of discs of :data:`PARTIAL_MASK_FRACTION` of
        the image's short side around the markers ``mf`` found, when not all were: the
        rock somewhere around them, its size in px not known without the grid."""
        import cv2

        m = np.zeros(shape[:2], np.uint8)
        rad = int(np.ceil(PARTIAL_MASK_FRACTION * min(shape[:2])))
        for x, y in mf.xy_px[mf.found]:
            cv2.circle(m, (int(round(x)), int(round(y))), rad, 255, -1)
        return m

    def mask(self, shape, frame):
        """uint8 mask (nonzero = ignore) of the rock and its surroundings for the grid.

        The same array every frame (only the last disc is cleared): valid until the
        next call.
        """
        import cv2

        if self._mask is None or self._mask[0].shape != tuple(shape[:2]):
            self._mask = (np.zeros(shape[:2], np.uint8), None)
        m, drawn = self._mask
        if drawn is not None:
            m[drawn] = 0
        p = self.predicted(frame)
        drawn = None
        if p is not None:
            (x, y), rad = rock_disc(self.det.layout_m, p, self.rig.rock_diameter_m)
            cv2.circle(m, (x, y), rad, 255, -1)
            drawn = (slice(max(y - rad, 0), max(y + rad + 1, 0)),
                     slice(max(x - rad, 0), max(x + rad + 1, 0)))
        self._mask = (m, drawn)
        return m


class _FrozenCheck:
    """Whether a frame repeats the frame before it (a dropped frame that the camera or
    the encoder filled with the previous image).  Such a frame shows an earlier instant
    than its time stamp: measured, the rock is one frame of its motion off (~70 mm at
    2 m/s) under a sigma of a millimetre, and fed to the followers it tells them that
    camera and rock stopped - the next frame's prediction is then two frames of motion
    short, which can slip the grid's cell index (CI seed 1539124920: one repeated frame,
    the index 4 cells off, 31 frames refused).  Progressive video only (the two fields
    of a frame differ in any case)."""

    def __init__(self):
        self.prev = None  # the last frame's small grey image
        self.changes: list[float] = []  # the last non-frozen frames' changes
        # the first change, judged against nothing: (its frame's key, change), until
        # the frames after it can judge it (:meth:`late_repeat`)
        self.first: tuple | None = None
        self.judged = 0  # changes measured
        self.repeats = 0  # frames found frozen

    def __call__(self, image, key=None) -> bool:
        import cv2

        g = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) if image.ndim == 3 else image
        small = cv2.resize(g, (max(g.shape[1] // 4, 1), max(g.shape[0] // 4, 1)),
                           interpolation=cv2.INTER_AREA).astype(np.float32)
        prev, self.prev = self.prev, small
        if prev is None or prev.shape != small.shape:
            return False
        change = float(cv2.absdiff(small, prev).mean())
        self.judged += 1
        if self.judged == 1:
            self.first = (key, change)
        typical = float(np.median(self.changes)) if self.changes else 0.0
        if typical > FROZEN_MIN_CHANGE and change < FROZEN_RATIO * typical:
            self.repeats += 1
            return True  # (not a change of its own: the typical one is kept)
        self.changes = (self.changes + [change])[-FROZEN_HISTORY:]
        return False

    def late_repeat(self):
        """The key of the first judged frame, once, if the frames after it show it was a
        repeat: the next frame changed (over ``FROZEN_MIN_CHANGE``, and the first by
        less than ``FROZEN_RATIO`` of that) and a repeat follows within
        ``FROZEN_HISTORY`` frames.  (Footage doubled from a lower rate - a clip exported
        at 30 fps from a 60 fps timeline - repeats every other frame; the first repeat
        had no change before it to be judged by, and stayed ok = 1, 6 mm off under a
        sigma of 0.6 mm.  A rock at rest before its release changes as little, but no
        repeat follows it.)  Else None."""
        if self.first is None or self.judged < 2:
            return None
        key, change = self.first
        nxt = self.changes[1] if len(self.changes) > 1 and self.changes[0] == change \
            else None
        if nxt is None or nxt <= FROZEN_MIN_CHANGE or change >= FROZEN_RATIO * nxt:
            self.first = None
            return None
        if self.repeats:
            self.first = None
            return key
        if self.judged > FROZEN_HISTORY:
            self.first = None
        return None


def _no_colour(records) -> str:
    """": " + why no marker can be found, when the frames have no colour, else ""."""
    return f": {NO_COLOUR}" if any(NO_COLOUR in r.status for r in records) else ""


def _anchor(markers_ice, markers_px, frame, max_gap: int, per_frame: int = 1):
    """The markers seen in ``frame`` (undistorted px) and their positions on the ice
    extrapolated from the last two measured frames (constant velocity; the rock's motion
    is smooth), for :meth:`GridTracker.update`; None without two frames measured in the
    last ``max_gap`` frames (settings' ``anchor_max_gap_frames``).

    Interlaced video (``per_frame`` = 2, ``frame`` = 2 x frame + field): from the last
    two of the same field where the history holds them.  The fields' markers differ by
    more than the rock's motion (a codec's colour mixed between them: DV's, 0.9-1.0 of
    the image's motion), and extrapolated across fields that difference alternates in
    sign and doubles: a pole camera's predicted motion swung by +-20 px from field to
    field, the grid was followed on a few whole-thread averages, sheared by 3 deg, and
    lost for 70 of 119 frames (camera sweep seed 2026113001, set-up 7).
    """
    if per_frame > 1:
        same = [(f, p) for f, p in markers_ice if (frame - f) % per_frame == 0]
        if len(same) >= 2:
            markers_ice = same
    if len(markers_ice) < 2:
        return None
    (f0, p0), (f1, p1) = markers_ice[-2:]
    if frame - f1 > max_gap:
        return None
    return markers_px, p1 + (p1 - p0) * (frame - f1) / (f1 - f0)


def blank_frame(image, settings) -> bool:
    """Whether ``image`` shows nothing: its grey levels (every 8th pixel) vary less than
    ``settings.blank_std`` (black, a flat fade-in)."""
    return float(image[::8, ::8].std()) < settings.blank_std


def _rock_rate(records, rec, max_gap_s: float = 0.2, after: bool = False):
    """The rock's velocity on the ice (m/s) and rate of turn (rad/s) from the two frames
    measured nearest before ``rec`` (or, ``after``, after it: ``records`` then starts
    after it) in its cell-index segment, or None."""
    near = []
    for r in (records if after else reversed(records[:-1])):
        if r.centre_app is None or r.segment != rec.segment:
            continue
        near.append(r)
        if len(near) == 2:
            break
    if len(near) < 2:
        return None
    a, b = near if after else near[::-1]
    dt = b.t - a.t
    if not 0 < dt <= max_gap_s or abs(rec.t - (a.t if after else b.t)) > max_gap_s:
        return None
    turn = np.angle(np.exp(1j * (b.phi - a.phi)))
    return (b.centre_app - a.centre_app) / dt, float(turn / dt)


def _settle_shutter(records, layout) -> None:
    """Move the markers of the frames measured before the rock's rate was known (a
    segment's first two) to one instant with the rate of the frames after them."""
    for i, rec in enumerate(records):
        if rec.shutter_pending is None:
            continue
        ice, dt = rec.shutter_pending
        rec.shutter_pending = None
        rate = _rock_rate(records[i + 1:], rec, after=True)
        if rate is not None:
            ice = to_one_instant(ice, dt, rate[0], rate[1], rec.centre_app)
            rec.centre_app, rec.phi, rec.scale, _ = similarity_fit(layout, ice)


def _row_time(rig: Rig, info, fields: bool):
    """The rolling shutter's per-measurement time offset for :func:`track_frames`, or
    None without ``[camera].rolling_shutter_ms``."""
    if not rig.rolling_shutter_ms:
        return None
    from .shutter import row_time_offsets

    readout_s = 1e-3 * rig.rolling_shutter_ms
    rotated = _decoded_rotated(info, fields)
    return lambda pts_px, shape: row_time_offsets(pts_px, shape, readout_s,
                                                  info.rotation_deg, rotated)


def _decoded_rotated(info, fields: bool) -> bool:
    """Whether the decoded frames are turned by the video's rotation tag: OpenCV
    turns them, PyAV (also for fields) does not."""
    return info.decoder != "pyav" and not fields


def _calibrate(image, rig, mask):
    """(calibration, "") or (None, why the grid was not found, without "no grid found")."""
    from ..calib import calibrate_frame

    try:
        return calibrate_frame(image, rig, mask=mask), ""
    except TrackingError as exc:
        msg = exc.message
        head = "no grid found"
        if msg.lower().startswith(head):  # our messages say it already
            msg = msg[len(head):].lstrip(" :") or msg
        return None, msg


def track_frames(frames, rig: Rig, path=None, progress=None, outline_every: int = 2,
                 row_time=None, strict: bool = True) -> tuple[list[FrameRecord], dict]:
    """Run the per-frame loop over an iterable of :class:`curltrack.video.Frame`.

    ``row_time(markers_px, image_shape)``, when given (a rolling shutter,
    :func:`curltrack.track.shutter.row_time_offsets`), gives each marker's exposure time
    relative to the frame's: their mean is added to the frame's time (the instant at
    which the rock's rows were exposed), and the markers are moved to that instant.

    The rock's outline (the scale check's second ruler) is measured on every
    ``outline_every``-th frame.

    ``strict`` = False (doctor's and calibrate's few frames) never gives up: frames
    without markers or grid keep their reasons and the records are returned.

    Returns
    -------
    (records, info) : list of FrameRecord, dict
        ``info`` holds the calibration (``calib``, made on frame ``calib_frame``) and
        the focal/principal point data.
    """
    from ..calib import GridTracker
    from ..calib.grid import pixel_scale, pixel_steps
    from ..calib.lens import apply_h, undistort

    st = rig.tracking
    det = MarkerDetector(rig)
    fol = _Follower(det, rig)
    tracker = None
    calib = None
    calib_msg = ""
    calib_frame = None
    records: list[FrameRecord] = []
    L = det.layout_m
    seen_markers = False
    markers_ice: list[tuple[int, np.ndarray]] = []  # last measured (frame, (M, 2) m)
    rec_segment = 0  # grid segment of markers_ice
    frozen = _FrozenCheck()
    last_H = None  # the last frame's homography (undistorted px -> lattice m)

    def measure_lead(rec, fr, mf, pose):  # (calib: the loop's, set before any is found)
        _measure_rock(rec, fr, fr.image, mf, pose, calib, rig, L, records, row_time,
                      outline_every)
    lead = _LeadIn(fol, measure_lead)
    img = None
    for fr in frames:
        rec = FrameRecord(fr.index, fr.t, field=fr.field)
        k = fr.sample  # running exposure index (frames, or fields of interlaced video)
        records.append(rec)
        if progress is not None:
            progress(1)
        img = fr.image
        if not seen_markers and blank_frame(img, st):  # black lead-in
            rec.status = BLANK  # (before the detector sees it: it adapts to what it sees)
            continue
        if fr.field is None and frozen(img, len(records) - 1):
            # (neither follower sees it: it would tell them that everything stopped)
            rec.status = rec.grid_status = FROZEN
            if len(records) >= 2:  # (what it shows is what the frame before showed)
                rec.markers_found = records[-2].markers_found
            continue
        late = frozen.late_repeat() if fr.field is None else None
        if late is not None and late >= 1:
            records[late].status = records[late].grid_status = FROZEN
            records[late].markers_found = records[late - 1].markers_found
        mf = fol.detect(img, k)
        pre_calib = None
        if mf is not None and mf.found.any() and not mf.found.all():
            # Some markers found, not all: the others are looked for where the layout
            # puts them, at the grid's scale (this frame's calibration when there is none
            # yet - with the rock's surroundings masked if it fails on the whole frame -
            # else the last frame's homography: the camera moves little in a frame).
            H_at = last_H
            if tracker is None:
                pre_calib = _calibrate(img, rig, None)
                if pre_calib[0] is None:
                    pre_calib = _calibrate(img, rig, fol.partial_mask(img.shape, mf))
                H_at = None if pre_calib[0] is None else pre_calib[0].H
            cal_at = calib if pre_calib is None else pre_calib[0]
            if H_at is not None and cal_at is not None:
                p = mf.xy_px[mf.found][0]
                mpp = pixel_scale(apply_h(H_at, undistort(pixel_steps(p), cal_at.K,
                                                          cal_at.dist)))
                mf = fol.complete(img, k, mf, mpp)
        found = mf is not None and bool(mf.found.all())
        rec.markers_found = (tuple(bool(f) for f in mf.found) if mf is not None
                             else (False,) * len(L))
        if not found:
            rec.status = ("rock/markers not found" if mf is None else
                          f"markers not found ({mf.message})")
            if not seen_markers and colourless(img):
                rec.status = f"markers not found: {NO_COLOUR}"
            if strict and not seen_markers and len(records) >= st.give_up_frames:
                raise TrackingError(
                    f"no markers of the rig's colours "
                    f"({', '.join(m.color for m in rig.markers)}) found in frames "
                    f"{records[0].frame}-{fr.index}" + _no_colour(records), path=path,
                    where=f"frame {fr.index}")
        seen_markers = seen_markers or found
        mask = fol.mask(img.shape, k)  # (nothing masked before the markers were found)
        if tracker is None:
            # The grid is calibrated on the first frame where that works, with or without
            # the markers found (the rock then unmasked), and followed from there: a
            # frame is measurable as soon as its markers are found, as doctor judges it.
            if pre_calib is not None and (pre_calib[0] is None or not found):
                calib, calib_msg = pre_calib  # (the markers' search calibrated already)
            else:
                calib, calib_msg = _calibrate(img, rig, mask if found else None)
            if calib is None:
                rec.grid_status = f"grid not found ({calib_msg})"
                if found:
                    rec.status = rec.grid_status
                if strict and len(records) >= st.give_up_frames and seen_markers:
                    raise TrackingError(f"no grid found in frames {records[0].frame}-"
                                        f"{fr.index}: {calib_msg}", path=path,
                                        where=f"frame {fr.index}")
                continue
            # (the settings' frame counts are frames: an interlaced video's fields
            # come two per frame)
            per_frame = 1 if fr.field is None else 2
            tracker, calib_frame = GridTracker(calib, rig, per_frame), fr.index
        # The grid is followed in every frame, also while the markers are hidden (a
        # broom), so that its motion prediction - and the cell index - stay current.
        anchor = None
        if found:  # the markers and a pixel's steps at their centre, undistorted once
            M = len(L)
            q = undistort(np.vstack([mf.xy_px, pixel_steps(mf.xy_px.mean(axis=0))]),
                          calib.K, calib.dist)
            anchor = _anchor(markers_ice, q[:M], k, st.anchor_max_gap_frames * per_frame,
                             per_frame)
        pose = tracker.update(img, k, mask=mask, anchor=anchor)
        if pose.ok:
            last_H = pose.H
        rec.H = pose.H
        rec.spacing_px = pose.spacing_px
        if not strict or not found:
            # (doctor's few frames: the pose whole; track keeps H only, and the pose of
            # a frame whose markers are hidden for clicks to be measured on it)
            rec.pose = pose
        if not pose.ok:
            rec.grid_status = f"grid: {pose.message}"
        if not found:
            lead.keep(rec, fr, k, pose)
            continue
        ice = _measure_rock(rec, fr, img, mf, pose, calib, rig, L, records, row_time,
                            outline_every, q)
        if ice is not None:
            if pose.segment != rec_segment:  # (the last positions: another cell index)
                markers_ice, rec_segment = [], pose.segment
            markers_ice = (markers_ice + [(k, ice)])[-4:]   # (two of each field)
        lead.found(k, fr, mf.xy_px)
    if row_time is not None:
        _settle_shutter(records, L)
    info = {"calib": calib, "calib_msg": calib_msg, "calib_frame": calib_frame,
            "n_markers": len(L), "shape": None if img is None else img.shape[:2]}
    if not strict:
        return records, info
    if records and not seen_markers:
        raise TrackingError(
            f"no markers of the rig's colours ({', '.join(m.color for m in rig.markers)}) "
            f"found in frames {records[0].frame}-{records[-1].frame}" + _no_colour(records),
            path=path)
    if records and calib is None:
        raise TrackingError(f"no grid found in frames {records[0].frame}-{records[-1].frame}"
                            f": {calib_msg}", path=path)
    return records, info


def track_video(video_path, rig: Rig, start_frame: int | None = None,
                end_frame: int | None = None, exclude_frames=(), overlay_path=None,
                progress=False, debug_frames=(), debug_dir=None, corrections=None):
    """Track a shot video: x(t), y(t), theta(t) in the shot frame, with stop times.

    Parameters
    ----------
    video_path : path
        Overhead video of the shot.
    rig : Rig
        Grid, rock and marker layout; camera height / fps when known.
    start_frame : int, optional
        The release frame (t = 0); default the first frame.
    end_frame : int, optional
        Last frame to track (inclusive); default the last frame of the video.
    exclude_frames : iterable of int
        Frames to skip (kept as ``ok`` = 0 rows).
    overlay_path : path, optional
        Write an annotated video there (second pass over the video).
    progress : bool or callable
        Show a progress bar (rich) on stderr; or a callable ``progress(done, total)``
        told the frames measured so far after each frame of the tracking pass (how
        ``run_batch`` counts frames on its workers).
    debug_frames, debug_dir : iterable of int, path, optional
        Write a PNG of what was found on each of these frames into ``debug_dir``.
    corrections : path, optional
        A corrections file (:mod:`curltrack.track.corrections`): frames measured from
        clicked marker positions, frames excluded; recorded in the sidecar.

    Notes
    -----
    Threads: the decoder and OpenCV's own functions use ``CURLTRACK_THREADS`` threads
    (environment variable, default 1 per process; 0 = OpenCV's choice); see
    :func:`curltrack.video.decoder_threads`.  BLAS runs on one thread: the numbers do
    not depend on any thread count.

    Returns
    -------
    Series
        Contract columns ``frame, t, x, y, theta, ok`` + ``sigma_xy`` (m),
        ``sigma_theta`` (rad) - 1 sigma: the marker centroids' and the homography's
        pixel noise scaled to the rows' own scatter about a smooth path, plus the
        slowly varying and shared parts (see
        :func:`curltrack.track.results.calibrate_sigma`) - and ``quality`` (0-1: how well the frame's apparent
        marker layout agrees with the whole video's, times the markers' colour contrast
        relative to 40 Lab units).  Sidecar: the contract keys plus
        ``camera_height_err_m``, ``parallax_factor(_err)``, ``t_stop_*_err``, the shot
        frame in the lattice frame and the lens terms.

    Raises
    ------
    VideoError
        Unreadable/truncated video, bad frame range.
    TrackingError
        No markers of the rig's colours, no grid, or the rock never measurable.

    Examples
    --------
    >>> from curltrack import load_rig, track_video, write_series
    >>> series = track_video("shot.mp4", load_rig("fixtures/rig.toml"))  # doctest: +SKIP
    >>> write_series("shot.csv", series)                                # doctest: +SKIP
    """
    from ..video import decoder_threads, iter_frames, probe_video
    from .results import build_series

    info = probe_video(video_path, fps_override=rig.fps)
    corr = None
    if corrections is not None:  # read first: a bad file fails before the long pass
        from .corrections import read_corrections

        corr = read_corrections(corrections, len(rig.markers))
    start = int(start_frame or 0)
    end = info.n_frames if end_frame is None else int(end_frame) + 1
    if not 0 <= start < info.n_frames:
        from ..errors import VideoError

        raise VideoError(f"start frame {start} outside 0..{info.n_frames - 1}",
                         path=video_path, where="--start-frame")
    if end <= start:
        from ..errors import VideoError

        raise VideoError(f"end frame {end - 1} is before start frame {start}",
                         path=video_path, where="--end-frame")
    end = min(end, info.n_frames)
    exclude = sorted({int(i) for i in exclude_frames if start <= int(i) < end})
    fields = info.interlaced
    frames = iter_frames(video_path, start=start, end=end, exclude=exclude,
                         fps_override=rig.fps, **info.reading)
    total = end - start - len(exclude)
    import cv2

    # OpenCV's own threads (and the decoder's, in curltrack.video) = CURLTRACK_THREADS,
    # default 1: the per-frame work is on small crops, and batch runs one process per core.
    # BLAS always on one thread: its threads change the order of the sums in the large
    # least-squares products of the calibration, and so the last digits of the first
    # homography - which the grid's snaps on the next frames grow to tenths of a mm
    # (a rendered phone clip: 0.6 mm in y, 1 mrad in theta with 2 threads).  The same
    # video must give the same numbers in a batch worker, at the command line and with
    # any CURLTRACK_THREADS.  (OpenCV's and the decoder's threads do not change them.)
    from threadpoolctl import threadpool_limits

    threads_before = cv2.getNumThreads()
    n_threads = decoder_threads()
    if n_threads > 0:
        cv2.setNumThreads(n_threads)
    from ..progress import progress_bar

    report = progress if callable(progress) else None
    progress = bool(progress) and report is None

    def tracking_pass(frames, rig, advance):
        return track_frames(
            frames, rig, path=video_path,
            progress=_counting(advance, report, total) if progress or report else None,
            outline_every=max(2, total // OUTLINE_FRAMES),
            row_time=_row_time(rig, info, fields))
    try:
        with threadpool_limits(limits=1, user_api="blas"), \
                progress_bar("tracking", total, enabled=progress) as advance:
            records, loop_info = tracking_pass(frames, rig, advance)
        readout = None
        given_readout_ms = rig.rolling_shutter_ms
        if not fields:
            readout = _measured_readout(records, loop_info, info)
            if given_readout_ms is None and readout.found:
                # a rolling shutter shown by the grid: the frames measured again with
                # each marker timed at its row (a second pass over the video)
                # (a sensor reads its rows within one frame period at most)
                rig = replace(rig, rolling_shutter_ms=1e3 * min(readout.readout_s,
                                                                1.0 / info.fps))
                with threadpool_limits(limits=1, user_api="blas"), \
                        progress_bar("rolling shutter", total, enabled=progress) as advance:
                    records, loop_info = tracking_pass(iter_frames(
                        video_path, start=start, end=end, exclude=exclude,
                        fps_override=rig.fps, **info.reading), rig, advance)
        blank = _blank_lead(records) if start_frame is None else 0
        if blank:  # black / empty frames before the scene: t = 0 at the first real frame
            records, start = records[blank:], records[blank].frame
            t0 = records[0].t
            for r in records:
                r.t -= t0
            exclude = [i for i in exclude if i >= start]
        # Excluded frames are rows too (ok = 0), at their nominal time.
        dt = 1.0 / info.fps
        by_frame = {(r.frame, r.field or 0): r for r in records}
        t_of = _time_interpolator([r for r in records if not r.field], start, dt)
        for i in exclude:
            for fld in ((0, 1) if fields else (None,)):
                by_frame[(i, fld or 0)] = FrameRecord(i, t_of(i) + 0.5 * dt * (fld or 0),
                                                      status="excluded by the user", field=fld)
        records = [by_frame[i] for i in sorted(by_frame)]
        corr_warnings = []
        if corr is not None:
            from .corrections import apply_corrections

            corr_warnings = apply_corrections(records, corr, loop_info["calib"], rig)
        series = build_series(records, rig, info, start, loop_info, path=video_path)
    except CurltrackError:  # (the asked frames matter most when the video is refused)
        if debug_dir is not None and len(debug_frames):
            _write_verdict_frames(video_path, debug_dir, debug_frames, rig)
        raise
    finally:
        cv2.setNumThreads(threads_before)
    if readout is not None and readout.n_frames:
        series.meta["rolling_shutter_measured_ms"] = round(1e3 * readout.readout_s, 3)
        series.meta["rolling_shutter_measured_sigma_ms"] = round(1e3 * readout.sigma_s, 3)
        if given_readout_ms is not None:
            if abs(1e-3 * given_readout_ms - readout.readout_s) > READOUT_DISAGREE_Z * \
                    readout.sigma_s:
                series.meta["warnings"].append(
                    f"{video_path}: the rig's rolling_shutter_ms {given_readout_ms:g} "
                    f"disagrees with the {1e3 * readout.readout_s:.1f} +- "
                    f"{1e3 * readout.sigma_s:.1f} ms the grid's shear under the camera's "
                    "motion shows: the rig's is used - check it")
        elif readout.found:
            series.meta["rolling_shutter_source"] = "measured from the grid"
            series.meta["warnings"].append(
                f"{video_path}: the grid shears with the camera's motion as a rolling "
                f"shutter reading its rows over {1e3 * readout.readout_s:.1f} +- "
                f"{1e3 * readout.sigma_s:.1f} ms does: each marker timed at its row with "
                "it (give [camera].rolling_shutter_ms in the rig if it is known)")
    if corr is not None:
        series.meta["corrections"] = {
            "file": corr["file"], "click_sigma_px": corr["click_sigma_px"],
            "frames_from_clicks": sorted(corr["clicked"]),
            "frames_excluded": sorted(corr["excluded"])}
        series.meta["warnings"].extend(corr_warnings)
    if blank:
        series.meta["warnings"].insert(0, f"frames {start - blank}-{start - 1} show neither "
                                       f"rock nor grid (black or empty): skipped; t = 0 at "
                                       f"frame {start} (give --start-frame to choose)")
    if overlay_path is not None:
        from .overlay import write_overlay

        with progress_bar("overlay", total, enabled=progress) as advance:
            write_overlay(video_path, overlay_path, records, series, loop_info, rig,
                          start=start, end=end, exclude=exclude, progress=advance)
    if debug_dir is not None and len(debug_frames):
        from .overlay import write_debug_frames

        write_debug_frames(video_path, debug_dir, debug_frames, records, series,
                           loop_info["calib"], rig)
    return series


def _measure_rock(rec: FrameRecord, fr, img, mf, pose, calib, rig: Rig, L, records,
                  row_time, outline_every: int, q=None):
    """Measure the rock of one frame whose markers ``mf`` were all found, on the grid's
    ``pose``: fills ``rec`` (apparent centre, angle, scale, sigmas, lattice at the rock)
    or gives its status the reason it cannot be measured.  ``L``: the rig's marker
    layout (m, rock frame).

    Returns the markers on the ice (lattice m, (M, 2)) when the lattice reached them
    (the grid's anchor for the next frames), else None.  ``q``: the markers and a
    pixel's steps at their centre, undistorted (computed when not given).
    """
    from ..calib.grid import pixel_steps
    from ..calib.lens import apply_h, undistort

    M = len(L)
    if q is None:
        q = undistort(np.vstack([mf.xy_px, pixel_steps(mf.xy_px.mean(axis=0))]),
                      calib.K, calib.dist)
    rec.markers_px = mf.xy_px
    seen_at = None  # each marker's exposure time relative to the row's t (s)
    if row_time is not None:
        offsets = row_time(mf.xy_px, img.shape)
        rec.t = fr.t + float(np.mean(offsets))
        seen_at = offsets - offsets.mean()
    if not pose.ok:
        rec.status = f"grid: {pose.message}"
        return None
    if not calib.in_checked_lens(mf.xy_px).all():
        rec.status = (f"lens: the rock is beyond the {calib.lens_radius_px:.0f} px from "
                      f"the image centre where the threads confirm the wide-angle lens "
                      f"(k1 = {calib.dist[0]:.3f}, k2 = {calib.dist[1]:.3f})")
        return None
    ice = apply_h(pose.H, q)[:M]
    rec.segment = pose.segment
    c, phi, s, _ = similarity_fit(L, ice)
    rec.mirrored = mirrored_layout(L, ice)
    at_instant = ice
    if seen_at is not None:
        rate = _rock_rate(records, rec)
        if rate is not None:  # each marker seen at its own row's time: one instant
            at_instant = to_one_instant(ice, seen_at, rate[0], rate[1], c)
            c, phi, s, _ = similarity_fit(L, at_instant)
        else:
            rec.shutter_pending = (ice, seen_at)
    mpp = read_lattice_at_rock(rec, pose, calib, L, q, at_instant, c)
    # (cells: a homography the threads leave free at the rock, however well it fits)
    unsure = rec.grid_sigma_m / min(calib.spacing_x_m, calib.spacing_y_m)
    if unsure > rig.tracking.max_grid_sigma_cells:
        rec.status = (f"grid: the lattice is not fixed at the rock (1 sigma "
                      f"{unsure:.2f} cell): the threads measured leave it free there")
        return ice
    rec.centre_app, rec.phi, rec.scale = c, phi, s
    if fr.index % outline_every == 0:  # the scale's second ruler
        rec.outline_m = outline_radius(img, pose.H, calib.K, calib.dist, c,
                                       rig.rock_diameter_m / 2)[0]
    rec.sigma_m = float(np.sqrt(np.mean(mf.sigma_px ** 2))) * mpp
    if fr.field is not None:
        rec.sigma_m *= FIELD_SIGMA_FACTOR
        rec.grid_sigma_m *= FIELD_SIGMA_FACTOR
    rec.grid_residual_m, rec.m_per_px = pose.residual_px * mpp, mpp
    rec.contrast = float(np.min(mf.contrast))
    if pose.message:
        rec.notes.append(pose.message)
    return ice


#: :class:`_LeadIn` keeps at most this many bytes of images (the frames nearest the
#: markers' first sighting): a 1080p video's ~40 frames, a DV video's ~300 fields.
LEAD_IN_BYTES = 256 * 2 ** 20


class _LeadIn:
    """The frames before the markers were first found, looked at again backwards.

    At release the rock is fastest: a camcorder's field (1/50-1/60 s) smears its markers
    over more than their size, and their colours fade towards the rock's grey - too far
    from the rig's colours for a search of the whole frame, so the first rows were lost
    and the origin (the rock at t = 0) extrapolated back to them (a PAL DV clip: the
    first 0.2 s, the origin 2.2 mm off).  Once the markers are found in two exposures,
    the earlier ones are searched where those two put them, going back in time, with
    the colours learnt on the sharp ones - as forwards after a loss.  The backward
    search stops at its first miss; the detector's colours are restored after it, so
    the forward pass is not changed by it.  The frames' images are kept until then
    (:data:`LEAD_IN_BYTES` at most: the latest ones).
    """

    def __init__(self, follower: "_Follower", measure):
        self.fol, self.measure = follower, measure
        self.kept: list = []  # (rec, frame, k, pose) of frames not measured, in order
        self.first: list = []  # (k, markers px) of the first exposures all found
        self.nbytes = 0
        self.done = False

    def keep(self, rec: FrameRecord, fr, k: int, pose) -> None:
        """A frame whose markers were not all found (before the first two that were)."""
        if self.done:
            return
        self.kept.append((rec, fr, k, pose))
        self.nbytes += fr.image.nbytes
        while self.nbytes > LEAD_IN_BYTES and self.kept:
            self.nbytes -= self.kept.pop(0)[1].image.nbytes

    def found(self, k: int, fr, xy_px) -> None:
        """Exposure ``k`` (of frame ``fr``) had all its markers found: after two (of each
        field), the kept frames are searched backwards, each found one measured by
        ``measure(rec, frame, mf, pose)`` (given at construction)."""
        if self.done:
            return
        per_frame = 1 if fr.field is None else 2
        self.first.append((k, np.asarray(xy_px, float).copy()))
        if len(self.first) < 2 * per_frame:
            return
        self.done = True
        k0 = self.first[0][0]
        kept = [item for item in self.kept if item[2] < k0]
        self.kept = []
        if not kept:
            return
        det = self.fol.det
        learnt = det.memory()
        back = _Follower(det, self.fol.rig, per_frame)
        back.hist = self.first[::-1]
        try:
            for rec, fr, k, pose in reversed(kept):
                mf = back.detect(fr.image, k)
                if back.lost or mf is None or not mf.found.all():
                    break
                rec.status = ""
                rec.markers_found = (True,) * len(mf.found)
                self.measure(rec, fr, mf, pose)
        finally:
            det.recall(learnt)


#: A readout given in the rig that is this many sigmas from the one the video shows is
#: warned about (a phone's spec sheet for another mode, a typo).
READOUT_DISAGREE_Z = 5.0


def _measured_readout(records, loop_info, info):
    """The rolling shutter's readout measured from the frames' grids
    (:func:`curltrack.track.shutter.estimate_readout`)."""
    from .shutter import ReadoutEstimate, estimate_readout

    calib = loop_info.get("calib")
    good = [r for r in records if r.H is not None and r.grid_status == ""]
    if calib is None or loop_info.get("shape") is None or len(good) < 3:
        return ReadoutEstimate(np.nan, np.nan, 0)
    return estimate_readout([r.t for r in good], [r.H for r in good], calib.K[:2, 2],
                            loop_info["shape"], info.rotation_deg,
                            decoded_rotated=_decoded_rotated(info, fields=False))


def _write_verdict_frames(video_path, debug_dir, frames, rig) -> None:
    """``calibrate``'s PNG of each of ``frames`` (track's verdict on it, from track's
    own loop), for a video whose series could not be built."""
    from pathlib import Path

    from ..video import read_frame
    from .check import check_frames
    from .overlay import write_verdict_frame

    Path(debug_dir).mkdir(parents=True, exist_ok=True)
    for verdict in check_frames(video_path, sorted(set(int(f) for f in frames)), rig,
                                fps_override=rig.fps):
        write_verdict_frame(debug_dir, read_frame(video_path, verdict.frame), verdict, rig)


def _counting(advance, report, total: int):
    """``advance`` (a progress bar's) that also tells ``report(done, total)``."""
    done = 0

    def step(n: int = 1) -> None:
        nonlocal done
        done += n
        advance(n)
        if report is not None:
            report(done, total)
    return step


def _blank_lead(records) -> int:
    """How many records at the start are blank frames (a black lead-in)."""
    for k, r in enumerate(records):
        if r.status != BLANK:
            return k
    return 0


def _time_interpolator(records, start, dt):
    """Time (s) of a frame that was not decoded: interpolated between decoded frames,
    extrapolated at the nominal frame period beyond them."""
    frames = np.array([r.frame for r in records], float)
    times = np.array([r.t for r in records], float)

    def t_of(i):
        if frames.size == 0:
            return float((i - start) * dt)
        if i < frames[0]:
            return float(times[0] - (frames[0] - i) * dt)
        if i > frames[-1]:
            return float(times[-1] + (i - frames[-1]) * dt)
        return float(np.interp(i, frames, times))

    return t_of
