"""receptance — hybrid modal model, track and contact receptances, measurement transfer functions.

Role in the data flow (``shared/DESIGN.md``): combines FE shapes from
:mod:`fem_import` with the test frequencies and damping from :mod:`ema`
(thesis §2.3), adds physical effects (residuals, primary suspension,
bearings, ...) as structural modifications, computes the Timoshenko track
receptance (§2.4) and the Hertzian contact stiffness, and forms the
half-wheelset, full vertical and full vertical+lateral transfer functions
(eqs. 2.6, 2.11, 2.22) that :mod:`estimator` inverts.

Three rooms: the model (:mod:`~receptance.modal_model`, :mod:`~receptance.hybrid`,
:mod:`~receptance.modification`, :mod:`~receptance.effect_modifications`,
:mod:`~receptance.model_io`, :mod:`~receptance.wheelset_description`); the
track, contact and transfer physics (:mod:`~receptance.track`,
:mod:`~receptance.contact`, :mod:`~receptance.transfer`,
:mod:`~receptance.robustness`); and the diagnosis against the lab's
measurements (:mod:`receptance.diagnosis`).  ``receptance.compare``,
``receptance.diagnose``, ``receptance.effects``, ``receptance.report`` and
``receptance.plot_compare`` are the diagnosis modules under their old names.
"""

# the old module names of the diagnosis (receptance.compare, receptance.diagnose) are loaded first, so that the
# functions bound below are not replaced by those modules when someone imports them later
from . import compare as _compare_module, diagnose as _diagnose_module  # noqa: F401
from .diagnosis import (EFFECTS, Comparison, ComparisonError, Diagnosis, DiagnosisError, Effect, EffectFit,
                        EffectNotApplicable, Measurement, Parameter, band_errors, compare, compare_frf, diagnose,
                        fit_effect, frf_errors, h1_variance, misfit, rank_effects, register_effect)
from .contact import ContactParameters, HertzContact, hertz_compliance, hertz_contact, hertz_stiffness
from .dofs import THESIS_DOFS, Dof, DofError, Point, dofs_from_channels, parse_dof, read_points, shifted_point
from .frame import RailwayFrame, check_railway_frame, railway_frame, to_railway_frame
from .hybrid import hybrid_model, read_pairing_table
from .modal_model import ModalModel, ModelError
from .model_io import ModelFileError, load_model, save_model
from .modification import (MODIFICATIONS, ROLES, GroundSprings, Modification, ModificationError, PointMass,
                           PrimarySuspension, RigidBody, Spring, Term, register)
from .wheelset_description import DescriptionError, WheelsetDescription, read_description
from .pole_residue import PoleResidues
from .robustness import RobustnessResult, perturbation_factors, perturbed_models, robustness_study
from .track import track_frf, track_receptance
from .trackform import Trackform, TrackformError, load_trackform
from .transfer import (FrequencyAxisError, MeasurementTransfer, MissingDOFError, TransferModelError,
                       acceleration_to_irregularity, contact_normals, full_vertical_transfer, half_wheelset_transfer,
                       irregularity_to_acceleration, vertical_lateral_transfer)

__all__ = [
    "Comparison", "ComparisonError", "band_errors", "compare", "compare_frf", "frf_errors", "h1_variance",
    "Diagnosis", "DiagnosisError", "EffectFit", "EffectNotApplicable", "Measurement", "diagnose", "fit_effect",
    "misfit", "rank_effects", "EFFECTS", "Effect", "Parameter", "register_effect",
    "DescriptionError", "WheelsetDescription", "read_description",
    "ContactParameters", "HertzContact", "hertz_compliance", "hertz_contact", "hertz_stiffness",
    "THESIS_DOFS", "Dof", "DofError", "Point", "dofs_from_channels", "parse_dof", "read_points", "shifted_point",
    "RailwayFrame", "check_railway_frame", "railway_frame", "to_railway_frame",
    "hybrid_model", "read_pairing_table",
    "ModalModel", "ModelError",
    "ModelFileError", "load_model", "save_model",
    "MODIFICATIONS", "ROLES", "GroundSprings", "Modification", "ModificationError", "PointMass", "PrimarySuspension",
    "RigidBody", "Spring", "Term", "register",
    "PoleResidues",
    "RobustnessResult", "perturbation_factors", "perturbed_models", "robustness_study",
    "track_frf", "track_receptance",
    "Trackform", "TrackformError", "load_trackform",
    "FrequencyAxisError", "MeasurementTransfer", "MissingDOFError", "TransferModelError",
    "acceleration_to_irregularity", "contact_normals", "full_vertical_transfer", "half_wheelset_transfer",
    "irregularity_to_acceleration", "vertical_lateral_transfer",
]
