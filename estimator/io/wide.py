"""Wide CSV run files: a time column, then one column per channel — what most DAQ software exports.

The table is parsed by :mod:`ema.wide_csv` (shared with the hammer-test reader); this module makes a run of it.

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

from pathlib import Path

import numpy as np
import pandas as pd

from ema.wide_csv import MAX_PREAMBLE_LINES, TIME_NAMES, read_wide_table, sniff_wide
from estimator.errors import RunFileError
from estimator.io.registry import RawChannel, RawRecording

__all__ = ["sniff_wide_csv", "read_wide_csv", "write_wide_csv", "TIME_NAMES", "MAX_PREAMBLE_LINES"]


def sniff_wide_csv(path: Path, head: bytes) -> bool:
    return sniff_wide(head)


def read_wide_csv(path: Path) -> RawRecording:
    table = read_wide_table(path, RunFileError, "wide CSV run file")
    return RawRecording({n: RawChannel(n, c.t, c.values, c.unit) for n, c in table.columns.items()}, table.header)


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
