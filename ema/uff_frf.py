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
``m/s/N``, ``m/N``); otherwise pass ``quantity=``. Data are taken as SI.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

import numpy as np
import pandas as pd

from .channels import read_channels, validate_channels
from .frf import QUANTITIES, FrequencyResponse
from .hammer_io import ChannelMismatchError, FunctionTypeError, SamplingError, UFFReadError, _read_uff_sets

__all__ = ["read_frf_uff"]

log = logging.getLogger("ema")

_SPEC_TO_QUANTITY = {12: "accelerance", 11: "mobility", 8: "receptance"}
_UNITS_TO_QUANTITY = {
    "m/s^2/n": "accelerance", "m/s2/n": "accelerance", "(m/s^2)/n": "accelerance", "m/n/s^2": "accelerance",
    "m/s/n": "mobility", "(m/s)/n": "mobility",
    "m/n": "receptance",
}
_FORCE_SPECS = {0, 9, 13}


def _dir_label(code: int) -> str:
    if code == 0:
        return "s"
    return ("+" if code > 0 else "-") + ("x", "y", "z", "rx", "ry", "rz")[abs(code) - 1]


def read_frf_uff(path: str | os.PathLike, channels_csv=None, *, quantity: str | None = None) -> FrequencyResponse:
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
            quantity = _UNITS_TO_QUANTITY.get(lab)
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
    for i, o in enumerate(outs):
        for k, r in enumerate(ins):
            if (o, r) not in frfs:
                raise ChannelMismatchError(f"{src}: no FRF for response {o[0]}:{_dir_label(o[1])} and reference "
                                           f"{r[0]}:{_dir_label(r[1])}")
            data[i, k] = frfs[(o, r)]["data"]
            if coh is not None:
                if (o, r) in cohs:
                    coh[i, k] = np.real(cohs[(o, r)]["data"])
                else:
                    log.warning("%s: coherence missing for response %s; coherence not attached", src, o[0])
                    coh = None
    if not np.all(np.isfinite(data)):
        raise UFFReadError(f"{src}: the FRF data contain NaN or infinite values")
    frf = FrequencyResponse(freqs_hz=x0, data=data, outputs=tuple(out_labels), inputs=tuple(in_labels),
                            quantity=quantity, coherence=coh, channels=channels, history=(f"read_frf_uff {src}",))
    log.info("read %s: %s", src, frf)
    return frf
