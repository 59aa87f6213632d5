"""Reading impact-hammer tests: the :class:`HammerTest` type and its readers.

A hammer test is a set of hits; in every hit the front-end records the force
of the instrumented hammer and the response of every accelerometer. The lab
exports them as UFF58 time histories (function type 1, one dataset per
channel per hit, the hit number in the record-6 "version / sequence number"
field, pyuff key ``ver_num``; files whose sequence number is the same in
every dataset, or differs in every dataset (a dataset counter), are numbered
by load case or by order, see :func:`_hit_numbers`) and describes the
channels in a separate table (:mod:`ema.channels`): the measuring
directions, positions and FE nodes are taken from that table, the samples
and the sampling from the file. The table selects the channels: datasets of
a node without a row are skipped with a WARNING naming them. A channel is
its node and quantity: at a driving point (force and accelerometer at one
node) the datasets' specific data type (13 / 12) tells them apart.

What a front end writes beside the time histories is skipped with an INFO
log: other dataset types, and datasets 58 of other function types (auto and
cross spectra, FRFs, coherences of the same run), one line per type with the
count; a file with no time response at all is refused.

Units (:func:`_channel_scale`): data labelled in g, mg, mm/s², in/s², ft/s²,
kN, lbf, kgf... are converted to SI by their labels; raw voltages (labelled V,
mV, µV, or unlabelled when the channel table has a ``sensitivity`` column) are
multiplied by the table's sensitivity (``SI = recorded x sensitivity``), and
refused naming the channel when there is none; a label the reader does not
know is taken in the table's unit, with one WARNING per label naming its
channels. A units dataset 164 that is not SI must agree with those labels,
see :func:`_check_unit_system`.

Sampling: the abscissa may be labelled s, ms or us; an abscissa flagged
uneven (spacing 0) whose values are evenly spaced is read as even. Force and
responses of one hit must start at the same time; different hits may start
at different times (absolute trigger times, sub-sample trigger jitter), and
the test's time axis is then the first hit's: every hit's windows are placed
at its own pulse (:mod:`ema.estimate`), so only the alignment within a hit
matters.

Readers go through a small registry (like ObsPy's ``read``):
:func:`read_hammer` sniffs the format and dispatches; an unknown format raises
:class:`UnknownFormatError` listing the supported ones: UFF58 (this module) and
the MDF files of data loggers (:mod:`ema.hammer_mdf`, a continuous recording
that :mod:`ema.continuous` cuts into hits). Several files of one
setup (one hit per file) are read as one test. In-memory data enter through
:meth:`HammerTest.from_arrays`; both paths end in the same validated
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

from fem_import.modes import number_ranges
from fem_import.uff_text import DatasetSpan, fortran_field_problem, prepare_for_pyuff, unreadable_field

from .channels import (datasheet_like_sensitivity, read_channels, unapplied_sensitivity_note, unit_key, unit_kind,
                       validate_channels)

__all__ = [
    "HammerTest",
    "read_hammer",
    "HAMMER_FORMATS",
    "HammerDataError",
    "UFFReadError",
    "MDFReadError",
    "TDMSReadError",
    "CSVReadError",
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


class MDFReadError(HammerDataError):
    """An MDF file asammdf cannot read (truncated, corrupt), or a channel block in it."""


class TDMSReadError(HammerDataError):
    """A TDMS file npTDMS cannot read, or reads only in part (cut short), or a channel without a time base."""


class CSVReadError(HammerDataError):
    """A CSV table of time histories that cannot be read: a cell not a number, a row cut short, no time column."""


class UnknownFormatError(HammerDataError):
    """A file format (given or sniffed) that no registered reader handles."""


class FunctionTypeError(HammerDataError):
    """A UFF58 dataset of the wrong function type (e.g. FRFs where time histories are expected)."""


class ChannelMismatchError(HammerDataError):
    """File and channel table disagree: a table row without data, data without a row, a duplicate dataset."""


class ReferenceNodeError(ChannelMismatchError):
    """Hits recorded at different reference (excitation) nodes: they cannot be averaged into one FRF."""


class UnitSystemError(HammerDataError):
    """Units that cannot be converted to SI: a units dataset 164 that is not SI and that the channels' unit labels
    do not confirm, raw voltages without a sensitivity, a unit of another quantity."""


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
        Time axis of the records [s]: the first hit's (the hit happens some
        pre-trigger time after its start). Records of other hits may have
        started at other absolute times; every hit is windowed and
        transformed relative to its own pulse, so only the sampling matters.
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
            raise SamplingError(f"{src}: sampling rate fs must be finite and > 0 Hz, got {fs!r}")
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
            raise SamplingError(f"{src}: hits must be {n_hits} unique hit numbers, got {hits!r}")
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
#: UFF58 function types (record 6, field 1), for messages.
_FUNCTION_NAMES = {0: "general or unknown", 1: "time response", 2: "auto spectrum", 3: "cross spectrum",
                   4: "frequency response function", 5: "transmissibility", 6: "coherence", 7: "auto correlation",
                   8: "cross correlation", 9: "power spectral density", 10: "energy spectral density",
                   11: "probability density function", 12: "spectrum", 13: "cumulative frequency distribution",
                   14: "peaks valley", 15: "stress/cycles", 16: "strain/cycles", 17: "orbit",
                   18: "mode indicator function", 19: "force pattern", 20: "partial power", 21: "partial coherence",
                   22: "eigenvalue", 23: "eigenvector", 24: "shock response spectrum", 25: "finite impulse response",
                   26: "multiple coherence", 27: "order function"}
#: Plausible peak force of an impact hammer [N] (a light tap of a modal hammer to a sledge); outside it the force's
#: unit or sensitivity is wrong (a datasheet sensitivity, V per N, in place of the factor N per V gives ~1e-5 of it).
_FORCE_PEAK_N = (0.1, 1e6)
#: Abscissa unit labels of time histories (:func:`ema.channels.unit_key` form) -> factor to seconds.
_TIME_UNITS = {"": 1.0, "s": 1.0, "sec": 1.0, "secs": 1.0, "second": 1.0, "seconds": 1.0, "ms": 1e-3,
               "msec": 1e-3, "us": 1e-6, "usec": 1e-6, "\u00b5s": 1e-6, "\u03bcs": 1e-6, "\ufffds": 1e-6}


def _function_label(t: int) -> str:
    return f"function type {t}" + (f" ({_FUNCTION_NAMES[t]})" if t in _FUNCTION_NAMES else "")


def _split_function_types(p: str, dsets: list[dict], wanted: set[int], purpose: str) -> tuple[list[dict], dict]:
    """The datasets 58 of the ``wanted`` function types, and the others by type (``{type: [datasets]}``).

    A front end's "export all functions of the run" writes auto and cross spectra, FRFs or coherences beside the
    functions a reader uses; they are skipped with one INFO line per function type (with the count).
    """
    kept: list[dict] = []
    other: dict[int, list[dict]] = {}
    for d in dsets:
        t = int(d["func_type"])
        (kept if t in wanted else other.setdefault(t, [])).append(d)
    for t, ds in sorted(other.items()):
        log.info("%s: skipped %d dataset%s 58 of %s (datasets %s); %s", p, len(ds), "s" if len(ds) > 1 else "",
                 _function_label(t), _index_ranges([d["_index"] for d in ds]), purpose)
    return kept, other


def _index_ranges(idx: list[int], limit: int = 6) -> str:
    """'1-3, 7, 9-12' (at most ``limit`` runs)."""
    return number_ranges(sorted(idx), limit)


def _check_record6(d: dict, p: str) -> None:
    """Direction codes within -6..6 and a response node > 0, or the record is named as malformed.

    pyuff turns optional fields it cannot parse into 0 (a custom writer overflowing the 10-character entity name
    shifts the node and direction fields), so a direction code like 900 or a response node 0 is what a malformed
    record 6 looks like; 0 is also not a node number (UFF nodes start at 1).
    """
    for key in ("rsp_dir", "ref_dir"):
        v = d.get(key)
        if v is None or isinstance(v, str) or not np.isfinite(v):
            raise UFFReadError(f"{p}: dataset {d.get('_index')}: header field {key!r} is unreadable ({v!r})")
        if not -6 <= int(v) <= 6:
            raise UFFReadError(
                f"{p}: record 6 of dataset {d['_index']} is malformed: "
                f"{'response' if key == 'rsp_dir' else 'reference'} direction code {int(v)} is outside -6..6 "
                f"(response node read as {int(d['rsp_node'])}); the fields are not at their columns "
                f"(FORMAT(2(I5,I10),2(1X,10A1,I10,I4)): an entity name longer than 10 characters?): fix the export"
            )
    if int(d["rsp_node"]) <= 0:
        raise UFFReadError(
            f"{p}: dataset {d['_index']} ({_function_label(int(d['func_type']))}): response node {int(d['rsp_node'])} "
            f"is not a valid UFF node (node numbers start at 1; a 0-based channel numbering?): renumber the channels "
            f"in the export (and the channel table), or fix record 6 if it is malformed"
        )


def _x_resolution(d: dict, xmax: float) -> float:
    """Half the spacing of the numbers an abscissa of magnitude ``xmax`` can be written with in this dataset."""
    if xmax <= 0:
        return 0.0
    if d.get("binary"):
        single = int(d.get("ord_data_type", 4)) in (2, 5)
        return float(np.spacing(np.float32(xmax) if single else np.float64(xmax))) / 2
    # ASCII abscissa values are E13.5 fields: 5 significant digits in Fortran's 0.12345E+01 form
    return 0.5 * 10.0 ** (np.floor(np.log10(xmax)) + 1 - 5)


def _sampling(d: dict, p: str, name: str) -> tuple[float, float, float, float]:
    """``(dt, t0, dt_tol, t0_tol)`` of a time history in seconds.

    The abscissa unit label gives seconds (``s``, ``ms``, ``us``; unlabelled = s); another unit is refused. Even
    spacing (code 1) takes dt and t0 from the header; spacing 0 with abscissa values that are evenly spaced
    (within the precision they are written with) takes them from a least-squares line through the values, and
    the tolerances say how well that line is known; unevenly spaced values are refused naming the step range.
    """
    raw = str(d.get("abscissa_axis_units_lab", "") or "").strip()
    key = unit_key(raw)
    if key not in _TIME_UNITS:
        raise SamplingError(
            f"{p}: {_dset_label(d)} ({name!r}): the abscissa unit {raw!r} is not a unit of time (s, ms or us); a "
            f"hammer test needs time histories"
        )
    scale = _TIME_UNITS[key]
    spacing = int(d["abscissa_spacing"])
    if spacing == 1:
        return float(d["abscissa_inc"]) * scale, float(d["abscissa_min"]) * scale, 0.0, 0.0
    if spacing != 0:
        raise SamplingError(f"{p}: {_dset_label(d)} ({name!r}): abscissa spacing code {spacing}; expected 1 (even) "
                            f"or 0 (uneven, with abscissa values)")
    x = np.asarray(d.get("x"), dtype=float)
    n = x.size
    if n < 2 or not np.all(np.isfinite(x)):
        raise SamplingError(f"{p}: {_dset_label(d)} ({name!r}): uneven abscissa without {n} finite abscissa values")
    k = np.arange(n, dtype=float) - (n - 1) / 2
    dt = float(k @ (x - x.mean()) / (k @ k))
    t0 = float(x.mean() - dt * (n - 1) / 2)
    res = _x_resolution(d, float(np.abs(x).max()))
    resid = float(np.abs(x - (t0 + dt * np.arange(n))).max())
    if not dt > 0 or resid > 3 * res + 1e-6 * abs(dt):
        steps = np.diff(x)
        raise SamplingError(
            f"{p}: {_dset_label(d)} ({name!r}): the abscissa values are uneven (step {steps.min() * scale:.6g} to "
            f"{steps.max() * scale:.6g} s, {resid * scale:.3g} s off an even grid); a hammer test needs evenly "
            f"sampled records"
        )
    return dt * scale, t0 * scale, 2 * res / (n - 1) * scale, 3 * res * scale


def _channel_scale(p: str, row, dsets: list[dict], has_sensitivity: bool) -> tuple[float, str, str]:
    """``(factor to SI, label, kind)`` of one UFF channel from its datasets' unit labels (:func:`unit_scale`).

    A channel labelled differently in different hits is refused.
    """
    labels = {str(d.get("ordinate_axis_units_lab", "") or "").strip() for d in dsets}
    if len(labels) > 1:
        raise ChannelMismatchError(f"{p}: channel {row.name!r} (node {row.node}) is in {sorted(labels)} in different "
                                   f"hits; one unit per channel")
    first = dsets[0]
    return unit_scale(p, row, labels.pop(), has_sensitivity, f"dataset {first['_index']} (hit {first.get('ver_num')})")


def unit_scale(p: str, row, lab: str, has_sensitivity: bool, where: str) -> tuple[float, str, str]:
    """``(factor to SI, label, kind)`` of one channel from its unit label in the file and the table's sensitivity.

    ``kind`` is :func:`ema.channels.unit_kind`'s. A physical label converts by itself (the front end converted,
    so the sensitivity is not applied); an electrical one (V, mV) is a raw voltage converted by the sensitivity
    (``SI = recorded x sensitivity``) and refused without one; unlabelled data are multiplied by the sensitivity
    when the table has one (else taken as SI); an unknown label is taken in the table's unit. A unit of the
    other quantity is refused. ``where`` names the record in messages (``"dataset 12 (hit 3)"``).
    """
    kind, factor = unit_kind(row.quantity, lab)
    sens = float(row.sensitivity) if has_sensitivity else None
    if kind == "electrical":
        if sens is None:
            raise UnitSystemError(
                f"{p}: {where}, channel {row.name!r} (node {row.node}): "
                f"unit label {lab!r} is an electrical unit: the data are raw voltages, and the channel table has no "
                f"'sensitivity' column to convert them to {row.unit}; add one (the factor on the recorded values: "
                f"SI = recorded x sensitivity, e.g. 98.07 for a 10.2 mV/(m/s^2) accelerometer recorded in V, 444.4 "
                f"for a 2.25 mV/N hammer), or export the data in physical units"
            )
        return sens, lab, kind
    if kind == "raw":
        return (sens if sens is not None else 1.0), lab, kind
    if kind == "other":
        raise UnitSystemError(
            f"{p}: {where}, channel {row.name!r} (node {row.node}) is "
            f"a {row.quantity} channel in the table, but its data are labelled {lab!r}, a unit of another quantity; "
            f"the table row or the file's channel is wrong"
        )
    return factor, lab, kind


def _label_agrees(quantity: str, label: str, u: dict) -> bool | None:
    """Whether a channel's unit label names the unit the units dataset ``u`` implies; None if unlabelled/unknown.

    ``g`` (and ``mg``) is not a unit of any system, so it agrees with every one; so do electrical labels (raw
    voltages, converted to SI by the channel table's sensitivity, not by a unit system).
    """
    kind, factor = unit_kind(quantity, label)
    if kind == "electrical":
        return True
    if kind != "physical":
        return None
    if quantity == "acceleration" and unit_key(label) in ("g", "gn", "g0", "mg"):
        return True
    # 164 factors are file units per SI unit: the file's length unit is 1/length m, its force unit 1/force N
    system = 1.0 / float(u["length"] if quantity == "acceleration" else u["force"])
    return bool(np.isclose(factor, system, rtol=1e-3))


def _check_unit_system(p: str, units: list[dict], by_key: dict, rows: dict) -> None:
    """Check the datasets 58 against a units dataset 164 that is not SI.

    A 164 governs the datasets after it (to the next 164). This reader converts by the datasets' unit labels
    (:func:`_channel_scale`), not by a unit system. If a 164 says inch/lbf and a label says ``N`` (or there is no
    label, so the data would be taken as SI), one of the two is wrong and the results would be off by the
    unit ratio without a message; so that is refused. Labels that name the declared system's units (``lbf``,
    ``in/s^2``) or ``g`` agree: the data are converted by the labels, logged at INFO.
    """
    if not units or all(_is_si(u) for u in units):
        return
    starts = [u["_index"] for u in units]
    agreed: set[str] = set()
    for (hit, key), d in sorted(by_key.items(), key=lambda kv: kv[1]["_index"]):
        k = int(np.searchsorted(starts, d["_index"])) - 1
        if k < 0 or _is_si(units[k]):
            continue
        u, row = units[k], rows[key]
        label = str(d.get("ordinate_axis_units_lab", "") or "").strip()
        ok = _label_agrees(row.quantity, label, u)
        if ok:
            agreed.add(f"{row.quantity} in {label}")
            continue
        why = (f"is labelled {label!r}, which is not the declared system's {row.quantity} unit" if ok is False else
               (f"has the unit label {label!r}, which the reader does not know" if unit_key(label)
                else "has no unit label") + ", so its data would be taken in SI units, not in the declared system's")
        raise UnitSystemError(
            f"{p}: {_units_label(u)}, but hit {hit}, channel {row.name!r} (node {row.node}, dataset {d['_index']}) "
            f"{why}; the unit system and the channel's unit cannot both be right. Export the hammer test in SI units "
            f"(164 code 1), or with unit labels in the declared units (g, lbf, in/s^2), or remove the 164 if the "
            f"labels are right"
        )
    if agreed:
        log.info("%s: %s; every channel's unit label agrees (%s): converted by the labels", p,
                 "; ".join(_units_label(u) for u in units if not _is_si(u)), ", ".join(sorted(agreed)))


def _ref_node(d: dict) -> int:
    return int(d.get("ref_node") or 0)


def _check_reference_nodes(p: str, by_key: dict, rows: dict, fnode: int) -> None:
    """Compare the datasets' reference nodes with each other and with the table's force node.

    A single-reference FRF is an H1 average over hits at one excitation point; a hit at another point averaged
    in would corrupt it without a trace, so hits (or the datasets of one hit) naming different reference nodes
    are refused. 0 means "not set" (many writers leave it) and an acceleration channel naming its own node is a
    self-reference, not an excitation point: both are not compared. One reference node for all hits that is
    not the table's force node may be a point-numbering difference: WARNING, the table is used.
    """
    refs: dict[int, dict[int, list[tuple[int, str]]]] = {}
    for (hit, key), d in by_key.items():
        node = key[0]
        r = _ref_node(d)
        if r == 0 or (r == node and node != fnode):
            continue
        refs.setdefault(hit, {}).setdefault(r, []).append(key)

    def chans(keys: list[tuple[int, str]]) -> str:
        names = [f"{rows[k].name!r} (node {k[0]})" for k in sorted(keys)]
        return ", ".join(names[:4]) + (f" and {len(names) - 4} more" if len(names) > 4 else "")

    for hit in sorted(refs):
        if len(refs[hit]) > 1:
            listed = "; ".join(f"node {r} in {chans(ks)}" for r, ks in sorted(refs[hit].items()))
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
                        rows[(fnode, "force")].name, fnode)


def _hit_numbers(dsets: list[dict], keys: list, p: str, rows: dict) -> list[int]:
    """The hit of each dataset: its sequence number (``ver_num``), as the lab writes it.

    ``keys`` are the datasets' channels (``(node, quantity)``). Front-ends that export every hit with the same
    sequence number number them by the load case (``load_case_id``) or only by their order in the file. So when
    the sequence number is the same in every dataset and a channel occurs more than once, the load case is used
    if it tells the hits apart, else the order: the k-th dataset of every channel is hit k — only when every
    channel occurs equally often (otherwise the hits cannot be counted, and the channels with fewer datasets are
    named). A sequence number that differs in every dataset is a running dataset counter, not a hit number: the
    load case or the order is used the same way. Either is logged (WARNING).
    """
    ver = [int(d["ver_num"]) for d in dsets]
    case = [int(d.get("load_case_id", 0) or 0) for d in dsets]
    n_chan = len(set(keys))
    same = len(set(ver)) == 1
    counter = len(dsets) > 1 and len(set(ver)) == len(dsets) and n_chan > 1
    if not same and not counter:
        return ver
    if same and len(set(zip(ver, keys))) == len(dsets):
        return ver
    what = (f"every dataset has sequence number {ver[0]}" if same else
            f"every dataset has its own sequence number ({min(ver)}..{max(ver)}: a dataset counter, not hit numbers)")
    if len(set(case)) > 1 and len(set(zip(case, keys))) == len(dsets):
        log.warning("%s: %s; the hits are numbered by their load case (%s)", p, what,
                    ", ".join(str(c) for c in sorted(set(case))))
        return case
    counts = {k: keys.count(k) for k in set(keys)}
    if len(set(counts.values())) != 1:
        most = max(counts.values())
        short = sorted((k for k, c in counts.items() if c < most), key=lambda k: (counts[k], k))
        listed = ", ".join(f"{rows[k].name!r} (node {k[0]}, {counts[k]})" for k in short[:6])
        more = f" and {len(short) - 6} more" if len(short) > 6 else ""
        raise ChannelMismatchError(
            f"{p}: {what} and no load case tells the hits apart, so the hits can only be counted by their order (a "
            f"channel that appears twice is in two hits); but the channels are not recorded equally often: "
            f"{listed}{more} have fewer datasets than the others ({most}), so which hit lacks them cannot be told. "
            f"Number the hits in the export (sequence number or load case per hit), or remove the incomplete hit"
        )
    seen: dict = {}
    order = []
    for k in keys:
        seen[k] = seen.get(k, 0) + 1
        order.append(seen[k])
    log.warning("%s: %s and no load case tells the hits apart; the %d hits are numbered by their order in the file "
                "(the k-th dataset of each channel is hit k)", p, what, max(order))
    return order


def _channel_of(d: dict, p: str, by_node: dict) -> tuple[int, str] | None:
    """The channel ``(node, quantity)`` of a dataset, or None when the table has no row at its node.

    At a node with one table row that row is the channel, and the file's specific data type must agree with its
    quantity. At a driving point (a force and an acceleration row at one node) the specific data type decides
    (13/9 force, 12 acceleration); unknown (0) cannot tell them apart.
    """
    node = int(d["rsp_node"])
    cands = by_node.get(node)
    if not cands:
        return None
    spec = int(d["ordinate_spec_data_type"])
    if len(cands) == 1:
        row = cands[0]
        if spec not in _SPEC_TYPES[row.quantity]:
            raise ChannelMismatchError(
                f"{p}: {_dset_label(d)}: the file says the ordinate is {_SPEC_NAMES.get(spec, spec)!r} "
                f"(specific data type {spec}) but channel {row.name!r} is a {row.quantity} channel in the table"
            )
        return node, row.quantity
    fits = [r for r in cands if spec in _SPEC_TYPES[r.quantity] and spec != 0]
    if len(fits) != 1:
        names = " and ".join(f"{r.name!r} ({r.quantity})" for r in cands)
        why = ("does not say which (specific data type 0, unknown)" if spec == 0 else
               f"says {_SPEC_NAMES.get(spec, spec)!r} (specific data type {spec}), neither")
        raise ChannelMismatchError(
            f"{p}: {_dset_label(d)}: node {node} is a driving point in the channel table ({names}), but the dataset "
            f"{why}; export the specific data type (13 excitation force, 12 acceleration) or give the two "
            f"channels distinct node numbers in the file and the table"
        )
    return node, fits[0].quantity


def _read_uff58(path: Path, channels: pd.DataFrame) -> HammerTest:
    p = str(path)
    log.info("reading hammer test %s (%.1f MB)", p, path.stat().st_size / 1e6)
    dsets, units = _read_uff_file(path, 58)
    for d in dsets:
        _check_dset_fields(d, p, ("func_type",))
    dsets, other = _split_function_types(p, dsets, {1}, "a hammer test uses the time responses (function type 1)")
    if not dsets:
        found = "; ".join(f"{len(ds)} dataset{'s' if len(ds) > 1 else ''} of {_function_label(t)}"
                          for t, ds in sorted(other.items()))
        d = other[min(other)][0]
        hint = ("; these are FRFs: read them with 'railmodal lab identify --frf' (ema.read_frf_uff)" if 4 in other
                else "")
        raise FunctionTypeError(
            f"{p}: no time response (function type 1) in the file: it holds {found} ({_dset_label(d)} has function "
            f"type {int(d['func_type'])}, expected 1 (time response) for a hammer test){hint}"
        )
    for d in dsets:
        _check_dset_fields(d, p, ("func_type", "ver_num", "rsp_node", "rsp_dir", "ref_node", "num_pts",
                                  "abscissa_spacing", "abscissa_min", "abscissa_inc", "ord_data_type",
                                  "ordinate_spec_data_type"))
        _check_record6(d, p)
    rows = {(int(r.node), str(r.quantity)): r for r in channels.itertuples(index=False)}
    by_node: dict[int, list] = {}
    for r in channels.itertuples(index=False):
        by_node.setdefault(int(r.node), []).append(r)
    fnode = int(channels.loc[channels["quantity"] == "force", "node"].iloc[0])
    fkey = (fnode, "force")
    has_sens = "sensitivity" in channels.columns

    # the table selects the channels: data without a row are skipped (named), never guessed into a channel
    keyed, keys = [], []
    extra: dict[int, list[dict]] = {}
    for d in dsets:
        key = _channel_of(d, p, by_node)
        if key is None:
            extra.setdefault(int(d["rsp_node"]), []).append(d)
            continue
        keyed.append(d)
        keys.append(key)
    if extra:
        def describe(node, ds):
            d = ds[0]
            name = str(d.get("rsp_ent_name", "") or "").strip()
            label = str(d.get("ordinate_axis_units_lab", "") or "").strip()
            return (f"node {node}" + (f" ({name!r})" if name and name.upper() != "NONE" else "")
                    + (f" in {label!r}" if unit_key(label) else "")
                    + f": {len(ds)} dataset{'s' if len(ds) > 1 else ''}")
        many = len(extra) > 1
        log.warning("%s: %d channel%s in the file without a row in the channel table %s skipped (the table selects "
                    "the channels): %s", p, len(extra), "s" if many else "", "are" if many else "is",
                    "; ".join(describe(n, ds) for n, ds in sorted(extra.items())))
    if not keyed:
        raise ChannelMismatchError(
            f"{p}: no dataset belongs to a channel of the table (file nodes {sorted(extra)}, table nodes "
            f"{sorted(by_node)}); the table or the file is not the one of this test"
        )

    by_key: dict[tuple[int, tuple[int, str]], dict] = {}
    sampling: dict[int, tuple[float, float, float, float]] = {}
    wrong_dir: dict[tuple[int, str], tuple[set[int], list[int]]] = {}
    for d, hit, key in zip(keyed, _hit_numbers(keyed, keys, p, rows), keys):
        row = rows[key]
        node = key[0]
        if (hit, key) in by_key:
            raise ChannelMismatchError(
                f"{p}: hit {hit}, channel {row.name!r} (node {node}) appears twice (datasets "
                f"{by_key[(hit, key)]['_index']} and {d['_index']}); each channel must be recorded once per hit"
            )
        if int(d["ord_data_type"]) not in (2, 4):
            raise FunctionTypeError(
                f"{p}: {_dset_label(d)} ({row.name!r}): ordinate data type {int(d['ord_data_type'])} is not real "
                f"(expected 2 or 4 for a time history)"
            )
        n_data = len(d["data"])
        if n_data != int(d["num_pts"]):
            raise UFFReadError(
                f"{p}: {_dset_label(d)} ({row.name!r}): the header announces {int(d['num_pts'])} samples but the "
                f"dataset holds {n_data}; the file is truncated or corrupt"
            )
        sampling[d["_index"]] = _sampling(d, p, row.name)
        rdir = int(d["rsp_dir"])
        if abs(rdir) in _AXES:
            axis = np.sign(rdir) * np.asarray(_AXES[abs(rdir)])
            tdir = np.array([row.dx, row.dy, row.dz])
            if float(axis @ tdir) < 0.99:
                codes, where = wrong_dir.setdefault(key, (set(), []))
                codes.add(rdir)
                where.append(int(d["_index"]))
        by_key[(hit, key)] = d
    for key, (codes, where) in wrong_dir.items():
        row = rows[key]
        tdir = tuple(round(float(v), 4) for v in (row.dx, row.dy, row.dz))
        warnings.warn(
            f"{p}: channel {row.name!r} (node {key[0]}): the file's direction code"
            f"{'s ' + ', '.join(map(str, sorted(codes))) if len(codes) > 1 else ' ' + str(next(iter(codes)))} "
            f"disagrees with the table's measuring direction {tdir} (dataset{'s' if len(where) > 1 else ''} "
            f"{_index_ranges(where)}); the table is used",
            ChannelDirectionWarning,
            stacklevel=4,  # the caller of read_hammer
        )

    hits = sorted({h for h, _ in by_key})
    for hit in hits:
        for key, row in rows.items():
            if (hit, key) in by_key:
                continue
            node = key[0]
            skipped = [d for ds in other.values() for d in ds if int(d["rsp_node"]) == node]
            if skipped:
                d = next((x for x in skipped if int(x["ver_num"]) == hit), skipped[0])
                raise FunctionTypeError(
                    f"{p}: hit {hit}: channel {row.name!r} (node {node}, {row.quantity}) has no time response in this "
                    f"hit; the file has {_dset_label(d)} of it with function type {int(d['func_type'])}, expected 1 "
                    f"(time response) for a hammer test: export its time history, or remove the row and the channel"
                )
            hint = (f"; the file has data at node(s) {sorted(extra)} without a table row (skipped): is the node "
                    f"number in the table right?" if extra else "")
            raise ChannelMismatchError(
                f"{p}: hit {hit}: channel {row.name!r} (node {node}, {row.quantity}) is in the channel table "
                f"but has no dataset in this hit; fix the table or drop the hit{hint}"
            )
    _check_reference_nodes(p, by_key, rows, fnode)
    _check_unit_system(p, units, by_key, rows)

    ref = by_key[(hits[0], fkey)]
    dt0, _, dtol0, _ = sampling[ref["_index"]]
    n0 = int(ref["num_pts"])
    if not dt0 > 0:
        raise SamplingError(f"{p}: {_dset_label(ref)}: sampling interval must be > 0 s, got {dt0!r}")
    starts: dict[int, float] = {}
    for hit in hits:
        force_d = by_key[(hit, fkey)]
        _, ft0, _, ftol = sampling[force_d["_index"]]
        starts[hit] = ft0
        for key in rows:
            d = by_key[(hit, key)]
            name, node = rows[key].name, key[0]
            dt, t0, dtol, t0tol = sampling[d["_index"]]
            if abs(dt - dt0) > 1e-9 * dt0 + dtol + dtol0:
                raise SamplingError(
                    f"{p}: hit {hit}, channel {name!r} (node {node}): sampling interval {dt!r} s differs from "
                    f"{dt0!r} s of the force channel in hit {hits[0]}; all records must share one sampling rate"
                )
            if int(d["num_pts"]) != n0:
                raise SamplingError(
                    f"{p}: hit {hit}, channel {name!r} (node {node}): {int(d['num_pts'])} samples, but the force "
                    f"channel in hit {hits[0]} has {n0}; all records must have the same length"
                )
            # force and responses of a hit must be recorded on one time axis (H1 relates them sample by sample);
            # different hits may start at different times (absolute trigger times, sub-sample trigger jitter)
            if abs(t0 - ft0) > 1e-6 * dt0 + t0tol + ftol:
                raise SamplingError(
                    f"{p}: hit {hit}, channel {name!r} (node {node}): record starts at {t0!r} s, the force channel "
                    f"of the same hit at {ft0!r} s; the force and the responses of a hit must share one time axis "
                    f"(start times may differ between hits, not within one)"
                )
    history: list[str] = [f"read_hammer {p}"]
    spread = max(starts.values()) - min(starts.values())
    if spread > 1e-6 * dt0:
        note = (f"the hits' records start at different times ({min(starts.values()):.9g} to "
                f"{max(starts.values()):.9g} s, spread {spread:.6g} s = {spread / dt0:.4g} samples): each hit is "
                f"used on its own time axis (windows at its own pulse); the test's time axis is hit {hits[0]}'s")
        log.info("%s: %s", p, note)
        history.append(note)

    acc_keys = [(int(n), "acceleration") for n in channels.loc[channels["quantity"] == "acceleration", "node"]]
    force = np.empty((len(hits), n0))
    resp = np.empty((len(hits), len(acc_keys), n0))
    scale = {key: _channel_scale(p, rows[key], [by_key[(h, key)] for h in hits], has_sens) for key in rows}
    for i, hit in enumerate(hits):
        force[i] = by_key[(hit, fkey)]["data"] * scale[fkey][0]
        for j, key in enumerate(acc_keys):
            resp[i, j] = by_key[(hit, key)]["data"] * scale[key][0]
    history += unit_notes(p, rows, scale, has_sens)
    check_force_peak(p, force, rows[fkey], scale[fkey], has_sens)
    _, t00, _, _ = sampling[ref["_index"]]
    test = HammerTest(fs=1.0 / dt0, time=_time_axis(t00, 1.0 / dt0, n0), channels=channels, force=force,
                      responses=resp, hits=tuple(hits), source=p, history=tuple(history))
    log.info("read %s: %d hits x %d channels + force, fs %g Hz, %d samples (%.3g s)",
             p, test.n_hits, test.n_channels, test.fs, n0, n0 * dt0)
    return test


def check_force_peak(p: str, force: np.ndarray, row, scale: tuple[float, str, str], has_sens: bool) -> None:
    """WARNING when the force's typical peak is no hammer's: a wrong unit label or sensitivity (not refused)."""
    peak = float(np.median(np.abs(force).max(axis=1)))
    if np.isfinite(peak) and peak > 0 and not _FORCE_PEAK_N[0] <= peak <= _FORCE_PEAK_N[1]:
        # (NaN and all-zero forces are refused by HammerTest with their own message)
        f_lab, f_kind = scale[1], scale[2]
        log.warning("%s: the hammer force peaks at %.4g N (median over the hits), outside the %g N to %g N of an "
                    "impact hammer: check the force channel's unit label (%s) and sensitivity%s", p, peak,
                    _FORCE_PEAK_N[0], _FORCE_PEAK_N[1], repr(f_lab) if f_lab else "none",
                    f" ({float(row.sensitivity):.6g}: SI = recorded x sensitivity)"
                    if has_sens and f_kind in ("raw", "electrical") else "")


def _channel_list(names: list[str], limit: int = 8) -> str:
    return ", ".join(names[:limit]) + (f" and {len(names) - limit} more" if len(names) > limit else "")


def unit_notes(p: str, rows: dict, scale: dict, has_sens: bool) -> list[str]:
    """Log what the unit labels and sensitivities did (once per label / case); return the history notes."""
    notes: list[str] = []
    converted = sorted({f"{rows[k].quantity} from {lab}" for k, (f, lab, kind) in scale.items()
                        if kind == "physical" and f != 1.0})
    if converted:
        log.info("%s: converted to SI units: %s", p, ", ".join(converted))
        notes.append(f"converted to SI: {', '.join(converted)}")
    applied = [f"{rows[k].name!r} ({lab or 'no label'}) x {f:.10g}" for k, (f, lab, kind) in scale.items()
               if has_sens and kind in ("electrical", "raw") and f != 1.0]
    if applied:
        note = (f"sensitivity applied to {len(applied)} channel{'s' if len(applied) > 1 else ''} recorded raw "
                f"(SI = recorded x sensitivity): {', '.join(applied)}")
        # data without any unit label are taken as raw by inference: say it where the user looks
        unlabelled = any(kind == "raw" and f != 1.0 for f, _, kind in scale.values())
        (log.warning if unlabelled else log.info)("%s: %s%s", p, note, "; the data carry no unit label, so they "
                                                  "are taken as raw: if the front end converted them, set the "
                                                  "sensitivity to 1" if unlabelled else "")
        notes.append(note)
    odd = [f"{rows[k].name!r} ({lab!r}, sensitivity {f:.6g})" for k, (f, lab, kind) in scale.items()
           if kind == "electrical" and datasheet_like_sensitivity(lab, f)]
    if odd:
        note = (f"the sensitivity of {_channel_list(odd)} gives less than 0.5 SI units per volt: it looks like a "
                f"datasheet sensitivity (V per N or per m/s^2); the column is the factor on the recorded values "
                f"(SI = recorded x sensitivity), e.g. 1 / 0.0102 = 98.04 for 10.2 mV/(m/s^2) recorded in V")
        log.warning("%s: %s", p, note)
        notes.append(note)
    unknown: dict[str, list[str]] = {}
    for k, (f, lab, kind) in scale.items():
        if kind == "unknown":
            unknown.setdefault(lab, []).append(f"{rows[k].name!r} (node {k[0]})")
    for lab, names in unknown.items():
        units = sorted({rows[k].unit for k, (_, lb, kind) in scale.items() if kind == "unknown" and lb == lab})
        note = (f"unit label {lab!r} not recognised on {len(names)} channel{'s' if len(names) > 1 else ''} "
                f"({_channel_list(names)}); the data are taken in {' and '.join(units)}, as the channel table says")
        log.warning("%s: %s", p, note)
        notes.append(note)
    ignored = [f"{rows[k].name!r} ({lab!r}, sensitivity {float(rows[k].sensitivity):.6g})"
               for k, (f, lab, kind) in scale.items()
               if has_sens and kind in ("physical", "unknown") and float(rows[k].sensitivity) != 1.0]
    if ignored:
        note = unapplied_sensitivity_note(ignored, "data are")
        log.warning("%s: %s", p, note)
        notes.append(note)
    return notes


def _sniff_uff(path: Path) -> bool:
    with open(path, "rb") as fh:
        head = fh.read(512)
    for line in head.splitlines():
        if line.strip():
            return line.strip() == b"-1"
    return False


def _sniff_mdf(path: Path) -> bool:
    from .hammer_mdf import sniff  # it builds on this module's types

    return sniff(path)


def _sniff_csv(path: Path) -> bool:
    from .hammer_csv import sniff

    return sniff(path)


def _read_csv(path: Path, table: pd.DataFrame) -> HammerTest:
    from .hammer_csv import read_hammer_csv

    return read_hammer_csv(path, table)


def _read_mdf(path: Path, table: pd.DataFrame) -> HammerTest:
    from .hammer_mdf import read_hammer_mdf

    return read_hammer_mdf(path, table)


def _sniff_tdms(path: Path) -> bool:
    from .tdms_file import sniff_tdms

    with open(path, "rb") as fh:
        return sniff_tdms(fh.read(4))


def _read_tdms(path: Path, table: pd.DataFrame) -> HammerTest:
    from .hammer_tdms import read_hammer_tdms

    return read_hammer_tdms(path, table)


#: Registered hammer-test readers: format name -> (sniffer, reader, description).
HAMMER_FORMATS: dict[str, tuple[Callable[[Path], bool], Callable[[Path, pd.DataFrame], HammerTest], str]] = {
    "uff58": (_sniff_uff, _read_uff58, "universal file, dataset 58/58b time histories (function type 1)"),
    "mdf": (_sniff_mdf, _read_mdf,
            "ASAM MDF 3/4 of a data logger (asammdf): continuous or one record per trigger, "
            "channels found by the table's names"),
    "tdms": (_sniff_tdms, _read_tdms,
             "NI TDMS (LabVIEW, FlexLogger, DAQmx logging; npTDMS): continuous or one group per trigger, channels "
             "found by the table's names"),
    "csv": (_sniff_csv, _read_csv,
            "wide CSV table of a DAQ export: a time column, then one column per channel named as in the table"),
}


#: Most files read as one hammer test (one hit per file is common; a setup has tens of hits, not thousands).
MAX_HAMMER_FILES = 1000


def read_hammer(uff_path, channels_csv, *, format: str | None = None) -> HammerTest:
    """Read a hammer test: time histories plus channel table.

    Parameters
    ----------
    uff_path : str, os.PathLike or sequence of them
        The time-history file (UFF58/58b: one dataset per channel per hit,
        function type 1, hit number in the sequence-number field ``ver_num``,
        channel in ``rsp_node`` and, at a driving point, the specific data
        type), or an MDF 3/4 file of a data logger (channels named as the
        table's ``name`` column; one continuous record per channel, or one
        channel group per trigger, :mod:`ema.hammer_mdf`), or a DAQ's wide
        CSV export (a time column, then one column per channel named as in
        the table, :mod:`ema.hammer_csv`). Several
        files (a list or tuple) are the hits of one setup
        stored in several files (a lab that writes one hit per file): each is
        read and checked against the same channel table, they must share the
        sampling rate and record length, and their hits are concatenated in
        the order given and renumbered 1, 2, ... (the mapping is logged and
        kept in the history).
    channels_csv : str, os.PathLike or pandas.DataFrame
        The channel table (a CSV file or a table); it supplies the measuring
        directions, positions and FE nodes, decides which node is the force
        and selects the channels (file channels without a row are skipped
        with a WARNING naming them).
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
        Truncated or corrupt file (pyuff's errors are re-raised with the
        file name); a malformed record 6 (direction code outside -6..6,
        response node 0).
    MDFReadError
        An MDF file or channel asammdf cannot read (:mod:`ema.hammer_mdf`,
        whose other refusals use the errors below).
    CSVReadError
        A CSV table with a cell that is not a number, a row cut short or no
        time column, by row and column (:mod:`ema.hammer_csv`).
    FunctionTypeError
        No time response (function type 1) in the file (datasets of other
        function types are skipped with an INFO log, and named when a table
        channel has only such datasets), or a dataset is not real.
    ChannelMismatchError
        A table row without data in some hit, a duplicate dataset for the
        same channel and hit, a quantity mismatch, hits that cannot be
        numbered, or a driving point the file does not tell apart.
    ReferenceNodeError
        Hits (or the datasets of one hit) name different non-zero reference
        nodes: they were excited at different points.
    UnitSystemError
        A units dataset 164 that is not SI contradicts a channel's unit label,
        or a channel has no (known) unit label under it; a raw voltage (unit
        label V, mV) without a ``sensitivity`` column in the table; a unit of
        the other quantity (``g`` on the force).
    SamplingError
        Mixed sampling intervals or record lengths, force and responses of
        one hit starting at different times, an abscissa that is not time or
        is unevenly spaced; several files with different sampling rates or
        record lengths.
    NonFiniteDataError, ZeroForceError
        NaN/inf samples; an all-zero or constant force record.
    ChannelTableError
        The channel table is invalid.

    Notes
    -----
    Unit labels (see :mod:`ema.channels`): data labelled in physical units
    (g, mg, m/s², in/s², ft/s², N, kN, lbf, kgf) are converted to SI; raw
    data (labelled V/mV/µV, or unlabelled when the table has a
    ``sensitivity`` column) are multiplied by the sensitivity
    (``SI = recorded x sensitivity``); an unrecognised label is taken in the
    table's unit with one WARNING per label naming its channels. Records of
    different hits may start at different times (absolute trigger times,
    sub-sample trigger jitter: INFO); the test's time axis is the first hit's.
    A file of one record per channel that holds several impacts (a continuous
    recording) is cut into one hit per impact (:mod:`ema.continuous`).
    """
    if isinstance(uff_path, (list, tuple)):
        paths = [Path(os.fspath(q)) for q in uff_path]
        if not paths:
            raise ValueError("read_hammer: no hammer-test file given")
        if len(paths) > MAX_HAMMER_FILES:
            raise ValueError(f"read_hammer: {len(paths)} files given; at most {MAX_HAMMER_FILES} files make one test")
        if len(paths) > 1:
            return _read_several(paths, channels_csv, format)
        uff_path = paths[0]
    path = Path(os.fspath(uff_path))
    if not path.is_file():
        raise FileNotFoundError(f"hammer-test file {str(path)!r} does not exist")
    table = _table(channels_csv, path)
    from .continuous import split_continuous  # a continuous recording is cut into hits (ema.continuous)

    return split_continuous(_read_one(path, table, format))


def _table(channels_csv, path: Path) -> pd.DataFrame:
    if isinstance(channels_csv, pd.DataFrame):
        return validate_channels(channels_csv, source=f"channel table for {path.name}")
    return read_channels(channels_csv)


def _read_one(path: Path, table: pd.DataFrame, format: str | None) -> HammerTest:
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


def _cut_continuous(tests: list[HammerTest]) -> list[HammerTest]:
    """Continuous recordings among several files cut into hits of one record length, so all hits share one FFT.

    The length is the triggered files' record length when there are any (a continuous file whose impacts come
    sooner than that is refused), else the shortest any continuous file gives on its own.
    """
    from .continuous import continuous_record_length, split_continuous

    lengths = [continuous_record_length(t) for t in tests]
    if all(n is None for n in lengths):
        return tests
    triggered = [t for t, n in zip(tests, lengths) if n is None]
    length = triggered[0].n_samples if triggered else min(n for n in lengths if n is not None)
    out = []
    for t, n in zip(tests, lengths):
        if n is None:
            out.append(t)
            continue
        try:
            out.append(split_continuous(t, length=length))
        except ValueError as exc:
            raise SamplingError(f"{exc}; {triggered[0].source} has triggered records of {length} samples "
                                f"({length / t.fs:.3f} s), so the continuous file's hits cannot be cut to match "
                                f"them: record the setup one way, or give its files separately") from None
    return out


def _read_several(paths: list[Path], channels_csv, format: str | None) -> HammerTest:
    """Several files of one setup as one test: the same table, one sampling, hits concatenated and renumbered."""
    seen: dict[Path, int] = {}
    for k, q in enumerate(paths):
        if not q.is_file():
            raise FileNotFoundError(f"hammer-test file {str(q)!r} does not exist")
        r = q.resolve()
        if r in seen:
            raise ValueError(f"hammer-test file {str(q)!r} is given twice (files {seen[r] + 1} and {k + 1}); its hits "
                             f"would be averaged in twice")
        seen[r] = k
    table = _table(channels_csv, paths[0])
    tests = _cut_continuous([_read_one(q, table, format) for q in paths])
    first = tests[0]
    for t in tests[1:]:
        if abs(t.fs - first.fs) > 1e-9 * first.fs:
            raise SamplingError(f"{t.source}: sampling rate {t.fs:.10g} Hz, but {first.source} has {first.fs:.10g} Hz; "
                                f"the files of one setup must share one sampling rate")
        if t.n_samples != first.n_samples:
            raise SamplingError(f"{t.source}: records of {t.n_samples} samples, but {first.source} has "
                                f"{first.n_samples}; the files of one setup must have one record length")
    force = np.concatenate([t.force for t in tests])
    resp = np.concatenate([t.responses for t in tests])
    mapping, k = [], 0
    for t in tests:
        new = list(range(k + 1, k + t.n_hits + 1))
        k += t.n_hits
        span = f"{new[0]}" if len(new) == 1 else f"{new[0]}-{new[-1]}"
        mapping.append(f"{span} = {t.source} hit{'s' if t.n_hits > 1 else ''} {', '.join(map(str, t.hits))}")
    note = f"{len(tests)} files of one setup read as one test of {k} hits, renumbered: " + "; ".join(mapping)
    log.info("%s", note)
    starts = [float(t.time[0]) for t in tests]
    if max(starts) - min(starts) > 1e-6 / first.fs:
        log.info("the files' records start at different times (%.9g to %.9g s): each hit is used on its own time axis; "
                 "the test's time axis is %s's", min(starts), max(starts), first.source)
    source = (", ".join(t.source for t in tests) if len(tests) <= 3 else
              f"{first.source} and {len(tests) - 1} more files")
    history = tuple(h for t in tests for h in t.history) + (note,)
    test = HammerTest(fs=first.fs, time=first.time, channels=first.channels, force=force, responses=resp,
                      hits=tuple(range(1, k + 1)), source=source, history=history)
    if test.n_hits < 3:
        log.warning("%s: %d hit%s in all: %s", source, test.n_hits, "" if test.n_hits == 1 else "s",
                    "no coherence and no level check across hits" if test.n_hits == 1 else
                    "the level check across hits needs at least 3")
    return test
