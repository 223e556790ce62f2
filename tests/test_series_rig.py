"""Series and rig parsers: contract round trips, clear errors, property-based checks."""

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from curltrack.errors import RigError, SeriesError
from curltrack.rig import load_rig
from curltrack.series import read_series, sidecar_path, write_series
from hardening.badinputs import RIG_TOML
from synth import closed_form_series

# the contract's example rig (shared with the hardening tests), with an unequal spacing
# and a [camera] table so that the round trip checks them too
RIG = (RIG_TOML.replace("spacing_y_m = 0.15", "spacing_y_m = 0.2")
       + "[camera]\nfps = 29.97\n")


def test_rig_round_trip(tmp_path):
    p = tmp_path / "rig.toml"
    p.write_text(RIG)
    rig = load_rig(p)
    assert rig.spacing_y_m == 0.2 and rig.fps == 29.97 and rig.camera_height_m is None
    assert rig.band_radius_m == 0.0625 and rig.inertia_radius_m == 0.14
    q = tmp_path / "again.toml"
    q.write_text(rig.to_toml())
    assert load_rig(q).markers == rig.markers


@pytest.mark.parametrize("edit, where", [
    (lambda s: s.replace("spacing_x_m = 0.15\n", ""), "[grid].spacing_x_m"),
    (lambda s: s.replace("diameter_m = 0.29", "diameter_m = 29"), "[rock].diameter_m"),
    (lambda s: s.replace("height_m = 0.114", "height_m = 11.4"), "[rock].height_m"),
    (lambda s: s.replace("spacing_y_m", "spacing_y_cm"), "[grid]"),
    (lambda s: s.replace('"#ffd000"', '"sunshine"'), "[[markers]][0].color"),
    (lambda s: s.replace("x_m = -0.08", 'x_m = "left"'), "[markers].x_m"),
    (lambda s: s.replace("[camera]", "[camra]"), "top level"),
    (lambda s: s.replace("[rock]", "[rock"), "not valid TOML"),
])
def test_bad_rigs_name_the_field(tmp_path, edit, where):
    p = tmp_path / "rig.toml"
    p.write_text(edit(RIG))
    with pytest.raises(RigError) as err:
        load_rig(p)
    msg = str(err.value)
    assert str(p) in msg and where in msg and "\n" not in msg


def test_series_round_trip_csv_and_parquet(tmp_path):
    s = closed_form_series(noise_m=0.002, seed=1)
    for name in ("shot.csv", "shot.parquet"):
        write_series(tmp_path / name, s)
        back = read_series(tmp_path / name)
        np.testing.assert_allclose(back.data["x"], s.data["x"], atol=1e-8)
        assert back.meta["t_stop_translation"] == s.meta["t_stop_translation"]
        assert sidecar_path(tmp_path / name).exists()
    assert not list(tmp_path.glob(".*"))  # no temporary files left behind


def _csv(tmp_path, text):
    p = tmp_path / "bad.csv"
    p.write_text(text)
    return p


@pytest.mark.parametrize("text, match", [
    ("frame,t,x,y,ok\n0,0,0,0,1\n", "missing column"),
    ("t,x,theta\n0,0,0\n", "missing column"),
    ("frame,t,x,y,theta,ok\n0,0,0,0,0,1\n1,0.03,abc,0,0,1\n", "non-numeric"),
    ("frame,t,x,y,theta,ok\n0,0,0,0,0,1\n1,0.0,0,0,0,1\n", "duplicate"),
    ("frame,t,x,y,theta,ok\n0,0.1,0,0,0,1\n1,0.05,0,0,0,1\n", "decreasing"),
    ("frame,t,x,y,theta,ok\n0,0,0,0,0,2\n", "'ok' must be 0 or 1"),
    ("frame,t,x,y,theta,ok\n", "no rows"),
])
def test_bad_series_are_clear_errors(tmp_path, text, match):
    p = _csv(tmp_path, text)
    with pytest.raises(SeriesError, match=match) as err:
        read_series(p)
    assert str(p) in str(err.value)


def test_nan_in_measured_row_becomes_unmeasured_with_warning(tmp_path):
    p = _csv(tmp_path, "frame,t,x,y,theta,ok\n0,0,0,0,0,1\n1,0.03,,0,0,1\n2,0.06,0,0,0,1\n")
    s = read_series(p)
    assert s.data["ok"].tolist() == [1, 0, 1]
    assert any("row 3" in w for w in s.warnings)


def test_a_table_of_t_x_y_alone_is_a_position_only_series(tmp_path):
    """Another instrument's export (t, x, y; a row without a fix left empty) is read as
    a position-only series, each column filled said in a warning."""
    p = _csv(tmp_path, "t,x,y,quality\n0,0,0,9\n0.1,0.001,0.2,9\n0.2,,0.4,0\n0.3,0,0.6,9\n")
    s = read_series(p)
    assert s.data["frame"].tolist() == [0, 1, 2, 3]
    assert s.data["ok"].tolist() == [1, 1, 0, 1]
    assert s.data["theta"].isna().all() and not s.theta_measured
    assert "quality" in s.data.columns   # (other columns kept)
    for col in ("frame", "ok", "theta"):
        assert any(f"no '{col}' column" in w and str(p) in w for w in s.warnings), col
    p.write_text("t,x,y,theta\n0,0,0,0\n0.1,0.001,0.2,0.1\n0.2,0,0.4,0.2\n")
    s = read_series(p)
    assert s.theta_measured and s.data["theta"].tolist() == [0, 0.1, 0.2]


def test_column_names_with_spaces_or_in_upper_case_are_read(tmp_path):
    """``frame, t, x`` (spaces after the commas) is the contract's table; ``T``, ``X``
    in upper case too, said in a warning; a name two columns could take is not
    guessed."""
    p = _csv(tmp_path, "frame, t, x, y, theta, ok, sigma_xy\n0,0,0,0,0,1,0.002\n"
                       "1,0.1,0,0.2,0.1,1,0.002\n")
    s = read_series(p)
    assert s.data["y"].tolist() == [0, 0.2] and "sigma_xy" in s.data.columns
    assert not any("read as" in w for w in s.warnings)
    p.write_text("Frame,T,X,Y,Theta,OK\n0,0,0,0,0,1\n1,0.1,0,0.2,0.1,1\n")
    s = read_series(p)
    assert s.data["t"].tolist() == [0, 0.1]
    assert any("read as" in w and "T" in w and str(p) in w for w in s.warnings)
    p.write_text("frame,t,X,x2,Y,y,theta,ok\n0,0,0,0,0,0,0,1\n")
    assert read_series(p).data["y"].tolist() == [0]   # (y given: Y is another column)


def test_ok_written_as_true_false_is_read(tmp_path):
    p = _csv(tmp_path, "frame,t,x,y,theta,ok\n0,0,0,0,0,True\n1,0.1,,0.2,0.1,False\n"
                       "2,0.2,0,0.4,0.2,true\n")
    assert read_series(p).data["ok"].tolist() == [1, 0, 1]


def test_missing_values_as_numpy_r_or_a_database_write_them_are_empty(tmp_path):
    """'nan' (numpy.savetxt, MATLAB), 'NA' (R), 'null'/'None' (a database), 'N/A': read as
    an empty cell - theta position-only, x a row not measured; a word is still refused."""
    from curltrack.errors import SeriesError

    p = _csv(tmp_path, "frame,t,x,y,theta,ok\n0,0,0,0,nan,1\n1,0.1,0,0.2,NA,1\n"
                       "2,0.2,NaN,0.4,null,1\n3,0.3,0,0.6,None,1\n4,0.4,0,0.8,N/A,1\n")
    s = read_series(p)
    assert s.data["theta"].isna().all() and not s.theta_measured
    assert s.data["ok"].tolist() == [1, 1, 0, 1, 1]
    p.write_text("frame,t,x,y,theta,ok\n0,0,0,0,0,1\n1,0.1,0,0.2,missing,1\n")
    with pytest.raises(SeriesError, match="non-numeric value 'missing'"):
        read_series(p)


def test_infinite_theta_is_not_a_position_only_row(tmp_path):
    p = _csv(tmp_path, "frame,t,x,y,theta,ok\n0,0,0,0,0,1\n1,0.03,0,0,inf,1\n2,0.06,0,0,,1\n")
    s = read_series(p)
    assert s.data["ok"].tolist() == [1, 0, 1]  # inf: not trusted; empty: position-only
    assert any("infinite theta" in w and "row 3" in w for w in s.warnings)


numbers = st.floats(allow_nan=True, allow_infinity=True, width=32)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(st.tuples(numbers, numbers, numbers, numbers, st.sampled_from([0, 1, 2])),
                min_size=0, max_size=12))
def test_any_table_is_read_or_rejected_cleanly(tmp_path, rows):
    df = pd.DataFrame(rows, columns=["t", "x", "y", "theta", "ok"])
    df.insert(0, "frame", range(len(df)))
    p = tmp_path / "prop.csv"
    df.to_csv(p, index=False)
    try:
        s = read_series(p)
    except SeriesError as exc:
        assert str(p) in str(exc)
        return
    t = s.data["t"].to_numpy()
    assert np.all(np.diff(t) > 0) and np.isfinite(t).all()
    ok = s.data["ok"].to_numpy() == 1
    assert np.isfinite(s.data.loc[ok, ["x", "y"]].to_numpy()).all()
    # theta of a measured row: a number, or empty (a position-only row), never infinite
    assert not np.isinf(s.data.loc[ok, "theta"].to_numpy()).any()


@settings(max_examples=60, deadline=None)
@given(st.dictionaries(st.sampled_from(["spacing_x_m", "spacing_y_m", "depth_m", "colors"]),
                       st.one_of(st.floats(allow_nan=True), st.integers(), st.text(max_size=5),
                                 st.lists(st.text(max_size=8), max_size=3))))
def test_any_grid_table_is_accepted_or_rejected_cleanly(grid):
    from curltrack.rig import rig_from_dict

    data = {"grid": grid, "rock": {"diameter_m": 0.29, "height_m": 0.114},
            "markers": [{"color": "#ff0000", "x_m": 0.08, "y_m": 0.0},
                        {"color": "#00ff00", "x_m": -0.08, "y_m": 0.0}]}
    try:
        rig = rig_from_dict(data)
    except RigError as exc:
        assert exc.where and "\n" not in str(exc)
        return
    assert 0.01 <= rig.spacing_x_m <= 2.0 and 0.01 <= rig.spacing_y_m <= 2.0
