"""Options of a field estimate, validated when built (each names its range)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace
from typing import Mapping

from estimator.errors import ConfigurationError
from receptance.contact import ContactParameters

__all__ = ["EstimatorConfig", "MODELS", "MODEL_ALIASES", "EN13231_BANDS_MM", "EN13231_WINDOWS_M",
           "DEFAULT_THRESHOLDS_UM", "WHEEL_WEAR_SEARCH", "parse_models"]

#: the thesis's three transfer-function models (receptance names)
MODELS = ("half", "vertical", "vertical_lateral")
#: CLI spellings
MODEL_ALIASES = {"half": "half", "vertical": "vertical", "lateral": "vertical_lateral",
                 "vertical_lateral": "vertical_lateral", "vertical+lateral": "vertical_lateral"}
#: EN 13231-3 wavelength bands [mm] and the moving-window lengths of thesis Table 4.1 [m]
EN13231_BANDS_MM = ((10.0, 30.0), (30.0, 100.0), (100.0, 300.0), (300.0, 1000.0))
EN13231_WINDOWS_M = {(10.0, 30.0): 0.15, (30.0, 100.0): 0.5, (100.0, 300.0): 1.5, (300.0, 1000.0): 5.0}
#: default peak-to-peak thresholds per band [µm] for the exceedance share (configurable; the values commonly
#: quoted as EN 13231-3 acceptance limits of a reprofiled rail — check them against the edition you work to)
DEFAULT_THRESHOLDS_UM = {(10.0, 30.0): 10.0, (30.0, 100.0): 10.0, (100.0, 300.0): 15.0, (300.0, 1000.0): 75.0}
#: relative interval of the rolling circumference searched around the nominal one, new wheel -> fully worn:
#: EN 15313 takes a wheel's last-turning diameter from its marking and the maintenance plan; a metro wheel is
#: re-profiled down by 30-40 mm of diameter (820 -> ~780 mm: -4.9 %) before it is scrapped; +1 % allows a new
#: wheel slightly above the model's radius and the odometer scale's error
WHEEL_WEAR_SEARCH = (-0.05, 0.01)


def parse_models(spec) -> tuple[str, ...]:
    """``"half,vertical,lateral"`` (or a sequence) → receptance model names, validated, order kept."""
    items = [s.strip() for s in spec.split(",")] if isinstance(spec, str) else [str(s).strip() for s in spec]
    out = []
    for s in items:
        if s.lower() not in MODEL_ALIASES:
            raise ConfigurationError(f"unknown transfer-function model {s!r}; choose from "
                                     f"{sorted(MODEL_ALIASES)} (half, vertical, lateral = vertical + lateral)")
        m = MODEL_ALIASES[s.lower()]
        if m not in out:
            out.append(m)
    if not out:
        raise ConfigurationError("give at least one transfer-function model (half, vertical, lateral)")
    return tuple(out)


def _curve_angles(spec) -> dict:
    """``{curve id: {role: (γ_L, γ_R)}}`` validated (roles leading/trailing/any, angles in [0, 1.5) rad)."""
    if not isinstance(spec, Mapping):
        raise ConfigurationError(f"curve_contact_angles must map curve id -> {{role: (gamma_L, gamma_R)}}, got {spec!r}")
    out = {}
    for cid, roles in spec.items():
        if not isinstance(roles, Mapping):
            raise ConfigurationError(f"curve_contact_angles[{cid!r}] must map role -> (gamma_L, gamma_R), got {roles!r}")
        out[str(cid)] = {}
        for role, g in roles.items():
            if role not in ("leading", "trailing", "any"):
                raise ConfigurationError(f"curve_contact_angles[{cid!r}]: role must be leading, trailing or any, "
                                         f"got {role!r}")
            if len(g) != 2:
                raise ConfigurationError(f"curve_contact_angles[{cid!r}][{role!r}] must be (gamma on rail L, gamma "
                                         f"on rail R) in rad, got {g!r}")
            for v in g:
                _rng(f"curve_contact_angles[{cid!r}][{role!r}]", v, 0.0, 1.5, unit="rad")
            out[str(cid)][role] = (float(g[0]), float(g[1]))
    return out


def _rng(name: str, v, lo: float, hi: float, *, lo_open=False, unit="") -> None:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ConfigurationError(f"{name} must be a finite number, got {v!r}")
    if v < lo or v > hi or (lo_open and v == lo):
        left = "(" if lo_open else "["
        raise ConfigurationError(f"{name} must lie in {left}{lo:g}, {hi:g}]{' ' + unit if unit else ''}, got {v!r}")


@dataclass(frozen=True)
class EstimatorConfig:
    """Every option of :func:`estimator.estimate_run`.

    Quality control: ``speed_gate_m_s`` (samples slower are masked; default
    3 m/s, the lowest speed at which the 100–300 mm band lies above
    ``f_lo_hz`` = 10 Hz), ``standstill_m_s``, ``flat_min_s`` (a dropout that
    holds the last value this long is masked), ``clip_min_samples``,
    ``mask_margin_s``, ``max_scale_error`` (odometer).

    Inversion: ``models``; ``f_lo_hz`` and ``f_hi_hz`` (default
    ``f_hi_fraction × fs``, the anti-aliasing passband of a delta-sigma DAQ);
    ``regularisation`` α (Tikhonov, relative to the one-third-octave envelope
    of the largest singular value of ``B``; see :mod:`estimator.inversion`);
    ``transfer_df_hz`` the frequency step the transfer functions are
    evaluated on; ``contact`` (Hertz contact: stiffness and contact-patch
    length); ``contact_filter`` (undo the contact patch's averaging);
    ``contact_angles`` = ``None`` (from the line's curvature with
    :mod:`estimator.contact_angles`) or ``(θ_L, θ_R)`` in rad for every curve;
    ``curve_contact_angles`` (a field calibration, :mod:`estimator.diagnosis`):
    per curve id and wheelset role, the contact angles on rails L and R, which
    take precedence on that curve (:meth:`curve_angles`); ``bogie_coupling``
    (the rail deflection under each wheelset due to the other wheelset's
    contact forces, :func:`estimator.inversion.rail_coupling`; off: the
    thesis's single-wheelset models); ``contact_loss_check`` (flag where the
    estimated dynamic contact force lifts the wheel off the rail,
    :mod:`estimator.contact_load`; the monitoring's uncertainty variants,
    which read band levels only, leave it off).

    Space: ``wheelbase_m`` (None: measured from the data, see
    :func:`estimator.workflow.estimate_run`), ``comb_revolutions`` (length of
    the moving synchronous average of the wheel comb, in revolutions),
    ``wheel_radius_m`` nominal rolling radius [m] (None: the wheelset
    model's, the contact points' distance from the axle's axis,
    :func:`estimator.inversion.check_wheelset_geometry`; give a measured radius
    for worn wheels, CLI ``--wheel-radius``). One radius serves the
    circumference search, the curving model's contact angles and the Hertz
    contact (``contact.wheel_rolling_radius`` follows it,
    :func:`estimator.workflow.prepare`). The circumference starts from it times
    the balise-measured odometer scale and is refined from the data over
    ``radius_search``: relative ``(lo, hi)``, default
    :data:`WHEEL_WEAR_SEARCH` (−5 %…+1 %, new to fully worn), or a float for a
    symmetric ``±`` interval. A peak is accepted when its z-score against the
    rail-only null reaches :data:`estimator.wheel.MIN_SIGNIFICANCE`, it stands
    :data:`estimator.wheel.MIN_CONTRAST` times above every other candidate and
    it is not at the edge of the interval; otherwise the odometer's
    circumference is used and the estimate's processing history says why.

    Sleepers: ``sleeper_comb`` removes the sleeper-passing part, the
    parametric excitation of the discrete supports that repeats with the
    sleeper spacing (:mod:`estimator.sleepers`), at its significant orders only;
    ``sleeper_spacing_m`` (None: the line's; without a line, nothing is
    separated); ``sleeper_bays`` ``R`` of its moving synchronous average
    (±R bays; the comb's noise at a removed order is ``Σw²/(Σw)²`` of the
    roughness's power there, +0.045 dB at 64).

    Standards: ``bands_mm``, ``thresholds_um`` per band, ``en15610_segment_m``
    (Fourier segment of EN 15610 Method A), ``section_length_m`` (spectra per
    line section, or per stretch of this length without a line).
    """

    models: tuple[str, ...] = MODELS
    speed_gate_m_s: float = 3.0
    standstill_m_s: float = 0.2
    flat_min_s: float = 0.02
    clip_min_samples: int = 3
    mask_margin_s: float = 0.005
    max_scale_error: float = 0.02
    f_lo_hz: float = 10.0
    f_hi_hz: float | None = None
    f_hi_fraction: float = 0.4
    regularisation: float = 0.02
    transfer_df_hz: float = 0.05
    contact: ContactParameters = field(default_factory=ContactParameters)
    contact_filter: bool = True
    contact_angles: tuple[float, float] | None = None
    curve_contact_angles: Mapping | None = None
    trackform_supports: str = "continuous"
    bogie_coupling: bool = True
    contact_loss_check: bool = True
    wheelbase_m: float | None = None
    comb_revolutions: int = 32
    sleeper_comb: bool = True
    sleeper_spacing_m: float | None = None
    sleeper_bays: int = 64
    wheel_radius_m: float | None = None
    radius_search: float | tuple[float, float] = WHEEL_WEAR_SEARCH
    bands_mm: tuple[tuple[float, float], ...] = EN13231_BANDS_MM
    thresholds_um: Mapping = field(default_factory=lambda: dict(DEFAULT_THRESHOLDS_UM))
    en15610_segment_m: float = 2.0
    section_length_m: float = 100.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "models", parse_models(self.models))
        _rng("speed_gate_m_s", self.speed_gate_m_s, 0.0, 100.0, lo_open=True, unit="m/s")
        _rng("standstill_m_s", self.standstill_m_s, 0.0, self.speed_gate_m_s, unit="m/s")
        _rng("flat_min_s", self.flat_min_s, 0.0, 10.0, lo_open=True, unit="s")
        _rng("clip_min_samples", self.clip_min_samples, 2, 1000)
        _rng("mask_margin_s", self.mask_margin_s, 0.0, 10.0, unit="s")
        _rng("max_scale_error", self.max_scale_error, 0.0, 0.5, lo_open=True)
        _rng("f_lo_hz", self.f_lo_hz, 0.0, 1e5, lo_open=True, unit="Hz")
        if self.f_hi_hz is not None:
            _rng("f_hi_hz", self.f_hi_hz, self.f_lo_hz, 1e5, lo_open=True, unit="Hz")
        _rng("f_hi_fraction", self.f_hi_fraction, 0.05, 0.5)
        _rng("regularisation", self.regularisation, 0.0, 1.0)
        _rng("transfer_df_hz", self.transfer_df_hz, 1e-3, 1.0, unit="Hz")
        if self.contact_angles is not None:
            if len(self.contact_angles) != 2:
                raise ConfigurationError(f"contact_angles must be (theta_L, theta_R) in rad, got {self.contact_angles!r}")
            for v in self.contact_angles:
                _rng("contact_angles", v, -1.5, 1.5, unit="rad")
            object.__setattr__(self, "contact_angles", tuple(float(v) for v in self.contact_angles))
        if self.curve_contact_angles is not None:
            object.__setattr__(self, "curve_contact_angles", _curve_angles(self.curve_contact_angles))
        if self.trackform_supports not in ("continuous", "discrete"):
            raise ConfigurationError(f"trackform_supports must be 'continuous' or 'discrete', "
                                     f"got {self.trackform_supports!r}")
        if not isinstance(self.bogie_coupling, bool):
            raise ConfigurationError(f"bogie_coupling must be True or False, got {self.bogie_coupling!r}")
        if not isinstance(self.contact_loss_check, bool):
            raise ConfigurationError(f"contact_loss_check must be True or False, got {self.contact_loss_check!r}")
        if self.wheelbase_m is not None:
            _rng("wheelbase_m", self.wheelbase_m, 0.5, 10.0, unit="m")
        _rng("comb_revolutions", self.comb_revolutions, 2, 10_000)
        if not isinstance(self.sleeper_comb, bool):
            raise ConfigurationError(f"sleeper_comb must be True or False, got {self.sleeper_comb!r}")
        if self.sleeper_spacing_m is not None:
            _rng("sleeper_spacing_m", self.sleeper_spacing_m, 0.2, 5.0, unit="m")
        _rng("sleeper_bays", self.sleeper_bays, 2, 10_000)
        if self.wheel_radius_m is not None:
            _rng("wheel_radius_m", self.wheel_radius_m, 0.1, 1.0, unit="m")
        if isinstance(self.radius_search, (tuple, list)):
            if len(self.radius_search) != 2:
                raise ConfigurationError(f"radius_search must be a half-width or (lo, hi) relative to the nominal "
                                         f"circumference, got {self.radius_search!r}")
            lo, hi = self.radius_search
            _rng("radius_search", lo, -0.2, 0.0, unit="(relative, lower end)")
            _rng("radius_search", hi, 0.0, 0.2, unit="(relative, upper end)")
            object.__setattr__(self, "radius_search", (float(lo), float(hi)))
        else:
            _rng("radius_search", self.radius_search, 0.0, 0.1)
        bands = tuple((float(a), float(b)) for a, b in self.bands_mm)
        for a, b in bands:
            if not 0 < a < b:
                raise ConfigurationError(f"bands_mm entries must be (short, long) with 0 < short < long, got {(a, b)}")
        object.__setattr__(self, "bands_mm", bands)
        th = {}
        for band in bands:
            v = dict(self.thresholds_um).get(band, DEFAULT_THRESHOLDS_UM.get(band, math.nan))
            th[band] = float(v)
        object.__setattr__(self, "thresholds_um", th)
        _rng("en15610_segment_m", self.en15610_segment_m, 1.0, 100.0, unit="m")
        _rng("section_length_m", self.section_length_m, 1.0, 1e5, unit="m")

    def f_hi(self, fs: float) -> float:
        """Upper frequency of the inversion band [Hz] for a run sampled at ``fs``."""
        hi = self.f_hi_fraction * fs if self.f_hi_hz is None else min(self.f_hi_hz, self.f_hi_fraction * fs * 1.25)
        if hi <= self.f_lo_hz:
            raise ConfigurationError(f"the inversion band {self.f_lo_hz:g}-{hi:g} Hz is empty at fs = {fs:g} Hz")
        return hi

    def window_m(self, band: tuple[float, float]) -> float:
        """Moving-window length of a band (thesis Table 4.1; otherwise 5 × the band's longest wavelength)."""
        return EN13231_WINDOWS_M.get(band, 5e-3 * band[1])

    def replace(self, **changes) -> "EstimatorConfig":
        return replace(self, **changes)

    def curve_angles(self, curve_id: str, role: str | None, side_of_rail: Mapping) -> tuple[float, float] | None:
        """Calibrated ``(θ_L, θ_R)`` (vehicle sides, thesis eq. 2.12) of a curve for a wheelset ``role``, or None.

        ``curve_contact_angles`` holds, per curve id and role (``leading``, ``trailing`` or ``any``), the
        contact angles ``(γ on rail L, γ on rail R)`` [rad] with the sign of :mod:`estimator.contact_angles`
        (γ > 0: the contact normal tilts towards the track centre); the vehicle sides read them through
        ``side_of_rail`` (θ_L = −γ of the rail under the left wheel, θ_R = +γ of the rail under the right one).
        """
        per_curve = (self.curve_contact_angles or {}).get(curve_id)
        if not per_curve:
            return None
        g = per_curve.get(role) if role in per_curve else per_curve.get("any")
        if g is None:
            return None
        gamma = {"L": g[0], "R": g[1]}
        rail_of_side = {s: r for r, s in side_of_rail.items()}
        return -gamma[rail_of_side["L"]], gamma[rail_of_side["R"]]

    def as_dict(self) -> dict:
        out = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name == "thresholds_um":
                v = {f"{a:g}-{b:g}": t for (a, b), t in v.items()}
            elif f.name == "contact":
                v = {g.name: getattr(v, g.name) for g in fields(v)}
            elif f.name == "curve_contact_angles" and v is not None:
                v = {c: {r: list(g) for r, g in roles.items()} for c, roles in v.items()}
            out[f.name] = v
        return out
