"""Benchmark: the whole lab diagnosis of one virtual-lab campaign (issue 5 goal: under a minute on 2 cores).

Times, per scenario, the full ``railmodal lab diagnose`` workflow (read the hammer files, screen, H1,
LSCE identification of both setups, pairing, hybrid model, compare, diagnose, figures and report) and its
stages, next to the goal.  No peer tool does this diagnosis; the reference is the issue's one-minute budget.

    python benchmarks/bench_diagnosis.py [scenario ...]      (default: rig bearing)
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

from lab_data.cache import campaign_dir
from railmodal.diagnose_command import run_lab_diagnosis

GOAL_S = 60.0


def main(scenarios: list[str]) -> None:
    print(f"{'scenario':<12} {'total s':>8} {'goal s':>7}  stages (s)")
    for name in scenarios:
        folder = campaign_dir(name, fe_export_hz=2000.0)  # generated (and cached) outside the timing
        setups = [(folder / f"{s}.uff", folder / f"{s}_channels.csv") for s in ("flexural", "torsional")]
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            result = run_lab_diagnosis(setups, folder / "fe_design.uff", folder / "points.csv", Path(tmp))
            total = time.perf_counter() - t0
        stages = ", ".join(f"{k} {v:.1f}" for k, v in result.timings_s.items())
        accepted = [f.name for f in result.diagnosis.accepted] or ["nothing"]
        print(f"{name:<12} {total:8.1f} {GOAL_S:7.0f}  {stages}")
        print(f"{'':<12} accepted: {', '.join(accepted)}; {'meets' if total < GOAL_S else 'MISSES'} the goal")


if __name__ == "__main__":
    main(sys.argv[1:] or ["rig", "bearing"])
