"""What the FE export cannot tell about the wheelset: a small description file (TOML).

The catalogued effects (:mod:`receptance.diagnosis.effects`) are physical
parts — an axlebox on its bearing, a wheel on its press fit, slings to a
crane — and need physical inputs: where the parts are, what they weigh,
where the wheelset hung.  A design FE model holds some of it (node
positions, and through its rigid-body modes the total mass, centre of mass
and inertia) but not all: an axlebox may be lumped into the journal node or
left out, a rotor-dynamics model has no mass matrix of its wheels, and the
hanging points of a test are not in any design file.  This module holds the
rest, with the defaults of thesis Table 2.1 (a metro trailer wheelset).

Every value is optional; what is not given is derived from the FE and the
points table (``points.csv``) or taken from the defaults, and the diagnosis
says which (:attr:`WheelsetDescription.given`).

File format (TOML, SI units; every key optional)::

    [wheelset]
    axle_mass_kg = 283.0          # Table 2.1
    disc_mass_kg = 135.0          # per brake disc (0 if none)
    n_discs = 2

    [axlebox]
    mass_kg = 78.0                # Table 2.1, per axlebox
    inertia_kg_m2 = [0.9, 1.2, 0.9]   # about x, y, z through its centre
    in_fe = "auto"                # "own_node", "lumped" (on the journal), "absent" or "auto"
    centre_L_m = [0.0, -0.97, 0.0]    # default: axlebox_L of points.csv
    centre_R_m = [0.0, 0.97, 0.0]

    [wheel]
    mass_kg = 251.0               # Table 2.1, per wheel
    rim_mass_kg = 150.0           # rim (tyre) ring
    web_mass_kg = 80.0            # web (plate between hub and rim)
    rolling_radius_m = 0.41       # default: contact points' distance from the axle axis
    rim_radius_m = 0.3825         # rim centroid; default 0.933 x rolling radius
    hub_radius_m = 0.135          # web's inner edge; default 0.33 x rolling radius
    hub_plane_L_m = -0.72         # y of the left hub (web) plane; default from the FE's wheel nodes
    hub_plane_R_m = 0.72

    [rig]
    # where the wheelset hung during the test: coordinates [m] or point names of points.csv;
    # without them rig_suspension fits the axial position of a symmetric pair of slings on the axle
    hanging_points = [[0.0, -0.55, 0.0], [0.0, 0.55, 0.0]]

:func:`read_description` reads such a file; :class:`WheelsetDescription`
is the value (``WheelsetDescription()`` is the Table 2.1 default).
"""

from __future__ import annotations

import math
import os
import tomllib
from dataclasses import dataclass, field, fields, replace
from pathlib import Path

__all__ = ["WheelsetDescription", "DescriptionError", "read_description", "AXLEBOX_IN_FE", "SCHEMA"]

#: how the FE export holds the axleboxes
AXLEBOX_IN_FE = ("auto", "own_node", "lumped", "absent")


class DescriptionError(ValueError):
    """A wheelset description that cannot be used (names the file, the key, what is allowed and what was given)."""


@dataclass(frozen=True)
class WheelsetDescription:
    """Physical data of the wheelset the FE may lack (SI units; thesis Table 2.1 defaults).

    Positions left ``None`` are derived from the FE export and the points
    table when an effect is attached (:mod:`receptance.diagnosis.geometry`).

    Attributes
    ----------
    axle_mass, disc_mass : float
        [kg]; ``disc_mass`` per disc.
    n_discs : int
    axlebox_mass : float
        Per axlebox [kg].
    axlebox_inertia : (float, float, float)
        About x, y, z through the axlebox centre [kg m²] (default: a 78 kg
        box 0.3 × 0.22 × 0.3 m).
    axlebox_in_fe : {"auto", "own_node", "lumped", "absent"}
        How the FE holds the axleboxes; ``"auto"`` decides from the geometry
        (a node of its own at the axlebox centre) and the FE's total mass.
    axlebox_centres : dict side -> (x, y, z) or None
    wheel_mass, rim_mass, web_mass : float
        Per wheel [kg]; the hub is the rest of ``wheel_mass``.
    rolling_radius, rim_radius, hub_radius : float or None
        [m].
    hub_planes : dict side -> y or None
        Axial position of each wheel's hub (web) plane [m]: the coordinate
        along the axle, from the left wheel towards the right, through the
        FE's origin (``y`` in the railway frame; the same number in the FE's
        own frame, which :mod:`receptance.frame` turns).
    hanging_points : tuple or None
        Where the wheelset hung in the test: ``(x, y, z)`` tuples or point
        names; None: unknown (``rig_suspension`` fits a symmetric pair).
    source : str
        File read ("" for defaults).
    given : frozenset of str
        Attributes the file stated (the rest are defaults or derived).
    """

    axle_mass: float = 283.0
    disc_mass: float = 135.0
    n_discs: int = 2
    axlebox_mass: float = 78.0
    axlebox_inertia: tuple[float, float, float] = (0.9, 1.2, 0.9)
    axlebox_in_fe: str = "auto"
    axlebox_centres: dict = field(default_factory=lambda: {"L": None, "R": None})
    wheel_mass: float = 251.0
    rim_mass: float = 150.0
    web_mass: float = 80.0
    rolling_radius: float | None = None
    rim_radius: float | None = None
    hub_radius: float | None = None
    hub_planes: dict = field(default_factory=lambda: {"L": None, "R": None})
    hanging_points: tuple | None = None
    source: str = ""
    given: frozenset = frozenset()

    def __post_init__(self) -> None:
        where = self.source or "wheelset description"
        for name in ("axle_mass", "disc_mass", "axlebox_mass", "wheel_mass", "rim_mass", "web_mass"):
            _check_number(where, name, getattr(self, name), allow_zero=name in ("disc_mass",))
        for name in ("rolling_radius", "rim_radius", "hub_radius"):
            if getattr(self, name) is not None:
                _check_number(where, name, getattr(self, name))
        if not isinstance(self.n_discs, int) or isinstance(self.n_discs, bool) or not 0 <= self.n_discs <= 8:
            raise DescriptionError(f"{where}: n_discs must be an integer 0-8, got {self.n_discs!r}")
        inertia = tuple(self.axlebox_inertia)
        if len(inertia) != 3:
            raise DescriptionError(f"{where}: axlebox inertia needs 3 values (about x, y, z) in kg m^2, got "
                                   f"{self.axlebox_inertia!r}")
        for v in inertia:
            _check_number(where, "axlebox inertia", v)
        object.__setattr__(self, "axlebox_inertia", tuple(float(v) for v in inertia))
        if self.axlebox_in_fe not in AXLEBOX_IN_FE:
            raise DescriptionError(f"{where}: axlebox in_fe must be one of {AXLEBOX_IN_FE}, got "
                                   f"{self.axlebox_in_fe!r}")
        if self.rim_mass + self.web_mass > self.wheel_mass:
            raise DescriptionError(f"{where}: rim ({self.rim_mass:g} kg) and web ({self.web_mass:g} kg) weigh more "
                                   f"than the wheel ({self.wheel_mass:g} kg)")
        if self.rim_radius is not None and self.hub_radius is not None and self.hub_radius >= self.rim_radius:
            raise DescriptionError(f"{where}: hub_radius ({self.hub_radius:g} m) must be below rim_radius "
                                   f"({self.rim_radius:g} m)")
        centres = {s: None if c is None else _xyz(where, f"axlebox centre_{s}", c)
                   for s, c in dict(self.axlebox_centres).items()}
        object.__setattr__(self, "axlebox_centres", centres)
        planes = {s: None if y is None else float(y) for s, y in dict(self.hub_planes).items()}
        object.__setattr__(self, "hub_planes", planes)
        if self.hanging_points is not None:
            pts = []
            for k, p in enumerate(self.hanging_points):
                pts.append(p if isinstance(p, str) else _xyz(where, f"rig hanging_points[{k}]", p))
            if not pts:
                raise DescriptionError(f"{where}: rig hanging_points is empty; leave it out to fit the sling "
                                       f"position")
            object.__setattr__(self, "hanging_points", tuple(pts))
        object.__setattr__(self, "given", frozenset(self.given))

    @property
    def wheelset_mass(self) -> float:
        """Axle, wheels and discs, without axleboxes [kg] (Table 2.1: 1054 kg)."""
        return self.axle_mass + 2 * self.wheel_mass + self.n_discs * self.disc_mass

    @property
    def hub_mass(self) -> float:
        """Per wheel: what is neither rim nor web [kg]."""
        return self.wheel_mass - self.rim_mass - self.web_mass

    def with_values(self, **changes) -> "WheelsetDescription":
        """A copy with some values changed (and marked as given)."""
        return replace(self, **changes, given=self.given | frozenset(changes))

    def to_dict(self) -> dict:
        """JSON-ready values, and which were given."""
        out = {f.name: getattr(self, f.name) for f in fields(self) if f.name not in ("given",)}
        out["given"] = sorted(self.given)
        return out


def _check_number(where: str, name: str, value, *, allow_zero: bool = False) -> None:
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value) and (
        value > 0 or (allow_zero and value == 0))
    if not ok:
        raise DescriptionError(f"{where}: {name} must be a finite number {'>=' if allow_zero else '>'} 0, got "
                               f"{value!r}")


def _xyz(where: str, name: str, value) -> tuple[float, float, float]:
    if isinstance(value, (str, bytes)) or not hasattr(value, "__len__") or len(value) != 3:
        raise DescriptionError(f"{where}: {name} must be 3 coordinates [x, y, z] in m, got {value!r}")
    out = []
    for v in value:
        if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
            raise DescriptionError(f"{where}: {name} must be 3 finite coordinates in m, got {value!r}")
        out.append(float(v))
    return tuple(out)


#: file section -> key -> (attribute, converter); converters take (where, key, value)
SCHEMA: dict[str, dict[str, str]] = {
    "wheelset": {"axle_mass_kg": "axle_mass", "disc_mass_kg": "disc_mass", "n_discs": "n_discs"},
    "axlebox": {"mass_kg": "axlebox_mass", "inertia_kg_m2": "axlebox_inertia", "in_fe": "axlebox_in_fe",
                "centre_L_m": "axlebox_centres.L", "centre_R_m": "axlebox_centres.R"},
    "wheel": {"mass_kg": "wheel_mass", "rim_mass_kg": "rim_mass", "web_mass_kg": "web_mass",
              "rolling_radius_m": "rolling_radius", "rim_radius_m": "rim_radius", "hub_radius_m": "hub_radius",
              "hub_plane_L_m": "hub_planes.L", "hub_plane_R_m": "hub_planes.R"},
    "rig": {"hanging_points": "hanging_points"},
}

#: the largest description file read (a description is a few hundred bytes)
MAX_BYTES = 1_000_000


def read_description(path: str | os.PathLike) -> WheelsetDescription:
    """Read a wheelset description (TOML, format in the module docstring).

    Raises
    ------
    FileNotFoundError
        No such file.
    DescriptionError
        Not TOML, an unknown section or key (the message lists the known
        ones), a value of the wrong type or out of range (names the file, the
        key, what is allowed and what was given).
    """
    p = Path(os.fspath(path))
    if not p.is_file():
        raise FileNotFoundError(f"wheelset description {str(p)!r} does not exist")
    if p.stat().st_size > MAX_BYTES:
        raise DescriptionError(f"{p}: {p.stat().st_size} bytes; a wheelset description is a small TOML file "
                               f"(at most {MAX_BYTES} bytes)")
    try:
        doc = tomllib.loads(p.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise DescriptionError(f"{p}: not a TOML file ({exc})") from None
    values: dict = {"axlebox_centres": {"L": None, "R": None}, "hub_planes": {"L": None, "R": None}}
    given = set()
    for section, body in doc.items():
        if section not in SCHEMA:
            raise DescriptionError(f"{p}: unknown section [{section}]; known sections: "
                                   f"{', '.join(f'[{s}]' for s in SCHEMA)}")
        if not isinstance(body, dict):
            raise DescriptionError(f"{p}: {section} must be a section ([{section}]), got a value {body!r}")
        for key, value in body.items():
            if key not in SCHEMA[section]:
                raise DescriptionError(f"{p}: unknown key {key!r} in [{section}]; known keys: "
                                       f"{', '.join(SCHEMA[section])}")
            attr = SCHEMA[section][key]
            if "." in attr:
                name, side = attr.split(".")
                values[name][side] = value
                given.add(name)
            else:
                if attr == "n_discs" and not isinstance(value, int):
                    raise DescriptionError(f"{p}: [{section}] {key} must be an integer, got {value!r}")
                if attr in ("axle_mass", "disc_mass", "axlebox_mass", "wheel_mass", "rim_mass", "web_mass",
                            "rolling_radius", "rim_radius", "hub_radius") and isinstance(value, int) \
                        and not isinstance(value, bool):
                    value = float(value)
                values[attr] = value
                given.add(attr)
    try:
        return WheelsetDescription(**values, source=str(p), given=frozenset(given))
    except DescriptionError:
        raise
    except (TypeError, ValueError) as exc:
        raise DescriptionError(f"{p}: {exc}") from None
