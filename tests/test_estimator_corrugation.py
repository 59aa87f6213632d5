"""Corrugation type: dominant wavelength, the model's resonances, the mechanism named (thesis Table 1.1).

Oracles: a narrow-band profile of known wavelength; the virtual lab's truth mode labels (first and second
torsion of the control wheelset); the exact Timoshenko pinned–pinned frequency; eq. 1.1 λ = v/f.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from estimator.corrugation import (MIN_PROMINENCE_DB, Resonances, classify, dominant_wavelength, model_resonances,
                                  spectral_peak)
from lab_data.cache import campaign_dir
from receptance import ContactParameters, Trackform
from receptance.track import pinned_pinned_frequency
from test_estimator_synthetic import control_model


def test_dominant_wavelength_of_a_corrugation():
    dx = 2.5e-3
    x = np.arange(0, 60, dx)
    rng = np.random.default_rng(0)
    p = 15e-6 * np.sin(2 * np.pi * x / 0.163) + 2e-6 * rng.standard_normal(x.size)
    assert dominant_wavelength(p, dx, (100.0, 300.0)) == pytest.approx(0.163, rel=0.01)
    p[1000:1100] = np.nan  # masked samples only remove their segments
    assert dominant_wavelength(p, dx, (100.0, 300.0)) == pytest.approx(0.163, rel=0.01)


def test_a_corrugation_stands_out_of_broadband_roughness_and_broadband_alone_does_not():
    """Rail roughness rising with wavelength (level ∝ λ², like ISO 3095's limit) puts the largest line of a band at
    its longest wavelength; the trend divided out, a 160 mm corrugation with a third of the band's energy is
    found with a prominence above 9 dB, and the broadband profile alone shows no peak above 6 dB."""
    dx = 2.5e-3
    x = np.arange(0, 150, dx)
    rng = np.random.default_rng(3)
    X = np.fft.rfft(rng.standard_normal(x.size))
    k = np.fft.rfftfreq(x.size, dx)
    X[1:] /= k[1:]  # amplitude ∝ λ: level ∝ λ²
    X[0] = 0
    bb = np.fft.irfft(X, x.size)
    band = (100.0, 300.0)
    from estimator.standards.en13231 import band_filter

    bb *= 10e-6 / band_filter(bb[None, :], dx, band)[0].std()
    lam_b, prom_b = spectral_peak(bb, dx, band)
    assert prom_b < MIN_PROMINENCE_DB
    corr = bb + 10e-6 * np.sin(2 * np.pi * x / 0.16)  # RMS 7 um against the band's 10 um
    lam, prom = spectral_peak(corr, dx, band)
    assert lam == pytest.approx(0.16, rel=0.01) and prom > MIN_PROMINENCE_DB + 3
    assert dominant_wavelength(corr, dx, band) == lam


def test_model_resonances_match_the_lab_truth_and_the_track():
    res = model_resonances(control_model(), Trackform(), ContactParameters().stiffness())
    truth = json.loads((campaign_dir("control") / "truth.json").read_text())
    tors = [d["f_hz"] for d in truth["design_modes"] if "torsion" in d["description"]]
    assert res.torsion_hz == pytest.approx(tors[:2], rel=0.01)  # 1st and 2nd torsion (rutting: 2nd)
    assert res.pinned_pinned_hz == pytest.approx(pinned_pinned_frequency(Trackform()))
    # P2: the unsprung wheel bouncing on the track's contact stiffness, thesis Table 1.1's 50-100 Hz range
    assert 30 < res.p2_hz < 110


def test_classification_follows_eq_1_1():
    res = Resonances(p2_hz=60.0, torsion_hz=(75.0, 270.0), pinned_pinned_hz=650.0)
    v = 9.0
    assert classify(v / 0.15, res)[0] == "P2 resonance"  # 60 Hz
    assert classify(v / 0.033, res)[0] == "second wheelset torsion (rutting)"  # 273 Hz
    assert classify(v / 0.014, res)[0] == "pinned-pinned resonance"  # 643 Hz
    name, nearest, f = classify(v / 0.05, res)  # 180 Hz: nothing within 20 %
    assert name.startswith("none within") and nearest == "second wheelset torsion (rutting)" and f == 270.0
