"""Rolling shutter: each measurement timed at the sensor row of the rock."""

import numpy as np
import pytest

from curltrack.render.encode import EncodingConfig, open_writer
from curltrack.track.shutter import row_time_offset, sensor_row_fraction
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


def test_row_time_offset_spans_the_readout():
    shape = (540, 960, 3)
    top, mid, bottom = ([[100.0, -0.5]], [[500.0, 269.5]], [[3.0, 539.5]])
    assert row_time_offset(top, shape, 0.02) == pytest.approx(-0.01)
    assert row_time_offset(mid, shape, 0.02) == pytest.approx(0.0)
    assert row_time_offset(bottom, shape, 0.02) == pytest.approx(0.01)
    with pytest.raises(ValueError):
        sensor_row_fraction(top, shape, 45)
