"""Reading FRFs computed by the acquisition front-end: UFF58 function type 4.

Some labs export FRFs instead of time histories: one UFF58 dataset per
response/reference pair, function type 4 ("frequency response function"),
complex ordinate, frequency abscissa. :func:`read_frf_uff` turns such a file
into the toolkit's :class:`~ema.frf.FrequencyResponse`; ordinary coherence
datasets (function type 6) for the same pairs are attached when present for
every pair. Datasets 58 of other function types (auto and cross spectra, time
histories of the same run) are skipped with one INFO line per type; a file
without FRFs is refused.

The quantity follows the ordinate's specific data type (12 acceleration ->
accelerance, 11 velocity -> mobility, 8 displacement -> receptance; the
denominator must be a force, 13 or 9, or unknown, 0). When the file leaves the
ordinate type unknown (0), the ordinate units label decides (``m/s^2/N``,
``m/s/N``, ``m/N``, ``g/N``, ...); otherwise pass ``quantity=``. Data are
converted to SI by their unit labels (numerator in g, mg, mm/s², in/s², ft/s²,
mm/s, in/s, mm, µm or in, denominator in kN, lbf or kgf: front-ends commonly
export accelerance in g/N, as one label or as ``g`` over ``N``, or the whole
unit over its force, ``m/s/N`` over ``N``); unlabelled data are taken as SI,
and so are data whose labels are not recognised, with one WARNING per label
naming the datasets (as :func:`ema.read_hammer` does). Labels that name
another quantity than the ordinate type (``m/s/N`` on an acceleration) are
refused: the file contradicts itself, and ``quantity=`` decides.

Raw voltages.  An FRF labelled in volts (``V/V``, ``g/V``, ``mV`` over ``N``)
or not labelled at all is converted by the channel table's ``sensitivity``
column (:mod:`ema.channels`: the factor on the recorded values giving SI), the
response's for a raw numerator and the force's for a raw denominator
(``H_SI = H x s_response / s_force``); an electrical label without a
sensitivity is refused (:class:`~ema.hammer_io.UnitSystemError`). FRFs
labelled in physical units are not multiplied by it (WARNING when it is not 1).

The data are checked before they are accepted: an FRF with NaN or infinite
values or identically zero (a dead channel), a coherence with NaN or infinite
values or outside [0, 1] raise :class:`~ema.hammer_io.UFFReadError` naming the
file, the dataset, the response and the first offending frequency; coherence
datasets without an FRF are ignored with a WARNING naming them. A mobility or
receptance is undefined at 0 Hz (a division by iω), so a NaN or infinite
0 Hz line there is set to 0 (INFO).

With a channel table the file is checked against it as the time-history
reader does: responses without an acceleration row are skipped (WARNING); a
reference node 0 (not set) is the table's force node (INFO), one other
reference node is logged (WARNING, the table is used), several are refused
(:class:`~ema.hammer_io.ReferenceNodeError`); a direction code contradicting
the table's measuring direction gives one
:class:`~ema.hammer_io.ChannelDirectionWarning` per channel.

Exponential window.  An H1 estimated through an exponential window of decay
``a`` carries poles shifted by ``−a``; the identification removes the shift
when it knows ``a`` (:attr:`~ema.frf.FrequencyResponse.exp_window_decay`).
UFF58 has no field for it, so :func:`write_frf_uff` records it in ID line 3
as ``exp_window_decay=<a> 1/s`` and :func:`read_frf_uff` reads it back from
there (any writer may follow the convention); otherwise pass
``exp_window_decay=`` (0 for FRFs without window or already corrected).
Front ends write a date or other text there: when neither the note nor the
argument gives a decay, a WARNING says that the damping is taken as exported.

:func:`write_frf_uff` writes FRFs (and their coherence) the way acquisition
systems export them, through pyuff: ASCII or binary (58b), double precision.
"""

from __future__ import annotations

import logging
import os
import re
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from .channels import (
    ELECTRICAL_UNITS,
    UNIT_TO_SI,
    datasheet_like_sensitivity,
    read_channels,
    unapplied_sensitivity_note,
    unit_key,
    validate_channels,
)
from .frf import QUANTITIES, FrequencyResponse
from .hammer_io import (
    _AXES,
    ChannelDirectionWarning,
    ChannelMismatchError,
    FunctionTypeError,
    ReferenceNodeError,
    SamplingError,
    UFFReadError,
    UnitSystemError,
    _function_label,
    _index_ranges,
    _read_uff_sets,
    _split_function_types,
)

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
                 "m/s": (1.0, "mobility"), "mm/s": (1e-3, "mobility"), "in/s": (0.0254, "mobility"),
                 "ft/s": (0.3048, "mobility"),
                 "m": (1.0, "receptance"), "mm": (1e-3, "receptance"), "um": (1e-6, "receptance"),
                 "\u00b5m": (1e-6, "receptance"), "\u03bcm": (1e-6, "receptance"), "in": (0.0254, "receptance")}
_DENOMINATOR_SI = UNIT_TO_SI["force"]
_DECAY = re.compile(r"exp_window_decay\s*=\s*([0-9.eE+-]+)")
_SPEC_NAMES = {12: "acceleration", 11: "velocity", 8: "displacement"}
#: rounding allowance of a written coherence beyond [0, 1] (ASCII E-format and single precision round 1.0 either way)
_COH_TOL = 1e-6


def _frf_units(d: dict) -> tuple[float, str | None, str, bool, str, str]:
    """What the ordinate and denominator unit labels of an FRF dataset say.

    Returns ``(factor, quantity, label, recognised, num_kind, den_kind)``: the factor of the physical labels to
    SI, the quantity the labels name (None if they do not), the labels for messages, whether they are
    recognised, and the kind of each part (:func:`ema.channels.unit_kind`: ``raw`` unlabelled, ``physical``,
    ``electrical``; ``unknown`` when not recognised). ``g/N`` as one numerator label or as ``g`` over ``N``; a
    bracketed numerator (``(m/s^2)/N``) too; the whole FRF unit as numerator with its force repeated as
    denominator (``m/s/N`` over ``N``, as :func:`write_frf_uff` writes); ``V/V`` or ``g/V`` for raw voltages.
    Unlabelled data (empty or ``NONE``) are SI and recognised, and so is an unlabelled part beside a labelled
    one. Labels it does not know give factor 1, no quantity and ``recognised`` False: the caller warns that the
    data are taken as SI.
    """
    num_raw = str(d.get("ordinate_axis_units_lab", "") or "").strip()
    den_raw = str(d.get("orddenom_axis_units_lab", "") or "").strip()
    num, den = unit_key(num_raw), unit_key(den_raw)
    label = repr(num_raw) + (f" over {den_raw!r}" if den else "")
    if not num and not den:
        return 1.0, None, label, True, "raw", "raw"
    if num in _UNITS_TO_QUANTITY and den in ("", "n"):  # SI FRF units written as one label (m/N/s^2)
        return 1.0, _UNITS_TO_QUANTITY[num], label, True, "physical", "physical"
    if "/" in num:
        head, _, tail = num.rpartition("/")
        # the numerator may be the whole FRF unit; a denominator label equal to its force is that same force
        # (a label, not a second division), any other denominator makes the pair ambiguous (not recognised)
        if (tail in _DENOMINATOR_SI or tail in ELECTRICAL_UNITS) and den in ("", tail):
            num, den = head, tail
    if num.startswith("(") and num.endswith(")"):
        num = num[1:-1]
    # an unlabelled part is SI, as unlabelled data are
    if not num:
        top, num_kind = (1.0, None), "raw"
    elif num in _NUMERATOR_SI:
        top, num_kind = _NUMERATOR_SI[num], "physical"
    elif num in ELECTRICAL_UNITS:
        top, num_kind = (1.0, None), "electrical"
    else:
        top, num_kind = None, "unknown"
    if not den:
        bottom, den_kind = 1.0, "raw"
    elif den in _DENOMINATOR_SI:
        bottom, den_kind = _DENOMINATOR_SI[den], "physical"
    elif den in ELECTRICAL_UNITS:
        bottom, den_kind = 1.0, "electrical"
    else:
        bottom, den_kind = None, "unknown"
    if top is None or bottom is None:
        return 1.0, None, label, False, num_kind, den_kind
    return top[0] / bottom, top[1], label, True, num_kind, den_kind


def _dir_label(code: int) -> str:
    if code == 0:
        return "s"
    if not 1 <= abs(code) <= 6:
        return str(code)
    return ("+" if code > 0 else "-") + ("x", "y", "z", "rx", "ry", "rz")[abs(code) - 1]


def _check_direction(src: str, what: str, code: int, row) -> None:
    """:class:`ChannelDirectionWarning` when a direction code along an axis contradicts the table's direction."""
    if abs(code) not in _AXES:
        return
    axis = np.sign(code) * np.asarray(_AXES[abs(code)])
    tdir = np.array([row.dx, row.dy, row.dz], dtype=float)
    if float(axis @ tdir) < 0.99:
        warnings.warn(
            f"{src}: {what} {row.name!r} (node {int(row.node)}): the file's direction code {code} disagrees with the "
            f"table's measuring direction {tuple(round(float(v), 4) for v in tdir)}; the table is used",
            ChannelDirectionWarning,
            stacklevel=3,
        )


def read_frf_uff(path: str | os.PathLike, channels_csv=None, *, quantity: str | None = None,
                 exp_window_decay: float | None = None) -> FrequencyResponse:
    """Read FRFs (UFF58, function type 4) into a :class:`~ema.frf.FrequencyResponse`.

    Parameters
    ----------
    path : str or os.PathLike
        The universal file (ASCII 58 or binary 58b).
    channels_csv : str, os.PathLike, pandas.DataFrame or None
        Channel table. With it, outputs are labelled by channel name in table
        order (every acceleration row must have an FRF; FRFs of responses
        without a row are skipped with a WARNING: the table selects the
        channels), the input by the force channel's name, and ``channels`` is
        set; its ``sensitivity`` column converts raw-voltage FRFs (module
        docstring). Without it, labels are ``"<node>:<dir>"`` (e.g.
        ``"101:+z"``; ``s`` for a scalar / off-axis direction) in file order.
    quantity : {"accelerance", "mobility", "receptance"}, optional
        Overrides the quantity read from the file.
    exp_window_decay : float, optional
        Exponential-window decay of the FRFs [1/s]; default: the
        ``exp_window_decay=`` note of ID line 3 (module docstring), else 0
        with a WARNING that the damping is taken as exported.

    Returns
    -------
    FrequencyResponse
        Reference node(s) = inputs; coherence attached when the file has a
        coherence dataset (function type 6) for every pair. Unrecognised units
        labels (taken as SI), labels overridden by ``quantity=``, applied
        sensitivities, a 0 Hz line set to 0 and the window decay's origin are
        logged and noted in ``history``.

    Raises
    ------
    UFFReadError
        Unreadable, truncated or corrupt file; an FRF with NaN or infinite
        values (except at 0 Hz in a mobility or receptance, where it is
        undefined and set to 0) or identically zero (dead channel); a
        coherence with NaN or infinite values or outside [0, 1]. The message
        names the dataset, the response and the first offending frequency.
    FunctionTypeError
        No FRF (function type 4) in the file (datasets of other function
        types are skipped with an INFO log), the ordinate is not complex, the
        denominator is not a force, or the quantity cannot be told: unknown,
        or the ordinate type and a units label disagree (and ``quantity=`` is
        not given).
    UnitSystemError
        Raw voltages (a V or mV label) without a ``sensitivity`` in the table.
    ChannelMismatchError
        Duplicate pairs, missing pairs, or file and table disagree.
    ReferenceNodeError
        With a table: the FRFs name different non-zero reference nodes.
    SamplingError
        The datasets do not share one frequency axis.
    """
    p = Path(os.fspath(path))
    if not p.is_file():
        raise FileNotFoundError(f"FRF file {str(p)!r} does not exist")
    if quantity is not None and quantity not in QUANTITIES:
        raise ValueError(f"quantity must be one of {sorted(QUANTITIES)} or None, got {quantity!r}")
    if exp_window_decay is not None and not (np.isfinite(exp_window_decay) and exp_window_decay >= 0):
        raise ValueError(f"exp_window_decay must be a finite decay >= 0 [1/s], got {exp_window_decay!r}")
    table = None
    if channels_csv is not None:
        table = (validate_channels(channels_csv, source=f"channel table for {p.name}")
                 if isinstance(channels_csv, pd.DataFrame) else read_channels(channels_csv))
    log.info("reading FRFs %s", p)
    src = str(p)
    dsets = _read_uff_sets(p, 58)
    for d in dsets:
        v = d.get("func_type")
        if v is None or isinstance(v, str) or not np.isfinite(v):
            raise UFFReadError(f"{src}: dataset {d['_index']}: header field 'func_type' is unreadable ({v!r})")
    dsets, other = _split_function_types(src, dsets, {4, 6}, "FRFs are read from function types 4 (FRF) and 6 "
                                                             "(coherence)")
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
        for k, side in ((0, "response"), (1, "reference")):
            if not -6 <= pair[k][1] <= 6:
                raise UFFReadError(f"{where}: record 6 is malformed: {side} direction code {pair[k][1]} is outside "
                                   f"-6..6; the fields are not at their columns (an entity name longer than 10 "
                                   f"characters?): fix the export")
        if pair[0][0] <= 0:
            raise UFFReadError(f"{where}: response node {pair[0][0]} is not a valid UFF node (node numbers start at 1; "
                               f"a 0-based channel numbering?): renumber the channels in the export and the table")
        if ft == 4:
            target = frfs
            if int(d["ord_data_type"]) not in (5, 6):
                raise FunctionTypeError(f"{where}: an FRF must have complex ordinates (data type 5 or 6), got "
                                        f"{int(d['ord_data_type'])}")
            den = int(d["orddenom_spec_data_type"])
            if den not in _FORCE_SPECS:
                raise FunctionTypeError(f"{where}: the FRF denominator must be a force (specific data type 13 or 9), "
                                        f"got {den}")
        else:
            target = cohs
        if pair in target:
            raise ChannelMismatchError(f"{where}: the same response/reference pair appears twice "
                                       f"(datasets {target[pair]['_index']} and {d['_index']})")
        n = len(d["data"])
        if n != int(d.get("num_pts", n)) or n == 0:
            raise UFFReadError(f"{where}: the header announces {d.get('num_pts')} values but the dataset holds {n}")
        target[pair] = d
    orphans = [f"dataset {c['_index']} ({_pair_text(pr)})" for pr, c in cohs.items() if pr not in frfs]
    cohs = {pr: c for pr, c in cohs.items() if pr in frfs}
    if not frfs:
        found = "; ".join(f"{len(ds)} dataset{'s' if len(ds) > 1 else ''} of {_function_label(t)}"
                          for t, ds in sorted(other.items()))
        hint = ("; time histories are read with ema.read_hammer (railmodal lab identify --hammer)" if 1 in other
                else "")
        raise FunctionTypeError(f"{src}: no FRF dataset (function type 4) in the file"
                                + (f"; it holds {found}" if found else "") + hint)

    # the table selects the channels: FRFs of responses without an acceleration row are skipped (named)
    if table is not None:
        acc_nodes = set(int(n) for n in table.loc[table["quantity"] == "acceleration", "node"])
        extra = sorted({pr[0] for pr in frfs if pr[0][0] not in acc_nodes})
        if extra:
            log.warning("%s: %d response%s without an acceleration row in the channel table %s skipped (the table "
                        "selects the channels): %s", src, len(extra), "s" if len(extra) > 1 else "",
                        "are" if len(extra) > 1 else "is",
                        ", ".join(f"node {n}:{_dir_label(c)} (dataset "
                                  f"{_index_ranges([d['_index'] for pr, d in frfs.items() if pr[0] == (n, c)])})"
                                  for n, c in extra))
            frfs = {pr: d for pr, d in frfs.items() if pr[0] not in extra}
            cohs = {pr: d for pr, d in cohs.items() if pr[0] not in extra}
            if not frfs:
                raise ChannelMismatchError(f"{src}: no FRF has a response in the channel table (table acceleration "
                                           f"nodes {sorted(acc_nodes)}); the table is not the one of this file")

    # quantity
    first = next(iter(frfs.values()))
    quantity_given = quantity is not None
    told_by = "quantity="  # what decided the quantity, for the message when a units label contradicts it
    if quantity is None:
        specs = {int(d["ordinate_spec_data_type"]) for d in frfs.values()}
        if len(specs) > 1:
            raise FunctionTypeError(f"{src}: the FRFs mix ordinate types {sorted(specs)}; expected one quantity")
        spec = specs.pop()
        if spec in _SPEC_TO_QUANTITY:
            quantity = _SPEC_TO_QUANTITY[spec]
            told_by = f"the ordinate type {spec} ({_SPEC_NAMES[spec]})"
        elif spec == 0:
            quantity = _frf_units(first)[1]
            told_by = f"the units label of dataset {first['_index']}"
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
                f"{x[0] if x.size else float('nan'):g}..{x[-1] if x.size else float('nan'):g} Hz that differs from "
                f"dataset {first['_index']} ({x0.size} lines {x0[0]:g}..{x0[-1]:g} Hz); all FRFs must share one axis"
            )
    if x0.size == 0 or not np.all(np.isfinite(x0)) or np.any(x0 < 0) or np.any(np.diff(x0) <= 0):
        raise SamplingError(f"{src}: the frequency axis must be finite, non-negative and increasing")

    outs = list(dict.fromkeys(pr[0] for pr in frfs))
    ins = list(dict.fromkeys(pr[1] for pr in frfs))
    read_notes: list[str] = []  # kept in the history: what was assumed or overridden in reading
    rows_out: list = []
    force_row = None
    if table is not None:
        force_row = next(table[table["quantity"] == "force"].itertuples(index=False))
        force_node = int(force_row.node)
        acc = table[table["quantity"] == "acceleration"].reset_index(drop=True)
        by_node = {}
        for o in outs:
            if o[0] in by_node:
                raise ChannelMismatchError(f"{src}: response node {o[0]} appears with two directions "
                                           f"({_dir_label(by_node[o[0]][1])}, {_dir_label(o[1])})")
            by_node[o[0]] = o
        missing = [f"{r.name!r} (node {r.node})" for r in acc.itertuples() if r.node not in by_node]
        if missing:
            raise ChannelMismatchError(f"{src}: channel(s) {', '.join(missing)} of the table have no FRF in the file")
        # reference nodes, as the time-history reader checks them: 0 is "not set"; one other node is a numbering
        # difference (WARNING, the table is used); several are different excitation points (refused)
        refs: dict[int, list[int]] = {}
        for pr, d in frfs.items():
            refs.setdefault(pr[1][0], []).append(int(d["_index"]))
        named = sorted(r for r in refs if r != 0)
        if len(named) > 1:
            listed = "; ".join(f"node {r} in datasets {_index_ranges(refs[r])}" for r in named)
            raise ReferenceNodeError(
                f"{src}: the FRFs name different reference (excitation) nodes: {listed} (the channel table's force "
                f"node is {force_node}); FRFs of different excitation points are not one single-reference test: "
                f"read each point's FRFs as their own file"
            )
        if named and named[0] != force_node:
            msg = (f"the FRFs name reference (excitation) node {named[0]}, but the channel table's force channel "
                   f"{force_row.name!r} is node {force_node}; the table is used: check that it describes the point "
                   f"the hammer hit")
            log.warning("%s: %s", src, msg)
            read_notes.append(msg)
        if 0 in refs:
            msg = (f"reference node 0 (not set) in {len(refs[0])} FRF{'s' if len(refs[0]) > 1 else ''}: taken as "
                   f"the channel table's force node {force_node} ({force_row.name!r})")
            log.info("%s: %s", src, msg)
            read_notes.append(msg)
        # one FRF per response: the table's single force is the input
        per_out: dict[tuple[int, int], list] = {}
        for pr in frfs:
            per_out.setdefault(pr[0], []).append(pr)
        for o, prs in per_out.items():
            if len(prs) > 1:
                raise ChannelMismatchError(
                    f"{src}: response {o[0]}:{_dir_label(o[1])} has {len(prs)} FRFs (references "
                    f"{', '.join(f'{r[0]}:{_dir_label(r[1])}' for _, r in prs)}; datasets "
                    f"{', '.join(str(frfs[pr]['_index']) for pr in prs)}); a single-reference test has one per response"
                )
        frfs = {pr[0]: d for pr, d in frfs.items()}
        cohs = {pr[0]: d for pr, d in cohs.items()}  # only pairs with an FRF are left
        outs = [by_node[int(n)] for n in acc["node"]]
        rows_out = list(acc.itertuples(index=False))
        ins = [None]
        out_labels = list(acc["name"])
        in_labels = [str(force_row.name)]
        channels = acc
        for o, row in zip(outs, rows_out):
            _check_direction(src, "response", o[1], row)
        ref_codes = {pr[1][1] for prs in per_out.values() for pr in prs}
        for code in sorted(ref_codes):
            _check_direction(src, "reference (force channel)", code, force_row)
        key_of = {(o, None): o for o in outs}
    else:
        out_labels = [f"{n}:{_dir_label(c)}" for n, c in outs]
        in_labels = [f"{n}:{_dir_label(c)}" for n, c in ins]
        channels = None
        if len(set(out_labels)) != len(out_labels) or len(set(in_labels)) != len(in_labels):
            raise ChannelMismatchError(f"{src}: response/reference labels are not unique: {out_labels} / {in_labels}")
        key_of = {(o, r): (o, r) for o in outs for r in ins}
    has_sens = table is not None and "sensitivity" in table.columns

    data = np.empty((len(outs), len(ins), x0.size), complex)
    # coherence is attached only when every FRF has one; a file whose coherence pairs with no FRF has none
    coh = np.empty(data.shape) if cohs else None
    converted: set[str] = set()
    unknown_units: dict[str, list[str]] = {}  # label -> the datasets carrying it, for one WARNING per label
    overridden: dict[str, list[str]] = {}  # label quantity -> datasets whose label quantity= overrides
    applied: list[str] = []  # sensitivities applied to raw FRFs
    ignored: list[str] = []  # sensitivities not applied (physical labels)
    force_ignored: set[str] = set()
    datasheet: list[str] = []  # electrical FRFs whose sensitivity looks like V per SI unit
    dc_undefined: list[str] = []  # non-finite 0 Hz lines of mobility/receptance set to 0
    no_coh: list[str] = []
    for i, o in enumerate(outs):
        for k, r in enumerate(ins):
            key = key_of.get((o, r))
            if key not in frfs:
                raise ChannelMismatchError(f"{src}: no FRF for response {o[0]}:{_dir_label(o[1])} and reference "
                                           f"{r[0]}:{_dir_label(r[1])}")
            d = frfs[key]
            if channels is not None:
                rr = (int(d["ref_node"]), int(d["ref_dir"]))
                resp = f"response {out_labels[i]!r} (node {o[0]}:{_dir_label(o[1])})"
                ref = f"reference {in_labels[k]!r} (node {rr[0]}:{_dir_label(rr[1])})"
            else:
                resp, ref = f"response {out_labels[i]}", f"reference {in_labels[k]}"
            channel = f"{resp}, {ref}"
            factor, label_quantity, label, recognised, num_kind, den_kind = _frf_units(d)
            if factor != 1.0:
                converted.add(label)
            raw = num_kind == "raw" and den_kind == "raw"
            if "electrical" in (num_kind, den_kind) and not has_sens:
                raise UnitSystemError(
                    f"{src}: dataset {d['_index']}, {channel}: units label {label} is electrical: the FRF is in raw "
                    f"voltages, and " + ("the channel table has no 'sensitivity' column" if table is not None else
                                         "no channel table with a 'sensitivity' column is given")
                    + " to convert it (SI = recorded x sensitivity, for the response and the force); add the "
                      "sensitivities, or export the FRFs in physical units"
                )
            if has_sens:
                s_resp, s_force = float(rows_out[i].sensitivity), float(force_row.sensitivity)
                sens = 1.0
                num_raw = str(d.get("ordinate_axis_units_lab", "") or "")
                den_raw = str(d.get("orddenom_axis_units_lab", "") or "")
                if (num_kind == "electrical" and datasheet_like_sensitivity(num_raw.rpartition("/")[0] or num_raw,
                                                                            s_resp)) or \
                        (den_kind == "electrical" and datasheet_like_sensitivity(den_raw or num_raw.rpartition("/")[2],
                                                                                 s_force)):
                    datasheet.append(f"{out_labels[i]!r}")
                if num_kind == "electrical" or raw:
                    sens *= s_resp
                elif s_resp != 1.0 and num_kind in ("physical", "unknown"):
                    ignored.append(f"{out_labels[i]!r} ({label})")
                if den_kind == "electrical" or raw:
                    sens /= s_force
                elif s_force != 1.0:
                    force_ignored.add(label)
                if sens != 1.0:
                    applied.append(f"dataset {d['_index']} ({out_labels[i]!r}, {label if not raw else 'no label'}) "
                                   f"x {sens:.10g}")
                factor *= sens
            if not recognised:
                unknown_units.setdefault(label, []).append(f"dataset {d['_index']} ({resp})")
            elif label_quantity is not None and label_quantity != quantity:
                if not quantity_given:
                    # a factor iw between the two readings: neither can be taken on trust
                    raise FunctionTypeError(
                        f"{src}: dataset {d['_index']}, {channel}: the units label {label} says {label_quantity} but "
                        f"{told_by} says {quantity}; the file contradicts itself: correct it or pass quantity="
                    )
                overridden.setdefault(label_quantity, []).append(f"dataset {d['_index']} ({label})")
            with np.errstate(invalid="ignore", over="ignore"):  # inf x factor: reported below
                row = np.asarray(d["data"]) * factor
            bad = ~np.isfinite(row)
            if bad.any():
                # a mobility or receptance is undefined at 0 Hz (a division by i omega): no analysis band reaches it
                dc_excused = quantity in ("mobility", "receptance") and x0[0] == 0.0 and bool(bad[0])
                if dc_excused and not bad[1:].any():
                    row = row.copy()
                    row[0] = 0.0
                    dc_undefined.append(int(d["_index"]))
                else:
                    j = int(np.argmax(bad[1:])) + 1 if dc_excused else int(np.argmax(bad))
                    what = "NaN" if np.isnan(row[j]) else "infinite"
                    raise UFFReadError(f"{src}: dataset {d['_index']}, {channel}: the FRF is {what} at {x0[j]:g} Hz "
                                       f"(first of {int(bad[1:].sum() if dc_excused else bad.sum())} NaN or "
                                       f"infinite line(s)" + (" above 0 Hz" if dc_excused else "") + ")")
            if not np.any(row):
                # a dead sensor or cable; the FRF-file path has no per-channel rejection to report it through
                # (the table requires every channel), so the user must fix the file or drop the channel
                raise UFFReadError(f"{src}: dataset {d['_index']}, {channel}: FRF is identically zero (dead "
                                   f"channel); remove the channel from the file and the channel table, or re-export it")
            data[i, k] = row
            if key in cohs:
                c = cohs[key]
                g2 = np.real(np.asarray(c["data"]))
                # ordinary coherence lies in [0, 1]; 1e-6 either side absorbs the rounding of written values
                # (ASCII E-format, single precision) without letting an impossible value through
                bad = ~np.isfinite(g2) | (g2 > 1.0 + _COH_TOL) | (g2 < -_COH_TOL)
                if bad.any():
                    j = int(np.argmax(bad))
                    raise UFFReadError(f"{src}: coherence dataset {c['_index']}, {channel}: coherence {g2[j]:g} at "
                                       f"{x0[j]:g} Hz (first of {int(bad.sum())} line(s) NaN, infinite or outside "
                                       f"[0, 1])")
                if coh is not None:
                    coh[i, k] = g2
            elif coh is not None:
                no_coh.append(f"dataset {d['_index']} ({resp})")
    if no_coh:
        log.warning("%s: no coherence dataset for the FRF(s) %s; coherence not attached", src, ", ".join(no_coh))
        coh = None
    if orphans:
        log.warning("%s: coherence %s without an FRF for the same response/reference pair; ignored", src,
                    ", ".join(orphans))
    for label, where in unknown_units.items():
        msg = (f"units label {label} not recognised ({', '.join(where)}); the data are taken as SI "
               f"({_QUANTITY_UNITS[quantity]})")
        log.warning("%s: %s", src, msg)
        read_notes.append(msg)
    for label_quantity, where in overridden.items():
        msg = f"units label(s) say {label_quantity} ({', '.join(where)}); read as {quantity} as quantity= says"
        log.warning("%s: %s", src, msg)
        read_notes.append(msg)
    if applied:
        msg = f"sensitivities applied to raw FRFs (SI = recorded x response sensitivity / force sensitivity): " \
              f"{', '.join(applied)}"
        unlabelled = any("no label" in a for a in applied)  # raw by inference, not by an electrical label
        (log.warning if unlabelled else log.info)(
            "%s: %s%s", src, msg, "; FRFs without a unit label are taken as raw: if the front end converted them, "
            "set the sensitivity to 1" if unlabelled else "")
        read_notes.append(msg)
    if datasheet:
        msg = (f"the sensitivities of the raw-voltage FRF(s) of {', '.join(datasheet[:8])}"
               f"{' ...' if len(datasheet) > 8 else ''} give less than 0.5 SI units per volt: they look like datasheet "
               f"sensitivities (V per N or per m/s^2); the column is the factor on the recorded values (SI = recorded "
               f"x sensitivity)")
        log.warning("%s: %s", src, msg)
        read_notes.append(msg)
    if force_ignored:
        ignored.append(f"the force {in_labels[0]!r} ({', '.join(sorted(force_ignored))})")
    if ignored:
        msg = unapplied_sensitivity_note(ignored, "FRFs are")
        log.warning("%s: %s", src, msg)
        read_notes.append(msg)
    if dc_undefined:
        msg = (f"the {quantity} is NaN or infinite at 0 Hz in {len(dc_undefined)} FRF"
               f"{'s' if len(dc_undefined) > 1 else ''} (datasets {_index_ranges(dc_undefined)}"
               f"): undefined there (a division by i omega), set to 0")
        log.info("%s: %s", src, msg)
        read_notes.append(msg)
    notes = {float(m.group(1)) for d in frfs.values() for m in [_DECAY.search(str(d.get("id3", "")))] if m}
    if len(notes) > 1 and exp_window_decay is None:
        raise UFFReadError(f"{src}: the FRFs record different exponential windows {sorted(notes)} 1/s in ID line 3")
    if exp_window_decay is not None:
        decay = float(exp_window_decay)
        if notes and notes != {decay}:
            msg = (f"the file records an exponential-window decay of {', '.join(f'{a:g}' for a in sorted(notes))} "
                   f"1/s in ID line 3; {decay:g} 1/s (given) is used")
            log.warning("%s: %s", src, msg)
            read_notes.append(msg)
        else:
            read_notes.append(f"exponential-window decay {decay:g} 1/s (given)")
    elif notes:
        decay = notes.pop()
        read_notes.append(f"exponential-window decay {decay:g} 1/s (from the file's ID line 3)")
    else:
        decay = 0.0
        msg = ("no exponential-window decay recorded (no 'exp_window_decay=' note in ID line 3) and none given: the "
               "damping is taken as exported; if the front end applied an exponential (response) window, give its "
               "decay (exp_window_decay=, or --window-decay of 'railmodal lab identify' / 'lab diagnose'), or the "
               "damping comes out too high by decay / omega")
        log.warning("%s: %s", src, msg)
        read_notes.append("no exponential-window decay recorded or given: damping taken as exported")
    history = (f"read_frf_uff {src}", *read_notes)
    if converted:
        note = f"converted to SI ({_QUANTITY_UNITS[quantity]}) from {', '.join(sorted(converted))}"
        log.info("%s: %s", src, note)
        history += (note,)
    frf = FrequencyResponse(freqs_hz=x0, data=data, outputs=tuple(out_labels), inputs=tuple(in_labels),
                            quantity=quantity, coherence=coh, channels=channels, history=history,
                            exp_window_decay=decay)
    log.info("read %s: %s", src, frf)
    return frf


def _pair_text(pr) -> str:
    if isinstance(pr[0], tuple):
        return (f"response {pr[0][0]}:{_dir_label(pr[0][1])}, reference {pr[1][0]}:{_dir_label(pr[1][1])}")
    return f"response {pr[0]}:{_dir_label(pr[1])}"


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
