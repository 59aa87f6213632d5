"""NI TDMS run files through npTDMS (:mod:`ema.tdms_file`).

A train DAQ on NI hardware (cRIO, cDAQ with LabVIEW or FlexLogger) writes the field contract's channels as
waveforms in groups, one group per time base: the accelerations (``wf_increment`` 1 ms), speed and position at a
lower rate, the balise events as a channel beside a ``Time`` channel of their group (one sample per passage).
The run header (``run_id, date, direction, leading_end, train, bogie, line``; others kept as extras) is the
file's root properties. Waveform time stamps count from the earliest ``wf_start_time`` of the file when every
waveform has one, so channels of different groups share one clock.

A file cut short (npTDMS reads it in part and only warns) is refused, and a name that several groups carry with
different data (:func:`estimator.io.mdf4.same_channel`) is available as ``NAME@GROUP`` (the group's name),
``NAME`` alone listed as unusable, as for an MDF 4 file (:func:`estimator.io.mdf4.read_raw`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ema.tdms_file import channel_records, open_tdms, sniff_tdms
from estimator.errors import RunFileError
from estimator.io.mdf4 import same_channel
from estimator.io.registry import RawChannel, RawRecording

__all__ = ["sniff", "read_raw", "header_text"]


def sniff(path: Path, head: bytes) -> bool:
    return sniff_tdms(head)


def header_text(key: str, value) -> str:
    """A root property as header text: dates as ISO dates (``date``) or ISO times, the rest as ``str``."""
    if isinstance(value, np.datetime64) or hasattr(value, "isoformat"):
        stamp = np.datetime64(value, "s")
        return str(np.datetime64(stamp, "D")) if key == "date" else np.datetime_as_string(stamp, unit="s")
    return str(value).strip()


def read_raw(path: Path) -> RawRecording:
    """Every channel of a TDMS file (time stamps, values, unit) and the root properties as the run header.

    Raises
    ------
    RunFileError
        The file npTDMS cannot read, reads only in part (cut short), holds no numeric channel, or a waveform
        interval that is not a positive number (named).
    """
    tdms = open_tdms(path, RunFileError, "TDMS file")
    header = {str(k): header_text(str(k), v) for k, v in tdms.properties.items() if str(k) != "name"}
    records, unusable = channel_records(tdms, path, RunFileError)
    by_name: dict[str, list] = {}
    for rec in records:
        if rec.name.strip().casefold() in ("time", "t"):
            continue
        by_name.setdefault(rec.name, []).append(rec)
    channels: dict[str, RawChannel] = {}
    for name, recs in by_name.items():
        read = [RawChannel(name, r.t, r.values, r.unit) for r in recs]
        if all(same_channel(read[0], c) for c in read[1:]):
            channels[name] = read[0]
            unusable.pop(name, None)
            continue
        labels = [f"{name}@{r.group_name}" for r in recs]
        for label, c in zip(labels, read):
            channels[label] = RawChannel(label, c.t, c.values, c.unit)
        unusable[name] = (f"groups {[r.group_name for r in recs]} hold {len(recs)} channels of this name with "
                          f"different data; name one of {labels} in the sensor table")
    if not channels:
        raise RunFileError(f"{path}: the TDMS file holds no numeric channel with a time base"
                           + (f" ({'; '.join(f'{k}: {v}' for k, v in list(unusable.items())[:3])})" if unusable
                              else ""))
    return RawRecording(channels, header, unusable)
