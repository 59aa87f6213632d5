"""Model against the measured FRFs of the hammer setups: the summary error ``E``, its noise floor, BIC cells.

For each channel ``c`` and octave band ``b`` the band-normalised complex
error ``e_cb = ‖H_m − H_x‖_b / ‖H_x‖_b``; the summary error is
``E = sqrt(mean_cb e_cb²)`` (a misfit at 15 Hz, where the accelerance is
small, counts as much as one at a 300 Hz resonance; the same figure as
:attr:`receptance.diagnosis.compare.Comparison.summary`).  The noise floor is
the ``E`` a perfect model would score: from the H1 random error (coherence
and number of averages, Bendat & Piersol ``σ²/|H|² = (1 − γ²)/((n − 1) γ²)``)
or, for FRF files without coherence, from the measurement's own noise
estimate (:mod:`receptance.diagnosis.noise`).

The band.  The octave cells are those of the comparison
(:func:`receptance.diagnosis.compare.octave_bands` over ``band_hz``, default
10–500 Hz: 10–20–40–80–160–320–500), so that ``E`` here and
:attr:`~receptance.diagnosis.compare.Comparison.summary` on the same band
are one figure (they differ only in whether the line at the top edge counts).
A wheelset hung from soft slings has its rig modes at a few hertz: a band
from 4 Hz (where the record's resolution allows) lets the diagnosis see
them.  :func:`check_band` refuses a band the measured lines do not cover or
resolve (every octave cell needs :data:`MIN_CELL_LINES` lines).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
import pandas as pd

from ema._blas import one_blas_thread
from ema.frf import FrequencyResponse
from receptance.diagnosis.compare import ComparisonError, band_errors, h1_variance, octave_bands
from receptance.diagnosis.errors import DiagnosisError
from receptance.dofs import dofs_from_channels
from receptance.modal_model import ModalModel

__all__ = ["Measurement", "Misfit", "misfit", "model_frfs", "OCTAVES", "DEFAULT_BAND_HZ", "MIN_CELL_LINES",
           "octave_edges", "check_band", "check_band_lines", "sixth_octaves"]

#: the diagnosis band unless the user gives one [Hz]
DEFAULT_BAND_HZ = (10.0, 500.0)
#: fewest frequency lines an octave cell of the misfit may hold (a band norm over fewer is one line's noise)
MIN_CELL_LINES = 4


def octave_edges(band_hz: tuple[float, float]) -> tuple[float, ...]:
    """Edges of the octave cells over ``band_hz``: the comparison's bands (:func:`compare.octave_bands`).

    ``(10, 500)`` gives 10, 20, 40, 80, 160, 320, 500 Hz; ``(4, 500)`` gives
    4, 8, 16, 32, 64, 128, 256, 500 Hz.

    Raises
    ------
    DiagnosisError
        Not ``0 < low < high`` (finite).
    """
    try:
        bands = octave_bands(tuple(band_hz))
    except (ComparisonError, TypeError, ValueError) as exc:
        raise DiagnosisError(f"diagnosis band: {exc}") from None
    return tuple([bands[0][0]] + [b for _, b in bands])


#: the default cells, 10-20-40-80-160-320-500 Hz
OCTAVES = octave_edges(DEFAULT_BAND_HZ)


def check_band_lines(band_hz: tuple[float, float], freqs_hz: np.ndarray, where: str = "measurement"
                     ) -> tuple[float, ...]:
    """The octave edges of ``band_hz`` once the band is known to suit the frequency lines ``freqs_hz``.

    The band must lie within the measured lines (one line spacing of slack
    at either end: a grid that stops a line short of the edge) and every
    octave cell must hold at least :data:`MIN_CELL_LINES` lines (the FRF's
    resolution ``Δf`` sets the lowest usable lower edge, about
    ``MIN_CELL_LINES × Δf``).

    Raises
    ------
    DiagnosisError
        Naming ``where``, the band, the measured lines and what would fit.
    """
    edges = octave_edges(band_hz)
    f = np.asarray(freqs_hz, float)
    if f.ndim != 1 or f.size < 2:
        raise DiagnosisError(f"{where}: {f.size} frequency line(s); a diagnosis needs a spectrum")
    df = float(np.median(np.diff(f)))
    lo, hi = edges[0], edges[-1]
    if lo < f[0] - df or hi > f[-1] + df:
        raise DiagnosisError(f"{where}: the diagnosis band {lo:g}–{hi:g} Hz reaches outside the measured lines "
                             f"{f[0]:g}–{f[-1]:g} Hz (Δf {df:g} Hz); choose a band inside them or estimate the FRFs "
                             f"over the band")
    for a, b in zip(edges[:-1], edges[1:]):
        n = int(np.count_nonzero((f >= a) & ((f <= b) if b >= hi else (f < b))))
        if n < MIN_CELL_LINES:
            raise DiagnosisError(f"{where}: the octave cell {a:g}–{b:g} Hz of the band {lo:g}–{hi:g} Hz holds {n} "
                                 f"line(s) at the FRF's resolution Δf {df:g} Hz, fewer than {MIN_CELL_LINES}; raise "
                                 f"the band's lower edge to at least {MIN_CELL_LINES * df:g} Hz or measure longer "
                                 f"records")
    return edges


def check_band(band_hz: tuple[float, float], measurements: Sequence["Measurement"]) -> tuple[float, ...]:
    """:func:`check_band_lines` for every setup; returns the octave edges of the misfit's cells."""
    edges = octave_edges(band_hz)
    for m in measurements:
        check_band_lines(band_hz, m.frf.freqs_hz, f"setup {m.setup!r}")
    return edges


@dataclass(frozen=True, eq=False)
class Measurement:
    """One setup's measured accelerance and its channel table (with the force row).

    Parameters
    ----------
    frf : FrequencyResponse
        Single-reference accelerance (``ema.estimate_frf`` or an FRF file).
    channels : DataFrame
        The setup's channel table.
    setup : str
        Name (default: the table's ``setup`` column).
    noise_variance : ndarray (n_out, n_freq), optional
        Expected squared complex random error of each line, when the FRF
        carries no coherence and averaging count to compute it from
        (:func:`receptance.diagnosis.noise.frf_noise_variance`).
    noise_method : str
        How the noise floor is obtained, in words (for the report).
    """

    frf: FrequencyResponse
    channels: pd.DataFrame
    setup: str = ""
    noise_variance: np.ndarray | None = field(default=None, repr=False)
    noise_method: str = ""
    # band weights per tuple of cell edges: every evaluation of a fit needs them, computed once per measurement
    _weights: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.frf.n_in != 1:
            raise DiagnosisError(f"setup {self.setup!r}: expected a single-reference FRF, got {self.frf.n_in} inputs")
        acc = self.channels[self.channels["quantity"] == "acceleration"]
        order = acc.set_index(acc["name"].astype(str))
        missing = [o for o in self.frf.outputs if o not in order.index]
        if missing:
            raise DiagnosisError(f"setup {self.setup!r}: FRF outputs {missing} are not in the channel table")
        table = pd.concat([order.loc[list(self.frf.outputs)].reset_index(drop=True),
                           self.channels[self.channels["quantity"] == "force"]], ignore_index=True)
        if not self.setup:
            s = table["setup"].dropna() if "setup" in table else pd.Series([], dtype=object)
            object.__setattr__(self, "setup", str(s.iloc[0]) if len(s) else "setup")
        if "setup" not in table or table["setup"].isna().all():
            table = table.assign(setup=self.setup)
        object.__setattr__(self, "channels", table)
        if self.noise_variance is not None:
            var = np.asarray(self.noise_variance, float)
            if var.shape != (self.frf.n_out, self.frf.freqs_hz.size) or np.any(~np.isfinite(var)) or np.any(var < 0):
                raise DiagnosisError(f"setup {self.setup!r}: noise_variance must be finite, >= 0 and shaped "
                                     f"({self.frf.n_out}, {self.frf.freqs_hz.size}), got {var.shape}")
            object.__setattr__(self, "noise_variance", var)
        if not self.noise_method:
            method = ("H1 random error from the coherence and the number of averaged hits (Bendat & Piersol)"
                      if h1_variance(self.frf) is not None else
                      "estimated from the FRF itself" if self.noise_variance is not None else "unknown")
            object.__setattr__(self, "noise_method", method)

    @functools.cached_property
    def dofs(self) -> tuple[list, list]:
        """The acceleration and force DOFs of the table, parsed once (every model evaluation needs them)."""
        acc = self.channels[self.channels["quantity"] == "acceleration"].reset_index(drop=True)
        force = self.channels[self.channels["quantity"] == "force"]
        return dofs_from_channels(acc), dofs_from_channels(force)

    def band_weights(self, bands=None) -> tuple[np.ndarray, np.ndarray]:
        """Per line ``1/‖H_x‖_b`` of its channel-band (0 outside the bands) and the band index of each line.

        ``bands``: the cells' edges (default :data:`OCTAVES`, :func:`octave_edges`).
        """
        key = OCTAVES if bands is None else tuple(float(b) for b in bands)
        if key not in self._weights:
            self._weights[key] = self._band_weights(key)
        return self._weights[key]

    def _band_weights(self, bands) -> tuple[np.ndarray, np.ndarray]:
        f = self.frf.freqs_hz
        Hx = self.frf.data[:, 0]
        idx = np.searchsorted(np.asarray(bands), f, side="right") - 1
        idx[(f < bands[0]) | (f >= bands[-1])] = -1
        w = np.zeros(Hx.shape)
        for b in range(len(bands) - 1):
            sel = idx == b
            if sel.sum() < 2:
                idx[sel] = -1
                continue
            w[:, sel] = 1.0 / np.linalg.norm(Hx[:, sel], axis=1, keepdims=True)
        return w, idx

    @functools.cached_property
    def variance(self) -> np.ndarray | None:
        """Expected squared random error of each line (n_out, n_f), or None when unknown."""
        var = h1_variance(self.frf)
        return var if var is not None else self.noise_variance

    @functools.cached_property
    def sigma(self) -> np.ndarray:
        """Random error of each line (n_out, n_f): the square root of :attr:`variance`."""
        if self.variance is None:
            raise DiagnosisError(
                f"setup {self.setup!r}: the measured FRF carries no coherence or averaging count and no noise "
                f"estimate, so its noise floor is unknown; estimate the FRFs with ema.estimate_frf, or give "
                f"noise_variance (receptance.diagnosis.noise.frf_noise_variance)")
        return np.sqrt(self.variance)


@dataclass(frozen=True)
class Misfit:
    """Model against measurements: summary error ``E``, its noise floor, and where the error sits."""

    summary: float
    noise_floor: float
    n_bands: int
    per_channel: pd.DataFrame = field(repr=False)
    per_band: pd.DataFrame = field(repr=False)
    fine: float = np.nan
    n_fine: int = 0

    def bic(self, k: int = 0) -> float:
        """``N ln E² + k ln N`` over the channel × sixth-octave cells (the resolution of the evidence)."""
        return float(self.n_fine * np.log(max(self.fine**2, 1e-300)) + k * np.log(max(self.n_fine, 2)))


def model_frfs(model: ModalModel, measurements: Sequence[Measurement], stride: int = 1) -> list[np.ndarray]:
    """The model's accelerance at each setup's channels (n_out, n_lines[::stride]), through its window."""
    return [model.channel_accelerance(*m.dofs, m.frf.freqs_hz[::stride], decay=m.frf.exp_window_decay, setup=m.setup)
            for m in measurements]


@one_blas_thread
def misfit(model: ModalModel, measurements: Sequence[Measurement], *,
           band_hz: tuple[float, float] = DEFAULT_BAND_HZ) -> Misfit:
    """Summary error ``E`` of ``model`` against ``measurements`` and its noise floor (module docstring).

    Parameters
    ----------
    model : ModalModel
    measurements : sequence of Measurement
    band_hz : (float, float)
        The band whose octave cells (:func:`octave_edges`) the error, the
        noise floor and the sixth-octave BIC cells cover (:func:`check_band`).
    """
    bands = check_band(band_hz, measurements)
    rows, brows = [], []
    frfs = model_frfs(model, measurements)
    for m, Hm in zip(measurements, frfs):
        Hx = m.frf.data[:, 0]
        sig = m.sigma
        w, idx = m.band_weights(bands)
        for i, name in enumerate(m.frf.outputs):
            rows.append({"setup": m.setup, "channel": name,
                         "rel_error": float(np.linalg.norm(Hm[i] - Hx[i]) / np.linalg.norm(Hx[i]))})
            for b in np.unique(idx[idx >= 0]):
                sel = idx == b
                e = np.linalg.norm(Hm[i, sel] - Hx[i, sel]) * w[i, sel][0]
                noise = np.linalg.norm(sig[i, sel]) * w[i, sel][0]
                brows.append({"setup": m.setup, "channel": name, "band_lo_hz": bands[b], "band_hi_hz": bands[b + 1],
                              "rel_error": float(e), "noise": float(noise)})
    per_band = pd.DataFrame(brows)
    summary = float(np.sqrt(np.mean(per_band["rel_error"] ** 2)))
    floor = float(np.sqrt(np.mean(per_band["noise"] ** 2)))
    fine = []
    for m, Hm in zip(measurements, frfs):
        edges = sixth_octaves(m.frf.freqs_hz, bands)
        fine.append(band_errors(m.frf.freqs_hz, m.frf.data[:, 0], Hm, edges).ravel())
    fine = np.concatenate(fine)
    return Misfit(summary, floor, len(per_band), pd.DataFrame(rows), per_band, float(np.sqrt(np.mean(fine**2))),
                  fine.size)


def sixth_octaves(f: np.ndarray, bands) -> list[tuple[float, float]]:
    """Sixth-octave cells over ``bands``' range, each holding at least two lines of ``f``.

    Near the lower edge of a low band a sixth octave can be narrower than two
    lines; such a cell is joined to the next one (the last to the one
    before), so every line of the band counts once.
    """
    lo, hi = max(bands[0], f[0]), min(bands[-1], f[-1])
    n = max(int(np.ceil(6 * np.log2(hi / lo))), 1)
    e = lo * (hi / lo) ** (np.arange(n + 1) / n)
    out: list[tuple[float, float]] = []
    start = e[0]
    for a, b in zip(e[:-1], e[1:]):
        if np.count_nonzero((f >= start) & (f < b)) >= 2:
            out.append((start, b))
            start = b
    if start < e[-1] and out:
        out[-1] = (out[-1][0], e[-1])
    elif not out:
        out.append((e[0], e[-1]))
    return out
