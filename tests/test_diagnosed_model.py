"""From the lab to the track: the diagnosed model's file, its roles, and the wheelset in service.

Oracles: a save/load round trip gives the same modes; a model file written before the effects learnt their new
options (no ``remove_from_journal``, no ``carried_points``) loads with the behaviour it was written with; the
in-service model drops the test artefacts and keeps the wheelset properties; a lab model plus a primary suspension
that vanishes reproduces the test frequencies (the base-frequency correction), where solving it from the test
frequencies would count the lab effect twice.
"""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from test_effect_geometry import BEARING, JOINT, as_model, build, describe, lowest
from receptance.diagnosis.effects import AxleboxBearing, MassLoading, RigSuspension, WheelSeatJoint
from receptance.effect_modifications import BearingBodies, RigSprings, SeatJoints, SlingSprings
from receptance.model_io import load_model, save_model
from receptance.modification import PrimarySuspension


@pytest.fixture(scope="module")
def lab():
    """A design FE (axlebox lumped on the journal, rim on web springs) whose modes below 300 Hz the test saw 3 %
    lower, with the bearing and the slings the diagnosis accepted."""
    _, fe, points = build("lumped", "rim_body")
    model = as_model(fe, points)
    f = fe.freqs_hz
    seen = (f > 0) & (f < 300)
    hybrid = replace(model, freqs_hz=np.where(seen, 0.97 * f, f), zeta=np.where(f > 0, 0.002, 0.0),
                     origin=tuple("test" if s else o for s, o in zip(seen, model.origin)))
    diagnosed = AxleboxBearing().apply(hybrid, BEARING, (), describe())
    diagnosed = RigSuspension().apply(diagnosed, {"vertical_N_per_m": 3.5e5, "horizontal_N_per_m": 4e3,
                                                  "hanging_y_m": 0.6}, (), describe())
    return hybrid, diagnosed


def test_diagnosed_model_file_round_trip(lab, tmp_path):
    _, diagnosed = lab
    path = save_model(diagnosed, tmp_path / "hybrid_model.npz")
    back = load_model(path)
    assert [m.kind for m in back.modifications] == ["bearing_bodies", "bearing_bodies", "sling_springs"]
    assert back.modifications[0].remove_from_journal and back.modifications[0].carried_points == (("axlebox_L",),)
    np.testing.assert_allclose(lowest(back, 20), lowest(diagnosed, 20), rtol=1e-12)
    joint = WheelSeatJoint().apply(back.without_modifications(), JOINT, (), describe())
    again = load_model(save_model(joint, tmp_path / "joint.npz"))
    assert isinstance(again.modifications[0], SeatJoints)
    np.testing.assert_allclose(lowest(again, 20), lowest(joint, 20), rtol=1e-12)


def test_the_exports_own_mode_numbers_survive_the_model_file(lab, tmp_path):
    """An export that numbers its modes 101, 102, ... (a Nastran run from a restart, modes in another order): the
    model file keeps the numbers; a file written before they were stored reads back as 1..m."""
    hybrid, _ = lab
    numbered = replace(hybrid, fe=replace(hybrid.fe, mode_numbers=np.arange(len(hybrid.fe)) + 101))
    path = save_model(numbered, tmp_path / "numbered.npz")
    np.testing.assert_array_equal(load_model(path).fe.mode_numbers, np.arange(len(hybrid.fe)) + 101)
    with np.load(path, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files if k != "fe_mode_numbers"}
    np.savez_compressed(tmp_path / "before.npz", **arrays)
    np.testing.assert_array_equal(load_model(tmp_path / "before.npz").fe.mode_numbers, np.arange(len(hybrid.fe)) + 1)


def test_model_files_written_before_the_new_options_still_load(lab, tmp_path):
    """An old file's bearing has no ``remove_from_journal``/``carried_points`` and its bodies no
    ``carried_points``: it loads as it was written (mass taken off the journal, the axlebox node carried)."""
    _, fe, points = build("own_node", "rim_body")
    model = AxleboxBearing().apply(as_model(fe, points), BEARING, (), describe())
    path = save_model(model, tmp_path / "new.npz")
    with np.load(path, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    header = json.loads(str(arrays["header"]))
    for mod in header["modifications"]:
        assert mod["kind"] == "bearing_bodies"
        mod.pop("remove_from_journal")
        mod.pop("carried_points")
    arrays["header"] = np.array(json.dumps(header))
    old = tmp_path / "old.npz"
    np.savez_compressed(old, **arrays)
    back = load_model(old)
    assert back.modifications[0].remove_from_journal and back.modifications[0].carried_points == ()
    # the axlebox point sits on the axlebox node, which the body carries: the same model
    np.testing.assert_allclose(lowest(back, 20), lowest(model, 20), rtol=1e-10)
    np.testing.assert_allclose(back.receptance("axlebox_L:z", "contact_L:z", [50.0, 150.0]).data,
                               model.receptance("axlebox_L:z", "contact_L:z", [50.0, 150.0]).data, rtol=1e-9)


def test_service_model_keeps_the_wheelset_and_drops_the_test(lab):
    _, diagnosed = lab
    with_sensors = MassLoading().apply(diagnosed, {"sensor_mass_kg": 0.05}, [_one_sensor()])
    service = with_sensors.for_service()
    assert [m.kind for m in service.modifications] == ["bearing_bodies", "bearing_bodies"]
    assert {m.role for m in with_sensors.modifications} == {"wheelset", "test_artefact"}
    assert "removed test artefacts ['sling_springs', 'sensor_masses']" in service.history[-1]
    assert RigSprings.role == SlingSprings.role == "test_artefact" and BearingBodies.role == "wheelset"


def _one_sensor():
    import pandas as pd

    return pd.DataFrame([{"node": 1, "name": "s", "quantity": "acceleration", "x": 0.0, "y": 0.0, "z": 0.0,
                          "dx": 0.0, "dy": 0.0, "dz": 1.0, "fe_node": 105, "setup": "a"}])


def test_service_model_starts_from_corrected_frequencies(lab):
    """The test frequencies contain the bearing. A service model (bearing kept, primary suspension added) is
    solved from the FE frequencies corrected by what the test said about the lab configuration: with a vanishing
    suspension it gives back the test's frequencies (2e-3), where starting from the test frequencies and adding
    the bearing again misses them by the bearing's own shift."""
    hybrid, diagnosed = lab
    service = diagnosed.for_service()
    tiny = service.with_modification(PrimarySuspension(stiffness=(1e-3, 1e-3, 1e-3), damping=(0.0, 0.0, 0.0)))
    pinned = lowest(diagnosed.for_service(), 8)
    np.testing.assert_allclose(pinned, np.sort(hybrid.freqs_hz[hybrid.freqs_hz > 0])[:8], rtol=1e-9)
    np.testing.assert_allclose(lowest(tiny, 8), pinned, rtol=2e-3)
    naive = replace(tiny, origin=tuple("fe" if o == "test" else o for o in tiny.origin))  # test freqs as the base
    assert np.max(np.abs(lowest(naive, 8) / pinned - 1)) > 5 * np.max(np.abs(lowest(tiny, 8) / pinned - 1))
    # the suspension of Table 2.1 adds the bounce and roll modes near 7 and 9 Hz, the flexible modes barely move
    full = lowest(service.with_modification(PrimarySuspension()), 12)
    assert 5 < full[0] < 10 and 7 < full[1] < 12
