"""`curltrack fit`: the paper's closed-form fits of one series."""

from __future__ import annotations

from pathlib import Path

import typer

from ..rig import BAND_RADIUS_M, INERTIA_RADIUS_M
from ._app import app, check_outputs, guarded


@app.command()
@guarded
def fit(
    series: Path = typer.Argument(..., help="SHOT.csv or .parquet (sidecar SHOT.json beside it "
                                  "supplies fps and stop times)."),
    output: Path = typer.Option(..., "-o", "--output", help="FIT.json to write."),
    plot: Path = typer.Option(None, "--plot", help="PNG: data, fits and residuals for x, y, θ."),
    rig: Path = typer.Option(None, "--rig", help="Rig TOML for R (inertia_radius_m) and r "
                             f"(band_radius_m); defaults {INERTIA_RADIUS_M} m and "
                             f"{BAND_RADIUS_M} m."),
    fixed_stop: bool = typer.Option(False, "--fixed-stop", help="Hold t_F at the detected stop "
                                    "times (the paper's procedure) instead of fitting it."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="Do not print the summary."),
):
    """Fit θ(t), y(t), x(t) with the paper's formulas and derive φ, α, ω0, v0, C_ω, C_y, x_F.

    Units: t in s, x/y in m, θ in rad (CCW from above), a_T in m/s², α in (m/s)^(−φ).
    Every fitted or derived key k of FIT.json has its 1σ uncertainty as k_err.
    """
    from .._atomic import write_json
    from ..fit import fit_series
    from ..rig import load_rig
    from ..series import read_series, sidecar_path

    check_outputs([series, sidecar_path(series), rig], [("-o", output), ("--plot", plot)])
    s = read_series(series)
    result = fit_series(s, load_rig(rig) if rig else None, fixed_stop=fixed_stop)
    write_json(output, result.summary())
    if plot:
        from ..plots import plot_fit

        plot_fit(s, result, plot)
    if not quiet:
        typer.echo(result.report())
        typer.echo(f"wrote {output}" + (f" and {plot}" if plot else ""))
