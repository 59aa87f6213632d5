"""The catalogue of physical effects a wheelset model may lack (compare, diagnose, add, watch the error fall).

Each effect is a small class: named physical parameters with units and
plausible bounds, and :meth:`Effect.attach`, which finds where the effect
sits in a given model — from physical geometry and the wheelset description
(:mod:`receptance.diagnosis.geometry`, :mod:`receptance.wheelset_description`),
never from a mesh style — and returns an :class:`Attachment` whose
:meth:`~Attachment.apply` adds the effect at given parameter values through
the structural-modification mechanism (:mod:`receptance.effect_modifications`)
or, for the two curve-fit effects, as channel terms.  An effect that cannot
be attached raises :class:`~receptance.diagnosis.errors.EffectNotApplicable`
naming the reason and what would make it apply.  The catalogue is open:
subclass :class:`Effect`, give it a ``name`` and parameters, implement
``attach`` and decorate with :func:`register_effect`.

=====================  ========  ==============  ==================================================
name                   physical  role            what it adds
=====================  ========  ==============  ==================================================
``rig_suspension``     yes       test artefact   soft springs to ground at the hanging points
``mass_loading``       yes       test artefact   the accelerometers' mass at every sensor of a setup
``axlebox_bearing``    yes       wheelset        the axlebox as its own body on bearing springs
``wheel_seat_joint``   yes       wheelset        each wheel's hub on press-fit springs to its seat
``primary_suspension`` yes       service         Table 2.1 springs and dampers at the axleboxes
``residuals``          patch     test artefact   lower and upper residual terms per channel
``experimental_mode``  patch     test artefact   a measured mode the FE lacks, with its constants
=====================  ========  ==============  ==================================================

Roles (:data:`receptance.modification.ROLES`): a test artefact belonged to
the test and is removed from the in-service model
(:meth:`receptance.ModalModel.for_service`); a wheelset property is kept.

Patches lower any error by curve fitting; the diagnosis counts every number
they fit (one residual pair or one modal constant per channel) and prefers a
physical effect that explains the same evidence with few parameters.

What the effects assume that a user may have to supply (wheelset
description; otherwise thesis Table 2.1's proportions scaled to the FE's
rigid-body mass, :meth:`receptance.wheelset_description.WheelsetDescription.fitted_to_fe`,
and said in the assumptions): the axlebox's mass and inertia (Table 2.1:
78 kg; 0.9/1.2/0.9 kg m²) and, for an FE that neither ties a node of its
own to the journal nor lumps a mass there, whether the FE carries it; the
wheel's mass split (Table 2.1: 251 kg, rim 150/251 and web 80/251 of it,
hub the rest) and radii when the FE is not a shell/solid wheel; where the
wheelset hung (else a symmetric pair of slings along the axle is fitted).
A mass taken off an FE node is checked against what the node carries
(:func:`receptance.diagnosis.geometry.removable_mass`): more is refused as
not applicable, naming the description key to state.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar, Mapping, Sequence

import numpy as np
import pandas as pd

from receptance.diagnosis.errors import EffectNotApplicable
from receptance.diagnosis.geometry import (SIDES, axlebox_attachment, hanging_attachment, needs_rotations,
                                           removable_mass, wheel_attachment, wheelset_geometry)
from receptance.dofs import Point
from receptance.effect_modifications import (BearingBodies, RigSprings, SeatJoints, SensorMasses, SlingSprings)
from receptance.modal_model import ChannelTerms, ModalModel, ModelError
from receptance.modification import Modification
from receptance.wheelset_description import WheelsetDescription

__all__ = [
    "Parameter", "Effect", "Attachment", "EFFECTS", "register_effect", "effect_names",
    "RigSuspension", "MassLoading", "AxleboxBearing", "WheelSeatJoint", "PrimarySuspensionEffect",
    "Residuals", "ExperimentalMode", "EffectNotApplicable",
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
    #: the bounds are the geometry's limits (a position along the axle), not plausibility limits: a value at a bound
    #: is a place (the axle end), not an implausible fit
    geometric: bool = False
    #: a ratio of one side over the other (right over left) scales these parameters on one side only: a fit
    #: searches their geometric mean over the two sides, so that the ratio does not move the mean (left and
    #: right swapped otherwise make two valleys one parameter at a time cannot join)
    scales: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if not 0 < self.lower < self.initial < self.upper:
            raise ValueError(f"parameter {self.name}: need 0 < lower < initial < upper, got "
                             f"{self.lower}, {self.initial}, {self.upper}")


@dataclass(frozen=True, eq=False)
class Attachment:
    """An effect attached to one model: where it sits, what it assumed, and how it is built from values.

    Attributes
    ----------
    effect : Effect
    parameters : tuple of Parameter
        What a fit adjusts on this model (the catalogue's, plus e.g. the sling
        position when the hanging points are unknown).
    points : tuple of Point
        Named points the effect adds to the model (journals, seats, slings).
    assumptions : tuple of str
        What was found and assumed, in words (the log and the report show them).
    data : dict
        What :meth:`Effect.build` needs besides the values (nodes, centres,
        masses found when attaching); picklable, so fits travel between
        processes.
    """

    effect: "Effect"
    parameters: tuple
    points: tuple
    assumptions: tuple
    data: dict = field(default_factory=dict, repr=False)

    def build(self, values: Mapping[str, float]) -> list:
        """The modifications (and points, channel terms) of the effect at ``values``."""
        return self.effect.build(values, self.data)

    def apply(self, model: ModalModel, values: Mapping[str, float]) -> ModalModel:
        """``model`` (the one attached to, or one sharing its FE and points) with the effect at ``values``."""
        names = [p.name for p in self.parameters]
        required = {p.name for p in self.effect.parameters()}
        missing = [n for n in names if n not in values and n in required]
        if missing:
            raise ModelError(f"{self.effect.name}: missing parameter value(s) {missing}; parameters are {names}")
        # a parameter this model adds to the catalogue's (the sling position) takes its starting value when not given
        v = {p.name: float(values[p.name]) if p.name in values else float(p.initial) for p in self.parameters}
        out = model.with_points(list(self.points)) if self.points else model
        for item in self.build(v):
            if isinstance(item, Modification):
                out = out.with_modification(item)
            elif isinstance(item, ChannelTerms):
                out = out.with_channel_terms(item)
            else:  # points whose place depends on a fitted value (the slings)
                out = out.with_points(list(item.points))
        return out


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
    role : str
        ``"test_artefact"`` (removed for service), ``"wheelset"`` (kept) or ``"service"``.
    """

    name: ClassVar[str] = ""
    physical: ClassVar[bool] = True
    in_test: ClassVar[bool] = True
    role: ClassVar[str] = "test_artefact"
    summary: ClassVar[str] = ""

    def parameters(self) -> tuple[Parameter, ...]:
        """The catalogue's parameters (names, units, bounds: unchanged for users)."""
        raise NotImplementedError

    def attach(self, model: ModalModel, setups: Sequence[pd.DataFrame] = (),
               description: WheelsetDescription | None = None) -> Attachment:
        """Where the effect sits in ``model`` (``setups``: the tests' channel tables).

        Raises
        ------
        EffectNotApplicable
            The model lacks what the effect needs (names it and the remedy).
        """
        raise NotImplementedError

    def apply(self, model: ModalModel, values: Mapping[str, float], setups: Sequence[pd.DataFrame] = (),
              description: WheelsetDescription | None = None) -> ModalModel:
        """A new model with the effect at parameter ``values`` (``attach`` then ``Attachment.apply``)."""
        return self.attach(model, setups, description).apply(model, values)

    def build(self, values: Mapping[str, float], data: Mapping) -> list:
        """The modifications of the effect at ``values``, from what :meth:`attach` found (``data``)."""
        raise NotImplementedError

    def n_fitted(self, setups: Sequence[pd.DataFrame] = ()) -> int:
        """How many numbers a fit of this effect adjusts (the penalty counts them all)."""
        return len(self.parameters())

    def _attached(self, data: dict, points=(), assumptions=(), parameters=None) -> Attachment:
        return Attachment(self, tuple(parameters if parameters is not None else self.parameters()), tuple(points),
                          tuple(assumptions), data)


EFFECTS: dict[str, type] = {}


def register_effect(cls: type) -> type:
    """Class decorator adding an effect to the catalogue under its ``name``."""
    if not cls.name:
        raise ValueError(f"{cls.__name__} needs a class attribute 'name'")
    EFFECTS[cls.name] = cls
    return cls


def effect_names() -> list[str]:
    return list(EFFECTS)


def _need_points(effect: str, model: ModalModel, names: Sequence[str]) -> None:
    missing = [n for n in names if n not in model.points]
    if missing:
        raise EffectNotApplicable(effect, f"the model lacks the point(s) {missing}; known points: "
                                          f"{sorted(model.points)}",
                                  f"add {', '.join(missing)} (name, fe_node, x, y, z) to points.csv")


def _check_modal_masses(effect: str, model: ModalModel, att: Attachment, what: str, keys: str) -> None:
    """Refuse an attachment whose mass removal leaves the model without finite poles.

    The wheel-seat joint takes the wheel's rigid mass off the seat and hands the momentum of the wheel's
    deformation back to the FE modes (floating frame): its mass matrix is indefinite by construction (the frame's
    coordinates are redundant with the modes'), so neither the seat's apparent mass nor positive definiteness tells
    whether the FE carries the wheel (a ring wheel whose seat carries 132 kg holds a 251 kg wheel exactly). A
    model left without finite poles is refused (before: "matrix contains invalid numeric entries", reported as a
    toolkit fault). Tried once, at the catalogue's starting stiffnesses. The non-finite poles once met with Table
    2.1's 251 kg wheel on the lab's 180 kg metro wheel came from the pinning of test frequencies, not from the
    joint (:func:`receptance.modal_model._identity_mass`): the joint made rigid gives back the FE's model for any
    wheel laid out (``tests/test_lab_other_designs_masses.py``).
    """
    trial = att.apply(model, {p.name: p.initial for p in att.parameters})
    try:
        with np.errstate(over="ignore", divide="ignore", invalid="ignore"):  # the failure is said below, once
            f = trial.modes()["f_hz"].to_numpy()
        ok = bool(np.all(np.isfinite(f)))
    except (ValueError, FloatingPointError, np.linalg.LinAlgError):
        ok = False
    if not ok:
        raise EffectNotApplicable(effect, f"taking {what} off the FE leaves the model without finite poles: the FE "
                                          f"carries less than that (a negative net mass), so the part of this "
                                          f"design is lighter",
                                  f"state the design's {keys} in the wheelset description")


# ----------------------------------------------------------------------------------- the effects
@register_effect
@dataclass(frozen=True)
class RigSuspension(Effect):
    """Soft springs to ground at the hanging points (a wheelset hung from a crane for the test).

    The hanging points are the wheelset description's (``[rig]
    hanging_points``, coordinates or points-table names).  When the
    description does not give them, the wheelset hung from a symmetric pair
    of slings whose axial position ``hanging_y_m`` (distance from the
    wheelset's mid-plane) is fitted too, between a tenth of the axle's half
    length and its end, starting at the axleboxes (the lifting lugs of thesis
    Fig. 3.1); the sling acts on the axle axis, between the two axle nodes
    around it.
    """

    name: ClassVar[str] = "rig_suspension"
    summary: ClassVar[str] = "soft springs at the hanging points"
    role: ClassVar[str] = "test_artefact"

    def parameters(self) -> tuple[Parameter, ...]:
        return (Parameter("vertical_N_per_m", "N/m", 1e3, 1e7, 1e5, "vertical stiffness per hanging point"),
                Parameter("horizontal_N_per_m", "N/m", 1e1, 1e6, 1e3, "horizontal stiffness per hanging point"))

    def attach(self, model, setups=(), description=None):
        geo = wheelset_geometry(model, description, effect=self.name)
        given = hanging_attachment(model, geo, effect=self.name)
        if given is not None:
            names = tuple(p.name for p in given)
            note = ("hanging points from the description: "
                    + ", ".join(f"{p.name} at {np.round(p.xyz, 3).tolist() if p.xyz else 'node'} (node {p.fe_node})"
                                for p in given))

            return self._attached({"points": names}, given, (note,))
        half = float(np.max(np.abs(geo.axle_y)))
        lo, hi = 0.1 * half, half
        boxes = [geo.description.axlebox_centres.get(s) or (model.points[f"axlebox_{s}"].xyz
                                                           if f"axlebox_{s}" in model.points else None) for s in SIDES]
        ys = [abs(b[1]) for b in boxes if b is not None]
        start = float(np.clip(np.mean(ys) if ys else 0.9 * half, lo * 1.05, hi * 0.98))
        params = self.parameters() + (Parameter("hanging_y_m", "m", lo, hi, start,
                                                "axial distance of the two slings from the mid-plane (fitted when "
                                                "the description gives no hanging points)", geometric=True),)
        x0, z0 = geo.axis_xz
        note = (f"hanging points unknown (no [rig] hanging_points in the description): a symmetric pair of slings on "
                f"the axle, at +-hanging_y_m fitted in {lo:.3g}-{hi:.3g} m from {start:.3g} m (the axleboxes)")

        data = {"axle_nodes": geo.axle_nodes, "axle_y": geo.axle_y, "axis_xz": (x0, z0), "range": (lo, hi)}
        return self._attached(data, (), (note,), params)

    def build(self, v, data):
        kv, kh = v["vertical_N_per_m"], v["horizontal_N_per_m"]
        if "points" in data:
            return [RigSprings(points=data["points"], stiffness=(kh, kh, kv))]
        lo, hi = data["range"]
        x0, z0 = data["axis_xz"]
        y = float(np.clip(v["hanging_y_m"], lo, hi))
        ys, nodes = data["axle_y"], data["axle_nodes"]
        pts_a, pts_b, weights, extra = [], [], [], []
        for k, sy in enumerate((-y, y)):
            # the two axle nodes around the sling, and the weight of the second (linear along the axle)
            j = int(np.clip(np.searchsorted(ys, sy), 1, ys.size - 1))
            t = float(np.clip((sy - ys[j - 1]) / (ys[j] - ys[j - 1]), 0.0, 1.0)) if ys[j] > ys[j - 1] else 0.0
            pa, pb = f"sling_{k + 1}_a", f"sling_{k + 1}_b"
            extra += [Point(pa, int(nodes[j - 1]), (x0, sy, z0)), Point(pb, int(nodes[j]), (x0, sy, z0))]
            pts_a.append(pa)
            pts_b.append(pb)
            weights.append(t)
        return [_Points(tuple(extra)), SlingSprings(points_a=tuple(pts_a), points_b=tuple(pts_b),
                                                    weights=tuple(weights), stiffness=(kh, kh, kv))]


@dataclass(frozen=True)
class _Points:
    """Points an effect's build step adds (their position depends on a fitted value)."""

    points: tuple


@register_effect
@dataclass(frozen=True)
class MassLoading(Effect):
    """The accelerometers' (and mounts') mass at every sensor of each setup."""

    name: ClassVar[str] = "mass_loading"
    summary: ClassVar[str] = "sensor and fixture masses"
    role: ClassVar[str] = "test_artefact"

    def parameters(self) -> tuple[Parameter, ...]:
        return (Parameter("sensor_mass_kg", "kg", 1e-3, 0.5, 0.03, "mass of one accelerometer with its mount"),)

    def attach(self, model, setups=(), description=None):
        points = []
        for table in setups:
            acc = table[table["quantity"] == "acceleration"]
            for _, r in acc.iterrows():
                key = f"sensor_{r.get('setup', '')}_{r['name']}"
                node = None if pd.isna(r.get("fe_node", np.nan)) else int(r["fe_node"])
                points.append(Point(key, node, (r["x"], r["y"], r["z"])))
        if not points:
            raise EffectNotApplicable(self.name, "no sensor positions: the setups' channel tables were not given",
                                      "pass the setups' channel tables (setups=...)")
        # sensors of two setups at one place are the same sensor: count it once
        unique = {}
        for p in points:
            unique.setdefault((p.fe_node, p.xyz), p)
        pts = tuple(unique.values())
        names = tuple(p.name for p in pts)
        return self._attached({"points": names}, pts,
                              (f"{len(pts)} sensor positions of {len(setups)} setup(s), one mass each",))

    def build(self, v, data):
        return [SensorMasses(points=data["points"], mass=v["sensor_mass_kg"])]


@register_effect
@dataclass(frozen=True)
class AxleboxBearing(Effect):
    """The axlebox on its bearing: a rigid body on radial, axial and rocking springs to the journal.

    Works whether the FE gives the axlebox its own node (tied to the journal),
    lumps it on the journal node or leaves it out
    (:func:`receptance.diagnosis.geometry.axlebox_attachment` decides from the
    geometry and the FE's mass, and says so).  ``mass`` and ``inertia``
    (default: the wheelset description's, else Table 2.1's 78 kg,
    0.3 × 0.22 × 0.3 m box scaled to the FE's rigid-body mass) are not fitted:
    the frequencies tell only stiffness over mass.
    """

    name: ClassVar[str] = "axlebox_bearing"
    summary: ClassVar[str] = "axlebox as its own body on radial/axial/rocking bearing springs"
    role: ClassVar[str] = "wheelset"
    sides: tuple[str, ...] = ("L", "R")
    mass: float | None = None
    inertia: tuple[float, float, float] | None = None

    def parameters(self) -> tuple[Parameter, ...]:
        return (Parameter("radial_N_per_m", "N/m", 1e7, 1e11, 1e9, "radial bearing stiffness per axlebox"),
                Parameter("axial_N_per_m", "N/m", 1e6, 1e11, 3e8, "axial bearing stiffness per axlebox"),
                Parameter("rocking_Nm_per_rad", "N m/rad", 1e4, 1e9, 1e7, "rocking stiffness per axlebox"),
                Parameter("right_over_left", "-", 0.5, 2.0, 1.0,
                          "stiffness of the right bearing over the left (two bearings never quite match)",
                          scales=("radial_N_per_m", "axial_N_per_m", "rocking_Nm_per_rad")))

    def attach(self, model, setups=(), description=None):
        desc = description or WheelsetDescription()
        changes = {}
        if self.mass is not None:
            changes["axlebox_mass"] = float(self.mass)
        if self.inertia is not None:
            changes["axlebox_inertia"] = tuple(self.inertia)
        if changes:
            desc = desc.with_values(**changes)
        needs_rotations(model, self.name, "its rocking springs act on the journal's rotation and carry the "
                                          "axlebox's inertia")
        geo = wheelset_geometry(model, desc, effect=self.name)
        desc = geo.description  # the masses not given fitted to the FE's rigid-body mass
        boxes = [axlebox_attachment(model, geo, s, setups, effect=self.name) for s in self.sides]
        journals = tuple(Point(f"journal_{b.side}", b.journal_node, b.centre) for b in boxes)
        # a negative net mass at the journal has no physical meaning (and a pole without energy in the FE)
        carried = tuple(removable_mass(model, j, desc.axlebox_mass, desc.axlebox_inertia, effect=self.name,
                                       part="axlebox", keys="[axlebox] mass_kg and inertia_kg_m2")
                        for j, b in zip(journals, boxes) if b.mass_in_fe)

        data = {"boxes": tuple(boxes), "mass": desc.axlebox_mass, "inertia": tuple(desc.axlebox_inertia)}
        return self._attached(data, journals, tuple(b.note for b in boxes) + geo.mass_notes + carried)

    def build(self, v, data):
        out = []
        for b in data["boxes"]:
            f = v["right_over_left"] if b.side == "R" else 1.0
            out.append(BearingBodies(
                sides=(b.side,), axlebox_nodes=(b.axlebox_node or 0,), journal_nodes=(b.journal_node,),
                centres=(b.centre,), mass=data["mass"], inertia=data["inertia"], radial=f * v["radial_N_per_m"],
                axial=f * v["axial_N_per_m"], rocking=f * v["rocking_Nm_per_rad"], remove_from_journal=b.mass_in_fe,
                carried_points=(b.carried_points,)))
        return out


@register_effect
@dataclass(frozen=True)
class PrimarySuspensionEffect(Effect):
    """The primary suspension of Table 2.1 (in service): fitted vertical and lateral stiffness per axlebox."""

    name: ClassVar[str] = "primary_suspension"
    summary: ClassVar[str] = "primary suspension springs and dampers at the axleboxes (in service)"
    in_test: ClassVar[bool] = False
    role: ClassVar[str] = "service"
    damping: tuple[float, float, float] = (85e3, 50e3, 11e3)
    longitudinal: float = 2 * 4.15e6

    def parameters(self) -> tuple[Parameter, ...]:
        return (Parameter("vertical_N_per_m", "N/m", 1e5, 1e8, 1e6, "vertical stiffness per axlebox"),
                Parameter("lateral_N_per_m", "N/m", 1e5, 1e8, 4e6, "lateral stiffness per axlebox"))

    def attach(self, model, setups=(), description=None):
        _need_points(self.name, model, ["axlebox_L", "axlebox_R"])
        return self._attached({})

    def build(self, v, data):
        from receptance.modification import PrimarySuspension

        return [PrimarySuspension(stiffness=(self.longitudinal, v["lateral_N_per_m"], v["vertical_N_per_m"]),
                                  damping=self.damping)]


@register_effect
@dataclass(frozen=True)
class WheelSeatJoint(Effect):
    """Press-fit compliance: each wheel's hub on rocking, radial, axial and torsional springs to its seat.

    Floating frame at the hub: the wheel's rigid motion becomes a body (its
    mass and inertia about the hub taken off the FE seat, as for the
    bearing) and its elastic deformation relative to the hub stays in the FE
    modes.  The two exchange inertia — the web and rim moving relative to the
    hub carry momentum (the umbrella mode pushes the hub along the axle) —
    and a modal export has no mass matrix, so the wheel's mass is laid out
    from its drawing (wheelset description; else Table 2.1's 251 kg wheel,
    rim 150 kg, web 80 kg, scaled to the FE's rigid-body mass) on the wheel's FE nodes, which are found from the contact
    point through the mesh (shell and solid wheels) or are the rim body's
    node (a rim on web springs):
    :func:`receptance.diagnosis.geometry.wheel_attachment`.  The wheel's
    sensors and contact point move with the body.  ``mass``, ``rim_mass``,
    ``web_mass`` override the description.
    """

    name: ClassVar[str] = "wheel_seat_joint"
    summary: ClassVar[str] = "wheel-seat press-fit compliance (rocking, radial, axial, torsional)"
    role: ClassVar[str] = "wheelset"
    sides: tuple[str, ...] = ("L", "R")
    mass: float | None = None
    rim_mass: float | None = None
    web_mass: float | None = None

    def parameters(self) -> tuple[Parameter, ...]:
        return (Parameter("rocking_Nm_per_rad", "N m/rad", 1e6, 1e10, 3e8, "rocking stiffness of one seat"),
                Parameter("radial_N_per_m", "N/m", 1e8, 1e11, 5e9, "radial stiffness of one seat"),
                Parameter("axial_N_per_m", "N/m", 1e7, 1e11, 3e9, "axial stiffness of one seat"),
                Parameter("torsional_Nm_per_rad", "N m/rad", 1e6, 1e10, 5e8, "torsional stiffness of one seat"))

    def attach(self, model, setups=(), description=None):
        desc = description or WheelsetDescription()
        changes = {k: float(v) for k, v in (("wheel_mass", self.mass), ("rim_mass", self.rim_mass),
                                            ("web_mass", self.web_mass)) if v is not None}
        if changes:
            desc = desc.with_values(**changes)
        needs_rotations(model, self.name, "its rocking and torsional springs act on the seat's and the hub's "
                                          "rotations, and the wheel's mass moves rigidly with the hub")
        geo = wheelset_geometry(model, desc, effect=self.name)
        desc = geo.description  # the masses not given fitted to the FE's rigid-body mass
        wheels = [wheel_attachment(model, geo, s, effect=self.name) for s in self.sides]
        seats = tuple(Point(f"seat_{w.side}", w.seat_node, w.centre) for w in wheels)
        fixed = dict(sides=tuple(self.sides), hub_nodes=tuple(w.reference_node for w in wheels),
                     seat_nodes=tuple(w.seat_node for w in wheels), centres=tuple(w.centre for w in wheels),
                     carried=tuple(w.carried for w in wheels), mass=desc.wheel_mass,
                     inertias=tuple(w.inertia for w in wheels),
                     coupling=tuple(tuple(map(tuple, np.asarray(w.coupling))) for w in wheels))

        att = self._attached(fixed, seats, tuple(w.note for w in wheels) + geo.mass_notes)
        _check_modal_masses(self.name, model, att, f"the wheel's {desc.wheel_mass:.4g} kg", "[wheel] mass_kg")
        return att

    def build(self, v, data):
        return [SeatJoints(**data, rocking=v["rocking_Nm_per_rad"], radial=v["radial_N_per_m"],
                           axial=v["axial_N_per_m"], torsional=v["torsional_Nm_per_rad"])]


@register_effect
@dataclass(frozen=True)
class Residuals(Effect):
    """Lower and upper residual terms per channel: modes below and above the band (a curve fit)."""

    name: ClassVar[str] = "residuals"
    physical: ClassVar[bool] = False
    role: ClassVar[str] = "test_artefact"
    summary: ClassVar[str] = "upper and lower residual terms for out-of-band modes"
    lower: Mapping = field(default_factory=dict)
    upper: Mapping = field(default_factory=dict)

    def parameters(self) -> tuple[Parameter, ...]:
        return ()

    def n_fitted(self, setups=()) -> int:
        return 2 * sum(int((t["quantity"] == "acceleration").sum()) for t in setups)

    def attach(self, model, setups=(), description=None):
        return self._attached({})

    def build(self, v, data):
        return [ChannelTerms("residuals", setup, dict(lower), dict(self.upper[setup]))
                for setup, lower in self.lower.items()]


@register_effect
@dataclass(frozen=True)
class ExperimentalMode(Effect):
    """A mode seen in the test that the FE lacks, added with its measured modal constants (a curve fit)."""

    name: ClassVar[str] = "experimental_mode"
    physical: ClassVar[bool] = False
    role: ClassVar[str] = "test_artefact"
    summary: ClassVar[str] = "a measured mode the FE lacks, with its measured shape"
    f_hz: float = 0.0
    zeta: float = 0.0
    constants: Mapping = field(default_factory=dict)

    def parameters(self) -> tuple[Parameter, ...]:
        return ()

    def n_fitted(self, setups=()) -> int:
        # frequency, damping and one complex modal constant per channel
        return 2 + 2 * sum(int((t["quantity"] == "acceleration").sum()) for t in setups)

    def attach(self, model, setups=(), description=None):
        return self._attached({})

    def build(self, v, data):
        return [ChannelTerms("experimental_mode", setup, modes=((self.f_hz, self.zeta, dict(res)),))
                for setup, res in self.constants.items()]
