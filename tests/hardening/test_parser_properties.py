"""Property-based tests of the rig and series readers at the file level: any bytes, any
mapping -> a valid object or one clear error naming the file (and field / row)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from curltrack.errors import RigError, SeriesError
from curltrack.rig import load_rig, rig_from_dict
from curltrack.series import read_series

SETTINGS = dict(deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture])

values = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-1000, 1000),
                   st.booleans(), st.text(max_size=6), st.lists(st.floats(0, 1), max_size=2))
good = {
    "grid": {"spacing_x_m": 0.15, "spacing_y_m": 0.15, "colors": ["#d02020", "#2040d0"]},
    "rock": {"diameter_m": 0.29, "height_m": 0.114},
    "markers": [{"color": "#ffd000", "x_m": 0.08, "y_m": 0.0},
                {"color": "#00c0ff", "x_m": -0.08, "y_m": 0.0}],
    "camera": {"fps": 30.0},
}
fields = [("grid", "spacing_x_m"), ("grid", "spacing_y_m"), ("grid", "depth_m"),
          ("grid", "colors"), ("grid", "spacing_cm"), ("rock", "diameter_m"),
          ("rock", "height_m"), ("rock", "band_radius_m"), ("rock", "inertia_radius_m"),
          ("rock", "mass_kg"), ("camera", "fps"), ("camera", "height_m"), ("camera", "iso"),
          ("markers", "x_m"), ("markers", "y_m"), ("markers", "color")]


@settings(max_examples=150, **SETTINGS)
@given(edits=st.lists(st.tuples(st.sampled_from(fields), values, st.booleans()), max_size=4))
def test_any_rig_mapping_is_valid_or_names_the_field(edits):
    """Random edits (set or delete) of a good rig: every accepted rig is physically
    plausible; every rejection names a section or field."""
    import copy

    data = copy.deepcopy(good)
    for (sec, key), value, delete in edits:
        tables = data[sec] if sec == "markers" else [data[sec]]
        for t in tables[:1]:
            if delete:
                t.pop(key, None)
            else:
                t[key] = value
    try:
        rig = rig_from_dict(data, source="edited.toml")
    except RigError as exc:
        msg = str(exc)
        assert msg.startswith("edited.toml: [") or msg.startswith("edited.toml: top level")
        assert "\n" not in msg
        return
    for v in (rig.spacing_x_m, rig.spacing_y_m, rig.rock_diameter_m, rig.rock_height_m,
              rig.band_radius_m, rig.inertia_radius_m):
        assert math.isfinite(v) and 0 <= v < 2.5
    assert len(rig.markers) >= 2
    assert rig.fps is None or 1 <= rig.fps <= 1000


@settings(max_examples=80, **SETTINGS)
@given(blob=st.one_of(st.binary(max_size=200), st.text(max_size=200).map(str.encode)))
def test_any_rig_bytes_load_or_fail_cleanly(tmp_path, blob):
    p = tmp_path / "fuzz.toml"
    p.write_bytes(blob)
    with pytest.raises(RigError) as info:  # random bytes are never a complete rig
        load_rig(p)
    assert str(info.value).startswith(str(p)) and "\n" not in str(info.value)


@settings(max_examples=80, **SETTINGS)
@given(blob=st.one_of(st.binary(max_size=300),
                      st.text(alphabet="0123456789.,-e\nnaftxyokhr", max_size=300)
                      .map(lambda s: ("frame,t,x,y,theta,ok\n" + s).encode())))
def test_any_series_bytes_read_or_fail_cleanly(tmp_path, blob):
    p = tmp_path / "fuzz.csv"
    p.write_bytes(blob)
    try:
        s = read_series(p)
    except SeriesError as exc:
        assert str(exc).startswith(str(p)) and "\n" not in str(exc)
        return
    t = s.data["t"].to_numpy()
    assert np.isfinite(t).all() and (np.diff(t) > 0).all()
    ok = s.data["ok"].to_numpy() == 1
    assert np.isfinite(s.data.loc[ok, ["x", "y", "theta"]].to_numpy(float)).all()
