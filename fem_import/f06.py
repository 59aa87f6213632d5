"""Nastran print file (``.f06``) reader of real eigenvectors.

The ``.f06`` is what every Nastran run writes, whatever the output requests: when a design office has kept
nothing else, it still holds the modes. pyNastran reads F06 files, but its last release (1.4.1) requires
numpy < 2, which this toolkit does not run on; so, as for the punch (:mod:`fem_import.punch`), a small parser of
what a SOL 103 ``DISPLACEMENT(PRINT)`` (or ``VECTOR``) request prints:

* **The eigenvalue table** (``R E A L   E I G E N V A L U E S``), one row per mode: mode number, extraction
  order, eigenvalue, radians, cycles, generalized mass, generalized stiffness. The generalized mass is 1 for
  Nastran's default ``NORM=MASS``; another (a ``NORM=MAX`` or ``POINT`` run) is divided out, ``φ / sqrt(m)``,
  and said in the history. Without the table (an ``ECHO``-trimmed file) the shapes are taken as
  mass-normalised, as a punch's are, with a note.
* **The eigenvector tables**, one per mode and page::

        EIGENVALUE =  3.948418E+05
            CYCLES =  1.000000E+02         R E A L   E I G E N V E C T O R   N O .          7

        POINT ID.   TYPE          T1             T2             T3             R1             R2             R3
               1      G      0.0            1.234567E-02  ...

  A table continued on the next page repeats the banner with the same number; its rows are appended. Grid
  points (``G``) give 6 DOF; scalar and extra points (``S``, ``E``) are skipped with a logged count. The page
  headers (a ``1`` in column 1, titles, ``SUBCASE n``) are skipped; the subcase is the last one they name.
  Fortran's letterless exponents (``1.234567-102``) and ``D`` exponents are read.

The eigenvalue is ``lambda = omega**2``, so ``f = sqrt(max(lambda, 0)) / (2 pi)``. Nastran prints the components
of each grid in its displacement coordinate system (``CD``), as it punches them; the bulk deck merged as geometry
says which, and :func:`fem_import.merge_geometry` rotates them to the basic system. A print file carries no
geometry and states no units: as for a punch, the coordinates come from a companion deck or ``--geometry``, and
units are SI unless declared (``--fe-units``). Complex eigenvectors are refused.

**Geometry from the bulk data echo.** A run with ``ECHO = SORT`` (Nastran's default) prints its bulk data in the
``S O R T E D   B U L K   D A T A   E C H O``: each card image eight columns after its entry count and dash
(``      27-        GRID    1001            0.      -.75    0.``). Those card images are read by the bulk-deck
reader (:func:`fem_import.nastran_bulk.bulk_geometry`, at the print file's own line numbers): grids, coordinate
systems and elements, merged into the modes as a companion deck would be. A print file without the echo
(``ECHO = NONE``), or whose echo lacks a grid of the eigenvectors, takes its geometry from a companion deck.
"""

from __future__ import annotations

import logging
import math
import re
from pathlib import Path

import numpy as np

from .errors import FEReadError
from .modes import FEModes
from .nastran_modes import ParsedMode as _Mode, frequencies, grid_shapes, select_subcase
from .registry import register_format

__all__ = ["read_f06", "sniff_f06"]

log = logging.getLogger("fem_import")

_VECTOR = re.compile(r"R E A L\s+E I G E N V E C T O R\s+N O \.\s+(\d+)")
_COMPLEX = re.compile(r"C O M P L E X\s+E I G E N V E C T O R")
_EIGENVALUE = re.compile(r"^\s*EIGENVALUE\s*=\s*(\S+)")
_TABLE = re.compile(r"R E A L\s+E I G E N V A L U E S")
_SUPERELEMENT = re.compile(r"^\s{20,}SUPERELEMENT\s+(\d+)\s*$")  # the page header of a superelement's output
_SUBCASE = re.compile(r"SUBCASE\s+(\d+)\s*$")
_SPACED = re.compile(r"(?:[A-Z] ){4,}[A-Z]")
_ECHO_CARD = re.compile(r"^\s*\d+-")
_NUMBER = re.compile(r"^([+-]?(?:\d+\.?\d*|\.\d+))(?:[EeDd]?([+-]\d+))?$")


def sniff_f06(head: bytes) -> bool:
    """True for a Nastran print file: spaced-letter headings (``E X E C U T I V E``, ``R E A L``) and page numbers,
    or the banner it opens with (a page eject ``1`` in column 1, then a copyright notice naming Nastran: NX
    Nastran's banner fills the first 4.5 kB, before any heading)."""
    text = head.decode("latin-1")
    upper = text.upper()
    if "NASTRAN" not in upper:
        return False
    if _SPACED.search(text) and re.search(r"\bPAGE\s+\d+", text):
        return True
    return text.split("\n", 1)[0].strip() == "1" and "COPYRIGHT" in upper


def _echo(lines: list[str]) -> list[str] | None:
    """The sorted bulk data echo's card images at their own line numbers, every other line blank (None: no echo)."""
    out = [""] * len(lines)
    inside = found = False
    for i, text in enumerate(lines):
        if "S O R T E D   B U L K   D A T A   E C H O" in text:
            inside = found = True
            continue
        if not inside:
            continue
        m = _ECHO_CARD.match(text)
        if m:
            out[i] = text[m.end() + 8:].rstrip()
        elif text.strip().upper() == "ENDDATA" or _TABLE.search(text) or _VECTOR.search(text):
            inside = False
    return out if found else None


def _number(token: str) -> float | None:
    m = _NUMBER.match(token)
    if m is None:
        return None
    return float(m.group(1) + (f"e{m.group(2)}" if m.group(2) else ""))


def _parse(path: str, lines: list[str]):
    """The eigenvector tables (in file order) and the eigenvalue table's rows ``{(subcase, mode): (lambda, m)}``."""
    modes: dict[tuple, _Mode] = {}
    table: dict[tuple, tuple[float, float]] = {}
    subcase = None
    eigenvalue = None
    current: _Mode | None = None
    in_table = augmented = listing = resvec_next = False
    rows = 0
    skipped: dict[str, int] = {}
    for i, raw in enumerate(lines):
        line_no = i + 1
        text = raw.rstrip("\r\n")
        m = _SUBCASE.search(text)
        if m and (text.startswith("0") or text.lstrip().startswith("SUBCASE")):
            subcase = int(m.group(1))
            continue
        m = _SUPERELEMENT.match(text)
        if m and int(m.group(1)) != 0:
            raise FEReadError(path, f"the print file of a superelement run (pages of SUPERELEMENT {m.group(1)}): each "
                              f"superelement's modes and grids are printed apart, which this reader does not keep "
                              f"apart; print the modes of a run without superelements", line=line_no)
        if "FREQUENCY LIST OF RESIDUAL VECTORS" in text.upper():
            resvec_next = True  # NX prints the residual vectors' own frequencies as an eigenvalue table: not modes
            continue
        if _COMPLEX.search(text):
            raise FEReadError(path, "complex eigenvectors are not supported; expected R E A L   E I G E N V E C T O R "
                              "tables (SOL 103)", line=line_no)
        if _TABLE.search(text):
            in_table, rows, current, augmented = True, 0, None, False
            listing, resvec_next = resvec_next, False
            continue
        if in_table and "AFTER AUGMENTATION" in text.upper():
            augmented = True  # this table's rows replace those printed before the residual vectors were added
            continue
        m = _EIGENVALUE.match(text)
        if m:
            value = _number(m.group(1))
            if value is None or not math.isfinite(value):
                raise FEReadError(path, f"EIGENVALUE {m.group(1)!r} is not a finite number", line=line_no)
            eigenvalue, current, in_table = value, None, False
            continue
        m = _VECTOR.search(text)
        if m:
            number = int(m.group(1))
            key = (subcase, number)
            if key in modes:
                current = modes[key]  # the table continued on a new page
                if current.eigenvalue != eigenvalue and eigenvalue is not None:
                    raise FEReadError(path, f"eigenvector {number} of subcase {subcase} is printed again with another "
                                      f"eigenvalue ({eigenvalue!r}, first {current.eigenvalue!r} at line "
                                      f"{current.line}): are two print files concatenated?", line=line_no)
            else:
                if eigenvalue is None:
                    raise FEReadError(path, f"eigenvector {number} has no 'EIGENVALUE =' line before its banner",
                                      line=line_no)
                current = modes[key] = _Mode(number, eigenvalue, subcase, line_no)
            in_table = False
            continue
        if text.startswith("1"):
            # a page eject ends a table; a banner (or the eigenvalue heading) on the next page resumes it
            current, in_table = None, False
            continue
        tokens = text.split()
        if in_table:
            vals = [_number(t) for t in tokens]
            if len(tokens) == 7 and all(v is not None for v in vals) and tokens[0].isdigit() and tokens[1].isdigit():
                key = (subcase, int(tokens[0]))
                rows += 1
                if listing:
                    continue
                if key in table and not augmented:
                    raise FEReadError(path, f"mode {tokens[0]} appears twice in the eigenvalue table of subcase "
                                      f"{subcase}", line=line_no)
                table[key] = (vals[2], vals[5])
            elif tokens and rows:
                in_table = False  # what follows the rows (a message, OUTPUT2's trailer numbers) is not the table
            continue
        if current is None or len(tokens) < 2 or not tokens[0].isdigit() or len(tokens[1]) != 1:
            continue
        kind = tokens[1].upper()
        if kind != "G":
            skipped[kind] = skipped.get(kind, 0) + 1
            continue
        if len(tokens) != 8:
            raise FEReadError(path, f"grid {tokens[0]} of eigenvector {current.number}: {len(tokens) - 2} values, "
                              f"expected T1 T2 T3 R1 R2 R3 (truncated file?)", line=line_no)
        vals = [_number(t) for t in tokens[2:]]
        if any(v is None for v in vals):
            bad = tokens[2 + [v is None for v in vals].index(True)]
            raise FEReadError(path, f"grid {tokens[0]} of eigenvector {current.number}: {bad!r} is not a number",
                              line=line_no)
        if not all(math.isfinite(v) for v in vals):
            raise FEReadError(path, f"grid {tokens[0]} of eigenvector {current.number} has non-finite values",
                              line=line_no)
        current.ids.append(int(tokens[0]))
        current.vals.append(vals)
    if skipped:
        log.info("%s: eigenvector rows of other point types skipped: %s", path,
                 ", ".join(f"{k} x{v}" for k, v in sorted(skipped.items())))
    return list(modes.values()), table


def read_f06(path: str, *, subcase: int | str | None = None, echo: bool = True) -> FEModes:
    """Read real eigenvectors from a Nastran print file (module docstring).

    Parameters
    ----------
    path : str
        The file.
    subcase : int, "lowest" or None, optional
        As for :func:`fem_import.punch.read_punch`: None requires a single subcase, ``"lowest"`` reads the lowest
        with a WARNING naming the others.
    echo : bool, optional
        Take the geometry from the bulk data echo (module docstring); :func:`fem_import.read` passes False when
        it is given a geometry.

    Returns
    -------
    FEModes
        Modes in mode-number order, 6 DOF per grid, mass-normalised (the generalized mass of the eigenvalue
        table divided out), the file's mode numbers kept; coordinates, elements and displacement systems from
        the bulk data echo when the file has one, else node coordinates NaN and no elements (merge them with
        ``read(..., geometry=...)``), in the grid order of the first mode.

    Raises
    ------
    FEReadError
        No real eigenvector table, complex eigenvectors, several subcases and no ``subcase``, a grid row with
        too few or bad values (names the line), a mode whose grid set differs from the first mode's, a grid
        printed twice in a mode, or a generalized mass that is not positive.
    """
    with open(path, encoding="latin-1", newline=None) as fh:
        lines = fh.read().split("\n")
    modes, table = _parse(path, lines)
    if not modes:
        beside = [q.name for q in (Path(path).with_suffix(".op2"), Path(path).with_suffix(".h5")) if q.is_file()]
        raise FEReadError(path, "no real eigenvectors found (expected 'R E A L   E I G E N V E C T O R   N O .' "
                          "tables: a SOL 103 run with DISPLACEMENT(PRINT) = ALL or VECTOR = ALL)"
                          + (f"; the run's results file beside it may hold them: read {beside[0]}" if beside else ""))
    chosen_modes = select_subcase(path, modes, subcase, "print file")
    chosen = chosen_modes[0].subcase
    modes = sorted(chosen_modes, key=lambda m: m.number)
    ref_ids, shapes = grid_shapes(path, modes, "eigenvector")
    numbers = [m.number for m in modes]
    history = [f"read {len(modes)} modes ({numbers[0]}..{numbers[-1]}, subcase {chosen}) on {ref_ids.size} grids "
               f"from Nastran print file {path}; no geometry in the file"]
    rows = [table.get((chosen, n)) or table.get((None, n)) for n in numbers]
    if all(r is not None for r in rows):
        gm = np.array([r[1] for r in rows])
        if np.any(~(gm > 0)):
            k = int(np.argmax(~(gm > 0)))
            raise FEReadError(path, f"mode {numbers[k]} has generalized mass {gm[k]!r} in the eigenvalue table; it "
                              f"must be positive")
        other = np.flatnonzero(np.abs(gm - 1.0) > 1e-4)
        if other.size:
            shapes = shapes / np.sqrt(gm)[:, None, None]
            history.append("normalised to unit modal mass (phi / sqrt(m), the eigenvalue table's generalized mass): "
                           + ", ".join(f"mode {numbers[k]} m={gm[k]:g}" for k in other[:20])
                           + (" ..." if other.size > 20 else ""))
    else:
        missing = [n for n, r in zip(numbers, rows) if r is None]
        log.info("%s: no eigenvalue-table row for mode(s) %s: their shapes are taken as mass-normalised", path,
                 missing[:10])
        history.append(f"no generalized mass printed for mode(s) {missing[:10]}: taken as mass-normalised "
                       f"(NORM=MASS, Nastran's default)")
    fe = FEModes(node_ids=ref_ids, xyz=np.full((ref_ids.size, 3), np.nan), elements=(),
                 freqs_hz=frequencies(path, modes), shapes=shapes,
                 modal_mass=np.ones(len(modes)), source=str(path), format="nastran-f06",
                 units="SI (m, kg, s) assumed (a print file does not state units)", history=tuple(history),
                 mode_numbers=np.asarray(numbers, np.int64))
    cards = _echo(lines) if echo else None
    if cards is None:
        return fe
    from .nastran_bulk import bulk_geometry
    from .registry import merge_geometry

    if not any(c[:8].strip().rstrip("*").upper() == "GRID" for c in cards if c):
        log.info("%s: the bulk data echo has no GRID card; the geometry must come from a companion deck", path)
        return fe
    try:
        geometry = bulk_geometry(path, cards)
    except FEReadError as exc:
        log.warning("%s: the bulk data echo does not give the geometry (%s); give the deck (--geometry) or put it "
                    "beside the print file", path, exc)
        return fe
    absent = sorted(set(ref_ids.tolist()) - set(geometry.node_ids.tolist()))
    if absent:
        log.warning("%s: the bulk data echo lacks %d grid(s) of the eigenvectors (first %s): its geometry is not "
                    "used; give the deck (--geometry) or put it beside the print file", path, len(absent), absent[:5])
        return fe
    return merge_geometry(fe, geometry)


register_format("nastran-f06", patterns=("*.f06", "*.F06"), sniff=sniff_f06, reader=read_f06, geometry=None,
                aliases=("f06",), description="MSC/NX Nastran print file, real eigenvectors and eigenvalue table")
