"""Continuous-support track receptance (thesis §2.4) against independent oracles.

Oracles: (1) the inverse Fourier integral over wavenumber of eq. 2.33, solved as a
2×2 linear system at each real k and integrated with ``scipy.integrate.quad``;
(2) the closed-form Euler–Bernoulli receptance on a Winkler foundation;
(3) the resonance frequencies the thesis reads off Figs. 2.10/2.11.
"""

import dataclasses

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.signal import find_peaks

from receptance.track import (beam_section, support_stiffness_per_metre, track_frf,
                              track_receptance)
from receptance.trackform import Trackform

TF = Trackform()
FREQS = np.geomspace(5, 2000, 30)


def _wavenumber_solution(k, f, tf, direction):
    """W(k) from eq. 2.33 with w, Φ ∝ exp(-jkx): solve the 2×2 system for a unit force."""
    I = tf.rail_I_yy if direction == "vertical" else tf.rail_I_zz
    E = tf.youngs_modulus * (1 + 1j * tf.rail_loss_factor)
    G = E / (2 * (1 + tf.poisson_ratio))
    a = tf.shear_factor * G * tf.rail_area
    w = 2 * np.pi * f
    keq = support_stiffness_per_metre(f, tf, direction)
    k = np.atleast_1d(k)
    M = np.empty(k.shape + (2, 2), complex)
    # eq. 1: (-m w² + keq) W + a d/dx(Φ - W')  ->  (-m w² + keq + a k²) W - j k a Φ = 1
    M[..., 0, 0] = -tf.rail_mass * w**2 + keq + a * k**2
    M[..., 0, 1] = -1j * k * a
    # eq. 2: -ρI w² Φ - E I Φ'' + a (Φ - W')  ->  (-ρI w² + E I k² + a) Φ + j k a W = 0
    M[..., 1, 0] = 1j * k * a
    M[..., 1, 1] = -tf.rail_density * I * w**2 + E * I * k**2 + a
    rhs = np.zeros(k.shape + (2, 1), complex)
    rhs[..., 0, 0] = 1.0
    return np.linalg.solve(M, rhs)[..., 0, 0]


def _inverse_fourier(f, tf, direction):
    """w(0) = (1/2π)∫W dk = (1/π)∫_0^∞ W dk (W even in k), quad on real and imaginary parts."""
    grid = np.linspace(0, 200, 40001)
    Wg = np.abs(_wavenumber_solution(grid, f, tf, direction))
    peaks = grid[find_peaks(Wg)[0]]
    kmax = 200.0
    total = 0j
    for part in (np.real, np.imag):
        fun = lambda k: part(_wavenumber_solution(k, f, tf, direction))[0]
        v1, _ = quad(fun, 0, kmax, points=list(peaks) or None, limit=400, epsabs=0, epsrel=1e-10)
        v2, _ = quad(fun, kmax, np.inf, limit=200, epsabs=0, epsrel=1e-10)
        total += (v1 + v2) * (1 if part is np.real else 1j)
    return total / np.pi


@pytest.mark.parametrize("direction", ["vertical", "lateral"])
def test_closed_form_matches_inverse_fourier_integral(direction):
    closed = track_receptance(FREQS, TF, direction)
    numeric = np.array([_inverse_fourier(f, TF, direction) for f in FREQS])
    err = np.abs(closed / numeric - 1)
    # measured: 6e-15 max (machine precision); the brief asks for 1 %
    assert err.max() < 1e-9, (FREQS[err.argmax()], err.max())


@pytest.mark.parametrize("direction", ["vertical", "lateral"])
def test_euler_bernoulli_limit(direction):
    """κGA → ∞ and no rotary inertia: w(0)/F = 1/(8 E*I β³), β⁴ = (k_eq* − mΩ²)/(4E*I)."""
    eb = dataclasses.replace(TF, shear_factor=1e7, rail_density=1e-9)
    f = np.geomspace(1, 3000, 200)
    sec = beam_section(eb, direction)
    s = support_stiffness_per_metre(f, eb, direction) - eb.rail_mass * (2 * np.pi * f) ** 2
    beta = (s / (4 * sec.EI)) ** 0.25      # Im s > 0 (damping): principal branch is continuous from s > 0
    expected = 1 / (8 * sec.EI * beta**3)
    got = track_receptance(f, eb, direction)
    assert np.max(np.abs(got / expected - 1)) < 1e-5
    # and the Timoshenko rail is measurably softer than Euler–Bernoulli at high frequency
    tim = track_receptance([2000.0], TF, direction)[0]
    eb2 = track_receptance([2000.0], eb, direction)[0]
    assert abs(tim) > 1.02 * abs(eb2)


def test_static_limit_is_winkler_beam():
    """At 0 Hz the track is a beam on the series stiffness k_rp k_sp/(k_rp+k_sp) (eq. 2.34)."""
    k = support_stiffness_per_metre(0.0, TF, "vertical")
    EI = TF.youngs_modulus * (1 + 1j * TF.rail_loss_factor) * TF.rail_I_yy
    beta = (k / (4 * EI)) ** 0.25
    # Shear flexibility softens the Timoshenko rail: the relevant scale is
    # E I β² / (κ G A) ≈ 3 % for the 50E5 rail (κ = 0.34); measured +4.8 %.
    r = track_receptance([0.0], TF)[0]
    assert 0.02 < (abs(r) / abs(1 / (8 * EI * beta**3)) - 1) < 0.08
    assert abs(np.angle(r) - np.angle(1 / (8 * EI * beta**3))) < 0.01


@pytest.mark.parametrize("direction", ["vertical", "lateral"])
def test_passive(direction):
    """A passive structure dissipates: Im(receptance) < 0 with exp(+jΩt)."""
    r = track_receptance(np.linspace(0, 3000, 3001), TF, direction)
    assert np.all(r.imag < 0)


def _peaks(direction, fmax=1000.0):
    f = np.arange(1.0, fmax, 0.05)
    a = np.abs(track_receptance(f, TF, direction))
    return f[find_peaks(a)[0]]


def test_thesis_resonances():
    """Thesis §2.4.2: vertical ≈ 112 Hz; lateral ≈ 67 Hz and 374 Hz.

    Measured here: vertical 113.9 Hz (+1.7 %), lateral 66.9 Hz (−0.2 %) and 378.7 Hz (+1.3 %).
    The thesis values are read off log plots ("at around"); a 3 % tolerance covers that
    reading and the model variant: dropping the viscous dampers of eq. 2.34 gives 114.4 /
    67.1 / 375.4 Hz, dropping the loss factors 114.4 / 67.0 / 369.2 Hz — all within 3 %, so
    the thesis figure cannot tell which damping it used, but it does confirm the per-metre
    stiffness k = K/L_s (with k = K the resonances would move by √0.75, i.e. −13 %).
    """
    v = _peaks("vertical")
    lat = _peaks("lateral")
    assert abs(v[0] / 112 - 1) < 0.03
    assert abs(lat[0] / 67 - 1) < 0.03
    assert abs(lat[1] / 374 - 1) < 0.03


def test_track_frf_labels_and_diagonal():
    frf = track_frf(FREQS, TF)
    assert frf.outputs == ("rail_z", "rail_y") and frf.inputs == ("rail_z", "rail_y")
    assert frf.quantity == "receptance"
    np.testing.assert_allclose(frf.data[0, 0], track_receptance(FREQS, TF, "vertical"), rtol=1e-14)
    np.testing.assert_allclose(frf.data[1, 1], track_receptance(FREQS, TF, "lateral"), rtol=1e-14)
    assert np.all(frf.data[0, 1] == 0) and np.all(frf.data[1, 0] == 0)


def test_bad_arguments():
    with pytest.raises(ValueError, match="direction"):
        track_receptance(FREQS, TF, "longitudinal")
    with pytest.raises(ValueError, match="supports"):
        track_receptance(FREQS, TF, supports="sleepers")
    with pytest.raises(ValueError, match="f_hz"):
        track_receptance([-1.0], TF)
