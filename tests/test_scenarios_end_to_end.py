"""Every scenario writes a complete, self-consistent campaign (slow: all scenarios end to end)."""

import json

import numpy as np
import pandas as pd
import pytest
import pyuff

from lab_data.campaign import simulate
from lab_data.scenarios import SCENARIOS


@pytest.mark.slow
@pytest.mark.parametrize("scenario", sorted(SCENARIOS))
def test_every_scenario_writes_a_consistent_campaign(tmp_path, scenario):
    files = simulate(scenario, tmp_path, progress=lambda m: None)
    manifest = json.loads(files["truth"].read_text())
    assert manifest["scenario"]["name"] == scenario
    n_design = len(manifest["design_modes"])
    for setup in ("flexural", "torsional"):
        info = manifest["setups"][setup]
        assert info["double_hits"] == [3]
        assert [c["hit"] for c in info["clipped"]] == [5]
        # the FE partners named in the manifest exist in the export
        partners = {p for m in info["modes"] for p in m["fe_partner"]}
        assert partners <= set(range(1, n_design + 1))
        observable = [m for m in info["modes"] if m["observable"]]
        assert len(observable) >= 4
        assert all(10.0 <= m["f_hz"] <= 500.0 for m in observable)
        headers = pyuff.UFF(str(files[f"{setup}_uff"])).read_sets(header_only=True)
        assert len(headers) == 30 * 6
        table = pd.read_csv(files[f"{setup}_channels"])
        assert len(table) == 30
    effects = manifest["scenario"]["effects"]
    if scenario in ("bearing", "bearing_rig", "absorber"):
        # a hidden effect that adds modes: some observable truth modes have no FE partner
        unpaired = [m for s in manifest["setups"].values() for m in s["modes"] if m["observable"] and not m["fe_partner"]]
        assert unpaired, f"{scenario}: the hidden effect adds no observable unpaired mode"
        assert effects
    if scenario == "control":
        assert not effects and manifest["scenario"]["as_built"] == {}
    if scenario == "residual":
        f = [m["f_hz"] for m in manifest["setups"]["flexural"]["modes"]]
        assert max(f) > 4000.0 and max(m["f_hz"] for m in manifest["design_modes"]) <= 500.0
    if scenario in ("rig", "bearing_rig"):
        rig = [m for m in manifest["setups"]["flexural"]["modes"] if m["family"] == "rig"]
        assert any(2.0 < m["f_hz"] < 6.0 for m in rig)
    # the truth spectrum below the export frequency never straddles it
    f_all = np.array([m["f_hz"] for m in manifest["setups"]["flexural"]["modes"]])
    assert not np.any(np.abs(f_all - 500.0) < 10.0)
