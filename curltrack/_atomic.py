"""Atomic file output: a killed run never leaves a half file under the final name."""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from pathlib import Path

from .errors import CurltrackError


def check_writable(path) -> None:
    """Raise :class:`CurltrackError` naming ``path`` when it cannot be an output file.

    Only what can be told before writing: ``path`` is an existing directory.
    """
    path = Path(path)
    if path.is_dir():
        raise CurltrackError("is a directory", path=path)
    for parent in path.parents:
        if parent.exists():
            if not parent.is_dir():
                raise CurltrackError(f"{parent} is not a directory", path=path)
            break


@contextlib.contextmanager
def atomic_path(path, suffix: str | None = None):
    """Yield a temporary path beside ``path``; rename it onto ``path`` on success.

    The temporary file keeps ``path``'s suffix (or ``suffix``) so that writers that
    choose a format by extension (OpenCV, matplotlib, pyarrow) still work.

    Raises
    ------
    CurltrackError
        Naming ``path``: it is a directory, or its folder cannot be made or written to.
    """
    path = Path(path)
    check_writable(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=suffix or path.suffix,
                                   dir=path.parent)
    except OSError as exc:
        raise CurltrackError(f"cannot write here ({exc.strerror})", path=path) from None
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; outputs get the usual mode
        try:
            os.replace(tmp, path)
        except OSError as exc:  # e.g. a directory made under the name while we wrote
            raise CurltrackError(f"cannot write ({exc.strerror})", path=path) from None
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_text(path, text: str) -> None:
    """Write ``text`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(text)


def _json_default(obj):
    import numpy as np

    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def _finite_or_none(obj):
    """Replace NaN/inf by None recursively (JSON has no NaN)."""
    import math

    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, dict):
        return {k: _finite_or_none(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite_or_none(v) for v in obj]
    return obj


def write_json(path, data) -> None:
    """Write ``data`` as indented JSON atomically; NaN/inf become null."""
    text = json.dumps(_finite_or_none(json.loads(json.dumps(data, default=_json_default))),
                      indent=2, allow_nan=False)
    write_text(path, text + "\n")
