"""Run identification with single-threaded OpenBLAS (private helper).

Identification performs hundreds of small and mid-sized dense operations
(one QR and a few products per model order, per Levenberg–Marquardt step).
With multi-threaded OpenBLAS on a machine whose cores are also busy with
other work, the BLAS threads spin-wait for each other at every call and each
call stalls: measured on 2 cores under load, ``identify`` took 4.1 s with two
BLAS threads and 1.5 s with one (idle, both are about equal because the
matrices are small).  :func:`single_threaded_blas` therefore limits the
OpenBLAS libraries loaded by numpy and scipy to one thread for the duration
of a call and restores the previous setting afterwards (thread-count control
through the libraries' own ``openblas_set_num_threads`` entry points, found
the way ``threadpoolctl`` finds them).  It is a no-op when no OpenBLAS is
found or on non-Linux systems, and can be disabled with the environment
variable ``RAILMODAL_BLAS_THREADS=keep``.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import logging
import os
import re
import threading

log = logging.getLogger("ema")

_SUFFIXES = ("", "64_")
_PREFIXES = ("", "scipy_")
_lock = threading.Lock()
_depth = 0
_saved: list[tuple[object, int]] = []
_handles: list[tuple[object, object]] | None = None


def _find() -> list[tuple[object, object]]:
    """(get, set) function pairs of every loaded OpenBLAS library."""
    global _handles
    if _handles is not None:
        return _handles
    found: list[tuple[object, object]] = []
    try:
        with open("/proc/self/maps") as fh:
            paths = sorted({p for p in re.findall(r"(/\S+\.so[.\d]*)", fh.read()) if "openblas" in p.lower()})
    except OSError:
        paths = []
    for path in paths:
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for pre in _PREFIXES:
            for suf in _SUFFIXES:
                get = getattr(lib, f"{pre}openblas_get_num_threads{suf}", None)
                put = getattr(lib, f"{pre}openblas_set_num_threads{suf}", None)
                if get is not None and put is not None:
                    get.restype = ctypes.c_int
                    put.argtypes = [ctypes.c_int]
                    found.append((get, put))
    _handles = found
    log.debug("OpenBLAS thread control: %d libraries", len(found))
    return found


@contextlib.contextmanager
def single_threaded_blas():
    """Context manager: OpenBLAS uses one thread inside, the previous count is restored on exit (re-entrant)."""
    global _depth
    if os.environ.get("RAILMODAL_BLAS_THREADS", "").lower() == "keep":
        yield
        return
    with _lock:
        if _depth == 0:
            _saved.clear()
            for get, put in _find():
                try:
                    n = int(get())
                    if n > 1:
                        put(1)
                        _saved.append((put, n))
                except (OSError, ValueError, ctypes.ArgumentError):  # pragma: no cover - leave a foreign library alone
                    continue
        _depth += 1
    try:
        yield
    finally:
        with _lock:
            _depth -= 1
            if _depth == 0:
                for put, n in _saved:
                    put(n)
                _saved.clear()


def one_blas_thread(fn):
    """Decorator: run ``fn`` inside :func:`single_threaded_blas`."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        with single_threaded_blas():
            return fn(*args, **kwargs)

    return wrapper
