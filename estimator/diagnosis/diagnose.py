"""Fit, rank and accept field effects one after the other — the lab diagnosis's criterion on field evidence.

Criterion (the lab diagnosis's, :mod:`receptance.diagnosis.fitting`, over
field cells): with ``N`` calibration cells (run × wheelset × segment × rail ×
one-third-octave band) and ``E`` the RMS of the cells' level errors
``10 lg(σ²_est/σ²_ref)`` [dB],

    BIC = N ln E² + k ln N,

``k`` the numbers the effect's fit adjusts. A candidate is *significant*
when ``ΔBIC < −bic_threshold`` (10), ``E`` falls by at least
``min_reduction`` (10 %) and ``E`` before it lay above ``noise_margin``
(1.2) × the noise floor; *plausible* when every fitted value lies in its
plausible range, off the search bounds; *validated* when the error of the
validation cells it acts on (segments the fit did not see: other stretches,
other days) falls by at least ``validation_min_reduction``. Candidates are
ranked by ΔBIC, those whose fitted values are plausible first: an effect
that lowers the error only with a value outside its physical range or on a
search bound has not explained the evidence, however large its ΔBIC (it
usually soaks up an error the catalogue does not hold), and is listed after
the physical ones. The best one that is all three is accepted, added to the
state, and the catalogue is fitted again on top of it — until none passes
(then the residual is reported plainly, with where it lies) or
``max_effects`` are accepted.

Fit: a grid over the bounds (9 values for one parameter, 5 × 5 for two: in
log for the factors) finds the basin, Nelder–Mead on the unit cube polishes
it (restarted once with a fresh simplex when it ends on a bound); an effect
with ``n_grid`` set grids only its leading parameters (a stretch's two
factors) and starts the others at their nominal values (its ends where the
evidence located it), Nelder–Mead then moves all of them. Uncertainty (1σ)
from the curvature of ``N ln E²`` at the optimum (a Gaussian likelihood
whose variance is estimated: ``Δ(N ln E²) = 1`` at one σ). A parameter whose
move by ± a quarter of its search span changes ``E`` by less than
``undetermined_de`` is *undetermined*: it returns to its nominal value and
the other parameters are polished again without it. Candidates are fitted in
worker processes (fork: the evidence is shared, nothing is pickled but the
results).
"""

from __future__ import annotations

import logging
import math
import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
import scipy.optimize

from estimator.diagnosis.effects import FieldEffect
from estimator.diagnosis.errors import FieldDiagnosisError
from estimator.diagnosis.state import FieldState

__all__ = ["CandidateFit", "FieldDiagnosis", "diagnose_field", "noise_floor", "cell_masks", "anomalous_stretches",
           "CRITERION"]

log = logging.getLogger("estimator")

CRITERION = ("BIC = N ln E² + k ln N over the calibration cells (run × wheelset × segment × rail × one-third-octave "
             "band, E = RMS level error in dB); accepted when ΔBIC < −{bic:g}, E falls ≥ {red:.0f} %, E before > "
             "{margin:g} × noise floor, fitted values plausible, and the error on the validation cells it acts on "
             "falls ≥ {val:.0f} %")

_GRID = {1: 9, 2: 5}
_NM_FEV = 30


@dataclass(frozen=True)
class CandidateFit:
    """One candidate effect fitted on top of the state accepted so far."""

    effect: FieldEffect
    params: dict
    uncertainty: dict
    undetermined: tuple[str, ...]
    at_bound: tuple[str, ...]
    n_fitted: int
    delta_bic: float
    error_before: float
    error_after: float
    validation_before: float
    validation_after: float
    n_validation: int
    significant: bool
    plausible: bool
    validated: bool
    fixes: pd.DataFrame = field(repr=False)
    state: FieldState = field(repr=False, default=FieldState())

    @property
    def name(self) -> str:
        return self.effect.name

    @property
    def passes(self) -> bool:
        return self.significant and self.plausible and self.validated

    def verdict(self) -> str:
        why = []
        if not self.significant:
            why.append("not significant")
        if not self.plausible:
            why.append("implausible value" + (f" (at bound: {', '.join(self.at_bound)})" if self.at_bound else ""))
        if not self.validated:
            why.append("no validation evidence" if self.n_validation == 0 else "does not lower the validation error")
        return "passes" if not why else "; ".join(why)

    def as_dict(self) -> dict:
        return {"effect": self.name, "where": self.effect.where, "label": self.effect.label(),
                "applied_by_estimator": self.effect.applied_by_estimator,
                "parameters": {k: float(v) for k, v in self.params.items()},
                "uncertainty": {k: float(v) for k, v in self.uncertainty.items()},
                "units": {p.name: p.unit for p in self.effect.parameters},
                "undetermined": list(self.undetermined), "at_bound": list(self.at_bound), "k": self.n_fitted,
                "delta_bic": self.delta_bic, "error_calibration_db": [self.error_before, self.error_after],
                "error_validation_db": [self.validation_before, self.validation_after],
                "n_validation_cells": self.n_validation, "significant": self.significant,
                "plausible": self.plausible, "validated": self.validated, "verdict": self.verdict(),
                "fixes": self.fixes.to_dict(orient="records"), "meaning": self.effect.meaning(self.params)}


@dataclass(frozen=True)
class FieldDiagnosis:
    """The result of :func:`diagnose_field`.

    Attributes
    ----------
    rounds : tuple of tuple of CandidateFit
        Every round's candidates, ranked (plausible ones first, then by ΔBIC).
    accepted : tuple of CandidateFit
        In the order they were accepted.
    state : FieldState
        The calibrated state (every accepted effect).
    noise_floor_db, scatter_db, reference_db, inversion_db : float
        Floor of ``E`` and its parts (run-to-run scatter; the reference's own noise; the regularised
        inversion's own bias).
    errors : pandas.DataFrame
        ``stage`` (nominal / after each accepted effect), ``set`` (calibration / validation), ``error_db``,
        ``n_cells``.
    residual : pandas.DataFrame
        Per segment and rail after the last accepted effect: mean and RMS error [dB] over runs and bands,
        ``unexplained`` where the RMS lies above ``noise_margin`` × floor and twice the median.
    verdict : str
    criterion : str
    """

    rounds: tuple
    accepted: tuple
    state: FieldState
    noise_floor_db: float
    scatter_db: float
    reference_db: float
    inversion_db: float
    errors: pd.DataFrame
    residual: pd.DataFrame
    by_band: pd.DataFrame
    verdict: str
    criterion: str

    @property
    def candidates(self) -> tuple:
        return self.rounds[0] if self.rounds else ()

    def unexplained_stretches(self) -> list[dict]:
        r = self.residual[self.residual["unexplained"]] if not self.residual.empty else self.residual
        return r.to_dict(orient="records")


# --------------------------------------------------------------------------- cells and the floor
def cell_masks(ev, min_snr_db: float) -> list[np.ndarray]:
    """Per segment: the cells with a reference above its own noise by ``min_snr_db``."""
    out = []
    for s in ev.segments:
        with np.errstate(divide="ignore", invalid="ignore"):
            snr = 10 * np.log10(s.ref_var / s.ref_noise_var)
        out.append(np.isfinite(s.ref_var) & (s.ref_var > 0) & ~(snr < min_snr_db))
    return out


def noise_floor(ev, errs: list[np.ndarray], masks: list[np.ndarray], inversion: list[np.ndarray] | None = None
                ) -> tuple[float, float, float, float]:
    """``(floor, scatter, reference, inversion)`` [dB]: run-to-run scatter of the same cells (same wheelset and
    role, any run or day; pooled, n/(n−1)); the reference's own noise ``10 lg(1 + σ²_noise/σ²_ref)`` as RMS; the inversion's own bias
    (:meth:`~estimator.diagnosis.model.Evaluator.inversion_floor`) as RMS over the calibration cells;
    floor = their root sum of squares."""
    groups: dict = {}
    for s, e, m in zip(ev.segments, errs, masks):
        for j in range(e.shape[0]):
            for k, b in enumerate(s.bands):
                if m[j, k] and np.isfinite(e[j, k]):
                    # replicates: the same wheelset in the same role over the same cell, any run or day (the
                    # error est − ref, not the roughness, is what repeats; leading and trailing differ in physics)
                    groups.setdefault((s.wheelset, s.role, s.from_m, s.rails[j], int(b)), []).append(e[j, k])
    dev, dof = 0.0, 0
    for v in groups.values():
        if len(v) > 1:
            a = np.asarray(v)
            dev += float(np.sum((a - a.mean()) ** 2))
            dof += a.size - 1
    scatter = math.sqrt(dev / dof) if dof else math.nan
    ref = []
    for s, m in zip(ev.segments, masks):
        with np.errstate(divide="ignore", invalid="ignore"):
            r = 10 * np.log10(1 + s.ref_noise_var / s.ref_var)
        ref.append(r[m])
    ref_all = np.concatenate(ref) if ref else np.zeros(0)
    reference = float(np.sqrt(np.mean(ref_all ** 2))) if ref_all.size else 0.0
    inv = 0.0
    if inversion is not None:
        inv, _ = _rms(inversion, masks, np.flatnonzero(ev.calibration))
        inv = 0.0 if math.isnan(inv) else inv
    floor = math.sqrt((0.0 if math.isnan(scatter) else scatter) ** 2 + reference ** 2 + inv ** 2)
    return floor, scatter, reference, inv


def anomalous_stretches(ev, errs: list[np.ndarray], masks: list[np.ndarray], floor: float, margin: float
                        ) -> list[tuple[float, float]]:
    """Stretches of consecutive calibration segments whose RMS error stands out (where the track may differ).

    Per segment position (pooled over runs, wheelsets, rails, bands) the RMS error; a segment stands out when
    it exceeds ``margin`` × the noise floor and the median of the segments by 3 robust standard deviations
    (1.4826 × MAD). Adjacent ones are merged.
    """
    acc: dict = {}
    for si, (s, e, m) in enumerate(zip(ev.segments, errs, masks)):
        if ev.calibration[si]:
            v = e[m & np.isfinite(e)]
            if v.size:
                acc.setdefault((s.from_m, s.to_m), []).append(v)
    if len(acc) < 3:
        return []
    keys = sorted(acc)
    rms = np.array([math.sqrt(float(np.mean(np.concatenate(acc[k]) ** 2))) for k in keys])
    med = float(np.median(rms))
    mad = 1.4826 * float(np.median(np.abs(rms - med)))
    hot = (rms > margin * floor) & (rms > med + 3 * max(mad, 0.1 * med))
    out: list[tuple[float, float]] = []
    for (a, b), h in zip(keys, hot):
        if not h:
            continue
        if out and abs(out[-1][1] - a) < 1e-6:
            out[-1] = (out[-1][0], b)
        else:
            out.append((a, b))
    return out


def _rms(errs, masks, sel) -> tuple[float, int]:
    parts = [errs[i][masks[i]] for i in sel]
    e = np.concatenate(parts) if parts else np.zeros(0)
    e = e[np.isfinite(e)]
    return (float(np.sqrt(np.mean(e ** 2))) if e.size else math.nan), int(e.size)


# --------------------------------------------------------------------------- fitting one candidate
class _Problem:
    """Everything a worker needs (inherited through fork)."""

    def __init__(self, evaluator, masks, base_state, base_errs, cfg):
        self.ev = evaluator
        self.masks = masks
        self.base_state = base_state
        self.base_errs = base_errs
        self.cfg = cfg
        cal = evaluator.evidence.calibration
        self.cal = np.flatnonzero(cal)
        self.val = np.flatnonzero(~cal)


_PROBLEM: _Problem | None = None


def _errors_with(pb: _Problem, effect: FieldEffect, values: dict, which: np.ndarray) -> list[np.ndarray]:
    st = effect.apply(pb.base_state, values)
    segs = pb.ev.evidence.segments
    touched = [i for i in which if effect.acts_on(segs[i])]
    new = dict(zip(touched, pb.ev.errors(st, touched)))
    return [new.get(i, pb.base_errs[i]) for i in range(len(segs))]


def _fit(effect: FieldEffect) -> CandidateFit:
    pb = _PROBLEM
    cfg = pb.cfg
    params = effect.parameters
    segs = pb.ev.evidence.segments

    def values_of(u):
        return {p.name: p.from_unit(float(x)) for p, x in zip(params, u)}

    def err(u) -> float:
        e, _ = _rms(_errors_with(pb, effect, values_of(u), pb.cal), pb.masks, pb.cal)
        return e if np.isfinite(e) else 1e6

    e0, n = _rms(pb.base_errs, pb.masks, pb.cal)
    if params:
        # the start grid covers the leading ``n_grid`` parameters (all by default); the others start at nominal
        ng = min(getattr(effect, "n_grid", len(params)), len(params))
        g = _GRID.get(ng, 3)
        axes = np.meshgrid(*[np.linspace(0, 1, g)] * ng, indexing="ij")
        rest = [p.to_unit(p.nominal) for p in params[ng:]]
        pts = np.stack([a.ravel() for a in axes] + [np.full(axes[0].size, r) for r in rest], axis=1)
        vals = np.array([err(p) for p in pts])
        u, e1 = _polish(err, pts[int(np.argmin(vals))], float(vals.min()), np.ones(len(params), bool),
                        0.5 / (g - 1), _NM_FEV * (1 + len(params) - ng))
    else:
        u = np.zeros(0)
        e1 = err(u)
    # a parameter the error does not see (± a quarter of its span moves E by < undetermined_de) is undetermined:
    # it goes back to its nominal value and is reported so, never as a fitted (or bound) value. Every parameter
    # is judged at the same optimum; the others are then polished again with the undetermined ones at nominal
    # (their optimum may have leant on an undetermined one sitting on its bound)
    undetermined = []
    for i, p in enumerate(params):
        q1, q2 = u.copy(), u.copy()
        q1[i] = min(u[i] + 0.25, 1.0)
        q2[i] = max(u[i] - 0.25, 0.0)
        if max(err(q1), err(q2)) - e1 < cfg.undetermined_de * e1:
            undetermined.append(p.name)
    if undetermined:
        free = np.array([p.name not in undetermined for p in params])
        u = u.copy()
        for i, p in enumerate(params):
            if not free[i]:
                u[i] = p.to_unit(p.nominal)
        e1 = err(u)
        if free.any():
            u, e1 = _polish(err, u, e1, free, 0.125, _NM_FEV * (1 + int(free.sum())))
    best = values_of(u)
    # uncertainty from the curvature of N ln E² (unit coordinates → values)
    unc, at_bound = {}, []
    for i, p in enumerate(params):
        if p.name in undetermined:
            unc[p.name] = math.inf
            continue
        h = 0.02
        up, dn = u.copy(), u.copy()
        up[i] = min(u[i] + h, 1.0)
        dn[i] = max(u[i] - h, 0.0)
        fu, fd = err(up), err(dn)
        hh = 0.5 * (up[i] - dn[i])
        d2 = n * (math.log(fu ** 2) - 2 * math.log(max(e1, 1e-12) ** 2) + math.log(fd ** 2)) / hh ** 2
        su = math.sqrt(2.0 / d2) if d2 > 0 else math.inf
        dv = abs(p.from_unit(min(u[i] + 1e-3, 1)) - p.from_unit(max(u[i] - 1e-3, 0))) / (
            min(u[i] + 1e-3, 1) - max(u[i] - 1e-3, 0))
        unc[p.name] = su * dv
        if p.at_bound(u[i]):
            at_bound.append(p.name)
    k = effect.n_fitted
    dbic = n * math.log(e1 ** 2) + k * math.log(n) - n * math.log(e0 ** 2) if n else math.inf
    # validation: the cells of the validation segments the effect acts on
    vsel = [i for i in pb.val if effect.acts_on(segs[i])]
    v0, nv = _rms(pb.base_errs, pb.masks, vsel)
    v_errs = _errors_with(pb, effect, best, np.array(vsel, int))
    v1, _ = _rms(v_errs, pb.masks, vsel)
    floor = cfg_floor(pb)
    significant = dbic < -cfg.bic_threshold and e1 <= (1 - cfg.min_reduction) * e0 and e0 > cfg.noise_margin * floor
    plausible = all(p.is_plausible(best[p.name]) for p in params) and not at_bound and effect.plausible(best)
    validated = nv > 0 and v1 <= (1 - cfg.validation_min_reduction) * v0
    c_errs = _errors_with(pb, effect, best, pb.cal)
    fixes = _fixes(pb, pb.base_errs, c_errs, [i for i in pb.cal if effect.acts_on(segs[i])])
    return CandidateFit(effect, best, unc, tuple(undetermined), tuple(at_bound), k, float(dbic), e0, e1, v0, v1, nv,
                        bool(significant), bool(plausible), bool(validated), fixes, effect.apply(pb.base_state, best))


def cfg_floor(pb: _Problem) -> float:
    return pb.floor


def _simplex(u0, step):
    n = u0.size
    s = [u0.copy()]
    for i in range(n):
        v = u0.copy()
        v[i] = v[i] + step if v[i] + step <= 1 else v[i] - step
        s.append(v)
    return np.array(s)


def _polish(err, u0: np.ndarray, e0: float, free: np.ndarray, step: float, maxfev: int) -> tuple[np.ndarray, float]:
    """Nelder–Mead on the unit cube over the ``free`` coordinates from ``u0`` (error ``e0``); when it ends with a
    coordinate on a bound it is restarted once with a fresh simplex of half the step: a simplex that collapses
    against a bound (a factor started on its search bound by the grid) stalls there while the other coordinates
    could still lower ``E``. Returns (u, E) — ``u0`` when nothing is better."""
    u, e = u0.copy(), e0
    idx = np.flatnonzero(free)

    def f(x):
        v = u0.copy()
        v[idx] = np.clip(x, 0, 1)
        return err(v)

    for h in (step, 0.5 * step):
        x0 = u[idx]
        res = scipy.optimize.minimize(f, x0, method="Nelder-Mead",
                                      options={"maxfev": maxfev, "xatol": 2e-3, "fatol": 1e-4,
                                               "initial_simplex": _simplex(x0, h)})
        if not res.fun < e - 1e-4:
            break
        u = u.copy()
        u[idx] = np.clip(res.x, 0, 1)
        e = float(res.fun)
        if not np.any((u[idx] < 0.01) | (u[idx] > 0.99)):
            break
    return u, e


def _fixes(pb, before, after, sel) -> pd.DataFrame:
    """Per rail and band: RMS error [dB] before/after on the given segments (the bands and rail it fixes)."""
    rows: dict = {}
    segs = pb.ev.evidence.segments
    bt = pb.ev.evidence.band_table
    for i in sel:
        s = segs[i]
        for j, rail in enumerate(s.rails):
            for k, b in enumerate(s.bands):
                if pb.masks[i][j, k] and np.isfinite(before[i][j, k]) and np.isfinite(after[i][j, k]):
                    r = rows.setdefault((rail, int(b)), [[], []])
                    r[0].append(before[i][j, k])
                    r[1].append(after[i][j, k])
    out = []
    for (rail, b), (e0, e1) in sorted(rows.items()):
        a0, a1 = float(np.sqrt(np.mean(np.square(e0)))), float(np.sqrt(np.mean(np.square(e1))))
        out.append({"rail": rail, "wavelength_mm": round(1e3 * bt[b, 0], 2), "before_db": a0, "after_db": a1,
                    "fixed": bool(a1 <= 0.5 * a0 and a0 - a1 > 1.0)})
    return pd.DataFrame(out, columns=["rail", "wavelength_mm", "before_db", "after_db", "fixed"])


# --------------------------------------------------------------------------- the loop
def _fit_all(candidates, workers):
    if workers <= 1 or len(candidates) <= 1 or "fork" not in multiprocessing.get_all_start_methods():
        return [_fit(c) for c in candidates]
    ctx = multiprocessing.get_context("fork")
    with ProcessPoolExecutor(max_workers=min(workers, len(candidates)), mp_context=ctx) as ex:
        return list(ex.map(_fit, candidates))


def _residual(ev, errs, masks, floor, margin) -> pd.DataFrame:
    rows: dict = {}
    for s, e, m in zip(ev.segments, errs, masks):
        for j, rail in enumerate(s.rails):
            v = e[j][m[j] & np.isfinite(e[j])]
            if v.size:
                rows.setdefault((s.from_m, s.to_m, rail), []).append(v)
    out = []
    for (a, b, rail), parts in sorted(rows.items()):
        v = np.concatenate(parts)
        out.append({"from_m": a, "to_m": b, "rail": rail, "mean_error_db": float(v.mean()),
                    "rms_error_db": float(np.sqrt(np.mean(v ** 2))), "n_cells": int(v.size)})
    df = pd.DataFrame(out, columns=["from_m", "to_m", "rail", "mean_error_db", "rms_error_db", "n_cells"])
    if df.empty:
        return df.assign(unexplained=pd.Series(dtype=bool))
    med = float(df["rms_error_db"].median())
    return df.assign(unexplained=(df["rms_error_db"] > margin * floor) & (df["rms_error_db"] > 2 * med))


def _by_band(ev, stages: list[tuple[str, list]], masks) -> pd.DataFrame:
    rows = []
    bt = ev.band_table
    for stage, errs in stages:
        acc: dict = {}
        for si, (s, e, m) in enumerate(zip(ev.segments, errs, masks)):
            part = "calibration" if ev.calibration[si] else "validation"
            for j, rail in enumerate(s.rails):
                for k, b in enumerate(s.bands):
                    if m[j, k] and np.isfinite(e[j, k]):
                        acc.setdefault((part, rail, int(b), s.role), []).append(e[j, k])
        for (part, rail, b, role), v in sorted(acc.items()):
            v = np.asarray(v)
            rows.append({"stage": stage, "set": part, "rail": rail, "role": role,
                         "wavelength_mm": round(1e3 * bt[b, 0], 2), "mean_error_db": float(v.mean()),
                         "rms_error_db": float(np.sqrt(np.mean(v ** 2))), "n_cells": int(v.size)})
    return pd.DataFrame(rows)


def _rank(c: CandidateFit) -> tuple[bool, float]:
    """Sort key: plausible candidates first, each group by ΔBIC (module docstring)."""
    return (not c.plausible, c.delta_bic)


def diagnose_field(evaluator, candidates: list[FieldEffect], config, *, state: FieldState = FieldState()
                   ) -> FieldDiagnosis:
    """Fit every candidate, rank by the penalised criterion, accept the best one that passes, repeat.

    Parameters
    ----------
    evaluator : Evaluator
        The evidence (calibration and validation segments) and the forward model.
    candidates : list of FieldEffect
        The catalogue at its locations (:func:`estimator.diagnosis.effects.catalogue`).
    config : DiagnosisConfig
    state : FieldState
        Effects already known (start of the search).

    Returns
    -------
    FieldDiagnosis

    Raises
    ------
    FieldDiagnosisError
        No calibration cell (the site holds no usable evidence).
    """
    global _PROBLEM
    ev = evaluator.evidence
    masks = cell_masks(ev, config.min_reference_snr_db)
    errs = evaluator.errors(state)
    cal = np.flatnonzero(ev.calibration)
    e0, n0 = _rms(errs, masks, cal)
    if n0 == 0:
        raise FieldDiagnosisError(f"no calibration cell on the site {ev.site[0]:g}-{ev.site[1]:g} m: no run segment "
                                  f"with a reference above its noise there ({len(ev.rejected)} segment(s) rejected)")
    floor, scatter, ref_db, inv_db = noise_floor(ev, errs, masks, evaluator.inversion_floor(state))
    workers = config.workers or max(1, min(2, len(os.sched_getaffinity(0))))
    criterion = CRITERION.format(bic=config.bic_threshold, red=100 * config.min_reduction, margin=config.noise_margin,
                                 val=100 * config.validation_min_reduction)
    rounds, accepted = [], []
    start_state = state
    stages = [("nominal", errs)]  # "nominal": the model the search starts from (a previous calibration, if given)
    remaining = list(candidates)
    while len(accepted) < config.max_effects and remaining:
        _PROBLEM = _Problem(evaluator, masks, state, errs, config)
        _PROBLEM.floor = floor
        fits = sorted(_fit_all(remaining, workers), key=_rank)
        rounds.append(tuple(fits))
        best = next((c for c in fits if c.passes), None)
        for c in fits[:5]:
            log.info("field diagnosis round %d: %s ΔBIC %.1f, E %.2f → %.2f dB, validation %.2f → %.2f dB: %s",
                     len(rounds), c.effect.label(), c.delta_bic, c.error_before, c.error_after,
                     c.validation_before, c.validation_after, c.verdict())
        if best is None:
            break
        accepted.append(best)
        state = best.state
        errs = evaluator.errors(state)
        stages.append((f"+ {best.effect.label()}", errs))
        # the accepted location is not offered again; other locations of the same kind stay candidates
        remaining = [c for c in remaining if c != best.effect]
    _PROBLEM = None
    val = np.flatnonzero(~ev.calibration)
    err_rows = []
    for stage, es in stages:
        for part, sel in (("calibration", cal), ("validation", val)):
            e, n = _rms(es, masks, sel)
            err_rows.append({"stage": stage, "set": part, "error_db": e, "n_cells": n})
    residual = _residual(ev, errs, masks, floor, config.noise_margin)
    e_end, _ = _rms(errs, masks, cal)
    if accepted:
        verdict = (f"{len(accepted)} effect(s) accepted: " + ", ".join(c.effect.label() for c in accepted)
                   + f"; calibration error {e0:.2f} → {e_end:.2f} dB (noise floor {floor:.2f} dB)")
    else:
        base = "the nominal model's" if start_state.is_nominal else "the starting calibration's"
        verdict = f"nothing accepted: {base} error {e0:.2f} dB"
    if e_end > config.noise_margin * floor:
        where = residual[residual["unexplained"]]
        loc = "; ".join(f"{r.from_m:g}-{r.to_m:g} m rail {r.rail} ({r.rms_error_db:.1f} dB)"
                        for r in where.itertuples()) or "spread over the site (no stretch stands out)"
        verdict += (f". No effect of the catalogue explains the residual {e_end:.2f} dB (> {config.noise_margin:g} × "
                    f"noise floor {floor:.2f} dB); it lies at: {loc}")
    else:
        verdict += f". The residual {e_end:.2f} dB is at the noise floor ({floor:.2f} dB)"
    return FieldDiagnosis(tuple(rounds), tuple(accepted), state, floor, scatter, ref_db, inv_db, pd.DataFrame(err_rows),
                          residual, _by_band(ev, stages, masks), verdict, criterion)
