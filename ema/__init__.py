"""ema — experimental modal analysis of impact-hammer tests.

Role in the data flow (``shared/DESIGN.md``): reads the lab's hammer-test
files (UFF58 time histories + channel table), screens hits, estimates H1/H2
FRFs and coherence, identifies modes by LSCE with a stabilisation diagram and
LSFD shapes, merges the setups' mode lists and pairs the experimental modes
with the FE modes of :mod:`fem_import` by MAC. Its output (a mode set and the
measured FRFs) feeds :mod:`receptance`.
"""

# The public names are loaded lazily (PEP 562): ``import ema`` is free until a name is used, so the CLI and
# the field side do not pay for pandas, scipy.cluster and the identification code at start-up.
from __future__ import annotations

import importlib

#: submodule -> the public names it defines, grouped as the data flow runs
_MODULES: dict[str, tuple[str, ...]] = {
    # input side: channel tables, hammer-test reading, hit screening, FRF estimation
    "channels": ("ChannelTableError", "read_channels", "validate_channels"),
    "estimate": ("EstimationError", "ForceWindow", "auto_exp_decay", "estimate_frf"),
    "frf": ("FRFShapeError", "FrequencyResponse"),
    "hammer_io": ("ChannelDirectionWarning", "ChannelMismatchError", "FunctionTypeError", "HammerDataError",
                  "HammerTest", "MDFReadError", "TDMSReadError", "CSVReadError", "NonFiniteDataError", "SamplingError",
                  "UFFReadError",
                  "UnknownFormatError", "ZeroForceError", "read_hammer"),
    "screening": ("Rejection", "Screening", "ScreeningConfig", "screen_hits"),
    "uff_frf": ("read_frf_uff",),
    # identification: LSCE, stabilisation, automatic pole selection, refinement, LSFD
    "identify": ("Identification", "PoleCluster", "RejectedPole", "identify", "select_poles", "select_poles_at"),
    "lsce": ("IdentificationError", "PoleSweep", "lsce", "zoom_impulse_response"),
    "lsfd": ("DEFAULT_RESIDUALS", "LSFDResult", "RefinedPoles", "lsfd", "mcf", "mpc", "mpd", "refine_poles",
             "synthesize"),
    "modeset": ("ModeSet",),
    "stabilisation": ("StabilisationDiagram", "stabilisation_diagram"),
    # setups and pairing: merging mode lists, MAC pairing with FE modes, modes folders
    "merge": ("merge_setups",),
    "modes_io": ("ModesFolderError", "read_modeset", "write_modeset"),
    "pairing": ("Pair", "Pairing", "describe_fe_mode", "fe_clusters", "mac_matrix", "pair_modes"),
}
_OWNER = {name: module for module, names in _MODULES.items() for name in names}

__all__ = list(_OWNER)


def __getattr__(name: str):
    try:
        module = _OWNER[name]
    except KeyError:
        raise AttributeError(f"module 'ema' has no attribute {name!r}") from None
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value  # later look-ups do not come here again
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_OWNER))
