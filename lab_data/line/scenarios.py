"""Field scenarios of the virtual line: hidden effects the estimator's default model lacks.

Every scenario runs on the same line, rails, wheels and operation; it adds
effects that the written files do not state (they appear only in the truth):

``nominal``
    Nothing hidden beyond what every run has (support scatter, sensor
    mounting a few mm off, ±2 % sensitivities, the causal track damping of the
    dynamics, the contact filter).
``trackform_change``
    Both resilient layers (rail pads and subplates, vertical and lateral
    stiffness) 40 % softer on 720–780 m, both rails — a section re-laid with
    another fastening type that ``line.json`` does not know about. (Softening
    the pads alone would move the axlebox response by < 1.5 dB below 400 Hz:
    the subplate dominates there.)
``sensor_offset``
    The vertical accelerometer on wheelset 1's left axlebox sits 40 mm
    outboard of the axlebox centre along the axle (the table says centre).
``wheel_polygon``
    Wheelset 1's left wheel is polygonised: 12th order (214 mm at the worn
    radius, inside the 100–300 mm band), 15 µm amplitude (30 µm peak-to-peak).
``contact_angle``
    The gauge of both curves is 3 mm tight on the outer rail: the outer wheels
    reach their flange root earlier, the curve contact angles are far from the
    default quasi-static values (leading outer wheel ~60–70° instead of 4–8°).
``two_effects``
    ``trackform_change`` and ``sensor_offset`` at once.
``pad_defect``
    Four consecutive rail pads of rail L at 590 m have lost 85 % of their
    stiffness (cracked, partly missing) — an effect outside the estimator's
    catalogue.
``lateral_sign``
    Wheelset 1's lateral accelerometer is mounted the wrong way round (its
    axis points to −y; the table says +y).
"""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["FieldScenario", "FIELD_SCENARIOS", "get_field_scenario", "FieldScenarioError"]


class FieldScenarioError(KeyError):
    """Unknown field scenario."""

    def __str__(self) -> str:  # KeyError quotes its message; show it plainly
        return str(self.args[0])


@dataclass(frozen=True)
class FieldScenario:
    """Hidden effects of a field scenario (all optional).

    Attributes
    ----------
    support_changes : tuple of dict
        ``{"rail": "LR"|"L"|"R", "from_m", "to_m", "factors": {layout factor name: multiplier}, "what"}``.
    sensor_offsets : dict
        Channel name -> true mounting offset (m, vehicle frame) replacing the drawn small offset.
    sign_flips : tuple of str
        Channels whose accelerometer is mounted the wrong way round.
    wheel_polygon : dict or None
        ``{"wheel": 0-3 (ws1 L, ws1 R, ws2 L, ws2 R), "order", "amplitude_m", "phase_rad"}``.
    gauge_narrowing_m : float
        Outer-rail gauge narrowing on the curves (contact-angle model).
    """

    name: str
    description: str
    support_changes: tuple = field(default_factory=tuple)
    sensor_offsets: dict = field(default_factory=dict)
    sign_flips: tuple = field(default_factory=tuple)
    wheel_polygon: dict | None = None
    gauge_narrowing_m: float = 0.0

    def parameters(self) -> dict:
        return {
            "name": self.name,
            "description": self.description,
            "support_changes": [dict(c) for c in self.support_changes],
            "sensor_offsets": {k: list(v) for k, v in self.sensor_offsets.items()},
            "sign_flips": list(self.sign_flips),
            "wheel_polygon": self.wheel_polygon,
            "gauge_narrowing_m": self.gauge_narrowing_m,
        }


_SOFT = 0.6
TRACKFORM_CHANGE = {
    "rail": "LR", "from_m": 720.0, "to_m": 780.0, "what": "pads and subplates 40 % softer (unknown re-laying)",
    "factors": {"pad_stiffness_z": _SOFT, "pad_stiffness_y": _SOFT, "subplate_stiffness_z": _SOFT,
                "subplate_stiffness_y": _SOFT},
}
PAD_DEFECT = {
    "rail": "L", "from_m": 589.9, "to_m": 592.9, "what": "4 rail pads lost 85 % of their stiffness",
    "factors": {"pad_stiffness_z": 0.15, "pad_stiffness_y": 0.15},
}
SENSOR_OFFSET = {"ACC_W1L_Z": (0.0, -0.040, 0.0)}  # 40 mm outboard (left side: -y)
POLYGON = {"wheel": 0, "order": 12, "amplitude_m": 15e-6, "phase_rad": 0.7}

FIELD_SCENARIOS: dict[str, FieldScenario] = {
    s.name: s
    for s in (
        FieldScenario("nominal", "no hidden effect beyond the line's everyday ones"),
        FieldScenario("trackform_change", "pads and subplates 40 % softer on 720-780 m, not in line.json",
                      support_changes=(TRACKFORM_CHANGE,)),
        FieldScenario("sensor_offset", "vertical accelerometer of wheelset 1 left 40 mm outboard of the axlebox "
                      "centre", sensor_offsets=SENSOR_OFFSET),
        FieldScenario("wheel_polygon", "wheelset 1 left wheel polygonised: 12th order, 15 um amplitude",
                      wheel_polygon=POLYGON),
        FieldScenario("contact_angle", "outer-rail gauge 3 mm tight on both curves: curve contact angles far "
                      "from the default", gauge_narrowing_m=3e-3),
        FieldScenario("two_effects", "trackform_change and sensor_offset together",
                      support_changes=(TRACKFORM_CHANGE,), sensor_offsets=SENSOR_OFFSET),
        FieldScenario("pad_defect", "4 rail pads of rail L at 590 m lost 85 % of their stiffness (outside the "
                      "catalogue)", support_changes=(PAD_DEFECT,)),
        FieldScenario("lateral_sign", "lateral accelerometer of wheelset 1 mounted the wrong way round (not in "
                      "the sensor table)", sign_flips=("ACC_W1L_Y",)),
    )
}


def get_field_scenario(name: str) -> FieldScenario:
    """Scenario by name; an unknown name raises :class:`FieldScenarioError` listing the valid ones."""
    try:
        return FIELD_SCENARIOS[name]
    except KeyError:
        raise FieldScenarioError(f"unknown field scenario {name!r}; choose one of {sorted(FIELD_SCENARIOS)}") from None
