"""CalculiX result file (``.frd``) reader of a frequency step's modes.

CalculiX (``ccx``), the open-source solver of Abaqus-style decks that FreeCAD's FEM and many small design offices
use, writes every ``*NODE FILE`` request of a ``*FREQUENCY`` step to ``jobname.frd``, the ASCII result format of
its pre- and post-processor CGX (the "Result Format" chapter of the CGX manual). No maintained Python package reads
it (``ccx2paraview`` converts it to VTK files; ``pyfrd`` is unmaintained), so this module parses the records a
frequency step writes:

* **Nodes** (``    2C`` block): ``-1`` records, node number (``I5`` in the short format, ``I10`` in the long one,
  as the block header's last field says) and three ``E12.5`` coordinates.
* **Elements** (``    3C``): a ``-1`` record (number, CGX type, group, material) and ``-2`` records of node numbers;
  the CGX types 1-12 (brick, penta, tetra, shell triangle and quad, beam; linear and quadratic) are kept as UFF
  descriptors of their corner nodes (a quadratic beam keeps its three).
* **Modes**: each mode is a result set opened by ``1PSTEP`` (the third field is the analysis step), with
  ``1PMODE`` (the mode number), ``1PGM`` (its generalized mass) and a ``100CL`` header whose analysis type is 2
  (frequency) and whose value is the frequency [cycles/time]; its ``DISP`` block gives ``D1..D3`` per node in fixed
  ``E12.5`` columns (values run together: ``1.05484E+00-3.08556E-01``). CalculiX normalises the eigenvectors to
  unit generalized mass (``1PGM 1.0``); another value is divided out, ``phi / sqrt(m)``. A negative eigenvalue
  (a rigid-body mode's round-off) is written as frequency 0, and so read. A step's modes are numbered 1, 2, ...;
  a gap, or a data record outside any block (its header lost), is a damaged file and refused.

A ``.frd`` keeps six significant digits per value and states no units: SI is assumed unless declared
(``--fe-units``), as for a Nastran punch. Shells and beams, which CalculiX expands to solids, give translations
only (3 DOF). Refused by name: a binary ``.frd`` (``*NODE FILE`` with ``OUTPUT=3D`` binary), complex modes
(``DISPI`` blocks of a ``*COMPLEX FREQUENCY`` step), cyclic-symmetry modes (a nodal diameter in ``1PHID``), several
frequency steps without ``subcase=``, a record cut short or a file without its closing ``9999`` record, and a mode
without displacements on every node.

``pyvista-frd-reader`` (0.3.1, PyVista's FRD reader) is not used: it indexes result sets by their time value, so
modes of equal frequency (the rigid-body modes, written as 0 Hz; a wheel's degenerate pairs, printed alike) fall
into one: the 12 modes of the test bar come out as 9 time points, with no message, and it drops ``1PMODE`` and
``1PGM``.
"""

from __future__ import annotations

import logging
import math

import numpy as np

from .errors import FEReadError
from .modes import Element, FEModes
from .registry import register_format
from .solutions import choose_step

__all__ = ["read_frd", "sniff_frd", "CGX_ELEMENTS"]

log = logging.getLogger("fem_import")

#: CGX element type -> UFF 2412 descriptor and the number of leading nodes kept (corners; a be3 keeps its three)
CGX_ELEMENTS = {1: (115, 8), 2: (112, 6), 3: (111, 4), 4: (115, 8), 5: (112, 6), 6: (111, 4), 7: (91, 3),
                8: (91, 3), 9: (94, 4), 10: (94, 4), 11: (21, 2), 12: (24, 3)}
#: nodes of each CGX element type, for reading its ``-2`` records
_CGX_NODES = {1: 8, 2: 6, 3: 4, 4: 20, 5: 15, 6: 10, 7: 3, 8: 6, 9: 4, 10: 8, 11: 2, 12: 3}


def sniff_frd(head: bytes) -> bool:
    """True for a CGX/CalculiX result file: it opens with a ``    1C`` record and carries ``1U`` user records or a
    ``    2C`` node block in its first kilobytes."""
    text = head.decode("latin-1")
    first = next((ln for ln in text.splitlines() if ln.strip()), "")
    return first.rstrip().startswith("    1C") and ("\n    1U" in text or "\n    2C" in text)


class _Lines:
    """The file's lines with their numbers, for messages."""

    def __init__(self, path: str, lines: list[str]):
        self.path, self.lines, self.i = path, lines, 0

    def fail(self, message: str, at: int | None = None) -> FEReadError:
        return FEReadError(self.path, message, line=(self.i if at is None else at) + 1)


def _values(src: _Lines, text: str, start: int, count: int, at: int) -> list[float]:
    out = []
    for k in range(count):
        field = text[start + 12 * k:start + 12 * (k + 1)]
        try:
            out.append(float(field))
        except ValueError:
            raise src.fail(f"value {k + 1} {field.strip()!r} of a record is not a number (the record is "
                           f"{len(text.rstrip())} characters; cut short?)", at) from None
    return out


def _width(src: _Lines, header: str, at: int) -> int:
    """Digits of the node and element numbers: the block header's format field (0 short, 1 long)."""
    try:
        fmt = int(header[-2:].strip() or 0)
    except ValueError:
        raise src.fail(f"block header {header.strip()!r} has no format field", at) from None
    if fmt >= 2:
        raise src.fail("a binary result block (format %d); write the .frd in ASCII (CalculiX's default)" % fmt, at)
    return 10 if fmt == 1 else 5


def _block_count(src: _Lines, header: str, at: int) -> int:
    try:
        return int(header[6:36].split()[-1])
    except (ValueError, IndexError):
        raise src.fail(f"block header {header.strip()!r} has no count", at) from None


def _value_records(src: _Lines, width: int, n_val: int, what: str) -> tuple[np.ndarray, np.ndarray]:
    """The ``-1`` records (a node number, then ``n_val`` E12.5 values, continued on ``-2`` records beyond 6) up to
    the block's ``-3``: node numbers and values (n, n_val)."""
    lines = src.lines
    ids, vals = [], []
    while True:
        src.i += 1
        if src.i >= len(lines):
            raise src.fail(f"the {what} does not end (no -3 record): the file is cut short")
        text = lines[src.i]
        if text[:3] == " -3":
            break
        if text[:3] != " -1":
            raise src.fail(f"expected a record ' -1' in the {what}, got {text[:20]!r}")
        try:
            ids.append(int(text[3:3 + width]))
        except ValueError:
            raise src.fail(f"node number {text[3:3 + width].strip()!r} is not an integer") from None
        row = _values(src, text, 3 + width, min(n_val, 6), src.i)
        while len(row) < n_val:  # continuation records of more than 6 components
            src.i += 1
            if src.i >= len(lines) or lines[src.i][:3] != " -2":
                raise src.fail(f"node {ids[-1]} of the {what} has {len(row)} of its {n_val} values")
            row += _values(src, lines[src.i], 3 + width, min(n_val - len(row), 6), src.i)
        vals.append(row)
    return np.asarray(ids, np.int64), np.asarray(vals, float).reshape(-1, n_val)


def _nodes(src: _Lines, header: str, at: int) -> tuple[np.ndarray, np.ndarray]:
    width = _width(src, header, at)
    count = _block_count(src, header, at)
    ids, xyz = _value_records(src, width, 3, "node block")
    if ids.size != count:
        raise src.fail(f"the node block holds {ids.size} nodes, its header says {count}", at)
    return ids, xyz


def _elements(src: _Lines, header: str, at: int) -> list[Element]:
    width = _width(src, header, at)
    per_line = 10 if width == 10 else 15
    lines = src.lines
    out = []
    while True:
        src.i += 1
        if src.i >= len(lines):
            raise src.fail("the element block does not end (no -3 record): the file is cut short")
        text = lines[src.i]
        if text[:3] == " -3":
            break
        if text[:3] != " -1":
            raise src.fail(f"expected an element record ' -1', got {text[:20]!r}")
        try:
            number, kind = int(text[3:3 + width]), int(text[3 + width:8 + width])
        except ValueError:
            raise src.fail(f"element record {text.strip()!r} has no number and type") from None
        if kind not in _CGX_NODES:
            raise src.fail(f"element {number}: CGX element type {kind} is not one CalculiX writes (1-12)")
        nodes: list[int] = []
        while len(nodes) < _CGX_NODES[kind]:
            src.i += 1
            if src.i >= len(lines) or lines[src.i][:3] != " -2":
                raise src.fail(f"element {number} (type {kind}) has {len(nodes)} of its {_CGX_NODES[kind]} nodes")
            row = lines[src.i][3:]
            n = min(per_line, _CGX_NODES[kind] - len(nodes))
            try:
                nodes += [int(row[width * k:width * (k + 1)]) for k in range(n)]
            except ValueError:
                raise src.fail(f"element {number}: a node number of {row.strip()!r} is not an integer") from None
        desc, keep = CGX_ELEMENTS[kind]
        out.append(Element(number, desc, tuple(nodes[:keep])))
    return out


class _Mode:
    __slots__ = ("step", "number", "freq", "mass", "nodes", "values", "line")

    def __init__(self, step, number, freq, mass, line):
        self.step, self.number, self.freq, self.mass, self.line = step, number, freq, mass, line
        self.nodes, self.values = None, None


def _result_block(src: _Lines, header: str, at: int, width: int) -> tuple[str, np.ndarray, np.ndarray]:
    """A ``-4`` block: its name, node numbers and values (n, components)."""
    name = header[5:13].strip()
    try:
        ncomp = int(header[13:18])
    except ValueError:
        raise src.fail(f"result block header {header.strip()!r} has no component count", at) from None
    comps = []
    lines = src.lines
    while src.i + 1 < len(lines) and lines[src.i + 1][:3] == " -5":
        src.i += 1
        comps.append(lines[src.i][5:13].strip())
    stored = [c for c in comps if c != "ALL"] or [f"C{k + 1}" for k in range(ncomp)]
    n_val = len(stored)
    if n_val == 0:
        raise src.fail(f"result block {name!r} has no components", at)
    ids, vals = _value_records(src, width, n_val, f"{name} block")
    return name, ids, vals


def _parameter(src: _Lines, text: str, start: int, kind, name: str, index: int = 0):
    """Field ``index`` of a ``1P`` parameter record (``1PSTEP``, ``1PMODE``, ``1PGM``, ``1PHID``) as ``kind``."""
    fields = text[start:].split()
    try:
        return kind(fields[index])
    except (IndexError, ValueError):
        raise src.fail(f"{name} record {text.strip()!r} lacks its value {index + 1} (a damaged record?)") from None


def _parse(path: str, lines: list[str]):
    src = _Lines(path, lines)
    node_ids = xyz = None
    elements: list[Element] = []
    modes: list[_Mode] = []
    step = number = None
    mass = 1.0
    harmonic = -1
    current: _Mode | None = None
    width = 10
    ended = False
    while src.i < len(lines):
        text = lines[src.i]
        head = text[:7]
        if text.startswith(" 9999"):
            ended = True
            break
        if head == "    2C ":
            node_ids, xyz = _nodes(src, text, src.i)
        elif head == "    3C ":
            elements = _elements(src, text, src.i)
        elif text.startswith("    1PSTEP"):
            step = _parameter(src, text, 10, int, "1PSTEP", index=2)
            number, mass, harmonic = None, 1.0, -1
        elif text.startswith("    1PMODE"):
            number = _parameter(src, text, 10, int, "1PMODE")
        elif text.startswith("    1PGM"):
            mass = _parameter(src, text, 8, float, "1PGM")
        elif text.startswith("    1PHID"):
            harmonic = _parameter(src, text, 9, int, "1PHID")
        elif text.startswith("  100C"):
            try:
                value = float(text[12:24])
                kind = int(text[56:58])
                numstep = int(text[58:63])
                fmt = int(text[73:75] or 1)
            except ValueError:
                raise src.fail(f"result header {text.strip()!r} is not a 100C record of the CGX format") from None
            if fmt >= 2:
                raise src.fail("a binary result block; write the .frd in ASCII (CalculiX's default)")
            width = 10 if fmt == 1 else 5
            current = None
            modal = "MODAL" in text[63:73].upper()
            if modal != (kind == 2):
                raise src.fail(f"result header {text.strip()!r}: analysis type {kind} and analysis "
                               f"{text[63:73].strip()!r} disagree (a damaged record?)")
            if kind == 2:
                if harmonic >= 0:
                    raise src.fail(f"cyclic-symmetry modes (nodal diameter {harmonic}); solve the full wheelset "
                                   f"or expand the sector (*CYCLIC SYMMETRY MODEL) and export real modes")
                if step is None:
                    raise src.fail("a mode's result header without its 1PSTEP record before it")
                current = _Mode(step, number if number is not None else numstep, value, mass, src.i)
                modes.append(current)
        elif text.startswith(" -4"):
            name, ids, vals = _result_block(src, text, src.i, width)
            if current is not None and name in ("DISPI", "PDISP"):
                raise src.fail(f"complex modes ({name} block: a *COMPLEX FREQUENCY step); export the real modes "
                               f"of a *FREQUENCY step")
            if current is not None and name == "DISP":
                if current.nodes is not None:
                    raise src.fail(f"mode {current.number} has two DISP blocks")
                if vals.shape[1] < 3:
                    raise src.fail(f"mode {current.number}: its DISP block holds {vals.shape[1]} components, not 3")
                current.nodes, current.values = ids, vals[:, :3]
        elif text.startswith(" -"):
            # a data record outside any block: its block's header was lost
            raise src.fail(f"record {text[:3].strip()!r} outside a block (its block header is missing: a damaged "
                           f"file?)")
        src.i += 1
    if not ended:
        raise src.fail("the file does not end with its ' 9999' record: it is cut short (a copy or a run that did "
                       "not finish)", len(lines) - 1)
    return node_ids, xyz, elements, modes


def read_frd(path: str, *, subcase: int | str | None = None) -> FEModes:
    """Read the modes of a CalculiX ``*FREQUENCY`` step from its ``.frd`` result file (module docstring).

    Parameters
    ----------
    path : str
        The file.
    subcase : int, "lowest" or None, optional
        The analysis step to read when the file holds several frequency steps: None requires one, ``"lowest"``
        reads the lowest with a WARNING naming the others.

    Returns
    -------
    FEModes
        The modes in the file's order, 3 DOF per node, mass-normalised (``1PGM`` divided out), the ``1PMODE``
        numbers kept, with the node coordinates and elements of the file; units as read (SI assumed).

    Raises
    ------
    FEReadError
        No node block, no frequency step with displacements, complex or cyclic-symmetry modes, several steps
        without ``subcase``, a record cut short or not a number (names the line), a mode whose nodes are not the
        file's, or a generalized mass that is not positive.
    """
    path = str(path)
    with open(path, encoding="latin-1", newline=None) as fh:
        lines = fh.read().split("\n")
    node_ids, xyz, elements, modes = _parse(path, lines)
    if node_ids is None:
        raise FEReadError(path, "no node block ('    2C'): not a CalculiX result file, or one cut before its nodes")
    with_disp = [m for m in modes if m.nodes is not None]
    if not with_disp:
        raise FEReadError(path, "no frequency step with displacements: request them in the *FREQUENCY step "
                                "(*NODE FILE with U)")
    bare = [m.number for m in modes if m.nodes is None]
    if bare:
        raise FEReadError(path, f"mode(s) {bare[:10]} have no displacement block (a file cut short, or a request "
                                f"without U)", line=modes[0].line + 1)
    chosen = choose_step(path, [m.step for m in with_disp], subcase, "frequency step")
    with_disp = [m for m in with_disp if m.step == chosen]
    numbers = [m.number for m in with_disp]
    if numbers != list(range(1, len(numbers) + 1)):
        gaps = sorted(set(range(1, max(numbers) + 1)) - set(numbers))
        raise FEReadError(path, f"frequency step {chosen}: the modes are numbered {numbers[:12]}"
                                f"{' ...' if len(numbers) > 12 else ''}, not one after the other"
                                + (f" (mode(s) {gaps[:5]} missing: a damaged file?)" if gaps else ""))
    row = {n: k for k, n in enumerate(node_ids.tolist())}
    shapes = np.zeros((len(with_disp), node_ids.size, 3))
    for k, m in enumerate(with_disp):
        missing = set(row) - set(m.nodes.tolist())
        unknown = set(m.nodes.tolist()) - set(row)
        if missing or unknown:
            what = (f"lacks {len(missing)} of the file's nodes (first {sorted(missing)[:5]})" if missing else
                    f"has {len(unknown)} node(s) the node block lacks (first {sorted(unknown)[:5]})")
            raise FEReadError(path, f"mode {m.number}: its DISP block {what}", line=m.line + 1)
        shapes[k, [row[n] for n in m.nodes.tolist()]] = m.values
    masses = np.array([m.mass for m in with_disp])
    if np.any(~(masses > 0)):
        k = int(np.argmax(~(masses > 0)))
        raise FEReadError(path, f"mode {numbers[k]} has generalized mass {masses[k]!r} (1PGM); it must be positive")
    history = [f"read {len(with_disp)} modes ({numbers[0]}..{numbers[-1]}, step {chosen}) on {node_ids.size} nodes "
               f"from CalculiX result file {path}"]
    other = np.flatnonzero(np.abs(masses - 1.0) > 1e-4)
    if other.size:
        shapes /= np.sqrt(masses)[:, None, None]
        history.append("normalised to unit modal mass (phi / sqrt(m), the 1PGM generalized mass): "
                       + ", ".join(f"mode {numbers[k]} m={masses[k]:g}" for k in other[:20]))
    if not np.all(np.isfinite(shapes)) or not all(math.isfinite(m.freq) for m in with_disp):
        raise FEReadError(path, "non-finite frequencies or shapes")
    ids = set(row)
    kept = [e for e in elements if set(e.nodes) <= ids]
    if len(kept) < len(elements):
        history.append(f"{len(elements) - len(kept)} element(s) on nodes outside the node block left out")
        log.warning("%s: %d element(s) use nodes the node block lacks; left out", path, len(elements) - len(kept))
    return FEModes(node_ids=node_ids, xyz=xyz, elements=tuple(kept),
                   freqs_hz=np.array([m.freq for m in with_disp]), shapes=shapes,
                   modal_mass=np.ones(len(with_disp)), source=path, format="calculix-frd",
                   units="SI (m, kg, s) assumed (a CalculiX result states no units)", history=tuple(history),
                   mode_numbers=np.asarray(numbers, np.int64))


register_format("calculix-frd", patterns=("*.frd", "*.FRD"), sniff=sniff_frd, reader=read_frd, geometry=None,
                aliases=("frd", "calculix"), description="CalculiX / CGX ASCII result file, *FREQUENCY step modes")
