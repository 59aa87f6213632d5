"""MSC Nastran HDF5 results (:mod:`fem_import.nastran_h5`).

No MSC Nastran run is at hand, so the files are written here with h5py in MSC's schema (the tables and field names
MSC Nastran 2020 writes: ``/NASTRAN/INPUT/NODE/GRID``, ``/NASTRAN/RESULT/NODAL/EIGENVECTOR`` with its index,
``/NASTRAN/RESULT/DOMAINS``, ``/NASTRAN/RESULT/SUMMARY/EIGENVALUE``, the element and coordinate-system tables).
The oracle is the lab's design export (universal file) the HDF5 file is written from: the modes, coordinates and
elements must come back; a cylindrical CP/CD system must turn back to the plain file's basic components; the
pairing made on it must be the universal file's.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import fem_import
from fem_import.errors import FEReadError

h5py = pytest.importorskip("h5py")


def _write(group, name: str, fields: list, rows: list):
    """A compound table: ``fields`` [(name, dtype, shape)], ``rows`` tuples in that order."""
    dt = np.dtype([(n, t, s) if s else (n, t) for n, t, s in fields])
    data = np.zeros(len(rows), dtype=dt)
    for k, row in enumerate(rows):
        for (n, _, _), v in zip(fields, row):
            data[n][k] = v
    group.create_dataset(name, data=data)


I8, F8 = "<i8", "<f8"
DOMAIN_FIELDS = [("ID", I8, ()), ("SUBCASE", I8, ()), ("STEP", I8, ()), ("ANALYSIS", I8, ()),
                 ("TIME_FREQ_EIGR", F8, ()), ("EIGI", F8, ()), ("MODE", I8, ()), ("DESIGN_CYCLE", I8, ()),
                 ("RANDOM", I8, ()), ("SE", I8, ()), ("AFPM", I8, ()), ("TRMC", I8, ()), ("INSTANCE", I8, ()),
                 ("MODULE", I8, ()), ("SUBSTEP", I8, ()), ("IMPFID", I8, ())]
VECTOR_FIELDS = [("ID", I8, ())] + [(c, F8, ()) for c in ("X", "Y", "Z", "RX", "RY", "RZ")] + [("DOMAIN_ID", I8, ())]
EIGEN_FIELDS = [("MODE", I8, ()), ("ORDER", I8, ()), ("EIGEN", F8, ()), ("OMEGA", F8, ()), ("FREQ", F8, ()),
                ("MASS", F8, ()), ("STIFF", F8, ()), ("RESFLG", I8, ()), ("FLDFLG", I8, ()), ("DOMAIN_ID", I8, ())]


def write_h5(path: Path, fe, *, gen_mass=None, subcases=None, cylindrical: bool = False, spoints=(),
             elements=True, index=True, complex_modes=False) -> Path:
    """The modes of ``fe`` as MSC Nastran writes them to ``jobname.h5``. ``cylindrical``: every grid given in a
    cylindrical system 5 (axis along basic y through (0.1, 0, 0.2)), CP = CD = 5, and its eigenvector components
    radial, tangential, axial there."""
    m = len(fe)
    gm = np.ones(m) if gen_mass is None else np.asarray(gen_mass, float)
    sub = np.ones(m, int) if subcases is None else np.asarray(subcases, int)
    lam = (2 * np.pi * fe.freqs_hz) ** 2
    origin = np.array([0.1, 0.0, 0.2])
    axes = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])  # columns e1 = z, e2 = x, e3 = y
    xyz, shapes = fe.xyz.copy(), fe.shapes.copy()
    if cylindrical:
        local = (xyz - origin) @ axes  # components along e1, e2, e3
        r, theta = np.hypot(local[:, 0], local[:, 1]), np.arctan2(local[:, 1], local[:, 0])
        xyz = np.column_stack([r, np.degrees(theta), local[:, 2]])
        for k in range(fe.node_ids.size):
            c, s = np.cos(theta[k]), np.sin(theta[k])
            frame = axes @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
            for j in (0, 3):
                shapes[:, k, j:j + 3] = shapes[:, k, j:j + 3] @ frame  # basic -> (radial, tangential, axial)
    with h5py.File(path, "w") as f:
        f.attrs["SCHEMA"] = np.array([20200])
        nas = f.create_group("NASTRAN")
        nas.attrs["VERSION"] = np.bytes_(b"msc20200")
        node = nas.create_group("INPUT/NODE")
        cs = 5 if cylindrical else 0
        _write(node, "GRID", [("ID", I8, ()), ("CP", I8, ()), ("X", F8, (3,)), ("CD", I8, ()), ("PS", I8, ()),
                              ("SEID", I8, ()), ("DOMAIN_ID", I8, ())],
               [(int(g), cs, xyz[k], cs, 0, 0, 1) for k, g in enumerate(fe.node_ids)])
        if spoints:
            _write(node, "SPOINT", [("ID", I8, ()), ("DOMAIN_ID", I8, ())], [(s, 1) for s in spoints])
        if cylindrical:
            coords = nas.create_group("INPUT/COORDINATE_SYSTEM")
            b, c = origin + axes[:, 2], origin + axes[:, 0]
            _write(coords, "CORD2C", [(n, I8, ()) for n in ("CID", "RID")] + [(n, F8, ()) for n in (
                "A1", "A2", "A3", "B1", "B2", "B3", "C1", "C2", "C3")] + [("DOMAIN_ID", I8, ())],
                   [(5, 0, *origin, *b, *c, 1)])
        if elements:
            el = nas.create_group("INPUT/ELEMENT")
            bars = [e for e in fe.elements if e.fe_descriptor == 21]
            quads = [e for e in fe.elements if e.fe_descriptor == 94]
            masses = [e for e in fe.elements if e.fe_descriptor == 161]
            _write(el, "CBAR", [(n, I8, ()) for n in ("EID", "PID", "GA", "GB", "FLAG")]
                   + [(n, F8, ()) for n in ("X1", "X2", "X3")] + [(n, I8, ()) for n in ("GO", "PA", "PB")]
                   + [(n, F8, ()) for n in ("W1A", "W2A", "W3A", "W1B", "W2B", "W3B")] + [("DOMAIN_ID", I8, ())],
                   [(e.element_id, max(e.physical_property, 1), *e.nodes, 1, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1)
                    for e in bars])
            _write(el, "CQUAD4", [("EID", I8, ()), ("PID", I8, ()), ("G", I8, (4,)), ("THETA", F8, ()),
                                  ("ZOFFS", F8, ()), ("TFLAG", I8, ()), ("T", F8, (4,)), ("MCID", I8, ()),
                                  ("DOMAIN_ID", I8, ())],
                   [(e.element_id, max(e.physical_property, 1), e.nodes, 0, 0, 0, (0, 0, 0, 0), -1, 1)
                    for e in quads])
            _write(el, "CONM2", [("EID", I8, ()), ("G", I8, ()), ("CID", I8, ()), ("M", F8, ())]
                   + [(n, F8, ()) for n in ("X1", "X2", "X3", "I1")] + [("I2", F8, (2,)), ("I3", F8, (3,)),
                                                                        ("DOMAIN_ID", I8, ())],
                   [(e.element_id, e.nodes[0], 0, 1.0, 0, 0, 0, 0, (0, 0), (0, 0, 0), 1) for e in masses])
        res = nas.create_group("RESULT")
        # domain 1: the subcase's summary; 2..: one per mode
        subs = sorted(set(sub.tolist()))
        domains = [(k + 1, s, 0, 2, 0.0, 0.0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0) for k, s in enumerate(subs)]
        first = len(domains) + 1
        domains += [(first + k, int(sub[k]), 1, 2, lam[k], 0.0, int(n), 0, 0, 0, 0, 0, 0, 0, 0, 0)
                    for k, n in enumerate(fe.mode_numbers)]
        _write(res, "DOMAINS", DOMAIN_FIELDS, domains)
        rows, idx = [], []
        for k in range(m):
            start = len(rows)
            rows += [(int(g), *shapes[k, j], first + k) for j, g in enumerate(fe.node_ids)]
            rows += [(s, 0.0, 0, 0, 0, 0, 0, first + k) for s in spoints]
            idx.append((first + k, start, len(rows) - start))
        _write(res.create_group("NODAL"), "EIGENVECTOR_CPLX" if complex_modes else "EIGENVECTOR", VECTOR_FIELDS, rows)
        if index:
            _write(f.create_group("INDEX/NASTRAN/RESULT/NODAL"), "EIGENVECTOR",
                   [("DOMAIN_ID", I8, ()), ("POSITION", I8, ()), ("LENGTH", I8, ())], idx)
        w = np.sqrt(np.maximum(lam, 0))
        _write(res.create_group("SUMMARY"), "EIGENVALUE", EIGEN_FIELDS,
               [(int(n), k + 1, lam[k], w[k], w[k] / 2 / np.pi, gm[k], gm[k] * lam[k], 0, 0, subs.index(sub[k]) + 1)
                for k, n in enumerate(fe.mode_numbers)])
    return path


@pytest.fixture(scope="module")
def design():
    from lab_data.cache import campaign_dir

    return fem_import.read(campaign_dir("control") / "fe_design.uff")


def _same(got, fe, rtol=1e-12):
    np.testing.assert_array_equal(got.node_ids, fe.node_ids)
    np.testing.assert_array_equal(got.mode_numbers, fe.mode_numbers)
    np.testing.assert_allclose(got.xyz, fe.xyz, atol=1e-12)
    np.testing.assert_allclose(got.freqs_hz, fe.freqs_hz, rtol=rtol, atol=1e-9)
    np.testing.assert_allclose(got.shapes, fe.shapes, rtol=rtol, atol=rtol * np.abs(fe.shapes).max())


def test_the_design_export_as_hdf5(tmp_path, design, caplog):
    p = write_h5(tmp_path / "ws.h5", design, spoints=(99001, 99002))
    assert fem_import.detect_format(p).name == "nastran-h5"
    with caplog.at_level(logging.INFO, logger="fem_import"):
        got, where = fem_import.read_with_geometry(p)
    assert "ws.h5" in where and "2 eigenvector rows" not in caplog.text and "50 eigenvector rows" in caplog.text
    _same(got, design)
    mesh = sorted((e.element_id, e.fe_descriptor, e.nodes) for e in got.elements)
    assert mesh == sorted((e.element_id, e.fe_descriptor, e.nodes) for e in design.elements)
    assert len(mesh) == 1068


def test_a_cylindrical_system_turns_back_to_basic(tmp_path, design):
    """Every grid placed by (R, theta, z) in a CORD2C and its eigenvector given radial, tangential, axial: the
    plain file's coordinates and components."""
    got = fem_import.read(write_h5(tmp_path / "cyl.h5", design, cylindrical=True))
    assert any("rotated from their displacement coordinate systems" in h for h in got.history)
    _same(got, design, rtol=1e-9)


def test_norm_max_subcases_and_the_index(tmp_path, design):
    flexible = fem_import.FEModes(design.node_ids, design.xyz, design.elements, design.freqs_hz[6:],
                                  design.shapes[6:], design.modal_mass[6:], mode_numbers=design.mode_numbers[6:])
    c = 1.0 / np.abs(flexible.shapes).max(axis=(1, 2))
    scaled = fem_import.FEModes(flexible.node_ids, flexible.xyz, flexible.elements, flexible.freqs_hz,
                                flexible.shapes * c[:, None, None], flexible.modal_mass,
                                mode_numbers=flexible.mode_numbers)
    got = fem_import.read(write_h5(tmp_path / "max.h5", scaled, gen_mass=c ** 2, index=False))
    assert "summary's generalized mass" in got.history[1]
    _same(got, flexible, rtol=1e-12)
    two = write_h5(tmp_path / "two.h5", design, subcases=[1] * 10 + [2] * 15)
    with pytest.raises(FEReadError, match=r"2 subcases \[1, 2\]"):
        fem_import.read(two)
    np.testing.assert_array_equal(fem_import.read(two, subcase=2).mode_numbers, design.mode_numbers[10:])


def test_hdf5_refusals(tmp_path, design):
    p = write_h5(tmp_path / "ws.h5", design)
    with pytest.raises(FEReadError, match="complex eigenvectors"):
        fem_import.read(write_h5(tmp_path / "cplx.h5", design, complex_modes=True))
    data = p.read_bytes()
    (tmp_path / "cut.h5").write_bytes(data[:len(data) // 2])
    with pytest.raises(FEReadError, match="cannot be opened"):
        fem_import.read(tmp_path / "cut.h5")
    with h5py.File(tmp_path / "other.h5", "w") as f:
        f.create_dataset("data", data=np.arange(3))
    with pytest.raises(FEReadError, match="without MSC Nastran's /NASTRAN group"):
        fem_import.read(tmp_path / "other.h5")
    with h5py.File(p, "a") as f:  # the index points past the table
        idx = f["INDEX/NASTRAN/RESULT/NODAL/EIGENVECTOR"][()]
        idx["LENGTH"][-1] += 5
        f["INDEX/NASTRAN/RESULT/NODAL/EIGENVECTOR"][...] = idx
    with pytest.raises(FEReadError, match="outside the table's"):
        fem_import.read(p)
    p = write_h5(tmp_path / "nofield.h5", design)
    with h5py.File(p, "a") as f:
        old = f["NASTRAN/INPUT/NODE/GRID"][()]
        del f["NASTRAN/INPUT/NODE/GRID"]
        names = [n for n in old.dtype.names if n != "CD"]
        f["NASTRAN/INPUT/NODE"].create_dataset("GRID", data=old[names])
    with pytest.raises(FEReadError, match=r"GRID lacks the field\(s\) \['CD'\]"):
        fem_import.read(p)


def test_lab_pair_on_the_hdf5_file_gives_the_universal_files_pairing(tmp_path):
    from bad_inputs_support import identify_and_pair
    from lab_data.cache import campaign_dir
    from railmodal.cli import main

    modes, pairing = identify_and_pair(campaign_dir("control"), tmp_path / "c")
    fe = fem_import.read(tmp_path / "c" / "fe_design.uff")
    write_h5(tmp_path / "ws.h5", fe)
    assert main(["-q", "lab", "pair", "--modes", str(modes), "--fem", str(tmp_path / "ws.h5"), "--out",
                 str(tmp_path / "h5_pairing")]) == 0
    ref = pd.read_csv(pairing / "pairing.csv")
    got = pd.read_csv(tmp_path / "h5_pairing" / "pairing.csv")
    pd.testing.assert_frame_equal(got, ref, check_exact=False, rtol=1e-9, atol=1e-9)
