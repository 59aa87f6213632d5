"""Nastran coordinate systems: grid positions (CP) and displacement directions (CD) in the basic system.

A design office meshes a wheel in a cylindrical system (radius, angle, axle position) and often asks Nastran for
its displacements there too. Nastran punches each grid's eigenvector in that grid's displacement system (``CD``),
so the components of a wheel grid are radial, tangential and axial, not x, y, z. This module gives every grid its
basic position and the rotation from its ``CD`` components to basic ones (MSC Nastran Quick Reference Guide,
CORD1R/C/S, CORD2R/C/S, GRID):

* **CORD2R/C/S** ``CID RID A1 A2 A3 B1 B2 B3 C1 C2 C3``: origin ``A``, a point ``B`` on the local z axis and a point
  ``C`` in the local x–z plane, all given in system ``RID`` (0 or blank: basic; a cylindrical or spherical ``RID``
  takes them in its own coordinates). ``e3 = (B − A)/|B − A|``, ``e2 = e3 × (C − A)`` normalised, ``e1 = e2 × e3``.
* **CORD1R/C/S** ``CIDA G1A G2A G3A CIDB G1B G2B G3B``: the same three points as grids (origin, z axis, x–z plane),
  at their basic positions; one entry may define two systems.
* A position in a rectangular system is ``(x, y, z)``; in a cylindrical one ``(R, θ [deg], z)``; in a spherical one
  ``(R, θ [deg], φ [deg])`` with ``x = R sinθ cosφ, y = R sinθ sinφ, z = R cosθ``.
* Displacement components (translations and rotations alike) in a rectangular system are along ``e1, e2, e3``; in
  a cylindrical one along the local radial, tangential and axial unit vectors at the grid, in a spherical one along
  ``e_R, e_θ, e_φ`` there. On a cylindrical system's axis (``R = 0``) the radial direction is undefined; ``θ = 0``
  is taken (``e1``), as Nastran does.

Systems may be defined in terms of each other and of grids in other systems: they are resolved in passes until
nothing changes, and what stays unresolved (an undefined ``RID``, a cycle, a CORD1 on an undefined grid) is named.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import FEReadError

__all__ = ["CoordSystem", "BASIC", "resolve"]


@dataclass(frozen=True)
class CoordSystem:
    """One resolved coordinate system: its kind (``"R"``, ``"C"``, ``"S"``), origin and axes in basic."""

    cid: int
    kind: str
    origin: np.ndarray  # (3,)
    axes: np.ndarray  # (3, 3), columns e1, e2, e3 in basic

    def to_basic(self, p) -> np.ndarray:
        """Basic position of the point whose coordinates in this system are ``p`` (module docstring)."""
        a, b, c = (float(v) for v in p)
        if self.kind == "R":
            local = np.array([a, b, c])
        elif self.kind == "C":
            t = math.radians(b)
            local = np.array([a * math.cos(t), a * math.sin(t), c])
        else:
            t, f = math.radians(b), math.radians(c)
            local = np.array([a * math.sin(t) * math.cos(f), a * math.sin(t) * math.sin(f), a * math.cos(t)])
        return self.origin + self.axes @ local

    def frame_at(self, basic) -> np.ndarray:
        """Columns: the unit vectors of this system's displacement components at the basic point ``basic``."""
        if self.kind == "R":
            return self.axes.copy()
        x, y, z = self.axes.T @ (np.asarray(basic, float) - self.origin)
        phi = math.atan2(y, x) if (x, y) != (0.0, 0.0) else 0.0
        if self.kind == "C":
            local = np.array([[math.cos(phi), -math.sin(phi), 0.0],
                              [math.sin(phi), math.cos(phi), 0.0],
                              [0.0, 0.0, 1.0]])
        else:
            theta = math.atan2(math.hypot(x, y), z)
            st, ct, sp, cp = math.sin(theta), math.cos(theta), math.sin(phi), math.cos(phi)
            local = np.array([[st * cp, ct * cp, -sp],
                              [st * sp, ct * sp, cp],
                              [ct, -st, 0.0]])
        return self.axes @ local


BASIC = CoordSystem(0, "R", np.zeros(3), np.eye(3))


def _axes(path: str, what: str, a: np.ndarray, b: np.ndarray, c: np.ndarray, line: int) -> np.ndarray:
    e3 = b - a
    n3 = np.linalg.norm(e3)
    if not n3 > 0:
        raise FEReadError(path, f"{what}: its z-axis point B coincides with its origin A", line=line)
    e3 = e3 / n3
    e2 = np.cross(e3, c - a)
    n2 = np.linalg.norm(e2)
    if not n2 > 1e-12 * max(n3, np.linalg.norm(c - a)):
        raise FEReadError(path, f"{what}: its x-z plane point C lies on its z axis", line=line)
    e2 = e2 / n2
    return np.column_stack([np.cross(e2, e3), e2, e3])


def resolve(path: str, cord2: dict, cord1: dict, grids: dict) -> tuple[dict[int, CoordSystem], dict[int, np.ndarray]]:
    """Every coordinate system and every grid's basic position.

    Parameters
    ----------
    path : str
        The deck (for messages).
    cord2 : dict
        ``cid -> (kind, rid, A, B, C, line)`` of the CORD2x entries.
    cord1 : dict
        ``cid -> (kind, (g1, g2, g3), line)`` of the CORD1x entries.
    grids : dict
        ``gid -> (cp, (x1, x2, x3), line)``.

    Returns
    -------
    systems : dict
        ``cid -> CoordSystem`` (0 is basic).
    positions : dict
        ``gid -> basic position``.

    Raises
    ------
    FEReadError
        A system defined twice, a system or grid left unresolved (names it, its line and what it waits for), or a
        degenerate system.
    """
    systems: dict[int, CoordSystem] = {0: BASIC}
    positions: dict[int, np.ndarray] = {}
    twice = set(cord2) & set(cord1)
    if twice:
        cid = min(twice)
        raise FEReadError(path, f"coordinate system {cid} is defined twice (CORD2 at line {cord2[cid][-1]}, CORD1 at "
                                f"line {cord1[cid][-1]})", line=cord1[cid][-1])
    todo2, todo1 = dict(cord2), dict(cord1)
    todo_g = {g: v for g, v in grids.items()}
    changed = True
    while changed:
        changed = False
        for g, (cp, x, line) in list(todo_g.items()):
            if cp in systems:
                positions[g] = systems[cp].to_basic(x)
                del todo_g[g]
                changed = True
        for cid, (kind, rid, a, b, c, line) in list(todo2.items()):
            if rid in systems:
                ref = systems[rid]
                pa, pb, pc = ref.to_basic(a), ref.to_basic(b), ref.to_basic(c)
                systems[cid] = CoordSystem(cid, kind, pa, _axes(path, f"CORD2{kind} {cid}", pa, pb, pc, line))
                del todo2[cid]
                changed = True
        for cid, (kind, gs, line) in list(todo1.items()):
            if all(g in positions for g in gs):
                pa, pb, pc = (positions[g] for g in gs)
                systems[cid] = CoordSystem(cid, kind, pa, _axes(path, f"CORD1{kind} {cid}", pa, pb, pc, line))
                del todo1[cid]
                changed = True
    if todo2:
        cid, (kind, rid, *_, line) = min(todo2.items())
        why = "is not defined" if rid not in cord2 and rid not in cord1 else "is not resolved (a cycle?)"
        raise FEReadError(path, f"CORD2{kind} {cid} is given in system {rid}, which {why}", line=line)
    if todo1:
        cid, (kind, gs, line) = min(todo1.items())
        missing = [g for g in gs if g not in positions]
        raise FEReadError(path, f"CORD1{kind} {cid} is defined by grid(s) {missing} that no GRID entry places",
                          line=line)
    if todo_g:
        g, (cp, _, line) = min(todo_g.items())
        raise FEReadError(path, f"GRID {g} is given in coordinate system CP = {cp}, which no CORD entry defines",
                          line=line)
    return systems, positions
