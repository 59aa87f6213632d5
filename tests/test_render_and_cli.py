"""Pictures of the wheelset and the command line."""

import json
import subprocess
import sys

import numpy as np
import pytest

from lab_data.plot import render_wheelset, wheelset_polydata
from lab_data.truth import design_modes
from lab_data.wheelset import WheelsetParameters
from railmodal.cli import main


@pytest.fixture(scope="module")
def design():
    return design_modes(WheelsetParameters(), 500.0)


def test_mesh_looks_like_a_wheelset(design):
    mesh = wheelset_polydata(design.model)
    x0, x1, y0, y1, z0, z1 = mesh.bounds
    p = WheelsetParameters()
    # the wheels span the rim diameter; the axleboxes close the journals' ends
    assert z1 - z0 == pytest.approx(2 * p.rim_radius, rel=1e-6)
    assert y1 - y0 == pytest.approx(2 * (p.axlebox_y + p.axlebox_half_size[1]), rel=1e-6)
    assert p.axlebox_y + p.axlebox_half_size[1] > p.axle_half_length
    assert mesh.n_cells > 1000
    assert mesh.n_lines >= 2 * p.n_theta  # rims and axle as beams


def test_render_writes_a_picture_with_content(tmp_path, design):
    from PIL import Image

    i = next(k for k, lab in enumerate(design.labels) if lab.family == "torsion")
    path = render_wheelset(design.model, tmp_path / "mode.png", shape=design.modes.shapes[i], title="torsion")
    img = np.asarray(Image.open(path).convert("L"), float)
    assert img.shape == (800, 1200)
    # a white background with a sizeable non-white object in it
    assert 0.05 < np.mean(img < 250) < 0.8


def test_shape_of_wrong_size_is_refused(design):
    with pytest.raises(ValueError, match="shape must have shape"):
        wheelset_polydata(design.model, np.zeros((3, 6)), 1.0)


def test_cli_simulate_writes_the_campaign(tmp_path, capsys):
    assert main(["-q", "lab", "simulate", "--scenario", "rig", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "flexural_uff" in out and "observable" in out
    manifest = json.loads((tmp_path / "truth.json").read_text())
    assert manifest["scenario"]["name"] == "rig"


def test_cli_rejects_unknown_scenario(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "railmodal.cli", "lab", "simulate", "--scenario", "nope", "--out", str(tmp_path)],
        capture_output=True, text=True,
    )
    assert proc.returncode == 2
    assert "invalid choice: 'nope'" in proc.stderr


def test_cli_reports_errors_without_a_traceback(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    # an --out that cannot be created is refused when the command line is parsed (exit 2), naming the file
    with pytest.raises(SystemExit) as exc:
        main(["-q", "lab", "simulate", "--scenario", "control", "--out", str(blocker / "sub")])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and "error: argument --out" in err and str(blocker) in err and "Traceback" not in err
    assert not (blocker.parent / "sub").exists()


def test_an_unforeseen_error_type_reaches_the_user_as_one_line(monkeypatch, capsys):
    """An exception the toolkit did not name (a TypeError deep in a library, say) is one 'railmodal: error:' line
    naming its type, exit 1, never a traceback; -v shows the traceback for a report."""
    import railmodal.cli as cli

    def boom(args):
        raise TypeError("unsupported operand type(s) for +: 'NoneType' and 'int'")

    monkeypatch.setattr(cli, "_cmd_scenarios", boom)  # bound when the parser is built, below
    assert cli.main(["-q", "lab", "scenarios"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("railmodal: error: unexpected TypeError: unsupported operand")
    assert "Traceback" not in err and "-v" in err
    assert cli.main(["-v", "lab", "scenarios"]) == 1
    assert "Traceback" in capsys.readouterr().err


def test_cli_simulates_another_wheelset_design(tmp_path, capsys):
    """``--design``: the light metro wheelset's campaign; its FE weighs what that design's parts weigh (axle, two
    wheels, two discs, two axleboxes: 890 kg), so the campaign is not the thesis's
    wheelset renamed. A truncation next to one of the design's modes is refused, naming it."""
    import fem_import
    from fem_import.checks import rigid_body_mass
    from lab_data.designs import get_design

    assert main(["-q", "lab", "simulate", "--scenario", "control", "--design", "metro", "--out",
                 str(tmp_path / "metro")]) == 0
    p = get_design("metro")
    parts = p.axle_mass + 2 * (p.wheel_mass + p.disc_mass + p.axlebox_mass)
    m = rigid_body_mass(fem_import.read(tmp_path / "metro" / "fe_design.uff"))
    assert m is not None and m.mass == pytest.approx(parts, rel=0.01)
    capsys.readouterr()
    # the freight design has four modes at 2017.7 Hz: an export cut at 2000 Hz would split them
    assert main(["-q", "lab", "simulate", "--scenario", "control", "--design", "freight", "--fe-export-hz", "2000",
                 "--out", str(tmp_path / "freight")]) != 0
    err = capsys.readouterr().err
    assert "2000" in err and "gap of the spectrum" in err and "Traceback" not in err
    assert not (tmp_path / "freight").exists()
