"""Field diagnosis — compare the estimate with a reference, find the missing physical effect, add it.

The field counterpart of the lab diagnosis (:mod:`receptance.diagnosis`), with its criterion
(``BIC = N ln E² + k ln N``, ΔBIC < −10, E down ≥ 10 %, above 1.2 × the noise floor, plausible values) and
one more rule: an effect is accepted only if it also lowers the error on validation stretches the fit did
not see (other sections, other days).

Modules: :mod:`~estimator.diagnosis.evidence` (each run's acceleration spectra per segment, computed once;
the reference's band variances), :mod:`~estimator.diagnosis.transfer` (the wheelset's receptances once,
the transfer function per candidate in milliseconds), :mod:`~estimator.diagnosis.state` (the accepted
effects in physical terms, and their realisation in the estimator), :mod:`~estimator.diagnosis.effects`
(the catalogue), :mod:`~estimator.diagnosis.model` (band levels for any state),
:mod:`~estimator.diagnosis.diagnose` (fit, rank, accept), :mod:`~estimator.diagnosis.compare` (where the
estimate fails), :mod:`~estimator.diagnosis.workflow` (runs + trolley → result),
:mod:`~estimator.diagnosis.report`, :mod:`~estimator.diagnosis.calibration` (the calibrated model on disk).
"""

from estimator.diagnosis.calibration import calibrated_field_model, load_calibration, save_calibration
from estimator.diagnosis.config import DiagnosisConfig
from estimator.diagnosis.diagnose import CandidateFit, FieldDiagnosis, diagnose_field
from estimator.diagnosis.effects import (ContactAngle, ContactStiffness, DiscreteSupports, FieldEffect, Parameter,
                                        SensorOffset, TrackformEffect, TrackformStretch, WheelRoughness,
                                        catalogue)
from estimator.diagnosis.errors import (CalibrationFileError, DiagnosisConfigError, FieldDiagnosisError,
                                        ReferenceCoverageError)
from estimator.diagnosis.state import FieldState, field_model_for, run_for
from estimator.diagnosis.workflow import FieldDiagnosisResult, run_field_diagnosis

__all__ = ["DiagnosisConfig", "CandidateFit", "FieldDiagnosis", "diagnose_field", "FieldEffect", "Parameter",
           "TrackformEffect", "TrackformStretch",
           "DiscreteSupports", "ContactAngle", "SensorOffset", "ContactStiffness",
           "WheelRoughness", "catalogue", "FieldState", "field_model_for", "run_for", "FieldDiagnosisResult",
           "run_field_diagnosis", "calibrated_field_model", "load_calibration", "save_calibration",
           "CalibrationFileError", "DiagnosisConfigError", "FieldDiagnosisError", "ReferenceCoverageError"]
