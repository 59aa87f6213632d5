"""The field state: what a field calibration changes in the estimator's model, as one immutable value.

A :class:`FieldState` holds every field effect accepted so far (and, while a
candidate is fitted, the candidate's values) in physical terms — a trackform
section, the rail's discrete supports, the resilient layers' causal
stiffening (the frequency their stated stiffness holds at), a curve's contact angles, an
accelerometer's true mounting point, the wheel load behind the Hertz
stiffness, a wheel's roughness left in the estimate. Two realisations of it
exist and must agree:

* the fast evaluator of the diagnosis (:mod:`estimator.diagnosis.evidence`,
  :mod:`estimator.diagnosis.transfer`), which re-derives only the transfer
  functions of the windows an effect touches;
* the single-run estimator itself: :func:`field_model_for` turns the state
  into a :class:`~estimator.workflow.FieldModel` (a line description with the
  trackform section, a sensor table with the mounting point, an
  :class:`~estimator.config.EstimatorConfig` with the contact angles, wheel
  load and supports) and :func:`run_for` gives a run read with the nominal
  table the calibrated mounting points.

``wheel_roughness`` has no counterpart in the estimator (the comb filter
already removes what is periodic in the wheel's rolling angle): it names the
wheel whose roughness is left in the estimate and is reported, not applied.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Mapping

import pandas as pd

from estimator.io.line import LineDescription, TrackSection
from receptance.trackform import Trackform

__all__ = ["TrackformChange", "FieldState", "field_model_for", "run_for", "line_with_changes", "sensors_with_offsets",
           "TRACKFORM_FACTORS"]

#: the Trackform fields a trackform change scales (pad and subplate stiffness and damping, both directions)
TRACKFORM_FACTORS = {
    "pad_stiffness": ("pad_stiffness_z", "pad_stiffness_y"),
    "subplate_stiffness": ("subplate_stiffness_z", "subplate_stiffness_y"),
    "pad_damping": ("pad_damping_z", "pad_damping_y"),
    "subplate_damping": ("subplate_damping_z", "subplate_damping_y"),
}


@dataclass(frozen=True)
class TrackformChange:
    """A stretch ``[from_m, to_m]`` whose pads and subplates differ from the line description by ``factors``.

    ``factors``: ``((name, multiplier), ...)`` with names of :data:`TRACKFORM_FACTORS` (each scales the
    vertical and the lateral value), applied to whatever trackform the line has there.
    """

    from_m: float
    to_m: float
    factors: tuple[tuple[str, float], ...]

    def apply(self, tf: Trackform) -> Trackform:
        changes = {}
        for name, mult in self.factors:
            for fname in TRACKFORM_FACTORS[name]:
                changes[fname] = getattr(tf, fname) * float(mult)
        return replace(tf, **changes)

    def as_dict(self) -> dict:
        return {"from_m": self.from_m, "to_m": self.to_m, "factors": dict(self.factors)}


@dataclass(frozen=True)
class FieldState:
    """Field effects in physical terms (module docstring); every field hashable, every method returns a new state.

    Attributes
    ----------
    trackform_changes : tuple of TrackformChange
    supports : {"continuous", "discrete"}
        Rail support model of the track receptance (thesis §2.4).
    support_spacing_m : float or None
        Support spacing of every trackform when given (else each trackform's own).
    loss_reference_hz : float or None
        Every trackform's pads and subplates follow the causal constant-loss law with their stated stiffness
        at this frequency (:attr:`receptance.trackform.Trackform.loss_reference_hz`); None: each trackform's own.
    curve_angles : tuple of (curve id, role, γ on rail L, γ on rail R)
        Contact angles [rad] (sign of :mod:`estimator.contact_angles`) of a curve for a wheelset role.
    sensor_offsets : tuple of (channel, dx, dy, dz)
        Mounting point of an accelerometer relative to the sensor table's [m] (vehicle frame).
    wheel_load_N : float or None
        Static wheel load behind the Hertz contact (stiffness and contact patch); None: the estimator's.
    wheel_roughness : tuple of (wheelset, vehicle side, level dB re 1 µm at 100 mm, slope dB per octave)
        A wheel's roughness left in the estimate (reported, not applied by the estimator).
    """

    trackform_changes: tuple[TrackformChange, ...] = ()
    supports: str = "continuous"
    support_spacing_m: float | None = None
    loss_reference_hz: float | None = None
    curve_angles: tuple[tuple[str, str, float, float], ...] = ()
    sensor_offsets: tuple[tuple[str, float, float, float], ...] = ()
    wheel_load_N: float | None = None
    wheel_roughness: tuple[tuple[int, str, float, float], ...] = ()

    # ------------------------------------------------------------------ new states
    def with_trackform_change(self, change: TrackformChange) -> "FieldState":
        return replace(self, trackform_changes=self.trackform_changes + (change,))

    def with_supports(self, supports: str, spacing_m: float | None) -> "FieldState":
        return replace(self, supports=supports, support_spacing_m=spacing_m)

    def with_loss_reference(self, reference_hz: float) -> "FieldState":
        return replace(self, loss_reference_hz=float(reference_hz))

    def with_curve_angles(self, curve_id: str, role: str, gamma_l: float, gamma_r: float) -> "FieldState":
        rest = tuple(a for a in self.curve_angles if (a[0], a[1]) != (curve_id, role))
        return replace(self, curve_angles=rest + ((curve_id, role, float(gamma_l), float(gamma_r)),))

    def with_sensor_offset(self, channel: str, dx: float, dy: float, dz: float) -> "FieldState":
        rest = tuple(o for o in self.sensor_offsets if o[0] != channel)
        return replace(self, sensor_offsets=rest + ((channel, float(dx), float(dy), float(dz)),))

    def with_wheel_load(self, load_N: float) -> "FieldState":
        return replace(self, wheel_load_N=float(load_N))

    def with_wheel_roughness(self, wheelset: int, side: str, level_db: float, slope_db: float) -> "FieldState":
        rest = tuple(w for w in self.wheel_roughness if (w[0], w[1]) != (wheelset, side))
        return replace(self, wheel_roughness=rest + ((int(wheelset), side, float(level_db), float(slope_db)),))

    # ------------------------------------------------------------------ views
    def line_wide(self, tf: Trackform) -> Trackform:
        """``tf`` with the state's line-wide trackform settings (support spacing, layers' reference frequency)."""
        changes = {}
        if self.support_spacing_m is not None:
            changes["support_spacing"] = float(self.support_spacing_m)
        if self.loss_reference_hz is not None:
            changes["loss_reference_hz"] = float(self.loss_reference_hz)
        return replace(tf, **changes) if changes else tf

    def offset_of(self, channel: str) -> tuple[float, float, float]:
        for c, dx, dy, dz in self.sensor_offsets:
            if c == channel:
                return dx, dy, dz
        return 0.0, 0.0, 0.0

    @property
    def is_nominal(self) -> bool:
        return self == FieldState()

    def summary(self) -> str:
        """One line naming every change of this state from the nominal one (``nominal`` when none)."""
        parts = []
        for c in self.trackform_changes:
            parts.append(f"trackform {c.from_m:g}-{c.to_m:g} m " + ", ".join(f"{k} x{v:.3g}" for k, v in c.factors))
        if self.supports != "continuous" or self.support_spacing_m is not None:
            parts.append(f"supports {self.supports}" + ("" if self.support_spacing_m is None
                                                        else f" at {self.support_spacing_m:.3g} m"))
        if self.loss_reference_hz is not None:
            parts.append(f"causal pads and subplates, stated stiffness at {self.loss_reference_hz:.4g} Hz")
        for cid, role, gl, gr in self.curve_angles:
            parts.append(f"curve {cid} ({role}) contact angles rail L {math.degrees(gl):.2f} deg, rail R "
                         f"{math.degrees(gr):.2f} deg")
        for ch, dx, dy, dz in self.sensor_offsets:
            parts.append(f"{ch} moved ({1e3 * dx:+.1f}, {1e3 * dy:+.1f}, {1e3 * dz:+.1f}) mm")
        if self.wheel_load_N is not None:
            parts.append(f"wheel load {1e-3 * self.wheel_load_N:.3g} kN")
        for w, side, lv, sl in self.wheel_roughness:
            parts.append(f"wheel {w}{side} roughness {lv:.1f} dB at 100 mm, {sl:+.1f} dB/octave (reported only)")
        return "; ".join(parts) if parts else "nominal"

    def as_dict(self) -> dict:
        return {"trackform_changes": [c.as_dict() for c in self.trackform_changes], "supports": self.supports,
                "support_spacing_m": self.support_spacing_m, "loss_reference_hz": self.loss_reference_hz,
                "curve_angles": [{"curve": c, "role": r, "gamma_rail_L_deg": math.degrees(gl),
                                  "gamma_rail_R_deg": math.degrees(gr), "gamma_rad": [gl, gr]}
                                 for c, r, gl, gr in self.curve_angles],
                "sensor_offsets": [{"channel": c, "dx_mm": 1e3 * dx, "dy_mm": 1e3 * dy, "dz_mm": 1e3 * dz,
                                    "offset_m": [dx, dy, dz]} for c, dx, dy, dz in self.sensor_offsets],
                "wheel_load_N": self.wheel_load_N,
                "wheel_roughness": [{"wheelset": w, "side": s, "level_db": lv, "slope_db_per_octave": sl}
                                    for w, s, lv, sl in self.wheel_roughness]}

    @staticmethod
    def from_dict(d: Mapping) -> "FieldState":
        return FieldState(
            trackform_changes=tuple(TrackformChange(float(c["from_m"]), float(c["to_m"]),
                                                    tuple((str(k), float(v)) for k, v in c["factors"].items()))
                                    for c in d.get("trackform_changes", [])),
            supports=str(d.get("supports", "continuous")),
            support_spacing_m=None if d.get("support_spacing_m") is None else float(d["support_spacing_m"]),
            loss_reference_hz=None if d.get("loss_reference_hz") is None else float(d["loss_reference_hz"]),
            # the exact SI values when present (the degrees and millimetres are for the reader)
            curve_angles=tuple((str(a["curve"]), str(a["role"]), *map(float, a["gamma_rad"])) if "gamma_rad" in a
                               else (str(a["curve"]), str(a["role"]), math.radians(float(a["gamma_rail_L_deg"])),
                                     math.radians(float(a["gamma_rail_R_deg"]))) for a in d.get("curve_angles", [])),
            sensor_offsets=tuple((str(o["channel"]), *map(float, o["offset_m"])) if "offset_m" in o
                                 else (str(o["channel"]), 1e-3 * float(o["dx_mm"]), 1e-3 * float(o["dy_mm"]),
                                       1e-3 * float(o["dz_mm"])) for o in d.get("sensor_offsets", [])),
            wheel_load_N=None if d.get("wheel_load_N") is None else float(d["wheel_load_N"]),
            wheel_roughness=tuple((int(w["wheelset"]), str(w["side"]), float(w["level_db"]),
                                   float(w["slope_db_per_octave"])) for w in d.get("wheel_roughness", [])))


# --------------------------------------------------------------------------- the estimator's realisation
def line_with_changes(line: LineDescription | None, default: Trackform, state: FieldState) -> LineDescription:
    """The line description with the state's trackform sections cut into its own (support spacing, dispersion).

    Every trackform change scales the trackform the line has over its stretch (``default`` where the line has
    none); sections are cut at the change's ends so that each piece keeps its own base trackform.
    """
    base = line if line is not None else LineDescription()
    sections = [(t.from_m, t.to_m, t.trackform or default, t.id) for t in base.trackforms]
    if not sections:
        sections = [(-math.inf, math.inf, default, "default")]
    for ch in state.trackform_changes:
        out = []
        for a, b, tf, name in sections:
            cuts = [a] + [c for c in (ch.from_m, ch.to_m) if a < c < b] + [b]
            for lo, hi in zip(cuts[:-1], cuts[1:]):
                inside = lo >= ch.from_m and hi <= ch.to_m
                out.append((lo, hi, ch.apply(tf) if inside else tf, f"{name} (field calibration)" if inside else name))
        sections = out
    tracks = tuple(TrackSection(n, a, b, state.line_wide(tf)) for a, b, tf, n in sections)
    return replace(base, trackforms=tracks)


def sensors_with_offsets(table: pd.DataFrame, state: FieldState) -> pd.DataFrame:
    """The sensor table with the state's mounting points (offsets added to ``x, y, z``)."""
    out = table.copy()
    for ch, dx, dy, dz in state.sensor_offsets:
        sel = out["name"] == ch
        if not sel.any():
            raise KeyError(f"sensor offset for channel {ch!r}, which the sensor table lacks (it has "
                           f"{list(out['name'])})")
        for axis, d in zip("xyz", (dx, dy, dz)):
            out.loc[sel, axis] = out.loc[sel, axis].astype(float) + d
    return out


def _estimator_config(cfg, state: FieldState):
    changes: dict = {}
    if state.curve_angles:
        angles: dict = {}
        for cid, role, gl, gr in state.curve_angles:
            angles.setdefault(cid, {})[role] = (gl, gr)
        changes["curve_contact_angles"] = angles
    if state.wheel_load_N is not None:
        changes["contact"] = replace(cfg.contact, wheel_load_N=float(state.wheel_load_N))
    if state.supports != cfg.trackform_supports:
        changes["trackform_supports"] = state.supports
    return cfg.replace(**changes) if changes else cfg


def field_model_for(fm, state: FieldState):
    """The :class:`~estimator.workflow.FieldModel` that realises ``state`` in the single-run estimator.

    Its line carries the trackform sections (an explicit trackform of ``fm`` becomes the line's everywhere),
    its sensor table the mounting points, its configuration the contact angles, wheel load and supports; its
    transfer-function cache starts empty.
    """
    from estimator.workflow import prepare

    if state.is_nominal:
        return fm
    line = line_with_changes(fm.line, fm.default_trackform(), state) if (
        state.trackform_changes or state.support_spacing_m is not None or state.loss_reference_hz is not None
        or fm.trackform is not None) else fm.line
    cfg = _estimator_config(fm.config, state)
    out = prepare(fm.model, sensors_with_offsets(fm.sensors, state), line=line, trackform=None, config=cfg)
    return replace(out, curving=fm.curving)


def run_for(run, state: FieldState):
    """A run read with the nominal sensor table, with the state's accelerometer mounting points."""
    if not state.sensor_offsets:
        return run
    ch = sensors_with_offsets(run.channels, state)
    moved = ", ".join(f"{c} ({1e3 * dx:+.1f}, {1e3 * dy:+.1f}, {1e3 * dz:+.1f}) mm" for c, dx, dy, dz in
                      state.sensor_offsets)
    return run.with_step(f"accelerometers at their calibrated mounting points: {moved}", channels=ch)
