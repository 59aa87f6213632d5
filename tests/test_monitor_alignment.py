"""Alignment of runs along chainage against synthetic oracles: known offsets, scales, breaks, welds, no match.

The oracle is a broadband rail profile on a 1 mm grid (the "truth"); a run
reads it at ``T(x)`` — the true chainage of the point the run places at
``x`` — plus measurement noise; the alignment must return ``x + δ(x) = T(x)``.
"""

from __future__ import annotations

import numpy as np
import pytest

from estimator.monitoring.alignment import (Alignment, ShiftFit, align_profiles, align_to_line, compose,
                                            feature_profile, fit_shift, knots_for)
from estimator.monitoring.config import MonitoringConfig

CFG = MonitoringConfig()
DX = 1e-3


@pytest.fixture(scope="module")
def rails():
    """Two independent broadband rails (wavelengths 10 mm – 2 m, 10 µm RMS) on 0–600 m."""
    rng = np.random.default_rng(1)
    X = np.arange(0, 600, DX)
    k = np.fft.rfftfreq(X.size, DX)
    S = np.zeros(k.size)
    sel = (k > 0.5) & (k < 100)
    S[sel] = k[sel] ** -1.5
    R = np.stack([np.fft.irfft((rng.standard_normal(k.size) + 1j * rng.standard_normal(k.size)) * np.sqrt(S), X.size)
                  for _ in range(2)])
    return X, 10e-6 * R / R.std(axis=1, keepdims=True)


def read(rails, true_of_x, x, noise, seed=2):
    X, R = rails
    rng = np.random.default_rng(seed)
    return np.stack([np.interp(true_of_x(x), X, r) for r in R]) + noise * rng.standard_normal((2, x.size))


def reference(rails):
    xr = np.arange(100, 500, 0.0025)
    return feature_profile(xr, read(rails, lambda x: x, xr, 1e-6, seed=3), "LR", CFG.align_band_mm)


def test_offset_and_half_percent_scale_are_recovered_to_a_fraction_of_a_millimetre(rails):
    ref = reference(rails)
    xs = np.arange(120, 480, 0.00247)  # another run's grid (its own wheel circumference)
    T = lambda x: 300 + (x - 300) * 1.005 + 1.7  # noqa: E731 - 0.5 % odometer scale, 1.7 m offset
    run = feature_profile(xs, read(rails, T, xs, 2e-6), "LR", CFG.align_band_mm)
    st = align_profiles(run, ref, CFG)
    assert st.accepted, st.reason
    inner = (xs > 140) & (xs < 460)
    err = xs + st.fit.shift(xs) - T(xs)
    assert np.sqrt(np.mean(err[inner] ** 2)) < 0.5e-3
    assert st.residual_mm < 1.0
    sc = st.fit.pieces()["scale"].to_numpy()
    np.testing.assert_allclose(sc, 1.005, atol=2e-5)


def test_a_scale_change_at_a_balise_is_a_knot_of_the_piecewise_fit(rails):
    ref = reference(rails)
    xs = np.arange(120, 480, 0.0025)
    # odometer reset at the balise at 300 m: different scale errors before and after, continuous chainage
    T = lambda x: np.where(x < 300, 300 + (x - 300) * 0.996, 300 + (x - 300) * 1.004) + 0.8  # noqa: E731
    run = feature_profile(xs, read(rails, T, xs, 2e-6), "LR", CFG.align_band_mm)
    st = align_profiles(run, ref, CFG, breakpoints=[300.0])
    assert st.accepted, st.reason
    p = st.fit.pieces()
    assert np.any(np.isclose(p["from_m"], 300.0, atol=0.01))
    np.testing.assert_allclose(p.loc[p["to_m"] <= 300.01, "scale"], 0.996, atol=3e-5)
    np.testing.assert_allclose(p.loc[p["from_m"] >= 299.99, "scale"], 1.004, atol=3e-5)
    err = xs + st.fit.shift(xs) - T(xs)
    assert np.sqrt(np.mean(err[(xs > 140) & (xs < 460)] ** 2)) < 0.5e-3


def test_a_run_of_another_track_is_rejected_with_the_reason(rails):
    ref = reference(rails)
    xs = np.arange(120, 480, 0.0025)
    rng = np.random.default_rng(9)
    other = rng.standard_normal((2, xs.size)) * 5e-6  # white noise: nothing in common with the reference
    st = align_profiles(feature_profile(xs, other, "LR", CFG.align_band_mm), ref, CFG)
    assert not st.accepted
    assert "correlate" in st.reason and f"{CFG.align_min_correlation:g}" in st.reason


def test_a_run_outside_the_reference_is_rejected(rails):
    ref = reference(rails)
    xs = np.arange(520, 590, 0.0025)
    st = align_profiles(feature_profile(xs, read(rails, lambda x: x, xs, 1e-6), "LR", CFG.align_band_mm), ref, CFG)
    assert not st.accepted and "share no stretch" in st.reason


class _Line:
    """A line description's parts the alignment uses: welds (per rail) in ``raw``, balises."""

    def __init__(self, welds, balises=()):
        self.raw = {"welds": [{"chainage_m": c, "rail": r} for c, r in welds]}
        self.welds = tuple(c for c, _ in welds)
        self.balises = tuple(("B", b) for b in balises)


def test_weld_dips_anchor_the_absolute_chainage(rails):
    """Welds (cosine dips of 0.5–0.9 m, 50–150 µm, staggered on the rails) at known chainages; the run is off by
    0.43 m: the weld template brings it back to within a few millimetres."""
    X, R = rails
    rng = np.random.default_rng(5)
    welds = []
    R2 = R.copy()
    for k, c in enumerate(np.arange(105.0, 495.0, 18.0)):
        rail = "LR"[k % 2]
        L, d = rng.uniform(0.5, 0.9), rng.uniform(50e-6, 150e-6)
        u = (X - c) / L
        R2["LR".index(rail)] += np.where(np.abs(u) < 0.5, -d * 0.5 * (1 + np.cos(2 * np.pi * u)), 0.0)
        welds.append((float(c), rail))
    xs = np.arange(120, 480, 0.0025)
    T = lambda x: x + 0.43  # noqa: E731
    prof = np.stack([np.interp(T(xs), X, r) for r in R2]) + 1e-6 * rng.standard_normal((2, xs.size))
    st = align_to_line(feature_profile(xs, prof, "LR", CFG.align_band_mm), _Line(welds, balises=[300.0]), CFG)
    assert st is not None and st.accepted, st.reason if st else "no stage"
    err = xs + st.fit.shift(xs) - T(xs)
    assert np.sqrt(np.mean(err[(xs > 140) & (xs < 460)] ** 2)) < 5e-3


def test_no_weld_in_the_run_gives_no_line_stage(rails):
    xs = np.arange(120, 480, 0.0025)
    fp = feature_profile(xs, read(rails, lambda x: x, xs, 1e-6), "LR", CFG.align_band_mm)
    assert align_to_line(fp, _Line([(550.0, "L")]), CFG) is None


def test_composition_and_stages_apply_in_order():
    a = ShiftFit(np.array([0.0, 100.0]), np.array([1.0, 1.5]))  # δ1 = 1 + 0.005 x
    b = ShiftFit(np.array([50.0, 150.0]), np.array([-0.2, 0.3]))
    c = compose(a, b)
    x = np.linspace(-10, 160, 400)
    y1 = x + a.shift(x)
    np.testing.assert_allclose(x + c.shift(x), y1 + b.shift(y1), atol=1e-6)
    al = Alignment("r", 1).then(_stage(a)).then(_stage(b))
    np.testing.assert_allclose(al.apply(x), y1 + b.shift(y1), atol=1e-12)


def _stage(fit):
    import pandas as pd

    from estimator.monitoring.alignment import AlignmentStage

    return AlignmentStage("t", fit, pd.DataFrame({"centre_m": [], "lag_m": [], "correlation": [], "kept": []}), 0.1,
                          True)


def test_robust_fit_ignores_windows_locked_on_a_wrong_peak():
    c = np.arange(0.0, 400.0, 10.0)
    lag = 0.5 + 0.002 * c
    bad = np.zeros(c.size, bool)
    bad[[3, 17, 30]] = True
    lag_obs = np.where(bad, lag + 0.05, lag)  # a corrugation's side peak one wavelength away
    fit, kept, res = fit_shift(c, lag_obs, np.ones(c.size), knots_for(0.0, 390.0, [], 250.0))
    assert not kept[bad].any() and kept[~bad].all()
    np.testing.assert_allclose(fit.shift(c), lag, atol=1e-9)
    assert res < 1e-9


def test_a_strong_periodic_corrugation_does_not_lock_windows_a_wavelength_off(rails):
    """Corrugation of 100 µm amplitude at 180 mm on rail R and 50 µm at 60 mm on L (ten and five times the
    broadband RMS) over 200–400 m, seen by the run with a 0.5 rad phase error (an inversion's phase at the
    corrugation's frequency depends on speed): left alone, the corrugation decides the correlation and drags
    windows off by a good part of a wavelength (the fit is then rejected: ~270 mm residual); with its spectral
    lines clipped the broadband roughness decides and the 0.5 % scale error is recovered."""
    X, R = rails
    on = (X >= 200) & (X < 400)

    def corrugated(phase):
        r = R.copy()
        r[1, on] += 100e-6 * np.sin(2 * np.pi * X[on] / 0.18 + phase)
        r[0, on] += 50e-6 * np.sin(2 * np.pi * X[on] / 0.06 - phase)
        return r

    rng = np.random.default_rng(4)
    xr = np.arange(100, 500, 0.0025)
    ref = feature_profile(xr, np.stack([np.interp(xr, X, r) for r in corrugated(0.0)])
                          + 1e-6 * rng.standard_normal((2, xr.size)), "LR", CFG.align_band_mm)
    xs = np.arange(120, 480, 0.0025)
    T = lambda x: 300 + (x - 300) * 0.995 - 1.2  # noqa: E731
    run = feature_profile(xs, np.stack([np.interp(T(xs), X, r) for r in corrugated(0.5)])
                          + 5e-6 * rng.standard_normal((2, xs.size)), "LR", CFG.align_band_mm)
    st = align_profiles(run, ref, CFG)
    assert st.accepted, st.reason
    assert st.windows["kept"].mean() > 0.9  # hardly a window locked on a side peak
    err = xs + st.fit.shift(xs) - T(xs)
    assert np.sqrt(np.mean(err[(xs > 140) & (xs < 460)] ** 2)) < 1e-3


def test_clip_tones_scales_only_the_lines_that_stand_out():
    from estimator.monitoring.alignment import clip_tones

    k = np.linspace(0, 200, 20001)
    rng = np.random.default_rng(0)
    P = (rng.standard_normal(k.size) + 1j * rng.standard_normal(k.size))
    P[5000] *= 50  # a tone
    Q = clip_tones(P, k)
    g = np.abs(Q) / np.abs(P)
    assert g[5000] < 0.1
    assert np.mean(g == 1.0) > 0.9  # the broadband lines are untouched
    np.testing.assert_allclose(np.angle(Q), np.angle(P), atol=1e-12)  # zero phase


def test_a_fit_is_rebuilt_from_its_stored_pieces():
    f = ShiftFit(np.array([10.0, 200.0, 450.0]), np.array([0.3, 0.8, 0.1]))
    g = ShiftFit.from_pieces(f.pieces())
    x = np.linspace(0, 500, 101)
    np.testing.assert_allclose(g.shift(x), f.shift(x), atol=1e-12)
    np.testing.assert_allclose(ShiftFit.from_pieces(ShiftFit(np.array([0.0]), np.array([0.25])).pieces()).shift(x), 0.25)
