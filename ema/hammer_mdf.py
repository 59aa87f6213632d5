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
from typing import NamedTuple

import numpy as np
import pandas as pd

from .hammer_io import (ChannelMismatchError, HammerTest, MDFReadError, SamplingError, UnitSystemError,
                        check_force_peak, unit_notes, unit_scale)
from .mdf_file import open_mdf, sniff_mdf

__all__ = ["read_hammer_mdf", "sniff"]

log = logging.getLogger("ema")


class _Record(NamedTuple):
    """One channel's record in one channel group: time stamps [s], values, unit, group index."""

    t: np.ndarray
    v: np.ndarray
    unit: str
    group: int


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


def _copies(mdf, p: str, name: str, where: list[tuple[int, int]], masters: dict) -> list[_Record]:
    """Every distinct record of one channel in the file (copies with the same data are one), in group order."""
    read: list[_Record] = []
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
        rec = _Record(np.asarray(sig.timestamps), values.astype(float), str(sig.unit or "").strip(), group)
        if not any(_same(rec, other) for other in read):
            read.append(rec)
    return read


def _same(a: _Record, b: _Record) -> bool:
    return (a.t.shape == b.t.shape and np.array_equal(a.t, b.t) and np.array_equal(a.v, b.v, equal_nan=True)
            and a.unit == b.unit)


def _span(t: np.ndarray) -> str:
    return f"{float(t[0]):.6f}–{float(t[-1]):.6f} s" if t.size else "no samples"


def _on_time_base(rec: _Record, ref: _Record, dt: float) -> bool:
    """True when ``rec`` is sampled at ``ref``'s instants (same count, first and last stamps within 0.1 % dt)."""
    return (rec.t.size == ref.t.size and abs(float(rec.t[0]) - float(ref.t[0])) <= 1e-3 * dt
            and abs(float(rec.t[-1]) - float(ref.t[-1])) <= 1e-3 * dt)


def _match(p: str, name: str, copies: list[_Record], force: _Record, fname: str, dt: float, hit: int,
           n_hits: int) -> _Record:
    """The record of channel ``name`` that belongs to the hit whose force record is ``force``.

    The one copy sampled at the force's instants; where several are (a logger that restarts its time stamps at
    every trigger), the one in the force's own channel group. None, or several without that, is refused.
    """
    timed = [c for c in copies if _on_time_base(c, force, dt)]
    if len(timed) == 1:
        return timed[0]
    if timed:
        own = [c for c in timed if c.group == force.group]
        if n_hits > 1 and len(own) == 1:
            return own[0]
        raise ChannelMismatchError(f"{p}: channel groups {timed[0].group} and {timed[1].group} both hold a channel "
                                   f"{name!r} on the force's time stamps, with different data; the table cannot say "
                                   f"which one it means: rename one in the logger, or export the one of the test")
    if n_hits == 1:
        rec = copies[0]
        t = rec.t
        if t.size != force.t.size:
            rate = (t.size - 1) / float(t[-1] - t[0]) if t.size > 1 and t[-1] > t[0] else float("nan")
            raise SamplingError(f"{p}: channel {name!r} (channel group {rec.group}): {t.size} samples ({rate:.6g} Hz), "
                                f"the force channel {fname!r} {force.t.size} ({1 / dt:.6g} Hz); force and "
                                f"responses must be recorded at one rate over one span")
        raise SamplingError(f"{p}: channel {name!r} (channel group {rec.group}) is sampled at other instants than "
                            f"the force channel {fname!r} (first sample at {float(t[0]):.9g} s, the "
                            f"force's at {float(force.t[0]):.9g} s); H1 relates force and responses sample by sample")
    starts = ", ".join(f"{float(c.t[0]):.6f} s (group {c.group})" for c in copies[:8])
    raise ChannelMismatchError(f"{p}: hit {hit} (the force record of channel group {force.group}, {_span(force.t)}): "
                               f"channel {name!r} has no record on the force's time stamps (its {len(copies)} "
                               f"record{'s' if len(copies) > 1 else ''} start at {starts}); every triggered record "
                               f"needs the force and all the table's responses")


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


def _hit_records(p: str, found: dict, copies: dict, fkey, force: _Record, hit: int,
                 n_hits: int) -> tuple[dict, tuple[float, float]]:
    """The records of one hit, keyed as the table, and the force's ``(t0, dt)``; each checked evenly sampled."""
    t0, dt = _even_time_axis(p, found[fkey], force.t)
    recs = {fkey: force}
    for key, name in found.items():
        if key != fkey:
            recs[key] = _match(p, name, copies[key], force, found[fkey], dt, hit, n_hits)
            _even_time_axis(p, name, recs[key].t)
    return recs, (t0, dt)


def _check_all_used(p: str, found: dict, copies: dict, hits: list, forces: list[_Record]) -> None:
    """A response record that no hit took is refused: nothing in the file is silently left out."""
    for key, name in found.items():
        taken = [id(h[0][key]) for h in hits]
        twice = [i for i, k in enumerate(taken) if k in taken[:i]]
        if twice:
            i = twice[0]
            raise ChannelMismatchError(f"{p}: hits {taken.index(taken[i]) + 1} and {i + 1} (force records in channel "
                                       f"groups {forces[taken.index(taken[i])].group} and {forces[i].group}) both "
                                       f"find channel {name!r} in channel group {hits[i][0][key].group}: their force "
                                       f"records share the time stamps, and the response is in neither's group")
        left = [c for c in copies[key] if id(c) not in set(taken)]
        if left:
            c = left[0]
            raise ChannelMismatchError(f"{p}: channel {name!r} (channel group {c.group}, {_span(c.t)}): a record on no "
                                       f"force record's time stamps ({len(forces)} force record"
                                       f"{'s' if len(forces) > 1 else ''}, the first {_span(forces[0].t)}); a "
                                       f"response recorded without its force cannot be part of the test")


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
        rows = {(int(r.node), str(r.quantity)): r for r in channels.itertuples(index=False)}
        found = {key: _file_name(str(r.name), names) for key, r in rows.items()}
        missing = [str(rows[k].name) for k, n in found.items() if n is None]
        if missing:
            shown = ", ".join(repr(n) for n in names[:20]) + (f" and {len(names) - 20} more" if len(names) > 20 else "")
            raise ChannelMismatchError(
                f"{p}: {len(missing)} channel{'s' if len(missing) > 1 else ''} of the channel table not in the file: "
                f"{', '.join(repr(n) for n in missing)}; the table's 'name' column must name the logger's channels "
                f"(the file holds {shown})")
        copies = {key: _copies(mdf, p, name, db[name], masters) for key, name in found.items()}
    finally:
        mdf.close()
    skipped = sorted(set(names) - set(found.values()) - {"time", "t"})
    if skipped:
        log.warning("%s: %d channel%s in the file without a row in the channel table skipped (the table selects the "
                    "channels by name): %s", p, len(skipped), "s" if len(skipped) > 1 else "",
                    ", ".join(repr(n) for n in skipped[:20]) + (" ..." if len(skipped) > 20 else ""))
    fkey = next(k for k in rows if k[1] == "force")
    # one force record is a continuous recording (or one hit); several are a triggered logger's hits, numbered
    # in time order (group order where a logger restarts the time stamps at every trigger)
    forces = sorted(copies[fkey], key=lambda r: (float(r.t[0]) if r.t.size else 0.0, r.group))
    hits = [_hit_records(p, found, copies, fkey, f, i + 1, len(forces)) for i, f in enumerate(forces)]
    _check_all_used(p, found, copies, hits, forces)
    t0, dt = hits[0][1]
    for i, (recs, (_, dt_i)) in enumerate(hits[1:], start=2):
        n_first, n_i = forces[0].t.size, forces[i - 1].t.size
        if n_i != n_first or abs(dt_i - dt) > 1e-6 * dt:
            raise SamplingError(f"{p}: hit {i} (channel group {forces[i - 1].group}, {_span(forces[i - 1].t)}): "
                                f"{n_i} samples at {1 / dt_i:.6g} Hz, hit 1 (channel group {forces[0].group}) "
                                f"{n_first} at {1 / dt:.6g} Hz; the triggered records of one test must share the "
                                f"rate and the record length (set the logger's trigger to a fixed length)")
    records = {}
    for key in rows:
        units = sorted({h[0][key].unit for h in hits})
        if len(units) > 1:
            raise UnitSystemError(f"{p}: channel {found[key]!r} is recorded in {' and '.join(map(repr, units))} in "
                                  f"different hits; one channel must keep one unit through the test")
        records[key] = hits[0][0][key]
    has_sens = "sensitivity" in channels.columns
    scale = {key: unit_scale(p, rows[key], records[key].unit, has_sens, f"channel group {records[key].group}")
             for key in rows}
    acc = [(int(n), "acceleration") for n in channels.loc[channels["quantity"] == "acceleration", "node"]]
    force = np.stack([h[0][fkey].v * scale[fkey][0] for h in hits])
    resp = np.stack([np.stack([h[0][k].v * scale[k][0] for k in acc]) for h in hits])
    layout = ("one record per channel" if len(hits) == 1 else
              f"{len(hits)} triggered records of {force.shape[1]} samples in channel groups "
              f"{', '.join(str(f.group) for f in forces[:12])}{' ...' if len(forces) > 12 else ''}, hits numbered in "
              f"time order")
    history = [f"read_hammer {p} (MDF, {layout}, {force.shape[1] * dt:.3f} s)"]
    history += unit_notes(p, rows, scale, has_sens)
    renamed = [f"{rows[k].name!r} as {n!r}" for k, n in found.items() if n != str(rows[k].name)]
    if renamed:
        note = f"channels found under a name differing in case or blanks: {', '.join(renamed)}"
        log.info("%s: %s", p, note)
        history.append(note)
    check_force_peak(p, force, rows[fkey], scale[fkey], has_sens)
    test = HammerTest(fs=1.0 / dt, time=t0 + dt * np.arange(force.shape[1]), channels=channels, force=force,
                      responses=resp, hits=tuple(range(1, len(hits) + 1)), source=p, history=tuple(history))
    log.info("read %s: %d channels + force, fs %g Hz, %d hit%s of %d samples (%.3g s)", p, test.n_channels, test.fs,
             test.n_hits, "s" if test.n_hits > 1 else "", test.n_samples, test.n_samples * dt)
    return test
