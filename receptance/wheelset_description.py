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
says which (:attr:`WheelsetDescription.given`).  Table 2.1's masses are one
wheelset's: for another, the masses not given are Table 2.1's proportions
scaled to the FE's own rigid-body mass (:meth:`WheelsetDescription.fitted_to_fe`),
and the rim and web default to Table 2.1's shares of the wheel's mass.

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
    rim_mass_kg = 150.0           # rim (tyre) ring; default 150/251 of mass_kg (Table 2.1's share)
    web_mass_kg = 80.0            # web (plate between hub and rim); default 80/251 of mass_kg
    rolling_radius_m = 0.41       # default: contact points' distance from the axle axis
    rim_radius_m = 0.3825         # rim centroid; default 0.933 x rolling radius
    hub_radius_m = 0.135          # web's inner edge; default 0.33 x rolling radius
    hub_plane_L_m = -0.72         # y of the left hub (web) plane; default from the FE's wheel nodes
    hub_plane_R_m = 0.72

    [rig]
    # where the wheelset hung during the test: coordinates [m] or point names of points.csv;
    # without them rig_suspension fits the axial position of a symmetric pair of slings on the axle
    hanging_points = [[0.0, -0.55, 0.0], [0.0, 0.55, 0.0]]

    [primary_suspension]
    # in service, per axlebox to ground (bogie neglected, thesis §2.3); default thesis Table 2.1
    stiffness_N_per_m = [8.3e6, 4.2e6, 1.0e6]     # x, y, z (Table 2.1: 2 x 4.15, 2 x 2.1, 2 x 0.5 kN/mm)
    damping_N_s_per_m = [85e3, 50e3, 11e3]        # x, y, z

:func:`read_description` reads such a file; :class:`WheelsetDescription`
is the value (``WheelsetDescription()`` is the Table 2.1 default).
"""

from __future__ import annotations

import math
import os
import tomllib
from dataclasses import dataclass, field, fields, replace
from pathlib import Path

__all__ = ["WheelsetDescription", "DescriptionError", "read_description", "AXLEBOX_IN_FE", "SCHEMA", "TABLE_2_1_MASSES",
           "MASS_NOTE_RTOL"]

#: how the FE export holds the axleboxes
AXLEBOX_IN_FE = ("auto", "own_node", "lumped", "absent")

#: thesis Table 2.1 masses [kg] (a metro trailer wheelset; per part: disc, wheel and axlebox each one of them)
TABLE_2_1_MASSES = {"axle_mass": 283.0, "disc_mass": 135.0, "wheel_mass": 251.0, "axlebox_mass": 78.0}
#: Table 2.1's rim and web as shares of its wheel (150 and 80 of 251 kg): the defaults of a wheel of any mass
RIM_SHARE, WEB_SHARE = 150.0 / 251.0, 80.0 / 251.0
#: Table 2.1's axlebox inertia about x, y, z [kg m²] (a 78 kg box 0.3 x 0.22 x 0.3 m)
TABLE_2_1_AXLEBOX_INERTIA = (0.9, 1.2, 0.9)
#: the description's masses and the FE's rigid-body mass are said to disagree beyond this share
MASS_NOTE_RTOL = 0.05
#: an FE whose mass is Table 2.1's to this share is Table 2.1's wheelset: its masses are used as they are (a mass
#: estimate is no better than that; a design office's FE of the thesis wheelset rounds its parts)
TABLE_2_1_MATCH = 0.01
#: description key of each mass (messages name what to state)
MASS_KEYS = {"axle_mass": "[wheelset] axle_mass_kg", "disc_mass": "[wheelset] disc_mass_kg",
             "wheel_mass": "[wheel] mass_kg", "axlebox_mass": "[axlebox] mass_kg",
             "axlebox_inertia": "[axlebox] inertia_kg_m2", "rim_mass": "[wheel] rim_mass_kg",
             "web_mass": "[wheel] web_mass_kg"}


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
        Per wheel [kg]; the hub is the rest of ``wheel_mass``.  ``rim_mass``
        and ``web_mass`` left None are Table 2.1's shares of ``wheel_mass``
        (:data:`RIM_SHARE`, :data:`WEB_SHARE`), so a wheel of any mass has a
        rim, a web and a hub.
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
    suspension_stiffness, suspension_damping : (float, float, float) or None
        The in-service primary suspension per axlebox along x, y, z [N/m],
        [N s/m]; None: thesis Table 2.1 (a Meneghino trailer, right for a
        wheelset of its mass and bogie only).
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
    rim_mass: float | None = None
    web_mass: float | None = None
    rolling_radius: float | None = None
    rim_radius: float | None = None
    hub_radius: float | None = None
    hub_planes: dict = field(default_factory=lambda: {"L": None, "R": None})
    hanging_points: tuple | None = None
    suspension_stiffness: tuple | None = None
    suspension_damping: tuple | None = None
    source: str = ""
    given: frozenset = frozenset()

    def __post_init__(self) -> None:
        where = self.source or "wheelset description"
        # rim and web not stated: Table 2.1's shares of this wheel (absolute 150 + 80 kg would outweigh a light wheel)
        if self.rim_mass is None and isinstance(self.wheel_mass, (int, float)):
            object.__setattr__(self, "rim_mass", RIM_SHARE * self.wheel_mass)
        if self.web_mass is None and isinstance(self.wheel_mass, (int, float)):
            object.__setattr__(self, "web_mass", WEB_SHARE * self.wheel_mass)
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
        for name, key in (("suspension_stiffness", "stiffness_N_per_m"), ("suspension_damping", "damping_N_s_per_m")):
            value = getattr(self, name)
            if value is not None:  # 0 is allowed: no spring (or damper) along that axis
                if isinstance(value, (str, bytes)) or not hasattr(value, "__len__") or len(value) != 3:
                    raise DescriptionError(f"{where}: [primary_suspension] {key} needs 3 values (x, y, z), got "
                                           f"{value!r}")
                for v in value:
                    _check_number(where, f"[primary_suspension] {key}", v, allow_zero=True)
                object.__setattr__(self, name, tuple(float(v) for v in value))
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
        """A copy with some values changed (and marked as given); a new wheel mass re-derives the rim and web
        masses that were not given (Table 2.1's shares)."""
        if "wheel_mass" in changes:
            for name in ("rim_mass", "web_mass"):
                if name not in changes and name not in self.given:
                    changes[name] = None
        given = self.given | frozenset(k for k, v in changes.items() if v is not None)
        return replace(self, **changes, given=given)

    def fitted_to_fe(self, fe_mass: float | None, axleboxes_in_fe: bool
                     ) -> tuple["WheelsetDescription", tuple[str, ...]]:
        """The masses the description does not give, fitted to an FE's rigid-body mass.

        Table 2.1 describes one wheelset; taken as it is for another it takes
        masses off FE nodes that do not carry them.  What one number can tell
        is the scale: the masses not in :attr:`given` become Table 2.1's
        scaled by one factor ``s``, the mass the FE's rigid-body modes imply
        less the given parts', over Table 2.1's mass of the parts not given
        (the axle, ``n_discs`` discs, two wheels, and the two axleboxes when
        the FE holds them).  The axlebox's inertia not given follows its mass
        as a geometrically similar box (``m ∝ L³``, ``I ∝ m L²``: the ratio to
        the power 5/3); rim and web not given are Table 2.1's shares of the
        wheel.  A description that gives every part is compared with the FE's
        mass instead.

        Parameters
        ----------
        fe_mass : float or None
            Total mass the FE's rigid-body modes imply [kg] (thesis eq. 2.29
            on the rigid modes; None: unknown, the masses stay as they are).
        axleboxes_in_fe : bool
            That mass includes the two axleboxes.

        Returns
        -------
        description : WheelsetDescription
            With the derived masses (:attr:`given` unchanged: they were not given).
        notes : tuple of str
            Where each mass came from; a disagreement with the FE's mass beyond
            :data:`MASS_NOTE_RTOL`.
        """
        counts = {"axle_mass": 1, "disc_mass": self.n_discs, "wheel_mass": 2,
                  "axlebox_mass": 2 if axleboxes_in_fe else 0}
        # stated: read from a file (``given``) or set to another value than Table 2.1's when constructed
        stated = set(self.given) | {k for k, v in TABLE_2_1_MASSES.items() if getattr(self, k) != v}
        if tuple(self.axlebox_inertia) != TABLE_2_1_AXLEBOX_INERTIA:
            stated.add("axlebox_inertia")
        free = [k for k in TABLE_2_1_MASSES if k not in stated]
        given = [k for k in TABLE_2_1_MASSES if k in stated]
        label = {"axle_mass": "axle", "disc_mass": "disc", "wheel_mass": "wheel", "axlebox_mass": "axlebox"}
        what = "with its two axleboxes" if axleboxes_in_fe else "without axleboxes"
        notes = []
        if given:
            notes.append("masses given by the description: " + ", ".join(
                f"{label[k]} {getattr(self, k):.4g} kg" for k in given))
        if fe_mass is None or not math.isfinite(fe_mass) or fe_mass <= 0:
            if free:
                notes.append("the FE's total mass is unknown (no six rigid-body modes), so the masses not given are "
                             "thesis Table 2.1's as they are (" + ", ".join(
                                 f"{label[k]} {getattr(self, k):.4g} kg" for k in free) + "); state them ("
                             + ", ".join(MASS_KEYS[k] for k in free) + ")")
            return self, tuple(notes)
        given_mass = sum(counts[k] * getattr(self, k) for k in given)
        table_free = sum(counts[k] * TABLE_2_1_MASSES[k] for k in free)
        left = fe_mass - given_mass
        if table_free > 0 and left > 0:
            s = left / table_free
            how = (f"Table 2.1's proportions scaled by {s:.4g} to the {left:.1f} kg the FE's rigid-body mass "
                   f"({fe_mass:.1f} kg, {what}) leaves" + (" after the given parts" if given else ""))
            if abs(s - 1.0) <= TABLE_2_1_MATCH:
                s = 1.0
                how = (f"thesis Table 2.1's as they are (the {left:.1f} kg the FE's rigid-body mass, {fe_mass:.1f} kg "
                       f"{what}, leaves" + (" after the given parts" if given else "") + " is Table 2.1's to "
                       f"{100 * TABLE_2_1_MATCH:g} %)")
        else:
            # nothing the FE holds is left to scale (or the given parts already outweigh it): the design's scale
            table_all = sum(counts[k] * TABLE_2_1_MASSES[k] for k in TABLE_2_1_MASSES)
            s = fe_mass / table_all
            how = (f"Table 2.1's scaled by {s:.4g}, the FE's rigid-body mass ({fe_mass:.1f} kg, {what}) over Table "
                   f"2.1's {table_all:.0f} kg of the same parts")
            off = (given_mass - fe_mass) / fe_mass
            if abs(off) > MASS_NOTE_RTOL:
                notes.append(f"the description's masses add up to {given_mass:.1f} kg ({what}), {100 * off:+.0f} % "
                             f"from the FE's rigid-body mass {fe_mass:.1f} kg: check them (and the FE's units)")
        changes: dict = {k: s * TABLE_2_1_MASSES[k] for k in free}
        if "axlebox_inertia" not in stated:
            ratio = changes.get("axlebox_mass", self.axlebox_mass) / TABLE_2_1_MASSES["axlebox_mass"]
            changes["axlebox_inertia"] = tuple(ratio ** (5 / 3) * v for v in TABLE_2_1_AXLEBOX_INERTIA)
        if "wheel_mass" in changes:
            # rim and web follow the wheel unless stated (a value other than the shares of the wheel)
            shares = {"rim_mass": RIM_SHARE, "web_mass": WEB_SHARE}
            changes.update({k: None for k, f in shares.items() if k not in self.given
                            and abs(getattr(self, k) - f * self.wheel_mass) <= 1e-9 * self.wheel_mass})
        out = replace(self, **changes)
        if free:
            parts = []
            for k in free:
                text = f"{label[k]} {getattr(out, k):.4g} kg"
                if k == "wheel_mass":
                    text += f" (rim {out.rim_mass:.4g}, web {out.web_mass:.4g} kg: Table 2.1's shares)"
                if k == "axlebox_mass" and "axlebox_inertia" not in stated:
                    text += f" (inertia {'/'.join(f'{v:.3g}' for v in out.axlebox_inertia)} kg m^2)"
                parts.append(text)
            notes.append(f"masses not given: {how}: " + ", ".join(parts) + " (state "
                         + ", ".join(MASS_KEYS[k] for k in free) + " if the design's differ)")
        return out, tuple(notes)

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
    "primary_suspension": {"stiffness_N_per_m": "suspension_stiffness", "damping_N_s_per_m": "suspension_damping"},
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
