"""Nodes and elements from a Nastran bulk data file: the geometry a punch file lacks.

A Nastran punch file (:mod:`fem_import.punch`) carries eigenvectors but no
coordinates or connectivity; the model's input deck (``.bdf``, ``.dat``,
``.nas``, ``.blk``) has them. This module reads the grid points (GRID) and
the connectivity of the element cards, in the three field formats of the
Nastran Quick Reference Guide (bulk data entry format):

* small field: 8-column fields, ``GRID    ID      CP      X1      X2      X3      CD``
  (name in columns 1-8, eight data fields in 9-72, the continuation field
  in 73-80);
* large field: a name ending in ``*`` and 16-column fields, four data
  fields per line, continued on a line starting with ``*``;
* free field: comma-separated, ``GRID,ID,CP,X1,X2,X3,CD``, continued on a
  line starting with ``+``, ``*`` or ``,``.

A continuation line starts with ``+`` or ``*``, or has a blank name field
(columns 1-8); it adds its data fields to the entry above it (continuations
are taken in file order: the entry's continuation field is not matched).
Comments (``$`` to the end of the line) and blank lines are skipped; tabs in
fixed-field lines are expanded to 8 columns. Replicated entries, as hand-written
decks generate grids and elements, are expanded (Quick Reference Guide, bulk
data replication): field 1 ``=`` repeats the entry above with ``=`` fields
copied, ``==`` copying all trailing fields (continuations included) and
``*x`` / ``*(x)`` fields incremented by ``x``; ``=n`` / ``=(n)`` generates
``n`` more images with the same increments.

Elements are returned as :class:`~fem_import.modes.Element` with the
UFF 2412 FE descriptor of the same element kind, so that an FE read as a
Nastran punch + bulk deck and the same FE read as UFF 2411/2412 have the
same mesh:

==========================  =====================================================
Nastran card                FE descriptor (UFF 2412), nodes
==========================  =====================================================
CBAR, CBEAM                 21 linear beam: GA, GB
CROD, CONROD, CTUBE         11 rod: G1, G2 (axial and torsion only)
CQUAD4, CQUADR              94 linear quadrilateral: G1-G4
CQUAD8                      95 parabolic quadrilateral (94 without mid-side grids)
CTRIA3, CTRIAR              91 linear triangle: G1-G3
CTRIA6                      92 parabolic triangle (91 without mid-side grids)
CTETRA                      111 linear tetrahedron (4 grids), 118 parabolic (10)
CPENTA                      112 linear wedge (6 grids), 113 parabolic (15)
CHEXA                       115 linear brick (8 grids), 116 parabolic (20)
CONM2, CONM1                161 lumped mass: G
CELAS1, CELAS2              136 / 137 translational / rotational spring (by the
                            component C1: 1-3 / 4-6): G1, G2; grounded (G2 blank
                            or 0): 138 / 139, one node
CBUSH                       136 spring (a bushing couples all six DOFs; the
                            UFF has no bushing): GA, GB; grounded: 138
RBAR                        121 rigid bar: GA, GB
RBE2                        122 rigid element: GN (independent), then GM1, ...
RBE3                        181 constraint: REFGRID, then every G(i,j)
==========================  =====================================================

RBE3 is an interpolation element: the reference grid moves with a weighted
average of the others, which it does *not* stiffen. Reading it as the rigid
element 122 would tell later code that its grids move as one rigid body; the
UFF's 181 "constraint" (a multipoint constraint, which an RBE3 is) keeps the
connectivity without that claim. Parabolic shells are put in the UFF's node
order (corners and mid-sides going round the boundary); solids keep
Nastran's order (corners first, then mid-sides), which only their
connectivity, not a drawing, uses. A blank property id takes the element id
(Nastran's default). A spring (CELAS1, CELAS2) on a scalar point (an id that no
GRID defines) has no place in the mesh and is skipped (logged); any other
element on an undefined grid is refused, unless the deck has INCLUDE
statements whose files are not found (a warning names them), whose grids
may be the missing ones: those elements are dropped with a warning. INCLUDE
files that are found are read where the statement stands
(:mod:`fem_import.nastran_include`); messages name their lines as
``line 12 of mesh.bdf``.

Other cards (properties, materials, loads, parameters,
scalar elements...) are skipped with one INFO log per card type and count.
Real numbers may use Nastran's exponent shorthand (``7.85-3`` = 7.85e-3,
``1.+4``) and Fortran ``D`` exponents. Coordinate systems (CORD2R/C/S, CORD1R/C/S,
:mod:`fem_import.nastran_coords`) place grids given in a ``CP`` system and
give each grid with a ``CD`` system (its own, or GRDSET's where its field
is blank) the rotation of its displacement
components to basic (the punch's eigenvectors of that grid are in it;
:func:`fem_import.merge_geometry` rotates them). A system left undefined
is refused, naming the grid and line. Lines before ``BEGIN BULK`` (executive
and case control) are skipped when the file has that line; reading stops at
``ENDDATA``. Units are taken as SI, like the punch file's: a bulk data file
does not state them.

pyNastran reads bulk data completely, but its current release pins
``numpy < 2`` (this project runs on numpy 2), so the grid and element
entries are parsed here.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Callable
from pathlib import PurePath

import numpy as np

from .errors import FEReadError
from .modes import Element, FEModes
from .nastran_coords import resolve
from .nastran_include import expand_includes
from .registry import Geometry, register_format

__all__ = ["read_bulk_geometry", "bulk_geometry", "sniff_bulk", "parse_nastran_real", "BULK_SUFFIXES",
           "CARD_DESCRIPTORS", "element_from_fields"]

log = logging.getLogger("fem_import")

#: File-name endings of Nastran input decks: for these a GRID card anywhere in the sniffed bytes is enough.
BULK_SUFFIXES = (".bdf", ".dat", ".nas", ".blk", ".bulk")

_SHORT_EXP = re.compile(r"^([+-]?(?:\d+\.?\d*|\.\d+))([+-]\d+)$")
# words that start an executive-control, case-control or bulk data line of a Nastran input deck
_DECK_WORDS = (
    # executive control (and the statements before it: NASTRAN, ASSIGN, INIT, INCLUDE)
    "NASTRAN", "ASSIGN", "INIT", "INCLUDE", "ID", "TIME", "SOL", "CEND", "DIAG", "COMPILE", "ALTER", "APP",
    "GEOMCHECK", "RESTART", "ECHOON", "ECHOOFF", "LINK", "MALTER", "DOMAINSOLVER", "EXPAND", "ACQUIRE",
    # case control
    "TITLE", "SUBTITLE", "LABEL", "ECHO", "SUBCASE", "METHOD", "SPC", "MPC", "LOAD", "DISPLACEMENT", "DISP",
    "VECTOR", "SET", "OUTPUT", "RESVEC", "BEGIN",
    # bulk data
    "GRID", "PARAM", "CORD1R", "CORD1C", "CORD1S", "CORD2R", "CORD2C", "CORD2S", "MAT1", "MAT2", "MAT8", "MAT9",
    "PSHELL", "PCOMP", "PSOLID", "PBAR", "PBARL", "PBEAM", "PBEAML", "PROD", "PBUSH", "PELAS", "PMASS", "EIGRL",
    "EIGR", "SPC1", "SPCADD", "MPCADD", "ENDDATA", "CBAR", "CBEAM", "CROD", "CONROD", "CTUBE", "CQUAD4", "CQUAD8",
    "CQUADR", "CTRIA3", "CTRIA6", "CTRIAR", "CTETRA", "CPENTA", "CHEXA", "CPYRAM", "CONM1", "CONM2", "CELAS1",
    "CELAS2", "CBUSH", "RBAR", "RBE1", "RBE2", "RBE3", "SPOINT", "DMIG",
)
_DECK_LINE = r"^(?:" + "|".join(sorted(_DECK_WORDS, key=len, reverse=True)) + r")\*?(?=$|[\s,=(*])"
_BEGIN_BULK = re.compile(r"^\s*BEGIN\s+BULK\b", re.IGNORECASE)
_BEGIN_SUPER = re.compile(r"^\s*BEGIN\s+(?:BULK\s+)?SUPER\b", re.IGNORECASE)
_GRID_CARD = re.compile(rb"^(?:GRID\*?|BEGIN\s+BULK)(?=$|[\s,*])", re.IGNORECASE | re.MULTILINE)


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


def sniff_bulk(head: bytes, name: str = "") -> bool:
    """True if ``head`` looks like a Nastran input deck (executive control, case control or bulk data).

    The first line that is not a comment (``$``) or blank must start with a
    word of a Nastran deck (``NASTRAN``, ``ASSIGN``, ``SOL``, ``CEND``,
    ``TITLE``, ``BEGIN BULK``, ``PARAM``, ``CORD2R``, ``INCLUDE``, ``GRID``,
    an element card...). For a file named like a deck (:data:`BULK_SUFFIXES`)
    a ``GRID`` card or a ``BEGIN BULK`` line anywhere in ``head`` is enough
    (a deck may start with statements of a pre-processor this list lacks),
    and the words are recognised in lower case too; for other names they
    must be upper case (so that a table starting ``time,...`` is no deck).
    """
    text = head.decode("latin-1")
    deck_name = PurePath(name).suffix.lower() in BULK_SUFFIXES
    first = None
    for ln in text.splitlines():
        s = ln.strip()
        if not s or s.startswith("$"):
            continue
        first = s
        break
    if first is not None and re.match(_DECK_LINE, first, re.IGNORECASE if deck_name else 0):
        return True
    return deck_name and _GRID_CARD.search(head) is not None


# --------------------------------------------------------------------------
# entries: cards with their continuation lines, as lists of data fields
# --------------------------------------------------------------------------
def _body(raw: str) -> str:
    """A line without its comment (``$`` to the end), tabs expanded in fixed-field lines, right-stripped."""
    body = raw.split("$", 1)[0].rstrip("\r\n")
    if "\t" in body and "," not in body:
        body = body.expandtabs(8)
    return body.rstrip()


def _is_continuation(body: str) -> bool:
    return body[:1] in ("+", "*", ",") or (body[:8].strip() == "" and body.strip() != "")


def _free_fields(parts: list[str], per_line: int) -> list[str]:
    """Data fields of one free-field line (``parts[0]`` is the name or continuation mark).

    Field 10 (``parts[per_line + 1]`` for small field) is the continuation
    field when it is blank or starts with ``+``/``*``; a longer line's other
    fields are data (some pre-processors write all fields of an entry on one line).
    """
    data = parts[1:]
    if len(data) > per_line:
        cont = data[per_line].strip()
        if not cont or cont[0] in "+*":
            data = data[:per_line] + data[per_line + 1:]
    data += [""] * (per_line - len(data))  # fields not written are blank; a continuation starts after them
    return [d.strip() for d in data]


def _line_fields(body: str, large: bool) -> list[str]:
    """The data fields of one line of an entry (the name or continuation field left out)."""
    if "," in body:
        parts = body.split(",")
        return _free_fields(parts, 4 if large else 8)
    body = body[:72]
    if large:
        return [body[k:k + 16].strip() for k in range(8, 72, 16)]
    return [body[k:k + 8].strip() for k in range(8, 72, 8)]


_REPEAT = re.compile(r"^=\(?(\d+)\)?$")      # =n or =(n) in field 1: n more images
_INCREMENT = re.compile(r"^\*\(?([^()]+)\)?$")  # *x or *(x) in a data field of a replicated entry


def _is_int_text(t: str) -> bool:
    return re.fullmatch(r"[+-]?\d+", t.strip()) is not None


def _incremented(path: str, line: int, k: int, before: str, token: str) -> str:
    """Field ``k`` of the preceding entry, ``before``, incremented by the ``*x`` of ``token``."""
    step = _INCREMENT.match(token).group(1).strip()
    if not before.strip():  # a blank field has a default, not a value to add to
        raise FEReadError(path, f"replicated entry: {_field(k)} increments a blank field of the entry above by "
                          f"{token!r}", line=line)
    if _is_int_text(before) and _is_int_text(step):
        return str(int(before) + int(step))
    try:
        return repr(parse_nastran_real(before) + parse_nastran_real(step))
    except ValueError:
        raise FEReadError(path, f"replicated entry: {_field(k)} increments {before.strip()!r} "
                          f"of the entry above by {token!r}: both must be numbers", line=line) from None


def _replicated(path: str, line: int, before: list[str], tokens: list[str]) -> list[str]:
    """The data fields of a replicated entry: ``tokens`` applied to the preceding entry's fields ``before``.

    Nastran Quick Reference Guide, bulk data replication: ``=`` copies the
    field of the preceding entry, ``==`` copies all its trailing fields
    (continuations included), ``*x`` or ``*(x)`` adds ``x`` to it (integer to
    integer, real otherwise); a blank field stays blank and any other text is
    a value of its own.
    """
    out: list[str] = []
    for k, t in enumerate(tokens):
        t = t.strip()
        if t == "==":
            return out + before[k:]
        if t == "=":
            out.append(before[k] if k < len(before) else "")
        elif _INCREMENT.match(t):
            out.append(_incremented(path, line, k, before[k] if k < len(before) else "", t))
        else:
            out.append(t)
    return out


def _entries(path: str, lines: list[str], start: int, where=None):
    """``(name, data fields, 1-based line, number of lines)`` of every bulk entry from line ``start`` on.

    Replicated entries (field 1 ``=``, with ``=``, ``==`` and ``*x`` fields)
    are expanded against the entry above them, and ``=n`` / ``=(n)`` yields
    ``n`` more images with the same replication (:func:`_replicated`); each
    image reports the line of the statement that made it. ``where`` gives
    per line the number to report (:class:`~fem_import.nastran_include.DeckLine`
    of a deck with its INCLUDE files spliced in); default: its 1-based index.
    """
    n = len(lines)
    i = start
    previous: tuple[str, list[str]] | None = None  # the entry above (name, fields), after expansion
    pattern: list[str] | None = None              # the replication fields that made it, for =n
    while i < n:
        body = _body(lines[i])
        if not body.strip():
            i += 1
            continue
        line_no = i + 1 if where is None else where[i]
        i += 1
        if _is_continuation(body):
            yield "", [], line_no, 1  # a continuation without its entry (reported by the caller)
            continue
        head = body.split(",", 1)[0] if "," in body else body[:8]
        name = head.strip().upper()
        large = name.endswith("*")
        name = name.rstrip("*").strip()
        fields = _line_fields(body, large)
        count = 1
        while i < n:
            nxt = _body(lines[i])
            if not nxt.strip():
                i += 1
                continue
            if not _is_continuation(nxt):
                break
            fields += _line_fields(nxt, nxt[:1] == "*")
            count += 1
            i += 1
        repeat = _REPEAT.match(name)
        if name == "=" or repeat:
            if previous is None or (repeat and pattern is None):
                what = "=n (repeat the replication above)" if repeat else "a replicated entry (=)"
                raise FEReadError(path, f"{what} without {'a replicated' if repeat else 'an'} entry above it",
                                  line=line_no)
            if name == "=":
                pattern = fields
                images = 1
            else:
                images = int(repeat.group(1))
            for _ in range(images):
                previous = (previous[0], _replicated(path, line_no, previous[1], pattern))
                yield previous[0], previous[1], line_no, count
            continue
        previous, pattern = (name, fields), None
        yield name, fields, line_no, count
        if name == "ENDDATA":
            return


# --------------------------------------------------------------------------
# element cards
# --------------------------------------------------------------------------
def _field(k: int) -> str:
    """Nastran's name of data field ``k`` (0-based) of an entry: fields 2-9 of the first line, then of each
    continuation (in small-field terms)."""
    return f"field {k % 8 + 2}" + (f" of continuation {k // 8}" if k >= 8 else "")


class _Card:
    """Field access with messages naming the file, card, element and line."""

    def __init__(self, path: str, name: str, fields: list[str], line: int):
        self.path, self.name, self.fields, self.line = path, name, fields, line
        self.eid: int | None = None

    def text(self, k: int) -> str:
        return self.fields[k].strip() if k < len(self.fields) else ""

    def integer(self, k: int, what: str, *, required: bool = True) -> int | None:
        t = self.text(k)
        if not t:
            if required:
                raise FEReadError(self.path, f"{self._who()}: {what} ({_field(k)}) is blank", line=self.line)
            return None
        try:
            return int(t)
        except ValueError:
            raise FEReadError(self.path, f"{self._who()}: {what} ({_field(k)}) {t!r} is not an integer",
                              line=self.line) from None

    def grids(self, ks, what: str = "grid") -> list[int]:
        """The non-blank grid ids in fields ``ks``."""
        out = []
        for k in ks:
            g = self.integer(k, f"{what} {len(out) + 1}", required=False)
            if g is not None:
                out.append(g)
        return out

    def _who(self) -> str:
        return f"{self.name} {self.eid}" if self.eid is not None else self.name


def _eid_pid(card: _Card, *, has_pid: bool = True) -> tuple[int, int]:
    card.eid = card.integer(0, "element id")
    if not has_pid:
        return card.eid, 0
    pid = card.integer(1, "property id", required=False)
    return card.eid, card.eid if pid is None else pid  # Nastran: a blank PID is the EID


def _two_node(desc: int) -> Callable:
    def build(card):
        eid, pid = _eid_pid(card)
        return desc, (card.integer(2, "grid A"), card.integer(3, "grid B")), pid
    return build


def _conrod(card):
    eid, _ = _eid_pid(card, has_pid=False)
    return 11, (card.integer(1, "grid 1"), card.integer(2, "grid 2")), 0


def _shell(linear: int, parabolic: int, corners: int) -> Callable:
    def build(card):
        eid, pid = _eid_pid(card)
        corner = [card.integer(2 + k, f"grid {k + 1}") for k in range(corners)]
        mids = card.grids(range(2 + corners, 2 + 2 * corners), "mid-side grid")
        if not mids:
            return linear, tuple(corner), pid
        if len(mids) == corners:  # the UFF's order: corner, mid-side, corner, mid-side, ...
            return parabolic, tuple(g for pair in zip(corner, mids) for g in pair), pid
        return parabolic, tuple(corner + mids), pid
    return build


def _solid(kinds: dict[int, int]) -> Callable:
    corners = min(kinds)
    most = max(kinds)

    def build(card):
        eid, pid = _eid_pid(card)
        grids = [card.integer(2 + k, f"grid {k + 1}") for k in range(corners)]
        grids += card.grids(range(2 + corners, 2 + most), "mid-side grid")
        desc = kinds.get(len(grids), kinds[most])
        return desc, tuple(grids), pid
    return build


def _conm(card):
    eid, _ = _eid_pid(card, has_pid=False)
    return 161, (card.integer(1, "grid"),), 0


def _spring(card, k_grid1: int, pid: int):
    g1 = card.integer(k_grid1, "grid 1", required=False)
    c1 = card.integer(k_grid1 + 1, "component 1", required=False) or 0
    g2 = card.integer(k_grid1 + 2, "grid 2", required=False)
    c2 = card.integer(k_grid1 + 3, "component 2", required=False) or 0
    nodes = tuple(dict.fromkeys(g for g in (g1, g2) if g))  # a spring between two DOFs of one grid has one node
    if not nodes:
        raise FEReadError(card.path, f"{card._who()}: no grid ({_field(k_grid1)} and {_field(k_grid1 + 2)} "
                          f"blank)", line=card.line)
    rotational = (c1 or c2) >= 4
    grounded = not (g1 and g2)
    return (139 if rotational else 138) if grounded else (137 if rotational else 136), nodes, pid


def _celas1(card):
    eid, pid = _eid_pid(card)
    return _spring(card, 2, pid)


def _celas2(card):
    eid, _ = _eid_pid(card, has_pid=False)  # field 3 is the stiffness K
    return _spring(card, 2, 0)


def _cbush(card):
    eid, pid = _eid_pid(card)
    ga = card.integer(2, "grid A")
    gb = card.integer(3, "grid B", required=False)
    return (136, (ga, gb), pid) if gb else (138, (ga,), pid)


def _rbar(card):
    card.eid = card.integer(0, "element id")
    return 121, (card.integer(1, "grid A"), card.integer(2, "grid B")), 0


def _id_list(card: _Card, tokens: list[tuple[int, str]], what: str) -> list[int]:
    """Integer ids of ``(field index, text)`` tokens, expanding ``a THRU b``."""
    out: list[int] = []
    k = 0
    while k < len(tokens):
        idx, t = tokens[k]
        if t.upper() == "THRU" and out and k + 1 < len(tokens):
            hi = card.integer(tokens[k + 1][0], what)
            out.extend(range(out[-1] + 1, hi + 1))
            k += 2
            continue
        out.append(card.integer(idx, what))
        k += 1
    return out


def _is_real_text(t: str) -> bool:
    return any(c in t.upper() for c in ".E")


def _rbe2(card):
    card.eid = card.integer(0, "element id")
    gn = card.integer(1, "independent grid GN")
    card.integer(2, "component CM", required=False)
    tokens = []
    for k in range(3, len(card.fields)):
        t = card.text(k)
        if not t:
            continue
        if _is_real_text(t):  # ALPHA (thermal expansion) and TREF end the grid list
            break
        tokens.append((k, t))
    gm = _id_list(card, tokens, "dependent grid")
    if not gm:
        raise FEReadError(card.path, f"RBE2 {card.eid}: no dependent grid GM", line=card.line)
    return 122, (gn, *gm), 0


def _rbe3(card):
    card.eid = card.integer(0, "element id")
    ref = card.integer(2, "reference grid REFGRID")
    grids: list[int] = []
    state = "weight"   # weight -> component -> grids ... | UM pairs | a keyword's value
    tokens: list[tuple[int, str]] = []
    k = 4
    while k < len(card.fields):
        t = card.text(k)
        k += 1
        if not t:
            continue
        u = t.upper()
        if u in ("ALPHA", "TREF"):
            grids += _id_list(card, tokens, "grid")
            tokens = []
            k += 1  # its value
            state = "done"
            continue
        if u == "UM":
            grids += _id_list(card, tokens, "grid")
            tokens = []
            state = "um-grid"
            continue
        if state == "um-grid":  # UM: pairs GMi CMi; the GMi are grids of the element already (else added)
            gm = card.integer(k - 1, "UM grid")
            if gm != ref and gm not in grids:
                grids.append(gm)
            state = "um-comp"
            continue
        if state == "um-comp":
            state = "um-grid"
            continue
        if state == "done":
            continue
        if _is_real_text(u):  # a weight WTi: the next field is its component, then grids
            grids += _id_list(card, tokens, "grid")
            tokens = []
            state = "component"
            continue
        if state == "component":
            state = "grids"
            continue
        if state == "grids":
            tokens.append((k - 1, t))
            continue
        raise FEReadError(card.path, f"RBE3 {card.eid}: {_field(k - 1)} {t!r} where a weight (a real number) "
                          f"is expected", line=card.line)
    grids += _id_list(card, tokens, "grid")
    if not grids:
        raise FEReadError(card.path, f"RBE3 {card.eid}: no independent grid (weight, component, grids)",
                          line=card.line)
    return 181, (ref, *grids), 0


#: Element cards read, and how: card name -> builder returning (FE descriptor, node ids, property id).
_BUILDERS: dict[str, Callable] = {
    "CBAR": _two_node(21), "CBEAM": _two_node(21),
    "CROD": _two_node(11), "CTUBE": _two_node(11), "CONROD": _conrod,
    "CQUAD4": _shell(94, 95, 4), "CQUADR": _shell(94, 95, 4), "CQUAD8": _shell(94, 95, 4),
    "CTRIA3": _shell(91, 92, 3), "CTRIAR": _shell(91, 92, 3), "CTRIA6": _shell(91, 92, 3),
    "CTETRA": _solid({4: 111, 10: 118}), "CPENTA": _solid({6: 112, 15: 113}), "CHEXA": _solid({8: 115, 20: 116}),
    "CONM2": _conm, "CONM1": _conm,
    "CELAS1": _celas1, "CELAS2": _celas2, "CBUSH": _cbush,
    "RBAR": _rbar, "RBE2": _rbe2, "RBE3": _rbe3,
}
# linear cards may not carry mid-side grids (CQUAD4 fields 7-8 are THETA/MCID, not grids)
_LINEAR_ONLY = {"CQUAD4": 4, "CQUADR": 4, "CTRIA3": 3, "CTRIAR": 3}
#: Nastran card -> FE descriptor(s) it is read as (see the module docstring).
CARD_DESCRIPTORS = {
    "CBAR": (21,), "CBEAM": (21,), "CROD": (11,), "CTUBE": (11,), "CONROD": (11,), "CQUAD4": (94,),
    "CQUADR": (94,), "CQUAD8": (95, 94), "CTRIA3": (91,), "CTRIAR": (91,), "CTRIA6": (92, 91),
    "CTETRA": (111, 118), "CPENTA": (112, 113), "CHEXA": (115, 116), "CONM2": (161,), "CONM1": (161,),
    "CELAS1": (136, 137, 138, 139), "CELAS2": (136, 137, 138, 139), "CBUSH": (136, 138), "RBAR": (121,),
    "RBE2": (122,), "RBE3": (181,),
}
# coordinate system cards not built (general curvilinear, moving rectangular): a grid in one is refused by name
_UNREAD_SYSTEMS = ("CORD3G", "CORD3R")
# rigid elements: Nastran's GEOM4 table, an id space apart from the elements
_RIGID = {"RBAR", "RBE2", "RBE3"}
_RIGID_DESCRIPTORS = {d for card in _RIGID for d in CARD_DESCRIPTORS[card]}
# cards whose "grids" may be scalar points (no GRID): skipped, not refused
_SCALAR_OK = {"CELAS1", "CELAS2"}


def element_from_fields(path: str, name: str, fields: list[str],
                        line: int | None) -> tuple[int, int, tuple[int, ...], int]:
    """``(element id, FE descriptor, node ids, property id)`` of an element entry ``name`` (a key of
    :data:`CARD_DESCRIPTORS`) from its fields after the name, as text in the card's field order (blank: absent).
    Shared with the readers of other Nastran files that hold the same entries (:mod:`fem_import.nastran_h5`,
    :mod:`fem_import.nastran_op2_geom`); ``line`` None for a file without lines."""
    card = _Card(path, name, fields, line)
    if name in _LINEAR_ONLY:
        card = _Card(path, name, fields[:2 + _LINEAR_ONLY[name]], line)
    desc, nodes, pid = _BUILDERS[name](card)
    return card.eid, desc, tuple(nodes), pid


def _grid(path: str, fields: list[str], line: int) -> tuple[int, int | None, tuple[float, float, float], int | None]:
    """``(id, CP, (X1, X2, X3) in CP, CD)`` of a GRID entry; a blank CP or CD is None (GRDSET's, else 0)."""
    f = fields + [""] * (6 - len(fields))
    try:
        gid = int(f[0].strip())
    except ValueError:
        raise FEReadError(path, f"GRID id {f[0].strip()!r} is not an integer", line=line) from None
    if gid <= 0 or gid >= 2**31:
        raise FEReadError(path, f"GRID id {gid} outside 1 .. 2^31-1", line=line)
    cs = []
    for what, text in (("CP", f[1]), ("CD", f[5])):
        t = text.strip()
        try:
            cs.append(int(t) if t else None)
        except ValueError:
            raise FEReadError(path, f"GRID {gid}: coordinate system {what} = {t!r} is not an integer",
                              line=line) from None
        if cs[-1] is not None and cs[-1] < 0:
            raise FEReadError(path, f"GRID {gid}: {what} = {cs[-1]} (a fluid or scalar grid has no place in a "
                                    f"structural wheelset model)", line=line)
    try:
        x = tuple(parse_nastran_real(v) for v in f[2:5])
    except ValueError:
        bad = next(v.strip() for v in f[2:5] if not _is_real(v))
        raise FEReadError(path, f"GRID {gid}: coordinate {bad!r} is not a number", line=line) from None
    if not all(np.isfinite(x)):
        raise FEReadError(path, f"GRID {gid}: non-finite coordinate {list(x)}", line=line)
    return gid, cs[0], x, cs[1]


def _grdset(path: str, fields: list[str], line: int) -> tuple[int, int, object]:
    """``(CP, CD, line)`` of the GRDSET entry: the defaults of blank GRID fields 3 (CP) and 7 (CD)."""
    card = _Card(path, "GRDSET", fields, line)
    cp = card.integer(1, "default CP", required=False) or 0
    cd = card.integer(5, "default CD", required=False) or 0
    if cp < 0 or cd < 0:
        raise FEReadError(path, f"GRDSET: CP = {cp}, CD = {cd}: a coordinate system id is not negative", line=line)
    return cp, cd, line


def _cord2(path: str, name: str, fields: list[str], line: int) -> tuple[int, tuple]:
    """``(CID, (kind, RID, A, B, C, line))`` of a CORD2R/C/S entry."""
    card = _Card(path, name, fields, line)
    cid = card.integer(0, "coordinate system id")
    rid = card.integer(1, "reference system RID", required=False) or 0
    if cid <= 0:
        raise FEReadError(path, f"{name}: coordinate system id must be positive, got {cid}", line=line)
    vals = []
    for k in range(2, 11):
        t = card.text(k)
        try:
            vals.append(parse_nastran_real(t))
        except ValueError:
            raise FEReadError(path, f"{name} {cid}: {_field(k)} {t!r} is not a number", line=line) from None
    if len(fields) <= 8:  # blank C fields are zeros, as Nastran reads them; a missing continuation is an error
        raise FEReadError(path, f"{name} {cid}: the continuation line with the point C (C1, C2, C3) is missing",
                          line=line)
    v = np.asarray(vals, float)
    return cid, (name[-1], rid, v[0:3], v[3:6], v[6:9], line)


def _cord1(path: str, name: str, fields: list[str], line: int) -> list[tuple[int, tuple]]:
    """``[(CID, (kind, (G1, G2, G3), line)), ...]`` of a CORD1R/C/S entry (one or two systems)."""
    card = _Card(path, name, fields, line)
    out = []
    for k0 in (0, 4):
        cid = card.integer(k0, "coordinate system id", required=(k0 == 0))
        if cid is None:
            continue
        gs = tuple(card.integer(k0 + j, f"grid G{j}") for j in (1, 2, 3))
        if len(set(gs)) < 3:
            raise FEReadError(path, f"{name} {cid}: its three grids must be distinct, got {list(gs)}", line=line)
        out.append((cid, (name[-1], gs, line)))
    return out


def read_bulk_geometry(path: str) -> Geometry:
    """Grid points (ID and basic coordinates) and element connectivity from a Nastran bulk data file.

    Returns
    -------
    Geometry
        Node ids in file order, basic coordinates [m] (SI assumed), the
        elements of the connectivity cards (module docstring) sorted by
        element id, with their UFF 2412 FE descriptors, and the grids'
        displacement frames when some grid has a ``CD`` system.

    Raises
    ------
    FEReadError
        No GRID entry, a field that is not a number, a repeated grid or
        element id (a rigid element that shares a structural element's id is
        renumbered instead, logged), a coordinate system undefined, defined twice or degenerate
        (names the grid or system), a large-field GRID* without its continuation, an element that
        lists a grid twice or uses a grid no GRID defines; names the line.
    """
    with open(path, encoding="latin-1") as fh:
        lines = fh.read().splitlines()
    begin = next((k for k, ln in enumerate(lines) if _BEGIN_BULK.match(ln)), None)
    if begin is None:  # a bulk-only (include) file; executive and case control alone end with CEND
        begin = next((k for k, ln in enumerate(lines) if ln.strip().upper() == "CEND"), -1)
    lines, where, _ = expand_includes(path, lines, begin + 1)
    return bulk_geometry(path, lines, begin + 1, where=where)


def bulk_geometry(path: str, lines: list[str], start: int = 0, *, where=None) -> Geometry:
    """:func:`read_bulk_geometry` of bulk entries given as card images (``lines[start:]``; blank lines are
    skipped, so a print file's echo can be passed at its own line numbers, the rest blanked). ``where``: the
    line numbers to report, per line (:func:`~fem_import.nastran_include.expand_includes`)."""
    ids: list[int] = []
    grids: dict[int, tuple] = {}  # id -> (CP, coordinates in CP, line)
    cds: dict[int, int] = {}  # id -> CD, where not basic
    cord2: dict[int, tuple] = {}
    cord1: dict[int, tuple] = {}
    seen: dict[int, int] = {}
    raw_elements: list[tuple[int, int, tuple[int, ...], int, str, int]] = []
    includes: list[str] = []
    blank_cd: list[int] = []  # grids whose CD field is blank: GRDSET's CD, else basic
    unread_systems: dict[int, tuple[str, int]] = {}  # cid -> (card, line) of systems this reader does not build
    grdset: tuple[int, int, int] | None = None
    skipped: dict[str, int] = {}
    orphans: list[int] = []
    for name, fields, line_no, count in _entries(path, lines, start, where):
        if not name:
            orphans.append(line_no)
            continue
        if name == "ENDDATA":
            break
        if name == "INCLUDE":
            includes.append(lines[line_no - 1].strip())
            continue
        if name == "SEBULK" or (name.startswith("BEGIN") and _BEGIN_SUPER.match(lines[line_no - 1])):
            statement = lines[line_no - 1].split("$", 1)[0].strip()
            raise FEReadError(path, f"a superelement deck ({statement}): each part or external superelement has "
                              f"grid and coordinate system ids of its own (and may be placed by SELOC), which this "
                              f"reader does not keep apart; give the deck of one model (no BEGIN SUPER or SEBULK)",
                              line=line_no)
        if name == "GRID":
            large = lines[line_no - 1].split(",", 1)[0].strip().endswith("*")
            if large and count < 2:
                raise FEReadError(path, "large-field GRID* entry without its '*' continuation line (X3, CD)",
                                  line=line_no)
            gid, cp, x, cd = _grid(path, fields, line_no)
            if gid in seen:
                raise FEReadError(path, f"GRID {gid} is defined twice (lines {seen[gid]} and {line_no})",
                                  line=line_no)
            seen[gid] = line_no
            ids.append(gid)
            grids[gid] = (cp, x, line_no)
            if cd is None:
                blank_cd.append(gid)
            elif cd:
                cds[gid] = cd
            continue
        if name == "GRDSET":
            if grdset is not None:
                raise FEReadError(path, f"GRDSET is given twice (lines {grdset[2]} and {line_no}); Nastran allows one",
                                  line=line_no)
            grdset = _grdset(path, fields, line_no)
            continue
        if name in _UNREAD_SYSTEMS:
            cid = _Card(path, name, fields, line_no).integer(0, "coordinate system id", required=False)
            if cid:
                unread_systems[cid] = (name, line_no)
            skipped[name] = skipped.get(name, 0) + 1
            continue
        if name in ("CORD2R", "CORD2C", "CORD2S", "CORD1R", "CORD1C", "CORD1S"):
            for cid, spec in ([_cord2(path, name, fields, line_no)] if name.startswith("CORD2")
                              else _cord1(path, name, fields, line_no)):
                table = cord2 if name.startswith("CORD2") else cord1
                if cid in cord2 or cid in cord1:
                    first = (cord2.get(cid) or cord1.get(cid))[-1]
                    raise FEReadError(path, f"coordinate system {cid} is defined twice (lines {first} and {line_no})",
                                      line=line_no)
                table[cid] = spec
            continue
        if name in _BUILDERS:
            eid, desc, nodes, pid = element_from_fields(path, name, fields, line_no)
            raw_elements.append((eid, desc, nodes, pid, name, line_no))
            continue
        skipped[name] = skipped.get(name, 0) + 1
    if includes:
        log.warning("%s: INCLUDE file(s) not found (%s), beside the deck or in the working directory; their grids "
                    "and elements are not read", path, "; ".join(includes[:3]))
    if orphans:
        log.warning("%s: %d continuation line(s) without an entry above them were skipped (first at line %s)",
                    path, len(orphans), orphans[0])
    for card, n in sorted(skipped.items()):
        log.info("%s: %d %s entr%s skipped (not grids or element connectivity)", path, n, card,
                 "y" if n == 1 else "ies")
    if not ids:
        raise FEReadError(path, "no GRID entry: the file carries no node coordinates")
    cp_default, cd_default = (grdset[0], grdset[1]) if grdset else (0, 0)
    for gid, (cp, x, line) in grids.items():
        if cp is None:
            grids[gid] = (cp_default, x, line)
    if cd_default:
        cds.update({gid: cd_default for gid in blank_cd})
    if grdset and (cp_default or cd_default):
        log.info("%s: GRDSET (line %s) gives the grids with a blank field CP = %d, CD = %d", path, grdset[2],
                 cp_default, cd_default)
    for gid in ids:
        for what, cid in (("CP", grids[gid][0]), ("CD", cds.get(gid))):
            if cid in unread_systems:
                card, where_cs = unread_systems[cid]
                raise FEReadError(path, f"GRID {gid}: its {what} system {cid} is a {card} (line {where_cs}), a "
                                  f"system this reader does not build (CORD1R/C/S and CORD2R/C/S are read)",
                                  line=seen[gid])
    elements = _check_elements(path, raw_elements, seen, bool(includes))
    try:
        systems, positions = resolve(path, cord2, cord1, grids)
    except FEReadError as exc:
        if not includes:
            raise
        raise FEReadError(path, f"{str(exc).split(': ', 1)[-1]} (the INCLUDE files not found may define it)",
                          line=exc.line) from None
    xyz = np.array([positions[g] for g in ids], float)
    frames = None
    if cds:
        undefined = sorted(g for g, cd in cds.items() if cd not in systems)
        if undefined:
            g = undefined[0]
            raise FEReadError(path, f"GRID {g}: its displacement system CD = {cds[g]} is defined by no CORD entry"
                              + (" (the INCLUDE files not found may define it)" if includes else ""), line=seen[g])
        frames = np.broadcast_to(np.eye(3), (len(ids), 3, 3)).copy()
        for k, g in enumerate(ids):
            if g in cds:
                frames[k] = systems[cds[g]].frame_at(xyz[k])
        log.info("%s: %d grid(s) give their displacements in local systems (CD %s): rotated to basic when the "
                 "modes are merged", path, len(cds), sorted(set(cds.values()))[:10])
    if len(systems) > 1:
        n_cp = sum(1 for cp, _, _ in grids.values() if cp)
        log.info("%s: %d coordinate system(s) resolved; %d grid position(s) converted to basic", path,
                 len(systems) - 1, n_cp)
    log.info("%s: %d grids and %d elements read", path, len(ids), len(elements))
    return Geometry(np.asarray(ids, np.int64), xyz, tuple(elements), str(path),
                    "SI (m, kg, s) assumed (a bulk data file does not state units)", frames)


def _check_elements(path, raw, grids: dict[int, int], has_includes: bool) -> list[Element]:
    """Validated elements: unique ids, positive distinct grids that GRID entries define.

    Rigid elements (RBAR, RBE2, RBE3) are kept by Nastran in a table of their
    own (GEOM4, not GEOM2), and NX Nastran runs decks whose rigid element
    shares its id with a structural element; the mesh needs one id per
    element, so such a rigid element is renumbered above the largest element
    id (logged with the numbers). Two structural or two rigid elements with
    one id are refused.
    """
    out: list[Element] = []
    where: dict[int, tuple[str, int]] = {}
    where_rigid: dict[int, tuple[str, int]] = {}
    scalar: dict[str, int] = {}
    dropped = []
    for eid, desc, nodes, pid, name, line in raw:
        if eid <= 0 or any(g <= 0 for g in nodes):
            raise FEReadError(path, f"{name} {eid}: element and grid ids must be positive, got element {eid}, "
                              f"grids {list(nodes)}", line=line)
        table = where_rigid if name in _RIGID else where
        if eid in table:
            first = table[eid]
            kind = "rigid element" if name in _RIGID else "element (masses and springs included)"
            raise FEReadError(path, f"element id {eid} is used twice ({first[0]} at line {first[1]}, {name} here); "
                              f"{kind} ids are unique in a Nastran model", line=line)
        table[eid] = (name, line)
        twice = sorted({g for g in nodes if nodes.count(g) > 1})
        if twice:
            raise FEReadError(path, f"{name} {eid} lists grid(s) {twice} more than once: an element's grids are "
                              f"distinct (Nastran refuses it too)", line=line)
        unknown = [g for g in nodes if g not in grids]
        if unknown:
            if name in _SCALAR_OK:
                scalar[name] = scalar.get(name, 0) + 1
                continue
            if has_includes:
                dropped.append((name, eid, unknown, line))
                continue
            raise FEReadError(path, f"{name} {eid} uses grid(s) {unknown[:10]} that no GRID entry defines",
                              line=line)
        out.append(Element(int(eid), int(desc), tuple(int(g) for g in nodes), int(pid)))
    out = _renumber_shared_rigid(path, out, where, where_rigid)
    for name, n in sorted(scalar.items()):
        log.info("%s: %d %s element(s) on scalar points (ids no GRID defines) skipped: they have no place in the "
                 "mesh", path, n, name)
    if dropped:
        name, eid, unknown, line = dropped[0]
        log.warning("%s: %d element(s) use grids no GRID entry of this file defines (first: %s %d at line %s, grids "
                    "%s), perhaps defined in the INCLUDE files; they are left out", path, len(dropped), name, eid,
                    line, unknown[:5])
    out.sort(key=lambda e: e.element_id)
    return out


def _renumber_shared_rigid(path, elements: list[Element], where: dict, where_rigid: dict) -> list[Element]:
    """``elements`` with each rigid element whose id a structural element also has given a fresh id."""
    shared = sorted(set(where) & set(where_rigid))
    if not shared:
        return elements
    top = max(max(where), max(where_rigid))
    new_id = {eid: top + k for k, eid in enumerate(shared, start=1)}
    out = [Element(new_id[e.element_id], e.fe_descriptor, e.nodes, e.physical_property)
           if e.element_id in new_id and e.fe_descriptor in _RIGID_DESCRIPTORS else e for e in elements]
    log.warning("%s: %d rigid element(s) share their id with a structural element (NX Nastran accepts it: rigid "
                "elements have their own table); in the mesh they are renumbered above the largest element id: %s",
                path, len(shared), ", ".join(f"{where_rigid[e][0]} {e} (line {where_rigid[e][1]}) -> {new_id[e]}"
                                             for e in shared[:5]) + (" ..." if len(shared) > 5 else ""))
    return out


def _is_real(text: str) -> bool:
    try:
        parse_nastran_real(text)
        return True
    except ValueError:
        return False


def _no_modes(path: str, **kwargs) -> FEModes:
    if PurePath(path).suffix.lower() in (".pch", ".punch"):  # EXTSEOUT and DMIG punches are bulk data entries
        raise FEReadError(path, "this punch file holds bulk data entries (DMIG matrices, superelement data), no "
                          "eigenvectors: a SOL 103 run punches them as '$EIGENVECTOR' blocks with DISPLACEMENT(PUNCH) "
                          "= ALL")
    raise FEReadError(path, "a Nastran bulk data file holds no mode shapes; use it as the geometry of a punch file "
                      "(fem_import.read(punch, geometry=this file) in Python, --geometry on the command line)")


register_format("nastran-bulk", patterns=("*.bdf", "*.dat", "*.nas", "*.blk", "*.bulk"), sniff=sniff_bulk,
                reader=_no_modes, geometry=read_bulk_geometry, aliases=("bdf", "bulk"),
                description="Nastran bulk data (GRID and element cards), geometry only")
