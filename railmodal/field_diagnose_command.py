"""``railmodal field diagnose``: a calibration site's runs + trolley → the missing field effects, a calibrated model.

The command validates every argument and input before any work, calls
:func:`estimator.diagnosis.run_field_diagnosis` and
:func:`estimator.diagnosis.report.write_field_diagnosis`, and writes its
results only when everything succeeded (temporary folder, then rename):
``field_diagnosis.json``, ``report.html``, figures and ``calibrated_model/``.
With ``--calibration`` (a previous ``calibrated_model/`` made for the same
``--model``) the diagnosis starts from that calibration.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from railmodal.arguments import bounded_float, bounded_int, calibration_path, existing_file, iso_date, output_folder

__all__ = ["add_field_diagnose_command", "MAX_RUN_FILES"]

MAX_RUN_FILES = 200
#: stretches a diagnosis reports the band-index error on, besides the site and the effects' own
MAX_VALIDATION_STRETCHES = 20


def _cmd_diagnose(args: argparse.Namespace) -> int:
    from estimator.diagnosis import DiagnosisConfig, run_field_diagnosis
    from estimator.diagnosis.effects import EFFECT_NAMES
    from estimator.diagnosis.report import write_field_diagnosis
    from receptance.trackform import load_trackform

    from railmodal.output import check_output_folder, staged_output

    check_output_folder(args.out)
    if len(args.runs) > MAX_RUN_FILES:
        raise ValueError(f"--runs: at most {MAX_RUN_FILES} files, got {len(args.runs)}")
    if len(set(map(str, args.runs))) != len(args.runs):
        raise ValueError("--runs: a file is given twice")
    lo, hi = args.site
    if not hi > lo:
        raise ValueError(f"--site FROM TO must have FROM < TO, got {lo:g} {hi:g}")
    stretches = [tuple(v) for v in (args.validation_stretch or [])]
    if len(stretches) > MAX_VALIDATION_STRETCHES:
        raise ValueError(f"--validation-stretch: at most {MAX_VALIDATION_STRETCHES}, got {len(stretches)}")
    for a, b in stretches:
        if not b > a:
            raise ValueError(f"--validation-stretch FROM TO must have FROM < TO, got {a:g} {b:g}")
    effects = None
    if args.effects:
        effects = tuple(e.strip() for e in args.effects.split(",") if e.strip())
        bad = sorted(set(effects) - set(EFFECT_NAMES))
        if bad:
            raise ValueError(f"--effects: unknown effect(s) {bad}; choose from {', '.join(EFFECT_NAMES)}")
    cfg = DiagnosisConfig(max_effects=args.max_effects, effects=effects, workers=args.workers)
    from estimator import EstimatorConfig

    ecfg = EstimatorConfig(wheelbase_m=args.wheelbase, wheel_radius_m=args.wheel_radius)
    trackform = load_trackform(args.trackform) if args.trackform else None
    say = (lambda m: None) if args.quiet else (lambda m: print(f"  … {m}", file=sys.stderr, flush=True))
    start = None
    if args.calibration:
        from estimator.diagnosis.calibration import calibration_for_model

        start, _ = calibration_for_model(args.calibration, args.model)
        say(f"starting from the calibration {args.calibration}: {start.summary()}")
    say(f"estimating {len(args.runs)} run(s), building the evidence, fitting the catalogue")
    res = run_field_diagnosis(list(args.runs), list(args.reference), (lo, hi), args.model, args.sensors,
                              line=args.line, trackform=trackform, config=cfg, estimator_config=ecfg,
                              calibration_date=args.calibration_date,
                              direction=args.direction, validation_stretches=stretches, start=start)
    with staged_output(args.out) as tmp:
        files = write_field_diagnosis(res, tmp, model_file=args.model)
    d = res.diagnosis
    print(f"site {lo:g}-{hi:g} m, calibration day {res.calibration_date}: {len(res.runs)} run(s), "
          f"{int(res.diagnosis.errors['n_cells'].iloc[0])} calibration cells; noise floor {d.noise_floor_db:.2f} dB")
    for c in d.accepted:
        vals = ", ".join(f"{k} {v:.4g}" for k, v in c.params.items())
        print(f"accepted: {c.effect.label()}: {vals}; error {c.error_before:.2f} -> {c.error_after:.2f} dB "
              f"(validation {c.validation_before:.2f} -> {c.validation_after:.2f} dB), dBIC {c.delta_bic:.0f}")
        print(f"  {c.effect.meaning(c.params)}")
    print(d.verdict)
    print(f"results: {Path(args.out) / files['json'].name}, report {Path(args.out) / files['report'].name}")
    return 0


def add_field_diagnose_command(sub) -> None:
    """Add ``diagnose`` to the ``railmodal field`` group (``sub``: the top-level sub-commands)."""
    from railmodal.monitor_commands import _field_subparsers  # the field group, however it was created

    fsub = _field_subparsers(sub)
    p = fsub.add_parser("diagnose", help="calibration site: compare with a trolley reference, find and fit the "
                                         "missing field effects, save the calibrated model")
    p.add_argument("--runs", required=True, nargs="+", type=existing_file("--runs", "run file"),
                   help="run files (MDF 4, TDMS, Parquet or CSV) over the site and the validation stretches")
    p.add_argument("--reference", required=True, nargs="+", type=existing_file("--reference", "trolley file"),
                   help="trolley files <YYYY-MM-DD>.csv (chainage_m, rail, roughness_um), one per survey day")
    p.add_argument("--site", required=True, nargs=2, metavar=("FROM", "TO"),
                   type=bounded_float("--site", -1e7, 1e7, unit="m"), help="calibration stretch [m]")
    p.add_argument("--model", required=True, type=existing_file("--model", "hybrid wheelset model (.npz)"))
    p.add_argument("--sensors", required=True, type=existing_file("--sensors", "sensor table"))
    p.add_argument("--line", default=None, type=existing_file("--line", "line description (line.json)"))
    p.add_argument("--trackform", default=None, type=existing_file("--trackform", "trackform (TOML/JSON)"))
    p.add_argument("--validation-stretch", nargs=2, action="append", metavar=("FROM", "TO"),
                   type=bounded_float("--validation-stretch", -1e7, 1e7, unit="m"),
                   help="a stretch [m] on which the EN 13231-3 band-index error of the days other than the "
                        "calibration day is also reported (e.g. where the track is known to have changed); "
                        "repeatable, at most "
                        f"{MAX_VALIDATION_STRETCHES}")
    p.add_argument("--calibration-date", default=None, type=iso_date("--calibration-date"),
                   help="survey day whose runs calibrate (default: the first reference's); other days validate")
    p.add_argument("--direction", choices=("forward", "backward"), default=None)
    p.add_argument("--wheelbase", default=None, type=bounded_float("--wheelbase", 0.5, 10.0, unit="m"),
                   help="bogie wheelbase [m] (default: measured from the two wheelsets' estimates)")
    p.add_argument("--wheel-radius", default=None, type=bounded_float("--wheel-radius", 0.2, 0.7, unit="m"),
                   help="nominal (e.g. measured, worn) wheel rolling radius [m] for the circumference search, the "
                        "contact angles and the Hertz contact (default: the model's, its contact points' distance "
                        "from the axle)")
    p.add_argument("--calibration", default=None, type=calibration_path, metavar="DIR",
                   help="a previous 'field diagnose' calibrated_model/ folder made with the same --model: the runs "
                        "are estimated with it and the search adds effects on top of it (diagnose what changed "
                        "since the line was calibrated)")
    p.add_argument("--effects", default=None,
                   help="catalogue effects to try, comma separated (default: all)")
    p.add_argument("--max-effects", default=3, type=bounded_int("--max-effects", 0, 6))
    p.add_argument("--workers", default=None, type=bounded_int("--workers", 1, 64))
    p.add_argument("--out", required=True, type=output_folder("--out"))
    p.set_defaults(func=_cmd_diagnose)
