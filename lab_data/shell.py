"""Four-node flat shell quadrilateral (membrane + MITC4 plate + drilling).

The wheel webs of the truth wheelset are meshed with this element. It is the
classical *flat facet* shell: in a local frame lying in the mean plane of the
four nodes, the membrane and plate responses are formed independently and
superposed, then rotated to global axes. Six DOF per node: three translations
and the three components of the global rotation vector (right-hand rule).

Formulation
-----------
Local frame
    ``e3 = n`` is the normalised cross product of the diagonals,
    ``(x3 - x1) x (x4 - x2)``; ``e1`` is the first side ``x2 - x1`` projected
    on the mean plane and ``e2 = e3 x e1``. Nodes are projected on the mean
    plane (through the centroid, normal ``n``). Because ``n`` comes from the
    nodes themselves, any convex node ordering is counter-clockwise about its
    own ``n``; reversing the ordering flips ``n`` and gives the same physical
    element. Pass ``normal=`` to have an ordering that contradicts an intended
    orientation rejected.
Membrane
    Bilinear isoparametric plane stress, full 2x2 Gauss quadrature.
Plate bending and transverse shear
    Mindlin-Reissner kinematics with local rotations ``beta_x = theta_y``,
    ``beta_y = -theta_x`` (in-plane displacement ``z * beta``). Curvatures
    are integrated with 2x2 Gauss. The transverse shear strains use the MITC4
    assumed-strain field of Bathe & Dvorkin (1985): the covariant shear
    strains ``e_rz`` are sampled at the edge mid-points ``(r, s) = (0, +-1)``
    and ``e_sz`` at ``(+-1, 0)``, interpolated linearly across the element and
    mapped back to Cartesian components with the inverse Jacobian. This removes
    shear locking for thin plates without the spurious zero-energy modes of
    reduced integration. Shear stiffness is ``shear_factor * G * t``.
Drilling rotation
    The rotation ``theta_n`` about the element normal is tied to the in-plane
    infinitesimal rotation ``omega = (du2/dx1 - du1/dx2) / 2`` by the
    Hughes & Brezzi (1989) penalty ``gamma * t * int (theta_n - omega)^2 dA``
    with ``gamma = drilling_ratio * G``. The penalty is sampled at the centroid
    (one point). A single sample leaves the three zero-mean patterns of the
    bilinear ``theta_n`` field energy-free, and in a mesh these form global
    mechanisms. They are stabilised by adding the deviation of
    ``theta_n - omega`` from its centroid value, sampled at the 2x2 Gauss
    points, with weight ``drilling_stabilisation`` relative to the centroid
    term. The deviation vanishes for rigid rotations, so rigid-body modes stay
    exact. With the default weight 1 the sum equals full 2x2 integration of the
    penalty on parallelograms. A smaller weight is closer to pure one-point
    quadrature but brings the stabilised drilling modes down in frequency,
    roughly ``f ~ sqrt(weight) * 55 kHz * (30 mm / t)`` for steel (they
    depend on thickness, not mesh size). Even the default
    stiffens in-plane bending by only about 0.15 % (cantilever strip, 80x8
    mesh), which is small next to the parasitic shear of the bilinear
    membrane.
Mass
    Consistent, 2x2 Gauss: ``rho t N^T N`` for the three translations and
    ``rho t^3 / 12 N^T N`` for all three rotations (including drilling, so the
    mass matrix is positive definite).

References
----------
K.-J. Bathe and E. N. Dvorkin, "A four-node plate bending element based on
Mindlin/Reissner plate theory and a mixed interpolation", Int. J. Numer.
Methods Eng. 21 (1985) 367-383.

T. J. R. Hughes and F. Brezzi, "On drilling degrees of freedom", Comput.
Methods Appl. Mech. Eng. 72 (1989) 105-121.
"""

from __future__ import annotations

import numpy as np

__all__ = ["shell_quad_matrices", "WARP_TOLERANCE"]

#: Allowed out-of-plane distance of a node from the mean plane, as a fraction
#: of the longest diagonal. Beyond it a flat facet misrepresents the geometry
#: (and loses exact rigid-body modes), so the element is rejected.
WARP_TOLERANCE = 1e-3

_G = 1.0 / np.sqrt(3.0)
# Natural coordinates of the nodes, counter-clockwise from (-1, -1).
_RN = np.array([-1.0, 1.0, 1.0, -1.0])
_SN = np.array([-1.0, -1.0, 1.0, 1.0])
# 2x2 Gauss points (all weights are 1).
_RG = _G * _RN
_SG = _G * _SN


def _shape(r: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Bilinear shape functions and natural derivatives, shape (npoints, 4)."""
    r = np.atleast_1d(r)[:, None]
    s = np.atleast_1d(s)[:, None]
    n = 0.25 * (1.0 + _RN * r) * (1.0 + _SN * s)
    dr = 0.25 * _RN * (1.0 + _SN * s)
    ds = 0.25 * _SN * (1.0 + _RN * r)
    return n, dr, ds


# Tabulated once: the element is evaluated hundreds of times per model build.
_NG, _DRG, _DSG = _shape(_RG, _SG)
_NC, _DRC, _DSC = _shape(np.array([0.0]), np.array([0.0]))
# MITC4 tying points: e_rz at B = (0, -1), D = (0, +1); e_sz at A = (-1, 0), C = (+1, 0).
_NT_R, _DRT_R, _ = _shape(np.array([0.0, 0.0]), np.array([-1.0, 1.0]))
_NT_S, _, _DST_S = _shape(np.array([-1.0, 1.0]), np.array([0.0, 0.0]))
# Linear interpolation weights of the tying values at the Gauss points:
# e_rz varies with s only, e_sz with r only.
_WT_R = np.stack([0.5 * (1.0 - _SG), 0.5 * (1.0 + _SG)], axis=1)
_WT_S = np.stack([0.5 * (1.0 - _RG), 0.5 * (1.0 + _RG)], axis=1)

# Local DOF indices within the 24-vector (node-major, 6 per node).
_U = np.arange(4) * 6
_V = _U + 1
_W = _U + 2
_TX = _U + 3
_TY = _U + 4
_TZ = _U + 5


def _cartesian_derivatives(dr: np.ndarray, ds: np.ndarray, xy: np.ndarray):
    """Jacobian determinants, inverse Jacobians and dN/dx, dN/dy at points.

    ``dr``, ``ds`` are (npoints, 4) natural derivatives; ``jac[p]`` is
    ``[[x_r, y_r], [x_s, y_s]]``.
    """
    jac = np.stack([dr @ xy, ds @ xy], axis=1)
    det = jac[:, 0, 0] * jac[:, 1, 1] - jac[:, 0, 1] * jac[:, 1, 0]
    inv = np.empty_like(jac)
    inv[:, 0, 0] = jac[:, 1, 1]
    inv[:, 0, 1] = -jac[:, 0, 1]
    inv[:, 1, 0] = -jac[:, 1, 0]
    inv[:, 1, 1] = jac[:, 0, 0]
    inv /= det[:, None, None]
    dx = inv[:, 0, 0, None] * dr + inv[:, 0, 1, None] * ds
    dy = inv[:, 1, 0, None] * dr + inv[:, 1, 1, None] * ds
    return det, inv, dx, dy


def _local_frame(xyz: np.ndarray, normal: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """Local frame (rows e1, e2, e3) and in-plane node coordinates (4, 2)."""
    d1 = xyz[2] - xyz[0]
    d2 = xyz[3] - xyz[1]
    cross = np.cross(d1, d2)
    diag = max(np.linalg.norm(d1), np.linalg.norm(d2))
    if not np.isfinite(diag) or diag == 0.0:
        raise ValueError("shell element has coincident or non-finite nodes")
    twice_area = np.linalg.norm(cross)
    # Relative to diag**2 so the check is scale free; 1e-12 is far below any
    # usable aspect ratio but above round-off of a genuinely degenerate quad.
    if twice_area <= 1e-12 * diag * diag:
        raise ValueError(
            f"shell element has zero area (|d13 x d24| = {twice_area:.3e} for diagonal {diag:.3e})"
        )
    e3 = cross / twice_area
    if normal is not None:
        hint = np.asarray(normal, dtype=float).reshape(3)
        if float(hint @ e3) < 0.0:
            raise ValueError(
                "shell element nodes are ordered clockwise about the given normal "
                f"{hint.tolist()} (element normal from the diagonals is {e3.tolist()}); "
                "reverse the node order"
            )
    centroid = xyz.mean(axis=0)
    dist = (xyz - centroid) @ e3
    warp = float(np.max(np.abs(dist)))
    if warp > WARP_TOLERANCE * diag:
        raise ValueError(
            f"shell element is warped: a node lies {warp:.3e} from the mean plane, "
            f"tolerance is {WARP_TOLERANCE:g} x longest diagonal = {WARP_TOLERANCE * diag:.3e}"
        )
    proj = xyz - np.outer(dist, e3)
    sides = np.linalg.norm(np.roll(proj, -1, axis=0) - proj, axis=1)
    if np.min(sides) <= 1e-8 * diag:
        raise ValueError(
            f"shell element has coincident nodes (side lengths {np.array2string(sides, precision=3)}); "
            "collapsed quads are not supported"
        )
    side = proj[1] - proj[0]
    e1 = side - (side @ e3) * e3
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(e3, e1)
    frame = np.vstack([e1, e2, e3])
    xy = (proj - proj[0]) @ frame[:2].T
    return frame, xy


def shell_quad_matrices(
    xyz,
    thickness: float,
    E: float,
    nu: float,
    rho: float,
    *,
    drilling_ratio: float = 1.0,
    shear_factor: float = 5.0 / 6.0,
    drilling_stabilisation: float = 1.0,
    normal=None,
) -> tuple[np.ndarray, np.ndarray]:
    """Stiffness and consistent mass of a 4-node flat shell in global axes.

    Parameters
    ----------
    xyz : array_like, shape (4, 3)
        Node coordinates [m], ordered around the element. The element normal
        is ``n = (x3 - x1) x (x4 - x2)`` normalised, and the ordering is
        counter-clockwise about it.
    thickness : float
        Shell thickness t [m], > 0.
    E : float
        Young's modulus [Pa], > 0.
    nu : float
        Poisson's ratio, in (-1, 0.5).
    rho : float
        Density [kg/m^3], > 0.
    drilling_ratio : float, optional
        Drilling penalty ``gamma`` as a multiple of the shear modulus G
        (Hughes & Brezzi penalty), > 0. Default 1.
    shear_factor : float, optional
        Transverse shear correction factor, > 0. Default 5/6.
    drilling_stabilisation : float, optional
        Weight, relative to the centroid penalty, of the Gauss-point
        stabilisation of the drilling field (see the module docstring), > 0.
        Default 1.
    normal : array_like, shape (3,), optional
        Intended outward normal. If given, an element whose node ordering is
        clockwise about it (``n . normal < 0``) is rejected.

    Returns
    -------
    K, M : ndarray, shape (24, 24)
        Symmetric stiffness [N/m, N, N m] and mass [kg, kg m, kg m^2] matrices.
        DOF order: node 1 ``(ux, uy, uz, rx, ry, rz)``, node 2, ... in global
        axes; rotations are rotation-vector components.

    Raises
    ------
    ValueError
        For invalid material or thickness, zero area, warping beyond
        :data:`WARP_TOLERANCE` x longest diagonal, a non-positive Jacobian at
        a Gauss point (non-convex, self-intersecting or inverted quad), or an
        ordering contradicting ``normal``.

    Notes
    -----
    Every node gets drilling stiffness from the penalty, so a shell-only mesh
    needs no artificial ``rz`` springs; at shell-beam junctions the drilling
    DOF is a genuine (penalty-stiff) rotation.
    """
    xyz = np.asarray(xyz, dtype=float)
    if xyz.shape != (4, 3):
        raise ValueError(f"xyz must have shape (4, 3), got {xyz.shape}")
    if not np.all(np.isfinite(xyz)):
        raise ValueError("shell element has non-finite node coordinates")
    t = float(thickness)
    if not (t > 0.0):
        raise ValueError(f"thickness must be positive, got {thickness!r}")
    if not (E > 0.0):
        raise ValueError(f"Young's modulus E must be positive, got {E!r}")
    if not (rho > 0.0):
        raise ValueError(f"density rho must be positive, got {rho!r}")
    if not (-1.0 < nu < 0.5):
        raise ValueError(f"Poisson's ratio nu must lie in (-1, 0.5), got {nu!r}")
    if not (drilling_ratio > 0.0):
        raise ValueError(f"drilling_ratio must be positive, got {drilling_ratio!r}")
    if not (shear_factor > 0.0):
        raise ValueError(f"shear_factor must be positive, got {shear_factor!r}")
    if not (drilling_stabilisation > 0.0):
        raise ValueError(f"drilling_stabilisation must be positive, got {drilling_stabilisation!r}")

    frame, xy = _local_frame(xyz, normal)
    G = E / (2.0 * (1.0 + nu))

    det, inv, dx, dy = _cartesian_derivatives(_DRG, _DSG, xy)
    d13, d24 = xy[2] - xy[0], xy[3] - xy[1]
    area = 0.5 * abs(d13[0] * d24[1] - d13[1] * d24[0])
    # A Gauss-point Jacobian that is tiny next to the mean (area / 4) would
    # make the element useless even when positive, hence a relative bound.
    if np.any(det <= 1e-10 * area):
        raise ValueError(
            "shell element has a non-positive Jacobian at a Gauss point "
            f"(det J = {np.array2string(det, precision=3)}): the quad is non-convex, "
            "self-intersecting or its nodes are not ordered around the element"
        )

    # --- membrane ---------------------------------------------------------
    bm = np.zeros((4, 3, 24))
    bm[:, 0, _U] = dx
    bm[:, 1, _V] = dy
    bm[:, 2, _U] = dy
    bm[:, 2, _V] = dx
    plane_stress = np.array([[1.0, nu, 0.0], [nu, 1.0, 0.0], [0.0, 0.0, 0.5 * (1.0 - nu)]]) / (1.0 - nu * nu)
    d_m = E * t * plane_stress
    d_b = E * t**3 / 12.0 * plane_stress

    # --- bending (beta_x = theta_y, beta_y = -theta_x) ---------------------
    bb = np.zeros((4, 3, 24))
    bb[:, 0, _TY] = dx
    bb[:, 1, _TX] = -dy
    bb[:, 2, _TY] = dy
    bb[:, 2, _TX] = -dx

    # --- MITC4 transverse shear --------------------------------------------
    # Covariant strain e_r = w_,r + beta . x_,r with the geometry of the tying
    # point itself (Bathe & Dvorkin): sampling where the strain is exact for a
    # Kirchhoff field is what makes the element free of shear locking.
    def covariant(n, dnat, xnat):
        b = np.zeros((n.shape[0], 24))
        b[:, _W] = dnat
        b[:, _TY] = n * xnat[:, 0, None]
        b[:, _TX] = -n * xnat[:, 1, None]
        return b

    er_tie = covariant(_NT_R, _DRT_R, _DRT_R @ xy)  # at (0, -1), (0, +1)
    es_tie = covariant(_NT_S, _DST_S, _DST_S @ xy)  # at (-1, 0), (+1, 0)
    e_nat = np.stack([_WT_R @ er_tie, _WT_S @ es_tie], axis=1)  # (gp, 2, 24)
    # [e_r, e_s] = J [gamma_xz, gamma_yz]
    bs = np.einsum("gij,gjk->gik", inv, e_nat)

    k_loc = np.einsum("g,gik,ij,gjl->kl", det, bm, d_m, bm)
    k_loc += np.einsum("g,gik,ij,gjl->kl", det, bb, d_b, bb)
    k_loc += (shear_factor * G * t) * np.einsum("g,gik,gil->kl", det, bs, bs)

    # --- drilling penalty ---------------------------------------------------
    gamma = drilling_ratio * G

    def drill_row(n, dxn, dyn):
        b = np.zeros((n.shape[0], 24))
        b[:, _TZ] = n
        b[:, _V] = -0.5 * dxn
        b[:, _U] = 0.5 * dyn
        return b

    _, _, dxc, dyc = _cartesian_derivatives(_DRC, _DSC, xy)
    bd_c = drill_row(_NC, dxc, dyc)[0]
    k_loc += (gamma * t * area) * np.outer(bd_c, bd_c)
    # Stabilisation: only the part of theta_n - omega that the centroid
    # sample cannot see, so the centroid term keeps its meaning.
    bd_h = drill_row(_NG, dx, dy) - bd_c
    k_loc += (drilling_stabilisation * gamma * t) * np.einsum("g,gk,gl->kl", det, bd_h, bd_h)

    # --- consistent mass ------------------------------------------------------
    nn = np.einsum("g,gi,gj->ij", det, _NG, _NG)
    m_loc = np.zeros((4, 6, 4, 6))
    m_trans = rho * t * nn
    m_rot = rho * t**3 / 12.0 * nn
    for k in range(3):
        m_loc[:, k, :, k] = m_trans
        m_loc[:, k + 3, :, k + 3] = m_rot

    # --- to global axes ---------------------------------------------------
    # Translations and rotation vectors both transform with the frame; the
    # mass blocks are isotropic per node, so only K needs rotating.
    k4 = k_loc.reshape(4, 2, 3, 4, 2, 3)
    k_glob = np.einsum("ki,apkbql,lj->apibqj", frame, k4, frame, optimize=True).reshape(24, 24)
    k_glob = 0.5 * (k_glob + k_glob.T)
    return k_glob, m_loc.reshape(24, 24)
