"""The instrumented bogie's channels (thesis §2.1) and the sensor table the field files carry.

Six accelerometers: one vertical on each axlebox and one lateral per
wheelset (wheelset 1 on its left axlebox, wheelset 2 on its right one), all
nominally at the axlebox centre, ``(0, ±0.97, 0)`` m from the wheelset
centre in the vehicle frame (x forward, y with the left side at −y, z up).
The true mounting points are a few mm to 2 cm off (drawn once per campaign:
each component normal with 6 mm standard deviation, clipped at ±15 mm) and
the true sensitivities differ from the calibration sheet by up to ±2 %;
scenarios may move a sensor further or turn one round
(:mod:`lab_data.line.scenarios`). Plus the odometry channels: encoder speed,
odometer position and balise events.

The table (``sensors.csv``, field contract) has one row per MDF4 channel:
``name, quantity, unit, wheelset, side, direction, x, y, z, sensitivity`` with
``sensitivity`` the factor giving SI from the recorded values (9.80665 for a
channel in g).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from .daq import G, ChannelSpec, DaqParameters
from .scenarios import FieldScenario

__all__ = ["AccelerometerSpec", "ACCELEROMETERS", "AXLEBOX_Y", "SPEED", "POSITION", "BALISE", "draw_sensors",
           "sensor_table"]

AXLEBOX_Y = 0.97  # lab_data.wheelset.WheelsetParameters.axlebox_y
SPEED, POSITION, BALISE = "SPEED", "ODO_POSITION", "BALISE"


@dataclass(frozen=True)
class AccelerometerSpec:
    """One accelerometer: channel name, wheelset, vehicle side, direction, nominal and true mounting, errors."""

    name: str
    wheelset: int
    side: str
    direction: str
    nominal: tuple[float, float, float]
    true: tuple[float, float, float]
    sensitivity_error: float
    sign: float

    def channel(self, daq: DaqParameters) -> ChannelSpec:
        rng = daq.range_vertical_g if self.direction == "z" else daq.range_lateral_g
        return ChannelSpec(self.name, self.direction, self.sensitivity_error, self.sign, rng)


#: (name, wheelset, side, direction)
ACCELEROMETERS = (
    ("ACC_W1L_Z", 1, "L", "z"), ("ACC_W1R_Z", 1, "R", "z"), ("ACC_W1L_Y", 1, "L", "y"),
    ("ACC_W2L_Z", 2, "L", "z"), ("ACC_W2R_Z", 2, "R", "z"), ("ACC_W2R_Y", 2, "R", "y"),
)


def draw_sensors(seed: int, scenario: FieldScenario) -> tuple[AccelerometerSpec, ...]:
    """True mounting points, sensitivity errors and signs of the six accelerometers (one campaign)."""
    rng = np.random.default_rng([seed, 6])
    out = []
    for name, ws, side, d in ACCELEROMETERS:
        y0 = -AXLEBOX_Y if side == "L" else AXLEBOX_Y
        nominal = (0.0, y0, 0.0)
        off = np.clip(rng.normal(0.0, 6e-3, 3), -15e-3, 15e-3)
        eps = float(rng.uniform(-0.02, 0.02))
        if name in scenario.sensor_offsets:
            off = np.asarray(scenario.sensor_offsets[name], float)
        true = tuple(float(a + b) for a, b in zip(nominal, off))
        sign = -1.0 if name in scenario.sign_flips else 1.0
        out.append(AccelerometerSpec(name, ws, side, d, nominal, true, eps, sign))
    return tuple(out)


def sensor_table(sensors: tuple[AccelerometerSpec, ...]) -> pd.DataFrame:
    """The ``sensors.csv`` table (nominal positions and sensitivities only: nothing of the truth)."""
    rows = [
        {"name": s.name, "quantity": "acceleration", "unit": "g", "wheelset": s.wheelset, "side": s.side,
         "direction": s.direction, "x": s.nominal[0], "y": s.nominal[1], "z": s.nominal[2], "sensitivity": G}
        for s in sensors
    ]
    for name, quantity, unit in ((SPEED, "speed", "m/s"), (POSITION, "position", "m"), (BALISE, "balise", "m")):
        rows.append({"name": name, "quantity": quantity, "unit": unit, "wheelset": None, "side": None,
                     "direction": None, "x": None, "y": None, "z": None, "sensitivity": 1.0})
    df = pd.DataFrame(rows, columns=["name", "quantity", "unit", "wheelset", "side", "direction", "x", "y", "z",
                                     "sensitivity"])
    df["wheelset"] = df["wheelset"].astype("Int64")
    return df
