"""One self-contained HTML page to check a tracked shot in a browser (``curltrack review``).

The page needs no server and no network: plotly.js is inlined from the ``plotly``
package and the overlay video (H.264) is embedded as base64.  Plots of x, y, theta
against t (with the paper's fit and its residuals), per-frame quality and sigma, the
discovery findings (the effect's stretch or instant shaded) and every warning on top.
Clicking a point seeks the video to that frame; playing the video moves a cursor over
the plots.  The page's state (``window.reviewState``) says which frame is shown.
"""

from __future__ import annotations

from .page import build_page, write_review

__all__ = ["build_page", "write_review"]
