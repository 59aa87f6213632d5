"""FE normal modes as imported from a file: the :class:`FEModes` type."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["FEModes", "Element", "DOF_NAMES"]

DOF_NAMES = ("ux", "uy", "uz", "rx", "ry", "rz")


@dataclass(frozen=True)
class Element:
    """One element of the FE mesh: UFF 2412 FE descriptor id (21 beam, 94 quad, 91 triangle, 161 mass, ...)."""

    element_id: int
    fe_descriptor: int
    nodes: tuple[int, ...]
    physical_property: int = 0


@dataclass(frozen=True, eq=False)
class FEModes:
    """Normal modes of an FE model, mass-normalised.

    Parameters
    ----------
    node_ids : ndarray of int (n,)
    xyz : ndarray (n, 3)
        Node coordinates [m].
    elements : tuple of Element
    freqs_hz : ndarray (m,)
    shapes : ndarray (m, n, n_dof)
        Modal displacements per node; ``n_dof`` is 3 (translations) or 6
        (translations and rotations, in :data:`DOF_NAMES` order).
    modal_mass : ndarray (m,)
        Modal masses after import: 1 when the shapes are mass-normalised
        (readers normalise when the file states another modal mass).
    source : str
        File the modes were read from.
    format : str
        Reader that read them (``"uff"``, ``"nastran-punch"``).
    units : str
        Unit system of the file as understood by the reader.
    """

    node_ids: np.ndarray
    xyz: np.ndarray
    elements: tuple[Element, ...]
    freqs_hz: np.ndarray
    shapes: np.ndarray
    modal_mass: np.ndarray
    source: str = ""
    format: str = ""
    units: str = "SI (m, kg, s)"
    history: tuple[str, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        ids = np.asarray(self.node_ids, dtype=np.int64)
        n = ids.size
        if np.unique(ids).size != n:
            raise ValueError("FEModes.node_ids must be unique")
        xyz = np.asarray(self.xyz, float)
        if xyz.shape != (n, 3):
            raise ValueError(f"FEModes.xyz must have shape ({n}, 3), got {xyz.shape}")
        f = np.asarray(self.freqs_hz, float)
        shapes = np.asarray(self.shapes, float)
        if shapes.ndim != 3 or shapes.shape[:2] != (f.size, n) or shapes.shape[2] not in (3, 6):
            raise ValueError(f"FEModes.shapes must be ({f.size}, {n}, 3 or 6), got {shapes.shape}")
        mm = np.asarray(self.modal_mass, float)
        if mm.shape != f.shape:
            raise ValueError(f"FEModes.modal_mass must have shape {f.shape}, got {mm.shape}")
        object.__setattr__(self, "node_ids", ids)
        object.__setattr__(self, "xyz", xyz)
        object.__setattr__(self, "freqs_hz", f)
        object.__setattr__(self, "shapes", shapes)
        object.__setattr__(self, "modal_mass", mm)
        object.__setattr__(self, "elements", tuple(self.elements))

    def __len__(self) -> int:
        return self.freqs_hz.size

    @property
    def has_rotations(self) -> bool:
        return self.shapes.shape[2] == 6

    def index(self, node: int) -> int:
        """Row of ``node`` in ``node_ids``; ``KeyError`` naming the node otherwise."""
        hit = np.flatnonzero(self.node_ids == int(node))
        if hit.size == 0:
            raise KeyError(f"node {node} is not in the FE model ({self.source or 'in memory'})")
        return int(hit[0])
