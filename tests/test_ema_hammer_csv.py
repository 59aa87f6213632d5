"""A hammer test exported by a DAQ program as a wide CSV table (ema.hammer_csv, ema.wide_csv).

Oracles: the toy continuous recording of test_ema_continuous, whose hits and modes are known, written as a DAQ
writes it (time to 7 decimals, values to 7 significant digits, accelerations in g, a preamble), must read as the
recording cut into hits and identify its modes; written with ``;`` and decimal commas, the same. The virtual lab's
small campaign, one CSV file per hit, must read as its UFF file to the text's precision. Each defect of a toy file
(a time column too coarse for the rate, a word in a cell, a row cut short, a channel with empty cells, a table
name the file lacks) must be refused naming the file and the row, column or channel.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import ema
from bad_inputs_support import small_campaign
from ema.hammer_csv import time_resolution
from lab_data.cache import campaign_dir
from test_ema_continuous import FS, TRUTH, continuous, table

G = 9.80665


def write_csv(path, time, columns, *, sep=",", decimal=".", time_format="%.7f", preamble=()):
    """``columns``: [(header, values)]; values written to 7 significant digits, as exports usually do."""
    lines = list(preamble)
    lines.append(sep.join(["time [s]"] + [h for h, _ in columns]))
    cells = [np.char.mod(time_format, np.asarray(time, float))]
    cells += [np.char.mod("%.6e", np.asarray(v, float)) for _, v in columns]
    rows = np.stack(cells, axis=1)
    if decimal != ".":
        rows = np.char.replace(rows, ".", decimal)
    lines += [sep.join(r) for r in rows]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def toy_columns(test: ema.HammerTest):
    return ([("Hammer [N]", test.force[0])]
            + [(f"ch{j} [g]", test.responses[0, j] / G) for j in range(test.n_channels)])


def test_time_resolution_is_the_decimals_the_stamps_were_written_to():
    t = np.arange(1000) / 12800.0
    assert time_resolution(np.round(t, 6)) == pytest.approx(1e-6)
    assert time_resolution(np.round(t, 3)) == pytest.approx(1e-3)
    assert time_resolution(t) == pytest.approx(1e-9)  # k/12800 s is exact in 9 decimals
    assert time_resolution(np.arange(1000) / 3000.0) == 0.0  # full precision: no rounding to allow for
    assert time_resolution(np.arange(5.0)) == 1.0


def test_a_daq_export_is_read_by_name_converted_and_cut_into_hits(tmp_path):
    rec = continuous()
    table().to_csv(tmp_path / "channels.csv", index=False)
    path = write_csv(tmp_path / "export.csv", rec.time, toy_columns(rec),
                     preamble=("DAQ export v3.2", "Start: 2026-11-30 09:12:44", "# not a hash header here"))
    test = ema.read_hammer(path, tmp_path / "channels.csv")
    # 7 decimals round every stamp by up to 5e-8 s, 0.016 % of the 3200 Hz interval: the rate is the true one
    assert test.fs == pytest.approx(FS, rel=1e-7)
    cut = ema.continuous.split_continuous(rec)
    assert test.n_hits == cut.n_hits == 5 and test.n_samples == cut.n_samples
    np.testing.assert_allclose(test.responses, cut.responses, rtol=1e-6, atol=1e-6 * np.abs(cut.responses).max())
    assert any("CSV" in h for h in test.history)
    screening = ema.screen_hits(test, band_hz=(20.0, 600.0))
    frf = ema.estimate_frf(test, band_hz=(20.0, 600.0), screening=screening)
    modes = ema.identify(frf, band_hz=(20.0, 600.0), max_order=20).modes
    np.testing.assert_allclose(np.sort(modes.freqs_hz), TRUTH.freqs_hz, rtol=1e-3)
    # a European spreadsheet: ';' and decimal commas, the same test
    eu = write_csv(tmp_path / "eu.csv", rec.time, toy_columns(rec), sep=";", decimal=",")
    np.testing.assert_array_equal(ema.read_hammer(eu, tmp_path / "channels.csv").responses, test.responses)


def test_bad_daq_exports_are_refused_by_file_row_and_column(tmp_path):
    rec = continuous(rebound_after=None)
    csv = tmp_path / "channels.csv"
    table().to_csv(csv, index=False)
    cols = toy_columns(rec)
    # milliseconds to 3 decimals of a second: 1 ms steps cannot tell 3200 Hz samples apart
    with pytest.raises(ema.SamplingError, match=r"coarse\.csv: the time column is written to 0\.001 s, while the "
                                                r"samples are"):
        ema.read_hammer(write_csv(tmp_path / "coarse.csv", rec.time, cols, time_format="%.3f"), csv)
    # 5 decimals: 1e-5 s rounding is 3 % of the interval, read within that resolution, not refused as jitter
    five = ema.read_hammer(write_csv(tmp_path / "five.csv", rec.time, cols, time_format="%.5f"), csv)
    assert five.fs == pytest.approx(FS, rel=1e-6)
    # a word where a number should be
    path = write_csv(tmp_path / "word.csv", rec.time, cols)
    lines = path.read_text().splitlines()
    fields = lines[1001].split(",")
    fields[2] = "overload"
    lines[1001] = ",".join(fields)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(ema.CSVReadError, match=r"word\.csv: column 'ch0 \[g\]', data row 1001 .*'overload' is not "
                                               r"a number"):
        ema.read_hammer(path, csv)
    # the export cut short in the middle of a row
    text = write_csv(tmp_path / "whole.csv", rec.time, cols).read_text()
    (tmp_path / "cut.csv").write_text(text[:len(text) // 2 + 7])
    with pytest.raises(ema.CSVReadError, match=r"cut\.csv: data row \d+ \(line \d+\) has \d field\(s\), the column "
                                               r"header 5: the file is cut short"):
        ema.read_hammer(tmp_path / "cut.csv", csv)
    # one channel written every other row only (a slower module)
    path = write_csv(tmp_path / "half.csv", rec.time, cols)
    lines = path.read_text().splitlines()
    for k in range(2, len(lines), 2):
        f = lines[k].split(",")
        f[3] = ""
        lines[k] = ",".join(f)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(ema.SamplingError, match=r"half\.csv: channel 'ch1' \(column 4\): 12800 samples \(1600 Hz\), "
                                                r"the force channel 'Hammer' 25600"):
        ema.read_hammer(path, csv)
    # a table name the export does not hold
    renamed = [cols[0], ("acc0 [g]", cols[1][1])] + cols[2:]
    with pytest.raises(ema.ChannelMismatchError, match=r"miss\.csv: 1 channel of the channel table not in the file: "
                                                       r"'ch0'.*export's channels \(the file holds 'Hammer', 'acc0'"):
        ema.read_hammer(write_csv(tmp_path / "miss.csv", rec.time, renamed), csv)


def test_a_triggered_export_reads_one_hit_per_trigger(tmp_path):
    """A DAQ's triggered export: each trigger's record appended with its own time stamps, from the pre-trigger's
    negative time. Each restart of the time column starts a hit; the hits are the continuous recording's cut,
    in the file's order. A trigger cut short is refused naming it and its length against the first."""
    cut = ema.continuous.split_continuous(continuous())
    table().to_csv(tmp_path / "channels.csv", index=False)
    t = cut.time - cut.time[0] - 0.05
    # each trigger's stamps from its own trigger instant: a jitter of a fraction of a sample, earlier in the later
    # triggers, must not reorder the hits
    time = np.concatenate([t - 1e-5 * k for k in range(cut.n_hits)])
    cols = [("Hammer [N]", cut.force.ravel())]
    cols += [(f"ch{j} [g]", cut.responses[:, j].ravel() / G) for j in range(cut.n_channels)]
    path = write_csv(tmp_path / "triggered.csv", time, cols)
    test = ema.read_hammer(path, tmp_path / "channels.csv")
    assert test.n_hits == cut.n_hits == 5 and test.n_samples == cut.n_samples
    assert test.fs == pytest.approx(FS, rel=1e-7) and test.time[0] == pytest.approx(-0.05, abs=1e-7)
    np.testing.assert_allclose(test.force, cut.force, rtol=1e-6, atol=1e-6 * np.abs(cut.force).max())
    np.testing.assert_allclose(test.responses, cut.responses, rtol=1e-6, atol=1e-6 * np.abs(cut.responses).max())
    assert any("5 triggered records of " in h and "in triggers 1, 2, 3, 4, 5" in h for h in test.history)
    # the third trigger lost its last 100 rows
    lines = path.read_text().splitlines()
    n = cut.n_samples
    del lines[1 + 3 * n - 100:1 + 3 * n]
    (tmp_path / "short.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(ema.SamplingError, match=rf"short\.csv: hit 3 \(trigger 3, .*\): {n - 100} samples at "
                                                rf"3200 Hz, hit 1 \(trigger 1\) {n} at 3200 Hz"):
        ema.read_hammer(tmp_path / "short.csv", tmp_path / "channels.csv")


def test_a_triggered_export_with_absolute_times_and_a_recording_with_lost_samples(tmp_path):
    """Absolute trigger times (trigger k's record from 10 k s on, one length for all): each jump forward starts a
    hit, and the hits are the recording's cut. A continuous recording that lost 320 samples jumps forward once,
    between records of different lengths: a gap, refused as such with its time."""
    cut = ema.continuous.split_continuous(continuous())
    table().to_csv(tmp_path / "channels.csv", index=False)
    t = cut.time - cut.time[0] - 0.05
    cols = [("Hammer [N]", cut.force.ravel())]
    cols += [(f"ch{j} [g]", cut.responses[:, j].ravel() / G) for j in range(cut.n_channels)]
    path = write_csv(tmp_path / "absolute.csv", np.concatenate([10.0 * k + t for k in range(cut.n_hits)]), cols)
    test = ema.read_hammer(path, tmp_path / "channels.csv")
    assert test.n_hits == cut.n_hits and test.n_samples == cut.n_samples
    np.testing.assert_allclose(test.responses, cut.responses, rtol=1e-6, atol=1e-6 * np.abs(cut.responses).max())
    rec = continuous(rebound_after=None)
    keep = np.r_[0:20000, 20320:rec.n_samples]
    lossy = write_csv(tmp_path / "lossy.csv", rec.time[keep],
                      [(h, v[keep]) for h, v in toy_columns(rec)])
    with pytest.raises(ema.SamplingError, match=r"lossy\.csv: channel 'Hammer': a gap of 0\.100\d* s \(320 samples "
                                                r"lost\?\) at t = 6\.2496\d* s"):
        ema.read_hammer(lossy, tmp_path / "channels.csv")


def test_the_lab_campaign_one_csv_file_per_hit_reads_as_its_uff_file(tmp_path_factory):
    folder = small_campaign(campaign_dir("control"), tmp_path_factory.mktemp("csv"))
    test = ema.read_hammer(folder / "flexural.uff", folder / "flexural_channels.csv")
    chans = pd.read_csv(folder / "flexural_channels.csv")
    acc = chans[chans["quantity"] == "acceleration"].reset_index(drop=True)
    fname = str(chans.loc[chans["quantity"] == "force", "name"].iloc[0])
    files = []
    for i, hit in enumerate(test.hits):
        cols = [(f"{fname} [N]", test.force[i])]
        cols += [(f"{r['name']} [m/s^2]", test.responses[i, j]) for j, r in acc.iterrows()]
        files.append(write_csv(folder / f"hit{hit}.csv", test.time, cols, time_format="%.9f"))
    logged = ema.read_hammer(files, folder / "flexural_channels.csv")
    assert logged.n_hits == test.n_hits and logged.fs == pytest.approx(test.fs, rel=1e-9)
    # 7 significant digits in the text: the UFF file's float32 samples to within 5e-7 of each value
    np.testing.assert_allclose(logged.responses, test.responses, rtol=6e-7, atol=1e-9 * np.abs(test.responses).max())
    np.testing.assert_allclose(logged.force, test.force, rtol=6e-7, atol=1e-9 * np.abs(test.force).max())


@pytest.mark.parametrize("sep, decimal", [(",", "."), (";", ",")])
def test_the_one_pass_parse_gives_the_cell_by_cell_one(tmp_path, sep, decimal):
    """A table of numbers, blank cells and NaN words is parsed in one pass of pandas' C parser (8x faster on a
    125 MB export, benchmarks/bench_wide_csv.py); it must give what the cell-by-cell parse gives: a blank cell no
    sample, a NaN word a lost one, rows out of time order sorted."""
    from ema import wide_csv

    rng = np.random.default_rng(2)
    t = np.arange(2000) / 3200.0
    cols = [(f"c{j} [g]", rng.standard_normal(t.size) * 10.0 ** rng.integers(-6, 6, t.size)) for j in range(3)]
    path = write_csv(tmp_path / "t.csv", t, cols, sep=sep, decimal=decimal, time_format="%.17g")
    lines = path.read_text().splitlines()
    # a lost sample written as a word, and two rows swapped (a logger merging buffers)
    f = lines[11].split(sep)
    f[2] = "n/a"
    lines[11] = sep.join(f)
    lines[20], lines[21] = lines[21], lines[20]
    # a slower channel: c2 written every third row only (no sample between)
    for k in range(2, len(lines), 3):
        f = lines[k].split(sep)
        f[3] = ""
        lines[k] = sep.join(f)
    path.write_text("\n".join(lines) + "\n")
    table = wide_csv.read_wide_table(path, ValueError)
    assert wide_csv._all_numbers(path, 0, sep, sep == ";", 4) is not None  # the one-pass path was taken
    names = [(f"c{j}", "g") for j in range(3)]
    slow = wide_csv._columns_cell_by_cell(path, 0, sep, sep == ";", [ln.strip() for ln in lines[0].split(sep)],
                                          names, 1.0, ValueError, "table")
    for name, _ in names:
        np.testing.assert_array_equal(table.columns[name].t, slow[name].t)
        np.testing.assert_array_equal(table.columns[name].values, slow[name].values)
    assert np.isnan(table.columns["c1"].values[10]) and np.all(np.diff(table.columns["c0"].t) > 0)
    c2 = table.columns["c2"]
    assert c2.t.size == 2000 - len(range(2, 2001, 3)) and not np.isnan(c2.values).any()
    # and both are the text's numbers, correctly rounded
    np.testing.assert_array_equal(table.columns["c0"].values[:10], [float(f"{v:.6e}") for v in cols[0][1][:10]])
