"""The effects' masses on wheelset designs other than the thesis's: never Table 2.1 in absolute terms.

Oracle: the virtual lab's other designs (:mod:`lab_data.designs`: a light metro wheelset, 180 kg wheels and 60 kg
axleboxes, FE 890 kg; a heavy freight wheelset, 340 kg wheels and 95 kg axleboxes, FE 1320 kg) and their bearing
campaigns' truth (``truth.json``: bearing radial 1e9 N/m, axial 2.5e8 N/m, rocking 5e6 N m/rad, right/left 1.15).
Before, Table 2.1's 251 kg wheel and 78 kg axlebox were taken off any FE: on the metro wheelset the wheel-seat joint
left a negative mass at the seat (non-finite poles, reported as a toolkit fault), the axlebox decision compared the
FE's 890 kg with Table 2.1's absolute totals and added a 78 kg body on top of the FE's own 60 kg axlebox node, and a
description giving only ``[wheel] mass_kg = 180`` was refused (rim 150 + web 80 kg > 180 kg).
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

import fem_import
from lab_data.cache import campaign_dir
from lab_data.designs import DESIGN_FE_MAX_HZ, get_design
from receptance.diagnosis import EffectNotApplicable
from receptance.diagnosis.effects import AxleboxBearing, WheelSeatJoint
from receptance.dofs import read_points
from receptance.hybrid import hybrid_model
from receptance.wheelset_description import WheelsetDescription, read_description

#: FE export top per design (a spectral gap of each design's truth, as the lab's campaigns need)
EXPORT_HZ = {"metro": 2000.0, "freight": 1950.0}


def _campaign(design: str, scenario: str = "bearing"):
    return campaign_dir(scenario, design=design, fe_max_hz=DESIGN_FE_MAX_HZ[design], fe_export_hz=EXPORT_HZ[design])


def _model(design: str):
    """The campaign's hybrid model with the truth's pairing (as the diagnosis builds it) and its channel tables."""
    from test_hybrid_model import truth_pairing

    folder = _campaign(design)
    manifest = json.loads((folder / "truth.json").read_text())
    fe = fem_import.read(folder / "fe_design.uff")
    model = hybrid_model(fe, truth_pairing(manifest, "flexural", fe=fe, folder=folder),
                         points=read_points(folder / "points.csv"), keep_fe="all", max_hz=500.0)
    tables = [pd.read_csv(folder / f"{s}_channels.csv") for s in ("flexural", "torsional")]
    return model, tables, manifest, folder


@pytest.fixture(scope="module")
def metro():
    return _model("metro")


@pytest.fixture(scope="module")
def freight():
    return _model("freight")


def test_a_description_giving_only_the_wheel_mass_splits_it_as_table_2_1(tmp_path):
    """Rim and web default to Table 2.1's shares of the wheel (150/251, 80/251), so a 180 kg wheel keeps a hub."""
    p = tmp_path / "metro.toml"
    p.write_text("[wheel]\nmass_kg = 180.0\n")
    d = read_description(p)
    assert d.rim_mass == pytest.approx(180.0 * 150 / 251) and d.web_mass == pytest.approx(180.0 * 80 / 251)
    assert d.hub_mass == pytest.approx(180.0 * 21 / 251)
    assert "rim_mass" not in d.given
    assert WheelsetDescription().with_values(wheel_mass=340.0).rim_mass == pytest.approx(340.0 * 150 / 251)
    stated = WheelsetDescription().with_values(rim_mass=140.0).with_values(wheel_mass=300.0)
    assert stated.rim_mass == 140.0 and stated.web_mass == pytest.approx(300.0 * 80 / 251)  # stated: kept


@pytest.mark.parametrize("design", ["metro", "freight"])
def test_masses_not_given_are_table_2_1_scaled_to_the_fe(design):
    """Without a description the masses add up to the FE's rigid-body mass in Table 2.1's proportions: the metro
    design's parts within 5 % (its proportions are Table 2.1's), the freight's axlebox nearer its 95 kg than Table
    2.1's 78 kg (only the scale is told; the rest the description must state, and the note says so)."""
    truth = get_design(design)
    fe_mass = truth.axle_mass + 2 * (truth.wheel_mass + truth.disc_mass + truth.axlebox_mass)
    d, notes = WheelsetDescription().fitted_to_fe(fe_mass, axleboxes_in_fe=True)
    assert d.wheelset_mass + 2 * d.axlebox_mass == pytest.approx(fe_mass)
    assert d.rim_mass + d.web_mass < d.wheel_mass
    assert "scaled" in notes[-1] and "[axlebox] mass_kg" in notes[-1]
    if design == "metro":
        assert d.axlebox_mass == pytest.approx(truth.axlebox_mass, rel=0.05)
        assert d.wheel_mass == pytest.approx(truth.wheel_mass, rel=0.05)
        np.testing.assert_allclose(d.axlebox_inertia, truth.axlebox_inertia, rtol=0.15)
    else:
        assert abs(d.axlebox_mass - truth.axlebox_mass) < abs(78.0 - truth.axlebox_mass)
    # a description that states every part is compared with the FE, relatively
    full = WheelsetDescription().with_values(axle_mass=283.0, disc_mass=135.0, wheel_mass=251.0, axlebox_mass=78.0)
    _, notes = full.fitted_to_fe(fe_mass, axleboxes_in_fe=True)
    assert any("% from the FE's rigid-body mass" in n for n in notes)
    _, notes = full.fitted_to_fe(1211.0, axleboxes_in_fe=True)
    assert not any("% from the FE's rigid-body mass" in n for n in notes)


def test_an_own_axlebox_node_tied_to_the_journal_is_the_axlebox_in_the_fe(metro):
    """The metro FE has its 60 kg axlebox on nodes 6000/7000 tied to the journals: the FE models it, whatever its
    890 kg says against Table 2.1's 1055/1211 kg (before: 'absent', 78 kg added on top). The body is the scaled
    default (within 5 % of the design's 60 kg) and the assumptions say where the mass came from."""
    model, tables, _, _ = metro
    att = AxleboxBearing().attach(model, tables)
    for box in att.data["boxes"]:
        assert (box.case, box.mass_in_fe) == ("own_node", True)
        assert "taken off the journal" in box.note
    assert att.data["mass"] == pytest.approx(get_design("metro").axlebox_mass, rel=0.05)
    text = " ".join(att.assumptions)
    assert "scaled" in text and "890.0 kg" in text and "carries up to" in text


def test_the_bearing_at_the_truth_explains_the_metro_measurement(metro):
    """With the scaled masses the bearing at the campaign's true stiffnesses brings the misfit to within 1.25 times
    the noise floor (with the design's exact masses it is 1.05 times; before, with a 78 kg body added to the FE's
    60 kg axlebox, no stiffness could)."""
    from ema import estimate_frf, read_hammer
    from receptance.diagnosis import Measurement, misfit

    model, tables, manifest, folder = metro
    t = manifest["scenario"]["effects"]["bearing"]
    truth = {k: t[k] for k in ("radial_N_per_m", "axial_N_per_m", "rocking_Nm_per_rad", "right_over_left")}
    meas = [Measurement(estimate_frf(read_hammer(folder / f"{s}.uff", folder / f"{s}_channels.csv")), tab, s)
            for s, tab in zip(("flexural", "torsional"), tables)]
    r = misfit(AxleboxBearing().apply(model, truth, tables), meas)
    assert r.summary < 1.25 * r.noise_floor


def test_the_wheel_seat_joint_on_a_light_wheel_has_finite_poles(metro):
    """The metro wheel weighs 180 kg: the joint takes the scaled default (within 5 %) off the seat and its model
    solves (before: 251 kg off a seat carrying less, a negative mass and 'matrix contains invalid numeric
    entries')."""
    model, tables, _, _ = metro
    att = WheelSeatJoint().attach(model, tables)
    assert att.data["mass"] == pytest.approx(get_design("metro").wheel_mass, rel=0.05)
    m2 = att.apply(model, {p.name: p.initial for p in att.parameters})
    f = m2.modes()["f_hz"].to_numpy()
    assert np.all(np.isfinite(f)) and np.sum((f > 1) & (f < 500)) >= 8
    assert np.all(np.isfinite(m2.frf_at_channels(tables[0], np.array([50.0, 200.0, 450.0])).data))


@pytest.mark.parametrize("effect,toml,key", [
    (AxleboxBearing, "[axlebox]\nmass_kg = 78.0\n", "[axlebox] mass_kg"),
    (AxleboxBearing, '[axlebox]\nmass_kg = 60.0\ninertia_kg_m2 = [0.9, 1.2, 0.9]\n', "[axlebox] mass_kg and inertia"),
])
def test_more_mass_than_the_fe_carries_is_refused_naming_the_key(metro, tmp_path, effect, toml, key):
    """Table 2.1's axlebox (78 kg, or its 0.9/1.2/0.9 kg m^2) stated for the metro design exceeds what the FE's
    modes carry at the journal (74 kg, 0.59/0.82 kg m^2): refused as not applicable, naming the description key,
    instead of a negative mass. (The wheel-seat joint is not refused so: see the next test.)"""
    model, tables, _, _ = metro
    p = tmp_path / "desc.toml"
    p.write_text(toml)
    with pytest.raises(EffectNotApplicable, match="negative") as err:
        effect().attach(model, tables, read_description(p))
    assert key in err.value.remedy


def test_a_heavier_wheel_stated_for_the_joint_keeps_the_model_consistent(metro):
    """Table 2.1's 251 kg wheel stated for the 180 kg metro wheel. This was refused ("non-finite poles") while the
    hybrid model pinned the test's frequencies by energy shares weighted by the modified diagonal mass; that refusal
    was the pinning's artifact (``tests/test_lab_joint_identity.py``). The joint's floating frame hands the layout's
    inertia back to the FE's modes, so whatever wheel is laid out, the joint made rigid is the FE's model again: the
    modes come back to 1e-4, and the layout's mass shows in the assumptions for the user to check. (The seat's
    apparent mass, 238 kg here, is no bound for it: a synthetic ring wheel whose seat carries 132 kg holds a 251 kg
    wheel exactly, ``tests/test_effect_geometry.py``.)"""
    model, tables, _, _ = metro
    att = WheelSeatJoint().attach(model, tables, WheelsetDescription().with_values(wheel_mass=251.0))
    rigid = att.apply(model, {p.name: 100.0 * p.upper for p in att.parameters})
    # to 1e-4: 100 times the upper bounds is rigid to 5e-5 at 354 Hz (before: non-finite poles)
    np.testing.assert_allclose(np.sort(rigid.modes()["f_hz"].to_numpy()), np.sort(model.modes()["f_hz"].to_numpy()),
                               rtol=1e-4)
    assert any("wheel's 251 kg were laid out" in a for a in att.assumptions)


def test_freight_masses_follow_its_fe_and_its_given_axlebox(freight):
    """Freight (1320 kg, 95 kg axleboxes): the scaled default axlebox (85 kg) replaces Table 2.1's 78 kg and says so;
    the axlebox stated as the design's is used as given and the bearing at the truth then fits to the noise
    floor's level (1.2 times)."""
    from ema import estimate_frf, read_hammer
    from receptance.diagnosis import Measurement, misfit

    model, tables, manifest, folder = freight
    truth = get_design("freight")
    att = AxleboxBearing().attach(model, tables)
    assert abs(att.data["mass"] - truth.axlebox_mass) < abs(78.0 - truth.axlebox_mass)
    assert any("1320.0 kg" in a for a in att.assumptions)
    desc = WheelsetDescription().with_values(axlebox_mass=truth.axlebox_mass,
                                             axlebox_inertia=tuple(truth.axlebox_inertia))
    t = manifest["scenario"]["effects"]["bearing"]
    values = {k: t[k] for k in ("radial_N_per_m", "axial_N_per_m", "rocking_Nm_per_rad", "right_over_left")}
    meas = [Measurement(estimate_frf(read_hammer(folder / f"{s}.uff", folder / f"{s}_channels.csv")), tab, s)
            for s, tab in zip(("flexural", "torsional"), tables)]
    r = misfit(AxleboxBearing().apply(model, values, tables, desc), meas)
    assert r.summary < 1.2 * r.noise_floor
