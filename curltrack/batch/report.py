"""Campaign plots like the paper's, and one HTML page (``curltrack batch --report``).

Figures (PNG, in ``OUTDIR/report/``), each split by ice surface when ``shots.csv``
gives one (column ``ice_surface``):

- ``lambda_theta_vs_omega0.png`` — lambda_theta against the initial angular speed
  |omega0| (rad/s) for pure rotations (the paper's Fig. of rotation lambdas);
- ``lambda_y_distribution.png`` — histogram of lambda_y over translating shots;
- ``curl_vs_turns.png`` — curl distance |x_F| (m) against the number of turns |N|;
- ``a_T_by_type.png`` — |a_T| (m/s^2) by shot type and ice surface.

Magnitudes are plotted: signs follow the spin (a counter-clockwise spin curls to -x).
"""

from __future__ import annotations

import html
from pathlib import Path

import numpy as np
import pandas as pd

from .._atomic import atomic_path, write_text

FIGURES = ("lambda_theta_vs_omega0", "lambda_y_distribution", "curl_vs_turns", "a_T_by_type")
SHOT_TYPES = ("pure_rotation", "rrss", "draw")
_SUMMARY_COLS = ("shot_id", "file", "ice_surface", "shot_type", "omega0", "v0",
                 "lambda_theta", "lambda_y", "n_turns", "x_F", "a_T", "t_FS", "t_Ftheta")


def _col(table: pd.DataFrame, name: str) -> pd.Series:
    if name in table.columns:
        return pd.to_numeric(table[name], errors="coerce")
    return pd.Series(np.nan, index=table.index)


def _groups(table: pd.DataFrame) -> pd.Series:
    """Ice surface per row ('all' when not given)."""
    if "ice_surface" in table.columns and table["ice_surface"].notna().any():
        return table["ice_surface"].fillna("unknown").astype(str).replace("", "unknown")
    return pd.Series("all", index=table.index)


def campaign_points(table: pd.DataFrame) -> dict[str, pd.DataFrame]:
    """The data of each figure: finished shots only, magnitudes, ice surface as ``group``.

    Returns
    -------
    dict of DataFrame
        ``lambda_theta_vs_omega0`` (x = |omega0| rad/s, y = lambda_theta),
        ``lambda_y_distribution`` (y = lambda_y), ``curl_vs_turns`` (x = |n_turns|,
        y = |x_F| m), ``a_T_by_type`` (x = shot_type, y = |a_T| m/s^2); each with
        ``x_err``/``y_err`` where known and ``group``.
    """
    done = table[table.get("status", pd.Series("done", index=table.index)) == "done"]
    group = _groups(done)
    stype = done["shot_type"] if "shot_type" in done.columns else pd.Series(None, index=done.index)

    def frame(mask, x, y, x_err=None, y_err=None):
        d = pd.DataFrame({"shot_id": done.get("shot_id"), "x": x, "y": y,
                          "x_err": x_err if x_err is not None else np.nan,
                          "y_err": y_err if y_err is not None else np.nan, "group": group})
        d = d[mask & np.isfinite(d["y"].astype(float))]
        return d.reset_index(drop=True)

    pure = stype == "pure_rotation"
    moving = stype.isin(["rrss", "draw"])
    return {
        "lambda_theta_vs_omega0": frame(pure & np.isfinite(_col(done, "omega0")),
                                        _col(done, "omega0").abs(), _col(done, "lambda_theta"),
                                        _col(done, "omega0_err"), _col(done, "lambda_theta_err")),
        "lambda_y_distribution": frame(moving, np.nan, _col(done, "lambda_y"),
                                       None, _col(done, "lambda_y_err")),
        "curl_vs_turns": frame(moving & np.isfinite(_col(done, "n_turns")),
                               _col(done, "n_turns").abs(), _col(done, "x_F").abs(),
                               _col(done, "n_turns_err"), _col(done, "x_F_err")),
        "a_T_by_type": frame(moving | pure, stype, _col(done, "a_T").abs(), None,
                             _col(done, "a_T_err")),
    }


def _empty(ax, text):
    ax.text(0.5, 0.5, text, ha="center", va="center", transform=ax.transAxes, color="0.4")


def _scatter(ax, d, xlabel, ylabel, empty_text):
    if d.empty:
        _empty(ax, empty_text)
    for name, g in d.groupby("group", sort=True):
        ax.errorbar(g["x"].astype(float), g["y"], xerr=g["x_err"], yerr=g["y_err"], fmt="o",
                    ms=4, capsize=2, label=f"{name} ({len(g)})")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if not d.empty:
        ax.legend(title="ice surface", fontsize=8)


def _plot(name: str, d: pd.DataFrame, ax) -> None:
    if name == "lambda_theta_vs_omega0":
        _scatter(ax, d, r"initial angular speed $|\omega_0|$ (rad/s)", r"$\lambda_\theta$",
                 "no pure-rotation shots")
        ax.set_title(r"Pure rotations: $\lambda_\theta$ vs. initial spin")
    elif name == "lambda_y_distribution":
        if d.empty:
            _empty(ax, "no translating shots")
        else:
            bins = np.histogram_bin_edges(d["y"], bins=min(20, max(5, len(d) // 2)))
            data = [g["y"].to_numpy() for _, g in d.groupby("group", sort=True)]
            labels = [f"{k} ({len(g)})" for k, g in d.groupby("group", sort=True)]
            ax.hist(data, bins=bins, stacked=True, label=labels)
            ax.legend(title="ice surface", fontsize=8)
        ax.set_xlabel(r"$\lambda_y$")
        ax.set_ylabel("shots")
        ax.set_title(r"$\lambda_y$ distribution (RRSS and draws)")
    elif name == "curl_vs_turns":
        _scatter(ax, d, "number of turns |N|", r"curl distance $|x_F|$ (m)",
                 "no translating shots")
        ax.set_title("Curl distance vs. number of turns")
    else:
        if d.empty:
            _empty(ax, "no fitted shots")
        types = [t for t in SHOT_TYPES if t in set(d["x"])]
        groups = sorted(d["group"].unique())
        width = 0.8 / max(1, len(groups))
        rng = np.random.default_rng(0)  # jitter only: fixed so reports are reproducible
        labelled: set = set()
        for j, grp in enumerate(groups):
            for i, t in enumerate(types):
                g = d[(d["x"] == t) & (d["group"] == grp)]
                if g.empty:
                    continue
                pos = i - 0.4 + width * (j + 0.5)
                xs = pos + rng.uniform(-0.3, 0.3, len(g)) * width
                ax.errorbar(xs, g["y"], yerr=g["y_err"], fmt="o", ms=4, capsize=2,
                            color=f"C{j}", label=None if grp in labelled else grp)
                labelled.add(grp)
                ax.hlines(g["y"].mean(), pos - width / 2, pos + width / 2, color=f"C{j}")
        ax.set_xticks(range(len(types)), types)
        ax.set_ylabel(r"$|a_T|$ (m/s$^2$)")
        ax.set_title(r"Transverse acceleration by shot type (bars: means)")
        if types:
            ax.legend(title="ice surface", fontsize=8)


def write_report(table: pd.DataFrame, outdir) -> Path:
    """Write the campaign figures and ``report.html`` into ``outdir``.

    Parameters
    ----------
    table : DataFrame
        The campaign table (:func:`curltrack.batch.table.build_table`).
    outdir : path
        Batch output folder; figures go to ``outdir/report/``.

    Returns
    -------
    Path
        ``outdir/report.html``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    outdir = Path(outdir)
    points = campaign_points(table)
    images = {}
    for name in FIGURES:
        fig, ax = plt.subplots(figsize=(6.4, 4.2), layout="constrained")
        try:
            _plot(name, points[name], ax)
            path = outdir / "report" / f"{name}.png"
            with atomic_path(path) as tmp:
                fig.savefig(tmp, dpi=110)
        finally:
            plt.close(fig)
        images[name] = path.relative_to(outdir).as_posix()
    page = outdir / "report.html"
    write_text(page, _html(table, images, points, _review_pages(table, outdir)))
    return page


def _review_pages(table: pd.DataFrame, outdir: Path) -> dict:
    """``<shot_id>/REVIEW.html`` for every fitted shot (plotly.js shared, in report/)."""
    from ..errors import CurltrackError
    from ..review import write_review

    done = table[table.get("status", pd.Series(dtype=str)) == "done"]
    if "shot_id" not in done or not len(done):
        return {}
    from plotly.offline import get_plotlyjs

    js = outdir / "report" / "plotly.min.js"
    write_text(js, get_plotlyjs())
    pages = {}
    for sid in done["shot_id"].astype(str):
        shot, rep = outdir / sid / "SHOT.csv", outdir / sid / "REPORT.json"
        if not shot.exists():
            continue
        try:
            write_review(shot, outdir / sid / "REVIEW.html",
                         report_path=rep if rep.exists() else None,
                         plotlyjs_src="../report/plotly.min.js")
        except CurltrackError:  # the campaign page still lists the shot, without a link
            continue
        pages[sid] = f"{sid}/REVIEW.html"
    return pages


def _html(table: pd.DataFrame, images: dict, points: dict, reviews: dict | None = None) -> str:
    status = table.get("status", pd.Series(dtype=str))
    n_done, n_failed = int((status == "done").sum()), int((status == "failed").sum())
    done = table[status == "done"]
    cols = [c for c in _SUMMARY_COLS if c in done.columns]
    failed = table[status == "failed"]
    parts = ["<!DOCTYPE html><html><head><meta charset='utf-8'><title>curltrack campaign"
             "</title><style>body{font-family:sans-serif;max-width:1100px;margin:auto}"
             "table{border-collapse:collapse;font-size:13px}td,th{border:1px solid #ccc;"
             "padding:2px 6px}img{max-width:100%}</style></head><body>",
             "<h1>curltrack campaign</h1>",
             f"<p>{len(table)} shot(s): {n_done} fitted, {n_failed} failed. Units: SI (m, s, "
             "rad); magnitudes plotted (signs follow the spin; a counter-clockwise spin "
             "curls to &minus;x). Data: <a href='campaign.csv'>campaign.csv</a>, "
             "<a href='campaign.parquet'>campaign.parquet</a>.</p>"]
    for name, src in images.items():
        parts.append(f"<h2>{html.escape(name.replace('_', ' '))} "
                     f"({len(points[name])} shot(s))</h2><img src='{html.escape(src)}'>")
    if len(done):
        parts.append("<h2>Fitted shots</h2>")
        parts.append(done[cols].to_html(index=False, float_format=lambda v: f"{v:.4g}",
                                        na_rep="", escape=True))
    if reviews:
        parts.append("<h2>Review pages</h2><p>Each shot's series, fit, residuals and "
                     "per-frame quality in the browser: " + ", ".join(
                         f"<a href='{html.escape(src)}'>{html.escape(sid)}</a>"
                         for sid, src in reviews.items()) + "</p>")
    if len(failed):
        parts.append("<h2>Failed shots</h2>")
        parts.append(failed[[c for c in ("shot_id", "file", "error") if c in failed.columns]]
                     .to_html(index=False, escape=True))
    parts.append("</body></html>")
    return "\n".join(parts) + "\n"
