"""The design FE as other tools export it (the probe of realistic design-office exports, D1 and D4-D10, D16).

Each test builds small FE files the way a tool writes them (``tests/fe_exports_support.py``) and checks the
reader against the same model written another way, or against a closed form: the Nastran bulk deck's mesh against
the UFF 2411/2412 of the same model (the lab's design export for the mesh of the campaign), mode shapes of quirky
UFF layouts against the plain layout, the rigid-body mass of a lumped model against the sum of its masses.
"""

from __future__ import annotations

import logging
import shutil

import numpy as np
import pandas as pd
import pytest

import fem_import
from fem_import.checks import check_point_offsets
from fem_import.uff_text import DatasetSpan, unreadable_field
from lab_data.cache import campaign_dir
import fe_exports_support as fx


def _as_tuples(elements):
    return sorted((e.element_id, e.fe_descriptor, tuple(e.nodes), e.physical_property) for e in elements)


def _mesh(elements):
    """The element set: label, FE descriptor and nodes."""
    return sorted((e.element_id, e.fe_descriptor, tuple(e.nodes)) for e in elements)


def _plate(n_modes=3, seed=1, ids=None):
    """A small free model: 6 nodes, 3 beams and 1 quad, random 6-DOF shapes, distinct frequencies."""
    rng = np.random.default_rng(seed)
    ids = np.array([1001, 1002, 1003, 1004, 2001, 2002]) if ids is None else np.asarray(ids)
    xyz = np.array([[0, -0.75, 0], [0, 0, 0], [0, 0.75, 0], [0, 0.75, 0.46], [0.3, -0.75, 0], [0.3, -0.75, 0.3]])
    shapes = rng.standard_normal((n_modes, ids.size, 6)) * 0.02
    freqs = 50.0 * np.arange(1, n_modes + 1)
    elements = [(1, 21, (int(ids[0]), int(ids[1])), 3), (2, 21, (int(ids[1]), int(ids[2])), 3),
                (3, 21, (int(ids[2]), int(ids[3])), 4), (4, 94, (int(ids[0]), int(ids[4]), int(ids[5]),
                                                               int(ids[1])), 99)]
    return ids, xyz, elements, freqs, shapes


# ============================================================================================== D1: bulk elements
def test_d1_bulk_deck_elements_equal_the_uff_2412_of_the_same_model(tmp_path):
    """The lab's design export (UFF 2411/2412: 122 beams, 940 quads, 6 masses) written again as a Nastran deck in
    small, large (``*`` continuations), free and '+'-continued small field: the same elements, with the same FE
    descriptors; through ``read(pch, geometry=bdf)`` and through the punch's companion file too. Before, the bulk
    reader kept the GRID cards only: no elements, and the diagnosis misplaced the axlebox."""
    folder = campaign_dir("control")
    uff = fem_import.read(folder / "fe_design.uff")
    geo = fem_import.read_geometry(folder / "fe_design.uff")
    elements = [(e.element_id, e.fe_descriptor, e.nodes, e.physical_property) for e in geo.elements]
    assert {e[1] for e in elements} == {21, 94, 161}
    styles = ("small", "large", "free", "plus")
    body = fx.grids(geo.node_ids, geo.xyz) + fx.element_cards(elements, lambda k: styles[k % 4])
    body += fx.free("PARAM", "POST", -1) + fx.small("PSHELL", 3, 1, 0.02) + fx.small("MAT1", 1, 2.1e11, None, 0.3)
    (tmp_path / "fe.bdf").write_text(fx.deck(body))
    shutil.copy(folder / "fe_design.pch", tmp_path / "fe.pch")

    bulk = fem_import.read_geometry(tmp_path / "fe.bdf")
    assert _mesh(bulk.elements) == _mesh(geo.elements)
    # the property table too, where Nastran has one (a CONM2 carries its mass itself)
    assert _as_tuples(e for e in bulk.elements if e.fe_descriptor != 161) == \
        _as_tuples(e for e in geo.elements if e.fe_descriptor != 161)
    np.testing.assert_allclose(bulk.xyz, geo.xyz, rtol=0, atol=1e-12)
    merged = fem_import.read(tmp_path / "fe.pch", geometry=tmp_path / "fe.bdf")
    assert _mesh(merged.elements) == _mesh(uff.elements) and len(uff.elements) == 1068
    companion, note = fem_import.read_with_geometry(tmp_path / "fe.pch")
    assert "companion file" in note and _mesh(companion.elements) == _mesh(uff.elements)


def test_d1_every_connectivity_card_in_every_field_format(tmp_path, caplog):
    """One deck with each connectivity card (small, large, free field; blank-name, '+', '*' continuations) against
    the same mesh written as UFF 2411/2412 with the descriptors of the module's table; unknown cards are skipped with
    one INFO per card type and count."""
    ids = np.arange(1, 29)
    xyz = np.column_stack([np.cos(ids), np.sin(ids), 0.01 * ids])
    cards = []
    cards += fx.small("CBAR", 1, 7, 1, 2, 0.0, 0.0, 1.0)
    cards += fx.free("CBEAM", 2, 7, 2, 3, 0.0, 0.0, 1.0, None, "", None, None, 0.0)  # continued on a '+' line
    cards += fx.large("CROD", 3, 5, 3, 4)
    cards += fx.small("CONROD", 4, 4, 5, 1, 0.01)
    cards += fx.small("CQUAD4", 5, 9, 1, 2, 3, 4, 0.0, 0.001)      # THETA, ZOFFS: not grids
    cards += fx.small("CQUAD8", 6, 9, 1, 2, 3, 4, 5, 6, 7, 8)      # G7, G8 on a blank-name continuation
    cards += fx.free("CTRIA3", 7, None, 5, 6, 7)                   # blank PID: the element id
    cards += fx.small_plus("CTRIA6", 8, 9, 5, 6, 7, 8, 9, 10)
    cards += fx.small("CTETRA", 9, 2, 11, 12, 13, 14)
    cards += fx.small_plus("CTETRA", 10, 2, *range(11, 21))
    cards += fx.large("CPENTA", 11, 2, *range(11, 17))
    cards += fx.small("CHEXA", 12, 2, *range(11, 19))
    cards += fx.large("CHEXA", 13, 2, *range(1, 21))
    cards += fx.free("CONM2", 14, 21, 0, 12.5)
    cards += fx.small("CELAS1", 15, 3, 21, 3, 22, 3)
    cards += fx.small("CELAS2", 16, 1.0e6, 22, 5, 23, 5)
    cards += fx.free("CELAS2", 17, 1.0e6, 24, 1)                  # grounded
    cards += fx.small("CBUSH", 18, 4, 23, 24, None, 0.0, 0.0, 1.0)
    cards += fx.small("RBAR", 19, 25, 26, 123456)
    cards += fx.small("RBE2", 20, 27, 123456, *range(1, 14), 1.2e-5)  # 13 dependent grids and ALPHA
    cards += fx.small("RBE3", 21, None, 28, 123, 1.0, 123, 1, 2, 3, 4, 0.5, 123, 5, 6, "UM", 28, 456, "ALPHA",
                      1.2e-5)
    for name, fields in (("PSHELL", (9, 1, 0.02)), ("PSHELL", (3, 1, 0.01)), ("MAT1", (1, 2.1e11, None, 0.3)),
                         ("EIGRL", (1, None, 2000.0))):
        cards += fx.small(name, *fields)
    deck = fx.deck(fx.grids(ids[:10], xyz[:10], "small") + fx.grids(ids[10:20], xyz[10:20], "large")
                   + fx.grids(ids[20:], xyz[20:]) + cards)
    (tmp_path / "all.bdf").write_text(deck)
    expected = [
        (1, 21, (1, 2), 7), (2, 21, (2, 3), 7), (3, 11, (3, 4), 5), (4, 11, (4, 5), 0), (5, 94, (1, 2, 3, 4), 9),
        (6, 95, (1, 5, 2, 6, 3, 7, 4, 8), 9), (7, 91, (5, 6, 7), 7), (8, 92, (5, 8, 6, 9, 7, 10), 9),
        (9, 111, (11, 12, 13, 14), 2), (10, 118, tuple(range(11, 21)), 2), (11, 112, tuple(range(11, 17)), 2),
        (12, 115, tuple(range(11, 19)), 2), (13, 116, tuple(range(1, 21)), 2), (14, 161, (21,), 0),
        (15, 136, (21, 22), 3), (16, 137, (22, 23), 0), (17, 138, (24,), 0), (18, 136, (23, 24), 4),
        (19, 121, (25, 26), 0), (20, 122, (27, *range(1, 14)), 0), (21, 181, (28, 1, 2, 3, 4, 5, 6), 0)]
    with caplog.at_level(logging.INFO, logger="fem_import"):
        bulk = fem_import.read_geometry(tmp_path / "all.bdf")
    assert _as_tuples(bulk.elements) == sorted(expected)
    np.testing.assert_allclose(bulk.xyz, xyz, atol=1e-5)  # small field: 8 columns
    infos = [r.getMessage() for r in caplog.records if r.levelno == logging.INFO]
    assert sum("PSHELL" in m for m in infos) == 1 and any("2 PSHELL entries skipped" in m for m in infos)
    assert any("1 EIGRL entry skipped" in m for m in infos) and any("1 MAT1 entry skipped" in m for m in infos)
    # the same mesh as UFF 2411/2412 (10+ nodes per element: two lines of labels) reads the same
    (tmp_path / "all.uff").write_text(fx.uff164() + fx.uff2411(ids, xyz) + fx.uff2412(expected))
    assert _as_tuples(fem_import.read_geometry(tmp_path / "all.uff").elements) == _as_tuples(bulk.elements)


def test_d1_bulk_element_refusals_name_card_and_line(tmp_path):
    ids = np.arange(1, 5)
    xyz = np.eye(4, 3)
    base = fx.grids(ids, xyz)
    (tmp_path / "twice.bdf").write_text(fx.deck(base + fx.small("CBAR", 1, 1, 1, 2) + fx.small("CONM2", 1, 3)))
    with pytest.raises(fem_import.FEReadError, match=r"twice\.bdf, line \d+: element id 1 is used twice \(CBAR at "
                                                     r"line \d+, CONM2 here\)"):
        fem_import.read_geometry(tmp_path / "twice.bdf")
    (tmp_path / "nogrid.bdf").write_text(fx.deck(base + fx.small("CQUAD4", 5, 1, 1, 2, 3, 99)))
    with pytest.raises(fem_import.FEReadError, match=r"CQUAD4 5 uses grid\(s\) \[99\] that no GRID entry defines"):
        fem_import.read_geometry(tmp_path / "nogrid.bdf")
    (tmp_path / "rep.bdf").write_text(fx.deck(base + fx.small("RBE2", 7, 1, 123456, 2, 1)))
    with pytest.raises(fem_import.FEReadError, match=r"RBE2 7 lists grid\(s\) \[1\] more than once"):
        fem_import.read_geometry(tmp_path / "rep.bdf")


# ==================================================================================== D4: UFF layout quirks
def _three_dof_uff(tmp_path):
    ids, xyz, elements, freqs, shapes = _plate()
    return ids, xyz, elements, freqs, shapes[:, :, :3]


def test_d4_layout_quirks_read_like_the_plain_file(tmp_path):
    """3-DOF 55 records padded to 80 columns (card images), blanks after some or all delimiters and lines, and a
    Fortran E13.5 value with a 3-digit exponent (``0.12000-100``, no 'E') give the plain file's modes. Before: a
    pyuff error, "no UFF dataset found", or "the file is truncated"."""
    ids, xyz, elements, freqs, shapes = _three_dof_uff(tmp_path)
    text = fx.uff_model(ids, xyz, elements, freqs, shapes)
    (tmp_path / "plain.uff").write_text(text)
    ref = fem_import.read(tmp_path / "plain.uff")
    lines = text.split("\n")[:-1]
    variants = {
        "pad80.uff": "\n".join(ln.ljust(80) for ln in lines) + "\n",
        "trailing.uff": "\n".join(ln + " " for ln in lines) + "\n",
        "some_delims.uff": text.replace("    -1\n    55\n", "    -1   \n    55  \n", 2),
    }
    tiny = text.split("\n")
    k = next(i for i, ln in enumerate(tiny) if ln.strip() == str(ids[2]) and i > text[:text.index("    55")].count(
        "\n")) + 1  # mode 1, node 1003: its third value
    tiny[k] = tiny[k][:26] + "  0.12000-100"
    variants["f3.uff"] = "\n".join(tiny)
    for name, body in variants.items():
        (tmp_path / name).write_text(body)
        fe = fem_import.read(tmp_path / name)
        np.testing.assert_array_equal(fe.node_ids, ref.node_ids)
        assert _as_tuples(fe.elements) == _as_tuples(ref.elements), name
        expected = ref.shapes.copy()
        if name == "f3.uff":
            expected[0, 2, 2] = 1.2e-101
        np.testing.assert_allclose(fe.shapes, expected, rtol=0, atol=1e-12, err_msg=name)
        np.testing.assert_allclose(fe.freqs_hz, freqs)


# ============================================================================ D5 + D10: 2412 parsed by the format
def test_d5_d10_long_elements_and_ten_digit_labels(tmp_path):
    """A 20-node brick (116), a 13-node rigid spider (122) and 10-digit I10 labels (no blank between two fields)
    are read as the format lays them out (before: "more than 8 nodes are not supported" / "declares 2 nodes but
    lists 1")."""
    big = 2_000_000_000
    ids = big + np.arange(1, 25)
    xyz = np.column_stack([np.cos(ids - big), np.sin(ids - big), np.zeros(24)])
    elements = [(big + 1, 21, (int(ids[0]), int(ids[1])), 1), (big + 2, 116, tuple(int(n) for n in ids[:20]), 2),
                (big + 3, 122, tuple(int(n) for n in ids[[23, *range(12)]]), 0),
                (big + 4, 161, (int(ids[22]),), 5)]
    rng = np.random.default_rng(3)
    shapes = rng.standard_normal((2, ids.size, 6)) * 0.01
    (tmp_path / "long.uff").write_text(fx.uff_model(ids, xyz, elements, [40.0, 90.0], shapes))
    assert "20000000012000000002\n" in (tmp_path / "long.uff").read_text()  # adjacent 10-digit fields
    fe = fem_import.read(tmp_path / "long.uff")
    assert _as_tuples(fe.elements) == sorted(elements)
    np.testing.assert_allclose(fe.shapes, shapes, rtol=1e-5, atol=1e-9)
    # a record cut short is still named
    text = (tmp_path / "long.uff").read_text()
    cut = text.replace("".join(f"{int(g):10d}" for g in ids[16:20]) + "\n", "")
    (tmp_path / "cut.uff").write_text(cut)
    with pytest.raises(fem_import.FEReadError, match=r"cut\.uff, dataset 2412, line \d+: element 2000000002 \(FE "
                                                     r"descriptor 116\) declares 20 nodes"):
        fem_import.read(tmp_path / "cut.uff")


# ===================================================================================== D6: FE in mm, points in m
def test_d6_an_fe_in_mm_without_units_is_named_not_the_points(tmp_path):
    """An FE written in mm by a tool that states no units (UFF without 164, a Nastran punch + deck) and a points
    table in metres: the message blames the FE's coordinates (before: "looks like km", rescale the points)."""
    ids, xyz, elements, freqs, shapes = _plate()
    mm = xyz * 1e3 * 1.6  # a 2.4 m model in mm
    (tmp_path / "mm.uff").write_text(fx.uff_model(ids, mm, elements, freqs, shapes, units=False))
    fe = fem_import.read(tmp_path / "mm.uff")
    point = mm[0] * 1e-3 + [0.0, 0.0, 0.03]
    with pytest.raises(fem_import.PointToleranceError) as err:
        check_point_offsets(fe, [ids[0]], [point], ["'contact_L'"], source="points.csv")
    text = str(err.value)
    assert "the FE coordinates look like mm" in text and "x 0.001 puts node 1001 0.03 m from the point" in text
    assert "the file states no units: UFF without dataset 164, a Nastran file" in text and "km" not in text
    # Nastran punch + bulk deck in mm: the same diagnosis
    modes = [(k + 1, (2 * np.pi * f) ** 2, ids, shapes[k]) for k, f in enumerate(freqs)]
    (tmp_path / "n.pch").write_text(fx.punch(modes))
    (tmp_path / "n.bdf").write_text(fx.deck(fx.grids(ids, mm)))
    nas = fem_import.read(tmp_path / "n.pch", geometry=tmp_path / "n.bdf")
    with pytest.raises(fem_import.PointToleranceError, match="the FE coordinates look like mm"):
        check_point_offsets(nas, [ids[0]], [point], ["'contact_L'"])
    # a model far larger than a wheelset is named even where no node is near the point
    with pytest.raises(fem_import.PointToleranceError, match=r"no railway wheelset .*look like mm"):
        check_point_offsets(fe, [ids[0]], [[5.0, 5.0, 5.0]], ["'contact_L'"])
    # points in mm with an FE in metres: the points are named, as before
    (tmp_path / "m.uff").write_text(fx.uff_model(ids, xyz * 1.6, elements, freqs, shapes))
    si = fem_import.read(tmp_path / "m.uff")
    with pytest.raises(fem_import.PointToleranceError, match=r"\(looks like mm: x 0.001 puts it .* positions must "
                                                             r"be in metres\)"):
        check_point_offsets(si, [ids[0]], [xyz[0] * 1.6e3], ["'contact_L'"])


# ===================================================================================== D7: Nastran detection
PATRAN = ("$ NASTRAN input file created by the MSC MSC.Nastran input file", "$ translator ( MSC Patran 2019 )",
          "ASSIGN OUTPUT2 = 'wheelset.op2', UNIT = 12", "NASTRAN SYSTEM(151)=1", "SOL 103", "CEND",
          "BEGIN BULK")


def test_d7_decks_of_pre_processors_are_recognised(tmp_path):
    ids, xyz, elements, freqs, shapes = _plate()
    cards = fx.grids(ids, xyz) + fx.element_cards(elements)
    (tmp_path / "patran.bdf").write_text(fx.deck(cards, header=PATRAN))
    (tmp_path / "include.bdf").write_text("PARAM,POST,-1\nCORD2R  1       0       0.      0.      0.      0.      0."
                                          "      1.\n        1.      0.      0.\n" + "\n".join(cards) + "\n")
    (tmp_path / "odd.dat").write_text("FEMAPX TRANSLATOR 11.2\nSOMETHING ELSE\n" + "\n".join(cards) + "\n")
    for name in ("patran.bdf", "include.bdf", "odd.dat"):
        assert fem_import.detect_format(tmp_path / name).name == "nastran-bulk", name
        geo = fem_import.read_geometry(tmp_path / name)
        assert _as_tuples(geo.elements) == sorted(elements), name
    # the GRID-anywhere rule is for deck file names only
    shutil.copy(tmp_path / "odd.dat", tmp_path / "odd.txt")
    with pytest.raises(fem_import.UnknownFormatError) as err:
        fem_import.detect_format(tmp_path / "odd.txt")
    assert "fem_import.read(path, format=NAME)" in str(err.value) and "command line" in str(err.value)


def test_d7_an_unrecognised_companion_is_named(tmp_path):
    ids, xyz, elements, freqs, shapes = _plate()
    modes = [(k + 1, (2 * np.pi * f) ** 2, ids, shapes[k]) for k, f in enumerate(freqs)]
    (tmp_path / "fe.pch").write_text(fx.punch(modes))
    (tmp_path / "fe.bdf").write_text("wheelset geometry, exported 27-11-2024\n1001 0.0 -0.75 0.0\n")
    with pytest.raises(fem_import.MissingCoordinatesError) as err:
        fem_import.read_with_geometry(tmp_path / "fe.pch")
    text = str(err.value)
    assert "fe.bdf exists but is not used" in text and "not recognised as a Nastran bulk deck" in text
    assert "no companion file" not in text


def test_d7_two_subcases_phrased_for_library_and_command_line(tmp_path, caplog):
    ids, xyz, elements, freqs, shapes = _plate()
    one = [(k + 1, (2 * np.pi * f) ** 2, ids, shapes[k]) for k, f in enumerate(freqs)]
    two = [(k + 1, (2 * np.pi * 1.5 * f) ** 2, ids, shapes[k]) for k, f in enumerate(freqs[:2])]
    (tmp_path / "two.pch").write_text(fx.punch(one, subcase=1) + fx.punch(two, subcase=2))
    with pytest.raises(fem_import.FEReadError) as err:
        fem_import.read(tmp_path / "two.pch")
    assert "fem_import.read(path, subcase=N)" in str(err.value) and "command line reads the lowest" in str(err.value)
    (tmp_path / "two.bdf").write_text(fx.deck(fx.grids(ids, xyz)))
    with caplog.at_level(logging.WARNING, logger="fem_import"):
        fe, _ = fem_import.read_with_geometry(tmp_path / "two.pch")
    np.testing.assert_allclose(fe.freqs_hz, freqs, rtol=1e-6)
    assert any("subcase 1 is read" in r.getMessage() for r in caplog.records)
    fe2, _ = fem_import.read_with_geometry(tmp_path / "two.pch", subcase=2)
    np.testing.assert_allclose(fe2.freqs_hz, 1.5 * freqs[:2], rtol=1e-6)


# ========================================================================================= D8: mode numbers
def test_d8_the_files_mode_numbers_are_carried_and_labelled(tmp_path):
    """Modes numbered by the file (UFF 55 record 7, punch MODE =) keep those numbers through reading, geometry
    merging and rotation; the pairing table names them (``fe_mode_numbers``) while ``fe_modes`` stays the
    positions receptance reads back."""
    from ema.modeset import ModeSet
    from ema.pairing import pair_modes

    ids, xyz, elements, freqs, shapes = _plate(n_modes=4, seed=5)
    numbers = [109, 101, 107, 103]
    order = np.argsort([3, 0, 2, 1])  # written out of order, as a post-processor may
    (tmp_path / "n.uff").write_text(fx.uff_model(ids, xyz, elements, freqs[order], shapes[order],
                                                 numbers=np.array(numbers)[order]))
    fe = fem_import.read(tmp_path / "n.uff")
    assert fe.mode_numbers.tolist() == np.array(numbers)[order].tolist()
    assert fe.mode_index(107) == int(np.flatnonzero(np.array(numbers)[order] == 107)[0])
    assert fe.rotated(np.eye(3)[[1, 2, 0]]).mode_numbers.tolist() == fe.mode_numbers.tolist()
    modes = [(n, (2 * np.pi * f) ** 2, ids, s) for n, f, s in zip(numbers, freqs, shapes)]
    (tmp_path / "n.pch").write_text(fx.punch(modes))
    (tmp_path / "n.bdf").write_text(fx.deck(fx.grids(ids, xyz) + fx.element_cards(elements)))
    pch = fem_import.read(tmp_path / "n.pch", geometry=tmp_path / "n.bdf")
    assert pch.mode_numbers.tolist() == numbers
    # the test saw the file's modes 107 and 101 (positions 3 and 2 of the punch)
    channels = pd.DataFrame({"name": [f"a{k}" for k in range(6) for _ in range(2)],
                             "node": np.repeat(np.arange(6), 2), "fe_node": np.repeat(ids, 2),
                             "x": np.repeat(xyz[:, 0], 2), "y": np.repeat(xyz[:, 1], 2), "z": np.repeat(xyz[:, 2], 2),
                             "dx": [1.0, 0.0] * 6, "dy": 0.0, "dz": [0.0, 1.0] * 6})
    channels["name"] = [f"a{k}" for k in range(12)]
    C = pch.at_points(channels["fe_node"], channels[["x", "y", "z"]].to_numpy(),
                      channels[["dx", "dy", "dz"]].to_numpy())
    seen = [2, 1]
    test = ModeSet(freqs_hz=pch.freqs_hz[seen] * 1.01, zeta=np.full(2, 0.002), shapes=C[:, seen].astype(complex),
                   dofs=tuple(channels["name"]), channels=channels, mpc=np.ones(2), mpd=np.zeros(2),
                   setup=("flexural",) * 2)
    table = pair_modes(test, pch, band_hz=(0.0, 1000.0)).table
    paired = table[table["test_mode"].notna()].set_index("test_mode")
    assert paired.loc[1, "fe_modes"] == "3" and paired.loc[1, "fe_mode_numbers"] == "107"
    assert paired.loc[2, "fe_modes"] == "2" and paired.loc[2, "fe_mode_numbers"] == "101"
    fe_only = table[table["test_mode"].isna()]
    assert sorted(fe_only["fe_mode_numbers"]) == ["103", "109"]


# ===================================================================================== D9: rigid-body modes
def test_d9_rigid_body_modes_by_their_shapes_not_a_1_hz_threshold(caplog):
    """A soft-spring free-free run puts the six rigid-body modes at 0.3-1.3 Hz: recognised by their shapes, they
    give the model's mass (the oracle: the sum of the point masses); without them the mass check says why it is
    skipped (before: silently skipped, or rigid_body_mass None)."""
    rigid = np.array([0.3, 0.5, 0.7, 0.9, 1.1, 1.3])
    ids, xyz, masses, freqs, shapes = fx.lumped_free_free(rigid, [45.0, 80.0, 120.0])
    fe = fem_import.FEModes(ids, xyz, (), freqs, shapes, np.ones(freqs.size), source="soft.uff")
    rb = fem_import.check_mass_normalisation(fe, total_mass=float(masses.sum()))
    assert rb is not None and rb.mass == pytest.approx(masses.sum(), rel=1e-9)
    found = fem_import.rigid_body_modes(fe)
    assert found.found and found.indices == (0, 1, 2, 3, 4, 5) and found.method == "shapes"
    # without coordinates, the frequency gap decides
    bare = fem_import.FEModes(ids, np.full_like(xyz, np.nan), (), freqs, shapes, np.ones(freqs.size))
    gap = fem_import.rigid_body_modes(bare)
    assert gap.found and gap.method == "frequency gap"
    # the rigid-body modes left out: not found, and the mass check says it is skipped and why
    flex = fem_import.FEModes(ids, xyz, (), freqs[6:], shapes[6:], np.ones(3), source="flex.uff",
                              mode_numbers=[7, 8, 9])
    miss = fem_import.rigid_body_modes(flex)
    assert not miss.found and "fewer than the six rigid-body modes" in miss.reason
    ids8, xyz8, m8, f8, s8 = fx.lumped_free_free(rigid, [45.0, 80.0, 120.0, 150.0, 190.0, 230.0, 260.0])
    flex8 = fem_import.FEModes(ids8, xyz8, (), f8[6:], s8[6:], np.ones(7), source="flex8.uff",
                               mode_numbers=range(7, 14))
    with caplog.at_level(logging.WARNING, logger="fem_import"):
        assert fem_import.check_mass_normalisation(flex8) is None
    text = " ".join(r.getMessage() for r in caplog.records)
    assert "flex8.uff" in text and "check skipped" in text and "mode 7 (45 Hz), one of the six lowest, is not a " \
                                                                 "rigid-body motion" in text


# ================================================================================ D16 (lab): free-format 58
def test_d16_free_format_numbers_are_named_as_not_fixed_columns(tmp_path):
    lines = ["    -1", "    58", "hammer", "hit 1", "NONE", "NONE", "NONE",
             "    1         1    1         0 NONE             900   0 NONE             900   0",
             "         2        12         1  0.00000E+00  7.81250E-05  0.00000E+00",
             "        17    0    0    0 Time                 s                   ",
             "        13    0    1    0 Force                N                   ",
             "         0    0    0    0 NONE                 NONE                ",
             "         0    0    0    0 NONE                 NONE                ",
             "".join(f"{v:13.5E}" for v in np.linspace(-1, 1, 6)),
             " ".join(f"{v:.6e}" for v in np.linspace(-0.5, 0.5, 6)), "    -1"]
    data = ("\n".join(lines) + "\n").encode()
    start = data.index(b"    58")
    span = DatasetSpan(1, 58, False, start, data.rindex(b"    -1"))
    bad = unreadable_field(data, span)
    assert bad is not None and bad.record == 13 and bad.line == 15
    assert "not in the fixed columns of the format 6E13.5" in bad.cause and "free-format" in bad.cause


# ------------------------------------------------------------------------------------------ declared FE units
def test_a_nastran_export_in_mm_t_s_is_read_in_si_when_its_units_are_declared(tmp_path):
    """The usual Nastran unit set for steel, mm-t-s, in a punch and bulk deck that cannot state it: read as SI the
    wheelset weighs 1/1000 of itself and is refused, the message naming the system; declared (--fe-units mm-t-s)
    the coordinates, translations and rotations come back to the SI export's to 1e-12 and its mass is the
    wheelset's. Oracle: the hand-made lumped wheelset, exported in SI, converted to mm-t-s by the mass
    normalisation's units (translations x sqrt(1000), rotations x sqrt(1000) / 1000)."""
    from fem_import import MassNormalisationError, read_with_geometry
    from fem_import.checks import rigid_body_mass
    from lab_data.nastran_punch import write_punch_eigenvectors
    from lumped_wheelset import build
    from receptance.hybrid import check_fe_for_model

    _, fe, _ = build("own_node", "ring")
    shapes = fe.shapes * np.sqrt(1000.0)
    shapes[..., 3:] /= 1000.0
    pch = write_punch_eigenvectors(tmp_path / "ws.pch", fe.node_ids, fe.freqs_hz, shapes)
    (tmp_path / "ws.bdf").write_text(fx.deck(fx.grids(fe.node_ids, fe.xyz * 1000.0)))
    raw, _ = read_with_geometry(pch)
    with pytest.raises(MassNormalisationError, match=r"read in mm-t-s it would weigh .* --fe-units mm-t-s"):
        check_fe_for_model(raw)
    si, where = read_with_geometry(pch, units="mm-t-s")
    assert "units declared mm-t-s" in where and "mm-t-s (declared)" in si.units
    np.testing.assert_allclose(si.xyz, fe.xyz, atol=1e-12)
    np.testing.assert_allclose(si.shapes, fe.shapes, rtol=1e-6, atol=1e-9 * np.abs(fe.shapes).max())
    assert rigid_body_mass(si).mass == pytest.approx(rigid_body_mass(fe).mass, rel=1e-5)
    check_fe_for_model(si)


def test_declared_units_are_refused_for_a_file_that_states_its_own(tmp_path):
    from fem_import import FEReadError, read_with_geometry
    from lab_data.uff_export import ElementRecord, write_fe_uff
    from lumped_wheelset import build

    _, fe, _ = build("own_node", "ring")
    path = write_fe_uff(tmp_path / "si.uff", fe.node_ids, fe.xyz,
                        [ElementRecord(e.element_id, e.fe_descriptor, 1, 1, 1, e.nodes) for e in fe.elements],
                        fe.freqs_hz, fe.shapes, model_name="lumped")
    with pytest.raises(FEReadError, match=r"states its units .* the declared unit system 'mm-t-s' is for files that "
                                          r"do not state them"):
        read_with_geometry(path, units="mm-t-s")
    with pytest.raises(ValueError, match="unknown FE unit system 'km-kg-s'; known: m-kg-s, mm-t-s"):
        read_with_geometry(path, units="km-kg-s")


# ------------------------------------------------------------------------------------ D17: the Nastran print file
def _design():
    return fem_import.read(campaign_dir("control") / "fe_design.uff")


def _f06_modes(fe, scale=None):
    lam = (2 * np.pi * fe.freqs_hz) ** 2
    s = np.ones(len(fe)) if scale is None else scale
    return [(int(n), float(lam[k]), fe.node_ids, fe.shapes[k] * s[k]) for k, n in enumerate(fe.mode_numbers)]


def test_d17_a_print_file_gives_the_modes_of_the_universal_file(tmp_path, caplog):
    """The lab's design export written as MSC Nastran prints it (an echo page, the eigenvalue table, 25 eigenvector
    tables of 1129 grids broken over pages of 50 rows, a scalar point), with its bulk deck beside it: the same
    modes to the print's 7 digits, coordinates from the deck, mode numbers kept."""
    fe = _design()
    (tmp_path / "ws.f06").write_text(fx.f06(_f06_modes(fe), scalars=(99001,)))
    (tmp_path / "ws.bdf").write_text(fx.deck(fx.grids(fe.node_ids, fe.xyz)))
    assert fem_import.detect_format(tmp_path / "ws.f06").name == "nastran-f06"
    with caplog.at_level(logging.INFO, logger="fem_import"):
        got, where = fem_import.read_with_geometry(tmp_path / "ws.f06")
    assert "companion file" in where and "S x25" in caplog.text
    np.testing.assert_array_equal(got.node_ids, fe.node_ids)
    np.testing.assert_array_equal(got.mode_numbers, fe.mode_numbers)
    np.testing.assert_allclose(got.xyz, fe.xyz, atol=1e-9)
    np.testing.assert_allclose(got.freqs_hz, fe.freqs_hz, rtol=1e-6, atol=1e-3)
    np.testing.assert_allclose(got.shapes, fe.shapes, rtol=1e-6, atol=1e-6 * np.abs(fe.shapes).max())
    # the content decides, not the extension: also under a deck's name, which puts the bulk sniffer first
    for name in ("ws.txt", "ws.dat", "ws.bdf"):
        shutil.copy(tmp_path / "ws.f06", tmp_path / name)
        assert fem_import.detect_format(tmp_path / name).name == "nastran-f06"


def test_d17_a_norm_max_run_is_mass_normalised_by_the_printed_generalized_mass(tmp_path):
    """NORM=MAX: every shape scaled to a largest component of 1, the generalized mass printed accordingly
    (m = c² for φ_max = c φ_mass): divided out, the mass-normalised shapes come back."""
    fe = _design()
    fe = fem_import.FEModes(fe.node_ids, fe.xyz, fe.elements, fe.freqs_hz[6:], fe.shapes[6:], fe.modal_mass[6:],
                            mode_numbers=fe.mode_numbers[6:])
    c = 1.0 / np.abs(fe.shapes).max(axis=(1, 2))
    (tmp_path / "max.f06").write_text(fx.f06(_f06_modes(fe, c), gen_mass=c ** 2))
    got = fem_import.read(tmp_path / "max.f06")
    assert "the eigenvalue table's generalized mass" in got.history[-1]
    np.testing.assert_allclose(got.shapes, fe.shapes, rtol=2e-6, atol=2e-6 * np.abs(fe.shapes).max())


def test_d17_print_file_refusals_name_the_line(tmp_path, caplog):
    fe = _design()
    modes = _f06_modes(fe)[:8]
    text = fx.f06(modes, rows_per_page=400)
    lines = text.splitlines(keepends=True)
    # a grid row cut short
    k = next(i for i, ln in enumerate(lines) if ln.strip().startswith(f"{fe.node_ids[3]} ") and " G " in ln)
    bad = lines[:k] + [lines[k][:60] + "\n"] + lines[k + 1:]
    (tmp_path / "cut.f06").write_text("".join(bad))
    with pytest.raises(fem_import.FEReadError, match=rf"cut\.f06, line {k + 1}: grid {fe.node_ids[3]} of eigenvector "
                                                     r"1: \d values, expected T1 T2 T3 R1 R2 R3"):
        fem_import.read(tmp_path / "cut.f06")
    # the file stops inside the last mode's table
    (tmp_path / "short.f06").write_text("".join(lines[:-600]))
    with pytest.raises(fem_import.FEReadError, match=r"eigenvector 8 lacks grid\(s\)"):
        fem_import.read(tmp_path / "short.f06")
    # two subcases: refused in Python without subcase=, the lowest read by read_with_geometry with a warning
    two = text + fx.f06(modes[:3], subcase=2)
    (tmp_path / "two.f06").write_text(two)
    with pytest.raises(fem_import.FEReadError, match=r"2 subcases \[1, 2\]"):
        fem_import.read(tmp_path / "two.f06")
    assert len(fem_import.read(tmp_path / "two.f06", subcase=2)) == 3
    (tmp_path / "two.bdf").write_text(fx.deck(fx.grids(fe.node_ids, fe.xyz)))
    with caplog.at_level(logging.WARNING, logger="fem_import"):
        assert len(fem_import.read_with_geometry(tmp_path / "two.f06")[0]) == 8
    assert "subcase 1 is read" in caplog.text
    # complex eigenvectors, and a run that printed none
    (tmp_path / "cplx.f06").write_text(text.replace("R E A L   E I G E N V E C T O R",
                                                    "C O M P L E X   E I G E N V E C T O R"))
    with pytest.raises(fem_import.FEReadError, match="complex eigenvectors are not supported"):
        fem_import.read(tmp_path / "cplx.f06")
    (tmp_path / "none.f06").write_text("".join(ln for ln in lines if "E I G E N V E C T O R" not in ln))
    with pytest.raises(fem_import.FEReadError, match=r"no real eigenvectors found .*DISPLACEMENT\(PRINT\)"):
        fem_import.read(tmp_path / "none.f06")


def test_d17_a_print_file_with_its_bulk_data_echo_carries_its_geometry(tmp_path, caplog):
    """ECHO = SORT, Nastran's default: the design export's grids and elements (CBAR, CQUAD4, CONM2 in small
    field) echoed in the print file give it the universal file's coordinates (to the 5 µm of 8-column fields) and
    mesh with no deck beside it; a deck given as geometry replaces the echo."""
    fe = _design()
    geo = fem_import.read_geometry(campaign_dir("control") / "fe_design.uff")
    elements = [(e.element_id, e.fe_descriptor, e.nodes, e.physical_property) for e in geo.elements]
    cards = fx.grids(geo.node_ids, geo.xyz, "small") + fx.element_cards(elements, lambda k: "small")
    (tmp_path / "echo.f06").write_text(fx.f06(_f06_modes(fe), echo=cards))
    got, where = fem_import.read_with_geometry(tmp_path / "echo.f06")
    assert where == "node coordinates from echo.f06"
    order = np.argsort(got.node_ids)
    ref = np.argsort(fe.node_ids)
    np.testing.assert_array_equal(got.node_ids[order], fe.node_ids[ref])
    np.testing.assert_allclose(got.xyz[order], fe.xyz[ref], atol=1e-5)  # the echo's 8-column fields: 5 µm
    np.testing.assert_allclose(got.shapes[:, order], fe.shapes[:, ref], rtol=1e-6, atol=1e-6 * np.abs(fe.shapes).max())
    assert _mesh(got.elements) == _mesh(geo.elements)
    # a deck given replaces the echo: shifted grids come from it
    (tmp_path / "moved.bdf").write_text(fx.deck(fx.grids(fe.node_ids, fe.xyz + [0.0, 0.0, 0.5])))
    moved = fem_import.read(tmp_path / "echo.f06", geometry=tmp_path / "moved.bdf")
    np.testing.assert_allclose(np.sort(moved.xyz[:, 2]), np.sort(fe.xyz[:, 2] + 0.5), atol=1e-9)
    # an echo that lacks grids of the eigenvectors is not used, and said
    (tmp_path / "part.f06").write_text(fx.f06(_f06_modes(fe), echo=cards[5:]))
    with caplog.at_level(logging.WARNING, logger="fem_import"):
        part = fem_import.read(tmp_path / "part.f06")
    assert not part.has_coordinates and "the bulk data echo does not give the geometry" in caplog.text
    assert "CBAR 1 uses grid(s) [1001, 1002] that no GRID entry defines" in caplog.text
    (tmp_path / "grids.f06").write_text(fx.f06(_f06_modes(fe), echo=cards[5:len(geo.node_ids)]))
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="fem_import"):
        assert not fem_import.read(tmp_path / "grids.f06").has_coordinates
    assert "the bulk data echo lacks 5 grid(s) of the eigenvectors (first [1001," in caplog.text
