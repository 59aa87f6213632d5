"""FRF files as commercial systems export them (UFF58 function type 4, with or without coherence, ASCII or binary):
written from a virtual-lab campaign's own H1 and read back, they give the same identification; their noise floor
comes from the coherence when the file has it and from the modal fit's residual when it has not.

Oracle: the campaign's H1 estimated from its time histories (ema.estimate_frf), with its coherence-based floor.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import ema
from ema.uff_frf import read_frf_uff, write_frf_uff
from lab_data.cache import campaign_dir
from receptance.diagnosis import Measurement, compare, frf_noise_variance
from receptance.diagnosis.noise import estimate_averages

BAND = (10.0, 500.0)


@pytest.fixture(scope="module")
def lab():
    folder = campaign_dir("rig", fe_export_hz=2000.0)
    out = {}
    for setup in ("flexural", "torsional"):
        table = pd.read_csv(folder / f"{setup}_channels.csv")
        test = ema.read_hammer(folder / f"{setup}.uff", table)
        H = ema.estimate_frf(test, band_hz=BAND, screening=ema.screen_hits(test, band_hz=BAND))
        out[setup] = (H, table, ema.identify(H, band_hz=BAND, setup=setup))
    return folder, out


@pytest.mark.parametrize("binary,coherence,quantity", [(False, True, "accelerance"), (True, False, "accelerance"),
                                                       (True, True, "mobility"), (False, False, "receptance")])
def test_frf_files_give_the_same_identification(lab, tmp_path, binary, coherence, quantity):
    _, setups = lab
    H, table, ident = setups["flexural"]
    path = write_frf_uff(H.as_quantity(quantity), tmp_path / "frf.uff", table, binary=binary, coherence=coherence)
    back = read_frf_uff(path, table)
    assert back.quantity == quantity
    assert back.exp_window_decay == H.exp_window_decay  # the window travels in ID line 3
    assert (back.coherence is not None) == coherence
    back = back.as_quantity("accelerance")
    np.testing.assert_array_equal(back.freqs_hz, H.freqs_hz)
    if binary and quantity == "accelerance":
        # binary 58b holds the doubles themselves: the identification (deterministic) cannot differ
        np.testing.assert_array_equal(back.data, H.data)
        return
    np.testing.assert_allclose(back.data, H.data, rtol=0, atol=1e-10 * np.abs(H.data).max())
    if quantity != "accelerance" or not coherence:
        return
    # ASCII holds 12 significant digits: the identification is the same to far below its own uncertainty
    again = ema.identify(back, band_hz=BAND, setup="flexural")
    assert len(again.modes) == len(ident.modes)
    np.testing.assert_allclose(again.modes.freqs_hz, ident.modes.freqs_hz, rtol=1e-9)
    np.testing.assert_allclose(again.modes.zeta, ident.modes.zeta, rtol=1e-6)


def test_noise_floor_without_coherence_is_estimated_from_the_modal_fit(lab):
    """Per setup, the floor from the residual of the identification's modal fit is within 10 % of the floor the
    coherence and the number of averaged hits give (measured: 1-4 % above), and the line-to-line roughness
    estimate (no synthesis) within 20 % (measured 7-12 % below)."""
    _, setups = lab
    from receptance.diagnosis.compare import h1_variance

    for setup, (H, table, ident) in setups.items():
        true_var = h1_variance(H)
        bare = H.with_history("coherence dropped", coherence=None, n_averages=None)
        var, method = frf_noise_variance(bare, ident.synthesis)
        assert "modal fit" in method
        floors = [_floor(bare, v) for v in (true_var, var, frf_noise_variance(bare)[0])]
        assert floors[1] == pytest.approx(floors[0], rel=0.10), setup
        assert floors[2] == pytest.approx(floors[0], rel=0.20), setup
        # with coherence but no count of averages, the count is estimated from the coherence and the modal fit
        n = estimate_averages(H.with_history("no count", n_averages=None), ident.synthesis)
        assert np.median(n) == pytest.approx(np.median(H.n_averages), abs=1)


def _floor(H, var) -> float:
    """Noise floor of E over channel x octave bands (receptance.diagnosis.compare's definition)."""
    edges = (10, 20, 40, 80, 160, 320, 500)
    f, Hx = H.freqs_hz, H.data[:, 0]
    cells = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        sel = (f >= lo) & ((f <= hi) if hi == 500 else (f < hi))
        cells.append(var[:, sel].sum(axis=1) / np.sum(np.abs(Hx[:, sel]) ** 2, axis=1))
    return float(np.sqrt(np.mean(cells)))


def test_compare_uses_the_noise_estimate_of_an_frf_without_coherence(lab):
    """The comparison takes a Measurement's own noise estimate when the FRF carries no coherence: same E, and a
    floor within 10 % of the coherence floor; without any estimate the floor is unknown (NaN)."""
    _, setups = lab
    H, table, ident = setups["flexural"]
    bare = H.with_history("coherence dropped", coherence=None, n_averages=None)
    var, method = frf_noise_variance(bare, ident.synthesis)
    with_coh = Measurement(H, table, "flexural")
    without = Measurement(bare, table, "flexural", noise_variance=var, noise_method=method)
    assert without.noise_method == method and "coherence" in with_coh.noise_method
    model = {"flexural": ident.synthesis}  # the measurement's own modal fit as "the model"
    a, b = compare(model, [with_coh], band_hz=BAND), compare(model, [without], band_hz=BAND)
    assert b.summary == pytest.approx(a.summary, rel=1e-12)
    assert b.noise_floor == pytest.approx(a.noise_floor, rel=0.10)
    assert np.isnan(compare(model, [("flexural", bare, table)], band_hz=BAND).noise_floor)
    with pytest.raises(ValueError):
        frf_noise_variance(bare, ident.synthesis.select(outputs=list(bare.outputs[:3])))


def test_lab_identify_reads_an_frf_file_in_place_of_the_hammer_test(lab, tmp_path, capsys):
    """``railmodal lab identify --frf``: the exported FRFs (binary, no coherence) give the modes the hammer test
    gives, and nothing is screened (no screening.csv)."""
    from ema.modes_io import read_modeset
    from railmodal.cli import main

    folder, setups = lab
    H, table, ident = setups["flexural"]
    path = write_frf_uff(H, tmp_path / "flexural_frf.uff", table, binary=True, coherence=False)
    out = tmp_path / "modes"
    assert main(["-q", "lab", "identify", "--frf", str(path), "--channels", str(folder / "flexural_channels.csv"),
                 "--out", str(out)]) == 0
    modes = read_modeset(out)
    np.testing.assert_allclose(modes.freqs_hz, ident.modes.freqs_hz, rtol=1e-9)
    assert not (out / "screening.csv").exists()
    assert f"{len(ident.modes)} modes identified in 'flexural'" in capsys.readouterr().out
