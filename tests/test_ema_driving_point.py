"""The driving point's sign (ema.driving_point): a hammer or accelerometer read with the wrong sign, without an FE.

Oracle: a toy modal truth whose first sensor sits at the force point along the hammer (its shape row equals the
force-point shape, so every modal constant there is a square, > 0). Negating the force channel, or giving that
sensor's direction the other sense in the table, must turn every constant the other way and be named; the truth as
recorded must pass, and a sensor at the force node across the hammer's line is no driving point.
"""

from __future__ import annotations

import logging

import numpy as np
import pandas as pd
import pytest

import ema
from ema.driving_point import driving_point_checks, driving_point_findings
from lab_data.hammer import ModalTruth, Pulse, add_noise, quantise, synthesize_hit
from railmodal.cli import main

FS = 3200.0
B = np.array([0.03, 0.025, -0.012, 0.02])  # the force-point shape along the hammer, 4 elastic modes
TRUTH = ModalTruth([72.6, 150.0, 262.0, 410.0], [0.004, 0.003, 0.005, 0.004], B,
                   np.array([B, [0.03, -0.01, 0.02, 0.015], [0.01, 0.02, 0.03, -0.01]]))


def table(sensor_dz=1.0, sensor_dy=0.0) -> pd.DataFrame:
    rows = [dict(node=101, name="hammer", quantity="force", unit="N", x=0, y=0, z=0, dx=0, dy=0, dz=1)]
    rows.append(dict(node=101, name="drive", quantity="acceleration", unit="m/s^2", x=0, y=0, z=0, dx=0,
                     dy=sensor_dy, dz=sensor_dz))
    rows += [dict(node=102 + j, name=f"ch{j}", quantity="acceleration", unit="m/s^2", x=1 + j, y=0, z=0, dx=0, dy=0,
                  dz=1) for j in range(2)]
    return pd.DataFrame(rows)


def hits(n=4, seed=2):
    rng = np.random.default_rng(seed)
    force, resp = [], []
    for _ in range(n):
        _, f, a = synthesize_hit(TRUTH, [Pulse(0.05 + 1e-3 * rng.uniform(), 6e-4 + 2e-4 * rng.uniform(), 1000.0)],
                                 fs=FS, duration=2.0)
        force.append(quantise(add_noise(f, 0.05, rng), 10000.0)[0])
        resp.append(quantise(add_noise(a, 5e-4, rng), 50.0)[0])
    return np.array(force), np.array(resp)


def identified(force, resp, tab):
    test = ema.HammerTest.from_arrays(force, resp, FS, tab, source="toy")
    frf = ema.estimate_frf(test, band_hz=(20.0, 600.0))
    return ema.identify(frf, band_hz=(20.0, 600.0), max_order=20).modes, test


@pytest.fixture(scope="module")
def records():
    return hits()


def test_the_recorded_driving_point_is_consistent(records):
    modes, test = identified(*records, table())
    np.testing.assert_allclose(np.sort(modes.freqs_hz), TRUTH.freqs_hz, rtol=2e-3)
    (check,) = driving_point_checks(modes, test.channels)
    assert (check.channel, check.node, check.expected_sign, check.angle_deg) == ("drive", 101, 1, 0.0)
    assert (check.verdict, check.n_modes, check.n_wrong) == ("consistent", 4, 0)
    assert driving_point_findings((check,)) == []


def test_a_negated_force_is_named_at_the_driving_point(records):
    force, resp = records
    modes, test = identified(-force, resp, table())
    (check,) = driving_point_checks(modes, test.channels)
    assert (check.verdict, check.n_wrong, check.wrong_share) == ("reversed", 4, 1.0)
    (finding,) = driving_point_findings((check,), source="toy")
    assert finding.startswith("toy: channel 'drive' at the hammer's node 101") and "wrong sign" in finding


def test_a_sensor_direction_reversed_in_the_table_is_named(records):
    """The same records with the sensor said to measure against the hammer (dz = -1): the constants there must
    be negative; the recorded ones are positive."""
    modes, test = identified(*records, table(sensor_dz=-1.0))
    (check,) = driving_point_checks(modes, test.channels)
    assert (check.expected_sign, check.verdict) == (-1, "reversed")


def test_a_sensor_across_the_hammer_is_no_driving_point(records):
    modes, test = identified(*records, table(sensor_dz=0.0, sensor_dy=1.0))
    assert driving_point_checks(modes, test.channels) == ()
    # 25 degrees off the line is still a driving point
    modes, test = identified(*records, table(sensor_dz=np.cos(np.radians(25)), sensor_dy=np.sin(np.radians(25))))
    (check,) = driving_point_checks(modes, test.channels)
    assert check.angle_deg == pytest.approx(25.0) and check.verdict == "consistent"


def test_lab_identify_warns_of_a_reversed_hammer(records, tmp_path, caplog, capsys):
    """Through the CLI: the UFF58 written from the negated records, the warning names setup and channel."""
    from lab_data.uff_export import TimeHistory, write_time_histories

    force, resp = records
    tab = table()
    tab.to_csv(tmp_path / "channels.csv", index=False)
    acc = tab[tab["quantity"] == "acceleration"]
    hist = []
    for h in range(force.shape[0]):
        hist.append(TimeHistory(h + 1, 101, 3, "force", "N", "hammer", 1 / FS, -force[h], 101, 3))
        hist += [TimeHistory(h + 1, int(r.node), 3, "acceleration", "m/s^2", r.name, 1 / FS, resp[h, j], 101, 3)
                 for j, r in enumerate(acc.itertuples())]
    write_time_histories(tmp_path / "hits.uff", hist)
    with caplog.at_level(logging.WARNING, logger="ema"):
        code = main(["-q", "lab", "identify", "--hammer", str(tmp_path / "hits.uff"), "--channels",
                     str(tmp_path / "channels.csv"), "--band", "20", "600", "--max-order", "20",
                     "--out", str(tmp_path / "modes")])
    assert code == 0
    warned = [r.getMessage() for r in caplog.records if "driving point" in r.getMessage()]
    assert len(warned) == 1 and "channel 'drive' at the hammer's node 101" in warned[0], warned
    assert "driving point 'drive': reversed (0 of 4 modal constants of the sign a driving point must have)" in \
        capsys.readouterr().out
