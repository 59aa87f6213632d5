"""Grids and elements of an OP2 file's GEOM tables: the geometry of a run whose input deck is not at hand.

``PARAM,POST,-1`` writes the model's tables to the OP2 (``GEOM1S``, ``GEOM2S``, ``GEOM4S``...). A record of a GEOM
table starts with three key words naming the entry type (MSC Nastran DMAP Programmer's Guide, GEOM2 and GEOM4),
followed by the entries of that type, each a fixed number of words for elements, or a list ended by ``-1`` (and
``-3``) for the rigid elements. The entries are turned into the bulk data fields of the same card and built by
:func:`fem_import.nastran_bulk.element_from_fields`, so an OP2 element and the deck's one come out the same
(FE descriptor, node order, property id).

Word counts differ between Nastran versions for some cards (shells carry more words in newer MSC releases; rigid
elements may end with a thermal expansion coefficient). Each record is therefore read with the layouts known for
its card and kept only with the one under which every entry has a positive element id and grids of the file's
grid table; a record that no layout fits is left out with a WARNING naming its card and size, as are cards of no
mesh meaning here (scalar points, plot elements, MPCs) at INFO. Checked on NX Nastran 9.1 and MSC Nastran 2020
files (pyYeti's tests): the bars of a 8221-bar model and the rigid elements RBE2 and RBE3 are the input deck's,
and a 32-bit and a 64-bit file of one model give the same CBEAM, CBUSH and CONM2 elements.

The grids of ``GEOM1`` (GRID: ``ID CP X1 X2 X3 CD PS SEID``; CORD2R/C/S: ``CID`` type, ``RID`` and the points A,
B, C) are the input's, in their ``CP`` systems: they are resolved as a deck's (:func:`fem_import.nastran_coords
.resolve`) when the file has no grid table (``BGPDT``), which holds them in basic. On the files at hand the two
agree to single precision, displacement systems included.
"""

from __future__ import annotations

import logging
from collections import Counter
from collections.abc import Callable

import numpy as np

from .errors import FEReadError
from .modes import Element
from .nastran_bulk import element_from_fields

__all__ = ["GEOM_TABLES", "FIXED_LAYOUTS", "op2_elements", "op2_grids"]

log = logging.getLogger("fem_import")

#: The data blocks read (the S suffix: the superelement-sorted tables PARAM,POST,-1 writes).
GEOM_TABLES = ("GEOM1S", "GEOM1", "GEOM2S", "GEOM2", "GEOM4S", "GEOM4")
_GRID = (4501, 45, 1)
_CORD2 = {(2101, 21, 8): "R", (2001, 20, 9): "C", (2201, 22, 10): "S"}
_END = (65535, 65535)  # key of a table's last record (its third word varies)


def _grids_at(positions: range | tuple[int, ...]) -> Callable[[np.ndarray, np.ndarray], list[str]]:
    """A layout's fields: element id, property id (words 0, 1) and the grids at ``positions``, blank where 0."""

    def fields(w: np.ndarray, f: np.ndarray) -> list[str]:
        return [str(w[0]), str(w[1])] + [str(w[k]) if w[k] else "" for k in positions]

    return fields


def _conrod(w, f):
    return [str(w[0]), str(w[1]), str(w[2])]


def _conm(w, f):
    return [str(w[0]), str(w[1])]


def _spring(w, f):  # CELAS1: EID PID G1 G2 C1 C2; CELAS2: EID K G1 G2 C1 C2 GE S -> EID PID|K G1 C1 G2 C2
    return [str(w[0]), str(w[1]), str(w[2]) if w[2] else "", str(w[4]), str(w[3]) if w[3] else "", str(w[5])]


#: Fixed-size entries: key -> (card, possible words per entry, fields builder, word indices that hold grids).
FIXED_LAYOUTS: dict[tuple[int, int, int], tuple[str, tuple[int, ...], Callable, tuple[int, ...]]] = {
    (2408, 24, 180): ("CBAR", (16,), _grids_at((2, 3)), (2, 3)),
    (5408, 54, 261): ("CBEAM", (18,), _grids_at((2, 3)), (2, 3)),
    (3001, 30, 48): ("CROD", (4,), _grids_at((2, 3)), (2, 3)),
    (3701, 37, 49): ("CTUBE", (4,), _grids_at((2, 3)), (2, 3)),
    (1601, 16, 47): ("CONROD", (8,), _conrod, (1, 2)),
    (2958, 51, 177): ("CQUAD4", (14, 17), _grids_at(range(2, 6)), (2, 3, 4, 5)),
    (8009, 80, 367): ("CQUADR", (14, 17), _grids_at(range(2, 6)), (2, 3, 4, 5)),
    (5959, 59, 282): ("CTRIA3", (13, 14, 16), _grids_at(range(2, 5)), (2, 3, 4)),
    (9200, 92, 385): ("CTRIAR", (13, 14, 16), _grids_at(range(2, 5)), (2, 3, 4)),
    (4701, 47, 326): ("CQUAD8", (17,), _grids_at(range(2, 10)), tuple(range(2, 10))),
    (4801, 48, 327): ("CTRIA6", (14,), _grids_at(range(2, 8)), tuple(range(2, 8))),
    (5508, 55, 217): ("CTETRA", (12,), _grids_at(range(2, 12)), tuple(range(2, 12))),
    (4108, 41, 280): ("CPENTA", (17,), _grids_at(range(2, 17)), tuple(range(2, 17))),
    (7308, 73, 253): ("CHEXA", (22,), _grids_at(range(2, 22)), tuple(range(2, 22))),
    (1501, 15, 64): ("CONM2", (13,), _conm, (1,)),
    (1401, 14, 63): ("CONM1", (24,), _conm, (1,)),
    (601, 6, 73): ("CELAS1", (6,), _spring, (2, 3)),
    (701, 7, 74): ("CELAS2", (8,), _spring, (2, 3)),
    (2608, 26, 60): ("CBUSH", (14,), _grids_at((2, 3)), (2, 3)),
    (6601, 66, 292): ("RBAR", (7, 8), lambda w, f: [str(w[0]), str(w[1]), str(w[2])], (1, 2)),
}
#: Records that carry nothing of the mesh (scalar points, plot elements, constraints), skipped at INFO.
_NOT_MESH = {(5551, 49, 105): "SPOINT", (5201, 52, 11): "PLOTEL", (4901, 49, 17): "MPC"}
_OPTIONAL_GRIDS = {"CELAS1", "CELAS2", "CBUSH", "CTETRA", "CPENTA", "CHEXA", "CQUAD8", "CTRIA6"}


def _fixed(card: str, sizes, build, grid_words, ints: np.ndarray, floats: np.ndarray, grids: set[int]):
    """``(fields per entry, words per entry)`` of the first layout under which the record is whole entries of
    positive ids on known grids, or None."""
    for size in sizes:
        if ints.size == 0 or ints.size % size:
            continue
        w = ints.reshape(-1, size)
        if np.any(w[:, 0] <= 0):
            continue
        g = w[:, list(grid_words)]
        known = np.isin(g, list(grids)) | ((g == 0) & (card in _OPTIONAL_GRIDS))
        if card in _OPTIONAL_GRIDS:
            known[:, 0] = np.isin(g[:, 0], list(grids))  # the first grid is never optional
        if not known.all():
            continue
        f = floats.reshape(-1, size)
        return [build(w[k], f[k]) for k in range(w.shape[0])], size
    return None


def _rbe2(ints: np.ndarray, floats: np.ndarray, grids: set[int], alpha: bool):
    """RBE2 entries ``EID GN CM GM... -1 [ALPHA]`` as bulk fields, or None if the record does not read so."""
    out, k, n = [], 0, ints.size
    while k < n:
        if k + 4 > n or ints[k] <= 0 or int(ints[k + 1]) not in grids:
            return None
        eid, gn, cm = (int(v) for v in ints[k:k + 3])
        k += 3
        gm = []
        while k < n and ints[k] != -1:
            if int(ints[k]) not in grids:
                return None
            gm.append(int(ints[k]))
            k += 1
        if k >= n or not gm:
            return None
        k += 1 + (1 if alpha else 0)
        if k > n:
            return None
        out.append([str(eid), str(gn), str(cm), *map(str, gm)])
    return out


def _rbe3(ints: np.ndarray, floats: np.ndarray, grids: set[int], alpha: bool):
    """RBE3 entries ``EID REFGRID REFC {WT C G... -1}... [-2 {GM CM}...] -3 [ALPHA]`` as bulk fields, or None."""
    out, k, n = [], 0, ints.size
    while k < n:
        if k + 4 > n or ints[k] <= 0 or int(ints[k + 1]) not in grids:
            return None
        fields = [str(int(ints[k])), "", str(int(ints[k + 1])), str(int(ints[k + 2]))]
        k += 3
        while k < n and ints[k] not in (-2, -3):
            fields += [repr(float(floats[k])), str(int(ints[k + 1])) if k + 1 < n else ""]
            k += 2
            while k < n and ints[k] != -1:
                if int(ints[k]) not in grids:
                    return None
                fields.append(str(int(ints[k])))
                k += 1
            k += 1
        if k < n and ints[k] == -2:
            fields.append("UM")
            k += 1
            while k < n and ints[k] != -3:
                fields.append(str(int(ints[k])))
                k += 1
        if k >= n or ints[k] != -3:
            return None
        k += 1 + (1 if alpha else 0)
        if k > n:
            return None
        out.append(fields)
    return out


_VARIABLE = {(6901, 69, 295): ("RBE2", _rbe2), (7101, 71, 187): ("RBE3", _rbe3)}


def op2_elements(path: str, records: list[tuple[str, bytes]], endian: str, word: int,
                 grid_ids) -> tuple[Element, ...]:
    """The elements of the GEOM2/GEOM4 ``records`` (``(table, record bytes)``, key words first) on ``grid_ids``.

    Returns
    -------
    tuple of Element
        Sorted by element id; empty if the tables hold none that this module reads (said in the log).
    """
    grids = {int(g) for g in np.asarray(grid_ids).tolist()}
    entries: list[tuple[str, list[str], str]] = []
    unread: Counter = Counter()
    unfit: list[str] = []
    for table, raw in records:
        if table.startswith("GEOM1"):
            continue
        ints = np.frombuffer(raw, dtype=f"{endian}i{word}")
        floats = np.frombuffer(raw, dtype=f"{endian}f{word}")
        if ints.size < 3:
            continue
        key = tuple(int(v) for v in ints[:3])
        if key[:2] == _END:
            continue
        body_i, body_f = ints[3:], floats[3:]
        if key in FIXED_LAYOUTS:
            card, sizes, build, grid_words = FIXED_LAYOUTS[key]
            got = _fixed(card, sizes, build, grid_words, body_i, body_f, grids)
            if got is None:
                unfit.append(f"{card} ({table}, {body_i.size} words)")
                continue
            entries += [(card, f, table) for f in got[0]]
        elif key in _VARIABLE:
            card, parse = _VARIABLE[key]
            got = parse(body_i, body_f, grids, False) or parse(body_i, body_f, grids, True)
            if got is None:
                unfit.append(f"{card} ({table}, {body_i.size} words)")
                continue
            entries += [(card, f, table) for f in got]
        else:
            unread[_NOT_MESH.get(key, f"record {key}")] += 1
    if unfit:
        log.warning("%s: element records that no known layout fits are left out: %s", path, "; ".join(unfit[:5]))
    if unread:
        log.info("%s: GEOM records of no mesh meaning here (or not read) skipped: %s", path,
                 ", ".join(f"{k} x{v}" for k, v in sorted(unread.items())))
    elements: dict[int, Element] = {}
    rigid: dict[int, Element] = {}
    for card, fields, table in entries:
        try:
            eid, desc, nodes, pid = element_from_fields(path, card, fields, None)
        except FEReadError as exc:
            log.warning("%s: %s entry of %s left out (%s)", path, card, table, exc)
            continue
        element = Element(int(eid), int(desc), tuple(int(g) for g in nodes), int(pid))
        space = rigid if table.startswith("GEOM4") else elements
        if eid in space:
            log.warning("%s: element id %d appears twice in %s; the second is left out", path, eid, table)
            continue
        space[eid] = element
    if not elements and not rigid:
        return ()
    top = max([*elements, *rigid])
    shared = sorted(set(elements) & set(rigid))
    for k, eid in enumerate(shared, start=1):  # as the deck reader does: rigid elements have their own id space
        e = rigid.pop(eid)
        rigid[top + k] = Element(top + k, e.fe_descriptor, e.nodes, e.physical_property)
    if shared:
        log.warning("%s: %d rigid element(s) share their id with a structural element; renumbered above %d",
                    path, len(shared), top)
    out = sorted([*elements.values(), *rigid.values()], key=lambda e: e.element_id)
    log.info("%s: %d elements read from the OP2's GEOM tables (%s)", path, len(out),
             ", ".join(f"{k} x{v}" for k, v in sorted(Counter(c for c, _, _ in entries).items())))
    return tuple(out)


def op2_grids(path: str, records: list[tuple[str, bytes]], endian: str, word: int, ids):
    """``(xyz, frames)`` in basic of the grids ``ids`` from the GEOM1 records, or None if those lack some grid.

    Raises
    ------
    FEReadError
        A coordinate system that no CORD2 record defines, a cycle or a degenerate system
        (:func:`fem_import.nastran_coords.resolve`); non-finite coordinates.
    """
    from .nastran_coords import resolve

    grids: dict[int, tuple] = {}
    cds: dict[int, int] = {}
    cord2: dict[int, tuple] = {}
    for table, raw in records:
        if not table.startswith("GEOM1"):
            continue
        ints = np.frombuffer(raw, dtype=f"{endian}i{word}")
        floats = np.frombuffer(raw, dtype=f"{endian}f{word}").astype(float)
        if ints.size < 3:
            continue
        key = tuple(int(v) for v in ints[:3])
        body_i, body_f = ints[3:], floats[3:]
        if key == _GRID and body_i.size % 8 == 0:
            for w, f in zip(body_i.reshape(-1, 8), body_f.reshape(-1, 8)):
                grids[int(w[0])] = (int(w[1]), tuple(f[2:5].tolist()), table)
                if w[5]:
                    cds[int(w[0])] = int(w[5])
        elif key in _CORD2 and body_i.size % 13 == 0:
            for w, f in zip(body_i.reshape(-1, 13), body_f.reshape(-1, 13)):
                cord2[int(w[0])] = (_CORD2[key], int(w[3]), f[4:7].copy(), f[7:10].copy(), f[10:13].copy(), table)
    wanted = [int(g) for g in np.asarray(ids).tolist()]
    absent = [g for g in wanted if g not in grids]
    if absent:
        if grids:
            log.warning("%s: the GEOM1 table lacks %d grid(s) of the eigenvectors (first %s): its grids are not used",
                        path, len(absent), absent[:5])
        return None
    bad = [g for g in wanted if not np.all(np.isfinite(grids[g][1]))]
    if bad:
        raise FEReadError(path, f"grid {bad[0]} has non-finite coordinates {list(grids[bad[0]][1])} in the GEOM1 "
                                f"table: the file is damaged")
    systems, positions = resolve(path, cord2, {}, grids)
    xyz = np.array([positions[g] for g in wanted], float)
    frames = np.repeat(np.eye(3)[None], len(wanted), axis=0)
    for k, g in enumerate(wanted):
        cd = cds.get(g)
        if cd is None:
            continue
        if cd not in systems:
            raise FEReadError(path, f"GRID {g}: its displacement system CD = {cd} is defined by no CORD2 record of "
                                    f"the GEOM1 table", dataset="GEOM1")
        frames[k] = systems[cd].frame_at(xyz[k])
    log.info("%s: %d grid positions read from the GEOM1 table (%d coordinate system(s))", path, len(wanted),
             len(cord2))
    return xyz, frames
