"""Nastran bulk data replication (``=``, ``==``, ``*x``, ``=n``) in :mod:`fem_import.nastran_bulk`.

Hand-written decks generate grids and elements with replication. The oracles are Nastran's own expansion of the
same deck (the sorted bulk data echo of its print file, NX Nastran, pyYeti's test run ``with_se``) and the grid
table (BGPDT) NX Nastran wrote to the OP2 file of a deck of 8222 replicated grids (``cant_beam``).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

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
