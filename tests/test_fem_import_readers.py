"""fem_import readers on the virtual lab's design FE export, the registry, and bad files.

Oracles: the lab's manifest (design frequencies), the lab's design FE model
itself (node coordinates, assembled mass and stiffness matrices: the
imported shapes must satisfy Phi^T M Phi = I and Phi^T K Phi = diag(omega^2),
thesis eq. 2.29), and the other file format (UFF vs punch).
"""

from __future__ import annotations

import logging
import shutil

import numpy as np
import pytest

import fem_import
from fem_import import FEReadError, UnknownFormatError
from lab_data.truth import design_modes
from lab_data.wheelset import WheelsetParameters
from test_fem_import_models import dataset_2414, small_model, write_small_punch, write_small_uff, write_small_uff_2414


@pytest.fixture(scope="module")
def design():
    return design_modes(WheelsetParameters(), 500.0)


@pytest.fixture(scope="module")
def uff_modes(control_dir):
    return fem_import.read(control_dir / "fe_design.uff")


@pytest.fixture(scope="module")
def pch_modes(control_dir):
    return fem_import.read(control_dir / "fe_design.pch")


def _full_dofs(modes, design):
    """Imported shapes as (6 n, m) columns in the design model's node order."""
    rows = np.array([modes.index(n) for n in design.model.node_ids])
    return modes.shapes[:, rows, :].reshape(len(modes), -1).T


# ---------------------------------------------------------------- lab files
def test_uff_frequencies_and_nodes_match_the_design(uff_modes, control_manifest, design):
    truth = np.array([d["f_hz"] for d in control_manifest["design_modes"]])
    assert uff_modes.format == "uff" and uff_modes.has_rotations
    assert len(uff_modes) == truth.size == 25
    np.testing.assert_allclose(uff_modes.freqs_hz, truth, rtol=1e-6, atol=1e-9)
    assert np.all(uff_modes.freqs_hz[:6] == 0.0)  # rigid-body modes
    assert uff_modes.node_ids.size == design.model.n_nodes == 1129
    rows = np.array([uff_modes.index(n) for n in design.model.node_ids])
    np.testing.assert_array_equal(uff_modes.xyz[rows], design.model.xyz)  # D25.16 round-trips exactly
    counts = {}
    for e in uff_modes.elements:
        counts[e.fe_descriptor] = counts.get(e.fe_descriptor, 0) + 1
    skins = sum(e.physical_property == 99 for e in uff_modes.elements)
    assert counts == {21: 122, 94: 940, 161: 6} and skins > 0
    assert all(len(e.nodes) == {21: 2, 94: 4, 161: 1}[e.fe_descriptor] for e in uff_modes.elements)


def test_punch_gives_the_same_modes_as_uff(pch_modes, uff_modes, control_manifest):
    truth = np.array([d["f_hz"] for d in control_manifest["design_modes"]])
    assert pch_modes.format == "nastran-punch" and pch_modes.has_rotations
    np.testing.assert_allclose(pch_modes.freqs_hz, truth, rtol=1e-6, atol=1e-9)
    assert not pch_modes.has_coordinates and pch_modes.elements == ()
    assert set(pch_modes.node_ids.tolist()) == set(uff_modes.node_ids.tolist())
    rows = np.array([pch_modes.index(n) for n in uff_modes.node_ids])
    peak = np.abs(uff_modes.shapes).max(axis=(1, 2))[:, None, None]
    assert np.max(np.abs(pch_modes.shapes[:, rows] - uff_modes.shapes) / peak) < 1e-6


@pytest.mark.parametrize("which", ["uff", "pch"])
def test_shapes_are_mass_normalised_on_the_design_model(which, uff_modes, pch_modes, design):
    modes = uff_modes if which == "uff" else pch_modes
    phi = _full_dofs(modes, design)
    gram = phi.T @ (design.system.M @ phi)
    assert np.max(np.abs(gram - np.eye(len(modes)))) < 1e-5
    # stiffness: Phi^T K Phi = diag(omega^2), relative to the largest omega^2
    w2 = (2 * np.pi * modes.freqs_hz) ** 2
    kgram = phi.T @ (design.system.K @ phi)
    assert np.max(np.abs(kgram - np.diag(w2))) < 1e-5 * w2.max()
    # degenerate pairs are exported as arbitrary mixtures; the pair block is still I
    pair = np.flatnonzero(np.isclose(modes.freqs_hz, modes.freqs_hz[7], rtol=1e-6))
    assert pair.size == 2
    np.testing.assert_allclose(gram[np.ix_(pair, pair)], np.eye(2), atol=1e-5)


def test_punch_with_geometry_equals_uff(control_dir, uff_modes):
    merged = fem_import.read(control_dir / "fe_design.pch", geometry=control_dir / "fe_design.uff")
    np.testing.assert_array_equal(merged.node_ids, uff_modes.node_ids)
    np.testing.assert_array_equal(merged.xyz, uff_modes.xyz)
    assert merged.elements == uff_modes.elements
    assert np.max(np.abs(merged.shapes - uff_modes.shapes)) < 1e-6 * np.abs(uff_modes.shapes).max()
    assert any("geometry" in h for h in merged.history)
    # an FEModes works as geometry as well
    again = fem_import.read(control_dir / "fe_design.pch", geometry=uff_modes)
    np.testing.assert_array_equal(again.xyz, merged.xyz)


def test_geometry_lacking_nodes_is_an_error(tmp_path, control_dir):
    small = write_small_uff(tmp_path / "small.uff")
    with pytest.raises(FEReadError, match=r"small\.uff.*1129 node\(s\).*not in the geometry"):
        fem_import.read(control_dir / "fe_design.pch", geometry=small)
    with pytest.raises(UnknownFormatError, match="carries no node coordinates"):
        fem_import.read(control_dir / "fe_design.pch", geometry=control_dir / "fe_design.pch")


# ---------------------------------------------------------------- registry
def test_formats_are_listed():
    assert fem_import.formats()[:2] == ("uff", "nastran-punch")
    assert fem_import.format_info("PCH").name == "nastran-punch"
    assert fem_import.format_info("unv").name == "uff"


def test_sniffing_ignores_the_extension(tmp_path, control_dir, uff_modes):
    odd_uff = shutil.copy(control_dir / "fe_design.uff", tmp_path / "model.pch")
    odd_pch = shutil.copy(control_dir / "fe_design.pch", tmp_path / "export.dat")
    assert fem_import.detect_format(odd_uff).name == "uff"
    assert fem_import.detect_format(odd_pch).name == "nastran-punch"
    a = fem_import.read(odd_uff)
    b = fem_import.read(odd_pch, geometry=odd_uff)
    assert a.format == "uff" and b.format == "nastran-punch"
    np.testing.assert_array_equal(a.shapes, uff_modes.shapes)
    np.testing.assert_allclose(b.shapes, uff_modes.shapes, atol=1e-6 * np.abs(a.shapes).max())


def test_unknown_content_lists_the_formats(tmp_path):
    junk = tmp_path / "notes.uff"
    junk.write_text("modal test notes\nnothing to see\n")
    with pytest.raises(UnknownFormatError) as err:
        fem_import.read(junk)
    msg = str(err.value)
    assert "notes.uff" in msg and "uff" in msg and "nastran-punch" in msg
    assert err.value.supported[:2] == ("uff", "nastran-punch")
    assert isinstance(err.value, ValueError)
    empty = tmp_path / "empty.pch"
    empty.write_bytes(b"")
    with pytest.raises(UnknownFormatError, match="empty file"):
        fem_import.read(empty)


def test_unknown_format_name_lists_the_formats(tmp_path):
    path = write_small_uff(tmp_path / "small.uff")
    with pytest.raises(UnknownFormatError, match=r"unknown format 'abaqus-odb'.*uff.*nastran-punch"):
        fem_import.read(path, format="abaqus-odb")


def test_missing_file_is_named(tmp_path):
    with pytest.raises(FileNotFoundError, match="no_such_model.uff"):
        fem_import.read(tmp_path / "no_such_model.uff")


def test_forced_wrong_format_is_a_read_error(tmp_path):
    pch = write_small_punch(tmp_path / "small.pch")
    with pytest.raises(FEReadError, match="small.pch"):
        fem_import.read(pch, format="uff")
    uff = write_small_uff(tmp_path / "small.uff")
    with pytest.raises(FEReadError, match="no real eigenvectors"):
        fem_import.read(uff, format="punch")


# ---------------------------------------------------------------- punch specifics
def _punch_lines(tmp_path, seed=0):
    return write_small_punch(tmp_path / "base.pch", seed).read_text().splitlines(keepends=True)


def _write(tmp_path, name, lines):
    path = tmp_path / name
    path.write_text("".join(lines))
    return path


def test_punch_frequency_from_eigenvalue(tmp_path):
    lines = _punch_lines(tmp_path)
    # rigid-body modes come with tiny negative eigenvalues: 0 Hz
    k = next(i for i, ln in enumerate(lines) if ln.startswith("$EIGENVALUE"))
    lines[k] = f"{'$EIGENVALUE = -1.2345678E-06  MODE =     1':<72}{k + 1:8d}\n"
    modes = fem_import.read(_write(tmp_path, "neg.pch", lines))
    assert modes.freqs_hz[0] == 0.0
    lam = (2 * np.pi * 80.25) ** 2
    assert modes.freqs_hz[2] == pytest.approx(np.sqrt(lam) / (2 * np.pi), rel=3e-8)


def test_punch_subcases(tmp_path):
    lines = _punch_lines(tmp_path)
    block = [i for i, ln in enumerate(lines) if ln.startswith("$TITLE")]
    second = [ln.replace("$SUBCASE ID =           1", "$SUBCASE ID =           2") for ln in lines[block[2]:]]
    path = _write(tmp_path, "two.pch", lines[:block[2]] + second)
    with pytest.raises(FEReadError, match=r"two\.pch.*2 subcases \[1, 2\].*subcase="):
        fem_import.read(path)
    one = fem_import.read(path, subcase=1)
    two = fem_import.read(path, subcase=2)
    assert len(one) == 2 and len(two) == 1
    assert two.freqs_hz[0] == pytest.approx(80.25, rel=1e-7)
    with pytest.raises(FEReadError, match="subcase 7 is not in the file"):
        fem_import.read(path, subcase=7)


def test_punch_skips_scalar_points_and_other_blocks(tmp_path, caplog):
    lines = _punch_lines(tmp_path)
    plain = fem_import.read(_write(tmp_path, "plain.pch", lines))
    # a scalar point after each mode's first grid, and a displacement block up front
    out = ["$TITLE   = STATIC\n", "$DISPLACEMENTS\n", "$REAL OUTPUT\n", "$SUBCASE ID =           9\n",
           f"{11:10d}       G{1.0:18.6E}{2.0:18.6E}{3.0:18.6E}\n", f"-CONT-            {0.0:18.6E}{0.0:18.6E}{0.0:18.6E}\n"]
    for i, ln in enumerate(lines):
        out.append(ln)
        if ln.startswith("-CONT-") and lines[i - 1].startswith("        11"):
            out.append(f"{500:10d}       S{7.0:18.6E}{0.0:18.6E}{0.0:18.6E}\n")
    with caplog.at_level(logging.INFO, logger="fem_import"):
        modes = fem_import.read(_write(tmp_path, "mixed.pch", out))
    np.testing.assert_array_equal(modes.shapes, plain.shapes)
    assert 500 not in modes.node_ids
    assert "scalar-point" in caplog.text and "DISPLACEMENTS" in caplog.text


def test_punch_sorted_by_point_is_refused_with_the_request_to_change(tmp_path):
    """SORT2 (one '$POINT ID' card per grid, then a card pair per mode) is named with the SORT1 request, not read
    as grid cards keyed by mode numbers."""
    lines = _punch_lines(tmp_path)
    k = next(i for i, ln in enumerate(lines) if ln.startswith("$EIGENVALUE"))
    sort2 = lines[:k] + [f"{'$POINT ID =          11  IDENTIFIED BY MODE':<72}{k + 1:8d}\n"]
    sort2 += [f"{m:10d}       G{0.1 * m:18.6E}{0.0:18.6E}{0.0:18.6E}\n"
              f"-CONT-{'':12}{0.0:18.6E}{0.0:18.6E}{0.0:18.6E}\n" for m in (1, 2, 3)]
    with pytest.raises(FEReadError, match=rf"s2\.pch, line {k + 1}: .*SORT2.*DISPLACEMENT\(PUNCH,SORT1\)"):
        fem_import.read(_write(tmp_path, "s2.pch", sort2))


def test_punch_truncated_card_names_line(tmp_path):
    lines = _punch_lines(tmp_path)
    path = tmp_path / "cut.pch"
    path.write_text("".join(lines[:-1]) + lines[-1][:40])  # last -CONT- card cut in R2
    with pytest.raises(FEReadError, match=rf"cut\.pch, line {len(lines)}"):
        fem_import.read(path)
    path.write_text("".join(lines[:-1]))  # grid card without its continuation
    with pytest.raises(FEReadError, match=rf"line {len(lines) - 1}: grid 15 of mode 3.*-CONT-"):
        fem_import.read(path)
    path.write_text("".join(lines[:-4]))  # whole grids missing from the last mode
    with pytest.raises(FEReadError, match=r"mode 3 lacks grid\(s\) \[14, 15\]"):
        fem_import.read(path)
    k = max(i for i, ln in enumerate(lines) if ln.startswith("$TITLE"))
    path.write_text("".join(lines[:k + 3]))  # headers of mode 3 only
    with pytest.raises(FEReadError, match=rf"line {k + 1}.*header cards and no data"):
        fem_import.read(path)


def test_punch_bad_values_are_named(tmp_path):
    lines = _punch_lines(tmp_path)
    k = [i for i, ln in enumerate(lines) if ln.startswith("        13")][1]  # grid 13, mode 2
    bad = lines.copy()
    bad[k] = bad[k][:18] + f"{'NaN':>18}" + bad[k][36:]
    with pytest.raises(FEReadError, match="mode 2 has non-finite values at grid 13"):
        fem_import.read(_write(tmp_path, "nan.pch", bad))
    bad = lines.copy()
    bad[k] = bad[k][:18] + f"{'1.2.3E+00':>18}" + bad[k][36:]
    with pytest.raises(FEReadError, match=rf"line {k + 1}: grid 13 T1 .*not a number: '1.2.3E\+00'"):
        fem_import.read(_write(tmp_path, "txt.pch", bad))
    cplx = [ln.replace("$REAL OUTPUT", "$REAL-IMAGINARY OUTPUT") for ln in lines]
    with pytest.raises(FEReadError, match="complex eigenvectors"):
        fem_import.read(_write(tmp_path, "cplx.pch", cplx))


# ---------------------------------------------------------------- UFF specifics
def _uff_text(tmp_path, seed=0):
    return write_small_uff(tmp_path / "base.uff", seed).read_text()


def test_uff_nan_in_a_shape_names_mode_and_node(tmp_path):
    text = _uff_text(tmp_path)
    _, _, _, _, shapes = small_model()
    # the value of mode 2, node 13, DOF 2 (as written, 1PE13.6)
    old = f"{shapes[1, 2, 0]:13.6E}{shapes[1, 2, 1]:13.6E}"
    assert text.count(old) == 1
    path = tmp_path / "nan.uff"
    path.write_text(text.replace(old, f"{shapes[1, 2, 0]:13.6E}{'NaN':>13}"))
    with pytest.raises(FEReadError, match=r"nan\.uff, dataset 55 \(mode 2\), line \d+: mode 2 has non-finite "
                                          r"shape values at node 13"):
        fem_import.read(path)


def test_uff_mode_missing_a_node_is_named(tmp_path):
    lines = _uff_text(tmp_path).splitlines(keepends=True)
    starts = [i for i, ln in enumerate(lines) if ln.rstrip() == "    55"]
    k = next(i for i in range(starts[2], len(lines)) if lines[i].strip() == "14")  # mode 3, node 14
    path = tmp_path / "hole.uff"
    path.write_text("".join(lines[:k] + lines[k + 2:]))
    with pytest.raises(FEReadError, match=r"mode 3 lacks node\(s\) \[14\]"):
        fem_import.read(path)


def test_uff_shape_node_absent_from_2411_is_named(tmp_path):
    text = _uff_text(tmp_path)
    lines = text.splitlines(keepends=True)
    k = next(i for i, ln in enumerate(lines) if ln.startswith("        15         0"))  # node 15 in 2411
    i2412 = next(i for i, ln in enumerate(lines) if ln.rstrip() == "  2412")
    end = next(i for i in range(i2412, len(lines)) if lines[i].rstrip() == "    -1")
    # drop node 15 from 2411 and the 2412 dataset (whose elements use it)
    path = tmp_path / "orphan.uff"
    path.write_text("".join(lines[:k] + lines[k + 2:i2412 - 1] + lines[end + 1:]))
    with pytest.raises(FEReadError, match=r"node\(s\) \[15\] that are not in the node dataset"):
        fem_import.read(path)


def test_uff_element_that_repeats_a_node_is_refused(tmp_path):
    """An element listing one node twice is corrupt (the format's writers and Nastran refuse it too); elements of
    more than 8 nodes themselves are read (tests/test_fe_exports_real.py)."""
    text = _uff_text(tmp_path)
    rigid = (f"{9:10d}{122:10d}{1:10d}{1:10d}{7:10d}{10:10d}\n" + "".join(f"{n:10d}" for n in [11, 12, 13, 14, 15,
             11, 12, 13]) + "\n" + f"{14:10d}{15:10d}\n")
    i2412 = text.index("  2412\n") + len("  2412\n")
    path = tmp_path / "big.uff"
    path.write_text(text[:i2412] + rigid + text[i2412:])
    with pytest.raises(FEReadError, match=r"big\.uff, dataset 2412.*element 9 .*lists node\(s\) \[11, 12, 13, 14, 15\] "
                                          r"more than once"):
        fem_import.read(path)


def test_uff_truncated_last_dataset(tmp_path):
    text = _uff_text(tmp_path)
    path = tmp_path / "cut.uff"
    path.write_text(text[: len(text) - 200])
    n_lines = text[: len(text) - 200].count("\n")
    with pytest.raises(FEReadError, match=r"cut\.uff, line \d+: the last dataset has no closing") as err:
        fem_import.read(path)
    assert 1 < err.value.line < n_lines
    assert text.splitlines()[err.value.line - 1].rstrip() == "    -1"


def test_uff_without_modes_is_an_error(tmp_path):
    text = _uff_text(tmp_path)
    path = tmp_path / "geo.uff"
    path.write_text(text[: text.index("    -1\n    55")])
    with pytest.raises(FEReadError, match="no dataset 55"):
        fem_import.read(path)
    geo = fem_import.read_geometry(path)
    assert geo.node_ids.tolist() == [11, 12, 13, 14, 15] and len(geo.elements) == 3


def test_uff_complex_modes_are_refused(tmp_path):
    text = _uff_text(tmp_path)
    path = tmp_path / "cplx.uff"
    # Record 6 of the first 55: analysis type 3 (complex eigenvalue)
    old = f"{1:10d}{2:10d}{3:10d}{8:10d}{2:10d}{6:10d}\n"
    path.write_text(text.replace(old, f"{1:10d}{3:10d}{3:10d}{8:10d}{2:10d}{6:10d}\n", 1))
    with pytest.raises(FEReadError, match=r"dataset 55 \(mode 1\).*analysis type 3"):
        fem_import.read(path)


# ---------------------------------------------------------------- UFF 2414 (analysis data)
def test_uff_2414_modes_equal_the_same_modes_as_55(tmp_path):
    """Simcenter-style 2414 (double precision, a 6-DOF node on two 3D25.16 lines), with a nodal strain energy and
    an element stress set of the same analysis beside the shapes: the modes read as from the 55 file, to the
    55 file's own 7 significant digits (1PE13.6); the other 2414 datasets are left out."""
    ids, _, _, freqs, shapes = small_model()
    energy = dataset_2414(90, 1, freqs[1], ids, np.abs(shapes[1, :, :3]), result=7)
    stress = dataset_2414(91, 1, freqs[1], ids, shapes[1, :, :6], location=2).replace(
        f"{int(ids[0]):10d}\n", f"{1:10d}{6:10d}\n", 1)
    m2414 = fem_import.read(write_small_uff_2414(tmp_path / "nx.unv", extra=energy))
    m55 = fem_import.read(write_small_uff(tmp_path / "base.uff"))
    assert m2414.format == "uff" and m2414.has_rotations and len(m2414) == len(freqs)
    np.testing.assert_array_equal(m2414.node_ids, m55.node_ids)
    np.testing.assert_array_equal(m2414.xyz, m55.xyz)
    assert m2414.elements == m55.elements
    np.testing.assert_allclose(m2414.freqs_hz, m55.freqs_hz, rtol=1e-5)
    np.testing.assert_allclose(m2414.shapes, shapes, rtol=1e-14, atol=0)  # D25.16: exact to double precision
    np.testing.assert_allclose(m55.shapes, m2414.shapes, rtol=1e-6, atol=1e-7)
    with_stress = fem_import.read(write_small_uff_2414(tmp_path / "nx2.unv", extra=stress))
    np.testing.assert_array_equal(with_stress.shapes, m2414.shapes)


def test_uff_2414_single_precision_3dof_and_modal_mass(tmp_path):
    ids, _, _, freqs, shapes = small_model()
    m = fem_import.read(write_small_uff_2414(tmp_path / "femap.unv", double=False, n_dof=3, modal_mass=4.0))
    assert not m.has_rotations and m.shapes.shape == (len(freqs), ids.size, 3)
    np.testing.assert_allclose(m.shapes, shapes[:, :, :3] / 2.0, rtol=5e-6, atol=0)  # phi / sqrt(4)
    assert any("unit modal mass" in h for h in m.history)


def test_uff_2414_truncated_node_record_is_named(tmp_path):
    path = write_small_uff_2414(tmp_path / "cut2414.unv")
    lines = path.read_text().splitlines(keepends=True)
    starts = [i for i, ln in enumerate(lines) if ln.rstrip() == "  2414"]
    node = next(i for i in range(starts[1], len(lines)) if lines[i].strip() == "13")  # mode 2, node 13
    path.write_text("".join(lines[:node + 1] + lines[node + 2:]))  # its second line of values lost
    with pytest.raises(FEReadError, match=r"cut2414\.unv, dataset 2414 \(mode 2\), line (\d+): .*node 13") as err:
        fem_import.read(path)
    assert err.value.line == node + 1


def test_uff_2414_complex_modes_are_refused(tmp_path):
    path = write_small_uff_2414(tmp_path / "cplx2414.unv")
    text = path.read_text()
    old = "".join(f"{v:10d}" for v in (1, 2, 3, 8, 4, 6))
    path.write_text(text.replace(old, "".join(f"{v:10d}" for v in (1, 3, 3, 8, 4, 6)), 1))
    with pytest.raises(FEReadError, match=r"dataset 2414 \(mode 1\).*analysis type 3 \(complex eigenvalue\)"):
        fem_import.read(path)


def _dataset_2420(label: int, kind: int, rotation: np.ndarray, origin) -> str:
    """One dataset 2420 (coordinate systems) as I-DEAS-style exporters write it."""
    rows = [*np.asarray(rotation, float), np.asarray(origin, float)]
    return ("    -1\n  2420\n         1\nPART\n" + f"{label:10d}{kind:10d}{8:10d}\nLOCAL {label}\n"
            + "".join("".join(f"{v:25.16E}" for v in r) + "\n" for r in rows) + "    -1\n")


def _nodes_in_system(text: str, nodes, label: int) -> str:
    for n in nodes:
        old = f"{n:10d}{0:10d}{0:10d}{1:10d}\n"
        assert text.count(old) == 1
        text = text.replace(old, f"{n:10d}{label:10d}{label:10d}{1:10d}\n")
    return text


@pytest.mark.parametrize("kind, rotation, origin, refused", [
    (0, np.eye(3), (0.0, 0.0, 0.0), None),                                  # the global system under label 5
    (0, [[0, 1, 0], [-1, 0, 0], [0, 0, 1]], (0.0, 0.0, 0.0), "Cartesian"),  # rotated 90 deg about z
    (0, np.eye(3), (0.0, 0.0, 0.75), "Cartesian"),                          # shifted to the wheel's plane
    (1, np.eye(3), (0.0, 0.0, 0.0), "cylindrical"),                         # r, theta, z about the axle
])
def test_uff_nodes_in_a_local_coordinate_system(tmp_path, caplog, kind, rotation, origin, refused):
    """Nodes whose coordinates and displacements are in a local system of dataset 2420: read when that system is
    the global one under another label, otherwise refused with the nodes and the system named (taking local
    coordinates or shapes as global would give a wrong geometry and wrong MACs without a word)."""
    text = _uff_text(tmp_path)
    base = fem_import.read(tmp_path / "base.uff")
    path = tmp_path / "local.uff"
    path.write_text(_dataset_2420(5, kind, rotation, origin) + _nodes_in_system(text, (12, 13), 5))
    if refused is None:
        with caplog.at_level(logging.WARNING, logger="fem_import"):
            got = fem_import.read(path)
        assert not [r for r in caplog.records if "coordinate system" in r.getMessage()]
        np.testing.assert_array_equal(got.shapes, base.shapes)
        np.testing.assert_array_equal(got.xyz, base.xyz)
        return
    with pytest.raises(FEReadError, match=rf"local\.uff, dataset 2411.*2 node\(s\) \(12-13\) give their coordinates "
                                          rf"and displacements in coordinate system 5 \({refused}, 'LOCAL 5'"):
        fem_import.read(path)


def test_uff_nodes_in_an_undefined_coordinate_system_are_read_with_a_warning(tmp_path, caplog):
    text = _uff_text(tmp_path)
    path = tmp_path / "undefined.uff"
    path.write_text(_nodes_in_system(text, (12,), 7))
    with caplog.at_level(logging.WARNING, logger="fem_import"):
        got = fem_import.read(path)
    assert any("coordinate systems [7] that no dataset 2420 or 18 defines" in r.getMessage() for r in caplog.records)
    np.testing.assert_array_equal(got.xyz, fem_import.read(tmp_path / "base.uff").xyz)
