"""Modal identification of SIMO FRFs: LSCE sweep, stabilisation, automatic pole selection, refinement, LSFD.

:func:`identify` chains the stages and returns everything as one
:class:`Identification`:

1. :func:`ema.lsce.lsce` — global LSCE poles for every order ``1 .. max_order``
   (order = number of poles in the band; zoomed formulation, one QR for all
   orders);
2. :func:`ema.stabilisation.stabilisation_diagram` — stability of frequency,
   damping and quick shapes from order to order;
3. :func:`select_poles` — physical poles without frequency hints: the
   fully stable in-band poles are clustered across orders (average-linkage
   hierarchical clustering on a distance combining relative frequency
   difference and ``1 - MAC`` of the quick shapes); clusters present in at
   least ``min_fraction`` of the orders are kept and represented by the
   median pole.  :func:`select_poles_at` is the manual alternative (a list
   of frequencies, nearest stable poles);
4. :func:`ema.lsfd.refine_poles` — nonlinear least squares of the global SIMO
   modal model with residual terms (variable projection), after every change
   of the pole set;
5. out-of-band pseudo-modes: a pole just above (then below) the band is
   tried and kept while it is significant and lowers the residual by at
   least ``min_gain`` — it absorbs modes just outside the band (e.g. the
   truncated 544/548 Hz modes of the ``residual`` scenario) that the constant
   residuals cannot follow, and is reported in ``fit.residual_poles``, never
   as a mode;
6. pruning of computational poles: negative or excessive damping, poles that
   left the band, duplicates, low modal phase collinearity, and poles whose
   removal does not worsen the FRF synthesis by more than ``significance``
   times the number of real parameters they carry, in units of the estimated
   noise variance (an information criterion; poles are removed one at a
   time, least significant first, and the rest re-refined);
7. mode splitting: every mode is tried as two close poles (a flexural pair
   split by a suspension, 0.02 % apart, is one pole in the diagram); a split
   is kept if both poles stay within the frequency tolerance, are significant
   and lower the residual by at least ``min_gain``;
8. :func:`ema.lsfd.lsfd` — residues (modal constants) of every channel, lower
   and upper residuals, MPC/MPD, synthesis error per channel.

Poles, frequencies and damping ratios are physical throughout: the
exponential-window shift ``a = frf.exp_window_decay`` is removed
(``s = s_w + a``; exact, see :mod:`ema.lsfd`).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
import pandas as pd
from scipy.cluster import hierarchy
from scipy.spatial.distance import squareform

from ._blas import one_blas_thread
from .frf import FrequencyResponse
from .lsce import IdentificationError, PoleSweep, band_lines, lsce
from .lsfd import DEFAULT_RESIDUALS, LSFDResult, RefinedPoles, lsfd, mcf, refine_poles
from .modeset import ModeSet
from .limits import MAX_ORDER
from .stabilisation import StabilisationDiagram, stabilisation_diagram

__all__ = [
    "PoleCluster",
    "RejectedPole",
    "Identification",
    "select_poles",
    "select_poles_at",
    "identify",
    "channel_weights",
    "MAX_ORDER",
]

log = logging.getLogger("ema")

#: Evaluation budget of a trial (pseudo-mode or split) optimisation with few free poles.
_TRIAL_NFEV = 30


@dataclass(frozen=True, eq=False)
class PoleCluster:
    """Stable poles of the diagram that belong to one physical pole candidate.

    Parameters
    ----------
    pole : complex
        Representative physical pole (median of the members' real and imaginary parts) [rad/s].
    members : ndarray int
        Indices into the diagram's pole arrays.
    n_orders : int
        Number of distinct model orders among the members.
    fraction : float
        ``n_orders`` / number of orders in the diagram.
    """

    pole: complex
    members: np.ndarray
    n_orders: int
    fraction: float

    @property
    def freq_hz(self) -> float:
        return float(abs(self.pole) / (2 * np.pi))

    @property
    def zeta(self) -> float:
        return float(-self.pole.real / abs(self.pole))


@dataclass(frozen=True)
class RejectedPole:
    """A candidate pole removed during selection, with the reason."""

    freq_hz: float
    zeta: float
    reason: str


@dataclass(frozen=True, eq=False)
class Identification:
    """Result of :func:`identify`.

    Parameters
    ----------
    modes : ModeSet
        The identified modes (physical f, zeta; shapes per ``modes.scaling``).
    diagram : StabilisationDiagram
        All poles of the sweep with stability flags (for plots).
    clusters : tuple of PoleCluster
        Candidate clusters kept by the automatic selection (empty for manual selection).
    refined : RefinedPoles or None
        Result of the last pole refinement (None with ``refine=False``).
    fit : LSFDResult
        Residues, residual terms, synthesis and per-channel error of the final model.
    rejected : tuple of RejectedPole
        Candidates removed, with the reason.
    diagnostics : pandas.DataFrame
        One row per mode: ``f_hz, zeta``; ``f_std_hz, zeta_std`` (one-sigma
        Gauss–Newton uncertainties); ``mpc, mpd, mcf`` (phase collinearity,
        mean phase deviation [deg], complexity factor); ``significance``
        (increase of the residual, in noise variances, if the mode is
        removed); ``support`` (fraction of LSCE orders its cluster spans).
    timings : dict
        Wall time [s] of each stage.
    weights : dict
        Channels weighted down in the pole estimation (:func:`channel_weights`), by name.
    """

    modes: ModeSet
    diagram: StabilisationDiagram
    clusters: tuple[PoleCluster, ...]
    refined: RefinedPoles | None
    fit: LSFDResult
    rejected: tuple[RejectedPole, ...]
    diagnostics: pd.DataFrame
    timings: dict = field(default_factory=dict)
    weights: dict = field(default_factory=dict)

    @property
    def synthesis(self) -> FrequencyResponse:
        """Synthesised FRF on the identification lines (comparable with the measured, windowed FRF)."""
        return self.fit.synthesis


# ------------------------------------------------------------------------- channel weights
#: A channel whose robust level exceeds this multiple of the median channel's is weighted down to it.
MAX_LEVEL_RATIO = 10.0


def channel_weights(frf: FrequencyResponse, max_ratio: float = MAX_LEVEL_RATIO) -> np.ndarray:
    """Weights (<= 1) that keep any one channel from swamping the global pole estimation.

    The robust level of a channel is the median of ``|H_j|`` over the band's
    lines. Least squares over all channels is the maximum-likelihood fit when
    the sensors' noise is alike, so channels keep their natural weight (1)
    unless their level exceeds ``max_ratio`` x the median channel's level —
    beyond the physical spread between the sensors of one setup (5.8 x at
    most in the virtual lab's setups), e.g. a wrong sensitivity; such a
    channel is scaled down to that level (and a WARNING names it).

    Returns
    -------
    ndarray (n_out,)
    """
    level = np.median(np.abs(frf.data[:, 0, :]), axis=1)
    ok = np.isfinite(level) & (level > 0)
    w = np.ones(frf.n_out)
    if ok.sum() < 2:
        return w
    ref = max_ratio * float(np.median(level[ok]))
    big = ok & (level > ref)
    w[big] = ref / level[big]
    for j in np.flatnonzero(big):
        log.warning("identify: channel %r has %.3g x the median channel's FRF level; weighted down by %.3g in the "
                    "pole estimation so that it cannot swamp the other channels (wrong sensitivity or unit?)",
                    frf.outputs[j], level[j] / (ref / max_ratio), w[j])
    return w


# ------------------------------------------------------------------------- selection
def _representative(lam: np.ndarray, order: np.ndarray) -> tuple[complex, int]:
    med = complex(np.median(lam.real), np.median(lam.imag))
    return med, int(np.unique(order).size)


def select_poles(
    diagram: StabilisationDiagram,
    *,
    min_fraction: float = 0.3,
    tol_freq: float | None = None,
    tol_mac: float | None = None,
    zeta_max: float = 0.1,
) -> tuple[PoleCluster, ...]:
    """Physical pole candidates from a stabilisation diagram, without frequency hints.

    Parameters
    ----------
    diagram : StabilisationDiagram
    min_fraction : float
        A cluster is kept if its poles occur in at least this fraction of the
        diagram's orders.
    tol_freq : float, optional
        Relative frequency scale of the cluster distance (default: the
        diagram's frequency tolerance).
    tol_mac : float, optional
        MAC scale of the cluster distance (default: the diagram's).
    zeta_max : float
        Candidates must have ``0 < zeta < zeta_max`` (physical damping).

    Returns
    -------
    tuple of PoleCluster
        Sorted by frequency.

    Notes
    -----
    Candidates are the fully stable in-band poles.  The distance between two
    candidates is ``|f_i - f_j| / (tol_freq max(f_i, f_j)) + (1 - MAC_ij) / (1 - tol_mac)``
    (the MAC term only when the diagram has shapes); average-linkage
    hierarchical clustering is cut at distance 1, so two poles join when
    they are (on average) within the stability tolerances of each other.
    """
    if not 0 < min_fraction <= 1:
        raise IdentificationError(f"min_fraction must be in (0, 1], got {min_fraction}")
    tol_f = float(tol_freq if tol_freq is not None else diagram.tolerances.get("tol_freq", 0.005))
    tol_m = float(tol_mac if tol_mac is not None else diagram.tolerances.get("tol_mac", 0.98))
    z = diagram.zeta
    cand = np.flatnonzero(diagram.stable & diagram.in_band & (z > 0) & (z < zeta_max))
    n_orders = max(diagram.orders.size, 1)
    if cand.size == 0:
        log.warning("no stable poles in band %s Hz: nothing selected", diagram.band_hz)
        return ()
    if cand.size == 1:
        groups = [cand]
    else:
        f = diagram.freqs_hz[cand]
        d = np.abs(f[:, None] - f[None, :]) / (tol_f * np.maximum(f[:, None], f[None, :]))
        if diagram.shapes is not None and tol_m < 1:
            sh = diagram.shapes[cand]
            nrm = np.sum(np.abs(sh) ** 2, axis=1)
            g = np.abs(np.conj(sh) @ sh.T) ** 2
            with np.errstate(invalid="ignore", divide="ignore"):
                macm = np.where(np.outer(nrm, nrm) > 0, g / np.outer(nrm, nrm), 0.0)
            d = d + (1 - np.clip(macm, 0, 1)) / (1 - tol_m)
        np.fill_diagonal(d, 0.0)
        d = 0.5 * (d + d.T)
        labels = hierarchy.fcluster(hierarchy.linkage(squareform(d, checks=False), method="average"), 1.0, "distance")
        groups = [cand[labels == k] for k in np.unique(labels)]
    out = []
    for g in groups:
        pole, k = _representative(diagram.poles[g], diagram.order[g])
        frac = k / n_orders
        if frac >= min_fraction:
            out.append(PoleCluster(pole=pole, members=g, n_orders=k, fraction=frac))
        else:
            log.debug("cluster at %.4g Hz in %d/%d orders: dropped", abs(pole) / 2 / np.pi, k, n_orders)
    out.sort(key=lambda c: c.freq_hz)
    log.info(
        "pole selection: %d stable candidates -> %d clusters in >= %.0f%% of %d orders: %s Hz",
        cand.size, len(out), 100 * min_fraction, n_orders, ", ".join(f"{c.freq_hz:.2f}" for c in out),
    )
    return tuple(out)


def select_poles_at(
    diagram: StabilisationDiagram,
    freqs_hz: Sequence[float],
    *,
    tol: float = 0.02,
    stable_only: bool = True,
) -> np.ndarray:
    """Manual selection: the pole nearest each requested frequency, as a median over the orders.

    Parameters
    ----------
    diagram : StabilisationDiagram
    freqs_hz : sequence of float
        Approximate natural frequencies [Hz].
    tol : float
        Relative search window around each frequency.
    stable_only : bool
        Use only fully stable poles (falls back to frequency-stable, then to
        all poles, when none is in the window).

    Returns
    -------
    ndarray complex (len(freqs_hz),)
        Physical poles.

    Raises
    ------
    IdentificationError
        If no pole of any order lies within ``tol`` of a requested frequency
        (the message names it).
    """
    fr = diagram.freqs_hz
    z = diagram.zeta
    out = []
    for f0 in np.atleast_1d(np.asarray(freqs_hz, float)):
        near = (np.abs(fr - f0) <= tol * f0) & (z > 0)
        masks = ([diagram.stable, diagram.stable_freq] if stable_only else []) + [np.ones_like(near)]
        idx = np.zeros(0, int)
        for mk in masks:
            idx = np.flatnonzero(near & mk)
            if idx.size:
                break
        if idx.size == 0:
            raise IdentificationError(
                f"no pole within {100 * tol:g} % of the requested {f0:g} Hz in the stabilisation diagram "
                f"(band {diagram.band_hz[0]:g}-{diagram.band_hz[1]:g} Hz)"
            )
        # per order the pole closest to f0, then the median over orders
        best = {}
        for i in idx:
            o = diagram.order[i]
            if o not in best or abs(fr[i] - f0) < abs(fr[best[o]] - f0):
                best[o] = i
        sel = np.array(list(best.values()))
        out.append(complex(np.median(diagram.poles[sel].real), np.median(diagram.poles[sel].imag)))
    return np.array(out, complex)


# ------------------------------------------------------------------------- pruning
@dataclass
class _Fit:
    """Mutable working state of the pruning loop (internal)."""

    modes: np.ndarray
    extra: np.ndarray
    support: np.ndarray
    refined: RefinedPoles | None = None
    split_born: np.ndarray | None = None  # bool per mode: created by a mode split


def _refit(frf, st: _Fit, band, residuals, refine, max_nfev) -> None:
    if refine and (st.modes.size or st.extra.size):
        st.refined = refine_poles(
            frf, st.modes, band_hz=band, residuals=residuals, residual_poles=st.extra, max_nfev=max_nfev
        )
        st.modes, st.extra = st.refined.poles, st.refined.residual_poles


def _pole_sane(p: complex) -> bool:
    return bool(np.isfinite(p) and p.real < 0 and p.imag > 0)


def _n_good(poles: np.ndarray, band) -> int:
    return sum(_pole_sane(p) and band[0] <= p.imag / (2 * np.pi) <= band[1] for p in poles)


def _out_of_band(p: complex, band) -> bool:
    """A pseudo-mode pole: stable, damping below 0.5, below the band or above it (up to ten times its upper edge)."""
    fd = p.imag / (2 * np.pi)
    return bool(_pole_sane(p) and -p.real < 0.5 * abs(p) and (0 < fd < band[0] or band[1] < fd < 10 * band[1]))


def _search_residual_poles(frf, st: _Fit, *, band, residuals, significance, min_gain, n_par, max_per_side,
                           max_nfev) -> None:
    """Add out-of-band pseudo-modes (upper side, then lower side) while each one is worth it.

    A trial pseudo-mode starts just outside the band edge and is optimised
    alone (the other poles fixed), then together with all poles; it is kept
    if it stays on its side of the band, is stable, leaves the modes in the
    band, and lowers the residual both significantly (``significance`` noise
    variances per parameter) and substantially (by ``min_gain`` of the
    residual: tiny systematic errors of very strong modes must not pull in
    pseudo-modes).
    """
    lo, hi = band
    for side in ("upper", "lower"):
        if side == "lower" and lo <= 0:
            continue
        for _ in range(max_per_side):
            f0, z0 = (1.1 * hi, 0.02) if side == "upper" else (0.5 * lo, 0.05)
            init = 2 * np.pi * f0 * complex(-z0, np.sqrt(1 - z0**2))
            base_cost = st.refined.cost if st.refined is not None else np.inf
            free = np.zeros(st.modes.size + st.extra.size + 1, bool)
            free[-1] = True
            trial = refine_poles(
                frf, st.modes, band_hz=band, residuals=residuals, residual_poles=np.append(st.extra, init),
                free=free, max_nfev=min(max_nfev, _TRIAL_NFEV),
            )
            promising = (
                np.isfinite(trial.residual_poles[-1]) and trial.residual_poles[-1].imag > 0
                and 1.0 - trial.cost / base_cost >= min_gain and trial.residual_delta_cost[-1] / n_par >= significance
            )
            if promising:
                # let every pole adapt to the new term (the in-band poles were biased by what it absorbs)
                trial = refine_poles(
                    frf, trial.poles, band_hz=band, residuals=residuals, residual_poles=trial.residual_poles,
                    max_nfev=max_nfev,
                )
            new = trial.residual_poles[-1]
            on_side = _out_of_band(new, band)
            sig = trial.residual_delta_cost[-1] / n_par
            gain = 1.0 - trial.cost / base_cost
            # the new term must not cost a mode: count the sane in-band poles before and after
            modes_ok = _n_good(trial.poles, band) >= _n_good(st.modes, band)
            extras_ok = all(_out_of_band(p, band) for p in trial.residual_poles)
            if on_side and extras_ok and modes_ok and sig >= significance and gain >= min_gain:
                st.modes, st.extra, st.refined = trial.poles, trial.residual_poles, trial
                log.info("%s residual pole at %.4g Hz (zeta %.3g) added: residual -%.1f%%", side,
                         abs(new) / 2 / np.pi, -new.real / abs(new), 100 * gain)
            else:
                log.debug("%s residual pole trial at %.4g Hz, zeta %.3g not kept (gain %.3g, significance %.3g)",
                          side, abs(new) / 2 / np.pi, -new.real / abs(new), gain, sig)
                break


def _search_splits(frf, st: _Fit, *, band, residuals, significance, min_gain, n_par, tol_freq, max_nfev) -> bool:
    """Try to split every mode into two close poles; keep a split that is significant and substantial.

    Modes closer than the resolution of the stabilisation diagram (e.g. a
    flexural pair split by a suspension, 0.02 % apart) come out of LSCE as one
    pole whose shape mixes both.  For each mode, two poles ``lambda (1 -+ 2e-4)``
    replace it and are optimised (the other poles fixed); the split is kept if
    both poles stay distinct, stable and within ``tol_freq`` of the original
    frequency (a pole that runs off to another frequency is not a split), each is significant
    (``significance`` noise variances per parameter) and the pair lowers the
    residual by at least ``min_gain``.  Returns True if any split was kept.
    """
    lo, hi = band
    changed = False
    k = 0
    while k < st.modes.size:
        p = st.modes[k]
        base = st.refined.cost if st.refined is not None else np.inf
        modes = np.concatenate([st.modes[:k], [p * (1 - 2e-4), p * (1 + 2e-4)], st.modes[k + 1:]])
        free = np.zeros(modes.size + st.extra.size, bool)
        free[[k, k + 1]] = True
        trial = refine_poles(frf, modes, band_hz=band, residuals=residuals, residual_poles=st.extra, free=free,
                             max_nfev=min(max_nfev, _TRIAL_NFEV))
        a, b = trial.poles[k], trial.poles[k + 1]
        ok = (
            _pole_sane(a) and _pole_sane(b)
            and all(lo <= x.imag / (2 * np.pi) <= hi for x in (a, b))
            and all(abs(abs(x) - abs(p)) <= tol_freq * abs(p) for x in (a, b))
            and abs(a - b) > 1e-6 * abs(p)
            and min(trial.delta_cost[k], trial.delta_cost[k + 1]) / n_par >= significance
            and 1.0 - trial.cost / base >= min_gain
        )
        if ok:
            log.info("mode at %.4f Hz split into %.4f and %.4f Hz (residual -%.1f%%)", abs(p) / 2 / np.pi,
                     abs(a) / 2 / np.pi, abs(b) / 2 / np.pi, 100 * (1.0 - trial.cost / base))
            st.modes = trial.poles
            st.support = np.concatenate([st.support[:k], [st.support[k]] * 2, st.support[k + 1:]])
            st.split_born = np.concatenate([st.split_born[:k], [True, True], st.split_born[k + 1:]])
            st.refined = trial
            changed = True
            k += 2
        else:
            k += 1
    return changed


def _prune(
    frf: FrequencyResponse,
    poles: np.ndarray,
    support: np.ndarray,
    *,
    band: tuple[float, float],
    residuals: tuple[int, ...],
    refine: bool,
    zeta_max: float,
    mpc_min: float,
    significance: float,
    aux_significance: float,
    residual_poles: int,
    min_gain: float,
    split: bool,
    tol_freq: float,
    max_nfev: int,
) -> tuple[_Fit, list[RejectedPole]]:
    rejected: list[RejectedPole] = []
    lo, hi = band
    n_par = 2 * frf.n_out + 2  # real parameters a mode carries (complex residues + pole)
    st = _Fit(modes=np.asarray(poles, complex), extra=np.zeros(0, complex), support=np.asarray(support, float),
              split_born=np.zeros(np.size(poles), bool))
    searched = not (refine and residual_poles > 0)
    split_done = not (refine and split)
    for _ in range(4 * max(poles.size, 1) + 8):
        _refit(frf, st, band, residuals, refine, max_nfev)
        new = st.modes
        fn = np.abs(new) / (2 * np.pi)
        zn = -new.real / np.abs(new)
        fd = new.imag / (2 * np.pi)
        bad = np.zeros(new.size, bool)
        reason = [""] * new.size
        for i in range(new.size):
            if not np.isfinite(new[i]) or zn[i] <= 0:
                bad[i], reason[i] = True, "negative damping"
            elif zn[i] >= zeta_max:
                bad[i], reason[i] = True, f"damping above {zeta_max:g}"
            elif not lo <= fd[i] <= hi:
                bad[i], reason[i] = True, "outside the band after refinement"
        order = np.argsort(fn)
        for a_, b_ in zip(order[:-1], order[1:]):
            if not bad[a_] and not bad[b_] and abs(new[a_] - new[b_]) < 1e-6 * abs(new[a_]):
                drop = b_ if st.support[b_] <= st.support[a_] else a_
                bad[drop], reason[drop] = True, "duplicate of another pole"
        # residual poles that wandered into the band or became unstable are dropped
        ex_ok = np.array([_pole_sane(p) and _out_of_band(p, band) for p in st.extra], bool)
        if not ex_ok.all():
            for p in st.extra[~ex_ok]:
                rejected.append(RejectedPole(float(abs(p) / 2 / np.pi), float(-p.real / abs(p)),
                                             "residual pole left the out-of-band region"))
            st.extra = st.extra[ex_ok]
            if not bad.any():
                continue
        if not searched and all(np.isfinite(p) and p.imag > 0 for p in st.modes):
            # first pass: out-of-band terms before judging the modes they bias
            searched = True
            n_before = st.extra.size
            _search_residual_poles(frf, st, band=band, residuals=residuals, significance=aux_significance,
                                   min_gain=min_gain, n_par=n_par, max_per_side=residual_poles,
                                   max_nfev=max_nfev)
            if st.extra.size > n_before:
                continue
        if not bad.any() and new.size:
            fit = lsfd(frf, new, band_hz=band, residuals=residuals, residual_poles=st.extra)
            # poles from an accepted split are exempt: two poles 0.01 % apart have ill-determined,
            # correlated residues (low MPC) although both are significant
            low = (fit.mpc < mpc_min) & ~st.split_born
            if low.any():
                i = int(np.argmin(np.where(low, fit.mpc, np.inf)))
                bad[i], reason[i] = True, f"MPC {fit.mpc[i]:.2f} below {mpc_min:g}"
        if not bad.any() and st.refined is not None and significance > 0 and new.size:
            sig = st.refined.delta_cost / n_par
            if np.any(sig < significance):
                i = int(np.argmin(sig))
                bad[i], reason[i] = True, (
                    f"removing it worsens the synthesis by only {st.refined.delta_cost[i]:.3g} noise variances "
                    f"(< {significance:g} x {n_par} parameters)"
                )
        if not bad.any() and not split_done:
            split_done = True
            if _search_splits(frf, st, band=band, residuals=residuals, significance=aux_significance, min_gain=min_gain,
                              n_par=n_par, tol_freq=tol_freq, max_nfev=max_nfev):
                continue
        if not bad.any():
            return st, rejected
        for i in np.flatnonzero(bad):
            rejected.append(RejectedPole(float(fn[i]), float(zn[i]), reason[i]))
            log.info("rejected pole %.4f Hz (zeta %.3g): %s", fn[i], zn[i], reason[i])
        keep = ~bad
        fallback = poles[keep] if poles.size == new.size else new[keep]
        init = np.where([_pole_sane(p) for p in new[keep]], new[keep], fallback)
        st.modes, st.support, st.split_born = init, st.support[keep], st.split_born[keep]
        poles = st.modes
    log.warning("pole pruning did not settle; returning the current poles")
    return st, rejected


# ------------------------------------------------------------------------- driver
def _unit_scale(shapes: np.ndarray) -> np.ndarray:
    out = shapes.copy()
    for r in range(shapes.shape[1]):
        k = int(np.argmax(np.abs(shapes[:, r])))
        if shapes[k, r] != 0:
            out[:, r] = shapes[:, r] / shapes[k, r]
    return out


def _channels_for(frf: FrequencyResponse) -> pd.DataFrame:
    if frf.channels is not None:
        return frf.channels.reset_index(drop=True)
    nan = np.full(frf.n_out, np.nan)
    return pd.DataFrame(
        {"node": nan, "name": list(frf.outputs), "x": nan, "y": nan, "z": nan, "dx": nan, "dy": nan, "dz": nan}
    )


@one_blas_thread
def identify(
    frf: FrequencyResponse,
    band_hz: tuple[float, float] | None = (10.0, 500.0),
    max_order: int = 100,
    *,
    freqs_hz: Sequence[float] | None = None,
    min_fraction: float = 0.3,
    tol_freq: float = 0.005,
    tol_damping: float = 0.05,
    tol_mac: float = 0.98,
    zeta_max: float = 0.1,
    mpc_min: float = 0.5,
    significance: float = 4.0,
    refine: bool = True,
    residuals: tuple[int, ...] = DEFAULT_RESIDUALS,
    residual_poles: int = 2,
    min_gain: float = 0.05,
    split: bool = True,
    scaling: str = "modal_constant",
    driving_point: str | None = None,
    setup: str | None = None,
    n_samples: int | None = None,
    max_nfev: int = 100,
) -> Identification:
    """Identify the modes of a single-input FRF set (LSCE -> stabilisation -> selection -> refinement -> LSFD).

    Parameters
    ----------
    frf : FrequencyResponse
        SIMO FRFs (accelerance, mobility or receptance; thesis eq. 3.2 H1),
        equally spaced lines; ``exp_window_decay`` is corrected for.
    band_hz : (float, float) or None
        Identification band (``None``: all lines).
    max_order : int
        Largest LSCE order (number of poles in the band), 1 to :data:`MAX_ORDER`.
    freqs_hz : sequence of float, optional
        Manual selection: approximate frequencies of the wanted modes
        (:func:`select_poles_at`); default automatic (:func:`select_poles`).
        The selected modes are kept unless unphysical (no significance/MPC
        pruning, no splits).  Select every mode of the band (or narrow the
        band): a mode left out of the model biases the refined poles of its
        neighbours.
    min_fraction : float
        Automatic selection: minimum fraction of orders a pole cluster must span.
    tol_freq, tol_damping, tol_mac : float
        Stabilisation tolerances (relative frequency, relative damping, MAC).
    zeta_max : float
        Largest admissible physical damping ratio.
    mpc_min : float
        Poles whose modal constants have a lower MPC are computational.
    significance : float
        A pole is kept only if removing it increases the residual by more than
        ``significance`` noise variances per real parameter it carries
        (``2 n_out + 2``); ``0`` disables the test.
    refine : bool
        Refine the selected poles by nonlinear least squares (recommended).
    residuals : tuple of int
        Residual powers of ``s`` in receptance form (see :mod:`ema.lsfd`);
        default lower (mass line) and upper (stiffness) residual.
    residual_poles : int
        Up to this many out-of-band pseudo-modes per side (above and below
        the band) are added to the model while they are significant (same
        criterion as ``significance``); they absorb modes just outside the
        band that the constant residuals cannot (``0`` disables).  They are
        returned in ``fit.residual_poles``, not as modes.
    min_gain : float
        A pseudo-mode or a mode split must also lower the residual by at
        least this fraction (on top of the ``significance`` test).
    split : bool
        Try to split every mode into two close poles (modes closer than the
        diagram resolves, e.g. a flexural pair separated by a suspension)
        and keep significant, substantial splits.
    scaling : {"modal_constant", "unit", "mass"}
        Shapes in the returned ModeSet: the modal constants ``A_jr`` (= ``c_jr
        b_r``, see :mod:`ema.lsfd`), unit largest component, or mass-normalised
        through ``driving_point`` (``A_jr / sqrt(A_kr)``).
    driving_point : str, optional
        Output label co-located with the force (needed for ``scaling="mass"``).
    setup : str, optional
        Setup name recorded per mode (default: the ``setup`` column of
        ``frf.channels`` if unique, else ``""``).
    n_samples : int, optional
        Zoomed impulse-response samples per channel for LSCE.
    max_nfev : int
        Iteration budget of each refinement.

    Returns
    -------
    Identification

    Raises
    ------
    IdentificationError
        Bad FRF or parameters (message names the channel/parameter), or a
        manual frequency without a nearby pole.
    """
    timings: dict[str, float] = {}
    if scaling not in ("modal_constant", "unit", "mass"):
        raise IdentificationError(f"scaling must be 'modal_constant', 'unit' or 'mass', got {scaling!r}")
    if scaling == "mass" and driving_point is None:
        raise IdentificationError("scaling='mass' needs driving_point=<output label co-located with the force>")
    if driving_point is not None and driving_point not in frf.outputs:
        raise IdentificationError(f"driving_point {driving_point!r} is not an output; outputs: {list(frf.outputs)}")
    if isinstance(max_order, bool) or not isinstance(max_order, (int, np.integer)) or not 1 <= max_order <= MAX_ORDER:
        raise IdentificationError(f"max_order must be an integer in [1, {MAX_ORDER}], got {max_order!r}")
    t0 = time.perf_counter()
    sub = band_lines(frf, band_hz)
    band = (float(sub.freqs_hz[0]), float(sub.freqs_hz[-1]))
    weights = channel_weights(sub)
    # poles come from the weighted FRFs (no channel can swamp the least squares); residues per channel from
    # the FRFs as measured (LSFD solves each channel on its own, so its weight does not matter there)
    fit_frf = sub if np.all(weights == 1) else sub.with_history(
        "channel weights " + ", ".join(f"{o}: {w:.3g}" for o, w in zip(sub.outputs, weights) if w < 1),
        data=sub.data * weights[:, None, None])
    sweep: PoleSweep = lsce(fit_frf, max_order=max_order, n_samples=n_samples)
    timings["lsce"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    diagram = stabilisation_diagram(sweep, fit_frf, tol_freq=tol_freq, tol_damping=tol_damping, tol_mac=tol_mac)
    timings["stabilisation"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    if freqs_hz is None:
        clusters = select_poles(diagram, min_fraction=min_fraction, zeta_max=zeta_max)
        poles0 = np.array([c.pole for c in clusters], complex)
        support = np.array([c.fraction for c in clusters], float)
        sig = significance
        mpcm = mpc_min
    else:
        clusters = ()
        poles0 = select_poles_at(diagram, freqs_hz, tol=max(4 * tol_freq, 0.02))
        support = np.ones(poles0.size)
        sig = 0.0  # the user asked for these modes: keep them unless unphysical
        mpcm = 0.0
    timings["selection"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    st, rejected = _prune(
        fit_frf, poles0, support, band=band, residuals=tuple(residuals), refine=refine, zeta_max=zeta_max,
        mpc_min=mpcm, significance=sig, aux_significance=significance, residual_poles=residual_poles,
        min_gain=min_gain,
        split=split and freqs_hz is None, tol_freq=tol_freq, max_nfev=max_nfev,
    )
    poles, support, refined = st.modes, st.support, st.refined
    order = np.argsort(np.abs(poles))
    poles, support = poles[order], support[order]
    if refined is not None and refined.poles.size:
        ro = np.argsort(np.abs(refined.poles))
        refined = RefinedPoles(
            poles=refined.poles[ro], initial=refined.initial[ro], cost=refined.cost, noise_var=refined.noise_var,
            freq_std_hz=refined.freq_std_hz[ro], zeta_std=refined.zeta_std[ro], delta_cost=refined.delta_cost[ro],
            iterations=refined.iterations, residual_poles=refined.residual_poles,
            residual_delta_cost=refined.residual_delta_cost,
        )
    timings["refinement"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    fit = lsfd(sub, poles, residuals=tuple(residuals), residual_poles=st.extra)
    timings["lsfd"] = time.perf_counter() - t0
    A = fit.modal_constants
    if scaling == "unit":
        shapes = _unit_scale(A)
    elif scaling == "mass":
        k = frf.outputs.index(driving_point)
        with np.errstate(invalid="ignore", divide="ignore"):
            shapes = A / np.sqrt(A[k][None, :])
    else:
        shapes = A
    if setup is None:
        setup = ""
        if frf.channels is not None and "setup" in frf.channels.columns:
            vals = pd.unique(frf.channels["setup"].dropna())
            if len(vals) == 1:
                setup = str(vals[0])
    f_id = np.abs(poles) / (2 * np.pi)
    z_id = -poles.real / np.abs(poles) if poles.size else np.zeros(0)
    step = (
        f"identify: LSCE orders 1-{max_order}, band {band[0]:g}-{band[1]:g} Hz, "
        f"{'manual' if freqs_hz is not None else 'automatic'} selection, {'refined, ' if refine else ''}"
        f"LSFD residuals {tuple(residuals)}, window decay {frf.exp_window_decay:g} 1/s corrected"
    )
    modes = ModeSet(
        freqs_hz=f_id,
        zeta=z_id,
        shapes=shapes,
        dofs=sub.outputs,
        channels=_channels_for(sub),
        mpc=fit.mpc,
        mpd=fit.mpd,
        setup=tuple([setup] * poles.size),
        scaling=scaling,
        source=f"ema.identify (LSCE + LSFD) of {frf!r}",
        history=tuple(frf.history) + (step,),
    )
    diag = pd.DataFrame(
        {
            "f_hz": f_id,
            "zeta": z_id,
            "f_std_hz": refined.freq_std_hz if refined is not None and poles.size else np.full(poles.size, np.nan),
            "zeta_std": refined.zeta_std if refined is not None and poles.size else np.full(poles.size, np.nan),
            "mpc": fit.mpc,
            "mpd": fit.mpd,
            "mcf": mcf(fit.modal_constants) if poles.size else np.zeros(0),
            "significance": refined.delta_cost if refined is not None and poles.size else np.full(poles.size, np.nan),
            "support": support,
        }
    )
    log.info(
        "identified %d modes in %.4g-%.4g Hz: %s; synthesis error median %.1f dB (%.2f s)",
        poles.size, band[0], band[1], ", ".join(f"{x:.2f}" for x in f_id),
        float(np.median(fit.error_db)) if fit.error_db.size else np.nan, sum(timings.values()),
    )
    return Identification(
        modes=modes,
        diagram=diagram,
        clusters=tuple(clusters),
        refined=refined,
        fit=fit,
        rejected=tuple(rejected),
        diagnostics=diag,
        timings=timings,
        weights={o: float(w) for o, w in zip(sub.outputs, weights) if w < 1},
    )
