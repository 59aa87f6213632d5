"""ema — experimental modal analysis of impact-hammer tests.

Role in the data flow (``shared/DESIGN.md``): reads the lab's hammer-test
files (UFF58 time histories + channel table), screens hits, estimates H1/H2
FRFs and coherence, identifies modes by LSCE with a stabilisation diagram and
LSFD shapes, merges the setups' mode lists and pairs the experimental modes
with the FE modes of :mod:`fem_import` by MAC. Its output (a mode set and the
measured FRFs) feeds :mod:`receptance`.
"""

# --- input side: channel tables, hammer-test reading, hit screening, FRF estimation ---
from .channels import ChannelTableError, read_channels, validate_channels
from .estimate import EstimationError, ForceWindow, auto_exp_decay, estimate_frf
from .frf import FRFShapeError, FrequencyResponse
from .hammer_io import (
    ChannelDirectionWarning,
    ChannelMismatchError,
    FunctionTypeError,
    HammerDataError,
    HammerTest,
    NonFiniteDataError,
    SamplingError,
    UFFReadError,
    UnknownFormatError,
    ZeroForceError,
    read_hammer,
)
from .screening import Rejection, Screening, ScreeningConfig, screen_hits
from .uff_frf import read_frf_uff

__all__ = [
    "ChannelTableError", "read_channels", "validate_channels",
    "EstimationError", "ForceWindow", "auto_exp_decay", "estimate_frf",
    "FRFShapeError", "FrequencyResponse",
    "ChannelDirectionWarning", "ChannelMismatchError", "FunctionTypeError", "HammerDataError", "HammerTest",
    "NonFiniteDataError", "SamplingError", "UFFReadError", "UnknownFormatError", "ZeroForceError", "read_hammer",
    "Rejection", "Screening", "ScreeningConfig", "screen_hits",
    "read_frf_uff",
]
# --- end of input side ---

# --- identification: LSCE, stabilisation, automatic pole selection, refinement, LSFD ---
from .identify import Identification, PoleCluster, RejectedPole, identify, select_poles, select_poles_at
from .lsce import IdentificationError, PoleSweep, lsce, zoom_impulse_response
from .lsfd import DEFAULT_RESIDUALS, LSFDResult, RefinedPoles, lsfd, mcf, mpc, mpd, refine_poles, synthesize
from .modeset import ModeSet
from .stabilisation import StabilisationDiagram, stabilisation_diagram

__all__ += [
    "Identification", "PoleCluster", "RejectedPole", "identify", "select_poles", "select_poles_at",
    "IdentificationError", "PoleSweep", "lsce", "zoom_impulse_response",
    "DEFAULT_RESIDUALS", "LSFDResult", "RefinedPoles", "lsfd", "mcf", "mpc", "mpd", "refine_poles", "synthesize",
    "ModeSet",
    "StabilisationDiagram", "stabilisation_diagram",
]
# --- end of identification ---

# --- setups and pairing: merging mode lists, MAC pairing with FE modes, modes folders ---
from .merge import merge_setups
from .modes_io import ModesFolderError, read_modeset, write_modeset
from .pairing import Pair, Pairing, describe_fe_mode, fe_clusters, mac_matrix, pair_modes

__all__ += [
    "merge_setups",
    "ModesFolderError", "read_modeset", "write_modeset",
    "Pair", "Pairing", "describe_fe_mode", "fe_clusters", "mac_matrix", "pair_modes",
]
# --- end of setups and pairing ---
