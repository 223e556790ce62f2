"""`curltrack export`: a series with derived columns (velocities and their 1 sigma)."""

from __future__ import annotations

from pathlib import Path

import typer

from ._app import app, check_outputs, guarded


@app.command()
@guarded
def export(
    series: Path = typer.Argument(..., help="SHOT.csv (or .parquet) with its sidecar."),
    output: Path = typer.Option(..., "-o", "--output",
                                help="OUT.csv (or .parquet); its sidecar OUT.json beside it."),
    derivatives: bool = typer.Option(False, "--derivatives",
                                     help="Add vx, vy, speed (m/s), omega (rad/s) and their "
                                     "1 sigma sigma_vx, sigma_vy, sigma_speed, sigma_omega."),
    window_s: float = typer.Option(0.5, "--window-s", min=0.0,
                                   help="Width of the local polynomial fit (s)."),
    order: int = typer.Option(2, "--order", min=1, max=4,
                              help="Degree of the local polynomial."),
):
    """Export a series with derived columns.

    --derivatives: velocities by local polynomial fits (Savitzky-Golay on the real
    times; no window straddles a stop or a long gap), with 1 sigma from the per-frame
    sigmas (or the data's scatter), including the frame-to-frame correlation of tracked
    noise.  Rows with ok = 0 get empty velocities.  The series' units are checked
    first, as by fit and discover (a unit mistake is an error naming the column).
    """
    from ..errors import ParameterError
    from ..export import derivatives as derive
    from ..sanity import check_units
    from ..series import read_series, sidecar_path, write_series

    if not derivatives:
        raise ParameterError("nothing to export: give --derivatives", where="export")
    check_outputs([series, sidecar_path(series)],
                  [("-o", output), ("-o (its sidecar)", sidecar_path(output))])
    s = read_series(series)
    # (velocities of a series in feet or milliseconds would be written as m/s)
    said = check_units(s)
    for w in said:
        typer.echo(f"warning: {w}", err=True)
    data = derive(s, window_s=window_s, order=order)
    meta = dict(s.meta, derivatives={"method": "local polynomial (Savitzky-Golay)",
                                     "window_s": window_s, "order": order,
                                     "source": str(series)})
    meta["warnings"] = [*meta.get("warnings", []), *said]
    side = write_series(output, data, meta)
    n = int(data["vx"].notna().sum())
    typer.echo(f"{n}/{len(data)} rows with velocities; wrote {output} and {side}")
