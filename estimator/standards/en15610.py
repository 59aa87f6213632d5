"""EN 15610 one-third-octave roughness level spectrum ``L_r`` (dB re 1 µm), Method A (clause 7.4.2).

Processing (EN 15610:2009 7.4–7.5, Annex C), applied to a stretch of the
estimated profile:

* segments of ``segment_m`` (≥ 1 m, 7.4.2) overlapping by half; only
  segments with no masked sample are used;
* each segment: mean and linear trend removed, Hann window, |DFT|²
  normalised by the window's energy so that the one-sided lines sum to the
  segment's mean square; the segments' spectra are averaged;
* a one-third-octave band (base ten: band ``k`` centred on ``10^{k/10}``
  cycles/m, edges ``10^{±1/20}`` around it) collects its lines in full and
  the two lines straddling its edges for the part of their width inside it
  (Annex C, Formula C.1);
* ``L_r = 10 lg(r²_band / r0²)``, ``r0 = 1 µm`` (3.3, Formula 1);
* a band is reported only when its nominal wavelength is at most a quarter
  of the segment (7.5), its upper edge lies below the Nyquist wavenumber,
  and — for an axlebox estimate — the run resolves it: the band lies inside
  ``[v_max/f_hi, v_min/f_lo]`` over the stretch (``resolved_m``).

Not applied: the spike removal (7.2) and curvature processing (7.3), which
correct a direct probe record for dirt and for pits narrower than a wheel:
an axlebox estimate is already what the wheel felt. ``phonometry``
(``environment/sources/acoustic_roughness.py``) implements the same Method A
correctly (the straddling-line rule, the quarter-length rule, the window
normalisation), but it refuses records sampled coarser than the 1 mm of
5.5 — an axlebox estimate at 1 kHz is sampled at millimetres to centimetres
— always applies 7.2/7.3 unless told not to, and needs Python ≥ 3.13; this
module is written from the standard's rules instead.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from scipy import fft as sfft
from scipy.signal.windows import hann

from estimator.standards.iso3095 import iso3095_limit_db

__all__ = ["R0", "third_octave_bands", "nominal_wavelength", "band_energies", "RoughnessSpectrum",
           "roughness_spectrum", "detrend_rows", "segments_of"]

R0 = 1e-6
_R10 = (1.0, 1.25, 1.6, 2.0, 2.5, 3.15, 4.0, 5.0, 6.3, 8.0)


def nominal_wavelength(k: int) -> float:
    """Nominal wavelength [m] of band ``k`` (R10 preferred number nearest ``10^{-k/10}``)."""
    mant = (-k) % 10
    exp = (-k - mant) // 10
    return _R10[mant] * 10.0**exp


def third_octave_bands(longest_m: float, shortest_m: float) -> np.ndarray:
    """Band indices ``k`` whose nominal wavelength lies in ``[shortest_m, longest_m]``, longest first."""
    # nominal wavelengths round the exact 10^(-k/10) by up to 1 % (0.04 in k)
    k_lo = int(math.ceil(-10 * math.log10(longest_m) - 0.05))
    k_hi = int(math.floor(-10 * math.log10(shortest_m) + 0.05))
    return np.arange(k_lo, k_hi + 1)


def detrend_rows(x: np.ndarray) -> np.ndarray:
    """Each row minus its least-squares straight line (closed form)."""
    n = x.shape[-1]
    u = np.arange(n) - (n - 1) / 2
    mean = x.mean(axis=-1, keepdims=True)
    slope = (x @ u)[..., None] / float(u @ u)
    return x - mean - slope * u


def segments_of(p: np.ndarray, n: int) -> np.ndarray:
    """Segments of ``n`` samples overlapping by half with no NaN, one per row (possibly none)."""
    if n < 8 or p.size < n:
        return np.zeros((0, n))
    bad = np.concatenate([[0], np.cumsum(~np.isfinite(p))])
    starts = np.arange(0, p.size - n + 1, max(1, n // 2))
    starts = starts[bad[starts + n] == bad[starts]]
    if starts.size == 0:
        return np.zeros((0, n))
    return np.lib.stride_tricks.sliding_window_view(p, n)[starts]


def band_energies(line_k: np.ndarray, line_e: np.ndarray, dk: float, bands: np.ndarray) -> np.ndarray:
    """Energy per band from narrow lines of width ``dk`` centred on ``line_k`` (Annex C partial lines)."""
    centre = 10.0 ** (bands / 10.0)
    lo, hi = centre * 10 ** -0.05, centre * 10 ** 0.05
    a = line_k - dk / 2
    b = line_k + dk / 2
    overlap = np.clip(np.minimum(b[:, None], hi[None, :]) - np.maximum(a[:, None], lo[None, :]), 0.0, None)
    return line_e @ (overlap / dk)


@dataclass(frozen=True, eq=False)
class RoughnessSpectrum:
    """One-third-octave roughness levels of a stretch (EN 15610 Method A)."""

    bands: np.ndarray
    wavelength_m: np.ndarray
    level_db: np.ndarray
    limit_db: np.ndarray
    n_segments: int
    length_m: float

    def as_rows(self) -> list[dict]:
        return [{"band": int(b), "wavelength_m": float(w), "level_db": float(l), "iso3095_limit_db": float(c)}
                for b, w, l, c in zip(self.bands, self.wavelength_m, self.level_db, self.limit_db)]


def roughness_spectrum(profile: np.ndarray, dx: float, *, segment_m: float = 2.0,
                       resolved_m: tuple[float, float] | None = None, longest_m: float = 0.5,
                       shortest_m: float = 0.00315) -> RoughnessSpectrum:
    """EN 15610 Method A spectrum of one stretch of profile (module docstring).

    Parameters
    ----------
    profile : ndarray (M,)
        Roughness [m] on a uniform grid (NaN = masked).
    dx : float
        Step [m].
    segment_m : float
        Fourier segment length [m] (≥ 1 m).
    resolved_m : (float, float), optional
        (shortest, longest) wavelength the run resolves over the stretch.
    longest_m, shortest_m : float
        Band range of the report.
    """
    p = np.asarray(profile, float)
    n = int(round(segment_m / dx))
    bands, wl, limit, win, win_energy, to_bands, ok_grid = _layout(n, float(dx), float(segment_m), float(longest_m),
                                                                   float(shortest_m))
    levels = np.full(bands.size, np.nan)
    segs = segments_of(p, n)
    if segs.shape[0]:
        segs = detrend_rows(segs)
        S = np.abs(sfft.rfft(segs * win, axis=1)) ** 2
        # one-sided lines that sum to the mean square: |X|² / (N Σw²) doubled except DC (and Nyquist)
        e = S.mean(axis=0) / (n * win_energy)
        e[1:] *= 2.0
        if n % 2 == 0:
            e[-1] /= 2.0
        energy = e[1:] @ to_bands
        ok = ok_grid.copy()
        if resolved_m is not None:
            lam_lo_edge = 1 / (10 ** (bands / 10) * 10 ** 0.05)  # shortest wavelength in the band
            lam_hi_edge = 1 / (10 ** (bands / 10) * 10 ** -0.05)
            ok &= (lam_lo_edge >= resolved_m[0]) & (lam_hi_edge <= resolved_m[1])
        with np.errstate(divide="ignore"):
            levels = np.where(ok, 10 * np.log10(np.maximum(energy, 1e-300) / R0**2), np.nan)
    k_seg = segs.shape[0]
    return RoughnessSpectrum(bands, wl, levels, limit.copy(), k_seg, (k_seg + 1) * n * dx / 2 if k_seg else 0.0)


@functools.lru_cache(maxsize=64)
def _layout(n: int, dx: float, segment_m: float, longest_m: float, shortest_m: float):
    """What every stretch of one grid shares (a run has tens of stretches per rail and model): bands, nominal
    wavelengths, ISO 3095 limit, Hann window and its energy, the lines-to-bands matrix of Annex C and the bands
    the segment length and the grid allow (7.5)."""
    bands = third_octave_bands(longest_m, shortest_m)
    wl = np.array([nominal_wavelength(int(k)) for k in bands])
    win = hann(n, sym=False)
    dk = 1.0 / (n * dx)
    k = np.arange(n // 2 + 1)[1:] * dk
    to_bands = band_energies(k, np.eye(k.size), dk, bands)
    ok = (wl <= segment_m / 4 * (1 + 1e-9)) & (10 ** (bands / 10) * 10 ** 0.05 < 0.5 / dx)
    for a in (bands, wl, win, to_bands, ok):
        a.flags.writeable = False
    limit = iso3095_limit_db(wl)
    limit.flags.writeable = False
    return bands, wl, limit, win, float(np.sum(win**2)), to_bands, ok
