"""Nastran input decks that NX Nastran ran and print files it wrote, read by :mod:`fem_import`, against what Nastran
made of them.

The decks and Nastran's outputs are those pyYeti ships with its own tests. Oracles:

* replication (``=``, ``==``, ``*x``, ``=n``), as hand-written decks generate grids and elements: Nastran's own
  expansion in the sorted bulk data echo of the print file (``with_se``) and the grid table (BGPDT) it wrote to
  the OP2 file of a deck of 8222 replicated grids (``cant_beam``);
* coordinate systems: the basic positions and the displacement systems of the grids of nine decks whose grids sit
  in chains of rectangular, cylindrical and spherical systems, from the USET and CSTM tables Nastran wrote
  (``make_gm_nx9_*``, through pyYeti's DMAP), and their RBE3 elements against the sparsity of the GM matrix
  Nastran formed from them (which grids the element ties);
* INCLUDE files: the sorted bulk data echo of the runs whose master deck includes its mesh;
* print files: NX's banner fills the first 4.5 kB (no heading there to tell the file by); a run with residual
  vectors prints their own frequencies as an eigenvalue table before the augmented one; a superelement run's pages.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import logging

import numpy as np
import pytest
import scipy.io

import fem_import
from fem_import import f06
from fem_import.errors import FEReadError
from fem_import.nastran_bulk import bulk_geometry, read_bulk_geometry

pyyeti = pytest.importorskip("pyyeti")
YETI_TESTS = Path(pyyeti.__file__).parent / "tests"


def yeti_file(rel: str) -> Path:
    p = YETI_TESTS / rel
    if not p.is_file():
        pytest.fail(f"pyyeti {pyyeti.__version__} does not ship {rel} (pyyeti >= 1.4.7 is needed)")
    return p


def test_replicated_deck_equals_nastrans_sorted_echo_of_it():
    """with_se.dat writes its 48 truss grids and 117 bars with =, ==, *1, *300., *-300. and =n; the print file
    echoes the bulk data Nastran made of it, one card per grid and element."""
    deck = read_bulk_geometry(str(yeti_file("nas2cam/with_se.dat")))
    out = yeti_file("nas2cam/with_se.out")
    echo = bulk_geometry(str(out), f06._echo(out.read_text(encoding="latin-1").split("\n")))
    assert deck.node_ids.size == echo.node_ids.size == 60
    order, echo_order = np.argsort(deck.node_ids), np.argsort(echo.node_ids)
    np.testing.assert_array_equal(deck.node_ids[order], echo.node_ids[echo_order])
    np.testing.assert_array_equal(deck.xyz[order], echo.xyz[echo_order])
    assert len(deck.elements) == 117 and deck.elements == echo.elements
    # =,36,,=,330.,== then =,*1,,=,*300.,== and =3: the PV array's grids climb 300 mm at a time
    xyz = dict(zip(deck.node_ids.tolist(), deck.xyz.tolist()))
    assert [xyz[g][1] for g in range(35, 41)] == [-30.0, 330.0, 630.0, 930.0, 1230.0, 1530.0]


def test_replicated_deck_agrees_with_the_op2_grid_table(tmp_path):
    """cant_beam.dat: GRID,1 then '=,*1,,*10.,==' and '=8220'; CBAR,1 then '=,*1,=,*1,*1,==' and '=8219'.
    NX Nastran's grid table of the run has the positions it made of them."""
    for ext in (".op2", ".dat"):
        shutil.copy(yeti_file(f"nas2cam_extseout/cant_beam{ext}"), tmp_path / f"cant_beam{ext}")
    deck = read_bulk_geometry(str(tmp_path / "cant_beam.dat"))
    assert deck.node_ids.tolist() == list(range(1, 8223))
    fe = fem_import.read(tmp_path / "cant_beam.op2")
    assert fe.node_ids.tolist() == deck.node_ids.tolist()
    # 8220 images of +10. each, summed in floating point: exact for these values
    np.testing.assert_array_equal(fe.xyz, deck.xyz)
    assert len(fe.elements) == 8221
    assert [e.nodes for e in fe.elements[:2]] == [(1, 2), (2, 3)] and fe.elements[-1].nodes == (8221, 8222)
    assert {e.fe_descriptor for e in fe.elements} == {21}


def _deck(tmp_path, text: str) -> str:
    p = tmp_path / "model.bdf"
    p.write_text("BEGIN BULK\n" + text + "ENDDATA\n")
    return str(p)


def test_replication_rules_in_small_field_and_free_field(tmp_path):
    text = (
        "GRID           1       0      0.      0.      0.\n"
        "=       *1      =       *(0.25) ==\n"             # fixed field, *(x)
        "=(2)\n"                                             # =(n)
        "GRID,11,,1.0,2.0,3.0,,\n"
        "=,*10,,=,*-0.5,\n"                                 # X3 blank in the image: Nastran reads it as 0.
        "CBAR,1,7,1,2,0.,0.,1.\n"
        "+,,,1.-3,,,\n"                                     # continuation: PA PB W1A...
        "=,*1,=,*1,*1,==\n"                                 # == copies the continuation too
        "=1\n"
        "CQUAD4,10,3,1,2,3,4\n"
        "=,*1,,*1,*1,*1,11\n"                               # blank PID: the element id; 11 is a value
    )
    g = read_bulk_geometry(_deck(tmp_path, text))
    xyz = dict(zip(g.node_ids.tolist(), g.xyz.tolist()))
    assert g.node_ids.tolist() == [1, 2, 3, 4, 11, 21]
    assert [xyz[k][0] for k in (1, 2, 3, 4)] == [0.0, 0.25, 0.5, 0.75]
    assert xyz[21] == [1.0, 1.5, 0.0]
    bars = [e for e in g.elements if e.fe_descriptor == 21]
    assert [(e.element_id, e.nodes, e.physical_property) for e in bars] == [(1, (1, 2), 7), (2, (2, 3), 7),
                                                                            (3, (3, 4), 7)]
    quads = {e.element_id: e for e in g.elements if e.fe_descriptor == 94}
    assert quads[11].nodes == (2, 3, 4, 11) and quads[11].physical_property == 11


def test_replication_refusals_name_the_line(tmp_path):
    with pytest.raises(FEReadError, match=r"line 2.*replicated entry \(=\) without an entry above"):
        read_bulk_geometry(_deck(tmp_path, "=,*1,,*1.,==\nGRID,1,,0.,0.,0.\n"))
    with pytest.raises(FEReadError, match=r"line 3.*=n .* without a replicated entry above"):
        read_bulk_geometry(_deck(tmp_path, "GRID,1,,0.,0.,0.\n=4\n"))
    with pytest.raises(FEReadError, match=r"line 3.*field 3 increments a blank field .* by '\*1\.'"):
        read_bulk_geometry(_deck(tmp_path, "GRID,1,,0.,0.,0.\n=,*1,*1.,==\n"))
    with pytest.raises(FEReadError, match=r"line 3.*field 2 increments 'POST' .* by '\*1': both must be numbers"):
        read_bulk_geometry(_deck(tmp_path, "PARAM,POST,-1\n=,*1,==\nGRID,1,,0.,0.,0.\n"))
    # an image that repeats an id is the duplicate Nastran would refuse, with both lines named
    with pytest.raises(FEReadError, match=r"GRID 1 is defined twice \(lines 2 and 3\)"):
        read_bulk_geometry(_deck(tmp_path, "GRID,1,,0.,0.,0.\n=,=,,*1.,==\n"))


GM_DECKS = ["make_gm_nx9_rbe3_1", "make_gm_nx9_rbe3_2", "make_gm_nx9_rbe3_3", "make_gm_nx9_rbe3_4",
            "make_gm_nx9_rbe3_um_1", "make_gm_nx9_rbe3_um_2", "make_gm_nx9_rbe3_um_3", "make_gm_nx9_rbe3_um_5",
            "make_gm_nx9_rbe3_um_6"]


def _local_axes(kind: int, p: np.ndarray) -> np.ndarray:
    """Unit vectors (columns, in the system's own rectangular axes) of the local directions of a rectangular (1),
    cylindrical (2: r, theta, z) or spherical (3: r, theta, phi) system at the point ``p`` of those axes."""
    if kind == 1:
        return np.eye(3)
    phi = np.arctan2(p[1], p[0])
    c, s = np.cos(phi), np.sin(phi)
    if kind == 2:
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    theta = np.arccos(p[2] / np.linalg.norm(p))
    st, ct = np.sin(theta), np.cos(theta)
    return np.column_stack([[st * c, st * s, ct], [ct * c, ct * s, -st], [-s, c, 0.0]])


@pytest.mark.parametrize("name", GM_DECKS)
def test_grids_in_chained_curvilinear_systems_sit_where_nastran_put_them(name, caplog):
    """Grids given in (CP) and displaced in (CD) CORD2R/C/S systems defined in one another, four deep. Nastran's
    USET has per grid its basic position, its CD system's kind, origin and axes; the displacement directions at the
    grid are those axes turned to the grid's angles (a cylindrical or spherical system's directions follow the
    point)."""
    uset = scipy.io.loadmat(str(yeti_file(f"nastran_gm_data/{name}.mat")))["uset"][0][0][0]
    with caplog.at_level(logging.WARNING, logger="fem_import"):
        g = read_bulk_geometry(str(yeti_file(f"nastran_gm_data/{name}.dat")))
    assert g.node_ids.size == 17 and g.displacement_frames is not None
    kinds = set()
    for k, gid in enumerate(g.node_ids):
        rows = uset[uset[:, 0] == gid]  # dof 1: basic xyz; 2: CD, kind; 3: CD origin; 4-6: CD axes (basic)
        assert rows.shape[0] == 6, gid
        kind, origin, axes = int(rows[1, 4]), rows[2, 3:6], rows[3:6, 3:6]
        kinds.add(kind)
        np.testing.assert_allclose(g.xyz[k], rows[0, 3:6], rtol=0, atol=1e-12 * 1000.0, err_msg=f"GRID {gid}")
        expected = axes @ _local_axes(kind, axes.T @ (rows[0, 3:6] - origin))
        np.testing.assert_allclose(g.displacement_frames[k], expected, rtol=0, atol=1e-12, err_msg=f"GRID {gid}")
    assert kinds == {1, 2, 3}
    # the deck's RBE3 1 and CBAR 1 share an id, which NX Nastran ran: the rigid element is renumbered, logged
    assert "RBE3 1 (line " in caplog.text and "renumbered" in caplog.text
    assert sorted(e.element_id for e in g.elements) == list(range(1, 17))


@pytest.mark.parametrize("name", GM_DECKS)
def test_rbe3_ties_the_grids_of_nastrans_gm_matrix(name):
    """The RBE3's reference grid, its weighted grids and (UM) dependent grids: every grid with a dependent DOF
    (the m-set, bit 1 of USET) or an independent DOF GM weights."""
    mat = scipy.io.loadmat(str(yeti_file(f"nastran_gm_data/{name}.mat")))
    uset, gm = mat["uset"][0][0][0], mat["gm"][0][0][0]
    grid_of = uset[:, 0].astype(int)
    m_set = (uset[:, 2].astype(int) & 1) == 1
    assert gm.shape == (m_set.sum(), (~m_set).sum())
    tied = set(grid_of[m_set]) | set(grid_of[~m_set][np.any(gm != 0, axis=0)])
    g = read_bulk_geometry(str(yeti_file(f"nastran_gm_data/{name}.dat")))
    (rbe3,) = [e for e in g.elements if e.fe_descriptor == 181]
    assert rbe3.nodes[0] == 124 and sorted(rbe3.nodes) == sorted(tied)


def test_two_rigid_elements_with_one_id_are_refused(tmp_path):
    text = "GRID,1,,0.,0.,0.\nGRID,2,,1.,0.,0.\nGRID,3,,2.,0.,0.\nRBE2,5,1,123456,2\nRBAR,5,2,3,123456\n"
    with pytest.raises(FEReadError, match=r"line 6: element id 5 is used twice \(RBE2 at line 5, RBAR here\); "
                                          r"rigid element ids are unique"):
        read_bulk_geometry(_deck(tmp_path, text))


@pytest.mark.parametrize("name", ["nas2cam_extseout/outboard", "nas2cam_extseout/inboard"])
def test_a_deck_that_includes_its_mesh_reads_as_nastrans_echo_of_it(name, tmp_path):
    """outboard.dat: ``include 'outboard.blk'`` (grids, CORD2R 10, bars), then one grid displaced in system 10."""
    for ext in (".dat", ".blk", ".out"):
        shutil.copy(yeti_file(name + ext), tmp_path / Path(name).with_suffix(ext).name)
    stem = Path(name).name
    deck = read_bulk_geometry(str(tmp_path / f"{stem}.dat"))
    out = tmp_path / f"{stem}.out"
    echo = bulk_geometry(str(out), f06._echo(out.read_text(encoding="latin-1").split("\n")))
    order, echo_order = np.argsort(deck.node_ids), np.argsort(echo.node_ids)
    np.testing.assert_array_equal(deck.node_ids[order], echo.node_ids[echo_order])
    np.testing.assert_array_equal(deck.xyz[order], echo.xyz[echo_order])
    np.testing.assert_array_equal(deck.displacement_frames[order], echo.displacement_frames[echo_order])
    assert deck.elements == echo.elements and len(deck.elements) > 50
    # without the included file: its grids are missing, said so, and the system it defines is named as missing
    (tmp_path / f"{stem}.blk").unlink()
    if stem == "outboard":
        with pytest.raises(FEReadError, match=r"line 37: GRID 60: its displacement system CD = 10 is defined by no "
                                              r"CORD entry \(the INCLUDE files not found may define it\)"):
            read_bulk_geometry(str(tmp_path / f"{stem}.dat"))


def test_include_rules(tmp_path, caplog):
    """A quoted name continued over lines, a nested include beside its includer, a name that differs in case, and
    messages that name the included file's own line."""
    sub = tmp_path / "mesh"
    sub.mkdir()
    (sub / "Grids.BDF").write_text("GRID,1,,0.,0.,0.\nGRID,2,,1.,0.,0.\n")
    (sub / "bars.bdf").write_text("$ bars\nINCLUDE 'grids.bdf'\nCBAR,7,1,1,2,0.,0.,1.\n")
    (tmp_path / "main.bdf").write_text("SOL 103\nCEND\nBEGIN BULK\nINCLUDE 'me\n   sh/bars.bdf'\n"
                                       "GRID,3,,2.,0.,0.\nCBAR,8,1,2,3,0.,0.,1.\nENDDATA\n")
    g = read_bulk_geometry(str(tmp_path / "main.bdf"))
    assert g.node_ids.tolist() == [1, 2, 3] and [e.nodes for e in g.elements] == [(1, 2), (2, 3)]
    (sub / "bars.bdf").write_text("$ bars\nINCLUDE 'grids.bdf'\nCBAR,7,1,1,2,0.,0.,1.\nGRID,2,,1.,0.,0.\n")
    with pytest.raises(FEReadError, match=r"main\.bdf, line 4 of me\s*sh/bars\.bdf: GRID 2 is defined twice "
                                          r"\(lines 2 of grids\.bdf and 4 of me\s*sh/bars\.bdf\)"):
        read_bulk_geometry(str(tmp_path / "main.bdf"))
    (sub / "Grids.BDF").write_text("INCLUDE '../main.bdf'\n")
    with pytest.raises(FEReadError, match=r"includes a file that includes it: main\.bdf -> bars\.bdf -> Grids\.BDF "
                                          r"-> main\.bdf"):
        read_bulk_geometry(str(tmp_path / "main.bdf"))
    (sub / "Grids.BDF").unlink()  # not found: the bar on its grids is left out, and the warning names the file
    (sub / "bars.bdf").write_text("INCLUDE 'grids.bdf'\nCBAR,7,1,1,2,0.,0.,1.\n")
    (tmp_path / "main.bdf").write_text("BEGIN BULK\nINCLUDE 'mesh/bars.bdf'\nGRID,3,,2.,0.,0.\nENDDATA\n")
    with caplog.at_level(logging.WARNING, logger="fem_import"):
        g = read_bulk_geometry(str(tmp_path / "main.bdf"))
    assert g.node_ids.tolist() == [3] and g.elements == ()
    assert "1 element(s) use grids no GRID entry of this file defines (first: CBAR 7 at line 2 of mesh/bars.bdf" \
        in caplog.text
    assert "INCLUDE file(s) not found (INCLUDE 'grids.bdf')" in caplog.text


def test_include_names_written_on_another_machine(tmp_path, caplog):
    (tmp_path / "mesh").mkdir()
    (tmp_path / "mesh" / "grids.bdf").write_text("GRID,1,,0.,0.,0.\nGRID,2,,1.,0.,0.\n")
    (tmp_path / "bars.bdf").write_text("CBAR,7,1,1,2,0.,0.,1.\n")
    (tmp_path / "main.bdf").write_text("BEGIN BULK\nINCLUDE 'mesh\\grids.bdf'\n"
                                       "INCLUDE 'C:\\Users\\lab\\wheelset\\bars.bdf'\nENDDATA\n")
    with caplog.at_level(logging.WARNING, logger="fem_import"):
        g = read_bulk_geometry(str(tmp_path / "main.bdf"))
    assert g.node_ids.tolist() == [1, 2] and [e.nodes for e in g.elements] == [(1, 2)]
    assert "INCLUDE 'C:\\Users\\lab\\wheelset\\bars.bdf' does not exist here" in caplog.text
    assert "mesh\\grids.bdf" not in caplog.text  # a relative Windows name is simply found


def test_an_nx_print_file_is_told_by_its_banner(tmp_path):
    for ext in (".out", ".op2"):
        shutil.copy(yeti_file(f"nas2cam_extseout/full{ext}"), tmp_path / f"full{ext}")
    head = (tmp_path / "full.out").read_bytes()[:fem_import.registry.SNIFF_BYTES]
    assert b"PAGE" not in head and b"E X E C" not in head  # NX's banner: no heading to tell the file by
    assert fem_import.detect_format(tmp_path / "full.out").name == "nastran-f06"
    with pytest.raises(FEReadError, match=r"full\.out: no real eigenvectors found .* the run's results file beside "
                                          r"it may hold them: read full\.op2"):
        fem_import.read(tmp_path / "full.out")


def test_the_residual_vectors_frequency_list_is_no_eigenvalue_table():
    """NX prints the residual vectors' frequencies (modes 1-9, here the vectors' own) between the eigenvalue tables
    before and after augmentation; the modes are the augmented table's 12 rows, whose first three the OP2 has."""
    out = yeti_file("nas2cam_extseout/inboard.out")
    _, table = f06._parse(str(out), out.read_text(encoding="latin-1").split("\n"))
    assert sorted(n for _, n in table) == list(range(1, 13))
    assert table[(None, 1)] == (1.483160e03, 1.0) and table[(None, 4)] == (1.960809e05, 1.0)
    assert table[(None, 12)] == (2.378353e07, 1.0)
    fe = fem_import.read(yeti_file("nas2cam_extseout/inboard.op2"))
    printed = np.sqrt([table[(None, n)][0] for n in (1, 2, 3)]) / (2 * np.pi)
    np.testing.assert_allclose(fe.freqs_hz, printed, rtol=1e-6)


def test_a_superelement_runs_print_file_is_refused():
    with pytest.raises(FEReadError, match=r"with_se\.out, line 655: the print file of a superelement run \(pages of "
                                          r"SUPERELEMENT 200\)"):
        fem_import.read(yeti_file("nas2cam/with_se.out"))


def test_a_punch_of_matrices_is_told_from_one_of_modes():
    """EXTSEOUT's punch: DMIG entries of the reduced matrices, bulk data without a '$EIGENVECTOR' block."""
    with pytest.raises(FEReadError, match=r"outboard\.pch: this punch file holds bulk data entries \(DMIG matrices"):
        fem_import.read(yeti_file("nas2cam_extseout/outboard.pch"))


def test_grdset_gives_the_blank_cp_and_cd_of_every_grid(tmp_path):
    """GRDSET fields 3 and 7 are the CP and CD of the GRIDs that leave theirs blank; an explicit 0 stays basic.
    Oracle: the same deck with the systems written on each grid."""
    cord = "CORD2C,2,,1.,0.,0.,1.,0.,1.\n,2.,0.,0.\n"
    explicit = cord + "GRID,1,2,1.,0.,0.,2\nGRID,2,2,1.,90.,0.5,2\nGRID,3,0,1.,0.,0.,0\n"
    blank = cord + "GRID,1,,1.,0.,0.\nGRID,2,,1.,90.,0.5\nGRID,3,0,1.,0.,0.,0\nGRDSET,,2,,,,2\n"  # GRDSET last
    a = read_bulk_geometry(_deck(tmp_path, explicit))
    (tmp_path / "model.bdf").rename(tmp_path / "explicit.bdf")
    b = read_bulk_geometry(_deck(tmp_path, blank))
    np.testing.assert_array_equal(a.xyz, b.xyz)
    np.testing.assert_array_equal(a.displacement_frames, b.displacement_frames)
    np.testing.assert_allclose(b.xyz, [[2.0, 0.0, 0.0], [1.0, 1.0, 0.5], [1.0, 0.0, 0.0]], atol=1e-15)
    with pytest.raises(FEReadError, match=r"GRDSET is given twice \(lines 2 and 3\)"):
        read_bulk_geometry(_deck(tmp_path, "GRDSET,,2\nGRDSET,,,,,,2\n" + explicit))


def test_a_grid_in_a_general_curvilinear_system_is_refused_by_name(tmp_path):
    text = "CORD3G,4,POLYNOMIAL,,1,2,3\nGRID,1,4,1.,0.,0.\nGRID,2,,0.,0.,0.,4\n"
    with pytest.raises(FEReadError, match=r"line 3: GRID 1: its CP system 4 is a CORD3G \(line 2\)"):
        read_bulk_geometry(_deck(tmp_path, text))
    with pytest.raises(FEReadError, match=r"line 4: GRID 2: its CD system 4 is a CORD3G \(line 2\)"):
        read_bulk_geometry(_deck(tmp_path, text.replace("GRID,1,4,", "GRID,1,,")))
