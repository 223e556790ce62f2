"""Campaign figures + HTML from a table of simulated fits with known values."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from curltrack.batch.report import FIGURES, campaign_points, write_report


def campaign(rng, n=40, surfaces=("pebbled", "flooded")) -> pd.DataFrame:
    types = rng.choice(["pure_rotation", "rrss", "draw"], n)
    omega0 = rng.choice([-1, 1], n) * rng.uniform(0.5, 20, n)
    rows = []
    for i, (t, w) in enumerate(zip(types, omega0)):
        moving = t != "pure_rotation"
        rows.append({
            "shot_id": f"s{i:02d}", "file": f"s{i:02d}.mp4", "status": "done",
            "error": None, "shot_type": t, "omega0": w, "omega0_err": 0.01,
            "lambda_theta": rng.uniform(1.3, 1.7), "lambda_theta_err": 0.01,
            "lambda_y": rng.uniform(1.7, 2.3) if moving else np.nan,
            "lambda_y_err": 0.02 if moving else np.nan,
            "n_turns": w * 5 / (2 * np.pi),
            "x_F": -np.sign(w) * rng.uniform(0.05, 1.0) if moving else np.nan,
            "a_T": -np.sign(w) * rng.uniform(1e-3, 3e-2),
            "ice_surface": surfaces[i % len(surfaces)] if surfaces else None})
    rows.append({"shot_id": "zz", "file": "zz.mp4", "status": "failed", "error": "<bad> & co"})
    return pd.DataFrame(rows)


@pytest.mark.parametrize("seed, surfaces", [(0, ("pebbled", "flooded")), (1, None)])
def test_points_select_the_right_shots(seed, surfaces):
    t = campaign(np.random.default_rng(seed), surfaces=surfaces)
    pts = campaign_points(t)
    pure = t[t["shot_type"] == "pure_rotation"]
    d = pts["lambda_theta_vs_omega0"]
    assert sorted(d["shot_id"]) == sorted(pure["shot_id"])
    np.testing.assert_allclose(d.sort_values("shot_id")["x"],
                               pure.sort_values("shot_id")["omega0"].abs())
    moving = t[t["shot_type"].isin(["rrss", "draw"])]
    assert sorted(pts["lambda_y_distribution"]["shot_id"]) == sorted(moving["shot_id"])
    curl = pts["curl_vs_turns"]
    assert (curl["y"] > 0).all() and (curl["x"] >= 0).all() and len(curl) == len(moving)
    assert "zz" not in set(pts["a_T_by_type"]["shot_id"])
    assert set(pts["a_T_by_type"]["group"]) == (set(surfaces) if surfaces else {"all"})


def test_report_files(tmp_path):
    t = campaign(np.random.default_rng(2))
    page = write_report(t, tmp_path)
    text = page.read_text()
    for name in FIGURES:
        png = tmp_path / "report" / f"{name}.png"
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert f"report/{name}.png" in text
    assert "&lt;bad&gt; &amp; co" in text and "<bad>" not in text
    # An empty campaign (everything failed) still gives a page, not an error.
    page = write_report(t[t["status"] == "failed"], tmp_path / "empty")
    assert "0 fitted, 1 failed" in page.read_text()
