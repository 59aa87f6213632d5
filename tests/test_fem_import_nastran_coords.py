"""Nastran coordinate systems (CORD2R/C/S, CORD1R/C/S; GRID CP and CD) read into basic positions and shapes.

Oracles: the closed-form position and unit vectors of cylindrical and spherical systems; and the virtual lab's own
export written twice as a punch and a bulk deck, once in the basic system and once with the left wheel meshed in a
cylindrical system about the axle (defined in a rotated, shifted rectangular system: nested RID), its eigenvector
components radial, tangential and axial there, and the right disc's in a CORD1R system on three grids. Both read to
the same positions and mode shapes (to the punch's 7 significant digits).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import fem_import
from fe_exports_support import deck, element_cards, large, punch
from fem_import.nastran_coords import CoordSystem, resolve
from lab_data.cache import campaign_dir


def test_cylindrical_and_spherical_systems_in_closed_form():
    # a cylindrical system whose z axis is the basic y axis through (1, 2, 3), its x axis along basic z
    a, b, c = np.array([1.0, 2.0, 3.0]), np.array([1.0, 3.0, 3.0]), np.array([1.0, 2.0, 4.0])
    systems, pos = resolve("t.bdf", {5: ("C", 0, a, b, c, 1), 6: ("S", 0, a, b, c, 2)}, {},
                           {1: (5, (0.5, 30.0, 0.2), 3), 2: (6, (0.5, 60.0, 30.0), 4)})
    cyl, sph = systems[5], systems[6]
    np.testing.assert_allclose(cyl.axes, np.column_stack([[0, 0, 1], [1, 0, 0], [0, 1, 0]]), atol=1e-15)
    r, t = 0.5, math.radians(30.0)
    np.testing.assert_allclose(pos[1], a + r * math.cos(t) * np.array([0, 0, 1]) + r * math.sin(t) * np.array([1, 0, 0])
                               + 0.2 * np.array([0, 1, 0]), atol=1e-15)
    F = cyl.frame_at(pos[1])
    np.testing.assert_allclose(F.T @ F, np.eye(3), atol=1e-15)
    radial = pos[1] - a - np.dot(pos[1] - a, [0, 1, 0]) * np.array([0, 1, 0])
    np.testing.assert_allclose(F[:, 0], radial / np.linalg.norm(radial), atol=1e-15)  # e_r away from the axis
    np.testing.assert_allclose(F[:, 2], [0, 1, 0], atol=1e-15)  # e_z along the axis
    # spherical: (R, θ, φ) -> R (sinθ cosφ, sinθ sinφ, cosθ) in the local axes; e_R points at the grid
    th, ph = math.radians(60.0), math.radians(30.0)
    local = 0.5 * np.array([math.sin(th) * math.cos(ph), math.sin(th) * math.sin(ph), math.cos(th)])
    np.testing.assert_allclose(pos[2], a + sph.axes @ local, atol=1e-15)
    G = sph.frame_at(pos[2])
    np.testing.assert_allclose(G.T @ G, np.eye(3), atol=1e-15)
    np.testing.assert_allclose(G[:, 0], (pos[2] - a) / 0.5, atol=1e-15)
    assert np.linalg.det(G) == pytest.approx(1.0)
    # on a cylindrical system's axis the radial direction is the system's x axis
    np.testing.assert_allclose(cyl.frame_at(a + 0.3 * np.array([0, 1, 0])), cyl.axes, atol=1e-15)


def test_unresolvable_systems_are_named():
    from fem_import.errors import FEReadError

    a, b, c = np.zeros(3), np.array([0, 0, 1.0]), np.array([1.0, 0, 0])
    with pytest.raises(FEReadError, match=r"line 7: CORD2R 3 is given in system 4, which is not defined"):
        resolve("t.bdf", {3: ("R", 4, a, b, c, 7)}, {}, {})
    with pytest.raises(FEReadError, match=r"CORD2R 3 is given in system 4, which is not resolved \(a cycle\?\)"):
        resolve("t.bdf", {3: ("R", 4, a, b, c, 7), 4: ("R", 3, a, b, c, 8)}, {}, {})
    with pytest.raises(FEReadError, match=r"CORD1C 9 is defined by grid\(s\) \[12\] that no GRID entry places"):
        resolve("t.bdf", {}, {9: ("C", (10, 11, 12), 5)}, {10: (0, (0, 0, 0), 1), 11: (0, (0, 0, 1), 2)})
    with pytest.raises(FEReadError, match=r"CORD2R 3: its x-z plane point C lies on its z axis"):
        resolve("t.bdf", {3: ("R", 0, a, b, 2 * b, 7)}, {}, {})


def _local_coordinates(system: CoordSystem, p: np.ndarray) -> tuple[float, float, float]:
    x, y, z = system.axes.T @ (p - system.origin)
    if system.kind == "R":
        return x, y, z
    return math.hypot(x, y), math.degrees(math.atan2(y, x)), z


def test_a_wheel_meshed_in_a_cylindrical_system_reads_as_the_basic_one(tmp_path):
    fe = fem_import.read(campaign_dir("control", fe_export_hz=2000.0) / "fe_design.uff")
    ids, xyz = fe.node_ids, fe.xyz
    shapes = fe.shapes[:12]
    lam = (2 * np.pi * fe.freqs_hz[:12]) ** 2
    elements = [(e.element_id, e.fe_descriptor, e.nodes, e.physical_property) for e in fe.elements]
    # system 10: rectangular, rotated 90 deg about basic x and shifted; system 20: cylindrical about the axle
    # (basic y through the origin), defined in system 10's coordinates; system 30: CORD1R on three basic grids
    a10, b10, c10 = np.array([0.3, -0.2, 0.1]), np.array([0.3, -1.2, 0.1]), np.array([1.3, -0.2, 0.1])
    sys10 = resolve("", {10: ("R", 0, a10, b10, c10, 1)}, {}, {})[0][10]

    def in10(p):
        return sys10.axes.T @ (np.asarray(p, float) - sys10.origin)

    a20, b20, c20 = np.array([0.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0])
    systems = resolve("", {10: ("R", 0, a10, b10, c10, 1), 20: ("C", 10, in10(a20), in10(b20), in10(c20), 2)},
                      {}, {})[0]
    cyl = systems[20]
    wheel = [k for k in range(ids.size) if xyz[k, 1] < -0.6 and math.hypot(xyz[k, 0], xyz[k, 2]) > 0.2]
    disc = [k for k in range(ids.size) if xyz[k, 1] > 0.2 and math.hypot(xyz[k, 0], xyz[k, 2]) > 0.15
            and xyz[k, 1] < 0.6][:20]
    assert len(wheel) > 50 and len(disc) >= 10
    on_axis = np.flatnonzero(np.hypot(xyz[:, 0], xyz[:, 2]) < 1e-9)
    g1, g2 = int(ids[on_axis[np.argmin(xyz[on_axis, 1])]]), int(ids[on_axis[np.argmax(xyz[on_axis, 1])]])
    g3 = int(ids[disc[0]])  # off the axis: the x-z plane
    cord1 = resolve("", {}, {30: ("R", (g1, g2, g3), 3)}, {g: (0, tuple(xyz[fe.index(g)]), 0) for g in (g1, g2, g3)})
    rect = cord1[0][30]
    local_shapes = shapes.copy()
    cards_basic, cards_local = [], []
    for k, n in enumerate(ids.tolist()):
        cards_basic += large("GRID", n, None, *map(float, xyz[k]))
        if k in wheel:
            F = cyl.frame_at(xyz[k])
            cards_local += large("GRID", n, 20, *map(float, _local_coordinates(cyl, xyz[k])), 20)
        elif k in disc:
            F = rect.frame_at(xyz[k])
            cards_local += large("GRID", n, None, *map(float, xyz[k]), 30)
        else:
            cards_local += large("GRID", n, None, *map(float, xyz[k]))
            continue
        for j in (0, 3):
            local_shapes[:, k, j:j + 3] = shapes[:, k, j:j + 3] @ F  # components along F's columns
    coords = (large("CORD2R", 10, None, *a10, *b10, *c10) + large("CORD2C", 20, 10, *in10(a20), *in10(b20), *in10(c20))
              + large("CORD1R", 30, g1, g2, g3))
    elem = element_cards(elements)
    for name, grid_cards, sh, extra in (("basic", cards_basic, shapes, []), ("local", cards_local, local_shapes, coords)):
        (tmp_path / f"{name}.bdf").write_text(deck(extra + grid_cards + elem))
        (tmp_path / f"{name}.pch").write_text(punch([(m + 1, lam[m], ids, sh[m]) for m in range(sh.shape[0])]))
    basic = fem_import.read(tmp_path / "basic.pch", geometry=tmp_path / "basic.bdf")
    local = fem_import.read(tmp_path / "local.pch", geometry=tmp_path / "local.bdf")
    np.testing.assert_allclose(local.xyz, basic.xyz, rtol=0, atol=1e-9)
    scale = np.abs(basic.shapes).max()
    np.testing.assert_allclose(local.shapes, basic.shapes, rtol=0, atol=2e-6 * scale)
    # and the local components really differ from the basic ones (the test would catch a reader that ignores CD)
    assert np.abs(local_shapes[:, wheel] - shapes[:, wheel]).max() > 0.1 * scale
    assert any("rotated from their displacement coordinate systems" in h for h in local.history)
