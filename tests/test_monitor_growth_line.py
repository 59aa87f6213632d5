"""Months of a line on the virtual line (issue 14's growth acceptance, short version): days, grinding, wheelbase.

Five survey days of two runs over eight weeks on the stretch around curve 1 (400–800 m; the corrugated low rail R
on 500–680 m grows linearly, truth.json ``corrugation_growth``), ground (460–720 m) between the 4th and 5th day.
The oracles are the line's truth: each day's true rail roughness processed by the same EN 13231-3 code
(tests/monitor_truth.py), the truth's grinding date and sections, and the vehicle's true wheelbase.
"""

from __future__ import annotations

import logging

import numpy as np
import pytest

from test_estimator_synthetic import control_model

pytestmark = pytest.mark.slow

GROWTH = dict(days=5, runs_per_day=2, section=(400.0, 800.0), span_days=56, grinding_after_day=4)
PATCH_BODY = (510.0, 670.0)  # the corrugation patch C1_low (rail R, 500-680 m) without its 10 m tapers


@pytest.fixture(scope="module")
def growth_store(tmp_path_factory):
    from lab_data.line.cache import line_campaign_dir
    from receptance.model_io import save_model

    from estimator.monitoring import IngestSpec, MonitoringConfig, MonitoringStore, ingest, monitor

    camp = line_campaign_dir("nominal", **GROWTH)
    d = tmp_path_factory.mktemp("growth_monitor")
    save_model(control_model(), d / "hybrid_model.npz")
    cfg = MonitoringConfig(n_perturbed=0, uncertainty_runs=0)
    spec = IngestSpec(str(d / "hybrid_model.npz"), str(camp / "sensors.csv"), line=str(camp / "line.json"),
                      monitoring=cfg)
    logging.getLogger("estimator").setLevel(logging.ERROR)
    st = MonitoringStore(d / "store")
    res = ingest(sorted((camp / "runs").rglob("*.mf4")), spec, st)
    return camp, res, monitor(st, line_file=camp / "line.json", cfg=cfg)


def test_every_run_is_processed_with_the_vehicles_wheelbase(growth_store):
    from monitor_truth import truth_json

    camp, res, m = growth_store
    assert res.failures.empty and len(res.runs) == 10 and res.runs["aligned"].all()
    assert np.all(np.abs(res.runs["wheelbase_m"] - truth_json(camp)["vehicle"]["wheelbase_m"]) <= 0.005)


def test_each_days_level_of_the_corrugated_rail_is_the_truths_within_1_5_db(growth_store):
    from monitor_truth import truth_windows

    from estimator.monitoring.averaging import energy_mean_db

    camp, res, m = growth_store
    dw = m.day_windows
    assert len(res.dates) == 5
    for d in res.dates:
        t = truth_windows(camp, d)
        for band in ("30-100", "100-300"):
            tt = t[(t["rail"] == "R") & (t["band_mm"] == band) & t["window_m"].between(PATCH_BODY[0], PATCH_BODY[1] - 1)]
            e = dw[(dw["date"] == d) & (dw["rail"] == "R") & (dw["band_mm"] == band) & dw["window_m"].isin(tt["window_m"])]
            assert len(e) > 100
            err = energy_mean_db(e["level_db"]) - energy_mean_db(tt[tt["window_m"].isin(e["window_m"])]["level_db"])
            assert abs(err) <= 1.5, (d, band, err)


def test_the_grinding_is_found_between_the_right_days_in_the_right_place_and_nowhere_else(growth_store):
    from monitor_truth import truth_json

    camp, res, m = growth_store
    g = truth_json(camp)["grinding"]
    ev = m.grinding
    assert len(ev) == 1
    e = ev.iloc[0]
    assert (e["date_before"], e["date_after"]) == (g["last_day_before"], g["first_day_after"])
    a, b = next((a, b) for a, b in g["sections_m"] if a < 800 and b > 400)
    # the detection's chainage resolution is its minimum stretch (grinding_min_length_m, 20 m)
    assert abs(e["from_m"] - a) <= 20.0 and abs(e["to_m"] - b) <= 20.0
