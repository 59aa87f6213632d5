"""Physical checks of imported FE modes: model size, point offsets, rigid-body mass, duplicate and absurd modes.

The tolerances scale with the model, not with any particular mesh:

* **Model size** ``D``: the diagonal of the nodes' bounding box. A point
  (sensor, contact point) is rigidly attached to its FE node by a link of
  length ``|p - x_node|``; a link longer than ``POINT_OFFSET_FRACTION * D``
  (a quarter of the structure) is not a rigid attachment but a wrong node or
  a wrong unit. When scaling the point by 1e-3, 1e-2 or 0.0254 brings it
  within the tolerance of its node the message says "looks like mm / cm /
  inches".
* **Rigid-body mass.** For a free-free export the six rigid-body modes are
  rigid motions ``u_i = t + theta x (x_i - c)`` of the nodes, so
  ``Phi_rb = R Q`` with the rigid-body matrix ``R`` of the node coordinates;
  mass normalisation ``Phi_rb^T M Phi_rb = I`` gives the 6 x 6 rigid-body
  mass matrix ``R^T M R = (Q Q^T)^-1`` (thesis eq. 2.29 applied to the rigid
  modes): its translational diagonal is the total mass, three times. Shapes
  scaled by ``s`` give a mass ``1/s^2`` times too small; shapes whose modal
  masses differ give three different "total masses".
* **Mass matrix**: with one, ``Phi^T M Phi`` must be the identity.
* **Absurd values**: a mass-normalised translation ``|u|`` at a node means
  that node's mass is at most ``1/u^2`` (its kinetic energy cannot exceed the
  mode's); ``|u| > MAX_MASS_NORMALISED_TRANSLATION`` would need a node lighter
  than ``1e-8`` kg (ten micrograms) — a corrupt value, not a mode.
* **Duplicates**: two eigenvectors of one symmetric eigenproblem are
  ``M``-orthogonal, so two modes at the same frequency with parallel shapes
  (MAC ~ 1 over every DOF) are one mode written twice, not a degenerate pair.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from .errors import FEGeometryError, FEImportError, FEReadError, PointToleranceError

__all__ = ["POINT_OFFSET_FRACTION", "MAX_MASS_NORMALISED_TRANSLATION", "UNIT_SLIPS", "MassNormalisationError",
           "RigidBodyMass", "model_size", "unit_slip", "point_offset_limit", "check_point_offsets", "rigid_body_mass",
           "check_mass_normalisation", "check_mode_values"]

log = logging.getLogger("fem_import")

#: A point farther from its FE node than this fraction of the model size is refused.
POINT_OFFSET_FRACTION = 0.25
#: Largest credible mass-normalised translation [1/sqrt(kg)]: 1/u^2 = 1e-8 kg.
MAX_MASS_NORMALISED_TRANSLATION = 1e4
#: Unit slips tried when a point is far from its node: factor to metres and the unit's name.
UNIT_SLIPS = ((1e-3, "mm"), (1e-2, "cm"), (0.0254, "inches"), (1e3, "km"))


class MassNormalisationError(FEImportError):
    """Shapes that are not mass-normalised (rigid-body mass inconsistent, or against a mass or a mass matrix)."""


def model_size(fe) -> float:
    """Diagonal of the bounding box of the nodes with coordinates [m] (NaN when no node has coordinates)."""
    xyz = np.asarray(fe.xyz, float)
    ok = np.all(np.isfinite(xyz), axis=1)
    if not ok.any():
        return float("nan")
    return float(np.linalg.norm(xyz[ok].max(axis=0) - xyz[ok].min(axis=0)))


def point_offset_limit(fe) -> float:
    """Largest accepted point-to-node distance [m]: :data:`POINT_OFFSET_FRACTION` of :func:`model_size`."""
    return POINT_OFFSET_FRACTION * model_size(fe)


def unit_slip(position, node_xyz, tolerance: float) -> str:
    """``" (looks like mm: x 0.001 puts it 0.03 m from its node)"`` when a unit factor brings the point to its node."""
    p = np.asarray(position, float)
    x = np.asarray(node_xyz, float)
    best = None
    for factor, unit in UNIT_SLIPS:
        d = float(np.linalg.norm(p * factor - x))
        if d <= tolerance and (best is None or d < best[0]):
            best = (d, factor, unit)
    if best is None:
        return ""
    d, factor, unit = best
    return f" (looks like {unit}: x {factor:g} puts it {d:.3g} m from its node; positions must be in metres)"


def check_point_offsets(fe, nodes, positions, names, *, source: str = "", limit: float | None = None) -> None:
    """Refuse points farther from their FE node than :func:`point_offset_limit`.

    Parameters
    ----------
    fe : FEModes
        With node coordinates (without them nothing is checked).
    nodes : sequence of int
        FE node of each point (must be in ``fe``).
    positions : array_like (p, 3)
        Point positions [m].
    names : sequence of str
        Point or channel names, quoted in the message.
    source : str
        The table the points come from, quoted in the message.
    limit : float, optional
        Largest distance [m]; default :func:`point_offset_limit`.

    Raises
    ------
    PointToleranceError
        Names the point, its node, the distance, the limit (and the model
        size it comes from) and a likely unit slip.
    """
    limit = point_offset_limit(fe) if limit is None else float(limit)
    if not np.isfinite(limit) or limit <= 0:
        return
    pos = np.asarray(positions, float).reshape(-1, 3)
    where = f"{source}: " if source else ""
    for name, node, p in zip(names, nodes, pos):
        x = fe.xyz[fe.index(int(node))]
        if not np.all(np.isfinite(x)) or not np.all(np.isfinite(p)):
            continue
        d = float(np.linalg.norm(p - x))
        if d > limit:
            raise PointToleranceError(
                f"{where}{name}: position {np.round(p, 6).tolist()} m lies {d:.4g} m from its fe_node {int(node)} at "
                f"{np.round(x, 6).tolist()} m, more than {limit:.3g} m ({POINT_OFFSET_FRACTION:g} x the model size "
                f"{model_size(fe):.3g} m of {fe.source or 'the FE model'}){unit_slip(p, x, limit)}; a sensor is "
                f"rigidly attached to a nearby node: check the fe_node and the unit of x, y, z")


@dataclass(frozen=True)
class RigidBodyMass:
    """Mass properties implied by the rigid-body modes of mass-normalised shapes.

    Attributes
    ----------
    masses : ndarray (3,)
        Total mass seen by a translation along x, y, z [kg] (equal for mass-normalised shapes).
    mass : float
        Their mean [kg].
    centre : ndarray (3,)
        Centre of mass [m].
    inertia : ndarray (3, 3)
        Inertia tensor about the centre of mass [kg m^2].
    modes : tuple of int
        1-based numbers of the rigid-body modes used.
    rigidity : float
        Largest relative residual of fitting the rigid modes' translations by rigid motions (0 = rigid).
    """

    masses: np.ndarray
    mass: float
    centre: np.ndarray
    inertia: np.ndarray
    modes: tuple[int, ...]
    rigidity: float

    @property
    def spread(self) -> float:
        """Relative spread of the three translational masses (0 for consistent normalisation)."""
        return float((self.masses.max() - self.masses.min()) / self.mass) if self.mass > 0 else float("inf")


def _skew(r: np.ndarray) -> np.ndarray:
    """``[r x]`` for each row of r: (n, 3, 3)."""
    z = np.zeros(len(r))
    return np.stack([np.stack([z, -r[:, 2], r[:, 1]], -1), np.stack([r[:, 2], z, -r[:, 0]], -1),
                     np.stack([-r[:, 1], r[:, 0], z], -1)], 1)


def rigid_body_mass(fe, rigid_below_hz: float = 1.0) -> RigidBodyMass | None:
    """Mass, centre of mass and inertia implied by the rigid-body modes (None when they cannot tell).

    Needs node coordinates and exactly six modes below ``rigid_below_hz``
    (a free-free export); the translations are used (rotational DOFs of
    shell models can be unreliable), with the rotations too when the nodes
    lie on one line (a beam model, whose rotation about its axis shows only
    there).

    Returns
    -------
    RigidBodyMass or None
        None without coordinates, or with fewer or more than six rigid modes.
    """
    f = np.asarray(fe.freqs_hz, float)
    rigid = np.flatnonzero(f < rigid_below_hz)
    ok = np.all(np.isfinite(fe.xyz), axis=1)
    if rigid.size != 6 or ok.sum() < 3:
        return None
    xyz = fe.xyz[ok]
    c = xyz.mean(axis=0)
    r = xyz - c
    # u_i = t + theta x r_i = [I, -[r_i x]] [t; theta]
    R = np.concatenate([np.broadcast_to(np.eye(3), (len(r), 3, 3)), -_skew(r)], axis=2).reshape(-1, 6)
    Phi = fe.shapes[rigid][:, ok, :3].reshape(6, -1).T  # (3 n, 6)
    if np.linalg.matrix_rank(R) < 6:
        if fe.shapes.shape[2] < 6:
            return None
        # nodes on one line (a beam model): the rotation about it shows only in the rotational DOFs, theta_i = theta
        Rr = np.concatenate([np.zeros((len(r), 3, 3)), np.broadcast_to(np.eye(3), (len(r), 3, 3))], axis=2)
        R = np.concatenate([R.reshape(len(r), 3, 6), Rr], axis=1).reshape(-1, 6)
        Phi = fe.shapes[rigid][:, ok, :].reshape(6, -1).T  # (6 n, 6)
        if np.linalg.matrix_rank(R) < 6:
            return None
    Q, *_ = np.linalg.lstsq(R, Phi, rcond=None)
    resid = np.linalg.norm(R @ Q - Phi, axis=0) / np.maximum(np.linalg.norm(Phi, axis=0), 1e-300)
    try:
        M = np.linalg.inv(Q @ Q.T)
    except np.linalg.LinAlgError:
        return None
    M = 0.5 * (M + M.T)
    masses = np.diag(M)[:3].copy()
    m = float(masses.mean())
    # coupling block: m [r_c x] = M[3:, :3]  ->  r_c from its antisymmetric part
    S = M[3:, :3] / m if m > 0 else np.zeros((3, 3))
    rc = np.array([S[2, 1] - S[1, 2], S[0, 2] - S[2, 0], S[1, 0] - S[0, 1]]) / 2
    # M[3:, 3:] is the inertia about c; shift to the centre of mass (parallel axes)
    J = M[3:, 3:] - m * (np.dot(rc, rc) * np.eye(3) - np.outer(rc, rc))
    return RigidBodyMass(masses, m, c + rc, J, tuple(int(k) + 1 for k in rigid), float(resid.max()))


def check_mass_normalisation(fe, *, total_mass: float | None = None, mass_matrix=None, rtol: float = 0.05,
                             rigid_below_hz: float = 1.0) -> RigidBodyMass | None:
    """Check that the shapes are mass-normalised, as far as the export allows.

    Parameters
    ----------
    fe : FEModes
    total_mass : float, optional
        The structure's mass [kg]; compared with the rigid-body modes' mass.
    mass_matrix : array_like or scipy sparse (n_nodes * n_dof, n_nodes * n_dof), optional
        Mass matrix in the DOF order of ``fe.shapes`` (node-major); then
        ``Phi^T M Phi`` must be the identity within ``rtol``.
    rtol : float
        Relative tolerance.
    rigid_below_hz : float
        Modes below this frequency are rigid-body modes.

    Returns
    -------
    RigidBodyMass or None
        The rigid-body mass properties when the export has six rigid modes and coordinates.

    Raises
    ------
    MassNormalisationError
        The three translational masses of the rigid modes disagree; the
        rigid-body mass disagrees with ``total_mass``; a modal mass from the
        mass matrix is not 1. The message names the file, the mode(s), what
        was found and the scale factor it implies.
    """
    src = fe.source or "FE modes"
    if mass_matrix is not None:
        phi = fe.shapes.reshape(len(fe), -1).T
        if mass_matrix.shape != (phi.shape[0], phi.shape[0]):
            raise MassNormalisationError(f"{src}: mass matrix is {mass_matrix.shape}, expected "
                                         f"({phi.shape[0]}, {phi.shape[0]}) for {fe.node_ids.size} nodes x "
                                         f"{fe.shapes.shape[2]} DOF")
        mm = np.einsum("ik,ik->k", phi, np.asarray(mass_matrix @ phi))
        k = int(np.argmax(np.abs(mm - 1)))
        if abs(mm[k] - 1) > rtol:
            raise MassNormalisationError(
                f"{src}: mode {k + 1} ({fe.freqs_hz[k]:.4g} Hz) has modal mass phi^T M phi = {mm[k]:.4g} with the "
                f"given mass matrix, expected 1 within {rtol:g}: the shapes are not mass-normalised (scaled by "
                f"{np.sqrt(abs(mm[k])):.4g}?)")
    rb = rigid_body_mass(fe, rigid_below_hz)
    if rb is None:
        if total_mass is not None:
            log.warning("%s: the total mass %g kg cannot be checked: the export has no six rigid-body modes below "
                        "%g Hz with node coordinates", src, total_mass, rigid_below_hz)
        return None
    if rb.mass <= 0 or rb.spread > rtol:
        raise MassNormalisationError(
            f"{src}: the rigid-body modes {list(rb.modes)} imply different total masses along x, y, z: "
            f"{', '.join(f'{v:.4g}' for v in rb.masses)} kg (spread {100 * rb.spread:.1f} %, at most "
            f"{100 * rtol:g} %); mass-normalised rigid modes give one mass: some shapes are not mass-normalised "
            f"(modal mass field wrong or shapes scaled)")
    if total_mass is not None:
        ratio = rb.mass / float(total_mass)
        if abs(ratio - 1) > rtol:
            raise MassNormalisationError(
                f"{src}: the rigid-body modes imply a total mass of {rb.mass:.4g} kg, but the structure has "
                f"{float(total_mass):.4g} kg (ratio {ratio:.4g}); mass-normalised shapes give the total mass: the "
                f"shapes look scaled by {1 / np.sqrt(ratio):.4g} (not mass-normalised, or the modal mass field is "
                f"wrong)")
    log.info("%s: rigid-body modes imply a total mass of %.4g kg, centre of mass %s m", src, rb.mass,
             np.round(rb.centre, 4).tolist())
    return rb


def check_mode_values(fe, *, source: str | None = None) -> None:
    """Refuse absurd shape values and modes written twice (see the module notes).

    Raises
    ------
    FEReadError
        A translation above :data:`MAX_MASS_NORMALISED_TRANSLATION` (names
        the mode, node, DOF and value), or two modes at the same frequency with
        parallel shapes (names both).
    """
    src = source or fe.source or "FE modes"
    shapes = np.asarray(fe.shapes, float)
    if shapes.size == 0:
        return
    tr = np.abs(shapes[:, :, :3])
    k, i, d = np.unravel_index(int(np.argmax(tr)), tr.shape)
    if tr[k, i, d] > MAX_MASS_NORMALISED_TRANSLATION:
        raise FEReadError(
            src, f"mode {k + 1} ({fe.freqs_hz[k]:.4g} Hz) has the value {shapes[k, i, d]:.4g} at node "
            f"{int(fe.node_ids[i])} ({'xyz'[d]} translation): a mass-normalised translation of that size needs a "
            # 1/u² without an overflow warning for an absurd value (a damaged file)
            f"node lighter than {math.exp(-2 * math.log(tr[k, i, d])):.3g} kg (limit |u| <= "
            f"{MAX_MASS_NORMALISED_TRANSLATION:g} 1/sqrt(kg)); the value is corrupt")
    f = np.asarray(fe.freqs_hz, float)
    flat = shapes.reshape(len(f), -1)
    norm = np.linalg.norm(flat, axis=1)
    order = np.argsort(f, kind="stable")
    for n, a in enumerate(order):
        for b in order[n + 1:]:
            if abs(f[b] - f[a]) > 1e-6 * max(abs(f[a]), abs(f[b]), 1e-3):
                break
            if norm[a] == 0 or norm[b] == 0:
                continue
            mac = float(np.dot(flat[a], flat[b]) ** 2 / (norm[a] ** 2 * norm[b] ** 2))
            if mac > 0.999:
                lo, hi = sorted((int(a), int(b)))
                raise FEReadError(
                    src, f"modes {lo + 1} and {hi + 1} are the same mode written twice ({f[lo]:.6g} Hz, MAC "
                    f"{mac:.4f} over every DOF): eigenvectors of one model are mass-orthogonal, even in a degenerate "
                    f"pair; remove the duplicate")
