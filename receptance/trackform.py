"""Trackform parameters (thesis Table 2.2) and their TOML/JSON loading.

A :class:`Trackform` holds, in SI units, the rail and the two-layer
(rail pad / baseplate / subplate) support data of the *Milano Modificato*
trackform (thesis §2.4, Table 2.2).  Its defaults are Table 2.2 converted to
SI (cm² → m², cm⁴ → m⁴, MPa → Pa, kN/mm → N/m, kNs/m → Ns/m).

File format (:func:`load_trackform`)
------------------------------------
A TOML (``.toml``) or JSON (``.json``) file whose keys are exactly the
field names of :class:`Trackform`, all in SI units, either at the top level
or inside a ``[trackform]`` table / ``{"trackform": {...}}`` object.  Every
field must be present (no silent defaults from a file), no unknown key is
accepted, and every value must be a finite number > 0::

    [trackform]
    rail_mass = 49.9              # kg/m
    rail_density = 7800.0         # kg/m^3
    rail_area = 63.62e-4          # m^2
    rail_I_yy = 1844e-8           # m^4, vertical bending
    ...

:func:`trackform_to_dict` gives the dictionary a file must contain.
"""

from __future__ import annotations

import json
import math
import tomllib
from dataclasses import asdict, dataclass, fields
from pathlib import Path

__all__ = ["Trackform", "TrackformError", "load_trackform", "trackform_to_dict"]


class TrackformError(ValueError):
    """Invalid trackform parameters: names the key, the file and what was expected."""


@dataclass(frozen=True)
class Trackform:
    """Rail and two-layer support parameters, SI units (thesis Table 2.2).

    Parameters
    ----------
    rail_mass : float
        Rail mass per unit length ``m_r`` [kg/m].
    rail_density : float
        Rail density ``ρ_r`` [kg/m³] (rotary inertia ``ρ_r I``, eq. 2.33).
    rail_area : float
        Cross-section ``A_r`` [m²].
    rail_I_yy : float
        Second moment of area for vertical bending [m⁴].
    rail_I_zz : float
        Second moment of area for lateral bending [m⁴].
    youngs_modulus : float
        ``E_r`` [Pa].
    poisson_ratio : float
        ``ν_r`` [-] (``G = E/(2(1+ν))``, eq. 2.31).
    shear_factor : float
        Timoshenko shear coefficient ``κ_r`` [-].
    rail_loss_factor : float
        ``η_r`` [-] (``E* = E(1+jη_r)``, eq. 2.31).
    support_spacing : float
        ``L_s`` [m]; continuous support stiffness is ``K/L_s`` (eq. 2.32).
    pad_stiffness_z, pad_stiffness_y : float
        Rail-pad stiffness per support ``K_rp`` vertical/lateral [N/m].
    pad_damping_z, pad_damping_y : float
        Rail-pad viscous damping per support ``C_rp`` [N s/m].
    pad_loss_factor : float
        ``η_rp`` [-].
    baseplate_mass : float
        Baseplate mass per support ``M_p`` [kg].
    subplate_stiffness_z, subplate_stiffness_y : float
        Subplate stiffness per support ``K_sp`` [N/m].
    subplate_damping_z, subplate_damping_y : float
        Subplate viscous damping per support ``C_sp`` [N s/m].
    subplate_loss_factor : float
        ``η_sp`` [-].
    """

    rail_mass: float = 49.9
    rail_density: float = 7800.0
    rail_area: float = 63.62e-4
    rail_I_yy: float = 1844e-8
    rail_I_zz: float = 362.4e-8
    youngs_modulus: float = 206e9
    poisson_ratio: float = 0.28
    shear_factor: float = 0.34
    rail_loss_factor: float = 0.02
    support_spacing: float = 0.75
    pad_stiffness_z: float = 150e6
    pad_stiffness_y: float = 51.71e6
    pad_damping_z: float = 1.5e3
    pad_damping_y: float = 0.75e3
    pad_loss_factor: float = 0.13
    baseplate_mass: float = 15.0
    subplate_stiffness_z: float = 30e6
    subplate_stiffness_y: float = 10.3e6
    subplate_damping_z: float = 2.8e3
    subplate_damping_y: float = 1.4e3
    subplate_loss_factor: float = 0.20

    def __post_init__(self) -> None:
        for f in fields(self):
            _check_value(f.name, getattr(self, f.name), "<Trackform(...)>")


def _check_value(key: str, value, source: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise TrackformError(f"{source}: trackform key {key!r} must be a number, got {value!r}")
    if not math.isfinite(value) or value <= 0:
        raise TrackformError(f"{source}: trackform key {key!r} must be finite and > 0, got {value!r}")
    return float(value)


def trackform_to_dict(trackform: Trackform) -> dict[str, float]:
    """Return the field → value dictionary a trackform file must contain (SI units)."""
    return asdict(trackform)


def load_trackform(path: str | Path) -> Trackform:
    """Read a :class:`Trackform` from a TOML or JSON file.

    Parameters
    ----------
    path : str or Path
        ``.toml`` or ``.json`` file; keys are the :class:`Trackform` field
        names in SI units, at top level or in a ``trackform`` table.

    Returns
    -------
    Trackform

    Raises
    ------
    TrackformError
        Unsupported extension, unparsable file, unknown or missing keys, or a
        non-numeric / non-positive value — the message names the file and key.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    try:
        text = path.read_bytes()
    except OSError as exc:
        raise TrackformError(f"{path}: cannot read trackform file ({exc})") from exc
    try:
        if suffix == ".toml":
            raw = tomllib.loads(text.decode("utf-8"))
        elif suffix == ".json":
            raw = json.loads(text.decode("utf-8"))
        else:
            raise TrackformError(f"{path}: unsupported trackform file extension {suffix!r}; "
                                 "supported: '.toml', '.json'")
    except (tomllib.TOMLDecodeError, json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise TrackformError(f"{path}: cannot parse trackform file ({exc})") from exc
    if not isinstance(raw, dict):
        raise TrackformError(f"{path}: expected a table/object of trackform keys, got {type(raw).__name__}")
    if set(raw) == {"trackform"} and isinstance(raw["trackform"], dict):
        raw = raw["trackform"]
    names = [f.name for f in fields(Trackform)]
    unknown = sorted(set(raw) - set(names))
    if unknown:
        raise TrackformError(f"{path}: unknown trackform key(s) {unknown}; allowed keys: {names}")
    missing = [n for n in names if n not in raw]
    if missing:
        raise TrackformError(f"{path}: missing trackform key(s) {missing}")
    values = {n: _check_value(n, raw[n], str(path)) for n in names}
    return Trackform(**values)
