"""The structural modifications the catalogued effects add: rig springs, slings, sensor masses, bearings, seats.

They are part of the model (a diagnosed model file stores them by ``kind``,
:mod:`receptance.model_io`); the catalogue that fits them to measurements is
:mod:`receptance.diagnosis.effects`.  Each says whether it was present during
the modal test (``in_test``: the test's frequencies already contain it, see
:attr:`receptance.ModalModel.pins_test_modes`) and what it is to the wheelset
in service (``role``, :data:`receptance.modification.ROLES`): rig springs,
slings and sensor masses are test artefacts, removed by
:meth:`receptance.ModalModel.for_service`; bearings and press fits are
properties of the wheelset, kept.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from receptance.modification import GroundSprings, Modification, PointMass, RigidBody, Term, register

__all__ = ["RigSprings", "SlingSprings", "SensorMasses", "BearingBodies", "SeatJoints", "detached_body_terms"]


@register
@dataclass(frozen=True)
class RigSprings(GroundSprings):
    """Ground springs that were there during the test (crane, bungees): the test's frequencies keep them."""

    kind: ClassVar[str] = "rig_springs"
    in_test: ClassVar[bool] = True
    role: ClassVar[str] = "test_artefact"


@register
@dataclass(frozen=True)
class SlingSprings(Modification):
    """Springs to ground at points along the axle between two FE nodes (slings around the axle body).

    Each hanging point ``k`` lies between the named points ``points_a[k]`` and
    ``points_b[k]`` (the same position, rigidly attached to the two axle
    nodes around it); its motion is ``(1 − t_k)`` times the first's plus
    ``t_k`` times the second's, which is continuous in the position — the
    axial position of the slings can be fitted.  Stiffness ``(kx, ky, kz)``
    per point; a loss factor for the slings' hysteresis.
    """

    kind: ClassVar[str] = "sling_springs"
    in_test: ClassVar[bool] = True
    role: ClassVar[str] = "test_artefact"
    points_a: tuple[str, ...] = ()
    points_b: tuple[str, ...] = ()
    weights: tuple[float, ...] = ()
    stiffness: tuple[float, float, float] = (0.0, 0.0, 0.0)
    loss_factor: float = 0.0

    def terms(self, rows) -> list[Term]:
        k = np.array(self.stiffness, float) * (1 + 1j * self.loss_factor)
        out = []
        for a, b, t in zip(self.points_a, self.points_b, self.weights):
            T = (1 - t) * rows([f"{a}:{ax}" for ax in "xyz"]) + t * rows([f"{b}:{ax}" for ax in "xyz"])
            out.append(Term(T, K=np.diag(k)))
        return out


@register
@dataclass(frozen=True)
class SensorMasses(Modification):
    """Point masses at sensor positions, present during the test (mass loading)."""

    kind: ClassVar[str] = "sensor_masses"
    in_test: ClassVar[bool] = True
    role: ClassVar[str] = "test_artefact"
    points: tuple[str, ...] = ()
    mass: float = 0.0

    def terms(self, rows) -> list[Term]:
        if not self.points:
            return []
        specs = [f"{p}:{a}" for p in self.points for a in ("x", "y", "z")]
        return [Term(rows(specs), M=np.eye(len(specs)) * self.mass)]


def detached_body_terms(rows, anchor: str, body: str, mass: float, inertia, stiffness: dict, loss_factor: float,
                        *, remove: bool = True) -> list[Term]:
    """A part on springs to ``anchor``: springs ``stiffness`` (axis -> value, complex with the loss factor)
    between the new ``body`` and the anchor; with ``remove`` the part's inertia is first taken off the anchor
    (negative point mass: the FE carried it rigidly there, exact for the rigid part of the motion)."""
    out = PointMass(point=anchor, mass=-mass, inertia=tuple(-np.asarray(inertia))).terms(rows) if remove else []
    axes = list(stiffness)
    k = np.array([stiffness[a] for a in axes]) * (1 + 1j * loss_factor)
    rel = rows([f"{body}:{a}" for a in axes]) - rows([f"{anchor}:{a}" for a in axes])
    return out + [Term(rel, K=np.diag(k))]


@register
@dataclass(frozen=True)
class BearingBodies(Modification):
    """Each axlebox as a rigid body on bearing springs to its journal (instead of a rigid link).

    Radial (x, z), axial (y) and rocking (about x and z) springs with a loss
    factor (rolling bearings dissipate: 0.01, about 0.5 % modal damping of
    the axlebox's own modes); spin about the axle stays free.  When the FE
    carries the axlebox (its own node tied to the journal, or its mass lumped
    on the journal: ``remove_from_journal``) its mass and inertia are taken
    off the journal; when the FE lacks it, the body is added.  The body
    carries the axlebox's own FE node (``axlebox_nodes``, 0 for none) and the
    named points ``carried_points`` (per side: the axlebox point and its
    sensors).
    """

    kind: ClassVar[str] = "bearing_bodies"
    in_test: ClassVar[bool] = True
    role: ClassVar[str] = "wheelset"
    sides: tuple[str, ...] = ("L", "R")
    axlebox_nodes: tuple[int, ...] = ()
    journal_nodes: tuple[int, ...] = ()
    centres: tuple = ()
    mass: float = 78.0
    inertia: tuple[float, float, float] = (1.3, 1.6, 1.3)
    radial: float = 1e9
    axial: float = 2.5e8
    rocking: float = 5e6
    loss_factor: float = 0.01
    remove_from_journal: bool = True
    carried_points: tuple = ()

    def bodies(self) -> tuple[RigidBody, ...]:
        names = tuple(self.carried_points) + ((),) * (len(self.sides) - len(self.carried_points))
        return tuple(RigidBody(f"axlebox_body_{s}", self.mass, tuple(self.inertia), tuple(c),
                               (int(n),) if n else (), None, tuple(pts))
                     for s, n, c, pts in zip(self.sides, self.axlebox_nodes, self.centres, names))

    def terms(self, rows) -> list[Term]:
        k = dict(x=self.radial, y=self.axial, z=self.radial, rx=self.rocking, rz=self.rocking)
        return [t for s in self.sides for t in detached_body_terms(
            rows, f"journal_{s}", f"axlebox_body_{s}", self.mass, self.inertia, k, self.loss_factor,
            remove=self.remove_from_journal)]


@register
@dataclass(frozen=True)
class SeatJoints(Modification):
    """Wheels on compliant seats (see :class:`receptance.diagnosis.effects.WheelSeatJoint`); each wheel's
    rigid motion is a body, its deformation stays in the FE modes (floating frame at ``hub_nodes``).

    ``coupling`` holds per side the 6 x modes matrix of the wheel deformation's momentum about the hub (in the
    FE modes' coordinates): with it the body and the FE deformation exchange inertia as they do in the FE.
    ``hub_nodes`` are the frame nodes (a hub node tied to the seat, or the seat itself when the FE lumps the hub
    on it); ``carried`` the wheel's FE nodes.
    """

    kind: ClassVar[str] = "seat_joints"
    in_test: ClassVar[bool] = True
    role: ClassVar[str] = "wheelset"
    sides: tuple[str, ...] = ("L", "R")
    hub_nodes: tuple[int, ...] = ()
    seat_nodes: tuple[int, ...] = ()
    centres: tuple = ()
    carried: tuple = ()
    mass: float = 251.0
    inertias: tuple = ()
    coupling: tuple = ()
    rocking: float = 3e8
    radial: float = 5e9
    axial: float = 3e9
    torsional: float = 5e8
    loss_factor: float = 0.01

    def bodies(self) -> tuple[RigidBody, ...]:
        return tuple(RigidBody(f"wheel_body_{s}", self.mass, tuple(i), tuple(c), tuple(n for n in nodes if n != seat),
                               hub)
                     for s, c, nodes, hub, seat, i in zip(self.sides, self.centres, self.carried, self.hub_nodes,
                                                          self.seat_nodes, self.inertias))

    def terms(self, rows) -> list[Term]:
        k = dict(x=self.radial, y=self.axial, z=self.radial, rx=self.rocking, ry=self.torsional, rz=self.rocking)
        out = []
        axes = ("x", "y", "z", "rx", "ry", "rz")
        for s, inertia, G in zip(self.sides, self.inertias, self.coupling):
            out += detached_body_terms(rows, f"seat_{s}", f"wheel_body_{s}", self.mass, inertia, k,
                                       self.loss_factor)
            rel = rows([f"wheel_body_{s}:{a}" for a in axes]) - rows([f"seat_{s}:{a}" for a in axes])
            G = np.asarray(G, float)
            dq = np.zeros_like(rel)
            dq[:, :G.shape[1]] = G
            out.append(Term(np.vstack([rel, dq]), M=np.block([[np.zeros((6, 6)), np.eye(6)],
                                                              [np.eye(6), np.zeros((6, 6))]])))
        return out
