"""Manual corrections: frames measured from the user's clicks on the markers, frames excluded.

A corrections file (JSON, downloaded from the review page or written by hand)::

    {"click_sigma_px": 1.0,
     "frames": {"123": {"markers_px": [[u0, v0], [u1, v1]]},   # one per rig marker, in order
                "130": {"exclude": true}}}

Pixels are the video's (origin at the centre of the top-left pixel, v down).  A clicked
frame is measured like a tracked one - the markers through that frame's grid
homography (the grid is followed also while a broom hides the markers) - with the
marker's 1 sigma from the click precision ``click_sigma_px``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..errors import InputError

__all__ = ["read_corrections", "apply_corrections"]

DEFAULT_CLICK_SIGMA_PX = 1.0


def read_corrections(path, n_markers: int) -> dict:
    """Read and check a corrections file: ``{"click_sigma_px", "clicked": {frame: (M, 2)},
    "excluded": set}``.

    Raises
    ------
    InputError
        Naming the file and the frame at fault.
    """
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, ValueError) as exc:
        raise InputError(f"cannot read the corrections ({exc})", path=path) from None
    if not isinstance(data, dict) or not isinstance(data.get("frames"), dict):
        raise InputError('expected {"frames": {FRAME: {...}}}', path=path)
    sigma = data.get("click_sigma_px", DEFAULT_CLICK_SIGMA_PX)
    if not isinstance(sigma, (int, float)) or not 0 < sigma < 50:
        raise InputError(f"click_sigma_px must be a number in (0, 50) px, got {sigma!r}",
                         path=path, where="click_sigma_px")
    clicked, excluded = {}, set()
    for key, entry in data["frames"].items():
        where = f"frames.{key}"
        if not str(key).isdigit() or not isinstance(entry, dict):
            raise InputError("expected a frame index and an object", path=path, where=where)
        if entry.get("exclude"):
            excluded.add(int(key))
            continue
        px = np.asarray(entry.get("markers_px"), dtype=float)
        if px.shape != (n_markers, 2) or not np.isfinite(px).all():
            raise InputError(f"markers_px must be {n_markers} [u, v] pairs (one per rig "
                             "marker, in the rig's order)", path=path, where=where)
        clicked[int(key)] = px
    return {"click_sigma_px": float(sigma), "clicked": clicked, "excluded": excluded,
            "file": str(path)}


def apply_corrections(records, corr: dict, calib, rig) -> list[str]:
    """Measure the clicked frames from their clicks, mark the excluded ones (in place).

    Returns warnings (clicked frames that cannot be measured: no grid on that frame).
    """
    from ..calib.grid import pixel_scale, pixel_steps
    from ..calib.lens import apply_h, undistort
    from .parallax import similarity_fit
    from .pipeline import read_lattice_at_rock

    L = rig.layout_m
    by_frame = {r.frame: r for r in records}
    tracked = [r for r in records if r.status == ""]
    contrast = np.nanmedian([r.contrast for r in tracked] or [np.nan])
    # clicks (~1 px) cannot judge the layout's scale (the tracked frames' agree to
    # ~0.1 %): a clicked frame takes the video's, so the parallax and the layout check
    # rest on the tracked frames
    scale = np.nanmedian([r.scale for r in tracked] or [np.nan])
    warnings = []
    for f in sorted(corr["excluded"]):
        if f in by_frame:
            rec = by_frame[f]
            rec.status, rec.centre_app = "excluded by the corrections file", None
    for f, px in sorted(corr["clicked"].items()):
        rec = by_frame.get(f)
        if rec is None or rec.H is None or calib is None or rec.grid_status:
            # (a homography only predicted from the frames before - the threads hidden
            # by a broom - is millimetres off where the rock is, and says nothing of it)
            why = f" ({rec.grid_status})" if rec is not None and rec.grid_status else ""
            warnings.append(f"{corr['file']}: frame {f}: the grid was not measured on this "
                            f"frame{why}; the clicks cannot be measured (ok = 0)")
            continue
        M = len(L)
        q = undistort(np.vstack([px, pixel_steps(px.mean(axis=0))]), calib.K, calib.dist)
        on_ice = apply_h(rec.H, q)
        c, phi, _, _ = similarity_fit(L, on_ice[:M])
        if rec.pose is not None:  # the lattice's misfit and sigma at the clicked rock
            mpp = read_lattice_at_rock(rec, rec.pose, calib, L, q, on_ice[:M], c)
        else:
            mpp = pixel_scale(on_ice[M:])
            if not np.isfinite(rec.grid_sigma_m):
                rec.grid_sigma_m = 0.3 * mpp
        rec.markers_px, rec.centre_app, rec.phi, rec.scale = px, c, phi, scale
        rec.sigma_m = corr["click_sigma_px"] * mpp
        rec.contrast = contrast
        rec.status = ""
        rec.clicked = True
        rec.notes.append("measured from clicks (corrections file)")
    return warnings
