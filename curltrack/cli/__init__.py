"""Command-line shell: one module per command (``curltrack/cli/<command>.py``).

Each module registers its command on :data:`app` with ``@app.command()`` and keeps
itself thin: parse, call the library, write outputs.  Modules are discovered here so
that adding a stage needs no edit to this file.
"""

from __future__ import annotations

import importlib
import pkgutil

from ._app import app, stdout_closed

for _mod in sorted(m.name for m in pkgutil.iter_modules(__path__) if not m.name.startswith("_")):
    importlib.import_module(f"{__name__}.{_mod}")


def main():  # console-script entry point
    try:
        app()
    except BrokenPipeError:  # --help or a summary piped into `head`
        stdout_closed()


__all__ = ["app", "main"]
