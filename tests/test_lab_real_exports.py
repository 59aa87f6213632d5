"""The lab readers against files written the ways real acquisition front ends write them.

A probe of ``railmodal lab identify`` / ``lab diagnose`` against realistic exports (Testlab, PULSE, m+p,
Dewesoft, HBK, NI scripts) found the defects D1-D15 these tests hold fixed. Every file is built here, small (3
accelerometers, a few hits of 2048 samples; :mod:`real_exports_support`), by a UFF58 writer independent of the
toolkit.

Oracles: the same data written in SI (the data read from a converted file equal the SI data to rounding, and the
modes identified from it equal the SI file's: frequencies to 1e-6 relative, shapes to 1e-9); sensitivities
applied exactly (SI = recorded x sensitivity); an FRF windowed analytically (poles shifted by the decay); the
message naming file, dataset, channel and what to do.
"""

from __future__ import annotations

import logging
import re
import warnings

import numpy as np
import pytest

import ema
import real_exports_support as rs
from bad_inputs_support import run
from ema import ChannelDirectionWarning, ChannelMismatchError, ChannelTableError, FunctionTypeError, SamplingError
from ema import UFFReadError, read_frf_uff, read_hammer
from ema.estimate import EstimationError
from ema.hammer_io import ReferenceNodeError, UnitSystemError
from ema.modes_io import read_modeset
from railmodal.cli import main

G = 9.80665
LBF = 4.4482216152605


@pytest.fixture(scope="module")
def data():
    return rs.hits()


@pytest.fixture(scope="module")
def si(data, tmp_path_factory):
    """The SI file (binary double precision), its table and the test read from it."""
    folder = tmp_path_factory.mktemp("si")
    force, resp = data
    uff = rs.write(folder / "si.uff", rs.specs(force, resp), binary=True)
    csv = rs.write_table(folder / "si_channels.csv", rs.table())
    return uff, csv, read_hammer(uff, csv)




def identify(capsys, out, *args):
    code, stdout, err = run(["-q", "lab", "identify", *map(str, args), "--band", *rs.BAND, "--max-order",
                             rs.MAX_ORDER, "--out", str(out)], capsys)
    assert code == 0, err
    return read_modeset(out)


@pytest.fixture(scope="module")
def si_modes(si, tmp_path_factory):
    uff, csv, _ = si
    out = tmp_path_factory.mktemp("si_modes") / "modes"
    assert main(["-q", "lab", "identify", "--hammer", str(uff), "--channels", str(csv), "--band", *rs.BAND,
                 "--max-order", rs.MAX_ORDER, "--out", str(out)]) == 0
    return read_modeset(out)


def assert_same_modes(a, b, f_rtol=1e-6, shape_rtol=1e-9):
    assert len(a) == len(b) == 3
    np.testing.assert_allclose(a.freqs_hz, b.freqs_hz, rtol=f_rtol)
    np.testing.assert_allclose(a.zeta, b.zeta, rtol=max(10 * f_rtol, 1e-6))
    scale = np.abs(b.shapes).max()
    np.testing.assert_allclose(a.shapes, b.shapes, rtol=0, atol=shape_rtol * scale)


def warning_lines(caplog):
    return [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]


# ------------------------------------------------------------------------------------------------ D1 units
@pytest.mark.parametrize("acc, acc_factor, force, force_factor, encoding", [
    ("in/s^2", 0.0254, "lbf", LBF, "latin-1"),
    ("in/s2", 0.0254, "kgf", G, "latin-1"),
    ("in/s\u00b2", 0.0254, "kN", 1e3, "utf-8"),
    ("ft/s^2", 0.3048, "N", 1.0, "latin-1"),
    ("mg", G * 1e-3, "lbf", LBF, "latin-1"),
    ("m/s\u00b2", 1.0, "N", 1.0, "latin-1"),  # pyuff decodes the latin-1 '²' as U+FFFD
])
def test_d1_unit_spellings_of_real_front_ends_are_converted(data, si, tmp_path, caplog, acc, acc_factor, force,
                                                             force_factor, encoding):
    """in/s^2, in/s2, in/s² (UTF-8), ft/s^2, mg and a latin-1 m/s² are converted to SI, without a warning (before:
    taken as m/s^2 with one WARNING per channel, shapes x39.37 for in/s^2)."""
    f, r = data
    uff = rs.write(tmp_path / "units.uff", rs.specs(f, r, acc_unit=acc, acc_factor=acc_factor, force_unit=force,
                                                     force_factor=force_factor), binary=True, encoding=encoding)
    with caplog.at_level(logging.INFO, logger="ema"):
        test = read_hammer(uff, si[1])
    assert warning_lines(caplog) == []
    np.testing.assert_allclose(test.responses, si[2].responses, rtol=1e-15, atol=0)
    np.testing.assert_allclose(test.force, si[2].force, rtol=1e-15, atol=0)
    if acc_factor != 1.0:
        assert any("converted to SI" in h and "acceleration from" in h for h in test.history)


def test_d1_us_lab_file_identifies_the_si_modes(data, si, si_modes, tmp_path, capsys):
    """A US lab's in/s^2 + lbf file gives the SI file's modes through 'lab identify' (before: shapes x39.37)."""
    f, r = data
    uff = rs.write(tmp_path / "ins2_lbf.uff", rs.specs(f, r, acc_unit="in/s^2", acc_factor=0.0254,
                                                        force_unit="lbf", force_factor=LBF), binary=True)
    assert_same_modes(identify(capsys, tmp_path / "m", "--hammer", uff, "--channels", si[1]), si_modes)


def test_d1_raw_volts_without_sensitivity_are_refused_naming_file_dataset_channel_and_label(data, si, tmp_path):
    f, r = data
    uff = rs.write(tmp_path / "volts.uff", rs.specs(f, r, acc_unit="V", acc_factor=0.01), binary=True)
    with pytest.raises(UnitSystemError) as err:
        read_hammer(uff, si[1])
    msg = str(err.value)
    for words in (str(uff), "dataset 2", "'acc_101' (node 101)", "'V'", "sensitivity"):
        assert words in msg, (words, msg)
    # a latin-1 'µV' is an electrical unit too
    uff = rs.write(tmp_path / "uvolts.uff", rs.specs(f, r, acc_unit="\u00b5V", acc_factor=1e-5), binary=True)
    with pytest.raises(UnitSystemError, match="electrical"):
        read_hammer(uff, si[1])


def test_d1_an_unknown_label_is_logged_once_with_its_channels(data, si, tmp_path, caplog):
    """Truly unknown labels keep the policy (the table's unit is used) with one WARNING per label naming the
    channels and their count (before: one line per channel and dataset)."""
    f, r = data

    def unit(s):
        return "furlong/s^2" if s["rsp_node"] in (101, 103) else ("N" if s["rsp_node"] == 900 else "m/s^2")

    uff = rs.write(tmp_path / "odd.uff", rs.specs(f, r, ord_unit=unit), binary=True)
    with caplog.at_level(logging.WARNING, logger="ema"):
        test = read_hammer(uff, si[1])
    lines = warning_lines(caplog)
    assert len(lines) == 1, lines
    assert "'furlong/s^2' not recognised on 2 channels ('acc_101' (node 101), 'acc_103' (node 103))" in lines[0]
    np.testing.assert_array_equal(test.responses, si[2].responses)


def test_d1_frf_labels_in_us_units_and_latin1_are_converted(tmp_path, caplog):
    f = np.arange(1, 801) * 0.5
    h = rs.accelerance(f)
    csv = rs.write_table(tmp_path / "t.csv", rs.table())
    ref = read_frf_uff(rs.write(tmp_path / "si.uff", rs.frf_specs(h, f), binary=True), csv, exp_window_decay=0.0)
    us = rs.write(tmp_path / "us.uff", rs.frf_specs(h * LBF / 0.0254, f, num_unit="in/s^2", den_unit="lbf"),
                  binary=True)
    lat = rs.write(tmp_path / "lat.uff", rs.frf_specs(h, f, num_unit="m/s\u00b2", den_unit="N"), binary=True)
    with caplog.at_level(logging.WARNING, logger="ema"):
        a = read_frf_uff(us, csv, exp_window_decay=0.0)
        b = read_frf_uff(lat, csv, exp_window_decay=0.0)
    assert warning_lines(caplog) == []
    np.testing.assert_allclose(a.data, ref.data, rtol=1e-14)
    np.testing.assert_array_equal(b.data, ref.data)


# ------------------------------------------------------------------------------------------ D2 sensitivity
SENS = [444.44, 98.07, 101.3, 95.2]  # hammer 2.25 mV/N recorded in V; accelerometers ~10 mV/(m/s^2)


@pytest.mark.parametrize("label", ["V", "NONE", ""])
def test_d2_raw_voltages_are_multiplied_by_the_tables_sensitivity(data, si, tmp_path, caplog, label):
    """Raw data (label V, or none) with a 'sensitivity' column: SI = recorded x sensitivity exactly, recorded in
    the history (before: the column was ignored and volts taken as SI)."""
    f, r = data
    recorded_f = f / SENS[0]
    recorded_r = r / np.array(SENS[1:])[None, :, None]
    dsets = rs.specs(recorded_f, recorded_r, acc_unit=label or " ", force_unit=label or " ")
    uff = rs.write(tmp_path / "raw.uff", dsets, binary=True)
    csv = rs.write_table(tmp_path / "raw_channels.csv", rs.table(sensitivity=SENS))
    with caplog.at_level(logging.INFO, logger="ema"):
        test = read_hammer(uff, csv)
    np.testing.assert_array_equal(test.force, recorded_f * SENS[0])
    np.testing.assert_array_equal(test.responses, recorded_r * np.array(SENS[1:])[None, :, None])
    np.testing.assert_allclose(test.responses, si[2].responses, rtol=1e-14)
    assert any("sensitivity applied to 4 channels" in h and "'acc_102'" in h for h in test.history)
    # labelled in V the data are raw by their label (INFO); unlabelled they are taken as raw by inference (WARNING)
    lines = warning_lines(caplog)
    if label == "V":
        assert lines == []
    else:
        assert len(lines) == 1 and "the data carry no unit label, so they are taken as raw" in lines[0]


def test_d2_a_datasheet_sensitivity_in_place_of_the_factor_is_named(data, tmp_path, caplog):
    """A table giving the datasheet's V per SI unit (0.00225 V/N) where the factor on the recorded values belongs
    (444.4 N/V) is applied as written (the column's meaning is fixed) but named in a WARNING."""
    f, r = data
    uff = rs.write(tmp_path / "v.uff", rs.specs(f / SENS[0], r / SENS[1], acc_unit="V", force_unit="V"),
                   binary=True)
    csv = rs.write_table(tmp_path / "datasheet.csv", rs.table(sensitivity=[1 / s for s in SENS]))
    with caplog.at_level(logging.WARNING, logger="ema"):
        read_hammer(uff, csv)
    lines = warning_lines(caplog)
    assert any("'hammer' ('V', sensitivity 0.00225" in m and "looks like a datasheet sensitivity" in m for m in lines)
    # unlabelled raw data cannot be judged by their unit, but the force then peaks at a few mN
    caplog.clear()
    uff = rs.write(tmp_path / "none.uff", rs.specs(f / SENS[0], r / SENS[1], acc_unit="NONE", force_unit="NONE"),
                   binary=True)
    with caplog.at_level(logging.WARNING, logger="ema"):
        test = read_hammer(uff, csv)
    assert test.force.max() < 0.1
    lines = warning_lines(caplog)
    assert any("the hammer force peaks at 0.00" in m and "sensitivity (0.00225" in m for m in lines)
    assert any("the data carry no unit label, so they are taken as raw" in m for m in lines)


def test_d2_sensitivity_of_converted_data_is_not_applied_and_named_once(data, si, tmp_path, caplog):
    """Data labelled in a physical unit were converted by the front end: the sensitivity is not applied, one
    WARNING names the channels; a table with sensitivity 1 everywhere reads exactly as one without the column."""
    f, r = data
    uff = rs.write(tmp_path / "g.uff", rs.specs(f, r, acc_unit="g", acc_factor=G), binary=True)
    csv = rs.write_table(tmp_path / "s.csv", rs.table(sensitivity=[1.0, 98.07, 1.0, 95.2]))
    with caplog.at_level(logging.WARNING, logger="ema"):
        test = read_hammer(uff, csv)
    lines = warning_lines(caplog)
    assert len(lines) == 1 and "'acc_101'" in lines[0] and "'acc_103'" in lines[0] and "'acc_102'" not in lines[0]
    assert "not applied" in lines[0]
    np.testing.assert_allclose(test.responses, si[2].responses, rtol=1e-15)
    ones = rs.write_table(tmp_path / "ones.csv", rs.table(sensitivity=[1.0] * 4))
    np.testing.assert_array_equal(read_hammer(si[0], ones).responses, si[2].responses)
    np.testing.assert_array_equal(si[2].responses, r)  # the table without the column: the file's numbers
    np.testing.assert_array_equal(si[2].force, f)


def test_d2_raw_volt_frfs_use_response_over_force_sensitivity(tmp_path, caplog):
    f = np.arange(1, 801) * 0.5
    h = rs.accelerance(f)
    ratio = np.array(SENS[1:]) / SENS[0]
    csv = rs.write_table(tmp_path / "s.csv", rs.table(sensitivity=SENS))
    for label in (("V", "V"), ("NONE", "NONE")):
        p = rs.write(tmp_path / f"v_{label[0]}.uff", rs.frf_specs(h / ratio[:, None], f, num_unit=label[0],
                                                                   den_unit=label[1]), binary=True)
        frf = read_frf_uff(p, csv, exp_window_decay=0.0)
        np.testing.assert_allclose(frf.data[:, 0], h, rtol=1e-14)
        assert any("sensitivities applied" in x for x in frf.history)
    with pytest.raises(UnitSystemError, match=r"dataset 1, response 'acc_101'.*'V' over 'V'.*sensitivity"):
        read_frf_uff(p.with_name("v_V.uff"), rs.table())
    gp = rs.write(tmp_path / "g.uff", rs.frf_specs(h / G, f, num_unit="g", den_unit="N"), binary=True)
    with caplog.at_level(logging.WARNING, logger="ema"):
        frf = read_frf_uff(gp, csv, exp_window_decay=0.0)
    np.testing.assert_allclose(frf.data[:, 0], h, rtol=1e-14)
    assert any("not applied" in m and "'acc_101'" in m for m in warning_lines(caplog))


# ------------------------------------------------------------------------------- D3 FRF exponential window
def test_d3_window_decay_of_front_end_frfs(tmp_path, capsys, caplog):
    """Front-end FRFs windowed with decay a (poles shifted by -a), ID line 3 a date: read_frf_uff warns that the
    damping is taken as exported; 'lab identify --frf --window-decay a' gives the damping of the unwindowed FRFs
    (without it: biased by a/omega)."""
    a = 3.0
    f = np.arange(1, 801) * 0.5
    csv = rs.write_table(tmp_path / "t.csv", rs.table())
    plain = rs.write(tmp_path / "plain.uff", rs.frf_specs(rs.accelerance(f), f), binary=True)
    windowed = rs.write(tmp_path / "win.uff", rs.frf_specs(rs.accelerance(f, shift=a), f), binary=True)
    with caplog.at_level(logging.WARNING, logger="ema"):
        frf = read_frf_uff(windowed, csv)
    assert frf.exp_window_decay == 0.0
    (line,) = warning_lines(caplog)
    assert str(windowed) in line and "no exponential-window decay recorded" in line and "--window-decay" in line
    assert read_frf_uff(windowed, csv, exp_window_decay=a).exp_window_decay == a

    ref = identify(capsys, tmp_path / "ref", "--frf", plain, "--channels", csv, "--window-decay", "0")
    good = identify(capsys, tmp_path / "good", "--frf", windowed, "--channels", csv, "--window-decay", a)
    biased = identify(capsys, tmp_path / "biased", "--frf", windowed, "--channels", csv)
    np.testing.assert_allclose(good.freqs_hz, ref.freqs_hz, rtol=1e-6)
    np.testing.assert_allclose(good.zeta, ref.zeta, rtol=1e-4)
    np.testing.assert_allclose(ref.zeta, [z for _, z in rs.MODES], rtol=1e-4)
    assert biased.zeta[0] > 1.3 * ref.zeta[0]

    uff = rs.write(tmp_path / "h.uff", rs.specs(*rs.hits(2)), binary=True)
    for extra, words in ((["--hammer", uff, "--window-decay", "1"], "with --hammer"),
                         (["--frf", windowed, "--window-decay", "-1"], "--window-decay"),
                         (["--frf", windowed, "--window-decay", "5000"], "--window-decay")):
        code, _, err = run(["-q", "lab", "identify", *map(str, extra), "--channels", str(csv), "--out",
                            str(tmp_path / "x")], capsys)
        assert code == 2 and words in err, err
    assert not (tmp_path / "x").exists()


# ------------------------------------------------------------------------------ D4 several files of one setup
def test_d4_one_hit_per_file_is_read_as_one_test(data, si, si_modes, tmp_path, capsys, caplog):
    """'--hammer' repeated: the files are one test, hits concatenated and renumbered (before: only the last file
    was read, silently). The modes equal those of the one file holding all hits."""
    f, r = data
    files = []
    for h in range(f.shape[0]):
        one = [dict(s, ver_num=1) for s in rs.specs(f[h:h + 1], r[h:h + 1])]
        files.append(rs.write(tmp_path / f"hit{h + 1:02d}.uff", one, binary=True))
    with caplog.at_level(logging.INFO, logger="ema"):
        test = read_hammer(files, si[1])
    assert test.hits == (1, 2, 3, 4)
    np.testing.assert_array_equal(test.responses, si[2].responses)
    assert f"2 = {files[1]} hit 1" in test.history[-1] and "4 files of one setup" in test.history[-1]
    args = [x for p in files for x in ("--hammer", p)]
    assert_same_modes(identify(capsys, tmp_path / "m", *args, "--channels", si[1]), si_modes, 1e-12, 1e-12)

    other_fs = rs.write(tmp_path / "fs.uff", rs.specs(f[:1], r[:1], abscissa_inc=0.5 / rs.FS), binary=True)
    with pytest.raises(SamplingError, match=re.escape(f"{other_fs}: sampling rate ") + r"409\d\.\d+ Hz, but "
                       + re.escape(f"{files[0]} has ") + r"204\d\.\d+ Hz; the files of one setup must share"):
        read_hammer([files[0], other_fs], si[1])
    other = rs.write_table(tmp_path / "other.csv", rs.table(x=[0.0, 0.5, 0.6, 0.7]))
    for extra, words in ((["--frf", files[0], "--frf", files[1], "--channels", si[1]], "--frf given 2 times"),
                         (["--hammer", files[0], "--channels", si[1], "--channels", other],
                          "--channels given 2 times with different tables"),
                         (["--hammer", files[0], "--hammer", files[0], "--channels", si[1]], "given twice")):
        code, _, err = run(["-q", "lab", "identify", *map(str, extra), "--out", str(tmp_path / "x")], capsys)
        assert code == 2 and words in err, err


# ------------------------------------------------------------------------------------ D5 start times per hit
@pytest.mark.parametrize("start", [lambda hit: 17.3 * (hit - 1), lambda hit: -0.05 + 1.3e-5 * (hit - 1) ** 2])
def test_d5_hits_starting_at_different_times_are_accepted(data, si, tmp_path, caplog, start):
    """Absolute trigger times per hit, or sub-sample trigger jitter: accepted (INFO with the spread); the FRFs
    equal those of a common start (every hit is windowed at its own pulse). Within a hit the force and the
    responses must still start together."""
    f, r = data
    uff = rs.write(tmp_path / "t0.uff", rs.specs(f, r, abscissa_min=lambda s: start(s["ver_num"])), binary=True)
    with caplog.at_level(logging.INFO, logger="ema"):
        test = read_hammer(uff, si[1])
    assert "start at different times" in caplog.text
    np.testing.assert_array_equal(test.responses, si[2].responses)
    a = ema.estimate_frf(test, band_hz=(20, 400), screening=False)
    b = ema.estimate_frf(si[2], band_hz=(20, 400), screening=False)
    assert a.exp_window_decay == pytest.approx(b.exp_window_decay, rel=1e-9)
    np.testing.assert_allclose(a.data, b.data, rtol=1e-9)

    def shifted(s):
        return start(s["ver_num"]) + (0.01 if s["ver_num"] == 2 and s["rsp_node"] == 102 else 0.0)

    bad = rs.write(tmp_path / "bad.uff", rs.specs(f, r, abscissa_min=shifted), binary=True)
    with pytest.raises(SamplingError, match=r"hit 2, channel 'acc_102' \(node 102\): record starts at .* the force "
                                            r"channel of the same hit"):
        read_hammer(bad, si[1])


# ----------------------------------------------------------------------------------- D6 other function types
def test_d6_other_function_types_are_skipped_with_one_line_per_type(data, si, tmp_path, caplog):
    f, r = data
    time_sets = rs.specs(f, r)
    spectra = [dict(s, func_type=2, data=np.abs(np.fft.rfft(s["data"]))[:512], abscissa_unit="Hz")
               for s in time_sets[:4]]
    frfs = rs.frf_specs(rs.accelerance(np.arange(1, 513) * 1.0), np.arange(1, 513) * 1.0)
    uff = rs.write(tmp_path / "all.uff", time_sets + spectra + frfs, binary=True)
    with caplog.at_level(logging.INFO, logger="ema"):
        test = read_hammer(uff, si[1])
    np.testing.assert_array_equal(test.responses, si[2].responses)
    assert "skipped 4 datasets 58 of function type 2 (auto spectrum)" in caplog.text
    assert "skipped 3 datasets 58 of function type 4 (frequency response function)" in caplog.text
    only_frf = rs.write(tmp_path / "frf.uff", frfs, binary=True)
    with pytest.raises(FunctionTypeError, match=r"no time response.*railmodal lab identify --frf"):
        read_hammer(only_frf, si[1])

    caplog.clear()
    fr = np.arange(1, 513) * 1.0
    h = rs.accelerance(fr)
    auto = [dict(s, func_type=2, data=np.abs(s["data"]) ** 2) for s in rs.frf_specs(h, fr)]
    cross = [dict(s, func_type=3) for s in rs.frf_specs(h, fr)]
    p = rs.write(tmp_path / "frf_all.uff", rs.frf_specs(h, fr) + auto + cross, binary=True)
    with caplog.at_level(logging.INFO, logger="ema"):
        frf = read_frf_uff(p, si[1], exp_window_decay=0.0)
    np.testing.assert_array_equal(frf.data[:, 0], h)
    assert "skipped 3 datasets 58 of function type 3 (cross spectrum)" in caplog.text


# --------------------------------------------------------------------------------- D7 FRF reference node
def test_d7_frf_reference_node_follows_the_time_readers_policy(tmp_path, caplog):
    f = np.arange(1, 801) * 0.5
    h = rs.accelerance(f)
    csv = rs.write_table(tmp_path / "t.csv", rs.table())
    ref = read_frf_uff(rs.write(tmp_path / "900.uff", rs.frf_specs(h, f), binary=True), csv, exp_window_decay=0)
    p0 = rs.write(tmp_path / "ref0.uff", rs.frf_specs(h, f, ref_node=0, ref_dir=0), binary=True)
    with caplog.at_level(logging.INFO, logger="ema"):
        frf = read_frf_uff(p0, csv, exp_window_decay=0)
    np.testing.assert_array_equal(frf.data, ref.data)
    assert "reference node 0 (not set) in 3 FRFs: taken as the channel table's force node 900" in caplog.text
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="ema"):
        read_frf_uff(rs.write(tmp_path / "950.uff", rs.frf_specs(h, f, ref_node=950), binary=True), csv,
                     exp_window_decay=0)
    assert any("reference (excitation) node 950" in m and "node 900" in m for m in warning_lines(caplog))
    mixed = rs.write(tmp_path / "mixed.uff", rs.frf_specs(h, f, ref_node=lambda s: 950 if s["rsp_node"] == 102
                                                           else 900), binary=True)
    with pytest.raises(ReferenceNodeError, match=r"node 900 in datasets 1, 3; node 950 in datasets 2"):
        read_frf_uff(mixed, csv, exp_window_decay=0)


# -------------------------------------------------------------------------------------- D8 driving point
def test_d8_force_and_accelerometer_on_one_node(data, si, si_modes, tmp_path, capsys):
    """A driving point (the hammer and acc_101 both at node 900, told apart by the specific data type) reads and
    identifies as the same data with distinct nodes; the FRF reader too. A true duplicate (same node and
    quantity) and a driving point the file does not tell apart are refused saying what to do."""
    f, r = data
    tab = rs.table()
    tab.loc[1, "node"] = 900
    csv = rs.write_table(tmp_path / "dp.csv", tab)
    uff = rs.write(tmp_path / "dp.uff", rs.specs(f, r, rsp_node=lambda s: 900 if s["rsp_node"] == 101
                                                 else s["rsp_node"]), binary=True)
    test = read_hammer(uff, csv)
    np.testing.assert_array_equal(test.responses, si[2].responses)
    np.testing.assert_array_equal(test.force, si[2].force)
    modes = identify(capsys, tmp_path / "m", "--hammer", uff, "--channels", csv)
    assert_same_modes(modes, si_modes, 1e-12, 1e-12)

    fr = np.arange(1, 801) * 0.5
    p = rs.write(tmp_path / "dp_frf.uff", rs.frf_specs(rs.accelerance(fr), fr, rsp_node=lambda s: 900
                                                      if s["rsp_node"] == 101 else s["rsp_node"]), binary=True)
    assert read_frf_uff(p, csv, exp_window_decay=0).outputs == ("acc_101", "acc_102", "acc_103")

    dup = rs.table()
    dup.loc[2, "node"] = 101
    with pytest.raises(ChannelTableError, match=r"node 101 appears as acceleration in rows \[2, 3\].*own node"):
        ema.validate_channels(dup)
    unknown = rs.write(tmp_path / "dp0.uff", rs.specs(f, r, rsp_node=lambda s: 900 if s["rsp_node"] == 101
                                                      else s["rsp_node"], ordinate_spec=0), binary=True)
    with pytest.raises(ChannelMismatchError, match=r"node 900 is a driving point.*specific data type 0.*distinct "
                                                   r"node numbers"):
        read_hammer(unknown, csv)


# ------------------------------------------------------------------------- D9 uneven flag with even values
@pytest.mark.parametrize("binary, double", [(True, False), (False, True)])
def test_d9_spacing_flag_0_with_evenly_spaced_abscissa(data, si, tmp_path, binary, double):
    f, r = data
    x = np.arange(rs.N) / rs.FS - 0.05
    uff = rs.write(tmp_path / "flag0.uff", rs.specs(f, r, spacing=0, x=x, abscissa_inc=0.0, abscissa_min=0.0),
                   binary=binary, double=double)
    test = read_hammer(uff, si[1])
    # from the abscissa values: as exact as they are written (float32, or 6 digits in ASCII)
    assert test.fs == pytest.approx(rs.FS, rel=1e-7 if binary else 1e-6)
    assert test.time[0] == pytest.approx(-0.05, abs=1e-9 if binary else 1e-6)
    tol = 6e-8 if binary else 1e-12  # float32 samples, or E20.12 fields
    np.testing.assert_allclose(test.responses, si[2].responses, rtol=tol, atol=tol * np.abs(r).max())
    gap = np.delete(np.arange(rs.N + 1) / rs.FS, 1000)
    uneven = rs.write(tmp_path / "gap.uff", rs.specs(f, r, spacing=0, x=gap), binary=binary, double=double)
    with pytest.raises(SamplingError, match=r"dataset 1 \(node 900, hit 1\) \('hammer'\): the abscissa values are "
                                            r"uneven \(step 0\.000488\d* to 0\.00097\d+ s"):
        read_hammer(uneven, si[1])


# ---------------------------------------------------------------------------------- D10 0 Hz of mobility
def test_d10_non_finite_0_hz_line(tmp_path, caplog):
    """A receptance or mobility is undefined at 0 Hz: NaN/inf there is set to 0 (INFO); in an accelerance, or at
    any other line, it stays an error."""
    f = np.arange(0, 800) * 0.5
    acc = rs.accelerance(f)
    csv = rs.write_table(tmp_path / "t.csv", rs.table())
    with np.errstate(divide="ignore", invalid="ignore"):
        rec = acc / (2j * np.pi * f) ** 2
    for quantity, spec, h in (("receptance", 8, rec), ("mobility", 11, np.where(f == 0, np.inf, rec * 2j * np.pi * f))):
        p = rs.write(tmp_path / f"{quantity}.uff", rs.frf_specs(h, f, spec=spec, num_unit="NONE"), binary=True)
        with caplog.at_level(logging.INFO, logger="ema"):
            frf = read_frf_uff(p, csv, exp_window_decay=0)
        assert frf.quantity == quantity and np.all(frf.data[:, 0, 0] == 0)
        np.testing.assert_array_equal(frf.data[:, 0, 1:], h[:, 1:])
        assert f"the {quantity} is NaN or infinite at 0 Hz in 3 FRFs (datasets 1-3)" in caplog.text
    bad_acc = acc.copy()
    bad_acc[:, 0] = np.nan
    p = rs.write(tmp_path / "acc.uff", rs.frf_specs(bad_acc, f), binary=True)
    with pytest.raises(UFFReadError, match="the FRF is NaN at 0 Hz"):
        read_frf_uff(p, csv, exp_window_decay=0)
    rec2 = rec.copy()
    rec2[1, 7] = np.nan
    p = rs.write(tmp_path / "rec2.uff", rs.frf_specs(rec2, f, spec=8, num_unit="NONE"), binary=True)
    with pytest.raises(UFFReadError, match=r"dataset 2, response 'acc_102'.*NaN at 3\.5 Hz \(first of 1 NaN or "
                                           r"infinite line\(s\) above 0 Hz\)"):
        read_frf_uff(p, csv, exp_window_decay=0)


# ------------------------------------------------------------------------------------ D11 hit numbering
def test_d11_hits_numbered_by_order_or_by_a_dataset_counter(data, si, tmp_path, caplog):
    f, r = data
    flat = [dict(s, ver_num=1) for s in rs.specs(f, r)]
    missing = [s for k, s in enumerate(flat) if k != 11]  # hit 3 lacks acc_103
    with pytest.raises(ChannelMismatchError, match=r"every dataset has sequence number 1.*'acc_103' \(node 103, 3\) "
                                                   r"have fewer datasets than the others \(4\)"):
        read_hammer(rs.write(tmp_path / "missing.uff", missing, binary=True), si[1])
    counter = [dict(s, ver_num=k + 1, load_case_id=s["ver_num"]) for k, s in enumerate(rs.specs(f, r))]
    with caplog.at_level(logging.WARNING, logger="ema"):
        test = read_hammer(rs.write(tmp_path / "counter.uff", counter, binary=True), si[1])
    assert test.hits == (1, 2, 3, 4)
    np.testing.assert_array_equal(test.responses, si[2].responses)
    assert "its own sequence number (1..16: a dataset counter, not hit numbers); the hits are numbered by their " \
           "load case" in caplog.text


# ------------------------------------------------------------------------------------ D12 messages
def test_d12_node_0_malformed_record_6_extra_channels_and_table_units(data, si, tmp_path, caplog):
    f, r = data
    node0 = rs.write(tmp_path / "node0.uff", rs.specs(f, r, rsp_node=lambda s: 0 if s["rsp_node"] == 900
                                                      else s["rsp_node"]), binary=True)
    with pytest.raises(UFFReadError, match=r"dataset 1 .*response node 0 is not a valid UFF node.*renumber"):
        read_hammer(node0, si[1])
    long_name = rs.write(tmp_path / "name.uff", rs.specs(f, r, rsp_ent_name="axlebox_left_1"), binary=True)
    with pytest.raises(UFFReadError, match=r"record 6 of dataset 1 is malformed.*outside -6\.\.6.*longer than 10"):
        read_hammer(long_name, si[1])

    mic = [dict(s, rsp_node=501, rsp_dir=0, ordinate_spec=0, ord_unit="Pa", rsp_ent_name="mic")
           for s in rs.specs(f, r) if s["rsp_node"] == 101]
    extra = rs.write(tmp_path / "mic.uff", rs.specs(f, r) + mic, binary=True)
    with caplog.at_level(logging.WARNING, logger="ema"):
        test = read_hammer(extra, si[1])
    np.testing.assert_array_equal(test.responses, si[2].responses)
    (line,) = warning_lines(caplog)
    assert "node 501 ('mic') in 'Pa': 4 datasets" in line and "skipped" in line

    tab = rs.table()
    tab.loc[0, "unit"] = "kN"
    with pytest.raises(ChannelTableError, match=r"row 1 \(node 900\), column 'unit'.*'kN'.*write the SI unit here.*"
                                                r"converted by their labels"):
        ema.validate_channels(tab, source="t.csv")


# -------------------------------------------------------------------------------- D13 abscissa unit, band
def test_d13_abscissa_in_ms_and_band_error_names_the_file(data, si, tmp_path):
    f, r = data
    ms = rs.write(tmp_path / "ms.uff", rs.specs(f, r, abscissa_inc=1e3 / rs.FS, abscissa_unit="ms"), binary=True)
    test = read_hammer(ms, si[1])
    assert test.fs == pytest.approx(si[2].fs, rel=1e-12)  # the writer's 6-digit E13.5 step, in ms or in s
    np.testing.assert_array_equal(test.responses, si[2].responses)
    hz = rs.write(tmp_path / "hz.uff", rs.specs(f, r, abscissa_unit="Hz"), binary=True)
    with pytest.raises(SamplingError, match=r"dataset 1 .*abscissa unit 'Hz' is not a unit of time"):
        read_hammer(hz, si[1])
    with pytest.raises(EstimationError, match=re.escape(f"{si[0]}: band_hz must satisfy") + r".*1024 Hz"):
        ema.estimate_frf(si[2], band_hz=(10.0, 5000.0), screening=False)


# ------------------------------------------------------------------- D14 D15 direction warnings, reprs
def test_d14_d15_one_direction_warning_per_channel_in_both_readers(data, si, tmp_path):
    f, r = data
    uff = rs.write(tmp_path / "dir.uff", rs.specs(f, r, rsp_dir=lambda s: 1 if s["rsp_node"] != 900 else -3),
                   binary=True)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        read_hammer(uff, si[1])
    msgs = [str(w.message) for w in caught if issubclass(w.category, ChannelDirectionWarning)]
    assert len(msgs) == 3, msgs
    assert "channel 'acc_101' (node 101): the file's direction code 1 disagrees with the table's measuring " \
           "direction (0.0, 0.0, 1.0) (datasets 2, 6, 10, 14)" in msgs[0]
    assert not any("np." in m for m in msgs)

    fr = np.arange(1, 801) * 0.5
    p = rs.write(tmp_path / "dir_frf.uff", rs.frf_specs(rs.accelerance(fr), fr, rsp_dir=lambda s: -3
                                                       if s["rsp_node"] == 102 else 3), binary=True)
    with pytest.warns(ChannelDirectionWarning, match=r"response 'acc_102' \(node 102\): the file's direction code -3"):
        read_frf_uff(p, si[1], exp_window_decay=0)

    dup = rs.table()
    dup.loc[3, "node"] = 102
    with pytest.raises(ChannelTableError) as err:
        ema.validate_channels(dup)
    assert "np." not in str(err.value) and "node 102" in str(err.value)
