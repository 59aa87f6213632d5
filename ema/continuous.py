"""A continuous (throughput) recording of a hammer test, cut into hits.

Front ends record a hammer test either triggered, one record per hit (the UFF58 datasets of one hit number), or
continuously: one long record per channel in which the operator hit the wheelset every few seconds. Read as one
hit, a continuous record holds many force pulses and is rejected as "force not a pulse". :func:`split_continuous`
finds the impacts in the force and cuts every channel into one record per impact, as a trigger would have:

* An **impact** is a run of force samples beyond :data:`IMPACT_LEVEL` x the record's largest pulse (its largest
  ``|force|`` after a 3-sample median, which a corrupt single sample does not survive) and beyond
  :data:`NOISE_FACTOR` x the force noise (1.4826 x its median absolute deviation), in the sense of that pulse.
  Pulses closer than :data:`MIN_HIT_SEPARATION_S` to the one before are the same hit: a hammer's rebound comes
  within a few contact times (1–10 ms), an operator's next hit half a second or more later. So a double hit stays
  inside its hit's record, where the screening finds it. A pulse of one sample (both neighbours below
  :data:`SINGLE_SAMPLE_LEVEL` of it) is a corrupt sample, as the screening's "force not a pulse" says: not an
  impact, and named in a WARNING, so that it cannot shorten every record.
* Every record has the same length, so that the hits average into one FFT: the **shortest spacing** between
  successive impacts. Each starts a pre-trigger before its impact: :data:`PRE_TRIGGER_SHARE` of that length (the
  pre-trigger gives the screening its rest value), or less when the first impact comes sooner after the start.
  When the recording stops sooner after the last impact, all records are shortened to what it leaves, if that
  is at least :data:`MIN_LAST_SHARE` of them (the screening's ``min_record_after_share``); otherwise that last
  impact is left out with a WARNING naming its time. Nothing else is dropped: a weak or double hit is cut like
  any other and judged by the screening.

Only a test of one record (one hit) holding at least :data:`MIN_IMPACTS` impacts is cut: two pulses in one
triggered record are a double hit, not two hits.

Several files of one setup (:func:`ema.read_hammer` given a list) share one record length: continuous files are
cut at the shortest length any of them gives on its own (:func:`continuous_record_length`), or at the triggered
files' record length when some are triggered, provided every continuous file's impacts are that far apart.
"""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np
from scipy.ndimage import median_filter

from .hammer_io import HammerTest

__all__ = ["find_impacts", "split_continuous", "continuous_record_length", "IMPACT_LEVEL", "NOISE_FACTOR",
           "MIN_HIT_SEPARATION_S", "PRE_TRIGGER_SHARE", "MIN_IMPACTS", "MIN_LAST_SHARE", "SINGLE_SAMPLE_LEVEL"]

log = logging.getLogger("ema")

#: share of the record's largest |force| an impact must exceed (weak taps are cut too, and judged by the screening)
IMPACT_LEVEL = 0.1
#: an impact must also exceed this many force-noise RMS
NOISE_FACTOR = 10.0
#: pulses closer than this to the one before belong to one hit (a rebound); an operator hits less often
MIN_HIT_SEPARATION_S = 0.1
#: the pre-trigger of each cut record, as a share of its length
PRE_TRIGGER_SHARE = 0.05
#: a pulse whose two neighbours are below this share of its peak is a single corrupt sample, not an impact
SINGLE_SAMPLE_LEVEL = 0.05
#: fewest impacts for a single record to be taken as a continuous recording
MIN_IMPACTS = 3
#: all records are shortened to the last impact's when it keeps at least this share of them after the impact
MIN_LAST_SHARE = 0.75


def _pulses(force: np.ndarray, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """Sample index of each pulse's largest force, and whether it is a single (corrupt) sample."""
    f = np.asarray(force, float)
    med = float(np.median(f))
    noise = 1.4826 * float(np.median(np.abs(f - med)))
    # the level is the largest pulse's after a 3-sample median, which a corrupt single sample does not survive
    smooth = median_filter(f - med, size=3, mode="nearest")
    k_max = int(np.argmax(np.abs(smooth)))
    sign = 1.0 if smooth[k_max] >= 0 else -1.0
    h = sign * (f - med)
    idx = np.flatnonzero(h > max(IMPACT_LEVEL * sign * smooth[k_max], NOISE_FACTOR * noise))
    if idx.size == 0:
        return np.zeros(0, np.int64), np.zeros(0, bool)
    gap = int(round(MIN_HIT_SEPARATION_S * fs))
    starts = np.concatenate([[0], np.flatnonzero(np.diff(idx) > gap) + 1])
    ends = np.concatenate([starts[1:], [idx.size]])
    peaks = np.array([idx[a] + int(np.argmax(h[idx[a]:idx[b - 1] + 1])) for a, b in zip(starts, ends)], np.int64)
    left = h[np.maximum(peaks - 1, 0)]
    right = h[np.minimum(peaks + 1, f.size - 1)]
    single = (left < SINGLE_SAMPLE_LEVEL * h[peaks]) & (right < SINGLE_SAMPLE_LEVEL * h[peaks])
    return peaks, single


def find_impacts(force: np.ndarray, fs: float) -> np.ndarray:
    """Sample index of each impact's largest force in a continuous force record (module docstring)."""
    peaks, single = _pulses(force, fs)
    return peaks[~single]


def _impacts(test: HammerTest) -> tuple[np.ndarray, np.ndarray] | None:
    """The impacts and corrupt single samples of a continuous recording; None when the test is not one."""
    if test.n_hits != 1:
        return None
    peaks, single = _pulses(test.force[0], test.fs)
    if int((~single).sum()) < MIN_IMPACTS:
        return None
    return peaks[~single], peaks[single]


def _natural_length(test: HammerTest, peaks: np.ndarray) -> int:
    """The record length a recording gives on its own: the shortest spacing, or less to keep the last impact."""
    length = int(np.min(np.diff(peaks)))
    tail = test.n_samples - int(peaks[-1])
    if MIN_LAST_SHARE * (length - _pre_trigger(length, peaks)) <= tail < length - _pre_trigger(length, peaks):
        # the longest record whose part after its own pre-trigger the tail holds
        length = int(tail / (1.0 - PRE_TRIGGER_SHARE)) + 1
        while length - _pre_trigger(length, peaks) > tail:
            length -= 1
    return length


def _pre_trigger(length: int, peaks: np.ndarray) -> int:
    """Samples before each impact in a record of ``length``: its share, or less when the first impact is sooner."""
    return min(int(round(PRE_TRIGGER_SHARE * length)), int(peaks[0]))


def continuous_record_length(test: HammerTest) -> int | None:
    """Samples per hit :func:`split_continuous` would cut ``test`` into; None when it is no continuous recording.

    Several continuous files of one setup are cut at the shortest of their lengths, so that all their hits
    average into one FFT (:func:`ema.read_hammer` with a list of files).
    """
    found = _impacts(test)
    return None if found is None else _natural_length(test, found[0])


def split_continuous(test: HammerTest, length: int | None = None) -> HammerTest:
    """The test cut into one hit per impact when its one record is a continuous recording; else the test as is.

    Parameters
    ----------
    test : HammerTest
    length : int, optional
        Samples per cut record; by default the recording's own (the shortest spacing between its impacts, see
        the module docstring). A given length longer than that spacing would put two impacts in one record:
        ``ValueError``. Impacts without a whole record after their pre-trigger are left out with a WARNING.

    Returns
    -------
    HammerTest
        Hits numbered 1, 2, ... in time order; the cut recorded in ``history`` and logged (WARNING, with the
        impacts' times and the record length).
    """
    found = _impacts(test)
    if found is None:
        return test
    peaks, corrupt = found
    src = test.source or "hammer test"
    for k in corrupt:
        log.warning("%s: a single force sample of %.4g N at t = %.4f s is no hammer pulse (a corrupt sample): not "
                    "taken as an impact", src, test.force[0][k], test.time[0] + k / test.fs)
    spacing = int(np.min(np.diff(peaks)))
    if length is None:
        length = _natural_length(test, peaks)
    elif length > spacing:
        raise ValueError(f"{src}: records of {length / test.fs:.3f} s asked for, but impacts come "
                         f"{spacing / test.fs:.3f} s apart: a record would hold two impacts")
    length = int(length)
    pre = _pre_trigger(length, peaks)
    starts = peaks - pre
    fits = starts + length <= test.n_samples
    for k in np.flatnonzero(~fits):
        log.warning("%s: the impact at t = %.3f s is followed by %.3f s of record, less than the %.3f s every other "
                    "hit's record has; left out", src, test.time[0] + peaks[k] / test.fs,
                    (test.n_samples - peaks[k]) / test.fs, (length - pre) / test.fs)
    starts = starts[fits]
    if starts.size < 2:
        return test
    cut = np.stack([np.arange(s, s + length) for s in starts])
    force = test.force[0][cut]
    responses = np.transpose(test.responses[0][:, cut], (1, 0, 2))
    times = ", ".join(f"{test.time[0] + (s + pre) / test.fs:.2f}" for s in starts)
    step = (f"split_continuous: one {test.n_samples / test.fs:.3f} s record holding {peaks.size} impacts cut into "
            f"{starts.size} hits of {length / test.fs:.3f} s ({pre / test.fs * 1e3:.0f} ms pre-trigger), impacts at "
            f"t = {times} s")
    log.warning("%s: a continuous recording: %s", src, step.split(": ", 1)[1])
    return replace(test, time=test.time[0] + np.arange(length) / test.fs + starts[0] / test.fs, force=force,
                   responses=responses, hits=tuple(range(1, starts.size + 1)), history=test.history + (step,))
