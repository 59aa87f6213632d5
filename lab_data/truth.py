"""Design and truth modal models of a scenario, and what each setup observes.

:func:`design_modes` solves the design FE model (what gets exported);
:func:`truth_modes` solves the as-built wheelset with the scenario's hidden
effects, names its modes, gives them the Table 3.1 damping and pairs them
with the design modes by mass-weighted (subspace) MAC. :func:`setup_view`
evaluates the truth at one setup's sensors and force point, rotates each
degenerate cluster so that only one member is excited by the hammer (the
others are unobservable by construction) and computes how strongly each mode
shows in the measured accelerances.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from .fe_model import FEModel, Modes, SystemMatrices, assemble, solve_modes
from .mode_labels import (
    ModeLabel,
    align_clusters,
    degenerate_clusters,
    label_modes,
    relabel_plane,
    renumber,
    truth_damping,
)
from .scenarios import Scenario, as_built_parameters
from .sensors import Setup, shape_matrix
from .wheelset import WheelsetParameters, build_wheelset

__all__ = ["SolvedModel", "design_modes", "truth_modes", "SetupView", "setup_view", "check_spectral_gap",
           "pair_with_design", "greedy_pairs", "truncated"]

log = logging.getLogger(__name__)

BAND_HZ = (10.0, 500.0)


@dataclass(frozen=True)
class SolvedModel:
    """A model with its assembled matrices, aligned modes, labels and damping."""

    model: FEModel
    system: SystemMatrices
    modes: Modes
    labels: tuple[ModeLabel, ...]
    zeta: np.ndarray


def truncated(s: SolvedModel, keep: np.ndarray) -> SolvedModel:
    """The same solved model with only the modes selected by the boolean mask ``keep``."""
    m = s.modes
    modes = Modes(m.freqs_hz[keep], m.shapes[keep], m.reduced[:, keep])
    return SolvedModel(s.model, s.system, modes, tuple(l for l, k in zip(s.labels, keep) if k), s.zeta[keep])


def _solve(model: FEModel, f_max_hz: float) -> SolvedModel:
    system = assemble(model)
    modes = align_clusters(model, system, solve_modes(model, system, f_max_hz))
    labels = tuple(label_modes(model, system, modes))
    return SolvedModel(model, system, modes, labels, truth_damping(list(labels), modes.freqs_hz))


def design_modes(params: WheelsetParameters, f_max_hz: float) -> SolvedModel:
    """The design FE model (nominal parameters, rigid joints and bearings, free-free) up to ``f_max_hz``."""
    return _solve(build_wheelset(params, name="design wheelset"), f_max_hz)


def check_spectral_gap(freqs_hz: np.ndarray, cut_hz: float, what: str, margin: float = 0.02) -> None:
    """Raise if a mode lies within ``margin`` (relative) of the truncation frequency.

    A mode straddling the cut would be in the truth but not in the export (or
    the reverse) by accident rather than by the scenario's design.
    """
    near = freqs_hz[np.abs(freqs_hz - cut_hz) < margin * cut_hz]
    if near.size:
        raise ValueError(
            f"{what}: modes at {np.round(near, 2).tolist()} Hz lie within {margin:.0%} of the truncation "
            f"frequency {cut_hz} Hz; choose a truncation frequency in a gap of the spectrum"
        )


def truth_modes(scenario: Scenario, params: WheelsetParameters, f_max_hz: float, design: SolvedModel) -> SolvedModel:
    """The as-built truth of ``scenario`` with its modes up to ``f_max_hz``.

    A truth mode that pairs with a design mode (see :func:`pair_with_design`)
    takes that mode's name and Table 3.1 damping, so "3rd flexural" means the
    same physical mode in every scenario even when a hidden effect reorders
    frequencies; modes the hidden effect adds keep their own classification.
    """
    p = as_built_parameters(params) if scenario.as_built else params
    model = build_wheelset(p, name=f"truth wheelset ({scenario.name})")
    for effect in scenario.effects:
        model = effect.apply(model)
    own = _solve(model, f_max_hz)
    pairs = pair_with_design(own, design)
    labels = []
    counters: dict[str, int] = {}
    cluster_of = {i: k for k, c in enumerate(degenerate_clusters(own.modes.freqs_hz)) for i in c}
    cluster_order: dict[tuple[int, str], int] = {}
    for i, (partner, _mac) in enumerate(pairs):
        lab = own.labels[i]
        if partner and design.labels[partner[0]].family != "rigid":
            labels.append(relabel_plane(design.labels[partner[0]], own.model, own.modes.shapes[i]))
        elif lab.family == "rigid":
            labels.append(lab)
        else:
            # modes the hidden effect adds are numbered among themselves
            key = (cluster_of[i], lab.family)
            if key not in cluster_order:
                counters[lab.family] = counters.get(lab.family, 0) + 1
                cluster_order[key] = counters[lab.family]
            labels.append(renumber(lab, cluster_order[key]))
    return SolvedModel(own.model, own.system, own.modes, tuple(labels), truth_damping(labels, own.modes.freqs_hz))


def pair_with_design(truth: SolvedModel, design: SolvedModel, threshold: float = 0.8) -> list[tuple[list[int], float]]:
    """Design partner(s) of every truth mode by mass-weighted subspace MAC.

    For each truth mode the MAC against each degenerate cluster of design
    modes is ``|Phi_c^T M phi|^2 / (phi^T M phi)`` (design mass matrix,
    design nodes only; ``Phi_c`` mass-orthonormal), i.e. the share of the
    truth shape that lies in the cluster's subspace. Pairs are assigned
    greedily by decreasing MAC, each design cluster taking at most as many
    truth modes as it has members, and only above ``threshold``; truth modes
    of hidden effects usually have no partner.

    Returns
    -------
    list of (design mode indices, MAC)
        One entry per truth mode; an empty index list means no partner (the
        MAC is then the best one found).
    """
    n_design_nodes = design.model.n_nodes
    # truth models may have extra nodes (an absorber); compare on design nodes by id
    t_idx = np.array([truth.model.index(n) for n in design.model.node_ids])
    t_full = truth.modes.shapes[:, t_idx, :].reshape(len(truth.modes.freqs_hz), 6 * n_design_nodes).T
    M = design.system.M
    cross = t_full.T @ (M @ design.modes.full)  # (mt, md)
    norm_t = np.einsum("im,im->m", t_full, M @ t_full)
    clusters = degenerate_clusters(design.modes.freqs_hz)
    with np.errstate(divide="ignore", invalid="ignore"):
        mac = np.stack([np.sum(cross[:, c] ** 2, axis=1) for c in clusters], axis=1) / norm_t[:, None]
    return greedy_pairs(np.nan_to_num(mac), clusters, threshold)


def greedy_pairs(mac: np.ndarray, clusters: list[list[int]], threshold: float) -> list[tuple[list[int], float]]:
    """Assign truth modes (rows of ``mac``) to design clusters (columns) by decreasing MAC.

    Each cluster takes at most as many truth modes as it has members, and
    only pairs with MAC >= ``threshold`` are made; an unpaired truth mode
    gets an empty list and its best MAC.
    """
    capacity = [len(c) for c in clusters]
    result: list[tuple[list[int], float]] = [([], float(mac[i].max())) for i in range(mac.shape[0])]
    for flat in np.argsort(-mac, axis=None):
        i, k = np.unravel_index(flat, mac.shape)
        if mac[i, k] < threshold:
            break
        if result[i][0] or capacity[k] == 0:
            continue
        capacity[k] -= 1
        result[i] = (list(clusters[k]), float(mac[i, k]))
    return result


@dataclass(frozen=True)
class SetupView:
    """The truth as one setup sees it.

    Attributes
    ----------
    freqs_hz, zeta : ndarray (m,)
    input_shape : ndarray (m,)
        Modal displacement at the force point along the force direction.
    output_shapes : ndarray (29, m)
        Modal displacement at each accelerometer along its direction.
    peak_ratio : ndarray (m,)
        Peak accelerance of the mode over all channels, ``max_j |c_j b| / (2 zeta)``,
        relative to the strongest mode in the band; 0 outside the band.
    point_shapes : ndarray (3 * n_points, m)
        Modal displacement at the named points along x, y, z.
    shapes_full : ndarray (m, n_nodes, 6)
        The truth shapes after the cluster rotation.
    labels : tuple of ModeLabel
        Truth labels with the bending plane re-read after the rotation.
    """

    freqs_hz: np.ndarray
    zeta: np.ndarray
    input_shape: np.ndarray
    output_shapes: np.ndarray
    point_shapes: np.ndarray
    peak_ratio: np.ndarray
    shapes_full: np.ndarray
    labels: tuple[ModeLabel, ...]


def setup_view(truth: SolvedModel, setup: Setup, points: list[tuple[str, int, tuple]]) -> SetupView:
    """Evaluate the truth at a setup's transducers and rotate degenerate clusters to the excitation.

    In a cluster of equal frequencies any orthonormal basis is a valid set of
    modes; the one whose first member is aligned with the force's modal
    participation makes every other member exactly unexcited, so the
    manifest can say which modes this setup can observe.
    """
    model = truth.model
    shapes = truth.modes.shapes.copy()
    f = truth.modes.freqs_hz
    force = setup.force

    def b_of(sh):
        return shape_matrix(model, sh, [force.fe_node], [force.position], [force.direction])[0]

    b = b_of(shapes)
    for c in degenerate_clusters(f):
        if len(c) < 2 or f[c[0]] < 1e-3:
            continue
        bc = b[c]
        nb = np.linalg.norm(bc)
        if nb < 1e-12:
            continue
        # Householder-free construction: QR of [b, I] gives an orthonormal basis led by b
        q, _ = np.linalg.qr(np.column_stack([bc / nb, np.eye(len(c))]))
        q = q[:, : len(c)]
        if q[:, 0] @ bc < 0:
            q[:, 0] *= -1
        shapes[c] = np.tensordot(q.T, shapes[c], axes=1)
    b = b_of(shapes)
    acc = setup.accelerometers
    C = shape_matrix(
        model, shapes, [s.fe_node for s in acc], [s.position for s in acc], [s.direction for s in acc]
    )
    P = shape_matrix(
        model, shapes,
        [fe for _, fe, _ in points for _k in range(3)],
        [x for _, _, x in points for _k in range(3)],
        [np.eye(3)[k] for _ in points for k in range(3)],
    )
    in_band = (f >= BAND_HZ[0]) & (f <= BAND_HZ[1])
    peak = np.zeros(len(f))
    with np.errstate(divide="ignore", invalid="ignore"):
        peak[in_band] = np.max(np.abs(C[:, in_band] * b[in_band]), axis=0) / (2 * truth.zeta[in_band])
    ratio = peak / peak.max() if peak.max() > 0 else peak
    labels = tuple(relabel_plane(lab, model, shapes[i]) for i, lab in enumerate(truth.labels))
    return SetupView(f.copy(), truth.zeta.copy(), b, C, P, ratio, shapes, labels)
