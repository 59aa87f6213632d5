"""A hammer test from named per-channel records, as data loggers and DAQ exports hold them.

The readers of such files (:mod:`ema.hammer_mdf`, :mod:`ema.hammer_csv`) collect, for each channel name of the
file the channel table asks for, its distinct records: time stamps, values, unit and where they sit (an MDF
channel group, a CSV column). :func:`match_names` finds the table's names in the file;
:func:`hammer_test_from_records` makes the test: one hit per force record (several are a triggered logger's
hits, numbered in time order, or in the file's order where their time stamps overlap, restarting at every
trigger); each response the copy sampled at its force record's instants, or, where several
are, the one in the force's own group. Every refusal names the file, the channel and, where there are several,
the hit (module docstring of :mod:`ema.hammer_mdf`).
"""

from __future__ import annotations

import logging
from typing import NamedTuple

import numpy as np
import pandas as pd

from .hammer_io import (ChannelMismatchError, HammerTest, SamplingError, UnitSystemError, check_force_peak,
                        unit_notes, unit_scale)

__all__ = ["ChannelRecord", "match_names", "same_record", "hammer_test_from_records"]

log = logging.getLogger("ema")


class ChannelRecord(NamedTuple):
    """One channel's record: time stamps [s], values, unit, group index (MDF channel group; 0 in a CSV file), and
    where it sits, for messages (``"channel group 3"``, ``"column 4"``)."""

    t: np.ndarray
    v: np.ndarray
    unit: str
    group: int
    where: str
    #: resolution of the time stamps as written (a CSV file's decimals), 0 when they are binary floats
    t_res: float = 0.0


def _file_name(wanted: str, names: list[str]) -> str | None:
    """The file's channel for a table name: the same name, else the one equal up to case and blanks."""
    if wanted in names:
        return wanted
    near = [n for n in names if n.strip().casefold() == wanted.strip().casefold()]
    return near[0] if len(near) == 1 else None


def match_names(p: str, channels: pd.DataFrame, names: list[str], who: str) -> tuple[dict, dict]:
    """The table's rows by ``(node, quantity)`` and, for each, the file's channel name (see :func:`_file_name`).

    A table name the file lacks is refused, with what the file holds; ``who`` says whose names they are
    (``"the logger's"``).
    """
    rows = {(int(r.node), str(r.quantity)): r for r in channels.itertuples(index=False)}
    found = {key: _file_name(str(r.name), names) for key, r in rows.items()}
    missing = [str(rows[k].name) for k, n in found.items() if n is None]
    if missing:
        shown = ", ".join(repr(n) for n in names[:20]) + (f" and {len(names) - 20} more" if len(names) > 20 else "")
        raise ChannelMismatchError(
            f"{p}: {len(missing)} channel{'s' if len(missing) > 1 else ''} of the channel table not in the file: "
            f"{', '.join(repr(n) for n in missing)}; the table's 'name' column must name {who} channels "
            f"(the file holds {shown})")
    return rows, found


def same_record(a: ChannelRecord, b: ChannelRecord) -> bool:
    """Whether two records hold the same samples (a copy of one channel in two places is one record)."""
    return (a.t.shape == b.t.shape and np.array_equal(a.t, b.t) and np.array_equal(a.v, b.v, equal_nan=True)
            and a.unit == b.unit)


def _span(t: np.ndarray) -> str:
    return f"{float(t[0]):.6f}–{float(t[-1]):.6f} s" if t.size else "no samples"


def _on_time_base(rec: ChannelRecord, ref: ChannelRecord, dt: float) -> bool:
    """True when ``rec`` is sampled at ``ref``'s instants (same count, first and last stamps within 0.1 % dt)."""
    return (rec.t.size == ref.t.size and abs(float(rec.t[0]) - float(ref.t[0])) <= 1e-3 * dt
            and abs(float(rec.t[-1]) - float(ref.t[-1])) <= 1e-3 * dt)


def _match(p: str, name: str, copies: list[ChannelRecord], force: ChannelRecord, fname: str, dt: float, hit: int,
           n_hits: int, word: str = "channel group") -> ChannelRecord:
    """The record of channel ``name`` that belongs to the hit whose force record is ``force``.

    The one copy sampled at the force's instants; where several are (a logger that restarts its time stamps at
    every trigger), the one in the force's own channel group. None, or several without that, is refused. ``word``
    names a group in messages (``"trigger"`` in a CSV table).
    """
    timed = [c for c in copies if _on_time_base(c, force, dt)]
    if len(timed) == 1:
        return timed[0]
    if timed:
        own = [c for c in timed if c.group == force.group]
        if n_hits > 1 and len(own) == 1:
            return own[0]
        raise ChannelMismatchError(f"{p}: {word}s {timed[0].group} and {timed[1].group} both hold a channel "
                                   f"{name!r} on the force's time stamps, with different data; the table cannot say "
                                   f"which one it means: rename one in the logger, or export the one of the test")
    if n_hits == 1:
        rec = copies[0]
        t = rec.t
        if t.size != force.t.size:
            rate = (t.size - 1) / float(t[-1] - t[0]) if t.size > 1 and t[-1] > t[0] else float("nan")
            raise SamplingError(f"{p}: channel {name!r} ({rec.where}): {t.size} samples ({rate:.6g} Hz), "
                                f"the force channel {fname!r} {force.t.size} ({1 / dt:.6g} Hz); force and "
                                f"responses must be recorded at one rate over one span")
        raise SamplingError(f"{p}: channel {name!r} ({rec.where}) is sampled at other instants than "
                            f"the force channel {fname!r} (first sample at {float(t[0]):.9g} s, the "
                            f"force's at {float(force.t[0]):.9g} s); H1 relates force and responses sample by sample")
    starts = ", ".join(f"{float(c.t[0]):.6f} s ({word} {c.group})" for c in copies[:8])
    raise ChannelMismatchError(f"{p}: hit {hit} (the force record of {word} {force.group}, {_span(force.t)}): "
                               f"channel {name!r} has no record on the force's time stamps (its {len(copies)} "
                               f"record{'s' if len(copies) > 1 else ''} start at {starts}); every triggered record "
                               f"needs the force and all the table's responses")


def _even_time_axis(p: str, name: str, t: np.ndarray, written: float = 0.0) -> tuple[float, float]:
    """``(t0, dt)`` of evenly spaced time stamps; a gap (lost samples), a step back or a jitter is refused.

    ``written``: the resolution the stamps were written to (a step may be off by that much).
    """
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
    bad = np.flatnonzero(np.abs(steps - dt) > 1e-6 * dt + 2 * res + 1.01 * written)
    if bad.size:
        k = int(bad[0])
        what = (f"a gap of {steps[k]:.6g} s ({steps[k] / dt - 1:.0f} samples lost?)" if steps[k] > 1.5 * dt else
                f"a step of {steps[k]:.6g} s")
        raise SamplingError(f"{p}: channel {name!r}: {what} at t = {tf[k]:.6f} s, where the record samples every "
                            f"{dt:.6g} s ({bad.size} uneven step{'s' if bad.size > 1 else ''} in all); a hammer test "
                            f"needs one evenly sampled record per channel")
    # the rate from the whole span, which float time stamps give more precisely than one step
    return float(tf[0]), float((tf[-1] - tf[0]) / (tf.size - 1))


def _hit_records(p: str, found: dict, copies: dict, fkey, force: ChannelRecord, hit: int,
                 n_hits: int, word: str) -> tuple[dict, tuple[float, float]]:
    """The records of one hit, keyed as the table, and the force's ``(t0, dt)``; each checked evenly sampled."""
    t0, dt = _even_time_axis(p, found[fkey], force.t, force.t_res)
    recs = {fkey: force}
    for key, name in found.items():
        if key != fkey:
            recs[key] = _match(p, name, copies[key], force, found[fkey], dt, hit, n_hits, word)
            _even_time_axis(p, name, recs[key].t, recs[key].t_res)
    return recs, (t0, dt)


def _check_all_used(p: str, found: dict, copies: dict, hits: list, forces: list[ChannelRecord]) -> None:
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
            raise ChannelMismatchError(f"{p}: channel {name!r} ({c.where}, {_span(c.t)}): a record on no "
                                       f"force record's time stamps ({len(forces)} force record"
                                       f"{'s' if len(forces) > 1 else ''}, the first {_span(forces[0].t)}); a "
                                       f"response recorded without its force cannot be part of the test")


def hammer_test_from_records(p: str, channels: pd.DataFrame, rows: dict, found: dict, names: list[str],
                             copies: dict[tuple, list[ChannelRecord]], fmt: str,
                             group_word: str = "channel group") -> HammerTest:
    """The hammer test of the records ``copies`` (per table key, the distinct records of its file channel).

    Parameters
    ----------
    p : str
        The file, in messages.
    channels : pandas.DataFrame
        Validated channel table.
    rows, found : dict
        From :func:`match_names`.
    names : list of str
        Every channel name of the file (those without a table row are named in a WARNING).
    copies : dict
        Per table key, the distinct records of its channel.
    fmt : str
        The format, in the history (``"MDF"``).
    group_word : str
        What a record's ``group`` is, in messages and the history (``"trigger"`` in a CSV table).
    """
    skipped = sorted(set(names) - set(found.values()) - {"time", "t"})
    if skipped:
        log.warning("%s: %d channel%s in the file without a row in the channel table skipped (the table selects the "
                    "channels by name): %s", p, len(skipped), "s" if len(skipped) > 1 else "",
                    ", ".join(repr(n) for n in skipped[:20]) + (" ..." if len(skipped) > 20 else ""))
    fkey = next(k for k in rows if k[1] == "force")
    # one force record is a continuous recording (or one hit); several are a triggered logger's hits, numbered
    # in time order, or in group order where the records overlap in time: the stamps restart at every trigger,
    # and a trigger's jitter moves its first stamp by a fraction of a sample, which says nothing of the order
    forces = sorted(copies[fkey], key=lambda r: (float(r.t[0]) if r.t.size else 0.0, r.group))
    restarted = any(b.t.size and a.t.size and b.t[0] <= a.t[-1] for a, b in zip(forces, forces[1:]))
    if restarted:
        forces = sorted(forces, key=lambda r: r.group)
    hits = [_hit_records(p, found, copies, fkey, f, i + 1, len(forces), group_word) for i, f in enumerate(forces)]
    _check_all_used(p, found, copies, hits, forces)
    t0, dt = hits[0][1]
    for i, (recs, (_, dt_i)) in enumerate(hits[1:], start=2):
        n_first, n_i = forces[0].t.size, forces[i - 1].t.size
        if n_i != n_first or abs(dt_i - dt) > 1e-6 * dt:
            raise SamplingError(f"{p}: hit {i} ({group_word} {forces[i - 1].group}, {_span(forces[i - 1].t)}): "
                                f"{n_i} samples at {1 / dt_i:.6g} Hz, hit 1 ({group_word} {forces[0].group}) "
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
    scale = {key: unit_scale(p, rows[key], records[key].unit, has_sens, records[key].where)
             for key in rows}
    acc = [(int(n), "acceleration") for n in channels.loc[channels["quantity"] == "acceleration", "node"]]
    force = np.stack([h[0][fkey].v * scale[fkey][0] for h in hits])
    resp = np.stack([np.stack([h[0][k].v * scale[k][0] for k in acc]) for h in hits])
    layout = ("one record per channel" if len(hits) == 1 else
              f"{len(hits)} triggered records of {force.shape[1]} samples in {group_word}s "
              f"{', '.join(str(f.group) for f in forces[:12])}{' ...' if len(forces) > 12 else ''}, hits numbered in "
              f"{'the file' if restarted else 'time'} order")
    history = [f"read_hammer {p} ({fmt}, {layout}, {force.shape[1] * dt:.3f} s)"]
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
