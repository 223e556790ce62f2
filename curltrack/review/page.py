"""The review page: figures (plotly), the embedded overlay video and the glue between them."""

from __future__ import annotations

import base64
import html
import json
from pathlib import Path

import numpy as np

from ..series import Series
from ..discover.results import format_limits

__all__ = ["build_page", "write_review", "video_frame_count"]

_SHADE = "rgba(255, 140, 0, 0.18)"


def video_frame_count(path) -> tuple[int, float]:
    """(frames, frames/s) of an mp4, from its container (PyAV)."""
    import av

    with av.open(str(path)) as c:
        s = c.streams.video[0]
        n = s.frames or sum(1 for _ in c.demux(s) if _.size)
        return int(n), float(s.average_rate or s.guessed_rate)


def _fit_curves(series: Series, fit):
    """Model curves on a fine grid and at the data, from a FitResult (or None)."""
    from ..fit import _theta_model, _xy_model

    d = series.measured
    t = d["t"].to_numpy(float)
    tt = np.linspace(0.0, float(t.max()) if len(t) else 1.0, 600)
    out = {}
    if fit is None:
        return tt, out
    if "xy" in fit.fits:
        p = fit.fits["xy"].params.valuesdict()
        out["x"], out["y"] = ((cx, cd) for cx, cd in zip(_xy_model(p, tt), _xy_model(p, t)))
    if "theta" in fit.fits:
        p = fit.fits["theta"].params.valuesdict()
        out["theta"] = (_theta_model(p, tt), _theta_model(p, t))
    return tt, out


def _marks(series: Series, report) -> tuple[list[dict], list[str]]:
    """Plotly shapes for the discovery findings (a patch's stretch, a pick's instant)."""
    if not report:
        return [], []
    shapes, notes = [], []
    d = series.measured
    t, y = d["t"].to_numpy(float), d["y"].to_numpy(float)
    for f in report.get("findings", []):
        named = f.get("supported") or f.get("effect") == report.get("verdict")
        p = f.get("params") or {}
        if not named:
            continue
        if f["effect"] == "friction_patch" and {"y_start_m", "y_end_m"} <= set(p):
            inside = t[(y >= min(p["y_start_m"], p["y_end_m"]))
                       & (y <= max(p["y_start_m"], p["y_end_m"]))]
            if inside.size:
                shapes.append(dict(type="rect", xref="x", yref="paper", x0=inside.min(),
                                   x1=inside.max(), y0=0, y1=1, fillcolor=_SHADE, line_width=0,
                                   layer="below"))
                notes.append(f"friction_patch: y {p['y_start_m']:.2f}-{p['y_end_m']:.2f} m "
                             f"(t {inside.min():.2f}-{inside.max():.2f} s, shaded)")
        elif f["effect"] == "pick" and "t_s" in p:
            shapes.append(dict(type="line", xref="x", yref="paper", x0=p["t_s"], x1=p["t_s"],
                               y0=0, y1=1, line=dict(color="darkorange", width=2, dash="dash")))
            notes.append(f"pick at t = {p['t_s']:.3f} s (dashed line)")
    return shapes, notes


def _figures(series: Series, fit, report):
    """(name, plotly Figure) for the series, the residuals and the per-frame quality."""
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    d = series.data
    meas = series.measured
    frames = meas["frame"].to_numpy(int)
    t = meas["t"].to_numpy(float)
    tt, curves = _fit_curves(series, fit)
    marks, _ = _marks(series, report)
    cursor = dict(type="line", xref="x", yref="paper", x0=0, x1=0, y0=0, y1=1,
                  line=dict(color="red", width=1.5))
    scale = {"x": (1.0, "x (m)", 1e3, "mm"), "y": (1.0, "y (m)", 1e3, "mm"),
             "theta": (1.0, "θ (rad)", np.degrees(1.0), "deg")}
    hover = "frame %{customdata}<br>t %{x:.3f} s<br>%{y:.5f}<extra></extra>"

    def base(rows, titles, height):
        fig = make_subplots(rows=rows, cols=1, shared_xaxes=True, vertical_spacing=0.04,
                            subplot_titles=titles)
        fig.update_layout(height=height, margin=dict(l=60, r=20, t=30, b=40),
                          shapes=[cursor, *marks], hovermode="closest", clickmode="event",
                          showlegend=False)
        fig.update_xaxes(title_text="t (s)", row=rows, col=1)
        return fig

    series_fig = base(3, ["x (m)", "y (m)", "θ (rad)"], 720)
    resid_fig = base(3, ["x − fit (mm)", "y − fit (mm)", "θ − fit (deg)"], 540)
    for i, c in enumerate(("x", "y", "theta"), start=1):
        q = meas[c].to_numpy(float)
        series_fig.add_trace(go.Scatter(x=t, y=q, mode="markers", customdata=frames,
                                          marker=dict(size=4, color="#444"), name=c,
                                          hovertemplate=hover), row=i, col=1)
        if c in curves:
            fine, at_data = curves[c]
            series_fig.add_trace(go.Scatter(x=tt, y=fine, mode="lines", hoverinfo="skip",
                                            line=dict(color="#d62728", width=1.5),
                                            name=f"{c} fit"), row=i, col=1)
            r = (q - at_data) * scale[c][2]
            resid_fig.add_trace(go.Scatter(x=t, y=r, mode="markers", customdata=frames,
                                             marker=dict(size=4, color="#1f77b4"),
                                             hovertemplate=hover.replace(":.5f", ":.2f")),
                                row=i, col=1)
    q_fig = base(3, ["quality (0-1); ok = 0 frames in red", "σ_xy (mm)", "σ_θ (deg)"], 540)
    all_frames = d["frame"].to_numpy(int)
    lost = d["ok"].to_numpy() == 0
    for i, (col, k) in enumerate((("quality", 1.0), ("sigma_xy", 1e3),
                                  ("sigma_theta", np.degrees(1.0))), start=1):
        if col in d:
            q_fig.add_trace(go.Scatter(x=d["t"], y=d[col] * k, mode="markers",
                                         customdata=all_frames, marker=dict(size=4),
                                         hovertemplate=hover.replace(":.5f", ":.3f")),
                            row=i, col=1)
    if lost.any():
        q_fig.add_trace(go.Scatter(x=d["t"][lost], y=np.zeros(lost.sum()), mode="markers",
                                     customdata=all_frames[lost],
                                     marker=dict(size=7, color="red", symbol="x"),
                                     hovertemplate="frame %{customdata}: ok = 0<extra></extra>"),
                        row=1, col=1)
    return [("series", series_fig), ("residuals", resid_fig), ("quality", q_fig)]


def _table(rows) -> str:
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r) + "</tr>"
                   for r in rows)
    return f"<table>{body}</table>"


def _fit_table(fit) -> str:
    if fit is None:
        return "<p>No fit (see the warnings).</p>"
    rows = []
    for k, v in fit.values.items():
        if v is None:
            continue
        e = fit.errors.get(k)
        if isinstance(v, str):
            rows.append((k, v, ""))
        else:
            rows.append((k, f"{v:.6g}", "" if e is None else f"± {e:.2g}"))
    return _table(rows)


def _report_html(report, notes) -> str:
    if not report:
        return "<p>No discovery report given (<code>--report REPORT.json</code>).</p>"
    rows = [(f.get("effect"), f"{f.get('delta_bic', float('nan')):.1f}",
             "named" if f.get("supported") else "",
             ", ".join(f"{k} = {v:.4g}" for k, v in (f.get("params") or {}).items()
                       if isinstance(v, (int, float))),
             format_limits(f.get("detection_limit")),
             f.get("evidence", "")) for f in report.get("findings", [])]
    head = f"<p><b>verdict: {html.escape(str(report.get('verdict')))}</b></p>"
    marks = "".join(f"<li>{html.escape(n)}</li>" for n in notes)
    return head + (f"<ul>{marks}</ul>" if marks else "") + _table(
        [("effect", "ΔBIC", "", "parameters", "not seeable below (median over places)",
          "evidence"), *rows])


_JS = """
const R = REVIEW;
const video = document.getElementById('video');
const plots = ['series', 'residuals', 'quality'].map(id => document.getElementById(id));
const pos = new Map(R.video_frames.map((f, i) => [f, i]));
const row = new Map(R.rows.frame.map((f, i) => [f, i]));
window.reviewState = {seekFrame: null, currentFrame: null, clicks: 0, ready: false};
function timeOfFrame(f) {
  let p = pos.get(f);
  if (p === undefined) p = Math.max(0, Math.min(R.video_frames.length - 1, f - R.video_frames[0]));
  return (p + 0.5) / R.fps;
}
function frameAt(tv) {
  // (a presented frame's media time is its start, which the container's time base can
  // put a hair before it: 1.99999 s for frame 60 at 30 fps was read as frame 59)
  const p = Math.max(0, Math.min(R.video_frames.length - 1, Math.floor(tv * R.fps + 0.01)));
  return R.video_frames[p];
}
function show(f) {
  // (moving the cursor redraws the plots and drops their hover, which a click needs:
  // only move it when the frame changes)
  if (f === window.reviewState.currentFrame) return;
  const i = row.get(f);
  window.reviewState.currentFrame = f;
  const box = document.getElementById('frameinfo');
  if (i === undefined) { box.textContent = 'frame ' + f; return; }
  const r = R.rows, fmt = (v, k, d) => (v === null ? '-' : (v * k).toFixed(d));
  box.textContent = 'frame ' + f + '   t ' + fmt(r.t[i], 1, 3) + ' s   x ' + fmt(r.x[i], 1, 4) +
    ' m   y ' + fmt(r.y[i], 1, 4) + ' m   θ ' + fmt(r.theta[i], 57.29577951308232, 2) +
    ' deg   ok ' + r.ok[i] + (r.quality ? '   quality ' + fmt(r.quality[i], 1, 2) : '') +
    (r.sigma_xy ? '   σxy ' + fmt(r.sigma_xy[i], 1000, 2) + ' mm' : '');
  const t = r.t[i];
  for (const p of plots) Plotly.relayout(p, {'shapes[0].x0': t, 'shapes[0].x1': t});
}
function seek(f) {
  window.reviewState.seekFrame = f;
  window.reviewState.clicks += 1;
  if (video) { video.pause(); video.currentTime = timeOfFrame(f); }
  show(f);
}
for (const p of plots) p.on('plotly_click', ev => {
  if (ev.points.length && ev.points[0].customdata !== undefined) seek(Number(ev.points[0].customdata));
});
if (video) {
  const follow = () => show(frameAt(video.currentTime));
  video.addEventListener('seeked', follow);
  video.addEventListener('timeupdate', follow);
  if ('requestVideoFrameCallback' in video) {
    const loop = (now, md) => { show(frameAt(md.mediaTime)); video.requestVideoFrameCallback(loop); };
    video.requestVideoFrameCallback(loop);
  }
}
// corrections: click the rock's markers on the shown frame (in the rig's order)
const corr = {click_sigma_px: 1.0, frames: {}};
window.reviewState.corrections = corr;
const canvas = document.getElementById('clicks');
let marking = null;
function place() {
  if (!video || !canvas) return;
  canvas.width = video.clientWidth; canvas.height = video.clientHeight;
  canvas.style.width = video.clientWidth + 'px'; canvas.style.height = video.clientHeight + 'px';
}
function markStatus(text) { document.getElementById('markstatus').textContent = text; }
function startMarking() {
  if (!video) return;
  video.pause(); place();
  const f = frameAt(video.currentTime);
  marking = {frame: f, px: []};
  canvas.style.display = 'block';
  canvas.getContext('2d').clearRect(0, 0, canvas.width, canvas.height);
  markStatus('frame ' + f + ': click marker ' + R.markers[0] + ' (1 of ' + R.markers.length + ')');
}
if (canvas) canvas.addEventListener('click', ev => {
  if (!marking) return;
  const r = canvas.getBoundingClientRect();
  const sx = video.videoWidth / r.width, sy = video.videoHeight / r.height;
  const u = (ev.clientX - r.left) * sx - 0.5, v = (ev.clientY - r.top) * sy - 0.5;
  marking.px.push([u, v]);
  const g = canvas.getContext('2d');
  g.strokeStyle = '#ff0'; g.lineWidth = 2; g.beginPath();
  g.arc(ev.clientX - r.left, ev.clientY - r.top, 6, 0, 2 * Math.PI); g.stroke();
  const k = marking.px.length;
  if (k < R.markers.length) {
    markStatus('frame ' + marking.frame + ': click marker ' + R.markers[k] + ' (' + (k + 1) +
               ' of ' + R.markers.length + ')');
    return;
  }
  corr.frames[String(marking.frame)] = {markers_px: marking.px};
  markStatus('frame ' + marking.frame + ' marked; ' + Object.keys(corr.frames).length +
             ' frame(s) in the corrections');
  marking = null; canvas.style.display = 'none';
});
function excludeFrame() {
  if (!video) return;
  const f = frameAt(video.currentTime);
  corr.frames[String(f)] = {exclude: true};
  markStatus('frame ' + f + ' excluded; ' + Object.keys(corr.frames).length + ' frame(s) in the corrections');
}
function downloadCorrections() {
  const blob = new Blob([JSON.stringify(corr, null, 1)], {type: 'application/json'});
  const a = document.createElement('a');
  a.href = URL.createObjectURL(blob); a.download = 'corrections.json'; a.click();
}
window.reviewState.ready = true;
"""

_CSS = """
body { font-family: system-ui, sans-serif; margin: 12px 20px; color: #222; }
.warn { background: #fff3cd; border: 1px solid #e0c060; padding: 6px 12px; margin: 6px 0; }
.warn li { margin: 2px 0; }
#fit { max-height: 420px; overflow-y: auto; }
#top { display: flex; gap: 16px; align-items: flex-start; flex-wrap: wrap; }
video { max-width: 100%; width: 720px; background: #000; }
#videobox { position: relative; display: inline-block; }
#clicks { position: absolute; left: 0; top: 0; display: none; cursor: crosshair; }
#frameinfo { font-family: monospace; margin: 4px 0 10px; white-space: pre; }
table { border-collapse: collapse; font-size: 13px; }
td { border: 1px solid #ccc; padding: 2px 6px; }
h2 { margin: 18px 0 4px; font-size: 18px; }
"""


def build_page(series: Series, fit=None, report=None, video_mp4: bytes | None = None,
               video_frames=None, fps: float | None = None, warnings=(), notes=(),
               title: str | None = None, plotlyjs_src: str | None = None,
               markers=("m0", "m1")) -> str:
    """The review page as one HTML string (plotly.js and the video inlined).

    Parameters
    ----------
    series : Series
        The tracked series with its sidecar.
    fit : FitResult or None
        The paper's fit of the series (curves and residuals).
    report : dict or None
        A REPORT.json mapping (findings, verdict).
    video_mp4 : bytes or None
        The overlay video (H.264 mp4).
    video_frames : sequence of int
        The video frame index of each overlay frame, in order.
    fps : float
        The overlay's frame rate (frames/s).
    warnings, notes : sequence of str
        Shown on top / under the title.
    markers : sequence of str
        Names of the rig's markers, in order (the corrections' clicks follow it).
    plotlyjs_src : str, optional
        A relative URL of plotly.min.js shared by several pages (``batch --report``);
        default: inlined.
    """
    import plotly.io as pio
    from plotly.offline import get_plotlyjs

    d = series.data
    title = title or series.name
    figs = _figures(series, fit, report)
    _, mark_notes = _marks(series, report)

    def col(c):
        if c not in d:
            return None
        v = d[c].to_numpy(float)
        return [None if not np.isfinite(x) else float(x) for x in v]

    data = {"fps": float(fps or series.meta.get("fps") or 30.0), "markers": list(markers),
            "video_frames": [int(f) for f in (video_frames if video_frames is not None
                                              else d["frame"])],
            "rows": {"frame": [int(f) for f in d["frame"]], "ok": [int(v) for v in d["ok"]],
                     **{c: col(c) for c in ("t", "x", "y", "theta", "quality", "sigma_xy")}}}
    divs = "\n".join(f'<h2>{name}</h2>' + pio.to_html(fig, include_plotlyjs=False,
                                                       full_html=False, div_id=name,
                                                       config={"displaylogo": False})
                     for name, fig in figs)
    warn = "".join(f"<li>{html.escape(w)}</li>" for w in warnings)
    warn_html = (f'<div class="warn" id="warnings"><b>{len(warnings)} warning(s)</b><ul>{warn}'
                 "</ul></div>") if warnings else '<div id="warnings"></div>'
    if video_mp4:
        b64 = base64.b64encode(video_mp4).decode("ascii")
        video_html = (f'<div id="videobox"><video id="video" controls muted preload="auto" '
                      f'playsinline src="data:video/mp4;base64,{b64}"></video>'
                      '<canvas id="clicks"></canvas></div><div><button id="mark" '
                      'onclick="startMarking()">mark the markers on this frame</button> '
                      '<button id="exclude" onclick="excludeFrame()">exclude this frame'
                      '</button> <button id="download" onclick="downloadCorrections()">'
                      'download corrections.json</button> <span id="markstatus"></span>'
                      '</div>')
    else:
        video_html = '<p id="novideo">No overlay video (give <code>--overlay OUT.mp4</code>).</p>'
    note_html = "".join(f"<p>{html.escape(n)}</p>" for n in notes)
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)} - curltrack review</title>
<style>{_CSS}</style>
{f'<script src="{html.escape(plotlyjs_src)}"></script>' if plotlyjs_src
 else f"<script>{get_plotlyjs()}</script>"}
</head><body>
<h1>{html.escape(title)}</h1>
{warn_html}
{note_html}
<div id="top"><div>{video_html}<div id="frameinfo">click a point of a plot: the video
shows that frame</div></div>
<div><h2>fit (FIT.json)</h2><div id="fit">{_fit_table(fit)}</div></div></div>
{divs}
<h2>discovery</h2>{_report_html(report, mark_notes)}
<script>const REVIEW = {json.dumps(data)};
{_JS}</script>
</body></html>
"""


def write_review(series_path, out_path, overlay=None, report_path=None, rig=None,
                 plotlyjs_src=None) -> list[str]:
    """Read a SHOT.csv (and its overlay video, REPORT.json), fit it, write the page.

    Returns the warnings shown on the page.
    """
    from .._atomic import write_text
    from ..errors import CurltrackError
    from ..fit import fit_series
    from ..series import read_series

    series = read_series(series_path)
    warnings = list(series.meta.get("warnings", []))
    notes = []
    fit = None
    try:
        fit = fit_series(series, rig)
        warnings += [w for w in fit.warnings if w not in warnings]
    except CurltrackError as exc:
        warnings.append(f"fit: {exc}")
    report = None
    if report_path is not None:
        try:
            report = json.loads(Path(report_path).read_text())
        except (OSError, ValueError) as exc:
            raise CurltrackError(f"cannot read the report ({exc})", path=report_path) from None
        warnings += [w for w in report.get("warnings", []) if w not in warnings]
    mp4 = frames = fps = None
    if overlay is None and series.meta.get("overlay"):
        cand = [Path(series.meta["overlay"]), Path(series_path).parent / series.meta["overlay"]]
        overlay = next((c for c in cand if c.exists()), None)
        if overlay is None:
            warnings.append(f"the overlay video {series.meta['overlay']} named in the sidecar "
                            "was not found")
    if overlay is not None:
        n, fps = video_frame_count(overlay)
        mp4 = Path(overlay).read_bytes()
        frames = _overlay_frames(series, n)
        if frames is None:
            frames = list(range(int(series.meta.get("start_frame") or 0),
                                int(series.meta.get("start_frame") or 0) + n))
            warnings.append(f"{overlay}: {n} frames but the series has "
                            f"{len(series.data)} rows; plot points are mapped to video "
                            "frames by their index from the start frame")
        notes.append(f"overlay video: {overlay} ({n} frames at {fps:.3f} fps)")
    if rig is None and series.meta.get("rig"):
        from ..rig import load_rig

        try:
            rig = load_rig(series.meta["rig"])
        except CurltrackError:
            notes.append(f"the rig {series.meta['rig']} named in the sidecar cannot be read: "
                         "marker names for corrections are m0, m1, ...")
    names = [f"m{i} ({m.color})" for i, m in enumerate(rig.markers)] if rig else ["m0", "m1"]
    write_text(out_path, build_page(series, fit, report, mp4, frames, fps, warnings, notes,
                                    plotlyjs_src=plotlyjs_src, markers=names))
    return warnings


def _overlay_frames(series: Series, n: int):
    """Video frame of each overlay frame: the series' rows, less the frames the user
    excluded (the overlay skips them); None when the counts do not agree."""
    frames = series.data["frame"].to_numpy(int)
    if len(frames) == n:
        return [int(f) for f in frames]
    excluded = set()
    for w in series.meta.get("warnings", []):
        if "excluded by the user" in w and "frame(s) " in w:
            for part in w.split("frame(s) ", 1)[1].split(":", 1)[0].split(","):
                a, _, b = part.strip().partition("-")
                if not (a.isdigit() and (b.isdigit() or not b)):
                    return None  # an unexpected wording: the caller maps by index
                excluded |= set(range(int(a), int(b or a) + 1))
    kept = [int(f) for f in frames if f not in excluded]
    return kept if len(kept) == n else None
