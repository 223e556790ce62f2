"""Progress bars (rich) on stderr for the long steps; silent when stderr is not a terminal."""

from __future__ import annotations

import contextlib
import sys

__all__ = ["progress_bar"]


@contextlib.contextmanager
def progress_bar(label: str, total: int | None, enabled: bool | None = None):
    """Yield ``advance(n=1)``: a transient rich bar on stderr, or a no-op.

    Parameters
    ----------
    label : str
        What is being counted (``"render"``, ``"overlay"``, ``"discover: candidates"``).
    total : int or None
        Steps expected (None: unknown).
    enabled : bool, optional
        Default: only when stderr is a terminal (never in pipes, logs or tests).
    """
    if enabled is None:
        enabled = sys.stderr.isatty()
    if not enabled:
        yield lambda n=1: None
        return
    from rich.console import Console
    from rich.progress import (BarColumn, MofNCompleteColumn, Progress, TextColumn,
                               TimeElapsedColumn, TimeRemainingColumn)

    bar = Progress(TextColumn(label), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                   TimeRemainingColumn(), transient=True, console=Console(stderr=True))
    task = bar.add_task(label, total=total)
    with bar:
        yield lambda n=1: bar.advance(task, n)
