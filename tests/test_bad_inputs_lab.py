"""Issue 11, lab side: bad hammer-test files and channel tables through ``railmodal lab identify`` / ``lab pair``.

Every bad file is built inside the test from a good virtual-lab campaign. A bad
hit or channel must be rejected by name and leave the identified modes as the
clean campaign's (within 0.05 % in frequency); a bad file or argument must stop
the command with a message naming the file and the item, and write nothing.
"""

from __future__ import annotations

import re

import numpy as np
import pandas as pd
import pytest

import ema
from bad_inputs_support import (
    copy_campaign,
    datasets58,
    find58,
    float32_at,
    identify_small,
    modes_csv,
    nothing_written,
    run,
    same_modes,
    scale_node,
    small_campaign,
    zero_node,
)
from lab_data.cache import campaign_dir
from railmodal.cli import main


@pytest.fixture(scope="module")
def control():
    return campaign_dir("control")


@pytest.fixture(scope="module")
def clean_flexural(control, tmp_path_factory):
    """Modes of the clean flexural setup, identified by the CLI with its defaults."""
    out = tmp_path_factory.mktemp("clean") / "modes"
    assert main(["-q", "lab", "identify", "--hammer", str(control / "flexural.uff"), "--channels",
                 str(control / "flexural_channels.csv"), "--out", str(out)]) == 0
    return modes_csv(out)


@pytest.fixture(scope="module")
def small(control, tmp_path_factory):
    """A small good campaign (4 clean hits, 8 channels, 1 s) and its clean modes (60-300 Hz)."""
    folder = small_campaign(control, tmp_path_factory.mktemp("small"))
    out = folder / "clean_modes"
    assert main(["-q", "lab", "identify", "--hammer", str(folder / "flexural.uff"), "--channels",
                 str(folder / "flexural_channels.csv"), "--band", "60", "300", "--max-order", "30",
                 "--out", str(out)]) == 0
    return folder, modes_csv(out)


def identify(folder, out, capsys, hammer="flexural.uff", channels="flexural_channels.csv", *extra):
    return run(["-q", "lab", "identify", "--hammer", str(folder / hammer), "--channels", str(folder / channels),
                *extra, "--out", str(out)], capsys)


# ------------------------------------------------------------------ case 1: one corrupt force sample
@pytest.mark.slow
def test_case1_a_flipped_byte_in_one_force_sample_rejects_that_hit(control, clean_flexural, tmp_path, capsys):
    raw = bytearray((control / "flexural.uff").read_bytes())
    d = find58(raw, hit=4, node=900)
    at = d.data + 4 * 30000 + 3  # the high byte of little-endian float32 sample 30000
    raw[at] ^= 0x40  # one bit: ~0.05 N of noise becomes ~1e37 N
    assert float32_at(raw, d, 30000) > 1e36
    bad = copy_campaign(control, tmp_path / "bad", names=("flexural_channels.csv",))
    (bad / "flexural.uff").write_bytes(bytes(raw))
    code, out, err = identify(bad, tmp_path / "modes", capsys)
    assert code == 0, err
    assert re.search(r"hit 4 rejected \(force not a pulse\).*single sample", out)
    screening = pd.read_csv(tmp_path / "modes" / "screening.csv")
    assert set(screening.loc[screening["reason"] == "force not a pulse", "hit"]) == {4}
    got = modes_csv(tmp_path / "modes")
    assert same_modes(got, clean_flexural), (got, clean_flexural)


@pytest.mark.slow
def test_case1_b_wrong_byte_order_of_one_force_dataset_names_the_hit(control, clean_flexural, tmp_path, capsys):
    raw = bytearray((control / "flexural.uff").read_bytes())
    d = find58(raw, hit=4, node=900)
    line = bytes(raw[d.header:raw.index(b"\n", d.header)])
    assert line[7:13] == b"     1"  # byte ordering 1 = little endian
    raw[d.header + 12] = ord("2")  # ... now says big endian
    bad = copy_campaign(control, tmp_path / "bad", names=("flexural_channels.csv",))
    (bad / "flexural.uff").write_bytes(bytes(raw))
    code, out, err = identify(bad, tmp_path / "modes", capsys)
    assert code == 0, err
    assert "hit 4 rejected (force not a pulse)" in out
    assert "low coherence" not in out  # the other hits' channels are fine
    assert same_modes(modes_csv(tmp_path / "modes"), clean_flexural)


@pytest.mark.parametrize("fault, reason, detail", [
    ("spike", "force not a pulse", r"force peak 1\.3e\+37 N at sample 9000 .* is a single sample"),
    # the median of the four peaks (hit 2's included) is 952 N: hit 2's 24.8 kN is 26 x it
    ("scale", "force too strong", r"peak 2\.478e\+04 N is 26 x the median peak 952\.3 N of the hits"),
    ("hum", "force not a pulse", r"\d+ % of the force energy lies outside the main pulse"),
])
def test_case1_force_plausibility_checks_fire_on_their_fault_only(small, fault, reason, detail):
    """Screening alone, on the small campaign's clean hits: a single-sample spike, a peak far above the other hits',
    most of the force energy outside the pulse — each rejects hit 2 with its own reason, and nothing else."""
    folder, _ = small
    test = ema.read_hammer(folder / "flexural.uff", folder / "flexural_channels.csv")
    assert ema.screen_hits(test).rejections == ()
    force, resp = test.force.copy(), test.responses.copy()
    if fault == "spike":
        force[1, 9000] = 1.3e37  # a corrupt sample far from the pulse
    elif fault == "scale":
        force[1] *= 30.0  # a peak 30 x the others' (a wrong scale factor) ...
        resp[1] *= 30.0  # ... with consistent responses, so only the force's size is odd
    else:
        force[1] += 40.0 * np.sin(2 * np.pi * 50.0 * test.time)  # 40 N of mains hum on the force channel
    bad = ema.HammerTest.from_arrays(force, resp, test.fs, test.channels, hit_numbers=test.hits, source="synthetic")
    scr = ema.screen_hits(bad)
    assert [(r.hit, r.channel, r.reason) for r in scr.rejections] == [(2, None, reason)], scr.rejections
    assert re.search(detail, scr.rejections[0].detail), scr.rejections[0].detail
    np.testing.assert_array_equal(scr.accepted.all(axis=1), [True, False, True, True])


def test_case1_a_late_triggered_hit_is_rejected_as_a_hit_not_through_its_channels(small):
    """Hit 2 recorded with its pulse at 0.8 s of the 1 s record (a late trigger; the other hits at 0.1 s): its
    response is cut before the exponential window takes it down, and its leakage once lowered every channel's
    coherence until channels, not the hit, were rejected. Now that hit alone is, by its own reason."""
    folder, _ = small
    test = ema.read_hammer(folder / "flexural.uff", folder / "flexural_channels.csv")
    start = ema.estimate.main_pulse(test.force[1])[0]
    shift = int(0.8 * test.fs) - start
    force, resp = test.force.copy(), test.responses.copy()
    force[1], resp[1] = np.roll(force[1], shift), np.roll(resp[1], shift, axis=-1)
    force[1, :shift], resp[1, :, :shift] = force[1, shift], resp[1, :, shift:shift + 1]  # quiet pre-trigger
    bad = ema.HammerTest.from_arrays(force, resp, test.fs, test.channels, hit_numbers=test.hits, source="synthetic")
    scr = ema.screen_hits(bad, band_hz=(60.0, 300.0))
    assert [(r.hit, r.channel, r.reason) for r in scr.rejections] == [(2, None, "pulse too late")], scr.rejections
    assert re.search(r"pulse at t = 0\.8\d* s leaves 0\.2 s of the record, the other hits' median 0\.899 s",
                     scr.rejections[0].detail), scr.rejections[0].detail
    np.testing.assert_array_equal(scr.accepted.all(axis=1), [True, False, True, True])


def test_case1_a_dc_offset_on_the_accelerometers_is_removed_and_named(small, tmp_path, capsys, caplog):
    """DC-coupled accelerometers record gravity: +9.81 m/s^2 on every response channel of the small campaign.
    The exponential window turns a constant into a 1/f spectrum incoherent with the force: half the channels were
    rejected for low coherence. The spectra and levels are taken about each record's offset (the channels named in a
    warning), and the modes are the clean campaign's."""
    folder, clean_modes = small
    raw = bytearray((folder / "flexural.uff").read_bytes())
    force_node = int(pd.read_csv(folder / "flexural_channels.csv").query("quantity == 'force'")["node"].iloc[0])
    for d in datasets58(bytes(raw)):
        if d.node != force_node:
            x = np.frombuffer(bytes(raw[d.data:d.data + d.n_bytes]), "<f4") + np.float32(9.81)
            raw[d.data:d.data + d.n_bytes] = x.astype("<f4").tobytes()
    bad = copy_campaign(folder, tmp_path / "bad", names=("flexural_channels.csv",))
    (bad / "flexural.uff").write_bytes(bytes(raw))
    with caplog.at_level("WARNING", logger="ema"):
        code, out, err = identify_small(bad, tmp_path / "modes", capsys)
    assert code == 0, err
    assert re.search(r"flexural.uff: 8 channel\(s\) carry a DC offset \(median over the hits, m/s\^2\): "
                     r"\w+ \+9\.81", caplog.text), caplog.text
    assert "rejected" not in out, out
    assert same_modes(modes_csv(tmp_path / "modes"), clean_modes)


# ------------------------------------------------------------------ case 2: one channel 1e6 x too large
@pytest.mark.slow
def test_case2_a_channel_a_million_times_too_large_is_rejected(control, clean_flexural, tmp_path, capsys):
    raw = bytearray((control / "flexural.uff").read_bytes())
    scale_node(raw, 105, 1e6)  # wrong sensitivity on axle_05 in every hit
    bad = copy_campaign(control, tmp_path / "bad", names=("flexural_channels.csv",))
    (bad / "flexural.uff").write_bytes(bytes(raw))
    code, out, err = identify(bad, tmp_path / "modes", capsys)
    assert code == 0, err
    table = pd.read_csv(control / "flexural_channels.csv").set_index("node")
    name = table.loc[105, "name"]
    assert re.search(rf"channel '{name}' \(node 105\) in every hit rejected \(level off its neighbours\): RMS level "
                     rf"1\.0\de\+06 x the median of its 4 nearest sensors", out), out
    assert same_modes(modes_csv(tmp_path / "modes"), clean_flexural)


def test_case2_weighting_keeps_one_channel_from_swamping_identification(small):
    """Without screening, identification alone: one channel 1e6 x too large changes no mode (weights <= 1)."""
    folder, clean_modes = small
    test = ema.read_hammer(folder / "flexural.uff", folder / "flexural_channels.csv")
    frf = ema.estimate_frf(test, band_hz=(60.0, 300.0))
    j = 3
    scaled = frf.with_history("one channel x 1e6", data=frf.data * np.where(np.arange(frf.n_out) == j, 1e6, 1.0)
                              [:, None, None])
    result = ema.identify(scaled, band_hz=(60.0, 300.0), max_order=30)
    assert set(result.weights) == {frf.outputs[j]} and result.weights[frf.outputs[j]] < 1e-4
    assert same_modes(result.modes.freqs_hz, clean_modes)
    # the modal constants are those of the data as measured (that channel's are 1e6 x), within 1 % of each mode's
    # largest constant (the poles moved by < 0.05 %)
    clean = ema.identify(frf, band_hz=(60.0, 300.0), max_order=30)
    assert clean.weights == {}
    scale = np.abs(clean.modes.shapes).max(axis=0)
    assert np.all(np.abs(result.modes.shapes[j] / 1e6 - clean.modes.shapes[j]) <= 0.01 * scale)
    others = np.arange(frf.n_out) != j
    assert np.all(np.abs(result.modes.shapes[others] - clean.modes.shapes[others]) <= 0.01 * scale)


# ------------------------------------------------------------------ case 7: node number above 2^63
def test_case7_node_number_above_2_63_in_a_channel_table(small, tmp_path, capsys):
    folder, _ = small
    table = pd.read_csv(folder / "flexural_channels.csv").astype(object)
    table.loc[2, "fe_node"] = 2**64 + 1
    table.to_csv(tmp_path / "channels.csv", index=False)
    text = (tmp_path / "channels.csv").read_text()
    assert "18446744073709551617" in text
    code, out, err = run(["-q", "lab", "identify", "--hammer", str(folder / "flexural.uff"), "--channels",
                          str(tmp_path / "channels.csv"), "--out", str(tmp_path / "o")], capsys)
    assert code == 1 and "Traceback" not in err
    assert "channels.csv" in err and "row 3" in err and "'fe_node'" in err and "2147483647" in err
    assert nothing_written(tmp_path / "o")


# ------------------------------------------------------------------ case 10: argument types with ranges
@pytest.mark.parametrize("extra, words", [
    (["--max-order", "0"], "--max-order must be an integer in [1, 300], got 0"),
    (["--max-order", "1000"], "--max-order must be an integer in [1, 300], got 1000"),
    (["--max-order", "ten"], "--max-order must be an integer in [1, 300], got 'ten'"),
    (["--band", "500", "10"], "--band LOW HIGH needs LOW < HIGH, got 500 10"),
    (["--band", "nan", "500"], "--band must be a finite number"),
    (["--band", "-5", "500"], "--band must be a number in [0, 100000] Hz, got -5"),
])
def test_case10_identify_arguments_have_ranges(small, tmp_path, capsys, extra, words):
    folder, _ = small
    code, out, err = identify(folder, tmp_path / "o", capsys, "flexural.uff", "flexural_channels.csv", *extra)
    assert code == 2 and words in err, err
    assert nothing_written(tmp_path / "o")


@pytest.mark.parametrize("value", ["2", "nan", "0", "-0.5"])
def test_case10_pair_mac_min_has_a_range(small, tmp_path, capsys, value):
    folder, _ = small
    code, out, err = run(["-q", "lab", "pair", "--modes", str(folder / "clean_modes"), "--fem",
                          str(folder / "fe_design.uff"), "--mac-min", value, "--out", str(tmp_path / "o")], capsys)
    assert code == 2 and "--mac-min must be a" in err and "(0, 1]" in err
    assert nothing_written(tmp_path / "o")


def test_case10_a_band_above_nyquist_is_named_before_writing(small, tmp_path, capsys):
    folder, _ = small
    code, out, err = identify(folder, tmp_path / "o", capsys, "flexural.uff", "flexural_channels.csv",
                              "--band", "10", "9000")
    assert code == 1 and "fs/2 = 6400 Hz" in err
    assert nothing_written(tmp_path / "o")


# ------------------------------------------------------------------ case 11: Fortran D exponents, ***** fields
def _ascii_small(folder, tmp_path):
    """Two hits of the small campaign's hammer test rewritten as ASCII UFF58 (E20.12 numbers)."""
    from lab_data.uff_export import TimeHistory, write_time_histories

    full = ema.read_hammer(folder / "flexural.uff", folder / "flexural_channels.csv")
    test = ema.HammerTest.from_arrays(full.force[:2], full.responses[:2], full.fs, full.channels,
                                      hit_numbers=full.hits[:2])
    table = pd.read_csv(folder / "flexural_channels.csv")
    hist = [TimeHistory(h, 900, 0, "force", "N", "hammer", test.dt, test.force[i], 900, 0) for i, h in
            enumerate(test.hits)]
    acc = table[table["quantity"] == "acceleration"]
    for i, h in enumerate(test.hits):
        for j, r in enumerate(acc.itertuples()):
            hist.append(TimeHistory(h, int(r.node), 0, "acceleration", "m/s^2", r.name, test.dt,
                                    test.responses[i, j], 900, 0))
    path = write_time_histories(tmp_path / "ascii.uff", hist, binary=False)
    return path, test


def test_case11_fortran_d_exponents_in_uff58_are_read(small, tmp_path):
    folder, _ = small
    path, test = _ascii_small(folder, tmp_path)
    text = path.read_text()
    d_text = re.sub(r"(\d)E([+-]\d\d)", r"\1D\2", text)
    assert d_text.count("D+") + d_text.count("D-") > 1000
    (tmp_path / "d.uff").write_text(d_text)
    back = ema.read_hammer(tmp_path / "d.uff", folder / "flexural_channels.csv")
    np.testing.assert_array_equal(back.force, ema.read_hammer(path, folder / "flexural_channels.csv").force)
    np.testing.assert_allclose(back.responses, test.responses, rtol=1e-6, atol=1e-9)


def test_case11_overflow_field_in_uff58_names_dataset_record_and_cause(small, tmp_path, capsys):
    folder, _ = small
    path, _ = _ascii_small(folder, tmp_path)
    lines = path.read_text().split("\n")
    # dataset 2 (first acceleration of hit 1): its 14th line is a data record
    starts = [k for k, ln in enumerate(lines) if ln.strip() == "58"]
    k = starts[1] + 14
    lines[k] = "*" * 20 + lines[k][20:]
    (tmp_path / "star.uff").write_text("\n".join(lines))
    code, out, err = identify(tmp_path, tmp_path / "o", capsys, "star.uff", str(folder / "flexural_channels.csv"))
    assert code == 1 and "Traceback" not in err
    assert "star.uff" in err and "dataset 2 (type 58), record 14" in err and f"line {k + 1}" in err
    assert "Fortran overflow" in err
    assert nothing_written(tmp_path / "o")


def test_case11_d_exponents_and_overflow_in_uff55(small, tmp_path, capsys):
    import fem_import

    folder, _ = small
    text = (folder / "fe_design.uff").read_text()
    lines = text.split("\n")
    first55 = next(k for k, ln in enumerate(lines) if ln.strip() == "55")
    d_lines = lines[:first55] + [re.sub(r"(\d)E([+-]\d\d)", r"\1D\2", ln) if k > 5 else ln
                                 for k, ln in enumerate(lines[first55:])]
    (tmp_path / "d55.uff").write_text("\n".join(d_lines))
    a, b = fem_import.read(folder / "fe_design.uff"), fem_import.read(tmp_path / "d55.uff")
    np.testing.assert_array_equal(a.shapes, b.shapes)
    np.testing.assert_array_equal(a.freqs_hz, b.freqs_hz)
    lines[first55 + 11] = lines[first55 + 11][:13] + "*" * 13 + lines[first55 + 11][26:]
    (tmp_path / "star55.uff").write_text("\n".join(lines))
    code, out, err = run(["-q", "lab", "pair", "--modes", str(folder / "clean_modes"), "--fem",
                          str(tmp_path / "star55.uff"), "--out", str(tmp_path / "o")], capsys)
    assert code == 1 and "Traceback" not in err
    assert "star55.uff" in err and "(type 55)" in err and "record 11" in err and "Fortran overflow" in err
    assert nothing_written(tmp_path / "o")


# ------------------------------------------------------------------ case 12: a dead channel is called dead
def test_case12_a_dead_channel_is_called_dead_not_clipped(small, tmp_path, capsys):
    folder, clean = small
    raw = bytearray((folder / "flexural.uff").read_bytes())
    node = datasets58(bytes(raw))[1].node
    zero_node(raw, node)
    bad = copy_campaign(folder, tmp_path / "bad", names=("flexural_channels.csv",))
    (bad / "flexural.uff").write_bytes(bytes(raw))
    code, out, err = identify_small(bad, tmp_path / "o", capsys)
    assert code == 0, err
    name = pd.read_csv(folder / "flexural_channels.csv").set_index("node").loc[node, "name"]
    assert re.search(rf"channel '{name}' \(node {node}\) in hit 1 rejected \(dead channel\): all 12800 samples are "
                     rf"0 m/s\^2", out), out
    assert "clipped" not in out
    assert same_modes(modes_csv(tmp_path / "o"), clean)


# ------------------------------------------------------------------ case 13: separators
@pytest.mark.parametrize("sep, decimal", [(";", ","), (";", "."), ("\t", ".")])
def test_case13_semicolon_decimal_comma_and_tab_channel_tables_are_read(small, tmp_path, capsys, sep, decimal):
    folder, clean = small
    table = pd.read_csv(folder / "flexural_channels.csv")
    table.to_csv(tmp_path / "channels.csv", sep=sep, decimal=decimal, index=False)
    code, out, err = identify(folder, tmp_path / "o", capsys, "flexural.uff", str(tmp_path / "channels.csv"),
                              "--band", "60", "300", "--max-order", "30")
    assert code == 0, err
    assert same_modes(modes_csv(tmp_path / "o"), clean)
    read = ema.read_channels(tmp_path / "channels.csv")
    np.testing.assert_allclose(read[["x", "y", "z"]].to_numpy(float), table[["x", "y", "z"]].to_numpy(float))


def test_case13_decimal_commas_in_a_comma_separated_table_are_named(small, tmp_path, capsys):
    folder, _ = small
    text = (folder / "flexural_channels.csv").read_text().split("\n")
    text[2] = text[2].replace("0.0,", "0,0,", 1)
    (tmp_path / "channels.csv").write_text("\n".join(text))
    code, out, err = identify(folder, tmp_path / "o", capsys, "flexural.uff", str(tmp_path / "channels.csv"))
    assert code == 1 and "channels.csv" in err and "decimal commas in a comma-separated file" in err
    assert nothing_written(tmp_path / "o")


# ------------------------------------------------------------------ case 14: conversion errors name row and column
def test_case14_a_non_number_in_a_channel_table_names_file_row_and_column(small, tmp_path, capsys):
    folder, _ = small
    table = pd.read_csv(folder / "flexural_channels.csv").astype(object)
    table.loc[2, "z"] = "abc"
    table.to_csv(tmp_path / "channels.csv", index=False)
    code, out, err = identify(folder, tmp_path / "o", capsys, "flexural.uff", str(tmp_path / "channels.csv"))
    assert code == 1
    assert re.search(r"channels\.csv.*row 3 \(node \d+\), column 'z': expected a finite number, got 'abc'", err), err
    assert nothing_written(tmp_path / "o")


# ------------------------------------------------------------------ case 17: --out a file, --hammer a folder
def test_case17_out_an_existing_file_and_hammer_a_folder(small, tmp_path, capsys):
    folder, _ = small
    (tmp_path / "taken").write_text("not a folder")
    code, out, err = identify(folder, tmp_path / "taken", capsys)
    assert code == 2 and "--out" in err and "is an existing file, not a folder" in err
    assert (tmp_path / "taken").read_text() == "not a folder"
    code, out, err = run(["-q", "lab", "identify", "--hammer", str(folder), "--channels",
                          str(folder / "flexural_channels.csv"), "--out", str(tmp_path / "o")], capsys)
    assert code == 2 and f"--hammer {str(folder)!r} is a folder, not a file" in err
    code, out, err = run(["-q", "lab", "identify", "--hammer", str(folder / "flexural.uff"), "--channels",
                          str(folder / "missing.csv"), "--out", str(tmp_path / "o")], capsys)
    assert code == 2 and "missing.csv" in err and "does not exist" in err
    assert nothing_written(tmp_path / "o")


def test_case6_identify_keeps_an_existing_out_folder_intact_on_failure(small, tmp_path, capsys):
    """Write last: a failure leaves --out as it was (old results stay, nothing half-written)."""
    folder, _ = small
    out = tmp_path / "o"
    out.mkdir()
    (out / "modes.csv").write_text("old results\n")
    (tmp_path / "bad.uff").write_bytes((folder / "flexural.uff").read_bytes()[:-5000])  # truncated
    code, _, err = identify(folder, out, capsys, str(tmp_path / "bad.uff"))
    assert code == 1 and "bad.uff" in err and "truncated" in err
    assert [p.name for p in out.iterdir()] == ["modes.csv"] and (out / "modes.csv").read_text() == "old results\n"
    assert not any(p.name.startswith(".o.partial-") for p in tmp_path.iterdir())
    # and a success replaces them
    code, _, err = identify_small(folder, out, capsys)
    assert code == 0, err
    assert {"modes.csv", "modes.uff", "screening.csv", "stabilisation.png", "synthesis.png"} <= {
        p.name for p in out.iterdir()}
    assert same_modes(modes_csv(out), small[1])
