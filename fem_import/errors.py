"""Exceptions of :mod:`fem_import`.

All are :class:`ValueError` subclasses so that callers that only know "bad
input" can catch them generically; each message names the file (or point),
the dataset/line or node where known, what was expected and what was found.
"""

from __future__ import annotations

__all__ = ["FEImportError", "UnknownFormatError", "FEReadError", "FEGeometryError",
           "MissingCoordinatesError", "PointToleranceError"]


class FEImportError(ValueError):
    """Base class of the errors raised by :mod:`fem_import`."""


class UnknownFormatError(FEImportError):
    """The format of a file could not be detected, or a format name is not registered.

    Attributes
    ----------
    path : str or None
        The file concerned (None when only a format name was bad).
    supported : tuple of str
        Names of the registered formats.
    """

    def __init__(self, message: str, *, path: str | None = None, supported: tuple[str, ...] = ()):
        super().__init__(message)
        self.path = path
        self.supported = tuple(supported)


class FEReadError(FEImportError):
    """A file of a known format is truncated, corrupt or not supported by its reader.

    Attributes
    ----------
    path : str
        The file.
    dataset : str or None
        Dataset / block concerned (e.g. ``"2411"``, ``"55 (mode 3)"``), if known.
    line : int or None
        1-based line number in the file, if known.
    """

    def __init__(self, path, message: str, *, dataset: str | None = None, line: int | None = None):
        where = [str(path)]
        if dataset is not None:
            where.append(f"dataset {dataset}")
        if line is not None:
            where.append(f"line {line}")
        super().__init__(f"{', '.join(where)}: {message}")
        self.path = str(path)
        self.dataset = dataset
        self.line = line


class FEGeometryError(FEImportError):
    """A point or element cannot be placed on the FE model (unknown node, bad direction...)."""


class MissingCoordinatesError(FEGeometryError):
    """Node coordinates are needed but the modes were read without geometry (they are NaN)."""


class PointToleranceError(FEGeometryError):
    """A point lies farther from its FE node (or from any node) than the allowed tolerance."""
