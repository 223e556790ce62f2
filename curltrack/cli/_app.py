"""The typer application and the one place where errors become exit codes."""

from __future__ import annotations

import functools
import sys

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


def fail(message: str, code: int = 1):
    """Print one line to stderr and exit."""
    typer.echo(f"curltrack: error: {message}", err=True)
    raise typer.Exit(code)


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


def _debug() -> bool:
    import os

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
