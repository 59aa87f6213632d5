"""Fortran number fields in ASCII universal-file datasets: ``D`` exponents and ``*****`` overflows.

Universal files are written by Fortran programs: a double-precision number
may carry a ``D`` exponent (``1.25D+02``, legal in every UFF dataset and the
way this project's own dataset 2411 is written), and a value too large for
its edit descriptor is written as asterisks (``*************``). pyuff reads
``D`` exponents in datasets 164 and 2411, but not in the records of datasets
55 and 58 it parses with ``float``/``numpy``, where both end in its bare
"Error when reading data-set(s)".

:func:`prepare_for_pyuff` looks at the numeric records of every ASCII
dataset 55 and 58 before pyuff does:

* an overflow field is reported as a :class:`FortranFieldProblem` naming the
  dataset, the record, the file line and the field (the value is lost: the
  writer must use a wider format);
* ``D`` exponents are rewritten as ``E`` in those records of a temporary
  copy of the file, which pyuff then reads (same datasets, same order).

Binary datasets (58b) are left alone: their data are bytes, not text. The
readers (:mod:`fem_import.uff`, :mod:`ema.hammer_io`) raise their own error
types with the problem's text.
"""

from __future__ import annotations

import contextlib
import logging
import os
import re
import tempfile
from dataclasses import dataclass
from typing import Iterator, Sequence

__all__ = ["FortranFieldProblem", "DatasetSpan", "fortran_field_problem", "prepare_for_pyuff", "unreadable_field"]

log = logging.getLogger("fem_import")

_D_EXP = re.compile(rb"(\d\.?\d*)[Dd]([+-]?\d)")
_OVERFLOW = re.compile(rb"\*{3,}")


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
    """The first overflow field of an ASCII dataset 55/58 (or None), and whether any ``D`` exponent needs fixing."""
    needs_fix = False
    for span in spans:
        if span.binary or span.set_type not in (55, 58):
            continue
        block = data[span.start:span.end]
        has_star = _OVERFLOW.search(block) is not None
        has_d = _D_EXP.search(block) is not None
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
            if _D_EXP.search(line) is not None:
                needs_fix = True
    return None, needs_fix


_NUMBER_RUN = re.compile(rb"\s*[-+]?(?:\d+\.?\d*|\.\d+)(?:[EeDd][-+]?\d+)?")


def unreadable_field(data: bytes, span: DatasetSpan) -> FortranFieldProblem | None:
    """The first numeric record of an ASCII dataset 55/58 holding something that is not a number (or None).

    Used to explain a reader's failure: numeric records are runs of Fortran
    numbers, adjacent or separated by blanks; the first character that does
    not continue such a run is reported with the text around it.
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
    return None


@contextlib.contextmanager
def prepare_for_pyuff(path: str | os.PathLike, data: bytes, spans: Sequence[DatasetSpan]) -> Iterator[str]:
    """The path pyuff should read: ``path`` itself, or a temporary copy with ``D`` exponents of 55/58 as ``E``.

    Call :func:`fortran_field_problem` first for overflow fields; this only
    rewrites exponents. The temporary copy is removed when the block ends.
    """
    _, needs_fix = fortran_field_problem(data, [s for s in spans])
    if not needs_fix:
        yield os.fspath(path)
        return
    out = bytearray()
    pos = 0
    n_fixed = 0
    for span in spans:
        if span.binary or span.set_type not in (55, 58):
            continue
        for record, start, line in _lines(data, span):
            if not _numeric_records(span.set_type, record):
                continue
            fixed, n = _D_EXP.subn(rb"\1E\2", line)
            if n:
                out += data[pos:start]
                out += fixed
                pos = start + len(line)
                n_fixed += n
    out += data[pos:]
    fd, tmp = tempfile.mkstemp(suffix=".uff", prefix="railmodal-dexp-")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(bytes(out))
        log.info("%s: %d Fortran D exponents in datasets 55/58 read as E", os.fspath(path), n_fixed)
        yield tmp
    finally:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
