"""The contact patch's averaging of short wavelengths, and its correction.

A wheel does not follow roughness shorter than its contact patch: it feels
the roughness averaged over the contact length with the Hertz pressure's
weight ``sqrt(1 − (x/a)²)`` (``a`` the semi-axis along the rolling
direction). For a sinusoid of wavenumber ``κ`` [rad/m] the averaging is
``H(κ) = 2 J₁(κa)/(κa)`` (the Fourier transform of the normalised
half-ellipse; Remington's one-dimensional contact filter). An axlebox
estimate is therefore of the *filtered* roughness; EN 13231-3 and EN 15610
describe the rail itself, as a trolley measures it. :func:`undo_contact_filter`
divides the estimate by ``H`` where the filter is mild (gain ≤ ``max_gain_db``,
default 6 dB, ``κa ≲ 2.2``) and keeps that largest gain at shorter
wavelengths, where the patch has wiped out what the wheel could tell.

``a`` comes from the Hertz solution of :class:`receptance.ContactParameters`
(wheel load, wheel radius, rail crown radius).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import fft as sfft
from scipy.special import j1

__all__ = ["MAX_GAIN_DB", "contact_filter_response", "contact_gain", "undo_contact_filter"]

#: the correction's cap [dB]: beyond it the patch has wiped out what the wheel could tell
MAX_GAIN_DB = 6.0


def contact_filter_response(k_cycles_per_m, semi_axis_m: float) -> np.ndarray:
    """``H = 2 J₁(κa)/(κa)`` with ``κ = 2π k`` (1 at ``k = 0``)."""
    ka = 2 * np.pi * np.abs(np.asarray(k_cycles_per_m, float)) * semi_axis_m
    with np.errstate(invalid="ignore", divide="ignore"):
        h = np.where(ka > 1e-9, 2 * j1(ka) / ka, 1.0)
    return h


def contact_gain(k_cycles_per_m: np.ndarray, semi_axis_m: float, max_gain_db: float = MAX_GAIN_DB) -> np.ndarray:
    """Correction gain ``1/H`` on an increasing wavenumber axis, capped (module docstring)."""
    k = np.asarray(k_cycles_per_m, float)
    h = contact_filter_response(k, semi_axis_m)
    floor = 10 ** (-max_gain_db / 20)
    ka = 2 * math.pi * k * semi_axis_m
    # beyond the point where H first falls to the floor keep the largest gain (no inversion of a wiped-out band)
    past = np.maximum.accumulate(h < floor)
    return np.where(past | (ka > 3.8), 1 / floor, 1 / np.maximum(h, floor))


def undo_contact_filter(profile: np.ndarray, dx: float, semi_axis_m: float,
                        max_gain_db: float = MAX_GAIN_DB) -> np.ndarray:
    """Divide a profile (…, M; NaN = masked, kept) by the contact filter, gain capped (module docstring)."""
    p = np.asarray(profile, float)
    bad = ~np.isfinite(p)
    m = p.shape[-1]
    nfft = sfft.next_fast_len(m + 64)
    P = sfft.rfft(np.where(bad, 0.0, p), nfft, axis=-1)
    out = sfft.irfft(P * contact_gain(sfft.rfftfreq(nfft, dx), semi_axis_m, max_gain_db), nfft, axis=-1)[..., :m]
    out[bad] = np.nan
    return out
