"""Named points and degrees of freedom of the wheelset model (thesis Fig. 2.5).

The thesis numbers the wheelset DOFs 1–12: 1–3 left contact point x, y, z;
4–6 left axlebox; 7–9 right contact point; 10–12 right axlebox.  The toolkit
names them too (``contact_L:z``, ``axlebox_R:y``) and accepts both.  A DOF is
a point (rigidly attached to an FE node, possibly off the FE grid) and a
measuring direction: a translation along a unit vector, or a rotation about
one (``rx``, ``ry``, ``rz``).  Sensors of a channel table are DOFs too, named
by their channel name.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

import numpy as np
import pandas as pd

__all__ = [
    "THESIS_DOFS", "Point", "Dof", "DofError", "read_points", "check_points", "parse_dof", "parse_dofs",
    "dofs_from_channels", "shifted_point",
]

#: thesis Fig. 2.5 numbering -> name
THESIS_DOFS: dict[int, str] = {
    1: "contact_L:x", 2: "contact_L:y", 3: "contact_L:z",
    4: "axlebox_L:x", 5: "axlebox_L:y", 6: "axlebox_L:z",
    7: "contact_R:x", 8: "contact_R:y", 9: "contact_R:z",
    10: "axlebox_R:x", 11: "axlebox_R:y", 12: "axlebox_R:z",
}
_AXES = {"x": 0, "y": 1, "z": 2}
_SPEC = re.compile(r"^(?P<point>[^:]+):(?P<sign>[+-]?)(?P<rot>r?)(?P<axis>[xyz])$")


class DofError(ValueError):
    """A DOF or point specification that cannot be resolved (names the spec and what is known)."""


@dataclass(frozen=True)
class Point:
    """A point rigidly attached to an FE node.

    Parameters
    ----------
    name : str
    fe_node : int or None
        Node the point is attached to (None: the nearest node within the
        model's tolerance).
    xyz : tuple of float, optional
        Position [m]; None means "at the node" (zero offset).
    """

    name: str
    fe_node: int | None
    xyz: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        if self.fe_node is not None:
            object.__setattr__(self, "fe_node", int(self.fe_node))
        if self.xyz is not None:
            xyz = tuple(float(v) for v in np.asarray(self.xyz, float).ravel())
            if len(xyz) != 3 or not np.all(np.isfinite(xyz)):
                raise DofError(f"point {self.name!r}: xyz must be 3 finite coordinates [m], got {self.xyz!r}")
            object.__setattr__(self, "xyz", xyz)
        if self.fe_node is None and self.xyz is None:
            raise DofError(f"point {self.name!r}: give an fe_node, a position, or both")


@dataclass(frozen=True)
class Dof:
    """A point and a direction: translation along, or rotation about, the unit vector ``direction``."""

    label: str
    point: Point
    direction: tuple[float, float, float]
    rotation: bool = False
    extra: Mapping = field(default_factory=dict, compare=False, repr=False)

    def __post_init__(self) -> None:
        d = np.asarray(self.direction, float).ravel()
        n = np.linalg.norm(d) if d.size == 3 else 0.0
        if d.size != 3 or not np.isfinite(n) or n == 0:
            raise DofError(f"DOF {self.label!r}: direction must be a finite non-zero 3-vector, got {self.direction!r}")
        object.__setattr__(self, "direction", tuple(float(v) for v in d / n))


def read_points(path: str | Path) -> dict[str, Point]:
    """Read a points table (``name, fe_node, x, y, z``; e.g. the lab's ``points.csv``).

    The separator and a decimal comma are detected, a UTF-8 byte-order mark
    is accepted (:func:`ema.channels.read_table_csv`).

    Raises
    ------
    FileNotFoundError
        No such file.
    DofError
        A folder instead of a file, missing columns, duplicate or empty names,
        a value that is not a number or a node label that is not a positive
        integer (names the file, the row, the column and the value).
    """
    from ema.channels import MAX_NODE, read_table_csv

    path = Path(path)
    df = read_table_csv(path, role="points table", required=("name", "fe_node", "x", "y", "z"), error=DofError)
    missing = [c for c in ("name", "fe_node", "x", "y", "z") if c not in df.columns]
    if missing:
        raise DofError(f"{path}: points table lacks column(s) {missing}; expected name, fe_node, x, y, z "
                       f"(found {list(df.columns)})")
    if len(df) == 0:
        raise DofError(f"{path}: the points table has no rows")
    names = df["name"].astype(object)
    for k, v in enumerate(names):
        if pd.isna(v) or not str(v).strip():
            raise DofError(f"{path}, row {k + 1}, column 'name': the point name is missing")
    names = names.astype(str).str.strip()
    if names.duplicated().any():
        raise DofError(f"{path}: duplicate point name(s) {sorted(names[names.duplicated()].unique())}")
    points = {}
    for k, (name, row) in enumerate(zip(names, df.itertuples(index=False)), 1):
        node = _cell(path, k, "fe_node", getattr(row, "fe_node"), name)
        if node is not None and not (node == round(node) and 0 < node <= MAX_NODE):
            raise DofError(f"{path}, row {k} ({name}), column 'fe_node': expected a positive integer node label up "
                           f"to {MAX_NODE}, got {getattr(row, 'fe_node')!r}")
        xyz = [_cell(path, k, c, getattr(row, c), name) for c in ("x", "y", "z")]
        if any(v is None for v in xyz) and not all(v is None for v in xyz):
            c = ("x", "y", "z")[[v is None for v in xyz].index(True)]
            raise DofError(f"{path}, row {k} ({name}), column {c!r}: the coordinate is missing (give x, y and z, "
                           f"or none for a point at its node)")
        try:
            points[name] = Point(name, None if node is None else int(node),
                                 None if xyz[0] is None else tuple(xyz))
        except DofError as exc:
            raise DofError(f"{path}, row {k}: {exc}") from None
    return points


def _cell(path: Path, row: int, column: str, value, name: str) -> float | None:
    """A numeric cell as float (None when empty), or DofError naming file, row, column and value."""
    if value is None or (isinstance(value, float) and np.isnan(value)) or (isinstance(value, str) and not value.strip()):
        return None
    try:
        v = float(value)
    except (TypeError, ValueError, OverflowError):
        raise DofError(f"{path}, row {row} ({name}), column {column!r}: expected a number, got {value!r}") from None
    if not np.isfinite(v):
        raise DofError(f"{path}, row {row} ({name}), column {column!r}: expected a finite number, got {value!r}")
    return v


def check_points(fe, points: Mapping[str, Point], *, source: str = "") -> None:
    """Every point's ``fe_node`` is in the FE model and the point lies near it.

    The tolerance scales with the model (:data:`fem_import.checks.POINT_OFFSET_FRACTION`
    of its size); a point explained by a unit slip is named so ("looks like
    cm").

    Raises
    ------
    DofError
        An fe_node that is not in the FE model (names the point and the source).
    fem_import.PointToleranceError
        A point far from its node.
    """
    from fem_import.checks import check_point_offsets

    where = f"{source}: " if source else ""
    known = set(np.asarray(fe.node_ids).tolist())
    for p in points.values():
        if p.fe_node is not None and p.fe_node not in known:
            raise DofError(f"{where}point {p.name!r}: fe_node {p.fe_node} is not a node of the FE model "
                           f"({fe.source or 'FE modes'}, {len(known)} nodes)")
    placed = [p for p in points.values() if p.fe_node is not None and p.xyz is not None]
    if placed and fe.has_coordinates:
        check_point_offsets(fe, [p.fe_node for p in placed], [p.xyz for p in placed], [repr(p.name) for p in placed],
                            source=source)


def shifted_point(point: Point, offset_m, name: str | None = None) -> Point:
    """The point moved by ``offset_m`` (3-vector [m]) and still attached to the same node.

    This is how an accelerometer mounted off the axlebox centre is modelled
    (thesis §4.3.5: ±10, ±30, ±50 mm): the node's rotations act through the
    offset.
    """
    off = np.asarray(offset_m, float).ravel()
    if off.size != 3 or not np.all(np.isfinite(off)):
        raise DofError(f"offset must be 3 finite values [m], got {offset_m!r}")
    if point.xyz is None:
        raise DofError(f"point {point.name!r} has no position, so it cannot be shifted; give it x, y, z")
    if name is None:
        mm = ",".join(f"{1000 * v:+g}" for v in off)
        name = f"{point.name}@({mm})mm"
    return Point(name, point.fe_node, tuple(np.asarray(point.xyz) + off))


def parse_dof(spec, points: Mapping[str, Point]) -> Dof:
    """Resolve a DOF specification.

    Accepted forms: a :class:`Dof`; a thesis number 1–12 (int or digit
    string, Fig. 2.5); ``"name:axis"`` with axis ``x, y, z`` (translation),
    ``rx, ry, rz`` (rotation), optionally signed (``"axlebox_L:-y"``); a
    tuple ``(point_name_or_Point, direction_3vector)`` with an optional label
    as third item.

    Raises
    ------
    DofError
        Names the specification and the known points.
    """
    if isinstance(spec, Dof):
        return spec
    if isinstance(spec, (int, np.integer)) or (isinstance(spec, str) and spec.strip().isdigit()):
        number = int(spec)
        if number not in THESIS_DOFS:
            raise DofError(f"DOF number {number} is not in the thesis numbering 1–12 (Fig. 2.5)")
        return parse_dof(THESIS_DOFS[number], points)
    if isinstance(spec, tuple) and len(spec) in (2, 3):
        pt = spec[0] if isinstance(spec[0], Point) else _point(str(spec[0]), points, str(spec))
        label = spec[2] if len(spec) == 3 else f"{pt.name}:{tuple(np.round(np.asarray(spec[1], float), 6))}"
        return Dof(str(label), pt, tuple(np.asarray(spec[1], float)))
    if isinstance(spec, str):
        m = _SPEC.match(spec.strip())
        if not m:
            raise DofError(f"DOF {spec!r}: expected 'point:axis' (axis x, y, z, rx, ry, rz, optionally signed), "
                           f"a thesis number 1–12, or (point, direction)")
        pt = _point(m["point"], points, spec)
        d = np.zeros(3)
        d[_AXES[m["axis"]]] = -1.0 if m["sign"] == "-" else 1.0
        return Dof(spec.strip(), pt, tuple(d), rotation=bool(m["rot"]))
    raise DofError(f"cannot read DOF specification {spec!r}")


def parse_dofs(specs, points: Mapping[str, Point]) -> list[Dof]:
    """:func:`parse_dof` over a sequence; a single spec is accepted too; labels must be unique."""
    if isinstance(specs, (str, int, np.integer, Dof)) or (isinstance(specs, tuple) and len(specs) in (2, 3)
                                                         and not isinstance(specs[0], (str, Dof, tuple))):
        specs = [specs]
    dofs = [parse_dof(s, points) for s in specs]
    labels = [d.label for d in dofs]
    dup = sorted({lab for lab in labels if labels.count(lab) > 1})
    if dup:
        raise DofError(f"DOF labels must be unique, repeated: {dup}")
    return dofs


def dofs_from_channels(channels: pd.DataFrame, *, quantity: str | None = None) -> list[Dof]:
    """One DOF per channel-table row (``name, x, y, z, dx, dy, dz``, optional ``fe_node``), labelled by name.

    Parameters
    ----------
    channels : pandas.DataFrame
        Channel table (``shared/DESIGN.md`` schema).
    quantity : str, optional
        Keep only rows of this quantity (``"acceleration"`` or ``"force"``).
    """
    need = [c for c in ("name", "x", "y", "z", "dx", "dy", "dz") if c not in channels.columns]
    if need:
        raise DofError(f"channel table lacks column(s) {need}")
    rows = channels if quantity is None else channels[channels["quantity"] == quantity]
    out = []
    for _, r in rows.iterrows():
        node = r.get("fe_node", None)
        node = None if node is None or pd.isna(node) else int(node)
        pt = Point(str(r["name"]), node, (r["x"], r["y"], r["z"]))
        out.append(Dof(str(r["name"]), pt, (r["dx"], r["dy"], r["dz"])))
    return out


def _point(name: str, points: Mapping[str, Point], spec: str) -> Point:
    try:
        return points[name]
    except KeyError:
        known = sorted(points) if points else "none (pass points=, e.g. read_points('points.csv'))"
        raise DofError(f"DOF {spec!r}: unknown point {name!r}; known points: {known}") from None
