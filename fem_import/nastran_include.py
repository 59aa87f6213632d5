"""INCLUDE statements of a Nastran input deck: the included files' lines spliced in where the statement stands.

A model's bulk data is often split: a master deck with ``INCLUDE 'mesh.bdf'``
lines, the grids, coordinate systems and elements in the included files
(Quick Reference Guide, INCLUDE statement). The file name is quoted (single
quotes), may be continued over several lines (the characters inside the
quotes are joined, each line stripped), and may itself include others. A
relative name is looked up beside the including file, then beside the master
deck, then in the working directory (Nastran resolves it against the
directory it runs in, which is usually the deck's); on a case-sensitive file
system a name that differs only in case from one file of that folder is
taken as that file, and ``\\`` is read as ``/`` (decks written on Windows);
an absolute name of another machine is looked for by its file name beside
the including file, with a warning.

An included file that is not found is left as the INCLUDE statement it was:
the bulk data reader then says that its grids and elements are missing. A
file that includes itself, directly or through others, is refused.
"""

from __future__ import annotations

import bisect
import logging
import os
import re
from pathlib import Path

from .errors import FEReadError

__all__ = ["DeckLine", "DeckLines", "expand_includes"]

log = logging.getLogger("fem_import")

_INCLUDE = re.compile(r"^INCLUDE(?=$|[\s'\"])", re.IGNORECASE)
_INCLUDE_LINE = re.compile(r"^[ \t]*INCLUDE(?=$|[\s'\"])", re.IGNORECASE | re.MULTILINE)
#: Nesting deeper than this is taken as a runaway (a cycle through differently written names).
MAX_DEPTH = 32


class DeckLine(int):
    """A 1-based line number of the spliced deck that prints as the line of the file it came from.

    It compares and indexes as the position in the spliced list of lines; in
    messages (``str``, f-strings) it reads ``12`` for a line of the master
    deck and ``12 of mesh.bdf`` for one of an included file.
    """

    def __new__(cls, value: int, text: str):
        obj = super().__new__(cls, value)
        obj.text = text
        return obj

    def __str__(self) -> str:
        return self.text

    def __format__(self, spec: str) -> str:
        return self.text if not spec else int.__format__(int(self), spec)


def _statement(lines: list[str], i: int) -> tuple[str, int] | None:
    """``(file name, number of lines)`` of the INCLUDE statement at line ``i``, or None if that is none."""
    head = lines[i].lstrip()
    if not _INCLUDE.match(head):
        return None
    rest = head[7:].strip()
    if not rest.startswith(("'", '"')):  # unquoted: one token (NX accepts it)
        name = rest.split("$", 1)[0].split()
        return (name[0] if name else ""), 1
    quote, text, n = rest[0], rest[1:], 1
    while quote not in text and i + n < len(lines):
        text += lines[i + n].strip()
        n += 1
    return text.split(quote, 1)[0].strip(), n


def _candidates(name: str, including: Path, master: Path) -> list[Path]:
    raw = Path(os.path.expandvars(os.path.expanduser(name)))
    if raw.is_absolute():
        return [raw]
    return [including.parent / raw, master.parent / raw, Path.cwd() / raw]


def _locate(name: str, including: Path, master: Path) -> Path | None:
    """The file an INCLUDE names, or None if none of the places it may be in has it.

    A name written on Windows (``mesh\\bars.bdf``) is also tried with ``/``; an
    absolute one from another machine (``C:\\models\\mesh.bdf``, ``/home/...``)
    that does not exist here is looked for by its file name beside the
    including file (the deck's folder copied as a whole), with a warning.
    """
    names = [name] + ([name.replace("\\", "/")] if "\\" in name else [])
    places = [p for n in names for p in _candidates(n, including, master)]
    for p in places:
        if p.is_file():
            return p
    for p in places:  # a deck written where file names ignore case
        folder = p.parent
        if folder.is_dir():
            match = [q for q in folder.iterdir() if q.name.lower() == p.name.lower() and q.is_file()]
            if len(match) == 1:
                return match[0]
    foreign = re.match(r"^[A-Za-z]:[\\/]", name) or Path(name).is_absolute()
    if foreign:
        base = re.split(r"[\\/]", name)[-1]
        here = including.parent / base
        if base and here.is_file():
            log.warning("%s: INCLUDE '%s' does not exist here; %s, beside the including file, is read in its place",
                        master, name, here)
            return here
    return None


class DeckLines:
    """Per line of a spliced deck, its :class:`DeckLine` (made when asked: a deck may have millions of lines)."""

    def __init__(self, segments: list[tuple[int, str | None, int]]):
        self._starts = [seg[0] for seg in segments]
        self._segments = segments

    def __getitem__(self, i: int) -> DeckLine:
        k = bisect.bisect_right(self._starts, i) - 1
        start, label, local = self._segments[k]
        n = i - start + local + 1
        return DeckLine(i + 1, str(n) if label is None else f"{n} of {label}")


def _statement_lines(text: list[str], first: int) -> list[int]:
    """Indices (from ``first`` on) of the lines that start an INCLUDE statement, found in one pass over the text."""
    joined = "\n".join(text[first:])
    found, line, pos = [], first, 0
    for m in _INCLUDE_LINE.finditer(joined):
        line += joined.count("\n", pos, m.start())
        pos = m.start()
        found.append(line)
    return found


def expand_includes(path, lines: list[str], start: int) -> tuple[list[str], DeckLines | None, list[Path]]:
    """The deck's lines with every INCLUDE statement from line ``start`` on replaced by the file it names.

    Returns
    -------
    lines : list of str
        The spliced lines; a followed INCLUDE statement's own lines are blank.
    where : DeckLines or None
        Per spliced line, its 1-based number there, printing as the line of its own file; None when the
        deck has no INCLUDE statement (the lines are its own).
    included : list of Path
        The files read, in the order they were spliced in.

    Raises
    ------
    FEReadError
        A file includes itself (directly or through others), or one cannot be read.
    """
    master = Path(path)
    if not _statement_lines(lines, start):
        return lines, None, []
    out: list[str] = []
    segments: list[tuple[int, str | None, int]] = []  # (first spliced index, file label, its first local index)
    included: list[Path] = []

    def splice(file: Path, text: list[str], first: int, label: str | None, chain: tuple[Path, ...]) -> None:
        def keep(a: int, b: int, blank: bool = False) -> None:
            if a < b:
                segments.append((len(out), label, a))
                out.extend([""] * (b - a) if blank else text[a:b])

        done = 0
        for i in _statement_lines(text, first):
            if i < done:  # a line inside the quoted name of the statement before
                continue
            found = _statement(text, i)
            if found is None:
                continue
            name, n = found
            target = _locate(name, file, master) if name else None
            if target is None:  # left as written: the reader warns that what it holds is missing
                continue
            resolved = target.resolve()
            here = str(i + 1) if label is None else f"{i + 1} of {label}"
            if resolved in chain or len(chain) > MAX_DEPTH:
                raise FEReadError(master, f"INCLUDE '{name}' includes a file that includes it: "
                                          f"{' -> '.join(p.name for p in chain + (resolved,))}", line=here)
            try:
                body = target.read_text(encoding="latin-1").splitlines()
            except OSError as exc:
                raise FEReadError(master, f"INCLUDE '{name}': {target} cannot be read ({exc})", line=here) from None
            keep(done, i)
            keep(i, i + n, blank=True)
            included.append(target)
            splice(target, body, 0, name, chain + (resolved,))
            done = i + n
        keep(done, len(text))

    splice(master, lines, start, None, (master.resolve(),))
    if included:
        log.info("%s: %d INCLUDE file(s) read: %s", master, len(included), ", ".join(p.name for p in included[:5]))
    return out, DeckLines(segments), included
