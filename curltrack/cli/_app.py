"""The typer application and the one place where errors become exit codes."""

from __future__ import annotations

import functools
import os
import sys
from pathlib import Path

import typer

from ..errors import CurltrackError

app = typer.Typer(
    name="curltrack",
    help=("Measure how curling rocks move (Jensen & Shegelski 2004).\n\n"
          "Pipeline: calibrate / track (video -> SHOT.csv) -> fit (FIT.json) / discover "
          "(REPORT.json); simulate and render make synthetic shots with ground truth.\n\n"
          "Units: SI throughout — metres, seconds, radians (theta counter-clockwise seen "
          "from above), m/s, rad/s. Exit status: 0 ok, 1 the input could not be measured "
          "(one line on stderr naming file and frame/field), 2 usage error."),
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


def _plain_flags() -> None:
    """--help: no ``<bool>`` type after plain flags (``--quiet``, ``--help``); typer >= 0.2x
    prints every option's type, which for a flag that takes no value only misleads."""
    from typer.core import TyperOption

    show = getattr(TyperOption, "display_type_rich", None)
    if show is None or getattr(show, "_curltrack", False):
        return

    def display_type_rich(self, ctx):
        return None if self.is_flag and self.metavar is None else show(self, ctx)

    display_type_rich._curltrack = True
    TyperOption.display_type_rich = display_type_rich


_plain_flags()


def fail(message: str, code: int = 1):
    """Print one line to stderr and exit."""
    typer.echo(f"curltrack: error: {message}", err=True)
    raise typer.Exit(code)


def check_outputs(inputs, outputs) -> None:
    """Refuse, before any work, outputs that would destroy an input or each other.

    Parameters
    ----------
    inputs : iterable of path or None
        Files the command reads (include sidecars: a SHOT.csv's SHOT.json is an input).
    outputs : iterable of (option, path or None)
        Files the command writes, each with the option that named it (``"-o"``,
        ``"--overlay"``); derived files (a sidecar) carry their option too.

    Raises
    ------
    CurltrackError
        ``OUT: OPTION: would overwrite the input FILE``, ``OUT: OPTION: is a directory``
        (or a device, FIFO, symbolic-link loop), or
        ``OUT: OPTION: the same file as OTHER``.
    """
    from .._atomic import check_writable

    ins = [Path(p) for p in inputs if p is not None]
    seen: list[tuple[str, Path]] = []
    for option, out in outputs:
        if out is None:
            continue
        out = Path(out)
        for inp in ins:
            if same_file(out, inp):
                raise CurltrackError(f"would overwrite the input {inp}", path=out, where=option)
        try:
            check_writable(out)
        except CurltrackError as exc:
            raise CurltrackError(exc.message, path=out, where=option) from None
        for other_option, other in seen:
            if same_file(out, other):
                raise CurltrackError(f"the same file as {other_option} {other}", path=out,
                                     where=option)
        seen.append((option, out))


def same_file(a: Path, b: Path) -> bool:
    """Same file: one inode (hard or symbolic links) or the same resolved path."""
    try:
        if os.path.samefile(a, b):
            return True
    except OSError:  # one does not exist (yet), or a symbolic-link loop
        pass
    try:
        return a.resolve() == b.resolve()
    except (OSError, RuntimeError):  # a link loop: check_writable names it
        return False


def guarded(func):
    """Decorator for commands: CurltrackError -> one line + exit 1; never a traceback."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        try:
            return func(*args, **kwargs)
        except CurltrackError as exc:
            fail(str(exc))
        except KeyboardInterrupt:
            fail("interrupted", 130)
        except BrokenPipeError:  # stdout's reader stopped early (`| head`): not an error
            stdout_closed()
        except (typer.Exit, typer.Abort, SystemExit):
            raise
        except MemoryError:
            fail("out of memory")
        except Exception as exc:  # an internal bug: still one line, but say it is ours
            if "--debug" in sys.argv or _debug():
                raise
            fail(f"internal error ({type(exc).__name__}: {exc}); rerun with "
                 f"CURLTRACK_DEBUG=1 for a traceback".replace("\n", " "))

    return wrapper


def stdout_closed():
    """The reader of stdout went away (``curltrack ... | head``): outputs are already
    written; leave quietly with status 0 (no traceback, no 'Broken pipe' at exit)."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass
    raise SystemExit(0)


def _debug() -> bool:
    return os.environ.get("CURLTRACK_DEBUG", "") not in ("", "0")


def _version(value: bool):
    if value:
        from .. import __version__

        typer.echo(f"curltrack {__version__}")
        raise typer.Exit()


@app.callback()
def _root(version: bool = typer.Option(False, "--version", callback=_version, is_eager=True,
                                       help="Print the version and exit.")):
    """Measure how curling rocks move (Jensen & Shegelski 2004)."""
