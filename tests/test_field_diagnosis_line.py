"""Field diagnosis on the virtual line (issue 15 acceptance, short section 400-800 m, 2 days × 2 runs).

Calibration: day 1 over 400-800 m; validation: day 2 (the fit never sees it). Oracles: each scenario's truth
(``truth/truth.json``: the hidden support change, the gauge narrowing behind the contact angles) and the line's
own curving law (:func:`lab_data.line.curving.rail_contact_angles`) for the true angles.

The wheelset model is the control wheelset's as the lab workflow saves it (design FE exported to 2 kHz, every FE
mode kept: :func:`test_estimator_synthetic.lab_workflow_model`). Measured with the bogie's rail coupling (each
wheelset's forces along its own contact normals) and the wheelset's comb in the evidence (the estimator's own
steps): ``nominal`` accepts nothing (E 1.44 dB, floor 0.73 dB); ``trackform_change`` the stretch 720.0-784.9 m
(truth 720-780 m) factor 0.57 (truth 0.60); ``contact_angle`` leading wheelset γ on the outer rail 62.0° (truth
58.3°); ``sensor_offset`` −37.7 mm alone; ``two_effects`` both, one after the other; ``lateral_sign`` nothing
forced onto it, the reversed channel named by the channel check; ``pad_defect`` nothing forced, located near
590 m on rail L. The last two tests give the estimator the line's own everyday laws (curving and loss law):
the verdicts hold there too.
"""

from __future__ import annotations

import functools
import glob
import math
import tempfile
from pathlib import Path

import numpy as np
import pytest

from curving_truth import curving_law
from line_laws import curve_c1_angles, line_with_causal_layers

pytestmark = pytest.mark.slow


@functools.lru_cache(maxsize=1)
def _model_file() -> str:
    import tempfile
    from pathlib import Path

    from receptance import save_model
    from test_estimator_synthetic import lab_workflow_model

    path = Path(tempfile.mkdtemp(prefix="field_diag_line_")) / "hybrid_model.npz"
    save_model(lab_workflow_model(), path)
    return str(path)


def _campaign(scenario: str) -> str:
    from lab_data.line.cache import line_campaign_dir
    from lab_data.line.campaign import FIRST_CURVE_SECTION

    return line_campaign_dir(scenario, days=2, runs_per_day=2, section=FIRST_CURVE_SECTION)


def _diagnose(scenario: str, validation_stretches=(), line=None, curve_contact_angles=None, **config):
    """The site's diagnosis on the campaign of ``scenario``; ``line`` (default: the campaign's ``line.json``) and
    ``curve_contact_angles`` (:class:`~estimator.config.EstimatorConfig`) change what the estimator is told."""
    from estimator.config import EstimatorConfig
    from estimator.diagnosis import DiagnosisConfig, run_field_diagnosis
    from lab_data.line.campaign import FIRST_CURVE_SECTION

    d = _campaign(scenario)
    res = run_field_diagnosis(sorted(glob.glob(f"{d}/runs/*/*.mf4")), sorted(glob.glob(f"{d}/trolley/*.csv")),
                              FIRST_CURVE_SECTION, _model_file(), f"{d}/sensors.csv",
                              line=str(line or f"{d}/line.json"), config=DiagnosisConfig(**{"workers": 2, **config}),
                              estimator_config=EstimatorConfig(wheelbase_m=2.1,
                                                               curve_contact_angles=curve_contact_angles),
                              validation_stretches=validation_stretches)
    return d, res


@functools.lru_cache(maxsize=1)
def _diagnose_nominal():
    """``nominal`` with the estimator's defaults: the line's own calibration (two tests read it)."""
    return _diagnose("nominal")


def _index_error(res, part: str, stage: str) -> float:
    """Band-index RMS error [dB] of a set (pooled over the runs, wheelsets, rails and bands, by window count)."""
    t = res.index_errors.query("set == @part and stage == @stage")
    return float(np.sqrt((t["rms_error_db"] ** 2 * t["n_windows"]).sum() / t["n_windows"].sum()))


def test_trackform_change_on_the_virtual_line():
    """Pads and subplates 40 % softer on 720-780 m (not in ``line.json``): the evidence singles out 720-768 m
    (its 24 m segments), the fitted-extent candidate ranks first — ahead of the line section 710-860 m
    (ΔBIC −1220 against −1068, its two ends counted) — with its ends within one Welch window (8 m) of the truth
    (measured 720.0 m, the evidence's edge: no segment before it; 785.0 m), the factor within 25 % (0.569), the
    validation cells' error at least halved (3.96 → 1.02 dB) and the EN 13231-3 band-index error of the
    validation day on the changed stretch at least halved (1.91 → 0.44 dB)."""
    from estimator.diagnosis import TrackformStretch
    from lab_data.line.files import read_truth

    truth = read_truth(_campaign("trackform_change"))["scenario"]["support_changes"][0]
    d, res = _diagnose("trackform_change", validation_stretches=[(truth["from_m"], truth["to_m"])],
                       effects=("trackform", "contact_stiffness"), max_effects=1)
    first = res.diagnosis.rounds[0][0]
    assert isinstance(first.effect, TrackformStretch)
    assert res.diagnosis.accepted and res.diagnosis.accepted[0].effect == first.effect
    section = next(c for c in res.diagnosis.rounds[0][1:] if c.name == "trackform")
    assert first.delta_bic < section.delta_bic and first.n_fitted == section.n_fitted + 2
    window = res.config.window_m
    assert abs(first.params["from_m"] - truth["from_m"]) <= window
    assert abs(first.params["to_m"] - truth["to_m"]) <= window
    assert abs(first.params["stiffness_factor"] / truth["factors"]["pad_stiffness_z"] - 1) < 0.25
    assert first.validation_after <= 0.5 * first.validation_before
    assert _index_error(res, "validation stretch", "calibrated") <= 0.5 * _index_error(res, "validation stretch",
                                                                                         "nominal")


def test_contact_angle_on_the_virtual_line():
    """Outer-rail gauge 3 mm tight: the leading wheelset's contact angles on curve C1 are found first, the outer
    rail's (L, 58°) within 25 % of the line's own curving law at the curve's speed (measured 62.0°), the
    validation cells' error and the validation day's band-index error at least halved."""
    from estimator.diagnosis import ContactAngle

    d, res = _diagnose("contact_angle", effects=("contact_angle", "contact_stiffness"), max_effects=1)
    first = res.diagnosis.rounds[0][0]
    assert isinstance(first.effect, ContactAngle) and first.effect.curve == "C1" and first.effect.role == "leading"
    g_l, g_r = curving_law(d)
    assert abs(first.params["gamma_L"] / g_l - 1) < 0.25
    assert abs(first.params["gamma_R"] - g_r) < math.radians(1.0)
    assert res.diagnosis.accepted and res.diagnosis.accepted[0].effect == first.effect
    assert first.validation_after <= 0.5 * first.validation_before
    # through the estimator: the validation day's EN 13231-3 band-index error at least halved (measured 7.03 → 2.80)
    assert _index_error(res, "validation", "calibrated") <= 0.5 * _index_error(res, "validation", "nominal")


def test_sensor_offset_on_the_virtual_line_ranks_first_and_falls_to_the_floor():
    """The vertical accelerometer of wheelset 1 left mounted 40 mm outboard: the true channel's offset ranks first,
    is the only effect accepted, within 25 % of the truth, the other lever arm (dx) undetermined at 0, and the
    validation day's EN 13231-3 band-index error falls by at least half of its excess over ``nominal``'s (the
    floor the estimate reaches with no hidden effect: same line, runs' speeds and noise; nothing is accepted
    there).

    Measured: ΔBIC −258 against the next candidate's −197; dy −37.7 mm (truth −40 mm); validation band index
    1.22 → 1.05 dB against the floor's 0.99 dB (73 % of the excess gone)."""
    from estimator.diagnosis import SensorOffset
    from lab_data.line.files import read_truth

    d, res = _diagnose("sensor_offset")
    (channel, offset), = read_truth(d)["scenario"]["sensor_offsets"].items()
    first = res.diagnosis.rounds[0][0]
    assert isinstance(first.effect, SensorOffset) and first.effect.channel == channel, res.diagnosis.verdict
    assert [a.effect for a in res.diagnosis.accepted] == [first.effect], res.diagnosis.verdict
    assert abs(first.params["dy"] / offset[1] - 1) < 0.25 and abs(first.params["dx"]) < 0.01
    assert first.validation_after < first.validation_before
    before = _index_error(res, "validation", "nominal")
    after = _index_error(res, "validation", "calibrated")
    _, nominal = _diagnose_nominal()
    assert nominal.diagnosis.accepted == ()
    floor = _index_error(nominal, "validation", "nominal")
    assert before > floor + 0.15, (before, floor)  # the offset shows in the band indexes (measured 1.22 vs 0.99 dB)
    assert after - floor <= 0.5 * (before - floor), (before, after, floor)


def assert_causal_track_picture(candidate) -> None:
    """``candidate`` is a trackform of a whole line section (not a stretch) with the pads' and subplates' stiffness
    factor within what the line's causal layers give over the evidence's 10-300 Hz.

    The line's layers (:mod:`lab_data.line.damping`) are causal: their storage stiffness ``Re K(1 + η g(f))``
    rises through the band. Eq. 2.32's is constant. A constant factor fitted over the band lies inside that range.
    """
    from estimator.diagnosis.effects import TrackformEffect, TrackformStretch
    from lab_data.line.damping import unit_loss_fit

    assert isinstance(candidate.effect, TrackformEffect) and not isinstance(candidate.effect, TrackformStretch), \
        candidate.effect
    g = unit_loss_fit().g(np.geomspace(10.0, 300.0, 200))
    storage = np.concatenate([(1 + eta * g).real for eta in (0.13, 0.20)])  # the line's pads and subplates
    assert storage.min() <= candidate.params["stiffness_factor"] <= storage.max(), (candidate.params, storage.min(),
                                                                                     storage.max())
    assert candidate.validation_after < candidate.validation_before


def test_two_effects_on_the_virtual_line_one_after_the_other():
    """``two_effects`` (the softer trackform on 720-780 m and the offset accelerometer together): exactly the two
    effects, the trackform stretch first, the offset second, each within 25 % of the truth and each lowering the
    validation cells' error.

    Measured: 720.0-784.9 m, factor 0.565 (truth 720-780 m, 0.60), ΔBIC −1105; then ACC_W1L_Z −36.7 mm (truth
    −40 mm), ΔBIC −270; nothing in round 3. Validation day's band index 1.47 → 1.13 dB (``nominal``'s 0.99 dB)."""
    from estimator.diagnosis import SensorOffset, TrackformStretch
    from lab_data.line.files import read_truth

    d, res = _diagnose("two_effects")
    truth = read_truth(d)["scenario"]
    change = truth["support_changes"][0]
    (channel, offset), = truth["sensor_offsets"].items()
    acc = res.diagnosis.accepted
    assert len(acc) == 2 and isinstance(acc[0].effect, TrackformStretch), res.diagnosis.verdict
    assert abs(acc[0].params["stiffness_factor"] / change["factors"]["pad_stiffness_z"] - 1) < 0.25
    assert abs(acc[0].params["from_m"] - change["from_m"]) <= res.config.window_m
    assert abs(acc[0].params["to_m"] - change["to_m"]) <= res.config.window_m
    c = acc[1]
    assert isinstance(c.effect, SensorOffset) and c.effect.channel == channel, res.diagnosis.verdict
    assert abs(c.params["dy"] / offset[1] - 1) < 0.25
    assert acc[0].validation_after < acc[0].validation_before and c.validation_after < c.validation_before


def test_nominal_on_the_virtual_line_accepts_nothing():
    """No hidden effect, the estimator's defaults: nothing is accepted, and the verdict says so.

    The nearest candidates are the line's everyday physics the defaults leave out (measured E 1.44 dB, noise
    floor 0.73 dB): the line-wide trackform of section milano_modificato (stiffness ×0.92, damping ×1.10,
    ΔBIC −212; the constant-loss picture of the line's causal pads and subplates,
    :func:`assert_causal_track_picture`), which lowers E by 9.9 % and the validation cells by 8.3 %, and curve
    C1's leading-wheelset contact angles (γ_L 6.0°, γ_R 1.0°, ΔBIC −122; the line's curving law 3.9° / 1.0°, the
    default 1.43°), E −6.1 %, validation −9.5 %; the criterion asks 10 % of each. The margins are thin. Until the rail
    coupling took each wheelset's forces along its own contact normals, the coupling computed the leading
    wheelset's forces at the trailing one's angles once the leading ones were fitted, and both were accepted.

    The evidence mirrors the estimator (bogie coupling, comb): calibration error ≤ 2 dB, and the corrugated rail's
    50 mm band (182 Hz at the curve's speed) within 2.5 dB of the trolley."""
    d, res = _diagnose_nominal()
    diag = res.diagnosis
    assert diag.accepted == (), diag.verdict
    assert diag.verdict.startswith("nothing accepted")
    assert_causal_track_picture(diag.rounds[0][0])
    e = diag.errors.query("stage == 'nominal' and set == 'calibration'")["error_db"].iloc[0]
    assert e <= 2.0
    bb = diag.by_band.query("stage == 'nominal' and set == 'calibration' and rail == 'R'")
    r50 = bb[(bb["wavelength_mm"] > 45) & (bb["wavelength_mm"] < 56)]
    assert not r50.empty and float(np.abs(r50["mean_error_db"]).max()) <= 2.5
    assert res.channel_check is not None and res.channel_check.empty  # no accelerometer reads against the model
    # the line's pads and subplates are causal (lab_data.line.damping): they equal their stated stiffness near
    # 100 Hz (98 Hz for the pads, 100 Hz for the subplates) and stiffen with frequency. The fit finds a reference
    # within a factor 2 of that out of a 2-5000 Hz search; it lowers E by a few per cent only (the 100-300 mm
    # cells it fixes are few), so it is not accepted
    stiff = [c for c in diag.candidates if c.name == "dynamic_stiffening"]
    assert len(stiff) == 1 and 50.0 <= stiff[0].params["reference_hz"] <= 200.0
    assert stiff[0].error_after < stiff[0].error_before


def test_reversed_lateral_accelerometer_is_not_forced_and_is_located():
    """``ACC_W1L_Y`` mounted the wrong way round (outside the catalogue): the band errors barely see it (the
    inversion leans on the vertical channels: E 1.53 dB as on ``nominal``), no effect is forced onto it, and the
    channel check names it alone: it reads against what the model predicts from the wheelset's other channels in
    every segment (median ρ −0.75, nominal +0.60), and reversing it makes the wheelset agree (ACC_W1L_Z, predicted
    from it, reads ρ −0.38 and is not named: its disagreement is the reversed channel's)."""
    from lab_data.line.files import read_truth

    d, res = _diagnose("lateral_sign", effects=("sensor_offset", "contact_angle", "contact_stiffness"))
    flipped = read_truth(d)["scenario"]["sign_flips"]
    assert res.diagnosis.accepted == (), res.diagnosis.verdict
    bad = res.channel_check
    assert list(bad["channel"]) == flipped and list(bad["reversal_explains"]) == flipped
    assert float(bad["share_negative"].iloc[0]) >= 0.9 and float(bad["median_rho"].iloc[0]) < -0.3
    assert flipped[0] in res.diagnosis.verdict


def test_pad_defect_is_not_forced_and_is_located():
    """Four rail pads of rail L at 590 m lost 85 % of their stiffness (outside the catalogue: a few sleepers are a
    defect, not a trackform section): no trackform change is forced onto it, and the comparison names the spot —
    a local departure of the 100-300 mm band index on rail L inside the defect's metres (measured 591-592 m,
    +3.4 dB)."""
    from lab_data.line.files import read_truth

    d, res = _diagnose("pad_defect", effects=("trackform",), max_effects=1)
    truth = read_truth(d)["scenario"]["support_changes"][0]
    assert res.diagnosis.accepted == (), res.diagnosis.verdict
    an = res.comparison.anomalies
    hit = an[(an["rail"] == truth["rail"]) & (an["to_m"] > truth["from_m"] - 1) & (an["from_m"] < truth["to_m"] + 1)]
    assert not hit.empty, an
    assert (an["rail"] == truth["rail"]).all() and an["from_m"].between(truth["from_m"] - 5, truth["to_m"] + 5).all()


# --------------------------------------------------------------------------------------------------------------
# The line's everyday laws given to the estimator
# --------------------------------------------------------------------------------------------------------------
# The estimator's defaults leave out two laws of the virtual line: the bogie-yaw curving behind the leading
# wheelset's contact angles, and the causal pads and subplates (:mod:`line_laws`). With the defaults ``nominal``
# accepts nothing all the same (the tests above): neither difference lowers the site's error by the criterion's
# 10 %. Before the rail coupling took each wheelset's forces along its own contact normals, both were accepted.
#
# The tests below remove those two differences through the estimator's own inputs (a line description whose
# trackforms carry the line's loss law, causal layers holding their table stiffness at 94.2 Hz, and the curve's
# contact angles of the line's curving law for each wheelset role) and check what is left for the diagnosis. The
# criterion, catalogue, site and runs are those above (400-800 m, 2 days × 2 runs, day 1 calibrates, day 2
# validates, the control wheelset's model as the lab workflow saves it).
#
# Measured: ``nominal`` accepts nothing (E 1.17 dB, noise floor 0.59 dB; validation band index 0.70 dB).
# ``sensor_offset`` ranks first (ΔBIC −352, next −104), is the only effect accepted, −46 mm (truth −40 mm), and
# the validation day's EN 13231-3 band-index error falls 1.07 → 0.74 dB, 0.04 dB above the ``nominal`` floor
# (the excess over the floor falls by 88 %).


@functools.lru_cache(maxsize=None)
def _diagnose_with_line_laws(scenario: str):
    d = _campaign(scenario)
    line = line_with_causal_layers(d, Path(tempfile.mkdtemp(prefix=f"laws_{scenario}_")))
    return _diagnose(scenario, line=line, curve_contact_angles=curve_c1_angles(d))


def test_nominal_with_the_lines_laws_accepts_nothing():
    """No hidden effect and the line's everyday laws given: nothing is accepted, and the verdict says so; the
    evidence's error stands above 1.2 × its floor (what the criterion's third test guards: the residual is the
    estimate's own, not an effect's) and no stretch of the site stands out."""
    _, res = _diagnose_with_line_laws("nominal")
    diag = res.diagnosis
    assert diag.accepted == (), diag.verdict
    assert diag.verdict.startswith("nothing accepted")
    e = diag.errors.query("stage == 'nominal' and set == 'calibration'")["error_db"].iloc[0]
    assert e <= 1.5  # measured 1.17 dB; with the defaults 1.44 dB
    assert e > 1.2 * diag.noise_floor_db  # the docstring's residual above the floor (0.59 dB measured)
    assert "no stretch stands out" in diag.verdict


def test_sensor_offset_with_the_lines_laws_ranks_first_and_falls_to_the_floor():
    """ACC_W1L_Z mounted 40 mm outboard, the line's laws given: the true channel's offset ranks first on the
    calibration day, is the only effect accepted, within 25 % of the truth; on the validation day the band-index
    error falls by ≥ 80 % of its excess over ``nominal``'s own (the floor the estimate reaches with no hidden
    effect: same line, laws, runs' speeds and noise)."""
    from estimator.diagnosis import SensorOffset
    from lab_data.line.files import read_truth

    d, res = _diagnose_with_line_laws("sensor_offset")
    (channel, offset), = read_truth(d)["scenario"]["sensor_offsets"].items()
    first = res.diagnosis.rounds[0][0]
    assert isinstance(first.effect, SensorOffset) and first.effect.channel == channel, res.diagnosis.verdict
    assert [a.effect for a in res.diagnosis.accepted] == [first.effect], res.diagnosis.verdict
    assert abs(first.params["dy"] / offset[1] - 1) < 0.25
    assert first.validation_after < first.validation_before
    before = _index_error(res, "validation", "nominal")
    after = _index_error(res, "validation", "calibrated")
    _, nominal = _diagnose_with_line_laws("nominal")
    floor = _index_error(nominal, "validation", "nominal")
    assert before > floor + 0.3  # the offset is visible in the band indexes (measured 1.07 against 0.70 dB)
    assert after - floor <= 0.2 * (before - floor), (before, after, floor)
