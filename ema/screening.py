"""Hit screening: which hits of which channels may be averaged into an FRF.

A hit is rejected as a whole when its force is unusable, a channel of a hit
when only that channel is; every rejection is a :class:`Rejection` with a
reason from :data:`REASONS` and a human-readable detail, and is logged on the
``"ema"`` logger at WARNING level. Nothing is silently averaged in: the
result's ``accepted`` mask is what :func:`ema.estimate_frf` averages.

Checks (thresholds in :class:`ScreeningConfig`):

``double hit`` (whole hit)
    The force, after the main pulse has returned below ``pulse_level`` x peak,
    exceeds ``double_hit_level`` x peak again (or did so before the main
    pulse) — the hammer bounced. The threshold is also at least
    ``noise_factor`` x the force noise RMS (robust estimate: 1.4826 x the
    median absolute deviation of the record), so noise never triggers it.
``force saturated`` (whole hit)
    The force's extreme value is repeated in at least ``clip_min_samples``
    samples (flat top at the ADC range).
``force not a pulse`` (whole hit)
    The force is not the pulse of a hammer tip: its peak is a single sample
    (both neighbours below ``pulse_level`` x peak — an ADC's anti-aliasing
    filter spreads even the hardest tip's contact over several samples, so
    this is a corrupt sample, e.g. a flipped byte or a wrong byte order), or
    more than ``max_energy_outside`` of the force record's energy lies
    outside the force window around the main pulse (not an impact record).
``pulse too late`` (whole hit)
    The record left after the force pulse is shorter than
    ``min_record_after_share`` x its median over the plausible hits (a late
    trigger, a pre-trigger set wrongly for one hit). The exponential window is
    chosen for the median hit, whose slowest response falls to 1e-4 by the
    record end; a hit with the share ``s`` of that record keeps ``1e-4 ** s``
    there (1e-3 at 3/4), and its leakage would lower every channel's
    coherence, so the channels, not the hit, would be rejected.
``force too weak`` (whole hit)
    Peak force below ``weak_force_ratio`` x the median peak of the plausible
    hits that are not too strong, or below ``min_force_snr`` x the force
    noise RMS.
``force too strong`` (whole hit)
    Peak force above ``strong_force_ratio`` x the median peak of the
    plausible hits: an operator varies hits by a factor of two or three, not
    ten (a corrupt sample or a wrong scale factor).
``struck another point`` (whole hit)
    More than ``max_unexplained_share`` (or :data:`OUTLIER_SPREADS` x the other hits' spread, if larger) of the
    hit's response power (median over the hammer tip's band, on the lines where at least two channels' FRF over the
    other hits is coherent) is not explained by any force at the other hits' point (:func:`force_fit`), beyond what
    the other hits leave: the larger of their median share and the share their noise would leave at this hit's force
    (noise's share falls as the inverse of the force power; the virtual lab's hits follow that law). A force at one
    point gives responses proportional to that point's column of the FRF matrix on every line; a hit at another
    point (a missed notch, a hit on the next mark) or in another direction gives another column, which departs from
    it between the resonances, where the modes mix in other proportions, though not at an isolated resonance, and
    often with a force spectrum as implied: the force check alone can pass it. Averaged in, it would mix two driving
    points into every FRF. A hit whose responses imply a force opposite to the measured one (a point where the
    dominant modes move the other way, or a hit from the other side) is rejected with this reason too. Judged with
    the force check, the worst hit of either first. Measured on the virtual lab's 100 setups (three designs, nine
    scenarios, 500 Hz and 2 kHz truths) the median share lies within 0.03–5.2 % and a hit's excess below 0.27 %; a
    toy hit with one mode's participation zeroed (struck on its nodal line) leaves 4.7 % against 0.9 %, one with a
    mode's sign flipped 90 %; the lab wheelset struck at the next sensor point of its disc rim 51 %, with the blow
    tilted 10° or 20° towards the axle 6.4 % and 6.6 % against 2.3 %.
``force off its responses`` (whole hit)
    The hit's force spectrum differs by more than ``max_force_offset_db`` from the force its own responses imply
    through the other hits' FRF, relative to the other hits' (:func:`force_consistency`, on the hammer tip's
    band and the lines where each channel's FRF is coherent; needs two other hits). A force input overloaded
    before the converter's filter comes out rounded, without the flat top "force saturated" looks for, and with
    less force than the structure received: the hit alone would raise every FRF by the difference. A glancing
    blow (a force the transducer's axis does not see) or a hit at another point does the same. The worst hit is
    rejected first and the others judged again, since a far-off force enters their FRF. The limit grows to
    :data:`OUTLIER_SPREADS` x the other hits' robust spread of the difference where that is larger: a hand-held
    hammer's direction varies from hit to hit, and with it the modes excited through its tilt (3° RMS moves the
    difference by up to ±1.1 dB on the virtual lab's wheelset), so a hit is judged as an outlier among its hits.
    Measured on the virtual lab's 72 setups (358 accepted hits) the differences lie within −0.02…+0.06 dB; a force
    clipped at 0.8, 0.7 and 0.5 of its peak and then filtered gives −1.3, −2.3 and −5.1 dB.
Two hits left (a WARNING, no rejection)
    The force and pattern checks need a third hit to tell which one is off. Of two, the first's FRF over the
    second's (:func:`pair_offset`, on the tip band's lines where both records lie 20 dB above their pre-trigger
    noise) beyond ``max_force_offset_db`` is logged with both hits named, and both are averaged in. Pairs of the
    virtual lab's hits agree within ±0.001 dB (72 pairs); a toy hit's force clipped at 0.7 gives −1.5 dB.
``dead channel`` (one channel of one hit)
    The record is constant (all zeros, say): a disconnected sensor or a
    channel switched off, not an ADC at its range.
``clipped`` (one channel of one hit)
    The channel's extreme value (the largest ``|a|``) is repeated exactly in
    at least ``clip_min_samples`` samples: an ADC held at its range. The range
    is not in the file, so only the data decide. The repeated samples need not
    be consecutive: high-frequency content can leave the rail for a sample
    and return. A genuine peak is a single sample: with 24-bit converters and
    sensor noise, two samples equal to the maximum to the last bit are very
    unlikely (none in the virtual-lab campaigns' ~1400 unclipped records).
``clipped``, a rounded clip (one channel of one hit)
    The channel's peak is below ``min_peak_ratio`` x the peak its own force
    predicts through the H1 of the other accepted hits, taken at the record's
    own scale where the prediction is moderate (:func:`peak_compression`;
    needs two other hits). A signal clipped before the converter's
    anti-aliasing or decimation filter (an analogue input or a sigma-delta
    modulator overloaded) comes out rounded, its flat top gone, so no two
    samples equal; but a structure is linear, so the other hits tell how high
    the peak should have been, and a clip lowers the peak only (a wrong
    sensitivity scales the whole record, and is left to the level checks).
    Measured on the virtual lab's 66 setups (9446 accepted records) the
    compression lies within 0.97–1.07; a record clipped at 0.9, 0.7 and 0.5
    of its peak and then filtered gives 0.91, 0.73 and 0.53. A noisy record
    that does not follow the prediction gets no verdict. The limit falls to
    ``exp(-OUTLIER_SPREADS x`` the other hits' robust spread of the channel's
    log compression``)`` where that is lower: a hand-held hammer's direction
    varies from hit to hit, and the modes its tilt excites with it, which
    spreads the compression to 0.79–1.5 at 3° RMS on the virtual lab's
    wheelset; a clip is then told only as an outlier among the hits.
``clipped``, at one level in every hit (one channel, all hits)
    Over the hits, the channel's peak grows as the peak the other hits' FRF implies for each hit's force to a
    power below ``min_peak_slope`` (:func:`peak_slopes`; a linear record's grows to the power 1): a clip rounded by
    the filter in every hit, which no single hit's comparison sees, since the other hits' prediction is clipped
    too. Needs four hits whose implied peaks span a factor :data:`MIN_PEAK_SPAN`, and the power below the limit
    with 95 % confidence over all the channels judged (Student's t of the fit at 0.05 / channels: a hand-held
    hammer's direction varies from hit to hit, and with it the peak of a channel the tilt-excited modes carry,
    which a 6-hit fit of 29 channels would otherwise call clipped by chance). Measured on the virtual lab's setups
    (747 channels with that span) the power lies within 0.93–1.04; a toy channel clipped at the smallest hit's
    peak, or lower, gives 0.02–0.08 (standard error 0.015–0.023).
``level inconsistent`` (one channel of one hit)
    The channel's response level per unit force (RMS of the record over the
    force pulse's RMS) differs from its median over the hits by more than
    ``max_level_spread`` (a structure is linear: the same hammer point gives
    the same level within the spread of the hits' spectra, a factor of two in
    the virtual lab). Needs three plausible hits.
``level off its neighbours`` (one channel, all hits)
    In the median over the hits, the channel's RMS level differs from the
    median level of its ``n_neighbours`` nearest sensors (by position) by more
    than ``max_neighbour_ratio``: a wrong sensitivity or unit (neighbouring
    sensors of a structure see levels within a decade of each other; a factor
    12 at most in the virtual lab's setups).
``low coherence`` (one channel, all hits)
    After averaging the remaining hits, the channel's coherence is below
    ``min_coherence`` on more than ``max_low_coherence_fraction`` of the band:
    a loose or broken sensor. Needs at least two accepted hits.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy import stats

from .estimate import ForceWindow, _spectra, auto_exp_decay, main_pulse, rest_values
from .estimate import force_window as _pulse_window
from .hammer_io import HammerTest

__all__ = ["ScreeningConfig", "Rejection", "Screening", "screen_hits", "REASONS", "ForceFit", "flat_extreme_count",
           "force_consistency", "force_fit", "pair_offset", "peak_compression", "peak_slopes"]

log = logging.getLogger("ema")

#: The reasons a rejection can have.
REASONS = ("double hit", "force saturated", "force not a pulse", "pulse too late", "force too weak", "force too strong",
           "struck another point", "force off its responses", "dead channel", "clipped", "level inconsistent",
           "level off its neighbours", "low coherence")


@dataclass(frozen=True)
class ScreeningConfig:
    """Thresholds of :func:`screen_hits` (see :mod:`ema.screening`).

    Parameters
    ----------
    pulse_level : float
        Fraction of the peak force delimiting the main pulse.
    double_hit_level : float
        A second excursion above this fraction of the peak force is a double hit.
    noise_factor : float
        Thresholds are at least this many force-noise RMS.
    weak_force_ratio : float
        A peak force below this fraction of the median peak is too weak.
    strong_force_ratio : float
        A peak force above this multiple of the median peak is too strong.
    max_energy_outside : float
        Largest fraction of the force energy outside the main pulse's window.
    min_record_after_share : float
        Shortest record after the pulse, as a share of its median over the hits.
    max_level_spread : float
        Largest factor between a channel's level per unit force in one hit and its median over the hits.
    max_neighbour_ratio : float
        Largest factor between a channel's level and the median level of its nearest sensors.
    n_neighbours : int
        Sensors compared with (nearest by position).
    min_force_snr : float
        A peak force below this many force-noise RMS is too weak.
    clip_min_samples : int
        Samples at the extreme value that make a channel (or the force) clipped.
    min_peak_ratio : float
        A channel's peak below this share of the peak the other hits' FRF predicts for the hit's force is clipped
        (or below ``exp(-OUTLIER_SPREADS x`` the other hits' robust spread of its log``)``, if lower).
    min_peak_slope : float
        A channel whose peak grows over the hits as the peak their forces imply to a power below this is clipped
        in every hit.
    max_force_offset_db : float
        Largest difference [dB] between a hit's force spectrum and the one its responses imply through the other
        hits' FRF (the error the hit would put into every FRF), or :data:`OUTLIER_SPREADS` x the other hits'
        robust spread of it, if larger.
    max_unexplained_share : float
        Largest share of a hit's response power (median over the tip band's lines) that no force at the other
        hits' point explains, beyond what the other hits leave (``struck another point`` in the module docstring),
        or :data:`OUTLIER_SPREADS` x their robust spread of it, if larger.
    min_coherence : float
        Coherence below this is "low".
    max_low_coherence_fraction : float
        A channel with low coherence on more than this fraction of the band is rejected.
    check_coherence : bool
        Run the coherence check.
    """

    pulse_level: float = 0.05
    double_hit_level: float = 0.10
    noise_factor: float = 10.0
    weak_force_ratio: float = 0.2
    strong_force_ratio: float = 10.0
    max_energy_outside: float = 0.5
    min_record_after_share: float = 0.75
    max_level_spread: float = 10.0
    max_neighbour_ratio: float = 100.0
    n_neighbours: int = 4
    min_force_snr: float = 100.0
    clip_min_samples: int = 2
    min_peak_ratio: float = 0.8
    min_peak_slope: float = 0.5
    max_force_offset_db: float = 1.0
    max_unexplained_share: float = 0.03
    min_coherence: float = 0.8
    max_low_coherence_fraction: float = 0.5
    check_coherence: bool = True

    def __post_init__(self) -> None:
        for name in ("strong_force_ratio", "max_level_spread", "max_neighbour_ratio"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 1):
                raise ValueError(f"ScreeningConfig.{name} must be a finite factor > 1, got {v!r}")
        if int(self.n_neighbours) != self.n_neighbours or self.n_neighbours < 1:
            raise ValueError(f"ScreeningConfig.n_neighbours must be an integer >= 1, got {self.n_neighbours!r}")
        for name in ("pulse_level", "double_hit_level", "weak_force_ratio", "min_coherence",
                     "max_low_coherence_fraction", "max_energy_outside", "min_record_after_share",
                     "min_peak_ratio", "min_peak_slope", "max_unexplained_share"):
            v = getattr(self, name)
            if not 0 <= v <= 1:
                raise ValueError(f"ScreeningConfig.{name} must be in [0, 1], got {v!r}")
        if not self.double_hit_level > self.pulse_level:
            raise ValueError(
                f"ScreeningConfig.double_hit_level ({self.double_hit_level}) must exceed pulse_level "
                f"({self.pulse_level})"
            )
        if not (np.isfinite(self.max_force_offset_db) and self.max_force_offset_db > 0):
            raise ValueError(f"ScreeningConfig.max_force_offset_db must be a finite level > 0 dB, got "
                             f"{self.max_force_offset_db!r}")
        if not (self.noise_factor >= 0 and self.min_force_snr >= 0):
            raise ValueError("ScreeningConfig.noise_factor and min_force_snr must be >= 0")
        if int(self.clip_min_samples) != self.clip_min_samples or self.clip_min_samples < 2:
            raise ValueError(f"ScreeningConfig.clip_min_samples must be an integer >= 2, got {self.clip_min_samples!r}")


@dataclass(frozen=True)
class Rejection:
    """One rejected hit, channel of a hit, or channel.

    Parameters
    ----------
    hit : int or None
        Hit number; None for a channel rejected in every hit (low coherence).
    channel : str or None
        Channel name; None when the whole hit is rejected.
    node : int or None
        The channel's node (None with ``channel``).
    reason : str
        One of :data:`REASONS`.
    detail : str
        What was measured, in words and numbers.
    """

    hit: int | None
    channel: str | None
    node: int | None
    reason: str
    detail: str

    def __str__(self) -> str:
        what = f"hit {self.hit}" if self.channel is None else (
            f"channel {self.channel!r} (node {self.node})" + ("" if self.hit is None else f" in hit {self.hit}")
            + (" in every hit" if self.hit is None else ""))
        return f"{what} rejected ({self.reason}): {self.detail}"


@dataclass(frozen=True, eq=False)
class Screening:
    """The outcome of :func:`screen_hits`.

    Parameters
    ----------
    hits : tuple of int
        The test's hit numbers (rows of ``accepted``).
    channels : tuple of str
        The test's response channel names (columns of ``accepted``).
    accepted : ndarray bool (n_hits, n_ch)
        True where the hit may be averaged into the channel's FRF.
    rejections : tuple of Rejection
    config : ScreeningConfig
    source : str
    """

    hits: tuple[int, ...]
    channels: tuple[str, ...]
    accepted: np.ndarray
    rejections: tuple[Rejection, ...]
    config: ScreeningConfig = field(default_factory=ScreeningConfig)
    source: str = ""

    def __post_init__(self) -> None:
        acc = np.array(self.accepted, dtype=bool)
        if acc.shape != (len(self.hits), len(self.channels)):
            raise ValueError(f"accepted must be ({len(self.hits)}, {len(self.channels)}), got {acc.shape}")
        acc.setflags(write=False)
        object.__setattr__(self, "accepted", acc)
        object.__setattr__(self, "rejections", tuple(self.rejections))

    @property
    def rejected_hits(self) -> tuple[int, ...]:
        """Hits rejected as a whole."""
        return tuple(sorted({r.hit for r in self.rejections if r.channel is None}))

    @property
    def clipped(self) -> tuple[tuple[int, str], ...]:
        """(hit, channel) pairs rejected because the channel clipped."""
        return tuple((r.hit, r.channel) for r in self.rejections if r.reason == "clipped")

    def accepted_hits(self, channel: str) -> tuple[int, ...]:
        """Hits averaged into ``channel``."""
        if channel not in self.channels:
            raise KeyError(f"unknown channel {channel!r}; channels: {list(self.channels)}")
        j = self.channels.index(channel)
        return tuple(h for h, a in zip(self.hits, self.accepted[:, j]) if a)

    def to_frame(self) -> pd.DataFrame:
        """One row per rejection: ``hit, channel, node, reason, detail``."""
        return pd.DataFrame([r.__dict__ for r in self.rejections], columns=["hit", "channel", "node", "reason", "detail"])

    def __repr__(self) -> str:
        return (f"Screening({len(self.hits)} hits x {len(self.channels)} channels, "
                f"{int(self.accepted.sum())} cells accepted, {len(self.rejections)} rejections)")


def flat_extreme_count(x: np.ndarray) -> tuple[int, float]:
    """Samples sitting exactly at the record's extreme value.

    For each rail (the maximum and the minimum) whose magnitude is within
    0.1 % of ``max |x|``, count the samples equal to it; return the larger
    count and that value. A genuine peak gives 1; an ADC held at its range
    gives one per saturated sample.
    """
    x = np.asarray(x)
    hi, lo = float(x.max()), float(x.min())
    ext = max(abs(hi), abs(lo))
    best = (0, ext)
    for v in (hi, lo):
        if abs(v) >= (1 - 1e-3) * ext:
            c = int(np.count_nonzero(x == v))
            if c > best[0]:
                best = (c, v)
    return best


#: a record whose moderate part correlates less than this with the other hits' prediction gets no clip verdict
MIN_PREDICTION_CORRELATION = 0.9


def peak_compression(test: HammerTest, accepted: np.ndarray, f_rest: np.ndarray, a_rest: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
    """How much each accepted record's peak falls short of the peak its force predicts through the other hits' H1.

    For channel ``j`` and hit ``h``: ``H = Σ_k F_k* A_k / Σ_k |F_k|²`` over the channel's other accepted hits
    ``k`` (whole records about their rest values, every line) and the prediction ``p = irfft(H F_h)``. The
    compression is the ratio of the record's largest ``|a|`` to the prediction's, over the record's scale where
    the prediction is moderate (the least-squares ``a ≈ s p`` on the samples with ``|p|`` between 5 % and 50 % of
    its peak). A clip lowers the peak only, so its compression is below 1; a wrong sensitivity scales the whole
    record alike, and a clean record follows the prediction: both near 1. Returns ``(compression, predicted peak)``,
    ``(n_hits, n_ch)``, NaN where the channel has fewer than three accepted hits, the cell is not accepted, or the
    record does not follow the prediction there (correlation below :data:`MIN_PREDICTION_CORRELATION`: a noisy or
    broken channel, which the coherence check judges).
    """
    n = test.n_samples
    compression = np.full(accepted.shape, np.nan)
    predicted = np.full(accepted.shape, np.nan)
    F = np.fft.rfft(test.force - f_rest[:, None], axis=1)
    for j in range(test.n_channels):
        hs = np.flatnonzero(accepted[:, j])
        if hs.size < 3:
            continue
        a = test.responses[hs, j] - a_rest[hs, j][:, None]
        A = np.fft.rfft(a, axis=1)
        Fh = F[hs]
        cross, power = Fh.conj() * A, np.abs(Fh) ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            H = np.nan_to_num((cross.sum(axis=0) - cross) / (power.sum(axis=0) - power))
        pred = np.fft.irfft(H * Fh, n, axis=1)
        peak = np.abs(pred).max(axis=1)
        mid = (np.abs(pred) >= 0.05 * peak[:, None]) & (np.abs(pred) <= 0.5 * peak[:, None])
        ap = np.sum(np.where(mid, a * pred, 0.0), axis=1)
        pp = np.sum(np.where(mid, pred ** 2, 0.0), axis=1)
        aa = np.sum(np.where(mid, a ** 2, 0.0), axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            scale = ap / pp
            c = np.abs(a).max(axis=1) / peak / scale
            follows = ap / np.sqrt(pp * aa) >= MIN_PREDICTION_CORRELATION
        compression[hs, j] = np.where((mid.sum(axis=1) >= 16) & follows, c, np.nan)
        predicted[hs, j] = peak * scale
    return compression, predicted


#: a channel's implied peaks must span at least this factor over its hits for a verdict on how its peak grows
MIN_PEAK_SPAN = 1.25
#: fewest hits for that verdict (each hit's prediction then comes from three others or more)
MIN_SLOPE_HITS = 4


def peak_slopes(accepted: np.ndarray, predicted: np.ndarray, measured: np.ndarray, limit: float
                ) -> list[tuple[int, float, float, float]]:
    """The channels whose peak does not grow with the peak the other hits' FRF implies for each hit's force.

    Per channel, over its accepted hits with a prediction (:func:`peak_compression`), the least-squares slope of
    ``log(measured peak)`` on ``log(implied peak)``: 1 for a linear record, near 0 for one held at a level in
    every hit (a clip rounded by the converter's filter, which no single hit's comparison sees, since the other
    hits' prediction is clipped too). Needs :data:`MIN_SLOPE_HITS` such hits whose implied peaks span
    :data:`MIN_PEAK_SPAN`; the slope must be below the limit with 95 % confidence over the channels judged
    (``slope + t·se < limit``, Student's t at ``1 - 0.05 / channels`` with the fit's degrees of freedom).

    Returns
    -------
    list of (channel index, slope, smallest and largest implied peak), for the slopes below ``limit``.
    """
    fits = []
    for j in range(accepted.shape[1]):
        hs = accepted[:, j] & np.isfinite(predicted[:, j]) & (predicted[:, j] > 0) & (measured[:, j] > 0)
        if hs.sum() < MIN_SLOPE_HITS:
            continue
        lp, lm = np.log(predicted[hs, j]), np.log(measured[hs, j])
        if lp.max() - lp.min() < np.log(MIN_PEAK_SPAN):
            continue
        slope, intercept = np.polyfit(lp, lm, 1)
        rss = float(np.sum((lm - slope * lp - intercept) ** 2))
        se = np.sqrt(rss / (lp.size - 2) / np.sum((lp - lp.mean()) ** 2))
        fits.append((j, float(slope), float(se), lp.size - 2, float(np.exp(lp.min())), float(np.exp(lp.max()))))
    # a verdict only where the slope is below the limit with 95 % confidence over every channel judged: hit-to-hit
    # scatter (the hammer's direction, noise) spreads a channel's peaks without the forces spreading
    alpha = 0.05 / max(len(fits), 1)
    return [(j, slope, lo, hi) for j, slope, se, dof, lo, hi in fits
            if slope + float(stats.t.ppf(1.0 - alpha, dof)) * se < limit]


#: a force record is compared with the responses' prediction on the lines where the other hits' force spectrum is
#: within this share of its largest power (-20 dB: the hammer tip's usable band, beyond which H is noise)
TIP_BAND_POWER = 1e-2
#: a channel's line enters the implied force where its coherence over the other hits is at least this
MIN_LINE_COHERENCE = 0.9
#: fewest lines of the tip's band with a known FRF for a verdict
MIN_TIP_LINES = 16


def _force_spectra(test: HammerTest, f_rest: np.ndarray, rows: np.ndarray
                   ) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """The spectra of the hits ``rows``' forces about their rest values through the default force window (which
    keeps the force noise after the pulse out of them, as in the estimate), and each main pulse's start and end."""
    n = test.n_samples
    pulses, windows = [], []
    for h in rows:
        start, _, end, _ = main_pulse(test.force[h])
        pulses.append((start, end))
        windows.append(_pulse_window(n, test.fs, start, end, ForceWindow()))
    return np.fft.rfft((test.force[rows] - f_rest[rows, None]) * np.array(windows), axis=1), pulses


@dataclass(frozen=True)
class ForceFit:
    """Each hit against the force its own responses imply through the other hits' FRF (:func:`force_fit`).

    Parameters
    ----------
    ratio : ndarray (n_hits,)
        ``Re Σ F̂* F_h / Σ |F̂|²`` over the tip's band: the hit's force spectrum over the one its responses imply,
        relative to the median of the other hits' (force noise biases every hit's alike). The hit's FRF is off
        from the others' by ``1 / ratio`` on every channel.
    peak_ratio : ndarray (n_hits,)
        The largest ``|f|`` of the force over the implied force's, both taken back to time on the tip's band,
        relative to the other hits' likewise.
    unexplained : ndarray (n_hits,)
        On the tip band's lines where at least two channels' FRF is coherent, the share of the hit's response
        power ``Σ_j |A_hj - H_j F̂|² / Σ_j |A_hj|²`` that no force at the other hits' point explains: its median
        over the lines. A force applied at one point gives responses proportional to that point's FRF column on
        every line, so only noise is left; a force at another point gives another column, which departs from it
        between the resonances, where the modes mix in other proportions.
    tip_power : ndarray (n_hits,)
        The hit's force power ``|F_h|²`` on those lines (median): the noise's part of ``unexplained`` falls as its
        inverse.
    """

    ratio: np.ndarray
    peak_ratio: np.ndarray
    unexplained: np.ndarray
    tip_power: np.ndarray


def force_fit(test: HammerTest, accepted: np.ndarray, f_rest: np.ndarray, a_rest: np.ndarray) -> ForceFit:
    """How each hit's force and response pattern compare with its own responses through the other hits' H1.

    For hit ``h``: per channel ``H_j = Σ_k F_k* A_kj / Σ_k |F_k|²`` over the channel's other accepted hits ``k``
    (records about their rest values, the force through the default force window); the force the responses
    imply, the least-squares solution over the channels accepted in ``h``, ``F̂ = Σ_j H_j* A_hj / Σ_j |H_j|²``,
    on the lines of the hammer tip's band (the other hits' force power within :data:`TIP_BAND_POWER` of its
    largest), each channel only where its coherence over the other hits is at least :data:`MIN_LINE_COHERENCE`
    (elsewhere its FRF is noise, and so would be the force it implies). A structure is linear and the force
    point the same, so ``F̂ = F_h`` and ``A_h = H F̂`` up to noise (see :class:`ForceFit` for what is returned).

    Every field is NaN (no verdict) for a hit without two other accepted hits on one of its channels, with fewer
    than :data:`MIN_TIP_LINES` lines of the tip's band where a channel's FRF is coherent (two channels for
    ``unexplained``), or with fewer than three accepted hits in all.
    """
    n = test.n_samples
    ratio = np.full(test.n_hits, np.nan)
    peak_ratio = np.full(test.n_hits, np.nan)
    unexplained = np.full(test.n_hits, np.nan)
    tip_power = np.full(test.n_hits, np.nan)
    hit_ok = accepted.any(axis=1)
    if np.count_nonzero(hit_ok) < 3:
        return ForceFit(ratio, peak_ratio, unexplained, tip_power)
    F, _ = _force_spectra(test, f_rest, np.arange(test.n_hits))
    A = np.fft.rfft(test.responses - a_rest[:, :, None], axis=2)
    power = np.abs(F) ** 2
    # sums over every usable hit, from which each hit's own term is taken out (leave one out)
    a = accepted.astype(float) * hit_ok[:, None]
    cross_all = np.einsum("kf,kj,kjf->jf", F.conj(), a, A)
    pf_all = a.T @ power
    pa_all = np.einsum("kj,kjf->jf", a, np.abs(A) ** 2)
    po_all = power[hit_ok].sum(axis=0)
    count = a.sum(axis=0)
    for h in np.flatnonzero(hit_ok):
        chans = np.flatnonzero(accepted[h] & (count - a[h] >= 2))
        if chans.size == 0:
            continue
        Ah = A[h, chans]
        with np.errstate(divide="ignore", invalid="ignore"):
            cross = cross_all[chans] - F[h].conj() * Ah
            pf = pf_all[chans] - power[h]
            pa = pa_all[chans] - np.abs(Ah) ** 2
            H = np.nan_to_num(cross / pf)
            # only the lines where a channel's FRF is known: its coherence over the other hits
            w = np.nan_to_num(np.abs(cross) ** 2 / (pf * pa)) >= MIN_LINE_COHERENCE
            implied = np.nan_to_num(np.einsum("jf,jf,jf->f", w, H.conj(), Ah)
                                    / np.einsum("jf,jf->f", w, np.abs(H) ** 2))
        po = po_all - power[h]
        tip = (po >= TIP_BAND_POWER * po[1:].max()) & w.any(axis=0)
        tip[0] = False  # the mean is the rest value's, not the pulse's
        if np.count_nonzero(tip) < MIN_TIP_LINES:
            continue
        ratio[h] = float(np.real(np.sum(implied[tip].conj() * F[h, tip])) / np.sum(np.abs(implied[tip]) ** 2))
        f = np.fft.irfft(np.where(tip, F[h], 0.0), n)
        pred = np.fft.irfft(np.where(tip, implied, 0.0), n)
        peak_ratio[h] = float(np.abs(f).max() / np.abs(pred).max())
        # one channel's line is fitted exactly by any force: the pattern needs two
        pattern = tip & (w.sum(axis=0) >= 2)
        if np.count_nonzero(pattern) >= MIN_TIP_LINES:
            wp, Ap = w[:, pattern], Ah[:, pattern]
            resid = np.einsum("jf,jf->f", wp, np.abs(Ap - H[:, pattern] * implied[pattern]) ** 2)
            total = np.einsum("jf,jf->f", wp, np.abs(Ap) ** 2)
            unexplained[h] = float(np.median(resid / total))
            tip_power[h] = float(np.median(power[h, pattern]))
    # each hit against the others: a bias common to every hit (force noise lowers every H1 alike) is no verdict
    out = []
    for x in (ratio, peak_ratio):
        ref = np.array([np.nanmedian(np.delete(x, h)) if np.isfinite(np.delete(x, h)).any() else np.nan
                        for h in range(x.size)])
        out.append(x / ref)
    return ForceFit(out[0], out[1], unexplained, tip_power)


def force_consistency(test: HammerTest, accepted: np.ndarray, f_rest: np.ndarray, a_rest: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Each hit's force over the force its own responses imply: ``ratio, peak_ratio`` of :func:`force_fit`."""
    fit = force_fit(test, accepted, f_rest, a_rest)
    return fit.ratio, fit.peak_ratio


#: fewest pre-trigger samples for a record's noise level (two hits are compared on lines above it)
MIN_NOISE_SAMPLES = 64
#: a line enters the comparison of two hits where both records' power is this far above their noise (20 dB)
PAIR_SNR = 100.0


def pair_offset(test: HammerTest, accepted: np.ndarray, f_rest: np.ndarray, a_rest: np.ndarray
                ) -> tuple[tuple[int, int], float] | None:
    """Of a test with exactly two accepted hits, the first's FRF over the second's, on the tip's band.

    The least-squares ``r`` of ``A_1 F_2 = r A_2 F_1`` (``H_1 = r H_2`` without dividing by a force line near a
    zero of its spectrum) over the channels accepted in both and the lines of both forces' tip band
    (:data:`TIP_BAND_POWER`) where both records lie :data:`PAIR_SNR` above their noise (each record's pre-trigger
    variance, white, as the power of a line of the whole record): with one other hit the coherence is 1 on every
    line and cannot tell signal from noise. Returns the two hits' rows and the ratio, or None without two hits, a
    pre-trigger of :data:`MIN_NOISE_SAMPLES` or :data:`MIN_TIP_LINES` such lines.
    """
    rows = np.flatnonzero(accepted.any(axis=1))
    if rows.size != 2:
        return None
    chans = np.flatnonzero(accepted[rows].all(axis=0))
    F, pulses = _force_spectra(test, f_rest, rows)
    A, ok = [], []
    for h, (start, end) in zip(rows, pulses):
        stop = start - (end - start + 1)
        if stop < MIN_NOISE_SAMPLES or chans.size == 0:
            return None
        a = test.responses[h, chans] - a_rest[h, chans][:, None]
        noise = test.n_samples * np.var(a[:, :stop], axis=1)
        A.append(np.fft.rfft(a, axis=1))
        ok.append(np.abs(A[-1]) ** 2 >= PAIR_SNR * noise[:, None])
    power = np.abs(F[0]) ** 2 + np.abs(F[1]) ** 2
    tip = power >= TIP_BAND_POWER * power[1:].max()
    tip[0] = False
    w = ok[0] & ok[1] & tip[None, :]
    if np.count_nonzero(w.any(axis=0)) < MIN_TIP_LINES:
        return None
    # H_1 / H_2 = A_1 F_2 / (A_2 F_1), fitted without dividing by a force line near a zero of its spectrum
    x, y = A[1] * F[0][None, :], A[0] * F[1][None, :]
    ratio = float(np.real(np.sum(w * x.conj() * y)) / np.sum(w * np.abs(x) ** 2))
    return (int(rows[0]), int(rows[1])), ratio


#: a hit is off the others when beyond this many times their robust spread (1.4826 x median absolute deviation)
OUTLIER_SPREADS = 3.0


def _outlier_limits(x: np.ndarray, floor: float) -> np.ndarray:
    """Per hit, the larger of ``floor`` and :data:`OUTLIER_SPREADS` x the robust spread of the other hits' finite
    ``x`` (the floor alone with fewer than three of them)."""
    out = np.full(x.size, float(floor))
    for h in range(x.size):
        o = np.delete(x, h)
        o = o[np.isfinite(o)]
        if o.size >= 3:
            out[h] = max(floor, OUTLIER_SPREADS * 1.4826 * float(np.median(np.abs(o - np.median(o)))))
    return out


def _limit_text(value: float, floor: float, unit: str, scale: float = 1.0) -> str:
    """A limit for a message: ``value`` (x ``scale``) in ``unit``, said to be the hits' spread when above ``floor``."""
    spread = f", {OUTLIER_SPREADS:g} x the other hits' spread" if value > floor else ""
    return f"limit {scale * value:.3g}{unit}{spread}"


def _db_move(ratio: float) -> str:
    """The level change ``1 / ratio`` puts into an FRF, in words."""
    return f"{-20 * np.log10(ratio):+.1f} dB" if ratio > 0 else "its sign"


def _robust_rms(x: np.ndarray) -> float:
    med = np.median(x)
    return float(1.4826 * np.median(np.abs(x - med)))


def _nearest_sensors(channels: pd.DataFrame, k: int) -> list[np.ndarray]:
    """For each response channel the indices of its ``k`` nearest sensors by position (all others without positions)."""
    n = len(channels)
    xyz = channels[["x", "y", "z"]].to_numpy(float) if {"x", "y", "z"} <= set(channels.columns) else np.full((n, 3),
                                                                                                              np.nan)
    out = []
    for j in range(n):
        others = np.array([i for i in range(n) if i != j], int)
        if np.all(np.isfinite(xyz)) and others.size:
            d = np.linalg.norm(xyz[others] - xyz[j], axis=1)
            others = others[np.argsort(d, kind="stable")[:k]]
        out.append(others)
    return out


#: a record offset above this share of its RMS about the offset is named (a DC-coupled sensor, gravity)
OFFSET_WARN_SHARE = 0.1


def _report_offsets(test: HammerTest, off: np.ndarray, level: np.ndarray) -> None:
    """A WARNING naming the channels whose DC offset ``off (n_hits, n_ch)`` (:func:`ema.estimate.rest_values`)
    exceeds :data:`OFFSET_WARN_SHARE` of the record's RMS ``level`` about it in any hit; the spectra are taken
    about it."""
    with np.errstate(divide="ignore", invalid="ignore"):
        share = np.abs(off) / level
    big = np.flatnonzero(np.any(share > OFFSET_WARN_SHARE, axis=0))
    if big.size:
        names = test.channel_names
        log.warning("screening %s: %d channel(s) carry a DC offset (median over the hits, m/s^2): %s; a DC-coupled "
                    "accelerometer (gravity) or a bias; the spectra and levels are taken about it", test.source
                    or "hammer test", big.size, ", ".join(f"{names[j]} {np.median(off[:, j]):+.4g}" for j in big[:10])
                    + (f" and {big.size - 10} more" if big.size > 10 else ""))


def _check_levels(test: HammerTest, cfg: ScreeningConfig, accepted: np.ndarray, pulse_rms: np.ndarray,
                  level: np.ndarray, reject) -> None:
    """The level checks of :func:`screen_hits` (``level inconsistent``, ``level off its neighbours``) on ``level``
    (hits, channels), each record's RMS about its rest value [m/s^2]; edits ``accepted``."""
    names = test.channel_names
    hit_ok = accepted.any(axis=1) & (pulse_rms > 0)
    # per unit force, the same channel from hit to hit (a linear structure, one hammer point)
    if hit_ok.sum() >= 3:
        with np.errstate(divide="ignore", invalid="ignore"):
            per_force = level / pulse_rms[:, None]
        for j in range(test.n_channels):
            use = hit_ok & accepted[:, j] & np.isfinite(per_force[:, j]) & (per_force[:, j] > 0)
            if use.sum() < 3:
                continue
            med = float(np.median(per_force[use, j]))
            for h in np.flatnonzero(use):
                r = per_force[h, j] / med
                if not 1 / cfg.max_level_spread <= r <= cfg.max_level_spread:
                    reject(test.hits[h], j, "level inconsistent",
                           f"response level per unit force {r:.3g} x the channel's median over the hits (limit "
                           f"{cfg.max_level_spread:g} x either way): a corrupt record (spike, wrong byte order?)")
                    accepted[h, j] = False
    # against the neighbouring sensors, in the same hits
    if test.n_channels < 2:
        return
    nb = _nearest_sensors(test.response_channels, int(cfg.n_neighbours))
    ratios = np.full(test.n_channels, np.nan)
    for j in range(test.n_channels):
        rows = np.flatnonzero(accepted[:, j] & hit_ok)
        if rows.size == 0:
            continue
        with np.errstate(divide="ignore", invalid="ignore"):
            ref = np.median(level[np.ix_(rows, nb[j])], axis=1)
            r = level[rows, j] / ref
        r = r[np.isfinite(r) & (r > 0)]
        if r.size:
            ratios[j] = float(np.median(r))
    for j in np.flatnonzero(np.isfinite(ratios)):
        r = ratios[j]
        if not 1 / cfg.max_neighbour_ratio <= r <= cfg.max_neighbour_ratio:
            near = ", ".join(names[i] for i in nb[j])
            reject(None, j, "level off its neighbours",
                   f"RMS level {r:.3g} x the median of its {len(nb[j])} nearest sensors ({near}) over the hits "
                   f"(limit {cfg.max_neighbour_ratio:g} x either way): a wrong sensitivity or unit?")
            accepted[:, j] = False


def screen_hits(
    test: HammerTest,
    *,
    config: ScreeningConfig | None = None,
    band_hz: tuple[float, float] = (10.0, 500.0),
    force_window: ForceWindow | None = ForceWindow(),
    exp_window_decay: float | None = None,
) -> Screening:
    """Screen the hits of a hammer test (see :mod:`ema.screening` for the checks).

    Parameters
    ----------
    test : HammerTest
    config : ScreeningConfig, optional
        Thresholds; defaults as documented in :class:`ScreeningConfig`.
    band_hz, force_window, exp_window_decay
        Band and windows of the coherence check (as in :func:`ema.estimate_frf`).

    Returns
    -------
    Screening
        The accepted hit x channel mask and the rejections, each also logged
        (logger ``"ema"``, WARNING) with its reason.
    """
    cfg = ScreeningConfig() if config is None else config
    src = test.source or "hammer test"
    names = test.channel_names
    nodes = tuple(int(n) for n in test.response_channels["node"])
    accepted = np.ones((test.n_hits, test.n_channels), bool)
    rejections: list[Rejection] = []

    def reject(hit, j, reason, detail):
        r = Rejection(hit, None if j is None else names[j], None if j is None else nodes[j], reason, detail)
        rejections.append(r)
        log.warning("screening %s: %s", src, r)

    # ---- force plausibility (whole hits): a hammer pulse, not a corrupt sample
    n = test.n_samples
    pulses = [main_pulse(test.force[h], cfg.pulse_level) for h in range(test.n_hits)]
    peaks = np.array([abs(test.force[h][p[1]]) for h, p in enumerate(pulses)])
    pulse_rms = np.zeros(test.n_hits)
    plausible = np.ones(test.n_hits, bool)
    for h, hit in enumerate(test.hits):
        f = test.force[h]
        start, ip, end, sign = pulses[h]
        w = _pulse_window(n, test.fs, start, end, ForceWindow(level=cfg.pulse_level))
        inside = float(np.sum((f * w) ** 2))
        total = float(np.sum(f ** 2))
        pulse_rms[h] = np.sqrt(inside / max(np.count_nonzero(w), 1))
        if start == end:
            nb = [abs(f[k]) for k in (ip - 1, ip + 1) if 0 <= k < n]
            reject(hit, None, "force not a pulse",
                   f"the force peak {f[ip]:.4g} N at sample {ip} (t = {test.time[ip]:.6g} s) is a single sample, its "
                   f"neighbours {max(nb) if nb else 0.0:.3g} N; an ADC's anti-aliasing filter spreads any hammer "
                   f"pulse over several samples: a corrupt sample (flipped byte, wrong byte order?)")
            plausible[h] = False
        elif total > 0 and 1 - inside / total > cfg.max_energy_outside:
            reject(hit, None, "force not a pulse",
                   f"{100 * (1 - inside / total):.0f} % of the force energy lies outside the main pulse at "
                   f"t = {test.time[ip]:.6g} s (limit {100 * cfg.max_energy_outside:g} %): not an impact record")
            plausible[h] = False
        if not plausible[h]:
            accepted[h] = False

    # ---- the record after the pulse (whole hits), against the plausible hits' median
    after = test.time[-1] - test.time[[p[0] for p in pulses]]
    if plausible.any():
        median_after = float(np.median(after[plausible]))
        for h in np.flatnonzero(plausible & (after < cfg.min_record_after_share * median_after)):
            reject(test.hits[h], None, "pulse too late",
                   f"the force pulse at t = {test.time[pulses[h][0]]:.4g} s leaves {after[h]:.3g} s of the record, "
                   f"the other hits' median {median_after:.3g} s (limit {cfg.min_record_after_share:g} x): the "
                   "response is cut before the exponential window has taken it down (a late trigger?)")
            plausible[h] = accepted[h] = False

    # ---- force checks (whole hits); sizes against the median peak of the plausible hits, the weak test
    # against the hits that are not too strong (one corrupt giant must not make every other hit "weak")
    median_all = float(np.median(peaks[plausible])) if plausible.any() else 0.0
    strong = plausible & (peaks > cfg.strong_force_ratio * median_all)
    median_peak = float(np.median(peaks[plausible & ~strong])) if (plausible & ~strong).any() else median_all
    for h, hit in enumerate(test.hits):
        if not plausible[h]:
            continue
        f = test.force[h]
        start, ip, end, sign = pulses[h]
        peak = peaks[h]
        noise = _robust_rms(f)
        reasons = []
        thr = max(cfg.double_hit_level * peak, cfg.noise_factor * noise)
        outside = sign * f > thr
        outside[start:end + 1] = False
        if outside.any():
            k = int(np.flatnonzero(outside)[np.argmax((sign * f)[outside])])
            dt_ms = (k - ip) / test.fs * 1e3
            single = (k == 0 or sign * f[k - 1] <= thr) and (k == n - 1 or sign * f[k + 1] <= thr)
            reasons.append(("double hit", f"second force pulse of {sign * f[k]:.4g} N ({100 * sign * f[k] / peak:.0f} % "
                            f"of the {peak:.4g} N peak) {dt_ms:+.2f} ms from the main pulse"
                            + (" (a single sample: a corrupt sample?)" if single else "")))
        n_flat, v = flat_extreme_count(f)
        if n_flat >= cfg.clip_min_samples:
            reasons.append(("force saturated", f"{n_flat} force samples flat at {v:.6g} N"))
        if not strong[h] and (peak < cfg.weak_force_ratio * median_peak or peak < cfg.min_force_snr * noise):
            reasons.append(("force too weak", f"peak {peak:.4g} N vs median peak {median_peak:.4g} N of the hits "
                            f"(limit {cfg.weak_force_ratio:g} x) and noise RMS {noise:.3g} N (limit "
                            f"{cfg.min_force_snr:g} x)"))
        if strong[h]:
            reasons.append(("force too strong", f"peak {peak:.4g} N is {peak / median_all:.3g} x the median peak "
                            f"{median_all:.4g} N of the hits (limit {cfg.strong_force_ratio:g} x): a corrupt sample "
                            f"or a wrong scale factor"))
        for reason, detail in reasons:
            reject(hit, None, reason, detail)
        if reasons:
            accepted[h] = False

    # ---- dead and clipped channels (per hit and channel)
    for h, hit in enumerate(test.hits):
        for j in range(test.n_channels):
            x = test.responses[h, j]
            lo, hi = float(x.min()), float(x.max())
            if lo == hi:
                reject(hit, j, "dead channel", f"all {x.size} samples are {lo:.6g} m/s^2 (a constant record): "
                                               f"sensor disconnected or channel off")
                accepted[h, j] = False
                continue
            n_flat, v = flat_extreme_count(x)
            if n_flat >= cfg.clip_min_samples:
                reject(hit, j, "clipped", f"{n_flat} samples flat at {v:.6g} m/s^2, the record's extreme "
                                          f"(ADC range reached)")
                accepted[h, j] = False

    # ---- DC offsets (named, not rejected: the spectra and levels are taken about them)
    f_rest, rest = rest_values(test, cfg.pulse_level, pulses=pulses)
    with np.errstate(over="ignore", invalid="ignore"):
        level = np.sqrt(np.mean(np.square(test.responses - rest[:, :, None]), axis=2))
    _report_offsets(test, rest, level)

    # ---- the force against the one its responses imply (whole hits); first, so that a wrong force does not
    # enter the other hits' FRF in the responses' test below
    # one hit at a time, the worst first: a hit whose force is far off enters the others' FRF and moves theirs
    while True:
        fit = force_fit(test, accepted, f_rest, rest)
        f_ratio, f_peak = fit.ratio, fit.peak_ratio
        with np.errstate(divide="ignore", invalid="ignore"):
            # no verdict (NaN) is no offset; a force opposite to the one implied is as far off as can be
            off = np.where(np.isnan(f_ratio), 0.0, np.where(f_ratio > 0, np.abs(20 * np.log10(f_ratio)), np.inf))
        # noise leaves a share in every hit, as the inverse of its force power: a hit is judged beyond the larger of
        # the others' median share and the one their noise would leave at its force
        u, noise = fit.unexplained, fit.unexplained * fit.tip_power
        excess = np.full(u.size, np.nan)
        for k in range(u.size):
            o, on = np.delete(u, k), np.delete(noise, k)
            if np.isfinite(o).any():
                excess[k] = u[k] - max(np.nanmedian(o), np.nanmedian(on) / fit.tip_power[k])
        excess = np.nan_to_num(excess, nan=0.0)
        # a hit is an outlier against the others' own spread too: a hand-held hammer's direction varies from hit to
        # hit, and with it the modes excited through its tilt (the FRF varies by as much from hit to hit)
        with np.errstate(divide="ignore", invalid="ignore"):
            db = np.where(f_ratio > 0, 20 * np.log10(f_ratio), np.nan)
        lim_db = _outlier_limits(db, cfg.max_force_offset_db)
        lim_share = _outlier_limits(u, cfg.max_unexplained_share)
        score = np.maximum(off / lim_db, excess / lim_share)
        if not score.max(initial=0.0) > 1.0:
            break
        h = int(np.argmax(score))
        others = int(np.count_nonzero(accepted.any(axis=1))) - 1
        force_part = (f"the force spectrum is {f_ratio[h]:.3f} x the one its responses imply through the other "
                      f"{others} hits' FRF in the hammer tip's band, its peak {f_peak[h]:.3f} x (relative to the other "
                      f"hits'; {_limit_text(lim_db[h], cfg.max_force_offset_db, ' dB')})")
        if excess[h] > lim_share[h]:
            reject(test.hits[h], None, "struck another point",
                   f"{100 * u[h]:.1f} % of its response power (median over the hammer tip's band) is not explained by "
                   f"any force at the point of the other {others} hits, against the {100 * (u[h] - excess[h]):.1f} % "
                   f"theirs leave at its force "
                   f"({_limit_text(lim_share[h], cfg.max_unexplained_share, ' % more', 100)}): its responses "
                   f"follow another column of the FRF matrix (another point, or another direction of the blow), "
                   f"which averaged in would mix two driving points into every FRF; {force_part}")
        elif not f_ratio[h] > 0:
            # one transducer cannot change its polarity between hits; the structure answered a force the other way
            reject(test.hits[h], None, "struck another point",
                   f"its responses imply a force opposite to the measured one: {force_part}; the hammer struck "
                   f"another point, where the modes that carry the responses move the other way, or struck from the "
                   f"other side; averaged in, it would cancel part of every FRF")
        else:
            why = ("clipped before the converter's filter, which rounds the flat top (the force input range set too "
                   "low for this hit), a glancing blow whose force the transducer's axis does not see, or a blow at "
                   "another point with responses in the same proportions"
                   if f_ratio[h] < 1 else
                   "the force channel picked up a spike, or the hammer struck another point with responses in the "
                   "same proportions")
            reject(test.hits[h], None, "force off its responses",
                   f"{force_part}: this hit would move every FRF by {_db_move(f_ratio[h])}; {why}")
        accepted[h] = False

    # ---- two hits left: nothing tells which one is off, but a disagreement is not averaged in unsaid
    pair = pair_offset(test, accepted, f_rest, rest)
    if pair is not None:
        (a, b), r = pair
        if not r > 0 or abs(20 * np.log10(r)) > cfg.max_force_offset_db:
            log.warning("screening %s: hits %s and %s, the only two accepted, disagree: hit %s's FRF is %.3f x hit "
                        "%s's on the hammer tip's band (limit %g dB); with two hits the screening cannot tell which "
                        "is off (a force clipped before the converter's filter, a glancing blow, a hit at another "
                        "point): both are averaged in, and the FRF is off by up to the difference; take a third hit",
                        src, test.hits[a], test.hits[b], test.hits[a], r, test.hits[b], cfg.max_force_offset_db)

    # ---- clipped before the converter's filter: the peak against the one the other hits predict
    ratio, predicted = peak_compression(test, accepted, f_rest, rest)
    # below the other hits' own spread too: the hammer's direction moves a channel's peak from hit to hit
    with np.errstate(divide="ignore", invalid="ignore"):
        log_ratio = np.log(ratio)
    spread = np.column_stack([_outlier_limits(log_ratio[:, j], 0.0) for j in range(test.n_channels)])
    peak_limit = np.minimum(cfg.min_peak_ratio, np.exp(-spread))
    rounded = np.nan_to_num(ratio, nan=np.inf) < peak_limit  # NaN: no verdict
    for h, j in zip(*np.nonzero(rounded)):
        others = int(accepted[:, j].sum()) - 1
        lim = peak_limit[h, j]
        why = f", {OUTLIER_SPREADS:g} x the other hits' spread" if lim < cfg.min_peak_ratio else ""
        reject(test.hits[h], j, "clipped",
               f"peak {np.abs(test.responses[h, j] - rest[h, j]).max():.4g} m/s^2 is {ratio[h, j]:.2f} x the "
               f"{predicted[h, j]:.4g} m/s^2 its force predicts through the other {others} hits' FRF, at the "
               f"record's own scale (limit {lim:.3g} x{why}): clipped before the converter's filter, which "
               "rounds the flat top (the input range set too low for this hit)")
    accepted &= ~rounded

    # ---- clipped at one level in every hit: the peak stays put while the forces change
    measured = np.abs(test.responses - rest[:, :, None]).max(axis=2)
    for j, slope, lo, hi in peak_slopes(accepted, predicted, measured, cfg.min_peak_slope):
        hs = accepted[:, j]
        reject(None, j, "clipped",
               f"its peak stays within {measured[hs, j].min():.4g}-{measured[hs, j].max():.4g} m/s^2 over "
               f"{int(hs.sum())} hits whose forces imply {lo:.4g}-{hi:.4g} m/s^2 through the other hits' FRF "
               f"(the peak grows as the implied one to the power {slope:.2f}; a linear record's to the power 1, limit "
               f"{cfg.min_peak_slope:g}): clipped at one level in every hit before the converter's filter (the "
               "sensor's own range, or the input range, exceeded by every hit)")
        accepted[:, j] = False

    # ---- levels: per unit force across hits, and against the neighbouring sensors
    _check_levels(test, cfg, accepted, pulse_rms, level, reject)

    # ---- coherence after averaging (per channel)
    if cfg.check_coherence:
        usable = accepted.sum(axis=0) >= 2
        if usable.any():
            mask = accepted & usable[None, :]
            decay = (auto_exp_decay(test, accepted=mask, level=cfg.pulse_level)
                     if exp_window_decay is None else float(exp_window_decay))
            _, sff, sfa, saa = _spectra(test, mask, band_hz, force_window, decay)
            with np.errstate(divide="ignore", invalid="ignore"):
                coh = np.nan_to_num(np.abs(sfa) ** 2 / (sff * saa), nan=0.0)
            low = (coh < cfg.min_coherence).mean(axis=1)
            for j in np.flatnonzero(usable & (low > cfg.max_low_coherence_fraction)):
                reject(None, j, "low coherence",
                       f"coherence below {cfg.min_coherence:g} on {100 * low[j]:.0f} % of {band_hz[0]:g}-"
                       f"{band_hz[1]:g} Hz after averaging {int(accepted[:, j].sum())} hits (median "
                       f"{np.median(coh[j]):.3f})")
                accepted[:, j] = False
        for j in np.flatnonzero(~usable & accepted.any(axis=0)):
            log.info("screening %s: channel %r has only one accepted hit; coherence not checked", src, names[j])

    out = Screening(test.hits, names, accepted, tuple(rejections), cfg, src)
    log.info("screening %s: %d of %d hit x channel cells accepted, %d rejections", src,
             int(accepted.sum()), accepted.size, len(rejections))
    return out
