"""The virtual line's own curving law, the oracle of a fitted curve contact angle (test helper).

The estimator's default curving (:mod:`estimator.contact_angles`) is first order: the pure-rolling shift of
5.1 mm on R = 400 m stays on the tread, 1.43° on both wheels. The line's law
(:func:`lab_data.line.curving.rail_contact_angles`) adds the bogie's yaw, which pushes the leading wheelset
further out; a field calibration's fitted angles are judged against it.
"""

from __future__ import annotations

import numpy as np


def curving_law(d, day: int = 1, leading: bool = True) -> tuple[float, float]:
    """The line's own contact angles (γ_L, γ_R) [rad] of the leading (or trailing) wheelset on curve C1's body at
    the median true speed there of the runs of survey ``day`` (1-based) of the campaign in folder ``d`` (the
    scenario's curving parameters)."""
    import pandas as pd

    from lab_data.line.curving import CurvingParameters, rail_contact_angles
    from lab_data.line.files import read_truth
    from lab_data.line.geometry import default_line

    truth = read_truth(d)
    body = []  # the true speed over the curve's body (510-670 m) in that day's runs
    for r in truth["runs"]:
        if r["day"] == day:
            tr = pd.read_parquet(f"{d}/truth/runs/{r['run_id']}.parquet")
            body.append(tr["speed_m_s"][(tr["chainage_m"] > 510) & (tr["chainage_m"] < 670)].abs().to_numpy())
    speed = float(np.median(np.concatenate(body)))
    cp = CurvingParameters(**{k: v for k, v in truth["curving"].items() if k in CurvingParameters.__dataclass_fields__})
    g_l, g_r = rail_contact_angles(default_line(), np.array([590.0]), np.array([speed]), np.array([leading]), cp)
    return float(g_l[0]), float(g_r[0])
