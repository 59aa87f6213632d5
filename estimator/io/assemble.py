"""From a file's raw channels and a sensor table to a validated :class:`~estimator.run.Run`.

Rules (field contract):

* a speed and a position channel; one of them may be absent from the
  sensor table (many loggers record only the train's speed, or only its
  odometer), and the other is derived from it and said so in the run's
  processing history: the position as an odometer makes it, the speed
  integrated along the direction of travel and reset to each balise's
  chainage at its passage (without a balise channel the chainage counts
  from the run's start); the speed from the position's steps, each reset
  or glitch step replaced by the running median of its neighbours, as a
  central difference over :data:`DERIVED_SPEED_WINDOW_S`. A channel the
  table names but the file lacks is an error (OdometryError naming it);
  the balise channel is optional (without it no reset is known);
* every acceleration channel of the sensor table is looked up by name; a
  missing one is **rejected** and logged (the wheelset it belongs to is
  processed with what remains, or not at all), never silently replaced; a
  name the file holds but not as one usable channel (several channel groups
  with different data under it, or not numbers) is an error naming why;
* all acceleration channels must share one sampling rate (the most common
  one, or ``fs`` when given): a channel at another rate is rejected and
  logged; samples must lie on a regular grid (ChannelError otherwise);
* samples the data logger lost (a buffer overrun: the time stamps jump by a
  whole number of sampling intervals and the grid goes on in phase) are NaN
  in the run, masked by quality control and reported as a ``time_gap``
  finding naming the channel, the time, the odometer's chainage and the
  samples lost — never interpolated over. A jump off the grid (the channel
  restarted out of phase with the others) is an error;
* speed and position need increasing time stamps; a stretch they do not
  cover is found by :func:`estimator.spatial.odometry_track`;
* a file unit that contradicts the sensor table's unit is an error
  (ChannelError naming both); so is an acceleration channel whose level no
  axlebox produces (over :data:`estimator.qc.ACC_RMS_MAX_G` RMS, or more than
  :data:`estimator.qc.ACC_GLITCH_MAX_SHARE` of its samples beyond
  :data:`estimator.qc.ACC_GLITCH_G`: counts, mV or a wrong sensitivity), and
  accelerations sampled below :data:`MIN_ACCELERATION_RATE_HZ` (time stamps
  in ms); non-finite time stamps are named errors;
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
from estimator.qc import ACC_GLITCH_G, ACC_GLITCH_MAX_SHARE, ACC_GLITCH_MS2, ACC_RMS_MAX_G, ACC_RMS_MAX_MS2, G0
from estimator.run import DIRECTIONS, ORIENTATIONS, Odometry, QCEvent, Run, RunHeader

__all__ = ["assemble_run", "sample_grid"]

log = logging.getLogger("estimator")

#: two channels' sampling rates are one rate within this relative difference
RATE_RTOL = 1e-3
#: every time-stamp difference must lie this close to a whole number of sampling intervals [intervals] (a logger's
#: time-stamp resolution is far below it); further off, the channel is not sampled regularly or not simultaneously
#: with the others (a phase error of 2π × 0.01 × 0.4 = 0.025 rad at the top of the inversion band)
GRID_ATOL = 0.01
#: an odometry channel's time stamps jumping by more than this many median intervals leave a gap (a balise
#: channel is an event list and has none)
ODOMETRY_GAP_FACTOR = 1.5
#: most samples per channel (about 12 h at 1 kHz)
MAX_SAMPLES = 50_000_000
#: Lowest sampling rate of the accelerations [Hz]. The inversion band ends at 0.4 fs; the EN 13231-3 30-100 mm band
#: at the 3 m/s speed gate needs 100 Hz, at metro speeds (10-20 m/s) several hundred, and axlebox data loggers
#: sample at 1-25 kHz. Below 200 Hz no corrugation band is resolved at all: the time stamps are in another unit
#: (ms or µs read as s) or the channel is not an axlebox acceleration.
MIN_ACCELERATION_RATE_HZ = 200.0
#: baseline [s] of the speed derived from a position channel when no speed is recorded: long enough to average an
#: odometer's resolution (1 cm over 0.2 s is 0.05 m/s) and to hold a median that rejects a reset step, short
#: against a metro's speed changes (a symmetric baseline passes a constant acceleration unchanged)
DERIVED_SPEED_WINDOW_S = 0.2
#: a position step further than this from its neighbours' running median (plus five of their median absolute
#: deviations, the odometer's resolution) is a reset or a glitch, not motion, when a speed is derived [m]
DERIVED_STEP_TOLERANCE_M = 0.05


def sample_grid(ch: RawChannel, source: str) -> tuple[float, np.ndarray]:
    """Sampling rate [Hz] of a channel and each sample's index on its regular grid (module docstring).

    The interval is the mean of the differences of one interval (about the median); every difference must then
    be a whole number of intervals (1: the next sample; ``k >= 2``: ``k - 1`` lost samples) within
    :data:`GRID_ATOL` of an interval. Judged difference by difference, a logger's time-stamp resolution
    (1 µs on a 1024 Hz channel) passes, and so does a clock whose rate wanders slowly over hours; a channel that
    restarts out of phase or is not sampled regularly is a ChannelError naming the channel and the time.
    """
    t = ch.t
    if t.size < 2:
        raise ChannelError(f"{source}: channel {ch.name!r} has {t.size} sample(s); a signal needs at least 2")
    _finite_time(ch, source, ChannelError)
    d = np.diff(t)
    if not np.all(d > 0):
        k = int(np.argmax(~(d > 0)))
        raise ChannelError(f"{source}: channel {ch.name!r} has non-increasing time stamps (at t = {t[k]:.6g} s)")
    dt = float(np.median(d))
    one = np.rint(d / dt) == 1
    dt = float(np.mean(d[one]))  # the median of quantised stamps is one of two values; their mean is the interval
    steps = np.maximum(np.rint(d / dt), 1.0)
    off = np.abs(d / dt - steps)  # each difference's distance from a whole number of intervals
    if not np.max(off) <= GRID_ATOL:  # (NaN compares False: caught too)
        k = int(np.argmax(off))
        what = (f"resumes {d[k] / dt:.3f} sampling intervals after a gap, off its sampling grid" if steps[k] > 1 else
                f"is not evenly sampled (an interval {d[k] / dt:.3f} times the mean)")
        raise ChannelError(f"{source}: channel {ch.name!r} {what} (interval {d[k]:.6g} s at t = {t[k]:.3f} s, "
                           f"mean {dt:.6g} s); the estimator needs a constant sampling rate" + _float32_hint(t, k, dt))
    return 1.0 / dt, np.concatenate([[0], np.cumsum(steps)]).astype(np.int64)


def _float32_hint(t: np.ndarray, k: int, dt: float) -> str:
    """Why a time base is off its grid when its stamps are single-precision numbers (a float32 master channel):
    their resolution grows with t, to 31 µs at 300 s, 3 % of a 1 kHz interval. Empty when they are not."""
    if not np.array_equal(t, t.astype(np.float32).astype(float)):
        return ""
    ulp = float(np.spacing(np.float32(abs(t[k]))))
    return (f". Every time stamp is a single-precision (float32) number, resolved to {ulp:.3g} s at "
            f"t = {t[k]:.3f} s ({100 * ulp / dt:.2g} % of the interval): write the master channel as float64 (or "
            "as sample counts with the rate)")


def _finite_time(ch: RawChannel, source: str, error: type[Exception]) -> None:
    """Raise ``error`` naming the channel and the first sample whose time stamp is NaN or infinite (a corrupt
    master channel: no sampling grid, no duration can be computed from it)."""
    bad = ~np.isfinite(ch.t)
    if bad.any():
        k = int(np.argmax(bad))
        raise error(f"{source}: channel {ch.name!r} has {int(bad.sum())} non-finite time stamp(s) (NaN/inf), the "
                    f"first at sample {k} of {ch.t.size} ({float(ch.t[k])!r} s"
                    f"{f' after {ch.t[k - 1]:.6g} s' if k > 0 and np.isfinite(ch.t[k - 1]) else ''}); the file's "
                    "time base is corrupt")


def _on_grid(ch: RawChannel, index: np.ndarray) -> np.ndarray:
    """The channel's values on its whole grid, NaN where the recording lost samples."""
    if index[-1] + 1 == index.size:
        return ch.values
    full = np.full(int(index[-1]) + 1, np.nan)
    full[index] = ch.values
    return full


def _time_gaps(ch: RawChannel, index: np.ndarray, fs: float, odometry: Odometry) -> list[QCEvent]:
    """One ``time_gap`` finding per run of lost samples, located with the odometer's reading."""
    out = []
    for j in np.flatnonzero(np.diff(index) > 1):
        lost = int(index[j + 1] - index[j] - 1)
        t_a, t_b = float(ch.t[j] + 1 / fs), float(ch.t[j + 1] - 1 / fs)
        c = np.interp([t_a, t_b], odometry.t, odometry.position)
        out.append(QCEvent("time_gap", ch.name, t_a, t_b,
                           f"{lost} sample(s) lost by the data logger (time stamps jump "
                           f"{ch.t[j + 1] - ch.t[j]:.6g} s); NaN in the run, not interpolated",
                           "masked", float(c.min()), float(c.max())))
    return out


def _short_ends(ch: RawChannel, name: str, k0: int, size: int, n: int, t0: float, fs: float,
                odometry: Odometry) -> list[QCEvent]:
    """``time_gap`` findings where a channel starts after or ends before the run's other accelerations."""
    out = []
    for a, b, what in ((0, k0, "starts"), (k0 + size, n, "ends")):
        if b > a:
            t_a, t_b = t0 + a / fs, t0 + (b - 1) / fs
            c = np.interp([t_a, t_b], odometry.t, odometry.position)
            out.append(QCEvent("time_gap", name, t_a, t_b,
                               f"channel {what} {(b - a) / fs:.6g} s {'after' if what == 'starts' else 'before'} "
                               "the run's other accelerations; NaN there, not interpolated", "masked",
                               float(c.min()), float(c.max())))
    return out


def _odometry_gaps(ch: RawChannel, source: str) -> list[tuple[float, float, str]]:
    """Stretches an odometry channel does not cover: its time stamps jump by more than
    :data:`ODOMETRY_GAP_FACTOR` median intervals (OdometryError if they do not increase)."""
    _finite_time(ch, source, OdometryError)
    d = np.diff(ch.t)
    if ch.t.size < 2 or not np.all(d > 0):
        raise OdometryError(f"{source}: channel {ch.name!r} needs at least two samples with increasing time stamps")
    j = np.flatnonzero(d > ODOMETRY_GAP_FACTOR * np.median(d))
    return [(float(ch.t[k]), float(ch.t[k + 1]), ch.name) for k in j]


def _unit_check(ch: RawChannel, row: pd.Series, source: str) -> None:
    file_unit = normalise_unit(ch.unit)
    if file_unit and file_unit != row["unit"]:
        raise ChannelError(f"{source}: channel {ch.name!r} is recorded in {ch.unit!r} but the sensor table says "
                           f"{row['unit']!r} (sensitivity {row['sensitivity']:g}); correct the table or the file")


def _level_check(values: np.ndarray, row: pd.Series, source: str) -> None:
    """Refuse an acceleration channel whose level no axlebox produces (:data:`estimator.qc.ACC_RMS_MAX_G`,
    :data:`estimator.qc.ACC_GLITCH_MAX_SHARE`): a unit or scaling error (ChannelError naming the channel, its unit
    and sensitivity). Isolated samples beyond :data:`estimator.qc.ACC_GLITCH_G` are left to quality control
    (glitches) and do not count towards the RMS."""
    sens = float(row["sensitivity"])
    x = values[np.isfinite(values)] * sens
    if x.size == 0:
        return
    over = np.abs(x) > ACC_GLITCH_MS2
    share = float(over.mean())
    rest = x[~over]
    rms = float(np.sqrt(np.mean(rest ** 2))) if rest.size else math.inf
    if share > ACC_GLITCH_MAX_SHARE or rms > ACC_RMS_MAX_MS2:
        rms_all = float(np.sqrt(np.mean(x ** 2)))
        raise ChannelError(
            f"{source}: channel {row['name']!r} (unit {row['unit']!r}, sensitivity {sens:g}): RMS {rms_all / G0:.4g} g "
            f"({rms_all:.4g} m/s^2) over the run, {100 * share:.3g} % of its samples beyond {ACC_GLITCH_G:g} g (peak "
            f"{float(np.max(np.abs(x))) / G0:.4g} g); an axlebox acceleration stays below {ACC_RMS_MAX_G:g} g RMS "
            f"and {ACC_GLITCH_G:g} g peak: raw ADC counts or mV without a conversion, or a wrong unit or sensitivity "
            "in the sensor table?")


def _unusable(raw: RawRecording, name: str, source: str, error: type[Exception]) -> None:
    """Raise ``error`` when the file holds ``name`` but not as a usable channel (ambiguous, not numeric)."""
    if name in raw.unusable:
        raise error(f"{source}: channel {name!r} of the sensor table cannot be used: {raw.unusable[name]}")


def _header(raw: RawRecording, source: str, direction: str | None) -> RunHeader:
    h = {k.strip(): str(v).strip() for k, v in raw.header.items()}
    if direction is None:
        direction = h.get("direction", "")
        if not direction:
            raise RunFileError(f"{source}: the run header has no 'direction' ({DIRECTIONS}, relative to chainage); "
                               "give it with --direction")
        if direction not in DIRECTIONS:
            raise RunFileError(f"{source}: header direction must be one of {DIRECTIONS} (relative to chainage), got "
                               f"{direction!r}; correct the header or give --direction")
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


def _speed_from_position(t: np.ndarray, pos: np.ndarray) -> np.ndarray:
    """Speed along chainage [m/s] from an odometer position (module docstring): reset and glitch steps replaced by
    the running median of their neighbours, then a central difference over :data:`DERIVED_SPEED_WINDOW_S`."""
    from scipy.ndimage import median_filter

    ok = np.isfinite(pos)
    p = np.interp(t, t[ok], pos[ok]) if not ok.all() else pos
    step = np.diff(p)
    dt = np.diff(t)
    w = 2 * max(2, int(round(DERIVED_SPEED_WINDOW_S / np.median(dt) / 2))) + 1
    rate = median_filter(step / dt, size=w, mode="nearest")
    dev = step - rate * dt
    mad = float(np.median(np.abs(dev - np.median(dev))))
    odd = np.abs(dev) > DERIVED_STEP_TOLERANCE_M + 5 * mad
    step = np.where(odd, rate * dt, step)
    d = np.concatenate([[0.0], np.cumsum(step)])
    h = DERIVED_SPEED_WINDOW_S / 2
    a, b = np.maximum(t - h, t[0]), np.minimum(t + h, t[-1])
    return (np.interp(b, t, d) - np.interp(a, t, d)) / (b - a)


def _position_from_speed(t: np.ndarray, speed: np.ndarray, balise_t: np.ndarray, balise_c: np.ndarray,
                         travel_sign: int) -> np.ndarray:
    """An odometer's position from a speed channel (module docstring): the distance integrated along the direction
    of travel (trapezoid; the speed's prevailing sign is taken as that direction, whatever the encoder's convention),
    reset to each balise's chainage plus the distance counted since its passage."""
    ok = np.isfinite(speed)
    v = np.interp(t, t[ok], speed[ok]) if not ok.all() else speed
    moving = np.abs(v) > 0.5
    along = -v if moving.any() and np.median(v[moving]) < 0 else v
    dist = np.concatenate([[0.0], np.cumsum(0.5 * (along[1:] + along[:-1]) * np.diff(t))])
    pos = travel_sign * dist
    for tb, cb in sorted(zip(balise_t, balise_c)):
        j = int(np.searchsorted(t, tb - 1e-9))  # the first sample after the passage, as a unit stamps its reset
        if j < t.size:
            pos[j:] = cb + travel_sign * (dist[j:] - np.interp(tb, t, dist))
    return pos


def _nan_stretches(ch: RawChannel) -> list[tuple[float, float, str]]:
    """Stretches a channel holds no finite value for, between the finite samples around them."""
    from estimator.qc import runs_of

    out = []
    for a, b in runs_of(~np.isfinite(ch.values)):
        out.append((float(ch.t[max(a - 1, 0)]), float(ch.t[min(b, ch.t.size - 1)]), ch.name))
    return out


SAMPLED_BALISE_REPEAT_SHARE = 0.5
"""A balise channel most of whose samples repeat the one before is sampled (the logger holds the last telegram's
chainage, or an idle value between telegrams), not an event list (one sample per passage)."""


def _balise_passages(t: np.ndarray, v: np.ndarray, name: str, source: str) -> tuple[np.ndarray, np.ndarray]:
    """The balise passages (time, chainage) of a balise channel.

    An event list (one sample per passage) is returned as it is. A sampled channel
    (:data:`SAMPLED_BALISE_REPEAT_SHARE`) has a passage where its value changes: the first sample with a new value.
    Its first value is a telegram received before the run (or the logger's idle value), and a return to it is the
    logger going idle between telegrams (a pulse-style channel); neither is a passage. Both are logged.
    """
    if t.size < 3:
        return t, v
    same = v[1:] == v[:-1]
    if same.mean() <= SAMPLED_BALISE_REPEAT_SHARE:
        return t, v
    change = np.flatnonzero(~same) + 1
    passage = change[v[change] != v[0]]
    log.warning("%s: balise channel %r is sampled (%d samples, %.0f %% repeating the one before), not one sample "
                "per passage: %d passage(s) taken where its value changes (at %s s); its first value %.3f m and "
                "returns to it are taken as held from before the run or idle", source, name, t.size,
                100 * same.mean(), passage.size, ", ".join(f"{x:.3f}" for x in t[passage][:10]), v[0])
    return t[passage], v[passage]


def _odometry(raw: RawRecording, sensors: pd.DataFrame, source: str, direction: str) -> tuple[Odometry, str]:
    """The run's odometry, and a processing note when one of speed and position is derived from the other."""
    rows = {q: sensors[sensors["quantity"] == q] for q in ("speed", "position", "balise")}
    got, gaps = {}, []
    for q in ("speed", "position"):
        if not len(rows[q]):
            continue
        name = str(rows[q]["name"].iloc[0])
        _unusable(raw, name, source, OdometryError)
        if name not in raw.channels:
            raise OdometryError(f"{source}: the {q} channel {name!r} of the sensor table is not in the file; the "
                                f"file has {sorted(raw.channels)}")
        ch = raw.channels[name]
        _unit_check(ch, rows[q].iloc[0], source)
        if not normalise_unit(ch.unit):
            # km/h read as m/s puts the run 3.6 times as far along the line, and nothing downstream can tell
            log.warning("%s: the %s channel %r carries no unit in the file: read in the sensor table's %r, which "
                        "the file cannot confirm", source, q, name, rows[q]["unit"].iloc[0])
        if ch.values.size < 2 or np.isfinite(ch.values).sum() < 2:
            raise OdometryError(f"{source}: the {q} channel {name!r} holds fewer than two finite values")
        # NaN in a recorded channel is a stretch it does not cover, like lost samples: odometry_track bridges a
        # short one (the other quantity or the chord carries it) and masks a long one
        gaps += _odometry_gaps(ch, source) + _nan_stretches(ch)
        got[q] = (name, ch, float(rows[q]["sensitivity"].iloc[0]))
    bt, bv, names = np.zeros(0), np.zeros(0), {q: n for q, (n, _, _) in got.items()}
    if len(rows["balise"]):
        bn = str(rows["balise"]["name"].iloc[0])
        _unusable(raw, bn, source, OdometryError)
        if bn in raw.channels:
            bc = raw.channels[bn]
            _unit_check(bc, rows["balise"].iloc[0], source)
            ok = np.isfinite(bc.values) & np.isfinite(bc.t)
            if not ok.all():
                # a passage whose chainage the logger could not decode resets the odometer to an unknown value:
                # odometry_track then sees an unexplained jump there and masks it up to the next balise
                log.warning("%s: balise channel %r: %d event(s) without a finite chainage ignored (at %s s); the "
                            "odometer reset there is unexplained", source, bn, int((~ok).sum()),
                            ", ".join(f"{x:.3f}" for x in bc.t[~ok][:10]))
            bt, bv = _balise_passages(bc.t[ok], bc.values[ok], bn, source)
            bv = bv * float(rows["balise"]["sensitivity"].iloc[0])
            names["balise"] = bn
        else:
            log.warning("%s: balise channel %r is not in the file; no odometer reset is known", source, bn)
    note, relative = "", False
    if "position" not in got:
        sn, sp, ss = got["speed"]
        t, speed = sp.t, sp.values * ss
        position = _position_from_speed(t, speed, bt, bv, 1 if direction == "forward" else -1)
        names["position"] = f"integrated from {sn}"
        relative = not bt.size
        note = (f"no position channel: the position integrated from speed {sn!r} along the direction of travel, "
                + ("counted from the run's start (no balise channel: chainage relative to the start)" if relative
                   else f"reset to the balise's chainage at each of {bt.size} passage(s)"))
    else:
        pn, pp, ps = got["position"]
        t, position = pp.t, pp.values * ps
        if "speed" in got:
            sn, sp, ss = got["speed"]
            speed = sp.values * ss
            if sp.t.shape != t.shape or not np.allclose(sp.t, t, rtol=0, atol=1e-9):
                speed = np.interp(t, sp.t, speed)
                log.info("%s: speed %r resampled onto the time base of position %r", source, sn, pn)
                # beyond the speed channel's own span interpolation would hold its end value (a train braking to
                # a stop would keep its speed, and pass the speed gate): the position's rate takes over there
                step = float(np.median(np.diff(sp.t)))
                beyond = (t < sp.t[0] - step) | (t > sp.t[-1] + step)
                if beyond.any():
                    speed[beyond] = _speed_from_position(t, position)[beyond]
                    log.warning("%s: speed %r covers %.3f-%.3f s, position %r %.3f-%.3f s: the speed outside its "
                                "span derived from the position (%d odometry samples)", source, sn, sp.t[0],
                                sp.t[-1], pn, t[0], t[-1], int(beyond.sum()))
        else:
            speed = _speed_from_position(t, position)
            names["speed"] = f"derived from {pn}"
            note = (f"no speed channel: the speed derived from position {pn!r} (central difference over "
                    f"{DERIVED_SPEED_WINDOW_S:g} s, reset and glitch steps replaced by the running median)")
    if note:
        # a chainage counted from the start cannot be placed on the line (curves, sections, trolley): say so loudly
        (log.warning if relative else log.info)("%s: %s", source, note)
    spans: dict[tuple[float, float], list[str]] = {}
    for g0, g1, name in gaps:  # both channels of one logger lose the same stretch: one gap
        spans.setdefault((g0, g1), []).append(name)
    return Odometry(t=t, speed=speed, position=position, balise_t=bt, balise_chainage=bv, names=names,
                    gaps=tuple((g0, g1, ", ".join(n)) for (g0, g1), n in sorted(spans.items()))), note


def assemble_run(raw: RawRecording, sensors: pd.DataFrame, source: str, fmt: str, *, fs: float | None = None,
                 direction: str | None = None) -> Run:
    """Build a :class:`Run` from a reader's output and a validated sensor table (module docstring)."""
    header = _header(raw, source, direction)
    odometry, derived = _odometry(raw, sensors, source, header.direction)
    acc_rows = sensors[sensors["quantity"] == "acceleration"].reset_index(drop=True)
    rejected: list[QCEvent] = []
    present, rates, grids = [], {}, {}
    unitless: list[str] = []
    for _, row in acc_rows.iterrows():
        name = str(row["name"])
        _unusable(raw, name, source, ChannelError)
        if name not in raw.channels:
            msg = (f"channel {name!r} (wheelset {row['wheelset']}, side {row['side']}, {row['direction']}) of the "
                   f"sensor table is missing from the file")
            log.warning("%s: %s", source, msg)
            rejected.append(QCEvent("missing_channel", name, math.nan, math.nan, msg, "rejected"))
            continue
        ch = raw.channels[name]
        _unit_check(ch, row, source)
        if not normalise_unit(ch.unit):
            unitless.append(f"{name} ({row['unit']})")
        rates[name], grids[name] = sample_grid(ch, source)
        if grids[name][-1] + 1 > MAX_SAMPLES:
            raise ChannelError(f"{source}: channel {name!r} spans {grids[name][-1] + 1} samples; at most "
                               f"{MAX_SAMPLES}")
        present.append(row)
    if unitless:
        log.warning("%s: acceleration channel(s) %s carry no unit in the file: read in the sensor table's units, "
                    "which the file cannot confirm", source, ", ".join(unitless))
    if not present:
        raise ChannelError(f"{source}: none of the acceleration channels of the sensor table "
                           f"{list(acc_rows['name'])} is in the file (it has {sorted(raw.channels)})")
    if fs is None:
        common = Counter(round(r, 6) for r in rates.values()).most_common(1)[0][0]
        fs_run = float(np.median([r for r in rates.values() if round(r, 6) == common]))
    else:
        fs_run = float(fs)
    if not fs_run >= MIN_ACCELERATION_RATE_HZ:
        names = [n for n, r in rates.items() if abs(r / fs_run - 1) <= RATE_RTOL]
        raise ChannelError(f"{source}: the acceleration channels {names} are sampled at {fs_run:.6g} Hz (time-stamp "
                           f"interval {1 / fs_run:.6g} s); an axlebox recording needs >= "
                           f"{MIN_ACCELERATION_RATE_HZ:g} Hz (the inversion band ends at 0.4 fs). Time stamps in ms or µs rather than s? (that would "
                           f"be {fs_run * 1e3:.6g} Hz or {fs_run * 1e6:.6g} Hz)")
    keep = []
    for row in present:
        name = str(row["name"])
        ch = raw.channels[name]
        # a rate a little off (another clock) keeps the first samples in place and drifts: judged by where the
        # channel's last sample falls on the run's time base, to the same GRID_ATOL as its first
        drift = (ch.t[-1] - ch.t[0]) * fs_run - (grids[name][-1] - grids[name][0])
        if abs(rates[name] / fs_run - 1) > RATE_RTOL:
            msg = (f"channel {name!r} is sampled at {rates[name]:.6g} Hz but the run's accelerations are at "
                   f"{fs_run:.6g} Hz")
        elif abs(drift) > GRID_ATOL:
            msg = (f"channel {name!r} is sampled at {rates[name]:.7g} Hz, {1e6 * (rates[name] / fs_run - 1):+.0f} ppm "
                   f"from the run's {fs_run:.7g} Hz: over its {ch.t[-1] - ch.t[0]:.1f} s it drifts {drift:+.2f} "
                   f"samples ({1e3 * drift / fs_run:+.2f} ms) off the other accelerations' time base (limit "
                   f"{GRID_ATOL:g} sample); not sampled simultaneously with them")
        else:
            keep.append(row)
            continue
        log.warning("%s: %s; channel rejected", source, msg)
        rejected.append(QCEvent("wrong_rate", name, math.nan, math.nan, msg, "rejected"))
    if len(keep) < 2:
        raise ChannelError(f"{source}: fewer than two acceleration channels are usable at {fs_run:g} Hz "
                           f"({[e.describe() for e in rejected]})")
    # the run spans every kept channel: a channel that starts late or ends early (a logger stopping one input, a
    # truncated export) is NaN where it has no sample, reported and masked there, and cuts none of the others
    t0 = min(raw.channels[str(r["name"])].t[0] for r in keep)
    t1 = max(raw.channels[str(r["name"])].t[-1] for r in keep)
    n = int(np.floor((t1 - t0) * fs_run + 1e-6)) + 1
    if n > MAX_SAMPLES:
        raise ChannelError(f"{source}: the acceleration channels together span {n} samples ({t0:.3f} to {t1:.3f} s); "
                           f"at most {MAX_SAMPLES}")
    data = np.full((len(keep), n), np.nan)
    gaps: list[QCEvent] = []
    for i, row in enumerate(keep):
        name = str(row["name"])
        ch = raw.channels[name]
        off = (ch.t[0] - t0) * fs_run
        k0 = int(round(off))
        if abs(off - k0) > 0.01:
            raise ChannelError(f"{source}: channel {name!r} starts {off - k0:+.3f} samples off the common time "
                               "base of the other accelerations; the estimator needs simultaneously sampled channels")
        values = _on_grid(ch, grids[name])
        data[i, k0:k0 + values.size] = values
        gaps += _time_gaps(ch, grids[name], fs_run, odometry)
        gaps += _short_ends(ch, name, k0, values.size, n, t0, fs_run, odometry)
    if n < 2:
        raise ChannelError(f"{source}: the acceleration channels hold fewer than two samples")
    for i, row in enumerate(keep):
        _level_check(data[i], row, source)
    for e in gaps:
        log.warning("%s: %s", source, e.describe())
    lost = f"; {len(gaps)} time-stamp gap(s), the samples lost masked" if gaps else ""
    table = pd.DataFrame(keep).reset_index(drop=True)
    run = Run(source=source, format=fmt, header=header, channels=table, fs=fs_run, t0=float(t0), acceleration=data,
              units=tuple(str(u) for u in table["unit"]), odometry=odometry, rejected=tuple(rejected + gaps),
              processing=(f"read {source} ({fmt}): {len(keep)} acceleration channels at {fs_run:g} Hz, "
                          f"{n / fs_run:.2f} s; odometry {odometry.names}; {odometry.balise_t.size} balise event(s); "
                          f"{len(rejected)} channel(s) rejected{lost}", *((derived,) if derived else ())))
    return run
