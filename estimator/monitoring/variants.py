"""Perturbed wheelset models and shifted accelerometers applied to the same accelerations (thesis §4.3.4–4.3.5).

**Transfer-function uncertainty (§4.3.4).** ``n_perturbed`` models (25 in
the thesis) are drawn as in the robustness study
(:func:`receptance.robustness.perturbation_factors`: every natural frequency
and damping ratio of the hybrid model times an independent uniform factor
within ``±perturbation``, 10 % in the thesis, one ``(n, n_modes, 2)`` draw
from ``numpy.random.default_rng(seed)``). The perturbation is applied to the
hybrid model's modal parameters — the quantities the modal test measured,
with their uncertainty — before its modifications (primary suspension,
effects) are solved, so a perturbed model is as physical as the nominal one.

**Accelerometer placement (§4.3.5).** Every accelerometer is moved by
``±s`` (``s`` in ``placement_shifts_mm``: 10, 30, 50 mm) along each axis of
``placement_axes`` (x along the track, y along the axle by default): one
variant per shift and axis, the receptances taken at the shifted points
(the point stays attached to its axlebox node and the node's rotations act
through the offset, :func:`receptance.dofs.shifted_point`'s model; here the
sensor table's mounting point moves, which :func:`estimator.inversion.sensor_model`
turns into that point).

**Wheel–rail contact (load and geometry).** The estimator's Hertz contact
(linearised stiffness ``k_H`` in the transfer functions, thesis eq. 2.5, and
the contact-patch semi-axis ``a`` of the contact filter it undoes) is computed
for one static wheel load and one pair of profile radii; in service both vary:
the wheel load with the passengers carried (a metro trailer car between tare
and crush load, ``±contact_load_range``, 25 % by default), the rail head's
transverse radius with wear and where on the head the wheel runs (curves: the
contact moves towards the gauge corner; ``contact_head_radius_m``, 0.2–0.5 m
by default around the 0.3 m of a new head). ``k_H ∝ (P R)^{1/3}``-type changes
of both the transfer functions and the contact filter follow from
:meth:`receptance.contact.ContactParameters.contact`. One variant per range
end (one at a time: a range is bounded, not a distribution).

**Track.** The estimator's track is the thesis's continuously supported
Timoshenko beam (Table 2.2 parameters, §2.4); a real track sits on discrete
supports and its pads and ballast stiffen with temperature and age and differ
from sleeper to sleeper. Variants: the receptance of the discretely supported
rail (midspan, :func:`receptance.track.track_frf` ``supports="discrete"``) in
place of the continuous one, and each of the pad and the ballast (subplate)
stiffness times and divided by ``track_stiffness_factor`` (2 by default: the
in-service spread of pad stiffness with temperature and ageing and of ballast
stiffness along a line is about a factor 2 either side, e.g. Thompson,
*Railway Noise and Vibration*, ch. 3 and 5); each layer's damping (loss
factor and viscous coefficient together) times and divided by
``track_damping_factor`` (2 by default: published pad loss factors run from
about 0.1 to 0.4, ibid.); and the layers' loss law itself. Eq. 2.32's constant
loss factor has no causal counterpart: a real elastomer's storage stiffness
rises with frequency (:func:`receptance.track.layer_dispersion`), and a
trackform's single stiffness holds only at the frequency it was characterised
at, which a trackform table rarely states (EN 13146-9 tests pads at low
frequency, a test rig on a track higher). One variant per frequency in
``track_loss_reference_hz`` (10 Hz and 1 kHz by default, the ends of the band
the estimator inverts) takes the causal law with the table's stiffness there.

Each variant is a :class:`~estimator.workflow.FieldModel` of its own whose
transfer functions are derived once and memoised, so all of a day's runs —
and a fleet worker's whole batch — share them; a run's accelerations (read
and checked once) go through every variant with the single-run estimator,
and the variants' band indexes are read on the nominal estimate's aligned
chainage windows.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from estimator.monitoring.config import MonitoringConfig
from estimator.monitoring.records import window_table

__all__ = ["Variant", "perturbed_variants", "placement_variants", "contact_variants", "track_variants",
           "variant_windows"]

log = logging.getLogger("estimator")


@dataclass(frozen=True, eq=False)
class Variant:
    """One perturbed or shifted field model: ``source`` is ``model`` or ``placement``."""

    source: str
    label: str
    field_model: object
    shift_m: tuple[str, float] | None = None  # (axis, metres) every accelerometer is moved by

    def applied_to(self, run):
        """The run as this variant sees it: its accelerometers' mounting points moved for a placement variant."""
        if self.shift_m is None:
            return run
        axis, d = self.shift_m
        ch = run.channels.copy()
        ch[axis] = ch[axis].astype(float) + d
        return run.with_step(f"accelerometers moved by {1e3 * d:+g} mm along {axis} (placement variant)", channels=ch)


def _variant_config(fm, cfg: MonitoringConfig):
    # a variant is read for its band levels only: its contact-loss check would cost as much as its own inversion
    return fm.config.replace(models=(cfg.model,), contact_loss_check=False)


def perturbed_variants(field_model, cfg: MonitoringConfig = MonitoringConfig()) -> list[Variant]:
    """The ``n_perturbed`` perturbed-model field models (module docstring)."""
    from receptance.robustness import perturbation_factors

    if cfg.n_perturbed == 0:
        return []
    m = field_model.model
    fw, fz = perturbation_factors(cfg.n_perturbed, len(m.freqs_hz), cfg.perturbation, cfg.perturbation_seed)
    out = []
    vc = _variant_config(field_model, cfg)
    for p in range(cfg.n_perturbed):
        z = np.minimum(m.zeta * fz[p], 0.999)
        mp = m.with_modal_parameters(m.freqs_hz * fw[p], z,
                                     step=f"perturbed model {p + 1}/{cfg.n_perturbed} (+/-{100 * cfg.perturbation:g} % "
                                          f"on f and zeta, seed {cfg.perturbation_seed})")
        out.append(Variant("model", f"model {p + 1:02d}", replace(field_model, model=mp, config=vc, cache={})))
    return out


def placement_variants(field_model, cfg: MonitoringConfig = MonitoringConfig()) -> list[Variant]:
    """One field model per accelerometer shift ``±s`` along each placement axis (module docstring)."""
    out = []
    vc = _variant_config(field_model, cfg)
    acc = field_model.sensors["quantity"] == "acceleration"
    for axis in cfg.placement_axes:
        for s in cfg.placement_shifts_mm:
            for sign in (+1, -1):
                table = field_model.sensors.copy()
                table.loc[acc, axis] = table.loc[acc, axis].astype(float) + sign * s * 1e-3
                # its own (empty) transfer cache: the memo is keyed by channel names, not mounting points
                out.append(Variant("placement", f"shift {axis} {sign * s:+g} mm",
                                   replace(field_model, sensors=table, config=vc, cache={}),
                                   (axis, sign * s * 1e-3)))
    return out


def contact_variants(field_model, cfg: MonitoringConfig = MonitoringConfig()) -> list[Variant]:
    """One field model per end of the wheel-load and rail-head-radius ranges (module docstring)."""
    base = field_model.config.contact
    vc = _variant_config(field_model, cfg)
    out = []
    ends = []
    if cfg.contact_load_range > 0:
        ends += [("wheel_load_N", base.wheel_load_N * (1 + sign * cfg.contact_load_range),
                  f"wheel load {100 * sign * cfg.contact_load_range:+g} %") for sign in (-1, 1)]
    ends += [("rail_head_radius", r, f"rail head radius {1e3 * r:g} mm") for r in cfg.contact_head_radius_m
             if abs(r - base.rail_head_radius) > 1e-9]
    for name, value, label in ends:
        params = replace(base, **{name: value})
        hc = params.contact()
        out.append(Variant("contact", label, replace(field_model, config=vc.replace(contact=params),
                                                     contact_stiffness=hc.stiffness, semi_axis_m=hc.semi_axis_x,
                                                     cache={})))
    return out


def _with_trackforms(field_model, change):
    """The field model with ``change(Trackform)`` applied to every trackform it uses (explicit, line's, default)."""
    if field_model.trackform is not None or field_model.line is None or not field_model.trackforms():
        return replace(field_model, trackform=change(field_model.default_trackform()), cache={})
    line = field_model.line
    tfs = tuple(replace(t, trackform=change(t.trackform)) if t.trackform is not None else t for t in line.trackforms)
    return replace(field_model, line=replace(line, trackforms=tfs), cache={})


def track_variants(field_model, cfg: MonitoringConfig = MonitoringConfig()) -> list[Variant]:
    """Discrete supports; pad and ballast stiffness and damping times/divided by their factors; the causal loss
    law with the stated stiffness at each of ``track_loss_reference_hz`` (module docstring)."""
    vc = _variant_config(field_model, cfg)
    out = []
    if cfg.track_discrete_supports and vc.trackform_supports != "discrete":
        out.append(Variant("track", "discrete supports (midspan)",
                           replace(field_model, config=vc.replace(trackform_supports="discrete"), cache={})))
    scaled = (("pad stiffness", cfg.track_stiffness_factor, ("pad_stiffness_z", "pad_stiffness_y")),
              ("ballast stiffness", cfg.track_stiffness_factor, ("subplate_stiffness_z", "subplate_stiffness_y")),
              ("pad damping", cfg.track_damping_factor, ("pad_loss_factor", "pad_damping_z", "pad_damping_y")),
              ("ballast damping", cfg.track_damping_factor,
               ("subplate_loss_factor", "subplate_damping_z", "subplate_damping_y")))
    for what, f, keys in scaled:
        if f <= 1:
            continue
        for k in (f, 1 / f):
            change = (lambda tf, keys=keys, k=k: replace(tf, **{n: getattr(tf, n) * k for n in keys}))
            fm = _with_trackforms(replace(field_model, config=vc), change)
            out.append(Variant("track", f"{what} x{k:.3g}", fm))
    for fr in cfg.track_loss_reference_hz:
        fm = _with_trackforms(replace(field_model, config=vc), lambda tf, fr=fr: replace(tf, loss_reference_hz=fr))
        out.append(Variant("track", f"causal layers, stated stiffness at {fr:g} Hz", fm))
    return out


def variant_windows(run, variants: list[Variant], alignments, cfg: MonitoringConfig, field_model=None
                    ) -> tuple[pd.DataFrame, list[str]]:
    """Every variant's band peak-to-peak per chainage window for one run (read once, estimated per variant).

    Parameters
    ----------
    run : estimator.run.Run
        The run as read (sensitivities applied).
    variants : list of Variant
    alignments : mapping wheelset → Alignment
        The nominal estimate's chainage corrections.
    cfg : MonitoringConfig
    field_model : FieldModel, optional
        The nominal model: with ``cfg.sensor_noise_rms_m_s2`` the noise floor is estimated with it too (source
        ``floor``, :mod:`estimator.monitoring.floor`).

    Returns
    -------
    windows, problems : DataFrame, list of str
        ``source, variant`` plus the columns of :func:`~estimator.monitoring.records.window_table`; the variants
        that could not be estimated and why.
    """
    from estimator.errors import EstimatorError
    from estimator.workflow import estimate_run

    frames, problems = [], []
    for v in variants:
        try:
            est = estimate_run(v.applied_to(run), v.field_model, indexes_only=True)
        except EstimatorError as exc:
            problems.append(f"{v.label}: {exc}")
            log.warning("%s: variant %s not estimated: %s", run.source, v.label, exc)
            continue
        w = window_table(est, cfg.model, alignments, cfg.window_m, lr_correlation=False)
        frames.append(w.assign(source=v.source, variant=v.label))
    if field_model is not None and cfg.sensor_noise_rms_m_s2 is not None:
        from estimator.monitoring.floor import FLOOR_SOURCE, noise_run

        label = f"sensor noise {cfg.sensor_noise_rms_m_s2:g} m/s^2"
        try:
            est = estimate_run(noise_run(run, cfg.sensor_noise_rms_m_s2), field_model, indexes_only=True)
            w = window_table(est, cfg.model, alignments, cfg.window_m, lr_correlation=False)
            frames.append(w.assign(source=FLOOR_SOURCE, variant=label))
        except EstimatorError as exc:
            problems.append(f"{label}: {exc}")
            log.warning("%s: noise floor not estimated: %s", run.source, exc)
    if not frames:
        return pd.DataFrame(), problems
    return pd.concat(frames, ignore_index=True), problems
