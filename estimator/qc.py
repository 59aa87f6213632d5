"""Quality control of a run before anything is inverted or averaged: every finding masked and logged.

Per acceleration channel:

* **dropouts** — NaN samples, and *flat* segments where the front end holds
  its last value (``≥ flat_min_s`` of bit-identical consecutive samples: a
  live 24-bit channel with sensor noise never repeats a value that long);
* **glitches** — samples beyond :data:`ACC_GLITCH_G` (500 g), which no axlebox
  produces: corrupt samples, masked, and never taken for clipping (the
  other wheelset's rail coupling does not take them at full scale);
* **clipping** — samples at the channel's largest magnitude that recur
  (``≥ clip_min_samples`` samples within 0.1 % of the extreme: a signal that
  merely peaks once is not clipped); the whole excursion beyond 99 % of that
  level is masked.

For the whole run (every channel):

* **low speed / standstill** — speed along the direction of travel below
  ``speed_gate_m_s`` (below ``standstill_m_s`` it is logged as standstill);
* **reversing** — negative speed along the direction of travel, or a
  chainage that runs backwards;
* **odometry** — stretches whose balise resets imply an implausible odometer
  scale (:func:`estimator.spatial.odometry_track`).

Each finding is a :class:`~estimator.run.QCEvent` (kind, channel, time and
chainage range, reason, action) logged at WARNING; masked samples are never
interpolated over (the inversion splits the run at them). Channels rejected
while reading (missing, wrong rate) and the samples the recording lost (time-stamp gaps, NaN in the run and
masked as dropouts) are carried into the events.
"""

from __future__ import annotations

import logging

import numpy as np

from estimator.config import EstimatorConfig
from estimator.run import QCEvent, QCMask, Run
from estimator.spatial import OdometryTrack

__all__ = ["check_run", "runs_of", "dropouts", "flat_segments", "clipped", "glitches", "ACC_GLITCH_G",
           "ACC_RMS_MAX_G", "ACC_GLITCH_MAX_SHARE"]

log = logging.getLogger("estimator")

G0 = 9.80665
#: Largest acceleration [g] an axlebox of a metro or tram produces. Measured axlebox peaks stay in the tens of g on
#: plain track and reach 50-100 g at rail joints, crossings and welds and a few hundred g under a severe wheel flat;
#: axlebox accelerometers are rated ±500 g (ICP shock types). A sample beyond it is no measurement but a corrupt
#: sample (a bit error, a front end's overflow code): a glitch, masked as such (kind ``glitch``) on its channel —
#: never taken as the clip level of a saturated channel, and never fed to the other wheelset's rail coupling as
#: a recorded full-scale value.
ACC_GLITCH_G = 500.0
ACC_GLITCH_MS2 = ACC_GLITCH_G * G0
#: Largest RMS acceleration [g] of an axlebox channel over a run. A metro's axlebox runs at a few g RMS (the virtual
#: line's about 0.4 g at 9 m/s), up to ~10-20 g over severe corrugation at speed; 100 g RMS is 5-10 times beyond any
#: of them. A channel at that level is in the wrong unit or scale (ADC counts or mV read as g, a sensitivity
#: applied twice): :func:`estimator.io.assemble.assemble_run` refuses it (ChannelError naming the channel, its unit
#: and sensitivity).
ACC_RMS_MAX_G = 100.0
ACC_RMS_MAX_MS2 = ACC_RMS_MAX_G * G0
#: Largest share of a channel's samples beyond :data:`ACC_GLITCH_G` that can still be isolated glitches (1 %: ten
#: corrupt samples a second at 1 kHz); more says the whole channel is off scale (a unit error), refused like a high
#: RMS.
ACC_GLITCH_MAX_SHARE = 0.01


def runs_of(flag: np.ndarray, max_gap: int = 0) -> list[tuple[int, int]]:
    """Half-open index ranges ``[i, j)`` where ``flag`` is True; runs separated by at most ``max_gap`` False
    samples are one (an event that flickers)."""
    f = np.asarray(flag, bool)
    if not f.any():
        return []
    d = np.diff(np.concatenate([[0], f.view(np.int8), [0]]))
    starts = np.flatnonzero(d == 1)
    ends = np.flatnonzero(d == -1)
    if max_gap > 0:
        keep = np.concatenate([[True], starts[1:] - ends[:-1] > max_gap])
        starts, ends = starts[keep], ends[np.concatenate([keep[1:], [True]])]
    return list(zip(starts.tolist(), ends.tolist()))


def _grow(flag: np.ndarray, n: int) -> np.ndarray:
    if n <= 0 or not flag.any():
        return flag
    idx = np.flatnonzero(np.diff(np.concatenate([[0], flag.view(np.int8), [0]])))
    out = flag.copy()
    for a, b in zip(idx[::2], idx[1::2]):
        out[max(a - n, 0):min(b + n, flag.size)] = True
    return out


def dropouts(x: np.ndarray) -> np.ndarray:
    """NaN (or infinite) samples."""
    return ~np.isfinite(x)


def glitches(x: np.ndarray) -> np.ndarray:
    """Finite samples beyond :data:`ACC_GLITCH_MS2` (an acceleration in m/s² no axlebox produces)."""
    with np.errstate(invalid="ignore"):
        return np.isfinite(x) & (np.abs(x) > ACC_GLITCH_MS2)


def flat_segments(x: np.ndarray, min_len: int) -> np.ndarray:
    """Samples inside runs of ≥ ``min_len`` bit-identical consecutive finite values."""
    same = np.zeros(x.size, bool)
    if x.size < 2:
        return same
    eq = (x[1:] == x[:-1]) & np.isfinite(x[1:])
    out = np.zeros(x.size, bool)
    for a, b in runs_of(eq):
        if b - a + 1 >= min_len:
            out[a:b + 1] = True
    return out


def clipped(x: np.ndarray, min_samples: int) -> tuple[np.ndarray, float]:
    """Clipped excursions of a channel and the clip level (0 when none).

    The level is the largest magnitude; the channel is clipped when at least
    ``min_samples`` samples sit within 0.1 % of it (a saturated ADC or
    amplifier holds its rail); every sample beyond 99 % of the level is
    flagged.
    """
    a = np.abs(x[np.isfinite(x)])
    if a.size == 0:
        return np.zeros(x.size, bool), 0.0
    level = float(a.max())
    if level == 0:
        return np.zeros(x.size, bool), 0.0
    at_rail = np.abs(x) >= level * (1 - 1e-3)
    if int(np.nansum(at_rail)) < min_samples:
        return np.zeros(x.size, bool), 0.0
    return np.nan_to_num(np.abs(x), nan=0.0) >= 0.99 * level, level


def _events(kind: str, channel: str, flag: np.ndarray, t: np.ndarray, chain: np.ndarray, reason: str,
            merge: int) -> list[QCEvent]:
    """One event per run of flagged samples; runs closer than ``merge`` samples are reported as one."""
    spans: list[list[int]] = []
    for a, b in runs_of(flag):
        if spans and a - spans[-1][1] < merge:
            spans[-1][1] = b
        else:
            spans.append([a, b])
    out = []
    for a, b in spans:
        c0, c1 = sorted((float(chain[a]), float(chain[b - 1])))
        out.append(QCEvent(kind, channel, float(t[a]), float(t[b - 1]), reason, "masked", c0, c1))
    return out


def check_run(run: Run, track: OdometryTrack, config: EstimatorConfig = EstimatorConfig()) -> Run:
    """Quality control (module docstring): the run with its :class:`~estimator.run.QCMask` set.

    Parameters
    ----------
    run : Run
        With sensitivities applied.
    track : OdometryTrack
        The run's continuous chainage (:func:`estimator.spatial.odometry_track`).
    config : EstimatorConfig
    """
    t = run.t
    chain = track.chainage_at(t)
    speed = track.speed_at(t)
    fs = run.fs
    margin = int(round(config.mask_margin_s * fs))
    merge = int(round(0.1 * fs))
    n_ch, n = run.acceleration.shape
    masked = np.zeros((n_ch, n), bool)
    saturated = np.zeros((n_ch, n), bool)
    events: list[QCEvent] = list(run.rejected)
    for i, name in enumerate(run.names):
        x = run.acceleration[i]
        nan = dropouts(x)
        # samples the logger lost are NaN too; the reading already reported them as time gaps
        lost = np.zeros(n, bool)
        for e in run.rejected:
            if e.kind == "time_gap" and e.channel == name:
                lost |= (t >= e.t_start - 0.5 / fs) & (t <= e.t_end + 0.5 / fs)
        glitch = glitches(x)
        # a glitch is neither the clip level nor part of a held value: both are judged on the rest
        xq = np.where(glitch, np.nan, x) if glitch.any() else x
        flat = flat_segments(xq, max(2, int(round(config.flat_min_s * fs))))
        clip, level = clipped(xq, config.clip_min_samples)
        peak = float(np.max(np.abs(x[glitch]))) if glitch.any() else 0.0
        for flag, kind, reason in (
                (nan & ~lost & ~np.isinf(x), "dropout_nan", "no data (NaN) in the recording"),
                (np.isinf(x), "non_finite", "infinite values (+/-inf) in the recording: an overflow or corrupt "
                                            "samples, not a measurement"),
                (glitch, "glitch", f"{int(glitch.sum())} sample(s) beyond {ACC_GLITCH_G:g} g (up to {peak:.4g} m/s^2): "
                                   "no axlebox produces that, corrupt samples; masked, and left out of the other "
                                   "wheelset's rail coupling"),
                (flat, "dropout_flat", f"value held constant for >= {config.flat_min_s * 1e3:g} ms (front end "
                                       "holding its last sample)"),
                (clip & ~flat, "clipping", f"channel saturated at {level:.4g} m/s^2 (>= {config.clip_min_samples} "
                                           "samples at the extreme)")):
            if flag.any():
                events.extend(_events(kind, name, flag, t, chain, reason, merge))
        masked[i] = _grow(nan | flat | clip | glitch, margin)
        saturated[i] = masked[i] & ~_grow(nan | flat | glitch, margin)
    # whole-run findings
    reverse = (speed < -config.standstill_m_s)
    dchain = np.gradient(chain) * track.travel_sign if n > 1 else np.zeros(n)
    reverse |= dchain < -config.standstill_m_s / fs
    still = (np.abs(speed) < config.standstill_m_s) & ~reverse
    slow = (speed < config.speed_gate_m_s) & ~still & ~reverse
    untrusted = np.zeros(n, bool)
    for t0, t1 in track.untrusted:
        untrusted |= (t >= t0) & (t <= t1)
    # beyond the odometry's first and last sample the chainage and speed would be held constant: not measured
    # (within one odometry interval of them the hold is the sampling's own resolution, as between two samples)
    step = float(np.median(np.diff(track.t))) if track.t.size > 1 else 0.0
    beyond = (t < track.t[0] - step) | (t > track.t[-1] + step)
    if beyond.any():
        events.extend(_events("odometry_gap", "*", beyond, t, chain,
                              f"no odometry sample (the odometry covers {track.t[0]:.3f} to {track.t[-1]:.3f} s): "
                              "the chainage there is not measured", merge))
        untrusted |= beyond
    for flag, kind, reason in (
            (still, "standstill", f"|speed| below {config.standstill_m_s:g} m/s"),
            (slow, "low_speed", f"speed below the gate {config.speed_gate_m_s:g} m/s"),
            (reverse, "reversing", "moving against the run's direction of travel"),
    ):
        if flag.any():
            events.extend(_events(kind, "*", flag, t, chain, reason, merge))
    # odometry_scale: a run whose odometer scale no two balises correct (its chainage drifts; nothing is masked)
    events.extend(e for e in track.events if e.kind in ("odometry_jump", "odometry_inconsistent", "odometry_gap",
                                                        "odometry_scale"))
    run_mask = still | slow | reverse | untrusted
    masked |= run_mask[None, :]
    saturated &= ~run_mask[None, :]
    # the reading logged its own findings (rejected channels, time gaps) when it made them
    for e in events[len(run.rejected):]:
        if e.action in ("masked", "rejected"):
            log.warning("%s: %s", run.source, e.describe())
    mask = QCMask(masked, tuple(events), saturated)
    share = mask.share(run.names)
    return run.with_mask(mask, f"quality control: {len(events)} finding(s); masked share {100 * share['run']:.1f} % "
                               f"of the run (speed gate {config.speed_gate_m_s:g} m/s)")
