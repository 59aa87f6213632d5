"""``railmodal model track`` and ``railmodal model build`` on the virtual lab's files."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from railmodal.cli import main
from receptance.model_io import load_model
from receptance.track import track_receptance
from receptance.trackform import Trackform, trackform_to_dict
from test_hybrid_model import truth_pairing


def test_model_track_writes_the_receptance_table_and_plot(tmp_path, capsys):
    assert main(["-q", "model", "track", "--out", str(tmp_path)]) == 0
    df = pd.read_csv(tmp_path / "track_receptance.csv")
    assert list(df.columns) == ["f_hz", "vertical_re", "vertical_im", "lateral_re", "lateral_im"]
    assert df["f_hz"].iloc[0] == 1.0 and df["f_hz"].iloc[-1] == 2000.0 and len(df) == 2000
    f = df["f_hz"].to_numpy()
    np.testing.assert_allclose(df["vertical_re"] + 1j * df["vertical_im"], track_receptance(f, Trackform(), "vertical"),
                               rtol=1e-8)
    np.testing.assert_allclose(df["lateral_re"] + 1j * df["lateral_im"], track_receptance(f, Trackform(), "lateral"),
                               rtol=1e-8)
    assert (tmp_path / "track_receptance.png").stat().st_size > 10_000
    # a user's trackform: a pad twice as stiff raises the vertical resonance
    params = dict(trackform_to_dict(Trackform()), pad_stiffness_z=2 * Trackform().pad_stiffness_z)
    (tmp_path / "stiff.toml").write_text("".join(f"{k} = {float(v)!r}\n" for k, v in params.items()))
    out = tmp_path / "stiff"
    code = main(["-q", "model", "track", "--trackform", str(tmp_path / "stiff.toml"), "--out", str(out)])
    if code != 0:
        pytest.fail(capsys.readouterr().err)
    stiff = pd.read_csv(out / "track_receptance.csv")
    band = (f > 60) & (f < 400)
    assert f[band][np.argmax(np.abs(stiff["vertical_re"] + 1j * stiff["vertical_im"])[band])] > \
        f[band][np.argmax(np.abs(df["vertical_re"] + 1j * df["vertical_im"])[band])]


def test_model_track_refuses_a_bad_trackform(tmp_path, capsys):
    params = dict(trackform_to_dict(Trackform()), pad_stiffness_z=-1.0)
    (tmp_path / "bad.toml").write_text("".join(f"{k} = {float(v)!r}\n" for k, v in params.items()))
    assert main(["-q", "model", "track", "--trackform", str(tmp_path / "bad.toml"), "--out", str(tmp_path)]) == 1
    assert "pad_stiffness_z" in capsys.readouterr().err


def test_model_build_saves_an_in_service_model_and_its_plots(tmp_path, control_dir, control_manifest, capsys):
    pairing = tmp_path / "pair"
    pairing.mkdir()
    truth_pairing(control_manifest).to_csv(pairing / "pairing.csv", index=False)
    out = tmp_path / "model"
    code = main(["-q", "model", "build", "--pairing", str(pairing), "--fem", str(control_dir / "fe_design.uff"),
                 "--points", str(control_dir / "points.csv"), "--hammer", str(control_dir / "flexural.uff"),
                 "--channels", str(control_dir / "flexural_channels.csv"), "--theta", "3", "-40",
                 "--robustness-models", "20", "--out", str(out)])
    text = capsys.readouterr()
    assert code == 0, text.err
    model = load_model(out / "hybrid_model.npz")
    assert [m.kind for m in model.modifications] == ["primary_suspension"]
    modes = pd.read_csv(out / "system_modes.csv")
    assert modes["f_hz"].iloc[0] == pytest.approx(6.43, abs=0.02)
    assert modes["f_hz"].iloc[1] == pytest.approx(9.00, abs=0.02)
    validation = pd.read_csv(out / "validation_flexural.csv")
    assert len(validation) == 29 and validation["rel_error"].max() < 0.01
    figures = ["fig4_1_half_receptances.png", "fig4_2_transfer_half.png", "fig4_3_transfer_vertical.png",
               "fig4_4_transfer_vertical_lateral.png", "fig4_5_spectral_std_half.png",
               "fig4_6_spectral_std_vertical.png", "fig4_7_spectral_std_vertical_lateral.png"]
    for name in ["receptances.png", "validation_flexural_worst.png", "validation_flexural_errors.png", *figures]:
        assert (out / name).stat().st_size > 10_000
    assert "6.4" in text.out


def test_model_build_names_a_missing_pairing(tmp_path, control_dir, capsys):
    code = main(["-q", "model", "build", "--pairing", str(tmp_path), "--fem", str(control_dir / "fe_design.uff"),
                 "--points", str(control_dir / "points.csv"), "--out", str(tmp_path / "o")])
    assert code == 1
    assert "lab pair" in capsys.readouterr().err
