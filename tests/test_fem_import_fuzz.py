"""Fuzzing the fem_import readers with hypothesis.

Every outcome of reading a damaged file must be either a valid FEModes or an
FEReadError / UnknownFormatError (both ValueError subclasses naming the
file): no IndexError, KeyError, UnboundLocalError or bare Exception from the
parsing layers leaking out, and no hang (each read runs under an alarm).
Truncation must never silently corrupt: a truncated file that still reads
gives exactly the first modes of the complete file.

Examples are derandomised (deterministic in CI) and few; the small 5-node
files keep each read at a few milliseconds.  For a longer, random campaign
set ``RAILMODAL_FUZZ_EXAMPLES`` (e.g. 5000).
"""

from __future__ import annotations

import contextlib
import os
import signal

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import fem_import
from fem_import import FEModes, FEReadError, UnknownFormatError
from test_fem_import_models import write_small_punch, write_small_uff, write_small_uff_2414

_LONG = os.environ.get("RAILMODAL_FUZZ_EXAMPLES")
FUZZ = settings(max_examples=int(_LONG or 60), deadline=None, derandomize=_LONG is None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
FEW = settings(max_examples=4, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])


class Hang(Exception):
    pass


@contextlib.contextmanager
def alarm(seconds: float):
    def on_alarm(signum, frame):
        raise Hang(f"reader still running after {seconds} s")

    old = signal.signal(signal.SIGALRM, on_alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def check_outcome(path, seconds=10.0, **kw):
    """Read ``path``: the FEModes, or None for the two accepted errors; anything else propagates."""
    try:
        with alarm(seconds):
            modes = fem_import.read(path, **kw)
    except (FEReadError, UnknownFormatError) as exc:
        assert str(path) in str(exc)
        return None
    assert isinstance(modes, FEModes)
    m, n = modes.shapes.shape[:2]
    assert m == modes.freqs_hz.size >= 1 and n == modes.node_ids.size >= 1
    assert np.all(np.isfinite(modes.shapes)) and np.all(np.isfinite(modes.freqs_hz))
    assert np.all(modes.freqs_hz >= 0)
    return modes


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    root = tmp_path_factory.mktemp("fuzz")
    out = {}
    for kind, writer in (("uff", write_small_uff), ("unv", write_small_uff_2414), ("pch", write_small_punch)):
        path = writer(root / f"small.{kind}")
        out[kind] = (path.read_bytes(), fem_import.read(path))
    out["dir"] = root
    return out


def _target(files, name):
    return files["dir"] / name


@pytest.mark.parametrize("kind", ["uff", "unv", "pch"])
@FUZZ
@given(data=st.data())
def test_truncation_never_leaks_nor_corrupts(files, kind, data):
    raw, full = files[kind]
    cut = data.draw(st.integers(0, len(raw) - 1), label="cut")
    path = _target(files, f"cut_{kind}.{kind}")
    path.write_bytes(raw[:cut])
    modes = check_outcome(path)
    if modes is not None:
        k = len(modes)
        # all modes only when the cut fell in the last line (its end of line, or the punch line counter)
        assert k < len(full) or b"\n" not in raw[cut:-1]
        if not np.array_equal(modes.node_ids, full.node_ids):
            # a punch file cut between two grid cards of its first mode is a valid punch file of fewer
            # grids (nothing in the format tells); its values must still be the right ones
            assert kind == "pch" and k == 1 and set(modes.node_ids.tolist()) < set(full.node_ids.tolist())
        rows = [full.index(n) for n in modes.node_ids]
        np.testing.assert_array_equal(modes.shapes, full.shapes[:k, rows])
        np.testing.assert_array_equal(modes.freqs_hz, full.freqs_hz[:k])


NUMERIC = set(b"0123456789.+-EeD")
REPLACEMENTS = st.sampled_from(list(b"0123456789.+-EeDdxXnNaA /\t\n*#$") + [0, 255])


@pytest.mark.parametrize("kind", ["uff", "unv", "pch"])
@FUZZ
@given(data=st.data())
def test_byte_corruption_in_numeric_fields(files, kind, data):
    raw, _ = files[kind]
    positions = [i for i, b in enumerate(raw) if b in NUMERIC]
    n_bytes = data.draw(st.integers(1, 3), label="n_bytes")
    buf = bytearray(raw)
    for _ in range(n_bytes):
        buf[data.draw(st.sampled_from(positions), label="pos")] = data.draw(REPLACEMENTS, label="byte")
    path = _target(files, f"bad_{kind}.{kind}")
    path.write_bytes(bytes(buf))
    check_outcome(path)
    check_outcome(path, format="nastran-punch" if kind == "pch" else "uff")


@pytest.mark.parametrize("kind", ["uff", "unv", "pch"])
@FUZZ
@given(data=st.data())
def test_line_edits(files, kind, data):
    """Deleted, duplicated or swapped lines."""
    lines = files[kind][0].splitlines(keepends=True)
    op = data.draw(st.sampled_from(["delete", "duplicate", "swap"]), label="op")
    i = data.draw(st.integers(0, len(lines) - 1), label="i")
    j = data.draw(st.integers(0, len(lines) - 1), label="j")
    if op == "delete":
        del lines[i]
    elif op == "duplicate":
        lines.insert(i, lines[i])
    else:
        lines[i], lines[j] = lines[j], lines[i]
    path = _target(files, f"edit_{kind}.{kind}")
    path.write_bytes(b"".join(lines))
    check_outcome(path)


HEADERS = {"uff": b"    -1\n    55\n", "unv": b"    -1\n  2414\n",
           "pch": b"$TITLE   = GARBAGE\n$EIGENVECTOR\n$REAL OUTPUT\n"}


@pytest.mark.parametrize("kind", ["none", "uff", "unv", "pch"])
@FUZZ
@given(body=st.one_of(st.binary(max_size=600),
                      st.text(alphabet=st.sampled_from(list("0123456789 .-+EG$\n-CONT=ABMODE")), max_size=600)
                      .map(lambda s: s.encode())))
def test_garbage(files, kind, body):
    """Random bytes, alone or behind a header that the sniffers accept (so the reader itself must cope)."""
    path = _target(files, f"junk_{kind}.dat")
    path.write_bytes(HEADERS.get(kind, b"") + body)
    check_outcome(path)


@pytest.mark.parametrize("name", ["fe_design.uff", "fe_design.pch"])
@FEW
@given(fraction=st.floats(0.05, 0.999))
def test_truncated_real_files(control_dir, tmp_path_factory, name, fraction):
    raw = (control_dir / name).read_bytes()
    path = tmp_path_factory.getbasetemp() / f"cut_{name}"
    path.write_bytes(raw[: int(fraction * len(raw))])
    modes = check_outcome(path, seconds=30.0)
    if modes is not None:  # only if the cut fell exactly between two modes
        assert len(modes) < 25
