"""The virtual line's description: chainage, curves, cant, switch, welds, balises, stations, trackform sections.

The default line (:func:`default_line`) stands in for the *Conciliazione –
Pagano* section of Milan's M1 that thesis §4.3 analyses ("a series of two
curves and a switch", Fig. 4.8), stretched to 1.8 km between two stations:

======================  ==============  ================================================
chainage [m]            what            detail
======================  ==============  ================================================
0 – 140                 station A       *Conciliazione*, the bogie stops at 100 m
410 – 470               trackform       pads renewed with softer ones (documented change)
470 – 710               curve 1         right, R 400 m, cant 40 mm, 40 m clothoids
860 – 900               switch          turnout to the left, straight route; crossing at 892 m on rail R
1000 – 1240             curve 2         left, R 320 m, cant 50 mm, 40 m clothoids
1660 – 1800             station B       *Pagano*, the bogie stops at 1740 m
======================  ==============  ================================================

Straight track elsewhere; thermite welds about every 36 m on each rail
(staggered, none in the switch); six balises; line speed 60 km/h and 35 km/h
through the curves. The track is thesis Table 2.2 (50E5 on the two-layer
*Milano Modificato* fastening) with the rail supported every L_s = 0.75 m.

Chainage runs in m along the line's reference direction; rails are ``L``/``R``
looking towards increasing chainage (DESIGN.md). A curve's ``direction`` is the
way it turns looking towards increasing chainage: a right curve has its
centre on the right, so its high (outer) rail is ``L`` and its low rail ``R``.
Signed curvature is positive for left curves.

Curvature and cant ramp linearly along the transitions (clothoids with linear
cant ramps). Cant is returned as the cross-level angle ``h / s`` with
``s = 1.5 m`` between the rail centrelines.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace

import numpy as np

from .track import milano_modificato

__all__ = [
    "RAIL_SPACING_M",
    "Curve",
    "Switch",
    "Weld",
    "Balise",
    "Station",
    "Section",
    "TrackformSection",
    "SpeedLimit",
    "Line",
    "LineError",
    "default_line",
    "curvature",
    "cant_angle",
    "speed_limit_kmh",
    "trackform_at",
    "line_dict",
]

#: Distance between the two rails' centrelines (standard gauge 1435 mm + head width), m: cant ``h`` -> angle ``h/s``.
RAIL_SPACING_M = 1.5


class LineError(ValueError):
    """An inconsistent line description (overlapping curves, features outside the line, ...)."""


@dataclass(frozen=True)
class Curve:
    """A curve with clothoid transitions and a linear cant ramp on each.

    ``from_m`` is the tangent-to-spiral point, ``to_m`` the spiral-to-tangent
    point; the circular body runs from ``from_m + transition_in_m`` to
    ``to_m - transition_out_m``.
    """

    id: str
    from_m: float
    to_m: float
    radius_m: float
    direction: str  # 'left' / 'right', looking towards increasing chainage
    cant_mm: float
    transition_in_m: float
    transition_out_m: float

    def __post_init__(self) -> None:
        if self.direction not in ("left", "right"):
            raise LineError(f"curve {self.id}: direction must be 'left' or 'right', got {self.direction!r}")
        if not self.radius_m > 0:
            raise LineError(f"curve {self.id}: radius must be > 0 m, got {self.radius_m}")
        if self.transition_in_m + self.transition_out_m >= self.to_m - self.from_m:
            raise LineError(f"curve {self.id}: transitions ({self.transition_in_m} + {self.transition_out_m} m) "
                            f"longer than the curve ({self.to_m - self.from_m} m)")

    @property
    def body(self) -> tuple[float, float]:
        """Chainage range of the circular part."""
        return self.from_m + self.transition_in_m, self.to_m - self.transition_out_m

    @property
    def low_rail(self) -> str:
        """The inner (low) rail: ``R`` for a right curve, ``L`` for a left one."""
        return "R" if self.direction == "right" else "L"

    @property
    def high_rail(self) -> str:
        return "L" if self.direction == "right" else "R"

    @property
    def sign(self) -> float:
        """+1 for a left curve (positive curvature), -1 for a right one."""
        return 1.0 if self.direction == "left" else -1.0

    def ramp(self, s: np.ndarray) -> np.ndarray:
        """0 on the tangents, rising linearly to 1 over the entry transition, 1 on the body, back to 0."""
        s = np.asarray(s, float)
        b0, b1 = self.body
        up = np.clip((s - self.from_m) / self.transition_in_m, 0.0, 1.0)
        down = np.clip((self.to_m - s) / self.transition_out_m, 0.0, 1.0)
        return np.minimum(up, down)


@dataclass(frozen=True)
class Switch:
    """A turnout run on its straight route: the switch toe at ``from_m``, the crossing nose on ``crossing_rail``."""

    id: str
    from_m: float
    to_m: float
    crossing_m: float
    crossing_rail: str
    diverging: str  # side of the diverging route, looking towards increasing chainage


@dataclass(frozen=True)
class Weld:
    chainage_m: float
    rail: str


@dataclass(frozen=True)
class Balise:
    id: str
    chainage_m: float


@dataclass(frozen=True)
class Station:
    name: str
    chainage_m: float  # where the instrumented bogie stops
    platform_from_m: float
    platform_to_m: float


@dataclass(frozen=True)
class Section:
    """A named stretch of the line (what an engineer calls "curve 1", "the switch", ...)."""

    id: str
    from_m: float
    to_m: float


@dataclass(frozen=True)
class TrackformSection:
    """A stretch of one trackform; ``parameters`` in the field names of ``receptance.Trackform`` (SI units)."""

    from_m: float
    to_m: float
    trackform: str
    parameters: dict
    note: str = ""


@dataclass(frozen=True)
class SpeedLimit:
    from_m: float
    to_m: float
    speed_kmh: float


@dataclass(frozen=True)
class Line:
    """Everything the line's description file (``line.json``) says about the line."""

    name: str
    id: str
    length_m: float
    sleeper_spacing_m: float
    line_speed_kmh: float
    sections: tuple[Section, ...]
    curves: tuple[Curve, ...]
    switches: tuple[Switch, ...]
    welds: tuple[Weld, ...]
    balises: tuple[Balise, ...]
    stations: tuple[Station, ...]
    trackform_sections: tuple[TrackformSection, ...]
    speed_limits: tuple[SpeedLimit, ...]
    notes: tuple[str, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        def inside(what: str, s: float) -> None:
            if not 0.0 <= s <= self.length_m:
                raise LineError(f"{what} at {s} m lies outside the line (0-{self.length_m} m)")

        spans = sorted((c.from_m, c.to_m, c.id) for c in self.curves)
        for (a0, a1, ia), (b0, b1, ib) in zip(spans, spans[1:]):
            if b0 < a1:
                raise LineError(f"curves {ia} ({a0}-{a1} m) and {ib} ({b0}-{b1} m) overlap")
        for c in self.curves:
            inside(f"curve {c.id}", c.from_m)
            inside(f"curve {c.id}", c.to_m)
        for w in self.welds:
            inside("weld", w.chainage_m)
            if w.rail not in ("L", "R"):
                raise LineError(f"weld at {w.chainage_m} m: rail must be 'L' or 'R', got {w.rail!r}")
        for b in self.balises:
            inside(f"balise {b.id}", b.chainage_m)
        if np.any(np.diff([b.chainage_m for b in self.balises]) <= 0):
            raise LineError("balises must be listed by increasing chainage")
        edges = [(t.from_m, t.to_m) for t in self.trackform_sections]
        if edges and (edges[0][0] > 0 or edges[-1][1] < self.length_m
                      or any(abs(a[1] - b[0]) > 1e-9 for a, b in zip(edges, edges[1:]))):
            raise LineError(f"trackform sections must tile 0-{self.length_m} m without gaps, got {edges}")

    def curve_at(self, s: float) -> Curve | None:
        for c in self.curves:
            if c.from_m <= s <= c.to_m:
                return c
        return None


def _milano_modificato(pad_scale: float = 1.0, pad_loss_factor: float | None = None) -> dict:
    """Thesis Table 2.2 in ``receptance.Trackform`` field names (SI), optionally with softer pads."""
    base = milano_modificato()
    return replace(base, pad_stiffness_z=base.pad_stiffness_z * pad_scale,
                   pad_stiffness_y=base.pad_stiffness_y * pad_scale,
                   pad_loss_factor=pad_loss_factor or base.pad_loss_factor).parameters()


#: The documented trackform change: pads renewed in 410-470 m with softer ones (100 instead of 150 kN/mm).
SOFT_PAD_SCALE = 100.0 / 150.0
SOFT_PAD_LOSS_FACTOR = 0.16


def _welds(length: float, rng: np.random.Generator, avoid: list[tuple[float, float]]) -> tuple[Weld, ...]:
    """Thermite welds every 36 m rail length (±2 m site adjustment), the two rails staggered by about 18 m."""
    welds = []
    for rail, start in (("L", 20.0), ("R", 38.0)):
        s = start
        while s < length - 5.0:
            x = s + rng.uniform(-2.0, 2.0)
            if not any(a <= x <= b for a, b in avoid):
                welds.append(Weld(round(float(x), 3), rail))
            s += 36.0
    return tuple(sorted(welds, key=lambda w: (w.chainage_m, w.rail)))


def default_line(seed: int = 412) -> Line:
    """The 1.8 km virtual line of the module docstring (weld positions drawn from ``seed``)."""
    length = 1800.0
    curves = (
        Curve("C1", 470.0, 710.0, 400.0, "right", 40.0, 40.0, 40.0),
        Curve("C2", 1000.0, 1240.0, 320.0, "left", 50.0, 40.0, 40.0),
    )
    switches = (Switch("S1", 860.0, 900.0, 892.0, "R", "left"),)
    welds = _welds(length, np.random.default_rng(seed), [(855.0, 905.0)])
    balises = (Balise("B01", 130.0), Balise("B02", 420.0), Balise("B03", 790.0), Balise("B04", 960.0),
               Balise("B05", 1300.0), Balise("B06", 1620.0))
    stations = (Station("Conciliazione", 100.0, 0.0, 140.0), Station("Pagano", 1740.0, 1660.0, 1800.0))
    sections = (
        Section("station_conciliazione", 0.0, 140.0), Section("straight_1", 140.0, 470.0),
        Section("curve_1", 470.0, 710.0), Section("straight_2", 710.0, 860.0), Section("switch_1", 860.0, 900.0),
        Section("straight_3", 900.0, 1000.0), Section("curve_2", 1000.0, 1240.0),
        Section("straight_4", 1240.0, 1660.0), Section("station_pagano", 1660.0, 1800.0),
    )
    base = _milano_modificato()
    trackforms = (
        TrackformSection(0.0, 410.0, "milano_modificato", base),
        TrackformSection(410.0, 470.0, "milano_modificato_soft_pads",
                         _milano_modificato(SOFT_PAD_SCALE, SOFT_PAD_LOSS_FACTOR),
                         "pads renewed with a softer type: 100 kN/mm vertical, loss factor 0.16"),
        TrackformSection(470.0, length, "milano_modificato", base),
    )
    limits = (SpeedLimit(0.0, length, 60.0), SpeedLimit(460.0, 720.0, 35.0), SpeedLimit(990.0, 1250.0, 35.0))
    return Line(
        name="virtual M1 Conciliazione - Pagano", id="VL1", length_m=length, sleeper_spacing_m=0.75,
        line_speed_kmh=60.0, sections=sections, curves=curves, switches=switches, welds=welds, balises=balises,
        stations=stations, trackform_sections=trackforms, speed_limits=limits,
        notes=("rails L/R looking towards increasing chainage; curve direction = turning sense looking towards "
               "increasing chainage; cant in mm over 1.5 m between rail centrelines",),
    )


def curvature(line: Line, s: np.ndarray) -> np.ndarray:
    """Signed curvature [1/m] at chainage ``s`` (positive for left curves), linear along the clothoids."""
    s = np.asarray(s, float)
    k = np.zeros_like(s)
    for c in line.curves:
        k += c.sign / c.radius_m * c.ramp(s)
    return k


def cant_angle(line: Line, s: np.ndarray) -> np.ndarray:
    """Cant as an angle [rad], positive when the high rail is the curve's outer rail (always, here)."""
    s = np.asarray(s, float)
    h = np.zeros_like(s)
    for c in line.curves:
        h += c.cant_mm * 1e-3 * c.ramp(s)
    return h / RAIL_SPACING_M


def speed_limit_kmh(line: Line, s: np.ndarray) -> np.ndarray:
    """Most restrictive posted speed limit at chainage ``s``."""
    s = np.asarray(s, float)
    v = np.full_like(s, line.line_speed_kmh)
    for lim in line.speed_limits:
        inside = (s >= lim.from_m) & (s <= lim.to_m)
        v = np.where(inside, np.minimum(v, lim.speed_kmh), v)
    return v


def trackform_at(line: Line, s: np.ndarray) -> np.ndarray:
    """Index into ``line.trackform_sections`` of the section holding each chainage."""
    s = np.asarray(s, float)
    edges = np.array([t.to_m for t in line.trackform_sections[:-1]])
    return np.searchsorted(edges, s, side="right")


def line_dict(line: Line) -> dict:
    """The line as the JSON-ready dict of ``line.json`` (field contract)."""
    return {
        "format": "railmodal-line",
        "version": 1,
        "name": line.name,
        "id": line.id,
        "length_m": line.length_m,
        "sleeper_spacing_m": line.sleeper_spacing_m,
        "sections": [asdict(s) for s in line.sections],
        "curves": [asdict(c) for c in line.curves],
        "switches": [asdict(s) for s in line.switches],
        "welds": [asdict(w) for w in line.welds],
        "balises": [asdict(b) for b in line.balises],
        "stations": [asdict(s) for s in line.stations],
        # each trackform section carries its parameters flat, in receptance.Trackform's field names
        "trackform_sections": [{"from_m": t.from_m, "to_m": t.to_m, "trackform": t.trackform, "note": t.note,
                                **t.parameters} for t in line.trackform_sections],
        "speed_limits": [asdict(v) for v in line.speed_limits],
        "notes": list(line.notes),
    }
