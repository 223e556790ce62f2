"""The frames before the markers were first found, searched again backwards
(:class:`curltrack.track.pipeline._LeadIn`).

At release a rock is at its fastest: a camcorder field smears its markers and fades
their colours, the first rows were lost and the origin extrapolated back (a PAL DV
clip: the first 0.2 s, every row 2.2 mm off; the DV file test failed on ~5 % of its
seeds).  These tests draw a rock moving (and turning) rigidly across synthetic frames,
smeared over each exposure, at random."""

import numpy as np

from curltrack.rig import default_rig
from curltrack.track.markers import MarkerDetector
from curltrack.track.pipeline import FrameRecord, _Follower, _LeadIn
from curltrack.video import Frame

PX_PER_M = 400.0
SHUTTER = 0.5   # exposure, frame periods
SUBFRAMES = 8


def _scene(rng):
    """A rock's motion: centre (px) and angle (rad) at time k (frames)."""
    c0 = np.array([rng.uniform(60, 90), rng.uniform(110, 130)])
    v = rng.uniform(5.0, 9.0) * np.array([1.0, rng.uniform(-0.1, 0.1)])   # px/frame
    w = rng.uniform(-0.03, 0.03)                                            # rad/frame
    a0 = rng.uniform(-np.pi, np.pi)
    return lambda k: (c0 + v * k, a0 + w * k)


def _markers_px(rig, pose):
    c, a = pose
    L = np.array([[m.x_m, m.y_m] for m in rig.markers]) * PX_PER_M
    rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    return c + L @ rot.T


def _image(rig, motion, k, rng, rock=True):
    """Frame ``k``: the rock and its markers averaged over the exposure, noise on."""
    import cv2

    acc = np.zeros((240, 360, 3))
    for j in range(SUBFRAMES):
        img = np.full((240, 360, 3), (232, 228, 225), np.uint8)
        if rock:
            pose = motion(k + SHUTTER * (j + 0.5) / SUBFRAMES)
            c = np.round(pose[0] * 16).astype(int)
            cv2.circle(img, tuple(c), int(0.145 * PX_PER_M * 16), (90, 88, 85), -1,
                       cv2.LINE_AA, shift=4)
            for m, p in zip(rig.markers, _markers_px(rig, pose)):
                r, g, b = m.rgb
                cv2.circle(img, tuple(np.round(p * 16).astype(int)), int(0.0125 * PX_PER_M * 16),
                           (b, g, r), -1, cv2.LINE_AA, shift=4)
        acc += img
    acc = acc / SUBFRAMES + rng.normal(0, 2.0, acc.shape)
    return np.clip(acc, 0, 255).astype(np.uint8)


def _run(rig, motion, rng, n_kept, blank=None):
    """Frames 0..n_kept-1 kept as not found, the next two found; returns the frames
    measured backwards ({k: markers px}) and whether the detector's colours came back."""
    det = MarkerDetector(rig)
    fol = _Follower(det, rig)
    measured = {}
    lead = _LeadIn(fol, lambda rec, f, m, pose: measured.update(
        {rec.frame: (rec.status, m.xy_px.copy())}))
    for k in range(n_kept):
        img = _image(rig, motion, k, rng, rock=k != blank)
        lead.keep(FrameRecord(k, k / 30.0, status="markers not found"),
                  Frame(k, k / 30.0, img), k, pose=object())
    before = None
    for k in (n_kept, n_kept + 1):
        fr = Frame(k, k / 30.0, _image(rig, motion, k, rng))
        mf = fol.detect(fr.image, k)
        assert mf is not None and mf.found.all()
        if k == n_kept + 1:
            before = det.memory()
        lead.found(k, fr, mf.xy_px)
    after = det.memory()
    same = np.array_equal(before[0], after[0]) and before[1] == after[1]
    return measured, same


def test_the_frames_before_the_first_markers_are_measured_backwards():
    """Every kept frame is searched where the found ones put it, back to the first:
    each found at the markers' place over its exposure (within a pixel), its status
    cleared; the detector's colours as they were."""
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    rig = default_rig()
    motion = _scene(rng)
    n_kept = int(rng.integers(3, 8))
    measured, same = _run(rig, motion, rng, n_kept)
    what = f"seed {seed}: measured {sorted(measured)} of 0-{n_kept - 1}"
    assert sorted(measured) == list(range(n_kept)), what
    for k, (status, xy) in measured.items():
        truth = np.mean([_markers_px(rig, motion(k + SHUTTER * (j + 0.5) / SUBFRAMES))
                         for j in range(SUBFRAMES)], axis=0)
        assert status == "", what
        assert np.abs(xy - truth).max() < 1.0, f"{what}: frame {k} {xy - truth} px off"
    assert same, f"{what}: the detector's colours changed"


def test_the_backward_search_stops_at_a_frame_without_the_rock():
    """A kept frame without the rock ends the search: the frames before it are not
    looked for (no prediction reaches across), and it is not measured."""
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    rig = default_rig()
    n_kept = int(rng.integers(4, 8))
    blank = int(rng.integers(1, n_kept - 1))
    measured, _ = _run(rig, _scene(rng), rng, n_kept, blank=blank)
    assert sorted(measured) == list(range(blank + 1, n_kept)), \
        f"seed {seed}: no rock in frame {blank}, measured {sorted(measured)}"


def test_interlaced_fields_are_extrapolated_within_each_field_backwards():
    """Backwards as forwards (``_Follower.predicted``, ``per_frame`` = 2): the fields'
    markers differ by more than the rock's motion (DV's colour mixed between them),
    and extrapolated across fields the prediction stood still (the DV clip: the
    backward search lost the rock 17 px from where it was)."""
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    v = rng.uniform(-20, 20, 2)             # px per field
    offset = rng.uniform(-10, 10, 2)        # field 1's markers against field 0's
    layout = rng.uniform(-30, 30, (2, 2))
    start = int(rng.integers(10, 50))

    def seen(k):
        return layout + v * k + offset * (k % 2)

    fol = _Follower(MarkerDetector(default_rig()), default_rig(), per_frame=2)
    fol.hist = [(k, seen(k)) for k in range(start + 3, start - 1, -1)]
    for k in range(start - 1, start - 4, -1):
        np.testing.assert_allclose(fol.predicted(k), seen(k), atol=1e-9,
                                   err_msg=f"seed {seed}, exposure {k}")
        fol.hist = (fol.hist + [(k, seen(k))])[-4:]
