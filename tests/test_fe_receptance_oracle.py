"""Oracles for the FE receptance oracle (tests/fe_receptance_oracle.py).

What each test checks, against what:

* reciprocity ``H_ij = H_ji`` (Maxwell–Betti) of the direct solve, to 1e-9 of
  the largest entry at each frequency, 1–500 Hz, free-free and in service;
* free-free mass line at 0.5 Hz: the 12 × 12 receptance equals the rigid-body
  mass line ``-g_i^T M_rb^{-1} g_j / Ω²`` built from total mass (checked
  against Table 2.1: 283 + 2·251 + 2·135 + 2·78 = 1211 kg), centre of mass and
  inertia tensor, to 1e-3 (the elastic modes, ≥ 71.5 Hz, contribute
  ~(0.5/71.5)² ≈ 5e-5 of it; measured 4e-6 … 2.6e-4 on the diagonal, the
  largest at contact:y where the wheel web's axial flexibility adds);
* in-service static/low-frequency limit at 0.01 Hz: unit loads at both
  axlebox centres in phase (x, y, z) and in anti-phase (z: roll, x: yaw) give
  per side ``1 / (k + iΩc − Ω² m_eff)`` with k, c of one axlebox (Table 2.1:
  k_z = 2 × 0.5 MN/m, c_z = 11 kN s/m, …) and m_eff = m/2 or J/b²; the force
  acts where the spring acts, so the structure does not deform statically;
  tolerance 1e-5 relative (elastic corrections ≈ (0.01/6.4)² ≈ 2e-6; the
  damper term is ≈ 7e-4 of the response, so the damper values are checked to
  ~1.5 %);
* power balance in service: ``-Im H_jj = Ω Σ_dampers c |H_(box, j)|²``, to
  1e-8, i.e. the dampers sit on the right DOFs with the right values;
* complete modal sum: ALL 1890 modes of the reduced free-free (and undamped
  in-service) model from ``lab_data.fe_model.solve_modes`` with the point
  kinematics of ``lab_data.sensors.shape_matrix`` (the code that writes the
  campaign's truth) reproduce the direct solve to 1e-7 (in service 2e-7) of
  the largest entry, including the stiffness-proportional damping (modal
  ζ_r = ζ f_r / f_ref);
* the in-service eigenfrequencies: bounce 6.43 Hz, roll 9.00 Hz (lab
  documentation), within 1 % of the rigid-body hand calculation, and the
  undamped direct solve changes sign across them.
"""

import numpy as np
import pytest

from fe_receptance_oracle import (
    THESIS_DOFS,
    OracleInputError,
    fe_eigenfrequencies_in_service,
    fe_receptance,
    read_points,
    reduced_system,
    rigid_body_mass_matrix,
)
from lab_data.fe_model import solve_modes
from lab_data.sensors import shape_matrix
from lab_data.wheelset import SuspensionParameters

DOFS = [THESIS_DOFS[i] for i in range(1, 13)]
SUSP = SuspensionParameters()
B_BOX = 0.97  # axlebox centre |y| [m] (points.csv)


@pytest.fixture(scope="module")
def points(control_dir):
    return control_dir / "points.csv"


def _rel_sym_error(H):
    return np.max(np.abs(H - H.transpose(1, 0, 2)), axis=(0, 1)) / np.max(np.abs(H), axis=(0, 1))


@pytest.mark.parametrize("in_service,zeta", [(False, 0.0), (True, 0.0), (True, 0.01)])
def test_reciprocity(points, in_service, zeta):
    f = np.geomspace(1.0, 500.0, 40)
    H = fe_receptance(points, DOFS, f, in_service=in_service, structural_zeta=zeta)
    err = _rel_sym_error(H)
    assert err.max() < 1e-9, f"worst at {f[np.argmax(err)]:.2f} Hz: {err.max():.2e}"


def test_total_mass_matches_table_2_1():
    mass, centre, J = rigid_body_mass_matrix()
    assert mass == pytest.approx(283 + 2 * 251 + 2 * 135 + 2 * 78, rel=1e-9)
    assert np.allclose(centre, 0.0, atol=1e-12)  # symmetric wheelset
    assert np.allclose(J, np.diag(np.diag(J)), atol=1e-9 * J.max())
    assert J[0, 0] == pytest.approx(J[2, 2], rel=1e-9)  # axisymmetric about y


def _rigid_rows(points_path, dofs, centre):
    """g_j: displacement of DOF j per rigid motion (tx, ty, tz, rx, ry, rz about ``centre``)."""
    pts = read_points(points_path)
    G = np.zeros((len(dofs), 6))
    for j, lab in enumerate(dofs):
        name, axis = lab.split(":")
        e = np.eye(3)["xyz".index(axis)]
        r = pts[name][1] - centre
        G[j, :3] = e
        G[j, 3:] = np.cross(r, e)  # e . (theta x r) = theta . (r x e)
    return G


def test_free_free_low_frequency_is_the_rigid_body_mass_line(points):
    f = 0.5
    w = 2 * np.pi * f
    mass, centre, J = rigid_body_mass_matrix()
    Mrb = np.zeros((6, 6))
    Mrb[:3, :3] = mass * np.eye(3)
    Mrb[3:, 3:] = J
    G = _rigid_rows(points, DOFS, centre)
    H_rb = -(G @ np.linalg.solve(Mrb, G.T)) / w**2
    H = fe_receptance(points, DOFS, [f], in_service=False)[:, :, 0]
    # axlebox vertical point receptance, the brief's headline number (1 % asked; 1e-3 asserted)
    i = DOFS.index("axlebox_L:z")
    assert H[i, i].real == pytest.approx(H_rb[i, i], rel=1e-3)
    assert abs(H[i, i].imag) < 1e-12 * abs(H[i, i])
    # whole 12 x 12 matrix, relative to its largest entry
    assert np.max(np.abs(H - H_rb)) < 1e-3 * np.max(np.abs(H_rb))


def test_in_service_low_frequency_limit_on_the_suspension(points):
    f = 0.01
    w = 2 * np.pi * f
    dofs = ["axlebox_L:x", "axlebox_L:y", "axlebox_L:z", "axlebox_R:x", "axlebox_R:y", "axlebox_R:z"]
    H = fe_receptance(points, dofs, [f], in_service=True)[:, :, 0]
    mass, _, J = rigid_body_mass_matrix()
    k, c = SUSP.stiffness, SUSP.damping
    for a in range(3):
        # in phase: displacement of the left box under unit loads on both boxes
        in_phase = H[a, a] + H[a, 3 + a]
        expect = 1.0 / (k[a] + 1j * w * c[a] - w**2 * mass / 2)
        assert abs(in_phase / expect - 1) < 1e-5, f"in phase along {'xyz'[a]}"
        assert in_phase.real == pytest.approx(1.0 / k[a], rel=1e-5)  # the static limit F/k per side
    # anti-phase z: roll about x; anti-phase x: yaw about z (lever arm b on both boxes)
    for a, Jaxis in ((2, J[0, 0]), (0, J[2, 2])):
        anti = H[a, a] - H[a, 3 + a]
        expect = 1.0 / (k[a] + 1j * w * c[a] - w**2 * Jaxis / B_BOX**2)
        assert abs(anti / expect - 1) < 1e-5, f"anti-phase along {'xyz'[a]}"


def test_in_service_power_balance_checks_the_dampers(points):
    dofs = DOFS
    box = {"axlebox_L": 3, "axlebox_R": 9}  # index of the box's x DOF in DOFS
    f = np.array([3.0, 6.43, 9.0, 50.0, 220.0])
    H = fe_receptance(points, dofs, f, in_service=True)
    c = np.asarray(SUSP.damping)
    for k, fk in enumerate(f):
        w = 2 * np.pi * fk
        dissipated = np.zeros(len(dofs))
        for i0 in box.values():
            dissipated += w * (c[:, None] * np.abs(H[i0:i0 + 3, :, k]) ** 2).sum(axis=0)
        lhs = -np.diag(H[:, :, k]).imag
        assert np.max(np.abs(lhs - dissipated)) < 1e-8 * np.max(np.abs(lhs)), f"{fk} Hz"
        assert np.all(lhs > 0)


def _modal_sum(model_modes, model, points_path, dofs, f, zeta_of):
    pts = read_points(points_path)
    nodes, pos, dirs = [], [], []
    for lab in dofs:
        name, axis = lab.split(":")
        nodes.append(pts[name][0])
        pos.append(pts[name][1])
        dirs.append(np.eye(3)["xyz".index(axis)])
    b = shape_matrix(model, model_modes.shapes, nodes, np.array(pos), np.array(dirs))  # (n_dof, m)
    wr = 2 * np.pi * model_modes.freqs_hz
    H = np.empty((len(dofs), len(dofs), len(f)), complex)
    for k, fk in enumerate(f):
        w = 2 * np.pi * fk
        den = wr**2 - w**2 + 2j * zeta_of(model_modes.freqs_hz) * wr * w
        H[:, :, k] = (b / den) @ b.T
    return H


@pytest.fixture(scope="module")
def all_modes_free():
    rs = reduced_system(False)
    modes = solve_modes(rs.model, rs.system, 1e7)
    assert len(modes.freqs_hz) == rs.n_dof == 1890  # a complete basis
    return rs.model, modes


@pytest.mark.parametrize("zeta", [0.0, 0.02])
def test_free_free_equals_complete_modal_sum(points, all_modes_free, zeta):
    model, modes = all_modes_free
    f_ref = 100.0
    f = np.array([2.0, 30.0, 71.0, 150.0, 221.0, 400.0])
    H = fe_receptance(points, DOFS, f, in_service=False, structural_zeta=zeta, structural_zeta_ref_hz=f_ref)
    Hm = _modal_sum(modes, model, points, DOFS, f, lambda fr: zeta * fr / f_ref)
    err = np.max(np.abs(H - Hm), axis=(0, 1)) / np.max(np.abs(Hm), axis=(0, 1))
    assert err.max() < 1e-7, dict(zip(f, err))


def test_undamped_in_service_equals_complete_modal_sum(points):
    undamped = SuspensionParameters(damping=(0.0, 0.0, 0.0))
    rs = reduced_system(True, suspension=undamped)
    modes = solve_modes(rs.model, rs.system, 1e7)
    assert len(modes.freqs_hz) == rs.n_dof
    f = np.array([1.0, 5.0, 8.0, 20.0, 100.0, 300.0])
    H = fe_receptance(points, DOFS, f, in_service=True, suspension=undamped)
    Hm = _modal_sum(modes, rs.model, points, DOFS, f, lambda fr: 0.0 * fr)
    err = np.max(np.abs(H - Hm), axis=(0, 1)) / np.max(np.abs(Hm), axis=(0, 1))
    # measured <= 4e-8 at 5 and 8 Hz (beside the undamped bounce and roll resonances); at 1 Hz, in the
    # quasi-static range of the stiff in-service system, round-off depends on BLAS's summation order:
    # 1e-8 with threaded BLAS, 4.7e-7 with one thread (the suite's workers). A modelling difference
    # would show at 1e-3 and above.
    assert err.max() < 1e-6, dict(zip(f, err))


def test_in_service_eigenfrequencies(points):
    modes = fe_eigenfrequencies_in_service(10)
    assert modes.labels[:6] == ("spin", "bounce", "roll", "lateral", "longitudinal", "yaw")
    assert modes.freqs_hz[0] < 1e-3
    bounce, roll = modes.freqs_hz[1], modes.freqs_hz[2]
    assert bounce == pytest.approx(6.43, abs=0.01) and roll == pytest.approx(9.00, abs=0.01)
    mass, _, J = rigid_body_mass_matrix()
    kz = SUSP.stiffness[2]
    assert bounce == pytest.approx(np.sqrt(2 * kz / mass) / (2 * np.pi), rel=0.01)
    assert roll == pytest.approx(np.sqrt(2 * kz * B_BOX**2 / J[0, 0]) / (2 * np.pi), rel=0.01)
    assert all(lab == "elastic" for lab in modes.labels[6:]) and modes.freqs_hz[6] > 70.0
    # the undamped direct solve resonates there: the in-phase (bounce) response changes sign
    undamped = SuspensionParameters(damping=(0.0, 0.0, 0.0))
    d = ["axlebox_L:z", "axlebox_R:z"]
    H = fe_receptance(points, d, [bounce - 1e-3, bounce + 1e-3], in_service=True, suspension=undamped)
    s = (H[0, 0] + H[0, 1]).real
    assert s[0] > 0 > s[1] and np.min(np.abs(s)) > 100 / kz


def test_points_as_dict_equal_points_file(points):
    pts = read_points(points)
    f = [40.0]
    a = fe_receptance(points, [1, 3, 6], f, in_service=True)
    b = fe_receptance(pts, ["contact_L:x", "contact_L:z", "axlebox_L:z"], f, in_service=True)
    assert np.array_equal(a, b)
    # the contact point is 30 mm outboard and 27.5 mm below its rim node: the offset matters
    moved = dict(pts, contact_L=(pts["contact_L"][0], pts["contact_L"][1] + np.array([0.0, 0.03, 0.0275])))
    c = fe_receptance(moved, ["contact_L:x"], f, in_service=True)
    assert abs(c[0, 0, 0] / a[0, 0, 0] - 1) > 1e-3


@pytest.mark.parametrize(
    "kwargs,match",
    [
        (dict(dofs=["axlebox_L:z"], freqs_hz=[0.0, 10.0]), "> 0 Hz"),
        (dict(dofs=["axlebox_L:w"], freqs_hz=[10.0]), "point:x\\|y\\|z"),
        (dict(dofs=["axle_L:z"], freqs_hz=[10.0]), "unknown point 'axle_L'"),
        (dict(dofs=[13], freqs_hz=[10.0]), "1-12"),
        (dict(dofs=["axlebox_L:z", 6], freqs_hz=[10.0]), "twice"),
    ],
)
def test_bad_input_is_named(points, kwargs, match):
    with pytest.raises(OracleInputError, match=match):
        fe_receptance(points, in_service=False, **kwargs)


def test_unknown_node_and_missing_file(tmp_path):
    with pytest.raises(OracleInputError, match="FE node 99"):
        fe_receptance({"p": (99, (0, 0, 0))}, ["p:z"], [10.0], in_service=False)
    with pytest.raises(OracleInputError, match="does not exist"):
        fe_receptance(tmp_path / "points.csv", ["p:z"], [10.0], in_service=False)
