"""The virtual line's everyday laws that the estimator's defaults do not carry (test and benchmark helper).

Two of the line's physical laws differ from what the estimator assumes when it is told nothing more:

* the track's resilient layers are causal (:mod:`lab_data.line.damping`): their storage stiffness rises through
  the band and equals the trackform table's at one frequency; the estimator's default is thesis eq. 2.32
  (constant storage stiffness and loss factor);
* the wheelsets' contact angles on a curve follow the line's curving law with the bogie's yaw
  (:mod:`lab_data.line.curving`, :func:`curving_truth.curving_law`); the estimator's default is first order
  (:mod:`estimator.contact_angles`).

Given both, through the estimator's own inputs (a line description whose trackforms carry
``loss_reference_hz``, and ``EstimatorConfig.curve_contact_angles``), the estimator's model is the line's up to
what the field diagnosis is meant to find.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from curving_truth import curving_law


def line_loss_reference_hz() -> float:
    """Frequency where the line's causal unit loss law ``g`` has zero real part (its layers' storage stiffness
    equals the table's there)."""
    from lab_data.line.damping import unit_loss_fit

    f = np.geomspace(1.0, 3000.0, 20001)
    g = unit_loss_fit().g(f)
    return float(f[np.argmin(np.abs(g.real))])


def line_with_loss_reference(d, out: Path, reference_hz: float) -> Path:
    """A copy of campaign ``d``'s ``line.json`` in folder ``out`` whose trackforms state the frequency their layers'
    stiffness holds at (the causal loss law, ``loss_reference_hz``)."""
    doc = json.loads((Path(d) / "line.json").read_text())
    for section in doc["trackform_sections"]:
        section["loss_reference_hz"] = float(reference_hz)
    path = Path(out) / f"line_loss_reference_{reference_hz:g}Hz.json"
    path.write_text(json.dumps(doc, indent=1))
    return path


def line_with_causal_layers(d, out: Path) -> Path:
    """A copy of campaign ``d``'s ``line.json`` in folder ``out`` whose trackforms carry the line's own loss law."""
    return line_with_loss_reference(d, out, line_loss_reference_hz())


def curve_c1_angles(d, day: int = 1) -> dict:
    """``EstimatorConfig.curve_contact_angles`` of curve C1 from the line's curving law at survey ``day``'s speed,
    leading and trailing wheelsets."""
    return {"C1": {role: curving_law(d, day, leading=role == "leading") for role in ("leading", "trailing")}}
