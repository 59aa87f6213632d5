"""Linearised Hertzian wheel–rail contact stiffness (thesis §2.2, eqs. 2.1–2.11).

The thesis treats the normal wheel–rail contact "within Hertz framework"
(Knothe & Stichel, ref. [23]) as a linear spring of stiffness ``k_H`` about
the static wheel load. Its compliance ``1/k_H`` enters every transfer
function: eq. 2.5/2.6 (half wheelset — the thesis writes ``K_H`` there where
``1/K_H`` is meant, see ``shared/DESIGN.md``), eqs. 2.8–2.11 (full vertical
wheelset) and the matrix ``[A_H,n]`` of eq. 2.20/2.22.

Geometry and sign convention
----------------------------
Axes follow the project convention: ``x`` along the track (rolling
direction), ``y`` lateral. Near the contact point the two surfaces are
approximated by their principal radii, with the principal directions of
wheel and rail aligned (no yaw angle between them):

========================  ===============================  =================
body                      rolling direction ``x``          lateral ``y``
========================  ===============================  =================
wheel                     rolling radius ``R_w``           transverse profile radius ``R_wt``
rail                      ∞ (straight rail)                head (crown) radius ``R_r``
========================  ===============================  =================

A radius is **positive when the surface is convex** at the contact (its
centre of curvature lies inside the body, as for the wheel rolling circle and
the rail crown) and **negative when it is concave** (centre of curvature
outside the body, e.g. a hollow-worn tread or the S1002 tread near the
flange root). ``numpy.inf`` means flat in that direction: a conical or
cylindrical tread has ``R_wt = inf``; the S1002 tread near the nominal rolling
circle is nearly straight (|R_wt| of metres), which is why the default is
``inf``. The gap between the undeformed surfaces is ``h = A x² + B y²`` with

    A = (1/R_w + 0) / 2,        B = (1/R_wt + 1/R_r) / 2,

and Hertz theory needs ``A > 0`` and ``B > 0`` (non-conformal contact); a
concave wheel radius tighter than the rail crown radius makes ``B <= 0`` and is
rejected.

Hertz solution
--------------
With ``p = (b/a)^2 = 1 - e^2`` (``a`` the semi-axis along the direction of the
*smaller* relative curvature, ``e`` the eccentricity) and the complete elliptic
integrals of modulus ``e`` written in Carlson's symmetric form,
``K(e) = R_F(0, p, 1)`` and ``K(e) - E(e) = (e^2/3) R_D(0, p, 1)``
(DLMF 19.25.1), the classical relations (Johnson, *Contact Mechanics*,
eqs. 3.69–3.72; Timoshenko & Goodier §140) become

    B_max / A_min = [ (a/b)^2 E(e) - K(e) ] / [ K(e) - E(e) ]
                  = ( 3 R_F / R_D - 1 ) / p,
    a^3   = N R_D(0, p, 1) / (2 π A_min E*),      b = a sqrt(p),
    δ     = 3 N K(e) / (2 π a E*),                p0 = 3 N / (2 π a b),
    1/E*  = (1 - ν_w^2)/E_w + (1 - ν_r^2)/E_r,

so no difference ``K - E`` is ever formed by subtraction (accurate down to the
circular limit). ``δ`` is the mutual approach, ``δ ∝ N^(2/3)``; hence the
linearised stiffness about the static load is exactly

    k_H = dN/dδ = (3/2) N / δ        (∝ N^(1/3)),

and the compliance used in eqs. 2.5–2.11 is ``1/k_H``.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq
from scipy.special import elliprd, elliprf

__all__ = [
    "ContactParameterError",
    "HertzContact",
    "ContactParameters",
    "effective_modulus",
    "hertz_ellipse_ratio",
    "hertz_contact",
    "hertz_stiffness",
    "hertz_compliance",
]

logger = logging.getLogger("receptance")

#: Default steel properties (wheel and rail), Pa and -.
STEEL_E = 206e9
STEEL_NU = 0.28


class ContactParameterError(ValueError):
    """A contact input (load, radius, elastic constant) is out of its allowed range.

    Attributes
    ----------
    parameter : str
        Name of the offending parameter.
    value : object
        The value received.
    expected : str
        What was expected.
    """

    def __init__(self, parameter: str, value, expected: str):
        super().__init__(f"Hertz contact parameter {parameter!r}: expected {expected}, got {value!r}")
        self.parameter = parameter
        self.value = value
        self.expected = expected


# ----------------------------------------------------------------------------- validation
def _finite_positive(name: str, value) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ContactParameterError(name, value, "a real number") from None
    if not (math.isfinite(v) and v > 0.0):
        raise ContactParameterError(name, value, "a finite number > 0")
    return v


def _radius(name: str, value, *, allow_negative: bool) -> float:
    """Validate a radius (m); return it. ``inf`` (flat) is allowed, 0 and NaN are not."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ContactParameterError(name, value, "a radius in m (float, numpy.inf for flat)") from None
    if math.isnan(v) or v == 0.0:
        raise ContactParameterError(name, value, "a non-zero radius in m (numpy.inf for flat)")
    if v < 0.0 and not allow_negative:
        raise ContactParameterError(name, value, "a positive (convex) radius in m or numpy.inf")
    if v == -math.inf:
        raise ContactParameterError(name, value, "+inf for a flat surface, not -inf")
    return v


def _poisson(name: str, value) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ContactParameterError(name, value, "a Poisson ratio (float)") from None
    if not (-1.0 < v < 0.5):
        raise ContactParameterError(name, value, "a Poisson ratio in (-1, 0.5)")
    return v


def effective_modulus(E_wheel: float = STEEL_E, nu_wheel: float = STEEL_NU,
                      E_rail: float | None = None, nu_rail: float | None = None) -> float:
    """Contact modulus ``E*`` of the wheel–rail pair (Pa).

    ``1/E* = (1 - ν_w²)/E_w + (1 - ν_r²)/E_r``; for identical materials
    ``E* = E / (2 (1 - ν²))``.

    Parameters
    ----------
    E_wheel, nu_wheel : float
        Young's modulus (Pa) and Poisson ratio of the wheel.
    E_rail, nu_rail : float, optional
        Same for the rail; default to the wheel values.

    Returns
    -------
    float
        ``E*`` in Pa.
    """
    E_w = _finite_positive("E", E_wheel)
    nu_w = _poisson("nu", nu_wheel)
    E_r = E_w if E_rail is None else _finite_positive("E_rail", E_rail)
    nu_r = nu_w if nu_rail is None else _poisson("nu_rail", nu_rail)
    return 1.0 / ((1.0 - nu_w**2) / E_w + (1.0 - nu_r**2) / E_r)


# ----------------------------------------------------------------------------- ellipticity
def _curvature_ratio(p: float) -> float:
    """``B_max/A_min`` as a function of ``p = (b/a)^2`` (Carlson form, no cancellation)."""
    rf = elliprf(0.0, p, 1.0)
    rd = elliprd(0.0, p, 1.0)
    return (3.0 * rf / rd - 1.0) / p


def hertz_ellipse_ratio(curvature_ratio: float) -> float:
    """Aspect ratio ``b/a <= 1`` of the Hertz contact ellipse for a relative-curvature ratio.

    Solves ``B/A = [(a/b)² E(e) − K(e)] / [K(e) − E(e)]`` (Johnson eq. 3.72)
    for ``e = sqrt(1 − (b/a)²)``, where ``B >= A`` are the relative
    curvatures along the minor and major ellipse axes.

    Parameters
    ----------
    curvature_ratio : float
        ``B/A`` or ``A/B`` (the larger over the smaller is used); must be
        finite and > 0.

    Returns
    -------
    float
        ``b/a`` in (0, 1]; 1 for a circular contact.
    """
    r = _finite_positive("curvature_ratio", curvature_ratio)
    r = max(r, 1.0 / r)
    if r == 1.0:
        return 1.0
    # (b/a)^2 ≈ r^(-4/3) for moderate r; bracket generously on a log scale.
    f = lambda logp: math.log(_curvature_ratio(math.exp(logp))) - math.log(r)  # noqa: E731
    hi = 0.0
    lo = -2.0 * math.log(r) - 5.0
    while f(lo) < 0.0:  # ratio is decreasing in p; push lo down until ratio(p_lo) > r
        lo *= 2.0
        if lo < -1400.0:
            raise ContactParameterError("curvature_ratio", curvature_ratio,
                                        "a ratio the Hertz ellipse can represent (< ~1e300)")
    logp = brentq(f, lo, hi, xtol=1e-15, rtol=4 * np.finfo(float).eps, maxiter=200)
    return math.exp(0.5 * logp)


# ----------------------------------------------------------------------------- solution
@dataclass(frozen=True)
class HertzContact:
    """Hertz solution for one wheel–rail contact at the static load.

    Attributes
    ----------
    load : float
        Normal load ``N`` (N).
    semi_axis_x, semi_axis_y : float
        Contact-ellipse semi-axes along the rolling direction ``x`` and
        laterally ``y`` (m).
    approach : float
        Mutual approach ``δ`` of distant points of wheel and rail (m).
    max_pressure : float
        Peak pressure ``p0 = 3N/(2π a b)`` (Pa).
    eccentricity : float
        ``e = sqrt(1 − (b/a)²)`` with ``b <= a``.
    A, B : float
        Relative curvatures along ``x`` and ``y`` (1/m): gap ``h = A x² + B y²``.
    E_star : float
        Contact modulus (Pa).
    """

    load: float
    semi_axis_x: float
    semi_axis_y: float
    approach: float
    max_pressure: float
    eccentricity: float
    A: float
    B: float
    E_star: float

    @property
    def stiffness(self) -> float:
        """Linearised normal stiffness ``k_H = dN/dδ = 1.5 N/δ`` (N/m)."""
        return 1.5 * self.load / self.approach

    @property
    def compliance(self) -> float:
        """Linearised normal compliance ``1/k_H`` (m/N), the term of eqs. 2.5–2.11."""
        return 1.0 / self.stiffness


def hertz_contact(static_load_N: float, wheel_rolling_radius: float,
                  wheel_transverse_radius: float = math.inf, rail_head_radius: float = 0.3, *,
                  E: float = STEEL_E, nu: float = STEEL_NU,
                  E_rail: float | None = None, nu_rail: float | None = None) -> HertzContact:
    """Full Hertz solution (ellipse, approach, pressure) of a wheel on a rail.

    Parameters
    ----------
    static_load_N : float
        Static normal wheel load ``N`` (N), > 0.
    wheel_rolling_radius : float
        Wheel rolling radius ``R_w`` (m), > 0 (curvature in the rolling direction).
    wheel_transverse_radius : float, default inf
        Transverse radius of the wheel tread profile ``R_wt`` (m); positive
        convex, negative concave, ``inf`` for a straight (conical) tread.
    rail_head_radius : float, default 0.3
        Transverse radius of the rail head crown ``R_r`` (m), > 0 or ``inf``
        (0.3 m is the 50E5 crown radius). The rail's longitudinal radius is ∞.
    E, nu : float
        Young's modulus (Pa) and Poisson ratio of the wheel (and of the rail
        unless ``E_rail`` / ``nu_rail`` are given).
    E_rail, nu_rail : float, optional
        Rail material, if different.

    Returns
    -------
    HertzContact

    Raises
    ------
    ContactParameterError
        Non-positive or non-finite load/modulus, Poisson ratio outside
        (−1, 0.5), zero/NaN radius, or a geometry whose relative curvature is
        not positive in both directions (conformal or separating surfaces).
    """
    N = _finite_positive("static_load_N", static_load_N)
    Rw = _radius("wheel_rolling_radius", wheel_rolling_radius, allow_negative=False)
    if math.isinf(Rw):
        raise ContactParameterError("wheel_rolling_radius", wheel_rolling_radius, "a finite radius in m")
    Rwt = _radius("wheel_transverse_radius", wheel_transverse_radius, allow_negative=True)
    Rr = _radius("rail_head_radius", rail_head_radius, allow_negative=False)
    E_star = effective_modulus(E, nu, E_rail, nu_rail)

    A = 0.5 * (1.0 / Rw)                    # rail is straight along x
    B = 0.5 * (1.0 / Rwt + 1.0 / Rr)
    if not B > 0.0:
        raise ContactParameterError(
            "wheel_transverse_radius", wheel_transverse_radius,
            f"a transverse geometry with positive relative curvature 1/R_wt + 1/R_r > 0 "
            f"(non-conformal Hertz contact); with rail_head_radius={Rr!r} a concave wheel "
            f"needs |R_wt| > R_r")

    A_min, B_max = min(A, B), max(A, B)
    k = hertz_ellipse_ratio(B_max / A_min)   # b/a
    p = k * k
    rf = float(elliprf(0.0, p, 1.0))         # K(e)
    rd = float(elliprd(0.0, p, 1.0))         # 3 (K - E) / e^2
    a = (N * rd / (2.0 * math.pi * A_min * E_star)) ** (1.0 / 3.0)
    b = a * k
    delta = 3.0 * N * rf / (2.0 * math.pi * a * E_star)
    p0 = 3.0 * N / (2.0 * math.pi * a * b)
    ax, ay = (a, b) if A <= B else (b, a)
    out = HertzContact(load=N, semi_axis_x=ax, semi_axis_y=ay, approach=delta, max_pressure=p0,
                       eccentricity=math.sqrt(max(0.0, 1.0 - p)), A=A, B=B, E_star=E_star)
    logger.debug("Hertz contact N=%.4g N: a_x=%.4g m a_y=%.4g m delta=%.4g m k_H=%.4g N/m",
                 N, ax, ay, delta, out.stiffness)
    return out


def hertz_stiffness(static_load_N: float, wheel_rolling_radius: float,
                    wheel_transverse_radius: float = math.inf, rail_head_radius: float = 0.3, *,
                    E: float = STEEL_E, nu: float = STEEL_NU,
                    E_rail: float | None = None, nu_rail: float | None = None) -> float:
    """Linearised Hertzian normal contact stiffness ``k_H`` (N/m) at the static load.

    ``k_H = dN/dδ = (3/2) N/δ`` with the Hertz approach ``δ`` of
    :func:`hertz_contact`; it is the ``K_H`` / ``k_H`` of thesis
    eqs. 1.12, 2.5–2.11 and 2.20 (whose compliance is ``1/k_H``).
    Parameters as for :func:`hertz_contact`.

    Returns
    -------
    float
        ``k_H`` in N/m (≈1.1e9 N/m for :class:`ContactParameters` defaults).
    """
    return hertz_contact(static_load_N, wheel_rolling_radius, wheel_transverse_radius,
                         rail_head_radius, E=E, nu=nu, E_rail=E_rail, nu_rail=nu_rail).stiffness


def hertz_compliance(static_load_N: float, wheel_rolling_radius: float,
                     wheel_transverse_radius: float = math.inf, rail_head_radius: float = 0.3, *,
                     E: float = STEEL_E, nu: float = STEEL_NU,
                     E_rail: float | None = None, nu_rail: float | None = None) -> float:
    """Linearised Hertzian contact compliance ``1/k_H`` (m/N).

    This is the term added to the wheel and rail receptances in eqs. 2.5/2.6
    (where the thesis misprints it as ``K_H``), 2.9 and 2.11. Parameters as
    for :func:`hertz_contact`.
    """
    return 1.0 / hertz_stiffness(static_load_N, wheel_rolling_radius, wheel_transverse_radius,
                                 rail_head_radius, E=E, nu=nu, E_rail=E_rail, nu_rail=nu_rail)


# ----------------------------------------------------------------------------- vehicle defaults
@dataclass(frozen=True)
class ContactParameters:
    """Wheel–rail contact inputs for the thesis vehicle (trailing wheelset of a *Meneghino*).

    Defaults
    --------
    wheel_load_N = 55e3
        Static wheel load: a metro car axle load of about 11.2 t (wheelset
        included) shared by two wheels, 11.2e3 kg × 9.81 m/s² / 2 ≈ 55 kN.
        The thesis does not state the load; this is an assumption.
    wheel_rolling_radius = 0.41
        Table 2.1 lists "wheel nominal diameter (new), R_w = 0.41 m"; the
        symbol and value are a radius (820 mm new wheel), used as such. The
        field estimator replaces it by its nominal wheel radius (the
        wheelset model's rolling radius or a measured one,
        :func:`estimator.workflow.with_wheel_radius`).
    wheel_transverse_radius = inf
        ORE S1002 tread (Table 2.1) near the nominal rolling circle is almost
        straight; a worn, hollow tread would be a negative (concave) radius.
    rail_head_radius = 0.3
        50E5 rail crown radius (EN 13674-1, Table 2.2 rail).
    E_wheel = E_rail = 206e9, nu_wheel = nu_rail = 0.28
        Wheel and rail steel.

    With these values ``k_H ≈ 1.14e9 N/m`` (thesis order of magnitude 1e9 N/m).
    """

    wheel_load_N: float = 55e3
    wheel_rolling_radius: float = 0.41
    wheel_transverse_radius: float = math.inf
    rail_head_radius: float = 0.3
    E_wheel: float = STEEL_E
    nu_wheel: float = STEEL_NU
    E_rail: float = STEEL_E
    nu_rail: float = STEEL_NU

    def __post_init__(self):
        # Validate eagerly so a bad parameter set fails where it is built, naming the field.
        names = {"static_load_N": "wheel_load_N", "E": "E_wheel", "nu": "nu_wheel"}
        try:
            self.contact()
        except ContactParameterError as err:
            field = names.get(err.parameter, err.parameter)
            raise ContactParameterError(f"ContactParameters.{field}", err.value, err.expected) from err

    def contact(self) -> HertzContact:
        """Hertz solution for these parameters (see :func:`hertz_contact`)."""
        return hertz_contact(self.wheel_load_N, self.wheel_rolling_radius,
                             self.wheel_transverse_radius, self.rail_head_radius,
                             E=self.E_wheel, nu=self.nu_wheel, E_rail=self.E_rail, nu_rail=self.nu_rail)

    def stiffness(self) -> float:
        """Linearised Hertzian stiffness ``k_H`` (N/m)."""
        return self.contact().stiffness

    def compliance(self) -> float:
        """Linearised Hertzian compliance ``1/k_H`` (m/N)."""
        return self.contact().compliance
