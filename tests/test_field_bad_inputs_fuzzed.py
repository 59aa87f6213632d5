"""Bad inputs of ``railmodal field estimate`` found by a fuzz probe: each is a named error or a reported finding.

Every case here is one the probe met (tracebacks T1-T6, silently wrong results S1-S8, messages that named no
file or the wrong cause U1-U8), made small: a noise run read through :func:`estimator.io.assemble.assemble_run`
or written as MDF 4, the control wheelset's model, a short synthetic run for the report. The physical limits
they hold the code to are the modules' constants (accelerations: :mod:`estimator.qc`; geometry:
:mod:`estimator.inversion`; curves: :mod:`estimator.io.line`; trolley levels: :func:`estimator.io.read_trolley`).
"""

from __future__ import annotations

import io
import json
import logging
import zipfile
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from estimator import (ChannelError, EstimatorConfig, RunFileError, SensorTableError, WheelsetModelError,
                       check_run, odometry_track, prepare, read_run)
from estimator.io import check_sensors, read_line, read_sensors, read_trolley
from estimator.io.assemble import assemble_run
from estimator.io.registry import RawChannel, RawRecording
from receptance.model_io import ModelFileError, load_model, save_model
from receptance.modification import ModificationError, modification_from_dict
from test_estimator_synthetic import SyntheticLine, control_model, make_run, sensor_table, write_mdf4

HEADER = {"run_id": "r7", "date": "2026-02-03", "direction": "forward", "train": "T12", "bogie": "B2",
          "line": "M1"}


def _channels(fs=1000.0, n=4000, seed=0, level_g=0.4):
    """Six accelerations of noise (``level_g`` RMS, in g), speed, position and a balise: a run's raw channels."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fs
    ch = {name: (t.copy(), rng.standard_normal(n) * level_g, "g") for name in sensor_table()["name"][:6]}
    to = np.arange(0, n / fs, 0.01)
    ch["SPEED"] = (to, np.full(to.size, 10.0), "m/s")
    ch["POSITION"] = (to, 100 + 10 * to, "m")
    ch["BALISE"] = (np.array([1.0]), np.array([110.0]), "m")
    return ch


def _assemble(ch, source="run.mf4"):
    raw = RawRecording({k: RawChannel(k, np.asarray(t, float), np.asarray(v, float), u)
                        for k, (t, v, u) in ch.items()}, dict(HEADER))
    return assemble_run(raw, check_sensors(sensor_table()), source, "mdf4")


@pytest.fixture(scope="module")
def model():
    return control_model()


@pytest.fixture(scope="module")
def model_file(tmp_path_factory, model):
    return save_model(model, tmp_path_factory.mktemp("model") / "hybrid_model.npz")


@pytest.fixture(scope="module")
def arrays(model_file):
    with np.load(model_file) as z:
        return {k: z[k] for k in z.files}


def _npz(path, arrays, **changes):
    a = {**arrays, **changes}
    np.savez_compressed(path, **a)
    return path


def _header(arrays, edit):
    h = json.loads(str(arrays["header"]))
    edit(h)
    return np.array(json.dumps(h))


# --------------------------------------------------------------------------------------------- T1 sensor table
@pytest.mark.parametrize("content", [b"", b"\n\n\n", b"\xef\xbb\xbf\r\n  \n"])
def test_an_empty_or_blank_sensor_table_is_named(tmp_path, content):
    """T1: pandas' separator sniffer raised a bare csv.Error on an empty file or one of blank lines."""
    p = tmp_path / "sensors.csv"
    p.write_bytes(content)
    with pytest.raises(SensorTableError, match=r"sensors.csv: the sensor table is empty"):
        read_sensors(p)


def test_a_sensor_table_without_separator_is_named(tmp_path):
    p = tmp_path / "sensors.csv"
    p.write_text("name\n\"a\nb\n")  # one column and an unterminated quote: no separator to sniff
    with pytest.raises(SensorTableError, match=r"sensors.csv: (not a readable CSV sensor table|missing column)"):
        read_sensors(p)


# --------------------------------------------------------------------------------------------- T2-T6, U7 model
def test_a_npy_array_a_zip_of_other_files_and_a_corrupt_member_are_named(tmp_path, model_file):
    """T2/T3: np.load returned an ndarray for a .npy named .npz (TypeError: no context manager), a zip of text
    files passed as an archive without a header, and a corrupt deflate stream raised zlib.error."""
    p = tmp_path / "npy.npz"
    buf = io.BytesIO()
    np.save(buf, np.arange(10))
    p.write_bytes(buf.getvalue())
    with pytest.raises(ModelFileError, match=r"npy.npz: a single .npy array, not a .npz"):
        load_model(p)
    p = tmp_path / "zip.npz"
    with zipfile.ZipFile(p, "w") as z:
        z.writestr("readme.txt", "hello")
    with pytest.raises(ModelFileError, match=r"zip.npz: a zip archive without NumPy arrays"):
        load_model(p)
    # one byte inverted inside header.npy's deflate stream: find one that breaks the stream (not only the CRC)
    data = model_file.read_bytes()
    info = zipfile.ZipFile(model_file).getinfo("header.npy")
    start = info.header_offset + 30 + len(info.filename) + len(info.extra)
    import zlib

    for k in range(start + 10, start + info.compress_size - 10):
        b = bytearray(data)
        b[k] ^= 0xFF
        try:
            zipfile.ZipFile(io.BytesIO(bytes(b))).read("header.npy")
        except zlib.error:
            break
        except Exception:  # noqa: BLE001 - a CRC error: try the next byte
            continue
    else:
        pytest.fail("no byte of the header's deflate stream gives zlib.error")
    p = tmp_path / "flip.npz"
    p.write_bytes(bytes(b))
    with pytest.raises(ModelFileError, match=r"flip.npz: not a readable .npz hybrid-model file \(error: Error -3"):
        load_model(p)


@pytest.mark.parametrize("raw, what", [("[1, 2, 3]", "a list"), ("42", "a number"), ('"text"', "a string")])
def test_a_header_that_is_not_a_json_object_is_named(tmp_path, arrays, raw, what):
    """T4: header.get on a list or a number raised AttributeError."""
    p = _npz(tmp_path / "m.npz", arrays, header=np.array(raw))
    with pytest.raises(ModelFileError, match=rf"m.npz: the header must be a JSON object .*got {what}"):
        load_model(p)


@pytest.mark.parametrize("edit, message", [
    (lambda a: {"elem_ptr": a["elem_ptr"][:-10]}, r"'elem_ptr' has \d+ entries, expected \d+"),
    (lambda a: {"elem_ptr": np.where(np.arange(a["elem_ptr"].size) == 3, np.nan, a["elem_ptr"].astype(float))},
     r"'elem_ptr' must be a 1-D integer array, got float64"),
    (lambda a: {"elem_id": a["elem_id"][:, None]}, r"'elem_id' must be a 1-D integer array, got int64 of shape"),
    (lambda a: {"elem_ptr": a["elem_ptr"][::-1].copy()}, r"'elem_ptr' must start at 0, never decrease"),
])
def test_inconsistent_element_arrays_are_named(tmp_path, arrays, edit, message):
    """T5: IndexError / TypeError while building the elements (outside the try)."""
    assert arrays["elem_id"].size > 10
    p = _npz(tmp_path / "m.npz", arrays, **edit(arrays))
    with pytest.raises(ModelFileError, match=rf"m.npz: array {message}"):
        load_model(p)


@pytest.mark.parametrize("edit, message", [
    (lambda h: h.update(points=[1, 2]), r"header 'points' must be an object .*got a list \[1, 2\]"),
    (lambda h: h.update(points={"contact_L": 5}), r"header 'points.contact_L' must be an object"),
    (lambda h: h.update(modifications=["a"]), r"header 'modifications\[0\]' must be an object .*got a string 'a'"),
    (lambda h: h.update(modifications={"kind": "x"}), r"header 'modifications' must be a list of objects"),
    (lambda h: h.update(channel_terms=[3]), r"header 'channel_terms\[0\]' must be an object"),
    (lambda h: h.update(test_only=[[1.0]]), r"header 'test_only\[0\]' must be a pair"),
    (lambda h: h.update(history=7), r"header 'history' must be a list"),
])
def test_header_entries_of_the_wrong_json_type_are_named(tmp_path, arrays, edit, message):
    """T6: points as a list, modifications as strings raised AttributeError outside the caught tuple."""
    p = _npz(tmp_path / "m.npz", arrays, header=_header(arrays, edit))
    with pytest.raises(ModelFileError, match=rf"m.npz: {message}"):
        load_model(p)


def test_a_stored_modification_that_is_not_an_object_is_a_modification_error():
    with pytest.raises(ModificationError, match="must be an object"):
        modification_from_dict("a")
    with pytest.raises(ModificationError, match="unknown modification kind"):
        modification_from_dict({"kind": ["a"]})


@pytest.mark.parametrize("key, bad", [("shapes", np.nan), ("shapes", np.inf), ("freqs_hz", np.nan),
                                      ("fe_freqs_hz", np.inf), ("zeta", np.nan), ("xyz", np.nan),
                                      ("test_mode", np.inf)])
def test_nan_or_inf_in_a_models_arrays_is_refused_at_load_naming_the_array(tmp_path, arrays, key, bad):
    """U7: NaN shapes loaded and failed much later as 'SVD did not converge'; the model's own checks named a
    mode but not the array."""
    a = arrays[key].astype(float).copy()
    a.flat[5] = bad
    p = _npz(tmp_path / "m.npz", arrays, **{key: a})
    with pytest.raises(ModelFileError, match=rf"m.npz: array '{key}' holds 1 non-finite value"):
        load_model(p)


def test_the_model_file_still_round_trips(model_file, model):
    back = load_model(model_file)
    assert np.array_equal(back.fe.xyz, model.fe.xyz) and back.points.keys() == model.points.keys()
    assert len(back.fe.elements) == len(model.fe.elements) and back.modifications == model.modifications


# --------------------------------------------------------------------------------------------- S1 MDF 4 header
def test_a_key_the_mdf4_header_comment_gives_twice_is_refused(tmp_path):
    """S1: asammdf parses the header comment into a dictionary and writes it back out: a key given twice in the
    file came back once, the last value winning (the run was reported as another run, exit 0). The comment is now
    read from the file's own block."""
    p = tmp_path / "dup.mf4"
    write_mdf4(p, _channels(), HEADER)
    data = p.read_bytes()
    old = b'<e name="train">T12</e>'
    assert data.count(old) == 1
    new = b'<e name="run_id">' + b"R" * (len(old) - len(b'<e name="run_id"></e>')) + b"</e>"
    assert len(new) == len(old)
    p.write_bytes(data.replace(old, new))
    from asammdf import MDF

    m = MDF(str(p))
    try:
        assert m.header.comment.count('name="run_id"') == 1  # what asammdf shows: the repetition is gone
    finally:
        m.close()
    with pytest.raises(RunFileError, match=r"dup.mf4: the header comment gives 'run_id' twice \('r7', then 'RR'\)"):
        read_run(p, sensor_table())
    from estimator.monitoring.headers import read_header

    with pytest.raises(RunFileError, match=r"gives 'run_id' twice"):
        read_header(p)
    # the same file without the repetition reads as before
    q = tmp_path / "ok.mf4"
    write_mdf4(q, _channels(), HEADER)
    run = read_run(q, sensor_table())
    assert run.header.run_id == "r7" and run.header.train == "T12"


# --------------------------------------------------------------------------------------------- U1, U2, U8 time
@pytest.mark.parametrize("where, bad", [(-1, np.inf), (1000, np.nan)])
def test_non_finite_time_stamps_are_named_with_the_channel(where, bad):
    """U1: an inf last time stamp gave 'cannot convert float infinity to integer' naming nothing."""
    ch = _channels()
    t, v, u = ch["ACC_W1L_Z"]
    t = t.copy()
    t[where] = bad
    ch["ACC_W1L_Z"] = (t, v, u)
    with pytest.raises(ChannelError, match=r"run.mf4: channel 'ACC_W1L_Z' has 1 non-finite time stamp"):
        _assemble(ch)


def test_a_nan_master_time_stamp_in_an_mdf4_is_not_called_two_different_channels(tmp_path):
    """U2: the single copy of a channel with a NaN time stamp compared unequal to itself, and the user was told
    to choose between channel groups."""
    ch = _channels()
    for name in list(ch)[:6]:
        t, v, u = ch[name]
        t = t.copy()
        t[1000] = np.nan
        ch[name] = (t, v, u)
    p = tmp_path / "nan_t.mf4"
    write_mdf4(p, ch, HEADER)
    with pytest.raises(ChannelError, match=r"nan_t.mf4: channel 'ACC_W1\w_\w' has 1 non-finite time stamp"):
        read_run(p, sensor_table())


def test_time_stamps_in_ms_are_named_at_reading():
    """U8: time stamps in ms (1 kHz read as 1 Hz) failed at the inversion with 'the inversion band 10-0.4 Hz is
    empty at fs = 1 Hz', naming neither the run nor the cause."""
    ch = {k: (t * 1000.0, v, u) for k, (t, v, u) in _channels().items()}
    with pytest.raises(ChannelError, match=r"run.mf4: the acceleration channels .* are sampled at 1 Hz .*Time "
                                           r"stamps in ms or µs rather than s\? \(that would be 1000 Hz"):
        _assemble(ch)


# --------------------------------------------------------------------------------------------- S2, S3 levels
def test_an_acceleration_in_adc_counts_is_a_channel_error_naming_unit_and_sensitivity():
    """S2: int16 counts recorded as 'g' (±50 g full scale: 655 counts per g) were estimated as corrugation of
    7-29 mm with no finding."""
    ch = _channels()
    t, v, u = ch["ACC_W1R_Z"]
    ch["ACC_W1R_Z"] = (t, np.round(v * 32767 / 50), u)
    with pytest.raises(ChannelError, match=r"run.mf4: channel 'ACC_W1R_Z' \(unit 'g', sensitivity 9.80665\): RMS "
                                           r"26\d(\.\d)? g .*raw ADC counts or mV"):
        _assemble(ch)
    ch = _channels()
    t, v, u = ch["ACC_W2L_Z"]
    ch["ACC_W2L_Z"] = (t, v * 1000, u)  # mV of a 1 mV/g... read as g: x1000
    with pytest.raises(ChannelError, match=r"channel 'ACC_W2L_Z' \(unit 'g', sensitivity 9.80665\): RMS "
                                           r"(39\d|40\d)(\.\d)? g"):
        _assemble(ch)
    # a real channel's level (0.4 g RMS, peaks of a few g) and a rough one (20 g RMS) pass
    _assemble(_channels())
    _assemble(_channels(level_g=20.0))


def test_isolated_non_physical_spikes_are_glitches_not_clipping_and_feed_no_coupling():
    """S3: 1e30 g at 10 samples was classed as clipping 'at 9.807e+30 m/s^2', and the other wheelset's rail
    coupling took those samples at full scale (its estimate 4.6e28 µm). They are glitches now: masked, reported
    as such, never saturated, never in the coupling."""
    from estimator.workflow import _coupling_valid

    ch = _channels()
    t, v, u = ch["ACC_W1L_Z"]
    v = v.copy()
    spikes = np.arange(1500, 3500, 200)
    v[spikes] = 1e30
    ch["ACC_W1L_Z"] = (t, v, u)
    run = _assemble(ch).apply_sensitivities()
    run = check_run(run, odometry_track(run.odometry, +1), EstimatorConfig())
    q = run.mask.table()
    assert not (q["kind"] == "clipping").any()
    g = q[q["kind"] == "glitch"]
    assert set(g["channel"]) == {"ACC_W1L_Z"} and g["reason"].str.contains("beyond 500 g").all()
    i = run.index("ACC_W1L_Z")
    assert run.mask.masked[i, spikes].all() and not run.mask.saturated.any()
    idx = np.array([i, run.index("ACC_W1R_Z")])
    steps: list = []
    assert not _coupling_valid(run, idx, 2, 1, steps)[0, spikes].any()  # per channel: ACC_W1L_Z's row
    # whatever mask a caller builds: a sample beyond what an axlebox produces is never taken as saturated
    forged = replace(run.mask, saturated=run.mask.masked.copy())
    assert not _coupling_valid(replace(run, mask=forged), idx, 2, 1, steps)[0, spikes].any()


# --------------------------------------------------------------------------------------------- S4, S6 geometry
def _scaled(model, fe_factor=1.0, point_factor=1.0):
    from receptance.dofs import Point

    fe = replace(model.fe, xyz=model.fe.xyz * fe_factor)
    pts = {n: Point(n, p.fe_node, None if p.xyz is None else tuple(np.asarray(p.xyz) * point_factor))
           for n, p in model.points.items()}
    return replace(model, fe=fe, points=pts)


def test_a_model_in_mm_is_refused_naming_what_was_found(model):
    """S4: a model whose node coordinates were in mm estimated roughness of 4-31 million µm with no warning."""
    with pytest.raises(WheelsetModelError, match=r"point axlebox_L .* is 969 m from its FE node .*look like mm"):
        prepare(_scaled(model, fe_factor=1000.0), sensor_table())
    with pytest.raises(WheelsetModelError, match=r"the axleboxes are 1940 m apart .*likely in mm: 1.94 m"):
        prepare(_scaled(model, 1000.0, 1000.0), sensor_table())
    # a rolling radius (contact point from the axle's axis) that is not a railway wheel's
    from receptance.dofs import Point

    pts = dict(model.points)
    pts["contact_L"] = Point("contact_L", pts["contact_L"].fe_node, (0.0, -0.75, -0.041))
    with pytest.raises(WheelsetModelError, match=r"point contact_L .* is 0.041 m from the axle's axis"):
        prepare(replace(model, points=pts), sensor_table())
    prepare(model, sensor_table())


@pytest.mark.parametrize("edit, message", [
    (lambda d: d.assign(x=d["y"], y=d["x"]), r"row 2 \('ACC_W1L_Z', side L\): mounting point \(-0.97, 0, 0\) m is "
                                             r"1.37 m from the model's side-L axlebox .*x and y swapped\?"),
    (lambda d: d.assign(y=d["y"].where(d["name"] != "ACC_W2R_Z", 0.05)),
     r"row 6 \('ACC_W2R_Z', side R\): mounting point \(0, 0.05, 0\) m is 0.92 m from"),
    (lambda d: d.assign(z=d["z"].where(d["name"] != "ACC_W2L_Z", 0.5)),
     r"row 5 \('ACC_W2L_Z', side L\): mounting point \(0, -0.97, 0.5\) m is 0.5 m from .*within 0.3 m of it$"),
])
def test_a_sensor_row_not_on_its_sides_axlebox_is_refused_naming_the_row(tmp_path, model, edit, message):
    """S6: x and y swapped put the axlebox sensors at y = 0; the estimate came out 9x too high with exit 0."""
    d = edit(sensor_table())
    p = tmp_path / "sensors.csv"
    d.to_csv(p, index=False)
    with pytest.raises(SensorTableError, match=rf"sensors.csv: {message}"):
        prepare(model, p)


def test_a_sensor_a_few_centimetres_off_the_axlebox_centre_is_accepted(model):
    """Within the axlebox housing (0.15 m forward, 0.12 m up) a mounting is plausible: kept as written."""
    d = sensor_table()
    d = d.assign(x=d["x"].where(d["direction"] != "y", 0.15), z=d["z"].where(d["direction"] != "y", 0.12))
    fm = prepare(model, d)
    lateral = fm.sensors[fm.sensors["direction"] == "y"]
    assert len(lateral) and (lateral["x"] == 0.15).all() and (lateral["z"] == 0.12).all()


# --------------------------------------------------------------------------------------------- S5, U3 line.json
LINE = {"name": "test", "id": "T", "length_m": 1000, "sleeper_spacing_m": 0.75,
        "sections": [{"id": "A", "from_m": 0, "to_m": 500}],
        "curves": [{"id": "C1", "from_m": 100, "to_m": 300, "radius_m": 400, "direction": "right", "cant_mm": 40,
                    "transition_in_m": 40, "transition_out_m": 40}]}


@pytest.mark.parametrize("key, value, message", [
    ("radius_m", 1e-9, r"radius_m 1e-09 m is outside 10-100000 m"),
    ("radius_m", 5.0, r"radius_m 5 m is outside 10-100000 m"),
    ("radius_m", 0.3, r"radius_m 0.3 m is outside .*\(a radius in km\? 300 m\)"),
    ("radius_m", 400000.0, r"radius_m 400000 m is outside .*\(a radius in mm\? 400 m\)"),
    ("radius_m", 1e300, r"radius_m 1e\+300 m is outside"),
    ("cant_mm", 1e6, r"cant_mm 1e\+06 mm is outside 0-200 mm"),
    ("cant_mm", -40.0, r"cant_mm -40 mm is outside 0-200 mm"),
    ("cant_mm", 0.04, r"cant_mm 0.04 mm is outside 0-200 mm \(a cant in m\? 40 mm\)"),
])
def test_a_curve_radius_or_cant_outside_physical_limits_is_refused(tmp_path, key, value, message):
    """S5: radius 1e-9 m was accepted and changed the estimate (rail L 100-300 mm 43.9 -> 242 µm); cant was not
    range-checked at all."""
    line = dict(LINE, curves=[dict(LINE["curves"][0], **{key: value})])
    p = tmp_path / "line.json"
    p.write_text(json.dumps(line))
    with pytest.raises(RunFileError, match=rf"line.json: curve 'C1': {message}"):
        read_line(p)


def test_plausible_curves_pass(tmp_path):
    line = dict(LINE, curves=[dict(LINE["curves"][0], radius_m=18.0, cant_mm=0),
                              dict(LINE["curves"][0], id="C2", from_m=400, to_m=600, radius_m=8000, cant_mm=180)])
    p = tmp_path / "line.json"
    p.write_text(json.dumps(line))
    assert [c.radius_m for c in read_line(p).curves] == [18.0, 8000.0]


def test_deeply_nested_json_is_a_named_error(tmp_path):
    """U3: RecursionError escaped read_line ('maximum recursion depth exceeded ...' without the file)."""
    p = tmp_path / "line.json"
    p.write_text('{"curves": ' + "[" * 100_000 + "]" * 100_000 + "}")
    with pytest.raises(RunFileError, match=r"line.json: not a JSON line description \(.*nested too deeply"):
        read_line(p)


# --------------------------------------------------------------------------------------------- U6 sensor cells
@pytest.mark.parametrize("col, value, message", [
    ("wheelset", np.inf, r"row 8 \('SPEED'\): wheelset of a speed channel must be empty \(or 0, 1, 2\), got inf"),
    ("wheelset", 1e30, r"row 8 \('SPEED'\): wheelset of a speed channel must be empty .*got 1e\+30"),
    ("x", np.inf, r"row 8 \('SPEED'\): column 'x' must be empty or a finite number, got inf"),
    ("z", "abc", r"row 8 \('SPEED'\): column 'z' must be empty or a finite number, got 'abc'"),
])
def test_inf_or_junk_in_an_unused_sensor_table_cell_is_named(tmp_path, col, value, message):
    """U6: inf in the SPEED row's wheelset cell raised pandas' IntCastingNaNError without file or row; 1e30 was cast
    silently."""
    d = sensor_table().astype({col: object})
    d.loc[d["name"] == "SPEED", col] = value
    p = tmp_path / "sensors.csv"
    d.to_csv(p, index=False)
    with pytest.raises(SensorTableError, match=rf"sensors.csv: {message}"):
        read_sensors(p)


# --------------------------------------------------------------------------------------------- S7, U4 trolley
def _trolley(path, scale=1.0, x0=400.0, n=20_000, extra=None):
    """A trolley record: broadband roughness of ~10 µm RMS on a 1 mm grid, both rails, times ``scale``."""
    rng = np.random.default_rng(3)
    x = x0 + 1e-3 * np.arange(n)
    rows = []
    for rail in "LR":
        r = np.convolve(rng.standard_normal(n), np.ones(20) / np.sqrt(20), "same") * 10.0 * scale
        rows.append(pd.DataFrame({"chainage_m": np.round(x, 4), "rail": rail, "roughness_um": r}))
    df = pd.concat(rows + ([pd.DataFrame(extra)] if extra else []), ignore_index=True)
    df.to_csv(path, index=False)
    return path


@pytest.mark.parametrize("scale, message", [
    (1e-3, r"RMS roughness 0.0\d+ µm \(-6\d dB re the ISO 3095 limit's 11.7 µm\) is not a rail roughness record in "
           r"µm .*likely values in mm written under roughness_um \(10.\d µm RMS once converted\)"),
    (1e-6, r"RMS roughness 1.\d+e-05 µm .*likely values in m written under roughness_um"),
    (1e3, r"RMS roughness 1\.\d+e\+04 µm \(\+59 dB .*likely values in nm \(or µm multiplied by 1000\)"),
])
def test_a_trolley_record_in_another_unit_is_refused_naming_the_likely_unit(tmp_path, scale, message):
    """S7: mm (or m) written under roughness_um gave a comparison +65 (+125) dB off, with exit 0 and no word."""
    p = _trolley(tmp_path / "trolley.csv", scale)
    with pytest.raises(RunFileError, match=rf"trolley.csv: rail L: {message}"):
        read_trolley(p)


def test_a_trolley_level_merely_outside_real_rails_is_a_warning_carried_in_the_frame(tmp_path, caplog):
    p = _trolley(tmp_path / "trolley.csv", 0.02)  # 0.2 µm RMS: smoother than a ground rail
    with caplog.at_level(logging.WARNING, logger="estimator"):
        tr = read_trolley(p)
    assert "rail L: RMS roughness 0.2" in caplog.text and "outside the 0.3-1000 µm of real rails" in caplog.text
    assert any("outside the 0.3-1000 µm" in n for n in tr.attrs["notes"])
    assert not read_trolley(_trolley(tmp_path / "ok.csv")).attrs["notes"]


def test_inf_chainage_is_left_out_by_name_and_an_absurd_span_is_refused(tmp_path, caplog):
    """U4: an inf chainage gave 'cannot convert float infinity to integer', one reading at 1e12 m asked numpy for
    7 PiB ('out of memory'); inf roughness was kept silently."""
    from estimator.reference import reference_indexes

    p = _trolley(tmp_path / "inf.csv", extra={"chainage_m": [np.inf, 500.0], "rail": ["L", "R"],
                                               "roughness_um": [1.0, np.inf]})
    with caplog.at_level(logging.WARNING, logger="estimator"):
        tr = read_trolley(p)
    assert "2 trolley row(s) without a numeric chainage or roughness left out (file line(s) 40002, 40003)" \
        in caplog.text and "inf" in caplog.text
    assert np.isfinite(tr[["chainage_m", "roughness_m"]].to_numpy()).all()
    reference_indexes(tr, source=str(p))
    p = _trolley(tmp_path / "far.csv", extra={"chainage_m": [1e12], "rail": ["L"], "roughness_um": [1.0]})
    with pytest.raises(RunFileError, match=r"far.csv: rail L: chainage 400-1e\+12 m at a 0.001 m step is "
                                           r"1e\+15 samples; a reference rail holds at most 50000000"):
        reference_indexes(read_trolley(p), source=str(p))


def test_a_trolley_file_without_one_readable_row_is_refused(tmp_path):
    p = tmp_path / "t.csv"
    p.write_text("chainage_m,rail,roughness_um\nx,L,1\n1.0,R,abc\n")
    with pytest.raises(RunFileError, match=r"t.csv: no trolley row with a finite numeric chainage and roughness"):
        read_trolley(p)


# --------------------------------------------------------------------------------------------- S8, U5 report
@pytest.fixture(scope="module")
def estimate(tmp_path_factory, model):
    """A 16 s run over 40-140 m (vertical model, wheelbase given): an estimate to write with references."""
    from estimator import estimate_run

    tmp = tmp_path_factory.mktemp("est")
    sr = make_run(tmp, model, duration_s=16, balises=(60.0,), start_m=40.0,
                  line=SyntheticLine(length_m=200.0, sinusoids={"L": [(0.06, 20e-6, 60, 150)], "R": []}))
    line = dict(LINE, curves=[dict(LINE["curves"][0], from_m=60, to_m=130, transition_in_m=10, transition_out_m=10)])
    (tmp / "line.json").write_text(json.dumps(line))
    fm = prepare(model, sensor_table(), line=tmp / "line.json",
                 config=EstimatorConfig(models=("vertical",), wheelbase_m=sr.wheelbase))
    return estimate_run(sr.path, fm)


def test_a_reference_that_does_not_overlap_the_run_is_stated(tmp_path, estimate, caplog):
    """S8: a trolley record 5 km away (or with its chainage in mm) gave comparison.csv n_windows = 0 everywhere
    and not a word."""
    from estimator.export import write_estimate
    from estimator.reference import reference_indexes

    p = _trolley(tmp_path / "far.csv", x0=5400.0)
    ref = reference_indexes(read_trolley(p), source=str(p))
    with caplog.at_level(logging.WARNING, logger="estimator"):
        files = write_estimate(estimate, tmp_path / "out", reference=ref, figures=False)
    want = r"far.csv: the reference \(rail L 5400.0-5420.0 m, rail R 5400.0-5420.0 m\) does not overlap the run's " \
           r"\d+\.\d-1\d\d\.\d m: nothing compared"
    assert pytest.importorskip("re").search(want, caplog.text)
    summ = json.loads(files["summary"].read_text())
    assert summ["reference"]["rails_compared"] == [] and any("does not overlap" in n
                                                             for n in summ["reference"]["notes"])
    html = files["report"].read_text()
    assert "does not overlap the run" in html and "No reference rail could be compared" in html
    # the chainage written in mm: said so, with where it would lie in m
    from estimator.reference import reference_overlap

    p = _trolley(tmp_path / "mm.csv", x0=60.0, n=60_000)
    tr = read_trolley(p)
    tr["chainage_m"] *= 1000.0
    (note,) = reference_overlap(estimate, reference_indexes(tr, source=str(p)))
    assert "mm.csv: the reference (rail L 60000.0-119999.0 m" in note and \
        "chainages in mm? they would cover rail L 60.0-120.0 m, rail R 60.0-120.0 m" in note


def test_a_reference_with_no_comparable_rail_does_not_fail_the_written_estimate(tmp_path, estimate, caplog):
    """U5: with no rail of >= 10 readings, plot_spectra raised KeyError 'rail' after the whole estimate."""
    from estimator.export import write_estimate
    from estimator.reference import reference_indexes

    p = tmp_path / "few.csv"
    pd.DataFrame({"chainage_m": [60.0, 61.0, 120.0], "rail": ["L", "L", "R"],
                  "roughness_um": [3.0, 5.0, 4.0]}).to_csv(p, index=False)
    with caplog.at_level(logging.WARNING, logger="estimator"):
        ref = reference_indexes(read_trolley(p), source=str(p))
    assert "few.csv: no reference rail could be compared" in caplog.text
    files = write_estimate(estimate, tmp_path / "out", reference=ref)
    assert any(k.startswith("figure_spectra") for k in files)
    html = files["report"].read_text()
    assert "No reference rail could be compared" in html and "rail L has 2 sample(s)" in html
    summ = json.loads(files["summary"].read_text())
    assert any("no reference rail could be compared" in n for n in summ["reference"]["notes"])


def test_a_reference_over_the_run_is_compared_without_remarks(tmp_path, estimate):
    from estimator.export import write_estimate
    from estimator.reference import reference_indexes

    p = _trolley(tmp_path / "ok.csv", x0=60.0, n=60_000)
    files = write_estimate(estimate, tmp_path / "out", reference=reference_indexes(read_trolley(p), source=str(p)),
                           figures=False)
    summ = json.loads(files["summary"].read_text())
    assert summ["reference"]["notes"] == [] and summ["reference"]["rails_compared"] == ["L", "R"]
    assert "No reference rail could be compared" not in files["report"].read_text()
