"""Modal model and structural modification against closed forms and an exact physical solution.

Oracles: (1) a rigid body on ground springs (bounce and roll frequencies and the point receptance in
closed form); (2) a lumped spring-mass system with its complete modal basis, modified by springs,
dampers and masses: the modal-coordinate solution must equal the direct physical solve
(K + iΩC − Ω²M)⁻¹ to rounding, because nothing is truncated.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from fem_import.modes import FEModes
from receptance.dofs import DofError, Point, shifted_point
from receptance.modal_model import ModalModel, ModelError
from receptance.modification import GroundSprings, PointMass, PrimarySuspension, Spring
from receptance.pole_residue import PoleResidues

MASS, IX, IY, IZ, B = 1200.0, 700.0, 150.0, 700.0, 0.97


def rigid_body_model(points=None) -> ModalModel:
    """Six mass-normalised rigid-body modes of one body (centre node 1, end nodes 2 and 3 at y = ∓B)."""
    xyz = np.array([[0, 0, 0], [0, -B, 0], [0, B, 0]], float)
    shapes = np.zeros((6, 3, 6))
    for k in range(3):
        shapes[k, :, k] = 1 / np.sqrt(MASS)
    for k, inertia in zip(range(3), (IX, IY, IZ)):
        theta = np.zeros(3)
        theta[k] = 1 / np.sqrt(inertia)
        shapes[3 + k, :, 3:] = theta
        shapes[3 + k, :, :3] = np.cross(theta, xyz)
    fe = FEModes(np.array([1, 2, 3]), xyz, (), np.zeros(6), shapes, np.ones(6), source="rigid body")
    pts = points or {"axlebox_L": Point("axlebox_L", 2), "axlebox_R": Point("axlebox_R", 3),
                     "centre": Point("centre", 1)}
    return ModalModel(fe, np.zeros(6), np.zeros(6), ("rigid",) * 6, np.arange(1, 7), np.full(6, np.nan), points=pts)


def test_bounce_and_roll_of_a_rigid_body_on_springs_match_the_closed_form():
    k, c = 1.0e6, 11e3
    model = rigid_body_model().with_modification(GroundSprings(stiffness=(0, 0, k), damping=(0, 0, c)))
    modes = model.modes()
    # bounce: m s² + 2c s + 2k = 0; roll about x: Ix s² + 2c B² s + 2k B² = 0
    expected = sorted([np.roots([MASS, 2 * c, 2 * k]), np.roots([IX, 2 * c * B**2, 2 * k * B**2])],
                      key=lambda r: abs(r[0]))
    for (_, row), roots in zip(modes.iterrows(), expected):
        lam = roots[np.argmax(roots.imag)]
        assert row.f_hz == pytest.approx(abs(lam) / (2 * np.pi), rel=1e-10)
        assert row.zeta == pytest.approx(-lam.real / abs(lam), rel=1e-9)
    assert len(modes) == 2  # the other four rigid motions stay unrestrained (mass lines, not poles)
    f = np.array([0.7, 3.0, 6.5, 9.0, 40.0])
    s = 2j * np.pi * f
    H = model.receptance("axlebox_L:z", "axlebox_L:z", f).data[0, 0]
    closed = 1 / (MASS * s**2 + 2 * c * s + 2 * k) + B**2 / (IX * s**2 + 2 * c * B**2 * s + 2 * k * B**2)
    np.testing.assert_allclose(H, closed, rtol=1e-10)


def test_unrestrained_rigid_motion_gives_the_mass_line():
    model = rigid_body_model()
    f = np.array([1.0, 10.0])
    H = model.receptance(["axlebox_L:z", "axlebox_L:x"], ["axlebox_R:z"], f).data[:, 0]
    s2 = (2j * np.pi * f) ** 2
    # vertical force at the right end: translation 1/m, roll about x brings -B·B/Ix at the left end
    np.testing.assert_allclose(H[0], (1 / MASS - B * B / IX) / s2, rtol=1e-12)
    np.testing.assert_allclose(H[1], 0.0, atol=1e-18)
    with pytest.raises(ValueError, match="0 Hz"):
        model.receptance("axlebox_L:z", None, [0.0, 1.0])


def _chain(n=7, seed=3):
    """A free lumped chain along y moving in z: masses m_i, springs k_i between neighbours."""
    rng = np.random.default_rng(seed)
    m = rng.uniform(20, 80, n)
    k = rng.uniform(2e6, 8e6, n - 1)
    K = np.zeros((n, n))
    for i, ki in enumerate(k):
        K[np.ix_([i, i + 1], [i, i + 1])] += ki * np.array([[1, -1], [-1, 1]])
    M = np.diag(m)
    w2, phi = scipy.linalg.eigh(K, M)
    w2[0] = 0.0  # the free chain's rigid translation
    xyz = np.column_stack([np.zeros(n), np.linspace(-1, 1, n), np.zeros(n)])
    shapes = np.zeros((n, n, 6))
    shapes[:, :, 2] = phi.T
    fe = FEModes(np.arange(1, n + 1), xyz, (), np.sqrt(np.abs(w2)) / (2 * np.pi), shapes, np.ones(n))
    points = {f"p{i}": Point(f"p{i}", i + 1) for i in range(n)}
    f = fe.freqs_hz
    model = ModalModel(fe, f, np.zeros(n), ("rigid",) + ("fe",) * (n - 1), np.arange(1, n + 1), np.full(n, np.nan),
                       points=points)
    return model, M, K


def test_modification_in_modal_coordinates_equals_the_physical_solution_with_a_complete_basis():
    model, M, K = _chain()
    n = M.shape[0]
    mods = [GroundSprings(points=("p1", "p5"), stiffness=(0, 0, 3e6), damping=(0, 0, 4e3)),
            Spring(a="p0:z", b="p6:z", stiffness=1e6, damping=500.0),
            PointMass(point="p3", mass=15.0),
            Spring(a="p2:z", stiffness=2e5, loss_factor=0.1)]
    Mp, Cp, Kp = M.copy(), np.zeros((n, n)), K.astype(complex)
    for i in (1, 5):
        Kp[i, i] += 3e6
        Cp[i, i] += 4e3
    e = np.zeros(n)
    e[0], e[6] = 1, -1
    Kp += 1e6 * np.outer(e, e)
    Cp += 500.0 * np.outer(e, e)
    Mp[3, 3] += 15.0
    Kp[2, 2] += 2e5 * (1 + 0.1j)
    for mod in mods:
        model = model.with_modification(mod)
    f = np.linspace(5, 1500, 301)
    w = 2 * np.pi * f
    direct = np.linalg.inv(Kp[None] + 1j * w[:, None, None] * Cp[None] - w[:, None, None] ** 2 * Mp[None])
    labels = [f"p{i}:z" for i in range(n)]
    H = model.receptance(labels, labels, f).data
    np.testing.assert_allclose(H, np.moveaxis(direct, 0, 2), rtol=1e-8, atol=1e-8 * np.abs(direct).max())
    # the system's natural frequencies are those of the modified physical system
    lam = scipy.linalg.eigvals(np.block([[np.zeros((n, n)), np.eye(n)],
                                         [-np.linalg.solve(Mp, Kp), -np.linalg.solve(Mp, Cp)]]))
    expected = np.sort(np.abs(lam[lam.imag > 0])) / (2 * np.pi)
    np.testing.assert_allclose(model.modes()["f_hz"].to_numpy(), expected, rtol=1e-9)


def test_untouched_modes_stay_closed_form_terms_and_agree_with_the_modal_sum():
    model, _, _ = _chain()
    f = np.linspace(5, 800, 50)
    direct = PoleResidues.from_modes(model.freqs_hz, model.zeta, model.rows(["p2:z"])[:, :7],
                                     model.rows(["p4:z"])[:, :7], ["a"], ["b"]).evaluate(f).data
    np.testing.assert_allclose(model.receptance("p2:z", "p4:z", f).data, direct, rtol=1e-12)


def test_offset_points_see_the_node_rotations_through_the_lever_arm():
    model = rigid_body_model()
    base = model.points["axlebox_L"]
    base = Point(base.name, base.fe_node, (0.0, -B, 0.0))
    shifted = [shifted_point(base, (dx, 0, 0)) for dx in (-0.05, -0.03, -0.01, 0.01, 0.03, 0.05)]
    contact = Point("contact_L", 2, (0.0, -B, -0.41))
    m = model.with_points([base, contact, *shifted]).with_modification(PrimarySuspension())
    f = np.linspace(2, 30, 15)
    # a longitudinal force at the contact point pitches the wheelset (about y) through its 0.41 m lever
    ref = m.receptance(["axlebox_L:z", "axlebox_L:ry"], ["contact_L:x"], f).data[:, 0]
    for p in shifted:
        dx = p.xyz[0] - base.xyz[0]
        h = m.receptance([f"{p.name}:z"], ["contact_L:x"], f).data[0, 0]
        # u_z(p) = u_z + (θ × r)_z = u_z − dx θ_y for r = (dx, 0, 0)
        np.testing.assert_allclose(h, ref[0] - dx * ref[1], rtol=1e-10, atol=1e-20)
    assert np.abs(ref[1]).max() > 0


def test_thesis_numbers_and_names_address_the_same_dofs():
    model = rigid_body_model({"contact_L": Point("contact_L", 2, (0, -B, -0.41)), "axlebox_L": Point("axlebox_L", 2),
                              "contact_R": Point("contact_R", 3, (0, B, -0.41)), "axlebox_R": Point("axlebox_R", 3)})
    f = np.array([3.0, 30.0])
    a = model.receptance([3, 6, 12], [3, 9], f).data
    b = model.receptance(["contact_L:z", "axlebox_L:z", "axlebox_R:z"], ["contact_L:z", "contact_R:z"], f).data
    np.testing.assert_array_equal(a, b)
    # reciprocity of the model
    h = model.receptance(["contact_L:y", "axlebox_R:z"], ["contact_L:y", "axlebox_R:z"], f).data
    np.testing.assert_allclose(h[0, 1], h[1, 0], rtol=1e-12)


def test_bad_specifications_name_what_is_wrong():
    model = rigid_body_model()
    with pytest.raises(DofError, match="unknown point 'wheel'"):
        model.receptance("wheel:z", None, [10.0])
    with pytest.raises(DofError, match="1–12"):
        model.receptance(13, None, [10.0])
    with pytest.raises(DofError, match="point:axis"):
        model.receptance("axlebox_L-z", None, [10.0])
    with pytest.raises(ModelError, match="damping ratio"):
        model.with_modal_parameters(zeta=np.full(6, 1.5))
    with pytest.raises(ValueError, match="stiffness must be finite"):
        GroundSprings(stiffness=(0, -1, 0))
    with pytest.raises(ModelError, match="expected a Modification"):
        model.with_modification("suspension")
