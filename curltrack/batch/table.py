"""The campaign table: one row per shot, written as ``campaign.parquet`` + ``campaign.csv``.

Columns, in order:

- the shot: ``shot_id``, ``file`` (video path relative to the batch folder),
  ``shot_index`` (position in a split video), ``start_frame``, ``end_frame``;
- ``status`` (``done`` | ``failed``), ``error`` (the one-line reason), ``error_type``;
- every key of the shot's ``FIT.json`` under its own name (``shot_type``, ``lambda_theta``,
  ``lambda_theta_err``, ``a_T`` ... as in the contract; lists become ``"; "``-joined text,
  nested dicts ``outer.inner`` columns); null for failed shots;
- tracking quality, prefixed ``track_`` (see
  :data:`curltrack.batch.pipeline.QUALITY_KEYS`); discovery, prefixed ``discover_``;
- the columns of ``shots.csv`` (lower-cased, spaces -> ``_``), e.g. ``ice_surface``,
  ``date``, ``thrower``, ``notes``; a name already taken gets the prefix ``meta_``;
- bookkeeping: ``version``, ``input_sha256``, ``elapsed_s`` (wall) and ``cpu_s`` (CPU
  time of the worker process) of the shot's processing, ``worker`` (host:pid).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd

from .._atomic import atomic_path
from ..errors import InputError

METADATA_FILE = "shots.csv"
SHOT_COLUMNS = ("shot_id", "file", "shot_index", "start_frame", "end_frame")
STATUS_COLUMNS = ("status", "error", "error_type")
BOOK_COLUMNS = ("version", "input_sha256", "elapsed_s", "cpu_s", "worker")


def read_shot_metadata(directory) -> pd.DataFrame | None:
    """Read ``shots.csv`` from the batch folder (None when there is none).

    It needs a ``file`` column (video path relative to the folder, or its bare name);
    every other column is free (``ice_surface``, ``date``, ``thrower``, ``notes`` ...).
    An optional ``shot`` column (1-based) gives per-shot rows for split videos.

    Raises
    ------
    InputError
        Unreadable file, no ``file`` column, an empty or repeated ``file`` entry.
    """
    path = Path(directory) / METADATA_FILE
    if not path.exists():
        return None
    try:
        meta = pd.read_csv(path, dtype=str, keep_default_na=False, skipinitialspace=True)
    except Exception as exc:  # pandas raises many kinds; all mean "unreadable"
        raise InputError(f"cannot read ({type(exc).__name__}: {exc})".splitlines()[0],
                         path=path) from None
    meta.columns = [re.sub(r"[\s\-]+", "_", str(c).strip().lower()) for c in meta.columns]
    if "file" not in meta.columns:
        raise InputError(f"needs a 'file' column (has {list(meta.columns)})", path=path,
                         where="header")
    meta["file"] = meta["file"].str.strip().str.replace("\\", "/", regex=False)
    empty = np.flatnonzero(meta["file"].to_numpy() == "")
    if empty.size:
        raise InputError("empty 'file'", path=path, where=f"row {empty[0] + 2}")
    if "shot" in meta.columns:
        shot = pd.to_numeric(meta["shot"].replace("", np.nan), errors="coerce")
        bad = np.flatnonzero(shot.isna() & (meta["shot"] != ""))
        if bad.size:
            raise InputError(f"'shot' must be a whole number, got {meta['shot'].iloc[bad[0]]!r}",
                             path=path, where=f"row {bad[0] + 2}")
        meta["shot"] = shot.astype("Int64")
    keys = ["file", "shot"] if "shot" in meta.columns else ["file"]
    dup = np.flatnonzero(meta.duplicated(keys).to_numpy())
    if dup.size:
        raise InputError(f"repeated entry for {meta['file'].iloc[dup[0]]!r}", path=path,
                         where=f"row {dup[0] + 2}")
    return meta


def flatten_record(record: dict) -> dict:
    """One table row from a shot's record (see :func:`curltrack.batch.shot.process_shot`)."""
    shot = record.get("shot", {})
    row = {k: shot.get(k) for k in SHOT_COLUMNS}
    if shot.get("id_note"):  # two files' names map to one id (see jobs.video_ids)
        row["shot_id_note"] = shot["id_note"]
    row.update({k: record.get(k) for k in STATUS_COLUMNS})
    for key, value in _flat(record.get("fit") or {}).items():
        row[key if key not in row else f"fit_{key}"] = value
    for prefix, part in (("track_", "quality"), ("discover_", "discovery")):
        for key, value in _flat(record.get(part) or {}).items():
            row[prefix + key] = value
    row.update({k: record.get(k) for k in BOOK_COLUMNS})
    return row


def _flat(d: dict, prefix: str = "") -> dict:
    out = {}
    for key, value in d.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(_flat(value, name + "."))
        elif isinstance(value, (list, tuple)):
            out[name] = "; ".join(v if isinstance(v, str) else json.dumps(v) for v in value)
        else:
            out[name] = value
    return out


def build_table(records, metadata: pd.DataFrame | None = None) -> pd.DataFrame:
    """The campaign table (one row per record, sorted by ``shot_id``), metadata joined."""
    rows = [flatten_record(r) for r in records]
    table = pd.DataFrame(rows, columns=_column_order(rows))
    table = table.sort_values("shot_id", kind="stable").reset_index(drop=True)
    if metadata is not None and len(table):
        table = _join_metadata(table, metadata)
    return _tidy(table)


def _column_order(rows) -> list[str]:
    cols: dict[str, None] = {}
    for r in rows:
        cols.update(dict.fromkeys(r))
    head = [c for c in (*SHOT_COLUMNS, *STATUS_COLUMNS) if c in cols]
    tail = [c for c in BOOK_COLUMNS if c in cols]
    return head + [c for c in cols if c not in head and c not in tail] + tail


def _join_metadata(table: pd.DataFrame, meta: pd.DataFrame) -> pd.DataFrame:
    """Match ``shots.csv`` rows by relative path, else by bare file name.

    With a ``shot`` column, a row with that shot number wins over a row without one
    (which applies to all shots of its video).
    """
    rows_by_file = {f: list(idx) for f, idx in meta.groupby("file").indices.items()}
    has_shot = "shot" in meta.columns
    extra = [c for c in meta.columns if c not in ("file", "shot")]
    values = {c: [None] * len(table) for c in extra}
    for row, (file, index) in enumerate(zip(table["file"], table["shot_index"])):
        file = str(file)
        cands = rows_by_file.get(file) or rows_by_file.get(file.rsplit("/", 1)[-1], [])
        if has_shot:
            shot = meta["shot"]
            exact = [i for i in cands if pd.notna(shot[i]) and pd.notna(index)
                     and int(shot[i]) == int(index)]
            cands = exact or [i for i in cands if pd.isna(shot[i])]
        if cands:
            for c in extra:
                values[c][row] = meta[c][cands[0]]
    for c in extra:
        table[f"meta_{c}" if c in table.columns else c] = values[c]
    return table


def _tidy(table: pd.DataFrame) -> pd.DataFrame:
    """Object columns become numbers when all their values are numbers, else text."""
    for col in table.columns:
        if table[col].dtype != object:
            continue
        vals = table[col].dropna()
        if len(vals) and all(isinstance(v, (bool, np.bool_)) for v in vals):
            continue
        if all(isinstance(v, (int, float, np.number)) and not isinstance(v, bool) for v in vals):
            table[col] = pd.to_numeric(table[col], errors="coerce").astype(float)
            if len(vals) and all(float(v).is_integer() for v in vals) and not table[col].isna().any():
                table[col] = table[col].astype("int64")
        else:
            table[col] = table[col].map(lambda v: v if v is None or isinstance(v, str)
                                        or (isinstance(v, float) and np.isnan(v)) else str(v))
    return table


def write_campaign(records, metadata, outdir) -> tuple[Path, Path, pd.DataFrame]:
    """Write ``campaign.parquet`` and ``campaign.csv`` in ``outdir`` atomically.

    Returns
    -------
    (Path, Path, DataFrame)
        The two paths and the table.
    """
    table = build_table(records, metadata)
    outdir = Path(outdir)
    parquet, csv = outdir / "campaign.parquet", outdir / "campaign.csv"
    with atomic_path(parquet) as tmp:
        table.to_parquet(tmp, index=False)
    with atomic_path(csv) as tmp:
        table.to_csv(tmp, index=False, float_format="%.9g")
    return parquet, csv, table


def read_campaign(path) -> pd.DataFrame:
    """Read a ``campaign.parquet`` (or ``.csv``)."""
    path = Path(path)
    if not path.exists():
        raise InputError("file not found", path=path)
    return pd.read_parquet(path) if path.suffix.lower() == ".parquet" else pd.read_csv(path)
