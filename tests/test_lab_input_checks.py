"""Lab input files checked against themselves: modes folders, UFF units / coordinate systems / mode numbers,
punch mode numbers, JSON trackforms with a repeated key.

Each bad file must be refused with a message naming the file and the offending row, line, mode or key (nothing
silently dropped, overwritten or accepted), while the valid variants (rows in another order, an identical repeat,
unnumbered modes) keep reading. Oracle: the file as written before the edit.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pandas as pd
import pytest

import fem_import
from ema.modes_io import ModesFolderError, read_modeset, write_modeset
from ema.modeset import ModeSet
from fem_import import FEReadError
from receptance.trackform import Trackform, TrackformError, load_trackform, trackform_to_dict
from test_fem_import_models import small_model, write_small_punch, write_small_uff


# ---------------------------------------------------------------- modes folder (ema.modes_io)
@pytest.fixture
def modes_folder(tmp_path):
    """A written modes folder of 3 modes on 4 DOFs, and the ModeSet it holds."""
    rng = np.random.default_rng(1)
    n, m = 4, 3
    channels = pd.DataFrame({
        "node": [101, 102, 103, 104], "name": ["a", "b", "c", "d"],
        "x": [0.0, 0.1, 0.2, 0.3], "y": [0.0, 0.0, 0.0, 0.0], "z": [0.0, 0.0, 0.0, 0.0],
        "dx": [0.0, 0.0, 1.0, 0.0], "dy": [0.0, 0.0, 0.0, 0.0], "dz": [1.0, 1.0, 0.0, 1.0],
        "fe_node": [11, 12, 13, 14], "setup": ["flex"] * n,
    })
    modes = ModeSet(freqs_hz=np.array([70.0, 130.0, 195.0]), zeta=np.array([0.004, 0.001, 0.0013]),
                    shapes=rng.normal(size=(n, m)) + 1j * rng.normal(size=(n, m)), dofs=("a", "b", "c", "d"),
                    channels=channels, mpc=np.full(m, 0.99), mpd=np.full(m, 2.0), setup=("flex",) * m)
    folder = write_modeset(modes, tmp_path / "modes")
    return folder, modes


def _edit_csv(path, edit):
    table = pd.read_csv(path)
    table = edit(table)
    table.to_csv(path, index=False)


def _edit_parquet(path, edit):
    table = edit(pd.read_parquet(path))
    table.to_parquet(path, index=False)


def _blank_f_hz(t):
    t.loc[1, "f_hz"] = np.nan
    return t


def _text_f_hz(t):
    t["f_hz"] = t["f_hz"].astype(object)
    t.loc[1, "f_hz"] = "abc"
    return t


def _repeated_mode(t):
    t.loc[2, "mode"] = 1
    return t


def _duplicate_row(t):
    extra = t[(t["mode"] == 1) & (t["dof"] == 0)].assign(re=99.0)
    return pd.concat([t, extra])


def _dof_minus_one(t):
    t.loc[t["dof"] == 3, "dof"] = -1
    return t


def _dof_fraction(t):
    t["dof"] = t["dof"].astype(float)
    t.loc[2, "dof"] = 1.5
    return t


BAD_FOLDERS = {
    "blank f_hz": ("modes.csv", _blank_f_hz, r"modes\.csv, row 2 \(mode 2\), column 'f_hz': the value is missing"),
    "text f_hz": ("modes.csv", _text_f_hz, r"modes\.csv, row 2 \(mode 2\), column 'f_hz': 'abc' is not a number"),
    "mode repeated": ("modes.csv", _repeated_mode, r"modes\.csv, row 3, column 'mode': mode 1 already given in row 1"),
    "no dx": ("dofs.csv", lambda t: t.drop(columns=["dx"]), r"dofs\.csv: column\(s\) \['dx'\] missing"),
    "duplicate (mode, dof)": ("shapes.parquet", _duplicate_row,
                              r"shapes\.parquet, row 13: mode 1, dof 0 already given in row 1"),
    "dof -1": ("shapes.parquet", _dof_minus_one, r"shapes\.parquet, row 4, column 'dof': -1 is not a DOF of dofs\.csv"),
    "dof 1.5": ("shapes.parquet", _dof_fraction, r"shapes\.parquet, row 3, column 'dof': 1\.5 is not an integer"),
}


@pytest.mark.parametrize("case", list(BAD_FOLDERS))
def test_modes_folder_inconsistent_files_are_named(modes_folder, case):
    """Item 1: a blank/text frequency, a repeated mode number, a missing column, a (mode, dof) given twice, a
    negative or fractional DOF index are refused naming the file, the row and the column (before: NaN poisoned the
    pairing, the later value overwrote, -1 wrapped to the last DOF, IndexError or messages without a file name)."""
    folder, _ = modes_folder
    name, edit, match = BAD_FOLDERS[case]
    (_edit_parquet if name.endswith(".parquet") else _edit_csv)(folder / name, edit)
    with pytest.raises(ModesFolderError, match=match) as exc:
        read_modeset(folder)
    assert str(folder / name) in str(exc.value)


def test_modes_folder_rows_are_matched_by_mode_number(modes_folder):
    """Item 1: modes.csv rows in another order attach each shape to its own mode (the ``mode`` column is the key
    shapes.parquet refers to); before, shapes were attached by row position."""
    folder, modes = modes_folder
    _edit_csv(folder / "modes.csv", lambda t: t.iloc[::-1])
    got = read_modeset(folder)
    np.testing.assert_array_equal(got.freqs_hz, modes.freqs_hz)
    np.testing.assert_array_equal(got.shapes, modes.shapes)


def test_modes_folder_error_reaches_the_cli_user_without_traceback(modes_folder, tmp_path, capsys):
    """Item 1: a float DOF index in ``lab pair --modes`` is a one-line error naming the file (was an IndexError
    traceback)."""
    from railmodal.cli import main

    folder, _ = modes_folder
    _edit_parquet(folder / "shapes.parquet", _dof_fraction)
    fem = write_small_uff(tmp_path / "fe.uff")
    code = main(["-q", "lab", "pair", "--modes", str(folder), "--fem", str(fem), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 1 and "Traceback" not in err
    assert re.search(r"railmodal: error: .*shapes\.parquet, row 3, column 'dof': 1\.5 is not an integer", err)
    assert not (tmp_path / "o").exists()


# ---------------------------------------------------------------- UFF 164 / 2420 (fem_import.uff)
def _dataset_164(code: int, description: str, length: float) -> str:
    return (f"    -1\n   164\n{code:10d}{description:<20}{2:10d}\n"
            + "".join(f"{v:25.17E}".replace("E", "D") for v in (length, 1.0, 1.0)) + "\n"
            + f"{273.15:25.17E}".replace("E", "D") + "\n    -1\n")


def _dataset_2420(label: int, rotation) -> str:
    rows = [*np.asarray(rotation, float), np.zeros(3)]
    return ("    -1\n  2420\n         1\nPART\n" + f"{label:10d}{0:10d}{8:10d}\nLOCAL {label}\n"
            + "".join("".join(f"{v:25.16E}" for v in r) + "\n" for r in rows) + "    -1\n")


def test_uff_second_units_dataset_must_agree(tmp_path):
    """Item 2: a later 164 in mm used to rescale every coordinate without a word; an identical repeat is fine."""
    text = write_small_uff(tmp_path / "base.uff").read_text()
    base = fem_import.read(tmp_path / "base.uff")
    same = tmp_path / "same.uff"
    same.write_text(text + _dataset_164(1, "SI - mks (Newton)", 1.0))
    np.testing.assert_array_equal(fem_import.read(same).xyz, base.xyz)
    mm = tmp_path / "mm.uff"
    mm.write_text(text + _dataset_164(2, "mm (milli newton)", 1000.0))
    line = text.count("\n") + 1
    with pytest.raises(FEReadError, match=rf"mm\.uff, dataset 164, line {line}: units differ from dataset 164 at "
                                          rf"line 1: units code 2 'mm \(milli newton\)'"):
        fem_import.read(mm)


def test_uff_coordinate_system_defined_twice_differently(tmp_path):
    """Item 2: a 2420 label defined again with another rotation used to overwrite the first definition."""
    text = write_small_uff(tmp_path / "base.uff").read_text()
    twice = tmp_path / "twice.uff"
    twice.write_text(_dataset_2420(5, np.eye(3)) + _dataset_2420(5, np.eye(3)) + text)
    assert len(fem_import.read(twice)) == 3  # the same definition twice: harmless
    rotated = [[0, 1, 0], [-1, 0, 0], [0, 0, 1]]
    clash = tmp_path / "clash.uff"
    first = _dataset_2420(5, rotated)
    clash.write_text(first + _dataset_2420(5, np.eye(3)) + text)
    with pytest.raises(FEReadError, match=rf"clash\.uff, dataset 2420, line {first.count(chr(10)) + 1}: coordinate "
                                          rf"system 5 is already defined by dataset 2420 at line 1"):
        fem_import.read(clash)


# ---------------------------------------------------------------- a mode number given twice (uff 55, punch)
def _record7(mode_n: int) -> str:
    """Record 7 of the lab's 55 (normal mode): 2 integers, 4 reals, load case 1, the mode number."""
    return f"{2:10d}{4:10d}{1:10d}{mode_n:10d}\n"


def test_uff55_mode_number_given_twice(tmp_path):
    """Item 3: two datasets 55 both saying 'mode 2' (at different frequencies) used to be read as two modes;
    modes all numbered 0 (not numbered) still read."""
    text = write_small_uff(tmp_path / "base.uff").read_text()
    assert text.count(_record7(3)) == 1
    dup = tmp_path / "dup.uff"
    dup.write_text(text.replace(_record7(3), _record7(2)))
    starts = [m.start() for m in re.finditer(r"    -1\n    55\n", text)]
    line2, line3 = (text.count("\n", 0, s) + 1 for s in starts[1:])
    with pytest.raises(FEReadError, match=rf"dup\.uff, dataset 55 \(mode 3\), line {line3}: mode number 2 already "
                                          rf"given at line {line2}"):
        fem_import.read(dup)
    unnumbered = tmp_path / "unnumbered.uff"
    zero = text
    for k in (1, 2, 3):
        zero = zero.replace(_record7(k), _record7(0))
    unnumbered.write_text(zero)
    np.testing.assert_array_equal(fem_import.read(unnumbered).freqs_hz, small_model()[3])


def test_punch_mode_given_twice_in_a_subcase(tmp_path):
    """Item 3: two punch runs concatenated (MODE 1, 2, 3, 1, 2, 3 in subcase 1) used to be read as six modes."""
    a = write_small_punch(tmp_path / "a.pch", 0).read_text()
    b = write_small_punch(tmp_path / "b.pch", 1).read_text()
    both = tmp_path / "ab.pch"
    both.write_text(a + b)
    lines = both.read_text().splitlines()
    at = [i + 1 for i, ln in enumerate(lines) if ln.startswith("$EIGENVALUE") and "MODE =     1" in ln]
    with pytest.raises(FEReadError, match=rf"ab\.pch, line {at[1]}: MODE 1 already given at line {at[0]} "
                                          rf"\(subcase 1\)"):
        fem_import.read(both)


# ---------------------------------------------------------------- JSON trackform (receptance.trackform)
@pytest.mark.parametrize("nested", [False, True])
def test_json_trackform_key_given_twice(tmp_path, nested):
    """Item 4: a JSON key given twice used to keep the last value (TOML refuses it)."""
    body = json.dumps(trackform_to_dict(Trackform()))[:-1] + ', "pad_stiffness_z": 450000000.0}'
    path = tmp_path / "track.json"
    path.write_text('{"trackform": ' + body + "}" if nested else body)
    with pytest.raises(TrackformError, match=r"track\.json: key 'pad_stiffness_z' given twice"):
        load_trackform(path)
