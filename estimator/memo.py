"""The transfer functions a process's field models memoise, in one store bounded in bytes.

A :class:`~estimator.workflow.FieldModel` memoises what it derives from its wheelset model (track receptances,
transfer functions per kind and contact angles, rail couplings per wheelset distance), so that a batch's runs
share them. Some keys are the run's own: the contact angles of a curve follow the run's speed, the rail coupling
the wheelbase the run measured. An unbounded memo then grows with every run: on the virtual line's 5-day
campaign a worker's 52 uncertainty variants held 845 MB of transfer functions after the first run and 1138 MB
after ten (1040 → 1936 entries), until Dask paused the worker at 80 % of its memory limit and the batch stood
still. Here every field model's memo is a view (:class:`Memo`) onto one store per process that evicts the
least recently used entries once their arrays exceed a byte budget: entries a run keeps using stay, a finished
run's are the first to go, and a value recomputed after eviction is the same (each depends on its key alone).

Least recently used is the worst order for a cycle longer than the store: the monitoring's uncertainty run
uses its 52 variants' transfer functions in the same order every run, so once they exceed the budget each one is
evicted just before its next use and every run computes all of them again (on the virtual line, with a 600 MB
budget, 111 s per uncertainty run instead of the 64 s it takes when they fit: 624 refaults in the second run).
The store counts such *refaults* (an evicted key put again) and, once they
reach :data:`REFAULT_WARNING`, logs one warning naming the budget and how to raise it. It does not change its
policy. A loop-resistant one was measured and not kept: a probation queue holding a quarter of the budget, entered
when most recent puts are refaults, as LIRS and 2Q do. On a pure cycle of 15 equal entries through a store of 10 it
hits 7 a pass where LRU hits 0. On the virtual line's uncertainty runs, 20 variants, with 60 % of their 390 MB
working set, it cut the puts from 309 to 213–235 a run, but not the time: 46.7 and 50.6 s against LRU's 43.3 and
49.5 s, with 26–33 s when everything fits. Evicting the latest put instead (optimal for a pure loop) made it
worse, 330 and 275 puts: within one variant's estimate an entry is read again right after it is put, so the
cycle is not the simple loop such policies assume. My reading of why fewer puts did not save time, not measured
entry by entry: the entries differ in cost far more than in number. Raising the budget is the fix.

The budget is the environment variable ``RAILMODAL_MEMO_MB`` when it is set, else :data:`DEFAULT_BUDGET_BYTES`;
inside a Dask worker at most :data:`WORKER_SHARE` of the worker's memory limit, so that the memo alone never
takes a worker to the 80 % at which Dask pauses it (a paused worker whose memory does not fall runs nothing
again). It is read when the store is first used, in each process.
"""

from __future__ import annotations

import dataclasses
import itertools
import logging
import os
import threading
from collections import OrderedDict
from collections.abc import MutableMapping
from typing import Any, Hashable, Iterator

import numpy as np

__all__ = ["Memo", "DEFAULT_BUDGET_BYTES", "WORKER_SHARE", "REFAULT_WARNING", "store_stats", "set_budget"]

log = logging.getLogger("estimator")

#: 1.5 GiB: what one uncertainty run of the monitoring reuses on the next (52 variants' transfer functions:
#: 0.99 GB on the virtual line with its three trackforms and one curve, the track's receptances and couplings
#: shared, :data:`estimator.workflow.TRACK_MEMO`) stays, with room for a line with more trackforms or curves.
#: With 384 MiB every variant was evicted before its next use (LRU over a cycle longer than the store) and
#: ingesting that campaign took 210 s instead of 112 s.
DEFAULT_BUDGET_BYTES = 3 * 2**29
#: the largest share of a Dask worker's memory limit the memo may take (the run being estimated needs the rest)
WORKER_SHARE = 0.35
#: refaults (evicted keys computed and put again) at which the store warns, once per process, that its budget
#: is below what the runs reuse
REFAULT_WARNING = 200
#: evicted keys remembered to recognise a refault (keys only, no values)
_GHOSTS = 8192


def nbytes(value: Any, _depth: int = 0) -> int:
    """Bytes of the NumPy arrays a memoised value holds (in containers and dataclasses, a few levels deep)."""
    if isinstance(value, np.ndarray):
        return int(value.nbytes)
    if _depth > 3:
        return 0
    if isinstance(value, (list, tuple)):
        return sum(nbytes(v, _depth + 1) for v in value)
    if isinstance(value, dict):
        return sum(nbytes(v, _depth + 1) for v in value.values())
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return sum(nbytes(getattr(value, f.name), _depth + 1) for f in dataclasses.fields(value))
    data = getattr(value, "data", None)  # any other object holding its values in `data`
    return int(data.nbytes) if isinstance(data, np.ndarray) else 0


class _Store:
    """Entries ``(namespace, key) -> (value, bytes)`` in least-recently-used order, within ``budget`` bytes."""

    def __init__(self, budget: int) -> None:
        self.budget = int(budget)
        self.entries: OrderedDict[tuple[int, Hashable], tuple[Any, int]] = OrderedDict()
        #: each namespace's live keys (a memo lists its own without scanning the store)
        self.keys: dict[int, set] = {}
        self.bytes = 0
        self.evicted = 0
        #: keys evicted lately (oldest first), and how many of them were put again
        self.ghosts: OrderedDict[tuple[int, Hashable], None] = OrderedDict()
        self.refaults = 0
        self.warned = False
        self.lock = threading.Lock()

    def _drop(self, full_key, size: int) -> None:
        self.bytes -= size
        ns, key = full_key
        live = self.keys.get(ns)
        if live is not None:
            live.discard(key)
            if not live:
                del self.keys[ns]

    def evict_beyond(self, budget: int) -> None:
        """Drop the least recently used entries until they fit ``budget``; the newest always stays (it is about to
        be used). Call with the lock held."""
        while self.bytes > budget and len(self.entries) > 1:
            full_key, (_, size) = self.entries.popitem(last=False)
            self._drop(full_key, size)
            self.evicted += 1
            self.ghosts[full_key] = None
            if len(self.ghosts) > _GHOSTS:
                self.ghosts.popitem(last=False)

    def get(self, full_key):
        with self.lock:
            value, _ = self.entries[full_key]
            self.entries.move_to_end(full_key)
            return value

    def put(self, full_key, value) -> None:
        size = nbytes(value)
        with self.lock:
            old = self.entries.pop(full_key, None)
            if old is not None:
                self.bytes -= old[1]
            elif full_key in self.ghosts:  # evicted, and wanted again
                del self.ghosts[full_key]
                self.refaults += 1
            self.entries[full_key] = (value, size)
            self.keys.setdefault(full_key[0], set()).add(full_key[1])
            self.bytes += size
            self.evict_beyond(self.budget)
            warn = self.refaults >= REFAULT_WARNING and not self.warned
            self.warned |= warn
        if warn:
            log.warning("the transfer-function memo's budget (%.0f MB) is below what the runs reuse: %d entries "
                        "were evicted and computed again; set RAILMODAL_MEMO_MB higher (within a Dask worker the "
                        "memo takes at most %.0f %% of --memory-limit)", self.budget / 2**20, self.refaults,
                        100 * WORKER_SHARE)

    def delete(self, full_key) -> None:
        with self.lock:
            _, size = self.entries.pop(full_key)
            self._drop(full_key, size)


_STORE: _Store | None = None
_NAMESPACES = itertools.count()


def _store() -> _Store:
    global _STORE
    if _STORE is None:
        mb = os.environ.get("RAILMODAL_MEMO_MB")
        try:
            budget = int(float(mb) * 2**20) if mb else DEFAULT_BUDGET_BYTES
        except ValueError:
            raise ValueError(f"RAILMODAL_MEMO_MB must be a number of megabytes, got {mb!r}") from None
        limit = _worker_memory_limit()
        if limit:
            budget = min(budget, int(WORKER_SHARE * limit))
        _STORE = _Store(max(budget, 0))
    return _STORE


def _worker_memory_limit() -> int | None:
    """The memory limit [bytes] of the Dask worker this code runs in, None outside one (or without a limit)."""
    try:
        from distributed import get_worker

        limit = get_worker().memory_manager.memory_limit
    except (ImportError, ValueError, AttributeError):
        return None
    return int(limit) if limit else None


def set_budget(n_bytes: int) -> None:
    """Set this process's memo budget [bytes], evicting at once what lies beyond it."""
    s = _store()
    with s.lock:
        s.budget = int(n_bytes)
        s.evict_beyond(s.budget)


def store_stats() -> dict:
    """``entries``, ``bytes``, ``budget``, ``evicted`` (entries evicted so far) and ``refaults`` (evicted keys put
    again) of this process's store."""
    s = _store()
    return {"entries": len(s.entries), "bytes": s.bytes, "budget": s.budget, "evicted": s.evicted,
            "refaults": s.refaults}


class Memo(MutableMapping):
    """One field model's memo: a dictionary whose entries live in the process's bounded store.

    Parameters
    ----------
    initial : mapping, optional
        Entries to start with.

    Notes
    -----
    An entry can only go when another one is put (the newest always stays), so ``if key not in memo: memo[key] =
    f()`` followed by ``return memo[key]`` is safe; a value needed across later puts is held by reference. A memo
    pickled (a field model sent to a Dask worker) sends no entries: the worker computes its own.
    """

    def __init__(self, initial=None) -> None:
        self._ns = next(_NAMESPACES)
        for k, v in dict(initial or {}).items():
            self[k] = v

    def _full(self, key):
        return (self._ns, key)

    def __getitem__(self, key):
        try:
            return _store().get(self._full(key))
        except KeyError:
            raise KeyError(key) from None

    def __setitem__(self, key, value) -> None:
        _store().put(self._full(key), value)

    def __delitem__(self, key) -> None:
        try:
            _store().delete(self._full(key))
        except KeyError:
            raise KeyError(key) from None

    def __contains__(self, key) -> bool:
        return self._full(key) in _store().entries

    def __iter__(self) -> Iterator:
        return iter(list(_store().keys.get(self._ns, ())))

    def __len__(self) -> int:
        return len(_store().keys.get(self._ns, ()))

    def __reduce__(self):
        return (Memo, ())

    def __repr__(self) -> str:
        return f"Memo({len(self)} entries)"
