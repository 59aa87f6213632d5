"""Run identification with single-threaded BLAS (private helper).

Identification performs hundreds of small and mid-sized dense operations
(one QR and a few products per model order, per Levenberg–Marquardt step).
With multi-threaded OpenBLAS on a machine whose cores are also busy with
other work, the BLAS threads spin-wait for each other at every call: measured
on 2 cores under load, ``identify`` took 4.1 s with two BLAS threads and
1.5 s with one (idle, both are about equal because the matrices are small).
:func:`one_blas_thread` limits the BLAS libraries to one thread for the
duration of a call and restores them afterwards, through ``threadpoolctl``.
Set ``RAILMODAL_BLAS_THREADS=keep`` to leave the thread count alone.
"""

from __future__ import annotations

import functools
import os

from threadpoolctl import threadpool_limits

__all__ = ["one_blas_thread"]


def one_blas_thread(fn):
    """Decorator: run ``fn`` with one BLAS thread (see module docstring)."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        if os.environ.get("RAILMODAL_BLAS_THREADS", "").lower() == "keep":
            return fn(*args, **kwargs)
        with threadpool_limits(limits=1, user_api="blas"):
            return fn(*args, **kwargs)

    return wrapper
