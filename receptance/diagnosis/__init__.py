"""receptance.diagnosis — the model against the lab's measurements: compare, diagnose, add the missing effects.

One of the three rooms of :mod:`receptance` (the model; the track, contact
and transfer physics; the diagnosis):

* :mod:`~receptance.diagnosis.compare` — model against measured FRFs, the
  figure of merit ``E`` and its noise floor, where the error sits;
* :mod:`~receptance.diagnosis.effects` — the catalogue of physical effects,
  attached by geometry (:mod:`~receptance.diagnosis.geometry`) with what the
  FE cannot tell from the wheelset description
  (:mod:`receptance.wheelset_description`);
* :mod:`~receptance.diagnosis.misfit`, :mod:`~receptance.diagnosis.fitting`,
  :mod:`~receptance.diagnosis.diagnose` — fitting every candidate (in
  parallel processes), the criterion, effect after effect;
* :mod:`~receptance.diagnosis.noise` — the noise floor of FRF files without
  coherence;
* :mod:`~receptance.diagnosis.workflow` — the whole lab workflow (identify →
  merge → pair → hybrid model → compare → diagnose → add effects) as one
  function with a documented result, which ``railmodal lab diagnose`` calls;
* :mod:`~receptance.diagnosis.report`, :mod:`~receptance.diagnosis.plot_compare`
  — the HTML report and the figures (matplotlib is imported only there).
"""

from .compare import Comparison, ComparisonError, band_errors, compare, compare_frf, frf_errors, h1_variance
from .diagnose import Diagnosis, RoundResult, diagnose, rank_effects
from .effects import EFFECTS, Attachment, Effect, Parameter, register_effect
from .errors import DiagnosisError, EffectNotApplicable
from .fitting import EffectFit, fit_effect
from .misfit import Measurement, Misfit, misfit
from .noise import estimate_averages, frf_noise_variance
from .workflow import LabDiagnosis, SetupFiles, run_lab_diagnosis

__all__ = [
    "Comparison", "ComparisonError", "band_errors", "compare", "compare_frf", "frf_errors", "h1_variance",
    "Diagnosis", "RoundResult", "diagnose", "rank_effects",
    "EFFECTS", "Attachment", "Effect", "Parameter", "register_effect",
    "DiagnosisError", "EffectNotApplicable",
    "EffectFit", "fit_effect",
    "Measurement", "Misfit", "misfit",
    "estimate_averages", "frf_noise_variance",
    "LabDiagnosis", "SetupFiles", "run_lab_diagnosis",
]
