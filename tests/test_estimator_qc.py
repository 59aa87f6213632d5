"""Quality control and odometry: every bad input is a named error or a logged, reported mask.

Oracles: faults placed at known times/chainages in synthetic runs; the field contract's orientation rule.
"""

from __future__ import annotations

import numpy as np
import pytest

from estimator import (EstimatorConfig, NoValidDataError, Odometry, check_run, estimate_run, odometry_track,
                       orientation, prepare, read_run)
from test_estimator_synthetic import control_model, make_run, sensor_table


@pytest.mark.parametrize("direction, orient, leading, rail_of_L, ws1_sign", [
    ("forward", "normal", 1, "L", +1),
    ("backward", "normal", 2, "L", +1),
    ("forward", "turned", 2, "R", -1),
    ("backward", "turned", 1, "R", -1),
])
def test_orientation_rule_of_the_field_contract(direction, orient, leading, rail_of_L, ws1_sign):
    o = orientation(direction, orient)
    assert o.leading == leading and o.trailing == 3 - leading
    assert o.rail_of_side["L"] == rail_of_L and o.side_of_rail[rail_of_L] == "L"
    assert o.wheelset_offset_sign == {1: ws1_sign, 2: -ws1_sign}
    assert o.travel_sign == (1 if direction == "forward" else -1)


def _odo(position, balise_t=(), balise_c=(), speed=10.0, rate=100.0):
    t = np.arange(position.size) / rate
    return Odometry(t, np.full(t.size, speed), position, np.array(balise_t, float), np.array(balise_c, float))


def test_balise_resets_remove_start_offset_and_scale_error():
    """Odometer 0.3 % long and started 2 m off; balises at 100 and 250 m pin it back to the true chainage."""
    rate, v, scale = 100.0, 10.0, 1.003
    t = np.arange(0, 30, 1 / rate)
    true = 50 + v * t
    pos = true[0] + 2.0 + v * scale * t
    bt, bc = [], []
    for b in (100.0, 250.0):
        j = int(np.searchsorted(true, b, side="right"))
        pos[j:] = b + v * scale * (t[j:] - (b - 50) / v)
        bt.append(t[j])
        bc.append(b)
    odo = Odometry(t, np.full(t.size, v * scale), pos, np.array(bt), np.array(bc))
    tr = odometry_track(odo, +1)
    assert np.max(np.abs(tr.chainage - true)) < 0.02  # start offset (2 m) and 0.3 % scale gone
    assert [e.action for e in tr.events] == ["corrected", "corrected"]
    assert tr.resets[0]["jump_m"] == pytest.approx(-2.0 - 0.003 * 50, abs=0.02)
    assert tr.scale[-1] == pytest.approx(1 / scale, rel=1e-4)


def test_an_implausible_balise_jump_masks_the_stretch_and_a_jump_without_balise_too():
    rate, v = 100.0, 10.0
    t = np.arange(0, 30, 1 / rate)
    true = 50 + v * t
    pos = true.copy()
    j1 = int(np.searchsorted(true, 100.0, side="right"))
    j2 = int(np.searchsorted(true, 250.0, side="right"))
    pos[j2:] += 20.0  # the second balise claims 20 m more than travelled over 150 m: 13 %, an odometry fault
    odo = Odometry(t, np.full(t.size, v), pos, np.array([t[j1], t[j2]]), np.array([100.0, 270.0]))
    tr = odometry_track(odo, +1)
    bad = [e for e in tr.events if e.kind == "odometry_jump"]
    assert len(bad) == 1 and bad[0].action == "masked" and "+13.3" in bad[0].reason
    assert bad[0].chainage_from == pytest.approx(100.0, abs=0.2) and bad[0].chainage_to == pytest.approx(270.0, abs=0.2)
    # a jump with no balise event is not trusted either
    pos = true.copy()
    pos[1500:] += 3.0
    tr = odometry_track(_odo(pos), +1)
    (ev,) = [e for e in tr.events if e.kind == "odometry_jump"]
    assert "without a balise" in ev.reason and tr.untrusted
    # no balise on either side: the whole run is masked, and the finding's chainage is all of it (the odometer's
    # 50-353 m), not the jump's 3 m at 200 m
    assert "not trusted to the end of the run (the jump at 199.90 m)" in ev.reason
    assert (ev.chainage_from, ev.chainage_to) == (pytest.approx(50.0), pytest.approx(352.9, abs=0.01))


@pytest.mark.parametrize("factor, what", [(3.6, "km/h read as m/s"), (1 / 3.6, "m/s read as km/h"), (2.0, None)])
def test_speed_and_position_disagreeing_by_a_unit_factor_say_which(factor, what):
    """A speed 3.6 x the position's rate all along is km/h read as m/s (a file without a unit label): the finding
    says so; a factor no unit explains (2) is a disagreement only."""
    t = np.arange(0, 30, 0.01)
    pos = 50 + 10 * t
    tr = odometry_track(Odometry(t, np.full(t.size, 10 * factor), pos, np.zeros(0), np.zeros(0)), +1)
    (ev,) = [e for e in tr.events if e.kind == "odometry_inconsistent"]
    if what is None:
        assert "read as" not in ev.reason
    else:
        assert f"the speed is {factor:.4g} x the position's rate all along: {what}?" in ev.reason


@pytest.fixture(scope="module")
def faulty(tmp_path_factory):
    """A run with a NaN dropout, a flat dropout, a clipped channel, standstill and reversing, at known times."""
    tmp = tmp_path_factory.mktemp("qc")

    def faults(ch):
        t, v, u = ch["ACC_W1L_Z"]
        v = v.copy()
        v[(t >= 10.0) & (t < 10.5)] = np.nan
        ch["ACC_W1L_Z"] = (t, v, u)
        t, v, u = ch["ACC_W2R_Z"]
        v = v.copy()
        sel = (t >= 20.0) & (t < 20.3)
        v[sel] = v[np.flatnonzero(sel)[0] - 1]
        ch["ACC_W2R_Z"] = (t, v, u)
        t, v, u = ch["ACC_W1R_Y"]
        lim = 0.5 * np.max(np.abs(v))
        ch["ACC_W1R_Y"] = (t, np.clip(v, -lim, lim), u)
        to, sp, su = ch["SPEED"]
        new = sp.copy()
        new[(to >= 34.0) & (to < 35.0)] = -1.5  # rolling back after the last balise, position consistent
        ch["SPEED"] = (to, new, su)
        tp, pos, pu = ch["POSITION"]
        ch["POSITION"] = (tp, pos + np.concatenate([[0.0], np.cumsum(new - sp)[:-1]]) * 0.01, pu)

    return make_run(tmp, control_model(), duration_s=40, faults=faults, name="faulty")


def test_dropouts_clipping_standstill_and_reversing_are_masked_with_reasons(faulty, caplog):
    run = read_run(faulty.path, sensor_table())
    tr = odometry_track(run.odometry, +1)
    run = check_run(run, tr, EstimatorConfig())
    q = run.mask.table()
    nan = q[q["kind"] == "dropout_nan"].iloc[0]
    assert nan["channel"] == "ACC_W1L_Z" and nan["t_start_s"] == pytest.approx(10.0, abs=0.01)
    assert nan["t_end_s"] == pytest.approx(10.5, abs=0.01)
    assert nan["chainage_from_m"] == pytest.approx(np.interp(10.0, faulty.t, faulty.chainage), abs=0.5)
    flat = q[q["kind"] == "dropout_flat"].iloc[0]
    assert flat["channel"] == "ACC_W2R_Z" and flat["t_start_s"] == pytest.approx(20.0, abs=0.01)
    clip = q[q["kind"] == "clipping"]
    assert set(clip["channel"]) == {"ACC_W1R_Y"} and len(clip) >= 3
    rev = q[q["kind"] == "reversing"].iloc[0]
    assert rev["t_start_s"] == pytest.approx(34.0, abs=0.05) and rev["channel"] == "*"
    assert not q["kind"].str.startswith("odometry").any()  # a consistent roll-back is no odometry fault
    assert (q["kind"] == "standstill").any() and (q["kind"] == "low_speed").any()
    i = run.index("ACC_W1L_Z")
    t = run.t
    assert run.mask.masked[i, (t > 10.1) & (t < 10.4)].all() and not run.mask.masked[i, (t > 12) & (t < 13)].any()
    share = run.masked_share
    assert share["ACC_W1L_Z"] > share["ACC_W2L_Z"] and 0 < share["run"] < 0.5
    assert "dropout_nan [ACC_W1L_Z]" in caplog.text
    # nothing interpolated over: the raw NaNs stay NaN in the run
    assert np.isnan(run.acceleration[i, (t > 10.1) & (t < 10.4)]).all()
    # saturated: exactly the clipped channel's masked samples outside the run-wide masks; a dropout is not
    j = run.index("ACC_W1R_Y")
    sat = run.mask.saturated
    assert sat[j].any() and not np.delete(sat, j, axis=0).any()
    assert not (sat[j] & ~run.mask.masked[j]).any()
    assert not sat[j, (t >= 34.0) & (t < 35.0)].any()  # reversing masks every channel whatever it recorded
    assert run.mask.coupling_valid([j])[sat[j]].all()
    assert not run.mask.coupling_valid([i, j])[(t > 10.1) & (t < 10.4)].any()


def test_the_estimate_reports_the_masks_and_skips_only_what_it_must(faulty):
    fm = prepare(control_model(), sensor_table(), config=EstimatorConfig(models=("half", "vertical")))
    est = estimate_run(faulty.path, fm)
    assert {"dropout_nan", "dropout_flat", "clipping", "reversing"} <= set(est.qc["kind"])
    p = est.profile(1, "vertical")
    i = p.rail_row("L")
    x_gap = np.interp(10.25, faulty.t, faulty.chainage) + est.wheelbase_m / 2
    k = np.searchsorted(p.chainage_m, x_gap)
    assert np.isnan(p.rail[i, k])  # the dropout is a hole in the profile, not an interpolation
    # wheelset 2's flat dropout (20-20.3 s) is a hole in wheelset 1's coupled estimate too, and it is said
    (msg,) = [s for s in est.processing if "leave out their own valid samples" in s]
    assert "1/vertical" in msg
    assert np.isfinite(p.rail[i, np.searchsorted(p.chainage_m, x_gap + 30)])


def test_a_run_with_nothing_valid_is_a_named_error(tmp_path):
    def kill(ch):
        for name in list(ch):
            if name.startswith("ACC"):
                t, v, u = ch[name]
                ch[name] = (t, np.full_like(v, np.nan), u)

    sr = make_run(tmp_path, control_model(), duration_s=20, faults=kill, name="dead")
    fm = prepare(control_model(), sensor_table(), config=EstimatorConfig(models=("vertical",)))
    # each reason once with whom it stopped, and what masked the run
    with pytest.raises(NoValidDataError, match=r"dead.mf4: nothing could be estimated \(wheelset 1/vertical: .* "
                                               r"\(ACC_W1L_Z, ACC_W1R_Z, ACC_W1R_Y masked over the whole run\); "
                                               r"wheelset 2/vertical: .*; masked share 100 %, mostly by dropout_nan "
                                               r"100 %, low_speed"):
        estimate_run(sr.path, fm)


def test_zero_speed_run_is_a_named_error(tmp_path):
    sr = make_run(tmp_path, control_model(), duration_s=20, v_cruise=0.0, name="still")
    fm = prepare(control_model(), sensor_table(), config=EstimatorConfig(models=("vertical",)))
    with pytest.raises(NoValidDataError, match=r"still.mf4: nothing could be estimated .*masked share 100 %, "
                                               r"mostly by standstill 100 % of the run; each finding is logged\)"):
        estimate_run(sr.path, fm)


def test_a_channel_dead_over_the_whole_run_leaves_the_other_sides_estimate(tmp_path):
    """ACC_W1L_Z NaN over the whole run: inverted with it, wheelset 1's half model (both sides in one inversion)
    would be masked everywhere and the wheelset lost. Left out, wheelset 1 is estimated on rail R by the half model
    (within 1 dB of the same run with the channel alive, 30-100 mm), its vertical model is not (it needs both
    sides), and the step says which channel was left out."""
    def kill(ch):
        t, v, u = ch["ACC_W1L_Z"]
        ch["ACC_W1L_Z"] = (t, np.full_like(v, np.nan), u)

    cfg = EstimatorConfig(models=("half", "vertical"), wheelbase_m=2.2)
    fm = prepare(control_model(), sensor_table(), config=cfg)
    dead = estimate_run(make_run(tmp_path, control_model(), duration_s=20, faults=kill, name="deadL").path, fm)
    alive = estimate_run(make_run(tmp_path, control_model(), duration_s=20, name="alive").path, fm)
    assert (1, "vertical") not in dead.profiles and (2, "vertical") in dead.profiles
    p, q = dead.profile(1, "half"), alive.profile(1, "half")
    assert p.rails == ("R",) and q.rails == ("L", "R")
    assert any("ACC_W1L_Z masked over the whole run: left out of every model" in s for s in dead.processing)
    b = list(p.indexes.bands_mm).index((30.0, 100.0))
    lp, lq = (np.nanmedian(x.indexes.pk_pk[b, x.rail_row("R")]) for x in (p, q))
    assert abs(20 * np.log10(lp / lq)) < 1.0


def test_a_channel_masked_on_part_of_the_run_costs_the_half_model_its_own_side_only(tmp_path):
    """ACC_W1L_Z NaN from 6 to 14 s of 20 s. The half model is one SISO model per side (T diagonal; the rail
    coupling joins the same rail only), so rail R's estimate of wheelset 1 does not read that channel: it stays
    whole over the gap and equals the same run's with the channel alive (30-100 mm pk-pk within 0.02 dB there),
    while its rail L has a hole. The vertical model mixes both channels and loses both rails over the gap;
    wheelset 2's half model loses only the rail whose coupling term reads wheelset 1's dead channel."""
    def kill(ch):
        t, v, u = ch["ACC_W1L_Z"]
        ch["ACC_W1L_Z"] = (t, np.where((t > 6.0) & (t < 14.0), np.nan, v), u)

    cfg = EstimatorConfig(models=("half", "vertical"), wheelbase_m=2.2)
    fm = prepare(control_model(), sensor_table(), config=cfg)
    sr = make_run(tmp_path, control_model(), duration_s=20, faults=kill, name="gapL")
    part = estimate_run(sr.path, fm)
    alive = estimate_run(make_run(tmp_path, control_model(), duration_s=20, name="alive").path, fm)
    band = (30.0, 100.0)

    def middle(p, t_mid=10.0, half_m=15.0):  # chainage of the gap's middle under wheelset p.wheelset
        x = np.interp(t_mid, sr.t, sr.chainage) + (1 if p.wheelset == 1 else -1) * part.wheelbase_m / 2
        return (p.chainage_m > x - half_m) & (p.chainage_m < x + half_m)

    h, v = part.profile(1, "half"), part.profile(1, "vertical")
    assert h.rails == ("L", "R")
    sel = middle(h)
    assert np.isnan(h.rail[h.rail_row("L"), sel]).all()
    assert np.isfinite(h.rail[h.rail_row("R"), sel]).all()
    assert np.isnan(v.rail[:, middle(v)]).all()
    a = alive.profile(1, "half")
    lp = np.nanmedian(h.pk_pk(band, "R")[sel])
    la = np.nanmedian(a.pk_pk(band, "R")[middle(a)])
    assert abs(20 * np.log10(lp / la)) < 0.02  # 0.0003 dB measured: the grid and the comb, not the gap
    # outside the gap (beyond the inverse filter's edges) rail L is estimated as usual
    early = h.chainage_m < np.interp(5.0, sr.t, sr.chainage) + part.wheelbase_m / 2
    early_a = a.chainage_m < np.interp(5.0, sr.t, sr.chainage) + part.wheelbase_m / 2
    assert np.isfinite(h.rail[h.rail_row("L"), early]).mean() == pytest.approx(
        np.isfinite(a.rail[a.rail_row("L"), early_a]).mean(), abs=0.01)
    h2 = part.profile(2, "half")
    sel2 = middle(h2)
    assert np.isnan(h2.rail[h2.rail_row("L"), sel2]).all() and np.isfinite(h2.rail[h2.rail_row("R"), sel2]).all()
