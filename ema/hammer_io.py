"""Reading impact-hammer tests: the :class:`HammerTest` type and its readers.

A hammer test is a set of hits; in every hit the front-end records the force
of the instrumented hammer and the response of every accelerometer. The lab
exports them as UFF58 time histories (function type 1, one dataset per
channel per hit, the hit number in the record-6 "version / sequence number"
field, pyuff key ``ver_num``; files whose sequence number is the same in
every dataset are numbered by load case or by order, see :func:`_hit_numbers`;
data labelled in g, mm/s², kN or lbf are converted to SI, see :func:`_si_factor`;
a units dataset 164 that is not SI must agree with those labels, see
:func:`_check_unit_system`; other dataset types are skipped with an INFO log)
and describes the channels in a separate table
(:mod:`ema.channels`): the measuring directions, positions and FE nodes are
taken from that table, the samples and the sampling from the file.

Readers go through a small registry (like ObsPy's ``read``):
:func:`read_hammer` sniffs the format and dispatches; an unknown format raises
:class:`UnknownFormatError` listing the supported ones. In-memory data enter
through :meth:`HammerTest.from_arrays`; both paths end in the same validated
:class:`HammerTest`.

Every problem with the data raises a subclass of :class:`HammerDataError`
whose message names the file, the channel (node and name) and the hit.

The reference (excitation) node of the datasets (pyuff ``ref_node``; 0 =
not set, as many writers leave it) is checked: a single-reference test is
averaged over hits at one point, so hits that name different reference nodes
raise :class:`ReferenceNodeError`; one reference node for every hit that is
not the channel table's force node is logged as a WARNING (the table is used).
"""

from __future__ import annotations

import logging
import os
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np
import pandas as pd

from fem_import.uff_text import DatasetSpan, fortran_field_problem, prepare_for_pyuff, unreadable_field

from .channels import UNIT_TO_SI, read_channels, validate_channels

__all__ = [
    "HammerTest",
    "read_hammer",
    "HAMMER_FORMATS",
    "HammerDataError",
    "UFFReadError",
    "UnknownFormatError",
    "FunctionTypeError",
    "ChannelMismatchError",
    "ReferenceNodeError",
    "UnitSystemError",
    "SamplingError",
    "NonFiniteDataError",
    "ZeroForceError",
    "ChannelDirectionWarning",
]

log = logging.getLogger("ema")


# --------------------------------------------------------------------------
# Exceptions
# --------------------------------------------------------------------------
class HammerDataError(ValueError):
    """Base class of every problem found in hammer-test data."""


class UFFReadError(HammerDataError):
    """A universal file that cannot be read: truncated, corrupt, or not a UFF at all."""


class UnknownFormatError(HammerDataError):
    """A file format (given or sniffed) that no registered reader handles."""


class FunctionTypeError(HammerDataError):
    """A UFF58 dataset of the wrong function type (e.g. FRFs where time histories are expected)."""


class ChannelMismatchError(HammerDataError):
    """File and channel table disagree: a table row without data, data without a row, a duplicate dataset."""


class ReferenceNodeError(ChannelMismatchError):
    """Hits recorded at different reference (excitation) nodes: they cannot be averaged into one FRF."""


class UnitSystemError(HammerDataError):
    """A units dataset 164 that is not SI and that the channels' unit labels do not confirm."""


class SamplingError(HammerDataError):
    """Datasets with different sampling intervals, start times or record lengths, or uneven sampling."""


class NonFiniteDataError(HammerDataError):
    """NaN or infinite samples."""


class ZeroForceError(HammerDataError):
    """A force record that is all zero or constant: no hit was recorded."""


class ChannelDirectionWarning(UserWarning):
    """The direction code in the file contradicts the measuring direction of the channel table."""


# --------------------------------------------------------------------------
# The data type
# --------------------------------------------------------------------------
def _time_axis(t0: float, fs: float, n: int) -> np.ndarray:
    """``t0 + k / fs``: the one formula both the readers and :meth:`HammerTest.from_arrays` use."""
    return t0 + np.arange(n) / fs


def _readonly(a: np.ndarray) -> np.ndarray:
    """A read-only copy (never freeze the caller's array)."""
    a = np.array(a, dtype=float, order="C", copy=True)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class HammerTest:
    """The time histories of an impact-hammer test (single reference).

    Parameters
    ----------
    fs : float
        Sampling rate [Hz].
    time : ndarray (N,)
        Time axis of every record [s] (the same for all hits; the hit happens
        some pre-trigger time after its start).
    channels : pandas.DataFrame
        The validated channel table (:func:`ema.channels.validate_channels`):
        the force row and the acceleration rows, in table order.
    force : ndarray (n_hits, N)
        Hammer force [N].
    responses : ndarray (n_hits, n_ch, N)
        Accelerations [m/s^2], channel axis in the order of the acceleration
        rows of ``channels`` (:attr:`response_channels`).
    hits : tuple of int
        Hit numbers (as in the file), one per first-axis entry.
    source : str
        Where the data come from (file name), quoted in messages.

    Raises
    ------
    HammerDataError
        Shapes disagree (:class:`SamplingError`), samples are not finite
        (:class:`NonFiniteDataError`) or a force record is constant
        (:class:`ZeroForceError`); ``ChannelTableError`` for a bad table.

    Notes
    -----
    Arrays are stored read-only. Equality is identity (``eq=False``).
    """

    fs: float
    time: np.ndarray
    channels: pd.DataFrame
    force: np.ndarray
    responses: np.ndarray
    hits: tuple[int, ...]
    source: str = ""
    history: tuple[str, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        src = self.source or "hammer test"
        # readers and from_arrays have validated (and reported on) the table already; this guards direct
        # construction without repeating the unknown-column warning on every derived test
        channels = validate_channels(self.channels, source=self.source, warn_extra=False)
        fs = float(self.fs)
        if not np.isfinite(fs) or fs <= 0:
            raise SamplingError(f"{src}: sampling rate fs must be finite and > 0 Hz, got {self.fs!r}")
        force = np.asarray(self.force, dtype=float)
        resp = np.asarray(self.responses, dtype=float)
        if force.ndim != 2:
            raise SamplingError(f"{src}: force must be (n_hits, N), got shape {force.shape}")
        n_hits, n = force.shape
        acc = channels[channels["quantity"] == "acceleration"].reset_index(drop=True)
        if resp.shape != (n_hits, len(acc), n):
            raise SamplingError(
                f"{src}: responses must be (n_hits, n_ch, N) = ({n_hits}, {len(acc)}, {n}) to match the force "
                f"({n_hits} hits x {n} samples) and the {len(acc)} acceleration rows of the channel table, "
                f"got shape {resp.shape}"
            )
        if n_hits == 0 or n < 16:
            raise SamplingError(f"{src}: need at least one hit of at least 16 samples, got {n_hits} hits x {n}")
        time = np.asarray(self.time, dtype=float)
        if time.shape != (n,) or not np.all(np.isfinite(time)):
            raise SamplingError(f"{src}: time must be a finite (N,) = ({n},) array, got shape {time.shape}")
        hits = tuple(int(h) for h in self.hits)
        if len(hits) != n_hits or len(set(hits)) != n_hits:
            raise SamplingError(f"{src}: hits must be {n_hits} unique hit numbers, got {self.hits!r}")
        fname = str(channels.loc[channels["quantity"] == "force", "name"].iloc[0])
        fnode = int(channels.loc[channels["quantity"] == "force", "node"].iloc[0])
        # non-finite samples
        bad = ~np.isfinite(force)
        if bad.any():
            h, k = np.argwhere(bad)[0]
            raise NonFiniteDataError(
                f"{src}: hit {hits[h]}, force channel {fname!r} (node {fnode}): sample {k} is {float(force[h, k])!r}; "
                f"all samples must be finite"
            )
        finite_resp = np.isfinite(resp).all(axis=2)
        if not finite_resp.all():
            h, c = np.argwhere(~finite_resp)[0]
            k = int(np.flatnonzero(~np.isfinite(resp[h, c]))[0])
            raise NonFiniteDataError(
                f"{src}: hit {hits[h]}, channel {acc['name'][c]!r} (node {acc['node'][c]}): sample {k} is "
                f"{float(resp[h, c, k])!r}; all samples must be finite"
            )
        span = force.max(axis=1) - force.min(axis=1)
        if np.any(span == 0):
            h = int(np.flatnonzero(span == 0)[0])
            raise ZeroForceError(
                f"{src}: hit {hits[h]}, force channel {fname!r} (node {fnode}) is constant ({float(force[h, 0])!r} N "
                f"throughout): no hit was recorded; check the hammer cable/ICP supply or drop this hit"
            )
        object.__setattr__(self, "fs", fs)
        object.__setattr__(self, "time", _readonly(time))
        object.__setattr__(self, "channels", channels)
        object.__setattr__(self, "force", _readonly(force))
        object.__setattr__(self, "responses", _readonly(resp))
        object.__setattr__(self, "hits", hits)
        object.__setattr__(self, "history", tuple(self.history))

    # ----------------------------------------------------------------- views
    @property
    def n_hits(self) -> int:
        return self.force.shape[0]

    @property
    def n_samples(self) -> int:
        return self.force.shape[1]

    @property
    def n_channels(self) -> int:
        """Number of response (acceleration) channels."""
        return self.responses.shape[1]

    @property
    def dt(self) -> float:
        return 1.0 / self.fs

    @property
    def response_channels(self) -> pd.DataFrame:
        """The acceleration rows of the channel table, in the order of the ``responses`` channel axis."""
        return self.channels[self.channels["quantity"] == "acceleration"].reset_index(drop=True)

    @property
    def force_channel(self) -> pd.Series:
        """The force row of the channel table."""
        return self.channels[self.channels["quantity"] == "force"].iloc[0]

    @property
    def channel_names(self) -> tuple[str, ...]:
        return tuple(self.response_channels["name"])

    def __repr__(self) -> str:
        return (
            f"HammerTest({self.source or 'arrays'!s}: {self.n_hits} hits x {self.n_channels} channels + force, "
            f"fs={self.fs:g} Hz, {self.n_samples} samples)"
        )

    # ---------------------------------------------------------- constructors
    @classmethod
    def from_arrays(
        cls,
        force,
        responses,
        fs: float,
        channels: pd.DataFrame,
        *,
        hit_numbers=None,
        t0: float = 0.0,
        source: str = "",
    ) -> "HammerTest":
        """A hammer test from in-memory arrays.

        Parameters
        ----------
        force : array_like (n_hits, N)
            Hammer force [N]; a 1-D array is one hit.
        responses : array_like (n_hits, n_ch, N)
            Accelerations [m/s^2], channel axis in the order of the
            acceleration rows of ``channels``; a 2-D array is one hit.
        fs : float
            Sampling rate [Hz].
        channels : pandas.DataFrame
            Channel table (validated here).
        hit_numbers : sequence of int, optional
            Default ``1..n_hits``.
        t0 : float, optional
            Time of the first sample [s].
        source : str, optional
            Name used in messages.

        Returns
        -------
        HammerTest
        """
        f = np.asarray(force, dtype=float)
        r = np.asarray(responses, dtype=float)
        if f.ndim == 1:
            f = f[None, :]
        if r.ndim == 2:
            r = r[None, :, :]
        n_hits = f.shape[0] if f.ndim == 2 else 0
        hits = tuple(range(1, n_hits + 1)) if hit_numbers is None else tuple(int(h) for h in hit_numbers)
        n = f.shape[-1] if f.ndim >= 1 else 0
        fs = float(fs)
        if not np.isfinite(fs) or fs <= 0:
            raise SamplingError(f"{source or 'arrays'}: sampling rate fs must be finite and > 0 Hz, got {fs!r}")
        time = _time_axis(float(t0), fs, n)
        channels = validate_channels(channels, source=source)  # here, once, with the unknown-column warning
        return cls(fs=fs, time=time, channels=channels, force=f, responses=r, hits=hits,
                   source=source, history=("from_arrays",))


# --------------------------------------------------------------------------
# UFF framing check (pyuff drops a truncated last dataset silently)
# --------------------------------------------------------------------------
_TAG = re.compile(rb"^ {0,5}-1 *\r?$", re.M)


def _line_end(raw: bytes, pos: int) -> int:
    e = raw.find(b"\n", pos)
    return len(raw) if e < 0 else e + 1


def _scan_uff(raw: bytes, path: str) -> list[tuple[int, bool, int, int]]:
    """Walk the dataset framing of a universal file.

    Returns ``[(dataset type, binary, start, end), ...]`` in file order
    (``start``: offset of the dataset-number line, ``end``: of the end tag). Raises
    :class:`UFFReadError` for a missing start or end tag, a header that is
    not a dataset number, or a binary block shorter than its header says
    (truncation).
    """
    n = len(raw)
    pos = 0
    sets: list[tuple[int, bool, int, int]] = []
    while True:
        # skip blank lines between datasets
        while pos < n:
            e = _line_end(raw, pos)
            if raw[pos:e].strip():
                break
            pos = e
        if pos >= n:
            return sets
        k = len(sets) + 1
        e = _line_end(raw, pos)
        if raw[pos:e].strip() != b"-1":
            raise UFFReadError(
                f"{path}: expected the start tag '    -1' of dataset {k} at byte {pos}, got "
                f"{raw[pos:min(e, pos + 40)]!r}; the file is corrupt or not a universal file"
            )
        pos = e
        if pos >= n:
            raise UFFReadError(f"{path}: the file ends after the start tag of dataset {k} (truncated)")
        e = _line_end(raw, pos)
        head = raw[pos:e]
        head_start = pos
        try:
            set_type = int(head[:6])
        except ValueError:
            raise UFFReadError(
                f"{path}: dataset {k} at byte {pos}: expected a dataset number in columns 1-6, got {head[:40]!r}"
            ) from None
        binary = len(head) > 6 and head[6:7] in (b"b", b"B")
        pos = e
        if binary:
            try:
                n_ascii = int(head[19:31])
                n_bytes = int(head[31:43])
            except ValueError:
                raise UFFReadError(
                    f"{path}: dataset {k} (type {set_type}b): cannot read the number of header lines and data "
                    f"bytes from the binary identifier line {head.rstrip()!r}"
                ) from None
            if n_ascii < 0 or n_bytes < 0:
                raise UFFReadError(f"{path}: dataset {k} (type {set_type}b): negative sizes in {head.rstrip()!r}")
            for _ in range(n_ascii):
                if pos >= n:
                    raise UFFReadError(f"{path}: dataset {k} (type {set_type}b): the file ends inside the header "
                                       f"(truncated)")
                pos = _line_end(raw, pos)
            if pos + n_bytes > n:
                raise UFFReadError(
                    f"{path}: dataset {k} (type {set_type}b): the header announces {n_bytes} data bytes but only "
                    f"{n - pos} remain (truncated file)"
                )
            pos += n_bytes
            # some writers put a line break between the data and the end tag
            if raw[pos:pos + 2] == b"\r\n":
                pos += 2 if raw[pos + 2:pos + 8].strip() == b"-1" else 0
            elif raw[pos:pos + 1] == b"\n" and raw[pos + 1:pos + 7].strip() == b"-1":
                pos += 1
            e = _line_end(raw, pos)
            if raw[pos:e].strip() != b"-1":
                raise UFFReadError(
                    f"{path}: dataset {k} (type {set_type}b): expected the end tag '    -1' right after the "
                    f"{n_bytes} data bytes (byte {pos}), got {raw[pos:min(e, pos + 40)]!r}; the file is corrupt"
                )
            end_tag = pos
            pos = e
        else:
            m = _TAG.search(raw, pos)
            if m is None:
                raise UFFReadError(f"{path}: dataset {k} (type {set_type}) has no end tag '    -1' (truncated file)")
            end_tag = m.start()
            pos = m.end()
            pos = _line_end(raw, pos) if pos < n and raw[pos:pos + 1] in (b"\r", b"\n") else pos
        sets.append((set_type, binary, head_start, end_tag))


# --------------------------------------------------------------------------
# pyuff access
# --------------------------------------------------------------------------
#: Names of dataset types for messages.
_DATASET_NAMES = {15: "nodes", 18: "coordinate systems", 55: "data at nodes", 58: "function at a DOF",
                  82: "trace lines", 151: "header", 164: "units", 1858: "dataset-58 qualifiers", 2411: "nodes",
                  2412: "elements", 2414: "analysis data", 2420: "coordinate systems"}


def _is_si(u: dict) -> bool:
    """Whether a units dataset 164 is SI: its conversion factors (file unit per SI unit) are 1."""
    return bool(np.isclose(float(u["length"]), 1.0, rtol=1e-6) and np.isclose(float(u["force"]), 1.0, rtol=1e-6))


def _units_label(u: dict) -> str:
    return (f"dataset {u['_index']} (type 164) declares units code {int(u['units_code'])} "
            f"{str(u.get('units_description', '')).strip()!r} (length unit {1 / float(u['length']):.6g} m, force unit "
            f"{1 / float(u['force']):.6g} N)")


def _read_uff_sets(path: Path, wanted_type: int = 58) -> list[dict]:
    """Framing check, then every dataset of ``wanted_type`` read by pyuff (as dicts, file order).

    Each dict gets an extra key ``'_index'``: its 1-based dataset number in the file.
    Fortran ``D`` exponents in ASCII datasets are read; an overflow field
    (``*****``) raises :class:`UFFReadError` naming the dataset, record and line
    (:mod:`fem_import.uff_text`). Other dataset types are skipped with an INFO
    log; a units dataset 164 that is not SI is not applied by this generic
    path, so it is named in a WARNING (the hammer reader uses
    :func:`_read_uff_file` and checks it against the unit labels,
    :func:`_check_unit_system`).
    """
    sets, units = _read_uff_file(path, wanted_type)
    for u in units:
        if not _is_si(u):
            log.warning("%s: %s; this reader does not apply a unit system: the data are taken in the units their "
                        "labels name (SI if unlabelled); check the unit labels", path, _units_label(u))
    return sets


def _read_uff_file(path: Path, wanted_type: int = 58) -> tuple[list[dict], list[dict]]:
    """Like :func:`_read_uff_sets`, plus the units datasets 164 (``(sets, units)``, each with ``'_index'``)."""
    p = str(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise UFFReadError(f"{p}: cannot read the file ({exc})") from exc
    if not raw.strip():
        raise UFFReadError(f"{p}: the file is empty")
    framing = _scan_uff(raw, p)
    spans = [DatasetSpan(k, t, b, s, e) for k, (t, b, s, e) in enumerate(framing, 1)]
    problem, _ = fortran_field_problem(raw, spans)
    if problem is not None:
        raise UFFReadError(f"{p}: {problem}")
    with prepare_for_pyuff(p, raw, spans) as readable:
        return _read_pyuff_sets(p, readable, framing, wanted_type, lambda i: unreadable_field(raw, spans[i]))


def _read_pyuff_sets(p: str, readable: str, framing, wanted_type: int,
                     explain=lambda i: None) -> tuple[list[dict], list[dict]]:
    """The datasets of ``wanted_type`` and the units datasets 164, read by pyuff; other types are logged (INFO)."""
    import pyuff  # third-party reader, imported where needed

    try:
        uff = pyuff.UFF(readable)
        types = [int(t) for t in uff.get_set_types()]
    except Exception as exc:  # pyuff raises bare Exception; re-raise naming the file
        raise UFFReadError(f"{p}: pyuff cannot index the file ({exc})") from exc
    if types != [f[0] for f in framing]:
        raise UFFReadError(
            f"{p}: the dataset framing is inconsistent ({len(framing)} datasets by their '    -1' tags and "
            f"headers, {len(types)} as indexed by pyuff); the file is corrupt"
        )
    if wanted_type not in types:
        raise UFFReadError(
            f"{p}: no dataset of type {wanted_type} in the file (dataset types found: {sorted(set(types))})"
        )
    # what is skipped is said (with counts), so a file holding more than the reader uses is not a surprise
    skipped: dict[int, int] = {}
    for t in types:
        if t not in (wanted_type, 164):
            skipped[t] = skipped.get(t, 0) + 1
    if skipped:
        log.info("%s: ignored %s; this reader uses datasets %d", p,
                 ", ".join(f"{n} dataset{'s' if n > 1 else ''} of type {t}"
                           + (f" ({_DATASET_NAMES[t]})" if t in _DATASET_NAMES else "")
                           for t, n in sorted(skipped.items())), wanted_type)
    out, units = [], []
    for i, t in enumerate(types):
        if t not in (wanted_type, 164):
            continue
        try:
            d = uff.read_sets(i)
        except Exception as exc:  # pyuff raises bare Exception; re-raise naming the file, dataset and cause
            bad = explain(i)
            if bad is not None:
                raise UFFReadError(f"{p}: {bad}") from exc
            raise UFFReadError(f"{p}: dataset {i + 1} (type {t}) cannot be read ({exc})") from exc
        if t == 164:
            if not isinstance(d, dict) or not all(isinstance(d.get(k), (int, float, np.number)) and
                                                  np.isfinite(d.get(k)) and (k == "units_code" or d.get(k) > 0)
                                                  for k in ("units_code", "length", "force")):
                raise UFFReadError(f"{p}: dataset {i + 1} (type 164, units) has no usable units code and positive "
                                   f"conversion factors (length, force); the file is corrupt")
            d["_index"] = i + 1
            units.append(d)
            continue
        if not isinstance(d, dict) or "data" not in d:
            raise UFFReadError(f"{p}: dataset {i + 1} (type {wanted_type}) cannot be read")
        d["_index"] = i + 1
        out.append(d)
    return out, units


def _dset_label(d: dict) -> str:
    return f"dataset {d.get('_index')} (node {d.get('rsp_node')}, hit {d.get('ver_num')})"


def _check_dset_fields(d: dict, p: str, keys: tuple[str, ...]) -> None:
    for key in keys:
        v = d.get(key)
        if v is None or isinstance(v, str) or not np.isfinite(v):
            raise UFFReadError(f"{p}: dataset {d.get('_index')}: header field {key!r} is unreadable ({v!r})")


#: UFF specific data types accepted for each channel quantity (0 = unknown).
_SPEC_TYPES = {"force": {0, 9, 13}, "acceleration": {0, 12}}
_SPEC_NAMES = {0: "unknown", 8: "displacement", 9: "reaction force", 11: "velocity", 12: "acceleration",
               13: "excitation force", 17: "time"}
_AXES = {1: (1.0, 0.0, 0.0), 2: (0.0, 1.0, 0.0), 3: (0.0, 0.0, 1.0)}


def _si_factor(p: str, row, dsets: list[dict]) -> tuple[float, str]:
    """The factor from a channel's unit in the file (its ordinate units label) to SI, and that label.

    Front-ends often export accelerations in g. An empty or ``NONE`` label leaves the data as the channel table
    says (SI); an unknown one too, with a warning; a channel labelled differently in different hits is an error.
    """
    labels = {str(d.get("ordinate_axis_units_lab", "") or "").strip() for d in dsets}
    if len(labels) > 1:
        raise ChannelMismatchError(f"{p}: channel {row.name!r} (node {row.node}) is in {sorted(labels)} in different "
                                   f"hits; one unit per channel")
    lab = labels.pop()
    key = lab.lower().replace(" ", "")
    if key in ("", "none"):
        return 1.0, lab
    factor = UNIT_TO_SI[row.quantity].get(key)
    if factor is None:
        log.warning("%s: channel %r (node %d): unit label %r not recognised; the data are taken in %s, as the channel "
                    "table says", p, row.name, row.node, lab, row.unit)
        return 1.0, lab
    return factor, lab


def _label_agrees(quantity: str, label: str, u: dict) -> bool | None:
    """Whether a channel's unit label names the unit the units dataset ``u`` implies; None if unlabelled/unknown.

    ``g`` is not a unit of any system, so it agrees with every one.
    """
    key = label.lower().replace(" ", "")
    factor = UNIT_TO_SI[quantity].get(key)
    if key in ("", "none") or factor is None:
        return None
    if quantity == "acceleration" and key == "g":
        return True
    # 164 factors are file units per SI unit: the file's length unit is 1/length m, its force unit 1/force N
    system = 1.0 / float(u["length"] if quantity == "acceleration" else u["force"])
    return bool(np.isclose(factor, system, rtol=1e-3))


def _check_unit_system(p: str, units: list[dict], by_key: dict, nodes: dict) -> None:
    """Check the datasets 58 against a units dataset 164 that is not SI.

    A 164 governs the datasets after it (to the next 164). This reader converts by the datasets' unit labels
    (:func:`_si_factor`), not by a unit system. If a 164 says inch/lbf and a label says ``N`` (or there is no
    label, so the data would be taken as SI), one of the two is wrong and the results would be off by the
    unit ratio without a message; so that is refused. Labels that name the declared system's units (``lbf``)
    or ``g`` agree: the data are converted by the labels, logged at INFO.
    """
    if not units or all(_is_si(u) for u in units):
        return
    starts = [u["_index"] for u in units]
    agreed: set[str] = set()
    for (hit, node), d in sorted(by_key.items(), key=lambda kv: kv[1]["_index"]):
        k = int(np.searchsorted(starts, d["_index"])) - 1
        if k < 0 or _is_si(units[k]):
            continue
        u, row = units[k], nodes[node]
        label = str(d.get("ordinate_axis_units_lab", "") or "").strip()
        ok = _label_agrees(row.quantity, label, u)
        if ok:
            agreed.add(f"{row.quantity} in {label}")
            continue
        why = (f"is labelled {label!r}, which is not the declared system's {row.quantity} unit" if ok is False else
               (f"has the unit label {label!r}, which the reader does not know" if label and label.upper() != "NONE"
                else "has no unit label") + ", so its data would be taken in SI units, not in the declared system's")
        raise UnitSystemError(
            f"{p}: {_units_label(u)}, but hit {hit}, channel {row.name!r} (node {node}, dataset {d['_index']}) {why}; "
            f"the unit system and the channel's unit cannot both be right. Export the hammer test in SI units (164 "
            f"code 1), or with unit labels in the declared units (g, lbf), or remove the 164 if the labels are right"
        )
    if agreed:
        log.info("%s: %s; every channel's unit label agrees (%s): converted by the labels", p,
                 "; ".join(_units_label(u) for u in units if not _is_si(u)), ", ".join(sorted(agreed)))


def _ref_node(d: dict) -> int:
    return int(d.get("ref_node") or 0)


def _check_reference_nodes(p: str, by_key: dict, nodes: dict, fnode: int) -> None:
    """Compare the datasets' reference nodes with each other and with the table's force node.

    A single-reference FRF is an H1 average over hits at one excitation point; a hit at another point averaged
    in would corrupt it without a trace, so hits (or the datasets of one hit) naming different reference nodes
    are refused. 0 means "not set" (many writers leave it) and an acceleration channel naming its own node is a
    self-reference, not an excitation point: both are not compared. One reference node for all hits that is
    not the table's force node may be a point-numbering difference: WARNING, the table is used.
    """
    refs: dict[int, dict[int, list[int]]] = {}
    for (hit, node), d in by_key.items():
        r = _ref_node(d)
        if r == 0 or (r == node and node != fnode):
            continue
        refs.setdefault(hit, {}).setdefault(r, []).append(node)

    def chans(ns: list[int]) -> str:
        names = [f"{nodes[n].name!r} (node {n})" for n in sorted(ns)]
        return ", ".join(names[:4]) + (f" and {len(names) - 4} more" if len(names) > 4 else "")

    for hit in sorted(refs):
        if len(refs[hit]) > 1:
            listed = "; ".join(f"node {r} in {chans(ns)}" for r, ns in sorted(refs[hit].items()))
            raise ReferenceNodeError(
                f"{p}: hit {hit}: its datasets name different reference (excitation) nodes: {listed}; the channels "
                f"of one hit share one excitation point: fix the export or remove hit {hit}"
            )
    by_ref: dict[int, list[int]] = {}
    for hit, rs in refs.items():
        by_ref.setdefault(next(iter(rs)), []).append(hit)
    if len(by_ref) > 1:
        # name the hits away from the table's force node (or, if none is at it, every group)
        odd = {r: hs for r, hs in by_ref.items() if r != fnode} if fnode in by_ref else by_ref
        listed = "; ".join(f"hit{'s' if len(hs) > 1 else ''} {', '.join(map(str, sorted(hs)))} at node {r}"
                           for r, hs in sorted(by_ref.items()))
        first = min(h for hs in odd.values() for h in hs)
        raise ReferenceNodeError(
            f"{p}: the hits name different reference (excitation) nodes: {listed} (the channel table's force node is "
            f"{fnode}); hits at different points cannot be averaged into one FRF (hit {first} would be averaged in "
            f"as if hit at node {fnode}): remove the hits at the other point(s) or read each point as its own test"
        )
    if by_ref:
        (r, hs), = by_ref.items()
        if r != fnode:
            log.warning("%s: hit%s %s name%s reference (excitation) node %d, but the channel table's force channel "
                        "%r is node %d; the table is used: check that it describes the point the hammer hit", p,
                        "s" if len(hs) > 1 else "", ", ".join(map(str, sorted(hs))), "" if len(hs) > 1 else "s", r,
                        nodes[fnode].name, fnode)


def _hit_numbers(dsets: list[dict], p: str) -> list[int]:
    """The hit of each dataset: its sequence number (``ver_num``), as the lab writes it.

    Front-ends that export every hit with the same sequence number number them by the load case
    (``load_case_id``) or only by their order in the file. So when the sequence number is the same in every
    dataset and a channel occurs more than once, the load case is used if it tells the hits apart, else the
    order: the k-th dataset of every channel is hit k — only when every channel occurs equally often (a lone
    repeated dataset stays the error the per-hit check names). Either is logged.
    """
    ver = [int(d["ver_num"]) for d in dsets]
    nodes = [int(d["rsp_node"]) for d in dsets]
    if len(set(ver)) > 1 or len(set(zip(ver, nodes))) == len(dsets):
        return ver
    case = [int(d.get("load_case_id", 0) or 0) for d in dsets]
    if len(set(case)) > 1 and len(set(zip(case, nodes))) == len(dsets):
        log.warning("%s: every dataset has sequence number %d; the hits are numbered by their load case (%s)",
                    p, ver[0], ", ".join(str(c) for c in sorted(set(case))))
        return case
    counts = {n: nodes.count(n) for n in set(nodes)}
    if len(set(counts.values())) != 1:
        return ver
    seen: dict[int, int] = {}
    order = []
    for n in nodes:
        seen[n] = seen.get(n, 0) + 1
        order.append(seen[n])
    log.warning("%s: every dataset has sequence number %d and no load case tells the hits apart; the %d hits are "
                "numbered by their order in the file (the k-th dataset of each channel is hit k)", p, ver[0],
                max(order))
    return order


def _read_uff58(path: Path, channels: pd.DataFrame) -> HammerTest:
    p = str(path)
    log.info("reading hammer test %s (%.1f MB)", p, path.stat().st_size / 1e6)
    dsets, units = _read_uff_file(path, 58)
    for d in dsets:
        _check_dset_fields(d, p, ("func_type", "ver_num", "rsp_node", "rsp_dir", "ref_node", "num_pts",
                                  "abscissa_spacing", "abscissa_min", "abscissa_inc", "ord_data_type",
                                  "ordinate_spec_data_type"))
    bad_func = [d for d in dsets if int(d["func_type"]) != 1]
    if bad_func:
        d = bad_func[0]
        hint = "; these are FRFs: read them with ema.read_frf_uff" if int(d["func_type"]) == 4 else ""
        raise FunctionTypeError(
            f"{p}: {_dset_label(d)} has function type {int(d['func_type'])}, expected 1 (time response) for a "
            f"hammer test{hint}"
        )
    nodes = {int(r.node): r for r in channels.itertuples(index=False)}
    by_key: dict[tuple[int, int], dict] = {}
    for d, hit in zip(dsets, _hit_numbers(dsets, p)):
        node = int(d["rsp_node"])
        if node not in nodes:
            raise ChannelMismatchError(
                f"{p}: {_dset_label(d)}: node {node} has data but no row in the channel table "
                f"(table nodes: {sorted(nodes)}); add the channel to the table or remove it from the file"
            )
        row = nodes[node]
        if (hit, node) in by_key:
            raise ChannelMismatchError(
                f"{p}: hit {hit}, channel {row.name!r} (node {node}) appears twice (datasets "
                f"{by_key[(hit, node)]['_index']} and {d['_index']}); each channel must be recorded once per hit"
            )
        if int(d["ord_data_type"]) not in (2, 4):
            raise FunctionTypeError(
                f"{p}: {_dset_label(d)} ({row.name!r}): ordinate data type {int(d['ord_data_type'])} is not real "
                f"(expected 2 or 4 for a time history)"
            )
        spec = int(d["ordinate_spec_data_type"])
        if spec not in _SPEC_TYPES[row.quantity]:
            raise ChannelMismatchError(
                f"{p}: {_dset_label(d)}: the file says the ordinate is {_SPEC_NAMES.get(spec, spec)!r} "
                f"(specific data type {spec}) but channel {row.name!r} is a {row.quantity} channel in the table"
            )
        n_data = len(d["data"])
        if n_data != int(d["num_pts"]):
            raise UFFReadError(
                f"{p}: {_dset_label(d)} ({row.name!r}): the header announces {int(d['num_pts'])} samples but the "
                f"dataset holds {n_data}; the file is truncated or corrupt"
            )
        if int(d["abscissa_spacing"]) != 1:
            raise SamplingError(
                f"{p}: {_dset_label(d)} ({row.name!r}): uneven abscissa spacing; a hammer test needs evenly "
                f"sampled records"
            )
        rdir = int(d["rsp_dir"])
        if abs(rdir) in _AXES:
            axis = np.sign(rdir) * np.asarray(_AXES[abs(rdir)])
            tdir = np.array([row.dx, row.dy, row.dz])
            if float(axis @ tdir) < 0.99:
                warnings.warn(
                    f"{p}: {_dset_label(d)} ({row.name!r}): the file's direction code {rdir} disagrees with the "
                    f"table's measuring direction {tuple(np.round(tdir, 4))}; the table is used",
                    ChannelDirectionWarning,
                    stacklevel=3,
                )
        by_key[(hit, node)] = d

    hits = sorted({h for h, _ in by_key})
    for hit in hits:
        for node, row in nodes.items():
            if (hit, node) not in by_key:
                raise ChannelMismatchError(
                    f"{p}: hit {hit}: channel {row.name!r} (node {node}, {row.quantity}) is in the channel table "
                    f"but has no dataset in this hit; fix the table or drop the hit"
                )
    _check_reference_nodes(p, by_key, nodes, int(channels.loc[channels["quantity"] == "force", "node"].iloc[0]))
    _check_unit_system(p, units, by_key, nodes)
    ref = by_key[(hits[0], int(channels.loc[channels['quantity'] == 'force', 'node'].iloc[0]))]
    dt0, t00, n0 = float(ref["abscissa_inc"]), float(ref["abscissa_min"]), int(ref["num_pts"])
    if not dt0 > 0:
        raise SamplingError(f"{p}: {_dset_label(ref)}: sampling interval must be > 0 s, got {dt0!r}")
    for (hit, node), d in by_key.items():
        name = nodes[node].name
        dt = float(d["abscissa_inc"])
        if abs(dt - dt0) > 1e-9 * dt0:
            raise SamplingError(
                f"{p}: hit {hit}, channel {name!r} (node {node}): sampling interval {dt!r} s differs from "
                f"{dt0!r} s of the force channel in hit {hits[0]}; all records must share one sampling rate"
            )
        if int(d["num_pts"]) != n0:
            raise SamplingError(
                f"{p}: hit {hit}, channel {name!r} (node {node}): {int(d['num_pts'])} samples, but the force "
                f"channel in hit {hits[0]} has {n0}; all records must have the same length"
            )
        if abs(float(d["abscissa_min"]) - t00) > 1e-6 * dt0:
            raise SamplingError(
                f"{p}: hit {hit}, channel {name!r} (node {node}): record starts at {float(d['abscissa_min'])!r} s, "
                f"the force channel in hit {hits[0]} at {t00!r} s; all records must share one time axis"
            )
    fnode = int(channels.loc[channels["quantity"] == "force", "node"].iloc[0])
    acc_nodes = channels.loc[channels["quantity"] == "acceleration", "node"].astype(int).tolist()
    force = np.empty((len(hits), n0))
    resp = np.empty((len(hits), len(acc_nodes), n0))
    scale = {node: _si_factor(p, nodes[node], [by_key[(h, node)] for h in hits]) for node in nodes}
    for i, hit in enumerate(hits):
        force[i] = by_key[(hit, fnode)]["data"] * scale[fnode][0]
        for j, node in enumerate(acc_nodes):
            resp[i, j] = by_key[(hit, node)]["data"] * scale[node][0]
    converted = sorted({f"{nodes[n].quantity} from {lab}" for n, (f, lab) in scale.items() if f != 1.0})
    if converted:
        log.info("%s: converted to SI units: %s", p, ", ".join(converted))
    history = (f"read_hammer {p}",) + ((f"converted to SI: {', '.join(converted)}",) if converted else ())
    test = HammerTest(fs=1.0 / dt0, time=_time_axis(t00, 1.0 / dt0, n0), channels=channels, force=force,
                      responses=resp, hits=tuple(hits), source=p, history=history)
    log.info("read %s: %d hits x %d channels + force, fs %g Hz, %d samples (%.3g s)",
             p, test.n_hits, test.n_channels, test.fs, n0, n0 * dt0)
    return test


def _sniff_uff(path: Path) -> bool:
    with open(path, "rb") as fh:
        head = fh.read(512)
    for line in head.splitlines():
        if line.strip():
            return line.strip() == b"-1"
    return False


#: Registered hammer-test readers: format name -> (sniffer, reader, description).
HAMMER_FORMATS: dict[str, tuple[Callable[[Path], bool], Callable[[Path, pd.DataFrame], HammerTest], str]] = {
    "uff58": (_sniff_uff, _read_uff58, "universal file, dataset 58/58b time histories (function type 1)"),
}


def read_hammer(uff_path: str | os.PathLike, channels_csv, *, format: str | None = None) -> HammerTest:
    """Read a hammer test: time histories plus channel table.

    Parameters
    ----------
    uff_path : str or os.PathLike
        The time-history file (UFF58/58b: one dataset per channel per hit,
        function type 1, hit number in the sequence-number field ``ver_num``,
        channel in ``rsp_node``).
    channels_csv : str, os.PathLike or pandas.DataFrame
        The channel table (a CSV file or a table); it supplies the measuring
        directions, positions and FE nodes, and decides which node is the force.
    format : str, optional
        A key of :data:`HAMMER_FORMATS`; sniffed from the file if omitted.

    Returns
    -------
    HammerTest
        Hits sorted by number; responses in the order of the table's
        acceleration rows.

    Raises
    ------
    FileNotFoundError
        The file does not exist.
    UnknownFormatError
        The format is not registered or cannot be recognised.
    UFFReadError
        Truncated or corrupt file (pyuff's errors are re-raised with the file name).
    FunctionTypeError
        A dataset is not a real time response (e.g. FRFs, function type 4).
    ChannelMismatchError
        A table row without data in some hit, data without a table row, a
        duplicate dataset for the same node and hit, or a quantity mismatch.
    ReferenceNodeError
        Hits (or the datasets of one hit) name different non-zero reference
        nodes: they were excited at different points.
    UnitSystemError
        A units dataset 164 that is not SI contradicts a channel's unit label,
        or a channel has no (known) unit label under it.
    SamplingError
        Mixed sampling intervals, record lengths or start times.
    NonFiniteDataError, ZeroForceError
        NaN/inf samples; an all-zero or constant force record.
    ChannelTableError
        The channel table is invalid.
    """
    path = Path(os.fspath(uff_path))
    if not path.is_file():
        raise FileNotFoundError(f"hammer-test file {str(path)!r} does not exist")
    if isinstance(channels_csv, pd.DataFrame):
        table = validate_channels(channels_csv, source=f"channel table for {path.name}")
    else:
        table = read_channels(channels_csv)
    if format is None:
        for name, (sniff, _, _) in HAMMER_FORMATS.items():
            if sniff(path):
                format = name
                break
        else:
            raise UnknownFormatError(
                f"{path}: cannot recognise the file format; supported formats: "
                + "; ".join(f"{k} ({v[2]})" for k, v in HAMMER_FORMATS.items())
            )
    if format not in HAMMER_FORMATS:
        raise UnknownFormatError(f"{path}: unknown format {format!r}; supported formats: {sorted(HAMMER_FORMATS)}")
    return HAMMER_FORMATS[format][1](path, table)

