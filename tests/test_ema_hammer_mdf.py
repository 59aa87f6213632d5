"""A hammer test recorded continuously by a data logger into an MDF file (ema.hammer_mdf, ema.continuous).

Oracles: the virtual lab's small campaign, its triggered hits end to end in MDF 4 channels named as a logger
names them (accelerations in g), which must identify as the triggered UFF file does (modes within 0.05 %); and a
toy recording whose every defect (a lost block of samples, a channel at another rate, a damaged file, a table
name the file lacks, raw volts without a sensitivity) is known and must be named.
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


def test_the_lab_campaign_recorded_by_a_logger_identifies_as_the_triggered_file(tmp_path_factory, capsys):
    """The small campaign's 4 hits (1 s records) end to end as MDF 4 channels in g: the same modes."""
    folder = small_campaign(campaign_dir("control"), tmp_path_factory.mktemp("mdf"))
    test = ema.read_hammer(folder / "flexural.uff", folder / "flexural_channels.csv")
    chans = pd.read_csv(folder / "flexural_channels.csv")
    acc = chans[chans["quantity"] == "acceleration"].reset_index(drop=True)
    fname = str(chans.loc[chans["quantity"] == "force", "name"].iloc[0])
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
