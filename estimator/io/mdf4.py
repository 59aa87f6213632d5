"""ASAM MDF 4 run files through asammdf.

The field contract: accelerations, speed, position and balise events as
channels (each with its unit; speed/position may sit in their own channel
group at a lower rate; the balise channel has one sample per passage), and
the run header as ``<common_properties>`` of the header block's comment
(``run_id, date, direction, leading_end, train, bogie, line``).
"""

from __future__ import annotations

import logging
import xml.etree.ElementTree as ET
from collections import Counter
from pathlib import Path

import numpy as np

from ema.mdf_file import open_mdf as open_mdf_file
from ema.mdf_file import sniff_mdf
from estimator.errors import RunFileError
from estimator.io.registry import RawChannel, RawRecording
from estimator.io.sensors import normalise_unit

__all__ = ["sniff", "read_raw", "header_properties", "run_header", "raw_header_comment", "RepeatedHeaderKey",
           "same_channel"]

log = logging.getLogger("estimator")


def sniff(path: Path, head: bytes) -> bool:
    return sniff_mdf(head)


class RepeatedHeaderKey(ValueError):
    """A header comment that gives one property two different values."""


def _local(tag) -> str:
    """An element's tag without its XML namespace (``{http://www.asam.net/mdf/v4}e`` -> ``e``)."""
    return tag.rsplit("}", 1)[-1] if isinstance(tag, str) else ""


def header_properties(comment: str) -> dict[str, str]:
    """``<e name="key">value</e>`` entries of an MDF 4 header comment's ``<common_properties>``.

    A comment without markup holds no properties (``{}``). Raises ValueError when the comment is markup that does
    not parse (an unescaped ``&``, a tag left open) and :class:`RepeatedHeaderKey` (a ValueError) when it gives one
    key two values: the run's identity, date and direction would otherwise be lost or chosen without a word.
    Elements are matched by their local name, so a comment in the ASAM namespace reads as one without.
    """
    if not comment or "<" not in comment:
        return {}
    try:
        root = ET.fromstring(comment)
    except ET.ParseError as exc:
        raise ValueError(f"the header comment is not valid XML ({exc})") from None
    except RecursionError:
        raise ValueError("the header comment is not valid XML (nested too deeply)") from None
    out: dict[str, str] = {}
    for el in root.iter():
        if _local(el.tag) == "e" and el.get("name"):
            k, v = el.get("name"), (el.text or "").strip()
            if k in out and out[k] != v:
                raise RepeatedHeaderKey(f"the header comment gives {k!r} twice ({out[k]!r}, then {v!r})")
            out[k] = v
    if not out:
        # asammdf keeps a comment it cannot parse as escaped text inside <TX>: properties written there are lost
        # unless said so
        text = " ".join(el.text or "" for el in root.iter() if _local(el.tag) == "TX")
        if "common_properties" in text or "<e name=" in text:
            try:
                ET.fromstring(text.strip())
            except ET.ParseError as exc:
                raise ValueError(f"the header comment is not valid XML ({exc})") from None
            return header_properties(text.strip())
    return out


def raw_header_comment(mdf, path) -> str | None:
    """The header block's comment as the file holds it (the MD/TX block's text), None when it has none or it
    cannot be read.

    asammdf's ``header.comment`` is not that text: asammdf parses the comment into a dictionary of common
    properties and writes it back out, so a key the file gives twice comes back once (the last value). The
    header block's ``comment_addr`` points at the block; :func:`asammdf.blocks.utils.get_text_v4` reads it.
    """
    from asammdf.blocks.utils import get_text_v4

    addr = int(getattr(mdf.header, "comment_addr", 0) or 0)
    if addr <= 0:
        return None
    try:
        size = Path(path).stat().st_size
        with open(path, "rb") as fh:
            text = get_text_v4(addr, fh, file_limit=size)
    except Exception:  # noqa: BLE001 - a block asammdf could not read either; its own reading decides below
        return None
    return text if isinstance(text, str) and text else None


def run_header(mdf, path) -> dict[str, str]:
    """The run header of an open MDF 4 file (:func:`header_properties`); RunFileError naming ``path`` when the
    comment cannot be read or gives a key twice.

    The comment is read as the file holds it (:func:`raw_header_comment`), so that a repeated key is seen; when
    that text holds no properties as XML (plain text, markup asammdf repairs), asammdf's reading of it is used.
    """
    try:
        raw = raw_header_comment(mdf, path)
        if raw:
            try:
                props = header_properties(raw)
            except RepeatedHeaderKey:
                raise
            except ValueError:
                props = {}
            if props:
                return props
        return header_properties(mdf.header.comment or "")
    except ValueError as exc:
        raise RunFileError(f"{path}: {exc}; the run header (run_id, date, direction, ...) cannot be read") from None


def open_mdf(path: Path):
    """``asammdf.MDF(path)`` of an MDF 4 file, or :class:`RunFileError` naming the file and asammdf's reason (or
    the version of an MDF 3 file); see :func:`ema.mdf_file.open_mdf`."""
    mdf = open_mdf_file(path, RunFileError, "MDF 4 file")
    if int(str(mdf.version).split(".")[0]) >= 4:
        return mdf
    version = mdf.version
    mdf.close()
    raise RunFileError(f"{path}: MDF version {version}; the field contract uses MDF 4")


def _read(mdf, path: Path, name: str, group: int, index: int) -> RawChannel | str:
    """One channel occurrence, or why it cannot be used (its values are not numbers)."""
    try:
        sig = mdf.get(name, group=group, index=index, raw=False)
    except Exception as exc:  # noqa: BLE001
        raise RunFileError(f"{path}: channel {name!r} cannot be read ({type(exc).__name__}: {exc}); the "
                           "file may be truncated") from None
    values = np.asarray(sig.samples)
    if values.dtype.kind not in "fiu":
        return f"its values are not numbers ({values.dtype}: text or structured values)"
    return RawChannel(name, np.asarray(sig.timestamps, float), values.astype(float), str(sig.unit or ""))


def same_channel(a: RawChannel, b: RawChannel) -> bool:
    """Whether two copies of a channel hold the same data (units compared by :func:`normalise_unit`)."""
    if a is b:
        return True
    return (normalise_unit(a.unit) == normalise_unit(b.unit) and a.t.shape == b.t.shape
            and np.array_equal(a.t, b.t, equal_nan=True) and np.array_equal(a.values, b.values, equal_nan=True))


def _copy_labels(name: str, keys: list[tuple[int, int]]) -> dict[tuple[int, int], str]:
    """``NAME@GROUP`` per copy, ``NAME@GROUP.INDEX`` for the copies of a group that holds several."""
    per_group = Counter(g for g, _ in keys)
    return {(g, i): f"{name}@{g}" if per_group[g] == 1 else f"{name}@{g}.{i}" for g, i in keys}


def read_raw(path: Path) -> RawRecording:
    """Every channel of an MDF 4 file (time stamps, values, unit) and the header's common properties.

    A name that several channels carry (a data logger recording one signal in two groups, two signals of one
    name, or two modules' inputs of one name in one group) is kept when every copy holds the same data (units
    compared by :func:`normalise_unit`, so ``g`` and ``G`` are one unit). Otherwise each copy is available as
    ``NAME@GROUP`` (the channel group's index in the file; ``NAME@GROUP.INDEX`` when one group holds several
    copies) and ``NAME`` alone is listed as unusable, with the qualified names in the reason: the sensor table
    must say which one it means; nothing is picked silently.

    Raises
    ------
    RunFileError
        The file is not a readable MDF 4 file (truncated, corrupt) — named with asammdf's reason.
    """
    mdf = open_mdf(path)
    try:
        header = run_header(mdf, path)
        channels: dict[str, RawChannel] = {}
        unusable: dict[str, str] = {}
        for name, where in mdf.channels_db.items():
            if name in ("time", "t", ""):
                continue
            copies = {(group, index): _read(mdf, path, name, group, index)
                      for group, index in where if index != mdf.masters_db.get(group)}
            if not copies:
                continue
            read = {k: c for k, c in copies.items() if isinstance(c, RawChannel)}
            if not read:
                unusable[name] = next(iter(copies.values()))
                continue
            first = next(iter(read.values()))
            if all(same_channel(first, c) for c in read.values()):
                channels[name] = first
                continue
            labels = _copy_labels(name, sorted(read))
            for key, label in labels.items():
                channels[label] = RawChannel(label, read[key].t, read[key].values, read[key].unit)
            groups = sorted({g for g, _ in read})
            unusable[name] = (f"channel groups {groups} hold {len(read)} channels of this name with different data; "
                              f"name one of {list(labels.values())} in the sensor table")
    finally:
        mdf.close()
    if not channels:
        raise RunFileError(f"{path}: the MDF file holds no numeric channel; the file may be truncated")
    return RawRecording(channels, header, unusable)
