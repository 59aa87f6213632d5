"""Where the catalogued effects attach to an FE export: found from physical geometry, not from a mesh style.

A design office draws a wheelset in many ways: shells or solids for the
wheels or a rigid rim on web springs, the axlebox as its own node on an
RBE2 spider, lumped on the journal node or left out, any node numbering.
The effects therefore find their FE attachments from what every export
shares — node positions, element connectivity and the rigid-body modes —
and from the points table and the wheelset description
(:mod:`receptance.wheelset_description`).

Length scale.  Every tolerance is a fraction of the wheel's rolling radius
``R`` (the description's, else the contact points' distance from the axle
axis, else the largest distance of a node from the axis): nodes on the axle
axis lie within ``AXIS_FRACTION R``, coincident nodes within
``COINCIDE_FRACTION R``, a journal node within ``JOURNAL_FRACTION R`` of the
axlebox centre, a wheel's nodes within ``WHEEL_HALF_WIDTH R`` of its contact
plane and ``WHEEL_OUTER R`` of the axis.  No fixed millimetres.

The axle line.  The nodes of the beam elements that run along the axle axis
(both ends on it, non-zero length); without element records the nodes on
the axis.  Nodes on the axis that are not on the axle line are parts tied
to it (a hub, a disc hub, an axlebox centre node).

Axleboxes (:func:`axlebox_attachment`).  The journal is the axle-line node
nearest the axlebox centre.  An FE node of its own at the centre (not on the
axle line; or the points table's ``axlebox`` node when that is not an axle
node) makes the axlebox "its own node".  Whether the FE carries the
axlebox's mass: the description may state it (``axlebox.in_fe``); else an
own node rigidly tied to the journal is the axlebox modelled in the FE, and
a lumped-mass element (FE descriptor 161) on the journal node (not on every
axle node) is the axlebox lumped there; only without either is the total
mass the rigid-body modes imply (:func:`fem_import.checks.rigid_body_mass`)
compared with the described wheelset with and without the two axleboxes —
the description's own masses when it gives them (relatively: nearer, and
within :data:`~receptance.wheelset_description.MASS_NOTE_RTOL`), else the
lumped case is assumed and said.

Masses (:meth:`~receptance.wheelset_description.WheelsetDescription.fitted_to_fe`).
The masses the description does not give are Table 2.1's proportions scaled
to the FE's rigid-body mass (:attr:`WheelsetGeometry.mass_notes` says how).
Before the bearing takes the axlebox off the journal it checks that the
node carries it (:func:`removable_mass`): the FE's retained modes give the
apparent mass at the node, ``(Σ φ φᵀ)⁻¹`` over its DOFs, the most a rigid
part there can weigh; more would leave the model a negative kinetic energy
(the wheel-seat joint, whose floating frame hands the wheel's deformation
momentum back to the modes, checks the modes' own masses instead).

Wheels (:func:`wheel_attachment`).  The wheel's FE nodes are those reached
from the contact point's node through the element connectivity without
crossing the axle line, inside the wheel's region, plus the nodes on the axis
coincident with its seat that are not axle nodes (a hub node tied to the
seat).  The seat is the axle-line node nearest the wheel's hub plane.  A
modal export has no mass matrix, so the wheel's mass is laid out from its
drawing (description: rim ring, web annulus, rigid hub) and each piece is
rigidly attached to its nearest wheel node: a shell or solid wheel spreads
it over its rings, a rim-on-web-springs model puts it all on the rim body
node with the ring's rotary inertia.
"""

from __future__ import annotations

import logging
from collections import deque
from dataclasses import dataclass, field, replace
from typing import Sequence

import numpy as np

from receptance.dofs import Point
from receptance.diagnosis.errors import EffectNotApplicable
from receptance.wheelset_description import MASS_NOTE_RTOL, TABLE_2_1_MASSES, WheelsetDescription

__all__ = ["WheelsetGeometry", "wheelset_geometry", "needs_rotations", "moves_with", "TIED_RTOL", "AxleboxAttachment", "axlebox_attachment", "WheelAttachment",
           "wheel_attachment", "hanging_attachment", "total_mass", "removable_mass", "AXIS_FRACTION", "COINCIDE_FRACTION", "JOURNAL_FRACTION",
           "WHEEL_HALF_WIDTH", "WHEEL_OUTER", "BEAM_DESCRIPTORS", "SIDES"]

log = logging.getLogger("receptance")

SIDES = ("L", "R")
#: a node lies on the axle axis within this fraction of the rolling radius
AXIS_FRACTION = 0.05
#: two nodes are at one place within this fraction
COINCIDE_FRACTION = 0.02
#: the journal node lies within this fraction of the axlebox centre (along the axle)
JOURNAL_FRACTION = 0.25
#: a wheel's nodes lie within this fraction of its contact plane, and within WHEEL_OUTER of the axis
WHEEL_HALF_WIDTH = 0.5
WHEEL_OUTER = 1.25
#: UFF 2412 FE descriptors of beam elements (11 rod, 21 linear beam, 22 tapered, 23 curved, 24 parabolic)
BEAM_DESCRIPTORS = frozenset({11, 21, 22, 23, 24})
#: a piece of the wheel's mass this close to a wheel node is lumped on it (else rigidly attached to it)
LUMP_FRACTION = 0.15
#: rim ring / web annulus / hub layout of the default wheel when the description states no radii
RIM_RADIUS_FRACTION = 0.933
HUB_RADIUS_FRACTION = 0.33
_N_ANGLES = 48
_N_WEB_RADII = 6


@dataclass(frozen=True)
class WheelsetGeometry:
    """The wheelset's frame in an FE export: axle axis, length scale, axle line, total mass.

    Attributes
    ----------
    axis_xz : (float, float)
        Where the axle axis (along y) crosses the x–z plane [m].
    scale : float
        The rolling radius ``R`` every tolerance is a fraction of [m].
    scale_source : str
        Where ``R`` came from.
    axle_nodes : ndarray of int
        Axle-line node labels, by y.
    axle_y : ndarray
        Their y [m].
    total_mass : float or None
        Mass the rigid-body modes imply [kg] (None: no six rigid modes or no coordinates).
    description : WheelsetDescription
        The description with the masses it does not give fitted to the FE's
        (:meth:`WheelsetDescription.fitted_to_fe`).
    line_source : str
        How the axle line was found when the export's beam elements could not tell it ("" when they did).
    mass_notes : tuple of str
        Where each mass came from (the effects that use masses add them to their assumptions).
    axlebox_cases : dict
        Side -> how the FE holds that axlebox (:func:`_axlebox_case`), or the
        :class:`EffectNotApplicable` that says why it cannot be told.
    """

    axis_xz: tuple[float, float]
    scale: float
    scale_source: str
    axle_nodes: np.ndarray
    axle_y: np.ndarray
    total_mass: float | None
    description: WheelsetDescription
    line_source: str = ""
    mass_notes: tuple = ()
    axlebox_cases: dict = field(default_factory=dict, repr=False)

    def radial(self, xyz: np.ndarray) -> np.ndarray:
        """Distance of points from the axle axis [m]."""
        xyz = np.atleast_2d(xyz)
        return np.hypot(xyz[:, 0] - self.axis_xz[0], xyz[:, 2] - self.axis_xz[1])

    def nearest_axle_node(self, y: float) -> tuple[int, float]:
        """The axle-line node nearest the axial position ``y``, and its distance along the axle [m]."""
        k = int(np.argmin(np.abs(self.axle_y - y)))
        return int(self.axle_nodes[k]), float(abs(self.axle_y[k] - y))


#: (FE source, statement) already logged: a fallback is said once per export, not once per candidate fit
_SAID: set = set()

#: two nodes move as one rigid link when their motions (transported rigidly) agree to this share in every mode
TIED_RTOL = 1e-4


def moves_with(fe, a: int, b: int) -> bool:
    """True when FE node ``a`` is rigidly tied to node ``b``: in every mode ``u_a = u_b + θ_b × (x_a − x_b)`` (and
    ``θ_a = θ_b``) to :data:`TIED_RTOL` of the modes' motion there (an RBE2 or a lumped part, not a spring)."""
    ia, ib = fe.index(a), fe.index(b)
    ua, ub = fe.shapes[:, ia, :3], fe.shapes[:, ib, :3]
    if fe.has_rotations:
        ta, tb = fe.shapes[:, ia, 3:], fe.shapes[:, ib, 3:]
        ub = ub + np.cross(tb, fe.xyz[ia] - fe.xyz[ib])
        diff = np.hstack([ua - ub, ta - tb])
        ref = np.hstack([np.abs(ua), np.abs(ta)])
    else:
        diff, ref = ua - ub, np.abs(ua)
    scale = np.maximum(np.abs(ref).max(axis=1), np.finfo(float).tiny)
    return bool(np.all(np.abs(diff).max(axis=1) <= TIED_RTOL * scale))


def _point_xyz(model, name: str) -> np.ndarray | None:
    p = model.points.get(name)
    if p is None:
        return None
    if p.xyz is not None:
        return np.asarray(p.xyz, float)
    if p.fe_node is not None and p.fe_node in set(model.fe.node_ids.tolist()):
        return model.fe.xyz[model.fe.index(p.fe_node)]
    return None


def needs_rotations(model, effect: str, why: str, nodes=None) -> None:
    """Refuse an effect that acts on nodal rotations when the export has none (3 DOF per node, as a solid-element
    model is exported) or, with ``nodes``, when those nodes have none (zero in every mode: solid elements' nodes in
    a 6-DOF export, :attr:`fem_import.FEModes.rotation_free`): named, with what would make it apply, instead of a
    fit whose springs act on nothing."""
    fix = ("export the rotations too (6 DOF per node), with the axle's centre line as beam or RBE2/RBE3 nodes whose "
           "rotations the export holds")
    if not model.fe.has_rotations:
        raise EffectNotApplicable(effect, f"the FE shapes have no rotations (3 DOF per node, as a solid-element export "
                                          f"writes them): {why}", fix)
    if nodes is None:
        return
    free = [int(n) for n in nodes if model.fe.rotation_free[model.fe.index(int(n))]]
    if free:
        which = f"node {free[0]} carries" if len(free) == 1 else f"nodes {', '.join(map(str, free))} carry"
        raise EffectNotApplicable(effect, f"{which} no rotations (zero in every mode of the export, as a solid "
                                          f"element's node): {why}", fix)


def wheelset_geometry(model, description: WheelsetDescription | None = None, *, effect: str = "effect"
                      ) -> WheelsetGeometry:
    """The wheelset's frame in the model's FE export (module docstring).

    Raises
    ------
    EffectNotApplicable
        No node coordinates, the axle not along y, no axle line.
    """
    desc = description or WheelsetDescription()
    fe = model.fe
    if not fe.has_coordinates:
        raise EffectNotApplicable(effect, f"the FE export {fe.source or ''} has no node coordinates, so its parts "
                                          f"cannot be found by geometry",
                                  "read the modes with their geometry (fem_import.read(path, geometry=...))")
    boxes = [desc.axlebox_centres.get(s) for s in SIDES]
    boxes = [np.asarray(b, float) if b is not None else _point_xyz(model, f"axlebox_{s}") for b, s in zip(boxes, SIDES)]
    if all(b is not None for b in boxes):
        axis = boxes[1] - boxes[0]
        if np.linalg.norm(axis) == 0 or abs(axis[1]) / np.linalg.norm(axis) < np.cos(np.radians(5)):
            raise EffectNotApplicable(
                effect, f"the axlebox centres {boxes[0].round(3).tolist()} and {boxes[1].round(3).tolist()} do not "
                        f"lie on a line along y; the toolkit's convention puts the axle along y (DESIGN.md)",
                "export the FE and the points in the convention x along the track, y along the axle, z up")
        axis_xz = (float(0.5 * (boxes[0][0] + boxes[1][0])), float(0.5 * (boxes[0][2] + boxes[1][2])))
    else:
        axis_xz = (0.0, 0.0)
    r_nodes = np.hypot(fe.xyz[:, 0] - axis_xz[0], fe.xyz[:, 2] - axis_xz[1])
    if desc.rolling_radius is not None:
        scale, source = float(desc.rolling_radius), f"the description's rolling radius ({desc.rolling_radius:g} m)"
    else:
        contacts = [_point_xyz(model, f"contact_{s}") for s in SIDES]
        contacts = [c for c in contacts if c is not None]
        if contacts:
            scale = float(np.mean([np.hypot(c[0] - axis_xz[0], c[2] - axis_xz[1]) for c in contacts]))
            source = f"the contact points' distance from the axle axis ({scale:.4g} m)"
        else:
            scale = float(r_nodes.max())
            source = f"the largest distance of an FE node from the axle axis ({scale:.4g} m)"
    if not np.isfinite(scale) or scale <= 0:
        raise EffectNotApplicable(effect, "the wheel radius cannot be told (contact points on the axle axis?)",
                                  "state wheel.rolling_radius_m in the wheelset description")
    tol = AXIS_FRACTION * scale
    on_axis = r_nodes <= tol
    line_source = ""
    ids = fe.node_ids
    index = {int(n): k for k, n in enumerate(ids)}
    line: set[int] = set()
    for e in fe.elements:
        if e.fe_descriptor not in BEAM_DESCRIPTORS or len(e.nodes) < 2:
            continue
        rows = [index.get(int(n)) for n in e.nodes[:2]]
        if None in rows or not all(on_axis[r] for r in rows):
            continue
        if np.linalg.norm(fe.xyz[rows[0]] - fe.xyz[rows[1]]) <= COINCIDE_FRACTION * scale:
            continue  # a zero-length element ties two parts at one place; it is not the axle
        line.update(rows)
    if len(line) < 2:
        line = set(np.flatnonzero(on_axis).tolist())
        # without connectivity a node of the points table that shares its place on the axis with another node is
        # a part tied there (an axlebox node on its journal), not the axle: the axle keeps the other
        named = {index[p.fe_node] for p in getattr(model, "points", {}).values()
                 if p.fe_node is not None and p.fe_node in index and index[p.fe_node] in line}
        for r in sorted(named):
            others = [k for k in line if k != r and np.linalg.norm(fe.xyz[k] - fe.xyz[r]) <= COINCIDE_FRACTION * scale]
            if others:
                line.discard(r)
        if len(line) >= 2:
            line_source = ("the export has no element records" if not fe.elements else
                           "no beam elements run along the axle axis")
            line_source += ("; every node on the axle axis is taken as the axle line, except the points table's "
                            "nodes that share a place with another (taken as parts tied there)")
            if (fe.source, line_source) not in _SAID:
                _SAID.add((fe.source, line_source))
                log.warning("%s: %s", fe.source or "FE export", line_source)
    if len(line) < 2:
        raise EffectNotApplicable(effect, f"no axle line: fewer than two FE nodes lie on the axle axis (within "
                                          f"{tol:.3g} m of x = {axis_xz[0]:.3g}, z = {axis_xz[1]:.3g} m)",
                                  "export the axle's centre-line nodes (beam axle, or RBE2 spider centres)")
    rows = np.array(sorted(line, key=lambda r: fe.xyz[r, 1]))
    geo = WheelsetGeometry(axis_xz, scale, source, ids[rows].astype(int), fe.xyz[rows, 1].copy(), total_mass(fe),
                           desc, line_source)
    # how the FE holds the axleboxes decides what its rigid-body mass includes, which the masses are fitted to
    cases = {}
    for s in SIDES:
        try:
            cases[s] = _axlebox_case(model, geo, s, effect)
        except EffectNotApplicable as exc:
            cases[s] = exc
    known = [c for c in cases.values() if not isinstance(c, EffectNotApplicable)]
    in_fe = all(c.mass_in_fe for c in known) if known else True
    fitted, notes = desc.fitted_to_fe(geo.total_mass, in_fe)
    if not known:
        notes = notes + ("how the FE holds the axleboxes cannot be told here; its mass is taken to include them",)
    return replace(geo, description=fitted, mass_notes=notes, axlebox_cases=cases)


def total_mass(fe, rigid_below_hz: float = 1.0) -> float | None:
    """Total mass the six rigid-body modes imply [kg] (None without them).

    :func:`fem_import.checks.rigid_body_mass` fits the modes' translations;
    when its nodes cannot tell every rigid motion (a beam model: all nodes
    on the axle axis, where a spin moves no node) the rotations are used
    too: at a node ``u = t + θ × (x − c)`` and the rotation is ``θ``; with
    ``Φ_rb = R Q`` and mass normalisation the rigid-body mass matrix is
    ``(Q Qᵀ)⁻¹`` (thesis eq. 2.29 on the rigid modes), its translational
    diagonal the total mass.
    """
    from fem_import.checks import rigid_body_mass

    rb = rigid_body_mass(fe)  # the rigid-body modes told by their shapes, whatever their frequencies
    if rb is not None:
        return float(rb.mass)
    rigid = np.flatnonzero(np.asarray(fe.freqs_hz) < rigid_below_hz)
    if rigid.size != 6 or not fe.has_rotations or not fe.has_coordinates:
        return None
    r = fe.xyz - fe.xyz.mean(axis=0)
    n = len(r)
    skew = np.zeros((n, 3, 3))
    skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 2] = -r[:, 2], r[:, 1], -r[:, 0]
    skew[:, 1, 0], skew[:, 2, 0], skew[:, 2, 1] = r[:, 2], -r[:, 1], r[:, 0]
    rows_u = np.concatenate([np.broadcast_to(np.eye(3), (n, 3, 3)), -skew], axis=2)
    rows_t = np.concatenate([np.zeros((n, 3, 3)), np.broadcast_to(np.eye(3), (n, 3, 3))], axis=2)
    R = np.concatenate([rows_u, rows_t], axis=1).reshape(-1, 6)
    Phi = fe.shapes[rigid].reshape(6, -1).T
    if np.linalg.matrix_rank(R) < 6:
        return None
    Q, *_ = np.linalg.lstsq(R, Phi, rcond=None)
    try:
        M = np.linalg.inv(Q @ Q.T)
    except np.linalg.LinAlgError:
        return None
    m = float(np.mean(np.diag(M)[:3]))
    return m if np.isfinite(m) and m > 0 else None


# ----------------------------------------------------------------------------------------- axleboxes
@dataclass(frozen=True)
class AxleboxAttachment:
    """How one axlebox sits in the FE export.

    Attributes
    ----------
    side : str
    centre : tuple
        Axlebox centre [m].
    journal_node : int
    axlebox_node : int or None
        Its own FE node (None: lumped on the journal or absent).
    mass_in_fe : bool
        The FE carries the axlebox's mass and inertia (own node or lumped):
        it must be taken off when the axlebox becomes a body.
    carried_points : tuple of str
        Points (``axlebox_<side>`` and the setups' axlebox sensors) that move
        with the axlebox body.
    case : str
        ``"own_node"``, ``"lumped"`` or ``"absent"``.
    note : str
        What was found and assumed, in words.
    """

    side: str
    centre: tuple
    journal_node: int
    axlebox_node: int | None
    mass_in_fe: bool
    carried_points: tuple[str, ...]
    case: str
    note: str


def _axlebox_sensors(setups: Sequence, side: str, centre: np.ndarray, own: int | None, journal: int,
                     scale: float) -> list[str]:
    """Channels on the axlebox of ``side``: attached to its own node, or named/labelled axlebox and near it."""
    from receptance.diagnosis.compare import infer_body

    names = []
    for table in setups:
        acc = table[table["quantity"] == "acceleration"]
        for _, r in acc.iterrows():
            node = r.get("fe_node", np.nan)
            node = None if node is None or (isinstance(node, float) and np.isnan(node)) else int(node)
            body = r.get("body") if isinstance(r.get("body"), str) else infer_body(str(r["name"]))
            xyz = np.array([r["x"], r["y"], r["z"]], float)
            near = np.linalg.norm(xyz - centre) <= WHEEL_HALF_WIDTH * scale
            if (own is not None and node == own) or (body == "axlebox" and near and node in (journal, own, None)):
                names.append(str(r["name"]))
    return sorted(set(names))


@dataclass(frozen=True)
class _AxleboxCase:
    """How the FE holds one axlebox (:func:`_axlebox_case`)."""

    centre: np.ndarray
    journal: int
    own: int | None
    case: str
    mass_in_fe: bool
    why: str


def _axlebox_case(model, geometry: WheelsetGeometry, side: str, effect: str = "axlebox_bearing") -> _AxleboxCase:
    """The axlebox of ``side``: its centre, journal, own node, and whether the FE carries its mass (module
    docstring). ``geometry.description`` is the description as given (its masses not yet fitted to the FE).

    Raises
    ------
    EffectNotApplicable
        No axlebox centre, no axle node near it, the axlebox on springs of its own in the FE, or
        ``in_fe = "own_node"`` stated but no own node found.
    """
    desc = geometry.description
    fe = model.fe
    R = geometry.scale
    centre = desc.axlebox_centres.get(side)
    centre = np.asarray(centre, float) if centre is not None else _point_xyz(model, f"axlebox_{side}")
    if centre is None:
        raise EffectNotApplicable(effect, f"the axlebox {side} centre is unknown (no 'axlebox_{side}' in the points "
                                          f"table, none in the description)",
                                  f"add axlebox_{side} (name, fe_node, x, y, z) to points.csv or axlebox.centre_"
                                  f"{side}_m to the description")
    journal, dist = geometry.nearest_axle_node(float(centre[1]))
    if dist > JOURNAL_FRACTION * R:
        raise EffectNotApplicable(effect, f"no axle node within {JOURNAL_FRACTION * R:.3g} m of the axlebox {side} "
                                          f"centre y = {centre[1]:.4g} m (nearest {journal}, {dist:.3g} m away)",
                                  "export the journal's centre-line node")
    if fe.has_rotations:  # (a 3-DOF export is judged on translations; the bearing refuses it on its own)
        # a journal without rotations in a 6-DOF export: neither the rigid link to an axlebox node nor a rocking
        # spring can be judged
        needs_rotations(model, effect, f"the axlebox {side} moves with its journal's rotation (a rigid link) and the "
                                       f"bearing's rocking springs act on it", nodes=[journal])
    line = set(geometry.axle_nodes.tolist())
    own = None
    p = model.points.get(f"axlebox_{side}")
    if p is not None and p.fe_node is not None and p.fe_node not in line and p.fe_node in set(fe.node_ids.tolist()):
        xyz = fe.xyz[fe.index(p.fe_node)]
        if np.linalg.norm(xyz - centre) <= JOURNAL_FRACTION * R:
            own = int(p.fe_node)
    if own is None:
        d = np.linalg.norm(fe.xyz - centre, axis=1)
        cand = [int(fe.node_ids[k]) for k in np.argsort(d) if d[k] <= COINCIDE_FRACTION * R
                and int(fe.node_ids[k]) not in line]
        own = cand[0] if cand else None
    if own is not None and not moves_with(fe, own, journal):
        raise EffectNotApplicable(effect, f"the FE already holds the axlebox {side} on springs of its own (node {own} "
                                          f"does not move rigidly with the journal node {journal})",
                                  "this effect replaces a rigid axlebox; compare the FE's own bearing stiffness with "
                                  "the measurement instead (or export the design with the axlebox tied)")
    if desc.axlebox_in_fe != "auto":
        case = desc.axlebox_in_fe
        if case == "own_node" and own is None:
            raise EffectNotApplicable(effect, f"the description says the axlebox has its own FE node, but no node "
                                              f"other than the journal {journal} lies at the axlebox {side} centre",
                                      "give the axlebox node as axlebox_" + side + " in points.csv, or set "
                                      "axlebox.in_fe to 'lumped' or 'absent'")
        return _AxleboxCase(centre, journal, own, case, case != "absent",
                            f"stated by the description ({desc.source or 'given'})")
    if own is not None:
        # a node of its own at the centre, moving rigidly with the journal, is the axlebox the FE models
        return _AxleboxCase(centre, journal, own, "own_node", True,
                            "the FE models the axlebox: a node of its own at the centre moves rigidly with the journal")
    masses = {int(n) for e in fe.elements if e.fe_descriptor == 161 for n in e.nodes}
    if journal in masses and not line <= masses:
        # what a beam axle lumps on its journal node, and on no other axle node by construction, is the axlebox
        return _AxleboxCase(centre, journal, None, "lumped", True,
                            f"a lumped-mass element sits on the journal node {journal} (not on every axle node)")
    m_fe = geometry.total_mass
    if m_fe is None:
        return _AxleboxCase(centre, journal, None, "lumped", True,
                            "the FE's total mass is unknown (no six rigid-body modes); assumed the axlebox is lumped "
                            "on the journal (usual in rotor-dynamics models); state axlebox.in_fe in the description "
                            "if not")
    # only the FE's total mass can tell: against the description's own masses when it gives them, else against
    # Table 2.1's, which describe one wheelset, so only a near match counts
    stated = {"axle_mass", "wheel_mass"} | ({"disc_mass"} if desc.n_discs else set())
    ref = desc if stated <= desc.given else WheelsetDescription(n_discs=desc.n_discs)
    whose = "the description's" if ref is desc else "thesis Table 2.1's"
    without = ref.wheelset_mass
    with_boxes = without + 2 * (desc.axlebox_mass if "axlebox_mass" in desc.given
                                else TABLE_2_1_MASSES["axlebox_mass"])
    mass_in_fe = abs(m_fe - with_boxes) < abs(m_fe - without)
    off = abs(m_fe - (with_boxes if mass_in_fe else without)) / m_fe
    if off <= MASS_NOTE_RTOL:
        why = (f"the FE's rigid-body modes give {m_fe:.1f} kg, {whose} wheelset "
               + (f"with axleboxes ({with_boxes:.0f} kg)" if mass_in_fe else f"without axleboxes ({without:.0f} kg)")
               + f" to {100 * off:.1f} %")
        return _AxleboxCase(centre, journal, None, "lumped" if mass_in_fe else "absent", mass_in_fe, why)
    why = (f"neither an axlebox node, nor a lumped mass on the journal, and the FE's {m_fe:.1f} kg matches {whose} "
           f"wheelset neither with ({with_boxes:.0f} kg) nor without axleboxes ({without:.0f} kg) within "
           f"{100 * MASS_NOTE_RTOL:g} %: assumed lumped on the journal (usual in rotor-dynamics models); state "
           f"axlebox.in_fe (and the masses) in the description")
    return _AxleboxCase(centre, journal, None, "lumped", True, why)


def axlebox_attachment(model, geometry: WheelsetGeometry, side: str, setups: Sequence = (), *,
                       effect: str = "axlebox_bearing") -> AxleboxAttachment:
    """Where the axlebox of ``side`` is in the FE and whether the FE carries its mass (module docstring).

    Raises
    ------
    EffectNotApplicable
        No axlebox centre (neither description nor points table), no axle
        node near it, or ``in_fe = "own_node"`` stated but no own node found.
    """
    found = geometry.axlebox_cases.get(side)
    if found is None:
        found = _axlebox_case(model, geometry, side, effect)
    if isinstance(found, EffectNotApplicable):
        raise EffectNotApplicable(effect, found.reason, found.remedy)
    desc = geometry.description
    centre, journal, own, case, mass_in_fe = found.centre, found.journal, found.own, found.case, found.mass_in_fe
    carried = [f"axlebox_{side}"] + _axlebox_sensors(setups, side, centre, own, journal, geometry.scale)
    what = {"own_node": f"its own FE node {own} (tied to the journal node {journal})",
            "lumped": f"lumped on the journal node {journal}",
            "absent": f"absent from the FE (journal node {journal})"}[case]
    note = (f"axlebox {side}: {what}; {found.why}; the body is {desc.axlebox_mass:.4g} kg with inertia "
            f"{'/'.join(f'{v:.3g}' for v in desc.axlebox_inertia)} kg m^2"
            + ("" if mass_in_fe else ", added (the FE lacks it)")
            + ("" if mass_in_fe is False else ", taken off the journal")
            + f"; {len(carried) - 1} sensor(s) move with it"
            + (f" ({geometry.line_source})" if geometry.line_source else ""))
    return AxleboxAttachment(side, tuple(float(c) for c in centre), journal, own, bool(mass_in_fe),
                             tuple(carried), case, note)


# -------------------------------------------------------------------------------------------- wheels
@dataclass(frozen=True)
class WheelAttachment:
    """One wheel in the FE export and its assumed mass layout.

    Attributes
    ----------
    side : str
    seat_node : int
        Axle-line node of the wheel seat.
    reference_node : int
        Node whose rigid motion is the wheel's frame in the FE (a hub node
        tied to the seat, else the seat itself).
    carried : tuple of int
        The wheel's FE nodes (the seat excluded).
    centre : tuple
        Hub centre on the axle axis [m].
    mass : float
        Wheel mass [kg].
    inertia : (float, float, float)
        About x, y, z through the centre [kg m²] (rim, web and hub as laid out).
    coupling : ndarray (6, modes)
        Linear and angular momentum about the centre of each FE mode's
        deformation of the wheel relative to the reference node's rigid
        motion, ``Σ m_j [d_j; r_j × d_j]`` over the mass layout.
    note : str
    """

    side: str
    seat_node: int
    reference_node: int
    carried: tuple[int, ...]
    centre: tuple
    mass: float
    inertia: tuple[float, float, float]
    coupling: np.ndarray
    note: str


def _adjacency(fe) -> dict[int, set[int]]:
    index = {int(n): k for k, n in enumerate(fe.node_ids)}
    adj: dict[int, set[int]] = {}
    for e in fe.elements:
        rows = [index[int(n)] for n in e.nodes if int(n) in index]
        for a in rows:
            adj.setdefault(a, set()).update(r for r in rows if r != a)
    return adj


def wheel_attachment(model, geometry: WheelsetGeometry, side: str, *, effect: str = "wheel_seat_joint"
                     ) -> WheelAttachment:
    """The wheel of ``side``: its FE nodes, seat, frame and mass layout (module docstring).

    Raises
    ------
    EffectNotApplicable
        No contact point, no wheel node, no seat node near the hub plane.
    """
    desc = geometry.description
    fe = model.fe
    R = geometry.scale
    contact = _point_xyz(model, f"contact_{side}")
    if contact is None:
        raise EffectNotApplicable(effect, f"the contact point contact_{side} is not in the points table",
                                  f"add contact_{side} (name, fe_node, x, y, z) to points.csv")
    p = model.points[f"contact_{side}"]
    start = fe.index(p.fe_node) if p.fe_node is not None else int(np.argmin(np.linalg.norm(fe.xyz - contact, axis=1)))
    line_rows = set(fe.index(n) for n in geometry.axle_nodes)
    r_all = geometry.radial(fe.xyz)
    region = (np.abs(fe.xyz[:, 1] - contact[1]) <= WHEEL_HALF_WIDTH * R) & (r_all <= WHEEL_OUTER * R)
    if fe.elements:
        adj = _adjacency(fe)
        seen, queue = {start}, deque([start])
        while queue:
            a = queue.popleft()
            for b in adj.get(a, ()):
                if b not in seen and b not in line_rows and region[b]:
                    seen.add(b)
                    queue.append(b)
        wheel = sorted(seen - line_rows)
        how = "reached from the contact point's node through the elements"
    else:
        wheel = sorted(set(np.flatnonzero(region & (np.abs(fe.xyz[:, 1] - contact[1]) <= 0.25 * R)).tolist())
                       - line_rows)
        how = "inside the wheel's region (the export has no elements to follow)"
    if not wheel:
        raise EffectNotApplicable(effect, f"no FE node of wheel {side} found near contact_{side}",
                                  f"attach contact_{side} to a rim node in points.csv")
    y_plane = desc.hub_planes.get(side)
    if y_plane is None:
        y_plane = float(np.mean(fe.xyz[wheel, 1]))
        plane_text = f"hub plane y = {y_plane:.4g} m (mean of the wheel's nodes)"
    else:
        plane_text = f"hub plane y = {y_plane:.4g} m (description)"
    seat, dist = geometry.nearest_axle_node(y_plane)
    if dist > JOURNAL_FRACTION * R:
        raise EffectNotApplicable(effect, f"no axle node within {JOURNAL_FRACTION * R:.3g} m of wheel {side}'s hub "
                                          f"plane y = {y_plane:.4g} m (nearest {seat}, {dist:.3g} m away)",
                                  "export the wheel seat's centre-line node, or state wheel.hub_plane_"
                                  f"{side}_m in the description")
    needs_rotations(model, effect, f"wheel {side}'s seat turns with the axle (its mass layout rides on the seat's "
                                   f"rotation) and the joint's rocking and torsional springs act on the seat's and the "
                                   f"hub's rotations", nodes=[seat])
    seat_xyz = fe.xyz[fe.index(seat)]
    # parts tied to the seat at its place (a hub centre node) move with the wheel; a rim body node at the same
    # place on web springs is no tie
    tied = [k for k in np.flatnonzero(np.linalg.norm(fe.xyz - seat_xyz, axis=1) <= COINCIDE_FRACTION * R)
            if k not in line_rows and moves_with(fe, int(fe.node_ids[k]), seat)]
    carried_rows = sorted(set(wheel) | set(tied))
    reference = int(fe.node_ids[tied[0]]) if tied else seat
    centre = np.array([geometry.axis_xz[0], seat_xyz[1], geometry.axis_xz[1]])
    # the wheel's mass laid out from its drawing, each piece rigidly attached to its nearest wheel node
    r_rim = desc.rim_radius or RIM_RADIUS_FRACTION * R
    r_hub = desc.hub_radius or HUB_RADIUS_FRACTION * R
    theta = 2 * np.pi * (np.arange(_N_ANGLES) + 0.5) / _N_ANGLES
    edges = np.linspace(r_hub, r_rim, _N_WEB_RADII + 1)
    radii_web = 0.5 * (edges[1:] + edges[:-1])
    area = np.diff(edges**2)
    pts, masses = [], []
    for r, m in [(r_rim, desc.rim_mass)] + [(r, desc.web_mass * a / area.sum()) for r, a in zip(radii_web, area)]:
        for t in theta:
            pts.append(centre + r * np.array([np.cos(t), 0.0, np.sin(t)]))
            masses.append(m / _N_ANGLES)
    pts, masses = np.array(pts), np.array(masses)
    cxyz = fe.xyz[carried_rows]
    dist = np.linalg.norm(pts[:, None, :] - cxyz[None, :, :], axis=2)
    nearest = np.argmin(dist, axis=1)
    nodes = fe.node_ids[np.asarray(carried_rows)[nearest]]
    # a piece near a node (a shell or solid wheel) is lumped on it: shell rotations (drilling) are no rigid link;
    # a piece far from every node (a rim body node at the centre) rides on its node's rigid motion
    near = dist[np.arange(len(pts)), nearest] <= LUMP_FRACTION * R
    where = np.where(near[:, None], cxyz[nearest], pts)
    coupling = _deformation_momentum(fe, nodes, where, masses, reference, centre)
    rel = pts - centre
    x, y, z = rel.T
    ri, ro = 0.5 * r_hub, r_hub  # the hub: a thick ring from about the seat to the web's inner edge
    i_hub_polar = desc.hub_mass * (ri**2 + ro**2) / 2
    i_hub_diam = desc.hub_mass * (ri**2 + ro**2) / 4
    inertia = (float(np.sum(masses * (y**2 + z**2)) + i_hub_diam), float(np.sum(masses * (x**2 + z**2)) + i_hub_polar),
               float(np.sum(masses * (x**2 + y**2)) + i_hub_diam))
    n_nodes = len(set(nodes.tolist()))
    layout = (f"the export has no mass matrix, so the wheel's {desc.wheel_mass:g} kg were laid out from its drawing: "
              f"rim {desc.rim_mass:g} kg as a ring at r = {r_rim:.4g} m, web {desc.web_mass:g} kg as an annulus "
              f"{r_hub:.4g}-{r_rim:.4g} m, hub {desc.hub_mass:g} kg rigid")
    if n_nodes == 1:
        layout += (f"; the wheel is one FE node ({int(nodes[0])}: a rigid rim on web springs), so rim and web move "
                   f"as one body with the ring's rotary inertia")
    else:
        layout += f"; spread over {n_nodes} wheel nodes (each piece on its nearest node)"
    note = (f"wheel {side}: {len(carried_rows)} FE nodes {how}; seat node {seat}, frame node {reference}; "
            f"{plane_text}; {layout}")
    return WheelAttachment(side, int(seat), int(reference), tuple(int(n) for n in fe.node_ids[carried_rows]),
                           tuple(float(c) for c in centre), float(desc.wheel_mass), inertia, coupling, note)


def _deformation_momentum(fe, nodes: np.ndarray, pts: np.ndarray, masses: np.ndarray, reference: int,
                          centre: np.ndarray) -> np.ndarray:
    """G (6 x modes): linear and angular momentum about ``centre`` of each FE mode's deformation of the mass
    pieces at ``pts`` (rigidly attached to ``nodes``) relative to the reference node's rigid motion,
    ``Σ m_j [d_j; (p_j − c) × d_j]`` — the inertial coupling between a floating frame and the deformation."""
    n = len(pts)
    eye = np.eye(3)
    dirs = np.tile(eye, (n, 1))
    where = np.repeat(pts, 3, axis=0)
    own = fe.at_points(np.repeat(nodes, 3), where, dirs)  # (3n, modes)
    ref = fe.at_points([reference] * (3 * n), where, dirs)
    d = (own - ref).reshape(n, 3, -1)  # (n, 3, modes)
    lin = np.einsum("j,jkm->km", masses, d)
    arm = pts - centre
    ang = np.einsum("j,jkm->km", masses, np.cross(arm[:, :, None], d, axisa=1, axisb=1, axisc=1))
    return np.vstack([lin, ang])


# ------------------------------------------------------------------------------------- hanging points
#: a part's rotary inertia taken off a node may exceed the node's apparent rotary inertia by this share: the
#: apparent value bounds what the node carries only through the retained modes' rotations there, and a part's
#: inertia is an estimate (Table 2.1's 0.9 kg m² box sits 0.5-1 % above the default design FE's journal); the
#: small negative inertia left has its spurious pole at sqrt(k / |ΔI|), far above any band. Beyond it the node's
#: rotation would carry a clearly negative kinetic energy.
ROTARY_SLACK = 0.1


def removable_mass(model, point: Point, mass: float, inertia=None, *, effect: str, part: str, keys: str) -> str:
    """Check that the FE carries at ``point`` the mass (and inertia) an effect takes off there.

    A part the FE holds rigidly at a node is moved onto a body of its own by
    a negative point mass at the node (:func:`receptance.effect_modifications.detached_body_terms`).
    The FE's retained modes give the node's apparent mass matrix
    ``A = (T Tᵀ)⁻¹`` (``T``: the mass-normalised shapes' rows of its DOFs,
    thesis eq. 2.24; with every mode kept ``A`` is the node's own mass,
    with fewer it is more); the modified kinetic energy stays positive only
    while the removed ``D ≤ A``, i.e. ``μ = λ_max(D^½ T Tᵀ D^½) ≤ 1``.

    Parameters
    ----------
    model : ModalModel
    point : Point
        The node the part is taken off (a journal, a seat).
    mass : float
        [kg].
    inertia : (float, float, float), optional
        About x, y, z [kg m²]; checked with :data:`ROTARY_SLACK`.
    effect, part, keys : str
        For the message: the effect, the part's name, the description keys that state its mass.

    Returns
    -------
    str
        What the node carries against what is taken off (for the effect's assumptions).

    Raises
    ------
    EffectNotApplicable
        More mass (or clearly more inertia) than the node carries: naming the keys to state.
    """
    m = model if point.name in model.points else model.with_points([point])
    T = m.rows([f"{point.name}:{a}" for a in ("x", "y", "z")])
    flex = T @ T.T
    apparent = 1.0 / float(np.linalg.eigvalsh(flex).max())
    mu = mass / apparent
    where = f"FE node {point.fe_node}" if point.fe_node is not None else point.name
    if mu > 1.0:
        raise EffectNotApplicable(effect, f"taking the {part}'s {mass:.4g} kg off {where} would leave a negative mass "
                                          f"there: the FE's modes carry at most {apparent:.4g} kg at that node (its "
                                          f"apparent mass), so the {part} of this design is lighter",
                                  f"state the design's {keys} in the wheelset description (at most what the FE "
                                  f"holds there)")
    note = f"{where} carries up to {apparent:.4g} kg in the FE's modes, the {part} takes {100 * mu:.0f} % of it"
    if inertia is not None:
        Tr = m.rows([f"{point.name}:{a}" for a in ("rx", "ry", "rz")])
        d = np.sqrt(np.asarray(inertia, float))
        mu_r = float(np.linalg.eigvalsh(d[:, None] * (Tr @ Tr.T) * d[None, :]).max())
        if mu_r > 1.0 + ROTARY_SLACK:
            raise EffectNotApplicable(effect, f"taking the {part}'s rotary inertia "
                                              f"{'/'.join(f'{v:.3g}' for v in inertia)} kg m^2 off {where} would "
                                              f"leave a negative inertia there ({100 * mu_r:.0f} % of what the FE's "
                                              f"modes carry at that node)",
                                      f"state the design's {keys} in the wheelset description (at most what the "
                                      f"FE holds there)")
        note += f" and {100 * mu_r:.0f} % of its rotary inertia"
    return note


def hanging_attachment(model, geometry: WheelsetGeometry, *, effect: str = "rig_suspension"
                       ) -> list[Point] | None:
    """The described hanging points as model points (None when the description gives none: fit them).

    A point given by name is the points table's; a position is attached to
    the nearest FE node (a rigid link, as a sensor is).

    Raises
    ------
    EffectNotApplicable
        A named point that is not in the points table, or a position farther
        than the wheel radius from every node.
    """
    desc = geometry.description
    if desc.hanging_points is None:
        return None
    fe = model.fe
    out = []
    for k, hp in enumerate(desc.hanging_points):
        if isinstance(hp, str):
            if hp not in model.points:
                raise EffectNotApplicable(effect, f"hanging point {hp!r} is not in the points table "
                                                  f"(known: {sorted(model.points)})",
                                          "name a point of points.csv or give its coordinates")
            q = model.points[hp]
            out.append(Point(f"hanging_{k + 1}", q.fe_node, q.xyz))
            continue
        xyz = np.asarray(hp, float)
        d = np.linalg.norm(fe.xyz - xyz, axis=1)
        j = int(np.argmin(d))
        if d[j] > geometry.scale:
            raise EffectNotApplicable(effect, f"hanging point {xyz.tolist()} m is {d[j]:.3g} m from the nearest FE "
                                              f"node, farther than the wheel radius",
                                      "give the hanging points in the FE's coordinates (m)")
        out.append(Point(f"hanging_{k + 1}", int(fe.node_ids[j]), tuple(xyz)))
    return out
