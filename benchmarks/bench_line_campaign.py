"""Benchmark: a virtual-line campaign of 10 days x 7 full runs on the local cores, then its cached re-access.

Goal (issue 12): the 10 x 7 campaign in <= 15 min on 2 cores, cached after.
The campaign is generated through :func:`lab_data.line.cache.line_campaign_dir`
into a temporary cache root (``--keep`` uses ``$RAILMODAL_CACHE`` instead, so
the campaign stays for later use), so the figure includes everything a first
call costs: the vehicle's modal model, the rails, every run, the trolley
files and the truth. The per-run dynamics is benchmarked on its own by
``bench_line_simulate.py``.

    python benchmarks/bench_line_campaign.py [--days 10] [--runs-per-day 7] [--workers 2] [--keep]
"""

from __future__ import annotations

import _checkout  # noqa: F401  (this checkout's packages first: measure the code beside this script)
import argparse
import json
import os
import re
import shutil
import sys
import tempfile
import time
from pathlib import Path

GOAL_S = 15 * 60.0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--days", type=int, default=10)
    ap.add_argument("--runs-per-day", type=int, default=7)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--scenario", default="nominal")
    ap.add_argument("--keep", action="store_true", help="generate into $RAILMODAL_CACHE and keep it")
    args = ap.parse_args(argv)

    tmp = None
    if not args.keep:
        tmp = tempfile.mkdtemp(prefix="railmodal-bench-line-")
        os.environ["RAILMODAL_CACHE"] = tmp
    from lab_data.line.cache import line_campaign_dir

    marks: dict[str, float] = {}
    run_cpu: list[float] = []

    def progress(msg: str) -> None:
        now = time.perf_counter() - t0
        for key in ("simulating", "writing the trolley"):
            if msg.startswith(key):
                marks[key] = now
        cpu = re.search(r"\(cpu ([0-9.]+) s\)", msg)
        if cpu:
            run_cpu.append(float(cpu.group(1)))
        print(f"  [{now:7.1f} s] {msg}", file=sys.stderr, flush=True)

    try:
        t0 = time.perf_counter()
        folder = line_campaign_dir(args.scenario, days=args.days, runs_per_day=args.runs_per_day,
                                   workers=args.workers, progress=progress)
        first = time.perf_counter() - t0
        t1 = time.perf_counter()
        line_campaign_dir(args.scenario, days=args.days, runs_per_day=args.runs_per_day, workers=args.workers)
        cached = time.perf_counter() - t1
        truth = json.loads((folder / "truth" / "truth.json").read_text())
        runs = truth["runs"]
        travel = sum(r["record_window_run_s"][1] - r["record_window_run_s"][0] for r in runs)
        size = sum(p.stat().st_size for p in Path(folder).rglob("*") if p.is_file())
        n = len(runs)
        print(f"virtual-line campaign: {args.days} days x {args.runs_per_day} runs = {n} runs, "
              f"{travel / 60:.1f} min of recorded travel, {size / 1e6:.0f} MB, {args.workers} worker(s)")
        print(f"{'':28s}{'measured':>12s}{'goal':>12s}")
        print(f"{'campaign, first call':28s}{first:11.1f}s{GOAL_S * args.days * args.runs_per_day / 70:11.0f}s"
              f"   ({'met' if first <= GOAL_S * n / 70 else 'NOT met'}; goal scaled to {n} runs)")
        print(f"{'per run (wall / workers)':28s}{first / n:11.2f}s{GOAL_S / 70:11.2f}s")
        print(f"{'per run (core seconds)':28s}{first * args.workers / n:11.2f}s")
        setup = marks.get("simulating", 0.0)
        runs_wall = marks.get("writing the trolley", first) - setup
        print(f"{'  setup (rails, vehicle)':28s}{setup:11.1f}s   (once per campaign; the wheelset FE is cached "
              f"across campaigns)")
        print(f"{'  runs':28s}{runs_wall:11.1f}s   ({runs_wall * args.workers / n:.1f} core s per run)")
        if run_cpu:
            cpu = sum(run_cpu) / len(run_cpu)
            print(f"{'  CPU per run (process)':28s}{cpu:11.1f}s   (independent of other load; 70 runs on "
                  f"{args.workers} free cores: {70 * cpu / args.workers / 60:.1f} min + setup)")
        print(f"{'  trolley + truth':28s}{first - setup - runs_wall:11.1f}s")
        if n != 70:
            est = setup + (first - setup - runs_wall) * 10 / args.days + runs_wall * 70 / n
            print(f"{'10 x 7, extrapolated':28s}{est:11.0f}s{GOAL_S:11.0f}s   (setup + 70 runs at the measured "
                  f"per-run cost + 10 days of truth, {args.workers} worker(s))")
        print(f"{'cached, second call':28s}{cached:11.3f}s")
        print(f"{'real time / simulated':28s}{first * args.workers / travel:11.3f}x  (core seconds per second of run)")
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
