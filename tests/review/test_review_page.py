"""The review page in a real headless browser (Debian's chromium driven by Playwright):
it opens offline, the overlay video plays, clicking a plot point seeks the video."""

import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from curltrack.physics.shot import ShotModel
from curltrack.rig import default_rig
from curltrack.simulate import simulate_series

ROOT = Path(__file__).resolve().parents[2]
CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"


def _browser():
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.skip("playwright is not installed (pip install playwright; test extras)")
    if not Path(CHROMIUM).exists():
        pytest.skip("no chromium: scripts/test.sh installs Debian's (apt-get install chromium) "
                    "when run as root with apt available")
    return sync_playwright


@pytest.fixture(scope="module")
def page_file(tmp_path_factory):
    from curltrack.render import RenderConfig, render_video
    from curltrack.review import write_review
    from curltrack.series import write_series
    from curltrack.track import track_video

    tmp = tmp_path_factory.mktemp("review")
    seed = int(np.random.SeedSequence().entropy % 2**31)
    rig = default_rig()
    sim = simulate_series(ShotModel(v0=0.5, omega0=1.2, alpha_y=0.03), fps=30)
    render_video(sim, rig, tmp / "v.mp4", config=RenderConfig(width=640, height=360,
                                                              blur_subframes=1), seed=seed)
    series = track_video(tmp / "v.mp4", rig, exclude_frames=[20, 21],
                         overlay_path=tmp / "overlay.mp4")
    write_series(tmp / "shot.csv", series)
    write_review(tmp / "shot.csv", tmp / "page.html", overlay=tmp / "overlay.mp4")
    return tmp / "page.html", series, seed


def test_review_page_in_a_browser(page_file):
    sync_playwright = _browser()
    path, series, seed = page_file
    artifacts = Path(os.environ.get("CURLTRACK_TEST_ARTIFACTS", ROOT / "test-artifacts"))
    artifacts.mkdir(parents=True, exist_ok=True)
    outside = []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox"])
        ctx = browser.new_context(viewport={"width": 1400, "height": 1000}, accept_downloads=True)
        page = ctx.new_page()

        def block(route):  # offline: nothing but the file itself may be fetched
            outside.append(route.request.url)
            route.abort()

        page.route(lambda url: not url.startswith(("file:", "data:", "blob:")), block)
        page.goto(path.as_uri())
        page.wait_for_function("window.reviewState && window.reviewState.ready", timeout=60000)
        # the video decodes and plays (H.264 in Debian's chromium)
        page.wait_for_function("document.getElementById('video').readyState >= 2",
                               timeout=30000)
        assert page.evaluate("document.getElementById('video').videoWidth") == 640
        page.evaluate("document.getElementById('video').play()")
        page.wait_for_function("document.getElementById('video').currentTime > 0.3",
                               timeout=30000)
        page.evaluate("document.getElementById('video').pause()")
        played_to = page.evaluate("window.reviewState.currentFrame")
        assert played_to is not None and played_to > 0  # the plots follow the video
        # click a point of the y(t) plot: the video seeks to that frame
        rng = np.random.default_rng(seed)
        meas = series.measured["frame"].to_numpy()
        k = int(rng.integers(30, len(meas) - 5))
        pts = page.locator("#series .scatterlayer .trace").nth(2).locator("path.point")
        pts.nth(k).scroll_into_view_if_needed()
        box = pts.nth(k).bounding_box()
        cx, cy = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
        page.mouse.move(cx - 3, cy)
        page.mouse.move(cx, cy)
        # plotly clicks the point its hover found: wait for the hover label, as a user would
        page.wait_for_selector("#series .hoverlayer .hovertext", timeout=10000)
        page.mouse.click(cx, cy)
        try:
            page.wait_for_function("window.reviewState.clicks > 0", timeout=10000)
        except Exception:  # (what the click hit, for whoever reads the failure)
            page.screenshot(path=str(artifacts / "review_click_failed.png"))
            raise AssertionError(f"seed {seed}: clicking point {k} of y(t) at {box} "
                                 "did not reach the plot") from None
        page.wait_for_function("!document.getElementById('video').seeking", timeout=10000)
        # (and the sought frame presented: the page follows both the 'seeked' event and
        # the presented frame's media time, which must name the same frame - CI read
        # 59 for 60 once, a presented frame's start a hair before 2 s)
        page.evaluate("new Promise(done => { const v = document.getElementById('video'); "
                      "if ('requestVideoFrameCallback' in v) v.requestVideoFrameCallback(() => "
                      "done()); setTimeout(done, 1000); })")
        state = page.evaluate("window.reviewState")
        t_video = page.evaluate("document.getElementById('video').currentTime")
        # a plotly click picks the nearest point: this one or a neighbour
        assert abs(state["seekFrame"] - meas[k]) <= 1, (state, int(meas[k]), seed)
        f = state["seekFrame"]
        video_frames = [int(v) for v in series.data["frame"] if v not in (20, 21)]
        assert abs(t_video - (video_frames.index(f) + 0.5) / 30.0) < 1e-3
        assert state["currentFrame"] == f
        cursor = page.evaluate("document.getElementById('series').layout.shapes[0].x0")
        t_f = float(series.data.set_index("frame").loc[f, "t"])
        assert abs(cursor - t_f) < 1e-6  # (plotly keeps float32 shapes; frames are >= 16 ms apart)
        # corrections: mark the markers of the shown frame by clicking, then download
        page.click("#mark")
        page.locator("#clicks").scroll_into_view_if_needed()  # (the plot click scrolled)
        box = page.locator("#clicks").bounding_box()
        picks = [(0.25, 0.5), (0.75, 0.4)]
        for fx, fy in picks:
            page.mouse.click(box["x"] + fx * box["width"], box["y"] + fy * box["height"])
        # (the page handles the clicks asynchronously: wait for the second one to land)
        try:
            page.wait_for_function(
                "Object.values(window.reviewState.corrections.frames)"
                ".some(c => c.markers_px && c.markers_px.length >= 2)", timeout=10000)
        except Exception:
            page.screenshot(path=str(artifacts / "review_marks_failed.png"))
            got = page.evaluate("JSON.stringify(window.reviewState.corrections)")
            raise AssertionError(f"seed {seed}: two clicks on the frame at {box} did not "
                                 f"mark two markers: {got}") from None
        marked = page.evaluate("window.reviewState.corrections.frames")
        assert list(marked) == [str(f)], marked
        want = [[fx * 640 - 0.5, fy * 360 - 0.5] for fx, fy in picks]
        np.testing.assert_allclose(marked[str(f)]["markers_px"], want, atol=1.0)
        with page.expect_download() as dl:
            page.click("#download")
        saved = Path(dl.value.path())
        from curltrack.track.corrections import read_corrections

        corr = read_corrections(saved, 2)  # what `track --corrections` reads
        assert list(corr["clicked"]) == [f]
        page.screenshot(path=str(artifacts / "review_page.png"), full_page=False)
        browser.close()
    assert outside == [], f"the page fetched from the network: {outside[:3]}"
