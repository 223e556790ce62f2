"""Matplotlib figures shared by the commands (Agg backend, written atomically)."""

from __future__ import annotations

import numpy as np

from ._atomic import atomic_path


def _figure(nrows, ncols, **kw):
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt.subplots(nrows, ncols, **kw)


def save(fig, path) -> None:
    """Save a figure atomically and close it."""
    import matplotlib.pyplot as plt

    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)


def plot_fit(series, result, path) -> None:
    """Data, fit and residuals for x, y and theta, as in the paper's figures.

    x is shown deskewed, with the curl fits for lambda = lambda_y (solid) and lambda free
    (dashed); residuals in mm and degrees below each panel.
    """
    from .fit import _theta_model, _xy_model, deskew

    d = series.measured
    d = d[d["t"] >= 0]
    t = d["t"].to_numpy(float)
    fig, axes = _figure(2, 3, figsize=(13, 6.5), sharex="col",
                        gridspec_kw={"height_ratios": [3, 1]})
    tt = np.linspace(0, t.max(), 800)
    panels = [("x", "x (m)", 1e3, "mm"), ("y", "y (m)", 1e3, "mm"),
              ("theta", "θ (rad)", 180 / np.pi, "deg")]
    for j, (col, label, scale, unit) in enumerate(panels):
        ax, axr = axes[0, j], axes[1, j]
        ax.set_ylabel(label)
        axr.set_ylabel(f"residual ({unit})")
        axr.set_xlabel("t (s)")
        axr.axhline(0, color="k", lw=0.6)
        q = d[col].to_numpy(float)
        if col in "xy" and "xy" in result.fits:
            q = deskew(result.fits["xy"].params.valuesdict(), d["x"], d["y"])["xy".index(col)]
            ax.set_ylabel(f"{label[0]} deskewed (m)")
        fits = []
        if col == "theta" and "theta" in result.fits:
            p = result.fits["theta"].params.valuesdict()
            fits = [(_theta_model(p, tt), _theta_model(p, t), "-",
                     f"λθ = {p['lambda_theta']:.3f}")]
        elif col in "xy" and "xy" in result.fits:
            k = "xy".index(col)
            frame = result.fits["xy"].params.valuesdict()  # the points' deskew frame
            for name, style in (("xy", "-"), ("xy_free", "--")):
                if name not in result.fits:  # the lambda-free fit may have failed
                    continue
                p = result.fits[name].params.valuesdict()
                lam = p.get("lambda_x", p["lambda_y"])
                lbl = f"λ = {lam:.3f}" + (" (free)" if name == "xy_free" else " (λy)")
                if col == "y":
                    lbl = f"λy = {p['lambda_y']:.3f}"
                # each fit's model in measured coordinates, then in the points' frame:
                # the lambda-free fit has its own psi, x0, y0
                fits.append((deskew(frame, *_xy_model(p, tt))[k],
                             deskew(frame, *_xy_model(p, t))[k], style, lbl))
                if col == "y":
                    break
        ax.plot(t, q, ".", ms=2.5, color="0.35", label="data")
        for curve, at_data, style, lbl in fits:
            ax.plot(tt, curve, style, color="C3" if style == "-" else "C0", lw=1.3, label=lbl)
            axr.plot(t, (q - at_data) * scale, ".", ms=2, color="C3" if style == "-" else "C0")
        ax.legend(fontsize=8, loc="best")
    v = result.values
    fig.suptitle(f"{series.name} — {v.get('shot_type')}", fontsize=10)
    fig.tight_layout()
    save(fig, path)
