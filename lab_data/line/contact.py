"""Wheel–rail normal contact: non-linear Hertz spring along each contact plane's normal.

**Law.** ``F = C_H δ^{3/2}`` for a compression ``δ > 0``, ``F = 0`` (contact lost, flagged) otherwise. The
thesis (§2.2) linearises it into ``K_H``; the line keeps it non-linear, so that a deep corrugation trough
lifts the wheel off the rail.

**Constant.** Hertz theory for the wheel (rolling radius ``R_w`` along the track, a conical tread across)
on the rail head (crown radius ``R_r`` across the track): relative curvatures
``A = 1/(2 R_w)``, ``B = 1/(2 R_r)``, equivalent radius ``R_e = 1/(2 sqrt(AB))``, contact modulus
``E* = E / (2 (1 − ν²))`` for two steel bodies, and (Johnson, *Contact Mechanics*, 1985, eq. 4.36 with
the ellipticity correction ``F₂``)

.. math::

    C_H = \\frac{4}{3} E^* \\sqrt{R_e}\\; F_2^{-3/2}, \\qquad
    F_2 = 1 - \\left[(B/A)^{0.0602} - 1\\right]^{1.456}.

For ``R_w = 0.41 m`` and ``R_r = 0.30 m``: ``C_H ≈ 8.97e10 N/m^1.5``; at a 40 kN wheel load the linearised
stiffness ``K_H = 1.5 C_H^{2/3} F^{1/3}`` is about 1.0 GN/m.

**Direction and sign (thesis eq. 2.12, Fig. 2.7).** Each wheel's contact plane is tilted by its angle θ
in the wheelset's y–z plane; the contact normal on the wheel is ``n = (−sin θ, cos θ)`` in (y, z) — the
second column of ``Λ(θ)`` of eq. 2.12. θ > 0 tilts the normal towards −y, so on the right wheel (+y) a
positive angle points into the track (flange side), on the left wheel a negative one does. The rail
pushes the wheel with ``+F n``, the wheel pushes the rail with ``−F n``. The compression is

.. math::

    δ = r + n · (u_\\text{rail} − u_\\text{wheel})

with ``r`` the roughness at the contact (rail + wheel, positive = material added on the surfaces) and
``u`` the displacements of the two contact points measured from the unloaded, just-touching state.
"""

from __future__ import annotations

import numpy as np

__all__ = ["hertz_constant", "hertz_force", "linearised_stiffness", "STEEL_E", "STEEL_NU"]

STEEL_E = 206e9
STEEL_NU = 0.3


def hertz_constant(wheel_radius: float, rail_crown_radius: float, E: float = STEEL_E, nu: float = STEEL_NU) -> float:
    """``C_H`` [N/m^1.5] of the module docstring (Johnson 1985, eq. 4.36).

    Raises
    ------
    ValueError
        If a radius or the modulus is not positive.
    """
    if not (wheel_radius > 0 and rail_crown_radius > 0 and E > 0 and 0 <= nu < 0.5):
        raise ValueError(f"hertz_constant needs positive radii and modulus and 0 <= nu < 0.5, got wheel_radius="
                         f"{wheel_radius!r}, rail_crown_radius={rail_crown_radius!r}, E={E!r}, nu={nu!r}")
    A = 1.0 / (2 * wheel_radius)
    B = 1.0 / (2 * rail_crown_radius)
    Re = 1.0 / (2 * np.sqrt(A * B))
    E_star = E / (2 * (1 - nu**2))
    ratio = max(A, B) / min(A, B)
    F2 = 1.0 - (ratio**0.0602 - 1.0) ** 1.456
    return float(4.0 / 3.0 * E_star * np.sqrt(Re) / F2**1.5)


def hertz_force(C_H: float, delta: np.ndarray) -> np.ndarray:
    """``C_H max(δ, 0)^{3/2}`` [N]."""
    d = np.clip(np.asarray(delta, float), 0.0, None)
    return C_H * d**1.5


def linearised_stiffness(C_H: float, force: float) -> float:
    """Tangent stiffness ``dF/dδ = 1.5 C_H^{2/3} F^{1/3}`` at a static load ``force`` [N/m]."""
    if force <= 0:
        raise ValueError(f"linearised_stiffness needs a positive static load, got {force!r}")
    return float(1.5 * C_H ** (2.0 / 3.0) * force ** (1.0 / 3.0))
