"""The ANSYS result file reader (:mod:`fem_import.ansys_rst`) on a real MAPDL 15.0 modal result.

The file is the one ansys-mapdl-reader ships (``examples.rstfile``): a 1 x 1 x 5 in titanium beam of 40 SOLID186
20-node bricks, 321 nodes, six modes from 7366 Hz, written without ``/UNITS``. The oracle of the shapes is
independent of the file's solver: the consistent mass matrix of the same mesh, assembled here from the 20-node
serendipity brick's shape functions (3 x 3 x 3 Gauss points, ANSYS's full integration) and the file's density.
Mass-normalised shapes in SI, with the coordinates and density converted to SI, give ``Phi^T M Phi = I``.
"""

from __future__ import annotations

import logging

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import fem_import
from fem_import import ansys_rst
from fem_import.modes import UNIT_SYSTEMS

reader = pytest.importorskip("ansys.mapdl.reader")
RST = reader.examples.rstfile

# the 20-node brick (SOLID186): corners I..P, then mid-sides of IJ JK KL LI, MN NO OP PM, IM JN KO LP
_CORNERS = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
                     [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], float)
_MIDS = np.array([[0, -1, -1], [1, 0, -1], [0, 1, -1], [-1, 0, -1], [0, -1, 1], [1, 0, 1], [0, 1, 1], [-1, 0, 1],
                  [-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
_NATURAL = np.vstack([_CORNERS, _MIDS])


def _hex20(x):
    """Shape functions (20,) and their natural derivatives (20, 3) of the serendipity brick at ``x``."""
    n, d = np.empty(20), np.empty((20, 3))
    for i, p in enumerate(_NATURAL):
        a = 1 + p * x
        if i < 8:
            s = float(p @ x) - 2
            n[i] = a.prod() * s / 8
            for k in range(3):
                others = [j for j in range(3) if j != k]
                d[i, k] = p[k] * a[others].prod() * (s + a[k]) / 8
        else:
            z = int(np.flatnonzero(p == 0)[0])
            others = [j for j in range(3) if j != z]
            n[i] = (1 - x[z] ** 2) * a[others].prod() / 4
            d[i, z] = -x[z] * a[others].prod() / 2
            for k in others:
                m = [j for j in others if j != k][0]
                d[i, k] = p[k] * (1 - x[z] ** 2) * a[m] / 4
    return n, d


def _consistent_mass(fe, result, density):
    """Node-major 3-DOF consistent mass matrix of the file's SOLID186 mesh on ``fe``'s nodes and coordinates."""
    g, w = np.polynomial.legendre.leggauss(3)
    points = [(np.array([a, b, c]), wa * wb * wc) for a, wa in zip(g, w) for b, wb in zip(g, w)
              for c, wc in zip(g, w)]
    row = {n: k for k, n in enumerate(fe.node_ids.tolist())}
    mass = np.zeros((fe.node_ids.size,) * 2)
    for element in result.mesh.elem:
        idx = [row[int(v)] for v in element[10:30]]
        xyz = fe.xyz[idx]
        m = np.zeros((20, 20))
        for x, weight in points:
            n, d = _hex20(x)
            m += density * np.outer(n, n) * np.linalg.det(d.T @ xyz) * weight
        mass[np.ix_(idx, idx)] += m
    return np.kron(mass, np.eye(3))


@pytest.fixture(scope="module")
def result():
    return reader.read_binary(RST)


@pytest.fixture(scope="module")
def fe():
    return fem_import.read(RST)


def test_the_real_file_is_sniffed_and_read_with_its_units_inferred(fe, result):
    """Recognised by content (not only by name); the six modes with the file's substep numbers; the unit system
    (no /UNITS in the file) inferred from the titanium's DENS 4.14e-4 and EX 1.69e7: in-lbf-s puts them at
    4425 kg/m^3 and 117 GPa, no other system near a structural material; the 1 x 1 x 5 in beam in metres."""
    assert fem_import.detect_format(RST).name == "ansys-rst"
    assert fe.format == "ansys-rst" and len(fe) == 6
    np.testing.assert_allclose(fe.freqs_hz, result.time_values, rtol=1e-12)
    assert fe.mode_numbers.tolist() == [1, 2, 3, 4, 5, 6]
    assert "converted from in-lbf-s" in fe.units and "inferred" in fe.units
    assert fe.node_ids.size == 321 and fe.shapes.shape == (6, 321, 3)
    np.testing.assert_allclose(fe.xyz.max(axis=0) - fe.xyz.min(axis=0), [0.0254, 0.0254, 0.127], rtol=1e-9)
    assert len(fe.elements) == 40 and {e.fe_descriptor for e in fe.elements} == {115}
    # a square section: the two bending planes' modes are degenerate pairs
    assert fe.freqs_hz[1] / fe.freqs_hz[0] - 1 < 1e-9 and fe.freqs_hz[4] / fe.freqs_hz[3] - 1 < 1e-9


def test_the_shapes_are_mass_normalised_in_si_against_the_mesh_own_mass_matrix(fe, result):
    """``Phi^T M Phi = I`` within 1e-4 with M assembled independently in SI (largest deviation 1.1e-5 measured).
    A slip of the length or mass unit would be off by factors of 39 or 175, a node misplaced by O(1)."""
    length, mass = UNIT_SYSTEMS["in-lbf-s"]
    density = result.materials[1]["DENS"] * mass * length ** 3
    m = _consistent_mass(fe, result, density)
    np.testing.assert_allclose(m.sum() / 3, density * 0.0254 ** 2 * 0.127, rtol=1e-9)
    phi = fe.shapes.reshape(len(fe), -1).T
    np.testing.assert_allclose(phi.T @ m @ phi, np.eye(len(fe)), atol=1e-4)
    fem_import.check_mass_normalisation(fe, mass_matrix=m, rtol=1e-4)


def test_nodal_to_global_is_the_intrinsic_zxy_rotation():
    """``Rz(THXY) Rx(THYZ) Ry(THZX)``, the turns about Z, the new X and the new Y (scipy's intrinsic "ZXY"); a
    node turned 90 deg about Z has its nodal X along the global Y."""
    rng = np.random.default_rng(3)
    angles = rng.uniform(-180, 180, (20, 3))
    np.testing.assert_allclose(ansys_rst.nodal_to_global(angles),
                               Rotation.from_euler("ZXY", angles, degrees=True).as_matrix(), atol=1e-12)
    np.testing.assert_allclose(ansys_rst.nodal_to_global([[90.0, 0.0, 0.0]])[0] @ [1, 0, 0], [0, 1, 0],
                               atol=1e-12)


def test_rotated_nodes_give_the_same_global_shapes(fe, monkeypatch):
    """The file written with rotated nodes (random THXY, THYZ, THZX on every node, components in those nodal
    systems): the reader turns them back to the shapes of the plain file, to 1e-12. The library's own turn to
    global applies the three angles in the reverse order and would not."""
    real = reader.read_binary(RST)
    rng = np.random.default_rng(7)
    angles = rng.uniform(-90, 90, (real.mesh.nnum.size, 3))
    rot = ansys_rst.nodal_to_global(angles)
    real.mesh._node_angles = angles

    def nodal(k, in_nodal_coord_sys=False, nodes=None):
        assert in_nodal_coord_sys, "the reader turns the components itself"
        nnum, u = real.__class__.nodal_solution(real, k, in_nodal_coord_sys=True)
        return nnum, np.einsum("nji,nj->ni", rot, u)  # u_nodal = R^T u_global

    monkeypatch.setattr(real, "nodal_solution", nodal)
    monkeypatch.setattr(reader, "read_binary", lambda path, **kw: real)
    turned = fem_import.read(RST, isolated=False)
    np.testing.assert_allclose(turned.shapes, fe.shapes, atol=1e-12 * np.abs(fe.shapes).max())
    assert any("rotated node" in h for h in turned.history)


@pytest.mark.parametrize("fraction", [0.98, 0.6, 0.05])
def test_a_truncated_file_is_refused_by_name_before_the_library_reads_it(tmp_path, fraction):
    """The library's C reader aborts the whole process on a record cut short (it did on a file cut at half its
    length); the reader compares the file with the end the result header states (byte 907920 of the 917504: the
    rest is padding to the 16 kB system record; a cut at 98 % ends before the data do)."""
    data = open(RST, "rb").read()
    path = tmp_path / "cut.rst"
    path.write_bytes(data[:int(len(data) * fraction)])
    with pytest.raises(fem_import.FEReadError, match=r"cut\.rst.*truncated"):
        fem_import.read(path)


def test_a_file_that_crashes_the_library_is_refused_and_this_process_lives(tmp_path, fe):
    """The length word of the nodal equivalence record (word 192) set to -5: the library's C reader aborts its
    process (``std::bad_alloc``, signal 6); read in a child, that is an FEReadError naming the file and the signal.
    The same read in this process would have killed the test run. The child's read of the intact file is the
    in-process one, bit for bit, log lines included."""
    data = bytearray(open(RST, "rb").read())
    data[4 * 192:4 * 193] = np.int32(-5).tobytes()
    path = tmp_path / "damaged.rst"
    path.write_bytes(bytes(data))
    with pytest.raises(fem_import.FEReadError, match=r"damaged\.rst: the ANSYS result reader crashed on this file "
                                                     r"\(killed by signal \d+"):
        fem_import.read(path)
    here = fem_import.read(RST, isolated=False)
    np.testing.assert_array_equal(fe.shapes, here.shapes)
    np.testing.assert_array_equal(fe.xyz, here.xyz)
    assert fe.elements == here.elements and fe.history == here.history and fe.units == here.units


def test_a_damaged_record_is_refused_by_name(tmp_path):
    """The length word of the first mode's record (word 81396) set to 2^30: the library then reads past the
    record, and stops somewhere else from run to run (a KeyError, "argument out of range", a mode without DOFs);
    each way is an FEReadError naming the file, never another exception. (Only in a child: what it reads there is
    not the file's, and could as well crash this process.)"""
    data = bytearray(open(RST, "rb").read())
    data[4 * 81396:4 * 81397] = np.int32(2 ** 30).tobytes()
    path = tmp_path / "damaged.rst"
    path.write_bytes(bytes(data))
    for _ in range(3):
        with pytest.raises(fem_import.FEReadError, match=r"damaged\.rst: "):
            fem_import.read(path)


def test_unity_normalised_and_non_modal_files_are_refused(monkeypatch):
    """Shapes scaled to a largest component of 1 (``MODOPT`` ``Nrmkey = ON``) carry no modal mass; a static
    analysis has no modes. Both named."""
    real = reader.read_binary(RST)

    def unity(k, in_nodal_coord_sys=False, nodes=None):
        nnum, u = real.__class__.nodal_solution(real, k, in_nodal_coord_sys=in_nodal_coord_sys)
        return nnum, u / np.abs(u).max()

    monkeypatch.setattr(real, "nodal_solution", unity)
    monkeypatch.setattr(reader, "read_binary", lambda path, **kw: real)
    with pytest.raises(fem_import.FEReadError, match="normalised to unity"):
        fem_import.read(RST, isolated=False)
    monkeypatch.setitem(real._resultheader, "kan", 0)
    with pytest.raises(fem_import.FEReadError, match="static analysis"):
        fem_import.read(RST, isolated=False)


@pytest.mark.parametrize("system", sorted(UNIT_SYSTEMS))
def test_the_unit_system_is_inferred_from_steel_in_every_system_but_bft(system, caplog):
    """Steel (7850 kg/m^3, 210 GPa) written in each system: identified alone, except in BFT, whose density (15.2
    slug/ft^3) reads as 15200 kg/m^3 in CGS and whose modulus (4.39e9 lbf/ft^2) as 439 MPa, both plausible: then
    SI is assumed and the reason names both systems. (CGS steel is told from BFT by its modulus: 2.1e12 dyn/cm^2
    read in lbf/ft^2 is 1e14 Pa.) A stated system is kept, with a WARNING when its materials are implausible."""
    length, mass = UNIT_SYSTEMS[system]
    materials = {1: (7850.0 / (mass * length ** 3), 210e9 / (mass * length))}
    found, how = ansys_rst._unit_system("x.rst", 0, materials)
    if system == "ft-slug-s":
        assert found is None and "cm-g-s" in how and "ft-slug-s" in how
    else:
        assert found == system and "inferred" in how
    with caplog.at_level(logging.WARNING, logger="fem_import"):
        assert ansys_rst._unit_system("x.rst", 1, materials)[0] == "m-kg-s"
    assert ("not structural materials" in caplog.text) == (system != "m-kg-s")


def test_other_ansys_files_and_garbage_are_not_taken_for_results(tmp_path):
    """The same run's ``.full`` (file number 4) and a short or foreign file are not sniffed as a result file."""
    assert ansys_rst.sniff_ansys_rst(open(reader.examples.fullfile, "rb").read(4096)) is False
    assert ansys_rst.sniff_ansys_rst(b"\x64\x00\x00") is False
    assert ansys_rst.sniff_ansys_rst(b"    -1\n   164\n" + bytes(100)) is False
    path = tmp_path / "model.rst"
    path.write_bytes(b"not a result file" * 20)
    with pytest.raises(fem_import.UnknownFormatError):
        fem_import.read(path)


def test_elements_whose_shape_hides_their_role_get_it_from_the_ansys_element_number():
    """Line cells of an MPC184, a COMBIN14 and a BEAM188, a MASS21 point and a CONTA174 face: rigid (122), spring
    (136), beam (21), mass (161), and the contact face left out (said) — a rigid link or a spring read as a beam
    would be taken for a stretch of the axle."""
    import pyvista as pv

    line, vertex, quad = pv.CellType.LINE, pv.CellType.VERTEX, pv.CellType.QUAD
    cells = np.array([2, 0, 1, 2, 1, 2, 2, 2, 3, 1, 3, 4, 0, 1, 2, 3])
    grid = pv.UnstructuredGrid(cells, np.array([line, line, line, vertex, quad]), np.eye(4, 3) * [1, 2, 3])
    grid.point_data["ansys_node_num"] = np.array([11, 12, 13, 14])
    grid.cell_data["ansys_elem_num"] = np.array([1, 2, 3, 4, 5])
    grid.cell_data["ansys_elem_type_num"] = np.array([184, 14, 188, 21, 174])

    class Result:
        pass

    result = Result()
    result.grid = grid
    elements, notes = ansys_rst._elements("x.rst", result, {11, 12, 13, 14})
    assert [(e.element_id, e.fe_descriptor, e.nodes) for e in elements] == [
        (1, 122, (11, 12)), (2, 136, (12, 13)), (3, 21, (13, 14)), (4, 161, (14,))]
    assert any("contact" in n and n.startswith("1 ") for n in notes)
