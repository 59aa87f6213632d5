"""Diagnosis: which catalogued physical effect explains where the model fails (and how large it is).

For every candidate effect of :mod:`receptance.effects` the diagnosis fits
its parameters to the measured FRFs of all setups and scores the fit.

Error measure.  For each channel ``c`` and octave band ``b`` the
band-normalised complex error ``e_cb = ‖H_m − H_x‖_b / ‖H_x‖_b``; the summary
error is ``E = sqrt(mean_cb e_cb²)`` (a misfit at 15 Hz, where the
accelerance is small, counts as much as one at a 300 Hz resonance).

Fitting.  The complex misfit of a stiffness is full of narrow valleys (a
sharp mode sliding past a measured peak), so the parameters are fitted on
smoothed log spectra: a coordinate search on sixth-octave levels finds the
basin, a finer search and a bounded least-squares polish on 24th-octave
levels place the modes.  The fit sees the physics alone — the design model
(FE frequencies) plus the effect, so that the stiffness is what moves the
modes from their FE to their measured frequencies; the scored model then
gives every mode that carries a measured one the test's frequency and
damping (paired modes and, within 3 %, test-only modes:
:class:`~receptance.modal_model.ModalModel`), as the hybrid model does.
Uncertainties come from the polish's Jacobian.

Criterion.  The Bayesian information criterion over the ``N`` cells of
channel × sixth-octave band (the resolution at which a modal effect shows;
``E_6`` the same band-normalised error on those cells)::

    BIC = N ln E_6² + k ln N

with ``k`` every number the fit adjusts — for the curve-fit effects one
residual pair or one modal constant per channel, so physics with few
parameters wins over patches that explain the same evidence.  A candidate
is *significant* when it lowers BIC by more than 10 (very strong evidence,
Kass & Raftery 1995), lowers ``E`` by at least 10 %, and the model's error
was above 1.2 times the measurement's noise floor ``E_noise`` (the same
figure for a perfect model: the H1 random error from coherence and number
of averages, Bendat & Piersol ``σ²/|H|² = (1 − γ²)/(2 n γ²)``); it is
*plausible* when its fitted values lie inside their bounds.  The best
significant, plausible physical effect (or ``residuals``) is accepted;
``experimental_mode`` is never accepted as an explanation: it can describe
a mode the FE lacks but says nothing of its cause, and the report says so.
After accepting an effect the diagnosis runs again on the improved model
and finds the next one.
"""

from __future__ import annotations

import functools
import logging
import time
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np
import pandas as pd
import scipy.optimize

from ema.frf import FrequencyResponse
from ema._blas import one_blas_thread
from receptance.compare import band_errors, h1_variance
from receptance.effects import EFFECTS, Effect, ExperimentalMode, Residuals
from receptance.modal_model import ModalModel, ModelError

__all__ = ["Measurement", "EffectFit", "Diagnosis", "Misfit", "misfit", "fit_effect", "rank_effects", "diagnose",
           "BIC_THRESHOLD", "MIN_REDUCTION"]

log = logging.getLogger("receptance")

BIC_THRESHOLD = 10.0
MIN_REDUCTION = 0.10
NOISE_MARGIN = 1.2
#: a fitted parameter whose halving or doubling moves the summary error by less than this share is undetermined
UNDETERMINED_DE = 0.01
OCTAVES = (10.0, 20.0, 40.0, 80.0, 160.0, 320.0, 500.0)


@dataclass(frozen=True)
class Measurement:
    """One setup's measured accelerance and its channel table (with the force row)."""

    frf: FrequencyResponse
    channels: pd.DataFrame
    setup: str = ""

    def __post_init__(self) -> None:
        if self.frf.n_in != 1:
            raise ModelError(f"setup {self.setup!r}: expected a single-reference FRF, got {self.frf.n_in} inputs")
        acc = self.channels[self.channels["quantity"] == "acceleration"]
        order = acc.set_index(acc["name"].astype(str))
        missing = [o for o in self.frf.outputs if o not in order.index]
        if missing:
            raise ModelError(f"setup {self.setup!r}: FRF outputs {missing} are not in the channel table")
        table = pd.concat([order.loc[list(self.frf.outputs)].reset_index(drop=True),
                           self.channels[self.channels["quantity"] == "force"]], ignore_index=True)
        if not self.setup:
            s = table["setup"].dropna() if "setup" in table else pd.Series([], dtype=object)
            object.__setattr__(self, "setup", str(s.iloc[0]) if len(s) else "setup")
        if "setup" not in table or table["setup"].isna().all():
            table = table.assign(setup=self.setup)
        object.__setattr__(self, "channels", table)

    def band_weights(self, bands=None) -> tuple[np.ndarray, np.ndarray]:
        """Per line ``1/‖H_x‖_b`` of its channel-band (0 outside the bands) and the band index of each line."""
        if bands is None or tuple(bands) == OCTAVES:
            return self._octave_weights
        return self._band_weights(bands)

    @functools.cached_property
    def _octave_weights(self) -> tuple[np.ndarray, np.ndarray]:
        # every evaluation of a fit needs them: computed once per measurement
        return self._band_weights(OCTAVES)

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
    def sigma(self) -> np.ndarray:
        """Random error of each line (n_out, n_f): the H1 variance of :func:`receptance.compare.h1_variance`."""
        var = h1_variance(self.frf)
        if var is None:
            raise ModelError(f"setup {self.setup!r}: the measured FRF carries no coherence or averaging count, so "
                             f"its noise floor is unknown; estimate it with ema.estimate_frf")
        return np.sqrt(var)


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
        return float(self.n_fine * np.log(self.fine**2) + k * np.log(max(self.n_fine, 2)))


def _model_frfs(model: ModalModel, measurements: Sequence[Measurement]) -> list[np.ndarray]:
    return [model.frf_at_channels(m.channels, m.frf.freqs_hz, decay=m.frf.exp_window_decay).data[:, 0]
            for m in measurements]


@one_blas_thread
def misfit(model: ModalModel, measurements: Sequence[Measurement], *, bands=OCTAVES) -> Misfit:
    """Summary error ``E`` of ``model`` against ``measurements`` and its noise floor (module docstring)."""
    rows, brows = [], []
    frfs = _model_frfs(model, measurements)
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
        edges = _sixth_octaves(m.frf.freqs_hz, bands)
        fine.append(band_errors(m.frf.freqs_hz, m.frf.data[:, 0], Hm, edges).ravel())
    fine = np.concatenate(fine)
    return Misfit(summary, floor, len(per_band), pd.DataFrame(rows), per_band, float(np.sqrt(np.mean(fine**2))),
                  fine.size)


def _sixth_octaves(f: np.ndarray, bands) -> list[tuple[float, float]]:
    lo, hi = max(bands[0], f[0]), min(bands[-1], f[-1])
    n = max(int(np.ceil(6 * np.log2(hi / lo))), 1)
    e = lo * (hi / lo) ** (np.arange(n + 1) / n)
    return [(a, b) for a, b in zip(e[:-1], e[1:]) if np.count_nonzero((f >= a) & (f < b)) >= 2]


@dataclass(frozen=True)
class EffectFit:
    """One candidate effect fitted to the measurements."""

    name: str
    physical: bool
    params: dict
    uncertainty: dict
    bounds: dict
    at_bound: tuple[str, ...]
    n_fitted: int
    delta_bic: float
    error_before: float
    error_after: float
    significant: bool
    plausible: bool
    fixes: pd.DataFrame = field(repr=False)
    model: ModalModel = field(repr=False)
    effect: Effect = field(repr=False)
    note: str = ""

    @property
    def reduction(self) -> float:
        return 1 - self.error_after / self.error_before if self.error_before > 0 else 0.0

    def to_dict(self) -> dict:
        return {"name": self.name, "physical": self.physical, "params": self.params,
                "uncertainty_rel": self.uncertainty, "bounds": self.bounds, "at_bound": list(self.at_bound),
                "n_fitted": self.n_fitted, "delta_bic": self.delta_bic, "error_before": self.error_before,
                "error_after": self.error_after, "significant": self.significant, "plausible": self.plausible,
                "fixes": self.fixes.head(8).to_dict(orient="records"), "note": self.note}


def _bic_fields(before: Misfit, after: Misfit, k: int) -> tuple[float, bool]:
    d = after.bic(k) - before.bic(0)
    reduction = 1 - after.summary / before.summary if before.summary > 0 else 0.0
    above_noise = before.summary > NOISE_MARGIN * before.noise_floor
    return float(d), bool(d < -BIC_THRESHOLD and reduction >= MIN_REDUCTION and above_noise)


def _fixes(before: Misfit, after: Misfit) -> pd.DataFrame:
    """Where an effect lowered the error: per body-agnostic channel and band, largest improvements first."""
    b, a = before.per_band, after.per_band
    if not len(b):
        return pd.DataFrame()
    j = b.merge(a, on=["setup", "channel", "band_lo_hz", "band_hi_hz"], suffixes=("_before", "_after"))
    j["improvement"] = j["rel_error_before"] - j["rel_error_after"]
    return j.sort_values("improvement", ascending=False).reset_index(drop=True)[
        ["setup", "channel", "band_lo_hz", "band_hi_hz", "rel_error_before", "rel_error_after", "improvement"]]


@one_blas_thread
def fit_effect(effect: Effect, model: ModalModel, measurements: Sequence[Measurement], *,
               before: Misfit | None = None) -> EffectFit:
    """Fit one effect's parameters (log scale, inside their bounds) and score it (module docstring)."""
    before = before or misfit(model, measurements)
    tables = [m.channels for m in measurements]
    if isinstance(effect, Residuals):
        effect = _fit_residuals(model, measurements)
        return _score(effect, {}, {}, model, measurements, before, tables)
    if isinstance(effect, ExperimentalMode):
        effect = _fit_experimental_mode(model, measurements, before)
        if effect is None:
            raise ModelError("no measured peak left to describe")
        return _score(effect, {"f_hz": effect.f_hz, "zeta": effect.zeta}, {}, model, measurements, before, tables)
    params = effect.parameters()
    lo = np.log10([p.lower for p in params])
    hi = np.log10([p.upper for p in params])
    x0 = np.log10([p.initial for p in params])

    # the parameters are fitted on the physics alone (FE frequencies + effect, nothing pinned): pinned modes
    # would flatten the misfit around the very frequency shifts that tell the stiffness (the scored model pins)
    physics = model.as_designed()

    def model_at(x):
        return effect.apply(physics, {p.name: 10 ** v for p, v in zip(params, x)}, tables)

    def frfs(x, stride):
        m = model_at(x)
        return [m.frf_at_channels(ms.channels, ms.frf.freqs_hz[::stride], decay=ms.frf.exp_window_decay).data[:, 0]
                for ms in measurements]

    # the complex misfit of a stiffness is full of narrow valleys (a sharp mode sliding past measured peaks);
    # smoothed log spectra have broad basins: a coordinate search on sixth-octave levels finds the basin, a
    # finer pass and a bounded least-squares polish on 24th-octave levels (3 % bands, a few half-power
    # bandwidths of a 0.5 %-damped mode) place the new modes
    coarse, fine = _SmoothSpectra(measurements, stride=4), _SmoothSpectra(measurements, per_octave=24, stride=2)
    def coarse_cost(x):
        return coarse.cost(frfs(x, 4))

    def fine_cost(x):
        return fine.cost(frfs(x, 2))

    x, best = x0.copy(), coarse_cost(x0)
    for _ in range(2):
        x, best = _coordinate_pass(x, best, coarse_cost, lambda i, x: np.linspace(lo[i], hi[i], 17))
    x, best = _coordinate_pass(x, fine_cost(x), fine_cost,
                               lambda i, x: np.clip(x[i] + np.linspace(-0.15, 0.15, 11), lo[i], hi[i]))
    res = scipy.optimize.least_squares(lambda x: fine.residuals(frfs(x, 2)), x, bounds=(lo, hi), diff_step=1e-3,
                                       x_scale=1.0, max_nfev=40)
    x = res.x if fine_cost(res.x) <= best else x
    values = {p.name: float(10 ** v) for p, v in zip(params, x)}
    unc = {}
    try:
        J = res.jac
        dof = max(J.shape[0] - len(x), 1)
        cov = np.linalg.inv(J.T @ J) * (2 * res.cost / dof)
        unc = {p.name: float(np.log(10) * np.sqrt(max(cov[i, i], 0))) for i, p in enumerate(params)}
    except np.linalg.LinAlgError:
        unc = {p.name: float("inf") for p in params}
    return _score(effect, values, unc, model, measurements, before, tables, params=params, x=x, lo=lo, hi=hi)


def _coordinate_pass(x: np.ndarray, best: float, cost: Callable, values: Callable) -> tuple[np.ndarray, float]:
    """One pass of a coordinate search: each parameter in turn takes the best of ``values(i, x)``, others held."""
    for i in range(x.size):
        for v in values(i, x):
            trial = x.copy()
            trial[i] = v
            c = cost(trial)
            if c < best:
                best, x = c, trial
    return x, best


class _SmoothSpectra:
    """Sixth-octave RMS levels of measured and model FRFs: a misfit with broad basins for the coarse search."""

    def __init__(self, measurements, per_octave: int = 6, stride: int = 1):
        self.edges = []
        self.levels = []
        for m in measurements:
            f = m.frf.freqs_hz[::stride]
            lo, hi = max(f[0], OCTAVES[0]), min(f[-1], OCTAVES[-1])
            n = max(int(np.ceil(per_octave * np.log2(hi / lo))), 1)
            edges = lo * (hi / lo) ** (np.arange(n + 1) / n)
            idx = np.clip(np.searchsorted(edges, f, side="right") - 1, 0, n - 1)
            keep = (f >= lo) & (f <= hi)
            self.edges.append((idx, keep, n))
            self.levels.append(self._levels(m.frf.data[:, 0, ::stride], idx, keep, n))

    @staticmethod
    def _levels(H, idx, keep, n):
        p = np.zeros((H.shape[0], n))
        np.add.at(p.T, idx[keep], (np.abs(H[:, keep]) ** 2).T)
        return 0.5 * np.log(np.maximum(p, 1e-300))

    def residuals(self, frfs) -> np.ndarray:
        """Level differences (natural log) over every channel and band."""
        return np.concatenate([(self._levels(H, idx, keep, n) - ref).ravel()
                               for (idx, keep, n), ref, H in zip(self.edges, self.levels, frfs)])

    def cost(self, frfs) -> float:
        return float(np.sum(self.residuals(frfs) ** 2))


def _insensitive(effect, values, name, model, measurements, tables, error: float) -> bool:
    for factor in (0.5, 2.0):
        moved = effect.apply(model, dict(values, **{name: values[name] * factor}), tables)
        if abs(misfit(moved, measurements).summary - error) > UNDETERMINED_DE * error:
            return False
    return True


def _score(effect, values, unc, model, measurements, before, tables, *, params=(), x=None, lo=None, hi=None):
    after_model = effect.apply(model, values, tables) if params else effect.apply(model, {}, tables)
    after = misfit(after_model, measurements)
    k = effect.n_fitted(tables)
    d_bic, significant = _bic_fields(before, after, k)
    at_bound, undetermined = (), ()
    if params:
        hit = [p.name for p, v, a, b in zip(params, x, lo, hi) if v - a < 0.02 or b - v < 0.02]
        # a parameter the data cannot determine (e.g. a horizontal rig stiffness whose modes lie far below the
        # band) drifts, often to a bound: that is "not determined", not "implausible". Judged by what it does to
        # the scored error: halving or doubling it moves E by less than UNDETERMINED_DE (or the fit's own
        # uncertainty exceeds a factor e)
        undetermined = tuple(p.name for p in params
                             if unc.get(p.name, np.inf) > 1.0 or _insensitive(effect, values, p.name, model,
                                                                               measurements, tables, after.summary))
        at_bound = tuple(n for n in hit if n not in undetermined)
    note = ""
    if undetermined:
        note = f"not determined by the data (flat misfit): {', '.join(undetermined)}. "
    if isinstance(effect, ExperimentalMode):
        note = (f"describes a measured mode at {effect.f_hz:.2f} Hz (zeta {100 * effect.zeta:.2f} %) that the "
                f"model lacks, by curve fitting; it does not say what physical part makes it")
    return EffectFit(effect.name, effect.physical, values, unc,
                     {p.name: (p.lower, p.upper) for p in params}, at_bound, k, d_bic,
                     before.summary, after.summary, significant, not at_bound, _fixes(before, after), after_model,
                     effect, note)


def _fit_residuals(model, measurements) -> Residuals:
    """Per channel, real lower and upper residuals by weighted linear least squares."""
    lower, upper = {}, {}
    for m, Hm in zip(measurements, _model_frfs(model, measurements)):
        s = 2j * np.pi * m.frf.freqs_hz + m.frf.exp_window_decay
        d = m.frf.data[:, 0] - Hm
        w, _ = m.band_weights()
        lower[m.setup], upper[m.setup] = {}, {}
        for i, name in enumerate(m.frf.outputs):
            # accelerance of the residuals: R_L + s² R_U
            A = np.column_stack([np.ones_like(s), s**2]) * w[i][:, None]
            A = np.vstack([A.real, A.imag])
            b = d[i] * w[i]
            sol, *_ = np.linalg.lstsq(A, np.concatenate([b.real, b.imag]), rcond=None)
            lower[m.setup][name] = float(sol[0])
            upper[m.setup][name] = float(sol[1])
    return Residuals(lower=lower, upper=upper)


def _exp_mode_constants(model, measurements, f, z, model_frfs):
    consts, resid = {}, []
    for m, Hm in zip(measurements, model_frfs):
        s = 2j * np.pi * m.frf.freqs_hz + m.frf.exp_window_decay
        w0 = 2 * np.pi * f
        g = s**2 / (s**2 + 2 * z * w0 * s + w0**2)
        d = m.frf.data[:, 0] - Hm
        wt, _ = m.band_weights()
        consts[m.setup] = {}
        for i, name in enumerate(m.frf.outputs):
            gi = g * wt[i]
            a = np.vdot(gi, d[i] * wt[i]) / np.vdot(gi, gi)
            consts[m.setup][name] = complex(a)
            resid.append((d[i] - a * g) * wt[i])
    return consts, np.concatenate(resid)


def _fit_experimental_mode(model, measurements, before: Misfit) -> ExperimentalMode | None:
    frfs = _model_frfs(model, measurements)
    # where the unexplained response is largest: sum over channels of the normalised misfit
    f_all = measurements[0].frf.freqs_hz
    power = np.zeros(f_all.size)
    for m, Hm in zip(measurements, frfs):
        if m.frf.freqs_hz.size == f_all.size:
            power += np.sum(np.abs((m.frf.data[:, 0] - Hm) * m.band_weights()[0]) ** 2, axis=0)
    if not np.any(power > 0):
        return None
    f0 = float(f_all[np.argmax(power)])

    def res(x):
        return _exp_mode_constants(model, measurements, x[0], 10 ** x[1], frfs)[1].view(float)

    df = max(f_all[1] - f_all[0], 1e-3)
    sol = scipy.optimize.least_squares(res, [f0, np.log10(0.005)], bounds=([f0 - 5 * df, -4.5], [f0 + 5 * df, -0.7]),
                                       x_scale=[df, 0.1], max_nfev=60)
    f, z = float(sol.x[0]), float(10 ** sol.x[1])
    consts, _ = _exp_mode_constants(model, measurements, f, z, frfs)
    return ExperimentalMode(f_hz=f, zeta=z, constants=consts)


@one_blas_thread
def rank_effects(model: ModalModel, measurements: Sequence[Measurement], *,
                 catalogue: Sequence[Effect] | None = None, skip: Sequence[str] = (),
                 progress: Callable[[str], None] | None = None) -> tuple[Misfit, list[EffectFit]]:
    """Fit every candidate and rank by ΔBIC (most negative first)."""
    before = misfit(model, measurements)
    effects = list(catalogue) if catalogue is not None else [cls() for cls in EFFECTS.values()]
    fits = []
    for eff in effects:
        if eff.name in skip or not eff.in_test:
            continue
        t0 = time.perf_counter()
        try:
            fit = fit_effect(eff, model, measurements, before=before)
        except ModelError as exc:
            log.info("candidate %s not applicable: %s", eff.name, exc)
            continue
        fits.append(fit)
        if progress:
            progress(f"{eff.name}: error {fit.error_before:.4f} -> {fit.error_after:.4f}, dBIC {fit.delta_bic:.3g}, "
                     f"{fit.n_fitted} fitted numbers ({time.perf_counter() - t0:.1f} s)")
    fits.sort(key=lambda f: f.delta_bic)
    return before, fits


@dataclass(frozen=True)
class Diagnosis:
    """Result of :func:`diagnose`: accepted effects in the order added, every round's ranked candidates."""

    accepted: tuple[EffectFit, ...]
    rounds: tuple[tuple[EffectFit, ...], ...]
    initial: Misfit
    final: Misfit
    model: ModalModel = field(repr=False)
    unexplained: tuple[str, ...] = ()

    def residual(self) -> dict:
        """Where the remaining error sits: worst channels and bands of the final model."""
        pb = self.final.per_band
        top = pb.sort_values("rel_error", ascending=False).head(8)
        bands = pb.groupby(["band_lo_hz", "band_hi_hz"])["rel_error"].apply(lambda e: float(np.sqrt(np.mean(e**2))))
        return {"summary_error": self.final.summary, "noise_floor": self.final.noise_floor,
                "worst": top[["setup", "channel", "band_lo_hz", "band_hi_hz", "rel_error"]].to_dict(orient="records"),
                "bands": [{"band_hz": [lo, hi], "rms_rel_error": v} for (lo, hi), v in bands.items()],
                "unexplained": list(self.unexplained)}

    def to_json(self) -> dict:
        return {"accepted": [{"name": f.name, "params": f.params, "error_before": f.error_before,
                              "error_after": f.error_after} for f in self.accepted],
                "candidates": [[f.to_dict() for f in r] for r in self.rounds][-1] if self.rounds else [],
                "rounds": [[f.to_dict() for f in r] for r in self.rounds],
                "residual": self.residual(),
                "criterion": f"BIC = N ln E6^2 + k ln N over N channel x sixth-octave cells; significant if dBIC < -{BIC_THRESHOLD:g}, "
                             f"E falls by >= {100 * MIN_REDUCTION:g} % and E was above {NOISE_MARGIN:g} x the noise "
                             f"floor; plausible if inside bounds",
                "initial": {"summary_error": self.initial.summary, "noise_floor": self.initial.noise_floor}}


@one_blas_thread
def diagnose(model: ModalModel, measurements: Sequence[Measurement], *, catalogue: Sequence[Effect] | None = None,
             max_effects: int = 3, progress: Callable[[str], None] | None = None) -> Diagnosis:
    """Find the missing effects one after the other (module docstring)."""
    current = model
    initial = misfit(model, measurements)
    accepted, rounds, unexplained = [], [], []
    skip: list[str] = []
    for _ in range(max_effects):
        before, fits = rank_effects(current, measurements, catalogue=catalogue, skip=skip, progress=progress)
        rounds.append(tuple(fits))
        pick = next((f for f in fits if f.significant and f.plausible and f.name != "experimental_mode"), None)
        patch = next((f for f in fits if f.significant and f.name == "experimental_mode"), None)
        if patch is not None and (pick is None or patch.delta_bic < pick.delta_bic):
            unexplained.append(patch.note)
        if pick is None:
            break
        accepted.append(pick)
        skip.append(pick.name)
        current = pick.model
        if progress:
            progress(f"accepted {pick.name} {pick.params}: error {pick.error_before:.4f} -> {pick.error_after:.4f}")
    final = misfit(current, measurements)
    if final.summary > NOISE_MARGIN * final.noise_floor:
        worst = final.per_band.assign(excess=final.per_band["rel_error"] ** 2 - final.per_band["noise"] ** 2)
        bands = worst.groupby(["band_lo_hz", "band_hi_hz"])["excess"].sum().sort_values(ascending=False)
        chans = worst.groupby(["setup", "channel"])["excess"].sum().sort_values(ascending=False)
        (lo, hi), _ = next(iter(bands.items()))
        unexplained.append(
            f"no catalogued effect explains the remaining error: E = {final.summary:.3f} is "
            f"{final.summary / final.noise_floor:.1f} x the noise floor {final.noise_floor:.3f}; most of it sits in "
            f"{lo:g}-{hi:g} Hz, on " + ", ".join(f"{s}/{c}" for s, c in list(chans.index[:4])))
    return Diagnosis(tuple(accepted), tuple(rounds), initial, final, current, tuple(unexplained))
