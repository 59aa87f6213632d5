"""From a file's raw channels and a sensor table to a validated :class:`~estimator.run.Run`.

Rules (field contract):

* speed and position channels are required (OdometryError naming them);
  the balise channel is optional (without it no reset is known);
* every acceleration channel of the sensor table is looked up by name; a
  missing one is **rejected** and logged (the wheelset it belongs to is
  processed with what remains, or not at all), never silently replaced;
* all acceleration channels must share one sampling rate (the most common
  one, or ``fs`` when given): a channel at another rate is rejected and
  logged; samples must be evenly spaced (ChannelError otherwise);
* a file unit that contradicts the sensor table's unit is an error
  (ChannelError naming both);
* the sensitivities of speed, position and balise channels are applied while
  reading; those of the accelerations by :meth:`Run.apply_sensitivities`
  (recorded in the history).
"""

from __future__ import annotations

import logging
import math
from collections import Counter

import numpy as np
import pandas as pd

from estimator.errors import ChannelError, OdometryError, RunFileError
from estimator.io.registry import RawChannel, RawRecording
from estimator.io.sensors import normalise_unit
from estimator.run import DIRECTIONS, ORIENTATIONS, Odometry, QCEvent, Run, RunHeader

__all__ = ["assemble_run", "channel_rate"]

log = logging.getLogger("estimator")

#: relative tolerance on a channel's sampling interval (jitter of the time stamps)
RATE_RTOL = 1e-3
#: most samples per channel (about 12 h at 1 kHz)
MAX_SAMPLES = 50_000_000


def channel_rate(ch: RawChannel, source: str) -> float:
    """Sampling rate of an evenly sampled channel [Hz] (ChannelError if uneven or too short)."""
    t = ch.t
    if t.size < 2:
        raise ChannelError(f"{source}: channel {ch.name!r} has {t.size} sample(s); a signal needs at least 2")
    d = np.diff(t)
    dt = float(np.median(d))
    if not dt > 0:
        raise ChannelError(f"{source}: channel {ch.name!r} has non-increasing time stamps")
    if np.max(np.abs(d - dt)) > max(RATE_RTOL * dt, 1e-9):
        k = int(np.argmax(np.abs(d - dt)))
        raise ChannelError(f"{source}: channel {ch.name!r} is not evenly sampled (interval {d[k]:.6g} s at "
                           f"t = {t[k]:.3f} s, median {dt:.6g} s); the estimator needs a constant sampling rate")
    return 1.0 / dt


def _unit_check(ch: RawChannel, row: pd.Series, source: str) -> None:
    file_unit = normalise_unit(ch.unit)
    if file_unit and file_unit != row["unit"]:
        raise ChannelError(f"{source}: channel {ch.name!r} is recorded in {ch.unit!r} but the sensor table says "
                           f"{row['unit']!r} (sensitivity {row['sensitivity']:g}); correct the table or the file")


def _header(raw: RawRecording, source: str, direction: str | None) -> RunHeader:
    h = {k.strip(): str(v).strip() for k, v in raw.header.items()}
    if direction is None:
        direction = h.get("direction", "")
        if not direction:
            raise RunFileError(f"{source}: the run header has no 'direction' ({DIRECTIONS}, relative to chainage); "
                               "give it with --direction")
    elif direction not in DIRECTIONS:
        raise RunFileError(f"direction must be one of {DIRECTIONS}, got {direction!r}")
    orientation = h.get("orientation", "") or "normal"
    if orientation not in ORIENTATIONS:
        raise RunFileError(f"{source}: header orientation must be one of {ORIENTATIONS}, got {orientation!r}")
    known = ("run_id", "date", "direction", "orientation", "train", "bogie", "line", "leading_end")
    from pathlib import Path

    return RunHeader(run_id=h.get("run_id") or Path(source).stem, date=h.get("date", ""), direction=direction,
                     orientation=orientation, train=h.get("train", ""), bogie=h.get("bogie", ""),
                     line=h.get("line", ""), leading_end=h.get("leading_end", ""),
                     extra={k: v for k, v in h.items() if k not in known})


def _odometry(raw: RawRecording, sensors: pd.DataFrame, source: str) -> Odometry:
    rows = {q: sensors[sensors["quantity"] == q] for q in ("speed", "position", "balise")}
    got = {}
    for q in ("speed", "position"):
        name = str(rows[q]["name"].iloc[0])
        if name not in raw.channels:
            raise OdometryError(f"{source}: the {q} channel {name!r} of the sensor table is not in the file; the "
                                f"file has {sorted(raw.channels)}")
        ch = raw.channels[name]
        _unit_check(ch, rows[q].iloc[0], source)
        if ch.values.size < 2 or not np.isfinite(ch.values).any():
            raise OdometryError(f"{source}: the {q} channel {name!r} holds no finite values")
        channel_rate(ch, source)
        got[q] = (name, ch, float(rows[q]["sensitivity"].iloc[0]))
    (sn, sp, ss), (pn, pp, ps) = got["speed"], got["position"]
    t = pp.t
    speed = sp.values * ss
    if sp.t.shape != t.shape or not np.allclose(sp.t, t, rtol=0, atol=1e-9):
        speed = np.interp(t, sp.t, speed)
        log.info("%s: speed %r resampled onto the time base of position %r", source, sn, pn)
    bt, bv, names = np.zeros(0), np.zeros(0), {"speed": sn, "position": pn}
    if len(rows["balise"]):
        bn = str(rows["balise"]["name"].iloc[0])
        if bn in raw.channels:
            bc = raw.channels[bn]
            _unit_check(bc, rows["balise"].iloc[0], source)
            ok = np.isfinite(bc.values)
            bt, bv = bc.t[ok], bc.values[ok] * float(rows["balise"]["sensitivity"].iloc[0])
            names["balise"] = bn
        else:
            log.warning("%s: balise channel %r is not in the file; no odometer reset is known", source, bn)
    return Odometry(t=t, speed=speed, position=pp.values * ps, balise_t=bt, balise_chainage=bv, names=names)


def assemble_run(raw: RawRecording, sensors: pd.DataFrame, source: str, fmt: str, *, fs: float | None = None,
                 direction: str | None = None) -> Run:
    """Build a :class:`Run` from a reader's output and a validated sensor table (module docstring)."""
    header = _header(raw, source, direction)
    odometry = _odometry(raw, sensors, source)
    acc_rows = sensors[sensors["quantity"] == "acceleration"].reset_index(drop=True)
    rejected: list[QCEvent] = []
    present, rates = [], {}
    for _, row in acc_rows.iterrows():
        name = str(row["name"])
        if name not in raw.channels:
            msg = (f"channel {name!r} (wheelset {row['wheelset']}, side {row['side']}, {row['direction']}) of the "
                   f"sensor table is missing from the file")
            log.warning("%s: %s", source, msg)
            rejected.append(QCEvent("missing_channel", name, math.nan, math.nan, msg, "rejected"))
            continue
        ch = raw.channels[name]
        _unit_check(ch, row, source)
        if ch.values.size > MAX_SAMPLES:
            raise ChannelError(f"{source}: channel {name!r} has {ch.values.size} samples; at most {MAX_SAMPLES}")
        rates[name] = channel_rate(ch, source)
        present.append(row)
    if not present:
        raise ChannelError(f"{source}: none of the acceleration channels of the sensor table "
                           f"{list(acc_rows['name'])} is in the file (it has {sorted(raw.channels)})")
    if fs is None:
        common = Counter(round(r, 6) for r in rates.values()).most_common(1)[0][0]
        fs_run = float(np.median([r for r in rates.values() if round(r, 6) == common]))
    else:
        fs_run = float(fs)
    keep = []
    for row in present:
        name = str(row["name"])
        if abs(rates[name] / fs_run - 1) > RATE_RTOL:
            msg = (f"channel {name!r} is sampled at {rates[name]:.6g} Hz but the run's accelerations are at "
                   f"{fs_run:.6g} Hz")
            log.warning("%s: %s; channel rejected", source, msg)
            rejected.append(QCEvent("wrong_rate", name, math.nan, math.nan, msg, "rejected"))
            continue
        keep.append(row)
    if len(keep) < 2:
        raise ChannelError(f"{source}: fewer than two acceleration channels are usable at {fs_run:g} Hz "
                           f"({[e.describe() for e in rejected]})")
    t0 = max(raw.channels[str(r["name"])].t[0] for r in keep)
    t1 = min(raw.channels[str(r["name"])].t[-1] for r in keep)
    n = int(np.floor((t1 - t0) * fs_run + 1e-6)) + 1
    if n < 2:
        raise ChannelError(f"{source}: the acceleration channels do not overlap in time")
    data = np.empty((len(keep), n))
    for i, row in enumerate(keep):
        ch = raw.channels[str(row["name"])]
        off = (t0 - ch.t[0]) * fs_run
        k0 = int(round(off))
        if abs(off - k0) > 0.01:
            raise ChannelError(f"{source}: channel {row['name']!r} starts {off - k0:+.3f} samples off the common time "
                               "base of the other accelerations; the estimator needs simultaneously sampled channels")
        data[i] = ch.values[k0:k0 + n]
    table = pd.DataFrame(keep).reset_index(drop=True)
    run = Run(source=source, format=fmt, header=header, channels=table, fs=fs_run, t0=float(t0), acceleration=data,
              units=tuple(str(u) for u in table["unit"]), odometry=odometry, rejected=tuple(rejected),
              processing=(f"read {source} ({fmt}): {len(keep)} acceleration channels at {fs_run:g} Hz, "
                          f"{n / fs_run:.2f} s; odometry {odometry.names}; {odometry.balise_t.size} balise event(s); "
                          f"{len(rejected)} channel(s) rejected",))
    return run
