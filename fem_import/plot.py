"""Pictures of imported FE modes: the mesh and a deformed mode shape (PyVista, off-screen).

Not imported by ``import fem_import``: PyVista is imported when a picture is
asked for, and renders off-screen (without an X display VTK's EGL/Mesa
window is selected before PyVista is imported).

Elements (UFF 2412 FE descriptors) become: shells and plane elements
(triangles 41, 81, 91, quadrilaterals 44, 84, 94 and their parabolic
variants, whose nodes go round the boundary) faces; rods, beams and pipes
(11, 21-24, 31, 32), springs (136, 137, 141) and rigid and constraint
elements (121, 122, 181: a Nastran RBE3; as a star from the first node)
lines; linear solids (111 tetra, 112 wedge, 115 brick) their boundary faces;
lumped masses (161) and one-node elements (grounded springs 138, 139)
vertices.  Display-only skins are ordinary quadrilaterals.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .errors import FEGeometryError, MissingCoordinatesError
from .modes import FEModes

__all__ = ["mesh_polydata", "render_mode"]

_FACES = {41, 42, 44, 45, 81, 82, 84, 85, 91, 92, 94, 95}
_LINES = {11, 21, 22, 23, 24, 31, 32, 136, 137, 141, 171, 172}
_STARS = {121, 122, 181}
_POINTS = {161}
# boundary faces of the linear solids, in local node numbers
_SOLIDS = {
    111: ((0, 1, 2), (0, 1, 3), (1, 2, 3), (0, 2, 3)),
    112: ((0, 1, 2), (3, 4, 5), (0, 1, 4, 3), (1, 2, 5, 4), (0, 2, 5, 3)),
    115: ((0, 1, 2, 3), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (0, 3, 7, 4)),
}


def _pyvista():
    if not os.environ.get("DISPLAY"):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista as pv

    pv.OFF_SCREEN = True
    return pv


def _check_mode(fe_modes: FEModes, mode_index) -> int:
    m = len(fe_modes)
    try:
        k = int(mode_index)
    except (TypeError, ValueError):
        raise ValueError(f"mode_index must be an integer in 0..{m - 1}, got {mode_index!r}") from None
    if k != mode_index or not 0 <= k < m:
        raise ValueError(f"mode_index must be an integer in 0..{m - 1} (0-based), got {mode_index!r}")
    return k


def mesh_polydata(fe_modes: FEModes, mode_index: int | None = None, scale: float = 0.0):
    """The FE mesh as a ``pyvista.PolyData``, optionally deformed by a mode.

    Parameters
    ----------
    fe_modes : FEModes
        Must have node coordinates.
    mode_index : int, optional
        0-based mode; None for the undeformed mesh.
    scale : float, optional
        Displacement scale: points move by ``scale * u`` [m per unit of the
        (mass-normalised) shape].

    Returns
    -------
    pyvista.PolyData
        One point per node (node order of ``fe_modes``), faces, lines and
        vertices from the elements; point data ``"displacement"`` (n, 3)
        and ``"magnitude"`` (n,) of the mode's translations (zeros without
        a mode) and ``"node_id"``.

    Raises
    ------
    MissingCoordinatesError
        If the nodes have no coordinates (punch file read without geometry).
    FEGeometryError
        If an element uses a node that is not in the model.
    ValueError
        If ``mode_index`` is out of range or ``scale`` not finite.
    """
    pv = _pyvista()
    if not fe_modes.has_coordinates:
        raise MissingCoordinatesError(f"{fe_modes.source or 'FE modes'}: nodes have no coordinates; read the "
                                      f"modes with geometry= to draw them")
    if not np.isfinite(scale):
        raise ValueError(f"scale must be finite, got {scale!r}")
    n = fe_modes.node_ids.size
    disp = np.zeros((n, 3))
    if mode_index is not None:
        disp = fe_modes.shapes[_check_mode(fe_modes, mode_index), :, :3]
    row = {nid: k for k, nid in enumerate(fe_modes.node_ids.tolist())}
    faces: list[int] = []
    lines: list[int] = []
    verts: list[int] = []
    for el in fe_modes.elements:
        try:
            idx = [row[nd] for nd in el.nodes]
        except KeyError as exc:
            raise FEGeometryError(f"element {el.element_id} uses node {exc.args[0]}, which is not in the model "
                                  f"({fe_modes.source or 'in memory'})") from None
        desc = el.fe_descriptor
        if desc in _FACES and len(idx) >= 3:
            faces += [len(idx), *idx]
        elif desc in _SOLIDS and len(idx) == max(max(f) for f in _SOLIDS[desc]) + 1:
            for f in _SOLIDS[desc]:
                faces += [len(f), *(idx[j] for j in f)]
        elif desc in _STARS and len(idx) >= 2:
            for j in idx[1:]:
                lines += [2, idx[0], j]
        elif desc in _POINTS or len(idx) == 1:
            verts += [1, *idx[:1]]
        elif len(idx) >= 2:  # lines and anything unknown: a polyline through its nodes
            lines += [len(idx), *idx]
    mesh = pv.PolyData(fe_modes.xyz + scale * disp,
                       faces=np.asarray(faces, np.int64) if faces else None,
                       lines=np.asarray(lines, np.int64) if lines else None,
                       verts=np.asarray(verts, np.int64) if verts else None)
    mesh.point_data["displacement"] = disp
    mesh.point_data["magnitude"] = np.linalg.norm(disp, axis=1)
    mesh.point_data["node_id"] = fe_modes.node_ids
    return mesh


def render_mode(fe_modes: FEModes, mode_index: int, path, *, amplitude: float | None = None,
                title: str | None = None, window_size: tuple[int, int] = (1200, 800),
                show_undeformed: bool = True, cmap: str = "viridis", camera_position=None) -> Path:
    """Render one mode shape on the mesh to a PNG file, off-screen.

    Parameters
    ----------
    fe_modes : FEModes
        With node coordinates and elements.
    mode_index : int
        0-based mode.
    path : str or os.PathLike
        Output PNG (parent folders are created).
    amplitude : float, optional
        Largest displayed translation [m]; default 8 % of the mesh's
        bounding-box diagonal.
    title : str, optional
        Default ``"mode <k+1>: <f> Hz"``.
    window_size : (int, int), optional
    show_undeformed : bool, optional
        Draw the undeformed mesh as a faint wireframe.
    cmap : str, optional
        Colour map of the translation magnitude.
    camera_position : optional
        PyVista camera position; default an isometric view from
        ``(+x, -y, +z)``.

    Returns
    -------
    pathlib.Path
        The written file.
    """
    pv = _pyvista()
    k = _check_mode(fe_modes, mode_index)
    base = mesh_polydata(fe_modes)
    diag = float(np.linalg.norm(np.ptp(fe_modes.xyz, axis=0))) or 1.0
    amp = 0.08 * diag if amplitude is None else float(amplitude)
    if not np.isfinite(amp) or amp < 0:
        raise ValueError(f"amplitude must be a non-negative length [m], got {amplitude!r}")
    peak = float(np.max(np.linalg.norm(fe_modes.shapes[k, :, :3], axis=1)))
    scale = amp / peak if peak > 0 else 0.0
    mesh = mesh_polydata(fe_modes, k, scale)
    plotter = pv.Plotter(off_screen=True, window_size=list(window_size))
    try:
        plotter.set_background("white")
        if show_undeformed:
            plotter.add_mesh(base, style="wireframe", color="lightgray", opacity=0.35, line_width=1)
        plotter.add_mesh(mesh, scalars="magnitude", cmap=cmap, show_edges=True, edge_color="dimgray",
                         line_width=2, point_size=6, show_scalar_bar=False)
        text = title if title is not None else f"mode {k + 1}: {fe_modes.freqs_hz[k]:.2f} Hz"
        if text:
            plotter.add_text(text, font_size=12, color="black")
        if camera_position is not None:
            plotter.camera_position = camera_position
        else:
            plotter.view_vector((1.0, -0.8, 0.5), viewup=(0.0, 0.0, 1.0))
            plotter.reset_camera()
            plotter.camera.zoom(1.3)
        out = Path(os.fspath(path))
        out.parent.mkdir(parents=True, exist_ok=True)
        plotter.screenshot(str(out))
    finally:
        plotter.close()
    return out
