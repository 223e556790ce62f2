"""Exception hierarchy.  Only the CLI turns these into exit codes."""

from __future__ import annotations


class CurltrackError(Exception):
    """Base class: an input could not be measured or a step failed (exit status 1).

    Parameters
    ----------
    message : str
        What is wrong, in one line.
    path : str or Path, optional
        The file at fault; prefixed to the message.
    where : str, optional
        The frame, row or field at fault (e.g. ``"frame 120"``, ``"[grid].spacing_x_m"``).
    """

    def __init__(self, message: str, path=None, where: str | None = None):
        self.message = message
        self.path = None if path is None else str(path)
        self.where = where
        super().__init__(self.__str__())

    def __str__(self) -> str:
        parts = [p for p in (self.path, self.where) if p]
        prefix = ": ".join(parts)
        return f"{prefix}: {self.message}" if prefix else self.message


class InputError(CurltrackError):
    """A file (rig, series, video) is missing, unreadable or invalid."""


class RigError(InputError):
    """The rig TOML is invalid."""


class SeriesError(InputError):
    """A SHOT.csv / sidecar is invalid."""


class VideoError(InputError):
    """A video cannot be opened or decoded."""


class ParameterError(CurltrackError):
    """Model or command parameters are invalid (negative alpha, phi >= 1, ...)."""


class FitError(CurltrackError):
    """A fit did not converge or is ill-posed (too few points, ...)."""


class TrackingError(CurltrackError):
    """The rock or grid could not be followed."""


class StartFrameError(TrackingError):
    """The video does not begin at the release: the rock speeds up from its first
    frames (at rest, or still pushed), so t and the origin would count from the wrong
    instant; the message names the release frame to give as ``--start-frame``."""
