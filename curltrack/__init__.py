"""curltrack: measure how curling rocks move.

Pipeline (data flows one way)::

    video -> calib (thread grid) -> track (markers, parallax) -> series (SHOT.csv, noise,
          stops) -> fit (the paper's closed forms) / discover (model vs. data)

``physics`` holds the one model core (closed forms, equations of motion, the effect
registry) shared by ``fit``, ``simulate``, ``render`` and ``discover``.

The public API (``from curltrack import ...``; each name is the stage's own function with
its real signature, imported on first use so that ``import curltrack`` stays light):

=====================  ===============================================================
``read_series``        SHOT.csv / .parquet + sidecar -> :class:`Series`
``write_series``       :class:`Series` -> SHOT.csv / .parquet + sidecar (atomic)
``calibrate_frame``    one frame -> the thread lattice, lens and homography
``track_video``        a shot video -> :class:`Series` (x, y, theta per frame, stops)
``fit_series``         the paper's fits -> :class:`FitResult` (``summary()`` = FIT.json)
``simulate_series``    the forward model sampled like a tracked video -> :class:`Series`
                       (``curltrack simulate``; the trajectory at any times is
                       :func:`curltrack.physics.simulate`)
``discover``           what the model gets wrong -> :class:`DiscoveryReport` (REPORT.json)
``write_report``       :class:`DiscoveryReport` -> REPORT.json (+ figure)
``render``             a series -> a synthetic overhead video and its truth
``run_batch``          a folder of videos -> a campaign (Dask)
=====================  ===============================================================

plus the types they take and return: :class:`Rig` (``load_rig``, ``default_rig``),
:class:`ShotModel`, :class:`Effect` and the registry ``EFFECTS``, :class:`Series`,
:class:`FitResult`, :class:`DiscoveryReport`, :class:`Finding`, and
:class:`CurltrackError` (every error the package raises on bad input).

Examples
--------
>>> from curltrack import ShotModel, fit_series, simulate_series
>>> series = simulate_series(ShotModel(v0=2.0, omega0=1.5), noise_m=0.002,
...                          noise_rad=0.005, seed=1)
>>> fit_series(series).values["shot_type"]
'draw'
"""

import os
import sys
import types

# OpenCV's own FFmpeg prints to stderr ("moov atom not found"; on every frame of an
# interlaced DV file, "Cannot convert interlaced to progressive frames", decoded right
# all the same): errors are reported once, as a VideoError.  OpenCV reads this when it
# first opens a video - in any module (the renderer's check of what it wrote opened
# one before the video module had set it, and every DV frame printed two lines) - so
# it is set here, once, unless the user set it.
os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")

__version__ = "0.1.0"

#: public name -> (module, attribute)
_API = {
    "read_series": ("curltrack.series", "read_series"),
    "write_series": ("curltrack.series", "write_series"),
    "Series": ("curltrack.series", "Series"),
    "calibrate_frame": ("curltrack.calib.grid", "calibrate_frame"),
    "track_video": ("curltrack.track.pipeline", "track_video"),
    "fit_series": ("curltrack.fit", "fit_series"),
    "FitResult": ("curltrack.fit", "FitResult"),
    "simulate_series": ("curltrack.simulate", "simulate_series"),
    "ShotModel": ("curltrack.physics.shot", "ShotModel"),
    "Effect": ("curltrack.physics.effects", "Effect"),
    "EFFECTS": ("curltrack.physics.effects", "EFFECTS"),
    "discover": ("curltrack.discover", "discover"),
    "write_report": ("curltrack.discover", "write_report"),
    "DiscoveryReport": ("curltrack.discover.results", "DiscoveryReport"),
    "Finding": ("curltrack.discover.results", "Finding"),
    "render": ("curltrack.render.video", "render_video"),
    "run_batch": ("curltrack.batch.runner", "run_batch"),
    "Rig": ("curltrack.rig", "Rig"),
    "load_rig": ("curltrack.rig", "load_rig"),
    "default_rig": ("curltrack.rig", "default_rig"),
    "CurltrackError": ("curltrack.errors", "CurltrackError"),
}

# (``curltrack.simulate`` is the module of simulate_series, so the model's own
# ``simulate`` is not re-exported under that name)
__all__ = sorted(_API) + ["__version__"]


class _Package(types.ModuleType):
    """``curltrack`` itself: ``discover`` and ``render`` name the public functions, not
    the sub-packages that hold them.  Importing a sub-package binds it on its parent
    (``curltrack.discover = <module>``); that binding is not kept for these names, so
    ``curltrack.discover`` is the function whatever was imported before (the
    sub-packages stay importable by their dotted names)."""

    def __setattr__(self, name, value):
        if name in _FUNCTION_OVER_PACKAGE and isinstance(value, types.ModuleType):
            return
        super().__setattr__(name, value)


_FUNCTION_OVER_PACKAGE = ("discover", "render")
sys.modules[__name__].__class__ = _Package


def __getattr__(name):
    # the stages' own objects, imported on first use (OpenCV, Dask and lmfit are heavy
    # and most commands need one stage only)
    if name not in _API:
        raise AttributeError(f"module 'curltrack' has no attribute {name!r}")
    import importlib

    module, attr = _API[name]
    value = getattr(importlib.import_module(module), attr)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_API))
