"""Reading a hammer test recorded by a data logger into an ASAM MDF file (MDF 3 or 4, through asammdf).

Data loggers (the acquisition systems that write MDF: HBM, Dewesoft, IMC, Vector...) record a hammer test in one
of two ways:

* **continuously**: one long record per channel, the operator hitting the wheelset every few seconds.
  :func:`read_hammer_mdf` reads it as a test of one hit; :func:`ema.read_hammer` then cuts it into one hit per
  impact (:mod:`ema.continuous`);
* **triggered**: one record per trigger, each written as its own channel group (or as one group per measuring
  module and trigger) holding the same channel names. Each force record is one hit, numbered in time order
  (in group order where the logger restarts the time stamps at every trigger); each response is the copy sampled
  at that force record's instants, or, where several are, the one in the force's own group.

The channel table (:mod:`ema.channels`) selects the channels **by name**: the row's ``name`` is the channel's
name in the file (exactly, else the one file channel whose name differs only in case and surrounding blanks).
Positions, directions and FE nodes come from the table, as for UFF; the samples, their time stamps and the
unit (the channel's physical unit after asammdf applies its conversion) from the file. Units and sensitivities
follow :func:`ema.hammer_io.unit_scale`, as for UFF. Copies of a channel with identical data (a logger's
overview group beside its detail group) are one record.

Refused by name (file, channel, hit): a damaged file (:class:`~ema.hammer_io.MDFReadError`), a table channel the
file lacks, two different records of a channel that could both be a hit's, a hit without one of the table's
responses, a response record that belongs to no force record (nothing in the file is silently left out), values
that are not numbers (:class:`~ema.hammer_io.ChannelMismatchError`); time stamps that are not evenly spaced (a
gap where samples were lost), channels at another rate or on another time base than the force, triggered records
of different lengths or rates (:class:`~ema.hammer_io.SamplingError`); a channel whose unit changes from hit to
hit (:class:`~ema.hammer_io.UnitSystemError`). File channels without a table row are skipped with a WARNING
naming them.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pandas as pd

from .hammer_io import ChannelMismatchError, HammerTest, MDFReadError
from .hammer_records import ChannelRecord, hammer_test_from_records, match_names, same_record
from .mdf_file import open_mdf, sniff_mdf

__all__ = ["read_hammer_mdf", "sniff"]

log = logging.getLogger("ema")


def sniff(path: Path) -> bool:
    """True when ``path`` starts with an MDF identification block."""
    with open(path, "rb") as fh:
        return sniff_mdf(fh.read(8))


def _copies(mdf, p: str, name: str, where: list[tuple[int, int]], masters: dict) -> list[ChannelRecord]:
    """Every distinct record of one channel in the file (copies with the same data are one), in group order."""
    read: list[ChannelRecord] = []
    for group, index in where:
        if index == masters.get(group):
            continue
        try:
            sig = mdf.get(name, group=group, index=index, raw=False)
        except Exception as exc:  # noqa: BLE001 - asammdf raises many kinds on a damaged block
            raise MDFReadError(f"{p}: channel {name!r} (channel group {group}) cannot be read ({type(exc).__name__}: "
                               f"{exc}); the file may be truncated") from None
        values = np.asarray(sig.samples)
        if values.dtype.kind not in "fiu":
            raise ChannelMismatchError(f"{p}: channel {name!r} (channel group {group}): its values are not numbers "
                                       f"({values.dtype}); a hammer test needs a force or acceleration signal")
        rec = ChannelRecord(np.asarray(sig.timestamps), values.astype(float), str(sig.unit or "").strip(), group,
                            f"channel group {group}")
        if not any(same_record(rec, other) for other in read):
            read.append(rec)
    return read


def read_hammer_mdf(path: Path, channels: pd.DataFrame) -> HammerTest:
    """A hammer test from an MDF file: one hit per force record (module docstring).

    Parameters
    ----------
    path : Path
    channels : pandas.DataFrame
        Validated channel table; its ``name`` column names the file's channels.

    Returns
    -------
    HammerTest
        One hit per triggered record, or one hit of the whole recording, which :func:`ema.read_hammer` cuts
        into hits when it holds several impacts.
    """
    p = str(path)
    log.info("reading hammer test %s (%.1f MB, MDF)", p, path.stat().st_size / 1e6)
    mdf = open_mdf(path, MDFReadError, "MDF file")
    try:
        masters = dict(mdf.masters_db)
        db = {n: list(w) for n, w in mdf.channels_db.items()
              if n and any(i != masters.get(g) for g, i in w)}
        names = sorted(db)
        rows, found = match_names(p, channels, names, "the logger's")
        copies = {key: _copies(mdf, p, name, db[name], masters) for key, name in found.items()}
    finally:
        mdf.close()
    return hammer_test_from_records(p, channels, rows, found, names, copies, "MDF")
