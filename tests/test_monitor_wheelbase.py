"""A bogie's wheelbase shared between its runs (estimator.monitoring.wheelbase and ingest's retry).

Oracles: the median of the confidently measured values (closed form), the refusal of a bogie whose measurements
do not describe one dimension, and — through ingest on a store — a run whose own measurement is refused being
processed again with its bogie's wheelbase, the source stated in its row.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from estimator.monitoring.wheelbase import MAX_SPREAD_M, BogieWheelbase, bogie_key, is_wheelbase_failure, \
    known_wheelbases


def _rows(values, sources, train="T1", bogie="B1"):
    return pd.DataFrame({"run_id": [f"r{i}" for i in range(len(values))], "train": train, "bogie": bogie,
                         "wheelbase_m": values, "wheelbase_source": sources})


def test_the_bogie_wheelbase_is_the_median_of_its_confident_measurements_only():
    rows = pd.concat([
        _rows([2.101, 2.099, 2.100, 2.140], ["measured (lead/trail cross-correlation 0.6)"] * 3 + ["given"]),
        _rows([2.500], ["measured (lead/trail cross-correlation 0.7)"], bogie="B2"),
        # a fallback row is not a measurement: it must not count (it would feed itself)
        _rows([9.0], ["bogie T1 / B1: median of 3 run(s) measured in this batch and store"], bogie="B3"),
    ], ignore_index=True).assign(run_id=lambda d: [f"x{i}" for i in range(len(d))])
    kb = known_wheelbases(rows)
    assert set(kb) == {("T1", "B1"), ("T1", "B2")}
    assert kb[("T1", "B1")].wheelbase_m == pytest.approx(2.100, abs=1e-12)
    assert kb[("T1", "B1")].runs == 3 and kb[("T1", "B1")].spread_m == pytest.approx(0.002, abs=1e-12)
    assert kb[("T1", "B2")].wheelbase_m == 2.5
    assert "median of 3 run(s)" in kb[("T1", "B1")].source and "2.100 m" in kb[("T1", "B1")].source


def test_measurements_that_scatter_beyond_one_dimension_give_no_fallback():
    good = "measured (lead/trail cross-correlation 0.6)"
    kb = known_wheelbases(_rows([2.10, 2.10 + 1.5 * MAX_SPREAD_M], [good, good]))
    assert kb == {}
    kb = known_wheelbases(_rows([2.10, 2.10 + 0.5 * MAX_SPREAD_M], [good, good]))
    assert kb[("T1", "B1")].wheelbase_m == pytest.approx(2.10 + 0.25 * MAX_SPREAD_M)
    assert known_wheelbases(pd.DataFrame()) == {}
    # rows of an older store (no source column): nothing known
    assert known_wheelbases(_rows([2.1], [good]).drop(columns=["wheelbase_source"])) == {}


def test_only_a_refused_wheelbase_measurement_is_retried():
    assert is_wheelbase_failure("WheelbaseError")
    assert not is_wheelbase_failure("NoValidDataError") and not is_wheelbase_failure("")
    assert bogie_key({"train": "Meneghino 805", "bogie": "car 2"}) == ("Meneghino 805", "car 2")
    assert bogie_key({}) == ("", "")


def test_ingest_retries_a_refused_run_with_its_bogies_wheelbase(tmp_path):
    from estimator.monitoring.store import MonitoringStore
    from estimator.monitoring.workflow import RunResult, wheelbase_retries

    good = "measured (lead/trail cross-correlation 0.6)"
    ok = RunResult("a.mf4", "a", "2024-03-04", "VL1", True, tables={"runs": _rows([2.1], [good]).assign(run_id="a")})
    ok2 = RunResult("b.mf4", "b", "2024-03-04", "VL1", True,
                    tables={"runs": _rows([2.1004], [good]).assign(run_id="b")})
    bad = RunResult("c.mf4", "c", "2024-03-04", "VL1", False,
                    "c.mf4: the wheelbase could not be measured from the data (lead/trail correlation 0.10 < 0.3)",
                    error_type="WheelbaseError")
    other_bogie = RunResult("d.mf4", "d", "2024-03-04", "VL1", False,
                            "d.mf4: the wheelbase could not be measured from the data (lead/trail correlation 0.1)",
                            error_type="WheelbaseError")
    broken = RunResult("e.mf4", "e", "2024-03-04", "VL1", False, "e.mf4: not an MDF 4 file", error_type="RunFileError")
    headers = {p: {"train": "T1", "bogie": "B1", "date": "2024-03-04"} for p in ("a.mf4", "b.mf4", "c.mf4", "e.mf4")}
    headers["d.mf4"] = {"train": "T1", "bogie": "B9", "date": "2024-03-04"}
    res = {r.path: r for r in (ok, ok2, bad, other_bogie, broken)}
    out = wheelbase_retries(res, headers, MonitoringStore(tmp_path / "store"), "m1")
    assert set(out) == {"c.mf4"}
    assert isinstance(out["c.mf4"], BogieWheelbase)
    assert out["c.mf4"].wheelbase_m == pytest.approx(np.median([2.1, 2.1004]), abs=1e-12)
