"""Bad data in a front-end's FRF file (UFF58, ema.read_frf_uff) are refused or logged, never silently accepted.

Each file is tiny (two channels, eight lines): an impossible coherence, an orphan coherence dataset, an unknown or
contradictory units label, a dead (all-zero) channel, a NaN in an FRF. Errors name the file, the dataset, the
response and the first offending frequency; warnings name the datasets and labels.
"""

from __future__ import annotations

import logging
import re
import struct

import numpy as np
import pandas as pd
import pytest
import pyuff

from ema.frf import FrequencyResponse
from ema.hammer_io import FunctionTypeError, UFFReadError
from ema.uff_frf import read_frf_uff, write_frf_uff

F = np.linspace(10.0, 80.0, 8)  # 10, 20, ..., 80 Hz


def _table() -> pd.DataFrame:
    rows = [dict(node=900, name="hammer", quantity="force", unit="N", x=0, y=0, z=0, dx=0, dy=0, dz=-1)]
    rows += [dict(node=n, name=f"acc_{n}", quantity="acceleration", unit="m/s^2", x=0.1 * k, y=0, z=0, dx=0, dy=0,
                  dz=1) for k, n in enumerate((101, 102))]
    return pd.DataFrame(rows)


def _write(path, H=None, coh=None, quantity="accelerance"):
    """Binary 58b from write_frf_uff: datasets FRF 101, [coh 101], FRF 102, [coh 102]."""
    H = np.array([[1.0 + 1.0j] * F.size, [2.0 - 1.0j] * F.size]) if H is None else H
    frf = FrequencyResponse(F, H[:, None, :], ("acc_101", "acc_102"), ("hammer",), quantity,
                            coherence=None if coh is None else coh[:, None, :])
    return write_frf_uff(frf, path, _table(), binary=True)


def _patch(path, marker: float, value: float):
    """Replace the one double ``marker`` in a binary file by ``value``: pyuff writes NaN as 0, a lab file has NaN."""
    raw = path.read_bytes()
    old = struct.pack("<d", marker)
    assert raw.count(old) == 1
    path.write_bytes(raw.replace(old, struct.pack("<d", value)))
    return path


def _rewrite(src, dst, edit):
    """The datasets of ``src``, edited in place by ``edit(list_of_dicts)``, written as ASCII to ``dst``."""
    sets = pyuff.UFF(str(src)).read_sets()
    for d in sets:
        d["binary"] = 0
    sets = edit(sets) or sets
    pyuff.UFF(str(dst)).write_sets(sets, mode="add")
    return dst


@pytest.mark.parametrize("value, shown", [(np.nan, "nan"), (1.7, "1.7")])
def test_impossible_coherence_is_refused_and_orphan_coherence_is_logged(tmp_path, caplog, value, shown):
    """NaN or > 1: refused naming file, coherence dataset (4 = coherence of the 2nd channel), response and first
    frequency; 1 + 1e-9 (rounding) is accepted. A coherence dataset whose FRF is absent is ignored with a
    WARNING naming it."""
    coh = np.full((2, F.size), 0.9)
    coh[1, 3], coh[1, 4] = 0.123456789, 0.5
    p = _patch(_write(tmp_path / "bad.uff", coh=coh), 0.123456789, value)
    msg = (f"{re.escape(str(p))}: coherence dataset 4, response 'acc_102' \\(node 102:\\+z\\).*coherence {shown} "
           f"at 40 Hz")
    with pytest.raises(UFFReadError, match=msg):
        read_frf_uff(p, _table())
    coh[1, 3:5] = 1.0 + 1e-9
    assert read_frf_uff(_write(tmp_path / "ok.uff", coh=coh), _table()).coherence is not None
    # drop the FRF of node 102 (dataset 3), keep its coherence: channel 101 alone, the orphan named
    orphan = _rewrite(tmp_path / "ok.uff", tmp_path / "orphan.uff",
                      lambda sets: [d for d in sets if not (d["func_type"] == 4 and d["rsp_node"] == 102)])
    with caplog.at_level(logging.WARNING, logger="ema"):
        frf = read_frf_uff(orphan)
    assert frf.outputs == ("101:+z",) and frf.coherence is not None
    assert re.search(r"orphan\.uff: coherence dataset 3 \(response 102:\+z, reference 900:-z\) without an FRF",
                     caplog.text)


def test_unknown_or_contradictory_units_labels_are_logged_or_refused(tmp_path, caplog):
    """A label no front end writes ('furlong/s^2' over 'stone'): taken as SI with a WARNING naming the datasets,
    channels and labels (as read_hammer does), noted in the history ('in/s^2' over 'lbf' is converted now:
    tests/test_lab_real_exports.py). An acceleration (ordinate type 12) labelled m/s/N is refused naming the dataset
    unless quantity= decides. The writer's own labels ('m/s^2/N' over 'N') read without any warning."""
    p = _write(tmp_path / "si.uff")
    with caplog.at_level(logging.WARNING, logger="ema"):
        ref = read_frf_uff(p, _table())
    assert caplog.text == ""

    def relabel(num, den):
        def edit(sets):
            for d in sets:
                d["ordinate_axis_units_lab"], d["orddenom_axis_units_lab"] = num, den
        return edit

    inch = _rewrite(p, tmp_path / "inch.uff", relabel("furlong/s^2", "stone"))
    with caplog.at_level(logging.WARNING, logger="ema"):
        frf = read_frf_uff(inch, _table())
    np.testing.assert_allclose(frf.data, ref.data, rtol=1e-12)
    assert re.search(r"inch\.uff: units label 'furlong/s\^2' over 'stone' not recognised \(dataset 1 \(response 'acc_101' "
                     r"\(node 101:\+z\)\), dataset 2 \(response 'acc_102'.*taken as SI \(m/s\^2/N\)", caplog.text)
    assert any("not recognised" in h for h in frf.history)

    mob = _rewrite(p, tmp_path / "mob.uff", relabel("m/s/N", "NONE"))
    with pytest.raises(FunctionTypeError, match=r"mob\.uff: dataset 1, response 'acc_101'.*'m/s/N' says mobility but "
                                                r"the ordinate type 12 \(acceleration\) says accelerance"):
        read_frf_uff(mob, _table())
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="ema"):
        assert read_frf_uff(mob, _table(), quantity="mobility").quantity == "mobility"
    assert "read as mobility as quantity= says" not in caplog.text  # the label agrees with quantity=
    with caplog.at_level(logging.WARNING, logger="ema"):
        read_frf_uff(mob, _table(), quantity="accelerance")
    assert "units label(s) say mobility (dataset 1 ('m/s/N')" in caplog.text


def test_dead_channel_is_refused(tmp_path, capsys):
    """An all-zero FRF is a dead sensor: refused naming the dataset and channel, also through the CLI (exit 1, one
    error line, no traceback)."""
    from railmodal.cli import main

    H = np.array([[1.0 + 1.0j] * F.size, [0.0] * F.size])
    p = _write(tmp_path / "dead.uff", H=H)
    with pytest.raises(UFFReadError, match=r"dead\.uff: dataset 2, response 'acc_102' \(node 102:\+z\), reference "
                                           r"'hammer' \(node 900:-z\): FRF is identically zero \(dead channel\)"):
        read_frf_uff(p, _table())
    _table().to_csv(tmp_path / "channels.csv", index=False)
    assert main(["-q", "lab", "identify", "--frf", str(p), "--channels", str(tmp_path / "channels.csv"),
                 "--out", str(tmp_path / "out")]) == 1
    err = capsys.readouterr().err
    assert "identically zero (dead channel)" in err and "Traceback" not in err


def test_nan_in_an_frf_names_dataset_channel_and_frequency(tmp_path):
    H = np.array([[1.0 + 1.0j] * F.size, [2.0 - 1.0j] * F.size])
    H[0, 5] = 3.14159265 + 1j
    p = _patch(_write(tmp_path / "nan.uff", H=H), 3.14159265, np.nan)
    with pytest.raises(UFFReadError, match=r"nan\.uff: dataset 1, response 101:\+z, reference 900:-z: the FRF is "
                                           r"NaN at 60 Hz"):
        read_frf_uff(p)
