"""Merging setups and pairing test modes with the design FE export, against the lab truth's pairing.

The test modes here are the truth's own modes at the sensors (from the
manifest), so these tests check merging and pairing alone; the end-to-end
tests pair the *identified* modes.
"""

import json

import numpy as np
import pandas as pd
import pytest

import fem_import
from ema.merge import merge_setups
from ema.modeset import ModeSet
from ema.pairing import fe_clusters, mac_matrix, pair_modes
from lab_data.cache import campaign_dir


def truth_modeset(folder, setup, *, observable_only=True, phase_noise=0.0, seed=0):
    manifest = json.loads((folder / "truth.json").read_text())
    table = pd.read_csv(folder / f"{setup}_channels.csv")
    acc = table[table["quantity"] == "acceleration"].reset_index(drop=True)
    modes = [m for m in manifest["setups"][setup]["modes"] if (m["observable"] or not observable_only)
             and 10 <= m["f_hz"] <= 500]
    rng = np.random.default_rng(seed)
    shapes = np.array([m["shapes"] for m in modes]).T.astype(complex)
    # a little complexity, as identified shapes of a lightly damped structure have
    shapes = shapes * np.exp(1j * phase_noise * rng.standard_normal(shapes.shape))
    ms = ModeSet(
        freqs_hz=np.array([m["f_hz"] for m in modes]),
        zeta=np.array([m["zeta"] for m in modes]),
        shapes=shapes,
        dofs=tuple(acc["name"]),
        channels=acc,
        mpc=np.ones(len(modes)),
        mpd=np.zeros(len(modes)),
        setup=(setup,) * len(modes),
    )
    return ms, modes


def test_mac_matrix_basics():
    rng = np.random.default_rng(1)
    a = rng.standard_normal((20, 3))
    m = mac_matrix(a, a)
    np.testing.assert_allclose(np.diag(m), 1.0)
    assert mac_matrix(a[:, :1], 3.7j * a[:, :1])[0, 0] == pytest.approx(1.0)
    b = a.copy()
    b[2, 0] = np.nan  # an unmeasured DOF is left out, not propagated
    assert np.isfinite(mac_matrix(b, a)).all()


def test_fe_clusters_group_repeated_eigenvalues():
    f = np.array([0, 0, 0, 71.5, 72.57, 72.57000001, 129.4, 415.5, 415.5, 415.5, 415.5])
    c = fe_clusters(f)
    assert [len(x) for x in c] == [3, 1, 2, 1, 4]


@pytest.mark.parametrize("scenario", ["control", "bearing", "joint", "rig", "residual", "absorber", "bearing_rig"])
def test_pairing_reproduces_the_truth_pairing(scenario):
    folder = campaign_dir(scenario)
    fe = fem_import.read(folder / "fe_design.uff")
    for setup in ("flexural", "torsional"):
        test, truth = truth_modeset(folder, setup, phase_noise=0.02, seed=hash(scenario) % 1000)
        pairing = pair_modes(test, fe)
        got = {p.test_index: set(j + 1 for j in p.fe_indices) for p in pairing.pairs}
        for i, m in enumerate(truth):
            if m["fe_partner"]:
                assert got.get(i) == set(m["fe_partner"]), (
                    f"{scenario}/{setup}: truth mode {m['description']} at {m['f_hz']:.2f} Hz should pair with "
                    f"FE {m['fe_partner']}, got {got.get(i)}"
                )
            else:
                assert i in pairing.unpaired_test, (
                    f"{scenario}/{setup}: {m['description']} at {m['f_hz']:.2f} Hz has no FE partner in the truth "
                    f"but was paired with {got.get(i)}"
                )
        # every listed mode appears in the table, paired or not
        assert len(pairing.table) == len(pairing.pairs) + len(pairing.unpaired_test) + len(pairing.unpaired_fe)


def test_degenerate_fe_pair_is_rotated_to_the_test_shape():
    folder = campaign_dir("control")
    fe = fem_import.read(folder / "fe_design.uff")
    test, truth = truth_modeset(folder, "flexural")
    pairing = pair_modes(test, fe)
    for p in pairing.pairs:
        if len(p.fe_indices) == 2:
            # the best combination of the arbitrary FE basis matches the test shape, plain MACs need not
            assert p.mac > 0.999
            fe_at = fem_import.shapes_at_channels(
                fem_import.FEModes(fe.node_ids, fe.xyz, fe.elements, np.array([1.0]), p.fe_shape[None], np.ones(1)),
                test.channels,
            )
            assert mac_matrix(test.shapes[:, [p.test_index]], fe_at)[0, 0] > 0.999


def test_merging_the_two_setups():
    folder = campaign_dir("control")
    flex, tf = truth_modeset(folder, "flexural")
    tors, tt = truth_modeset(folder, "torsional")
    merged = merge_setups([flex, tors])
    # the 2nd wheel (0 nodal diameters) mode shows on the shared axlebox channels in both setups: one mode
    both = [m["f_hz"] for m in tf if any(abs(m["f_hz"] - n["f_hz"]) < 1e-6 for n in tt)]
    for f in both:
        hits = np.flatnonzero(np.abs(merged.freqs_hz - f) < 1e-6 * f)
        assert len(hits) >= 1
    assert len(merged) < len(flex) + len(tors)
    # DOFs: 29 + 29 minus the 4 shared axlebox channels
    assert merged.shapes.shape[0] == 54
    # a degenerate bending pair: each setup's hammer excites its own member (z in the flexural
    # setup, an oblique mix in the torsional one, since the tilted tangential hit also tilts the
    # disc); the shared axlebox channels see the same z component, so the pair is listed once
    f3 = [m["f_hz"] for m in tf if m["description"] == "3rd flexural (z)"][0]
    assert np.sum(np.abs(merged.freqs_hz - f3) < 1e-6 * f3) == 1
    # torsion is invisible to the flexural setup and to the axlebox channels: kept from the torsional setup
    f_t1 = [m["f_hz"] for m in tt if m["description"] == "1st torsion"][0]
    k = int(np.argmin(np.abs(merged.freqs_hz - f_t1)))
    assert merged.setup[k] == "torsional"
    assert np.isnan(merged.shapes[:25, k]).all() or np.isnan(merged.shapes[:, k]).sum() == 25
    # the merged set still pairs with the FE export
    fe = fem_import.read(folder / "fe_design.uff")
    pairing = pair_modes(merged, fe)
    assert not pairing.unpaired_test
