"""Argument checks shared by the lab's file writers: each raises ``ValueError`` naming the argument and the value."""

from __future__ import annotations

import numbers

import numpy as np

__all__ = ["MAX_I10", "is_int", "check_int", "check_text", "check_labels", "check_finite_array"]

MAX_I10 = 2**31 - 1  # largest label that fits an I10 field and int32


def is_int(value) -> bool:
    return isinstance(value, numbers.Integral) and not isinstance(value, (bool, np.bool_))


def check_int(name: str, value, lo: int, hi: int) -> int:
    if not is_int(value) or not lo <= int(value) <= hi:
        raise ValueError(f"{name} must be an integer in [{lo}, {hi}], got {value!r}")
    return int(value)


def check_text(name: str, value, *, max_len: int, allow_empty: bool = False) -> str:
    if not isinstance(value, str):
        raise ValueError(f"{name} must be a str, got {type(value).__name__} {value!r}")
    if not allow_empty and not value.strip():
        raise ValueError(f"{name} must not be empty, got {value!r}")
    if len(value) > max_len:
        raise ValueError(f"{name} must have at most {max_len} characters, got {len(value)}: {value!r}")
    if not (value.isascii() and value.isprintable()):
        raise ValueError(f"{name} must be printable ASCII without line breaks, got {value!r}")
    return value


def check_labels(name: str, value, hi: int = MAX_I10) -> np.ndarray:
    """Positive, unique integer labels as a 1-D int64 array."""
    arr = np.asarray(value)
    if arr.ndim != 1 or arr.size == 0:
        raise ValueError(f"{name} must be a non-empty 1-D sequence of integers, got shape {arr.shape}")
    if not np.issubdtype(arr.dtype, np.integer):
        raise ValueError(f"{name} must contain integers, got dtype {arr.dtype}")
    arr = arr.astype(np.int64)
    if arr.min() < 1 or arr.max() > hi:
        raise ValueError(f"{name} must lie in [1, {hi}], got min {arr.min()} and max {arr.max()}")
    uniq, counts = np.unique(arr, return_counts=True)
    if np.any(counts > 1):
        raise ValueError(f"{name} must be unique, got duplicates {uniq[counts > 1][:10].tolist()}")
    return arr


def check_finite_array(name: str, value, shape: tuple) -> np.ndarray:
    """Finite float64 array of the given shape (None entries are free)."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a real numeric array, got {type(value).__name__}") from exc
    if arr.ndim != len(shape) or any(s is not None and s != a for s, a in zip(shape, arr.shape)):
        want = "(" + ", ".join("*" if s is None else str(s) for s in shape) + ")"
        raise ValueError(f"{name} must have shape {want}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))[0].tolist()
        raise ValueError(f"{name} must be finite, got {arr[tuple(bad)]} at index {bad}")
    return arr
