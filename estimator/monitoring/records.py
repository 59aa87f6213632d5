"""What the monitoring keeps of one run: band indexes per chainage window on aligned chainage, spectra, QC.

A single-run estimate (:class:`~estimator.results.FieldEstimate`) holds each
wheelset's EN 13231-3 peak-to-peak profile along its own chainage grid.
:func:`window_table` reads them on the aligned chainage and reduces each
band, rail and wheelset to one value per chainage window of ``window_m``: the
**energy mean** of the peak-to-peak amplitude over the window's valid samples,
``sqrt(mean(pk²))`` (the moving RMS of eq. 4.1 is an energy measure; its
square adds), with the window's valid share and mean speed. Windows are
fixed on the line (``[k·window_m, (k+1)·window_m)``), so every run and day
fills the same ones.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np
import pandas as pd
from scipy import fft as sfft

from estimator.monitoring.config import band_label
from estimator.standards.en13231 import band_filter

__all__ = ["RunInfo", "Sections", "bin_windows", "window_table", "spectra_rows", "toolkit_version", "file_hash", "config_hash"]


def toolkit_version() -> str:
    """The installed railmodal version."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("railmodal")
    except PackageNotFoundError:  # running from a source tree that is not installed
        return "unknown"


def file_hash(path) -> str:
    """SHA-256 of a file (first 16 hex digits): the model version recorded on every row."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()[:16]


def config_hash(*parts: Mapping) -> str:
    """Short hash of configuration dictionaries (JSON, keys sorted)."""
    return hashlib.sha256(json.dumps(list(parts), sort_keys=True, default=str).encode()).hexdigest()[:12]


@dataclass(frozen=True)
class RunInfo:
    """Identity of the rows one run produces (recorded on each of them)."""

    line: str
    model_hash: str
    model_file: str
    toolkit_version: str
    config_hash: str


@dataclass(frozen=True, eq=False)
class Sections:
    """The line's named sections (``line.json``), or fixed-length stretches ``a-b m`` when it has none."""

    ids: tuple[str, ...]
    from_m: np.ndarray
    to_m: np.ndarray
    length_m: float = 100.0

    @staticmethod
    def of(line, length_m: float = 100.0) -> "Sections":
        secs = tuple(getattr(line, "sections", ()) or ()) if line is not None else ()
        if secs:
            s = sorted(secs, key=lambda s: s.from_m)
            return Sections(tuple(x.id for x in s), np.array([x.from_m for x in s]), np.array([x.to_m for x in s]),
                            length_m)
        return Sections((), np.zeros(0), np.zeros(0), length_m)

    def at(self, x) -> np.ndarray:
        """Section id at each chainage (fixed-length stretch name outside the named sections)."""
        x = np.asarray(x, float)
        out = np.empty(x.shape, dtype=object)
        j = np.searchsorted(self.from_m, x, side="right") - 1
        inside = (j >= 0) & (x <= self.to_m[np.clip(j, 0, None)]) if self.from_m.size else np.zeros(x.shape, bool)
        ids = np.array(self.ids, dtype=object)
        if inside.any():
            out[inside] = ids[j[inside]]
        if (~inside).any():
            a = np.floor(x[~inside] / self.length_m) * self.length_m
            out[~inside] = [f"{v:g}-{v + self.length_m:g}m" for v in a]
        return out

    def extent(self, section: str) -> tuple[float, float]:
        if section in self.ids:
            i = self.ids.index(section)
            return float(self.from_m[i]), float(self.to_m[i])
        try:
            a, b = section.rstrip("m").split("-")
            return float(a), float(b)
        except ValueError:
            return math.nan, math.nan


def bin_windows(xa: np.ndarray, pk: np.ndarray, dx: float, bands, rails, window_m: float,
                speed: np.ndarray | None = None, filtered: np.ndarray | None = None) -> pd.DataFrame:
    """Energy mean of peak-to-peak profiles per fixed chainage window (module docstring).

    Parameters
    ----------
    xa : ndarray (M,)
        Chainage of each sample (aligned) [m].
    pk : ndarray (n_bands, n_rails, M)
        Peak-to-peak amplitude [m], NaN where masked or unresolved.
    dx : float
        Sample step [m] (the window's expected sample count is ``window_m/dx``).
    bands, rails : sequences
    window_m : float
    speed : ndarray (M,), optional
    filtered : ndarray (n_bands, 2, M), optional
        Band-filtered profiles of two rails, for ``lr_correlation``.

    Returns
    -------
    pandas.DataFrame
        ``rail, band_mm, window_m, pk_pk_um, valid_share, speed_m_s, lr_correlation``.
    """
    cols = ["rail", "band_mm", "window_m", "pk_pk_um", "valid_share", "speed_m_s", "lr_correlation"]
    fin = np.isfinite(xa)
    if not fin.any():
        return pd.DataFrame(columns=cols)
    k = np.floor(np.where(fin, xa, np.nanmin(xa)) / window_m).astype(np.int64)
    k0 = int(k[fin].min())
    kk = k - k0
    nb = int(kk[fin].max()) + 1
    expected = window_m / dx
    if speed is not None:
        vok = np.isfinite(speed) & fin
        vsum = np.bincount(kk[vok], weights=speed[vok], minlength=nb)
        vcnt = np.bincount(kk[vok], minlength=nb)
    frames = []
    for b, band in enumerate(bands):
        lr = _lr_correlation(np.where(fin, filtered[b], np.nan), kk, nb) \
            if filtered is not None and len(rails) == 2 else np.full(nb, np.nan)
        for i, rail in enumerate(rails):
            v = pk[b, i]
            ok = np.isfinite(v) & fin
            if not ok.any():
                continue
            s_ = np.bincount(kk[ok], weights=v[ok] ** 2, minlength=nb)
            n = np.bincount(kk[ok], minlength=nb)
            idx = np.flatnonzero(n > 0)
            if speed is not None:
                with np.errstate(invalid="ignore", divide="ignore"):
                    sp = np.where(vcnt[idx] > 0, vsum[idx] / vcnt[idx], np.nan)
            else:
                sp = np.full(idx.size, np.nan)
            frames.append(pd.DataFrame({
                "rail": rail, "band_mm": band_label(band), "window_m": (idx + k0) * window_m,
                "pk_pk_um": np.sqrt(s_[idx] / n[idx]) * 1e6, "valid_share": np.minimum(n[idx] / expected, 1.0),
                "speed_m_s": sp, "lr_correlation": lr[idx]}))
    if not frames:
        return pd.DataFrame(columns=cols)
    return pd.concat(frames, ignore_index=True)[cols]


def window_table(estimate, model: str, alignments: Mapping | None, window_m: float, *,
                 lr_correlation: bool = True) -> pd.DataFrame:
    """Band peak-to-peak per chainage window, wheelset and rail of one estimate (module docstring).

    Parameters
    ----------
    estimate : FieldEstimate
    model : str
        Transfer-function model whose profiles are read.
    alignments : mapping wheelset → Alignment, optional
        Chainage corrections (none: the estimate's chainage).
    window_m : float
    lr_correlation : bool
        Compute the ``lr_correlation`` column (NaN when False: the uncertainty variants, which do not keep it,
        skip the band filtering it needs).

    Returns
    -------
    pandas.DataFrame
        ``wheelset, role, rail, band_mm, window_m`` (start of the window), ``pk_pk_um, valid_share,
        speed_m_s, lr_correlation`` (zero-lag correlation of the two rails' band-filtered estimates over the
        window: the cross-talk check of :mod:`estimator.monitoring.consistency`).
    """
    frames = []
    for (w, kind), p in estimate.profiles.items():
        if kind != model:
            continue
        x = p.chainage_m
        xa = alignments[w].apply(x) if alignments and w in alignments else x
        filtered = None
        if lr_correlation and len(p.rails) == 2:
            # the rails' band-filtered estimates (where the band is resolved) for the cross-talk check; one FFT
            # serves every band (padded for the longest wavelength)
            bad = ~np.isfinite(p.rail)
            nfft = sfft.next_fast_len(x.size + int(math.ceil(2e-3 * max(b[1] for b in p.indexes.bands_mm) / p.dx)))
            spec = (sfft.rfft(np.where(bad, 0.0, p.rail), nfft, axis=-1), nfft)
            filtered = np.stack([np.where(p.resolved[b], band_filter(p.rail, p.dx, band, spectrum=spec), np.nan)
                                 for b, band in enumerate(p.indexes.bands_mm)])
        t = bin_windows(xa, p.indexes.pk_pk, p.dx, p.indexes.bands_mm, p.rails, window_m, p.speed_m_s, filtered)
        frames.append(t.assign(wheelset=w, role=p.role))
    cols = ["wheelset", "role", "rail", "band_mm", "window_m", "pk_pk_um", "valid_share", "speed_m_s",
            "lr_correlation"]
    if not frames:
        return pd.DataFrame(columns=cols)
    return pd.concat(frames, ignore_index=True)[cols]


def _lr_correlation(z: np.ndarray, kk: np.ndarray, nb: int) -> np.ndarray:
    """Zero-lag correlation of the two rails' band-filtered estimates per window (NaN samples skipped)."""
    ok = np.isfinite(z).all(axis=0)
    if not ok.any():
        return np.full(nb, np.nan)
    a, b, k = z[0, ok], z[1, ok], kk[ok]
    ab = np.bincount(k, weights=a * b, minlength=nb)
    aa = np.bincount(k, weights=a * a, minlength=nb)
    bb = np.bincount(k, weights=b * b, minlength=nb)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where((aa > 0) & (bb > 0), ab / np.sqrt(aa * bb), np.nan)


def spectra_rows(estimate, model: str, sections: Sections) -> pd.DataFrame:
    """EN 15610 levels of the estimate's stretches for one model, each with the section of its midpoint."""
    sp = estimate.spectra
    if sp is None or len(sp) == 0:
        return pd.DataFrame()
    sp = sp[sp["model"] == model].copy()
    if sp.empty:
        return sp
    sp["section"] = sections.at(0.5 * (sp["from_m"].to_numpy(float) + sp["to_m"].to_numpy(float)))
    keep = ["wheelset", "role", "stretch", "section", "rail", "from_m", "to_m", "n_segments", "band", "wavelength_m",
            "level_db", "iso3095_limit_db"]
    return sp[[c for c in keep if c in sp.columns]].reset_index(drop=True)
