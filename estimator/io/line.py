"""The line description (``line.json`` of the field contract) and trolley reference files.

``line.json``: ``name, id, length, sleeper spacing, sections [{id, from_m, to_m}],
curves [{from_m, to_m, radius_m, direction 'left'/'right', cant_mm,
transition_in_m, transition_out_m}], switches [{id, from_m, to_m,
crossing_m, crossing_rail}], welds [{chainage_m, rail}], balises [{id,
chainage_m}], stations, trackform sections [{from_m, to_m, trackform name,
the receptance.Trackform fields}], speed limits``. Curvature and cant ramp
linearly along the transitions (clothoids with linear cant ramps). A curve's
``direction`` is the way it turns looking towards increasing chainage; its
low (inner) rail is ``R`` for a right curve and ``L`` for a left one.

:func:`read_line` refuses what it cannot read as meant, naming the file and
the entry (:class:`~estimator.errors.RunFileError`): stretches run towards
increasing chainage and have a length; sections, curves and trackform
sections may touch but not overlap (nested sections are not supported);
a weld's or crossing's rail is ``L``, ``R`` or left out for both. A
``format`` other than ``railmodal-line`` or a ``version`` newer than this
reader's is refused; so is a top-level key that is a near miss of one it
reads (``curvse``: the curves would be silently absent). Other unknown
top-level keys are kept in ``raw`` and named in a warning, and a file that
holds nothing the estimate uses is warned about.

Trolley files (``trolley/<date>.csv``): ``chainage_m, rail, roughness_um``.
"""

from __future__ import annotations

import difflib
import json
import logging
import math
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Mapping

import numpy as np
import pandas as pd

from estimator.errors import RunFileError
from receptance.trackform import PLAUSIBLE, DuplicateJSONKey, Trackform, TrackformError, unique_json_keys

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


# --------------------------------------------------------------------------- reading line.json
_REQUIRED = object()

#: Keys a trackform section takes besides the Trackform fields: its stretch, its name (``trackform``, as the
#: virtual line writes it, or ``name``/``id``), free-text notes (the virtual line writes ``note``) and
#: ``parameters``, the Trackform fields as a nested object.
_TRACKFORM_SECTION_KEYS = ("from_m", "to_m", "trackform", "name", "id", "note", "notes", "description", "comment",
                           "parameters")
_TRACKFORM_FIELD_ORDER = tuple(f.name for f in fields(Trackform))
#: Sleeper spacings a line may state [m]: the physical range of a Trackform's support spacing, so that a spacing
#: in mm (600) or a sign slip is refused rather than combing the spectra at a wavelength that is not there.
_SLEEPER_SPACING_RANGE_M = PLAUSIBLE["support_spacing"]["physical"]
#: Curve radii a line may state [m]. The tightest curves rail vehicles run through are a tramway's, about 15-25 m
#: (metros rarely go below 60-100 m; 10 m leaves a margin below the tightest tram curve); beyond 100 km a curve
#: bends the track less than its alignment tolerances do (mainline curves stay below ~10-15 km). A radius outside
#: is a slip or another unit (a radius in km: 0.3; in mm: 400000) and would change the estimate's contact angles.
CURVE_RADIUS_RANGE_M = (10.0, 100_000.0)
#: Cant (superelevation) a line may state [mm]: 0 to 200 mm (EN 13803 allows up to 180-200 mm on ballasted and slab
#: track; no line raises the inner rail over a curve's body). A non-zero cant below 1 mm is a cant in m (0.04 for
#: 40 mm): cants are set in whole millimetres.
CANT_RANGE_MM = (0.0, 200.0)


def _json_kind(v) -> str:
    """``v`` as the JSON reader sees it (for messages): its JSON type and a short rendering."""
    if v is None:
        return "null"
    # bool before int: JSON true/false arrive as Python bools, which are ints too
    kinds = ((bool, "true/false"), ((int, float), "a number"), (str, "a string"), (list, "a list"),
             (dict, "an object"))
    kind = next((name for t, name in kinds if isinstance(v, t)), type(v).__name__)
    text = repr(v)
    return f"{kind} {text if len(text) <= 80 else text[:77] + '...'}"


def _num(d: Mapping, key: str, src: str, item: str = "", default=_REQUIRED) -> float:
    """``d[key]`` as a finite float, ``default`` when absent.

    Parameters
    ----------
    d : mapping
        The JSON object holding the value.
    key : str
    src : str
        The file, for messages.
    item : str
        How messages name the entry (``curve 'C1'``, ``welds[3]``); empty for the file's top level.
    default : float, optional
        The value when ``key`` is absent; without it an absent key is an error.

    Raises
    ------
    RunFileError
        Naming the file, the item and the key: absent (without a default), not a number, or not finite.
    """
    at = f"{src}: {item}: " if item else f"{src}: "
    if key not in d:
        if default is _REQUIRED:
            raise RunFileError(f"{at}{key!r} is missing")
        return default
    v = d[key]
    # JSON true/false would pass float() as 1/0: a flag where a chainage belongs is a slip, not a number
    if isinstance(v, bool):
        raise RunFileError(f"{at}{key!r} must be a number, got {v!r}")
    try:
        x = float(v)
    except (TypeError, ValueError, OverflowError):
        hint = " (with a decimal point, not a comma)" if isinstance(v, str) and "," in v else ""
        raise RunFileError(f"{at}{key!r} must be a number{hint}, got {_json_kind(v)}") from None
    if not math.isfinite(x):
        raise RunFileError(f"{at}{key!r} must be finite, got {v!r}")
    return x


def _given(d: Mapping, keys: tuple[str, ...], src: str) -> str | None:
    """Which of ``keys`` (a name and its aliases) the file uses; None when none.

    Two of them with different values would leave one silently unread, so that is refused.
    """
    given = [k for k in keys if k in d]
    for k in given[1:]:
        if d[k] != d[given[0]]:
            raise RunFileError(f"{src}: both {given[0]!r} and {k!r} are given, with different values; "
                               f"give one of them")
    return given[0] if given else None


def _entries(d: Mapping, keys: tuple[str, ...], src: str) -> tuple[str, list[dict]]:
    """The list of objects under ``keys[0]`` (or an alias) and the key it came under; ``[]`` when absent.

    Raises
    ------
    RunFileError
        When the value is not a list (an object, null, a number) or an entry is not an object (a bare list of
        numbers would leave which number is which to guessing).
    """
    key = _given(d, keys, src)
    if key is None:
        return keys[0], []
    v = d[key]
    if not isinstance(v, list):
        raise RunFileError(f"{src}: {key!r} must be a list of objects [{{...}}, ...], got {_json_kind(v)}")
    for i, e in enumerate(v):
        if not isinstance(e, dict):
            raise RunFileError(f"{src}: {key}[{i}] must be an object with named fields (like "
                               f'{{"from_m": 0, "to_m": 100}}), got {_json_kind(e)}')
    return key, v


def _ident(e: Mapping) -> str | None:
    """The entry's ``id`` as text, None when it has none."""
    v = e.get("id")
    return None if v is None or v == "" else str(v)


def _label(e: Mapping, kind: str, key: str, i: int) -> str:
    """How messages name an entry: ``section 'S1'`` by its id, else by its place in the list, ``sections[2]``."""
    ident = _ident(e)
    return f"{kind} {ident!r}" if ident is not None else f"{key}[{i}]"


def _stretch(e: Mapping, src: str, item: str) -> tuple[float, float]:
    """``(from_m, to_m)`` of a stretch, which runs towards increasing chainage and has a length.

    A reversed or zero-length stretch holds no chainage: every lookup would miss it (no rows, zero curvature).
    """
    a, b = _num(e, "from_m", src, item), _num(e, "to_m", src, item)
    if a > b:
        raise RunFileError(f"{src}: {item}: from_m {a:g} > to_m {b:g} (a stretch runs towards increasing "
                           "chainage)")
    if a == b:
        raise RunFileError(f"{src}: {item}: from_m = to_m = {a:g}, a stretch of zero length")
    return a, b


def _no_overlap(spans: list[tuple[str, float, float]], src: str, why: str) -> None:
    """Refuse two of ``(label, from_m, to_m)`` sharing more than an end point.

    Sorted by start, any overlap shows between neighbours, so one pass finds it.
    """
    s = sorted(spans, key=lambda t: (t[1], t[2]))
    for (ia, a0, a1), (ib, b0, b1) in zip(s, s[1:]):
        if b0 < a1:
            raise RunFileError(f"{src}: {ia} ({a0:g}-{a1:g} m) and {ib} ({b0:g}-{b1:g} m) overlap; {why}")


def _unique_ids(spans: list[tuple[str, float, float]], src: str, kind: str, why: str) -> None:
    """Refuse an id given to two of ``(id, from_m, to_m)``."""
    seen: dict[str, tuple[float, float]] = {}
    for ident, a, b in spans:
        if ident in seen:
            raise RunFileError(f"{src}: {kind} id {ident!r} is given twice ({seen[ident][0]:g}-{seen[ident][1]:g} m "
                               f"and {a:g}-{b:g} m); {why}")
        seen[ident] = (a, b)


def _rail(e: Mapping, key: str, src: str, item: str) -> None:
    """Refuse a rail other than ``L``/``R`` (any case); absent, null or empty means both rails.

    That is how the alignment reads welds and crossing noses (:func:`estimator.monitoring.alignment._line_features`);
    there a weld on ``"left"`` would match neither rail and vanish, and a crossing on ``"left"`` would count on
    both.
    """
    v = e.get(key)
    if v is None or v == "":
        return
    if not isinstance(v, str) or v.upper() not in ("L", "R"):
        raise RunFileError(f"{src}: {item}: {key!r} must be 'L' or 'R' (rails named looking towards increasing "
                           f"chainage), or left out for both rails; got {_json_kind(v)}")


def _curve(e: Mapping, i: int, src: str) -> Curve:
    """One entry of ``curves`` (module docstring), checked: a stretch, a radius, transitions that fit."""
    item = _label(e, "curve", "curves", i)
    direction = str(e.get("direction", "")).lower()
    if direction not in ("left", "right"):
        raise RunFileError(f"{src}: {item}: direction must be 'left' or 'right', got {e.get('direction')!r}")
    r = _num(e, "radius_m", src, item)
    if r <= 0:
        raise RunFileError(f"{src}: {item}: radius_m must be > 0, got {r:g}")
    lo, hi = CURVE_RADIUS_RANGE_M
    if not lo <= r <= hi:
        hint = next((f" (a radius in {u}? {r * f:g} m)" for f, u in ((1e-3, "mm"), (1e3, "km"))
                     if lo <= r * f <= hi), "")
        raise RunFileError(f"{src}: {item}: radius_m {r:g} m is outside {lo:g}-{hi:g} m{hint}; the tightest tram "
                           "curves are about 15-25 m, and a curve flatter than 100 km is a straight")
    cant = _num(e, "cant_mm", src, item, 0.0)
    lo, hi = CANT_RANGE_MM
    if not lo <= cant <= hi or 0 < cant < 1:
        hint = (f" (a cant in m? {cant * 1e3:g} mm)" if 0 < cant < 1 else
                f" (a cant in um? {cant * 1e-3:g} mm)" if lo <= cant * 1e-3 <= hi and cant > hi else "")
        raise RunFileError(f"{src}: {item}: cant_mm {cant:g} mm is outside {lo:g}-{hi:g} mm{hint}; cant is the "
                           "outer rail's superelevation in whole millimetres")
    a, b = _stretch(e, src, item)
    t_in, t_out = _num(e, "transition_in_m", src, item, 0.0), _num(e, "transition_out_m", src, item, 0.0)
    for key, t in (("transition_in_m", t_in), ("transition_out_m", t_out)):
        if t < 0:
            raise RunFileError(f"{src}: {item}: {key} must be >= 0, got {t:g}")
    # the two ramps would cross below 1: the curvature would never reach 1/R nor the cant its value
    if t_in + t_out - (b - a) > 1e-9 * max(1.0, b - a):
        raise RunFileError(f"{src}: {item}: transitions {t_in:g} m + {t_out:g} m are longer than the curve "
                           f"({a:g}-{b:g} m, {b - a:g} m); its curvature would never reach 1/radius_m")
    return Curve(_ident(e) or f"curve_{i + 1}", a, b, r, direction, cant, t_in, t_out)


def _trackform_section(e: Mapping, i: int, key: str, src: str) -> TrackSection:
    """One trackform section: its stretch and the Trackform of its flat or nested (``parameters``) fields.

    Every key must be known: a misspelt field (``pad_stifness``) would otherwise leave the trackform at its
    default unannounced.
    """
    name = str(e.get("trackform", e.get("name", e.get("id", f"trackform_{i + 1}"))))
    item = f"{key}[{i}] {name!r}"
    nested = e.get("parameters")
    if nested is None:
        nested = {}
    if not isinstance(nested, dict):
        raise RunFileError(f"{src}: {item}: 'parameters' must be an object of Trackform fields, got "
                           f"{_json_kind(nested)}")
    unknown = [k for k in e if k not in _TRACKFORM_FIELDS and k not in _TRACKFORM_SECTION_KEYS]
    unknown += [f"parameters.{k}" for k in nested if k not in _TRACKFORM_FIELDS]
    if unknown:
        valid = _TRACKFORM_SECTION_KEYS + _TRACKFORM_FIELD_ORDER
        hints = []
        for k in unknown:
            close = difflib.get_close_matches(k.removeprefix("parameters."), valid, n=1, cutoff=0.75)
            if close:
                hints.append(f"{k!r}: did you mean {close[0]!r}?")
        raise RunFileError(f"{src}: {item}: unknown key(s) {', '.join(map(repr, unknown))}"
                           + (f" ({'; '.join(hints)})" if hints else "")
                           + f"; a trackform section takes {', '.join(_TRACKFORM_SECTION_KEYS)} and the Trackform "
                           f"fields {', '.join(_TRACKFORM_FIELD_ORDER)}")
    flat = {k: v for k, v in e.items() if k in _TRACKFORM_FIELDS}
    twice = [k for k in flat if k in nested and nested[k] != flat[k]]
    if twice:
        raise RunFileError(f"{src}: {item}: {', '.join(map(repr, twice))} given both flat and in 'parameters', "
                           "with different values; give each once")
    a, b = _stretch(e, src, item)
    params = {**flat, **nested}
    tf = None
    if params:
        try:
            tf = Trackform(**params)
        except (TrackformError, TypeError) as exc:
            # Trackform names itself "<Trackform(...)>"; the item already says where the value came from
            raise RunFileError(f"{src}: {item}: {str(exc).replace('<Trackform(...)>: ', '')}") from None
    return TrackSection(name, a, b, tf)


def _switch(e: Mapping, i: int, src: str) -> tuple[float, float]:
    """One switch: its stretch; its crossing nose (``crossing_m``, ``crossing_rail``) checked for the alignment."""
    item = _label(e, "switch", "switches", i)
    a, b = _stretch(e, src, item)
    # the alignment skips a crossing whose chainage is not a number (a feature lost unannounced)
    if "crossing_m" in e:
        _num(e, "crossing_m", src, item)
    _rail(e, "crossing_rail", src, item)
    return a, b


def _weld(e: Mapping, i: int, src: str) -> float:
    """One weld's chainage; its ``rail`` (L, R, or absent for both) checked for the alignment."""
    item = f"welds[{i}]"
    x = _num(e, "chainage_m", src, item)
    _rail(e, "rail", src, f"{item} at {x:g} m")
    return x


def _positive(d: Mapping, keys: tuple[str, ...], src: str, default: float) -> float:
    """A top-level number > 0 under ``keys[0]`` or an alias, ``default`` when absent."""
    key = _given(d, keys, src)
    if key is None:
        return default
    v = _num(d, key, src)
    if v <= 0:
        raise RunFileError(f"{src}: {key!r} must be > 0, got {v:g}")
    return v


#: the line description's format name and the newest version this reader reads
LINE_FORMAT, LINE_VERSION = "railmodal-line", 1
#: top-level keys read into the description, and those kept as information (the virtual line writes them)
_LINE_KEYS = ("curves", "sections", "trackforms", "trackform_sections", "balises", "switches", "welds", "length_m",
              "length", "sleeper_spacing_m", "sleeper_spacing", "name", "id")
_LINE_INFO_KEYS = ("format", "version", "stations", "speed_limits", "notes", "note", "description", "comment")


def _top_level(d: Mapping, src: str) -> None:
    """Refuse another format, a newer version and a near-miss key; warn of other unknown keys (module docstring)."""
    fmt = d.get("format", LINE_FORMAT)
    if fmt != LINE_FORMAT:
        raise RunFileError(f"{src}: format {fmt!r}; this reader reads {LINE_FORMAT!r} line descriptions")
    version = d.get("version", LINE_VERSION)
    if not (isinstance(version, (int, float)) and not isinstance(version, bool) and 1 <= version <= LINE_VERSION):
        raise RunFileError(f"{src}: version {version!r}; this reader reads {LINE_FORMAT!r} versions 1 to "
                           f"{LINE_VERSION} (a newer toolkit wrote it?)")
    known = _LINE_KEYS + _LINE_INFO_KEYS
    unknown = [k for k in d if k not in known]
    for k in unknown:
        near = difflib.get_close_matches(str(k).lower(), _LINE_KEYS, n=1, cutoff=0.75)
        if near and near[0] not in d:
            raise RunFileError(f"{src}: top-level key {k!r} is not one a line description takes; did you mean "
                               f"{near[0]!r}? (as written, the file would be read without its {near[0]})")
    if unknown:
        log.warning("%s: top-level key(s) %s are not part of a line description; kept, not used", src, unknown)
    if not any(k in d for k in _LINE_KEYS[:7]):
        log.warning("%s: holds none of %s; the estimate uses straight track and the default trackform everywhere",
                    src, ", ".join(_LINE_KEYS[:7]))


def read_line(path) -> LineDescription:
    """Read and check ``line.json`` (field contract, module docstring); unknown top-level keys are kept in ``raw``.

    Every entry the estimator uses is checked, and refused by name (the file and the entry, ``section 'S1'`` or
    ``curves[2]``) rather than read into something else: lists that are not lists of objects, numbers that are
    not numbers, stretches that are reversed or of zero length, curves whose transitions do not fit, overlapping
    sections, curves or trackform sections (each chainage has one), repeated section or curve ids, unknown
    trackform keys, weld and crossing rails other than L/R, a sleeper spacing outside 0.1-5 m.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    LineDescription

    Raises
    ------
    FileNotFoundError
        When the file does not exist.
    RunFileError
        Naming the file and the offending entry and value.
    """
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"line description {p} does not exist")
    if p.stat().st_size > MAX_LINE_BYTES:
        raise RunFileError(f"{p}: {p.stat().st_size} bytes; a line description is at most {MAX_LINE_BYTES}")
    try:
        d = json.loads(p.read_text(encoding="utf-8-sig"), object_pairs_hook=unique_json_keys)
    except DuplicateJSONKey as exc:
        raise RunFileError(f"{p}: key {exc.key!r} is given twice in one object ({exc.keys}); plain JSON keeps "
                           "the last one, so give each key once") from None
    except (ValueError, UnicodeDecodeError) as exc:
        raise RunFileError(f"{p}: not a JSON line description ({exc})") from None
    except RecursionError:
        raise RunFileError(f"{p}: not a JSON line description (lists or objects nested too deeply to read; a line "
                           "description nests a few levels)") from None
    if not isinstance(d, dict):
        raise RunFileError(f"{p}: a line description is a JSON object")
    src = str(p)
    _top_level(d, src)

    curves = [_curve(c, i, src) for i, c in enumerate(_entries(d, ("curves",), src)[1])]
    _unique_ids([(c.id, c.from_m, c.to_m) for c in curves], src, "curve",
                "curves are looked up by id (calibrated contact angles)")
    _no_overlap([(f"curve {c.id!r}", c.from_m, c.to_m) for c in curves], src,
                "curves may touch but not overlap (a chainage has one curvature and one cant)")

    sections = []
    for i, s in enumerate(_entries(d, ("sections",), src)[1]):
        item = _label(s, "section", "sections", i)
        sections.append(TrackSection(_ident(s) or f"section_{i + 1}", *_stretch(s, src, item)))
    _unique_ids([(s.id, s.from_m, s.to_m) for s in sections], src, "section",
                "results are reported per section id")
    # nested sections are not supported: the monitoring names a chainage by the section starting last before it
    # (estimator.monitoring.records.Sections.at), so an outer section would lose the chainages past an inner one
    _no_overlap([(f"section {s.id!r}", s.from_m, s.to_m) for s in sections], src,
                "sections may touch but not overlap or nest (each chainage belongs to one section)")

    tf_key, tf_entries = _entries(d, ("trackforms", "trackform_sections"), src)
    trackforms = [_trackform_section(t, i, tf_key, src) for i, t in enumerate(tf_entries)]
    # the estimate's track model takes the last section holding a chainage, trackform_at the first
    _no_overlap([(f"{tf_key}[{i}] {t.id!r}", t.from_m, t.to_m) for i, t in enumerate(trackforms)], src,
                "trackform sections may touch but not overlap (a chainage has one trackform)")

    balises = tuple((_ident(b) or str(i), _num(b, "chainage_m", src, _label(b, "balise", "balises", i)))
                    for i, b in enumerate(_entries(d, ("balises",), src)[1]))
    switches = tuple(_switch(s, i, src) for i, s in enumerate(_entries(d, ("switches",), src)[1]))
    welds = tuple(_weld(w, i, src) for i, w in enumerate(_entries(d, ("welds",), src)[1]))

    length = _positive(d, ("length_m", "length"), src, math.inf)
    spacing = _positive(d, ("sleeper_spacing_m", "sleeper_spacing"), src, 0.75)
    lo, hi = _SLEEPER_SPACING_RANGE_M
    if not lo <= spacing <= hi:
        raise RunFileError(f"{src}: sleeper spacing {spacing:g} m is outside {lo:g}-{hi:g} m (a spacing in mm?)")
    return LineDescription(name=str(d.get("name", "")), id=str(d.get("id", "")), length_m=length,
                           sleeper_spacing_m=spacing, sections=tuple(sections), curves=tuple(curves),
                           trackforms=tuple(trackforms), balises=balises, switches=switches, welds=welds, source=src,
                           raw=d)


def _trolley_csv(p: Path) -> pd.DataFrame:
    """The trolley file as pandas reads it; an empty or unparsable file is a RunFileError naming it.

    pandas' own errors (``No columns to parse from file``, ``Expected 3 fields in line 7``) do not say which file,
    and a run given several references could not tell them apart.
    """
    try:
        return pd.read_csv(p, encoding="utf-8-sig")
    except pd.errors.EmptyDataError:
        raise RunFileError(f"{p}: the trolley file is empty; expected a header chainage_m, rail, roughness_um and "
                           "one row per reading") from None
    except UnicodeDecodeError as exc:
        raise RunFileError(f"{p}: not a text (UTF-8) trolley CSV ({exc.reason})") from None
    except (pd.errors.ParserError, ValueError) as exc:
        raise RunFileError(f"{p}: not a readable trolley CSV ({str(exc).strip()})") from None


def _iso3095_rms_um() -> float:
    """RMS [µm] of a rail exactly at the ISO 3095:2013 limit spectrum over its 22 one-third octaves (3.15 mm to
    0.4 m): the energy sum of the limit levels (dB re 1 µm)."""
    from estimator.standards.iso3095 import ISO3095_LIMIT_DB

    return float(math.sqrt(sum(10 ** (v / 10) for v in ISO3095_LIMIT_DB.values())))


#: RMS [µm] of a rail at the ISO 3095:2013 limit spectrum, 3.15 mm - 0.4 m (about 11.7 µm): the yardstick of a
#: trolley record's level.
ISO3095_LIMIT_RMS_UM = _iso3095_rms_um()
#: A trolley record's RMS roughness (each rail, about its median) in µm within which no remark is made: from
#: -32 dB to +39 dB re the ISO 3095 limit's RMS. Acoustically ground rails sit 10-20 dB below the limit; severe
#: corrugation stands 20-30 dB above it in its band, and long-wave irregularity (to 1 m) adds up to a few hundred
#: µm. Outside this range the record is logged and reported as implausible (WARNING, in the report).
TROLLEY_RMS_PLAUSIBLE_UM = (0.3, 1000.0)
#: Beyond these RMS levels [µm] a record is refused (RunFileError): below 0.1 µm (-41 dB re the limit's RMS, below
#: any ground rail and at the displacement resolution of roughness trolleys), above 10 mm (+59 dB: a track-geometry
#: record or a unit error). A unit mix-up moves the level by 60 dB (mm or nm as µm) or 120 dB (m as µm), so it
#: lands here for any real rail.
TROLLEY_RMS_LIMITS_UM = (0.1, 10_000.0)


def _likely_unit(level_um: float) -> str:
    """Which unit mix-up brings an implausible RMS level [µm] into the plausible range (empty when none)."""
    lo, hi = TROLLEY_RMS_PLAUSIBLE_UM
    for factor, what in ((1e3, "values in mm written under roughness_um"), (1e6, "values in m written under "
                                                                                  "roughness_um"),
                         (1e-3, "values in nm (or µm multiplied by 1000) written under roughness_um")):
        if lo <= level_um * factor <= hi:
            return f"; likely {what} ({level_um * factor:.3g} µm RMS once converted)"
    return ""


def _trolley_level(p: Path, out: pd.DataFrame) -> list[str]:
    """Check each rail's RMS roughness against :data:`TROLLEY_RMS_LIMITS_UM` (RunFileError beyond) and
    :data:`TROLLEY_RMS_PLAUSIBLE_UM` (returned remarks, logged as WARNINGs)."""
    notes = []
    for rail, g in out.groupby("rail", sort=True):
        r = g["roughness_m"].to_numpy(float) * 1e6
        if r.size < 2:
            continue
        level = float(np.sqrt(np.mean((r - np.median(r)) ** 2)))
        rel = 20 * math.log10(level / ISO3095_LIMIT_RMS_UM) if level > 0 else -math.inf
        what = (f"{p}: rail {rail}: RMS roughness {level:.3g} µm ({rel:+.0f} dB re the ISO 3095 limit's "
                f"{ISO3095_LIMIT_RMS_UM:.1f} µm)")
        lo, hi = TROLLEY_RMS_LIMITS_UM
        if not lo <= level <= hi:
            raise RunFileError(f"{what} is not a rail roughness record in µm (refused outside {lo:g}-{hi:g} µm)"
                               f"{_likely_unit(level)}")
        lo, hi = TROLLEY_RMS_PLAUSIBLE_UM
        if not lo <= level <= hi:
            note = (f"{what} is outside the {lo:g}-{hi:g} µm of real rails{_likely_unit(level)}; the comparison "
                    "with it is doubtful")
            log.warning("%s", note)
            notes.append(note)
    return notes


def read_trolley(path) -> pd.DataFrame:
    """Read a trolley reference file: ``chainage_m, rail, roughness_um`` → columns in SI plus ``roughness_um``.

    Returns a frame with ``chainage_m, rail, roughness_m`` sorted by rail and chainage. Rows whose chainage or
    roughness is not a finite number are left out and named (file line numbers) in a WARNING: the reference
    comparison then sees a gap there and does not bridge it. A chainage given twice on one rail (two passes pasted
    into one file) is a RunFileError, since which of the two readings holds cannot be told. Each rail's level is
    checked (:func:`_trolley_level`): a record many decades off a rail's roughness (mm, m or nm written as µm) is
    a RunFileError naming the likely unit; one merely outside the range of real rails is a WARNING, kept in
    ``attrs["notes"]`` of the frame for the report.
    """
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"trolley file {p} does not exist")
    df = _trolley_csv(p)
    need = [c for c in ("chainage_m", "rail", "roughness_um") if c not in df.columns]
    if need:
        raise RunFileError(f"{p}: trolley file lacks column(s) {need} (chainage_m, rail, roughness_um)")
    df["rail"] = df["rail"].astype(str).str.upper()
    bad = sorted(set(df["rail"].unique()) - {"L", "R"})
    if bad:
        raise RunFileError(f"{p}: rail must be L or R, got {bad}")
    out = pd.DataFrame({"chainage_m": pd.to_numeric(df["chainage_m"], errors="coerce"), "rail": df["rail"],
                        "roughness_m": pd.to_numeric(df["roughness_um"], errors="coerce") * 1e-6})
    # inf is no reading either (a logger's overflow, 'inf' in the file): left out like text, and named
    finite = np.isfinite(out[["chainage_m", "roughness_m"]].to_numpy(float)).all(axis=1)
    bad_rows = out.index[~finite]
    notes = []
    if len(bad_rows):
        note = (f"{p}: {len(bad_rows)} trolley row(s) without a numeric chainage or roughness left out (file "
                f"line(s) {', '.join(str(i + 2) for i in bad_rows[:10])}{', ...' if len(bad_rows) > 10 else ''}) "
                "(text, blanks, NaN and inf are no reading); the comparison interpolates across up to 5 missing "
                "samples, longer stretches are gaps")
        log.warning("%s", note)
        notes.append(note)
    out = out[finite].sort_values(["rail", "chainage_m"], kind="stable").reset_index(drop=True)
    if out.empty:
        raise RunFileError(f"{p}: no trolley row with a finite numeric chainage and roughness ({len(df)} row(s) in "
                           "the file); nothing to compare with")
    twice = out[out.duplicated(["rail", "chainage_m"], keep=False)]
    if len(twice):
        counts = twice.groupby(["rail", "chainage_m"], sort=True).size()
        (r, x), k = counts.index[0], int(counts.iloc[0])
        raise RunFileError(f"{p}: rail {r}: chainage {x:.4f} m is given {k} times ({len(counts)} repeated "
                           "chainage(s) in all); a trolley record holds one reading per rail and chainage")
    notes += _trolley_level(p, out)
    out.attrs["source"] = str(p)
    out.attrs["notes"] = tuple(notes)
    return out
