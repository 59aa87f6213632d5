"""fem_import.plot: mesh polydata from the imported elements and an off-screen mode picture."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

import fem_import
from fem_import import MissingCoordinatesError


@pytest.fixture(scope="module")
def uff_modes(control_dir):
    return fem_import.read(control_dir / "fe_design.uff")


def test_package_import_pulls_nothing_graphical():
    code = ("import sys, fem_import; bad = [m for m in ('pyvista', 'vtk', 'matplotlib') if m in sys.modules]; "
            "print(bad); sys.exit(1 if bad else 0)")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_mesh_polydata_cells_and_deformation(uff_modes):
    from fem_import.plot import mesh_polydata

    mesh = mesh_polydata(uff_modes)
    assert mesh.n_points == 1129
    assert mesh.n_lines == 122            # beams (21)
    assert mesh.n_verts == 6              # lumped masses (161)
    assert mesh.n_cells == 122 + 940 + 6  # + quads (94), skins included
    np.testing.assert_array_equal(mesh.points, uff_modes.xyz)
    k, scale = 13, 0.02
    moved = mesh_polydata(uff_modes, k, scale)
    np.testing.assert_allclose(moved.points, uff_modes.xyz + scale * uff_modes.shapes[k, :, :3], atol=1e-12)
    np.testing.assert_allclose(moved["magnitude"], np.linalg.norm(uff_modes.shapes[k, :, :3], axis=1))
    # the skin quads (property 99) are drawn: every node of a skin is a point of a face
    skin_nodes = {n for e in uff_modes.elements if e.physical_property == 99 for n in e.nodes}
    face_points = set(np.unique(mesh.faces.reshape(-1, 5)[:, 1:]).tolist())
    assert {uff_modes.index(n) for n in skin_nodes} <= face_points


def test_render_mode_writes_a_picture_with_content(tmp_path, uff_modes):
    from PIL import Image

    from fem_import.plot import render_mode

    path = render_mode(uff_modes, 6, tmp_path / "pics" / "torsion.png", window_size=(600, 400))
    img = np.asarray(Image.open(path).convert("RGB"), float)
    assert img.shape == (400, 600, 3)
    non_white = np.any(img < 245, axis=2)
    assert 0.03 < non_white.mean() < 0.8
    # coloured by displacement magnitude: more than a grey level in the picture
    colour = np.ptp(img, axis=2) > 30
    assert colour.mean() > 0.01


def test_render_needs_coordinates_and_a_valid_mode(control_dir, uff_modes, tmp_path):
    from fem_import.plot import mesh_polydata, render_mode

    pch = fem_import.read(control_dir / "fe_design.pch")
    with pytest.raises(MissingCoordinatesError, match="geometry="):
        mesh_polydata(pch)
    with pytest.raises(ValueError, match=r"mode_index must be an integer in 0\.\.24"):
        render_mode(uff_modes, 25, tmp_path / "x.png")
