"""ISO 3095:2013 rail roughness limit (Fig. 2, 6.2.5), one-third-octave levels in dB re 1 µm.

The same 22 values are the reference-track limit of EN 15610 and of the
noise TSI; EN 15610 spectra are drawn beside it (thesis §4.3 uses EN 13231-3
indexes; the spectra are the acoustic view of the same roughness).
"""

from __future__ import annotations

import numpy as np

__all__ = ["ISO3095_LIMIT_DB", "iso3095_limit_db"]

#: nominal one-third-octave wavelength [m] -> limit level [dB re 1 µm]
ISO3095_LIMIT_DB: dict[float, float] = {
    0.4: 17.1, 0.315: 15.0, 0.25: 13.0, 0.2: 11.0, 0.16: 9.0, 0.125: 7.0, 0.1: 4.9, 0.08: 2.9, 0.063: 0.9,
    0.05: -1.1, 0.04: -3.2, 0.0315: -5.0, 0.025: -5.6, 0.02: -6.2, 0.016: -6.8, 0.0125: -7.4, 0.01: -8.0,
    0.008: -8.6, 0.0063: -9.2, 0.005: -9.8, 0.004: -10.4, 0.00315: -11.0,
}


def iso3095_limit_db(wavelength_m) -> np.ndarray:
    """Limit at one-third-octave wavelengths (nominal or exact ``10^(-k/10)`` m); NaN outside the table."""
    lam = np.atleast_1d(np.asarray(wavelength_m, float))
    nominal = np.array(sorted(ISO3095_LIMIT_DB))
    out = np.full(lam.shape, np.nan)
    for i, w in enumerate(lam):
        j = int(np.argmin(np.abs(np.log(nominal / w))))
        if abs(np.log(nominal[j] / w)) < 0.05:
            out[i] = ISO3095_LIMIT_DB[float(nominal[j])]
    return out
