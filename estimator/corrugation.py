"""Corrugation type: the dominant wavelength and the speed give a frequency, matched to the model's resonances.

Thesis §1.1 (Table 1.1, eq. 1.1 ``λ = v/f``): the wavelength-fixing
mechanism works at a fixed *frequency*; the corrugation's wavelength is that
frequency's at the traffic's speed. For each corrugated stretch and rail the
dominant wavelength (peak of the averaged narrow-band spectrum inside the
corrugated band) and the stretch's speed give ``f = v/λ``, compared with the
resonances of the same models the estimate is made with (a stretch above the
thresholds without a prominent peak is broadband roughness, not corrugation:
no mechanism is named, :func:`spectral_peak`):

* **P2** — the wheel bouncing on the track's contact stiffness: the peak of
  the contact force per unit roughness ``1/|A_W,33 + A_R,Z + 1/K_H|`` (the
  half-wheelset model's dynamic compliance, thesis eq. 2.5) between 20 and
  250 Hz (thesis eq. 1.3 is its one-mass estimate);
* **wheelset torsion** — the hybrid model's modes whose wheels turn about
  the axle (the contact points' longitudinal displacements carry most of the
  shape while the axleboxes stay put); the first is the "other P2 /
  torsion" mechanism, the second the rutting one (thesis §1.1.2);
* **pinned–pinned** — the rail span between supports (exact Timoshenko
  value of :func:`receptance.track.pinned_pinned_frequency`).

The mechanism named is the nearest (in log frequency) within ``tolerance``;
otherwise the report says none matches (Table 1.1's "trackform-specific"
or an unmodelled mechanism) and gives the nearest.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from estimator.standards.en15610 import detrend_rows, segments_of
from receptance.track import pinned_pinned_frequency
from receptance.transfer import half_wheelset_transfer

__all__ = ["Resonances", "model_resonances", "classify", "TABLE_1_1", "dominant_wavelength", "spectral_peak",
           "MIN_PROMINENCE_DB", "wheelset_agreement", "CURVE_DISAGREEMENT_HINT"]

#: thesis Table 1.1: type, mechanism, typical frequency range [Hz], damage mechanism
TABLE_1_1 = (
    ("pinned-pinned ('roaring rails')", "pinned-pinned resonance", (400.0, 1200.0), "wear"),
    ("rutting", "second torsional resonance of the wheelset", (250.0, 400.0), "wear"),
    ("heavy haul / light rail / other P2", "P2 resonance", (50.0, 100.0), "plastic flow / bending / wear"),
    ("other P2 resonance (with torsion)", "first torsional resonance near P2", (50.0, 150.0), "wear"),
    ("trackform-specific", "trackform resonance", (math.nan, math.nan), "wear"),
)


@dataclass(frozen=True)
class Resonances:
    """Frequencies [Hz] of the candidate wavelength-fixing mechanisms of one wheelset on one trackform."""

    p2_hz: float
    torsion_hz: tuple[float, ...]
    pinned_pinned_hz: float

    def candidates(self) -> list[tuple[str, float]]:
        out = [("P2 resonance", self.p2_hz)]
        names = ("first wheelset torsion (other P2 / torsion)", "second wheelset torsion (rutting)")
        out += [(n, f) for n, f in zip(names, self.torsion_hz)]
        out.append(("pinned-pinned resonance", self.pinned_pinned_hz))
        return [(n, f) for n, f in out if np.isfinite(f)]


def _torsional_modes(model) -> tuple[float, ...]:
    """Frequencies of the model's torsional modes (first two): the wheels turn about the axle.

    A mode is torsional when the longitudinal (x) displacements of the two contact points carry more than
    60 % of the contact points' motion while the axleboxes, on the axle's axis, hardly move along x (less
    than a tenth of the contact points: not a bending of the axle in the horizontal plane).
    """
    try:
        rows = model.rows(["contact_L:x", "contact_R:x", "contact_L:y", "contact_R:y", "contact_L:z", "contact_R:z",
                           "axlebox_L:x", "axlebox_R:x"])
    except Exception:  # noqa: BLE001 - a model without these DOFs has no torsion to offer
        return ()
    m = len(model)
    phi = rows[:, :m]
    out = []
    for j in np.argsort(model.freqs_hz):
        f = float(model.freqs_hz[j])
        if f < 20:
            continue
        cx = float(phi[0, j] ** 2 + phi[1, j] ** 2)
        total = float(np.sum(phi[:6, j] ** 2))
        ax = float(phi[6, j] ** 2 + phi[7, j] ** 2)
        if total > 0 and cx / total > 0.6 and ax < 0.1 * cx:
            if not out or f > 1.03 * out[-1]:  # one entry per degenerate / close pair
                out.append(f)
    return tuple(out[:2])


def model_resonances(model, trackform, contact_stiffness: float, track_frf_fn=None) -> Resonances:
    """P2, wheelset torsion and pinned–pinned frequencies (module docstring)."""
    from receptance.track import track_frf

    f = np.linspace(20.0, 250.0, 2301)
    mt = half_wheelset_transfer(model, f, side="L", track=(track_frf_fn or track_frf)(f, trackform),
                                contact_stiffness=contact_stiffness)
    D = np.abs(mt.dynamic_compliance.data[0, 0])
    p2 = float(f[int(np.argmin(D))])
    return Resonances(p2, _torsional_modes(model), pinned_pinned_frequency(trackform))


def classify(frequency_hz: float, resonances: Resonances, tolerance: float = 0.2) -> tuple[str, str, float]:
    """(mechanism named or "none within ±tol", nearest candidate, its frequency) for a corrugation frequency."""
    cands = resonances.candidates()
    if not cands or not np.isfinite(frequency_hz) or frequency_hz <= 0:
        return "unknown", "", math.nan
    dist = [abs(math.log(frequency_hz / f)) for _, f in cands]
    k = int(np.argmin(dist))
    name, f = cands[k]
    if dist[k] <= math.log1p(tolerance):
        return name, name, f
    return f"none within ±{100 * tolerance:.0f} % (trackform-specific or unmodelled)", name, f


#: a spectral peak this far above the stretch's broadband trend [dB] is a dominant wavelength (a corrugation)
MIN_PROMINENCE_DB = 6.0


def spectral_peak(profile: np.ndarray, dx: float, band_mm: tuple[float, float], segment_m: float = 2.0
                  ) -> tuple[float, float]:
    """Dominant wavelength [m] of a stretch inside ``band_mm`` and its prominence [dB] over the broadband trend.

    Welch spectrum (Hann, ½ overlap, masked segments left out; segments of at least 20 of the band's longest
    wavelengths, so that its lines are 5 % apart at most). Rail roughness is broadband with a level
    rising with wavelength (ISO 3095's limit falls ~ 10 dB per decade of wavenumber), so the largest line of a
    band is its longest wavelength unless something periodic stands out: the trend — a straight line of
    ``lg S`` against ``lg k`` fitted (least squares) over the band and half an octave either side — is divided
    out first, and the peak's height over it is the prominence (a corrugation: ≥ :data:`MIN_PROMINENCE_DB`).
    """
    p = np.asarray(profile, float)
    # lines at most 1/20 of the band's lowest wavenumber apart: a corrugation (a few per cent wide) stands out
    n = int(round(max(segment_m, 20 * band_mm[1] * 1e-3) / dx))
    if p.size < n or n < 8:
        return math.nan, math.nan
    segs = segments_of(p, n)
    if segs.shape[0] == 0:
        return math.nan, math.nan
    from scipy.signal.windows import hann

    segs = detrend_rows(segs) * hann(n, sym=False)
    S = (np.abs(np.fft.rfft(segs, axis=1)) ** 2).mean(axis=0)
    k = np.fft.rfftfreq(n, dx)
    sel = (k >= 1e3 / band_mm[1]) & (k <= 1e3 / band_mm[0])
    wide = (k >= 1e3 / band_mm[1] / math.sqrt(2)) & (k <= 1e3 / band_mm[0] * math.sqrt(2)) & (S > 0)
    if not sel.any() or wide.sum() < 3:
        return math.nan, math.nan
    slope, icpt = np.polyfit(np.log10(k[wide]), np.log10(S[wide]), 1)
    rel = np.log10(np.maximum(S, 1e-300)) - (icpt + slope * np.log10(np.maximum(k, 1e-12)))
    i = np.flatnonzero(sel)[int(np.argmax(rel[sel]))]
    prominence = float(10 * rel[i])
    if 0 < i < S.size - 1:  # parabolic refinement on the log spectrum
        a, b, c = rel[i - 1:i + 2]
        den = a - 2 * b + c
        off = float(np.clip(0.5 * (a - c) / den, -0.5, 0.5)) if den < 0 else 0.0  # a maximum: den < 0
        return float(1.0 / (k[i] + off * (k[1] - k[0]))), prominence
    return float(1.0 / k[i]), prominence


def dominant_wavelength(profile: np.ndarray, dx: float, band_mm: tuple[float, float], segment_m: float = 2.0
                        ) -> float:
    """Wavelength [m] of the most prominent narrow-band line of a stretch inside ``band_mm`` (:func:`spectral_peak`)."""
    return spectral_peak(profile, dx, band_mm, segment_m)[0]


def table_1_1() -> pd.DataFrame:
    return pd.DataFrame(TABLE_1_1, columns=["type", "mechanism", "typical_hz", "damage"])


#: why the two wheelsets may disagree on a curve, and what calibrates it
CURVE_DISAGREEMENT_HINT = ("in a curve the leading wheelset's contact angles are the first suspect: calibrate them "
                           "with 'railmodal field diagnose' at a trolley-measured site")


def wheelset_agreement(corrugation: pd.DataFrame, model: str) -> pd.DataFrame:
    """The corrugated stretches the leading wheelset finds (one per rail and band: its most prominent spectral
    peak), each with what the trailing wheelset, a second and independent estimate of the same rail, says.

    Parameters
    ----------
    corrugation : DataFrame
        :attr:`FieldEstimate.corrugation` (``role, model, stretch, rail, band_mm, median_pk_pk_um,
        peak_prominence_db``, ...).
    model : str
        The transfer-function model to read.

    Returns
    -------
    DataFrame
        The leading wheelset's rows (sorted by rail and band) with ``trailing_pk_pk_um`` (NaN where the trailing
        wheelset is not above the threshold there), ``agree`` and ``note`` (empty, or why they may disagree: on a
        curve, :data:`CURVE_DISAGREEMENT_HINT`; stretch names ``curve <id>`` are :mod:`estimator.workflow`'s).
    """
    c = corrugation
    cols = list(c.columns) + ["trailing_pk_pk_um", "agree", "note"]
    if c.empty:
        return pd.DataFrame(columns=cols)
    lead = c[(c["role"] == "leading") & (c["model"] == model) & (c["peak_prominence_db"] >= MIN_PROMINENCE_DB)]
    best = lead.sort_values("peak_prominence_db", ascending=False).drop_duplicates(["rail", "band_mm"])
    trail = c[(c["role"] == "trailing") & (c["model"] == model)][["stretch", "rail", "band_mm", "median_pk_pk_um"]]
    out = best.merge(trail.rename(columns={"median_pk_pk_um": "trailing_pk_pk_um"}).drop_duplicates(
        ["stretch", "rail", "band_mm"]), on=["stretch", "rail", "band_mm"], how="left")
    out["agree"] = out["trailing_pk_pk_um"].notna()
    on_curve = out["stretch"].astype(str).str.startswith("curve ")
    out["note"] = np.where(~out["agree"] & on_curve, CURVE_DISAGREEMENT_HINT, "")
    return out.sort_values(["rail", "band_mm"]).reset_index(drop=True)[cols]
