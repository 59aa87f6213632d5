"""Independent FE oracle: wheelset receptances by a direct harmonic solve (no modes).

Test-support module (it imports the virtual lab, which the toolkit must not).
The toolkit's hybrid modal model builds wheelset receptances from a truncated
set of mass-normalised FE modes and adds the primary suspension (thesis
Table 2.1) as a structural modification in modal coordinates. This module
gives the reference those results are compared with: the full design FE
model of the lab (``lab_data.wheelset.build_wheelset(WheelsetParameters())``)
solved directly at each frequency,

    (K + i Ω C - Ω² M) q = T^T L^T f,        u = L T q,

on the constraint-reduced (independent) DOFs ``q`` (``u_full = T q`` resolves
the rigid links), with no modal truncation at all. ``L`` maps the 6 DOFs of a
point's FE node to the point's displacement along a global axis through the
rigid-attachment kinematics ``u_p = u_n + θ_n × (p - x_n)`` — the same
transformation the FE export's 6-DOF shapes are evaluated with
(``lab_data.sensors.shape_matrix``). Force and displacement use the same
vector, so the result is reciprocal by construction of the physics, not by
symmetrisation.

Damping ``C``:

* in service (``in_service=True``): the primary-suspension dampers from each
  axlebox centre node to ground (``lab_data.wheelset.in_service``; Table 2.1,
  one damper per axlebox, c = (85, 50, 11) kN s/m along x, y, z). The
  springs, 2 × (4.15, 2.1, 0.5) MN/m per axlebox, are in ``K``.
* ``structural_zeta > 0`` adds stiffness-proportional damping
  ``β K_struct`` on the wheelset's own (elastic) stiffness, suspension springs
  excluded, with ``β = 2 ζ / (2π f_ref)``. A free-free mode of frequency
  ``f_r`` then has the modal damping ratio ``ζ f_r / f_ref`` exactly (the
  free-free undamped modes diagonalise ``K_struct``), i.e. ``ζ`` at the
  reference frequency ``structural_zeta_ref_hz`` (default 100 Hz).

The main use is ``structural_zeta = 0``: only the suspension dampers, which
the hybrid model reproduces with zero modal damping.

Singularity: the free-free model has six rigid-body modes and the in-service
model keeps one zero-frequency mechanism — spin about the axle (the springs
act on the axlebox centres, which lie on the axle axis, and the design model
ties the axleboxes rigidly to the journals). Both are therefore singular at
0 Hz only; frequencies must be > 0.

The reduced design model has 1890 independent DOFs (1129 nodes × 6 = 6774
full DOFs, the rest slaved by rigid links); one sparse LU (``splu``) per
frequency.
"""

from __future__ import annotations

import functools
import logging
import re
import time
from dataclasses import dataclass
from os import PathLike
from pathlib import Path
from typing import Mapping, NamedTuple, Sequence

import numpy as np
import pandas as pd
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from lab_data.fe_model import SystemMatrices, assemble, rigid_body_vectors
from lab_data.wheelset import SuspensionParameters, WheelsetParameters, build_wheelset, in_service as add_suspension

__all__ = [
    "OracleInputError",
    "THESIS_DOFS",
    "ReducedSystem",
    "InServiceModes",
    "reduced_system",
    "read_points",
    "point_matrix",
    "fe_receptance",
    "fe_eigenfrequencies_in_service",
    "rigid_body_mass_matrix",
]

log = logging.getLogger(__name__)

#: thesis Fig. 2.5 numbering of the wheelset DOFs
THESIS_DOFS: dict[int, str] = {
    1: "contact_L:x", 2: "contact_L:y", 3: "contact_L:z",
    4: "axlebox_L:x", 5: "axlebox_L:y", 6: "axlebox_L:z",
    7: "contact_R:x", 8: "contact_R:y", 9: "contact_R:z",
    10: "axlebox_R:x", 11: "axlebox_R:y", 12: "axlebox_R:z",
}
_AXES = {"x": 0, "y": 1, "z": 2}
_LABEL = re.compile(r"^(?P<point>[^:]+):(?P<axis>[xyz])$")
_STRUCTURE_PREFIX = "primary_"  # element groups of the suspension (lab_data.wheelset.in_service)


class OracleInputError(ValueError):
    """Bad input to the oracle; the message names the parameter, what was expected and what was received."""


@dataclass(frozen=True)
class ReducedSystem:
    """Constraint-reduced matrices of the design wheelset (free-free or in service).

    Attributes
    ----------
    model : lab_data.fe_model.FEModel
    system : lab_data.fe_model.SystemMatrices
        Full-DOF assembly (``transform`` maps independent to all DOFs).
    K_struct, K_susp, M, C_susp : scipy.sparse.csc_matrix
        Reduced wheelset stiffness, suspension stiffness, mass and suspension
        damping, shape ``(n_indep, n_indep)``.
    """

    model: object
    system: SystemMatrices
    K_struct: sp.csc_matrix
    K_susp: sp.csc_matrix
    M: sp.csc_matrix
    C_susp: sp.csc_matrix

    @property
    def n_dof(self) -> int:
        return self.M.shape[0]


@functools.lru_cache(maxsize=8)
def reduced_system(
    in_service: bool,
    params: WheelsetParameters = WheelsetParameters(),
    suspension: SuspensionParameters = SuspensionParameters(),
) -> ReducedSystem:
    """Assemble and constraint-reduce the design wheelset (cached per argument set).

    Parameters
    ----------
    in_service : bool
        Add the primary suspension (springs and dampers to ground at both axlebox centres).
    params : WheelsetParameters
    suspension : SuspensionParameters
        Used only when ``in_service``.

    Returns
    -------
    ReducedSystem
    """
    model = build_wheelset(params, name="design wheelset")
    if in_service:
        model = add_suspension(model, suspension)
    system = assemble(model)
    T = system.transform.tocsc()

    def red(A) -> sp.csc_matrix:
        R = (T.T @ A @ T).tocsc()
        return (0.5 * (R + R.T)).tocsc()  # remove round-off asymmetry of the triple product only

    n_full = T.shape[0]
    k_struct = sp.csr_matrix((n_full, n_full))
    k_susp = sp.csr_matrix((n_full, n_full))
    for key, k in system.stiffness.items():
        if key.startswith(_STRUCTURE_PREFIX):
            k_susp = k_susp + k
        else:
            k_struct = k_struct + k
    return ReducedSystem(model, system, red(k_struct), red(k_susp), red(system.M), red(system.damping))


def read_points(points) -> dict[str, tuple[int, np.ndarray]]:
    """Normalise a points specification to ``{name: (fe_node, xyz)}``.

    Parameters
    ----------
    points : mapping, path or DataFrame
        ``{name: (fe_node, (x, y, z))}``, or a ``points.csv`` path / table with
        columns ``name, fe_node, x, y, z``.

    Returns
    -------
    dict
    """
    if isinstance(points, (str, PathLike)):
        path = Path(points)
        if not path.is_file():
            raise OracleInputError(f"points file {str(path)!r} does not exist (expected a points.csv)")
        table = pd.read_csv(path)
        where = f"points file {str(path)!r}"
    elif isinstance(points, pd.DataFrame):
        table, where = points, "points table"
    elif isinstance(points, Mapping):
        out = {}
        for name, spec in points.items():
            try:
                node, xyz = spec
                xyz = np.asarray(xyz, float).reshape(3)
                node = int(node)
            except (TypeError, ValueError):
                raise OracleInputError(
                    f"points[{name!r}] must be (fe_node, (x, y, z)), got {spec!r}"
                ) from None
            if not np.all(np.isfinite(xyz)):
                raise OracleInputError(f"points[{name!r}]: coordinates must be finite, got {xyz.tolist()}")
            out[str(name)] = (node, xyz)
        return out
    else:
        raise OracleInputError(
            f"points must be a dict name -> (fe_node, xyz), a points.csv path or a DataFrame; got {type(points).__name__}"
        )
    missing = {"name", "fe_node", "x", "y", "z"} - set(table.columns)
    if missing:
        raise OracleInputError(f"{where} lacks columns {sorted(missing)}; expected name, fe_node, x, y, z")
    return {
        str(r["name"]): (int(r["fe_node"]), np.array([r["x"], r["y"], r["z"]], float)) for _, r in table.iterrows()
    }


def _parse_dof(label, points: Mapping) -> tuple[str, str, int]:
    text = THESIS_DOFS.get(label) if isinstance(label, (int, np.integer)) and not isinstance(label, bool) else label
    if text is None:
        raise OracleInputError(f"DOF number {label} is not a thesis DOF; expected 1-12 (Fig. 2.5)")
    m = _LABEL.match(str(text))
    if m is None:
        raise OracleInputError(f"DOF label {label!r} is not of the form 'point:x|y|z' (e.g. 'axlebox_L:z')")
    if m["point"] not in points:
        raise OracleInputError(f"DOF {label!r}: unknown point {m['point']!r}; known points: {sorted(points)}")
    return str(text), m["point"], _AXES[m["axis"]]


def point_matrix(model, points, dofs: Sequence) -> sp.csr_matrix:
    """Rows mapping all FE DOFs to point displacements along global axes.

    Row ``j`` gives ``e_k · (u_n + θ_n × (p - x_n)) = e_k · u_n + ((p - x_n) × e_k) · θ_n``
    for DOF ``j`` = (point attached to node ``n`` at ``p``, axis ``e_k``).

    Parameters
    ----------
    model : lab_data.fe_model.FEModel
    points : see :func:`read_points`
    dofs : sequence of str or int
        ``"point:x|y|z"`` labels or thesis DOF numbers 1–12.

    Returns
    -------
    scipy.sparse.csr_matrix, shape (n_dof, 6 * n_nodes)
    """
    pts = read_points(points)
    if len(dofs) == 0:
        raise OracleInputError("dofs is empty; give at least one 'point:x|y|z' label")
    rows, cols, vals = [], [], []
    seen = set()
    for j, label in enumerate(dofs):
        text, name, axis = _parse_dof(label, pts)
        if text in seen:
            raise OracleInputError(f"DOF {text!r} appears twice in dofs")
        seen.add(text)
        node, xyz = pts[name]
        try:
            idx = model.dofs(node)
        except KeyError:
            raise OracleInputError(f"point {name!r}: FE node {node} is not in the design wheelset model") from None
        e = np.zeros(3)
        e[axis] = 1.0
        r = xyz - model.coords(node)
        coeff = np.concatenate([e, np.cross(r, e)])
        for d, c in zip(idx, coeff):
            if c != 0.0:
                rows.append(j)
                cols.append(d)
                vals.append(c)
    return sp.csr_matrix((vals, (rows, cols)), shape=(len(dofs), 6 * model.n_nodes))


def _check_freqs(freqs_hz) -> np.ndarray:
    f = np.atleast_1d(np.asarray(freqs_hz, float))
    if f.ndim != 1 or f.size == 0:
        raise OracleInputError(f"freqs_hz must be a non-empty 1-D array [Hz], got shape {np.shape(freqs_hz)}")
    bad = f[~np.isfinite(f) | (f <= 0)]
    if bad.size:
        raise OracleInputError(
            f"freqs_hz must be finite and > 0 Hz (the free-free model and the in-service model's spin about "
            f"the axle are singular at 0 Hz); got {bad[:5].tolist()}"
        )
    return f


def fe_receptance(
    points,
    dofs: Sequence,
    freqs_hz,
    *,
    in_service: bool,
    structural_zeta: float = 0.0,
    structural_zeta_ref_hz: float = 100.0,
    params: WheelsetParameters = WheelsetParameters(),
    suspension: SuspensionParameters = SuspensionParameters(),
) -> np.ndarray:
    """Receptance matrix of the full design FE wheelset by a direct sparse harmonic solve.

    ``H[i, j, k]`` is the displacement at DOF ``i`` per unit force at DOF
    ``j`` [m/N] at ``freqs_hz[k]``: the wheelset receptances ``A_ij`` of the
    thesis (eqs. 2.17, 2.21; DOFs numbered as in Fig. 2.5), from eq. 2.28
    written in physical coordinates (``[Φ] = I``), i.e. without modal
    truncation.

    Parameters
    ----------
    points : mapping, path or DataFrame
        ``{name: (fe_node, (x, y, z))}`` or the campaign's ``points.csv``.
    dofs : sequence of str or int
        Output = input DOFs, ``"point:x|y|z"`` or thesis numbers 1–12.
    freqs_hz : array_like
        Frequencies [Hz], all > 0.
    in_service : bool
        False: free-free wheelset. True: on the primary suspension (springs
        and dampers to ground at both axlebox centres, Table 2.1).
    structural_zeta : float
        Stiffness-proportional damping ``β K_struct``, ``β = 2 ζ / (2π f_ref)``
        (damping ratio ``ζ f / f_ref`` of a free-free mode at ``f``). 0: none.
    structural_zeta_ref_hz : float
        Reference frequency ``f_ref`` [Hz] at which the damping ratio equals
        ``structural_zeta``.
    params, suspension :
        Model parameters (defaults: the design wheelset and Table 2.1).

    Returns
    -------
    ndarray, complex, shape (n_dof, n_dof, n_freq)
    """
    f = _check_freqs(freqs_hz)
    if not (np.isfinite(structural_zeta) and structural_zeta >= 0):
        raise OracleInputError(f"structural_zeta must be finite and >= 0, got {structural_zeta!r}")
    if not (np.isfinite(structural_zeta_ref_hz) and structural_zeta_ref_hz > 0):
        raise OracleInputError(f"structural_zeta_ref_hz must be > 0 Hz, got {structural_zeta_ref_hz!r}")
    t0 = time.perf_counter()
    rs = reduced_system(bool(in_service), params, suspension)
    L = (point_matrix(rs.model, points, dofs) @ rs.system.transform).tocsr()  # (n_dof, n_indep)
    Lt = L.T.toarray().astype(complex)
    K = (rs.K_struct + rs.K_susp).tocsc()
    C = rs.C_susp
    if structural_zeta > 0:
        C = (C + (2 * structural_zeta / (2 * np.pi * structural_zeta_ref_hz)) * rs.K_struct).tocsc()
    M = rs.M
    kdiag, cdiag, mdiag = np.abs(K.diagonal()), np.abs(C.diagonal()), M.diagonal()
    t_setup = time.perf_counter() - t0
    H = np.empty((L.shape[0], L.shape[0], f.size), complex)
    for k, fk in enumerate(f):
        w = 2 * np.pi * fk
        # symmetric diagonal scaling D Z D (translations ~1e12 N/m vs rotations): keeps Z symmetric,
        # cuts pivoting, fill-in and the reciprocity error of the LU at low frequency
        d = 1.0 / np.sqrt(kdiag + w * cdiag + w * w * mdiag)
        D = sp.diags(d)
        Z = (D @ (K + (1j * w) * C - (w * w) * M) @ D).tocsc()
        lu = spla.splu(Z, permc_spec="MMD_ATA")
        # one right-hand side at a time: SuperLU's multi-RHS solve goes through threaded BLAS and is
        # 10-100x slower than this loop when the cores are shared
        B = d[:, None] * Lt
        X = d[:, None] * np.column_stack([lu.solve(B[:, j]) for j in range(B.shape[1])])
        H[:, :, k] = L @ X
    log.debug(
        "fe_receptance: %d independent DOFs, %d outputs, %d frequencies, setup %.2f s, %.1f ms per frequency",
        rs.n_dof, L.shape[0], f.size, t_setup, 1e3 * (time.perf_counter() - t0 - t_setup) / f.size,
    )
    return H


def rigid_body_mass_matrix(
    params: WheelsetParameters = WheelsetParameters(),
) -> tuple[float, np.ndarray, np.ndarray]:
    """Total mass, centre of mass and inertia tensor about it, from the FE mass matrix.

    Returns
    -------
    mass : float
    centre : ndarray (3,)
    inertia : ndarray (3, 3)
        About the centre of mass, global axes.
    """
    rs = reduced_system(False, params)
    model, M = rs.model, rs.system.M
    R0 = rigid_body_vectors(model, np.zeros(3))
    G0 = R0.T @ (M @ R0)
    mass = G0[0, 0]
    # static moments: translation y . rotation z about 0 = m x_c, etc.
    centre = np.array([G0[1, 5], G0[2, 3], G0[0, 4]]) / mass
    R = rigid_body_vectors(model, centre)
    G = R.T @ (M @ R)
    return float(mass), centre, G[3:, 3:]


class InServiceModes(NamedTuple):
    """Lowest undamped in-service modes of the full FE wheelset.

    ``freqs_hz`` [Hz]; ``labels``: ``spin`` (rotation about the axle, y),
    ``bounce`` (z), ``roll`` (about x), ``lateral`` (y), ``longitudinal`` (x),
    ``yaw`` (about z) when one rigid-body motion about the centre of mass
    holds more than half of the mode's kinetic energy, else ``elastic``;
    ``rigid_share``: that fraction (0–1).
    """

    freqs_hz: np.ndarray
    labels: tuple[str, ...]
    rigid_share: np.ndarray


_RIGID_NAMES = ("longitudinal", "lateral", "bounce", "roll", "spin", "yaw")


def fe_eigenfrequencies_in_service(
    n: int = 10,
    *,
    params: WheelsetParameters = WheelsetParameters(),
    suspension: SuspensionParameters = SuspensionParameters(),
) -> InServiceModes:
    """Lowest ``n`` undamped eigenfrequencies of the design wheelset on its primary suspension.

    Sparse generalized symmetric eigenproblem ``K φ = ω² M φ`` on the reduced
    DOFs, Lanczos in shift-invert mode about ``-(2π · 1 Hz)²`` (``K`` itself is
    singular: spin about the axle); frequencies below ~1e-4 Hz are the spin
    mechanism's numerical zero. Each mode is labelled by its rigid-body
    content: the mass-weighted projection onto the six rigid motions about the
    centre of mass (mass-orthonormalised), the largest component naming it.

    Parameters
    ----------
    n : int
    params, suspension :
        Model parameters (defaults: design wheelset, Table 2.1 suspension).

    Returns
    -------
    InServiceModes
    """
    if not (isinstance(n, (int, np.integer)) and 1 <= n <= 200):
        raise OracleInputError(f"n must be an integer in 1..200, got {n!r}")
    rs = reduced_system(True, params, suspension)
    K = (rs.K_struct + rs.K_susp).tocsc()
    M = rs.M.tocsc()
    sigma = (2 * np.pi) ** 2
    # shift-invert about -sigma: the eigenvalues nearest to it are the lowest ones, spin included
    vals, vecs = spla.eigsh(K, k=n, M=M, sigma=-sigma, which="LM")
    order = np.argsort(vals)
    vals, vecs = vals[order], vecs[:, order]
    vecs = vecs / np.sqrt(np.einsum("ij,ij->j", vecs, M @ vecs))
    freqs = np.sqrt(np.clip(vals, 0.0, None)) / (2 * np.pi)
    _, centre, _ = rigid_body_mass_matrix(params)
    R = rigid_body_vectors(rs.model, centre)[rs.system.independent]
    G = R.T @ M @ R
    # mass-orthonormalise each rigid motion on its own (about the centre of mass G is nearly diagonal)
    R = R / np.sqrt(np.diag(G))
    P = R.T @ (M @ vecs)  # (6, n) projections of mass-normalised modes
    share = P**2
    labels = []
    for i in range(n):
        j = int(np.argmax(share[:, i]))
        labels.append(_RIGID_NAMES[j] if share[j, i] > 0.5 else "elastic")
    return InServiceModes(freqs, tuple(labels), share.max(axis=0))
