"""Wheel-web springs of a rim-on-web wheel model, from plate theory.

A rotor-dynamics design model does not mesh the wheel web: it treats the rim
as a rigid body joined to the hub by six springs (two radial, one axial, two
rocking, one torsional) and lumps the web's mass on the hub and the rim. A
designer computes the springs from the web as an annular plate of inner
radius ``a`` (the hub), outer radius ``b`` (the rim) and thickness ``t``,
clamped in a rigid hub and in a rigid rim:

* **axial** (rim moves along the axle, ``n = 0``): Kirchhoff plate,
  ``w = C1 + C2 r^2 + C3 ln r + C4 r^2 ln r`` with ``w(a) = w'(a) = 0``,
  ``w(b) = delta``, ``w'(b) = 0`` (the rim is guided: it does not tilt);
  the total edge shear is ``|2 pi r Q_r| = 8 pi D |C4|``, so
  ``k_axial = 8 pi D |C4| / delta`` (Timoshenko & Woinowsky-Krieger,
  *Theory of Plates and Shells*, 1959, §18–19).
* **rocking** (rim tilts about a diameter, ``n = 1``):
  ``w = W(r) cos(theta)``, ``W = A r + B r^3 + C / r + D r ln r``
  (the ``n = 1`` biharmonic solution, ibid. §62) with ``W(a) = W'(a) = 0``,
  ``W(b) = phi b``, ``W'(b) = phi``; the stiffness is twice the strain
  energy for ``phi = 1``.
* **torsional** (rim turns about the axle in its plane): the Lamé shear
  annulus, ``k_t = 4 pi G t / (1/a^2 - 1/b^2)`` (exact in plane stress).
* **radial** (rim shifted in its plane): a Ritz estimate with the
  displacement field ``u = delta ln(r/a) / ln(b/a)`` along the shift,
  ``k_r = pi t (E / (1 - nu^2) + G) / ln(b/a)`` (an upper bound; the radial
  modes lie far above the test band, where only its order of magnitude
  matters).

The web's mass is shared between the rim body and the hub by Rayleigh's
principle: the rim body carries the web mass that the static deflection
shape of each motion makes move with it (kinetic-energy equivalent,
``int rho t (w / w_rim)^2 dA``) — from the axial shape for its mass, the
rocking shape for its diametral inertia and the torsion shape for its polar
inertia; the hub keeps the rest of the wheel.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .fe_model import Material

__all__ = ["WebSprings", "RimBody", "web_springs", "rim_body", "wheel_inertia"]

_N_GAUSS = 64


@dataclass(frozen=True)
class WebSprings:
    """Stiffness of the web between hub and rigid rim.

    Attributes
    ----------
    axial : float
        Rim translation along the axle [N/m].
    radial : float
        Rim translation in its plane, per direction [N/m].
    rocking : float
        Rim rotation about a diameter [N m/rad].
    torsional : float
        Rim rotation about the axle [N m/rad].
    """

    axial: float
    radial: float
    rocking: float
    torsional: float

    def global_values(self) -> tuple[float, float, float, float, float, float]:
        """The six spring values along x, y, z, rx, ry, rz for a wheel whose axis is y."""
        return (self.radial, self.axial, self.radial, self.rocking, self.torsional, self.rocking)


@dataclass(frozen=True)
class RimBody:
    """The rigid rim body: rim plus the web mass moving with it (Rayleigh), about the rim centre.

    Attributes
    ----------
    mass : float [kg]
    diametral : float
        Moment of inertia about a diameter [kg m^2].
    polar : float
        Moment of inertia about the wheel axis [kg m^2].
    """

    mass: float
    diametral: float
    polar: float


def _plate_rigidity(material: Material, t: float) -> float:
    return material.E * t**3 / (12 * (1 - material.nu**2))


def _check_annulus(a: float, b: float, t: float) -> None:
    if not 0 < a < b or t <= 0:
        raise ValueError(f"web needs 0 < inner radius < outer radius and a positive thickness, got a={a!r}, "
                         f"b={b!r}, t={t!r}")


def _axial_shape(a: float, b: float) -> np.ndarray:
    """Coefficients C1..C4 of the clamped–guided annular plate with unit rim deflection."""

    def row(r, d):
        if d == 0:
            return [1.0, r**2, np.log(r), r**2 * np.log(r)]
        return [0.0, 2 * r, 1 / r, 2 * r * np.log(r) + r]

    A = np.array([row(a, 0), row(a, 1), row(b, 0), row(b, 1)])
    return np.linalg.solve(A, [0.0, 0.0, 1.0, 0.0])


def _rocking_shape(a: float, b: float) -> np.ndarray:
    """Coefficients of ``W = A r + B r^3 + C/r + D r ln r`` for a unit rim tilt."""

    def row(r, d):
        if d == 0:
            return [r, r**3, 1 / r, r * np.log(r)]
        return [1.0, 3 * r**2, -1 / r**2, np.log(r) + 1]

    A = np.array([row(a, 0), row(a, 1), row(b, 0), row(b, 1)])
    return np.linalg.solve(A, [0.0, 0.0, b, 1.0])


def _gauss(a: float, b: float) -> tuple[np.ndarray, np.ndarray]:
    x, w = np.polynomial.legendre.leggauss(_N_GAUSS)
    return 0.5 * (b - a) * x + 0.5 * (b + a), 0.5 * (b - a) * w


def web_springs(a: float, b: float, t: float, material: Material) -> WebSprings:
    """The six web springs of an annular web clamped in a rigid hub (radius ``a``) and a rigid rim (``b``).

    Parameters
    ----------
    a, b : float
        Inner (hub) and outer (rim) radius of the web [m].
    t : float
        Web thickness [m].
    material : Material

    Returns
    -------
    WebSprings
    """
    _check_annulus(a, b, t)
    D = _plate_rigidity(material, t)
    nu = material.nu
    c = _axial_shape(a, b)
    axial = 8 * np.pi * D * abs(c[3])

    A, B, C, Dd = _rocking_shape(a, b)
    r, w = _gauss(a, b)
    W = A * r + B * r**3 + C / r + Dd * r * np.log(r)
    W1 = A + 3 * B * r**2 - C / r**2 + Dd * (np.log(r) + 1)
    W2 = 6 * B * r + 2 * C / r**3 + Dd / r
    g = W1 / r - W / r**2  # curvature terms of w = W cos(theta): k_tt = g cos, k_rt = -g sin
    # U = (pi D / 2) int [W''^2 + g^2 + 2 nu W'' g + 2 (1 - nu) g^2] r dr, and k = 2 U for a unit tilt
    rocking = np.pi * D * np.sum(w * (W2**2 + g**2 + 2 * nu * W2 * g + 2 * (1 - nu) * g**2) * r)

    torsional = 4 * np.pi * material.G * t / (1 / a**2 - 1 / b**2)
    radial = np.pi * t * (material.E / (1 - nu**2) + material.G) / np.log(b / a)
    return WebSprings(float(axial), float(radial), float(rocking), float(torsional))


def rim_body(a: float, b: float, t: float, material: Material, rim_mass: float, rim_radial: float,
             rim_axial: float) -> RimBody:
    """Mass and inertia of the rigid rim body: a rectangular-section ring plus the web mass moving with it.

    Parameters
    ----------
    a, b, t, material
        The web, as for :func:`web_springs`; ``b`` is also the rim's centroid radius.
    rim_mass : float
        Mass of the rim ring [kg].
    rim_radial, rim_axial : float
        Radial and axial size of the rim section [m].

    Returns
    -------
    RimBody
    """
    _check_annulus(a, b, t)
    rho_t = material.rho * t
    r, w = _gauss(a, b)
    c = _axial_shape(a, b)
    w_axial = c[0] + c[1] * r**2 + c[2] * np.log(r) + c[3] * r**2 * np.log(r)
    m_web = 2 * np.pi * rho_t * np.sum(w * w_axial**2 * r)
    A, B, C, Dd = _rocking_shape(a, b)
    W = A * r + B * r**3 + C / r + Dd * r * np.log(r)
    i_diam_web = np.pi * rho_t * np.sum(w * W**2 * r)  # out-of-plane motion W(r) cos(theta) per unit tilt
    u_t = r * (1 / a**2 - 1 / r**2) / (1 / a**2 - 1 / b**2)  # Lamé tangential displacement per unit rim turn
    i_polar_web = 2 * np.pi * rho_t * np.sum(w * u_t**2 * r)
    h, L = rim_radial, rim_axial
    i_polar_rim = rim_mass * (b**2 + h**2 / 4)
    i_diam_rim = rim_mass * (b**2 / 2 + h**2 / 8 + L**2 / 12)
    return RimBody(float(rim_mass + m_web), float(i_diam_rim + i_diam_web), float(i_polar_rim + i_polar_web))


def wheel_inertia(masses_and_radii: list[tuple[float, float, float, float]]) -> tuple[float, float, float]:
    """Mass, diametral and polar inertia of coaxial rings about their common centre.

    Parameters
    ----------
    masses_and_radii : list of (mass, inner radius, outer radius, axial length)
        Thick rings (a disc has inner radius 0), all centred on the same plane.

    Returns
    -------
    (mass, diametral, polar) : tuple of float
        ``I_polar = m (ri^2 + ro^2) / 2``, ``I_diam = m ((ri^2 + ro^2) / 4 + L^2 / 12)``.
    """
    m = sum(p[0] for p in masses_and_radii)
    polar = sum(mm * (ri**2 + ro**2) / 2 for mm, ri, ro, _ in masses_and_radii)
    diam = sum(mm * ((ri**2 + ro**2) / 4 + L**2 / 12) for mm, ri, ro, L in masses_and_radii)
    return float(m), float(diam), float(polar)
