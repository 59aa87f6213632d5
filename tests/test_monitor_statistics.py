"""Averaging, intervals, consistency checks, grinding detection and trends against closed forms and simulations.

Oracles: hand-computed energy means and weights; the coverage of the
run-to-run interval over many simulated days (energies scattering as a
moving mean square does: scaled χ²); quadrature of the interval sources;
synthetic survey days with a known step drop (grinding), a known offset
between wheelsets or directions, a known growth line and its threshold
crossing.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from estimator.monitoring.averaging import day_average, energy_mean_db, section_table
from estimator.monitoring.config import MonitoringConfig
from estimator.monitoring.confidence import coverage, variant_deltas, variant_spread, with_intervals
from estimator.monitoring.consistency import consistency_checks
from estimator.monitoring.grinding import detect_grinding, grinding_effect
from estimator.monitoring.records import Sections
from estimator.monitoring.trends import day_number, forecast, growth

CFG = MonitoringConfig()


def rows(run_id, pk, *, window=0.0, wheelset=1, role="leading", rail="L", band="30-100", valid=1.0, speed=10.0,
         date="2024-03-04", direction="forward", section="s"):
    return {"run_id": run_id, "pk_pk_um": pk, "window_m": window, "wheelset": wheelset, "role": role, "rail": rail,
            "band_mm": band, "valid_share": valid, "speed_m_s": speed, "date": date, "direction": direction,
            "section": section}


# ----------------------------------------------------------------------------- averaging
def test_energy_average_weights_and_per_run_combination():
    w = pd.DataFrame([rows("a", 3.0), rows("b", 4.0)])
    d = day_average(w)
    assert d["pk_pk_um"].iloc[0] == pytest.approx(math.sqrt((9 + 16) / 2), rel=1e-12)
    assert d["runs"].iloc[0] == 2
    # masked share 0.5 halves a run's weight
    d = day_average(w, {"a": 0.5, "b": 0.0})
    assert d["pk_pk_um"].iloc[0] == pytest.approx(math.sqrt((0.5 * 9 + 16) / 1.5), rel=1e-12)
    # a run at half the median speed weighs (1/2)² (median of 5, 10, 10 is 10)
    w3 = pd.DataFrame([rows("a", 3.0, speed=5.0), rows("b", 4.0), rows("c", 4.0)])
    assert day_average(w3)["pk_pk_um"].iloc[0] == pytest.approx(math.sqrt((0.25 * 9 + 32) / 2.25), rel=1e-12)
    # the two wheelsets of one run are one estimate; a window with too few valid samples is left out
    w4 = pd.DataFrame([rows("a", 3.0), rows("a", 5.0, wheelset=2, role="trailing"), rows("b", 4.0),
                       rows("c", 100.0, valid=0.3)])
    d = day_average(w4)
    assert d["runs"].iloc[0] == 2
    assert d["pk_pk_um"].iloc[0] == pytest.approx(math.sqrt((17 + 16) / 2), rel=1e-12)


def test_section_values_are_energy_means_weighted_by_valid_share():
    w = pd.DataFrame([rows("a", 2.0, window=0.0, valid=1.0), rows("a", 4.0, window=1.0, valid=0.6),
                      rows("a", 50.0, window=2.0, valid=0.2)])
    s = section_table(w)
    assert s["pk_pk_um"].iloc[0] == pytest.approx(math.sqrt((4 + 0.6 * 16) / 1.6), rel=1e-12)
    assert energy_mean_db([0.0, 10.0]) == pytest.approx(10 * math.log10((1 + 10) / 2))


# ----------------------------------------------------------------------------- intervals
def test_run_to_run_interval_covers_the_true_level_95_percent_of_days():
    """Each run's window energy is the truth's times χ²_k/k (a moving mean square of a Gaussian signal over k
    independent samples); over 600 simulated days of 7 runs the 95 % interval holds the truth 92–98 % of the time."""
    rng = np.random.default_rng(11)
    n_days, n_runs, k, truth_um = 600, 7, 12, 20.0
    e = truth_um ** 2 * rng.chisquare(k, size=(n_days, n_runs)) / k
    w = pd.DataFrame([rows(f"r{j}", math.sqrt(e[i, j]), window=float(i)) for i in range(n_days) for j in range(n_runs)])
    d = with_intervals(day_average(w))
    truth = pd.DataFrame({"rail": "L", "band_mm": "30-100", "window_m": np.arange(n_days, dtype=float),
                          "level_db": 20 * math.log10(truth_um)})
    cov = coverage(d, truth, by=())
    assert 0.92 <= cov["coverage"].iloc[0] <= 0.98
    assert np.isnan(with_intervals(day_average(w[w["run_id"] == "r0"]))["scatter_hi_db"]).all()  # one run: no scatter


def test_sources_combine_in_quadrature_on_each_side():
    day = pd.DataFrame({"date": ["d"], "rail": ["L"], "band_mm": ["30-100"], "window_m": [0.0], "level_db": [20.0],
                        "n_eff": [1e9], "se_db": [1.0 / 1.959963984540054], "pk_pk_um": [10.0]})
    spread = pd.DataFrame({"date": ["d", "d"], "source": ["model", "placement"], "rail": ["L", "L"],
                           "band_mm": ["30-100"] * 2, "window_m": [0.0, 0.0], "lo_db": [-2.0, 0.4],
                           "hi_db": [3.0, 0.5]})
    out = with_intervals(day, spread).iloc[0]
    assert out["scatter_hi_db"] == pytest.approx(1.0, rel=1e-6)
    assert out["ci_lo_db"] == pytest.approx(20 - math.sqrt(1 + 4), rel=1e-6)  # placement above nominal: no lower part
    assert out["ci_hi_db"] == pytest.approx(20 + math.sqrt(1 + 9 + 0.25), rel=1e-6)


def test_reference_calibration_is_a_prediction_interval_that_covers_windows_it_did_not_see():
    """Window errors N(+0.6 dB, 0.5 dB) (the estimator's bias and window-to-window error on the line): a calibration
    site of n windows bounds the truth of the windows it did not see in 95 % of them on average over repeated
    sites (93.5-96.5 %), for long sites (n = 300) and short ones (n = 8: Student's t widens the interval, so
    short sites still cover); a band with fewer windows than ``min_windows`` is not calibrated; the site range
    selects the windows."""
    from estimator.monitoring.confidence import reference_calibration

    rng = np.random.default_rng(21)
    for n, trials in ((300, 40), (8, 400)):
        covered = []
        for _ in range(trials):
            site = pd.DataFrame({"rail": "L", "band_mm": "30-100", "window_m": np.arange(n, dtype=float),
                                 "error_db": rng.normal(0.6, 0.5, n)})
            cal = reference_calibration(site).iloc[0]
            other = rng.normal(0.6, 0.5, 200)
            truth_offset = -other  # the truth lies at L - error
            covered.append(((truth_offset >= cal["lo_db"]) & (truth_offset <= cal["hi_db"])).mean())
        assert 0.935 <= np.mean(covered) <= 0.965, (n, np.mean(covered))
    errs = pd.DataFrame({"rail": ["L", "R", "L"], "band_mm": ["30-100", "30-100", "100-300"],
                         "window_m": [1.0, 2.0, 50.0], "error_db": [0.5, 0.7, 0.1]})
    cal = reference_calibration(errs, site=(0.0, 10.0), min_windows=2).set_index("band_mm")
    assert list(cal.index) == ["30-100"] and cal.loc["30-100", "windows"] == 2
    assert cal.loc["30-100", "mean_error_db"] == pytest.approx(0.6)
    assert np.isnan(reference_calibration(errs, min_windows=5)[["lo_db", "hi_db"]].to_numpy()).all()


def test_the_reference_source_widens_each_side_in_quadrature_and_keeps_the_floor():
    from estimator.monitoring.confidence import with_reference

    day = pd.DataFrame({"rail": ["L", "L", "L"], "band_mm": ["30-100", "30-100", "300-1000"],
                        "window_m": [0.0, 1.0, 0.0], "level_db": [20.0, 20.0, 30.0],
                        "ci_lo_db": [19.0, -np.inf, 29.0], "ci_hi_db": [22.0, 20.0, 31.0]})
    cal = pd.DataFrame({"band_mm": ["30-100"], "lo_db": [-1.5], "hi_db": [0.4]})
    out = with_reference(day, cal)
    assert out["ci_lo_db"].iloc[0] == pytest.approx(20 - math.sqrt(1 + 2.25))
    assert out["ci_hi_db"].iloc[0] == pytest.approx(20 + math.sqrt(4 + 0.16))
    assert out["ci_lo_db"].iloc[1] == -np.inf  # below the noise floor: no lower bound, as before
    assert (out.iloc[2][["ci_lo_db", "ci_hi_db"]].to_numpy() == [29.0, 31.0]).all()  # band not calibrated
    assert np.isnan(out["reference_hi_db"].iloc[2]) and out["reference_lo_db"].iloc[0] == -1.5
    cal_below = pd.DataFrame({"band_mm": ["30-100"], "lo_db": [-2.0], "hi_db": [-0.5]})  # truth always below
    assert with_reference(day, cal_below)["ci_hi_db"].iloc[0] == pytest.approx(22.0)


def test_variant_spread_is_the_quantile_of_level_differences_against_the_same_run():
    nom = pd.DataFrame([rows("a", 10.0), rows("b", 20.0)])
    rng = np.random.default_rng(3)
    dv = rng.normal(0.0, 1.5, size=(2, 40))
    var = pd.DataFrame([{**rows(r, p * 10 ** (dv[i, j] / 20)), "source": "model", "variant": f"m{j}"}
                        for i, (r, p) in enumerate((("a", 10.0), ("b", 20.0))) for j in range(40)])
    sp = variant_spread(variant_deltas(var, nom))
    assert sp["lo_db"].iloc[0] == pytest.approx(np.quantile(dv.ravel(), 0.025), abs=1e-9)
    assert sp["hi_db"].iloc[0] == pytest.approx(np.quantile(dv.ravel(), 0.975), abs=1e-9)
    assert sp["variants"].iloc[0] == 80


def test_a_source_of_several_parameters_adds_each_parameters_side_in_quadrature():
    """Track variants of one run: pad stiffness x2 / x0.5 move the level by +0.6 / -0.8 dB, the supports by
    +0.3 dB, the loss law (two ends) by -0.4 / -0.1 dB: independent unknowns, so the source's sides are
    -sqrt(0.8² + 0.4²) and +sqrt(0.6² + 0.3²) — not the largest single deviation; a source of one parameter
    (joint draws) keeps its quantiles."""
    from estimator.monitoring.confidence import parameter_of

    nom = pd.DataFrame([rows("a", 10.0)])
    moves = {"pad stiffness x2": 0.6, "pad stiffness x0.5": -0.8, "discrete supports (midspan)": 0.3,
             "causal layers, stated stiffness at 10 Hz": -0.4, "causal layers, stated stiffness at 1e+03 Hz": -0.1}
    var = pd.DataFrame([{**rows("a", 10.0 * 10 ** (db / 20)), "source": "track", "variant": label}
                        for label, db in moves.items()])
    sp = variant_spread(variant_deltas(var, nom), confidence=1.0).iloc[0]
    assert sp["parameters"] == 3 and sp["variants"] == 5
    assert sp["lo_db"] == pytest.approx(-math.hypot(0.8, 0.4), abs=1e-9)
    assert sp["hi_db"] == pytest.approx(math.hypot(0.6, 0.3), abs=1e-9)
    assert sp["median_db"] == pytest.approx(-0.1, abs=1e-9)
    assert [parameter_of(v) for v in ("shift y -30 mm", "wheel load +25 %", "rail head radius 200 mm", "model 07")] \
        == ["shift y", "wheel load", "rail head radius", "model"]


# ----------------------------------------------------------------------------- consistency
def _survey(n_runs=6, span=(0, 300), noise_db=0.4, seed=0, lead_offset=None, fwd_offset=None, corr=None):
    rng = np.random.default_rng(seed)
    out = []
    for r in range(n_runs):
        direction = "forward" if r % 2 == 0 else "backward"
        for x in np.arange(*span, 1.0):
            for ws, role in ((1, "leading"), (2, "trailing")):
                L = 20 + noise_db * rng.standard_normal()
                if lead_offset and role == "leading" and lead_offset[0] <= x < lead_offset[1]:
                    L += lead_offset[2]
                if fwd_offset and direction == "forward" and fwd_offset[0] <= x < fwd_offset[1]:
                    L += fwd_offset[2]
                for rail in "LR":
                    rho = corr[2] if corr and corr[0] <= x < corr[1] else 0.1 * rng.standard_normal()
                    out.append({**rows(f"r{r}", 10 ** (L / 20), window=float(x), wheelset=ws, role=role, rail=rail,
                                       direction=direction), "lr_correlation": rho})
    return pd.DataFrame(out)


def test_consistency_checks_flag_only_where_estimates_disagree():
    w = _survey(lead_offset=(200, 230, 4.0), fwd_offset=(100, 120, 5.0), corr=(40, 60, 0.95))
    flags, _ = consistency_checks(w, None, CFG)
    lt = flags[flags["check"] == "leading_vs_trailing"]
    assert set(lt["rail"]) == {"L", "R"}
    for _, f in lt.iterrows():
        assert f["from_m"] == pytest.approx(200, abs=1) and f["to_m"] == pytest.approx(230, abs=1)
        assert f["value"] == pytest.approx(4.0, abs=0.5)
    dr = flags[flags["check"] == "directions"]
    assert len(dr) == 2 and (dr["from_m"] >= 99).all() and (dr["to_m"] <= 121).all()
    ct = flags[flags["check"] == "crosstalk"]
    assert len(ct) == 1 and ct["from_m"].iloc[0] == 40 and ct["to_m"].iloc[0] == 60
    clean, _ = consistency_checks(_survey(seed=1), None, CFG)
    assert clean.empty


# ----------------------------------------------------------------------------- grinding
def _days(drop=None, short=None, dates=("2024-03-04", "2024-03-13", "2024-03-22", "2024-03-31"), seed=0):
    rng = np.random.default_rng(seed)
    out = []
    for i, d in enumerate(dates):
        for band in ("30-100", "100-300", "300-1000"):
            for rail in "LR":
                for x in np.arange(0.0, 400.0, 1.0):
                    L = 20 + 0.3 * i + 0.5 * rng.standard_normal()  # slow growth and day-to-day noise
                    for (a, b, db, after) in (drop, short):
                        if (a, b, db, after) != (None,) * 4 and a <= x < b and i >= after:
                            L -= db
                    out.append({"date": d, "band_mm": band, "rail": rail, "window_m": x, "level_db": L,
                                "pk_pk_um": 10 ** (L / 20)})
    return pd.DataFrame(out)


def test_a_grinding_is_located_and_dated_and_nothing_else_is_detected():
    none = (None, None, None, None)
    d = _days(drop=(150.0, 250.0, 8.0, 2), short=(330.0, 336.0, 10.0, 1))
    ev, short = detect_grinding(d, CFG)
    assert len(ev) == 1
    e = ev.iloc[0]
    assert (e["date_before"], e["date_after"]) == ("2024-03-13", "2024-03-22")
    assert e["from_m"] == pytest.approx(150, abs=3) and e["to_m"] == pytest.approx(250, abs=3)
    assert e["drop_db_30-100"] == pytest.approx(-8 + 0.3, abs=0.6)
    assert len(short) == 1 and short["from_m"].iloc[0] == pytest.approx(330, abs=3)
    eff = grinding_effect(ev, d, {"30-100": 10.0, "100-300": 15.0, "300-1000": 75.0})
    r = eff[(eff["rail"] == "L") & (eff["band_mm"] == "30-100")].iloc[0]
    assert r["change_db"] == pytest.approx(-7.7, abs=0.3)
    assert r["removed"] == bool(r["after_pk_pk_um"] < 10.0)
    assert detect_grinding(_days(drop=none, short=none, seed=4), CFG)[0].empty


# ----------------------------------------------------------------------------- trends
def test_growth_rate_and_threshold_crossing_forecast():
    """pk = 2 + 0.5 t µm from the last grinding, with 0.4 dB day scatter: the slope, and the crossing of 30 µm
    (t* = 56 d) with an interval that holds it."""
    rng = np.random.default_rng(7)
    t = np.arange(0, 45, 9.0)
    dates = [(pd.Timestamp("2024-04-01") + pd.Timedelta(days=float(x))).date().isoformat() for x in t]
    se = 0.4 / math.sqrt(7)
    pk = (2 + 0.5 * t) * 10 ** (se * rng.standard_normal(t.size) / 20)
    pre = ["2024-03-01", "2024-03-10", "2024-03-19"]  # before the grinding: high and growing, must be ignored
    ds = pd.DataFrame({"date": pre + dates, "section": "curve", "rail": "R", "band_mm": "100-300",
                       "pk_pk_um": [40.0, 44.0, 48.0] + list(pk), "se_db": se})
    events = pd.DataFrame({"date_before": ["2024-03-19"], "date_after": ["2024-04-01"], "from_m": [100.0],
                           "to_m": [300.0]})
    secs = Sections(("curve",), np.array([120.0]), np.array([280.0]))
    g = growth(ds, events, secs, CFG).iloc[0]
    assert g["since"] == "2024-04-01" and g["days"] == 5
    assert abs(g["slope_um_per_day"] - 0.5) < 3 * g["slope_se_um_per_day"]
    assert g["growth_um_per_month"] == pytest.approx(0.5 * 365.25 / 12, rel=0.1)
    f = forecast(pd.DataFrame([g]), {"100-300": 30.0}, ds).iloc[0]
    assert f["status"] == "forecast"
    t_true = day_number(["2024-04-01"])[0] + 56.0
    assert abs(f["crossing_day"] - t_true) < 0.1 * 56
    assert f["crossing_lo"] <= "2024-05-27" <= f["crossing_hi"]
    f2 = forecast(pd.DataFrame([g]), {"100-300": 10.0}, ds).iloc[0]
    assert f2["status"].startswith("above threshold since 2024-04-")


def test_a_flat_section_gets_no_forecast():
    ds = pd.DataFrame({"date": ["2024-04-01", "2024-04-10", "2024-04-19"], "section": "s", "rail": "L",
                       "band_mm": "30-100", "pk_pk_um": [3.0, 3.05, 2.98], "se_db": 0.3})
    g = growth(ds, None, None, CFG)
    f = forecast(g, {"30-100": 10.0}, ds).iloc[0]
    assert f["status"] == "not growing significantly" and f["crossing_date"] == ""


# ----------------------------------------------------------------------------- outliers, systematic forecast
def test_an_estimate_far_from_its_days_others_is_left_out_of_the_day_average():
    """Six runs × two wheelsets of one section at 20 µm (±0.2 dB), one wheelset at +6 dB: it alone is an outlier
    (deviation 6 dB beyond max(2 dB, 3 × the others' robust scatter)); the day level is the others' energy mean."""
    from estimator.monitoring.outliers import outlying_estimates, without_outliers
    from estimator.monitoring.workflow import day_tables

    rng = np.random.default_rng(3)
    w = []
    for r in range(6):
        for ws in (1, 2):
            pk = 20.0 * 10 ** (0.2 * rng.standard_normal() / 20)
            if (r, ws) == (2, 2):
                pk = 20.0 * 10 ** (6.0 / 20)
            w += [rows(f"r{r}", pk * (1 + 0.01 * k), window=float(k), wheelset=ws) for k in range(5)]
    w = pd.DataFrame(w)
    out = outlying_estimates(w, CFG)
    assert len(out) == 1 and (out["run_id"].iloc[0], out["wheelset"].iloc[0]) == ("r2", 2)
    assert out["deviation_db"].iloc[0] == pytest.approx(6.0, abs=0.5) and out["limit_db"].iloc[0] == 2.0
    kept = without_outliers(w, out)
    assert len(kept) == len(w) - 5 and not ((kept["run_id"] == "r2") & (kept["wheelset"] == 2)).any()
    dw, _ = day_tables(w, pd.DataFrame(), pd.DataFrame(), CFG)
    ref = day_average(kept)
    assert np.allclose(dw.sort_values("window_m")["level_db"], ref.sort_values("window_m")["level_db"], atol=1e-12)
    # a +1 dB estimate is within the day's spread; and three others are too few to judge one
    w2 = w.assign(pk_pk_um=np.where((w["run_id"] == "r2") & (w["wheelset"] == 2), w["pk_pk_um"] / 10 ** 0.25, w["pk_pk_um"]))
    assert outlying_estimates(w2, CFG).empty
    assert outlying_estimates(w[(w["run_id"] == "r1") | ((w["run_id"] == "r2") & (w["wheelset"] == 2))], CFG).empty


def test_a_run_covering_part_of_a_section_is_judged_on_the_chainage_it_covers():
    """A section whose corrugation starts at window 10 (10 µm before, 30 µm after): a run whose QC kept only
    windows 0-7 reads 10 µm there like every other run — not an outlier, although its section level is ~9 dB under
    the others'; the same partial run at +6 dB on its windows is one (deviation 6 dB on the shared windows)."""
    from estimator.monitoring.outliers import outlying_estimates

    def level(k):
        return 10.0 if k < 10 else 30.0

    rng = np.random.default_rng(5)
    w = []
    for r in range(5):
        for ws in (1, 2):
            w += [rows(f"r{r}", level(k) * 10 ** (0.2 * rng.standard_normal() / 20), window=float(k), wheelset=ws)
                  for k in range(30)]
    partial = [rows("p", level(k) * 10 ** (0.1 * rng.standard_normal() / 20), window=float(k)) for k in range(8)]
    assert outlying_estimates(pd.DataFrame(w + partial), CFG).empty
    loud = [dict(r, pk_pk_um=r["pk_pk_um"] * 10 ** (6 / 20)) for r in partial]
    out = outlying_estimates(pd.DataFrame(w + loud), CFG)
    assert len(out) == 1 and out["run_id"].iloc[0] == "p"
    assert out["deviation_db"].iloc[0] == pytest.approx(6.0, abs=0.3)
    assert out["level_db"].iloc[0] == pytest.approx(20 + 6.0, abs=0.3)  # 10 µm + 6 dB = 26 dB re 1 µm


def test_the_forecast_interval_holds_the_systematic_level_uncertainty():
    """pk = 10 + 0.5 t, threshold 40 µm: t* = 60 d; a systematic interval of −1/+2 dB scales the amplitude by
    k ∈ [10^(−1/20), 10^(2/20)], so the crossing can be as early as (40/k_hi − 10)/0.5 and as late as
    (40/k_lo − 10)/0.5 (closed form; the statistical part is negligible here)."""
    cov = np.diag([1e-8, 1e-12])
    g = pd.DataFrame([{"section": "s", "rail": "R", "band_mm": "30-100", "last_pk_pk_um": 30.0, "since": "",
                       "intercept_um": 10.0, "slope_um_per_day": 0.5, "slope_se_um_per_day": 1e-6, "t0_day": 19800.0,
                       "cov": cov, "growth_um_per_month": 15.2, "systematic_lo_db": -1.0, "systematic_hi_db": 2.0}])
    f = forecast(g, {"30-100": 40.0}).iloc[0]
    assert f["crossing_day"] == pytest.approx(19860.0, abs=1e-6) and f["interval"] == "statistical and systematic"
    early = 19800.0 + (40.0 / 10 ** (2 / 20) - 10.0) / 0.5
    late = 19800.0 + (40.0 / 10 ** (-1 / 20) - 10.0) / 0.5
    assert f["crossing_lo"] == pd.Timestamp("1970-01-01").date().fromordinal(
        pd.Timestamp("1970-01-01").date().toordinal() + int(round(early))).isoformat()
    assert f["crossing_hi"] == pd.Timestamp("1970-01-01").date().fromordinal(
        pd.Timestamp("1970-01-01").date().toordinal() + int(round(late))).isoformat()
    f0 = forecast(g.drop(columns=["systematic_lo_db", "systematic_hi_db"]), {"30-100": 40.0}).iloc[0]
    assert f0["interval"] == "statistical only" and f0["crossing_lo"] == f0["crossing_hi"] == f0["crossing_date"]
    # the date's sensitivity to a gain error common to every day: estimates 0.01 dB high reach 40 µm when the
    # true amplitude is 40 / 10^(0.01/20), (60 − t*) / 0.01 days earlier per dB (finite difference of the closed form)
    t_high = (40.0 / 10 ** (0.01 / 20) - 10.0) / 0.5
    assert f["days_per_db"] == pytest.approx((60.0 - t_high) / 0.01, rel=1e-3)
    assert f["days_per_db"] == pytest.approx(40.0 * math.log(10) / 20 / 0.5, rel=1e-12)  # 9.2 d/dB, 15 % of t*
    assert not f["possibly_above_now"]  # no last survey day given: nothing to compare the early end with
    # surveyed up to day 40 (pk 30 µm): with +4 dB possible the true amplitude, 30 × 10^(4/20) = 47.5 µm, is above
    # 40 µm already; the early end (40/k_hi − 10)/0.5 = 30.5 d would lie before the last day, so the interval
    # starts on that day and says the section may be above now; with +2 dB (43.5 d) it does not
    last = pd.Timestamp("1970-01-01") + pd.Timedelta(days=19840)
    g4 = g.assign(last_date=last.date().isoformat(), systematic_hi_db=4.0)
    f4 = forecast(g4, {"30-100": 40.0}).iloc[0]
    assert f4["possibly_above_now"] and f4["crossing_lo"] == last.date().isoformat()
    assert f4["crossing_date"] == f["crossing_date"] and f4["crossing_hi"] == f["crossing_hi"]
    f2 = forecast(g4.assign(systematic_hi_db=2.0), {"30-100": 40.0}).iloc[0]
    assert not f2["possibly_above_now"] and f2["crossing_lo"] == f["crossing_lo"] > last.date().isoformat()


def test_a_day_with_one_run_takes_the_sections_pooled_scatter():
    """Days with several runs give se = scatter/√n_eff; a single-run day (no scatter of its own) is weighted with
    the median scatter of the others over √1 — the weighted fit equals the closed-form WLS with those errors."""
    from estimator.monitoring.trends import _wls

    dates = ["2024-04-01", "2024-04-11", "2024-04-21", "2024-05-01"]
    pk = np.array([10.0, 14.5, 20.5, 24.0])
    ds = pd.DataFrame({"date": dates, "section": "s", "rail": "R", "band_mm": "30-100", "pk_pk_um": pk,
                       "scatter_db": [0.6, np.nan, 0.4, 0.5], "n_eff": [4.0, 1.0, 4.0, 4.0],
                       "se_db": [0.3, np.nan, 0.2, 0.25]})
    g = growth(ds, None, None, CFG).iloc[0]
    se = np.array([0.3, 0.5, 0.2, 0.25])  # the single-run day: median(0.6, 0.4, 0.5) / √1
    a, b, cov = _wls(np.array([0.0, 10.0, 20.0, 30.0]), pk, pk * math.log(10) / 20 * se)
    assert g["slope_um_per_day"] == pytest.approx(b, rel=1e-12)
    assert g["slope_se_um_per_day"] == pytest.approx(math.sqrt(cov[1, 1]), rel=1e-12)


def test_contact_and_track_variants_span_the_stated_ranges():
    """Wheel load ±25 %: Hertz semi-axis and stiffness scale as (1 ± 0.25)^(1/3) (a ∝ (P R)^(1/3), k_H ∝
    P^(1/3)); the track variants: discrete supports, pad and ballast stiffness and damping ×2 and ÷2 on every
    trackform, and the causal loss law with the table's stiffness at 10 Hz and at 1 kHz."""
    from test_estimator_synthetic import control_model, sensor_table

    from estimator.monitoring.variants import contact_variants, track_variants
    from estimator.workflow import prepare

    fm = prepare(control_model(), sensor_table())
    cv = contact_variants(fm, CFG)
    assert [v.label for v in cv] == ["wheel load -25 %", "wheel load +25 %", "rail head radius 200 mm",
                                     "rail head radius 500 mm"]
    for v, f in zip(cv[:2], (0.75, 1.25)):
        assert v.field_model.semi_axis_m / fm.semi_axis_m == pytest.approx(f ** (1 / 3), rel=1e-9)
        assert v.field_model.contact_stiffness / fm.contact_stiffness == pytest.approx(f ** (1 / 3), rel=1e-9)
        assert v.field_model.cache is not fm.cache and v.source == "contact"
    # a rail head curved more tightly across narrows the ellipse and lengthens it along the rail (Hertz)
    assert cv[3].field_model.semi_axis_m < fm.semi_axis_m < cv[2].field_model.semi_axis_m
    tv = track_variants(fm, CFG)
    assert [v.label for v in tv] == ["discrete supports (midspan)", "pad stiffness x2", "pad stiffness x0.5",
                                     "ballast stiffness x2", "ballast stiffness x0.5", "pad damping x2",
                                     "pad damping x0.5", "ballast damping x2", "ballast damping x0.5",
                                     "causal layers, stated stiffness at 10 Hz",
                                     "causal layers, stated stiffness at 1000 Hz"]
    assert tv[0].field_model.config.trackform_supports == "discrete"
    base = fm.default_trackform()
    tf = {v.label: v.field_model.default_trackform() for v in tv[1:]}
    assert tf["pad stiffness x2"].pad_stiffness_z == pytest.approx(2 * base.pad_stiffness_z)
    assert tf["ballast stiffness x0.5"].subplate_stiffness_y == pytest.approx(0.5 * base.subplate_stiffness_y)
    assert tf["ballast stiffness x0.5"].pad_stiffness_z == base.pad_stiffness_z
    # a layer's damping is its loss factor and its dashpot together; its stiffness and the other layer stay
    pd2 = tf["pad damping x2"]
    assert (pd2.pad_loss_factor, pd2.pad_damping_z, pd2.pad_damping_y) == pytest.approx(
        (2 * base.pad_loss_factor, 2 * base.pad_damping_z, 2 * base.pad_damping_y))
    assert (pd2.pad_stiffness_z, pd2.subplate_loss_factor) == (base.pad_stiffness_z, base.subplate_loss_factor)
    assert tf["ballast damping x0.5"].subplate_damping_z == pytest.approx(0.5 * base.subplate_damping_z)
    # the causal law: the table's stiffness at the stated frequency, softer below it, stiffer above
    from receptance.track import layer_dispersion, support_stiffness_per_metre
    for label, fr in (("causal layers, stated stiffness at 10 Hz", 10.0),
                      ("causal layers, stated stiffness at 1000 Hz", 1000.0)):
        assert tf[label].loss_reference_hz == fr and base.loss_reference_hz is None
        k_causal = support_stiffness_per_metre(fr, tf[label])
        assert abs(k_causal / support_stiffness_per_metre(fr, base) - 1) < 1e-12
        lo, at, hi = layer_dispersion([0.5 * fr, fr, 2 * fr], base.pad_loss_factor, fr)
        assert lo < at == 1.0 < hi
    none = CFG.replace(contact_load_range=0.0, contact_head_radius_m=(), track_stiffness_factor=1.0,
                       track_damping_factor=1.0, track_loss_reference_hz=(), track_discrete_supports=False)
    assert contact_variants(fm, none) == [] and track_variants(fm, none) == []


def test_the_noise_floor_is_subtracted_in_energy_and_windows_under_it_are_upper_bounds():
    """Levels 20, 15 and 11 dB above a 0 dB floor and one at 2 dB: kept, kept (Δ ≥ 10), energy-subtracted
    (10 lg(10^1.1 − 1)) and below floor (upper bound, lower −inf); coverage counts the latter as covered when the
    truth is under its upper bound."""
    from estimator.monitoring.floor import day_floor, noise_run, with_floor

    L = np.array([20.0, 15.0, 5.0, 2.0])
    day = pd.DataFrame({"date": "2024-03-04", "rail": "L", "band_mm": "30-100", "window_m": np.arange(4.0), "level_db": L,
                        "pk_pk_um": 10 ** (L / 20), "ci_lo_db": L - 1.0, "ci_hi_db": L + 1.0})
    var = pd.DataFrame([rows(r, 1.0, window=float(k)) for r in ("a", "b") for k in range(4)]).assign(
        source="floor", variant="noise")
    fl = day_floor(var)
    assert np.allclose(fl["floor_pk_um"], 1.0)
    out = with_floor(day, fl)
    assert list(out["floor_status"]) == ["above floor", "above floor", "floor subtracted", "below floor"]
    assert out["level_db"].iloc[2] == pytest.approx(10 * np.log10(10 ** 0.5 - 1), abs=1e-12)
    assert out["ci_hi_db"].iloc[2] == pytest.approx(out["level_db"].iloc[2] + 1.0, abs=1e-12)
    assert out["ci_lo_db"].iloc[3] == -np.inf and out["ci_hi_db"].iloc[3] == 3.0
    truth = pd.DataFrame({"date": "2024-03-04", "rail": "L", "band_mm": "30-100", "window_m": [3.0], "level_db": [-10.0]})
    assert coverage(out, truth)["coverage"].iloc[0] == 1.0
    assert (with_floor(day, pd.DataFrame())["floor_status"] == "no floor").all()

    class R:  # the run's shape, dropouts and history are what the floor estimate keeps
        acceleration = np.array([[1.0, np.nan, 2.0, 3.0] * 2500])

        def with_step(self, step, **changes):
            return changes["acceleration"], step

    acc, step = noise_run(R(), 0.03, seed=1)
    assert np.isnan(acc[0, 1::4]).all() and np.std(acc[np.isfinite(acc)]) == pytest.approx(0.03, rel=0.05)
    assert "0.03 m/s^2" in step


def test_trend_plot_takes_a_zero_width_interval_that_rounding_made_negative():
    """One run a day and no systematic source: the interval has zero width, and the floor correction's dB round
    trip can leave its lower end 1e-15 above the level; the trend figure still draws (matplotlib refuses negative
    error bars)."""
    import matplotlib

    matplotlib.use("Agg")
    from estimator.monitoring.plot import plot_trend

    pk = np.array([10.0, 12.0])
    ds = pd.DataFrame({"date": ["2024-03-04", "2024-03-18"], "section": "s", "rail": "L", "band_mm": "30-100",
                       "pk_pk_um": pk, "pk_lo_um": pk * (1 + 1e-15), "pk_hi_um": pk * 1.1})
    fig = plot_trend(ds, pd.DataFrame(columns=["section", "rail", "band_mm", "slope_um_per_day"]), pd.DataFrame(),
                     "s", "L", "30-100")
    assert len(fig.axes[0].lines) >= 1


def test_a_calibration_site_the_reference_does_not_cover_is_a_named_error():
    from estimator.monitoring.confidence import reference_calibration
    from estimator.monitoring.errors import MonitoringError

    errs = pd.DataFrame({"rail": ["L", "R"], "band_mm": ["30-100"] * 2, "window_m": [10.0, 11.0],
                         "error_db": [0.5, 0.7]})
    with pytest.raises(MonitoringError, match=r"calibration site 500-600 m.*covers 10-11 m"):
        reference_calibration(errs, site=(500.0, 600.0))
