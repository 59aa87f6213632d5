"""The noise floor of a measured FRF that arrived without what H1 noise theory needs.

The floor of the figure of merit ``E`` (:mod:`receptance.diagnosis.compare`)
is the ``E`` a perfect model would score against the noisy measurement.
From a hammer campaign's time data it follows from the coherence ``γ²``
and the number ``n`` of averaged hits (Bendat & Piersol, random error of H1:
``σ² = |H|² (1 − γ²)/((n − 1) γ²)``).  Commercial systems export FRFs
(UFF58), sometimes with the coherence, rarely with the number of averages.

Without coherence: the modal-fit residual.  The identification fits every
channel with the modes of the band plus residual terms (LSFD, a few dozen
real numbers against thousands of lines); what that synthesis cannot
describe is the measurement's random error, plus whatever the modal fit
misses.  Per channel and sixth-octave band the variance is the median of
``|H_x − H_synthesis|²`` over the band's lines divided by ``ln 2`` (the
median of an exponential variable — ``|z|²`` of complex Gaussian noise —
is ``ln 2`` times its mean; the median ignores the few lines where the
synthesis misses a peak).  It is an upper bound: a modal-fit error counts
as noise.  On the virtual lab the floor it gives is 1–4 % above the
coherence floor of the same data.

Without a synthesis: the line-to-line roughness.  The true FRF is smooth
over a few lines away from sharp peaks, its random error is not: the
second difference ``Δ²H = H_{k−1} − 2 H_k + H_{k+1}`` removes the smooth
part.  An exponential window ``e^{−a t}`` on a record of length
``T = 1/Δf`` correlates the noise of neighbouring lines,
``ρ_j = 1/(1 − i π j Δf / a)``, so ``E|Δ²e|² = σ² (6 − 8 Re ρ_1 + 2 Re ρ_2)``;
the same robust median per band gives ``σ²``.  Measured on the virtual lab:
7–12 % below the coherence floor (peaks narrower than a few lines leak
into it).

With coherence but without the number of averages: ``n`` is estimated per
channel so that the coherence formula matches the modal-fit residual
(median over the band's lines), and rounded; the report says so.
"""

from __future__ import annotations

import numpy as np

from ema.frf import FrequencyResponse

__all__ = ["frf_noise_variance", "estimate_averages", "PER_OCTAVE"]

#: resolution of the noise estimate: bands per octave
PER_OCTAVE = 6


def _bands(f: np.ndarray, per_octave: int) -> list[np.ndarray]:
    pos = f[f > 0]
    if pos.size < 2:
        return [np.ones(f.size, bool)]
    lo, hi = pos[0], f[-1]
    n = max(int(np.ceil(per_octave * np.log2(hi / lo))), 1)
    edges = lo * (hi / lo) ** (np.arange(n + 1) / n)
    idx = np.clip(np.searchsorted(edges, f, side="right") - 1, 0, n - 1)
    out = [idx == k for k in range(n)]
    # a band with fewer than 8 lines joins its upper neighbour (a median of 3 lines is no estimate)
    merged, acc = [], np.zeros(f.size, bool)
    for sel in out:
        acc = acc | sel
        if acc.sum() >= 8:
            merged.append(acc)
            acc = np.zeros(f.size, bool)
    if acc.any():
        if merged:
            merged[-1] = merged[-1] | acc
        else:
            merged.append(acc)
    return merged


def frf_noise_variance(frf: FrequencyResponse, synthesis: FrequencyResponse | None = None, *,
                       per_octave: int = PER_OCTAVE) -> tuple[np.ndarray, str]:
    """Expected squared complex random error of each line of a single-reference FRF (module docstring).

    Parameters
    ----------
    frf : FrequencyResponse
        Measured (one input).
    synthesis : FrequencyResponse, optional
        The identification's modal synthesis on the same lines and outputs
        (``ema.identify(...).synthesis``); without it the line-to-line
        roughness is used.
    per_octave : int
        Resolution of the estimate.

    Returns
    -------
    variance : ndarray (n_out, n_freq)
    method : str
        How it was estimated, in words (for the report).
    """
    H = frf.data[:, 0]
    f = frf.freqs_hz
    var = np.zeros(H.shape)
    if synthesis is not None:
        if synthesis.data.shape[0] != H.shape[0] or synthesis.freqs_hz.shape != f.shape or not np.allclose(
                synthesis.freqs_hz, f, rtol=1e-9):
            raise ValueError(f"the synthesis ({synthesis.data.shape[0]} outputs, {synthesis.freqs_hz.size} lines) "
                             f"must be on the measurement's outputs and lines ({H.shape[0]}, {f.size})")
        r = H - synthesis.data[:, 0]
        for sel in _bands(f, per_octave):
            var[:, sel] = (np.median(np.abs(r[:, sel]) ** 2, axis=1) / np.log(2))[:, None]
        return var, (f"estimated from the measurement itself: the residual of the identification's modal fit "
                     f"(LSFD synthesis), robust median per channel and 1/{per_octave}-octave band (an upper bound: "
                     f"what the modal fit misses counts as noise); no coherence in the FRF file")
    a = float(frf.exp_window_decay)
    df = float(np.median(np.diff(f))) if f.size > 1 else 1.0
    if a > 0:
        rho1 = 1.0 / (1.0 - 1j * np.pi * df / a)
        rho2 = 1.0 / (1.0 - 2j * np.pi * df / a)
        factor = 6.0 - 8.0 * rho1.real + 2.0 * rho2.real
    else:
        factor = 6.0
    d2 = np.zeros(H.shape, complex)
    d2[:, 1:-1] = H[:, :-2] - 2 * H[:, 1:-1] + H[:, 2:]
    inner = np.ones(f.size, bool)
    inner[[0, -1]] = False
    for sel in _bands(f, per_octave):
        use = sel & inner
        if not use.any():
            use = inner
        var[:, sel] = (np.median(np.abs(d2[:, use]) ** 2, axis=1) / np.log(2) / factor)[:, None]
    return var, (f"estimated from the measurement itself: line-to-line roughness of the FRF (second differences, "
                 f"corrected for the exponential window's line correlation, a = {a:.3g} 1/s), robust median per "
                 f"channel and 1/{per_octave}-octave band; no coherence in the FRF file")


def estimate_averages(frf: FrequencyResponse, synthesis: FrequencyResponse | None = None) -> np.ndarray:
    """Number of averaged hits per output implied by the FRF's coherence and its noise estimate.

    ``n − 1 = median_f [ |H|² (1 − γ²) / γ² / σ²_f ]`` with ``σ²`` from
    :func:`frf_noise_variance`; at least 2.
    """
    if frf.coherence is None:
        raise ValueError("the FRF has no coherence to estimate the number of averages from")
    var, _ = frf_noise_variance(frf, synthesis)
    g2 = np.clip(frf.coherence[:, 0], 1e-12, 1.0)
    ratio = np.abs(frf.data[:, 0]) ** 2 * (1 - g2) / g2 / np.maximum(var, np.finfo(float).tiny)
    ok = (g2 < 1.0) & np.isfinite(ratio) & (ratio > 0)
    n = np.array([np.median(ratio[i, ok[i]]) + 1 if ok[i].any() else 2.0 for i in range(ratio.shape[0])])
    return np.maximum(np.round(n), 2).astype(int)
