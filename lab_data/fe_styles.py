"""The design FE export in one of two styles, and how the truth pairs with it.

``mesh``
    The lab's own 3D design model (:mod:`lab_data.wheelset`): shell webs and
    discs, beam axle and rims, rigid links; transducers attach to the mesh
    node under them.
``beam``
    The model a design office builds for rotor dynamics
    (:mod:`lab_data.design_beam`): Timoshenko beam axle, lumped hubs, discs and
    axleboxes, rims as rigid bodies on web springs, its own node numbers.
    Every transducer and point attaches rigidly to the node of the body it
    sits on: rim sensors and contact points to the rim-centre node, disc
    sensors and the hammer to the disc-seat node, axle sensors to the
    nearest axle station, axlebox sensors and centres to the journal node;
    their true positions are kept.

The truth (the as-built 3D wheelset) is the same in both styles. Its modes are
paired with the exported modes — in the ``mesh`` style by mass-weighted MAC
on the shared nodes (:func:`lab_data.truth.pair_with_design`), in the
``beam`` style, where the two models share no node, by mass-weighted MAC on
the beam model's DOFs with the truth reduced to them
(:func:`truth_on_beam`), against each degenerate cluster of exported modes,
assigned greedily like :func:`~lab_data.truth.pair_with_design`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .design_beam import BeamDesign, beam_elements, solve_beam_design
from .fe_model import Beam, PointMass, Shell
from .mode_labels import degenerate_clusters, mix_clusters
from .sensors import Sensor, Setup, shape_matrix
from .truth import SolvedModel, check_spectral_gap, greedy_pairs, pair_with_design, truncated
from .uff_export import ElementRecord
from .wheelset import WheelsetParameters

__all__ = ["FE_STYLES", "DesignExport", "mesh_export", "beam_export", "mesh_elements", "subspace_mac",
           "sensor_mac", "truth_on_beam"]

FE_STYLES = ("mesh", "beam")
PAIR_MAC = 0.8


@dataclass(frozen=True)
class DesignExport:
    """The design FE as exported in one style, with the transducers attached to it.

    Attributes
    ----------
    style : str
        ``mesh`` or ``beam``.
    solved : SolvedModel
        The exported model with its modes up to the export frequency
        (degenerate pairs aligned to the x and z planes) and their labels.
    freqs_hz, shapes : ndarray
        The exported modes, degenerate clusters in the arbitrary basis a
        solver returns.
    elements : tuple of ElementRecord
        UFF 2412 records.
    setups : dict of str to Setup
        The sensor setups with ``fe_node`` on the exported model.
    points : list of (name, fe_node, xyz)
        Contact points and axlebox centres on the exported model.
    pairs : list of (list of int, float)
        Per truth mode: its partner modes in the export (0-based) and the MAC.
    model_name, description, punch_title : str
        Identification written into the files.
    beam : BeamDesign or None
        The beam design's bodies and springs (``beam`` style only).
    """

    style: str
    solved: SolvedModel
    freqs_hz: np.ndarray
    shapes: np.ndarray
    elements: tuple[ElementRecord, ...]
    setups: dict
    points: list
    pairs: list
    model_name: str
    description: str
    punch_title: str
    beam: BeamDesign | None = None


def mesh_elements(model) -> list[ElementRecord]:
    """UFF 2412 records of the 3D design model: beams (21), shells (94), lumped masses (161), display skins (94).

    Physical property numbers: 1 axle beams, 2 wheel-rim beams, 3 wheel webs,
    4 brake discs, 5 lumped masses, 99 display skins (no stiffness, no mass:
    they only give the mesh its wheelset look).
    """
    records = []
    eid = 1
    for e in model.elements:
        if isinstance(e, Beam):
            prop = 2 if "rim" in e.group else 1
            records.append(ElementRecord(eid, 21, prop, 1, 7, tuple(int(n) for n in e.nodes)))
        elif isinstance(e, Shell):
            prop = 4 if e.group.startswith("disc") else 3
            records.append(ElementRecord(eid, 94, prop, 1, 8, tuple(int(n) for n in e.nodes)))
        elif isinstance(e, PointMass):
            records.append(ElementRecord(eid, 161, 5, 1, 2, (int(e.node),)))
        else:
            continue
        eid += 1
    for s in model.skins:
        records.append(ElementRecord(eid, 94, 99, 1, 11, tuple(int(n) for n in s.nodes)))
        eid += 1
    return records


def mesh_export(design: SolvedModel, truth: SolvedModel, setups: dict, points: list,
                rng: np.random.Generator) -> DesignExport:
    """The ``mesh`` style: the 3D design model as it is, transducers on its nodes."""
    exported = mix_clusters(design.model, design.system, design.modes, rng)
    return DesignExport(
        "mesh", design, exported.freqs_hz, exported.shapes, tuple(mesh_elements(design.model)), dict(setups),
        list(points), pair_with_design(truth, design), "railmodal design wheelset",
        "Meneghino trailer wheelset, design FE, free-free, SI units (m, kg, s)",
        "RAILMODAL DESIGN WHEELSET FREE-FREE",
    )


def subspace_mac(a: np.ndarray, basis: np.ndarray) -> np.ndarray:
    """Share of each column of ``a`` lying in the span of ``basis``'s columns: ``|P a|^2 / |a|^2``.

    For a one-column basis this is the usual MAC; for a degenerate cluster it
    does not depend on the basis an FE solver chose inside the cluster.
    """
    q, r = np.linalg.qr(np.asarray(basis, float))
    keep = np.abs(np.diag(r)) > 1e-12 * max(np.abs(np.diag(r)).max(initial=0.0), 1e-300)
    q = q[:, keep]
    a = np.asarray(a, float).reshape(len(q), -1)
    norm = np.einsum("im,im->m", a, a)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.sum((q.T @ a) ** 2, axis=0) / norm
    return np.nan_to_num(out)


def _at(solved: SolvedModel, sensors: list[Sensor]) -> np.ndarray:
    """Shapes (n_sensors, m) at rigidly attached sensors along their measuring directions."""
    return shape_matrix(solved.model, solved.modes.shapes, [s.fe_node for s in sensors],
                        [s.position for s in sensors], [s.direction for s in sensors])


def truth_on_beam(truth: SolvedModel, design: SolvedModel, beam: BeamDesign) -> np.ndarray:
    """The truth's modes reduced to the beam design's DOFs: ``(6 n_beam_nodes, m)``.

    Axle stations take the truth's axle motion interpolated linearly along
    the axle (all six DOFs); every lumped body (rim, disc, axlebox) takes the
    least-squares rigid-body motion of its nodes in the truth — for a rim,
    the nodes of the rim ring (the 3D web's outer edge). Wheel modes with
    nodal diameters >= 2 have no rigid part and vanish here, as they should.
    """
    m = len(truth.modes.freqs_hz)
    out = np.zeros((beam.model.n_nodes, 6, m))
    shapes = truth.modes.shapes  # (m, n, 6)
    axle = design.model.nodes_of("axle")
    t_idx = np.array([truth.model.index(n) for n in axle])
    y = truth.model.xyz[t_idx, 1]
    order = np.argsort(y)
    y, t_idx = y[order], t_idx[order]
    # linear interpolation along the axle as a matrix: W[i, j] = weight of truth station j at beam station i
    W = np.stack([np.interp(beam.axle_y, y, np.eye(len(y))[j]) for j in range(len(y))], axis=1)
    rows = [beam.model.index(n) for n in beam.axle_nodes]
    out[rows] = np.einsum("ij,mjk->ikm", W, shapes[:, t_idx, :])
    bodies = {}
    for side in ("L", "R"):
        wheel = design.model.nodes_of(f"wheel_{side}")
        xyz = design.model.xyz[[design.model.index(n) for n in wheel]]
        r = np.hypot(xyz[:, 0], xyz[:, 2])
        bodies[beam.rim_node[side]] = wheel[np.isclose(r, r.max(), rtol=1e-6)]
        bodies[beam.disc_node[side]] = design.model.nodes_of(f"disc_{side}")
        bodies[beam.journal_node[side]] = design.model.nodes_of(f"axlebox_{side}")
    for node, members in bodies.items():
        centre = beam.model.coords(node)
        idx = np.array([truth.model.index(n) for n in members])
        rel = truth.model.xyz[idx] - centre
        # u_i = t + theta x r_i  ->  rows [I, -[r_i]x] per node
        A = np.zeros((3 * len(idx), 6))
        for i, (rx, ry, rz) in enumerate(rel):
            A[3 * i: 3 * i + 3, :3] = np.eye(3)
            A[3 * i: 3 * i + 3, 3:] = [[0.0, rz, -ry], [-rz, 0.0, rx], [ry, -rx, 0.0]]
        u = shapes[:, idx, :3].reshape(m, -1).T
        fit = np.linalg.lstsq(A, u, rcond=None)[0]  # (6, m)
        out[beam.model.index(node)] = fit
    return out.reshape(6 * beam.model.n_nodes, m)


def beam_export(params: WheelsetParameters, export_hz: float, design: SolvedModel, truth: SolvedModel,
                setups: dict, points: list, rng: np.random.Generator) -> DesignExport:
    """The ``beam`` style: the rotor-dynamics design model, transducers moved to the nodes of their bodies.

    Parameters
    ----------
    params : WheelsetParameters
        The design drawing (the same as the 3D design model's).
    export_hz : float
        Highest exported mode [Hz]; it must lie in a gap of the beam model's spectrum.
    design : SolvedModel
        The 3D design model: it says which body each transducer sits on.
    truth : SolvedModel
        The as-built truth, to pair with the export.
    setups, points
        Transducers and named points on the 3D design model.
    rng : numpy.random.Generator
        Mixes the degenerate clusters of the export.

    Returns
    -------
    DesignExport
    """
    beam, solved_all = solve_beam_design(params, export_hz * 1.1)
    check_spectral_gap(solved_all.modes.freqs_hz, export_hz, "beam design FE export")
    solved = truncated(solved_all, solved_all.modes.freqs_hz <= export_hz)
    exported = mix_clusters(solved.model, solved.system, solved.modes, rng)

    def body(node: int) -> str:
        return design.model.node_groups[design.model.index(node)]

    def moved(s: Sensor) -> Sensor:
        return replace(s, fe_node=beam.attach(body(s.fe_node), s.position))

    beam_setups = {name: Setup(st.name, moved(st.force), tuple(moved(s) for s in st.accelerometers))
                   for name, st in setups.items()}
    beam_points = [(name, beam.attach(body(fe), x), x) for name, fe, x in points]

    # pair by mass-weighted MAC on the beam's DOFs: |Phi_c^T M phi|^2 / (phi^T M phi), Phi_c mass-orthonormal
    t = truth_on_beam(truth, design, beam)
    M = solved.system.M
    Mt = M @ t
    cross = solved.modes.full.T @ Mt  # (m_beam, m_truth)
    norm = np.einsum("im,im->m", t, Mt)
    clusters = degenerate_clusters(solved.modes.freqs_hz)
    with np.errstate(divide="ignore", invalid="ignore"):
        mac = np.nan_to_num(np.stack([np.sum(cross[c] ** 2, axis=0) for c in clusters], axis=1) / norm[:, None])
    pairs = greedy_pairs(mac, clusters, PAIR_MAC)
    return DesignExport(
        "beam", solved, exported.freqs_hz, exported.shapes, tuple(beam_elements(beam)), beam_setups, beam_points,
        pairs, "railmodal design wheelset (beam)",
        "Meneghino trailer wheelset, beam+lumped-mass design FE, free-free, SI (m, kg, s)",
        "RAILMODAL DESIGN WHEELSET BEAM MODEL FREE-FREE", beam,
    )


def sensor_mac(export: DesignExport, setup_name: str, truth_shapes: np.ndarray, partner: list[int]) -> float | None:
    """MAC at one setup's accelerometers between a truth shape and its partner cluster in the export.

    Parameters
    ----------
    export : DesignExport
    setup_name : str
    truth_shapes : ndarray (n_accelerometers,)
        The truth mode at the setup's accelerometers, along their directions.
    partner : list of int
        The partner modes in the export (0-based); empty gives None.
    """
    if not partner:
        return None
    acc = list(export.setups[setup_name].accelerometers)
    basis = _at(export.solved, acc)[:, partner]
    return float(subspace_mac(truth_shapes, basis)[0])
