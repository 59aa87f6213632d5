"""Parquet and CSV run files: one long table ``channel, t_s, value, unit`` (one row per sample).

Channels may have different rates (accelerations at 1 kHz, speed and
position at 100 Hz, one row per balise passage): a long table holds them
without resampling. The run header travels with the table:

* Parquet: a JSON object under the schema metadata key ``run_header``;
* CSV: lines ``# key = value`` before the column names.

:func:`write_run_table` writes a :class:`~estimator.run.Run` (or raw channels)
in either form, so an MDF 4 recording can be converted.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import Mapping

import numpy as np
import pandas as pd

from ema.wide_csv import NAN_WORDS, read_hash_header
from estimator.errors import RunFileError
from estimator.io.registry import RawChannel, RawRecording

__all__ = ["sniff_parquet", "sniff_csv", "read_parquet", "read_csv", "read_csv_header", "write_run_table", "COLUMNS"]

log = logging.getLogger("estimator")

COLUMNS = ("channel", "t_s", "value", "unit")
HEADER_KEY = b"run_header"


def sniff_parquet(path: Path, head: bytes) -> bool:
    return head[:4] == b"PAR1"


def sniff_csv(path: Path, head: bytes) -> bool:
    try:
        text = head.decode("utf-8-sig")
    except UnicodeDecodeError:
        return False
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.startswith("#")]
    return bool(lines) and all(c in lines[0].replace(" ", "") for c in ("channel", "t_s", "value"))


def _numbers(cells: pd.Series, path: Path, channel, column: str) -> np.ndarray:
    """A column as floats; a cell that is neither a number nor a missing-value word is refused by row (coerced
    to NaN it would pass as a logger's dropout and hide a damaged file)."""
    values = pd.to_numeric(cells, errors="coerce")
    bad = (values.isna() & cells.notna()).to_numpy().copy()
    if bad.any():
        bad[bad] = ~cells[bad].astype(str).str.strip().str.lower().isin(NAN_WORDS).to_numpy()
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise RunFileError(f"{path}: channel {channel!r}, column {column!r}, data row {int(cells.index[k]) + 1} "
                           f"(counted from 1 after the column header): {cells.iloc[k]!r} is not a number"
                           + (f" ({int(bad.sum())} such cells)" if bad.sum() > 1 else ""))
    return values.to_numpy(float)


def _seconds(df: pd.DataFrame, path: Path) -> pd.DataFrame:
    """``t_s`` in seconds: a column of clock times (datetime64, as pandas writes a DatetimeIndex reset to a
    column) counts from the table's first stamp, a column of durations (timedelta64) is converted. Read as
    numbers, either would be nanoseconds: a 1 kHz channel would look sampled at 1e-6 Hz."""
    t = df["t_s"]
    if pd.api.types.is_datetime64_any_dtype(t):
        t0 = t.min()
        log.info("%s: column t_s holds clock times: read as seconds from the first stamp, %s", path, t0)
        return df.assign(t_s=(t - t0).dt.total_seconds())
    if pd.api.types.is_timedelta64_dtype(t):
        return df.assign(t_s=t.dt.total_seconds())
    return df


def _from_frame(df: pd.DataFrame, header: Mapping[str, str], path: Path) -> RawRecording:
    missing = [c for c in COLUMNS[:3] if c not in df.columns]
    if missing:
        raise RunFileError(f"{path}: missing column(s) {missing}; a tabular run file has columns {list(COLUMNS)}")
    if "unit" not in df.columns:
        df = df.assign(unit="")
    blank = df["channel"].isna().to_numpy() | (df["channel"].astype(str).str.strip() == "").to_numpy()
    if blank.any():
        rows = np.flatnonzero(blank) + 1
        raise RunFileError(f"{path}: {rows.size} data row(s) have no channel name (row(s) "
                           f"{', '.join(map(str, rows[:10]))}{', ...' if rows.size > 10 else ''}, counted from 1 "
                           "after the column header); their samples cannot be given to any channel")
    df = _seconds(df, path)
    channels = {}
    for name, g in df.groupby("channel", sort=False):
        t = _numbers(g["t_s"], path, name, "t_s")
        v = _numbers(g["value"], path, name, "value")
        if np.isnan(t).any():
            raise RunFileError(f"{path}: channel {name!r} has rows without a time stamp t_s")
        order = np.argsort(t, kind="stable")
        units = g["unit"].fillna("").astype(str).unique()
        if len(units) > 1:
            raise RunFileError(f"{path}: channel {name!r} has several units {list(units)}")
        channels[str(name)] = RawChannel(str(name), t[order], v[order], units[0] if len(units) else "")
    if not channels:
        raise RunFileError(f"{path}: no samples")
    return RawRecording(channels, dict(header))


def read_parquet(path: Path) -> RawRecording:
    import pyarrow.parquet as pq

    try:
        table = pq.read_table(path)
    except Exception as exc:  # noqa: BLE001 - pyarrow raises several kinds on a damaged file
        raise RunFileError(f"{path}: not a readable Parquet file ({type(exc).__name__}: {exc})") from None
    meta = table.schema.metadata or {}
    header = {}
    if HEADER_KEY in meta:
        try:
            header = {str(k): str(v) for k, v in json.loads(meta[HEADER_KEY]).items()}
        except (ValueError, AttributeError):
            raise RunFileError(f"{path}: the run_header metadata is not a JSON object") from None
    return _from_frame(table.to_pandas(), header, path)


def read_csv_header(path: Path) -> tuple[dict[str, str], int]:
    """The ``# key = value`` header lines of a CSV run table, and how many lines they take.

    Raises RunFileError when a key is given twice with two values (which one holds cannot be told).
    """
    return read_hash_header(path, RunFileError)


def read_csv(path: Path) -> RawRecording:
    header, skip = read_csv_header(path)
    try:
        df = pd.read_csv(path, skiprows=skip, encoding="utf-8-sig", dtype={"channel": str, "unit": str},
                         low_memory=False)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise RunFileError(f"{path}: not a readable CSV run table: neither a long table (columns channel, t_s, "
                           f"value, unit) nor a wide one (a column header starting with a time column within the "
                           f"first lines); pandas: {str(exc).strip()}") from None
    df.columns = [str(c).strip() for c in df.columns]
    return _from_frame(df, header, path)


def write_run_table(channels: Mapping[str, RawChannel], header: Mapping[str, str], path, fmt: str | None = None
                    ) -> Path:
    """Write raw channels and a header as a Parquet (``.parquet``) or CSV (``.csv``) run table."""
    p = Path(path)
    fmt = fmt or ("csv" if p.suffix.lower() == ".csv" else "parquet")
    frames = [pd.DataFrame({"channel": c.name, "t_s": np.asarray(c.t, float), "value": np.asarray(c.values, float),
                            "unit": c.unit}) for c in channels.values()]
    df = pd.concat(frames, ignore_index=True)
    if fmt == "csv":
        with open(p, "w", encoding="utf-8", newline="") as fh:
            for k, v in header.items():
                fh.write(f"# {k} = {v}\n")
            df.to_csv(fh, index=False, float_format="%.10g")
    elif fmt == "parquet":
        import pyarrow as pa
        import pyarrow.parquet as pq

        table = pa.Table.from_pandas(df, preserve_index=False)
        table = table.replace_schema_metadata({**(table.schema.metadata or {}),
                                               HEADER_KEY: json.dumps(dict(header)).encode()})
        pq.write_table(table, p)
    else:
        raise ValueError(f"fmt must be 'csv' or 'parquet', got {fmt!r}")
    return p
