"""Reading FRFs computed by the acquisition front-end: UFF58 function type 4.

Some labs export FRFs instead of time histories: one UFF58 dataset per
response/reference pair, function type 4 ("frequency response function"),
complex ordinate, frequency abscissa. :func:`read_frf_uff` turns such a file
into the toolkit's :class:`~ema.frf.FrequencyResponse`; ordinary coherence
datasets (function type 6) for the same pairs are attached when present for
every pair.

The quantity follows the ordinate's specific data type (12 acceleration ->
accelerance, 11 velocity -> mobility, 8 displacement -> receptance; the
denominator must be a force, 13 or 9, or unknown, 0). When the file leaves the
ordinate type unknown (0), the ordinate units label decides (``m/s^2/N``,
``m/s/N``, ``m/N``, ``g/N``, ...); otherwise pass ``quantity=``. Data are
converted to SI by their unit labels (numerator in g, mm/s², mm/s, mm or µm,
denominator in kN or lbf: front-ends commonly export accelerance in g/N, as
one label or as ``g`` over ``N``); unlabelled data are taken as SI.

Exponential window.  An H1 estimated through an exponential window of decay
``a`` carries poles shifted by ``−a``; the identification removes the shift
when it knows ``a`` (:attr:`~ema.frf.FrequencyResponse.exp_window_decay`).
UFF58 has no field for it, so :func:`write_frf_uff` records it in ID line 3
as ``exp_window_decay=<a> 1/s`` and :func:`read_frf_uff` reads it back from
there (any writer may follow the convention); otherwise pass
``exp_window_decay=`` (0 for FRFs without window or already corrected).

:func:`write_frf_uff` writes FRFs (and their coherence) the way acquisition
systems export them, through pyuff: ASCII or binary (58b), double precision.
"""

from __future__ import annotations

import logging
import os
import re
from pathlib import Path

import numpy as np
import pandas as pd

from .channels import UNIT_TO_SI, read_channels, validate_channels
from .frf import QUANTITIES, FrequencyResponse
from .hammer_io import ChannelMismatchError, FunctionTypeError, SamplingError, UFFReadError, _read_uff_sets

__all__ = ["read_frf_uff", "write_frf_uff"]

log = logging.getLogger("ema")

_SPEC_TO_QUANTITY = {12: "accelerance", 11: "mobility", 8: "receptance"}
_UNITS_TO_QUANTITY = {
    "m/s^2/n": "accelerance", "m/s2/n": "accelerance", "(m/s^2)/n": "accelerance", "m/n/s^2": "accelerance",
    "m/s/n": "mobility", "(m/s)/n": "mobility",
    "m/n": "receptance",
}
_FORCE_SPECS = {0, 9, 13}
_QUANTITY_TO_SPEC = {"accelerance": 12, "mobility": 11, "receptance": 8}
_QUANTITY_UNITS = {"accelerance": "m/s^2/N", "mobility": "m/s/N", "receptance": "m/N"}
#: numerator unit labels (lower case, no blanks) -> (factor to SI, quantity); front-ends often write g/N
_NUMERATOR_SI = {**{u: (f, "accelerance") for u, f in UNIT_TO_SI["acceleration"].items()},
                 "m/s": (1.0, "mobility"), "mm/s": (1e-3, "mobility"),
                 "m": (1.0, "receptance"), "mm": (1e-3, "receptance"), "um": (1e-6, "receptance"),
                 "\u00b5m": (1e-6, "receptance")}
_DENOMINATOR_SI = UNIT_TO_SI["force"]
_DECAY = re.compile(r"exp_window_decay\s*=\s*([0-9.eE+-]+)")


def _frf_units(d: dict) -> tuple[float, str | None, str]:
    """(factor to SI, quantity, label) of an FRF dataset from its ordinate and denominator unit labels.

    ``g/N`` as one numerator label or as ``g`` over ``N``; a bracketed numerator (``(m/s^2)/N``) too. Labels it
    does not know give factor 1 and no quantity (the data are taken as SI).
    """
    num = str(d.get("ordinate_axis_units_lab", "") or "").strip().lower().replace(" ", "")
    den = str(d.get("orddenom_axis_units_lab", "") or "").strip().lower().replace(" ", "")
    label = num + (f" / {den}" if den else "")
    if den in ("", "none") and "/" in num:
        head, _, tail = num.rpartition("/")
        if tail in _DENOMINATOR_SI:
            num, den = head, tail
    if num.startswith("(") and num.endswith(")"):
        num = num[1:-1]
    top = _NUMERATOR_SI.get(num)
    bottom = 1.0 if den in ("", "none") else _DENOMINATOR_SI.get(den)
    if top is None or bottom is None:
        return 1.0, None, label
    return top[0] / bottom, top[1], label


def _dir_label(code: int) -> str:
    if code == 0:
        return "s"
    return ("+" if code > 0 else "-") + ("x", "y", "z", "rx", "ry", "rz")[abs(code) - 1]


def read_frf_uff(path: str | os.PathLike, channels_csv=None, *, quantity: str | None = None,
                 exp_window_decay: float | None = None) -> FrequencyResponse:
    """Read FRFs (UFF58, function type 4) into a :class:`~ema.frf.FrequencyResponse`.

    Parameters
    ----------
    path : str or os.PathLike
        The universal file (ASCII 58 or binary 58b).
    channels_csv : str, os.PathLike, pandas.DataFrame or None
        Channel table. With it, outputs are labelled by channel name in table
        order (every acceleration row must have an FRF and every FRF a row),
        the input by the force channel's name, and ``channels`` is set.
        Without it, labels are ``"<node>:<dir>"`` (e.g. ``"101:+z"``; ``s``
        for a scalar / off-axis direction) in file order.
    quantity : {"accelerance", "mobility", "receptance"}, optional
        Overrides the quantity read from the file.
    exp_window_decay : float, optional
        Exponential-window decay of the FRFs [1/s]; default: the
        ``exp_window_decay=`` note of ID line 3 (module docstring), else 0.

    Returns
    -------
    FrequencyResponse
        Reference node(s) = inputs; coherence attached when the file has a
        coherence dataset (function type 6) for every pair.

    Raises
    ------
    UFFReadError
        Unreadable, truncated or corrupt file.
    FunctionTypeError
        A dataset is neither an FRF nor a coherence, the ordinate is not
        complex, the denominator is not a force, or the quantity cannot be told.
    ChannelMismatchError
        Duplicate pairs, missing pairs, or file and table disagree.
    SamplingError
        The datasets do not share one frequency axis.
    """
    p = Path(os.fspath(path))
    if not p.is_file():
        raise FileNotFoundError(f"FRF file {str(p)!r} does not exist")
    if quantity is not None and quantity not in QUANTITIES:
        raise ValueError(f"quantity must be one of {sorted(QUANTITIES)} or None, got {quantity!r}")
    table = None
    if channels_csv is not None:
        table = (validate_channels(channels_csv, source=f"channel table for {p.name}")
                 if isinstance(channels_csv, pd.DataFrame) else read_channels(channels_csv))
    log.info("reading FRFs %s", p)
    src = str(p)
    dsets = _read_uff_sets(p, 58)
    frfs: dict[tuple[tuple[int, int], tuple[int, int]], dict] = {}
    cohs: dict[tuple[tuple[int, int], tuple[int, int]], dict] = {}
    for d in dsets:
        for key in ("func_type", "rsp_node", "rsp_dir", "ref_node", "ref_dir", "ord_data_type",
                    "ordinate_spec_data_type", "orddenom_spec_data_type"):
            v = d.get(key)
            if v is None or isinstance(v, str) or not np.isfinite(v):
                raise UFFReadError(f"{src}: dataset {d['_index']}: header field {key!r} is unreadable ({v!r})")
        ft = int(d["func_type"])
        pair = ((int(d["rsp_node"]), int(d["rsp_dir"])), (int(d["ref_node"]), int(d["ref_dir"])))
        where = f"{src}: dataset {d['_index']} (response {pair[0][0]}:{_dir_label(pair[0][1])}, reference " \
                f"{pair[1][0]}:{_dir_label(pair[1][1])})"
        if ft == 4:
            target = frfs
            if int(d["ord_data_type"]) not in (5, 6):
                raise FunctionTypeError(f"{where}: an FRF must have complex ordinates (data type 5 or 6), got "
                                        f"{int(d['ord_data_type'])}")
            den = int(d["orddenom_spec_data_type"])
            if den not in _FORCE_SPECS:
                raise FunctionTypeError(f"{where}: the FRF denominator must be a force (specific data type 13 or 9), "
                                        f"got {den}")
        elif ft == 6:
            target = cohs
        else:
            hint = "; time histories are read with ema.read_hammer" if ft == 1 else ""
            raise FunctionTypeError(f"{where}: function type {ft}; expected 4 (FRF) or 6 (coherence){hint}")
        if pair in target:
            raise ChannelMismatchError(f"{where}: the same response/reference pair appears twice "
                                       f"(datasets {target[pair]['_index']} and {d['_index']})")
        n = len(d["data"])
        if n != int(d.get("num_pts", n)) or n == 0:
            raise UFFReadError(f"{where}: the header announces {d.get('num_pts')} values but the dataset holds {n}")
        target[pair] = d
    if not frfs:
        raise FunctionTypeError(f"{src}: no FRF dataset (function type 4) in the file")

    # quantity
    first = next(iter(frfs.values()))
    if quantity is None:
        specs = {int(d["ordinate_spec_data_type"]) for d in frfs.values()}
        if len(specs) > 1:
            raise FunctionTypeError(f"{src}: the FRFs mix ordinate types {sorted(specs)}; expected one quantity")
        spec = specs.pop()
        if spec in _SPEC_TO_QUANTITY:
            quantity = _SPEC_TO_QUANTITY[spec]
        elif spec == 0:
            lab = str(first.get("ordinate_axis_units_lab", "")).strip().lower().replace(" ", "")
            quantity = _frf_units(first)[1] or _UNITS_TO_QUANTITY.get(lab)
            if quantity is None:
                raise FunctionTypeError(
                    f"{src}: cannot tell accelerance, mobility or receptance: ordinate type unknown (0) and units "
                    f"label {first.get('ordinate_axis_units_lab')!r}; pass quantity= explicitly"
                )
        else:
            raise FunctionTypeError(
                f"{src}: ordinate specific data type {spec} is not a structural response (expected 12 "
                f"acceleration, 11 velocity or 8 displacement)"
            )

    # common frequency axis
    x0 = np.asarray(first["x"], dtype=float)
    for pair, d in list(frfs.items()) + list(cohs.items()):
        x = np.asarray(d["x"], dtype=float)
        if x.shape != x0.shape or not np.allclose(x, x0, rtol=1e-6, atol=1e-9 * max(1.0, float(np.abs(x0).max()))):
            raise SamplingError(
                f"{src}: dataset {d['_index']} (response node {pair[0][0]}) has a frequency axis of {x.size} lines "
                f"{x[:1]}..{x[-1:]} Hz that differs from dataset {first['_index']} ({x0.size} lines "
                f"{x0[:1]}..{x0[-1:]} Hz); all FRFs must share one axis"
            )
    if x0.size == 0 or not np.all(np.isfinite(x0)) or np.any(x0 < 0) or np.any(np.diff(x0) <= 0):
        raise SamplingError(f"{src}: the frequency axis must be finite, non-negative and increasing")

    outs = list(dict.fromkeys(pr[0] for pr in frfs))
    ins = list(dict.fromkeys(pr[1] for pr in frfs))
    if table is not None:
        force_node = int(table.loc[table["quantity"] == "force", "node"].iloc[0])
        acc = table[table["quantity"] == "acceleration"].reset_index(drop=True)
        by_node = {}
        for o in outs:
            if o[0] not in set(acc["node"]):
                raise ChannelMismatchError(f"{src}: response node {o[0]} has FRFs but no acceleration row in the "
                                           f"channel table; add it or remove it from the file")
            if o[0] in by_node:
                raise ChannelMismatchError(f"{src}: response node {o[0]} appears with two directions "
                                           f"({_dir_label(by_node[o[0]][1])}, {_dir_label(o[1])})")
            by_node[o[0]] = o
        missing = [f"{r.name!r} (node {r.node})" for r in acc.itertuples() if r.node not in by_node]
        if missing:
            raise ChannelMismatchError(f"{src}: channel(s) {', '.join(missing)} of the table have no FRF in the file")
        bad_ref = [i for i in ins if i[0] != force_node]
        if bad_ref:
            raise ChannelMismatchError(f"{src}: reference node {bad_ref[0][0]} is not the table's force node "
                                       f"{force_node}")
        outs = [by_node[int(n)] for n in acc["node"]]
        out_labels = list(acc["name"])
        in_labels = [str(table.loc[table["quantity"] == "force", "name"].iloc[0])]
        channels = acc
    else:
        out_labels = [f"{n}:{_dir_label(c)}" for n, c in outs]
        in_labels = [f"{n}:{_dir_label(c)}" for n, c in ins]
        channels = None
        if len(set(out_labels)) != len(out_labels) or len(set(in_labels)) != len(in_labels):
            raise ChannelMismatchError(f"{src}: response/reference labels are not unique: {out_labels} / {in_labels}")

    data = np.empty((len(outs), len(ins), x0.size), complex)
    coh = np.empty(data.shape) if cohs else None
    converted: set[str] = set()
    for i, o in enumerate(outs):
        for k, r in enumerate(ins):
            if (o, r) not in frfs:
                raise ChannelMismatchError(f"{src}: no FRF for response {o[0]}:{_dir_label(o[1])} and reference "
                                           f"{r[0]}:{_dir_label(r[1])}")
            factor, _, label = _frf_units(frfs[(o, r)])
            if factor != 1.0:
                converted.add(label)
            data[i, k] = np.asarray(frfs[(o, r)]["data"]) * factor
            if coh is not None:
                if (o, r) in cohs:
                    coh[i, k] = np.real(cohs[(o, r)]["data"])
                else:
                    log.warning("%s: coherence missing for response %s; coherence not attached", src, o[0])
                    coh = None
    if not np.all(np.isfinite(data)):
        raise UFFReadError(f"{src}: the FRF data contain NaN or infinite values")
    if exp_window_decay is None:
        notes = {float(m.group(1)) for d in frfs.values() for m in [_DECAY.search(str(d.get("id3", "")))] if m}
        if len(notes) > 1:
            raise UFFReadError(f"{src}: the FRFs record different exponential windows {sorted(notes)} 1/s in ID line 3")
        exp_window_decay = notes.pop() if notes else 0.0
    if not (np.isfinite(exp_window_decay) and exp_window_decay >= 0):
        raise ValueError(f"exp_window_decay must be a finite decay >= 0 [1/s], got {exp_window_decay!r}")
    history = (f"read_frf_uff {src}",)
    if converted:
        note = f"converted to SI ({_QUANTITY_UNITS[quantity]}) from {', '.join(sorted(converted))}"
        log.info("%s: %s", src, note)
        history += (note,)
    frf = FrequencyResponse(freqs_hz=x0, data=data, outputs=tuple(out_labels), inputs=tuple(in_labels),
                            quantity=quantity, coherence=coh, channels=channels, history=history,
                            exp_window_decay=float(exp_window_decay))
    log.info("read %s: %s", src, frf)
    return frf


_BINARY_HEADER = re.compile(rb"(?m)^    58b(\s*\d+)(\s*\d+)(\s*\d+)( *\d+)")


def _fix_binary_byte_counts(path: Path, n_bytes: list[int]) -> None:
    """Write the true data size into each 58b header: pyuff 2.5 writes ``8 * num_pts`` bytes for complex data too
    (it writes ``16 * num_pts``), and a strict reader frames datasets by that count."""
    raw = path.read_bytes()
    headers = list(_BINARY_HEADER.finditer(raw))
    if len(headers) != len(n_bytes):
        raise OSError(f"{path}: expected {len(n_bytes)} binary 58 headers after writing, found {len(headers)}")
    out, last = [], 0
    for m, n in zip(headers, n_bytes):
        out.append(raw[last:m.start(4)])
        out.append(f"{n:12d}".encode())
        last = m.end(4)
    out.append(raw[last:])
    path.write_bytes(b"".join(out))


def _direction_code(d) -> int:
    """UFF direction code of a unit vector: ±1..3 along an axis, 0 (scalar) for an oblique one."""
    d = np.asarray(d, float)
    k = int(np.argmax(np.abs(d)))
    if np.isclose(abs(d[k]), 1.0, atol=1e-9):
        return int(np.sign(d[k])) * (k + 1)
    return 0


def write_frf_uff(frf: FrequencyResponse, path: str | os.PathLike, channels=None, *, binary: bool = False,
                  coherence: bool = True, description: str = "railmodal FRF export") -> Path:
    """Write single-reference FRFs as UFF58 function type 4 (and their coherence as type 6), as a lab system would.

    Parameters
    ----------
    frf : FrequencyResponse
        One input; quantity accelerance, mobility or receptance.
    path : str or os.PathLike
        The file written (overwritten).
    channels : pandas.DataFrame or path, optional
        The channel table giving each output's node and direction and the
        force node (default: ``frf.channels`` and the table's force row are
        needed, so give the table when ``frf.channels`` lacks the force).
    binary : bool
        Binary 58b instead of ASCII.
    coherence : bool
        Also write the coherence (when the FRF has one).
    description : str
        ID line 1.

    Returns
    -------
    Path

    Raises
    ------
    ValueError
        Several inputs, an output without a channel row, no force row.
    """
    import pyuff  # third-party writer, imported where needed

    if frf.n_in != 1:
        raise ValueError(f"write_frf_uff writes single-reference FRFs, got {frf.n_in} inputs")
    if channels is None:
        raise ValueError("give the channel table (channels=): it holds the nodes, directions and the force row")
    table = channels if isinstance(channels, pd.DataFrame) else read_channels(channels)
    acc = table[table["quantity"] == "acceleration"].set_index(table.loc[table["quantity"] == "acceleration",
                                                                         "name"].astype(str))
    force = table[table["quantity"] == "force"]
    if len(force) != 1:
        raise ValueError(f"the channel table must have one force row, found {len(force)}")
    missing = [o for o in frf.outputs if o not in acc.index]
    if missing:
        raise ValueError(f"outputs {missing} have no acceleration row in the channel table")
    f = np.asarray(frf.freqs_hz, float)
    even = f.size > 1 and np.allclose(np.diff(f), f[1] - f[0], rtol=1e-9, atol=0)
    ref = force.iloc[0]
    ref_dir = _direction_code((ref["dx"], ref["dy"], ref["dz"]))
    spec = _QUANTITY_TO_SPEC[frf.quantity]
    note = f"exp_window_decay={float(frf.exp_window_decay)!r} 1/s"
    sets = []
    for i, name in enumerate(frf.outputs):
        row = acc.loc[name]
        common = dict(type=58, binary=int(bool(binary)), id1=description[:80], id2=f"channel {name}"[:80], id3=note,
                      id4="NONE", id5="NONE", load_case_id=0, rsp_ent_name=str(name)[:10], rsp_node=int(row["node"]),
                      rsp_dir=_direction_code((row["dx"], row["dy"], row["dz"])), ref_ent_name=str(ref["name"])[:10],
                      ref_node=int(ref["node"]), ref_dir=ref_dir, abscissa_spacing=int(even),
                      abscissa_min=float(f[0]), abscissa_inc=float(f[1] - f[0]) if f.size > 1 else 0.0,
                      abscissa_spec_data_type=18, abscissa_axis_units_lab="Hz", x=f, num_pts=f.size)
        sets.append(dict(common, func_type=4, ver_num=1, ord_data_type=6, data=np.asarray(frf.data[i, 0], complex),
                         ordinate_spec_data_type=spec, ordinate_axis_units_lab=_QUANTITY_UNITS[frf.quantity],
                         orddenom_spec_data_type=13, orddenom_axis_units_lab="N"))
        if coherence and frf.coherence is not None:
            sets.append(dict(common, func_type=6, ver_num=1, ord_data_type=4,
                             data=np.asarray(frf.coherence[i, 0], float), ordinate_spec_data_type=0,
                             ordinate_axis_units_lab="NONE", orddenom_spec_data_type=0))
    out = Path(os.fspath(path))
    if out.exists():
        out.unlink()
    try:
        pyuff.UFF(str(out)).write_sets(sets, mode="add")
    except Exception as exc:  # pyuff raises bare Exception; name the file
        raise OSError(f"{out}: pyuff could not write the FRF datasets ({exc})") from exc
    if binary:
        _fix_binary_byte_counts(out, [8 * d["num_pts"] * (2 if np.iscomplexobj(d["data"]) else 1) for d in sets])
    log.info("wrote %d FRF datasets%s to %s (%s)", len(frf.outputs),
             " and their coherence" if coherence and frf.coherence is not None else "", out,
             "binary" if binary else "ASCII")
    return out
