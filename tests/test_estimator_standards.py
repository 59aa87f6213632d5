"""EN 13231-3 band indexes, EN 15610 spectra, ISO 3095 limit and the contact filter against closed forms.

Oracles: scipy's Butterworth ``sosfiltfilt`` for the zero-phase band filter; a sinusoid's RMS and
peak-to-peak (eq. 4.1 with the square: 2√2 RMS = 2 A); a sinusoid's one-third-octave level
20 lg(A/√2 / 1 µm); 2 J1(ka)/(ka) for the contact filter (independent numerical averaging).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import signal

from estimator.contact_filter import contact_filter_response, undo_contact_filter
from estimator.standards import band_filter, band_indexes, exceedance, iso3095_limit_db, moving_rms, pk_pk
from estimator.standards.en13231 import BUTTERWORTH_ORDER, band_response
from estimator.standards.en15610 import nominal_wavelength, roughness_spectrum, third_octave_bands


def test_band_filter_is_zero_phase_butterworth_minus_3db_at_the_edges():
    dx = 1e-3
    x = np.arange(0, 60, dx)
    rng = np.random.default_rng(1)
    p = rng.standard_normal(x.size) * 1e-6
    band = (30.0, 100.0)
    z = band_filter(p, dx, band)
    # oracle: scipy's Butterworth sections applied forward and backward, cut-offs moved so that the
    # zero-phase (squared) response is -3 dB at the band edges
    q = (math.sqrt(2) - 1) ** (1 / (2 * BUTTERWORTH_ORDER))
    fs = 1 / dx
    hp = signal.butter(BUTTERWORTH_ORDER, 1e3 / band[1] * q, "highpass", fs=fs, output="sos")
    lp = signal.butter(BUTTERWORTH_ORDER, 1e3 / band[0] / q, "lowpass", fs=fs, output="sos")
    ref = signal.sosfiltfilt(lp, signal.sosfiltfilt(hp, p))
    mid = slice(10000, -10000)  # away from both implementations' end effects
    assert np.max(np.abs(z[mid] - ref[mid])) < 0.02 * np.std(ref[mid])
    assert band_response(np.array([1e3 / 100, 1e3 / 30]), band) == pytest.approx([1 / math.sqrt(2)] * 2, rel=1e-4)
    assert band_response(np.array([1e3 / 55]), band)[0] == pytest.approx(1.0, abs=0.01)


def test_sinusoid_gives_its_peak_to_peak_in_its_band_only():
    dx = 2e-3
    x = np.arange(0, 80, dx)
    A, lam = 20e-6, 0.060
    p = A * np.sin(2 * np.pi * x / lam)
    idx = band_indexes(p[None, :], dx, [(30.0, 100.0), (100.0, 300.0)], [0.5, 1.5])
    inside = idx.pk_pk[0, 0, 5000:-5000]
    assert np.nanmean(inside) == pytest.approx(2 * A, rel=0.01)  # eq. 4.1 with the square: 2√2 · A/√2
    assert np.nanmax(idx.pk_pk[1, 0, 5000:-5000]) < 0.05 * 2 * A  # next band: the 4th-order skirt, -28 dB
    # window edges are not estimated
    assert np.isnan(idx.rms[0, 0, :10]).all()


def test_moving_rms_of_a_sinusoid_and_masked_windows():
    dx = 1e-3
    x = np.arange(0, 10, dx)
    z = 3.0 * np.sin(2 * np.pi * x / 0.1)
    r = moving_rms(z, dx, 0.5)  # 5 whole periods
    assert np.nanmax(np.abs(r - 3 / math.sqrt(2))) < 2e-3 * 3 / math.sqrt(2)  # 501 samples: 5 periods + 1
    z[4000] = np.nan
    r = moving_rms(z, dx, 0.5)
    assert np.isnan(r[4000 - 250:4000 + 250]).all() and np.isfinite(r[4000 + 260])
    assert pk_pk(np.array([1.0])) == pytest.approx([2 * math.sqrt(2)])
    assert exceedance(np.array([1.0, 3.0, np.nan, 5.0]), 2.0) == pytest.approx(100 * 2 / 3)


def test_en15610_level_of_a_sinusoid_and_the_reporting_rules():
    dx = 1e-3
    x = np.arange(0, 40, dx)
    A = 10e-6
    lam = 1 / 10 ** (15 / 10)  # band 15: centre 31.6 /m, nominal 31.5 mm
    spec = roughness_spectrum(A * np.sin(2 * np.pi * x / lam), dx, segment_m=2.0)
    k = list(spec.bands).index(15)
    assert nominal_wavelength(15) == 0.0315
    assert spec.level_db[k] == pytest.approx(20 * math.log10(A / math.sqrt(2) / 1e-6), abs=0.1)
    assert spec.level_db[k - 3] < spec.level_db[k] - 25 and spec.level_db[k + 3] < spec.level_db[k] - 25
    # quarter-length rule: a 2 m segment reports to 0.5 m, not beyond
    assert np.isnan(spec.level_db[spec.wavelength_m > 0.5]).all() and np.isfinite(spec.level_db[0])
    # a run that resolves only 40-200 mm reports only those bands
    spec2 = roughness_spectrum(A * np.sin(2 * np.pi * x / lam), dx, segment_m=2.0, resolved_m=(0.04, 0.2))
    ok = np.isfinite(spec2.level_db)
    assert (spec2.wavelength_m[ok] >= 0.04).all() and (spec2.wavelength_m[ok] <= 0.2).all()
    assert np.isnan(spec2.level_db[k])
    # a masked sample removes only the segments holding it
    p = A * np.sin(2 * np.pi * x / lam)
    p[20000] = np.nan
    assert roughness_spectrum(p, dx).n_segments == spec.n_segments - 2
    assert third_octave_bands(0.5, 0.00315)[0] == 3 and iso3095_limit_db([0.1, 0.0315, 2.0])[:2].tolist() == [4.9, -5.0]


def test_contact_filter_is_the_hertz_pressure_average_and_its_correction_inverts_it():
    a = 5.6e-3
    # independent oracle: average a sinusoid over the contact with the weight sqrt(1 - (s/a)^2)
    s = np.linspace(-a, a, 20001)
    w = np.sqrt(np.clip(1 - (s / a) ** 2, 0, None))
    for lam in (0.02, 0.05, 0.2):
        oracle = np.sum(w * np.cos(2 * np.pi * s / lam)) / np.sum(w)
        assert contact_filter_response(1 / lam, a) == pytest.approx(oracle, rel=1e-4)
    dx = 1e-3
    x = np.arange(0, 20, dx)
    lam = 0.04
    true = 5e-6 * np.sin(2 * np.pi * x / lam)
    felt = true * contact_filter_response(1 / lam, a)
    back = undo_contact_filter(felt, dx, a)
    assert np.max(np.abs(back[2000:-2000] - true[2000:-2000])) < 0.01 * 5e-6
    # beyond the 6 dB cap the gain stays at 2 (nothing wiped out is invented)
    lam = 0.008
    felt = 1e-6 * np.sin(2 * np.pi * x / lam)
    assert np.std(undo_contact_filter(felt, dx, a)[2000:-2000]) == pytest.approx(2 * np.std(felt), rel=0.02)


def test_band_indexes_do_not_depend_on_the_sampling_step():
    """The decimated band computation gives the same pk-pk at 1 mm and 2.5 mm (a strong line just outside)."""
    out = []
    for dx in (1e-3, 2.5e-3):
        x = np.arange(0, 200, dx)
        p = 20e-6 * np.sin(2 * np.pi * x / 0.06) + 2e-6 * np.sin(2 * np.pi * x / 0.2 + 1)
        bi = band_indexes(p[None], dx, [(100.0, 300.0), (30.0, 100.0)], [1.5, 0.5])
        out.append([np.nanmedian(bi.pk_pk[b, 0]) for b in range(2)])
    np.testing.assert_allclose(out[0], out[1], rtol=0.01)


def test_a_reference_is_not_interpolated_across_a_stretch_it_did_not_measure(caplog):
    """A trolley record (1 mm step, 60 µm sine of 60 mm wavelength on rail L) lacks 20 m in its middle: the
    30-100 mm band peak-to-peak is NaN inside the gap, not the ~0 of a straight line drawn across it, and equals
    the sine's 2·60 µm outside; a rail of 5 samples is left out with a WARNING naming it."""
    import logging

    import pandas as pd

    from estimator.reference import reference_indexes

    x = np.arange(0.0, 100.0, 0.001)
    keep = (x < 40.0) | (x >= 60.0)
    r = 60e-6 * np.sin(2 * np.pi * x / 0.060)
    table = pd.concat([pd.DataFrame({"chainage_m": x[keep], "rail": "L", "roughness_m": r[keep]}),
                       pd.DataFrame({"chainage_m": np.arange(5.0), "rail": "R", "roughness_m": 0.0})])
    with caplog.at_level(logging.WARNING, logger="estimator"):
        ref = reference_indexes(table, source="trolley.csv")
    assert "trolley.csv: rail R has 5 sample(s) (< 10): not compared" in caplog.text and set(ref.x) == {"L"}
    xg, pk = ref.pk_pk((30, 100), "L")
    assert np.isnan(pk[(xg > 45) & (xg < 55)]).all()
    np.testing.assert_allclose(pk[(xg > 10) & (xg < 30)], 120e-6, rtol=0.05)
    np.testing.assert_allclose(pk[(xg > 70) & (xg < 90)], 120e-6, rtol=0.05)
