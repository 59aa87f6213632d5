"""Discrete rail supports along the line: per-sleeper scatter, documented and hidden trackform sections.

One support (baseplate on its subplate, pad under the rail) every
``sleeper_spacing_m`` from half a spacing after chainage 0, the same
positions under both rails. Each support's parameters are the trackform's
(thesis Table 2.2) times multiplicative factors (rows: rail ``L``, ``R``):

* scatter sleeper by sleeper: stiffness factors normal with 4 % standard
  deviation, damping factors 6 %, each clipped at ±3 standard deviations
  (manufacturing and ageing spread of elastomers);
* the line's documented trackform sections (``line.json``): their pads'
  stiffness and loss factor relative to the base trackform;
* the scenario's hidden support changes (:mod:`lab_data.line.scenarios`),
  applied to every support whose chainage lies in the changed stretch.
"""

from __future__ import annotations

import numpy as np

from .geometry import Line
from .scenarios import FieldScenario

__all__ = ["SCATTERED", "support_factors", "track_layout"]

#: Support fields given a per-sleeper scatter (the dynamics core's ``SUPPORT_FIELDS`` names).
SCATTERED = ("pad_stiffness_z", "pad_stiffness_y", "pad_damping_z", "pad_damping_y",
             "subplate_stiffness_z", "subplate_stiffness_y", "subplate_damping_z", "subplate_damping_y")


def support_factors(line: Line, scenario: FieldScenario, seed: int) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Support chainages (n,) and factors ``{field: (2, n)}`` on the line's first trackform section's values."""
    from .track import SUPPORT_FIELDS

    ls = line.sleeper_spacing_m
    x = np.arange(0.5 * ls, line.length_m, ls)
    rng = np.random.default_rng([seed, 75])
    factors = {name: np.ones((2, x.size)) for name in SUPPORT_FIELDS}
    for name in SCATTERED:
        sd = 0.04 if "stiffness" in name else 0.06
        factors[name] = 1.0 + np.clip(rng.normal(0.0, sd, (2, x.size)), -3 * sd, 3 * sd)
    base = line.trackform_sections[0].parameters
    for sec in line.trackform_sections:
        inside = (x >= sec.from_m) & (x < sec.to_m)
        for name in SUPPORT_FIELDS:
            ratio = sec.parameters[name] / base[name]
            if ratio != 1.0:
                factors[name][:, inside] *= ratio
    for change in scenario.support_changes:
        inside = (x >= change["from_m"]) & (x <= change["to_m"])
        rows = ["LR".index(r) for r in change["rail"]]
        for name, mult in change["factors"].items():
            if name not in factors:
                raise KeyError(f"scenario {scenario.name}: unknown support field {name!r} ({SUPPORT_FIELDS})")
            for r in rows:
                factors[name][r, inside] *= mult
    return x, factors


def track_layout(line: Line, scenario: FieldScenario, seed: int, *, continuous: bool = False):
    """The dynamics core's ``TrackLayout`` for this line and scenario (base trackform: Table 2.2)."""
    from .track import TrackLayout, TrackParameters

    x, factors = support_factors(line, scenario, seed)
    base = TrackParameters(**line.trackform_sections[0].parameters)
    return TrackLayout(support_chainage=x, support_factors=factors, base=base, continuous=continuous)
