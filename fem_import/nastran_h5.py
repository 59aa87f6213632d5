"""MSC Nastran HDF5 results (``.h5``) reader of real eigenvectors, SOL 103.

MSC Nastran (2016 and later) writes its results as an HDF5 file (``MDLPRM,HDF5,0``; Patran and MSC Apex read it),
in place of or beside the OP2. The file is a tree of compound tables read here through h5py, by field name (MSC
Nastran HDF5 schema):

* ``/NASTRAN/RESULT/NODAL/EIGENVECTOR``: one row per point and mode, ``ID, X, Y, Z, RX, RY, RZ, DOMAIN_ID``; the
  index ``/INDEX/NASTRAN/RESULT/NODAL/EIGENVECTOR`` (``DOMAIN_ID, POSITION, LENGTH``) says which rows belong to
  which domain. Rows of points that are not grids (``SPOINT``, ``EPOINT``) are skipped with a logged count.
  ``EIGENVECTOR_CPLX`` (complex modes) is refused.
* ``/NASTRAN/RESULT/DOMAINS``: a domain's ``SUBCASE`` and ``MODE``, and ``TIME_FREQ_EIGR``, its eigenvalue.
* ``/NASTRAN/RESULT/SUMMARY/EIGENVALUE``: ``MODE, EIGEN, MASS`` per mode of a subcase (by its ``DOMAIN_ID``);
  the eigenvalue ``EIGEN = omega**2`` gives the frequency, the generalized mass ``MASS`` other than 1 (``NORM=MAX``)
  is divided out, as for the print file and the OP2. Without the summary, the domains' eigenvalues are used and
  the shapes are taken as mass-normalised, with a note.
* **Geometry** from the input tables: ``/NASTRAN/INPUT/NODE/GRID`` (``ID, CP, X, CD``), the coordinate systems
  ``/NASTRAN/INPUT/COORDINATE_SYSTEM/CORD2R|C|S`` (``CID, RID, A1 .. C3``) and ``CORD1R|C|S`` (``CID, G1, G2, G3``)
  resolved as a bulk deck's (:mod:`fem_import.nastran_coords`), and the elements of
  ``/NASTRAN/INPUT/ELEMENT/<card>`` read as the bulk deck's entries of the same name
  (:func:`fem_import.nastran_bulk.element_from_fields`, so each card keeps its role). Eigenvectors are given in
  each grid's ``CD`` system and are turned to basic. ``RBE3`` (whose weights sit in side tables) is left out,
  said in the log.

An HDF5 file is checked as the library opens it: a cut file is refused (HDF5 records where it ends). A table that
lacks a field of the schema, an index that points outside its table or at rows of another domain, a mode without
some grid of the others, several subcases without ``subcase=`` and a generalized mass that is not positive are
refused by name. A file states no units: SI is assumed unless ``--fe-units`` says otherwise.
"""

from __future__ import annotations

import logging
from collections import Counter

import numpy as np

from .errors import FEReadError
from .modes import FEModes
from .nastran_modes import ParsedMode, frequencies, grid_shapes, select_subcase
from .registry import register_format

__all__ = ["read_nastran_h5", "sniff_nastran_h5", "H5_ELEMENT_FIELDS"]

log = logging.getLogger("fem_import")

_MAGIC = b"\x89HDF\r\n\x1a\n"
_VECTOR = "NASTRAN/RESULT/NODAL/EIGENVECTOR"
#: Element tables read, and the fields giving the bulk entry's fields in their order (a ``(name, n)`` pair is an
#: array field of ``n`` grids, zeros for absent mid-side grids).
H5_ELEMENT_FIELDS: dict[str, tuple] = {
    "CBAR": ("EID", "PID", "GA", "GB"), "CBEAM": ("EID", "PID", "GA", "GB"),
    "CROD": ("EID", "PID", ("G", 2)), "CTUBE": ("EID", "PID", ("G", 2)), "CONROD": ("EID", "G1", "G2"),
    "CQUAD4": ("EID", "PID", ("G", 4)), "CQUADR": ("EID", "PID", ("G", 4)), "CQUAD8": ("EID", "PID", ("G", 8)),
    "CTRIA3": ("EID", "PID", ("G", 3)), "CTRIAR": ("EID", "PID", ("G", 3)), "CTRIA6": ("EID", "PID", ("G", 6)),
    "CTETRA": ("EID", "PID", ("G", 10)), "CPENTA": ("EID", "PID", ("G", 15)), "CHEXA": ("EID", "PID", ("G", 20)),
    "CONM2": ("EID", "G"), "CONM1": ("EID", "G"),
    "CELAS1": ("EID", "PID", "G1", "C1", "G2", "C2"), "CELAS2": ("EID", "K", "G1", "C1", "G2", "C2"),
    "CBUSH": ("EID", "PID", "GA", "GB"), "RBAR": ("EID", "GA", "GB"),
}


def sniff_nastran_h5(head: bytes, name: str = "") -> bool:
    """True for an HDF5 file (its signature) that names a ``NASTRAN`` group in its first bytes or is called .h5."""
    if not head.startswith(_MAGIC):
        return False
    return b"NASTRAN" in head or name.lower().endswith((".h5", ".hdf5"))


def _table(path: str, f, where: str, fields, *, required: bool = True):
    """The compound table at ``where`` (None if absent and not ``required``), with ``fields`` checked."""
    if where not in f:
        if required:
            raise FEReadError(path, f"no table /{where}", dataset=where)
        return None
    data = f[where][()]
    names = data.dtype.names or ()
    missing = [n for n in fields if n not in names]
    if missing:
        raise FEReadError(path, f"table /{where} lacks the field(s) {missing} of the MSC Nastran schema (it has "
                                f"{list(names)})", dataset=where)
    return data


def _domain_rows(path: str, f, vec) -> list[tuple[int, np.ndarray]]:
    """``(domain, row indices)`` of the eigenvector table, from its index if there is one."""
    index = _table(path, f, "INDEX/" + _VECTOR, ("DOMAIN_ID", "POSITION", "LENGTH"), required=False)
    dom = np.asarray(vec["DOMAIN_ID"], np.int64)
    if index is None:
        order = list(dict.fromkeys(dom.tolist()))
        return [(d, np.flatnonzero(dom == d)) for d in order]
    out = []
    for d, pos, n in zip(index["DOMAIN_ID"].tolist(), index["POSITION"].tolist(), index["LENGTH"].tolist()):
        if pos < 0 or n <= 0 or pos + n > dom.size:
            raise FEReadError(path, f"the eigenvector index gives domain {d} rows {pos}..{pos + n - 1}, outside the "
                                    f"table's {dom.size} rows (truncated file?)", dataset="INDEX/" + _VECTOR)
        rows = np.arange(pos, pos + n)
        if np.any(dom[rows] != d):
            raise FEReadError(path, f"the eigenvector index gives domain {d} rows that belong to domain(s) "
                                    f"{sorted(set(dom[rows].tolist()) - {d})[:5]}", dataset="INDEX/" + _VECTOR)
        out.append((d, rows))
    return out


def _modes(path: str, f) -> tuple[list[ParsedMode], dict]:
    """The eigenvectors per domain, and ``{(subcase, mode): (eigenvalue, generalized mass)}`` of the summary."""
    vec = _table(path, f, _VECTOR, ("ID", "X", "Y", "Z", "RX", "RY", "RZ", "DOMAIN_ID"))
    domains = _table(path, f, "NASTRAN/RESULT/DOMAINS", ("ID", "SUBCASE", "TIME_FREQ_EIGR", "MODE"))
    info = {int(r["ID"]): r for r in domains}
    grid_ids = np.asarray(_table(path, f, "NASTRAN/INPUT/NODE/GRID", ("ID",))["ID"], np.int64)
    values = np.column_stack([np.asarray(vec[c], float) for c in ("X", "Y", "Z", "RX", "RY", "RZ")])
    ids = np.asarray(vec["ID"], np.int64)
    is_grid = np.isin(ids, grid_ids)
    modes = []
    for d, rows in _domain_rows(path, f, vec):
        if d not in info:
            raise FEReadError(path, f"eigenvectors of domain {d}, which /NASTRAN/RESULT/DOMAINS does not list",
                              dataset=_VECTOR)
        r = info[d]
        mode = ParsedMode(int(r["MODE"]), float(r["TIME_FREQ_EIGR"]), int(r["SUBCASE"]), None)
        keep = rows[is_grid[rows]]
        mode.ids, mode.vals = ids[keep].tolist(), values[keep]
        modes.append(mode)
    others = int(np.count_nonzero(~is_grid))
    if others:
        log.info("%s: %d eigenvector rows of points that are not grids (SPOINT, EPOINT) skipped", path, others)
    summary = _table(path, f, "NASTRAN/RESULT/SUMMARY/EIGENVALUE", ("MODE", "EIGEN", "MASS", "DOMAIN_ID"),
                     required=False)
    table = {}
    for r in summary if summary is not None else ():
        sub = info.get(int(r["DOMAIN_ID"]))
        table[(int(sub["SUBCASE"]) if sub is not None else None, int(r["MODE"]))] = (float(r["EIGEN"]),
                                                                                      float(r["MASS"]))
    return modes, table


def _geometry(path: str, f, ids: np.ndarray):
    """``(xyz, frames, elements)`` of the grids ``ids`` in basic, from the input tables."""
    from .nastran_bulk import element_from_fields
    from .nastran_coords import resolve

    grid = _table(path, f, "NASTRAN/INPUT/NODE/GRID", ("ID", "CP", "X", "CD"))
    grids = {int(g): (int(cp), tuple(float(v) for v in x), None)
             for g, cp, x in zip(grid["ID"], grid["CP"], grid["X"])}
    cd = {int(g): int(c) for g, c in zip(grid["ID"], grid["CD"])}
    cord2, cord1 = {}, {}
    for kind in "RCS":
        t = _table(path, f, f"NASTRAN/INPUT/COORDINATE_SYSTEM/CORD2{kind}",
                   ("CID", "RID", "A1", "A2", "A3", "B1", "B2", "B3", "C1", "C2", "C3"), required=False)
        for r in t if t is not None else ():
            v = np.array([float(r[c]) for c in ("A1", "A2", "A3", "B1", "B2", "B3", "C1", "C2", "C3")])
            cord2[int(r["CID"])] = (kind, int(r["RID"]), v[0:3], v[3:6], v[6:9], None)
        t = _table(path, f, f"NASTRAN/INPUT/COORDINATE_SYSTEM/CORD1{kind}", ("CID", "G1", "G2", "G3"),
                   required=False)
        for r in t if t is not None else ():
            cord1[int(r["CID"])] = (kind, (int(r["G1"]), int(r["G2"]), int(r["G3"])), None)
    systems, positions = resolve(path, cord2, cord1, grids)
    absent = [n for n in ids.tolist() if n not in positions]
    if absent:
        raise FEReadError(path, f"{len(absent)} grid(s) of the eigenvectors are not in /NASTRAN/INPUT/NODE/GRID, "
                                f"first {absent[:10]}")
    xyz = np.array([positions[n] for n in ids.tolist()])
    bad = ~np.all(np.isfinite(xyz), axis=1)
    if np.any(bad):
        raise FEReadError(path, f"grid {ids[bad][0]} has non-finite coordinates {xyz[bad][0].tolist()}",
                          dataset="NASTRAN/INPUT/NODE/GRID")
    frames = np.repeat(np.eye(3)[None], ids.size, axis=0)
    for k, n in enumerate(ids.tolist()):
        if cd[n]:
            if cd[n] not in systems:
                raise FEReadError(path, f"grid {n}: displacement coordinate system CD = {cd[n]} is not defined")
            frames[k] = systems[cd[n]].frame_at(xyz[k])
    elements = []
    group = f.get("NASTRAN/INPUT/ELEMENT")
    for card in sorted(group.keys()) if group is not None else ():
        if card == "RBE2":
            elements += _rbe2(path, f)
            continue
        if card not in H5_ELEMENT_FIELDS:
            why = ("its weights and grids sit in side tables not read" if card == "RBE3"
                   else "not an element the wheelset model uses")
            log.info("%s: element table %s left out (%s)", path, card, why)
            continue
        spec = H5_ELEMENT_FIELDS[card]
        t = _table(path, f, f"NASTRAN/INPUT/ELEMENT/{card}", [s if isinstance(s, str) else s[0] for s in spec])
        for r in t:
            fields = []
            for s in spec:
                if isinstance(s, str):
                    fields.append(str(r[s]))
                else:
                    fields += [str(int(g)) if g else "" for g in np.atleast_1d(r[s[0]])[:s[1]]]
            elements.append(element_from_fields(path, card, fields, None))
    return xyz, frames, elements


def _rbe2(path: str, f) -> list:
    """RBE2 rows (``RB``: ``EID, GN, CM, GM_POS, GM_LEN``) with their dependent grids (``GM``: ``ID``)."""
    from .nastran_bulk import element_from_fields

    rb = _table(path, f, "NASTRAN/INPUT/ELEMENT/RBE2/RB", ("EID", "GN", "CM", "GM_POS", "GM_LEN"))
    gm = np.asarray(_table(path, f, "NASTRAN/INPUT/ELEMENT/RBE2/GM", ("ID",))["ID"], np.int64)
    out = []
    for r in rb:
        pos, n = int(r["GM_POS"]), int(r["GM_LEN"])
        if pos < 0 or n <= 0 or pos + n > gm.size:
            raise FEReadError(path, f"RBE2 {int(r['EID'])}: dependent grids {pos}..{pos + n - 1} outside the GM "
                                    f"table's {gm.size} rows", dataset="NASTRAN/INPUT/ELEMENT/RBE2/GM")
        fields = [str(int(r["EID"])), str(int(r["GN"])), str(int(r["CM"]))] + [str(g) for g in gm[pos:pos + n]]
        out.append(element_from_fields(path, "RBE2", fields, None))
    return out


def read_nastran_h5(path: str, *, subcase: int | str | None = None, echo: bool = True) -> FEModes:
    """Read real eigenvectors from an MSC Nastran HDF5 result file (module docstring).

    Parameters
    ----------
    path : str
        The file.
    subcase : int, "lowest" or None, optional
        As for :func:`fem_import.punch.read_punch`.
    echo : bool, optional
        Take the geometry from the file's input tables; :func:`fem_import.read` passes False when it is given a
        geometry, whose ``CD`` systems then turn the shapes.

    Returns
    -------
    FEModes
        Modes in mode-number order, 6 DOF per grid, mass-normalised, the file's mode numbers kept; basic
        coordinates, the elements, and shapes in the basic axes (with ``echo``).

    Raises
    ------
    FEReadError
        A cut or damaged file, a table or field of the schema missing, complex eigenvectors, several subcases and no
        ``subcase``, a mode without some grid of the others, a generalized mass that is not positive.
    """
    import h5py

    try:
        fh = h5py.File(path, "r")
    except OSError as exc:
        raise FEReadError(path, f"the HDF5 file cannot be opened ({exc}): cut short or damaged") from None
    try:
        with fh as f:
            if "NASTRAN" not in f:
                raise FEReadError(path, f"an HDF5 file without MSC Nastran's /NASTRAN group (it holds "
                                        f"{sorted(f.keys())[:10]})")
            if _VECTOR not in f:
                if _VECTOR + "_CPLX" in f:
                    raise FEReadError(path, "complex eigenvectors (EIGENVECTOR_CPLX): only real normal modes "
                                            "(SOL 103) are read", dataset=_VECTOR + "_CPLX")
                raise FEReadError(path, f"no real eigenvectors (/{_VECTOR}: a SOL 103 run with DISPLACEMENT = ALL "
                                        f"and MDLPRM,HDF5)")
            parsed, table = _modes(path, f)
            modes = sorted(select_subcase(path, parsed, subcase, "HDF5 file"), key=lambda m: m.number)
            numbers = [m.number for m in modes]
            if len(set(numbers)) != len(numbers):
                twice = sorted(n for n, c in Counter(numbers).items() if c > 1)
                raise FEReadError(path, f"subcase {modes[0].subcase}: mode(s) {twice[:10]} have two eigenvectors")
            ref_ids, shapes = grid_shapes(path, modes, "eigenvector")
            geometry = _geometry(path, f, ref_ids) if echo else None
    except FEReadError:
        raise
    except (OSError, KeyError, IndexError, ValueError, TypeError, RuntimeError) as exc:  # h5py, a damaged object
        raise FEReadError(path, f"the HDF5 tables cannot be read ({type(exc).__name__}: {exc})") from None
    chosen = modes[0].subcase
    history = [f"read {len(modes)} modes ({numbers[0]}..{numbers[-1]}, subcase {chosen}) on {ref_ids.size} grids "
               f"from MSC Nastran HDF5 file {path}"]
    rows = [table.get((chosen, n)) for n in numbers]
    if all(r is not None for r in rows):
        for m, r in zip(modes, rows):
            m.eigenvalue = r[0]
        gm = np.array([r[1] for r in rows])
        if np.any(~(gm > 0)):
            k = int(np.argmax(~(gm > 0)))
            raise FEReadError(path, f"mode {numbers[k]} has generalized mass {gm[k]!r} in the eigenvalue summary; "
                                    f"it must be positive", dataset="NASTRAN/RESULT/SUMMARY/EIGENVALUE")
        other = np.flatnonzero(np.abs(gm - 1.0) > 1e-4)
        if other.size:
            shapes = shapes / np.sqrt(gm)[:, None, None]
            history.append("normalised to unit modal mass (phi / sqrt(m), the eigenvalue summary's generalized "
                           "mass): " + ", ".join(f"mode {numbers[k]} m={gm[k]:g}" for k in other[:20])
                           + (" ..." if other.size > 20 else ""))
    else:
        log.info("%s: no eigenvalue summary row for some modes: the domains' eigenvalues are used and the shapes "
                 "taken as mass-normalised", path)
        history.append("no generalized mass in the file: taken as mass-normalised (NORM=MASS, Nastran's default)")
    fe = FEModes(node_ids=ref_ids, xyz=np.full((ref_ids.size, 3), np.nan), elements=(),
                 freqs_hz=frequencies(path, modes), shapes=shapes, modal_mass=np.ones(len(modes)),
                 source=str(path), format="nastran-h5",
                 units="SI (m, kg, s) assumed (a Nastran HDF5 file does not state units)", history=tuple(history),
                 mode_numbers=np.asarray(numbers, np.int64))
    if geometry is None:
        return fe
    from .registry import Geometry, merge_geometry

    xyz, frames, elements = geometry
    return merge_geometry(fe, Geometry(ref_ids, xyz, tuple(_as_element(e) for e in elements),
                                       f"{path} (input tables)", fe.units, displacement_frames=frames))


def _as_element(entry):
    from .modes import Element

    eid, desc, nodes, pid = entry
    return Element(int(eid), int(desc), tuple(int(n) for n in nodes), int(pid))


register_format("nastran-h5", patterns=("*.h5", "*.H5", "*.hdf5"), sniff=sniff_nastran_h5, reader=read_nastran_h5,
                geometry=None, aliases=("h5",), description="MSC Nastran HDF5 results (MDLPRM,HDF5): real "
                                                            "eigenvectors, eigenvalue summary, input tables")
