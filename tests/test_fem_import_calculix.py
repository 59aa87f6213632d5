"""The CalculiX result reader (:mod:`fem_import.calculix_frd`) on files CalculiX 2.20 wrote.

``tests/data/calculix`` holds the decks (``make_bar.py`` writes them) and the gzipped ``.frd`` files ``ccx`` wrote
from them: a free steel bar 30 x 20 x 400 mm of 48 C3D20 bricks (12 modes, 6 of them rigid-body), and a coarser
bar solved free (8 modes) and then clamped at z = 0 (4 modes). The oracles are closed forms of the bar: its mass
1.884 kg, centre and inertia from the rigid-body modes of mass-normalised shapes, the bending frequencies of a
Timoshenko beam, and the clamped bar's of a cantilever.
"""

from __future__ import annotations

import gzip
import logging
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import fem_import
from fem_import.calculix_frd import sniff_frd

DATA = Path(__file__).parent / "data" / "calculix"
A, B, L, E, NU, RHO = 0.03, 0.02, 0.40, 210e9, 0.3, 7850.0
MASS = A * B * L * RHO


def _unzip(name: str, folder: Path) -> Path:
    path = folder / f"{name}.frd"
    path.write_bytes(gzip.decompress((DATA / f"{name}.frd.gz").read_bytes()))
    return path


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("frd")
    return {name: _unzip(name, folder) for name in ("bar", "bar_two_steps")}


@pytest.fixture(scope="module")
def bar(files):
    return fem_import.read(files["bar"])


def _bending(beta_l: float, width: float, depth: float) -> float:
    """Bending frequency [Hz] about the axis across ``depth``: Euler-Bernoulli ``beta^2/(2 pi L^2) sqrt(EI/rho A)``
    lowered by shear and rotary inertia to first order, ``1 - (beta r / L)^2 (1 + E / (kappa G)) / 2`` (a
    rectangle's kappa = 10 (1 + nu) / (12 + 11 nu))."""
    area, inertia = width * depth, width * depth ** 3 / 12
    kappa, shear = 10 * (1 + NU) / (12 + 11 * NU), E / (2 * (1 + NU))
    euler = beta_l ** 2 / (2 * math.pi * L ** 2) * math.sqrt(E * inertia / (RHO * area))
    r = math.sqrt(inertia / area)
    return euler * (1 - 0.5 * (beta_l * r / L) ** 2 * (1 + E / (kappa * shear)))


def test_the_bar_is_sniffed_and_read_with_its_mesh(bar, files):
    assert fem_import.detect_format(files["bar"]).name == "calculix-frd"
    assert bar.format == "calculix-frd" and len(bar) == 12 and bar.shapes.shape == (12, 381, 3)
    assert bar.mode_numbers.tolist() == list(range(1, 13))
    np.testing.assert_allclose(bar.xyz.max(axis=0) - bar.xyz.min(axis=0), [A, B, L], rtol=1e-6)
    assert len(bar.elements) == 48 and {e.fe_descriptor for e in bar.elements} == {115}
    assert "assumed" in bar.units  # a .frd states no units


def test_mass_normalised_shapes_give_the_bar_s_mass_centre_and_inertia(bar):
    """The six rigid-body modes of unit-modal-mass shapes carry the bar's mass (1.884 kg, to the .frd's six
    digits: 1e-5), its centre (15, 10, 200) mm and its inertia about the centre, ``m (b^2 + L^2) / 12`` and the
    like, products of inertia zero (to 1e-6 of the largest moment, the six digits again)."""
    rb = fem_import.check_mass_normalisation(bar, total_mass=MASS, rtol=1e-5)
    assert rb.modes == (1, 2, 3, 4, 5, 6)
    np.testing.assert_allclose(rb.masses, MASS, rtol=1e-5)
    np.testing.assert_allclose(rb.centre, [A / 2, B / 2, L / 2], atol=1e-6)
    expected = MASS / 12 * np.diag([B ** 2 + L ** 2, A ** 2 + L ** 2, A ** 2 + B ** 2])
    np.testing.assert_allclose(rb.inertia, expected, rtol=1e-4, atol=1e-6 * expected.max())


def test_the_first_bending_modes_are_the_timoshenko_bar_s(bar):
    """Free-free, beta L = 4.730: 658.2 Hz across the 20 mm depth and 975.4 Hz across the 30 mm width (the
    first-order shear correction lowers Euler-Bernoulli's 664.6 and 996.9 Hz by 1 and 2 %); the file's 659.24 and
    977.88 Hz are within 0.5 % (the mesh and the first-order correction)."""
    elastic = bar.freqs_hz[6:8]
    np.testing.assert_allclose(elastic, [_bending(4.730, A, B), _bending(4.730, B, A)], rtol=5e-3)


def test_a_generalized_mass_other_than_one_is_divided_out(files, bar, tmp_path):
    """Mode 7 written with its shape doubled and ``1PGM 4.0`` reads back as the unit-mass shape."""
    lines = files["bar"].read_text().split("\n")
    start = next(i for i, t in enumerate(lines) if t.startswith("    1PMODE") and int(t.split()[1]) == 7)
    for i in range(start - 6, start):
        if lines[i].startswith("    1PGM"):
            lines[i] = lines[i][:24] + "4.000000E+00" + lines[i][36:]
    i = next(k for k in range(start, len(lines)) if lines[k].startswith(" -4  DISP"))
    i += 1
    while lines[i][:3] == " -5":
        i += 1
    while lines[i][:3] == " -1":
        values = [2 * float(lines[i][13 + 12 * k:25 + 12 * k]) for k in range(3)]
        lines[i] = lines[i][:13] + "".join(f"{v:12.5E}" for v in values)
        i += 1
    path = tmp_path / "scaled.frd"
    path.write_text("\n".join(lines))
    scaled = fem_import.read(path)
    np.testing.assert_allclose(scaled.shapes, bar.shapes, atol=1e-5 * np.abs(bar.shapes).max())
    assert any("1PGM" in h and "mode 7 m=4" in h for h in scaled.history)


def test_two_frequency_steps_need_a_choice(files, caplog):
    """Step 1 free (8 modes), step 2 clamped at z = 0 (4 modes): ``read`` refuses to guess; ``subcase=2`` gives
    the cantilever, beta L = 1.875 (within 3 %: 6 bricks along the bar, and the clamp holds the end face's
    Poisson contraction); the command line's route reads the lowest with a WARNING."""
    with pytest.raises(fem_import.FEReadError, match=r"2 frequency steps \(\[1, 2\]\); choose one"):
        fem_import.read(files["bar_two_steps"])
    clamped = fem_import.read(files["bar_two_steps"], subcase=2)
    assert len(clamped) == 4
    np.testing.assert_allclose(clamped.freqs_hz[:2], [_bending(1.875, A, B), _bending(1.875, B, A)], rtol=0.03)
    with caplog.at_level(logging.WARNING, logger="fem_import"):
        free, note = fem_import.read_with_geometry(files["bar_two_steps"])
    assert len(free) == 8 and "reading the lowest, 1" in caplog.text and "beam" not in note
    with pytest.raises(fem_import.FEReadError, match=r"no frequency step 3"):
        fem_import.read(files["bar_two_steps"], subcase=3)


@pytest.mark.parametrize("edit, match", [
    (lambda t: t.replace(t[t.index("    1PGK"):t.index(" -5  D2")], "", 1), "outside a block"),
    (lambda t: t[:len(t) // 2], "cut short"),
    (lambda t: t[:t.rindex(" 9999")], "9999"),
    (lambda t: t.replace("    1PHID                         -1", "    1PHID                          2", 1),
     "cyclic-symmetry"),
    (lambda t: t.replace(" -4  DISP ", " -4  DISPI", 1), "complex modes"),
    (lambda t: t.replace("\n -1        17 0.00000E+00", "\n -1        17 0.0000xE+00", 1), "not a number"),
    (lambda t: t.replace("    2C                            80", "    2C                            81", 1),
     "holds 80 nodes, its header says 81"),
])
def test_damaged_files_are_refused_by_line(files, tmp_path, edit, match):
    text = files["bar_two_steps"].read_text()
    damaged = edit(text)
    assert damaged != text
    path = tmp_path / "damaged.frd"
    path.write_text(damaged)
    with pytest.raises(fem_import.FEReadError, match=match) as err:
        fem_import.read(path, subcase=1)
    assert "damaged.frd" in str(err.value)


@settings(max_examples=60, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow,
                                                                                  HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_fuzzed_files_read_whole_or_are_refused(files, tmp_path, data):
    """Cut at any byte, a byte changed or a run of bytes lost anywhere: the modes of the file, or a FEReadError /
    UnknownFormatError; never another exception, and never fewer modes than the file has (a lost mode header
    leaves its records outside any block, or a gap in the mode numbers: both refused)."""
    raw = files["bar_two_steps"].read_bytes()
    how = data.draw(st.sampled_from(["cut", "change", "lose"]))
    k = data.draw(st.integers(0, len(raw) - 1))
    if how == "cut":
        raw = raw[:k]
    elif how == "change":
        raw = raw[:k] + bytes([data.draw(st.integers(32, 126))]) + raw[k + 1:]
    else:
        raw = raw[:k] + raw[k + data.draw(st.integers(1, 400)):]
    path = tmp_path / "fuzz.frd"
    path.write_bytes(raw)
    try:
        fe = fem_import.read(path, format="calculix-frd", subcase=1)
    except (fem_import.FEReadError, fem_import.UnknownFormatError):
        return
    assert len(fe) == 8


def test_other_files_are_not_taken_for_results():
    assert sniff_frd(b"    1C\n    1UPGM               CalculiX\n") is True
    assert sniff_frd(b"    -1\n  2411\n") is False
    assert sniff_frd(b"$TITLE   = bar\n") is False
    assert sniff_frd(b"") is False


def test_a_clamped_step_is_refused_as_a_wheelset_model_with_the_calculix_advice(files):
    """The clamped bar's modes (no rigid-body mode) cannot make a free wheelset's model: refused, saying how to
    export from 0 Hz in CalculiX's terms too; the free step's six rigid-body modes pass the same check."""
    from fem_import.checks import MassNormalisationError
    from receptance.hybrid import check_fe_for_model

    clamped = fem_import.read(files["bar_two_steps"], subcase=2)
    with pytest.raises(MassNormalisationError, match=r"holds no rigid-body modes .*CalculiX \*FREQUENCY without a "
                                                     r"lower bound"):
        check_fe_for_model(clamped, total_mass=MASS)
    free = fem_import.read(files["bar_two_steps"], subcase=1)
    assert check_fe_for_model(free, total_mass=MASS).mass == pytest.approx(MASS, rel=1e-5)


def _write_frd(path, fe, short=False):
    """``fe``'s translations as CalculiX writes a *FREQUENCY step (CGX long format, or the short one: node and
    element numbers in 5 columns, format flag 0; E12.5 values); beams and shells as be2 / tr3 / qu4 elements;
    masses and rigid elements, which CalculiX has no result element for, left out. Written from the CGX manual's
    record layout, apart from the reader."""
    cgx = {21: 11, 91: 7, 94: 9}
    w, flag = (5, 0) if short else (10, 1)
    lines = ["    1C", "    1UPGM               CalculiX", f"    2C{fe.node_ids.size:>30d}{'':37s}{flag}"]
    lines += [f" -1{n:{w}d}" + "".join(f"{v:12.5E}" for v in p) for n, p in zip(fe.node_ids, fe.xyz)]
    lines.append(" -3")
    kept = [e for e in fe.elements if e.fe_descriptor in cgx and len(e.nodes) == {21: 2, 91: 3, 94: 4}[e.fe_descriptor]]
    lines.append(f"    3C{len(kept):>30d}{'':37s}{flag}")
    for e in kept:
        lines.append(f" -1{e.element_id:{w}d}{cgx[e.fe_descriptor]:5d}{0:5d}{1:5d}")
        lines.append(" -2" + "".join(f"{n:{w}d}" for n in e.nodes))
    lines.append(" -3")
    for k, f in enumerate(fe.freqs_hz):
        lines += [f"    1PSTEP{k + 1:>26d}{1:>12d}{1:>12d}", f"    1PGM                {1.0:12.6E}",
                  f"    1PHID{-1:>30d}", f"    1PMODE{k + 1:>25d}",
                  f"  100CL{101 + k:5d}{f:12.5E}{fe.node_ids.size:12d}{'':20s} 2{k + 1:5d}MODAL     {flag:2d}",
                  " -4  DISP        4    1", " -5  D1          1    2    1    0", " -5  D2          1    2    2    0",
                  " -5  D3          1    2    3    0", " -5  ALL         1    2    0    0    1ALL"]
        u = np.where(np.abs(fe.shapes[k, :, :3]) < 1e-90, 0.0, fe.shapes[k, :, :3])
        lines += [f" -1{n:{w}d}" + "".join(f"{v:12.5E}" for v in row) for n, row in zip(fe.node_ids, u)]
        lines.append(" -3")
    lines.append(" 9999")
    path.write_text("\n".join(lines) + "\n")
    return path, kept


def test_the_lab_design_export_as_a_calculix_file_reads_back_to_six_digits(tmp_path):
    """The virtual lab's design wheelset (the campaign's UFF export: shell webs and discs, beam axle and rims,
    25 modes with degenerate pairs) written as a CalculiX result: the same nodes and elements, the frequencies and
    translations to the format's six digits, the same rigid-body mass, and the same shapes at the campaign's
    sensors on their nodes (what pairing by MAC uses) to 1e-5 of each mode's largest translation; a sensor off its
    beam node is refused by name, as for any export without rotations."""
    import pandas as pd

    from lab_data.cache import campaign_dir

    folder = campaign_dir("control")
    uff = fem_import.read(folder / "fe_design.uff")
    path, kept = _write_frd(tmp_path / "design.frd", uff)
    frd = fem_import.read(path)
    assert frd.format == "calculix-frd" and len(frd) == len(uff) and np.array_equal(frd.node_ids, uff.node_ids)
    assert [(e.element_id, e.fe_descriptor, e.nodes) for e in frd.elements] == [
        (e.element_id, e.fe_descriptor, e.nodes) for e in kept]
    np.testing.assert_allclose(frd.freqs_hz, uff.freqs_hz, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(frd.xyz, uff.xyz, rtol=1e-5, atol=1e-9)
    scale = np.abs(uff.shapes[:, :, :3]).max(axis=(1, 2))
    assert np.all(np.abs(frd.shapes - uff.shapes[:, :, :3]).max(axis=(1, 2)) <= 1e-5 * scale)  # 1.2e-6 measured
    np.testing.assert_allclose(fem_import.rigid_body_mass(frd).mass, fem_import.rigid_body_mass(uff).mass, rtol=1e-5)
    channels = pd.read_csv(folder / "flexural_channels.csv")
    # an axle sensor sits 74 mm off its beam node: a file of translations cannot carry the motion the node's
    # rotation gives it there, and says so; the sensors on (or within 5 cm of) their nodes read the same
    with pytest.raises(fem_import.PointToleranceError, match=r"the shapes have no rotations \(3 DOF per node\)"):
        fem_import.shapes_at_channels(frd, channels)
    node_xyz = dict(zip(uff.node_ids.tolist(), uff.xyz))
    near = channels[[np.linalg.norm(np.array([r.x, r.y, r.z]) - node_xyz[int(r.fe_node)]) <= 0.05
                     for r in channels.itertuples()]]
    assert 5 <= (near["quantity"] == "acceleration").sum() < (channels["quantity"] == "acceleration").sum()
    a = fem_import.shapes_at_channels(uff, near)
    b = fem_import.shapes_at_channels(frd, near)
    # to 1e-5 of each mode's largest translation (1.1e-6 measured): a sensor's reading d . u of a mode that barely
    # moves it is the difference of larger components, each to six digits
    assert np.all(np.abs(b - a).max(axis=0) <= 1e-5 * scale)
    # the short format (5-column numbers, as CGX writes models whose numbers fit) reads the same
    short = fem_import.read(_write_frd(tmp_path / "short.frd", uff, short=True)[0])
    assert np.array_equal(short.node_ids, frd.node_ids) and short.elements == frd.elements
    np.testing.assert_array_equal(short.shapes, frd.shapes)
    np.testing.assert_array_equal(short.xyz, frd.xyz)
