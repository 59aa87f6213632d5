"""Issue 11, model side: bad FE exports, points, pairings, trackforms and arguments through ``lab pair``,
``model build`` and ``model track``.

Every bad file is built inside the test from a good virtual-lab campaign. Each
case asserts the exit status, that nothing is written on failure, and that the
message names the file and the offending item.
"""

from __future__ import annotations

import dataclasses
import re
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import fem_import
from bad_inputs_support import grid_cards, identify_and_pair, nothing_written, run, uff55_blocks, write_fe
from lab_data.cache import campaign_dir
from receptance.trackform import Trackform, TrackformWarning, load_trackform, trackform_to_dict


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    """The small campaign, its clean modes and their pairing (``lab identify`` + ``lab pair``)."""
    folder = tmp_path_factory.mktemp("lab")
    modes, pairing = identify_and_pair(campaign_dir("control"), folder)
    return folder, modes, pairing


@pytest.fixture(scope="module")
def fe(lab):
    return fem_import.read(lab[0] / "fe_design.uff")


def build(args, capsys, lab, out, **files):
    folder, _, pairing = lab
    argv = ["-q", "model", "build", "--pairing", str(files.get("pairing", pairing)), "--fem",
            str(files.get("fem", folder / "fe_design.uff")), "--points", str(files.get("points", folder / "points.csv")),
            "--robustness-models", "2", *args, "--out", str(out)]
    return run(argv, capsys)


def identify_then_pair(folder, channels, tmp_path, capsys):
    """``lab identify`` with a channel table (must succeed), then ``lab pair`` of its modes into ``tmp_path / "o"``."""
    code, out, err = run(["-q", "lab", "identify", "--hammer", str(folder / "flexural.uff"), "--channels",
                          str(channels), "--band", "60", "300", "--max-order", "30", "--out", str(tmp_path / "modes")],
                         capsys)
    assert code == 0, err
    return run(["-q", "lab", "pair", "--modes", str(tmp_path / "modes"), "--fem", str(folder / "fe_design.uff"),
                "--out", str(tmp_path / "o")], capsys)


# ------------------------------------------------------------------ case 3: points and sensors far from their node
def test_case3_points_in_cm_are_named_by_build(lab, tmp_path, capsys):
    folder = lab[0]
    points = pd.read_csv(folder / "points.csv")
    points[["x", "y", "z"]] *= 100.0
    points.to_csv(tmp_path / "points_cm.csv", index=False)
    code, out, err = build([], capsys, lab, tmp_path / "o", points=tmp_path / "points_cm.csv")
    assert code == 1 and "Traceback" not in err
    assert "points_cm.csv" in err and "'contact_L'" in err and "looks like cm" in err
    assert nothing_written(tmp_path / "o")


def test_case3_channel_positions_in_mm_are_named_by_pair(lab, tmp_path, capsys):
    folder, modes, _ = lab
    table = pd.read_csv(folder / "flexural_channels.csv")
    table[["x", "y", "z"]] *= 1000.0
    table.to_csv(tmp_path / "channels_mm.csv", index=False)
    # identify does not need positions: it succeeds; the pairing with the FE names the slip
    code, out, err = identify_then_pair(folder, tmp_path / "channels_mm.csv", tmp_path, capsys)
    assert code == 1 and "Traceback" not in err
    first = table[table["quantity"] == "acceleration"].iloc[0]
    assert f"channel {first['name']!r}" in err and "looks like mm" in err and "fe_design.uff" in err
    assert nothing_written(tmp_path / "o")
    # model build's validation against a hammer test names it too, before any work
    code, out, err = build(["--hammer", str(folder / "flexural.uff"), "--channels", str(tmp_path / "channels_mm.csv")],
                           capsys, lab, tmp_path / "o2")
    assert code == 1 and "looks like mm" in err and f"channel {first['name']!r}" in err
    assert nothing_written(tmp_path / "o2")


def test_case3_the_tolerance_scales_with_the_model(fe):
    """The limit is a quarter of the model's size: the same point table passes on a model ten times larger."""
    from fem_import.checks import check_point_offsets, model_size, point_offset_limit

    assert point_offset_limit(fe) == pytest.approx(0.25 * model_size(fe))
    assert model_size(fe) == pytest.approx(np.linalg.norm(fe.xyz.max(0) - fe.xyz.min(0)))
    node = int(fe.node_ids[0])
    p = fe.xyz[0] + [0.0, 0.0, 0.3 * model_size(fe)]
    with pytest.raises(fem_import.PointToleranceError, match="sensor A"):
        check_point_offsets(fe, [node], [p], ["sensor A"])
    big = dataclasses.replace(fe, xyz=10 * fe.xyz)
    check_point_offsets(big, [node], [10 * fe.xyz[0] + [0.0, 0.0, 0.3 * model_size(fe)]], ["sensor A"])


# ------------------------------------------------------------------ case 4: the pairing against the FE file
def test_case4_two_fe_modes_swapped_in_the_export(lab, fe, tmp_path, capsys):
    pairing = pd.read_csv(lab[2] / "pairing.csv", dtype={"fe_modes": str})
    single = pairing[pairing["fe_modes"].fillna("").str.fullmatch(r"\d+") & pairing["test_mode"].notna()]
    a = int(single["fe_modes"].iloc[0])
    b = a + 2 if abs(fe.freqs_hz[a + 1] - fe.freqs_hz[a - 1]) > 1 else a + 1
    order = np.arange(len(fe))
    order[[a - 1, b - 1]] = order[[b - 1, a - 1]]
    write_fe(tmp_path / "swapped.uff", fe, shapes=fe.shapes[order], freqs=fe.freqs_hz[order])
    code, out, err = build([], capsys, lab, tmp_path / "o", fem=tmp_path / "swapped.uff")
    assert code == 1 and "Traceback" not in err
    assert "pairing.csv" in err and f"FE mode(s) {a}" in err and "swapped.uff" in err
    assert f"{fe.freqs_hz[b - 1]:.6g} Hz" in err and "another order" in err
    assert nothing_written(tmp_path / "o")


def test_case4_an_edited_test_frequency(lab, tmp_path, capsys):
    pairing = pd.read_csv(lab[2] / "pairing.csv", dtype={"fe_modes": str, "fe_weights": str})
    k = int(np.flatnonzero(pairing["test_mode"].notna() & pairing["fe_modes"].notna())[0])
    pairing.loc[k, "f_test_hz"] *= 10.0
    pairing.to_csv(tmp_path / "pairing.csv", index=False)
    code, out, err = build([], capsys, lab, tmp_path / "o", pairing=tmp_path / "pairing.csv")
    assert code == 1
    assert f"pairing.csv, row {k + 1}" in err and "edited" in err
    # without df_pct / f_fe_hz columns, the factor between test and FE frequency still gives it away
    pairing.drop(columns=["df_pct", "f_fe_hz"]).to_csv(tmp_path / "bare.csv", index=False)
    code, out, err = build([], capsys, lab, tmp_path / "o", pairing=tmp_path / "bare.csv")
    assert code == 1 and f"bare.csv, row {k + 1}" in err and "10 x apart" in err
    assert nothing_written(tmp_path / "o")


# ------------------------------------------------------------------ case 5: shapes not mass-normalised
def test_case5_shapes_ten_times_too_large_are_named_before_any_work(lab, fe, tmp_path, capsys):
    write_fe(tmp_path / "x10.uff", fe, shapes=10 * fe.shapes)
    code, out, err = build([], capsys, lab, tmp_path / "o", fem=tmp_path / "x10.uff")
    assert code == 1 and "Traceback" not in err
    assert "x10.uff" in err and "wheelset mass of 12.11 kg" in err and "not mass-normalised" in err
    assert nothing_written(tmp_path / "o")
    # against the true mass the factor is named exactly
    code, out, err = build(["--total-mass", "1211"], capsys, lab, tmp_path / "o", fem=tmp_path / "x10.uff")
    assert code == 1 and "scaled by 10" in err and "1211 kg" in err
    assert nothing_written(tmp_path / "o")


def test_case5_rigid_body_mass_and_mass_matrix_oracles(fe):
    """Oracle: the lab's FE mass matrix (its nodes are the export's, in the same order). The rigid-body modes give
    its total mass (a unit translation's kinetic energy, 1^T M 1; Table 2.1: wheelset 1054 kg + 2 axleboxes of
    78 kg), Phi^T M Phi = I for every mode, and shapes x 10 are refused with the factor named."""
    from fem_import.checks import MassNormalisationError, check_mass_normalisation, rigid_body_mass
    from lab_data.truth import design_modes
    from lab_data.wheelset import WheelsetParameters

    design = design_modes(WheelsetParameters(), 500.0)
    assert np.array_equal(design.model.node_ids, fe.node_ids)
    M = design.system.M
    ux = np.zeros((fe.node_ids.size, 6))
    ux[:, 0] = 1.0
    total = float(ux.ravel() @ (M @ ux.ravel()))
    rb = rigid_body_mass(fe)
    assert rb.mass == pytest.approx(total, rel=1e-6) and rb.spread < 1e-9 and rb.rigidity < 1e-5
    assert rb.mass == pytest.approx(1054 + 2 * 78, rel=0.01)
    np.testing.assert_allclose(rb.centre, 0.0, atol=1e-6)  # symmetric wheelset centred at the origin
    assert rb.inertia[1, 1] < rb.inertia[0, 0]  # the axle axis is the axis of least inertia
    check_mass_normalisation(fe, mass_matrix=M, total_mass=total)
    with pytest.raises(MassNormalisationError, match=r"modal mass phi\^T M phi = 100 .*scaled by 10"):
        check_mass_normalisation(dataclasses.replace(fe, shapes=10 * fe.shapes), mass_matrix=M)


def test_case5_a_beam_model_of_the_same_wheelset_has_the_same_mass(fe):
    """A design office's beam export (nodes on the axle's axis: the rotation about it shows in the rotational DOFs
    only) gives the mass of the lab's 3D mesh export — two FE models, one wheelset."""
    from fem_import.checks import rigid_body_mass

    beam = fem_import.read(campaign_dir("control", fe_style="beam") / "fe_design.uff")
    xz = np.hypot(beam.xyz[:, 0], beam.xyz[:, 2])
    assert xz.max() < 1e-9  # every node on the axis: translations alone cannot see the spin
    rb_beam, rb_mesh = rigid_body_mass(beam), rigid_body_mass(fe)
    assert rb_beam.mass == pytest.approx(rb_mesh.mass, rel=1e-6)
    assert rb_beam.inertia[1, 1] == pytest.approx(rb_mesh.inertia[1, 1], rel=0.05)  # polar inertia of the spin


def test_case5_inconsistent_rigid_modes_are_refused(fe):
    from fem_import.checks import MassNormalisationError, check_mass_normalisation

    shapes = fe.shapes.copy()
    shapes[0] *= 3.0  # one rigid mode with modal mass 1/9 in the file
    with pytest.raises(MassNormalisationError, match="imply different total masses along x, y, z"):
        check_mass_normalisation(dataclasses.replace(fe, shapes=shapes))


# ------------------------------------------------------------------ case 6: nothing written before a failure
@pytest.mark.parametrize("args, words", [
    (["--robustness-models", "0"], "--robustness-models must be an integer in [2, 5000], got 0"),
    (["--robustness-models", "100000"], "--robustness-models must be an integer in [2, 5000], got 100000"),
    (["--band", "500", "1"], "--band LOW HIGH needs LOW < HIGH, got 500 1"),
    (["--theta", "95", "0"], "--theta must be a number in (-90, 90) deg, got 95"),
    (["--default-zeta", "1"], "--default-zeta must be a number in [0, 1), got 1"),
    (["--total-mass", "-5"], "--total-mass must be a number in (0, 1e+06] kg, got -5"),
])
def test_case6_build_refuses_bad_arguments_before_writing(lab, tmp_path, capsys, args, words):
    code, out, err = build(args, capsys, lab, tmp_path / "o")
    assert code == 2 and words in err, err
    assert nothing_written(tmp_path / "o")


def test_case6_a_failure_during_the_work_leaves_out_untouched(lab, tmp_path, capsys, monkeypatch):
    """Write last: even a failure after validation (here: in the robustness plots) writes nothing to --out."""
    import receptance.plot_transfer as plot_transfer

    def boom(*a, **k):
        raise RuntimeError("plotting failed")

    monkeypatch.setattr(plot_transfer, "plot_spectral_std", boom)
    code, out, err = build([], capsys, lab, tmp_path / "o")
    assert code == 1 and "plotting failed" in err
    assert nothing_written(tmp_path / "o")


def test_case6_build_succeeds_and_writes_everything(lab, tmp_path, capsys):
    code, out, err = build([], capsys, lab, tmp_path / "o")
    assert code == 0, err
    names = {p.name for p in (tmp_path / "o").iterdir()}
    assert {"hybrid_model.npz", "modes.csv", "system_modes.csv", "receptances.png",
            "fig4_7_spectral_std_vertical_lateral.png"} <= names
    modes = pd.read_csv(tmp_path / "o" / "system_modes.csv")
    assert modes["f_hz"].iloc[0] == pytest.approx(6.43, abs=0.02)  # bounce on the primary suspension
    assert not any(p.name.startswith(".o.partial-") for p in tmp_path.iterdir())


# ------------------------------------------------------------------ cases 8, 9, 7b, 17b: model track
@pytest.mark.parametrize("df, words", [
    ("0", "--df must be a number in (0, 100] Hz, got 0"),
    ("-1", "--df must be a number in (0, 100] Hz, got -1"),
    ("1e-5", "--df = 1e-05 is refused: 199900000 frequency lines over 1-2000 Hz, at most 200000"),
    ("nan", "--df must be a finite number in (0, 100] Hz, got 'nan'"),
    ("1000", "--df must be a number in (0, 100] Hz, got 1000"),
])
def test_case8_track_df_is_bounded_with_the_limit_named(tmp_path, capsys, df, words):
    code, out, err = run(["-q", "model", "track", "--df", df, "--out", str(tmp_path / "o")], capsys)
    assert code == 2 and words in err, err
    assert nothing_written(tmp_path / "o")


def _trackform_file(tmp_path, name="track.toml", **changes):
    d = dict(trackform_to_dict(Trackform()), **changes)
    p = tmp_path / name
    p.write_text("[trackform]\n" + "".join(f"{k} = {v!r}\n" for k, v in d.items()))
    return p


@pytest.mark.parametrize("key, value, words", [
    ("pad_stiffness_z", 1e300, "'pad_stiffness_z' = 1e+300 N/m is outside the physical range [100000, 1e+11] N/m"),
    ("poisson_ratio", 0.6, "'poisson_ratio' = 0.6 is outside the physical range (0, 0.5)"),
    ("rail_loss_factor", 1.5, "'rail_loss_factor' = 1.5 is outside the physical range (0, 1]"),
    ("baseplate_mass", 1e-9, "'baseplate_mass' = 1e-09 kg is outside the physical range [0.01, 2000] kg"),
    ("rail_area", 63.62, "'rail_area' = 63.62 m^2 is outside the physical range"),
])
def test_case9_trackform_values_outside_physical_decades(tmp_path, capsys, key, value, words):
    path = _trackform_file(tmp_path, **{key: value})
    code, out, err = run(["-q", "model", "track", "--trackform", str(path), "--out", str(tmp_path / "o")], capsys)
    assert code == 1 and "track.toml" in err and words in err, err
    assert nothing_written(tmp_path / "o")


def test_case9_rail_mass_against_density_times_area_names_the_unit_slip(tmp_path):
    path = _trackform_file(tmp_path, rail_area=63.62e-4 * 5)  # inside the physical range, but 5 x the rail's
    with pytest.raises(Exception, match=r"track\.toml: rail_mass 49\.9 kg/m disagrees with rail_density x rail_area "
                                        r"= 7800 x 0\.03181 = 248\.1 kg/m"):
        load_trackform(path)


def test_case9_unusual_but_possible_values_warn_and_run(tmp_path, capsys):
    path = _trackform_file(tmp_path, pad_stiffness_z=5e9)  # a very stiff pad: typical up to 1.5 GN/m
    with pytest.warns(TrackformWarning, match=r"'pad_stiffness_z' = 5e\+09 N/m is outside the typical range "
                                              r"\[2e\+07, 1.5e\+09\] N/m"):
        tf = load_trackform(path)
    assert tf.pad_stiffness_z == 5e9
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", TrackformWarning)
        code, out, err = run(["-q", "model", "track", "--trackform", str(path), "--out", str(tmp_path / "o")],
                             capsys)
    assert code == 0, err
    assert len(pd.read_csv(tmp_path / "o" / "track_receptance.csv")) == 2000


def test_case7_a_400_digit_integer_in_a_trackform(tmp_path, capsys):
    path = _trackform_file(tmp_path)
    text = path.read_text().replace("rail_mass = 49.9", "rail_mass = " + "9" * 400)
    path.write_text(text)
    code, out, err = run(["-q", "model", "track", "--trackform", str(path), "--out", str(tmp_path / "o")], capsys)
    assert code == 1 and "Traceback" not in err
    assert "track.toml" in err and "'rail_mass'" in err and "400 digits" in err
    assert nothing_written(tmp_path / "o")


def test_case17_deep_json_and_toml_with_a_bom(tmp_path, capsys):
    deep = tmp_path / "deep.json"
    deep.write_text("[" * 100_000 + "]" * 100_000)
    code, out, err = run(["-q", "model", "track", "--trackform", str(deep), "--out", str(tmp_path / "o")], capsys)
    assert code == 1 and "deep.json" in err and "nested too deeply" in err
    assert nothing_written(tmp_path / "o")
    # a byte-order mark (Windows editors write one) is not content: the file reads as without it
    plain = _trackform_file(tmp_path, "plain.toml")
    bom = tmp_path / "bom.toml"
    bom.write_bytes(b"\xef\xbb\xbf" + plain.read_bytes())
    assert load_trackform(bom) == load_trackform(plain) == Trackform()
    code, out, err = run(["-q", "model", "track", "--trackform", str(bom), "--out", str(tmp_path / "b")], capsys)
    assert code == 0, err
    code, out, err = run(["-q", "model", "track", "--out", str(tmp_path / "d")], capsys)
    assert (tmp_path / "b" / "track_receptance.csv").read_text() == (tmp_path / "d" / "track_receptance.csv").read_text()


def test_case17_track_out_an_existing_file_and_trackform_a_folder(tmp_path, capsys):
    (tmp_path / "taken.csv").write_text("x")
    code, out, err = run(["-q", "model", "track", "--out", str(tmp_path / "taken.csv")], capsys)
    assert code == 2 and "is an existing file, not a folder" in err
    code, out, err = run(["-q", "model", "track", "--trackform", str(tmp_path), "--out", str(tmp_path / "o")], capsys)
    assert code == 2 and "is a folder, not a file" in err
    assert nothing_written(tmp_path / "o")


# ------------------------------------------------------------------ case 14: points.csv conversion errors
@pytest.mark.parametrize("column, value", [("fe_node", "abc"), ("x", "1,5e"), ("fe_node", "3.5")])
def test_case14_points_conversion_errors_name_file_row_and_column(lab, tmp_path, capsys, column, value):
    points = pd.read_csv(lab[0] / "points.csv").astype(object)
    points.loc[2, column] = value
    points.to_csv(tmp_path / "points.csv", index=False)
    code, out, err = build([], capsys, lab, tmp_path / "o", points=tmp_path / "points.csv")
    assert code == 1 and "Traceback" not in err
    assert re.search(rf"points\.csv, row 3 \(contact_R\), column '{column}': expected .*got '?{re.escape(value)}'?",
                     err), err
    assert nothing_written(tmp_path / "o")


def test_case13_points_with_semicolons_and_decimal_commas(lab, tmp_path):
    from receptance.dofs import read_points

    points = pd.read_csv(lab[0] / "points.csv")
    points.to_csv(tmp_path / "points.csv", sep=";", decimal=",", index=False)
    assert read_points(tmp_path / "points.csv") == read_points(lab[0] / "points.csv")


# ------------------------------------------------------------------ case 15
def test_case15_an_fe_node_not_in_the_fe_is_named_by_channel(lab, tmp_path, capsys):
    folder = lab[0]
    table = pd.read_csv(folder / "flexural_channels.csv")
    table.loc[2, "fe_node"] = 999999
    table.to_csv(tmp_path / "channels.csv", index=False)
    code, out, err = identify_then_pair(folder, tmp_path / "channels.csv", tmp_path, capsys)
    assert code == 1
    assert f"channel {table.loc[2, 'name']!r}" in err and "fe_node 999999 is not a node" in err and "point 2" not in err
    assert nothing_written(tmp_path / "o")


def test_case15_a_duplicated_uff55_mode(lab, tmp_path, capsys):
    lines, blocks = uff55_blocks((lab[0] / "fe_design.uff").read_text())
    a, b = blocks[13]  # mode 14, a single (non-degenerate) mode
    dup = lines[:b + 1] + lines[a:b + 1] + lines[b + 1:]
    (tmp_path / "dup.uff").write_text("\n".join(dup))
    code, out, err = run(["-q", "lab", "pair", "--modes", str(lab[1]), "--fem", str(tmp_path / "dup.uff"), "--out",
                          str(tmp_path / "o")], capsys)
    assert code == 1 and "dup.uff" in err and "modes 14 and 15 are the same mode written twice" in err
    assert nothing_written(tmp_path / "o")


def test_case15_a_1e99_shape_value(lab, tmp_path, capsys):
    lines, blocks = uff55_blocks((lab[0] / "fe_design.uff").read_text())
    a, _ = blocks[9]  # mode 10
    k = a + 13  # the values line of the second node (records 1-8, then node / values lines)
    assert len(lines[k]) == 78 and lines[k][9] == "E"  # six E13.6 fields
    lines[k] = " 1.000000E+99" + lines[k][13:]
    (tmp_path / "big.uff").write_text("\n".join(lines))
    code, out, err = build([], capsys, lab, tmp_path / "o", fem=tmp_path / "big.uff")
    assert code == 1 and "big.uff" in err and "mode 10" in err and "1e+99" in err and "corrupt" in err
    assert nothing_written(tmp_path / "o")


def test_case15_one_fe_mode_paired_twice(lab, tmp_path, capsys):
    pairing = pd.read_csv(lab[2] / "pairing.csv", dtype={"fe_modes": str, "fe_weights": str})
    rows = np.flatnonzero(pairing["test_mode"].notna() & pairing["fe_modes"].fillna("").str.fullmatch(r"\d+"))
    i, j = rows[:2]
    pairing.loc[j, "fe_modes"] = pairing.loc[i, "fe_modes"]
    pairing.loc[j, "f_fe_hz"] = pairing.loc[i, "f_fe_hz"]
    pairing.loc[j, "df_pct"] = 100 * (pairing.loc[j, "f_fe_hz"] - pairing.loc[j, "f_test_hz"]) / pairing.loc[
        j, "f_test_hz"]
    pairing.to_csv(tmp_path / "pairing.csv", index=False)
    code, out, err = build([], capsys, lab, tmp_path / "o", pairing=tmp_path / "pairing.csv")
    assert code == 1
    assert f"FE mode(s) {pairing.loc[i, 'fe_modes']} paired with 2 test modes" in err and "pairing.csv" in err
    assert nothing_written(tmp_path / "o")


# ------------------------------------------------------------------ case 16: a Nastran punch needs geometry
def test_case16_punch_without_geometry_says_which_file_is_needed(lab, tmp_path, capsys):
    import shutil

    shutil.copy(campaign_dir("control") / "fe_design.pch", tmp_path / "fe.pch")
    code, out, err = run(["-q", "lab", "pair", "--modes", str(lab[1]), "--fem", str(tmp_path / "fe.pch"), "--out",
                          str(tmp_path / "o")], capsys)
    assert code == 1 and "fe.pch" in err and "no node coordinates" in err and "--geometry FILE" in err
    assert "GRID cards" in err and "dataset 2411" in err
    assert nothing_written(tmp_path / "o")


@pytest.mark.slow
def test_case16_punch_with_geometry_pairs_and_builds_like_the_uff(lab, fe, tmp_path, capsys):
    import shutil

    folder, modes, pairing = lab
    pch = tmp_path / "fe.pch"
    shutil.copy(campaign_dir("control") / "fe_design.pch", pch)
    # geometry from a Nastran bulk data file (small, large and free field GRID cards)
    (tmp_path / "grids.bdf").write_text(grid_cards(fe.node_ids, fe.xyz))
    geo = fem_import.read_geometry(tmp_path / "grids.bdf")
    np.testing.assert_allclose(geo.xyz, fe.xyz, atol=1e-5)
    code, out, err = run(["-q", "lab", "pair", "--modes", str(modes), "--fem", str(pch), "--geometry",
                          str(tmp_path / "grids.bdf"), "--out", str(tmp_path / "pair")], capsys)
    assert code == 0, err
    a = pd.read_csv(pairing / "pairing.csv", dtype={"fe_modes": str})
    b = pd.read_csv(tmp_path / "pair" / "pairing.csv", dtype={"fe_modes": str})
    assert list(a["fe_modes"].fillna("")) == list(b["fe_modes"].fillna(""))
    np.testing.assert_allclose(a["mac"], b["mac"], atol=1e-4)
    # the punch's companion file (same name, .bdf) is found alone and gives the UFF's coordinates
    shutil.copy(tmp_path / "grids.bdf", tmp_path / "fe.bdf")
    from_pch, note = fem_import.read_with_geometry(pch)
    assert "companion file" in note and "fe.bdf" in note
    np.testing.assert_allclose(from_pch.xyz, fe.xyz, atol=1e-5)
    np.testing.assert_allclose(from_pch.shapes, fe.shapes, atol=1e-7 * np.abs(fe.shapes).max())
    # and model build runs on the punch with --geometry: the in-service bounce as from the UFF
    code, out, err = build(["--geometry", str(folder / "fe_design.uff")], capsys, lab, tmp_path / "m", fem=pch,
                           pairing=tmp_path / "pair")
    assert code == 0, err
    modes = pd.read_csv(tmp_path / "m" / "system_modes.csv")
    assert modes["f_hz"].iloc[0] == pytest.approx(6.43, abs=0.02)


def test_case16_bulk_grid_formats_and_refusals(tmp_path):
    from fem_import.nastran_bulk import parse_nastran_real

    assert parse_nastran_real("7.85-3") == pytest.approx(7.85e-3)
    assert parse_nastran_real("1.+4") == 1e4 and parse_nastran_real("-2.5D+2") == -250.0
    assert parse_nastran_real(" ") == 0.0
    (tmp_path / "cp.bdf").write_text("BEGIN BULK\nGRID    1       5       0.0     1.0     2.0\nENDDATA\n")
    with pytest.raises(fem_import.FEReadError, match=r"cp\.bdf, line 2: GRID 1 is given in coordinate system CP = 5, "
                                                 r"which no CORD entry defines"):
        fem_import.read_geometry(tmp_path / "cp.bdf")
    (tmp_path / "bad.bdf").write_text("BEGIN BULK\nGRID,7,,0.0,abc,1.0\nENDDATA\n")
    with pytest.raises(fem_import.FEReadError, match=r"GRID 7: coordinate 'abc' is not a number"):
        fem_import.read_geometry(tmp_path / "bad.bdf")
    with pytest.raises(fem_import.FEReadError, match="holds no mode shapes"):
        fem_import.read(tmp_path / "cp.bdf")


# ------------------------------------------------------------------ the repeated reader warning
def test_a_repeated_reader_warning_is_given_once_per_file_with_a_count(lab, tmp_path, caplog):
    import logging

    lines, blocks = uff55_blocks((lab[0] / "fe_design.uff").read_text())
    for a, _ in blocks:
        rec6 = a + 7  # record 6: model type, analysis type, data characteristic, result type (8 = displacement)
        fields = lines[rec6].split()
        assert fields[3] == "8"
        lines[rec6] = "".join(f"{int(v):10d}" for v in fields[:3] + ["12"] + fields[4:])
    (tmp_path / "acc.uff").write_text("\n".join(lines))
    with caplog.at_level(logging.WARNING, logger="fem_import"):
        fem_import.read(tmp_path / "acc.uff")
    msgs = [r.getMessage() for r in caplog.records if "specific data type" in r.getMessage()]
    assert msgs == [f"{tmp_path / 'acc.uff'}: {len(blocks)} dataset(s) 55 (modes 1-{len(blocks)}): specific data "
                    f"type 12 is not displacement (8); read as mode shape"]


@pytest.mark.skipif(not Path("/proc/self").exists(), reason="needs a virtual file system that takes no files")
def test_an_output_folder_nothing_can_be_written_in_is_refused_before_any_work():
    """/proc passes the permission bits for root but takes no folder: refused up front, naming --out and the
    folder, instead of failing after the whole computation on a hidden staging folder's name."""
    from railmodal.output import OutputFolderError, check_output_folder

    with pytest.raises(OutputFolderError, match=r"--out '/proc/railmodal_out': nothing can be written in '/proc'"):
        check_output_folder("/proc/railmodal_out")
    assert not list(Path("/proc").glob(".railmodal_out.probe-*"))
