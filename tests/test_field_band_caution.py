"""Band indexes that rest on weak ground are flagged: the contact filter's correction and the pinned-pinned resonance.

Oracles: the contact filter's closed form ``H = 2 J₁(κa)/(κa)`` (its correction at the band's shortest wavelength,
and the wavelength where it falls to the correction's cap, solved here independently); the exact pinned-pinned
frequency of the trackform (:func:`receptance.track.pinned_pinned_frequency`) against the band's frequencies
``v/λ`` at the run's speed, inside the inversion band. End to end on a synthetic 2.5 kHz run: the 10-30 mm band,
which holds the pinned-pinned frequency at 10 m/s, is flagged in the index table and in the report; 100-300 mm is
not. (What the flag stands for, measured on the virtual line, is in :mod:`estimator.band_caution`.)
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.special import j1

from estimator.band_caution import CONTACT_CAUTION_DB, band_cautions
from receptance.track import pinned_pinned_frequency
from receptance.trackform import Trackform

A = 5.0e-3  # contact patch semi-axis [m]


def _h(lam_m: float) -> float:
    u = 2 * math.pi / lam_m * A
    return 2 * j1(u) / u


def test_contact_correction_is_the_inverse_of_the_patch_filter():
    mild = band_cautions((30.0, 100.0), np.array([10.0]), (10.0, 400.0), A, [])
    assert mild.contact_correction_db == pytest.approx(-20 * math.log10(_h(0.030)), abs=1e-6)
    assert mild.contact_correction_db < CONTACT_CAUTION_DB and not mild.contact_capped and mild.text == ""
    short = band_cautions((10.0, 30.0), np.array([10.0]), (10.0, 400.0), A, [])
    assert short.contact_capped and short.contact_correction_db == pytest.approx(6.0, abs=1e-9)
    # the cap acts below the wavelength where H first falls to -6 dB
    u_cap = brentq(lambda u: 2 * j1(u) / u - 10 ** (-6 / 20), 1.0, 3.0)
    lam_cap_mm = 2 * math.pi * A / u_cap * 1e3
    assert f"wavelengths under {lam_cap_mm:.0f} mm" in short.text and "+6.0 dB" in short.text
    off = band_cautions((10.0, 30.0), np.array([10.0]), (10.0, 400.0), A, [], contact_filter=False)
    assert off.contact_correction_db == 0.0 and not off.contact_capped and off.text == ""


def test_pinned_pinned_is_flagged_only_in_the_band_that_holds_it_at_the_runs_speed():
    pp = pinned_pinned_frequency(Trackform())
    assert 300.0 < pp < 1000.0
    # 10-30 mm at 10 m/s is 333-1000 Hz
    hit = band_cautions((10.0, 30.0), np.array([9.5, 10.0, np.nan]), (10.0, 1000.0), A, [pp])
    assert hit.pinned_pinned_hz == pytest.approx(pp) and f"({pp:.0f} Hz)" in hit.text
    # the inversion band stops below it (a 1 kHz run), the band lies above it (30 m/s), or the supports are modelled
    assert math.isnan(band_cautions((10.0, 30.0), np.array([10.0]), (10.0, 400.0), A, [pp]).pinned_pinned_hz)
    assert math.isnan(band_cautions((10.0, 30.0), np.array([30.0]), (10.0, 2000.0), A, [pp]).pinned_pinned_hz)
    assert band_cautions((30.0, 100.0), np.array([30.0]), (10.0, 2000.0), A, [pp]).pinned_pinned_hz == \
        pytest.approx(pp)
    assert math.isnan(band_cautions((10.0, 30.0), np.array([10.0]), (10.0, 1000.0), A, [pp],
                                    discrete_supports=True).pinned_pinned_hz)
    # standstill samples say nothing about the band's frequencies
    assert math.isnan(band_cautions((10.0, 30.0), np.array([0.0, np.nan]), (10.0, 1000.0), A, [pp]).pinned_pinned_hz)


def test_a_high_rate_run_flags_the_band_holding_the_pinned_pinned_resonance(tmp_path):
    from estimator import EstimatorConfig, estimate_run, prepare
    from estimator.report import write_report
    from test_estimator_synthetic import control_model, make_run, sensor_table

    sr = make_run(tmp_path, duration_s=30.0, fs=2500.0)
    fm = prepare(control_model(), sensor_table(), config=EstimatorConfig(models=("vertical",), wheelbase_m=sr.wheelbase))
    est = estimate_run(sr.path, fm)
    pp = pinned_pinned_frequency(Trackform())
    run = est.indexes[(est.indexes["stretch"] == "run") & (est.indexes["wheelset"] == est.leading)]
    short = run[run["band_mm"] == "10-30"]
    long_ = run[run["band_mm"] == "100-300"]
    assert (short["valid_share"] > 0).all() and np.allclose(short["pinned_pinned_hz"], pp)
    assert short["caution"].str.contains("pinned-pinned").all() and short["contact_capped"].all()
    assert (long_["caution"] == "").all() and long_["pinned_pinned_hz"].isna().all()
    html = write_report(est, tmp_path / "report.html").read_text()
    # the box of cautions (the report's opening box names corrugated bands too, 100-300 mm among them)
    box = html[html.index("<b>Bands to read with care</b>"):]
    box = box[:box.index("</div>")]
    assert "10-30 mm: " in box and "100-300 mm: " not in box
    assert "1 band(s) to read with care" in html[:html.index("<h2>")]  # and the opening box points to it
