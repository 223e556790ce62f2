"""Thread budget of the decoder and of OpenCV in tracking: CURLTRACK_THREADS."""

import pytest

from curltrack.errors import VideoError
from curltrack.video import decoder_threads


def test_default_is_one_thread(monkeypatch):
    monkeypatch.delenv("CURLTRACK_THREADS", raising=False)
    assert decoder_threads() == 1


@pytest.mark.parametrize("value, expected", [("4", 4), ("0", 0), (" 2 ", 2), ("", 1)])
def test_value_from_the_environment(monkeypatch, value, expected):
    monkeypatch.setenv("CURLTRACK_THREADS", value)
    assert decoder_threads() == expected


def test_bad_value_names_the_variable(monkeypatch):
    monkeypatch.setenv("CURLTRACK_THREADS", "many")
    with pytest.raises(VideoError, match="CURLTRACK_THREADS"):
        decoder_threads()
