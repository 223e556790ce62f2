"""``curltrack discover`` on files: REPORT.json per the contract, the plot, exit codes."""

import json

import numpy as np
from typer.testing import CliRunner

from curltrack.cli import app
from curltrack.series import write_series
from discover._synth import make_case

runner = CliRunner()


def test_cli_writes_report_and_plot(tmp_path):
    rng = np.random.default_rng(303)
    shots, truth = make_case("pick", float(rng.uniform(0.004, 0.008)), rng)
    csv = tmp_path / "SHOT.csv"
    write_series(csv, shots[0])
    out, png = tmp_path / "REPORT.json", tmp_path / "REPORT.png"
    res = runner.invoke(app, ["discover", str(csv), "-o", str(out), "--plot", str(png)])
    assert res.exit_code == 0, res.output
    rep = json.loads(out.read_text())
    assert rep["verdict"] == "pick"
    assert png.stat().st_size > 10_000
    assert set(rep["baseline"]) >= {"model", "params", "rms", "bic"}
    assert rep["baseline"]["model"] == "paper"
    dbic = [f["delta_bic"] for f in rep["findings"]]
    assert dbic == sorted(dbic, reverse=True)
    for f in rep["findings"]:
        for key in ("effect", "delta_bic", "rms_before", "rms_after", "heldout_rmse_before",
                    "heldout_rmse_after", "params", "params_err", "evidence"):
            assert key in f
        assert isinstance(f["evidence"], str) and f["evidence"]
    top = rep["findings"][0]
    assert top["effect"] == "pick"
    assert set(top["rms_before"]) == {"x", "y", "theta"}
    assert top["rms_after"]["x"] < top["rms_before"]["x"]
    # a named effect lies above the smallest size its threshold lets be seen
    lim = top["detection_limit"]
    assert max(abs(top["params"][p]) / lim[p]["min"] for p in lim) > 1, (lim, top["params"])
    assert not list(tmp_path.glob(".REPORT*"))  # no temporary files left behind


def test_cli_bad_input_is_one_line_exit_1(tmp_path):
    bad = tmp_path / "BAD.csv"
    bad.write_text("frame,t,x,y,theta,ok\n0,0,0,0,0,1\n1,0.03,abc,0,0,1\n")
    out = tmp_path / "R.json"
    res = runner.invoke(app, ["discover", str(bad), "-o", str(out)])
    assert res.exit_code == 1
    assert "BAD.csv" in res.output and "Traceback" not in res.output
    assert not out.exists()
    short = tmp_path / "SHORT.csv"
    short.write_text("frame,t,x,y,theta,ok\n" + "".join(
        f"{i},{i / 30:.4f},0,{0.05 * i:.4f},0,1\n" for i in range(10)))
    res = runner.invoke(app, ["discover", str(short), "-o", str(out)])
    assert res.exit_code == 1 and "SHORT.csv" in res.output
    res = runner.invoke(app, ["discover", str(short), "-o", str(out), "--baseline", "wet"])
    assert res.exit_code == 2
