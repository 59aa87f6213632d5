"""The virtual line around the dynamics: line, roughness, operation, odometry, DAQ, files — against oracles.

The first part checks each stage on its own (closed forms, spectra estimated
by Welch's method rather than by the synthesis' own FFT, the standard's
table); the second reads a short simulated campaign back with asammdf and
pandas and checks that every fault, jump, grinding and offset is where the
truth manifest says.
"""

import contextlib
import datetime as dt
import json

import numpy as np
import pandas as pd
import pytest
from scipy import signal
from threadpoolctl import threadpool_limits
from scipy.integrate import trapezoid

from lab_data.line import campaign as camp
from lab_data.line.curving import CurvingParameters, contact_angle_deg, rail_contact_angles, wheelset_shift
from lab_data.line.daq import G, ChannelSpec, DaqParameters, Fault, anti_alias_decimate, quantise, record_channels
from lab_data.line.geometry import LineError, cant_angle, curvature, default_line, line_dict, speed_limit_kmh
from lab_data.line.odometry import OdometryParameters, simulate_odometry
from lab_data.line.operation import AtoParameters, ato_profile
from lab_data.line.roughness import (ISO3095_LIMIT_DB, Grinding, RoughnessConfig, build_rail_roughness,
                                     build_wheel_roughness, contact_filter_kernel, hertz_semi_axis,
                                     rail_broadband_target_db, third_octave_wavelengths)
from lab_data.line.scenarios import FIELD_SCENARIOS, get_field_scenario
from lab_data.line.supports import support_factors

LINE = default_line()


def welch_band_levels(x, dx, centres):
    """One-third-octave levels [dB re 1 µm] from a Welch PSD (independent of the synthesis' FFT)."""
    k, psd = signal.welch(x, fs=1.0 / dx, nperseg=2**16, detrend=False)
    dk = k[1] - k[0]
    out = []
    for c in centres:
        lo, hi = 10 ** (-1 / 20) / c, 10 ** (1 / 20) / c
        out.append(10 * np.log10(psd[(k >= lo) & (k < hi)].sum() * dk / 1e-12))
    return np.array(out)


@pytest.fixture(scope="module")
def rails():
    cfg = RoughnessConfig(grindings=(Grinding("2024-04-20", camp.GRINDING_SECTIONS),))
    return build_rail_roughness(LINE, cfg)


# ------------------------------------------------------------------------------------------------ line


def test_line_layout_meets_the_issue():
    assert LINE.length_m >= 1500.0
    assert len(LINE.curves) == 2 and all(300.0 <= c.radius_m <= 600.0 and c.cant_mm > 0 for c in LINE.curves)
    assert all(c.transition_in_m > 0 and c.transition_out_m > 0 for c in LINE.curves)
    assert LINE.switches and len(LINE.welds) > 20 and len(LINE.balises) >= 4 and len(LINE.stations) == 2
    assert {t.trackform for t in LINE.trackform_sections} == {"milano_modificato", "milano_modificato_soft_pads"}
    d = json.loads(json.dumps(line_dict(LINE)))
    soft = [t for t in d["trackform_sections"] if t["trackform"].endswith("soft_pads")][0]
    assert soft["pad_stiffness_z"] == pytest.approx(100e6) and soft["subplate_stiffness_z"] == pytest.approx(30e6)
    assert d["curves"][0]["direction"] == "right" and d["curves"][1]["direction"] == "left"
    with pytest.raises(LineError, match="overlap"):
        type(LINE)(**{**LINE.__dict__, "curves": LINE.curves + (LINE.curves[0],)})


def test_curvature_and_cant_follow_clothoids_and_ramps():
    c1 = LINE.curves[0]
    mid_transition = c1.from_m + 0.5 * c1.transition_in_m
    k = curvature(LINE, np.array([c1.from_m - 1, mid_transition, 600.0, c1.to_m + 1]))
    assert k == pytest.approx([0.0, -0.5 / 400.0, -1 / 400.0, 0.0])  # right curve: negative curvature
    assert cant_angle(LINE, np.array([600.0]))[0] == pytest.approx(0.040 / 1.5)
    assert curvature(LINE, np.array([1100.0]))[0] == pytest.approx(1 / 320.0)
    assert speed_limit_kmh(LINE, np.array([300.0, 600.0])) == pytest.approx([60.0, 35.0])


def test_contact_angles_follow_the_quasi_static_shift():
    p = CurvingParameters()
    s = np.array([300.0, 600.0])
    v = np.full(2, 32 / 3.6)
    # straight: both wheels on the table's centred value
    gl, gr = rail_contact_angles(LINE, s, v, np.array([True, True]), p)
    assert np.degrees([gl[0], gr[0]]) == pytest.approx([1.6, 1.6])
    # right curve R 400: closed form of the shift towards the outer (left) rail
    a_nc = v[1] ** 2 / 400 - 9.80665 * 0.040 / 1.5
    lead = 0.41 * 0.75 / 400 / 0.2 + 1e-3 + 4e-3 * a_nc
    y = wheelset_shift(LINE, s, v, np.array([True, True]), p)
    assert y[1] == pytest.approx(-lead, rel=1e-9)
    assert np.degrees(gl[1]) == pytest.approx(contact_angle_deg(lead))  # the outer wheel climbs
    assert np.degrees(gr[1]) == pytest.approx(contact_angle_deg(-lead))
    assert np.degrees(gl[1]) > 3.0 > np.degrees(gr[1])
    # the contact_angle scenario: the outer wheel reaches its flange
    gl2, _ = rail_contact_angles(LINE, s, v, np.array([True, True]), CurvingParameters(gauge_narrowing_m=3e-3))
    assert np.degrees(gl2[1]) > 45.0


def test_support_scatter_sections_and_hidden_changes():
    x, f = support_factors(LINE, get_field_scenario("nominal"), 1)
    assert np.diff(x) == pytest.approx(np.full(x.size - 1, 0.75))
    plain = (x < 400) | (x > 480)
    assert 0.03 < np.std(f["pad_stiffness_z"][:, plain]) < 0.05  # "a few per cent"
    soft = (x >= 410) & (x < 470)
    assert np.mean(f["pad_stiffness_z"][:, soft]) == pytest.approx(100 / 150, rel=0.03)
    assert np.mean(f["subplate_stiffness_z"][:, soft]) == pytest.approx(1.0, abs=0.02)
    _, g = support_factors(LINE, get_field_scenario("trackform_change"), 1)
    hidden = (x >= 720) & (x <= 780)
    assert g["subplate_stiffness_z"][:, hidden] / f["subplate_stiffness_z"][:, hidden] == pytest.approx(0.6)
    assert g["pad_stiffness_y"][:, hidden] / f["pad_stiffness_y"][:, hidden] == pytest.approx(0.6)
    assert np.array_equal(g["pad_stiffness_z"][:, ~hidden], f["pad_stiffness_z"][:, ~hidden])
    _, h = support_factors(LINE, get_field_scenario("pad_defect"), 1)
    changed = np.flatnonzero(np.any(h["pad_stiffness_z"] != f["pad_stiffness_z"], axis=0))
    assert changed.size == 4 and np.all(h["pad_stiffness_z"][0, changed] / f["pad_stiffness_z"][0, changed] == pytest.approx(0.15))
    assert np.array_equal(h["pad_stiffness_z"][1], f["pad_stiffness_z"][1])


def test_every_required_field_scenario_exists():
    need = {"nominal", "trackform_change", "sensor_offset", "wheel_polygon", "contact_angle", "two_effects",
            "pad_defect", "lateral_sign"}
    assert need <= set(FIELD_SCENARIOS)
    with pytest.raises(KeyError, match="unknown field scenario 'nope'"):
        get_field_scenario("nope")


# ------------------------------------------------------------------------------------------------ roughness


def test_iso3095_limit_and_target():
    centres = third_octave_wavelengths(0.4, 0.00315)
    assert centres.size == 22
    target = rail_broadband_target_db(centres)
    assert target - np.array([ISO3095_LIMIT_DB[k] for k in sorted(ISO3095_LIMIT_DB, reverse=True)]) == \
        pytest.approx(np.full(22, 3.0))
    assert rail_broadband_target_db(np.array([1.0]))[0] == pytest.approx(17.1 + 3.0 + 2 * 4)


def test_broadband_rail_roughness_matches_its_spectrum(rails):
    centres = third_octave_wavelengths(0.5, 0.004)
    sl = rails.slice(150.0, 450.0)  # straight, not ground, no corrugation
    for row in range(2):
        base = rails.base[row]
        got = welch_band_levels(base, rails.config.dx, centres)
        assert got == pytest.approx(rail_broadband_target_db(centres), abs=0.6)
    # the day's profile on a plain straight adds only weld dips (long waves) to the broadband part
    day = rails.on("2024-03-04")[0, sl]
    short = centres <= 0.1
    got = welch_band_levels(day, rails.config.dx, centres[short])
    assert got == pytest.approx(rail_broadband_target_db(centres[short]), abs=1.5)


def test_corrugation_grows_on_the_low_rails_and_grinding_removes_it(rails):
    dx = rails.config.dx
    sos = signal.butter(4, [1 / 0.1, 1 / 0.03], "bandpass", fs=1 / dx, output="sos")
    body = rails.slice(520.0, 660.0)  # curve 1 body: low rail R

    def pk(date, row):
        band = signal.sosfiltfilt(sos, rails.on(date)[row, rails.slice(480.0, 700.0)])
        inner = slice(body.start - rails.slice(480.0, 700.0).start, body.stop - rails.slice(480.0, 700.0).start)
        return 2 * np.sqrt(2) * np.sqrt(np.mean(band[inner] ** 2)) * 1e6

    p = rails.config.patches[0]
    assert p.rail == "R" and LINE.curves[0].low_rail == "R" and rails.config.patches[1].rail == LINE.curves[1].low_rail
    # 45 days after the previous grinding (2024-01-19): law residual + rate x days in 30-100 mm
    law = p.pk_pk_um(45.0)[0]
    broadband = pk("2024-03-04", 0)  # the high rail of the same curve: broadband only
    got = pk("2024-03-04", 1)
    assert np.sqrt(max(got**2 - broadband**2, 0.0)) == pytest.approx(law, rel=0.15)
    assert pk("2024-04-19", 1) > 1.5 * got  # grown
    after = pk("2024-04-21", 1)
    assert after < 0.35 * pk("2024-04-19", 1)  # ground away
    # outside the ground sections grinding changes nothing
    out = rails.slice(1400.0, 1500.0)
    assert np.array_equal(rails.on("2024-04-19")[:, out], rails.on("2024-04-21")[:, out])


def test_grinding_lowers_the_broadband_level_and_leaves_its_signature(rails):
    centres = third_octave_wavelengths(0.2, 0.008)
    sl = rails.slice(470.0, 715.0)  # curve 1's high rail L: ground, no corrugation patch
    before = welch_band_levels(rails.on("2024-04-19")[0, sl], rails.config.dx, centres)
    after = welch_band_levels(rails.on("2024-04-21")[0, sl], rails.config.dx, centres)
    no_sig = np.abs(np.log(centres / 0.025)) > 0.2
    no_weld = centres <= 0.1
    assert np.median((before - after)[no_sig & no_weld]) == pytest.approx(6.0, abs=1.5)
    k25 = int(np.argmin(np.abs(centres - 0.025)))
    assert after[k25] > before[k25]  # the stones' facets


def test_wheel_roughness_is_periodic_and_the_polygon_has_its_order():
    w = build_wheel_roughness(np.array([0.4085, 0.4083, 0.409, 0.4088]), 5,
                              polygon={"wheel": 0, "order": 12, "amplitude_m": 15e-6, "phase_rad": 0.7})
    th = np.linspace(0, 2 * np.pi, 50)
    a = w.at(np.stack([th] * 4))
    b = w.at(np.stack([th + 2 * np.pi] * 4))
    assert a == pytest.approx(b, abs=1e-15)
    plain = build_wheel_roughness(np.array([0.4085, 0.4083, 0.409, 0.4088]), 5)
    diff = np.fft.rfft(w.table - plain.table, axis=1) * 2 / w.table.shape[1]
    assert np.abs(diff[0, 12]) == pytest.approx(15e-6, rel=1e-6) and np.angle(diff[0, 12]) == pytest.approx(0.7)
    assert np.abs(diff).sum() == pytest.approx(15e-6, rel=1e-6)  # nothing else changed
    # the random part: the rail's broadband shape 6 dB lower, on wavelengths of the worn circumference
    # (short waves only: a 2.6 m circumference holds too few orders per long-wave band for a stable level)
    centres = third_octave_wavelengths(0.063, 0.008)
    energy = np.mean([10 ** (welch_band_levels(np.tile(plain.table[i], 8), 2 * np.pi * r / plain.table.shape[1],
                                               centres) / 10) for i, r in enumerate(plain.radius_m)], axis=0)
    # a band holds 0.23 C / lambda orders of Rayleigh amplitude: 3 standard deviations of its level, 4 wheels
    orders = 0.23 * 2 * np.pi * 0.4085 / centres
    tol = 3 * 4.34 / np.sqrt(4 * orders)
    assert np.all(np.abs(10 * np.log10(energy) - (rail_broadband_target_db(centres) - 6.0)) < tol)


def test_contact_filter_kernel_transfer_is_the_hertz_average():
    a = hertz_semi_axis(52e3)
    assert 4e-3 < a < 7e-3
    h = contact_filter_kernel(a, 1e-4)
    assert h.sum() == pytest.approx(1.0)
    # transfer of the sqrt(1-(x/a)^2) weight: 2 J1(ka)/(ka) (Fourier transform of a semicircle)
    from scipy.special import j1

    for lam in (0.03, 0.05, 0.1):
        k = 2 * np.pi / lam
        x = (np.arange(h.size) - h.size // 2) * 1e-4
        got = np.sum(h * np.cos(k * x))
        assert got == pytest.approx(2 * j1(k * a) / (k * a), abs=0.01)


# ------------------------------------------------------------------------------------------------ operation


@pytest.mark.parametrize("direction", ["forward", "backward"])
def test_ato_profile_stops_at_stations_and_runs_the_curves_at_30_to_35(direction):
    ato = AtoParameters(curve_kmh=32.0)
    p = ato_profile(LINE, direction, ato)
    start, end = LINE.stations[0].chainage_m, LINE.stations[-1].chainage_m
    if direction == "backward":
        start, end = end, start
    assert p.s[0] == start and p.s[-1] == end and p.v[0] == 0 and p.v[-1] == 0
    t = np.arange(0.0, p.duration, 0.01)
    s, v, a = p.at(t)
    assert np.all(v <= speed_limit_kmh(LINE, s) / 3.6 + 1e-6)
    assert np.max(a) <= ato.acceleration + 1e-6 and np.min(a) >= -ato.deceleration - 1e-6
    for c in LINE.curves:
        on = (s >= c.from_m) & (s <= c.to_m)
        assert 30.0 <= 3.6 * v[on].min() and 3.6 * v[on].max() <= 35.0
    # integrating the speed gives back the distance (closed form for piecewise constant acceleration)
    assert trapezoid(v, t) == pytest.approx(abs(end - start), abs=0.05)
    # a standing start: 1/2 a t^2 while accelerating from rest
    t1 = ato.dwell_start_s + 3.0
    assert abs(p.at(np.array([t1]))[0][0] - start) == pytest.approx(0.5 * ato.acceleration * 9.0, rel=1e-3)


# ------------------------------------------------------------------------------------------------ odometry


def test_odometry_scale_error_offsets_and_balise_jumps():
    p = ato_profile(LINE, "forward")
    r_true = 0.4085
    o = simulate_odometry(LINE, p, r_true, start_offset_m=1.7, p=OdometryParameters())
    s_true, _, _ = p.at(o.t)
    scale = 0.41 / r_true
    assert o.scale == pytest.approx(scale)
    assert 0.001 < scale - 1 < 0.01  # "a few tenths of a per cent"
    first = o.resets[0]
    before = o.t < first["t_s"]
    # before the first balise: the start offset plus the scale error on the distance travelled
    pred = 1.7 + (scale - 1) * (s_true[before] - s_true[0])
    assert o.position[before] - s_true[before] == pytest.approx(pred, abs=0.01)
    for r0, r1 in zip(o.resets, o.resets[1:]):
        assert r1["jump_m"] == pytest.approx(-(scale - 1) * (r1["reference_m"] - r0["reference_m"]), abs=0.01)
        k = int(np.searchsorted(o.t, r1["t_s"]))
        assert o.position[k] - o.position[k - 1] == pytest.approx(r1["jump_m"] + (s_true[k] - s_true[k - 1]) * scale,
                                                                   abs=0.01)
    assert list(o.balise_value) == [b.chainage_m for b in LINE.balises]


# ------------------------------------------------------------------------------------------------ DAQ


@pytest.mark.parametrize("fs", [20000.0, 10240.0])  # integer ratio, and the dynamics' rate (up = 25, down = 256)
def test_anti_alias_filter_passband_stopband_and_delay(fs):
    t = np.arange(0, 4.0, 1 / fs)
    tones = (37.0, 213.0, 390.0)
    x = np.stack([np.sin(2 * np.pi * f * t + 0.4) for f in tones] + [np.sin(2 * np.pi * 640.0 * t)])
    y = anti_alias_decimate(x, fs, 1000.0)
    to = np.arange(y.shape[1]) / 1000.0
    inner = slice(500, -500)
    for i, f in enumerate(tones):  # flat passband, no delay left
        assert np.max(np.abs(y[i, inner] - np.sin(2 * np.pi * f * to[inner] + 0.4))) < 1e-4
    assert np.sqrt(np.mean(y[3, inner] ** 2)) < 1e-4  # 640 Hz would alias to 360 Hz: -80 dB at least


def test_quantisation_clipping_and_faults():
    q, clipped = quantise(np.array([0.0, 1e-7, 49.9, 60.0, -70.0]), 50.0, 24)
    lsb = 100.0 / 2**24
    assert q[1] == pytest.approx(round(1e-7 / lsb) * lsb)
    assert list(clipped) == [False, False, False, True, True] and q[3] < 50.0 and q[4] == -50.0
    fs_in = 10240.0  # the dynamics' rate: a non-integer decimation (25/256)
    t = np.arange(0, 10.0, 1 / fs_in)
    acc = np.stack([3 * G * np.sin(2 * np.pi * 50 * t)] * 2)
    ch = (ChannelSpec("A", "z", 0.02), ChannelSpec("B", "z", -0.01, sign=-1.0))
    faults = (Fault("nan", "A", 2.0, 0.5), Fault("clip", "B", range_g=2.0))
    rec, clip, info = record_channels(acc, fs_in, ch, faults, np.random.default_rng(0), DaqParameters())
    to = np.arange(rec.shape[1]) / 1000.0
    nan = np.isnan(rec[0])
    assert to[nan].min() == pytest.approx(2.0) and nan.sum() == 500
    ok = (to > 1) & (to < 1.9)
    # sensitivity error +2 %: 3 g x 1.02 (least-squares amplitude of the 50 Hz tone); the sign flip of B shows
    basis = np.stack([np.sin(2 * np.pi * 50 * to[ok]), np.cos(2 * np.pi * 50 * to[ok])], axis=1)
    coef = np.linalg.lstsq(basis, rec[0, ok], rcond=None)[0]
    assert np.hypot(*coef) == pytest.approx(3 * 1.02, rel=5e-4)
    inside = ok & (np.abs(rec[1]) < 1.9)
    assert np.corrcoef(rec[0, inside], rec[1, inside])[0, 1] < -0.999
    assert clip[1].any() and not clip[0].any()
    assert np.max(rec[1]) == pytest.approx(2.0, abs=1e-6) and info["B"]["range_g"] == 2.0


# ------------------------------------------------------------------------------------------------ planning


def test_plan_is_deterministic_and_places_faults_grinding_and_trolley_days():
    c = camp.LineCampaignConfig(days=10, runs_per_day=7)
    a, b = camp.plan_line_campaign(c), camp.plan_line_campaign(c)
    assert a.runs == b.runs and a.wheel_radii == b.wheel_radii and a.sensors == b.sensors
    dates = [dt.date.fromisoformat(d) for d in a.dates]
    assert len(dates) == 10 and (dates[-1] - dates[0]).days == 84
    assert a.dates[5] < a.grinding.date < a.dates[6]
    assert a.trolley_dates == (a.dates[0], a.dates[5], a.dates[6], a.dates[9])
    assert sum(1 for r in a.runs if any(f.kind in ("nan", "flat") for f in r.faults)) == 14
    assert sum(1 for r in a.runs if any(f.kind == "clip" for f in r.faults)) == 10
    assert {r.direction for r in a.runs} == {"forward", "backward"}
    assert all(0.0015 < 0.41 / r - 1 < 0.006 for r in a.wheel_radii)
    offsets = [np.linalg.norm(np.subtract(s.true, s.nominal)) for s in a.sensors]
    assert all(1e-3 < o < 0.03 for o in offsets) and all(abs(s.sensitivity_error) <= 0.02 for s in a.sensors)
    assert camp.plan_line_campaign(camp.LineCampaignConfig(seed=7)).runs != a.runs


@pytest.mark.parametrize("bad, match", [
    ({"days": 0}, "days must be in 1..30"),
    ({"runs_per_day": 13}, "runs_per_day must be in 1..12"),
    ({"section": (50.0, 300.0)}, "section must be FROM TO"),
    ({"section": (400.0, 420.0)}, "at least 50 m"),
    ({"wheelset_scenario": "nope"}, "wheelset_scenario must be one of"),
    ({"fs": 50.0}, "fs must be in"),
    ({"start_date": "04/03/2024"}, "ISO date"),
])
def test_config_refuses_bad_values_with_a_clear_message(bad, match):
    with pytest.raises(camp.LineConfigError, match=match):
        camp.LineCampaignConfig(**bad)


# ------------------------------------------------------------------------------------------------ a campaign

SHORT = dict(days=2, runs_per_day=2, section=camp.FIRST_CURVE_SECTION)


@pytest.fixture(scope="module")
def campaign():
    from lab_data.line.cache import line_campaign_dir
    from lab_data.line.files import read_truth

    folder = line_campaign_dir("nominal", **SHORT)
    return folder, read_truth(folder)


def _mdf(path):
    from asammdf import MDF

    return MDF(path)


@pytest.mark.slow
def test_every_file_reads_back_and_follows_the_contract(campaign):
    from lab_data.line.files import header_properties

    folder, truth = campaign
    sensors = pd.read_csv(folder / "sensors.csv")
    assert list(sensors.columns) == ["name", "quantity", "unit", "wheelset", "side", "direction", "x", "y", "z",
                                     "sensitivity"]
    acc = sensors[sensors.quantity == "acceleration"]
    assert len(acc) == 6 and set(acc.unit) == {"g"} and np.allclose(acc.sensitivity, G)
    assert sorted(zip(acc.wheelset, acc.direction)) == [(1, "y"), (1, "z"), (1, "z"), (2, "y"), (2, "z"), (2, "z")]
    line = json.loads((folder / "line.json").read_text())
    assert {"curves", "switches", "welds", "balises", "stations", "trackform_sections", "speed_limits"} <= set(line)
    assert len(truth["runs"]) == 4
    for run in truth["runs"]:
        with _mdf(folder / run["file"]) as m:
            props = header_properties(m)
            assert {k: props[k] for k in ("run_id", "date", "direction")} == \
                {"run_id": run["run_id"], "date": run["date"], "direction": run["direction"]}
            assert {"train", "bogie", "line", "orientation"} <= set(props)
            for _, row in sensors.iterrows():
                sig = m.get(row["name"])
                assert sig.unit == row["unit"]
                if row["quantity"] == "acceleration":
                    assert sig.samples.size == run["samples"]
                    assert np.diff(sig.timestamps) == pytest.approx(np.full(sig.samples.size - 1, 1e-3))
            speed = m.get("SPEED")
            assert np.diff(speed.timestamps).mean() == pytest.approx(0.01)
        lead = 1 if run["direction"] == "forward" else 2
        assert run["leading_wheelset"] == lead
    for date in truth["trolley"]["dates"]:
        t = pd.read_csv(folder / "trolley" / f"{date}.csv")
        assert list(t.columns) == ["chainage_m", "rail", "roughness_um"] and set(t.rail) == {"L", "R"}
        assert np.diff(t[t.rail == "L"].chainage_m) == pytest.approx(np.full((t.rail == "L").sum() - 1, 1e-3),
                                                                    abs=1e-6)


@pytest.mark.slow
def test_dropouts_and_clipping_are_where_the_manifest_says(campaign):
    folder, truth = campaign
    drop = [r for r in truth["runs"] if r["dropouts"]]
    assert [r["run_id"] for r in drop] == [truth["runs"][1]["run_id"]]
    planned = truth["runs"][2]["planned_faults"]
    assert [f["kind"] for f in planned] == ["clip"]
    assert planned[0]["channel"] in {c["channel"] for c in truth["runs"][2]["clipped"]}
    for run in truth["runs"]:
        with _mdf(folder / run["file"]) as m:
            for name, info in run["daq"].items():
                x = m.get(name).samples.astype(float)
                t = np.arange(x.size) / 1000.0
                expect_nan = np.zeros(x.size, bool)
                for d in info["dropouts"]:
                    sel = (t >= d["t_start_s"] - 1e-9) & (t <= d["t_end_s"] + 1e-9)
                    assert sel.sum() == d["samples"]
                    if d["kind"] == "nan":
                        expect_nan |= sel
                    else:
                        assert np.ptp(x[sel]) == 0.0
                assert np.array_equal(np.isnan(x), expect_nan)
                rng_g, lsb = info["range_g"], info["lsb_g"]
                stuck = np.zeros(x.size, bool)
                for c in info["clipped"]:
                    stuck |= (t >= c["t_s"][0] - 1e-9) & (t <= c["t_s"][1] + 1e-9)
                # full scale is +(R - 1 LSB) / -R; float32 storage moves a value by < 0.4 LSB
                at_full_scale = np.abs(x) >= rng_g - 1.5 * lsb
                assert np.array_equal(at_full_scale & ~expect_nan, stuck & ~expect_nan)
                assert stuck.sum() == info["clipped_samples"]
    tight = truth["runs"][2]["daq"][planned[0]["channel"]]
    assert 0 < tight["clipped_samples"] < 0.01 * truth["runs"][2]["samples"]  # ~0.1 %: the range was the 99.9 % quantile


@pytest.mark.slow
def test_balise_jumps_odometer_scale_and_offsets_are_as_stated(campaign):
    from lab_data.line.files import read_run_truth

    folder, truth = campaign
    scale = truth["odometry"]["scale"]
    assert 0.001 < scale - 1 < 0.006
    n_resets = 0
    for run in truth["runs"]:
        true = read_run_truth(folder, run["run_id"])
        with _mdf(folder / run["file"]) as m:
            pos, bal = m.get("ODO_POSITION"), m.get("BALISE")
        s_true = np.interp(pos.timestamps, true.t_s, true.chainage_m)
        err = pos.samples - s_true
        resets = run["odometry"]["resets"]
        assert list(bal.samples) == [r["reference_m"] for r in resets]
        assert bal.timestamps == pytest.approx([r["t_s"] for r in resets], abs=1e-9)
        edges = [0] + [int(np.searchsorted(pos.timestamps, r["t_s"] - 1e-9)) for r in resets] + [pos.samples.size]
        for k, (a, b) in enumerate(zip(edges, edges[1:])):
            if b - a < 50:
                continue
            # between resets the error grows with the distance travelled at the scale error
            slope = np.polyfit(np.abs(s_true[a:b] - s_true[a]), err[a:b] * np.sign(s_true[b - 1] - s_true[a]), 1)[0]
            assert slope == pytest.approx(scale - 1, abs=2e-4)
        for r in resets:
            k = int(np.searchsorted(pos.timestamps, r["t_s"] - 1e-9))
            step = pos.samples[k] - pos.samples[k - 1]
            travelled = (s_true[k] - s_true[k - 1]) * scale
            assert step - travelled == pytest.approx(r["jump_m"], abs=0.01)
            assert abs(r["jump_m"]) > 0.1
            n_resets += 1
    assert n_resets >= 4  # B02 and B03 in every run


@pytest.mark.slow
def test_grinding_day_and_corrugation_growth_in_the_truth(campaign):
    from lab_data.line.files import read_true_roughness

    folder, truth = campaign
    g = truth["grinding"]
    d1, d2 = (d["date"] for d in truth["days"])
    assert g["last_day_before"] == d1 and g["first_day_after"] == d2 and d1 < g["date"] <= d2
    pk = {}
    for date in (d1, d2):
        r = read_true_roughness(folder, date)
        for lo, hi, name in ((520, 660, "curve"), (404, 456, "outside")):
            sel = (r.chainage_m >= lo) & (r.chainage_m <= hi)
            for band in ((0.03, 0.1), (0.1, 0.3)):
                sos = signal.butter(4, [1 / band[1], 1 / band[0]], "bandpass", fs=1000.0, output="sos")
                for rail in "LR":
                    x = signal.sosfiltfilt(sos, r[f"{rail}_um"].to_numpy(float))
                    pk[date, name, band, rail] = 2 * np.sqrt(2) * np.sqrt(np.mean(x[sel] ** 2))
    for day in truth["days"]:
        c1 = [p for p in day["corrugation"] if p["id"] == "C1_low"][0]
        assert c1["epoch"] == (0 if day["date"] < g["date"] else 1)
        for k, band in enumerate(((0.03, 0.1), (0.1, 0.3))):
            # the low rail R carries the stated corrugation on top of a broadband part like the high rail's
            got = np.sqrt(pk[day["date"], "curve", band, "R"] ** 2 - pk[day["date"], "curve", band, "L"] ** 2)
            assert got == pytest.approx(c1["pk_pk_um"][k], rel=0.25)
    # grinding took 6 dB off the broadband roughness of the ground curve (high rail L: no corrugation)...
    ratio = pk[d2, "curve", (0.03, 0.1), "L"] / pk[d1, "curve", (0.03, 0.1), "L"]
    assert 20 * np.log10(ratio) == pytest.approx(-6.0, abs=1.5)
    # ... and nothing outside the ground sections
    assert pk[d2, "outside", (0.03, 0.1), "L"] == pytest.approx(pk[d1, "outside", (0.03, 0.1), "L"], rel=1e-6)


@pytest.mark.slow
def test_trolley_is_the_truth_shifted_by_its_offset_with_sub_micron_noise(campaign):
    from lab_data.line.files import read_true_roughness

    folder, truth = campaign
    date = truth["trolley"]["dates"][0]
    t = pd.read_csv(folder / "trolley" / f"{date}.csv")
    r = read_true_roughness(folder, date)
    left = t[t.rail == "L"]
    # find the offset by cross-correlation on the 1 mm grid (trolley chainage = true + offset): 60 m of the
    # trolley's record against the (equally high-passed) truth over +-1 m of lag
    x = left.chainage_m.to_numpy()
    y = left.roughness_um.to_numpy()
    part = (x > x[0] + 100.0) & (x <= x[0] + 160.0)
    hp = signal.butter(2, 1e-3 / 3.0 * 2, "highpass", output="sos")
    rx = r.chainage_m.to_numpy()
    near = (rx >= x[part][0] - 1.0) & (rx <= x[part][-1] + 1.0)
    ref = signal.sosfiltfilt(hp, r.L_um.to_numpy(float))[near]
    score = signal.correlate(ref, y[part] - y[part].mean(), mode="valid")
    found = x[part][0] - rx[near][int(np.argmax(score))]
    assert found == pytest.approx(truth["trolley"]["offset_m"], abs=1.5e-3)
    true_hp = signal.filtfilt(*signal.butter(2, 1e-3 / 3.0 * 2, "highpass"),
                              np.interp(x - truth["trolley"]["offset_m"], r.chainage_m, r.L_um))
    noise = (y - true_hp)[2000:-2000]
    assert np.std(noise) == pytest.approx(0.3, rel=0.15)  # µm


@pytest.mark.slow
def test_the_corrugated_low_rail_shakes_its_axlebox_more(campaign):
    """Physics through the whole chain: in curve 1 the leading wheelset's low-rail (R) axlebox sees more
    30-100 mm band energy than its high-rail one, on straight track both alike."""
    from lab_data.line.files import read_run_truth

    folder, truth = campaign
    run = truth["runs"][0]  # forward: wheelset 1 leads; day 1 (corrugated)
    true = read_run_truth(folder, run["run_id"])
    with _mdf(folder / run["file"]) as m:
        zl, zr = (m.get(n).samples.astype(float) * G for n in ("ACC_W1L_Z", "ACC_W1R_Z"))
    v = true.speed_m_s.to_numpy()
    chain = true.ws1_chainage_m.to_numpy()
    curve, straight = (chain > 530) & (chain < 650), (chain > 405) & (chain < 465)
    f_lo, f_hi = v[curve].mean() / 0.1, v[curve].mean() / 0.03
    sos = signal.butter(4, [f_lo, min(f_hi, 400.0)], "bandpass", fs=1000.0, output="sos")
    bl, br = signal.sosfiltfilt(sos, zl), signal.sosfiltfilt(sos, zr)

    def ratio(sel):
        return np.sqrt(np.mean(br[sel] ** 2) / np.mean(bl[sel] ** 2))

    # the low rail's band roughness is about twice the high rail's there (corrugation + broadband, truth);
    # the axle couples the two sides, so the axleboxes differ less, but clearly, and only in the curve
    assert ratio(curve) > 1.25 * ratio(straight)
    assert 0.8 < ratio(straight) < 1.25


@pytest.mark.slow
def test_recorded_level_below_the_p2_resonance_is_the_wheel_following_the_rail(campaign):
    """Absolute level through the whole chain (dynamics, DAQ, g in the file, sensitivity in sensors.csv).

    Below the P2 resonance (wheel mass on the track's stiffness, 50-100 Hz) the wheel follows the
    contact-filtered rail: a = d²r/dt² along the wheel's true path, amplified by 1 / (1 - (f/f_P2)²) ≥ 1 and
    raised a little by the wheel's own roughness (6 dB below the rail's) and the sleeper-passing harmonics.
    So the recorded band level lies between the rail-only kinematic level and a few times it; a scale error
    (a gain in the DAQ chain, g read as m/s²) lands far outside.
    """
    from lab_data.line.files import read_run_truth, read_true_roughness

    folder, truth = campaign
    sensors = pd.read_csv(folder / "sensors.csv").set_index("name")
    run = truth["runs"][0]
    true = read_run_truth(folder, run["run_id"])
    rails = read_true_roughness(folder, run["date"])
    kernel = contact_filter_kernel(truth["roughness"]["contact_filter"]["semi_axis_m"], 1e-3)
    t = true.t_s.to_numpy()
    sos = signal.butter(4, [15.0, 35.0], "bandpass", fs=1000.0, output="sos")
    with _mdf(folder / run["file"]) as m:
        for ws in (1, 2):
            chain = true[f"ws{ws}_chainage_m"].to_numpy()
            straight = (chain > 405.0) & (chain < 465.0)
            for side in "LR":
                name = f"ACC_W{ws}{side}_Z"
                rail = np.convolve(rails[f"{side}_um"].to_numpy() * 1e-6, kernel, mode="same")
                z = np.interp(chain, rails.chainage_m, rail)
                kin = signal.sosfiltfilt(sos, np.gradient(np.gradient(z, t), t))[straight]
                rec = signal.sosfiltfilt(sos, m.get(name).samples.astype(float) * sensors.sensitivity[name])
                ratio = np.sqrt(np.mean(rec[straight] ** 2) / np.mean(kin**2))
                assert 0.9 < ratio < 4.0, (name, ratio)


@pytest.mark.slow
def test_a_run_is_deterministic(campaign, tmp_path):
    folder, truth = campaign
    plan = camp.plan_line_campaign(camp.LineCampaignConfig(scenario="nominal", **SHORT))
    world = camp.build_world(plan)
    (tmp_path / "truth" / "runs").mkdir(parents=True)
    with threadpool_limits(1):  # as in the campaign's workers: BLAS sums in the same order
        rec = camp.simulate_run(world, plan.runs[0], tmp_path)
    assert rec["samples"] == truth["runs"][0]["samples"]
    with _mdf(tmp_path / rec["file"]) as a, _mdf(folder / rec["file"]) as b:
        for name in ("ACC_W1L_Z", "ACC_W2R_Y", "ODO_POSITION"):
            assert np.array_equal(a.get(name).samples, b.get(name).samples)


# ------------------------------------------------------------------------------------------------ command line


@pytest.mark.parametrize("argv, code, message", [
    (["--days", "0"], 2, "--days must be an integer in [1, 30], got 0"),
    (["--runs-per-day", "99"], 2, "--runs-per-day must be an integer in [1, 12], got 99"),
    (["--section", "700", "500"], 2, "needs LOW < HIGH"),
    (["--section", "50", "500"], 2, "--section must be a number in [100, 1740] m"),
    (["--section", "500", "520"], 1, "at least 50 m long"),
    (["--scenario", "nope"], 2, "invalid choice: 'nope'"),
])
def test_simulate_line_refuses_bad_arguments_before_any_work(tmp_path, capsys, argv, code, message):
    from railmodal.cli import main

    out = tmp_path / "out"
    base = ["lab", "simulate-line", "--scenario", "nominal", "--out", str(out)]
    if argv[0] == "--scenario":
        base = base[:2] + base[4:]
    with pytest.raises(SystemExit) if code == 2 else contextlib.nullcontext():  # argparse exits with 2
        assert main(base + argv) == code
    assert message in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.slow
def test_simulate_line_writes_a_campaign(tmp_path, capsys):
    from railmodal.cli import main

    out = tmp_path / "line"
    rc = main(["-q", "lab", "simulate-line", "--scenario", "lateral_sign", "--days", "1", "--runs-per-day", "1",
               "--section", "420", "480", "--out", str(out)])
    assert rc == 0
    text = capsys.readouterr().out
    assert "1 runs over 1 day(s)" in text and "wheelset 1 leads" in text
    assert (out / "line.json").exists() and (out / "sensors.csv").exists()
    assert len(list((out / "runs").rglob("*.mf4"))) == 1
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".line.partial")]


def test_trolley_csv_is_what_pandas_writes_byte_for_byte(tmp_path):
    """The chunked ``%`` writer of the trolley files gives pandas' ``to_csv(float_format="%.4f")`` text exactly,
    a missing value included, across chunk boundaries."""
    from lab_data.line.files import write_trolley_csv

    rng = np.random.default_rng(3)
    x = 400.0 + 1e-3 * np.arange(2_503)
    r = 4e-6 * rng.standard_normal((2, x.size))
    r[0, 7], r[1, -1], x[11] = np.nan, -0.0, np.nan
    write_trolley_csv(tmp_path / "fast.csv", x, r, rows_per_chunk=1_000)
    frames = [pd.DataFrame({"chainage_m": x, "rail": rail, "roughness_um": r[i] * 1e6}) for i, rail in enumerate("LR")]
    pd.concat(frames, ignore_index=True).to_csv(tmp_path / "pandas.csv", index=False, float_format="%.4f")
    assert (tmp_path / "fast.csv").read_bytes() == (tmp_path / "pandas.csv").read_bytes()
