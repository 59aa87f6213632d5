"""Nastran binary results (``.op2``) reader of real eigenvectors, SOL 103.

The OP2 is what MSC and NX Nastran write for post-processors (``PARAM,POST,-1`` or ``-2``; Femap, Patran and
HyperMesh read it), so it is often the only result file a design office keeps. It is a sequence of Fortran
unformatted records holding *data blocks*; the records (endianness, 32- or 64-bit words, the split of long
records) are read by `pyYeti <https://pyyeti.readthedocs.io>`_'s ``pyyeti.nastran.op2``, which also assembles
the grid table (``BGPDT``, ``EQEXIN``) and the coordinate systems (``CSTM``). pyNastran, the better known
reader, pins numpy < 2 in its last release (1.4.1), which this toolkit does not run on. What this module reads
(MSC Nastran DMAP Programmer's Guide, the OUG and LAMA tables):

* **Eigenvectors**: every ``OUG*`` table (``OUGV1`` in SOL 103) whose records are eigenvectors, one identification
  record and one data record per mode. Identification words: 1 approach code x 10 + device code (approach 2: real
  eigenvalues), 2 table code (7: eigenvector; its thousands are the sort code, 1 for SORT2, 2 for complex), 4 the
  subcase, 5 the mode number, 6 the eigenvalue ``lambda = omega**2``, 9 the format code (1: real), 10 the words
  per point (8). Data: per point ``10 id + device``, the point type (1 grid, 2 scalar point, 3 extra point) and
  T1 T2 T3 R1 R2 R3. Grids give 6 DOF; scalar and extra points are skipped with a logged count. Tables of other
  results (static displacements, frequency response) are skipped; complex and SORT2 eigenvectors are refused.
* **Generalized mass**: the ``LAMA`` table (mode, extraction order, eigenvalue, radians, cycles, generalized mass,
  generalized stiffness). A mass other than 1 (``NORM=MAX`` or ``POINT``) is divided out, ``phi / sqrt(m)``, as
  for the print file (:mod:`fem_import.f06`). The table belongs to the eigenvectors whose eigenvalues it holds;
  without one the shapes are taken as mass-normalised (``NORM=MASS``, Nastran's default), with a note.
* **Geometry** (``PARAM,POST,-1`` writes it): each grid's basic coordinates and displacement system ``CD`` from
  the grid table, the systems' origins and axes from ``CSTM``. The eigenvectors are given in each grid's ``CD``
  system, as Nastran punches and prints them; they are turned to the basic axes at the grid
  (:meth:`fem_import.nastran_coords.CoordSystem.frame_at`: rectangular, cylindrical, spherical). The elements
  come from the run's input deck beside the file (same stem, ``.dat``/``.bdf``/``.nas``/``.blk``), used only
  when its grids sit where the OP2 puts them (within :data:`DECK_TOLERANCE` of the model's size, else said in a
  WARNING); without such a deck, from the OP2's own GEOM2 and GEOM4 tables (:mod:`fem_import.nastran_op2_geom`:
  bars, beams, rods, shells, solids, masses, springs, bushings, RBAR, RBE2, RBE3), else the modes have none.
  A file without the grid table takes the grids of its ``GEOM1`` table (GRID and CORD2R/C/S records, resolved as
  a deck's); one without either (an ``OUTPUT2`` of the eigenvectors alone) takes coordinates, ``CD`` systems and
  elements from a companion deck or ``--geometry``, as a punch does.

**Bad files.** The Fortran record structure is walked before the library sees the file
(:func:`check_records`): a record whose length words disagree, a cut inside a record, or a file that does not end
with Nastran's end-of-file records is refused with its byte offset. An eigenvector table without its end-of-table
record, an eigenvalue table that holds more modes than the eigenvector table read, or a grid missing from some
modes is refused as truncated. The library's own exceptions on damaged content become :class:`FEReadError`.
Superelement results (several superelements' grid tables) are refused: their residual and upstream grids need the
superelement map, which is not read. An OP2 states no units: SI is assumed unless ``--fe-units`` says otherwise.
"""

from __future__ import annotations

import logging
import struct
import warnings
from collections import Counter

import numpy as np

from .errors import FEReadError
from .modes import FEModes
from .nastran_coords import CoordSystem
from .nastran_modes import ParsedMode, frequencies, grid_shapes, select_subcase
from .nastran_op2_geom import GEOM_TABLES, op2_elements, op2_grids
from .registry import register_format

__all__ = ["read_op2", "sniff_op2", "check_records", "DECK_TOLERANCE"]

log = logging.getLogger("fem_import")

#: Largest distance between a grid of the companion deck and the OP2's grid table, as a fraction of the model's
#: size (bounding-box diagonal), for the deck's elements to be used: the grid table holds single-precision
#: coordinates (7 digits), a deck's 8-column fields 5 to 7.
DECK_TOLERANCE = 1e-4
#: OUG approach code of real eigenvalue analysis, and table code of eigenvectors.
APPROACH_REAL_EIGENVALUES = 2
TABLE_EIGENVECTOR = 7
_POINT_TYPES = {1: "grid", 2: "scalar point", 3: "extra point", 4: "modal point"}
_CD_KINDS = {1: "R", 2: "C", 3: "S"}
_LABEL = b"NASTRANFORTTAPEIDCODE"


def _layout(head: bytes) -> tuple[str, int] | None:
    """``(endian, word bytes)`` from the first record's length word, or None if it is not an OP2's (4 or 8)."""
    if len(head) < 4:
        return None
    for endian in ("<", ">"):
        first = struct.unpack(endian + "i", head[:4])[0]
        if first in (4, 8):
            return endian, first
    return None


def sniff_op2(head: bytes) -> bool:
    """True if the file opens with an OP2 header: a one-word record, then ``NASTRAN FORT TAPE ID CODE``."""
    if _layout(head) is None:
        return False
    return _LABEL in head[:512].replace(b" ", b"")


def check_records(path: str) -> tuple[str, int]:
    """Walk the file's Fortran records; ``(endian, word bytes)`` if they are whole (module docstring).

    Each record is ``n``, ``n`` bytes, ``n`` (4-byte length words). Nastran ends the file with end-of-file records
    (a zero key twice after the last table's end).

    Raises
    ------
    FEReadError
        A length word that runs past the end, two length words that disagree, or no end-of-file records: the
        message gives the byte offset.
    """
    with open(path, "rb") as fh:
        size = fh.seek(0, 2)
        fh.seek(0)
        layout = _layout(fh.read(4))
        if layout is None:
            raise FEReadError(path, "not an OP2 file: the first record's length word is neither 4 nor 8")
        endian, word = layout
        length = struct.Struct(endian + "i")
        key = struct.Struct(endian + ("i" if word == 4 else "q"))
        pos, zeros = 0, 0
        while pos < size:
            # seek from length word to length word: the records' contents are not read here
            if pos + 4 > size:
                raise FEReadError(path, f"cut inside a record's length word at byte {pos} of {size} (truncated file)")
            fh.seek(pos)
            head = fh.read(4)
            n = length.unpack(head)[0]
            if n < 0 or pos + 8 + n > size:
                raise FEReadError(path, f"the record at byte {pos} declares {n} bytes, but the file ends at byte "
                                        f"{size} (truncated file)")
            body = fh.read(n) if n == word else None
            fh.seek(pos + 4 + n)
            if fh.read(4) != head:
                raise FEReadError(path, f"the record at byte {pos} ({n} bytes) does not end with its length word: "
                                        f"the file is damaged")
            zeros = zeros + 1 if body is not None and key.unpack(body)[0] == 0 else 0
            pos += 8 + n
    if zeros < 2:
        raise FEReadError(path, f"the file ends at byte {size} without Nastran's end-of-file records (a zero key "
                                f"after the last table's end): it was cut between two records or not closed")
    return endian, word


def _words(raw: bytes, endian: str, word: int, kind: str) -> np.ndarray:
    return np.frombuffer(raw, dtype=f"{endian}{kind}{word}")


def _eigenvector_tables(o2, path: str, endian: str, word: int) -> list[ParsedMode]:
    """The real eigenvectors of every OUG table (module docstring), in file order."""
    modes: list[ParsedMode] = []
    skipped: Counter = Counter()
    others: list[str] = []
    for name in [n for n in o2.dbnames if n.startswith("OUG")]:
        for k in range(len(o2.dbnames[name])):
            o2.set_position(name, k)
            o2.rdop2nt()
            while (mode := _next_mode(o2, path, name, endian, word, others, skipped)) is not None:
                modes.append(mode)
    if others:
        log.info("%s: result tables other than real eigenvectors skipped: %s", path, ", ".join(sorted(set(others))))
    if skipped:
        log.info("%s: eigenvector entries of points that are not grids skipped (per mode): %s", path,
                 ", ".join(f"{k} x{v // max(len(modes), 1)}" for k, v in sorted(skipped.items())))
    return modes


def _next_mode(o2, path: str, name: str, endian: str, word: int, others: list, skipped: Counter):
    """The next eigenvector of the table ``name`` (positioned at a record pair), or None at the table's end or if the
    table holds other results (named in ``others``)."""
    ident = o2.rdop2record("bytes")
    if not ident:
        return None
    ints, reals = _words(ident, endian, word, "i"), _words(ident, endian, word, "f")
    if ints.size < 10:
        raise FEReadError(path, f"an identification record of {ints.size} words (10 or more expected)", dataset=name)
    approach, table, sort = int(ints[0]) // 10, int(ints[1]) % 1000, int(ints[1]) // 1000
    data = o2.rdop2record("bytes")
    if data is None:
        raise FEReadError(path, "an identification record without its data record (truncated file?)", dataset=name)
    if approach != APPROACH_REAL_EIGENVALUES or table != TABLE_EIGENVECTOR:
        others.append(f"{name} (approach {approach}, table {table})")
        return None
    if sort & 2 or int(ints[8]) != 1:
        raise FEReadError(path, f"complex eigenvectors (sort code {sort}, format code {int(ints[8])}): only real "
                                f"normal modes (SOL 103) are read", dataset=name)
    if sort & 1:
        raise FEReadError(path, "eigenvectors sorted by point (SORT2); write them by mode: "
                                "DISPLACEMENT(SORT1,PLOT) = ALL", dataset=name)
    if int(ints[9]) != 8:
        raise FEReadError(path, f"{int(ints[9])} words per point (8 expected for real eigenvectors)", dataset=name)
    if len(data) % (8 * word):
        raise FEReadError(path, f"mode {int(ints[4])}: a data record of {len(data)} bytes, not whole points of 8 "
                                f"words", dataset=name)
    pts_i = _words(data, endian, word, "i").reshape(-1, 8)
    pts_f = _words(data, endian, word, "f").reshape(-1, 8)
    grid = pts_i[:, 1] == 1
    for t, c in Counter(pts_i[~grid, 1].tolist()).items():
        skipped[_POINT_TYPES.get(t, f"point type {t}")] += c
    mode = ParsedMode(int(ints[4]), float(reals[5]), int(ints[3]), None)
    mode.ids = (pts_i[grid, 0] // 10).tolist()
    mode.vals = pts_f[grid, 2:8].astype(float)
    return mode


def _generalized_mass(path: str, lama: list, modes: list[ParsedMode]) -> np.ndarray | None:
    """Per mode, the generalized mass of the LAMA table whose eigenvalues are the modes' (None if none is)."""
    lam = np.array([m.eigenvalue for m in modes])
    numbers = np.array([m.number for m in modes])
    for table in lama:
        table = np.asarray(table, float)
        if table.ndim != 2 or table.shape[1] < 6:
            continue
        rows = {int(r[0]): r for r in table}
        if not all(n in rows for n in numbers.tolist()):
            continue
        eig = np.array([rows[n][2] for n in numbers.tolist()])
        if np.allclose(eig, lam, rtol=1e-5, atol=1e-6 * max(float(np.max(np.abs(lam))), 1.0)):
            if len(rows) > len(modes):
                absent = sorted(set(rows) - set(numbers.tolist()))
                raise FEReadError(path, f"the eigenvalue table (LAMA) holds {len(rows)} modes, the eigenvector "
                                        f"tables {len(modes)}: mode(s) {absent[:10]} have no eigenvector (truncated "
                                        f"file, or DISPLACEMENT written for some modes only)", dataset="LAMA")
            return np.array([rows[n][5] for n in numbers.tolist()])
    return None


def _grid_geometry(path: str, post: dict, ids: np.ndarray):
    """``(xyz, frames)`` of the grids ``ids`` in basic from the grid table and CSTM, or None without a grid table."""
    uset = post.get("uset")
    if uset is None or len(uset) == 0:
        return None
    node = uset.index.get_level_values(0).to_numpy()
    dof = uset.index.get_level_values(1).to_numpy()
    values = uset[["x", "y", "z"]].to_numpy(float)
    first = {n: k for k, n in enumerate(node.tolist()) if dof[k] == 1}
    absent = [n for n in ids.tolist() if n not in first]
    if absent:
        raise FEReadError(path, f"{len(absent)} grid(s) of the eigenvectors are not in the grid table (BGPDT), first "
                                f"{absent[:10]}")
    rows = np.array([first[n] for n in ids.tolist()])
    if rows.max() + 1 >= dof.size or np.any(dof[rows + 1] != 2) or np.any(node[rows + 1] != ids):
        raise FEReadError(path, "the grid table (USET from BGPDT/EQEXIN) does not list each grid's DOF 1 and 2 "
                                "together: the file is damaged")
    xyz = values[rows]
    bad = ~np.all(np.isfinite(xyz), axis=1)
    if np.any(bad):
        raise FEReadError(path, f"grid {ids[bad][0]} has non-finite coordinates {xyz[bad][0].tolist()} in the grid "
                                f"table (BGPDT): the file is damaged")
    cd = values[rows + 1, 0].astype(int)
    cstm = post.get("cstm2") or {}
    systems: dict[int, CoordSystem] = {}
    frames = np.repeat(np.eye(3)[None], ids.size, axis=0)
    for cid in sorted(set(cd.tolist()) - {0}):
        if cid not in cstm:
            raise FEReadError(path, f"displacement coordinate system {cid} of grid(s) "
                                    f"{ids[cd == cid][:5].tolist()} is not in the coordinate system table (CSTM)")
        m = np.asarray(cstm[cid], float)
        kind = _CD_KINDS.get(int(m[0, 1]))
        if kind is None:
            raise FEReadError(path, f"coordinate system {cid} is of type {int(m[0, 1])}; rectangular (1), "
                                    f"cylindrical (2) and spherical (3) are read")
        systems[cid] = CoordSystem(cid, kind, m[1].copy(), m[2:5].copy())
    for k in np.flatnonzero(cd != 0):
        frames[k] = systems[int(cd[k])].frame_at(xyz[k])
    return xyz, frames


def _geom_records(o2) -> list[tuple[str, bytes]]:
    """``(table, record)`` of every record of the file's GEOM1, GEOM2 and GEOM4 tables
    (:mod:`fem_import.nastran_op2_geom`)."""
    out = []
    for name in [n for n in o2.dbnames if n in GEOM_TABLES]:
        for k in range(len(o2.dbnames[name])):
            o2.set_position(name, k)
            o2.rdop2nt()
            while record := o2.rdop2record("bytes"):
                out.append((name, record))
    return out


def _deck_elements(path: str, ids: np.ndarray, xyz: np.ndarray):
    """The elements of the companion deck, if its grids are where the grid table puts them (module docstring)."""
    from .registry import find_geometry_companion, read_geometry

    deck = find_geometry_companion(path)
    if deck is None:
        log.info("%s: no input deck beside the file (same stem, .dat/.bdf/.nas/.blk); the modes have no elements",
                 path)
        return (), None
    try:
        geo = read_geometry(deck)
    except (FEReadError, OSError) as exc:
        log.warning("%s: its elements are not taken from %s, which cannot be read (%s)", path, deck, exc)
        return (), None
    where = {n: k for k, n in enumerate(np.asarray(geo.node_ids).tolist())}
    absent = [n for n in ids.tolist() if n not in where]
    size = float(np.linalg.norm(np.ptp(xyz, axis=0))) if ids.size > 1 else 0.0
    if absent:
        log.warning("%s: its elements are not taken from %s: the deck lacks %d grid(s) of the eigenvectors (first "
                    "%s)", path, deck, len(absent), absent[:5])
        return (), None
    off = np.linalg.norm(np.asarray(geo.xyz, float)[[where[n] for n in ids.tolist()]] - xyz, axis=1)
    worst = int(np.argmax(off))
    if off[worst] > DECK_TOLERANCE * size:
        log.warning("%s: its elements are not taken from %s: grid %d sits %.4g from the OP2's position, more than "
                    "%.0e of the model's size %.4g (another model or another mesh)", path, deck, ids[worst],
                    off[worst], DECK_TOLERANCE, size)
        return (), None
    return tuple(geo.elements), deck


def read_op2(path: str, *, subcase: int | str | None = None, echo: bool = True) -> FEModes:
    """Read real eigenvectors from a Nastran OP2 file (module docstring).

    Parameters
    ----------
    path : str
        The file.
    subcase : int, "lowest" or None, optional
        As for :func:`fem_import.punch.read_punch`: None requires a single subcase, ``"lowest"`` reads the lowest
        with a WARNING naming the others.
    echo : bool, optional
        Take the geometry from the file's grid table (and the elements from its input deck); :func:`fem_import.read`
        passes False when it is given a geometry, whose ``CD`` systems then turn the shapes.

    Returns
    -------
    FEModes
        Modes in mode-number order, 6 DOF per grid, mass-normalised, the file's mode numbers kept; with the grid
        table, basic coordinates and shapes in the basic axes, else coordinates NaN and shapes in each grid's
        ``CD`` components (merge a geometry with ``read(..., geometry=...)``).

    Raises
    ------
    FEReadError
        A damaged or truncated file (names the byte offset or the table), no real eigenvectors, complex or SORT2
        eigenvectors, several subcases and no ``subcase``, a grid missing from some modes, a generalized mass that
        is not positive, superelement results.
    """
    from pyyeti.nastran import op2 as yeti_op2

    endian, word = check_records(path)
    try:
        with warnings.catch_warnings():
            # the library warns about absent USET or superelement tables; what matters is checked here
            warnings.simplefilter("ignore")
            with yeti_op2.OP2(path) as o2:
                parsed = _eigenvector_tables(o2, path, endian, word)
                geom = _geom_records(o2) if parsed and echo else []
                post = o2.rdparampost(get_mats=False, get_ougs=False, get_dr_tables=False, which="all") \
                    if parsed else {}
    except FEReadError:
        raise
    except Exception as exc:  # the library's reading of a damaged table: any exception type
        raise FEReadError(path, f"the OP2 tables cannot be read ({type(exc).__name__}: {exc}): the file is "
                                f"damaged or not a Nastran results file") from None
    if not parsed:
        raise FEReadError(path, "no real eigenvectors found (expected an OUGV1 table of a SOL 103 run with "
                                "DISPLACEMENT(PLOT) = ALL and PARAM,POST,-1)")
    if len(post.get("bgpdt", {})) > 1 or len(np.atleast_2d(post.get("selist", np.zeros((1, 2))))) > 1:
        raise FEReadError(path, "the file holds the results of several superelements: their grids need the "
                                "superelement map, which is not read; write the modes of a run without superelements")
    lama = post.get("lama", [])
    lama = lama if isinstance(lama, list) else [lama]
    modes = sorted(select_subcase(path, parsed, subcase, "OP2 file"), key=lambda m: m.number)
    chosen = modes[0].subcase
    numbers = [m.number for m in modes]
    if len(set(numbers)) != len(numbers):
        twice = sorted(n for n, c in Counter(numbers).items() if c > 1)
        raise FEReadError(path, f"subcase {chosen}: mode(s) {twice[:10]} have eigenvectors in two tables")
    ref_ids, shapes = grid_shapes(path, modes, "eigenvector")
    history = [f"read {len(modes)} modes ({numbers[0]}..{numbers[-1]}, subcase {chosen}) on {ref_ids.size} grids "
               f"from Nastran OP2 file {path}"]
    gm = _generalized_mass(path, lama, modes)
    if gm is not None:
        if np.any(~(gm > 0)):
            k = int(np.argmax(~(gm > 0)))
            raise FEReadError(path, f"mode {numbers[k]} has generalized mass {gm[k]!r} in the eigenvalue table; it "
                                    f"must be positive", dataset="LAMA")
        other = np.flatnonzero(np.abs(gm - 1.0) > 1e-4)
        if other.size:
            shapes = shapes / np.sqrt(gm)[:, None, None]
            history.append("normalised to unit modal mass (phi / sqrt(m), the eigenvalue table's generalized mass): "
                           + ", ".join(f"mode {numbers[k]} m={gm[k]:g}" for k in other[:20])
                           + (" ..." if other.size > 20 else ""))
    else:
        log.info("%s: no eigenvalue table (LAMA) of these modes: their shapes are taken as mass-normalised", path)
        history.append("no generalized mass in the file: taken as mass-normalised (NORM=MASS, Nastran's default)")
    fe = FEModes(node_ids=ref_ids, xyz=np.full((ref_ids.size, 3), np.nan), elements=(),
                 freqs_hz=frequencies(path, modes), shapes=shapes, modal_mass=np.ones(len(modes)),
                 source=str(path), format="nastran-op2",
                 units="SI (m, kg, s) assumed (an OP2 file does not state units)", history=tuple(history),
                 mode_numbers=np.asarray(numbers, np.int64))
    if not echo:
        return fe
    geometry, table = _grid_geometry(path, post, ref_ids), "grid table"
    if geometry is None and geom:
        geometry, table = op2_grids(path, geom, endian, word, ref_ids), "GEOM1 table"
    if geometry is None:
        log.info("%s: no grid table (BGPDT, GEOM1) in the file: the coordinates must come from a companion deck",
                 path)
        return fe
    from .registry import Geometry, merge_geometry

    xyz, frames = geometry
    elements, deck = _deck_elements(path, ref_ids, xyz)
    source = f"{path} ({table})" + (f" and {deck} (elements)" if deck is not None else "")
    if deck is None and geom:
        elements = op2_elements(path, geom, endian, word, ref_ids)
        source += " and its GEOM tables (elements)" if elements else ""
    return merge_geometry(fe, Geometry(ref_ids, xyz, elements, source, fe.units, displacement_frames=frames))


register_format("nastran-op2", patterns=("*.op2", "*.OP2"), sniff=sniff_op2, reader=read_op2, geometry=None,
                aliases=("op2",), description="MSC/NX Nastran OP2 results (PARAM,POST,-1): real eigenvectors, "
                                              "eigenvalue table, grid table (pyYeti)")
