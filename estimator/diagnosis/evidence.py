"""The evidence of a field diagnosis: each run's acceleration spectra per chainage segment, computed once.

A candidate effect changes only the transfer functions, never the
accelerations, so the diagnosis keeps, per run, wheelset and segment of
``segment_m`` along chainage, the one-sided cross-spectral density matrix
``S_a(f)`` of the wheelset's channels (Welch, Hann windows of ``window_m``
of travel, half overlap: :func:`scipy.signal.csd`). The estimate's roughness
spectrum through any transfer function ``T`` is then ``S_r = T S_a Tᴴ``
(thesis eq. 2.22 applied to spectra), and its variance in a wavelength band
``[λ₁, λ₂]`` is the integral of ``S_r`` over ``v/λ₂ ≤ f ≤ v/λ₁`` — the band
variance does not depend on whether it is counted in time or chainage.
The reference (trolley) gets the same windows in chainage; its own noise
(sub-µm, white) is the median level of its shortest wavelengths, and a band
whose reference lies less than ``min_reference_snr_db`` above that noise
holds no evidence.

With the bogie's rail coupling (the estimator's ``bogie_coupling``), ``S``
holds the other wheelset's channels too, at the same instants (appended after
the segment's own ones): the estimator adds the rail deflection the other
wheelset's contact forces cause, so its estimate is a map of both
(:meth:`estimator.diagnosis.transfer.WheelsetBlocks.coupled_transfer`).

The estimator removes each wheelset's own roughness with its comb filter
(:func:`estimator.wheel.comb`: the synchronous average over ``±R``
revolutions of the wheel, subtracted); a spectrum of the raw accelerations
would carry it (+1 dB on an in-service rail where the wheels are 6 dB
smoother, +3 dB on a fresh-ground one). :func:`comb_channels` applies the
same comb to the channels first, in the wheelset's angle, with the
circumference the estimator found — at a locally constant speed the comb
and the inversion's linear time-invariant filter commute, so the estimate
of the combed channels is the estimator's combed estimate. The estimator's
sleeper comb (:mod:`estimator.sleepers`) is applied the same way, at the
sleeper spacing and the orders it removed from the estimate.

Cells: run × wheelset × segment × rail × one-third-octave wavelength band
(IEC 61260 base-10 bands) that the segment's speed puts inside the
inversion band and that ``min_cycles`` wavelengths fit into one window.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy import signal

from estimator.diagnosis.errors import ReferenceCoverageError

__all__ = ["SegmentSpectra", "Evidence", "third_octave_bands", "reference_band_variance", "run_segments",
           "segments_of", "cells_frame", "comb_channels"]

log = logging.getLogger("estimator")

#: a segment whose speed varies more than this share about its mean is not used (the f ↔ λ map blurs)
MAX_SPEED_VARIATION = 0.10


def third_octave_bands(shortest_m: float, longest_m: float) -> np.ndarray:
    """Base-10 one-third-octave wavelength bands (IEC 61260) with centres in ``[shortest, longest]``.

    Returns ``(n, 3)``: centre, lower and upper wavelength [m] (lower < centre < upper).
    """
    n = np.arange(math.ceil(-10 * math.log10(longest_m) - 1e-9), math.floor(-10 * math.log10(shortest_m) + 1e-9) + 1)
    c = 10.0 ** (-n / 10.0)
    out = np.stack([c, c * 10 ** (-1 / 20), c * 10 ** (1 / 20)], axis=1)
    return out[np.argsort(out[:, 0])]


def segments_of(lo: float, hi: float, segment_m: float) -> list[tuple[float, float]]:
    """Whole segments of ``segment_m`` inside ``[lo, hi]`` (on a grid anchored at chainage 0)."""
    a = math.ceil(lo / segment_m - 1e-9) * segment_m
    out = []
    while a + segment_m <= hi + 1e-9:
        out.append((a, a + segment_m))
        a += segment_m
    return out


@dataclass(frozen=True, eq=False)
class SegmentSpectra:
    """One wheelset's channels over one chainage segment of one run.

    Attributes
    ----------
    run_id, date : str
    wheelset : int
    role : {"leading", "trailing"}
    from_m, to_m : float
    speed_m_s : float
        Mean speed over the segment.
    rails : tuple of str
        Rail under each estimated vehicle side (rows of ``T``).
    curve : str or None
        Id of the curve whose body holds the segment (None on tangent track).
    theta : (float, float)
        The estimator's contact angles (θ_L, θ_R) there, before any calibration [rad].
    f : ndarray (n_f,)
        Frequencies of ``S`` [Hz].
    S : ndarray (n_f, m, m)
        One-sided cross-spectral densities of the channels [(m/s²)²/Hz].
    bands : ndarray (n_b,) of int
        Indices into the diagnosis's band table of the bands this segment resolves.
    ref_var : ndarray (n_rails, n_b)
        The reference's band variance per rail [m²] (NaN where it has no evidence).
    ref_noise_var : ndarray (n_rails, n_b)
        The reference's own noise in the band [m²].
    other : int or None
        The bogie's other wheelset whose channels follow the own ones in ``S`` (rail coupling), or None.
    wheelbase_m : float or None
        The distance between the two wheelsets the estimator used (with ``other``).
    """

    run_id: str
    date: str
    wheelset: int
    role: str
    from_m: float
    to_m: float
    speed_m_s: float
    rails: tuple[str, ...]
    curve: str | None
    theta: tuple[float, float]
    f: np.ndarray
    S: np.ndarray
    bands: np.ndarray
    ref_var: np.ndarray
    ref_noise_var: np.ndarray
    other: int | None = None
    wheelbase_m: float | None = None

    @property
    def centre_m(self) -> float:
        return 0.5 * (self.from_m + self.to_m)


@dataclass(frozen=True, eq=False)
class Evidence:
    """Segments of every run, the band table and which segments calibrate (the rest validate)."""

    segments: tuple[SegmentSpectra, ...]
    band_table: np.ndarray
    calibration: np.ndarray  # (n_segments,) bool
    site: tuple[float, float]
    rejected: tuple[str, ...] = field(default_factory=tuple)

    def subset(self, keep: np.ndarray) -> "Evidence":
        idx = np.flatnonzero(keep)
        return Evidence(tuple(self.segments[i] for i in idx), self.band_table, self.calibration[idx], self.site,
                        self.rejected)


def _band_integral(freq: np.ndarray, psd: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """Integral of a one-sided PSD (last axis) over ``[lo, hi]`` (rectangle rule on the Welch grid)."""
    df = float(freq[1] - freq[0])
    sel = (freq >= lo) & (freq < hi)
    return psd[..., sel].sum(axis=-1) * df


def reference_band_variance(x: np.ndarray, r: np.ndarray, band_table: np.ndarray, window_m: float,
                            ) -> tuple[np.ndarray, np.ndarray]:
    """Band variances of a reference profile and of its own white noise over one segment.

    Parameters
    ----------
    x, r : ndarray
        Chainage [m] (uniform) and roughness [m] of one rail over the segment.
    band_table : ndarray (n, 3)
        :func:`third_octave_bands`.
    window_m : float
        Welch window (Hann, half overlap) in chainage.

    Returns
    -------
    var, noise : ndarray (n,)
        Band variance [m²]; the noise's, from the median PSD at wavelengths below 4 samples' worth ×
        2 (the trolley's sub-µm floor: rail roughness there lies far below it).
    """
    dx = float(np.median(np.diff(x)))
    nper = min(int(round(window_m / dx)), r.size)
    k, P = signal.welch(r - r.mean(), fs=1.0 / dx, window="hann", nperseg=nper, detrend="linear")
    var = np.array([_band_integral(k, P, 1.0 / b[2], 1.0 / b[1]) for b in band_table])
    hi_k = k >= 0.25 / dx
    level = float(np.median(P[hi_k])) if hi_k.any() else 0.0
    noise = level * (1.0 / band_table[:, 1] - 1.0 / band_table[:, 2])
    return var, noise


#: band-limited upsampling of the channels before they are read on the wheel's angle grid (polyphase FIR)
COMB_UPSAMPLING = 4


def comb_channels(acc: np.ndarray, chainage: np.ndarray, circumference_m: float, revolutions: int,
                  orders=None) -> np.ndarray:
    """Accelerations with one wheelset's periodic (wheel) part removed by the estimator's comb.

    With ``orders``, the same for another period in chainage: the sleeper spacing in ``circumference_m``,
    ``R`` in bays, and only the orders the estimator's sleeper comb removed
    (:func:`estimator.sleepers.sleeper_comb`).

    Parameters
    ----------
    acc : ndarray (m, n)
        Channels [m/s²], NaN where masked (the comb leaves those out and they stay NaN).
    chainage : ndarray (n,)
        The wheelset's chainage at each sample (either direction of travel).
    circumference_m : float
        The wheel's rolling circumference on the same chainage (:func:`estimator.wheel.circumference`).
    revolutions : int
        ``R`` of :func:`estimator.wheel.comb`.

    Returns
    -------
    ndarray (m, n)
        ``acc − periodic``: the channels are upsampled :data:`COMB_UPSAMPLING` × (polyphase FIR,
        :func:`scipy.signal.resample_poly`) and read on an angle grid as fine as the upsampled samples, the
        comb's synchronous average over the neighbouring revolutions is taken there and read back at each
        sample's angle. Samples where the wheel does not advance (standstill, reversing) keep their value (the
        speed gate drops them).
    """
    from estimator.wheel import comb, only_orders

    acc = np.asarray(acc, float)
    u = np.asarray(chainage, float)
    n = u.size
    if n < 16:
        return acc.copy()
    u = u * (1.0 if u[-1] >= u[0] else -1.0)
    ok = np.isfinite(acc).all(axis=0)
    q = COMB_UPSAMPLING
    up = signal.resample_poly(np.where(ok, acc, 0.0), q, 1, axis=1)[:, :q * (n - 1) + 1]
    pos = np.arange(up.shape[1]) / q
    u_up = np.interp(pos, np.arange(n), u)
    bad_up = np.interp(pos, np.arange(n), (~ok).astype(float)) > 0
    forward = np.concatenate([[True], np.diff(u_up) > 0]) & (u_up >= np.maximum.accumulate(u_up))
    if forward.sum() < 2:
        return acc.copy()
    us = u_up[forward]
    step = float(np.max(np.diff(us)))
    n_per_rev = int(math.ceil(circumference_m / step))
    dx = circumference_m / n_per_rev
    grid = np.arange(us[0], us[-1], dx)
    if grid.size < 2 * n_per_rev:
        return acc.copy()
    X = np.stack([np.interp(grid, us, a[forward]) for a in up])
    X[:, np.interp(grid, us, bad_up[forward].astype(float)) > 0] = np.nan
    periodic = np.nan_to_num(X - comb(X, n_per_rev, revolutions)[0])
    if orders is not None:
        n_rev = grid.size // n_per_rev
        keep = np.zeros(n_per_rev // 2 + 1, bool)
        keep[[k for k in orders if 0 < k < keep.size]] = True
        kept = only_orders(periodic[:, :n_rev * n_per_rev].reshape(len(up), n_rev, n_per_rev), keep)
        periodic = np.concatenate([kept.reshape(len(up), -1), np.zeros((len(up), grid.size - n_rev * n_per_rev))],
                                  axis=1)
    out = acc.copy()
    fwd = np.concatenate([[True], np.diff(u) > 0]) & (u >= np.maximum.accumulate(u))
    for i in range(acc.shape[0]):
        out[i, fwd] = acc[i, fwd] - np.interp(u[fwd], grid, periodic[i])
    return out


def run_segments(run, wheelset: int, kind: str, chainage: np.ndarray, speed: np.ndarray, role: str,
                 rails: tuple[str, ...], segments: list[tuple[float, float]], reference: dict, band_table: np.ndarray,
                 cfg, est_cfg, classes_of, *, coupled: tuple[int, float] | None = None,
                 acceleration: np.ndarray | None = None) -> tuple[list[SegmentSpectra], list[str]]:
    """The :class:`SegmentSpectra` of one run's wheelset on the given segments.

    Parameters
    ----------
    run : estimator.Run
        Sensitivities applied, quality-controlled (its mask is honoured: a segment with any masked sample of
        the wheelset's channels is rejected and named).
    chainage, speed : ndarray (n_samples,)
        The wheelset's chainage and speed at each acceleration sample.
    rails : tuple of str
        Rail under each vehicle side of the model (``T``'s rows).
    reference : dict
        Rail → (x, roughness) on a uniform grid (the same day's trolley, on the train's chainage).
    cfg : DiagnosisConfig
    est_cfg : EstimatorConfig
        Inversion band.
    classes_of : callable
        ``(chainage samples) -> (curve id or None, (θ_L, θ_R))`` or None where the segment straddles classes
        (a transition or a trackform boundary: not used).
    coupled : (int, float), optional
        ``(other wheelset, wheelbase [m])``: the other wheelset's channels of the same model are appended to
        ``S`` (module docstring); its masked samples count too.
    acceleration : ndarray (n_channels, n_samples), optional
        The run's channels (rows of ``run.acceleration``) to use instead, e.g. combed (:func:`comb_channels`).
    """
    from estimator.inversion import model_channels

    chans = run.wheelset_channels(wheelset)
    rows, _ = model_channels(kind, chans)
    idx = chans.loc[rows, "row"].to_numpy(int)
    if coupled is not None:
        chans_o = run.wheelset_channels(coupled[0])
        rows_o, _ = model_channels(kind, chans_o)
        idx = np.concatenate([idx, chans_o.loc[rows_o, "row"].to_numpy(int)])
    acc = (run.acceleration if acceleration is None else acceleration)[idx]
    masked = run.mask.masked[idx].any(axis=0) if run.mask is not None else np.zeros(acc.shape[1], bool)
    fs = run.fs
    f_lo, f_hi = est_cfg.f_lo_hz, est_cfg.f_hi(fs)
    out, rejected = [], []
    for a, b in segments:
        sel = np.flatnonzero((chainage >= a) & (chainage < b))
        where = f"{run.source}: wheelset {wheelset}, segment {a:g}-{b:g} m"
        if sel.size == 0:
            continue
        if sel[-1] - sel[0] + 1 != sel.size:
            rejected.append(f"{where}: passed more than once (reversing): not used")
            continue
        if masked[sel].any():
            rejected.append(f"{where}: {int(masked[sel].sum())} masked sample(s): not used")
            continue
        v = speed[sel]
        vm = float(np.mean(v))
        if vm < est_cfg.speed_gate_m_s or np.std(v) > MAX_SPEED_VARIATION * vm:
            rejected.append(f"{where}: speed {vm:.1f} ± {np.std(v):.1f} m/s (gate {est_cfg.speed_gate_m_s:g} m/s, "
                            f"variation ≤ {100 * MAX_SPEED_VARIATION:g} %): not used")
            continue
        cls = classes_of(chainage[sel])
        if cls is None:
            rejected.append(f"{where}: straddles a curve transition or trackform boundary: not used")
            continue
        curve, theta = cls
        nper = int(round(cfg.window_m / vm * fs))
        if sel.size < nper:
            continue
        x = acc[:, sel]
        f, S = signal.csd(x[None, :, :], x[:, None, :], fs=fs, window="hann", nperseg=nper, detrend="constant")
        S = np.moveaxis(S, 2, 0)  # (n_f, m, m): csd(x, y) = conj(X) Y, so S[j, k] = E[X_j X_k*]
        ok_bands = []
        for i, (c, lo, hi) in enumerate(band_table):
            if vm / hi >= f_lo and vm / lo <= f_hi and hi <= cfg.window_m / cfg.min_cycles:
                ok_bands.append(i)
        ok_bands = np.array(ok_bands, int)
        if ok_bands.size == 0:
            continue
        ref_var = np.full((len(rails), ok_bands.size), np.nan)
        ref_noise = np.full_like(ref_var, np.nan)
        for j, rail in enumerate(rails):
            if rail not in reference:
                continue
            xr, rr = reference[rail]
            s = (xr >= a) & (xr < b)
            if s.sum() < 0.95 * (b - a) / max(float(np.median(np.diff(xr))), 1e-9):
                continue
            var, noise = reference_band_variance(xr[s], rr[s], band_table[ok_bands], cfg.window_m)
            ref_var[j], ref_noise[j] = var, noise
        if not np.isfinite(ref_var).any():
            rejected.append(f"{where}: the reference does not cover it: not used")
            continue
        out.append(SegmentSpectra(run.run_id, run.header.date, wheelset, role, a, b, vm, rails, curve, theta, f, S,
                                  ok_bands, ref_var, ref_noise, None if coupled is None else int(coupled[0]),
                                  None if coupled is None else float(coupled[1])))
    return out, rejected


def cells_frame(ev: Evidence) -> pd.DataFrame:
    """One row per cell (segment × rail × band) with the reference level [dB re 1 µm] and its SNR [dB]."""
    rows = []
    for si, s in enumerate(ev.segments):
        for j, rail in enumerate(s.rails):
            for k, b in enumerate(s.bands):
                rv, nv = s.ref_var[j, k], s.ref_noise_var[j, k]
                rows.append({"segment": si, "run_id": s.run_id, "date": s.date, "wheelset": s.wheelset,
                             "role": s.role, "from_m": s.from_m, "to_m": s.to_m, "speed_m_s": s.speed_m_s,
                             "curve": s.curve, "rail": rail, "band": int(b),
                             "wavelength_mm": 1e3 * ev.band_table[b, 0],
                             "calibration": bool(ev.calibration[si]),
                             "ref_db": 10 * math.log10(rv / 1e-12) if rv > 0 else math.nan,
                             "ref_snr_db": 10 * math.log10(rv / nv) if nv > 0 and rv > 0 else math.inf})
    return pd.DataFrame(rows)


def reference_on_grid(reference: pd.DataFrame, dx: float = 1e-3) -> dict:
    """Rail → (x, roughness [m]) on a uniform grid from a ``chainage_m, rail, roughness_m`` table."""
    out = {}
    for rail, g in reference.groupby("rail"):
        x = g["chainage_m"].to_numpy(float)
        r = g["roughness_m"].to_numpy(float)
        if x.size < 10:
            continue
        xs = np.arange(x[0], x[-1], dx)
        out[str(rail)] = (xs, np.interp(xs, x, r))
    if not out:
        raise ReferenceCoverageError("the reference holds no rail with at least 10 samples")
    return out
