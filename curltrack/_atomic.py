"""Atomic file output: a killed run never leaves a half file under the final name."""

from __future__ import annotations

import contextlib
import errno
import json
import os
import signal
import stat
import secrets
import threading
from pathlib import Path

from .errors import CurltrackError


def check_writable(path) -> None:
    """Raise :class:`CurltrackError` naming ``path`` when it cannot be an output file.

    Only what can be told before writing: an output only ever replaces a regular file
    (or a link to one), so an existing directory, device, FIFO or socket is refused, and
    so is a symbolic-link loop.
    """
    path = Path(path)
    try:
        st = os.stat(path)
    except (FileNotFoundError, NotADirectoryError):  # (a parent that is a file: below)
        st = None
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise CurltrackError("symbolic link loop (the link points, through other "
                                 "links, back to itself)", path=path) from None
        if exc.errno == errno.ENOTDIR:
            raise CurltrackError("a part of the path is not a directory (a file stands "
                                 "where a folder should be)", path=path) from None
        raise CurltrackError(f"cannot use as an output ({exc.strerror})", path=path) from None
    if st is not None and not stat.S_ISREG(st.st_mode):
        if stat.S_ISDIR(st.st_mode):
            raise CurltrackError("is a directory", path=path)
        raise CurltrackError(f"is a {_kind(st.st_mode)}, not a regular file: outputs only "
                             "replace regular files", path=path)
    for parent in path.parents:
        if parent.exists():
            if not parent.is_dir():
                raise CurltrackError(f"{parent} is not a directory", path=path)
            break


def _kind(mode: int) -> str:
    for test, name in ((stat.S_ISCHR, "character device"), (stat.S_ISBLK, "block device"),
                       (stat.S_ISFIFO, "FIFO (named pipe)"), (stat.S_ISSOCK, "socket")):
        if test(mode):
            return name
    return "special file"


def write_error(exc: OSError, path) -> CurltrackError:
    """The one-line error for an ``OSError`` met while writing ``path``."""
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        return CurltrackError(f"disk full while writing ({exc.strerror}); nothing was "
                              "written under this name", path=path)
    return CurltrackError(f"cannot write ({exc.strerror or exc})", path=path)


#: Temporary files being written by this process (removed on SIGTERM as on any error).
_LIVE: set[str] = set()


def _on_sigterm(signum, frame):
    # Unwinds through atomic_path's clean-up like Ctrl-C does (exit status 128 + 15).
    raise SystemExit(128 + signum)


def _install_sigterm() -> None:
    """SIGTERM ends the process by an exception (so temporary files are removed),
    when this is the main thread and nobody else handles SIGTERM."""
    if threading.current_thread() is not threading.main_thread():
        return
    with contextlib.suppress(ValueError, OSError):
        if signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
            signal.signal(signal.SIGTERM, _on_sigterm)


def _temp_prefix(path: Path) -> str:
    return f".{path.stem}."


def clean_stale(path) -> list[Path]:
    """Remove temporary files of ``path`` left by a process that no longer runs.

    Temporary names are ``.STEM.PID.XXXX.SUFFIX``; one whose PID is not alive was left
    by a killed run (SIGKILL cannot be caught).
    """
    path = Path(path)
    removed = []
    with contextlib.suppress(OSError):
        for p in path.parent.glob(f"{_temp_prefix(path)}*"):
            rest = p.name[len(_temp_prefix(path)):]
            pid = rest.split(".", 1)[0]
            if not pid.isdigit() or int(pid) == os.getpid() or _alive(int(pid)):
                continue
            with contextlib.suppress(OSError):
                p.unlink()
                removed.append(p)
    return removed


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # e.g. another user's process
        return True
    return True


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
    _install_sigterm()
    tmp = None
    try:
        # The name is known before the file exists: a SIGTERM or Ctrl-C at any point
        # after it (also inside the creating call) finds it to remove.  (Blocking the
        # signals does not close that window: a signal sent to the process goes to a
        # decoder or encoder thread that does not block it, and Python raises it in the
        # main thread all the same.)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            clean_stale(path)
            for _ in range(100):
                tmp = str(path.parent / f"{_temp_prefix(path)}{os.getpid()}."
                                        f"{secrets.token_hex(4)}{suffix or path.suffix}")
                try:
                    os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
                    break
                except FileExistsError:
                    tmp = None
            else:
                raise FileExistsError(errno.EEXIST, "no free temporary name")
        except OSError as exc:
            raise CurltrackError(f"cannot write here ({exc.strerror})", path=path) from None
        _LIVE.add(tmp)
        try:
            yield Path(tmp)
        except OSError as exc:
            raise write_error(exc, path) from None
        check_writable(path)  # (a FIFO or device made under the name while we wrote)
        os.chmod(tmp, 0o666 & ~_umask())  # (made 0600) outputs get the usual mode
        try:
            os.replace(tmp, path)
        except OSError as exc:  # e.g. a directory made under the name while we wrote
            raise CurltrackError(f"cannot write ({exc.strerror})", path=path) from None
    except BaseException:
        if tmp is not None:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(tmp)
        raise
    finally:
        _LIVE.discard(tmp)


@contextlib.contextmanager
def signals_after():
    """Run a block that must not be interrupted by a Python exception: SIGINT and
    SIGTERM arriving in it are delivered when it ends.

    A KeyboardInterrupt raised inside FFmpeg's encoders (through PyAV) was swallowed
    there and the run went on to exit 0 with its outputs (2 of 40 signal runs); between
    frames the exception unwinds through the clean-up.  (A segfault inside FFmpeg on
    about 1 signal in 150-200 runs is not this; its temporary file is left to the next
    run's :func:`clean_stale`.)
    """
    held = (signal.SIGINT, signal.SIGTERM)
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    got = []
    old = {}
    try:
        for sig in held:
            prev = signal.getsignal(sig)
            if prev is None:  # (a handler not installed from Python: left alone)
                continue
            old[sig] = prev
            signal.signal(sig, lambda signum, frame: got.append(signum))
    except (ValueError, OSError):
        pass
    try:
        yield
    finally:
        for sig, prev in old.items():
            signal.signal(sig, prev)
        if got:
            signal.raise_signal(got[0])


def verify_video(tmp, n_frames: int, path) -> None:
    """Check a just-written video before it is renamed onto ``path``.

    The file is re-opened and must hold ``n_frames`` decodable frames (OpenCV's writer
    only warns when the disk fills: a truncated file would otherwise take the name).

    Raises
    ------
    CurltrackError
        Naming ``path``: the file is unreadable or holds another number of frames.
    """
    import cv2

    why = ""
    if _free_bytes(tmp) == 0:
        why = "; the disk is full"
    cap = cv2.VideoCapture(str(tmp))
    try:
        if not cap.isOpened():
            raise CurltrackError(f"the video could not be written completely (the written "
                                 f"file cannot be opened{why}); nothing was written under "
                                 "this name", path=path)
        got = int(round(cap.get(cv2.CAP_PROP_FRAME_COUNT)))
        ok = got == n_frames
        if ok and n_frames > 0:
            cap.set(cv2.CAP_PROP_POS_FRAMES, n_frames - 1)
            ok = cap.read()[0]
            if not ok:
                # OpenCV seeks by time at the nominal rate, which misses the last frame
                # of a variable-frame-rate file: decode through it instead
                cap.set(cv2.CAP_PROP_POS_FRAMES, 0)
                n_read = 0
                while n_read <= n_frames and cap.grab():
                    n_read += 1
                got, ok = n_read, n_read == n_frames
    finally:
        cap.release()
    if not ok:
        raise CurltrackError(f"the video could not be written completely ({got} of "
                             f"{n_frames} frames readable{why}); nothing was written under "
                             "this name", path=path)


def _free_bytes(path) -> int:
    try:
        st = os.statvfs(Path(path).parent)
    except OSError:
        return -1
    return st.f_bavail * st.f_frsize


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
