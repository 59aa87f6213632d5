"""Wheel/rail separation: angle-domain comb, circumference, polygon orders.

Oracles: an exactly periodic signal (removed to machine precision), random rail roughness (its energy kept),
a known polygon order and amplitude; a synthetic run with a polygonised wheel against the same run without.
"""

from __future__ import annotations

import numpy as np
import pytest

from estimator import EstimatorConfig, estimate_run, prepare
from estimator.wheel import MIN_SIGNIFICANCE, circumference, comb, comb_response, wheel_roughness
from test_estimator_synthetic import SyntheticLine, control_model, make_run, sensor_table


def _rail(n, dx, seed=3, rms=5e-6):
    rng = np.random.default_rng(seed)
    X = np.fft.rfft(rng.standard_normal(n))
    k = np.fft.rfftfreq(n, dx)
    X[(k < 1 / 0.5) | (k > 1 / 0.02)] = 0
    r = np.fft.irfft(X, n)
    return rms * r / r.std()


def test_comb_removes_the_periodic_part_and_keeps_the_rail():
    N, n_rev = 1024, 120
    dx = 2.58 / N
    rng = np.random.default_rng(0)
    wheel = np.fft.irfft(np.fft.rfft(rng.standard_normal(N)) * (np.arange(N // 2 + 1) < 60), N) * 3e-6
    rail = _rail(N * n_rev, dx)
    prof = np.vstack([np.tile(wheel, n_rev), rail])
    prof[:, 50_000:52_000] = np.nan  # a masked gap: no weight, no interpolation
    out, per = comb(prof, N, 32)
    ok = np.isfinite(out[0])
    # an exactly periodic wheel is removed to machine precision (gap or not)
    assert np.max(np.abs(out[0, ok])) < 1e-9 * np.abs(wheel).max()
    # the energy of a random rail is kept to 0.3 dB (notches ~1/32 order wide, the revolution itself left out)
    ratio_db = 10 * np.log10(np.mean(out[1, ok] ** 2) / np.mean(rail[ok] ** 2))
    assert abs(ratio_db) < 0.3
    assert np.isnan(out[:, 50_500]).all()
    assert comb_response(np.array([1.0, 12.0, 0.5, 12.5]), 32) == pytest.approx([0, 0, 1.03, 1.03], abs=0.01)


@pytest.mark.parametrize("kernel", ["_comb", "_comb_numpy"])
def test_compiled_comb_equals_the_direct_sum(kernel):
    """The one-pass running-sum comb (compiled, and its numpy fallback) equals the triangular weighted sum written
    out term by term, gaps and a partial last revolution included."""
    import estimator.wheel as wheel

    rng = np.random.default_rng(7)
    R, rows, n_rev, N = 3, 2, 23, 5
    X = rng.standard_normal((rows, n_rev, N))
    X[:, 4:6, :] = np.nan
    X[1, :, 2] = np.where(rng.random(n_rev) < 0.4, np.nan, X[1, :, 2])
    X[0, :, 4] = np.nan  # an angle with no valid revolution at all
    X[:, -1, 3:] = np.nan  # past the profile's end: the last revolution is partial
    M = n_rev * N - 2
    P = np.ascontiguousarray(X.reshape(rows, -1)[:, :M])
    rail, per = getattr(wheel, kernel)(P, N, R, 0.05 * R * (R + 1))
    want = np.full_like(X, np.nan)
    for i in range(rows):
        for r in range(n_rev):
            for k in range(N):
                num = den = 0.0
                for m in range(-R, R + 1):
                    if m == 0 or not 0 <= r + m < n_rev or not np.isfinite(X[i, r + m, k]):
                        continue
                    num += (R + 1 - abs(m)) * X[i, r + m, k]
                    den += R + 1 - abs(m)
                if den > 0.05 * R * (R + 1):
                    want[i, r, k] = num / den
    want = want.reshape(rows, -1)[:, :M]
    assert np.array_equal(np.isnan(per), np.isnan(want))
    np.testing.assert_allclose(per[np.isfinite(per)], want[np.isfinite(want)], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(rail, P - np.where(np.isfinite(want), per, 0.0))


def test_circumference_and_polygon_order_from_a_wheel_on_random_rail():
    C_true = 2.5717
    dx = 2.5e-3
    x = np.arange(0, 400, dx)
    rng = np.random.default_rng(4)
    angle = 2 * np.pi * x / C_true
    orders = np.arange(1, 80)
    amps = 0.4e-6 * rng.random(orders.size)
    wheel = (amps[:, None] * np.sin(orders[:, None] * angle[None, :] + rng.uniform(0, 6.3, orders.size)[:, None])).sum(0)
    wheel += 15e-6 * np.sin(12 * angle + 0.7)
    prof = np.vstack([wheel + _rail(x.size, dx, 5), _rail(x.size, dx, 6)])
    fit = circumference(prof, dx, 2.5717 * 1.003, search=0.005)
    assert fit.found and fit.circumference_m == pytest.approx(C_true, rel=1e-4)
    n_rev = int(np.ceil(fit.circumference_m / dx))
    xg = np.arange(0, 400, fit.circumference_m / n_rev)
    on_grid = np.vstack([np.interp(xg, x, p) for p in prof])
    wr = wheel_roughness(on_grid, n_rev, ("L", "R"), fit.circumference_m)
    top = wr.polygon("L").iloc[0]
    assert top["order"] == 12 and top["amplitude_m"] == pytest.approx(15e-6, rel=0.05)
    assert wr.polygon("R").empty or wr.polygon("R")["amplitude_m"].max() < 2e-6


def _red_rail(rng, n, dx, slope):
    """Random rail-only profile (two sides) whose power spectrum falls as ``k^slope`` (rail roughness: −2 to −3)."""
    k = np.fft.rfftfreq(n, dx)
    shape = np.where(k > 0, np.maximum(k, 0.5) ** (slope / 2), 0.0)
    return np.stack([np.fft.irfft((rng.standard_normal(k.size) + 1j * rng.standard_normal(k.size)) * shape, n)
                     for _ in range(2)])


@pytest.mark.parametrize("slope", [0, -2, -3])
def test_circumference_significance_follows_its_null_for_any_rail_spectrum(slope):
    """Rail only: the z-score is the maximum of ~200 independent unit normals over a ±1 % search (median ≈ 2.9),
    whatever the spectrum's slope or a gap; the unwhitened autocorrelation gave a median of 1.5 and false peaks
    above 10 on a red spectrum."""
    rng = np.random.default_rng(7 + slope)
    dx, n = 0.005, 60_000
    sig = []
    for i in range(12):
        prof = _red_rail(rng, n, dx, slope)
        if i % 2:
            prof[:, 20_000:24_000] = np.nan
        sig.append(circumference(prof, dx, 2.5656, search=0.01).significance)
    assert 2.0 < np.median(sig) < 4.0
    assert max(sig) < 0.6 * MIN_SIGNIFICANCE


def test_a_wheel_below_a_red_rail_is_found():
    """A wheel whose roughness (orders 1–80) is 6 dB below a k⁻² rail (the virtual line's level offset) and whose
    nominal circumference is 0.16 % off (the odometer's, from the other wheelset): found to 2e-5."""
    rng = np.random.default_rng(11)
    dx, n, C_true = 0.005, 60_000, 2.5697
    x = np.arange(n) * dx
    rail = _red_rail(rng, n, dx, -2)
    angle = 2 * np.pi * x / C_true
    orders = np.arange(1, 81)
    amps = orders ** -1.0  # k⁻² in power, like the rail
    wheel = (amps[:, None] * np.sin(orders[:, None] * angle + rng.uniform(0, 2 * np.pi, (orders.size, 1)))).sum(0)
    wheel *= 0.5 * rail.std() / wheel.std()
    fit = circumference(rail + wheel, dx, 2.5656, search=0.01)
    assert fit.found and fit.circumference_m == pytest.approx(C_true, rel=2e-5)


@pytest.fixture(scope="module")
def polygon_runs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("poly")
    line = SyntheticLine(sinusoids={"L": [(0.150, 15e-6, 100.0, 300.0)], "R": []}, broadband_rms=1.5e-6)
    poly = {"wheelset": 1, "side": "L", "order": 12, "amplitude_m": 15e-6}
    a = make_run(tmp, control_model(), line=line, duration_s=45, name="plain")
    b = make_run(tmp, control_model(), line=line, duration_s=45, wheel_polygon=poly, name="polygon")
    fm = prepare(control_model(), sensor_table(), config=EstimatorConfig(models=("vertical_lateral",)))
    return estimate_run(a.path, fm), estimate_run(b.path, fm)


def test_polygonised_wheel_is_separated_from_the_rail(polygon_runs):
    """Synthetic analogue of the wheel_polygon acceptance: rail within 1 dB, order and amplitude within 20 %."""
    plain, poly = polygon_runs
    p = poly.profile(1, "vertical_lateral")
    top = p.wheel.polygon("L").iloc[0]
    assert top["order"] == 12 and top["amplitude_m"] == pytest.approx(15e-6, rel=0.2)
    q = plain.profile(1, "vertical_lateral")
    for band in ((30.0, 100.0), (100.0, 300.0)):
        a, b = p.pk_pk(band, "L"), np.interp(p.chainage_m, q.chainage_m, q.pk_pk(band, "L"))
        ok = np.isfinite(a) & np.isfinite(b) & (p.chainage_m > 110) & (p.chainage_m < 290)
        assert abs(10 * np.log10(np.mean(a[ok] ** 2) / np.mean(b[ok] ** 2))) < 1.0
    # the untouched wheelset 2 shows no polygon: the wheelbase is measured right in spite of the narrow-band rail
    # (whitened lag search) and the rail's coupling of the wheelsets is inverted (not handed to wheelset 2)
    assert poly.wheelbase_m == pytest.approx(2.2, abs=0.005)
    assert poly.profile(2, "vertical_lateral").wheel.polygon("L").query("order == 12").empty
