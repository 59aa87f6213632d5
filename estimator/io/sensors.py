"""The sensor table (``sensors.csv`` of the field contract): one row per recorded channel, validated.

Columns: ``name, quantity, unit, wheelset, side, direction, x, y, z, sensitivity``.

* ``quantity`` ∈ {acceleration, speed, position, balise};
* ``unit`` the recorded unit: accelerations in any unit of the lab's table
  (:data:`ema.channels.UNIT_TO_SI`: ``m/s^2``, ``mm/s^2``, ``g``, ``mg``,
  ``in/s^2``, ``ft/s^2`` and their spellings), speeds in ``m/s``, ``km/h``,
  positions in ``m``, ``mm``, ``km``;
* ``wheelset`` 1 or 2 (vehicle numbering: 1 at the car's front end) for
  accelerations, blank otherwise; ``side`` ``L``/``R`` of the vehicle;
  ``direction`` ``x``/``y``/``z`` (vehicle frame);
* ``x, y, z`` the nominal mounting point relative to the wheelset's centre [m]
  (vehicle frame: x forward, y to the left side at −y, z up);
* ``sensitivity`` the factor on the recorded values that gives SI units
  (9.80665 for a channel in g, 1 for SI).

Channel names are free: the estimator finds channels through this table.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pandas as pd

from ema.channels import UNIT_TO_SI as _LAB_UNIT_TO_SI
from estimator.errors import SensorTableError

__all__ = ["read_sensors", "check_sensors", "SENSOR_COLUMNS", "QUANTITIES", "normalise_unit", "UNIT_TO_SI"]

SENSOR_COLUMNS = ("name", "quantity", "unit", "wheelset", "side", "direction", "x", "y", "z", "sensitivity")
QUANTITIES = ("acceleration", "speed", "position", "balise")
#: Largest sensor table read (a bogie has a few dozen channels).
MAX_ROWS = 1000
MAX_BYTES = 1_000_000

#: accelerations: the lab's unit table (:data:`ema.channels.UNIT_TO_SI`), not a copy of it; the canonical
#: spelling of a factor is the lab table's first label with it (``m/s^2``, ``mm/s^2``, ``in/s^2``, ``ft/s^2``,
#: ``g``, ``mg``)
_ACC_CANONICAL: dict[float, str] = {}
for _label, _factor in _LAB_UNIT_TO_SI["acceleration"].items():
    _ACC_CANONICAL.setdefault(_factor, _label)
del _label, _factor
#: spellings data loggers write (compared without blanks, "·" or "*", "**" as "^", lower case) -> canonical unit:
#: the accelerations' from the lab's table, speeds and positions (which the lab does not record) here
_UNIT_ALIASES = {**{label: _ACC_CANONICAL[f] for label, f in _LAB_UNIT_TO_SI["acceleration"].items()},
                 "m/s": "m/s", "ms-1": "m/s", "ms^-1": "m/s", "km/h": "km/h", "kph": "km/h", "kmh": "km/h",
                 "km/hr": "km/h", "kmh-1": "km/h", "kmh^-1": "km/h", "m": "m", "mm": "mm", "km": "km"}
#: SI factor of each recognised unit (the sensitivity of a perfect sensor recorded in it)
UNIT_TO_SI = {**{label: f for f, label in _ACC_CANONICAL.items()},
              "m/s": 1.0, "km/h": 1 / 3.6, "m": 1.0, "mm": 1e-3, "km": 1e3}
_QUANTITY_UNITS = {"acceleration": tuple(_ACC_CANONICAL.values()), "speed": ("m/s", "km/h"),
                   "position": ("m", "mm", "km"), "balise": ("m", "mm", "km")}


_SUPERSCRIPTS = str.maketrans({"⁻": "^-", "¹": "1", "²": "2"})


def normalise_unit(unit) -> str:
    """Canonical spelling of a unit (``"m/s²"``, ``"m s-2"``, ``"m·s^-2"`` → ``"m/s^2"``; ``"G"`` → ``"g"``);
    unknown units are returned stripped."""
    u = "" if unit is None or (isinstance(unit, float) and math.isnan(unit)) else str(unit).strip()
    key = "".join(u.split()).replace("**", "^").replace("·", "").replace("*", "").lower().translate(_SUPERSCRIPTS)
    return _UNIT_ALIASES.get(key, u)


def read_sensors(path) -> pd.DataFrame:
    """Read and validate a sensor table (CSV; separator detected; UTF-8 with or without BOM).

    Raises
    ------
    FileNotFoundError
        No such file.
    SensorTableError
        A missing column, a bad value (names row, column, allowed values and the value).
    """
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"sensor table {p} does not exist")
    if p.stat().st_size > MAX_BYTES:
        raise SensorTableError(f"{p}: {p.stat().st_size} bytes; a sensor table is at most {MAX_BYTES} bytes")
    raw = p.read_bytes()
    if not raw.strip(b" \t\r\n\x00\xef\xbb\xbf"):
        raise SensorTableError(f"{p}: the sensor table is empty ({len(raw)} bytes, no header line); expected a "
                               f"header {','.join(SENSOR_COLUMNS)} and one row per recorded channel")
    try:
        df = pd.read_csv(p, sep=None, engine="python", encoding="utf-8-sig", dtype={"name": str, "side": str,
                                                                                      "direction": str, "unit": str,
                                                                                      "quantity": str})
    except (pd.errors.ParserError, UnicodeDecodeError, pd.errors.EmptyDataError, csv.Error) as exc:
        # csv.Error: the separator sniffer found no separator (one column, or no header line)
        raise SensorTableError(f"{p}: not a readable CSV sensor table ({type(exc).__name__}: {exc}); expected a "
                               f"header line {','.join(SENSOR_COLUMNS)} with a separator") from None
    return check_sensors(df, source=str(p))


def _blank(v) -> bool:
    """An empty cell (NaN as pandas reads it, or only blanks)."""
    if isinstance(v, str):
        return not v.strip()
    try:
        return bool(pd.isna(v))
    except (TypeError, ValueError):
        return False


def _show(v) -> str:
    """A cell as messages show it: ``an empty cell``, a number as written, text quoted."""
    if _blank(v):
        return "an empty cell"
    if isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool):
        return f"{float(v):g}"
    return repr(v)


def _num(df: pd.DataFrame, col: str, source: str, rows) -> np.ndarray:
    vals = pd.to_numeric(df[col], errors="coerce").to_numpy(float)
    for i in rows:
        if not np.isfinite(vals[i]):
            raise SensorTableError(f"{source}: row {i + 2} ({df['name'].iloc[i]!r}): column {col!r} must be a finite "
                                   f"number, got {_show(df[col].iloc[i])}")
    return vals


def check_sensors(df: pd.DataFrame, source: str = "<sensor table>") -> pd.DataFrame:
    """Validate a sensor table (see the module docstring); returns a clean copy with typed columns.

    Rules: every column present; unique non-empty names; ``quantity`` in
    :data:`QUANTITIES`; at most one speed, one position and one balise channel,
    and a speed or a position channel (the estimator derives the other); at
    least two acceleration channels; accelerations have
    ``wheelset`` 1/2, ``side`` L/R, ``direction`` x/y/z, finite ``x, y, z`` with
    the mounting point on its side of the car (``y <= 0`` for L), a finite
    non-zero sensitivity and a unit of their quantity; a sensitivity more than
    20 % away from the unit's SI factor is refused (a g channel with
    sensitivity 1 is a common mistake).
    """
    if len(df) > MAX_ROWS:
        raise SensorTableError(f"{source}: {len(df)} rows; at most {MAX_ROWS}")
    df = df.copy()
    df.columns = [str(c).strip().lower() for c in df.columns]
    missing = [c for c in SENSOR_COLUMNS if c not in df.columns]
    if missing:
        raise SensorTableError(f"{source}: missing column(s) {missing}; a sensor table has columns "
                               f"{list(SENSOR_COLUMNS)} (field contract)")
    if df.empty:
        raise SensorTableError(f"{source}: no rows")
    df["name"] = df["name"].astype(str).str.strip()
    if (df["name"] == "").any() or df["name"].isin(["nan", "None"]).any():
        raise SensorTableError(f"{source}: every row needs a channel name")
    dup = sorted(df.loc[df["name"].duplicated(), "name"])
    if dup:
        raise SensorTableError(f"{source}: channel names must be unique, repeated: {dup}")
    df["quantity"] = df["quantity"].astype(str).str.strip().str.lower()
    bad = df.loc[~df["quantity"].isin(QUANTITIES)]
    if len(bad):
        i = bad.index[0]
        raise SensorTableError(f"{source}: row {i + 2} ({df['name'][i]!r}): quantity must be one of {QUANTITIES}, "
                               f"got {df['quantity'][i]!r}")
    counts = df["quantity"].value_counts()
    for q in ("speed", "position", "balise"):
        n = int(counts.get(q, 0))
        if n > 1:
            raise SensorTableError(f"{source}: at most one {q} channel expected, found {n}")
    if not counts.get("speed", 0) and not counts.get("position", 0):
        raise SensorTableError(f"{source}: no speed and no position channel; the run's chainage needs at least one "
                               "of them (both preferred: the other is derived from the one recorded)")
    if int(counts.get("acceleration", 0)) < 2:
        raise SensorTableError(f"{source}: at least two acceleration channels are needed (two vertical per wheelset "
                               f"for the full models), found {int(counts.get('acceleration', 0))}")
    df["unit"] = [normalise_unit(u) for u in df["unit"]]
    acc = np.flatnonzero(df["quantity"].to_numpy() == "acceleration")
    sens = _num(df, "sensitivity", source, range(len(df)))
    for i in range(len(df)):
        q, u = df["quantity"].iloc[i], df["unit"].iloc[i]
        if u not in _QUANTITY_UNITS[q]:
            raise SensorTableError(f"{source}: row {i + 2} ({df['name'].iloc[i]!r}): unit of a {q} channel must be "
                                   f"one of {list(_QUANTITY_UNITS[q])}, got {df['unit'].iloc[i]!r}")
        if sens[i] == 0:
            raise SensorTableError(f"{source}: row {i + 2} ({df['name'].iloc[i]!r}): sensitivity must be non-zero")
        ref = UNIT_TO_SI[u]
        if not 0.8 <= abs(sens[i]) / ref <= 1.25:
            raise SensorTableError(
                f"{source}: row {i + 2} ({df['name'].iloc[i]!r}): sensitivity {sens[i]:g} does not convert {u} to SI "
                f"(expected about {ref:g}, within -20/+25 %); the sensitivity is the factor giving "
                f"{'m/s^2' if q == 'acceleration' else 'SI'} from the recorded values")
    df["sensitivity"] = sens
    ws = pd.to_numeric(df["wheelset"], errors="coerce").astype(float)  # (a nullable Int64 column: NA -> NaN)
    is_acc = df["quantity"].to_numpy() == "acceleration"
    for i in range(len(df)):
        if is_acc[i]:
            if ws.iloc[i] not in (1, 2):
                raise SensorTableError(f"{source}: row {i + 2} ({df['name'].iloc[i]!r}): wheelset must be 1 or 2 for "
                                       f"an acceleration, got {_show(df['wheelset'].iloc[i])} (the instrumented "
                                       f"bogie's two wheelsets, 1 at the car's front end: a vehicle's axles 3 and 4 "
                                       f"are 1 and 2 here)")
        elif not _blank(df["wheelset"].iloc[i]) and ws.iloc[i] not in (0, 1, 2):
            # a speed, position or balise channel belongs to no wheelset: a value there is a slip (a shifted row)
            raise SensorTableError(f"{source}: row {i + 2} ({df['name'].iloc[i]!r}): wheelset of a "
                                   f"{df['quantity'].iloc[i]} channel must be empty (or 0, 1, 2), got "
                                   f"{_show(df['wheelset'].iloc[i])}")
    df["wheelset"] = ws.where(is_acc, 0).fillna(0).astype(int)
    for col, allowed in (("side", ("L", "R")), ("direction", ("x", "y", "z"))):
        vals = df[col].astype(str).str.strip()
        vals = vals.str.upper() if col == "side" else vals.str.lower()
        for i in acc:
            if vals.iloc[i] not in allowed:
                raise SensorTableError(f"{source}: row {i + 2} ({df['name'].iloc[i]!r}): {col} must be one of "
                                       f"{allowed}, got {df[col].iloc[i]!r}")
        df[col] = vals.where(df["quantity"] == "acceleration", "")
    xyz = {c: _num(df, c, source, acc) for c in ("x", "y", "z")}
    for c in ("x", "y", "z"):
        # unused for speed, position and balise rows, but a value given there must still be a number: inf or text
        # in a cell is a broken row (a shifted column), not something to drop without a word
        for i in np.flatnonzero(~is_acc):
            v = df[c].iloc[i]
            if not _blank(v) and not np.isfinite(xyz[c][i]):
                raise SensorTableError(f"{source}: row {i + 2} ({df['name'].iloc[i]!r}): column {c!r} must be empty "
                                       f"or a finite number, got {_show(v)}")
    for c in ("x", "y", "z"):
        df[c] = xyz[c]
    for i in acc:
        side, y = df["side"].iloc[i], xyz["y"][i]
        if (side == "L" and y > 0) or (side == "R" and y < 0):
            raise SensorTableError(f"{source}: row {i + 2} ({df['name'].iloc[i]!r}): side {side} but y = {y:g} m; "
                                   "the vehicle's left side is at -y (field contract), so y <= 0 on L and >= 0 on R")
        if max(abs(xyz[c][i]) for c in ("x", "y", "z")) > 3.0:
            raise SensorTableError(f"{source}: row {i + 2} ({df['name'].iloc[i]!r}): mounting point "
                                   f"({xyz['x'][i]:g}, {y:g}, {xyz['z'][i]:g}) m is more than 3 m from the wheelset "
                                   "centre; x, y, z are in metres relative to the wheelset's centre")
    return df.loc[:, list(SENSOR_COLUMNS)].reset_index(drop=True)
