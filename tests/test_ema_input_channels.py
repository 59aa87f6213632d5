"""Channel table validation (ema.channels): schema, normalisation and error messages."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from ema import ChannelTableError, read_channels, validate_channels


def table(**changes) -> pd.DataFrame:
    df = pd.DataFrame(
        {
            "node": [900, 101, 102],
            "name": ["hammer", "axle_01", "axle_02"],
            "quantity": ["force", "acceleration", "acceleration"],
            "unit": ["N", "m/s^2", "m/s^2"],
            "x": [0.0, 0.0, 0.0],
            "y": [-0.4, -0.56, -0.26],
            "z": [0.32, 0.074, 0.076],
            "dx": [0.0, 0.0, 0.6],
            "dy": [0.242535625036, 0.0, 0.8],
            "dz": [-0.970142500145, 1.0, 0.0],
            "fe_node": [4306, 1019, 1030],
            "setup": ["flexural"] * 3,
        }
    )
    for key, (row, value) in changes.items():
        df.loc[row, key] = value
    return df


def test_valid_table_is_normalised_and_input_untouched():
    df = table()
    df.loc[2, ["dx", "dy"]] = [0.6003, 0.8004]  # norm 1.0005: rounding in a CSV, normalised
    before = df.copy()
    out = validate_channels(df, source="t.csv")
    pd.testing.assert_frame_equal(df, before)
    assert list(out.columns[:10]) == ["node", "name", "quantity", "unit", "x", "y", "z", "dx", "dy", "dz"]
    norms = np.linalg.norm(out[["dx", "dy", "dz"]].to_numpy(), axis=1)
    np.testing.assert_allclose(norms, 1.0, atol=1e-15)
    np.testing.assert_allclose(out.loc[2, ["dx", "dy"]].to_numpy(float), np.array([0.6003, 0.8004]) / 1.0005, rtol=1e-12)
    assert out["node"].dtype == np.int64 and out["fe_node"].dtype == np.int64
    # idempotent
    pd.testing.assert_frame_equal(validate_channels(out), out)


def test_unit_spellings_are_canonicalised():
    out = validate_channels(table(unit=(1, "m/s2")))
    assert out.loc[1, "unit"] == "m/s^2"


@pytest.mark.parametrize(
    "changes, words",
    [
        ({"quantity": (1, "velocity")}, ["row 2 (node 101)", "'quantity'", "velocity", "acceleration"]),
        ({"unit": (1, "g")}, ["row 2 (node 101)", "'unit'", "'g'", "m/s^2"]),
        ({"quantity": (1, "force"), "unit": (1, "N")}, ["exactly one", "force", "[900, 101]"]),
        ({"quantity": (0, "acceleration"), "unit": (0, "m/s^2")}, ["exactly one", "found 0"]),
        ({"node": (2, 101)}, ["'node'", "unique", "101", "rows [2, 3]"]),
        ({"name": (2, "axle_01")}, ["'name'", "unique", "axle_01"]),
        ({"dz": (1, 1.01)}, ["row 2 (node 101)", "unit vector", "1.01"]),
        ({"dz": (1, 0.0)}, ["row 2 (node 101)", "unit vector", "norm 0"]),
        ({"x": (2, np.inf)}, ["row 3 (node 102)", "'x'", "finite"]),
        ({"y": (2, np.nan)}, ["row 3 (node 102)", "'y'", "finite"]),
        ({"node": (1, 10.5)}, ["row 2", "'node'", "positive integer", "10.5"]),
        ({"fe_node": (1, -3)}, ["row 2 (node 101)", "'fe_node'", "positive integer"]),
    ],
)
def test_bad_tables_name_the_source_row_and_column(changes, words):
    df = table()
    for key, (row, value) in changes.items():
        if isinstance(value, float) and key in ("node", "fe_node"):
            df[key] = df[key].astype(float)
        df.loc[row, key] = value
    with pytest.raises(ChannelTableError) as err:
        validate_channels(df, source="lab/flexural_channels.csv")
    msg = str(err.value)
    assert "lab/flexural_channels.csv" in msg
    for w in words:
        assert w in msg, (w, msg)


def test_missing_column_is_listed():
    with pytest.raises(ChannelTableError, match=r"missing required column\(s\) \['dz'\]"):
        validate_channels(table().drop(columns="dz"), source="x.csv")


def test_no_acceleration_channel():
    with pytest.raises(ChannelTableError, match="no acceleration channel"):
        validate_channels(table().iloc[:1])


def test_sensitivity_must_be_positive():
    df = table()
    df["sensitivity"] = [2.3e-3, 10.2e-3, -1.0]
    with pytest.raises(ChannelTableError, match=r"row 3 \(node 102\), column 'sensitivity'"):
        validate_channels(df)
    df["sensitivity"] = [2.3e-3, 10.2e-3, 9.9e-3]
    assert validate_channels(df)["sensitivity"].tolist() == [2.3e-3, 10.2e-3, 9.9e-3]


def test_read_channels_roundtrip_and_errors(tmp_path, control_dir):
    lab = read_channels(control_dir / "flexural_channels.csv")
    assert len(lab) == 30 and (lab["quantity"] == "force").sum() == 1
    assert lab.loc[lab["quantity"] == "force", "node"].item() == 900
    p = tmp_path / "c.csv"
    table(dz=(1, 2.0)).to_csv(p, index=False)
    with pytest.raises(ChannelTableError, match=str(p).replace("\\", "\\\\")):
        read_channels(p)
    with pytest.raises(FileNotFoundError, match="nothing.csv"):
        read_channels(tmp_path / "nothing.csv")
    (tmp_path / "empty.csv").write_text("")
    with pytest.raises(ChannelTableError, match="empty.csv"):
        read_channels(tmp_path / "empty.csv")
