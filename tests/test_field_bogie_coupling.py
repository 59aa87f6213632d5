"""The bogie's two wheelsets in the field estimate: rail coupling, lead/trail wheelbase and odometer scale.

Runs are synthetic (:func:`test_estimator_synthetic.make_run`: both wheelsets through receptance's forward map with
the rail coupling them, :func:`test_estimator_synthetic.forward_bogie`), short (30 s, ~240 m) and on tangent
track. Oracles: the roughness written (band levels within 1 dB where the coupling is inverted, > 2 dB off where it
is not), the wheelbase written (to a few mm), the odometer's scale written (the chainage to a few cm where
0.4 % drifts ~1 m), and the refusal reasons.
"""

from __future__ import annotations

import logging
import re
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from test_estimator_synthetic import SyntheticLine, _truth_reference, control_model, make_run, sensor_table

WHEELBASE = 2.2
BAND = (30.0, 100.0)


@pytest.fixture(scope="module")
def model():
    return control_model()


@pytest.fixture(scope="module")
def bogie_run(tmp_path_factory, model):
    """One 30 s forward run, both wheelsets fully instrumented (rail L: 60 mm corrugation, rail R: 180 mm)."""
    return make_run(tmp_path_factory.mktemp("bogie"), model, duration_s=30, name="bogie")


def _table_without(*names) -> pd.DataFrame:
    t = sensor_table()
    return t[~t["name"].isin(names)].reset_index(drop=True)


def _estimate(model, sr, table, **cfg):
    from estimator import EstimatorConfig, estimate_run, prepare

    return estimate_run(sr.path, prepare(model, table, config=EstimatorConfig(**cfg)))


def _error_db(est, sr, wheelset, kind, rail="L", band=BAND):
    from estimator.reference import compare_bands

    c = compare_bands(est, _truth_reference(sr), (110, 250), bands=[band], models=[kind], wheelsets=[wheelset])
    return float(c.set_index("rail").loc[rail, "mean_error_db"])


# --------------------------------------------------------------------------- D1: coupling across model kinds
def test_a_missing_lateral_channel_keeps_the_other_wheelsets_vertical_lateral_coupling(model, bogie_run):
    """Without ACC_W2R_Y wheelset 2 has no vertical + lateral model. Wheelset 1's vertical + lateral estimate used
    to lose its rail coupling (the other wheelset's forces were taken from the same model only) and read > 2 dB high
    at 60 mm; the coupling term is the rail deflection under wheelset 1 from wheelset 2's contact forces, which
    wheelset 2's vertical model inverts: on tangent track (contact angles 0, no lateral share) the estimate is
    back within 1 dB, the source stated."""
    sr = bogie_run
    est = _estimate(model, sr, _table_without("ACC_W2R_Y"), wheelbase_m=sr.wheelbase)
    step = next(s for s in est.processing if s.startswith("rail coupling of the two wheelsets"))
    assert "1/vertical_lateral," in step and "except 1/vertical_lateral from 2/vertical" in step, step
    # the same model's forces where the other wheelset has it
    assert "1/vertical from" not in step and "1/half from" not in step
    assert not any("1/vertical_lateral" in s and "without the rail coupling" in s for s in est.processing)
    coupled = _error_db(est, sr, 1, "vertical_lateral")
    single = _error_db(_estimate(model, sr, _table_without("ACC_W2R_Y"), wheelbase_m=sr.wheelbase,
                                 bogie_coupling=False, models=("vertical_lateral",)), sr, 1, "vertical_lateral")
    assert abs(coupled) < 1.0 and abs(single) > 2.0, (coupled, single)


def test_forces_of_a_half_model_couple_only_the_rail_they_act_on(model, bogie_run):
    """Wheelset 1 without ACC_W1L_Z has only a half model, of side R: wheelset 2's models take wheelset 1's force
    on rail R from it, state that rail L has none, and wheelset 1's half model on rail R (where it has a force
    partner) is coupled with wheelset 2's forces."""
    sr = bogie_run
    est = _estimate(model, sr, _table_without("ACC_W1L_Z"), wheelbase_m=sr.wheelbase)
    text = " | ".join(est.processing)
    assert "2/vertical from 1/half" in text and "1/half," in text and "1/half from" not in text
    assert "2/vertical's rail coupling has no force of wheelset 1 on rail L" in text
    # rail R: wheelset 2's coupled estimate with wheelset 1's half-model forces reads the 180 mm corrugation right
    assert abs(_error_db(est, sr, 2, "vertical", rail="R", band=(100.0, 300.0))) < 1.0


# --------------------------------------------------------------------------- D2: wheelbase by rail
def test_the_wheelbase_is_measured_on_the_rail_both_wheelsets_estimate(model, bogie_run):
    """Without ACC_W1L_Z wheelset 1's only estimate (half model) holds rail R in its first row, wheelset 2's half
    model rail L: pairing rows compared rail R with rail L (no correlation, the run refused). Paired by rail, the
    wheelbase comes from rail R, within 5 mm of the one written."""
    sr = bogie_run
    est = _estimate(model, sr, _table_without("ACC_W1L_Z"), models=("half", "vertical"))
    assert est.wheelbase_m == pytest.approx(sr.wheelbase, abs=0.005)
    assert est.wheelbase_source.startswith("measured")


def test_no_rail_on_both_wheelsets_is_refused_for_that_reason(model, bogie_run):
    """Wheelset 1 measures rail L only, wheelset 2 rail R only: no lag can be measured, and the error says why."""
    from estimator import WheelbaseError

    with pytest.raises(WheelbaseError, match=r"no rail instrumented on both wheelsets \(wheelset 1: rail\(s\) L; "
                                             r"wheelset 2: rail\(s\) R\).*--wheelbase"):
        _estimate(model, bogie_run, _table_without("ACC_W1R_Z", "ACC_W1R_Y", "ACC_W2L_Z"), models=("half",))


# --------------------------------------------------------------------------- D3: one wheelset
def test_one_instrumented_wheelset_says_its_estimate_lacks_the_coupling(model, bogie_run, caplog):
    """Only wheelset 1 instrumented: nothing measures wheelset 2's forces. The estimate says so (WARNING and
    processing history) and is the uncoupled one (> 2 dB high at 60 mm here)."""
    sr = bogie_run
    with caplog.at_level(logging.WARNING, logger="estimator"):
        est = _estimate(model, sr, _table_without("ACC_W2L_Z", "ACC_W2R_Z", "ACC_W2R_Y"), models=("vertical",),
                        wheelbase_m=sr.wheelbase)
    msg = [s for s in est.processing if "without the rail coupling (one instrumented wheelset)" in s]
    assert msg and "1/vertical" in msg[0] and "not measured" in msg[0]
    assert any("one instrumented wheelset" in r.getMessage() and r.levelno == logging.WARNING
               for r in caplog.records)
    assert _error_db(est, sr, 1, "vertical") > 2.0


# --------------------------------------------------------------------------- D6: correlation band
def _two_wheelset_irregularities(fs: float, v: float = 10.0, a: float = 2.1, duration: float = 30.0, seed=3):
    """Time irregularities of two wheelsets ``a`` apart at constant speed, band-limited as an inversion at ``fs``
    leaves them (λ ≥ v / 0.4 fs): one rail roughness from 50 mm to 1 m both see, plus each wheel's own roughness
    below 40 mm (its own wheel, its own patch, its own noise): the waves both see alike and the ones they do not."""
    from estimator.inversion import UPSAMPLE, TimeIrregularity
    from estimator.spatial import OdometryTrack

    rng = np.random.default_rng(seed)
    dxr = 1e-3
    x = np.arange(-5.0, v * duration + 5.0, dxr)
    k = np.fft.rfftfreq(x.size, dxr)

    def band(lo_m, hi_m):
        X = np.fft.rfft(rng.standard_normal(x.size))
        X[(k < 1 / hi_m) | (k > 1 / lo_m)] = 0
        r = np.fft.irfft(X, x.size)
        return r / r.std()

    rail = 1e-6 * band(0.05, 1.0)
    own = {w: 1e-6 * band(v / (0.4 * fs), 0.04) for w in (1, 2)}
    tu = np.arange(int(duration * fs * UPSAMPLE)) / (fs * UPSAMPLE)
    tis = {}
    for w, off in ((1, a / 2), (2, -a / 2)):
        y = np.interp(v * tu + off, x, rail + own[w])
        tis[(w, "vertical")] = TimeIrregularity("vertical", w, ("L", "R"), fs,
                                                ((0.0, 1.0, duration - 1.0, np.vstack([y, y])),))
    t = np.arange(0, duration, 0.01)
    track = OdometryTrack(t=t, chainage=v * t, speed=np.full(t.size, v), scale=np.ones(t.size), resets=(),
                          events=(), travel_sign=1)
    return tis, track


def test_the_lead_trail_correlation_does_not_depend_on_the_sampling_rate():
    """Whitened over the whole inversion band (λ ≥ v/0.4 fs), the correlation fell as fs rose: each one-third
    octave of waves the wheelsets see differently (their own wheels, patches, noise) counts as much as a coherent
    one (here 0.56 at 1 kHz, 0.26 at 2 kHz: refused). Over wavelengths longer than a few contact patches it is
    what the rail makes it at 1 and 2 kHz alike (here only the rail from 50 mm up is common: correlation ~1) and
    the lag is the wheelbase."""
    from estimator.orientation import orientation
    from estimator.workflow import _lead_trail

    fm = SimpleNamespace(semi_axis_m=0.0052)  # the Hertz patch of the virtual line's wheels (a_x)
    orient = orientation("forward", "normal")
    out = {}
    for fs in (1000.0, 2000.0):
        tis, track = _two_wheelset_irregularities(fs)
        lt = _lead_trail(fm, tis, track, orient, 10.0 / (0.4 * fs))
        out[fs] = (*lt.wheelbase(), lt.rails)
    for fs, (a, corr, rails) in out.items():
        assert a == pytest.approx(2.1, abs=0.002), out
        assert corr > 0.9 and rails == ("L", "R"), out
    assert abs(out[1000.0][1] - out[2000.0][1]) < 0.03, out


# --------------------------------------------------------------------------- D4: odometer scale
def _far_offset(est, sr, lo, hi):
    """Shift [m] of the estimate's chainage against the truth on [lo, hi] (peak of the cross-correlation)."""
    p = est.profile(1, "vertical")
    x, y = p.chainage_m, p.rail[p.rail_row("L")]
    sel = (x >= lo) & (x <= hi) & np.isfinite(y)
    best, arg = -np.inf, 0.0
    for lag in np.arange(-1.5, 1.5, 0.002):
        r = np.interp(x[sel] + lag, sr.truth_x, sr.truth["L"])
        c = np.corrcoef(y[sel], r)[0, 1]
        if c > best:
            best, arg = c, lag
    return arg, best


@pytest.fixture(scope="module")
def one_balise_run(tmp_path_factory, model):
    """Broadband rails only, one balise at 60 m, an odometer counting 0.4 % long."""
    line = SyntheticLine(sinusoids={}, broadband_rms=2e-6)
    return make_run(tmp_path_factory.mktemp("odo"), model, line=line, duration_s=30, balises=(60.0,),
                    odometer_scale=1.004, name="one_balise")


def test_one_balise_and_a_given_wheelbase_give_the_odometer_scale(model, one_balise_run):
    """With one balise nothing pinned the scale: 0.4 % put the chainage ~0.8 m off 200 m from the balise. The
    lead/trail lag is the wheelbase in odometer metres; over the given wheelbase it gives the scale (1/1.004 to
    2e-4), the chainage then lies within 3 cm of the truth there, and the QC table says how it was corrected."""
    sr = one_balise_run
    est = _estimate(model, sr, sensor_table(), models=("vertical",), wheelbase_m=sr.wheelbase)
    row = est.qc[est.qc["kind"] == "odometry_scale"]
    assert len(row) == 1 and row["action"].iloc[0] == "corrected"
    scale = float(re.search(r"odometer scale ([0-9.]+)", row["reason"].iloc[0]).group(1))
    assert scale == pytest.approx(1 / 1.004, abs=2e-4)
    assert any(s.startswith("chainage:") and "given wheelbase" in s for s in est.processing)
    lag, corr = _far_offset(est, sr, 230.0, 260.0)
    assert corr > 0.8 and abs(lag) < 0.03, (lag, corr)


def test_one_balise_without_a_wheelbase_states_the_uncorrected_chainage(model, one_balise_run, caplog):
    """Wheelbase measured (in odometer metres): the scale stays 1; a QC finding, a WARNING naming the run and the
    history give the stretch and the chainage uncertainty (the configured 2 % of the distance from the balise)."""
    sr = one_balise_run
    with caplog.at_level(logging.WARNING, logger="estimator"):
        est = _estimate(model, sr, sensor_table(), models=("vertical",))
    row = est.qc[est.qc["kind"] == "odometry_scale"]
    assert len(row) == 1 and row["action"].iloc[0] == "uncorrected"
    reason = row["reason"].iloc[0]
    assert "balise at 60.00 m" in reason and "not corrected" in reason
    far = float(re.search(r"\+/-[0-9.]+ m ([0-9.]+) m away", reason).group(1))
    assert far == pytest.approx(float(np.max(sr.chainage)) - 60.0, abs=5.0)
    assert any(r.levelno == logging.WARNING and str(sr.path) in r.getMessage() and "not corrected" in r.getMessage()
               for r in caplog.records)
    assert any(s.startswith("chainage:") and "--wheelbase" in s for s in est.processing)
    lag, _ = _far_offset(est, sr, 230.0, 260.0)
    assert 0.5 < abs(lag) < 1.0  # 0.4 % of ~190 m: what the finding warns of


def test_rescaled_track_is_a_new_track_about_its_balise():
    """:func:`estimator.spatial.rescaled` stretches the chainage about the run's balise, leaves the input as it was,
    and refuses a track whose scale two balises set."""
    from estimator import Odometry, odometry_track
    from estimator.spatial import rescaled

    t = np.arange(0, 30, 0.01)
    d = 10.0 * t * 1.004  # an odometer counting 0.4 % long
    pos = 100.0 + d
    j = 1000  # reset to the balise at 200 m at t = 10 s
    pos[j:] = 200.0 + (d[j:] - d[j])
    odo = Odometry(t=t, speed=np.full(t.size, 10.04), position=pos, balise_t=np.array([t[j]]),
                   balise_chainage=np.array([200.0]))
    tr = odometry_track(odo, +1)
    assert tr.scale_source == "odometer" and [e.kind for e in tr.events].count("odometry_scale") == 1
    out = rescaled(tr, 1 / 1.004, "test")
    truth = 200.0 + 10.0 * (t - t[j])
    assert np.max(np.abs(out.chainage - truth)) < 1e-6 and np.max(np.abs(tr.chainage - truth)) > 0.7
    assert out.speed == pytest.approx(np.full(t.size, 10.0)) and tr.scale_source == "odometer"
    assert [e.action for e in out.events if e.kind == "odometry_scale"] == ["corrected"]
    with pytest.raises(ValueError, match="already set"):
        rescaled(out, 1.0, "again")
