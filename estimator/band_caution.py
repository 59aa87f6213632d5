"""Where a band index rests on weak ground: the contact filter's correction and the pinned–pinned resonance.

Two things make an EN 13231-3 band's level less certain than the rest, and
an analyst should see them beside the number rather than find out against a
trolley:

* **The contact filter's correction.** The estimate is of the roughness the
  wheel feels, averaged over its Hertz patch (:mod:`estimator.contact_filter`);
  the rail's own roughness is that divided by ``H(κ) = 2 J₁(κa)/(κa)``. Where
  the correction exceeds :data:`CONTACT_CAUTION_DB` the band's level depends on
  the contact patch's semi-axis ``a`` (wheel load, wheel and rail profiles) as
  much as on the measurement; where the patch has wiped the wavelength out
  (``H`` below the correction's cap) the correction stops and the level is a
  lower bound of the rail's there.
* **The track's pinned–pinned resonance.** With the rail on continuous
  supports (thesis eq. 2.33, the default ``trackform_supports``) the track
  model has no pinned–pinned resonance; a real track's receptance peaks and
  dips there with the wheel's position in the bay (Thompson, *Railway Noise
  and Vibration*, 2009, §3.5), and the inversion through the continuous
  model misreads the band that holds it at the run's speed. Measured on the
  virtual line (``nominal``, curve 1 at 9.1 m/s, one 2.5 kHz run, vertical
  model, leading wheelset; pinned–pinned 647 Hz): the 10–30 mm band
  (303–910 Hz there) reads +2.9 / +3.3 dB against the true rail (rails L / R;
  30–100 mm +1.3 / +0.2 dB, 100–300 mm +0.6 / +0.3 dB). Without the
  contact-filter correction the one-third octaves of 16–20 mm (455–569 Hz)
  still read +0.1…+2.9 dB above the truth filtered by the line's own patch,
  and 12.5 mm (728 Hz) +6…+9 dB: the inversion itself over-reads around the
  resonance, and the correction adds to it. The track model with discrete
  supports at one position in the bay (``trackform_supports = "discrete"``)
  reads +6.9 / +6.7 dB there, worse: the wheel passes every position. A
  band is flagged rather than corrected.

:func:`band_cautions` returns, per band and stretch, the largest correction,
whether it was capped, the pinned–pinned frequency inside the band and a
sentence for the report; the estimator adds them to its band index table
(:attr:`estimator.results.FieldEstimate.indexes`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Sequence

import numpy as np

from estimator.contact_filter import MAX_GAIN_DB, contact_filter_response, contact_gain

__all__ = ["CONTACT_CAUTION_DB", "BandCaution", "band_cautions"]

#: a band whose contact-filter correction exceeds this [dB] depends on the contact patch's size
CONTACT_CAUTION_DB = 3.0


@dataclass(frozen=True)
class BandCaution:
    """What weakens one band's level on one stretch.

    Attributes
    ----------
    contact_correction_db : float
        Largest contact-filter correction applied over the band [dB] (0 without the correction).
    contact_capped : bool
        Part of the band lies where the patch wiped the roughness out: the correction was capped there.
    pinned_pinned_hz : float
        The track's pinned–pinned frequency inside the band's frequencies at the stretch's speeds (NaN: none,
        or the supports are modelled discretely).
    text : str
        One sentence per caution ("" when none).
    """

    contact_correction_db: float
    contact_capped: bool
    pinned_pinned_hz: float
    text: str


def band_cautions(band_mm: tuple[float, float], speeds_m_s: np.ndarray, inversion_band_hz: tuple[float, float],
                  semi_axis_m: float, pinned_pinned_hz: Sequence[float], *, contact_filter: bool = True,
                  discrete_supports: bool = False) -> BandCaution:
    """The cautions of one EN 13231-3 band on one stretch (module docstring).

    Parameters
    ----------
    band_mm : (float, float)
        The band's wavelengths [mm].
    speeds_m_s : ndarray
        The wheelset's speed over the stretch (NaN ignored).
    inversion_band_hz : (float, float)
        Frequencies the inversion covers.
    semi_axis_m : float
        Contact patch semi-axis along the rolling direction [m] (thesis eq. 2.5).
    pinned_pinned_hz : sequence of float
        Pinned–pinned frequencies of the trackforms on the stretch (:func:`receptance.track.pinned_pinned_frequency`).
    contact_filter : bool
        Whether the estimate undid the contact filter.
    discrete_supports : bool
        Whether the track model has discrete supports (then it holds the pinned–pinned resonance).
    """
    lam_lo, lam_hi = band_mm[0] * 1e-3, band_mm[1] * 1e-3
    correction_db, capped, contact_notes = _contact_part(float(band_mm[0]), float(band_mm[1]), float(semi_axis_m),
                                                         bool(contact_filter))
    notes = list(contact_notes)
    pp = math.nan
    v = np.asarray(speeds_m_s, float)
    v = np.abs(v[np.isfinite(v) & (v != 0)])
    if not discrete_supports and v.size:
        f_a = max(float(v.min()) / lam_hi, inversion_band_hz[0])
        f_b = min(float(v.max()) / lam_lo, inversion_band_hz[1])
        inside = [f for f in pinned_pinned_hz if math.isfinite(f) and f_a <= f <= f_b]
        if inside:
            pp = float(min(inside))
            notes.append(f"the track's pinned-pinned resonance ({pp:.0f} Hz) lies in the band at this speed, where "
                         f"the track model on continuous supports is least right: expect the level to read a few dB "
                         f"high")
    return BandCaution(correction_db, capped, pp, "; ".join(notes))


@lru_cache(maxsize=256)
def _contact_part(lam_lo_mm: float, lam_hi_mm: float, semi_axis_m: float, contact_filter: bool
                  ) -> tuple[float, bool, tuple[str, ...]]:
    """The contact filter's caution of a band: largest correction [dB], capped, sentences (one band, one patch:
    the same on every stretch, so computed once)."""
    if not contact_filter:
        return 0.0, False, ()
    lam_lo, lam_hi = lam_lo_mm * 1e-3, lam_hi_mm * 1e-3
    notes = []
    correction_db = float(20 * np.log10(contact_gain(np.array([1 / lam_hi, 1 / lam_lo]), semi_axis_m,
                                                     MAX_GAIN_DB)).max())
    # contact_gain returns exactly the cap where it stopped correcting
    capped = correction_db >= MAX_GAIN_DB - 1e-9
    if correction_db > CONTACT_CAUTION_DB:
        notes.append(f"the contact-filter correction reaches +{correction_db:.1f} dB: the level depends on the "
                     f"contact patch (a = {1e3 * semi_axis_m:.2f} mm) as much as on the measurement")
    if capped:
        notes.append(f"wavelengths under {1e3 * _capped_below(semi_axis_m):.0f} mm are shorter than the patch lets "
                     f"the wheel feel: the correction stops at +{MAX_GAIN_DB:g} dB there and their level is a lower "
                     f"bound")
    return correction_db, capped, tuple(notes)


def _capped_below(semi_axis_m: float) -> float:
    """Longest wavelength [m] at which the correction is capped (the filter first falls to the cap)."""
    ka = np.linspace(0.01, 3.8, 3800)
    h = contact_filter_response(ka / (2 * math.pi * semi_axis_m), semi_axis_m)
    past = np.flatnonzero(h < 10 ** (-MAX_GAIN_DB / 20))
    ka_cap = float(ka[past[0]]) if past.size else 3.8
    return 2 * math.pi * semi_axis_m / ka_cap
