"""UFF (universal file, "UNV") reader of FE normal modes, through pyuff.

Datasets used (layouts: UC-SDRL universal file descriptions, as printed by
``pyuff.get_structure_<n>()``):

* **164** units: code 1 (SI) is taken as is; another code is converted to SI
  with the file's own factors ``L`` (length) and ``F`` (force) ("to convert
  from universal file units to SI divide by the factor"): coordinates are
  divided by ``L``; the file's mass unit is force unit * s^2 / length unit =
  ``Mk = L / F`` kg.  Mass-normalised shapes (``x = Phi q`` with kinetic
  energy ``q'^2 / 2``, thesis eq. 2.24, 2.29) have translations in
  ``1 / sqrt(mass)`` and rotations in ``1 / (length sqrt(mass))``, so
  translations are divided by ``sqrt(Mk)`` and rotations multiplied by
  ``L / sqrt(Mk)``.  A non-SI code without usable factors raises
  :class:`FEReadError`, and so does a second 164 with other factors (the
  units apply to the whole file; an identical repeat is accepted).
* **2411** nodes (double precision) and the legacy **15** (single precision):
  labels and coordinates, in the global Cartesian system: labels 0 and 1,
  or a system that **2420** defines as Cartesian with the identity rotation
  at the origin.  Nodes in any other system of 2420 (rotated, shifted,
  cylindrical, spherical) are refused, naming the nodes and the system (the
  format does not say which way its matrix maps); a label that no 2420 or 18
  defines is logged and taken as global; a label defined twice differently
  is refused (an identical repeat is accepted).
* **18** coordinate systems (origin, +x axis point, +xz plane point, in a
  reference system): nodes whose coordinates are given in a Cartesian one
  are converted to global, and mode shapes whose components are given in a
  Cartesian or cylindrical one are turned to global at each node
  (:mod:`fem_import.uff_coords`); curvilinear coordinates and spherical
  components are refused by name.
* **2412** elements: label, FE descriptor id, physical property and node
  labels, read here (not by pyuff, which reads one line of node labels and
  splits fields on blanks, so that an element with more than 8 nodes and
  two adjacent 10-digit labels could not be read): Record 1 in 10-column
  fields (6I10), the beam record (3I10) for descriptors 11 and 21-24, then
  the node labels, 8 per line (``ceil(n / 8)`` lines of 8I10; one long line
  is accepted too). Records written with blank-separated fields are read
  when they hold exactly the expected number of integers. An element whose
  records are cut short or misaligned, that lists a node twice or uses a
  node the node dataset lacks, is refused naming it and its line.
* **55** data at nodes, one dataset per mode: analysis type 2 (normal mode),
  real data, 3 values per node (data characteristic 2: translations) or 6
  (data characteristic 3: translations and rotations).  Record 7 gives the
  mode number (kept as :attr:`FEModes.mode_numbers`), record 8 the
  frequency [Hz] and the modal mass.  Shapes with a modal mass ``m`` other
  than 1 are scaled to unit modal mass, ``phi / sqrt(m)``; a modal mass of 0
  (pyuff's default when writing) is taken as "already mass-normalised" with a
  logged warning.  A mode number (record 7) that two datasets give is
  refused (0 means "not numbered" and may repeat).
* **2414** analysis data, the form current FE post-processors (Simcenter/NX,
  FEMAP, Salome-Meca) write results in: a dataset is a mode shape when its
  data sit at nodes (record 3 = 1), its analysis type is 2 (normal mode) and
  its result type 8 (displacement; 95/96, "unknown 3/6-DOF vector", are read
  as shapes with a warning), with data characteristic 2 or 3 as for 55 and
  real values (data type 2 or 4).  Record 10 field 6 is the mode number,
  record 12 fields 2 and 4 the frequency [Hz] and the modal mass (the
  dataset's chart).  Other 2414 datasets (stresses, strain energy, element
  data, static or transient results) are not mode shapes and are left out
  (logged); complex modes (analysis types 3 and 7) are refused as in 55.

Everything else that pyuff parses is parsed by pyuff; this module checks the
dataset framing (so that a truncated last dataset is reported instead of
silently dropped, as pyuff's block pairing would do) and validates what pyuff
returns (consistent lengths, integral labels, finite values, node sets).
Besides 2412, the data records of 2414 are read here: pyuff 2.5 reads one
line of values per node, but double-precision exports write a 6-DOF node on
two lines (``3D25.16``), so these records are read node line by node line,
with the values counted across lines.

Layout quirks of real exports are evened out before pyuff reads the file
(:func:`fem_import.uff_text.prepare_for_pyuff`, on a temporary copy): blanks
after a ``    -1`` delimiter or at the end of a dataset 55 line (records
padded to 80 columns), ``D`` exponents and Fortran's 3-digit exponents
without a letter (``0.12000-100``, E13.5 of 1.2e-101) in datasets 55 and 58.
Shapes are returned in the node order of dataset 2411 (file order).

Mode numbers: the file's own (record 7 of 55, record 10 of 2414) when every
mode has a positive one (they are unique: a number given twice is refused);
when some or all are 0 ("not numbered") the modes are numbered by position.
"""

from __future__ import annotations

import logging
import math
import re

import numpy as np

from .errors import FEReadError
from .modes import Element, FEModes, number_ranges
from .registry import Geometry, register_format
from .uff_coords import System18, resolve_18, systems_18
from .uff_text import DatasetSpan, fortran_field_problem, fortran_float, prepare_for_pyuff, unreadable_field

__all__ = ["read_uff", "read_uff_geometry", "sniff_uff"]

log = logging.getLogger("fem_import")

_SUPPORTED = (15, 164, 2411, 2412, 55, 2414)
#: 2414 result types read as mode shapes: displacement, and the 'unknown' 3- and 6-DOF vectors
_SHAPE_RESULTS = {8: "displacement", 95: "unknown 3-DOF vector", 96: "unknown 6-DOF vector"}
#: FE descriptors with the beam record (Record 2 of 2412: orientation node, fore and aft cross sections).
_BEAM_DESCRIPTORS = frozenset({11, 21, 22, 23, 24})
_DELIM = b"    -1"


# --------------------------------------------------------------------------
# sniffing and framing
# --------------------------------------------------------------------------
def sniff_uff(head: bytes) -> bool:
    """True if ``head`` starts (after blank lines) with a ``    -1`` delimiter and a dataset number."""
    text = head.decode("latin-1")
    lines = [ln for ln in text.splitlines() if ln.strip()]
    if len(lines) < 2 or lines[0].strip() != "-1" or len(lines[0].rstrip()) != 6:
        return False
    return re.fullmatch(r"\s*\d{1,6}", lines[1][:6]) is not None


def _delimiters(data: bytes) -> list[int]:
    """Offsets of the ``    -1`` delimiters: ``    -1`` followed by blanks only up to the end of its line.

    pyuff's rule (``UFF.refresh``) accepts an end of line right after the
    ``-1`` or exactly 74 blanks; a delimiter with other trailing blanks (an
    editor's, an exporter's) is one too, and
    :func:`~fem_import.uff_text.prepare_for_pyuff` strips those blanks before
    pyuff reads the file, so that both count the same datasets.
    """
    out = []
    n = len(data)
    ind = -1
    while True:
        ind = data.find(_DELIM, ind + 1)
        if ind == -1:
            return out
        k = ind + 6
        while k < n and data[k] in (32, 9):
            k += 1
        if k == n or data[k] in (10, 13):
            out.append(ind)


def _check_framing(path: str, data: bytes) -> list[int]:
    """Check that every dataset is closed and nothing lies between datasets.

    Returns the 1-based line number of each dataset's opening delimiter.
    """
    marks = _delimiters(data)

    def line_of(offset: int) -> int:
        return data.count(b"\n", 0, offset) + 1

    if not marks:
        raise FEReadError(path, "no UFF dataset found (no '    -1' delimiter line)")
    if len(marks) % 2:
        raise FEReadError(path, "the last dataset has no closing '    -1' delimiter: the file is truncated",
                          line=line_of(marks[-1]))
    starts = marks[0::2]
    ends = marks[1::2]
    gaps = [(0, starts[0])] + [(e + 6, s) for e, s in zip(ends[:-1], starts[1:])] + [(ends[-1] + 6, len(data))]
    for lo, hi in gaps:
        chunk = data[lo:hi]
        if chunk.strip(b" \t\r\n\x00\x1a"):
            bad = lo + len(chunk) - len(chunk.lstrip(b" \t\r\n\x00\x1a"))
            raise FEReadError(path, "text outside any dataset (between '    -1' delimiters): the file is "
                              "corrupt or a dataset delimiter is missing", line=line_of(bad))
    return [(line_of(s), s, e) for s, e in zip(starts, ends)]


def _ints(text: str, n: int | None) -> list[int] | None:
    """The integers of a record in 10-column fields (``n`` of them, or as many as the line holds).

    Fixed columns first (two adjacent 10-digit labels have no blank between
    them); a record written with blank-separated fields is read when it
    holds exactly ``n`` integers. None when neither reading fits.
    """
    t = text.rstrip()
    count = n if n is not None else -(-len(t) // 10)
    fields = [t[10 * k:10 * k + 10] for k in range(count)]
    try:
        vals = [int(f) for f in fields]
        if not t[10 * count:].strip():
            return vals
    except ValueError:
        pass
    toks = t.split()
    if (n is None or len(toks) == n) and all(re.fullmatch(r"[+-]?\d+", tok) for tok in toks) and toks:
        return [int(tok) for tok in toks]
    return None


def _elements_2412(path, block: bytes, line: int, known: set[int] | None) -> list[Element]:
    """Dataset 2412 (``block`` from its opening delimiter, at ``line``) as elements (module docstring)."""
    lines = block.decode("latin-1").splitlines()
    out: list[Element] = []
    i = 2
    while i < len(lines):
        if not lines[i].strip():
            i += 1
            continue
        at = line + i
        rec = _ints(lines[i], 6)
        if rec is None:
            raise FEReadError(path, f"record 1 of an element must hold 6 integers in 10-column fields (label, FE "
                              f"descriptor, physical property, material property, colour, number of nodes), got "
                              f"{lines[i].rstrip()!r}: the records are misaligned or corrupt", dataset="2412",
                              line=at)
        eid, desc, prop, _, _, nn = rec
        who = f"element {eid} (FE descriptor {desc})"
        i += 1
        if eid <= 0:
            raise FEReadError(path, f"{who}: element labels must be positive", dataset="2412", line=at)
        if nn < 1:
            raise FEReadError(path, f"{who} declares {nn} nodes; an element has at least one", dataset="2412",
                              line=at)
        if desc in _BEAM_DESCRIPTORS:
            beam = _ints(lines[i], 3) if i < len(lines) else None
            if beam is None:
                got = repr(lines[i].rstrip()) if i < len(lines) else "the end of the dataset"
                raise FEReadError(path, f"{who} is a beam: its record 1 is followed by the beam record (orientation "
                                  f"node, fore and aft cross-section numbers, 3I10), got {got}", dataset="2412",
                                  line=line + i)
            i += 1
        nodes: list[int] = []
        while len(nodes) < nn:
            if i >= len(lines) or not lines[i].strip():
                raise FEReadError(path, f"{who} declares {nn} nodes but lists {len(nodes)}: the dataset ends, the "
                                  f"record is truncated", dataset="2412", line=at)
            labels = _ints(lines[i], None)
            if labels is None or len(nodes) + len(labels) > nn:
                raise FEReadError(path, f"{who} declares {nn} nodes, but the line of node labels "
                                  f"{lines[i].rstrip()!r} does not hold the {nn - len(nodes)} label(s) left (8 per "
                                  f"line, 10 columns each): the record is truncated or misaligned", dataset="2412",
                                  line=line + i)
            nodes += labels
            i += 1
        if any(n <= 0 for n in nodes):
            raise FEReadError(path, f"{who} has non-positive node labels {nodes}", dataset="2412", line=at)
        twice = sorted({n for n in nodes if nodes.count(n) > 1})
        if twice:
            raise FEReadError(path, f"{who} has {nn} nodes and lists node(s) {twice[:10]} more than once: an "
                              f"element's nodes are distinct; the record is corrupt", dataset="2412", line=at)
        if known is not None:
            unknown = [n for n in nodes if n not in known]
            if unknown:
                raise FEReadError(path, f"{who} uses node(s) {unknown[:10]} that are not in the node dataset "
                                  f"(2411/15)", dataset="2412", line=at)
        out.append(Element(int(eid), int(desc), tuple(int(n) for n in nodes), int(prop)))
    return out


# --------------------------------------------------------------------------
# helpers on pyuff's output
# --------------------------------------------------------------------------
def _labels(path, values, what, dataset, line) -> np.ndarray:
    """Integral, positive labels from pyuff's float/int output."""
    arr = np.asarray(values, dtype=float).ravel()
    bad = ~np.isfinite(arr) | (arr != np.round(arr)) | (arr <= 0) | (arr > 2**31)
    if np.any(bad):
        k = int(np.argmax(bad))
        raise FEReadError(path, f"{what} must be positive integers, got {arr[k]!r} in record {k + 1}: "
                          f"the dataset is corrupt", dataset=dataset, line=line)
    return arr.astype(np.int64)


def _units_factors(path, dset, line) -> tuple[float, float, str]:
    """(length factor, mass factor, description) converting file units to SI by division."""
    code = dset.get("units_code")
    desc = str(dset.get("units_description", "")).strip()
    lf = float(dset.get("length", float("nan")))
    ff = float(dset.get("force", float("nan")))
    if code == 1:
        if not (math.isclose(lf, 1.0, rel_tol=1e-9) and math.isclose(ff, 1.0, rel_tol=1e-9)):
            raise FEReadError(path, f"units code 1 (SI) with conversion factors length {lf!r}, force {ff!r}; "
                              f"expected 1 and 1", dataset="164", line=line)
        return 1.0, 1.0, "SI (m, kg, s)"
    if not (np.isfinite(lf) and np.isfinite(ff) and lf > 0 and ff > 0):
        raise FEReadError(path, f"non-SI units code {code} ({desc!r}) without usable conversion factors "
                          f"(length {lf!r}, force {ff!r}); expected positive factors to convert to m and N",
                          dataset="164", line=line)
    return lf, lf / ff, f"SI (m, kg, s), converted from units code {code} ({desc})"


class _Parts:
    """What a UFF file holds, validated (internal)."""

    def __init__(self):
        self.node_ids: np.ndarray | None = None
        self.xyz: np.ndarray | None = None
        self.node_line: int | None = None
        self.elements: list[Element] = []
        self.length_factor = 1.0
        self.mass_factor = 1.0
        self.units = "SI (m, kg, s)"
        self.units_given = False
        self.modes: list[dict] = []
        self.history: list[str] = []
        #: per node (order of ``node_ids``), the columns of its displacement system's unit vectors in the global
        #: system, where a node's displacements are given in a local system of dataset 18; else None
        self.frames: np.ndarray | None = None


def _spans(data: bytes, frames) -> list[DatasetSpan]:
    """The datasets framed by ``_check_framing`` as :class:`~fem_import.uff_text.DatasetSpan`."""
    out = []
    for k, (_, s, e) in enumerate(frames, 1):
        head = data.find(b"\n", s) + 1
        line = data[head:data.find(b"\n", head) if data.find(b"\n", head) >= 0 else e]
        try:
            kind = int(line[:6])
        except ValueError:
            kind = -1
        out.append(DatasetSpan(k, kind, line[6:7] in (b"b", b"B"), head, e))
    return out


def _read_parts(path: str, *, want_modes: bool) -> _Parts:
    with open(path, "rb") as fh:
        data = fh.read()
    frames = _check_framing(path, data)
    spans = _spans(data, frames)
    problem, _ = fortran_field_problem(data, spans)
    if problem is not None:
        raise FEReadError(path, f"record {problem.record}: field {problem.field!r}: {problem.cause}",
                          dataset=f"{problem.dataset} (type {problem.set_type})", line=problem.line)
    with prepare_for_pyuff(path, data, spans) as readable:
        return _read_parts_with(path, readable, data, frames, want_modes=want_modes)


def _read_parts_with(path: str, readable: str, data: bytes, frames, *, want_modes: bool) -> _Parts:
    import pyuff

    start_lines = [f[0] for f in frames]
    try:
        uf = pyuff.UFF(readable)
        types = np.asarray(uf.get_set_types(), dtype=np.int64)
    except Exception as exc:  # pyuff raises bare Exception
        raise FEReadError(path, f"pyuff could not index the datasets: {exc}") from exc
    if types.size != len(start_lines):
        raise FEReadError(path, f"pyuff found {types.size} datasets where the delimiters frame "
                          f"{len(start_lines)}: the file is corrupt")

    parts = _Parts()
    node_chunks: list[tuple[np.ndarray, np.ndarray, int, np.ndarray]] = []
    element_sets: list[tuple[bytes, int]] = []
    systems: dict[int, tuple[int, str, np.ndarray]] = {}
    system_lines: dict[int, int] = {}  # label -> line of the 2420 dataset that defines it
    systems18: dict[int, System18] = {}
    units_line: int | None = None      # line of the first 164 (the one in force) ...
    units_said = ""                    # ... and its units, as an error message quotes them
    wanted = {15, 18, 164, 2411, 2412, 2420} | ({55, 2414} if want_modes else set())
    ignored: dict[int, int] = {}
    for k, (kind, line) in enumerate(zip(types.tolist(), start_lines)):
        if kind <= 0:
            raise FEReadError(path, "the dataset number after the '    -1' delimiter is missing or not an "
                              "integer", line=line + 1)
        if kind not in wanted:
            ignored[kind] = ignored.get(kind, 0) + 1
            continue
        if kind == 2414:  # read here, not by pyuff (module docstring)
            md = _mode_2414(path, data[frames[k][1]:frames[k][2]], line, len(parts.modes) + 1)
            if md is None:
                ignored[kind] = ignored.get(kind, 0) + 1
            else:
                parts.modes.append(md)
            continue
        if kind == 2412:  # read here, not by pyuff (module docstring), once the nodes are known
            element_sets.append((data[frames[k][1]:frames[k][2]], line))
            continue
        try:
            dset = uf.read_sets(setn=k)
        except Exception as exc:
            bad = unreadable_field(data, _spans(data, frames)[k]) if kind == 55 else None
            if bad is not None:
                raise FEReadError(path, f"record {bad.record}: {bad.field!r}: {bad.cause}",
                                  dataset=f"{bad.dataset} (type 55, mode {len(parts.modes) + 1})",
                                  line=bad.line) from exc
            raise FEReadError(path, f"pyuff could not read this dataset: {exc}", dataset=str(kind),
                              line=line) from exc
        if not isinstance(dset, dict):
            raise FEReadError(path, f"pyuff returned {type(dset).__name__} instead of a dataset dict",
                              dataset=str(kind), line=line)
        if kind == 164:
            factors = _units_factors(path, dset, line)
            said = (f"units code {dset.get('units_code')!r} {str(dset.get('units_description', '')).strip()!r}, "
                    f"length factor {factors[0]:g}, mass factor {factors[1]:g}")
            if units_line is None:
                parts.length_factor, parts.mass_factor, parts.units = factors
                parts.units_given = True
                units_line, units_said = line, said
            elif not (math.isclose(factors[0], parts.length_factor, rel_tol=1e-12)
                      and math.isclose(factors[1], parts.mass_factor, rel_tol=1e-12)):
                # the units apply to the whole file (a 164 placed anywhere scales every coordinate and shape):
                # a second, different 164 would silently rescale what the first one described
                raise FEReadError(path, f"units differ from dataset 164 at line {units_line}: {said} here, "
                                  f"{units_said} there; a file has one unit system: keep one dataset 164",
                                  dataset="164", line=line)
        elif kind in (2411, 15):
            node_chunks.append(_nodes(path, dset, kind, line))
        elif kind == 2420:
            _add_systems(path, systems, system_lines, _coordinate_systems(path, dset, line), line)
        elif kind == 18:
            for cs in systems_18(path, dset, line):
                old = systems18.setdefault(cs.label, cs)
                if old is not cs and not (old.kind == cs.kind and old.reference == cs.reference and all(
                        np.allclose(a, b, rtol=1e-12, atol=0.0) for a, b in
                        ((old.origin, cs.origin), (old.x_point, cs.x_point), (old.xz_point, cs.xz_point)))):
                    raise FEReadError(path, f"coordinate system {cs.label} is already defined by dataset 18 at line "
                                      f"{old.line} and is defined again here differently; which one holds cannot "
                                      "be told: keep one", dataset="18", line=line)
        else:
            parts.modes.append(_mode(path, dset, line, len(parts.modes) + 1))
    _check_mode_numbers(path, parts.modes)
    odd: dict = {}
    for md in parts.modes:
        if md["spec"] not in (8, 0, None):
            odd.setdefault(md["spec"], []).append(md["k"])
    for spec, ks in odd.items():
        # once per file with a count, not once per dataset
        log.warning("%s: %d dataset(s) 55 (modes %s): specific data type %s is not displacement (8); read as "
                    "mode shape", path, len(ks), _ranges(ks), spec)
    if ignored:
        level = logging.INFO if want_modes else logging.DEBUG
        log.log(level, "%s: datasets not used by the FE reader: %s", path,
                ", ".join(f"{n} x{c}" for n, c in sorted(ignored.items())))

    if node_chunks:
        ids = np.concatenate([c[0] for c in node_chunks])
        xyz = np.concatenate([c[1] for c in node_chunks])
        uniq, counts = np.unique(ids, return_counts=True)
        if np.any(counts > 1):
            raise FEReadError(path, f"node label(s) defined more than once: {uniq[counts > 1][:10].tolist()}",
                              dataset="2411", line=node_chunks[0][2])
        xyz, parts.frames, notes = _node_systems(path, ids, np.concatenate([c[3] for c in node_chunks]), xyz,
                                                 systems, systems18, node_chunks[0][2])
        parts.history.extend(notes)
        parts.node_ids, parts.xyz, parts.node_line = ids, xyz / parts.length_factor, node_chunks[0][2]
        if parts.length_factor != 1.0:
            parts.history.append(f"coordinates divided by the file's length factor {parts.length_factor:g} (to m)")
    known = set(parts.node_ids.tolist()) if parts.node_ids is not None else None
    seen: set[int] = set()
    for block, line in element_sets:
        for el in _elements_2412(path, block, line, known):
            if el.element_id in seen:
                raise FEReadError(path, f"element label {el.element_id} is defined more than once",
                                  dataset="2412", line=line)
            seen.add(el.element_id)
            parts.elements.append(el)
    parts.elements.sort(key=lambda e: e.element_id)
    return parts


def _ranges(numbers) -> str:
    """``[7, 1, 2, 3]`` -> ``"1-3, 7"``."""
    return number_ranges(sorted(numbers))


def _nodes(path, dset, kind, line) -> tuple[np.ndarray, np.ndarray, int, np.ndarray]:
    keys = ("node_nums", "def_cs", "disp_cs", "color", "x", "y", "z")
    try:
        cols = [np.asarray(dset[key], dtype=float).ravel() for key in keys]
    except (KeyError, TypeError, ValueError) as exc:
        raise FEReadError(path, f"pyuff returned no usable node table ({exc!r})", dataset=str(kind),
                          line=line) from exc
    n = cols[0].size
    if any(c.size != n for c in cols):
        raise FEReadError(path, "the number of values is not 7 per node (label, 2 coordinate systems, colour, "
                          "x, y, z): a record is truncated or corrupt", dataset=str(kind), line=line)
    if n == 0:
        raise FEReadError(path, "no nodes in the dataset", dataset=str(kind), line=line)
    ids = _labels(path, cols[0], "node labels", str(kind), line)
    for c, what in zip(cols[1:4], ("coordinate system numbers", "displacement coordinate system numbers",
                                   "colour numbers")):
        if np.any(~np.isfinite(c) | (c != np.round(c)) | (c < 0)):
            k = int(np.argmax(~np.isfinite(c) | (c != np.round(c)) | (c < 0)))
            raise FEReadError(path, f"{what} must be non-negative integers, got {c[k]!r} for node record "
                              f"{k + 1}: a record is corrupt or misaligned", dataset=str(kind), line=line)
    xyz = np.column_stack(cols[4:7])
    if not np.all(np.isfinite(xyz)):
        k = int(np.argmax(~np.all(np.isfinite(xyz), axis=1)))
        raise FEReadError(path, f"node {ids[k]} has non-finite coordinates {xyz[k].tolist()}",
                          dataset=str(kind), line=line)
    return ids, xyz, line, np.column_stack(cols[1:3]).astype(int)


def _coordinate_systems(path, dset, line) -> list[tuple[int, int, str, np.ndarray]]:
    """Dataset 2420 through pyuff: (label, type 0/1/2, name, 4 x 3 matrix: rotation rows, then the origin) each.

    A list, not a dict: a label repeated inside the dataset must reach :func:`_add_systems`, not vanish.
    """
    try:
        labels = [int(v) for v in dset["CS_sys_labels"]]
        types = [int(v) for v in dset["CS_types"]]
        names = [str(v) for v in dset["CS_names"]]
        mats = [np.asarray(m, dtype=float).reshape(4, 3) for m in dset["CS_matrices"]]
    except (KeyError, TypeError, ValueError) as exc:
        raise FEReadError(path, f"pyuff returned no usable coordinate-system table ({exc!r})", dataset="2420",
                          line=line) from exc
    if not len(labels) == len(types) == len(names) == len(mats):
        raise FEReadError(path, "coordinate systems with missing records (label, type, name and 4 matrix rows "
                          "each): a record is truncated", dataset="2420", line=line)
    return list(zip(labels, types, names, mats))


def _add_systems(path, systems, system_lines, new, line) -> None:
    """Add the coordinate systems of one dataset 2420 (at ``line``) to ``systems``, refusing a conflicting label.

    A label defined twice with different definitions would leave the later one in force for every node that
    names it, without a word; which one the exporter meant cannot be told, so the file is refused. A repeat of
    the same definition (type, rotation and origin; the name is only a comment) is harmless and accepted.

    Raises
    ------
    FEReadError
        Names the label, both lines and both definitions.
    """
    for lab, typ, name, m in new:
        if lab in systems:
            typ0, _, m0 = systems[lab]
            if typ != typ0 or not np.allclose(m, m0, rtol=1e-12, atol=1e-12):
                raise FEReadError(path, f"coordinate system {lab} is already defined by dataset 2420 at line "
                                  f"{system_lines[lab]} ({_show_system(typ0, m0)}) and is defined again here with "
                                  f"another definition ({_show_system(typ, m)}); which one holds cannot be told: "
                                  f"keep one", dataset="2420", line=line)
            continue
        systems[lab] = (typ, name, m)
        system_lines[lab] = line


_CS_TYPES = {0: "Cartesian", 1: "cylindrical", 2: "spherical"}


def _show_system(typ: int, m: np.ndarray) -> str:
    """A coordinate system of 2420 as an error message quotes it: kind, rotation rows, origin."""
    return f"{_CS_TYPES.get(typ, f'type {typ}')}, rotation {m[:3].tolist()}, origin {m[3].tolist()}"


def _node_systems(path, node_ids, node_cs, xyz, systems, systems18, line
                  ) -> tuple[np.ndarray, np.ndarray | None, list[str]]:
    """Nodes' coordinates in the global system, and the frames of their displacement components.

    Labels 0 and 1 are the global system in the exporters' convention. A system that dataset 2420 defines as
    Cartesian with the identity rotation at the origin is the global one under another label. Any other system
    of 2420 is refused: the format does not say which way its matrix maps (its exporters differ), and taking its
    coordinates or mode shapes as global would build a wrong geometry and wrong MACs. The systems of dataset 18
    are defined by three points and are used (:mod:`fem_import.uff_coords`): Cartesian definition systems,
    Cartesian and cylindrical displacement systems. A label that neither defines cannot be checked: logged as
    taken to be global.

    Returns
    -------
    xyz : ndarray (n, 3)
        Global coordinates (the file's length unit).
    frames : ndarray (n, 3, 3) or None
        Columns: the global unit vectors of each node's displacement components (None: all global).
    notes : list of str
        What was converted, for the model's history.
    """
    tol = 1e-9 * max(float(np.abs(xyz).max()), 1.0)
    both = sorted(set(systems) & set(systems18))
    if both:
        raise FEReadError(path, f"coordinate system(s) {both} are defined by both dataset 2420 and dataset 18; "
                          "which one holds cannot be told: keep one", dataset="18", line=systems18[both[0]].line)

    def global_2420(lab) -> bool:
        typ, _, m = systems[lab]
        return typ == 0 and np.allclose(m[:3], np.eye(3), rtol=0.0, atol=1e-9) and bool(np.all(np.abs(m[3]) <= tol))

    global_labels = {lab for lab in systems if global_2420(lab)} | {lab for lab in (0, 1) if lab not in systems}
    resolved = resolve_18(path, systems18, global_labels) if systems18 else {}
    undefined = []
    for lab in np.unique(node_cs):
        if lab in global_labels or lab in resolved:
            continue
        if lab not in systems:
            undefined.append(int(lab))
            continue
        typ, name, m = systems[lab]
        rows = np.any(node_cs == lab, axis=1)
        raise FEReadError(path, f"{_nodes_in(node_ids[rows])} give their {_which(node_cs[rows], lab)} in "
                          f"coordinate system {int(lab)} ({_CS_TYPES.get(typ, f'type {typ}')}"
                          f"{', ' + repr(name.strip()) if name.strip() else ''}; dataset 2420: origin "
                          f"{m[3].tolist()}, not the global system); this reader takes the systems of dataset "
                          "2420 as the global one only: export the nodes and mode shapes in the global system "
                          "(or define the system by a dataset 18)", dataset="2411", line=line)
    if undefined:
        log.warning("%s: nodes use coordinate systems %s that no dataset 2420 or 18 defines; they are taken as the "
                    "global system", path, undefined)
    out, frames, notes = np.array(xyz, float), None, []
    for lab, cs in resolved.items():
        rows = node_cs[:, 0] == lab
        if not rows.any():
            continue
        if cs.kind != "R":
            raise FEReadError(path, f"{_nodes_in(node_ids[rows])} give their coordinates in "
                              f"{systems18[lab].describe()}: the format does not state the unit of a curvilinear "
                              "system's angles; export the coordinates in a Cartesian system (the displacements "
                              "may stay cylindrical)", dataset="2411", line=line)
        out[rows] = cs.origin + xyz[rows] @ cs.axes.T
        notes.append(f"coordinates of {int(rows.sum())} node(s) converted from {systems18[lab].describe()} to "
                     "the global system")
    for lab, cs in resolved.items():
        rows = np.flatnonzero(node_cs[:, 1] == lab)
        if not rows.size:
            continue
        if cs.kind == "S":
            raise FEReadError(path, f"{_nodes_in(node_ids[rows])} give their displacements in "
                              f"{systems18[lab].describe()}: the order of a spherical system's components differs "
                              "between exporters; export them in a Cartesian or cylindrical system",
                              dataset="2411", line=line)
        if frames is None:
            frames = np.tile(np.eye(3), (node_ids.size, 1, 1))
        for i in rows:
            frames[i] = cs.frame_at(out[i])
        notes.append(f"displacements of {rows.size} node(s) turned from {systems18[lab].describe()} to the global "
                     "system")
    return out, frames, notes


def _nodes_in(ids: np.ndarray) -> str:
    return f"{ids.size} node(s) ({_ranges(ids.tolist()[:50])}{', ...' if ids.size > 50 else ''})"


def _which(cs_rows: np.ndarray, lab) -> str:
    return "coordinates and displacements" if np.all(cs_rows == lab) else "coordinates or displacements"


def _check_mode_numbers(path, modes: list[dict]) -> None:
    """Refuse a mode number that two datasets (55 or 2414) give.

    Two exports concatenated, or a dataset pasted twice, would otherwise be read as extra modes (spurious
    partners in the pairing). Only positive numbers are compared: 0 (pyuff's default when writing) or a missing
    number means "not numbered", and some exporters leave every mode so.

    Raises
    ------
    FEReadError
        Names the mode number and the lines of both datasets; an exact copy (same frequency, nodes and values)
        is called "the same mode written twice".
    """
    given: dict[int, dict] = {}
    for md in modes:
        try:
            n = int(md["mode_n"])
        except (TypeError, ValueError, OverflowError):
            continue
        if n <= 0:
            continue
        prev = given.get(n)
        if prev is None:
            given[n] = md
            continue
        if (prev["freq"] == md["freq"] and np.array_equal(prev["ids"], md["ids"])
                and np.array_equal(prev["vals"], md["vals"])):
            what = (f"modes {prev['k']} and {md['k']} are the same mode written twice (mode number {n}, "
                    f"{md['freq']:.6g} Hz, at lines {prev['line']} and {md['line']}): remove the duplicate")
        else:
            what = (f"mode number {n} already given at line {prev['line']} (dataset {prev['where']}, "
                    f"{prev['freq']:.6g} Hz; this one {md['freq']:.6g} Hz): a mode number may appear once; "
                    f"are two exports concatenated?")
        raise FEReadError(path, what, dataset=md["where"], line=md["line"])


def _mode(path, dset, line, k) -> dict:
    """Validated content of one dataset 55 (k = its position among the file's modes, 1-based)."""
    where = f"55 (mode {k})"
    at = dset.get("analysis_type")
    if at != 2:
        raise FEReadError(path, f"analysis type {at!r}; only normal modes (analysis type 2) are supported",
                          dataset=where, line=line)
    if dset.get("data_type") != 2:
        raise FEReadError(path, f"data type {dset.get('data_type')!r}; normal modes must be real (data type 2)",
                          dataset=where, line=line)
    ch, per = dset.get("data_ch"), dset.get("n_data_per_node")
    _check_characteristic(path, ch, per, where, line)
    try:
        nodes = np.asarray(dset["node_nums"])
        vals = np.column_stack([np.asarray(dset[f"r{i}"], dtype=float) for i in range(1, per + 1)])
        freq = float(dset["freq"])
        mm = float(dset["modal_m"])
    except (KeyError, TypeError, ValueError) as exc:
        raise FEReadError(path, f"pyuff returned an incomplete dataset ({exc!r})", dataset=where,
                          line=line) from exc
    return _shape(path, where, line, k, dset.get("mode_n"), nodes, vals, freq, mm, dset.get("spec_data_type"))


def _check_characteristic(path, ch, per, where, line) -> None:
    if (ch, per) not in ((2, 3), (3, 6)):
        raise FEReadError(path, f"data characteristic {ch!r} with {per!r} values per node; expected 2 (3 DOF "
                          f"translation, 3 values) or 3 (6 DOF translation and rotation, 6 values)",
                          dataset=where, line=line)


def _shape(path, where, line, k, mode_n, nodes, vals, freq, mm, spec) -> dict:
    """A mode's labels, values, frequency and modal mass, validated (datasets 55 and 2414)."""
    if nodes.ndim != 1 or nodes.size == 0 or vals.shape[0] != nodes.size:
        raise FEReadError(path, f"{nodes.size} node labels but {vals.shape[0]} value records: the dataset is "
                          f"truncated or corrupt", dataset=where, line=line)
    ids = _labels(path, nodes, "node labels", where, line)
    uniq, counts = np.unique(ids, return_counts=True)
    if np.any(counts > 1):
        raise FEReadError(path, f"node(s) {uniq[counts > 1][:10].tolist()} appear more than once",
                          dataset=where, line=line)
    bad = ~np.all(np.isfinite(vals), axis=1)
    if np.any(bad):
        raise FEReadError(path, f"mode {k} has non-finite shape values at node {ids[int(np.argmax(bad))]}",
                          dataset=where, line=line)
    if not math.isfinite(freq):
        raise FEReadError(path, f"mode {k} has a non-finite frequency {freq!r}", dataset=where, line=line)
    if not math.isfinite(mm) or mm < 0:
        raise FEReadError(path, f"mode {k} has modal mass {mm!r}; expected a positive number (or 0 for "
                          f"'mass-normalised')", dataset=where, line=line)
    return {"k": k, "mode_n": mode_n, "freq": freq, "modal_mass": mm, "ids": ids, "vals": vals,
            "line": line, "spec": spec, "where": where}


def _numbers(path, text: str, n_min: int, kind, what: str, dataset: str, line: int) -> list:
    """At least ``n_min`` numbers of type ``kind`` from a free-format record (Fortran ``D`` exponents read)."""
    try:
        vals = [fortran_float(tok) if kind is float else int(tok) for tok in text.split()]
    except ValueError:
        raise FEReadError(path, f"{what}: {text.strip()!r} holds a field that is not "
                          f"{'a number' if kind is float else 'an integer'}", dataset=dataset, line=line) from None
    if len(vals) < n_min:
        raise FEReadError(path, f"{what}: {len(vals)} value(s) where {n_min} are expected: the record is "
                          f"truncated", dataset=dataset, line=line)
    return vals


def _mode_2414(path, block: bytes, line: int, k: int) -> dict | None:
    """One dataset 2414 as a mode shape, or None when it holds no mode shape (module docstring).

    ``block`` runs from the opening delimiter (``line``) to the closing one.
    """
    lines = block.decode("latin-1").splitlines()
    where = f"2414 (mode {k})"
    if len(lines) < 15:
        raise FEReadError(path, f"{len(lines) - 2} header record line(s) where 13 are expected: the dataset is "
                          f"truncated", dataset="2414", line=line)
    label = lines[2].strip()
    location = _numbers(path, lines[4], 1, int, "record 3 (dataset location)", "2414", line + 4)[0]
    if location != 1:
        return None  # data on elements or points: not a mode shape
    _, analysis, ch, result, dtype, per = _numbers(path, lines[10], 6, int, "record 9", "2414", line + 10)[:6]
    if analysis in (3, 7):
        raise FEReadError(path, f"analysis type {analysis} (complex eigenvalue); only normal modes (analysis type "
                          f"2) are supported", dataset=where, line=line + 10)
    if analysis != 2 or result not in _SHAPE_RESULTS:
        return None  # another analysis, or a nodal result that is no displacement (energy, stress, ...)
    _check_characteristic(path, ch, per, where, line + 10)
    if dtype not in (2, 4):
        raise FEReadError(path, f"data type {dtype}; normal modes must be real (data type 2 or 4)", dataset=where,
                          line=line + 10)
    if result != 8:
        log.warning("%s: dataset 2414 %s (mode %d) holds result type %d (%s); read as mode shape", path, label, k,
                    result, _SHAPE_RESULTS[result])
    ints = _numbers(path, lines[11], 0, int, "record 10", where, line + 11)
    mode_n = ints[5] if len(ints) > 5 else None
    real = _numbers(path, lines[13], 2, float, "record 12 (time, frequency, ...)", where, line + 13)
    freq, mm = real[1], (real[3] if len(real) > 3 else 0.0)  # no modal mass: taken as mass-normalised (logged)
    nodes, vals = [], []
    i, data = 15, lines
    while i < len(data):
        if not data[i].strip():
            i += 1
            continue
        node = _numbers(path, data[i], 1, int, "record 14 (node number)", where, line + i)
        if len(node) != 1:
            raise FEReadError(path, f"record 14: {data[i].strip()!r} where a node number alone is expected: the "
                              f"records are misaligned", dataset=where, line=line + i)
        row, start = [], i
        i += 1
        while len(row) < per and i < len(data):
            row += _numbers(path, data[i], 1, float, f"record 15 of node {node[0]}", where, line + i)
            i += 1
        if len(row) != per:
            raise FEReadError(path, f"node {node[0]} has {len(row)} value(s) where {per} are expected: the "
                              f"dataset is truncated or its records misaligned", dataset=where, line=line + start)
        nodes.append(node[0])
        vals.append(row)
    return _shape(path, where, line, k, mode_n, np.asarray(nodes), np.asarray(vals, float).reshape(-1, per), freq,
                  mm, 8)


def read_uff_geometry(path: str) -> Geometry:
    """Nodes (2411/15) and elements (2412) of a universal file, in SI units.

    Raises
    ------
    FEReadError
        If the file is truncated or corrupt, or has no node dataset.
    """
    parts = _read_parts(path, want_modes=False)
    if parts.node_ids is None:
        raise FEReadError(path, "no node dataset (2411 or 15): the file carries no geometry")
    units = parts.units if parts.units_given else f"{parts.units} assumed (no units dataset 164)"
    return Geometry(parts.node_ids, parts.xyz, tuple(parts.elements), str(path), units)


def read_uff(path: str) -> FEModes:
    """Read FE normal modes from a universal file (datasets 164, 2411/15, 2412, 55 or 2414).

    Parameters
    ----------
    path : str
        The file.

    Returns
    -------
    FEModes
        Modes in file order; shapes ``(m, n_nodes, 3 or 6)`` in the node
        order of dataset 2411 (restricted to the nodes that have shapes),
        scaled to unit modal mass, SI units.  Without a node dataset the
        node order is that of the first mode and the coordinates are NaN.

    Raises
    ------
    FEReadError
        If the file is truncated or corrupt, has no mode shape (55 or 2414), mixes 3- and
        6-DOF shapes, if a mode misses a node of the others, if a mode has a
        node unknown to dataset 2411, if a shape value is not finite, if two
        datasets give the same mode number, if the units cannot be converted
        to SI or two datasets 164 disagree, or if a coordinate system is
        defined twice differently.  The message names the file, dataset and
        line.
    """
    parts = _read_parts(path, want_modes=True)
    if not parts.modes:
        raise FEReadError(path, "no dataset 55 (normal mode shapes) in the file, nor a 2414 with normal-mode "
                                "displacements at nodes")
    history = list(parts.history)
    first = parts.modes[0]
    n_dof = first["vals"].shape[1]
    ref = set(first["ids"].tolist())
    for md in parts.modes[1:]:
        where = md["where"]
        if md["vals"].shape[1] != n_dof:
            raise FEReadError(path, f"mode {md['k']} has {md['vals'].shape[1]} values per node but mode 1 has "
                              f"{n_dof}: all modes must have the same DOFs", dataset=where, line=md["line"])
        have = set(md["ids"].tolist())
        if have != ref:
            missing = sorted(ref - have)
            extra = sorted(have - ref)
            what = (f"lacks node(s) {missing[:10]} present in mode 1" if missing
                    else f"has node(s) {extra[:10]} absent from mode 1")
            raise FEReadError(path, f"mode {md['k']} {what}: all modes must cover the same nodes",
                              dataset=where, line=md["line"])

    if parts.node_ids is not None:
        known = set(parts.node_ids.tolist())
        extra = sorted(ref - known)
        if extra:
            raise FEReadError(path, f"mode shapes have node(s) {extra[:10]} that are not in the node dataset "
                              f"(2411/15){' ...' if len(extra) > 10 else ''}", dataset=first["where"],
                              line=first["line"])
        keep = np.array([n in ref for n in parts.node_ids.tolist()], bool)
        node_ids, xyz = parts.node_ids[keep], parts.xyz[keep]
        if not keep.all():
            log.info("%s: %d node(s) of dataset 2411 have no mode shape and are left out", path, int((~keep).sum()))
        elements = [e for e in parts.elements if all(n in ref for n in e.nodes)]
        if len(elements) < len(parts.elements):
            log.warning("%s: %d element(s) use nodes without mode shapes and were dropped", path,
                        len(parts.elements) - len(elements))
    else:
        log.warning("%s: no node dataset (2411 or 15); node coordinates are unknown (NaN)", path)
        node_ids = first["ids"]
        xyz = np.full((node_ids.size, 3), np.nan)
        elements = []

    numbers = _mode_numbers(path, parts.modes)
    if not parts.units_given:
        history.append("no units dataset 164: the file's units are taken as SI (m, kg, s)")
    shapes = np.empty((len(parts.modes), node_ids.size, n_dof))
    for j, md in enumerate(parts.modes):
        order = np.argsort(md["ids"], kind="stable")
        pos = np.searchsorted(md["ids"], node_ids, sorter=order)
        shapes[j] = md["vals"][order[pos]]
    if parts.frames is not None:
        # components in each node's displacement system -> global; rotations turn like translations
        fr = parts.frames[keep]
        for a in range(0, n_dof, 3):
            shapes[:, :, a:a + 3] = np.einsum("nij,mnj->mni", fr, shapes[:, :, a:a + 3])
        history.append("mode shapes turned from the nodes' displacement systems (dataset 18) to the global system")
    freqs = np.array([md["freq"] for md in parts.modes])
    if np.any(freqs < 0):
        neg = np.flatnonzero(freqs < 0)
        log.warning("%s: mode(s) %s have negative frequencies %s Hz; set to 0 Hz", path, (neg + 1).tolist(),
                    freqs[neg].tolist())
        freqs = np.maximum(freqs, 0.0)

    mm = np.array([md["modal_mass"] for md in parts.modes])
    zero = np.flatnonzero(mm == 0)
    if zero.size:
        log.warning("%s: mode(s) %s have modal mass 0 (not given); the shapes are assumed mass-normalised",
                    path, (zero + 1).tolist())
        history.append(f"modal mass 0 (not given) in mode(s) {(zero + 1).tolist()}: assumed mass-normalised")
    scale = np.where(mm > 0, mm, 1.0)
    other = np.flatnonzero((mm > 0) & (mm != 1.0))
    if other.size:
        shapes = shapes / np.sqrt(scale)[:, None, None]
        history.append("normalised to unit modal mass (phi / sqrt(m)): "
                       + ", ".join(f"mode {k + 1} m={mm[k]:g}" for k in other[:20])
                       + (" ..." if other.size > 20 else ""))
    if parts.length_factor != 1.0 or parts.mass_factor != 1.0:
        # x = phi q with T = q'^2 / 2: translations of phi are 1/sqrt(mass), rotations 1/(length sqrt(mass))
        lf, mk = parts.length_factor, parts.mass_factor
        shapes = shapes / math.sqrt(mk)
        if n_dof == 6:
            shapes[:, :, 3:] *= lf
        history.append(f"shapes converted to SI: translations / sqrt({mk:g}) (file mass unit in kg)"
                       + (f", rotations * {lf:g} / sqrt({mk:g})" if n_dof == 6 else ""))
    history.insert(0, f"read {len(parts.modes)} modes ({n_dof} DOF/node, {node_ids.size} nodes) from UFF {path}")
    return FEModes(node_ids=node_ids, xyz=xyz, elements=tuple(elements), freqs_hz=freqs, shapes=shapes,
                   modal_mass=np.ones(freqs.size), source=str(path), format="uff", units=parts.units,
                   history=tuple(history), mode_numbers=numbers)


def _mode_numbers(path, modes: list[dict]) -> np.ndarray:
    """The file's mode numbers when every mode has a positive one (unique: :func:`_check_mode_numbers`),
    else the positions 1..m (logged)."""
    given = []
    for md in modes:
        try:
            given.append(int(md["mode_n"]))
        except (TypeError, ValueError, OverflowError):
            given.append(0)
    if all(n > 0 for n in given):
        return np.asarray(given, np.int64)
    if any(n > 0 for n in given):
        log.info("%s: %d of %d modes have no mode number (0); all modes are numbered by their position", path,
                 sum(n <= 0 for n in given), len(given))
    return np.arange(1, len(modes) + 1, dtype=np.int64)


register_format("uff", patterns=("*.uff", "*.unv", "*.uf"), sniff=sniff_uff, reader=read_uff,
                geometry=read_uff_geometry, aliases=("unv", "universal"),
                description="Universal file: 164, 2411/15, 2412, 55 or 2414 (via pyuff)")
