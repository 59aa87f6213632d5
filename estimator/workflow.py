"""The field estimate of one run, as a library workflow (thesis Fig. 2.3): read → QC → invert → space → indexes.

:func:`prepare` builds a :class:`FieldModel` once per wheelset model, sensor
table, line and options (the transfer functions are computed on first use
and memoised, so a fleet's runs share them); :func:`estimate_run` turns one
run into a :class:`~estimator.results.FieldEstimate`:

1. read the run (:func:`estimator.io.read_run`), sensitivities applied once;
2. direction and orientation → leading wheelset, rail of each vehicle side
   (:func:`estimator.orientation.orientation`);
3. continuous chainage from the odometer, balise resets handled
   (:func:`estimator.spatial.odometry_track`);
4. quality control, every finding masked and logged (:func:`estimator.qc.check_run`);
5. per wheelset and model, the accelerations are inverted through the
   regularised transfer functions of :mod:`estimator.inversion` — per
   trackform section of the line and per contact-angle class (tangent track,
   each curve), blended along the curve transitions;
6. wheelbase: given, or measured by cross-correlating the leading and
   trailing wheelsets' (whitened) estimates of the same rails (they see the
   same roughness ``a`` apart; rail by rail, over wavelengths longer than a
   few contact patches); with the wheelbase given and fewer than two balises
   in the run, that lag gives the odometer's scale
   (:func:`estimator.spatial.rescaled`); the same correlations, every rail of one
   wheelset against every rail of the other, check the channels against the
   sensor table (a channel of the wrong sign, swapped sides or wheelsets:
   :mod:`estimator.lead_trail`; refused naming them); then, with ``bogie_coupling``, each
   wheelset is inverted again with the rail deflection the other wheelset's
   contact forces cause under it (:func:`estimator.inversion.rail_coupling`;
   the forces from the other wheelset's same model, else its richest one,
   what they lack stated);
   the other wheelset's samples masked only for clipping enter that
   coupling term as recorded (full scale), up to ``MAX_COUPLING_SATURATED_SHARE``
   of them, rather than dropping the coupling for the whole run;
7. rolling circumference per wheelset (:func:`estimator.wheel.circumference`),
   then each wheelset's irregularity is read on a grid of ``N`` samples per
   revolution (step ≤ ``λ_min/3``, :func:`estimator.spatial.spatial_step`);
8. comb filter at the rotation orders → rail roughness and wheel roughness
   with its polygon orders (:mod:`estimator.wheel`); the sleeper-passing part
   removed at its significant orders (:mod:`estimator.sleepers`); contact
   filter undone (:mod:`estimator.contact_filter`);
9. EN 13231-3 band indexes where the speed lets the inversion band cover the
   band, exceedance shares; EN 15610 spectra per stretch (line sections and
   curves) with the ISO 3095 limit; corrugation type (:mod:`estimator.corrugation`);
10. where the estimated dynamic contact force exceeds the static wheel load, the
   wheel leaves the rail: flagged (``contact_loss``, :mod:`estimator.contact_load`).
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Mapping

import numpy as np
import pandas as pd
from scipy import fft as sfft

from estimator.config import EstimatorConfig
from estimator.band_caution import band_cautions
from estimator.contact_angles import CurvingModel, contact_angles
from estimator.contact_filter import contact_gain
from estimator.contact_load import contact_force, contact_loss_events
from estimator.corrugation import MIN_PROMINENCE_DB, classify, model_resonances, spectral_peak
from estimator.errors import ChannelError, ConfigurationError, NoValidDataError, WheelbaseError
from estimator.inversion import (TimeIrregularity, check_sensor_mounting, check_wheelset_geometry,
                                 condition_by_band, invert, model_channels, rail_coupling, sample_many,
                                 side_valid_time, side_validity, wheelset_transfer)
from estimator.io import LineDescription, read_line, read_run
from estimator.io.sensors import check_sensors, read_sensors
from estimator.lead_trail import MIN_CORRELATION, LeadTrail, arrangement_findings, lead_trail
from estimator.memo import Memo
from estimator.orientation import Orientation, orientation
from estimator.qc import check_run, glitches
from estimator.results import FieldEstimate, ProfileEstimate
from estimator.run import Run
from estimator.sleepers import SleeperPassing, quasi_static_orders, sleeper_comb
from estimator.spatial import OdometryTrack, nice_step, odometry_track, rescaled, spatial_step
from estimator.standards.en13231 import band_indexes, exceedance
from estimator.standards.en15610 import roughness_spectrum
from estimator.wheel import MIN_SIGNIFICANCE, CircumferenceFit, circumference, comb, wheel_roughness
from receptance.contact import ContactParameters
from receptance.track import pinned_pinned_frequency, track_frf
from receptance.trackform import Trackform

__all__ = ["FieldModel", "prepare", "with_wheel_radius", "in_service", "estimate_run", "transfer_classes",
           "WHEELBASE_RANGE_M",
           "WHEELBASE_MIN_CORRELATION"]

log = logging.getLogger("estimator")

#: range searched for the wheelbase when it is measured from the data [m]
WHEELBASE_RANGE_M = (1.2, 4.0)
#: smallest normalised correlation between the two wheelsets' estimates for a measured wheelbase
WHEELBASE_MIN_CORRELATION = MIN_CORRELATION
_PRIMARY = ("vertical_lateral", "vertical", "half")
#: what a wheelset inverted without the rail coupling costs, measured on the virtual line (nominal, curve 1, its
#: corrugated rail, leading wheelset, vertical + lateral model, 1 m windows)
UNCOUPLED_EFFECT = ("on the virtual line's corrugated curve +4.6 dB in 30-100 mm instead of +1.0 dB coupled; "
                    "100-300 mm unaffected")
#: grid step of the circumference search [m] (the wheel's orders with wavelengths >= 20 mm)
CIRCUMFERENCE_STEP_M = 0.005
#: Largest share of the run whose samples of the other wheelset may be masked for clipping alone (the clipped
#: samples and the QC margin around them) and still feed this wheelset's rail-coupling term. Clipping only cuts
#: the peaks, so a recorded full-scale value errs by the clipped excess, which reaches this wheelset's estimate
#: through a correction term; without it the wheelset is inverted uncoupled (1-4 dB high in 30-100 mm on the
#: virtual line's curve) or loses the stretches around every clip (tests/test_estimator_synthetic.py). A channel
#: clipping on more than a tenth of the run bounds nothing any more; the virtual line's tight range masks 2.7 %.
MAX_COUPLING_SATURATED_SHARE = 0.10


#: What depends on the track alone, shared by every field model of the process: a trackform's receptance
#: (:func:`receptance.track.track_frf`) and the rail coupling of two wheelsets on it (:func:`rail_coupling`),
#: keyed by the trackform's values. The monitoring's uncertainty variants of one wheelset model differ in the
#: wheelset, the sensors or the contact, not the track: each held its own copies before (52 of every trackform's
#: receptance, and 52 of every coupling per run's wheelbase), which took one uncertainty run past the memo's budget
#: on the virtual line, so that every variant's transfer functions were evicted before the next run used them.
TRACK_MEMO = Memo()


@dataclass(frozen=True, eq=False)
class FieldModel:
    """A wheelset model prepared for field estimates with one sensor table, line and set of options.

    Transfer functions are computed on first use for each (model, wheelset,
    trackform, contact angles) and memoised in ``cache`` (a :class:`~estimator.memo.Memo`
    the object owns, in the process's store bounded in bytes; a dictionary given
    is taken as its first entries), so that many runs share them; what depends on the track alone (its
    receptance, the rail coupling) is memoised once per process for every field model (:data:`TRACK_MEMO`).
    ``provenance``: where the
    model's settings came from beyond the files it was prepared from (a field
    calibration), recorded first in every estimate's processing history.
    """

    model: object
    sensors: pd.DataFrame
    line: LineDescription | None
    trackform: Trackform | None
    config: EstimatorConfig
    contact_stiffness: float
    semi_axis_m: float
    curving: CurvingModel = CurvingModel()
    provenance: tuple[str, ...] = ()
    cache: Memo = field(default_factory=Memo, repr=False)

    def __post_init__(self):
        if not isinstance(self.cache, Memo):
            object.__setattr__(self, "cache", Memo(self.cache))
        # a calibration's angles are keyed by curve id: an id the line lacks (another line's calibration, a renamed
        # curve) would otherwise be carried in the provenance as if it applied, while nothing uses it
        wanted = sorted((self.config.curve_contact_angles or {}).keys())
        if not wanted:
            return
        known = [c.id for c in self.line.curves] if self.line is not None else []
        unknown = [c for c in wanted if c not in known]
        if self.line is None:
            raise ConfigurationError(f"calibrated contact angles are given for curve(s) {wanted}, which only a line "
                                     "description can place: give the line (--line)")
        if unknown:
            raise ConfigurationError(f"calibrated contact angles are given for curve(s) {unknown}, which line "
                                     f"{self.line.source or self.line.name!r} does not have (its curves: {known})")

    def trackforms(self) -> list[tuple[float, float, Trackform]]:
        """Trackform sections ``(from, to, Trackform)``; an explicit trackform applies everywhere."""
        if self.trackform is not None or self.line is None:
            return []
        return [(t.from_m, t.to_m, t.trackform) for t in self.line.trackforms if t.trackform is not None]

    def default_trackform(self) -> Trackform:
        return self.trackform if self.trackform is not None else Trackform()

    def _trackform(self, tf_index: int) -> Trackform:
        return self.default_trackform() if tf_index < 0 else self.trackforms()[tf_index][2]

    def _track(self, tf_index: int, fs: float):
        tf, df, supports = self._trackform(tf_index), self.config.transfer_df_hz, self.config.trackform_supports
        key = ("track", tf, supports, df, fs)  # the track's values, not its index: shared across field models
        if key not in TRACK_MEMO:
            f = df * np.arange(1, int(np.floor(0.5 * fs / df)) + 1)
            TRACK_MEMO[key] = track_frf(f, tf, supports=supports)
        return TRACK_MEMO[key]

    def transfer(self, kind: str, channels: pd.DataFrame, fs: float, tf_index: int, theta: tuple[float, float]):
        """Memoised :func:`estimator.inversion.wheelset_transfer`."""
        th = (0.0, 0.0) if kind != "vertical_lateral" else (round(theta[0], 5), round(theta[1], 5))
        key = ("T", kind, tuple(channels["name"]), fs, tf_index, th)
        if key not in self.cache:
            lo, hi = self.config.f_lo_hz, self.config.f_hi(fs)
            self.cache[key] = wheelset_transfer(self.model, channels, kind, fs, f_lo=lo, f_hi=hi,
                                                alpha=self.config.regularisation, df=self.config.transfer_df_hz,
                                                track=self._track(tf_index, fs),
                                                contact_stiffness=self.contact_stiffness, theta=th)
        return self.cache[key]

    def coupling(self, tr, tr_other, tf_index: int, distance_m: float) -> np.ndarray:
        """Memoised :func:`estimator.inversion.rail_coupling` on the transfer grid of ``tr``."""
        # the distance is computed at the key's 0.1 mm (far below what a wheelbase is measured to): the value
        # then depends on the key alone, not on which run asked first (a batch gives the same numbers in any order)
        d = round(float(distance_m), 4)
        f = tr.freqs_hz
        tf = self._trackform(tf_index)
        key = ("C", tf, d, tr.sides, tr_other.sides, tr.theta, tr_other.theta, f.size, float(f[0]), float(f[-1]))
        if key not in TRACK_MEMO:
            TRACK_MEMO[key] = rail_coupling(f, tf, d, tr.sides, tr_other.sides, tr.theta, tr_other.theta)
        return TRACK_MEMO[key]

    def resonances(self, tf_index: int = -1):
        key = ("res", tf_index)
        if key not in self.cache:
            self.cache[key] = model_resonances(self.model, self._trackform(tf_index), self.contact_stiffness)
        return self.cache[key]


def in_service(model):
    """The wheelset as it runs: a lab model (free-free, with the test's artefacts) gets its test artefacts
    removed (:meth:`ModalModel.for_service`) and the primary suspension added; a model that already has a
    primary suspension (``railmodal model build``) keeps it. Either way every mode the model holds enters
    its receptances (:func:`with_every_mode`)."""
    kinds = [getattr(mod, "kind", "") for mod in getattr(model, "modifications", ())]
    if not hasattr(model, "with_modification") or "primary_suspension" in kinds:
        return with_every_mode(model)
    from receptance.modification import PrimarySuspension

    if hasattr(model, "for_service"):
        model = model.for_service()
    log.info("model %s has no primary suspension: test artefacts removed and the primary suspension added "
             "(thesis Table 2.1) for the wheelset in service", getattr(model, "name", ""))
    return with_every_mode(model.with_modification(PrimarySuspension()))


def with_every_mode(model):
    """The model with the FE modes above its test band in its receptances (``max_hz`` lifted).

    The lab keeps a model to its test band (``ModalModel.max_hz``): the FRFs it is compared with were
    measured at the test's sensors, where LSFD residuals stand for the modes above. A field inversion has
    no such residuals, and it needs the receptance at the wheel–rail contact, where the modes above the band
    (the wheel's web and tread modes) add a flexibility comparable with the track's near the band's top
    (thesis eq. 2.28 summed over every mode). Measured on the virtual line: with the modes above 500 Hz
    left out, the half-model transfer ``D/B`` is off by +0.8 dB at 190 Hz and +2.6 dB at 300 Hz; with the
    design FE's modes to 2 kHz in, by at most 0.4 dB over 50–400 Hz.
    """
    cap = getattr(model, "max_hz", None)
    if cap is None:
        return model
    above = int(np.sum(np.asarray(model.freqs_hz) > cap))
    if not above:  # nothing above the cap: lifting it changes no receptance
        return replace(model, max_hz=None)
    step = (f"in service: the {above} FE mode(s) above the test band's {cap:g} Hz enter the receptances (their "
            f"flexibility at the wheel-rail contact)")
    log.info("model %s: %s", getattr(model, "name", ""), step)
    return replace(model, max_hz=None, history=tuple(model.history) + (step,))


#: The model's highest mode must reach this multiple of the inversion band's top: the first mode left out then
#: answers the band's top with at most 1/(1 - 1/3²) = 1.125 times its static flexibility, i.e. quasi-statically.
MODAL_BASIS_FACTOR = 3.0


def modal_basis(model, f_hi: float) -> tuple[str, bool]:
    """A processing note on the model's modal basis and whether it is too short for the band's top ``f_hi``.

    Returns
    -------
    note : str
    short : bool
        True when the highest mode lies below :data:`MODAL_BASIS_FACTOR` × ``f_hi``: the contact
        receptance then lacks the flexibility of the modes above, and the estimate's upper band is biased
        (see :func:`with_every_mode` for the size measured on the virtual line).
    """
    f = np.asarray(getattr(model, "freqs_hz", ()), float)
    cap = getattr(model, "max_hz", None)
    if cap is not None:
        f = f[f <= cap]
    elastic = f[f > 0]
    if not elastic.size:
        return "wheelset model: no elastic mode", False
    top = float(elastic.max())
    note = f"wheelset model: {elastic.size} elastic modes up to {top:.0f} Hz"
    if top >= MODAL_BASIS_FACTOR * f_hi:
        return note, False
    return (note + f", below {MODAL_BASIS_FACTOR:g} x the band's top {f_hi:g} Hz: the contact receptance lacks the "
            f"flexibility of the modes above, the upper band is biased; build the model from an FE export reaching "
            f">= {MODAL_BASIS_FACTOR * f_hi:.0f} Hz with every FE mode kept"), True


def prepare(model, sensors, *, line=None, trackform: Trackform | None = None,
            config: EstimatorConfig | None = None) -> FieldModel:
    """A :class:`FieldModel` from a wheelset model (ModalModel or a ``hybrid_model.npz`` path; made
    :func:`in_service`), a sensor table (path or DataFrame), an optional line description (path or
    LineDescription) and options.

    Raises
    ------
    ModelFileError, SensorTableError, RunFileError
        An unreadable model file, sensor table or line description.
    WheelsetModelError
        A model whose geometry is not a railway wheelset's in metres
        (:func:`estimator.inversion.check_wheelset_geometry`).
    SensorTableError
        An accelerometer row not on its side's axlebox (:func:`estimator.inversion.check_sensor_mounting`).
    """
    from receptance.model_io import load_model

    cfg = config or EstimatorConfig()
    m = in_service(load_model(model) if isinstance(model, (str, Path)) else model)
    table = read_sensors(sensors) if isinstance(sensors, (str, Path)) else check_sensors(sensors)
    # model and sensor table against each other before any run is read: a wheelset in metres (not mm), and every
    # accelerometer on its side's axlebox (not x and y swapped, not near the middle of the axle)
    what = f"model {model}" if isinstance(model, (str, Path)) else f"model {getattr(m, 'name', '') or '(object)'!r}"
    geometry = check_wheelset_geometry(m, what)
    check_sensor_mounting(m, table, str(sensors) if isinstance(sensors, (str, Path)) else "<sensor table>")
    ln = read_line(line) if isinstance(line, (str, Path)) else line
    cfg = with_wheel_radius(cfg, geometry, what)
    contact = cfg.contact.contact()
    return FieldModel(m, table, ln, trackform, cfg, contact.stiffness, contact.semi_axis_x,
                      CurvingModel(rolling_radius_m=cfg.wheel_radius_m))


def with_wheel_radius(cfg: EstimatorConfig, geometry: dict, what: str = "the wheelset model") -> EstimatorConfig:
    """``cfg`` with its nominal wheel radius resolved and carried into the Hertz contact.

    The radius is ``cfg.wheel_radius_m`` when given (a measured, worn wheel), else the model's rolling radius:
    the mean distance of its contact points from the axle's axis (``geometry`` of
    :func:`estimator.inversion.check_wheelset_geometry`). One radius serves the circumference search, the curving
    model (thesis eq. 2.12 angles) and ``contact.wheel_rolling_radius`` (Hertz stiffness and patch, thesis
    eq. 2.5): a wheel 2 cm smaller than assumed otherwise shifts the comb's period onto a shadow peak
    (:mod:`estimator.wheel`) and the contact stiffness by 1 %.
    """
    model_r = 0.5 * (geometry["rolling_radius_L_m"] + geometry["rolling_radius_R_m"])
    r = float(cfg.wheel_radius_m) if cfg.wheel_radius_m is not None else model_r
    source = "given" if cfg.wheel_radius_m is not None else "the model's contact points"
    default_contact_r = ContactParameters.__dataclass_fields__["wheel_rolling_radius"].default
    c_r = cfg.contact.wheel_rolling_radius
    if c_r != default_contact_r and abs(c_r - r) > 1e-6:
        # an explicit contact radius that disagrees with the wheel's: the wheel radius wins (one wheel), said aloud
        log.warning("%s: the contact's wheel_rolling_radius %.4f m is replaced by the nominal wheel radius %.4f m "
                    "(%s); set wheel_radius_m (--wheel-radius) to change both", what, c_r, r, source)
    log.info("%s: nominal wheel radius %.4f m (%s; the model's rolling radius %.4f m)", what, r, source, model_r)
    contact = cfg.contact if c_r == r else replace(cfg.contact, wheel_rolling_radius=r)
    return cfg.replace(wheel_radius_m=r, contact=contact)


# --------------------------------------------------------------------------- helpers
def sleeper_spacing(cfg: EstimatorConfig, fm: FieldModel) -> float | None:
    """The sleeper spacing the sleeper comb uses: the option's, else the line's; None when it is off or unknown."""
    if not cfg.sleeper_comb:
        return None
    if cfg.sleeper_spacing_m is not None:
        return float(cfg.sleeper_spacing_m)
    return float(fm.line.sleeper_spacing_m) if fm.line is not None else None


def expected_sleeper_passing(fm: FieldModel, x: np.ndarray, spacing: float) -> np.ndarray | None:
    """The track model's quasi-static sleeper-passing orders under the wheel load (:func:`quasi_static_orders`)
    for the trackform covering most of ``x``; None when that trackform's support spacing is not ``spacing``."""
    sections = fm.trackforms()
    tf = max(sections, key=lambda s: min(s[1], x[-1]) - max(s[0], x[0]))[2] if sections else fm.default_trackform()
    if abs(tf.support_spacing - spacing) > 0.01 * spacing:
        return None
    load = fm.config.contact.wheel_load_N
    key = ("sleeper_passing", tf, load)
    if key not in fm.cache:
        fm.cache[key] = quasi_static_orders(tf, load)
    return fm.cache[key]


def _sleeper_step(w: int, kind: str, sp: SleeperPassing) -> str:
    parts = []
    for rail in sorted(set(sp.orders["rail"])):
        o = sp.removed(rail)
        orders = ", ".join(f"order {int(r.order)} ({1e3 * r.wavelength_m:.0f} mm) {1e6 * r.amplitude_m:.1f} µm"
                           + (f" (track model under the wheel load {1e6 * r.expected_m:.1f} µm)"
                              if np.isfinite(r.expected_m) else "") for r in o.itertuples())
        parts.append(f"rail {rail}: " + (f"removed {orders}" if len(o) else "nothing significant"))
    return f"sleeper passing (spacing {sp.spacing_m:g} m, ±{sp.bays} bays), wheelset {w}, {kind}: " + "; ".join(parts)


def _sleeper_off(cfg: EstimatorConfig) -> str:
    if not cfg.sleeper_comb:
        return "sleeper passing not separated (sleeper_comb off)"
    return "sleeper passing not separated: no line and no sleeper_spacing_m given"


def _chainage_to_time(track: OdometryTrack, offset: float):
    """Monotone map chainage → time for a wheel ``offset`` ahead of the odometry reference (along chainage)."""
    c = track.chainage * track.travel_sign
    mono = np.maximum.accumulate(c)
    keep = np.concatenate([[True], np.diff(mono) > 0])
    xs, ts = mono[keep], track.t[keep]

    def t_of(x: np.ndarray) -> np.ndarray:
        return np.interp((np.asarray(x) - offset) * track.travel_sign, xs, ts, left=np.nan, right=np.nan)

    return t_of


def _class_weights(fm: FieldModel, kind: str, chain: np.ndarray, orient: Orientation, role: str | None = None
                   ) -> list[tuple[int, tuple[float, float], np.ndarray]]:
    """(trackform index, (θ_L, θ_R) vehicle sides, weight per sample) of every class present.

    ``role`` (``leading``/``trailing``) selects a curve's calibrated angles
    (``EstimatorConfig.curve_contact_angles``), which take precedence on that curve.
    """
    cfg = fm.config
    tf_idx = np.full(chain.size, -1)
    for i, (a, b, _) in enumerate(fm.trackforms()):
        tf_idx[(chain >= a) & (chain <= b)] = i
    angle_classes: list[tuple[tuple[float, float], np.ndarray]] = []
    if kind == "vertical_lateral":
        line = fm.line
        if line is not None and line.curves:
            if cfg.contact_angles is not None:
                tangent = (0.0, 0.0)
            else:
                tl, tr = contact_angles(np.zeros(1), orient.side_of_rail, fm.curving)
                tangent = (float(tl[0]), float(tr[0]))
            rest = np.ones(chain.size)
            for c in line.curves:
                w = c.ramp(chain)
                if not np.any(w > 0):
                    continue
                calibrated = cfg.curve_angles(c.id, role, orient.side_of_rail)
                if calibrated is not None:
                    body = calibrated
                elif cfg.contact_angles is not None:
                    body = cfg.contact_angles
                else:
                    bl, br = contact_angles(np.array([c.sign / c.radius_m]), orient.side_of_rail, fm.curving)
                    body = (float(bl[0]), float(br[0]))
                angle_classes.append((body, w))
                rest = rest - w
            angle_classes.insert(0, (tangent, np.clip(rest, 0.0, 1.0)))
        else:
            angle_classes.append((cfg.contact_angles or (0.0, 0.0), np.ones(chain.size)))
    else:
        angle_classes.append(((0.0, 0.0), np.ones(chain.size)))
    out = []
    for t in np.unique(tf_idx):
        ind = (tf_idx == t).astype(float)
        for th, w in angle_classes:
            ww = ind * w
            if np.any(ww > 0):
                out.append((int(t), th, ww))
    return out


#: public name of the class rule: the field diagnosis (:mod:`estimator.diagnosis`) uses the estimator's own classes
transfer_classes = _class_weights


#: The lead/trail correlation uses wavelengths of at least this many contact-patch lengths (2 a_x). Shorter
#: waves reach the two wheelsets' estimates differently — averaged over each wheel's own Hertz patch, mixed with
#: each wheel's own roughness and the sensors' noise, near the track's pinned-pinned resonance at high rates —
#: and, the spectra being whitened, each such one-third octave would weigh as much as a coherent one. A band tied
#: to the patch (~50 mm for a_x = 5.2 mm) rather than to the sampling rate keeps the correlation what the rails
#: make it at any fs. Measured on the virtual line (nominal, 400-800 m, vertical model): over the whole band 0.57,
#: 0.56, 0.40, 0.49 at 0.5, 1, 2, 2.5 kHz (one 2 kHz run at the 0.3 threshold); from 52 mm 0.67, 0.75, 0.75, 0.76,
#: the wheelbase within 0.3 mm of the vehicle's (tests/test_field_bogie_coupling.py).
WHEELBASE_PATCH_LENGTHS = 5.0
#: Chainage [m] over which the channels are checked. A correlation over wavelengths of 0.05-1.2 m on 300 m has a
#: standard error of about 1/sqrt(300 m / 0.05 m) ≈ 0.013, against the check's 0.3. It costs 0.036 s of a 150 s
#: run's 2.2 s estimate; the whole run cost 0.26 s (measured with the correlation padded to twice the run).
ARRANGEMENT_CHECK_SPAN_M = 300.0
#: preference among a wheelset's estimates of a rail for the lead/trail correlation
_WHEELBASE_KINDS = ("vertical", "vertical_lateral", "half")
#: ... and for the channel check: the half model's estimate of a rail flips exactly with its channel (a flipped
#: channel's rail correlates at -0.65 on a synthetic run, against -0.38 through the vertical model, which mixes the
#: two sides)
_CHECK_KINDS = ("half", "vertical", "vertical_lateral")


def _lead_trail(fm: FieldModel, tis: Mapping, track: OdometryTrack, orient: Orientation, lam_min: float,
                span_m: float | None = None, kinds: tuple[str, ...] | None = None) -> LeadTrail | None:
    """The two wheelsets' estimates of each rail (``kinds`` in order of preference, :data:`_WHEELBASE_KINDS` by
    default), cross-correlated over the
    wavelengths from ``max(λ_min, WHEELBASE_PATCH_LENGTHS · 2 a_x)`` (the Hertz patch, thesis eq. 2.5) to the
    shortest wheelbase searched (:func:`estimator.lead_trail.lead_trail`); None without both wheelsets.

    An estimate's rows are the vehicle sides it has (``TimeIrregularity.sides``): a half model of a wheelset without
    its left vertical channel holds rail R in row 0. Pairing by rail (``orient.rail_of_side``), not by row,
    compares the same rail. ``span_m``: only the stretch of that length where the most of the estimates are
    valid (the channel check, :data:`ARRANGEMENT_CHECK_SPAN_M`), not the whole run.
    """
    chosen: dict[tuple[int, str], tuple[tuple[int, str], int]] = {}
    for w in (1, 2):
        for side in "LR":
            key = next((k for k in kinds or _WHEELBASE_KINDS if (w, k) in tis and side in tis[(w, k)].sides), None)
            if key is not None:
                chosen[(w, orient.rail_of_side[side])] = ((w, key), tis[(w, key)].sides.index(side))
    if not any(w == 1 for w, _ in chosen) or not any(w == 2 for w, _ in chosen):
        return None
    lam_lo = max(lam_min, WHEELBASE_PATCH_LENGTHS * 2 * fm.semi_axis_m)
    dx = max(lam_min / 2, 0.005)
    lo, hi = float(np.nanmin(track.chainage)), float(np.nanmax(track.chainage))
    t_of = _chainage_to_time(track, 0.0)  # the bogie's centre: wheelset 1 sees r(x + s a/2), wheelset 2 r(x - s a/2)
    keys = sorted({key for key, _ in chosen.values()})
    if span_m is not None and hi - lo > span_m:
        step = 0.5
        xc = np.arange(lo, hi, step)
        coarse = dict(zip(keys, sample_many([tis[k] for k in keys], t_of(xc))))
        ok = np.all([np.isfinite(coarse[key][row]) for key, row in chosen.values()], axis=0)
        m = int(span_m / step)
        filled = np.convolve(ok.astype(float), np.ones(m), mode="valid")
        lo = float(xc[int(np.argmax(filled))])
        hi = lo + span_m
    x = np.arange(lo, hi, dx)
    ts = t_of(x)
    sampled = dict(zip(keys, sample_many([tis[k] for k in keys], ts)))
    profiles = {wr: sampled[key][row] for wr, (key, row) in sorted(chosen.items())}
    return lead_trail(profiles, dx, lam_lo, orient.wheelset_offset_sign[1], WHEELBASE_RANGE_M)


def _check_arrangement(run: Run, fm: FieldModel, tis: Mapping, track: OdometryTrack, orient: Orientation,
                       lam_min: float) -> None:
    """Refuse a run whose two wheelsets' estimates contradict the sensor table (a channel of the wrong sign, sides
    or wheelsets swapped: :func:`estimator.lead_trail.arrangement_findings`): every estimate would be wrong, or
    on the wrong rail, and the lead/trail lag meaningless. Read on :data:`ARRANGEMENT_CHECK_SPAN_M` of the run,
    :data:`_CHECK_KINDS` first."""
    lt = _lead_trail(fm, tis, track, orient, lam_min, ARRANGEMENT_CHECK_SPAN_M, _CHECK_KINDS)
    if lt is None:
        return
    names = {}
    for w in (1, 2):
        chans = run.wheelset_channels(w)
        for side in "LR":
            z = chans[(chans["direction"] == "z") & (chans["side"] == side)]["name"]
            if len(z):
                names[(w, orient.rail_of_side[side])] = str(z.iloc[0])
    found = arrangement_findings(lt, names, direction=orient.direction, orientation=orient.orientation)
    if found:
        raise ChannelError(f"{run.source}: the two wheelsets' estimates contradict the sensor table: "
                           + "; ".join(found))


def _odometer_scale_from_wheelbase(fm: FieldModel, lt: LeadTrail | None, track: OdometryTrack,
                                   wheelbase_m: float) -> tuple[OdometryTrack, str]:
    """The track with the odometer's scale from the lead/trail lag over a known wheelbase, or the track as it is
    and why not.

    The two wheelsets see the same rail ``a`` apart; on a chainage that counts odometer metres (scale 1: fewer
    than two balises, :func:`estimator.spatial.odometry_track`) that lag reads ``a / s``, ``s`` the odometer's
    scale. With the drawing's ``a`` given, ``s = a / lag`` (on the virtual line 1/1.0045 against the truth's
    1/1.0041: 0.04 % over the run, where the uncorrected 0.41 % drifted 1 m in 240 m). A scale beyond
    ``max_scale_error`` is a wrong lag or a wrong drawing value, not wear: not applied.
    """
    rails = lt.rails if lt is not None else ()
    if not rails:
        return track, "no rail is estimated on both wheelsets, so the lead/trail lag cannot measure it"
    lag, contrast = lt.wheelbase()
    if lag is None or contrast < WHEELBASE_MIN_CORRELATION:
        return track, (f"the lead/trail lag cannot measure it (correlation {contrast:.2f} < "
                       f"{WHEELBASE_MIN_CORRELATION})")
    scale = wheelbase_m / lag
    if abs(scale - 1) > fm.config.max_scale_error:
        return track, (f"the lead/trail lag {lag:.4f} m over the given wheelbase {wheelbase_m:.3f} m implies a "
                       f"scale error of {100 * (scale - 1):+.2f} %, beyond +/-{100 * fm.config.max_scale_error:g} %: "
                       f"check the wheelbase")
    return rescaled(track, scale, f"the lead/trail lag {lag:.4f} m over the given wheelbase {wheelbase_m:.3f} m "
                                  f"(correlation {contrast:.2f}, rail(s) {', '.join(rails)})"), ""


def _grid(track: OdometryTrack, offset: float, dx: float) -> np.ndarray:
    c = track.chainage + offset
    lo, hi = float(np.nanmin(c)), float(np.nanmax(c))
    x0 = math.ceil(lo / dx) * dx
    return x0 + dx * np.arange(int(math.floor((hi - x0) / dx)) + 1)


def _stretches(fm: FieldModel, lo: float, hi: float) -> list[tuple[str, float, float]]:
    """Stretches for spectra and indexes: the line's sections and curves (or fixed lengths) inside [lo, hi]."""
    out = []
    if fm.line is not None:
        for s in fm.line.sections:
            if s.to_m > lo and s.from_m < hi:
                out.append((f"section {s.id}", max(s.from_m, lo), min(s.to_m, hi)))
        for c in fm.line.curves:
            if c.to_m > lo and c.from_m < hi:
                a, b = c.from_m + c.transition_in_m, c.to_m - c.transition_out_m
                out.append((f"curve {c.id}", max(a, lo), min(b, hi)))
    if not out:
        L = fm.config.section_length_m
        a = math.floor(lo / L) * L
        while a < hi:
            out.append((f"{a:g}-{a + L:g} m", max(a, lo), min(a + L, hi)))
            a += L
    return out


def _pinned_pinned(fm: FieldModel, lo: float, hi: float) -> list[float]:
    """Pinned-pinned frequencies [Hz] of the trackforms on chainage ``lo``..``hi`` (the default's where the line
    gives none there)."""
    key = ("pp", lo, hi)
    if key not in fm.cache:
        tfs = [t for a, b, t in fm.trackforms() if b > lo and a < hi] or [fm.default_trackform()]
        fm.cache[key] = sorted({pinned_pinned_frequency(t) for t in tfs})
    return fm.cache[key]


def _dead_channels(run: Run) -> list[str]:
    """Acceleration channels quality control masked everywhere: they carry nothing, and inverted together with a
    live channel (the half model's two sides, a wheelset's rows) they would mask it too."""
    if run.mask is None or run.mask.masked.shape[1] == 0:
        return []
    return [name for i, name in enumerate(run.names) if run.mask.masked[i].all()]


def _grouped(skipped: list[str], everyone: bool = False) -> str:
    """``"wheelset W, model: reason"`` lines as each reason once with whom it stopped (``everyone``: a reason
    shared by all is said so)."""
    by_reason: dict[str, list[str]] = {}
    for m in skipped:
        who, _, reason = m.partition(": ")
        by_reason.setdefault(reason, []).append(who.replace(", ", "/"))
    return "; ".join((f"all {len(who)} wheelset/model combinations" if everyone and len(by_reason) == 1 else
                      ", ".join(who)) + f": {reason}" for reason, who in by_reason.items())


def _nothing_estimated(run: Run, skipped: list[str]) -> NoValidDataError:
    """The error when no wheelset/model is left: each reason once with whom it stopped, and the quality-control
    findings that masked most of the run (what to look at first; the log lists each finding)."""
    why = _grouped(skipped, everyone=True) or "every sample masked"
    t = run.t
    hits: dict[str, np.ndarray] = {}
    for e in run.mask.events if run.mask is not None else ():
        if e.action == "masked" and np.isfinite(e.t_start):
            hits.setdefault(e.kind, np.zeros(t.size, bool))[(t >= e.t_start) & (t <= e.t_end)] = True
    cover = sorted(((float(h.mean()), kind) for kind, h in hits.items() if h.mean() >= 0.01), reverse=True)
    worst = ", ".join(f"{kind} {100 * share:.0f} %" for share, kind in cover[:4])
    return NoValidDataError(f"{run.source}: nothing could be estimated ({why}; masked share "
                            f"{100 * run.masked_share['run']:.0f} %" + (f", mostly by {worst} of the run" if worst
                                                                         else "") + "; each finding is logged)")


# --------------------------------------------------------------------------- the workflow
def _coupling_valid(run, idx_o: np.ndarray, w: int, wo: int, steps: list) -> np.ndarray:
    """Samples of wheelset ``wo``'s channels ``idx_o`` (per channel, rows in that order) its contact forces may
    be taken from for wheelset ``w``'s rail coupling: valid ones, and saturated ones up to
    ``MAX_COUPLING_SATURATED_SHARE`` of the run (stated and logged)."""
    strict = ~run.mask.masked[idx_o]
    loose = ~(run.mask.masked[idx_o] & ~run.mask.saturated[idx_o])  # Mask.coupling_valid, per channel
    # only samples a front end can hold at its full scale: never a corrupt one (NaN, or beyond what an axlebox
    # produces, estimator.qc.glitches), whatever mask a caller built
    acc_o = run.acceleration[idx_o]
    loose &= np.isfinite(acc_o) & ~glitches(acc_o) | strict
    extra = (loose & ~strict).any(axis=0)
    if not extra.any():
        return strict
    share = float(extra.mean())
    names = ", ".join(run.names[i] for i in sorted(set(idx_o.tolist())) if run.mask.saturated[i].any())
    if share > MAX_COUPLING_SATURATED_SHARE:
        msg = (f"wheelset {w}'s rail coupling leaves out wheelset {wo}'s clipped samples ({names}: "
               f"{100 * share:.1f} % of the run masked for clipping alone, more than "
               f"{100 * MAX_COUPLING_SATURATED_SHARE:g} %)")
        _say_once(run, steps, msg)
        return strict
    msg = (f"wheelset {w}'s rail coupling takes wheelset {wo}'s clipped samples as recorded ({names}: "
           f"{100 * share:.1f} % of the run masked for clipping alone, for wheelset {wo} itself): the clipped "
           f"excess enters wheelset {w}'s estimate through the coupling term only")
    _say_once(run, steps, msg)
    return loose


def _coupling_gaps(w: int, kind: str, wo: int, ko: str, classes, sides: tuple[str, ...],
                   sides_o: tuple[str, ...], orient: Orientation) -> list[str]:
    """What of wheelset ``wo``'s contact forces wheelset ``w``'s coupling term lacks with ``wo``'s model ``ko``.

    The term is ``C F'`` (:func:`estimator.inversion.rail_coupling`): ``F'`` one force per side of ``wo`` along
    its contact normal. A vertical or half model has no lateral channel and takes the normal as vertical: its
    force is the vertical one, and the share ``sin θ_s sin θ' α_y(a) F'`` of a contact angle ``θ_s`` of ``w``
    (vertical + lateral model in a curve) is unknown. A half model of a wheelset missing one side's vertical
    channel has no force on that side's rail: no coupling there.
    """
    out = []
    if kind == "vertical_lateral" and ko != "vertical_lateral":
        th = max(abs(math.degrees(a)) for _, pair, _ in classes for a in pair)
        if th > 0:
            out.append(f"{w}/{kind}'s rail coupling takes wheelset {wo}'s vertical contact forces from its {ko} model "
                       f"(no lateral channel on wheelset {wo}): the lateral component of wheelset {wo}'s forces is "
                       f"unknown and its share of the rail deflection under wheelset {w} (sin θ sin θ' times the "
                       f"rail's lateral transfer receptance, contact angles up to {th:.1f} deg here) is left out")
    for s in sides:
        if s not in sides_o:
            out.append(f"{w}/{kind}'s rail coupling has no force of wheelset {wo} on rail {orient.rail_of_side[s]} "
                       f"(its {ko} model has no vertical channel on side {s}): no coupling on that rail")
    return out


def _why_no_rails(run: Run, wheelsets: list[int], skipped: list[str]) -> str:
    """Why wheelsets have no estimate: their channels quality control masked over most of the run (with the
    findings' kinds) and their models' skip reasons; '' when there is nothing to say."""
    share = run.masked_share
    parts = []
    for w in wheelsets:
        for name in run.wheelset_channels(w)["name"]:
            if share.get(name, 0.0) >= 0.5:
                kinds = sorted({e.kind for e in run.mask.events if e.channel == name}) if run.mask else []
                parts.append(f"{name} masked over {share[name]:.0%} of the run ({', '.join(kinds) or 'masked'})")
        mine = _grouped([m for m in skipped if m.startswith(f"wheelset {w},")])
        parts += [mine] if mine else []
    return f" because {'; '.join(parts)}" if parts else ""


def _outside_trackforms(fm: FieldModel, chains: dict[int, np.ndarray]) -> list[str]:
    """The stretches a run passes that none of the line's trackform sections holds (the default trackform is used
    there, and a user who described the line's track should know where it does not apply)."""
    sections = fm.trackforms()
    if fm.trackform is not None or not sections:
        return []
    from estimator.qc import runs_of

    out = []
    for w, x in chains.items():
        inside = np.zeros(x.size, bool)
        for a, b, _ in sections:
            inside |= (x >= a) & (x <= b)
        spans = [(float(np.min(x[i:j])), float(np.max(x[i:j]))) for i, j in runs_of(~inside & np.isfinite(x))]
        if spans:
            where = ", ".join(f"{lo:.1f}-{hi:.1f} m" for lo, hi in spans[:5]) + (" ..." if len(spans) > 5 else "")
            out.append(f"wheelset {w} passes chainage {where}, which no trackform section of the line holds (they "
                       f"cover {', '.join(f'{a:g}-{b:g} m' for a, b, _ in sections[:6])}): receptance's default "
                       "trackform (Trackform()) is used there")
    return out


def _estimated_sides(run, steps: list, ti: TimeIrregularity) -> TimeIrregularity:
    """``ti`` without the sides it has no valid stretch of, said (:meth:`TimeIrregularity.estimated_sides`)."""
    out = ti.estimated_sides()
    gone = [s for s in ti.sides if s not in out.sides]
    if gone:
        _say_once(run, steps, f"wheelset {ti.wheelset}, {ti.kind}: vehicle side(s) {', '.join(gone)} not estimated "
                              f"(the channels they read have no valid stretch long enough); the other side is")
    return out


def _contact_loss(run: Run, fm: FieldModel, plans: list, kind: str, edge_s: float, chainage: np.ndarray,
                  orient: Orientation) -> list:
    """Where wheelset ``plans``' estimated dynamic contact force (its model ``kind``) lifts the wheel off the rail
    (:mod:`estimator.contact_load`)."""
    _, sub, classes, transfers = next(p for p in plans if p[0] == kind)
    idx = sub["row"].to_numpy(int)
    force = contact_force(run.acceleration[idx], run.t0, run.fs, ~run.mask.masked[idx], transfers,
                          [c[2] for c in classes], edge_s=edge_s)
    vertical = sub[sub["direction"] == "z"]
    return contact_loss_events(force, run.t, chainage, fm.config.contact.wheel_load_N, orient.rail_of_side,
                               dict(zip(vertical["side"], vertical["name"])))


def _say_once(run, steps: list, msg: str) -> None:
    """A finding stated once per run however many models meet it."""
    if msg not in steps:
        steps.append(msg)
        log.warning("%s: %s", run.source, msg)


def estimate_run(run, field_model: FieldModel, *, direction: str | None = None, format: str | None = None,
                 indexes_only: bool = False) -> FieldEstimate:
    """Estimate rail roughness per rail from one run (module docstring).

    Parameters
    ----------
    run : Run or str or Path
        A run (sensitivities applied) or a run file read with the field model's sensor table.
    field_model : FieldModel
        From :func:`prepare`.
    direction : {"forward", "backward"}, optional
        Override the header's direction of travel.
    format : str, optional
        Run-file format when ``run`` is a path.
    indexes_only : bool
        The profiles and their band indexes only, for another estimate of accelerations already estimated
        (the monitoring's uncertainty variants, :mod:`estimator.monitoring.variants`): the channels are not
        checked against the sensor table again (the same accelerations' first estimate did it), and the
        stretch tables (``indexes``, ``spectra``, ``corrugation``) are left empty. The profiles are those of the
        full estimate, to the bit.

    Returns
    -------
    FieldEstimate

    Raises
    ------
    RunFileError, ChannelError, OdometryError, NoValidDataError, ConfigurationError
    """
    fm = field_model
    cfg = fm.config
    timings: dict[str, float] = {}
    t_start = time.perf_counter()
    if not isinstance(run, Run):
        run = read_run(run, fm.sensors, format, direction=direction)
    elif direction is not None:
        run = run.with_direction(direction)
    if not run.sensitivity_applied:
        run = run.apply_sensitivities()
    if fm.line is not None and run.odometry.chainage_relative:
        # the line's curves (contact angles), trackforms and sections would be laid on the wrong stretch, silently
        raise ConfigurationError(
            f"{run.source}: the run's chainage counts from its start (position {run.odometry.names['position']}, "
            f"no balise passage), so it cannot be placed on line {fm.line.source or fm.line.name!r}: record the "
            "position or balise channel, or estimate without the line")
    orient = orientation(run.header.direction, run.header.orientation)
    track = odometry_track(run.odometry, orient.travel_sign, max_scale_error=cfg.max_scale_error, source=run.source)
    run = check_run(run, track, cfg)
    timings["read_qc"] = time.perf_counter() - t_start
    fs = run.fs
    f_lo, f_hi = cfg.f_lo_hz, cfg.f_hi(fs)
    # the shortest wavelength this run resolves: its slowest speed where any channel is kept (never below the
    # speed gate); a run without a slow stretch gets a coarser grid and costs less
    t_run = run.t
    kept = ~run.mask.masked.all(axis=0)
    v_kept = np.abs(track.speed_at(t_run)[kept])
    v_slow = max(cfg.speed_gate_m_s, float(v_kept.min())) if v_kept.size else cfg.speed_gate_m_s
    dx_target, lam_min = spatial_step(v_slow, f_hi)
    if ("basis", f_hi) not in fm.cache:  # once per model and band: the note, and the warning when it is short
        basis, short = modal_basis(fm.model, f_hi)
        if short:
            log.warning("%s", basis)
        fm.cache[("basis", f_hi)] = basis
    steps = [*fm.provenance, fm.cache[("basis", f_hi)],
             f"orientation: {orient.direction}/{orient.orientation}, leading wheelset {orient.leading}, vehicle "
             f"L on rail {orient.rail_of_side['L']}",
             f"chainage from the odometer: {len(track.resets)} balise reset(s) corrected, "
             f"{len(track.untrusted)} stretch(es) not trusted"]
    wb_guess = cfg.wheelbase_m or 2.5
    # ---- inversion per wheelset and model
    t0 = time.perf_counter()
    tis: dict[tuple[int, str], TimeIrregularity] = {}
    conditioning: dict[tuple[int, str], pd.DataFrame] = {}
    skipped: list[str] = []
    plans_by_w: dict[int, list] = {}
    edges: dict[int, float] = {}
    chains: dict[int, np.ndarray] = {}  # each wheelset's chainage per sample (its transfer classes, and coupling's)
    dead = _dead_channels(run)
    if dead:
        _say_once(run, steps, f"channel(s) {', '.join(dead)} masked over the whole run: left out of every model "
                              "(a model that needs them is not estimated; the other channels' models are)")
    for w in run.wheelsets:
        chans = run.wheelset_channels(w)
        gone = [n for n in chans["name"] if n in dead]
        chans = chans[~chans["name"].isin(dead)].reset_index(drop=True)
        chain_w = chains[w] = track.chainage_at(t_run) + orient.wheelset_offset_sign[w] * wb_guess / 2
        plans = []
        for kind in cfg.models:
            try:
                rows, _ = model_channels(kind, chans)
            except ChannelError as exc:
                why = f"{exc}" + (f" ({', '.join(gone)} masked over the whole run)" if gone else "")
                skipped.append(f"wheelset {w}, {kind}: {why}")
                log.warning("%s: wheelset %d, model %s not estimated: %s", run.source, w, kind, why)
                continue
            sub = chans.loc[rows].reset_index(drop=True)
            classes = _class_weights(fm, kind, chain_w, orient, orient.role(w))
            transfers = [fm.transfer(kind, sub.drop(columns="row"), fs, t, th) for t, th, _ in classes]
            plans.append((kind, sub, classes, transfers))
        # one edge per wheelset: its models then share their valid stretches (and one time -> space interpolation)
        edge_w = max((tr.edge_s for *_, trs in plans for tr in trs), default=0.0)
        plans_by_w[w], edges[w] = plans, edge_w
    for msg in _outside_trackforms(fm, chains):
        _say_once(run, steps, msg)
    kinds_of = {w: {kind for kind, *_ in plans} for w, plans in plans_by_w.items()}
    coupling = cfg.bogie_coupling and len(plans_by_w) == 2
    # fewer than two balises leave the odometer's scale unmeasured; with the wheelbase given (a drawing value) the
    # lead/trail lag in odometer metres measures it (below), from the uncoupled estimates of both wheelsets
    scale_from_wb = cfg.wheelbase_m is not None and track.scale_source == "odometer" and all(kinds_of.values()) \
        and len(kinds_of) == 2
    # with a given wheelbase the uncoupled pass would only be thrown away: a coupled pair is inverted once, below
    # (every model of a wheelset whose partner has any model: the coupling takes the partner's forces from it)
    defer = coupling and cfg.wheelbase_m is not None and not scale_from_wb and all(kinds_of.values())
    for w, plans in plans_by_w.items():
        for kind, sub, classes, transfers in plans:
            conds = []
            for (t, th, _), tr in zip(classes, transfers):
                conds.append(condition_by_band(tr).assign(trackform=t, theta_L_deg=math.degrees(th[0]),
                                                          theta_R_deg=math.degrees(th[1])))
            conditioning[(w, kind)] = pd.concat(conds, ignore_index=True)
            if defer:
                continue
            idx = sub["row"].to_numpy(int)
            valid = ~run.mask.masked[idx]  # per channel: a half model's side needs its own only
            ti = invert(run.acceleration[idx], run.t0, fs, valid, transfers, [c[2] for c in classes],
                        edge_s=edges[w])
            if ti.valid_time <= 0:
                skipped.append(f"wheelset {w}, {kind}: no valid stretch long enough after quality control")
                continue
            tis[(w, kind)] = _estimated_sides(run, steps, ti)
    if not tis and not defer:
        raise _nothing_estimated(run, skipped)
    timings["inversion"] = time.perf_counter() - t0
    steps.append(f"inverted {len(tis)} wheelset/model combination(s) in {f_lo:g}-{f_hi:g} Hz "
                 f"(Tikhonov alpha {cfg.regularisation:g})")
    # ---- wheelbase
    t0 = time.perf_counter()
    scale_why = "give the wheelbase (wheelbase_m / --wheelbase) for the lead/trail lag to measure it"
    if not defer and not indexes_only:
        # the channels against the sensor table first: a channel of the wrong sign or on the wrong side would
        # otherwise surface as an unmeasurable wheelbase (a deferred pair is checked once coupled, below)
        _check_arrangement(run, fm, tis, track, orient, lam_min)
    if cfg.wheelbase_m is not None:
        wb, wb_src = cfg.wheelbase_m, "given"
        if scale_from_wb:
            lt = _lead_trail(fm, tis, track, orient, lam_min)
            track, scale_why = _odometer_scale_from_wheelbase(fm, lt, track, wb)
            if track.scale_source != "odometer":
                # the QC table and every chainage below carry the corrected scale
                fixed = tuple(e for e in track.events if e.kind == "odometry_scale")
                run = run.with_mask(replace(run.mask, events=tuple(e for e in run.mask.events
                                                                   if e.kind != "odometry_scale") + fixed),
                                    f"chainage: {fixed[0].reason}")
                log.info("%s: %s", run.source, fixed[0].reason)
    else:
        lt = _lead_trail(fm, tis, track, orient, lam_min)
        est, contrast = lt.wheelbase() if lt is not None else (None, 0.0)
        rails = lt.rails if lt is not None else ()
        if len(run.wheelsets) > 1 and not rails:
            have = "; ".join(f"wheelset {w}: rail(s) " + (", ".join(sorted({orient.rail_of_side[s] for (ww, _), ti
                                                                          in tis.items() if ww == w
                                                                          for s in ti.sides})) or "none")
                             for w in run.wheelsets)
            why = _why_no_rails(run, [w for w in run.wheelsets if not any(ww == w for ww, _ in tis)], skipped)
            raise WheelbaseError(f"{run.source}: no rail instrumented on both wheelsets ({have}){why}: the "
                                 f"lead/trail lag cannot be measured; give --wheelbase (wheelbase_m)")
        if est is None or contrast < WHEELBASE_MIN_CORRELATION:
            if len(run.wheelsets) > 1:
                raise WheelbaseError(
                    f"{run.source}: the wheelbase could not be measured from the data (lead/trail correlation "
                    f"{contrast:.2f} < {WHEELBASE_MIN_CORRELATION} on rail(s) {', '.join(rails)}); give it "
                    f"(wheelbase_m / --wheelbase)")
            raise WheelbaseError(f"{run.source}: one instrumented wheelset: give the wheelbase (wheelbase_m / "
                                     "--wheelbase) to place it along chainage")
        wb, wb_src = est, f"measured (lead/trail cross-correlation {contrast:.2f})"
        scale_why = ("the wheelbase is measured, in odometer metres, from the same lag: give the drawing's "
                     "(wheelbase_m / --wheelbase) for the lag to measure the scale")
    steps.append(f"wheelbase {wb:.3f} m ({wb_src})")
    if track.scale_source == "odometer":
        uncorrected = next(e for e in track.events if e.kind == "odometry_scale")
        _say_once(run, steps, f"chainage: {uncorrected.reason}; {scale_why}")
    timings["wheelbase"] = time.perf_counter() - t0
    # ---- the rail couples the bogie's two wheelsets: each inversion again with the other's contact forces
    if coupling:
        t0 = time.perf_counter()
        coupled, holes, alone_why, other_model = [], [], {}, []
        for w, wo in ((1, 2), (2, 1)):
            other = {kind: sub for kind, sub, _, _ in plans_by_w.get(wo, [])}
            # every model inverts the other wheelset's contact forces (B⁺_α a', WheelsetTransfer.P: one per vehicle
            # side along its contact normal), whichever of its channels it uses: the same model's when the other
            # wheelset has it (both then assume the same wheelset dynamics; on the virtual line's curve a pair of
            # different models reads ~1 dB higher in 30-100 mm), else its richest model with data
            sources = [k for k in _PRIMARY if k in other and ((wo, k) in tis or defer)]
            for kind, sub, classes, transfers in plans_by_w.get(w, []):
                idx = sub["row"].to_numpy(int)
                valid = ~run.mask.masked[idx]
                if not ((w, kind) in tis or defer):
                    continue  # no valid stretch of its own
                own_time = side_valid_time(valid, transfers, fs, max(edges.values()))
                for ko in sorted(sources, key=lambda k: k != kind):
                    cls, trs = classes, transfers
                    if ko == "vertical_lateral" and kind != "vertical_lateral":
                        # the other's normal forces depend on its contact angles: this wheelset's transfer (the same
                        # at every angle) is taken once per angle class of the other's
                        cls = _class_weights(fm, ko, chains[w], orient, orient.role(w))
                        trs = [fm.transfer(kind, sub.drop(columns="row"), fs, t, th) for t, th, _ in cls]
                    sub_o = other[ko]
                    # the other wheelset's forces along its own contact normals: its role's angles on the same class
                    # (a curve's calibrated angles differ between the leading and the trailing wheelset; the same
                    # classes in the same order, one wheelbase apart as the rest of the coupling)
                    cls_o = _class_weights(fm, ko, chains[w], orient, orient.role(wo)) if ko == "vertical_lateral" \
                        else cls
                    assert [c[0] for c in cls_o] == [c[0] for c in cls], "coupling classes out of step"
                    trs_o = [fm.transfer(ko, sub_o.drop(columns="row"), fs, t, th) for t, th, _ in cls_o]
                    # C[s, s'] couples the same rail only (rail_coupling): with θ' = 0 (a vertical or half model of the
                    # other) its vertical force alone enters, cos θ_s α_z(a) F'_z
                    cps = [fm.coupling(tr, tro, t, wb) for (t, _, _), tr, tro in zip(cls, trs, trs_o)]
                    idx_o = sub_o["row"].to_numpy(int)
                    valid_o = _coupling_valid(run, idx_o, w, wo, steps)
                    ti = invert(run.acceleration[idx], run.t0, fs, valid, trs, [c[2] for c in cls],
                                edge_s=max(edges.values()),
                                coupled=(run.acceleration[idx_o], valid_o, trs_o, cps))
                    kept = ti.valid_time_by_side
                    if ti.valid_time <= 0 or np.any((kept <= 0) & (own_time > 0)):
                        continue  # a side the coupling leaves nothing of: the model as a whole tries the next
                    tis[(w, kind)] = _estimated_sides(run, steps, ti)
                    coupled.append(f"{w}/{kind}")
                    if ko != kind:
                        other_model.append(f"{w}/{kind} from {wo}/{ko}")
                    # own samples the coupling costs a side (the other wheelset's channels it reads masked)
                    lost = float(np.max(np.count_nonzero(side_validity(valid, trs) & ~side_validity(
                        valid, trs, valid_o, trs_o, cps), axis=1))) / fs
                    if lost > 0:
                        holes.append(f"{w}/{kind} {lost:.1f} s")
                    for note in _coupling_gaps(w, kind, wo, ko, cls, trs[0].sides, trs_o[0].sides, orient):
                        _say_once(run, steps, note)
                    break
                else:
                    if not other:
                        alone_why[(w, kind)] = f"wheelset {wo} has no model estimated"
                    elif not sources:
                        alone_why[(w, kind)] = f"no model of wheelset {wo} has a valid stretch long enough"
                    else:
                        alone_why[(w, kind)] = "no stretch long enough valid on both wheelsets"
                    if defer:
                        # this wheelset alone, as without the coupling
                        ti = invert(run.acceleration[idx], run.t0, fs, valid, transfers, [c[2] for c in classes],
                                    edge_s=edges[w])
                        if ti.valid_time > 0:
                            tis[(w, kind)] = _estimated_sides(run, steps, ti)
                        else:
                            skipped.append(f"wheelset {w}, {kind}: no valid stretch long enough after quality "
                                           f"control")
        steps.append(f"rail coupling of the two wheelsets {wb:.3f} m apart (Timoshenko rail transfer receptance) "
                     f"added for {', '.join(coupled) or 'none'}" + (
                         f"; the other wheelset's contact forces from its same model, except "
                         f"{', '.join(other_model)}" if other_model else
                         "; the other wheelset's contact forces from its same model" if coupled else ""))
        if holes:
            _say_once(run, steps, f"coupled estimates leave out their own valid samples where the other wheelset's "
                                  f"channels are masked, each hole widened by the inverse filter's edges (the "
                                  f"coupling needs both; holes in the profile, no uncoupled patch; a half model's "
                                  f"side only where the other's channel on its rail is masked): "
                                  f"{', '.join(holes)}")
        for why in dict.fromkeys(alone_why.values()):
            alone = [f"{w}/{kind}" for (w, kind) in tis if alone_why.get((w, kind)) == why]
            if alone:
                _say_once(run, steps, f"{', '.join(alone)} inverted without the rail coupling ({why}): the other "
                                      f"wheelset's contact forces, which deflect the rail under it, are missing from "
                                      f"its estimate ({UNCOUPLED_EFFECT})")
        timings["coupling"] = time.perf_counter() - t0
        if not tis:
            raise _nothing_estimated(run, skipped)
    elif cfg.bogie_coupling:
        alone = ", ".join(f"{w}/{kind}" for (w, kind) in tis)
        _say_once(run, steps, f"{alone} inverted without the rail coupling (one instrumented wheelset): the bogie's "
                              f"other wheelset rolls on the same rails {wb:.3f} m away and its contact forces, which "
                              f"deflect the rail under this one, are not measured ({UNCOUPLED_EFFECT}); instrument "
                              f"both wheelsets for the coupled estimate")
    if defer and not indexes_only:  # inverted once, coupled: the channels checked on those estimates
        t0 = time.perf_counter()
        _check_arrangement(run, fm, tis, track, orient, lam_min)
        timings["wheelbase"] += time.perf_counter() - t0
    # ---- space, comb, indexes per wheelset
    t0 = time.perf_counter()
    profiles: dict[tuple[int, str], ProfileEstimate] = {}
    circ: dict[int, CircumferenceFit] = {}
    dx_used: dict[int, float] = {}
    bands = cfg.bands_mm
    windows = [cfg.window_m(b) for b in bands]
    # (a FieldModel built without prepare() may carry no radius yet: the model's, as prepare() would resolve it)
    r_nom = cfg.wheel_radius_m if cfg.wheel_radius_m is not None else with_wheel_radius(
        cfg, check_wheelset_geometry(fm.model)).wheel_radius_m
    c_nom = 2 * math.pi * r_nom * float(np.median(track.scale))
    spacing = sleeper_spacing(cfg, fm)
    sleeper_steps: list[str] = []
    lifted: list = []  # contact-loss findings (estimator.contact_load)
    t_contact = 0.0
    for w in sorted({w for w, _ in tis}):
        offset = orient.wheelset_offset_sign[w] * wb / 2
        t_of = _chainage_to_time(track, offset)
        primary = next(k for k in _PRIMARY if (w, k) in tis)
        if cfg.contact_loss_check:
            t1 = time.perf_counter()
            lifted += _contact_loss(run, fm, plans_by_w[w], primary, edges[w], track.chainage_at(t_run) + offset,
                                    orient)
            t_contact += time.perf_counter() - t1
        dx_c = nice_step(max(dx_target, CIRCUMFERENCE_STEP_M))  # orders up to ~500 need no finer grid
        x_nom = _grid(track, offset, dx_c)
        prof_nom = tis[(w, primary)].sample(t_of(x_nom))
        fit = circumference(prof_nom, dx_c, c_nom, search=cfg.radius_search)
        if not fit.found:
            lo, hi = (-cfg.radius_search, cfg.radius_search) if np.ndim(cfg.radius_search) == 0 else cfg.radius_search
            msg = (f"wheelset {w}: circumference not fitted, {fit.verdict}; searched {c_nom * (1 + lo):.4f}-"
                   f"{c_nom * (1 + hi):.4f} m around the nominal wheel radius {r_nom:.4f} m; the odometer's "
                   f"{c_nom:.4f} m is used for the wheel comb (a wrong one leaves the wheel's roughness in the rail "
                   f"estimate: give the measured radius, --wheel-radius)")
            # a weak wheel (no periodicity) is common and harmless; a refused strong peak means a wrong radius
            if fit.significance >= MIN_SIGNIFICANCE:
                _say_once(run, steps, msg)
            else:
                log.info("%s: %s", run.source, msg)
                steps.append(msg)
            fit = replace(fit, circumference_m=c_nom, nominal_m=c_nom)
        circ[w] = fit
        n_rev = int(math.ceil(fit.circumference_m / dx_target))
        dx = fit.circumference_m / n_rev
        dx_used[w] = dx
        x = _grid(track, offset, dx)
        tx = t_of(x)
        v = track.speed_at(np.where(np.isfinite(tx), tx, track.t[0]))
        v = np.where(np.isfinite(tx), v, np.nan)
        resolved = np.stack([(v <= b[0] * 1e-3 * f_hi) & (v >= b[1] * 1e-3 * f_lo) for b in bands])
        kinds = [k for k in cfg.models if (w, k) in tis]
        sampled = sample_many([tis[(w, k)] for k in kinds], tx)
        # one comb for every model of the wheelset (they share their mask, hence the comb's weights)
        rail_parts = np.split(comb(np.concatenate(sampled), n_rev, cfg.comb_revolutions)[0],
                              np.cumsum([len(s) for s in sampled])[:-1])
        for kind, irr_sides, rail_part in zip(kinds, sampled, rail_parts):
            ti = tis[(w, kind)]  # rows of irr_sides: vehicle sides of ti.sides
            rails = tuple(orient.rail_of_side[s] for s in ti.sides)
            wheel = wheel_roughness(irr_sides, n_rev, ti.sides, fit.circumference_m)
            passing = None
            if spacing is not None:
                rail_part, passing = sleeper_comb(rail_part, float(x[0]), dx, spacing, rails, bays=cfg.sleeper_bays,
                                                  expected_m=expected_sleeper_passing(fm, x, spacing))
                sleeper_steps.append(_sleeper_step(w, kind, passing))
            # one spectrum of the rail part serves the contact-filter correction and every EN band
            bad = ~np.isfinite(rail_part)
            nfft = sfft.next_fast_len(x.size + int(math.ceil(2 * max(b[1] for b in bands) * 1e-3 / dx)))
            # single precision is ample for filtering (relative 1e-7 against dB-level results) and halves the cost
            P = sfft.rfft(np.where(bad, 0.0, rail_part).astype(np.float32), nfft, axis=-1)
            if cfg.contact_filter:
                P *= contact_gain(sfft.rfftfreq(nfft, dx), fm.semi_axis_m).astype(np.float32)
            rail = sfft.irfft(P, nfft, axis=-1)[:, :x.size].astype(float)
            rail[bad] = np.nan
            idx = band_indexes(rail, dx, bands, windows, resolved[:, None, :], spectrum=(P, nfft))
            profiles[(w, kind)] = ProfileEstimate(w, orient.role(w), kind, rails, x, dx, irr_sides, rail, v, idx,
                                                  resolved, wheel, conditioning[(w, kind)], passing)
    timings["space_comb_indexes"] = time.perf_counter() - t0 - t_contact
    timings["contact_load"] = t_contact
    for e in lifted:
        log.warning("%s: %s", run.source, e.describe())
    if cfg.contact_loss_check:
        steps.append(f"contact: the estimated dynamic contact force against the static wheel load "
                     f"{cfg.contact.wheel_load_N / 1e3:.1f} kN: " + (
                         f"the wheel leaves the rail on {len(lifted)} stretch(es) (contact_loss findings)" if lifted
                         else "the wheels stay on the rails"))
    steps.append("time -> chainage at " + ", ".join(f"wheelset {w}: dx {1e3 * d:.2f} mm, circumference "
                                                     f"{circ[w].circumference_m:.4f} m" for w, d in dx_used.items())
                 + f"; nominal wheel radius {r_nom:.4f} m; shortest resolved wavelength {1e3 * lam_min:.1f} mm")
    steps += sleeper_steps or [_sleeper_off(cfg)]
    # ---- tables: indexes, spectra, corrugation
    t0 = time.perf_counter()
    all_x = np.concatenate([p.chainage_m for p in profiles.values()])
    stretches = _stretches(fm, float(np.nanmin(all_x)), float(np.nanmax(all_x)))
    index_rows, spec_rows, corr_rows = [], [], []
    resonances = fm.resonances()
    for (w, kind), p in ({} if indexes_only else profiles).items():
        for name, a, b in [("run", -math.inf, math.inf)] + stretches:
            i0, i1 = np.searchsorted(p.chainage_m, [a, b], side="left")
            sel = slice(int(i0), int(i1))
            if i1 <= i0:
                continue
            v_sel = np.abs(p.speed_m_s[sel])
            v_sel = v_sel[np.isfinite(v_sel) & (v_sel > 0)]
            v_range = np.array([v_sel.min(), v_sel.max()]) if v_sel.size else v_sel  # the cautions use the range only
            cautions = [band_cautions(band, v_range, (f_lo, f_hi), fm.semi_axis_m, _pinned_pinned(fm, a, b),
                                      contact_filter=cfg.contact_filter,
                                      discrete_supports=cfg.trackform_supports == "discrete") for band in bands]
            for i, rail in enumerate(p.rails):
                for bi, band in enumerate(bands):
                    # pk-pk is smooth over its window: statistics on the band's own (decimated) grid
                    d = p.indexes.decimation[bi] if p.indexes.decimation else 1
                    pk = p.indexes.pk_pk[bi, i, sel][::d]
                    ok = np.isfinite(pk)
                    index_rows.append({
                        "wheelset": w, "role": p.role, "model": kind, "stretch": name, "rail": rail,
                        "band_mm": f"{band[0]:g}-{band[1]:g}", "window_m": windows[bi],
                        "valid_share": float(ok.mean()) if ok.size else 0.0,
                        "median_pk_pk_um": float(np.median(pk[ok]) * 1e6) if ok.any() else math.nan,
                        "max_pk_pk_um": float(np.max(pk[ok]) * 1e6) if ok.any() else math.nan,
                        "threshold_um": cfg.thresholds_um[band],
                        "exceedance_pct": exceedance(pk, cfg.thresholds_um[band] * 1e-6),
                        "contact_correction_db": cautions[bi].contact_correction_db,
                        "contact_capped": cautions[bi].contact_capped,
                        "pinned_pinned_hz": cautions[bi].pinned_pinned_hz,
                        "caution": cautions[bi].text if ok.any() else ""})
                if name == "run":
                    continue
                vs = p.speed_m_s[sel]
                vs = vs[np.isfinite(vs) & np.isfinite(p.rail[i, sel])]  # noqa: PLW2901
                if vs.size == 0:
                    continue
                res = (float(vs.max()) / f_hi, float(vs.min()) / f_lo)
                spec = roughness_spectrum(p.rail[i, sel], p.dx, segment_m=cfg.en15610_segment_m, resolved_m=res)
                for r in spec.as_rows():
                    spec_rows.append({"wheelset": w, "role": p.role, "model": kind, "stretch": name, "rail": rail,
                                      "from_m": a, "to_m": b, "n_segments": spec.n_segments, **r})
                for bi, band in enumerate(bands):
                    if band not in ((30.0, 100.0), (100.0, 300.0)):
                        continue
                    d = p.indexes.decimation[bi] if p.indexes.decimation else 1
                    pk = p.indexes.pk_pk[bi, i, sel][::d]
                    ok = np.isfinite(pk)
                    if ok.sum() < 10 or np.median(pk[ok]) * 1e6 <= cfg.thresholds_um[band]:
                        continue
                    lam, prom = spectral_peak(p.rail[i, sel], p.dx, band)
                    v_med = float(np.median(vs))
                    f_c = v_med / lam if lam > 0 else math.nan
                    mech, nearest, f_near = classify(f_c, resonances)
                    if not prom >= MIN_PROMINENCE_DB:
                        mech = (f"broadband roughness above the threshold (no spectral peak {MIN_PROMINENCE_DB:g} dB "
                                "over the trend): no wavelength-fixing mechanism")
                    corr_rows.append({"wheelset": w, "role": p.role, "model": kind, "stretch": name, "rail": rail,
                                      "band_mm": f"{band[0]:g}-{band[1]:g}",
                                      "median_pk_pk_um": float(np.median(pk[ok]) * 1e6),
                                      "dominant_wavelength_mm": lam * 1e3, "peak_prominence_db": prom,
                                      "speed_m_s": v_med, "frequency_hz": f_c,
                                      "mechanism": mech, "nearest": nearest, "nearest_hz": f_near})
    res_table = pd.DataFrame([{"mechanism": n, "frequency_hz": f} for n, f in resonances.candidates()])
    timings["tables"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_start
    qc = run.mask.table()
    if lifted:
        qc = pd.concat([qc, pd.DataFrame([e.as_dict() for e in lifted], columns=qc.columns)], ignore_index=True)
    return FieldEstimate(
        run_id=run.run_id, source=run.source, header={**{k: getattr(run.header, k) for k in (
            "run_id", "date", "direction", "orientation", "train", "bogie", "line", "leading_end")},
            **run.header.extra},
        direction=orient.direction, orientation=orient.orientation, leading=orient.leading, fs=fs,
        duration_s=run.duration_s, masked_share=run.masked_share, qc=qc, odometry=pd.DataFrame(list(track.resets)),
        dx_m=dx_used, lambda_min_m=lam_min, band_hz=(f_lo, f_hi), wheelbase_m=float(wb), wheelbase_source=wb_src,
        circumference=circ, profiles=profiles, indexes=pd.DataFrame(index_rows), spectra=pd.DataFrame(spec_rows),
        corrugation=pd.DataFrame(corr_rows, columns=["wheelset", "role", "model", "stretch", "rail", "band_mm",
                                                     "median_pk_pk_um", "dominant_wavelength_mm",
                                                     "peak_prominence_db", "speed_m_s",
                                                     "frequency_hz", "mechanism", "nearest", "nearest_hz"]),
        resonances=res_table, skipped=tuple(skipped), processing=run.processing + tuple(steps),
        config=cfg.as_dict(), timings_s=timings, stretches=tuple(stretches))
