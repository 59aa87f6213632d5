"""Fortran number fields and layout quirks in ASCII universal files, evened out before pyuff reads them.

Universal files are written by Fortran programs: a double-precision number
may carry a ``D`` exponent (``1.25D+02``, legal in every UFF dataset and the
way this project's own dataset 2411 is written); a number whose exponent
has three digits is written without the exponent letter by ``Ew.d``
(``0.12000-100`` for 1.2e-101); a value too large for its edit descriptor
is written as asterisks (``*************``). pyuff reads ``D`` exponents in
datasets 164 and 2411, but not in the records of datasets 55 and 58 it
parses with ``float``/``numpy``, where all three end in its bare "Error when
reading data-set(s)". Card-image exports also pad lines with blanks to 80
columns, and editors leave trailing blanks: pyuff then misses a ``    -1``
delimiter followed by blanks (it accepts none or exactly 74), and cuts a
padded dataset 55 value line into too many 13-column fields.

:func:`prepare_for_pyuff` looks at the file before pyuff does:

* an overflow field is reported as a :class:`FortranFieldProblem` naming the
  dataset, the record, the file line and the field (the value is lost: the
  writer must use a wider format; :func:`fortran_field_problem`);
* in a temporary copy of the file, which pyuff then reads (same datasets,
  same lines, same order): ``D`` exponents and letterless 3-digit exponents
  in the numeric records of datasets 55 and 58 get an ``E`` (the field keeps
  its width: the blank before it is used), and trailing blanks are removed
  from the delimiter lines, the dataset-number lines and the lines of
  datasets 55.

Binary datasets (58b) are left alone: their data are bytes, not text. The
readers (:mod:`fem_import.uff`, :mod:`ema.hammer_io`) raise their own error
types with the problem's text; when pyuff fails anyway, :func:`unreadable_field`
names the first field that is not a number, or not in the fixed columns
the dataset's format requires (free-format numbers separated by blanks).
"""

from __future__ import annotations

import contextlib
import logging
import os
import re
import tempfile
from dataclasses import dataclass
from typing import Callable, Iterator, Sequence

__all__ = ["FortranFieldProblem", "DatasetSpan", "fortran_field_problem", "fortran_float", "prepare_for_pyuff",
           "unreadable_field"]

log = logging.getLogger("fem_import")

_D_EXP = re.compile(rb"(\d\.?\d*)[Dd]([+-]?\d)")
_OVERFLOW = re.compile(rb"\*{3,}")
# a Fortran Ew.d field of a number with a 3-digit exponent: no exponent letter (' 0.12000-100')
_F3_EXP = re.compile(rb"(^|[ \t])([+-]?(?:\d+\.\d*|\.\d+))([+-]\d{3})(?=[ \t\r\n]|$)", re.M)
_F3_TOKEN = re.compile(r"([+-]?(?:\d+\.\d*|\.\d+))([+-]\d{3})")
_TRAILING = re.compile(rb"[ \t]+(?=\r?\n|\r|$)")


def fortran_float(text: str) -> float:
    """A Fortran real: ``1.5E-3``, ``1.5D-3``, and ``0.12000-100`` (Ew.d of a 3-digit exponent) = 1.2e-101.

    Raises
    ------
    ValueError
        Not a number.
    """
    t = text.strip().replace("D", "E").replace("d", "e")
    m = _F3_TOKEN.fullmatch(t)
    if m:
        t = f"{m.group(1)}E{m.group(2)}"
    return float(t)


# quick scan of a whole dataset: digits -> '9', '-' -> '+', 'd' -> 'D'; then plain substring searches
_SHAPES = bytes.maketrans(b"0123456789-d", b"9999999999+D")


def _suspects(block: bytes) -> tuple[bool, bool]:
    """(an overflow field may be there, a D or letterless 3-digit exponent may be there), by substring search.

    A fast filter over large ASCII datasets: only a block it flags is searched line by line with the exact
    patterns.
    """
    shapes = block.translate(_SHAPES)
    return b"***" in block, (b"D+9" in shapes or b"D9" in shapes or b"9+999" in shapes)


def _f3_fix(m: re.Match) -> bytes:
    # the blank before the field makes room for the 'E': the field keeps its width (pyuff cuts fixed columns)
    return m.group(2) + b"E" + m.group(3)


@dataclass(frozen=True)
class DatasetSpan:
    """One dataset of a universal file: its type, whether binary, its 1-based number, and its byte span.

    ``start`` is the offset of the line holding the dataset number (after the
    opening ``    -1``), ``end`` the offset of the closing ``    -1``.
    """

    number: int
    set_type: int
    binary: bool
    start: int
    end: int


@dataclass(frozen=True)
class FortranFieldProblem:
    """An unreadable numeric field: where it is and why."""

    dataset: int
    set_type: int
    record: int
    line: int
    field: str
    cause: str

    def __str__(self) -> str:
        return (f"dataset {self.dataset} (type {self.set_type}), record {self.record} (line {self.line}): field "
                f"{self.field!r}: {self.cause}")


def _numeric_records(set_type: int, record: int) -> bool:
    """Records that hold numbers only (1-based after the dataset-number line)."""
    if set_type == 55:
        return record >= 6  # records 1-5 are ID text
    if set_type == 58:
        return record == 7 or record >= 12  # 1-5 ID text, 6 and 8-11 mix labels with integers
    return False


def _lines(data: bytes, span: DatasetSpan):
    """(record number, absolute line start offset, line bytes) of the dataset's records."""
    pos = data.find(b"\n", span.start)
    pos = span.end if pos < 0 else pos + 1  # skip the dataset-number line
    record = 0
    while pos < span.end:
        e = data.find(b"\n", pos, span.end)
        e = span.end if e < 0 else e + 1
        record += 1
        yield record, pos, data[pos:e]
        pos = e


def fortran_field_problem(data: bytes, spans: Sequence[DatasetSpan]) -> tuple[FortranFieldProblem | None, bool]:
    """The first overflow field of an ASCII dataset 55/58 (or None), and whether any ``D`` or letterless
    3-digit exponent needs fixing."""
    needs_fix = False
    for span in spans:
        if span.binary or span.set_type not in (55, 58):
            continue
        has_star, has_d = _suspects(data[span.start:span.end])
        if not (has_star or has_d):
            continue
        for record, pos, line in _lines(data, span):
            if not _numeric_records(span.set_type, record):
                continue
            m = _OVERFLOW.search(line)
            if m is not None:
                # the field is the run of non-blank characters around the asterisks
                lo = line.rfind(b" ", 0, m.start()) + 1
                hi = line.find(b" ", m.end())
                field = line[lo:hi if hi >= 0 else len(line)].strip().decode("latin-1")
                return FortranFieldProblem(
                    span.number, span.set_type, record, data.count(b"\n", 0, pos) + 1, field,
                    "asterisks are a Fortran overflow: the value did not fit its field when the file was written, "
                    "so it is lost; write the file with a wider format"), needs_fix
            if _D_EXP.search(line) is not None or _F3_EXP.search(line) is not None:
                needs_fix = True
    return None, needs_fix


_NUMBER_RUN = re.compile(rb"\s*[-+]?(?:\d+\.?\d*|\.\d+)(?:[EeDd][-+]?\d+|[-+]\d{3}(?!\d))?")
_REAL = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[EeDd][-+]?\d+|[-+]\d{3})?")


def _layout(data: bytes, span: DatasetSpan) -> tuple[tuple[int, ...], str, str, Callable[[int], bool]] | None:
    """Field widths of a dataset's value records, the format's name, what asks for it, and which records hold values."""
    if span.set_type == 55:
        return (13,), "6E13.5", "dataset 55", lambda r: r >= 10 and r % 2 == 0
    if span.set_type != 58:
        return None
    rec7 = next((line for record, _, line in _lines(data, span) if record == 7), b"")
    try:
        ordinate, spacing = int(rec7[0:10]), int(rec7[20:30])
    except ValueError:
        return None
    what = f"ordinate data type {ordinate} with {'even' if spacing == 1 else 'uneven'} abscissa spacing"
    if ordinate in (2, 5):
        return (13,), "6E13.5", what, lambda r: r >= 12
    if ordinate == 4:
        return ((20,), "4E20.12", what, lambda r: r >= 12) if spacing == 1 else \
            ((13, 20), "2(E13.5,E20.12)", what, lambda r: r >= 12)
    if ordinate == 6:
        return ((20,), "4E20.12", what, lambda r: r >= 12) if spacing == 1 else \
            ((13, 20, 20), "E13.5,2E20.12", what, lambda r: r >= 12)
    return None


def _fixed_column_problem(data: bytes, span: DatasetSpan) -> FortranFieldProblem | None:
    """The first value field that is not a number at the fixed columns of the dataset's format (or None)."""
    layout = _layout(data, span)
    if layout is None:
        return None
    widths, fmt, what, holds_values = layout
    for record, pos, line in _lines(data, span):
        if not holds_values(record):
            continue
        body = line.rstrip(b" \t\r\n").decode("latin-1")
        col, k = 0, 0
        while col < len(body):
            w = widths[k % len(widths)]
            field = body[col:col + w]
            if not _REAL.fullmatch(field.strip()) or (len(field) == w and field[-1] == " "):
                return FortranFieldProblem(
                    span.number, span.set_type, record, data.count(b"\n", 0, pos) + 1, field,
                    f"the values are not in the fixed columns of the format {fmt} that {what} requires: columns "
                    f"{col + 1}-{col + w} read {field!r}, not one number; free-format numbers (separated by blanks) "
                    f"cannot be read: write each value right-aligned in its {w}-column field")
            col += w
            k += 1
    return None


def unreadable_field(data: bytes, span: DatasetSpan) -> FortranFieldProblem | None:
    """The first numeric record of an ASCII dataset 55/58 holding something that is not a number (or None).

    Used to explain a reader's failure: numeric records are runs of Fortran
    numbers, adjacent or separated by blanks; the first character that does
    not continue such a run is reported with the text around it. When every
    character belongs to a number, the value records are checked against the
    fixed columns of the dataset's format (55: 6E13.5; 58: 6E13.5, 4E20.12
    or 2(E13.5,E20.12) by the ordinate data type of record 7): numbers in
    free format are named so.
    """
    if span.binary or span.set_type not in (55, 58):
        return None
    for record, pos, line in _lines(data, span):
        if not _numeric_records(span.set_type, record):
            continue
        body = line.rstrip(b"\r\n")
        k = 0
        while k < len(body):
            m = _NUMBER_RUN.match(body, k)
            if m is None or m.end() == k:
                if not body[k:].strip():
                    break
                lo, hi = max(0, k - 6), min(len(body), k + 7)
                return FortranFieldProblem(
                    span.number, span.set_type, record, data.count(b"\n", 0, pos) + 1,
                    body[lo:hi].decode("latin-1"),
                    f"{body[k:k + 1].decode('latin-1')!r} at column {k + 1} is not part of a number")
            k = m.end()
    return _fixed_column_problem(data, span)


def _line_of(data: bytes, pos: int) -> tuple[int, int]:
    """(start, end) of the line holding offset ``pos`` (end after its line break)."""
    start = data.rfind(b"\n", 0, pos) + 1
    e = data.find(b"\n", pos)
    return start, len(data) if e < 0 else e + 1


def _fix_records(block: bytes, set_type: int) -> tuple[bytes, int]:
    """``block`` (a dataset from its number line) with D and letterless 3-digit exponents of its numeric records
    as E; and how many were fixed."""
    out = bytearray()
    n_fixed = 0
    pos = block.find(b"\n")
    pos = len(block) if pos < 0 else pos + 1
    out += block[:pos]
    record = 0
    while pos < len(block):
        e = block.find(b"\n", pos)
        e = len(block) if e < 0 else e + 1
        line = block[pos:e]
        record += 1
        if _numeric_records(set_type, record):
            line, a = _D_EXP.subn(rb"\1E\2", line)
            line, b = _F3_EXP.subn(_f3_fix, line)
            n_fixed += a + b
        out += line
        pos = e
    return bytes(out), n_fixed


@contextlib.contextmanager
def prepare_for_pyuff(path: str | os.PathLike, data: bytes, spans: Sequence[DatasetSpan]) -> Iterator[str]:
    """The path pyuff should read: ``path`` itself, or a temporary copy with the quirks evened out.

    The copy (module docstring) has ``D`` and letterless 3-digit exponents
    of the numeric records of datasets 55/58 as ``E``, and no trailing blanks
    on delimiter lines, dataset-number lines and the lines of datasets 55;
    it has the same datasets and lines, so line numbers of the original hold.
    Call :func:`fortran_field_problem` first for overflow fields. The
    temporary copy is removed when the block ends.
    """
    _, needs_fix = fortran_field_problem(data, [s for s in spans])
    ascii_spans = [s for s in spans if not s.binary]
    strip = any(_TRAILING.search(data, *_line_of(data, s.start)) is not None for s in ascii_spans)
    gaps, pos = [], 0
    for span in sorted(spans, key=lambda s: s.start):
        gaps.append((pos, span.start))
        pos = span.end
    gaps.append((pos, len(data)))
    strip = strip or any(_TRAILING.search(data[lo:hi]) is not None for lo, hi in gaps)
    strip = strip or any(_TRAILING.search(data[s.start:s.end]) is not None for s in ascii_spans if s.set_type == 55)
    if not (needs_fix or strip):
        yield os.fspath(path)
        return
    out = bytearray()
    n_fixed = 0
    for (lo, hi), span in zip(gaps, sorted(spans, key=lambda s: s.start) + [None]):
        out += _TRAILING.sub(b"", data[lo:hi])
        if span is None:
            break
        block = data[span.start:span.end]
        if not span.binary:
            head_end = block.find(b"\n") + 1 or len(block)
            block = _TRAILING.sub(b"", block[:head_end]) + block[head_end:]
            if span.set_type == 55:
                block = _TRAILING.sub(b"", block)
            if needs_fix and span.set_type in (55, 58):
                block, n = _fix_records(block, span.set_type)
                n_fixed += n
        out += block
    fd, tmp = tempfile.mkstemp(suffix=".uff", prefix="railmodal-uff-")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(bytes(out))
        if n_fixed:
            log.info("%s: %d Fortran D or 3-digit exponents in datasets 55/58 read as E", os.fspath(path), n_fixed)
        yield tmp
    finally:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
