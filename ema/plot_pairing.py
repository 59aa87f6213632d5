"""Pictures of a test/FE pairing: the MAC matrix (matplotlib) and side-by-side mode renders (PyVista).

Computing lives in :mod:`ema.pairing`; these functions only draw. Nothing
graphical is imported at module import.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fem_import.modes import FEModes

from .modeset import ModeSet
from .pairing import Pairing

__all__ = ["plot_mac", "render_pair"]


def plot_mac(pairing: Pairing, test: ModeSet, fe: FEModes, ax=None):
    """MAC matrix (test modes × FE modes in the pairing band) with the chosen pairs outlined.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    fe_cols = sorted({j for c in pairing.clusters for j in c})
    if ax is None:
        fig, ax = plt.subplots(figsize=(1.0 + 0.35 * max(len(fe_cols), 4), 1.0 + 0.35 * max(len(test), 4)))
    else:
        fig = ax.figure
    mac = pairing.mac[:, fe_cols] if fe_cols else np.zeros((len(test), 0))
    im = ax.imshow(mac, vmin=0, vmax=1, cmap="Greys", aspect="auto")
    col_of = {j: k for k, j in enumerate(fe_cols)}
    for p in pairing.pairs:
        for j in p.fe_indices:
            ax.add_patch(plt.Rectangle((col_of[j] - 0.5, p.test_index - 0.5), 1, 1, fill=False, ec="tab:red", lw=1.5))
    ax.set_xticks(range(len(fe_cols)))
    ax.set_xticklabels([f"{j + 1}\n{fe.freqs_hz[j]:.0f}" for j in fe_cols], fontsize=7)
    ax.set_yticks(range(len(test)))
    ax.set_yticklabels([f"{i + 1}: {f:.1f} Hz" for i, f in enumerate(test.freqs_hz)], fontsize=7)
    ax.set_xlabel("FE mode (number / Hz)")
    ax.set_ylabel("test mode")
    ax.set_title("MAC (red: pairs; degenerate FE pairs share a test mode by subspace MAC)", fontsize=8)
    fig.colorbar(im, ax=ax, fraction=0.04)
    fig.tight_layout()
    return fig


def _shape_mesh(fe: FEModes, shape: np.ndarray, amplitude: float):
    """The FE mesh deformed by an arbitrary shape (e.g. a combination of a degenerate pair)."""
    from fem_import.plot import mesh_polydata

    one = FEModes(fe.node_ids, fe.xyz, fe.elements, np.array([1.0]), np.asarray(shape)[None], np.ones(1),
                  source=fe.source)
    peak = np.max(np.linalg.norm(np.asarray(shape)[:, :3], axis=1))
    return mesh_polydata(one, 0, amplitude / peak if peak > 0 else 0.0)


def _sensor_lines(ch, points: np.ndarray, ok: np.ndarray) -> list[list[int]]:
    """Polylines through the sensors of each body (channel-name prefix), as in a test-geometry wireframe.

    Sensors spread along the axle are joined in y order; sensors around a
    wheel or disc are joined around the circumference (closed).
    """
    import re

    groups: dict[str, list[int]] = {}
    for k, name in enumerate(ch["name"].astype(str)):
        if ok[k]:
            groups.setdefault(re.sub(r"[_\d]+$", "", name), []).append(k)
    lines = []
    for idx in groups.values():
        if len(idx) < 3:
            continue
        idx = np.array(idx)
        p = points[idx]
        radius = np.hypot(p[:, 0], p[:, 2])
        if np.ptp(p[:, 1]) > np.ptp(radius) + 1e-9:
            order = idx[np.argsort(p[:, 1])]
            lines.append(list(order))
        else:
            order = idx[np.argsort(np.arctan2(p[:, 2], p[:, 0]))]
            lines.append(list(order) + [order[0]])
    return lines


def render_pair(test: ModeSet, test_index: int, fe: FEModes, fe_shape: np.ndarray, path, *, title: str = "",
                amplitude: float = 0.08, window_size=(1600, 700)) -> Path:
    """Test shape on the sensor geometry (left) beside the FE shape on the mesh (right), as a PNG.

    The test shape is drawn as the sensor points displaced along their
    measuring directions by the real part of the (phase-aligned) shape; the
    undeformed FE mesh is shown faintly behind it for orientation.

    Parameters
    ----------
    test : ModeSet
    test_index : int
    fe : FEModes
    fe_shape : ndarray (n_nodes, n_dof)
        The FE shape to show (e.g. :attr:`Pair.fe_shape`, the best combination of a degenerate pair).
    path : str or Path
    """
    from fem_import.plot import _pyvista, mesh_polydata

    pv = _pyvista()
    phi = test.shapes[:, test_index]
    ok = np.isfinite(phi)
    phi = np.where(ok, phi, 0)
    phi = phi * np.exp(-1j * np.angle(phi[np.argmax(np.abs(phi))]))
    re = phi.real
    ch = test.channels
    pos = ch[["x", "y", "z"]].to_numpy(float)
    d = ch[["dx", "dy", "dz"]].to_numpy(float)
    scale = amplitude / np.max(np.abs(re)) if np.max(np.abs(re)) > 0 else 0.0
    moved = pos + scale * re[:, None] * d

    plotter = pv.Plotter(shape=(1, 2), off_screen=True, window_size=list(window_size))
    plotter.set_background("white")
    ghost = mesh_polydata(fe)
    plotter.subplot(0, 0)
    plotter.add_mesh(ghost, color="lightgray", opacity=0.15)
    cloud = pv.PolyData(moved[ok])
    cloud.point_data["amplitude"] = np.abs(re[ok])
    plotter.add_mesh(cloud, scalars="amplitude", cmap="viridis", point_size=14, render_points_as_spheres=True,
                     show_scalar_bar=False)
    for line in _sensor_lines(ch, pos, ok):  # ordered on the undeformed geometry
        plotter.add_mesh(pv.lines_from_points(moved[line]), color="black", line_width=2)
    arrows = pv.PolyData(pos[ok])
    arrows["vectors"] = scale * re[ok, None] * d[ok]
    plotter.add_mesh(arrows.glyph(orient="vectors", scale=False, factor=0.06), color="tab:red")
    plotter.add_text(f"test {test_index + 1}: {test.freqs_hz[test_index]:.2f} Hz, "
                     f"zeta {100 * test.zeta[test_index]:.3f} %", font_size=10, color="black")
    plotter.camera_position = [(3.2, -2.4, 1.6), (0.0, 0.0, 0.0), (0.0, 0.0, 1.0)]
    plotter.subplot(0, 1)
    mesh = _shape_mesh(fe, fe_shape, amplitude)
    plotter.add_mesh(mesh, scalars="magnitude", cmap="viridis", show_edges=True, edge_color="dimgray",
                     show_scalar_bar=False)
    plotter.add_text(title or "FE", font_size=10, color="black")
    plotter.camera_position = [(3.2, -2.4, 1.6), (0.0, 0.0, 0.0), (0.0, 0.0, 1.0)]
    plotter.link_views()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    plotter.screenshot(str(path))
    plotter.close()
    return path
