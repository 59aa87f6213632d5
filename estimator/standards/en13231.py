"""EN 13231-3 band indexes: band-filtered profiles, moving RMS and peak-to-peak, exceedance (thesis §4.3.1).

The railhead profile is band-pass filtered (zero phase) into the wavelength
bands 10–30, 30–100, 100–300 and 300–1000 mm, its moving RMS is taken over
the window of thesis Table 4.1 (0.15, 0.5, 1.5, 5 m) and turned into a
peak-to-peak amplitude (thesis eq. 4.1, with the square inside the RMS that
the thesis drops — DESIGN.md):

    Irr_pk-pk(x) = 2√2 · sqrt( (1/L) ∫_{x−L/2}^{x+L/2} z_band(ξ)² dξ )

**Band filter.** A Butterworth high-pass and low-pass in wavenumber, order 4
each, applied forward and backward (zero phase, squared magnitude), with
cut-offs placed so that the zero-phase response is −3 dB exactly at the band
edges: ``k_c = k_edge (√2 − 1)^{±1/(2N)}``. It is applied as its squared
magnitude in the wavenumber domain (what ``filtfilt`` does, without its edge
padding), on the zero-filled profile; samples closer to a gap than the
band's longest wavelength are masked.

**Windows.** Centred windows of ``round(L/dx)`` samples (odd); a window that
holds a masked sample is masked. **Exceedance**: share of the valid length
where the peak-to-peak amplitude exceeds a threshold.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import fft as sfft

__all__ = ["BUTTERWORTH_ORDER", "band_response", "band_filter", "moving_rms", "pk_pk", "exceedance",
           "BandIndexes", "band_indexes", "grow_mask"]

BUTTERWORTH_ORDER = 4
PK_PK_PER_RMS = 2 * math.sqrt(2)


def band_response(k: np.ndarray, band_mm: tuple[float, float], order: int = BUTTERWORTH_ORDER) -> np.ndarray:
    """Zero-phase (squared-magnitude) response of the band filter at wavenumbers ``k`` [cycles/m]."""
    k = np.abs(np.asarray(k, float))
    k_lo, k_hi = 1e3 / band_mm[1], 1e3 / band_mm[0]
    q = (math.sqrt(2) - 1) ** (1 / (2 * order))
    c_hp, c_lp = k_lo * q, k_hi / q
    with np.errstate(divide="ignore", over="ignore"):
        hp = 1 / (1 + (c_hp / np.where(k > 0, k, np.inf)) ** (2 * order))
        lp = 1 / (1 + (k / c_lp) ** (2 * order))
    return np.where(k > 0, hp, 0.0) * lp


def grow_mask(bad: np.ndarray, n: int) -> np.ndarray:
    """``bad`` widened by ``n`` samples on each side (along the last axis)."""
    b = np.asarray(bad, bool)
    if n <= 0 or not b.any():
        return b
    m = b.shape[-1]
    c = np.zeros(b.shape[:-1] + (m + 2 * n + 1,), np.int32)
    np.cumsum(b, axis=-1, out=c[..., n + 1:m + n + 1])
    c[..., m + n + 1:] = c[..., m + n:m + n + 1]
    # window [i - n, i + n] of b  ->  c[i + 2n + 1] - c[i] in the padded cumulative count
    return (c[..., 2 * n + 1:] - c[..., :m]) > 0


def band_filter(profile: np.ndarray, dx: float, band_mm: tuple[float, float], *, spectrum=None) -> np.ndarray:
    """Zero-phase band-pass of a profile (module docstring); NaN kept and grown by the band's longest wavelength.

    Parameters
    ----------
    profile : ndarray (..., M)
        Uniformly sampled profile [m] (NaN = masked).
    dx : float
        Sample step [m].
    band_mm : (float, float)
        (shortest, longest) wavelength [mm].
    spectrum : (ndarray, int), optional
        Precomputed ``(rfft of the zero-filled profile, nfft)`` to reuse across bands.
    """
    p = np.asarray(profile, float)
    bad = ~np.isfinite(p)
    m = p.shape[-1]
    pad = int(math.ceil(2 * band_mm[1] * 1e-3 / dx))
    if spectrum is None:
        nfft = sfft.next_fast_len(m + pad)
        P = sfft.rfft(np.where(bad, 0.0, p), nfft, axis=-1)
    else:
        P, nfft = spectrum
    k = sfft.rfftfreq(nfft, dx)
    z = sfft.irfft(P * band_response(k, band_mm), nfft, axis=-1)[..., :m]
    z[grow_mask(bad, int(math.ceil(band_mm[1] * 1e-3 / dx)))] = np.nan
    return z


def moving_rms(z: np.ndarray, dx: float, window_m: float) -> np.ndarray:
    """Centred moving RMS over ``window_m`` (odd number of samples); NaN where the window holds a NaN."""
    z = np.asarray(z, float)
    n = max(1, int(round(window_m / dx)))
    n += (n + 1) % 2
    h = n // 2
    m = z.shape[-1]
    out = np.full(z.shape, np.nan)
    if m < n:
        return out
    bad = ~np.isfinite(z)
    c = np.zeros(z.shape[:-1] + (m + 1,))
    np.cumsum(np.where(bad, 0.0, z * z), axis=-1, out=c[..., 1:])
    cb = np.zeros(z.shape[:-1] + (m + 1,), np.int32)
    np.cumsum(bad, axis=-1, out=cb[..., 1:])
    ms = (c[..., n:] - c[..., :-n]) / n
    nbad = cb[..., n:] - cb[..., :-n]
    out[..., h:m - h] = np.where(nbad == 0, np.sqrt(np.maximum(ms, 0.0)), np.nan)
    return out


def pk_pk(rms: np.ndarray) -> np.ndarray:
    """Peak-to-peak amplitude of eq. 4.1: ``2√2 × RMS`` (a sinusoid's peak-to-peak)."""
    return PK_PK_PER_RMS * np.asarray(rms)


def exceedance(pk: np.ndarray, threshold_m: float) -> float:
    """Share [%] of the valid samples where ``pk`` exceeds ``threshold_m`` (NaN when nothing is valid)."""
    v = np.asarray(pk)[np.isfinite(pk)]
    return float(100.0 * np.mean(v > threshold_m)) if v.size else float("nan")


@dataclass(frozen=True, eq=False)
class BandIndexes:
    """EN 13231-3 results of one profile: the peak-to-peak amplitude per band on the profile's grid.

    ``decimation[i]`` is the step factor band ``i`` was filtered and windowed at (≥ 4 samples per its
    shortest wavelength); its peak-to-peak is interpolated back onto the profile's grid.
    """

    dx: float
    bands_mm: tuple[tuple[float, float], ...]
    windows_m: tuple[float, ...]
    pk_pk: np.ndarray  # (n_bands, ..., M)
    decimation: tuple[int, ...] = ()

    @property
    def rms(self) -> np.ndarray:
        """Moving RMS (eq. 4.1 before the factor 2√2)."""
        return self.pk_pk / PK_PK_PER_RMS


def _divisor_at_most(n: int, d: int) -> int:
    d = max(1, d)
    while n % d:
        d -= 1
    return d


#: a band resolved over less than this share of a profile is filtered stretch by stretch
LOCAL_SHARE = 0.3


def _local_band(p: np.ndarray, dx: float, band, win: float, res_any: np.ndarray, resolved: np.ndarray) -> np.ndarray:
    """Moving RMS of one band computed only around the stretches where it is resolved (NaN elsewhere)."""
    from estimator.qc import runs_of

    m = p.shape[-1]
    out = np.full(p.shape, np.nan)
    margin = int(math.ceil(3 * band[1] * 1e-3 / dx))
    spans: list[list[int]] = []
    for a, b in runs_of(res_any):
        a0, b0 = max(0, a - margin), min(m, b + margin)
        if spans and a0 <= spans[-1][1]:
            spans[-1][1] = b0
        else:
            spans.append([a0, b0])
    for a0, b0 in spans:
        if b0 - a0 < 8:
            continue
        sub = p[..., a0:b0]
        z = band_filter(sub, dx, band)
        z = np.where(resolved[..., a0:b0], z, np.nan)
        out[..., a0:b0] = moving_rms(z, dx, win)
    return out


def band_indexes(profile: np.ndarray, dx: float, bands_mm, windows_m, resolved: np.ndarray | None = None, *,
                 spectrum: tuple[np.ndarray, int] | None = None) -> BandIndexes:
    """Band-filter a profile into each band and take its moving RMS and peak-to-peak (module docstring).

    Each band is computed on a grid decimated to 4 samples per its shortest wavelength (the band-limited
    decimation: the filtered spectrum is truncated at the coarse grid's Nyquist wavenumber, where the
    zero-phase band filter is below −40 dB, so the result does not depend on the sampling) and its
    peak-to-peak interpolated back.

    Parameters
    ----------
    profile : ndarray (..., M)
        Profile [m] (NaN = masked).
    dx : float
    bands_mm : sequence of (short, long) [mm]
    windows_m : sequence of float
        Window per band (thesis Table 4.1).
    resolved : ndarray of bool (n_bands, M) or (n_bands, ..., M), optional
        Where each band is resolved by the run (speed); elsewhere the band is masked before the window.
    spectrum : (ndarray, int), optional
        ``(rfft of the zero-filled profile, nfft)`` when the caller has it (it may hold a correction).
    """
    p = np.asarray(profile, float)
    bad = ~np.isfinite(p)
    m = p.shape[-1]
    longest = max(b[1] for b in bands_mm)
    if spectrum is None:
        nfft = sfft.next_fast_len(m + int(math.ceil(2 * longest * 1e-3 / dx)))
        P = sfft.rfft(np.where(bad, 0.0, p), nfft, axis=-1)
    else:
        P, nfft = spectrum
    k = sfft.rfftfreq(nfft, dx)
    idx_full = np.arange(m)
    out = np.full((len(bands_mm),) + p.shape, np.nan)
    real = np.float32 if P.dtype == np.complex64 else float
    decim = []
    for i, (band, win) in enumerate(zip(bands_mm, windows_m)):
        if resolved is not None and spectrum is not None:
            res_any = np.broadcast_to(resolved[i], p.shape).reshape(-1, m).any(axis=0)
            if res_any.mean() < LOCAL_SHARE:
                # a band the run resolves over a small part only (the 10-30 mm band is resolved below 4 m/s):
                # filter those stretches on their own instead of the whole profile
                decim.append(1)
                out[i] = _local_band(p, dx, band, win, res_any, np.broadcast_to(resolved[i], p.shape))
                continue
        d = _divisor_at_most(nfft, int(band[0] * 1e-3 / (4 * dx)))
        decim.append(d)
        nb = nfft // d // 2 + 1
        z = sfft.irfft(P[..., :nb] * band_response(k[:nb], band).astype(real), nfft // d,
                       axis=-1)[..., :(m + d - 1) // d] / d
        masked = grow_mask(bad, int(math.ceil(band[1] * 1e-3 / dx)))
        if resolved is not None:
            masked = masked | ~np.broadcast_to(resolved[i], p.shape)
        z[masked[..., ::d]] = np.nan
        r = moving_rms(z, d * dx, win)
        if d == 1:
            out[i] = r
        else:
            xd = idx_full[::d]
            rows = r.reshape(-1, r.shape[-1])
            full = out[i].reshape(-1, m)
            for j in range(rows.shape[0]):
                full[j] = np.interp(idx_full, xd, rows[j], right=np.nan)
    out *= PK_PK_PER_RMS  # eq. 4.1: peak-to-peak = 2√2 RMS (in place: the array is large)
    return BandIndexes(dx, tuple(tuple(b) for b in bands_mm), tuple(windows_m), out, tuple(decim))
