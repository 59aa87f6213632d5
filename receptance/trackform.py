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
field must be present (no silent defaults from a file) except the optional
``loss_reference_hz`` (absent: eq. 2.32's constant loss), no unknown or
repeated key is accepted, and every value must be a finite number > 0 inside its physical range
(:data:`PLAUSIBLE`, :func:`check_trackform`: refused outside it, a warning
outside the typical range; a UTF-8 byte-order mark is accepted)::

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

__all__ = ["Trackform", "TrackformError", "TrackformWarning", "load_trackform", "trackform_to_dict", "check_trackform",
           "PLAUSIBLE", "DuplicateJSONKey", "unique_json_keys"]

#: Largest trackform file read (a trackform is ~21 numbers).
MAX_FILE_BYTES = 1_000_000


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
    loss_reference_hz : float or None
        ``None`` (default): every loss factor is frequency independent, eq. 2.31–2.32 as written. A frequency
        ``f_ref`` [Hz]: the pad and subplate follow the causal constant-loss law instead (Kramers–Kronig: a
        loss that is the same at every frequency needs a storage stiffness rising with frequency, the dynamic
        stiffening of elastomers), ``K(f) = K (1 + jη) (f / f_ref)^{2 arctan(η)/π}`` (Kjartansson, *J.
        Geophys. Res.* 84, 1979, the constant-Q model), so that the table's ``K`` holds at ``f_ref``, the
        frequency at which the layer was characterised. :func:`receptance.track.support_stiffness_per_metre`
        applies it. Optional in a trackform file (absent = ``None``).
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
    loss_reference_hz: float | None = None

    def __post_init__(self) -> None:
        for f in fields(self):
            if f.name in OPTIONAL and getattr(self, f.name) is None:
                continue
            _check_value(f.name, getattr(self, f.name), "<Trackform(...)>")


#: Trackform fields a file may leave out (their default, ``None``, means "not modelled").
OPTIONAL = ("loss_reference_hz",)


def _check_value(key: str, value, source: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise TrackformError(f"{source}: trackform key {key!r} must be a number, got {value!r}")
    try:
        v = float(value)
    except OverflowError:
        digits = len(str(abs(value))) if isinstance(value, int) else 0
        raise TrackformError(f"{source}: trackform key {key!r} must be finite and > 0, got an integer of {digits} "
                             f"digits (too large for a float)") from None
    if not math.isfinite(v) or v <= 0:
        raise TrackformError(f"{source}: trackform key {key!r} must be finite and > 0, got {value!r}")
    return v


#: Plausible values of each parameter (SI): outside ``physical`` a trackform is refused, outside ``typical``
#: (the ballasted and slab tracks of the literature: rails 30–80 kg/m, pads 20 MN/m–1.5 GN/m, sleeper spacing
#: 0.5–0.8 m, ...) a warning is given. (low, high, unit); ``None`` bounds are open (exclusive).
PLAUSIBLE: dict[str, dict[str, tuple]] = {
    "rail_mass": {"physical": (5.0, 500.0), "typical": (25.0, 80.0), "unit": "kg/m"},
    "rail_density": {"physical": (1000.0, 25000.0), "typical": (7000.0, 8100.0), "unit": "kg/m^3"},
    "rail_area": {"physical": (5e-4, 5e-2), "typical": (3e-3, 1.1e-2), "unit": "m^2"},
    "rail_I_yy": {"physical": (1e-8, 1e-3), "typical": (5e-6, 6e-5), "unit": "m^4"},
    "rail_I_zz": {"physical": (1e-9, 1e-3), "typical": (1e-6, 1.5e-5), "unit": "m^4"},
    "youngs_modulus": {"physical": (1e9, 1e12), "typical": (1.9e11, 2.2e11), "unit": "Pa"},
    "poisson_ratio": {"physical": (0.0, 0.5), "typical": (0.25, 0.33), "unit": "", "open": True},
    "shear_factor": {"physical": (0.0, 1.0), "typical": (0.3, 0.6), "unit": ""},
    "rail_loss_factor": {"physical": (0.0, 1.0), "typical": (1e-3, 0.05), "unit": ""},
    "support_spacing": {"physical": (0.1, 5.0), "typical": (0.5, 0.8), "unit": "m"},
    "pad_stiffness_z": {"physical": (1e5, 1e11), "typical": (2e7, 1.5e9), "unit": "N/m"},
    "pad_stiffness_y": {"physical": (1e5, 1e11), "typical": (1e7, 1e9), "unit": "N/m"},
    "pad_damping_z": {"physical": (1.0, 1e7), "typical": (1e2, 1e5), "unit": "N s/m"},
    "pad_damping_y": {"physical": (1.0, 1e7), "typical": (1e2, 1e5), "unit": "N s/m"},
    "pad_loss_factor": {"physical": (0.0, 1.0), "typical": (0.05, 0.5), "unit": ""},
    "baseplate_mass": {"physical": (0.01, 2000.0), "typical": (1.0, 350.0), "unit": "kg"},
    "subplate_stiffness_z": {"physical": (1e5, 1e11), "typical": (5e6, 1e9), "unit": "N/m"},
    "subplate_stiffness_y": {"physical": (1e5, 1e11), "typical": (2e6, 1e9), "unit": "N/m"},
    "subplate_damping_z": {"physical": (1.0, 1e7), "typical": (1e2, 1e5), "unit": "N s/m"},
    "subplate_damping_y": {"physical": (1.0, 1e7), "typical": (1e2, 1e5), "unit": "N s/m"},
    "subplate_loss_factor": {"physical": (0.0, 1.0), "typical": (0.05, 0.5), "unit": ""},
    # pads are characterised from a few Hz (EN 13146-9 low-frequency stiffness) to ~1 kHz (ISO 10846 methods)
    "loss_reference_hz": {"physical": (0.01, 1e5), "typical": (1.0, 3000.0), "unit": "Hz"},
}


class TrackformWarning(UserWarning):
    """A trackform parameter outside its typical (but possible) range."""


def check_trackform(trackform: "Trackform", source: str = "<Trackform>") -> "Trackform":
    """Plausibility of every parameter: refuse values outside their physical range, warn outside the typical one.

    Besides the ranges of :data:`PLAUSIBLE` the rail's mass per metre must
    match ``rail_density * rail_area`` (within a factor 2; a warning beyond
    10 %): a slipped unit (cm^2 for m^2) shows there.

    Parameters
    ----------
    trackform : Trackform
    source : str
        The file (or description) quoted in messages.

    Returns
    -------
    Trackform
        The same object.

    Raises
    ------
    TrackformError
        Names the source, the parameter, its value, its unit and the physical range.

    Warns
    -----
    TrackformWarning
        A parameter outside its typical range (named with the range).
    """
    import warnings

    for name, spec in PLAUSIBLE.items():
        v = getattr(trackform, name)
        if v is None:  # an optional field left out
            continue
        lo, hi = spec["physical"]
        unit = spec["unit"]
        lo_open = lo == 0.0 or spec.get("open", False)  # a zero stiffness, mass or loss factor is no parameter
        hi_open = spec.get("open", False)
        inside = (lo < v if lo_open else lo <= v) and (v < hi if hi_open else v <= hi)
        if not inside:
            rng = f"{'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}" + (f" {unit}" if unit else "")
            raise TrackformError(f"{source}: trackform key {name!r} = {v:g}{' ' + unit if unit else ''} is outside "
                                 f"the physical range {rng}; check the value and its unit (SI)")
        tlo, thi = spec["typical"]
        if not tlo <= v <= thi:
            warnings.warn(f"{source}: trackform key {name!r} = {v:g}{' ' + unit if unit else ''} is outside the "
                          f"typical range [{tlo:g}, {thi:g}]{' ' + unit if unit else ''}; it is used as given",
                          TrackformWarning, stacklevel=2)
    m = trackform.rail_density * trackform.rail_area
    ratio = trackform.rail_mass / m
    if not 0.5 <= ratio <= 2.0:
        raise TrackformError(
            f"{source}: rail_mass {trackform.rail_mass:g} kg/m disagrees with rail_density x rail_area = "
            f"{trackform.rail_density:g} x {trackform.rail_area:g} = {m:.4g} kg/m (ratio {ratio:.3g}, allowed "
            f"0.5–2); a unit slipped (cm^2 for m^2?)")
    if not 0.9 <= ratio <= 1.1:
        warnings.warn(f"{source}: rail_mass {trackform.rail_mass:g} kg/m is {ratio:.3g} x rail_density x rail_area "
                      f"({m:.4g} kg/m)", TrackformWarning, stacklevel=2)
    return trackform


def trackform_to_dict(trackform: Trackform) -> dict[str, float]:
    """Return the field → value dictionary a trackform file must contain (SI units; optional fields when set)."""
    return {k: v for k, v in asdict(trackform).items() if not (k in OPTIONAL and v is None)}


class DuplicateJSONKey(Exception):
    """A JSON object names a key twice (raised by :func:`unique_json_keys`; each reader reports it with its file).

    Not a ``ValueError``: it must not be taken for a JSON syntax error, whose
    message would not name the key. ``keys``: the object's keys, for messages.
    """

    def __init__(self, key: str, keys: list[str]):
        super().__init__(key)
        self.key, self.keys = key, ", ".join(keys[:12]) + (", ..." if len(keys) > 12 else "")


def unique_json_keys(pairs: list[tuple[str, object]]) -> dict:
    """``object_pairs_hook`` for :func:`json.loads` that refuses a repeated key.

    Plain ``json.loads`` keeps the last of two equal keys, so a file edited by
    appending a line would silently take the appended value (TOML refuses a
    repeated key; JSON must not be more lenient).

    Raises
    ------
    DuplicateJSONKey
        Naming the first key given twice.
    """
    out: dict = {}
    for key, value in pairs:
        if key in out:
            raise DuplicateJSONKey(key, [k for k, _ in pairs])
        out[key] = value
    return out


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
        Unsupported extension, unparsable or too deeply nested file, unknown,
        missing or repeated keys, a non-numeric / non-positive value, or one
        outside its physical range — the message names the file, the key and the range.

    Warns
    -----
    TrackformWarning
        A value outside its typical range.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    try:
        text = path.read_bytes()
    except OSError as exc:
        raise TrackformError(f"{path}: cannot read trackform file ({exc})") from exc
    if suffix not in (".toml", ".json"):
        raise TrackformError(f"{path}: unsupported trackform file extension {suffix!r}; "
                             "supported: '.toml', '.json'")
    if len(text) > MAX_FILE_BYTES:
        raise TrackformError(f"{path}: {len(text)} bytes; a trackform file has a few dozen keys (at most "
                             f"{MAX_FILE_BYTES} bytes)")
    try:
        # a UTF-8 byte-order mark (Windows editors write one) is not part of the content
        decoded = text.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise TrackformError(f"{path}: not UTF-8 text (byte {exc.start}); save the trackform as UTF-8") from None
    try:
        raw = tomllib.loads(decoded) if suffix == ".toml" else json.loads(decoded, object_pairs_hook=unique_json_keys)
    except DuplicateJSONKey as exc:
        raise TrackformError(f"{path}: key {exc.key!r} given twice; a key may appear once (which value is meant?)") \
            from None
    except ValueError as exc:  # TOMLDecodeError, JSONDecodeError, an integer beyond Python's digit limit
        raise TrackformError(f"{path}: cannot parse trackform file ({exc})") from exc
    except RecursionError:
        raise TrackformError(f"{path}: cannot parse trackform file: it is nested too deeply (a trackform is one "
                             f"flat table of numbers)") from None
    if not isinstance(raw, dict):
        raise TrackformError(f"{path}: expected a table/object of trackform keys, got {type(raw).__name__}")
    if set(raw) == {"trackform"} and isinstance(raw["trackform"], dict):
        raw = raw["trackform"]
    names = [f.name for f in fields(Trackform)]
    unknown = sorted(set(raw) - set(names))
    if unknown:
        raise TrackformError(f"{path}: unknown trackform key(s) {unknown}; allowed keys: {names}")
    missing = [n for n in names if n not in raw and n not in OPTIONAL]
    if missing:
        raise TrackformError(f"{path}: missing trackform key(s) {missing}")
    values = {n: _check_value(n, raw[n], str(path)) for n in names if n in raw}
    return check_trackform(Trackform(**values), str(path))
