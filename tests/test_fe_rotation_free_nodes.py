"""Nodes without rotations in a 6-DOF export: a solid element's node.

Nastran's punch and most UFF writers export every grid with six components; the nodes only solid elements
connect carry translations alone and are written with R1-R3 = 0. A rigid link from such a node (a sensor a few
centimetres off it, an effect's rocking spring on it) would silently drop the rotation's share of the motion.

Oracles: the rigid-link formula ``u(P) = u + θ × (P − x_n)`` evaluated by hand; the virtual lab's own exports (mesh
and beam styles) have rotations at every node, so nothing changes for them; a node whose rotations are zeroed is
found, a point off it beyond the tolerance is refused naming the point and node, within it the translation is
the answer, and the bearing's rocking springs on a journal without rotations are not applicable, named.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import fem_import
from fem_import.errors import PointToleranceError
from fem_import.modes import FEModes
from lab_data.cache import campaign_dir


def _modes(zero_rotations=()):
    """Three nodes on a line, two modes with rotations; the nodes in ``zero_rotations`` carry none."""
    rng = np.random.default_rng(3)
    shapes = rng.standard_normal((2, 3, 6))
    for n in zero_rotations:
        shapes[:, n, 3:] = 0.0
    xyz = np.array([[0.0, 0.0, 0.0], [0.0, 0.5, 0.0], [0.0, 1.0, 0.0]])
    return FEModes(np.array([1, 2, 3]), xyz, (), np.array([10.0, 20.0]), shapes, np.ones(2), source="three.uff")


def test_a_node_whose_rotations_are_zero_in_every_mode_is_found():
    assert not _modes().rotation_free.any()
    assert _modes(zero_rotations=(1,)).rotation_free.tolist() == [False, True, False]
    three_dof = replace(_modes(), shapes=_modes().shapes[:, :, :3])
    assert three_dof.rotation_free.all()


def test_a_point_off_a_node_without_rotations_is_refused_and_one_on_it_takes_its_translation():
    fe = _modes(zero_rotations=(1,))
    d = np.array([[0.0, 0.0, 1.0]])
    # on a node with rotations: the rigid link, by hand
    offset = np.array([0.1, 0.0, 0.0])
    got = fe.at_points([3], [[0.1, 1.0, 0.0]], d)
    want = (fe.shapes[:, 2, :3] + np.cross(fe.shapes[:, 2, 3:], offset)) @ d[0]
    np.testing.assert_allclose(got[0], want, rtol=1e-12)
    # 0.1 m off the solid node: refused, naming the point and the node
    with pytest.raises(PointToleranceError, match=r"axle_01: node 2 carries no rotations .* lies 0\.1 m from it"):
        fe.at_points([2], [[0.1, 0.5, 0.0]], d, names=["axle_01"])
    # 1 cm off it, within the tolerance: its translation (a surface sensor on a surface node)
    got = fe.at_points([2], [[0.01, 0.5, 0.0]], d)
    np.testing.assert_allclose(got[0], fe.shapes[:, 1, 2], rtol=0, atol=0)


@pytest.mark.parametrize("style", ["mesh", "beam"])
def test_the_virtual_labs_exports_have_rotations_at_every_node(style):
    config = {"fe_export_hz": 2000.0} if style == "mesh" else {"fe_export_hz": 2000.0, "fe_style": style}
    fe = fem_import.read(campaign_dir("control", **config) / "fe_design.uff")
    assert fe.has_rotations and not fe.rotation_free.any()


def test_the_bearing_is_not_applicable_on_journals_without_rotations():
    """The journals of the virtual lab's export made solid nodes (their rotations zeroed): the bearing's rocking
    springs would act on nothing, so it is refused with the nodes named, not fitted to an undetermined value."""
    from lab_campaign_model import truth_paired
    from receptance.diagnosis.effects import AxleboxBearing
    from receptance.diagnosis.errors import EffectNotApplicable

    model, meas, _ = truth_paired(campaign_dir("bearing", fe_export_hz=2000.0))
    att = AxleboxBearing().attach(model, [m.channels for m in meas])
    journals = sorted({int(p.fe_node) for p in att.points})
    shapes = model.fe.shapes.copy()
    idx = [model.fe.index(n) for n in journals]
    shapes[:, idx, 3:] = 0.0
    solid = replace(model, fe=replace(model.fe, shapes=shapes))
    assert solid.fe.rotation_free[idx].all() and solid.fe.rotation_free.sum() == len(idx)
    with pytest.raises(EffectNotApplicable, match=rf"node {journals[0]} carries no rotations .* the axlebox L moves "
                                                  rf"with its journal's rotation"):
        AxleboxBearing().attach(solid, [m.channels for m in meas])


def test_the_wheel_seat_joint_is_not_applicable_on_seats_without_rotations():
    from lab_campaign_model import truth_paired
    from receptance.diagnosis.effects import WheelSeatJoint
    from receptance.diagnosis.errors import EffectNotApplicable

    model, meas, _ = truth_paired(campaign_dir("joint", fe_export_hz=2000.0))
    att = WheelSeatJoint().attach(model, [m.channels for m in meas])
    seats = sorted({int(p.fe_node) for p in att.points})
    shapes = model.fe.shapes.copy()
    shapes[:, [model.fe.index(n) for n in seats], 3:] = 0.0
    solid = replace(model, fe=replace(model.fe, shapes=shapes))
    with pytest.raises(EffectNotApplicable, match=rf"node {seats[0]} carries no rotations .* wheel L's seat turns"):
        WheelSeatJoint().attach(solid, [m.channels for m in meas])


def test_a_rotation_asked_of_a_node_without_rotations_is_refused():
    from lab_campaign_model import truth_paired
    from receptance.dofs import DofError

    model, _, _ = truth_paired(campaign_dir("control", fe_export_hz=2000.0))
    node = model.points["axlebox_L"].fe_node
    got = model.rows(["axlebox_L:ry"])  # the journal's rotation about the axle: torsion modes carry it
    assert np.abs(got).max() > 0
    shapes = model.fe.shapes.copy()
    shapes[:, model.fe.index(node), 3:] = 0.0
    solid = replace(model, fe=replace(model.fe, shapes=shapes))
    with pytest.raises(DofError, match=rf"'axlebox_L:ry': node {node} carries no rotations"):
        solid.rows(["axlebox_L:ry"])
