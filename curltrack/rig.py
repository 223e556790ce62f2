"""The rig: the physical set-up of one recording session, read from TOML.

Every length is in metres (SI inside).  See ``shared/contract.md`` for the file format.
Unknown keys are an error (a typo such as ``spacing_x_cm`` must not be silently ignored);
lengths that look like centimetres (e.g. ``diameter_m = 29``) are an error too.
"""

from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import RigError
from .settings import TrackingSettings, settings_from_table

G = 9.81  # m/s^2, as in the paper
#: the rock's defaults (contract): inertia radius R (I = M R^2 / 2) and running-band
#: radius r, in m -- the paper's values; a rig's [rock] table overrides them
INERTIA_RADIUS_M = 0.14
BAND_RADIUS_M = 0.0625


@dataclass(frozen=True)
class Marker:
    """A coloured marker on the rock's top, in the rock's own frame (m, origin = rock axis)."""

    color: str
    x_m: float
    y_m: float

    @property
    def rgb(self) -> tuple[int, int, int]:
        """Colour as 0-255 (R, G, B)."""
        return parse_color(self.color)


@dataclass(frozen=True)
class Rig:
    """A recording set-up.

    Attributes
    ----------
    spacing_x_m, spacing_y_m : float
        Thread spacing (m): between threads running along y, and along x.
    grid_colors : tuple of str
        Thread colours ("#rrggbb"), repeating in this order across the lattice; may be empty.
    grid_depth_m : float
        Threads' depth under the ice surface (m).
    rock_diameter_m, rock_height_m : float
        Rock diameter and height of its top (the marker plane) above the ice (m).
    band_radius_m, inertia_radius_m : float
        r and R of the paper's formulas (m); I = M R^2 / 2.
    markers : tuple of Marker
        Two or more markers.
    fps : float or None
        Frame-rate override (frames/s).
    camera_height_m : float or None
        Lens height above the ice (m); estimated from the video when None.
    tracking : TrackingSettings
        The tracker's thresholds (the rig's ``[tracking]`` table over the defaults).
    rolling_shutter_ms : float or None
        Rolling-shutter readout time (ms): the sensor's top row is exposed this much
        before its bottom row (phones, action cameras); each measurement is then timed
        at the row where the rock was seen.  None = a global shutter.
    """

    spacing_x_m: float = 0.15
    spacing_y_m: float = 0.15
    grid_colors: tuple[str, ...] = ("#d02020", "#2040d0")
    grid_depth_m: float = 0.0
    rock_diameter_m: float = 0.29
    rock_height_m: float = 0.114
    band_radius_m: float = BAND_RADIUS_M
    inertia_radius_m: float = INERTIA_RADIUS_M
    markers: tuple[Marker, ...] = field(default_factory=lambda: (
        Marker("#ffd000", 0.08, 0.0), Marker("#00c0ff", -0.08, 0.0)))
    fps: float | None = None
    camera_height_m: float | None = None
    rolling_shutter_ms: float | None = None
    source: str | None = None
    tracking: TrackingSettings = field(default_factory=TrackingSettings)

    @property
    def layout_m(self) -> np.ndarray:
        """The markers' positions in the rock's frame (m, (M, 2), rig order)."""
        return np.array([[m.x_m, m.y_m] for m in self.markers])

    def to_toml(self) -> str:
        """Serialise back to the contract's TOML."""
        lines = ["[grid]",
                 f"spacing_x_m = {self.spacing_x_m!r}",
                 f"spacing_y_m = {self.spacing_y_m!r}"]
        if self.grid_colors:
            lines.append("colors = [" + ", ".join(f'"{c}"' for c in self.grid_colors) + "]")
        lines += [f"depth_m = {self.grid_depth_m!r}", "", "[rock]",
                  f"diameter_m = {self.rock_diameter_m!r}",
                  f"height_m = {self.rock_height_m!r}",
                  f"band_radius_m = {self.band_radius_m!r}",
                  f"inertia_radius_m = {self.inertia_radius_m!r}", ""]
        for m in self.markers:
            lines += ["[[markers]]", f'color = "{m.color}"', f"x_m = {m.x_m!r}",
                      f"y_m = {m.y_m!r}", ""]
        cam = []
        if self.fps is not None:
            cam.append(f"fps = {self.fps!r}")
        if self.camera_height_m is not None:
            cam.append(f"height_m = {self.camera_height_m!r}")
        if self.rolling_shutter_ms is not None:
            cam.append(f"rolling_shutter_ms = {self.rolling_shutter_ms!r}")
        if cam:
            lines += ["[camera]", *cam, ""]
        changed = self.tracking.changed()
        if changed:
            lines += ["[tracking]", *(f"{k} = {v!r}" for k, v in changed.items()), ""]
        return "\n".join(lines)


_HEX = re.compile(r"^#?([0-9a-fA-F]{6})$")
_NAMED = {
    "red": "#d02020", "blue": "#2040d0", "green": "#20a040", "yellow": "#ffd000",
    "cyan": "#00c0ff", "magenta": "#e020c0", "orange": "#ff8000", "black": "#000000",
    "purple": "#8030c0",
}


def parse_color(text: str, where: str = "color") -> tuple[int, int, int]:
    """Parse "#rrggbb" (or a few plain names) into (R, G, B) 0-255.

    Raises
    ------
    RigError
        For anything else.
    """
    if not isinstance(text, str):
        raise RigError(f"expected a colour string like \"#d02020\", got {text!r}", where=where)
    m = _HEX.match(_NAMED.get(text.strip().lower(), text.strip()))
    if not m:
        raise RigError(f"unknown colour {text!r} (use \"#rrggbb\")", where=where)
    h = m.group(1)
    return int(h[0:2], 16), int(h[2:4], 16), int(h[4:6], 16)


_ALLOWED = {
    "grid": {"spacing_x_m", "spacing_y_m", "colors", "depth_m"},
    "rock": {"diameter_m", "height_m", "band_radius_m", "inertia_radius_m"},
    "markers": {"color", "x_m", "y_m"},
    "camera": {"fps", "height_m", "rolling_shutter_ms"},
}

# Plausible ranges (m); values outside are almost always a unit mistake.
_RANGES = {
    "grid.spacing_x_m": (0.01, 2.0), "grid.spacing_y_m": (0.01, 2.0),
    "grid.depth_m": (0.0, 0.1), "rock.diameter_m": (0.05, 1.0),
    "rock.height_m": (0.0, 0.5), "rock.band_radius_m": (0.01, 0.5),
    "rock.inertia_radius_m": (0.01, 0.5), "markers.x_m": (-0.5, 0.5),
    "markers.y_m": (-0.5, 0.5), "camera.fps": (1.0, 1000.0), "camera.height_m": (0.3, 20.0),
    "camera.rolling_shutter_ms": (0.0, 100.0),
}


def _number(table: dict, key: str, section: str, default=None, required=False):
    where = f"[{section}].{key}"
    if key not in table:
        if required:
            raise RigError("missing required field", where=where)
        return default
    value = table[key]
    try:
        finite = math.isfinite(value)  # also copes with integers too large for a float
    except (TypeError, OverflowError):
        finite = False
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not finite:
        raise RigError(f"expected a finite number, got {value!r}", where=where)
    lo, hi = _RANGES[f"{section}.{key}"]
    if not lo <= value <= hi:
        hint = " (lengths are in metres)" if key.endswith("_m") else ""
        raise RigError(f"{value!r} is outside the plausible range [{lo}, {hi}]{hint}", where=where)
    return float(value)


def _check_keys(table: dict, section: str) -> None:
    unknown = set(table) - _ALLOWED[section]
    if unknown:
        raise RigError(f"unknown key(s) {sorted(unknown)}; expected some of "
                       f"{sorted(_ALLOWED[section])}", where=f"[{section}]")


def rig_from_dict(data: dict, source: str | None = None) -> Rig:
    """Build and validate a :class:`Rig` from a parsed TOML mapping."""
    try:
        unknown = set(data) - set(_ALLOWED) - {"tracking"}
        if unknown:
            raise RigError(f"unknown section(s) {sorted(unknown)}", where="top level")
        for required in ("grid", "rock", "markers"):
            if required not in data:
                raise RigError("missing required section", where=f"[{required}]")
        grid, rock, cam = data["grid"], data["rock"], data.get("camera", {})
        markers_raw = data["markers"]
        if not isinstance(markers_raw, list):
            raise RigError("expected [[markers]] tables", where="[[markers]]")
        for sec, tbl in (("grid", grid), ("rock", rock), ("camera", cam)):
            if not isinstance(tbl, dict):
                raise RigError("expected a table", where=f"[{sec}]")
            _check_keys(tbl, sec)
        colors = grid.get("colors", [])
        if not isinstance(colors, list):
            raise RigError("expected a list of colour strings", where="[grid].colors")
        for i, c in enumerate(colors):
            parse_color(c, where=f"[grid].colors[{i}]")
        markers = []
        for i, m in enumerate(markers_raw):
            if not isinstance(m, dict):
                raise RigError("expected a table", where=f"[[markers]][{i}]")
            _check_keys(m, "markers")
            if "color" not in m:
                raise RigError("missing required field", where=f"[[markers]][{i}].color")
            parse_color(m["color"], where=f"[[markers]][{i}].color")
            markers.append(Marker(m["color"],
                                  _number(m, "x_m", "markers", required=True),
                                  _number(m, "y_m", "markers", required=True)))
        if len(markers) < 2:
            raise RigError(f"need two or more markers, got {len(markers)}", where="[[markers]]")
        pos = np.array([[m.x_m, m.y_m] for m in markers])
        if np.ptp(pos, axis=0).max() < 0.02:
            raise RigError("markers must be at least 2 cm apart", where="[[markers]]")
        diameter = _number(rock, "diameter_m", "rock", required=True)
        _check_marker_layout(markers, diameter, colors)
        try:
            tracking = settings_from_table(data.get("tracking", {}))
        except ValueError as exc:
            key, msg = exc.args
            raise RigError(msg, where="[tracking]" + (f".{key}" if key else "")) from None
        return Rig(
            spacing_x_m=_number(grid, "spacing_x_m", "grid", required=True),
            spacing_y_m=_number(grid, "spacing_y_m", "grid", required=True),
            grid_colors=tuple(colors),
            grid_depth_m=_number(grid, "depth_m", "grid", 0.0),
            rock_diameter_m=_number(rock, "diameter_m", "rock", required=True),
            rock_height_m=_number(rock, "height_m", "rock", required=True),
            band_radius_m=_number(rock, "band_radius_m", "rock", BAND_RADIUS_M),
            inertia_radius_m=_number(rock, "inertia_radius_m", "rock", INERTIA_RADIUS_M),
            markers=tuple(markers),
            fps=_number(cam, "fps", "camera"),
            camera_height_m=_number(cam, "height_m", "camera"),
            rolling_shutter_ms=_number(cam, "rolling_shutter_ms", "camera"),
            source=source,
            tracking=tracking,
        )
    except RigError as exc:
        if exc.path is None and source is not None:
            raise RigError(exc.message, path=source, where=exc.where) from None
        raise


#: Smallest colour difference (CIE76 delta E) between a marker and a thread, or two
#: marker colours meant to differ: closer, the classifier confuses them.
MIN_COLOR_DELTA_E = 20.0


def _lab(hex_color: str) -> np.ndarray:
    import cv2

    rgb = np.array(parse_color(hex_color), np.float32).reshape(1, 1, 3) / 255.0
    return cv2.cvtColor(rgb[..., ::-1].copy(), cv2.COLOR_BGR2Lab).reshape(3)


def _check_marker_layout(markers, diameter_m: float, thread_colors) -> None:
    """Markers on the rock, unlike the threads, and a layout whose angle is unambiguous.

    Raises
    ------
    RigError
        A marker beyond the rock's rim; a marker the colour of a thread; same-coloured
        markers a turn can swap (the angle would be ambiguous by that turn).
    """
    import itertools

    for i, m in enumerate(markers):
        r = float(np.hypot(m.x_m, m.y_m))
        if r > diameter_m / 2:
            raise RigError(f"the marker is {r:.3f} m from the rock's axis, outside the rock "
                           f"([rock].diameter_m = {diameter_m:g} m): positions are in metres "
                           "from the axis", where=f"[[markers]][{i}]")
        for j, c in enumerate(thread_colors):
            de = float(np.linalg.norm(_lab(m.color) - _lab(c)))
            if de < MIN_COLOR_DELTA_E:
                raise RigError(f"{m.color} is too close to the thread colour {c} "
                               f"([grid].colors[{j}], delta E {de:.0f} < "
                               f"{MIN_COLOR_DELTA_E:g}): markers would be confused with the "
                               "threads; use a colour unlike the threads'",
                               where=f"[[markers]][{i}].color")
    labs = [_lab(m.color) for m in markers]
    for i, j in itertools.combinations(range(len(markers)), 2):
        de = float(np.linalg.norm(labs[i] - labs[j]))
        if 0 < de < MIN_COLOR_DELTA_E:
            raise RigError(f"{markers[j].color} is too close to marker {i}'s {markers[i].color}"
                           f" (delta E {de:.0f}): give the markers clearly different colours, "
                           "or exactly the same one", where=f"[[markers]][{j}].color")
    if len(markers) > 8:
        return
    pos = np.array([[m.x_m, m.y_m] for m in markers])
    pos = pos - pos.mean(axis=0)
    groups: dict[str, list[int]] = {}
    for i, m in enumerate(markers):
        groups.setdefault(m.color.lower(), []).append(i)
    for perm in itertools.product(*(itertools.permutations(g) for g in groups.values())):
        mapping = dict(zip([i for g in groups.values() for i in g],
                           [i for p in perm for i in p]))
        if all(k == v for k, v in mapping.items()):
            continue
        other = pos[[mapping[i] for i in range(len(markers))]]
        # a pure turn about the layout's centre taking pos onto other?
        ang = np.arctan2((pos[:, 0] * other[:, 1] - pos[:, 1] * other[:, 0]).sum(),
                         (pos * other).sum())
        c, s = np.cos(ang), np.sin(ang)
        if np.abs(pos @ np.array([[c, s], [-s, c]]) - other).max() < 0.005:
            same = [i for i, v in mapping.items() if i != v]
            raise RigError(f"markers {same} have one colour ({markers[same[0]].color}) and a "
                           f"turn of {abs(np.degrees(ang)):.0f} deg swaps them: the rock's "
                           "angle would be ambiguous; give them different colours (or add "
                           "a marker that breaks the symmetry)", where="[[markers]]")


def load_rig(path) -> Rig:
    """Read and validate a rig TOML file.

    Raises
    ------
    RigError
        Naming the file and the field at fault.
    """
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise RigError(f"cannot read rig file ({exc.strerror})", path=path) from None
    try:
        text = raw.decode("utf-8-sig")  # TOML is UTF-8; tolerate an editor's byte-order mark
    except UnicodeDecodeError:
        raise RigError("not a text (UTF-8) file", path=path) from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise RigError(f"not valid TOML: {exc}", path=path) from None
    return rig_from_dict(data, source=str(path))


def default_rig() -> Rig:
    """The contract's example rig (0.15 m red/blue grid, two markers 0.16 m apart)."""
    return Rig()
