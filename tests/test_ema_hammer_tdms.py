"""A hammer test recorded into an NI TDMS file, continuously or one group per trigger (ema.hammer_tdms).

The files are written with npTDMS's own writer as LabVIEW and FlexLogger lay them out (waveform properties
``wf_increment``, ``wf_start_offset``, ``wf_start_time``, ``unit_string``; or a group's time channel). Oracles: the
toy recording of ``test_ema_continuous`` (its modes known), the same hits as the MDF reader's tests, and the
virtual lab's small campaign, whose hits must come out sample for sample as its UFF file's.
"""

from __future__ import annotations

import logging

import numpy as np
import pandas as pd
import pytest

import ema
from bad_inputs_support import small_campaign
from lab_data.cache import campaign_dir
from test_ema_continuous import FS, TRUTH, continuous, table

pytest.importorskip("nptdms")
G = 9.80665
T0 = np.datetime64("2026-11-30T09:15:00.000000", "us")


def write_tdms(path, groups):
    """``groups``: [(group, [(name, unit, values, start_s or None, clock)])]; ``start_s`` a trigger time after
    T0 (None: no ``wf_start_time``); ``clock`` True writes a ``Time`` channel instead of waveform properties."""
    from nptdms import ChannelObject, TdmsWriter

    with TdmsWriter(str(path)) as writer:
        for group, signals in groups:
            objects = []
            for name, unit, values, start, clock in signals:
                props = {"unit_string": unit}
                if clock:
                    objects.append(ChannelObject(group, "Time", (start or 0.0) + np.arange(len(values)) / FS,
                                                 properties={"unit_string": "s"}))
                else:
                    props.update(wf_increment=1.0 / FS, wf_start_offset=0.0)
                    if start is not None:
                        props["wf_start_time"] = T0 + np.timedelta64(round(start * 1e6), "us")
                objects.append(ChannelObject(group, name, np.asarray(values, float), properties=props))
            writer.write_segment(objects)
    return path


def toy(test, start=0.0, clock=False, unit="g"):
    scale = G if unit == "g" else 1.0
    return ([("Hammer", "N", test.force[0], start, clock)]
            + [(f"ch{j}", unit, test.responses[0, j] / scale, start, False) for j in range(test.n_channels)])


def test_a_continuous_tdms_recording_is_read_by_name_converted_and_cut_into_hits(tmp_path, caplog):
    rec = continuous()
    csv = tmp_path / "channels.csv"
    table().to_csv(csv, index=False)
    path = write_tdms(tmp_path / "rec.tdms", [("Measured", toy(rec, start=0.0))])
    assert ema.hammer_io.HAMMER_FORMATS["tdms"][0](path)
    with caplog.at_level(logging.INFO, logger="ema"):
        test = ema.read_hammer(path, csv)
    assert any("'hammer' as 'Hammer'" in r.getMessage() for r in caplog.records)
    assert test.fs == pytest.approx(FS, rel=1e-12) and test.n_hits == 5
    cut = ema.continuous.split_continuous(rec)
    np.testing.assert_allclose(test.responses, cut.responses, rtol=1e-12, atol=1e-12 * np.abs(cut.responses).max())
    screening = ema.screen_hits(test, band_hz=(20.0, 600.0))
    frf = ema.estimate_frf(test, band_hz=(20.0, 600.0), screening=screening)
    modes = ema.identify(frf, band_hz=(20.0, 600.0), max_order=20).modes
    np.testing.assert_allclose(np.sort(modes.freqs_hz), TRUTH.freqs_hz, rtol=1e-3)
    # the same recording with a Time channel in place of the waveform properties
    clocked = ema.read_hammer(write_tdms(tmp_path / "clock.tdms", [("Measured", toy(rec, clock=True))]), csv)
    np.testing.assert_allclose(clocked.responses, test.responses, rtol=1e-9)


def test_a_triggered_tdms_file_is_one_hit_per_group_in_time_order(tmp_path):
    """One group per trigger, written out of time order: the hits are numbered by ``wf_start_time`` (the time
    counted from the earliest trigger); without it (every trigger's offset 0) by group order."""
    hits = ema.continuous.split_continuous(continuous())
    csv = tmp_path / "channels.csv"
    table().to_csv(csv, index=False)

    def one(i):
        return ([("Hammer", "N", hits.force[i])] + [(f"ch{j}", "g", hits.responses[i, j] / G)
                                                   for j in range(hits.n_channels)])

    starts = 3.0 + 2.5 * np.arange(hits.n_hits)
    order = [2, 0, 4, 1, 3]
    groups = [(f"Trigger {i}", [(n, u, v, starts[i], False) for n, u, v in one(i)]) for i in order]
    test = ema.read_hammer(write_tdms(tmp_path / "trig.tdms", groups), csv)
    assert test.hits == (1, 2, 3, 4, 5)
    assert test.time[0] == pytest.approx(0.0, abs=1e-9)
    np.testing.assert_allclose(test.responses, hits.responses, rtol=1e-12, atol=1e-12 * np.abs(hits.responses).max())
    assert any("5 triggered records" in h for h in test.history)
    restarted = [(f"Trigger {i}", [(n, u, v, None, False) for n, u, v in one(i)]) for i in range(hits.n_hits)]
    again = ema.read_hammer(write_tdms(tmp_path / "zero.tdms", restarted), csv)
    np.testing.assert_array_equal(again.responses, test.responses)


def test_bad_tdms_files_are_refused_by_file_channel_and_hit(tmp_path, capfd):
    rec = continuous(rebound_after=None)
    csv = tmp_path / "channels.csv"
    table().to_csv(csv, index=False)
    whole = write_tdms(tmp_path / "whole.tdms", [("Measured", toy(rec))]).read_bytes()
    # cut short in the copy: npTDMS would read the part and only log a warning
    (tmp_path / "cut.tdms").write_bytes(whole[:len(whole) - 1000])
    with pytest.raises(ema.TDMSReadError, match=r"cut\.tdms: the TDMS file is cut short"):
        ema.read_hammer(tmp_path / "cut.tdms", csv)
    assert "will attempt" not in capfd.readouterr().err  # npTDMS's own lines stay off the terminal
    (tmp_path / "head.tdms").write_bytes(whole[:20])
    with pytest.raises(ema.TDMSReadError, match=r"head\.tdms: the TDMS file is cut short: segment 1 at byte 0 has "
                                                r"20 of the 28 bytes of its lead-in"):
        ema.read_hammer(tmp_path / "head.tdms", csv)
    # an accelerometer written without a time base
    from nptdms import ChannelObject, TdmsWriter

    with TdmsWriter(str(tmp_path / "notime.tdms")) as writer:
        objects = [ChannelObject("Measured", n, np.asarray(v, float),
                                 properties={"unit_string": u, "wf_increment": 1 / FS} if n != "ch1" else
                                 {"unit_string": u}) for n, u, v, _, _ in toy(rec)]
        writer.write_segment(objects)
    with pytest.raises(ema.ChannelMismatchError, match=r"notime\.tdms: channel 'ch1' of the channel table cannot "
                                                       r"be read: no time base in group 'Measured'"):
        ema.read_hammer(tmp_path / "notime.tdms", csv)
    # a table channel the file lacks
    renamed = [s if s[0] != "ch0" else ("acc0",) + s[1:] for s in toy(rec)]
    with pytest.raises(ema.ChannelMismatchError, match=r"miss\.tdms: 1 channel of the channel table not in the "
                                                       r"file: 'ch0'.*'acc0'"):
        ema.read_hammer(write_tdms(tmp_path / "miss.tdms", [("Measured", renamed)]), csv)
    # the fourth trigger stopped early
    hits = ema.continuous.split_continuous(rec)
    short = round(0.9 * hits.n_samples)
    groups = []
    for i in range(hits.n_hits):
        n = short if i == 3 else hits.n_samples
        sigs = [("Hammer", "N", hits.force[i, :n])] + [(f"ch{j}", "g", hits.responses[i, j, :n] / G)
                                                       for j in range(hits.n_channels)]
        groups.append((f"Trigger {i}", [(a, b, c, 3.0 + 2.5 * i, False) for a, b, c in sigs]))
    with pytest.raises(ema.SamplingError, match=rf"short\.tdms: hit 4 \(group 3, .*\): {short} samples at 3200 Hz, "
                                                rf"hit 1 \(group 0\) {hits.n_samples} at 3200 Hz"):
        ema.read_hammer(write_tdms(tmp_path / "short.tdms", groups), csv)


def test_the_lab_campaign_logged_as_tdms_gives_the_uff_file_s_hits(tmp_path_factory):
    """The small campaign's hits as a LabVIEW triggered acquisition (one group per hit, 10 s apart, m/s^2): the
    UFF file's force and responses sample for sample."""
    folder = small_campaign(campaign_dir("control"), tmp_path_factory.mktemp("tdms"))
    test = ema.read_hammer(folder / "flexural.uff", folder / "flexural_channels.csv")
    chans = pd.read_csv(folder / "flexural_channels.csv")
    acc = chans[chans["quantity"] == "acceleration"].reset_index(drop=True)
    fname = str(chans.loc[chans["quantity"] == "force", "name"].iloc[0])
    from nptdms import ChannelObject, TdmsWriter

    path = folder / "triggered.tdms"
    with TdmsWriter(str(path)) as writer:
        for i in range(test.n_hits):
            props = dict(wf_increment=1.0 / test.fs, wf_start_offset=float(test.time[0]),
                         wf_start_time=T0 + np.timedelta64(10 * i, "s"))
            objects = [ChannelObject(f"Acquisition {i + 1}", fname, test.force[i], properties=dict(props,
                                                                                                unit_string="N"))]
            objects += [ChannelObject(f"Acquisition {i + 1}", str(r["name"]), test.responses[i, j],
                                      properties=dict(props, unit_string="m/s^2")) for j, r in acc.iterrows()]
            writer.write_segment(objects)
    logged = ema.read_hammer(path, folder / "flexural_channels.csv")
    assert logged.hits == tuple(range(1, test.n_hits + 1))
    np.testing.assert_array_equal(logged.responses, test.responses)
    np.testing.assert_array_equal(logged.force, test.force)
    assert logged.fs == pytest.approx(test.fs, rel=1e-12)
