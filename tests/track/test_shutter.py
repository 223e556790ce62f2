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
