"""The line description reader refuses nonsensical or malformed ``line.json`` / trolley files by name.

Every refusal is a :class:`RunFileError` whose message starts with the file and names the offending entry, so
that the CLI prints it instead of a traceback, and nothing the file says is dropped or read as something else.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from estimator import RunFileError
from estimator.io import read_line, read_trolley

#: A well-formed line every case below spoils in one place.
GOOD = {
    "name": "test", "id": "T", "length_m": 1000, "sleeper_spacing_m": 0.75,
    "sections": [{"id": "S1", "from_m": 0, "to_m": 300}, {"id": "S2", "from_m": 300, "to_m": 1000}],
    "curves": [{"id": "C1", "from_m": 100, "to_m": 300, "radius_m": 400, "direction": "right", "cant_mm": 40,
                "transition_in_m": 40, "transition_out_m": 40}],
    "switches": [{"id": "W1", "from_m": 600, "to_m": 640, "crossing_m": 632, "crossing_rail": "R"}],
    "welds": [{"chainage_m": 20.0, "rail": "L"}, {"chainage_m": 38.0, "rail": "r"}, {"chainage_m": 700.0}],
    "balises": [{"id": "B1", "chainage_m": 50}],
    "trackform_sections": [
        {"from_m": 0, "to_m": 410, "trackform": "slab", "note": "as built", "pad_stiffness_z": 150e6},
        {"from_m": 410, "to_m": 1000, "trackform": "soft", "parameters": {"pad_stiffness_z": 100e6}}],
}


def _write(tmp_path, line: dict, name: str = "line.json"):
    p = tmp_path / name
    p.write_text(json.dumps(line))
    return p


def _with(**changes) -> dict:
    return json.loads(json.dumps({**GOOD, **changes}))


def _assert_refused(tmp_path, line: dict, *named: str) -> str:
    """Read ``line``; assert a RunFileError starting with the file and naming every one of ``named``."""
    p = _write(tmp_path, line)
    with pytest.raises(RunFileError) as info:
        read_line(p)
    msg = str(info.value)
    assert msg.startswith(f"{p}: "), msg
    for part in named:
        assert part in msg, (part, msg)
    return msg


def test_the_well_formed_line_and_the_virtual_lines_file_read(tmp_path):
    """The base case reads (touching sections and trackforms, welds on l/r/both, notes), and so does every
    ``line.json`` the project writes itself (the virtual line, :func:`lab_data.line.geometry.line_dict`)."""
    from lab_data.line import files
    from lab_data.line.geometry import default_line, line_dict

    ln = read_line(_write(tmp_path, GOOD))
    assert [s.id for s in ln.sections] == ["S1", "S2"] and ln.section_of(300.0) == "S1"
    assert ln.welds == (20.0, 38.0, 700.0) and ln.switches == ((600.0, 640.0),)
    assert [t.trackform.pad_stiffness_z for t in ln.trackforms] == [150e6, 100e6]
    assert ln.curvature(np.array([200.0])) == pytest.approx([-1 / 400])
    virtual = read_line(files.write_json(line_dict(default_line()), tmp_path / "virtual.json"))
    assert len(virtual.sections) == 9 and len(virtual.curves) == 2 and len(virtual.trackforms) == 3


@pytest.mark.parametrize("change, named", [
    (dict(sections=[{"id": "S1", "from_m": 500, "to_m": 100}]), ["section 'S1'", "from_m 500 > to_m 100"]),
    (dict(sections=[{"id": "Z", "from_m": 100, "to_m": 100}]), ["section 'Z'", "zero length"]),
    (dict(curves=[dict(GOOD["curves"][0], from_m=400, to_m=200, transition_in_m=0, transition_out_m=0)]),
     ["curve 'C1'", "from_m 400 > to_m 200"]),
    (dict(curves=[dict(GOOD["curves"][0], to_m=100)]), ["curve 'C1'", "zero length"]),
    (dict(curves=[dict(GOOD["curves"][0], from_m=200, to_m=260, transition_in_m=50, transition_out_m=50)]),
     ["curve 'C1'", "transitions 50 m + 50 m are longer than the curve (200-260 m, 60 m)"]),
    (dict(curves=[dict(GOOD["curves"][0], transition_in_m=-5)]), ["curve 'C1'", "transition_in_m must be >= 0"]),
    (dict(switches=[dict(GOOD["switches"][0], from_m=640, to_m=600)]), ["switch 'W1'", "from_m 640 > to_m 600"]),
    (dict(trackform_sections=[dict(GOOD["trackform_sections"][0], to_m=0)]),
     ["trackform_sections[0] 'slab'", "zero length"]),
])
def test_reversed_or_empty_stretches_and_curves_that_never_reach_their_radius_are_refused(tmp_path, change, named):
    _assert_refused(tmp_path, _with(**change), *named)


def test_overlapping_nested_or_twice_named_sections_are_refused(tmp_path):
    """Nested sections are not supported: the monitoring names a chainage by the section starting last before it
    (``Sections.at``), so the outer section would lose the chainages past the inner one."""
    _assert_refused(tmp_path, _with(sections=[{"id": "A", "from_m": 0, "to_m": 300}, {"id": "B", "from_m": 200,
                                                                               "to_m": 500}]),
             "section 'A' (0-300 m) and section 'B' (200-500 m) overlap")
    _assert_refused(tmp_path, _with(sections=[{"id": "A", "from_m": 0, "to_m": 500}, {"id": "B", "from_m": 100,
                                                                               "to_m": 200}]),
             "section 'A' (0-500 m) and section 'B' (100-200 m) overlap", "nest")
    _assert_refused(tmp_path, _with(sections=[{"id": "A", "from_m": 0, "to_m": 300}, {"id": "A", "from_m": 300,
                                                                               "to_m": 500}]),
             "section id 'A' is given twice (0-300 m and 300-500 m)")
    _assert_refused(tmp_path, _with(curves=[GOOD["curves"][0], dict(GOOD["curves"][0], id="C2", from_m=250, to_m=450)]),
             "curve 'C1' (100-300 m) and curve 'C2' (250-450 m) overlap")


def test_overlapping_trackform_sections_are_refused(tmp_path):
    """``trackform_at`` takes the first section holding a chainage, the estimate's track model the last."""
    tfs = [{"name": "slab", "from_m": 0, "to_m": 500, "support_spacing": 0.6},
           {"name": "ballast", "from_m": 200, "to_m": 300, "support_spacing": 0.65}]
    _assert_refused(tmp_path, _with(trackform_sections=tfs),
             "trackform_sections[0] 'slab' (0-500 m) and trackform_sections[1] 'ballast' (200-300 m) overlap")
    # under the other key the message names that key
    line = {k: v for k, v in GOOD.items() if k != "trackform_sections"}
    _assert_refused(tmp_path, dict(line, trackforms=tfs), "trackforms[0] 'slab'", "trackforms[1] 'ballast'", "overlap")


@pytest.mark.parametrize("entry, named", [
    ({"from_m": 0, "to_m": 1000, "trackform": "slab", "pad_stifness": 1e9},
     ["trackform_sections[0] 'slab'", "unknown key(s) 'pad_stifness'", "did you mean 'pad_stiffness_z'?",
      "pad_stiffness_z, pad_stiffness_y", "from_m, to_m, trackform"]),
    ({"from_m": 0, "to_m": 1000, "trackform": "slab", "parameters": {"supportspacing": 0.6}},
     ["trackform_sections[0] 'slab'", "'parameters.supportspacing'", "did you mean 'support_spacing'?"]),
    ({"from_m": 0, "to_m": 1000, "trackform": "slab", "parameters": [0.6]},
     ["trackform_sections[0] 'slab'", "'parameters' must be an object"]),
    ({"from_m": 0, "to_m": 1000, "trackform": "slab", "pad_stiffness_z": 1e8, "parameters": {"pad_stiffness_z": 2e8}},
     ["trackform_sections[0] 'slab'", "'pad_stiffness_z' given both flat and in 'parameters'"]),
    ({"from_m": 0, "to_m": 1000, "trackform": "slab", "pad_stiffness_z": "stiff"},
     ["trackform_sections[0] 'slab'", "'pad_stiffness_z' must be a number"]),
])
def test_unknown_or_malformed_trackform_fields_are_refused_with_the_valid_names(tmp_path, entry, named):
    msg = _assert_refused(tmp_path, _with(trackform_sections=[entry]), *named)
    assert "<Trackform(...)>" not in msg


@pytest.mark.parametrize("change, named", [
    (dict(curves=[[0, 100, 300, "left"]]), ["curves[0] must be an object", "[0, 100, 300, 'left']"]),
    (dict(sections={"id": "S1", "from_m": 0, "to_m": 1}), ["'sections' must be a list of objects", "an object"]),
    (dict(curves=None), ["'curves' must be a list of objects", "got null"]),
    (dict(welds=[12.5]), ["welds[0] must be an object"]),
    (dict(length_m="12,5"), ["'length_m' must be a number (with a decimal point, not a comma)", "'12,5'"]),
    (dict(length_m=-10), ["'length_m' must be > 0"]),
    (dict(sleeper_spacing_m="0,6"), ["'sleeper_spacing_m' must be a number", "'0,6'"]),
    (dict(sleeper_spacing_m=-0.6), ["'sleeper_spacing_m' must be > 0, got -0.6"]),
    (dict(sleeper_spacing_m=0), ["'sleeper_spacing_m' must be > 0, got 0"]),
    (dict(sleeper_spacing_m=600), ["sleeper spacing 600 m is outside 0.1-5 m"]),
    (dict(sleeper_spacing_m=0.6, sleeper_spacing=0.75), ["both 'sleeper_spacing_m' and 'sleeper_spacing'"]),
    (dict(trackforms=[{"from_m": 0, "to_m": 1}]), ["both 'trackforms' and 'trackform_sections'"]),
    (dict(sections=[{"id": "S1", "from_m": True, "to_m": 100}]), ["section 'S1'", "'from_m' must be a number"]),
    (dict(sections=[{"id": "S1", "to_m": 100}]), ["section 'S1'", "'from_m' is missing"]),
    (dict(balises=[{"id": "B1", "chainage_m": "km 0+050"}]), ["balise 'B1'", "'chainage_m' must be a number"]),
    (dict(format="something-else"), ["format 'something-else'", "'railmodal-line'"]),
    (dict(version=99), ["version 99", "a newer toolkit"]),
    (dict(version="1"), ["version '1'"]),
])
def test_wrong_json_types_and_bad_numbers_are_named(tmp_path, change, named):
    _assert_refused(tmp_path, _with(**change), *named)


def test_a_misspelt_key_is_refused_and_other_unknown_keys_are_named(tmp_path, caplog):
    """``curvse`` would leave the line without its curves (contact angles 0 on every curve, indexes several dB
    off): refused with the key it nearly is. A key unlike any the reader takes is kept and named in a warning;
    an object holding nothing the estimate uses is warned about."""
    line = _with()
    line["curvse"] = line.pop("curves")
    _assert_refused(tmp_path, line, "top-level key 'curvse'", "did you mean 'curves'?")
    line = _with()
    line["trackform_sectons"] = line.pop("trackform_sections")
    _assert_refused(tmp_path, line, "'trackform_sectons'", "did you mean 'trackform_sections'?")
    with caplog.at_level("WARNING", logger="estimator"):
        d = read_line(_write(tmp_path, _with(operator="Metro X", format="railmodal-line", version=1)))
    assert len(d.curves) == 1 and d.raw["operator"] == "Metro X"
    assert "top-level key(s) ['operator'] are not part of a line description" in caplog.text
    caplog.clear()
    with caplog.at_level("WARNING", logger="estimator"):
        read_line(_write(tmp_path, {}, "empty.json"))
    assert "holds none of curves, sections, trackforms" in caplog.text


def test_a_key_given_twice_is_refused(tmp_path):
    """Plain JSON keeps the last of two equal keys: a second ``curves`` would hide the first."""
    text = json.dumps(GOOD)[:-1] + ', "curves": []}'
    p = tmp_path / "line.json"
    p.write_text(text)
    with pytest.raises(RunFileError, match="^" + re.escape(f"{p}: key 'curves' is given twice in one object")):
        read_line(p)


@pytest.mark.parametrize("change, named", [
    (dict(welds=[{"chainage_m": 20.0, "rail": "left"}]), ["welds[0] at 20 m", "'rail' must be 'L' or 'R'", "'left'"]),
    (dict(welds=[{"chainage_m": "20,5", "rail": "L"}]), ["welds[0]", "'chainage_m' must be a number"]),
    (dict(switches=[dict(GOOD["switches"][0], crossing_m="nose")]), ["switch 'W1'", "'crossing_m' must be a number"]),
    (dict(switches=[dict(GOOD["switches"][0], crossing_m=None)]), ["switch 'W1'", "'crossing_m' must be a number"]),
    (dict(switches=[dict(GOOD["switches"][0], crossing_rail="left")]),
     ["switch 'W1'", "'crossing_rail' must be 'L' or 'R'"]),
])
def test_welds_and_crossings_the_alignment_would_skip_are_refused(tmp_path, change, named):
    """The alignment skips a weld on ``"left"`` (it matches neither rail) and a crossing without a numeric
    chainage, and counts a crossing on ``"left"`` on both rails; a rail left out means both."""
    _assert_refused(tmp_path, _with(**change), *named)


@pytest.mark.parametrize("content, named", [
    (b"", "the trolley file is empty"),
    (b"\n\n", "the trolley file is empty"),
    (bytes(range(256)) * 4, "not a text (UTF-8) trolley CSV"),
    (b"chainage_m,rail,roughness_um\n0,L,1\n0.001,L,2,5,6\n", "not a readable trolley CSV"),
], ids=["empty", "blank_lines", "binary", "ragged_row"])
def test_an_empty_or_garbled_trolley_file_is_named(tmp_path, content, named):
    p = tmp_path / "2024-03-04.csv"
    p.write_bytes(content)
    with pytest.raises(RunFileError, match="^" + re.escape(f"{p}: {named}")):
        read_trolley(p)


def test_the_cli_prints_the_named_error_not_a_traceback(tmp_path, capsys):
    """``railmodal field estimate --line`` with a curve given as a bare list: a one-line message, exit 1."""
    from receptance.model_io import save_model
    from railmodal.cli import main
    from test_estimator_io import _channels
    from test_estimator_io import _write as write_run
    from test_estimator_synthetic import control_model, sensor_table

    save_model(control_model(), tmp_path / "m.npz")
    sensor_table().to_csv(tmp_path / "s.csv", index=False)
    run = write_run(tmp_path, "r", _channels(), "csv")
    line = _write(tmp_path, _with(curves=[[0, 100, 300, "left"]]))
    rc = main(["field", "estimate", "--run", str(run), "--sensors", str(tmp_path / "s.csv"), "--model",
               str(tmp_path / "m.npz"), "--line", str(line), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert rc == 1 and "Traceback" not in err
    assert f"{line}: curves[0] must be an object" in err
