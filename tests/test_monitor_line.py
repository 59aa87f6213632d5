"""Monitoring on the virtual line (issue 14's acceptance, short version): alignment against the true chainage,
the day average of the corrugated curve against the true roughness.

One survey day of four runs on the stretch around curve 1 (400–800 m, the corrugated low rail R on 500–680 m),
the lab's control wheelset as the hybrid model. The oracles are the line's truth: the true rail roughness of the
day (what a perfect trolley measures) processed by the same EN 13231-3 code, and, for the alignment, that true
roughness on true chainage: the estimated profile, moved by the run's stored correction, is cross-correlated with
it window by window; what is left is the alignment's true error.
"""

from __future__ import annotations

import logging

import numpy as np
import pandas as pd
import pytest

from test_estimator_synthetic import control_model

pytestmark = pytest.mark.slow

BANDS = ("30-100", "100-300")
PATCH = (510.0, 670.0)  # the corrugation patch C1_low on rail R (500-680 m) without its 10 m tapers


#: the progress messages of the module's ingest (what the command line's bar shows)
PROGRESS: list[str] = []


@pytest.fixture(scope="module")
def line_store(tmp_path_factory):
    from lab_data.line.cache import line_campaign_dir
    from lab_data.line.campaign import FIRST_CURVE_SECTION
    from receptance.model_io import save_model

    from estimator.monitoring import IngestSpec, MonitoringConfig, MonitoringStore, ingest

    camp = line_campaign_dir("nominal", days=1, runs_per_day=4, section=FIRST_CURVE_SECTION)
    d = tmp_path_factory.mktemp("line_monitor")
    save_model(control_model(), d / "hybrid_model.npz")
    spec = IngestSpec(str(d / "hybrid_model.npz"), str(camp / "sensors.csv"), line=str(camp / "line.json"),
                      monitoring=MonitoringConfig(n_perturbed=0, uncertainty_runs=0))
    logging.getLogger("estimator").setLevel(logging.ERROR)
    st = MonitoringStore(d / "store")
    PROGRESS.clear()
    res = ingest(sorted((camp / "runs").rglob("*.mf4")), spec, st, progress=lambda a, b, m: PROGRESS.append(m))
    return camp, spec, st, res


def _truth_windows(camp, date, window_m):
    from estimator import EstimatorConfig
    from estimator.monitoring.reference import TrolleyRecord, trolley_windows

    tr = pd.read_parquet(camp / "truth" / "rail_roughness" / f"{date}.parquet")
    x = tr["chainage_m"].to_numpy()
    rec = TrolleyRecord("truth", date, float(x[0]), float(np.median(np.diff(x))), ("L", "R"),
                        np.stack([tr["L_um"].to_numpy(), tr["R_um"].to_numpy()]) * 1e-6)
    tw = trolley_windows(rec, None, EstimatorConfig(), window_m)
    return tw[tw["valid_share"] >= 0.99], rec


def test_runs_are_placed_on_the_true_chainage_within_10_mm(line_store):
    from estimator.io import read_run
    from estimator.monitoring.alignment import ShiftFit, align_profiles, feature_profile
    from estimator.monitoring.workflow import run_context
    from estimator.workflow import estimate_run

    from dataclasses import replace

    camp, spec, st, res = line_store
    assert len(res.runs) >= 3 and res.runs["aligned"].all()
    assert (res.runs["alignment_residual_mm"] <= 10.0).all()
    wheelbase = res.runs.set_index("run_id")["wheelbase_m"]
    cfg = spec.monitoring
    al = st.read("alignment")
    ctx = run_context(spec)
    date = res.dates[0]
    _, rec = _truth_windows(camp, date, cfg.window_m)
    truth = feature_profile(rec.x, rec.values, rec.rails, cfg.align_band_mm, "truth")
    errors = []
    for run_id, src in res.runs[["run_id", "source"]].drop_duplicates().itertuples(index=False):
        # the run as ingested: with its stored wheelbase (a run whose own measurement was refused used its bogie's)
        fm = replace(ctx.field_model, config=ctx.field_model.config.replace(wheelbase_m=float(wheelbase[run_id])))
        est = estimate_run(read_run(src, fm.sensors), fm)
        for (w, kind), p in est.profiles.items():
            if kind != cfg.model:
                continue
            rows = al[(al["run_id"] == run_id) & (al["wheelset"] == w)]
            # no stage: the day's reference where the line's features did not anchor it (odometer chainage kept)
            fit = ShiftFit.from_pieces(rows) if len(rows) else ShiftFit.identity()
            fp = feature_profile(p.chainage_m, p.rail, p.rails, cfg.align_band_mm).shifted(fit)
            left = align_profiles(fp, truth, cfg)  # what still separates the aligned run from the true chainage
            assert left.accepted, left.reason
            x = fp.x[(fp.x > fp.x[0] + 20) & (fp.x < fp.x[-1] - 20)]
            errors.append(float(np.sqrt(np.mean(left.fit.shift(x) ** 2))))
    # every wheelset estimate stored (run 20240304_03_fw's wheelset 2 is masked out by QC: its channel clips)
    assert len(errors) == len(st.read("windows")[["run_id", "wheelset"]].drop_duplicates()) >= 7
    assert max(errors) <= 0.010


def test_a_run_whose_wheelbase_is_refused_is_processed_with_its_bogies(line_store):
    """Run 20240304_03_fw has a channel clipping all along (its 1.4 g range, truth.json daq): its lead/trail
    correlation is ~0 and the single-run estimator refuses to measure its wheelbase. Ingest processes it again with
    the median of the bogie's other runs, states so, and the value is the vehicle's true wheelbase."""
    from monitor_truth import truth_json

    camp, spec, st, res = line_store
    true_wb = truth_json(camp)["vehicle"]["wheelbase_m"]
    assert res.failures.empty and len(res.runs) == 4
    r = res.runs.set_index("run_id")
    assert r.loc["20240304_03_fw", "wheelbase_source"].startswith("bogie ")
    assert "median of 3 run(s)" in r.loc["20240304_03_fw", "wheelbase_source"]
    assert r.drop(index="20240304_03_fw")["wheelbase_source"].str.startswith("measured").all()
    assert np.all(np.abs(r["wheelbase_m"] - true_wb) <= 0.005)
    assert st.read("failures").empty  # its first failure was replaced, not kept beside its rows
    # and the progress said it was deferred, not failed
    first = [m for m in PROGRESS if m.startswith("20240304_03_fw")]
    assert first[0] == ("20240304_03_fw: wheelbase not measured on this run; deferred until its bogie's other runs "
                        "give it") and first[-1].startswith("20240304_03_fw (2024-03-04) done in")
    assert not any("FAILED" in m for m in PROGRESS)


def test_the_day_average_of_the_corrugated_curve_is_the_true_band_peak_to_peak(line_store):
    from estimator.monitoring import monitor
    from estimator.monitoring.averaging import energy_mean_db, level_db

    camp, spec, st, res = line_store
    m = monitor(st, line_file=camp / "line.json")
    date = res.dates[0]
    tw, _ = _truth_windows(camp, date, spec.monitoring.window_m)
    dw = m.day_windows
    for band in BANDS:
        d = dw[(dw["rail"] == "R") & (dw["band_mm"] == band) & dw["window_m"].between(PATCH[0], PATCH[1] - 1)]
        t = tw[(tw["rail"] == "R") & (tw["band_mm"] == band) & tw["window_m"].isin(d["window_m"])]
        assert len(t) > 100
        est = energy_mean_db(d[d["window_m"].isin(t["window_m"])]["level_db"])
        true = energy_mean_db(level_db(t["pk_pk_um"]))
        assert est == pytest.approx(true, abs=1.0), band


def test_the_trolley_table_per_rail_and_band_is_the_trains_error_against_the_truth(line_store):
    """The trolley files of the line (truth + 0.3 µm noise, high-passed at 3 m, on a chainage offset by a few dm)
    through the reference path: aligned to the train's chainage to the truth's offset, and its table of band errors
    per rail is the train's error against the truth itself (the trolley measures the rail, not the contact)."""
    from monitor_truth import truth_json, truth_windows

    from estimator.monitoring import monitor
    from estimator.monitoring.reference import band_errors, compare_reference

    camp, spec, st, res = line_store
    date = res.dates[0]
    comp = compare_reference(st, camp / "trolley" / f"{date}.csv", cfg=spec.monitoring)
    offset = truth_json(camp)["trolley"]["offset_m"]  # trolley chainage = true chainage + offset_m
    assert comp.alignment.accepted
    x = np.linspace(420.0, 780.0, 10)
    assert np.max(np.abs(comp.alignment.fit.shift(x) + offset)) <= 0.010
    days = monitor(st, line_file=camp / "line.json").day_windows
    vs_truth, _ = band_errors(days[days["date"] == date].assign(valid_share=1.0),
                              truth_windows(camp, date).assign(valid_share=1.0))
    tab = comp.errors.merge(vs_truth, on=["rail", "band_mm"], suffixes=("", "_truth"))
    tab = tab[tab["band_mm"].isin(BANDS)]
    assert len(tab) == 4 and (tab["windows"] >= 0.9 * tab["windows_truth"]).all()
    assert np.all(np.abs(tab["level_error_db"] - tab["level_error_db_truth"]) <= 0.3)
    assert np.all(np.abs(tab["level_error_db"]) <= 1.5)


def test_a_trolley_calibrated_half_bounds_the_truth_on_the_other_half(line_store):
    """The trolley of one half of the section (400-600 m or 600-800 m) calibrates the estimator's window error;
    on the other half, which the calibration did not see, the intervals with the reference source cover the true
    band peak-to-peak in ≥ 90 % of the 1 m windows (30-100 and 100-300 mm; measured 0.995 and 0.955 on these 4
    runs without the perturbation sources, 0.997 and 0.986 on the acceptance's 7-run day with them)."""
    from monitor_truth import truth_windows

    from estimator.monitoring import monitor, reference_calibration, with_reference
    from estimator.monitoring.confidence import coverage
    from estimator.monitoring.reference import compare_reference

    camp, spec, st, res = line_store
    date = res.dates[0]
    comp = compare_reference(st, camp / "trolley" / f"{date}.csv", cfg=spec.monitoring)
    days = monitor(st, line_file=camp / "line.json").day_windows
    truth = truth_windows(camp, date)
    held = []
    for site in ((400.0, 600.0), (600.0, 800.0)):
        cal = reference_calibration(comp.windows, site=site)
        assert (cal.set_index("band_mm").loc[list(BANDS), "windows"] >= 150).all()
        d = with_reference(days, cal)
        held.append(d[(d["window_m"] < site[0]) | (d["window_m"] >= site[1])])
    cov = coverage(pd.concat(held, ignore_index=True), truth).set_index("band_mm")["coverage"]
    assert (cov[list(BANDS)] >= 0.9).all(), cov.to_dict()
