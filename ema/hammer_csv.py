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
hit (several files of one hit each make a test, as UFF files do).

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
    """A hammer test from a wide CSV table: one record per table channel, read as one hit (module docstring).

    Parameters
    ----------
    path : Path
    channels : pandas.DataFrame
        Validated channel table; its ``name`` column names the file's columns.

    Returns
    -------
    HammerTest
        One hit; :func:`ema.read_hammer` cuts a continuous recording into hits.

    Raises
    ------
    CSVReadError
        A damaged table (a cell that is not a number, a row cut short, no time column), by row and column.
    SamplingError
        Time stamps too coarse to tell the samples apart, or not evenly spaced; a channel with fewer samples.
    """
    p = str(path)
    log.info("reading hammer test %s (%.1f MB, CSV)", p, path.stat().st_size / 1e6)
    table = read_wide_table(path, CSVReadError, "wide CSV hammer-test file")
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
    copies = {key: [ChannelRecord(table.columns[name].t, table.columns[name].values, table.columns[name].unit, 0,
                                  f"column {column[name]}", res)]
              for key, name in found.items()}
    return hammer_test_from_records(p, channels, rows, found, names, copies, "CSV")
