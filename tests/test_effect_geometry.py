"""The effects attach by physical geometry to FE exports drawn in any style, and add exactly the physics they claim.

Oracle: small hand-made wheelset FE models (tests/lumped_wheelset.py: beams, springs, lumped masses, rigid links,
solved by a dense eigenproblem with every mode kept), each drawn the ways a design office draws a wheelset — the
axlebox as its own node tied to the journal, lumped on the journal or absent; a wheel as a ring of nodes on a hub
tied to the seat, or as a rigid rim body on web springs — and the same wheelset with the hidden effect built into
the FE (axlebox on bearing springs, hub on press-fit springs). With a complete modal basis the structural
modification is exact, so the effect applied to the design model must give the truth's natural frequencies.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pandas as pd
import pytest

from lumped_wheelset import M_RIM, M_WEB, M_WHEEL, R_HUB, R_RIM, R_WHEEL, build
from receptance.diagnosis import DiagnosisError, EffectNotApplicable, Measurement, diagnose
from receptance.diagnosis.effects import AxleboxBearing, Effect, Parameter, RigSuspension, WheelSeatJoint
from receptance.diagnosis.geometry import axlebox_attachment, wheel_attachment, wheelset_geometry
from receptance.dofs import Point
from receptance.effect_modifications import RigSprings, SlingSprings
from receptance.modal_model import ModalModel
from receptance.wheelset_description import DescriptionError, WheelsetDescription, read_description

BEARING = {"radial_N_per_m": 1e9, "axial_N_per_m": 2.5e8, "rocking_Nm_per_rad": 5e6, "right_over_left": 1.0}
JOINT = {"rocking_Nm_per_rad": 6e7, "radial_N_per_m": 2e9, "axial_N_per_m": 1e9, "torsional_Nm_per_rad": 2e8}


def describe(scale: float = 1.0, **kw) -> WheelsetDescription:
    """The lumped wheelset's masses (no discs) and radii, as a user would state them."""
    return WheelsetDescription(axle_mass=283.0, n_discs=0, wheel_mass=M_WHEEL, rim_mass=M_RIM, web_mass=M_WEB,
                               rim_radius=scale * R_RIM, hub_radius=scale * R_HUB, rolling_radius=scale * R_WHEEL,
                               **kw)


def as_model(fe, points) -> ModalModel:
    f = fe.freqs_hz
    pts = {n: Point(n, node, xyz) for n, (node, xyz) in points.items()}
    return ModalModel(fe, f, np.zeros(f.size), tuple("rigid" if v == 0 else "fe" for v in f),
                      np.arange(1, f.size + 1), np.full(f.size, np.nan), points=pts)


def lowest(model: ModalModel, n: int) -> np.ndarray:
    f = model.modes()["f_hz"].to_numpy()
    return np.sort(f[f > 0.1])[:n]


@pytest.mark.parametrize("axlebox", ["own_node", "lumped", "absent"])
@pytest.mark.parametrize("wheel", ["ring", "rim_body"])
def test_axlebox_bearing_is_exact_whatever_way_the_fe_holds_the_axlebox(axlebox, wheel):
    """The effect finds how the FE holds the axlebox (its own tied node, lumped on the journal, left out: told
    apart by the geometry and the total mass of the rigid-body modes) and gives the truth's frequencies (axlebox
    on bearing springs) to 1e-6 on the lowest 30 modes."""
    truth, _, _ = build("bearing", wheel)
    _, fe, points = build(axlebox, wheel)
    model = as_model(fe, points)
    desc = describe()
    att = AxleboxBearing().attach(model, (), desc)
    box = att.data["boxes"][0]
    assert box.case == axlebox
    assert box.mass_in_fe == (axlebox != "absent")
    assert "axlebox_L" in box.carried_points
    assert ("taken off the journal" in att.assumptions[0]) == (axlebox != "absent")
    got = lowest(att.apply(model, BEARING), 30)
    np.testing.assert_allclose(got, truth.frequencies()[:30], rtol=1e-6)


@pytest.mark.parametrize("wheel,truth_style", [("ring", "joint"), ("rim_body", "rim_joint")])
def test_wheel_seat_joint_is_exact_for_a_ring_wheel_and_a_rim_on_web_springs(wheel, truth_style):
    """A ring of rim nodes on a hub tied to the seat, or one rim body node on web springs with the hub lumped on
    the seat: the wheel's nodes are found through the elements (a rim node at the seat's place on springs is no
    tie), and with the mass layout the description states the floating-frame joint reproduces the truth (hub on
    press-fit springs) to 1e-3 (the rim nodes' own small rotary inertia is not in the layout)."""
    truth, _, _ = build("own_node", truth_style)
    _, fe, points = build("own_node", wheel)
    model = as_model(fe, points)
    att = WheelSeatJoint().attach(model, (), describe())
    fixed = att.data
    assert fixed["seat_nodes"][0] == 103  # the axle node at the hub plane
    if wheel == "ring":
        assert fixed["hub_nodes"][0] == 1000  # the hub node tied to the seat is the frame
        assert len(fixed["carried"][0]) == 25
    else:
        assert fixed["hub_nodes"][0] == 103  # the hub is lumped on the seat: the seat is the frame
        assert fixed["carried"][0] == (1000,)  # the rim body node, on springs at the seat's place
        assert "one FE node" in att.assumptions[0]
    got = lowest(att.apply(model, JOINT), 30)
    np.testing.assert_allclose(got, truth.frequencies()[:30], rtol=1e-3)


def test_an_export_without_elements_keeps_the_axlebox_node_off_the_axle_line(caplog):
    """A UFF without dataset 2412, or a Nastran punch with nodes-only geometry: no connectivity tells the axle
    from the axlebox node that sits on its journal (both on the axis, at one place). The points table's node is the
    part tied there, so the bearing attaches as with the elements: its own node, the same frequencies (1e-9), and
    the fallback is said once. Before, the axlebox node became axle, the axlebox 'lumped on the journal', and on the
    virtual lab's bearing campaign the fit ended at E 30.98 % instead of 7.95 %."""
    from dataclasses import replace

    _, fe, points = build("own_node", "ring")
    bare = replace(fe, elements=(), source="nodes_only.uff")
    desc = describe()
    with caplog.at_level(logging.WARNING, logger="receptance"):
        boxes = [axlebox_attachment(as_model(f, points), wheelset_geometry(as_model(f, points), desc), "L")
                 for f in (fe, bare, bare)]
    assert [(b.case, b.axlebox_node, b.journal_node) for b in boxes] == [("own_node", 1500, 101)] * 3
    assert "no element records" in boxes[1].note
    said = [r for r in caplog.records if "no element records" in r.getMessage()]
    assert len(said) == 1 and "nodes_only.uff" in said[0].getMessage()
    f_full = lowest(AxleboxBearing().apply(as_model(fe, points), BEARING, (), desc), 30)
    f_bare = lowest(AxleboxBearing().apply(as_model(bare, points), BEARING, (), desc), 30)
    np.testing.assert_allclose(f_bare, f_full, rtol=1e-9)


def test_an_export_without_rigid_body_modes_is_refused_with_the_remedy():
    """Modes exported from the first flexible mode up (Nastran EIGRL V1 > 0): the free wheelset's model would lack
    its rigid-body mass line below that mode, and on the virtual lab's bearing campaign the diagnosis accepted a
    'residuals' pseudo-effect and a bearing 20 % off, silently. Now a named error says what to export."""
    from fem_import import FEModes, MassNormalisationError
    from receptance.hybrid import check_fe_for_model

    _, fe, _ = build("own_node", "ring")
    flexible = fe.freqs_hz > 1.0
    cut = FEModes(fe.node_ids, fe.xyz, fe.elements, fe.freqs_hz[flexible], fe.shapes[flexible],
                  fe.modal_mass[flexible], source="no_rigid.uff")
    assert check_fe_for_model(fe) is not None
    with pytest.raises(MassNormalisationError, match=r"no_rigid.uff: the export holds no rigid-body modes .* "
                                                     r"export the modes from 0 Hz"):
        check_fe_for_model(cut)


@pytest.mark.parametrize("effect", [AxleboxBearing(), WheelSeatJoint()])
def test_effects_on_rotations_say_when_the_export_has_none(effect):
    """A 3-DOF export (translations only, as a solid model writes it): the bearing's rocking and the seat's rocking
    and torsion need nodal rotations. Before, the fit failed on 'journal_L:rx' or on a rim point 0.16 m from its
    node, reported as a fault of the toolkit; now the effect is not applicable, with the reason and the remedy."""
    from dataclasses import replace

    _, fe, points = build("own_node", "ring")
    model = as_model(replace(fe, shapes=fe.shapes[..., :3]), points)
    with pytest.raises(EffectNotApplicable, match="no rotations .* solid-element export") as exc:
        effect.attach(model, (), describe())
    assert "6 DOF per node" in exc.value.remedy


def test_attachments_scale_with_the_model_not_with_millimetres():
    """Twice the size and other node labels: the same attachments (tolerances are fractions of the wheel)."""
    _, fe, points = build("own_node", "ring", scale=2.0, id_offset=70000)
    model = as_model(fe, points)
    geo = wheelset_geometry(model, describe(2.0))
    assert geo.scale == pytest.approx(2 * R_WHEEL)
    assert list(geo.axle_nodes) == [70101 + k for k in range(9)]
    box = axlebox_attachment(model, geo, "R")
    assert (box.journal_node, box.axlebox_node, box.case) == (70109, 72500, "own_node")
    wheel = wheel_attachment(model, geo, "L")
    assert (wheel.seat_node, wheel.reference_node) == (70103, 71000)
    truth, _, _ = build("bearing", "rim_body", scale=2.0)
    _, fe, points = build("own_node", "rim_body", scale=2.0, id_offset=70000)
    got = lowest(AxleboxBearing().apply(as_model(fe, points), BEARING, (), describe(2.0)), 20)
    np.testing.assert_allclose(got, truth.frequencies()[:20], rtol=1e-6)


def test_what_the_effects_cannot_attach_to_is_said_with_the_remedy():
    _, fe, points = build("lumped", "ring")
    no_boxes = {k: v for k, v in points.items() if not k.startswith("axlebox")}
    with pytest.raises(EffectNotApplicable) as exc:
        AxleboxBearing().attach(as_model(fe, no_boxes), (), describe())
    assert "axlebox L centre is unknown" in exc.value.reason and "points.csv" in exc.value.remedy
    # the description states what the geometry contradicts
    with pytest.raises(EffectNotApplicable, match="its own FE node"):
        AxleboxBearing().attach(as_model(fe, points), (), describe(axlebox_in_fe="own_node"))
    # an FE that already holds the axlebox on springs of its own
    _, springy, pts = build("bearing", "ring", loss=0.0)
    with pytest.raises(EffectNotApplicable, match="already holds the axlebox"):
        AxleboxBearing().attach(as_model(springy, pts), (), describe())
    no_contact = {k: v for k, v in points.items() if not k.startswith("contact")}
    with pytest.raises(EffectNotApplicable) as exc:
        WheelSeatJoint().attach(as_model(fe, no_contact), (), describe())
    assert exc.value.to_dict() == {"name": "wheel_seat_joint", "reason": exc.value.reason,
                                   "what_would_make_it_apply": exc.value.remedy}


def test_slings_move_continuously_along_the_axle_and_match_springs_at_a_node():
    """A sling exactly at an axle node is a ground spring at that node; between nodes the motion is blended
    linearly, so the modes change continuously with the sling position (it can be fitted)."""
    _, fe, points = build("own_node", "rim_body")
    model = as_model(fe, points)
    att = RigSuspension().attach(model, (), describe())
    names = [p.name for p in att.parameters]
    assert names == ["vertical_N_per_m", "horizontal_N_per_m", "hanging_y_m"]
    k = {"vertical_N_per_m": 3.5e5, "horizontal_N_per_m": 4e3}
    at_node = lowest(att.apply(model, dict(k, hanging_y_m=0.85)), 12)
    pts = {"h1": Point("h1", 102, (0.0, -0.85, 0.0)), "h2": Point("h2", 108, (0.0, 0.85, 0.0))}
    direct = lowest(model.with_points(pts).with_modification(RigSprings(points=("h1", "h2"),
                                                                        stiffness=(4e3, 4e3, 3.5e5))), 12)
    np.testing.assert_allclose(at_node, direct, rtol=1e-9)
    bounce = [lowest(att.apply(model, dict(k, hanging_y_m=y)), 2)[1] for y in (0.84, 0.85, 0.86)]
    assert abs(bounce[2] - bounce[1]) < 0.02 * bounce[1] and abs(bounce[1] - bounce[0]) < 0.02 * bounce[1]
    # the roll mode (rotation about x) stiffens as the slings move out: k y^2
    roll = [lowest(att.apply(model, dict(k, hanging_y_m=y)), 3)[-1] for y in (0.3, 0.6, 0.9)]
    assert roll[0] < roll[1] < roll[2]
    # the user's old call, without the sling position, hangs at the axleboxes (its starting value)
    assert att.apply(model, k).modifications[-1].weights is not None
    # hanging points given in the description: no position is fitted
    given = RigSuspension().attach(model, (), describe(hanging_points=("axlebox_L", "axlebox_R")))
    assert [p.name for p in given.parameters] == ["vertical_N_per_m", "horizontal_N_per_m"]
    assert isinstance(given.apply(model, k).modifications[-1], RigSprings)
    assert isinstance(att.apply(model, dict(k, hanging_y_m=0.5)).modifications[-1], SlingSprings)


# ------------------------------------------------------------------------------------------ diagnosis robustness
@dataclass(frozen=True)
class _Broken(Effect):
    """A catalogue entry with a bug: it raises a plain RuntimeError when attached."""

    name: ClassVar[str] = "broken_effect"

    def parameters(self):
        return (Parameter("k", "N/m", 1.0, 100.0, 10.0),)

    def attach(self, model, setups=(), description=None):
        raise RuntimeError("index out of range in a user's effect")


def _synthetic_measurement(model: ModalModel) -> Measurement:
    """The model's own accelerance at four sensors, with a coherence of 0.999 over 5 hits (a noise floor)."""
    from ema.frf import FrequencyResponse

    rows = [("hammer", "force", 104, (0.0, -0.35, 0.0), (0, 0, 1))]
    rows += [(f"axle_{k}", "acceleration", 101 + k, (0.0, y, 0.0), (0, 0, 1))
             for k, y in enumerate((-1.0, -0.85, 0.0, 0.85))]
    table = pd.DataFrame([{"node": 900 + i, "name": n, "quantity": q, "unit": "N" if q == "force" else "m/s^2",
                           "x": p[0], "y": p[1], "z": p[2], "dx": d[0], "dy": d[1], "dz": d[2], "fe_node": fn,
                           "setup": "s1"} for i, (n, q, fn, p, d) in enumerate(rows)])
    f = np.arange(10.0, 500.0, 0.5)
    H = model.frf_at_channels(table, f)
    frf = FrequencyResponse(f, H.data, H.outputs, ("hammer",), "accelerance", coherence=np.full(H.data.shape, 0.999),
                            n_averages=np.full(H.n_out, 5))
    return Measurement(frf, table, "s1")


@pytest.mark.parametrize("workers", [1, 2])
def test_a_candidate_that_fails_or_does_not_apply_never_ends_the_diagnosis(workers, caplog):
    _, fe, points = build("lumped", "rim_body")
    model = as_model(fe, {k: v for k, v in points.items() if not k.startswith("axlebox")})
    meas = _synthetic_measurement(model)
    catalogue = [AxleboxBearing(), _Broken(), RigSuspension()]
    with caplog.at_level(logging.WARNING, logger="receptance"):
        result = diagnose(model, [meas], catalogue=catalogue, max_effects=1, workers=workers,
                          description=describe())
    na = {d["name"]: d for d in result.not_applicable}
    assert set(na) == {"axlebox_bearing", "broken_effect"}
    assert "axlebox L centre is unknown" in na["axlebox_bearing"]["reason"]
    assert "RuntimeError" in na["broken_effect"]["reason"]
    assert [f.name for f in result.rounds[0]] == ["rig_suspension"]  # the others did not stop it
    assert result.accepted == ()  # the model is its own measurement: nothing is missing
    warned = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert any("axlebox_bearing" in w and "not applicable" in w for w in warned)
    assert any("broken_effect" in w and "failed" in w for w in warned)
    doc = result.to_json()
    assert {d["name"] for d in doc["not_applicable"]} == {"axlebox_bearing", "broken_effect"}
    assert all(set(d) == {"name", "reason", "what_would_make_it_apply"} for d in doc["not_applicable"])
    # and in the report's diagnosis section, with the remedy
    from receptance.diagnosis.report import _section_diagnosis

    page = _section_diagnosis(result, doc["criterion"])
    assert "Candidates that could not be tried" in page and "axlebox L centre is unknown" in page
    assert na["axlebox_bearing"]["what_would_make_it_apply"].split()[0] in page


def test_only_the_toolkits_errors_leave_diagnose():
    _, fe, points = build("lumped", "rim_body")
    model = as_model(fe, points)
    meas = _synthetic_measurement(model)
    with pytest.raises(DiagnosisError, match="no measurement"):
        diagnose(model, [], max_effects=1)
    with pytest.raises(DiagnosisError, match="max_effects"):
        diagnose(model, [meas], max_effects=-1)


# -------------------------------------------------------------------------------------------- description file
def test_description_file_is_read_with_units_and_checked(tmp_path):
    p = tmp_path / "wheelset.toml"
    p.write_text('[axlebox]\nmass_kg = 80\ninertia_kg_m2 = [1.0, 1.3, 1.0]\nin_fe = "lumped"\n'
                 'centre_L_m = [0.0, -1.0, 0.0]\n[wheel]\nrim_mass_kg = 140.0\nhub_plane_R_m = 0.72\n'
                 '[rig]\nhanging_points = [[0.0, -0.55, 0.08], "axlebox_R"]\n', encoding="utf-8")
    d = read_description(p)
    assert (d.axlebox_mass, d.axlebox_inertia, d.axlebox_in_fe) == (80.0, (1.0, 1.3, 1.0), "lumped")
    assert d.axlebox_centres == {"L": (0.0, -1.0, 0.0), "R": None} and d.hub_planes["R"] == 0.72
    assert d.hanging_points == ((0.0, -0.55, 0.08), "axlebox_R")
    assert d.given >= {"axlebox_mass", "rim_mass", "hanging_points", "axlebox_centres"}
    assert "wheel_mass" not in d.given and d.wheel_mass == 251.0  # Table 2.1 default
    assert d.wheelset_mass == pytest.approx(283 + 2 * 251 + 2 * 135)
    bad = tmp_path / "bad.toml"
    bad.write_text("[axlebox]\nmas_kg = 80\n")
    with pytest.raises(DescriptionError, match=r"bad.toml: unknown key 'mas_kg' in \[axlebox\]; known keys: mass_kg"):
        read_description(bad)
    bad.write_text("[wheel]\nmass_kg = -3\n")
    with pytest.raises(DescriptionError, match="wheel_mass must be a finite number > 0, got -3"):
        read_description(bad)
    bad.write_text('[axlebox]\nin_fe = "welded"\n')
    with pytest.raises(DescriptionError, match="in_fe must be one of"):
        read_description(bad)
    bad.write_text("[bogie]\nmass_kg = 1\n")
    with pytest.raises(DescriptionError, match=r"unknown section \[bogie\]"):
        read_description(bad)
    bad.write_text("[wheel\n")
    with pytest.raises(DescriptionError, match="not a TOML file"):
        read_description(bad)
    with pytest.raises(FileNotFoundError):
        read_description(tmp_path / "none.toml")
