"""``curltrack discover SHOT.csv [SHOT2.csv ...] -o REPORT.json [--baseline paper|dry] [--plot REPORT.png]``."""

from __future__ import annotations

from enum import Enum
from pathlib import Path
from typing import List, Optional

import typer

from ._app import app, check_outputs, guarded


class Baseline(str, Enum):
    paper = "paper"
    dry = "dry"


@app.command()
@guarded
def discover(
    shots: List[Path] = typer.Argument(..., help="SHOT.csv/.parquet files (one session)."),
    output: Path = typer.Option(..., "-o", "--output", help="REPORT.json to write."),
    baseline: Baseline = typer.Option(Baseline.paper, "--baseline",
                                      help="paper (mu = alpha v^phi) or dry (phi = 0)."),
    plot: Optional[Path] = typer.Option(None, "--plot", help="Figure (PNG) to write."),
    seed: int = typer.Option(0, "--seed", help="Seed of the bootstrap."),
    rig: Optional[Path] = typer.Option(None, "--rig",
                                       help="Rig TOML: the rock's R and r (defaults otherwise)."),
    extensions: bool = typer.Option(True, "--extensions/--no-extensions",
                                    help="Also try data-driven extensions of the equations "
                                         "(verdict 'extended')."),
):
    """What the simulation gets wrong in measured shots, its named cause, the extended
    model and its gain (delta-BIC, held-out error, residual tests)."""
    from ..discover import discover as run, write_report
    from ..rig import load_rig
    from ..series import sidecar_path

    from ..errors import InputError
    from ._app import same_file

    for i, a in enumerate(shots):
        twice = next((b for b in shots[:i] if same_file(a, b)), None)
        if twice is not None:
            raise InputError(f"the same shot given twice (also as {twice}): each shot "
                             "would count as two", path=a)
    check_outputs([*shots, *(sidecar_path(p) for p in shots), rig],
                  [("-o", output), ("--plot", plot)])
    report = run([str(p) for p in shots], baseline=baseline.value, seed=seed,
                 rig=load_rig(rig) if rig is not None else None, extensions=extensions)
    write_report(report, output, plot)
    for w in report.get("warnings") or []:
        typer.echo(f"warning: {w}", err=True)
    typer.echo(f"verdict: {report['verdict']}  ({output})")
    limits = report.limits_text() if report["verdict"] == "none" else ""
    if limits:
        typer.echo(f"not seen; below these sizes it could not have been (median over "
                   f"each effect's places, REPORT.json has the range): {limits}")
    if report.get("extension"):
        typer.echo(f"extension: {report['extension']['summary']}")
    if report["verdict"] == "unexplained":   # (why, in the report's words)
        why = next((f.evidence for f in report.findings if f.effect == "unexplained"), "")
        if why:
            typer.echo(f"why: {why}")
