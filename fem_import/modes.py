"""FE normal modes as imported from a file: the :class:`FEModes` type.

Besides holding the modes, :class:`FEModes` evaluates them where a sensor or
the hammer sits: :meth:`FEModes.at_points` gives the modal displacement of a
point rigidly attached to an FE node along a measuring direction,
``d . (u + theta x (p - x_node))``; :func:`shapes_at_channels` does the same
for the rows of a channel table.  These are the mode-shape coefficients
``c_jr`` (sensor j) and ``b_r`` (force point) of the modal accelerance
``H_j = sum_r c_jr b_r s^2 / (s^2 + 2 zeta_r omega_r s + omega_r^2)`` that
the hybrid model of :mod:`receptance` sums: the modal superposition
``x = [Phi] q`` of thesis eq. 2.24 with mass-normalised shapes,
``[Phi]^T [M] [Phi] = I`` (eq. 2.29), solved per frequency as in eq. 2.28.
"""

from __future__ import annotations

import functools
import warnings
from dataclasses import dataclass, field

import numpy as np

from .errors import FEGeometryError, MissingCoordinatesError, PointToleranceError

__all__ = ["FEModes", "Element", "DOF_NAMES", "UNIT_SYSTEMS", "shapes_at_channels", "number_ranges"]

DOF_NAMES = ("ux", "uy", "uz", "rx", "ry", "rz")

#: Consistent unit systems of FE solvers -> (file length units per metre, kg per file mass unit); the mass unit is
#: force x s² / length: mm-t-s (N, the usual Nastran/Abaqus set for steel structures), mm-kg-s (mN), in-lbf-s
#: (lbf s²/in = 175.1268 kg), and ANSYS's other /UNITS: cm-g-s (CGS, dyne), ft-slug-s (BFT, lbf), um-kg-s (uMKS, µN)
UNIT_SYSTEMS: dict[str, tuple[float, float]] = {
    "m-kg-s": (1.0, 1.0),
    "mm-t-s": (1000.0, 1000.0),
    "mm-kg-s": (1000.0, 1.0),
    "in-lbf-s": (1.0 / 0.0254, 0.45359237 * 9.80665 / 0.0254),
    "cm-g-s": (100.0, 1e-3),
    "ft-slug-s": (1.0 / 0.3048, 0.45359237 * 9.80665 / 0.3048),
    "um-kg-s": (1e6, 1.0),
}


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
    history : tuple of str
        Processing steps applied on import (normalisation, unit conversion,
        merged geometry...).
    mode_numbers : ndarray of int (m,), optional
        The number the file gives each mode (UFF 55 record 7 / 2414 record
        10 mode number, Nastran punch ``MODE =``), in the order of the modes;
        default (None) ``1 .. m``, their positions. They label the modes for
        the user (a file's "mode 108" is not the 108th mode when the export
        starts at 101 or leaves the rigid-body modes out); code indexes the
        modes by position (0-based), :meth:`mode_index` maps one to the other.

    Notes
    -----
    Node coordinates are NaN when the file carries none (a Nastran punch
    file read without ``geometry=``); :attr:`has_coordinates` tells.
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
    mode_numbers: np.ndarray | None = None

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
        if self.mode_numbers is None:
            numbers = np.arange(1, f.size + 1, dtype=np.int64)
        else:
            raw = np.asarray(self.mode_numbers)
            try:
                numbers = raw.astype(float)
            except (TypeError, ValueError):
                raise ValueError(f"FEModes.mode_numbers must be integers, got {self.mode_numbers!r}") from None
            if numbers.shape != f.shape or not np.all(np.isfinite(numbers)) or np.any(numbers != np.round(numbers)):
                raise ValueError(f"FEModes.mode_numbers must be {f.size} integers (one per mode), got "
                                 f"{raw.tolist()!r}")
            numbers = numbers.astype(np.int64)
            uniq, counts = np.unique(numbers, return_counts=True)
            if np.any(counts > 1):
                raise ValueError(f"FEModes.mode_numbers must be unique; {uniq[counts > 1].tolist()} repeat")
        object.__setattr__(self, "mode_numbers", numbers)

    def __len__(self) -> int:
        return self.freqs_hz.size

    def mode_index(self, number: int) -> int:
        """Position (0-based) of the mode the file numbers ``number``.

        Raises
        ------
        KeyError
            No mode has that number (the message lists the numbers).
        """
        hit = np.flatnonzero(self.mode_numbers == int(number))
        if hit.size == 0:
            raise KeyError(f"no mode numbered {number} in {self.source or 'the FE modes'} (mode numbers "
                           f"{number_ranges(self.mode_numbers.tolist())})")
        return int(hit[0])

    @property
    def has_rotations(self) -> bool:
        return self.shapes.shape[2] == 6

    @functools.cached_property
    def rotation_free(self) -> np.ndarray:
        """Nodes without rotations (bool per node): every node of a 3-DOF export, and in a 6-DOF export the nodes
        whose rotations are zero in every mode — a solid element's node, which carries translations only and
        which Nastran and most UFF writers still export with R1–R3 = 0. A rigid link from such a node would
        silently drop the rotation's share of a point's motion.

        Zero is judged against the export's largest translation over the model's size (``1e-12`` of it): a
        rotation that small moves no point of the model by a measurable amount.
        """
        n = self.shapes.shape[1]
        if not self.has_rotations:
            return np.ones(n, bool)
        rot = np.abs(self.shapes[:, :, 3:]).max(axis=(0, 2)) if self.shapes.shape[0] else np.zeros(n)
        trans = float(np.abs(self.shapes[:, :, :3]).max()) if self.shapes.size else 0.0
        xyz = self.xyz[np.all(np.isfinite(self.xyz), axis=1)]
        size = float(np.ptp(xyz, axis=0).max()) if xyz.shape[0] > 1 else 0.0
        return rot <= 1e-12 * trans / (size if size > 0 else 1.0)

    def in_si_units(self, system: str) -> "FEModes":
        """The modes of a file written in the unit ``system`` (a key of :data:`UNIT_SYSTEMS`), in SI.

        For a file that does not state its units (a Nastran punch and bulk deck, a UFF without dataset 164)
        and was read as SI: coordinates are divided by the file's length factor ``L`` (file length units per
        metre); mass-normalised shapes (``x = Φ q`` with kinetic energy ``q'²/2``, thesis eqs. 2.24, 2.29) have
        translations in ``1/sqrt(mass)``, divided by ``sqrt(Mk)`` (``Mk`` kg per file mass unit), and rotations
        in ``1/(length sqrt(mass))``, multiplied by ``L / sqrt(Mk)`` — the conversion the UFF reader applies for
        a dataset 164. Frequencies are in Hz in every system listed.

        Raises
        ------
        ValueError
            An unknown system (the message lists them).
        """
        if system not in UNIT_SYSTEMS:
            raise ValueError(f"unknown FE unit system {system!r}; known: {', '.join(UNIT_SYSTEMS)}")
        length, mass = UNIT_SYSTEMS[system]
        if length == 1.0 and mass == 1.0:
            return self
        shapes = self.shapes / np.sqrt(mass)
        if self.has_rotations:
            shapes[..., 3:] *= length
        step = (f"declared in {system}: coordinates / {length:g}, translations / sqrt({mass:g})"
                + (f", rotations * {length:g} / sqrt({mass:g})" if self.has_rotations else "") + " (to SI)")
        return FEModes(self.node_ids, self.xyz / length, self.elements, self.freqs_hz, shapes, self.modal_mass,
                       source=self.source, format=self.format,
                       units=f"SI (m, kg, s), converted from {system} (declared)",
                       history=self.history + (step,), mode_numbers=self.mode_numbers)

    def rotated(self, rotation, *, note: str = "") -> "FEModes":
        """The same modes in another Cartesian frame: ``x' = Q x`` for the proper rotation ``Q``.

        Node coordinates, modal translations and modal rotations (axial
        vectors, which a proper rotation turns like translations) are all
        turned by ``Q``; frequencies, modal masses and the mesh are unchanged.
        The step is added to :attr:`history` (``note`` says why).

        Raises
        ------
        FEGeometryError
            ``rotation`` is not a 3 × 3 proper rotation (orthonormal, det +1).
        """
        q = np.asarray(rotation, float)
        if q.shape != (3, 3) or not np.all(np.isfinite(q)) or not np.allclose(q @ q.T, np.eye(3), atol=1e-9) \
                or np.linalg.det(q) < 0:
            raise FEGeometryError(f"rotation must be a 3 x 3 proper rotation matrix (orthonormal, det +1), got "
                                  f"{np.round(q, 6).tolist()}")
        shapes = self.shapes.copy()
        shapes[..., :3] = shapes[..., :3] @ q.T
        if self.has_rotations:
            shapes[..., 3:] = shapes[..., 3:] @ q.T
        step = "rotated into another frame" + (f" ({note})" if note else "")
        return FEModes(self.node_ids, self.xyz @ q.T, self.elements, self.freqs_hz, shapes, self.modal_mass,
                       source=self.source, format=self.format, units=self.units, history=self.history + (step,),
                       mode_numbers=self.mode_numbers)

    def index(self, node: int) -> int:
        """Row of ``node`` in ``node_ids``; ``KeyError`` naming the node otherwise."""
        hit = np.flatnonzero(self.node_ids == int(node))
        if hit.size == 0:
            raise KeyError(f"node {node} is not in the FE model ({self.source or 'in memory'})")
        return int(hit[0])

    @functools.cached_property
    def offset_limit(self) -> float:
        """Largest point-to-node distance [m] :meth:`at_points` accepts: a quarter of the model size
        (:func:`fem_import.checks.point_offset_limit`; infinite without coordinates)."""
        from .checks import point_offset_limit

        limit = point_offset_limit(self)
        return limit if np.isfinite(limit) and limit > 0 else float("inf")

    @property
    def has_coordinates(self) -> bool:
        """True if every node has finite coordinates."""
        return bool(np.all(np.isfinite(self.xyz)))

    def _where(self) -> str:
        return self.source or "FE modes in memory"

    def _row(self, node, name: str) -> int:
        try:
            value = float(node)
        except (TypeError, ValueError):
            raise FEGeometryError(f"{name}: fe_node must be an integer node label, got {node!r}") from None
        if not np.isfinite(value) or value != round(value):
            raise FEGeometryError(f"{name}: fe_node must be an integer node label, got {node!r}")
        hit = np.flatnonzero(self.node_ids == int(value))
        if hit.size == 0:
            raise FEGeometryError(f"{name}: fe_node {int(value)} is not a node of the FE model ({self._where()}, "
                                  f"{self.node_ids.size} nodes)")
        return int(hit[0])

    def nearest_node(self, position, tolerance: float = 0.05, *, name: str = "point") -> int:
        """Label of the node closest to ``position``, if within ``tolerance``.

        Parameters
        ----------
        position : array_like (3,)
            Point [m].
        tolerance : float, optional
            Largest accepted distance [m] (default 0.05).
        name : str, optional
            Name of the point for error messages.

        Returns
        -------
        int
            Node label.

        Raises
        ------
        MissingCoordinatesError
            If the model has no node coordinates (punch file without geometry).
        PointToleranceError
            If no node lies within ``tolerance``; the message gives the
            closest node and its distance.
        """
        tol = _check_tolerance(tolerance)
        pos = np.asarray(position, float)
        if pos.shape != (3,) or not np.all(np.isfinite(pos)):
            raise FEGeometryError(f"{name}: position must be 3 finite coordinates [m], got {position!r}")
        ok = np.all(np.isfinite(self.xyz), axis=1)
        if not ok.any():
            raise MissingCoordinatesError(
                f"{name}: the FE model ({self._where()}) has no node coordinates, so the node nearest to "
                f"{pos.tolist()} cannot be found; read it with geometry= (fem_import.read(path, geometry=...) in "
                f"Python, --geometry FILE on the command line) or give the fe_node")
        rows = np.flatnonzero(ok)
        dist = np.linalg.norm(self.xyz[rows] - pos, axis=1)
        k = int(np.argmin(dist))
        if dist[k] > tol:
            raise PointToleranceError(
                f"{name}: no FE node within {tol:g} m of {pos.tolist()}; the closest is node "
                f"{int(self.node_ids[rows[k]])} at {dist[k]:.4g} m ({self._where()})")
        return int(self.node_ids[rows[k]])

    def at_points(self, fe_nodes, positions, directions, *, tolerance: float = 0.05, names=None,
                  max_offset=None) -> np.ndarray:
        """Mode shapes at points rigidly attached to FE nodes, along given directions.

        For a point ``p`` attached to node ``n`` (position ``x_n``, modal
        translation ``u`` and rotation ``theta``) measuring along the unit
        vector ``d``, the modal displacement is
        ``d . (u + theta x (p - x_n))`` (small rotations of a rigid link).
        With 3-DOF shapes (no rotations), or a node whose rotations are zero
        in every mode (:attr:`rotation_free`), it is ``d . u``, accepted only
        when the point lies within ``tolerance`` of its node.  These are the shape
        coefficients of the modal superposition ``x = [Phi] q`` (thesis
        eq. 2.24) at the sensor and force locations.

        Parameters
        ----------
        fe_nodes : sequence of int or None, or None
            Node each point is attached to; None (or NaN) entries, or None
            for all, take the nearest node within ``tolerance``.
        positions : array_like (p, 3) or None
            Point positions [m]; None: the points are at their nodes (zero
            offset, works without node coordinates).
        directions : array_like (p, 3)
            Measuring directions; normalised (with a warning) if not unit.
        tolerance : float, optional
            Largest point-to-node distance [m] for the nearest-node search
            and for 3-DOF shapes (default 0.05).
        names : sequence of str, optional
            Point names for error messages (default ``"point <k>"``).
        max_offset : None, "model" or float, optional
            Refuse a point farther than this from its node [m]; ``"model"``:
            :attr:`offset_limit` (a quarter of the model size, what tables of
            sensors and points are checked with); None (default): no check (a
            rigid link of any length).

        Returns
        -------
        ndarray (p, m)
            Real modal displacement of each point (row) in each mode
            (column), mass-normalised like the shapes.

        Raises
        ------
        FEGeometryError
            Bad sizes, a zero/non-finite direction, an fe_node not in the
            model (names the point and node).
        MissingCoordinatesError
            Positions given (or a nearest node asked) but the model has no
            coordinates.
        PointToleranceError
            A 3-DOF model (or a node without rotations) and a point farther
            than ``tolerance`` from its node, or no node within ``tolerance`` (names the point and
            distance); a point farther from its node than ``max_offset`` (a
            wrong node or unit, named "looks like mm" when a unit factor
            explains it).
        """
        tol = _check_tolerance(tolerance)
        d = np.asarray(directions, float)
        if d.ndim != 2 or d.shape[1] != 3:
            raise FEGeometryError(f"directions must have shape (n_points, 3), got {d.shape}")
        p = d.shape[0]
        names = [f"point {k}" for k in range(p)] if names is None else [str(n) for n in names]
        if len(names) != p:
            raise FEGeometryError(f"names has {len(names)} entries for {p} points")
        nodes = [None] * p if fe_nodes is None else list(fe_nodes)
        if len(nodes) != p:
            raise FEGeometryError(f"fe_nodes has {len(nodes)} entries for {p} directions")
        pos = None
        if positions is not None:
            pos = np.asarray(positions, float)
            if pos.shape != (p, 3):
                raise FEGeometryError(f"positions must have shape ({p}, 3), got {pos.shape}")
            bad = ~np.all(np.isfinite(pos), axis=1)
            if bad.any():
                k = int(np.argmax(bad))
                raise FEGeometryError(f"{names[k]}: position must be finite, got {pos[k].tolist()}")
        norm = np.linalg.norm(d, axis=1)
        bad = ~np.isfinite(norm) | (norm == 0)
        if bad.any():
            k = int(np.argmax(bad))
            raise FEGeometryError(f"{names[k]}: direction must be a finite non-zero vector, got {d[k].tolist()}")
        off_unit = np.abs(norm - 1.0) > 1e-6
        if off_unit.any():
            k = int(np.argmax(off_unit))
            warnings.warn(f"{names[k]}: direction {d[k].tolist()} has length {norm[k]:.6g}; directions are "
                          f"normalised to unit length", UserWarning, stacklevel=2)
        d = d / norm[:, None]

        rows = np.empty(p, np.int64)
        for k, node in enumerate(nodes):
            if node is None or (isinstance(node, (float, np.floating)) and np.isnan(node)):
                if pos is None:
                    raise FEGeometryError(f"{names[k]}: neither fe_node nor position is given")
                rows[k] = self.index(self.nearest_node(pos[k], tol, name=names[k]))
            else:
                rows[k] = self._row(node, names[k])

        if pos is None:
            offset = np.zeros((p, 3))
        else:
            node_xyz = self.xyz[rows]
            missing = ~np.all(np.isfinite(node_xyz), axis=1)
            if missing.any():
                k = int(np.argmax(missing))
                raise MissingCoordinatesError(
                    f"{names[k]}: node {int(self.node_ids[rows[k]])} has no coordinates in {self._where()}, so the "
                    f"offset of the point from its node is unknown; read the modes with geometry= "
                    f"(fem_import.read(path, geometry=...) in Python, --geometry FILE on the command line) or "
                    f"pass positions=None for points at their nodes")
            offset = pos - node_xyz
            if max_offset is not None:
                # a rigid link longer than a quarter of the structure is a wrong node or a wrong unit
                limit = self.offset_limit if isinstance(max_offset, str) else float(max_offset)
                far = np.linalg.norm(offset, axis=1) > limit
                if far.any():
                    from .checks import check_point_offsets

                    k = int(np.argmax(far))
                    check_point_offsets(self, [self.node_ids[rows[k]]], pos[k:k + 1], [names[k]], limit=limit)
        # a node without rotations (a 3-DOF export, or a solid element's node in a 6-DOF one) carries a point only
        # where the rigid link's rotation share is negligible: within the tolerance
        dist = np.linalg.norm(offset, axis=1)
        far = self.rotation_free[rows] & (dist > tol)
        if far.any():
            k = int(np.argmax(far))
            node = int(self.node_ids[rows[k]])
            why = (f"node {node} carries no rotations (they are zero in every mode of {self._where()}: a solid "
                   f"element's node, exported with 6 DOF)" if self.has_rotations else
                   f"the shapes have no rotations (3 DOF per node) at its node {node}")
            raise PointToleranceError(
                f"{names[k]}: {why} and the point lies {dist[k]:.4g} m from it, more than the tolerance {tol:g} m; "
                f"attach it to a node within {tol:g} m (a surface node next to the sensor, its fe_node), export the "
                f"shapes with rotations at a beam or RBE node, or, in Python, pass a larger tolerance= to "
                f"FEModes.at_points")
        disp = self.shapes[:, rows, :3]
        if self.has_rotations:
            disp = disp + np.cross(self.shapes[:, rows, 3:], offset[None, :, :])
        return np.einsum("mpk,pk->pm", disp, d)


def number_ranges(numbers, limit: int | None = None) -> str:
    """``[1, 2, 3, 7]`` -> ``"1-3, 7"``: runs of consecutive integers in the order given (sort first for sets), at
    most ``limit`` runs (``", ... (k more runs)"``), for messages that name datasets, nodes, modes or rows."""
    out, run = [], []
    for n in numbers:
        if run and n == run[-1] + 1:
            run.append(n)
            continue
        if run:
            out.append(f"{run[0]}-{run[-1]}" if len(run) > 1 else str(run[0]))
        run = [n]
    if run:
        out.append(f"{run[0]}-{run[-1]}" if len(run) > 1 else str(run[0]))
    if limit is not None and len(out) > limit:
        return ", ".join(out[:limit]) + f", ... ({len(out) - limit} more runs)"
    return ", ".join(out)


def _check_tolerance(tolerance) -> float:
    try:
        tol = float(tolerance)
    except (TypeError, ValueError):
        raise FEGeometryError(f"tolerance must be a non-negative distance [m], got {tolerance!r}") from None
    if not np.isfinite(tol) or tol < 0:
        raise FEGeometryError(f"tolerance must be a non-negative distance [m], got {tolerance!r}")
    return tol


def shapes_at_channels(fe_modes: FEModes, channels, *, tolerance: float = 0.05,
                       quantity: str | None = "acceleration") -> np.ndarray:
    """Mode shapes at the sensors of a channel table.

    Parameters
    ----------
    fe_modes : FEModes
    channels : pandas.DataFrame
        Channel table (``shared/DESIGN.md`` schema): columns ``x, y, z, dx,
        dy, dz``, optional ``fe_node`` (missing/NaN: nearest node within
        ``tolerance``), optional ``name`` and ``quantity``.
    tolerance : float, optional
        See :meth:`FEModes.at_points`.
    quantity : str or None, optional
        Keep only rows with this ``quantity`` (default ``"acceleration"``,
        i.e. drop the force row); None keeps all rows.

    Returns
    -------
    ndarray (n_rows, m)
        Shapes at the kept rows, in table order (``d . (u + theta x offset)``).

    Raises
    ------
    ValueError
        If a required column is missing (names it) or no row is kept.
    FEGeometryError
        As :meth:`FEModes.at_points`, naming the channel; a sensor farther
        from its ``fe_node`` than a quarter of the model size
        (:attr:`FEModes.offset_limit`) is refused (PointToleranceError).
    """
    import pandas as pd

    if not isinstance(channels, pd.DataFrame):
        raise TypeError(f"channels must be a pandas DataFrame, got {type(channels).__name__}")
    need = ["x", "y", "z", "dx", "dy", "dz"]
    missing = [c for c in need if c not in channels.columns]
    if missing:
        raise ValueError(f"channel table lacks column(s) {missing}; required: {need}, optional: fe_node, name, "
                         f"quantity")
    rows = channels
    if quantity is not None and "quantity" in channels.columns:
        rows = channels[channels["quantity"] == quantity]
        if rows.empty:
            raise ValueError(f"channel table has no row with quantity {quantity!r}; quantities present: "
                             f"{sorted(channels['quantity'].astype(str).unique())}")
    if "name" in rows.columns:
        names = [f"channel {n!r}" for n in rows["name"].tolist()]
    else:
        names = [f"channel row {i!r}" for i in rows.index.tolist()]
    if "fe_node" in rows.columns:
        nodes = [None if pd.isna(v) else v for v in rows["fe_node"].tolist()]
    else:
        nodes = None
    return fe_modes.at_points(nodes, rows[["x", "y", "z"]].to_numpy(float), rows[["dx", "dy", "dz"]].to_numpy(float),
                              tolerance=tolerance, names=names, max_offset="model")
