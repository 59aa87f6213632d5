"""An FE export drawn in any frame: the railway frame found from the points and the whole lab chain unchanged by it.

Oracles: the frame a known rotation put the inputs in (the points must give its inverse back, for any rotation and
origin); the hand-made wheelset FE of tests/lumped_wheelset.py, whose receptances, transfer functions and bearing
effect in the railway frame are the reference every turned copy must reproduce; and the virtual lab's ``bearing``
campaign, diagnosed as written and after turning every file (FE export, points, channel tables) into a CAD frame
(axle along X, Y up, another origin): the same effect with the same parameters and errors.
"""

from __future__ import annotations

import itertools

import numpy as np
import pandas as pd
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from fem_import.modes import FEModes
from lumped_wheelset import build
from receptance.dofs import DofError, Point
from receptance.frame import SNAP_DEG, RailwayFrame, railway_frame, to_railway_frame
from receptance.modal_model import ModalModel

#: the CAD frame of many design offices: X along the axle, Y up, Z along the track (x_cad = Q_CAD x_rail)
Q_CAD = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])


def _rotation(q) -> np.ndarray:
    """The proper rotation of a (not necessarily unit) quaternion."""
    w, x, y, z = np.asarray(q, float) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _placed(fe: FEModes, points: dict, q: np.ndarray, shift) -> tuple[FEModes, dict]:
    """The FE and points as a design office in frame ``x' = q x + shift`` would export them."""
    turned = fe.rotated(q)
    moved = FEModes(turned.node_ids, turned.xyz + np.asarray(shift, float), turned.elements, turned.freqs_hz,
                    turned.shapes, turned.modal_mass, source="cad.uff")
    pts = {n: Point(n, node, tuple(q @ np.asarray(xyz) + shift)) for n, (node, xyz) in points.items()}
    return moved, pts


def _model(fe: FEModes, points: dict) -> ModalModel:
    f = fe.freqs_hz
    pts = {n: p if isinstance(p, Point) else Point(n, p[0], p[1]) for n, p in points.items()}
    return ModalModel(fe, f, np.full(f.size, 0.01) * (f > 0), tuple("rigid" if v == 0 else "fe" for v in f),
                      np.arange(1, f.size + 1), np.full(f.size, np.nan), points=pts)


@pytest.fixture(scope="module")
def wheelset():
    _, fe, points = build("own_node", "ring")
    return fe, points


_quaternions = st.lists(st.floats(-1.0, 1.0), min_size=4, max_size=4).filter(lambda q: np.linalg.norm(q) > 0.2)
_shifts = st.lists(st.floats(-5.0, 5.0), min_size=3, max_size=3)


def _off_axes_deg(rot: np.ndarray) -> float:
    """Angle [deg] between the railway frame drawn by ``rot`` and the nearest frame of the FE's own axes."""
    best = 180.0
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((-1.0, 1.0), repeat=3):
            p = np.zeros((3, 3))
            p[range(3), perm] = signs
            if np.linalg.det(p) > 0:
                best = min(best, RailwayFrame(rot.T @ p.T).angle_deg)
    return best


@settings(max_examples=40, deadline=None)
@given(q=_quaternions, shift=_shifts)
def test_the_points_give_back_any_oblique_rotation_and_origin(wheelset, q, shift):
    """Whatever oblique frame and origin the FE was drawn in, the points recover the rotation (to 1e-12) and the
    turned FE has the railway frame's shapes and the railway coordinates up to the origin's shift."""
    fe, points = wheelset
    rot = _rotation(q)
    assume(_off_axes_deg(rot) > SNAP_DEG + 1.0)
    fe_cad, pts_cad = _placed(fe, points, rot, shift)
    frame, pts, fe2, _, _ = to_railway_frame(pts_cad, fe_cad)
    np.testing.assert_allclose(frame.rotation @ rot, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(fe2.shapes, fe.shapes, atol=1e-12 * np.abs(fe.shapes).max())
    origin = fe2.xyz - fe.xyz
    np.testing.assert_allclose(origin, np.broadcast_to(origin[0], origin.shape), atol=1e-12)
    for name, (_, xyz) in points.items():
        np.testing.assert_allclose(np.asarray(pts[name].xyz) - origin[0], xyz, atol=1e-12)


def test_points_given_by_their_node_only_take_the_fe_coordinates_and_the_fe_axes(wheelset):
    """The lumped wheelset's contact node stands 7.5° off the bottom of its 24-node rim: the frame is the FE's
    axes all the same (snapped, and said), in the railway frame and in the CAD frame; a frame 30° oblique is
    turned exactly."""
    fe, points = wheelset
    by_node = {n: Point(n, node) for n, (node, _) in points.items()}
    for q in (np.eye(3), Q_CAD):
        fe_cad, _ = _placed(fe, points, q, (0.3, -1.2, 4.0))
        frame = railway_frame(by_node, fe_cad)
        np.testing.assert_allclose(frame.rotation, q.T, atol=1e-12)
        assert "axlebox_L→axlebox_R" in frame.basis and "7.5° off the FE's axes, taken as them" in frame.basis
    tilt = _rotation([np.cos(np.radians(15.0)), np.sin(np.radians(15.0)), 0.0, 0.0])  # 30° about x
    fe_cad, pts_cad = _placed(fe, points, tilt, (0.0, 0.0, 0.0))
    np.testing.assert_allclose(railway_frame(pts_cad, fe_cad).rotation @ tilt, np.eye(3), atol=1e-12)


def test_a_model_in_the_railway_frame_is_left_untouched(wheelset):
    """The virtual lab's own exports (and every model built before) keep their bits: the same objects back."""
    fe, points = wheelset
    pts = {n: Point(n, node, xyz) for n, (node, xyz) in points.items()}
    table = pd.DataFrame({"x": [0.0], "y": [0.5], "z": [0.1], "dx": [0.0], "dy": [0.0], "dz": [1.0]})
    frame, pts2, fe2, (table2,), _ = to_railway_frame(pts, fe, tables=[table])
    assert frame.is_identity and pts2 is pts and fe2 is fe and table2 is table
    assert frame.describe().startswith("the FE export is in the railway frame")


def test_receptances_transfer_functions_and_effects_are_those_of_the_railway_frame(wheelset):
    """A wheelset drawn in the CAD frame, turned by the points: receptances between contact points and axleboxes
    in x, y, z, the primary suspension's system, the vertical + lateral transfer function with contact angles
    and the bearing effect (which needs the axle along y) all equal the railway-frame model's (1e-9)."""
    from receptance.diagnosis.effects import AxleboxBearing
    from receptance.diagnosis.errors import EffectNotApplicable
    from receptance.modification import PrimarySuspension
    from receptance.transfer import vertical_lateral_transfer
    from receptance.wheelset_description import WheelsetDescription

    fe, points = wheelset
    ref = _model(fe, points)
    fe_cad, pts_cad = _placed(fe, points, Q_CAD, (0.3, -1.2, 4.0))
    with pytest.raises(EffectNotApplicable, match="along y"):
        AxleboxBearing().attach(_model(fe_cad, pts_cad), (), WheelsetDescription())
    frame, pts, fe2, _, _ = to_railway_frame(pts_cad, fe_cad)
    turned = _model(fe2, pts)
    dofs = [f"{p}_{s}:{a}" for p in ("contact", "axlebox") for s in "LR" for a in "xyz"]
    f = np.geomspace(5.0, 800.0, 60)
    for a, b in ((ref, turned), (ref.with_modification(PrimarySuspension()),
                                 turned.with_modification(PrimarySuspension()))):
        ha, hb = a.receptance(dofs, dofs[:3], f), b.receptance(dofs, dofs[:3], f)
        np.testing.assert_allclose(hb.data, ha.data, rtol=1e-9, atol=1e-9 * np.abs(ha.data).max())
    ta = vertical_lateral_transfer(ref, f, theta_l=-0.06, theta_r=0.4)
    tb = vertical_lateral_transfer(turned, f, theta_l=-0.06, theta_r=0.4)
    np.testing.assert_allclose(tb.transfer.data, ta.transfer.data, rtol=1e-9,
                               atol=1e-9 * np.abs(ta.transfer.data).max())
    bearing = {"radial_N_per_m": 1e9, "axial_N_per_m": 2.5e8, "rocking_Nm_per_rad": 5e6, "right_over_left": 1.0}
    fa = AxleboxBearing().apply(ref, bearing, (), WheelsetDescription()).modes()["f_hz"].to_numpy()
    fb = AxleboxBearing().apply(turned, bearing, (), WheelsetDescription()).modes()["f_hz"].to_numpy()
    np.testing.assert_allclose(fb, fa, rtol=1e-9)


def test_the_description_and_channel_tables_turn_with_the_fe(wheelset):
    from receptance.wheelset_description import WheelsetDescription

    fe, points = wheelset
    fe_cad, pts_cad = _placed(fe, points, Q_CAD, (0.0, 0.0, 0.0))
    desc = WheelsetDescription(axlebox_centres={"L": tuple(Q_CAD @ [0.0, -1.0, 0.0]), "R": None},
                               hanging_points=(tuple(Q_CAD @ [0.0, -0.55, 0.1]), "axlebox_R"),
                               hub_planes={"L": -0.7, "R": 0.7})
    table = pd.DataFrame({"name": ["a"], "x": [Q_CAD[0] @ [0.1, 0.5, 0.2]], "y": [Q_CAD[1] @ [0.1, 0.5, 0.2]],
                          "z": [Q_CAD[2] @ [0.1, 0.5, 0.2]], "dx": [Q_CAD[0, 2]], "dy": [Q_CAD[1, 2]],
                          "dz": [Q_CAD[2, 2]]})
    _, _, _, (t2,), d2 = to_railway_frame(pts_cad, fe_cad, tables=[table], description=desc)
    np.testing.assert_allclose(t2[["x", "y", "z"]].to_numpy()[0], [0.1, 0.5, 0.2], atol=1e-15)
    np.testing.assert_allclose(t2[["dx", "dy", "dz"]].to_numpy()[0], [0.0, 0.0, 1.0], atol=1e-15)
    np.testing.assert_allclose(d2.axlebox_centres["L"], [0.0, -1.0, 0.0], atol=1e-15)
    assert d2.axlebox_centres["R"] is None and d2.hanging_points[1] == "axlebox_R"
    np.testing.assert_allclose(d2.hanging_points[0], [0.0, -0.55, 0.1], atol=1e-15)
    assert d2.hub_planes == {"L": -0.7, "R": 0.7}  # axial positions: the projection on the axle, kept
    assert table["x"].iloc[0] == Q_CAD[0] @ [0.1, 0.5, 0.2]  # the caller's table is not modified


@pytest.mark.parametrize("move,match", [
    (("contact_L", (0.0, -0.73, 0.0)), "contact_L .* lies on the axle axis"),
    (("contact_R", (0.0, 0.73, 0.41)), "different sides of the axle axis"),
    (("contact_R", (0.0, 0.73, -0.75)), "point 13.1° apart"),
    (("axlebox_R", (0.0, -1.0, 0.0)), "axlebox_L and axlebox_R are at the same place"),
])
def test_points_that_contradict_a_wheelset_are_named(wheelset, move, match):
    fe, points = wheelset
    pts = {n: Point(n, node, xyz) for n, (node, xyz) in points.items()}
    name, xyz = move
    pts[name] = Point(name, pts[name].fe_node, xyz)
    with pytest.raises(DofError, match=match):
        railway_frame(pts, fe, source="points.csv")


def test_without_a_contact_position_the_fe_frame_is_kept_and_said(wheelset):
    fe, points = wheelset
    pts = {n: Point(n, node, xyz) for n, (node, xyz) in points.items() if n.startswith("axlebox")}
    frame, pts2, fe2, _, _ = to_railway_frame(pts, fe)
    assert frame.is_identity and fe2 is fe and "do not fix it" in frame.basis


def test_the_field_refuses_a_model_that_is_not_in_the_railway_frame(wheelset):
    """A model built from a CAD-frame FE without turning it: its ``:z`` DOFs are not vertical, so the estimator
    refuses it, naming the FE axes and the remedy; a rotation that is not proper is refused too."""
    from estimator.errors import WheelsetModelError
    from estimator.inversion import sensor_model

    fe, points = wheelset
    fe_cad, pts_cad = _placed(fe, points, Q_CAD, (0.0, 0.0, 0.0))
    channels = pd.DataFrame({"name": ["ACC"], "side": ["L"], "x": [0.0], "y": [0.0], "z": [0.1],
                             "direction": ["z"]})
    with pytest.raises(WheelsetModelError, match=r"not in the railway frame .* railway x = \+Z, y = \+X, z = \+Y of the FE"):
        sensor_model(_model(fe_cad, pts_cad), channels)
    _, pts, fe2, _, _ = to_railway_frame(pts_cad, fe_cad)
    sensor_model(_model(fe2, pts), channels)
    with pytest.raises(ValueError, match="proper 3 x 3 rotation"):
        RailwayFrame(np.diag([1.0, 1.0, -1.0]))


def _turn_campaign(src, dst, q: np.ndarray, shift) -> None:
    """Write the lab campaign ``src`` as a lab with frame ``x' = q x + shift`` would: FE export, points and
    channel tables turned; the hammer files (and their direction codes) as recorded."""
    import shutil

    import fem_import
    from lab_data.uff_export import ElementRecord, write_fe_uff

    dst.mkdir(parents=True, exist_ok=True)
    for name in ("flexural.uff", "torsional.uff"):
        shutil.copy(src / name, dst / name)
    fe = fem_import.read(src / "fe_design.uff")
    turned = fe.rotated(q)
    write_fe_uff(dst / "fe_design.uff", fe.node_ids, turned.xyz + shift,
                 [ElementRecord(e.element_id, e.fe_descriptor, e.physical_property, 1, 1, e.nodes)
                  for e in fe.elements], fe.freqs_hz, turned.shapes, model_name="wheelset in the CAD frame")
    pts = pd.read_csv(src / "points.csv")
    pts[["x", "y", "z"]] = pts[["x", "y", "z"]].to_numpy() @ q.T + shift
    pts.to_csv(dst / "points.csv", index=False)
    for setup in ("flexural", "torsional"):
        t = pd.read_csv(src / f"{setup}_channels.csv")
        t[["x", "y", "z"]] = t[["x", "y", "z"]].to_numpy() @ q.T + shift
        t[["dx", "dy", "dz"]] = t[["dx", "dy", "dz"]].to_numpy() @ q.T
        t.to_csv(dst / f"{setup}_channels.csv", index=False)


@pytest.mark.slow
# the copied hammer files keep the direction codes of the frame they were recorded in, which the CAD-frame tables
# now contradict: the reader says so and uses the tables, as it should
@pytest.mark.filterwarnings("ignore::ema.hammer_io.ChannelDirectionWarning")
def test_lab_diagnosis_of_a_campaign_in_a_cad_frame_is_the_railway_frames(tmp_path):
    """The ``bearing`` campaign with its design FE, points and channel tables in the CAD frame (axle along X, Y
    up, origin moved by (0.2, 1.5, -0.3) m): the diagnosis says it turned the FE, accepts the bearings with the same
    stiffnesses and the same errors as on the campaign as written (1e-6), and its saved model is accepted by the
    field side. Before the frame was found, the bearing, joint and rig effects were not applicable there and the
    residual error stayed at 5.6 × the noise floor."""
    import json

    from lab_data.cache import campaign_dir
    from receptance.diagnosis.workflow import run_lab_diagnosis
    from receptance.frame import check_railway_frame

    src = campaign_dir("bearing", fe_export_hz=2000.0)
    cad = tmp_path / "cad"
    _turn_campaign(src, cad, Q_CAD, np.array([0.2, 1.5, -0.3]))
    runs = {}
    for name, d in (("railway", src), ("cad", cad)):
        setups = [(d / f"{s}.uff", d / f"{s}_channels.csv") for s in ("flexural", "torsional")]
        runs[name] = run_lab_diagnosis(setups, d / "fe_design.uff", d / "points.csv", tmp_path / name, max_effects=1,
                                       workers=2)
    ref, got = runs["railway"], runs["cad"]
    assert [f.name for f in got.diagnosis.accepted] == [f.name for f in ref.diagnosis.accepted] == ["axlebox_bearing"]
    for k, v in ref.diagnosis.accepted[0].params.items():
        assert got.diagnosis.accepted[0].params[k] == pytest.approx(v, rel=1e-6), k
    assert got.diagnosis.final.summary == pytest.approx(ref.diagnosis.final.summary, rel=1e-6)
    assert got.diagnosis.initial.summary == pytest.approx(ref.diagnosis.initial.summary, rel=1e-6)
    doc = json.loads((tmp_path / "cad" / "diagnosis.json").read_text())
    np.testing.assert_allclose(doc["frame"]["rotation_fe_to_railway"], Q_CAD.T, atol=1e-12)
    assert "turned by 120.0°" in doc["frame"]["note"]
    check_railway_frame(got.model.points, got.model.fe)  # the field side takes the saved model

    # 'railmodal model build' from the CAD-frame files (with the hammer validation) saves the railway model
    from railmodal.cli import main
    from receptance.model_io import load_model

    models = {}
    for name, d in (("railway", src), ("cad", cad)):
        assert main(["--quiet", "model", "build", "--pairing", str(tmp_path / name / "pairing.csv"), "--fem",
                     str(d / "fe_design.uff"), "--points", str(d / "points.csv"), "--hammer", str(d / "flexural.uff"),
                     "--channels", str(d / "flexural_channels.csv"), "--keep-fe", "all", "--robustness-models", "2",
                     "--out", str(tmp_path / f"build_{name}")]) == 0
        models[name] = load_model(tmp_path / f"build_{name}" / "hybrid_model.npz")
    dofs = ["contact_L:z", "contact_L:y", "axlebox_L:z", "axlebox_R:y", "contact_R:x"]
    f = np.geomspace(10.0, 500.0, 40)
    ha = models["railway"].receptance(dofs, dofs[:2], f).data
    hb = models["cad"].receptance(dofs, dofs[:2], f).data
    np.testing.assert_allclose(hb, ha, rtol=1e-9, atol=1e-9 * np.abs(ha).max())
    va = pd.read_csv(tmp_path / "build_railway" / "validation_flexural.csv")
    vb = pd.read_csv(tmp_path / "build_cad" / "validation_flexural.csv")
    np.testing.assert_allclose(vb["db_rms"], va["db_rms"], rtol=1e-6)
