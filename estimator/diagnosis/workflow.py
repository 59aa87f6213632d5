"""A field diagnosis from run files and trolley references, as one library workflow (what the CLI calls).

:func:`run_field_diagnosis`:

1. prepares the estimator's :class:`~estimator.workflow.FieldModel` (the
   diagnosed transfer-function model only);
2. reads every run, estimates it (:func:`estimator.estimate_run`: the
   wheelbase and the profiles the comparison needs; with a previous
   calibration, ``start``, through it: the search adds effects on top of
   it) and pairs it with the trolley record of its day; a run with no
   same-day reference is named and left out;
3. aligns each trolley record to the train's chainage
   (:func:`estimator.monitoring.alignment.align_profiles`, the monitoring
   layer's two-pass piecewise fit, against the day's first run);
4. builds the evidence once (:mod:`estimator.diagnosis.evidence`): segments
   inside the site on the calibration day calibrate, every other segment
   (other stretches, other days) validates; with the estimator's
   ``bogie_coupling`` each segment holds both wheelsets' channels (the
   estimate of one depends on the other's through the rail), combed as the
   estimator combs that wheelset's estimate;
5. compares and localises (:mod:`estimator.diagnosis.compare`), fits and
   ranks the catalogue (:func:`~estimator.diagnosis.diagnose.diagnose_field`);
6. re-estimates every run with the calibrated model
   (:func:`~estimator.diagnosis.state.field_model_for`) and reports the
   EN 13231-3 band-index error before and after, on the calibration site
   and on the validation stretches;
7. checks every accelerometer against what the model predicts from its
   wheelset's other channels (:mod:`estimator.diagnosis.channels`) and names
   one that reads against it (a channel fault is outside the catalogue).
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
import pandas as pd

from estimator.config import EstimatorConfig
from estimator.diagnosis.channels import channel_check, inconsistent_channels
from estimator.diagnosis.compare import FieldComparison, compare_with_reference, index_errors
from estimator.diagnosis.config import DiagnosisConfig
from estimator.diagnosis.diagnose import FieldDiagnosis, anomalous_stretches, cell_masks, diagnose_field, noise_floor
from estimator.diagnosis.effects import catalogue
from estimator.diagnosis.errors import FieldDiagnosisError, ReferenceCoverageError
from estimator.diagnosis.evidence import Evidence, comb_channels, run_segments, segments_of, third_octave_bands
from estimator.diagnosis.model import Evaluator
from estimator.diagnosis.state import FieldState, field_model_for, run_for
from estimator.diagnosis.transfer import wheelset_blocks
from receptance.trackform import Trackform

__all__ = ["FieldDiagnosisResult", "run_field_diagnosis", "MAX_RUNS", "MAX_SITE_M"]

log = logging.getLogger("estimator")

#: bounds of one diagnosis (every run is estimated twice and held in memory)
MAX_RUNS = 200
MAX_SITE_M = 20_000.0


@dataclass(frozen=True, eq=False)
class FieldDiagnosisResult:
    """Everything a field diagnosis produced (the CLI writes it)."""

    diagnosis: FieldDiagnosis
    comparison: FieldComparison
    index_errors: pd.DataFrame
    state: FieldState
    site: tuple[float, float]
    calibration_date: str
    runs: pd.DataFrame
    rejected: tuple[str, ...]
    config: DiagnosisConfig
    estimator_config: EstimatorConfig
    timings_s: dict = field(default_factory=dict)
    #: channels reading against the model (:func:`~estimator.diagnosis.channels.inconsistent_channels`)
    channel_check: pd.DataFrame | None = None
    #: the calibration the search started from (``state`` holds it and what was accepted on top)
    start: FieldState = FieldState()


def _classes_of(fm, kind, orient, role):
    from estimator.workflow import transfer_classes

    line = fm.line

    def classes_of(chain: np.ndarray):
        cls = transfer_classes(fm, kind, chain, orient, role)
        full = [c for c in cls if np.min(c[2]) >= 0.999]
        if len(full) != 1:
            return None
        curve = None
        if line is not None:
            for c in line.curves:
                r = c.ramp(chain)
                if np.min(r) >= 0.999:
                    curve = c.id
                elif np.max(r) > 0:
                    return None
        return curve, full[0][1]

    return classes_of


def _base_trackform(fm):
    default = fm.default_trackform()

    def at(x: float) -> Trackform:
        if fm.trackform is not None or fm.line is None:
            return default
        return fm.line.trackform_at(x) or default

    return at


def _effect_stretches(diag, line, site) -> list[tuple[float, float]]:
    """Where the accepted effects act: a trackform change's stretch, a curve's body; the site otherwise."""
    from estimator.diagnosis.effects import ContactAngle, TrackformEffect

    out = []
    for c in diag.accepted:
        e = c.effect
        if isinstance(e, TrackformEffect):
            out.append(e.extent(c.params))
        elif isinstance(e, ContactAngle) and line is not None:
            cv = next((k for k in line.curves if k.id == e.curve), None)
            if cv is not None:
                out.append((cv.from_m + cv.transition_in_m, cv.to_m - cv.transition_out_m))
        else:
            out.append(tuple(site))
    return out


def run_field_diagnosis(runs: Sequence, references: Sequence, site: tuple[float, float], model, sensors, *,
                        line=None, trackform: Trackform | None = None, config: DiagnosisConfig | None = None,
                        estimator_config: EstimatorConfig | None = None, calibration_date: str | None = None,
                        direction: str | None = None, validation_stretches: Sequence = (),
                        start: FieldState | None = None) -> FieldDiagnosisResult:
    """Diagnose the estimator's model on a calibration site (module docstring).

    Parameters
    ----------
    runs : sequence of path or Run
    references : sequence of path
        Trolley files (``chainage_m, rail, roughness_um``), the survey date in the file name
        (``<YYYY-MM-DD>.csv``).
    site : (float, float)
        Calibration stretch [m] on the train's chainage.
    model, sensors, line, trackform : as :func:`estimator.prepare`
    calibration_date : str, optional
        The survey day whose runs calibrate (default: the first reference's day); other days validate.
    validation_stretches : sequence of (float, float)
        Stretches ``(from, to)`` [m] on which the EN 13231-3 band-index error of the other days is also
        reported (set ``validation stretch``), e.g. where a practitioner knows the track was re-laid.
    start : FieldState, optional
        A previous calibration of the same model (:func:`~estimator.diagnosis.calibration.calibration_for_model`,
        ``railmodal field diagnose --calibration``): the runs are estimated with it, the comparison and the
        ``nominal`` stage of every table are its, and the search adds effects on top of it (an effect of the
        same kind and place is fitted again). A line calibrated once for its everyday physics (the curves'
        contact angles, the track law) is diagnosed later for what changed since.

    Raises
    ------
    FieldDiagnosisError, ReferenceCoverageError
    """
    from estimator import check_run, estimate_run, prepare, read_run
    from estimator.monitoring.alignment import align_profiles, feature_profile
    from estimator.monitoring.reference import read_trolley_record
    from estimator.orientation import orientation
    from estimator.spatial import odometry_track

    cfg = config or DiagnosisConfig()
    ecfg = (estimator_config or EstimatorConfig()).replace(models=(cfg.model,))
    lo, hi = float(site[0]), float(site[1])
    if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
        raise FieldDiagnosisError(f"site must be FROM < TO in m, got {site!r}")
    if hi - lo > MAX_SITE_M or hi - lo < cfg.segment_m:
        raise FieldDiagnosisError(f"site {lo:g}-{hi:g} m must be between one segment ({cfg.segment_m:g} m) and "
                                  f"{MAX_SITE_M:g} m long")
    stretches = tuple((float(a), float(b)) for a, b in validation_stretches)
    bad = [st for st in stretches if not (math.isfinite(st[0]) and math.isfinite(st[1]) and st[1] > st[0])]
    if bad:
        raise FieldDiagnosisError(f"validation stretches must be FROM < TO in m, got {bad!r}")
    if not runs or len(runs) > MAX_RUNS:
        raise FieldDiagnosisError(f"give 1..{MAX_RUNS} runs, got {len(runs)}")
    if not references:
        raise ReferenceCoverageError("give at least one trolley reference")
    t_start = time.perf_counter()
    timings: dict = {}
    fm = prepare(model, sensors, line=line, trackform=trackform, config=ecfg)
    ecfg = fm.config  # the nominal wheel radius resolved from the model, carried into the Hertz contact
    start = start or FieldState()
    fm_start = field_model_for(fm, start)
    recs = {}
    for p in references:
        rec = read_trolley_record(p)
        if not rec.date:
            raise ReferenceCoverageError(f"{p}: the survey date must be in the file name (<YYYY-MM-DD>.csv)")
        if rec.date in recs:
            raise ReferenceCoverageError(f"{p}: a second reference for {rec.date} ({recs[rec.date].source})")
        recs[rec.date] = rec
    cal_date = calibration_date or sorted(recs)[0]
    if cal_date not in recs:
        raise ReferenceCoverageError(f"no reference on the calibration date {cal_date} (have {sorted(recs)})")
    # ---- runs: read, estimate, pair with their day's reference
    rejected: list[str] = []
    items = []
    for r in runs:
        run = read_run(r, fm.sensors, direction=direction) if not hasattr(r, "acceleration") else r
        if not run.sensitivity_applied:
            run = run.apply_sensitivities()
        if run.header.date not in recs:
            rejected.append(f"{run.source}: no reference on its day {run.header.date!r} (have {sorted(recs)}): "
                            "not used")
            log.warning(rejected[-1])
            continue
        est = estimate_run(run_for(run, start), fm_start)
        items.append((run, est))
    if not any(run.header.date == cal_date for run, _ in items):
        raise ReferenceCoverageError(f"no run on the calibration date {cal_date}")
    timings["estimate_nominal"] = time.perf_counter() - t_start
    # ---- align each reference to the day's first run
    t0 = time.perf_counter()
    aligned = {}
    for d, rec in recs.items():
        first = next((e for run, e in items if run.header.date == d), None)
        if first is None:
            rejected.append(f"{rec.source}: no run on {d}: reference not used")
            continue
        p = next(iter(first.profiles.values()))
        target = feature_profile(p.chainage_m, p.rail, p.rails, cfg.alignment.align_band_mm, f"run {first.run_id}")
        fp = feature_profile(rec.x, rec.values, rec.rails, cfg.alignment.align_band_mm, f"trolley {d}")
        stage = align_profiles(fp, target, cfg.alignment, target_name=f"run {first.run_id}")
        if not stage.accepted:
            raise ReferenceCoverageError(f"{rec.source}: cannot be aligned to the train's chainage ({stage.reason})")
        xa = rec.x + stage.fit.shift(rec.x)
        grid = np.arange(math.ceil(xa[0] / rec.dx) * rec.dx, xa[-1], rec.dx)
        aligned[d] = {rail: (grid, np.interp(grid, xa, rec.values[i], left=np.nan, right=np.nan))
                      for i, rail in enumerate(rec.rails)}
        log.info("%s aligned to run %s: residual %.1f mm", rec.source, first.run_id, stage.residual_mm)
    timings["align"] = time.perf_counter() - t0
    # ---- evidence, once
    t0 = time.perf_counter()
    band_table = third_octave_bands(cfg.shortest_m, cfg.longest_m)
    segs, cal, blocks, channels = [], [], {}, []
    runs_rows = []
    for run, est in items:
        orient = orientation(run.header.direction, run.header.orientation)
        track = odometry_track(run.odometry, orient.travel_sign, max_scale_error=ecfg.max_scale_error,
                               source=run.source)
        qrun = check_run(run, track, ecfg)
        ref = aligned.get(run.header.date)
        if ref is None:
            continue
        ref_lo = max(float(np.nanmin(x[np.isfinite(v)])) for x, v in ref.values())
        ref_hi = min(float(np.nanmax(x[np.isfinite(v)])) for x, v in ref.values())
        n_before = len(segs)
        for w in qrun.wheelsets:
            chans = qrun.wheelset_channels(w)
            if w not in blocks:
                blocks[w] = wheelset_blocks(fm.model, chans, cfg.model, qrun.fs, f_lo=ecfg.f_lo_hz,
                                            f_hi=ecfg.f_hi(qrun.fs), alpha=ecfg.regularisation, df=cfg.transfer_df_hz)
                names = set(blocks[w].channels)
                channels.append(chans[chans["name"].isin(names)])
        masked_acc = np.where(qrun.mask.masked, np.nan, qrun.acceleration) if qrun.mask is not None \
            else qrun.acceleration
        for w in qrun.wheelsets:
            # the estimator's bogie coupling: the other wheelset's channels enter this one's estimate
            others = [o for o in qrun.wheelsets if o != w]
            coupled = (others[0], float(est.wheelbase_m)) if ecfg.bogie_coupling and len(others) == 1 else None
            chain = track.chainage_at(qrun.t) + orient.wheelset_offset_sign[w] * est.wheelbase_m / 2
            # the estimator's comb removes this wheelset's wheel roughness from all it inverts (own and coupled)
            combed = comb_channels(masked_acc, chain, est.circumference[w].circumference_m, ecfg.comb_revolutions) \
                if w in est.circumference else None
            sleeper = est.profile(w, cfg.model).sleeper if (w, cfg.model) in est.profiles else None
            removed = sorted(set(sleeper.significant["order"])) if sleeper else []
            if removed:  # and its sleeper comb the sleeper-passing part, at the orders it removed
                combed = comb_channels(masked_acc if combed is None else combed, chain, sleeper.spacing_m,
                                       sleeper.bays, orders=removed)
            speed = np.abs(track.speed_at(qrun.t))
            c_lo, c_hi = float(np.nanmin(chain)), float(np.nanmax(chain))
            rails = tuple(orient.rail_of_side[s] for s in blocks[w].sides)
            got, rej = run_segments(qrun, w, cfg.model, chain, speed, orient.role(w), rails,
                                    segments_of(max(c_lo, ref_lo), min(c_hi, ref_hi), cfg.segment_m), ref, band_table,
                                    cfg, ecfg, _classes_of(fm, cfg.model, orient, orient.role(w)), coupled=coupled,
                                    acceleration=combed)
            segs += got
            rejected += rej
            cal += [run.header.date == cal_date and s.from_m >= lo - 1e-9 and s.to_m <= hi + 1e-9 for s in got]
        runs_rows.append({"run_id": run.run_id, "source": run.source, "date": run.header.date,
                          "direction": orient.direction, "segments": len(segs) - n_before,
                          "wheelbase_m": est.wheelbase_m})
    ev = Evidence(tuple(segs), band_table, np.array(cal, bool), (lo, hi), tuple(rejected))
    have = (min(s.from_m for s in segs), max(s.to_m for s in segs)) if segs else None
    if not ev.calibration.any():
        where = (f"; the segments of every day cover {have[0]:g}-{have[1]:g} m" if have else
                 "; no segment on any day")
        raise ReferenceCoverageError(f"no usable segment of {cfg.segment_m:g} m inside the site {lo:g}-{hi:g} m on "
                                     f"{cal_date}{where} ({len(rejected)} rejection(s): {'; '.join(rejected[:3])})")
    c_lo = min(s.from_m for s, c in zip(segs, cal) if c)
    c_hi = max(s.to_m for s, c in zip(segs, cal) if c)
    if c_lo > lo + cfg.segment_m or c_hi < hi - cfg.segment_m:
        log.warning("site %g-%g m: the runs and the reference of %s give segments on %g-%g m of it only; the "
                    "calibration rests on that", lo, hi, cal_date, c_lo, c_hi)
    for a, b in stretches:
        if have is None or b <= have[0] or a >= have[1]:
            log.warning("validation stretch %g-%g m lies outside every day's segments (%s): not evaluated", a, b,
                        f"{have[0]:g}-{have[1]:g} m" if have else "none")
    timings["evidence"] = time.perf_counter() - t0
    # ---- compare, diagnose
    t0 = time.perf_counter()
    evaluator = Evaluator(ev, blocks, _base_trackform(fm), ecfg.contact, contact_filter=ecfg.contact_filter)
    nominal = evaluator.errors(start)
    masks = cell_masks(ev, cfg.min_reference_snr_db)
    floor, *_ = noise_floor(ev, nominal, masks, evaluator.inversion_floor(start))
    hot = anomalous_stretches(ev, nominal, masks, floor, cfg.noise_margin)
    cands = catalogue(ev, fm.line, pd.concat(channels, ignore_index=True), names=cfg.effects,
                      min_section_m=cfg.min_section_m, stretches=hot)
    diag = diagnose_field(evaluator, cands, cfg, state=start)
    timings["diagnose"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    # ---- the band-index error before/after, through the estimator itself
    rows, cal_tables = [], []
    fm_cal = field_model_for(fm, diag.state)
    focus = _effect_stretches(diag, fm.line, (lo, hi))
    for run, est in items:
        ref = aligned.get(run.header.date)
        if ref is None:
            continue
        is_cal = run.header.date == cal_date
        nominal_t = index_errors(est, ref, (lo, hi), is_cal, ecfg, cfg.en_window_m, focus, stretches)
        if is_cal:
            cal_tables.append(nominal_t)
        rows.append(nominal_t.assign(stage="nominal", run_id=run.run_id, date=run.header.date))
        if diag.state == start:
            after_t = nominal_t
        else:
            after = estimate_run(run_for(run, diag.state), fm_cal)
            after_t = index_errors(after, ref, (lo, hi), is_cal, ecfg, cfg.en_window_m, focus, stretches)
        rows.append(after_t.assign(stage="calibrated", run_id=run.run_id, date=run.header.date))
    idx_err = pd.concat(rows, ignore_index=True) if rows else pd.DataFrame()
    comparison = compare_with_reference([e for run, e in items if run.header.date == cal_date], aligned, ev, nominal,
                                        diag, cfg, index_tables=cal_tables)
    # the verdict names local departures the segments' spectra are too coarse to single out (a few sleepers)
    an = comparison.anomalies
    if an is not None and len(an):
        spots = "; ".join(f"{r.from_m:g}-{r.to_m:g} m rail {r.rail} {r.band_mm} mm ({r.departure_db:+.1f} dB)"
                          for r in an.head(5).itertuples())
        diag = dataclasses.replace(diag, verdict=diag.verdict + f". Local departures from the reference in (nearly) "
                                   f"every run (nominal estimate, EN 13231-3 windows of {cfg.en_window_m:g} m): {spots}")
    # a channel reading against the model and its wheelset's other channels (outside the catalogue: named only)
    bad = inconsistent_channels(channel_check(evaluator, diag.state))
    if len(bad):
        spots = "; ".join(
            f"{r.channel} (wheelset {r.wheelset}, {r.from_m:g}-{r.to_m:g} m): median ρ {r.median_rho:+.2f} over "
            f"{r.n_segments} segments, {100 * r.share_negative:.0f} % negative"
            + (f"; reversing {r.reversal_explains} makes every channel of the wheelset agree (mounted the wrong way "
               "round or a wrong axis in the sensor table)" if r.reversal_explains else "") for r in bad.itertuples())
        diag = dataclasses.replace(diag, verdict=diag.verdict + ". Channel check (each accelerometer against what the "
                                   f"model predicts from its wheelset's other channels): {spots}")
    timings["compare"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_start
    return FieldDiagnosisResult(diag, comparison, idx_err, diag.state, (lo, hi), cal_date, pd.DataFrame(runs_rows),
                                tuple(rejected), cfg, ecfg, timings, bad, start)
