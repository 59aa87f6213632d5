"""The catalogue of physical effects a wheelset model may lack (issue: compare, diagnose, add, watch the error fall).

Each effect is a small class: named physical parameters with units and
plausible bounds, and :meth:`Effect.apply`, which returns a new model with
the effect added through the structural-modification mechanism
(:mod:`receptance.modification`) or, for the two curve-fit effects, as
channel terms.  The catalogue is open: subclass :class:`Effect`, give it a
``name`` and parameters, implement ``apply`` and decorate with
:func:`register_effect`.

=====================  ========  ================================================================
name                   physical  what it adds
=====================  ========  ================================================================
``rig_suspension``     yes       soft springs to ground at the hanging points (crane, bungees)
``mass_loading``       yes       the accelerometers' mass at every sensor of a setup
``axlebox_bearing``    yes       the axlebox as its own rigid body on radial/axial/rocking springs
``wheel_seat_joint``   yes       the wheel's hub on rocking/radial/axial/torsional springs (press fit)
``primary_suspension`` yes       Table 2.1 springs and dampers at the axleboxes (in service)
``residuals``          patch     lower and upper residual terms per channel (out-of-band modes)
``experimental_mode``  patch     a measured mode the FE lacks, with its measured modal constants
=====================  ========  ================================================================

Patches lower any error by curve fitting; the diagnosis counts every number
they fit (one residual pair or one modal constant per channel) and prefers a
physical effect that explains the same evidence with few parameters.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar, Mapping, Sequence

import numpy as np
import pandas as pd

from receptance.dofs import Point
from receptance.modal_model import ChannelTerms, ModalModel, ModelError
from receptance.modification import GroundSprings, Modification, PointMass, RigidBody, Term, register

__all__ = [
    "Parameter", "Effect", "EFFECTS", "register_effect", "effect_names",
    "RigSuspension", "MassLoading", "AxleboxBearing", "WheelSeatJoint", "PrimarySuspensionEffect",
    "Residuals", "ExperimentalMode",
    "RigSprings", "SensorMasses", "BearingBodies",
]


@dataclass(frozen=True)
class Parameter:
    """A fitted physical parameter: name, unit, plausible bounds and a starting value (fitted in log scale)."""

    name: str
    unit: str
    lower: float
    upper: float
    initial: float
    description: str = ""

    def __post_init__(self) -> None:
        if not 0 < self.lower < self.initial < self.upper:
            raise ValueError(f"parameter {self.name}: need 0 < lower < initial < upper, got "
                             f"{self.lower}, {self.initial}, {self.upper}")


class Effect:
    """Base class of catalogued effects.

    Attributes
    ----------
    name : str
        Catalogue name (``diagnosis.json`` uses it).
    physical : bool
        False for curve-fit patches (``residuals``, ``experimental_mode``).
    in_test : bool
        Present while the wheelset was tested (its model keeps the test's frequencies).
    """

    name: ClassVar[str] = ""
    physical: ClassVar[bool] = True
    in_test: ClassVar[bool] = True
    summary: ClassVar[str] = ""

    def parameters(self) -> tuple[Parameter, ...]:
        raise NotImplementedError

    def apply(self, model: ModalModel, values: Mapping[str, float], setups: Sequence[pd.DataFrame] = ()
              ) -> ModalModel:
        """A new model with the effect at parameter ``values`` (``setups``: the tests' channel tables)."""
        raise NotImplementedError

    def n_fitted(self, setups: Sequence[pd.DataFrame] = ()) -> int:
        """How many numbers a fit of this effect adjusts (the penalty counts them all)."""
        return len(self.parameters())

    def _values(self, values: Mapping[str, float]) -> dict[str, float]:
        names = [p.name for p in self.parameters()]
        missing = [n for n in names if n not in values]
        if missing:
            raise ModelError(f"{self.name}: missing parameter value(s) {missing}; parameters are {names}")
        return {n: float(values[n]) for n in names}


EFFECTS: dict[str, type] = {}


def register_effect(cls: type) -> type:
    """Class decorator adding an effect to the catalogue under its ``name``."""
    if not cls.name:
        raise ValueError(f"{cls.__name__} needs a class attribute 'name'")
    EFFECTS[cls.name] = cls
    return cls


def effect_names() -> list[str]:
    return list(EFFECTS)


# ----------------------------------------------------------------- modifications used by the effects
@register
@dataclass(frozen=True)
class RigSprings(GroundSprings):
    """Ground springs that were there during the test (crane, bungees): the test's frequencies keep them."""

    kind: ClassVar[str] = "rig_springs"
    in_test: ClassVar[bool] = True


@register
@dataclass(frozen=True)
class SensorMasses(Modification):
    """Point masses at sensor positions, present during the test (mass loading)."""

    kind: ClassVar[str] = "sensor_masses"
    in_test: ClassVar[bool] = True
    points: tuple[str, ...] = ()
    mass: float = 0.0

    def terms(self, rows) -> list[Term]:
        if not self.points:
            return []
        specs = [f"{p}:{a}" for p in self.points for a in ("x", "y", "z")]
        return [Term(rows(specs), M=np.eye(len(specs)) * self.mass)]


@register
@dataclass(frozen=True)
class BearingBodies(Modification):
    """Each axlebox as a rigid body on bearing springs to its journal (instead of a rigid link).

    The FE carries the axlebox rigidly on the journal; its mass and inertia
    are taken off the journal (negative point mass, exact for the rigid part
    of the motion) and given to a new rigid body joined to the journal by
    radial (x, z), axial (y) and rocking (about x and z) springs with a loss
    factor (rolling bearings dissipate: 0.01, i.e. about 0.5 % modal damping
    of the axlebox's own modes); spin about the axle stays free.  Sensors on
    the axlebox move with the body.
    """

    kind: ClassVar[str] = "bearing_bodies"
    in_test: ClassVar[bool] = True
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

    def bodies(self) -> tuple[RigidBody, ...]:
        return tuple(RigidBody(f"axlebox_body_{s}", self.mass, tuple(self.inertia), tuple(c), (int(n),))
                     for s, n, c in zip(self.sides, self.axlebox_nodes, self.centres))

    def terms(self, rows) -> list[Term]:
        k = dict(x=self.radial, y=self.axial, z=self.radial, rx=self.rocking, rz=self.rocking)
        return [t for s in self.sides for t in _detached_body_terms(
            rows, f"journal_{s}", f"axlebox_body_{s}", self.mass, self.inertia, k, self.loss_factor)]


def _detached_body_terms(rows, anchor: str, body: str, mass: float, inertia, stiffness: dict,
                         loss_factor: float) -> list[Term]:
    """A part the FE carried rigidly on ``anchor``, detached: its inertia taken off the anchor (negative point
    mass, exact for the rigid part of the motion) and springs ``stiffness`` (axis -> value, complex with the
    loss factor) between the new ``body`` and the anchor."""
    out = PointMass(point=anchor, mass=-mass, inertia=tuple(-np.asarray(inertia))).terms(rows)
    axes = list(stiffness)
    k = np.array([stiffness[a] for a in axes]) * (1 + 1j * loss_factor)
    rel = rows([f"{body}:{a}" for a in axes]) - rows([f"{anchor}:{a}" for a in axes])
    return out + [Term(rel, K=np.diag(k))]


# ----------------------------------------------------------------------------------- the effects
def _points(model: ModalModel, names: Sequence[str]) -> None:
    missing = [n for n in names if n not in model.points]
    if missing:
        raise ModelError(f"the model lacks the point(s) {missing} this effect needs; known points: "
                         f"{sorted(model.points)} (read them with receptance.read_points)")


@register_effect
@dataclass(frozen=True)
class RigSuspension(Effect):
    """Soft springs to ground at the hanging points (a wheelset hung from a crane for the test)."""

    name: ClassVar[str] = "rig_suspension"
    summary: ClassVar[str] = "soft springs at the hanging points"
    points: tuple[str, ...] = ("axlebox_L", "axlebox_R")

    def parameters(self) -> tuple[Parameter, ...]:
        return (Parameter("vertical_N_per_m", "N/m", 1e3, 1e7, 1e5, "vertical stiffness per hanging point"),
                Parameter("horizontal_N_per_m", "N/m", 1e1, 1e6, 1e3, "horizontal stiffness per hanging point"))

    def apply(self, model, values, setups=()):
        v = self._values(values)
        _points(model, self.points)
        kv, kh = v["vertical_N_per_m"], v["horizontal_N_per_m"]
        return model.with_modification(RigSprings(points=self.points, stiffness=(kh, kh, kv)))


@register_effect
@dataclass(frozen=True)
class MassLoading(Effect):
    """The accelerometers' (and mounts') mass at every sensor of each setup."""

    name: ClassVar[str] = "mass_loading"
    summary: ClassVar[str] = "sensor and fixture masses"

    def parameters(self) -> tuple[Parameter, ...]:
        return (Parameter("sensor_mass_kg", "kg", 1e-3, 0.5, 0.03, "mass of one accelerometer with its mount"),)

    def apply(self, model, values, setups=()):
        v = self._values(values)
        names, points = [], []
        for table in setups:
            acc = table[table["quantity"] == "acceleration"]
            for _, r in acc.iterrows():
                key = f"sensor_{r.get('setup', '')}_{r['name']}"
                node = None if pd.isna(r.get("fe_node", np.nan)) else int(r["fe_node"])
                points.append(Point(key, node, (r["x"], r["y"], r["z"])))
                names.append(key)
        if not names:
            raise ModelError("mass_loading needs the setups' channel tables (sensor positions)")
        # sensors of two setups at one place are the same sensor: count it once
        unique = {}
        for p in points:
            unique.setdefault((p.fe_node, p.xyz), p)
        pts = list(unique.values())
        return model.with_points(pts).with_modification(
            SensorMasses(points=tuple(p.name for p in pts), mass=v["sensor_mass_kg"]))


@register_effect
@dataclass(frozen=True)
class AxleboxBearing(Effect):
    """The axlebox on its bearing: a rigid body on radial, axial and rocking springs to the journal.

    ``mass`` and ``inertia`` describe the axlebox (Table 2.1: 78 kg; the
    default inertia is that of a 78 kg box 0.3 × 0.22 × 0.3 m) and are not
    fitted.  The journal is the FE node at the axlebox centre other than the
    axlebox's own node.
    """

    name: ClassVar[str] = "axlebox_bearing"
    summary: ClassVar[str] = "axlebox as its own body on radial/axial/rocking bearing springs"
    sides: tuple[str, ...] = ("L", "R")
    mass: float = 78.0
    inertia: tuple[float, float, float] = (0.9, 1.2, 0.9)

    def parameters(self) -> tuple[Parameter, ...]:
        return (Parameter("radial_N_per_m", "N/m", 1e7, 1e11, 1e9, "radial bearing stiffness per axlebox"),
                Parameter("axial_N_per_m", "N/m", 1e6, 1e11, 3e8, "axial bearing stiffness per axlebox"),
                Parameter("rocking_Nm_per_rad", "N m/rad", 1e4, 1e9, 1e7, "rocking stiffness per axlebox"),
                Parameter("right_over_left", "-", 0.5, 2.0, 1.0,
                          "stiffness of the right bearing over the left (two bearings never quite match)"))

    def apply(self, model, values, setups=()):
        v = self._values(values)
        names = [f"axlebox_{s}" for s in self.sides]
        _points(model, names)
        boxes, journals, centres, extra = [], [], [], []
        for s, name in zip(self.sides, names):
            box = model.points[name]
            centre = np.asarray(box.xyz if box.xyz is not None else model.fe.xyz[model.fe.index(box.fe_node)])
            d = np.linalg.norm(model.fe.xyz - centre, axis=1)
            d[model.fe.node_ids == box.fe_node] = np.inf
            j = int(np.argmin(d))
            if d[j] > 0.02:
                raise ModelError(f"axlebox_bearing: no journal node within 20 mm of the {name} centre "
                                 f"(nearest {int(model.fe.node_ids[j])} at {d[j]:.3f} m)")
            boxes.append(int(box.fe_node))
            journals.append(int(model.fe.node_ids[j]))
            centres.append(tuple(float(c) for c in centre))
            extra.append(Point(f"journal_{s}", int(model.fe.node_ids[j]), tuple(centre)))
        out = model.with_points(extra)
        for k, s in enumerate(self.sides):
            f = v["right_over_left"] if s == "R" else 1.0
            out = out.with_modification(BearingBodies(
                sides=(s,), axlebox_nodes=(boxes[k],), journal_nodes=(journals[k],), centres=(centres[k],),
                mass=self.mass, inertia=tuple(self.inertia), radial=f * v["radial_N_per_m"],
                axial=f * v["axial_N_per_m"], rocking=f * v["rocking_Nm_per_rad"]))
        return out


@register_effect
@dataclass(frozen=True)
class PrimarySuspensionEffect(Effect):
    """The primary suspension of Table 2.1 (in service): fitted vertical and lateral stiffness per axlebox."""

    name: ClassVar[str] = "primary_suspension"
    summary: ClassVar[str] = "primary suspension springs and dampers at the axleboxes (in service)"
    in_test: ClassVar[bool] = False
    damping: tuple[float, float, float] = (85e3, 50e3, 11e3)
    longitudinal: float = 2 * 4.15e6

    def parameters(self) -> tuple[Parameter, ...]:
        return (Parameter("vertical_N_per_m", "N/m", 1e5, 1e8, 1e6, "vertical stiffness per axlebox"),
                Parameter("lateral_N_per_m", "N/m", 1e5, 1e8, 4e6, "lateral stiffness per axlebox"))

    def apply(self, model, values, setups=()):
        from receptance.modification import PrimarySuspension

        v = self._values(values)
        _points(model, ["axlebox_L", "axlebox_R"])
        return model.with_modification(PrimarySuspension(
            stiffness=(self.longitudinal, v["lateral_N_per_m"], v["vertical_N_per_m"]), damping=self.damping))


@register_effect
@dataclass(frozen=True)
class WheelSeatJoint(Effect):
    """Press-fit compliance: each wheel's hub on rocking, radial, axial and torsional springs to its seat.

    Floating frame at the hub: the wheel's rigid motion becomes a body (its
    mass and inertia about the hub taken off the FE seat, as for the
    bearing) and its elastic deformation relative to the hub stays in the FE
    modes.  The two exchange inertia — the web and rim moving relative to the
    hub carry momentum (the umbrella mode pushes the hub along the axle) —
    and a modal export has no mass matrix, so the wheel's masses are lumped
    from what its drawing gives: ``rim_mass`` on the outermost node ring,
    ``web_mass`` over the rings by tributary annulus, the rest of ``mass``
    (Table 2.1: 251 kg) on the rigid hub.  The wheel's sensors and contact
    point move with the body.  The wheel's FE nodes are those within
    ``half_width`` of the hub plane and outside ``seat_radius``.
    """

    name: ClassVar[str] = "wheel_seat_joint"
    summary: ClassVar[str] = "wheel-seat press-fit compliance (rocking, radial, axial, torsional)"
    sides: tuple[str, ...] = ("L", "R")
    mass: float = 251.0
    rim_mass: float = 150.0
    web_mass: float = 80.0
    half_width: float = 0.08
    seat_radius: float = 0.09

    def parameters(self) -> tuple[Parameter, ...]:
        return (Parameter("rocking_Nm_per_rad", "N m/rad", 1e6, 1e10, 3e8, "rocking stiffness of one seat"),
                Parameter("radial_N_per_m", "N/m", 1e8, 1e11, 5e9, "radial stiffness of one seat"),
                Parameter("axial_N_per_m", "N/m", 1e7, 1e11, 3e9, "axial stiffness of one seat"),
                Parameter("torsional_Nm_per_rad", "N m/rad", 1e6, 1e10, 5e8, "torsional stiffness of one seat"))

    def apply(self, model, values, setups=()):
        v = self._values(values)
        names = [f"contact_{s}" for s in self.sides]
        _points(model, names)
        fe = model.fe
        hubs, seats, centres, carried, extra, inertias, couplings = [], [], [], [], [], [], []
        for s, name in zip(self.sides, names):
            y_plane = float(model.points[name].xyz[1]) if model.points[name].xyz is not None else \
                float(fe.xyz[fe.index(model.points[name].fe_node), 1])
            on_axis = np.hypot(fe.xyz[:, 0], fe.xyz[:, 2]) < 1e-6
            near = np.flatnonzero(on_axis & (np.abs(fe.xyz[:, 1] - y_plane) < self.half_width))
            if near.size < 2:
                raise ModelError(f"wheel_seat_joint: no hub/seat nodes on the axle near y = {y_plane:.3f} m")
            # the seat and the hub are two FE nodes at one place on the axis (joined by a rigid link in the FE)
            ys = np.round(fe.xyz[near, 1], 6)
            vals, counts = np.unique(ys, return_counts=True)
            shared = vals[counts >= 2]
            if shared.size == 0:
                raise ModelError(f"wheel_seat_joint: no pair of co-located hub and seat nodes on the axle near "
                                 f"y = {y_plane:.3f} m")
            hub_y = float(shared[np.argmin(np.abs(shared - y_plane))])
            pair = near[np.abs(fe.xyz[near, 1] - hub_y) < 1e-6]
            ring = np.flatnonzero((np.abs(fe.xyz[:, 1] - hub_y) < self.half_width) & (
                np.hypot(fe.xyz[:, 0], fe.xyz[:, 2]) > self.seat_radius))
            # the node of the pair that the wheel nodes are not: heuristically the higher label is the hub
            seat, hub = sorted(int(n) for n in fe.node_ids[pair[:2]])
            centre = np.array([0.0, hub_y, 0.0])
            masses = self._node_masses(fe.xyz[ring] - centre)
            inertias.append(_lumped_inertia(masses, fe.xyz[ring] - centre))
            couplings.append(_deformation_momentum(fe, ring, fe.index(hub), masses, centre))
            hubs.append(hub)
            seats.append(seat)
            centres.append(tuple(centre))
            carried.append(tuple(int(n) for n in fe.node_ids[ring]) + (hub,))
            extra.append(Point(f"seat_{s}", seat, tuple(centre)))
        mod = SeatJoints(sides=self.sides, hub_nodes=tuple(hubs), seat_nodes=tuple(seats), centres=tuple(centres),
                         carried=tuple(carried), mass=self.mass, inertias=tuple(inertias),
                         coupling=tuple(couplings), rocking=v["rocking_Nm_per_rad"], radial=v["radial_N_per_m"],
                         axial=v["axial_N_per_m"], torsional=v["torsional_Nm_per_rad"])
        return model.with_points(extra).with_modification(mod)

    def _node_masses(self, rel: np.ndarray) -> np.ndarray:
        """Lumped masses of the wheel's nodes: the rim's mass on the outermost ring; the web's (a plate of even
        thickness) by each ring's tributary annulus between the midpoints to its neighbours.  The hub's own mass
        (the rest of ``mass``) moves rigidly with it."""
        r = np.round(np.hypot(rel[:, 0], rel[:, 2]), 4)
        rings = np.unique(r)
        edges = np.concatenate([[rings[0]], 0.5 * (rings[1:] + rings[:-1]), [rings[-1]]])
        area = np.diff(edges**2)
        m = np.zeros(r.size)
        for k, ring in enumerate(rings):
            on = r == ring
            m[on] = (self.web_mass * area[k] / area.sum() + (self.rim_mass if k == rings.size - 1 else 0.0)) / on.sum()
        return m


def _lumped_inertia(masses: np.ndarray, rel: np.ndarray) -> tuple[float, float, float]:
    """Principal inertia (about x, y, z through the hub) of point masses at ``rel``."""
    x, y, z = rel.T
    return (float(np.sum(masses * (y**2 + z**2))), float(np.sum(masses * (x**2 + z**2))),
            float(np.sum(masses * (x**2 + y**2))))


def _deformation_momentum(fe, nodes: np.ndarray, hub: int, masses: np.ndarray, centre: np.ndarray) -> tuple:
    """G (6 x modes): linear and angular momentum about the hub of each FE mode's deformation of the wheel
    relative to the hub's rigid motion, Σ m_i [d_i; r_i × d_i] — the inertial coupling between the wheel's
    rigid motion and its elastic deformation that a floating frame at the hub must keep."""
    rel = fe.xyz[nodes] - fe.xyz[hub]
    u = fe.shapes[:, nodes, :3]  # (modes, nodes, 3)
    hub_t, hub_r = fe.shapes[:, hub, :3], fe.shapes[:, hub, 3:6]
    d = u - hub_t[:, None, :] - np.cross(hub_r[:, None, :], rel[None, :, :])
    lin = np.einsum("j,mjk->km", masses, d)
    arm = fe.xyz[nodes] - centre
    ang = np.einsum("j,mjk->km", masses, np.cross(arm[None, :, :], d))
    return tuple(map(tuple, np.vstack([lin, ang])))


@register
@dataclass(frozen=True)
class SeatJoints(Modification):
    """Wheels on compliant seats (see :class:`WheelSeatJoint`); the wheel's rigid motion is a body.

    ``coupling`` holds per side the 6 x modes matrix of the wheel deformation's momentum about the hub (in the
    FE modes' coordinates): with it the body and the FE deformation exchange inertia as they do in the FE.
    """

    kind: ClassVar[str] = "seat_joints"
    in_test: ClassVar[bool] = True
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
        return tuple(RigidBody(f"wheel_body_{s}", self.mass, tuple(i), tuple(c), tuple(nodes), hub)
                     for s, c, nodes, hub, i in zip(self.sides, self.centres, self.carried, self.hub_nodes,
                                                   self.inertias))

    def terms(self, rows) -> list[Term]:
        k = dict(x=self.radial, y=self.axial, z=self.radial, rx=self.rocking, ry=self.torsional, rz=self.rocking)
        out = []
        axes = ("x", "y", "z", "rx", "ry", "rz")
        for s, inertia, G in zip(self.sides, self.inertias, self.coupling):
            out += _detached_body_terms(rows, f"seat_{s}", f"wheel_body_{s}", self.mass, inertia, k,
                                        self.loss_factor)
            rel = rows([f"wheel_body_{s}:{a}" for a in axes]) - rows([f"seat_{s}:{a}" for a in axes])
            G = np.asarray(G, float)
            dq = np.zeros_like(rel)
            dq[:, :G.shape[1]] = G
            out.append(Term(np.vstack([rel, dq]), M=np.block([[np.zeros((6, 6)), np.eye(6)],
                                                              [np.eye(6), np.zeros((6, 6))]])))
        return out


@register_effect
@dataclass(frozen=True)
class Residuals(Effect):
    """Lower and upper residual terms per channel: modes below and above the band (a curve fit)."""

    name: ClassVar[str] = "residuals"
    physical: ClassVar[bool] = False
    summary: ClassVar[str] = "upper and lower residual terms for out-of-band modes"
    lower: Mapping = field(default_factory=dict)
    upper: Mapping = field(default_factory=dict)

    def parameters(self) -> tuple[Parameter, ...]:
        return ()

    def n_fitted(self, setups=()) -> int:
        return 2 * sum(int((t["quantity"] == "acceleration").sum()) for t in setups)

    def apply(self, model, values, setups=()):
        out = model
        for setup, lower in self.lower.items():
            out = out.with_channel_terms(ChannelTerms("residuals", setup, dict(lower), dict(self.upper[setup])))
        return out


@register_effect
@dataclass(frozen=True)
class ExperimentalMode(Effect):
    """A mode seen in the test that the FE lacks, added with its measured modal constants (a curve fit)."""

    name: ClassVar[str] = "experimental_mode"
    physical: ClassVar[bool] = False
    summary: ClassVar[str] = "a measured mode the FE lacks, with its measured shape"
    f_hz: float = 0.0
    zeta: float = 0.0
    constants: Mapping = field(default_factory=dict)

    def parameters(self) -> tuple[Parameter, ...]:
        return ()

    def n_fitted(self, setups=()) -> int:
        # frequency, damping and one complex modal constant per channel
        return 2 + 2 * sum(int((t["quantity"] == "acceleration").sum()) for t in setups)

    def apply(self, model, values, setups=()):
        out = model
        for setup, res in self.constants.items():
            out = out.with_channel_terms(ChannelTerms("experimental_mode", setup,
                                                      modes=((self.f_hz, self.zeta, dict(res)),)))
        return out
