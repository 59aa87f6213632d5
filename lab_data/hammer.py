"""Impact-hammer test synthesis from a known modal truth.

This module turns a modal "truth" (natural frequencies, damping ratios and
mass-normalised mode shapes at the force point and at the sensors) plus a
description of one hammer hit (a sum of half-sine force pulses) into the time
histories a real data-acquisition front-end would record: the force channel
and one acceleration channel per sensor.  It also provides the truth's
analytic accelerance, which is the oracle the lab's frequency-response
estimates are compared against.

Model
-----
Every mode obeys ``q_r'' + 2 zeta_r w_r q_r' + w_r**2 q_r = b_r f(t)`` and
sensor ``j`` measures ``a_j = sum_r c_jr q_r''``.  For an elastic mode the
force-to-acceleration transfer function splits into a direct term and one
complex pole pair,

    b s**2 / (s**2 + 2 zeta w s + w**2) = b + P / (s - lam) + conj(P) / (s - conj(lam)),

with ``lam = -zeta w + i w sqrt(1 - zeta**2)`` and ``P = b lam**2 / (lam - conj(lam))``.
Hence ``a_j(t) = D_j f(t) + Re(sum_r W_jr z_r(t))`` with ``z_r' = lam_r z_r + f``,
``D_j = sum_r c_jr b_r`` (rigid-body modes contribute only to ``D``) and
``W_jr = 2 c_jr P_r``.  One complex first-order state per mode replaces the
real 2-state system; the two are algebraically identical.

Integration: first-order hold on an oversampled grid
----------------------------------------------------
A real front-end digitises *continuous* signals after an analogue
anti-aliasing filter.  We stand in for the analogue world with a fine grid at
``oversample * fs`` (step ``h``) on which the force is the analytic
half-sine sampled there.  The first-order-hold (FOH) discretisation
``z[n+1] = e^{lam h} z[n] + g0 u[n] + g1 u[n+1]`` integrates the modal
equation *exactly* for a piecewise-linear input, i.e. for the linear
interpolant of the samples ``u[n]``: no time-stepping error at all, however
light the damping and however long the record.  A zero-order hold would add
a half-step delay (a phase error growing with frequency) and a sampled
impulse response would alias the response.

Why oversample?  (1) The hammer pulse is only 0.3-1 ms long, a handful of
samples at ``fs``; the fine grid resolves its shape.  (2) The response has
energy above ``fs / 2`` (modes up to several kHz, the broadband direct term
during the pulse); it must exist on the grid so that the anti-aliasing filter
removes it instead of folding it into the band.  (3) Linear interpolation
weights the input spectrum with ``sinc**2(pi f h)``.  The flat parts of the
record (force channel, direct term ``D f``) see the plain samples, whose
spectrum equals the sum of all interpolation images, but the resonant part
only sees the attenuated baseband.  Uncorrected, this biases the FRF of the
resonant part by ``-(pi f h)**2 / 3``: relative to ``H`` that is -0.003 dB at
500 Hz but up to ~0.8 dB at low-accelerance lines near 2 kHz with
``oversample = 4``.  The modal states are therefore driven by the samples
passed through a 7-tap zero-phase equaliser whose response approximates
``1 / sinc**2(pi f h)`` to 7e-6 below ``0.4 fs`` (``oversample = 4``); the
force channel and the direct term keep the plain samples.  In the band the
record then satisfies ``A(f) = H(f) F(f)`` whatever the force spectrum (its
sampling aliases cancel because every part of the record is driven by the
same samples): the windowed H1 of a noise-free record of the test suite's
toy truth matches the oracle to 2e-5 dB below 500 Hz and to ~2e-3 dB up to
``0.4 fs``.  The residual difference to a front-end that
filters before sampling is that the samples' spectrum includes the aliases
of the half-sine's spectrum, so the effective pulse differs from the
analytic one by ``O((pi h / width)**2)`` (a few 1e-4 of the impulse for a
0.5 ms pulse at 4 x 12.8 kHz, depending on where the pulse ends fall between
fine samples).  It is common to force and response, so it cancels in any FRF
estimate; compare with an analytic half-sine response only at a higher
``oversample``.

Closed-form continuation
------------------------
The force is non-zero for a few milliseconds only.  The FOH recursion is
stepped (vectorised over modes) just around the pulses.  Everywhere else the
modal input is zero, each modal state is a geometric sequence
``z[n] = z_ref e^{lam (n - n_ref) h}``, and an FIR filter applied to a
geometric sequence returns the same sequence times the filter's z-transform
evaluated at ``e^{lam h}``.  The filtered, decimated acceleration of the long
free decay is therefore evaluated exactly as ``Re(W' Z)`` with a modal
amplitude matrix ``W'`` and a block of complex exponentials ``Z`` on the
output grid: a dense matrix product instead of ``m`` recursions over
``oversample * N`` samples.  As in a real front-end, whose filter keeps
running past the end of a record, there is no end-of-record filter transient.

Anti-aliasing and why it cancels in H1
--------------------------------------
Force and accelerations pass through the *same* linear time-invariant
operator: a long zero-phase Kaiser low-pass FIR on the fine grid followed by
decimation to ``fs`` (identical to ``scipy.signal.resample_poly(x, 1,
oversample, window=antialias_fir(oversample))`` away from the record end).
Its stop band (from ``0.6 fs``) is attenuated by about 100 dB, so whatever
folds into ``[0, 0.4 fs]`` is negligible.  In the pass band the filter
multiplies the spectra of force and response by the same ``G(f)``, so in
``H1 = sum conj(F) A / sum |F|**2`` it cancels identically, ripple and all.
Multiplying both filtered signals by an exponential window
``exp(-sigma t)`` is equivalent to windowing before filtering with the
modified kernel ``g(t) exp(-sigma t)``, again the same for both channels,
so the windowed H1 equals the accelerance at ``s = i w + sigma``
(:func:`analytic_accelerance` with ``decay=sigma``).

Noise (:func:`add_noise`) and ADC quantisation/saturation (:func:`quantise`)
are separate steps so that the noise-free signals remain available as a
reference.
"""

from __future__ import annotations

import logging
import math
import numbers
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal as sp_signal

__all__ = [
    "ModalTruth",
    "Pulse",
    "add_noise",
    "analytic_accelerance",
    "antialias_fir",
    "exponential_window",
    "force_signal",
    "quantise",
    "synthesize_hit",
]

logger = logging.getLogger(__name__)

#: Upper edge of the band the lab analyses, as a fraction of ``fs``.  The
#: anti-aliasing filter is flat up to here and everything that could fold
#: into it (from ``(1 - _PASS_FRACTION) * fs`` upwards) is in its stop band.
_PASS_FRACTION = 0.4
#: Design stop-band attenuation of the anti-aliasing FIR (the requirement is
#: 80 dB; the margin absorbs the approximation in Kaiser's design formula).
_STOP_ATTENUATION_DB = 100.0
#: A pulse must span at least this many fine-grid steps, otherwise its
#: piecewise-linear representation no longer resembles a half-sine.
_MIN_FINE_STEPS_PER_PULSE = 4
#: Output samples per block in the closed-form free-decay evaluation; bounds
#: the memory of the block of complex exponentials (2 * m * block floats).
_FREE_DECAY_BLOCK = 2048
#: Below this |x| the phi-functions are summed as a Taylor series to avoid
#: cancellation in expm1(x) - x.
_PHI_SERIES_RADIUS = 0.5
_PHI_SERIES_TERMS = 22
#: Zero-phase 7-tap equaliser ``c0 + 2 sum_k c_k cos(2 k x)`` matching
#: ``1 / sinc**2(x)``, ``x = pi f h``, through O(x**6) (Taylor-matched; exact
#: rationals).  Undoes the linear-interpolation kernel seen by the modal
#: states; relative residual < 1e-4 below 0.4 fs for oversample >= 4.
_FOH_EQUALISER_HALF = np.array([533.0 / 420.0, -779.0 / 5040.0, 11.0 / 504.0, -1.0 / 560.0])
_FOH_EQUALISER = np.concatenate([_FOH_EQUALISER_HALF[:0:-1], _FOH_EQUALISER_HALF])
_EQ_HALF = _FOH_EQUALISER_HALF.size - 1


# --------------------------------------------------------------------------
# Data types
# --------------------------------------------------------------------------
def _float_array(name: str, value: object, ndim: int) -> NDArray[np.float64]:
    """Copy ``value`` into a read-only finite float array of ``ndim`` dims."""
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a numeric array, got {value!r}") from exc
    if arr.ndim != ndim:
        raise ValueError(
            f"{name} must be {ndim}-D, got shape {arr.shape} (value {value!r})"
        )
    bad = ~np.isfinite(arr)
    if np.any(bad):
        idx = tuple(int(i) for i in np.argwhere(bad)[0])
        raise ValueError(f"{name} must be finite, got {name}{list(idx)} = {arr[idx]!r}")
    arr.flags.writeable = False
    return arr


@dataclass(frozen=True, eq=False)
class ModalTruth:
    """Modal model of the structure as seen from one force point.

    Parameters
    ----------
    freqs_hz : ndarray, shape (m,)
        Undamped natural frequencies in Hz, ``>= 0``; rigid-body modes have 0.
    zeta : ndarray, shape (m,)
        Viscous modal damping ratios, ``0 <= zeta < 1`` (ignored for rigid
        modes).
    input_shape : ndarray, shape (m,)
        Mass-normalised modal displacement ``b_r`` at the force point along
        the force direction.
    output_shapes : ndarray, shape (n_out, m)
        Mass-normalised modal displacement ``c_jr`` at each sensor along its
        measuring direction.

    Raises
    ------
    ValueError
        If a field has the wrong shape, is not finite or is out of range.
        The message names the field and the offending value.

    Notes
    -----
    The arrays are copied and made read-only so that a truth cannot change
    behind the back of signals already synthesised from it.  Equality is
    identity (``eq=False``) because element-wise array comparison has no
    single truth value.
    """

    freqs_hz: NDArray[np.float64]
    zeta: NDArray[np.float64]
    input_shape: NDArray[np.float64]
    output_shapes: NDArray[np.float64]

    def __post_init__(self) -> None:
        freqs = _float_array("freqs_hz", self.freqs_hz, 1)
        m = freqs.size
        if m == 0:
            raise ValueError(f"freqs_hz must contain at least one mode, got {self.freqs_hz!r}")
        if np.any(freqs < 0.0):
            i = int(np.flatnonzero(freqs < 0.0)[0])
            raise ValueError(f"freqs_hz must be >= 0, got freqs_hz[{i}] = {freqs[i]!r}")
        zeta = _float_array("zeta", self.zeta, 1)
        if zeta.shape != (m,):
            raise ValueError(
                f"zeta must have shape ({m},) like freqs_hz, got shape {zeta.shape}"
            )
        bad = (zeta < 0.0) | (zeta >= 1.0)
        if np.any(bad):
            i = int(np.flatnonzero(bad)[0])
            raise ValueError(f"zeta must satisfy 0 <= zeta < 1, got zeta[{i}] = {zeta[i]!r}")
        b = _float_array("input_shape", self.input_shape, 1)
        if b.shape != (m,):
            raise ValueError(
                f"input_shape must have shape ({m},) like freqs_hz, got shape {b.shape}"
            )
        c = _float_array("output_shapes", self.output_shapes, 2)
        if c.shape[1] != m or c.shape[0] == 0:
            raise ValueError(
                f"output_shapes must have shape (n_out >= 1, {m}), got shape {c.shape}"
            )
        object.__setattr__(self, "freqs_hz", freqs)
        object.__setattr__(self, "zeta", zeta)
        object.__setattr__(self, "input_shape", b)
        object.__setattr__(self, "output_shapes", c)

    @property
    def n_modes(self) -> int:
        """Number of modes ``m``."""
        return int(self.freqs_hz.size)

    @property
    def n_outputs(self) -> int:
        """Number of sensor channels ``n_out``."""
        return int(self.output_shapes.shape[0])


@dataclass(frozen=True)
class Pulse:
    """One half-sine force pulse of a hammer hit.

    Parameters
    ----------
    t0 : float
        Start of the half-sine in s, relative to the record start (``>= 0``).
    width : float
        Duration of the half-sine in s (``> 0``; 0.3-1 ms is typical).
    amplitude : float
        Peak force in N.

    Raises
    ------
    ValueError
        If a field is not a finite real number or is out of range.
    """

    t0: float
    width: float
    amplitude: float

    def __post_init__(self) -> None:
        for name in ("t0", "width", "amplitude"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, numbers.Real):
                raise ValueError(f"{name} must be a real number, got {value!r}")
            if not math.isfinite(float(value)):
                raise ValueError(f"{name} must be finite, got {value!r}")
            object.__setattr__(self, name, float(value))
        if self.t0 < 0.0:
            raise ValueError(f"t0 must be >= 0 (pulse before the record start), got {self.t0!r}")
        if self.width <= 0.0:
            raise ValueError(f"width must be > 0, got {self.width!r}")


def _as_pulses(pulses: Pulse | Sequence[Pulse]) -> tuple[Pulse, ...]:
    """Normalise a single pulse or a sequence of pulses to a non-empty tuple."""
    seq = (pulses,) if isinstance(pulses, Pulse) else tuple(pulses)
    if not seq:
        raise ValueError("pulses must contain at least one Pulse, got an empty sequence")
    for i, p in enumerate(seq):
        if not isinstance(p, Pulse):
            raise ValueError(f"pulses[{i}] must be a Pulse, got {p!r}")
    return seq


# --------------------------------------------------------------------------
# Force and oracle
# --------------------------------------------------------------------------
def force_signal(t: ArrayLike, pulses: Pulse | Sequence[Pulse]) -> NDArray[np.float64]:
    """Evaluate the analytic hammer force.

    Parameters
    ----------
    t : array_like
        Times in s (any shape).
    pulses : Pulse or sequence of Pulse
        The pulses of the hit; overlapping pulses add.

    Returns
    -------
    ndarray
        ``sum_p A_p sin(pi (t - t0_p) / width_p)`` on ``t0_p <= t < t0_p + width_p``
        and zero elsewhere, same shape as ``t``.

    Notes
    -----
    The interval is half-open so that the force is exactly zero at and after
    the nominal end (``sin(pi)`` is not exactly zero in floating point).
    """
    t_arr = np.asarray(t, dtype=float)
    out = np.zeros(t_arr.shape)
    for p in _as_pulses(pulses):
        tau = t_arr - p.t0
        inside = (tau >= 0.0) & (tau < p.width)
        out[inside] += p.amplitude * np.sin(np.pi * tau[inside] / p.width)
    return out


def analytic_accelerance(
    truth: ModalTruth, f_hz: ArrayLike, decay: float = 0.0
) -> NDArray[np.complex128]:
    """Accelerance of the truth, optionally as seen through an exponential window.

    Parameters
    ----------
    truth : ModalTruth
        The modal model.
    f_hz : array_like, shape (n_f,)
        Frequencies in Hz.
    decay : float, optional
        Exponential-window decay rate ``sigma`` in 1/s (``>= 0``).  The FRF is
        evaluated at ``s = i 2 pi f + sigma``, which is exactly what the ratio
        of the spectra of ``exp(-sigma (t - t_ref))``-windowed force and
        response yields (the window's ``t_ref`` cancels in the ratio).

    Returns
    -------
    ndarray, shape (n_out, n_f), complex
        ``H_j = sum_r c_jr b_r s**2 / (s**2 + 2 zeta_r w_r s + w_r**2)``;
        rigid-body modes (``w_r = 0``) contribute ``c_jr b_r``.

    Raises
    ------
    ValueError
        If ``f_hz`` is not a finite 1-D array or ``decay`` is negative or not
        finite.
    """
    if not isinstance(truth, ModalTruth):
        raise ValueError(f"truth must be a ModalTruth, got {type(truth).__name__}")
    f = _float_array("f_hz", f_hz, 1)
    decay = float(decay)
    if not math.isfinite(decay) or decay < 0.0:
        raise ValueError(f"decay must be finite and >= 0, got {decay!r}")
    w = 2.0 * np.pi * truth.freqs_hz
    rigid = w == 0.0
    gain = truth.output_shapes * truth.input_shape[None, :]  # c_jr b_r
    out = np.empty((truth.n_outputs, f.size), dtype=complex)
    # Chunk over frequency so that (m, chunk) stays small for long FRFs.
    chunk = 4096
    for start in range(0, f.size, chunk):
        s = 2j * np.pi * f[start : start + chunk] + decay
        s2 = s * s
        denom = s2[None, :] + (2.0 * truth.zeta * w)[:, None] * s[None, :] + (w * w)[:, None]
        with np.errstate(invalid="ignore", divide="ignore"):
            modal = s2[None, :] / denom
        # s**2 / s**2 = 1 for rigid modes, also at s = 0 where the quotient is 0/0.
        modal[rigid, :] = 1.0
        out[:, start : start + chunk] = gain @ modal
    return out


def exponential_window(n: int, fs: float, t_start: float, decay: float) -> NDArray[np.float64]:
    """Exponential (force/response) window as used by impact-testing analysers.

    Parameters
    ----------
    n : int
        Number of samples.
    fs : float
        Sampling rate in Hz; sample ``k`` is at ``t = k / fs``.
    t_start : float
        Time in s where the decay starts; the window is 1 before it.
    decay : float
        Decay rate ``sigma`` in 1/s (``>= 0``).

    Returns
    -------
    ndarray, shape (n,)
        ``1`` for ``t < t_start`` and ``exp(-decay (t - t_start))`` after.

    Notes
    -----
    The windowed H1 equals :func:`analytic_accelerance` with the same
    ``decay`` exactly when both signals vanish before ``t_start``.  The
    zero-phase anti-aliasing filter spreads the force a few tens of samples
    ahead of the pulse, so place ``t_start`` well before the first pulse (or
    at 0, which makes the window a pure exponential).
    """
    if isinstance(n, bool) or not isinstance(n, numbers.Integral) or n < 0:
        raise ValueError(f"n must be a non-negative integer, got {n!r}")
    for name, value in (("fs", fs), ("t_start", t_start), ("decay", decay)):
        if not math.isfinite(float(value)):
            raise ValueError(f"{name} must be finite, got {value!r}")
    if fs <= 0.0:
        raise ValueError(f"fs must be > 0, got {fs!r}")
    if decay < 0.0:
        raise ValueError(f"decay must be >= 0, got {decay!r}")
    t = np.arange(int(n)) / float(fs)
    return np.exp(-float(decay) * np.clip(t - float(t_start), 0.0, None))


# --------------------------------------------------------------------------
# Anti-aliasing filter
# --------------------------------------------------------------------------
def _check_oversample(oversample: object) -> int:
    if isinstance(oversample, bool) or not isinstance(oversample, numbers.Integral):
        raise ValueError(f"oversample must be an integer >= 1, got {oversample!r}")
    if oversample < 1:
        raise ValueError(f"oversample must be an integer >= 1, got {oversample!r}")
    return int(oversample)


def antialias_fir(oversample: int) -> NDArray[np.float64]:
    """Zero-phase Kaiser low-pass FIR that emulates the front-end's anti-aliasing.

    Parameters
    ----------
    oversample : int
        Decimation factor from the fine grid (``oversample * fs``) to ``fs``.

    Returns
    -------
    ndarray, shape (2 L + 1,)
        Symmetric taps with unit DC gain, flat up to ``0.4 fs`` and attenuating
        by about 100 dB from ``0.6 fs`` (everything that would fold into
        ``[0, 0.4 fs]``).  For ``oversample == 1`` there is no room for a
        filter and ``[1.0]`` is returned.

    Notes
    -----
    Use it with ``scipy.signal.resample_poly(x, 1, oversample, window=h)``
    to reproduce the decimation done inside :func:`synthesize_hit`.
    """
    os_ = _check_oversample(oversample)
    if os_ == 1:
        return np.ones(1)
    # Frequencies normalised to the fine-grid Nyquist frequency os * fs / 2.
    width = 2.0 * (1.0 - 2.0 * _PASS_FRACTION) / os_
    numtaps, beta = sp_signal.kaiserord(_STOP_ATTENUATION_DB, width)
    numtaps += 1 - numtaps % 2  # odd length: integer group delay -> exact zero phase
    return sp_signal.firwin(numtaps, 1.0 / os_, window=("kaiser", beta))


# --------------------------------------------------------------------------
# Synthesis
# --------------------------------------------------------------------------
def _phi12(x: NDArray[np.complex128]) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
    """Return ``phi1(x) = (e^x - 1)/x`` and ``phi2(x) = (e^x - 1 - x)/x**2``."""
    phi1 = np.empty_like(x)
    phi2 = np.empty_like(x)
    small = np.abs(x) < _PHI_SERIES_RADIUS
    xb = x[~small]
    em1 = np.expm1(xb)
    phi1[~small] = em1 / xb
    phi2[~small] = (em1 - xb) / (xb * xb)
    xs = x[small]
    p1 = np.zeros_like(xs)
    p2 = np.zeros_like(xs)
    # Horner on sum_k x^k/(k+1)! and sum_k x^k/(k+2)!; the truncation error
    # is below 0.5**22 / 23! ~ 1e-29.
    for k in range(_PHI_SERIES_TERMS, -1, -1):
        p1 = p1 * xs + 1.0 / math.factorial(k + 1)
        p2 = p2 * xs + 1.0 / math.factorial(k + 2)
    phi1[small] = p1
    phi2[small] = p2
    return phi1, phi2


class _Synthesiser:
    """Evaluate the filtered, decimated record of one hit (see module docstring).

    All fine-grid indices are absolute: fine sample ``n`` is at ``n * h``
    with ``h = 1 / (oversample * fs)``, coarse sample ``k`` at fine ``k * os``.
    """

    def __init__(self, truth: ModalTruth, fs: float, oversample: int) -> None:
        self.fs = fs
        self.os = oversample
        self.h = 1.0 / (fs * oversample)
        taps = antialias_fir(oversample)
        self.half = (taps.size - 1) // 2
        # Output k = sum_j taps[j] x[k os + L - j] = sum_j taps_rev[j] x[k os - L + j].
        self.taps_rev = taps[::-1].copy()

        w = 2.0 * np.pi * truth.freqs_hz
        elastic = w > 0.0
        c = truth.output_shapes
        b = truth.input_shape
        self.direct = c @ b  # D_j: feed-through of all modes, rigid ones included
        w_e = w[elastic]
        z_e = truth.zeta[elastic]
        wd = w_e * np.sqrt(1.0 - z_e * z_e)
        self.lam = -z_e * w_e + 1j * wd
        residue = b[elastic] * self.lam**2 / (2j * wd)
        self.weights = 2.0 * c[:, elastic] * residue[None, :]  # W_jr
        lam_h = self.lam * self.h
        self.step = np.exp(lam_h)
        phi1, phi2 = _phi12(lam_h)
        self.g1 = self.h * phi2
        self.g0 = self.h * phi1 - self.g1
        # FIR applied to a geometric sequence z[n0 + j] = z[n0] E^j.
        j = np.arange(self.taps_rev.size)
        self.filtered_weights = self.weights * (
            np.exp(self.lam[:, None] * (self.h * j[None, :])) @ self.taps_rev
        )[None, :]
        self._basis: NDArray[np.float64] | None = None

    # -- forced part ------------------------------------------------------
    def forced_range(self, pulse: Pulse, n_out: int) -> tuple[int, int] | None:
        """Coarse indices whose filter support touches the pulse's non-zero samples."""
        lo = int(np.floor(pulse.t0 / self.h)) - 1
        hi = int(np.ceil((pulse.t0 + pulse.width) / self.h)) + 1
        idx = np.arange(lo, hi + 1)
        # Same expression (idx * h) as in forced(): the non-zero set is consistent.
        nz = np.flatnonzero(force_signal(idx * self.h, pulse))
        if nz.size == 0:
            return None
        # The equalised modal input reaches _EQ_HALF samples beyond the force.
        n_first = int(idx[nz[0]]) - _EQ_HALF
        n_last = int(idx[nz[-1]]) + _EQ_HALF
        k_lo = max(0, -((self.half - n_first) // self.os))  # ceil((n_first - L) / os)
        k_hi = min(n_out - 1, (n_last + self.half) // self.os)
        return (k_lo, k_hi) if k_lo <= k_hi else None

    def forced(
        self,
        k_lo: int,
        k_hi: int,
        pulses: tuple[Pulse, ...],
        n_ref: int | None,
        z_ref: NDArray[np.complex128] | None,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], int, NDArray[np.complex128]]:
        """Step the FOH recursion over a forced stretch and filter it explicitly.

        Returns the force (n_k,), accelerations (n_out, n_k) and the new anchor
        (first fine index after the last non-zero modal input, state there).
        """
        r0 = k_lo * self.os - self.half
        # One sample beyond the last support so that the anchor always exists.
        r1 = k_hi * self.os + self.half + 1
        idx = np.arange(r0, r1 + 1)
        u_ext = force_signal(np.arange(r0 - _EQ_HALF, r1 + _EQ_HALF + 1) * self.h, pulses)
        u = u_ext[_EQ_HALF:-_EQ_HALF]
        # Modal input: equalised samples (see module docstring); the force
        # channel and the direct term use the plain samples.
        u_eq = np.convolve(u_ext, _FOH_EQUALISER, mode="valid")
        z = np.empty((self.lam.size, idx.size), dtype=complex)
        if z_ref is None:
            z[:, 0] = 0.0  # at rest before the first pulse
        else:
            z[:, 0] = z_ref * np.exp(self.lam * (self.h * (r0 - n_ref)))
        step, g0, g1 = self.step, self.g0, self.g1
        for n in range(idx.size - 1):
            z[:, n + 1] = step * z[:, n] + g0 * u_eq[n] + g1 * u_eq[n + 1]
        accel = self.direct[:, None] * u[None, :] + (self.weights @ z).real
        n_win = self.taps_rev.size
        force_win = np.lib.stride_tricks.sliding_window_view(u[:-1], n_win)[:: self.os]
        accel_win = np.lib.stride_tricks.sliding_window_view(accel[:, :-1], n_win, axis=1)[
            :, :: self.os
        ]
        force_out = force_win @ self.taps_rev
        accel_out = accel_win @ self.taps_rev
        nz = np.flatnonzero(u_eq)
        # First index with zero modal input from here on.  It lies inside the
        # range whenever later output samples exist; otherwise it is unused.
        last = min(int(nz[-1]) + 1 if nz.size else 0, idx.size - 1)
        return force_out, accel_out, int(idx[last]), z[:, last].copy()

    # -- free part --------------------------------------------------------
    def free(
        self,
        out: NDArray[np.float64],
        k_a: int,
        k_b: int,
        n_ref: int,
        z_ref: NDArray[np.complex128],
    ) -> None:
        """Write the exact filtered free decay for coarse samples ``k_a..k_b`` into ``out``.

        Requires that the modal input is zero on all fine samples from
        ``n_ref`` to the end of the filter support of ``k_b``.
        """
        block = min(_FREE_DECAY_BLOCK, k_b - k_a + 1)
        if self._basis is None or self._basis.shape[1] < block:
            kappa = np.arange(block) / self.fs
            e = np.exp(self.lam[:, None] * kappa[None, :])
            # Re(M E) = [Re M, -Im M] @ [Re E; Im E]: one real GEMM per block.
            self._basis = np.concatenate([e.real, e.imag], axis=0)
        for k0 in range(k_a, k_b + 1, block):
            nb = min(block, k_b + 1 - k0)
            # Exponent >= 0 in time: forward propagation only, no overflow.
            amp = z_ref * np.exp(self.lam * (self.h * (k0 * self.os - self.half - n_ref)))
            mod = self.filtered_weights * amp[None, :]
            stacked = np.concatenate([mod.real, -mod.imag], axis=1)
            out[:, k0 : k0 + nb] = stacked @ self._basis[:, :nb]


def synthesize_hit(
    truth: ModalTruth,
    pulses: Pulse | Sequence[Pulse],
    *,
    fs: float = 12800.0,
    duration: float = 4.0,
    oversample: int = 4,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Synthesise the noise-free force and acceleration records of one hit.

    Parameters
    ----------
    truth : ModalTruth
        The modal model.
    pulses : Pulse or sequence of Pulse
        The force pulses of the hit (e.g. a double hit as two pulses).  Each
        must lie inside the record and span at least 4 fine-grid steps.
    fs : float, optional
        Output sampling rate in Hz.
    duration : float, optional
        Record length in s; ``N = round(duration * fs)`` samples.
    oversample : int, optional
        Ratio of the fine integration grid to ``fs`` (see the module
        docstring).  The run time hardly depends on it.  ``1`` leaves no room
        for an anti-aliasing filter and is meant for diagnostics only.

    Returns
    -------
    t : ndarray, shape (N,)
        Sample times ``k / fs``.
    force : ndarray, shape (N,)
        Anti-alias filtered, decimated force in N.
    accel : ndarray, shape (n_out, N)
        Anti-alias filtered, decimated accelerations (units of the mode
        shapes squared times N, i.e. m/s**2 for mass-normalised shapes in
        kg**-1/2).

    Raises
    ------
    ValueError
        On invalid arguments; a pulse that does not fit in the record names
        ``t0``/``width``.

    Notes
    -----
    The structure is at rest before the first pulse, and the front-end's
    filter is taken to keep running beyond the record (as a real one does),
    so the record has no filter transients at either end.  Signals are
    neither noisy nor quantised; see :func:`add_noise` and :func:`quantise`.
    """
    if not isinstance(truth, ModalTruth):
        raise ValueError(f"truth must be a ModalTruth, got {type(truth).__name__}")
    pulse_seq = _as_pulses(pulses)
    fs = float(fs)
    duration = float(duration)
    if not math.isfinite(fs) or fs <= 0.0:
        raise ValueError(f"fs must be finite and > 0, got {fs!r}")
    if not math.isfinite(duration) or duration <= 0.0:
        raise ValueError(f"duration must be finite and > 0, got {duration!r}")
    os_ = _check_oversample(oversample)
    n_samples = int(round(duration * fs))
    if n_samples < 1:
        raise ValueError(f"duration must cover at least one sample at fs={fs!r}, got {duration!r}")
    record = n_samples / fs
    min_width = _MIN_FINE_STEPS_PER_PULSE / (fs * os_)
    for i, p in enumerate(pulse_seq):
        if p.t0 >= record:
            raise ValueError(
                f"pulses[{i}].t0 = {p.t0!r} s lies outside the record [0, {record!r}) s"
            )
        if p.t0 + p.width > record:
            raise ValueError(
                f"pulses[{i}] (t0 = {p.t0!r} s, width = {p.width!r} s) ends after the "
                f"record end {record!r} s"
            )
        if p.width < min_width:
            raise ValueError(
                f"pulses[{i}].width = {p.width!r} s spans fewer than "
                f"{_MIN_FINE_STEPS_PER_PULSE} fine steps; increase oversample"
            )

    synth = _Synthesiser(truth, fs, os_)
    t = np.arange(n_samples) / fs
    force = np.zeros(n_samples)
    accel = np.zeros((truth.n_outputs, n_samples))

    ranges = sorted(
        r for r in (synth.forced_range(p, n_samples) for p in pulse_seq) if r is not None
    )
    segments: list[list[int]] = []
    for k_lo, k_hi in ranges:
        if segments and k_lo <= segments[-1][1] + 1:
            segments[-1][1] = max(segments[-1][1], k_hi)
        else:
            segments.append([k_lo, k_hi])
    logger.debug("synthesize_hit: %d modes, %d forced segment(s) %s", truth.n_modes,
                 len(segments), segments)

    n_ref: int | None = None
    z_ref: NDArray[np.complex128] | None = None
    k_next = 0
    for k_lo, k_hi in segments:
        if z_ref is not None and k_lo > k_next:
            synth.free(accel, k_next, k_lo - 1, n_ref, z_ref)  # type: ignore[arg-type]
        f_out, a_out, n_ref, z_ref = synth.forced(k_lo, k_hi, pulse_seq, n_ref, z_ref)
        force[k_lo : k_hi + 1] = f_out
        accel[:, k_lo : k_hi + 1] = a_out
        k_next = k_hi + 1
    if z_ref is not None and k_next < n_samples:
        synth.free(accel, k_next, n_samples - 1, n_ref, z_ref)  # type: ignore[arg-type]
    return t, force, accel


# --------------------------------------------------------------------------
# Front-end imperfections
# --------------------------------------------------------------------------
def _per_channel(name: str, value: ArrayLike, x: NDArray[np.float64]) -> NDArray[np.float64]:
    """Broadcast a scalar or per-channel (per-row) parameter against ``x``."""
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 1 and x.ndim == 2 and arr.size == x.shape[0]:
        arr = arr[:, None]  # one value per channel (row)
    try:
        np.broadcast_shapes(arr.shape, x.shape)
    except ValueError as exc:
        raise ValueError(
            f"{name} must be a scalar or one value per channel, got shape {arr.shape} "
            f"for a signal of shape {x.shape}"
        ) from exc
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return arr


def add_noise(
    signal: ArrayLike, rms: ArrayLike, rng: np.random.Generator
) -> NDArray[np.float64]:
    """Add white Gaussian sensor / front-end noise.

    Parameters
    ----------
    signal : array_like
        Clean signal, shape (N,) or (n_ch, N).
    rms : float or array_like
        Noise standard deviation (``>= 0``); a 1-D array of length ``n_ch``
        gives one value per channel of a 2-D signal.
    rng : numpy.random.Generator
        Source of randomness (pass a seeded generator for reproducibility).

    Returns
    -------
    ndarray
        A new array ``signal + noise``; the input is not modified.
    """
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    x = np.asarray(signal, dtype=float)
    sigma = _per_channel("rms", rms, x)
    if np.any(sigma < 0.0):
        raise ValueError(f"rms must be >= 0, got {rms!r}")
    return x + sigma * rng.standard_normal(x.shape)


def quantise(
    signal: ArrayLike, full_scale: ArrayLike, bits: int = 24
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Emulate the ADC: saturate at the input range and round to the LSB.

    Parameters
    ----------
    signal : array_like
        Signal, shape (N,) or (n_ch, N).
    full_scale : float or array_like
        ADC range ``FS > 0`` (input span ``[-FS, +FS]``); a 1-D array of
        length ``n_ch`` gives one range per channel of a 2-D signal.
    bits : int, optional
        ADC resolution; the step is ``2 FS / 2**bits``.

    Returns
    -------
    quantised : ndarray
        ``step * round(clip(x, -FS, FS) / step)``; an overloaded channel
        saturates flat at ``+-FS``.
    clipped_mask : ndarray of bool
        True exactly where ``|x| > FS`` (the saturated samples).
    """
    if isinstance(bits, bool) or not isinstance(bits, numbers.Integral) or not 1 <= bits <= 52:
        raise ValueError(f"bits must be an integer in [1, 52], got {bits!r}")
    x = np.asarray(signal, dtype=float)
    fsc = _per_channel("full_scale", full_scale, x)
    if np.any(fsc <= 0.0):
        raise ValueError(f"full_scale must be > 0, got {full_scale!r}")
    step = 2.0 * fsc / 2.0 ** int(bits)
    clipped = np.abs(x) > fsc
    # FS is an integer number of steps (2**(bits-1)), so +-FS survives rounding.
    quantised = np.round(np.clip(x, -fsc, fsc) / step) * step
    return quantised, clipped
