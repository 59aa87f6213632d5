"""Rail roughness standards: EN 13231-3 band indexes, EN 15610 one-third-octave spectra, ISO 3095 limit."""

from estimator.standards.en13231 import BandIndexes, band_filter, band_indexes, exceedance, moving_rms, pk_pk
from estimator.standards.en15610 import RoughnessSpectrum, roughness_spectrum, third_octave_bands
from estimator.standards.iso3095 import ISO3095_LIMIT_DB, iso3095_limit_db

__all__ = ["BandIndexes", "band_filter", "band_indexes", "exceedance", "moving_rms", "pk_pk", "RoughnessSpectrum",
           "roughness_spectrum", "third_octave_bands", "ISO3095_LIMIT_DB", "iso3095_limit_db"]
