"""Test helper: a virtual-lab campaign folder as the diagnosis sees it with the truth's pairing.

The hybrid model of the design FE export with the truth's flexural pairing (the model reports modes up to the
500 Hz test band, every FE mode kept as the modifications' basis) and the H1 measurements of both setups.
"""

from __future__ import annotations

import json

import pandas as pd

import fem_import
from ema import estimate_frf, read_hammer
from receptance.diagnosis import Measurement
from receptance.dofs import read_points
from receptance.hybrid import hybrid_model


def truth_paired(folder):
    """``(model, measurements, manifest)`` of the campaign in ``folder``."""
    from test_hybrid_model import truth_pairing

    manifest = json.loads((folder / "truth.json").read_text())
    fe = fem_import.read(folder / "fe_design.uff")
    model = hybrid_model(fe, truth_pairing(manifest, "flexural", fe=fe, folder=folder),
                         points=read_points(folder / "points.csv"), keep_fe="all", max_hz=500.0)
    meas = [Measurement(estimate_frf(read_hammer(folder / f"{s}.uff", folder / f"{s}_channels.csv")),
                        pd.read_csv(folder / f"{s}_channels.csv"), s) for s in ("flexural", "torsional")]
    return model, meas, manifest
