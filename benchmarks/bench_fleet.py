"""Fleet benchmark: N runs through Dask on 2 local workers vs 1 — scaling, throughput per core, cores for a fleet.

Usage::

    python benchmarks/bench_fleet.py                  # virtual-line runs (generated and cached if needed)
    python benchmarks/bench_fleet.py --source synthetic --runs 8

What is timed is the fleet's steady state: one task per run (read, QC,
estimate, align to the day's reference, band indexes per window), every
worker warmed up first (its field model built and its transfer functions
derived on one run), then N runs on a ``LocalCluster`` of 1 worker and of 2
workers (one thread each). Printed side by side:

* wall time, runs per minute, **scaling** (time on 1 worker / time on 2; the goal is ≥ 1.7);
* **throughput per core** in multiples of real time: recorded seconds processed per second of one core;
* from the measured per-run cost, the **cores a 20-train fleet** recording 18 h a day needs to keep up
  (processing around the clock), and with the transfer-function and placement uncertainty run on one
  run per day and section in addition;
* the local path (this process) for reference, and the check that Dask's results equal it.

The machine's cores may be shared with other work; the script prints the load average before and after.
"""

from __future__ import annotations

import _checkout  # noqa: F401  (this checkout's packages first: measure the code beside this script)
import argparse
import logging
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

FLEET_TRAINS = 20
HOURS_PER_DAY = 18.0


def _synthetic(folder: Path, n: int):
    from test_estimator_synthetic import control_model, make_run, sensor_table

    from receptance.model_io import save_model

    model = control_model()
    save_model(model, folder / "hybrid_model.npz")
    sensor_table().to_csv(folder / "sensors.csv", index=False)
    rng = np.random.default_rng(0)
    runs = [make_run(folder, model, duration_s=40.0, start_offset_m=float(rng.uniform(-2, 2)),
                     odometer_scale=float(1 + rng.uniform(-0.004, 0.004)), name=f"b{k:02d}",
                     header_extra={"run_id": f"b{k:02d}"}).path for k in range(n + 1)]
    return folder / "hybrid_model.npz", folder / "sensors.csv", None, runs


def _line(folder: Path, n: int):
    from test_estimator_synthetic import control_model

    from lab_data.line.cache import line_campaign_dir
    from receptance.model_io import save_model

    camp = line_campaign_dir("nominal", days=1, runs_per_day=min(n + 1, 12), progress=lambda m: print("  ..", m))
    save_model(control_model(), folder / "hybrid_model.npz")
    runs = sorted((camp / "runs").rglob("*.mf4"))
    return folder / "hybrid_model.npz", camp / "sensors.csv", camp / "line.json", runs


def _timed_batch(ex, paths, spec, ref) -> tuple[float, list]:
    from estimator.monitoring.workflow import process_run

    shared = ex.share(ref)
    calls = [((str(p), spec, shared), {"uncertainty": False}) for p in paths]
    t0 = time.perf_counter()
    out = [None] * len(calls)
    for i, r in ex.run(process_run, calls):
        out[i] = r
    return time.perf_counter() - t0, out


def _quiet() -> None:
    """The run's QC findings are logged as warnings; the benchmark prints its figures only."""
    logging.getLogger("estimator").setLevel(logging.ERROR)


def _warm(ex, path, spec, ref) -> None:
    """Every worker builds its field model and derives its transfer functions on one run."""
    from estimator.monitoring.workflow import process_run

    if hasattr(ex, "client"):
        ex.client.run(_quiet)  # in the workers too, as in this process
        ex.client.run(process_run, str(path), spec, ref)
    else:
        process_run(str(path), spec, ref)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--source", choices=("line", "synthetic"), default="line")
    ap.add_argument("--runs", type=int, default=8, help="runs timed (default 8)")
    ap.add_argument("--workdir", default=None)
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.ERROR)
    logging.getLogger("estimator").setLevel(logging.ERROR)
    import tempfile

    from estimator import EstimatorConfig
    from estimator.fleet import DaskExecutor, LocalExecutor
    from estimator.io import read_run
    from estimator.monitoring import IngestSpec, MonitoringConfig
    from estimator.monitoring.workflow import process_run, run_context

    work = Path(args.workdir or tempfile.mkdtemp(prefix="bench_fleet_"))
    work.mkdir(parents=True, exist_ok=True)
    print(f"load average before: {os.getloadavg()}, cores: {os.cpu_count()}")
    model, sensors, line, runs = (_line if args.source == "line" else _synthetic)(work, args.runs)
    spec = IngestSpec(str(model), str(sensors), line=str(line) if line else None,
                      estimator=EstimatorConfig(wheelbase_m=None if line else 2.2),
                      monitoring=MonitoringConfig(n_perturbed=0, uncertainty_runs=0))
    ref_res = process_run(str(runs[0]), spec, None)
    if not ref_res.ok:
        print(f"the reference run failed: {ref_res.error}")
        return 1
    ref = ref_res.reference
    paths = [runs[1 + (k % (len(runs) - 1))] for k in range(args.runs)]
    ctx = run_context(spec)
    recorded = sum(read_run(p, ctx.field_model.sensors).duration_s for p in paths)
    print(f"{args.runs} runs from {args.source}: {recorded:.0f} s recorded ({recorded / args.runs:.1f} s each)")

    # the local path (this process) — also the reference results
    _warm(LocalExecutor(), paths[0], spec, ref)
    t_loc, out_loc = _timed_batch(LocalExecutor(), paths, spec, ref)
    times = {}
    outs = {}
    for n in (1, 2):
        with DaskExecutor(workers=n) as ex:
            _warm(ex, paths[0], spec, ref)
            times[n], outs[n] = _timed_batch(ex, paths, spec, ref)
    # equality with the local path
    worst = 0.0
    for n in (1, 2):
        for a, b in zip(out_loc, outs[n]):
            wa, wb = a.tables["windows"], b.tables["windows"]
            worst = max(worst, float(np.max(np.abs(wa["pk_pk_um"].to_numpy() - wb["pk_pk_um"].to_numpy()))))
    scaling = times[1] / times[2]
    per_core = {"local": recorded / t_loc, 1: recorded / times[1], 2: recorded / (2 * times[2])}
    print()
    print(f"{'executor':<26}{'wall [s]':>10}{'runs/min':>10}{'x real time':>13}{'x real time / core':>20}")
    print(f"{'local (this process)':<26}{t_loc:>10.1f}{60 * args.runs / t_loc:>10.1f}{recorded / t_loc:>13.0f}"
          f"{per_core['local']:>20.0f}")
    for n in (1, 2):
        print(f"{f'dask, {n} worker(s)':<26}{times[n]:>10.1f}{60 * args.runs / times[n]:>10.1f}"
              f"{recorded / times[n]:>13.0f}{per_core[n]:>20.0f}")
    # time inside the tasks (the run's own processing) against the wall time per run: the rest is scheduling,
    # transfer of arguments and results, and waiting for a core the machine's other work holds
    for label, out, wall in (("local", out_loc, t_loc), ("dask 1 worker", outs[1], times[1]),
                             ("dask 2 workers", outs[2], 2 * times[2])):
        inside = float(np.median([r.timings_s.get("total", np.nan) for r in out]))
        print(f"{label:<16} median time inside a task {inside:6.2f} s; worker-seconds per run {wall / args.runs:6.2f} s")
    print(f"\nscaling 2 workers vs 1: {scaling:.2f}x (goal >= 1.7)")
    print(f"Dask results vs the local path: largest difference {worst:.3g} um (goal <= 1e-12 relative)")
    per_run = 2 * times[2] / args.runs
    rec_per_day = FLEET_TRAINS * HOURS_PER_DAY * 3600
    cores = rec_per_day / per_core[2] / 86400
    print(f"\nmeasured cost: {per_run:.2f} core-seconds per run of {recorded / args.runs:.0f} s "
          f"({per_core[2]:.0f}x real time per core)")
    print(f"a {FLEET_TRAINS}-train fleet recording {HOURS_PER_DAY:g} h a day records {rec_per_day / 3600:.0f} h a day: "
          f"{rec_per_day / per_core[2] / 3600:.1f} core-hours of processing, i.e. {cores:.2f} core(s) running around "
          f"the clock (at least 1; {max(1, int(np.ceil(cores)))} to keep up)")
    # the intervals' extra cost: one run through the perturbed, shifted, contact and track variants (a reduced
    # set: 3 perturbed models, one placement shift), per variant, scaled to the default set's count
    mc = MonitoringConfig(n_perturbed=3, placement_shifts_mm=(30.0,), placement_axes=("y",), uncertainty_runs=1)
    spec_u = IngestSpec(spec.model, spec.sensors, line=spec.line, estimator=spec.estimator, monitoring=mc)
    n_u = len(run_context(spec_u).uncertainty_variants())
    spec_full = IngestSpec(spec.model, spec.sensors, line=spec.line, estimator=spec.estimator,
                           monitoring=MonitoringConfig())
    n_full = len(run_context(spec_full).uncertainty_variants())
    process_run(str(paths[0]), spec_u, ref, uncertainty=True)  # derive the variants' transfer functions once
    t0 = time.perf_counter()
    res_u = process_run(str(paths[0]), spec_u, ref, uncertainty=True)
    t_u = time.perf_counter() - t0
    per_variant = res_u.timings_s.get("variants", t_u) / n_u
    print(f"intervals: {per_variant:.2f} s per variant and run ({n_u} variants timed); the default {n_full} "
          f"variants on one run a day add {n_full * per_variant:.0f} core-seconds a day per line (beside the fleet's "
          f"{rec_per_day / per_core[2]:.0f})")
    print(f"load average after: {os.getloadavg()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
