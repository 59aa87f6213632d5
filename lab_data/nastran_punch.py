"""MSC/NX Nastran punch (``.pch``) exporter for real eigenvectors, SORT1.

A SOL 103 run with ``DISPLACEMENT(PUNCH) = ALL`` (or ``VECTOR(PUNCH)``)
writes one block per mode.  Every line is an 80-column card image: data in
columns 1-72 and a running line counter (``I8``) in columns 73-80 that
counts over the whole file.  Formats as in the Nastran OFP punch routine
(``OFPPUN`` of COSMIC NASTRAN, which MSC and NX kept)::

    $TITLE   =<title>                                              FORMAT(10H$TITLE   =,15A4,2X,I8)
    $SUBTITLE=<subtitle>                                           FORMAT(10H$SUBTITLE=,15A4,2X,I8)
    $LABEL   =<label>                                              FORMAT(10H$LABEL   =,15A4,2X,I8)
    $EIGENVECTOR                                                   FORMAT(12H$EIGENVECTOR,60X,I8)
    $REAL OUTPUT                                                   FORMAT(12H$REAL OUTPUT,60X,I8)
    $SUBCASE ID =           1                                      FORMAT(13H$SUBCASE ID =,I12,47X,I8)
    $EIGENVALUE =  3.9478418E+05  MODE =     1                     FORMAT(13H$EIGENVALUE =,1P,E15.7,2X,6HMODE =,I6,30X,I8)
             1       G      1.000000E-01      0.000000E+00 ...     FORMAT(I10,7X,A1,3(1P,E18.6),I8)
    -CONT-                  3.000000E-03      0.000000E+00 ...     FORMAT(6H-CONT-,12X,3(1P,E18.6),I8)

Column map of a grid card: 1-10 grid id, 18 point type (``G`` grid),
19-36 / 37-54 / 55-72 T1, T2, T3; continuation card: 1-6 ``-CONT-``,
19-36 / 37-54 / 55-72 R1, R2, R3; 73-80 line counter.  The eigenvalue is
``lambda = omega**2 = (2*pi*f)**2`` in (rad/s)**2.

Precision: eigenvalues ``1PE15.7`` = 8 significant digits (frequencies
recovered to a relative 2.5e-8), vector components ``1PE18.6`` = 7
significant digits (relative rounding error <= 5e-7).  Components with
magnitude below 1e-99 are written as 0 (Nastran prints two-digit
exponents); magnitudes of 1e99 or more are rejected.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from .validation import check_finite_array, check_labels, check_text

__all__ = ["write_punch_eigenvectors"]

_MAX_GRID_ID = 99_999_999     # Nastran grid ids: 0 < id < 100,000,000
_MAX_COUNTER = 99_999_999     # I8 line counter
_TINY = 1e-99
_HUGE = 1e99


def _card(text: str, counter: int) -> str:
    return f"{text:<72}{counter:8d}\n"


def write_punch_eigenvectors(path, node_ids, freqs_hz, shapes, *, title="") -> Path:
    """Write real eigenvectors as an MSC/NX Nastran SORT1 punch file.

    One block per mode in the given order (``MODE = 1..n_modes``), each with
    the header cards ``$TITLE``, ``$SUBTITLE``, ``$LABEL``,
    ``$EIGENVECTOR``, ``$REAL OUTPUT``, ``$SUBCASE ID = 1`` and
    ``$EIGENVALUE = (2*pi*f)**2  MODE = n``, followed by a grid card (T1,
    T2, T3) and a ``-CONT-`` card (R1, R2, R3) per grid, all grids of type
    ``G``.  Layout, column map and precision: see the module docstring.

    Parameters
    ----------
    path : str or os.PathLike
        Output file (overwritten), conventionally ``*.pch``.
    node_ids : array_like of int, shape (n_nodes,)
        Positive, unique grid ids (< 100,000,000).
    freqs_hz : array_like of float, shape (n_modes,)
        Natural frequencies [Hz], finite, >= 0 (rigid-body modes have 0).
    shapes : array_like of float, shape (n_modes, n_nodes, 6)
        Eigenvectors in the order T1, T2, T3, R1, R2, R3, finite,
        magnitudes < 1e99.
    title : str, optional
        ``$TITLE`` text, at most 60 printable ASCII characters (``15A4``).
        ``$SUBTITLE`` and ``$LABEL`` are written blank.

    Returns
    -------
    pathlib.Path
        The written file.

    Raises
    ------
    ValueError
        If an argument has the wrong shape, type or value; the message names
        the argument and what was received.
    """
    ids = check_labels("node_ids", node_ids, hi=_MAX_GRID_ID)
    freqs = check_finite_array("freqs_hz", freqs_hz, (None,))
    if np.any(freqs < 0):
        raise ValueError(f"freqs_hz must be >= 0, got {freqs[freqs < 0][:5].tolist()}")
    if freqs.size > 999_999:
        raise ValueError(f"freqs_hz: at most 999999 modes fit the MODE field (I6), got {freqs.size}")

    vecs = check_finite_array("shapes", shapes, (freqs.size, ids.size, 6))
    if np.any(np.abs(vecs) >= _HUGE):
        bad = np.argwhere(np.abs(vecs) >= _HUGE)[0].tolist()
        raise ValueError(f"shapes must have magnitudes below {_HUGE:g}, got {vecs[tuple(bad)]} at index {bad}")
    vecs = np.where(np.abs(vecs) < _TINY, 0.0, vecs)
    eigenvalues = (2.0 * math.pi * freqs) ** 2
    if np.any(eigenvalues >= _HUGE):
        raise ValueError(f"freqs_hz too large for the eigenvalue field, got max {freqs.max()!r}")
    check_text("title", title, max_len=60, allow_empty=True)

    n_lines = freqs.size * (7 + 2 * ids.size)
    if n_lines > _MAX_COUNTER:
        raise ValueError(f"shapes: {n_lines} punch lines exceed the 8-digit line counter")

    grid_fmt = "%10d       G%18.6E%18.6E%18.6E%8d\n-CONT-            %18.6E%18.6E%18.6E%8d\n"
    id_list = ids.tolist()
    counter = 0
    parts = []
    for k in range(freqs.size):
        header = [
            f"$TITLE   ={title:<60}",
            f"$SUBTITLE={'':<60}",
            f"$LABEL   ={'':<60}",
            "$EIGENVECTOR",
            "$REAL OUTPUT",
            f"$SUBCASE ID ={1:12d}",
            f"$EIGENVALUE ={eigenvalues[k]:15.7E}  MODE ={k + 1:6d}",
        ]
        for text in header:
            counter += 1
            parts.append(_card(text, counter))
        flat = []
        for nid, row in zip(id_list, vecs[k].tolist()):
            flat.extend((nid, row[0], row[1], row[2], counter + 1, row[3], row[4], row[5], counter + 2))
            counter += 2
        parts.append((grid_fmt * len(id_list)) % tuple(flat))

    out = Path(os.fspath(path))
    with open(out, "w", encoding="ascii", newline="\n") as fh:
        fh.writelines(parts)
    return out
