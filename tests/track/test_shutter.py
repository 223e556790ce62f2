"""Rolling shutter: each measurement timed at the sensor row of the rock."""

import numpy as np
import pytest

from curltrack.render.encode import EncodingConfig, open_writer
from curltrack.track.shutter import row_time_offsets, sensor_row_fraction
from curltrack.video import iter_frames, probe_video


@pytest.mark.parametrize("rotation", [0, 90, 180, 270])
def test_sensor_row_through_the_decoder(tmp_path, rotation):
    """A dot drawn at a known sensor row, written with a rotation tag and decoded as the
    tracker decodes it, is found at that sensor row."""
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    W, H = 160, 96
    u, v = int(rng.integers(20, W - 20)), int(rng.integers(15, H - 15))
    img = np.full((H, W, 3), 40, np.uint8)
    img[v - 3:v + 4, u - 3:u + 4] = 255
    path = tmp_path / f"r{rotation}.mp4"
    w = open_writer(path, 30.0, (W, H), EncodingConfig(codec="h264", rotation_deg=rotation))
    for k in range(3):
        w.write(img, k / 30.0)
    w.close()
    info = probe_video(path)
    assert info.rotation_deg == rotation
    fr = next(iter(iter_frames(path, decoder=info.decoder)))
    g = fr.image.mean(axis=2)
    ys, xs = np.nonzero(g > 150)
    dot = np.array([[xs.mean(), ys.mean()]])
    frac = sensor_row_fraction(dot, fr.image.shape, info.rotation_deg,
                               decoded_rotated=info.decoder != "pyav")
    assert frac[0] == pytest.approx((v + 0.5) / H, abs=0.6 / H), (seed, info.decoder, dot)


def test_row_time_offsets_span_the_readout():
    shape = (540, 960, 3)
    top, mid, bottom = ([[100.0, -0.5]], [[500.0, 269.5]], [[3.0, 539.5]])
    assert row_time_offsets(top, shape, 0.02)[0] == pytest.approx(-0.01)
    assert row_time_offsets(mid, shape, 0.02)[0] == pytest.approx(0.0)
    assert row_time_offsets(bottom, shape, 0.02)[0] == pytest.approx(0.01)
    with pytest.raises(ValueError):
        sensor_row_fraction(top, shape, 45)


def test_shutter_slide_is_the_ice_speed_times_the_readout():
    """A camera sliding at a steady speed (drawn at random) over the ice: the slide under
    the image during the readout is speed x readout (a cell jump is ignored)."""
    from types import SimpleNamespace

    from curltrack.calib.lens import camera_matrix
    from curltrack.track.results import shutter_slide

    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    speed, readout, fps = rng.uniform(0.2, 3.0), rng.uniform(0.005, 0.03), 30.0
    heading = rng.uniform(0, 2 * np.pi)
    K = camera_matrix(960, 540)
    calib = SimpleNamespace(K=K, dist=(-0.1, 0.0))
    recs = []
    for k in range(20):
        shift = speed * k / fps * np.array([np.cos(heading), np.sin(heading)])
        if k >= 12:
            shift = shift + (0.15, 0.0)  # the cell index re-anchored by one cell
        H = np.array([[0.002, 0, shift[0]], [0, -0.002, shift[1]], [0, 0, 1.0]])
        recs.append(SimpleNamespace(status="", H=H, t=k / fps, frame=k))
    frame, slide = shutter_slide(recs, calib, readout)
    assert slide == pytest.approx(speed * readout, rel=1e-6), seed


def test_markers_seen_at_their_rows_times_are_moved_to_one_instant():
    """A rock translating and turning (drawn at random) whose markers are each seen at
    its own time offset: moved back, they lie where the rock put them at offset 0, and
    the pair's angle is right (uncorrected it is off by ~|v| dt / d)."""
    from curltrack.track.parallax import similarity_fit
    from curltrack.track.shutter import to_one_instant

    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    layout = rng.uniform(-0.1, 0.1, (int(rng.integers(2, 5)), 2))
    layout -= layout.mean(axis=0)
    v, omega = rng.uniform(-2, 2, 2), rng.uniform(-3, 3)
    c0, phi0 = rng.uniform(-1, 1, 2), rng.uniform(-np.pi, np.pi)
    dt = rng.uniform(-0.015, 0.015, len(layout))
    dt -= dt.mean()

    def seen(t, i):
        a = phi0 + omega * t
        R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        return c0 + v * t + R @ layout[i]

    pts = np.array([seen(dt[i], i) for i in range(len(layout))])
    c, _, _, _ = similarity_fit(layout, pts)
    back = to_one_instant(pts, dt, v, omega, c)
    truth = np.array([seen(0.0, i) for i in range(len(layout))])
    # (c is the sheared points' centre, within |omega dt| x |layout| of the true one)
    np.testing.assert_allclose(back, truth, atol=2e-4, err_msg=str(seed))
    _, phi, _, _ = similarity_fit(layout, back)
    assert abs(np.angle(np.exp(1j * (phi - phi0)))) < 2e-3, seed


def _sheared_homographies(rng, readout_s, rotation, mirrored, n=150, fps=30.0,
                          shape=(540, 960)):
    """Homographies (undistorted px -> ice m) of a camera moving over the ice with a
    random shaking velocity, each row read ``readout_s`` * its sensor row fraction later:
    the image of the ice sheared by the velocity times the readout."""
    from curltrack.track.shutter import sensor_row_fraction

    c = np.array([shape[1] / 2, shape[0] / 2])
    pts = np.array([c, c + (1.0, 0.0), c + (0.0, 1.0)])
    f = sensor_row_fraction(pts, shape, rotation, True)
    grad = np.array([f[1] - f[0], f[2] - f[0]])
    t = np.arange(n) / fps
    # image velocity (px/s): following at up to ~300 px/s plus a 2-6 Hz shake
    v = (rng.uniform(-300, 300, 2)[None, :] * np.minimum(t, 1.0)[:, None]
         + rng.uniform(20, 80) * np.sin(2 * np.pi * rng.uniform(2, 6) * t[:, None]
                                         + rng.uniform(0, 6, 2)))
    s = rng.uniform(0.002, 0.004)  # m per px
    psi = rng.uniform(0, 2 * np.pi) + np.cumsum(rng.normal(0, 0.002, n))
    flip = np.diag([1.0, -1.0 if mirrored else 1.0])
    Hs = []
    centre = np.zeros(2)  # the ice under the image centre: it moves back as the image moves
    for k in range(n):
        A = s * flip @ np.array([[np.cos(psi[k]), -np.sin(psi[k])],
                                 [np.sin(psi[k]), np.cos(psi[k])]])
        centre = centre - A @ v[k] / fps
        # p_true = p_obs - v R (f(p_obs) - f(c)): an affine map of p_obs
        B = np.eye(2) - readout_s * np.outer(v[k], grad)
        L = A @ B
        H = np.eye(3)
        H[:2, :2] = L
        H[:2, 2] = centre - L @ c
        Hs.append(H)
    return t, np.array(Hs), c, shape


@pytest.mark.parametrize("rotation", [0, 90, 180, 270])
def test_readout_measured_from_the_lattice_shear(rotation):
    """A rolling shutter's readout (3-30 ms) is recovered from the frames' homographies
    under the camera's motion, for any rotation tag and a lattice mirrored or not; a
    global shutter (0 ms) is not taken for one."""
    from curltrack.track.shutter import estimate_readout

    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    readout = rng.uniform(0.003, 0.030)
    mirrored = bool(rng.integers(2))
    t, Hs, c, shape = _sheared_homographies(rng, readout, rotation, mirrored)
    # each homography measured to ~0.05 px: noise on the lattice's map
    noisy = Hs * (1 + rng.normal(0, 2e-5, Hs.shape))
    est = estimate_readout(t, noisy, c, shape, rotation)
    what = f"seed {seed}: readout {1e3 * readout:.2f} ms, mirrored {mirrored}"
    assert est.found, what
    # (first-order algebra and central-difference velocities: ~1-2 % off on clean maps)
    assert abs(est.readout_s - readout) < 0.05 * readout + 0.3e-3, \
        f"{what}: {1e3 * est.readout_s:.2f} +- {1e3 * est.sigma_s:.2f} ms"
    t, Hs, c, shape = _sheared_homographies(rng, 0.0, rotation, mirrored)
    est = estimate_readout(t, Hs * (1 + rng.normal(0, 2e-5, Hs.shape)), c, shape, rotation)
    assert not est.found, f"{what}: a global shutter read as {1e3 * est.readout_s:.2f} ms"
