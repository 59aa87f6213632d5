"""Tests of the 4-node flat shell element (:mod:`lab_data.shell`).

References are analytic: Kirchhoff and Mindlin (Navier) solutions of the
simply supported square plate, Timoshenko beam theory for an in-plane
cantilever, and Leissa's free square plate value for the first flexible mode.
The small assembly helper lives here, not in the module under test.
"""

from __future__ import annotations

import time

import numpy as np
import pytest
import scipy.linalg
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from lab_data.shell import WARP_TOLERANCE, shell_quad_matrices

E, NU, RHO = 210e9, 0.3, 7850.0
G = E / (2.0 * (1.0 + NU))


# --------------------------------------------------------------------------- helpers
def _rotation(seed: int) -> np.ndarray:
    """A proper 3D rotation matrix, reproducible from ``seed``."""
    q, r = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0.0:
        q[:, 0] *= -1.0
    return q


def _plate_mesh(nx: int, ny: int, lx: float, ly: float) -> tuple[np.ndarray, np.ndarray]:
    """Structured mesh in the x-y plane: coordinates (N, 3), quads (nx*ny, 4) CCW about +z."""
    x, y = np.meshgrid(np.linspace(0.0, lx, nx + 1), np.linspace(0.0, ly, ny + 1), indexing="ij")
    xyz = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    n0 = (i * (ny + 1) + j).ravel()
    quads = np.column_stack([n0, n0 + ny + 1, n0 + ny + 2, n0 + 1])
    return xyz, quads


def _assemble(xyz: np.ndarray, quads: np.ndarray, t: float, **kw) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """Global sparse K and M (6 DOF per node) of a shell mesh."""
    rows, cols, kv, mv = [], [], [], []
    for q in quads:
        ke, me = shell_quad_matrices(xyz[q], t, E, NU, RHO, **kw)
        dofs = (6 * q[:, None] + np.arange(6)).ravel()
        r, c = np.meshgrid(dofs, dofs, indexing="ij")
        rows.append(r.ravel())
        cols.append(c.ravel())
        kv.append(ke.ravel())
        mv.append(me.ravel())
    n = 6 * len(xyz)
    r, c = np.concatenate(rows), np.concatenate(cols)
    k = sp.csr_matrix((np.concatenate(kv), (r, c)), shape=(n, n))
    m = sp.csr_matrix((np.concatenate(mv), (r, c)), shape=(n, n))
    return k, m


def _rigid_modes(xyz: np.ndarray) -> np.ndarray:
    """(6N, 6) rigid-body motions: 3 translations, 3 rotations u = theta x x."""
    modes = []
    for k in range(3):
        r = np.zeros((len(xyz), 6))
        r[:, k] = 1.0
        modes.append(r.ravel())
    for k in range(3):
        theta = np.eye(3)[k]
        r = np.zeros((len(xyz), 6))
        r[:, :3] = np.cross(theta, xyz)
        r[:, 3:] = theta
        modes.append(r.ravel())
    return np.array(modes).T


def _lowest_frequencies(k, m, fixed, n_modes: int) -> np.ndarray:
    """Lowest circular frequencies [rad/s] with the DOFs ``fixed`` restrained."""
    free = np.setdiff1d(np.arange(k.shape[0]), fixed)
    kf = k[free][:, free].tocsc()
    mf = m[free][:, free].tocsc()
    w2 = spla.eigsh(kf, k=n_modes, M=mf, sigma=0.0, which="LM", return_eigenvectors=False)
    return np.sqrt(np.sort(w2))


def _simply_supported_dofs(xyz: np.ndarray, a: float, hard: bool) -> np.ndarray:
    """w = 0 on all edges; in-plane u, v fixed on the edges (only to remove the
    in-plane rigid motions: a flat plate's membrane and bending decouple).
    ``hard`` also fixes the rotation about the edge normal (the tangential
    rotation of the normal), the support of the Navier/Mindlin solution."""
    on_x = np.isclose(xyz[:, 0], 0.0) | np.isclose(xyz[:, 0], a)  # edges x = const
    on_y = np.isclose(xyz[:, 1], 0.0) | np.isclose(xyz[:, 1], a)
    edge = np.flatnonzero(on_x | on_y)
    fixed = [6 * edge + k for k in range(3)]
    if hard:
        fixed += [6 * np.flatnonzero(on_x) + 3, 6 * np.flatnonzero(on_y) + 4]
    return np.unique(np.concatenate(fixed))


def _flexural_rigidity(t: float) -> float:
    return E * t**3 / (12.0 * (1.0 - NU**2))


# A general quad: non-rectangular, non-parallelogram, not aligned with any axis.
_QUAD_2D = np.array([[0.0, 0.0], [1.1, 0.1], [1.3, 0.9], [-0.1, 1.0]])


def _quad_in_3d(seed: int = 1) -> np.ndarray:
    xyz = np.column_stack([_QUAD_2D, np.zeros(4)])
    return xyz @ _rotation(seed).T + np.array([3.0, -2.0, 5.0])


# --------------------------------------------------------------------------- 1. single element
def test_single_element_rigid_body_modes_and_mass():
    xyz = _quad_in_3d()
    t = 0.05
    k, m = shell_quad_matrices(xyz, t, E, NU, RHO)
    assert k.shape == m.shape == (24, 24)
    np.testing.assert_allclose(k, k.T, rtol=0, atol=1e-12 * np.abs(k).max())
    np.testing.assert_allclose(m, m.T, rtol=0, atol=1e-15 * np.abs(m).max())

    eig = np.linalg.eigvalsh(k)
    rel = eig / eig[-1]
    assert np.sum(np.abs(rel) < 1e-10) == 6
    assert rel[6] > 1e-7  # the first flexible mode is far from round-off

    r = _rigid_modes(xyz)
    assert np.abs(k @ r).max() < 1e-10 * np.abs(k).max()

    eig_m = np.linalg.eigvalsh(m)
    assert eig_m[0] > 1e-6 * eig_m[-1]

    area = 0.5 * np.linalg.norm(np.cross(xyz[2] - xyz[0], xyz[3] - xyz[1]))
    for d in range(3):
        e_t = np.zeros(24)
        e_t[d::6] = 1.0
        np.testing.assert_allclose(e_t @ m @ e_t, RHO * t * area, rtol=1e-12)
        e_r = np.zeros(24)
        e_r[3 + d :: 6] = 1.0
        np.testing.assert_allclose(e_r @ m @ e_r, RHO * t**3 / 12.0 * area, rtol=1e-12)
    # Translations are not coupled to other directions or to rotations.
    ux = np.zeros(24)
    ux[0::6] = 1.0
    uy = np.zeros(24)
    uy[1::6] = 1.0
    assert abs(ux @ m @ uy) < 1e-14 * RHO * t * area


def test_reversed_node_order_is_the_same_element():
    xyz = _quad_in_3d(seed=4)
    k, m = shell_quad_matrices(xyz, 0.02, E, NU, RHO)
    order = [0, 3, 2, 1]  # clockwise about the original normal: the normal flips
    kr, mr = shell_quad_matrices(xyz[order], 0.02, E, NU, RHO)
    perm = (6 * np.array(order)[:, None] + np.arange(6)).ravel()
    np.testing.assert_allclose(kr, k[np.ix_(perm, perm)], rtol=0, atol=1e-9 * np.abs(k).max())
    np.testing.assert_allclose(mr, m[np.ix_(perm, perm)], rtol=0, atol=1e-12 * np.abs(m).max())


def test_one_call_is_fast():
    xyz = _quad_in_3d()
    shell_quad_matrices(xyz, 0.02, E, NU, RHO)
    n = 200
    start = time.perf_counter()
    for _ in range(n):
        shell_quad_matrices(xyz, 0.02, E, NU, RHO)
    per_call = (time.perf_counter() - start) / n
    assert per_call < 5e-3


# --------------------------------------------------------------------------- 2. free mesh
def test_free_plate_has_exactly_six_zero_modes():
    a, t = 1.0, 0.01
    xyz, quads = _plate_mesh(6, 6, a, a)
    # Distort the interior so that no mode is hidden by mesh regularity.
    interior = (xyz[:, 0] > 0) & (xyz[:, 0] < a) & (xyz[:, 1] > 0) & (xyz[:, 1] < a)
    rng = np.random.default_rng(7)
    xyz[interior, :2] += rng.uniform(-0.03, 0.03, size=(interior.sum(), 2))
    k, m = _assemble(xyz, quads, t)
    lam = scipy.linalg.eigh(k.toarray(), m.toarray(), eigvals_only=True)

    assert np.all(np.abs(lam[:6]) < 1e-6 * lam[6])
    # The 7th is the first free-free bending (twist) mode. Leissa (1969),
    # free square plate with nu = 0.3: omega a^2 sqrt(rho t / D) = 13.4728.
    omega_ref = 13.4728 * np.sqrt(_flexural_rigidity(t) / (RHO * t)) / a**2
    assert np.sqrt(lam[6]) == pytest.approx(omega_ref, rel=0.03)


def test_pure_one_point_drilling_would_leave_mechanisms():
    # Guards the reason for the drilling stabilisation: without it, the
    # zero-mean drilling patterns are mechanisms of the free mesh.
    xyz, quads = _plate_mesh(3, 3, 1.0, 1.0)
    k, _ = _assemble(xyz, quads, 0.05, drilling_stabilisation=1e-14)
    eig = np.linalg.eigvalsh(k.toarray())
    assert np.sum(eig < 1e-10 * eig[-1]) > 6
    k, _ = _assemble(xyz, quads, 0.05)
    eig = np.linalg.eigvalsh(k.toarray())
    assert np.sum(eig < 1e-10 * eig[-1]) == 6


def test_drilling_modes_are_far_above_the_bending_band():
    # 30 mm steel, a wheel-web-like thickness: stabilised drilling modes must
    # not pollute the band of interest (< 10 kHz) with spurious modes.
    t = 0.03
    xyz, quads = _plate_mesh(6, 6, 0.4, 0.4)
    xyz[:, :2] += 0.01 * np.sin(7.0 * xyz[:, :2])
    k, m = _assemble(xyz, quads, t)
    lam, vec = scipy.linalg.eigh(k.toarray(), m.toarray())
    md = m.toarray()
    rz = np.arange(5, k.shape[0], 6)
    drill_share = np.einsum("im,ij,jm->m", vec[rz], md[np.ix_(rz, rz)], vec[rz])
    f_drill = np.sqrt(lam[drill_share > 0.5]) / (2.0 * np.pi)
    assert f_drill.min() > 20e3


# --------------------------------------------------------------------------- patch tests
@pytest.mark.parametrize("state", ["membrane", "bending"])
def test_patch_test_on_distorted_mesh_in_3d(state):
    """Constant membrane strain (with a rigid in-plane rotation) or constant
    curvature imposed on the boundary of a distorted patch is reproduced
    exactly inside, including the drilling rotation theta_n = omega."""
    xyz2, quads = _plate_mesh(3, 3, 1.0, 1.0)
    interior = np.flatnonzero((xyz2[:, 0] > 0) & (xyz2[:, 0] < 1) & (xyz2[:, 1] > 0) & (xyz2[:, 1] < 1))
    xyz2[interior, :2] += np.random.default_rng(2).uniform(-0.12, 0.12, size=(len(interior), 2))
    x, y = xyz2[:, 0], xyz2[:, 1]
    local = np.zeros((len(xyz2), 6))
    if state == "membrane":
        b = np.array([[1.0e-3, -4.0e-4], [7.0e-4, -3.0e-4]])  # u = b x: strain + rotation
        local[:, :2] = xyz2[:, :2] @ b.T
        local[:, 5] = 0.5 * (b[1, 0] - b[0, 1])
    else:
        kx, ky, kxy = 2.0e-3, -1.0e-3, 1.5e-3
        local[:, 2] = 0.5 * kx * x**2 + 0.5 * ky * y**2 + 0.5 * kxy * x * y
        local[:, 3] = ky * y + 0.5 * kxy * x  # theta_x = dw/dy
        local[:, 4] = -(kx * x + 0.5 * kxy * y)  # theta_y = -dw/dx
    rot = _rotation(8)
    exact = np.hstack([local[:, :3] @ rot.T, local[:, 3:] @ rot.T]).ravel()
    k, _ = _assemble(xyz2 @ rot.T, quads, 0.05)

    inner = (6 * interior[:, None] + np.arange(6)).ravel()
    bound = np.setdiff1d(np.arange(k.shape[0]), inner)
    kd = k.toarray()
    u_inner = np.linalg.solve(kd[np.ix_(inner, inner)], -kd[np.ix_(inner, bound)] @ exact[bound])
    np.testing.assert_allclose(u_inner, exact[inner], rtol=0, atol=1e-9 * np.abs(exact).max())


# --------------------------------------------------------------------------- 3. thin SS plate
def test_thin_simply_supported_plate_converges_to_kirchhoff():
    a, t = 1.0, 0.01
    omega_unit = np.pi**2 / a**2 * np.sqrt(_flexural_rigidity(t) / (RHO * t))
    ref = omega_unit * np.array([2.0, 5.0, 5.0])  # (1,1), (1,2), (2,1)
    errors = []
    for n in (4, 8, 16):
        xyz, quads = _plate_mesh(n, n, a, a)
        k, m = _assemble(xyz, quads, t)
        w = _lowest_frequencies(k, m, _simply_supported_dofs(xyz, a, hard=False), 3)
        assert w[2] == pytest.approx(w[1], rel=1e-6)  # symmetric mesh: (1,2) and (2,1) degenerate
        errors.append(np.abs(w / ref - 1.0))
    errors = np.array(errors)
    # Measured: (1,1) 7.2 %, 1.7 %, 0.32 %; (1,2) 31.9 %, 6.5 %, 1.4 %.
    assert np.all(np.diff(errors, axis=0) < 0)
    assert errors[-1, 0] < 0.01
    assert errors[-1, 1] < 0.02
    # Second-order convergence of the fundamental: error ratio ~4 per halving.
    assert errors[1, 0] / errors[2, 0] > 3.0


def test_no_shear_locking_in_the_thin_limit():
    a, n = 1.0, 8
    xyz, quads = _plate_mesh(n, n, a, a)
    fixed = _simply_supported_dofs(xyz, a, hard=False)
    err = []
    for t in (1e-2, 1e-4):
        k, m = _assemble(xyz, quads, t)
        w = _lowest_frequencies(k, m, fixed, 1)[0]
        err.append(w / (2.0 * np.pi**2 / a**2 * np.sqrt(_flexural_rigidity(t) / (RHO * t))) - 1.0)
    # A locking element would be orders of magnitude too stiff at t/a = 1e-4.
    assert abs(err[1]) < 0.02
    assert abs(err[1] - err[0]) < 1e-3


# --------------------------------------------------------------------------- 4. thick SS plate
def _mindlin_navier_frequencies(a: float, t: float, kappa: float, m: int = 1, n: int = 1) -> np.ndarray:
    """Roots of Mindlin's frequency cubic for the hard simply supported plate.

    With ``w = W sin(al x) sin(be y)``, ``psi_x = X cos(al x) sin(be y)``,
    ``psi_y = Y sin(al x) cos(be y)`` the Mindlin (1951) plate equations reduce
    to ``(K3 - omega^2 M3) [W, X, Y] = 0``; ``det(K3 - omega^2 M3) = 0`` is the
    cubic in ``omega^2``, whose three roots are the flexural, thickness-shear
    and thickness-twist frequencies of the (m, n) wave.
    """
    d = _flexural_rigidity(t)
    s = kappa * G * t
    al, be = m * np.pi / a, n * np.pi / a
    k2 = al**2 + be**2
    k3 = np.array(
        [
            [s * k2, s * al, s * be],
            [s * al, 0.5 * d * ((1 - NU) * k2 + (1 + NU) * al**2) + s, 0.5 * d * (1 + NU) * al * be],
            [s * be, 0.5 * d * (1 + NU) * al * be, 0.5 * d * ((1 - NU) * k2 + (1 + NU) * be**2) + s],
        ]
    )
    m3 = np.diag([RHO * t, RHO * t**3 / 12.0, RHO * t**3 / 12.0])
    return np.sqrt(scipy.linalg.eigh(k3, m3, eigvals_only=True))


def test_thick_simply_supported_plate_matches_mindlin():
    """Fundamental frequency at t/a = 0.1 for both usual shear factors.

    The reference is the lowest root of Mindlin's cubic, which is exact for the
    hard simple support (rotation about the edge normal restrained). The soft
    support has a boundary layer and a different (lower) frequency.
    """
    a, t = 1.0, 0.1
    omega_kirchhoff = 2.0 * np.pi**2 / a**2 * np.sqrt(_flexural_rigidity(t) / (RHO * t))
    xyz, quads = _plate_mesh(16, 16, a, a)
    fixed = _simply_supported_dofs(xyz, a, hard=True)
    fe, ref = [], []
    for kappa in (5.0 / 6.0, np.pi**2 / 12.0):
        omega_ref = _mindlin_navier_frequencies(a, t, kappa)[0]
        # Shear and rotary inertia must matter at t/a = 0.1, else the test is moot.
        assert omega_ref < 0.97 * omega_kirchhoff
        k, m = _assemble(xyz, quads, t, shear_factor=kappa)
        w = _lowest_frequencies(k, m, fixed, 1)[0]
        # Measured: +0.41 % for both shear factors.
        assert w == pytest.approx(omega_ref, rel=0.015)
        fe.append(w)
        ref.append(omega_ref)
    # The two references differ by only 0.03 %; the discretisation error
    # cancels in the ratio, so this checks that shear_factor is really used.
    assert fe[0] / fe[1] == pytest.approx(ref[0] / ref[1], rel=3e-5)


# --------------------------------------------------------------------------- 5. invariance
def test_frequencies_invariant_under_rigid_rotation_of_the_mesh():
    xyz, quads = _plate_mesh(3, 3, 1.0, 0.8)
    rng = np.random.default_rng(3)
    xyz[:, :2] += rng.uniform(-0.05, 0.05, size=(len(xyz), 2))
    k, m = _assemble(xyz, quads, 0.05)
    lam = scipy.linalg.eigh(k.toarray(), m.toarray(), eigvals_only=True)

    moved = xyz @ _rotation(11).T + np.array([0.3, -1.2, 2.0])
    k2, m2 = _assemble(moved, quads, 0.05)
    lam2 = scipy.linalg.eigh(k2.toarray(), m2.toarray(), eigvals_only=True)

    np.testing.assert_allclose(lam2[6:], lam[6:], rtol=1e-9)
    assert np.all(np.abs(lam2[:6]) < 1e-8 * lam[6])


# --------------------------------------------------------------------------- 6. in-plane cantilever
def _cantilever_tip_deflection(drilling_ratio: float = 1.0) -> tuple[float, float]:
    length, height, t, p = 1.0, 0.1, 0.02, 1.0e3
    nx, ny = 80, 8
    xyz, quads = _plate_mesh(nx, ny, length, height)
    rot = _rotation(5)
    k, _ = _assemble(xyz @ rot.T, quads, t, drilling_ratio=drilling_ratio)

    root = np.flatnonzero(np.isclose(xyz[:, 0], 0.0))
    tip = np.flatnonzero(np.isclose(xyz[:, 0], length))
    fixed = (6 * root[:, None] + np.arange(6)).ravel()
    free = np.setdiff1d(np.arange(k.shape[0]), fixed)

    # Uniform shear traction on the tip edge, consistent nodal loads, along
    # the strip's (rotated) height direction.
    weights = np.where(np.isclose(xyz[tip, 1], 0.0) | np.isclose(xyz[tip, 1], height), 0.5, 1.0) / ny
    direction = rot[:, 1]
    f = np.zeros(k.shape[0])
    for node, wgt in zip(tip, weights):
        f[6 * node : 6 * node + 3] = p * wgt * direction
    u = np.zeros(k.shape[0])
    u[free] = spla.spsolve(k[free][:, free].tocsc(), f[free])
    tip_u = u[(6 * tip[:, None] + np.arange(3)).ravel()].reshape(-1, 3)
    deflection = float(np.mean(tip_u @ direction))

    inertia = t * height**3 / 12.0
    area = t * height
    timoshenko = p * length**3 / (3.0 * E * inertia) + p * length / (5.0 / 6.0 * G * area)
    return deflection, timoshenko


def test_inplane_cantilever_matches_timoshenko_beam():
    deflection, reference = _cantilever_tip_deflection()
    # Measured: -1.1 % (bilinear parasitic shear and the fully clamped root).
    assert deflection == pytest.approx(reference, rel=0.03)
    # The drilling penalty itself adds little stiffness: a 1000x weaker
    # penalty changes the tip deflection by well under 1 %.
    weak, _ = _cantilever_tip_deflection(drilling_ratio=1e-3)
    assert deflection == pytest.approx(weak, rel=0.005)


# --------------------------------------------------------------------------- 7. errors
def _square(z3: float = 0.0) -> np.ndarray:
    return np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, z3], [0.0, 1.0, 0.0]])


def test_warped_element_is_rejected_with_tolerance_in_message():
    diag = np.sqrt(2.0)
    # z3 moves each node z3/4 off the mean plane.
    ok = 4.0 * 0.5 * WARP_TOLERANCE * diag
    shell_quad_matrices(_square(ok), 0.01, E, NU, RHO)
    bad = 4.0 * 2.0 * WARP_TOLERANCE * diag
    with pytest.raises(ValueError, match=r"warped.*tolerance"):
        shell_quad_matrices(_square(bad), 0.01, E, NU, RHO)


def test_clockwise_element_is_rejected():
    xyz = _square()[[0, 3, 2, 1]]  # clockwise about +z
    with pytest.raises(ValueError, match="clockwise"):
        shell_quad_matrices(xyz, 0.01, E, NU, RHO, normal=[0.0, 0.0, 1.0])
    # Counter-clockwise ordering is accepted with the same intended normal.
    shell_quad_matrices(_square(), 0.01, E, NU, RHO, normal=[0.0, 0.0, 1.0])


@pytest.mark.parametrize(
    "xy, match",
    [
        ([[0, 0], [2, 0], [0.6, 0.6], [0, 2]], "Jacobian"),  # re-entrant (non-convex)
        ([[0, 0], [2, 0], [0, 1], [1.5, 1.5]], "Jacobian"),  # self-intersecting (bow tie)
        ([[0, 0], [1, 0], [2, 0], [3, 0]], "zero area"),  # collinear
        ([[0, 0], [0, 0], [1, 1], [0, 1]], "coincident"),  # collapsed side
    ],
    ids=["non-convex", "bow-tie", "zero-area", "collapsed"],
)
def test_bad_geometry_is_rejected(xy, match):
    xyz = np.column_stack([np.asarray(xy, float), np.zeros(4)])
    with pytest.raises(ValueError, match=match):
        shell_quad_matrices(xyz, 0.01, E, NU, RHO)


@pytest.mark.parametrize(
    "args, match",
    [
        ((0.0, E, NU, RHO), "thickness"),
        ((0.01, -E, NU, RHO), "Young"),
        ((0.01, E, 0.5, RHO), "Poisson"),
        ((0.01, E, -1.0, RHO), "Poisson"),
        ((0.01, E, NU, 0.0), "density"),
    ],
)
def test_bad_material_is_rejected(args, match):
    with pytest.raises(ValueError, match=match):
        shell_quad_matrices(_square(), *args)
