"""Odometry of the instrumented car: encoder speed, integrated position with balise resets, balise events.

An incremental encoder on the axle end of one wheelset (``encoder_wheelset``)
counts ``pulses_per_rev`` pulses per revolution. The on-board unit converts
counts to distance with the **nominal** wheel radius, so every metre it
integrates is ``r_nominal / r_true`` metres long: a worn wheel (true radius
a few tenths of a millimetre to a millimetre smaller) makes the position run
ahead by a few tenths of a per cent. The speed channel is the count
difference over a ``gate_s`` gate, at ``rate_hz``, times the nominal distance
per pulse.

Position is chainage (the train knows its direction from the cab): it starts
from the departure station's chainage plus the run's **start offset** (the
ATC's initial position is only as good as the last stop's estimate) and is
reset to a balise's reference chainage at the first output sample after the
bogie passes it (the reference point of the odometry is the instrumented
bogie — a stated simplification: real antennas sit elsewhere under the car,
a constant offset). Each reset is a jump: ``jump = reference − position
just before``. The balise channel has one sample per passage, at the reset
time, with the balise's reference chainage as value.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .geometry import Line
from .operation import SpeedProfile

__all__ = ["OdometryParameters", "Odometry", "simulate_odometry"]


@dataclass(frozen=True)
class OdometryParameters:
    nominal_radius_m: float = 0.41
    encoder_wheelset: int = 2
    pulses_per_rev: int = 1024
    rate_hz: float = 100.0
    gate_s: float = 0.1


@dataclass(frozen=True)
class Odometry:
    """What the odometry records, and its truth.

    ``t`` (rate_hz) with ``speed`` [m/s] and ``position`` [m]; balise events ``balise_t`` and
    ``balise_value`` (reference chainage); per reset the truth ``resets`` (balise id, time, true chainage,
    position before, jump).
    """

    t: np.ndarray
    speed: np.ndarray
    position: np.ndarray
    balise_t: np.ndarray
    balise_value: np.ndarray
    resets: tuple[dict, ...]
    scale: float  # r_nominal / r_true of the encoder wheel
    start_offset_m: float


def simulate_odometry(line: Line, profile: SpeedProfile, true_radius_m: float, start_offset_m: float,
                      p: OdometryParameters = OdometryParameters()) -> Odometry:
    """Encoder speed, odometer position and balise events of one run (see the module docstring)."""
    t = np.arange(0.0, profile.duration + 1e-9, 1.0 / p.rate_hz)
    s_true, _, _ = profile.at(t)
    travelled = np.abs(s_true - s_true[0])  # the train never reverses on a run
    per_pulse_true = 2 * np.pi * true_radius_m / p.pulses_per_rev
    per_pulse_nom = 2 * np.pi * p.nominal_radius_m / p.pulses_per_rev
    counts = np.floor(travelled / per_pulse_true + 1e-9)
    gate = int(round(p.gate_s * p.rate_hz))
    dc = counts - np.concatenate([np.full(gate, counts[0]), counts[:-gate]])
    speed = dc * per_pulse_nom / p.gate_s
    sign = profile.travel_sign
    dist_nom = counts * per_pulse_nom
    position = np.empty_like(t)
    origin_pos = s_true[0] + start_offset_m
    origin_dist = 0.0
    resets = []
    b_t, b_v = [], []
    passes = sorted(
        ((profile.time_at(b.chainage_m), b) for b in line.balises
         if min(profile.s[0], profile.s[-1]) < b.chainage_m < max(profile.s[0], profile.s[-1])),
        key=lambda tb: tb[0],
    )
    k0 = 0
    for tb, b in passes:
        k = int(np.searchsorted(t, tb, side="right"))  # first sample after the bogie passed
        if k >= t.size:
            break
        position[k0:k] = origin_pos + sign * (dist_nom[k0:k] - origin_dist)
        # the unit time-stamps the detection and carries on from the balise with the pulses counted since
        at_balise = np.floor(abs(b.chainage_m - s_true[0]) / per_pulse_true + 1e-9) * per_pulse_nom
        before = origin_pos + sign * (at_balise - origin_dist)
        resets.append({"balise": b.id, "t_s": float(t[k]), "t_pass_s": float(tb), "reference_m": b.chainage_m,
                       "true_chainage_m": float(s_true[k]), "position_before_m": float(before),
                       "jump_m": float(b.chainage_m - before)})
        b_t.append(t[k])
        b_v.append(b.chainage_m)
        origin_pos, origin_dist, k0 = b.chainage_m, at_balise, k
    position[k0:] = origin_pos + sign * (dist_nom[k0:] - origin_dist)
    return Odometry(t, speed, position, np.array(b_t), np.array(b_v, float), tuple(resets),
                    p.nominal_radius_m / true_radius_m, start_offset_m)
