"""An accelerometer read with the wrong sign, found against the design FE's shapes.

Oracle: the virtual lab's truth modes at the sensors (:func:`test_ema_pairing.truth_modeset`, with the phase
scatter of identified shapes), each channel's row negated in turn, as a channel mounted the wrong way round or a
channel table with the wrong direction sign leaves it. The end-to-end tests (tests/test_ema_end_to_end.py) do the
same on identified modes of every scenario.
"""

from dataclasses import replace

import numpy as np
import pytest

import fem_import
from ema.merge import merge_setups
from ema.pairing import pair_modes
from ema.polarity import channel_polarity, polarity_findings
from lab_data.cache import campaign_dir
from test_ema_pairing import truth_modeset


def _negated(test, j):
    shapes = test.shapes.copy()
    shapes[j] = -shapes[j]
    return replace(test, shapes=shapes)


@pytest.mark.parametrize("scenario", ["control", "bearing"])
def test_each_channel_negated_in_turn_is_the_one_blamed(scenario):
    """control: the FE is the wheelset; bearing: a hidden bearing stiffness the design FE lacks moves the axlebox
    shapes. No channel is blamed on the data as measured; a negated one is blamed alone, and found unless it
    carries weight in fewer than two modes (the disc channels) or the FE's shapes there are off."""
    folder = campaign_dir(scenario)
    fe = fem_import.read(folder / "fe_design.uff")
    sets = [truth_modeset(folder, s, phase_noise=0.02, seed=3)[0] for s in ("flexural", "torsional")]
    merged = merge_setups(sets)
    for test in (*sets, merged):
        table = channel_polarity(test, fe, pair_modes(test, fe))
        assert not table["suspect"].any(), table[table["suspect"]]
        assert (table.loc[table["modes"] > 0, "median_gain"] < 0).all()  # negating a right channel costs MAC
    # the check reads only the pairing's FE clusters, which the shapes do not change: one pairing serves
    pairing = pair_modes(merged, fe)
    found, decidable = 0, 0
    for j in range(len(merged.dofs)):
        t2 = channel_polarity(_negated(merged, j), fe, pairing)
        blamed = list(np.flatnonzero(t2["suspect"]))
        assert blamed in ([], [j]), (merged.dofs[j], t2[t2["suspect"]])
        found += blamed == [j]
        decidable += int(t2["modes"].iloc[j] >= 2)
    print(f"{scenario}, both setups merged: {found} of {len(merged.dofs)} negated channels found ({decidable} "
          f"carry weight in two modes or more)")
    assert found >= 0.8 * decidable


def test_the_finding_names_the_channel_its_node_and_what_to_check():
    folder = campaign_dir("control")
    fe = fem_import.read(folder / "fe_design.uff")
    test = truth_modeset(folder, "torsional")[0]
    j = test.dofs.index("wheelL_5")
    flipped = _negated(test, j)
    (finding,) = polarity_findings(channel_polarity(flipped, fe, pair_modes(flipped, fe)))
    assert finding.startswith("channel wheelL_5 (setup torsional) at node 135 looks read with the wrong sign")
    assert "sign of its direction in the channel table" in finding


def test_lab_pair_warns_of_a_channel_table_with_a_wrong_direction_sign(tmp_path, caplog):
    """The sensor is mounted as built, its row in the channel table says the opposite direction: ``lab pair``
    writes every channel's verdict and warns naming the channel."""
    import pandas as pd

    from ema.modes_io import write_modeset
    from railmodal.cli import main

    folder = campaign_dir("control")
    test = truth_modeset(folder, "torsional", phase_noise=0.02, seed=3)[0]
    channels = test.channels.copy()
    row = channels.index[channels["name"] == "wheelL_5"]
    channels.loc[row, ["dx", "dy", "dz"]] *= -1
    write_modeset(replace(test, channels=channels), tmp_path / "modes")
    code = main(["-q", "lab", "pair", "--modes", str(tmp_path / "modes"), "--fem", str(folder / "fe_design.uff"),
                 "--out", str(tmp_path / "pairing")])
    assert code == 0
    table = pd.read_csv(tmp_path / "pairing" / "channel_polarity.csv")
    assert list(table.loc[table["suspect"], "name"]) == ["wheelL_5"]
    assert "channel wheelL_5 (setup torsional) at node 135 looks read with the wrong sign" in caplog.text


def test_the_diagnosis_report_puts_the_finding_in_its_pairing_section():
    from receptance.diagnosis.report import SECTION_TITLES, _Figures, _section_pairing

    finding = "channel wheelL_5 (setup torsional) at node 135 looks read with the wrong sign: negated, ..."
    html = _section_pairing(None, [], _Figures({}), "", [finding])
    assert html.index(SECTION_TITLES[1]) < html.index("Channels that look read with the wrong sign")
    assert "box warn" in html and "wheelL_5 (setup torsional) at node 135" in html
    assert "wrong sign" not in _section_pairing(None, [], _Figures({}), "", [])
