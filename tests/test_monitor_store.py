"""The monitoring store: idempotent re-ingest, versions side by side, a crash mid-write, concurrent writers, readers.

Each test counts rows against the exact set written: a lost or a duplicated
row fails it.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import re

import numpy as np
import pandas as pd
import pytest

from estimator.monitoring.errors import StoreError
from estimator.monitoring.store import RUN_TABLES, MonitoringStore, RunIdCollision


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


def test_a_file_the_store_did_not_write_is_refused_by_name(tmp_path):
    """A copy of a run's file under another name (read as a second model version, or averaged in twice), a file
    in a partition whose date is no calendar date, a truncated file and a foreign table: each refused by
    :meth:`MonitoringStore.verify` naming the file; the store as written passes."""
    import shutil

    st = MonitoringStore(tmp_path / "store")
    st.write("line1", "r1", "m1", run_tables("r1", "2024-03-04"))
    st.write("line1", "r2", "m1", run_tables("r2", "2024-03-04"))
    assert st.verify() == 8  # runs and windows: one file per run, section and table
    part = tmp_path / "store" / "windows" / "line=line1" / "section=s1"
    good = part / "date=2024-03-04" / "r1__m1.parquet"
    for bad, why in ((good.with_name("r1__m1_copy.parquet"), "its rows are of model version(s) ['m1'], its name "
                                                             "says 'm1_copy'"),
                     (good.with_name("copy of r1.parquet"), "not a name the store writes"),
                     (part / "date=2024-02-30" / "r1__m1.parquet", "partition date '2024-02-30' is not a calendar "
                                                                   "date")):
        bad.parent.mkdir(exist_ok=True)
        shutil.copy(good, bad)
        with pytest.raises(StoreError, match=re.escape(f"{bad}: {why}")):
            st.verify()
        bad.unlink()
    bad = good.with_name("r3__m1.parquet")
    bad.write_bytes(good.read_bytes()[:200])
    with pytest.raises(StoreError, match=re.escape(f"{bad}: not a readable Parquet file")):
        st.verify()
    pd.DataFrame({"a": [1.0]}).to_parquet(bad)
    with pytest.raises(StoreError, match=re.escape(f"{bad}: no model_hash column")):
        st.verify()
    bad.unlink()
    assert st.verify() == 8


def test_a_second_check_reads_only_what_changed_since_the_first(tmp_path, monkeypatch):
    """``reprocess`` checks the store, then its ``ingest`` does: the second reads no footer again, but a file
    rewritten in between (here by a foreign hand) is read and refused."""
    import estimator.monitoring.store as store_module

    st = MonitoringStore(tmp_path / "store")
    st.write("line1", "r1", "m1", run_tables("r1", "2024-03-04"))
    st.write("line1", "r2", "m1", run_tables("r2", "2024-03-04"))
    real = store_module.pq.ParquetFile
    opened = []
    monkeypatch.setattr(store_module.pq, "ParquetFile", lambda f, *a, **k: opened.append(f) or real(f, *a, **k))
    assert st.verify() == 8 and len(opened) == 8
    assert st.verify() == 8 and len(opened) == 8
    f = tmp_path / "store" / "windows" / "line=line1" / "section=s1" / "date=2024-03-04" / "r1__m1.parquet"
    pd.DataFrame({"a": [1.0]}).to_parquet(f)
    with pytest.raises(StoreError, match=re.escape(f"{f}: no model_hash column")):
        st.verify()
    assert opened[8:] == [f]


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


# --------------------------------------------------------------------------- one run per file name
def ident(run_id: str, date: str, source, train="T1", bogie="B2") -> dict:
    return {"run_id": run_id, "date": date, "source": str(source), "train": train, "bogie": bogie}


def write_run(st, line, run_id, date, source, model="m1", value=1.0, train="T1"):
    """A run's rows as the ingest writes them (its QC rows carry its file, train and bogie), with its identity."""
    t = run_tables(run_id, date, value=value, model=model)
    t["runs"] = t["runs"].assign(source=str(source), train=train, bogie="B2")
    return st.write(line, run_id, model, t, run=ident(run_id, date, source, train))


def failure_row(run_id: str, source, date="unknown", model="m1") -> dict:
    return {"failures": pd.DataFrame([{"run_id": run_id, "source": str(source), "stage": "estimate", "error": "x",
                                       "section": "none", "date": date, "model_hash": model}])}


def counts(st: MonitoringStore) -> dict:
    return {t: len(st.read(t)) for t in ("runs", "windows", "failures")}


def test_a_different_run_under_the_same_file_name_is_refused_and_the_stored_run_kept(tmp_path):
    """A logger restarting at R001 every day, two trains' loggers, ids that differ only where safe_name maps
    them to one file name, a run that now fails: each would have replaced the stored run's rows everywhere."""
    st = MonitoringStore(tmp_path / "store")
    a, b, c = (tmp_path / f"{n}.mf4" for n in "abc")
    for k, f in enumerate((a, b, c)):
        f.write_bytes(bytes([k]) * 100)
    write_run(st, "line1", "R001", "2026-01-05", a)
    write_run(st, "line1", "T12_run_5", "2026-01-05", c)
    before = counts(st)
    assert before == {"runs": 4, "windows": 200, "failures": 0}
    with pytest.raises(RunIdCollision) as e:  # the next day's R001
        write_run(st, "line1", "R001", "2026-01-14", b, value=9.0)
    msg = str(e.value)
    assert msg.startswith(f"{b}: run_id 'R001'") and f"run_id of {a} (date 2026-01-05) in the store" in msg
    assert "unique" in msg and (e.value.source, e.value.other_source) == (str(b), str(a))
    with pytest.raises(RunIdCollision, match="train 'T1' there, 'T7' here"):  # another train's R001, same day
        write_run(st, "line1", "R001", "2026-01-05", b, value=9.0, train="T7")
    with pytest.raises(RunIdCollision, match="the two files differ"):  # a logger restarted within the day
        write_run(st, "line1", "R001", "2026-01-05", b, value=9.0)
    with pytest.raises(RunIdCollision, match="same file name 'T12_run_5' as run_id 'T12_run_5'"):
        write_run(st, "line1", "T12/run 5", "2026-01-05", b, value=9.0)
    with pytest.raises(RunIdCollision):  # another file's failure (header unread) under the name
        st.write("line1", "R001", "m1", failure_row("R001", b), run=ident("R001", "unknown", b))
    with pytest.raises(RunIdCollision):  # a different run is refused in another model version too
        write_run(st, "line1", "R001", "2026-01-14", b, model="m2")
    assert counts(st) == before
    w = st.read("windows")
    assert set(w["date"]) == {"2026-01-05"} and set(w["pk_pk_um"]) == {1.0}
    assert set(st.read("runs")["source"]) == {str(a), str(c)}
    # another line holds its own run ids
    write_run(st, "line2", "R001", "2026-01-14", b)
    assert len(st.read("windows", line="line2")) == 100 and len(st.read("windows", line="line1")) == 200


def test_the_same_run_is_replaced_wherever_its_file_now_is(tmp_path):
    """Re-processing a run replaces its rows: from its file, from an identical copy, from the file moved; as a
    failure; and a run id that merely starts like another's ("R1" and "R1__x") is no collision."""
    st = MonitoringStore(tmp_path / "store")
    a = tmp_path / "a.mf4"
    a.write_bytes(b"run R001")
    write_run(st, "line1", "R001", "2026-01-05", a)
    write_run(st, "line1", "R001", "2026-01-05", a, value=2.0)
    copy = tmp_path / "copy.mf4"
    copy.write_bytes(a.read_bytes())
    write_run(st, "line1", "R001", "2026-01-05", copy, value=3.0)
    moved = tmp_path / "archive" / "a.mf4"
    moved.parent.mkdir()
    a.rename(moved)
    copy.unlink()
    write_run(st, "line1", "R001", "2026-01-05", moved, value=4.0)
    assert counts(st) == {"runs": 2, "windows": 100, "failures": 0}
    assert set(st.read("windows")["pk_pk_um"]) == {4.0}
    # a new model version of the same run lies beside the old one
    write_run(st, "line1", "R001", "2026-01-05", moved, model="m2")
    assert len(st.read("windows")) == 200
    # the run now fails (its header unreadable): its failure replaces its rows (of this model version)
    st.write("line1", "R001", "m2", failure_row("R001", moved, model="m2"), replace_tables=RUN_TABLES,
             run=ident("R001", "unknown", moved))
    assert len(st.read("windows", model_hash="m2")) == 0 and len(st.read("failures")) == 1
    write_run(st, "line1", "R1__x", "2026-01-06", moved)
    write_run(st, "line1", "R1", "2026-01-07", a)
    assert len(st.read("windows", model_hash="m1")) == 300
    # without a run to check (a day's aggregates), the write replaces as before
    st.write("line1", "R001", "m1", run_tables("R001", "2026-01-14", value=5.0))
    assert set(st.read("windows", model_hash="m1", date="2026-01-14")["pk_pk_um"]) == {5.0}


@pytest.fixture(scope="module")
def field_runs(tmp_path_factory):
    """Synthetic runs: R001 of two days (a logger restarting its numbering) and two ids with one file name."""
    from receptance.model_io import save_model
    from test_estimator_synthetic import control_model, make_run, sensor_table

    from estimator import EstimatorConfig
    from estimator.monitoring import IngestSpec, MonitoringConfig

    d = tmp_path_factory.mktemp("dup_ids")
    model = control_model()
    save_model(model, d / "hybrid_model.npz")
    sensor_table().to_csv(d / "sensors.csv", index=False)
    runs = {}
    for name, rid, date, off in (("jan05", "R001", "2026-01-05", 1.5), ("jan14", "R001", "2026-01-14", 0.7),
                                 ("t12a", "T12/run 5", "2026-01-05", 1.0), ("t12b", "T12_run_5", "2026-01-05", 1.2)):
        runs[name] = make_run(d, model, duration_s=25.0, start_offset_m=off, name=name,
                              header_extra={"run_id": rid, "date": date}).path
    spec = IngestSpec(str(d / "hybrid_model.npz"), str(d / "sensors.csv"), estimator=EstimatorConfig(wheelbase_m=2.2),
                      monitoring=MonitoringConfig(uncertainty_runs=0))
    return {"dir": d, "runs": runs, "spec": spec}


def _spy(monkeypatch):
    import estimator.monitoring.workflow as wf

    seen = []
    real = wf.process_run

    def spy(path, *a, **k):
        seen.append(str(path))
        return real(path, *a, **k)

    monkeypatch.setattr(wf, "process_run", spy)
    return seen


def test_ingest_refuses_a_second_run_with_the_same_run_id_and_keeps_the_first(field_runs, monkeypatch):
    from estimator.monitoring import ingest

    jan05, jan14 = str(field_runs["runs"]["jan05"]), str(field_runs["runs"]["jan14"])
    st = MonitoringStore(field_runs["dir"] / "store_a")
    first = ingest([jan05], field_runs["spec"], st)
    assert list(first.runs["run_id"]) == ["R001"] and first.failures.empty
    tables = ("runs", "windows", "alignment", "spectra", "days", "day_sections")
    before = {t: len(st.read(t)) for t in tables}
    assert before["windows"] > 0 and before["days"] > 0
    seen = _spy(monkeypatch)
    res = ingest([jan14], field_runs["spec"], st)
    assert seen == []  # refused before processing
    assert res.runs.empty and res.dates == () and len(res.failures) == 1
    f = res.failures.iloc[0]
    assert f["stage"] == "run_id" and f["source"] == jan14 and f["date"] == "2026-01-14"
    assert f["error"].startswith(f"{jan14}: run_id 'R001'") and f"{jan05} (date 2026-01-05) in the store" in f["error"]
    assert {t: len(st.read(t)) for t in tables} == before
    for t in tables:
        assert set(st.read(t)["date"]) == {"2026-01-05"}
    assert st.read("failures").empty  # the refusal is reported, not stored under the name it would overwrite
    # re-ingesting the stored run replaces its rows, never duplicates them
    again = ingest([jan05], field_runs["spec"], st)
    assert seen == [jan05] and list(again.runs["run_id"]) == ["R001"] and again.failures.empty
    # (its alignment rows change: it is now aligned to the day's stored reference instead of being it)
    assert {t: len(st.read(t)) for t in tables if t != "alignment"} == {t: n for t, n in before.items()
                                                                          if t != "alignment"}
    assert not st.read("alignment").duplicated(["run_id", "wheelset", "stage", "from_m"]).any()
    assert not st.read("windows").duplicated(["run_id", "wheelset", "rail", "band_mm", "window_m"]).any()


def test_ingest_refuses_run_ids_sharing_a_file_name_within_a_batch(field_runs, monkeypatch):
    from estimator.monitoring import ingest

    a, b = str(field_runs["runs"]["t12a"]), str(field_runs["runs"]["t12b"])
    st = MonitoringStore(field_runs["dir"] / "store_b")
    seen = _spy(monkeypatch)
    res = ingest([a, b], field_runs["spec"], st)
    assert seen == [] and res.runs.empty and len(res.failures) == 2
    err = res.failures.set_index("source")["error"]
    assert set(res.failures["stage"]) == {"run_id"}
    assert err[a].startswith(f"{a}: run_id 'T12/run 5'") and f"run_id 'T12_run_5' of {b}" in err[a]
    assert "in this batch" in err[a] and "same file name 'T12_run_5'" in err[a]
    assert err[b].startswith(f"{b}: run_id 'T12_run_5'") and f"run_id 'T12/run 5' of {a}" in err[b]
    assert not st.files("runs") and not st.files("windows")


def test_a_run_folder_names_the_tables_it_does_not_take_as_runs(tmp_path, caplog):
    """A folder gives its MDF 4 files as runs (it also holds store files, trolley records and exports); Parquet and
    CSV files beside them are passed over with a WARNING naming them, so a run table left in it is not lost unseen."""
    import logging

    from estimator.monitoring.workflow import collect_runs

    (tmp_path / "day").mkdir()
    for name in ("day/r1.mf4", "day/r2.parquet", "trolley.csv"):
        (tmp_path / name).write_bytes(b"x")
    with caplog.at_level(logging.WARNING, logger="estimator"):
        assert collect_runs([tmp_path]) == [str(tmp_path / "day" / "r1.mf4")]
    assert "2 Parquet/CSV file(s) not taken as runs" in caplog.text and "day/r2.parquet, trolley.csv" in caplog.text
    # the same run given twice (and through its folder) is ingested once, and the repetition is said
    caplog.clear()
    r1 = tmp_path / "day" / "r1.mf4"
    with caplog.at_level(logging.WARNING, logger="estimator"):
        assert collect_runs([r1, tmp_path / "day" / ".." / "day" / "r1.mf4", tmp_path / "day"]) == [str(r1)]
    assert caplog.text.count("is given more than once") == 2 and "ingested once" in caplog.text


def test_a_date_that_is_no_calendar_day_is_refused_at_writing(tmp_path):
    """2024-02-30 has the form YYYY-MM-DD: stored as a survey day it would break every later reading of the days
    (estimator.monitoring.store.calendar_date: the ingest's header check and the store's own partition check)."""
    from estimator.monitoring.store import calendar_date

    assert calendar_date("2024-02-29") and not calendar_date("2024-02-30") and not calendar_date("2023-02-29")
    assert not calendar_date("yesterday") and not calendar_date("2024-2-3") and not calendar_date("unknown")
    assert calendar_date("unknown", unknown_ok=True)
    st = MonitoringStore(tmp_path / "store")
    with pytest.raises(StoreError, match=r"date must be a YYYY-MM-DD calendar date .* got '2024-02-30'"):
        st.write("line1", "r1", "m1", run_tables("r1", "2024-02-30"))
    assert st.files("windows") == [] and st.files("runs") == []


def test_a_trolley_record_named_with_no_calendar_date_is_refused_and_one_rail_is_said(tmp_path, caplog):
    """The survey day is read from the trolley file's name: 2024-13-45 is refused naming the file (not a bare
    date error); a record of one rail reads, and the warning says the comparison covers that rail alone."""
    import logging

    from estimator.monitoring.errors import TrolleyReferenceError
    from estimator.monitoring.reference import read_trolley_record

    x = np.arange(0.0, 50.0, 0.005)
    rows = pd.DataFrame({"chainage_m": np.tile(x, 2), "rail": np.repeat(["L", "R"], x.size),
                         "roughness_um": np.tile(5.0 * np.sin(2 * np.pi * x / 0.05), 2)})
    bad = tmp_path / "2024-13-45.csv"
    rows.to_csv(bad, index=False)
    with pytest.raises(TrolleyReferenceError, match=re.escape(f"{bad}: the name's date '2024-13-45' is not a "
                                                              "calendar date")):
        read_trolley_record(bad)
    one = tmp_path / "2024-03-04.csv"
    rows[rows["rail"] == "R"].to_csv(one, index=False)
    with caplog.at_level(logging.WARNING, logger="estimator"):
        rec = read_trolley_record(one)
    assert rec.rails == ("R",) and rec.date == "2024-03-04"
    assert "holds rail R only: the comparison, and a calibration from it, covers that rail alone" in caplog.text


def test_a_trolley_band_its_sampling_cannot_resolve_is_left_out_and_said(caplog):
    """A trolley sampled every 100 mm resolves nothing under 200 mm (Nyquist): 10-30, 30-100 and 100-300 mm would be
    aliased noise, tens of dB off the train. They are left out with a warning; 300-1000 mm is compared, and its
    peak-to-peak of a 500 mm sine of 20 µm amplitude is 40 µm within the sampling's cos(π/5) bound."""
    import logging

    from estimator import EstimatorConfig
    from estimator.monitoring.reference import TrolleyRecord, trolley_windows

    x = np.arange(0.0, 60.0, 0.1)
    rec = TrolleyRecord("coarse.csv", "2024-03-04", 0.0, 0.1, ("L",), (20e-6 * np.sin(2 * np.pi * x / 0.5))[None, :])
    with caplog.at_level(logging.WARNING, logger="estimator"):
        tw = trolley_windows(rec, None, EstimatorConfig(), 1.0)
    assert set(tw["band_mm"]) == {"300-1000"}
    assert "sampled every 100 mm, which does not resolve the band(s) 10-30, 30-100, 100-300 mm" in caplog.text
    mid = tw[tw["window_m"].between(10, 50)]["pk_pk_um"]
    assert 40.0 * np.cos(np.pi / 5) - 0.5 <= mid.median() <= 40.5
