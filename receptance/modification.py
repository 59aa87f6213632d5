"""Structural modifications of a modal model: springs, dampers, masses and added rigid bodies.

A modification adds mass, damping and stiffness between physical DOFs of the
model (points of the FE model along directions, or the DOFs of rigid bodies it
adds).  With ``T`` the rows that map the model's coordinates (modal
coordinates ``q`` plus 6 coordinates per added body) to those physical DOFs,
the modified system in coordinates is (thesis eqs. 2.27–2.29 with the extra
matrices projected)::

    (diag(1) + Tᵀ ΔM T) q̈ + (diag(2ζω) + Tᵀ ΔC T) q̇ + (diag(ω²) + Tᵀ ΔK T) q = Tᵀ f

:class:`~receptance.modal_model.ModalModel` assembles and solves it once into
poles and residues.  A new physical effect is one small class: subclass
:class:`Modification`, give it a ``kind`` and implement :meth:`terms` (and
:meth:`bodies` if it adds a body); register it with :func:`register` so model
files can store it.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable, ClassVar, Sequence

import numpy as np

__all__ = [
    "Modification", "Term", "RigidBody", "GroundSprings", "PrimarySuspension", "Spring", "PointMass",
    "MODIFICATIONS", "register", "modification_from_dict", "ModificationError", "ROLES",
]

#: what a modification is to the wheelset in service (:meth:`receptance.ModalModel.for_service`)
ROLES = {
    "test_artefact": "present only during the modal test (rig, sensors): removed for service",
    "wheelset": "a property of the wheelset itself (bearing, press fit, added mass): kept in service",
    "service": "the wheelset's environment in service (primary suspension, supports)",
}


class ModificationError(ValueError):
    """A modification with bad parameters (names the modification and the parameter)."""


@dataclass(frozen=True)
class Term:
    """``ΔM, ΔC, ΔK`` between the physical DOFs whose rows (over the model's coordinates) are ``rows``."""

    rows: np.ndarray  # (n_a, n_coords) real
    M: np.ndarray | None = None  # (n_a, n_a)
    C: np.ndarray | None = None
    K: np.ndarray | None = None  # may be complex (loss factor)


@dataclass(frozen=True)
class RigidBody:
    """A rigid body added to the model with 6 DOFs (translations, then rotations about its centre).

    Parameters
    ----------
    name : str
        DOFs of the body are addressed as ``"<name>:x"`` ... ``"<name>:rz"``.
    mass : float
        [kg].
    inertia : tuple of 3 float
        Principal moments about x, y, z through ``centre`` [kg m²].
    centre : tuple of 3 float
        [m].
    carries : tuple of int
        FE nodes whose motion the body now carries (sensors and points
        attached to these nodes move with the body, not with the FE modes).
    reference_node : int, optional
        For a flexible part (a wheel on a compliant seat): the carried nodes
        move with the body *plus* their FE deformation relative to the rigid
        motion of this FE node (a floating frame): ``u = u_body + θ_body × r +
        (u_FE − u_FE,rigid about the reference node)``.  None: the carried
        nodes move rigidly with the body (an axlebox).
    carried_points : tuple of str, optional
        Named points (model points such as ``axlebox_L``, sensors by channel
        name) that move with the body whatever node they are attached to: a
        part the FE lumped into another part's node (an axlebox lumped on the
        journal) or left out has no node of its own.
    """

    name: str
    mass: float
    inertia: tuple[float, float, float]
    centre: tuple[float, float, float]
    carries: tuple[int, ...] = ()
    reference_node: int | None = None
    carried_points: tuple[str, ...] = ()

    def mass_matrix(self) -> np.ndarray:
        return np.diag([self.mass] * 3 + list(self.inertia)).astype(float)


class Modification:
    """Base class of structural modifications (see the module docstring).

    Subclasses are frozen dataclasses with a class attribute ``kind`` (the
    name used in model files and reports) and implement :meth:`terms`.
    """

    kind: ClassVar[str] = ""
    #: present while the wheelset was tested (rig, bearings, sensors): see ModalModel.pins_test_modes
    in_test: ClassVar[bool] = False
    #: one of :data:`ROLES`: whether the in-service model keeps it (ModalModel.for_service)
    role: ClassVar[str] = "wheelset"

    def bodies(self) -> tuple[RigidBody, ...]:
        """Rigid bodies this modification adds (default none)."""
        return ()

    def terms(self, rows: Callable[[Sequence], np.ndarray]) -> list[Term]:  # pragma: no cover - interface
        """The mass, damping and stiffness it adds.

        Parameters
        ----------
        rows : callable
            ``rows(dof_specs)`` returns the rows (n, n_coords) of the named
            DOFs (``"axlebox_L:z"``, ``"<body>:ry"``, thesis numbers...).
        """
        raise NotImplementedError

    def describe(self) -> str:
        """One line for a model's history: the parameters, long arrays summarised by their size."""
        parts = []
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            size = np.size(np.asarray(v, dtype=object)) if isinstance(v, (tuple, list, np.ndarray)) else 1
            parts.append(f"{f.name}=<{size} values>" if size > 12 else f"{f.name}={_jsonable(v)!r}")
        return f"{self.kind}({', '.join(parts)})"

    def to_dict(self) -> dict:
        """JSON-ready parameters (``kind`` plus the dataclass fields)."""
        out = {"kind": self.kind}
        for f in dataclasses.fields(self):
            out[f.name] = _jsonable(getattr(self, f.name))
        return out


MODIFICATIONS: dict[str, type] = {}


def register(cls: type) -> type:
    """Class decorator: make a modification storable in model files under its ``kind``."""
    if not cls.kind:
        raise ModificationError(f"{cls.__name__} needs a non-empty class attribute 'kind'")
    MODIFICATIONS[cls.kind] = cls
    return cls


def modification_from_dict(d: dict) -> Modification:
    """Rebuild a modification stored by :meth:`Modification.to_dict` (ModificationError naming what is wrong:
    an entry that is not an object, an unknown kind, parameters the kind does not take)."""
    if not isinstance(d, dict):
        raise ModificationError(f"a stored modification must be an object {{\"kind\": ..., parameters}}, got "
                                f"{type(d).__name__} {d!r:.60}")
    kind = d.get("kind")
    if not isinstance(kind, str) or kind not in MODIFICATIONS:
        raise ModificationError(f"unknown modification kind {kind!r}; registered kinds: {sorted(MODIFICATIONS)}")
    cls = MODIFICATIONS[kind]
    params = {k: _from_json(v) for k, v in d.items() if k != "kind"}
    try:
        return cls(**params)
    except TypeError as exc:
        raise ModificationError(f"modification {kind!r}: {exc}") from None


def _jsonable(v):
    if isinstance(v, (np.floating, np.integer)):
        return v.item()
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, tuple):
        return [_jsonable(x) for x in v]
    if isinstance(v, RigidBody):
        return {"__body__": {f.name: _jsonable(getattr(v, f.name)) for f in dataclasses.fields(v)}}
    return v


def _from_json(v):
    if isinstance(v, dict) and "__body__" in v:
        b = v["__body__"]
        return RigidBody(b["name"], b["mass"], tuple(b["inertia"]), tuple(b["centre"]), tuple(b["carries"]),
                         b.get("reference_node"), tuple(b.get("carried_points", ())))
    if isinstance(v, list):
        return tuple(_from_json(x) for x in v)
    return v


def _positive(name: str, values, *, what: str, allow_zero: bool = True) -> tuple[float, ...]:
    arr = np.atleast_1d(np.asarray(values, float))
    bad = ~np.isfinite(arr) | (arr < 0) | ((arr == 0) & (not allow_zero))
    if bad.any():
        raise ModificationError(f"{what}: {name} must be finite and {'>=' if allow_zero else '>'} 0, got {values!r}")
    return tuple(float(v) for v in arr)


@register
@dataclass(frozen=True)
class GroundSprings(Modification):
    """Springs and viscous dampers from points to ground along x, y, z (and optionally about x, y, z).

    Parameters
    ----------
    points : tuple of str
        Point names (each gets the same springs).
    stiffness : (kx, ky, kz)
        Translational stiffness per point [N/m].
    damping : (cx, cy, cz)
        Viscous damping per point [N s/m].
    rotational_stiffness : (krx, kry, krz), optional
        [N m/rad].
    rotational_damping : (crx, cry, crz), optional
        [N m s/rad].
    loss_factor : float, optional
        Hysteretic loss factor η: stiffness ``k (1 + iη)``.
    """

    kind: ClassVar[str] = "ground_springs"
    role: ClassVar[str] = "service"
    points: tuple[str, ...] = ("axlebox_L", "axlebox_R")
    stiffness: tuple[float, float, float] = (0.0, 0.0, 0.0)
    damping: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotational_stiffness: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotational_damping: tuple[float, float, float] = (0.0, 0.0, 0.0)
    loss_factor: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "points", tuple(str(p) for p in self.points))
        for name in ("stiffness", "damping", "rotational_stiffness", "rotational_damping"):
            vals = _positive(name, getattr(self, name), what=self.kind)
            if len(vals) != 3:
                raise ModificationError(f"{self.kind}: {name} needs 3 values (x, y, z), got {getattr(self, name)!r}")
            object.__setattr__(self, name, vals)
        _positive("loss_factor", self.loss_factor, what=self.kind)
        if not self.points:
            raise ModificationError(f"{self.kind}: give at least one point")

    def terms(self, rows) -> list[Term]:
        k = np.array(self.stiffness + self.rotational_stiffness) * (1 + 1j * self.loss_factor)
        c = np.array(self.damping + self.rotational_damping)
        axes = ("x", "y", "z", "rx", "ry", "rz")
        active = (k != 0) | (c != 0)
        out = []
        for p in self.points:
            specs = [f"{p}:{a}" for a, on in zip(axes, active) if on]
            if specs:
                out.append(Term(rows(specs), K=np.diag(k[active]), C=np.diag(c[active])))
        return out


@register
@dataclass(frozen=True)
class PrimarySuspension(GroundSprings):
    """The primary suspension of thesis Table 2.1, to ground at both axleboxes (thesis §2.3, §4.1).

    Table 2.1 gives the stiffness as ``2 × value`` (two spring units per
    axlebox: x 2×4.15, y 2×2.1, z 2×0.5 kN/mm) and one damper per axlebox
    (x 85, y 50, z 11 kN s/m).  Bogie motion is neglected (thesis §2.3), so
    the springs go to ground.  Gives the bounce and roll modes near 7 and 9 Hz.
    """

    kind: ClassVar[str] = "primary_suspension"
    stiffness: tuple[float, float, float] = (2 * 4.15e6, 2 * 2.1e6, 2 * 0.5e6)
    damping: tuple[float, float, float] = (85e3, 50e3, 11e3)


@register
@dataclass(frozen=True)
class Spring(Modification):
    """One spring–damper along a DOF, between two DOFs (relative motion ``x_a − x_b``) or to ground.

    Parameters
    ----------
    a : str
        DOF spec (``"axlebox_L:z"``, ``"<body>:ry"``, thesis number...).
    b : str, optional
        Second DOF; None grounds the spring.
    stiffness : float
        [N/m] or [N m/rad].
    damping : float
        [N s/m] or [N m s/rad].
    loss_factor : float
    """

    kind: ClassVar[str] = "spring"
    a: str = ""
    b: str | None = None
    stiffness: float = 0.0
    damping: float = 0.0
    loss_factor: float = 0.0

    def __post_init__(self) -> None:
        if not self.a:
            raise ModificationError("spring: give the DOF 'a' it acts on")
        _positive("stiffness", self.stiffness, what=f"spring at {self.a}")
        _positive("damping", self.damping, what=f"spring at {self.a}")
        _positive("loss_factor", self.loss_factor, what=f"spring at {self.a}")

    def terms(self, rows) -> list[Term]:
        r = rows([self.a])
        if self.b is not None:
            r = r - rows([self.b])
        k = np.array([[self.stiffness * (1 + 1j * self.loss_factor)]])
        return [Term(r, K=k, C=np.array([[float(self.damping)]]))]


@register
@dataclass(frozen=True)
class PointMass(Modification):
    """A mass (and optionally rotary inertia) attached at a point (sensor, fixture, thesis §3.2 mass loading).

    Parameters
    ----------
    point : str
    mass : float
        [kg]; negative values remove mass (e.g. an FE lumped mass that a
        modification moves elsewhere).
    inertia : (Ixx, Iyy, Izz), optional
        [kg m²] about the point.
    """

    kind: ClassVar[str] = "point_mass"
    point: str = ""
    mass: float = 0.0
    inertia: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        if not self.point:
            raise ModificationError("point_mass: give the point it sits at")
        vals = np.asarray((self.mass,) + tuple(self.inertia), float)
        if vals.size != 4 or not np.all(np.isfinite(vals)):
            raise ModificationError(f"point_mass at {self.point}: mass and 3 inertias must be finite, got "
                                    f"{self.mass!r}, {self.inertia!r}")
        object.__setattr__(self, "inertia", tuple(float(v) for v in self.inertia))

    def terms(self, rows) -> list[Term]:
        axes = ["x", "y", "z"]
        m = [self.mass] * 3
        for a, i in zip(("rx", "ry", "rz"), self.inertia):
            if i != 0:
                axes.append(a)
                m.append(i)
        return [Term(rows([f"{self.point}:{a}" for a in axes]), M=np.diag(m))]
