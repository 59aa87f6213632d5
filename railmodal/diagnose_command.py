"""``railmodal lab diagnose``: argument parsing and printing around :func:`receptance.diagnosis.workflow.run_lab_diagnosis`.

The workflow (identify → merge → pair → hybrid model → compare → diagnose →
add effects, files and report) is the library function; this module parses
and validates the command line before any work, runs it into a staged
output folder (``--out`` receives the results only when everything
succeeded) and prints a short summary.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path
from typing import Callable

from typing import TYPE_CHECKING

from railmodal.arguments import add_geometry_argument, band_action, bounded_float, bounded_int, existing_file, output_folder

if TYPE_CHECKING:
    from receptance.diagnosis.workflow import LabDiagnosis

__all__ = ["add_diagnose_parser", "cmd_diagnose", "summarise", "run_staged"]

#: most setups on one command line
MAX_SETUP_OPTIONS = 20


def _progress_printer(quiet: bool) -> Callable[[str], None]:
    if quiet:
        return lambda msg: None
    return lambda msg: print(f"  … {msg}", file=sys.stderr, flush=True)


def _undetermined(fit, name: str) -> bool:
    u = (fit.uncertainty or {}).get(name)
    return u is not None and not (math.isfinite(float(u)) and float(u) <= 1.0)


def summarise(result: LabDiagnosis) -> list[str]:
    """A few lines for the terminal: accepted effects, error before/after, what remains, where the report is."""
    d = result.diagnosis
    c = result.comparisons
    lines = [f"model vs measurement: error E {100 * c[0].summary:.2f} % (noise floor {100 * c[0].noise_floor:.2f} %)"]
    if d.accepted:
        for k, f in enumerate(d.accepted, 1):
            params = ", ".join(f"{n} = {v:.4g}" + (" (undetermined)" if _undetermined(f, n) else "")
                               for n, v in f.params.items())
            lines.append(f"  effect {k}: {f.name} ({params}): E {100 * f.error_before:.2f} % -> "
                         f"{100 * f.error_after:.2f} %")
    else:
        lines.append("  no catalogued effect passed the criterion")
    if d.accepted:
        lines.append(f"final error E {100 * c[-1].summary:.2f} % (noise floor {100 * c[-1].noise_floor:.2f} %)")
    for u in d.unexplained:
        lines.append(f"  {u}")
    for na in d.not_applicable:
        lines.append(f"  not applicable: {na['name']}: {na['reason']}")
    lines.append(f"report:    {result.report}")
    lines.append(f"diagnosis: {result.json}")
    lines.append(f"model:     {result.paths['model']}")
    return lines


def run_staged(setups, fem, points, out, **kwargs) -> LabDiagnosis:
    """:func:`run_lab_diagnosis` into a temporary folder beside ``out`` that becomes ``out`` on success."""
    from railmodal.output import staged_output
    from receptance.diagnosis.workflow import run_lab_diagnosis

    with staged_output(out) as tmp:
        result = run_lab_diagnosis(setups, fem, points, tmp, **kwargs)
    return result.moved(Path(out))


class _SetupData(argparse.Action):
    """``--hammer`` and ``--frf`` in command-line order: each pairs with the ``--channels`` of the same rank."""

    def __call__(self, parser, namespace, values, option_string=None):
        items = list(getattr(namespace, "setup_data", None) or [])
        items.append((option_string.lstrip("-"), values))
        setattr(namespace, "setup_data", items)


def cmd_diagnose(args: argparse.Namespace) -> int:
    """Handler of ``railmodal lab diagnose`` (see :func:`add_diagnose_parser`)."""
    # the library is imported by the handler, not at start-up: every other command would pay for it
    from receptance.diagnosis.workflow import SetupFiles

    parser = args._diagnose_parser
    data, channels = list(args.setup_data or []), list(args.channels or [])
    if not data:
        parser.error("give each setup's data: --hammer (time histories) or --frf (exported FRFs), with its --channels")
    if len(data) != len(channels):
        hammers = sum(1 for k, _ in data if k == "hammer")
        frfs = len(data) - hammers
        parser.error(f"each --hammer or --frf needs its --channels (in the same order): got {hammers} --hammer, "
                     f"{frfs} --frf and {len(channels)} --channels")
    if len(data) > MAX_SETUP_OPTIONS:
        parser.error(f"at most {MAX_SETUP_OPTIONS} setups, got {len(data)}")
    setups = [SetupFiles(channels=c, **{kind: path}) for (kind, path), c in zip(data, channels)]
    t0 = time.perf_counter()
    result = run_staged(setups, Path(args.fem), Path(args.points), Path(args.out), band_hz=tuple(args.band),
                        max_effects=args.max_effects, max_order=args.max_order, mac_min=args.mac_min,
                        description=args.description, n_averages=args.averages, frf_window_decay=args.window_decay,
                        workers=args.workers, geometry=args.geometry, total_mass=args.total_mass,
                        fe_units=args.fe_units, mode_margin=args.mode_margin,
                        progress=_progress_printer(args.quiet))
    for line in summarise(result):
        print(line)
    print(f"done in {time.perf_counter() - t0:.1f} s")
    return 0


def add_diagnose_parser(lab_subparsers) -> argparse.ArgumentParser:
    """Register ``railmodal lab diagnose`` on the ``lab`` subparsers; returns its parser."""
    from ema.limits import MAX_ORDER

    d = lab_subparsers.add_parser(
        "diagnose", help="hammer tests or FRF files + FE export -> identify, pair, hybrid model, compare, diagnose; "
                         "diagnosis.json, report.html and the diagnosed model",
        description="Identify the modes of every setup, pair them with the FE modes, build the hybrid model, "
                    "compare it with the measured FRFs, find the missing physical effects one by one, and write "
                    "diagnosis.json, a self-contained report.html (figures also as PNG in figures/) and the "
                    "diagnosed model hybrid_model.npz into --out.")
    d.add_argument("--hammer", action=_SetupData, nargs="+",
                   type=existing_file("--hammer", "hammer-test (UFF58, MDF, TDMS or CSV)"),
                   metavar="FILE",
                   help="UFF58 hammer-test time histories (or a data logger's MDF or NI TDMS recording, or a DAQ's "
                        "wide CSV export) of one setup (repeat "
                        "per setup, each with its --channels); "
                        "several files after one --hammer are the hits of one setup stored one (or a few) per file")
    d.add_argument("--frf", action=_SetupData, type=existing_file("--frf", "FRF (UFF58)"),
                   help="UFF58 FRFs of one setup as a commercial system exports them (function type 4, "
                        "accelerance/mobility/receptance, ASCII or binary, coherence (type 6) optional); in place "
                        "of --hammer")
    d.add_argument("--channels", action="append", type=existing_file("--channels", "channel table"),
                   help="channel table CSV of the preceding --hammer or --frf file")
    d.add_argument("--fem", required=True, type=existing_file("--fem", "FE modes"),
                   help="FE modes file (UFF 2411/2412 with 55 or 2414, Nastran .pch, .f06, .op2 or .h5, an ANSYS "
                        ".rst or a CalculiX .frd)")
    add_geometry_argument(d)
    d.add_argument("--total-mass", type=bounded_float("--total-mass", 0.0, 1e6, lo_open=True, unit="kg"),
                   default=None, help="the exported wheelset's mass [kg] to check the FE shapes' mass normalisation "
                                      "against (default: the physical range of a railway wheelset)")
    d.add_argument("--points", required=True, type=existing_file("--points", "points table"),
                   help="points table CSV: name, fe_node, x, y, z")
    d.add_argument("--description", type=existing_file("--description", "wheelset description (TOML)"),
                   default=None, help="wheelset description (TOML): axlebox and wheel masses, where the wheelset "
                                      "hung... (default: thesis Table 2.1 values; see README)")
    d.add_argument("--out", required=True, type=output_folder("--out"), help="output folder")
    d.add_argument("--band", nargs=2, type=bounded_float("--band", 0.0, 1e5, lo_open=True, unit="Hz"),
                   action=band_action("--band", 0.0, 1e5), default=[10.0, 500.0], metavar=("LOW", "HIGH"),
                   help="identification, comparison and diagnosis band [Hz]: its octaves are the cells of the error "
                        "E, its noise floor and every fit (default 10 500; a wheelset hung from soft slings shows "
                        "its rig modes only from a few Hz, e.g. 4 500, where the records resolve it)")
    d.add_argument("--mode-margin", type=bounded_float("--mode-margin", 1.0, 4.0), default=1.0,
                   help="the model keeps the modes up to this multiple of the band's top, 1-4 (default 1; a real "
                        "wheelset's modes just above the band are in its measurement: 1.5 keeps them)")
    d.add_argument("--max-effects", type=bounded_int("--max-effects", 0, 10), default=3,
                   help="most effects accepted one after the other, 0-10 (default 3)")
    d.add_argument("--max-order", type=bounded_int("--max-order", 1, MAX_ORDER), default=100,
                   help=f"largest LSCE order, 1 to {MAX_ORDER} (default 100)")
    d.add_argument("--mac-min", type=bounded_float("--mac-min", 0.0, 1.0, lo_open=True), default=0.8,
                   help="smallest MAC of a test-FE pair, in (0, 1] (default 0.8)")
    d.add_argument("--averages", type=bounded_int("--averages", 2, 10000), default=None,
                   help="number of averages behind the coherence of --frf files (default: estimated)")
    d.add_argument("--window-decay", type=bounded_float("--window-decay", 0.0, 1000.0, unit="1/s"), default=None,
                   help="exponential-window decay of --frf files [1/s] (default: the file's note in ID line 3, "
                        "else none: the damping is taken as exported, with a WARNING)")
    d.add_argument("--workers", type=bounded_int("--workers", 1, 64), default=None,
                   help="parallel processes fitting the candidates (default: the usable cores)")
    d.set_defaults(func=cmd_diagnose, _diagnose_parser=d, setup_data=None)
    return d
