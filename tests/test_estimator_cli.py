"""``railmodal field estimate`` end to end on a synthetic run: files, report sections, and refusals before work."""

from __future__ import annotations

import json
import math
import re
from html import escape

import pandas as pd
import pytest

from estimator.report import SECTION_TITLES
from railmodal.cli import main
from receptance import save_model
from test_estimator_synthetic import control_model, make_run, sensor_table


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("cli")
    model = tmp / "hybrid_model.npz"
    save_model(control_model(), model)
    sensors = tmp / "sensors.csv"
    sensor_table().to_csv(sensors, index=False)
    sr = make_run(tmp, control_model(), duration_s=30, name="cli_run")
    truth = pd.concat([pd.DataFrame({"chainage_m": sr.truth_x[::2], "rail": r, "roughness_um": sr.truth[r][::2] * 1e6})
                       for r in "LR"])
    truth.to_csv(tmp / "trolley.csv", index=False)
    return tmp, model, sensors, sr


def test_field_estimate_writes_profiles_tables_figures_and_the_report(inputs, capsys):
    tmp, model, sensors, sr = inputs
    out = tmp / "out"
    code = main(["-q", "field", "estimate", "--run", str(sr.path), "--sensors", str(sensors), "--model", str(model),
                 "--models", "half,lateral", "--reference", str(tmp / "trolley.csv"), "--out", str(out)])
    text = capsys.readouterr()
    assert code == 0, text.err
    assert "wheelbase 2.20" in text.out and "report:" in text.out
    for name in ("profiles_ws1.parquet", "profiles_ws2.parquet", "band_pk_pk.parquet", "indexes.csv", "spectra.csv",
                 "corrugation.csv", "wheel_orders.csv", "qc.csv", "comparison.csv", "summary.json", "report.html"):
        assert (out / name).is_file(), name
    prof = pd.read_parquet(out / "profiles_ws1.parquet")
    assert {"chainage_m", "half_L_um", "vertical_lateral_R_um"} <= set(prof.columns)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["models"] == ["half", "vertical_lateral"] and summary["leading_wheelset"] == 1
    html = (out / "report.html").read_text()
    for title in SECTION_TITLES:
        assert title in html
    assert html.count("data:image/png;base64") >= 4
    # the header's fields, given or not: the synthetic file names its train and leaves leading_end out
    assert "<td>train</td><td>T1</td>" in html
    assert "<td>leading_end</td><td>(not in the run header)</td>" in html
    # the report opens with the findings the console printed, the same sentences (µm where the console says um)
    box = html[html.index("<b>In short.</b>"):html.index(SECTION_TITLES[0])]
    found = [ln for ln in text.out.splitlines() if ln.startswith(("corrugated:", "no stretch above"))]
    assert found and all(escape(ln.replace(" um", " µm").replace("lambda", "λ").replace("->", "→")) in box
                         for ln in found)
    # and they are the synthetic line's corrugations: 60 mm on rail L (40 µm pk-pk), 180 mm on rail R (30 µm);
    # the level within 2 dB (the median over stretches that include the patches' 5 m tapers reads low)
    said = {(m[1], m[2]): (float(m[3]), float(m[4])) for m in (re.search(
        r"rail (\w), (\d+-\d+) mm: ([0-9.]+) µm pk-pk .*λ ([0-9.]+) mm", item) for item in re.findall(
        r"<li>(corrugated:.*?)</li>", box)) if m}
    assert set(said) == {("L", "30-100"), ("R", "100-300")}
    for key, (pk_um, lam_mm) in {("L", "30-100"): (40.0, 60.0), ("R", "100-300"): (30.0, 180.0)}.items():
        assert abs(20 * math.log10(said[key][0] / pk_um)) < 2.0 and abs(said[key][1] / lam_mm - 1) < 0.05, key
    # each band figure says its band and stretch in words, shorter band first
    caps = re.findall(r"<figcaption>EN 13231-3 peak-to-peak, ([0-9]+–[0-9]+) mm, ([^,]+),", html)
    assert [c[0] for c in caps][:2] == ["30–100", "100–300"] and all("_" not in c[1] for c in caps)
    cmp = pd.read_csv(out / "comparison.csv")
    vl = cmp[(cmp["model"] == "vertical_lateral") & (cmp["role"] == "leading")
             & cmp["band_mm"].isin(["30-100", "100-300"])].dropna(subset=["mean_error_db"])
    assert len(vl) == 4 and vl["energy_error_db"].abs().max() < 1.5  # whole run: corrugation dominates the energy


def test_sleeper_comb_is_reported_and_can_be_switched_off(inputs, capsys):
    """The synthetic forward map has no sleeper passing: with a spacing given, the comb tests every order, finds
    none and says so; without a line or spacing, and with --keep-sleeper-passing, the history says why it did not
    run."""
    tmp, model, sensors, sr = inputs
    base = ["-q", "field", "estimate", "--run", str(sr.path), "--sensors", str(sensors), "--model", str(model),
            "--models", "vertical", "--wheelbase", "2.2"]
    histories = {}
    for name, extra in (("given", ["--sleeper-spacing", "0.6"]), ("none", []),
                        ("kept", ["--sleeper-spacing", "0.6", "--keep-sleeper-passing"])):
        out = tmp / f"sleeper_{name}"
        assert main(base + extra + ["--out", str(out)]) == 0, capsys.readouterr().err
        summary = json.loads((out / "summary.json").read_text())
        histories[name] = " | ".join(summary["processing"])
        if name == "given":
            assert {(s["wheelset"], s["spacing_m"]) for s in summary["sleeper_passing"]} == {(1, 0.6), (2, 0.6)}
            assert all(s["removed"] == [] for s in summary["sleeper_passing"])
        else:
            assert summary["sleeper_passing"] == []
    assert "sleeper passing (spacing 0.6 m, ±64 bays), wheelset 1, vertical: rail L: nothing significant" \
        in histories["given"]
    assert "no line and no sleeper_spacing_m given" in histories["none"]
    assert "sleeper_comb off" in histories["kept"]


@pytest.mark.parametrize("args, message", [
    (["--models", "half,sideways"], "unknown transfer-function model 'sideways'"),
    (["--speed-gate", "0"], "--speed-gate"),
    (["--wheelbase", "40"], "--wheelbase"),
    (["--sleeper-spacing", "0.01"], "--sleeper-spacing"),
])
def test_bad_arguments_are_refused_before_any_work(inputs, capsys, args, message):
    tmp, model, sensors, sr = inputs
    out = tmp / "never"
    code = None
    try:
        code = main(["-q", "field", "estimate", "--run", str(sr.path), "--sensors", str(sensors), "--model",
                     str(model), "--out", str(out), *args])
    except SystemExit as exc:  # argparse refuses with exit status 2
        code = exc.code
    assert code in (1, 2)
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_missing_and_bad_files_are_named(inputs, capsys, tmp_path):
    tmp, model, sensors, sr = inputs
    with pytest.raises(SystemExit):
        main(["-q", "field", "estimate", "--run", str(tmp / "nope.mf4"), "--sensors", str(sensors), "--model",
              str(model), "--out", str(tmp_path / "o")])
    assert "nope.mf4" in capsys.readouterr().err
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a model")
    code = main(["-q", "field", "estimate", "--run", str(sr.path), "--sensors", str(sensors), "--model", str(bad),
                 "--out", str(tmp_path / "o")])
    assert code == 1 and "bad.npz" in capsys.readouterr().err and not (tmp_path / "o").exists()


def test_the_summary_says_whether_the_trailing_wheelset_agrees():
    """A stretch above the threshold on the leading wheelset is printed with the trailing wheelset's value, or with
    the plain statement that the trailing estimate is not above the threshold there (the two disagree); in a curve
    the leading wheelset's contact angles are named as the first suspect, with the command that calibrates them."""
    from types import SimpleNamespace

    from railmodal.field_commands import summarise_estimate

    def row(role, rail, pk):
        return {"wheelset": 1 if role == "leading" else 2, "role": role, "model": "vertical_lateral",
                "stretch": "curve C1", "rail": rail, "band_mm": "30-100", "median_pk_pk_um": pk,
                "dominant_wavelength_mm": 50.0, "peak_prominence_db": 9.0, "speed_m_s": 9.1, "frequency_hz": 182.0,
                "mechanism": "P2 resonance", "nearest": "P2", "nearest_hz": 180.0}

    corr = pd.DataFrame([row("leading", "L", 11.4), row("leading", "R", 23.3), row("trailing", "R", 21.9)])
    est = SimpleNamespace(run_id="r", duration_s=40.0, direction="forward", leading=1, masked_share={"run": 0.0},
                          qc=pd.DataFrame(), wheelbase_m=2.1, wheelbase_source="given", band_hz=(10.0, 400.0),
                          lambda_min_m=0.02, skipped=(), corrugation=corr, models=("vertical_lateral",))
    lines = [ln for ln in summarise_estimate(est) if ln.startswith("corrugated")]
    assert len(lines) == 2
    assert "rail L" in lines[0] and "NOT above the threshold on the trailing wheelset" in lines[0]
    assert "contact angles are the first suspect" in lines[0] and "field diagnose" in lines[0]  # a curve
    assert "rail R" in lines[1] and "trailing wheelset 21.9 um" in lines[1] and "suspect" not in lines[1]
    # the report's corrugation section lists the same stretch with the same note
    from estimator.report import _wheelset_disagreements

    split = _wheelset_disagreements(est)
    assert len(split) == 1 and split[0].startswith("curve C1, rail L, 30-100 mm: 11.4") and "field diagnose" in split[0]
    # on a straight the disagreement is stated without the curve's suspect
    straight = corr.assign(stretch="section straight_1")
    lines = [ln for ln in summarise_estimate(SimpleNamespace(**{**vars(est), "corrugation": straight}))
             if ln.startswith("corrugated")]
    assert "NOT above the threshold" in lines[0] and "suspect" not in lines[0]


def test_a_field_calibration_is_applied_named_and_refused_for_another_model(inputs, capsys, tmp_path):
    """``--calibration``: the diagnosis's calibrated model changes the estimate where its effect acts (the Hertz
    contact of a heavier wheel load, stiff: the high frequencies, 10-30 mm at 10 m/s), is named in the summary
    and the report's processing history, and is refused, naming both hashes, for a model it was not made for."""
    from estimator.diagnosis import FieldState, save_calibration

    tmp, model, sensors, sr = inputs
    base = ["-q", "field", "estimate", "--run", str(sr.path), "--sensors", str(sensors), "--model", str(model),
            "--models", "vertical"]
    assert main(base + ["--out", str(tmp_path / "nominal")]) == 0
    save_calibration(tmp_path / "cal", model, FieldState().with_wheel_load(110e3), site=(40.0, 200.0),
                     date="2026-01-05")
    capsys.readouterr()
    assert main(base + ["--calibration", str(tmp_path / "cal"), "--out", str(tmp_path / "cal_out")]) == 0
    out = capsys.readouterr().out
    assert "field calibration " in out and "+cal" in out and "wheel load 110 kN" in out
    assert "wheel load 110 kN" in (tmp_path / "cal_out" / "report.html").read_text()
    key = ["wheelset", "stretch", "rail", "wavelength_m"]
    a = pd.read_csv(tmp_path / "nominal" / "spectra.csv").set_index(key)["level_db"]
    b = pd.read_csv(tmp_path / "cal_out" / "spectra.csv").set_index(key)["level_db"]
    d = (b - a.reindex(b.index)).dropna()
    w = d.index.get_level_values("wavelength_m")
    # a heavier wheel has a longer contact patch, which averages the short wavelengths more (the contact filter),
    # so the same accelerations mean more rail roughness there; from 100 mm on, patch and Hertz spring hardly matter
    m = d.groupby(level="wavelength_m").mean()
    assert m[0.0315] > 0.5 and (m[m.index <= 0.08].diff().dropna() < 0).all()
    assert d[(w >= 0.1) & (w <= 0.5)].abs().max() < 0.25
    # made for another model: refused before any work, both hashes named
    other = tmp_path / "other.npz"
    other.write_bytes(model.read_bytes() + b"\0")
    code = main(base[:-2] + ["--model", str(other), "--models", "vertical", "--calibration", str(tmp_path / "cal"),
                             "--out", str(tmp_path / "refused")])
    err = capsys.readouterr().err
    assert code == 1 and "calibrates the model with hash" in err and "other.npz" in err
    assert not (tmp_path / "refused").exists()
