"""Pictures for docs/: a frame of the documented example rig, what `calibrate` finds,
and the review page of that shot (screenshot by Debian's chromium through Playwright).

Usage: python scripts/make_docs_images.py   (writes docs/images/*.png; seeded, ~1 min)
"""

from __future__ import annotations

import re
import sys
import tempfile
from pathlib import Path

import cv2
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from curltrack.calib import calibrate_frame  # noqa: E402
from curltrack.calib.overlay import draw_grid  # noqa: E402
from curltrack.physics.shot import ShotModel  # noqa: E402
from curltrack.render import RenderConfig, render_video  # noqa: E402
from curltrack.rig import load_rig  # noqa: E402
from curltrack.simulate import simulate_series  # noqa: E402
from curltrack.video import read_frame  # noqa: E402


def example_rig_text(doc=ROOT / "docs" / "rig.md") -> str:
    """The TOML of the annotated example in docs/rig.md."""
    return re.search(r"```toml\n(.*?)```", doc.read_text(), re.S).group(1)


def main(out=ROOT / "docs" / "images", frame=20):
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        (tmp / "rig.toml").write_text(example_rig_text())
        rig = load_rig(tmp / "rig.toml")
        sim = simulate_series(ShotModel(v0=0.7, omega0=1.2, alpha_y=0.03), fps=30)
        render_video(sim, rig, tmp / "v.mp4", config=RenderConfig(), seed=11)
        img = read_frame(tmp / "v.mp4", frame)
        cal = calibrate_frame(img, rig)
        for name, im in (("example_frame", img), ("calibrate_overlay", draw_grid(img, cal))):
            small = cv2.resize(im, None, fx=2 / 3, fy=2 / 3, interpolation=cv2.INTER_AREA)
            rgb = Image.fromarray(cv2.cvtColor(small, cv2.COLOR_BGR2RGB))
            rgb.quantize(colors=128).save(out / f"{name}.png", optimize=True)
            print(f"wrote {out / name}.png")
        _review_screenshot(tmp, rig, out / "review_page.png")


def _review_screenshot(tmp, rig, png):
    from playwright.sync_api import sync_playwright

    from curltrack.review import write_review
    from curltrack.series import write_series
    from curltrack.track import track_video

    series = track_video(tmp / "v.mp4", rig, overlay_path=tmp / "overlay.mp4")
    write_series(tmp / "shot.csv", series)
    write_review(tmp / "shot.csv", tmp / "page.html", overlay=tmp / "overlay.mp4")
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path="/usr/bin/chromium", args=["--no-sandbox"])
        page = browser.new_page(viewport={"width": 1300, "height": 1150})
        page.goto((tmp / "page.html").as_uri())
        page.wait_for_function("window.reviewState && window.reviewState.ready")
        page.evaluate("document.getElementById('video').currentTime = 60.5 / 30")
        page.wait_for_function("window.reviewState.currentFrame === 60")
        page.screenshot(path=str(tmp / "shot.png"))
        browser.close()
    Image.open(tmp / "shot.png").convert("RGB").quantize(colors=128).save(png, optimize=True)
    print(f"wrote {png}")


if __name__ == "__main__":
    main()
