"""The toolkit's one frequency-response type.

:class:`FrequencyResponse` holds a labelled MIMO frequency response: a
frequency axis in Hz and complex data shaped ``(n_out, n_in, n_freq)``, the
output and input DOF labels, the quantity (receptance, mobility or
accelerance) and its units, optional coherence and channel metadata, and the
processing history. It is modelled on python-control's
``FrequencyResponseData``: shapes are checked on construction with messages
that say which axis disagrees, and operations return new objects.

Every module of the toolkit (``ema``, ``receptance``, ``estimator``) uses this
type; the axis order never changes.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Sequence

import numpy as np
import pandas as pd

__all__ = ["FrequencyResponse", "QUANTITIES", "FRFShapeError"]

#: quantity -> (power of i*omega relative to receptance, SI units)
QUANTITIES: dict[str, tuple[int, str]] = {
    "receptance": (0, "m/N"),
    "mobility": (1, "m/s/N"),
    "accelerance": (2, "m/s^2/N"),
    # a ratio of other quantities (e.g. irregularity per axlebox acceleration, thesis eq. 2.6):
    # no power of i*omega relates it to the others, so it has no conversions; give units explicitly
    "transfer": (None, ""),
}


class FRFShapeError(ValueError):
    """A frequency response whose arrays or labels disagree in size."""


@dataclass(frozen=True, eq=False)
class FrequencyResponse:
    """A labelled MIMO frequency response.

    Parameters
    ----------
    freqs_hz : ndarray (n_freq,)
        Strictly increasing, non-negative frequencies [Hz].
    data : ndarray complex (n_out, n_in, n_freq)
        The response; a 1-D or 2-D array is promoted (one output / one input).
    outputs, inputs : sequence of str
        DOF labels, e.g. ``"101:+z"`` or ``"contact_L:z"``.
    quantity : str
        ``"receptance"``, ``"mobility"`` or ``"accelerance"``.
    units : str, optional
        Defaults to the SI units of ``quantity``.
    coherence : ndarray (n_out, n_in, n_freq), optional
        Ordinary coherence of an estimate.
    channels : pandas.DataFrame, optional
        One row per output (channel metadata: node, direction, ...).
    exp_window_decay : float
        Decay rate ``a`` [1/s] of an exponential window applied to the
        measured signals: every pole of this response is shifted by ``-a``,
        so identified damping must be corrected (``sigma_true = sigma - a``).
    history : tuple of str
        Processing steps applied, oldest first.
    n_averages : ndarray of int (n_out,), optional
        Number of measurements (hits) averaged into each output's estimate.
    """

    freqs_hz: np.ndarray
    data: np.ndarray
    outputs: tuple[str, ...]
    inputs: tuple[str, ...]
    quantity: str = "accelerance"
    units: str = ""
    coherence: np.ndarray | None = None
    channels: pd.DataFrame | None = None
    exp_window_decay: float = 0.0
    history: tuple[str, ...] = field(default_factory=tuple)
    n_averages: np.ndarray | None = None

    def __post_init__(self) -> None:
        f = np.asarray(self.freqs_hz, dtype=float)
        if f.ndim != 1 or f.size == 0:
            raise FRFShapeError(f"freqs_hz must be a non-empty 1-D array, got shape {np.shape(self.freqs_hz)}")
        if not np.all(np.isfinite(f)) or np.any(f < 0) or np.any(np.diff(f) <= 0):
            raise FRFShapeError("freqs_hz must be finite, non-negative and strictly increasing")
        d = np.asarray(self.data, dtype=complex)
        if d.ndim == 1:
            d = d[None, None, :]
        elif d.ndim == 2:
            d = d[:, None, :]
        if d.ndim != 3:
            raise FRFShapeError(f"data must be (n_out, n_in, n_freq), got shape {np.shape(self.data)}")
        if d.shape[2] != f.size:
            raise FRFShapeError(f"data has {d.shape[2]} frequency lines but freqs_hz has {f.size}")
        outputs = tuple(str(o) for o in self.outputs)
        inputs = tuple(str(i) for i in self.inputs)
        if len(outputs) != d.shape[0]:
            raise FRFShapeError(f"data has {d.shape[0]} outputs but {len(outputs)} output labels were given")
        if len(inputs) != d.shape[1]:
            raise FRFShapeError(f"data has {d.shape[1]} inputs but {len(inputs)} input labels were given")
        if len(set(outputs)) != len(outputs) or len(set(inputs)) != len(inputs):
            raise FRFShapeError("output and input labels must be unique")
        if self.quantity not in QUANTITIES:
            raise ValueError(f"quantity must be one of {sorted(QUANTITIES)}, got {self.quantity!r}")
        coh = None
        if self.coherence is not None:
            coh = np.asarray(self.coherence, dtype=float).reshape(d.shape) if np.size(self.coherence) == d.size else None
            if coh is None:
                raise FRFShapeError(f"coherence must have the shape of data {d.shape}, got {np.shape(self.coherence)}")
        if self.channels is not None and len(self.channels) != len(outputs):
            raise FRFShapeError(f"channels has {len(self.channels)} rows but there are {len(outputs)} outputs")
        if not np.isfinite(self.exp_window_decay) or self.exp_window_decay < 0:
            raise ValueError(f"exp_window_decay must be finite and >= 0, got {self.exp_window_decay!r}")
        n_avg = None
        if self.n_averages is not None:
            n_avg = np.asarray(self.n_averages).astype(int, copy=True)
            if n_avg.shape != (d.shape[0],):
                raise FRFShapeError(f"n_averages must have shape ({d.shape[0]},) (one per output), "
                                    f"got {np.shape(self.n_averages)}")
            n_avg.setflags(write=False)
        object.__setattr__(self, "n_averages", n_avg)
        f.setflags(write=False)
        d.setflags(write=False)
        object.__setattr__(self, "freqs_hz", f)
        object.__setattr__(self, "data", d)
        object.__setattr__(self, "outputs", outputs)
        object.__setattr__(self, "inputs", inputs)
        object.__setattr__(self, "coherence", coh)
        object.__setattr__(self, "units", self.units or QUANTITIES[self.quantity][1])
        object.__setattr__(self, "history", tuple(self.history))

    # ------------------------------------------------------------------ views
    @property
    def n_out(self) -> int:
        return self.data.shape[0]

    @property
    def n_in(self) -> int:
        return self.data.shape[1]

    @property
    def omega(self) -> np.ndarray:
        """Angular frequency [rad/s]."""
        return 2 * np.pi * self.freqs_hz

    def with_history(self, step: str, **changes) -> "FrequencyResponse":
        """A copy with ``changes`` applied and ``step`` appended to the history."""
        return replace(self, history=self.history + (step,), **changes)

    def as_quantity(self, quantity: str) -> "FrequencyResponse":
        """The same response as receptance, mobility or accelerance (multiplying by powers of i*omega).

        Converting *from* receptance/mobility *to* a lower power divides by
        ``i*omega``; at 0 Hz that is undefined and raises ``ValueError``.
        """
        if quantity not in QUANTITIES:
            raise ValueError(f"quantity must be one of {sorted(QUANTITIES)}, got {quantity!r}")
        if QUANTITIES[quantity][0] is None or QUANTITIES[self.quantity][0] is None:
            if quantity == self.quantity:
                return self
            raise ValueError(f"cannot convert {self.quantity} to {quantity}: a 'transfer' response is a ratio of "
                             f"other quantities and has no conversion")
        p = QUANTITIES[quantity][0] - QUANTITIES[self.quantity][0]
        if p == 0:
            return self
        jw = 1j * self.omega
        if p < 0 and np.any(jw == 0):
            raise ValueError(f"cannot convert {self.quantity} to {quantity} at 0 Hz; select a band above 0 Hz first")
        return self.with_history(f"as {quantity}", data=self.data * jw**p, quantity=quantity, units="")

    def select(self, *, outputs: Sequence[str] | None = None, inputs: Sequence[str] | None = None,
               band_hz: tuple[float, float] | None = None) -> "FrequencyResponse":
        """Sub-response by output/input labels and/or a frequency band (inclusive)."""
        oi = self._indices(self.outputs, outputs, "output")
        ii = self._indices(self.inputs, inputs, "input")
        fi = np.arange(len(self.freqs_hz))
        if band_hz is not None:
            lo, hi = band_hz
            fi = np.flatnonzero((self.freqs_hz >= lo) & (self.freqs_hz <= hi))
            if fi.size == 0:
                raise ValueError(f"band {band_hz} Hz holds no frequency line (axis {self.freqs_hz[0]}–{self.freqs_hz[-1]} Hz)")
        coh = None if self.coherence is None else self.coherence[np.ix_(oi, ii, fi)]
        ch = None if self.channels is None else self.channels.iloc[oi].reset_index(drop=True)
        n_avg = None if self.n_averages is None else self.n_averages[oi]
        return replace(
            self,
            freqs_hz=self.freqs_hz[fi],
            data=self.data[np.ix_(oi, ii, fi)],
            outputs=tuple(self.outputs[i] for i in oi),
            inputs=tuple(self.inputs[i] for i in ii),
            coherence=coh,
            channels=ch,
            n_averages=n_avg,
        )

    @staticmethod
    def _indices(labels: tuple[str, ...], wanted: Sequence[str] | None, what: str) -> np.ndarray:
        if wanted is None:
            return np.arange(len(labels))
        pos = {lab: i for i, lab in enumerate(labels)}
        missing = [w for w in wanted if w not in pos]
        if missing:
            raise KeyError(f"unknown {what} label(s) {missing}; available: {list(labels)}")
        return np.array([pos[w] for w in wanted], dtype=int)

    def __repr__(self) -> str:
        return (
            f"FrequencyResponse({self.quantity} [{self.units}], {self.n_out} outputs x {self.n_in} inputs, "
            f"{len(self.freqs_hz)} lines {self.freqs_hz[0]:g}–{self.freqs_hz[-1]:g} Hz)"
        )
