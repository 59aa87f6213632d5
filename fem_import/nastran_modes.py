"""What the Nastran result readers (punch, print file, OP2, HDF5) share: one parsed mode, choosing a subcase, and one
shapes array from per-mode grid lists.

A parsed mode (:class:`ParsedMode`, or any object with the same attributes) has ``number``, ``eigenvalue``
(``lambda = omega**2``), ``subcase``, ``line``, ``ids`` (grid ids) and ``vals`` (T1 T2 T3 R1 R2 R3 per grid).
"""

from __future__ import annotations

import logging
import math

import numpy as np

from .errors import FEReadError

__all__ = ["ParsedMode", "select_subcase", "grid_shapes", "frequencies"]

log = logging.getLogger("fem_import")


class ParsedMode:
    """One eigenvector as a reader collects it: its grids' ids and values are appended as they are read."""

    __slots__ = ("number", "eigenvalue", "subcase", "line", "ids", "vals")

    def __init__(self, number, eigenvalue, subcase, line):
        self.number, self.eigenvalue, self.subcase, self.line = number, eigenvalue, subcase, line
        self.ids: list[int] = []
        self.vals: list = []


def select_subcase(path: str, modes: list, subcase, what: str = "file") -> list:
    """The modes of one subcase: the only one, ``subcase`` (an id), or with ``"lowest"`` the lowest id (a
    WARNING names the others). Several subcases and ``subcase=None`` are refused, naming each with its modes'
    band; ``what`` names the file kind in the advice."""
    subcases = sorted({m.subcase for m in modes}, key=lambda s: (s is None, s))
    if subcase is None or (isinstance(subcase, str) and subcase == "lowest"):
        if len(subcases) > 1:
            def band(s):
                f = [math.sqrt(max(m.eigenvalue, 0.0)) / (2 * math.pi) for m in modes if m.subcase == s]
                return f"subcase {s}: {len(f)} modes, {min(f):.4g}-{max(f):.4g} Hz"

            listed = "; ".join(band(s) for s in subcases)
            if subcase is None:
                raise FEReadError(path, f"eigenvectors of {len(subcases)} subcases {subcases} ({listed}); choose "
                                  f"one: fem_import.read(path, subcase=N) in Python (the command line reads the "
                                  f"lowest, subcase {subcases[0]}, with a warning)")
            log.warning("%s: eigenvectors of %d subcases %s (%s); subcase %s is read. Another one: "
                        "fem_import.read(path, subcase=N) or fem_import.read_with_geometry(path, subcase=N) in "
                        "Python; the command line has no subcase option: write a %s of that subcase alone",
                        path, len(subcases), subcases, listed, subcases[0], what)
            return [m for m in modes if m.subcase == subcases[0]]
        return list(modes)
    if subcase not in subcases:
        raise FEReadError(path, f"subcase {subcase!r} is not in the file; it has subcases {subcases}")
    return [m for m in modes if m.subcase == subcase]


def grid_shapes(path: str, modes: list, label: str = "mode") -> tuple[np.ndarray, np.ndarray]:
    """``(grid ids, shapes (m, n, 6))`` in the grid order of the first mode.

    Raises FEReadError naming the mode (``label`` and number) and its line: no grids, a grid given twice, a
    non-finite value, or a grid set that differs from the first mode's (a truncated file)."""
    first = modes[0]
    for m in modes:
        if not m.ids:
            raise FEReadError(path, f"{label} {m.number} has no grid entries (truncated file?)", line=m.line)
        uniq, counts = np.unique(np.asarray(m.ids, np.int64), return_counts=True)
        if np.any(counts > 1):
            raise FEReadError(path, f"{label} {m.number} lists grid(s) {uniq[counts > 1][:10].tolist()} more "
                              f"than once", line=m.line)
        bad = ~np.all(np.isfinite(np.asarray(m.vals, float)), axis=1)
        if np.any(bad):
            raise FEReadError(path, f"{label} {m.number} has non-finite values at grid {m.ids[int(np.argmax(bad))]}",
                              line=m.line)
    ref_ids = np.asarray(first.ids, np.int64)
    ref = set(first.ids)
    shapes = np.empty((len(modes), ref_ids.size, 6))
    for j, m in enumerate(modes):
        ids = np.asarray(m.ids, np.int64)
        if len(m.ids) != ref_ids.size or set(m.ids) != ref:
            missing = sorted(ref - set(m.ids))
            extra = sorted(set(m.ids) - ref)
            what = (f"lacks grid(s) {missing[:10]} of {label} {first.number}" if missing
                    else f"has grid(s) {extra[:10]} absent from {label} {first.number}")
            raise FEReadError(path, f"{label} {m.number} {what} (truncated file?): all modes must cover the same "
                              f"grids", line=m.line)
        order = np.argsort(ids, kind="stable")
        shapes[j] = np.asarray(m.vals, float)[order[np.searchsorted(ids, ref_ids, sorter=order)]]
    return ref_ids, shapes


def frequencies(path: str, modes: list) -> np.ndarray:
    """``sqrt(max(lambda, 0)) / 2 pi`` [Hz]; eigenvalues below ``-(2 pi 0.1 Hz)^2`` are named in a WARNING (rigid-body
    modes come out with tiny negative ones)."""
    lam = np.array([m.eigenvalue for m in modes])
    big_neg = np.flatnonzero(lam < -(2 * math.pi * 0.1) ** 2)
    if big_neg.size:
        log.warning("%s: mode(s) %s have negative eigenvalues %s (below -(2 pi 0.1 Hz)^2); set to 0 Hz", path,
                    [modes[k].number for k in big_neg], lam[big_neg].tolist())
    return np.sqrt(np.maximum(lam, 0.0)) / (2 * math.pi)
