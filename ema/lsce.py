"""Global least-squares complex exponential (LSCE) pole estimation, zoomed on a band.

The thesis identifies its modes with "a least-squares complex exponential
method" (thesis §3.4, after its refs. [24], [27]; Brown et al., SAE 790221,
1979) from the H1 accelerances of eq. 3.2.  This module implements the SIMO
*global* variant: one set of autoregressive (Prony) coefficients common to all
output channels, solved by least squares for every model order up to
``max_order`` at once.

Zoomed impulse response
-----------------------
Classic LSCE inverse-transforms the FRF from 0 Hz to Nyquist, so a band
``[f_lo, f_hi]`` has to be padded (sdypy-EMA pads with zeros and, when
``lower > 0``, keeps the sampling interval of the full band, which mis-scales
every identified frequency).  Here only the ``N`` lines of the band are used.
With the lines ``f_k = f_lo + k df`` (``k = 0 .. N-1``) the complex sequence

.. math:: h[n] = \\frac{1}{N} \\sum_{k=0}^{N-1} H(f_k) e^{2\\pi i k n / N}

is the *zoomed* impulse response: for a pole ``lambda`` inside the band the
term ``R / (i w - lambda)`` contributes (up to a constant and to a short
transient caused by the band edges, which the higher model orders absorb)
``z^n`` with

.. math:: z = \\exp\\big((\\lambda - i\\,2\\pi f_{lo})\\,\\Delta t\\big),\\qquad \\Delta t = 1 / (N\\,df),

(the identity :math:`\\sum_{k\\in\\mathbb{Z}} e^{ikx}/(k-\\kappa) \\propto e^{i\\kappa x}`
for ``0 < x < 2 pi``).  Poles outside the band do not produce exponentials in
``h`` and therefore do not alias into the band.  The sequence is complex, so
the AR coefficients are complex and every root is one pole: **the model order
is the number of poles in the band** (a real-valued LSCE of "order n" with
``2n`` coefficients over 0–f_hi has ``n`` pole pairs spread over the whole
baseband).  A pole is recovered as
``lambda = (ln|z| + i arg z) / dt + i 2 pi f_lo`` with ``arg z`` taken in
``[0, 2 pi)``, i.e. its frequency falls in ``[f_lo, f_lo + N df)``.

All orders from one factorisation
---------------------------------
For order ``p`` the prediction equations of channel ``j`` are
``h_j[n] + sum_{i=1..p} a_i h_j[n-i] = 0`` for ``n = P .. L-1`` with
``P = max_order`` fixed for every order, so the regression matrix of order
``p`` is the first ``p`` columns of the matrix of order ``P``.  One QR
factorisation ``[A_P | y] = Q R`` of the stacked (all channels) matrix then
gives every order: ``R[:p, :p] a = -R[:p, P]``.  The cost is one tall QR
plus ``max_order`` triangular solves and polynomial roots, instead of one
least-squares problem per order.

Exponential window
------------------
If the FRF was measured with an exponential window ``exp(-a t)`` on force and
response (:attr:`~ema.frf.FrequencyResponse.exp_window_decay`), every pole is
shifted by ``-a``.  :class:`PoleSweep` keeps the poles as identified
(``poles_windowed``) and gives the corrected ones (``lambda + a``).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from scipy.linalg import solve_triangular

from ._blas import one_blas_thread
from .frf import FrequencyResponse

__all__ = ["PoleSweep", "lsce", "zoom_impulse_response", "band_lines", "IdentificationError", "pole_frequency_hz",
           "pole_damping"]

log = logging.getLogger("ema")


class IdentificationError(ValueError):
    """Modal identification cannot proceed with the given FRF or parameters."""


def band_lines(frf: FrequencyResponse, band_hz: tuple[float, float] | None) -> FrequencyResponse:
    """The SIMO part of ``frf`` restricted to ``band_hz``, with its frequency axis checked.

    Parameters
    ----------
    frf : FrequencyResponse
        One input (SIMO); several inputs raise :class:`IdentificationError`.
    band_hz : (float, float) or None
        Inclusive band; ``None`` keeps all lines.

    Returns
    -------
    FrequencyResponse
        The selected lines.

    Raises
    ------
    IdentificationError
        If the response has more than one input, the band is empty or
        reversed, the lines are not equally spaced, or the data holds NaN/inf
        (the message names the channel).
    """
    if not isinstance(frf, FrequencyResponse):
        raise IdentificationError(f"frf must be a FrequencyResponse, got {type(frf).__name__}")
    if frf.n_in != 1:
        raise IdentificationError(
            f"identification is SIMO: frf must have exactly one input, got {frf.n_in} ({list(frf.inputs)}); "
            "use frf.select(inputs=[...]) to pick one"
        )
    if band_hz is not None:
        lo, hi = (float(b) for b in band_hz)
        if not (np.isfinite(lo) and np.isfinite(hi)) or lo < 0 or hi <= lo:
            raise IdentificationError(f"band_hz must be (low, high) with 0 <= low < high, got {band_hz!r}")
        try:
            frf = frf.select(band_hz=(lo, hi))
        except ValueError as exc:
            raise IdentificationError(str(exc)) from exc
    f = frf.freqs_hz
    if f.size < 8:
        raise IdentificationError(f"band {band_hz} Hz holds only {f.size} lines; at least 8 are needed")
    df = np.diff(f)
    if not np.allclose(df, df[0], rtol=1e-6, atol=0):
        i = int(np.argmax(np.abs(df - df[0])))
        raise IdentificationError(
            f"frequency lines must be equally spaced for LSCE; spacing {df[0]:g} Hz at the start but "
            f"{df[i]:g} Hz between {f[i]:g} and {f[i + 1]:g} Hz"
        )
    bad = ~np.isfinite(frf.data)
    if bad.any():
        j, _, k = np.argwhere(bad)[0]
        raise IdentificationError(
            f"frf data of channel {frf.outputs[j]!r} is not finite at {f[k]:g} Hz; drop the channel "
            "(frf.select(outputs=...)) or the line (band_hz)"
        )
    return frf


def zoom_impulse_response(data: np.ndarray, freqs_hz: np.ndarray) -> tuple[np.ndarray, float]:
    """Zoomed (band-pass, frequency-shifted) impulse responses of equally spaced FRF lines.

    Parameters
    ----------
    data : ndarray complex (n_out, N)
        FRF lines ``H(f_lo + k df)``.
    freqs_hz : ndarray (N,)
        The equally spaced lines.

    Returns
    -------
    h : ndarray complex (n_out, N)
        ``h[n] = (1/N) sum_k H_k exp(2 pi i k n / N)``; a band pole ``lambda``
        appears as ``z^n`` with ``z = exp((lambda - 2 pi i f_lo) dt)``.
    dt : float
        Sampling interval ``1 / (N df)`` [s].
    """
    n = freqs_hz.size
    df = (freqs_hz[-1] - freqs_hz[0]) / (n - 1)
    return np.fft.ifft(data, axis=-1), 1.0 / (n * df)


@dataclass(frozen=True, eq=False)
class PoleSweep:
    """Poles of every LSCE model order.

    Parameters
    ----------
    orders : ndarray (n_orders,) int
        Model orders = number of poles of each model.
    poles_windowed : tuple of ndarray complex
        Continuous-time poles [rad/s] of each order as identified from the
        (possibly exponentially windowed) FRF, ``len == orders[i]``.
    band_hz : (float, float)
        The band the poles were identified in.
    exp_window_decay : float
        Window decay ``a`` [1/s]; the physical poles are ``poles_windowed + a``.
    dt : float
        Sampling interval of the zoomed impulse response [s].
    n_samples : int
        Impulse-response samples used per channel.
    """

    orders: np.ndarray
    poles_windowed: tuple[np.ndarray, ...]
    band_hz: tuple[float, float]
    exp_window_decay: float
    dt: float
    n_samples: int

    def poles(self, i: int) -> np.ndarray:
        """Physical (window-corrected) poles of the ``i``-th order: ``s = s_w + a``."""
        return self.poles_windowed[i] + self.exp_window_decay


@one_blas_thread
def lsce(
    frf: FrequencyResponse,
    *,
    band_hz: tuple[float, float] | None = None,
    max_order: int = 100,
    min_order: int = 1,
    n_samples: int | None = None,
    normalise_channels: bool = False,
) -> PoleSweep:
    """Global SIMO LSCE poles for model orders ``min_order .. max_order``.

    Parameters
    ----------
    frf : FrequencyResponse
        Single-input FRFs (any quantity) on equally spaced lines.
    band_hz : (float, float), optional
        Band to identify in; default all lines of ``frf``.
    max_order : int
        Largest number of poles (in the band).
    min_order : int
        Smallest order returned.
    n_samples : int, optional
        Zoomed impulse-response samples used per channel; default
        ``max(N // 2, 3 * max_order)`` capped at ``N - 1`` (``N`` lines).
    normalise_channels : bool
        Scale every channel's impulse response to unit RMS before the common
        least-squares fit (equal say for weak channels); default ``False``
        (equal absolute noise on all channels makes the plain sum optimal).

    Returns
    -------
    PoleSweep

    Raises
    ------
    IdentificationError
        Bad FRF (see :func:`band_lines`), bad orders, or a band too short for
        ``max_order``.

    Notes
    -----
    The prediction equations of all channels and of all orders share one QR
    factorisation (module docstring).  The frequency of every pole lies in
    ``[f_lo, f_lo + N df)``.
    """
    frf = band_lines(frf, band_hz)
    f = frf.freqs_hz
    max_order = int(max_order)
    min_order = int(min_order)
    if max_order < 1 or not 1 <= min_order <= max_order:
        raise IdentificationError(f"need 1 <= min_order <= max_order, got min_order={min_order}, max_order={max_order}")
    n = f.size
    L = int(n_samples) if n_samples is not None else min(n - 1, max(n // 2, 3 * max_order))
    if L > n or L < 1:
        raise IdentificationError(f"n_samples must be in 1..{n} (lines in the band), got {n_samples}")
    rows_per_channel = L - 1 - max_order
    n_out = frf.n_out
    if rows_per_channel < 1 or rows_per_channel * n_out < 2 * max_order:
        raise IdentificationError(
            f"max_order={max_order} is too high for {n} lines x {n_out} channels in band "
            f"{f[0]:g}-{f[-1]:g} Hz (n_samples={L}); lower max_order or widen the band"
        )
    h, dt = zoom_impulse_response(frf.data[:, 0, :], f)
    # skip n = 0 (the periodic discontinuity); use samples 1 .. L-1
    h = h[:, 1:L]
    if normalise_channels:
        rms = np.sqrt(np.mean(np.abs(h) ** 2, axis=1, keepdims=True))
        h = h / np.where(rms > 0, rms, 1.0)
    P = max_order
    # windows h[m .. m+P]; reversed -> [h[n], h[n-1], ..., h[n-P]] with n = m + P
    win = sliding_window_view(h, P + 1, axis=1)[:, :, ::-1].reshape(-1, P + 1)
    M = np.empty_like(win)
    M[:, :P] = win[:, 1:]
    M[:, P] = win[:, 0]
    R = np.linalg.qr(M, mode="r")
    w0 = 2 * np.pi * f[0]
    orders = np.arange(min_order, max_order + 1)
    poles = []
    for p in orders:
        Rp = R[:p, :p]
        coef = _solve_upper(Rp, -R[:p, P])
        z = np.roots(np.concatenate([[1.0], coef]))
        z = z[z != 0]
        lam = (np.log(np.abs(z)) + 1j * np.mod(np.angle(z), 2 * np.pi)) / dt + 1j * w0
        poles.append(np.sort_complex(lam))
    log.info(
        "LSCE: %d channels, %d lines %.4g-%.4g Hz, orders %d..%d (%d IR samples per channel)",
        n_out, n, f[0], f[-1], min_order, max_order, L,
    )
    return PoleSweep(
        orders=orders,
        poles_windowed=tuple(poles),
        band_hz=(float(f[0]), float(f[-1])),
        exp_window_decay=float(frf.exp_window_decay),
        dt=float(dt),
        n_samples=L,
    )


def _solve_upper(R: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve ``R x = b`` for upper-triangular ``R``; zero pivots (rank deficiency) give a least-norm answer."""
    d = np.abs(np.diag(R))
    if d.size and d.min() > 1e-13 * d.max():
        return solve_triangular(R, b, lower=False, check_finite=False)
    return np.linalg.lstsq(R, b, rcond=None)[0]


def pole_frequency_hz(poles: np.ndarray) -> np.ndarray:
    """Undamped natural frequency ``|lambda| / 2 pi`` of continuous-time poles [Hz]."""
    return np.abs(poles) / (2 * np.pi)


def pole_damping(poles: np.ndarray) -> np.ndarray:
    """Damping ratio ``-Re(lambda) / |lambda|`` of continuous-time poles."""
    return -np.real(poles) / np.abs(poles)
