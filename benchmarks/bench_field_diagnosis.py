"""Benchmark: one field diagnosis of a calibration site on the virtual line (issue 15: ≤ 60 s on 2 cores).

Runs :func:`estimator.diagnosis.run_field_diagnosis` on the ``nominal`` virtual-line campaign (2 days × 2 runs over
the first-curve section 400–800 m, the whole catalogue) and prints, side by side, the time of each stage and
the target; and what the same search would cost without the precomputed evidence (every candidate evaluation
a full :func:`estimator.estimate_run` of every run: evaluations × one estimate).

    python benchmarks/bench_field_diagnosis.py [SCENARIO] [--fe-export-hz 2000|none]

``--fe-export-hz`` picks the wheelset model: the control wheelset's lab model from a design FE exported to that
frequency with every FE mode kept (default 2000, as ``railmodal lab diagnose`` saves it), or ``none`` for the
test band's 500 Hz model.
"""

from __future__ import annotations

import _checkout  # noqa: F401  (this checkout's packages first: measure the code beside this script)
import glob
import os
import time
from pathlib import Path


TARGET_S = 60.0


def main(scenario: str = "nominal", fe_export_hz: float | None = 2000.0) -> None:
    from estimator.config import EstimatorConfig
    from estimator.diagnosis import DiagnosisConfig, run_field_diagnosis
    from lab_data.line.cache import line_campaign_dir
    from lab_data.line.campaign import FIRST_CURVE_SECTION
    from receptance import save_model
    from test_estimator_synthetic import control_model, lab_workflow_model

    d = line_campaign_dir(scenario, days=2, runs_per_day=2, section=FIRST_CURVE_SECTION)
    tag = "500Hz" if fe_export_hz is None else f"fe_{fe_export_hz:g}Hz"
    model = Path(os.environ.get("TMPDIR", "/tmp")) / f"bench_field_diagnosis_model_{tag}.npz"
    save_model(control_model() if fe_export_hz is None else lab_workflow_model(fe_export_hz), model)
    runs = sorted(glob.glob(f"{d}/runs/*/*.mf4"))
    t0 = time.perf_counter()
    res = run_field_diagnosis(runs, sorted(glob.glob(f"{d}/trolley/*.csv")), FIRST_CURVE_SECTION, model,
                              f"{d}/sensors.csv", line=f"{d}/line.json", config=DiagnosisConfig(workers=2),
                              estimator_config=EstimatorConfig(wheelbase_m=2.1))
    total = time.perf_counter() - t0
    t = res.timings_s
    n_cand = sum(len(r) for r in res.diagnosis.rounds)
    one_estimate = t["estimate_nominal"] / len(runs)
    # grid + Nelder–Mead + curvature + undetermined + validation: about 45 evaluations per candidate
    naive = n_cand * 45 * len(runs) * one_estimate
    print(f"field diagnosis, scenario {scenario}, site {FIRST_CURVE_SECTION[0]:g}-{FIRST_CURVE_SECTION[1]:g} m, "
          f"{len(runs)} runs, {n_cand} candidate fits, 2 workers, wheelset model {tag}")
    print(f"{'stage':34s}{'seconds':>10s}")
    for k in ("estimate_nominal", "align", "evidence", "diagnose", "compare"):
        print(f"{k:34s}{t.get(k, float('nan')):10.1f}")
    print(f"{'whole command (library call)':34s}{total:10.1f}   target {TARGET_S:.0f} s")
    print(f"{'diagnosis proper (evidence + fit)':34s}{t['evidence'] + t['diagnose']:10.1f}   target {TARGET_S:.0f} s")
    print(f"{'without precomputed evidence (est.)':34s}{naive:10.0f}   ({n_cand} fits × ~45 evaluations × "
          f"{len(runs)} runs × {one_estimate:.1f} s per estimate)")
    print(res.diagnosis.verdict)


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenario", nargs="?", default="nominal")
    ap.add_argument("--fe-export-hz", default="2000", help="design FE export frequency [Hz], or 'none'")
    a = ap.parse_args()
    main(a.scenario, None if a.fe_export_hz.lower() == "none" else float(a.fe_export_hz))
