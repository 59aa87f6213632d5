"""Choosing one of a result file's solutions: an ANSYS load step, a CalculiX analysis step.

A file may hold the modes of several solutions (modal analyses after different prestress, a free and a
supported run). The readers take ``subcase=`` as Nastran's readers do (:func:`fem_import.nastran_modes.select_subcase`):
None requires a single solution, ``"lowest"`` reads the lowest with a WARNING naming the others (what
:func:`fem_import.read_with_geometry` passes), a number reads that one.
"""

from __future__ import annotations

import logging

from .errors import FEReadError

__all__ = ["choose_step"]

log = logging.getLogger("fem_import")


def choose_step(path: str, steps, subcase, word: str) -> int:
    """The solution to read among ``steps`` (their numbers); ``word`` names them in messages ("load step").

    Raises
    ------
    FEReadError
        Several solutions and ``subcase=None`` (names them), or a number the file does not hold.
    """
    steps = sorted(set(int(s) for s in steps))
    if subcase is None or (isinstance(subcase, str) and subcase == "lowest"):
        if len(steps) > 1:
            if subcase is None:
                raise FEReadError(path, f"{len(steps)} {word}s ({steps}); choose one (subcase=)")
            log.warning("%s: %d %ss %s; reading the lowest, %d", path, len(steps), word, steps, steps[0])
        return steps[0]
    try:
        step = int(subcase)
    except (TypeError, ValueError):
        raise FEReadError(path, f"subcase={subcase!r} is not a {word} number; the file has {steps}") from None
    if step not in steps:
        raise FEReadError(path, f"no {word} {step}; the file has {steps}")
    return step
