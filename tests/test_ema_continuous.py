"""A continuous (throughput) hammer recording cut into hits (ema.continuous).

Oracles: a toy modal truth recorded continuously with known impact times (irregular spacing, one rebound), whose
identified modes must be the truth's; and the virtual lab's small campaign written as one record per channel, its
hits end to end, which must identify as the triggered file does (the same screening verdicts, modes within 0.05 %).
"""

from __future__ import annotations

import logging

import numpy as np
import pandas as pd
import pytest

import ema
from bad_inputs_support import SMALL_BAND, SMALL_ORDER, modes_csv, run, same_modes, small_campaign
from ema.continuous import MIN_HIT_SEPARATION_S, PRE_TRIGGER_SHARE, find_impacts, split_continuous
from lab_data.cache import campaign_dir
from lab_data.hammer import ModalTruth, Pulse, add_noise, quantise, synthesize_hit

FS = 3200.0
TRUTH = ModalTruth([72.6, 150.0, 262.0, 410.0], [0.010, 0.008, 0.010, 0.010], [0.03, 0.025, -0.012, 0.02],
                   np.array([[0.03, -0.01, 0.02, 0.015], [0.01, 0.02, 0.03, -0.01], [-0.02, 0.01, 0.01, 0.02]]))
IMPACTS = (0.30, 1.80, 3.05, 4.75, 6.30)  # s: spacings 1.5, 1.25, 1.7, 1.55


def table() -> pd.DataFrame:
    rows = [dict(node=900, name="hammer", quantity="force", unit="N", x=0, y=0, z=0, dx=0, dy=0, dz=-1)]
    rows += [dict(node=101 + j, name=f"ch{j}", quantity="acceleration", unit="m/s^2", x=j, y=0, z=0, dx=0, dy=0,
                  dz=1) for j in range(3)]
    return pd.DataFrame(rows)


def continuous(duration=8.0, rebound_after=2, seed=4, impacts=IMPACTS):
    """One record: an impact at each of ``impacts`` (700-1300 N), a rebound 6 ms after impact ``rebound_after``."""
    rng = np.random.default_rng(seed)
    pulses = [Pulse(t, 6e-4, rng.uniform(700, 1300)) for t in impacts]
    if rebound_after is not None:
        pulses.append(Pulse(impacts[rebound_after] + 6e-3, 6e-4, 400.0))
    _, f, a = synthesize_hit(TRUTH, pulses, fs=FS, duration=duration)
    f = quantise(add_noise(f, 0.05, rng), 10000.0)[0]
    a = quantise(add_noise(a, 5e-4, rng), 50.0)[0]
    return ema.HammerTest.from_arrays(f[None], a[None], FS, table(), source="toy continuous")


def test_impacts_are_found_where_they_were_made_and_a_rebound_is_not_one():
    test = continuous()
    peaks = find_impacts(test.force[0], FS)
    # each impact's largest sample: the middle of its 0.6 ms half-sine, to a sample
    np.testing.assert_allclose(peaks / FS, np.array(IMPACTS) + 3e-4, atol=1.5 / FS)


def test_a_continuous_recording_is_cut_into_hits_that_identify_the_truth(caplog):
    with caplog.at_level(logging.WARNING, logger="ema"):
        cut = split_continuous(continuous())
    assert cut.hits == (1, 2, 3, 4, 5)
    length = 1.25  # the shortest spacing
    assert cut.n_samples == round(length * FS)
    pre = round(PRE_TRIGGER_SHARE * length * FS)
    np.testing.assert_allclose(cut.time[0] + pre / FS, IMPACTS[0] + 3e-4, atol=1.5 / FS)
    (msg,) = [r.getMessage() for r in caplog.records if "continuous recording" in r.getMessage()]
    assert "holding 5 impacts cut into 5 hits of 1.250 s" in msg and "t = 0.30, 1.80, 3.05, 4.75, 6.30 s" in msg
    assert "split_continuous" in cut.history[-1]
    screening = ema.screen_hits(cut, band_hz=(20.0, 600.0))
    assert [(r.hit, r.reason) for r in screening.rejections] == [(3, "double hit")]
    frf = ema.estimate_frf(cut, band_hz=(20.0, 600.0), screening=screening)
    modes = ema.identify(frf, band_hz=(20.0, 600.0), max_order=20).modes
    np.testing.assert_allclose(np.sort(modes.freqs_hz), TRUTH.freqs_hz, rtol=1e-3)
    # the exponential window's correction returns the damping, though the previous hit's tail starts each record
    np.testing.assert_allclose(modes.zeta[np.argsort(modes.freqs_hz)], TRUTH.zeta, rtol=0.1)


def test_a_corrupt_sample_between_hits_does_not_shorten_the_records(caplog):
    test = continuous(rebound_after=None)
    force = test.force.copy()
    k = int(2.2 * FS)
    force[0, k] = 50 * force.max()  # a flipped exponent byte between impacts 2 and 3
    bad = ema.HammerTest.from_arrays(force, test.responses, FS, table(), source="toy continuous")
    assert find_impacts(bad.force[0], FS).size == 5
    with caplog.at_level(logging.WARNING, logger="ema"):
        cut = split_continuous(bad)
    assert cut.n_hits == 5 and cut.n_samples == round(1.25 * FS)
    assert any(f"a single force sample of {force[0, k]:.4g} N at t = 2.2000 s" in r.getMessage()
               for r in caplog.records)
    # it stays in hit 2's record, where the screening judges it
    assert np.max(cut.force[1]) == force[0, k]


def test_a_last_impact_without_most_of_a_record_is_left_out_by_name(caplog):
    with caplog.at_level(logging.WARNING, logger="ema"):
        cut = split_continuous(continuous(duration=7.0, rebound_after=None))
    assert cut.n_hits == 4 and cut.n_samples == round(1.25 * FS)
    (msg,) = [r.getMessage() for r in caplog.records if "left out" in r.getMessage()]
    assert "the impact at t = 6.300 s is followed by 0.700 s of record, less than the 1.188 s" in msg
    # 1.0 s after it is 84 % of a record: every record is shortened to keep that hit
    cut = split_continuous(continuous(duration=7.3 + 3e-4, rebound_after=None))
    assert cut.n_hits == 5 and cut.n_samples == int(1.0 * FS / (1 - PRE_TRIGGER_SHARE))


def test_a_triggered_record_with_a_rebound_or_two_hits_is_not_cut():
    """Two pulses in one record are a double hit for the screening, not two hits; several records are never cut."""
    _, f, a = synthesize_hit(TRUTH, [Pulse(0.1, 6e-4, 1000.0), Pulse(0.1 + 2 * MIN_HIT_SEPARATION_S, 6e-4, 900.0)],
                             fs=FS, duration=1.0)
    one = ema.HammerTest.from_arrays(f[None], a[None], FS, table())
    assert split_continuous(one) is one
    many = continuous()
    many = ema.HammerTest.from_arrays(np.repeat(many.force, 2, axis=0), np.repeat(many.responses, 2, axis=0), FS,
                                      table())
    assert split_continuous(many) is many


def write_uff(test: ema.HammerTest, path) -> None:
    """Each hit's records as UFF 58 datasets, as a front end exports them."""
    from lab_data.uff_export import TimeHistory, write_time_histories

    hist = []
    for h, hit in enumerate(test.hits):
        hist.append(TimeHistory(hit, 900, 0, "force", "N", "hammer", test.dt, test.force[h].astype(np.float32), 900,
                                0))
        hist += [TimeHistory(hit, 101 + j, 0, "acceleration", "m/s^2", f"ch{j}", test.dt,
                             test.responses[h, j].astype(np.float32), 900, 0) for j in range(3)]
    write_time_histories(path, hist)


def test_several_continuous_files_are_cut_at_one_record_length(tmp_path, caplog):
    """Two continuous files whose impacts are 1.25 s and 0.9 s apart at the closest: all hits at 0.9 s."""
    table().to_csv(tmp_path / "channels.csv", index=False)
    write_uff(continuous(), tmp_path / "a.uff")
    write_uff(continuous(duration=4.5, rebound_after=None, seed=5, impacts=(0.2, 1.4, 2.3, 3.5)), tmp_path / "b.uff")
    with caplog.at_level(logging.WARNING, logger="ema"):
        test = ema.read_hammer([tmp_path / "a.uff", tmp_path / "b.uff"], tmp_path / "channels.csv")
    assert test.n_hits == 9 and test.n_samples == round(0.9 * FS)
    cuts = [r.getMessage() for r in caplog.records if "continuous recording" in r.getMessage()]
    assert len(cuts) == 2 and all("hits of 0.900 s" in m for m in cuts)
    screening = ema.screen_hits(test, band_hz=(20.0, 600.0))
    assert [(r.hit, r.reason) for r in screening.rejections] == [(3, "double hit")]
    frf = ema.estimate_frf(test, band_hz=(20.0, 600.0), screening=screening)
    modes = ema.identify(frf, band_hz=(20.0, 600.0), max_order=20).modes
    np.testing.assert_allclose(np.sort(modes.freqs_hz), TRUTH.freqs_hz, rtol=1e-3)


def test_a_continuous_file_beside_triggered_ones_is_cut_at_their_record_length(tmp_path):
    table().to_csv(tmp_path / "channels.csv", index=False)
    write_uff(continuous(rebound_after=None), tmp_path / "cont.uff")
    for name, seconds in (("short", 1.0), ("long", 1.5)):
        _, f, a = synthesize_hit(TRUTH, [Pulse(0.05, 6e-4, 1000.0)], fs=FS, duration=seconds)
        write_uff(ema.HammerTest.from_arrays(f[None], a[None], FS, table()), tmp_path / f"{name}.uff")
    test = ema.read_hammer([tmp_path / "short.uff", tmp_path / "cont.uff"], tmp_path / "channels.csv")
    assert test.n_hits == 6 and test.n_samples == round(1.0 * FS)
    # impacts 1.25 s apart cannot give 1.5 s records: refused by name, not cut with two impacts in a record
    with pytest.raises(ema.SamplingError, match=r"cont\.uff.*1\.250 s apart.*long\.uff has triggered records"):
        ema.read_hammer([tmp_path / "long.uff", tmp_path / "cont.uff"], tmp_path / "channels.csv")


def test_the_lab_campaign_recorded_continuously_identifies_as_the_triggered_file(tmp_path_factory, capsys):
    """The small campaign's 4 hits (1 s records) end to end in one record per channel: the same modes."""
    from lab_data.uff_export import TimeHistory, write_time_histories

    folder = small_campaign(campaign_dir("control"), tmp_path_factory.mktemp("trig"))
    test = ema.read_hammer(folder / "flexural.uff", folder / "flexural_channels.csv")
    assert test.n_hits == 4
    table = pd.read_csv(folder / "flexural_channels.csv")
    acc = table[table["quantity"] == "acceleration"].reset_index(drop=True)
    fr = table[table["quantity"] == "force"].iloc[0]
    hist = [TimeHistory(1, int(fr["node"]), 0, "force", "N", str(fr["name"]), test.dt,
                        test.force.reshape(-1).astype(np.float32), int(fr["node"]), 0)]
    hist += [TimeHistory(1, int(r["node"]), 0, "acceleration", "m/s^2", str(r["name"]), test.dt,
                         test.responses[:, j].reshape(-1).astype(np.float32), int(fr["node"]), 0)
             for j, r in acc.iterrows()]
    write_time_histories(folder / "continuous.uff", hist)
    cut = ema.read_hammer(folder / "continuous.uff", folder / "flexural_channels.csv")
    # the recording stops 0.9 s after the last impact: every record is shortened to its 5 % pre-trigger + 0.9 s,
    # not that hit left out
    assert cut.n_hits == 4 and cut.n_samples == pytest.approx(0.9 / 0.95 * test.fs, abs=0.01 * test.fs)
    outs = []
    for name in ("flexural.uff", "continuous.uff"):
        out = folder / f"modes_{name[:4]}"
        code, _, err = run(["-q", "lab", "identify", "--hammer", str(folder / name), "--channels",
                            str(folder / "flexural_channels.csv"), "--band", *SMALL_BAND, "--max-order", SMALL_ORDER,
                            "--out", str(out)], capsys)
        assert code == 0, err
        outs.append(modes_csv(out))
    assert same_modes(outs[1], outs[0]), outs
