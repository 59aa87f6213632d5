"""Monitoring workflows: ingest runs into the store, update the days, and read a line's state back (thesis §4.3.3–4.3.6).

:func:`ingest` (``railmodal field ingest``)
    1. reads every run's header (date, run id) without its samples, and
       refuses — before any processing, as a failure of that run — a run
       whose id is stored under the same file name as another run of the
       batch or of the store (:func:`~estimator.monitoring.store.same_run`:
       run ids must be unique per line, or one run's rows would replace the
       other's);
    2. per survey day, its **reference run** (the first by run id whose
       estimate succeeds; or the reference already stored for that day and
       model) is estimated and aligned to the line's welds and crossings
       (absolute chainage, :func:`~estimator.monitoring.alignment.align_to_line`);
    3. every other run of the day is estimated (:func:`estimator.estimate_run`)
       and aligned to the day's reference (:func:`~estimator.monitoring.alignment.align_profiles`);
       runs that cannot be aligned are rejected with the reason (their QC
       row is kept, their band indexes are not averaged in). When most of a
       day's runs cannot be aligned to its reference, the reference is the
       odd one out (a run of another track, a bad recording): the first
       rejected run becomes the reference and the day is processed again
       (at most :data:`MAX_REFERENCE_RETRIES` times);
    4. ``uncertainty_runs`` runs of each day (the reference first, then the
       others by run id) also go through the perturbed and shifted-sensor
       models (:mod:`estimator.monitoring.variants`);
    5. runs whose own wheelbase measurement the single-run estimator refused are
       processed again with their bogie's wheelbase measured on its other runs
       of the batch and the store (:mod:`~estimator.monitoring.wheelbase`; the
       source is stated in the run's row);
    6. each run's rows are written to the store as soon as they are ready
       (:class:`~estimator.monitoring.store.MonitoringStore`: atomic,
       idempotent, safe with concurrent writers);
    7. the days touched are re-averaged with their intervals (:func:`update_days`; estimates far from their
       day's others left out, :mod:`~estimator.monitoring.outliers`; the noise floor subtracted,
       :mod:`~estimator.monitoring.floor`).

    Steps 2–5 are one task per run (:func:`process_run`), run by an executor
    (:mod:`estimator.fleet`: this process, or Dask).

:func:`update_days`
    Energy averages per day, rail, band and window and per section
    (:mod:`~estimator.monitoring.averaging`), with the run-to-run, model and
    placement intervals (:mod:`~estimator.monitoring.confidence`), written to
    the ``days`` and ``day_sections`` tables.

:func:`monitor` (``railmodal field monitor``)
    Reads one model version of a line (optionally a chainage range) back:
    day averages with intervals, consistency findings, grinding events and
    their effect, growth per section/rail/band and the threshold-crossing
    forecast, and — when the store holds several model versions — what
    changed between them. :func:`reprocess` re-ingests the archive with a new
    wheelset model (both versions stay side by side).
"""

from __future__ import annotations

import datetime as _dt
import logging
import math
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np
import pandas as pd

from estimator.config import EstimatorConfig
from estimator.errors import EstimatorError
from estimator.monitoring.alignment import (Alignment, FeatureProfile, align_profiles, align_to_line,
                                            feature_profile)
from estimator.monitoring.averaging import day_average, section_table
from estimator.monitoring.config import MonitoringConfig, band_label
from estimator.monitoring.confidence import variant_deltas, variant_spread, with_intervals, with_reference
from estimator.monitoring.consistency import consistency_checks
from estimator.monitoring.errors import MonitoringError, StoreError
from estimator.monitoring.grinding import detect_grinding, grinding_effect
from estimator.monitoring.floor import FLOOR_SOURCE, day_floor, with_floor
from estimator.monitoring.headers import read_header
from estimator.monitoring.outliers import outlying_estimates, without_outliers
from estimator.monitoring.records import RunInfo, Sections, config_hash, file_hash, spectra_rows, toolkit_version, \
    window_table
from estimator.monitoring.store import (RUN_TABLES, UNKNOWN_DATE, MonitoringStore, RunIdCollision, calendar_date,
                                        collision_message, safe_name, same_run)
from estimator.monitoring.trends import forecast, growth
from estimator.monitoring.variants import (contact_variants, perturbed_variants, placement_variants, track_variants,
                                           variant_windows)
from estimator.monitoring.wheelbase import BogieWheelbase, bogie_key, is_wheelbase_failure, known_wheelbases

__all__ = ["collect_runs", "IngestSpec", "DayReference", "RunResult", "IngestResult", "MonitorResult", "process_run", "ingest",
           "update_days", "monitor", "reprocess", "run_context"]

log = logging.getLogger("estimator")

MAX_RUNS_PER_BATCH = 100_000
#: times a day's reference is replaced when most of the day's runs cannot be aligned to it
MAX_REFERENCE_RETRIES = 2


# --------------------------------------------------------------------------- specification and context
@dataclass(frozen=True)
class IngestSpec:
    """Everything a task needs to process a run (small and picklable: paths and options).

    Parameters
    ----------
    model : str
        Hybrid wheelset model file (``hybrid_model.npz``); its SHA-256 is the model version.
    sensors : str
        Sensor table (``sensors.csv``).
    line : str, optional
        Line description (``line.json``): sections, curves, trackforms, balises, welds.
    estimator : EstimatorConfig
        Single-run options (``models`` is reduced to the monitored model).
    monitoring : MonitoringConfig
    direction : str, optional
        Override every run's direction of travel.
    line_id : str, optional
        The line's id in the store (default: ``line.json``'s id, else the runs' header ``line``).
    calibration : str, optional
        A field calibration of this model (``railmodal field diagnose``'s ``calibrated_model/`` folder or its
        ``field_calibration.json``): its accepted effects are applied, and the store's model version becomes
        ``<model hash>+cal<state hash>`` so that calibrated and nominal results stay apart.
    """

    model: str
    sensors: str
    line: str | None = None
    estimator: EstimatorConfig = field(default_factory=EstimatorConfig)
    monitoring: MonitoringConfig = field(default_factory=MonitoringConfig)
    direction: str | None = None
    line_id: str | None = None
    calibration: str | None = None

    def __post_init__(self) -> None:
        for name in ("model", "sensors") + (("line",) if self.line else ()):
            p = Path(getattr(self, name))
            if not p.is_file():
                raise FileNotFoundError(f"{name} file {p} does not exist")
            object.__setattr__(self, name, str(p.resolve()))
        if self.calibration is not None:
            p = Path(self.calibration)
            if not p.exists():
                raise FileNotFoundError(f"calibration {p} does not exist")
            object.__setattr__(self, "calibration", str(p.resolve()))
        # only the monitored model is estimated (the single-run report compares the three)
        object.__setattr__(self, "estimator", self.estimator.replace(models=(self.monitoring.model,)))

    def key(self) -> str:
        return config_hash({"model": self.model, "sensors": self.sensors, "line": self.line,
                            "estimator": self.estimator.as_dict(), "monitoring": self.monitoring.as_dict(),
                            "direction": self.direction, "line_id": self.line_id, "calibration": self.calibration})


@dataclass(frozen=True, eq=False)
class _Context:
    spec: IngestSpec
    field_model: object
    line: object
    sections: Sections
    info: RunInfo
    variants: dict = field(default_factory=dict)

    def uncertainty_variants(self) -> list:
        if "all" not in self.variants:
            cfg = self.spec.monitoring
            fm = self.field_model
            self.variants["all"] = (perturbed_variants(fm, cfg) + placement_variants(fm, cfg) + contact_variants(fm, cfg)
                                    + track_variants(fm, cfg))
        return self.variants["all"]


_CONTEXTS: dict[str, _Context] = {}


def run_context(spec: IngestSpec) -> _Context:
    """The field model, line and identity of a spec, built once per process (a worker's runs share them)."""
    key = spec.key()
    if key not in _CONTEXTS:
        from estimator.workflow import prepare

        fm = prepare(spec.model, spec.sensors, line=spec.line, config=spec.estimator)
        if spec.calibration is None:
            version = file_hash(spec.model)
        else:  # the calibration hashes the model file itself (its check and its version)
            from estimator.diagnosis import calibrated_field_model

            fm, version = calibrated_field_model(fm, spec.model, spec.calibration)
        line = fm.line
        info = RunInfo(line=spec.line_id or (line.id if line is not None and line.id else ""),
                       model_hash=version, model_file=Path(spec.model).name,
                       toolkit_version=toolkit_version(),
                       config_hash=config_hash(spec.estimator.as_dict(), spec.monitoring.as_dict()))
        if len(_CONTEXTS) > 8:
            _CONTEXTS.clear()
        _CONTEXTS[key] = _Context(spec, fm, line, Sections.of(line, spec.estimator.section_length_m), info)
    return _CONTEXTS[key]


# --------------------------------------------------------------------------- the day's reference
@dataclass(frozen=True, eq=False)
class DayReference:
    """A day's alignment reference: the reference run's feature signal on absolute chainage."""

    line: str
    date: str
    run_id: str
    profile: FeatureProfile
    note: str = ""

    def frame(self) -> pd.DataFrame:
        d = {"x_m": self.profile.x}
        for i, r in enumerate(self.profile.rails):
            d[r] = self.profile.values[i].astype(np.float32)
        return pd.DataFrame(d)

    def meta(self) -> dict:
        return {"run_id": self.run_id, "x0": self.profile.x0, "dx": self.profile.dx, "rails": list(self.profile.rails),
                "note": self.note}

    @staticmethod
    def from_store(line: str, date: str, frame: pd.DataFrame, meta: Mapping) -> "DayReference":
        rails = tuple(meta.get("rails", [c for c in frame.columns if c != "x_m"]))
        vals = np.stack([frame[r].to_numpy(float) for r in rails])
        return DayReference(line, date, str(meta.get("run_id", "")),
                            FeatureProfile(float(meta["x0"]), float(meta["dx"]), rails, vals, "reference"),
                            str(meta.get("note", "")))


# --------------------------------------------------------------------------- one run
@dataclass(frozen=True, eq=False)
class RunResult:
    """What one task returns: the run's tables (or its failure) and, for a reference run, the day's reference."""

    path: str
    run_id: str
    date: str
    line: str
    ok: bool
    error: str = ""
    tables: Mapping[str, pd.DataFrame] = field(default_factory=dict)
    reference: DayReference | None = None
    aligned: bool = False
    reason: str = ""
    timings_s: Mapping[str, float] = field(default_factory=dict)
    #: class name of the estimator error that failed the run ("" when it did not fail on one)
    error_type: str = ""


def _failure(path, header: Mapping, info: RunInfo, error: str, stage: str, line: str | None = None,
             error_type: str = "") -> RunResult:
    run_id = str(header.get("run_id") or Path(path).stem)
    date = str(header.get("date", ""))
    date = date if calendar_date(date) else "unknown"
    line = line or info.line or str(header.get("line") or "line")
    row = pd.DataFrame([{"run_id": run_id, "source": str(path), "stage": stage, "error": error, "section": "none",
                         "date": date, **_identity(info)}])
    return RunResult(str(path), run_id, date, line, False, error, {"failures": row}, error_type=error_type)


def _identity(info: RunInfo) -> dict:
    return {"model_hash": info.model_hash, "model_file": info.model_file, "toolkit_version": info.toolkit_version,
            "config_hash": info.config_hash}


def _run_identity(path, header, run_id: str | None = None, date: str | None = None) -> dict:
    """The run as the store identifies it (:data:`~estimator.monitoring.store.RUN_IDENTITY`), from its header
    (a dict, or the error that reading it raised) as :func:`_failure` and :func:`process_run` name it."""
    h = header if isinstance(header, Mapping) else {}
    d = str(h.get("date", "")) if date is None else date
    return {"run_id": run_id if run_id is not None else str(h.get("run_id") or Path(path).stem),
            "date": d if calendar_date(d) else UNKNOWN_DATE, "source": str(path),
            "train": str(h.get("train", "")), "bogie": str(h.get("bogie", ""))}


def _align(est, feats: dict[int, FeatureProfile], reference: DayReference | None, ctx: _Context,
           cfg: MonitoringConfig) -> tuple[dict[int, Alignment], DayReference | None, str]:
    """Alignments per wheelset; for a reference run (``reference`` None) also the day's reference."""
    balises = [c for _, c in ctx.line.balises] if ctx.line is not None else []
    run_id = est.run_id
    out: dict[int, Alignment] = {}
    if reference is not None:
        for w, fp in feats.items():
            st = align_profiles(fp, reference.profile, cfg, breakpoints=balises,
                                target_name=f"reference {reference.run_id}")
            out[w] = Alignment(run_id, w, (st,))
        return out, None, ""
    lead = est.leading if est.leading in feats else min(feats)
    note = ""
    st = align_to_line(feats[lead], ctx.line, cfg) if ctx.line is not None else None
    if st is None:
        out[lead] = Alignment(run_id, lead, ())
        note = "no weld or crossing of the line in the run: the reference keeps the odometer's (balise-pinned) chainage"
    elif not st.accepted:
        out[lead] = Alignment(run_id, lead, ())
        note = f"the line's features do not anchor the reference ({st.reason}): odometer chainage kept"
    else:
        out[lead] = Alignment(run_id, lead, (st,))
    if note:
        log.warning("%s: %s", run_id, note)
    fit = out[lead].stages[0].fit if out[lead].stages else None
    prof = feats[lead].shifted(fit) if fit is not None else feats[lead]
    ref = DayReference(ctx.info.line or str(est.header.get("line", "")), str(est.header.get("date", "")), run_id,
                       FeatureProfile(prof.x0, prof.dx, prof.rails, prof.values, "reference"), note)
    for w, fp in feats.items():
        if w == lead:
            continue
        st2 = align_profiles(fp, ref.profile, cfg, breakpoints=balises, target_name=f"reference {run_id} (leading)")
        out[w] = Alignment(run_id, w, (st2,))
    return out, ref, note


def _with_wheelbase(field_model, wheelbase_m: float):
    """The field model with the wheelbase given instead of measured; the memo of transfer functions is shared."""
    return replace(field_model, config=field_model.config.replace(wheelbase_m=wheelbase_m))


def process_run(path, spec: IngestSpec, reference: DayReference | None = None, *, uncertainty: bool = False,
                wheelbase: BogieWheelbase | None = None) -> RunResult:
    """Estimate, align and tabulate one run (one task of :func:`ingest`; module docstring).

    Parameters
    ----------
    path : str or Path
        Run file.
    spec : IngestSpec
    reference : DayReference, optional
        The day's reference; None makes this run the day's reference (aligned to the line's features).
    uncertainty : bool
        Also run the perturbed and shifted-sensor models on this run's accelerations.
    wheelbase : BogieWheelbase, optional
        The bogie's wheelbase known from its other runs (:mod:`~estimator.monitoring.wheelbase`): used instead of
        measuring it on this run (whose own measurement failed); its source goes into the run's row.

    Returns
    -------
    RunResult
        Never raises for a bad run: its failure (with the reason) is in the result.
    """
    from estimator.io import read_run
    from estimator.workflow import estimate_run

    t_start = time.perf_counter()
    ctx = run_context(spec)
    cfg = spec.monitoring
    header: dict = {}
    fm = ctx.field_model if wheelbase is None else _with_wheelbase(ctx.field_model, wheelbase.wheelbase_m)
    try:
        header = read_header(path)
        run = read_run(path, fm.sensors, direction=spec.direction)
        est = estimate_run(run, fm)
    except (EstimatorError, OSError) as exc:
        return _failure(path, header, ctx.info, str(exc), "estimate", error_type=type(exc).__name__)
    timings = {"estimate": time.perf_counter() - t_start}
    date = str(est.header.get("date", ""))
    if not calendar_date(date):
        return _failure(path, header, ctx.info, f"{path}: the run header's date must be a YYYY-MM-DD calendar date, "
                        f"got {date!r}", "header")
    if _dt.date.fromisoformat(date) > _dt.date.today() + _dt.timedelta(days=1):
        log.warning("%s: the run header's date %s is in the future: a logger clock not set? (stored as that survey "
                    "day)", path, date)
    line_id = ctx.info.line or str(est.header.get("line") or "line")
    if ctx.info.line and est.header.get("line") and str(est.header["line"]) != ctx.info.line:
        log.warning("%s: the run header says line %r, the line description %r: stored under %r", path,
                    str(est.header["line"]), ctx.info.line, ctx.info.line)
    info = replace(ctx.info, line=line_id)
    feats = {w: feature_profile(p.chainage_m, p.rail, p.rails, cfg.align_band_mm, f"{est.run_id} ws{w}")
             for (w, k), p in est.profiles.items() if k == cfg.model}
    if not feats:
        return _failure(path, header, info, f"{path}: the {cfg.model} model could not be estimated "
                                            f"({'; '.join(est.skipped) or 'no profile'})", "estimate")
    t0 = time.perf_counter()
    alignments, new_ref, note = _align(est, feats, reference, ctx, cfg)
    timings["align"] = time.perf_counter() - t0
    accepted = {w: a for w, a in alignments.items() if a.accepted}
    reasons = "; ".join(f"wheelset {w}: {a.reason}" for w, a in alignments.items() if not a.accepted)
    ident = _identity(info)
    mid = float(np.nanmedian(np.concatenate([p.chainage_m for p in est.profiles.values()])))
    mid_section = str(ctx.sections.at(np.array([mid]))[0])
    windows = window_table(est, cfg.model, accepted, cfg.window_m) if accepted else pd.DataFrame()
    if len(windows):
        windows = windows[windows["wheelset"].isin(list(accepted))]
        windows = windows.assign(run_id=est.run_id, direction=est.direction,
                                 section=ctx.sections.at(windows["window_m"].to_numpy(float) + 0.5 * cfg.window_m),
                                 date=date, **ident)
    # variants (transfer-function and placement uncertainty) on the same accelerations
    variants = pd.DataFrame()
    problems: list[str] = []
    if uncertainty and accepted:
        t0 = time.perf_counter()
        vs = ctx.uncertainty_variants()
        if wheelbase is not None:
            vs = [replace(v, field_model=_with_wheelbase(v.field_model, wheelbase.wheelbase_m)) for v in vs]
        # the noise floor with the run's own wheelbase (sensor noise alone has no lead/trail correlation to measure)
        variants, problems = variant_windows(run, vs, accepted, cfg,
                                             field_model=_with_wheelbase(fm, float(est.wheelbase_m)))
        if len(variants):
            variants = variants[variants["wheelset"].isin(list(accepted))]
            variants = variants.drop(columns=["speed_m_s", "lr_correlation", "role"]).assign(
                run_id=est.run_id, section=ctx.sections.at(variants["window_m"].to_numpy(float) + 0.5 * cfg.window_m),
                date=date, **ident)
        timings["variants"] = time.perf_counter() - t0
    spectra = spectra_rows(est, cfg.model, ctx.sections)
    if len(spectra):
        spectra = spectra[spectra["wheelset"].isin(list(accepted))] if accepted else spectra.iloc[:0]
        spectra = spectra.assign(run_id=est.run_id, direction=est.direction, date=date, **ident)
    al_rows = pd.concat([a.table() for a in alignments.values()], ignore_index=True)
    al_rows = al_rows.assign(section=mid_section, date=date, **ident)
    residual = {w: a.residual_mm for w, a in alignments.items()}
    # the run's QC row, once per section it covers
    secs = sorted(set(windows["section"])) if len(windows) else [mid_section]
    run_rows = []
    for sec in secs:
        ws = windows[windows["section"] == sec] if len(windows) else windows
        run_rows.append({
            "run_id": est.run_id, "source": str(path), "direction": est.direction, "train": str(est.header.get("train", "")),
            "bogie": str(est.header.get("bogie", "")), "leading": int(est.leading), "duration_s": float(est.duration_s),
            "masked_share": float(est.masked_share.get("run", math.nan)), "wheelbase_m": float(est.wheelbase_m),
            "wheelbase_source": wheelbase.source if wheelbase is not None else str(est.wheelbase_source),
            "speed_m_s": float(ws["speed_m_s"].mean()) if len(ws) else math.nan,
            "valid_share": float(ws["valid_share"].mean()) if len(ws) else 0.0,
            "aligned": bool(accepted) and len(accepted) == len(alignments),
            "wheelsets_used": ",".join(str(w) for w in sorted(accepted)),
            "alignment_residual_mm": float(np.nanmax([residual[w] for w in accepted])) if accepted and any(
                np.isfinite(residual[w]) for w in accepted) else math.nan,
            "rejected_reason": reasons, "reference_run": reference.run_id if reference is not None else est.run_id,
            "is_reference": reference is None, "reference_note": note, "uncertainty": bool(uncertainty and accepted),
            "variant_problems": "; ".join(problems), "section": sec, "date": date,
            "processed_at": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"), **ident})
    timings["total"] = time.perf_counter() - t_start
    tables = {"runs": pd.DataFrame(run_rows), "windows": windows, "variants": variants, "spectra": spectra,
              "alignment": al_rows}
    return RunResult(str(path), est.run_id, date, line_id, True, "", tables, new_ref, bool(accepted), reasons,
                     timings)


# --------------------------------------------------------------------------- the batch
#: file patterns a folder given as a run is searched for (recursively)
RUN_PATTERNS = ("*.mf4", "*.MF4", "*.mdf", "*.MDF", "*.tdms", "*.TDMS")


def collect_runs(items: Sequence, limit: int = MAX_RUNS_PER_BATCH) -> list[str]:
    """Run files from files and folders (a folder is searched recursively for MDF 4 and TDMS files), sorted, unique.

    Raises
    ------
    FileNotFoundError, MonitoringError
        A path that does not exist; no run file; more than ``limit``.
    """
    out: list[str] = []
    for it in items:
        p = Path(it)
        if p.is_dir():
            found = sorted({str(f) for pat in RUN_PATTERNS for f in p.rglob(pat) if f.is_file()})
            if not found:
                raise MonitoringError(f"folder {p} holds no MDF 4 or TDMS run file ({', '.join(RUN_PATTERNS)}); give "
                                      "Parquet or CSV runs as files")
            out += found
            # a folder also holds store files, trolley records and exports, so only its MDF 4 / TDMS files are runs;
            # say which tables were passed over, in case they were runs
            other = sorted(str(f.relative_to(p)) for pat in ("*.parquet", "*.csv") for f in p.rglob(pat)
                           if f.is_file())
            if other:
                log.warning("folder %s: %d Parquet/CSV file(s) not taken as runs (a folder gives its MDF 4 files; "
                            "give Parquet or CSV runs as files): %s%s", p, len(other), ", ".join(other[:5]),
                            ", ..." if len(other) > 5 else "")
        elif p.is_file():
            out.append(str(p))
        else:
            raise FileNotFoundError(f"run file or folder {p} does not exist")
        if len(out) > limit:
            raise MonitoringError(f"more than {limit} run files; ingest them in batches")
    seen: dict[Path, str] = {}
    for f in out:
        key = Path(f).resolve()
        if key in seen:
            log.warning("run file %s is given more than once (also as %s): ingested once", f, seen[key])
        else:
            seen[key] = f
    out = sorted(seen.values())
    if not out:
        raise MonitoringError("no run file given")
    return out


@dataclass(frozen=True, eq=False)
class IngestResult:
    """What :func:`ingest` did: runs written, rejected (with reasons) and failed, the model version, the days."""

    line: str
    model_hash: str
    runs: pd.DataFrame
    failures: pd.DataFrame
    dates: tuple[str, ...]
    executor: str
    timings_s: Mapping[str, float]

    @property
    def rejected(self) -> pd.DataFrame:
        r = self.runs
        return r[~r["aligned"]] if len(r) else r


def _as_result(res, path: str, ctx: _Context, line: str | None = None) -> RunResult:
    if isinstance(res, RunResult):
        return res
    if isinstance(res, tuple) and len(res) == 2 and res[0] == "error":
        return _failure(path, {}, ctx.info, f"{path}: {res[1]}", "task", line)
    return _failure(path, {}, ctx.info, f"{path}: unexpected task result {type(res).__name__}", "task", line)


def ingest(runs: Sequence, spec: IngestSpec, store, *, executor=None,
           progress: Callable[[int, int, str], None] | None = None, update: bool = True) -> IngestResult:
    """Process runs into the monitoring store (module docstring).

    Parameters
    ----------
    runs : sequence of str or Path
        Run files (any format of :func:`estimator.read_run`), any number of days.
    spec : IngestSpec
    store : MonitoringStore or str or Path
    executor : LocalExecutor or DaskExecutor, optional
        Where the tasks run (default: this process).
    progress : callable(done, total, message), optional
        Called after every run.
    update : bool
        Re-average the days touched (:func:`update_days`) at the end.

    Returns
    -------
    IngestResult
    """
    from estimator.fleet import LocalExecutor

    t_start = time.perf_counter()
    st = store if isinstance(store, MonitoringStore) else MonitoringStore(store)
    st.verify()  # a file the store did not write is refused before any work reads or adds to it
    paths = [str(Path(p)) for p in runs]
    if not paths:
        raise MonitoringError("no run file to ingest")
    if len(paths) > MAX_RUNS_PER_BATCH:
        raise MonitoringError(f"{len(paths)} run files in one batch; at most {MAX_RUNS_PER_BATCH}")
    if len(set(paths)) != len(paths):
        dup = sorted({p for p in paths if paths.count(p) > 1})
        raise MonitoringError(f"run file(s) given twice: {dup[:5]}")
    ctx = run_context(spec)
    ex = executor or LocalExecutor()
    say = progress or (lambda done, total, msg: log.info("[%d/%d] %s", done, total, msg))
    total = len(paths)
    done = 0
    latest: dict[str, RunResult] = {}
    headers: dict[str, dict | str] = {}

    def refusal(r: RunResult, message: str) -> RunResult:
        # the refused run's failure row is reported, not stored: under its file name it would replace the rows
        # of the run that holds the name
        if not r.ok and r.error:
            message = f"{message} (the run also failed: {r.error})"
        log.warning("%s", message)
        h = headers.get(r.path)
        return _failure(r.path, h if isinstance(h, Mapping) else {}, ctx.info, message, "run_id", r.line,
                        error_type=RunIdCollision.__name__)

    def record(r: RunResult, refused: str = "") -> RunResult:
        """Write a task's result (or report its refusal, ``refused``); the result as recorded."""
        nonlocal done, total
        done += 1
        total = max(total, done)
        if refused:
            r = refusal(r, refused)
        else:
            try:
                st.write(r.line, r.run_id, ctx.info.model_hash, r.tables, replace_tables=RUN_TABLES,
                         run=_run_identity(r.path, headers.get(r.path), r.run_id, r.date))
            except RunIdCollision as exc:  # another ingest stored a different run under this name meanwhile
                r = refusal(r, str(exc))
        latest[r.path] = r
        if not r.ok and is_wheelbase_failure(r.error_type):
            # step 4 below processes it again with the wheelbase its bogie's other runs measure
            say(done, total, f"{r.run_id}: wheelbase not measured on this run; deferred until its bogie's other "
                             "runs give it")
        elif not r.ok:
            say(done, total, f"{r.run_id}: FAILED ({r.error})")
        elif not r.aligned:
            say(done, total, f"{r.run_id}: rejected ({r.reason})")
        else:
            say(done, total, f"{r.run_id} ({r.date}) done in {r.timings_s.get('total', math.nan):.1f} s")
        return r

    # 1. headers: group by day; the batch's line (for runs whose header cannot be read)
    for p in paths:
        try:
            headers[p] = read_header(p)
        except (EstimatorError, OSError) as exc:
            headers[p] = str(exc)
    named = [str(h.get("line")) for h in headers.values() if isinstance(h, dict) and h.get("line")]
    batch_line = ctx.info.line or (max(sorted(set(named)), key=named.count) if named else "line")
    refused = _run_id_collisions(paths, headers, st, ctx.info.line, batch_line)
    by_date: dict[str, list[tuple[str, str]]] = {}
    for p, h in headers.items():
        d = str(h.get("date", "")) if isinstance(h, dict) else ""
        if not isinstance(h, dict):
            r = _failure(p, {}, ctx.info, h, "header", batch_line)
        elif not calendar_date(d):
            r = _failure(p, h, ctx.info, f"{p}: the run header's date must be a YYYY-MM-DD calendar date, got {d!r}",
                         "header",
                         batch_line)
        elif p in refused:  # never processed (nor a candidate for its day's reference)
            r = RunResult(p, str(h.get("run_id")), d, ctx.info.line or str(h.get("line") or "line"), True)
        else:
            by_date.setdefault(d, []).append((str(h.get("run_id")), p))
            continue
        record(r, refused.get(p, ""))
    order = {d: [p for _, p in sorted(v)] for d, v in sorted(by_date.items())}
    unc_k = spec.monitoring.uncertainty_runs
    line_for = {d: ctx.info.line or str(headers[ps[0]].get("line") or batch_line) for d, ps in order.items()}
    # 2. the days' references: stored ones, else the first run of the day that succeeds
    refs: dict[str, DayReference] = {}
    all_paths = {d: list(ps) for d, ps in order.items()}
    pending = {}
    for d, ps in order.items():
        stored = st.read_reference(line_for[d], d, ctx.info.model_hash)
        if stored is not None:
            refs[d] = DayReference.from_store(line_for[d], d, *stored)
        else:
            pending[d] = list(ps)

    def references(pending: dict[str, list[str]], extra: Mapping[str, dict] | None = None) -> dict[str, str]:
        """Process each day's candidates in turn until one succeeds; the reference run's path per day.

        ``extra``: keyword arguments of :func:`process_run` per candidate path (e.g. a known wheelbase).
        """
        chosen = {}
        extra = extra or {}
        while pending:
            # the reference (the day's most trusted run) is always one of the uncertainty runs
            calls = [((pending[d][0], spec, None), {"uncertainty": unc_k > 0, **extra.get(pending[d][0], {})})
                     for d in pending]
            dates = list(pending)
            for i, res in ex.run(process_run, calls):
                d = dates[i]
                path = pending[d][0]
                r = record(_as_result(res, path, ctx, batch_line))
                if r.ok and r.reference is not None:
                    refs[d] = r.reference
                    st.write_reference(r.line, d, ctx.info.model_hash, r.reference.frame(), r.reference.meta())
                    chosen[d] = path
                    pending[d] = []
                else:
                    pending[d] = pending[d][1:]
            pending = {d: v for d, v in pending.items() if v}
        return chosen

    chosen = references(pending)
    # 3. the other runs against their day's reference (a stored reference's run is re-processed like the others).
    #    A reference that most of its day's runs cannot be aligned to is itself the odd one out (a run of another
    #    track, a bad recording): the first of those runs becomes the reference and the day is processed again.
    todo = {d: [p for p in all_paths[d] if p != chosen.get(d)] for d in all_paths if d in refs}
    retries = dict.fromkeys(todo, 0)
    while todo:
        calls, call_days = [], []
        shared = {d: ex.share(refs[d]) for d, ps in todo.items() if ps}
        for d, ps in todo.items():
            for i, p in enumerate(ps):
                calls.append(((p, spec, shared[d]), {"uncertainty": i < unc_k - (1 if d in chosen else 0)}))
                call_days.append((d, p))
        day_results: dict[str, list[RunResult]] = {d: [] for d in todo}
        for i, res in ex.run(process_run, calls):
            d, p = call_days[i]
            day_results[d].append(record(_as_result(res, p, ctx, batch_line)))
        again = {}
        for d, rs in day_results.items():
            rejected = sorted((r for r in rs if r.ok and not r.aligned), key=lambda r: r.run_id)
            aligned = [r for r in rs if r.ok and r.aligned]
            if len(rejected) > len(aligned) and retries[d] < MAX_REFERENCE_RETRIES:
                log.warning("%s: %d of the day's %d runs cannot be aligned to reference %s; choosing another",
                            d, len(rejected), len(rs), refs[d].run_id)
                retries[d] += 1
                new = references({d: [r.path for r in rejected]})
                if d in new:
                    chosen[d] = new[d]
                    again[d] = [p for p in all_paths[d] if p != new[d]]
        todo = again
    # 4. runs whose wheelbase could not be measured: again with their bogie's wheelbase measured on its other runs
    #    (this batch and the store; estimator.monitoring.wheelbase), the source stated in their row
    retry_wb = wheelbase_retries(latest, headers, st, ctx.info.model_hash)
    if retry_wb:
        for d in sorted({headers[p]["date"] for p in retry_wb}):
            ps = sorted(p for p in retry_wb if headers[p]["date"] == d)
            if d not in refs:  # every candidate reference of the day failed: the first retried run is the reference
                p0 = ps.pop(0)
                if d not in references({d: [p0]}, {p0: {"wheelbase": retry_wb[p0]}}):
                    continue
            shared = ex.share(refs[d])
            calls = [((p, spec, shared), {"wheelbase": retry_wb[p]}) for p in ps]
            for i, res in ex.run(process_run, calls):
                record(_as_result(res, ps[i], ctx, batch_line))
    timings = {"runs": time.perf_counter() - t_start}
    written = list(latest.values())
    dates = tuple(sorted({r.date for r in written if r.ok}))
    lines = sorted({r.line for r in written if r.ok})
    if update and dates:
        t0 = time.perf_counter()
        for ln in lines:
            update_days(st, ln, dates, ctx.info.model_hash, spec.monitoring)
        timings["days"] = time.perf_counter() - t0
    runs_df = pd.concat([r.tables["runs"] for r in written if r.ok and "runs" in r.tables], ignore_index=True) \
        if any(r.ok for r in written) else pd.DataFrame()
    fails = pd.concat([r.tables["failures"] for r in written if not r.ok], ignore_index=True) \
        if any(not r.ok for r in written) else pd.DataFrame()
    if len(runs_df):
        runs_df = runs_df.drop_duplicates("run_id")
    return IngestResult(lines[0] if lines else (ctx.info.line or ""), ctx.info.model_hash, runs_df, fails, dates,
                        ex.describe() if hasattr(ex, "describe") else type(ex).__name__, timings)


def _run_id_collisions(paths: Sequence[str], headers: Mapping, store: MonitoringStore, line_id: str,
                       batch_line: str) -> dict[str, str]:
    """The runs of a batch to refuse before processing them, with the reason: their run id names the same file
    as another run's on the same line (:func:`~estimator.monitoring.store.same_run`).

    Every run of a group of the batch that share a file name is refused (which of them is "the" run is the
    user's call: the message names the other file); a run whose name is held in the store by a different run is
    refused, a run that is the stored one is re-processed (its rows replaced). A run id that cannot name a
    file is refused too.
    """
    refused: dict[str, str] = {}
    idents, groups = {}, {}
    for p in paths:
        h = headers.get(p)
        dated = isinstance(h, Mapping) and calendar_date(str(h.get("date", "")))
        # the line the run's rows will be written to (process_run for a dated header, else the batch's: _failure)
        line = line_id or (str(h.get("line") or "line") if dated else batch_line)
        idents[p] = _run_identity(p, h)
        try:
            key = (safe_name(line), safe_name(idents[p]["run_id"]))
        except StoreError as exc:
            refused[p] = f"{p}: the run_id cannot be stored ({exc}); give the run another run_id in its header"
            continue
        groups.setdefault(key, []).append(p)
    for ps in groups.values():
        for p in ps if len(ps) > 1 else ():
            others = [q for q in ps if q != p]
            more = f" (and {len(others) - 1} more file(s) of the batch)" if len(others) > 1 else ""
            refused[p] = collision_message(idents[p], idents[others[0]], "in this batch" + more)
    stored = store.stored_runs(line_id or None)
    if len(stored):
        owners = {k: g.to_dict("records") for k, g in stored.groupby(["line", "key"], sort=False)}
        for key, ps in groups.items():
            for p in ps:
                if p in refused:
                    continue
                other = next((o for o in owners.get(key, ()) if not same_run(o, idents[p])), None)
                if other is not None:
                    refused[p] = collision_message(idents[p], other)
    return refused


def wheelbase_retries(results: Mapping[str, RunResult], headers: Mapping, store: MonitoringStore, model_hash: str
                      ) -> dict[str, BogieWheelbase]:
    """The runs of a batch to process again with their bogie's known wheelbase, and that wheelbase.

    A run qualifies when its estimate failed only because its own wheelbase measurement was refused and its
    bogie (header ``train``, ``bogie``) has wheelbases measured confidently on other runs of this batch or of the
    store (:func:`~estimator.monitoring.wheelbase.known_wheelbases`). Runs already processed with a fallback are
    not retried again.
    """
    failed = {p: r for p, r in results.items() if not r.ok and is_wheelbase_failure(r.error_type)
              and isinstance(headers.get(p), Mapping)}
    if not failed:
        return {}
    frames = [r.tables["runs"] for r in results.values() if r.ok and "runs" in r.tables]
    stored = store.read("runs", model_hash=model_hash)
    if len(stored):
        frames.append(stored)
    known = known_wheelbases(pd.concat(frames, ignore_index=True) if frames else pd.DataFrame())
    out = {}
    for p in failed:
        kb = known.get(bogie_key(headers[p]))
        if kb is None:
            log.warning("%s: wheelbase not measured and no other run of bogie %s measured it", p, bogie_key(headers[p]))
            continue
        out[p] = kb
    return out


# --------------------------------------------------------------------------- the days
def _masked_share(runs: pd.DataFrame) -> dict:
    if runs.empty:
        return {}
    return runs.drop_duplicates("run_id").set_index("run_id")["masked_share"].to_dict()


def day_tables(windows: pd.DataFrame, variants: pd.DataFrame, runs: pd.DataFrame, cfg: MonitoringConfig
               ) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Day averages with intervals per window and per section, from a version's run rows (no store needed).

    Estimates that depart from their day's others beyond the day's scatter
    (:mod:`~estimator.monitoring.outliers`) are left out of the averages (their rows stay in the store); with a
    noise floor (variants of source ``floor``) the levels are corrected for it (:mod:`~estimator.monitoring.floor`).
    """
    ms = _masked_share(runs)
    out = outlying_estimates(windows, cfg)
    windows, variants = without_outliers(windows, out), without_outliers(variants, out)
    floor = variants[variants["source"] == FLOOR_SOURCE] if len(variants) else variants
    variants = variants[variants["source"] != FLOOR_SOURCE] if len(variants) else variants
    by = ("date", "section")
    dw = day_average(windows, ms, unit="window_m", by=by)
    sp = variant_spread(variant_deltas(variants, windows, "window_m"), unit="window_m", confidence=cfg.confidence,
                        by=by) if len(variants) else None
    dw = with_floor(with_intervals(dw, sp, unit="window_m", confidence=cfg.confidence, by=by),
                    day_floor(floor, "window_m", by), "window_m", by)
    sw = section_table(windows)
    sv = section_table(variants) if len(variants) else variants
    ds = day_average(sw, ms, unit="section", by=("date",))
    sps = variant_spread(variant_deltas(sv, sw, "section"), unit="section", confidence=cfg.confidence,
                         by=("date",)) if len(sv) else None
    ds = with_floor(with_intervals(ds, sps, unit="section", confidence=cfg.confidence, by=("date",)),
                    day_floor(section_table(floor) if len(floor) else floor, "section"), "section")
    return dw, ds


def update_days(store, line: str, dates: Sequence[str], model_hash: str, cfg: MonitoringConfig = MonitoringConfig()
                ) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Re-average the given days of one line and model version and write the ``days`` and ``day_sections`` tables."""
    st = store if isinstance(store, MonitoringStore) else MonitoringStore(store)
    dates = sorted(set(dates))
    win = st.read("windows", line=line, date=dates, model_hash=model_hash)
    if win.empty:
        return pd.DataFrame(), pd.DataFrame()
    var = st.read("variants", line=line, date=dates, model_hash=model_hash)
    runs = st.read("runs", line=line, date=dates, model_hash=model_hash)
    ident = win[["model_hash", "model_file", "toolkit_version", "config_hash"]].iloc[0].to_dict()
    dw, ds = day_tables(win, var, runs, cfg)
    for d in dates:
        tw = dw[dw["date"] == d].assign(**ident)
        ts = ds[ds["date"] == d].assign(**ident)
        st.write(line, f"day-{d}", model_hash, {"days": tw, "day_sections": ts}, replace_tables=("days", "day_sections"))
    return dw, ds


# --------------------------------------------------------------------------- reading a line back
@dataclass(frozen=True, eq=False)
class MonitorResult:
    """A line's state from the store (one model version; see :func:`monitor`).

    Attributes
    ----------
    line, model_hash : str
    section_range : (float, float) or None
    runs : DataFrame
        QC row per run (first section), with alignment verdicts.
    day_windows, day_sections : DataFrame
        Day averages with intervals per window and per section.
    windows, variants : DataFrame
        The run rows they come from.
    flags : DataFrame
        Consistency findings (:mod:`~estimator.monitoring.consistency`).
    outliers : DataFrame
        Run-wheelset estimates left out of the day averages (:mod:`~estimator.monitoring.outliers`).
    grinding, grinding_short, grinding_effect : DataFrame
    growth, forecast : DataFrame
    versions : DataFrame
        Model versions in the store.
    changes : DataFrame
        Per other version: day level differences per section, rail and band.
    thresholds_um : dict
    sections : Sections
    alignment : DataFrame
    calibration : DataFrame
        The reference calibration applied to the window intervals
        (:func:`~estimator.monitoring.confidence.reference_calibration`; empty without one).
    """

    line: str
    model_hash: str
    section_range: tuple | None
    runs: pd.DataFrame
    day_windows: pd.DataFrame
    day_sections: pd.DataFrame
    windows: pd.DataFrame
    variants: pd.DataFrame
    flags: pd.DataFrame
    grinding: pd.DataFrame
    grinding_short: pd.DataFrame
    grinding_effect: pd.DataFrame
    growth: pd.DataFrame
    forecast: pd.DataFrame
    versions: pd.DataFrame
    changes: pd.DataFrame
    thresholds_um: Mapping
    sections: Sections
    alignment: pd.DataFrame
    consistency: Mapping = field(default_factory=dict)
    outliers: pd.DataFrame = field(default_factory=pd.DataFrame)
    calibration: pd.DataFrame = field(default_factory=pd.DataFrame)


def _thresholds(cfg: MonitoringConfig, est_cfg: EstimatorConfig | None = None) -> dict:
    base = (est_cfg or EstimatorConfig()).thresholds_um
    th = {band_label(b): v for b, v in base.items()}
    if cfg.thresholds_um:
        th.update({band_label(b): v for b, v in cfg.thresholds_um.items()})
    return th


def _pick_version(st: MonitoringStore, line: str, model_hash: str | None) -> str:
    vs = st.model_versions(line)
    if vs.empty:
        raise StoreError(f"store {st.root} holds no run of line {line!r}")
    if model_hash is None:
        return str(vs["model_hash"].iloc[-1])
    hit = vs[vs["model_hash"].str.startswith(model_hash)]
    if hit.empty:
        raise StoreError(f"store {st.root}: no model version {model_hash!r} for line {line!r}; it holds "
                         f"{list(vs['model_hash'])}")
    return str(hit["model_hash"].iloc[0])


def _in_range(df: pd.DataFrame, col: str, rng, width: float = 0.0) -> pd.DataFrame:
    if rng is None or df.empty or col not in df.columns:
        return df
    x = df[col].to_numpy(float)
    return df[(x + width > rng[0]) & (x < rng[1])]


def _until(df: pd.DataFrame, as_of: str | None) -> pd.DataFrame:
    if as_of is None or df.empty or "date" not in df.columns:
        return df
    return df[df["date"].astype(str) <= as_of]


def monitor(store, *, line: str | None = None, section_range: tuple[float, float] | None = None,
            model_hash: str | None = None, cfg: MonitoringConfig = MonitoringConfig(),
            estimator_config: EstimatorConfig | None = None, line_file=None, as_of: str | None = None,
            calibration: pd.DataFrame | None = None) -> MonitorResult:
    """A line's monitoring state from the store (module docstring).

    Parameters
    ----------
    store : MonitoringStore or path
    line : str, optional
        The line's id (default: the only line in the store).
    section_range : (float, float), optional
        Chainage range [m] to look at.
    model_hash : str, optional
        Model version (a prefix is enough; default: the last one processed).
    cfg : MonitoringConfig
    estimator_config : EstimatorConfig, optional
        For the default band thresholds.
    line_file : path, optional
        ``line.json`` for the sections' extents (default: fixed-length sections).
    as_of : str, optional
        ``YYYY-MM-DD``: the line as it was known on that day (only the survey days up to it): the growth and the
        grinding plan that were forecast then, to be checked against what happened afterwards.
    calibration : pandas.DataFrame, optional
        The estimate's error against a trolley on a calibration site
        (:func:`~estimator.monitoring.confidence.reference_calibration`): added to every window's interval as the
        measured systematic source (:func:`~estimator.monitoring.confidence.with_reference`).
    """
    from estimator.io import read_line

    st = store if isinstance(store, MonitoringStore) else MonitoringStore(store)
    st.verify()  # a file the store did not write is refused before any work reads or adds to it
    lines = st.lines()
    if not lines:
        what = "is empty" if Path(st.root).is_dir() else "does not exist"
        raise StoreError(f"store {st.root} {what} (ingest runs first: railmodal field ingest ... --store {st.root})")
    if line is None:
        if len(lines) > 1:
            raise StoreError(f"store {st.root} holds several lines {lines}; choose one (--line)")
        line = lines[0]
    elif line not in lines:
        raise StoreError(f"store {st.root} holds no line {line!r}; it holds {lines}")
    mh = _pick_version(st, line, model_hash)
    ln = read_line(line_file) if line_file else None
    est_cfg = estimator_config or EstimatorConfig()
    sections = Sections.of(ln, est_cfg.section_length_m)
    if as_of is not None and not calendar_date(str(as_of)):
        raise MonitoringError(f"as_of must be a date YYYY-MM-DD, got {as_of!r}")
    runs = _until(st.read("runs", line=line, model_hash=mh), as_of)
    win = _in_range(st.read("windows", line=line, model_hash=mh), "window_m", section_range, cfg.window_m)
    var = _in_range(st.read("variants", line=line, model_hash=mh), "window_m", section_range, cfg.window_m)
    win, var = _until(win, as_of), _until(var, as_of)
    if win.empty:
        raise StoreError(f"store {st.root}: no band index of line {line!r}, model {mh}"
                         + (f" in {section_range[0]:g}-{section_range[1]:g} m" if section_range else "")
                         + (f" up to {as_of}" if as_of else ""))
    dw = _until(_in_range(st.read("days", line=line, model_hash=mh), "window_m", section_range, cfg.window_m), as_of)
    ds = _until(st.read("day_sections", line=line, model_hash=mh), as_of)
    if dw.empty or ds.empty or section_range is not None:
        dw, ds = day_tables(win, var, runs, cfg)
    if calibration is not None and len(calibration):
        dw = with_reference(dw, calibration)
    th = _thresholds(cfg, est_cfg)
    flags, checks = consistency_checks(win, _masked_share(runs), cfg)
    events, short = detect_grinding(dw, cfg)
    effect = grinding_effect(events, dw, th) if len(events) else pd.DataFrame()
    gr = growth(ds, events, sections, cfg)
    fc = forecast(gr, th, ds, cfg.confidence) if len(gr) else pd.DataFrame()
    versions = st.model_versions(line)
    changes = []
    for other in versions["model_hash"]:
        if other == mh:
            continue
        od = st.read("day_sections", line=line, model_hash=other)
        if od.empty:
            continue
        keys = ["date", "section", "rail", "band_mm"]
        j = ds.merge(od[keys + ["level_db"]], on=keys, suffixes=("", "_other"))
        j = j.assign(other_model=other, change_db=j["level_db"] - j["level_db_other"])
        changes.append(j[keys + ["other_model", "level_db", "level_db_other", "change_db"]])
    alignment = _until(st.read("alignment", line=line, model_hash=mh), as_of)
    return MonitorResult(line, mh, section_range, runs.drop_duplicates("run_id") if len(runs) else runs, dw, ds, win,
                         var, flags, events, short, effect, gr, fc, versions,
                         pd.concat(changes, ignore_index=True) if changes else pd.DataFrame(), th, sections, alignment,
                         checks, outlying_estimates(win, cfg),
                         calibration if calibration is not None else pd.DataFrame())


def reprocess(store, spec: IngestSpec, *, line: str | None = None, from_model: str | None = None, executor=None,
              progress=None) -> IngestResult:
    """Re-ingest every run of a model version with ``spec``'s (new) model; the old version stays beside it.

    The transfer functions are re-derived from the new model (a new field model), every run file recorded in the
    store is processed again, and the days are re-averaged under the new model's version.
    """
    st = store if isinstance(store, MonitoringStore) else MonitoringStore(store)
    st.verify()  # a file the store did not write is refused before any work reads or adds to it
    runs = st.read("runs", line=line)
    if runs.empty:
        raise StoreError(f"store {st.root} holds no run to reprocess")
    if from_model is not None:
        runs = runs[runs["model_hash"].str.startswith(from_model)]
        if runs.empty:
            raise StoreError(f"store {st.root}: no run processed with model version {from_model!r}")
    sources = sorted(set(runs["source"]))
    missing = [s for s in sources if not Path(s).is_file()]
    if missing:
        raise StoreError(f"{len(missing)} run file(s) recorded in the store are gone, e.g. {missing[:3]}")
    return ingest(sources, spec, st, executor=executor, progress=progress)
