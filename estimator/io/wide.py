"""Wide CSV run files: a time column, then one column per channel — what most DAQ software exports.

Layout (``# key = value`` run-header lines first, as in the long CSV of :mod:`estimator.io.tabular`)::

    # run_id = 20240304_01_fw
    time [s],ACC_W1L_Z [g],ACC_W1R_Z [g],...,SPEED [km/h],BALISE [m]
    0.000,0.0123,-0.0045,...,36.0,
    0.001,0.0131,-0.0050,...,,

* The first column is the time: named ``t``, ``t_s``, ``time`` or ``zeit`` (any case), in seconds unless its header
  gives ``[ms]`` or ``[us]``.
* A channel's unit is its header's bracket (``name [unit]`` or ``name (unit)``); none: the sensor table's unit is
  taken, as for a long table with a blank unit.
* Channels of different rates share the rows: an **empty cell is no sample** of that channel (speed at 100 Hz in a
  1 kHz table, one cell per balise passage), while a cell reading ``NaN`` is a sample that is missing (a dropout,
  masked by quality control). Any other text is refused, naming the row and column.
* Separator ``,``, ``;`` or tab, sniffed from the column header; with ``;`` a decimal comma is accepted
  (``0,0123``), as spreadsheets in much of Europe write it.
* Plain-text lines before the column header (a DAQ program's preamble: its name, the start time, a comment),
  up to :data:`MAX_PREAMBLE_LINES` of them, are the run header too: ``key: value``, ``key = value`` or a row of
  two fields gives ``key``; any other line is kept under ``preamble``. The column header is the first line whose
  first field is a time column's name.
"""

from __future__ import annotations

import csv
import re
from pathlib import Path

import numpy as np
import pandas as pd

from estimator.errors import RunFileError
from estimator.io.registry import RawChannel, RawRecording
from estimator.io.tabular import NAN_WORDS, read_csv_header

__all__ = ["sniff_wide_csv", "read_wide_csv", "write_wide_csv", "TIME_NAMES", "MAX_PREAMBLE_LINES"]

TIME_NAMES = ("t", "t_s", "time", "zeit")
_TIME_UNITS = {"": 1.0, "s": 1.0, "sec": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6}
#: plain-text lines looked through for the column header (a DAQ program's preamble is a few lines)
MAX_PREAMBLE_LINES = 40
_KEY_VALUE = re.compile(r"^\s*(?P<key>[^:=]*?[^:=\s])\s*[:=]\s*(?P<value>.*?)\s*$")
_HEAD = re.compile(r"^\s*(?P<name>.*?)\s*(?:[\[(]\s*(?P<unit>[^\])]*?)\s*[\])])?\s*$")


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


def sniff_wide_csv(path: Path, head: bytes) -> bool:
    try:
        text = head.decode("utf-8-sig")
    except UnicodeDecodeError:
        return False
    lines = [ln for ln in text.splitlines() if not ln.startswith("#")]
    # the last line of the head may be cut: only whole lines decide
    return _preamble(lines[:-1] if len(head) == 4096 else lines) is not None


def _preamble_header(path: Path, lines: list[str], header: dict[str, str]) -> dict[str, str]:
    """The run header with the preamble's lines: ``key: value`` / ``key = value`` / two fields, the rest kept as
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
            raise RunFileError(f"{path}: header key {k!r} is given twice ({out[k]!r}, then {v!r}); which one holds "
                               "cannot be told")
        out[k] = v
    if free:
        out["preamble"] = " | ".join(free)
    return out


def read_wide_csv(path: Path) -> RawRecording:
    header, skip = read_csv_header(path)
    with open(path, encoding="utf-8-sig") as fh:
        for _ in range(skip):
            fh.readline()
        plain = [fh.readline() for _ in range(MAX_PREAMBLE_LINES + 1)]
    k = _preamble(plain)
    if k is None:
        raise RunFileError(f"{path}: no column header starting with a time column ({', '.join(TIME_NAMES)}) in the "
                           f"{MAX_PREAMBLE_LINES} lines after the '#' header; a wide CSV run file has one, then one "
                           "row per time step")
    header = _preamble_header(path, plain[:k], header)
    skip += k
    first = plain[k]
    sep = _separator(first)
    try:
        df = pd.read_csv(path, skiprows=skip, sep=sep, encoding="utf-8-sig", dtype=str, keep_default_na=False)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise RunFileError(f"{path}: not a readable CSV run table ({exc})") from None
    # pandas renames a repeated column ("x.1") and pads a short row with blanks (a channel without a sample
    # there): both are judged on the file's own text
    cols = [c.strip() for c in next(csv.reader([first.rstrip("\r\n")], delimiter=sep))]
    if len(cols) != df.shape[1]:
        raise RunFileError(f"{path}: the column header has {len(cols)} fields but the table {df.shape[1]} columns")
    _ragged_rows(path, skip + 1, sep, len(cols))
    t_name, t_unit = _name_unit(cols[0])
    if t_name.lower() not in TIME_NAMES or len(cols) < 2:
        raise RunFileError(f"{path}: a wide CSV run file starts with a time column ({', '.join(TIME_NAMES)}) and "
                           f"has one column per channel; found {cols[:5]}")
    if t_unit.strip() not in _TIME_UNITS:
        raise RunFileError(f"{path}: time column {cols[0]!r}: unit {t_unit!r} is not one of "
                           f"{sorted(k for k in _TIME_UNITS if k)}")
    decimal_comma = sep == ";"
    t = _numbers(df.iloc[:, 0], path, cols[0], decimal_comma, allow_blank=False) * _TIME_UNITS[t_unit.strip()]
    channels = {}
    for j, col in enumerate(cols[1:], start=1):
        name, unit = _name_unit(col)
        if not name:
            raise RunFileError(f"{path}: column {j + 1} has no channel name in the header")
        if name in channels:
            raise RunFileError(f"{path}: channel {name!r} is given by two columns")
        cells = df.iloc[:, j]
        present = cells.str.strip() != ""
        v = _numbers(cells[present], path, col, decimal_comma, allow_blank=True)
        tc = t[present.to_numpy()]
        order = np.argsort(tc, kind="stable")
        channels[name] = RawChannel(name, tc[order], v[order], unit)
    if not channels or all(c.t.size == 0 for c in channels.values()):
        raise RunFileError(f"{path}: no samples")
    return RawRecording(channels, dict(header))


def _ragged_rows(path: Path, header_lines: int, sep: str, n_fields: int) -> None:
    """Refuse a data row with fewer or more fields than the column header (a file cut short, a lost cell).

    A blank cell keeps its separators (``1.0,,2.0``), so a short row is a damaged one, not a missing sample.
    Counted on the bytes (numeric run tables quote nothing), at the speed of the reading itself.
    """
    raw = np.frombuffer(path.read_bytes(), np.uint8)
    newline = np.flatnonzero(raw == ord("\n"))
    ends = np.append(newline, raw.size) if raw.size and raw[-1] != ord("\n") else newline
    starts = np.concatenate([[0], newline + 1])[:ends.size]
    seps = np.concatenate([[0], np.cumsum(raw == ord(sep))])
    count = seps[ends] - seps[starts]
    length = ends - starts - (raw[np.maximum(ends - 1, 0)] == ord("\r"))
    data = np.arange(ends.size) >= header_lines
    bad = np.flatnonzero(data & (length > 0) & (count != n_fields - 1))
    if bad.size:
        k = int(bad[0])
        raise RunFileError(f"{path}: data row {k - header_lines + 1} (line {k + 1}) has {int(count[k]) + 1} field(s), "
                           f"the column header {n_fields}: the file is cut short or the row lost cells"
                           + (f" ({bad.size} such rows)" if bad.size > 1 else ""))


def _numbers(cells: pd.Series, path: Path, column: str, decimal_comma: bool, *, allow_blank: bool) -> np.ndarray:
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
        raise RunFileError(f"{path}: column {column!r}, data row {row} (counted from 1 after the column header): "
                           f"{cells.iloc[k]!r} is not a number")
    return values


def write_wide_csv(channels, header, path) -> Path:
    """Raw channels (a mapping of :class:`RawChannel`) and a header as a wide CSV run file: the union of the channels'
    time stamps as rows, an empty cell where a channel has no sample."""
    p = Path(path)
    t = np.unique(np.concatenate([np.asarray(c.t, float) for c in channels.values()]))
    out = {"time [s]": [f"{v:.17g}" for v in t]}
    for c in channels.values():
        col = np.full(t.size, "", dtype=object)
        col[np.searchsorted(t, np.asarray(c.t, float))] = [f"{v:.17g}" for v in np.asarray(c.values, float)]
        out[f"{c.name} [{c.unit}]" if c.unit else c.name] = col
    with open(p, "w", encoding="utf-8", newline="") as fh:
        for k, v in header.items():
            fh.write(f"# {k} = {v}\n")
        pd.DataFrame(out).to_csv(fh, index=False)
    return p
