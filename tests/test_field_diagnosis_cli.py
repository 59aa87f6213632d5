"""End to end: synthetic MDF 4 runs + a trolley file → ``railmodal field diagnose`` → JSON, report, calibrated model.

The runs are made by the estimator tests' forward map with the nominal track (no hidden effect), so the oracle
is "nothing accepted" and a residual at the noise floor; argument and input errors reach the user as one line
naming the option or file, and nothing is written.
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from railmodal.cli import main


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    from receptance import save_model
    from test_estimator_synthetic import SyntheticLine, control_model, make_run, sensor_table

    tmp = tmp_path_factory.mktemp("fdiag")
    model = tmp / "hybrid_model.npz"
    save_model(control_model(), model)
    sensor_table().to_csv(tmp / "sensors.csv", index=False)
    line = SyntheticLine(length_m=400.0)
    runs = [make_run(tmp, line=line, duration_s=30.0, v_cruise=12.0, name="r1", balises=(60.0, 200.0)).path,
            make_run(tmp, line=line, duration_s=30.0, v_cruise=14.0, name="r2", balises=(60.0, 200.0)).path]
    x, rails = line.profiles()
    rng = np.random.default_rng(5)
    rows = [pd.DataFrame({"chainage_m": x, "rail": r, "roughness_um": 1e6 * rails[r] + 0.02 * rng.standard_normal(x.size)})
            for r in ("L", "R")]
    ref = tmp / "2026-01-05.csv"
    pd.concat(rows).to_csv(ref, index=False)
    return tmp, model, runs, ref


@pytest.mark.slow
def test_field_diagnose_command_on_a_nominal_site(campaign, capsys):
    tmp, model, runs, ref = campaign
    out = tmp / "diag"
    code = main(["field", "diagnose", "--runs", *map(str, runs), "--reference", str(ref), "--site", "96", "216",
                 "--model", str(model), "--sensors", str(tmp / "sensors.csv"), "--effects",
                 "sensor_offset,contact_stiffness,contact_angle", "--workers", "2", "--validation-stretch", "120",
                 "180", "--out", str(out)])
    text = capsys.readouterr()
    assert code == 0, text.err
    doc = json.loads((out / "field_diagnosis.json").read_text())
    assert doc["accepted"] == [], doc["verdict"]
    assert doc["rounds"] and all(c["effect"] in ("sensor_offset", "contact_stiffness") for c in doc["rounds"][0])
    e = [r for r in doc["errors"] if r["stage"] == "nominal"]
    assert {r["set"] for r in e} == {"calibration", "validation"} and all(r["n_cells"] > 20 for r in e)
    # the nominal estimate of the nominal field: a few dB per one-third-octave cell (the bands where one rail's
    # narrow-band corrugation leaks into the other's near-empty band dominate), its EN band indexes within 4 dB
    assert 0.3 < e[0]["error_db"] < 8.0
    en = doc["comparison"]["en_bands"]
    assert en and max(r["rms_error_db"] for r in en) < 4.0
    assert doc["noise_floor_db"]["total"] > 0
    # a named validation stretch is reported for the days that do not calibrate: both runs here are of the
    # calibration day, so it has no rows (the other-day case: tests/test_field_diagnosis_line.py)
    assert not any(r["set"] == "validation stretch" for r in doc["band_index_errors"])
    assert (out / "report.html").read_text().count("Field diagnosis") >= 1
    cal = json.loads((out / "calibrated_model" / "field_calibration.json").read_text())
    assert cal["version"].endswith("+nominal") and (out / "calibrated_model" / "hybrid_model.npz").is_file()
    assert "nothing accepted" in text.out


def test_field_diagnose_rejects_bad_arguments_before_work(campaign, capsys):
    tmp, model, runs, ref = campaign
    out = tmp / "never"
    base = ["field", "diagnose", "--runs", str(runs[0]), "--reference", str(ref), "--model", str(model),
            "--sensors", str(tmp / "sensors.csv"), "--out", str(out)]
    assert main(base + ["--site", "200", "100"]) == 1
    assert "--site FROM TO" in capsys.readouterr().err
    assert main(base + ["--site", "100", "200", "--effects", "trackform,magic"]) == 1
    assert "magic" in capsys.readouterr().err
    assert main(base + ["--site", "100", "200", "--validation-stretch", "150", "120"]) == 1
    assert "--validation-stretch FROM TO" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(base[:-2] + ["--site", "100", "200", "--out", str(out), "--max-effects", "9"])
    assert "--max-effects" in capsys.readouterr().err
    assert not out.exists()


def test_calibration_file_round_trip_and_refusals(tmp_path, campaign):
    from estimator.diagnosis import CalibrationFileError, FieldState, load_calibration, save_calibration
    from estimator.diagnosis.state import TrackformChange

    _, model, _, _ = campaign
    st = (FieldState().with_trackform_change(TrackformChange(10.0, 50.0, (("pad_stiffness", 2.0),)))
          .with_curve_angles("C1", "leading", 0.1, 0.5).with_sensor_offset("ACC_W1L_Z", 0.0, 0.08, 0.0)
          .with_wheel_load(60e3))
    p = save_calibration(tmp_path / "cal", model, st, site=(0, 100), date="2026-01-05")
    back, doc = load_calibration(tmp_path / "cal")
    assert back == st and "+cal" in doc["version"]
    d = json.loads(p.read_text())
    d["format_version"] = 99
    p.write_text(json.dumps(d))
    with pytest.raises(CalibrationFileError, match="format version 99"):
        load_calibration(tmp_path / "cal")
