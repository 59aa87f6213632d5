"""The measured modal constants against the FE's (receptance.diagnosis.scale).

Oracle: the virtual lab's ``control`` campaign, whose truth is its design FE, so the measured constants equal the
FE's (ratio 1 within the identification's accuracy); the same FE with its shapes scaled the way a non-normalised
export is (a factor ``k`` on every shape makes the FE's constants ``k²`` larger), and the same table with the
hammer's direction reversed (the ratio changes sign).
"""

from __future__ import annotations

import logging

import numpy as np
import pytest

import ema
import fem_import
from fem_import.modes import FEModes
from lab_data.cache import campaign_dir
from receptance.diagnosis import DiagnosisError
from receptance.diagnosis.scale import MAX_RATIO, check_modal_scale, modal_scale


@pytest.fixture(scope="module")
def control():
    logging.disable(logging.WARNING)
    try:
        d = campaign_dir("control")
        fe = fem_import.read(d / "fe_design.uff")
        table = ema.read_channels(d / "torsional_channels.csv")
        test = ema.read_hammer(d / "torsional.uff", table)
        modes = ema.identify(ema.estimate_frf(test, screening=ema.screen_hits(test)), setup="torsional").modes
    finally:
        logging.disable(logging.NOTSET)
    return fe, table, modes


def _scaled(fe: FEModes, k: float) -> FEModes:
    return FEModes(fe.node_ids, fe.xyz, fe.elements, fe.freqs_hz, k * fe.shapes, fe.modal_mass, source="scaled.uff")


def test_measured_constants_equal_the_fes_when_the_truth_is_the_design(control):
    fe, table, modes = control
    scale = modal_scale(modes, fe, table, setup="torsional")
    assert scale.n_modes >= 6 and scale.ratio == pytest.approx(1.0, abs=0.01)
    good = scale.table[scale.table["weight"] > 0]
    np.testing.assert_allclose(good["ratio"], 1.0, atol=0.02)
    assert scale.table["weight"].sum() == pytest.approx(1.0)
    check_modal_scale(scale)


@pytest.mark.parametrize("k", [0.5, 2.0, 1e-3 ** 0.5])  # a factor 4 either way; mm read as m on the shapes' scale
def test_shapes_that_are_not_mass_normalised_are_refused(control, k):
    fe, table, modes = control
    scale = modal_scale(modes, _scaled(fe, k), table, setup="torsional")
    assert scale.ratio == pytest.approx(1 / k ** 2, rel=0.02)
    with pytest.raises(DiagnosisError, match=r"setup 'torsional' \(t.uff\): the measured modal constants are .* times "
                                             r"the FE's \(scaled.uff\).*mass-normalised in SI units"):
        check_modal_scale(scale, fem="scaled.uff", measurement="t.uff")


def test_a_factor_within_what_effects_do_passes(control):
    fe, table, modes = control
    k = (0.9 * MAX_RATIO) ** -0.5  # the measured constants 0.9 × MAX_RATIO the FE's
    check_modal_scale(modal_scale(modes, _scaled(fe, k), table, setup="torsional"))


def test_a_reversed_hammer_direction_is_named(control):
    fe, table, modes = control
    flipped = table.copy()
    force = flipped["quantity"] == "force"
    flipped.loc[force, ["dx", "dy", "dz"]] = -flipped.loc[force, ["dx", "dy", "dz"]]
    scale = modal_scale(modes, fe, flipped, setup="torsional")
    assert scale.ratio == pytest.approx(-1.0, abs=0.01)
    with pytest.raises(DiagnosisError, match="of the other sign, so the hammer's measuring direction"):
        check_modal_scale(scale)


def test_modes_scaled_otherwise_are_not_judged(control):
    from dataclasses import replace

    fe, table, modes = control
    assert modal_scale(replace(modes, scaling="unit"), fe, table) is None
    assert modal_scale(modes, fe, table[table["quantity"] != "force"]) is None
