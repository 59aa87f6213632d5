"""receptance — hybrid modal model, track and contact receptances, measurement transfer functions.

Role in the data flow (``shared/DESIGN.md``): combines FE shapes from
:mod:`fem_import` with the test frequencies and damping from :mod:`ema`
(thesis §2.3), adds physical effects (residuals, primary suspension,
bearings, ...) as structural modifications, computes the Timoshenko track
receptance (§2.4) and the Hertzian contact stiffness, and forms the
half-wheelset, full vertical and full vertical+lateral transfer functions
(eqs. 2.6, 2.11, 2.22) that :mod:`estimator` inverts.
"""

from .compare import Comparison, ComparisonError, band_errors, compare, compare_frf, frf_errors, h1_variance
from .diagnose import Diagnosis, EffectFit, Measurement, diagnose, fit_effect, misfit, rank_effects
from .effects import EFFECTS, Effect, Parameter, register_effect
from .contact import ContactParameters, HertzContact, hertz_compliance, hertz_contact, hertz_stiffness
from .dofs import THESIS_DOFS, Dof, DofError, Point, dofs_from_channels, parse_dof, read_points, shifted_point
from .hybrid import hybrid_model, read_pairing_table
from .modal_model import ModalModel, ModelError
from .model_io import ModelFileError, load_model, save_model
from .modification import (MODIFICATIONS, GroundSprings, Modification, ModificationError, PointMass,
                           PrimarySuspension, RigidBody, Spring, Term, register)
from .pole_residue import PoleResidues
from .robustness import RobustnessResult, perturbation_factors, perturbed_models, robustness_study
from .track import track_frf, track_receptance
from .trackform import Trackform, TrackformError, load_trackform
from .transfer import (FrequencyAxisError, MeasurementTransfer, MissingDOFError, TransferModelError,
                       acceleration_to_irregularity, contact_normals, full_vertical_transfer, half_wheelset_transfer,
                       irregularity_to_acceleration, vertical_lateral_transfer)

__all__ = [
    "Comparison", "ComparisonError", "band_errors", "compare", "compare_frf", "frf_errors", "h1_variance",
    "Diagnosis", "EffectFit", "Measurement", "diagnose", "fit_effect", "misfit", "rank_effects",
    "EFFECTS", "Effect", "Parameter", "register_effect",
    "ContactParameters", "HertzContact", "hertz_compliance", "hertz_contact", "hertz_stiffness",
    "THESIS_DOFS", "Dof", "DofError", "Point", "dofs_from_channels", "parse_dof", "read_points", "shifted_point",
    "hybrid_model", "read_pairing_table",
    "ModalModel", "ModelError",
    "ModelFileError", "load_model", "save_model",
    "MODIFICATIONS", "GroundSprings", "Modification", "ModificationError", "PointMass", "PrimarySuspension",
    "RigidBody", "Spring", "Term", "register",
    "PoleResidues",
    "RobustnessResult", "perturbation_factors", "perturbed_models", "robustness_study",
    "track_frf", "track_receptance",
    "Trackform", "TrackformError", "load_trackform",
    "FrequencyAxisError", "MeasurementTransfer", "MissingDOFError", "TransferModelError",
    "acceleration_to_irregularity", "contact_normals", "full_vertical_transfer", "half_wheelset_transfer",
    "irregularity_to_acceleration", "vertical_lateral_transfer",
]
