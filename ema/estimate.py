"""FRF estimation from impact-hammer hits: windows, H1/H2 and coherence.

For every hit the force ``f(t)`` and the accelerations ``a_j(t)`` are windowed
and Fourier transformed on the full ``rfft`` grid of the record (resolution
``fs / N``, 0.25 Hz for a 4 s record; no zero padding), then averaged over the
hits accepted for each channel (:mod:`ema.screening`)::

    S_ff = sum_h |F_h|^2,   S_fa = sum_h conj(F_h) A_h,   S_aa = sum_h |A_h|^2
    H1 = S_fa / S_ff,       H2 = S_aa / conj(S_fa),       gamma^2 = |S_fa|^2 / (S_ff S_aa) = H1 / H2

This is the thesis's estimator (section 3.3): with the linear model
``Y(f) = H(f) X(f)`` (eq. 3.1) and noise uncorrelated with the input,
``H1 = P_yx / P_xx`` (eq. 3.2), the cross spectrum of force and response over
the force auto spectrum, averaged over hits. H1 is unbiased by noise on the
response, H2 by noise on the force; their ratio is the ordinary coherence
(real, 0..1).

Windows
-------
*Force window* (:class:`ForceWindow`): the force record is kept over the main
pulse (from the first to the last sample above ``level`` x peak, plus
``pre_s`` / ``post_s`` margins) with a half-cosine taper of ``taper_s`` on
each side and zeroed elsewhere. It removes the force channel's noise from the
long record; the force is zero there anyway.

*Exponential window*: ``w(t) = exp(-a (t - t_hit))`` over the whole record,
``t_hit`` the start of the main pulse of the hit. Both windows are placed
per hit at its own pulse (sample index) on the test's time axis, so records
of different hits that started at different absolute times (trigger times,
sub-sample trigger jitter; :func:`ema.read_hammer`) give the same FRF: only
the alignment of force and responses within a hit matters. It makes lightly damped
responses decay within the record (no leakage). Its effect is exact and known:
if ``a(t) = (h * f)(t)`` then ``w a = (w h) * (w f)`` for an exponential ``w``,
so the windowed FRF is the true one evaluated at ``s = i omega + a``: every
pole ``lambda_r`` is shifted to ``lambda_r - a``. Identification therefore
corrects the damping exactly: ``sigma_true = sigma_identified - a`` (with
``sigma = -Re(lambda)``) and ``zeta_true = sigma_true / |lambda_true|`` from the
corrected pole. The decay ``a`` is recorded in
:attr:`FrequencyResponse.exp_window_decay`.

**The shift is exact only if the same window (same start time, same decay)
multiplies the force and every response of that hit.** :func:`estimate_frf`
does so; do not apply a different window to one of the channels: a response
window started ``dt`` later scales that FRF by ``exp(a dt)``, a different
decay (or an analyser's window clamped to 1 before a different start) distorts
it so that no single pole shift describes it.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .frf import FrequencyResponse
from .hammer_io import HammerTest

if TYPE_CHECKING:  # pragma: no cover
    from .screening import Screening

__all__ = [
    "ForceWindow",
    "estimate_frf",
    "auto_exp_decay",
    "main_pulse",
    "force_window",
    "exponential_window",
    "EstimationError",
]

log = logging.getLogger("ema")

#: Estimators understood by :func:`estimate_frf`.
ESTIMATORS = ("H1", "H2")


class EstimationError(ValueError):
    """An FRF cannot be estimated with the given data or arguments."""


@dataclass(frozen=True)
class ForceWindow:
    """Rectangular-with-cosine-tapers force window around the main pulse.

    Parameters
    ----------
    pre_s, post_s : float
        Flat margins before the pulse start and after the pulse end [s].
    taper_s : float
        Length of the half-cosine taper on each side [s].
    level : float
        The pulse extends from the first to the last sample (around the peak)
        whose force exceeds ``level`` x peak force.
    """

    pre_s: float = 1e-3
    post_s: float = 1e-3
    taper_s: float = 1e-3
    level: float = 0.05

    def __post_init__(self) -> None:
        for name in ("pre_s", "post_s", "taper_s"):
            v = getattr(self, name)
            if not np.isfinite(v) or v < 0:
                raise ValueError(f"ForceWindow.{name} must be finite and >= 0 s, got {v!r}")
        if not 0 < self.level < 1:
            raise ValueError(f"ForceWindow.level must be in (0, 1), got {self.level!r}")


def main_pulse(force: np.ndarray, level: float = 0.05) -> tuple[int, int, int, float]:
    """Locate the main force pulse of one hit.

    Parameters
    ----------
    force : ndarray (N,)
        Force record.
    level : float
        Fraction of the peak that delimits the pulse.

    Returns
    -------
    start, peak, end : int
        Sample indices: the contiguous run around the largest ``|force|``
        where ``sign * force > level * |peak|`` (``sign`` of the peak) is
        ``start..end`` inclusive.
    sign : float
        +1 or -1, the sign of the peak (a sensor mounted the other way round
        records negative pulses).
    """
    f = np.asarray(force, dtype=float)
    ip = int(np.argmax(np.abs(f)))
    sign = 1.0 if f[ip] >= 0 else -1.0
    above = sign * f > level * abs(f[ip])
    below = np.flatnonzero(~above)
    before = below[below < ip]
    after = below[below > ip]
    start = int(before[-1] + 1) if before.size else 0
    end = int(after[0] - 1) if after.size else f.size - 1
    return start, ip, end, sign


def force_window(n: int, fs: float, start: int, end: int, spec: ForceWindow) -> np.ndarray:
    """The force window (see :class:`ForceWindow`) for a pulse spanning samples ``start..end``."""
    i = np.arange(n, dtype=float)
    lo = start - spec.pre_s * fs
    hi = end + spec.post_s * fs
    tap = spec.taper_s * fs
    w = ((i >= lo) & (i <= hi)).astype(float)
    if tap > 0:
        left = (i < lo) & (i > lo - tap)
        w[left] = 0.5 * (1 + np.cos(np.pi * (lo - i[left]) / tap))
        right = (i > hi) & (i < hi + tap)
        w[right] = 0.5 * (1 + np.cos(np.pi * (i[right] - hi) / tap))
    return w


def exponential_window(time: np.ndarray, t_hit: float, decay: float) -> np.ndarray:
    """``exp(-decay (t - t_hit))`` over the whole record (values > 1 before the hit).

    A pure exponential (not clamped to 1 before ``t_hit``) keeps the pole shift
    exact whatever the signals do before the hit.
    """
    return np.exp(-decay * (np.asarray(time, dtype=float) - t_hit))


def _pulses(test: HammerTest, level: float) -> list[tuple[int, int, int, float]]:
    return [main_pulse(test.force[h], level) for h in range(test.n_hits)]


#: the fewest pre-trigger samples a rest value is taken from; with fewer the record is taken about zero
MIN_PRETRIGGER_SAMPLES = 16


def rest_values(test: HammerTest, level: float = 0.05, *, pulses: list | None = None
                ) -> tuple[np.ndarray, np.ndarray]:
    """The rest value of every record, from its pre-trigger: ``(force (n_hits,), responses (n_hits, n_ch))``.

    A DC-coupled accelerometer records gravity or its bias as a constant, which the exponential window turns into
    a spectrum falling as 1/f across the band, incoherent with the force. The spectra (:func:`_spectra`), the decay
    estimate and the level checks (:mod:`ema.screening`) take each record about its rest value, as an AC-coupled
    input would; the records stay as read. The rest value is the median of the samples before the main pulse, ending
    one pulse width before its start (:func:`main_pulse`): before the hit the structure is at rest, whereas over the
    whole record a slow rig swing or a response not yet decayed moves the median off the rest value. A hit with
    fewer than :data:`MIN_PRETRIGGER_SAMPLES` such samples is taken about zero. ``pulses``: the hits'
    :func:`main_pulse` at ``level`` when the caller has them already.
    """
    f_rest = np.zeros(test.n_hits)
    a_rest = np.zeros((test.n_hits, test.n_channels))
    for h, (start, _, end, _) in enumerate(_pulses(test, level) if pulses is None else pulses):
        stop = start - (end - start + 1)
        if stop >= MIN_PRETRIGGER_SAMPLES:
            f_rest[h] = np.median(test.force[h, :stop])
            a_rest[h] = np.median(test.responses[h][:, :stop], axis=1)
    return f_rest, a_rest


def auto_exp_decay(test: HammerTest, *, target: float = 1e-4, accepted: np.ndarray | None = None,
                   level: float = 0.05) -> float:
    """Exponential-window decay making the slowest response fall to ``target`` by the record end.

    The natural decay rate of every channel is estimated from the RMS of its
    response (summed over the accepted hits) in an early segment (5–15 % of
    the time after the hit) and in the last 10 % of the record:
    ``sigma_j = ln(rms_early / rms_late) / dt``. The slowest channel sets
    ``a = ln(1 / target) / T - min_j sigma_j`` (``T``: hit to record end),
    clipped at 0. A noise floor in the late segment makes ``sigma_j`` smaller,
    hence ``a`` larger: the choice errs on the safe side.

    Parameters
    ----------
    test : HammerTest
    target : float
        Envelope ratio wanted at the record end (0 < target < 1).
    accepted : ndarray bool (n_hits, n_ch), optional
        Hit x channel cells to use (default all).
    level : float
        Pulse level (see :func:`main_pulse`).

    Returns
    -------
    float
        Decay ``a`` [1/s].
    """
    if not 0 < target < 1:
        raise ValueError(f"target must be in (0, 1), got {target!r}")
    mask = np.ones((test.n_hits, test.n_channels), bool) if accepted is None else np.asarray(accepted, bool)
    pulses = _pulses(test, level)
    t = test.time
    t_hit = float(np.median([t[p[0]] for p in pulses]))
    T = float(t[-1] - t_hit)
    if T <= 0:
        raise EstimationError(f"{test.source or 'hammer test'}: the hit is at the end of the record")
    early = (t >= t_hit + 0.05 * T) & (t <= t_hit + 0.15 * T)
    late = t >= t[-1] - 0.1 * T
    if early.sum() < 2 or late.sum() < 2:
        return float(np.log(1 / target) / T)
    e2 = np.zeros(test.n_channels)
    l2 = np.zeros(test.n_channels)
    rest = rest_values(test, level)[1]
    for h in range(test.n_hits):
        m = mask[h]
        if not m.any():
            continue
        r = test.responses[h][m] - rest[h, m, None]
        e2[m] += np.mean(r[:, early] ** 2, axis=1)
        l2[m] += np.mean(r[:, late] ** 2, axis=1)
    ok = (e2 > 0) & (l2 > 0)
    dt_seg = float(np.mean(t[late]) - np.mean(t[early]))
    if ok.any():
        rates = 0.5 * np.log(e2[ok] / l2[ok]) / dt_seg
        slowest = max(float(rates.min()), 0.0)
    else:
        slowest = 0.0
    return float(max(np.log(1 / target) / T - slowest, 0.0))


def _band_lines(test: HammerTest, band_hz: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = (float(b) for b in band_hz)
    nyq = test.fs / 2
    src = test.source or "hammer test"
    if not (0 <= lo < hi <= nyq):
        raise EstimationError(
            f"{src}: band_hz must satisfy 0 <= low < high <= fs/2 = {nyq:g} Hz (sampled at {test.fs:g} Hz), got "
            f"({lo:g}, {hi:g})"
        )
    f = np.fft.rfftfreq(test.n_samples, d=1.0 / test.fs)
    idx = np.flatnonzero((f >= lo) & (f <= hi))
    if idx.size == 0:
        raise EstimationError(f"{src}: band_hz ({lo:g}, {hi:g}) holds no frequency line of the {f[1]:g} Hz grid")
    return f[idx], idx


def _spectra(test: HammerTest, accepted: np.ndarray, band_hz: tuple[float, float],
             fwin: ForceWindow | None, decay: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Averaged auto/cross spectra over the accepted cells.

    Returns ``freqs (nf,)``, ``S_ff (n_ch, nf)``, ``S_fa (n_ch, nf)`` complex, ``S_aa (n_ch, nf)``.
    """
    freqs, idx = _band_lines(test, band_hz)
    nch, nf = test.n_channels, idx.size
    sff = np.zeros((nch, nf))
    sfa = np.zeros((nch, nf), complex)
    saa = np.zeros((nch, nf))
    level = fwin.level if fwin is not None else 0.05
    n = test.n_samples
    pulses = _pulses(test, level)
    f_rest, a_rest = rest_values(test, level, pulses=pulses)
    for h in range(test.n_hits):
        m = accepted[h]
        if not m.any():
            continue
        start, _, end, _ = pulses[h]
        w_exp = exponential_window(test.time, float(test.time[start]), decay) if decay > 0 else np.ones(n)
        w_f = w_exp if fwin is None else w_exp * force_window(n, test.fs, start, end, fwin)
        F = np.fft.rfft((test.force[h] - f_rest[h]) * w_f)[idx]
        A = np.fft.rfft((test.responses[h][m] - a_rest[h, m, None]) * w_exp, axis=1)[:, idx]
        sff[m] += (F.real ** 2 + F.imag ** 2)[None, :]
        sfa[m] += np.conj(F)[None, :] * A
        saa[m] += A.real ** 2 + A.imag ** 2
    return freqs, sff, sfa, saa


def estimate_frf(
    test: HammerTest,
    *,
    band_hz: tuple[float, float] = (10.0, 500.0),
    force_window: ForceWindow | None = ForceWindow(),
    exp_window_decay: float | None = None,
    screening: "Screening | None | bool" = None,
    estimator: str = "H1",
) -> FrequencyResponse:
    """Accelerance FRFs (force -> every accelerometer) averaged over the accepted hits.

    Parameters
    ----------
    test : HammerTest
        The hits (:func:`ema.read_hammer` or :meth:`HammerTest.from_arrays`).
    band_hz : (float, float)
        Band kept from the full ``rfft`` grid of the record (inclusive).
    force_window : ForceWindow or None
        Force window (see the module docstring); None keeps the whole force record.
    exp_window_decay : float or None
        Decay ``a`` [1/s] of the exponential window applied to force and
        responses; ``None`` chooses it with :func:`auto_exp_decay` (slowest
        response down to 1e-4 at the record end); ``0`` applies none.
    screening : Screening, None or False
        Which hit x channel cells to average: a :class:`~ema.screening.Screening`;
        ``None`` (default) screens the hits here with
        :func:`~ema.screening.screen_hits` and the same windows and band (every
        rejection is logged); ``False`` averages every hit of every channel
        (no screening — for comparison only).
    estimator : {"H1", "H2"}
        ``H1 = S_fa / S_ff`` (default; thesis eq. 3.2, unbiased by response noise) or
        ``H2 = S_aa / conj(S_fa)`` (unbiased by force noise). The other one is
        always recoverable: ``H2 = H1 / coherence``.

    Returns
    -------
    FrequencyResponse
        Accelerance [m/s^2/N], outputs = the channel names with at least one
        accepted hit (a channel rejected in every hit is left out, with a
        WARNING), input = the force channel name; ``coherence`` the ordinary
        coherence, ``n_averages`` the number of hits averaged per output,
        ``exp_window_decay`` = ``a`` (the poles of the data are shifted by
        ``-a``; see the module docstring), ``channels`` the outputs' rows of
        the channel table.

    Raises
    ------
    EstimationError
        Bad band, estimator, decay, or a screening that does not belong to ``test``.
    """
    if estimator not in ESTIMATORS:
        raise EstimationError(f"estimator must be one of {ESTIMATORS}, got {estimator!r}")
    if force_window is not None and not isinstance(force_window, ForceWindow):
        raise EstimationError(f"force_window must be a ForceWindow or None, got {force_window!r}")
    src = test.source or "hammer test"
    _band_lines(test, band_hz)  # validate early
    if screening is None:
        from .screening import screen_hits

        screening = screen_hits(test, band_hz=band_hz, force_window=force_window,
                                exp_window_decay=exp_window_decay)
    if screening is False:
        accepted = np.ones((test.n_hits, test.n_channels), bool)
        how = "no screening (all hits)"
    else:
        accepted = np.asarray(getattr(screening, "accepted", None))
        if accepted.shape != (test.n_hits, test.n_channels) or tuple(screening.hits) != test.hits \
                or tuple(screening.channels) != test.channel_names:
            raise EstimationError(
                f"{src}: the screening does not belong to this test (hits {tuple(screening.hits)} x "
                f"{len(screening.channels)} channels, test has hits {test.hits} x {test.n_channels})"
            )
        accepted = accepted.astype(bool)
        how = f"screened ({len(screening.rejections)} rejections)"
    level = force_window.level if force_window is not None else 0.05
    if exp_window_decay is None:
        decay = auto_exp_decay(test, accepted=accepted, level=level)
    else:
        decay = float(exp_window_decay)
        if not np.isfinite(decay) or decay < 0:
            raise EstimationError(f"exp_window_decay must be finite and >= 0 1/s, got {exp_window_decay!r}")
    freqs, sff, sfa, saa = _spectra(test, accepted, band_hz, force_window, decay)
    n_avg = accepted.sum(axis=0)
    keep = n_avg > 0
    names = test.channel_names
    for j in np.flatnonzero(~keep):
        log.warning("%s: channel %r has no accepted hit; it is left out of the FRF", src, names[j])
    if not keep.any():
        raise EstimationError(f"{src}: no hit was accepted for any channel; nothing to average")
    with np.errstate(divide="ignore", invalid="ignore"):
        h1 = sfa / sff
        coh = np.abs(sfa) ** 2 / (sff * saa)
        h2 = saa / np.conj(sfa)
    coh = np.clip(np.nan_to_num(coh, nan=0.0), 0.0, 1.0)
    data = (h1 if estimator == "H1" else h2)[keep][:, None, :]
    chans = test.response_channels[keep].reset_index(drop=True)
    for j in np.flatnonzero(keep):
        used = [test.hits[h] for h in np.flatnonzero(accepted[:, j])]
        if len(used) < test.n_hits:
            log.info("%s: channel %r averaged over hits %s", src, names[j], used)
    step = (f"estimate_frf {estimator}: {how}, band {band_hz[0]:g}-{band_hz[1]:g} Hz, "
            f"force window {force_window}, exponential window a={decay:.6g} 1/s, from {src}")
    frf = FrequencyResponse(
        freqs_hz=freqs,
        data=data,
        outputs=tuple(n for n, k in zip(names, keep) if k),
        inputs=(str(test.force_channel["name"]),),
        quantity="accelerance",
        coherence=coh[keep][:, None, :],
        channels=chans,
        exp_window_decay=decay,
        n_averages=n_avg[keep],
        history=tuple(test.history) + (step,),
    )
    log.info("%s: %s FRFs of %d channels, %d lines %g-%g Hz, exponential window a=%.4g 1/s",
             src, estimator, frf.n_out, freqs.size, freqs[0], freqs[-1], decay)
    return frf
