"""Nastran punch (``.pch``) reader of real eigenvectors, SORT1.

No library reads these: pyNastran reads OP2 and F06 results and bulk data,
not punch result files, and pyuff is UFF only; so this module carries a small
fixed-column parser, limited to what a SOL 103 ``DISPLACEMENT(PUNCH)`` (or
``VECTOR(PUNCH)``) request writes.  Every line is an 80-column card image:
data in columns 1-72, a line counter in 73-80 (ignored)::

    $TITLE   = ...                      header cards ($TITLE, $SUBTITLE, $LABEL)
    $EIGENVECTOR                        result type
    $REAL OUTPUT                        real (not complex) values
    $SUBCASE ID =           1
    $EIGENVALUE =  3.9478418E+05  MODE =     1
          1001       G      2.873611E-02      4.655703E-22     -6.379952E-22
    -CONT-                  2.975262E-20     -5.830429E-19      2.450024E-17

Grid card: columns 1-10 point id, 18 point type, 19-36 / 37-54 / 55-72 T1,
T2, T3; continuation card: columns 1-6 ``-CONT-``, 19-36 / 37-54 / 55-72 R1,
R2, R3.  Grid points (type ``G``) give 6 DOF per node; scalar points (``S``)
are skipped with a logged note.  The eigenvalue is ``lambda = omega**2``
[(rad/s)**2], so ``f = sqrt(max(lambda, 0)) / (2 pi)`` (rigid-body modes
come out with tiny negative eigenvalues, hence 0 Hz).  Other result blocks
(``$DISPLACEMENTS``, ``$SPCF``, element output...) are skipped; complex
output is refused, and so is SORT2 output (eigenvectors sorted by point: a
``$POINT ID`` card per grid, then one card pair per mode) with the SORT1
request that replaces it.  Nastran punches eigenvectors in the displacement
coordinate system of each grid (CD); the bulk deck merged as geometry says
which (:mod:`fem_import.nastran_coords`), and :func:`fem_import.merge_geometry`
rotates them to the basic system.

A punch file has no geometry: node coordinates are NaN unless
``fem_import.read(path, geometry=...)`` merges them from a UFF file or an
:class:`~fem_import.modes.FEModes`.  Eigenvectors are taken as
mass-normalised (Nastran's default ``NORM=MASS`` of EIGRL); the file does
not say otherwise.
"""

from __future__ import annotations

import logging
import math
import re

import numpy as np

from .errors import FEReadError
from .modes import FEModes
from .nastran_modes import ParsedMode as _Mode, frequencies, grid_shapes, select_subcase
from .registry import register_format

__all__ = ["read_punch", "sniff_punch"]

log = logging.getLogger("fem_import")

# header cards that qualify the current result block without starting a new one
_MODIFIERS = ("TITLE", "SUBTITLE", "LABEL", "REAL OUTPUT", "REAL-IMAGINARY OUTPUT", "MAGNITUDE-PHASE OUTPUT",
              "SUBCASE ID", "EIGENVALUE", "ELEMENT TYPE", "FREQUENCY", "TIME", "POINT ID", "ELEMENT ID")
_SNIFF_KEYS = ("TITLE", "SUBTITLE", "LABEL", "EIGENVECTOR", "DISPLACEMENTS", "REAL OUTPUT", "SUBCASE ID",
               "EIGENVALUE")
_EIG = re.compile(r"\$EIGENVALUE\s*=\s*(\S+)\s+MODE\s*=\s*(\S+)", re.IGNORECASE)
_FIELDS = ((18, 36), (36, 54), (54, 72))


def sniff_punch(head: bytes) -> bool:
    """True if the first non-blank line is a punch header card (``$TITLE``, ``$EIGENVECTOR``...)."""
    text = head.decode("latin-1")
    for ln in text.splitlines():
        if not ln.strip():
            continue
        card = ln[:72].upper()
        return card.startswith("$") and any(card[1:].startswith(k) for k in _SNIFF_KEYS)
    return False


def _header_key(card: str) -> str:
    body = card[1:].upper()
    for key in _MODIFIERS:
        if body.startswith(key):
            return key
    return body.split("=")[0].strip()


def _value(path, line_no, card, field, what):
    lo, hi = _FIELDS[field]
    text = card[lo:hi].strip()
    if not text:
        raise FEReadError(path, f"{what} (columns {lo + 1}-{hi}) is blank: the card is truncated",
                          line=line_no)
    try:
        return float(text.replace("D", "E").replace("d", "e"))
    except ValueError:
        raise FEReadError(path, f"{what} (columns {lo + 1}-{hi}) is not a number: {text!r}",
                          line=line_no) from None


def _parse(path: str, lines: list[str], ends_with_newline: bool = True) -> list[_Mode]:
    modes: list[_Mode] = []
    block = None          # current result type
    real = True
    subcase = None
    current: _Mode | None = None
    pending = None        # line of the first header card not yet followed by data
    scalars = 0
    skipped: dict[str, int] = {}
    n = len(lines)
    i = 0
    while i < n:
        raw = lines[i]
        line_no = i + 1
        i += 1
        card = raw[:72].rstrip("\r\n")
        if not card.strip():
            continue
        if card.startswith("$"):
            if pending is None:
                pending = line_no
            key = _header_key(card)
            if key == "REAL OUTPUT":
                real = True
            elif key in ("REAL-IMAGINARY OUTPUT", "MAGNITUDE-PHASE OUTPUT"):
                real = False
            elif key == "SUBCASE ID":
                text = card.split("=", 1)[1].strip() if "=" in card else ""
                try:
                    subcase = int(text)
                except ValueError:
                    raise FEReadError(path, f"$SUBCASE ID is not an integer: {text!r}", line=line_no) from None
            elif key == "EIGENVALUE":
                m = _EIG.match(card.strip())
                if m is None:
                    raise FEReadError(path, "malformed $EIGENVALUE card; expected "
                                      "'$EIGENVALUE = <value>  MODE = <n>'", line=line_no)
                try:
                    lam = float(m.group(1).replace("D", "E"))
                    number = int(m.group(2))
                except ValueError:
                    raise FEReadError(path, f"$EIGENVALUE card has a bad value or mode number: "
                                      f"{m.group(1)!r}, {m.group(2)!r}", line=line_no) from None
                if not math.isfinite(lam):
                    raise FEReadError(path, f"mode {number} has a non-finite eigenvalue {lam!r}", line=line_no)
                if block == "EIGENVECTOR":
                    if not real:
                        raise FEReadError(path, "complex eigenvectors (REAL-IMAGINARY or MAGNITUDE-PHASE "
                                          "output) are not supported; expected $REAL OUTPUT", line=line_no)
                    current = _Mode(number, lam, subcase, line_no)
                    modes.append(current)
            elif key == "POINT ID" and block == "EIGENVECTOR":
                # SORT2 sorts by point: a '$POINT ID' card, then one card pair per mode, keyed by mode number
                raise FEReadError(path, "eigenvectors sorted by point (SORT2: a '$POINT ID =' card per grid) are "
                                  "not read; request SORT1 output in the case control (DISPLACEMENT(PUNCH,SORT1) = "
                                  "ALL) and run the export again", line=line_no)
            elif key in _MODIFIERS:
                pass
            else:
                block = key
                current = None
                if key == "EIGENVECTOR":
                    real = True
            continue

        # a data card
        pending = None
        if block != "EIGENVECTOR":
            skipped[block or "(no header)"] = skipped.get(block or "(no header)", 0) + 1
            continue
        if current is None:
            raise FEReadError(path, "eigenvector data before any $EIGENVALUE card", line=line_no)
        if card.startswith("-CONT-"):
            raise FEReadError(path, "continuation card without a preceding grid card", line=line_no)
        id_text = card[:10].strip()
        kind = card[17:18].upper() if len(card) > 17 else ""
        try:
            pid = int(id_text)
        except ValueError:
            raise FEReadError(path, f"point id (columns 1-10) is not an integer: {id_text!r}",
                              line=line_no) from None
        if pid <= 0:
            raise FEReadError(path, f"point id must be positive, got {pid}", line=line_no)
        has_cont = i < n and lines[i].startswith("-CONT-")
        if kind == "S":
            scalars += 1
            if has_cont:
                i += 1
            continue
        if kind != "G":
            raise FEReadError(path, f"point {pid}: point type (column 18) {kind!r}; expected 'G' (grid) or "
                              f"'S' (scalar)", line=line_no)
        if not has_cont:
            what = "the file ends" if i >= n else "the next card is not '-CONT-'"
            raise FEReadError(path, f"grid {pid} of mode {current.number}: {what}; expected the '-CONT-' card "
                              f"with R1, R2, R3 (truncated file?)", line=line_no)
        cont = lines[i][:72].rstrip("\r\n")
        i += 1
        if i == n and not ends_with_newline and len(cont.rstrip()) < 72:
            raise FEReadError(path, f"grid {pid} of mode {current.number}: the last card stops at column "
                              f"{len(cont.rstrip())} without an end of line; the file is truncated", line=i)
        t = [_value(path, line_no, card, f, f"grid {pid} T{f + 1}") for f in range(3)]
        r = [_value(path, line_no + 1, cont, f, f"grid {pid} R{f + 1}") for f in range(3)]
        current.ids.append(pid)
        current.vals.append((*t, *r))
    if pending is not None and modes:
        raise FEReadError(path, "the file ends with header cards and no data after them: truncated?",
                          line=pending)
    if scalars:
        log.info("%s: %d scalar-point (S) eigenvector entries skipped", path, scalars)
    if skipped:
        log.info("%s: data cards of other result blocks skipped: %s", path,
                 ", ".join(f"{k} x{v}" for k, v in skipped.items()))
    return modes


def read_punch(path: str, *, subcase: int | str | None = None) -> FEModes:
    """Read real eigenvectors from a Nastran punch file (SORT1).

    Parameters
    ----------
    path : str
        The file.
    subcase : int, "lowest" or None, optional
        Subcase to read when the file holds eigenvectors of several. None
        (default) requires a single subcase (several are refused, naming
        them); ``"lowest"`` reads the lowest subcase id and logs a WARNING
        naming the others (what :func:`fem_import.read_with_geometry`, and so
        the command line, does).

    Returns
    -------
    FEModes
        Modes in file order, 6 DOF per grid in the grid order of the first
        mode, frequencies ``sqrt(max(lambda, 0)) / 2 pi`` [Hz], modal mass 1
        (mass-normalised, Nastran's default), the file's ``MODE`` numbers as
        :attr:`~fem_import.modes.FEModes.mode_numbers`; node coordinates NaN
        and no elements (merge them with ``read(..., geometry=...)``).

    Raises
    ------
    FEReadError
        If the file has no real eigenvectors, several subcases and no
        ``subcase``, a truncated or malformed card (names the line), a mode
        whose grid set differs from the first mode's (names mode and grid),
        a repeated grid, a mode number given twice in the subcase read (names
        both lines), or a non-finite value (names mode and grid).
    """
    with open(path, encoding="latin-1", newline=None) as fh:
        text = fh.read()
    lines = text.split("\n")
    ends_with_newline = text.endswith("\n")
    if ends_with_newline:
        lines.pop()
    modes = _parse(path, lines, ends_with_newline)
    if not modes:
        raise FEReadError(path, "no real eigenvectors found (expected '$EIGENVECTOR', '$REAL OUTPUT' and "
                          "'$EIGENVALUE' header cards followed by grid cards)")
    modes = select_subcase(path, modes, subcase, "punch file")

    # Two punch runs concatenated (or a block pasted twice) give MODE 1, 2, 3, 1, 2, 3 in one subcase: read in
    # file order they would be six modes, three of them spurious, and pairing would take them as real.
    given: dict[int, int] = {}
    for m in modes:
        if m.number in given:
            raise FEReadError(path, f"MODE {m.number} already given at line {given[m.number]} (subcase "
                              f"{m.subcase if m.subcase is not None else 'not given'}); a mode number may appear "
                              f"once per subcase: are two punch files concatenated?", line=m.line)
        given[m.number] = m.line
    ref_ids, shapes = grid_shapes(path, modes)
    freqs = frequencies(path, modes)
    numbers = [m.number for m in modes]
    history = (f"read {len(modes)} modes (MODE {numbers[0]}..{numbers[-1]}, subcase {modes[0].subcase}) on "
               f"{ref_ids.size} grids from Nastran punch {path}; no geometry in the file",)
    return FEModes(node_ids=ref_ids, xyz=np.full((ref_ids.size, 3), np.nan), elements=(), freqs_hz=freqs,
                   shapes=shapes, modal_mass=np.ones(len(modes)), source=str(path), format="nastran-punch",
                   units="SI (m, kg, s) assumed (a punch file does not state units)", history=history,
                   mode_numbers=np.asarray(numbers, np.int64))


register_format("nastran-punch", patterns=("*.pch", "*.punch"), sniff=sniff_punch, reader=read_punch,
                geometry=None, aliases=("pch", "punch", "nastran"),
                description="MSC/NX Nastran punch file, real eigenvectors, SORT1")
