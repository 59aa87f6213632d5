"""fem_import — readers of finite-element modal exports.

Role in the data flow (``shared/DESIGN.md``): reads the design office's FE
export (UFF 2411/2412 with 55 or 2414, Nastran punch or print-file
eigenvectors, an ANSYS modal .rst, a CalculiX .frd) through a format
registry into FE modes (nodes, elements, frequencies, mass-normalised shapes)
and evaluates shapes at sensor points and directions. It is the first link:
:mod:`ema` pairs against it and :mod:`receptance` builds the hybrid model from
its shapes.

Public API
----------
read(path, format=None, *, geometry=None, **kwargs) -> FEModes
    Read modes through the format registry (format sniffed from content).
read_with_geometry(path, geometry=None, *, subcase=None) -> (FEModes, note)
    The same, with node coordinates and elements from ``geometry`` (UFF
    2411/2412 or a Nastran bulk deck: GRID and element cards) or a companion
    file; says which file is needed. What the command line calls.
check_mass_normalisation(fe, total_mass=None, mass_matrix=None), rigid_body_mass(fe)
    Mass normalisation against the rigid-body modes, a total mass, a mass matrix.
rigid_body_modes(fe) -> RigidBodyModes
    The six rigid-body modes recognised by their shapes (or the frequency
    gap without coordinates), with the reason when there are not six.
formats() -> tuple of str
    Registered format names; :func:`format_info`, :func:`register_format`,
    :func:`unregister_format`, :func:`detect_format`, :func:`read_geometry`,
    :func:`merge_geometry`.
FEModes, Element, Geometry
    The data types; :meth:`FEModes.at_points`, :meth:`FEModes.nearest_node`,
    :attr:`FEModes.mode_numbers` (the file's mode numbers) and
    :meth:`FEModes.mode_index`.
shapes_at_channels(fe_modes, channels) -> ndarray
    Shapes at the rows of a channel table.
Exceptions: UnknownFormatError, FEReadError, FEGeometryError,
MissingCoordinatesError, PointToleranceError (all ValueError).

Pictures live in :mod:`fem_import.plot` (PyVista, imported on demand).
"""

import logging as _logging

from .errors import (
    FEGeometryError,
    FEImportError,
    FEReadError,
    MissingCoordinatesError,
    PointToleranceError,
    UnknownFormatError,
)
from .modes import DOF_NAMES, Element, FEModes, shapes_at_channels
from .registry import (
    FormatInfo,
    Geometry,
    detect_format,
    format_info,
    formats,
    merge_geometry,
    read,
    read_with_geometry,
    find_geometry_companion,
    read_geometry,
    register_format,
    unregister_format,
)
from . import uff as _uff, punch as _punch, f06 as _f06, nastran_bulk as _bulk  # noqa: E402,F401  (built-in readers)
from . import ansys_rst as _rst, calculix_frd as _frd  # noqa: E402,F401
from . import nastran_op2 as _op2, nastran_h5 as _h5  # noqa: E402,F401
from .checks import (  # noqa: E402
    MassNormalisationError,
    RigidBodyMass,
    RigidBodyModes,
    check_mass_normalisation,
    check_mode_values,
    model_size,
    rigid_body_mass,
    rigid_body_modes,
)

_logging.getLogger("fem_import").addHandler(_logging.NullHandler())

__all__ = [
    "read", "formats", "format_info", "register_format", "unregister_format", "detect_format", "read_geometry",
    "merge_geometry",
    "FEModes", "Element", "Geometry", "FormatInfo", "DOF_NAMES", "shapes_at_channels",
    "FEImportError", "UnknownFormatError", "FEReadError", "FEGeometryError", "MissingCoordinatesError",
    "PointToleranceError", "read_with_geometry", "find_geometry_companion", "MassNormalisationError", "RigidBodyMass",
    "check_mass_normalisation", "check_mode_values", "model_size", "rigid_body_mass", "RigidBodyModes",
    "rigid_body_modes",
]
