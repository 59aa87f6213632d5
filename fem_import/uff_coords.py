"""Coordinate systems of a universal file's dataset 18 and the nodes given in them.

Dataset 18 (UC-SDRL description, ``pyuff.get_structure_18()``) defines each local system by three points given in
its reference system: the origin ``O``, a point ``X`` on the +x axis and a point ``P`` in the +xz plane (method of
definition 1), with the system's type (0 Cartesian, 1 cylindrical, 2 spherical). The axes follow without any
convention to guess: ``e1 = (X − O)/|X − O|``, ``e2 = (P − O) × e1`` normalised (``P − O = a e1 + c e3`` with
``c > 0``), ``e3 = e1 × e2``.

What a node's two system labels (dataset 2411/15: definition and displacement) mean here:

* **definition system** (the coordinates): Cartesian — ``x_global = O + [e1 e2 e3] x_local``. A cylindrical or
  spherical definition system is refused: the format does not say whether its angles are in degrees or radians,
  nor (spherical) which angle is the polar one;
* **displacement system** (the mode shape's components): Cartesian — the components are along ``e1, e2, e3``;
  cylindrical — along the radial, tangential and axial unit vectors at the node's global position (unambiguous:
  no angle is read); spherical — refused (its component order is exporter-specific).

Rotations, like translations, are components of a vector and turn with the same matrix.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import FEReadError
from .nastran_coords import BASIC, CoordSystem

__all__ = ["System18", "systems_18", "resolve_18", "KINDS"]

#: dataset 18's system types, as :class:`~fem_import.nastran_coords.CoordSystem` names them
KINDS = {0: "R", 1: "C", 2: "S"}
_NAMES = {0: "Cartesian", 1: "cylindrical", 2: "spherical"}


@dataclass(frozen=True)
class System18:
    """One coordinate system of a dataset 18, as written (points in its reference system, file units)."""

    label: int
    kind: int
    reference: int
    name: str
    origin: np.ndarray
    x_point: np.ndarray
    xz_point: np.ndarray
    line: int

    def describe(self) -> str:
        return (f"coordinate system {self.label} ({_NAMES.get(self.kind, f'type {self.kind}')}"
                f"{', ' + repr(self.name) if self.name else ''}; dataset 18 at line {self.line})")


def systems_18(path: str, dset: dict, line: int) -> list[System18]:
    """The systems of one dataset 18 as pyuff read it; a truncated record or an unknown type is named."""
    try:
        labels = np.asarray(dset["cs_num"], float).ravel()
        kinds = np.asarray(dset["cs_type"], float).ravel()
        refs = np.asarray(dset["ref_cs_num"], float).ravel()
        methods = np.asarray(dset["method"], float).ravel()
        names = [str(v) for v in dset["cs_name"]]
        pts = [np.asarray(dset[k], float).reshape(-1, 3) for k in ("ref_o", "x_point", "xz_point")]
    except (KeyError, TypeError, ValueError) as exc:
        raise FEReadError(path, f"pyuff returned no usable coordinate-system table ({exc!r})", dataset="18",
                          line=line) from exc
    n = labels.size
    if not (kinds.size == refs.size == methods.size == len(names) == n and all(p.shape[0] == n for p in pts)):
        raise FEReadError(path, "coordinate systems with missing records (3 records each: labels, name, 9 "
                          "definition values): a record is truncated", dataset="18", line=line)
    out = []
    for i in range(n):
        ints = (labels[i], kinds[i], refs[i], methods[i])
        if not all(np.isfinite(v) and v == round(v) and v >= 0 for v in ints):
            raise FEReadError(path, f"system record {i + 1}: label, type, reference and method must be non-negative "
                              f"integers, got {[float(v) for v in ints]}", dataset="18", line=line)
        label, kind, ref, method = (int(v) for v in ints)
        if kind not in KINDS:
            raise FEReadError(path, f"coordinate system {label}: type {kind} is not 0 (Cartesian), 1 (cylindrical) "
                              "or 2 (spherical)", dataset="18", line=line)
        if method != 1:
            raise FEReadError(path, f"coordinate system {label}: method of definition {method}; only 1 (origin, "
                              "+x axis point, +xz plane point) is defined by the format", dataset="18", line=line)
        o, x, p = (q[i] for q in pts)
        if not (np.all(np.isfinite(o)) and np.all(np.isfinite(x)) and np.all(np.isfinite(p))):
            raise FEReadError(path, f"coordinate system {label}: non-finite definition points", dataset="18",
                              line=line)
        out.append(System18(label, kind, ref, names[i].strip(), o, x, p, line))
    return out


def _axes(path: str, s: System18) -> np.ndarray:
    """Columns ``e1, e2, e3`` in the reference system (module docstring)."""
    e1 = s.x_point - s.origin
    n1 = np.linalg.norm(e1)
    if not n1 > 0:
        raise FEReadError(path, f"{s.describe()}: its +x axis point coincides with its origin", dataset="18",
                          line=s.line)
    e1 = e1 / n1
    e2 = np.cross(s.xz_point - s.origin, e1)
    n2 = np.linalg.norm(e2)
    if not n2 > 1e-9 * max(n1, np.linalg.norm(s.xz_point - s.origin)):
        raise FEReadError(path, f"{s.describe()}: its +xz plane point lies on its x axis", dataset="18",
                          line=s.line)
    e2 = e2 / n2
    return np.column_stack([e1, e2, np.cross(e1, e2)])


def resolve_18(path: str, systems: dict[int, System18], global_labels: set[int]) -> dict[int, CoordSystem]:
    """Every system of ``systems`` with its origin and axes in the global system.

    A reference to label 0, or to a label in ``global_labels`` (the global system under another label), is the
    global system; a reference to another system of dataset 18 must be a Cartesian one (a curvilinear reference
    would give the definition points in angles, see the module docstring). An undefined reference or a cycle is
    named.
    """
    out: dict[int, CoordSystem] = {}

    def resolve(label: int, chain: tuple[int, ...]) -> CoordSystem:
        if label in out:
            return out[label]
        s = systems[label]
        if s.reference in chain + (label,):
            raise FEReadError(path, f"{s.describe()}: its reference systems form a cycle "
                              f"{' -> '.join(map(str, chain + (label, s.reference)))}", dataset="18", line=s.line)
        if s.reference == 0 or s.reference in global_labels:
            ref = BASIC
        elif s.reference in systems:
            ref = resolve(s.reference, chain + (label,))
            if ref.kind != "R":
                raise FEReadError(path, f"{s.describe()}: its reference, system {s.reference}, is "
                                  f"{_NAMES[{'C': 1, 'S': 2}[ref.kind]]}; its definition points would be angles "
                                  "whose unit the format does not state: define it in a Cartesian system",
                                  dataset="18", line=s.line)
        else:
            raise FEReadError(path, f"{s.describe()}: its reference system {s.reference} is not defined by a "
                              "dataset 18", dataset="18", line=s.line)
        axes = _axes(path, s)
        out[label] = CoordSystem(label, KINDS[s.kind], ref.origin + ref.axes @ s.origin, ref.axes @ axes)
        return out[label]

    for label in systems:
        resolve(label, ())
    return out
