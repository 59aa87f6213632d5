"""Exception classes of the field diagnosis: each names the file, run, stretch or parameter at fault."""

from __future__ import annotations

from estimator.errors import EstimatorError

__all__ = ["FieldDiagnosisError", "ReferenceCoverageError", "DiagnosisConfigError", "CalibrationFileError"]


class FieldDiagnosisError(EstimatorError):
    """A field diagnosis that cannot be made (no usable run, no calibration or validation evidence)."""


class ReferenceCoverageError(FieldDiagnosisError):
    """The reference (trolley) does not cover the site, or no run can be aligned to it; names file and stretch."""


class DiagnosisConfigError(FieldDiagnosisError):
    """An option of the field diagnosis outside its range (names it, the range and the value)."""


class CalibrationFileError(FieldDiagnosisError):
    """A calibrated-model folder that cannot be read (missing file, other format, newer version)."""
