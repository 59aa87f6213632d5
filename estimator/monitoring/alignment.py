"""Alignment of runs along chainage: to the line's fixed features and to a reference run (thesis §4.3.3).

Runs of the same stretch disagree in position: the odometer integrates the
encoder speed with the nominal wheel radius (a scale error of a few tenths of
a per cent), the train control's initial position is only as good as the last
stop's (metre-scale start offsets), and the wheelset's place along the bogie
comes from a wheelbase. The single-run estimator already pins the chainage at
every balise passage (:func:`estimator.spatial.odometry_track`: offset and
scale between consecutive balises); what is left is corrected here from the
rails themselves.

**Feature signal.** The estimated rail roughness of both rails,
zero-phase band-filtered (EN 13231-3's filter, :func:`estimator.standards.en13231.band_filter`)
to ``align_band_mm`` (default 20–1000 mm: the broadband roughness, weld dips
and collars, the switch's dips — what every run of a day sees identically).
For the wide search (below) its spectrum's **tonal lines are clipped**: any
line more than ``TONE_CLIP`` (2) times the median magnitude of its
one-sixth octave is scaled down to that level (a real, positive gain: zero
phase, positions unchanged). A corrugation is nearly periodic; left alone,
its wavelength dominates the correlation, which then peaks at every multiple
of it and locks windows a wavelength off. Clipped, the broadband roughness
the runs share decides the coarse lag (the generalised cross-correlation
idea of weighting frequencies, kept to the few lines that stand out). The
narrow search (±15 mm or so, less than half the shortest corrugation
wavelength of the band: one peak) keeps the corrugation, which is often
the best-estimated part of the signal.

**Local lags.** The run is cut into windows of ``align_window_m`` every
``align_step_m``; each window is cross-correlated with the target (a
reference run's feature signal, or the line's feature template) over lags
``±align_max_lag_m``; the normalised correlation (both rails summed)

    ρ(ℓ) = Σ_rails Σ_x s(x) r(x + ℓ) / sqrt(Σ_rails Σ_x s(x)² · Σ_rails Σ_x r(x + ℓ)²)

peaks at the window's misplacement ``ℓ`` (the run reads chainage ``x`` where
the target reads ``x + ℓ``), refined to a fraction of a sample by a parabola
through the peak and its neighbours. Two passes: a wide search in the
long-wave band ``align_coarse_band_mm`` (a broad, unambiguous peak; the
signals decimated to a quarter of the band's shortest wavelength), then,
on the run re-gridded by the first pass's fit (so that inside a window the
remaining misplacement is constant), a narrow search in the fine band
(a sharp peak: sub-millimetre precision; the narrow range, four times the
first pass's residual and at least 15 mm, keeps a corrugation's periodic
side peaks out).

**Piecewise offset and scale.** The correction ``δ(x)`` is continuous and
linear between knots: the line's balises inside the run (where the odometer
was reset) plus as many more as keep every piece at most ``align_piece_m``
long; knots with fewer than three windows on either side are dropped. It is
fitted to the windows' lags by weighted least squares (weight ``ρ²``) with
iterative rejection of windows more than ``max(3 × 1.4826 MAD, 2 mm)`` from
the fit (a window locked on a wrong peak). A piece ``[a, b]`` then has an
offset ``δ(a)`` and a scale ``1 + (δ(b) − δ(a))/(b − a)``; the aligned
chainage is ``x + δ(x)``.

**Residual and rejection.** The residual is the RMS distance of the kept
windows' lags from the fit [mm]. A run is rejected — with the reason — when
fewer than ``align_min_windows`` windows correlate above
``align_min_correlation`` (another track, a run mostly masked, a stretch the
target does not cover), when the residual exceeds ``align_max_residual_mm``,
or when a piece's scale is further than ``align_max_scale_error`` from 1.

**Reference and line.** :func:`align_to_line` aligns a profile to the line's
feature template: a dip of ``weld_length_m`` (cosine) at every weld of
``line.json`` (on its rail when the file says which) and at a switch's
crossing nose when given, band-filtered like the run. A day's reference run is
aligned to the line (absolute chainage); every other run of the day to the
reference (:func:`align_profiles`), and the two corrections are composed
(:class:`Alignment`).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
import pandas as pd
from numpy.lib.stride_tricks import sliding_window_view
from scipy import fft as sfft
from scipy import signal as ssignal

from estimator.monitoring.config import MonitoringConfig
from estimator.standards.en13231 import band_filter

__all__ = ["ShiftFit", "AlignmentStage", "Alignment", "FeatureProfile", "feature_profile", "local_lags",
           "fit_shift", "compose", "clip_tones", "align_profiles", "line_template", "align_to_line", "knots_for"]

log = logging.getLogger("estimator")

#: smallest outlier threshold of the robust fit [m] (below it, lags are kept whatever the MAD)
MIN_OUTLIER_M = 0.002
#: windows must hold at least this share of valid samples to be correlated
MIN_VALID_SHARE = 0.6
#: a feature spectrum's line above this many times its one-sixth-octave median is clipped to it
TONE_CLIP = 2.0
TONE_OCTAVE_FRACTION = 6


# --------------------------------------------------------------------------- the correction
@dataclass(frozen=True, eq=False)
class ShiftFit:
    """A continuous piecewise-linear chainage correction ``δ(x)`` (linear extrapolation beyond the knots)."""

    knots_m: np.ndarray
    shift_m: np.ndarray

    def shift(self, x) -> np.ndarray:
        """``δ(x)`` [m]."""
        x = np.asarray(x, float)
        k, d = self.knots_m, self.shift_m
        if k.size == 1:
            return np.full_like(x, d[0])
        out = np.interp(x, k, d)
        lo, hi = x < k[0], x > k[-1]
        out[lo] = d[0] + (x[lo] - k[0]) * (d[1] - d[0]) / (k[1] - k[0])
        out[hi] = d[-1] + (x[hi] - k[-1]) * (d[-1] - d[-2]) / (k[-1] - k[-2])
        return out

    def pieces(self) -> pd.DataFrame:
        """One row per piece: ``from_m, to_m, offset_m`` (δ at its start) and ``scale`` (``1 + dδ/dx``)."""
        k, d = self.knots_m, self.shift_m
        if k.size == 1:
            return pd.DataFrame({"from_m": [-math.inf], "to_m": [math.inf], "offset_m": [float(d[0])], "scale": [1.0]})
        return pd.DataFrame({"from_m": k[:-1], "to_m": k[1:], "offset_m": d[:-1],
                             "scale": 1.0 + np.diff(d) / np.diff(k)})

    @staticmethod
    def identity() -> "ShiftFit":
        return ShiftFit(np.array([0.0]), np.array([0.0]))

    @staticmethod
    def from_pieces(pieces: pd.DataFrame) -> "ShiftFit":
        """The fit back from its :meth:`pieces` (e.g. one run, wheelset and stage of the store's ``alignment``)."""
        p = pieces.sort_values("from_m")
        a, b = p["from_m"].to_numpy(float), p["to_m"].to_numpy(float)
        off, sc = p["offset_m"].to_numpy(float), p["scale"].to_numpy(float)
        if not np.isfinite(a[0]):
            return ShiftFit(np.array([0.0]), off[:1].copy())
        return ShiftFit(np.append(a, b[-1]), np.append(off, off[-1] + (sc[-1] - 1.0) * (b[-1] - a[-1])))


@dataclass(frozen=True, eq=False)
class AlignmentStage:
    """One alignment: a run's profile against one target (a reference run, or the line's features).

    Attributes
    ----------
    target : str
        ``reference <run id>`` or ``line features``.
    fit : ShiftFit
    windows : pandas.DataFrame
        ``centre_m, lag_m, correlation, kept`` of every window correlated.
    residual_mm : float
        RMS distance of the kept windows' lags from the fit.
    accepted : bool
    reason : str
        Why the stage was rejected (empty when accepted).
    """

    target: str
    fit: ShiftFit
    windows: pd.DataFrame
    residual_mm: float
    accepted: bool
    reason: str = ""

    def pieces(self) -> pd.DataFrame:
        return self.fit.pieces().assign(target=self.target)


@dataclass(frozen=True, eq=False)
class Alignment:
    """The chainage correction of one run's wheelset: stages applied in order (run → reference → line)."""

    run_id: str
    wheelset: int
    stages: tuple[AlignmentStage, ...] = ()

    @property
    def accepted(self) -> bool:
        return all(s.accepted for s in self.stages)

    @property
    def reason(self) -> str:
        return "; ".join(f"{s.target}: {s.reason}" for s in self.stages if not s.accepted)

    @property
    def residual_mm(self) -> float:
        """Root-sum-square of the stages' residuals (independent errors)."""
        r = [s.residual_mm for s in self.stages if np.isfinite(s.residual_mm)]
        return float(math.sqrt(sum(v * v for v in r))) if r else math.nan

    def apply(self, x) -> np.ndarray:
        """Aligned chainage of points the run places at ``x``."""
        y = np.asarray(x, float)
        for s in self.stages:
            y = y + s.fit.shift(y)
        return y

    def table(self) -> pd.DataFrame:
        """Pieces of every stage with the stage's residual and verdict."""
        rows = []
        for i, s in enumerate(self.stages):
            p = s.pieces().assign(stage=i, residual_mm=s.residual_mm, accepted=s.accepted, reason=s.reason,
                                  windows_kept=int(s.windows["kept"].sum()) if len(s.windows) else 0,
                                  windows=len(s.windows))
            rows.append(p)
        cols = ["stage", "target", "from_m", "to_m", "offset_m", "scale", "residual_mm", "windows_kept", "windows",
                "accepted", "reason"]
        if not rows:
            return pd.DataFrame(columns=cols)
        return pd.concat(rows, ignore_index=True)[cols].assign(run_id=self.run_id, wheelset=self.wheelset)

    def then(self, stage: AlignmentStage) -> "Alignment":
        return Alignment(self.run_id, self.wheelset, self.stages + (stage,))


# --------------------------------------------------------------------------- feature signals
@dataclass(frozen=True, eq=False)
class FeatureProfile:
    """A band-filtered feature signal on a uniform grid: ``x0 + dx·j``, rows per rail (NaN = masked)."""

    x0: float
    dx: float
    rails: tuple[str, ...]
    values: np.ndarray  # (n_rails, M)
    label: str = ""
    memo: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def x(self) -> np.ndarray:
        if "x" not in self.memo:
            self.memo["x"] = self.x0 + self.dx * np.arange(self.values.shape[1])
        return self.memo["x"]

    def __getstate__(self):  # the memo is not shipped to Dask workers
        d = dict(self.__dict__)
        d["memo"] = {}
        return d

    def __setstate__(self, d):
        self.__dict__.update(d)

    def rows(self, rails: Sequence[str]) -> np.ndarray:
        return np.stack([self.values[self.rails.index(r)] for r in rails])

    def filtered(self, band_mm: tuple[float, float]) -> "FeatureProfile":
        return FeatureProfile(self.x0, self.dx, self.rails, band_filter(self.values, self.dx, band_mm), self.label)

    def coarse(self, band_mm: tuple[float, float], clip: bool = True) -> "FeatureProfile":
        """Tonal lines clipped (:func:`clip_tones`; unless ``clip`` is False), filtered to a long-wave band and
        decimated to a quarter of its shortest wavelength (memoised): the wide search's signal (module docstring)."""
        key = ("coarse", tuple(band_mm), clip)
        if key not in self.memo:
            v = self.values
            nfft = sfft.next_fast_len(v.shape[-1] + int(math.ceil(2 * band_mm[1] * 1e-3 / self.dx)))
            P = sfft.rfft(np.where(np.isfinite(v), v, 0.0), nfft, axis=-1)
            if clip:
                P = clip_tones(P, sfft.rfftfreq(nfft, self.dx))
            f = band_filter(v, self.dx, band_mm, spectrum=(P, nfft))
            q = max(1, int(band_mm[0] * 1e-3 / (4 * self.dx)))
            self.memo[key] = FeatureProfile(self.x0, self.dx * q, self.rails, f[:, ::q], self.label)
        return self.memo[key]

    def shifted(self, fit: ShiftFit) -> "FeatureProfile":
        """The profile re-gridded on aligned chainage (linear interpolation; the grid step is kept)."""
        xa = self.x + fit.shift(self.x)
        x0 = math.ceil(xa[0] / self.dx) * self.dx
        xn = x0 + self.dx * np.arange(int(math.floor((xa[-1] - x0) / self.dx)) + 1)
        vals = np.stack([np.interp(xn, xa, v, left=np.nan, right=np.nan) for v in self.values])
        return FeatureProfile(float(x0), self.dx, self.rails, vals, self.label)


def clip_tones(spectrum: np.ndarray, k: np.ndarray, factor: float = TONE_CLIP,
               fraction: int = TONE_OCTAVE_FRACTION) -> np.ndarray:
    """Spectral lines above ``factor`` × the median magnitude of their ``1/fraction`` octave scaled down to it.

    Parameters
    ----------
    spectrum : ndarray (..., K)
        One-sided spectra (rows: rails) at the wavenumbers ``k`` [1/m] (``k[0] = 0``).
    k : ndarray (K,)

    Returns
    -------
    ndarray
        The spectra times a real gain in (0, 1] (zero phase: positions along chainage unchanged).
    """
    P = np.atleast_2d(spectrum)
    if k.size < 3:
        return np.array(spectrum)
    mag = np.abs(P)
    n_oct = math.log2(k[-1] / k[1])
    edges = k[1] * 2.0 ** (np.arange(0.0, n_oct + 1.0 / fraction, 1.0 / fraction))
    bounds = np.searchsorted(k, edges, side="left")
    bounds = np.unique(np.concatenate([[1], bounds, [k.size]]))
    env = np.empty_like(mag)
    env[..., 0] = mag[..., 0]
    for a, b in zip(bounds[:-1], bounds[1:]):
        env[..., a:b] = np.median(mag[..., a:b], axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        gain = np.where(mag > factor * env, factor * env / mag, 1.0)
    return (P * gain).reshape(np.shape(spectrum))


def feature_profile(x: np.ndarray, profile: np.ndarray, rails: Sequence[str], band_mm: tuple[float, float],
                    label: str = "") -> FeatureProfile:
    """The feature signal of an estimated profile (rows per rail on the uniform grid ``x``), band-filtered."""
    x = np.asarray(x, float)
    if x.size < 2:
        return FeatureProfile(float(x[0]) if x.size else 0.0, 1.0, tuple(rails), np.full((len(rails), x.size), np.nan),
                              label)
    dx = float(np.median(np.diff(x)))
    vals = band_filter(np.atleast_2d(profile), dx, band_mm)
    return FeatureProfile(float(x[0]), dx, tuple(rails), vals, label)


# --------------------------------------------------------------------------- local lags
def _on_grid(fp: FeatureProfile, xg: np.ndarray, rails: Sequence[str]) -> np.ndarray:
    """``fp``'s rows read at the chainages ``xg`` (linear interpolation, NaN outside)."""
    vals = fp.rows(rails)
    return np.stack([np.interp(xg, fp.x, v, left=np.nan, right=np.nan) for v in vals])


#: searches at most this many lags either side are made with one matrix product per window, longer ones by FFT
DIRECT_LAGS = 64


def local_lags(run: FeatureProfile, target: FeatureProfile, centres: np.ndarray, window_m: float,
               max_lag_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Misplacement of each window of ``run`` against ``target`` (module docstring) and its correlation.

    Parameters
    ----------
    run, target : FeatureProfile
        Same rails in both (those present in both are used); the run is read on the target's grid.
    centres : ndarray
        Window centres in the run's chainage [m].
    window_m, max_lag_m : float

    Returns
    -------
    lags, correlation : ndarray
        ``lags[i]`` [m] such that the run's ``x`` is the target's ``x + lag``; NaN (and correlation 0) where the
        window holds too few valid samples or the peak lies on the edge of the search.
    """
    rails = [r for r in run.rails if r in target.rails]
    dx = target.dx
    n = int(round(window_m / dx))
    K = int(math.ceil(max_lag_m / dx))
    lags = np.full(centres.size, np.nan)
    corr = np.zeros(centres.size)
    if not rails or n < 8:
        return lags, corr
    traw = target.rows(rails)
    t_ok = np.isfinite(traw).all(axis=0)
    tvals = np.where(np.isfinite(traw), traw, 0.0)
    run_g = _on_grid(run, target.x, rails)  # the run on the target's grid, once
    e_all = np.concatenate([[0.0], np.cumsum((tvals * tvals).sum(axis=0))])
    c_all = np.concatenate([[0], np.cumsum(t_ok)])
    M = tvals.shape[1]
    for i, c in enumerate(centres):
        j0 = int(round((c - 0.5 * window_m - target.x0) / dx))  # target index of the window's first sample
        if j0 < 0 or j0 + n > M:
            continue
        s = run_g[:, j0:j0 + n]
        ok = np.isfinite(s).all(axis=0)
        if ok.mean() < MIN_VALID_SHARE:
            continue
        s = np.where(ok, s, 0.0)
        es = float((s * s).sum())
        a, b = max(j0 - K, 0), min(j0 + n + K, M)
        if b - a < n + 2 or es <= 0:
            continue
        r = tvals[:, a:b]
        if b - a - n <= 2 * DIRECT_LAGS:
            num = sum(sliding_window_view(r[k], n) @ s[k] for k in range(len(rails)))
        else:
            num = sum(ssignal.correlate(r[k], s[k], mode="valid", method="fft") for k in range(len(rails)))
        er = e_all[a + n:b + 1] - e_all[a:b - n + 1]
        cover = (c_all[a + n:b + 1] - c_all[a:b - n + 1]) / n
        with np.errstate(invalid="ignore", divide="ignore"):
            rho = np.where((er > 0) & (cover >= MIN_VALID_SHARE), num / np.sqrt(es * er), 0.0)
        if rho.size < 3:
            continue
        k = int(np.argmax(rho))
        if k == 0 or k == rho.size - 1:
            continue  # the peak lies on the edge of the search: no lag
        y0, y1, y2 = rho[k - 1], rho[k], rho[k + 1]
        den = y0 - 2 * y1 + y2
        off = 0.5 * (y0 - y2) / den if den < 0 else 0.0
        lags[i] = dx * (a + k + off - j0)
        corr[i] = float(y1)
    return lags, corr


# --------------------------------------------------------------------------- the fit
def knots_for(lo: float, hi: float, breakpoints: Sequence[float], piece_m: float) -> np.ndarray:
    """Knots of the piecewise fit on ``[lo, hi]``: the ends, the breakpoints inside, more so pieces ≤ ``piece_m``."""
    base = sorted({lo, hi} | {float(b) for b in breakpoints if lo < b < hi})
    out = [base[0]]
    for a, b in zip(base[:-1], base[1:]):
        m = max(1, int(math.ceil((b - a) / piece_m)))
        out += list(a + (b - a) * np.arange(1, m + 1) / m)
    return np.array(out)


def _hat_basis(x: np.ndarray, knots: np.ndarray) -> np.ndarray:
    """Linear B-spline (hat) basis on ``knots`` evaluated at ``x`` (linear extrapolation at the ends)."""
    if knots.size == 1:
        return np.ones((x.size, 1))
    B = np.zeros((x.size, knots.size))
    j = np.clip(np.searchsorted(knots, x, side="right") - 1, 0, knots.size - 2)
    u = (x - knots[j]) / (knots[j + 1] - knots[j])
    B[np.arange(x.size), j] = 1 - u
    B[np.arange(x.size), j + 1] = u
    return B


def _prune_knots(knots: np.ndarray, x: np.ndarray, min_per_piece: int = 3) -> np.ndarray:
    """Drop interior knots until every piece holds at least ``min_per_piece`` points (ends kept)."""
    k = list(knots)
    while len(k) > 2:
        counts = np.histogram(x, bins=k)[0]
        i = int(np.argmin(counts))
        if counts[i] >= min_per_piece:
            break
        # merge the poorest piece with its poorer neighbour by removing the knot between them
        if i == 0:
            del k[1]
        elif i == len(counts) - 1:
            del k[-2]
        else:
            del k[i if counts[i - 1] <= counts[i + 1] else i + 1]
    if len(k) == 2 and np.sum((x >= k[0]) & (x <= k[1])) < 2:
        return np.array([0.5 * (k[0] + k[1])])
    return np.array(k)


def fit_shift(centres: np.ndarray, lags: np.ndarray, weights: np.ndarray, knots: np.ndarray,
              max_iter: int = 10) -> tuple[ShiftFit, np.ndarray, float]:
    """Robust weighted least-squares piecewise-linear fit of ``lags`` at ``centres`` (module docstring).

    Returns
    -------
    fit, kept, residual_m : ShiftFit, ndarray of bool, float
    """
    ok = np.isfinite(lags) & (weights > 0)
    kept = ok.copy()
    fit = ShiftFit(np.array([0.0]), np.array([float(np.nanmedian(lags)) if ok.any() else 0.0]))
    if not ok.any():
        return fit, kept, math.nan
    for _ in range(max_iter):
        kn = _prune_knots(knots, centres[kept]) if kept.sum() >= 2 else np.array([float(np.mean(centres[kept]))])
        B = _hat_basis(centres[kept], kn)
        w = np.sqrt(weights[kept])
        coef, *_ = np.linalg.lstsq(B * w[:, None], lags[kept] * w, rcond=None)
        fit = ShiftFit(kn, coef)
        res = lags - fit.shift(centres)
        mad = 1.4826 * np.median(np.abs(res[kept] - np.median(res[kept])))
        new = ok & (np.abs(res) <= max(3 * mad, MIN_OUTLIER_M))
        if new.sum() < 2 or np.array_equal(new, kept):
            break
        kept = new
    res = lags[kept] - fit.shift(centres[kept])
    return fit, kept, float(np.sqrt(np.mean(res ** 2))) if kept.any() else math.nan


def compose(first: ShiftFit, second: ShiftFit) -> ShiftFit:
    """``δ(x) = δ₁(x) + δ₂(x + δ₁(x))``: the correction ``first`` followed by ``second``.

    Exact at the union of ``first``'s knots and the pre-images of ``second``'s
    (both are linear between them); a pre-image within 5 cm of one of
    ``first``'s knots is merged into it (a sub-micrometre approximation for
    pieces tens of metres long with scales within a few per cent of 1).
    """
    k2 = second.knots_m
    # preimage of second's knots under x -> x + δ1(x) (monotone: |dδ1/dx| < 1); two fixed-point steps suffice
    pre = k2 - first.shift(k2)
    pre = k2 - first.shift(pre)
    # a pre-image within 5 cm of one of first's knots is that knot (pieces are tens of metres long)
    near = np.min(np.abs(pre[:, None] - first.knots_m[None, :]), axis=1) < 0.05
    k = np.unique(np.concatenate([first.knots_m, pre[~near]]))
    d = first.shift(k)
    return ShiftFit(k, d + second.shift(k + d))


def _centres(fp: FeatureProfile, target: FeatureProfile, cfg: MonitoringConfig) -> np.ndarray:
    x = fp.x
    valid = np.isfinite(fp.values).all(axis=0)
    if not valid.any():
        return np.zeros(0)
    lo, hi = float(x[valid][0]), float(x[valid][-1])
    lo = max(lo, target.x0 - cfg.align_max_lag_m) + 0.5 * cfg.align_window_m
    hi = min(hi, target.x[-1] + cfg.align_max_lag_m) - 0.5 * cfg.align_window_m
    if hi < lo:
        return np.zeros(0)
    n = int(math.floor((hi - lo) / cfg.align_step_m)) + 1
    return lo + cfg.align_step_m * np.arange(n) + 0.5 * ((hi - lo) - cfg.align_step_m * (n - 1))


def align_profiles(run: FeatureProfile, target: FeatureProfile, cfg: MonitoringConfig = MonitoringConfig(), *,
                   breakpoints: Sequence[float] = (), target_name: str = "reference",
                   centres: np.ndarray | None = None, clip: bool = True) -> AlignmentStage:
    """Align a run's feature signal to a target's (module docstring): two passes, robust piecewise fit.

    Parameters
    ----------
    run, target : FeatureProfile
        Filtered in ``cfg.align_band_mm`` (see :func:`feature_profile`).
    cfg : MonitoringConfig
    breakpoints : sequence of float
        Chainages where the odometer was reset (the line's balises): knots of the fit.
    target_name : str
        Named in the stage and its messages.
    centres : ndarray, optional
        Window centres (default: every ``align_step_m`` where both cover).
    clip : bool
        Clip tonal lines for the wide search (default; off against the line's weld template, whose welds
        recur at the rail length, beyond the search range).

    Returns
    -------
    AlignmentStage
    """
    c = _centres(run, target, cfg) if centres is None else np.asarray(centres, float)
    empty = pd.DataFrame({"centre_m": c, "lag_m": np.full(c.size, np.nan), "correlation": np.zeros(c.size),
                          "kept": np.zeros(c.size, bool)})
    if c.size == 0:
        return AlignmentStage(target_name, ShiftFit.identity(), empty, math.nan, False,
                              f"the run and the {target_name} share no stretch of at least "
                              f"{cfg.align_window_m:g} m")
    coarse_r = run.coarse(cfg.align_coarse_band_mm, clip)
    coarse_t = target.coarse(cfg.align_coarse_band_mm, clip)
    lag1, rho1 = local_lags(coarse_r, coarse_t, c, cfg.align_window_m, cfg.align_max_lag_m)
    good1 = rho1 >= cfg.align_min_correlation
    knots = knots_for(float(c.min()), float(c.max()), breakpoints, cfg.align_piece_m)
    if good1.sum() < cfg.align_min_windows:
        return AlignmentStage(target_name, ShiftFit.identity(), empty.assign(lag_m=lag1, correlation=rho1),
                              math.nan, False,
                              f"only {int(good1.sum())} of {c.size} windows of {cfg.align_window_m:g} m correlate "
                              f"with the {target_name} above {cfg.align_min_correlation:g} (long-wave band "
                              f"{cfg.align_coarse_band_mm[0]:g}-{cfg.align_coarse_band_mm[1]:g} mm); at least "
                              f"{cfg.align_min_windows} are needed")
    fit1, kept1, res1 = fit_shift(c, np.where(good1, lag1, np.nan), rho1 ** 2, knots)
    # second pass on the run re-gridded by the first fit: inside a window the remaining lag is constant, so the
    # fine band's sharp peak is not smeared by the scale error
    fine_range = max(4 * res1, 0.015) if np.isfinite(res1) else 0.05
    warped = run.shifted(fit1)
    c2 = c + fit1.shift(c)
    lag2, rho2 = local_lags(warped, target, c2, cfg.align_window_m, fine_range)
    good2 = rho2 >= cfg.align_min_correlation
    windows = pd.DataFrame({"centre_m": c, "lag_m": lag2 + fit1.shift(c), "correlation": rho2,
                            "kept": np.zeros(c.size, bool)})
    if good2.sum() < cfg.align_min_windows:
        return AlignmentStage(target_name, fit1, windows, res1 * 1e3, False,
                              f"only {int(good2.sum())} of {c.size} windows correlate with the {target_name} above "
                              f"{cfg.align_min_correlation:g} in the fine band {cfg.align_band_mm[0]:g}-"
                              f"{cfg.align_band_mm[1]:g} mm; at least {cfg.align_min_windows} are needed")
    knots2 = knots_for(float(c2.min()), float(c2.max()), breakpoints, cfg.align_piece_m)
    fit2, kept, res = fit_shift(c2, np.where(good2, lag2, np.nan), rho2 ** 2, knots2)
    fit = compose(fit1, fit2)
    windows["kept"] = kept
    reasons = []
    if kept.sum() < cfg.align_min_windows:
        reasons.append(f"only {int(kept.sum())} windows agree with one offset + scale (at least "
                       f"{cfg.align_min_windows} needed)")
    if np.isfinite(res) and res * 1e3 > cfg.align_max_residual_mm:
        reasons.append(f"residual {res * 1e3:.1f} mm RMS above {cfg.align_max_residual_mm:g} mm")
    sc = fit.pieces()["scale"].to_numpy()
    if np.any(np.abs(sc - 1) > cfg.align_max_scale_error):
        worst = sc[np.argmax(np.abs(sc - 1))]
        reasons.append(f"a piece's scale {worst:.4f} is beyond 1 ± {cfg.align_max_scale_error:g}")
    return AlignmentStage(target_name, fit, windows, res * 1e3, not reasons, "; ".join(reasons))


# --------------------------------------------------------------------------- the line's features
def _line_features(line) -> list[tuple[float, str | None, float]]:
    """(chainage, rail or None, relative depth) of the line's point features: welds and crossing noses."""
    raw = getattr(line, "raw", {}) or {}
    feats: list[tuple[float, str | None, float]] = []
    welds = raw.get("welds")
    if isinstance(welds, list) and welds:
        for w in welds:
            try:
                feats.append((float(w["chainage_m"]), str(w["rail"]).upper() if w.get("rail") else None, 1.0))
            except (KeyError, TypeError, ValueError):
                continue
    else:
        feats += [(float(c), None, 1.0) for c in getattr(line, "welds", ())]
    for s in raw.get("switches", []) or []:
        if isinstance(s, dict) and "crossing_m" in s:
            try:
                rail = str(s.get("crossing_rail", "")).upper() or None
                feats.append((float(s["crossing_m"]), rail if rail in ("L", "R") else None, 1.0))
            except (TypeError, ValueError):
                continue
    return feats


def line_template(line, x0: float, dx: float, n: int, rails: Sequence[str], cfg: MonitoringConfig = MonitoringConfig()
                  ) -> FeatureProfile | None:
    """The line's feature template on a grid (a cosine dip of ``weld_length_m`` per feature), band-filtered.

    Returns None when the line lists no point feature in the grid's stretch.
    """
    x = x0 + dx * np.arange(n)
    feats = [f for f in _line_features(line) if x[0] - cfg.weld_length_m <= f[0] <= x[-1] + cfg.weld_length_m]
    if not feats:
        return None
    vals = np.zeros((len(rails), n))
    L = cfg.weld_length_m
    for c, rail, depth in feats:
        i0, i1 = np.searchsorted(x, [c - L / 2, c + L / 2])
        u = (x[i0:i1] - c) / L
        dip = -depth * 0.5 * (1 + np.cos(2 * np.pi * u))
        for k, r in enumerate(rails):
            if rail is None or rail == r:
                vals[k, i0:i1] += dip
    return FeatureProfile(x0, dx, tuple(rails), band_filter(vals, dx, cfg.align_band_mm), "line features")


def align_to_line(run: FeatureProfile, line, cfg: MonitoringConfig = MonitoringConfig()) -> AlignmentStage | None:
    """Align a feature signal to the line's welds and crossings (absolute chainage); None without features.

    Windows are placed on the features (one per feature inside the run), so a
    long plain stretch does not dilute the correlation.
    """
    pad = cfg.align_max_lag_m + cfg.align_window_m
    n = run.values.shape[1] + 2 * int(math.ceil(pad / run.dx))
    x0 = run.x0 - pad
    tpl = line_template(line, x0, run.dx, n, run.rails, cfg)
    if tpl is None:
        return None
    x = run.x
    feats = sorted({round(f[0], 3) for f in _line_features(line)
                    if x[0] + 0.5 * cfg.align_window_m <= f[0] <= x[-1] - 0.5 * cfg.align_window_m})
    if not feats:
        return None
    breakpoints = [c for _, c in getattr(line, "balises", ())]
    return align_profiles(run, tpl, cfg, breakpoints=breakpoints, target_name="line features",
                          centres=np.array(feats), clip=False)
