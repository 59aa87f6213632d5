"""Small UFF58 files written the ways real acquisition front ends write them, for tests/test_lab_real_exports.py.

The writer (:func:`uff58`) is independent of the toolkit and of the virtual lab's exporter: it formats UFF58 /
58b records itself (ASCII or binary, single or double precision, either byte order, any unit labels, function
types, specific data types, abscissa spacing and labels, text encoding), as Testlab, PULSE/BK Connect, m+p,
Dewesoft, HBK and NI scripts do (the same logic as the probe of the lab readers, /tmp/probe_lab/uffw.py).

The data are a 3-mode, 3-accelerometer structure hit by a half-sine hammer pulse (:func:`hits`): a few hits of
2048 samples at 2048 Hz, so a file reads and identifies in a fraction of a second.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

FS = 2048.0
N = 2048
FORCE_NODE = 900
ACC_NODES = (101, 102, 103)
#: (frequency [Hz], damping ratio) of the three modes
MODES = ((62.0, 0.012), (147.0, 0.008), (236.0, 0.015))
#: mode shapes at the accelerometers (rows) and at the hammer point
SHAPES = np.array([[1.0, 0.6, -0.4], [0.5, -0.9, 0.7], [-0.3, 0.4, 1.0]])
SHAPE_AT_FORCE = np.array([1.0, 0.8, 0.6])
BAND = ("20", "400")
MAX_ORDER = "24"


def table(**columns) -> pd.DataFrame:
    """The channel table: the hammer at node 900 (along -z), accelerometers 101-103 along +z."""
    rows = [dict(node=FORCE_NODE, name="hammer", quantity="force", unit="N", x=0.0, y=0.0, z=0.1, dx=0.0, dy=0.0,
                 dz=-1.0)]
    rows += [dict(node=n, name=f"acc_{n}", quantity="acceleration", unit="m/s^2", x=0.2 * k, y=0.0, z=0.0,
                  dx=0.0, dy=0.0, dz=1.0) for k, n in enumerate(ACC_NODES)]
    df = pd.DataFrame(rows)
    for key, values in columns.items():
        df[key] = values
    return df


def accelerance(f_hz: np.ndarray, shift: float = 0.0) -> np.ndarray:
    """Accelerance (n_ch, n_f) [m/s^2/N] of the structure at ``s = i omega + shift`` (an exponential window of
    decay ``shift`` evaluates the FRF there: its poles move by ``-shift``)."""
    s = 2j * np.pi * np.asarray(f_hz, float) + shift
    h = np.zeros((len(ACC_NODES), s.size), complex)
    for r, (fr, zr) in enumerate(MODES):
        wr = 2 * np.pi * fr
        h += np.outer(SHAPES[:, r] * SHAPE_AT_FORCE[r], s ** 2 / (s ** 2 + 2 * zr * wr * s + wr ** 2))
    return h


def hits(n_hits: int = 4, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Force (n_hits, N) [N] and accelerations (n_hits, 3, N) [m/s^2] of ``n_hits`` hits (linear convolution of a
    half-sine pulse with the impulse response, a little noise)."""
    rng = np.random.default_rng(seed)
    m = 4 * N
    f = np.fft.rfftfreq(m, 1 / FS)
    h = accelerance(f)
    force = np.zeros((n_hits, N))
    resp = np.zeros((n_hits, len(ACC_NODES), N))
    for k in range(n_hits):
        k0 = 100 + 7 * k
        width = 3
        pulse = np.zeros(m)
        pulse[k0:k0 + width + 1] = (180.0 + 15 * k) * np.sin(np.pi * np.arange(width + 1) / width)
        a = np.fft.irfft(h * np.fft.rfft(pulse)[None, :], n=m, axis=1)[:, :N]
        force[k] = pulse[:N] + 0.02 * rng.standard_normal(N)
        resp[k] = a + 1e-3 * rng.standard_normal((len(ACC_NODES), N))
    return force, resp


def specs(force: np.ndarray, resp: np.ndarray, *, acc_unit: str = "m/s^2", force_unit: str = "N",
          acc_factor: float = 1.0, force_factor: float = 1.0, **common) -> list[dict]:
    """One dataset spec per channel and hit, hit-major, the data divided by the unit's factor to SI
    (``acc_factor``, ``force_factor``) as a front end exporting in that unit writes them; ``common`` goes into
    every spec (a callable value is called with the spec and returns the value)."""
    out = []
    for h in range(force.shape[0]):
        chans = [(FORCE_NODE, -3, 13, "Force", force_unit, force[h] / force_factor)]
        chans += [(n, 3, 12, "Acceleration", acc_unit, resp[h, j] / acc_factor) for j, n in enumerate(ACC_NODES)]
        for node, direction, spec, lab, unit, data in chans:
            s = dict(func_type=1, ver_num=h + 1, load_case_id=0, rsp_node=node, rsp_dir=direction,
                     ref_node=FORCE_NODE, ref_dir=-3, id1=f"channel {node}", id2=f"hit {h + 1}",
                     abscissa_min=0.0, abscissa_inc=1 / FS, ordinate_spec=spec, ord_lab=lab, ord_unit=unit,
                     data=np.asarray(data, float))
            for key, value in common.items():
                s[key] = value(s) if callable(value) else value
            out.append(s)
    return out


def frf_specs(h: np.ndarray, f_hz: np.ndarray, *, num_unit: str = "m/s^2", den_unit: str = "N", spec: int = 12,
              id3: str = "01-Jan-24 10:00:00", ref_node=FORCE_NODE, **common) -> list[dict]:
    """One FRF dataset (function type 4) per accelerometer."""
    out = []
    for j, node in enumerate(ACC_NODES):
        s = dict(func_type=4, ver_num=1, load_case_id=0, rsp_node=node, rsp_dir=3, ref_node=0, ref_dir=-3,
                 id1=f"FRF {node}", id3=id3, abscissa_min=float(f_hz[0]), abscissa_inc=float(f_hz[1] - f_hz[0]),
                 abscissa_spec=18, abscissa_lab="Frequency", abscissa_unit="Hz", ordinate_spec=spec,
                 ord_lab="Accelerance", ord_unit=num_unit, den_spec=13, den_lab="Force", den_unit=den_unit,
                 data=np.asarray(h[j], complex))
        s["ref_node"] = ref_node(s) if callable(ref_node) else ref_node
        for key, value in common.items():
            s[key] = value(s) if callable(value) else value
        out.append(s)
    return out


def _e13(v: float, fmt: str) -> str:
    if fmt == "1P":
        return f"{v:13.5E}"
    if v == 0:
        return f"{'0.00000E+00':>13}"
    m, e = f"{abs(v):.4E}".split("E")
    return f"{'-' if v < 0 else ''}0.{m.replace('.', '')}E{int(e) + 1:+03d}".rjust(13)


def uff58(d: dict, *, binary: bool = False, double: bool = True, eol: str = "\n", encoding: str = "latin-1",
          byte_order: int = 1, xfmt: str = "1P") -> bytes:
    """One dataset 58 (or 58b) as bytes.

    ``d`` keys: func_type, ver_num, load_case_id, rsp_ent_name, rsp_node, rsp_dir, ref_ent_name, ref_node,
    ref_dir, id1..id5, abscissa_min, abscissa_inc, spacing (1 even, 0 uneven with ``x``), abscissa_spec,
    abscissa_lab, abscissa_unit, ordinate_spec, ord_lab, ord_unit, den_spec, den_lab, den_unit, data (real or
    complex). ``encoding`` encodes the text records (labels and names: latin-1 as Windows front ends, or utf-8).
    """
    data = np.asarray(d["data"])
    cplx = np.iscomplexobj(data)
    spacing = int(d.get("spacing", 1))
    ord_type = (6 if double else 5) if cplx else (4 if double else 2)
    n = data.size
    lines = []
    if binary:
        per = (2 if cplx else 1) + (1 if spacing == 0 else 0)
        nb = n * per * (8 if double else 4)
        lines.append(f"{58:6d}b{byte_order:6d}{2:6d}{11:12d}{nb:12d}{0:6d}{0:6d}{0:12d}{0:12d}")
    else:
        lines.append(f"{58:6d}")
    for k in range(1, 6):
        lines.append(f"{str(d.get(f'id{k}', 'NONE')):<80}")
    lines.append(f"{d['func_type']:5d}{d.get('func_id', 1):10d}{d['ver_num']:5d}{d.get('load_case_id', 0):10d}"
                 f" {str(d.get('rsp_ent_name', 'NONE')):<10}{d['rsp_node']:10d}{d['rsp_dir']:4d}"
                 f" {str(d.get('ref_ent_name', 'NONE')):<10}{d['ref_node']:10d}{d['ref_dir']:4d}")
    lines.append(f"{ord_type:10d}{n:10d}{spacing:10d}{_e13(d['abscissa_min'], xfmt)}{_e13(d['abscissa_inc'], xfmt)}"
                 f"{_e13(0.0, xfmt)}")
    lines.append(f"{d.get('abscissa_spec', 17):10d}{0:5d}{0:5d}{0:5d} {d.get('abscissa_lab', 'Time'):<20} "
                 f"{d.get('abscissa_unit', 's'):<20}")
    lines.append(f"{d['ordinate_spec']:10d}{0:5d}{0:5d}{0:5d} {d.get('ord_lab', 'NONE'):<20} "
                 f"{d.get('ord_unit', 'NONE'):<20}")
    lines.append(f"{d.get('den_spec', 0):10d}{0:5d}{0:5d}{0:5d} {d.get('den_lab', 'NONE'):<20} "
                 f"{d.get('den_unit', 'NONE'):<20}")
    lines.append(f"{0:10d}{0:5d}{0:5d}{0:5d} {'NONE':<20} {'NONE':<20}")
    head = ("    -1" + eol + eol.join(lines) + eol).encode(encoding)
    if cplx:
        vals = np.empty(2 * n)
        vals[0::2], vals[1::2] = data.real, data.imag
    else:
        vals = data.astype(float)
    if spacing == 0:
        per = 3 if cplx else 2
        v2 = np.empty(per * n)
        v2[0::per] = np.asarray(d["x"], float)
        if cplx:
            v2[1::3], v2[2::3] = data.real, data.imag
        else:
            v2[1::2] = vals
        vals = v2
    if binary:
        bo = "<" if byte_order == 1 else ">"
        body = vals.astype(bo + ("f8" if double else "f4")).tobytes()
    else:
        if not double:
            s = [f"{v:13.5E}" for v in vals]
            rows = ["".join(s[i:i + 6]) for i in range(0, len(s), 6)]
        elif spacing == 1:
            s = [f"{v:20.12E}" for v in vals]
            rows = ["".join(s[i:i + 4]) for i in range(0, len(s), 4)]
        elif cplx:  # 1E13.5, 2E20.12 per line
            rows = [f"{vals[i]:13.5E}{vals[i + 1]:20.12E}{vals[i + 2]:20.12E}" for i in range(0, len(vals), 3)]
        else:  # 2(E13.5,E20.12)
            s = [f"{vals[i]:13.5E}{vals[i + 1]:20.12E}" for i in range(0, len(vals), 2)]
            rows = ["".join(s[i:i + 2]) for i in range(0, len(s), 2)]
        body = (eol.join(rows) + eol).encode("ascii")
    return head + body + ("    -1" + eol).encode()


def write(path, dsets: list[dict], **kw) -> Path:
    """The datasets as one universal file (function ids numbered in file order); returns the path."""
    path = Path(path)
    with open(path, "wb") as fh:
        for i, s in enumerate(dsets, 1):
            fh.write(uff58(dict(s, func_id=s.get("func_id", i)), **kw))
    return path


def write_table(path, df: pd.DataFrame) -> Path:
    path = Path(path)
    df.to_csv(path, index=False)
    return path
