"""One field run as one immutable object: channels, sensor metadata, odometry, events, QC mask, history.

A :class:`Run` holds what the instrumented bogie recorded on one passage
(thesis §2.1: one vertical accelerometer per axlebox and one lateral per
wheelset, 1 kHz, speed from an encoder and a position referenced by the
train control system) and everything later steps need to know about it:

* the acceleration channels on one time base (``fs``), with the rows of the
  sensor table that describe them (wheelset, vehicle side, direction,
  mounting point, sensitivity);
* the odometry (:class:`Odometry`): speed, position (reset at balises) and
  the balise events, on their own time base;
* the run header (:class:`RunHeader`: run id, date, direction of travel,
  orientation of the car, train, bogie, line);
* the quality-control mask (:class:`QCMask`) once :func:`estimator.qc.check_run`
  has run, and the channels rejected while reading (missing, wrong rate);
* the processing history: one line per step, appended only after the step
  succeeded (as ObsPy's ``Trace.stats.processing``).

Every method returns a new run; arrays are read-only.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace
from typing import Mapping

import numpy as np
import pandas as pd

from estimator.errors import ChannelError, ConfigurationError

__all__ = ["RunHeader", "Odometry", "QCEvent", "QCMask", "Run", "DIRECTIONS", "ORIENTATIONS", "SI_UNITS"]

log = logging.getLogger("estimator")

DIRECTIONS = ("forward", "backward")
ORIENTATIONS = ("normal", "turned")
#: SI unit of each quantity after the sensitivities are applied
SI_UNITS = {"acceleration": "m/s^2", "speed": "m/s", "position": "m", "balise": "m"}


def _frozen(a, dtype=float) -> np.ndarray:
    out = np.array(a, dtype=dtype, copy=True)
    out.setflags(write=False)
    return out


@dataclass(frozen=True)
class RunHeader:
    """The run header (field contract: ``run_id, date, direction, leading_end, train, bogie, line``).

    ``direction`` is relative to chainage: ``forward`` = the car travels towards
    increasing chainage. ``orientation`` is ``normal`` (the car's front end faces
    increasing chainage, the default) or ``turned``.
    """

    run_id: str
    date: str = ""
    direction: str = "forward"
    orientation: str = "normal"
    train: str = ""
    bogie: str = ""
    line: str = ""
    leading_end: str = ""
    extra: Mapping[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.direction not in DIRECTIONS:
            raise ConfigurationError(f"run {self.run_id!r}: header direction must be one of {DIRECTIONS} "
                                     f"(relative to chainage), got {self.direction!r}")
        if self.orientation not in ORIENTATIONS:
            raise ConfigurationError(f"run {self.run_id!r}: header orientation must be one of {ORIENTATIONS}, "
                                     f"got {self.orientation!r}")
        object.__setattr__(self, "extra", dict(self.extra))

    def with_direction(self, direction: str) -> "RunHeader":
        """The header with ``direction`` overridden (the CLI's ``--direction``)."""
        return replace(self, direction=direction)


@dataclass(frozen=True, eq=False)
class Odometry:
    """Speed, position and balise events as recorded (SI units, sensitivities applied).

    Attributes
    ----------
    t : ndarray (n,)
        Time stamps of speed and position [s].
    speed : ndarray (n,)
        Encoder speed [m/s] (sign as recorded: negative = reversing, if the encoder is signed).
    position : ndarray (n,)
        Odometer chainage [m], reset to a balise's reference chainage at each passage (jumps).
    balise_t, balise_chainage : ndarray (k,)
        One event per balise passage: its time [s] and the balise's reference chainage [m].
    names : dict
        Channel name of ``speed``, ``position`` and ``balise`` in the file.
    gaps : tuple of (float, float, str)
        Stretches ``(t_from, t_to, channel)`` the speed or position channel does not cover (its time stamps jump
        by more than :data:`estimator.io.assemble.ODOMETRY_GAP_FACTOR` intervals): the position there is
        interpolated, :func:`estimator.spatial.odometry_track` judges whether that can be trusted.
    """

    t: np.ndarray
    speed: np.ndarray
    position: np.ndarray
    balise_t: np.ndarray
    balise_chainage: np.ndarray
    names: Mapping[str, str] = field(default_factory=dict)
    gaps: tuple[tuple[float, float, str], ...] = ()

    def __post_init__(self) -> None:
        for name in ("t", "speed", "position", "balise_t", "balise_chainage"):
            object.__setattr__(self, name, _frozen(getattr(self, name)))
        if not (self.t.shape == self.speed.shape == self.position.shape) or self.t.ndim != 1:
            raise ChannelError(f"odometry: time ({self.t.shape}), speed ({self.speed.shape}) and position "
                               f"({self.position.shape}) must be 1-D arrays of one length (resample the speed and "
                               "position channels to one time base)")
        if self.balise_t.shape != self.balise_chainage.shape:
            raise ChannelError("odometry: balise times and chainages must have one entry per passage")
        object.__setattr__(self, "names", dict(self.names))
        object.__setattr__(self, "gaps", tuple((float(a), float(b), str(c)) for a, b, c in self.gaps))

    @property
    def chainage_relative(self) -> bool:
        """True when the chainage counts from the run's start: the position integrated from the speed with no
        balise passage to reset it (:mod:`estimator.io.assemble`), so it cannot be placed on a line."""
        return self.names.get("position", "").startswith("integrated from") and not self.balise_t.size


@dataclass(frozen=True)
class QCEvent:
    """One quality-control finding: where (channel, time, chainage), why, and what was done.

    ``channel`` is ``"*"`` when the finding concerns every channel (speed gate,
    reversing, odometry). ``action`` is ``"masked"`` (samples excluded),
    ``"rejected"`` (the channel is not used at all) or ``"corrected"`` (e.g. a
    balise jump within the odometer's tolerance, distributed over the stretch
    before it).
    """

    kind: str
    channel: str
    t_start: float
    t_end: float
    reason: str
    action: str = "masked"
    chainage_from: float = float("nan")
    chainage_to: float = float("nan")

    def describe(self) -> str:
        where = f" {self.t_start:.3f}-{self.t_end:.3f} s" if np.isfinite(self.t_start) else ""  # whole channel
        if np.isfinite(self.chainage_from):
            where += f", chainage {self.chainage_from:.1f}-{self.chainage_to:.1f} m"
        return f"{self.kind} [{self.channel}]{where}: {self.reason} ({self.action})"

    def as_dict(self) -> dict:
        return {"kind": self.kind, "channel": self.channel, "t_start_s": self.t_start, "t_end_s": self.t_end,
                "chainage_from_m": self.chainage_from, "chainage_to_m": self.chainage_to, "reason": self.reason,
                "action": self.action}


@dataclass(frozen=True, eq=False)
class QCMask:
    """Masked samples per acceleration channel (True = excluded) and the findings that masked them.

    ``saturated`` marks the masked samples whose only finding is the channel's clipping: their recorded value is
    the front end's full scale, a bound on the true acceleration rather than a missing one. They never enter the
    channel's own wheelset's inversion; the other wheelset's rail-coupling term may use them
    (:func:`estimator.workflow.estimate_run`): without them that wheelset loses every stretch around the clips, or
    is inverted without the coupling at all.
    """

    masked: np.ndarray
    events: tuple[QCEvent, ...] = ()
    saturated: np.ndarray | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "masked", _frozen(self.masked, bool))
        object.__setattr__(self, "events", tuple(self.events))
        sat = np.zeros_like(self.masked) if self.saturated is None else np.asarray(self.saturated, bool)
        if sat.shape != self.masked.shape:
            raise ValueError(f"saturated samples of shape {sat.shape} for a mask of shape {self.masked.shape}")
        object.__setattr__(self, "saturated", _frozen(sat & self.masked, bool))

    def coupling_valid(self, rows) -> np.ndarray:
        """Samples at which the channels ``rows`` are valid or only saturated (see the class docstring)."""
        return ~(self.masked[rows] & ~self.saturated[rows]).any(axis=0)

    def share(self, channels: tuple[str, ...]) -> dict[str, float]:
        """Masked share per channel and for the run (samples masked in any channel)."""
        out = {name: float(self.masked[i].mean()) if self.masked.shape[1] else 1.0 for i, name in enumerate(channels)}
        out["run"] = float(self.masked.any(axis=0).mean()) if self.masked.shape[1] else 1.0
        return out

    def table(self) -> pd.DataFrame:
        """The findings as a table (one row per event)."""
        cols = ["kind", "channel", "t_start_s", "t_end_s", "chainage_from_m", "chainage_to_m", "reason", "action"]
        return pd.DataFrame([e.as_dict() for e in self.events], columns=cols)


@dataclass(frozen=True, eq=False)
class Run:
    """One run of the instrumented bogie (see the module docstring).

    Attributes
    ----------
    source : str
        File the run was read from.
    format : str
        Reader that read it (``mdf4``, ``parquet``, ``csv``).
    header : RunHeader
    channels : pandas.DataFrame
        One sensor-table row per acceleration channel, in the order of ``acceleration``:
        ``name, quantity, unit, wheelset, side, direction, x, y, z, sensitivity``.
    fs : float
        Sampling rate of the accelerations [Hz].
    t0 : float
        Time of the first acceleration sample [s] (same clock as the odometry).
    acceleration : ndarray (n_channels, n)
        Accelerations; SI [m/s²] once ``sensitivity_applied``; NaN where the
        file had none (dropouts).
    units : tuple of str
        Current unit of each acceleration channel.
    odometry : Odometry
    sensitivity_applied : bool
    rejected : tuple of QCEvent
        Findings of the reading: channels of the sensor table that could not be used (missing, wrong rate;
        action ``rejected``) and samples the recording lost (``time_gap``, action ``masked``: NaN in
        ``acceleration``).
    mask : QCMask or None
        Set by :func:`estimator.qc.check_run`.
    processing : tuple of str
        History, one entry per successful step.
    """

    source: str
    format: str
    header: RunHeader
    channels: pd.DataFrame
    fs: float
    t0: float
    acceleration: np.ndarray
    units: tuple[str, ...]
    odometry: Odometry
    sensitivity_applied: bool = False
    rejected: tuple[QCEvent, ...] = ()
    mask: QCMask | None = None
    processing: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        acc = _frozen(self.acceleration)
        if acc.ndim != 2 or acc.shape[0] != len(self.channels):
            raise ChannelError(f"{self.source}: acceleration array {acc.shape} must have one row per channel "
                               f"({len(self.channels)})")
        if not (np.isfinite(self.fs) and self.fs > 0):
            raise ChannelError(f"{self.source}: sampling rate must be > 0 Hz, got {self.fs!r}")
        if len(self.units) != acc.shape[0]:
            raise ChannelError(f"{self.source}: one unit per acceleration channel expected")
        if self.mask is not None and self.mask.masked.shape != acc.shape:
            raise ChannelError(f"{self.source}: QC mask {self.mask.masked.shape} does not match the accelerations "
                               f"{acc.shape}")
        object.__setattr__(self, "acceleration", acc)
        object.__setattr__(self, "channels", self.channels.reset_index(drop=True).copy())
        object.__setattr__(self, "units", tuple(self.units))
        object.__setattr__(self, "rejected", tuple(self.rejected))
        object.__setattr__(self, "processing", tuple(self.processing))

    # ------------------------------------------------------------------ views
    @property
    def run_id(self) -> str:
        return self.header.run_id

    @property
    def n_samples(self) -> int:
        return int(self.acceleration.shape[1])

    @property
    def duration_s(self) -> float:
        return self.n_samples / self.fs

    @property
    def t(self) -> np.ndarray:
        """Time stamps of the acceleration samples [s]."""
        return self.t0 + np.arange(self.n_samples) / self.fs

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self.channels["name"].astype(str))

    def index(self, name: str) -> int:
        """Row of channel ``name`` in :attr:`acceleration` (ChannelError naming the known channels)."""
        try:
            return self.names.index(name)
        except ValueError:
            raise ChannelError(f"{self.source}: no acceleration channel {name!r}; the run has {list(self.names)}"
                               ) from None

    def wheelset_channels(self, wheelset: int) -> pd.DataFrame:
        """Sensor rows of one wheelset (1 or 2), with their row in :attr:`acceleration` as ``row``."""
        ch = self.channels.assign(row=np.arange(len(self.channels)))
        return ch[ch["wheelset"].astype(int) == int(wheelset)].reset_index(drop=True)

    @property
    def wheelsets(self) -> tuple[int, ...]:
        return tuple(sorted({int(w) for w in self.channels["wheelset"]}))

    @property
    def masked_share(self) -> dict[str, float]:
        """Masked share per channel and for the run (0 before QC)."""
        if self.mask is None:
            return {**{n: 0.0 for n in self.names}, "run": 0.0}
        return self.mask.share(self.names)

    # ------------------------------------------------------------- new runs
    def with_step(self, step: str, **changes) -> "Run":
        """A new run with ``changes`` applied and ``step`` appended to the history."""
        return replace(self, processing=self.processing + (step,), **changes)

    def apply_sensitivities(self) -> "Run":
        """Accelerations in SI: each channel times its ``sensitivity`` (once; a second call raises).

        The odometry is converted by the reader (its channels' sensitivities are
        applied while reading, see :func:`estimator.io.read_run`).
        """
        if self.sensitivity_applied:
            raise ChannelError(f"{self.source}: sensitivities were already applied ({self.processing[-1:]}); "
                               "applying them twice would scale the data twice")
        s = self.channels["sensitivity"].to_numpy(float)
        acc = self.acceleration * s[:, None]
        desc = ", ".join(f"{n} x{v:g}" for n, v in zip(self.names, s))
        return self.with_step(f"sensitivities applied (recorded unit -> m/s^2): {desc}", acceleration=acc,
                              units=tuple(SI_UNITS["acceleration"] for _ in s), sensitivity_applied=True)

    def with_direction(self, direction: str) -> "Run":
        """The run with its header direction overridden (recorded in the history)."""
        if direction == self.header.direction:
            return self
        return self.with_step(f"direction overridden: {self.header.direction} -> {direction}",
                              header=self.header.with_direction(direction))

    def with_mask(self, mask: QCMask, step: str) -> "Run":
        return self.with_step(step, mask=mask)

    def __repr__(self) -> str:
        return (f"Run({self.run_id!r}, {self.header.direction}, {len(self.channels)} acceleration channels at "
                f"{self.fs:g} Hz, {self.duration_s:.1f} s, from {self.source})")
