"""Finite-element model data types, assembly and the undamped modal solution.

A model is a set of nodes (6 DOF each: ux, uy, uz, rx, ry, rz in global axes),
structural elements (Timoshenko beams, flat shells, point masses, springs and
dampers), rigid links (master/slave constraints) and display-only skin quads.
Assembly gives sparse global stiffness (split by element group and
deformation type, so strain energy can be partitioned when modes are
classified), mass and damping, and the constraint transformation ``T`` with
``u_full = T u_independent``. The modal solution solves
``(K - w^2 M) phi = 0`` on the independent DOFs and returns mass-normalised
shapes on all nodes (``Phi^T M Phi = I``).

This module belongs to the virtual lab and deliberately shares no code with
the toolkit packages (``ema``, ``fem_import``, ``receptance``): the data that
tests the toolkit is never produced by the code under test.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace
from typing import Iterable

import numpy as np
import scipy.linalg
import scipy.sparse as sp

from .beam import BeamSection, beam_matrices
from .shell import shell_quad_matrices

__all__ = [
    "Material",
    "Beam",
    "Shell",
    "PointMass",
    "Spring",
    "RigidLink",
    "SkinQuad",
    "FEModel",
    "SystemMatrices",
    "Modes",
    "assemble",
    "solve_modes",
    "rigid_body_vectors",
]

log = logging.getLogger(__name__)

DOF_NAMES = ("ux", "uy", "uz", "rx", "ry", "rz")


@dataclass(frozen=True)
class Material:
    """Linear elastic isotropic material (SI units)."""

    name: str
    E: float
    nu: float
    rho: float

    @property
    def G(self) -> float:
        return self.E / (2 * (1 + self.nu))

    def scaled(self, *, E: float = 1.0, rho: float = 1.0) -> "Material":
        """Copy with Young's modulus and density multiplied by the given factors."""
        return replace(self, E=self.E * E, rho=self.rho * rho)


@dataclass(frozen=True)
class Beam:
    nodes: tuple[int, int]
    section: BeamSection
    material: Material
    e2_hint: tuple[float, float, float]
    group: str


@dataclass(frozen=True)
class Shell:
    nodes: tuple[int, int, int, int]
    thickness: float
    material: Material
    group: str


@dataclass(frozen=True)
class PointMass:
    """Rigid-body mass and inertia tensor (about the node, global axes)."""

    node: int
    mass: float
    inertia: tuple[tuple[float, float, float], ...]
    group: str


@dataclass(frozen=True)
class Spring:
    """Diagonal spring/damper between two nodes, or to ground when ``node_b`` is None.

    ``stiffness`` and ``damping`` hold 6 values each along the global DOFs
    (N/m, N m/rad; N s/m, N m s/rad).
    """

    node_a: int
    node_b: int | None
    stiffness: tuple[float, ...]
    damping: tuple[float, ...]
    group: str


@dataclass(frozen=True)
class RigidLink:
    """Slave nodes follow the master rigidly: u_s = u_m + theta_m x (x_s - x_m), theta_s = theta_m."""

    master: int
    slaves: tuple[int, ...]
    group: str


@dataclass(frozen=True)
class SkinQuad:
    """Display-only quadrilateral (no stiffness, no mass); its nodes must be rigidly linked."""

    nodes: tuple[int, int, int, int]
    group: str


@dataclass(frozen=True)
class FEModel:
    """Nodes, elements and constraints of a finite-element model.

    Attributes
    ----------
    node_ids : ndarray of int, shape (n,)
    xyz : ndarray, shape (n, 3)
        Node coordinates [m] (x along the track, y along the axle, z up).
    node_groups : tuple of str
        Body each node belongs to (``axle``, ``wheel_L``, ``axlebox_R``, ...).
    elements : tuple
        Beams, shells, point masses and springs.
    links : tuple of RigidLink
    skins : tuple of SkinQuad
    name : str
    """

    node_ids: np.ndarray
    xyz: np.ndarray
    node_groups: tuple[str, ...]
    elements: tuple
    links: tuple[RigidLink, ...]
    skins: tuple[SkinQuad, ...]
    name: str = "model"
    _index: dict = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        ids = np.asarray(self.node_ids, dtype=np.int64)
        if ids.ndim != 1 or len(np.unique(ids)) != len(ids):
            raise ValueError(f"FEModel.node_ids must be unique, got {len(ids)} ids with duplicates")
        if np.shape(self.xyz) != (len(ids), 3):
            raise ValueError(f"FEModel.xyz must have shape ({len(ids)}, 3), got {np.shape(self.xyz)}")
        if len(self.node_groups) != len(ids):
            raise ValueError("FEModel.node_groups must name a group for every node")
        object.__setattr__(self, "node_ids", ids)
        object.__setattr__(self, "xyz", np.asarray(self.xyz, dtype=float))
        object.__setattr__(self, "_index", {int(n): i for i, n in enumerate(ids)})

    @property
    def n_nodes(self) -> int:
        return len(self.node_ids)

    def index(self, node: int) -> int:
        try:
            return self._index[int(node)]
        except KeyError:
            raise KeyError(f"node {node} is not in model {self.name!r}") from None

    def coords(self, node: int) -> np.ndarray:
        return self.xyz[self.index(node)]

    def dofs(self, node: int) -> np.ndarray:
        return 6 * self.index(node) + np.arange(6)

    def nodes_of(self, group: str) -> np.ndarray:
        return self.node_ids[[g == group for g in self.node_groups]]

    def with_changes(
        self,
        *,
        add_elements: Iterable = (),
        remove_groups: Iterable[str] = (),
        links: tuple[RigidLink, ...] | None = None,
        name: str | None = None,
    ) -> "FEModel":
        """New model with elements added, element groups removed and/or links replaced."""
        drop = set(remove_groups)
        elements = tuple(e for e in self.elements if e.group not in drop) + tuple(add_elements)
        return replace(
            self,
            elements=elements,
            links=self.links if links is None else links,
            name=self.name if name is None else name,
            _index=None,
        )

    def element_mass(self) -> dict[str, float]:
        """Translational mass per element group [kg] (beams, shells, point masses)."""
        out: dict[str, float] = {}
        for e in self.elements:
            if isinstance(e, Beam):
                L = np.linalg.norm(self.coords(e.nodes[1]) - self.coords(e.nodes[0]))
                m = e.material.rho * e.section.area * L
            elif isinstance(e, Shell):
                p = np.array([self.coords(n) for n in e.nodes])
                area = 0.5 * np.linalg.norm(np.cross(p[2] - p[0], p[3] - p[1]))
                m = e.material.rho * e.thickness * area
            elif isinstance(e, PointMass):
                m = e.mass
            else:
                continue
            out[e.group] = out.get(e.group, 0.0) + m
        return out


@dataclass(frozen=True)
class SystemMatrices:
    """Assembled global matrices on all DOFs and the constraint transformation.

    ``stiffness`` maps ``"group/part"`` (e.g. ``"axle/torsion"``,
    ``"wheel_L/shell"``, ``"bearing_L/spring"``) to a sparse matrix; their sum
    is the global stiffness. ``mass`` maps groups to sparse mass matrices.
    ``transform`` (n_full x n_indep) maps independent DOFs to all DOFs;
    ``independent`` lists the full-DOF index of each independent DOF.
    """

    stiffness: dict[str, sp.csr_matrix]
    mass: dict[str, sp.csr_matrix]
    damping: sp.csr_matrix
    transform: sp.csr_matrix
    independent: np.ndarray
    grounded: bool

    @property
    def K(self) -> sp.csr_matrix:
        return sum(self.stiffness.values())

    @property
    def M(self) -> sp.csr_matrix:
        return sum(self.mass.values())


@dataclass(frozen=True)
class Modes:
    """Undamped normal modes, mass-normalised, on all nodes.

    Attributes
    ----------
    freqs_hz : ndarray (m,)
    shapes : ndarray (m, n_nodes, 6)
        Modal displacements/rotations per node DOF, ``Phi^T M Phi = I``.
    reduced : ndarray (n_indep, m)
        The same shapes on the independent DOFs (for energies and checks).
    """

    freqs_hz: np.ndarray
    shapes: np.ndarray
    reduced: np.ndarray

    @property
    def full(self) -> np.ndarray:
        """Shapes as (n_full_dof, m) columns."""
        m = len(self.freqs_hz)
        return self.shapes.reshape(m, -1).T


def _spring_block(k: np.ndarray) -> np.ndarray:
    d = np.diag(k)
    return np.block([[d, -d], [-d, d]])


def _constraint_transform(model: FEModel) -> tuple[sp.csr_matrix, np.ndarray]:
    n_dof = 6 * model.n_nodes
    slave_rows: dict[int, dict[int, float]] = {}
    for link in model.links:
        m_idx = model.dofs(link.master)
        xm = model.coords(link.master)
        for s in link.slaves:
            if s == link.master:
                raise ValueError(f"rigid link {link.group!r}: node {s} is both master and slave")
            r = model.coords(s) - xm
            s_idx = model.dofs(s)
            if s_idx[0] in slave_rows:
                raise ValueError(f"node {s} is a slave of more than one rigid link (second: {link.group!r})")
            ux, uy, uz, rx, ry, rz = m_idx
            slave_rows[s_idx[0]] = {ux: 1.0, ry: r[2], rz: -r[1]}
            slave_rows[s_idx[1]] = {uy: 1.0, rz: r[0], rx: -r[2]}
            slave_rows[s_idx[2]] = {uz: 1.0, rx: r[1], ry: -r[0]}
            for k in range(3, 6):
                slave_rows[s_idx[k]] = {m_idx[k]: 1.0}

    resolved: dict[int, dict[int, float]] = {}

    def resolve(dof: int, depth: int = 0) -> dict[int, float]:
        if dof not in slave_rows:
            return {dof: 1.0}
        if dof in resolved:
            return resolved[dof]
        if depth > 50:
            raise ValueError(f"rigid links form a cycle through DOF {dof}")
        out: dict[int, float] = {}
        for master, c in slave_rows[dof].items():
            if c == 0.0:
                continue
            for d, cc in resolve(master, depth + 1).items():
                out[d] = out.get(d, 0.0) + c * cc
        resolved[dof] = out
        return out

    independent = [d for d in range(n_dof) if d not in slave_rows]
    col = {d: j for j, d in enumerate(independent)}
    rows, cols, vals = [], [], []
    for d in range(n_dof):
        for master, c in resolve(d).items():
            rows.append(d)
            cols.append(col[master])
            vals.append(c)
    return sp.csr_matrix((vals, (rows, cols)), shape=(n_dof, len(independent))), np.array(independent)


def assemble(model: FEModel) -> SystemMatrices:
    """Assemble stiffness (per group and part), mass (per group) and damping.

    Parameters
    ----------
    model : FEModel

    Returns
    -------
    SystemMatrices
    """
    n_dof = 6 * model.n_nodes
    k_parts: dict[str, list] = {}
    m_parts: dict[str, list] = {}
    c_coo: list = []
    grounded = False

    def add(store: dict, key: str, dofs: np.ndarray, block: np.ndarray) -> None:
        r, c = np.meshgrid(dofs, dofs, indexing="ij")
        store.setdefault(key, []).append((r.ravel(), c.ravel(), block.ravel()))

    for e in model.elements:
        if isinstance(e, Beam):
            x1, x2 = model.coords(e.nodes[0]), model.coords(e.nodes[1])
            kd, me = beam_matrices(x1, x2, e.section, e.material.E, e.material.G, e.material.rho, np.array(e.e2_hint))
            dofs = np.concatenate([model.dofs(n) for n in e.nodes])
            for part, kp in kd.items():
                add(k_parts, f"{e.group}/{part}", dofs, kp)
            add(m_parts, e.group, dofs, me)
        elif isinstance(e, Shell):
            xyz = np.array([model.coords(n) for n in e.nodes])
            ke, me = shell_quad_matrices(xyz, e.thickness, e.material.E, e.material.nu, e.material.rho)
            dofs = np.concatenate([model.dofs(n) for n in e.nodes])
            add(k_parts, f"{e.group}/shell", dofs, ke)
            add(m_parts, e.group, dofs, me)
        elif isinstance(e, PointMass):
            block = np.zeros((6, 6))
            block[:3, :3] = np.eye(3) * e.mass
            block[3:, 3:] = np.asarray(e.inertia, float)
            add(m_parts, e.group, model.dofs(e.node), block)
        elif isinstance(e, Spring):
            k = np.asarray(e.stiffness, float)
            c = np.asarray(e.damping, float)
            if e.node_b is None:
                grounded = grounded or bool(np.any(k > 0))
                dofs = model.dofs(e.node_a)
                add(k_parts, f"{e.group}/spring", dofs, np.diag(k))
                r, cc = np.meshgrid(dofs, dofs, indexing="ij")
                c_coo.append((r.ravel(), cc.ravel(), np.diag(c).ravel()))
            else:
                dofs = np.concatenate([model.dofs(e.node_a), model.dofs(e.node_b)])
                add(k_parts, f"{e.group}/spring", dofs, _spring_block(k))
                r, cc = np.meshgrid(dofs, dofs, indexing="ij")
                c_coo.append((r.ravel(), cc.ravel(), _spring_block(c).ravel()))
        else:
            raise TypeError(f"unknown element type {type(e).__name__} in model {model.name!r}")

    def build(store: dict) -> dict[str, sp.csr_matrix]:
        out = {}
        for key, chunks in store.items():
            r = np.concatenate([c[0] for c in chunks])
            c = np.concatenate([c[1] for c in chunks])
            v = np.concatenate([c[2] for c in chunks])
            out[key] = sp.csr_matrix((v, (r, c)), shape=(n_dof, n_dof))
        return out

    if c_coo:
        r = np.concatenate([c[0] for c in c_coo])
        cc = np.concatenate([c[1] for c in c_coo])
        v = np.concatenate([c[2] for c in c_coo])
        damping = sp.csr_matrix((v, (r, cc)), shape=(n_dof, n_dof))
    else:
        damping = sp.csr_matrix((n_dof, n_dof))
    T, independent = _constraint_transform(model)
    return SystemMatrices(build(k_parts), build(m_parts), damping, T, independent, grounded)


def rigid_body_vectors(model: FEModel, centre: np.ndarray) -> np.ndarray:
    """Six rigid-body motions on all DOFs: translations x, y, z and rotations about x, y, z through ``centre``.

    Returns
    -------
    ndarray, shape (6 * n_nodes, 6)
    """
    n = model.n_nodes
    R = np.zeros((n, 6, 6))
    r = model.xyz - np.asarray(centre, float)
    for k in range(3):
        R[:, k, k] = 1.0
        axis = np.zeros(3)
        axis[k] = 1.0
        R[:, :3, 3 + k] = np.cross(axis, r)
        R[:, 3 + k, 3 + k] = 1.0
    return R.reshape(6 * n, 6)


def _reduce(system: SystemMatrices, matrix: sp.csr_matrix) -> np.ndarray:
    T = system.transform
    return (T.T @ matrix @ T).toarray()


def solve_modes(model: FEModel, system: SystemMatrices, f_max_hz: float, *, rigid_tol_hz: float = 0.05) -> Modes:
    """Undamped normal modes up to ``f_max_hz``, mass-normalised.

    For a model with no spring to ground, the zero-frequency subspace is
    replaced by the physical rigid-body motions (translations and rotations
    about the centre of mass, mass-orthonormalised by Löwdin's symmetric
    orthogonalisation), which span the same subspace but have a meaning a
    user can read; any further zero-frequency mechanisms (e.g. an axlebox
    free to spin on its bearing) are kept as the solver returns them,
    made mass-orthogonal to the rigid-body motions.

    Parameters
    ----------
    model : FEModel
    system : SystemMatrices
        From :func:`assemble` on the same model.
    f_max_hz : float
        Highest frequency kept.
    rigid_tol_hz : float
        Modes below this frequency count as zero-frequency mechanisms.

    Returns
    -------
    Modes
    """
    K = _reduce(system, system.K)
    M = _reduce(system, system.M)
    K = 0.5 * (K + K.T)
    M = 0.5 * (M + M.T)
    # a positive shift makes K + sigma M definite for a free structure, so the
    # rigid-body eigenvalues come out as clean small numbers around zero
    sigma = (2 * np.pi * 1.0) ** 2
    w2_max = (2 * np.pi * f_max_hz) ** 2
    vals, vecs = scipy.linalg.eigh(K + sigma * M, M, subset_by_value=(-np.inf, w2_max + sigma), driver="gvx")
    w2 = vals - sigma
    freqs = np.sqrt(np.clip(w2, 0.0, None)) / (2 * np.pi)

    if not system.grounded:
        zero = freqs < rigid_tol_hz
        n_zero = int(zero.sum())
        if n_zero < 6:
            raise RuntimeError(
                f"model {model.name!r} has no ground springs but only {n_zero} zero-frequency modes "
                f"(< {rigid_tol_hz} Hz); expected at least 6 rigid-body modes"
            )
        m_full = system.M
        R0 = rigid_body_vectors(model, np.zeros(3))
        mass = float(R0[:, 0] @ (m_full @ R0[:, 0]))
        centre = _centre_of_mass(model, m_full, mass)
        R_full = rigid_body_vectors(model, centre)
        # rigid motions satisfy the rigid links, so their independent entries define them
        R = R_full[system.independent]
        gram = R.T @ M @ R
        ev, evec = np.linalg.eigh(gram)
        R = R @ (evec @ np.diag(ev**-0.5) @ evec.T)
        Z = vecs[:, zero]
        extra = Z - R @ (R.T @ M @ Z)
        g = extra.T @ M @ extra
        ev2, evec2 = np.linalg.eigh(g)
        # Z is mass-normalised: a genuine extra mechanism keeps a Gram eigenvalue near 1
        keep = ev2 > 1e-6
        extra = extra @ evec2[:, keep] @ np.diag(ev2[keep] ** -0.5)
        vecs = np.hstack([R, extra, vecs[:, ~zero]])
        freqs = np.concatenate([np.zeros(R.shape[1] + extra.shape[1]), freqs[~zero]])
        log.debug("model %s: %d rigid-body + %d extra zero modes", model.name, R.shape[1], extra.shape[1])

    full = system.transform @ vecs
    shapes = full.T.reshape(len(freqs), model.n_nodes, 6)
    return Modes(freqs_hz=freqs, shapes=shapes, reduced=vecs)


def _centre_of_mass(model: FEModel, m_full: sp.csr_matrix, mass: float) -> np.ndarray:
    # a translation against a rotation about the origin gives a static moment
    R0 = rigid_body_vectors(model, np.zeros(3))
    MR = m_full @ R0
    sx = R0[:, 1] @ MR[:, 5]  # t_y . (rot_z about 0) = m * x_cg
    sy = R0[:, 2] @ MR[:, 3]  # t_z . (rot_x about 0) = m * y_cg
    sz = R0[:, 0] @ MR[:, 4]  # t_x . (rot_y about 0) = m * z_cg
    return np.array([sx, sy, sz]) / mass
