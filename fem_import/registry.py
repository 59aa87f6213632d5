"""Format registry and :func:`read`, after ObsPy's ``read()`` plugins.

A reader registers a name, file-name patterns and a *sniffing* function that
looks at the first bytes of a file; :func:`read` with ``format=None`` asks the
sniffers (those whose patterns match the file name first, but the content
decides, not the extension) and calls the first reader that recognises the
file.  Readers return an :class:`~fem_import.modes.FEModes`.

A reader may also provide a *geometry* function (nodes and elements only):
it is what ``read(..., geometry=path)`` uses to add coordinates and elements
to modes read from a file that has none (a Nastran punch file).
"""

from __future__ import annotations

import dataclasses
import fnmatch
import inspect
import logging
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import FEReadError, UnknownFormatError
from .modes import UNIT_SYSTEMS, Element, FEModes

__all__ = ["FormatInfo", "Geometry", "register_format", "unregister_format", "formats", "format_info",
           "detect_format", "read", "read_geometry", "merge_geometry", "find_geometry_companion",
           "read_with_geometry", "COMPANION_SUFFIXES"]

log = logging.getLogger("fem_import")

#: Nastran result files: eigenvectors in each grid's displacement system (CD), subcases
NASTRAN_RESULTS = ("nastran-punch", "nastran-f06", "nastran-op2", "nastran-h5")
#: Files holding several solutions, read with ``subcase=`` (Nastran subcases, ANSYS load steps)
SUBCASE_FORMATS = NASTRAN_RESULTS + ("ansys-rst", "calculix-frd")
#: Number of leading bytes handed to the sniffing functions.
SNIFF_BYTES = 4096
#: What the built-in formats are recognised by (for messages).
HOW_RECOGNISED = ("a universal file starts with a '    -1' line and a dataset number; a Nastran punch file with a "
                  "header card such as '$TITLE' or '$EIGENVECTOR'; a Nastran print file (.f06) by its spaced-letter "
                  "headings and page numbers, or the copyright banner it opens with; a Nastran bulk deck with "
                  "executive or case control "
                  "(NASTRAN, ASSIGN, SOL, CEND, ...) or bulk entries (BEGIN BULK, PARAM, CORD2R, GRID, ...; a "
                  ".bdf/.dat/.nas/.blk file with a GRID card in its first 4 kB); an ANSYS result file (.rst) by its "
                  "binary standard header (file number 12); a CalculiX result file (.frd) by its '    1C' opening "
                  "record; a Nastran OP2 file by its 'NASTRAN FORT TAPE ID CODE' header record; an MSC Nastran HDF5 "
                  "file by the HDF5 signature and a NASTRAN group (or the .h5 name).")


@dataclass(frozen=True, eq=False)
class Geometry:
    """Nodes and elements of an FE mesh, without modes (what ``geometry=`` merges in).

    Parameters
    ----------
    node_ids : ndarray of int (n,)
    xyz : ndarray (n, 3)
        Coordinates [m].
    elements : tuple of Element
    source : str
        File the geometry was read from.
    units : str
    displacement_frames : ndarray (n, 3, 3), optional
        Per node, the unit vectors (columns, in the global system) of the directions its mode-shape components are
        given in (a Nastran grid's ``CD`` system); None: every node's are the global axes.
    """

    node_ids: np.ndarray
    xyz: np.ndarray
    elements: tuple[Element, ...]
    source: str = ""
    units: str = "SI (m, kg, s)"
    displacement_frames: np.ndarray | None = None


@dataclass(frozen=True)
class FormatInfo:
    """A registered file format.

    Parameters
    ----------
    name : str
        Format name, the ``format=`` value of :func:`read` (lower case).
    patterns : tuple of str
        ``fnmatch`` patterns of usual file names (``"*.uff"``); they only
        order the sniffers, the content decides.
    sniff : callable(bytes) -> bool or callable(bytes, str) -> bool
        Gets the first :data:`SNIFF_BYTES` bytes (and, if it takes a second
        argument, the file name, for content rules that hold only for some
        file names); True if the content is of this format.  Must not raise.
    reader : callable(path, **kwargs) -> FEModes
    geometry : callable(path) -> Geometry, optional
        Reads nodes and elements only; None if the format carries no geometry.
    description : str
    aliases : tuple of str
        Other accepted names for ``format=``.
    sniff_takes_name : bool
        Whether ``sniff`` is called with the file name too (set by
        :func:`register_format` from its signature).
    """

    name: str
    patterns: tuple[str, ...]
    sniff: Callable[..., bool]
    reader: Callable[..., FEModes]
    geometry: Callable[[str], Geometry] | None = None
    description: str = ""
    aliases: tuple[str, ...] = ()
    sniff_takes_name: bool = False

    def sniffs(self, head: bytes, name: str = "") -> bool:
        """Whether the sniffing function accepts ``head`` (the first bytes of the file called ``name``)."""
        return bool(self.sniff(head, name) if self.sniff_takes_name else self.sniff(head))


_REGISTRY: dict[str, FormatInfo] = {}
_BUILTINS_LOADED = False


def _load_builtins() -> None:
    global _BUILTINS_LOADED
    if not _BUILTINS_LOADED:
        _BUILTINS_LOADED = True
        # they register themselves, in this order
        from . import uff, punch, nastran_bulk, ansys_rst, calculix_frd, nastran_op2, nastran_h5  # noqa: F401


def register_format(name: str, *, patterns, sniff, reader, geometry=None, description: str = "",
                    aliases=(), replace: bool = False) -> FormatInfo:
    """Register a reader.

    Parameters
    ----------
    name : str
        Format name (stored lower case).
    patterns : sequence of str
        File-name patterns, e.g. ``("*.pch", "*.punch")``.
    sniff : callable(bytes) -> bool or callable(bytes, str) -> bool
        Content test on the first :data:`SNIFF_BYTES` bytes; a function of
        two arguments also gets the file name.
    reader : callable(path, **kwargs) -> FEModes
    geometry : callable(path) -> Geometry, optional
    description : str, optional
    aliases : sequence of str, optional
    replace : bool, optional
        Allow replacing an already registered format of the same name.

    Returns
    -------
    FormatInfo

    Raises
    ------
    ValueError
        If ``name`` (or an alias) is already registered and ``replace`` is False.
    """
    key = str(name).strip().lower()
    if not key:
        raise ValueError("register_format: name must be a non-empty string")
    info = FormatInfo(key, tuple(str(p).lower() for p in patterns), sniff, reader, geometry, description,
                      tuple(str(a).lower() for a in aliases), _takes_name(sniff))
    if not replace:
        taken = {n for i in _REGISTRY.values() for n in (i.name, *i.aliases)}
        clash = sorted(taken & {key, *info.aliases})
        if clash:
            raise ValueError(f"register_format: format name(s) {clash} already registered; pass replace=True")
    _REGISTRY[key] = info
    return info


def _takes_name(sniff) -> bool:
    """Whether a sniffing function takes a second positional argument (the file name)."""
    try:
        params = list(inspect.signature(sniff).parameters.values())
    except (TypeError, ValueError):
        return False
    positional = [p for p in params if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
    return len(positional) >= 2 or any(p.kind == p.VAR_POSITIONAL for p in params)


def unregister_format(name: str) -> FormatInfo:
    """Remove a registered format (by name or alias) and return its :class:`FormatInfo`.

    Raises
    ------
    UnknownFormatError
        If no format has that name.
    """
    info = format_info(name)
    del _REGISTRY[info.name]
    return info


def formats() -> tuple[str, ...]:
    """Names of the registered formats, in registration order.

    Returns
    -------
    tuple of str
        E.g. ``("uff", "nastran-punch")``.
    """
    _load_builtins()
    return tuple(_REGISTRY)


def _describe() -> str:
    return "; ".join(f"{i.name} ({', '.join(i.patterns)})" for i in _REGISTRY.values())


def format_info(name: str) -> FormatInfo:
    """The :class:`FormatInfo` of a format name or alias (case-insensitive).

    Raises
    ------
    UnknownFormatError
        If no format has that name; the message lists the supported ones.
    """
    _load_builtins()
    key = str(name).strip().lower()
    for info in _REGISTRY.values():
        if key == info.name or key in info.aliases:
            return info
    raise UnknownFormatError(f"unknown format {name!r}; supported formats: {_describe()}",
                             supported=tuple(_REGISTRY))


def _check_file(path) -> Path:
    p = Path(os.fspath(path))
    if not p.exists():
        raise FileNotFoundError(2, f"FE file not found: {p}", str(p))
    if p.is_dir():
        raise IsADirectoryError(21, f"expected an FE file, got a directory: {p}", str(p))
    return p


def detect_format(path) -> FormatInfo:
    """Sniff the format of ``path`` from its first bytes.

    Formats whose file-name patterns match are asked first; the first whose
    sniffing function accepts the content wins.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    UnknownFormatError
        If no registered format recognises the content; the message names
        the file and lists the supported formats.
    """
    _load_builtins()
    p = _check_file(path)
    with open(p, "rb") as fh:
        head = fh.read(SNIFF_BYTES)
    name = p.name.lower()
    infos = list(_REGISTRY.values())
    infos.sort(key=lambda i: not any(fnmatch.fnmatch(name, pat) for pat in i.patterns))
    for info in infos:
        try:
            ok = info.sniffs(head, p.name)
        except Exception as exc:  # a plugin's sniffer must not break detection of the others
            log.debug("sniffer of %s failed on %s: %r", info.name, p, exc)
            ok = False
        if ok:
            log.debug("%s: detected format %s", p, info.name)
            return info
    what = "empty file" if not head else "content not recognised"
    raise UnknownFormatError(
        f"{p}: unknown or undetectable FE file format ({what}); supported formats: {_describe()}. The format is "
        f"told from the content, whatever the file name: {HOW_RECOGNISED} To force a format, call "
        f"fem_import.read(path, format=NAME) (geometry: fem_import.read_geometry(path, format=NAME)) in Python; the "
        f"command line detects the format from the content only.",
        path=str(p), supported=tuple(_REGISTRY))


def read_geometry(path, format: str | None = None) -> Geometry:
    """Read nodes and elements (no modes) from a file of a format that carries geometry.

    Parameters
    ----------
    path : str or os.PathLike
    format : str, optional
        Format name; sniffed when None.

    Returns
    -------
    Geometry

    Raises
    ------
    UnknownFormatError
        If the format is unknown, or carries no geometry.
    FEReadError
        If the file is truncated or corrupt.
    """
    p = _check_file(path)
    info = format_info(format) if format is not None else detect_format(p)
    if info.geometry is None:
        with_geo = [i.name for i in _REGISTRY.values() if i.geometry is not None]
        raise UnknownFormatError(f"{p}: format {info.name!r} carries no node coordinates; "
                                 f"geometry can be read from: {with_geo}", path=str(p),
                                 supported=tuple(_REGISTRY))
    return info.geometry(str(p))


def _as_geometry(geometry) -> Geometry:
    if isinstance(geometry, Geometry):
        return geometry
    if isinstance(geometry, FEModes):
        return Geometry(geometry.node_ids, geometry.xyz, geometry.elements, geometry.source, geometry.units)
    if isinstance(geometry, (str, os.PathLike)):
        return read_geometry(geometry)
    raise TypeError(f"geometry must be a file path, an FEModes or a Geometry, got {type(geometry).__name__}")


def merge_geometry(modes: FEModes, geometry) -> FEModes:
    """Coordinates and elements of ``geometry`` on the nodes of ``modes``.

    Parameters
    ----------
    modes : FEModes
    geometry : str, os.PathLike, FEModes or Geometry
        Where the nodes and elements come from (a file is read with
        :func:`read_geometry`).

    Returns
    -------
    FEModes
        A new object: the nodes of ``modes`` in the order of the geometry's
        node list, their coordinates, and the geometry's elements whose nodes
        all have shapes (others are dropped with a logged warning); the shapes
        of nodes with a displacement frame (a Nastran grid's ``CD`` system)
        rotated to the global axes.

    Raises
    ------
    FEReadError
        If a node of ``modes`` is not in the geometry (names the first ones).
    """
    geo = _as_geometry(geometry)
    gids = np.asarray(geo.node_ids, np.int64)
    gxyz = np.asarray(geo.xyz, float)
    have = set(modes.node_ids.tolist())
    missing = sorted(have - set(gids.tolist()))
    if missing:
        raise FEReadError(geo.source or "geometry", f"{len(missing)} node(s) of the modes read from "
                          f"{modes.source or 'memory'} are not in the geometry, first: {missing[:10]}")
    keep = np.array([g in have for g in gids.tolist()], bool)
    ids = gids[keep]
    xyz = gxyz[keep]
    row = {n: k for k, n in enumerate(modes.node_ids.tolist())}
    order = np.array([row[n] for n in ids.tolist()], np.int64)
    shapes = modes.shapes[:, order, :]
    steps = []
    if geo.displacement_frames is not None:
        frames = np.asarray(geo.displacement_frames, float)[keep]
        local = np.flatnonzero(np.abs(frames - np.eye(3)).max(axis=(1, 2)) > 0)
        if local.size and modes.format not in NASTRAN_RESULTS:
            # a CD system says how Nastran punches a grid's components; another file states its own directions
            log.warning("%s: %d node(s) of the geometry %s have displacement coordinate systems (CD); the modes were "
                        "read from a %s file, whose components are taken as global, not rotated", modes.source,
                        local.size, geo.source, modes.format or "non-punch")
        elif local.size:
            # components along the node's own directions -> global: u = R u_local, for translations and rotations
            shapes = shapes.copy()
            for j in range(0, shapes.shape[2], 3):
                shapes[:, local, j:j + 3] = np.einsum("nab,mnb->mna", frames[local], shapes[:, local, j:j + 3])
            steps.append(f"mode shapes of {local.size} node(s) rotated from their displacement coordinate systems "
                         f"to the global one ({geo.source or 'geometry'})")
    elements = [e for e in geo.elements if all(n in have for n in e.nodes)]
    dropped = len(geo.elements) - len(elements)
    if dropped:
        log.warning("%s: %d element(s) of the geometry %s use nodes without mode shapes and were dropped",
                    modes.source, dropped, geo.source)
    step = f"geometry (coordinates, {len(elements)} elements) merged from {geo.source or 'memory'}"
    return dataclasses.replace(modes, node_ids=ids, xyz=xyz, elements=tuple(elements),
                               shapes=shapes, history=modes.history + (step,) + tuple(steps))


def read(path, format: str | None = None, *, geometry=None, **kwargs) -> FEModes:
    """Read FE normal modes from a file through the format registry.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    format : str, optional
        Format name or alias (see :func:`formats`): ``"uff"`` (alias
        ``"unv"``), ``"nastran-punch"`` (aliases ``"pch"``, ``"punch"``) or
        ``"nastran-f06"`` (alias ``"f06"``), ``"nastran-op2"`` (alias ``"op2"``), ``"nastran-bulk"``,
        ``"ansys-rst"``, ``"calculix-frd"``.
        None (default): sniffed from the content, whatever the extension.
    geometry : str, os.PathLike, FEModes or Geometry, optional
        Source of node coordinates and elements to merge in (needed for a
        Nastran punch file, which has none): see :func:`merge_geometry`.
    **kwargs
        Passed to the format's reader (e.g. ``subcase=`` for a punch file).

    Returns
    -------
    FEModes
        Mass-normalised modes in SI units.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist (the message names it).
    UnknownFormatError
        If ``format`` is not a registered name, or the content is not
        recognised; the message names the file and lists the formats.
    FEReadError
        If the file is truncated, corrupt or uses an unsupported feature; the
        message names the file and, where known, the dataset and line.

    Examples
    --------
    >>> import fem_import
    >>> modes = fem_import.read("fe_design.pch", geometry="fe_design.uff")  # doctest: +SKIP
    >>> modes.freqs_hz[6]  # doctest: +SKIP
    71.53...
    """
    from .checks import check_mode_values

    p = _check_file(path)
    info = format_info(format) if format is not None else detect_format(p)
    if geometry is not None and "echo" in inspect.signature(info.reader).parameters:
        # a given geometry replaces what the file echoes (a print file's bulk data): its CD systems rotate once
        kwargs.setdefault("echo", False)
    modes = info.reader(str(p), **kwargs)
    check_mode_values(modes, source=str(p))
    if geometry is not None:
        modes = merge_geometry(modes, geometry)
    log.info("read %d modes on %d nodes from %s (%s)", len(modes), modes.node_ids.size, p, info.name)
    return modes


#: File extensions of a geometry companion (same stem as the modes file), in order of preference.
COMPANION_SUFFIXES = (".bdf", ".dat", ".nas", ".blk", ".uff", ".unv")


def _companion_candidates(path) -> tuple[Path | None, list[tuple[Path, str]]]:
    """The first companion file that carries geometry, and the candidates passed over with the reason."""
    p = Path(os.fspath(path))
    rejected: list[tuple[Path, str]] = []
    seen: set[Path] = set()
    for suffix in COMPANION_SUFFIXES:
        for cand in (p.with_suffix(suffix), p.with_suffix(suffix.upper())):
            if cand == p or cand in seen or not cand.is_file():
                continue
            seen.add(cand)
            try:
                info = detect_format(cand)
            except UnknownFormatError:
                rejected.append((cand, "its content is not recognised as a Nastran bulk deck or a universal file ("
                                       + HOW_RECOGNISED.rstrip(".") + ")"))
                continue
            except OSError as exc:
                rejected.append((cand, f"it cannot be read ({exc})"))
                continue
            if info.geometry is None:
                rejected.append((cand, f"it is recognised as {info.name!r}, a format that carries no node "
                                       f"coordinates"))
                continue
            return cand, rejected
    return None, rejected


def find_geometry_companion(path) -> Path | None:
    """A file beside ``path`` with the same stem that carries node coordinates (``.bdf``, ``.dat``, ``.nas``,
    ``.blk``, ``.uff``, ``.unv``), or None.

    A candidate whose content is not recognised (or is of a format without
    geometry) is passed over; :func:`read_with_geometry` names such files.
    """
    return _companion_candidates(path)[0]


def read_with_geometry(path, geometry=None, *, option: str = "--geometry", subcase=None,
                       units: str | None = None) -> tuple[FEModes, str]:
    """FE modes with node coordinates: from the file itself, from ``geometry``, or from a companion file.

    This is how the command line reads an FE export (``--fem``, ``--geometry``).

    Parameters
    ----------
    path : str or os.PathLike
        The modes file (UFF, Nastran punch).
    geometry : str or os.PathLike, optional
        A file with node coordinates (UFF 2411 or Nastran bulk GRID cards)
        and elements (UFF 2412, Nastran element cards).
    option : str
        How the geometry is asked for on the command line, for the message.
    subcase : int, optional
        Nastran punch and print files: the subcase to read; an ANSYS result
        file: the load step. None (default): the only one, or the lowest
        with a WARNING naming the others when the file holds several
        (:func:`fem_import.punch.read_punch` with ``subcase="lowest"``;
        :func:`read` itself refuses to guess).
    units : str, optional
        The unit system of a file that does not state its units (a Nastran
        punch and bulk deck, a UFF without dataset 164): a key of
        :data:`fem_import.modes.UNIT_SYSTEMS` (``"mm-t-s"``...), applied to
        the modes and the merged geometry (:meth:`FEModes.in_si_units`).
        None: SI, as read. A file that states its units is refused with it
        (the file's own statement is converted already).

    Returns
    -------
    (FEModes, str)
        The modes and a note saying where the coordinates came from.

    Raises
    ------
    MissingCoordinatesError
        The modes file has no coordinates, none was given and no companion
        file was found: the message says which file is needed, and names a
        companion candidate that exists but was not recognised.
    """
    from .errors import MissingCoordinatesError

    p = Path(os.fspath(path))
    info = detect_format(p)
    kwargs = {}
    if info.name in SUBCASE_FORMATS:
        kwargs["subcase"] = "lowest" if subcase is None else subcase
    elif subcase is not None:
        raise UnknownFormatError(f"{p}: subcase={subcase!r} applies to Nastran punch and print files and ANSYS "
                                 f"result files (the load step); this file is "
                                 f"{info.name!r}", path=str(p), supported=tuple(_REGISTRY))
    if units is not None and units not in UNIT_SYSTEMS:
        raise ValueError(f"unknown FE unit system {units!r}; known: {', '.join(UNIT_SYSTEMS)}")

    def declared(fe: FEModes, where: str) -> tuple[FEModes, str]:
        if units is None:
            return fe, where
        from .checks import _units_stated

        if _units_stated(fe):
            raise FEReadError(p, f"the file states its units ({fe.units}), which the reader has converted to SI "
                                 f"already; the declared unit system {units!r} is for files that do not state them "
                                 f"(a Nastran punch and bulk deck, a UFF without dataset 164, an ANSYS result without "
                                 f"/UNITS whose materials do not tell): leave it out")
        return fe.in_si_units(units), f"{where}; units declared {units}, converted to SI"

    if geometry is not None:
        fe = read(p, info.name, geometry=geometry, **kwargs)
        return declared(fe, f"node coordinates from {geometry}")
    fe = read(p, info.name, **kwargs)
    if fe.has_coordinates:
        return declared(fe, f"node coordinates from {p.name}")
    companion, rejected = _companion_candidates(p)
    if companion is not None:
        log.info("%s has no node coordinates; using those of the companion file %s", p, companion)
        return declared(merge_geometry(fe, companion), (f"node coordinates from the companion file {companion} "
                                                        f"(pass {option} to choose another)"))
    names = "/".join(p.with_suffix(s).name for s in COMPANION_SUFFIXES[:3]) + f"/{p.with_suffix('.uff').name}"
    if rejected:
        found = "; ".join(f"{c.name} exists but is not used: {why}" for c, why in rejected)
        tail = f"a companion file {names} would be used if it were recognised: {found}"
    else:
        tail = f"no companion file {names} was found next to it"
    raise MissingCoordinatesError(
        f"{p} ({fe.format or 'FE modes'}) holds no node coordinates, and the sensors and points must be placed on "
        f"the FE nodes: give {option} FILE (a universal file with dataset 2411, or a Nastran bulk data file with "
        f"GRID cards, e.g. {p.with_suffix('.bdf').name}); {tail}")
