"""A batch on Dask (a local cluster of two worker processes) gives the local path's results; a bad run fails alone."""

from __future__ import annotations

import os
import time

import numpy as np
import pandas as pd
import pytest

from test_estimator_synthetic import control_model, make_run, sensor_table

from estimator import EstimatorConfig
from estimator.fleet import DaskExecutor, LocalExecutor
from estimator.monitoring import IngestSpec, MonitoringConfig, MonitoringStore, ingest

KEYS = {"windows": ["run_id", "wheelset", "rail", "band_mm", "window_m"],
        "days": ["date", "rail", "band_mm", "window_m"],
        "variants": ["run_id", "variant", "wheelset", "rail", "band_mm", "window_m"],
        "alignment": ["run_id", "wheelset", "stage", "from_m"],
        "runs": ["run_id", "section"]}


@pytest.fixture(scope="module")
def batch(tmp_path_factory):
    from receptance.model_io import save_model

    d = tmp_path_factory.mktemp("fleet")
    model = control_model()
    save_model(model, d / "hybrid_model.npz")
    sensor_table().to_csv(d / "sensors.csv", index=False)
    runs = [make_run(d, model, duration_s=20.0, start_offset_m=o, odometer_scale=s, name=f"f{k}",
                     header_extra={"run_id": f"f{k}"}).path
            for k, (o, s) in enumerate([(1.0, 1.002), (-1.5, 0.999), (0.3, 1.0)])]
    bad = d / "broken.mf4"
    bad.write_bytes(b"MDF     4.10    " + bytes(200))
    spec = IngestSpec(str(d / "hybrid_model.npz"), str(d / "sensors.csv"), estimator=EstimatorConfig(wheelbase_m=2.2),
                      monitoring=MonitoringConfig(n_perturbed=1, placement_shifts_mm=(30.0,), placement_axes=("y",),
                                                   contact_load_range=0.0, contact_head_radius_m=(),
                                                   track_stiffness_factor=1.0, track_damping_factor=1.0,
                                                   track_loss_reference_hz=(), track_discrete_supports=False))
    return d, runs + [bad], spec


def _table(st: MonitoringStore, name: str) -> pd.DataFrame:
    t = st.read(name)
    t = t.drop(columns=[c for c in ("processed_at",) if c in t.columns])
    return t.sort_values(KEYS[name]).reset_index(drop=True)


@pytest.mark.slow
def test_dask_batch_equals_the_local_path_and_reports_a_failed_run(batch):
    d, runs, spec = batch
    local = MonitoringStore(d / "local")
    r_local = ingest(runs, spec, local, executor=LocalExecutor())
    seen = []
    with DaskExecutor(workers=2, memory_limit="1.5GiB") as ex:
        # the nanny's MALLOC_TRIM_THRESHOLD_ (fixed mmap threshold: ~1.9x the CPU per run) is not in the workers
        assert ex.client.run(os.environ.get, "MALLOC_TRIM_THRESHOLD_") == {w: None for w in ex.client.run(os.getpid)}
        r_dask = ingest(runs, spec, MonitoringStore(d / "dask"), executor=ex,
                        progress=lambda done, total, msg: seen.append((done, total)))
    assert seen[-1][0] == seen[-1][1] == 4  # the progress reached every run, the failed one included
    assert "dask" in r_dask.executor and "2 worker" in r_dask.executor
    for r in (r_local, r_dask):
        assert len(r.failures) == 1 and "broken" in r.failures["source"].iloc[0]
        assert set(r.runs["run_id"]) == {"f0", "f1", "f2"}
    dask = MonitoringStore(d / "dask")
    for name in KEYS:
        a, b = _table(local, name), _table(dask, name)
        assert len(a) == len(b) > 0, name
        pd.testing.assert_frame_equal(a, b, check_exact=False, rtol=1e-12, atol=0, obj=name)
    w = _table(dask, "windows")
    assert np.isfinite(w["pk_pk_um"]).all()


def _set_status(ex, status):
    """Every worker of ``ex`` to ``status`` (Dask's memory monitor off, so that it does not resume a worker whose
    memory is low), once the scheduler says so."""
    def set_it(dask_worker, name=status.name):
        from distributed.core import Status

        dask_worker.memory_manager.memory_pause_fraction = False
        dask_worker.status = Status[name]

    ex.client.run(set_it)
    for _ in range(200):
        if all(w["status"] == status.name for w in ex.client.scheduler_info()["workers"].values()):
            return
        time.sleep(0.05)
    raise AssertionError(f"the workers did not report {status.name}")


def test_the_days_reference_reaches_the_tasks_when_every_worker_is_paused(caplog):
    """Dask's scheduler refuses a scatter while no worker is running (2 s, then "No valid workers found"): on the
    virtual line's 5-day campaign, with both workers paused at 80 % of their memory limit, the batch ended there
    with the scheduler's traceback on the console. Now no scatter is tried then: the tasks carry the reference."""
    from distributed import Future
    from distributed.core import Status

    ref = np.arange(5.0)  # a day's reference is one object (a dict or a list would be scattered item by item)
    with DaskExecutor(workers=1) as ex:
        _set_status(ex, Status.paused)
        with caplog.at_level("WARNING", logger="estimator"):
            shared = ex.share(ref)
        assert shared is ref and "no Dask worker is running now (paused)" in caplog.text
        _set_status(ex, Status.running)
        shared = ex.share(ref)
        assert isinstance(shared, Future) and np.array_equal(shared.result(), ref)


def test_a_batch_whose_workers_stay_paused_fails_its_runs_with_the_reason(caplog):
    """A worker paused at 80 % of its memory limit never takes the next task if its memory does not fall: the
    batch used to stand still (the virtual line's 5-day campaign, one worker, before the memo was bounded)."""
    from distributed.core import Status

    with DaskExecutor(workers=1, stall_timeout_s=1.0) as ex:
        _set_status(ex, Status.paused)
        t0 = time.monotonic()
        with caplog.at_level("ERROR", logger="estimator"):
            out = dict(ex.run(abs, [((-1,), {}), ((-2,), {})]))
        assert time.monotonic() - t0 < 30
        assert sorted(out) == [0, 1] and all(r[0] == "error" and "paused at 80 % of its memory limit" in r[1]
                                             and "--memory-limit" in r[1] for r in out.values())
        assert "2 run(s) not processed" in caplog.text
        _set_status(ex, Status.running)
        assert dict(ex.run(abs, [((-3,), {})])) == {0: 3}  # running again: the same executor works
