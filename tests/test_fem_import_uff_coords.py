"""UFF dataset 18 coordinate systems: nodes and mode shapes given in local systems read as the global model.

Oracle: the small test model written in the global system (``write_small_uff_2414``) and the same model written
with some nodes' coordinates in a rotated, shifted Cartesian system and some nodes' displacement components in
that system or in a cylindrical one (defined in the first: a nested reference), each local value computed here
from the definition points with its own algebra (not :mod:`fem_import.uff_coords`). Both files must read the same
to the precision of dataset 18's points (E13.5: six digits).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import fem_import
from fem_import import FEReadError
from test_fem_import_models import dataset_2414, small_model, write_small_uff_2414


def _rotation(ax: float, az: float) -> np.ndarray:
    cx, sx, cz, sz = math.cos(ax), math.sin(ax), math.cos(az), math.sin(az)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ rx


#: system 5: Cartesian, axes = columns of R5 in global, origin O5; system 6: cylindrical about the global y axis
#: through (0.2, *, 0.25) (an axle), defined in system 5's coordinates
R5, O5 = _rotation(0.35, 0.52), np.array([0.1, -0.2, 0.3])
AXIS_POINT, AXIS = np.array([0.2, 0.0, 0.25]), np.array([0.0, 1.0, 0.0])


def _e(v) -> str:
    return "".join(f"{x:13.5E}" for x in v)


def _record_18(label, kind, ref, name, o, x, xz) -> str:
    return f"{label:10d}{kind:10d}{ref:10d}{1:10d}{1:10d}\n{name}\n{_e([*o, *x])}\n{_e(xz)}\n"


def _dataset_18(records: str) -> str:
    return "    -1\n    18\n" + records + "    -1\n"


def _systems_18() -> str:
    # system 5 in global: origin, a point on +x, a point in the +xz plane
    s5 = _record_18(5, 0, 0, "ROTATED", O5, O5 + 0.9 * R5[:, 0], O5 + 0.4 * R5[:, 0] + 0.7 * R5[:, 2])
    # system 6 (cylindrical, z along the axle): x axis along global z, defined by points given in system 5
    o6 = AXIS_POINT
    x6 = o6 + np.array([0.0, 0.0, 1.0])
    xz6 = o6 + 0.5 * AXIS + 0.2 * np.array([0.0, 0.0, 1.0])
    to5 = lambda p: R5.T @ (p - O5)  # noqa: E731
    s6 = _record_18(6, 1, 5, "AXLE", to5(o6), to5(x6), to5(xz6))
    return _dataset_18(s5 + s6)


def _cylindrical_frame(p: np.ndarray) -> np.ndarray:
    """Columns: radial, tangential, axial unit vectors at global point ``p`` of system 6 (x axis = global z)."""
    ez = AXIS
    ex = np.array([0.0, 0.0, 1.0])
    d = p - AXIS_POINT
    r = d - (d @ ez) * ez
    er = r / np.linalg.norm(r) if np.linalg.norm(r) > 0 else ex
    return np.column_stack([er, np.cross(ez, er), ez])


def _local_file(path, systems: str, def_cs: dict, disp_cs: dict) -> None:
    """The small model with the nodes of ``def_cs`` / ``disp_cs`` (node -> label) in those systems."""
    ids, xyz, _, freqs, shapes = small_model()
    text = write_small_uff_2414(path).read_text()
    start = text.index("    -1\n  2411\n")
    end = text.index("    -1\n", text.index("\n", start + 7) + 1) + 7
    rows, local_shapes = [], shapes.copy()
    for i, n in enumerate(ids.tolist()):
        p = xyz[i]
        dc, uc = def_cs.get(n, 0), disp_cs.get(n, 0)
        if dc == 5:
            p = R5.T @ (p - O5)
        frame = {0: np.eye(3), 5: R5}[uc] if uc != 6 else _cylindrical_frame(xyz[i])
        for a in (0, 3):
            local_shapes[:, i, a:a + 3] = shapes[:, i, a:a + 3] @ frame  # components along the frame's columns
        rows.append(f"{n:10d}{dc:10d}{uc:10d}{1:10d}\n" + "".join(f"{v:25.16E}" for v in p) + "\n")
    nodes = "    -1\n  2411\n" + "".join(rows) + "    -1\n"
    head = text[:start] + nodes + text[end:text.index("    -1\n  2414")]
    modes = "".join(dataset_2414(k + 1, k + 1, f, ids, local_shapes[k]) for k, f in enumerate(freqs))
    path.write_text(systems + head + modes)


def test_nodes_and_shapes_in_dataset_18_systems_read_as_the_global_model(tmp_path):
    """Nodes 12-13 with coordinates and displacements in the rotated system 5, node 15 with cylindrical
    components (system 6, defined inside system 5): the model equals the global file's."""
    base = fem_import.read(write_small_uff_2414(tmp_path / "global.unv"))
    path = tmp_path / "local.unv"
    _local_file(path, _systems_18(), {12: 5, 13: 5}, {12: 5, 13: 5, 15: 6})
    got = fem_import.read(path)
    np.testing.assert_array_equal(got.node_ids, base.node_ids)
    scale = np.abs(base.xyz).max()
    np.testing.assert_allclose(got.xyz, base.xyz, rtol=0, atol=2e-5 * scale)
    np.testing.assert_allclose(got.shapes, base.shapes, rtol=0, atol=2e-5 * np.abs(base.shapes).max())
    assert any("converted from coordinate system 5" in h for h in got.history)
    assert any("turned from the nodes' displacement systems" in h for h in got.history)
    # without the systems applied the file would not read as the model: the test can fail
    assert np.abs(got.xyz[1] - R5.T @ (base.xyz[1] - O5)).max() > 0.05


def test_dataset_18_systems_the_reader_cannot_interpret_are_refused_by_name(tmp_path):
    """Coordinates in a cylindrical system (angle unit not stated), a spherical displacement system, a reference
    cycle and a label that dataset 2420 defines too are refused, naming the system, its line and the nodes."""
    path = tmp_path / "cyl_coords.unv"
    _local_file(path, _systems_18(), {14: 6}, {})
    with pytest.raises(FEReadError, match=r"1 node\(s\) \(14\) give their coordinates in coordinate system 6 "
                                          r"\(cylindrical, 'AXLE'; dataset 18 at line 1\).*unit"):
        fem_import.read(path)
    sph = _systems_18().replace(f"{6:10d}{1:10d}{5:10d}", f"{6:10d}{2:10d}{5:10d}")
    _local_file(path, sph, {}, {15: 6})
    with pytest.raises(FEReadError, match=r"displacements in coordinate system 6 \(spherical"):
        fem_import.read(path)
    cycle = _systems_18().replace(f"{5:10d}{0:10d}{0:10d}", f"{5:10d}{0:10d}{6:10d}")
    _local_file(path, cycle, {12: 5}, {})
    with pytest.raises(FEReadError, match=r"reference systems form a cycle"):
        fem_import.read(path)
    twice = ("    -1\n  2420\n         1\nPART\n" + f"{5:10d}{0:10d}{8:10d}\nLOCAL 5\n"
             + "".join("".join(f"{v:25.16E}" for v in r) + "\n" for r in [*np.eye(3), np.zeros(3)]) + "    -1\n")
    _local_file(path, twice + _systems_18(), {12: 5}, {})
    with pytest.raises(FEReadError, match=r"coordinate system\(s\) \[5\] are defined by both dataset 2420 and "
                                          r"dataset 18"):
        fem_import.read(path)
