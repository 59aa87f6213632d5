"""Fitting one catalogued effect to the measured FRFs, and scoring the fit.

The complex misfit of a stiffness is full of narrow valleys (a sharp mode
sliding past a measured peak), so the parameters are fitted on smoothed log
spectra.  A global stage on sixth-octave levels finds the basin
(:func:`_global_search`) from the effect's whole physical bounds, never from
a start tuned to one wheelset: a joint space-filling design (scrambled
Sobol points, their number scaled to the parameter count) — parameters are
coupled (the left bearing's rocking and the right/left ratio move the same
modes), so a search of one parameter at a time from a fixed start lands in
whichever valley the start lies in — then local coordinate passes (±2 grid
steps) from the best few distinct points, and from the best of them a sweep
of each parameter over its whole bounds at the resolution the sixth-octave
levels resolve (a narrow basin — an axial mode sliding past one measured
peak — that a coarse joint design steps over) and a small simplex search.
A side ratio (``right_over_left``) is searched with the geometric mean of
the two sides of the parameters it scales (:attr:`Parameter.scales`), not
one side's value: left and right swapped is otherwise a second valley.
Evaluations grow linearly with the parameter count (about 550 for the
bearing's four, 100 for one).  A finer pass and a bounded
least-squares polish on 24th-octave levels (3 % bands, a few half-power
bandwidths of a 0.5 %-damped mode) place the modes.  The fit sees the
physics alone — the design model (FE frequencies) plus the effect, so that
the stiffness is what moves the modes from their FE to their measured
frequencies; the scored model then gives every mode that carries a measured
one the test's frequency and damping (paired modes and, within 3 %,
test-only modes: :class:`~receptance.modal_model.ModalModel`), as the hybrid
model does.  Uncertainties come from the polish's Jacobian.
Every level, cell and score covers the diagnosis band ``band_hz`` (its
octave cells: :func:`receptance.diagnosis.misfit.octave_edges`).

Criterion (:mod:`receptance.diagnosis.diagnose` applies it): the Bayesian
information criterion over the ``N`` cells of channel × sixth-octave band,
``BIC = N ln E_6² + k ln N`` with ``k`` every number the fit adjusts; a
candidate is significant when it lowers BIC by more than
:data:`BIC_THRESHOLD`, lowers ``E`` by at least :data:`MIN_REDUCTION` and
the model's error was above :data:`NOISE_MARGIN` times the noise floor.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np
import pandas as pd
import scipy.optimize
from scipy.stats import qmc

from ema._blas import one_blas_thread
from receptance.diagnosis.effects import Attachment, Effect, ExperimentalMode, Residuals
from receptance.diagnosis.errors import DiagnosisError
from receptance.diagnosis.misfit import DEFAULT_BAND_HZ, Measurement, Misfit, check_band, misfit, model_frfs
from receptance.modal_model import ModalModel
from receptance.wheelset_description import WheelsetDescription

__all__ = ["EffectFit", "fit_effect", "BIC_THRESHOLD", "MIN_REDUCTION", "NOISE_MARGIN", "UNDETERMINED_DE",
           "COARSE_POINTS", "GLOBAL_POINTS_PER_PARAMETER", "GLOBAL_STARTS", "SWEEP_DECADES", "SIMPLEX_EVALUATIONS",
           "LOCAL_POINTS", "FINE_POINTS", "POLISH_NFEV", "SCORED_POINTS", "SCORED_SPAN"]

BIC_THRESHOLD = 10.0
MIN_REDUCTION = 0.10
NOISE_MARGIN = 1.2
#: a fitted parameter whose halving or doubling moves the summary error by less than this share is undetermined
UNDETERMINED_DE = 0.01
#: the grid of the local passes: COARSE_POINTS log-spaced values span a parameter's bounds, a local pass tries
#: LOCAL_POINTS grid steps around the best; values per parameter of the fine pass (±0.15 decade); function
#: evaluations of the least-squares polish
COARSE_POINTS = 13
#: the global stage: scrambled Sobol points per fitted parameter (a power of two at least this many times the
#: parameter count, so the joint design grows with the dimension, not exponentially as a grid would), and how many
#: of its best mutually distinct points are refined locally
GLOBAL_POINTS_PER_PARAMETER = 32
GLOBAL_STARTS = 3
#: the step [decades] of the whole-bounds sweep: sixth-octave levels resolve a frequency shift of 2^(1/6), and a
#: stiffness (or mass) moves its modes as its square root (f = sqrt(k/m) / 2 pi), so 2^(1/3) in the parameter
SWEEP_DECADES = 2 * float(np.log10(2.0)) / 6
#: function evaluations per parameter of the joint (Nelder-Mead) step that ends the global stage
SIMPLEX_EVALUATIONS = 20
LOCAL_POINTS = 5
FINE_POINTS = 5
POLISH_NFEV = 10
#: the last pass on the scored error: values per parameter within ±SCORED_SPAN decades
SCORED_POINTS = 5
SCORED_SPAN = 0.1


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
    assumptions: tuple[str, ...] = ()
    role: str = ""
    seconds: float = 0.0
    n_evaluations: int = 0
    attachment: Attachment | None = field(default=None, repr=False)

    @property
    def reduction(self) -> float:
        return 1 - self.error_after / self.error_before if self.error_before > 0 else 0.0

    def to_dict(self) -> dict:
        return {"name": self.name, "physical": self.physical, "role": self.role, "params": self.params,
                "uncertainty_rel": self.uncertainty, "bounds": self.bounds, "at_bound": list(self.at_bound),
                "n_fitted": self.n_fitted, "delta_bic": self.delta_bic, "error_before": self.error_before,
                "error_after": self.error_after, "significant": self.significant, "plausible": self.plausible,
                "fixes": self.fixes.head(8).to_dict(orient="records"), "note": self.note,
                "assumptions": list(self.assumptions), "seconds": self.seconds,
                "n_evaluations": self.n_evaluations}


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
               before: Misfit | None = None, description: WheelsetDescription | None = None,
               start: dict | None = None, band_hz: tuple[float, float] = DEFAULT_BAND_HZ) -> EffectFit:
    """Fit one effect's parameters (log scale, inside their bounds) and score it (module docstring).

    Parameters
    ----------
    effect : Effect
    model : ModalModel
    measurements : sequence of Measurement
    before : Misfit, optional
        The model's misfit (computed when not given).
    description : WheelsetDescription, optional
        What the FE cannot tell (Table 2.1 defaults otherwise).
    start : dict, optional
        Values by parameter name (e.g. a previous round's fit) tried with the
        global stage's design, as the catalogue's starting values are.
    band_hz : (float, float)
        The diagnosis band: its octave cells define the error, the noise floor,
        the smoothed spectra and the score (``before`` must be on the same band).

    Raises
    ------
    EffectNotApplicable
        The effect cannot be attached to this model.
    DiagnosisError
        The band does not suit the measured lines (:func:`~receptance.diagnosis.misfit.check_band`).
    """
    t0 = time.perf_counter()
    edges = check_band(band_hz, measurements)
    before = before or misfit(model, measurements, band_hz=band_hz)
    tables = [m.channels for m in measurements]
    if isinstance(effect, Residuals):
        effect = _fit_residuals(model, measurements, edges)
        att = effect.attach(model, tables, description)
        return _score(att, {}, {}, model, measurements, before, tables, band_hz, t0=t0, n_eval=1)
    if isinstance(effect, ExperimentalMode):
        effect = _fit_experimental_mode(model, measurements, before, edges)
        if effect is None:
            raise DiagnosisError("experimental_mode: no measured peak left to describe")
        att = effect.attach(model, tables, description)
        return _score(att, {"f_hz": effect.f_hz, "zeta": effect.zeta}, {}, model, measurements, before, tables,
                      band_hz, t0=t0, n_eval=1)
    # the parameters are fitted on the physics alone (FE frequencies + effect, nothing pinned): pinned modes
    # would flatten the misfit around the very frequency shifts that tell the stiffness (the scored model pins)
    physics = model.as_designed()
    att = effect.attach(physics, tables, description)
    params = att.parameters
    lo = np.log10([p.lower for p in params])
    hi = np.log10([p.upper for p in params])
    x0 = np.log10([p.initial for p in params])
    if start:
        x0 = np.array([np.clip(np.log10(start[p.name]), a, b) if p.name in start and start[p.name] > 0 else v
                       for p, v, a, b in zip(params, x0, lo, hi)])
    count = [0]

    def frfs(x, stride):
        count[0] += 1
        return model_frfs(att.apply(physics, {p.name: 10 ** v for p, v in zip(params, x)}), measurements, stride)

    # smoothed log spectra have broad basins where the complex misfit has narrow valleys
    coarse = _SmoothSpectra(measurements, edges, stride=4)
    fine = _SmoothSpectra(measurements, edges, per_octave=24, stride=2)

    def coarse_cost(x):
        return coarse.cost(frfs(x, 4))

    def fine_cost(x):
        return fine.cost(frfs(x, 2))

    # the catalogue's starting values (and a previous round's fit) are two more points of the global design, not
    # where the search begins: a start that suits one wheelset puts another in the wrong valley
    initial = np.log10([p.initial for p in params])
    # a side ratio's parameters are searched as their geometric mean over the two sides (Parameter.scales), x = A y:
    # the ratio then moves the two sides apart, not one side away from the other
    A = np.eye(len(params))
    for j, p in enumerate(params):
        A[[i for i, q in enumerate(params) if q.name in p.scales], j] = -0.5
    y, _ = _global_search(lambda y: coarse_cost(A @ y), lo, hi,
                          starts=[np.linalg.solve(A, s) for s in ([x0, initial] if start else [x0])])
    x = np.clip(A @ y, lo, hi)
    best = fine_cost(x)
    if FINE_POINTS > 1:
        x, best = _coordinate_pass(x, best, fine_cost, lambda i, x: np.clip(
            x[i] + np.linspace(-0.15, 0.15, FINE_POINTS), lo[i], hi[i]))
    res = scipy.optimize.least_squares(lambda x: fine.residuals(frfs(x, 2)), x, bounds=(lo, hi), diff_step=1e-3,
                                       x_scale=1.0, max_nfev=POLISH_NFEV)
    x = res.x if fine_cost(res.x) <= best else x

    # last, a short pass on the criterion itself: the scored model (measured frequencies pinned) has no sharp valleys
    # left, and its error tells what the smoothed spectra of the physics alone cannot — a design model's own
    # frequency errors (an as-built axle a little stiffer) would otherwise be absorbed by the effect's stiffness
    def scored(x):
        count[0] += 1
        return misfit(att.apply(model, {p.name: 10 ** v for p, v in zip(params, x)}), measurements,
                      band_hz=band_hz).summary

    def scored_values(i, x):
        if params[i].geometric:
            # a place (the slings along the axle) is weakly told by the smoothed levels: its whole range is tried
            return np.linspace(lo[i], hi[i], 2 * SCORED_POINTS - 1)
        return np.clip(x[i] + np.linspace(-SCORED_SPAN, SCORED_SPAN, SCORED_POINTS), lo[i], hi[i])

    if SCORED_POINTS > 1:
        x, _ = _coordinate_pass(x, scored(x), scored, scored_values)
    values = {p.name: float(10 ** v) for p, v in zip(params, x)}
    try:
        J = res.jac
        dof = max(J.shape[0] - len(x), 1)
        cov = np.linalg.inv(J.T @ J) * (2 * res.cost / dof)
        unc = {p.name: float(np.log(10) * np.sqrt(max(cov[i, i], 0))) for i, p in enumerate(params)}
    except np.linalg.LinAlgError:
        unc = {p.name: float("inf") for p in params}
    return _score(att, values, unc, model, measurements, before, tables, band_hz, params=params, x=x, lo=lo, hi=hi,
                  t0=t0, n_eval=count[0])


def _global_search(cost: Callable, lo: np.ndarray, hi: np.ndarray, starts: Sequence = (), *,
                   seed: int = 0) -> tuple[np.ndarray, float]:
    """The basin of ``cost`` over the box ``lo``..``hi`` (log10 of the parameters), searched jointly.

    Three steps, each over the whole bounds (module docstring): ``cost`` at a
    scrambled Sobol design of :data:`GLOBAL_POINTS_PER_PARAMETER` points per
    parameter (rounded up to a power of two) and at ``starts``; local
    coordinate passes (±``LOCAL_POINTS // 2`` steps of the
    :data:`COARSE_POINTS` grid, until no gain, at most two) from the
    :data:`GLOBAL_STARTS` best points that lie more than that many steps
    apart in some parameter; from the best result, a sweep of each parameter
    over its bounds in steps of :data:`SWEEP_DECADES`, a local pass at that
    step and a Nelder–Mead simplex of that size (:data:`SIMPLEX_EVALUATIONS`
    per parameter; coupled parameters move together).  Deterministic
    (``seed`` scrambles the design).

    Parameters
    ----------
    cost : callable
        ``cost(x) -> float`` of a point ``x`` (shape ``(d,)``).
    lo, hi : ndarray
        The bounds, ``lo < hi``.
    starts : sequence of ndarray, optional
        Points added to the design (clipped to the bounds).
    seed : int

    Returns
    -------
    x : ndarray
    cost : float
    """
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    d = lo.size
    u = qmc.Sobol(d, scramble=True, seed=seed).random_base2(int(np.ceil(np.log2(max(GLOBAL_POINTS_PER_PARAMETER * d,
                                                                                       2)))))
    design = [np.clip(np.asarray(s, float), lo, hi) for s in starts] + list(lo + u * (hi - lo))
    costs = np.array([cost(x) for x in design])
    step = (hi - lo) / (COARSE_POINTS - 1)
    half = max((LOCAL_POINTS - 1) // 2, 1)
    chosen: list[int] = []
    for i in np.argsort(costs, kind="stable"):
        if all(np.max(np.abs(design[i] - design[j]) / step) > half for j in chosen):
            chosen.append(int(i))
        if len(chosen) == GLOBAL_STARTS:
            break

    def local(x, best, steps):
        for _ in range(2):
            x_new, best_new = _coordinate_pass(x, best, cost, lambda i, x: np.clip(
                x[i] + steps[i] * np.arange(-half, half + 1), lo[i], hi[i]))
            gained = best_new < best
            x, best = x_new, best_new
            if not gained:
                break
        return x, best

    refined = [local(design[i].copy(), costs[i], step) for i in chosen]
    x, best = min(refined, key=lambda r: r[1])
    # a basin narrower than the design's spacing in one parameter (its mode sliding past one measured peak)
    x, best = _coordinate_pass(x, best, cost, lambda i, x: np.linspace(
        lo[i], hi[i], int(np.ceil((hi[i] - lo[i]) / SWEEP_DECADES)) + 1))
    x, best = local(x, best, np.full(d, SWEEP_DECADES))
    # last, jointly: several parameters a step apart at once (a coupled pair) is a move no coordinate pass makes
    inward = np.where(x + SWEEP_DECADES > hi, -SWEEP_DECADES, SWEEP_DECADES)
    simplex = np.vstack([x] + [x + inward * e for e in np.eye(d)])
    res = scipy.optimize.minimize(cost, x, method="Nelder-Mead", bounds=list(zip(lo, hi)),
                                  options={"initial_simplex": simplex, "maxfev": SIMPLEX_EVALUATIONS * d,
                                           "xatol": 0.01, "fatol": 1e-3 * abs(best)})
    return (res.x, float(res.fun)) if res.fun < best else (x, best)


def _coordinate_pass(x: np.ndarray, best: float, cost: Callable, values: Callable) -> tuple[np.ndarray, float]:
    """One pass of a coordinate search: each parameter in turn takes the best of ``values(i, x)``, others held."""
    for i in range(x.size):
        for v in values(i, x):
            if v == x[i]:
                continue  # the current point's cost is known
            trial = x.copy()
            trial[i] = v
            c = cost(trial)
            if c < best:
                best, x = c, trial
    return x, best


class _SmoothSpectra:
    """Fractional-octave RMS levels of measured and model FRFs: a misfit with broad basins for the searches.

    Over the range of ``bands`` (the diagnosis band's octave edges).
    """

    def __init__(self, measurements, bands, per_octave: int = 6, stride: int = 1):
        self.edges = []
        self.levels = []
        for m in measurements:
            f = m.frf.freqs_hz[::stride]
            lo, hi = max(f[0], bands[0]), min(f[-1], bands[-1])
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


def _insensitive(att, values, name, model, measurements, error: float, band_hz) -> bool:
    for factor in (0.5, 2.0):
        moved = att.apply(model, dict(values, **{name: values[name] * factor}))
        if abs(misfit(moved, measurements, band_hz=band_hz).summary - error) > UNDETERMINED_DE * error:
            return False
    return True


def _score(att: Attachment, values, unc, model, measurements, before, tables, band_hz, *, params=(), x=None,
           lo=None, hi=None, t0=None, n_eval=0) -> EffectFit:
    effect = att.effect
    after_model = att.apply(model, values if params else {})
    after = misfit(after_model, measurements, band_hz=band_hz)
    # every number the fit adjusted: an added geometric parameter (the slings' position, fitted when the
    # description gives none) counts as well as the effect's declared ones
    k = max(effect.n_fitted(tables), len(params))
    d_bic, significant = _bic_fields(before, after, k)
    at_bound, undetermined, at_limit = (), (), []
    if params:
        hit = [p.name for p, v, a, b in zip(params, x, lo, hi) if v - a < 0.02 or b - v < 0.02]
        at_limit = [n for n in hit if any(p.name == n and p.geometric for p in params)]
        hit = [n for n in hit if n not in at_limit]
        # a parameter the data cannot determine (e.g. a horizontal rig stiffness whose modes lie far below the
        # band) drifts, often to a bound: that is "not determined", not "implausible". Judged by what it does to
        # the scored error: halving or doubling it moves E by less than UNDETERMINED_DE (or the fit's own
        # uncertainty exceeds a factor e)
        undetermined = tuple(p.name for p in params
                             if unc.get(p.name, np.inf) > 1.0 or _insensitive(att, values, p.name, model,
                                                                               measurements, after.summary,
                                                                               band_hz))
        at_bound = tuple(n for n in hit if n not in undetermined)
    note = ""
    if undetermined:
        note = f"not determined by the data (flat misfit): {', '.join(undetermined)}. "
    if params and at_limit:
        note += f"at the end of its geometric range: {', '.join(at_limit)}. "
    if isinstance(effect, ExperimentalMode):
        note = (f"describes a measured mode at {effect.f_hz:.2f} Hz (zeta {100 * effect.zeta:.2f} %) that the "
                f"model lacks, by curve fitting; it does not say what physical part makes it")
    seconds = time.perf_counter() - t0 if t0 is not None else 0.0
    return EffectFit(effect.name, effect.physical, values, unc,
                     {p.name: (p.lower, p.upper) for p in params}, at_bound, k, d_bic,
                     before.summary, after.summary, significant, not at_bound, _fixes(before, after), after_model,
                     effect, note, tuple(att.assumptions), effect.role, seconds, n_eval, att)


def _fit_residuals(model, measurements, bands) -> Residuals:
    """Per channel, real lower and upper residuals by weighted linear least squares over the cells ``bands``."""
    lower, upper = {}, {}
    for m, Hm in zip(measurements, model_frfs(model, measurements)):
        s = 2j * np.pi * m.frf.freqs_hz + m.frf.exp_window_decay
        d = m.frf.data[:, 0] - Hm
        w, _ = m.band_weights(bands)
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


def _exp_mode_constants(model, measurements, f, z, model_frfs_, bands):
    consts, resid = {}, []
    for m, Hm in zip(measurements, model_frfs_):
        s = 2j * np.pi * m.frf.freqs_hz + m.frf.exp_window_decay
        w0 = 2 * np.pi * f
        g = s**2 / (s**2 + 2 * z * w0 * s + w0**2)
        d = m.frf.data[:, 0] - Hm
        wt, _ = m.band_weights(bands)
        consts[m.setup] = {}
        for i, name in enumerate(m.frf.outputs):
            gi = g * wt[i]
            a = np.vdot(gi, d[i] * wt[i]) / np.vdot(gi, gi)
            consts[m.setup][name] = complex(a)
            resid.append((d[i] - a * g) * wt[i])
    return consts, np.concatenate(resid)


def _fit_experimental_mode(model, measurements, before: Misfit, bands) -> ExperimentalMode | None:
    frfs = model_frfs(model, measurements)
    # where the unexplained response is largest: sum over channels of the normalised misfit
    f_all = measurements[0].frf.freqs_hz
    power = np.zeros(f_all.size)
    for m, Hm in zip(measurements, frfs):
        if m.frf.freqs_hz.size == f_all.size:
            power += np.sum(np.abs((m.frf.data[:, 0] - Hm) * m.band_weights(bands)[0]) ** 2, axis=0)
    if not np.any(power > 0):
        return None
    f0 = float(f_all[np.argmax(power)])

    def res(x):
        return _exp_mode_constants(model, measurements, x[0], 10 ** x[1], frfs, bands)[1].view(float)

    df = max(f_all[1] - f_all[0], 1e-3)
    sol = scipy.optimize.least_squares(res, [f0, np.log10(0.005)], bounds=([f0 - 5 * df, -4.5], [f0 + 5 * df, -0.7]),
                                       x_scale=[df, 0.1], max_nfev=60)
    f, z = float(sol.x[0]), float(10 ** sol.x[1])
    consts, _ = _exp_mode_constants(model, measurements, f, z, frfs, bands)
    return ExperimentalMode(f_hz=f, zeta=z, constants=consts)
