"""Wide CSV tables of time histories: a time column, then one column per channel — what most DAQ software exports.

Shared by the hammer-test reader (:mod:`ema.hammer_csv`) and the field run reader (:mod:`estimator.io.wide`),
which imports it from here because imports flow ``ema`` <- ``estimator``. Each caller passes its own error type.

Layout (``# key = value`` header lines first, optional)::

    # run_id = 20240304_01_fw
    time [s],ACC_W1L_Z [g],ACC_W1R_Z [g],...,SPEED [km/h],BALISE [m]
    0.000,0.0123,-0.0045,...,36.0,
    0.001,0.0131,-0.0050,...,,

* The first column is the time: named ``t``, ``t_s``, ``time`` or ``zeit`` (any case), in seconds unless its header
  gives ``[ms]`` or ``[us]``.
* A channel's unit is its header's bracket (``name [unit]`` or ``name (unit)``); none: blank (the caller's table
  decides).
* Channels of different rates share the rows: an **empty cell is no sample** of that channel (speed at 100 Hz in a
  1 kHz table, one cell per balise passage), while a cell reading ``NaN`` is a sample that is missing (a dropout).
  Any other text is refused, naming the row and column.
* Separator ``,``, ``;`` or tab, sniffed from the column header; with ``;`` a decimal comma is accepted
  (``0,0123``), as spreadsheets in much of Europe write it.
* Plain-text lines before the column header (a DAQ program's preamble: its name, the start time, a comment),
  up to :data:`MAX_PREAMBLE_LINES` of them, are header too: ``key: value``, ``key = value`` or a row of two fields
  gives ``key``; any other line is kept under ``preamble``. The column header is the first line whose first field
  is a time column's name.
* A row with fewer or more fields than the column header (a file cut short, a lost cell) is refused by line.

A table of numbers, blank cells and NaN words is parsed in one pass of pandas' C parser, 8 bytes a cell (the
blank cells told from the NaN words by the file's bytes); a table with a damaged cell (a word, a quoted field)
is read cell by cell, which names the bad cell by row and column. The row check locates the separators by
position. ``benchmarks/bench_wide_csv.py``: a 125 MB export of 30 channels reads in 0.9 s within 0.43 GB (cell
by cell 8 s, 0.55 GB; before, with a cumulative count per byte in the row check, 11 s and 2.6 GB).
"""

from __future__ import annotations

import csv
import re
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pandas as pd

__all__ = ["WideColumn", "WideTable", "read_wide_table", "read_hash_header", "sniff_wide", "TIME_NAMES",
           "MAX_PREAMBLE_LINES", "NAN_WORDS"]

TIME_NAMES = ("t", "t_s", "time", "zeit")
_TIME_UNITS = {"": 1.0, "s": 1.0, "sec": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6}
#: plain-text lines looked through for the column header (a DAQ program's preamble is a few lines)
MAX_PREAMBLE_LINES = 40
#: cells read as a missing sample (NaN), not as damage
NAN_WORDS = frozenset({"", "nan", "-nan", "+nan", "na", "n/a", "null", "none"})
_KEY_VALUE = re.compile(r"^\s*(?P<key>[^:=]*?[^:=\s])\s*[:=]\s*(?P<value>.*?)\s*$")
_HEAD = re.compile(r"^\s*(?P<name>.*?)\s*(?:[\[(]\s*(?P<unit>[^\])]*?)\s*[\])])?\s*$")


class WideColumn(NamedTuple):
    """One channel of a wide table: its time stamps [s] (the rows where it has a cell), values, unit."""

    name: str
    t: np.ndarray
    values: np.ndarray
    unit: str


class WideTable(NamedTuple):
    """A wide table read: the header's fields (strings) and the channels by name, in column order."""

    header: dict[str, str]
    columns: dict[str, WideColumn]


def _name_unit(column: str) -> tuple[str, str]:
    m = _HEAD.match(str(column))
    return (m.group("name"), m.group("unit") or "") if m else (str(column).strip(), "")


def _separator(line: str) -> str:
    counts = {sep: line.count(sep) for sep in (",", ";", "\t")}
    return max(counts, key=counts.get)


def _is_column_header(line: str) -> bool:
    cols = next(csv.reader([line], delimiter=_separator(line)), [])
    return len(cols) >= 2 and _name_unit(cols[0])[0].lower() in TIME_NAMES and "channel" not in cols


def _preamble(lines) -> int | None:
    """Index of the column header among the plain lines after the ``#`` header (None: not within the limit)."""
    for k, line in enumerate(lines):
        if k >= MAX_PREAMBLE_LINES:
            return None
        if _is_column_header(line.rstrip("\r\n")):
            return k
    return None


def sniff_wide(head: bytes) -> bool:
    """True when the first bytes of a file hold a column header starting with a time column."""
    try:
        text = head.decode("utf-8-sig")
    except UnicodeDecodeError:
        return False
    lines = [ln for ln in text.splitlines() if not ln.startswith("#")]
    # the last line of the head may be cut: only whole lines decide
    return _preamble(lines[:-1] if len(head) == 4096 else lines) is not None


def read_hash_header(path: Path, error: type[Exception]) -> tuple[dict[str, str], int]:
    """The ``# key = value`` header lines of a CSV table, and how many lines they take.

    Raises ``error`` when a key is given twice with two values (which one holds cannot be told).
    """
    header: dict[str, str] = {}
    skip = 0
    with open(path, encoding="utf-8-sig") as fh:
        for line in fh:
            if not line.startswith("#"):
                break
            skip += 1
            body = line[1:].strip()
            if "=" in body:
                k, v = (x.strip() for x in body.split("=", 1))
                if k in header and header[k] != v:
                    raise error(f"{path}: header key {k!r} is given twice ({header[k]!r}, then {v!r}); "
                                "which one holds cannot be told")
                header[k] = v
    return header, skip


def _preamble_header(path: Path, lines: list[str], header: dict[str, str], error) -> dict[str, str]:
    """The header with the preamble's lines: ``key: value`` / ``key = value`` / two fields, the rest kept as
    ``preamble``; a key given twice with two values is refused, as in the ``#`` header."""
    out, free = dict(header), []
    for line in (ln.strip() for ln in lines):
        if not line:
            continue
        m = _KEY_VALUE.match(line)
        fields = next(csv.reader([line], delimiter=_separator(line)), [])
        if m is not None:
            k, v = m.group("key"), m.group("value")
        elif len(fields) == 2 and fields[0].strip():
            k, v = fields[0].strip(), fields[1].strip()
        else:
            free.append(line)
            continue
        if k in out and out[k] != v:
            raise error(f"{path}: header key {k!r} is given twice ({out[k]!r}, then {v!r}); which one holds "
                        "cannot be told")
        out[k] = v
    if free:
        out["preamble"] = " | ".join(free)
    return out


def read_wide_table(path: Path, error: type[Exception], what: str = "wide CSV file", *,
                    sort: bool = True) -> WideTable:
    """Read a wide CSV table (module docstring); every damage is ``error`` naming the file, row and column.

    Parameters
    ----------
    path : Path
    error : exception type
        The caller's error family.
    what : str
        What the file should be, in the messages (``"wide CSV run file"``).
    sort : bool
        Sort each channel's samples by time (rows out of time order); False keeps the file's row order, where a
        time column stepping back means something (a triggered export's restart).
    """
    header, skip = read_hash_header(path, error)
    with open(path, encoding="utf-8-sig") as fh:
        for _ in range(skip):
            fh.readline()
        plain = [fh.readline() for _ in range(MAX_PREAMBLE_LINES + 1)]
    k = _preamble(plain)
    if k is None:
        raise error(f"{path}: no column header starting with a time column ({', '.join(TIME_NAMES)}) in the "
                    f"{MAX_PREAMBLE_LINES} lines after the '#' header; a {what} has one, then one row per time step")
    header = _preamble_header(path, plain[:k], header, error)
    skip += k
    first = plain[k]
    sep = _separator(first)
    # the column header as the file writes it: pandas would rename a repeated column ("x.1")
    cols = [c.strip() for c in next(csv.reader([first.rstrip("\r\n")], delimiter=sep))]
    _ragged_rows(path, skip + 1, sep, len(cols), error)
    t_name, t_unit = _name_unit(cols[0])
    if t_name.lower() not in TIME_NAMES or len(cols) < 2:
        raise error(f"{path}: a {what} starts with a time column ({', '.join(TIME_NAMES)}) and has one column per "
                    f"channel; found {cols[:5]}")
    if t_unit.strip() not in _TIME_UNITS:
        raise error(f"{path}: time column {cols[0]!r}: unit {t_unit!r} is not one of "
                    f"{sorted(k for k in _TIME_UNITS if k)}")
    names = []
    for j, col in enumerate(cols[1:], start=1):
        name, unit = _name_unit(col)
        if not name:
            raise error(f"{path}: column {j + 1} has no channel name in the header")
        if name in (n for n, _ in names):
            raise error(f"{path}: channel {name!r} is given by two columns")
        names.append((name, unit))
    decimal_comma = sep == ";"
    values = _all_numbers(path, skip, sep, decimal_comma, len(cols))
    t_scale = _TIME_UNITS[t_unit.strip()]
    blank = None
    if values is not None and np.isnan(values).any():
        # a NaN is a blank cell (no sample) or a NaN word (a lost sample): the bytes tell which
        blank = _blank_cells(path, skip + 1, sep, len(cols))
        if blank.shape != values.shape:
            values = None
    if values is not None and not np.isnan(values[:, 0]).any():
        t = values[:, 0] * t_scale
        if sort and not np.all(np.diff(t) >= 0):  # rows out of time order: each channel sorted, as cell by cell
            order = np.argsort(t, kind="stable")
            t, values = t[order], values[order]
            blank = None if blank is None else blank[order]
        columns = {name: (WideColumn(name, t, values[:, j], unit) if blank is None or not blank[:, j].any() else
                          WideColumn(name, t[~blank[:, j]], values[~blank[:, j], j], unit))
                   for j, (name, unit) in enumerate(names, start=1)}
    else:
        columns = _columns_cell_by_cell(path, skip, sep, decimal_comma, cols, names, t_scale, error, what, sort)
    if not columns or all(c.t.size == 0 for c in columns.values()):
        raise error(f"{path}: no samples")
    return WideTable(dict(header), columns)


def _all_numbers(path: Path, skip: int, sep: str, decimal_comma: bool, n_fields: int) -> np.ndarray | None:
    """Every cell as a float in one pass of pandas' C parser (8 bytes a cell), a blank cell or a NaN word as NaN;
    None when a cell is neither a number nor blank nor a NaN word, or a field is quoted: those files are read cell
    by cell (:func:`_columns_cell_by_cell`), which names a bad cell by row and column."""
    words = sorted({v for w in NAN_WORDS - {""} for v in (w, w.upper(), w.capitalize(), "NaN")} | {""})
    with open(path, "rb") as fh:
        if b'"' in fh.read():
            return None
    try:
        df = pd.read_csv(path, skiprows=skip, sep=sep, encoding="utf-8-sig", dtype=np.float64, na_values=words,
                         keep_default_na=False, decimal="," if decimal_comma else ".")
    except (ValueError, pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError):
        return None
    if df.shape[1] != n_fields or df.shape[0] == 0:
        return None
    return df.to_numpy(np.float64)


def _line_bounds(path: Path, sep: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per line of the file, where it starts and ends (a ``\r`` before the newline excluded), and the positions
    of the separators: the file's layout from its bytes, for the row check and for telling blank cells."""
    raw = np.frombuffer(path.read_bytes(), np.uint8)
    newline = np.flatnonzero(raw == ord("\n"))
    ends = np.append(newline, raw.size) if raw.size and raw[-1] != ord("\n") else newline
    starts = np.concatenate([[0], newline + 1])[:ends.size]
    ends = ends - (raw[np.maximum(ends - 1, 0)] == ord("\r"))
    # separators located by position (8 bytes a cell, not a cumulative count per byte)
    at = np.flatnonzero(raw == ord(sep))
    count = np.searchsorted(at, ends) - np.searchsorted(at, starts)
    return starts, ends, at, count


def _blank_cells(path: Path, header_lines: int, sep: str, n_fields: int) -> np.ndarray:
    """``(n_rows, n_fields)``: which cells of the data rows are blank (two separators side by side, or one at a
    row's end), in the rows pandas reads (empty lines skipped). The rows have ``n_fields`` fields
    (:func:`_ragged_rows`)."""
    starts, ends, at, _ = _line_bounds(path, sep)
    data = (np.arange(ends.size) >= header_lines) & (ends > starts)
    starts, ends = starts[data], ends[data]
    first = np.searchsorted(at, starts)
    bounds = np.column_stack([starts - 1, at[first[:, None] + np.arange(n_fields - 1)], ends])
    return np.diff(bounds, axis=1) == 1


def _columns_cell_by_cell(path: Path, skip: int, sep: str, decimal_comma: bool, cols: list[str],
                          names: list[tuple[str, str]], t_scale: float, error, what: str,
                          sort: bool = True) -> dict[str, WideColumn]:
    """The channels of a table the one-pass parse does not take (a damaged cell, a quoted field, a blank time),
    read cell by cell, so that a bad cell is named by row and column."""
    try:
        df = pd.read_csv(path, skiprows=skip, sep=sep, encoding="utf-8-sig", dtype=str, keep_default_na=False)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise error(f"{path}: not a readable {what} ({exc})") from None
    if len(cols) != df.shape[1]:
        raise error(f"{path}: the column header has {len(cols)} fields but the table {df.shape[1]} columns")
    t = _numbers(df.iloc[:, 0], path, cols[0], decimal_comma, error, allow_blank=False) * t_scale
    columns: dict[str, WideColumn] = {}
    for j, (name, unit) in enumerate(names, start=1):
        cells = df.iloc[:, j]
        present = cells.str.strip() != ""
        v = _numbers(cells[present], path, cols[j], decimal_comma, error, allow_blank=True)
        tc = t[present.to_numpy()]
        order = np.argsort(tc, kind="stable") if sort else slice(None)
        columns[name] = WideColumn(name, tc[order], v[order], unit)
    return columns


def _ragged_rows(path: Path, header_lines: int, sep: str, n_fields: int, error) -> None:
    """Refuse a data row with fewer or more fields than the column header (a file cut short, a lost cell).

    A blank cell keeps its separators (``1.0,,2.0``), so a short row is a damaged one, not a missing sample.
    Counted on the bytes (numeric tables quote nothing), at the speed of the reading itself.
    """
    starts, ends, _, count = _line_bounds(path, sep)
    data = np.arange(ends.size) >= header_lines
    bad = np.flatnonzero(data & (ends > starts) & (count != n_fields - 1))
    if bad.size:
        k = int(bad[0])
        raise error(f"{path}: data row {k - header_lines + 1} (line {k + 1}) has {int(count[k]) + 1} field(s), "
                    f"the column header {n_fields}: the file is cut short or the row lost cells"
                    + (f" ({bad.size} such rows)" if bad.size > 1 else ""))


def _numbers(cells: pd.Series, path: Path, column: str, decimal_comma: bool, error, *,
             allow_blank: bool) -> np.ndarray:
    """The cells as floats: ``NaN`` words are NaN, anything else that is not a number is refused by row."""
    text = cells.str.strip()
    if decimal_comma:
        text = text.str.replace(",", ".", regex=False)
    nan_word = text.str.lower().isin(NAN_WORDS - {""})  # a blank cell is no sample, judged by the caller
    values = pd.to_numeric(text.where(~nan_word, "nan"), errors="coerce").to_numpy(float)
    bad = np.isnan(values) & ~nan_word.to_numpy()
    if not allow_blank:
        bad |= nan_word.to_numpy()
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        row = int(cells.index[k]) + 1
        raise error(f"{path}: column {column!r}, data row {row} (counted from 1 after the column header): "
                    f"{cells.iloc[k]!r} is not a number")
    return values
