"""Reading field runs: sensor tables, the MDF 4 / Parquet / CSV registry, headers, units, sensitivities, bad files."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from estimator import (ChannelError, OdometryError, RunFileError, SensorTableError, UnknownFormatError, read_run,
                       read_sensors)
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
    (lambda d: d[d["quantity"] != "speed"], "exactly one speed"),
    (lambda d: pd.concat([d, d.iloc[[0]]]), "unique"),
    (lambda d: d.assign(unit=d["unit"].where(d["name"] != "SPEED", "furlong")), "unit of a speed channel"),
])
def test_sensor_table_errors_name_row_column_and_value(tmp_path, edit, message):
    p = tmp_path / "bad.csv"
    edit(sensor_table()).to_csv(p, index=False)
    with pytest.raises(SensorTableError, match=message):
        read_sensors(p)


@pytest.mark.parametrize("fmt", ["mdf4", "parquet", "csv"])
def test_the_three_formats_give_the_same_run(tmp_path, table, fmt):
    ch = _channels()
    path = tmp_path / f"run.{dict(mdf4='mf4', parquet='parquet', csv='csv')[fmt]}"
    if fmt == "mdf4":
        write_mdf4(path, ch, HEADER)
    else:
        write_run_table({k: RawChannel(k, *v) for k, v in ch.items()}, HEADER, path, fmt)
    run = read_run(path, table)
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
