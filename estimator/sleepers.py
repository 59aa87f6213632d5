"""Sleeper passing separated from rail roughness: a comb at the orders of the sleeper spacing.

A wheel rolling along a rail on discrete supports follows the rail's
deflection under its own load, and that deflection varies within every
sleeper bay (stiffer above a sleeper, softer at mid-span). This parametric
excitation repeats with the sleeper spacing ``d`` (Knothe & Grassie 1993;
Nielsen & Igeland 1995). The axlebox accelerometers see it like a roughness
at ``d`` and its harmonics ``d/k``. A trolley measures the unloaded rail, so
it does not see it. The estimator's transfer functions are time-invariant,
built on the thesis's continuously supported rail (eq. 2.32–2.35), so they
leave this part in the estimated roughness.
For ``d`` between 0.5 and 1 m it lands in the EN 13231-3 300–1000 mm band.

It is periodic in the line's chainage, not in time. The separation is the
wheel comb's (:mod:`estimator.wheel`) with the bay in place of the wheel
revolution:

1. The rail part is read on a grid of ``N`` samples per bay, phase-locked to
   chainage multiples of ``d``.
2. A moving synchronous average over ``±R`` bays, with triangular weights
   and the bay itself left out, estimates the periodic part at every bay.
   This follows the amplitude as the wheel load and the supports change
   along the line.
3. Only the **significant orders** are kept. Significant means that the
   amplitude of the run's synchronous average exceeds ``floor_factor`` times
   its floor ``σ_k/√n``, the same test as the wheel's polygon orders. Order 0
   is never kept, because it is the rail's long wavelengths.

Where the track has no sleeper effect, or the spacing given is wrong, no
order is significant and nothing is removed.

**What the track model expects.** :func:`quasi_static_orders` gives the
orders of ``P α(x)``: the static wheel load times the discretely supported
rail's receptance at bay position ``x`` (:func:`receptance.track.track_receptance`,
0.5 Hz). Beside each removed order the estimate reports this expectation. A
measured amplitude well above it points to weaker support than the trackform
says, such as voided sleepers or worn pads. On the virtual line the removed
order 1 is 16–17 µm against 18 µm expected.

The cost on the random roughness at a kept order is the comb's noise, a power
factor ``1 + Σw²/(Σw)²``: +0.045 dB at ``R = 64``, and only at the kept
orders. A genuine rail roughness that repeats exactly with the sleeper
spacing (rail seated into its fastenings) cannot be told from sleeper passing
by an axlebox system. :class:`SleeperPassing` reports what was removed, per
rail and order, so an analyst can look at it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from estimator.inversion import cubic_sample
from estimator.wheel import comb, only_orders, order_decomposition

__all__ = ["SleeperPassing", "sleeper_comb", "quasi_static_orders"]

#: fewest samples per bay (the orders kept are low; the grid only has to carry them)
MIN_SAMPLES_PER_BAY = 16


@dataclass(frozen=True, eq=False)
class SleeperPassing:
    """What :func:`sleeper_comb` removed from one wheelset's rail estimate.

    Attributes
    ----------
    spacing_m : float
        Sleeper spacing ``d``.
    bays : int
        ``R``: the neighbouring bays on each side in the moving average.
    orders : pandas.DataFrame
        ``rail, order, wavelength_m, amplitude_m, floor_m, significant, expected_m``. These are the run's
        synchronous average per rail. The significant orders are the ones removed. ``expected_m`` is the track
        model's quasi-static expectation, NaN when not given.
    removed_rms_m : tuple of float
        RMS of the removed part per rail row (valid samples).
    """

    spacing_m: float
    bays: int
    orders: pd.DataFrame
    removed_rms_m: tuple[float, ...]

    @property
    def significant(self) -> pd.DataFrame:
        """The removed orders of every rail (rows of :attr:`orders`, in their order)."""
        return self.orders[self.orders["significant"]]

    def removed(self, rail: str) -> pd.DataFrame:
        """Significant (removed) orders of one rail, largest first."""
        o = self.significant
        return o[o["rail"] == rail].sort_values("amplitude_m", ascending=False)


def quasi_static_orders(trackform, wheel_load_n: float, max_order: int = 12, n_positions: int = 64) -> np.ndarray:
    """Amplitudes [m] of orders ``1..max_order`` of the rail's static deflection under the wheel across a bay.

    The deflection is ``P α(x)``: the wheel load times the receptance of the rail on discrete supports at
    bay position ``x``, taken at 0.5 Hz where it is quasi-static (the thesis's Table 2.2 trackform,
    :func:`receptance.track.track_receptance` with ``supports="discrete"``). The bay is the trackform's
    ``support_spacing``.
    """
    from receptance.track import track_receptance

    pos = np.arange(n_positions) / n_positions
    w = wheel_load_n * np.array([track_receptance(np.array([0.5]), trackform, "vertical", supports="discrete",
                                                  position=q)[0].real for q in pos])
    return np.abs(np.fft.rfft(w))[1:max_order + 1] * 2 / n_positions


def sleeper_comb(profile: np.ndarray, x0: float, dx: float, spacing_m: float, rails: tuple[str, ...], *,
                 bays: int = 64, floor_factor: float = 4.0, max_order: int = 12, expected_m: np.ndarray | None = None
                 ) -> tuple[np.ndarray, SleeperPassing]:
    """Rail roughness without the sleeper-passing part (module docstring).

    Parameters
    ----------
    profile : ndarray (n_rails, M)
        Rail roughness estimate on a uniform grid ``x0 + j dx`` [m], NaN where masked.
    x0, dx : float
        The grid's first chainage and its step [m].
    spacing_m : float
        Sleeper spacing ``d`` [m] of the line.
    rails : tuple of str
        Rail of each row.
    bays : int
        ``R`` of the moving synchronous average (±R bays).
    floor_factor : float
        An order is removed when its amplitude exceeds this multiple of its floor.
    max_order : int
        Highest order tested (wavelength ``d / max_order``).
    expected_m : ndarray, optional
        What the track model expects of orders ``1, 2, …`` (:func:`quasi_static_orders`), reported beside
        each order.

    Returns
    -------
    rail : ndarray (n_rails, M)
        ``profile`` minus the significant orders of its moving synchronous average.
    passing : SleeperPassing
    """
    p = np.atleast_2d(np.asarray(profile, float))
    n_rows, m = p.shape
    if not (spacing_m > 0 and math.isfinite(spacing_m)):
        raise ValueError(f"sleeper spacing must be a positive length, got {spacing_m!r}")
    n_per = max(MIN_SAMPLES_PER_BAY, int(math.ceil(spacing_m / dx)))
    n_per += n_per % 2
    step = spacing_m / n_per
    # phase-locked to the line (order phases compare between runs), a bay to spare at each end for the cubic
    xb0 = (math.floor(x0 / spacing_m) - 1) * spacing_m
    n_bays = int(math.ceil((x0 + (m - 1) * dx - xb0) / spacing_m)) + 1
    xs = xb0 + np.arange(n_bays * n_per) * step
    on_bays = cubic_sample(p, (xs - x0) / dx)
    X = on_bays.reshape(n_rows, n_bays, n_per)
    kmax = min(max_order, n_per // 2 - 1)
    rows, keep = [], np.zeros((n_rows, n_per // 2 + 1), bool)
    for i in range(n_rows):
        full = X[i][np.isfinite(X[i]).all(axis=1)]
        mean, floor = order_decomposition(full) if full.shape[0] >= 2 else (None, None)
        for k in range(1, kmax + 1):
            amp = abs(mean[k]) if mean is not None else math.nan
            sig = bool(mean is not None and amp > floor_factor * floor[k])
            keep[i, k] = sig
            exp = float(expected_m[k - 1]) if expected_m is not None and k <= len(expected_m) else math.nan
            rows.append({"rail": rails[i], "order": k, "wavelength_m": spacing_m / k, "amplitude_m": float(amp),
                         "floor_m": float(floor[k]) if floor is not None else math.nan, "significant": sig,
                         "expected_m": exp})
    orders = pd.DataFrame(rows, columns=["rail", "order", "wavelength_m", "amplitude_m", "floor_m", "significant",
                                         "expected_m"])
    if not keep.any():
        return p.copy(), SleeperPassing(float(spacing_m), int(bays), orders, (0.0,) * n_rows)
    R = int(bays)
    per = only_orders(comb(on_bays, n_per, R)[1].reshape(n_rows, n_bays, n_per), keep[:, None, :]).reshape(n_rows, -1)
    part = cubic_sample(per, (x0 + np.arange(m) * dx - xb0) / step)
    part = np.where(np.isfinite(part), part, 0.0)
    rail = p - part
    ok = np.isfinite(p)
    rms = tuple(float(np.sqrt(np.mean(part[i][ok[i]] ** 2))) if ok[i].any() else 0.0 for i in range(n_rows))
    return rail, SleeperPassing(float(spacing_m), R, orders, rms)
