"""Field diagnosis mechanics against synthetic evidence whose truth and hidden effect are known.

Oracle: the accelerations' cross-spectra are made with the *forward* map ``H = B D⁻¹`` of the true field
(a stiffer section, a moved accelerometer, a curve's contact angles) from a known roughness spectrum; the
reference's band variance is that spectrum's integral. The diagnosis sees the nominal model and must find
the hidden effect (ranked first, its value within 25 %), lower the validation error, accept nothing when
the truth is nominal, and leave an effect outside the catalogue unexplained at the right stretch.
The transfer blocks are held equal to the estimator's own transfer function.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pandas as pd
import pytest

from estimator.config import EstimatorConfig
from estimator.diagnosis.config import DiagnosisConfig
from estimator.diagnosis.diagnose import diagnose_field
from estimator.diagnosis.effects import (ContactAngle, SensorOffset, TrackformEffect, WheelRoughness, catalogue)
from estimator.diagnosis.evidence import Evidence, SegmentSpectra, segments_of, third_octave_bands
from estimator.diagnosis.model import Evaluator
from estimator.diagnosis.state import FieldState, TrackformChange
from estimator.diagnosis.transfer import wheelset_blocks
from estimator.io.line import Curve, LineDescription, TrackSection
from receptance.contact import ContactParameters
from receptance.trackform import Trackform

FS = 1000.0
SPEED = 20.0
SITE = (0.0, 240.0)
LINE = LineDescription(sections=(TrackSection("A", 0.0, 168.0), TrackSection("B", 168.0, 336.0),
                                 TrackSection("C", 336.0, 480.0)),
                       curves=(Curve("C1", 72.0, 408.0, 600.0, "left"),))
CHANNELS = pd.DataFrame([("ACC_W1L_Z", "acceleration", "g", 1, "L", "z", 0.0, -0.97, 0.0, 9.80665),
                         ("ACC_W1R_Z", "acceleration", "g", 1, "R", "z", 0.0, 0.97, 0.0, 9.80665),
                         ("ACC_W1R_Y", "acceleration", "g", 1, "R", "y", 0.0, 0.97, 0.0, 9.80665)],
                        columns=["name", "quantity", "unit", "wheelset", "side", "direction", "x", "y", "z",
                                 "sensitivity"])
CFG = DiagnosisConfig(workers=2)


@functools.lru_cache(maxsize=1)
def blocks():
    from test_estimator_synthetic import control_model

    ec = EstimatorConfig()
    return wheelset_blocks(control_model(), CHANNELS, "vertical_lateral", FS, f_lo=ec.f_lo_hz, f_hi=ec.f_hi(FS),
                           alpha=ec.regularisation, df=CFG.transfer_df_hz)


def roughness_psd(k: np.ndarray, level: float) -> np.ndarray:
    """Rail roughness PSD [m²/(1/m)] over wavenumber: ~k⁻³ (a broadband rail) with a corrugation bump."""
    k = np.maximum(k, 1e-3)
    return level * 1e-12 * (k / 10.0) ** -3 * (1 + 20 * np.exp(-0.5 * ((k - 1 / 0.06) / 1.5) ** 2))


def synthetic_evidence(truth: FieldState, *, days=("d1", "d1", "d2"), anomaly=None, seed=3) -> Evidence:
    """Evidence of runs over 0-480 m (20 m/s, wheelset 1 leading) through the true field ``truth``.

    ``anomaly``: ``(from_m, to_m, gain(f))`` multiplies the accelerations' spectra there (an effect outside the
    catalogue). Each run gets its own acceleration noise (1e-4 of the signal PSD, white) and a ±5 % Welch-like
    scatter per frequency line.
    """
    bl = blocks()
    band_table = third_octave_bands(CFG.shortest_m, CFG.longest_m)
    ec = EstimatorConfig()
    rng = np.random.default_rng(seed)
    ev0 = Evaluator(Evidence((), band_table, np.zeros(0, bool), SITE), {1: bl}, lambda x: Trackform(),
                    ContactParameters())
    nper = int(round(CFG.window_m / SPEED * FS))
    f = np.fft.rfftfreq(nper, 1 / FS)[1:]
    segs, cal = [], []
    for r, day in enumerate(days):
        for a, b in segments_of(0.0, 480.0, CFG.segment_m):
            c = 0.5 * (a + b)
            curve = "C1" if 72.0 + 1 <= a and b <= 408.0 else None
            if LINE.curve_at(a) is not None and curve is None:
                continue  # straddles the curve's ends
            probe = SegmentSpectra("probe", day, 1, "leading", a, b, SPEED, ("L", "R"), curve, (0.0, 0.0), f,
                                   np.zeros((f.size, 3, 3)), np.zeros(0, int), np.zeros((2, 0)), np.zeros((2, 0)))
            th = ev0.theta_at(truth, probe)
            K = ev0.stiffness(truth)
            offs = np.array([truth.offset_of(n) for n in bl.channels])
            H = bl.forward(ev0.trackform_at(truth, c), th, K, offsets=offs)
            Hf = np.stack([np.interp(f, bl.f, H[:, i, j].real) + 1j * np.interp(f, bl.f, H[:, i, j].imag)
                           for i in range(3) for j in range(2)], axis=1).reshape(f.size, 3, 2)
            level = 1.0 + 0.5 * math.sin(c / 50.0)
            Pr = np.stack([roughness_psd(f / SPEED, level), roughness_psd(f / SPEED, 0.6 * level)], axis=1) / SPEED
            S = np.einsum("fij,fj,fkj->fik", Hf, Pr, np.conj(Hf))
            if anomaly is not None and anomaly[0] <= c <= anomaly[1]:
                g = anomaly[2](f)
                S = S * (g[:, None, None] * g[:, None, None])
            noise = 1e-4 * np.mean(np.einsum("fii->fi", S).real, axis=0)
            S = S * (1 + 0.05 * rng.standard_normal(f.size))[:, None, None] + np.eye(3)[None] * noise[None, :, None]
            ok = [i for i, (lc, lo, hi) in enumerate(band_table)
                  if SPEED / hi >= ec.f_lo_hz and SPEED / lo <= ec.f_hi(FS) and hi <= CFG.window_m / CFG.min_cycles]
            ok = np.array(ok)
            # the reference through the same windows in chainage (dk = df/v): the same discrete band sums
            dfw = float(f[1] - f[0])
            ref = np.array([[Pr[(f >= SPEED / band_table[i, 2]) & (f < SPEED / band_table[i, 1]), j].sum() * dfw
                             for i in ok] for j in range(2)])
            segs.append(SegmentSpectra(f"run{r}", day, 1, "leading", a, b, SPEED, ("L", "R"), curve, (0.0, 0.0), f,
                                       S, ok, ref, ref * 1e-4))
            cal.append(day == days[0] and a >= SITE[0] and b <= SITE[1])
    return Evidence(tuple(segs), band_table, np.array(cal), SITE)


def diagnose(truth: FieldState, **kw):
    ev = synthetic_evidence(truth, **kw)
    evaluator = Evaluator(ev, {1: blocks()}, lambda x: Trackform(), ContactParameters())
    cands = catalogue(ev, LINE, CHANNELS, names=("trackform", "contact_angle", "sensor_offset", "contact_stiffness",
                                                 "wheel_roughness"))
    return diagnose_field(evaluator, cands, CFG)


def test_blocks_equal_the_estimators_transfer_function():
    from estimator.inversion import wheelset_transfer
    from receptance.track import track_frf
    from test_estimator_synthetic import control_model

    ec = EstimatorConfig()
    bl = blocks()
    tf = Trackform()
    df = CFG.transfer_df_hz
    f = df * np.arange(1, int(0.5 * FS / df) + 1)
    th = (-0.05, 0.4)
    ref = wheelset_transfer(control_model(), CHANNELS, "vertical_lateral", FS, f_lo=ec.f_lo_hz, f_hi=ec.f_hi(FS),
                            alpha=ec.regularisation, df=df, track=track_frf(f, tf), theta=th,
                            contact_stiffness=ContactParameters().contact().stiffness)
    T = bl.transfer(tf, th, ContactParameters().contact().stiffness)
    n = bl.f.size
    got, want = T, ref.T[1:n + 1]
    sel = (bl.f > 20) & (bl.f < 350)
    rel = np.abs(got[sel] - want[sel]) / np.abs(want[sel]).max(axis=0, keepdims=True)
    assert rel.max() < 1e-6
    # and the forward map is its inverse in the band (T H = I up to the regularisation)
    H = bl.forward(tf, th, ContactParameters().contact().stiffness)
    TH = np.einsum("fij,fjk->fik", T[sel], H[sel])
    assert np.median(np.abs(TH - np.eye(2)[None])) < 0.05


def test_sensor_offset_lever_is_the_rigid_body_rotation():
    """A moved sensor reads d·u(P) + (δ×d)·θ(P): its row equals the model evaluated at the moved point."""
    from estimator.inversion import sensor_model
    from test_estimator_synthetic import control_model

    bl = blocks()
    d = np.array([0.05, -0.04, 0.03])
    rows = bl.sensor_rows(np.array([d, [0, 0, 0], [0, 0, 0]]))
    moved = CHANNELS.copy()
    moved.loc[0, ["x", "y", "z"]] = moved.loc[0, ["x", "y", "z"]].to_numpy(float) + d
    m_w, labels = sensor_model(control_model(), moved)
    H = m_w.receptance([labels[0]], ["contact_L:y", "contact_L:z", "contact_R:y", "contact_R:z"], bl.f[::200]).data
    np.testing.assert_allclose(rows[::200, 0, :], H[0].T, rtol=1e-6, atol=1e-6 * np.abs(H).max())


def test_nominal_truth_accepts_nothing():
    res = diagnose(FieldState())
    assert res.accepted == ()
    assert "nothing accepted" in res.verdict
    nominal = res.errors.query("stage == 'nominal' and set == 'calibration'")["error_db"].iloc[0]
    assert nominal < 0.5


@pytest.mark.slow
def test_trackform_change_found_ranked_first_and_validated():
    truth = FieldState().with_trackform_change(TrackformChange(168.0, 336.0, (
        ("pad_stiffness", 2.5), ("subplate_stiffness", 2.5), ("pad_damping", 1.0), ("subplate_damping", 1.0))))
    res = diagnose(truth)
    first = res.rounds[0][0]
    assert isinstance(first.effect, TrackformEffect) and first.effect.section == "B"
    assert res.accepted and res.accepted[0].effect == first.effect
    assert abs(first.params["stiffness_factor"] / 2.5 - 1) < 0.25
    assert first.validation_after <= 0.5 * first.validation_before
    assert first.uncertainty["stiffness_factor"] < 0.5


@pytest.mark.slow
def test_sensor_offset_found():
    truth = FieldState().with_sensor_offset("ACC_W1L_Z", 0.0, 0.08, 0.0)
    res = diagnose(truth)
    first = res.rounds[0][0]
    assert isinstance(first.effect, SensorOffset) and first.effect.channel == "ACC_W1L_Z"
    assert abs(first.params["dy"] / 0.08 - 1) < 0.25
    assert res.accepted[0].effect == first.effect
    assert first.validation_after <= 0.5 * first.validation_before


@pytest.mark.slow
def test_contact_angle_and_two_effects_one_after_the_other():
    truth = (FieldState().with_curve_angles("C1", "leading", 0.0, 0.6)
             .with_sensor_offset("ACC_W1R_Y", 0.0, 0.0, 0.06))
    res = diagnose(truth)
    names = [c.effect.name for c in res.accepted]
    assert set(names[:2]) == {"contact_angle", "sensor_offset"}, res.verdict
    ca = next(c for c in res.accepted if isinstance(c.effect, ContactAngle))
    assert abs(ca.params["gamma_R"] / 0.6 - 1) < 0.25
    e = res.errors.query("set == 'validation'")["error_db"].to_numpy()
    assert e[-1] <= 0.5 * e[0]


@pytest.mark.slow
def test_effect_outside_the_catalogue_is_left_unexplained_and_located():
    """A local anomaly (a +10 dB band of 60-120 Hz in one segment, both days): no effect forced, stretch named."""
    gain = lambda f: np.where((f > 60) & (f < 120), 10 ** (10 / 20), 1.0)  # noqa: E731
    res = diagnose(FieldState(), anomaly=(120.0, 144.0, gain))
    assert not [c for c in res.accepted if not isinstance(c.effect, WheelRoughness)] or res.accepted == ()
    assert "No effect of the catalogue explains" in res.verdict
    located = res.residual[res.residual["unexplained"]]
    assert not located.empty and set(located["from_m"]) == {120.0}


def test_the_calibrated_estimator_uses_the_transfer_function_the_diagnosis_fitted():
    """Two realisations of one field state agree: the estimator's FieldModel (field_model_for) and the
    diagnosis's fast blocks give the same T on the changed section, with the changed trackform there only."""
    from estimator.inversion import model_channels
    from estimator.workflow import prepare
    from estimator.diagnosis.state import field_model_for
    from estimator.io.line import TrackSection
    from test_estimator_synthetic import control_model, sensor_table

    line = LineDescription(sections=LINE.sections, curves=LINE.curves,
                           trackforms=(TrackSection("all", 0.0, 480.0, Trackform()),))
    ec = EstimatorConfig(models=("vertical_lateral",))
    fm = prepare(control_model(), sensor_table(), line=line, config=ec)
    st = FieldState().with_trackform_change(TrackformChange(168.0, 336.0, (
        ("pad_stiffness", 0.6), ("subplate_stiffness", 0.6), ("pad_damping", 2.2), ("subplate_damping", 2.2))))
    fm2 = field_model_for(fm, st)
    tfs = fm2.trackforms()
    assert [(a, b) for a, b, _ in tfs] == [(0.0, 168.0), (168.0, 336.0), (336.0, 480.0)]
    assert tfs[1][2].pad_stiffness_z == pytest.approx(0.6 * Trackform().pad_stiffness_z)
    assert tfs[0][2] == Trackform() and tfs[2][2] == Trackform()
    ch = sensor_table()
    ch1 = ch[(ch.quantity == "acceleration") & (ch.wheelset == 1)].reset_index(drop=True)
    rows, _ = model_channels("vertical_lateral", ch1)
    sub = ch1.loc[rows].reset_index(drop=True)
    T_est = fm2.transfer("vertical_lateral", sub, FS, 1, (0.0, 0.0)).T
    bl = wheelset_blocks(fm.model, sub, "vertical_lateral", FS, f_lo=ec.f_lo_hz, f_hi=ec.f_hi(FS),
                         alpha=ec.regularisation, df=ec.transfer_df_hz)
    ev = Evaluator(Evidence((), None, np.zeros(0, bool), (0, 1)), {1: bl}, lambda x: Trackform(), ec.contact)
    T_fast = bl.transfer(ev.trackform_at(st, 200.0), (0.0, 0.0), ev.stiffness(st))
    sel = (bl.f > 20) & (bl.f < 350)
    diff = np.abs(T_fast[sel] - T_est[1:bl.f.size + 1][sel]).max() / np.abs(T_est[1:bl.f.size + 1][sel]).max()
    assert diff < 1e-9
