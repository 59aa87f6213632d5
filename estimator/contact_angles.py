"""Contact-plane angles along a run from the line's curvature (a first-order quasi-static curving estimate).

The vertical + lateral model (thesis eq. 2.22) needs the contact-plane angles
``θ_L, θ_R`` of each wheel. The thesis took them from a multibody run of the
curve; give such angles when known (``EstimatorConfig.contact_angles``).
Otherwise this module estimates them from the line description:

* on tangent track both wheels touch the rail crown on the tread: the angle
  is the tread's cone angle ``γ₀ = atan(1/40)`` (1:40 tread on a 1:40
  inclined rail);
* in a curve of curvature ``κ`` the wheelset runs out towards the high rail
  by the pure-rolling shift ``y = r₀ b₀ |κ| / λ_e`` (Wickens; ``r₀`` rolling
  radius, ``b₀`` half the contact-point spacing, ``λ_e`` equivalent
  conicity), limited to the flange clearance ``y_f``;
* the contact angle as a function of the shift towards a wheel's flange is a
  generic tread–flange shape: ``γ₀`` on the tread up to the flange root
  ``y_r``, then rising linearly to the flange angle ``γ_f`` at ``y_f``; the
  outer wheel reads ``γ(y)``, the inner wheel ``γ(−y) = γ₀``.

Sign (thesis eq. 2.12, normal ``(−sin θ, cos θ)`` in the wheelset's y–z
plane, left wheel at −y): a contact normal tilted towards the track centre,
as the rail pushes the wheel, is ``θ_R = +γ_R`` and ``θ_L = −γ_L``.

This is deliberately simple (no bogie yaw, no cant-deficiency shift): the
field diagnosis (issue 15) fits ``contact_angle`` where it matters.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["CurvingModel", "contact_angles"]


@dataclass(frozen=True)
class CurvingModel:
    """Parameters of the quasi-static estimate (module docstring); SI units, angles in rad."""

    rolling_radius_m: float = 0.41
    half_contact_spacing_m: float = 0.75
    equivalent_conicity: float = 0.15
    tread_angle_rad: float = float(np.arctan(1 / 40))
    flange_root_m: float = 0.006
    flange_clearance_m: float = 0.008
    flange_angle_rad: float = float(np.radians(70.0))

    def gamma(self, shift_m: np.ndarray) -> np.ndarray:
        """Contact angle [rad] of a wheel shifted ``shift_m`` towards its flange."""
        y = np.asarray(shift_m, float)
        rise = np.clip((y - self.flange_root_m) / (self.flange_clearance_m - self.flange_root_m), 0.0, 1.0)
        return self.tread_angle_rad + rise * (self.flange_angle_rad - self.tread_angle_rad)


def contact_angles(curvature: np.ndarray, side_of_rail: dict, model: CurvingModel = CurvingModel()
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Contact-plane angles ``(θ_L, θ_R)`` of the vehicle's left and right wheels along a run.

    Parameters
    ----------
    curvature : ndarray
        Signed curvature [1/m] at the wheelset (positive for a left curve,
        looking towards increasing chainage).
    side_of_rail : dict
        Rail (``"L"``/``"R"``) → vehicle side (:func:`estimator.orientation.orientation`).
    model : CurvingModel

    Returns
    -------
    theta_L, theta_R : ndarray
        Thesis eq. 2.12 angles [rad] of the vehicle's left and right wheels.
    """
    k = np.asarray(curvature, float)
    shift = np.minimum(model.rolling_radius_m * model.half_contact_spacing_m * np.abs(k)
                       / model.equivalent_conicity, model.flange_clearance_m)
    g_out = model.gamma(shift)
    g_in = model.gamma(-shift)
    # the outer (high) rail of a left curve (k > 0) is R, of a right curve L
    outer_is_rail_R = k > 0
    gamma_rail = {"R": np.where(outer_is_rail_R, g_out, g_in), "L": np.where(outer_is_rail_R, g_in, g_out)}
    gamma_side = {side_of_rail[r]: g for r, g in gamma_rail.items()}
    return -gamma_side["L"], gamma_side["R"]
