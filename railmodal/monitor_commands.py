"""``railmodal field ingest / monitor / compare-reference / reprocess``: months of runs of a line.

* ``field ingest RUNS... --sensors S.csv --model hybrid_model.npz --store DIR [--line line.json]`` —
  every run estimated, aligned and written to the monitoring store (a Dask local cluster by default,
  ``--scheduler ADDRESS`` for an existing cluster, ``--executor local`` for this process), then the days
  re-averaged; a progress bar on stderr; a failed or rejected run is reported and the batch goes on.
* ``field monitor --store DIR [--section FROM TO] [--calibration-trolley T.csv [--calibration-site FROM TO]]
  --out DIR`` — trends, grinding events, forecast table, figures and an HTML report; with a trolley record of a
  calibration site, the estimate's measured error there widens every window's interval
  (:func:`estimator.monitoring.confidence.reference_calibration`).
* ``field compare-reference --store DIR --trolley T.csv... --out DIR`` — trolley records aligned to the
  train's chainage, processed by the same EN code, band errors per rail (table and plots).
* ``field reprocess --store DIR --model NEW.npz --sensors S.csv [--line line.json]`` — the archive again
  with a new wheelset model; both versions stay in the store.

Every argument is validated before any work; results are written only on success (the store by atomic
per-file replacement, ``--out`` through a temporary folder renamed at the end).
"""

from __future__ import annotations

import argparse
import logging
import math
import sys
import time
from pathlib import Path

from railmodal.arguments import (band_action, bounded_float, bounded_int, calibration_path, existing_file, iso_date,
                                 output_folder)

log = logging.getLogger("estimator")

__all__ = ["add_monitor_commands"]

_DIRECTIONS = ("forward", "backward")


def _bar(quiet: bool):
    """A text progress bar on stderr: ``[#####.....] 12/70  message``."""
    if quiet:
        return lambda done, total, msg: None

    def show(done: int, total: int, msg: str) -> None:
        n = 30
        k = int(round(n * done / max(total, 1)))
        print(f"\r[{'#' * k}{'.' * (n - k)}] {done}/{total}  {msg[:90]:<90}", file=sys.stderr, end="",
              flush=True)
        if done >= total:
            print(file=sys.stderr, flush=True)

    return show


def _store_folder(option: str):
    def parse(text: str) -> Path:
        p = Path(text)
        if p.exists() and not p.is_dir():
            raise argparse.ArgumentTypeError(f"{option} {text!r} is a file, not a store folder")
        return p

    parse.__name__ = "store folder"
    return parse


def _spec(args, model) -> object:
    from estimator import EstimatorConfig
    from estimator.monitoring import IngestSpec, MonitoringConfig

    est = EstimatorConfig(wheelbase_m=args.wheelbase, speed_gate_m_s=args.speed_gate, wheel_radius_m=args.wheel_radius)
    mon = MonitoringConfig(model=args.model_kind, window_m=args.window, n_perturbed=args.perturbed,
                           uncertainty_runs=args.uncertainty_runs)
    return IngestSpec(str(model), str(args.sensors), line=str(args.line) if args.line else None, estimator=est,
                      monitoring=mon, direction=args.direction, calibration=args.calibration)


def _executor(args):
    from estimator.fleet import DaskExecutor, LocalExecutor

    if args.executor == "local" and not args.scheduler:
        return LocalExecutor()
    return DaskExecutor(args.scheduler, workers=args.workers, memory_limit=args.memory_limit)


def _print_ingest(res) -> None:
    r = res.runs
    ok = int(r["aligned"].sum()) if len(r) else 0
    print(f"line {res.line}, model version {res.model_hash}: {len(r)} run(s) written ({ok} aligned and averaged), "
          f"{len(res.failures)} failed; survey days {', '.join(res.dates) or 'none'}; executor {res.executor}")
    if len(r):
        rej = r[~r["aligned"]]
        for _, x in rej.iterrows():
            print(f"  rejected {x['run_id']}: {x['rejected_reason']}")
        res_mm = r.loc[r["aligned"], "alignment_residual_mm"]
        if len(res_mm):
            print(f"  alignment residual: median {res_mm.median():.2f} mm, max {res_mm.max():.2f} mm RMS")
    for _, f in res.failures.iterrows() if len(res.failures) else []:
        print(f"  failed {f['run_id']}: {f['error']}")
    print(f"done in {sum(res.timings_s.values()):.1f} s")


def _cmd_ingest(args: argparse.Namespace) -> int:
    from estimator.monitoring import MonitoringStore, ingest
    from estimator.monitoring.workflow import collect_runs

    runs = collect_runs(args.runs)
    spec = _spec(args, args.model)
    store = MonitoringStore(args.store)
    with _executor(args) as ex:
        res = ingest(runs, spec, store, executor=ex, progress=_bar(args.quiet))
    _print_ingest(res)
    return 0 if len(res.runs) else 1


def _cmd_reprocess(args: argparse.Namespace) -> int:
    from estimator.monitoring import MonitoringStore, reprocess

    spec = _spec(args, args.model)
    store = MonitoringStore(args.store)
    with _executor(args) as ex:
        res = reprocess(store, spec, line=args.line_id, from_model=args.from_model, executor=ex,
                        progress=_bar(args.quiet))
    _print_ingest(res)
    return 0 if len(res.runs) else 1


def _cmd_monitor(args: argparse.Namespace) -> int:
    from estimator.monitoring import MonitoringStore, monitor
    from estimator.monitoring.report import write_monitoring
    from railmodal.output import check_output_folder, staged_output

    t0 = time.perf_counter()
    check_output_folder(args.out)
    store = MonitoringStore(args.store)
    calibration = None
    if args.calibration_trolley:
        from estimator.monitoring import reference_calibration
        from estimator.monitoring.reference import compare_reference

        comp = compare_reference(store, args.calibration_trolley, line=args.line_id, model_hash=args.model_version)
        site = tuple(args.calibration_site) if args.calibration_site else None
        calibration = reference_calibration(comp.windows, site=site)
        for _, r in calibration.iterrows():
            state = (f"truth within [{r['lo_db']:+.2f}, {r['hi_db']:+.2f}] dB of an estimate"
                     if math.isfinite(r["lo_db"]) else "too few windows: not calibrated")
            print(f"  calibration {r['band_mm']:>8s} mm on {r['from_m']:.0f}-{r['to_m']:.0f} m: {r['windows']} "
                  f"windows, error {r['mean_error_db']:+.2f} ± {r['sd_error_db']:.2f} dB: {state}")
    elif args.calibration_site:
        raise ValueError("--calibration-site needs --calibration-trolley (the trolley record of the site)")
    res = monitor(store, line=args.line_id, section_range=tuple(args.section) if args.section else None,
                  model_hash=args.model_version, line_file=args.line, as_of=args.as_of, calibration=calibration)
    with staged_output(args.out) as tmp:
        files = write_monitoring(res, tmp)
    dates = sorted(res.day_windows["date"].unique())
    print(f"line {res.line}, model {res.model_hash}: {len(dates)} survey day(s) {dates[0]} to {dates[-1]}, "
          f"{len(res.runs)} run(s)")
    fc = res.forecast
    if len(fc):
        for _, r in fc[fc["status"] != "too few days"].head(12).iterrows():
            lo = f"possibly above already ({r['crossing_lo']})" if r.get("possibly_above_now") else r["crossing_lo"]
            when = (f" {r['crossing_date']} [{lo} .. {r['crossing_hi']}], {r['days_per_db']:.0f} d "
                    "earlier per dB read high") if r["status"] == "forecast" else ""
            print(f"  {r['section']:>22s} rail {r['rail']} {r['band_mm']:>8s} mm: {r['last_pk_pk_um']:7.1f} um "
                  f"(threshold {r['threshold_um']:g}) {r['status']}{when}")
    for _, g in res.grinding.iterrows():
        print(f"  grinding between {g['date_before']} and {g['date_after']} on {g['from_m']:.0f}-{g['to_m']:.0f} m")
    if len(res.flags):
        print(f"  {len(res.flags)} consistency finding(s): see consistency_flags.csv")
    for _, o in res.outliers.iterrows():
        print(f"  left out of the {o['date']} average: run {o['run_id']} wheelset {o['wheelset']} rail {o['rail']} "
              f"{o['band_mm']} mm on {o['section']} ({o['deviation_db']:+.1f} dB from the day's others, limit "
              f"{o['limit_db']:.1f} dB)")
    print(f"report: {Path(args.out) / files['report'].name} ({time.perf_counter() - t0:.1f} s)")
    return 0


def _cmd_compare(args: argparse.Namespace) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    import pandas as pd

    from estimator.monitoring import MonitoringStore
    from estimator.monitoring.plot import plot_reference
    from estimator.monitoring.reference import compare_reference
    from railmodal.output import check_output_folder, staged_output

    check_output_folder(args.out)
    store = MonitoringStore(args.store)
    trolleys = {}
    for t in args.trolley:  # the same record twice would count its bands twice in the tables
        key = Path(t).resolve()
        if key in trolleys:
            log.warning("trolley file %s is given more than once (also as %s): compared once", t, trolleys[key])
        trolleys.setdefault(key, t)
    results = [compare_reference(store, t, line=args.line_id, model_hash=args.model_version)
               for t in trolleys.values()]
    with staged_output(args.out) as tmp:
        tables = []
        for c in results:
            stem = Path(c.trolley).stem
            c.errors.assign(trolley=stem, train_date=c.train_date).to_csv(tmp / f"band_errors_{stem}.csv", index=False)
            c.windows.to_csv(tmp / f"windows_{stem}.csv", index=False)
            if len(c.spectra):
                c.spectra.to_csv(tmp / f"spectra_{stem}.csv", index=False)
            fig = plot_reference(c.windows)
            fig.savefig(tmp / f"reference_{stem}.png", dpi=110)
            plt.close(fig)
            tables.append(c.errors.assign(trolley=stem, train_date=c.train_date))
        pd.concat(tables, ignore_index=True).to_csv(tmp / "band_errors.csv", index=False)
    for c in results:
        shift = c.alignment.fit.shift(c.alignment.windows["centre_m"].to_numpy(float))
        print(f"trolley {c.trolley} ({c.date or 'undated'}) against the train's {c.train_date} average, model "
              f"{c.model_hash}: aligned with offset {float(np.median(shift)):+.3f} m (median over the record), "
              f"residual {c.alignment.residual_mm:.1f} mm")
        for _, e in c.errors.iterrows():
            print(f"  rail {e['rail']} {e['band_mm']:>8s} mm: level error {e['level_error_db']:+.1f} dB, window "
                  f"errors mean {e['mean_error_db']:+.1f} dB, RMS {e['rms_error_db']:.1f} dB, {100 * e['within_3db']:.0f} "
                  f"% within 3 dB ({e['windows']} windows)")
    print(f"tables and plots in {args.out}")
    return 0


def _field_subparsers(sub):
    """The ``field`` group's sub-commands (created when the single-run commands did not create it)."""
    parser = sub.choices.get("field")
    if parser is None:
        parser = sub.add_parser("field", help="field runs of the instrumented bogie")
    for action in parser._actions:  # noqa: SLF001 - argparse keeps its sub-command action here
        if isinstance(action, argparse._SubParsersAction):  # noqa: SLF001
            return action
    return parser.add_subparsers(dest="field_command", required=True)


def _common_processing(p) -> None:
    p.add_argument("--sensors", required=True, type=existing_file("--sensors", "sensor table"),
                   help="sensor table CSV (name, quantity, unit, wheelset, side, direction, x, y, z, sensitivity)")
    p.add_argument("--model", required=True, type=existing_file("--model", "hybrid wheelset model (.npz)"),
                   help="hybrid_model.npz ('railmodal model build' or 'lab diagnose'); its hash is the model version")
    p.add_argument("--calibration", default=None, type=calibration_path, metavar="DIR",
                   help="calibrated_model/ folder of 'railmodal field diagnose' for this model: its field effects "
                        "are applied and the store keeps the results under the calibrated version")
    p.add_argument("--store", required=True, type=_store_folder("--store"), help="monitoring store folder")
    p.add_argument("--line", default=None, type=existing_file("--line", "line description (line.json)"),
                   help="line.json: sections, curves, trackforms, balises and welds (alignment)")
    p.add_argument("--direction", choices=_DIRECTIONS, default=None, help="override every run's direction")
    p.add_argument("--wheelbase", default=None, type=bounded_float("--wheelbase", 0.5, 10.0, unit="m"),
                   help="bogie wheelbase [m] (default: measured from each run)")
    p.add_argument("--wheel-radius", default=None, type=bounded_float("--wheel-radius", 0.2, 0.7, unit="m"),
                   help="nominal (e.g. measured, worn) wheel rolling radius [m] for the circumference search, the "
                        "contact angles and the Hertz contact (default: the model's, its contact points' distance "
                        "from the axle)")
    p.add_argument("--speed-gate", default=3.0, type=bounded_float("--speed-gate", 0.0, 100.0, lo_open=True,
                                                                    unit="m/s"), help="default 3 m/s")
    p.add_argument("--model-kind", default="vertical_lateral", choices=("half", "vertical", "vertical_lateral"),
                   help="transfer-function model monitored (default vertical_lateral)")
    p.add_argument("--window", default=1.0, type=bounded_float("--window", 0.05, 1000.0, unit="m"),
                   help="chainage window of the stored band indexes (default 1 m)")
    p.add_argument("--perturbed", default=25, type=bounded_int("--perturbed", 0, 200),
                   help="perturbed wheelset models (+/-10 %% on f and zeta) for the intervals (default 25)")
    p.add_argument("--uncertainty-runs", default=1, type=bounded_int("--uncertainty-runs", 0, 100),
                   help="runs per day put through the perturbed and shifted-sensor models (default 1)")
    p.add_argument("--executor", choices=("dask", "local"), default="dask",
                   help="dask (a local cluster, or --scheduler) or local (this process) (default dask)")
    p.add_argument("--scheduler", default=None, help="address of an existing Dask scheduler (tcp://host:8786)")
    p.add_argument("--workers", default=2, type=bounded_int("--workers", 1, 256),
                   help="worker processes of the local Dask cluster (default 2)")
    p.add_argument("--memory-limit", default="4GiB", help="memory limit per local Dask worker (default 4GiB)")


def add_monitor_commands(sub) -> None:
    """Add ``ingest``, ``monitor``, ``compare-reference`` and ``reprocess`` to the ``railmodal field`` group."""
    fsub = _field_subparsers(sub)
    ing = fsub.add_parser("ingest", help="runs -> monitoring store (estimate, align, average; Dask)")
    ing.add_argument("runs", nargs="+", help="run files (MDF 4, TDMS, Parquet, CSV) or folders of MDF 4 / TDMS files")
    _common_processing(ing)
    ing.set_defaults(func=_cmd_ingest)

    rep = fsub.add_parser("reprocess", help="the store's runs again with a new wheelset model (versions side by side)")
    _common_processing(rep)
    rep.add_argument("--line-id", default=None, help="line in the store (default: all)")
    rep.add_argument("--from-model", default=None, help="reprocess the runs of this model version (hash prefix)")
    rep.set_defaults(func=_cmd_reprocess)

    mon = fsub.add_parser("monitor", help="store -> trends, grinding events, forecast table, HTML report")
    mon.add_argument("--store", required=True, type=_store_folder("--store"), help="monitoring store folder")
    mon.add_argument("--section", nargs=2, type=bounded_float("--section", 0.0, 1e7, unit="m"), default=None,
                     metavar=("FROM", "TO"), action=band_action("--section", 0.0, 1e7, unit="m"),
                     help="chainage range to report [m]")
    mon.add_argument("--out", required=True, type=output_folder("--out"), help="output folder")
    mon.add_argument("--line", default=None, type=existing_file("--line", "line description (line.json)"),
                     help="line.json for the sections' extents (trends per section)")
    mon.add_argument("--line-id", default=None, help="line in the store (default: the only one)")
    mon.add_argument("--model-version", default=None, help="model version (hash prefix; default: the last processed)")
    mon.add_argument("--as-of", default=None, type=iso_date("--as-of"),
                     help="YYYY-MM-DD: the line as known on that day (survey days up to it: the forecast made then)")
    mon.add_argument("--calibration-trolley", default=None,
                     type=existing_file("--calibration-trolley", "trolley record (CSV)"),
                     help="trolley record of a calibration site: the estimate's error against it is added to every "
                          "window's interval")
    mon.add_argument("--calibration-site", nargs=2, type=bounded_float("--calibration-site", 0.0, 1e7, unit="m"),
                     default=None, metavar=("FROM", "TO"), action=band_action("--calibration-site", 0.0, 1e7, unit="m"),
                     help="chainage range of the calibration site [m] (default: all the trolley covers)")
    mon.set_defaults(func=_cmd_monitor)

    cmp_ = fsub.add_parser("compare-reference", help="trolley records against the train's day averages per band "
                                                     "and rail")
    cmp_.add_argument("--store", required=True, type=_store_folder("--store"), help="monitoring store folder")
    cmp_.add_argument("--trolley", required=True, nargs="+", type=existing_file("--trolley", "trolley record (CSV)"),
                      help="trolley files chainage_m, rail, roughness_um (named <YYYY-MM-DD>.csv)")
    cmp_.add_argument("--out", required=True, type=output_folder("--out"), help="output folder")
    cmp_.add_argument("--line-id", default=None, help="line in the store (default: the only one)")
    cmp_.add_argument("--model-version", default=None, help="model version (hash prefix; default: the last processed)")
    cmp_.set_defaults(func=_cmd_compare)
