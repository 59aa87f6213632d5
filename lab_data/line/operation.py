"""Automatic train operation: the speed profile of a station-to-station run, in both directions.

The train stands at the departure station, accelerates at a constant rate to
its cruise speed, slows before each speed restriction so that it enters it at
the target speed, keeps the target until the **whole train** has left it, and
brakes at a constant rate to stop at the arrival station (thesis §4.3: the
ATO of M1 runs the curves at 30–35 km/h).

The profile is built on a fine distance grid as the minimum of three
envelopes (target speed, acceleration from the departure, braking to every
lower target ahead) — the standard "forward/backward pass" of running-time
calculation — and integrated to time with ``dt = 2 ds / (v_i + v_{i+1})``,
exact for piecewise constant acceleration. ATO regulation is not perfect: the
cruise speed wanders by a fraction of a km/h along the line (a slow
sinusoid per run, stated in the plan). Jerk limitation is not modelled
(acceleration steps at the phase changes).

Train geometry (:class:`TrainGeometry`): the instrumented bogie sits 30 m
behind the car's front end, the train's front end 30 m ahead of it and its
rear end 77 m behind (a 107 m six-car *Meneghino*); a restriction on track
``[a, b]`` holds for the bogie on ``[a − 30, b + 77]`` in both directions,
because the car never turns (field contract).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from scipy.interpolate import CubicHermiteSpline

from .geometry import Line

__all__ = ["AtoParameters", "TrainGeometry", "SpeedProfile", "draw_ato", "ato_profile"]


@dataclass(frozen=True)
class TrainGeometry:
    bogie_to_front_m: float = 30.0
    bogie_to_rear_m: float = 77.0


@dataclass(frozen=True)
class AtoParameters:
    """One run's ATO settings (drawn per run by :func:`draw_ato`)."""

    cruise_kmh: float = 58.0
    curve_kmh: float = 32.0
    acceleration: float = 0.9  # m/s^2
    deceleration: float = 0.8  # m/s^2
    dwell_start_s: float = 3.0
    dwell_end_s: float = 3.0
    wander_kmh: float = 0.4  # amplitude of the cruise speed's slow wander
    wander_wavelength_m: float = 350.0
    wander_phase: float = 0.0

    def parameters(self) -> dict:
        return asdict(self)


def draw_ato(rng: np.random.Generator) -> AtoParameters:
    """ATO settings of one run: curve target 30–35 km/h, cruise 56–60 km/h, rates ±10 %, dwell 2–4 s."""
    return AtoParameters(
        cruise_kmh=float(rng.uniform(56.0, 60.0)),
        curve_kmh=float(rng.uniform(30.5, 34.5)),
        acceleration=float(rng.uniform(0.8, 1.0)),
        deceleration=float(rng.uniform(0.72, 0.88)),
        dwell_start_s=float(rng.uniform(2.0, 4.0)),
        dwell_end_s=float(rng.uniform(2.0, 4.0)),
        wander_kmh=float(rng.uniform(0.2, 0.6)),
        wander_phase=float(rng.uniform(0, 2 * np.pi)),
    )


@dataclass(frozen=True)
class SpeedProfile:
    """Chainage and speed of the instrumented bogie against time (true values).

    ``t`` starts at 0 with the train standing; ``s`` is chainage [m]; ``v`` the speed [m/s] (≥ 0, along the
    travel); ``direction`` is ``forward`` (increasing chainage) or ``backward``.
    """

    t: np.ndarray
    s: np.ndarray
    v: np.ndarray
    direction: str
    ato: AtoParameters

    @property
    def travel_sign(self) -> int:
        return 1 if self.direction == "forward" else -1

    @property
    def duration(self) -> float:
        return float(self.t[-1])

    def at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(chainage, speed, acceleration along the travel) at times ``t`` — cubic Hermite in time (C1)."""
        spline = CubicHermiteSpline(self.t, self.s, self.travel_sign * self.v)
        t = np.clip(np.asarray(t, float), self.t[0], self.t[-1])
        s = spline(t)
        v = self.travel_sign * spline(t, 1)
        a = self.travel_sign * spline(t, 2)
        return s, np.maximum(v, 0.0), a

    def time_at(self, s: float) -> float:
        """First time the bogie reaches chainage ``s`` (it must lie on the run)."""
        u = self.travel_sign * (self.s - self.s[0])
        target = self.travel_sign * (s - self.s[0])
        if not 0 <= target <= u[-1] + 1e-9:
            raise ValueError(f"chainage {s} m is not on this run ({self.s[0]:.1f} -> {self.s[-1]:.1f} m)")
        i = int(np.searchsorted(u, target))
        if i == 0:
            return float(self.t[0])
        # invert the (monotone) travel between the two knots
        return float(np.interp(target, u[i - 1:i + 1], self.t[i - 1:i + 1]))


def ato_profile(line: Line, direction: str, ato: AtoParameters = AtoParameters(),
                train: TrainGeometry = TrainGeometry(), ds: float = 0.05) -> SpeedProfile:
    """Speed profile of a run between the line's two stations.

    Parameters
    ----------
    line : Line
        Its first and last stations are departure/arrival (swapped for ``backward``).
    direction : {'forward', 'backward'}
    ato : AtoParameters
    train : TrainGeometry
    ds : float
        Distance step of the construction grid [m].
    """
    if direction not in ("forward", "backward"):
        raise ValueError(f"direction must be 'forward' or 'backward', got {direction!r}")
    a_st, b_st = line.stations[0].chainage_m, line.stations[-1].chainage_m
    start, end = (a_st, b_st) if direction == "forward" else (b_st, a_st)
    sign = 1.0 if direction == "forward" else -1.0
    dist = abs(end - start)
    u = np.arange(0.0, dist + ds / 2, ds)
    u[-1] = dist
    s = start + sign * u
    # target speed along the bogie's path: cruise with a slow wander, restrictions extended by the train length
    target = (ato.cruise_kmh + ato.wander_kmh * np.sin(2 * np.pi * s / ato.wander_wavelength_m + ato.wander_phase))
    target = np.minimum(target, line.line_speed_kmh)
    for lim in line.speed_limits:
        if lim.speed_kmh >= line.line_speed_kmh:
            continue
        zone = (s >= lim.from_m - train.bogie_to_front_m) & (s <= lim.to_m + train.bogie_to_rear_m)
        target = np.where(zone, np.minimum(target, min(ato.curve_kmh, lim.speed_kmh)), target)
    vt = target / 3.6
    # forward pass: accelerate from rest; backward pass: brake to every lower target ahead and to the stop
    v = np.empty_like(u)
    v[0] = 0.0
    for i in range(1, u.size):
        v[i] = min(vt[i], np.sqrt(v[i - 1] ** 2 + 2 * ato.acceleration * ds))
    v[-1] = 0.0
    for i in range(u.size - 2, -1, -1):
        v[i] = min(v[i], np.sqrt(v[i + 1] ** 2 + 2 * ato.deceleration * ds))
    v[0] = 0.0
    dt = 2 * np.diff(u) / (v[:-1] + v[1:])
    t = ato.dwell_start_s + np.concatenate([[0.0], np.cumsum(dt)])
    t = np.concatenate([[0.0], t, [t[-1] + ato.dwell_end_s]])
    s = np.concatenate([[s[0]], s, [s[-1]]])
    v = np.concatenate([[0.0], v, [0.0]])
    return SpeedProfile(t, s, v, direction, ato)
