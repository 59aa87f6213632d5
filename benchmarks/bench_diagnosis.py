"""Benchmark: the whole lab diagnosis of one virtual-lab campaign, for both design-FE export styles.

Goals (issue 10): the whole ``railmodal lab diagnose`` of one campaign within 60 s on 2 cores, for the lab's
mesh-style FE and a design office's beam-style FE; and, because machines differ, a ratio measured in the same
run: the diagnosis stage costs at most 3 x the identification of the same campaign. Times, per campaign, the full
workflow (read the hammer files, screen, H1, LSCE/LSFD identification of both setups, pairing, hybrid model,
compare, diagnose, figures, report, saved model) stage by stage, the cores the candidates' fits used, and the
seconds of every candidate in every round. No peer tool does this diagnosis; the references are the issue's
budgets.

    python benchmarks/bench_diagnosis.py [scenario[:style] ...]      (default: rig bearing rig:beam bearing:beam)
"""

from __future__ import annotations

import _checkout  # noqa: F401  (this checkout's packages first: measure the code beside this script)
import os
import sys
import tempfile
import time
from pathlib import Path

from lab_data.cache import campaign_dir
from receptance.diagnosis.diagnose import usable_cores
from receptance.diagnosis.workflow import run_lab_diagnosis

GOAL_S = 60.0
GOAL_RATIO = 3.0


def main(cases: list[str]) -> None:
    print(f"usable cores: {usable_cores()} (os.cpu_count() = {os.cpu_count()}); load average "
          f"{' '.join(f'{v:.2f}' for v in os.getloadavg())}")
    print(f"{'campaign':<18} {'total s':>8} {'goal s':>7} {'identify s':>11} {'diagnose s':>11} {'ratio':>6} "
          f"{'goal':>5} {'workers':>8}")
    for case in cases:
        name, _, style = case.partition(":")
        style = style or "mesh"
        config = {"fe_export_hz": 2000.0} if style == "mesh" else {"fe_export_hz": 2000.0, "fe_style": style}
        folder = campaign_dir(name, **config)  # generated (and cached) outside the timing
        setups = [(folder / f"{s}.uff", folder / f"{s}_channels.csv") for s in ("flexural", "torsional")]
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            result = run_lab_diagnosis(setups, folder / "fe_design.uff", folder / "points.csv", Path(tmp) / "out")
            total = time.perf_counter() - t0
        t = result.timings_s
        ratio = t["diagnose"] / t["identify"]
        d = result.diagnosis
        label = f"{name} ({style})"
        print(f"{label:<18} {total:8.1f} {GOAL_S:7.0f} {t['identify']:11.1f} {t['diagnose']:11.1f} {ratio:6.2f} "
              f"{GOAL_RATIO:5.1f} {d.workers:8d}")
        accepted = [f.name for f in d.accepted] or ["nothing"]
        verdict = ("meets" if total <= GOAL_S else "MISSES") + " the 60 s goal; " + (
            "meets" if ratio <= GOAL_RATIO else "MISSES") + " the 3x ratio"
        print(f"{'':<18} accepted: {', '.join(accepted)}; {verdict}")
        print(f"{'':<18} stages (s): " + ", ".join(f"{k} {v:.1f}" for k, v in t.items()))
        for k, secs in enumerate(d.seconds, 1):
            print(f"{'':<18} round {k} candidates (s): "
                  + ", ".join(f"{n} {v:.1f}" for n, v in sorted(secs.items(), key=lambda kv: -kv[1])))


if __name__ == "__main__":
    main(sys.argv[1:] or ["rig", "bearing", "rig:beam", "bearing:beam"])
