"""Round-trip tests of the UFF and Nastran punch exporters of ``lab_data``.

pyuff is the reference reader for the universal files; the punch file is read
back with a small fixed-column parser written here, independent of the
writer.  Precision of the formats (see the module docstrings):

* UFF 2411 coordinates ``D25.16``: exact double round trip.
* UFF 55 frequencies and shapes ``1PE13.6``: 7 significant digits,
  relative error <= 5e-7, checked at rtol 1e-6.
* UFF 58b data: IEEE float32, exact to ``np.float32(x)``; ``dt`` as
  ``1PE13.6``, exact for 1/51200 s.
* Punch eigenvalues ``1PE15.7`` (8 digits), components ``1PE18.6`` (7 digits),
  checked at rtol 1e-6.
"""

from __future__ import annotations

import dataclasses
import math
import re
import time

import numpy as np
import pytest

pyuff = pytest.importorskip("pyuff")

from lab_data.nastran_punch import write_punch_eigenvectors  # noqa: E402
from lab_data.uff_export import (  # noqa: E402
    ElementRecord,
    TimeHistory,
    write_fe_uff,
    write_time_histories,
)

FS = 51200.0
DT = 1.0 / FS


# --------------------------------------------------------------------------
# fixtures
# --------------------------------------------------------------------------
def _mesh():
    node_ids = np.array([10, 20, 30, 40, 50, 60])
    xyz = np.array([
        [0.0, -1.0, 0.0],
        [0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.1, 1.0, 0.45],
        [-0.1, 1.0, 0.45],
        [-0.1, 1.0, -0.45],
    ]) + np.array([1e-7, -1.0 / 3.0, 2.0 / 7.0])   # non-round coordinates
    elements = [
        ElementRecord(1, 21, 1, 1, 7, (10, 20)),
        ElementRecord(2, 21, 1, 1, 7, (20, 30)),
        ElementRecord(3, 94, 2, 1, 8, (30, 40, 50, 60)),
        ElementRecord(4, 161, 3, 0, 9, (20,)),
        ElementRecord(5, 136, 4, 0, 10, (10, 60)),
        ElementRecord(6, 122, 0, 0, 11, (30, 40, 50)),
    ]
    return node_ids, xyz, elements


def _modes(n_nodes, seed=0):
    rng = np.random.default_rng(seed)
    freqs = np.array([0.0, 87.654321])              # rigid-body + elastic mode
    shapes = rng.normal(size=(2, n_nodes, 6)) * 10.0 ** rng.uniform(-6, 2, size=(2, n_nodes, 6))
    shapes[0] = 0.0
    shapes[0, :, 2] = 0.0281                         # vertical rigid translation
    return freqs, shapes


def _history(**kw):
    base = dict(hit=1, node=101, direction=3, quantity="acceleration", unit="m/s^2",
                name="axle_01", dt=DT, data=np.linspace(-1.0, 1.0, 16), ref_node=7,
                ref_direction=-3)
    base.update(kw)
    return TimeHistory(**base)


# --------------------------------------------------------------------------
# UFF FE model: 164, 2411, 2412, 55
# --------------------------------------------------------------------------
def test_fe_uff_round_trip_with_pyuff(tmp_path):
    node_ids, xyz, elements = _mesh()
    freqs, shapes = _modes(node_ids.size)
    path = write_fe_uff(tmp_path / "wheelset.unv", node_ids, xyz, elements, freqs, shapes,
                        model_name="wheelset FE", description="free-free")
    assert path.exists()

    uff = pyuff.UFF(str(path))
    assert list(uff.get_set_types()) == [164, 2411, 2412, 55, 55]
    units, nodes, elems, *modes = uff.read_sets()

    assert units["units_code"] == 1 and units["length"] == 1.0 and units["force"] == 1.0

    # 2411: D25.16 keeps all 17 significant digits -> exact.
    np.testing.assert_array_equal(nodes["node_nums"].astype(int), node_ids)
    np.testing.assert_array_equal(np.column_stack([nodes["x"], nodes["y"], nodes["z"]]), xyz)
    assert np.all(nodes["def_cs"] == 0) and np.all(nodes["disp_cs"] == 0)

    # 2412: pyuff groups elements by FE descriptor.
    for el in elements:
        (rec,) = [r for r in elems[el.fe_descriptor] if r["element_nums"] == el.element_id]
        assert tuple(rec["nodes_nums"]) == el.nodes
        assert rec["num_nodes"] == len(el.nodes)
        assert (rec["phys_table"], rec["mat_table"], rec["color"]) == (
            el.physical_property, el.material_property, el.color)
        if el.fe_descriptor == 21:
            assert (rec["beam_orientation"], rec["beam_foreend_cross"], rec["beam_aftend_cross"]) == (
                0, el.physical_property, el.physical_property)

    # 55: one dataset per mode, rigid mode included.
    for k, m in enumerate(modes):
        assert (m["analysis_type"], m["data_ch"], m["n_data_per_node"]) == (2, 3, 6)
        assert m["mode_n"] == k + 1
        assert m["modal_m"] == 1.0 and m["modal_damp_vis"] == 0.0
        assert m["id1"] == "wheelset FE" and m["id2"] == "free-free"
        assert "SI" in m["id3"]
        np.testing.assert_allclose(m["freq"], freqs[k], rtol=1e-6, atol=0)
        np.testing.assert_array_equal(m["node_nums"], node_ids)
        got = np.column_stack([m[f"r{i}"] for i in range(1, 7)])
        np.testing.assert_allclose(got, shapes[k], rtol=1e-6, atol=0)
    assert modes[0]["freq"] == 0.0


def test_fe_uff_rigid_element_node_lines_wrap_after_eight(tmp_path):
    node_ids = np.arange(1, 11)
    xyz = np.zeros((10, 3))
    xyz[:, 0] = np.arange(10)
    spider = ElementRecord(1, 122, 0, 0, 1, tuple(range(1, 11)))
    path = write_fe_uff(tmp_path / "spider.unv", node_ids, xyz, [spider], [], np.zeros((0, 10, 6)),
                        model_name="spider")
    lines = path.read_text().splitlines()
    i = lines.index("  2412")
    assert lines[i + 1].split() == ["1", "122", "0", "0", "1", "10"]
    assert lines[i + 2] == "".join(f"{n:10d}" for n in range(1, 9))     # FORMAT(8I10)
    assert lines[i + 3] == "".join(f"{n:10d}" for n in (9, 10))
    assert lines[i + 4] == "    -1"


def test_fe_uff_tiny_values_are_written_as_zero(tmp_path):
    node_ids, xyz, elements = _mesh()
    freqs, shapes = _modes(node_ids.size)
    shapes[1, 0, :] = [1e-120, -1e-100, 9.99e-99, 1e-99, -1.0, 0.0]
    path = write_fe_uff(tmp_path / "m.unv", node_ids, xyz, elements, freqs, shapes, model_name="m")
    mode = pyuff.UFF(str(path)).read_sets()[-1]
    got = [mode[f"r{i}"][0] for i in range(1, 7)]
    np.testing.assert_allclose(got, [0.0, 0.0, 9.99e-99, 1e-99, -1.0, 0.0], rtol=1e-6, atol=0)


# --------------------------------------------------------------------------
# UFF 58 / 58b time histories
# --------------------------------------------------------------------------
def test_time_histories_binary_round_trip(tmp_path):
    rng = np.random.default_rng(1)
    acc = rng.normal(size=4096) * 37.0                       # float64, not float32-exact
    force = np.abs(rng.normal(size=4096)) * 1500.0
    hist = [
        _history(hit=12, node=101, direction=-2, data=acc, name="axle_03"),
        _history(hit=12, node=7, direction=-3, quantity="force", unit="N", data=force,
                 name="hammer", ref_node=7, ref_direction=-3),
    ]
    path = write_time_histories(tmp_path / "hit12.uff", hist)
    sets = pyuff.UFF(str(path)).read_sets()
    assert len(sets) == 2
    for h, d in zip(hist, sets):
        assert d["binary"] == 1 and d["byte_ordering"] == 1 and d["fp_format"] == 2
        assert d["n_bytes"] == 4 * h.data.size
        assert d["ord_data_type"] == 2                       # real, single precision
        assert d["func_type"] == 1                           # time response
        assert d["ver_num"] == h.hit                         # hit = sequence number
        assert d["load_case_id"] == 0
        assert (d["rsp_node"], d["rsp_dir"]) == (h.node, h.direction)
        assert (d["ref_node"], d["ref_dir"]) == (h.ref_node, h.ref_direction)
        assert d["id1"] == h.name
        assert d["abscissa_spacing"] == 1 and d["abscissa_min"] == 0.0
        assert d["abscissa_inc"] == h.dt                     # 1.953125E-05 is exact
        assert d["abscissa_spec_data_type"] == 17 and d["abscissa_axis_units_lab"] == "s"
        np.testing.assert_array_equal(d["data"], h.data.astype(np.float32).astype(np.float64))
    assert sets[0]["ordinate_spec_data_type"] == 12
    assert sets[0]["ordinate_axis_units_lab"] == "m/s^2"
    assert sets[0]["ordinate_len_unit_exp"] == 1
    assert sets[1]["ordinate_spec_data_type"] == 13
    assert sets[1]["ordinate_axis_units_lab"] == "N"
    assert sets[1]["ordinate_force_unit_exp"] == 1


def test_time_histories_ascii_round_trip(tmp_path):
    data = np.random.default_rng(2).normal(size=1001) * 1e-3
    path = write_time_histories(tmp_path / "a.uff", [_history(data=data)], binary=False)
    (d,) = [pyuff.UFF(str(path)).read_sets()]
    assert d["binary"] == 0 and d["ord_data_type"] == 4
    np.testing.assert_array_equal(d["data"].astype(np.float32), data.astype(np.float32))
    assert d["abscissa_inc"] == DT and d["ver_num"] == 1


def test_two_hits_three_channels_listed_in_order(tmp_path):
    channels = [("hammer", 7, -3, "force", "N"), ("axle_01", 101, 3, "acceleration", "m/s^2"),
                ("axle_02", 102, -1, "acceleration", "m/s^2")]
    hist = [
        _history(hit=hit, node=node, direction=d, quantity=q, unit=u, name=name,
                 data=np.full(8, 10.0 * hit + c))
        for hit in (1, 2) for c, (name, node, d, q, u) in enumerate(channels)
    ]
    path = write_time_histories(tmp_path / "run.uff", hist)
    uff = pyuff.UFF(str(path))
    assert uff.get_n_sets() == 6
    assert list(uff.get_set_types()) == [58] * 6
    sets = uff.read_sets()
    assert [(d["ver_num"], d["id1"], d["rsp_node"]) for d in sets] == [
        (h.hit, h.name, h.node) for h in hist]
    assert [d["func_id"] for d in sets] == [1, 2, 3, 4, 5, 6]
    assert [d["data"][0] for d in sets] == [10.0, 11.0, 12.0, 20.0, 21.0, 22.0]


def test_write_360_datasets_of_51200_samples_is_fast(tmp_path):
    rng = np.random.default_rng(3)
    pool = [(rng.integers(-2**23, 2**23, size=51200) * 2.0**-20).astype(np.float32) for _ in range(6)]
    hist = [
        _history(hit=hit, node=100 + c, name=f"axle_{c:02d}", data=pool[c])
        for hit in range(1, 61) for c in range(6)
    ]
    t0 = time.perf_counter()
    path = write_time_histories(tmp_path / "campaign.uff", hist)
    elapsed = time.perf_counter() - t0
    assert path.stat().st_size > 360 * 51200 * 4
    assert elapsed < 5.0, f"writing 360 x 51200 samples took {elapsed:.2f} s"


# --------------------------------------------------------------------------
# Nastran punch
# --------------------------------------------------------------------------
def _parse_punch(text):
    """Independent fixed-column parser of a SORT1 real eigenvector punch file."""
    counters, blocks, block = [], [], None
    for line in text.splitlines():
        assert len(line) <= 80, line
        body, counters_field = line[:72], line[72:80]
        counters.append(int(counters_field))
        if body.startswith("$"):
            if body.startswith("$TITLE"):
                block = {"headers": [], "ids": [], "vals": []}
                blocks.append(block)
            block["headers"].append(body.split("=")[0].strip())
            if body.startswith("$TITLE   ="):
                block["title"] = body[10:70].rstrip()
            if body.startswith("$SUBCASE ID ="):
                block["subcase"] = int(body[13:25])
            if body.startswith("$EIGENVALUE ="):
                assert body[30:36] == "MODE ="
                block["eigenvalue"] = float(body[13:28])
                block["mode"] = int(body[36:42])
        elif body.startswith("-CONT-"):
            block["vals"][-1] += [float(body[c:c + 18]) for c in (18, 36, 54)]
        else:
            assert body[17] == "G"
            block["ids"].append(int(body[0:10]))
            block["vals"].append([float(body[c:c + 18]) for c in (18, 36, 54)])
    return counters, blocks


def test_punch_round_trip_and_layout(tmp_path):
    rng = np.random.default_rng(4)
    node_ids = np.array([1, 2, 1001, 99_999_999])
    freqs = np.array([0.0, 0.0, 54.321, 1234.5678901])
    shapes = rng.normal(size=(4, 4, 6)) * 10.0 ** rng.uniform(-8, 1, size=(4, 4, 6))
    path = write_punch_eigenvectors(tmp_path / "modes.pch", node_ids, freqs, shapes,
                                    title="WHEELSET SOL 103")
    text = path.read_text()
    counters, blocks = _parse_punch(text)

    assert all(len(line) == 80 for line in text.splitlines())
    assert counters == list(range(1, len(counters) + 1))
    assert len(blocks) == freqs.size
    for k, b in enumerate(blocks):
        assert b["headers"] == ["$TITLE", "$SUBTITLE", "$LABEL", "$EIGENVECTOR", "$REAL OUTPUT",
                                "$SUBCASE ID", "$EIGENVALUE"]
        assert b["title"] == "WHEELSET SOL 103" and b["subcase"] == 1 and b["mode"] == k + 1
        f = math.sqrt(max(b["eigenvalue"], 0.0)) / (2.0 * math.pi)
        np.testing.assert_allclose(f, freqs[k], rtol=1e-6, atol=0)
        assert b["ids"] == node_ids.tolist()
        np.testing.assert_allclose(np.array(b["vals"]), shapes[k], rtol=1e-6, atol=0)


# --------------------------------------------------------------------------
# invalid inputs
# --------------------------------------------------------------------------
def _fe_args(**over):
    node_ids, xyz, elements = _mesh()
    freqs, shapes = _modes(node_ids.size)
    args = dict(node_ids=node_ids, xyz=xyz, elements=elements, freqs_hz=freqs, shapes=shapes,
                model_name="m")
    args.update(over)
    return args


_N, _X, _E = _mesh()
_F, _S = _modes(_N.size)


@pytest.mark.parametrize("over, name", [
    (dict(node_ids=[1, 2, 3, 4, 5, 5]), "node_ids"),
    (dict(node_ids=[0, 2, 3, 4, 5, 6]), "node_ids"),
    (dict(node_ids=np.arange(6) + 1.5), "node_ids"),
    (dict(xyz=_X[:, :2]), "xyz"),
    (dict(xyz=np.where(_X == _X[2, 1], np.nan, _X)), "xyz"),
    (dict(freqs_hz=[-1.0, 10.0]), "freqs_hz"),
    (dict(freqs_hz=[0.0, np.inf]), "freqs_hz"),
    (dict(shapes=_S[:, :, :3]), "shapes"),
    (dict(shapes=_S[:1]), "shapes"),
    (dict(shapes=np.where(_S == _S[1, 0, 0], np.nan, _S)), "shapes"),
    (dict(shapes=_S * 1e120), "shapes"),
    (dict(elements=[ElementRecord(1, 21, 1, 1, 1, (10, 99))]), "elements[0].nodes[1]"),
    (dict(elements=[ElementRecord(1, 21, 1, 1, 1, (10, 20, 30))]), "elements[0].nodes"),
    (dict(elements=[ElementRecord(1, 44, 1, 1, 1, (10, 20, 30, 40))]), "elements[0].fe_descriptor"),
    (dict(elements=[_E[0], dataclasses.replace(_E[1], element_id=1)]), "elements[1].element_id"),
    (dict(elements=[dataclasses.replace(_E[0], color=-1)]), "elements[0].color"),
    (dict(model_name=""), "model_name"),
    (dict(model_name="x" * 81), "model_name"),
])
def test_write_fe_uff_rejects_invalid_input(tmp_path, over, name):
    with pytest.raises(ValueError, match=re.escape(name)):
        write_fe_uff(tmp_path / "bad.unv", **_fe_args(**over))


@pytest.mark.parametrize("over, name", [
    (dict(dt=0.0), "histories[0].dt"),
    (dict(dt=float("nan")), "histories[0].dt"),
    (dict(direction=7), "histories[0].direction"),
    (dict(hit=-1), "histories[0].hit"),
    (dict(hit=100_000), "histories[0].hit"),
    (dict(node=0), "histories[0].node"),
    (dict(quantity="velocity"), "histories[0].quantity"),
    (dict(unit="g"), "histories[0].unit"),
    (dict(quantity="force", unit="m/s^2"), "histories[0].unit"),
    (dict(data=np.zeros((2, 8))), "histories[0].data"),
    (dict(data=np.array([0.0, np.nan, 1.0])), "histories[0].data"),
    (dict(data=np.array([0.0, 1e300])), "histories[0].data"),
    (dict(name="axle\n01"), "histories[0].name"),
    (dict(name=""), "histories[0].name"),
])
def test_write_time_histories_rejects_invalid_history(tmp_path, over, name):
    with pytest.raises(ValueError, match=re.escape(name)):
        write_time_histories(tmp_path / "bad.uff", [_history(**over)])


def test_write_time_histories_rejects_bad_arguments(tmp_path):
    with pytest.raises(ValueError, match="histories"):
        write_time_histories(tmp_path / "bad.uff", [])
    with pytest.raises(ValueError, match=re.escape("histories[1]")):
        write_time_histories(tmp_path / "bad.uff", [_history(), "not a history"])
    with pytest.raises(ValueError, match="binary"):
        write_time_histories(tmp_path / "bad.uff", [_history()], binary="yes")


@pytest.mark.parametrize("over, name", [
    (dict(node_ids=[1.0, 2.0]), "node_ids"),
    (dict(node_ids=[1, 1]), "node_ids"),
    (dict(node_ids=[1, 100_000_000]), "node_ids"),
    (dict(freqs_hz=[np.nan]), "freqs_hz"),
    (dict(freqs_hz=[-5.0]), "freqs_hz"),
    (dict(shapes=np.zeros((1, 3, 6))), "shapes"),
    (dict(shapes=np.full((1, 2, 6), np.inf)), "shapes"),
    (dict(title="T" * 61), "title"),
])
def test_write_punch_rejects_invalid_input(tmp_path, over, name):
    args = dict(node_ids=[1, 2], freqs_hz=[10.0], shapes=np.ones((1, 2, 6)))
    args.update(over)
    with pytest.raises(ValueError, match=re.escape(name)):
        write_punch_eigenvectors(tmp_path / "bad.pch", **args)
