"""A trolley survey calibrates the estimator; months of runs monitored with it (issues 14 and 15 together).

The practitioner's loop on the virtual line's growth campaign (5 survey days × 2 runs over 8 weeks, 400-800 m;
the corrugated low rail R on 500-680 m grows, ground on 460-720 m between the 4th and 5th day): the field
diagnosis is run at the site with the trolley of the first day (calibration) and of the last day before the
grinding (validation); the calibrated model it saves is given to the monitoring ingest of every run, beside
an ingest with the nominal model. The oracles are the line's truth: its curving law for the fitted angles
(tests/curving_truth.py), each day's true rails through the same EN 13231-3 code and the truth's crossing date
of the forecast threshold (tests/monitor_truth.py).

Measured (control wheelset as the lab workflow saves it, FE to 2 kHz; eq. 2.32 track): the one effect accepted
is curve C1's leading-wheelset contact angles (γ_L 5.3°, γ_R 0.8°; the line's law 3.9° / 1.0°, the default
1.43°). On the three days the calibration did not see, the daily level errors of the patch (2 rails × 2 bands)
fall from RMS 0.63 dB (worst +1.36) to 0.30 dB (worst −0.57); the 30-100 mm forecast made before the grinding
from −19.5 % to −9.8 % of its horizon. The 100-300 mm forecast is not asserted: with the eq. 2.32 track it
stays late (+93 %): the band's error at the corrugation's frequency weighs more as the corrugation grows
(−0.24 → −0.68 dB from day 1 to day 4), so the fitted growth is low. The track's frequency-dependent pad
stiffness fixes it (README, issue 14's table); calibrated on day 4 instead, the diagnosis's line-wide
trackform candidate that carries it lowers E by 8 % (1.33 → 1.22 dB), short of the 10 % its criterion asks.
"""

from __future__ import annotations

import logging

import numpy as np
import pandas as pd
import pytest

from curving_truth import assert_everyday_curve_angles

pytestmark = pytest.mark.slow

GROWTH = dict(days=5, runs_per_day=2, section=(400.0, 800.0), span_days=56, grinding_after_day=4)
SITE = (400.0, 800.0)
PATCH_BODY = (510.0, 670.0)  # the corrugation patch C1_low (rail R, 500-680 m) without its 10 m tapers
THRESHOLD_30_100_UM = 45.0


@pytest.fixture(scope="module")
def months(tmp_path_factory):
    from lab_data.line.cache import line_campaign_dir
    from monitor_truth import truth_json
    from receptance.model_io import save_model
    from test_estimator_synthetic import lab_workflow_model

    from estimator.config import EstimatorConfig
    from estimator.diagnosis import DiagnosisConfig, run_field_diagnosis
    from estimator.diagnosis.calibration import save_calibration
    from estimator.monitoring import IngestSpec, MonitoringConfig, MonitoringStore, ingest, monitor

    camp = line_campaign_dir("nominal", **GROWTH)
    dates = sorted(p.name for p in (camp / "runs").iterdir() if p.is_dir())
    cal_day, val_day = dates[0], truth_json(camp)["grinding"]["last_day_before"]
    work = tmp_path_factory.mktemp("field_calibration_months")
    model = work / "hybrid_model.npz"
    save_model(lab_workflow_model(), model)
    logging.getLogger("estimator").setLevel(logging.ERROR)
    diag = run_field_diagnosis([str(p) for d in (cal_day, val_day) for p in sorted((camp / "runs" / d).glob("*.mf4"))],
                               [str(camp / "trolley" / f"{d}.csv") for d in (cal_day, val_day)], SITE, str(model),
                               str(camp / "sensors.csv"), line=str(camp / "line.json"),
                               config=DiagnosisConfig(workers=2), estimator_config=EstimatorConfig(wheelbase_m=2.1),
                               calibration_date=cal_day)
    save_calibration(work / "calibrated_model", model, diag.state, site=SITE, date=cal_day)
    cfg = MonitoringConfig(n_perturbed=0, uncertainty_runs=0, thresholds_um={"30-100": THRESHOLD_30_100_UM})
    runs = sorted((camp / "runs").rglob("*.mf4"))
    monitored = {}
    for name, cal in (("nominal", None), ("calibrated", str(work / "calibrated_model"))):
        spec = IngestSpec(str(model), str(camp / "sensors.csv"), line=str(camp / "line.json"), monitoring=cfg,
                          calibration=cal)
        st = MonitoringStore(work / name)
        res = ingest(runs, spec, st)
        assert res.failures.empty, res.failures
        monitored[name] = (res, monitor(st, line_file=camp / "line.json", cfg=cfg),
                           monitor(st, line_file=camp / "line.json", cfg=cfg, as_of=val_day))
    return camp, (cal_day, val_day), diag, monitored


def _daily_errors(camp, m, dates) -> pd.DataFrame:
    """Day average − truth [dB] of the patch body's band level, per day, rail and band (energy means)."""
    from monitor_truth import truth_windows

    from estimator.monitoring.averaging import energy_mean_db

    rows = []
    dw = m.day_windows
    for d in dates:
        t = truth_windows(camp, d)
        for rail in ("L", "R"):
            for band in ("30-100", "100-300"):
                tt = t[(t["rail"] == rail) & (t["band_mm"] == band)
                       & t["window_m"].between(PATCH_BODY[0], PATCH_BODY[1] - 1)]
                e = dw[(dw["date"] == d) & (dw["rail"] == rail) & (dw["band_mm"] == band)
                       & dw["window_m"].isin(tt["window_m"])]
                assert len(e) > 100, (d, rail, band, len(e))
                rows.append({"date": d, "rail": rail, "band_mm": band,
                             "error_db": energy_mean_db(e["level_db"])
                             - energy_mean_db(tt[tt["window_m"].isin(e["window_m"])]["level_db"])})
    return pd.DataFrame(rows)


def test_the_trolley_day_calibrates_the_leading_wheelsets_curve_angles(months):
    """The one effect accepted at the site is the everyday one the estimator's first-order curving leaves out,
    fitted closer to the line's own law than the default on both rails; the calibrated model is versioned."""
    camp, _, diag, monitored = months
    assert len(diag.diagnosis.accepted) == 1, diag.diagnosis.verdict
    assert_everyday_curve_angles(camp, diag.diagnosis.accepted[0])
    nominal, calibrated = (monitored[k][0].model_hash for k in ("nominal", "calibrated"))
    assert calibrated.startswith(nominal + "+cal"), (nominal, calibrated)


def test_the_calibration_lowers_the_level_error_on_the_days_it_did_not_see(months):
    """Days 2, 3 and 5 (the last after the grinding) are neither the calibration's nor the validation's: their
    patch levels (2 rails × 2 bands) with the calibrated model are within ±1 dB of the truth, and their RMS error
    falls by at least 30 % against the nominal model's (measured 0.63 → 0.30 dB)."""
    camp, used, _, monitored = months
    unseen = [d for d in monitored["nominal"][0].dates if d not in used]
    assert len(unseen) == 3
    before = _daily_errors(camp, monitored["nominal"][1], unseen)["error_db"].to_numpy()
    after = _daily_errors(camp, monitored["calibrated"][1], unseen)["error_db"].to_numpy()
    rms = lambda e: float(np.sqrt(np.mean(e ** 2)))  # noqa: E731
    assert np.all(np.abs(after) <= 1.0), after
    assert rms(after) <= 0.7 * rms(before), (rms(before), rms(after))


def test_the_calibrated_months_find_the_grinding_and_forecast_the_30_100_mm_crossing(months):
    """With the calibrated model: the grinding found between the right survey days on the ground stretch (within
    the detection's 20 m resolution) and nowhere else; the 30-100 mm threshold crossing of the corrugated rail R
    on curve 1, forecast on the last day before the grinding, within ±20 % of its horizon from the truth's date
    (the rails regenerated without the grinding; measured −9.8 %)."""
    from monitor_truth import crossing_date, truth_json

    camp, (_, as_of), _, monitored = months
    _, m, mf = monitored["calibrated"]
    g = truth_json(camp)["grinding"]
    assert len(m.grinding) == 1
    e = m.grinding.iloc[0]
    assert (e["date_before"], e["date_after"]) == (g["last_day_before"], g["first_day_after"])
    a, b = next((a, b) for a, b in g["sections_m"] if a < SITE[1] and b > SITE[0])
    assert abs(e["from_m"] - a) <= 20.0 and abs(e["to_m"] - b) <= 20.0
    fc = mf.forecast[(mf.forecast["section"] == "curve_1") & (mf.forecast["rail"] == "R")
                     & (mf.forecast["band_mm"] == "30-100")]
    assert len(fc) == 1 and fc["crossing_date"].iloc[0]
    true = crossing_date(camp, m.sections.extent("curve_1"), "R", "30-100", THRESHOLD_30_100_UM, as_of)
    horizon = (pd.Timestamp(true) - pd.Timestamp(as_of)).days
    err = (pd.Timestamp(fc["crossing_date"].iloc[0]) - pd.Timestamp(true)).days
    assert horizon > 14 and abs(err) <= 0.2 * horizon, (fc.iloc[0].to_dict(), true, err, horizon)
