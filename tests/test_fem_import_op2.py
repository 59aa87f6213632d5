"""Nastran OP2 results (:mod:`fem_import.nastran_op2`), on files MSC and NX Nastran wrote.

The files are those pyYeti (the OP2 record reader) ships with its own tests: runs of a free-free truss with their
input decks and print files. The oracles are Nastran's other outputs of the same run, read without pyYeti: the
print file's weight check (grid point weight generator: mass, centre, inertia) against the mass the rigid-body
eigenvectors imply, and its eigenvalue table against the OP2's frequencies.
"""

from __future__ import annotations

import logging
import random
import re
import shutil
import struct
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import fem_import
from fem_import.checks import rigid_body_mass
from fem_import.errors import FEImportError, FEReadError
from fem_import.nastran_op2 import DECK_TOLERANCE, _grid_geometry, check_records, sniff_op2

pyyeti = pytest.importorskip("pyyeti")
YETI_TESTS = Path(pyyeti.__file__).parent / "tests"


def yeti_file(rel: str) -> Path:
    p = YETI_TESTS / rel
    if not p.is_file():
        pytest.fail(f"pyyeti {pyyeti.__version__} does not ship {rel}; the OP2 tests read the Nastran runs of its "
                    f"wheel (pyyeti >= 1.4.7)")
    return p


@pytest.fixture()
def full_run(tmp_path):
    """The free-free truss run (NX Nastran 9.1, SOL 103 in SEMFREQ, PARAM,POST,-1) with its deck, in a tmp dir."""
    for ext in (".op2", ".dat", ".out"):
        shutil.copy(yeti_file(f"nas2cam_extseout/full{ext}"), tmp_path / f"full{ext}")
    return tmp_path


def weight_check(out: Path):
    """Mass, centre of mass and inertia about it from the print file's grid point weight generator output."""
    lines = out.read_text(encoding="latin-1").split("\n")
    k = next(i for i, ln in enumerate(lines) if "MASS AXIS SYSTEM (S)" in ln)
    rows = [lines[k + j].split() for j in (1, 2, 3)]
    mass = np.array([float(r[1]) for r in rows])
    centre = np.array([float(rows[1][2]), float(rows[0][3]), float(rows[0][4])])
    k = next(i for i in range(k, len(lines)) if lines[i].strip() == "I(S)")
    inertia = np.array([[float(v) for v in lines[k + j].replace("*", " ").split()] for j in (1, 2, 3)])
    return mass, centre, inertia


def eigenvalue_table(out: Path) -> dict[int, float]:
    """Mode number -> eigenvalue of the print file's R E A L   E I G E N V A L U E S rows."""
    rows = {}
    for ln in out.read_text(encoding="latin-1").split("\n"):
        t = ln.split()
        if len(t) == 7 and t[0].isdigit() and t[1].isdigit() and re.fullmatch(r"-?\d\.\d{6}E[+-]\d\d", t[2]):
            rows.setdefault(int(t[0]), float(t[2]))
    return rows


def test_sniffed_and_read_with_the_decks_elements(full_run):
    p = full_run / "full.op2"
    assert fem_import.detect_format(p).name == "nastran-op2"
    assert sniff_op2(yeti_file("nastran_op2_data/tugd_2020_64bit.op2").read_bytes()[:4096])  # 64-bit words
    assert not sniff_op2(b"$TITLE   = punch\n") and not sniff_op2(b"\x04\x00\x00\x00\x03\x00\x00\x00")
    fe = fem_import.read(p)
    assert (len(fe), fe.node_ids.size, fe.shapes.shape[2]) == (278, 49, 6)
    assert fe.format == "nastran-op2" and "assumed" in fe.units
    np.testing.assert_array_equal(fe.mode_numbers, np.arange(1, 279))
    deck = fem_import.read_geometry(full_run / "full.dat")
    assert len(fe.elements) == len(deck.elements) == 118
    # the grid table's coordinates are the deck's (single precision against 8-column fields)
    where = {n: k for k, n in enumerate(deck.node_ids.tolist())}
    np.testing.assert_allclose(fe.xyz, deck.xyz[[where[n] for n in fe.node_ids.tolist()]], atol=1e-4)


def test_rigid_body_modes_carry_nastrans_weight_check(full_run):
    """Mass-normalised eigenvectors of the six rigid-body modes imply the structure's mass, centre and inertia; the
    print file's weight generator computes them from the mass matrix directly. The run is in mm-kg-s."""
    fe = fem_import.read(full_run / "full.op2").in_si_units("mm-kg-s")
    rb = rigid_body_mass(fe)
    mass, centre, inertia = weight_check(full_run / "full.out")
    assert rb.modes == (1, 2, 3, 4, 5, 6)
    np.testing.assert_allclose(rb.masses, mass, rtol=1e-6)       # 3.345436 kg
    np.testing.assert_allclose(rb.centre * 1e3, centre, atol=1e-3)  # (633.370, 150, 150) mm
    np.testing.assert_allclose(np.diag(rb.inertia) * 1e6, np.diag(inertia), rtol=1e-6)


def test_frequencies_are_the_print_files(full_run):
    fe = fem_import.read(full_run / "full.op2")
    table = eigenvalue_table(full_run / "full.out")
    lam = np.array([table[n] for n in fe.mode_numbers.tolist()])
    f = np.sqrt(np.maximum(lam, 0.0)) / (2 * np.pi)
    assert np.all(fe.freqs_hz[:6] < 1e-3)
    # 7 printed digits
    np.testing.assert_allclose(fe.freqs_hz[6:], f[6:], rtol=1e-6)
    assert fe.freqs_hz[6] == pytest.approx(1.699, abs=1e-3)


def test_the_print_file_of_the_same_run_reads_its_eigenvalue_table(full_run):
    """The print file of a run that also writes an OP2 holds OUTPUT2's trailer lines (seven integers after the
    eigenvalue table), which are not table rows."""
    from fem_import import f06

    path = full_run / "full.out"
    _, table = f06._parse(str(path), path.read_text(encoding="latin-1").split("\n"))
    assert sorted(n for _, n in table) == list(range(1, 279))


def test_without_a_matching_deck_the_elements_come_from_the_geom_tables(full_run, caplog):
    """PARAM,POST,-1 writes GEOM2S (the 117 bars) and GEOM4S (the RBE2): read as the deck's cards of the same
    name, they are the deck's 118 elements. A deck of another mesh is not used for them."""
    p = full_run / "full.op2"
    (full_run / "full.out").unlink()
    deck_text = (full_run / "full.dat").read_text()
    deck = fem_import.read_geometry(full_run / "full.dat")
    (full_run / "full.dat").unlink()
    with caplog.at_level(logging.INFO, logger="fem_import"):
        alone = fem_import.read(p)
    assert alone.has_coordinates and alone.elements == deck.elements and len(alone.elements) == 118
    assert "no input deck beside the file" in caplog.text and "118 elements read from the OP2's GEOM" in caplog.text
    assert "GEOM tables (elements)" in alone.history[-1]
    # a deck of another mesh: grid 1 moved by 1 % of the model's size
    size = float(np.linalg.norm(np.ptp(alone.xyz, axis=0)))
    moved = deck_text.replace("GRID           1       0      0.      0.    300.",
                              f"GRID           1       0{-0.01 * size:8.2f}      0.    300.")
    assert moved != deck_text and 0.01 > DECK_TOLERANCE
    (full_run / "full.dat").write_text(moved)
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="fem_import"):
        fe = fem_import.read(p)
    assert "grid 1 sits" in caplog.text and fe.elements == deck.elements
    np.testing.assert_array_equal(fe.xyz, alone.xyz)


@pytest.mark.parametrize("rel, deck_rel", [("nas2cam_extseout/cant_beam", "nas2cam_extseout/cant_beam"),
                                            ("nas2cam_csuper/assemble", "nas2cam_csuper/assemble")])
def test_geom_tables_give_the_decks_bars_and_rigid_elements(rel, deck_rel, tmp_path):
    """8221 CBARs of NX's 16-word layout; RBE2 (three, one with one dependent component) and an RBE3 of GEOM4S."""
    shutil.copy(yeti_file(rel + ".op2"), tmp_path / "alone.op2")
    fe = fem_import.read(tmp_path / "alone.op2")
    deck = fem_import.read_geometry(yeti_file(deck_rel + ".dat"))
    assert fe.elements == deck.elements and len(fe.elements) in (8221, 4)


def test_geom_tables_of_a_32_and_a_64_bit_file_agree():
    """MSC Nastran 2020's files of one model in 32- and 64-bit words: CBEAM (18 words), CBUSH (14), CONM2 (13)."""
    from pyyeti.nastran import op2 as yeti_op2

    from fem_import.nastran_op2 import _geom_records
    from fem_import.nastran_op2_geom import op2_elements

    got = {}
    for bits in (32, 64):
        path = yeti_file(f"nastran_op2_data/tugd_2020_{bits}bit.op2")
        endian, word = check_records(str(path))
        with yeti_op2.OP2(str(path)) as o2:
            records = _geom_records(o2)
            uset = o2.rdparampost(get_mats=False, get_ougs=False, get_dr_tables=False)["uset"]
        ids = np.unique(uset.index.get_level_values(0).to_numpy())
        got[bits] = op2_elements(str(path), records, endian, word, ids)
        assert word == bits // 8
    assert got[32] == got[64]
    kinds = pd.Series([e.fe_descriptor for e in got[64]]).value_counts().to_dict()
    assert kinds == {161: 26, 21: 24, 136: 8}
    assert all(len(e.nodes) == (1 if e.fe_descriptor == 161 else 2) for e in got[64])


def test_a_given_geometry_replaces_the_grid_table(full_run):
    p = full_run / "full.op2"
    own = fem_import.read(p)
    given = fem_import.read(p, geometry=full_run / "full.dat")
    order = np.argsort(given.node_ids)  # the deck's grid order
    np.testing.assert_array_equal(given.node_ids[order], own.node_ids)
    np.testing.assert_allclose(given.xyz[order], own.xyz, atol=1e-4)
    np.testing.assert_array_equal(given.shapes[:, order], own.shapes)
    assert len(given.elements) == len(own.elements)
    fe, where = fem_import.read_with_geometry(p, units="mm-kg-s")
    assert "full.op2" in where and fe.xyz[:, 0].max() == pytest.approx(own.xyz[:, 0].max() / 1000)


def test_displacement_systems_turn_the_shapes_to_basic():
    """A grid whose CD is a cylindrical system has its eigenvector components radial, tangential and axial; the
    grid table (basic position, CD) and CSTM (origin, axes) give the frame at the grid. System 20: origin (0, 1, 3),
    axes e1 = basic y, e2 = basic z, e3 = basic x. Grid 8 at basic (1, 1, 5) is at local (0, 2, 1): radius 2 along
    e2, so radial = basic z, tangential = -e1 = -basic y, axial = basic x."""
    from fem_import.registry import Geometry, merge_geometry

    ids = np.array([7, 8])
    xyz = np.array([[0.5, 2.0, 0.0], [1.0, 1.0, 5.0]])
    index = pd.MultiIndex.from_tuples([(n, d) for n in ids.tolist() for d in range(1, 7)], names=("id", "dof"))
    values = np.zeros((12, 3))
    values[0], values[6] = xyz
    values[1], values[7] = (0, 1, 0), (20, 2, 0)
    axes = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    cstm2 = {20: np.vstack([[20, 2, 0], [0.0, 1.0, 3.0], axes])}
    got_xyz, frames = _grid_geometry("x.op2", {"uset": pd.DataFrame(values, index=index, columns=["x", "y", "z"]),
                                               "cstm2": cstm2}, ids)
    np.testing.assert_array_equal(got_xyz, xyz)
    np.testing.assert_array_equal(frames[0], np.eye(3))
    np.testing.assert_allclose(frames[1], [[0, 0, 1], [0, -1, 0], [1, 0, 0]], atol=1e-15)
    # a mode whose grid 8 moves 1 radially and turns 2 about the tangent: basic z, and -2 about basic y
    shapes = np.zeros((1, 2, 6))
    shapes[0, 1] = (1, 0, 0, 0, 2, 0)
    fe = fem_import.FEModes(ids, np.full((2, 3), np.nan), (), np.array([10.0]), shapes, np.ones(1),
                            format="nastran-op2")
    turned = merge_geometry(fe, Geometry(ids, got_xyz, (), "x.op2", displacement_frames=frames))
    np.testing.assert_allclose(turned.shapes[0, 1], [0, 0, 1, 0, -2, 0], atol=1e-15)
    values[7] = (21, 2, 0)
    with pytest.raises(FEReadError, match="system 21 of grid"):
        _grid_geometry("x.op2", {"uset": pd.DataFrame(values, index=index, columns=["x", "y", "z"]),
                                 "cstm2": cstm2}, ids)


def test_other_files_of_the_library():
    # eigenvectors without a grid table: coordinates from a deck, as for a punch
    fe = fem_import.read(yeti_file("nastran_op2_data/rdop2gpwg_1.op2"))
    assert (len(fe), fe.node_ids.size, fe.has_coordinates) == (18, 10, False)
    with pytest.raises(FEReadError, match="several superelements"):
        fem_import.read(yeti_file("nas2cam_extseout/assemble.op2"))
    with pytest.raises(FEReadError, match="no real eigenvectors"):
        fem_import.read(yeti_file("nastran_op2_data/tugd_2020_64bit.op2"))


def _record_ends(data: bytes) -> list[int]:
    ends, pos = [], 0
    while pos < len(data):
        pos += 8 + struct.unpack_from("<i", data, pos)[0]
        ends.append(pos)
    return ends


@pytest.mark.parametrize("rel", ["nas2cam_extseout/inboard.op2", "nastran_op2_data/rdop2gpwg_1.op2"])
def test_a_cut_file_is_refused_or_read_whole(tmp_path, rel):
    """Cut at every record boundary and at random bytes: a refusal, or (a cut after the eigenvector tables, whose
    later tables are not read) the modes of the whole file; never fewer modes or grids."""
    data = yeti_file(rel).read_bytes()
    ref = fem_import.read(yeti_file(rel))
    rng = random.Random(3)
    cuts = _record_ends(data)[:-1] + rng.sample(range(100, len(data)), 60)
    p = tmp_path / "cut.op2"
    outcomes = {"refused": 0, "whole": 0}
    for c in cuts:
        p.write_bytes(data[:c])
        try:
            fe = fem_import.read(p)
        except FEImportError:  # FEReadError; a cut inside the header record is not recognised as an OP2
            outcomes["refused"] += 1
            continue
        assert (len(fe), fe.node_ids.size) == (len(ref), ref.node_ids.size), f"cut at byte {c}"
        np.testing.assert_array_equal(fe.shapes, ref.shapes)
        outcomes["whole"] += 1
    assert outcomes["refused"] > 0.9 * len(cuts)
    with pytest.raises(FEReadError, match="declares .* bytes, but the file ends"):
        p.write_bytes(data[:len(data) // 2])
        check_records(str(p))


def test_a_changed_byte_is_refused_or_read(tmp_path):
    """Single-byte changes anywhere: a named refusal or finite modes, never another exception."""
    src = yeti_file("nas2cam_extseout/inboard.op2")
    data = src.read_bytes()
    rng = random.Random(5)
    p = tmp_path / "changed.op2"
    refused = 0
    for _ in range(150):
        b = bytearray(data)
        b[rng.randrange(len(b))] = rng.randrange(256)
        p.write_bytes(bytes(b))
        try:
            fe = fem_import.read(p)
        except FEImportError:
            refused += 1
            continue
        assert np.all(np.isfinite(fe.shapes)) and np.all(np.isfinite(fe.freqs_hz))
    assert refused > 0


def test_an_eigenvalue_table_after_residual_vector_augmentation_replaces_the_first():
    """Nastran prints the eigenvalue table before and after adding residual vectors (RESVEC); the rows of the
    second are the eigenvectors' own. Two tables of one subcase without that heading are still refused."""
    from fem_import import f06

    def table(heading, rows):
        return ["1    RUN                                       PAGE  3", "0                     SUBCASE 1",
                "                 R E A L   E I G E N V A L U E S", heading,
                "   MODE    EXTRACTION      EIGENVALUE   RADIANS   CYCLES   GENERALIZED   GENERALIZED",
                "    NO.       ORDER                                          MASS         STIFFNESS"] + [
                f"{n:9d}{n:10d}   {lam:.6E}   1.0E+00   1.0E+00   {m:.6E}   {lam:.6E}" for n, lam, m in rows]

    before = table("         (BEFORE AUGMENTATION OF RESIDUAL VECTORS)", [(1, 4.0e4, 1.0), (2, 9.0e4, 1.0)])
    after = table("         (AFTER AUGMENTATION OF RESIDUAL VECTORS)",
                  [(1, 4.0e4, 1.0), (2, 9.0e4, 1.0), (3, 4.0e6, 2.0)])
    trailer = [" *** USER INFORMATION MESSAGE 4114 (OUTPX2)", "     DATA BLOCK LAMA     WRITTEN ON FORTRAN UNIT  12",
               "                    101                 3                 0                 0                 0"
               "                 0                 0"]
    _, rows = f06._parse("run.f06", before + trailer + after + trailer)
    assert rows == {(1, 1): (4.0e4, 1.0), (1, 2): (9.0e4, 1.0), (1, 3): (4.0e6, 2.0)}
    with pytest.raises(FEReadError, match="mode 1 appears twice"):
        f06._parse("run.f06", before + before)


# ------------------------------------------------------------------------- the lab's design export as an OP2
def write_op2(path: Path, modes, *, gen_mass=None, subcase: int = 1, scalars=(), lama: bool = True,
              endian: str = "<", word: int = 4) -> Path:
    """An OP2 of a SOL 103 run written with ``struct`` alone, in the record layout of the NX Nastran files above
    (header records, then per table: name, trailer, header record, and each record preceded by its word count and
    followed by its ``-k 1 0`` markers; ``0`` ends a table, another ``0`` the file): the eigenvalue table (LAMA)
    and one OUGV1 identification and data record per mode. ``modes`` is [(mode number, eigenvalue (rad/s)^2, ids,
    (n, 6) values[, subcase])]; no grid table (the coordinates come from a deck). ``word`` 8 writes the 64-bit
    form of ``tugd_2020_64bit.op2``: 8-byte integers and reals, each 4 characters of a name padded to 8 bytes."""
    out = bytearray()
    i, f = ("i", "f") if word == 4 else ("q", "d")

    def pack(fmt: str, *values) -> bytes:
        return struct.pack(endian + fmt.replace("i", i).replace("f", f), *values)

    def text(s: bytes) -> bytes:
        return b"".join(s[k:k + 4].ljust(word) for k in range(0, len(s), 4))

    def rec(body: bytes):
        out.extend(struct.pack(endian + "i", len(body)) + body + struct.pack(endian + "i", len(body)))

    def key(v: int):
        rec(pack("i", v))

    def table(name: str, records):
        name8 = text(f"{name:<8}".encode())
        key(2), rec(name8), key(-1), key(7), rec(pack("7i", 101, len(records), 0, 0, 0, 0, 0))
        key(-2), key(1), key(0), key(2), rec(name8)
        for j, body in enumerate(records, start=3):
            key(-j), key(1), key(0), key(len(body) // word), rec(body)
        key(-(len(records) + 3)), key(1), key(0), key(0)

    key(3), rec(pack("3i", 12, 1, 26)), key(7), rec(text(b"NASTRAN FORT TAPE ID CODE - "))
    key(2), rec(text(b"NX9.1   ")), key(-1), key(0)
    gm = np.ones(len(modes)) if gen_mass is None else np.asarray(gen_mass, float)
    title = text(b"RAILMODAL TEST".ljust(128))
    if lama:
        rows = b"".join(pack("2i5f", n, k + 1, lam, np.sqrt(max(lam, 0)), np.sqrt(max(lam, 0)) / 2 / np.pi,
                             gm[k], gm[k] * lam) for k, (n, lam, *_) in enumerate(modes))
        table("LAMA", [pack("10i", 21, 6, 0, 0, 0, 0, 0, 0, 0, 7) + bytes(word * 40) + title * 3, rows])
    records = []
    for n, lam, ids, vals, *case in modes:
        # approach 2 x 10 + device 2, table 7, -, subcase, mode, eigenvalue, -, -, format 1, 8 words per point
        ident = pack("5if4i", 22, 7, 0, case[0] if case else subcase, n, lam, 0, 0, 1, 8) + bytes(word * 40)
        points = b"".join(pack("2i6f", int(g) * 10 + 2, 1, *row) for g, row in zip(ids, vals))
        points += b"".join(pack("2i6f", int(s) * 10 + 2, 2, 0.0, 0, 0, 0, 0, 0) for s in scalars)
        records += [ident + title * 3, points]
    table("OUGV1", records)
    key(0)
    path.write_bytes(bytes(out))
    return path


def _design():
    from lab_data.cache import campaign_dir

    return fem_import.read(campaign_dir("control") / "fe_design.uff")


def _modes(fe, scale=None):
    lam = (2 * np.pi * fe.freqs_hz) ** 2
    s = np.ones(len(fe)) if scale is None else scale
    return [(int(n), float(lam[k]), fe.node_ids, fe.shapes[k] * s[k]) for k, n in enumerate(fe.mode_numbers)]


def test_the_design_export_as_an_op2_gives_the_universal_files_modes(tmp_path, caplog):
    """The lab's design export (25 modes on 1129 grids, 6 DOF) written as an OP2 with a scalar point, its deck
    beside it: the same modes to single precision, coordinates and elements from the deck, mode numbers kept."""
    import fe_exports_support as fx

    fe = _design()
    write_op2(tmp_path / "ws.op2", _modes(fe), scalars=(99001,))
    geo = fem_import.read_geometry(_design().source)
    elements = [(e.element_id, e.fe_descriptor, e.nodes, e.physical_property) for e in geo.elements]
    (tmp_path / "ws.bdf").write_text(fx.deck(fx.grids(fe.node_ids, fe.xyz) + fx.element_cards(elements)))
    with caplog.at_level(logging.INFO, logger="fem_import"):
        got, where = fem_import.read_with_geometry(tmp_path / "ws.op2")
    assert "companion file" in where and "scalar point x1" in caplog.text
    np.testing.assert_array_equal(got.node_ids, fe.node_ids)
    np.testing.assert_array_equal(got.mode_numbers, fe.mode_numbers)
    assert len(got.elements) == len(fe.elements) == 1068
    np.testing.assert_allclose(got.xyz, fe.xyz, atol=1e-9)
    np.testing.assert_allclose(got.freqs_hz, fe.freqs_hz, rtol=1e-7, atol=1e-3)
    np.testing.assert_allclose(got.shapes, fe.shapes, rtol=1e-6, atol=1e-7 * np.abs(fe.shapes).max())


def test_a_norm_max_op2_is_mass_normalised_by_its_generalized_mass(tmp_path):
    fe = _design()
    c = 1.0 / np.abs(fe.shapes[6:]).max(axis=(1, 2))
    flexible = fem_import.FEModes(fe.node_ids, fe.xyz, fe.elements, fe.freqs_hz[6:], fe.shapes[6:],
                                  fe.modal_mass[6:], mode_numbers=fe.mode_numbers[6:])
    write_op2(tmp_path / "max.op2", _modes(flexible, c), gen_mass=c ** 2)
    got = fem_import.read(tmp_path / "max.op2")
    assert "the eigenvalue table's generalized mass" in got.history[-1]
    np.testing.assert_allclose(got.shapes, flexible.shapes, rtol=2e-6, atol=2e-7 * np.abs(fe.shapes).max())
    # without its eigenvalue table the shapes are taken as they are, and said
    write_op2(tmp_path / "nolama.op2", _modes(flexible), lama=False)
    assert "taken as mass-normalised" in fem_import.read(tmp_path / "nolama.op2").history[-1]


def test_op2_refusals(tmp_path):
    fe = _design()
    modes = _modes(fe)[:8]
    # two subcases (a free run and another): a choice, or the lowest with a warning on the command line's path
    write_op2(tmp_path / "two.op2", [m + (1,) for m in modes[:4]] + [m + (2,) for m in modes[4:]], lama=False)
    with pytest.raises(FEReadError, match=r"2 subcases \[1, 2\]"):
        fem_import.read(tmp_path / "two.op2")
    np.testing.assert_array_equal(fem_import.read(tmp_path / "two.op2", subcase=2).mode_numbers, [5, 6, 7, 8])
    # a mode that lacks a grid of the others (a file cut inside a record and patched up)
    short = [modes[0], (modes[1][0], modes[1][1], modes[1][2][:-1], modes[1][3][:-1])] + modes[2:]
    write_op2(tmp_path / "gap.op2", short)
    with pytest.raises(FEReadError, match=r"eigenvector 2 lacks grid\(s\)"):
        fem_import.read(tmp_path / "gap.op2")
    # a LAMA of more modes than eigenvectors: eigenvectors lost
    p = write_op2(tmp_path / "short.op2", modes)
    data = p.read_bytes()
    write_op2(tmp_path / "seven.op2", modes[:7])
    seven = (tmp_path / "seven.op2").read_bytes()
    lama_end = seven.index(b"OUGV1   ") - 12
    full_lama_end = data.index(b"OUGV1   ") - 12
    (tmp_path / "lost.op2").write_bytes(data[:full_lama_end] + seven[lama_end:])
    with pytest.raises(FEReadError, match=r"LAMA.*holds 8 modes, the eigenvector tables 7"):
        fem_import.read(tmp_path / "lost.op2")
    # SORT2 and complex eigenvectors by name
    for code, words in ((1007, "SORT2"), (2007, "complex eigenvectors")):
        b = bytearray(data)
        at = b.index(struct.pack("<2i", 22, 7))
        while at >= 0:
            b[at + 4:at + 8] = struct.pack("<i", code)
            at = b.find(struct.pack("<2i", 22, 7), at + 8)
        (tmp_path / "x.op2").write_bytes(bytes(b))
        with pytest.raises(FEReadError, match=words):
            fem_import.read(tmp_path / "x.op2")
    # cut inside the eigenvector table's closing markers: the table and the file are not closed
    (tmp_path / "open.op2").write_bytes(data[:-24])
    with pytest.raises(FEReadError, match="without Nastran's end-of-file records"):
        fem_import.read(tmp_path / "open.op2")


def test_lab_pair_on_the_op2_gives_the_universal_files_pairing(tmp_path):
    """End to end: the small campaign's identified modes paired with the OP2 of its design export (coordinates and
    elements from ``--geometry``, the universal file itself): the pairing of the universal file."""
    from bad_inputs_support import identify_and_pair
    from railmodal.cli import main

    modes, pairing = identify_and_pair(campaign_src(), tmp_path / "c")
    fe = fem_import.read(tmp_path / "c" / "fe_design.uff")
    write_op2(tmp_path / "ws.op2", _modes(fe))
    assert main(["-q", "lab", "pair", "--modes", str(modes), "--fem", str(tmp_path / "ws.op2"), "--geometry",
                 str(tmp_path / "c" / "fe_design.uff"), "--out", str(tmp_path / "op2_pairing")]) == 0
    ref = pd.read_csv(pairing / "pairing.csv")
    got = pd.read_csv(tmp_path / "op2_pairing" / "pairing.csv")
    assert len(got) == len(ref) > 3
    for col in ref.columns:
        if pd.api.types.is_numeric_dtype(ref[col]):
            # single-precision eigenvalues: frequencies to 3e-8, so df_pct [%] to a few 1e-6
            np.testing.assert_allclose(got[col], ref[col], rtol=1e-5, atol=1e-5, err_msg=col)
        else:
            assert got[col].tolist() == ref[col].tolist(), col


def campaign_src():
    from lab_data.cache import campaign_dir

    return campaign_dir("control")


@pytest.mark.parametrize("endian, word", [(">", 4), ("<", 8), (">", 8)])
def test_big_endian_and_64_bit_files(tmp_path, endian, word):
    """The same run in the byte orders and word sizes Nastran writes (Unix big-endian machines, ``-ilp64`` runs):
    the modes of the 32-bit little-endian file, 64-bit reals to double precision."""
    fe = _design()
    ref = fem_import.read(write_op2(tmp_path / "le32.op2", _modes(fe)[:9]))
    p = write_op2(tmp_path / "x.op2", _modes(fe)[:9], endian=endian, word=word)
    assert fem_import.detect_format(p).name == "nastran-op2"
    assert check_records(str(p)) == (endian, word)
    got = fem_import.read(p)
    np.testing.assert_array_equal(got.node_ids, ref.node_ids)
    tol = 1e-6 if word == 4 else 1e-12
    np.testing.assert_allclose(got.shapes, fe.shapes[:9], rtol=tol, atol=tol * np.abs(fe.shapes).max())
    np.testing.assert_allclose(got.freqs_hz[6:], fe.freqs_hz[6:9], rtol=tol)


def test_a_damaged_eigenvalue_is_refused(tmp_path):
    modes = _modes(_design())[:8]
    modes[7] = (modes[7][0], float("nan"), modes[7][2], modes[7][3])
    with pytest.raises(FEReadError, match="mode 8 has the frequency nan"):
        fem_import.read(write_op2(tmp_path / "nan.op2", modes, lama=False))


@pytest.mark.parametrize("rel", ["nas2cam_extseout/cant_beam.op2", "nas2cam_extseout/full.op2",
                                 "nas2cam_csuper/assemble.op2"])
def test_geom1_grids_are_the_grid_tables(rel, tmp_path, monkeypatch):
    """GEOM1 holds the input's GRIDs and CORD2s, in their CP systems; resolved, they are BGPDT's basic positions and
    CSTM's displacement directions (assemble: three grids displaced in a CORD2R). A file without the grid table
    (PARAM,POST,-2 style) reads the same modes on them."""
    import fem_import.nastran_op2 as nastran_op2

    shutil.copy(yeti_file(rel), tmp_path / "alone.op2")
    with_table = fem_import.read(tmp_path / "alone.op2")
    monkeypatch.setattr(nastran_op2, "_grid_geometry", lambda path, post, ids: None)
    without = fem_import.read(tmp_path / "alone.op2")
    assert "GEOM1 table" in without.history[-1] and "grid table" in with_table.history[-1]
    np.testing.assert_array_equal(without.node_ids, with_table.node_ids)
    np.testing.assert_allclose(without.xyz, with_table.xyz, rtol=0, atol=1e-6 * np.abs(with_table.xyz).max())
    np.testing.assert_allclose(without.shapes, with_table.shapes, rtol=0, atol=1e-6 * np.abs(with_table.shapes).max())
    assert without.elements == with_table.elements


def test_a_2007_file_without_a_grid_table_has_its_geom1_grids():
    """NX's 2007 run of the inboard model has no grid table pyYeti reads; its GEOM1 grids are where the later run's
    grid table puts the same grids."""
    old = fem_import.read(yeti_file("nas2cam_extseout/inboard_v2007.op2"))
    new = fem_import.read(yeti_file("nas2cam_extseout/inboard.op2"))
    assert "GEOM1 table" in old.history[-1] and "grid table" in new.history[-1]
    np.testing.assert_array_equal(old.node_ids, new.node_ids)
    np.testing.assert_allclose(old.xyz, new.xyz, rtol=1e-7)
    np.testing.assert_allclose(old.freqs_hz, new.freqs_hz, rtol=1e-5)
