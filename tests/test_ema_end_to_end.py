"""Issue 3 end to end through the toolkit's own chain, on every scenario.

read_hammer -> screen -> estimate_frf -> identify, per setup, against the
truth manifest (the acceptance numbers); then merge the two setups and pair
with the design FE export read by fem_import: the pairing reproduces the
truth's pairing. The CLI runs the same chain on one scenario.
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

import ema
import fem_import
from ema.merge import merge_setups
from ema.pairing import pair_modes
from ema.polarity import channel_polarity
from lab_data.cache import campaign_dir
from railmodal.cli import main
from test_ema_identify_support import assert_acceptance, match_to_truth

SCENARIOS = ("control", "residual", "bearing", "rig", "joint", "bearing_rig", "absorber")


def identify_setup(folder, setup):
    test = ema.read_hammer(folder / f"{setup}.uff", folder / f"{setup}_channels.csv")
    frf = ema.estimate_frf(test, band_hz=(10.0, 500.0))
    return ema.identify(frf, band_hz=(10.0, 500.0), max_order=100, setup=setup)


@pytest.mark.slow
@pytest.mark.parametrize("scenario", SCENARIOS)
def test_identify_merge_and_pair_against_truth(scenario):
    folder = campaign_dir(scenario)
    manifest = json.loads((folder / "truth.json").read_text())
    fe = fem_import.read(folder / "fe_design.uff")
    per_setup = {}
    for setup in ("flexural", "torsional"):
        result = identify_setup(folder, setup)
        st = manifest["setups"][setup]
        m = match_to_truth(result.modes, st)
        print(f"\n{scenario}/{setup}: {len(result.modes)} modes; worst |df|/f {100 * m.worst_df:.5f} %, "
              f"|dzeta|/zeta {100 * m.worst_dzeta:.3f} %, MAC {m.worst_mac:.6f}")
        assert_acceptance(m, f"{scenario}/{setup}")
        per_setup[setup] = result.modes

        # pairing of this setup's identified modes reproduces the truth's pairing
        pairing = pair_modes(result.modes, fe)
        # every channel reads with the sign its table gives: none is blamed (tests/test_ema_polarity.py)
        assert not channel_polarity(result.modes, fe, pairing)["suspect"].any()
        got = {p.test_index: {j + 1 for j in p.fe_indices} for p in pairing.pairs}
        truth = [t for t in st["modes"] if t["observable"]]
        for t in truth:
            i = int(np.argmin(np.abs(result.modes.freqs_hz - t["f_hz"])))
            if t["fe_partner"]:
                assert got.get(i) == set(t["fe_partner"]), (
                    f"{scenario}/{setup}: {t['description']} at {t['f_hz']:.2f} Hz: FE {t['fe_partner']} expected, "
                    f"got {got.get(i)}"
                )
            else:
                assert i in pairing.unpaired_test, f"{scenario}/{setup}: {t['description']} wrongly paired"

    merged = merge_setups([per_setup["flexural"], per_setup["torsional"]])
    assert len(merged) <= len(per_setup["flexural"]) + len(per_setup["torsional"])
    pairing = pair_modes(merged, fe)
    assert not channel_polarity(merged, fe, pairing)["suspect"].any()
    # every truth partner of an observable mode appears in the merged pairing
    wanted = {tuple(sorted(t["fe_partner"])) for s in manifest["setups"].values() for t in s["modes"]
              if t["observable"] and t["fe_partner"]}
    got = {tuple(sorted(j + 1 for j in p.fe_indices)) for p in pairing.pairs}
    assert wanted <= got


@pytest.mark.slow
def test_another_acquisition_rate_is_identified_to_the_same_acceptance():
    """A lab whose front end samples at 8192 Hz (a power-of-two rate) with 5 hits: the flexural setup's modes meet
    the acceptance of the 12.8 kHz campaigns (measured: |df|/f 3e-6, |dzeta|/zeta 0.07 %, MAC 0.99994; at
    25.6 kHz the same within 2e-6, 0.14 %, 0.99999). Nothing in the chain assumes the virtual lab's rate."""
    folder = campaign_dir("control", fs=8192.0, n_hits=5)
    manifest = json.loads((folder / "truth.json").read_text())
    test = ema.read_hammer(folder / "flexural.uff", folder / "flexural_channels.csv")
    assert test.fs == pytest.approx(8192.0)
    result = identify_setup(folder, "flexural")
    assert_acceptance(match_to_truth(result.modes, manifest["setups"]["flexural"]), "8192 Hz/flexural")


@pytest.mark.slow
def test_cli_identify_and_pair(tmp_path):
    folder = campaign_dir("control")
    out = {}
    for setup in ("flexural", "torsional"):
        out[setup] = tmp_path / setup
        assert main(["-q", "lab", "identify", "--hammer", str(folder / f"{setup}.uff"), "--channels",
                     str(folder / f"{setup}_channels.csv"), "--out", str(out[setup])]) == 0
        modes = pd.read_csv(out[setup] / "modes.csv")
        assert {"f_hz", "zeta", "mpc", "setup"} <= set(modes.columns)
        assert (out[setup] / "stabilisation.png").stat().st_size > 10_000
        assert (out[setup] / "modes.uff").exists()
    pair_dir = tmp_path / "pairing"
    assert main(["-q", "lab", "pair", "--modes", str(out["flexural"]), "--modes", str(out["torsional"]),
                 "--fem", str(folder / "fe_design.uff"), "--out", str(pair_dir)]) == 0
    table = pd.read_csv(pair_dir / "pairing.csv")
    polarity = pd.read_csv(pair_dir / "channel_polarity.csv")
    assert len(polarity) > 29 and not polarity["suspect"].any()  # both setups' channels, none blamed
    assert {"f_test_hz", "f_fe_hz", "df_pct", "zeta", "mac", "description"} <= set(table.columns)
    paired = table.dropna(subset=["f_test_hz", "f_fe_hz"])
    # control: the test frequencies are the FE ones (truth = design) and every paired MAC is high
    assert np.all(np.abs(paired["df_pct"]) < 0.05)
    assert np.all(paired["mac"] > 0.99)
    # FE-only modes are listed, not dropped: the 2-nodal-diameter wheel modes no hit can excite
    assert (table["description"].str.startswith("FE only") & (table["f_fe_hz"].round(0) == 416)).sum() == 4
    assert len(list(pair_dir.glob("pair_*.png"))) == len(paired)
    # ... and on to the hybrid model (issue 4): the identified pairing builds a model that reproduces the
    # measured FRFs of both setups and sits on its suspension at the lab FE's bounce and roll frequencies
    model_dir = tmp_path / "model"
    args = ["-q", "model", "build", "--pairing", str(pair_dir), "--fem", str(folder / "fe_design.uff"),
            "--points", str(folder / "points.csv"), "--robustness-models", "10", "--out", str(model_dir)]
    for setup in ("flexural", "torsional"):
        args += ["--hammer", str(folder / f"{setup}.uff"), "--channels", str(folder / f"{setup}_channels.csv")]
    assert main(args) == 0
    system = pd.read_csv(model_dir / "system_modes.csv")
    # lab FE (full mesh): 6.4305 and 9.0032 Hz; the hybrid model keeps only the paired modes (thesis policy)
    np.testing.assert_allclose(system["f_hz"].iloc[:2], [6.4305, 9.0032], rtol=3e-3)
    for setup in ("flexural", "torsional"):
        validation = pd.read_csv(model_dir / f"validation_{setup}.csv")
        assert validation["rel_error"].max() < 0.02, validation.sort_values("rel_error").tail(3)


def test_cli_identify_reports_bad_input(tmp_path, capsys):
    folder = campaign_dir("control")
    bad = tmp_path / "cut.uff"
    bad.write_bytes((folder / "flexural.uff").read_bytes()[:100_000])
    code = main(["-q", "lab", "identify", "--hammer", str(bad), "--channels", str(folder / "flexural_channels.csv"),
                 "--out", str(tmp_path / "o")])
    assert code == 1
    err = capsys.readouterr().err
    assert "cut.uff" in err and "Traceback" not in err
