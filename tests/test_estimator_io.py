"""Reading field runs: sensor tables, the MDF 4 / Parquet / CSV registry, headers, units, sensitivities, bad files."""

from __future__ import annotations

import logging
import re

import numpy as np
import pandas as pd
import pytest

from estimator import (ChannelError, OdometryError, RunFileError, SensorTableError, UnknownFormatError, check_run,
                       read_run, read_sensors)
from estimator.io import formats, read_line, read_trolley
from estimator.io.registry import RawChannel
from estimator.io.tabular import write_run_table
from test_estimator_synthetic import G, sensor_table, write_mdf4


def _channels(fs=1000.0, n=3000, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fs
    ch = {name: (t.copy(), rng.standard_normal(n) * 0.1, "g") for name in sensor_table()["name"][:6]}
    to = np.arange(0, n / fs, 0.01)
    ch["SPEED"] = (to, np.full(to.size, 10.0), "m/s")
    ch["POSITION"] = (to, 100 + 10 * to, "m")
    ch["BALISE"] = (np.array([1.0]), np.array([110.0]), "m")
    return ch


HEADER = {"run_id": "r7", "date": "2026-02-03", "direction": "forward", "train": "T12", "bogie": "B2",
          "line": "M1", "weather": "dry"}


def write_tdms(path, channels: dict, header: dict) -> None:
    """A TDMS file as an NI train DAQ writes the field contract: one group per time base, evenly sampled ones as
    waveforms (``wf_increment``, ``wf_start_offset``, one ``wf_start_time``), the events beside a ``Time`` channel;
    the header as root properties."""
    from nptdms import ChannelObject, RootObject, TdmsWriter

    start = np.datetime64("2026-02-03T07:30:00", "us")
    groups: dict = {}
    for name, (t, v, unit) in channels.items():
        key = (t.size, float(t[0]) if t.size else 0.0, float(t[1] - t[0]) if t.size > 1 else 0.0)
        groups.setdefault(key, []).append((name, t, v, unit))
    objects = [RootObject(properties=dict(header))]
    for k, members in enumerate(groups.values()):
        t = members[0][1]
        dt = np.diff(t)
        wave = t.size > 1 and np.allclose(dt, dt[0], rtol=1e-12, atol=0)
        if not wave:
            objects.append(ChannelObject(f"group {k}", "Time", np.asarray(t, float), properties={"unit_string": "s"}))
        for name, _, v, unit in members:
            props = {"unit_string": unit}
            if wave:
                props.update(wf_increment=float(dt[0]), wf_start_offset=float(t[0]), wf_start_time=start)
            objects.append(ChannelObject(f"group {k}", name, np.asarray(v, float), properties=props))
    with TdmsWriter(str(path)) as writer:
        writer.write_segment(objects)


def _write(folder, stem, ch, fmt):
    """The channels as a run file of format ``fmt`` in ``folder``."""
    p = folder / f"{stem}.{dict(mdf4='mf4', parquet='parquet', csv='csv', tdms='tdms')[fmt.split('-')[0]]}"
    if fmt == "mdf4":
        write_mdf4(p, ch, HEADER)
    elif fmt == "tdms":
        write_tdms(p, ch, HEADER)
    elif fmt == "csv-wide":
        from estimator.io.wide import write_wide_csv

        write_wide_csv({k: RawChannel(k, *v) for k, v in ch.items()}, HEADER, p)
    else:
        write_run_table({k: RawChannel(k, *v) for k, v in ch.items()}, HEADER, p, fmt)
    return p


@pytest.fixture()
def table(tmp_path):
    p = tmp_path / "sensors.csv"
    sensor_table().to_csv(p, index=False)
    return p


def test_sensor_table_reads_and_types_its_columns(table):
    s = read_sensors(table)
    acc = s[s["quantity"] == "acceleration"]
    assert len(acc) == 6 and set(acc["wheelset"]) == {1, 2} and set(acc["side"]) == {"L", "R"}
    assert acc["sensitivity"].iloc[0] == pytest.approx(G)


@pytest.mark.parametrize("edit, message", [
    (lambda d: d.drop(columns="sensitivity"), "missing column"),
    (lambda d: d.assign(side=d["side"].where(d["name"] != "ACC_W1L_Z", "X")), "side must be one of"),
    (lambda d: d.assign(sensitivity=d["sensitivity"].where(d["name"] != "ACC_W1L_Z", 1.0)), "does not convert g"),
    (lambda d: d.assign(y=d["y"].where(d["name"] != "ACC_W1L_Z", 0.97)), "left side is at -y"),
    (lambda d: d.assign(wheelset=d["wheelset"].where(d["name"] != "ACC_W1L_Z", 3)), "wheelset must be 1 or 2"),
    (lambda d: d[~d["quantity"].isin(["speed", "position"])], "no speed and no position channel"),
    (lambda d: pd.concat([d, d[d["quantity"] == "speed"].assign(name="SPEED2")]), "at most one speed"),
    (lambda d: pd.concat([d, d.iloc[[0]]]), "unique"),
    (lambda d: d.assign(unit=d["unit"].where(d["name"] != "SPEED", "furlong")), "unit of a speed channel"),
])
def test_sensor_table_errors_name_row_column_and_value(tmp_path, edit, message):
    p = tmp_path / "bad.csv"
    edit(sensor_table()).to_csv(p, index=False)
    with pytest.raises(SensorTableError, match=message):
        read_sensors(p)


@pytest.mark.parametrize("fmt", ["mdf4", "tdms", "parquet", "csv", "csv-wide"])
def test_the_formats_give_the_same_run(tmp_path, table, fmt):
    ch = _channels()
    run = read_run(_write(tmp_path, "run", ch, fmt), table)
    assert run.format == fmt
    assert run.header.run_id == "r7" and run.header.direction == "forward" and run.header.train == "T12"
    assert run.header.extra == {"weather": "dry"}
    assert run.fs == pytest.approx(1000.0) and run.n_samples == 3000
    # sensitivities applied once: recorded g -> m/s^2, and said so in the history
    np.testing.assert_allclose(run.acceleration[0], ch["ACC_W1L_Z"][1] * G, rtol=1e-9)
    assert run.units == ("m/s^2",) * 6 and "sensitivities applied" in run.processing[-1]
    with pytest.raises(ChannelError, match="already applied"):
        run.apply_sensitivities()
    assert run.odometry.balise_chainage.tolist() == [110.0]
    assert run.odometry.speed[0] == pytest.approx(10.0)


@pytest.mark.parametrize("kind", ["datetime", "timedelta"])
def test_a_parquet_time_column_of_clock_times_or_durations_is_read_in_seconds(tmp_path, table, kind):
    """pandas writes a DAQ's time stamps as datetime64 (or timedelta64): read as numbers they would be
    nanoseconds and the 1 kHz channels refused as sampled at 1e-6 Hz. Clock times count from the first stamp."""
    ch = _channels()
    p = _write(tmp_path, "plain", ch, "parquet")
    df = pd.read_parquet(p)
    dt = pd.to_timedelta(df["t_s"], unit="s")
    df["t_s"] = pd.Timestamp("2026-02-03 08:00:00") + dt if kind == "datetime" else dt
    q = tmp_path / f"{kind}.parquet"
    df.to_parquet(q)
    import pyarrow.parquet as pq

    meta = pq.read_schema(p).metadata
    pq.write_table(pq.read_table(q).replace_schema_metadata({**pq.read_schema(q).metadata, b"run_header":
                                                             meta[b"run_header"]}), q)
    a, b = read_run(p, table), read_run(q, table)
    np.testing.assert_allclose(b.t, a.t, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(b.acceleration, a.acceleration)
    np.testing.assert_allclose(b.odometry.balise_t, [1.0], atol=1e-9)


def test_an_unknown_format_lists_the_supported_ones(tmp_path, table):
    p = tmp_path / "run.xyz"
    p.write_bytes(b"\x00\x01garbage" * 10)
    with pytest.raises(UnknownFormatError, match="mdf4.*parquet.*csv"):
        read_run(p, table)
    assert set(formats()) >= {"mdf4", "parquet", "csv"}


# asammdf's __del__ of the half-built reader fails on a bad file; nothing of it may reach the user's terminal
@pytest.mark.filterwarnings("error::pytest.PytestUnraisableExceptionWarning")
def test_a_truncated_mdf4_is_a_named_error(tmp_path, table):
    p = tmp_path / "run.mf4"
    write_mdf4(p, _channels(n=20000), HEADER)
    data = p.read_bytes()
    cut = tmp_path / "cut.mf4"
    cut.write_bytes(data[: len(data) // 3])
    with pytest.raises(RunFileError, match="cut.mf4"):
        read_run(cut, table)


def test_a_truncated_tdms_is_a_named_error_not_a_shorter_run(tmp_path, table):
    """npTDMS reads a cut file as far as it goes and only warns: the run would silently end early."""
    p = tmp_path / "run.tdms"
    write_tdms(p, _channels(n=20000), HEADER)
    data = p.read_bytes()
    cut = tmp_path / "cut.tdms"
    cut.write_bytes(data[: 2 * len(data) // 3])
    with pytest.raises(RunFileError, match=r"cut\.tdms: the TDMS file is cut short"):
        read_run(cut, table)
    # refused by the segment lead-ins themselves, not by npTDMS's warning: so also where logging is silenced
    logging.disable(logging.CRITICAL)
    try:
        with pytest.raises(RunFileError, match=r"cut\.tdms: the TDMS file is cut short: segment 1 at byte 0 ends at "
                                               rf"byte {len(data)}, the file at byte {2 * len(data) // 3}"):
            read_run(cut, table)
    finally:
        logging.disable(logging.NOTSET)
    # LabVIEW leaves the next-segment offset at -1 in a file it never closed (a DAQ that lost power)
    open_ = tmp_path / "open.tdms"
    open_.write_bytes(data[:12] + b"\xff" * 8 + data[20:])
    with pytest.raises(RunFileError, match=r"open\.tdms: the TDMS file is cut short: segment 1 at byte 0 ends "
                                           r"nowhere \(the writer never closed it\)"):
        read_run(open_, table)


def test_an_mdf3_file_is_named_as_such_by_the_estimate_and_by_a_batch_reading_its_header(tmp_path, table):
    """MDF 3 carries no XML header comment: a batch reading the header first once refused it for a missing
    date, hiding the reason the estimate gives."""
    from asammdf import MDF

    from estimator.monitoring.headers import read_header

    p = tmp_path / "run.mf4"
    write_mdf4(p, _channels(), HEADER)
    old = tmp_path / "run.mdf"
    with MDF(str(p)) as mdf:
        mdf.convert("3.30").save(str(old), overwrite=True)
    for read in (lambda q: read_run(q, table), read_header):
        with pytest.raises(RunFileError, match=r"run.mdf: MDF version 3.30; the field contract uses MDF 4"):
            read(old)


def test_a_missing_channel_is_rejected_and_logged_not_invented(tmp_path, table, caplog):
    ch = _channels()
    del ch["ACC_W2R_Y"]
    p = tmp_path / "run.mf4"
    write_mdf4(p, ch, HEADER)
    run = read_run(p, table)
    assert "ACC_W2R_Y" not in run.names and len(run.names) == 5
    (ev,) = run.rejected
    assert ev.kind == "missing_channel" and ev.channel == "ACC_W2R_Y" and ev.action == "rejected"
    assert "ACC_W2R_Y" in caplog.text


def test_a_channel_at_a_wrong_rate_is_rejected(tmp_path, table):
    ch = _channels()
    t, v, u = ch["ACC_W1R_Y"]
    ch["ACC_W1R_Y"] = (t[::2], v[::2], u)  # 500 Hz among 1 kHz channels
    p = tmp_path / "run.mf4"
    write_mdf4(p, ch, HEADER)
    run = read_run(p, table)
    (ev,) = run.rejected
    assert ev.kind == "wrong_rate" and "500" in ev.reason and "ACC_W1R_Y" not in run.names
    # an expected rate the whole file misses leaves too few channels: a named error
    with pytest.raises(ChannelError, match="fewer than two"):
        read_run(p, table, fs=2000.0)


def test_a_channel_on_another_clock_is_rejected_by_its_drift(tmp_path, table):
    """ACC_W1L_Z truly sampled at 999.2 Hz (honest time stamps, 0.08 % off: inside the rate tolerance). Put on the
    1 kHz grid, its last sample would sit (1000/999.2 − 1) × its 2999 intervals = 2.40 samples before its time; it
    is rejected with that drift named. A clock 1 ppm off drifts 0.003 samples over the 3 s and is kept."""
    ch = _channels()
    t, v, u = ch["ACC_W1L_Z"]
    p = tmp_path / "run.mf4"
    ch["ACC_W1L_Z"] = (t[0] + np.arange(t.size) / 999.2, v, u)
    write_mdf4(p, ch, HEADER)
    run = read_run(p, table)
    (ev,) = run.rejected
    drift = (t.size - 1) * (1000.0 / 999.2 - 1)
    assert ev.kind == "wrong_rate" and ev.channel == "ACC_W1L_Z" and "ACC_W1L_Z" not in run.names
    assert f"drifts {drift:+.2f} samples" in ev.reason and "999.2 Hz" in ev.reason
    ch["ACC_W1L_Z"] = (t[0] + np.arange(t.size) / (1000.0 * (1 + 1e-6)), v, u)
    write_mdf4(p, ch, HEADER)
    run = read_run(p, table)
    assert not run.rejected and "ACC_W1L_Z" in run.names


def test_unit_contradicting_the_table_missing_odometry_and_header_direction(tmp_path, table):
    ch = _channels()
    ch["ACC_W1L_Z"] = (ch["ACC_W1L_Z"][0], ch["ACC_W1L_Z"][1], "m/s^2")
    p = tmp_path / "unit.mf4"
    write_mdf4(p, ch, HEADER)
    with pytest.raises(ChannelError, match="recorded in 'm/s\\^2' but the sensor table says 'g'"):
        read_run(p, table)
    ch = _channels()
    del ch["POSITION"]
    p = tmp_path / "nopos.mf4"
    write_mdf4(p, ch, HEADER)
    with pytest.raises(OdometryError, match="position channel 'POSITION'"):
        read_run(p, table)
    p = tmp_path / "nodir.mf4"
    write_mdf4(p, _channels(), {k: v for k, v in HEADER.items() if k != "direction"})
    with pytest.raises(RunFileError, match="no 'direction'"):
        read_run(p, table)
    assert read_run(p, table, direction="backward").header.direction == "backward"
    write_mdf4(p, _channels(), {**HEADER, "direction": "sideways"})  # named by the file, not by the run id
    with pytest.raises(RunFileError, match=rf"^{re.escape(str(p))}: header direction must be one of .* got 'sideways'"):
        read_run(p, table)
    assert read_run(p, table, direction="forward").header.direction == "forward"


def test_line_and_trolley_files(tmp_path):
    import json

    line = {"name": "test", "id": "T", "length_m": 1000, "sleeper_spacing_m": 0.75,
            "sections": [{"id": "A", "from_m": 0, "to_m": 500}],
            "curves": [{"id": "c1", "from_m": 100, "to_m": 300, "radius_m": 400, "direction": "right", "cant_mm": 40,
                        "transition_in_m": 40, "transition_out_m": 40}],
            "balises": [{"id": "b1", "chainage_m": 50}],
            "trackforms": [{"from_m": 0, "to_m": 1000, "trackform": "soft", "pad_stiffness_z": 100e6}]}
    (tmp_path / "line.json").write_text(json.dumps(line))
    ln = read_line(tmp_path / "line.json")
    (c,) = ln.curves
    assert c.low_rail == "R" and c.high_rail == "L"
    # curvature ramps over the transitions: half way up the first clothoid, full on the body, negative (right)
    assert ln.curvature(np.array([120.0, 200.0, 350.0])) == pytest.approx([-0.5 / 400, -1 / 400, 0.0])
    assert ln.trackform_at(10.0).pad_stiffness_z == 100e6
    bad = dict(line, curves=[dict(line["curves"][0], direction="up")])
    (tmp_path / "bad.json").write_text(json.dumps(bad))
    with pytest.raises(RunFileError, match="'left' or 'right'"):
        read_line(tmp_path / "bad.json")
    pd.DataFrame({"chainage_m": [0.0, 0.001, 0.0, 0.001], "rail": ["L", "L", "r", "R"],
                  "roughness_um": [1.0, 2.0, 3.0, 4.0]}).to_csv(tmp_path / "trolley.csv", index=False)
    tr = read_trolley(tmp_path / "trolley.csv")
    assert tr["roughness_m"].tolist() == pytest.approx([1e-6, 2e-6, 3e-6, 4e-6]) and set(tr["rail"]) == {"L", "R"}


def test_unreadable_trolley_rows_are_named_and_a_repeated_chainage_is_refused(tmp_path, caplog):
    """A trolley row with a blank roughness and one with a text chainage are left out with their file line numbers
    in a WARNING (the comparison sees a gap there); a chainage given twice on one rail is a named error."""
    pd.DataFrame({"chainage_m": ["0.000", "0.001", "x", "0.003", "0.000"], "rail": ["L", "L", "L", "L", "R"],
                  "roughness_um": [1.0, None, 3.0, 4.0, 5.0]}).to_csv(tmp_path / "t.csv", index=False)
    with caplog.at_level(logging.WARNING, logger="estimator"):
        tr = read_trolley(tmp_path / "t.csv")
    assert "2 trolley row(s) without a numeric chainage or roughness left out (file line(s) 3, 4)" in caplog.text
    assert tr["chainage_m"].tolist() == pytest.approx([0.0, 0.003, 0.0])
    pd.DataFrame({"chainage_m": [0.0, 0.001, 0.001, 0.0], "rail": ["L", "L", "L", "R"],
                  "roughness_um": [1.0, 2.0, 2.5, 3.0]}).to_csv(tmp_path / "twice.csv", index=False)
    with pytest.raises(RunFileError, match=r"rail L: chainage 0.0010 m is given 2 times \(1 repeated"):
        read_trolley(tmp_path / "twice.csv")


# ------------------------------------------------------------------ what real data loggers write
def _without(ch, name, i0, i1):
    t, v, u = ch[name]
    keep = np.r_[0:i0, i1:t.size]
    ch[name] = (t[keep], v[keep], u)


@pytest.mark.parametrize("fmt", ["mdf4", "parquet"])
def test_samples_the_logger_lost_are_nan_masked_and_reported_not_interpolated(tmp_path, table, fmt, caplog):
    """A buffer overrun: ACC_W1L_Z loses samples 1000-1049 (1.000-1.049 s; the odometer reads 110.0-110.49 m)."""
    from estimator.spatial import odometry_track

    ch = _channels()
    _without(ch, "ACC_W1L_Z", 1000, 1050)
    run = read_run(_write(tmp_path, "gap", ch, fmt), table)
    assert run.n_samples == 3000 and run.fs == pytest.approx(1000.0)
    i = run.index("ACC_W1L_Z")
    assert np.isnan(run.acceleration[i, 1000:1050]).all()
    assert np.isfinite(run.acceleration[i, :1000]).all() and np.isfinite(run.acceleration[i, 1050:]).all()
    # the samples around the gap are where the file put them, not shifted by the lost ones
    np.testing.assert_allclose(run.acceleration[i, 1050:], ch["ACC_W1L_Z"][1][1000:] * G, rtol=1e-12)
    (ev,) = [e for e in run.rejected if e.kind == "time_gap"]
    assert ev.channel == "ACC_W1L_Z" and ev.action == "masked" and "50 sample(s) lost" in ev.reason
    assert (ev.t_start, ev.t_end) == (pytest.approx(1.000), pytest.approx(1.049))
    assert (ev.chainage_from, ev.chainage_to) == (pytest.approx(110.0), pytest.approx(110.49))
    assert "time_gap [ACC_W1L_Z]" in caplog.text and "1 time-stamp gap" in run.processing[0]
    # quality control masks them and reports them once, as the gap (not again as a NaN dropout), and does not log
    # the reading's finding a second time
    caplog.clear()
    checked = check_run(run, odometry_track(run.odometry, +1))
    assert checked.mask.masked[i, 1000:1050].all() and not checked.mask.masked[i, :900].any()
    kinds = [e.kind for e in checked.mask.events if e.channel == "ACC_W1L_Z"]
    assert kinds == ["time_gap"]
    assert "time_gap" not in caplog.text


def test_a_channel_resuming_off_its_sampling_grid_is_an_error(tmp_path, table):
    ch = _channels()
    t, v, u = ch["ACC_W2L_Z"]
    t = t.copy()
    t[1500:] += 0.0004  # resumes 0.4 sampling intervals late: no longer sampled with the other channels
    ch["ACC_W2L_Z"] = (np.r_[t[:1000], t[1500:]], np.r_[v[:1000], v[1500:]], u)
    p = _write(tmp_path, "offgrid", ch, "parquet")
    with pytest.raises(ChannelError, match=r"'ACC_W2L_Z' resumes 501\.\d+ sampling intervals after a gap, off its"):
        read_run(p, table)


def test_time_stamps_of_a_loggers_clock_resolution_are_a_grid_and_jitter_is_not(tmp_path, table):
    """A 1024 Hz channel stamped to the microsecond (intervals of 976 and 977 µs) is evenly sampled at 1024 Hz, and
    so is one whose stamps wander slowly against the samples; stamps scattered by a fifth of an interval are not."""
    ch = _channels(fs=1024.0)
    for name in [k for k in ch if k.startswith("ACC")]:
        t, v, u = ch[name]
        ch[name] = (np.round(t * 1e6) / 1e6, v, u)
    assert len(np.unique(np.round(np.diff(ch["ACC_W1L_Z"][0]) * 1e6))) == 2
    run = read_run(_write(tmp_path, "us", ch, "parquet"), table)
    assert run.fs == pytest.approx(1024.0, rel=1e-6) and run.n_samples == 3000 and not run.rejected
    # a time reference the sampling clock wanders against (GPS stamps on a crystal): slow, a third of an interval
    # over the record, every interval within 0.05 % — one grid
    slow = {k: (t + 0.3 / 1024.0 * np.sin(np.pi * np.arange(t.size) / t.size), v, u) if k.startswith("ACC")
            else (t, v, u) for k, (t, v, u) in ch.items()}
    assert read_run(_write(tmp_path, "slow", slow, "parquet"), table).n_samples == 3000
    t, v, u = ch["ACC_W1L_Z"]
    ch["ACC_W1L_Z"] = (t + np.random.default_rng(1).uniform(-0.2, 0.2, t.size) / 1024.0, v, u)
    with pytest.raises(ChannelError, match="'ACC_W1L_Z' is not evenly sampled") as info:
        read_run(_write(tmp_path, "jitter", ch, "parquet"), table)
    assert "float32" not in str(info.value)


def test_a_float32_master_is_named_as_the_cause_of_an_uneven_time_base(tmp_path, table):
    """An MDF 4 whose time stamps are single precision, 299-302 s into a recording at 1 kHz: resolved to 31 µs
    there (3 % of an interval), the time base is off its grid; the refusal says why and what to write instead."""
    ch = {k: ((299.0 + t).astype(np.float32), v, u) for k, (t, v, u) in _channels().items()}
    with pytest.raises(ChannelError, match=r"'ACC_W1L_Z' is not evenly sampled .*single-precision \(float32\) "
                                           r"number, resolved to 3.05e-05 s at t = (299|30[01])\.\d+ s \(3.1 % of the "
                                           r"interval\): write the master channel as float64"):
        read_run(_write(tmp_path, "f32", ch, "mdf4"), table)
    # the same stamps in double precision are one grid
    ch = {k: (299.0 + t, v, u) for k, (t, v, u) in _channels().items()}
    assert read_run(_write(tmp_path, "f64", ch, "mdf4"), table).n_samples == 3000


@pytest.mark.parametrize("lost, action", [(5, "corrected"), (60, "masked")])
def test_a_stretch_without_odometry_is_interpolated_when_short_and_masked_when_long(tmp_path, table, lost, action):
    """Speed and position (100 Hz) lose ``lost`` samples from 1.5 s: 0.05 s is bridged (the position's bend under
    a metro's braking stays < 5 mm), 0.6 s is not measured and masked."""
    from estimator.spatial import MAX_ODOMETRY_GAP_S, odometry_track

    ch = _channels()
    for name in ("SPEED", "POSITION"):
        _without(ch, name, 150, 150 + lost)
    run = read_run(_write(tmp_path, "odogap", ch, "parquet"), table)
    ((g0, g1, names),) = run.odometry.gaps
    assert names == "SPEED, POSITION"
    assert (g0, g1) == (pytest.approx(1.49), pytest.approx(1.5 + lost / 100))
    tr = odometry_track(run.odometry, +1)
    (ev,) = [e for e in tr.events if e.kind == "odometry_gap"]
    assert ev.action == action and (g1 - g0 > MAX_ODOMETRY_GAP_S) == (action == "masked")
    assert ev.chainage_from == pytest.approx(114.9) and ev.chainage_to == pytest.approx(115.0 + lost / 10)
    assert bool(tr.untrusted) == (action == "masked")
    np.testing.assert_allclose(tr.chainage_at(np.array([1.52])), 115.2, atol=1e-9)  # constant speed: exact
    checked = check_run(run, tr)
    inside = (run.t > g0) & (run.t < g1)
    if action == "masked":
        assert checked.mask.masked[:, inside].all()
    else:
        assert not checked.mask.masked[:, inside].any()
    assert not checked.mask.masked[:, run.t < g0 - 0.1].any()


def _mdf_with_two_groups(path, ch, copy):
    """All channels as :func:`write_mdf4` writes them, plus ``copy`` = (name, t, values, unit) in a group of its own."""
    from asammdf import MDF, Signal

    write_mdf4(path, ch, HEADER)
    mdf = MDF(str(path))
    name, t, v, unit = copy
    mdf.append([Signal(np.asarray(v, float), np.asarray(t, float), name=name, unit=unit),
                Signal(np.zeros(t.size), np.asarray(t, float), name="STATUS", unit="")])
    out = path.with_name("two_" + path.name)
    mdf.save(str(out), overwrite=True)
    mdf.close()
    return out


def test_a_name_in_two_channel_groups_is_kept_when_equal_and_must_be_chosen_when_not(tmp_path, table):
    ch = _channels()
    t, v, u = ch["ACC_W1R_Z"]
    same = _mdf_with_two_groups(tmp_path / "same.mf4", ch, ("ACC_W1R_Z", t[::1], v, u))
    # a logger writing one signal in two groups: one channel, the same data
    np.testing.assert_array_equal(read_run(same, table).acceleration[read_run(same, table).index("ACC_W1R_Z")],
                                  v * G)
    # two different signals of one name (here the second one sampled at 500 Hz): never picked silently
    other = _mdf_with_two_groups(tmp_path / "other.mf4", ch, ("ACC_W1R_Z", t[::2], -v[::2], u))
    with pytest.raises(ChannelError, match=r"'ACC_W1R_Z' of the sensor table cannot be used: channel groups "
                                           r"\[\d+, \d+\] .*name one of \['ACC_W1R_Z@\d+', 'ACC_W1R_Z@\d+'\]"):
        read_run(other, table)
    # the sensor table names the copy it means
    from estimator.io.registry import read_raw

    raw, _ = read_raw(other)
    qualified = sorted(n for n in raw.channels if n.startswith("ACC_W1R_Z@"))
    full_rate = [n for n in qualified if raw.channels[n].t.size == t.size]
    s = pd.read_csv(table)
    s.loc[s["name"] == "ACC_W1R_Z", "name"] = full_rate[0]
    chosen = tmp_path / "chosen.csv"
    s.to_csv(chosen, index=False)
    run = read_run(other, chosen)
    np.testing.assert_array_equal(run.acceleration[run.index(full_rate[0])], v * G)


def test_two_channels_of_one_name_in_one_group_must_be_chosen_and_a_unit_spelling_is_no_difference(tmp_path,
                                                                                                    table):
    """Two modules' inputs of one name in one channel group (a Vector-style ``SIGNAL\\SOURCE`` name indexes the
    bare name twice) are two signals: neither is picked silently (the last one once was). A copy in another group
    whose unit is spelled ``G`` where the first says ``g`` holds the same data: one channel."""
    from asammdf import MDF, Signal

    from estimator.io.registry import read_raw

    ch = _channels()
    t, v, u = ch["ACC_W1R_Z"]
    path = tmp_path / "module.mf4"
    write_mdf4(path, ch, HEADER)
    mdf = MDF(str(path))
    mdf.append([Signal(-v, t, name="ACC_W1R_Z", unit=u), Signal(3 * v, t, name="ACC_W1R_Z", unit=u)])
    mdf.save(str(path), overwrite=True)
    mdf.close()
    with pytest.raises(ChannelError, match=r"'ACC_W1R_Z' of the sensor table cannot be used: channel groups "
                                           r"\[\d+, \d+\] hold 3 channels .*'ACC_W1R_Z@\d+', "
                                           r"'ACC_W1R_Z@\d+\.\d+', 'ACC_W1R_Z@\d+\.\d+'\]"):
        read_run(path, table)
    raw, _ = read_raw(path)
    copies = sorted((n for n in raw.channels if n.startswith("ACC_W1R_Z@")), key=lambda n: n.count("."))
    assert len(copies) == 3 and [raw.channels[n].values[1] / v[1] for n in copies[1:]] == pytest.approx([-1, 3])
    same = _mdf_with_two_groups(tmp_path / "same.mf4", ch, ("ACC_W1R_Z", t, v, "G"))
    raw, _ = read_raw(same)
    assert "ACC_W1R_Z" in raw.channels and "ACC_W1R_Z" not in raw.unusable


@pytest.mark.parametrize("file_unit, table_unit, factor", [
    ("m s-2", "m/s^2", 1.0), ("m·s⁻²", "m/s²", 1.0), ("m/s**2", "m/s^2", 1.0), ("G", "g", G), ("gn", "g", G),
    ("mm/s^2", "mm/s²", 1e-3),
    # units the lab's hammer reader knows (ema.channels.UNIT_TO_SI): the field reads them through the same table
    ("mg", "mg", 1e-3 * G), ("in/s²", "in/s^2", 0.0254), ("FT/S**2", "ft/s^2", 0.3048),
])
def test_unit_spellings_of_data_loggers_are_one_unit(tmp_path, file_unit, table_unit, factor):
    """A unit a logger spells its own way is the table's unit (and its SI factor), not a contradiction."""
    ch = _channels()
    ch = {k: (t, v, file_unit) if k.startswith("ACC") else (t, v, u) for k, (t, v, u) in ch.items()}
    s = sensor_table()
    acc = s["quantity"] == "acceleration"
    s.loc[acc, "unit"], s.loc[acc, "sensitivity"] = table_unit, factor
    table = tmp_path / "sensors.csv"
    s.to_csv(table, index=False)
    p = tmp_path / "run.mf4"
    write_mdf4(p, ch, HEADER)
    run = read_run(p, table)
    np.testing.assert_allclose(run.acceleration[0], ch["ACC_W1L_Z"][1] * factor, rtol=1e-12)


def test_every_acceleration_unit_the_lab_knows_the_field_sensor_table_knows_with_its_factor():
    """One unit table (ema.channels.UNIT_TO_SI): each label with its SI factor as the sensitivity is a valid row,
    and a g channel in mg (sensitivity 1000 x too large) is still refused by the sensitivity check."""
    from ema.channels import UNIT_TO_SI as LAB
    from estimator.io.sensors import UNIT_TO_SI, check_sensors, normalise_unit

    s = sensor_table()
    acc = s["quantity"] == "acceleration"
    for label, factor in LAB["acceleration"].items():
        s.loc[acc, "unit"], s.loc[acc, "sensitivity"] = label, factor
        out = check_sensors(s)
        assert UNIT_TO_SI[normalise_unit(label)] == factor, label
        np.testing.assert_allclose(out.loc[acc, "sensitivity"], factor, rtol=0)
    s.loc[acc, "unit"], s.loc[acc, "sensitivity"] = "mg", G
    with pytest.raises(SensorTableError, match="does not convert mg to SI"):
        check_sensors(s)


@pytest.mark.parametrize("recorded", ["speed", "position"])
def test_a_run_recording_only_speed_or_only_position_gets_the_other_derived(tmp_path, recorded):
    """A logger with only the train's speed (or only its odometer, resolved to 1 cm) still gives the chainage: a
    50 s run at up to 10 m/s with a 0.2 % odometer scale error, a 1.5 m start offset and three balises, the
    odometry at 100 Hz. Oracle: the bogie's true chainage and speed between the first and the last balise.

    * position recorded: chainage within 5 mm RMS (half the alignment's 10 mm budget); speed within 0.05 m/s
      (1 cm over the 0.2 s baseline) on 95 % of the samples and within 0.08 m/s where the acceleration ends (the
      baseline rounds that corner by about a W / 8 = 0.03 m/s);
    * speed recorded: the balise event's time stamp is all that pins the chainage, so it is right to the distance
      travelled in one stamp interval (10 m/s × 10 ms = 0.1 m: the monitoring alignment takes such offsets out).
    """
    from estimator.spatial import odometry_track
    from test_estimator_synthetic import make_run, speed_profile

    other = {"speed": "position", "position": "speed"}[recorded]

    def quantise(ch):
        t, v, u = ch["POSITION"]
        ch["POSITION"] = (t, np.round(v, 2), u)

    sr = make_run(tmp_path, duration_s=50.0, faults=quantise, name="full")
    table = tmp_path / "sensors_one.csv"
    sensor_table().query("quantity != @other").to_csv(table, index=False)
    run = read_run(sr.path, table)
    assert any(f"no {other} channel" in h for h in run.processing)
    assert run.odometry.names[other].startswith("integrated from" if other == "position" else "derived from")
    tr = odometry_track(run.odometry, +1)
    assert not tr.untrusted and not [e for e in tr.events if e.action == "masked"]
    assert len([e for e in tr.events if e.kind == "odometry_reset"]) == 3
    pinned = (sr.t >= run.odometry.balise_t[0] + 0.1) & (sr.t <= run.odometry.balise_t[-1])
    err = tr.chainage_at(sr.t[pinned]) - sr.chainage[pinned]
    if recorded == "position":
        assert np.sqrt(np.mean(err ** 2)) < 0.005
        dv = np.abs(tr.speed_at(sr.t[pinned]) - speed_profile(sr.t, 10.0)[pinned])
        assert np.percentile(dv, 95) < 0.05 and dv.max() < 0.08
    else:
        assert np.max(np.abs(err)) < 10.0 * 0.01
        np.testing.assert_allclose(tr.speed_at(sr.t[pinned]), speed_profile(sr.t, 10.0)[pinned], atol=0.02)


def test_a_derived_speed_still_exposes_an_odometer_jump_and_a_backward_speed_only_run_counts_down(tmp_path):
    """Without a speed channel the reset steps are rejected by the running median, so a jump no balise explains
    stays a jump (masked, named); a backward run with an unsigned speed and no position counts chainage down."""
    from estimator.spatial import odometry_track

    ch = _channels()
    t, pos, u = ch["POSITION"]
    ch["POSITION"] = (t, np.where(t >= 2.0, pos + 0.8, pos), u)  # a 0.8 m glitch at 2 s, no balise there
    table = tmp_path / "nospeed.csv"
    sensor_table().query("quantity != 'speed'").to_csv(table, index=False)
    run = read_run(_write(tmp_path, "jump", ch, "parquet"), table)
    np.testing.assert_allclose(run.odometry.speed[5:-5], 10.0, atol=1e-9)  # a constant 10 m/s, the jump rejected
    tr = odometry_track(run.odometry, +1)
    (ev,) = [e for e in tr.events if e.kind == "odometry_jump"]
    assert "+0.800 m at 2.00 s without a balise event" in ev.reason
    ch = _channels()
    to = ch["POSITION"][0]
    ch["BALISE"] = (np.array([1.0]), np.array([890.0]), "m")
    table = tmp_path / "nopos.csv"
    sensor_table().query("quantity != 'position'").to_csv(table, index=False)
    run = read_run(_write(tmp_path, "back", ch, "parquet"), table, direction="backward")
    tr = odometry_track(run.odometry, -1)
    np.testing.assert_allclose(tr.chainage_at(to), 890.0 - 10.0 * (to - 1.0), atol=1e-9)
    (note,) = [h for h in run.processing if "no position channel" in h]
    assert "reset to the balise's chainage at each of 1 passage(s)" in note


@pytest.mark.parametrize("both", [False, True], ids=["only-channel", "both-recorded"])
@pytest.mark.parametrize("recorded", ["SPEED", "POSITION"])
@pytest.mark.parametrize("lost, action", [(5, "corrected"), (60, "masked")])
def test_nan_in_an_odometry_channel_is_a_gap_judged_like_lost_samples(tmp_path, recorded, lost, action, both):
    """NaN in an odometry channel from 1.5 s, whether it is the only one or the other is recorded too: the stretch
    is an odometry gap, bridged when short (0.05 s) and masked when long (0.6 s), as for samples the logger lost;
    the channel is interpolated across, so no NaN speed slips past the jump test and the speed gate unflagged."""
    from estimator.spatial import odometry_track

    ch = _channels()
    t, v, u = ch[recorded]
    v = v.copy()
    v[150:150 + lost] = np.nan
    ch[recorded] = (t, v, u)
    table = tmp_path / "one.csv"
    dropped = "NONE" if both else "POSITION" if recorded == "SPEED" else "SPEED"  # noqa: F841 (read by query)
    sensor_table().query("name != @dropped").to_csv(table, index=False)
    run = read_run(_write(tmp_path, "nan", ch, "parquet"), table)
    ((g0, g1, name),) = run.odometry.gaps
    assert name == recorded and (g0, g1) == (pytest.approx(1.49), pytest.approx(1.5 + lost / 100))
    tr = odometry_track(run.odometry, +1)
    (ev,) = [e for e in tr.events if e.kind == "odometry_gap"]
    assert ev.action == action
    assert not [e for e in tr.events if e.kind in ("odometry_jump", "odometry_inconsistent")]
    np.testing.assert_allclose(tr.chainage_at(np.array([1.0, 2.5])), [110.0, 125.0], atol=1e-6)
    np.testing.assert_allclose(tr.speed_at(np.array([1.5 + lost / 200])), 10.0, atol=1e-9)
    checked = check_run(run, tr)
    inside = (run.t > g0) & (run.t < g1)
    assert checked.mask.masked[:, inside].all() == (action == "masked")
    assert not checked.mask.masked[:, run.t < g0 - 0.1].any()


def test_a_balise_event_without_a_chainage_is_named_and_its_reset_masked_not_silently_dropped(tmp_path, table,
                                                                                               caplog):
    """Two balise passages, the first (1 s) logged without a chainage (NaN), at which the odometer was reset 0.5 m
    forward: the reading names the event and its time, and the reset it cannot explain is masked as an odometer
    jump up to the next balise (2 s), not bridged as if the odometer were right."""
    from estimator.spatial import odometry_track

    ch = _channels()
    t, pos, u = ch["POSITION"]
    ch["POSITION"] = (t, np.where(t >= 1.0 - 1e-9, pos + 0.5, pos), u)
    ch["BALISE"] = (np.array([1.0, 2.0]), np.array([np.nan, 120.5]), "m")
    with caplog.at_level(logging.WARNING, logger="estimator"):
        run = read_run(_write(tmp_path, "nanbalise", ch, "parquet"), table)
    assert "'BALISE': 1 event(s) without a finite chainage ignored (at 1.000 s)" in caplog.text
    assert run.odometry.balise_t.tolist() == [2.0]
    tr = odometry_track(run.odometry, +1)
    (ev,) = [e for e in tr.events if e.kind == "odometry_jump"]
    assert "+0.500 m at 1.00 s without a balise event" in ev.reason and ev.action == "masked"
    assert (ev.t_start, ev.t_end) == (pytest.approx(0.0), pytest.approx(2.0))


@pytest.mark.parametrize("end", ["head", "tail"])
def test_a_channel_shorter_than_the_others_is_masked_where_it_has_no_sample_and_cuts_no_other(tmp_path, table, end):
    """One acceleration channel of a 3 s run lacks its first 0.5 s (or its last 2 s): the run keeps its 3 s, that
    channel is NaN there and masked with a finding that says so, and every other channel keeps all its samples."""
    ch = _channels()
    t, v, u = ch["ACC_W2R_Y"]
    keep = t >= 0.5 if end == "head" else t < 1.0
    ch["ACC_W2R_Y"] = (t[keep], v[keep], u)
    run = read_run(_write(tmp_path, "short", ch, "parquet"), table)
    assert run.n_samples == 3000 and run.t[0] == pytest.approx(0.0)
    i = run.names.index("ACC_W2R_Y")
    np.testing.assert_array_equal(np.isnan(run.acceleration[i]), ~keep)
    (ev,) = [e for e in run.rejected if e.channel == "ACC_W2R_Y"]
    assert ev.kind == "time_gap" and ev.action == "masked"
    assert ("channel starts 0.5 s after" if end == "head" else "channel ends 2 s before") in ev.reason
    from estimator.spatial import odometry_track

    checked = check_run(run, odometry_track(run.odometry, +1))
    assert checked.mask.masked[i, ~keep].all()
    others = [k for k in range(len(run.names)) if k != i]
    assert not checked.mask.masked[others].any()
    assert not [e for e in checked.mask.events if e.kind == "dropout_nan"]  # reported once, as the reading's finding


def test_a_speed_channel_ending_before_the_position_is_not_held_at_its_last_value(tmp_path, table, caplog):
    """Speed in a channel group of its own that stops at 1.5 s while the position goes on to 3 s, braking from
    10 m/s to a stop at 2.5 s: interpolation held 10 m/s to the end, so the standstill passed the speed gate. Past
    its span the speed is the position's rate (a 0.2 s central difference: exact on this parabola to 0.05 m/s
    away from the stop's corner), and the log says so."""
    ch = _channels()
    t, _, u = ch["POSITION"]
    tau = np.clip(t - 1.5, 0.0, 1.0)
    ch["POSITION"] = (t, np.where(t < 1.5, 100 + 10 * t, 115 + 10 * tau - 5 * tau ** 2), u)
    ts, vs, us = ch["SPEED"]
    ch["SPEED"] = (ts[ts < 1.5][::2], vs[ts < 1.5][::2], us)  # another rate too: resampled onto the position's
    with caplog.at_level(logging.WARNING, logger="estimator"):
        run = read_run(_write(tmp_path, "speedshort", ch, "parquet"), table)
    assert re.search(r"speed 'SPEED' covers 0\.000-1\.480 s, position 'POSITION' 0\.000-2\.990 s: the speed outside "
                     r"its span derived from the position \(\d+ odometry samples\)", caplog.text), caplog.text
    o = run.odometry
    np.testing.assert_allclose(np.interp([1.8, 2.0, 2.2], o.t, o.speed), [7.0, 5.0, 3.0], atol=0.05)
    assert np.all(np.abs(o.speed[o.t > 2.7]) < 1e-9)


def test_accelerations_beyond_the_odometry_are_masked_not_given_a_held_chainage(tmp_path, table):
    """Speed and position end at 1.5 s while the accelerations run to 3 s: past the odometry's last sample (and
    one odometry interval) the chainage is not measured, so those samples are masked and the finding says why."""
    ch = _channels()
    for name in ("SPEED", "POSITION"):
        t, v, u = ch[name]
        ch[name] = (t[t <= 1.5], v[t <= 1.5], u)
    from estimator.spatial import odometry_track

    run = read_run(_write(tmp_path, "odoend", ch, "parquet"), table)
    checked = check_run(run, odometry_track(run.odometry, +1))
    (ev,) = [e for e in checked.mask.events if e.kind == "odometry_gap"]
    assert "odometry covers 0.000 to 1.500 s" in ev.reason and ev.t_start == pytest.approx(1.511)
    assert checked.mask.masked[:, run.t > 1.51 + 1e-9].all() and not checked.mask.masked[:, run.t <= 1.5].any()


def test_an_odometer_that_does_not_reset_at_a_balise_is_pinned_to_the_balise_and_says_so(tmp_path, table, caplog):
    """The balises say 150 m and 160.1 m at 1 s and 2 s, but the odometer (10 m/s from 100 m) never resets: the
    balise is the absolute reference, so the chainage follows it (offset 40 m, the 1 % scale error between the two
    corrected), and each passage is reported as not reset, with the odometer's reading."""
    from estimator.spatial import odometry_track

    ch = _channels()
    ch["BALISE"] = (np.array([1.0, 2.0]), np.array([150.0, 160.1]), "m")
    run = read_run(_write(tmp_path, "noreset", ch, "parquet"), table)
    with caplog.at_level(logging.WARNING, logger="estimator"):
        tr = odometry_track(run.odometry, +1, source="noreset.parquet")
    evs = [e for e in tr.events if e.kind == "odometry_not_reset"]
    assert len(evs) == 2 and "balise at 150.00 m: the odometer reads 110.00 m after the passage (-40.00 m off" \
        in evs[0].reason
    assert "noreset.parquet: odometry_not_reset" in caplog.text
    np.testing.assert_allclose(tr.chainage_at(np.array([1.0, 1.5, 2.0])), [150.0, 155.05, 160.1], atol=1e-6)
    assert not tr.untrusted
    ch = _channels()  # an odometer that resets as the field contract says: no such finding
    ch["BALISE"] = (np.array([1.0, 2.0]), np.array([110.0, 120.0]), "m")
    run = read_run(_write(tmp_path, "reset", ch, "parquet"), table)
    assert not [e for e in odometry_track(run.odometry, +1).events if e.kind == "odometry_not_reset"]


@pytest.mark.parametrize("style", ["held", "pulse"])
def test_a_sampled_balise_channel_gives_one_passage_per_telegram_not_one_per_sample(tmp_path, table, style, caplog):
    """Loggers often sample the balise reader with the odometry (100 Hz) instead of writing one event per passage:
    the last telegram's chainage held (0 before the first), or each telegram for a few samples between idle zeros.
    Either way the passages are where the value changes to a telegram (1 s at 110 m and 2 s at 120 m here, on an
    odometer counting 100 + 10 t that resets correctly); each sample read as a passage once pinned the chainage
    to the held value and masked the whole run. Said in the log, with the passages taken."""
    from estimator.spatial import odometry_track

    ch = _channels()
    to = ch["SPEED"][0]
    if style == "held":
        v = np.select([to >= 2.0, to >= 1.0], [120.0, 110.0], 0.0)
    else:
        v = np.select([(to >= 2.0) & (to < 2.03), (to >= 1.0) & (to < 1.03)], [120.0, 110.0], 0.0)
    ch["BALISE"] = (to, v, "m")
    with caplog.at_level(logging.WARNING, logger="estimator"):
        run = read_run(_write(tmp_path, style, ch, "parquet"), table)
    np.testing.assert_allclose(run.odometry.balise_t, [1.0, 2.0], atol=1e-9)
    np.testing.assert_allclose(run.odometry.balise_chainage, [110.0, 120.0])
    assert "balise channel 'BALISE' is sampled (300 samples" in caplog.text and "2 passage(s) taken" in caplog.text
    tr = odometry_track(run.odometry, +1)
    assert not [e for e in tr.events if e.kind in ("odometry_not_reset", "odometry_jump")]
    np.testing.assert_allclose(tr.chainage_at(np.array([0.5, 1.5, 2.5])), [105.0, 115.0, 125.0], atol=1e-6)


def test_a_header_that_cannot_be_read_or_gives_a_key_twice_and_rows_without_a_channel_are_named(tmp_path, table):
    """The run's identity must not be lost or chosen silently: an MDF 4 header comment that is not valid XML (an
    unescaped '&'), a CSV header giving 'direction' twice with two values, and CSV rows with an empty channel
    cell (samples no channel can take) are each a RunFileError naming the file and what is wrong."""
    ch = _channels()
    p = tmp_path / "badxml.mf4"
    write_mdf4(p, ch, {**HEADER, "train": "T12 & T13"})
    from estimator.monitoring.headers import read_header  # what a batch reads first: the same refusals

    with pytest.raises(RunFileError, match=r"badxml.mf4: the header comment is not valid XML .*cannot be read"):
        read_run(p, table)
    with pytest.raises(RunFileError, match=r"badxml.mf4: the header comment is not valid XML .*cannot be read"):
        read_header(p)
    p = _write(tmp_path, "twice", ch, "csv")
    p.write_text("# direction = backward\n" + p.read_text())
    for read in (lambda q: read_run(q, table), read_header):
        with pytest.raises(RunFileError, match=r"twice.csv: header key 'direction' is given twice \('backward', "
                                               r"then 'forward'\)"):
            read(p)
    p = _write(tmp_path, "blank", ch, "csv")
    lines = p.read_text().splitlines()
    first = next(i for i, ln in enumerate(lines) if ln.startswith("ACC_W1L_Z,"))
    for i in (first + 5, first + 6):
        lines[i] = lines[i].replace("ACC_W1L_Z", "", 1)
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(RunFileError, match=r"blank.csv: 2 data row\(s\) have no channel name \(row\(s\) 6, 7,"):
        read_run(p, table)


def test_a_channel_without_a_unit_in_the_file_is_named(tmp_path, table, caplog):
    """The file cannot confirm the sensor table's unit of a channel it gives without one: read, and said — for the
    odometry too, where km/h read as m/s would silently put the run 3.6 times as far along the line."""
    ch = _channels()
    ch["ACC_W1L_Z"] = (*ch["ACC_W1L_Z"][:2], "")
    ch["SPEED"] = (*ch["SPEED"][:2], "")
    with caplog.at_level(logging.WARNING, logger="estimator"):
        run = read_run(_write(tmp_path, "nounit", ch, "csv"), table)
    assert "ACC_W1L_Z" in run.names
    assert "acceleration channel(s) ACC_W1L_Z (g) carry no unit in the file" in caplog.text
    assert "the speed channel 'SPEED' carries no unit in the file: read in the sensor table's 'm/s'" in caplog.text
    assert "position channel" not in caplog.text


def test_text_in_a_number_column_is_refused_and_infinity_is_named(tmp_path, table):
    """A long CSV whose value cell reads 'abc' is damaged, not a dropout: refused naming channel, column and row.
    Empty and NaN cells are missing samples. An 'inf' reads (a logger's overflow) and quality control names it
    as infinite values, not as no data."""
    from estimator.spatial import odometry_track

    ch = _channels()
    p = _write(tmp_path, "text", ch, "csv")
    lines = p.read_text().splitlines()
    first = next(i for i, ln in enumerate(lines) if ln.startswith("ACC_W1L_Z,"))
    header = next(i for i, ln in enumerate(lines) if ln.startswith("channel"))
    for value, k in (("abc", 7), ("", 5), ("NaN", 6)):
        parts = lines[first + k].split(",")
        parts[2] = value
        lines[first + k] = ",".join(parts)
    p.write_text("\n".join(lines) + "\n")
    row = first + 7 - header
    with pytest.raises(RunFileError, match=rf"text.csv: channel 'ACC_W1L_Z', column 'value', data row {row} .*"
                                           r"'abc' is not a number"):
        read_run(p, table)
    parts = lines[first + 7].split(",")
    parts[2] = "inf"
    lines[first + 7] = ",".join(parts)
    p.write_text("\n".join(lines) + "\n")
    run = read_run(p, table)
    checked = check_run(run, odometry_track(run.odometry, +1))
    kinds = {(e.kind, e.channel) for e in checked.mask.events}
    assert ("non_finite", "ACC_W1L_Z") in kinds and ("dropout_nan", "ACC_W1L_Z") in kinds


def test_a_wide_csv_as_daq_software_writes_it(tmp_path):
    """Semicolons and decimal commas, time in ms, units in brackets or parentheses; an empty cell is no sample of
    that channel, a ``NaN`` cell a missing sample; anything else is refused naming its column and row."""
    from estimator.io.registry import read_raw

    p = tmp_path / "daq.csv"
    p.write_text("# run_id = w1\n# direction = forward\n"
                 "Time [ms];ACC_W1L_Z (g);SPEED [km/h];BALISE\n"
                 "0;0,5;36,0;\n1;NaN;;\n2;-0,25;;110,5\n3;0,125;37,5;\n", encoding="utf-8")
    raw, fmt = read_raw(p)
    assert fmt == "csv-wide" and raw.header == {"run_id": "w1", "direction": "forward"}
    acc, v, bal = raw.channels["ACC_W1L_Z"], raw.channels["SPEED"], raw.channels["BALISE"]
    np.testing.assert_array_equal(acc.t, [0.0, 0.001, 0.002, 0.003])
    assert acc.unit == "g" and np.isnan(acc.values[1]) and acc.values[[0, 2, 3]].tolist() == [0.5, -0.25, 0.125]
    assert v.unit == "km/h" and v.t.tolist() == [0.0, 0.003] and v.values.tolist() == [36.0, 37.5]
    assert bal.unit == "" and bal.t.tolist() == [0.002] and bal.values.tolist() == [110.5]
    bad = tmp_path / "bad.csv"
    bad.write_text("time,ACC_W1L_Z [g]\n0.0,0.1\n0.001,abc\n")
    with pytest.raises(RunFileError, match=r"column 'ACC_W1L_Z \[g\]', data row 2 .*'abc' is not a number"):
        read_raw(bad)
    bad.write_text("time [h],ACC_W1L_Z [g]\n0.0,0.1\n")
    with pytest.raises(RunFileError, match=r"time column 'time \[h\]': unit 'h' is not one of"):
        read_raw(bad)

    # a file cut short mid-row, or a row that lost a cell, is refused naming the row (a blank cell keeps its
    # separators, so it is no sample of that channel, not damage); so is a channel given by two columns
    good = "# run_id = w2\ntime [s],ACC_W1L_Z [g],SPEED [m/s]\n0.0,0.1,10\n0.001,,\n0.002,0.3,\n"
    bad.write_text(good + "0.003,0.4\n0.004,0.5,10\n")
    with pytest.raises(RunFileError, match=r"bad.csv: data row 4 \(line 6\) has 2 field\(s\), the column header 3"):
        read_raw(bad)
    bad.write_text(good + "0.003,0.4")  # cut short, no final newline
    with pytest.raises(RunFileError, match=r"data row 4 \(line 6\) has 2 field\(s\)"):
        read_raw(bad)
    bad.write_text(good.replace("\n", "\r\n"))
    assert read_raw(bad)[0].channels["ACC_W1L_Z"].t.tolist() == [0.0, 0.002]
    bad.write_text("time [s],ACC_W1L_Z [g],ACC_W1L_Z [g]\n0.0,0.1,0.3\n")
    with pytest.raises(RunFileError, match=r"channel 'ACC_W1L_Z' is given by two columns"):
        read_raw(bad)

def test_a_wide_csv_with_a_daq_programs_preamble(tmp_path):
    """Plain-text lines before the column header (a program name, a start time, a blank line, a two-field row) are
    the run header: read as such, with the samples as without them; a conflicting key, or no column header within
    the preamble limit, is refused by name. Before, the long-table reader took the file and gave pandas'
    tokenizer message."""
    from estimator.io.registry import read_raw
    from estimator.io.wide import MAX_PREAMBLE_LINES

    table = "time [s],ACC_W1L_Z [g],SPEED [km/h]\n0.000,0.5,36\n0.001,-0.25,\n0.002,0.125,37.5\n"
    p = tmp_path / "pre.csv"
    p.write_text("# run_id = p1\nDEWESoft X3 export\nStart time: 2024-03-04 10:00:00\n\nOperator,J. Doe\n"
                 "vehicle = 501\n" + table)
    raw, fmt = read_raw(p)
    assert fmt == "csv-wide"
    assert raw.header == {"run_id": "p1", "Start time": "2024-03-04 10:00:00", "Operator": "J. Doe",
                          "vehicle": "501", "preamble": "DEWESoft X3 export"}
    (tmp_path / "plain.csv").write_text(table)
    plain, _ = read_raw(tmp_path / "plain.csv")
    for k in plain.channels:
        np.testing.assert_array_equal(raw.channels[k].t, plain.channels[k].t)
        np.testing.assert_array_equal(raw.channels[k].values, plain.channels[k].values)
    # a cut row is still named by its line in the file
    p.write_text("DEWESoft X3 export\n\n" + table + "0.003\n")
    with pytest.raises(RunFileError, match=r"data row 4 \(line 7\) has 1 field\(s\)"):
        read_raw(p)
    p.write_text("# vehicle = 501\nvehicle: 502\n" + table)
    with pytest.raises(RunFileError, match=r"header key 'vehicle' is given twice \('501', then '502'\)"):
        read_raw(p)
    p.write_text("".join(f"line {k}\n" for k in range(MAX_PREAMBLE_LINES + 1)) + table)
    with pytest.raises(RunFileError, match=r"pre.csv: no column header starting with a time column .* in the 40"):
        read_raw(p, format="csv-wide")
    with pytest.raises(RunFileError, match=r"pre.csv: not a readable CSV run table: neither a long table .* nor a "
                                           r"wide one"):
        read_raw(p)


def assert_same_estimate(mdf_path, other):
    """The control model's estimates of the MDF 4 run and of ``other``, the same run in another format, are equal
    to the bit."""
    from estimator import EstimatorConfig, estimate_run, prepare
    from test_estimator_synthetic import control_model, sensor_table

    fm = prepare(control_model(), sensor_table(), config=EstimatorConfig(wheelbase_m=2.2))
    a, b = estimate_run(mdf_path, fm), estimate_run(other, fm)
    assert b.source.endswith(other.name) and set(a.profiles) == set(b.profiles)
    pd.testing.assert_frame_equal(a.indexes, b.indexes, check_exact=True)
    for k in a.profiles:
        np.testing.assert_array_equal(a.profiles[k].rail, b.profiles[k].rail)


def test_a_run_estimated_from_a_wide_csv_equals_its_mdf4(tmp_path):
    """The synthetic run written as MDF 4 and converted to a wide CSV (every channel at its own rate, 17 digits)
    gives the same estimate, to the bit."""
    from estimator.io.registry import read_raw
    from estimator.io.wide import write_wide_csv
    from test_estimator_synthetic import make_run

    sr = make_run(tmp_path, duration_s=30.0)
    raw, _ = read_raw(sr.path)
    wide = write_wide_csv(raw.channels, raw.header, tmp_path / "run_wide.csv")
    assert read_raw(wide)[1] == "csv-wide"
    assert_same_estimate(sr.path, wide)


def test_a_run_estimated_from_tdms_equals_its_mdf4(tmp_path):
    """The synthetic run written as MDF 4 and converted to TDMS as an NI DAQ writes it (waveforms per time base,
    the balise events beside a Time channel, the header as root properties): the same channels, stamps and header,
    and the same estimate, to the bit."""
    from estimator.io.registry import read_raw
    from test_estimator_synthetic import make_run

    sr = make_run(tmp_path, duration_s=30.0)
    raw, _ = read_raw(sr.path)
    path = tmp_path / "run.tdms"
    write_tdms(path, {k: (c.t, c.values, c.unit) for k, c in raw.channels.items()}, dict(raw.header))
    again, fmt = read_raw(path)
    assert fmt == "tdms" and dict(again.header) == dict(raw.header) and set(again.channels) == set(raw.channels)
    for k, c in raw.channels.items():
        np.testing.assert_array_equal(again.channels[k].t, c.t)
        np.testing.assert_array_equal(again.channels[k].values, c.values)
    assert_same_estimate(sr.path, path)
