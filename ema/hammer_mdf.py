"""Reading a hammer test recorded by a data logger into an ASAM MDF file (MDF 3 or 4, through asammdf).

Data loggers (the acquisition systems that write MDF: HBM, Dewesoft, IMC, Vector...) record a hammer test
continuously: one long record per channel, the operator hitting the wheelset every few seconds.
:func:`read_hammer_mdf` reads that record as a test of one hit; :func:`ema.read_hammer` then cuts it into one
hit per impact (:mod:`ema.continuous`).

The channel table (:mod:`ema.channels`) selects the channels **by name**: the row's ``name`` is the channel's
name in the file (exactly, else the one file channel whose name differs only in case and surrounding blanks).
Positions, directions and FE nodes come from the table, as for UFF; the samples, their time stamps and the
unit (the channel's physical unit after asammdf applies its conversion) from the file. Units and sensitivities
follow :func:`ema.hammer_io.unit_scale`, as for UFF.

Refused by name (file and channel): a damaged file (:class:`~ema.hammer_io.MDFReadError`), a table channel the
file lacks or holds twice with different data, values that are not numbers
(:class:`~ema.hammer_io.ChannelMismatchError`); time stamps that are not evenly spaced (a gap where samples were
lost), channels at another rate or on another time base than the force (:class:`~ema.hammer_io.SamplingError`).
File channels without a table row are skipped with a WARNING naming them.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pandas as pd

from .hammer_io import (ChannelMismatchError, HammerTest, MDFReadError, SamplingError, check_force_peak,
                        unit_notes, unit_scale)
from .mdf_file import open_mdf, sniff_mdf

__all__ = ["read_hammer_mdf", "sniff"]

log = logging.getLogger("ema")


def sniff(path: Path) -> bool:
    """True when ``path`` starts with an MDF identification block."""
    with open(path, "rb") as fh:
        return sniff_mdf(fh.read(8))


def _file_name(wanted: str, names: list[str]) -> str | None:
    """The file's channel for a table name: the same name, else the one equal up to case and blanks."""
    if wanted in names:
        return wanted
    near = [n for n in names if n.strip().casefold() == wanted.strip().casefold()]
    return near[0] if len(near) == 1 else None


def _record(mdf, p: str, name: str, where: list[tuple[int, int]], masters: dict) -> tuple[np.ndarray, np.ndarray,
                                                                                           str, int]:
    """Time stamps, values, unit and group of one channel; several differing copies are refused."""
    read = []
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
        read.append((np.asarray(sig.timestamps), values.astype(float), str(sig.unit or "").strip(), group))
    first = read[0]
    for other in read[1:]:
        if not (other[0].shape == first[0].shape and np.array_equal(other[0], first[0])
                and np.array_equal(other[1], first[1], equal_nan=True) and other[2] == first[2]):
            raise ChannelMismatchError(f"{p}: channel groups {first[3]} and {other[3]} both hold a channel {name!r}, "
                                       f"with different data; the table cannot say which one it means: rename one "
                                       f"in the logger, or export the one of the test")
    return first


def _even_time_axis(p: str, name: str, t: np.ndarray) -> tuple[float, float]:
    """``(t0, dt)`` of evenly spaced time stamps; a gap (lost samples), a step back or a jitter is refused."""
    if t.size < 2:
        raise SamplingError(f"{p}: channel {name!r} holds {t.size} sample{'s' if t.size != 1 else ''}; a hammer "
                            f"test needs a record")
    # the time stamps' own resolution: float32 time stamps of a long recording are coarse
    res = 4.0 * float(np.spacing(np.abs(t).max().astype(t.dtype if t.dtype.kind == "f" else float)))
    tf = t.astype(float)
    steps = np.diff(tf)
    dt = float(np.median(steps))
    if not dt > 0:
        raise SamplingError(f"{p}: channel {name!r}: its time stamps do not increase (median step {dt!r} s)")
    bad = np.flatnonzero(np.abs(steps - dt) > 1e-6 * dt + 2 * res)
    if bad.size:
        k = int(bad[0])
        what = (f"a gap of {steps[k]:.6g} s ({steps[k] / dt - 1:.0f} samples lost?)" if steps[k] > 1.5 * dt else
                f"a step of {steps[k]:.6g} s")
        raise SamplingError(f"{p}: channel {name!r}: {what} at t = {tf[k]:.6f} s, where the record samples every "
                            f"{dt:.6g} s ({bad.size} uneven step{'s' if bad.size > 1 else ''} in all); a hammer test "
                            f"needs one evenly sampled record per channel")
    # the rate from the whole span, which float time stamps give more precisely than one step
    return float(tf[0]), float((tf[-1] - tf[0]) / (tf.size - 1))


def read_hammer_mdf(path: Path, channels: pd.DataFrame) -> HammerTest:
    """A hammer test from an MDF file: one record per table channel, read as one hit (module docstring).

    Parameters
    ----------
    path : Path
    channels : pandas.DataFrame
        Validated channel table; its ``name`` column names the file's channels.

    Returns
    -------
    HammerTest
        One hit; :func:`ema.read_hammer` cuts a continuous recording into hits.
    """
    p = str(path)
    log.info("reading hammer test %s (%.1f MB, MDF)", p, path.stat().st_size / 1e6)
    mdf = open_mdf(path, MDFReadError, "MDF file")
    try:
        masters = dict(mdf.masters_db)
        db = {n: list(w) for n, w in mdf.channels_db.items()
              if n and any(i != masters.get(g) for g, i in w)}
        names = sorted(db)
        rows = {(int(r.node), str(r.quantity)): r for r in channels.itertuples(index=False)}
        found = {key: _file_name(str(r.name), names) for key, r in rows.items()}
        missing = [str(rows[k].name) for k, n in found.items() if n is None]
        if missing:
            shown = ", ".join(repr(n) for n in names[:20]) + (f" and {len(names) - 20} more" if len(names) > 20 else "")
            raise ChannelMismatchError(
                f"{p}: {len(missing)} channel{'s' if len(missing) > 1 else ''} of the channel table not in the file: "
                f"{', '.join(repr(n) for n in missing)}; the table's 'name' column must name the logger's channels "
                f"(the file holds {shown})")
        records = {key: _record(mdf, p, name, db[name], masters) for key, name in found.items()}
    finally:
        mdf.close()
    skipped = sorted(set(names) - set(found.values()) - {"time", "t"})
    if skipped:
        log.warning("%s: %d channel%s in the file without a row in the channel table skipped (the table selects the "
                    "channels by name): %s", p, len(skipped), "s" if len(skipped) > 1 else "",
                    ", ".join(repr(n) for n in skipped[:20]) + (" ..." if len(skipped) > 20 else ""))
    fkey = next(k for k in rows if k[1] == "force")
    t_ref = records[fkey][0]
    t0, dt = _even_time_axis(p, found[fkey], t_ref)
    for key, (t, _, _, group) in records.items():
        if key == fkey:
            continue
        name = found[key]
        if t.size != t_ref.size:
            rate = (t.size - 1) / float(t[-1] - t[0]) if t.size > 1 and t[-1] > t[0] else float("nan")
            raise SamplingError(f"{p}: channel {name!r} (channel group {group}): {t.size} samples ({rate:.6g} Hz), "
                                f"the force channel {found[fkey]!r} {t_ref.size} ({1 / dt:.6g} Hz); force and "
                                f"responses must be recorded at one rate over one span")
        t0_k, _ = _even_time_axis(p, name, t)
        if abs(t0_k - t0) > 1e-3 * dt or abs(float(t[-1]) - float(t_ref[-1])) > 1e-3 * dt:
            raise SamplingError(f"{p}: channel {name!r} (channel group {group}) is sampled at other instants than "
                                f"the force channel {found[fkey]!r} (first sample at {float(t[0]):.9g} s, the "
                                f"force's at {t0:.9g} s); H1 relates force and responses sample by sample")
    has_sens = "sensitivity" in channels.columns
    scale = {key: unit_scale(p, rows[key], records[key][2], has_sens, f"channel group {records[key][3]}")
             for key in rows}
    acc = [(int(n), "acceleration") for n in channels.loc[channels["quantity"] == "acceleration", "node"]]
    force = (records[fkey][1] * scale[fkey][0])[None, :]
    resp = np.stack([records[k][1] * scale[k][0] for k in acc])[None, :, :]
    history = [f"read_hammer {p} (MDF, one record per channel, {force.shape[1] * dt:.3f} s)"]
    history += unit_notes(p, rows, scale, has_sens)
    renamed = [f"{rows[k].name!r} as {n!r}" for k, n in found.items() if n != str(rows[k].name)]
    if renamed:
        note = f"channels found under a name differing in case or blanks: {', '.join(renamed)}"
        log.info("%s: %s", p, note)
        history.append(note)
    check_force_peak(p, force, rows[fkey], scale[fkey], has_sens)
    test = HammerTest(fs=1.0 / dt, time=t0 + dt * np.arange(force.shape[1]), channels=channels, force=force,
                      responses=resp, hits=(1,), source=p, history=tuple(history))
    log.info("read %s: %d channels + force, fs %g Hz, %d samples (%.3g s)", p, test.n_channels, test.fs,
             test.n_samples, test.n_samples * dt)
    return test
