"""The line description (``line.json`` of the field contract) and trolley reference files.

``line.json``: ``name, id, length, sleeper spacing, sections [{id, from_m, to_m}],
curves [{from_m, to_m, radius_m, direction 'left'/'right', cant_mm,
transition_in_m, transition_out_m}], switches, welds, balises [{id,
chainage_m}], stations, trackform sections [{from_m, to_m, trackform name,
the receptance.Trackform fields}], speed limits``. Curvature and cant ramp
linearly along the transitions (clothoids with linear cant ramps). A curve's
``direction`` is the way it turns looking towards increasing chainage; its
low (inner) rail is ``R`` for a right curve and ``L`` for a left one.

Trolley files (``trolley/<date>.csv``): ``chainage_m, rail, roughness_um``.
"""

from __future__ import annotations

import json
import logging
import math
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Mapping

import numpy as np
import pandas as pd

from estimator.errors import RunFileError
from receptance.trackform import Trackform, TrackformError

__all__ = ["Curve", "TrackSection", "LineDescription", "read_line", "read_trolley", "MAX_LINE_BYTES"]

log = logging.getLogger("estimator")

MAX_LINE_BYTES = 20_000_000
_TRACKFORM_FIELDS = {f.name for f in fields(Trackform)}


@dataclass(frozen=True)
class Curve:
    id: str
    from_m: float
    to_m: float
    radius_m: float
    direction: str
    cant_mm: float = 0.0
    transition_in_m: float = 0.0
    transition_out_m: float = 0.0

    @property
    def low_rail(self) -> str:
        """The inner (low) rail, named as the line names rails (L/R looking towards increasing chainage)."""
        return "R" if self.direction == "right" else "L"

    @property
    def high_rail(self) -> str:
        return "L" if self.low_rail == "R" else "R"

    @property
    def sign(self) -> float:
        """+1 for a left curve (positive signed curvature), −1 for a right one."""
        return 1.0 if self.direction == "left" else -1.0

    def ramp(self, s: np.ndarray) -> np.ndarray:
        """0 outside, 1 on the circular body, linear along the transitions."""
        s = np.asarray(s, float)
        a, b = self.from_m, self.to_m
        ti, to = max(self.transition_in_m, 1e-9), max(self.transition_out_m, 1e-9)
        up = np.clip((s - a) / ti, 0, 1)
        down = np.clip((b - s) / to, 0, 1)
        return np.where((s >= a) & (s <= b), np.minimum(up, down), 0.0)


@dataclass(frozen=True)
class TrackSection:
    """A named stretch ``[from_m, to_m]`` (a line section, or a trackform section with its Trackform)."""

    id: str
    from_m: float
    to_m: float
    trackform: Trackform | None = None


@dataclass(frozen=True, eq=False)
class LineDescription:
    """What the estimator uses of ``line.json``: sections, curves, balises, trackforms."""

    name: str = ""
    id: str = ""
    length_m: float = math.inf
    sleeper_spacing_m: float = 0.75
    sections: tuple[TrackSection, ...] = ()
    curves: tuple[Curve, ...] = ()
    trackforms: tuple[TrackSection, ...] = ()
    balises: tuple[tuple[str, float], ...] = ()
    switches: tuple[tuple[float, float], ...] = ()
    welds: tuple[float, ...] = ()
    source: str = ""
    raw: Mapping = field(default_factory=dict, repr=False)

    def curvature(self, s) -> np.ndarray:
        """Signed curvature [1/m] at chainage ``s`` (positive for left curves)."""
        s = np.asarray(s, float)
        k = np.zeros_like(s)
        for c in self.curves:
            k = k + c.sign / c.radius_m * c.ramp(s)
        return k

    def cant_angle(self, s, rail_spacing_m: float = 1.5) -> np.ndarray:
        """Cant angle [rad] ``h/s`` (positive: the curve's outer rail raised)."""
        s = np.asarray(s, float)
        out = np.zeros_like(s)
        for c in self.curves:
            out = out + c.cant_mm * 1e-3 / rail_spacing_m * c.ramp(s)
        return out

    def curve_at(self, s: float) -> Curve | None:
        for c in self.curves:
            if c.from_m <= s <= c.to_m:
                return c
        return None

    def trackform_at(self, s: float) -> Trackform | None:
        for t in self.trackforms:
            if t.from_m <= s <= t.to_m:
                return t.trackform
        return None

    def section_of(self, s: float) -> str:
        for sec in self.sections:
            if sec.from_m <= s <= sec.to_m:
                return sec.id
        return ""


def _f(d: Mapping, key: str, src: str, default=None) -> float:
    if key not in d:
        if default is None:
            raise RunFileError(f"{src}: entry {dict(d)!r} lacks {key!r}")
        return default
    try:
        v = float(d[key])
    except (TypeError, ValueError):
        raise RunFileError(f"{src}: {key!r} must be a number, got {d[key]!r}") from None
    if not math.isfinite(v):
        raise RunFileError(f"{src}: {key!r} must be finite, got {d[key]!r}")
    return v


def read_line(path) -> LineDescription:
    """Read ``line.json`` (field contract); unknown keys are kept in ``raw``.

    Raises
    ------
    FileNotFoundError, RunFileError
    """
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"line description {p} does not exist")
    if p.stat().st_size > MAX_LINE_BYTES:
        raise RunFileError(f"{p}: {p.stat().st_size} bytes; a line description is at most {MAX_LINE_BYTES}")
    try:
        d = json.loads(p.read_text(encoding="utf-8-sig"))
    except (ValueError, UnicodeDecodeError) as exc:
        raise RunFileError(f"{p}: not a JSON line description ({exc})") from None
    if not isinstance(d, dict):
        raise RunFileError(f"{p}: a line description is a JSON object")
    src = str(p)
    curves = []
    for i, c in enumerate(d.get("curves", [])):
        direction = str(c.get("direction", "")).lower()
        if direction not in ("left", "right"):
            raise RunFileError(f"{src}: curve {i}: direction must be 'left' or 'right', got {c.get('direction')!r}")
        r = _f(c, "radius_m", src)
        if r <= 0:
            raise RunFileError(f"{src}: curve {i}: radius_m must be > 0, got {r}")
        curves.append(Curve(str(c.get("id", f"curve_{i + 1}")), _f(c, "from_m", src), _f(c, "to_m", src), r,
                            direction, _f(c, "cant_mm", src, 0.0), _f(c, "transition_in_m", src, 0.0),
                            _f(c, "transition_out_m", src, 0.0)))
    sections = tuple(TrackSection(str(s.get("id", f"section_{i + 1}")), _f(s, "from_m", src), _f(s, "to_m", src))
                     for i, s in enumerate(d.get("sections", [])))
    trackforms = []
    for i, t in enumerate(d.get("trackforms", d.get("trackform_sections", []))):
        params = {k: v for k, v in t.items() if k in _TRACKFORM_FIELDS}
        if isinstance(t.get("parameters"), dict):
            params.update({k: v for k, v in t["parameters"].items() if k in _TRACKFORM_FIELDS})
        tf = None
        if params:
            try:
                tf = Trackform(**{**{f: getattr(Trackform(), f) for f in _TRACKFORM_FIELDS}, **params})
            except (TrackformError, TypeError) as exc:
                raise RunFileError(f"{src}: trackform section {i}: {exc}") from None
        name = str(t.get("trackform", t.get("name", t.get("id", f"trackform_{i + 1}"))))
        trackforms.append(TrackSection(name, _f(t, "from_m", src), _f(t, "to_m", src), tf))
    balises = tuple((str(b.get("id", i)), _f(b, "chainage_m", src)) for i, b in enumerate(d.get("balises", [])))
    switches = tuple((_f(s, "from_m", src), _f(s, "to_m", src)) for s in d.get("switches", []))
    welds = tuple(_f(w, "chainage_m", src) for w in d.get("welds", []))
    length = d.get("length_m", d.get("length", math.inf))
    spacing = d.get("sleeper_spacing_m", d.get("sleeper_spacing", 0.75))
    return LineDescription(name=str(d.get("name", "")), id=str(d.get("id", "")), length_m=float(length),
                           sleeper_spacing_m=float(spacing), sections=sections, curves=tuple(curves),
                           trackforms=tuple(trackforms), balises=balises, switches=switches, welds=welds, source=src,
                           raw=d)


def read_trolley(path) -> pd.DataFrame:
    """Read a trolley reference file: ``chainage_m, rail, roughness_um`` → columns in SI plus ``roughness_um``.

    Returns a frame with ``chainage_m, rail, roughness_m`` sorted by rail and chainage. Rows whose chainage or
    roughness is not a number are left out and named (file line numbers) in a WARNING: the reference comparison
    then sees a gap there and does not bridge it. A chainage given twice on one rail (two passes pasted into one
    file) is a RunFileError, since which of the two readings holds cannot be told.
    """
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"trolley file {p} does not exist")
    df = pd.read_csv(p, encoding="utf-8-sig")
    need = [c for c in ("chainage_m", "rail", "roughness_um") if c not in df.columns]
    if need:
        raise RunFileError(f"{p}: trolley file lacks column(s) {need} (chainage_m, rail, roughness_um)")
    df["rail"] = df["rail"].astype(str).str.upper()
    bad = sorted(set(df["rail"].unique()) - {"L", "R"})
    if bad:
        raise RunFileError(f"{p}: rail must be L or R, got {bad}")
    out = pd.DataFrame({"chainage_m": pd.to_numeric(df["chainage_m"], errors="coerce"), "rail": df["rail"],
                        "roughness_m": pd.to_numeric(df["roughness_um"], errors="coerce") * 1e-6})
    bad_rows = out.index[out.isna().any(axis=1)]
    if len(bad_rows):
        log.warning("%s: %d trolley row(s) without a numeric chainage or roughness left out (file line(s) %s%s); "
                    "the comparison treats them as a gap", p, len(bad_rows),
                    ", ".join(str(i + 2) for i in bad_rows[:10]), ", ..." if len(bad_rows) > 10 else "")
    out = out.dropna().sort_values(["rail", "chainage_m"], kind="stable").reset_index(drop=True)
    twice = out[out.duplicated(["rail", "chainage_m"], keep=False)]
    if len(twice):
        counts = twice.groupby(["rail", "chainage_m"], sort=True).size()
        (r, x), k = counts.index[0], int(counts.iloc[0])
        raise RunFileError(f"{p}: rail {r}: chainage {x:.4f} m is given {k} times ({len(counts)} repeated "
                           "chainage(s) in all); a trolley record holds one reading per rail and chainage")
    return out
