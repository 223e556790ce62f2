"""`batch --report` links each fitted shot's review page from the campaign page."""

import numpy as np
import pandas as pd

from curltrack.physics.shot import ShotModel
from curltrack.simulate import simulate_series


def test_campaign_page_links_review_pages(tmp_path):
    from curltrack.batch.report import write_report
    from curltrack.series import write_series

    rng = np.random.default_rng()
    rows = []
    for sid in ("a", "b", "c"):
        rows.append({"shot_id": sid, "file": f"{sid}.mp4", "status": "done",
                     "shot_type": "draw", "omega0": 1.0, "lambda_y": 1.9})
        if sid != "c":  # c: no series on disk (no link, no error)
            sim = simulate_series(ShotModel(v0=rng.uniform(0.8, 1.5), omega0=1.0), fps=30,
                                  noise_m=0.002, noise_rad=0.005, seed=int(rng.integers(1 << 30)))
            write_series(tmp_path / sid / "SHOT.csv", sim)
    rows.append({"shot_id": "z", "file": "z.mp4", "status": "failed", "error": "bad"})
    page = write_report(pd.DataFrame(rows), tmp_path).read_text()
    for sid in ("a", "b"):
        assert f"href='{sid}/REVIEW.html'" in page
        review = (tmp_path / sid / "REVIEW.html").read_text()
        assert '<script src="../report/plotly.min.js">' in review  # one shared copy, offline
        assert "No overlay video" in review
    assert "c/REVIEW.html" not in page and "z/REVIEW.html" not in page
    assert (tmp_path / "report" / "plotly.min.js").stat().st_size > 1_000_000
