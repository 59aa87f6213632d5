"""Batches of runs on Dask: a local cluster by default, any Dask scheduler to scale out.

A fleet's days of recordings — or a whole archive after a wheelset model
changed — are processed by :func:`estimator.monitoring.ingest` with an
*executor* that runs one task per run:

* :class:`LocalExecutor` runs the tasks one after the other in this process
  (the reference path);
* :class:`DaskExecutor` submits them to Dask (``distributed``): a
  ``LocalCluster`` of ``workers`` processes with one thread each when no
  scheduler is given (no set-up), or the existing cluster at ``scheduler``
  (``tcp://host:8786``; the run files and the model must be readable by the
  workers at the same paths).

**One task per run.** A task gets a run file's path and the (small) ingest
specification — model, sensor table and line paths, options — and returns
the run's tables (band indexes per window, spectra, alignment, QC): never the
accelerations. Each worker process builds the field model once and keeps
it (its transfer functions are memoised), so a worker's later runs reuse them.
The day's alignment reference (a feature signal of a few MB) is scattered to
the workers once per day (``Client.scatter(..., broadcast=True)``).

**Memory bounded per task.** One thread per worker process: a worker runs
one task at a time under its ``memory_limit`` (default 4 GiB; Dask's nanny
restarts a worker that exceeds it and the run is reported as failed); a task
holds one run (a 1 kHz, 6-channel run of a few minutes is a few tens of MB)
and its estimate. What a worker keeps between tasks, the memoised transfer
functions, is bounded too (:mod:`estimator.memo`: 1 GiB, at most 35 % of the limit):
unbounded, it grew with every run until Dask paused the worker at 80 % of a
2 GiB limit and the batch stood still (measured on the virtual line's 5-day
campaign: 1.74 GB after three runs, nothing more done). Measured with the
bound: a worker's memory stays at 1.6–2.0 GB over the same campaign, and the
results are those of the unbounded local path to the bit.

**Allocation.** Dask's nanny starts its workers with
``MALLOC_TRIM_THRESHOLD_=65536`` (to hand freed memory back to the system).
With glibc that also fixes the mmap threshold at 128 KiB, so every large
temporary of an estimate is a fresh ``mmap`` whose pages fault in again: the
same run took 1.9x the CPU inside a worker (1.5 s against 0.8 s, measured).
The local cluster unsets it for its workers. For an existing cluster, start
its workers with ``distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_:
null`` in their Dask configuration; the results are the same either way,
only the speed differs. The workers still hold memory within their
``memory_limit``.

**Failures** of one run (an unreadable file, a run that cannot be aligned, a
worker lost) come back as that run's failure — with the reason — and the
batch goes on. A batch whose workers all stay paused at 80 % of their memory
limit (Dask runs nothing on a paused worker) fails its remaining runs after
``stall_timeout_s`` (10 min) with that reason, instead of standing still.

**Same results.** Both executors call the same function with the same
arguments and hold BLAS to one thread inside each task (threadpoolctl), so a
batch on Dask gives the local path's numbers (tested to 1e-12; in practice
bit for bit).
"""

from __future__ import annotations

import logging
import time
import traceback
from typing import Any, Callable, Iterator, Sequence

__all__ = ["LocalExecutor", "DaskExecutor", "executor_for", "call_isolated"]

log = logging.getLogger("estimator")


def call_isolated(fn: Callable, *args, **kwargs):
    """Run ``fn`` with BLAS held to one thread; an exception comes back as ``("error", text)`` (never raised)."""
    from threadpoolctl import threadpool_limits

    try:
        with threadpool_limits(1):
            return fn(*args, **kwargs)
    except Exception as exc:  # noqa: BLE001 - one run's failure must not stop a batch; reported with its reason
        tb = traceback.format_exception_only(type(exc), exc)[-1].strip()
        return ("error", tb)


class LocalExecutor:
    """Tasks one after the other in this process (the reference path)."""

    name = "local"

    def __enter__(self) -> "LocalExecutor":
        return self

    def __exit__(self, *exc) -> None:
        return None

    def share(self, obj: Any) -> Any:
        return obj

    def run(self, fn: Callable, calls: Sequence[tuple[tuple, dict]]) -> Iterator[tuple[int, Any]]:
        """Yield ``(index, result)`` for each call ``(args, kwargs)``, in order."""
        for i, (args, kwargs) in enumerate(calls):
            yield i, call_isolated(fn, *args, **kwargs)

    def describe(self) -> str:
        return "local (this process, one run at a time)"


class DaskExecutor:
    """Tasks on Dask: a new ``LocalCluster`` or an existing scheduler (module docstring).

    Parameters
    ----------
    scheduler : str, optional
        Address of an existing scheduler (``tcp://host:8786``); None starts a local cluster.
    workers : int
        Worker processes of the local cluster (one thread each).
    memory_limit : str or int
        Memory limit per worker of the local cluster (Dask's syntax, e.g. ``"4GiB"``). A worker's transfer-function
        memo takes at most :data:`estimator.memo.WORKER_SHARE` of it.
    stall_timeout_s : float
        How long every worker may stay paused (memory) with nothing completing before the runs left fail.
    """

    name = "dask"

    def __init__(self, scheduler: str | None = None, *, workers: int = 2, memory_limit="4GiB",
                 stall_timeout_s: float = 600.0) -> None:
        from distributed import Client, LocalCluster

        self.stall_timeout_s = float(stall_timeout_s)

        # the scheduler's and workers' own INFO chatter is not the user's business (warnings still show)
        for name in ("distributed", "dask"):
            if logging.getLogger(name).getEffectiveLevel() < logging.WARNING:
                logging.getLogger(name).setLevel(logging.WARNING)
        self.scheduler = scheduler
        self.cluster = None
        if scheduler:
            try:
                self.client = Client(scheduler, timeout="20s")
            except (OSError, TimeoutError) as exc:
                raise OSError(f"cannot reach the Dask scheduler at {scheduler!r}: {exc}") from None
        else:
            import dask

            # Dask's nanny sets MALLOC_TRIM_THRESHOLD_ = 64 KiB in the workers it spawns. Setting it also switches
            # off glibc's dynamic mmap threshold, so every array above 128 KiB is mmap'ed and its pages are
            # faulted in afresh: an estimate (FFT-sized temporaries) then took 1.9x the CPU of the same run in a
            # plain process. Unset, the workers allocate as this process does (module docstring).
            with dask.config.set({"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}):
                self.cluster = LocalCluster(n_workers=int(workers), threads_per_worker=1, processes=True,
                                            memory_limit=memory_limit, dashboard_address=None)
            self.client = Client(self.cluster)

    def __enter__(self) -> "DaskExecutor":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()

    def share(self, obj: Any) -> Any:
        """``obj`` sent once to every worker (a broadcast scatter), or ``obj`` itself, which each task then carries,
        when no worker can take it now: Dask refuses a scatter while every worker is paused (memory), and the
        batch must not end on it."""
        status = [w.get("status") for w in self._workers()]
        if "running" not in status:
            log.warning("no Dask worker is running now (%s): the tasks carry the day's reference themselves",
                        ", ".join(sorted(set(map(str, status)))) or "none connected")
            return obj
        try:
            return self.client.scatter(obj, broadcast=True)
        except (TimeoutError, OSError) as exc:  # a worker paused between the check and the scatter
            log.warning("the day's reference could not be scattered to the workers (%s): the tasks carry it "
                        "themselves", exc)
            return obj

    def run(self, fn: Callable, calls: Sequence[tuple[tuple, dict]]) -> Iterator[tuple[int, Any]]:
        """Submit every call and yield ``(index, result)`` as they complete (a lost task yields its error).

        A worker paused at 80 % of its memory limit takes no task until its memory falls, which it may never do:
        when every worker has been paused for :attr:`stall_timeout_s` with nothing completing, the calls left
        fail with that reason instead of the batch standing still."""
        from distributed import wait

        futures = {self.client.submit(call_isolated, fn, *args, pure=False, **kwargs): i
                   for i, (args, kwargs) in enumerate(calls)}
        pending, paused_since = set(futures), None
        while pending:
            try:
                done, pending = wait(pending, timeout=min(5.0, self.stall_timeout_s), return_when="FIRST_COMPLETED")
            except TimeoutError:
                done = set()
            for fut in done:
                try:
                    res = fut.result()
                except Exception as exc:  # noqa: BLE001 - a worker lost or killed (memory limit): that run fails
                    res = ("error", f"{type(exc).__name__}: {exc}")
                fut.release()
                yield futures[fut], res
            workers = [] if done else self._workers()
            if not workers or any(w.get("status") != "paused" for w in workers):
                paused_since = None
                continue
            paused_since = paused_since or time.monotonic()
            if time.monotonic() - paused_since < self.stall_timeout_s:
                continue
            limits = ", ".join(map(str, sorted({w.get("memory_limit") for w in workers})))
            why = (f"every Dask worker has been paused at 80 % of its memory limit ({limits} bytes) for "
                   f"{self.stall_timeout_s:g} s with nothing completing: give the workers more memory "
                   "(--memory-limit) or fewer at a time")
            log.error("%s; %d run(s) not processed", why, len(pending))
            for fut in pending:
                fut.cancel()
                yield futures[fut], ("error", why)
            return

    def _workers(self) -> list[dict]:
        """The scheduler's record of each worker (``status``: running, paused, ...; ``memory_limit``)."""
        return list(self.client.scheduler_info().get("workers", {}).values())

    def describe(self) -> str:
        info = self.client.scheduler_info()
        n = len(info.get("workers", {}))
        where = self.scheduler or "a local cluster"
        return f"dask ({where}, {n} worker(s))"


def executor_for(scheduler: str | None = None, workers: int | None = None, memory_limit="4GiB"):
    """:class:`DaskExecutor` when a scheduler or more than one worker is asked for, else :class:`LocalExecutor`."""
    if scheduler or (workers is not None and workers > 1):
        return DaskExecutor(scheduler, workers=workers or 2, memory_limit=memory_limit)
    return LocalExecutor()
