"""Run-file format registry: ``read_run(path, sensors=..., format=None)`` sniffs the format and dispatches.

A reader is a function ``read_raw(path) -> RawRecording`` registered under a
format name with a sniffer ``sniff(path, head_bytes) -> bool`` (ObsPy's
``read()`` plugin pattern). The built-in formats are MDF 4 (``mdf4``, via
asammdf), NI TDMS (``tdms``, via npTDMS, :mod:`estimator.io.tdms`), Parquet
(``parquet``), CSV as a long table (``csv``) and CSV as a
wide table, one column per channel (``csv-wide``, :mod:`estimator.io.wide`);
:func:`register_format` adds one. An unknown format raises :class:`~estimator.errors.UnknownFormatError`
listing the supported ones.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping

import numpy as np

from estimator.errors import RunFileError, UnknownFormatError

__all__ = ["RawChannel", "RawRecording", "FormatPlugin", "register_format", "formats", "sniff_format", "read_raw"]

log = logging.getLogger("estimator")

#: Largest run file read (a few hours of 6 channels at 1 kHz in float64 is ~1 GB).
MAX_FILE_BYTES = 4 * 1024**3


@dataclass(frozen=True, eq=False)
class RawChannel:
    """One channel as a file holds it: time stamps [s], values (recorded unit), unit."""

    name: str
    t: np.ndarray
    values: np.ndarray
    unit: str = ""


@dataclass(frozen=True, eq=False)
class RawRecording:
    """What a reader returns: channels by name, the run header's fields (strings), and the names the file holds
    but that cannot be used as they stand, each with the reason (e.g. a name several channel groups carry with
    different data; the reason names the qualified names that can be used instead)."""

    channels: Mapping[str, RawChannel]
    header: Mapping[str, str] = field(default_factory=dict)
    unusable: Mapping[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class FormatPlugin:
    name: str
    extensions: tuple[str, ...]
    sniff: Callable[[Path, bytes], bool]
    read: Callable[[Path], RawRecording]
    description: str = ""


_FORMATS: dict[str, FormatPlugin] = {}


def register_format(plugin: FormatPlugin) -> None:
    """Add (or replace) a run-file format."""
    _FORMATS[plugin.name] = plugin


def formats() -> dict[str, FormatPlugin]:
    """The registered formats by name."""
    _builtin()
    return dict(_FORMATS)


def _builtin() -> None:
    if _FORMATS:
        return
    from estimator.io import mdf4, tabular, tdms, wide

    register_format(FormatPlugin("mdf4", (".mf4", ".mdf"), mdf4.sniff, mdf4.read_raw, "ASAM MDF 4 (asammdf)"))
    register_format(FormatPlugin("tdms", (".tdms",), tdms.sniff, tdms.read_raw,
                                 "NI TDMS (npTDMS): waveforms per group, header in the root properties"))
    register_format(FormatPlugin("parquet", (".parquet", ".pq"), tabular.sniff_parquet, tabular.read_parquet,
                                 "long table channel, t_s, value, unit; header in the schema metadata"))
    register_format(FormatPlugin("csv", (".csv", ".txt"), tabular.sniff_csv, tabular.read_csv,
                                 "long table channel, t_s, value, unit; header as '# key = value' lines"))
    register_format(FormatPlugin("csv-wide", (".csv", ".txt"), wide.sniff_wide_csv, wide.read_wide_csv,
                                 "wide table as DAQ software exports it: a time column, then one column per channel "
                                 "'name [unit]', an empty cell where a channel has no sample"))


def sniff_format(path: Path) -> str:
    """The format of ``path`` from its first bytes, then its extension (UnknownFormatError otherwise)."""
    _builtin()
    with open(path, "rb") as fh:
        head = fh.read(4096)
    for plugin in _FORMATS.values():
        try:
            if plugin.sniff(path, head):
                return plugin.name
        except Exception:  # noqa: BLE001 - a sniffer that cannot tell just says no
            continue
    ext = path.suffix.lower()
    for plugin in _FORMATS.values():
        if ext in plugin.extensions:
            return plugin.name
    raise UnknownFormatError(f"{path}: unknown run-file format (first bytes {head[:8]!r}, extension {ext!r}); "
                             f"supported formats: {_supported()}")


def _supported() -> str:
    return ", ".join(f"{p.name} ({'/'.join(p.extensions)}: {p.description})" for p in _FORMATS.values())


def read_raw(path, format: str | None = None) -> tuple[RawRecording, str]:
    """Read a run file with the reader of ``format`` (sniffed when None); returns the recording and the format."""
    _builtin()
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"run file {p} does not exist")
    size = p.stat().st_size
    if size == 0:
        raise RunFileError(f"{p}: the file is empty")
    if size > MAX_FILE_BYTES:
        raise RunFileError(f"{p}: {size / 1e9:.1f} GB; run files are read whole, at most {MAX_FILE_BYTES / 1e9:.1f} GB "
                           "(split the recording)")
    if format is None:
        format = sniff_format(p)
    elif format not in _FORMATS:
        raise UnknownFormatError(f"{p}: format {format!r} is not supported; supported formats: {_supported()}")
    raw = _FORMATS[format].read(p)
    log.info("%s: read as %s, %d channels", p, format, len(raw.channels))
    return raw, format
