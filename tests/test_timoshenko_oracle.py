"""Self-tests of the analytic free-free Timoshenko / torsion oracle.

The oracle (``tests/timoshenko_oracle.py``) is checked against

* the Euler-Bernoulli free-free values (slender limit), including the
  first-order rotary-inertia / shear correction obtained by perturbation
  theory from the Euler-Bernoulli mode shapes;
* the expected trend with slenderness;
* two independent numerical solutions of the same boundary-value problem:
  Chebyshev collocation (generalised eigenproblem, gives the whole spectrum
  and therefore also checks that no mode is missed or spurious) and shooting
  with ``scipy.integrate.solve_ivp`` on the first-order system, for stocky
  shafts with modes on both sides of the second-spectrum cut-off;
* the closed-form torsion result.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad, solve_ivp
from scipy.linalg import eig
from scipy.optimize import brentq

import timoshenko_oracle as oracle

E_STEEL = 210e9
NU_STEEL = 0.3
G_STEEL = E_STEEL / (2.0 * (1.0 + NU_STEEL))
RHO_STEEL = 7850.0

# Free-free Euler-Bernoulli roots of cos(bL) cosh(bL) = 1.
BETA_L_EB = np.array([4.730040745, 7.853204624, 10.99560784, 14.13716549])


def _beam(L_over_d, d=0.16, d_in_ratio=0.0, G_factor=1.0):
    sec = oracle.solid_or_hollow_circle(d, d_in_ratio * d, nu=NU_STEEL)
    return dict(
        L=L_over_d * d,
        E=E_STEEL,
        G=G_STEEL * G_factor,
        rho=RHO_STEEL,
        A=sec["A"],
        I=sec["I"],
        kappa=sec["kappa"],
    )


def _euler_bernoulli(p, beta_l=BETA_L_EB):
    return beta_l**2 * np.sqrt(p["E"] * p["I"] / (p["rho"] * p["A"] * p["L"] ** 4)) / (2 * np.pi)


def _dimensionless(p):
    g = p["E"] * p["I"] / (p["kappa"] * p["G"] * p["A"] * p["L"] ** 2)
    s2 = p["I"] / (p["A"] * p["L"] ** 2)
    return g, s2


def _lam_from_hz(f, p):
    omega = 2 * np.pi * np.asarray(f)
    return omega**2 * p["rho"] * p["A"] * p["L"] ** 4 / (p["E"] * p["I"])


# --------------------------------------------------------------------------
# Euler-Bernoulli limit
# --------------------------------------------------------------------------


def _eb_energy_ratios(beta_l):
    """Return (int w'^2 / int w^2, int w'''^2 / int w''^2) of an E-B free-free mode."""
    b = beta_l
    sg = (np.cosh(b) - np.cos(b)) / (np.sinh(b) - np.sin(b))
    w0 = lambda x: np.cosh(b * x) + np.cos(b * x) - sg * (np.sinh(b * x) + np.sin(b * x))
    w1 = lambda x: b * (np.sinh(b * x) - np.sin(b * x) - sg * (np.cosh(b * x) + np.cos(b * x)))
    w2 = lambda x: b**2 * (np.cosh(b * x) - np.cos(b * x) - sg * (np.sinh(b * x) - np.sin(b * x)))
    w3 = lambda x: b**3 * (np.sinh(b * x) + np.sin(b * x) - sg * (np.cosh(b * x) - np.cos(b * x)))
    sq = lambda f: quad(lambda x: f(x) ** 2, 0.0, 1.0, epsabs=0.0, epsrel=1e-12, limit=200)[0]
    return sq(w1) / sq(w0), sq(w3) / sq(w2)


def test_euler_bernoulli_roots_are_roots():
    b = BETA_L_EB
    assert np.all(np.abs(np.cos(b) * np.cosh(b) - 1.0) < 1e-6 * np.cosh(b))


def test_euler_bernoulli_limit_very_slender():
    """L/d = 1000 steel shaft: Timoshenko -> Euler-Bernoulli to 1e-4 (actually ~2.5e-5)."""
    p = _beam(1000.0, d=0.01)
    f = oracle.free_free_bending_frequencies(4, **p)
    rel = f / _euler_bernoulli(p) - 1.0
    assert np.all(rel < 0.0)
    assert np.max(np.abs(rel)) < 1e-4


def test_euler_bernoulli_limit_l_over_d_200_large_shear_stiffness():
    """L/d = 200 with kappa G A -> large.

    Only rotary inertia remains.  For a circular section at L/d = 200 it
    still lowers mode 4 by ~2.2e-4 (mode 1: 3.9e-5), so the raw 1e-4 check
    holds for modes 1-2; all four modes match Euler-Bernoulli corrected by
    first-order perturbation theory, f/f_EB = 1 - s2/2 int w'^2 / int w^2,
    to 1e-6.
    """
    p = _beam(200.0, d=0.02, G_factor=1e6)
    f = oracle.free_free_bending_frequencies(4, **p)
    f_eb = _euler_bernoulli(p)
    rel = f / f_eb - 1.0
    assert np.all(np.abs(rel[:2]) < 1e-4)
    assert np.all(np.abs(rel) < 3e-4)
    g, s2 = _dimensionless(p)
    ratios = np.array([_eb_energy_ratios(b) for b in BETA_L_EB])
    predicted = 1.0 - 0.5 * (s2 * ratios[:, 0] + g * ratios[:, 1])
    assert np.max(np.abs(f / (f_eb * predicted) - 1.0)) < 1e-6


def test_first_order_shear_and_rotary_correction_l_over_d_200_steel():
    """Real steel at L/d = 200: deviation from E-B (up to 6e-4) is first order.

    f/f_EB = 1 - (s2 int w'^2/int w^2 + g int w'''^2/int w''^2)/2, residual O((d/L)^4).
    """
    p = _beam(200.0, d=0.02)
    f = oracle.free_free_bending_frequencies(4, **p)
    f_eb = _euler_bernoulli(p)
    g, s2 = _dimensionless(p)
    ratios = np.array([_eb_energy_ratios(b) for b in BETA_L_EB])
    predicted = 1.0 - 0.5 * (s2 * ratios[:, 0] + g * ratios[:, 1])
    assert np.max(np.abs(f / f_eb - 1.0)) > 5e-4  # the correction is really there
    assert np.max(np.abs(f / (f_eb * predicted) - 1.0)) < 2e-6


# --------------------------------------------------------------------------
# Trend with slenderness
# --------------------------------------------------------------------------


def test_shear_and_rotary_inertia_lower_frequencies_more_for_stocky_beams():
    ratios = []
    for l_over_d in (20.0, 10.0, 5.0):
        p = _beam(l_over_d)
        ratios.append(oracle.free_free_bending_frequencies(4, **p) / _euler_bernoulli(p))
    ratios = np.array(ratios)  # rows: L/d = 20, 10, 5 ; columns: modes 1..4
    assert np.all(ratios < 1.0)
    # stockier -> lower, for every mode
    assert np.all(np.diff(ratios, axis=0) < 0.0)
    # higher modes (shorter wavelength) -> lower, for every slenderness
    assert np.all(np.diff(ratios, axis=1) < 0.0)
    # sanity of magnitude: L/d = 5 mode 4 is lowered substantially
    assert ratios[2, 3] < 0.7


def test_frequencies_scale_with_wave_speed():
    p = _beam(8.0)
    f1 = oracle.free_free_bending_frequencies(5, **p)
    p2 = dict(p, E=4 * p["E"], G=4 * p["G"])
    f2 = oracle.free_free_bending_frequencies(5, **p2)
    np.testing.assert_allclose(f2, 2 * f1, rtol=1e-12)


# --------------------------------------------------------------------------
# Independent numerical solutions of the same boundary-value problem
# --------------------------------------------------------------------------


def _cheb(N):
    """Chebyshev differentiation matrix and nodes on [0, 1] (Trefethen, cheb.m)."""
    j = np.arange(N + 1)
    x = np.cos(np.pi * j / N)
    c = np.where((j == 0) | (j == N), 2.0, 1.0) * (-1.0) ** j
    X = np.tile(x, (N + 1, 1)).T
    dX = X - X.T
    D = np.outer(c, 1.0 / c) / (dX + np.eye(N + 1))
    D -= np.diag(D.sum(axis=1))
    # map [-1, 1] -> [0, 1]: xi = (1 - x)/2, d/dxi = -2 d/dx
    return -2.0 * D, (1.0 - x) / 2.0


def _chebyshev_lambdas(g, s2, N=48):
    """Free-free Timoshenko eigenvalues lam by Chebyshev collocation.

    Dimensionless equations on xi in [0, 1] (w scaled by L):
        (w'' - psi') / g = -lam w
        psi'' + (w' - psi) / g = -lam s2 psi
    boundary rows: w' - psi = 0 and psi' = 0 at both ends.
    """
    D, _ = _cheb(N)
    n = N + 1
    Id = np.eye(n)
    D2 = D @ D
    Z = np.zeros((n, n))
    K = -np.block([[D2 / g, -D / g], [D / g, D2 - Id / g]])
    M = np.block([[Id, Z], [Z, s2 * Id]])
    for row in (0, N):
        K[row] = np.concatenate([D[row], -Id[row]])  # shear force
        M[row] = 0.0
        K[n + row] = np.concatenate([np.zeros(n), D[row]])  # bending moment
        M[n + row] = 0.0
    vals = eig(K, M, right=False)
    vals = vals[np.isfinite(vals)]
    vals = np.sort(vals[np.abs(vals.imag) < 1e-6 * np.maximum(1.0, np.abs(vals.real))].real)
    # the two smallest are the rigid-body modes (lam = 0 up to round-off)
    assert np.all(np.abs(vals[:2]) < 1e-3 * vals[2])
    return vals[2:]


def _shooting_determinant(lam, g, s2):
    """det of the end-conditions at xi=1 for the two free-start solutions."""

    def rhs(_, y):
        out = np.empty_like(y)
        for k in (0, 4):
            w, dw, psi, dpsi = y[k : k + 4]
            out[k] = dw
            out[k + 1] = dpsi - lam * g * w
            out[k + 2] = dpsi
            out[k + 3] = -(dw - psi) / g - lam * s2 * psi
        return out

    # free at xi=0: psi' = 0 and w' = psi; unknowns w(0), psi(0)
    y0 = np.array([1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0])
    sol = solve_ivp(rhs, (0.0, 1.0), y0, method="DOP853", rtol=1e-12, atol=1e-14)
    y = sol.y[:, -1]
    r = [[y[3], y[1] - y[2]], [y[7], y[5] - y[6]]]
    return r[0][0] * r[1][1] - r[0][1] * r[1][0]


STOCKY_CASES = {
    # name: (L/d_out, d_in/d_out, number of modes, min. modes above cut-off)
    "solid L/d=5": (5.0, 0.0, 4, 0),
    "solid L/d=2 (short thick shaft)": (2.0, 0.0, 4, 2),
    "thin tube L/d=5": (5.0, 0.9, 6, 2),
}


@pytest.mark.parametrize("case", list(STOCKY_CASES))
def test_against_chebyshev_collocation_and_shooting(case):
    l_over_d, din, n, n_above = STOCKY_CASES[case]
    p = _beam(l_over_d, d_in_ratio=din)
    g, s2 = _dimensionless(p)
    f = oracle.free_free_bending_frequencies(n, **p)
    lam_oracle = _lam_from_hz(f, p)

    f_c = oracle.timoshenko_cutoff_frequency(
        G=p["G"], rho=p["rho"], A=p["A"], I=p["I"], kappa=p["kappa"]
    )
    assert np.isclose(_lam_from_hz(f_c, p), 1.0 / (g * s2), rtol=1e-12)
    assert np.sum(f > f_c) >= n_above
    roots = oracle.free_free_bending_roots(n, g=g, s2=s2)
    assert [r.above_cutoff for r in roots] == list(f > f_c)
    assert {r.family for r in roots} == {"symmetric", "antisymmetric"}

    # 1) Chebyshev collocation: whole spectrum, so also no missing/extra modes
    lam_cheb = _chebyshev_lambdas(g, s2)[:n]
    np.testing.assert_allclose(lam_oracle, lam_cheb, rtol=1e-8)

    # 2) shooting with solve_ivp, bracket around the collocation value
    for lam_ref, lam_o in zip(lam_cheb, lam_oracle):
        a, b = lam_ref * (1 - 2e-3), lam_ref * (1 + 2e-3)
        fa, fb = _shooting_determinant(a, g, s2), _shooting_determinant(b, g, s2)
        assert fa * fb < 0
        lam_shoot = brentq(_shooting_determinant, a, b, args=(g, s2), xtol=1e-14, rtol=1e-13)
        # frequency ~ sqrt(lam): require 1e-4 relative in frequency (expect ~1e-9)
        assert abs(math.sqrt(lam_o / lam_shoot) - 1.0) < 1e-4
        assert abs(lam_o / lam_shoot - 1.0) < 1e-8


def test_regime_switch_is_continuous_and_root_free():
    """Determinants join continuously at the cut-off (no artificial sign change)."""
    p = _beam(2.0)
    g, s2 = _dimensionless(p)
    lam_c = 1.0 / (g * s2)
    eps = np.array([-1e-9, -1e-12, 0.0, 1e-12, 1e-9])
    d_sym, d_anti = oracle._determinants(lam_c * (1 + eps), g, s2)
    for d in (d_sym, d_anti):
        assert np.all(np.sign(d) == np.sign(d[2]))
        assert np.ptp(d) < 1e-6 * np.max(np.abs(d))


def test_bending_input_validation():
    p = _beam(10.0)
    with pytest.raises(ValueError):
        oracle.free_free_bending_frequencies(0, **p)
    with pytest.raises(ValueError):
        oracle.free_free_bending_frequencies(3, **dict(p, kappa=-1.0))
    f = oracle.free_free_bending_frequencies(7, **p)
    assert f.shape == (7,) and np.all(np.diff(f) > 0) and np.all(f > 0)


# --------------------------------------------------------------------------
# Section properties
# --------------------------------------------------------------------------


def test_section_properties():
    d, di = 0.2, 0.12
    s = oracle.solid_or_hollow_circle(d, di, nu=0.3)
    assert math.isclose(s["A"], math.pi * (d**2 - di**2) / 4, rel_tol=1e-14)
    assert math.isclose(s["I"], math.pi * (d**4 - di**4) / 64, rel_tol=1e-14)
    assert math.isclose(s["J"], 2 * s["I"], rel_tol=1e-14)
    assert s["shear_coefficient"].startswith("Cowper")

    solid = oracle.solid_or_hollow_circle(d, nu=0.3)
    assert math.isclose(solid["kappa"], 6 * 1.3 / (7 + 6 * 0.3), rel_tol=1e-14)  # 0.8864
    # thin-walled limit of Cowper's formula: 2(1+nu)/(4+3nu)
    thin = oracle.solid_or_hollow_circle(d, d * (1 - 1e-9), nu=0.3)
    assert math.isclose(thin["kappa"], 2 * 1.3 / (4 + 0.9), rel_tol=1e-6)
    hut = oracle.solid_or_hollow_circle(d, nu=0.3, shear_coefficient="hutchinson")
    assert math.isclose(hut["kappa"], 6 * 1.3**2 / (7 + 3.6 + 0.36), rel_tol=1e-14)  # 0.9252
    with pytest.raises(NotImplementedError):
        oracle.solid_or_hollow_circle(d, di, shear_coefficient="hutchinson")
    with pytest.raises(ValueError):
        oracle.solid_or_hollow_circle(d, d)


# --------------------------------------------------------------------------
# Torsion
# --------------------------------------------------------------------------


def test_torsion_against_wave_speed():
    L, G, rho = 2.2, 81e9, 7850.0
    c = math.sqrt(G / rho)  # ~3212 m/s
    f = oracle.free_free_torsion_frequencies(5, L=L, G=G, rho=rho)
    np.testing.assert_allclose(f, np.arange(1, 6) * c / (2 * L), rtol=1e-14)
    assert math.isclose(f[0], 730.0, rel_tol=1e-3)  # 3212.2 / 4.4


def test_torsion_independent_of_diameter():
    """Circular sections: J == polar moment, so c = sqrt(G J / (rho Ip)) = sqrt(G/rho)."""
    L, G, rho = 2.2, 81e9, 7850.0
    f_ref = oracle.free_free_torsion_frequencies(3, L=L, G=G, rho=rho)
    for d_out, d_in in [(0.05, 0.0), (0.2, 0.0), (0.2, 0.15), (0.6, 0.59)]:
        s = oracle.solid_or_hollow_circle(d_out, d_in)
        polar = math.pi / 32 * (d_out**4 - d_in**4)
        c = math.sqrt(G * s["J"] / (rho * polar))
        np.testing.assert_allclose(np.arange(1, 4) * c / (2 * L), f_ref, rtol=1e-13)
