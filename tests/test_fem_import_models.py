"""Small FE model files for the fem_import tests, and tests on files written by pyuff itself.

The writers here are shared with the other ``test_fem_import*`` files
(imported as ``test_fem_import_models``):

* :func:`small_model` / :func:`write_small_uff` / :func:`write_small_punch`:
  a 5-node model (a quad, a beam, a lumped mass) with 3 modes, written by
  the virtual lab's exporters (6 DOF, 7 significant digits);
* :func:`write_pyuff_modes`: any nodes/shapes written with pyuff's own
  writers (``prepare_164/2411/2412/55``, ``E13.5``), 3 or 6 DOF, any modal
  mass and unit system.
"""

from __future__ import annotations

import logging
import math

import numpy as np
import pytest
import pyuff

import fem_import
from fem_import import FEReadError
from lab_data.nastran_punch import write_punch_eigenvectors
from lab_data.uff_export import ElementRecord, write_fe_uff

SMALL_IDS = np.array([11, 12, 13, 14, 15])
SMALL_XYZ = np.array([[0.0, 0.0, 0.0], [0.4, 0.0, 0.0], [0.4, 0.3, 0.0], [0.0, 0.3, 0.0], [0.0, 0.3, 0.5]])
SMALL_FREQS = np.array([0.0, 12.5, 80.25])


def small_model(seed: int = 0):
    """Nodes, elements, frequencies and (3, 5, 6) shapes of the small test model."""
    rng = np.random.default_rng(seed)
    shapes = rng.normal(scale=0.3, size=(SMALL_FREQS.size, SMALL_IDS.size, 6))
    elements = [ElementRecord(1, 94, 1, 1, 8, (11, 12, 13, 14)),
                ElementRecord(2, 21, 2, 1, 7, (14, 15)),
                ElementRecord(3, 161, 5, 1, 2, (15,))]
    return SMALL_IDS, SMALL_XYZ, elements, SMALL_FREQS, shapes


def write_small_uff(path, seed: int = 0):
    ids, xyz, elements, freqs, shapes = small_model(seed)
    write_fe_uff(path, ids, xyz, elements, freqs, shapes, model_name="small test model")
    return path


def dataset_2414(label, mode_n, freq, ids, values, *, double=True, analysis=2, result=8, location=1,
                  modal_mass=1.0) -> str:
    """One dataset 2414 as FE post-processors write it: double precision as 3D25.16 (a 6-DOF node on two
    lines), single precision as 6E13.5."""
    per = values.shape[1]
    out = ["    -1", "  2414", f"{label:10d}", f"MODE {mode_n}", f"{location:10d}", "NONE", "NONE", "NONE", "NONE",
           f" MODE SAME{mode_n:10d} FREQUENCY{freq:13.5E}",
           "".join(f"{v:10d}" for v in (1, analysis, 2 if per == 3 else 3, result, 4 if double else 2, per)),
           "".join(f"{v:10d}" for v in (1, 0, 1, 0, 1, mode_n, 0, 0)), f"{0:10d}{0:10d}",
           "".join(f"{v:13.5E}" for v in (0.0, freq, (2 * np.pi * freq) ** 2, modal_mass, 0.0, 0.0)),
           "".join(f"{0.0:13.5E}" for _ in range(6))]
    per_line = 3 if double else 6
    for n, row in zip(ids, values):
        out.append(f"{int(n):10d}")
        for a in range(0, per, per_line):
            chunk = row[a:a + per_line]
            out.append("".join(f"{v:25.16E}".replace("E", "D") if double else f"{v:13.5E}" for v in chunk))
    out.append("    -1")
    return "\n".join(out) + "\n"


def write_small_uff_2414(path, seed: int = 0, *, double=True, n_dof=6, extra="", modal_mass=1.0):
    """The small model's 164/2411/2412 (as :func:`write_small_uff` writes them) with its modes as 2414 datasets
    instead of 55; ``extra`` (datasets' text) goes before them."""
    text = write_small_uff(path, seed).read_text()
    ids, _, _, freqs, shapes = small_model(seed)
    body = "".join(dataset_2414(k + 1, k + 1, f, ids, shapes[k, :, :n_dof], double=double, modal_mass=modal_mass)
                   for k, f in enumerate(freqs))
    path.write_text(text[: text.index("    -1\n    55")] + extra + body)
    return path


def write_small_punch(path, seed: int = 0):
    ids, _, _, freqs, shapes = small_model(seed)
    write_punch_eigenvectors(path, ids, freqs, shapes, title="SMALL TEST MODEL")
    return path


def write_pyuff_modes(path, ids, xyz, freqs, shapes, *, modal_mass=1.0, units=(1, "SI", 1.0, 1.0),
                      elements=None):
    """Write 164 + 2411 (+ 2412) + one 55 per mode with pyuff's writers.

    ``shapes`` (m, n, 3 or 6); ``units`` = (code, description, length factor,
    force factor); ``elements`` = {descriptor: [(element id, node labels), ...]}
    (no beams: pyuff writes the beam record only for descriptor 11).
    """
    ids = np.asarray(ids)
    shapes = np.asarray(shapes, float)
    n_dof = shapes.shape[2]
    sets = [pyuff.prepare_164(units_code=units[0], units_description=units[1], temp_mode=2, length=units[2],
                              force=units[3], temp=1.0, temp_offset=273.15),
            pyuff.prepare_2411(node_nums=ids, def_cs=np.zeros(ids.size, int), disp_cs=np.zeros(ids.size, int),
                               color=np.ones(ids.size, int), x=xyz[:, 0], y=xyz[:, 1], z=xyz[:, 2])]
    if elements:
        dset = {"type": 2412}
        for desc, items in elements.items():
            dset[desc] = [{"element_nums": eid, "fe_descriptor": desc, "phys_table": 1, "mat_table": 1, "color": 8,
                           "num_nodes": len(nodes), "nodes_nums": list(nodes)} for eid, nodes in items]
        sets.append(dset)
    mm = np.broadcast_to(np.asarray(modal_mass, float), (len(freqs),))
    for k, f in enumerate(freqs):
        kw = {f"r{i + 1}": shapes[k, :, i] for i in range(n_dof)}
        sets.append(pyuff.prepare_55(model_type=1, analysis_type=2, data_ch=2 if n_dof == 3 else 3,
                                     spec_data_type=8, data_type=2, n_data_per_node=n_dof, load_case=1,
                                     mode_n=k + 1, freq=float(f), modal_m=float(mm[k]), modal_damp_vis=0.0,
                                     modal_damp_his=0.0, node_nums=ids, id1="pyuff test", **kw))
    uf = pyuff.UFF(str(path))
    uf.write_sets(sets, mode="overwrite")
    return path


PLATE_IDS = np.array([1, 2, 3, 4, 5, 6])
PLATE_XYZ = np.array([[0, 0, 0], [0.5, 0, 0], [1.0, 0, 0], [0, 0.5, 0], [0.5, 0.5, 0], [1.0, 0.5, 0]], float)
PLATE_ELEMENTS = {94: [(1, (1, 2, 5, 4))], 91: [(2, (2, 3, 6)), (3, (2, 6, 5))]}


def _plate_shapes(n_dof, seed=1):
    return np.random.default_rng(seed).normal(scale=0.2, size=(3, PLATE_IDS.size, n_dof))


def test_pyuff_3dof_file_reads_translations_only(tmp_path):
    shapes = _plate_shapes(3)
    freqs = [0.0, 33.3, 101.0]
    path = write_pyuff_modes(tmp_path / "plate3.unv", PLATE_IDS, PLATE_XYZ, freqs, shapes, elements=PLATE_ELEMENTS)
    modes = fem_import.read(path)
    assert modes.format == "uff" and not modes.has_rotations
    assert modes.shapes.shape == (3, 6, 3)
    np.testing.assert_array_equal(modes.node_ids, PLATE_IDS)
    np.testing.assert_allclose(modes.xyz, PLATE_XYZ, rtol=0, atol=1e-15)
    # pyuff writes E13.5: 6 significant digits, relative rounding <= 5e-6
    np.testing.assert_allclose(modes.shapes, shapes, rtol=5e-6, atol=0)
    np.testing.assert_allclose(modes.freqs_hz, freqs, rtol=5e-6)
    kinds = sorted((e.fe_descriptor, e.nodes) for e in modes.elements)
    assert kinds == [(91, (2, 3, 6)), (91, (2, 6, 5)), (94, (1, 2, 5, 4))]


def test_modal_mass_four_halves_the_shapes(tmp_path):
    shapes = _plate_shapes(6)
    freqs = [0.0, 33.3, 101.0]
    one = fem_import.read(write_pyuff_modes(tmp_path / "m1.uff", PLATE_IDS, PLATE_XYZ, freqs, shapes))
    four = fem_import.read(write_pyuff_modes(tmp_path / "m4.uff", PLATE_IDS, PLATE_XYZ, freqs, shapes,
                                             modal_mass=[4.0, 4.0, 0.25]))
    np.testing.assert_allclose(four.shapes[:2], one.shapes[:2] / 2.0, rtol=1e-15)
    np.testing.assert_allclose(four.shapes[2], one.shapes[2] * 2.0, rtol=1e-15)
    np.testing.assert_array_equal(four.modal_mass, [1.0, 1.0, 1.0])
    assert any("unit modal mass" in h and "m=4" in h for h in four.history)
    assert not any("modal mass" in h for h in one.history)


def test_modal_mass_zero_is_taken_as_normalised_with_a_warning(tmp_path, caplog):
    shapes = _plate_shapes(3)
    path = write_pyuff_modes(tmp_path / "m0.uff", PLATE_IDS, PLATE_XYZ, [1.0, 2.0, 3.0], shapes, modal_mass=0.0)
    with caplog.at_level(logging.WARNING, logger="fem_import"):
        modes = fem_import.read(path)
    np.testing.assert_allclose(modes.shapes, shapes, rtol=5e-6)
    assert "modal mass 0" in caplog.text and "assumed mass-normalised" in caplog.text


def test_mm_tonne_units_convert_to_si_rigid_body_closed_form(tmp_path):
    """A rigid body in mm, t, s, N (units code 9, user defined): mass m at node 1, inertia J about z, node 2 at 1 m on x.

    Mass-normalised rigid modes in SI: x-translation u = 1/sqrt(m) at both
    nodes; z-rotation theta = 1/sqrt(J), node 2 moves u_y = theta * 1 m.  In
    the file the same physics is written in file units: m_file = m * 1e-3 t,
    J_file = J * 1e3 t mm^2, lengths in mm.
    """
    m, J = 250.0, 40.0
    m_f, J_f = m * 1e-3, J * 1e3
    xyz_mm = np.array([[0.0, 0.0, 0.0], [1000.0, 0.0, 0.0]])
    shapes_f = np.zeros((2, 2, 6))
    shapes_f[0, :, 0] = 1 / math.sqrt(m_f)
    shapes_f[1, :, 5] = 1 / math.sqrt(J_f)
    shapes_f[1, 1, 1] = 1000.0 / math.sqrt(J_f)
    path = write_pyuff_modes(tmp_path / "mm.unv", [1, 2], xyz_mm, [0.0, 0.0], shapes_f,
                             units=(9, "mm t s N", 1000.0, 1.0))
    modes = fem_import.read(path)
    np.testing.assert_allclose(modes.xyz, [[0, 0, 0], [1.0, 0, 0]], rtol=0, atol=1e-15)
    np.testing.assert_allclose(modes.shapes[0, :, 0], 1 / math.sqrt(m), rtol=5e-6)
    np.testing.assert_allclose(modes.shapes[1, :, 5], 1 / math.sqrt(J), rtol=5e-6)
    assert modes.shapes[1, 1, 1] == pytest.approx(1.0 / math.sqrt(J), rel=5e-6)
    assert "converted from units code 9" in modes.units
    # and the rigid link still holds in SI: u_y(node 2) = theta_z * 1 m
    assert modes.at_points([1], [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])[0, 1] == pytest.approx(
        modes.shapes[1, 1, 1], rel=1e-5)


def test_non_si_units_without_factors_are_refused(tmp_path):
    path = write_pyuff_modes(tmp_path / "ft.uff", PLATE_IDS, PLATE_XYZ, [1.0, 2.0, 3.0], _plate_shapes(3),
                             units=(2, "BG: Foot (pound f)", 0.0, 0.0))
    with pytest.raises(FEReadError, match=r"ft\.uff.*dataset 164.*non-SI units code 2"):
        fem_import.read(path)


def test_si_code_with_inconsistent_factors_is_refused(tmp_path):
    path = write_pyuff_modes(tmp_path / "si.uff", PLATE_IDS, PLATE_XYZ, [1.0, 2.0, 3.0], _plate_shapes(3),
                             units=(1, "SI", 1000.0, 1.0))
    with pytest.raises(FEReadError, match="units code 1"):
        fem_import.read(path)


def test_small_lab_written_files_round_trip(tmp_path):
    ids, xyz, elements, freqs, shapes = small_model()
    uff = fem_import.read(write_small_uff(tmp_path / "small.uff"))
    pch = fem_import.read(write_small_punch(tmp_path / "small.pch"), geometry=uff)
    for modes in (uff, pch):
        np.testing.assert_array_equal(modes.node_ids, ids)
        np.testing.assert_allclose(modes.shapes, shapes, rtol=5e-7)
        np.testing.assert_allclose(modes.freqs_hz, freqs, rtol=5e-7)
        np.testing.assert_allclose(modes.xyz, xyz, atol=1e-15)
        assert sorted(e.element_id for e in modes.elements) == [1, 2, 3]


def test_node_order_follows_2411_whatever_the_order_of_the_shapes(tmp_path):
    ids, xyz, elements, freqs, shapes = small_model()
    uff = fem_import.read(write_small_uff(tmp_path / "small.uff"))
    # punch grids in reverse order, merged with the UFF geometry: back in 2411 order
    write_punch_eigenvectors(tmp_path / "rev.pch", ids[::-1], freqs, shapes[:, ::-1], title="REVERSED")
    rev = fem_import.read(tmp_path / "rev.pch")
    np.testing.assert_array_equal(rev.node_ids, ids[::-1])
    merged = fem_import.read(tmp_path / "rev.pch", geometry=tmp_path / "small.uff")
    np.testing.assert_array_equal(merged.node_ids, ids)
    np.testing.assert_array_equal(merged.shapes, uff.shapes)
    # a dataset 55 listing its nodes in another order than 2411
    lines = (tmp_path / "small.uff").read_text().splitlines(keepends=True)
    first = next(i for i, ln in enumerate(lines) if ln.rstrip() == "    55")
    body = first + 9  # after the 5 ID lines and records 6-8
    pairs = [lines[body + 2 * j: body + 2 * j + 2] for j in range(5)]
    lines[body: body + 10] = [ln for pair in pairs[::-1] for ln in pair]
    (tmp_path / "shuffled.uff").write_text("".join(lines))
    shuffled = fem_import.read(tmp_path / "shuffled.uff")
    np.testing.assert_array_equal(shuffled.node_ids, ids)
    np.testing.assert_array_equal(shuffled.shapes, uff.shapes)


def test_legacy_dataset_15_nodes(tmp_path):
    shapes = _plate_shapes(3)[:, :3]
    ids, xyz = PLATE_IDS[:3], PLATE_XYZ[:3] + [0.0, 0.0, 0.125]
    sets = [pyuff.prepare_15(node_nums=ids.tolist(), def_cs=[0] * 3, disp_cs=[0] * 3, color=[1] * 3,
                             x=xyz[:, 0].tolist(), y=xyz[:, 1].tolist(), z=xyz[:, 2].tolist())]
    for k in range(2):
        sets.append(pyuff.prepare_55(model_type=1, analysis_type=2, data_ch=2, spec_data_type=8, data_type=2,
                                     n_data_per_node=3, load_case=1, mode_n=k + 1, freq=10.0 * (k + 1), modal_m=1.0,
                                     modal_damp_vis=0.0, modal_damp_his=0.0, node_nums=ids,
                                     r1=shapes[k, :, 0], r2=shapes[k, :, 1], r3=shapes[k, :, 2]))
    pyuff.UFF(str(tmp_path / "legacy.unv")).write_sets(sets, mode="overwrite")
    modes = fem_import.read(tmp_path / "legacy.unv")
    np.testing.assert_allclose(modes.xyz, xyz, rtol=5e-6)  # E13.5
    np.testing.assert_allclose(modes.shapes, shapes[:2], rtol=5e-6)
    assert modes.units == "SI (m, kg, s)"  # no dataset 164: SI assumed


def test_a_plugin_format_registers_and_is_sniffed(tmp_path):
    def sniff(head):
        return head.startswith(b"#tiny-modes")

    def reader(path):
        vals = np.loadtxt(path, comments="#")
        return fem_import.FEModes(node_ids=[1], xyz=[[0, 0, 0]], elements=(), freqs_hz=vals[:, 0],
                                  shapes=vals[:, None, 1:4], modal_mass=np.ones(len(vals)), source=str(path),
                                  format="tiny")

    fem_import.register_format("tiny", patterns=("*.tiny",), sniff=sniff, reader=reader)
    try:
        with pytest.raises(ValueError, match="already registered"):
            fem_import.register_format("tiny", patterns=(), sniff=sniff, reader=reader)
        path = tmp_path / "x.txt"
        path.write_text("#tiny-modes\n5.0 1 0 0\n9.0 0 1 0\n")
        modes = fem_import.read(path)
        assert modes.format == "tiny" and modes.freqs_hz.tolist() == [5.0, 9.0]
        assert "tiny" in fem_import.formats()
    finally:
        fem_import.unregister_format("tiny")
    assert "tiny" not in fem_import.formats()
    with pytest.raises(fem_import.UnknownFormatError, match="supported formats"):
        fem_import.read(path)
