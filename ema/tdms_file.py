"""Opening NI TDMS files (LabVIEW, FlexLogger, SignalExpress, DAQmx logging) through npTDMS.

Shared by the hammer-test reader (:mod:`ema.hammer_tdms`) and the field run reader (:mod:`estimator.io.tdms`),
which imports it from here because imports flow ``ema`` <- ``estimator``.

A TDMS file holds groups of channels; a channel's samples come with NI's waveform properties (``wf_increment``
the sampling interval [s], ``wf_start_offset`` [s], ``wf_start_time`` the absolute start) or, in files written
without them, beside a time channel of their group (``Time``, ``time``, ``t``, in s). :func:`channel_records`
gives every numeric channel with its time stamps and unit (``unit_string``, NI's unit property):

* waveform channels: ``t = start + wf_start_offset + k wf_increment``, where ``start`` is the channel's
  ``wf_start_time`` in seconds after the earliest ``wf_start_time`` of the file when every waveform channel has
  one (a triggered acquisition's records then sit at their trigger times), else 0;
* other channels: the group's time channel, which must have as many samples.

npTDMS reads a file cut short as far as it goes and only logs a WARNING (``Last segment of file has less data
than expected``); :func:`open_tdms` turns that into a refusal naming the file, so a half record is never read as
a whole one (and npTDMS's own lines, which say it "will attempt to read to the end", do not reach the terminal).
Before npTDMS reads, :func:`check_segments` walks the segment lead-ins itself, so a cut file is refused even
where a program's logging setup silences npTDMS's warning.
"""

from __future__ import annotations

import logging
import struct
from pathlib import Path
from typing import NamedTuple

import numpy as np

__all__ = ["sniff_tdms", "open_tdms", "check_segments", "channel_records", "TdmsChannel", "TIME_NAMES"]

#: Names of a group's explicit time channel (compared without case).
TIME_NAMES = ("time", "t", "zeit", "timestamp", "time [s]")
#: npTDMS's WARNING texts of a file cut short.
_CUT = ("less data than expected", "not a multiple of the chunk size", "incomplete")


def sniff_tdms(head: bytes) -> bool:
    """True for a TDMS file: its first segment's lead-in tag is ``TDSm`` (an index file, ``.tdms_index``, starts
    ``TDSh`` and holds no data)."""
    return head[:4] == b"TDSm"


_LEAD_IN = 28
_BIG_ENDIAN = 1 << 6
_INCOMPLETE = 0xFFFFFFFFFFFFFFFF


def check_segments(path: Path, error: type[Exception], what: str = "TDMS file") -> int:
    """Walk the file's segment lead-ins (TDMS file format: ``TDSm``, the table-of-contents mask, the version, the
    next segment's offset and the raw data's offset); the number of segments, or ``error`` for a file cut short
    (a segment reaching past the end of the file, or the offset LabVIEW leaves at -1 in a file it never closed)
    or a lead-in that is not one. This does not depend on npTDMS's warnings, which a program's logging setup may
    silence."""
    size = Path(path).stat().st_size
    count = pos = 0
    with open(path, "rb") as fh:
        while pos < size:
            fh.seek(pos)
            head = fh.read(_LEAD_IN)
            if len(head) < _LEAD_IN:
                raise error(f"{path}: the {what} is cut short: segment {count + 1} at byte {pos} has "
                            f"{len(head)} of the {_LEAD_IN} bytes of its lead-in; copy it again")
            if head[:4] != b"TDSm":
                raise error(f"{path}: segment {count + 1} at byte {pos} does not start with 'TDSm' (a damaged "
                            f"{what})")
            order = ">" if struct.unpack("<I", head[4:8])[0] & _BIG_ENDIAN else "<"
            next_offset = struct.unpack(order + "Q", head[12:20])[0]
            end = pos + _LEAD_IN + next_offset
            if next_offset == _INCOMPLETE or end > size:
                raise error(f"{path}: the {what} is cut short: segment {count + 1} at byte {pos} ends "
                            + ("nowhere (the writer never closed it)" if next_offset == _INCOMPLETE else
                               f"at byte {end}, the file at byte {size}") + "; copy it again")
            count += 1
            pos = end
    return count


class _Collect(logging.Handler):
    def __init__(self):
        super().__init__(logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record):
        self.messages.append(record.getMessage())


def open_tdms(path: Path, error: type[Exception], what: str = "TDMS file"):
    """``nptdms.TdmsFile.read(path)``, or ``error`` naming the file: one npTDMS cannot read, or one it reads only
    in part (cut short)."""
    from nptdms import TdmsFile

    check_segments(path, error, what)
    collect = _Collect()
    # npTDMS gives each of its loggers a stderr handler: while it reads, its words go to this refusal only
    loggers = [logging.getLogger(n) for n in list(logging.root.manager.loggerDict) if n.startswith("nptdms.")]
    saved = [(lg, lg.handlers[:], lg.propagate) for lg in loggers]
    top = logging.getLogger("nptdms")
    top_saved = (top.handlers[:], top.propagate)
    for lg in loggers:
        lg.handlers, lg.propagate = [], True
    top.handlers, top.propagate = [collect], False
    try:
        try:
            tdms = TdmsFile.read(str(path))
        except Exception as exc:  # noqa: BLE001 - npTDMS raises ValueError, KeyError, struct.error... on damage
            raise error(f"{path}: not a readable {what} ({type(exc).__name__}: {exc}); the file may be truncated "
                        f"or corrupt") from None
    finally:
        for lg, handlers, propagate in saved:
            lg.handlers, lg.propagate = handlers, propagate
        top.handlers, top.propagate = top_saved
    cut = [m for m in collect.messages if any(c in m.lower() for c in _CUT)]
    if cut:
        raise error(f"{path}: the {what} is cut short: its last segment holds less data than the segment's lead-in "
                    f"says; copy it again")
    if not any(True for g in tdms.groups() for _ in g.channels()):
        raise error(f"{path}: the {what} holds no channel; the file may be truncated")
    return tdms


class TdmsChannel(NamedTuple):
    """A numeric channel: its group (index in the file and name), name, time stamps [s], values, unit."""

    group: int
    group_name: str
    name: str
    t: np.ndarray
    values: np.ndarray
    unit: str


def _seconds(start, origin) -> float:
    return float((np.datetime64(start, "ns") - np.datetime64(origin, "ns")) / np.timedelta64(1, "ns")) * 1e-9


def channel_records(tdms, path: Path, error: type[Exception]) -> tuple[list[TdmsChannel], dict[str, str]]:
    """Every numeric channel of an open file with its time stamps (module docstring), and the channels that
    cannot be used with the reason (text values, no time base).

    ``error`` is raised for a waveform property that is not a positive finite number (names the channel).
    """
    groups = list(tdms.groups())
    starts = [c.properties.get("wf_start_time") for g in groups for c in g.channels()
              if "wf_increment" in c.properties]
    origin = min(np.datetime64(s, "ns") for s in starts) if starts and all(s is not None for s in starts) else None
    out: list[TdmsChannel] = []
    unusable: dict[str, str] = {}
    for k, group in enumerate(groups):
        channels = list(group.channels())
        clock = [c for c in channels if c.name.strip().casefold() in TIME_NAMES and "wf_increment" not in c.properties]
        for ch in channels:
            label = f"{ch.name} (group {group.name!r})"
            if clock and ch is clock[0]:
                continue
            values = np.asarray(ch[:])
            if values.dtype.kind not in "fiu":
                unusable[ch.name] = f"its values are not numbers ({values.dtype}) in group {group.name!r}"
                continue
            props = ch.properties
            unit = str(props.get("unit_string", "") or "").strip()
            if "wf_increment" in props:
                dt = float(props["wf_increment"])
                offset = float(props.get("wf_start_offset", 0.0) or 0.0)
                if not (np.isfinite(dt) and dt > 0 and np.isfinite(offset)):
                    raise error(f"{path}: channel {label}: waveform interval wf_increment = {dt!r} s (and offset "
                                f"{offset!r} s); it must be a positive number")
                start = _seconds(props["wf_start_time"], origin) if origin is not None else 0.0
                t = start + offset + dt * np.arange(values.size)
            elif clock:
                t = np.asarray(clock[0][:], float)
                if t.size != values.size:
                    raise error(f"{path}: channel {label} has {values.size} samples, its group's time channel "
                                f"{clock[0].name!r} {t.size}")
            else:
                unusable[ch.name] = (f"no time base in group {group.name!r}: neither waveform properties "
                                     f"(wf_increment) nor a time channel ({', '.join(TIME_NAMES[:3])})")
                continue
            out.append(TdmsChannel(k, group.name, ch.name, t, values.astype(float), unit))
    return out, unusable
