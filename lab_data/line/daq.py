"""Accelerometers and data acquisition: from true accelerations to recorded channels.

The chain, in the order the hardware applies it (thesis §2.1: six
accelerometers, 1 kHz):

1. **Mounting** — each accelerometer sits at its true point (a few mm to
   2 cm from the nominal axlebox centre; the dynamics returns the
   acceleration there) and may be mounted the wrong way round (scenario
   ``lateral_sign``: the true measuring axis is −y while the table says +y).
2. **Sensitivity** — the true sensitivity differs from the calibration sheet
   by ε ∈ [−2 %, +2 %] per sensor: recorded = (1 + ε) × true.
3. **Anti-aliasing and decimation** — the DAQ's delta-sigma converter
   filters the oversampled signal with a linear-phase FIR (passband flat to
   ``0.4 fs``, stopband from ``0.5 fs``, Kaiser window, its group delay
   compensated in the time stamps, as commercial DAQs do) and decimates to
   ``fs`` (default 1 kHz): :func:`anti_alias_decimate`, built on
   :func:`scipy.signal.resample_poly`.
4. **Noise** — sensor and front-end noise, white over the band, 0.03 m/s² RMS
   (a 10 mV/g ICP accelerometer with a 24-bit front end).
5. **Range, quantisation, clipping** — ±``range_g`` per channel (50 g
   vertical, 20 g lateral), 24-bit ADC (LSB ``2 range / 2^24``); values
   beyond the range stick at full scale (clipping). Channels are written in
   g (the unit in the sensor table, sensitivity 9.80665).
6. **Faults** — a dropout (a NaN segment, or a flat segment where the
   front end holds its last value) and, in other runs, a clipped channel
   whose range an operator set too tight (the run's 99.9 % quantile of
   ``|a|`` to two significant digits: about 0.1 % of the samples clip).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from fractions import Fraction

import numpy as np
from scipy import signal

__all__ = ["G", "DaqParameters", "ChannelSpec", "Fault", "anti_alias_decimate", "quantise", "record_channels",
           "tight_range", "intervals"]

G = 9.80665


@dataclass(frozen=True)
class DaqParameters:
    fs: float = 1000.0
    bits: int = 24
    range_vertical_g: float = 50.0
    range_lateral_g: float = 20.0
    noise_rms: float = 0.03  # m/s^2
    passband: float = 0.4  # fraction of fs
    stopband: float = 0.5

    def parameters(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class ChannelSpec:
    """One accelerometer channel: name, true sensitivity error, sign and range."""

    name: str
    direction: str  # 'y' or 'z' (vehicle frame)
    sensitivity_error: float  # recorded / true - 1
    sign: float = 1.0  # -1 when mounted the wrong way round
    range_g: float = 50.0


@dataclass(frozen=True)
class Fault:
    """A fault in one channel of one run: ``kind`` 'nan' / 'flat' (dropout) or 'clip' (range set too tight)."""

    kind: str
    channel: str
    t_start_s: float = 0.0
    duration_s: float = 0.0
    range_g: float | None = None


def _resampling(fs_in: float, fs_out: float) -> tuple[int, int]:
    frac = Fraction(fs_out / fs_in).limit_denominator(100000)
    if abs(float(frac) - fs_out / fs_in) > 1e-9 * fs_out / fs_in:
        raise ValueError(f"cannot resample {fs_in} Hz to {fs_out} Hz by a rational factor")
    return frac.numerator, frac.denominator


def anti_alias_decimate(x: np.ndarray, fs_in: float, fs_out: float, p: DaqParameters = DaqParameters()) -> np.ndarray:
    """Linear-phase FIR anti-aliasing filter + rational resampling along the last axis (delay compensated).

    The FIR is designed at the up-sampled rate with passband edge ``p.passband · fs_out`` and stopband edge
    ``p.stopband · fs_out`` (Kaiser window for 100 dB attenuation); ``resample_poly`` applies it polyphase and
    removes its group delay.
    """
    up, down = _resampling(fs_in, fs_out)
    f_hi = fs_in * up
    width = (p.stopband - p.passband) * fs_out
    numtaps, beta = signal.kaiserord(100.0, width / (0.5 * f_hi))
    numtaps |= 1
    cutoff = 0.5 * (p.passband + p.stopband) * fs_out
    h = signal.firwin(numtaps, cutoff, window=("kaiser", beta), fs=f_hi)
    # resample_poly scales an array window by ``up`` itself (the zero-stuffing gain): no ``* up`` here
    return signal.resample_poly(x, up, down, axis=-1, window=h)


def intervals(mask: np.ndarray, max_gap: int = 0) -> list[tuple[int, int]]:
    """Index pairs (first, last) of the contiguous runs of True in a 1-D mask.

    Runs separated by at most ``max_gap`` False samples are merged into one (an event that flickers).
    """
    if not mask.any():
        return []
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    runs = [[int(a), int(b)] for a, b in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1)]
    merged = [runs[0]]
    for a, b in runs[1:]:
        if a - merged[-1][1] - 1 <= max_gap:
            merged[-1][1] = b
        else:
            merged.append([a, b])
    return [(a, b) for a, b in merged]


def quantise(x: np.ndarray, full_scale: float, bits: int) -> tuple[np.ndarray, np.ndarray]:
    """Round to the ADC grid of ``±full_scale`` with ``bits`` bits and clip at full scale; (values, clipped mask)."""
    lsb = 2 * full_scale / 2**bits
    top = (2 ** (bits - 1) - 1) * lsb
    bottom = -(2 ** (bits - 1)) * lsb
    q = np.round(x / lsb) * lsb
    clipped = (q >= top) | (q <= bottom)
    return np.clip(q, bottom, top), clipped


def tight_range(y: np.ndarray, quantile: float = 0.999) -> float:
    """An operator's too-tight range: the ``quantile`` of ``|y|`` rounded down to two significant digits."""
    q = float(np.quantile(np.abs(y[np.isfinite(y)]), quantile))
    decade = 10.0 ** (np.floor(np.log10(q)) - 1)
    return float(np.floor(q / decade) * decade)


def record_channels(acc_true: np.ndarray, fs_in: float, channels: tuple[ChannelSpec, ...], faults: tuple[Fault, ...],
                    rng: np.random.Generator, p: DaqParameters = DaqParameters()
                    ) -> tuple[np.ndarray, np.ndarray, dict]:
    """Turn true accelerations (n_ch, n) [m/s²] sampled at ``fs_in`` into recorded channels in g at ``p.fs``.

    Fault times are in s from the first output sample.

    Returns
    -------
    recorded : ndarray (n_ch, m) float32 in g (NaN inside 'nan' dropouts)
    clipped : ndarray (n_ch, m) bool
        Samples stuck at full scale.
    truth : dict
        Per channel the range and LSB used and the dropouts (kind, first and last sample time, samples).
    """
    if acc_true.shape[0] != len(channels):
        raise ValueError(f"{acc_true.shape[0]} acceleration rows for {len(channels)} channels")
    gain = np.array([c.sign * (1 + c.sensitivity_error) for c in channels])[:, None]
    y = anti_alias_decimate(acc_true * gain, fs_in, p.fs, p)
    y = y + p.noise_rms * rng.standard_normal(y.shape)
    y_g = y / G
    n = y_g.shape[1]
    t = np.arange(n) / p.fs
    out = np.empty(y_g.shape, np.float32)
    clip_mask = np.zeros(y_g.shape, bool)
    info = {}
    by_channel = {c.name: [f for f in faults if f.channel == c.name] for c in channels}
    for i, c in enumerate(channels):
        rng_g = c.range_g
        for f in by_channel[c.name]:
            if f.kind == "clip":
                # an operator's range: given, or just below this run's 99.9 % quantile
                rng_g = float(f.range_g) if f.range_g is not None else tight_range(y_g[i])
        q, clipped = quantise(y_g[i], rng_g, p.bits)
        clip_mask[i] = clipped
        record = {"range_g": rng_g, "lsb_g": 2 * rng_g / 2**p.bits, "dropouts": []}
        for f in by_channel[c.name]:
            if f.kind in ("nan", "flat"):
                sel = (t >= f.t_start_s) & (t < f.t_start_s + f.duration_s)
                idx = np.flatnonzero(sel)
                if idx.size:
                    q[idx] = np.nan if f.kind == "nan" else q[max(idx[0] - 1, 0)]
                    record["dropouts"].append({"kind": f.kind, "t_start_s": float(t[idx[0]]),
                                               "t_end_s": float(t[idx[-1]]), "samples": int(idx.size)})
            elif f.kind != "clip":
                raise ValueError(f"unknown fault kind {f.kind!r} (nan, flat, clip)")
        out[i] = q
        info[c.name] = record
    return out, clip_mask, info
