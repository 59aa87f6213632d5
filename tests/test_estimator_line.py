"""Acceptance of the field estimate on the virtual line (issue 13): no inverse crime.

The virtual line (``lab_data.line``) makes its accelerations with a time-domain simulation the estimator
knows nothing of (the lab's as-built truth wheelsets on their primary suspension, a discretely supported
Timoshenko track, non-linear Hertz contact, DAQ noise, anti-aliasing, sensor offsets and sensitivity errors).
The truth band indexes are computed from the line's true rail roughness by the same EN processing
(:func:`estimator.reference.reference_indexes`): the comparison is per 1 m chainage window, over the body of
curve 1 where rail R (the low rail of a right-hand curve) carries the corrugation.

The noise floor of a band is the peak-to-peak the DAQ noise alone would give: the DAQ's noise (white,
``daq.noise_rms``, written in the truth) through the estimator's own inverse filter over the frequencies the
band occupies at the run's speed — ``σ_n² = Σ_j ∫ |T_ij(f)|² (2 σ²/fs) df`` and ``pk-pk = 2√2 σ_n``; a window
counts where the truth lies 6 dB above it.
"""

from __future__ import annotations

import functools
import json
import math

import numpy as np
import pandas as pd
import pytest

from test_estimator_synthetic import control_model

pytestmark = pytest.mark.slow

BANDS = ((30.0, 100.0), (100.0, 300.0))
#: how far above the noise floor a truth window must lie to count [dB]
ABOVE_FLOOR_DB = 6.0


def truth_of(folder) -> dict:
    return json.loads((folder / "truth" / "truth.json").read_text())


def runs_of(folder) -> list[dict]:
    runs = truth_of(folder)["runs"]
    return runs if isinstance(runs, list) else []


def corrugated_span(folder) -> tuple[str, tuple[float, float]]:
    """Rail and chainage span of the corrugation patch on curve 1's body (the patch's tapers left out)."""
    t = truth_of(folder)
    line = json.loads((folder / "line.json").read_text())
    curve = min(line["curves"], key=lambda c: c["from_m"])
    body = (curve["from_m"] + curve["transition_in_m"], curve["to_m"] - curve["transition_out_m"])
    patch = next(p for p in t["roughness"]["config"]["patches"] if p["from_m"] < body[1] and p["to_m"] > body[0])
    a = max(body[0], patch["from_m"] + patch["taper_m"])
    b = min(body[1], patch["to_m"] - patch["taper_m"])
    return patch["rail"], (float(a), float(b))


def true_rails(folder, date: str) -> pd.DataFrame:
    rr = pd.read_parquet(folder / "truth" / "rail_roughness" / f"{date}.parquet")
    return pd.concat([pd.DataFrame({"chainage_m": rr["chainage_m"], "rail": rail,
                                    "roughness_m": rr[f"{rail}_um"].to_numpy(float) * 1e-6}) for rail in "LR"],
                     ignore_index=True)


def field_model(folder, model, models=("half", "vertical", "vertical_lateral")):
    """The estimator as an analyst sets it up: the campaign's sensor table and line, the car's wheel load."""
    from estimator import EstimatorConfig, prepare
    from receptance import ContactParameters

    load = truth_of(folder)["vehicle"]["static_wheel_load_N"]  # the car's static wheel load: known to an analyst
    cfg = EstimatorConfig(models=models, contact=ContactParameters(wheel_load_N=load))
    return prepare(model, folder / "sensors.csv", line=folder / "line.json", config=cfg)


def noise_floor_um(fm, est, run_path, wheelset: int, model: str, band, speed: float, noise_rms: float) -> float:
    """Peak-to-peak [µm] the DAQ noise alone gives in ``band`` through the inverse filter (module docstring)."""
    from estimator.inversion import model_channels
    from estimator.io import read_run

    run = read_run(run_path, fm.sensors)
    chans = run.wheelset_channels(wheelset)
    rows, _ = model_channels(model, chans)
    sub = chans.loc[rows].reset_index(drop=True).drop(columns="row")
    tr = fm.transfer(model, sub, run.fs, -1, (0.0, 0.0))
    f = tr.freqs_hz
    sel = (f >= speed / (band[1] * 1e-3)) & (f <= speed / (band[0] * 1e-3))
    df = f[1] - f[0]
    var = (np.abs(tr.T[sel]) ** 2).sum(axis=2) * (2 * noise_rms ** 2 / run.fs) * df  # (n_f, sides)
    return float(2 * math.sqrt(2) * math.sqrt(var.sum(axis=0).max()) * 1e6)


@functools.lru_cache(maxsize=None)
def nominal_case():
    """A single forward run of `nominal` over curve 1, estimated with the control wheelset's hybrid model."""
    from estimator import estimate_run
    from estimator.reference import reference_indexes
    from lab_data.line.campaign import FIRST_CURVE_SECTION
    from lab_data.line.cache import line_campaign_dir

    folder = line_campaign_dir("nominal", days=1, runs_per_day=1, section=FIRST_CURVE_SECTION)
    run = runs_of(folder)[0]
    fm = field_model(folder, control_model())
    est = estimate_run(folder / run["file"], fm)
    ref = reference_indexes(true_rails(folder, run["date"]), fm.config)
    return folder, run, fm, est, ref


def floors(case, model="vertical_lateral") -> dict:
    folder, run, fm, est, _ = case
    rail, span = corrugated_span(folder)
    p = est.profile(est.leading, model)
    i0, i1 = np.searchsorted(p.chainage_m, span)
    v = float(np.nanmedian(p.speed_m_s[i0:i1]))
    noise = truth_of(folder)["daq"]["noise_rms"]
    return {band: noise_floor_um(fm, est, folder / run["file"], est.leading, model, band, v, noise) * 10 ** (
        ABOVE_FLOOR_DB / 20) for band in BANDS}


def band_errors(case, models=None) -> pd.DataFrame:
    from estimator.reference import compare_bands

    folder, run, fm, est, ref = case
    _, span = corrugated_span(folder)
    return compare_bands(est, ref, span, min_reference_um=floors(case), models=models, bands=BANDS)


def test_nominal_band_peak_to_peak_on_the_corrugated_curve():
    """vertical + lateral model, leading wheelset: ±1.5 dB mean, ±3 dB on ≥ 90 % of the 1 m windows."""
    case = nominal_case()
    folder, run, fm, est, ref = case
    rail, _ = corrugated_span(folder)
    e = band_errors(case, models=["vertical_lateral"])
    e = e[(e["wheelset"] == est.leading) & (e["rail"] == rail)].set_index("band_mm")
    for band in ("30-100", "100-300"):
        r = e.loc[band]
        assert r["n_windows"] >= 100, r
        assert abs(r["mean_error_db"]) <= 1.5, r
        assert r["within_3db_pct"] >= 90.0, r


def test_nominal_the_wheels_stay_on_the_rails():
    """The line's non-linear Hertz contact lost no contact on this run (its truth lists no event), and the
    estimate flags none: the estimated dynamic force stays within about +/-0.2 of the static load there."""
    folder, run, fm, est, _ = nominal_case()
    assert run["contact_loss"] == []
    assert not (est.qc["kind"] == "contact_loss").any()
    assert any("the wheels stay on the rails" in s for s in est.processing)


def test_nominal_the_corrugated_rail_is_identified_in_both_bands():
    """The corrugated rail's band level exceeds the other rail's in both bands, keeping at least half the truth's contrast."""
    from estimator.reference import window_pk

    folder, run, fm, est, ref = nominal_case()
    rail, span = corrugated_span(folder)
    other = "L" if rail == "R" else "R"
    edges = np.arange(span[0], span[1] + 1e-9, 1.0)
    for w in (1, 2):
        p = est.profile(w, "vertical_lateral")
        for band in BANDS:
            lv = {r: np.sqrt(np.nanmean(window_pk(p.chainage_m, p.pk_pk(band, r), edges) ** 2)) for r in "LR"}
            tv = {r: np.sqrt(np.nanmean(window_pk(*ref.pk_pk(band, r), edges) ** 2)) for r in "LR"}
            d_true, d_est = 20 * math.log10(tv[rail] / tv[other]), 20 * math.log10(lv[rail] / lv[other])
            assert d_true > 0  # the truth's side
            # the same side, clearly: at least half the truth's contrast between the rails (in dB) is kept
            # (the thesis could not tell the side in 30-100 mm: there the contrast vanished)
            assert d_est >= 0.5 * d_true, (w, band, d_est, d_true)


def test_nominal_en15610_spectrum_of_the_corrugated_section():
    """L_r of the corrugated rail within ±2 dB of the truth in every one-third-octave band the run resolves."""
    from estimator.reference import compare_spectra

    folder, run, fm, est, ref = nominal_case()
    rail, span = corrugated_span(folder)
    s = compare_spectra(est, ref, span, fm.config, models=["vertical_lateral"], wheelsets=[est.leading])
    s = s[s["rail"] == rail].dropna(subset=["error_db"])
    assert len(s) >= 8  # the run resolves more than a decade of wavelengths on the curve
    worst = s.loc[s["error_db"].abs().idxmax()]
    assert s["error_db"].abs().max() <= 2.0, worst


def test_three_models_compared_on_the_line():
    """The three transfer-function models on the same run (measured, leading wheelset, RMS of the 1 m window
    errors): on the corrugated rail all three are within 2 dB and the vertical + lateral model within 0.5 dB of
    the best; on the other rail, whose estimate the corrugation's cross-talk spoils, the vertical + lateral model
    wins clearly in both bands (the half model, blind to the other wheel, is worst)."""
    from estimator.reference import models_ranking

    case = nominal_case()
    folder, run, fm, est, ref = case
    rail, _ = corrugated_span(folder)
    other = "L" if rail == "R" else "R"
    e = band_errors(case)
    e = e[e["wheelset"] == est.leading]
    rank = models_ranking(e).set_index(["rail", "band_mm"])
    assert set(e["model"]) == {"half", "vertical", "vertical_lateral"}
    assert (e.loc[e["rail"] == rail, "rms_error_db"] <= 2.0).all(), e
    for band in ("30-100", "100-300"):
        r = rank.loc[(rail, band)]
        assert r["rms_error_db_vertical_lateral"] <= min(r["rms_error_db_half"], r["rms_error_db_vertical"]) + 0.5, r
        o = rank.loc[(other, band)]
        assert o["best_model"] == "vertical_lateral", o
        assert o["rms_error_db_half"] > o["rms_error_db_vertical"] > o["rms_error_db_vertical_lateral"], o


def test_leading_and_trailing_wheelsets_agree_within_their_scatter():
    """Both wheelsets estimate the same rails: their mean difference lies within the scatter of the window
    differences (its standard error times 3, the windows of 1 m being nearly independent beyond 1.5 m)."""
    from estimator.export import lead_trail_agreement

    folder, run, fm, est, ref = nominal_case()
    rail, span = corrugated_span(folder)
    a = lead_trail_agreement(est, "vertical_lateral")
    a = a[(a["rail"] == rail) & a["band_mm"].isin(["30-100", "100-300"])]
    assert len(a) == 2
    for r in a.itertuples():
        n_eff = r.n_windows / 1.5
        assert abs(r.mean_diff_db) <= max(3 * r.std_diff_db / math.sqrt(n_eff), 0.5), r
        assert abs(r.mean_diff_db) <= 1.5, r


def test_sleeper_passing_is_found_on_the_line_and_is_the_rails_deflection_under_the_wheel():
    """The wheel follows the rail's deflection under its own load across each sleeper bay. The sleeper comb
    finds its order 1 on both rails of both wheelsets, with an amplitude within 25 % of ``P α(x)``: the line's
    static wheel load times the discretely supported track's receptance across a bay
    (:func:`estimator.sleepers.quasi_static_orders`, held to a static Timoshenko beam FE in
    ``tests/test_estimator_sleepers.py``; it shares no code with the line's time-domain track). The line holds no
    rail roughness periodic with the sleepers, and no other order stands out.

    Measured: 16–17 µm on the line against 18.1 µm quasi-static. I did not identify the 10 % gap. The
    wheelset's inertia at 12–15 Hz is not it: the track's receptance there is only 1 % above the static one.
    """
    folder, run, fm, est, _ = nominal_case()
    x = est.profile(est.leading, "vertical_lateral").chainage_m
    sections = fm.trackforms()
    main = max(sections, key=lambda s: max(0.0, min(s[1], x[-1]) - max(s[0], x[0])))[2]
    from estimator.sleepers import quasi_static_orders

    oracle = quasi_static_orders(main, truth_of(folder)["vehicle"]["static_wheel_load_N"])[0] * 1e6
    assert 10.0 < oracle < 30.0  # the oracle itself is what a metro track gives (0.8 mm static deflection)
    for w in (1, 2):
        sp = est.profile(w, "vertical_lateral").sleeper
        assert sp.spacing_m == pytest.approx(json.loads((folder / "line.json").read_text())["sleeper_spacing_m"])
        for rail in "LR":
            removed = sp.removed(rail)
            assert list(removed["order"]) == [1], (w, rail, removed)
            assert removed["amplitude_m"].iloc[0] * 1e6 == pytest.approx(oracle, rel=0.25), (w, rail)
    assert any(s.startswith("sleeper passing (spacing 0.75 m") for s in est.processing)
    # the estimator's own expectation (the analyst's wheel load on the line's trackform) is reported beside it
    expected = est.profile(est.leading, "vertical_lateral").sleeper.removed("L")["expected_m"].iloc[0] * 1e6
    load = fm.config.contact.wheel_load_N
    assert expected == pytest.approx(quasi_static_orders(main, load)[0] * 1e6, rel=1e-9)


def test_wheel_polygon_is_separated_on_the_line():
    """`wheel_polygon` (12th order, 15 µm on wheelset 1 left): the rail estimate after the comb within 1 dB of
    the `nominal` run's, the polygon's order and amplitude within 20 %."""
    from estimator import estimate_run
    from lab_data.line.campaign import FIRST_CURVE_SECTION
    from lab_data.line.cache import line_campaign_dir

    folder0, run0, fm0, est0, _ = nominal_case()
    folder = line_campaign_dir("wheel_polygon", days=1, runs_per_day=1, section=FIRST_CURVE_SECTION)
    t = truth_of(folder)
    poly = t["scenario"]["wheel_polygon"]
    wheel = ("1L", "1R", "2L", "2R")[poly["wheel"]]
    w, side = int(wheel[0]), wheel[1]
    est = estimate_run(folder / runs_of(folder)[0]["file"], field_model(folder, control_model(),
                                                                         models=("vertical_lateral",)))
    p = est.profile(w, "vertical_lateral")
    top = p.wheel.polygon(side).iloc[0]
    assert top["order"] == poly["order"]
    assert top["amplitude_m"] == pytest.approx(poly["amplitude_m"], rel=0.2)
    q = est0.profile(w, "vertical_lateral")
    rail = est.profile(w, "vertical_lateral").rails[("L", "R").index(side)]
    lo, hi = max(p.chainage_m[0], q.chainage_m[0]) + 5, min(p.chainage_m[-1], q.chainage_m[-1]) - 5
    for band in BANDS:
        a, b = p.pk_pk(band, rail), np.interp(p.chainage_m, q.chainage_m, q.pk_pk(band, rail))
        ok = np.isfinite(a) & np.isfinite(b) & (p.chainage_m > lo) & (p.chainage_m < hi)
        assert abs(10 * np.log10(np.mean(a[ok] ** 2) / np.mean(b[ok] ** 2))) <= 1.0, band


@functools.lru_cache(maxsize=None)
def bearing_models():
    """The lab's `bearing` campaign through the lab workflow: the hybrid model before the diagnosis (no effect) and
    the diagnosed one (the effects it accepted), as `railmodal lab diagnose` saves it."""
    import tempfile
    from pathlib import Path

    from lab_data.cache import campaign_dir
    from receptance.diagnosis.workflow import run_lab_diagnosis

    d = campaign_dir("bearing", fe_export_hz=2000.0)
    setups = [(d / f"{s}.uff", d / f"{s}_channels.csv") for s in ("flexural", "torsional")]
    with tempfile.TemporaryDirectory(prefix="bearing_diagnosis_") as out:  # the models stay in memory
        result = run_lab_diagnosis(setups, d / "fe_design.uff", d / "points.csv", Path(out) / "diagnosis")
    return result.model.without_modifications(), result.model, result


def bearing_errors() -> pd.DataFrame:
    """Band errors on curve 1 of the line run with the lab's `bearing` wheelsets, model before and after diagnosis."""
    from estimator import estimate_run
    from estimator.reference import compare_bands, reference_indexes
    from lab_data.line.campaign import FIRST_CURVE_SECTION
    from lab_data.line.cache import line_campaign_dir

    folder = line_campaign_dir("nominal", days=1, runs_per_day=1, section=FIRST_CURVE_SECTION,
                               wheelset_scenario="bearing")
    run = runs_of(folder)[0]
    before, after, _ = bearing_models()
    _, span = corrugated_span(folder)
    frames = []
    for name, model in (("before", before), ("after", after)):
        fm = field_model(folder, model, models=("vertical_lateral",))
        est = estimate_run(folder / run["file"], fm)
        ref = reference_indexes(true_rails(folder, run["date"]), fm.config)
        frames.append(compare_bands(est, ref, span, bands=BANDS).assign(model_state=name))
    return pd.concat(frames, ignore_index=True)


def test_bearing_estimate_is_closer_to_the_truth_after_the_lab_diagnosis():
    """End to end with the lab: on the line with the `bearing` wheelsets, the estimate made with the diagnosed
    hybrid model is closer to the truth (RMS of the 1 m window errors, both rails, both bands, both wheelsets)."""
    _, after, result = bearing_models()
    assert any("bearing" in m.kind for m in after.modifications), [m.kind for m in after.modifications]
    e = bearing_errors()
    rms = e.groupby("model_state").apply(lambda g: float(np.sqrt(np.mean(g["rms_error_db"] ** 2))),
                                         include_groups=False)
    assert rms["after"] < rms["before"], e


def test_calibrated_angles_for_a_curve_the_line_lacks_are_refused_not_carried_as_if_applied(tmp_path):
    """A calibration holding contact angles for curve 'C9' prepared with a line whose only curve is 'C1' (another
    line's calibration, a renamed curve) is a ConfigurationError naming both; without any line it says that the
    angles need one; with the right id it prepares."""
    import json

    from estimator import ConfigurationError, EstimatorConfig, prepare, read_line
    from test_estimator_synthetic import control_model, sensor_table

    (tmp_path / "line.json").write_text(json.dumps({"name": "M1", "curves": [
        {"id": "C1", "from_m": 100, "to_m": 300, "radius_m": 400, "direction": "left"}]}))
    line = read_line(tmp_path / "line.json")
    model, table = control_model(), sensor_table()
    cfg = EstimatorConfig(curve_contact_angles={"C9": {"leading": (0.3, 0.03)}})
    with pytest.raises(ConfigurationError, match=r"curve\(s\) \['C9'\], which line .*line.json' does not have "
                                                 r"\(its curves: \['C1'\]\)"):
        prepare(model, table, line=line, config=cfg)
    with pytest.raises(ConfigurationError, match="only a line description can place"):
        prepare(model, table, config=cfg)
    fm = prepare(model, table, line=line, config=EstimatorConfig(curve_contact_angles={"C1": {"any": (0.3, 0.03)}}))
    assert fm.config.curve_angles("C1", "leading", {"L": "L", "R": "R"}) == pytest.approx((-0.3, 0.03))


def test_a_chainage_counted_from_the_runs_start_is_not_laid_on_the_line(tmp_path):
    """A speed-only logger without a balise channel gives a chainage relative to the run's start: laid on the line
    it would take another stretch's curves (contact angles), trackforms and section names, silently. With a line
    the estimate is refused, naming the run and the line; one balise passage makes the chainage absolute."""
    import json

    from estimator import ConfigurationError, estimate_run, prepare, read_line
    from test_estimator_io import _channels, _write
    from test_estimator_synthetic import control_model, sensor_table

    (tmp_path / "line.json").write_text(json.dumps({"name": "M1", "curves": [
        {"id": "C1", "from_m": 100, "to_m": 300, "radius_m": 400, "direction": "left"}]}))
    table = sensor_table().query("quantity not in ('position', 'balise')")
    ch = {k: v for k, v in _channels().items() if k not in ("POSITION", "BALISE")}
    run = _write(tmp_path, "speedonly", ch, "parquet")
    model = control_model()
    with pytest.raises(ConfigurationError, match=r"speedonly.parquet: the run's chainage counts from its start "
                                                 r"\(position integrated from SPEED, no balise passage\), so it "
                                                 r"cannot be placed on line .*line.json"):
        estimate_run(run, prepare(model, table, line=read_line(tmp_path / "line.json")))
    from estimator import read_run

    assert read_run(run, table).odometry.chainage_relative
    with_balise = _write(tmp_path, "balise", {**ch, "BALISE": _channels()["BALISE"]}, "parquet")
    assert not read_run(with_balise, sensor_table().query("quantity != 'position'")).odometry.chainage_relative


def test_chainage_no_trackform_section_holds_is_named(tmp_path):
    """A line whose trackform sections cover 0-500 m and 560-1000 m: a wheelset passing 480-600 m is told that
    500-560 m takes the default trackform (the stretches it passes there, to the sample); a line covering it all,
    or a trackform given for the whole run, says nothing."""
    import json

    from estimator import prepare, read_line
    from estimator.workflow import _outside_trackforms
    from test_estimator_synthetic import control_model, sensor_table

    tfs = [{"from_m": 0, "to_m": 500, "trackform": "slab", "pad_stiffness_z": 150e6},
           {"from_m": 560, "to_m": 1000, "trackform": "slab", "pad_stiffness_z": 150e6}]
    (tmp_path / "line.json").write_text(json.dumps({"name": "M1", "trackform_sections": tfs}))
    model, table = control_model(), sensor_table()
    fm = prepare(model, table, line=read_line(tmp_path / "line.json"))
    x = np.linspace(480.0, 600.0, 1201)
    (msg,) = _outside_trackforms(fm, {1: x})
    assert "wheelset 1 passes chainage 500.1-559.9 m, which no trackform section" in msg
    assert "they cover 0-500 m, 560-1000 m" in msg and "default trackform" in msg
    assert _outside_trackforms(fm, {1: np.linspace(10.0, 490.0, 50), 2: np.linspace(570.0, 990.0, 50)}) == []
    from receptance import Trackform

    assert _outside_trackforms(prepare(model, table, line=read_line(tmp_path / "line.json"), trackform=Trackform()),
                               {1: x}) == []
