"""Shapes at sensor points: FEModes.at_points / nearest_node / shapes_at_channels.

Oracles: the lab's truth manifest (mode shapes at the sensors, the force
point and the named points, computed by the lab from its own FE solution)
and closed forms for a rigid link.
"""

from __future__ import annotations


import numpy as np
import pandas as pd
import pytest

import fem_import
from fem_import import FEGeometryError, FEModes, MissingCoordinatesError, PointToleranceError, shapes_at_channels


@pytest.fixture(scope="module")
def uff_modes(control_dir):
    return fem_import.read(control_dir / "fe_design.uff")


def _rel_err(a, b):
    return np.max(np.abs(a - b)) / np.max(np.abs(b))


@pytest.mark.parametrize("setup", ["flexural", "torsional"])
def test_sensor_shapes_equal_truth_for_non_degenerate_modes(setup, uff_modes, control_dir, control_manifest):
    view = control_manifest["setups"][setup]
    table = pd.read_csv(control_dir / f"{setup}_channels.csv")
    acc = table[table["quantity"] == "acceleration"]
    assert acc["node"].tolist() == view["accelerometer_nodes"]
    shapes = shapes_at_channels(uff_modes, table)
    assert shapes.shape == (29, 25)
    force = table[table["quantity"] == "force"]
    b = uff_modes.at_points(force["fe_node"], force[["x", "y", "z"]].to_numpy(), force[["dx", "dy", "dz"]].to_numpy())
    checked = 0
    for mode in view["modes"]:
        if len(mode["fe_partner"]) != 1:
            continue
        k = mode["fe_partner"][0] - 1
        truth = np.asarray(mode["shapes"])
        sign = np.sign(truth @ shapes[:, k])
        assert _rel_err(sign * shapes[:, k], truth) < 1e-5, mode["description"]
        assert abs(sign * b[0, k] - mode["input_shape"]) < 1e-5 * np.max(np.abs(truth))
        checked += 1
    assert checked == 5  # 3 torsion modes, 2 wheel 0-nodal-diameter modes


def test_degenerate_truth_shapes_lie_in_the_fe_pair_span(uff_modes, control_dir, control_manifest):
    view = control_manifest["setups"]["flexural"]
    shapes = shapes_at_channels(uff_modes, pd.read_csv(control_dir / "flexural_channels.csv"))
    pairs = [m for m in view["modes"] if len(m["fe_partner"]) == 2 and m["f_hz"] > 0]
    assert len(pairs) == 10
    for mode in pairs:
        basis = shapes[:, np.asarray(mode["fe_partner"]) - 1]
        truth = np.asarray(mode["shapes"])
        coef, *_ = np.linalg.lstsq(basis, truth, rcond=None)
        assert _rel_err(basis @ coef, truth) < 1e-5
        # mass-normalised mixtures of a mass-normalised pair: unit coefficient vector
        assert np.linalg.norm(coef) == pytest.approx(1.0, abs=1e-4)


def test_named_points_equal_truth(uff_modes, control_dir, control_manifest):
    points = pd.read_csv(control_dir / "points.csv")
    sensors = shapes_at_channels(uff_modes, pd.read_csv(control_dir / "flexural_channels.csv"))
    modes = [m for m in control_manifest["setups"]["flexural"]["modes"] if len(m["fe_partner"]) == 1]
    for mode in modes:
        k = mode["fe_partner"][0] - 1
        sign = np.sign(np.asarray(mode["shapes"]) @ sensors[:, k])
        for _, row in points.iterrows():
            got = uff_modes.at_points([row["fe_node"]] * 3, [row[["x", "y", "z"]].to_numpy(float)] * 3, np.eye(3),
                                      names=[row["name"]] * 3)[:, k]
            truth = np.asarray(mode["points"][row["name"]])
            scale = np.max(np.abs(mode["shapes"]))
            assert np.max(np.abs(sign * got - truth)) < 1e-5 * scale, (mode["description"], row["name"])


def _link_model(n_dof=6):
    """One node at the origin with u = (0, 0, 0.5), theta = (0, 0, 2) in mode 0 and u = (1, 0, 0) in mode 1."""
    shapes = np.zeros((2, 2, n_dof))
    shapes[0, 0, 2] = 0.5
    if n_dof == 6:
        shapes[0, 0, 5] = 2.0
    shapes[1, 0, 0] = 1.0
    return FEModes(node_ids=[7, 8], xyz=[[0, 0, 0], [3, 0, 0]], elements=(), freqs_hz=[10.0, 20.0], shapes=shapes,
                   modal_mass=[1.0, 1.0], source="link")


def test_rigid_link_closed_form():
    fe = _link_model()
    # point at (0.25, 0, 0.1) on node 7: u + theta x r = (0,0,0.5) + (0,0,2) x (0.25,0,0.1) = (0, 0.5, 0.5)
    d = np.array([[0, 1, 0], [0, 0, 1], [1, 0, 0], [0, 1, 1] / np.sqrt(2)])
    got = fe.at_points([7] * 4, [[0.25, 0, 0.1]] * 4, d)
    np.testing.assert_allclose(got[:, 0], [0.5, 0.5, 0.0, 1 / np.sqrt(2)], atol=1e-15)
    np.testing.assert_allclose(got[:, 1], [0.0, 0.0, 1.0, 0.0], atol=1e-15)


def test_three_dof_shapes_need_points_within_tolerance():
    fe = _link_model(3)
    got = fe.at_points([7], [[0.01, 0.0, 0.02]], [[0, 0, 1]])
    assert got[0, 0] == 0.5  # the translation of the node, no rotation arm
    with pytest.raises(PointToleranceError, match=r"sensor A: .*no rotations.* node 7 and the point lies 0\.25 m from it.*0\.05 m"):
        fe.at_points([7], [[0.25, 0, 0.0]], [[0, 1, 0]], names=["sensor A"])
    assert fe.at_points([7], [[0.25, 0, 0.0]], [[1, 0, 0]], tolerance=0.3)[0, 1] == 1.0


def test_nearest_node_and_tolerance():
    fe = _link_model()
    assert fe.nearest_node([2.98, 0.01, 0.0]) == 8
    with pytest.raises(PointToleranceError, match=r"hammer: no FE node within 0\.05 m.*closest is node 7 at 1\.5 m"):
        fe.nearest_node([0, 1.5, 0], name="hammer")
    # fe_node None -> nearest node within tolerance
    got = fe.at_points([None, np.nan], [[0.0, 0.0, 0.01], [3.0, 0.0, 0.0]], [[0, 0, 1], [1, 0, 0]])
    np.testing.assert_allclose(got, fe.at_points([7, 8], [[0.0, 0.0, 0.01], [3.0, 0.0, 0.0]],
                                                 [[0, 0, 1], [1, 0, 0]]))


def test_far_sensor_without_fe_node_is_refused(uff_modes, control_dir):
    table = pd.read_csv(control_dir / "flexural_channels.csv")
    acc = table[table["quantity"] == "acceleration"].copy()
    acc["fe_node"] = np.nan
    acc.loc[acc.index[0], ["x", "y", "z"]] = [0.0, 0.0, 2.0]  # 2 m off the wheelset
    with pytest.raises(PointToleranceError, match=r"channel 'axle_01': no FE node within 0\.05 m.*closest is node"):
        shapes_at_channels(uff_modes, acc)
    # sensors sitting on their node are found without fe_node
    on = acc.iloc[1:].copy()
    rows = [uff_modes.index(n) for n in table.loc[on.index, "fe_node"]]
    on[["x", "y", "z"]] = uff_modes.xyz[rows]
    with_nodes = on.assign(fe_node=table.loc[on.index, "fe_node"])
    np.testing.assert_allclose(shapes_at_channels(uff_modes, on), shapes_at_channels(uff_modes, with_nodes))


def test_punch_without_geometry_needs_positions_none(control_dir, uff_modes):
    pch = fem_import.read(control_dir / "fe_design.pch")
    with pytest.raises(MissingCoordinatesError, match=r"axle_01: node 1019 has no coordinates.*geometry="):
        pch.at_points([1019], [[0.0, -0.56, 0.074]], [[0, 0, 1]], names=["axle_01"])
    with pytest.raises(MissingCoordinatesError, match="no node coordinates"):
        pch.nearest_node([0.0, 0.0, 0.0])
    at_node = pch.at_points([1019, 1019], None, [[0, 0, 1], [0, 1, 0]])
    row = uff_modes.index(1019)
    np.testing.assert_allclose(at_node, uff_modes.shapes[:, row, [2, 1]].T, atol=1e-6 * np.abs(uff_modes.shapes).max())


def test_bad_point_inputs_are_named(uff_modes):
    with pytest.raises(FEGeometryError, match=r"s1: fe_node 424242 is not a node"):
        uff_modes.at_points([424242], [[0, 0, 0]], [[0, 0, 1]], names=["s1"])
    with pytest.raises(FEGeometryError, match=r"point 0: direction must be a finite non-zero vector"):
        uff_modes.at_points([1019], [[0, 0, 0]], [[0, 0, 0]])
    with pytest.raises(FEGeometryError, match=r"positions must have shape \(1, 3\)"):
        uff_modes.at_points([1019], [[0, 0]], [[0, 0, 1]])
    with pytest.raises(FEGeometryError, match="tolerance must be a non-negative"):
        uff_modes.at_points([1019], [[0, 0, 0]], [[0, 0, 1]], tolerance=-1)
    with pytest.warns(UserWarning, match="normalised to unit length"):
        scaled = uff_modes.at_points([1019], None, [[0, 0, 2.0]])
    np.testing.assert_allclose(scaled, uff_modes.at_points([1019], None, [[0, 0, 1.0]]))


def test_channel_table_checks(uff_modes, control_dir):
    table = pd.read_csv(control_dir / "flexural_channels.csv")
    with pytest.raises(ValueError, match=r"lacks column\(s\) \['dz'\]"):
        shapes_at_channels(uff_modes, table.drop(columns="dz"))
    with pytest.raises(ValueError, match="no row with quantity 'velocity'"):
        shapes_at_channels(uff_modes, table, quantity="velocity")
    every = shapes_at_channels(uff_modes, table, quantity=None)
    assert every.shape == (30, 25)
    bad = table.copy()
    bad.loc[3, "fe_node"] = 99999
    with pytest.raises(FEGeometryError, match=rf"channel '{bad.loc[3, 'name']}': fe_node 99999"):
        shapes_at_channels(uff_modes, bad)
