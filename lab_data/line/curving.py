"""Contact-plane angles per wheel from a quasi-static curving model.

The wheel–rail contact plane tilts with the lateral position of the wheelset
on the rails: on straight track both wheels touch the rail crown on the tread
(a couple of degrees: the 1:40 rail inclination and the tread cone); in a
curve the wheelset shifts towards the high rail, the outer wheel's contact
climbs towards the flange root, the inner wheel's moves out on the tread.

**Model (stated, deterministic).** The lateral shift of each wheelset towards
the curve's outer rail is

.. math::

    y = \\frac{r_0 b_0 |\\kappa|}{\\lambda_e} \\pm y_\\psi \\frac{|\\kappa|}{\\kappa_{ref}}
        + C_{cd}\\,a_{nc}, \\qquad a_{nc} = v^2 |\\kappa| - g\\,\\phi

— the pure-rolling shift of a wheelset of equivalent conicity λ_e in a curve
of curvature κ (Wickens; ``r_0`` rolling radius, ``b_0`` half the contact
spacing), the yaw constraint of the bogie frame pushing the leading wheelset
out and the trailing one in (``y_ψ`` at ``κ_ref`` = 1/400 m⁻¹, proportional to
the curvature), and the quasi-static answer to the cant deficiency ``a_nc``
(``φ`` the cant angle) through the gravitational stiffness (``C_cd``). Each
wheel's contact angle γ is then read from the contact-angle function of the
wheel/rail pair, γ(y) with y the shift towards that wheel's flange:
:data:`CONTACT_ANGLE_TABLE` has the shape of the S1002 wheel on a 1:40 inclined
50E5/UIC60 head (tread 1–5°, the flange root from about 6 mm, the flange flank
near 70° at 8–9 mm, where the flange clearance is used up), interpolated
monotonically. The outer wheel reads γ(y), the inner wheel γ(−y).

**Sign.** γ ≥ 0 means the normal of the contact plane, on the wheel, tilts
towards the track centre (the rail pushes the wheel back in). In the
wheelset frame of thesis eq. 2.12 (normal ``(-sin θ, cos θ)`` in y–z, left
wheel at −y) this is ``θ_R = +γ_R`` and ``θ_L = −γ_L``:
:func:`thesis_angles` converts.

Scenario ``contact_angle`` narrows the gauge on the curves (the outer rail's
gauge face moved in by ``gauge_narrowing_m``): the outer wheels reach their
flange root earlier, which puts the curve angles far from this default.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from scipy.interpolate import PchipInterpolator

from .geometry import Line, cant_angle, curvature

__all__ = ["CONTACT_ANGLE_TABLE", "CurvingParameters", "contact_angle_deg", "wheelset_shift", "rail_contact_angles",
           "thesis_angles"]

G = 9.80665

#: (shift towards this wheel's flange [mm], contact angle [deg]) — S1002 on 1:40 inclined 50E5, shape of the
#: published contact-angle functions; flange clearance ~7.5 mm.
CONTACT_ANGLE_TABLE = (
    (-10.0, 0.6), (-6.0, 0.9), (-3.0, 1.2), (0.0, 1.6), (2.0, 2.2), (4.0, 3.3), (5.0, 4.5), (5.5, 6.0),
    (6.0, 9.0), (6.5, 17.0), (7.0, 35.0), (7.5, 55.0), (8.0, 65.0), (9.0, 70.0), (20.0, 70.0),
)

_GAMMA = PchipInterpolator(np.array([p[0] for p in CONTACT_ANGLE_TABLE]) * 1e-3,
                           np.radians([p[1] for p in CONTACT_ANGLE_TABLE]), extrapolate=False)


@dataclass(frozen=True)
class CurvingParameters:
    """Parameters of the quasi-static shift (see the module docstring)."""

    rolling_radius_m: float = 0.41
    half_contact_spacing_m: float = 0.75
    equivalent_conicity: float = 0.2
    yaw_shift_m: float = 1.0e-3  # leading +, trailing - at R = 400 m
    yaw_shift_ref_curvature: float = 1.0 / 400.0
    cant_deficiency_compliance: float = 4.0e-3  # m of shift per m/s^2 of cant deficiency
    gauge_narrowing_m: float = 0.0  # scenario contact_angle: outer rail's gauge face moved in, on curves only

    def parameters(self) -> dict:
        return asdict(self)


def contact_angle_deg(shift_m: np.ndarray) -> np.ndarray:
    """Contact angle [deg] of a wheel shifted ``shift_m`` towards its own flange (table, monotone interpolation)."""
    y = np.clip(np.asarray(shift_m, float), CONTACT_ANGLE_TABLE[0][0] * 1e-3, CONTACT_ANGLE_TABLE[-1][0] * 1e-3)
    return np.degrees(_GAMMA(y))


def wheelset_shift(line: Line, s: np.ndarray, speed: np.ndarray, leading: np.ndarray,
                   p: CurvingParameters = CurvingParameters()) -> np.ndarray:
    """Signed lateral shift [m] of a wheelset at chainage ``s``, positive towards rail ``R``.

    Parameters
    ----------
    s, speed : array
        Chainage of the wheelset and the train's speed [m/s] (any sign of travel).
    leading : array of bool
        Whether this wheelset leads the bogie (decided by the travel direction).
    """
    k = curvature(line, s)
    ak = np.abs(k)
    a_nc = np.asarray(speed, float) ** 2 * ak - G * cant_angle(line, s)
    yaw = np.where(leading, 1.0, -1.0) * p.yaw_shift_m * ak / p.yaw_shift_ref_curvature
    out = p.rolling_radius_m * p.half_contact_spacing_m * ak / p.equivalent_conicity + yaw \
        + p.cant_deficiency_compliance * a_nc * (ak > 0)
    # left curve: the outer rail is R (+); right curve: L (-)
    return np.sign(k) * out


def rail_contact_angles(line: Line, s: np.ndarray, speed: np.ndarray, leading: np.ndarray,
                        p: CurvingParameters = CurvingParameters()) -> tuple[np.ndarray, np.ndarray]:
    """Contact angles γ [rad] (module sign) of the wheels running on rail L and on rail R.

    On a curve the outer rail's gauge face may be moved in by ``p.gauge_narrowing_m`` (scenario): the outer
    wheel then sees its flange that much earlier.
    """
    y = wheelset_shift(line, s, speed, leading, p)
    k = curvature(line, s)
    narrow = p.gauge_narrowing_m * (np.abs(k) > 0)
    # the wheel on R is shifted towards its flange by +y, the wheel on L by -y
    outer_r = k > 0
    g_r = contact_angle_deg(y + np.where(outer_r, narrow, 0.0))
    g_l = contact_angle_deg(-y + np.where(~outer_r & (k < 0), narrow, 0.0))
    return np.radians(g_l), np.radians(g_r)


def thesis_angles(gamma_left: np.ndarray, gamma_right: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Module-sign angles -> thesis eq. 2.12 angles ``(θ_L, θ_R) = (−γ_L, +γ_R)``."""
    return -np.asarray(gamma_left), np.asarray(gamma_right)
