"""The channel table of a hammer test: schema, validation and reading.

A hammer test's channels are described by a table (a CSV file written by the
lab, one row per channel) with the columns of ``shared/DESIGN.md``:

========== ======== ==============================================================
column     required meaning
========== ======== ==============================================================
node       yes      channel / response node number, as in the UFF58 ``rsp_node``
name       yes      channel name, e.g. ``axle_01`` (the FRF output label)
quantity   yes      ``force`` (exactly one row: the hammer) or ``acceleration``
unit       yes      ``N`` for force, ``m/s^2`` for acceleration: the SI unit the
                    toolkit works in (data labelled g, kN, lbf, in/s^2... in
                    the file are converted by their labels, see
                    :data:`UNIT_TO_SI`)
x, y, z    yes      sensor position [m]
dx, dy, dz yes      unit measuring direction (normalised if within 1e-3 of 1)
fe_node    no       FE node the sensor is rigidly attached to
sensitivity no      the factor on the recorded values that gives SI units, as in
                    the field sensor table (:mod:`estimator.io.sensors`):
                    ``SI = recorded x sensitivity``, 1 for data already in SI;
                    see *Sensitivity* below
setup      no       name of the test setup (``flexural``, ``torsional``, ...);
                    one value for the whole table (a hammer test is one setup)
========== ======== ==============================================================

A channel is identified by its ``node`` and ``quantity``: a driving point
(the hammer and an accelerometer at the same UFF node, told apart in the file
by the specific data type, 13 excitation force / 12 acceleration) is two rows
with the same node. Two rows with the same node and quantity are refused
(one node per sensor: a triaxial accelerometer needs a node per direction).

Sensitivity
-----------
Data recorded as raw voltages carry an electrical unit label (``V``, ``mV``,
``µV``; :data:`ELECTRICAL_UNITS`) or none at all (empty or ``NONE``): the
readers multiply them by the channel's ``sensitivity``, the factor from the
recorded values to SI (for an accelerometer of 10.2 mV/(m/s²) recorded in V,
``1 / 0.0102 = 98.04``; recorded in mV, ``0.098``; a hammer of 2.25 mV/N
recorded in V, ``444.4``). Without a ``sensitivity`` column, an electrical
label is refused (the data cannot be converted) and unlabelled data are taken
as SI. Data labelled in a physical unit were converted by the front end: they
are converted by their label and the sensitivity is not applied (a WARNING
names the channels whose sensitivity is not 1). See :func:`unit_kind`.

Descriptive columns (:data:`DESCRIPTIVE_COLUMNS`: ``comment``, ``description``,
``serial``, ...) are kept as they are. Any other column is kept with a
WARNING, except one that looks like a misspelt or repeated known column
(``fe-node``, ``FE_node``, ``sensitivty``, ``z.1``): that is refused, because
the table would otherwise be read as if the column were absent (sensors fall
back to the nearest FE node, say) without anyone noticing.

The validation is modelled on MNE-Python's ``Info``: a bad table raises
:class:`ChannelTableError` whose message names the file, the row (node) and
the column, what was found, what is allowed, and what to do about it.
"""

from __future__ import annotations

import difflib
import logging
import os
import re
from pathlib import Path

import numpy as np
import pandas as pd

__all__ = [
    "ChannelTableError",
    "REQUIRED_COLUMNS",
    "OPTIONAL_COLUMNS",
    "DESCRIPTIVE_COLUMNS",
    "CHANNEL_QUANTITIES",
    "UNIT_TO_SI",
    "ELECTRICAL_UNITS",
    "unit_key",
    "unit_kind",
    "datasheet_like_sensitivity",
    "validate_channels",
    "read_channels",
    "read_table_csv",
    "MAX_NODE",
]

log = logging.getLogger("ema")

#: Columns every channel table must have, in canonical order.
REQUIRED_COLUMNS: tuple[str, ...] = ("node", "name", "quantity", "unit", "x", "y", "z", "dx", "dy", "dz")
#: Columns a channel table may have.
OPTIONAL_COLUMNS: tuple[str, ...] = ("fe_node", "sensitivity", "setup")
#: Free-text columns a lab may add for people (kept, never read, no warning).
DESCRIPTIVE_COLUMNS: tuple[str, ...] = ("comment", "comments", "description", "note", "notes", "label", "serial",
                                        "serial_number", "sensor_type", "sensor_model", "manufacturer", "location")
#: quantity -> accepted unit spellings (the first is the canonical SI unit).
CHANNEL_QUANTITIES: dict[str, tuple[str, ...]] = {
    "force": ("N",),
    "acceleration": ("m/s^2", "m/s2", "m/s**2", "m/s\u00b2"),
}
#: Unit labels front-ends write (:func:`unit_key` form: lower case, no blanks, ``**`` and ``²`` as ``^2``) ->
#: factor to the quantity's SI unit (data in g, kN, in/s^2, ...). ``s\ufffd`` is a latin-1/cp1252 ``s²``
#: (Windows front ends) as pyuff decodes it (UTF-8 with replacement characters). The first label of each factor
#: is its canonical spelling. This is the toolkit's one unit table: the field sensor table reads its
#: accelerations through it too (:mod:`estimator.io.sensors`), so a unit the lab knows the field knows.
UNIT_TO_SI: dict[str, dict[str, float]] = {
    "acceleration": {"m/s^2": 1.0, "m/s2": 1.0, "m/s/s": 1.0, "m/sec^2": 1.0, "m/sec2": 1.0, "m/s\ufffd": 1.0,
                     "mm/s^2": 1e-3, "mm/s2": 1e-3, "mm/s\ufffd": 1e-3,
                     "in/s^2": 0.0254, "in/s2": 0.0254, "in/s/s": 0.0254, "in/sec^2": 0.0254, "in/sec2": 0.0254,
                     "in/s\ufffd": 0.0254,
                     "ft/s^2": 0.3048, "ft/s2": 0.3048, "ft/s/s": 0.3048, "ft/sec^2": 0.3048, "ft/sec2": 0.3048,
                     "ft/s\ufffd": 0.3048,
                     "g": 9.80665, "gn": 9.80665, "g0": 9.80665, "mg": 9.80665e-3,
                     # spellings of data loggers (m·s⁻², g_n as the field's sensor tables write them)
                     "ms-2": 1.0, "ms^-2": 1.0, "g_n": 9.80665},
    "force": {"n": 1.0, "newton": 1.0, "newtons": 1.0, "kn": 1e3, "dan": 10.0, "lbf": 4.4482216152605,
              "lb": 4.4482216152605, "lbs": 4.4482216152605, "kgf": 9.80665, "kp": 9.80665},
}
#: Electrical unit labels (:func:`unit_key` form) -> volts per unit: the data are raw voltages that only a
#: sensitivity converts (``\ufffdv`` is a latin-1 ``µV`` decoded as UTF-8 with replacement).
ELECTRICAL_UNITS: dict[str, float] = {"v": 1.0, "volt": 1.0, "volts": 1.0, "mv": 1e-3, "uv": 1e-6,
                                      "\u00b5v": 1e-6, "\u03bcv": 1e-6, "\ufffdv": 1e-6}
#: Largest node number: UFF node fields are I10 (and FE codes use 32-bit labels).
MAX_NODE = 2**31 - 1
#: A direction vector whose norm differs from 1 by more than this is rejected
#: (it is a typo, not a rounding error); within it, it is normalised.
DIRECTION_NORM_TOL = 1e-3


class ChannelTableError(ValueError):
    """A channel table that does not follow the schema (see :mod:`ema.channels`)."""


def unit_key(label) -> str:
    """The form of a unit label looked up in :data:`UNIT_TO_SI`: lower case, no blanks, ``**`` as ``^``,
    superscript ``²`` as ``^2`` (``'M/S²'`` -> ``'m/s^2'``); ``''`` for no label (empty or ``NONE``)."""
    key = "".join(str(label if label is not None else "").split()).lower()
    key = key.replace("**", "^").replace("\u00b2", "^2")
    return "" if key == "none" else key


#: Smallest plausible sensitivity of data recorded in volts [SI unit per V]: a hammer gives tens to thousands of N/V
#: (25 to 0.2 mV/N), an accelerometer about 1 to 1e5 (m/s^2)/V (10 V/g to 0.1 mV/g); a datasheet sensitivity
#: (V per SI unit, 0.0002 to 0.1) written in its place is far below.
MIN_SENSITIVITY_PER_VOLT = 0.5


def datasheet_like_sensitivity(label, sensitivity: float) -> bool:
    """Whether the sensitivity of data labelled in an electrical unit looks like a datasheet value (V per SI unit)
    rather than the factor on the recorded values: below :data:`MIN_SENSITIVITY_PER_VOLT` SI units per volt."""
    volts = ELECTRICAL_UNITS.get(unit_key(label))
    return volts is not None and float(sensitivity) / volts < MIN_SENSITIVITY_PER_VOLT


def unit_kind(quantity: str, label) -> tuple[str, float]:
    """What a channel's unit label in a file says about its data, and the factor to SI it implies.

    Parameters
    ----------
    quantity : {"force", "acceleration"}
        The channel's quantity (from the channel table).
    label : str
        The unit label written in the file (UFF58 record 10).

    Returns
    -------
    kind : {"raw", "physical", "electrical", "other", "unknown"}
        ``raw``: no label (empty or ``NONE``), the data are as recorded;
        ``physical``: a unit of the quantity (factor to SI);
        ``electrical``: V, mV, µV (factor to volts): raw voltages;
        ``other``: a unit of the other quantity (``g`` on a force channel);
        ``unknown``: not recognised.
    factor : float
        Factor to SI (``physical``), to volts (``electrical``), else 1.
    """
    key = unit_key(label)
    if not key:
        return "raw", 1.0
    if key in UNIT_TO_SI[quantity]:
        return "physical", UNIT_TO_SI[quantity][key]
    if key in ELECTRICAL_UNITS:
        return "electrical", ELECTRICAL_UNITS[key]
    if any(key in units for q, units in UNIT_TO_SI.items() if q != quantity):
        return "other", 1.0
    return "unknown", 1.0


def _where(source: str) -> str:
    return f"channel table {source!r}" if source else "channel table"


def _row_label(df: pd.DataFrame, i: int) -> str:
    """'row 3 (node 103)' or 'row 3' if the node is unusable."""
    node = df["node"].iloc[i] if "node" in df.columns else None
    try:
        n = int(node)
        return f"row {i + 1} (node {n})" if 0 < n <= MAX_NODE else f"row {i + 1}"
    except (TypeError, ValueError, OverflowError):
        return f"row {i + 1}"


def _norm_column(name: str) -> str:
    """A column name without case, blanks and punctuation differences ('FE-node ' -> 'fe_node')."""
    return re.sub(r"[^0-9a-z]+", "_", name.strip().lower()).strip("_")


def unapplied_sensitivity_note(channels: list[str], what: str, limit: int = 8) -> str:
    """The message for channels whose ``sensitivity`` is not applied because their ``what`` ("data are", "FRFs
    are") are labelled in a physical unit (the front end converted them)."""
    listed = ", ".join(channels[:limit]) + (f" and {len(channels) - limit} more" if len(channels) > limit else "")
    return (f"the sensitivity of {len(channels)} channel{'s' if len(channels) > 1 else ''} is not applied: their "
            f"{what} labelled in a physical unit, so the front end converted them already ({listed}); set the "
            f"sensitivity to 1 for converted data, or export raw data (label V or none) to have it applied")


def _rows_text(rows: list[int], limit: int = 8) -> str:
    """'rows 1-3, 7' for 0-based row positions (1-based in the text, runs collapsed, at most ``limit`` runs)."""
    from fem_import.modes import number_ranges

    return ("row " if len(rows) == 1 else "rows ") + number_ranges([r + 1 for r in sorted(rows)], limit)


def _check_columns(df: pd.DataFrame, where: str, warn_extra: bool) -> None:
    """Refuse repeated and misspelt known columns; WARN about other unknown ones.

    A misspelt known column (``fe-node``) or a repeated one (``z`` twice, which pandas renames ``z.1``) is kept
    by pandas as an extra column while the known column is missing or holds the first copy: the table would
    be read as if the column were not there, so results would change without a message. Other unknown
    columns change nothing but may be a typo nobody meant, so they are named once.
    """
    known = REQUIRED_COLUMNS + OPTIONAL_COLUMNS
    hint = f"channel-table columns are {list(REQUIRED_COLUMNS)} (optional {list(OPTIONAL_COLUMNS)})"
    names = [str(c) for c in df.columns]
    seen: dict[str, int] = {}
    for k, c in enumerate(names):
        if c in seen:
            raise ChannelTableError(
                f"{where}: column {c!r} appears twice (columns {seen[c] + 1} and {k + 1}); only one copy could be "
                f"used, so the table is ambiguous: remove the repeated column"
            )
        seen[c] = k
    extra = []
    for c in names:
        if c in known:
            continue
        m = re.fullmatch(r"(.+)\.(\d+)", c)
        if m and m.group(1) in names:
            # pandas.read_csv renames a repeated header 'z' to 'z.1'
            raise ChannelTableError(
                f"{where}: column {c!r} looks like a second {m.group(1)!r} column (pandas renames a repeated "
                f"header {m.group(1)!r} to {c!r}); only the first copy would be used: remove the repeated column"
            )
        norm = _norm_column(c)
        if norm in DESCRIPTIVE_COLUMNS:
            continue
        target = norm if norm in known else next(iter(difflib.get_close_matches(norm, known, n=1, cutoff=0.8)), None)
        if target is not None:
            what = (f"repeats column {target!r} (the same name up to case, blanks or punctuation): only one copy "
                    f"would be used" if target in names else
                    f"is not a channel-table column; did you mean {target!r}? As it is, the table would be read as "
                    f"if {target!r} were absent")
            raise ChannelTableError(f"{where}: column {c!r} {what}; rename or remove it. The {hint}")
        extra.append(c)
    if extra and warn_extra:
        log.warning("%s: unknown column(s) %s are kept but not used; the %s, and descriptive columns %s are "
                    "kept without notice", where, extra, hint, list(DESCRIPTIVE_COLUMNS))


def validate_channels(df: pd.DataFrame, *, source: str = "", warn_extra: bool = True) -> pd.DataFrame:
    """Check a channel table and return a validated, normalised copy.

    Parameters
    ----------
    df : pandas.DataFrame
        The table (see the module docstring for the schema). Not modified.
    source : str, optional
        Where the table comes from (a file name), quoted in error messages.
    warn_extra : bool, optional
        Log a WARNING (logger ``"ema"``) naming unknown columns that are
        neither known nor descriptive. Callers re-validating a table that was
        already checked pass False, so the warning is given once.

    Returns
    -------
    pandas.DataFrame
        A copy with a fresh ``RangeIndex``, the required columns first (in
        canonical order) then the optional and any extra columns; ``node``
        (and ``fe_node``) as ``int64``, ``name``/``quantity``/``unit``/``setup``
        as ``str`` (units in canonical spelling: ``N``, ``m/s^2``), positions
        and directions as ``float64`` with every direction of unit length.
        Row order is kept.

    Raises
    ------
    ChannelTableError
        A required column is missing; a value is missing, non-numeric or not
        finite; a quantity or unit is not allowed; there is not exactly one
        force row; a name, or a node with the same quantity, is repeated
        (a force and an acceleration row may share a node: a driving
        point); a direction is not a unit
        vector (within 1e-3); ``fe_node`` is not a positive integer or
        ``sensitivity`` not a positive number; a column is repeated or a
        misspelt known column (``fe-node``); the ``setup`` column names more
        than one setup. The message names the source, the row and node, and
        the column.
    """
    where = _where(source)
    if not isinstance(df, pd.DataFrame):
        raise ChannelTableError(f"{where}: expected a pandas.DataFrame, got {type(df).__name__}")
    # before the missing-column check, so that 'Node' or 'fe-node' is named as the misspelling it is
    _check_columns(df, where, warn_extra)
    missing = [c for c in REQUIRED_COLUMNS if c not in df.columns]
    if missing:
        raise ChannelTableError(
            f"{where}: missing required column(s) {missing}; a channel table needs columns "
            f"{list(REQUIRED_COLUMNS)} (optional {list(OPTIONAL_COLUMNS)}). Add them to the CSV header."
        )
    if len(df) == 0:
        raise ChannelTableError(f"{where}: the table has no rows; it needs one force row and at least one channel")
    out = df.reset_index(drop=True).copy()

    # -- integers: node (required), fe_node (optional)
    for col in ("node", "fe_node"):
        if col not in out.columns:
            continue
        vals = []
        for i, v in enumerate(out[col].tolist()):
            ok = False
            try:
                fv = float(v)
                ok = bool(np.isfinite(fv) and fv == int(fv) and 0 < fv <= MAX_NODE)
            except (TypeError, ValueError, OverflowError):
                ok = False
            if not ok:
                raise ChannelTableError(
                    f"{where}: {_row_label(out, i) if col != 'node' else f'row {i + 1}'}, column {col!r}: "
                    f"expected a positive integer node number up to {MAX_NODE} (the I10 field of a universal "
                    f"file), got {v!r}"
                    + ("; UFF node numbers start at 1: renumber a 0-based channel numbering in the export and the "
                       "table" if col == "node" and isinstance(v, (int, float)) and v == 0 else "")
                    + (". Leave fe_node out of the table if the FE node is unknown." if col == "fe_node" else "")
                )
            vals.append(int(fv))
        out[col] = np.asarray(vals, dtype=np.int64)

    # -- strings
    for col in ("name", "quantity", "unit") + (("setup",) if "setup" in out.columns else ()):
        vals = []
        for i, v in enumerate(out[col].tolist()):
            if v is None or (isinstance(v, float) and np.isnan(v)) or str(v).strip() == "":
                raise ChannelTableError(f"{where}: {_row_label(out, i)}, column {col!r}: value is missing")
            vals.append(str(v).strip())
        out[col] = vals

    # -- quantity and unit
    for i, (q, u) in enumerate(zip(out["quantity"], out["unit"])):
        if q not in CHANNEL_QUANTITIES:
            raise ChannelTableError(
                f"{where}: {_row_label(out, i)}, column 'quantity': expected one of "
                f"{sorted(CHANNEL_QUANTITIES)}, got {q!r}"
            )
        if u not in CHANNEL_QUANTITIES[q]:
            raise ChannelTableError(
                f"{where}: {_row_label(out, i)}, column 'unit': a {q} channel must be in "
                f"{CHANNEL_QUANTITIES[q][0]!r} (SI), got {u!r}: write the SI unit here, the unit the toolkit works "
                f"in; data labelled in other units in the file (g, mg, in/s^2, kN, lbf...) are converted by their "
                f"labels, and raw voltages by a 'sensitivity' column (SI = recorded x sensitivity)"
            )
    out["unit"] = [CHANNEL_QUANTITIES[q][0] for q in out["quantity"]]
    n_force = int((out["quantity"] == "force").sum())
    if n_force != 1:
        raise ChannelTableError(
            f"{where}: expected exactly one row with quantity 'force' (the hammer), found {n_force}"
            + (f" (nodes {out.loc[out['quantity'] == 'force', 'node'].tolist()})" if n_force else "")
            + "; single-reference hammer tests have one force channel"
        )
    if n_force == len(out):
        raise ChannelTableError(f"{where}: the table has a force row but no acceleration channel")

    # -- one setup per table: the setup names the modes identified from this test, and the CLI and
    # ema.identify take the table's single value; a mixed column would be reduced to its first value
    if "setup" in out.columns:
        groups: dict[str, list[int]] = {}
        for i, v in enumerate(out["setup"]):
            groups.setdefault(v, []).append(i)
        if len(groups) > 1:
            listed = "; ".join(f"{v!r} in {_rows_text(r)}" for v, r in groups.items())
            raise ChannelTableError(
                f"{where}: column 'setup' must have one value for the whole table (a hammer test is one setup), "
                f"found {len(groups)}: {listed}; split the table (and the hammer-test file) per setup"
            )

    # -- uniqueness: a channel is (node, quantity); a driving point has a force and an acceleration row at
    # one node, which the file tells apart by the specific data type (13 excitation force, 12 acceleration)
    dup = out[out.duplicated(["node", "quantity"], keep=False)]
    if len(dup):
        node, q = int(dup["node"].iloc[0]), str(dup["quantity"].iloc[0])
        rows = [int(i) + 1 for i in dup.index[(dup["node"] == node) & (dup["quantity"] == q)]]
        raise ChannelTableError(
            f"{where}: column 'node' must be unique per quantity, but node {node} appears as {q} in rows {rows}; "
            f"give every sensor its own node (in the file and the table; a triaxial accelerometer needs one node "
            f"per direction). Only a driving point may share a node: one force row and one acceleration row"
        )
    dup = out["name"][out["name"].duplicated(keep=False)]
    if len(dup):
        rows = [int(i) + 1 for i in dup.index]
        raise ChannelTableError(
            f"{where}: column 'name' must be unique, but {str(dup.iloc[0])!r} appears in rows {rows}; "
            f"give every channel its own name"
        )

    # -- floats
    for col in ("x", "y", "z", "dx", "dy", "dz") + (("sensitivity",) if "sensitivity" in out.columns else ()):
        vals = pd.to_numeric(out[col], errors="coerce").to_numpy(dtype=float)
        bad = ~np.isfinite(vals)
        if col == "sensitivity":
            bad |= ~(vals > 0)
        if np.any(bad):
            i = int(np.flatnonzero(bad)[0])
            what = "a positive finite number" if col == "sensitivity" else "a finite number"
            raise ChannelTableError(
                f"{where}: {_row_label(out, i)}, column {col!r}: expected {what}, got {df[col].tolist()[i]!r}"
            )
        out[col] = vals

    # -- directions
    d = out[["dx", "dy", "dz"]].to_numpy(dtype=float)
    norm = np.linalg.norm(d, axis=1)
    bad = np.abs(norm - 1.0) > DIRECTION_NORM_TOL
    if np.any(bad):
        i = int(np.flatnonzero(bad)[0])
        raise ChannelTableError(
            f"{where}: {_row_label(out, i)}, columns ('dx', 'dy', 'dz'): the measuring direction must be a "
            f"unit vector (norm within {DIRECTION_NORM_TOL:g} of 1), got {tuple(float(v) for v in d[i])} with norm "
            f"{norm[i]:.6g}; "
            f"check the signs and the sensor orientation"
        )
    d = d / norm[:, None]
    out["dx"], out["dy"], out["dz"] = d[:, 0], d[:, 1], d[:, 2]

    order = list(REQUIRED_COLUMNS) + [c for c in OPTIONAL_COLUMNS if c in out.columns]
    order += [c for c in out.columns if c not in order]
    return out[order]


def read_channels(csv_path: str | os.PathLike) -> pd.DataFrame:
    """Read and validate a channel table CSV.

    Parameters
    ----------
    csv_path : str or os.PathLike
        Comma-separated file with a header line (see :mod:`ema.channels`).

    Returns
    -------
    pandas.DataFrame
        The validated table (:func:`validate_channels`).

    Raises
    ------
    FileNotFoundError
        The file does not exist.
    ChannelTableError
        The file is a folder, cannot be parsed as CSV, or the table is
        invalid; the message names the file (and row and column).

    Notes
    -----
    The separator (``,``, ``;``, tab or ``|``) and a decimal comma are
    detected (:func:`read_table_csv`); a UTF-8 byte-order mark is accepted.
    A repeated header is refused; unknown columns are handled as described
    in :mod:`ema.channels`.
    """
    path = Path(os.fspath(csv_path))
    df = read_table_csv(path, role="channel table", required=REQUIRED_COLUMNS, error=ChannelTableError)
    table = validate_channels(df, source=str(path))
    log.debug("read channel table %s: %d channels", path, len(table))
    return table


_SEPARATORS = (",", ";", "\t", "|")
_NAMES = {",": "comma", ";": "semicolon", "\t": "tab", "|": "vertical bar"}


def read_table_csv(path: str | os.PathLike, *, role: str, required, error=ValueError, dtype=None) -> pd.DataFrame:
    """Read a CSV table whatever its separator, naming the file in every error.

    The separator is the one of ``,`` ``;`` tab ``|`` that splits the header
    into the most ``required`` columns; with a separator other than the comma,
    numbers written with a decimal comma (``0,56``) are read as such. A UTF-8
    byte-order mark is dropped. Column names are stripped of blanks.

    Parameters
    ----------
    path : str or os.PathLike
    role : str
        What the table is ("channel table", "points table"), for messages.
    required : sequence of str
        Columns the table must have (used to recognise the separator; a
        missing one is reported by the caller's validation).
    error : type
        Exception class raised for a table that cannot be parsed.
    dtype : dict, optional
        Passed to :func:`pandas.read_csv`.

    Raises
    ------
    FileNotFoundError
        No such file.
    error
        A folder instead of a file, not text, rows that do not match the
        header (e.g. decimal commas in a comma-separated file), or a column
        name that appears twice in the header.
    """
    import csv
    import io

    path = Path(os.fspath(path))
    if path.is_dir():
        raise error(f"{role} {str(path)!r} is a folder, not a file; give the CSV file")
    if not path.is_file():
        raise FileNotFoundError(f"{role} {str(path)!r} does not exist")
    raw = path.read_bytes()
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise error(f"{role} {str(path)!r}: not UTF-8 text (byte {exc.start}: {raw[exc.start:exc.start + 1]!r}); "
                    f"save the table as UTF-8 CSV") from None
    lines = [ln for ln in text.splitlines() if ln.strip()]
    if not lines:
        raise error(f"{role} {str(path)!r} is empty; it needs a header line with columns {list(required)}")
    header = lines[0]
    want = set(required)
    scores = {sep: len(want & {c.strip() for c in header.split(sep)}) for sep in _SEPARATORS}
    sep = max(_SEPARATORS, key=lambda s: (scores[s], s == ","))
    # pandas renames a repeated header 'z' to 'z.1' and every reader then uses the first copy only: which
    # of the two was meant cannot be known, so the file is refused (read the header row itself to see it)
    cols = [c.strip() for c in next(csv.reader([header], delimiter=sep, skipinitialspace=True), [])]
    first: dict[str, int] = {}
    for k, c in enumerate(cols):
        if c and c in first:
            raise error(f"{role} {str(path)!r}: column {c!r} appears twice in the header (columns {first[c] + 1} "
                        f"and {k + 1}); only one copy could be used, so the table is ambiguous: remove the repeated "
                        f"column")
        first.setdefault(c, k)
    body = "\n".join(lines[1:])
    decimal = "."
    if sep != "," and re.search(r"(^|[^\d.])[-+]?\d+,\d+([eE][-+]?\d+)?($|[^\d])", body, re.M):
        decimal = ","
    if sep != "," or decimal != ".":
        log.info("%s %s: read with %s separators%s", role, path, _NAMES[sep],
                 " and decimal commas" if decimal == "," else "")
    try:
        df = pd.read_csv(io.StringIO(text), sep=sep, decimal=decimal, skipinitialspace=True, dtype=dtype)
    except pd.errors.ParserError as exc:
        hint = ""
        if sep == "," and re.search(r"\d,\d", body):
            hint = "; it looks like decimal commas in a comma-separated file: use '.' for decimals or ';' to separate"
        raise error(f"{role} {str(path)!r}: rows do not match the header ({exc}){hint}") from None
    except pd.errors.EmptyDataError as exc:
        raise error(f"{role} {str(path)!r}: cannot be parsed as CSV ({exc})") from None
    df.columns = [str(c).strip() for c in df.columns]
    if len(df.columns) == 1 and len(want) > 1:
        only = str(df.columns[0])
        guess = next((_NAMES[s] for s in _SEPARATORS if s in only), None)
        if guess:
            raise error(f"{role} {str(path)!r}: the header {only!r} is one column; it looks {guess}-separated but "
                        f"does not name the columns {list(required)}")
    return df
