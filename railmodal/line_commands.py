"""``railmodal lab simulate-line``: write a virtual-line campaign (MDF4 runs, sensor table, line, trolley, truth).

The command validates every argument before any work (bounded sizes, a
section inside the station-to-station run, known scenarios), simulates into a
temporary folder beside ``--out`` and renames it only when the campaign is
complete; progress goes to stderr, the summary to stdout.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from railmodal.arguments import band_action, bounded_float, bounded_int, output_folder
from railmodal.output import staged_output

__all__ = ["add_line_commands", "summarise_campaign"]


def _progress(msg: str) -> None:
    print(f"  … {msg}", file=sys.stderr, flush=True)


def _field_scenarios() -> dict:
    from lab_data.line.scenarios import FIELD_SCENARIOS

    return FIELD_SCENARIOS


def _wheelset_scenarios() -> list[str]:
    from lab_data.scenarios import SCENARIOS

    return sorted(SCENARIOS)


def summarise_campaign(folder: Path) -> list[str]:
    """Lines describing a written campaign folder (files, days, grinding, trolley, faults)."""
    truth = json.loads((folder / "truth" / "truth.json").read_text())
    runs = truth["runs"]
    size = sum(p.stat().st_size for p in folder.rglob("*") if p.is_file())
    lines = [f"campaign {folder}: {len(runs)} runs over {len(truth['days'])} day(s), "
             f"{size / 1e6:.1f} MB",
             f"scenario {truth['scenario']['name']}: {truth['scenario']['description']}; wheelsets: lab scenario "
             f"{truth['wheelset_scenario']!r}"]
    g = truth["grinding"]
    if g:
        lines.append(f"grinding on {g['date']} (between survey days {g['last_day_before']} and "
                     f"{g['first_day_after']}), sections {g['sections_m']} m")
    lines.append(f"trolley days: {', '.join(truth['trolley']['dates']) or 'none'}")
    for r in runs:
        faults = [f"dropout {d['kind']} on {d['channel']}" for d in r["dropouts"]]
        faults += sorted({f"clipping on {c['channel']}" for c in r["clipped"]})
        lines.append(f"  {r['file']}: {r['direction']}, wheelset {r['leading_wheelset']} leads, "
                     f"{r['chainage_range_m'][0]:.0f} -> {r['chainage_range_m'][1]:.0f} m, {r['samples']} samples"
                     + (f"; {', '.join(faults)}" if faults else ""))
    return lines


def _cmd_simulate_line(args: argparse.Namespace) -> int:
    from lab_data.line.campaign import LineCampaignConfig, plan_line_campaign, write_line_campaign

    config = LineCampaignConfig(scenario=args.scenario, days=args.days, runs_per_day=args.runs_per_day,
                                section=tuple(args.section) if args.section else None,
                                wheelset_scenario=args.wheelset_scenario, seed=args.seed, fs=args.fs)
    plan = plan_line_campaign(config)  # validated: nothing is written if the configuration is refused
    t0 = time.perf_counter()
    step = None if args.quiet else _progress
    with staged_output(args.out) as tmp:
        write_line_campaign(plan, tmp, progress=step, workers=args.workers)
    for line in summarise_campaign(Path(args.out)):
        print(line)
    print(f"done in {time.perf_counter() - t0:.1f} s")
    return 0


def add_line_commands(lab_sub) -> None:
    """Add ``simulate-line`` to the ``railmodal lab`` sub-commands."""
    from lab_data.line.geometry import default_line

    line = default_line()
    lo, hi = line.stations[0].chainage_m, line.stations[-1].chainage_m
    scenarios = _field_scenarios()
    p = lab_sub.add_parser(
        "simulate-line", help="write a virtual-line campaign: MDF4 runs, sensors.csv, line.json, trolley, truth",
        description="Simulate the instrumented bogie over the virtual line for DAYS x RUNS-PER-DAY runs. Field "
                    "scenarios: " + "; ".join(f"{k}: {v.description}" for k, v in scenarios.items()),
    )
    p.add_argument("--scenario", required=True, choices=sorted(scenarios), help="field scenario")
    p.add_argument("--days", type=bounded_int("--days", 1, 30), default=10, help="survey days (default 10)")
    p.add_argument("--runs-per-day", type=bounded_int("--runs-per-day", 1, 12), default=7,
                   help="runs per day, alternating forward/backward (default 7)")
    p.add_argument("--out", required=True, type=output_folder("--out"), help="campaign folder")
    p.add_argument("--section", nargs=2, type=bounded_float("--section", lo, hi, unit="m"), default=None,
                   metavar=("FROM", "TO"), action=band_action("--section", lo, hi, unit="m"),
                   help=f"simulate only this stretch of the {lo:g}-{hi:g} m run (at least 50 m)")
    p.add_argument("--wheelset-scenario", default="control", choices=_wheelset_scenarios(),
                   help="virtual-lab scenario whose as-built wheelsets run on the line (default control)")
    p.add_argument("--seed", type=bounded_int("--seed", 0, 2**31 - 1), default=2022, help="random seed")
    p.add_argument("--fs", type=bounded_float("--fs", 200.0, 5000.0, unit="Hz"), default=1000.0,
                   help="acceleration sampling rate (default 1000 Hz)")
    p.add_argument("--workers", type=bounded_int("--workers", 1, 64), default=None,
                   help="parallel runs (default: the local cores)")
    p.set_defaults(func=_cmd_simulate_line)
