"""The transfer-function memo: bounded in bytes, least recently used evicted first, and never a different number.

Oracles: the store's byte count against the arrays put in; an estimate made with a memo too small to keep
anything between its stages equals, to the bit, the one made with everything kept; runs whose keys are their
own (a wheelbase each) leave the store within its budget however many there are.
"""

from __future__ import annotations

import pickle
from dataclasses import dataclass

import numpy as np
import pytest

from test_estimator_synthetic import control_model, make_run, sensor_table

from estimator import EstimatorConfig, estimate_run, prepare
from estimator import memo as memo_mod
from estimator.memo import Memo, nbytes, set_budget, store_stats


@pytest.fixture
def budget():
    """Restore the process's budget after a test changes it."""
    before = store_stats()["budget"]
    yield set_budget
    set_budget(before)


def test_entries_beyond_the_budget_go_least_recently_used_first(budget):
    budget(10 * 8000)
    m = Memo()
    for k in range(10):
        m[k] = np.zeros(1000)  # 8000 bytes each: exactly the budget
    assert len(m) == 10
    _ = m[0]  # used again: now the most recent
    m["new"] = np.zeros(1000)
    assert 0 in m and 1 not in m and "new" in m  # the oldest unused one went, not the one just read
    assert store_stats()["bytes"] <= 10 * 8000
    m["big"] = np.zeros(100_000)  # alone above the budget: kept (it is about to be used), everything else goes
    assert "big" in m and len(m) == 1 and m["big"].size == 100_000
    # the keys evicted are forgotten too: a long batch's per-run keys do not pile up beside the store
    store = memo_mod._store()
    assert sum(len(k) for k in store.keys.values()) == len(store.entries)
    with pytest.raises(KeyError):
        _ = m[0]


def test_a_memo_is_a_mapping_whose_namespace_is_its_own(budget):
    budget(2**30)
    a, b = Memo({"x": np.ones(3)}), Memo()
    assert "x" in a and "x" not in b and a.get("x").sum() == 3.0 and b.get("x") is None
    b["x"] = 5
    assert a["x"].size == 3 and b["x"] == 5
    del a["x"]
    assert "x" not in a and b["x"] == 5 and sorted(b) == ["x"]
    # a field model sent to a Dask worker carries no entries: the worker computes and bounds its own
    assert len(pickle.loads(pickle.dumps(b))) == 0


def test_nbytes_counts_the_arrays_inside_containers_and_dataclasses():
    from ema.frf import FrequencyResponse

    @dataclass(frozen=True)
    class Transfer:
        T: np.ndarray
        f: np.ndarray
        sides: tuple

    assert nbytes(Transfer(np.zeros((2, 3, 100), complex), np.zeros(100), ("L", "R"))) == 2 * 3 * 100 * 16 + 800
    frf = FrequencyResponse(np.arange(1.0, 11.0), np.zeros((1, 1, 10), complex), ("a",), ("b",), "receptance")
    assert nbytes(frf) >= 10 * 16
    assert nbytes([np.zeros(10), (np.zeros(5), {"a": np.zeros(2)})]) == 8 * 17
    assert nbytes("a note") == 0


def test_a_budget_in_the_environment_is_read_and_a_bad_one_named(monkeypatch):
    monkeypatch.setattr(memo_mod, "_STORE", None)
    monkeypatch.setenv("RAILMODAL_MEMO_MB", "12.5")
    assert store_stats()["budget"] == int(12.5 * 2**20)
    monkeypatch.setattr(memo_mod, "_STORE", None)
    monkeypatch.setenv("RAILMODAL_MEMO_MB", "lots")
    with pytest.raises(ValueError, match="RAILMODAL_MEMO_MB.*'lots'"):
        store_stats()
    # monkeypatch puts the process's own store back afterwards


@pytest.fixture(scope="module")
def synthetic_run(tmp_path_factory):
    d = tmp_path_factory.mktemp("memo")
    return make_run(d, control_model(), duration_s=20.0, name="memo_run")


def test_an_estimate_with_a_memo_that_keeps_nothing_equals_the_one_that_keeps_everything(synthetic_run, budget):
    """Each memoised value depends on its key alone, so recomputing it after eviction changes no number."""
    cfg = EstimatorConfig(wheelbase_m=2.2)
    budget(2**30)
    full = estimate_run(synthetic_run.path, prepare(control_model(), sensor_table(), config=cfg))
    budget(1)  # every entry evicted by the next one
    evicted = store_stats()["evicted"]
    starved = estimate_run(synthetic_run.path, prepare(control_model(), sensor_table(), config=cfg))
    assert store_stats()["evicted"] > evicted
    assert full.profiles.keys() == starved.profiles.keys()
    for k, p in full.profiles.items():
        np.testing.assert_array_equal(p.rail, starved.profiles[k].rail)
    np.testing.assert_array_equal(full.indexes["median_pk_pk_um"].to_numpy(), starved.indexes["median_pk_pk_um"])


def test_runs_with_keys_of_their_own_leave_the_store_within_its_budget(synthetic_run, budget):
    """Each run's wheelset distance is its own coupling key (a measured wheelbase differs from run to run): with
    an unbounded memo every run added its couplings for good."""
    fm = prepare(control_model(), sensor_table(), config=EstimatorConfig(wheelbase_m=2.2))
    budget(2**30)
    estimate_run(synthetic_run.path, fm)
    one_run = store_stats()["bytes"]
    assert one_run > 0
    cap = int(1.5 * one_run)
    budget(cap)
    evicted = store_stats()["evicted"]
    for wb in (2.1, 2.15, 2.25, 2.3):
        fm = prepare(control_model(), sensor_table(), config=EstimatorConfig(wheelbase_m=wb))
        estimate_run(synthetic_run.path, fm)
        assert store_stats()["bytes"] <= cap
    assert store_stats()["evicted"] > evicted


def test_a_budget_below_what_the_runs_reuse_is_counted_and_said_once(monkeypatch, caplog):
    """A cycle longer than the store (the uncertainty variants, run after run) makes LRU evict each entry just
    before its next use: every key comes back. The store counts those refaults and warns once."""
    monkeypatch.setattr(memo_mod, "_STORE", memo_mod._Store(10 * 8000))
    monkeypatch.setattr(memo_mod, "REFAULT_WARNING", 15)
    m = Memo()
    with caplog.at_level("WARNING", logger="estimator"):
        for k in range(12):  # 12 entries of 8000 bytes in a store of 10: the first two go
            m[k] = np.zeros(1000)
        assert store_stats()["refaults"] == 0 and 0 not in m
        for _ in range(2):  # the same cycle again: each key was evicted before it came back
            for k in range(12):
                if k not in m:
                    m[k] = np.zeros(1000)
        # LRU at its worst: in each later cycle every key was evicted by the put before it, so all 12 come back
        assert store_stats()["refaults"] == 24
        said = [r.getMessage() for r in caplog.records if "RAILMODAL_MEMO_MB" in r.getMessage()]
        assert len(said) == 1 and "budget (0 MB)" in said[0] and "24 entries" not in said[0]  # said at the 15th
        m["fresh"] = np.zeros(1000)  # a key never evicted is no refault
    assert store_stats()["refaults"] == 24
