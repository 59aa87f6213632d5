"""Physical checks of imported FE modes: model size, point offsets, rigid-body mass, duplicate and absurd modes.

The tolerances scale with the model, not with any particular mesh:

* **Model size** ``D``: the diagonal of the nodes' bounding box. A point
  (sensor, contact point) is rigidly attached to its FE node by a link of
  length ``|p - x_node|``; a link longer than ``POINT_OFFSET_FRACTION * D``
  (a quarter of the structure) is not a rigid attachment but a wrong node or
  a wrong unit. Which side has the wrong unit is told apart: when the FE's
  node coordinates times 1e-3, 1e-2 or 0.0254 put the node near the point,
  or the model is larger than a railway wheelset can be
  (:data:`WHEELSET_SIZE_M`) and such a factor brings it into that range, the
  message says "the FE coordinates look like mm" (a UFF without dataset 164
  or a Nastran file states no units); when scaling the *point* by such a
  factor brings it near its node, it says the positions "look like mm / cm
  / inches" (points must be in metres whatever the FE's units).
* **Rigid-body modes** (:func:`rigid_body_modes`): the six lowest modes of a
  free-free export whose shapes are rigid-body motions, recognised by the
  shapes (the residual of fitting each by a rigid motion of the nodes) and
  not by a frequency threshold: a soft-spring or shifted free-free run puts
  them at up to a few Hz, a well-conditioned one at 1e-4 Hz or at slightly
  negative eigenvalues. Without node coordinates the frequency gap to the
  first flexible mode decides.
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

from .errors import FEImportError, FEReadError, PointToleranceError

__all__ = ["POINT_OFFSET_FRACTION", "MAX_MASS_NORMALISED_TRANSLATION", "UNIT_SLIPS", "WHEELSET_SIZE_M",
           "RIGID_RESIDUAL_MAX", "RIGID_GAP_FRACTION", "MassNormalisationError", "RigidBodyMass", "RigidBodyModes",
           "model_size", "unit_slip", "fe_unit_slip", "point_offset_limit", "check_point_offsets", "rigid_body_modes",
           "rigid_body_mass", "check_mass_normalisation", "check_mode_values"]

log = logging.getLogger("fem_import")

#: A point farther from its FE node than this fraction of the model size is refused.
POINT_OFFSET_FRACTION = 0.25
#: Largest credible mass-normalised translation [1/sqrt(kg)]: 1/u^2 = 1e-8 kg.
MAX_MASS_NORMALISED_TRANSLATION = 1e4
#: Unit slips tried when a point is far from its node: factor to metres and the unit's name.
UNIT_SLIPS = ((1e-3, "mm"), (1e-2, "cm"), (0.0254, "inches"))
#: Size range [m] (bounding-box diagonal) of a railway wheelset FE model: a larger model is in another unit.
WHEELSET_SIZE_M = (0.3, 10.0)
#: Largest relative residual of a rigid-body mode's shape fitted by a rigid motion of the nodes.
RIGID_RESIDUAL_MAX = 0.05
#: Without node coordinates, the six lowest modes are rigid-body modes when f6 <= this fraction of f7.
RIGID_GAP_FRACTION = 0.05


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


def _units_stated(fe) -> bool:
    """Whether the FE's file stated its units (a UFF with dataset 164), as far as the import history tells."""
    return not ("assumed" in str(fe.units) or any("no units dataset 164" in h for h in fe.history))


def fe_unit_slip(fe, position, node_xyz, limit: float, node=None) -> str:
    """Message part naming FE coordinates in another unit (mm, cm, inches), or "".

    The FE is in another unit when its node coordinates times the unit's
    factor put the node within ``limit`` times that factor of ``position``
    and make the model wheelset-sized (:data:`WHEELSET_SIZE_M`), or when its
    size (:func:`model_size`) exceeds that range and the factor brings it
    into it.
    """
    p = np.asarray(position, float)
    x = np.asarray(node_xyz, float)
    size = model_size(fe)
    lo, hi = WHEELSET_SIZE_M
    if _units_stated(fe) and fe.format == "ansys-rst":
        why = (f" although the file is read as {fe.units}: the model's /UNITS or material data are wrong; solve "
               f"it with /UNITS and materials in one consistent system")
    elif _units_stated(fe):
        why = (f" although the file states {fe.units}: its units dataset 164 is wrong; export the FE in SI units "
               f"(m) with a matching dataset 164")
    else:
        why = (" (the file states no units: UFF without dataset 164, a Nastran file, or an ANSYS result without "
               "/UNITS whose materials do not tell); the points are in metres: "
               "export the FE in SI units (m)" + (", or add a units dataset 164" if fe.format == "uff" else ""))
    what = f"node {node}" if node is not None else "the node"
    for factor, unit in UNIT_SLIPS:
        d = float(np.linalg.norm(p - factor * x))
        # the scaled model must be wheelset-sized too: a point at the origin is near any node scaled by 1e-3
        if d <= max(limit * factor, 1e-9) and lo <= size * factor <= hi:
            return (f"; the FE coordinates look like {unit}: x {factor:g} puts {what} {d:.3g} m from the point and "
                    f"makes the model {size * factor:.3g} m large{why}")
    if np.isfinite(size) and size > hi:
        for factor, unit in UNIT_SLIPS:
            if lo <= size * factor <= hi:
                return (f"; a model {size:.3g} m large is no railway wheelset ({lo:g}-{hi:g} m): the FE coordinates "
                        f"look like {unit} (x {factor:g} makes it {size * factor:.3g} m){why}")
        return f"; a model {size:.3g} m large is no railway wheelset ({lo:g}-{hi:g} m): check the FE's units"
    return ""


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
        size it comes from) and a likely unit slip: of the FE coordinates
        (:func:`fe_unit_slip`, said first) or of the point's position
        (:func:`unit_slip`).
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
            head = (f"{where}{name}: position {np.round(p, 6).tolist()} m lies {d:.4g} m from its fe_node {int(node)} "
                    f"at {np.round(x, 6).tolist()} m, more than {limit:.3g} m ({POINT_OFFSET_FRACTION:g} x the model "
                    f"size {model_size(fe):.3g} m of {fe.source or 'the FE model'})")
            fe_slip = fe_unit_slip(fe, p, x, limit, int(node))
            if fe_slip:
                raise PointToleranceError(head + fe_slip)
            raise PointToleranceError(
                f"{head}{unit_slip(p, x, limit)}; a sensor is rigidly attached to a nearby node: check the fe_node "
                f"and the unit of x, y, z")


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


@dataclass(frozen=True)
class RigidBodyModes:
    """Which modes of an export are its six rigid-body modes, and how that was told (:func:`rigid_body_modes`).

    Attributes
    ----------
    indices : tuple of int
        0-based positions of the six rigid-body modes (in frequency order);
        empty when the export does not have six.
    residuals : ndarray
        Rigidity residual of each of the lowest modes examined (frequency
        order; NaN where the coordinates cannot tell), 0 for a rigid motion.
    gap : float
        ``f6 / f7``: the sixth-lowest frequency over the seventh (NaN with
        fewer than seven modes or ``f7 = 0``).
    method : str
        ``"shapes"`` (rigidity residual), ``"frequency gap"`` or ``""`` (none found).
    reason : str
        How they were recognised, or why no six rigid-body modes were found
        (for messages: "mass check skipped: ...").
    """

    indices: tuple[int, ...]
    residuals: np.ndarray
    gap: float
    method: str
    reason: str

    @property
    def found(self) -> bool:
        return len(self.indices) == 6


def _rigid_basis(fe) -> tuple[np.ndarray, np.ndarray, bool] | None:
    """Rigid-motion basis ``R`` (rows: the DOFs used), the node rows used, and whether rotations are used.

    Translations ``u_i = t + theta x (x_i - c)`` of the nodes with coordinates;
    when they cannot tell all six motions (nodes on one line: a beam model)
    and the shapes have rotations, the rotations ``theta_i = theta`` too.
    None when even that cannot tell them.
    """
    ok = np.all(np.isfinite(fe.xyz), axis=1)
    if ok.sum() < 2:
        return None
    xyz = fe.xyz[ok]
    r = xyz - xyz.mean(axis=0)
    n = len(r)
    R = np.concatenate([np.broadcast_to(np.eye(3), (n, 3, 3)), -_skew(r)], axis=2).reshape(-1, 6)
    if np.linalg.matrix_rank(R) == 6:
        return R, ok, False
    if fe.shapes.shape[2] < 6:
        return None
    Rr = np.concatenate([np.zeros((n, 3, 3)), np.broadcast_to(np.eye(3), (n, 3, 3))], axis=2)
    R = np.concatenate([R.reshape(n, 3, 6), Rr], axis=1).reshape(-1, 6)
    if np.linalg.matrix_rank(R) < 6:
        return None
    return R, ok, True


def _phi(fe, modes, ok, rotations: bool) -> np.ndarray:
    """Shapes of ``modes`` at the rows of :func:`_rigid_basis`, one column each."""
    sub = fe.shapes[np.asarray(modes)][:, ok, :] if rotations else fe.shapes[np.asarray(modes)][:, ok, :3]
    return sub.reshape(len(modes), -1).T


def rigid_body_modes(fe, *, max_residual: float = RIGID_RESIDUAL_MAX,
                     max_gap: float = RIGID_GAP_FRACTION) -> RigidBodyModes:
    """The six rigid-body modes of a free-free export, recognised physically rather than by a frequency threshold.

    With node coordinates, the six lowest modes are the rigid-body modes when
    each one's shape is a rigid motion of the nodes (the relative residual of
    fitting ``u_i = t + theta x (x_i - c)``, translations, and rotations too
    for a beam model, is at most ``max_residual``), together they span all
    six motions, and the seventh mode is not one (seven would be a mechanism
    or an unconnected part). Their frequencies do not matter: a shifted or
    soft-spring free-free run puts them at a few Hz, a well-conditioned one
    at 1e-4 Hz. Without coordinates (a punch file read alone) they are
    recognised by the frequency gap to the first flexible mode,
    ``f6 <= max_gap * f7``.

    Parameters
    ----------
    fe : FEModes
    max_residual : float
        Largest relative rigidity residual of a rigid-body mode (default
        :data:`RIGID_RESIDUAL_MAX`).
    max_gap : float
        Largest ``f6 / f7`` accepted by the frequency-gap rule (default
        :data:`RIGID_GAP_FRACTION`).

    Returns
    -------
    RigidBodyModes
        ``found`` tells whether there are six; ``reason`` says how they were
        recognised or why not.
    """
    f = np.asarray(fe.freqs_hz, float)
    m = f.size
    order = np.argsort(f, kind="stable")
    gap = float(f[order[5]] / f[order[6]]) if m >= 7 and f[order[6]] > 0 else float("nan")
    label = lambda j: f"mode {int(fe.mode_numbers[j])} ({f[j]:.4g} Hz)"  # noqa: E731
    if m < 6:
        return RigidBodyModes((), np.full(m, np.nan), gap, "", f"the export has {m} modes, fewer than the six "
                                                               f"rigid-body modes of a free-free structure")
    basis = _rigid_basis(fe)
    if basis is None:
        if np.isfinite(gap) and gap <= max_gap:
            return RigidBodyModes(tuple(int(j) for j in order[:6]), np.full(min(m, 7), np.nan), gap,
                                  "frequency gap", f"the six lowest modes (up to {f[order[5]]:.4g} Hz) lie below "
                                  f"{max_gap:g} x the seventh ({f[order[6]]:.4g} Hz); no node coordinates to check "
                                  f"their shapes")
        why = ("there is no seventh mode to compare with" if m < 7 else
               f"the sixth-lowest mode ({f[order[5]]:.4g} Hz) is not far below the seventh ({f[order[6]]:.4g} Hz; "
               f"ratio {gap:.3g} > {max_gap:g})")
        return RigidBodyModes((), np.full(min(m, 7), np.nan), gap, "",
                              f"the shapes cannot be checked for rigid-body motion (no node coordinates, or nodes "
                              f"that cannot tell the six motions) and {why}")
    R, ok, rotations = basis
    lowest = order[:min(m, 7)]
    Phi = _phi(fe, lowest, ok, rotations)
    Q, *_ = np.linalg.lstsq(R, Phi, rcond=None)
    res = np.linalg.norm(R @ Q - Phi, axis=0) / np.maximum(np.linalg.norm(Phi, axis=0), 1e-300)
    bad = [k for k in range(6) if not res[k] <= max_residual]
    if bad:
        k = bad[0]
        return RigidBodyModes((), res, gap, "", f"{label(lowest[k])}, one of the six lowest, is not a rigid-body "
                              f"motion (it deviates {100 * res[k]:.3g} % from one, more than {100 * max_residual:g} "
                              f"%): the export has fewer than six rigid-body modes (a constrained model, or the "
                              f"rigid-body modes were left out of the export)")
    if m >= 7 and res[6] <= max_residual:
        return RigidBodyModes((), res, gap, "", f"seven modes are rigid-body motions (the seventh, "
                              f"{label(lowest[6])}, deviates {100 * res[6]:.3g} % from one): a mechanism or an "
                              f"unconnected part; which six are the structure's cannot be told")
    sv = np.linalg.svd(Q[:, :6], compute_uv=False)
    if sv[-1] <= 1e-6 * sv[0]:
        return RigidBodyModes((), res, gap, "", "the six lowest modes are rigid-body motions but not six different "
                              "ones (two are the same motion): the export is corrupt")
    return RigidBodyModes(tuple(int(j) for j in lowest[:6]), res, gap, "shapes",
                          f"the six lowest modes (up to {f[lowest[5]]:.4g} Hz) are rigid-body motions (largest "
                          f"deviation {100 * float(res[:6].max()):.2g} %)")


def rigid_body_mass(fe, rigid_below_hz: float | None = None) -> RigidBodyMass | None:
    """Mass, centre of mass and inertia implied by the rigid-body modes (None when they cannot tell).

    Needs node coordinates and six rigid-body modes (a free-free export);
    the translations are used (rotational DOFs of shell models can be
    unreliable), with the rotations too when the nodes lie on one line (a
    beam model, whose rotation about its axis shows only there).

    Parameters
    ----------
    fe : FEModes
    rigid_below_hz : float, optional
        None (default): the rigid-body modes are recognised by their shapes
        (:func:`rigid_body_modes`); a number: the modes below it, which must
        be six (the older threshold rule).

    Returns
    -------
    RigidBodyMass or None
        None without coordinates, or without six rigid-body modes (the reason:
        :func:`rigid_body_modes`).
    """
    f = np.asarray(fe.freqs_hz, float)
    if rigid_below_hz is None:
        found = rigid_body_modes(fe)
        if not found.found:
            return None
        rigid = np.asarray(found.indices)
    else:
        rigid = np.flatnonzero(f < rigid_below_hz)
    ok = np.all(np.isfinite(fe.xyz), axis=1)
    if rigid.size != 6 or ok.sum() < 3:
        return None
    basis = _rigid_basis(fe)
    if basis is None:
        return None
    R, ok, rotations = basis
    c = fe.xyz[ok].mean(axis=0)
    Phi = _phi(fe, rigid, ok, rotations)
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
                             rigid_below_hz: float | None = None) -> RigidBodyMass | None:
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
    rigid_below_hz : float, optional
        None (default): the rigid-body modes are recognised by their shapes
        (:func:`rigid_body_modes`); a number: the modes below it.

    Returns
    -------
    RigidBodyMass or None
        The rigid-body mass properties when the export has six rigid modes and
        coordinates. None when the check against the rigid-body modes cannot
        be made: a WARNING says so and why (:attr:`RigidBodyModes.reason`).

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
                f"{src}: mode {int(fe.mode_numbers[k])} ({fe.freqs_hz[k]:.4g} Hz) has modal mass phi^T M phi = "
                f"{mm[k]:.4g} with the "
                f"given mass matrix, expected 1 within {rtol:g}: the shapes are not mass-normalised (scaled by "
                f"{np.sqrt(abs(mm[k])):.4g}?)")
    rb = rigid_body_mass(fe, rigid_below_hz)
    if rb is None:
        if not np.any(np.all(np.isfinite(fe.xyz), axis=1)):
            why = "the modes have no node coordinates"
        elif rigid_below_hz is None:
            why = rigid_body_modes(fe).reason
        else:
            n = int(np.sum(np.asarray(fe.freqs_hz) < rigid_below_hz))
            why = f"{n} modes lie below {rigid_below_hz:g} Hz, not the six rigid-body modes"
        what = f"the total mass {total_mass:g} kg and the" if total_mass is not None else "the"
        log.warning("%s: %s mass normalisation of the shapes cannot be checked against the rigid-body modes (check "
                    "skipped): %s", src, what, why)
        return None
    if rb.mass <= 0 or rb.spread > rtol:
        raise MassNormalisationError(
            f"{src}: the rigid-body modes {[int(fe.mode_numbers[k - 1]) for k in rb.modes]} imply different total "
            f"masses along x, y, z: "
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


def _number(fe, k: int) -> int:
    """The file's number of the mode at position ``k`` (0-based)."""
    numbers = getattr(fe, "mode_numbers", None)
    return int(numbers[k]) if numbers is not None else k + 1


def check_mode_values(fe, *, source: str | None = None) -> None:
    """Refuse absurd shape values and modes written twice (see the module notes).

    Raises
    ------
    FEReadError
        A non-finite frequency or shape value, a translation above
        :data:`MAX_MASS_NORMALISED_TRANSLATION` (names the mode, node, DOF and
        value), or two modes at the same frequency with parallel shapes (names
        both).
    """
    src = source or fe.source or "FE modes"
    shapes = np.asarray(fe.shapes, float)
    if shapes.size == 0:
        return
    bad = np.flatnonzero(~np.isfinite(np.asarray(fe.freqs_hz, float)))
    if bad.size:
        raise FEReadError(src, f"mode {_number(fe, int(bad[0]))} has the frequency {fe.freqs_hz[bad[0]]!r}: a "
                               f"damaged eigenvalue")
    if not np.all(np.isfinite(shapes)):
        k, i, d = np.argwhere(~np.isfinite(shapes))[0]
        raise FEReadError(src, f"mode {_number(fe, int(k))} has the value {shapes[k, i, d]!r} at node "
                               f"{int(fe.node_ids[i])} (DOF {d + 1}): a damaged shape")
    tr = np.abs(shapes[:, :, :3])
    k, i, d = np.unravel_index(int(np.argmax(tr)), tr.shape)
    if tr[k, i, d] > MAX_MASS_NORMALISED_TRANSLATION:
        raise FEReadError(
            src, f"mode {_number(fe, k)} ({fe.freqs_hz[k]:.4g} Hz) has the value {shapes[k, i, d]:.4g} at node "
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
                    src, f"modes {_number(fe, lo)} and {_number(fe, hi)} are the same mode written twice "
                    f"({f[lo]:.6g} Hz, MAC "
                    f"{mac:.4f} over every DOF): eigenvectors of one model are mass-orthogonal, even in a degenerate "
                    f"pair; remove the duplicate")
