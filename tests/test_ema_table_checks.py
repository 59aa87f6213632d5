"""Checks of what the hammer-test files and channel tables declare beside the data.

* the reference (excitation) node of the UFF58 datasets against the other hits and the table's force node;
* datasets of other types (logged) and a units dataset 164 that is not SI (checked against the unit labels);
* channel-table headers: misspelt, repeated and unknown columns, and a table mixing setups.

Oracles: small UFF58 files written by the virtual lab's exporter (whose reference node, units and labels are
known), edited in their text where a front-end would write something else.
"""

from __future__ import annotations

import dataclasses
import logging
import re

import numpy as np
import pandas as pd
import pytest

from ema import ChannelTableError, read_channels, read_hammer
from ema.hammer_io import ReferenceNodeError, UnitSystemError
from lab_data.uff_export import TimeHistory, write_time_histories

FS = 1024.0
N = 256
NODES = (101, 102)
LBF = 4.4482216152605
G = 9.80665

#: A units dataset 164 in inch-pound-second (factors: file units per SI unit), as a US front-end writes it.
UFF164_IPS = ("    -1\n   164\n         5IPS (lbf in s)               2\n"
              "  3.93700787401574803D+01  2.24808943099710480D-01  1.00000000000000000D+00\n"
              "  2.73149999999999977D+02\n    -1\n")
UFF164_SI = ("    -1\n   164\n         1SI - mks (Newton)            2\n"
             "  1.00000000000000000D+00  1.00000000000000000D+00  1.00000000000000000D+00\n"
             "  2.73149999999999977D+02\n    -1\n")
#: One FE node (dataset 2411): a dataset a hammer reader has no use for.
UFF2411 = ("    -1\n  2411\n        11         0         0         1\n"
           "   0.0000000000000000D+00   0.0000000000000000D+00   0.0000000000000000D+00\n    -1\n")


def small_table(**extra) -> pd.DataFrame:
    rows = [dict(node=900, name="hammer", quantity="force", unit="N", x=0, y=0, z=0, dx=0, dy=0, dz=-1)]
    rows += [dict(node=n, name=f"acc_{n}", quantity="acceleration", unit="m/s^2", x=0.1 * k, y=0, z=0, dx=0, dy=0,
                  dz=1) for k, n in enumerate(NODES)]
    df = pd.DataFrame(rows)
    for key, values in extra.items():
        df[key] = values
    return df


def histories(n_hits=3, ref=lambda hit: 900) -> list[TimeHistory]:
    """A force pulse and two decaying responses per hit; ``ref(hit)`` is the reference node the datasets name."""
    rng = np.random.default_rng(1)
    t = np.arange(N) / FS
    out = []
    for hit in range(1, n_hits + 1):
        k0 = 20 + hit
        force = 0.01 * rng.standard_normal(N)
        force[k0:k0 + 5] += 100.0 * np.sin(np.pi * np.arange(1, 6) / 6)
        out.append(TimeHistory(hit, 900, 0, "force", "N", "hammer", 1 / FS, force.astype(np.float32), ref(hit), 0))
        for j, node in enumerate(NODES):
            tt = np.clip(t - t[k0], 0, None)
            acc = (j + 1) * np.exp(-8 * tt) * np.sin(2 * np.pi * (60 + 25 * j) * tt) + 1e-3 * rng.standard_normal(N)
            out.append(TimeHistory(hit, node, 0, "acceleration", "m/s^2", f"acc_{node}", 1 / FS,
                                   acc.astype(np.float32), ref(hit), 0))
    return out


def write(tmp_path, name, hist, *, binary=True, before="", edit=lambda text: text):
    """The histories as a UFF58 file (``before``: datasets written ahead of them; ``edit``: on the ASCII text)."""
    path = write_time_histories(tmp_path / name, hist, binary=binary)
    if before or not binary:
        path.write_text(before + edit(path.read_text()))
    csv = tmp_path / f"{name}.csv"
    small_table().to_csv(csv, index=False)
    return path, csv


# ---------------------------------------------------------------------------------------------- reference node
def test_hits_at_another_reference_node_are_refused_and_a_lone_other_node_is_named(tmp_path, caplog):
    """Hit 3 recorded at reference node 950 among hits at the force node 900 is a roving-hammer hit: averaging it
    into the FRF would corrupt it, so the file is refused naming the file, the hit and both nodes. One other
    reference node for every hit is named in a WARNING (the table decides); 0 (unset) and the virtual lab's
    files (reference = force node) read without a word."""
    path, csv = write(tmp_path, "roving.uff", histories(ref=lambda hit: 950 if hit == 3 else 900))
    with pytest.raises(ReferenceNodeError) as err:
        read_hammer(path, csv)
    msg = str(err.value)
    for words in (str(path), "hit 3 at node 950", "hits 1, 2 at node 900", "force node is 900", "averaged"):
        assert words in msg, (words, msg)

    path, csv = write(tmp_path, "other.uff", histories(ref=lambda hit: 950))
    with caplog.at_level(logging.WARNING, logger="ema"):
        test = read_hammer(path, csv)
    assert test.hits == (1, 2, 3)
    warned = [r.getMessage() for r in caplog.records if "reference" in r.getMessage()]
    assert len(warned) == 1 and str(path) in warned[0] and "node 950" in warned[0] and "node 900" in warned[0]

    for ref in (0, 900):
        caplog.clear()
        path, csv = write(tmp_path, f"ref{ref}.uff", histories(ref=lambda hit: ref))
        with caplog.at_level(logging.WARNING, logger="ema"):
            assert read_hammer(path, csv).n_hits == 3
        assert not caplog.records, caplog.text


# ------------------------------------------------------------------------------------ other datasets, units 164
def test_other_datasets_are_logged_and_a_non_si_units_dataset_must_agree_with_the_labels(tmp_path, caplog):
    """Datasets the reader skips are named in an INFO log with their counts. A 164 declaring inch/lbf over data
    labelled N and m/s^2 is refused (which one is right cannot be known; the results would be off by 4.45 or
    39.4); labels in the declared units (lbf) or in g agree, and the data are converted by them."""
    hist = histories(n_hits=2)
    path, csv = write(tmp_path, "si164.uff", hist, binary=False, before=UFF164_SI + UFF2411)
    with caplog.at_level(logging.INFO, logger="ema"):
        ref = read_hammer(path, csv)
    assert f"{path}: ignored 1 dataset of type 2411 (nodes)" in caplog.text

    path, csv = write(tmp_path, "ips_si_labels.uff", hist, binary=False, before=UFF164_IPS)
    with pytest.raises(UnitSystemError) as err:
        read_hammer(path, csv)
    msg = str(err.value)
    for words in (str(path), "(type 164)", "IPS (lbf in s)", "hit 1, channel 'hammer' (node 900", "labelled 'N'"):
        assert words in msg, (words, msg)

    scaled = [dataclasses.replace(h, data=h.data / (G if h.quantity == "acceleration" else LBF)) for h in hist]

    def relabel(text):
        text = re.sub(r"(?<= )m/s\^2(?= )", "g    ", text)
        return text.replace(" N                   ", " lbf                 ")

    path, csv = write(tmp_path, "ips_lbf_g.uff", scaled, binary=False, before=UFF164_IPS, edit=relabel)
    test = read_hammer(path, csv)
    np.testing.assert_allclose(test.force, ref.force, rtol=2e-7, atol=0)
    np.testing.assert_allclose(test.responses, ref.responses, rtol=2e-7, atol=0)


# ------------------------------------------------------------------------------------------- channel-table header
def test_misspelt_repeated_and_unknown_columns_and_mixed_setups(tmp_path, caplog):
    """'fe-node' would be kept as an extra column while the sensors fall back to the nearest FE node, a second
    'z' would become an unused 'z.1', a mixed setup column would be reduced to its first value: each is refused
    naming the file and the column (and rows). Descriptive columns pass silently, other unknown ones with a
    WARNING listing the known columns."""
    def table_file(name, text):
        p = tmp_path / name
        p.write_text(text)
        return p

    base = small_table(fe_node=[4306, 1019, 1030]).to_csv(index=False)

    p = table_file("typo.csv", base.replace("fe_node", "fe-node", 1))
    with pytest.raises(ChannelTableError, match=re.escape(f"'{p}': column 'fe-node' is not a channel-table column; "
                                                          f"did you mean 'fe_node'?")):
        read_channels(p)

    lines = base.splitlines()
    p = table_file("dup.csv", "\n".join([lines[0] + ",z"] + [ln + ",0.5" for ln in lines[1:]]) + "\n")
    with pytest.raises(ChannelTableError, match=re.escape(f"'{p}': column 'z' appears twice in the header "
                                                          f"(columns 7 and 12)")):
        read_channels(p)

    p = tmp_path / "mixed.csv"
    small_table(setup=["flexural", "flexural", "torsional"]).to_csv(p, index=False)
    with pytest.raises(ChannelTableError, match=re.escape(f"'{p}': column 'setup' must have one value") +
                       r".*'flexural' in rows 1-2; 'torsional' in row 3"):
        read_channels(p)

    p = tmp_path / "extra.csv"
    small_table(comment=["tip: steel", "", "on the axle"], operator=["AB", "AB", "AB"]).to_csv(p, index=False)
    with caplog.at_level(logging.WARNING, logger="ema"):
        table = read_channels(p)
    assert {"comment", "operator"} <= set(table.columns)
    (msg,) = [r.getMessage() for r in caplog.records]
    assert str(p) in msg and "['operator']" in msg and "fe_node" in msg and "comment" not in msg.split("kept")[0]
