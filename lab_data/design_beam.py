"""The design wheelset as a design office models it for rotor dynamics: beam axle, lumped masses, rims on springs.

A second style of design FE for the same :class:`~lab_data.wheelset.WheelsetParameters`
(issue 10: the lab diagnosis must work on any design FE, not only on the
lab's own 3D mesh). The modelling choices are the usual ones of a
rotor-dynamics model of a railway wheelset:

* **Axle** — Timoshenko beam elements (:mod:`lab_data.beam`) along y with the
  stepped sections of the drawing (same hollow bore as the 3D model, so the
  axle weighs ``axle_mass``), stations at every section change and at the
  disc, wheel and bearing centres, subdivided to at most
  :data:`MAX_ELEMENT` (7 cm, about half a body diameter; the 3D model uses
  3.5 cm and extra stations at the sensor positions).
* **Hubs and brake discs** — lumped (mass + inertia) on the axle node at their
  centre plane, as rotor codes lump rigid disks on shaft stations (no
  separate hub node). A disc is rigid: its plate modes lie above 1 kHz, out
  of the design model's scope.
* **Wheel rims** — one rigid body each (mass and inertia on a rim-centre node
  on the axle axis in the web plane, coincident with the wheel-seat node),
  joined to the wheel-seat node by six web springs computed from plate
  theory (:func:`lab_data.web_springs.web_springs`); the web mass is shared
  between rim body and hub by Rayleigh's principle
  (:func:`lab_data.web_springs.rim_body`), and the hub keeps the rest of the
  wheel's mass and inertia so that the wheel as a whole weighs
  ``wheel_mass``.
* **Axleboxes** — lumped (mass + inertia) on the journal node at the bearing
  centre; there is no axlebox node.

Node numbering (its own, unrelated to :data:`lab_data.wheelset.NODE`): axle
stations ``1..N`` from the left journal end to the right one
(:data:`AXLE_FIRST_NODE`), rim centres :data:`RIM_NODE` ``501`` (left) and
``502`` (right). Element groups: ``axle`` (beams), ``hub_L/R``,
``disc_L/R``, ``rim_L/R``, ``axlebox_L/R`` (point masses), ``wheel_L/R``
(the web springs, so that their strain energy classifies a mode as a wheel
mode). The model is free-free.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .beam import annulus_section, rectangle_section
from .fe_model import Beam, FEModel, PointMass, Spring, assemble, solve_modes
from .mode_labels import ModeLabel, align_clusters, label_modes, truth_damping
from .truth import SolvedModel
from .uff_export import ElementRecord
from .web_springs import RimBody, WebSprings, rim_body, web_springs, wheel_inertia
from .wheelset import WheelsetParameters

__all__ = [
    "MAX_ELEMENT",
    "AXLE_FIRST_NODE",
    "RIM_NODE",
    "BeamDesign",
    "axle_beam",
    "build_beam_design",
    "beam_elements",
    "label_beam_modes",
    "solve_beam_design",
]

#: Longest axle element of the beam design [m].
MAX_ELEMENT = 0.07
#: Label of the axle's first station (left journal end); the others follow along +y.
AXLE_FIRST_NODE = 1
#: Rim-centre node of each wheel.
RIM_NODE = {"L": 501, "R": 502}
#: UFF 2412 physical-property numbers of the lumped elements and web springs (axle sections take 1, 2, ...).
PROPERTY = {"hub": 21, "disc": 22, "rim": 23, "axlebox": 24, "web": 31}


@dataclass(frozen=True)
class BeamDesign:
    """The beam-and-lumped-mass design model and where its bodies sit.

    Attributes
    ----------
    model : FEModel
    axle_nodes : ndarray of int
        Axle stations from left to right.
    axle_y : ndarray
        Their lateral positions [m].
    seat_node, disc_node, journal_node, rim_node : dict of str to int
        Per side (``"L"``, ``"R"``): the wheel-seat, disc-seat and journal
        (bearing-centre) axle nodes and the rim-centre node.
    web : WebSprings
    rim : RimBody
    hub : tuple of float
        Lumped hub (mass, diametral, polar inertia) on each wheel-seat node.
    disc : tuple of float
        Lumped brake disc (mass, diametral, polar inertia).
    """

    model: FEModel
    axle_nodes: np.ndarray
    axle_y: np.ndarray
    seat_node: dict
    disc_node: dict
    journal_node: dict
    rim_node: dict
    web: WebSprings
    rim: RimBody
    hub: tuple[float, float, float]
    disc: tuple[float, float, float]

    def attach(self, body: str, position) -> int:
        """The node a transducer on ``body`` is rigidly attached to.

        Parameters
        ----------
        body : str
            ``axle``, ``wheel_L/R`` (rim: the rim body), ``disc_L/R``,
            ``axlebox_L/R`` (the journal node carries the lumped axlebox).
        position : array_like (3,)
            The transducer's position [m]; on the axle it picks the nearest
            station.

        Returns
        -------
        int
        """
        if body == "axle":
            return int(self.axle_nodes[np.argmin(np.abs(self.axle_y - float(position[1])))])
        kind, _, side = body.partition("_")
        table = {"wheel": self.rim_node, "disc": self.disc_node, "axlebox": self.journal_node}
        if kind not in table or side not in ("L", "R"):
            raise ValueError(f"unknown body {body!r}; expected axle, wheel_L/R, disc_L/R or axlebox_L/R")
        return int(table[kind][side])


def _stations(p: WheelsetParameters, max_element: float) -> np.ndarray:
    # stations where a designer needs them: section changes, disc/wheel/bearing centres, the ends
    features = {0.0, p.disc_y, p.wheel_y, p.axlebox_y}
    features.update(y for y, _ in p.axle_segments)
    pts = sorted(features)
    right = [0.0]
    for a, b in zip(pts[:-1], pts[1:]):
        n = max(1, int(np.ceil((b - a) / max_element - 1e-9)))
        right.extend(np.linspace(a, b, n + 1)[1:])
    right = np.array(right)
    return np.concatenate([-right[:0:-1], right])


def axle_beam(p: WheelsetParameters, max_element: float = MAX_ELEMENT) -> tuple[np.ndarray, list[int], list[Beam]]:
    """The axle of the beam design: stations ``y``, their node labels and the Timoshenko elements between them.

    The axle is hollow with the bore that makes it weigh ``p.axle_mass``
    (:meth:`WheelsetParameters.axle_bore`); each element takes the section
    of the drawing at its mid-point.
    """
    if not 0 < max_element <= 0.5:
        raise ValueError(f"max_element must be in (0, 0.5] m, got {max_element!r}")
    ys = _stations(p, max_element)
    ids = list(range(AXLE_FIRST_NODE, AXLE_FIRST_NODE + len(ys)))
    mat = p.axle_material
    bore = p.axle_bore()
    elements = [Beam((ids[i], ids[i + 1]), annulus_section(p.axle_diameter(0.5 * (ys[i] + ys[i + 1])), bore, mat.nu),
                     mat, (0.0, 0.0, 1.0), "axle") for i in range(len(ys) - 1)]
    return ys, ids, elements


def build_beam_design(p: WheelsetParameters = WheelsetParameters(), *, max_element: float = MAX_ELEMENT,
                      name: str = "beam design wheelset") -> BeamDesign:
    """Build the free-free beam-and-lumped-mass design model of wheelset ``p``.

    Parameters
    ----------
    p : WheelsetParameters
        The same drawing the 3D design model is built from.
    max_element : float
        Longest axle element [m].
    name : str

    Returns
    -------
    BeamDesign
    """
    ys, ids, elements = axle_beam(p, max_element)
    xyz = [(0.0, float(y), 0.0) for y in ys]
    groups = ["axle"] * len(ys)

    def at(y: float) -> int:
        i = int(np.argmin(np.abs(ys - y)))
        if abs(ys[i] - y) > 1e-9:
            raise RuntimeError(f"no axle station at y = {y}")
        return ids[i]

    # wheel: web springs and rim body from plate theory; the hub keeps the rest of the wheel
    wm = p.wheel_material
    a, b, t = p.hub_radius, p.rim_radius, p.web_thickness
    web = web_springs(a, b, t, wm)
    m_rim = wm.rho * rectangle_section(p.rim_radial, p.rim_axial).area * 2 * np.pi * b
    rim = rim_body(a, b, t, wm, m_rim, p.rim_radial, p.rim_axial)
    m_web = wm.rho * t * np.pi * (b**2 - a**2)
    m_hub_ring = p.wheel_mass - m_rim - m_web
    if m_hub_ring <= 0:
        raise ValueError(f"rim ({m_rim:.1f} kg) and web ({m_web:.1f} kg) exceed the wheel mass {p.wheel_mass} kg")
    seat_r = 0.5 * p.axle_diameter(p.wheel_y)
    _, wheel_diam, wheel_polar = wheel_inertia([
        (m_hub_ring, seat_r, a, p.hub_length),
        (m_web, a, b, t),
        (m_rim, b - p.rim_radial / 2, b + p.rim_radial / 2, p.rim_axial),
    ])
    hub = (p.wheel_mass - rim.mass, wheel_diam - rim.diametral, wheel_polar - rim.polar)
    if min(hub) <= 0:
        raise ValueError(f"the rim body {rim} leaves no mass or inertia for the hub of a {p.wheel_mass} kg wheel")

    # brake disc: rigid hub ring (0.12 m long, as the drawing) plus friction ring, lumped on its seat
    dm = p.disc_material
    m_plate = dm.rho * p.disc_thickness * np.pi * (p.disc_outer_radius**2 - p.disc_hub_radius**2)
    disc_seat_r = 0.5 * p.axle_diameter(p.disc_y)
    disc = wheel_inertia([
        (p.disc_mass - m_plate, disc_seat_r, p.disc_hub_radius, 0.12),
        (m_plate, p.disc_hub_radius, p.disc_outer_radius, p.disc_thickness),
    ])

    seat, disc_node, journal, rim_node = {}, {}, {}, {}
    for side, sgn in (("L", -1.0), ("R", 1.0)):
        seat[side] = at(sgn * p.wheel_y)
        disc_node[side] = at(sgn * p.disc_y)
        journal[side] = at(sgn * p.axlebox_y)
        rim_node[side] = RIM_NODE[side]
        ids.append(rim_node[side])
        xyz.append((0.0, sgn * p.wheel_y, 0.0))
        groups.append(f"wheel_{side}")
        elements.append(PointMass(seat[side], hub[0], np.diag([hub[1], hub[2], hub[1]]).tolist(), f"hub_{side}"))
        elements.append(PointMass(rim_node[side], rim.mass, np.diag([rim.diametral, rim.polar, rim.diametral]).tolist(),
                                  f"rim_{side}"))
        elements.append(Spring(seat[side], rim_node[side], web.global_values(), (0.0,) * 6, f"wheel_{side}"))
        elements.append(PointMass(disc_node[side], disc[0], np.diag([disc[1], disc[2], disc[1]]).tolist(),
                                  f"disc_{side}"))
        bx, by, bz = p.axlebox_inertia
        elements.append(PointMass(journal[side], p.axlebox_mass, np.diag([bx, by, bz]).tolist(), f"axlebox_{side}"))

    model = FEModel(np.array(ids), np.array(xyz), tuple(groups), tuple(elements), (), (), name)
    axle = np.array(ids[: len(ys)])
    return BeamDesign(model, axle, ys, seat, disc_node, journal, rim_node, web, rim, hub, disc)


def beam_elements(design: BeamDesign) -> list[ElementRecord]:
    """UFF 2412 records of the beam design, as a rotor-dynamics pre-processor exports them.

    Axle beams are linear beams (descriptor 21) with one physical property per
    cross-section (1 = the largest section, then by decreasing area);
    every lumped mass is a lumped-mass element (161; properties 21 hubs, 22
    discs, 23 rims, 24 axleboxes); each web is a node-to-node translational
    spring (136) plus a node-to-node rotational spring (137) between the
    wheel-seat and rim-centre nodes (property 31).
    """
    model = design.model
    areas = sorted({round(e.section.area, 12) for e in model.elements if isinstance(e, Beam)}, reverse=True)
    prop_of = {area: k + 1 for k, area in enumerate(areas)}
    records = []
    eid = 1
    for e in model.elements:
        if isinstance(e, Beam):
            prop = prop_of[round(e.section.area, 12)]
            records.append(ElementRecord(eid, 21, prop, 1, 7, tuple(int(n) for n in e.nodes)))
        elif isinstance(e, PointMass):
            records.append(ElementRecord(eid, 161, PROPERTY[e.group.split("_")[0]], 1, 2, (int(e.node),)))
        elif isinstance(e, Spring):
            for desc in (136, 137):
                records.append(ElementRecord(eid, desc, PROPERTY["web"], 1, 5, (int(e.node_a), int(e.node_b))))
                eid += 1
            continue
        else:
            raise TypeError(f"unexpected element {type(e).__name__} in the beam design")
        eid += 1
    return records


def _web_motion(model: FEModel, vec: np.ndarray, web: WebSprings) -> str:
    """Which web spring stores most energy in a wheel mode: axial, rocking, radial or torsional."""
    k = np.array(web.global_values())
    energy = np.zeros(6)
    for e in model.elements:
        if isinstance(e, Spring) and e.node_b is not None:
            d = vec[model.dofs(e.node_b)] - vec[model.dofs(e.node_a)]
            energy += k * d**2
    per: dict[str, float] = {}
    for kind, en in zip(("radial", "axial", "radial", "rocking", "torsional", "rocking"), energy):
        per[kind] = per.get(kind, 0.0) + en
    return max(per, key=per.get)


def label_beam_modes(design: BeamDesign, system, modes) -> list[ModeLabel]:
    """Name the beam design's modes as :func:`lab_data.mode_labels.label_modes` names the 3D model's.

    The same strain-energy rules (the web springs are the ``wheel`` family);
    a wheel mode is described by the web spring storing most energy
    (``axial`` = 0 nodal diameters, ``rocking`` = 1 nodal diameter,
    ``radial``, ``torsional``), since a rigid rim has no rings to count
    nodal diameters on.
    """
    full = modes.full

    def pattern(family: str, i: int) -> tuple[int, str]:
        motion = _web_motion(design.model, full[:, i], design.web)
        return {"axial": 0, "rocking": 1}.get(motion, -1), motion

    return label_modes(design.model, system, modes, plate_pattern=pattern)


def solve_beam_design(p: WheelsetParameters, f_max_hz: float, *, max_element: float = MAX_ELEMENT):
    """The beam design model solved up to ``f_max_hz``: ``(BeamDesign, SolvedModel)``.

    The modes are mass-normalised (``Phi^T M Phi = I``), the six rigid-body
    modes are the physical translations and rotations about the centre of
    mass, and degenerate pairs are aligned to the x and z planes (the
    export mixes them again, as a solver would).
    """
    design = build_beam_design(p, max_element=max_element)
    system = assemble(design.model)
    modes = align_clusters(design.model, system, solve_modes(design.model, system, f_max_hz))
    labels = tuple(label_beam_modes(design, system, modes))
    return design, SolvedModel(design.model, system, modes, labels, truth_damping(list(labels), modes.freqs_hz))
