"""Saving and loading identified modes (a :class:`~ema.modeset.ModeSet`) as a folder.

Layout of a modes folder (written by ``railmodal lab identify``):

``modes.csv``
    One row per mode: ``mode, f_hz, zeta, mpc, mpd, setup``; ``mode`` numbers
    the modes 1 to m and is the key ``shapes.parquet`` refers to.
``dofs.csv``
    One row per measured DOF: the channel metadata (``label, node, name, x, y,
    z, dx, dy, dz`` and ``fe_node``, ``setup`` when known).
``shapes.parquet``
    The complex shapes, long format ``mode, dof, re, im``; a DOF a mode was
    not measured at (merged setups) is absent — exact round trip.
``modes.uff``
    The same modes for other tools: UFF 2411 (test nodes at the sensor
    positions) and one UFF 55 per mode (analysis type 3, complex eigenvalue;
    3-DOF global vectors per node, the measured components placed along
    their measuring directions; unmeasured components 0).
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pandas as pd
import pyuff

from .modeset import ModeSet

__all__ = ["write_modeset", "read_modeset", "ModesFolderError"]

log = logging.getLogger("ema")


class ModesFolderError(ValueError):
    """A modes folder that is incomplete or inconsistent."""


def write_modeset(modes: ModeSet, folder: str | Path) -> Path:
    """Write ``modes`` into ``folder`` (created if needed); returns the folder."""
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    table = modes.to_frame()
    table.insert(0, "mode", np.arange(1, len(modes) + 1))
    table.to_csv(out / "modes.csv", index=False, float_format="%.10g")
    dofs = modes.channels.copy()
    dofs.insert(0, "label", list(modes.dofs))
    dofs.to_csv(out / "dofs.csv", index=False)
    m_idx, d_idx = np.nonzero(np.isfinite(modes.shapes.T))
    long = pd.DataFrame(
        {"mode": m_idx + 1, "dof": d_idx, "re": modes.shapes.T[m_idx, d_idx].real, "im": modes.shapes.T[m_idx, d_idx].imag}
    )
    long.to_parquet(out / "shapes.parquet", index=False)
    _write_uff(modes, out / "modes.uff")
    return out


def _write_uff(modes: ModeSet, path: Path) -> None:
    ch = modes.channels
    nodes = np.unique(ch["node"].astype(int))
    pos = {int(n): ch.loc[ch["node"].astype(int) == n, ["x", "y", "z"]].to_numpy(float)[0] for n in nodes}
    if path.exists():
        path.unlink()
    uff = pyuff.UFF(str(path))
    # pyuff's prepare_* helpers fail on numpy 2 arrays; its writers take plain dicts
    sets = [
        {
            "type": 2411,
            "node_nums": nodes.astype(int),
            "def_cs": np.zeros(len(nodes), int),
            "disp_cs": np.zeros(len(nodes), int),
            "color": np.ones(len(nodes), int),
            "x": np.array([pos[n][0] for n in nodes]),
            "y": np.array([pos[n][1] for n in nodes]),
            "z": np.array([pos[n][2] for n in nodes]),
        }
    ]
    dirs = ch[["dx", "dy", "dz"]].to_numpy(float)
    node_row = {int(n): k for k, n in enumerate(nodes)}
    for j in range(len(modes)):
        vec = np.zeros((len(nodes), 3), complex)
        phi = np.nan_to_num(modes.shapes[:, j])
        for r in range(len(ch)):
            vec[node_row[int(ch["node"].iloc[r])]] += phi[r] * dirs[r]
        s = modes.poles[j]
        sets.append(
            {
                "type": 55,
                "id1": f"railmodal identified mode {j + 1}",
                "id2": f"f = {modes.freqs_hz[j]:.6f} Hz, zeta = {modes.zeta[j]:.6e}, setup {modes.setup[j]}"[:80],
                "id3": "NONE",
                "id4": "NONE",
                "id5": "NONE",
                "model_type": 1,
                "analysis_type": 3,
                "data_ch": 2,
                "spec_data_type": 12,
                "load_case": 1,
                "mode_n": j + 1,
                "eig": complex(s),
                "modal_a": 0j,
                "modal_b": 0j,
                "node_nums": nodes.astype(int),
                "r1": vec[:, 0],
                "r2": vec[:, 1],
                "r3": vec[:, 2],
            }
        )
    uff.write_sets(sets, mode="add")


#: Columns of modes.csv, dofs.csv and shapes.parquet that :func:`read_modeset` needs.
_MODES_COLUMNS = ("mode", "f_hz", "zeta", "mpc", "mpd", "setup")
_DOFS_COLUMNS = ("label", "node", "x", "y", "z", "dx", "dy", "dz")
_SHAPES_COLUMNS = ("mode", "dof", "re", "im")
#: A measuring direction whose norm differs from 1 by more than this is refused (the writer stores unit vectors).
_DIRECTION_NORM_TOL = 1e-3
#: Text columns of the CSV files: kept as text ("1", "NA" and "None" are names, not numbers or gaps).
_TEXT_COLUMNS = {"label": str, "name": str, "setup": str, "quantity": str, "unit": str}


def _read_csv(path: Path) -> pd.DataFrame:
    """``path`` as a table, every parsing failure a :class:`ModesFolderError` naming the file.

    Only a blank field is a gap (``NA``, ``null`` ... stay text): a setup or channel called ``NA`` must not turn
    into a missing value.
    """
    try:
        return pd.read_csv(path, dtype=_TEXT_COLUMNS, keep_default_na=False, na_values=[""])
    except pd.errors.EmptyDataError:
        raise ModesFolderError(f"{path}: the file is empty; it needs a header line and one row per entry") from None
    except UnicodeDecodeError as exc:
        raise ModesFolderError(f"{path}: not UTF-8 text (byte {exc.start}); is it a CSV file?") from None
    except (pd.errors.ParserError, ValueError, OSError) as exc:
        raise ModesFolderError(f"{path}: cannot read the CSV table ({exc})") from exc


def _read_parquet(path: Path) -> pd.DataFrame:
    """``path`` as a table, every reading failure a :class:`ModesFolderError` naming the file."""
    import pyarrow

    try:
        return pd.read_parquet(path)
    except (pyarrow.ArrowException, ValueError, OSError) as exc:
        raise ModesFolderError(f"{path}: cannot read the parquet table ({exc})") from exc


def _need_columns(frame: pd.DataFrame, path: Path, columns) -> None:
    missing = [c for c in columns if c not in frame.columns]
    if missing:
        raise ModesFolderError(f"{path}: column(s) {missing} missing; the file needs columns {list(columns)} "
                               f"(found {list(map(str, frame.columns))})")


def _plain(value):
    """A numpy scalar as the Python value, so that messages read ``-1``, not ``np.int64(-1)``."""
    return value.item() if isinstance(value, np.generic) else value


def _row(i: int, rows) -> str:
    return rows[i] if rows is not None else f"row {i + 1}"


def _refuse_rows(path: Path, bad: np.ndarray, col: str, values, why: str, rows=None) -> None:
    """Raise naming the first row flagged in ``bad``: ``<file>, row 3 (...), column 'c': <value> <why>``.

    ``rows`` names each row (default ``row i+1``, counted from 1 after the header); ``values=None`` leaves the
    value out (``why`` then says what is wrong on its own).
    """
    if np.any(bad):
        i = int(np.argmax(bad))
        shown = "" if values is None else f"{_plain(values[i])!r} "
        raise ModesFolderError(f"{path}, {_row(i, rows)}, column {col!r}: {shown}{why}")


def _numbers(frame: pd.DataFrame, col: str, path: Path, *, blank_ok: bool = False, rows=None) -> np.ndarray:
    """Column ``col`` as floats; text, or a gap unless ``blank_ok``, raises naming file, row and column."""
    raw = frame[col]
    values = pd.to_numeric(raw, errors="coerce").to_numpy(float)
    text = np.isnan(values) & raw.notna().to_numpy()
    _refuse_rows(path, text, col, raw.to_numpy(), "is not a number", rows)
    if not blank_ok:
        _refuse_rows(path, raw.isna().to_numpy(), col, None, "the value is missing (blank or NaN)", rows)
    return values


def _integers(frame: pd.DataFrame, col: str, path: Path) -> np.ndarray:
    """Column ``col`` as int64; a fraction, gap, text or non-finite value raises naming file, row and column.

    Integral floats (``3.0``, another tool's float column) are accepted: the value, not the dtype, matters.
    """
    values = _numbers(frame, col, path)
    bad = ~np.isfinite(values) | (values != np.round(values)) | (np.abs(values) > 2**62)
    _refuse_rows(path, bad, col, frame[col].to_numpy(), "is not an integer")
    return values.astype(np.int64)


def _read_modes_table(path: Path) -> tuple[np.ndarray, pd.DataFrame]:
    """modes.csv validated: (the row order that sorts it by mode number, the table).

    The ``mode`` column is the key shapes.parquet refers to, so the rows are matched by it, not by their
    position: a table whose rows were sorted (by frequency, say) still attaches each shape to its own mode.
    """
    table = _read_csv(path)
    _need_columns(table, path, _MODES_COLUMNS)
    m = len(table)
    number = _integers(table, "mode", path)
    first: dict[int, int] = {}
    for i, n in enumerate(number.tolist()):
        if not 1 <= n <= m:
            raise ModesFolderError(f"{path}, row {i + 1}, column 'mode': mode {n} is out of range; the {m} rows "
                                   f"must number the modes 1 to {m}, each once")
        if n in first:
            raise ModesFolderError(f"{path}, row {i + 1}, column 'mode': mode {n} already given in row "
                                   f"{first[n] + 1}; the {m} rows must number the modes 1 to {m}, each once")
        first[n] = i
    rows = [f"row {i + 1} (mode {n})" for i, n in enumerate(number.tolist())]
    f = _numbers(table, "f_hz", path, rows=rows)
    _refuse_rows(path, ~(np.isfinite(f) & (f > 0)), "f_hz", f, "is not a natural frequency (a finite number > 0 Hz)",
                 rows)
    zeta = _numbers(table, "zeta", path, rows=rows)
    # |zeta| >= 1 has no oscillating pole (sqrt(1 - zeta^2) in ModeSet.poles): NaN poles would poison the pairing
    _refuse_rows(path, ~(np.isfinite(zeta) & (np.abs(zeta) < 1)), "zeta", zeta,
                 "is not a damping ratio (a finite number between -1 and 1)", rows)
    for col in ("mpc", "mpd"):
        # indicators only (not used to pair): a blank is a missing indicator, but text is a damaged table
        _refuse_rows(path, np.isinf(_numbers(table, col, path, blank_ok=True, rows=rows)), col,
                     table[col].to_numpy(), "is not finite", rows)
    _refuse_rows(path, table["setup"].isna().to_numpy(), "setup", None,
                 "the value is blank; it names the setup the mode was identified in", rows)
    out = pd.DataFrame({"mode": number, "f_hz": f, "zeta": zeta, "mpc": pd.to_numeric(table["mpc"]).to_numpy(float),
                        "mpd": pd.to_numeric(table["mpd"]).to_numpy(float), "setup": table["setup"].astype(str)})
    return np.argsort(number, kind="stable"), out


def _read_dofs_table(path: Path) -> pd.DataFrame:
    """dofs.csv validated (labels unique, integer nodes, finite positions, unit directions); returned as read."""
    dofs = _read_csv(path)
    _need_columns(dofs, path, _DOFS_COLUMNS)
    labels = dofs["label"]
    _refuse_rows(path, labels.isna().to_numpy(), "label", None, "the value is blank; every DOF needs a label")
    dup = labels.duplicated().to_numpy()
    if dup.any():
        i = int(np.argmax(dup))
        j = int(np.flatnonzero((labels == labels.iloc[i]).to_numpy())[0])
        raise ModesFolderError(f"{path}, row {i + 1}, column 'label': {labels.iloc[i]!r} already given in row "
                               f"{j + 1}; each DOF has its own label")
    rows = [f"row {i + 1} ({lab!r})" for i, lab in enumerate(labels.tolist())]
    node = _integers(dofs, "node", path)
    _refuse_rows(path, node <= 0, "node", node, "is not a positive node number", rows)
    xyz = np.column_stack([_numbers(dofs, c, path, rows=rows) for c in ("x", "y", "z", "dx", "dy", "dz")])
    for k, c in enumerate(("x", "y", "z", "dx", "dy", "dz")):
        _refuse_rows(path, ~np.isfinite(xyz[:, k]), c, xyz[:, k], "is not finite", rows)
    norm = np.linalg.norm(xyz[:, 3:], axis=1)
    bad = np.abs(norm - 1) > _DIRECTION_NORM_TOL
    if bad.any():
        i = int(np.argmax(bad))
        raise ModesFolderError(f"{path}, {rows[i]}, columns 'dx', 'dy', 'dz': the measuring direction "
                               f"{xyz[i, 3:].tolist()} has length {norm[i]:.6g}; it must be a unit vector")
    if "fe_node" in dofs:
        fe = _numbers(dofs, "fe_node", path, blank_ok=True, rows=rows)
        given = ~np.isnan(fe)
        _refuse_rows(path, given & ~(np.isfinite(fe) & (fe == np.round(fe)) & (fe > 0)), "fe_node", fe,
                     "is not a positive FE node number (leave it blank when unknown)", rows)
    return dofs


def read_modeset(folder: str | Path) -> ModeSet:
    """Read a modes folder written by :func:`write_modeset`.

    The three files are checked against each other, since a mismatch would
    not fail later but pair wrong shapes: ``modes.csv`` numbers its modes 1
    to m, each once (rows are matched by that number, not by position), with
    finite frequencies > 0 and damping ratios in (-1, 1); ``dofs.csv`` has
    unique labels, integer nodes, finite positions and unit directions;
    ``shapes.parquet`` gives each (mode, DOF) at most once, with integer
    numbers of modes in modes.csv and DOFs (0-based rows) of dofs.csv, finite
    values, and at least one value per mode.

    Parameters
    ----------
    folder : str or Path
        The modes folder.

    Returns
    -------
    ModeSet
        Modes in mode-number order.

    Raises
    ------
    ModesFolderError
        If a file is missing, unreadable, lacks a column, has a bad value, or
        the files disagree; the message names the file, the row and column.
    """
    folder = Path(folder)
    for name in ("modes.csv", "dofs.csv", "shapes.parquet"):
        if not (folder / name).exists():
            raise ModesFolderError(f"{folder}: {name} is missing; is this a folder written by 'railmodal lab identify'?")
    order, table = _read_modes_table(folder / "modes.csv")
    table = table.iloc[order].reset_index(drop=True)
    dofs = _read_dofs_table(folder / "dofs.csv")
    path = folder / "shapes.parquet"
    long = _read_parquet(path)
    _need_columns(long, path, _SHAPES_COLUMNS)
    m, n = len(table), len(dofs)
    shapes = np.full((n, m), np.nan + 0j)
    mode, dof = _integers(long, "mode", path), _integers(long, "dof", path)
    _refuse_rows(path, (mode < 1) | (mode > m), "mode", mode, f"is not a mode of modes.csv (1 to {m})")
    # a negative index would silently wrap to the last DOF
    _refuse_rows(path, (dof < 0) | (dof >= n), "dof", dof, f"is not a DOF of dofs.csv (0 to {n - 1}, its row - 1)")
    where = [f"row {i + 1} (mode {a}, dof {b})" for i, (a, b) in enumerate(zip(mode.tolist(), dof.tolist()))]
    parts = {}
    for col in ("re", "im"):  # checked apart: 1j * inf would turn up as a NaN real part
        parts[col] = _numbers(long, col, path, rows=where)
        _refuse_rows(path, ~np.isfinite(parts[col]), col, parts[col], "is not finite", where)
    value = parts["re"] + 1j * parts["im"]
    first: dict[tuple[int, int], int] = {}
    for i, key in enumerate(zip(mode.tolist(), dof.tolist())):
        if key in first:
            # a second value would overwrite the first without a word
            raise ModesFolderError(f"{path}, row {i + 1}: mode {key[0]}, dof {key[1]} already given in row "
                                   f"{first[key] + 1}; each (mode, dof) may appear once")
        first[key] = i
    shapes[dof, mode - 1] = value
    empty = ~np.isfinite(shapes).any(axis=0)
    if empty.any():
        k = int(np.argmax(empty))
        raise ModesFolderError(f"{path}: mode {k + 1} of modes.csv has no shape value; every mode needs at least "
                               f"one (mode, dof) row")
    labels = tuple(dofs.pop("label").astype(str))
    return ModeSet(
        freqs_hz=table["f_hz"].to_numpy(float),
        zeta=table["zeta"].to_numpy(float),
        shapes=shapes,
        dofs=labels,
        channels=dofs,
        mpc=table["mpc"].to_numpy(float),
        mpd=table["mpd"].to_numpy(float),
        setup=tuple(table["setup"]),
        source=str(folder),
    )
