"""`curltrack fit` from the command line: outputs, exit codes, one-line errors."""

import json
import subprocess
import sys

import numpy as np
import pytest
from typer.testing import CliRunner

from curltrack.cli import app
from curltrack.fit import FIT_KEYS
from curltrack.series import write_series
from synth import closed_form_series

runner = CliRunner()


@pytest.fixture(scope="module")
def shot(tmp_path_factory):
    p = tmp_path_factory.mktemp("fit") / "shot.csv"
    write_series(p, closed_form_series(noise_m=0.002, noise_rad=np.radians(0.3), seed=4))
    return p


def test_fit_writes_contract_json_and_plot(shot, tmp_path):
    out, png = tmp_path / "fit.json", tmp_path / "fit.png"
    res = runner.invoke(app, ["fit", str(shot), "-o", str(out), "--plot", str(png), "-q"])
    assert res.exit_code == 0, res.output
    d = json.loads(out.read_text())
    for k in FIT_KEYS:
        assert k in d
    for k in ("lambda_theta", "lambda_y", "a_T", "phi_y", "alpha_y", "v0", "x_F", "C_omega"):
        assert d[f"{k}_err"] > 0
    assert d["lambda_y"] == pytest.approx(1.897, abs=0.01)
    assert d["t_FS_detected"] == 24.0
    assert png.stat().st_size > 20_000


def test_fit_without_sidecar_detects_stops_or_says_why(shot, tmp_path):
    lone = tmp_path / "lone.csv"
    lone.write_text(shot.read_text())
    out = tmp_path / "fit.json"
    res = runner.invoke(app, ["fit", str(lone), "-o", str(out), "-q"])
    if res.exit_code == 0:
        d = json.loads(out.read_text())
        assert any("stops detected" in w for w in d["warnings"])
        assert d["t_FS"] == pytest.approx(24.0, abs=2 / 30)
    else:  # stop detector not importable: still a clean one-line failure
        assert res.exit_code == 1 and "Traceback" not in res.output


@pytest.mark.parametrize("text, needle", [
    ("frame,t,x,y,ok\n0,0,0,0,1\n", "missing column"),
    ("frame,t,x,y,theta,ok\n0,0,0,0,0,1\n1,0.03,zz,0,0,1\n", "row 3"),
    ("frame,t,x,y,theta,ok\n0,0,0,0,0,1\n1,0.03,0,0,0,1\n", "too few"),
])
def test_bad_input_exit_1_one_line(tmp_path, text, needle):
    bad = tmp_path / "bad.csv"
    bad.write_text(text)
    (tmp_path / "bad.json").write_text('{"t_stop_translation": 1.0, "t_stop_rotation": 1.0}')
    out = tmp_path / "fit.json"
    proc = subprocess.run([sys.executable, "-m", "curltrack.cli", "fit", str(bad), "-o", str(out)],
                          capture_output=True, text=True)
    assert proc.returncode == 1
    err = proc.stderr.strip()
    assert len(err.splitlines()) == 1 and str(bad) in err and needle in err
    assert not out.exists()


def test_usage_error_is_exit_2(tmp_path):
    res = runner.invoke(app, ["fit", str(tmp_path / "x.csv")])  # no -o
    assert res.exit_code == 2
