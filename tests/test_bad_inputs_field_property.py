"""Property-based: a mutated field run never gives a traceback from ``railmodal field estimate``.

A short synthetic run (12 s, 6 accelerometers at 1 kHz, odometry, a balise) is written as ASAM MDF 4, as a long CSV
table and as a wide CSV, then mutated by hypothesis:

* **MDF 4** (binary): any byte XOR any non-zero mask; truncation anywhere;
* **CSV** (long and wide): any character replaced by any printable one, a line feed or a tab; truncation anywhere.

Each mutated file goes through the CLI in-process. It must either be estimated (exit status 0, with its report:
the mutation was a legal value, or what it broke is masked and logged by the quality control) or stop with exit
status 1 and a ``railmodal: error:`` message that names the run file; never a traceback, never another status.
The runs are seeded (``derandomize``), so the suite is reproducible.
"""

from __future__ import annotations

import string
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bad_inputs_support import run

pytestmark = pytest.mark.slow

SETTINGS = dict(derandomize=True, deadline=None, max_examples=int(__import__("os").environ.get("FIELD_PROP_EXAMPLES", 10)),
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
CHARACTERS = string.printable


@pytest.fixture(scope="module")
def field(tmp_path_factory):
    from estimator.io.registry import read_raw
    from estimator.io.tabular import write_run_table
    from estimator.io.wide import write_wide_csv
    from receptance import save_model
    from test_estimator_synthetic import control_model, make_run, sensor_table

    d = tmp_path_factory.mktemp("field_prop")
    sr = make_run(d, duration_s=12.0)
    raw, _ = read_raw(sr.path)
    files = {"mdf4": Path(sr.path), "csv-wide": write_wide_csv(raw.channels, raw.header, d / "wide.csv")}
    write_run_table(raw.channels, raw.header, d / "long.csv", "csv")
    files["csv"] = d / "long.csv"
    sensor_table().to_csv(d / "sensors.csv", index=False)
    save_model(control_model(), d / "model.npz")
    return d, {k: p.read_bytes() for k, p in files.items()}, {k: p.suffix for k, p in files.items()}


def _assert_estimated_or_named(field, tmp_path, fmt: str, data: bytes, capsys):
    d, _, suffix = field
    path = tmp_path / f"mutated{suffix[fmt]}"
    path.write_bytes(data)
    out = tmp_path / "out"
    code, stdout, stderr = run(["field", "estimate", "--run", str(path), "--sensors", str(d / "sensors.csv"),
                                "--model", str(d / "model.npz"), "--wheelbase", "2.2", "--models", "vertical",
                                "--out", str(out)], capsys)
    assert "Traceback" not in stderr + stdout, stderr[-2000:]
    assert code in (0, 1), (code, stderr[-2000:])
    if code == 1:
        assert "railmodal: error:" in stderr and path.name in stderr, stderr[-2000:]
    else:
        assert (out / "report.html").is_file()


def _mutated_text(clean: bytes, data) -> bytes:
    kind = data.draw(st.sampled_from(["replace", "truncate"]))
    if kind == "truncate":
        return clean[:data.draw(st.integers(0, len(clean) - 1))]
    i = data.draw(st.integers(0, len(clean) - 1))
    c = data.draw(st.sampled_from(CHARACTERS)).encode()
    return clean[:i] + c + clean[i + 1:]


@settings(**SETTINGS)
@given(data=st.data())
def test_a_mutated_mdf4_run_is_estimated_or_named(field, tmp_path_factory, capsys, data):
    clean = field[1]["mdf4"]
    if data.draw(st.booleans()):
        i = data.draw(st.integers(0, len(clean) - 1))
        mutated = clean[:i] + bytes([clean[i] ^ data.draw(st.integers(1, 255))]) + clean[i + 1:]
    else:
        mutated = clean[:data.draw(st.integers(0, len(clean) - 1))]
    _assert_estimated_or_named(field, tmp_path_factory.mktemp("mdf4"), "mdf4", mutated, capsys)


@settings(**SETTINGS)
@given(data=st.data())
def test_a_mutated_long_csv_run_is_estimated_or_named(field, tmp_path_factory, capsys, data):
    _assert_estimated_or_named(field, tmp_path_factory.mktemp("csv"), "csv", _mutated_text(field[1]["csv"], data), capsys)


@settings(**SETTINGS)
@given(data=st.data())
def test_a_mutated_wide_csv_run_is_estimated_or_named(field, tmp_path_factory, capsys, data):
    _assert_estimated_or_named(field, tmp_path_factory.mktemp("wide"), "csv-wide", _mutated_text(field[1]["csv-wide"], data), capsys)
