"""Issue 11, property-based: mutated good files never give a traceback or a silently different result.

Good files of a small virtual-lab campaign (4 clean hits, 8 channels, 1 s) are
mutated by hypothesis — byte flips, truncation, a channel scaled as by a wrong
sensitivity — and run through the CLI. Each run must either succeed with the
clean result (every mode within 0.05 % in frequency of the clean
identification; the same FE partners for the pairing) or exit with status 1
and a ``railmodal: error:`` message naming the mutated file; never a
traceback, never another status.

What is mutated and how:

* **UFF58** (binary hammer test, ``lab identify``): any byte XOR any
  non-zero mask; a byte in a dataset's ASCII header; truncation anywhere; one
  channel multiplied in every hit by 1e-6 .. 1e6.
* **UFF55** (ASCII FE export, ``lab pair``): a character replaced by one that
  is not a digit or sign (a digit turned into another digit, or ``+`` into
  ``-``, writes another valid number — an edited value, not a corruption any
  reader can see; frequencies of that kind are the pairing checks' business);
  truncation; one mode's shape scaled (MAC is scale-free: the pairing must not
  change).
* **CSV** (channel table, ``lab identify``): any character replaced by any
  printable one; truncation; one sensor's position scaled.

The runs are seeded (``derandomize``) so the suite is reproducible; the
numbers of examples (16, 8, 12) keep the file under a minute on 2 cores.
"""

from __future__ import annotations

import string

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bad_inputs_support import (
    SMALL_ORDER,
    datasets58,
    identify_and_pair,
    modes_csv,
    run,
    same_modes,
    scale_node,
)
from lab_data.cache import campaign_dir

pytestmark = pytest.mark.slow

SETTINGS = dict(derandomize=True, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                        HealthCheck.too_slow])
PAIR_BAND = ("60", "140")  # two modes: the pairing renders stay few


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    folder = tmp_path_factory.mktemp("prop")
    modes, pairing = identify_and_pair(campaign_dir("control"), folder)
    narrow = folder / "modes_narrow"
    assert run_ok(["lab", "identify", "--hammer", str(folder / "flexural.uff"), "--channels",
                   str(folder / "flexural_channels.csv"), "--band", *PAIR_BAND, "--max-order", SMALL_ORDER,
                   "--out", str(narrow)])
    assert run_ok(["lab", "pair", "--modes", str(narrow), "--fem", str(folder / "fe_design.uff"), "--out",
                   str(folder / "pairing_narrow")])
    return {
        "folder": folder,
        "uff58": (folder / "flexural.uff").read_bytes(),
        "csv": (folder / "flexural_channels.csv").read_text(),
        "uff55": (folder / "fe_design.uff").read_text(),
        "modes": modes_csv(modes),
        "narrow": narrow,
        "pairing": pd.read_csv(folder / "pairing_narrow" / "pairing.csv", dtype={"fe_modes": str}),
    }


def run_ok(args) -> bool:
    from railmodal.cli import main

    return main(["-q", *args]) == 0


def check_outcome(code, out, err, name, same) -> None:
    """Success with the clean result, or status 1 with a named error; nothing else."""
    assert "Traceback" not in err, err
    assert code in (0, 1), (code, err)
    if code == 0:
        assert same(), out
    else:
        assert err.startswith("railmodal: error:") and name in err, err


def _identify(folder, hammer, channels, out, capsys):
    return run(["-q", "lab", "identify", "--hammer", str(hammer), "--channels", str(channels), "--band", "60", "300",
                "--max-order", SMALL_ORDER, "--out", str(out)], capsys)


# ---------------------------------------------------------------- UFF58
def uff58_mutation(raw: bytes):
    sets = datasets58(raw)
    headers = [(d.header, d.data) for d in sets]
    nodes = sorted({d.node for d in sets if d.node != 900})
    flip = st.tuples(st.just("flip"), st.integers(0, len(raw) - 1), st.integers(1, 255))
    header = st.tuples(st.just("flip"), st.sampled_from(headers).flatmap(lambda hd: st.integers(hd[0], hd[1] - 1)),
                       st.integers(1, 255))
    cut = st.tuples(st.just("cut"), st.integers(0, len(raw) - 1), st.just(0))
    scale = st.tuples(st.just("scale"), st.sampled_from(nodes), st.sampled_from([1e-6, 1e-3, 9.81, 1e3, 1e6]))
    return st.one_of(flip, header, cut, scale)


def apply58(raw: bytes, m) -> bytes:
    kind, a, b = m
    buf = bytearray(raw)
    if kind == "flip":
        buf[a] ^= b
    elif kind == "cut":
        del buf[a:]
    else:
        scale_node(buf, a, b)
    return bytes(buf)


@settings(max_examples=16, **SETTINGS)
@given(data=st.data())
def test_mutated_uff58_identifies_the_clean_modes_or_names_the_error(lab, tmp_path_factory, capsys, data):
    m = data.draw(uff58_mutation(lab["uff58"]))
    tmp = tmp_path_factory.mktemp("m58")
    (tmp / "mutated.uff").write_bytes(apply58(lab["uff58"], m))
    code, out, err = _identify(lab["folder"], tmp / "mutated.uff", lab["folder"] / "flexural_channels.csv",
                               tmp / "o", capsys)
    check_outcome(code, out, err, "mutated.uff", lambda: same_modes(modes_csv(tmp / "o"), lab["modes"]))
    if code != 0:
        assert not (tmp / "o").exists()


# ---------------------------------------------------------------- UFF55
NOT_A_NUMBER_CHANGE = [c for c in string.printable if c not in string.digits + "+-"]


def uff55_mutation(text: str):
    first55 = text.index("\n    55\n")
    flip = st.tuples(st.just("flip"), st.integers(first55, len(text) - 1), st.sampled_from(NOT_A_NUMBER_CHANGE))
    cut = st.tuples(st.just("cut"), st.integers(first55, len(text) - 1), st.just(""))
    scale = st.tuples(st.just("scale"), st.integers(7, 25), st.sampled_from(["0.001", "10", "1000"]))
    return st.one_of(flip, cut, scale)


def apply55(text: str, m, fe) -> str:
    kind, a, b = m
    if kind == "flip":
        return text if text[a] == b else text[:a] + b + text[a + 1:]
    if kind == "cut":
        return text[:a]
    return None  # scaled mode: written from the FE modes


@settings(max_examples=8, **SETTINGS)
@given(data=st.data())
def test_mutated_uff55_pairs_like_the_clean_export_or_names_the_error(lab, tmp_path_factory, capsys, data):
    import fem_import
    from bad_inputs_support import write_fe

    m = data.draw(uff55_mutation(lab["uff55"]))
    tmp = tmp_path_factory.mktemp("m55")
    path = tmp / "mutated.uff"
    text = apply55(lab["uff55"], m, None)
    if text is None:
        fe = fem_import.read(lab["folder"] / "fe_design.uff")
        shapes = fe.shapes.copy()
        shapes[m[1] - 1] *= float(m[2])
        write_fe(path, fe, shapes=shapes)
    else:
        path.write_text(text)
    code, out, err = run(["-q", "lab", "pair", "--modes", str(lab["narrow"]), "--fem", str(path), "--out",
                          str(tmp / "o")], capsys)

    def same():
        got = pd.read_csv(tmp / "o" / "pairing.csv", dtype={"fe_modes": str})
        clean = lab["pairing"]
        paired = clean["test_mode"].notna()
        return (list(got["fe_modes"].fillna("")[got["test_mode"].notna()]) == list(clean["fe_modes"].fillna("")[paired])
                and np.allclose(got["f_fe_hz"][got["test_mode"].notna()], clean["f_fe_hz"][paired], rtol=5e-4))

    check_outcome(code, out, err, "mutated.uff", same)


# ---------------------------------------------------------------- CSV
def csv_mutation(text: str, n_rows: int):
    flip = st.tuples(st.just("flip"), st.integers(0, len(text) - 1), st.sampled_from(string.printable))
    cut = st.tuples(st.just("cut"), st.integers(0, len(text) - 1), st.just(""))
    move = st.tuples(st.just("move"), st.integers(1, n_rows - 1), st.sampled_from(["100", "1000", "0.001"]))
    return st.one_of(flip, cut, move)


@settings(max_examples=12, **SETTINGS)
@given(data=st.data())
def test_mutated_channel_table_identifies_the_clean_modes_or_names_the_error(lab, tmp_path_factory, capsys, data):
    text = lab["csv"]
    table = pd.read_csv(lab["folder"] / "flexural_channels.csv")
    kind, a, b = data.draw(csv_mutation(text, len(table)))
    if kind == "flip":
        text = text[:a] + b + text[a + 1:]
    elif kind == "cut":
        text = text[:a]
    else:
        table.loc[a, ["x", "y", "z"]] *= float(b)
        text = table.to_csv(index=False)
    tmp = tmp_path_factory.mktemp("mcsv")
    (tmp / "mutated.csv").write_text(text)
    code, out, err = _identify(lab["folder"], lab["folder"] / "flexural.uff", tmp / "mutated.csv", tmp / "o", capsys)
    check_outcome(code, out, err, "mutated.csv", lambda: same_modes(modes_csv(tmp / "o"), lab["modes"]))
