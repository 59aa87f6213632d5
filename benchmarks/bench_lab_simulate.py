"""Wall time of `railmodal lab simulate` for every scenario (goal: under a minute each on 2 cores).

Run: python benchmarks/bench_lab_simulate.py
Prints, per scenario, the time to solve the models and plan the campaign,
the time to synthesise and write all files, and the total.
"""

import _checkout  # noqa: F401  (this checkout's packages first: measure the code beside this script)
import tempfile
import time

from lab_data.campaign import CampaignConfig, plan_campaign, write_campaign
from lab_data.scenarios import SCENARIOS


def main() -> None:
    print(f"{'scenario':12s} {'plan [s]':>9s} {'write [s]':>10s} {'total [s]':>10s} {'truth modes':>12s}")
    for name in sorted(SCENARIOS):
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            plan = plan_campaign(CampaignConfig(scenario=name))
            t1 = time.perf_counter()
            write_campaign(plan, tmp, progress=lambda m: None)
            t2 = time.perf_counter()
        print(f"{name:12s} {t1 - t0:9.2f} {t2 - t1:10.2f} {t2 - t0:10.2f} {len(plan.truth.modes.freqs_hz):12d}")


if __name__ == "__main__":
    main()
