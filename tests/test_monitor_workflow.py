"""Ingest → store → monitor on synthetic runs; rejection and failure of single runs; model change; the CLI.

The runs are the estimator's synthetic runs (``test_estimator_synthetic``:
receptance's forward map of a known rail roughness, odometer scale error,
start offset and balise resets), which test the monitoring's mechanics; the
accuracy acceptance is measured on the virtual line (``test_monitor_line.py``).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from test_estimator_synthetic import SyntheticLine, control_model, make_run, sensor_table

from estimator import EstimatorConfig
from estimator.monitoring.averaging import energy_mean_db
from estimator.monitoring import IngestSpec, MonitoringConfig, MonitoringStore, ingest, monitor, reprocess

MON = MonitoringConfig(n_perturbed=2, placement_shifts_mm=(30.0,), placement_axes=("y",), uncertainty_runs=1,
                       contact_head_radius_m=(), track_damping_factor=1.0, track_loss_reference_hz=(),
                       track_discrete_supports=False, sensor_noise_rms_m_s2=0.03)


@pytest.fixture(scope="module")
def field(tmp_path_factory):
    """A model file, a sensor table, two days of synthetic runs, a run of another track and a truncated file."""
    from receptance.model_io import save_model

    d = tmp_path_factory.mktemp("field")
    model = control_model()
    save_model(model, d / "hybrid_model.npz")
    sensor_table().to_csv(d / "sensors.csv", index=False)
    runs = []
    for k, (date, off, sc) in enumerate([("2026-01-05", 1.5, 1.003), ("2026-01-05", -2.0, 0.998),
                                         ("2026-01-14", 0.7, 1.001)]):
        runs.append(make_run(d, model, duration_s=25.0, start_offset_m=off, odometer_scale=sc, name=f"run{k}",
                             header_extra={"run_id": f"r{k}", "date": date}).path)
    other = make_run(d, model, line=SyntheticLine(seed=99, sinusoids={}), duration_s=25.0, name="other",
                     header_extra={"run_id": "other", "date": "2026-01-05"}).path
    bad = d / "truncated.mf4"
    bad.write_bytes(runs[0].read_bytes()[:5000])
    spec = IngestSpec(str(d / "hybrid_model.npz"), str(d / "sensors.csv"), estimator=EstimatorConfig(wheelbase_m=2.2),
                      monitoring=MON)
    return {"dir": d, "runs": runs, "other": other, "bad": bad, "spec": spec, "model": model}


@pytest.fixture(scope="module")
def ingested(field):
    st = MonitoringStore(field["dir"] / "store")
    res = ingest(field["runs"] + [field["other"], field["bad"]], field["spec"], st)
    return st, res


def test_runs_are_aligned_averaged_and_bad_ones_reported_without_stopping_the_batch(ingested):
    st, res = ingested
    runs = res.runs.set_index("run_id")
    assert set(runs.index) == {"r0", "r1", "r2", "other"}
    assert runs.loc[["r0", "r1", "r2"], "aligned"].all()
    assert (runs.loc[["r0", "r1", "r2"], "alignment_residual_mm"] < 5.0).all()
    assert not runs.loc["other", "aligned"] and "correlate" in runs.loc["other", "rejected_reason"]
    assert len(res.failures) == 1 and "truncated" in res.failures["source"].iloc[0]
    w = st.read("windows")
    assert set(w["run_id"]) == {"r0", "r1", "r2"}  # the rejected run is not averaged in
    assert {"model_hash", "toolkit_version", "model_file"} <= set(w.columns)
    assert (w["model_hash"] == res.model_hash).all()
    assert set(st.read("days")["date"]) == {"2026-01-05", "2026-01-14"}
    v = st.read("variants")
    assert set(v["source"]) == {"model", "placement", "contact", "track", "floor"} and v["run_id"].nunique() == 2
    # one model per source and range end: 2 perturbed, 2 shifts, wheel load -/+, pad and ballast stiffness x/÷ 2
    assert v.groupby("source")["variant"].nunique().to_dict() == {"model": 2, "placement": 2, "contact": 2, "track": 4,
                                                                   "floor": 1}


def test_the_synthetic_corrugation_is_found_on_the_right_rail(ingested):
    """Sinusoids of 20 µm amplitude at 60 mm on L and 15 µm at 180 mm on R over 100–300 m: day averages in the
    middle of them (energy mean over the windows) are the sinusoids' peak-to-peak (2√2 × RMS = 2 × amplitude)
    within 1.5 dB."""
    st, res = ingested
    d = st.read("days", date="2026-01-05")
    mid = d[(d["window_m"] >= 150) & (d["window_m"] < 250)]
    lvl = mid.groupby(["rail", "band_mm"])["level_db"].apply(energy_mean_db)
    assert lvl[("L", "30-100")] == pytest.approx(20 * np.log10(40.0), abs=1.5)
    assert lvl[("R", "100-300")] == pytest.approx(20 * np.log10(30.0), abs=1.5)
    assert lvl[("R", "30-100")] < lvl[("L", "30-100")] - 10


def test_re_ingest_is_idempotent(field, ingested):
    st, _ = ingested
    before = st.read("windows").sort_values(["run_id", "wheelset", "rail", "band_mm", "window_m"]).reset_index(drop=True)
    ingest([field["runs"][1]], field["spec"], st)  # the day's stored reference is reused
    after = st.read("windows").sort_values(["run_id", "wheelset", "rail", "band_mm", "window_m"]).reset_index(drop=True)
    assert len(after) == len(before)
    pd.testing.assert_frame_equal(before.drop(columns=["section", "line", "date"]),
                                  after.drop(columns=["section", "line", "date"]), check_exact=False, rtol=1e-12)


def test_monitor_reads_a_line_back(ingested):
    st, res = ingested
    m = monitor(st)
    assert m.model_hash == res.model_hash and set(m.day_windows["date"]) == {"2026-01-05", "2026-01-14"}
    assert {"ci_lo_db", "ci_hi_db", "model_lo_db", "placement_hi_db"} <= set(m.day_windows.columns)
    assert (m.day_windows["ci_lo_db"] <= m.day_windows["level_db"] + 1e-9).all()
    # the sensor noise's floor (0.03 m/s^2 through the same inversion) lies far under the 40 µm sinusoids
    mid = m.day_windows[m.day_windows["window_m"].between(150, 249) & (m.day_windows["rail"] == "L")
                        & (m.day_windows["band_mm"] == "30-100")]
    assert len(mid) and (mid["floor_status"] == "above floor").all() and (mid["above_floor_db"] > 20).all()
    assert len(m.growth) and len(m.forecast)
    sub = monitor(st, section_range=(100.0, 200.0))
    assert sub.day_windows["window_m"].between(99.0, 200.0).all()


def test_a_new_model_is_reprocessed_beside_the_old_one(field, ingested, tmp_path):
    from receptance.model_io import save_model

    st, res = ingested
    m2 = field["model"]
    m2 = m2.with_modal_parameters(m2.freqs_hz * 1.05, step="test: frequencies +5 %")
    save_model(m2, tmp_path / "hybrid_model_v2.npz")
    spec2 = IngestSpec(str(tmp_path / "hybrid_model_v2.npz"), field["spec"].sensors,
                       estimator=EstimatorConfig(wheelbase_m=2.2), monitoring=MonitoringConfig(n_perturbed=0,
                                                                                              uncertainty_runs=0))
    r2 = reprocess(st, spec2, from_model=res.model_hash)
    assert r2.model_hash != res.model_hash
    assert set(st.model_versions()["model_hash"]) == {res.model_hash, r2.model_hash}
    m = monitor(st)  # the last processed version, with what changed against the first
    assert m.model_hash == r2.model_hash
    assert len(m.changes) and (m.changes["other_model"] == res.model_hash).all()
    assert np.isfinite(m.changes["change_db"]).all() and (m.changes["change_db"].abs() > 0).any()
    old = monitor(st, model_hash=res.model_hash[:8])
    assert old.model_hash == res.model_hash


def test_a_field_calibration_is_ingested_as_its_own_version(field, ingested, tmp_path):
    """The diagnosis's calibrated model feeds the store: applied, versioned apart, refused for another model."""
    from receptance.model_io import save_model

    from estimator.diagnosis import CalibrationFileError, FieldState, save_calibration

    st, res = ingested
    state = FieldState().with_loss_reference(60.0)
    save_calibration(tmp_path / "cal", field["spec"].model, state, site=(0.0, 100.0), date="2026-01-05")
    spec = IngestSpec(field["spec"].model, field["spec"].sensors, estimator=EstimatorConfig(wheelbase_m=2.2),
                      monitoring=MonitoringConfig(n_perturbed=0, uncertainty_runs=0), calibration=str(tmp_path / "cal"))
    r = reprocess(st, spec, from_model=res.model_hash)
    assert r.model_hash.startswith(res.model_hash + "+cal") and len(r.runs) == len(res.runs)
    assert {res.model_hash, r.model_hash} <= set(st.model_versions()["model_hash"])
    # the synthetic runs were made through eq. 2.32's track: stiffening the layers changes the estimate where
    # the track shapes it (the unsprung mass on the track, 100-300 mm at these speeds), not by a constant
    a = monitor(st, model_hash=res.model_hash).day_windows
    b = monitor(st, model_hash=r.model_hash).day_windows
    j = a.merge(b, on=["date", "rail", "band_mm", "window_m"], suffixes=("_n", "_c"))
    d = (j["level_db_c"] - j["level_db_n"]).groupby(j["band_mm"]).median()
    assert abs(d["100-300"]) > 0.1 and abs(d["100-300"] - d["30-100"]) > 0.05
    # a calibration made for another model is refused, naming both models
    other = field["model"].with_modal_parameters(field["model"].freqs_hz * 1.02, step="test: another model")
    save_model(other, tmp_path / "other.npz")
    save_calibration(tmp_path / "cal_other", tmp_path / "other.npz", state, site=(0.0, 100.0), date="2026-01-05")
    with pytest.raises(CalibrationFileError, match=r"calibrates the model with hash .* not hybrid_model\.npz"):
        ingest(field["runs"][:1], IngestSpec(field["spec"].model, field["spec"].sensors,
                                             calibration=str(tmp_path / "cal_other")), st)


def test_cli_ingest_monitor_and_bad_arguments(field, tmp_path, capsys):
    from railmodal.cli import main

    store = tmp_path / "cli_store"
    args = ["-q", "field", "ingest", *map(str, field["runs"][:2]), "--sensors", str(field["dir"] / "sensors.csv"),
            "--model", str(field["dir"] / "hybrid_model.npz"), "--store", str(store), "--executor", "local",
            "--perturbed", "0", "--uncertainty-runs", "0", "--wheelbase", "2.2"]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "2 run(s) written (2 aligned and averaged)" in out
    assert main(["-q", "field", "monitor", "--store", str(store), "--out", str(tmp_path / "rep")]) == 0
    html = (tmp_path / "rep" / "report.html").read_text()
    assert "Grinding plan" in html and "data:image/png;base64" in html
    assert (tmp_path / "rep" / "forecast.csv").exists()
    # bad arguments stop before any work, naming the option
    with pytest.raises(SystemExit) as e:
        main(["field", "monitor", "--store", str(store), "--out", str(tmp_path / "x"), "--section", "300", "100"])
    assert e.value.code == 2
    assert "--section" in capsys.readouterr().err
    (tmp_path / "afile").write_text("x")
    with pytest.raises(SystemExit):
        main(["field", "monitor", "--store", str(tmp_path / "afile"), "--out", str(tmp_path / "y")])
    assert main(["field", "monitor", "--store", str(tmp_path / "empty"), "--out", str(tmp_path / "z")]) == 1
    assert "empty" in capsys.readouterr().err
    assert not (tmp_path / "z").exists()
    assert main(args[:3] + [str(tmp_path / "nope.mf4")] + args[5:]) == 1
    assert "does not exist" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:  # a folder that holds no field calibration
        main(args + ["--calibration", str(tmp_path)])
    assert e.value.code == 2 and "--calibration" in capsys.readouterr().err


def test_cli_compare_reference_with_a_trolley_on_its_own_chainage(field, ingested, tmp_path, capsys):
    """The synthetic line measured by a 'trolley' (1 mm, 0.3 µm noise) whose chainage is 0.35 m off the train's:
    the offset is found and the band errors per rail are tabulated."""
    from railmodal.cli import main

    st, _ = ingested
    x, rails = SyntheticLine().profiles()
    sel = (x >= 60) & (x <= 320)
    rng = np.random.default_rng(5)
    frames = [pd.DataFrame({"chainage_m": x[sel] + 0.35, "rail": r,
                            "roughness_um": 1e6 * rails[r][sel] + 0.3 * rng.standard_normal(sel.sum())})
              for r in "LR"]
    trolley = tmp_path / "2026-01-05.csv"
    pd.concat(frames).to_csv(trolley, index=False)
    assert main(["-q", "field", "compare-reference", "--store", str(st.root), "--trolley", str(trolley), "--out",
                 str(tmp_path / "cmp")]) == 0
    out = capsys.readouterr().out
    assert "offset -0.35" in out
    err = pd.read_csv(tmp_path / "cmp" / "band_errors.csv").set_index(["rail", "band_mm"])
    assert abs(err.loc[("L", "30-100"), "level_error_db"]) < 1.5
    assert abs(err.loc[("R", "100-300"), "level_error_db"]) < 1.5
    assert (tmp_path / "cmp" / "reference_2026-01-05.png").exists()


def test_a_calibration_site_widens_the_intervals_to_cover_the_truth_elsewhere(field, ingested, tmp_path, capsys):
    """A trolley record (the true rails, 0.3 µm noise) of 60-190 m calibrates the estimator's error; on the rest
    of what the runs cover (190-225 m, which the calibration did not see) the widened 95 % intervals cover the
    true band peak-to-peak in ≥ 90 % of the windows of each band, where the intervals without it cover fewer
    (measured 30-100 mm 0.67 → 0.99, 100-300 mm 0.84 → 0.99)."""
    from railmodal.cli import main
    from estimator.monitoring.confidence import coverage
    from estimator.monitoring.reference import TrolleyRecord, trolley_windows

    st, res = ingested
    version = ["--model-version", res.model_hash]  # the fixture's model (another test may add a version)
    x, rails = SyntheticLine().profiles()
    sel = (x >= 60) & (x <= 320)
    rng = np.random.default_rng(6)
    site = (x >= 60) & (x <= 190)
    frames = [pd.DataFrame({"chainage_m": x[site], "rail": r,
                            "roughness_um": 1e6 * rails[r][site] + 0.3 * rng.standard_normal(site.sum())})
              for r in "LR"]
    trolley = tmp_path / "2026-01-05.csv"
    pd.concat(frames).to_csv(trolley, index=False)
    rc = main(["-q", "field", "monitor", "--store", str(st.root), "--out", str(tmp_path / "plain")] + version)
    assert rc == 0, capsys.readouterr().err
    rc = main(["-q", "field", "monitor", "--store", str(st.root), "--out", str(tmp_path / "cal"),
               "--calibration-trolley", str(trolley), "--calibration-site", "60", "190"] + version)
    out, err = capsys.readouterr()
    assert rc == 0, err
    assert "calibration   30-100 mm on" in out and "truth within" in out
    cal = pd.read_csv(tmp_path / "cal" / "calibration.csv").set_index("band_mm")
    assert cal.loc["30-100", "windows"] >= 100 and np.isfinite(cal.loc["30-100", ["lo_db", "hi_db"]]).all()
    # the oracle: the true rails' band peak-to-peak per window, by the same EN processing
    d = np.diff(x).mean()
    rec = TrolleyRecord("truth", "2026-01-05", x[sel][0], d, tuple("LR"), np.vstack([rails[r][sel] for r in "LR"]))
    truth = trolley_windows(rec, None, EstimatorConfig(), 1.0).assign(level_db=lambda t: 20 * np.log10(t["pk_pk_um"]))
    truth = truth[(truth["window_m"] >= 190) & (truth["valid_share"] >= 0.5)]
    for folder in ("plain", "cal"):
        dw = pd.read_csv(tmp_path / folder / "day_windows.csv")
        cov = coverage(dw, truth, by=()).set_index("band_mm")["coverage"]
        if folder == "plain":
            plain = cov
    for band in ("30-100", "100-300"):
        assert cov[band] >= 0.9 and cov[band] >= plain[band], (band, cov[band], plain[band])
    dw = pd.read_csv(tmp_path / "cal" / "day_windows.csv")
    assert {"reference_lo_db", "reference_hi_db"} <= set(dw.columns)
