"""Reading a hammer test exported as a wide CSV table: a time column, then one column per channel.

Most acquisition programs (LabVIEW, Dewesoft, catman, PAK, a spreadsheet) export a recording this way::

    # rig = wheelset 2, flexural setup
    time [s],hammer [N],AX101 [g],AX102 [g],...
    0.0000000,0.012,0.0003,-0.0001,...

The table is parsed by :mod:`ema.wide_csv` (units in the column header's brackets, a ``#`` header or a
preamble, ``;`` with a decimal comma, a ``NaN`` cell a lost sample, damaged rows refused by line). The channel
table selects the columns **by name**, as for an MDF file (:mod:`ema.hammer_records`): positions, directions and
FE nodes come from the table; units and sensitivities follow :func:`ema.hammer_io.unit_scale`. A file is one
record per channel: a continuous recording, which :func:`ema.read_hammer` cuts into hits at the impacts, or one
hit (several files of one hit each make a test, as UFF files do). A triggered export appends one record per
trigger: where the time column steps back (each trigger's own stamps), or jumps forward between records of one
length (absolute trigger times), a new trigger starts, and each trigger is one hit (numbered in the file's order;
every trigger must hold the same number of samples at the same rate). A forward jump between records of
different lengths is a gap in one recording (lost samples), and refused as such.

The time column is decimal text: an export that writes it to, say, 6 decimals rounds every stamp by up to half a
microsecond, which at 12.8 kHz is 0.6 % of the sampling interval. The stamps are judged evenly spaced within
that resolution (found from the text's own decimals), and a time column too coarse to tell the samples apart
(its resolution half the interval or more) is refused. A channel with empty cells (fewer samples than the
force) is refused as a channel at another rate.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pandas as pd

from .hammer_io import CSVReadError, HammerTest, SamplingError
from .hammer_records import ChannelRecord, hammer_test_from_records, match_names
from .wide_csv import read_wide_table, sniff_wide

__all__ = ["read_hammer_csv", "sniff", "time_resolution"]

log = logging.getLogger("ema")

#: Most decimals looked for in a time column (beyond, float64 rounding of the parsed stamps takes over).
MAX_DECIMALS = 12


def sniff(path: Path) -> bool:
    """True when ``path`` starts with a column header whose first field is a time column."""
    with open(path, "rb") as fh:
        return sniff_wide(fh.read(4096))


def time_resolution(t: np.ndarray) -> float:
    """The decimal step the time stamps were written to: the largest ``10**-k`` they are all multiples of.

    Zero when they need more than :data:`MAX_DECIMALS` decimals (written in full precision).
    """
    t = np.asarray(t, float)
    scale = max(float(np.abs(t).max()), 1.0) if t.size else 1.0
    for k in range(MAX_DECIMALS + 1):
        q = 10.0 ** -k
        # a stamp is a multiple of q when it is within float rounding of one
        if np.all(np.abs(t / q - np.round(t / q)) <= 1e-6 + 4 * np.finfo(float).eps * scale / q):
            return q
    return 0.0


def read_hammer_csv(path: Path, channels: pd.DataFrame) -> HammerTest:
    """A hammer test from a wide CSV table: one record per table channel and trigger (module docstring).

    Parameters
    ----------
    path : Path
    channels : pandas.DataFrame
        Validated channel table; its ``name`` column names the file's columns.

    Returns
    -------
    HammerTest
        One hit per trigger; of one record, :func:`ema.read_hammer` cuts a continuous recording into hits.

    Raises
    ------
    CSVReadError
        A damaged table (a cell that is not a number, a row cut short, no time column), by row and column.
    SamplingError
        Time stamps too coarse to tell the samples apart, or not evenly spaced; a channel with fewer samples.
    """
    p = str(path)
    log.info("reading hammer test %s (%.1f MB, CSV)", p, path.stat().st_size / 1e6)
    # the file's row order: a time column stepping back is a triggered export's next trigger
    table = read_wide_table(path, CSVReadError, "wide CSV hammer-test file", sort=False)
    names = list(table.columns)
    rows, found = match_names(p, channels, names, "the export's")
    column = {n: j + 2 for j, n in enumerate(names)}  # column 1 is the time
    # every channel's stamps come from the one time column: its resolution once, from the fullest channel
    t = max((table.columns[n].t for n in found.values()), key=len)
    res = time_resolution(t)
    if t.size > 1 and res > 0:
        dt = float(np.median(np.diff(t)))
        if res >= 0.5 * dt:
            raise SamplingError(f"{p}: the time column is written to {res:g} s, while the samples are "
                                f"{dt:.6g} s apart: the stamps cannot tell them apart; export the time with more "
                                f"decimals")
    copies = {key: _trigger_records(table.columns[name], column[name], res) for key, name in found.items()}
    n_triggers = len(copies[next(k for k in rows if k[1] == "force")])
    if n_triggers > 1:
        log.info("%s: %d triggers (the time column steps back or jumps forward between them), one hit each", p,
                 n_triggers)
    return hammer_test_from_records(p, channels, rows, found, names, copies, "CSV", group_word="trigger")


def _trigger_records(col, column: int, res: float) -> list[ChannelRecord]:
    """A column's records: one, or one per trigger (a triggered export appends each trigger's record).

    A trigger starts where the time column steps back (each record's own stamps, from the pre-trigger's negative
    time, say), or jumps forward when every record so delimited holds the same number of samples (absolute trigger
    times: a fixed record length per trigger). A forward jump that leaves records of different lengths is a gap
    in one recording (lost samples), left for the time-axis check to refuse.
    """
    t, v = col.t, col.values
    steps = np.diff(t)
    back = steps < 0
    forward = np.zeros_like(back)
    if np.any(steps > 0):
        dt = float(np.median(steps[steps > 0]))
        forward = steps > 1.5 * dt + res
    starts = _bounds(back | forward, t.size)
    if forward.any() and len(set(np.diff(starts).tolist())) > 1:
        starts = _bounds(back, t.size)
    if starts.size == 2:
        return [ChannelRecord(t, v, col.unit, 0, f"column {column}", res)]
    return [ChannelRecord(t[a:b], v[a:b], col.unit, k, f"column {column}, trigger {k}", res)
            for k, (a, b) in enumerate(zip(starts[:-1], starts[1:]), start=1)]


def _bounds(cut: np.ndarray, n: int) -> np.ndarray:
    """Record boundaries ``[0, ..., n]`` from the steps after which a new record starts."""
    return np.concatenate([[0], np.flatnonzero(cut) + 1, [n]])
