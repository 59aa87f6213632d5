"""Direction of travel and orientation → leading wheelset, which rail each vehicle side runs on, offsets.

The field contract's rule (binding for the virtual line and real files):
``direction`` is relative to chainage (``forward`` = towards increasing
chainage); ``orientation`` is ``normal`` when the car's front end faces
increasing chainage, ``turned`` otherwise. Then

* the leading wheelset is 1 for (forward, normal) and (backward, turned), else 2;
* the vehicle's L side runs on rail L when ``normal``, on rail R when ``turned``;
* wheelset 1 sits at the front end: its chainage is the bogie centre's
  ``+ a/2`` when ``normal`` and ``− a/2`` when ``turned`` (``a`` the wheelbase);
  wheelset 2 the opposite.
"""

from __future__ import annotations

from dataclasses import dataclass

from estimator.errors import ConfigurationError
from estimator.run import DIRECTIONS, ORIENTATIONS

__all__ = ["Orientation", "orientation"]


@dataclass(frozen=True)
class Orientation:
    """What a run's direction and orientation imply (see the module docstring)."""

    direction: str
    orientation: str
    leading: int
    trailing: int
    travel_sign: int
    rail_of_side: dict
    side_of_rail: dict
    wheelset_offset_sign: dict

    def role(self, wheelset: int) -> str:
        return "leading" if wheelset == self.leading else "trailing"


def orientation(direction: str, orientation: str = "normal") -> Orientation:
    """The field contract's rule as one pure function (tested for all four combinations).

    Parameters
    ----------
    direction : {"forward", "backward"}
        Direction of travel relative to chainage.
    orientation : {"normal", "turned"}
        Which way the car's front end faces.

    Returns
    -------
    Orientation
        ``leading`` / ``trailing`` wheelset numbers, ``travel_sign`` (+1 towards
        increasing chainage), ``rail_of_side`` (vehicle side → rail),
        ``side_of_rail`` (rail → vehicle side) and ``wheelset_offset_sign``
        (wheelset → sign of its offset ``± a/2`` from the bogie centre along chainage).
    """
    if direction not in DIRECTIONS:
        raise ConfigurationError(f"direction must be one of {DIRECTIONS}, got {direction!r}")
    if orientation not in ORIENTATIONS:
        raise ConfigurationError(f"orientation must be one of {ORIENTATIONS}, got {orientation!r}")
    forward = direction == "forward"
    normal = orientation == "normal"
    leading = 1 if forward == normal else 2
    rail_of_side = {"L": "L", "R": "R"} if normal else {"L": "R", "R": "L"}
    side_of_rail = {r: s for s, r in rail_of_side.items()}
    front = 1 if normal else -1
    return Orientation(direction, orientation, leading, 3 - leading, 1 if forward else -1, rail_of_side,
                       side_of_rail, {1: front, 2: -front})
