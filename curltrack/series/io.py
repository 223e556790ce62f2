"""SHOT.csv / SHOT.parquet + sidecar SHOT.json: read, validate, write (atomically).

Columns (contract): ``frame`` (video frame index), ``t`` (s since the start frame),
``x``, ``y`` (m, rock centre on the ice), ``theta`` (rad, cumulative, CCW from above),
``ok`` (1 = measured; a row with x, y and an empty theta is a position-only
measurement, see :attr:`Series.theta_measured`).  Optional: ``sigma_xy`` (m), ``sigma_theta`` (rad), ``quality``
and anything else (kept as is).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import pandas as pd

from .. import __version__
from .._atomic import atomic_path, write_json
from ..errors import SeriesError

COLUMNS = ("frame", "t", "x", "y", "theta", "ok")
#: (``field``: interlaced video measured per field - 0 the field exposed first, 1 the
#: second; see :func:`sample_index`)
OPTIONAL_COLUMNS = ("sigma_xy", "sigma_theta", "quality", "field")
SIDECAR_KEYS = ("fps", "start_frame", "n_frames", "stop_frame_translation",
                "stop_frame_rotation", "t_stop_translation", "t_stop_rotation",
                "camera_height_m", "grid_spacing_px", "frames_lost", "warnings", "version")


@dataclass(frozen=True)
class Series:
    """A shot's per-frame series and its sidecar metadata.

    A value: no stage of curltrack edits a series it is given (:meth:`with_meta` and
    :func:`dataclasses.replace` make new ones), so one series can be fitted, discovered
    and written in any order with the same results.

    Attributes
    ----------
    data : DataFrame
        The contract's columns (``frame, t, x, y, theta, ok`` + optional ones).
    meta : dict
        The sidecar (``fps``, stop frames/times, ``warnings`` ...).
    path : Path or None
        Where it was read from.

    Examples
    --------
    >>> s = read_series("SHOT.csv")                              # doctest: +SKIP
    >>> s2 = s.with_meta(t_stop_translation=None)   # s itself unchanged  # doctest: +SKIP
    """

    data: pd.DataFrame
    meta: dict = field(default_factory=dict)
    path: Path | None = None

    @property
    def warnings(self) -> list:
        """The sidecar's warnings (a copy)."""
        return list(self.meta.get("warnings") or [])

    def with_meta(self, **changes) -> "Series":
        """A new series whose sidecar has ``changes`` applied (data shared, unchanged)."""
        return replace(self, meta={**self.meta, **changes})

    @property
    def measured(self) -> pd.DataFrame:
        """Rows with ``ok`` = 1."""
        return self.data[self.data["ok"] == 1]

    @property
    def theta_measured(self) -> bool:
        """Whether the instrument measured the rotation: the sidecar's
        ``theta_measured`` if given, else whether any measured row has a theta."""
        flag = self.meta.get("theta_measured")
        if flag is not None:
            return bool(flag)
        return bool(np.isfinite(self.measured["theta"].to_numpy(float)).any())

    @property
    def name(self) -> str:
        return str(self.path) if self.path else "<series>"


def sample_index(data: pd.DataFrame) -> np.ndarray:
    """Each row's exposure number: ``frame``, or ``2 * frame + field`` for a series
    measured per field (a ``field`` column: interlaced video, two rows per frame).

    Consecutive exposures get consecutive numbers - what the noise model
    (:func:`~curltrack.series.noise.estimate_noise`: second differences of consecutive
    rows) and the whitening across gaps count by.  By ``frame`` alone a field series
    has no two consecutive rows (two share each frame number): ``discover`` refused
    every tracked interlaced video with "too few consecutive measured frames".
    """
    frame = data["frame"].to_numpy(int)
    if "field" not in data.columns:
        return frame
    return 2 * frame + data["field"].to_numpy(int)


#: Cell values read as empty (case-insensitive): numpy's and MATLAB's "nan", R's "NA",
#: a database's "null"/"None", "N/A".
MISSING_SPELLINGS = ("nan", "na", "n/a", "null", "none")


def _is_datetime(value) -> bool:
    import warnings

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return not pd.isna(pd.to_datetime(str(value)))
    except (ValueError, TypeError, OverflowError):
        return False


def sidecar_path(path) -> Path:
    """``SHOT.csv`` -> ``SHOT.json``."""
    return Path(path).with_suffix(".json")


def make_meta(fps: float, n_frames: int, start_frame: int = 0, **extra) -> dict:
    """A sidecar dict with every contract key present (unknown ones None)."""
    meta = {k: None for k in SIDECAR_KEYS}
    meta.update(fps=float(fps), start_frame=int(start_frame), n_frames=int(n_frames),
                frames_lost=0, warnings=[], version=__version__)
    meta.update(extra)
    return meta


def _plain(value) -> str:
    """A number as a reader would write it: ``2``, ``1.5`` (never ``np.float64(1.5)``)."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        return repr(value)
    return str(int(v)) if v.is_integer() and abs(v) < 1e15 else repr(v)


def _contract_names(data: pd.DataFrame, name: str) -> tuple[pd.DataFrame, list[str]]:
    """Column names as the contract writes them: spaces around a name dropped (a CSV
    written ``frame, t, x``), and a contract column named in another case (``T``,
    ``X``) read as it, said in a warning - where no other column takes that name."""
    known = [*COLUMNS, *OPTIONAL_COLUMNS]
    names = [c.strip() if isinstance(c, str) else c for c in data.columns]
    said = []
    lower = [c.lower() if isinstance(c, str) else c for c in names]
    cased = {}
    for i, c in enumerate(names):
        k = lower[i]
        if (c not in known and k in known and k not in names
                and lower.count(k) == 1):
            cased[c] = k
            names[i] = k
    if cased:
        said.append(f"{name}: column(s) {', '.join(cased)} read as "
                    f"{', '.join(cased.values())} (the contract's names are lower case)")
    if names == list(data.columns):
        return data, said
    out = data.copy()
    out.columns = names
    return out, said


def _fill_optional(data: pd.DataFrame, name: str) -> tuple[pd.DataFrame, list[str]]:
    """A table of ``t``, ``x``, ``y`` (and ``theta``) without the contract's ``frame``
    and ``ok`` (another instrument's export) completed to the contract's columns, each
    filled one said in a warning: ``frame`` numbered from 0, ``ok`` = 1 where x and y
    are given, ``theta`` empty (position-only) when absent.  A table with ``frame`` or
    ``ok`` is one of the contract's, and any column it lacks is :func:`validate`'s
    error."""
    missing = [c for c in COLUMNS if c not in data.columns]
    if not {"frame", "ok"} <= set(missing) or not set(missing) <= {"frame", "theta", "ok"}:
        return data, []
    out, said = data.copy(), []
    if "frame" in missing:
        out["frame"] = np.arange(len(out))
        said.append(f"{name}: no 'frame' column: rows numbered from 0")
    if "ok" in missing:
        xy = out[["x", "y"]].apply(pd.to_numeric, errors="coerce")
        out["ok"] = np.isfinite(xy.to_numpy(float)).all(axis=1).astype(int)
        said.append(f"{name}: no 'ok' column: every row with x and y taken as measured")
    if "theta" in missing:
        out["theta"] = np.nan
        said.append(f"{name}: no 'theta' column: a position-only series (x, y; no "
                    f"rotation)")
    return out[[*COLUMNS, *[c for c in out.columns if c not in COLUMNS]]], said


def validate(data: pd.DataFrame, name: str = "<series>") -> tuple[pd.DataFrame, list[str]]:
    """Check a series table against the contract; return a clean copy and warnings.

    A table of ``t``, ``x``, ``y`` (and ``theta``) without ``frame`` and ``ok`` is
    completed (:func:`_fill_optional`, with a warning per column filled).

    Raises
    ------
    SeriesError
        Missing columns, text in numbers, non-increasing ``t``, bad ``ok`` values.
    """
    data, renamed = _contract_names(data, name)
    data, filled = _fill_optional(data, name)
    missing = [c for c in COLUMNS if c not in data.columns]
    if missing:
        sep = next((c for c in ";\t|" if len(data.columns) == 1
                    and len(str(data.columns[0]).split(c)) >= len(COLUMNS)), None)
        if sep is not None:  # one column whose name holds all the others
            raise SeriesError(f"the columns are separated by {sep!r}, not ',' (a CSV from a "
                              "locale that writes decimal commas?): save it with ','",
                              path=name)
        raise SeriesError(f"missing column(s) {missing}; expected {list(COLUMNS)}", path=name)
    out = data.copy()
    for col in out.columns:
        if col in COLUMNS or col in OPTIONAL_COLUMNS:
            if col == "ok" and out[col].dtype != float:   # (True/False, as pandas writes)
                out[col] = out[col].map(lambda v: {"true": 1, "false": 0}.get(
                    str(v).strip().lower(), v))
            # (the spellings of a missing value that numpy, R, MATLAB and databases
            # write read as empty, as pandas' own empty cell)
            text = out[col].astype(str).str.strip()
            out[col] = out[col].where(~text.str.lower().isin(MISSING_SPELLINGS), np.nan)
            num = pd.to_numeric(out[col], errors="coerce")
            bad = num.isna() & out[col].notna() & (out[col].astype(str).str.strip() != "")
            if bad.any():
                row = int(np.flatnonzero(bad.to_numpy())[0])
                hint = ("; it looks like a date/time: t is seconds since the release"
                        if col == "t" and _is_datetime(out[col].iloc[row]) else "")
                raise SeriesError(f"non-numeric value {out[col].iloc[row]!r} in column "
                                  f"'{col}'{hint}", path=name, where=f"row {row + 2}")
            out[col] = num.astype(float)
    warnings: list[str] = [*renamed, *filled]
    if len(out) == 0:
        raise SeriesError("no rows", path=name)
    for col in ("frame", "t", "ok"):
        if out[col].isna().any():
            row = int(np.flatnonzero(out[col].isna().to_numpy())[0])
            raise SeriesError(f"empty '{col}'", path=name, where=f"row {row + 2}")
    if not np.isin(out["ok"], (0, 1)).all():
        row = int(np.flatnonzero(~np.isin(out["ok"], (0, 1)))[0])
        raise SeriesError(f"'ok' must be 0 or 1, got {_plain(out['ok'].iloc[row])}",
                          path=name, where=f"row {row + 2}")
    t = out["t"].to_numpy()
    if not np.isfinite(t).all():
        row = int(np.flatnonzero(~np.isfinite(t))[0])
        raise SeriesError("non-finite 't'", path=name, where=f"row {row + 2}")
    dt = np.diff(t)
    if (dt <= 0).any():
        row = int(np.flatnonzero(dt <= 0)[0]) + 1
        kind = "duplicate" if dt[row - 1] == 0 else "decreasing"
        from ..sanity import MAX_T_S

        hint = (": t looks like a clock time, not seconds since the release"
                if abs(t[row]) > MAX_T_S else "")
        raise SeriesError(f"{kind} time t={_plain(t[row])} in column 't' (t must "
                          f"increase){hint}", path=name, where=f"row {row + 2}")
    out["frame"] = out["frame"].astype(int)
    out["ok"] = out["ok"].astype(int)
    if "field" in out.columns:
        bad = ~np.isin(out["field"].to_numpy(float), (0.0, 1.0))
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            raise SeriesError(f"'field' must be 0 or 1 (the field exposed first or "
                              f"second), got {_plain(out['field'].iloc[row])}", path=name,
                              where=f"row {row + 2}")
        out["field"] = out["field"].astype(int)
    ok = out["ok"].to_numpy() == 1
    holes = ok & ~np.isfinite(out[["x", "y"]].to_numpy()).all(axis=1)
    if holes.any():
        rows = np.flatnonzero(holes)
        warnings.append(f"{name}: {len(rows)} row(s) marked ok=1 have empty/NaN x or y "
                        f"(first at row {rows[0] + 2}); treated as ok=0")
        out.loc[holes, "ok"] = 0
    # an infinite theta is not an empty one (position-only): the row is not trusted
    inf_theta = ok & ~holes & np.isinf(out["theta"].to_numpy(float))
    if inf_theta.any():
        rows = np.flatnonzero(inf_theta)
        warnings.append(f"{name}: {len(rows)} row(s) marked ok=1 have an infinite theta "
                        f"(first at row {rows[0] + 2}); treated as ok=0")
        out.loc[inf_theta, "ok"] = 0
        holes = holes | inf_theta
    # position-only rows (contract): x, y measured, theta empty -- kept; theta is then
    # simply not used there.  A series with theta on some rows only is said so.
    no_theta = ok & ~holes & ~np.isfinite(out["theta"].to_numpy())
    if no_theta.any() and not no_theta.sum() == (ok & ~holes).sum():
        rows = np.flatnonzero(no_theta)
        warnings.append(f"{name}: {len(rows)} measured row(s) have no theta (first at row "
                        f"{rows[0] + 2}); x, y kept, theta not used there")
    return out, warnings


def read_series(path) -> Series:
    """Read a SHOT.csv or SHOT.parquet and its sidecar (if any), validated.

    Parameters
    ----------
    path : str or Path
        The series file; its sidecar is the same name with ``.json`` (a Parquet file may
        carry the sidecar in its metadata instead).

    Returns
    -------
    Series
        Contract columns (``ok`` = 1 rows with an empty x, y or theta become ``ok`` = 0,
        with a warning) and the sidecar (``warnings`` always present).

    Raises
    ------
    SeriesError
        The file is missing, unreadable or violates the contract.

    Examples
    --------
    >>> from curltrack import read_series
    >>> s = read_series("out/demo/shot.csv")           # doctest: +SKIP
    >>> s.measured[["t", "x", "y", "theta"]].head()     # doctest: +SKIP
    >>> s.meta["t_stop_translation"]                    # doctest: +SKIP
    """
    path = Path(path)
    if not path.exists():
        raise SeriesError("file not found", path=path)
    try:
        if path.suffix.lower() == ".parquet":
            data = pd.read_parquet(path)
        else:
            data = pd.read_csv(path, dtype=str, keep_default_na=False, na_values=[""])
    except Exception as exc:  # pandas raises many kinds; all mean "unreadable"
        raise SeriesError(f"cannot read series ({type(exc).__name__}: {exc})".splitlines()[0],
                          path=path) from None
    data, warnings = validate(data, str(path))
    meta = {}
    side = sidecar_path(path)
    if side.exists():
        try:
            meta = json.loads(side.read_text())
        except (OSError, ValueError) as exc:  # ValueError: bad JSON or not UTF-8
            raise SeriesError(f"cannot read sidecar ({exc})", path=side) from None
        if not isinstance(meta, dict):
            raise SeriesError("sidecar must be a JSON object", path=side)
    elif path.suffix.lower() == ".parquet":
        raw = _parquet_meta(path)
        meta = raw or {}
    meta.setdefault("warnings", [])
    meta["warnings"] = list(meta["warnings"]) + warnings
    return Series(data.reset_index(drop=True), meta, path)


def _parquet_meta(path) -> dict | None:
    import pyarrow.parquet as pq

    md = pq.read_schema(path).metadata or {}
    raw = md.get(b"curltrack")
    return json.loads(raw) if raw else None


def write_series(path, series: Series | pd.DataFrame, meta: dict | None = None) -> Path:
    """Write a series (``.csv`` or ``.parquet`` by extension) and its sidecar, atomically.

    Parameters
    ----------
    path : str or Path
        ``SHOT.csv`` or ``SHOT.parquet``; the sidecar goes beside it as ``SHOT.json``.
    series : Series or DataFrame
        The series (its ``meta`` is the sidecar unless ``meta`` is given), or a table
        with the contract's columns.
    meta : dict, optional
        The sidecar (``version`` and ``warnings`` are added when missing).

    Returns
    -------
    Path
        The sidecar's path.

    Examples
    --------
    >>> from curltrack import ShotModel, simulate_series, write_series
    >>> write_series("sim.csv", simulate_series(ShotModel(v0=2.0, omega0=1.5)))  # doctest: +SKIP
    PosixPath('sim.json')
    """
    if isinstance(series, Series):
        data, meta = series.data, (meta if meta is not None else series.meta)
    else:
        data = series
    meta = dict(meta or {})
    meta.setdefault("version", __version__)
    meta.setdefault("warnings", [])
    data = data.copy()
    cols = list(COLUMNS) + [c for c in data.columns if c not in COLUMNS]
    data = data[cols]
    path = Path(path)
    with atomic_path(path) as tmp:
        if path.suffix.lower() == ".parquet":
            import pyarrow as pa
            import pyarrow.parquet as pq

            table = pa.Table.from_pandas(data, preserve_index=False)
            md = dict(table.schema.metadata or {})
            md[b"curltrack"] = json.dumps(meta, default=float).encode()
            pq.write_table(table.replace_schema_metadata(md), tmp)
        else:
            data.to_csv(tmp, index=False, float_format="%.9g", na_rep="")
    side = sidecar_path(path)
    write_json(side, meta)
    return side
