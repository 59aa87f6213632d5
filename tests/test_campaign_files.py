"""The files of a virtual campaign: H1 fidelity against the truth, pyuff read-back, hit defects, determinism."""

import hashlib
import json

import numpy as np
import pandas as pd
import pytest
import pyuff
from scipy.ndimage import maximum_filter1d

from lab_data.campaign import CampaignConfig, plan_campaign, write_campaign
from lab_data.hammer import analytic_accelerance, synthesize_hit
from lab_data.scenarios import get_scenario

FS = 12800.0


def h1_windowed(t, force, acc, t0, decay):
    """H1 of one record with the same exponential window on force and response (exact for the truth's poles)."""
    w = np.where(t >= t0, np.exp(-decay * (t - t0)), 1.0)
    F = np.fft.rfft(force * w)
    A = np.fft.rfft(acc * w, axis=-1)
    return np.fft.rfftfreq(len(t), 1 / FS), A * np.conj(F) / np.abs(F) ** 2


@pytest.mark.parametrize("scenario", ["control", "residual"])
@pytest.mark.parametrize("setup", ["flexural", "torsional"])
@pytest.mark.parametrize("hit_index", [0, 2])  # a single hit and the double hit
def test_noise_free_h1_matches_truth_accelerance_within_0_2_db(plans, scenario, setup, hit_index):
    plan = plans(scenario)
    hit = plan.hits[setup][hit_index]
    assert hit.double == (hit_index == 2)
    t, force, acc = synthesize_hit(plan.modal[setup], hit.pulses, fs=FS, duration=plan.config.duration)
    # the lightest damping (0.011 % at 415 Hz) rings past the 4 s record: an exponential window
    # with the same decay on force and response shifts every pole by `decay`, exactly
    decay = 2.5
    f, H1 = h1_windowed(t, force, acc, hit.pulses[0].t0, decay)
    band = (f >= 10.0) & (f <= 500.0)
    truth = analytic_accelerance(plan.modal[setup], f[band], decay=decay)
    mag = 20 * np.log10(np.abs(truth))
    # away from antiresonances: more than 20 dB below the largest value within +-5 Hz
    keep = mag >= maximum_filter1d(mag, size=41, axis=1) - 20.0
    assert keep.mean() > 0.8
    err_db = 20 * np.log10(np.abs(H1[:, band]) / np.abs(truth))
    err_deg = np.degrees(np.abs(np.angle(H1[:, band] / truth)))
    assert np.max(np.abs(err_db[keep])) < 0.2
    assert np.max(err_deg[keep]) < 1.0


def test_fe_export_reads_back_with_pyuff(control_dir, control_manifest):
    sets = pyuff.UFF(str(control_dir / "fe_design.uff")).read_sets()
    types = [s["type"] for s in sets]
    assert types[:3] == [164, 2411, 2412]
    modes = [s for s in sets if s["type"] == 55]
    expected = [m["f_hz"] for m in control_manifest["design_modes"]]
    assert len(modes) == len(expected)
    np.testing.assert_allclose([m["freq"] for m in modes], expected, rtol=1e-6, atol=1e-6)
    assert sum(f < 0.01 for f in expected) == 6  # rigid-body modes exported
    nodes = sets[1]["node_nums"].astype(int)
    assert len(nodes) == len(modes[0]["node_nums"])
    # six DOF per node, mass-normalised shapes: the axlebox centre carries 78 kg of the z translation
    for key in ("r1", "r2", "r3", "r4", "r5", "r6"):
        assert np.all(np.isfinite(modes[0][key]))
    elements = sets[2]
    assert {21, 94, 161} <= set(k for k in elements if isinstance(k, int))
    table = pd.read_csv(control_dir / "flexural_channels.csv")
    assert set(table["fe_node"]) <= set(nodes)


def test_punch_file_carries_the_same_modes(control_dir, control_manifest):
    text = (control_dir / "fe_design.pch").read_text().splitlines()
    assert all(len(line) <= 80 for line in text)
    eig = [float(line.split("=")[1].split()[0]) for line in text if line.startswith("$EIGENVALUE")]
    f = np.sqrt(np.clip(eig, 0, None)) / (2 * np.pi)
    expected = [m["f_hz"] for m in control_manifest["design_modes"]]
    np.testing.assert_allclose(f, expected, rtol=1e-6, atol=1e-3)


@pytest.mark.parametrize("setup", ["flexural", "torsional"])
def test_hammer_file_reads_back_and_matches_channel_table(control_dir, control_manifest, setup):
    table = pd.read_csv(control_dir / f"{setup}_channels.csv")
    assert list(table.columns) == ["node", "name", "quantity", "unit", "x", "y", "z", "dx", "dy", "dz", "fe_node",
                                   "setup"]
    assert (table["quantity"] == "force").sum() == 1 and (table["quantity"] == "acceleration").sum() == 29
    np.testing.assert_allclose(np.linalg.norm(table[["dx", "dy", "dz"]].to_numpy(), axis=1), 1.0, rtol=1e-12)
    sets = pyuff.UFF(str(control_dir / f"{setup}.uff")).read_sets()
    assert len(sets) == 30 * len(control_manifest["setups"][setup]["hits"])
    assert all(s["type"] == 58 and s["func_type"] == 1 and s["binary"] == 1 for s in sets)
    for hit in range(1, 7):
        in_hit = [s for s in sets if s["ver_num"] == hit]
        assert sorted(int(s["rsp_node"]) for s in in_hit) == sorted(table["node"])
    assert all(len(s["data"]) == 51200 and s["abscissa_inc"] == pytest.approx(1 / FS, rel=1e-6) for s in sets)
    # pre-trigger: nothing happens before the hit (noise only)
    force = [s for s in sets if int(s["rsp_node"]) == 900]
    for s in force:
        assert np.max(np.abs(s["data"][: int(0.09 * FS)])) < 1.0
        assert np.max(s["data"]) > 500.0


def _pulses(force, threshold):
    above = np.abs(force) > threshold
    return int(np.sum(above[1:] & ~above[:-1]))


@pytest.mark.parametrize("setup", ["flexural", "torsional"])
def test_double_hit_and_clipped_channel_are_where_the_manifest_says(control_dir, control_manifest, setup):
    info = control_manifest["setups"][setup]
    assert info["double_hits"] == [3]
    assert len(info["clipped"]) == 1 and info["clipped"][0]["hit"] == 5
    sets = pyuff.UFF(str(control_dir / f"{setup}.uff")).read_sets()
    for s in sets:
        node, hit, data = int(s["rsp_node"]), int(s["ver_num"]), s["data"]
        if node == 900:
            n = _pulses(data, 0.05 * np.max(np.abs(data)))
            assert n == (2 if hit in info["double_hits"] else 1), f"hit {hit} shows {n} force pulses"
            continue
        full_scale = info["ranges_m_per_s2"][str(node)]
        at_limit = np.abs(np.abs(data) - full_scale) <= 1e-6 * full_scale
        flat = int(np.max(np.convolve(at_limit, np.ones(3, int), mode="valid"))) == 3
        assert flat == ({"hit": hit, "node": node} in info["clipped"]), f"hit {hit} node {node}"


def test_points_table(control_dir):
    points = pd.read_csv(control_dir / "points.csv")
    assert list(points.columns) == ["name", "fe_node", "x", "y", "z"]
    assert list(points["name"]) == ["contact_L", "axlebox_L", "contact_R", "axlebox_R"]
    contact = points.set_index("name").loc["contact_L"]
    assert contact["y"] == pytest.approx(-0.75) and contact["z"] == pytest.approx(-0.41)


def test_manifest_truth_and_pairing_in_control(control_manifest):
    for setup in ("flexural", "torsional"):
        modes = control_manifest["setups"][setup]["modes"]
        for m in modes:
            assert m["fe_partner"], f"control truth mode {m['description']} has no FE partner"
            assert m["fe_mac"] > 0.999
            assert 1e-4 <= m["zeta"] <= 5e-3 or m["family"] == "rigid"
            assert len(m["shapes"]) == 29
    seen = {s: {m["description"] for m in control_manifest["setups"][s]["modes"] if m["observable"]}
            for s in ("flexural", "torsional")}
    assert {"1st flexural (z)", "2nd flexural (z)", "3rd flexural (z)", "4th flexural (z)"} <= seen["flexural"]
    assert {"1st torsion", "2nd torsion", "3rd torsion"} <= seen["torsional"]
    assert not any("torsion" in d for d in seen["flexural"])  # a radial hit through the axis gives no torque


def test_campaign_is_deterministic(tmp_path):
    plan = plan_campaign(CampaignConfig(scenario="joint"))
    digests = []
    for k in range(2):
        files = write_campaign(plan_campaign(CampaignConfig(scenario="joint")), tmp_path / str(k), progress=lambda m: None)
        digests.append({key: hashlib.sha256(p.read_bytes()).hexdigest() for key, p in files.items()})
    assert digests[0] == digests[1]
    assert plan.hits == plan_campaign(CampaignConfig(scenario="joint")).hits
    other = plan_campaign(CampaignConfig(scenario="joint", seed=7))
    assert other.hits != plan.hits


def test_bad_configuration_is_refused_with_a_clear_message():
    with pytest.raises(KeyError, match="unknown scenario 'nope'.*control"):
        get_scenario("nope")
    with pytest.raises(ValueError, match="n_hits must be >= 5"):
        CampaignConfig(n_hits=3)
    with pytest.raises(ValueError, match="different hits"):
        CampaignConfig(double_hit=5, overload_hit=5)
    with pytest.raises(ValueError, match="duration"):
        CampaignConfig(duration=2.0)
    # an export frequency right on a mode would split a cluster between truth and export
    with pytest.raises(ValueError, match="truncation frequency 424.6"):
        plan_campaign(CampaignConfig(fe_max_hz=424.6))
    with pytest.raises(ValueError, match="fe_export_hz .* must be >= fe_max_hz"):
        CampaignConfig(fe_export_hz=400.0)
    with pytest.raises(ValueError, match="hammer_scatter_deg must be within 0-20 degrees, got -1"):
        CampaignConfig(hammer_scatter_deg=-1.0)


def test_a_tilted_blow_excites_the_modes_its_direction_projects_on():
    """tilted_direction turns the hammer's direction by the angles asked (towards the axle raises its axial
    component; about that plane leaves it but for the cosine), and hit_truth's participations are the force point's modal displacement
    along the tilted direction: the sum of its components along x, y and z weighted by the direction's."""
    from dataclasses import replace

    from lab_data.campaign import hit_truth
    from lab_data.sensors import shape_matrix, tilted_direction

    plan = plan_campaign(CampaignConfig())
    hit = plan.hits["flexural"][0]
    assert hit.tilt_deg == (0.0, 0.0) and hit_truth(plan, "flexural", hit) is plan.modal["flexural"]
    force = plan.setups["flexural"].force
    d0 = np.array(force.direction)
    towards = np.array(tilted_direction(d0, 5.0, 0.0))
    about = np.array(tilted_direction(d0, 0.0, 5.0))
    assert np.degrees(np.arccos(towards @ d0)) == pytest.approx(5.0, abs=1e-6) and towards[1] > d0[1]
    # about the axle-ward plane: the turn is normal to it, so the axial component only shrinks with the cosine
    assert np.degrees(np.arccos(about @ d0)) == pytest.approx(5.0, abs=1e-6)
    assert about[1] == pytest.approx(d0[1] * np.cos(np.radians(5.0)), rel=1e-12)
    d = np.array(tilted_direction(d0, 5.0, -3.0))
    b = hit_truth(plan, "flexural", replace(hit, tilt_deg=(5.0, -3.0))).input_shape
    xyz = shape_matrix(plan.truth.model, plan.views["flexural"].shapes_full, [force.fe_node] * 3,
                       [force.position] * 3, list(np.eye(3)))
    np.testing.assert_allclose(b, d @ xyz, rtol=1e-9, atol=1e-12 * np.abs(b).max())
    np.testing.assert_allclose(plan.modal["flexural"].input_shape, d0 @ xyz, rtol=1e-9,
                               atol=1e-12 * np.abs(b).max())


def test_a_richer_fe_export_leaves_the_truth_in_the_band():
    """fe_export_hz=2000: the design export holds the modes to 2 kHz (a basis for structural modifications),
    the truth and its test still stop at 500 Hz, and the exported modes below 500 Hz are the default ones."""
    rich = plan_campaign(CampaignConfig(scenario="bearing", fe_export_hz=2000.0))
    plain = plan_campaign(CampaignConfig(scenario="bearing"))
    assert rich.export_freqs_hz.max() <= 2000.0 and rich.export_freqs_hz.max() > 1500.0
    assert plain.export_freqs_hz.max() <= 500.0
    n = plain.export_freqs_hz.size
    np.testing.assert_allclose(rich.export_freqs_hz[:n], plain.export_freqs_hz, rtol=1e-9)
    assert rich.export_freqs_hz[n] > 500.0
    np.testing.assert_allclose(rich.truth.modes.freqs_hz, plain.truth.modes.freqs_hz, rtol=1e-9)
    assert rich.truth.modes.freqs_hz.max() <= 500.0


def test_manifest_is_plain_json(control_dir):
    manifest = json.loads((control_dir / "truth.json").read_text())
    assert manifest["format"] == "railmodal-virtual-lab-truth"
    assert manifest["scenario"]["name"] == "control"
    assert set(manifest["files"]) >= {"fe_uff", "fe_punch", "points", "flexural_uff", "torsional_uff"}
