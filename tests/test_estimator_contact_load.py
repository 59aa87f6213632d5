"""Contact loss: the estimated dynamic contact force against the static wheel load (estimator.contact_load).

Oracle: a pure 60 mm corrugation on rail L through the linear forward map; its contact force in closed form,
``F = D⁻¹ n`` (thesis eq. 2.20, full vertical model, rail R smooth) with the rail coupling the bogie's two
wheelsets as the synthetic run has it, at the frequencies the run's speeds make of it. The contact force
``B⁺_α a`` depends neither on the contact stiffness nor on the track, so the static load the flag compares it
with can be set low enough for a 40 µm corrugation to lift the wheel, without a forward map that leaves the
linear regime.
"""

from __future__ import annotations

import numpy as np
import pytest

from estimator import EstimatorConfig, estimate_run, prepare
from receptance import ContactParameters, Trackform, track_frf
from test_estimator_synthetic import SyntheticLine, control_model, make_run, sensor_table

AMPLITUDE_M = 40e-6
WAVELENGTH_M = 0.060
PATCH_M = (100.0, 300.0)


def _closed_form_force(speeds: np.ndarray, wheelbase: float) -> np.ndarray:
    """|F_L| [N] of wheelsets 1 and 2 (rows) under the corrugation on rail L over the frequencies ``v / λ`` of the
    speeds' range: the bogie's two wheelsets on one rail, ``[[D, C], [C, D]] F = n`` (thesis eq. 2.20 per
    wheelset, ``C`` the rail's transfer receptance at the wheelbase), wheelset 2 seeing the corrugation
    ``a / v`` later, as the synthetic run's forward map has it."""
    from estimator.inversion import rail_coupling, sensor_model
    from receptance.transfer import full_vertical_transfer

    chans = sensor_table().iloc[:2].reset_index(drop=True)
    m_w, labels = sensor_model(control_model(), chans)
    v = np.linspace(np.min(speeds), np.max(speeds), 50)
    f = v / WAVELENGTH_M
    mt = full_vertical_transfer(m_w, f, channels=labels, track=track_frf(f, Trackform()),
                                contact_stiffness=ContactParameters().stiffness())
    D = np.moveaxis(mt.dynamic_compliance.data, 2, 0)
    C = rail_coupling(f, Trackform(), wheelbase, ("L", "R"), ("L", "R"))
    big = np.block([[D, C], [C, D]])
    n = np.zeros((f.size, 4), complex)
    n[:, 0] = AMPLITUDE_M
    n[:, 2] = AMPLITUDE_M * np.exp(-2j * np.pi * f * wheelbase / v)
    F = np.linalg.solve(big, n[..., None])[..., 0]
    return np.abs(F[:, [0, 2]]).T


@pytest.fixture(scope="module")
def corrugated(tmp_path_factory):
    line = SyntheticLine(sinusoids={"L": [(WAVELENGTH_M, AMPLITUDE_M, *PATCH_M)]}, rel_width=0.0, broadband_rms=0.0)
    return make_run(tmp_path_factory.mktemp("lift"), control_model(), line=line, duration_s=40, name="lift")


def test_a_wheel_load_the_force_exceeds_is_flagged_where_and_on_the_rail_it_is(corrugated):
    """With the static load at 1.6 kN the corrugation's force lifts wheel L of both wheelsets on the corrugated
    patch only: flagged there, on rail L, each wheelset's lowest F/Q as the closed form's largest at the run's
    speeds (2.25 and 1.66, the rail coupling making them differ; within 5 %, 1 % measured). Rail R (smooth) is
    never flagged. The estimate is not masked."""
    sr = corrugated
    load = 1600.0
    cfg = EstimatorConfig(models=("vertical",), wheelbase_m=sr.wheelbase,
                          contact=ContactParameters(wheel_load_N=load))
    est = estimate_run(sr.path, prepare(control_model(), sensor_table(), config=cfg))
    q = est.qc[est.qc["kind"] == "contact_loss"]
    assert len(q) >= 2 and (q["action"] == "flagged").all()
    assert set(q["channel"]) == {"ACC_W1L_Z", "ACC_W2L_Z"}
    assert (q["chainage_from_m"] > PATCH_M[0] - 1).all() and (q["chainage_to_m"] < PATCH_M[1] + 1).all()
    low = q.assign(low=q["reason"].str.extract(r"reaches (-?[\d.]+) x")[0].astype(float)).groupby("channel")["low"]
    # the speeds at which the wheels crossed the patch: the closed form's largest |F| there, per wheelset
    inside = (sr.chainage > PATCH_M[0] + 10) & (sr.chainage < PATCH_M[1] - 10)
    f_closed = _closed_form_force(np.abs(np.gradient(sr.chainage, sr.t))[inside], sr.wheelbase).max(axis=1)
    np.testing.assert_allclose(-low.min()[["ACC_W1L_Z", "ACC_W2L_Z"]], f_closed / load, rtol=0.05)
    assert np.isfinite(est.profile(1, "vertical").rail).all(axis=0).mean() > 0.7  # flagged, not masked
    assert any("the wheel leaves the rail on" in s for s in est.processing)


def test_the_nominal_wheel_load_keeps_the_wheels_on_the_rails(corrugated):
    """The same run at the default 55 kN static load: no finding, and the history says so."""
    cfg = EstimatorConfig(models=("vertical",), wheelbase_m=corrugated.wheelbase)
    est = estimate_run(corrugated.path, prepare(control_model(), sensor_table(), config=cfg))
    assert not (est.qc["kind"] == "contact_loss").any()
    assert any("the wheels stay on the rails" in s for s in est.processing)


def test_the_contact_force_is_the_models_own_with_its_sign():
    """``contact_force`` of one wheelset (no rail coupling) against ``F = D⁻¹ n`` evaluated line by line on the
    same irregularity (rail L: 45 and 90 Hz in a phase that makes the force lopsided, so a wrong sign would show;
    rail R: 143 Hz), in the inversion's band: within 3 % RMS on each side; and the flag reads its sign."""
    from estimator.contact_load import contact_force, contact_loss_events
    from estimator.inversion import sensor_model
    from receptance.transfer import full_vertical_transfer
    from test_estimator_synthetic import forward_accelerations, wheelset1_transfer

    fs, n = 1000.0, 20000
    t = np.arange(n) / fs
    irr = np.vstack([10e-6 * np.sin(2 * np.pi * 45 * t) + 8e-6 * np.cos(2 * np.pi * 90 * t),
                     4e-6 * np.sin(2 * np.pi * 143 * t + 1)])
    model = control_model()
    acc, names = forward_accelerations(model, sensor_table(), 1, irr, fs)
    tr = wheelset1_transfer(model, "vertical", fs)
    est = contact_force(acc[[names.index(c) for c in tr.channels]], 0.0, fs, np.ones(n, bool), [tr]).sample(t)
    # the closed form on the record's own frequency lines (the forward map's), 45/90/143 Hz all inside the band
    fb = np.fft.rfftfreq(n, 1 / fs)[1:]
    m_w, labels = sensor_model(model, sensor_table().iloc[:2].reset_index(drop=True))
    mt = full_vertical_transfer(m_w, fb, channels=labels, track=track_frf(fb, Trackform()),
                                contact_stiffness=ContactParameters().stiffness())
    D = np.moveaxis(mt.dynamic_compliance.data, 2, 0)
    N = np.fft.rfft(irr, axis=1)[:, 1:].T[:, :, None]
    F = np.fft.irfft(np.vstack([np.zeros((1, 2)), np.linalg.solve(D, N)[:, :, 0]]).T, n=n, axis=1)
    inner = (t > 3) & (t < 17)
    for k in range(2):
        err = np.sqrt(np.mean((est[k, inner] - F[k, inner]) ** 2)) / F[k, inner].std()
        assert err < 0.03, (k, err)
    # the flag reads the model's sign: rail L's force dips to -1348 N and peaks at +1676 N; a load 10 % above the
    # dip is never crossed (with the sign turned, the peak would cross it), 10 % below it is, on rail L only
    ti = contact_force(acc[[names.index(c) for c in tr.channels]], 0.0, fs, np.ones(n, bool), [tr])
    dip, peak = -F[0, inner].min(), F[0, inner].max()
    assert peak > 1.2 * dip
    sides = {"L": "L", "R": "R"}
    assert not contact_loss_events(ti, t[inner], 10.0 * t[inner], 1.1 * dip, sides, sides)
    found = contact_loss_events(ti, t[inner], 10.0 * t[inner], 0.9 * dip, sides, sides)
    assert found and {e.channel for e in found} == {"L"}


def test_the_command_says_it_and_the_report_warns(corrugated, tmp_path, capsys):
    """``railmodal field estimate --wheel-load 1.6``: a line on the console, the findings in qc.csv and a warning
    box in the report's quality-control section; no traceback."""
    import pandas as pd

    from railmodal.cli import main
    from receptance import save_model

    save_model(control_model(), tmp_path / "m.npz")
    sensor_table().to_csv(tmp_path / "s.csv", index=False)
    out = tmp_path / "out"
    code = main(["-q", "field", "estimate", "--run", str(corrugated.path), "--sensors", str(tmp_path / "s.csv"),
                 "--model", str(tmp_path / "m.npz"), "--models", "vertical", "--wheel-load", "1.6",
                 "--wheelbase", str(corrugated.wheelbase), "--out", str(out)])
    text = capsys.readouterr()
    assert code == 0, text.err
    assert "contact loss: the wheel leaves the rail on" in text.out and "ACC_W1L_Z" in text.out
    qc = pd.read_csv(out / "qc.csv")
    assert set(qc.loc[qc["kind"] == "contact_loss", "action"]) == {"flagged"}
    assert "The wheel leaves the rail on" in (out / "report.html").read_text()
