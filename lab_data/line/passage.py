"""What the dynamics is given for one passage: positions, roughness and contact angles per wheel per step.

The instrumented car never turns (field contract): its front end — and
wheelset 1 — faces increasing chainage, the vehicle's left wheels run on rail
``L``. Wheelset 1 sits half a wheelbase ahead of the bogie centre in
chainage, wheelset 2 half a wheelbase behind; wheelset 1 leads when the car
travels forward (towards increasing chainage), wheelset 2 when it travels
backward. Wheels are ordered ``(ws1 L, ws1 R, ws2 L, ws2 R)``.

Per wheel and step: the contact-filtered rail roughness at the wheel's
chainage (linear interpolation on the 1 mm grid) plus the wheel's own
roughness at its rolling angle ``φ0 + (s(t) − s(0)) / r_axle`` (the two
wheels of a rigid axle turn together, at the mean of their true radii; the
sign of the travel turns the wheel either way, so the wheel's profile is
read in the right order for both directions), and the contact-plane angles of
:mod:`lab_data.line.curving` in the thesis eq. 2.12 sign.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .curving import CurvingParameters, rail_contact_angles, thesis_angles
from .geometry import Line, cant_angle, curvature
from .roughness import WheelRoughness

__all__ = ["WHEELS", "PassageArrays", "passage_arrays", "sample_uniform"]

WHEELS = ("ws1_L", "ws1_R", "ws2_L", "ws2_R")


@dataclass(frozen=True)
class PassageArrays:
    t: np.ndarray  # (n,)
    bogie_chainage: np.ndarray  # (n,)
    speed: np.ndarray  # (n,) m/s along the travel
    wheel_chainage: np.ndarray  # (4, n)
    roughness: np.ndarray  # (4, n) m, rail (filtered) + wheel
    contact_angle: np.ndarray  # (4, n) rad, thesis eq. 2.12 sign
    curvature: np.ndarray  # (n,) at the bogie
    cant: np.ndarray  # (n,) rad at the bogie
    leading_wheelset: int


def sample_uniform(field: np.ndarray, x0: float, dx: float, s: np.ndarray) -> np.ndarray:
    """Linear interpolation of rows sampled at ``x0 + k dx`` at positions ``s`` (clamped at the ends)."""
    u = np.clip((np.asarray(s, float) - x0) / dx, 0.0, field.shape[-1] - 1.000001)
    i = u.astype(np.int64)
    f = u - i
    return field[..., i] * (1 - f) + field[..., i + 1] * f


def passage_arrays(line: Line, t: np.ndarray, s: np.ndarray, v: np.ndarray, direction: str, *, wheelbase: float,
                   rail: np.ndarray, x0: float, dx: float, wheels: WheelRoughness, wheel_angle0: np.ndarray,
                   curving: CurvingParameters) -> PassageArrays:
    """Per-step inputs of the dynamics for a bogie at chainage ``s(t)`` with speed ``v(t)``.

    Parameters
    ----------
    rail : ndarray (2, n_grid)
        Contact-filtered rail roughness of the day (rows L, R) on the grid ``x0 + k dx``.
    wheel_angle0 : array (4,)
        Rolling angle of each wheel at ``t[0]``.
    """
    sign = 1.0 if direction == "forward" else -1.0
    half = 0.5 * wheelbase
    s_ws = np.stack([s + half, s - half])  # wheelset 1 ahead in chainage, the car never turns
    wheel_s = np.repeat(s_ws, 2, axis=0)
    r_rail = np.empty((4, s.size))
    for w in range(4):
        r_rail[w] = sample_uniform(rail[w % 2], x0, dx, wheel_s[w])
    # both wheels of a (rigid) axle turn together: the angle follows the wheelset's mean rolling radius
    r_axle = np.repeat(wheels.radius_m.reshape(2, 2).mean(axis=1), 2)
    angle = wheel_angle0[:, None] + (wheel_s - wheel_s[:, :1]) / r_axle[:, None]
    rough = r_rail + wheels.at(angle)
    leading = 1 if sign > 0 else 2
    # curvature, cant and contact angles change over metres: evaluate them every 2 ms (< 4 cm of travel) only
    step = max(1, int(round(0.002 / (t[1] - t[0])))) if t.size > 1 else 1
    idx = np.unique(np.concatenate([np.arange(0, s.size, step), [s.size - 1]]))
    theta_c = np.empty((4, idx.size))
    for k in range(2):
        g_l, g_r = rail_contact_angles(line, s_ws[k, idx], v[idx], np.full(idx.size, leading == k + 1), curving)
        theta_c[2 * k], theta_c[2 * k + 1] = thesis_angles(g_l, g_r)
    theta = np.stack([np.interp(t, t[idx], row) for row in theta_c])
    kappa = np.interp(t, t[idx], curvature(line, s[idx]))
    cant = np.interp(t, t[idx], cant_angle(line, s[idx]))
    return PassageArrays(t, s, v, wheel_s, rough, theta, kappa, cant, leading)
