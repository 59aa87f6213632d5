"""The monitoring store: idempotent re-ingest, versions side by side, a crash mid-write, concurrent writers, readers.

Each test counts rows against the exact set written: a lost or a duplicated
row fails it.
"""

from __future__ import annotations

import multiprocessing as mp
import os

import numpy as np
import pandas as pd
import pytest

from estimator.monitoring.errors import StoreError
from estimator.monitoring.store import MonitoringStore


def run_tables(run_id: str, date: str, sections=("s1", "s2"), n=50, value=1.0, model="m1") -> dict:
    """Rows of one run: ``n`` windows per section in ``windows``, one QC row per section in ``runs``."""
    w = []
    for k, s in enumerate(sections):
        w.append(pd.DataFrame({"run_id": run_id, "window_m": 100.0 * k + np.arange(n), "pk_pk_um": value,
                               "section": s, "date": date, "model_hash": model, "toolkit_version": "t"}))
    runs = pd.DataFrame({"run_id": run_id, "section": list(sections), "date": date, "model_hash": model,
                         "model_file": "m.npz", "toolkit_version": "t", "processed_at": "x"})
    return {"windows": pd.concat(w, ignore_index=True), "runs": runs}


def test_re_ingest_replaces_rows_and_never_duplicates(tmp_path):
    st = MonitoringStore(tmp_path / "store")
    st.write("line1", "r1", "m1", run_tables("r1", "2024-03-04"))
    st.write("line1", "r2", "m1", run_tables("r2", "2024-03-04"))
    st.write("line1", "r1", "m1", run_tables("r1", "2024-03-04", value=2.0))  # re-processed
    w = st.read("windows")
    assert len(w) == 200
    assert set(w.loc[w["run_id"] == "r1", "pk_pk_um"]) == {2.0}
    assert not w.duplicated(["run_id", "section", "window_m"]).any()
    # the re-processed run now covers one section only: its rows in the other section go
    st.write("line1", "r1", "m1", run_tables("r1", "2024-03-04", sections=("s1",), value=3.0))
    w = st.read("windows")
    assert len(w[w["run_id"] == "r1"]) == 50 and len(w) == 150
    assert not (tmp_path / "store" / "windows" / "line=line1" / "section=s2" / "date=2024-03-04" /
                "r1__m1.parquet").exists()


def test_two_model_versions_side_by_side(tmp_path):
    st = MonitoringStore(tmp_path / "store")
    st.write("line1", "r1", "m1", run_tables("r1", "2024-03-04", model="m1"))
    st.write("line1", "r1", "m2", run_tables("r1", "2024-03-04", model="m2", value=5.0))
    assert len(st.read("windows")) == 200
    assert set(st.read("windows", model_hash="m2")["pk_pk_um"]) == {5.0}
    assert list(st.model_versions()["model_hash"]) == ["m1", "m2"]


def test_a_crash_mid_write_leaves_the_store_readable_with_no_partial_or_duplicate_rows(tmp_path, monkeypatch):
    st = MonitoringStore(tmp_path / "store")
    st.write("line1", "r1", "m1", run_tables("r1", "2024-03-04", value=1.0))
    real = os.replace
    calls = {"n": 0}

    def dying_replace(a, b):
        calls["n"] += 1
        if calls["n"] == 2:  # the first partition file is renamed, then the writer dies
            raise KeyboardInterrupt("power cut")
        return real(a, b)

    monkeypatch.setattr(os, "replace", dying_replace)
    with pytest.raises(KeyboardInterrupt):
        st.write("line1", "r1", "m1", run_tables("r1", "2024-03-04", value=2.0))
    monkeypatch.setattr(os, "replace", real)
    w = MonitoringStore(tmp_path / "store").read("windows")
    # every window is there exactly once: the renamed partition holds the new rows, the other the old ones
    assert len(w) == 100 and not w.duplicated(["run_id", "section", "window_m"]).any()
    assert set(w["pk_pk_um"]) <= {1.0, 2.0}
    assert not list((tmp_path / "store").rglob("*.tmp-*"))  # the writer removed its temporary files
    # a temporary file of a writer killed outright (no clean-up) is invisible to readers and cleaned by the next
    part = tmp_path / "store" / "windows" / "line=line1" / "section=s1" / "date=2024-03-04"
    (part / ".r9__m1.parquet.tmp-999-dead").write_bytes(b"PAR1 half a file")
    assert len(st.read("windows")) == 100
    st.write("line1", "r1", "m1", run_tables("r1", "2024-03-04", value=3.0))
    assert not list((tmp_path / "store").rglob("*.tmp-*"))
    assert set(st.read("windows")["pk_pk_um"]) == {3.0}


def _writer(root: str, ids: list[str], value: float) -> None:
    st = MonitoringStore(root)
    for rid in ids:
        st.write("line1", rid, "m1", run_tables(rid, "2024-03-05", sections=("s1", "s2", "s3"), n=40, value=value))


def test_two_processes_writing_at_once_lose_nothing(tmp_path):
    root = str(tmp_path / "store")
    a = [f"a{i:02d}" for i in range(12)] + [f"both{i}" for i in range(4)]
    b = [f"b{i:02d}" for i in range(12)] + [f"both{i}" for i in range(4)]
    ctx = mp.get_context("spawn")
    procs = [ctx.Process(target=_writer, args=(root, ids, v)) for ids, v in ((a, 1.0), (b, 2.0))]
    for p in procs:
        p.start()
    for p in procs:
        p.join(120)
        assert p.exitcode == 0
    w = MonitoringStore(root).read("windows")
    expected = set(a) | set(b)
    assert set(w["run_id"]) == expected
    assert len(w) == len(expected) * 3 * 40
    assert not w.duplicated(["run_id", "section", "window_m"]).any()
    r = MonitoringStore(root).read("runs")
    assert len(r) == len(expected) * 3


def test_pandas_duckdb_and_dask_read_the_store_directly(tmp_path):
    import dask.dataframe as dd
    import duckdb

    st = MonitoringStore(tmp_path / "store")
    st.write("line1", "r1", "m1", run_tables("r1", "2024-03-04"))
    st.write("line1", "r2", "m1", run_tables("r2", "2024-03-05"))
    folder = tmp_path / "store" / "windows"
    p = pd.read_parquet(folder)
    assert len(p) == 200 and {"line", "section", "date"} <= set(p.columns)
    n = duckdb.sql(f"select count(*), count(distinct date) from read_parquet('{folder}/**/*.parquet', "
                   "hive_partitioning=true)").fetchall()[0]
    assert n == (200, 2)
    d = dd.read_parquet(folder).compute()
    assert len(d) == 200


def test_a_folder_that_is_not_a_store_is_refused(tmp_path):
    (tmp_path / "x").mkdir()
    (tmp_path / "x" / "notes.txt").write_text("mine")
    with pytest.raises(StoreError, match="not a monitoring store"):
        MonitoringStore(tmp_path / "x")
    (tmp_path / "f").write_text("a file")
    with pytest.raises(StoreError, match="is a file"):
        MonitoringStore(tmp_path / "f")
    st = MonitoringStore(tmp_path / "s")
    with pytest.raises(StoreError, match="YYYY-MM-DD"):
        st.write("line1", "r1", "m1", run_tables("r1", "04/03/2024"))
    with pytest.raises(StoreError, match="unknown table"):
        st.write("line1", "r1", "m1", {"nonsense": pd.DataFrame({"section": ["a"], "date": ["2024-03-04"]})})
