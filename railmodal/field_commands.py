"""``railmodal field estimate``: one field run → rail roughness per rail, EN 13231-3 indexes, EN 15610 spectra.

The command validates every argument and input file before any work,
calls the library workflow (:func:`estimator.prepare`, with a field
calibration :func:`estimator.diagnosis.calibrated_field_model`,
:func:`estimator.estimate_run`, :func:`estimator.export.write_estimate`) and
writes its results only when everything succeeded (temporary folder, then
rename). It prints a short summary: masked share, wheelbase, the corrugated
stretches and where the report is.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from railmodal.arguments import bounded_float, calibration_path, existing_file, output_folder

__all__ = ["add_field_commands", "summarise_estimate"]

_DIRECTIONS = ("forward", "backward")


def _progress(quiet: bool):
    if quiet:
        return lambda msg: None
    return lambda msg: print(f"  … {msg}", file=sys.stderr, flush=True)


def summarise_estimate(est, files: dict | None = None) -> list[str]:
    """Lines the command prints about an estimate: the run, then its findings (:func:`estimator.findings.headline`,
    which the report's "In short" box shows too)."""
    from estimator.findings import headline

    lines = [f"run {est.run_id}: {est.duration_s:.1f} s, {est.direction} (wheelset {est.leading} leading), masked "
             f"{100 * est.masked_share.get('run', 0.0):.1f} % in any channel, {len(est.qc)} quality-control "
             f"finding(s)",
             f"wheelbase {est.wheelbase_m:.3f} m ({est.wheelbase_source}); inversion band {est.band_hz[0]:g}-"
             f"{est.band_hz[1]:g} Hz; shortest resolved wavelength {1e3 * est.lambda_min_m:.1f} mm"]
    lines += headline(est, plain=True)
    if files and "report" in files:
        lines.append(f"report: {files['report']}")
    return lines


def _cmd_estimate(args: argparse.Namespace) -> int:
    from estimator import EstimatorConfig, estimate_run, parse_models, prepare
    from estimator.export import write_estimate
    from estimator.io import read_trolley
    from estimator.reference import reference_indexes
    from receptance.trackform import load_trackform

    from railmodal.output import check_output_folder, staged_output

    step = _progress(args.quiet)
    out = Path(args.out)
    check_output_folder(out)
    models = parse_models(args.models)
    from receptance.contact import ContactParameters

    cfg = EstimatorConfig(models=models, speed_gate_m_s=args.speed_gate, wheelbase_m=args.wheelbase,
                          regularisation=args.regularisation, bogie_coupling=not args.single_wheelset,
                          contact=ContactParameters(wheel_load_N=args.wheel_load * 1e3),
                          wheel_radius_m=args.wheel_radius,
                          sleeper_comb=not args.keep_sleeper_passing, sleeper_spacing_m=args.sleeper_spacing)
    trackform = load_trackform(args.trackform) if args.trackform else None
    t0 = time.perf_counter()
    step(f"preparing the transfer functions ({', '.join(models)}) from {args.model}")
    fm = prepare(args.model, args.sensors, line=args.line, trackform=trackform, config=cfg)
    if args.calibration:
        from estimator.diagnosis import calibrated_field_model

        fm, _ = calibrated_field_model(fm, args.model, args.calibration)
    reference = None
    if args.reference:
        reference = reference_indexes(read_trolley(args.reference), cfg, source=str(args.reference))
    step(f"estimating {args.run}")
    est = estimate_run(args.run, fm, direction=args.direction)
    step("writing profiles, indexes, spectra, figures and the report")
    with staged_output(out) as tmp:
        files = write_estimate(est, tmp, reference=reference)
    files = {k: out / Path(v).relative_to(tmp) for k, v in files.items()}
    for line in (*fm.provenance, *summarise_estimate(est, files)):
        print(line)
    print(f"done in {time.perf_counter() - t0:.1f} s")
    return 0


def demo_field_step(out: Path, model, wheelset_scenario: str, progress=None) -> list[str]:
    """``railmodal demo``'s field step: a short virtual-line run estimated with the model the lab workflow built.

    Simulates one forward run of the ``nominal`` line over curve 1 (the corrugated low rail) with the lab
    scenario's wheelsets into ``out/line``, estimates it with ``model`` (made :func:`estimator.in_service`:
    test artefacts removed, primary suspension added) and writes the estimate, compared with the day's trolley
    record, into ``out/field``. Returns the lines to print.
    """
    from estimator import estimate_run, prepare
    from estimator.export import write_estimate
    from estimator.io import read_trolley
    from estimator.reference import reference_indexes
    from lab_data.line.campaign import FIRST_CURVE_SECTION, simulate_line

    from railmodal.output import staged_output

    step = progress or (lambda msg: None)
    line_dir, field_dir = out / "line", out / "field"
    with staged_output(line_dir) as tmp:
        simulate_line("nominal", tmp, progress=step, days=1, runs_per_day=1, section=FIRST_CURVE_SECTION,
                      wheelset_scenario=wheelset_scenario)
    run = sorted((line_dir / "runs").rglob("*.mf4"))[0]
    fm = prepare(model, line_dir / "sensors.csv", line=line_dir / "line.json")
    step(f"estimating {run.name} with the lab's model (half, vertical, vertical + lateral)")
    est = estimate_run(run, fm)
    trolley = sorted((line_dir / "trolley").glob("*.csv"))
    reference = reference_indexes(read_trolley(trolley[0]), fm.config, source=str(trolley[0])) if trolley else None
    with staged_output(field_dir) as tmp:
        files = write_estimate(est, tmp, reference=reference)
    files = {k: field_dir / Path(v).relative_to(tmp) for k, v in files.items()}
    return summarise_estimate(est, files)


def add_field_commands(sub) -> None:
    """Add ``railmodal field ...`` to the top-level subparsers."""
    field = sub.add_parser("field", help="field runs of the instrumented bogie: rail roughness estimation")
    fsub = field.add_subparsers(dest="field_command", required=True)
    est = fsub.add_parser("estimate", help="one run -> rail roughness per rail, EN 13231-3 indexes, EN 15610 spectra, "
                                           "report")
    est.add_argument("--run", required=True, type=existing_file("--run", "run (MDF 4, TDMS, Parquet or CSV)"),
                     help="run file (ASAM MDF 4, NI TDMS, a Parquet/CSV long table channel, t_s, value, unit, or a "
                          "wide CSV: "
                          "a time column, then one column per channel 'name [unit]')")
    est.add_argument("--sensors", required=True, type=existing_file("--sensors", "sensor table"),
                     help="sensor table CSV: name, quantity, unit, wheelset, side, direction, x, y, z, sensitivity")
    est.add_argument("--model", required=True, type=existing_file("--model", "hybrid wheelset model (.npz)"),
                     help="hybrid_model.npz written by 'railmodal model build' or 'lab diagnose'")
    est.add_argument("--trackform", default=None, type=existing_file("--trackform", "trackform (TOML/JSON)"),
                     help="trackform file for the whole run (default: the line's trackform sections, else thesis "
                          "Table 2.2)")
    est.add_argument("--line", default=None, type=existing_file("--line", "line description (line.json)"),
                     help="line.json: curves (contact angles), trackform sections, sections for the spectra")
    est.add_argument("--models", default="half,vertical,lateral",
                     help="transfer-function models, comma separated from half, vertical, lateral "
                          "(default: all three)")
    est.add_argument("--direction", choices=_DIRECTIONS, default=None,
                     help="override the run header's direction of travel (relative to chainage)")
    est.add_argument("--reference", default=None, type=existing_file("--reference", "trolley reference (CSV)"),
                     help="trolley file chainage_m, rail, roughness_um: compared in the report")
    est.add_argument("--wheelbase", default=None, type=bounded_float("--wheelbase", 0.5, 10.0, unit="m"),
                     help="bogie wheelbase [m] (default: measured from the two wheelsets' estimates)")
    est.add_argument("--speed-gate", default=3.0, type=bounded_float("--speed-gate", 0.0, 100.0, lo_open=True,
                                                                      unit="m/s"),
                     help="samples slower than this are masked (default 3 m/s)")
    est.add_argument("--regularisation", default=0.02, type=bounded_float("--regularisation", 0.0, 1.0),
                     help="Tikhonov parameter relative to the largest singular value's 1/3-octave envelope "
                          "(default 0.02)")
    est.add_argument("--wheel-load", default=55.0, type=bounded_float("--wheel-load", 1.0, 500.0, unit="kN"),
                     help="static wheel load [kN] for the Hertz contact stiffness and patch, and the contact-loss "
                          "check (default 55)")
    est.add_argument("--wheel-radius", default=None, type=bounded_float("--wheel-radius", 0.2, 0.7, unit="m"),
                     help="nominal (e.g. measured, worn) wheel rolling radius [m] for the circumference search, the "
                          "contact angles and the Hertz contact (default: the model's, its contact points' distance "
                          "from the axle)")
    est.add_argument("--single-wheelset", action="store_true",
                     help="the thesis's single-wheelset transfer functions: leave out the rail's coupling of the "
                          "bogie's two wheelsets (default: included)")
    est.add_argument("--sleeper-spacing", default=None, type=bounded_float("--sleeper-spacing", 0.2, 5.0, unit="m"),
                     help="sleeper spacing [m] for the sleeper comb (default: the --line's)")
    est.add_argument("--keep-sleeper-passing", action="store_true",
                     help="leave the sleeper-passing part (the rail's deflection under the wheel across each bay) in "
                          "the estimate (default: its significant orders are removed)")
    est.add_argument("--calibration", default=None, type=calibration_path, metavar="DIR",
                     help="calibrated_model/ folder of 'railmodal field diagnose' made for this --model: its field "
                          "effects (trackform, contact angles, mounting points, ...) are applied and named in the "
                          "report's processing history")
    est.add_argument("--out", required=True, type=output_folder("--out"))
    est.set_defaults(func=_cmd_estimate)
