"""Opening ASAM MDF files (MDF 3 and 4) through asammdf, with damaged files named instead of half read.

Shared by the hammer-test reader (:mod:`ema.hammer_mdf`) and the field run reader (:mod:`estimator.io.mdf4`),
which imports it from here because imports flow ``ema`` <- ``estimator``.
"""

from __future__ import annotations

import gc
import sys
from pathlib import Path

__all__ = ["open_mdf", "sniff_mdf"]


def sniff_mdf(head: bytes) -> bool:
    """True for an MDF file: its identification block starts with ``MDF`` (ASAM MDF 4.2 clause 6.2, ``id_file``)."""
    return head[:3] == b"MDF"


def _quiet_half_built_mdf(hook):
    """An unraisable-exception hook that drops the AttributeError of a half-built asammdf ``MDF4.__del__``."""
    def quiet(unraisable):
        owner = getattr(unraisable.object, "__qualname__", "")
        if unraisable.exc_type is AttributeError and owner.endswith("MDF4.__del__"):
            return
        hook(unraisable)
    return quiet


def open_mdf(path: Path, error: type[Exception], what: str = "MDF file"):
    """``asammdf.MDF(path)``, or ``error`` naming the file and asammdf's reason.

    A damaged file leaves asammdf's reader half built; its ``__del__`` then fails on attributes ``__init__``
    never set, and Python would print that traceback on the user's terminal after the named error. The object
    is collected here with that one report silenced.

    Parameters
    ----------
    path : Path
    error : exception type
        Raised for an unreadable file (the caller's error family).
    what : str
        What the file should be, in the message (``"MDF 4 file"``).
    """
    from asammdf import MDF

    reason = None
    hook = sys.unraisablehook
    sys.unraisablehook = _quiet_half_built_mdf(hook)
    try:
        try:
            return MDF(str(path))
        except Exception as exc:  # noqa: BLE001 - asammdf raises many kinds on a damaged file
            reason = f"{type(exc).__name__}: {exc}"
        gc.collect()  # the half-built reader dies with the exception's frames
    finally:
        sys.unraisablehook = hook
    raise error(f"{path}: not a readable {what} ({reason}); the file may be truncated or corrupt")
