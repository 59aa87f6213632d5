"""A hammer test recorded by a data logger into an MDF file, continuously or triggered (ema.hammer_mdf).

Oracles: the virtual lab's small campaign, its triggered hits end to end in MDF 4 channels named as a logger
names them (accelerations in g), which must identify as the triggered UFF file does (modes within 0.05 %); and a
toy recording whose every defect (a lost block of samples, a channel at another rate, a damaged file, a table
name the file lacks, raw volts without a sensitivity) is known and must be named; the same toy cut into hits and
written back as triggered records, in three layouts, must read as those hits, and a lost, orphaned or short
record or a unit changing between hits must be named by hit and channel.
"""

from __future__ import annotations

import logging

import numpy as np
import pandas as pd
import pytest

import ema
from bad_inputs_support import identify_small, modes_csv, same_modes, small_campaign
from ema.hammer_io import UnitSystemError
from lab_data.cache import campaign_dir
from test_ema_continuous import FS, TRUTH, continuous, table

G = 9.80665


def write_mdf(path, time, signals, *, version="4.10", groups=None):
    """``signals``: [(name, unit, values)] in one channel group (or in the groups ``groups`` gives per signal)."""
    from asammdf import MDF, Signal

    mdf = MDF(version=version)
    by_group: dict[int, list] = {}
    for k, (name, unit, values) in enumerate(signals):
        t = time if not isinstance(values, tuple) else values[0]
        v = values if not isinstance(values, tuple) else values[1]
        by_group.setdefault(0 if groups is None else groups[k], []).append(
            Signal(np.asarray(v, np.float32), np.asarray(t, float), name=name, unit=unit))
    for sigs in by_group.values():
        mdf.append(sigs)
    mdf.save(path, overwrite=True)
    mdf.close()
    return path


def toy_signals(test: ema.HammerTest):
    return ([("Hammer", "N", test.force[0])]
            + [(f"ch{j}", "g", test.responses[0, j] / G) for j in range(test.responses.shape[1])])


def test_a_logger_recording_is_read_by_name_converted_and_cut_into_hits(tmp_path, caplog):
    rec = continuous()
    table().to_csv(tmp_path / "channels.csv", index=False)
    extra = ("PT100", "degC", (np.arange(80) * 0.1, np.full(80, 21.5)))  # a slow channel in its own group
    path = write_mdf(tmp_path / "rec.mf4", rec.time, toy_signals(rec) + [extra], groups=[0, 0, 0, 0, 1])
    with caplog.at_level(logging.INFO, logger="ema"):
        test = ema.read_hammer(path, tmp_path / "channels.csv")
    # the table's "hammer" is the logger's "Hammer"; g converted to m/s^2; the temperature skipped by name
    msgs = [r.getMessage() for r in caplog.records]
    assert any("'hammer' as 'Hammer'" in m for m in msgs)
    assert any("skipped" in m and "'PT100'" in m for m in msgs)
    assert test.fs == pytest.approx(FS, rel=1e-9)
    assert test.n_hits == 5 and test.n_samples == round(1.25 * FS)
    cut = ema.continuous.split_continuous(rec)
    np.testing.assert_allclose(test.responses, cut.responses, rtol=1e-6, atol=1e-6 * np.abs(cut.responses).max())
    np.testing.assert_allclose(test.force, cut.force, rtol=1e-6, atol=1e-6 * np.abs(cut.force).max())
    screening = ema.screen_hits(test, band_hz=(20.0, 600.0))
    frf = ema.estimate_frf(test, band_hz=(20.0, 600.0), screening=screening)
    modes = ema.identify(frf, band_hz=(20.0, 600.0), max_order=20).modes
    np.testing.assert_allclose(np.sort(modes.freqs_hz), TRUTH.freqs_hz, rtol=1e-3)


def test_an_mdf3_file_reads_as_the_mdf4_one(tmp_path):
    rec = continuous(rebound_after=None)
    table().to_csv(tmp_path / "channels.csv", index=False)
    a = ema.read_hammer(write_mdf(tmp_path / "a.mf4", rec.time, toy_signals(rec)), tmp_path / "channels.csv")
    b = ema.read_hammer(write_mdf(tmp_path / "b.mdf", rec.time, toy_signals(rec), version="3.30"),
                        tmp_path / "channels.csv")
    np.testing.assert_allclose(b.responses, a.responses, rtol=1e-6)
    assert b.n_hits == a.n_hits == 5


def test_bad_logger_files_are_refused_by_file_and_channel(tmp_path):
    rec = continuous(rebound_after=None)
    csv = tmp_path / "channels.csv"
    table().to_csv(csv, index=False)
    sigs = toy_signals(rec)
    # a table name the file does not hold: named, with what the file holds
    renamed = [("Hammer", "N", sigs[0][2]), ("acc0", "g", sigs[1][2])] + sigs[2:]
    with pytest.raises(ema.ChannelMismatchError, match=r"miss\.mf4: 1 channel of the channel table not in the file: "
                                                       r"'ch0'.*'acc0'"):
        ema.read_hammer(write_mdf(tmp_path / "miss.mf4", rec.time, renamed), csv)
    # 0.1 s of samples lost by the logger: the time stamps jump
    keep = np.ones(rec.n_samples, bool)
    keep[int(2.0 * FS):int(2.1 * FS)] = False
    gap = [(n, u, (rec.time[keep], v[keep])) for n, u, v in sigs]
    with pytest.raises(ema.SamplingError, match=r"gap\.mf4: channel 'Hammer': a gap of 0\.100313 s \(320 samples "
                                                r"lost\?\) at t = 1\.999688 s"):
        ema.read_hammer(write_mdf(tmp_path / "gap.mf4", rec.time, gap), csv)
    # one accelerometer at half the rate, in its own group
    half = sigs[:3] + [(sigs[3][0], "g", (rec.time[::2], sigs[3][2][::2]))]
    with pytest.raises(ema.SamplingError, match=r"rate\.mf4: channel 'ch2' \(channel group 1\): 12800 samples "
                                                r"\(1600 Hz\), the force channel 'Hammer' 25600 \(3200 Hz\)"):
        ema.read_hammer(write_mdf(tmp_path / "rate.mf4", rec.time, half, groups=[0, 0, 0, 1]), csv)
    # raw volts without a sensitivity column
    volts = sigs[:1] + [(n, "V", v) for n, _, v in sigs[1:]]
    with pytest.raises(UnitSystemError, match=r"volt\.mf4: channel group 0, channel 'ch0' \(node 101\): unit "
                                                  r"label 'V' is an electrical unit"):
        ema.read_hammer(write_mdf(tmp_path / "volt.mf4", rec.time, volts), csv)
    # a NaN where the logger lost a value
    nan = [(n, u, v.copy()) for n, u, v in sigs]
    nan[2][2][int(3.3 * FS)] = np.nan
    with pytest.raises(ema.NonFiniteDataError, match=r"nan\.mf4: hit 1, channel 'ch1' \(node 102\): sample "
                                                     rf"{int(3.3 * FS)} is nan"):
        ema.read_hammer(write_mdf(tmp_path / "nan.mf4", rec.time, nan), csv)
    # a file cut short in the copy
    whole = write_mdf(tmp_path / "whole.mf4", rec.time, sigs).read_bytes()
    (tmp_path / "cut.mf4").write_bytes(whole[:len(whole) // 3])
    with pytest.raises(ema.HammerDataError, match=r"cut\.mf4.*(truncated|corrupt)"):
        ema.read_hammer(tmp_path / "cut.mf4", csv)


def triggered_signals(test: ema.HammerTest, starts, *, module_of=None, unit="g"):
    """One trigger's records per hit at the absolute start times ``starts``, with the groups each signal goes to.

    ``module_of(j)``: the measuring module of response ``j`` (0 is the force's); each module and trigger is a group.
    """
    sigs, groups = [], []
    modules = sorted({0} | {module_of(j) if module_of else 0 for j in range(test.n_channels)})
    names = ["Hammer"] + [f"ch{j}" for j in range(test.n_channels)]
    for i, t0 in enumerate(starts):
        t = t0 + np.arange(test.n_samples) / test.fs
        scale = G if unit == "g" else 1.0
        sigs.append((names[0], "N", (t, test.force[i])))
        groups.append(i * len(modules))
        for j in range(test.n_channels):
            sigs.append((names[j + 1], unit, (t, test.responses[i, j] / scale)))
            groups.append(i * len(modules) + modules.index(module_of(j) if module_of else 0))
    return sigs, groups


def test_a_triggered_logger_file_is_one_hit_per_record_in_time_order(tmp_path, caplog):
    """The cut toy recording written back as a logger's triggered records: the same hits, whatever the layout."""
    hits = ema.continuous.split_continuous(continuous())
    csv = tmp_path / "channels.csv"
    table().to_csv(csv, index=False)
    starts = 3.0 + 2.5 * np.arange(hits.n_hits)
    # one group per trigger, written out of time order: the hits are numbered by their time stamps
    sigs, groups = triggered_signals(hits, starts)
    order = [2, 0, 4, 1, 3]
    per_hit = len(sigs) // hits.n_hits
    pick = [k for i in order for k in range(i * per_hit, (i + 1) * per_hit)]
    with caplog.at_level(logging.INFO, logger="ema"):
        test = ema.read_hammer(write_mdf(tmp_path / "trig.mf4", None, [sigs[k] for k in pick],
                                         groups=[groups[k] for k in pick]), csv)
    assert test.hits == (1, 2, 3, 4, 5) and test.n_samples == hits.n_samples
    assert test.time[0] == pytest.approx(starts[0], abs=0.5 / FS)
    np.testing.assert_allclose(test.responses, hits.responses, rtol=1e-6, atol=1e-6 * np.abs(hits.responses).max())
    np.testing.assert_allclose(test.force, hits.force, rtol=1e-6, atol=1e-6 * np.abs(hits.force).max())
    assert any("5 triggered records" in h for h in test.history)
    # one group per measuring module and trigger (force + ch0 on one module, ch1 and ch2 on another)
    sigs, groups = triggered_signals(hits, starts, module_of=lambda j: 0 if j == 0 else 1)
    mod = ema.read_hammer(write_mdf(tmp_path / "mod.mf4", None, sigs, groups=groups), csv)
    np.testing.assert_array_equal(mod.responses, test.responses)
    # a logger that restarts its time stamps at every trigger: the responses are the force's group's
    sigs, groups = triggered_signals(hits, np.zeros(hits.n_hits))
    again = ema.read_hammer(write_mdf(tmp_path / "zero.mf4", None, sigs, groups=groups), csv)
    np.testing.assert_array_equal(again.responses, test.responses)


def test_bad_triggered_logger_files_are_refused_by_hit_and_channel(tmp_path):
    hits = ema.continuous.split_continuous(continuous(rebound_after=None))
    csv = tmp_path / "channels.csv"
    table().to_csv(csv, index=False)
    starts = 3.0 + 2.5 * np.arange(hits.n_hits)
    sigs, groups = triggered_signals(hits, starts, module_of=lambda j: j)

    def write(name, keep=lambda k, sig: True, change=lambda k, sig: sig, zero=False):
        s, g = triggered_signals(hits, np.zeros(hits.n_hits) if zero else starts, module_of=lambda j: j)
        kept = [(change(k, sig), grp) for k, (sig, grp) in enumerate(zip(s, g)) if keep(k, sig)]
        return write_mdf(tmp_path / name, None, [a for a, _ in kept], groups=[b for _, b in kept])

    per_hit = len(sigs) // hits.n_hits
    # groups: force + ch0, ch1, ch2 per trigger (3 per hit; a group left empty is not written)
    # the third trigger's ch1 lost: the hit and the channel named
    with pytest.raises(ema.ChannelMismatchError, match=r"lost\.mf4: hit 3 \(the force record of channel group 6, "
                                                       r"8\.000000–9\.249688 s\): channel 'ch1' has no record"):
        ema.read_hammer(write("lost.mf4", keep=lambda k, sig: not (k == 2 * per_hit + 2)), csv)
    # a response record whose force record is missing: not silently left out
    with pytest.raises(ema.ChannelMismatchError, match=r"orphan\.mf4: channel 'ch0' \(channel group 12, "
                                                       r"13\.000000–14\.249688 s\): a record on no force record"):
        ema.read_hammer(write("orphan.mf4", keep=lambda k, sig: k != 4 * per_hit), csv)
    # the fourth trigger stopped early
    short = round(0.9 * hits.n_samples)
    with pytest.raises(ema.SamplingError, match=rf"short\.mf4: hit 4 \(channel group 9, .*\): {short} samples at "
                                                rf"3200 Hz, hit 1 \(channel group 0\) {hits.n_samples} at 3200 Hz"):
        ema.read_hammer(write("short.mf4", change=lambda k, sig: sig if k // per_hit != 3 else
                              (sig[0], sig[1], (sig[2][0][:short], sig[2][1][:short]))), csv)
    # one channel in g in one hit and in m/s^2 in the others
    with pytest.raises(UnitSystemError, match=r"unit\.mf4: channel 'ch2' is recorded in 'g' and 'm/s\^2' in "
                                              r"different hits"):
        ema.read_hammer(write("unit.mf4", change=lambda k, sig: sig if k != per_hit + 3 else
                              (sig[0], "m/s^2", (sig[2][0], sig[2][1] * G))), csv)
    # time stamps restarted at each trigger and ch1 in its own module's group: no way to tell its hits apart
    with pytest.raises(ema.ChannelMismatchError, match=r"zero\.mf4: channel groups 1 and 4 both hold a channel "
                                                       r"'ch1' on the force's time stamps"):
        ema.read_hammer(write("zero.mf4", zero=True), csv)


def test_the_lab_campaign_recorded_by_a_logger_identifies_as_the_triggered_file(tmp_path_factory, capsys):
    """The small campaign's 4 hits (1 s records) end to end as MDF 4 channels in g: the same modes.

    Written as a triggered logger's records (one group per hit, in m/s^2), the same hits sample for sample.
    """
    folder = small_campaign(campaign_dir("control"), tmp_path_factory.mktemp("mdf"))
    test = ema.read_hammer(folder / "flexural.uff", folder / "flexural_channels.csv")
    chans = pd.read_csv(folder / "flexural_channels.csv")
    acc = chans[chans["quantity"] == "acceleration"].reset_index(drop=True)
    fname = str(chans.loc[chans["quantity"] == "force", "name"].iloc[0])
    trig, groups = [], []
    for i in range(test.n_hits):
        t = 10.0 * i + test.time
        trig.append((fname, "N", (t, test.force[i])))
        trig += [(str(r["name"]), "m/s^2", (t, test.responses[i, j])) for j, r in acc.iterrows()]
        groups += [i] * (1 + len(acc))
    logged = ema.read_hammer(write_mdf(folder / "triggered.mf4", None, trig, groups=groups),
                             folder / "flexural_channels.csv")
    assert logged.hits == tuple(range(1, test.n_hits + 1))  # a logger counts its triggers, UFF kept its numbers
    np.testing.assert_array_equal(logged.responses, test.responses)
    np.testing.assert_array_equal(logged.force, test.force)
    time = np.arange(test.force.size) / test.fs
    sigs = [(fname, "N", test.force.reshape(-1))]
    sigs += [(str(r["name"]), "g", test.responses[:, j].reshape(-1) / G) for j, r in acc.iterrows()]
    write_mdf(folder / "logger.mf4", time, sigs)
    outs = []
    for name in ("flexural.uff", "logger.mf4"):
        out = folder / f"modes_{name[:4]}"
        code, _, err = identify_small(folder, out, capsys, hammer=name)
        assert code == 0, err
        outs.append(modes_csv(out))
    assert same_modes(outs[1], outs[0]), outs
