"""``railmodal lab diagnose`` and ``railmodal demo`` end to end on the virtual lab (CLI, report, saved model, FRF files).

Oracle: the lab truth of the 'rig' scenario (crane springs of 3.5e5 N/m vertical per axlebox lug, hidden
from the toolkit) and of its hammer campaign (which hits were double, which channel clipped). The FE export
reaches 2 kHz (``fe_export_hz``) so the structural modifications have a rich basis, as in a real lab.
"""

from __future__ import annotations

import base64
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from lab_data.cache import campaign_dir
from railmodal.cli import main
from receptance.diagnosis.workflow import to_jsonable
from receptance.report import SECTION_TITLES

IMG = '<img src="data:image/png;base64,'


def _no_nan(text: str):
    """json.loads that refuses NaN/Infinity (not JSON)."""
    def bad(token):
        raise ValueError(f"non-JSON constant {token} in diagnosis.json")
    return json.loads(text, parse_constant=bad)


@pytest.fixture(scope="module")
def rig_run(tmp_path_factory):
    folder = campaign_dir("rig", fe_export_hz=2000.0)
    out = tmp_path_factory.mktemp("diagnose_rig") / "out"
    # what the lab knows about its rig: the wheelset hung from the axlebox lugs (a wheelset description)
    description = out.parent / "wheelset.toml"
    description.write_text('[rig]\nhanging_points = ["axlebox_L", "axlebox_R"]\n', encoding="utf-8")
    argv = ["-q", "lab", "diagnose"]
    for setup in ("flexural", "torsional"):
        argv += ["--hammer", str(folder / f"{setup}.uff"), "--channels", str(folder / f"{setup}_channels.csv")]
    argv += ["--fem", str(folder / "fe_design.uff"), "--points", str(folder / "points.csv"), "--out", str(out),
             "--description", str(description)]
    return folder, out, argv


@pytest.fixture(scope="module")
def rig_result(rig_run):
    import contextlib
    import io

    folder, out, argv = rig_run
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(argv)
    assert code == 0
    manifest = json.loads((folder / "truth.json").read_text())
    return out, _no_nan((out / "diagnosis.json").read_text()), manifest, buf.getvalue()


@pytest.mark.slow
def test_rig_diagnosis_finds_the_crane_springs_with_their_stiffness(rig_result):
    out, doc, manifest, stdout = rig_result
    truth = manifest["scenario"]["effects"]["rig"]["vertical_N_per_m"]
    assert truth == pytest.approx(3.5e5)
    first = doc["accepted"][0]
    assert first["name"] == "rig_suspension"
    assert first["params"]["vertical_N_per_m"] == pytest.approx(truth, rel=0.25)
    assert first["error_after"] < first["error_before"]
    # issue acceptance: the error falls by half or down to (1.2 x) the noise floor of the measurement
    final = doc["final"]
    assert final["summary_error"] <= max(0.5 * doc["initial"]["summary_error"], 1.2 * final["noise_floor"])
    # nothing else is in the rig: no second effect, and the physics beats the patches of round 1
    assert [a["name"] for a in doc["accepted"]] == ["rig_suspension"]
    round1 = doc["rounds"][0]
    assert round1[0]["name"] == "rig_suspension"
    for patch in ("residuals", "experimental_mode"):
        fit = next(f for f in round1 if f["name"] == patch)
        assert fit["delta_bic"] > first["delta_bic"] and fit["n_fitted"] > 100
    # candidates ranked by the criterion (most negative dBIC first), every round
    for r in doc["rounds"]:
        d = [f["delta_bic"] for f in r]
        assert d == sorted(d) and len(r) >= 5
    assert doc["candidates"] == doc["rounds"][-1]
    assert "BIC" in doc["criterion"]
    # residual: where the remaining error sits
    res = doc["residual"]
    assert {"summary_error", "noise_floor", "worst", "bands"} <= set(res)
    assert len(res["worst"]) > 0 and len(res["bands"]) == 6
    assert res["summary_error"] == pytest.approx(final["summary_error"])
    # two independent implementations of E (compare.Comparison and diagnose.misfit) agree (they differ only in
    # whether the line at the band's top edge, 500 Hz, counts: a few ppm)
    assert doc["steps"][0]["summary_error"] == pytest.approx(first["error_before"], rel=1e-4)
    assert doc["steps"][1]["summary_error"] == pytest.approx(first["error_after"], rel=1e-4)
    assert set(doc["timings_s"]) >= {"identify", "pair_and_model", "compare", "diagnose", "figures", "total"}
    assert all(v >= 0 for v in doc["timings_s"].values())
    assert doc["timings_s"]["total"] >= doc["timings_s"]["diagnose"]
    # the terminal summary names the effect and the report
    assert "rig_suspension" in stdout and str(out / "report.html") in stdout
    # the hanging points came from the description: no position fitted
    assert set(first["params"]) == {"vertical_N_per_m", "horizontal_N_per_m"}
    assert doc["description"]["hanging_points"] == ["axlebox_L", "axlebox_R"]
    assert doc["not_applicable"] == [] and doc["workers"] >= 1
    assert all(set(r) >= {"rig_suspension", "axlebox_bearing"} for r in doc["candidate_seconds"][:1])


@pytest.mark.slow
def test_rig_diagnosis_saves_the_diagnosed_model_with_roles(rig_result):
    """hybrid_model.npz holds the accepted effect; the rig is a test artefact the in-service model drops."""
    from receptance.model_io import load_model

    out, doc, _, _ = rig_result
    assert doc["model"]["file"] == "hybrid_model.npz" and (out / "hybrid_model.npz").is_file()
    assert doc["model"]["modifications"] == [{"kind": "rig_springs", "role": "test_artefact",
                                              "kept_in_service": False}]
    model = load_model(out / "hybrid_model.npz")
    assert [m.kind for m in model.modifications] == ["rig_springs"]
    assert model.modifications[0].stiffness[2] == pytest.approx(doc["accepted"][0]["params"]["vertical_N_per_m"])
    assert model.for_service().modifications == ()
    assert doc["accepted"][0]["role"] == "test_artefact"


@pytest.mark.slow
def test_model_build_takes_the_wheelset_from_the_diagnosis_not_the_test(rig_run, rig_result, tmp_path):
    """``model build --diagnosed``: the in-service model carries the wheelset properties the diagnosis found and
    drops its test artefacts (here the crane springs) before the primary suspension is added."""
    from receptance.model_io import load_model

    folder, out, _ = rig_run
    code = main(["-q", "model", "build", "--pairing", str(out), "--fem", str(folder / "fe_design.uff"),
                 "--points", str(folder / "points.csv"), "--diagnosed", str(out / "hybrid_model.npz"),
                 "--out", str(tmp_path / "service")])
    assert code == 0
    model = load_model(tmp_path / "service" / "hybrid_model.npz")
    assert [m.kind for m in model.modifications] == ["primary_suspension"]
    assert any("removed test artefacts ['rig_springs']" in h for h in model.history)


@pytest.mark.slow
def test_rig_diagnosis_reports_the_hits_the_lab_spoilt(rig_result):
    """What-was-measured is right: the double hits and the clipped channel the lab planted are the rejections."""
    _, doc, manifest, _ = rig_result
    by_name = {s["setup"]: s for s in doc["setups"]}
    assert set(by_name) == {"flexural", "torsional"}
    for name, setup in manifest["setups"].items():
        got = by_name[name]
        assert got["rejected_hits"] == sorted(setup["double_hits"])
        for c in setup["clipped"]:
            assert any(f"(node {c['node']}) in hit {c['hit']} rejected (clipped)" in r for r in got["rejections"])
        assert got["n_averages"] == [len(setup["hits"]) - 2, len(setup["hits"]) - 1]
        assert got["n_modes"] >= 5
    # the identified modes reach the truth frequencies of the observable modes (0.5 %)
    truth_f = sorted({m["f_hz"] for s in manifest["setups"].values() for m in s["modes"] if m["observable"]})
    found = np.array([m["f_hz"] for s in doc["setups"] for m in s["modes"]])
    for f in truth_f:
        assert np.min(np.abs(found - f)) / f < 0.005, f


@pytest.mark.slow
def test_rig_report_is_self_contained_and_readable_top_to_bottom(rig_result):
    out, doc, _, _ = rig_result
    page = (out / "report.html").read_text(encoding="utf-8")
    positions = [page.find(f">{t}<") for t in SECTION_TITLES]
    assert all(p > 0 for p in positions) and positions == sorted(positions)
    pngs = sorted((out / "figures").glob("*.png"))
    assert len(pngs) >= 12
    assert page.count(IMG) == len(pngs)  # every figure embedded, once
    for blob in re.findall(r'data:image/png;base64,([A-Za-z0-9+/=]+)"', page):
        assert base64.b64decode(blob)[:8] == b"\x89PNG\r\n\x1a\n"
    assert "src=\"figures/" not in page and "<script" not in page  # nothing the mail would lose
    for effect in doc["accepted"]:
        assert f"Effect 1: {effect['name']}" in page
    assert "Physics before patches" in page and "noise floor" in page.lower()
    assert doc["criterion"].replace("<", "&lt;").replace(">", "&gt;") in page
    # the figure of merit in the report is the one in the json
    assert f"E fell from {100 * doc['steps'][0]['summary_error']:.2f} %" in page
    assert f"to {100 * doc['steps'][-1]['summary_error']:.2f} %" in page


@pytest.mark.slow
def test_demo_runs_the_lab_workflow_and_prints_where_the_report_is(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["-q", "demo", "--out", str(out), "--scenario", "rig"]) == 0
    printed = capsys.readouterr().out
    m = re.search(r"^report:\s+(\S+)$", printed, re.MULTILINE)
    assert m, printed
    report = Path(m.group(1))
    assert report == out / "diagnosis" / "report.html" and report.is_file()
    assert "rig_suspension" in printed
    doc = _no_nan((out / "diagnosis" / "diagnosis.json").read_text())
    assert doc["accepted"][0]["name"] == "rig_suspension"
    assert len(printed.splitlines()) < 25  # short and readable


@pytest.mark.slow
def test_lab_diagnose_reads_exported_frf_files_without_coherence(tmp_path, rig_result):
    """The lab's FRFs as an acquisition system exports them (flexural: binary, no coherence; torsional: ASCII
    mobility with coherence): the same diagnosis (rig_suspension, vertical within 25 % of the truth), the noise
    floor estimated from the modal fit for the file without coherence and said so in the report."""
    import ema
    import pandas as pd
    from ema.uff_frf import write_frf_uff

    folder = campaign_dir("rig", fe_export_hz=2000.0)
    argv = ["-q", "lab", "diagnose"]
    for setup, binary, quantity, coherence in (("flexural", True, "accelerance", False),
                                               ("torsional", False, "mobility", True)):
        table = pd.read_csv(folder / f"{setup}_channels.csv")
        test = ema.read_hammer(folder / f"{setup}.uff", table)
        H = ema.estimate_frf(test, screening=ema.screen_hits(test))
        path = write_frf_uff(H.as_quantity(quantity), tmp_path / f"{setup}_frf.uff", table, binary=binary,
                             coherence=coherence)
        argv += ["--frf", str(path), "--channels", str(folder / f"{setup}_channels.csv")]
    out = tmp_path / "out"
    description = tmp_path / "wheelset.toml"
    description.write_text('[rig]\nhanging_points = ["axlebox_L", "axlebox_R"]\n', encoding="utf-8")
    argv += ["--fem", str(folder / "fe_design.uff"), "--points", str(folder / "points.csv"), "--out", str(out),
             "--averages", "5", "--description", str(description), "--max-effects", "1"]
    assert main(argv) == 0
    doc = _no_nan((out / "diagnosis.json").read_text())
    truth = json.loads((folder / "truth.json").read_text())["scenario"]["effects"]["rig"]["vertical_N_per_m"]
    assert [a["name"] for a in doc["accepted"]] == ["rig_suspension"]
    assert doc["accepted"][0]["params"]["vertical_N_per_m"] == pytest.approx(truth, rel=0.25)
    by_name = {s["setup"]: s for s in doc["setups"]}
    assert "modal fit" in by_name["flexural"]["noise_floor_method"]
    assert "coherence" in by_name["torsional"]["noise_floor_method"] and by_name["torsional"]["n_averages"] == [5, 5]
    # the same data as the hammer files: the same diagnosis, and a floor near the one coherence gives
    hammer = rig_result[1]
    assert doc["accepted"][0]["params"]["vertical_N_per_m"] == pytest.approx(
        hammer["accepted"][0]["params"]["vertical_N_per_m"], rel=0.05)
    assert doc["initial"]["summary_error"] == pytest.approx(hammer["initial"]["summary_error"], rel=0.02)
    assert doc["initial"]["noise_floor"] == pytest.approx(hammer["initial"]["noise_floor"], rel=0.15)
    page = (out / "report.html").read_text(encoding="utf-8")
    assert "estimated from the measurement itself" in page


# ---------------------------------------------------------------------------------------------- bad input
def _files(tmp_path, *names):
    paths = []
    for n in names:
        p = tmp_path / n
        p.write_text("placeholder\n")
        paths.append(str(p))
    return paths


def test_hammer_without_its_channels_is_an_argparse_error(tmp_path, capsys):
    hammer, fem, points = _files(tmp_path, "a.uff", "fe.uff", "points.csv")
    with pytest.raises(SystemExit) as exc:
        main(["lab", "diagnose", "--hammer", hammer, "--fem", fem, "--points", points, "--out", str(tmp_path)])
    assert exc.value.code == 2
    assert "--channels" in capsys.readouterr().err


def test_mismatched_hammer_and_channels_counts_are_an_argparse_error(tmp_path, capsys):
    a, b, ca, fem, points = _files(tmp_path, "a.uff", "b.uff", "a.csv", "fe.uff", "points.csv")
    with pytest.raises(SystemExit) as exc:
        main(["lab", "diagnose", "--hammer", a, "--channels", ca, "--hammer", b, "--fem", fem, "--points", points,
              "--out", str(tmp_path / "out")])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "2 --hammer, 0 --frf and 1 --channels" in err
    assert not (tmp_path / "out").exists()


def test_missing_fe_file_is_named_before_any_work(tmp_path, capsys):
    a, ca, points = _files(tmp_path, "a.uff", "a.csv", "points.csv")
    fem = tmp_path / "nowhere" / "fe_design.uff"
    with pytest.raises(SystemExit) as exc:
        main(["lab", "diagnose", "--hammer", a, "--channels", ca, "--fem", str(fem), "--points", points,
              "--out", str(tmp_path / "out")])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--fem: FE modes" in err and str(fem) in err and "does not exist" in err
    assert not (tmp_path / "out").exists()  # failed fast: the placeholder hammer file was never read


def test_missing_hammer_file_is_named(tmp_path, capsys):
    a, ca, fem, points = _files(tmp_path, "a.uff", "a.csv", "fe.uff", "points.csv")
    missing = tmp_path / "b.uff"
    with pytest.raises(SystemExit) as exc:
        main(["lab", "diagnose", "--hammer", a, "--channels", ca, "--hammer", str(missing), "--channels", ca,
              "--fem", fem, "--points", points, "--out", str(tmp_path / "out")])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--hammer: hammer-test" in err and str(missing) in err


def test_hammer_and_frf_setups_pair_with_their_channels_in_order(tmp_path, capsys):
    a, b, ca, fem, points = _files(tmp_path, "a.uff", "b.uff", "a.csv", "fe.uff", "points.csv")
    with pytest.raises(SystemExit) as exc:
        main(["lab", "diagnose", "--hammer", a, "--channels", ca, "--frf", b, "--fem", fem, "--points", points,
              "--out", str(tmp_path / "out")])
    assert exc.value.code == 2
    assert "1 --hammer, 1 --frf and 1 --channels" in capsys.readouterr().err


def test_a_bad_description_is_named_before_any_work(tmp_path, capsys):
    a, ca, fem, points = _files(tmp_path, "a.uff", "a.csv", "fe.uff", "points.csv")
    desc = tmp_path / "wheelset.toml"
    desc.write_text("[axlebox]\nmass = 78\n")
    code = main(["lab", "diagnose", "--hammer", a, "--channels", ca, "--fem", fem, "--points", points,
                 "--description", str(desc), "--out", str(tmp_path / "out")])
    assert code == 1
    err = capsys.readouterr().err
    assert str(desc) in err and "unknown key 'mass'" in err
    assert not (tmp_path / "out").exists()


def test_fe_mass_and_points_are_checked_before_any_identification(tmp_path, capsys):
    """The FE export's rigid-body mass (against --total-mass) and the points' nodes are checked before the hammer
    files are read: the placeholder hammer file below is never opened, and nothing is written."""
    folder = campaign_dir("rig", fe_export_hz=2000.0)
    (hammer,) = _files(tmp_path, "a.uff")
    argv = ["lab", "diagnose", "--hammer", hammer, "--channels", str(folder / "flexural_channels.csv"),
            "--fem", str(folder / "fe_design.uff"), "--out", str(tmp_path / "out")]
    assert main(argv + ["--points", str(folder / "points.csv"), "--total-mass", "600"]) == 1
    err = capsys.readouterr().err
    assert "600" in err and "fe_design.uff" in err and "placeholder" not in err
    bad = tmp_path / "points.csv"
    lines = (folder / "points.csv").read_text().splitlines()
    header = lines[0].split(",")
    row = lines[1].split(",")
    row[header.index("fe_node")] = "987654"
    bad.write_text("\n".join([lines[0], ",".join(row)] + lines[2:]) + "\n")
    assert main(argv + ["--points", str(bad)]) == 1
    err = capsys.readouterr().err
    assert "987654" in err and str(bad) in err
    assert not (tmp_path / "out").exists()


def test_two_setups_with_the_same_name_are_refused_before_any_work(tmp_path, capsys):
    a, b, fem, points = _files(tmp_path, "a.uff", "b.uff", "fe.uff", "points.csv")
    table = tmp_path / "same.csv"
    table.write_text("node,name,quantity,unit,x,y,z,dx,dy,dz,fe_node,setup\n"
                     "900,hammer,force,N,0,0,0,0,0,1,1,flexural\n"
                     "101,axle_01,acceleration,m/s^2,0,0.5,0,0,0,1,2,flexural\n")
    code = main(["lab", "diagnose", "--hammer", a, "--channels", str(table), "--hammer", b, "--channels",
                 str(table), "--fem", fem, "--points", points, "--out", str(tmp_path / "out")])
    assert code == 1
    err = capsys.readouterr().err
    assert "same name 'flexural'" in err and a in err and b in err and "give them all after one --hammer" in err
    assert not (tmp_path / "out").exists()


def test_hits_stored_in_several_files_are_one_setup(tmp_path, capsys, monkeypatch):
    """A lab that writes one hit per file gives them all after one --hammer: one setup (read as one test by
    ema.read_hammer), paired with its --channels; the same-name refusal says how to do it."""
    import railmodal.diagnose_command as dc

    a, b, c, ca, cb, fem, points = _files(tmp_path, "h1.uff", "h2.uff", "t.uff", "a.csv", "b.csv", "fe.uff",
                                          "points.csv")
    seen = {}

    def fake(setups, *args, **kwargs):
        seen["setups"] = setups
        raise ValueError("stop here")

    monkeypatch.setattr(dc, "run_staged", fake)
    assert main(["lab", "diagnose", "--hammer", a, b, "--channels", ca, "--hammer", c, "--channels", cb, "--fem",
                 fem, "--points", points, "--out", str(tmp_path / "out")]) == 1
    first, second = seen["setups"]
    assert [str(f) for f in first.files] == [a, b] and str(first.channels) == ca and first.data == Path(a)
    assert [str(f) for f in second.files] == [c] and str(second.channels) == cb
    assert "(2 files)" in first.label and second.label == c


def test_diagnosis_json_converter_makes_strict_json():
    doc = {"a": np.float64(0.25), "b": np.int32(3), "c": (np.nan, np.inf, 1.5), "d": np.array([1.0, 2.0]),
           "e": np.bool_(True), "f": Path("x/y"), 7: complex(1, -2)}
    out = to_jsonable(doc)
    text = json.dumps(out, allow_nan=False)
    back = json.loads(text)
    assert back == {"a": 0.25, "b": 3, "c": [None, None, 1.5], "d": [1.0, 2.0], "e": True, "f": "x/y",
                    "7": {"re": 1.0, "im": -2.0}}
    assert isinstance(back["b"], int) and not math.isnan(back["a"])
