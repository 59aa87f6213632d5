"""Pictures of the virtual lab's wheelset: the FE mesh and its mode shapes (PyVista, off-screen).

Nothing graphical is imported at package import; PyVista is imported when a
picture is asked for, and renders off-screen (VTK's EGL/Mesa works headless).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .fe_model import Beam, FEModel, Shell

__all__ = ["wheelset_polydata", "render_wheelset"]


def _pyvista():
    # without an X display VTK would first try (and loudly fail) an X window;
    # EGL renders headless directly
    if not os.environ.get("DISPLAY"):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista as pv

    pv.OFF_SCREEN = True
    return pv


def wheelset_polydata(model: FEModel, shape: np.ndarray | None = None, scale: float = 0.0):
    """The wheelset as a ``pyvista.PolyData``: shells and skins as faces, beams as lines.

    Parameters
    ----------
    model : FEModel
    shape : ndarray (n_nodes, 6), optional
        A mode shape; its translations displace the points by ``scale``.
    scale : float
        Displacement scale [m per unit of shape].

    Returns
    -------
    pyvista.PolyData
        With point data ``"displacement"`` (magnitude of the shape's
        translation, 0 without a shape).
    """
    pv = _pyvista()
    points = model.xyz.copy()
    disp = np.zeros(model.n_nodes)
    if shape is not None:
        shape = np.asarray(shape, float)
        if shape.shape != (model.n_nodes, 6):
            raise ValueError(f"shape must have shape ({model.n_nodes}, 6), got {shape.shape}")
        points = points + scale * shape[:, :3]
        disp = np.linalg.norm(shape[:, :3], axis=1)
    faces = []
    lines = []
    for e in model.elements:
        if isinstance(e, Shell):
            faces.append([4, *(model.index(n) for n in e.nodes)])
        elif isinstance(e, Beam):
            lines.append([2, *(model.index(n) for n in e.nodes)])
    for s in model.skins:
        faces.append([4, *(model.index(n) for n in s.nodes)])
    mesh = pv.PolyData(points, faces=np.concatenate(faces) if faces else None,
                       lines=np.concatenate(lines) if lines else None)
    mesh.point_data["displacement"] = disp
    return mesh


def render_wheelset(
    model: FEModel,
    path: str | Path,
    *,
    shape: np.ndarray | None = None,
    title: str = "",
    amplitude: float = 0.08,
    window_size: tuple[int, int] = (1200, 800),
) -> Path:
    """Render the wheelset (optionally deformed by a mode shape) to a PNG file.

    Parameters
    ----------
    model : FEModel
    path : str or Path
        Output PNG.
    shape : ndarray (n_nodes, 6), optional
        Mode shape; scaled so the largest translation is ``amplitude`` m.
    title : str
    amplitude : float
        Largest displayed displacement [m].
    window_size : (int, int)

    Returns
    -------
    Path
    """
    pv = _pyvista()
    scale = 0.0
    if shape is not None:
        peak = np.max(np.linalg.norm(np.asarray(shape)[:, :3], axis=1))
        scale = amplitude / peak if peak > 0 else 0.0
    mesh = wheelset_polydata(model, shape, scale)
    plotter = pv.Plotter(off_screen=True, window_size=list(window_size))
    plotter.set_background("white")
    if shape is None:
        plotter.add_mesh(mesh, color="lightsteelblue", show_edges=True, edge_color="dimgray", line_width=2)
    else:
        plotter.add_mesh(pv.PolyData(model.xyz), color="lightgray", point_size=1, render_points_as_spheres=False,
                         opacity=0.2)
        plotter.add_mesh(mesh, scalars="displacement", cmap="viridis", show_edges=True, edge_color="dimgray",
                         line_width=2, show_scalar_bar=False)
    if title:
        plotter.add_text(title, font_size=12, color="black")
    plotter.camera_position = [(3.2, -2.4, 1.6), (0.0, 0.0, 0.0), (0.0, 0.0, 1.0)]
    plotter.camera.zoom(1.5)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    plotter.screenshot(str(path))
    plotter.close()
    return path
