"""Tests of receptance.contact (linearised Hertzian contact stiffness).

Oracles:
* circular limits (sphere on plane, crossed cylinders of equal radius) against
  the closed form δ = (9 N² / (16 E*² R))^(1/3), a³ = 3NR/(4E*);
* elliptical contacts against two independent numerical integrations of the
  Hertz problem that never use the elliptic-integral relations of the module:
  (i) Love's potential integrals (the "Hertz table": b/a, a/c and δ/δ_c as
  functions of A/B, solved by quadrature + root finding), and
  (ii) direct Boussinesq integration of the elliptical pressure
  p0 sqrt(1 − x²/a² − y²/b²) at several surface points, which must give the
  approach δ and the gap curvatures A, B that the module was asked to match;
* exact N^(1/3) scaling and k_H = dN/dδ by finite differences.
"""

import math

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.optimize import brentq
from scipy.special import ellipe, ellipk

from receptance.contact import (
    ContactParameterError,
    ContactParameters,
    effective_modulus,
    hertz_compliance,
    hertz_contact,
    hertz_ellipse_ratio,
    hertz_stiffness,
)

E, NU = 206e9, 0.28
E_STAR = E / (2 * (1 - NU**2))


def closed_form_circle(N, R, E_star=E_STAR):
    """Hertz circular contact: approach and contact radius (Johnson eqs. 4.22-4.23)."""
    delta = (9 * N**2 / (16 * E_star**2 * R)) ** (1 / 3)
    a = (3 * N * R / (4 * E_star)) ** (1 / 3)
    return delta, a


# --------------------------------------------------------------------------- (1) circular limits
@pytest.mark.parametrize("N, R", [(55e3, 0.41), (1.0, 0.01), (2e5, 0.5)])
def test_sphere_on_plane_matches_closed_form(N, R):
    # wheel with equal rolling and transverse radius (a sphere) on a flat rail
    c = hertz_contact(N, R, R, math.inf, E=E, nu=NU)
    delta, a = closed_form_circle(N, R)
    assert c.approach == pytest.approx(delta, rel=1e-12)
    assert c.semi_axis_x == pytest.approx(a, rel=1e-12)
    assert c.semi_axis_y == pytest.approx(a, rel=1e-12)
    assert c.eccentricity == 0.0
    assert c.stiffness == pytest.approx(1.5 * N / delta, rel=1e-12)
    assert c.max_pressure == pytest.approx(3 * N / (2 * math.pi * a * a), rel=1e-12)


@pytest.mark.parametrize("R", [0.3, 0.41])
def test_crossed_equal_cylinders_is_circular(R):
    # cylindrical tread (R_wt = inf) of radius R crossing a rail crown of radius R
    N = 55e3
    c = hertz_contact(N, R, math.inf, R, E=E, nu=NU)
    delta, a = closed_form_circle(N, R)
    assert c.approach == pytest.approx(delta, rel=1e-12)
    assert c.semi_axis_x == pytest.approx(a, rel=1e-12)
    assert hertz_stiffness(N, R, math.inf, R) == pytest.approx(1.5 * N / delta, rel=1e-12)
    assert hertz_compliance(N, R, math.inf, R) == pytest.approx(delta / (1.5 * N), rel=1e-12)


def test_nearly_circular_is_continuous():
    # no cancellation near e -> 0: a 1e-9 curvature perturbation moves delta by O(1e-9)
    N, R = 55e3, 0.3
    c = hertz_contact(N, R, math.inf, R * (1 + 1e-9))
    delta, _ = closed_form_circle(N, R)
    assert c.approach == pytest.approx(delta, rel=1e-8)
    assert c.eccentricity < 1e-3


def test_dissimilar_materials_closed_form():
    N, R = 10e3, 0.2
    E2, nu2 = 110e9, 0.33  # e.g. a bronze/cast-iron counterpart
    Es = 1 / ((1 - NU**2) / E + (1 - nu2**2) / E2)
    assert effective_modulus(E, NU, E2, nu2) == pytest.approx(Es, rel=1e-14)
    c = hertz_contact(N, R, R, math.inf, E=E, nu=NU, E_rail=E2, nu_rail=nu2)
    assert c.approach == pytest.approx(closed_form_circle(N, R, Es)[0], rel=1e-12)
    # material symmetry: swapping wheel and rail steel changes nothing
    k1 = hertz_stiffness(N, 0.4, -2.0, 0.3, E=E, nu=NU, E_rail=E2, nu_rail=nu2)
    k2 = hertz_stiffness(N, 0.4, -2.0, 0.3, E=E2, nu=nu2, E_rail=E, nu_rail=NU)
    assert k1 == pytest.approx(k2, rel=1e-13)


# --------------------------------------------------------------------------- (2) elliptical: Hertz table
def _love_integrals(a, b):
    """Love's potential integrals for the Hertz pressure on an ellipse (semi-axes a along x, b along y).

    u(x, y) = (a b p0 / (2 E*)) [I0 - Ix x² - Iy y²] with
    I0 = ∫ dw/Δ, Ix = ∫ dw/((a²+w)Δ), Iy = ∫ dw/((b²+w)Δ), Δ = sqrt((a²+w)(b²+w)w).
    Substituting w = s² removes the 1/sqrt(w) singularity.
    """
    def d(s):
        return math.sqrt((a * a + s * s) * (b * b + s * s))

    opts = dict(epsabs=0.0, epsrel=1e-12, limit=200)
    I0 = quad(lambda s: 2.0 / d(s), 0, math.inf, **opts)[0]
    Ix = quad(lambda s: 2.0 / ((a * a + s * s) * d(s)), 0, math.inf, **opts)[0]
    Iy = quad(lambda s: 2.0 / ((b * b + s * s) * d(s)), 0, math.inf, **opts)[0]
    return I0, Ix, Iy


def hertz_table_row(A_over_B):
    """Independent Hertz-table row for a curvature ratio A/B <= 1 (A along the major axis).

    Returns (b/a, a/c, δ/δ_c) with c = sqrt(ab) and δ_c the approach of a
    circular contact of equivalent radius R_e = 1/(2 sqrt(AB)) under the same
    load — the quantities tabulated by Johnson (Contact Mechanics, §4.2,
    Fig. 4.4) and, through m, n, by Timoshenko & Goodier (§140).
    Obtained from Love's integrals by quadrature and root finding only.
    """
    # ratio of curvatures produced by the elliptical pressure: A/B = Ix/Iy
    k = brentq(lambda k: _love_integrals(1.0, k)[1] / _love_integrals(1.0, k)[2] - A_over_B,
               1e-4, 1.0 - 1e-12, xtol=1e-14, rtol=1e-13)
    # dimensional solution for unit E*, load N, A: u = (3N/(4π E*)) (I0 - Ix x² - Iy y²)
    N, Es, A = 1.0, 1.0, 1.0
    I0_1, Ix_1, _ = _love_integrals(1.0, k)        # integrals for a = 1 scale as a^-1, a^-3
    a = (3 * N / (4 * math.pi * Es) * Ix_1 / A) ** (1 / 3)
    delta = 3 * N / (4 * math.pi * Es) * I0_1 / a
    B = A / A_over_B
    Re = 1 / (2 * math.sqrt(A * B))
    delta_c = (9 * N**2 / (16 * Es**2 * Re)) ** (1 / 3)
    c = math.sqrt(a * a * k)
    return k, a / c, delta / delta_c


@pytest.mark.parametrize("A_over_B", [0.1, 0.5, 0.9])
def test_elliptical_contact_matches_independent_hertz_table(A_over_B):
    k_ref, a_over_c_ref, d_ratio_ref = hertz_table_row(A_over_B)
    # the module's ellipse ratio, from either orientation of the ratio
    assert hertz_ellipse_ratio(1 / A_over_B) == pytest.approx(k_ref, rel=1e-9)
    assert hertz_ellipse_ratio(A_over_B) == pytest.approx(k_ref, rel=1e-9)

    # realise the ratio with a wheel geometry: A = 1/(2 R_w), B = 1/(2 R_r) (flat tread)
    Rw = 0.41
    Rr = Rw * A_over_B                  # B = A / A_over_B  -> rail crown tighter
    N = 55e3
    c = hertz_contact(N, Rw, math.inf, Rr, E=E, nu=NU)
    a, b = c.semi_axis_x, c.semi_axis_y  # ellipse long along the rolling direction
    assert b / a == pytest.approx(k_ref, rel=1e-9)
    A, B = c.A, c.B
    Re = 1 / (2 * math.sqrt(A * B))
    delta_c = closed_form_circle(N, Re)[0]
    assert a / math.sqrt(a * b) == pytest.approx(a_over_c_ref, rel=1e-9)
    assert c.approach / delta_c == pytest.approx(d_ratio_ref, rel=1e-9)


def test_hertz_table_reference_values_are_plausible():
    # the oracle itself: known qualitative features of the Hertz table
    # (b/a ≈ (A/B)^(2/3) within a few %, δ/δ_c slightly below 1 and -> 1 at A = B)
    for r in (0.1, 0.5):
        k, _, d = hertz_table_row(r)
        assert k == pytest.approx(r ** (2 / 3), rel=0.05)
        assert 0.9 < d < 1.0
    k, a_c, d = hertz_table_row(1.0 - 1e-9)
    assert k == pytest.approx(1.0, abs=1e-4) and d == pytest.approx(1.0, abs=1e-8)


def test_ellipse_ratio_agrees_with_legendre_form():
    # scipy ellipk/ellipe (parameter m = e²) in Johnson's eq. 3.72 form
    for k in (0.05, 0.3, 0.7, 0.95):
        m = 1 - k * k
        K, Ee = ellipk(m), ellipe(m)
        ratio = (Ee / k**2 - K) / (K - Ee)
        assert hertz_ellipse_ratio(ratio) == pytest.approx(k, rel=1e-9)


def _boussinesq_displacement(x0, y0, ax, ay, p0, E_star, n_theta=256, n_rho=48):
    """Surface displacement at (x0, y0) under p0 sqrt(1 − x²/ax² − y²/ay²), by direct quadrature.

    u = 1/(π E*) ∬ p dA / r, evaluated in polar coordinates about (x0, y0)
    (the 1/r singularity cancels with the Jacobian), trapezoidal in θ
    (periodic, spectrally accurate) and Gauss–Legendre in ρ after ρ = ρe (1 − t²),
    which makes the square-root edge behaviour smooth.
    """
    th = np.linspace(0.0, 2 * np.pi, n_theta, endpoint=False)
    c, s = np.cos(th), np.sin(th)
    g = c**2 / ax**2 + s**2 / ay**2
    beta = x0 * c / ax**2 + y0 * s / ay**2
    q0 = 1.0 - x0**2 / ax**2 - y0**2 / ay**2
    rho_e = (-beta + np.sqrt(beta**2 + g * q0)) / g          # edge distance along θ
    t, w = np.polynomial.legendre.leggauss(n_rho)
    t, w = 0.5 * (t + 1.0), 0.5 * w                          # on [0, 1]
    rho = rho_e[:, None] * (1.0 - t[None, :] ** 2)
    Q = np.clip(q0 - 2 * beta[:, None] * rho - g[:, None] * rho**2, 0.0, None)
    inner = (p0 * np.sqrt(Q) * 2.0 * rho_e[:, None] * t[None, :]) @ w
    return inner.mean() * 2 * np.pi / (np.pi * E_star)


@pytest.mark.parametrize("Rwt, Rr", [
    (math.inf, 0.3),    # default: ellipse long in x
    (0.25, 0.3),        # convex tread, strongly elongated in x
    (-0.5, 0.3),        # hollow (concave) tread: lateral curvature < rolling -> long in y
    (math.inf, 0.05),   # B/A = 8.2
])
def test_pressure_reproduces_gap_by_direct_boussinesq_integration(Rwt, Rr):
    N, Rw = 55e3, 0.41
    c = hertz_contact(N, Rw, Rwt, Rr, E=E, nu=NU)
    ax, ay = c.semi_axis_x, c.semi_axis_y
    assert c.max_pressure == pytest.approx(3 * N / (2 * math.pi * ax * ay), rel=1e-12)
    # equilibrium: total load of the elliptical pressure = N
    assert 2 / 3 * math.pi * ax * ay * c.max_pressure == pytest.approx(N, rel=1e-12)
    A = 0.5 / Rw
    B = 0.5 * (1 / Rwt + 1 / Rr)
    if Rwt < 0:
        assert ay > ax
    u = lambda x, y: _boussinesq_displacement(x, y, ax, ay, c.max_pressure, E_STAR)  # noqa: E731
    assert u(0.0, 0.0) == pytest.approx(c.approach, rel=1e-9)
    # inside the contact the deformed surfaces conform: u = δ − A x² − B y²
    for fx, fy in [(0.5, 0.0), (0.0, 0.6), (0.4, -0.5), (-0.7, 0.3)]:
        x, y = fx * ax, fy * ay
        assert u(x, y) == pytest.approx(c.approach - A * x**2 - B * y**2, rel=1e-9)


# --------------------------------------------------------------------------- (3) load dependence
@pytest.mark.parametrize("geom", [(0.41, math.inf, 0.3), (0.41, 0.25, 0.3), (0.41, -0.5, 0.3)])
def test_stiffness_scales_as_cube_root_of_load(geom):
    k1 = hertz_stiffness(10e3, *geom)
    assert hertz_stiffness(80e3, *geom) == pytest.approx(2.0 * k1, rel=1e-12)
    assert hertz_stiffness(27e4, *geom) == pytest.approx(k1 * 27 ** (1 / 3), rel=1e-12)


def test_stiffness_is_derivative_of_load_approach_curve():
    N, h = 55e3, 1.0
    d = lambda n: hertz_contact(n, 0.41, -0.8, 0.3).approach  # noqa: E731
    k_fd = 2 * h / (d(N + h) - d(N - h))
    assert hertz_stiffness(N, 0.41, -0.8, 0.3) == pytest.approx(k_fd, rel=1e-7)


# --------------------------------------------------------------------------- (4) vehicle defaults
def test_default_vehicle_contact_stiffness_about_1e9():
    p = ContactParameters()
    k = p.stiffness()
    # thesis order of magnitude 1e9 N/m; value for 55 kN, R_w 0.41 m, flat tread, 0.3 m crown
    assert k == pytest.approx(1.1322e9, rel=1e-4)
    assert p.compliance() == pytest.approx(1 / k, rel=1e-14)
    c = p.contact()
    # realistic patch: ~11 mm x 9 mm, ~1 GPa peak pressure
    assert 2 * c.semi_axis_x == pytest.approx(11.2e-3, rel=0.01)
    assert 2 * c.semi_axis_y == pytest.approx(9.1e-3, rel=0.01)
    assert c.max_pressure == pytest.approx(1.03e9, rel=0.01)
    # equivalent-radius circular estimate is within a fraction of a percent for B/A = 1.37
    Re = 1 / (2 * math.sqrt(c.A * c.B))
    assert k == pytest.approx(1.5 * 55e3 / closed_form_circle(55e3, Re)[0], rel=5e-3)


# --------------------------------------------------------------------------- validation
@pytest.mark.parametrize("kwargs, param", [
    (dict(static_load_N=-1.0), "static_load_N"),
    (dict(static_load_N=0.0), "static_load_N"),
    (dict(static_load_N=float("nan")), "static_load_N"),
    (dict(wheel_rolling_radius=-0.41), "wheel_rolling_radius"),
    (dict(wheel_rolling_radius=math.inf), "wheel_rolling_radius"),
    (dict(wheel_transverse_radius=0.0), "wheel_transverse_radius"),
    (dict(wheel_transverse_radius=-0.2), "wheel_transverse_radius"),  # concave tighter than crown
    (dict(rail_head_radius=-0.3), "rail_head_radius"),
    (dict(rail_head_radius="wide"), "rail_head_radius"),
    (dict(E=0.0), "E"),
    (dict(nu=0.5), "nu"),
    (dict(nu_rail=0.7), "nu_rail"),
    (dict(E_rail=-1.0), "E_rail"),
])
def test_bad_input_raises_naming_parameter(kwargs, param):
    args = dict(static_load_N=55e3, wheel_rolling_radius=0.41,
                wheel_transverse_radius=math.inf, rail_head_radius=0.3)
    args.update(kwargs)
    with pytest.raises(ContactParameterError, match=repr(param)) as info:
        hertz_stiffness(**args)
    assert info.value.parameter == param
    assert isinstance(info.value, ValueError)


def test_contact_parameters_validate_on_construction():
    with pytest.raises(ContactParameterError, match="ContactParameters.wheel_load_N"):
        ContactParameters(wheel_load_N=-5.0)
    with pytest.raises(ContactParameterError, match="curvature_ratio"):
        hertz_ellipse_ratio(0.0)
