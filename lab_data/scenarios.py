"""Design FE model versus as-built truth, and the hidden-effect scenarios.

The **design** model is what the design office exports: nominal parameters,
wheels and axleboxes rigidly fixed to the axle, free-free. The **as-built
truth** is what the lab measures. Apart from ``control`` it differs from the
design by small parameter errors (:data:`AS_BUILT`) and, per scenario, by one
or more hidden physical effects that the design model lacks:

``control``
    Truth = design FE; only damping and noise added.
``bearing``
    Axleboxes ride on compliant rolling bearings (double-row tapered roller
    units) instead of being rigidly fixed: radial 1.0e9 N/m, axial 2.5e8 N/m,
    rocking 5.0e6 N m/rad, free spin. The right bearing is 15 % stiffer than
    the left (different preload), as two real bearings are. These values sit
    in the catalogue range of railway axlebox bearings and put the axlebox
    axial and rocking modes inside 10–500 Hz.
``rig``
    The wheelset hangs from the crane on two coil springs hooked to the
    axlebox lifting lugs (thesis Fig. 3.1–3.2a): 3.5e5 N/m vertical and
    4e3 N/m horizontal (pendulum + coil shear) each, so the bounce is near
    2.7 Hz instead of 0 Hz — the FE is free-free.
``joint``
    Wheel-seat press fit with finite stiffness between hub and axle:
    rocking 6.0e7 N m/rad (tilting of the hub about x and z), radial
    2.0e9 N/m, axial 1.0e9 N/m, torsional 2.0e8 N m/rad.
``residual``
    The FE export is truncated at the export frequency (500 Hz by default)
    while the truth keeps all its modes up to 5 kHz.
``bearing_rig``
    Two hidden effects at once: ``bearing`` and ``rig``.
``rig_sling``
    The wheelset hangs from the crane on two slings wrapped around the axle
    body between each wheel and its brake disc, at y = ±0.52 m (inboard of
    the wheel hub, clear of the disc seat's shoulder and 4 cm from the axle
    accelerometers at ±0.56 m), not at the axleboxes: the same spring values
    as ``rig`` (3.5e5 N/m vertical, 4e3 N/m horizontal per sling).
``bearing_sling_rig``
    Two hidden effects at once: ``bearing`` and ``rig_sling``.
``absorber``
    An effect outside any catalogue: a tuned vibration absorber bolted to the
    left brake disc rim (6 kg on a 9.0e6 N/m spring acting vertically,
    2 % damping), tuned to about 195 Hz, near the 3rd flexural mode.

In every scenario except ``residual`` the truth synthesises only its modes
below the export frequency: the hidden effect is then the only thing the
exported model lacks. The export frequency must lie in a gap of the
spectrum; :func:`check_spectral_gap` enforces that.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Protocol

import numpy as np

from .fe_model import FEModel, PointMass, Spring
from .wheelset import NODE, WheelsetParameters

__all__ = [
    "HiddenEffect",
    "CompliantBearings",
    "RigSuspension",
    "SlingRig",
    "WheelSeatJoint",
    "TunedAbsorber",
    "Scenario",
    "SCENARIOS",
    "AS_BUILT",
    "get_scenario",
    "as_built_parameters",
]

#: As-built deviations from the design (factors on WheelsetParameters fields):
#: axle steel 1.5 % stiffer, wheel webs 1 % thinner (about 3 % lower bending
#: stiffness), discs 2 % heavier, axleboxes 1.5 % lighter.
AS_BUILT: dict[str, float] = {
    "web_thickness": 0.99,
    "disc_mass": 1.02,
    "axlebox_mass": 0.985,
}
AS_BUILT_AXLE_E = 1.015


class HiddenEffect(Protocol):
    name: str

    def apply(self, model: FEModel) -> FEModel: ...

    def parameters(self) -> dict: ...


def _replace_links(model: FEModel, link_groups: set[str]) -> tuple:
    found = {link.group for link in model.links} & link_groups
    if found != link_groups:
        raise ValueError(f"model {model.name!r} lacks the rigid links {sorted(link_groups - found)}")
    return tuple(link for link in model.links if link.group not in link_groups)


@dataclass(frozen=True)
class CompliantBearings:
    """Axlebox on bearing springs instead of a rigid link (spin about the axle left free)."""

    radial: float = 1.0e9
    axial: float = 2.5e8
    rocking: float = 5.0e6
    right_factor: float = 1.15
    damping_ratio_hint: float = 0.005
    name: str = "bearing"

    def apply(self, model: FEModel) -> FEModel:
        links = _replace_links(model, {"bearing_L", "bearing_R"})
        springs = []
        for side, f in (("L", 1.0), ("R", self.right_factor)):
            journal = next(l.master for l in model.links if l.group == f"bearing_{side}")
            k = (self.radial * f, self.axial * f, self.radial * f, self.rocking * f, 0.0, self.rocking * f)
            springs.append(Spring(journal, NODE[f"axlebox_{side}"], k, (0.0,) * 6, f"bearing_{side}"))
        return model.with_changes(add_elements=springs, links=links, name=f"{model.name}+bearing")

    def parameters(self) -> dict:
        return {
            "radial_N_per_m": self.radial,
            "axial_N_per_m": self.axial,
            "rocking_Nm_per_rad": self.rocking,
            "spin_Nm_per_rad": 0.0,
            "right_over_left": self.right_factor,
        }


@dataclass(frozen=True)
class RigSuspension:
    """Crane springs from the axlebox lifting lugs to the (fixed) crane."""

    vertical: float = 3.5e5
    horizontal: float = 4.0e3
    name: str = "rig"

    def apply(self, model: FEModel) -> FEModel:
        springs = [
            Spring(
                NODE[f"axlebox_{side}"],
                None,
                (self.horizontal, self.horizontal, self.vertical, 0.0, 0.0, 0.0),
                (0.0,) * 6,
                f"rig_{side}",
            )
            for side in ("L", "R")
        ]
        return model.with_changes(add_elements=springs, name=f"{model.name}+rig")

    def parameters(self) -> dict:
        return {"vertical_N_per_m": self.vertical, "horizontal_N_per_m": self.horizontal, "attachment": "axleboxes"}


@dataclass(frozen=True)
class SlingRig:
    """Crane slings around the axle body at y = ±``y``: springs from the axle to the (fixed) crane.

    The sling acts on the axle's centreline at ``y``; when no axle station lies
    there, each spring is shared between the two neighbouring stations by the
    lever rule (force and moment about the sling preserved). The difference
    from an exact point attachment is a spring ``k xi (1 - xi)`` on the
    relative motion of two stations 3.5 cm apart, negligible against the
    axle's bending stiffness.
    """

    vertical: float = 3.5e5
    horizontal: float = 4.0e3
    y: float = 0.52
    name: str = "rig"

    def apply(self, model: FEModel) -> FEModel:
        axle = model.nodes_of("axle")
        ys = np.array([model.coords(n)[1] for n in axle])
        order = np.argsort(ys)
        axle, ys = axle[order], ys[order]
        springs = []
        for side, sgn in (("L", -1.0), ("R", 1.0)):
            target = sgn * self.y
            if not ys[0] < target < ys[-1]:
                raise ValueError(f"sling at y = {target} m lies outside the axle ({ys[0]:.3f} .. {ys[-1]:.3f} m)")
            j = int(np.clip(np.searchsorted(ys, target), 1, len(ys) - 1))
            xi = (target - ys[j - 1]) / (ys[j] - ys[j - 1])
            for node, w in ((axle[j - 1], 1.0 - xi), (axle[j], xi)):
                if w <= 1e-12:
                    continue
                k = (w * self.horizontal, w * self.horizontal, w * self.vertical, 0.0, 0.0, 0.0)
                springs.append(Spring(int(node), None, k, (0.0,) * 6, f"rig_{side}"))
        return model.with_changes(add_elements=springs, name=f"{model.name}+sling")

    def parameters(self) -> dict:
        return {
            "vertical_N_per_m": self.vertical,
            "horizontal_N_per_m": self.horizontal,
            "attachment": "slings on the axle body",
            "y_m": [-self.y, self.y],
            "hanging_points_m": [[0.0, -self.y, 0.0], [0.0, self.y, 0.0]],
        }


@dataclass(frozen=True)
class WheelSeatJoint:
    """Press-fit compliance between wheel hub and axle wheel seat."""

    rocking: float = 6.0e7
    radial: float = 2.0e9
    axial: float = 1.0e9
    torsional: float = 2.0e8
    name: str = "joint"

    def apply(self, model: FEModel) -> FEModel:
        links = _replace_links(model, {"joint_L", "joint_R"})
        springs = []
        for side in ("L", "R"):
            seat = next(l.master for l in model.links if l.group == f"joint_{side}")
            k = (self.radial, self.axial, self.radial, self.rocking, self.torsional, self.rocking)
            springs.append(Spring(seat, NODE[f"wheel_{side}"], k, (0.0,) * 6, f"joint_{side}"))
        return model.with_changes(add_elements=springs, links=links, name=f"{model.name}+joint")

    def parameters(self) -> dict:
        return {
            "rocking_Nm_per_rad": self.rocking,
            "radial_N_per_m": self.radial,
            "axial_N_per_m": self.axial,
            "torsional_Nm_per_rad": self.torsional,
        }


@dataclass(frozen=True)
class TunedAbsorber:
    """A mass on a vertical spring bolted to the top of the left brake disc's outer ring."""

    mass: float = 6.0
    stiffness: float = 9.0e6
    name: str = "absorber"

    def apply(self, model: FEModel) -> FEModel:
        disc = model.nodes_of("disc_L")
        xyz = np.array([model.coords(n) for n in disc])
        top = disc[np.argmax(xyz[:, 2])]
        nid = NODE["disc_L"] + 999
        new = replace(
            model,
            node_ids=np.append(model.node_ids, nid),
            xyz=np.vstack([model.xyz, model.coords(top)]),
            node_groups=model.node_groups + ("absorber",),
            _index=None,
        )
        # the absorber mass only moves vertically: the other DOFs are tied to the disc by stiff springs
        stiff = 1e11
        k = (stiff, stiff, self.stiffness, stiff * 1e-3, stiff * 1e-3, stiff * 1e-3)
        return new.with_changes(
            add_elements=[
                Spring(int(top), nid, k, (0.0,) * 6, "absorber"),
                PointMass(nid, self.mass, np.diag([1e-4, 1e-4, 1e-4]).tolist(), "absorber"),
            ],
            name=f"{model.name}+absorber",
        )

    def parameters(self) -> dict:
        f = np.sqrt(self.stiffness / self.mass) / (2 * np.pi)
        return {"mass_kg": self.mass, "stiffness_N_per_m": self.stiffness, "tuned_hz": f, "location": "disc_L top"}


@dataclass(frozen=True)
class Scenario:
    """A virtual-lab scenario: as-built deviations plus hidden effects.

    Attributes
    ----------
    name, description : str
    as_built : bool
        Apply :data:`AS_BUILT` parameter errors to the truth.
    effects : tuple of HiddenEffect
    truth_max_hz : float or None
        Highest truth mode synthesised; None means "the export frequency".
    """

    name: str
    description: str
    as_built: bool = True
    effects: tuple = field(default_factory=tuple)
    truth_max_hz: float | None = None

    def parameters(self) -> dict:
        return {
            "name": self.name,
            "description": self.description,
            "as_built": {**AS_BUILT, "axle_E": AS_BUILT_AXLE_E} if self.as_built else {},
            "effects": {e.name: e.parameters() for e in self.effects},
            "truth_max_hz": self.truth_max_hz,
        }


SCENARIOS: dict[str, Scenario] = {
    s.name: s
    for s in (
        Scenario("control", "truth = design FE; only damping and noise added", as_built=False),
        Scenario("bearing", "axleboxes on compliant bearings instead of rigidly fixed", effects=(CompliantBearings(),)),
        Scenario("rig", "wheelset hangs on soft crane springs; the FE is free-free", effects=(RigSuspension(),)),
        Scenario("joint", "wheel-seat press-fit compliance", effects=(WheelSeatJoint(),)),
        Scenario("residual", "FE export truncated while the truth has many higher modes", truth_max_hz=5000.0),
        Scenario(
            "bearing_rig",
            "two hidden effects: compliant bearings and crane springs",
            effects=(CompliantBearings(), RigSuspension()),
        ),
        Scenario(
            "rig_sling",
            "wheelset hangs from two crane slings around the axle body, not at the axleboxes; the FE is free-free",
            effects=(SlingRig(),),
        ),
        Scenario(
            "bearing_sling_rig",
            "two hidden effects: compliant bearings and crane slings around the axle body",
            effects=(CompliantBearings(), SlingRig()),
        ),
        Scenario(
            "absorber",
            "an effect no catalogue has: tuned vibration absorber bolted to the left brake disc",
            effects=(TunedAbsorber(),),
        ),
    )
}


def get_scenario(name: str) -> Scenario:
    """Scenario by name; an unknown name raises ``KeyError`` listing the valid ones."""
    try:
        return SCENARIOS[name]
    except KeyError:
        raise KeyError(f"unknown scenario {name!r}; choose one of {sorted(SCENARIOS)}") from None


def as_built_parameters(design: WheelsetParameters) -> WheelsetParameters:
    """The as-built wheelset parameters: design with :data:`AS_BUILT` deviations."""
    p = design.varied(**AS_BUILT)
    return replace(p, axle_material=p.axle_material.scaled(E=AS_BUILT_AXLE_E))
