"""The uncertainty variants' estimates: only what they are read for, the same numbers, and one copy of the track.

Oracles: the full single-run estimate of the same accelerations (a variant's band peak-to-peak per window must
equal it to the bit), and the count of track receptances and rail couplings in the process's memo (one per
trackform and coupling key, however many variants of the wheelset model use them).
"""

from __future__ import annotations

from collections import Counter

import numpy as np
import pandas as pd
import pytest

from test_estimator_synthetic import control_model, make_run, sensor_table

from estimator import EstimatorConfig, estimate_run, prepare, read_run
from estimator.memo import set_budget, store_stats
from estimator.monitoring import MonitoringConfig
from estimator.monitoring.records import window_table
from estimator.monitoring.variants import perturbed_variants, placement_variants, variant_windows
from estimator.workflow import TRACK_MEMO

CFG = EstimatorConfig(wheelbase_m=2.2)
MON = MonitoringConfig(n_perturbed=2, placement_shifts_mm=(30.0,), placement_axes=("y",))


@pytest.fixture(scope="module")
def field(tmp_path_factory):
    d = tmp_path_factory.mktemp("variants")
    sr = make_run(d, control_model(), duration_s=20.0, name="variant_run")
    fm = prepare(control_model(), sensor_table(), config=CFG)
    return fm, read_run(sr.path, fm.sensors)


def test_an_estimate_of_the_indexes_only_has_the_full_estimates_profiles_to_the_bit(field):
    fm, run = field
    full = estimate_run(run, fm)
    lean = estimate_run(run, fm, indexes_only=True)
    assert full.profiles.keys() == lean.profiles.keys() and len(full.profiles) == 6
    for k, p in full.profiles.items():
        q = lean.profiles[k]
        np.testing.assert_array_equal(p.rail, q.rail)
        np.testing.assert_array_equal(p.indexes.pk_pk, q.indexes.pk_pk)
        np.testing.assert_array_equal(p.chainage_m, q.chainage_m)
    # the stretch tables are what it leaves out
    assert len(full.indexes) and len(full.spectra) and lean.indexes.empty and lean.spectra.empty
    assert lean.corrugation.empty and list(lean.corrugation.columns) == list(full.corrugation.columns)
    # the window table without the rails' cross-correlation: the same levels, the correlation left NaN
    a = window_table(full, "vertical_lateral", None, 1.0)
    b = window_table(lean, "vertical_lateral", None, 1.0, lr_correlation=False)
    pd.testing.assert_frame_equal(a.drop(columns="lr_correlation"), b.drop(columns="lr_correlation"))
    assert a["lr_correlation"].notna().any() and b["lr_correlation"].isna().all()


def test_variant_windows_equal_those_of_full_estimates_of_each_variant(field):
    fm, run = field
    vs = perturbed_variants(fm, MON) + placement_variants(fm, MON)
    assert len(vs) == 4
    got, problems = variant_windows(run, vs, None, MON)
    assert problems == []
    for v in vs:
        want = window_table(estimate_run(v.applied_to(run), v.field_model), MON.model, None, MON.window_m)
        mine = got[got["variant"] == v.label].drop(columns=["source", "variant"]).reset_index(drop=True)
        pd.testing.assert_frame_equal(want.drop(columns="lr_correlation"), mine.drop(columns="lr_correlation"),
                                      check_exact=True)
    # and a perturbed model is a different estimate (the comparison above is not of one model with itself)
    per = got[got["source"] == "model"].pivot_table(index=["wheelset", "rail", "band_mm", "window_m"],
                                                    columns="variant", values="pk_pk_um")
    assert (per.iloc[:, 0] - per.iloc[:, 1]).abs().max() > 1e-3


def test_variants_of_one_wheelset_model_share_the_tracks_receptance_and_coupling(field):
    """Before, each variant's memo held its own copy of every trackform's receptance and of every rail coupling
    (52 of each on the monitoring's default set), which took one uncertainty run past the memo's budget."""
    fm, run = field
    set_budget(2**30)
    before = store_stats()["evicted"]
    estimate_run(run, fm)
    shared = Counter(k[0] for k in TRACK_MEMO)
    assert shared["track"] >= 1 and shared["C"] >= 1
    vs = perturbed_variants(fm, MON) + placement_variants(fm, MON)
    for v in vs:
        estimate_run(v.applied_to(run), v.field_model, indexes_only=True)
        assert not any(k[0] in ("track", "C") for k in v.field_model.cache)
        assert any(k[0] == "T" for k in v.field_model.cache)  # the wheelset's transfer functions are its own
    assert Counter(k[0] for k in TRACK_MEMO) == shared  # nothing added: every variant found the nominal model's
    assert store_stats()["evicted"] == before  # (not because something was evicted in between)
