"""Hybrid model from a pairing (thesis §2.3, Table 3.1 policy), model files, and the model against the lab.

Oracles: the virtual lab's truth (its modes' FE partners, frequencies and damping, its measured H1)
and the lab's in-service FE model (bounce and roll frequencies).
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

import fem_import
from ema import estimate_frf, read_hammer
from lab_data.cache import campaign_dir
from receptance.compare import compare_frf
from receptance.dofs import read_points
from receptance.hybrid import hybrid_model, read_pairing_table
from receptance.modal_model import ModelError
from receptance.model_io import FORMAT, ModelFileError, load_model, save_model
from receptance.modification import PrimarySuspension


def truth_pairing(manifest, setup="flexural", fe_frequencies=False, fe=None, folder=None) -> pd.DataFrame:
    """The pairing table the truth implies: each elastic truth mode with its design FE partner(s).

    With ``fe`` and ``folder`` (the campaign) a degenerate FE pair gets the combination of its members that
    matches the truth shape at the setup's sensors (``fe_weights``), as ``ema.pair_modes`` reports it.
    """
    rows = []
    design_f = {d["mode"]: d["f_hz"] for d in manifest["design_modes"]}
    sensors = None
    if fe is not None and folder is not None:
        from fem_import.modes import shapes_at_channels

        table = pd.read_csv(folder / f"{setup}_channels.csv")
        acc = table[table["quantity"] == "acceleration"].set_index("node")
        acc = acc.loc[manifest["setups"][setup]["accelerometer_nodes"]].reset_index()
        sensors = shapes_at_channels(fe, acc)
    for k, m in enumerate(manifest["setups"][setup]["modes"]):
        # a rigid-body FE mode is never a test partner (on a rig it becomes a few-Hz suspension mode)
        if m["f_hz"] > 1 and m.get("fe_partner") and min(design_f[j] for j in m["fe_partner"]) > 1:
            f = float(np.mean(fe.freqs_hz[[j - 1 for j in m["fe_partner"]]])) if fe_frequencies else m["f_hz"]
            weights = ""
            if sensors is not None and len(m["fe_partner"]) > 1:
                C = sensors[:, [j - 1 for j in m["fe_partner"]]]
                w, *_ = np.linalg.lstsq(C, np.asarray(m["shapes"], float), rcond=None)
                weights = ";".join(f"{v:.6f}" for v in w / np.linalg.norm(w))
            rows.append({"test_mode": k + 1, "f_test_hz": f, "fe_modes": "+".join(map(str, m["fe_partner"])),
                         "zeta": m["zeta"], "mac": m.get("fe_mac", np.nan), "fe_weights": weights})
        elif m["f_hz"] > 1 and not m.get("fe_partner") and m.get("peak_ratio", 1.0) >= 0.005:
            # a measured mode the FE lacks, visible on some channel (the identification finds it; the pairing
            # lists it test-only)
            rows.append({"test_mode": k + 1, "f_test_hz": m["f_hz"], "fe_modes": "", "zeta": m["zeta"],
                         "mac": np.nan, "fe_weights": ""})
    return pd.DataFrame(rows)


@pytest.fixture(scope="module")
def fe(control_dir):
    return fem_import.read(control_dir / "fe_design.uff")


@pytest.fixture(scope="module")
def points(control_dir):
    return read_points(control_dir / "points.csv")


def test_paired_modes_take_the_test_frequency_and_damping(fe, points):
    # FE modes 8+9 are the first degenerate bending pair (72.6 Hz), 14 the 0-ND wheel mode
    table = pd.DataFrame({"test_mode": [1, 2, 3, np.nan], "f_test_hz": [70.0, 71.0, 210.0, np.nan],
                          "fe_modes": ["8+9", "8+9", "14", "16"], "zeta": [0.001, 0.002, 0.003, np.nan]})
    model = hybrid_model(fe, table, points=points)
    t = model.table.set_index("fe_mode")
    assert list(t.index) == [1, 2, 3, 4, 5, 6, 8, 9, 14]  # rigid modes + paired, FE-only 16 not kept
    assert (t.loc[1:6, "f_hz"] == 0).all() and (t.loc[1:6, "origin"] == "rigid").all()
    assert t.loc[8, "f_hz"] == 70.0 and t.loc[9, "f_hz"] == 71.0  # two partners: frequency order
    assert t.loc[9, "zeta"] == 0.002 and t.loc[14, "zeta"] == 0.003
    assert t.loc[14, "f_fe_hz"] == pytest.approx(213.1, abs=0.1)
    one = hybrid_model(fe, table.iloc[[0, 2]], points=points)
    assert one.table.set_index("fe_mode").loc[[8, 9], "f_hz"].tolist() == [70.0, 70.0]  # axisymmetric twin
    kept = hybrid_model(fe, table, points=points, keep_fe="unpaired", default_zeta=0.004).table.set_index("fe_mode")
    assert kept.loc[16, "f_hz"] == pytest.approx(fe.freqs_hz[15]) and kept.loc[16, "origin"] == "fe"
    assert kept.loc[16, "zeta"] == 0.004
    assert len(hybrid_model(fe, table, keep_fe="all").table) == len(fe)
    assert list(hybrid_model(fe, table, keep_fe=[20]).table["fe_mode"]) == [1, 2, 3, 4, 5, 6, 8, 9, 14, 20]


def test_bad_pairings_are_refused_with_the_reason(fe, tmp_path):
    with pytest.raises(ModelError, match=r"FE mode\(s\) \[99\] not in the FE export"):
        hybrid_model(fe, pd.DataFrame({"test_mode": [1], "f_test_hz": [70.0], "fe_modes": ["99"], "zeta": [0.001]}))
    with pytest.raises(ModelError, match="rigid-body mode"):
        hybrid_model(fe, pd.DataFrame({"test_mode": [1], "f_test_hz": [70.0], "fe_modes": ["2"], "zeta": [0.001]}))
    with pytest.raises(ModelError, match="damping"):
        hybrid_model(fe, pd.DataFrame({"test_mode": [1], "f_test_hz": [70.0], "fe_modes": ["8"], "zeta": [np.nan]}))
    with pytest.raises(ModelError, match="no pairing table"):
        read_pairing_table(tmp_path)
    (tmp_path / "pairing.csv").write_text("a,b\n1,2\n")
    with pytest.raises(ModelError, match="lacks column"):
        read_pairing_table(tmp_path)
    with pytest.raises(ModelError, match="pairs no test mode"):
        hybrid_model(fe, pd.DataFrame({"test_mode": [np.nan], "f_test_hz": [np.nan], "fe_modes": ["8"],
                                       "zeta": [np.nan]}))


def test_in_service_bounce_and_roll_match_the_lab_fe_model(fe, points, control_manifest):
    """Lab FE in service (design wheelset + the same springs, solved on the full mesh): 6.43 and 9.00 Hz."""
    model = hybrid_model(fe, truth_pairing(control_manifest, fe_frequencies=True, fe=fe), points=points,
                         keep_fe="all", default_zeta=0.0)
    modes = model.with_modification(PrimarySuspension()).modes()
    assert modes["f_hz"].iloc[0] == pytest.approx(6.43, abs=0.01)  # bounce
    assert modes["f_hz"].iloc[1] == pytest.approx(9.00, abs=0.01)  # roll
    # the free-free model has no mode below 70 Hz
    assert model.modes()["f_hz"].min() > 70


def test_model_file_round_trip_and_refusals(fe, points, control_manifest, tmp_path):
    from receptance.modal_model import ChannelTerms

    model = hybrid_model(fe, truth_pairing(control_manifest), points=points).with_modification(PrimarySuspension())
    model = model.with_channel_terms(ChannelTerms("residuals", "flexural", {"axle_01": 1e-4}, {"axle_01": 2e-9},
                                                  ((195.0, 0.01, {"axle_01": 3e-3 + 1e-3j}),)))
    path = save_model(model, tmp_path / "m")
    assert path.name == "m.npz"
    back = load_model(path)
    f = np.linspace(1, 500, 300)
    dofs = ["contact_L:z", "axlebox_L:z", "contact_R:y", "axlebox_R:y"]
    np.testing.assert_array_equal(back.receptance(dofs, dofs, f).data, model.receptance(dofs, dofs, f).data)
    assert back.modifications == model.modifications and back.origin == model.origin
    assert back.channel_terms == model.channel_terms
    assert len(back.fe.elements) == len(fe.elements)
    with np.load(path) as z:
        header = json.loads(str(z["header"]))
        arrays = {k: z[k] for k in z.files}
    assert header["format"] == FORMAT and header["version"] == 1
    newer = dict(arrays, header=np.array(json.dumps(dict(header, version=2))))
    np.savez(tmp_path / "newer.npz", **newer)
    with pytest.raises(ModelFileError, match="version 2"):
        load_model(tmp_path / "newer.npz")
    alien = dict(arrays, header=np.array(json.dumps(dict(header, modifications=[{"kind": "flux_capacitor"}]))))
    np.savez(tmp_path / "alien.npz", **alien)
    with pytest.raises(ModelFileError, match="flux_capacitor"):
        load_model(tmp_path / "alien.npz")
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(ModelFileError, match="junk.npz"):
        load_model(tmp_path / "junk.npz")


def _measured(folder, setup):
    test = read_hammer(folder / f"{setup}.uff", folder / f"{setup}_channels.csv")
    return estimate_frf(test), pd.read_csv(folder / f"{setup}_channels.csv")


@pytest.mark.parametrize("setup", ["flexural", "torsional"])
def test_hybrid_model_reproduces_the_measured_frfs_of_the_lab(fe, points, control_dir, control_manifest, setup):
    """Thesis Figs. 3.18–3.19 on the control wheelset (truth = design FE): with the test's frequencies and damping
    the FE shapes reproduce the measured accelerance on every channel within 1 % complex error (noise, the
    out-of-band truncation at 500 Hz); the model must be seen through the measurement's exponential window."""
    H, channels = _measured(control_dir, setup)
    model = hybrid_model(fe, truth_pairing(control_manifest, setup), points=points)
    good = compare_frf(model, H, channels)
    assert good.channels["rel_error"].max() < 0.01
    assert good.channels["frac"].min() > 0.9995
    unwindowed = compare_frf(model, H.with_history("window ignored", exp_window_decay=0.0), channels)
    assert unwindowed.channels["rel_error"].median() > 10 * good.channels["rel_error"].median()


def test_test_frequencies_remove_most_of_the_fe_error_on_an_as_built_wheelset(fe, points):
    """On the as-built 'residual' wheelset (parameters 1-2 % off design) the FE frequencies miss every resonance
    (complex error ~100 %); the hybrid model's test frequencies bring the median below 5 %."""
    folder = campaign_dir("residual")
    manifest = json.loads((folder / "truth.json").read_text())
    H, channels = _measured(folder, "flexural")
    hybrid = compare_frf(hybrid_model(fe, truth_pairing(manifest), points=points), H, channels)
    fe_only = compare_frf(hybrid_model(fe, truth_pairing(manifest, fe_frequencies=True, fe=fe), points=points),
                          H, channels)
    assert fe_only.channels["rel_error"].median() > 0.8
    assert hybrid.channels["rel_error"].median() < 0.05
    assert fe_only.summary_db > hybrid.summary_db


def _every_mode_model(fe, points):
    elastic = np.flatnonzero(fe.freqs_hz > 1.0)
    table = pd.DataFrame({"test_mode": elastic + 1, "f_test_hz": fe.freqs_hz[elastic],
                          "fe_modes": [str(j + 1) for j in elastic], "zeta": 0.0})
    return hybrid_model(fe, table, points=points).with_modification(PrimarySuspension())


def test_in_service_receptances_converge_to_the_full_fe_solution(fe, points, control_dir):
    """The 12 thesis DOFs (Fig. 2.5) of the in-service wheelset against the lab's full FE model solved directly
    (1890 DOFs, suspension springs and dampers, no modal truncation; tests/fe_receptance_oracle.py).

    The modification itself is exact (tests/test_modal_model.py, complete basis); what remains here is the
    truncation of the FE export: the contact points sit on the wheel rims, whose local flexibility lives in
    modes far above 500 Hz. With the 500 Hz export the whole 12x12 matrix is within 2.5 % of its largest entry
    up to 100 Hz; exporting modes to 2 kHz halves the error everywhere (convergence to the oracle)."""
    from fe_receptance_oracle import fe_receptance
    from receptance.dofs import THESIS_DOFS

    dofs = [THESIS_DOFS[k] for k in range(1, 13)]
    f = np.linspace(2.0, 400.0, 67)
    oracle = fe_receptance(control_dir / "points.csv", dofs, f, in_service=True)
    scale = np.abs(oracle).max(axis=(0, 1))

    def worst(model, lo, hi):
        H = model.receptance(dofs, dofs, f).data
        band = (f >= lo) & (f <= hi)
        return float((np.abs(H - oracle) / scale)[:, :, band].max())

    fe_2k = fem_import.read(campaign_dir("control", fe_max_hz=2000.0) / "fe_design.uff")
    m500, m2k = _every_mode_model(fe, points), _every_mode_model(fe_2k, points)
    assert worst(m500, 2, 100) < 0.025
    assert worst(m2k, 2, 100) < 0.6 * worst(m500, 2, 100)
    assert worst(m2k, 300, 400) < 0.6 * worst(m500, 300, 400)


def test_a_model_band_near_the_export_top_is_warned(fe, points, caplog):
    """Local modifications need FE modes above the band: a 500 Hz export for a 500 Hz model is flagged."""
    table = pd.DataFrame({"test_mode": [1.0], "f_test_hz": [213.0], "fe_modes": ["14"], "zeta": [0.001]})
    with caplog.at_level("WARNING", logger="receptance"):
        model = hybrid_model(fe, table, points=points, keep_fe="all", max_hz=500.0)
    assert "stops at 425 Hz" in caplog.text and model.max_hz == 500.0
    caplog.clear()
    with caplog.at_level("WARNING", logger="receptance"):
        hybrid_model(fe, table, points=points, keep_fe="all", max_hz=200.0)
    assert "stops at" not in caplog.text
