"""Node coordinates from a Nastran bulk data file (GRID cards): the geometry a punch file lacks.

A Nastran punch file (:mod:`fem_import.punch`) carries eigenvectors but no
coordinates; the model's input deck (``.bdf``, ``.dat``, ``.nas``) has them
as GRID cards. This module reads only those, in the three field formats of
the Nastran Quick Reference Guide (bulk data entry format):

* small field: 8-column fields, ``GRID    ID      CP      X1      X2      X3      CD``;
* large field: ``GRID*`` with 16-column fields, X3 and CD on the ``*`` continuation;
* free field: comma-separated, ``GRID,ID,CP,X1,X2,X3,CD``.

Real numbers may use Nastran's exponent shorthand (``7.85-3`` = 7.85e-3,
``1.+4``) and Fortran ``D`` exponents. Only the basic coordinate system is
supported: a GRID with a non-zero ``CP`` (position system) or ``CD``
(displacement system: the punch's eigenvectors of that grid would be in it)
is refused, naming the grid and line. Lines before ``BEGIN BULK`` (executive
and case control) are skipped when the file has that line; ``INCLUDE`` files
are not followed (a warning names them). Units are taken as SI, like the
punch file's.

pyNastran reads bulk data completely, but its current release pins
``numpy < 2`` (this project runs on numpy 2), so the few GRID formats are
parsed here.
"""

from __future__ import annotations

import logging
import re

import numpy as np

from .errors import FEReadError
from .modes import FEModes
from .registry import Geometry, register_format

__all__ = ["read_bulk_geometry", "sniff_bulk", "parse_nastran_real"]

log = logging.getLogger("fem_import")

_SHORT_EXP = re.compile(r"^([+-]?(?:\d+\.?\d*|\.\d+))([+-]\d+)$")
_BULK_WORDS = ("BEGIN BULK", "SOL ", "CEND", "GRID", "CBAR", "CQUAD4", "CTRIA3", "CHEXA", "MAT1", "PSHELL",
               "EIGRL", "ENDDATA")


def parse_nastran_real(text: str) -> float:
    """A Nastran real field: ``1.5``, ``1.5E-3``, ``1.5D-3``, ``1.5-3`` (= 1.5e-3), ``1.+4``; blank is 0.

    Raises
    ------
    ValueError
        Not a number.
    """
    t = text.strip().upper().replace("D", "E")
    if not t:
        return 0.0
    m = _SHORT_EXP.match(t)
    if m:
        t = f"{m.group(1)}E{m.group(2)}"
    return float(t)


def sniff_bulk(head: bytes) -> bool:
    """True if, past comments, the file starts like a Nastran input deck (executive/case control or bulk entries)."""
    text = head.decode("latin-1")
    for ln in text.splitlines():
        s = ln.strip().upper()
        if not s or s.startswith("$"):
            continue
        return any(s.startswith(w) for w in _BULK_WORDS) or s.startswith(("ID ", "TIME ", "SOL,", "GRID*",
                                                                            "GRID,"))
    return False


def _fields(path: str, lines: list[str], i: int) -> tuple[list[str], int]:
    """The fields of the GRID entry at line ``i`` (ID, CP, X1, X2, X3, CD) and the next line index."""
    line = lines[i].rstrip("\r\n")
    head = line[:8].strip().upper()
    if "," in line[:10]:
        parts = [p.strip() for p in line.split(",")]
        vals = parts[1:7]
        return vals + [""] * (6 - len(vals)), i + 1
    if head.startswith("GRID*"):
        body = line[8:72].ljust(64)
        vals = [body[k:k + 16] for k in range(0, 64, 16)]  # ID, CP, X1, X2
        nxt = i + 1
        cont = ""
        if nxt < len(lines) and lines[nxt][:1] == "*":
            cont = lines[nxt].rstrip("\r\n")[8:72].ljust(64)
            nxt += 1
        else:
            raise FEReadError(path, "large-field GRID* entry without its '*' continuation line (X3, CD)",
                              line=i + 1)
        return vals + [cont[0:16], cont[16:32]], nxt
    body = line[8:72].ljust(64)
    return [body[k:k + 8] for k in range(0, 48, 8)], i + 1


def read_bulk_geometry(path: str) -> Geometry:
    """Grid points (ID and basic coordinates) from a Nastran bulk data file.

    Returns
    -------
    Geometry
        Node ids in file order, coordinates [m] (SI assumed), no elements.

    Raises
    ------
    FEReadError
        No GRID entry, a field that is not a number, a repeated grid id, or a
        grid in a non-basic coordinate system (CP or CD not 0); names the line.
    """
    with open(path, encoding="latin-1") as fh:
        lines = fh.read().splitlines()
    start = 0
    for k, ln in enumerate(lines):
        if ln.strip().upper().startswith("BEGIN BULK"):
            start = k + 1
            break
    ids: list[int] = []
    xyz: list[tuple[float, float, float]] = []
    seen: dict[int, int] = {}
    includes = []
    i = start
    while i < len(lines):
        raw = lines[i]
        s = raw.strip().upper()
        if s.startswith("INCLUDE"):
            includes.append(raw.strip())
        if not s.startswith("GRID"):
            i += 1
            continue
        line_no = i + 1
        f, i = _fields(path, lines, i)
        try:
            gid = int(f[0].strip())
        except ValueError:
            raise FEReadError(path, f"GRID id {f[0].strip()!r} is not an integer", line=line_no) from None
        if gid <= 0 or gid >= 2**31:
            raise FEReadError(path, f"GRID id {gid} outside 1 .. 2^31-1", line=line_no)
        for what, text in (("CP", f[1]), ("CD", f[5])):
            t = text.strip()
            if t and t != "0":
                raise FEReadError(path, f"GRID {gid} uses coordinate system {what} = {t}; only the basic system "
                                  f"(blank or 0) is supported — export the grids in the basic system", line=line_no)
        try:
            x = tuple(parse_nastran_real(v) for v in f[2:5])
        except ValueError:
            bad = next(v.strip() for v in f[2:5] if not _is_real(v))
            raise FEReadError(path, f"GRID {gid}: coordinate {bad!r} is not a number", line=line_no) from None
        if not all(np.isfinite(x)):
            raise FEReadError(path, f"GRID {gid}: non-finite coordinate {list(x)}", line=line_no)
        if gid in seen:
            raise FEReadError(path, f"GRID {gid} is defined twice (lines {seen[gid]} and {line_no})", line=line_no)
        seen[gid] = line_no
        ids.append(gid)
        xyz.append(x)
    if includes:
        log.warning("%s: INCLUDE statements are not followed (%s); grids in included files are not read",
                    path, "; ".join(includes[:3]))
    if not ids:
        raise FEReadError(path, "no GRID entry: the file carries no node coordinates")
    return Geometry(np.asarray(ids, np.int64), np.asarray(xyz, float), (), str(path),
                    "SI (m, kg, s) assumed (a bulk data file does not state units)")


def _is_real(text: str) -> bool:
    try:
        parse_nastran_real(text)
        return True
    except ValueError:
        return False


def _no_modes(path: str, **kwargs) -> FEModes:
    raise FEReadError(path, "a Nastran bulk data file holds no mode shapes; use it as the geometry of a punch file "
                      "(fem_import.read(punch, geometry=this file) or --geometry)")


register_format("nastran-bulk", patterns=("*.bdf", "*.dat", "*.nas", "*.blk"), sniff=sniff_bulk, reader=_no_modes,
                geometry=read_bulk_geometry, aliases=("bdf", "bulk"),
                description="Nastran bulk data (GRID cards), geometry only")
