"""The diagnosis band: the octave cells of the misfit, its noise floor and every fit follow the band the user gives.

Oracles: the comparison stage (``compare``, an independent implementation of ``E`` and its floor) on the same band;
the cells' edges, which follow from the band alone (octaves from its lower edge); the FRF's resolution (an octave
cell needs ``MIN_CELL_LINES`` lines, so the lowest usable lower edge is that many line spacings); and the physics of
the virtual lab's hidden absorber (6 kg tuned to ~195 Hz): a band that stops well below its resonance does not see
it, a band around it does.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from receptance.diagnosis import DiagnosisError, compare, diagnose, fit_effect, misfit
from receptance.diagnosis.effects import MassLoading
from receptance.diagnosis.misfit import MIN_CELL_LINES, OCTAVES, check_band_lines, octave_edges, sixth_octaves
from test_diagnose import _campaign


@pytest.fixture(scope="module")
def absorber():
    return _campaign("absorber")


def _cells(m):
    return sorted(set(zip(m.per_band["band_lo_hz"], m.per_band["band_hi_hz"])))


def test_octave_edges_follow_the_band():
    assert OCTAVES == octave_edges((10.0, 500.0)) == (10.0, 20.0, 40.0, 80.0, 160.0, 320.0, 500.0)
    assert octave_edges((4.0, 500.0)) == (4.0, 8.0, 16.0, 32.0, 64.0, 128.0, 256.0, 500.0)
    # a top cell narrower than half an octave joins the one below (as compare.octave_bands does)
    assert octave_edges((20.0, 170.0)) == (20.0, 40.0, 80.0, 170.0)
    with pytest.raises(DiagnosisError, match="0 < low < high"):
        octave_edges((0.0, 500.0))


def test_band_is_checked_against_the_lines_and_their_resolution():
    f = np.arange(1, 2001) * 0.25  # a 4 s record: 0.25 Hz lines up to 500 Hz
    assert check_band_lines((4.0, 500.0), f) == octave_edges((4.0, 500.0))
    # the lowest octave 0.5-1 Hz holds 2 lines: refused, naming the cell and the lowest usable edge (4 x 0.25 Hz)
    with pytest.raises(DiagnosisError, match=r"0\.5–1 Hz .* holds 2 line.*at least 1 Hz"):
        check_band_lines((0.5, 500.0), f, "setup 'flexural'")
    with pytest.raises(DiagnosisError, match=r"setup 'x'.*outside the measured lines 0\.25–500 Hz"):
        check_band_lines((10.0, 800.0), f, "setup 'x'")
    assert MIN_CELL_LINES * 0.25 == 1.0
    # sixth-octave cells narrower than two lines near a low edge join the next one: every line counts once
    cells = sixth_octaves(f, octave_edges((2.0, 500.0)))
    assert cells[0][0] == 2.0 and cells[-1][1] == pytest.approx(500.0)
    assert all(np.count_nonzero((f >= a) & (f < b)) >= 2 for a, b in cells)
    assert all(b0 == pytest.approx(a1) for (_, b0), (a1, _) in zip(cells[:-1], cells[1:]))


def test_misfit_cells_cover_the_band_and_agree_with_compare(absorber):
    model, meas, _ = absorber
    n_ch = sum(m.frf.n_out for m in meas)
    full = misfit(model, meas)
    assert _cells(full) == list(zip(OCTAVES[:-1], OCTAVES[1:])) and full.n_bands == 6 * n_ch
    for band in ((10.0, 160.0), (160.0, 320.0), (20.0, 500.0)):
        m = misfit(model, meas, band_hz=band)
        edges = octave_edges(band)
        assert _cells(m) == list(zip(edges[:-1], edges[1:]))
        assert m.n_bands == (len(edges) - 1) * n_ch
        f = meas[0].frf.freqs_hz
        assert m.n_fine == sum(m_.frf.n_out for m_ in meas) * len(sixth_octaves(f, edges))
        # the comparison stage on the same band is the same figure (they differ only in whether the line at the
        # band's top edge counts: ~1e-4)
        c = compare(model, meas, band_hz=band)
        assert m.summary == pytest.approx(c.summary, rel=1e-3)
        assert m.noise_floor == pytest.approx(c.noise_floor, rel=1e-3)
    # the absorber (~195 Hz) is invisible well below its resonance and dominates the octave around it
    below, around = misfit(model, meas, band_hz=(10.0, 160.0)), misfit(model, meas, band_hz=(160.0, 320.0))
    assert below.summary < 1.5 * below.noise_floor
    assert around.summary > 5 * around.noise_floor
    assert below.summary < full.summary < around.summary
    # a band outside the measured lines (10-500 Hz) is refused, naming the setup
    with pytest.raises(DiagnosisError, match="setup 'flexural'.*outside the measured lines"):
        misfit(model, meas, band_hz=(4.0, 500.0))


def test_fits_and_diagnosis_score_on_the_band(absorber):
    model, meas, _ = absorber
    band = (10.0, 160.0)
    fit = fit_effect(MassLoading(), model, meas, band_hz=band)
    assert fit.error_before == pytest.approx(misfit(model, meas, band_hz=band).summary)
    assert set(fit.fixes["band_lo_hz"]) == {10.0, 20.0, 40.0, 80.0}
    result = diagnose(model, meas, max_effects=0, band_hz=band)
    assert result.band_hz == band and result.to_json()["band_hz"] == list(band)
    assert result.initial.summary == pytest.approx(fit.error_before)
    assert "10-160 Hz" in result.to_json()["criterion"]
    with pytest.raises(DiagnosisError, match="outside the measured lines"):
        diagnose(model, meas, max_effects=0, band_hz=(10.0, 1000.0))


@pytest.mark.slow
def test_a_band_from_4_hz_finds_the_bearings_and_the_slings_of_a_suspended_rig():
    """'bearing_sling_rig' on the design office's beam FE: compliant bearings and crane slings around the axle body
    (y = ±0.52 m, not given). On 10-500 Hz the slings' trace is too small to pass the criterion (their bounce and
    roll modes lie at 2-4 Hz); a band from 4 Hz (16 lines in its lowest octave at the 0.25 Hz resolution) holds
    their tails, and the diagnosis finds both effects one after the other, with the slings' stiffness and
    position, down to the noise floor."""
    import json

    import fem_import
    from ema import estimate_frf, read_hammer
    from lab_data.cache import campaign_dir
    from receptance.diagnosis import Measurement
    from receptance.dofs import read_points
    from receptance.hybrid import hybrid_model
    from test_hybrid_model import truth_pairing

    band = (4.0, 500.0)
    folder = campaign_dir("bearing_sling_rig", fe_export_hz=2000.0, fe_style="beam")
    manifest = json.loads((folder / "truth.json").read_text())
    fe = fem_import.read(folder / "fe_design.uff")
    model = hybrid_model(fe, truth_pairing(manifest, "flexural", fe=fe, folder=folder),
                         points=read_points(folder / "points.csv"), keep_fe="all", max_hz=band[1])
    meas = [Measurement(estimate_frf(read_hammer(folder / f"{s}.uff", folder / f"{s}_channels.csv"), band_hz=band),
                        pd.read_csv(folder / f"{s}_channels.csv"), s) for s in ("flexural", "torsional")]
    result = diagnose(model, meas, max_effects=2, band_hz=band)
    assert [f.name for f in result.accepted] == ["axlebox_bearing", "rig_suspension"]
    bearing, rig = result.accepted
    truth = manifest["scenario"]["effects"]
    for name in ("radial_N_per_m", "axial_N_per_m", "rocking_Nm_per_rad", "right_over_left"):
        assert bearing.params[name] == pytest.approx(truth["bearing"][name], rel=0.25), name
    assert rig.params["vertical_N_per_m"] == pytest.approx(truth["rig"]["vertical_N_per_m"], rel=0.25)
    assert rig.params["hanging_y_m"] == pytest.approx(abs(truth["rig"]["y_m"][1]), rel=0.25)
    assert rig.n_fitted == 3  # the position is a fitted number too
    assert rig.reduction > 0.25 and rig.delta_bic < -100
    assert result.final.summary < 1.2 * result.final.noise_floor
    assert set(result.final.per_band["band_lo_hz"]) == set(octave_edges(band)[:-1])


def test_lab_diagnose_refuses_a_band_the_fe_or_the_records_cannot_support(tmp_path, capsys):
    """Before any identification: a band whose top octave lies above the FE export's highest mode (the model
    would have no mode there), a band whose lowest octave the 4 s records resolve with 2 lines, a lower edge of 0."""
    from lab_data.cache import campaign_dir
    from railmodal.cli import main

    folder = campaign_dir("rig", fe_export_hz=2000.0)
    base = ["lab", "diagnose", "--hammer", str(folder / "flexural.uff"), "--channels",
            str(folder / "flexural_channels.csv"), "--fem", str(folder / "fe_design.uff"), "--points",
            str(folder / "points.csv"), "--out", str(tmp_path / "out")]
    assert main(["-q", *base, "--band", "10", "5000"]) == 1
    err = capsys.readouterr().err
    assert "fe_design.uff" in err and "top octave 2560–5000 Hz" in err
    assert main(["-q", *base, "--band", "0.5", "500"]) == 1
    err = capsys.readouterr().err
    assert "setup 'flexural'" in err and "0.5–1 Hz" in err and "at least 1 Hz" in err
    with pytest.raises(SystemExit) as exc:
        main([*base, "--band", "0", "500"])
    assert exc.value.code == 2 and "--band" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
