"""The catalogue of field effects: each a physical change of the estimator's transfer functions.

An effect is a small frozen class with named, bounded parameters
(:class:`Parameter`), a location (which evidence segments its change reaches:
:meth:`FieldEffect.acts_on`), :meth:`FieldEffect.apply`, which returns the
:class:`~estimator.diagnosis.state.FieldState` with the effect's values, and
:meth:`FieldEffect.meaning`, what an accepted fit says in the field's terms
(a calibration to keep, or a component to inspect) for the report.
Adding an effect to the catalogue is one such class and one line in
:func:`catalogue`.

=====================  ==========================================================  =====================
effect                 physical change (thesis)                                     parameters
=====================  ==========================================================  =====================
``trackform``          the section's pad/subplate stiffness and damping (rail       stiffness factor,
                       receptance ``A_R``, §2.4, eq. 2.22); on a stretch the        damping factor (and
                       evidence located, its ends are fitted too                    start, end)
``discrete_supports``  the rail on discrete sleepers instead of a continuous        (the model switch)
                       support (§2.4), at the line's sleeper spacing
``dynamic_stiffening`` every pad and subplate stiffening with frequency as a        reference frequency
                       causal constant-loss layer must (eq. 2.32's η kept; the
                       stated stiffness holds at the fitted frequency)
``contact_angle``      the contact angles γ_L, γ_R of one curve for the leading     γ on rail L, on R
                       or trailing wheelset (contact normals ``N``, eq. 2.12)
``sensor_offset``      an accelerometer's true mounting point (a row of ``A_B``,    the two offsets its
                       ``u(P+δ) = u(P) + θ×δ``)                                     reading depends on
``contact_stiffness``  the wheel load behind the Hertz stiffness ``K_H``            wheel load
``wheel_roughness``    a wheel's own roughness left in the estimate (subtracted     level at 100 mm,
                       in power; reported, not applied by the estimator)            slope per octave
=====================  ==========================================================  =====================
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from estimator.diagnosis.state import FieldState, TrackformChange

__all__ = ["Parameter", "FieldEffect", "TrackformEffect", "TrackformStretch",
           "DiscreteSupports", "DynamicStiffening", "ContactAngle", "SensorOffset",
           "ContactStiffness", "WheelRoughness", "EFFECT_NAMES", "catalogue"]


#: stiffness factors of a whole section that the frequency a pad's table holds at explains: a causal layer's
#: stiffness rises by 2 arctan(η)/π per neper (:func:`receptance.track.layer_dispersion`), for η = 0.2 ×0.75 at
#: 10 Hz and ×1.3 at 1 kHz against its value at 100 Hz
TYPICAL_TABLE_SPREAD = (0.7, 1.4)
#: contact angles bounding the tread (cone and its rounding to the flange root) and the flange root (rising to the
#: flank): a 1:40 or 1:20 tread is 1.4-2.9°, worn treads reach a few degrees; the flange flank is 60-75°
FLANGE_ROOT_RAD = math.radians(8.0)
FLANGE_FLANK_RAD = math.radians(30.0)


@dataclass(frozen=True)
class Parameter:
    """A fitted parameter: bounds of the search, the plausible range, log or linear scale, unit."""

    name: str
    lo: float
    hi: float
    nominal: float
    log: bool = False
    unit: str = ""
    plausible: tuple[float, float] | None = None
    #: a bound that is a physical limit (a contact angle of 0: tread contact) and not the search's edge: a value
    #: there is a legitimate fit, not a sign that the effect wants more than the search allows
    physical_lo: bool = False
    #: the same for the upper bound (a stretch's end at the last evidence: the data cannot place it further)
    physical_hi: bool = False

    def at_bound(self, u: float) -> bool:
        return (u < 0.01 and not self.physical_lo) or (u > 0.99 and not self.physical_hi)

    def grid(self, n: int) -> np.ndarray:
        if self.log:
            return np.geomspace(self.lo, self.hi, n)
        return np.linspace(self.lo, self.hi, n)

    def to_unit(self, v: float) -> float:
        """Value → position in [0, 1] of the search (log or linear)."""
        if self.log:
            return math.log(v / self.lo) / math.log(self.hi / self.lo)
        return (v - self.lo) / (self.hi - self.lo)

    def from_unit(self, u: float) -> float:
        u = min(max(u, 0.0), 1.0)
        if self.log:
            return self.lo * (self.hi / self.lo) ** u
        return self.lo + u * (self.hi - self.lo)

    def is_plausible(self, v: float) -> bool:
        lo, hi = self.plausible or (self.lo, self.hi)
        return lo <= v <= hi


@dataclass(frozen=True)
class FieldEffect:
    """Base of the catalogue (module docstring). ``name`` is the catalogue name, ``where`` the location."""

    name = ""
    parameters: tuple = ()

    @property
    def where(self) -> str:
        return ""

    @property
    def n_fitted(self) -> int:
        """Numbers the fit chooses (a model switch counts as one)."""
        return max(len(self.parameters), 1)

    @property
    def applied_by_estimator(self) -> bool:
        return True

    def acts_on(self, seg) -> bool:
        return True

    def plausible(self, values: dict) -> bool:
        """A check across parameters beyond each one's plausible range (default: none)."""
        return True

    def apply(self, state: FieldState, values: dict) -> FieldState:
        raise NotImplementedError

    def label(self) -> str:
        return f"{self.name} ({self.where})" if self.where else self.name

    def meaning(self, values: dict) -> str:
        """What an accepted fit with ``values`` says about the track, the vehicle or the sensors, and what to do."""
        return ""


@dataclass(frozen=True)
class TrackformEffect(FieldEffect):
    from_m: float = 0.0
    to_m: float = 0.0
    section: str = ""
    name = "trackform"
    parameters: tuple = (Parameter("stiffness_factor", 0.1, 10.0, 1.0, log=True, plausible=(0.15, 7.0)),
                         Parameter("damping_factor", 0.2, 5.0, 1.0, log=True, plausible=(0.25, 4.0)))

    @property
    def where(self) -> str:
        return f"section {self.section} {self.from_m:g}-{self.to_m:g} m"

    def extent(self, values: dict) -> tuple[float, float]:
        """The stretch ``(from, to)`` [m] the change covers with these values."""
        return self.from_m, self.to_m

    def acts_on(self, seg) -> bool:
        # any overlap: a segment partly covered is inverted part by part (Evaluator.pieces)
        return seg.from_m < self.to_m and seg.to_m > self.from_m

    def meaning(self, values: dict) -> str:
        k, c = values["stiffness_factor"], values.get("damping_factor", 1.0)
        a, b = self.extent(values)
        what = (f"The track on {a:.1f}-{b:.1f} m acts with pads and subplates {k:.2f} times as stiff and {c:.2f} "
                f"times as damped as its trackform table says.")
        if TYPICAL_TABLE_SPREAD[0] <= k <= TYPICAL_TABLE_SPREAD[1]:
            return (what + " That is within the spread of a pad's table values and the frequency they were tested at "
                    "(a causal pad stiffens with frequency): correct the section's trackform for later estimates; "
                    "nothing to inspect on its account.")
        state = "softer: pads degraded, fastenings loose or missing" if k < 1 else "stiffer: pads aged or hardened"
        return what + f" That is {state}; inspect the pads and fastenings there."

    def apply(self, state, values):
        k, c = values["stiffness_factor"], values.get("damping_factor", 1.0)
        a, b = self.extent(values)
        return state.with_trackform_change(TrackformChange(
            a, b, (("pad_stiffness", k), ("subplate_stiffness", k), ("pad_damping", c), ("subplate_damping", c))))


@dataclass(frozen=True)
class TrackformStretch(TrackformEffect):
    """A trackform change where the evidence says the track differs, its two ends fitted with the factors.

    ``from_m``–``to_m`` is the run of segments that stand out
    (:func:`estimator.diagnosis.diagnose.anomalous_stretches`); a segment the change covers only in part may
    not stand out, so each true end lies within one segment (``resolution_m``) of it: the fitted start is
    searched on ``from_m ± resolution_m``, the end on ``to_m ± resolution_m`` (an end at its search bound is
    implausible: the change reaches beyond what the evidence located). A segment partly covered weighs the
    changed and the nominal inversion by their shares of its length (:meth:`Evaluator.pieces`), which is what
    resolves an end inside a segment. The two ends count in the criterion's ``k`` (4 numbers against a line
    section's 2). A fitted stretch shorter than ``min_length_m`` is a defect, not a trackform (implausible).
    """

    resolution_m: float = 24.0
    min_length_m: float = 40.0
    #: calibration evidence beyond the stretch's start / end (within one segment); without it the data cannot
    #: place that end further out: its search stops at the stretch's edge, which is then a legitimate value
    evidence_before: bool = True
    evidence_after: bool = True
    #: the leading parameters the start grid covers (the factors; the ends start at the evidence's)
    n_grid = 2

    def __post_init__(self):
        r = self.resolution_m
        a, b = self.from_m, self.to_m
        ends = (Parameter("from_m", a - r if self.evidence_before else a, a + r, a, unit="m",
                          physical_lo=not self.evidence_before),
                Parameter("to_m", b - r, b + r if self.evidence_after else b, b, unit="m",
                          physical_hi=not self.evidence_after))
        object.__setattr__(self, "parameters", TrackformEffect.parameters + ends)

    @property
    def where(self) -> str:
        return f"{self.section}, ends fitted within ±{self.resolution_m:g} m"

    def extent(self, values: dict) -> tuple[float, float]:
        return values.get("from_m", self.from_m), values.get("to_m", self.to_m)

    def acts_on(self, seg) -> bool:
        return seg.from_m < self.to_m + self.resolution_m and seg.to_m > self.from_m - self.resolution_m

    def plausible(self, values: dict) -> bool:
        a, b = self.extent(values)
        return b - a >= self.min_length_m

    def meaning(self, values: dict) -> str:
        return (super().meaning(values) + " The change is local (its ends fitted from the evidence): if it is a "
                "known trackform change (renewed pads, another fastening), add it to the line description as a "
                "trackform section.")


@dataclass(frozen=True)
class DiscreteSupports(FieldEffect):
    name = "discrete_supports"
    parameters: tuple = ()

    @property
    def where(self) -> str:
        return "every trackform, at its sleeper spacing"

    def meaning(self, values: dict) -> str:
        return ("The rail's support on discrete sleepers shows in the evidence (the rail's receptance between "
                "sleepers, up to its pinned-pinned resonance): estimate this line with trackform_supports = "
                "'discrete'.")

    def apply(self, state, values):
        return state.with_supports("discrete", None)


@dataclass(frozen=True)
class DynamicStiffening(FieldEffect):
    """Eq. 2.32's constant loss factor made causal: the layers stiffen with frequency (Kramers–Kronig).

    A pad or subplate with a loss factor ``η`` cannot have a stiffness independent of frequency; it rises by
    ``2 arctan(η)/π`` per neper (:func:`receptance.track.layer_dispersion`). The trackform's stated stiffness
    is then the one at the frequency the layer was characterised at — unknown in the field, fitted here. The
    search spans the frequencies pads are tested at (a few Hz in EN 13146-9's low-frequency test to ~1 kHz in
    the high-frequency methods); it acts on every trackform, where the rail receptance shapes the estimate
    most (the unsprung mass on the track, 30–150 Hz).
    """

    name = "dynamic_stiffening"
    parameters: tuple = (Parameter("reference_hz", 2.0, 5000.0, 100.0, log=True, unit="Hz",
                                   plausible=(3.0, 3000.0)),)

    @property
    def where(self) -> str:
        return "every trackform's pads and subplates"

    def meaning(self, values: dict) -> str:
        return (f"The pads and subplates behave as causal elastomers whose table stiffness holds at "
                f"{values['reference_hz']:.0f} Hz and rises with frequency: set loss_reference_hz = "
                f"{values['reference_hz']:.0f} in the line's trackforms for later estimates.")

    def apply(self, state, values):
        return state.with_loss_reference(values["reference_hz"])


@dataclass(frozen=True)
class ContactAngle(FieldEffect):
    curve: str = ""
    role: str = "any"
    name = "contact_angle"
    parameters: tuple = (Parameter("gamma_L", 0.0, 1.4, 0.0, unit="rad", plausible=(0.0, 1.3), physical_lo=True),
                         Parameter("gamma_R", 0.0, 1.4, 0.0, unit="rad", plausible=(0.0, 1.3), physical_lo=True))

    @property
    def where(self) -> str:
        return f"curve {self.curve}, {self.role} wheelset"

    def acts_on(self, seg) -> bool:
        return seg.curve == self.curve and (self.role == "any" or seg.role == self.role)

    def meaning(self, values: dict) -> str:
        g = {r: values[f"gamma_{r}"] for r in "LR"}
        top = max(g, key=g.get)
        deg = ", ".join(f"{math.degrees(v):.1f}° on rail {r}" for r, v in g.items())
        what = f"On curve {self.curve} the {self.role} wheelset's contact angles are {deg}."
        if g[top] < FLANGE_ROOT_RAD:
            return (what + " Both wheels run on their treads, the wheelset shifted as the bogie's curving puts it "
                    "(its yaw, the cant deficiency, the profiles' shape): a calibration of this curve, not a defect; "
                    "the calibrated model keeps it for the curve's estimates.")
        if g[top] < FLANGE_FLANK_RAD:
            return (what + f" The wheel on rail {top} runs near its flange root: more shift than the treads "
                    "explain (tight gauge, worn profiles); check the gauge and the profiles if it is unexpected.")
        return (what + f" The wheel on rail {top} runs on its flange: the gauge is narrower than the wheelset "
                "needs, or the bogie steers badly; check the gauge and the flange lubrication in this curve.")

    def apply(self, state, values):
        return state.with_curve_angles(self.curve, self.role, values["gamma_L"], values["gamma_R"])


#: the offsets an accelerometer's reading depends on, per measuring direction (δ × d ≠ 0)
_LEVERS = {"z": ("dx", "dy"), "y": ("dx", "dz"), "x": ("dy", "dz")}
_AXES = ("dx", "dy", "dz")


@dataclass(frozen=True)
class SensorOffset(FieldEffect):
    channel: str = ""
    direction: str = "z"
    wheelset: int = 1
    name = "sensor_offset"
    parameters: tuple = ()

    def __post_init__(self):
        if not self.parameters:
            object.__setattr__(self, "parameters", tuple(
                Parameter(a, -0.15, 0.15, 0.0, unit="m", plausible=(-0.12, 0.12)) for a in _LEVERS[self.direction]))

    @property
    def where(self) -> str:
        return f"channel {self.channel}"

    def acts_on(self, seg) -> bool:
        # the other wheelset's channels enter a coupled segment through its contact forces
        return self.wheelset in (seg.wheelset, seg.other)

    def meaning(self, values: dict) -> str:
        axes = [a for a in sorted(values) if a in _AXES]
        moved = ", ".join(f"{1e3 * values[a]:+.0f} mm along {a[1]}" for a in axes if abs(values[a]) >= 5e-4) or \
            ", ".join(f"{1e3 * values[a]:+.1f} mm along {a[1]}" for a in axes)
        return (f"Accelerometer {self.channel} reads as if mounted {moved} from the sensor table's point: check "
                "its mount (bracket, adhesive, a swapped position) or correct its position in the sensor table.")

    def apply(self, state, values):
        d = {a: values.get(a, 0.0) for a in ("dx", "dy", "dz")}
        return state.with_sensor_offset(self.channel, d["dx"], d["dy"], d["dz"])


@dataclass(frozen=True)
class ContactStiffness(FieldEffect):
    name = "contact_stiffness"
    parameters: tuple = (Parameter("wheel_load_N", 1e4, 2e5, 5.5e4, log=True, unit="N", plausible=(2e4, 1.5e5)),)

    def meaning(self, values: dict) -> str:
        return (f"The wheel-rail contact is as stiff as under a wheel load of {values['wheel_load_N'] / 1e3:.0f} kN "
                "(Hertz): compare it with the vehicle's weighed load; a different load or worn profiles (other "
                "curvature radii) change the contact stiffness.")

    def apply(self, state, values):
        return state.with_wheel_load(values["wheel_load_N"])


@dataclass(frozen=True)
class WheelRoughness(FieldEffect):
    wheelset: int = 1
    side: str = "L"
    name = "wheel_roughness"
    parameters: tuple = (Parameter("level_db", -40.0, 30.0, -40.0, unit="dB re 1 µm at 100 mm", plausible=(-40, 25)),
                         Parameter("slope_db_per_octave", -12.0, 12.0, 0.0, unit="dB/octave"))

    @property
    def where(self) -> str:
        return f"wheelset {self.wheelset}, vehicle side {self.side}"

    @property
    def applied_by_estimator(self) -> bool:
        return False

    def acts_on(self, seg) -> bool:
        return seg.wheelset == self.wheelset

    def meaning(self, values: dict) -> str:
        return (f"Wheelset {self.wheelset}'s wheel on vehicle side {self.side} leaves its own roughness in the rail "
                f"estimate ({values['level_db']:.0f} dB re 1 µm at 100 mm, {values['slope_db_per_octave']:+.1f} "
                "dB/octave) beyond what the comb filter removes: measure or reprofile the wheel. The estimator does "
                "not subtract it: where the rail is smoother than the wheel, that rail's estimate from this wheel "
                "reads the wheel.")

    def apply(self, state, values):
        return state.with_wheel_roughness(self.wheelset, self.side, values["level_db"], values["slope_db_per_octave"])


EFFECT_NAMES = ("trackform", "discrete_supports", "dynamic_stiffening", "contact_angle", "sensor_offset",
                "contact_stiffness", "wheel_roughness")


def catalogue(evidence, line, channels, *, names=None, min_section_m: float = 40.0, stretches=()
              ) -> list[FieldEffect]:
    """Every candidate of the catalogue at every location the evidence reaches.

    ``trackform``: each line section and trackform section, and each of ``stretches`` (``(from, to)``: where
    the evidence itself says the track differs, :func:`estimator.diagnosis.diagnose.anomalous_stretches`), at
    least ``min_section_m`` long and holding evidence; ``contact_angle``: each curve with evidence on its body, per wheelset role; ``sensor_offset``:
    each acceleration channel of the model (``channels``: table rows with ``name``, ``direction``,
    ``wheelset``, ``side``); ``wheel_roughness``: each wheel.
    """
    names = EFFECT_NAMES if names is None else tuple(names)
    unknown = sorted(set(names) - set(EFFECT_NAMES))
    if unknown:
        from estimator.diagnosis.errors import DiagnosisConfigError
        raise DiagnosisConfigError(f"unknown field effect(s) {unknown}; the catalogue has {list(EFFECT_NAMES)}")
    segs = evidence.segments
    out: list[FieldEffect] = []
    if "trackform" in names and (line is not None or stretches):
        line = line if line is not None else type("_NoLine", (), {"sections": (), "trackforms": ()})()
        places = [(s.id, s.from_m, s.to_m) for s in tuple(line.sections) + tuple(line.trackforms)]
        seen = set()
        for sid, a, b in places:
            if (a, b) in seen:
                continue
            seen.add((a, b))
            if b - a >= min_section_m and any(a <= s.centre_m <= b for s in segs):
                out.append(TrackformEffect(from_m=a, to_m=b, section=str(sid)))
        # where the evidence located a change: its ends are fitted within one segment (the evidence's resolution)
        res = float(np.median([s.to_m - s.from_m for s in segs])) if segs else 0.0
        cal = [s for s, c in zip(segs, evidence.calibration) if c]
        for a, b in stretches:
            if b - a >= min_section_m and any(a <= s.centre_m <= b for s in segs):
                out.append(TrackformStretch(
                    from_m=a, to_m=b, section=f"{a:g}-{b:g} m (from the evidence)", resolution_m=res,
                    min_length_m=min_section_m, evidence_before=any(s.from_m < a and s.to_m > a - res for s in cal),
                    evidence_after=any(s.to_m > b and s.from_m < b + res for s in cal)))
    if "discrete_supports" in names:
        out.append(DiscreteSupports())
    if "dynamic_stiffening" in names:
        out.append(DynamicStiffening())
    if "contact_angle" in names:
        for cid, role in sorted({(s.curve, s.role) for s in segs if s.curve is not None}):
            out.append(ContactAngle(curve=cid, role=role))
    if "sensor_offset" in names:
        for r in channels.itertuples():
            out.append(SensorOffset(channel=str(r.name), direction=str(r.direction), wheelset=int(r.wheelset)))
    if "contact_stiffness" in names:
        out.append(ContactStiffness())
    if "wheel_roughness" in names:
        for w, side in sorted({(int(r.wheelset), str(r.side)) for r in channels.itertuples()}):
            out.append(WheelRoughness(wheelset=w, side=side))
    return out
