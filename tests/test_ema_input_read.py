"""Reading hammer tests (ema.read_hammer, HammerTest.from_arrays) and front-end FRFs (ema.read_frf_uff).

Oracles: pyuff's raw datasets for the lab files; hand-made small UFF58 files
(written with the virtual lab's exporter or pyuff) whose content is known;
an analytic FRF written by pyuff and read back.
"""

from __future__ import annotations

import dataclasses
import logging
import re
import warnings

import numpy as np
import pandas as pd
import pytest
import pyuff
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import ema
from ema import (
    ChannelDirectionWarning,
    ChannelMismatchError,
    FunctionTypeError,
    HammerDataError,
    HammerTest,
    NonFiniteDataError,
    SamplingError,
    UFFReadError,
    UnknownFormatError,
    ZeroForceError,
    read_frf_uff,
    read_hammer,
)
from lab_data.hammer import ModalTruth, analytic_accelerance
from lab_data.uff_export import TimeHistory, write_time_histories

FS_SMALL = 1024.0
N_SMALL = 256
NODES = (101, 102)


# --------------------------------------------------------------------------
# small synthetic tests
# --------------------------------------------------------------------------
def small_table(nodes=NODES, force_node=900) -> pd.DataFrame:
    rows = [dict(node=force_node, name="hammer", quantity="force", unit="N", x=0, y=0, z=0, dx=0, dy=0, dz=-1)]
    for k, n in enumerate(nodes):
        rows.append(dict(node=n, name=f"acc_{n}", quantity="acceleration", unit="m/s^2", x=0.1 * k, y=0, z=0,
                         dx=0, dy=0, dz=1))
    return pd.DataFrame(rows)


def small_signals(n_hits=2, nodes=NODES, n=N_SMALL, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS_SMALL
    force = np.zeros((n_hits, n))
    resp = np.zeros((n_hits, len(nodes), n))
    for h in range(n_hits):
        k0 = 20 + h
        force[h, k0:k0 + 5] = 100.0 * np.sin(np.pi * np.arange(1, 6) / 6)
        for j in range(len(nodes)):
            tt = np.clip(t - t[k0], 0, None)
            resp[h, j] = (j + 1) * np.exp(-8 * tt) * np.sin(2 * np.pi * (60 + 25 * j) * tt)
    force += 0.01 * rng.standard_normal(force.shape)
    resp += 1e-3 * rng.standard_normal(resp.shape)
    return force.astype(np.float32).astype(float), resp.astype(np.float32).astype(float)


def small_histories(n_hits=2, nodes=NODES, n=N_SMALL, dt=1 / FS_SMALL, seed=0, direction=0):
    force, resp = small_signals(n_hits, nodes, n, seed)
    hist = []
    for h in range(n_hits):
        hist.append(TimeHistory(h + 1, 900, 0, "force", "N", "hammer", dt, force[h], 900, 0))
        for j, node in enumerate(nodes):
            hist.append(TimeHistory(h + 1, node, direction, "acceleration", "m/s^2", f"acc_{node}", dt,
                                    resp[h, j], 900, 0))
    return hist


def write_small(tmp_path, name="small.uff", binary=True, histories=None, table=None):
    uff = write_time_histories(tmp_path / name, histories or small_histories(), binary=binary)
    csv = tmp_path / (name + ".csv")
    (small_table() if table is None else table).to_csv(csv, index=False)
    return uff, csv


@pytest.mark.parametrize("binary", [True, False])
def test_small_file_roundtrip(tmp_path, binary):
    uff, csv = write_small(tmp_path, binary=binary)
    test = read_hammer(uff, csv)
    force, resp = small_signals()
    assert test.hits == (1, 2) and test.fs == FS_SMALL and test.n_samples == N_SMALL
    if binary:  # float32 stored exactly
        np.testing.assert_array_equal(test.force, force)
        np.testing.assert_array_equal(test.responses, resp)
    else:  # E20.12 keeps 13 significant digits, enough to recover the float32 values exactly
        np.testing.assert_array_equal(test.force.astype(np.float32), force.astype(np.float32))
        np.testing.assert_array_equal(test.responses.astype(np.float32), resp.astype(np.float32))
        np.testing.assert_allclose(test.responses, resp, rtol=1e-12, atol=0)
    np.testing.assert_allclose(test.time, np.arange(N_SMALL) / FS_SMALL, rtol=0, atol=1e-12)
    assert test.channel_names == ("acc_101", "acc_102")


# --------------------------------------------------------------------------
# the lab's files
# --------------------------------------------------------------------------
@pytest.mark.parametrize("setup", ["flexural", "torsional"])
def test_read_lab_file_equals_pyuff(control_dir, setup, caplog):
    uff, csv = control_dir / f"{setup}.uff", control_dir / f"{setup}_channels.csv"
    with caplog.at_level(logging.INFO, logger="ema"):
        test = read_hammer(uff, csv)
    assert any(str(uff) in r.getMessage() and r.name == "ema" for r in caplog.records)
    assert (test.n_hits, test.n_channels, test.n_samples) == (6, 29, 51200)
    assert test.hits == (1, 2, 3, 4, 5, 6)
    assert test.fs == pytest.approx(12800.0, rel=1e-12)
    table = pd.read_csv(csv)
    acc = table[table["quantity"] == "acceleration"].reset_index(drop=True)
    # directions come from the table (the file says 0 = off-axis for most channels)
    np.testing.assert_allclose(test.response_channels[["dx", "dy", "dz"]].to_numpy(),
                               acc[["dx", "dy", "dz"]].to_numpy(), atol=1e-9)
    assert list(test.response_channels["node"]) == list(acc["node"])
    # every sample equals pyuff's raw data
    sets = pyuff.UFF(str(uff)).read_sets()
    assert len(sets) == 180
    col = {n: j for j, n in enumerate(acc["node"])}
    for d in sets:
        h = test.hits.index(d["ver_num"])
        ref = test.force[h] if d["rsp_node"] == 900 else test.responses[h, col[d["rsp_node"]]]
        np.testing.assert_array_equal(ref, d["data"])


def test_truncated_lab_file(control_dir, tmp_path):
    raw = (control_dir / "flexural.uff").read_bytes()
    rng = np.random.default_rng(7)
    cuts = [len(raw) - 2, len(raw) - 9, 1000] + list(rng.integers(2000, len(raw) - 10, 2))
    for cut in cuts:
        p = tmp_path / "cut.uff"
        p.write_bytes(raw[:cut])
        with pytest.raises(UFFReadError, match=re.escape(str(p))):
            read_hammer(p, control_dir / "flexural_channels.csv")
    # the final line break is optional
    p.write_bytes(raw[:-1])
    assert read_hammer(p, control_dir / "flexural_channels.csv").n_hits == 6


# --------------------------------------------------------------------------
# bad input
# --------------------------------------------------------------------------
@pytest.mark.parametrize("binary", [True, False])
def test_truncated_small_file_at_every_kind_of_point(tmp_path, binary):
    uff, csv = write_small(tmp_path, binary=binary)
    raw = uff.read_bytes()
    starts = [m.start() for m in re.finditer(rb"    -1\n", raw)]
    # inside headers, inside data, at dataset boundaries, inside tags
    assert len(starts) == 12  # 2 hits x 3 channels, start and end tags
    hit_end = starts[5] + 7  # after the last dataset of hit 1
    cuts = sorted(set([1, 5, 90, 700, len(raw) // 2, len(raw) - 3] + [s + 3 for s in starts[1:-1]]
                      + [starts[2], starts[4] + 7, starts[-1]]) - {hit_end, hit_end + 3})
    for cut in cuts:
        p = tmp_path / f"cut{cut}.uff"
        p.write_bytes(raw[:cut])
        with pytest.raises(HammerDataError) as err:
            read_hammer(p, csv)
        assert str(p) in str(err.value)
    # a cut exactly between two hits leaves a valid file with fewer hits: UFF has no dataset count to check
    p = tmp_path / "one_hit.uff"
    p.write_bytes(raw[:hit_end])
    assert read_hammer(p, csv).hits == (1,)


def test_row_without_data_names_channel_and_hit(tmp_path):
    uff, csv = write_small(tmp_path, table=small_table(nodes=(101, 102, 103)))
    with pytest.raises(ChannelMismatchError) as err:
        read_hammer(uff, csv)
    msg = str(err.value)
    assert str(uff) in msg and "node 103" in msg and "'acc_103'" in msg and "hit 1" in msg


def test_row_without_data_in_one_hit_only(tmp_path):
    hist = [h for h in small_histories() if not (h.hit == 2 and h.node == 102)]
    uff, csv = write_small(tmp_path, histories=hist)
    with pytest.raises(ChannelMismatchError, match=r"hit 2: channel 'acc_102' \(node 102"):
        read_hammer(uff, csv)


def test_data_without_row(tmp_path, caplog):
    """A channel the table does not list (a microphone, a spare sensor): the table selects the channels, so it is
    skipped, and a WARNING names the file, the node, its unit and its datasets."""
    uff, csv = write_small(tmp_path, table=small_table(nodes=(101,)))
    with caplog.at_level(logging.WARNING, logger="ema"):
        test = read_hammer(uff, csv)
    assert test.n_channels == 1
    assert str(uff) in caplog.text and "skipped (the table selects the channels): node 102 in 'm/s^2': 2 datasets" \
        in caplog.text


def test_duplicate_dataset(tmp_path):
    hist = small_histories()
    uff, csv = write_small(tmp_path, histories=hist + [hist[1]])
    with pytest.raises(ChannelMismatchError, match=r"hit 1, channel 'acc_101' \(node 101\) appears twice"):
        read_hammer(uff, csv)


def test_mixed_sampling_rates(tmp_path):
    hist = small_histories()
    h = hist[4]
    hist[4] = TimeHistory(h.hit, h.node, h.direction, h.quantity, h.unit, h.name, 1 / 2048, h.data)
    uff, csv = write_small(tmp_path, histories=hist)
    with pytest.raises(SamplingError) as err:
        read_hammer(uff, csv)
    msg = str(err.value)
    assert str(uff) in msg and "hit 2" in msg and "'acc_101'" in msg and "sampling interval" in msg


def test_mixed_record_lengths(tmp_path):
    hist = small_histories()
    h = hist[2]
    hist[2] = TimeHistory(h.hit, h.node, h.direction, h.quantity, h.unit, h.name, h.dt, h.data[:200])
    uff, csv = write_small(tmp_path, histories=hist)
    with pytest.raises(SamplingError, match=r"hit 1, channel 'acc_102' \(node 102\): 200 samples"):
        read_hammer(uff, csv)


def test_nan_samples(tmp_path):
    uff, csv = write_small(tmp_path, binary=False)
    text = uff.read_text()
    # the 11th value of dataset 2 (hit 1, node 101): replace one E20.12 field by NaN
    blocks = text.split("    -1\n")
    lines = blocks[3].splitlines(True)
    data_line = lines[12]
    lines[12] = data_line[:40] + f"{'NaN':>20}" + data_line[60:]
    blocks[3] = "".join(lines)
    uff.write_text("    -1\n".join(blocks))
    with pytest.raises(NonFiniteDataError) as err:
        read_hammer(uff, csv)
    msg = str(err.value)
    assert str(uff) in msg and "hit 1" in msg and "'acc_101'" in msg and "sample 2" in msg


def test_zero_force(tmp_path):
    hist = small_histories()
    h = hist[3]  # hit 2 force
    assert h.node == 900 and h.hit == 2
    hist[3] = TimeHistory(h.hit, h.node, h.direction, h.quantity, h.unit, h.name, h.dt, np.zeros(N_SMALL))
    uff, csv = write_small(tmp_path, histories=hist)
    with pytest.raises(ZeroForceError) as err:
        read_hammer(uff, csv)
    assert str(uff) in str(err.value) and "hit 2" in str(err.value) and "'hammer'" in str(err.value)


def test_wrong_function_type(tmp_path):
    uff, csv = write_small(tmp_path, binary=False)
    text = uff.read_text()
    text = text.replace("    1         2    1         0 NONE", "    2         2    1         0 NONE")
    uff.write_text(text)
    with pytest.raises(FunctionTypeError, match=r"function type 2, expected 1") as err:
        read_hammer(uff, csv)
    assert "node 101" in str(err.value) and "hit 1" in str(err.value)


def test_quantity_mismatch_between_file_and_table(tmp_path):
    table = small_table()
    table.loc[0, ["quantity", "unit"]] = ["acceleration", "m/s^2"]
    table.loc[1, ["quantity", "unit"]] = ["force", "N"]
    uff, csv = write_small(tmp_path, table=table)
    with pytest.raises(ChannelMismatchError, match=r"'excitation force'.*'hammer' is a acceleration channel"):
        read_hammer(uff, csv)


def test_corrupt_header_bytes(tmp_path):
    uff, csv = write_small(tmp_path)
    raw = bytearray(uff.read_bytes())
    second = raw.find(b"    -1\n    58b", 10)
    raw[second + 8:second + 10] = b"x!"  # dataset number of the second dataset
    uff.write_bytes(bytes(raw))
    with pytest.raises(UFFReadError, match=re.escape(str(uff)) + ".*dataset 2"):
        read_hammer(uff, csv)


def test_unknown_format_lists_supported(tmp_path):
    p = tmp_path / "notes.txt"
    p.write_text("impact test, wheelset 2\nhits 1-6 on the tread\n")
    (tmp_path / "c.csv").write_text(small_table().to_csv(index=False))
    with pytest.raises(UnknownFormatError, match="uff58.*mdf.*csv"):
        read_hammer(p, tmp_path / "c.csv")
    with pytest.raises(UnknownFormatError, match="'xlsx'.*uff58"):
        read_hammer(p, tmp_path / "c.csv", format="xlsx")
    # a time column then channels is a CSV export; its channels must be the table's
    p.write_text("time,force\n0,1\n")
    with pytest.raises(ChannelMismatchError, match="notes.txt: .* of the channel table not in the file"):
        read_hammer(p, tmp_path / "c.csv")
    with pytest.raises(FileNotFoundError):
        read_hammer(tmp_path / "missing.uff", tmp_path / "c.csv")


def test_direction_code_contradicting_table_warns(tmp_path):
    uff, csv = write_small(tmp_path, histories=small_histories(direction=1))  # +X in the file, +z in the table
    with pytest.warns(ChannelDirectionWarning, match=r"direction code 1 disagrees"):
        test = read_hammer(uff, csv)
    np.testing.assert_array_equal(test.response_channels[["dx", "dy", "dz"]].to_numpy(), [[0, 0, 1], [0, 0, 1]])


def test_from_arrays_validates(tmp_path):
    force, resp = small_signals()
    table = small_table()
    test = HammerTest.from_arrays(force, resp, FS_SMALL, table, hit_numbers=[4, 9], source="bench")
    assert test.hits == (4, 9) and test.time[1] == pytest.approx(1 / FS_SMALL)
    with pytest.raises(SamplingError, match=r"bench: responses must be .*\(2, 2, 256\)"):
        HammerTest.from_arrays(force, resp[:, :1], FS_SMALL, table, source="bench")
    bad = resp.copy()
    bad[1, 1, 17] = np.inf
    with pytest.raises(NonFiniteDataError, match=r"bench: hit 2, channel 'acc_102' \(node 102\): sample 17"):
        HammerTest.from_arrays(force, bad, FS_SMALL, table, source="bench")
    zero = force.copy()
    zero[0] = 3.0
    with pytest.raises(ZeroForceError, match="hit 1"):
        HammerTest.from_arrays(zero, resp, FS_SMALL, table)
    with pytest.raises(SamplingError, match="unique"):
        HammerTest.from_arrays(force, resp, FS_SMALL, table, hit_numbers=[1, 1])
    with pytest.raises(ema.ChannelTableError):
        HammerTest.from_arrays(force, resp, FS_SMALL, table.drop(columns="dx"))
    # inputs are copied and read-only
    assert not test.force.flags.writeable
    force[0, 0] = 1e9
    assert test.force[0, 0] != 1e9


# --------------------------------------------------------------------------
# fuzzing: any mutation either reads consistently or raises HammerDataError naming the file
# --------------------------------------------------------------------------
_BASE: dict[bool, bytes] = {}


def _base_bytes(tmp_path_factory, binary: bool) -> bytes:
    if binary not in _BASE:
        d = tmp_path_factory.mktemp("fuzzbase")
        hist = small_histories(n_hits=2, n=64)
        _BASE[binary] = write_time_histories(d / "base.uff", hist, binary=binary).read_bytes()
    return _BASE[binary]


mutation = st.tuples(st.sampled_from(["cut", "flip", "insert", "delete", "digit"]), st.floats(0, 1),
                     st.integers(0, 255))


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(binary=st.booleans(), mutations=st.lists(mutation, min_size=1, max_size=3))
def test_fuzz_read_hammer(tmp_path_factory, binary, mutations):
    raw = bytearray(_base_bytes(tmp_path_factory, binary))
    for op, where, byte in mutations:
        if not raw:
            break
        k = min(int(where * len(raw)), len(raw) - 1)
        if op == "cut":
            raw = raw[:k]
        elif op == "flip":
            raw[k] = byte
        elif op == "insert":
            raw[k:k] = bytes([byte])
        elif op == "delete":
            del raw[k]
        else:  # change a digit in the ASCII part (header fields, numbers)
            digits = [m.start() for m in re.finditer(rb"[0-9]", bytes(raw[:2000]))]
            if digits:
                raw[digits[int(where * (len(digits) - 1))]] = ord("0") + byte % 10
    d = tmp_path_factory.mktemp("fuzz")
    p = d / "fuzz.uff"
    p.write_bytes(bytes(raw))
    csv = d / "c.csv"
    small_table().to_csv(csv, index=False)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ChannelDirectionWarning)
            test = read_hammer(p, csv)
    except (HammerDataError, UnknownFormatError) as exc:
        assert str(p) in str(exc)
    else:
        assert test.responses.shape == (test.n_hits, 2, test.n_samples)
        assert np.all(np.isfinite(test.responses)) and np.all(np.isfinite(test.force))


# --------------------------------------------------------------------------
# front-end FRFs (UFF58 function type 4)
# --------------------------------------------------------------------------
TOY = ModalTruth([0.0, 72.6, 150.0, 410.0], [0.0, 0.002, 0.001, 0.004], [0.03, 0.02, -0.015, 0.01],
                 np.array([[0.03, 0.025, 0.01, -0.02], [0.03, -0.01, 0.02, 0.015]]))


def write_frf_file(path, H, f, nodes=(101, 102), spec=12, func_type=4, units="NONE", coherence=None):
    uff = pyuff.UFF(str(path))
    sets = []
    for j, node in enumerate(nodes):
        sets.append(pyuff.prepare_58(
            binary=0, func_type=func_type, rsp_node=node, rsp_dir=3, ref_node=900, ref_dir=-3, data=H[j], x=f,
            id1=f"FRF {node}", rsp_ent_name="NONE", ref_ent_name="NONE", abscissa_spacing=1,
            abscissa_spec_data_type=18, ordinate_spec_data_type=spec, orddenom_spec_data_type=13,
            ord_data_type=6, num_pts=len(f), abscissa_min=float(f[0]), abscissa_inc=float(f[1] - f[0]),
            ordinate_axis_units_lab=units))
        if coherence is not None:
            sets.append(pyuff.prepare_58(
                binary=0, func_type=6, rsp_node=node, rsp_dir=3, ref_node=900, ref_dir=-3, data=coherence[j],
                x=f, id1=f"COH {node}", rsp_ent_name="NONE", ref_ent_name="NONE", abscissa_spacing=1,
                abscissa_spec_data_type=18, ordinate_spec_data_type=0, orddenom_spec_data_type=0,
                ord_data_type=4, num_pts=len(f), abscissa_min=float(f[0]), abscissa_inc=float(f[1] - f[0])))
    uff.write_sets(sets, mode="add")
    return path


def test_read_frf_uff_roundtrip_against_analytic(tmp_path):
    f = np.arange(40, 2001) * 0.25  # 10-500 Hz
    H = analytic_accelerance(TOY, f)
    coh = np.tile(np.linspace(0.9, 1.0, f.size), (2, 1))
    p = write_frf_file(tmp_path / "frf.uff", H, f, coherence=coh)
    frf = read_frf_uff(p)
    assert frf.quantity == "accelerance" and frf.units == "m/s^2/N"
    assert frf.outputs == ("101:+z", "102:+z") and frf.inputs == ("900:-z",)
    np.testing.assert_allclose(frf.freqs_hz, f, rtol=0, atol=1e-9)
    # ASCII E20.12 keeps 12-13 significant digits
    rel = np.abs(frf.data[:, 0, :] - H) / np.abs(H)
    assert rel.max() < 1e-10
    np.testing.assert_allclose(frf.coherence[:, 0, :], coh, rtol=1e-11)
    # with a channel table: names, table order, channels attached
    table = small_table(nodes=(102, 101))
    frf2 = read_frf_uff(p, table)
    assert frf2.outputs == ("acc_102", "acc_101") and frf2.inputs == ("hammer",)
    np.testing.assert_array_equal(frf2.data[0], frf.data[1])
    assert list(frf2.channels["node"]) == [102, 101]


def test_read_frf_uff_quantity_from_file(tmp_path):
    f = np.arange(40, 401) * 0.25
    H = analytic_accelerance(TOY, f)
    mob = H / (2j * np.pi * f)
    frf = read_frf_uff(write_frf_file(tmp_path / "m.uff", mob, f, spec=11))
    assert frf.quantity == "mobility"
    np.testing.assert_allclose(frf.as_quantity("accelerance").data[:, 0, :], H, rtol=1e-10)
    frf = read_frf_uff(write_frf_file(tmp_path / "u.uff", H, f, spec=0, units="m/s^2/N"))
    assert frf.quantity == "accelerance"
    with pytest.raises(FunctionTypeError, match="pass quantity="):
        read_frf_uff(write_frf_file(tmp_path / "x.uff", H, f, spec=0))
    assert read_frf_uff(tmp_path / "x.uff", quantity="receptance").quantity == "receptance"


def test_read_frf_uff_errors(tmp_path):
    f = np.arange(40, 401) * 0.25
    H = analytic_accelerance(TOY, f)
    p = write_frf_file(tmp_path / "frf.uff", H, f)
    with pytest.raises(ChannelMismatchError, match=r"'acc_103' \(node 103\) of the table have no FRF"):
        read_frf_uff(p, small_table(nodes=(101, 102, 103)))
    assert read_frf_uff(p, small_table(nodes=(101,))).n_out == 1  # response 102 skipped, said (as read_hammer)
    with pytest.raises(FunctionTypeError, match="ema.read_frf_uff"):
        read_hammer(p, small_table())
    uff, _ = write_small(tmp_path)
    with pytest.raises(FunctionTypeError, match="function type 1.*ema.read_hammer"):
        read_frf_uff(uff)
    raw = p.read_bytes()
    q = tmp_path / "cut.uff"
    q.write_bytes(raw[: len(raw) // 3])
    with pytest.raises(UFFReadError, match=re.escape(str(q))):
        read_frf_uff(q)


def test_hits_numbered_by_order_when_every_dataset_has_the_same_sequence_number(tmp_path, caplog):
    """A front-end that writes sequence number 1 in every dataset (hit after hit, all channels each): the hits are
    numbered by their order in the file (logged), and the samples are those of the file with proper numbers."""
    ref_hist = small_histories(n_hits=3)
    flat = [dataclasses.replace(h, hit=1) for h in ref_hist]
    uff, csv = write_small(tmp_path, histories=flat)
    with caplog.at_level(logging.WARNING, logger="ema"):
        test = read_hammer(uff, csv)
    assert "numbered by their order in the file" in caplog.text and str(uff) in caplog.text
    ref = read_hammer(*write_small(tmp_path, name="ref.uff", histories=ref_hist))
    assert test.hits == ref.hits == (1, 2, 3)
    np.testing.assert_array_equal(test.force, ref.force)
    np.testing.assert_array_equal(test.responses, ref.responses)
    # a channel missing from one hit leaves the channels unevenly repeated: that stays an error
    uneven = [h for h in flat if not (h is flat[4])]
    with pytest.raises(ChannelMismatchError, match="appears twice"):
        read_hammer(*write_small(tmp_path, name="uneven.uff", histories=uneven))


def test_accelerations_exported_in_g_are_read_in_si(tmp_path, caplog):
    """A front-end exporting the accelerations in g (ordinate units label 'g') and the force in kN: the samples are
    converted to m/s^2 and N (g = 9.80665 m/s^2), the conversion is logged and kept in the test's history."""
    ref_hist = small_histories()
    scaled = [dataclasses.replace(h, data=h.data / (9.80665 if h.quantity == "acceleration" else 1e3))
              for h in ref_hist]
    uff, csv = write_small(tmp_path, name="in_g.uff", binary=False, histories=scaled)
    text = uff.read_text()
    in_g = re.sub(r"(?<= )m/s\^2(?= )", "g    ", text)
    uff.write_text(in_g.replace(" N                   ", " kN                  "))
    with caplog.at_level(logging.INFO, logger="ema"):
        test = read_hammer(uff, csv)
    ref = read_hammer(*write_small(tmp_path, name="si.uff", binary=False, histories=ref_hist))
    # the file holds single precision: the scaled samples were rounded to float32 (relative 6e-8)
    np.testing.assert_allclose(test.responses, ref.responses, rtol=2e-7, atol=0)
    np.testing.assert_allclose(test.force, ref.force, rtol=2e-7, atol=0)
    assert "acceleration from g" in caplog.text and "force from kN" in caplog.text
    assert any("converted to SI" in h for h in test.history)


@pytest.mark.parametrize("units, denominator, spec, factor", [("g/N", None, 12, 9.80665), ("g", "N", 0, 9.80665),
                                                             ("(m/s^2)/kN", None, 12, 1e-3), ("mm/N", None, 8, 1e-3)])
def test_frf_units_of_the_front_end_are_converted_to_si(tmp_path, units, denominator, spec, factor):
    """FRFs exported in g/N (one label, or g over N with the ordinate type left unknown), per kN, or in mm/N: read
    in SI (the accelerance of the analytic toy to 1e-10), the quantity told by the units, the conversion kept in the
    history."""
    f = np.arange(40, 401) * 0.25
    H = analytic_accelerance(TOY, f)
    p = write_frf_file(tmp_path / "frf.uff", H / factor, f, spec=spec, units=units)
    if denominator:
        text = p.read_text()
        p.write_text(text.replace(f"{'NONE':<20}", f"{denominator:<20}"))
    frf = read_frf_uff(p)
    assert frf.quantity == ("receptance" if units.startswith("mm") else "accelerance")
    np.testing.assert_allclose(frf.data[:, 0, :], H, rtol=1e-10)
    assert any("converted to SI" in h for h in frf.history)
