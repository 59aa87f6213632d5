"""Reading a hammer test recorded into an NI TDMS file (LabVIEW, FlexLogger, SignalExpress; through npTDMS).

A lab whose acquisition runs on NI hardware logs a hammer test as a TDMS file of groups of channels
(:mod:`ema.tdms_file`), in one of the two ways a data logger does (:mod:`ema.hammer_mdf`):

* **continuously**: one group, one long waveform per channel; :func:`ema.read_hammer` cuts it into hits at the
  impacts (:mod:`ema.continuous`);
* **triggered**: one group per trigger (LabVIEW's "one group per acquisition", FlexLogger's triggered logging)
  holding the same channel names. Each force record is one hit, numbered in time order (the records'
  ``wf_start_time``), or in group order where the time stamps restart at every trigger; each response is the copy
  sampled at its force record's instants, or, where several are, the one in the force's own group.

The channel table selects the channels **by name** (:func:`ema.hammer_records.match_names`): positions,
directions and FE nodes come from the table; samples (npTDMS applies DAQmx scaling), time stamps (waveform
properties, or the group's time channel) and the unit (``unit_string``) from the file. Units and sensitivities
follow :func:`ema.hammer_io.unit_scale`. Copies of a channel with identical data are one record.

Refused by name (file, channel, hit): a file npTDMS cannot read or reads only in part (cut short,
:class:`~ema.hammer_io.TDMSReadError`), a table channel the file lacks or holds only without a time base, and
the record checks of :func:`ema.hammer_records.hammer_test_from_records` (gaps, rates, lengths, units, orphan
records). File channels without a table row are skipped with a WARNING naming them.
"""

from __future__ import annotations

import logging
from pathlib import Path

import pandas as pd

from .hammer_io import ChannelMismatchError, HammerTest, TDMSReadError
from .hammer_records import ChannelRecord, hammer_test_from_records, match_names, same_record
from .tdms_file import channel_records, open_tdms

__all__ = ["read_hammer_tdms"]

log = logging.getLogger("ema")


def read_hammer_tdms(path: Path, channels: pd.DataFrame) -> HammerTest:
    """A hammer test from a TDMS file: one hit per force record (module docstring).

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
    log.info("reading hammer test %s (%.1f MB, TDMS)", p, path.stat().st_size / 1e6)
    tdms = open_tdms(path, TDMSReadError, "TDMS file")
    records, unusable = channel_records(tdms, path, TDMSReadError)
    by_name: dict[str, list[ChannelRecord]] = {}
    for rec in records:
        new = ChannelRecord(rec.t, rec.values, rec.unit, rec.group, f"group {rec.group} ({rec.group_name!r})")
        same = by_name.setdefault(rec.name, [])
        if not any(same_record(new, other) for other in same):
            same.append(new)
    names = sorted(by_name)
    for name, why in unusable.items():
        if name not in by_name and name.strip().casefold() in {str(n).strip().casefold() for n in channels["name"]}:
            raise ChannelMismatchError(f"{p}: channel {name!r} of the channel table cannot be read: {why}")
    rows, found = match_names(p, channels, names, "the TDMS file's")
    copies = {key: by_name[name] for key, name in found.items()}
    return hammer_test_from_records(p, channels, rows, found, names, copies, "TDMS", group_word="group")
