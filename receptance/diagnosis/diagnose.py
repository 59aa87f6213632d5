"""Diagnosis: which catalogued physical effect explains where the model fails (and how large it is).

For every candidate effect of :mod:`receptance.diagnosis.effects` the
diagnosis fits its parameters to the measured FRFs of all setups
(:func:`receptance.diagnosis.fitting.fit_effect`: smoothed spectra, the
physics alone) and scores the fit (:mod:`receptance.diagnosis.misfit`:
summary error ``E`` over channel × octave bands, its noise floor).  The
octave cells, the noise floor, every fit and every score cover one band,
``band_hz`` (default 10–500 Hz; the comparison's band in the lab workflow):
a wheelset hung from soft slings shows its rig modes only in a band that
starts near them.

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
figure for a perfect model); it is *plausible* when its fitted values lie
inside their bounds.  The best significant, plausible physical effect (or
``residuals``) is accepted; ``experimental_mode`` is never accepted as an
explanation: it can describe a mode the FE lacks but says nothing of its
cause, and the report says so.  After accepting an effect the diagnosis
runs again on the improved model and finds the next one; a candidate of an
earlier round starts from its previous values.

Robustness.  An effect that cannot be attached to the model (a point it
needs is missing, the FE cannot tell where a part is) is reported — logged
at WARNING and listed in :attr:`Diagnosis.not_applicable` with the reason and
what would make it apply — and the diagnosis goes on; so does it when a
candidate's fit fails for any other reason.  Only the toolkit's own named
errors (:class:`~receptance.diagnosis.errors.DiagnosisError`,
:class:`~receptance.modal_model.ModelError`) leave :func:`diagnose`.

Speed.  The candidates of a round are independent fits: they run in
parallel worker processes (one per usable core, at most one per candidate,
BLAS limited to one thread in each), longest first.  ``workers=1`` fits them
one after the other in the calling process.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import time
import traceback
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from ema._blas import one_blas_thread
from receptance.diagnosis.effects import EFFECTS, Effect
from receptance.diagnosis.errors import DiagnosisError, EffectNotApplicable
from receptance.diagnosis.fitting import BIC_THRESHOLD, MIN_REDUCTION, NOISE_MARGIN, EffectFit, fit_effect
from receptance.diagnosis.misfit import DEFAULT_BAND_HZ, Measurement, Misfit, check_band, misfit
from receptance.modal_model import ModalModel, ModelError
from receptance.wheelset_description import WheelsetDescription

__all__ = ["Diagnosis", "RoundResult", "diagnose", "rank_effects", "usable_cores"]

log = logging.getLogger("receptance")

#: the longest fits first, so that two workers finish together (measured cost order on the virtual lab)
_COST_ORDER = ("axlebox_bearing", "wheel_seat_joint", "rig_suspension", "mass_loading", "experimental_mode",
               "residuals")


def usable_cores() -> int:
    """Cores this process may run on (its CPU affinity), at least 1."""
    try:
        return max(len(os.sched_getaffinity(0)), 1)
    except AttributeError:  # pragma: no cover - platforms without affinity
        return max(os.cpu_count() or 1, 1)


@dataclass(frozen=True)
class RoundResult:
    """One round of :func:`rank_effects`: the model's misfit, the ranked fits, what could not be tried."""

    before: Misfit
    fits: tuple[EffectFit, ...]
    not_applicable: tuple[dict, ...] = ()
    seconds: dict = field(default_factory=dict)
    workers: int = 1


# ------------------------------------------------------------------------------- worker processes
_WORKER: dict = {}


def _init_worker(model, measurements, before, description, band_hz) -> None:
    from threadpoolctl import threadpool_limits

    # one BLAS thread per process: the workers already use every core
    _WORKER["limits"] = threadpool_limits(limits=1)
    _WORKER.update(model=model, measurements=measurements, before=before, description=description, band_hz=band_hz)


def _fit_in_worker(effect: Effect, start: dict | None):
    return _fit_one(effect, _WORKER["model"], _WORKER["measurements"], _WORKER["before"], _WORKER["description"],
                    start, _WORKER["band_hz"])


def _fit_one(effect, model, measurements, before, description, start, band_hz):
    """Fit one candidate; never raises: ("fit", EffectFit) | ("not_applicable", dict) | ("failed", dict, text)."""
    t0 = time.perf_counter()
    try:
        fit = fit_effect(effect, model, measurements, before=before, description=description, start=start,
                         band_hz=band_hz)
        return ("fit", fit, time.perf_counter() - t0)
    except EffectNotApplicable as exc:
        return ("not_applicable", exc.to_dict(), time.perf_counter() - t0)
    except Exception as exc:  # noqa: BLE001 - a candidate's failure must not end the diagnosis
        return ("failed", {"name": effect.name, "reason": f"fitting failed: {type(exc).__name__}: {exc}",
                           "what_would_make_it_apply": "report this with the input files: it is a fault of the "
                                                       "toolkit or of an unusual FE export"},
                time.perf_counter() - t0, traceback.format_exc())


def _context():
    methods = multiprocessing.get_all_start_methods()
    # fork shares the parent's imported modules (and effects a user registered in a script); elsewhere spawn
    return multiprocessing.get_context("fork" if "fork" in methods else "spawn")


def _run_fits(jobs, model, measurements, before, description, workers, progress, band_hz):
    """Every (effect, start) of ``jobs`` fitted, in parallel when ``workers > 1``; results in completion order."""
    results = []

    def report(effect, out):
        results.append((effect, out))
        if progress and out[0] == "fit":
            f = out[1]
            progress(f"{f.name}: error {f.error_before:.4f} -> {f.error_after:.4f}, dBIC {f.delta_bic:.3g}, "
                     f"{f.n_fitted} fitted numbers ({out[2]:.1f} s, {f.n_evaluations} evaluations)")
        elif progress:
            progress(f"{effect.name}: not applicable: {out[1]['reason']}")

    if workers > 1 and len(jobs) > 1:
        done = set()
        try:
            with ProcessPoolExecutor(max_workers=min(workers, len(jobs)), mp_context=_context(),
                                     initializer=_init_worker,
                                     initargs=(model, measurements, before, description, band_hz)) as pool:
                futures = {pool.submit(_fit_in_worker, e, s): e for e, s in jobs}
                for fut in as_completed(futures):
                    e = futures[fut]
                    report(e, fut.result())
                    done.add(e.name)
            return results
        except (BrokenProcessPool, OSError, RuntimeError) as exc:
            log.warning("parallel fitting stopped (%s: %s); fitting the remaining candidates here", type(exc).__name__,
                        exc)
            jobs = [(e, s) for e, s in jobs if e.name not in done]
    for e, s in jobs:
        report(e, _fit_one(e, model, measurements, before, description, s, band_hz))
    return results


@one_blas_thread
def rank_effects(model: ModalModel, measurements: Sequence[Measurement], *,
                 catalogue: Sequence[Effect] | None = None, skip: Sequence[str] = (),
                 progress: Callable[[str], None] | None = None, description: WheelsetDescription | None = None,
                 workers: int | None = None, starts: dict | None = None,
                 band_hz: tuple[float, float] = DEFAULT_BAND_HZ) -> RoundResult:
    """Fit every candidate and rank by ΔBIC (most negative first).

    Parameters
    ----------
    model, measurements
    catalogue : sequence of Effect, optional
        Default: one of each registered effect.
    skip : sequence of str
        Names not to try (effects already accepted).
    progress : callable, optional
        Receives one line per fitted candidate.
    description : WheelsetDescription, optional
    workers : int, optional
        Parallel processes (default: the usable cores).
    starts : dict, optional
        Starting values per effect name (a previous round's fits).
    band_hz : (float, float)
        The diagnosis band (module docstring).
    """
    before = misfit(model, measurements, band_hz=band_hz)
    effects = list(catalogue) if catalogue is not None else [cls() for cls in EFFECTS.values()]
    jobs = [e for e in effects if e.name not in skip and e.in_test]
    jobs.sort(key=lambda e: _COST_ORDER.index(e.name) if e.name in _COST_ORDER else -1)
    n_workers = max(1, min(usable_cores() if workers is None else int(workers), len(jobs)))
    results = _run_fits([(e, (starts or {}).get(e.name)) for e in jobs], model, measurements, before, description,
                        n_workers, progress, tuple(band_hz))
    fits, not_applicable, seconds = [], [], {}
    for effect, out in results:
        seconds[effect.name] = float(out[2])
        if out[0] == "fit":
            fits.append(out[1])
            continue
        not_applicable.append(out[1])
        log.warning("candidate %s %s: %s; to apply it: %s", effect.name,
                    "failed" if out[0] == "failed" else "not applicable", out[1]["reason"],
                    out[1]["what_would_make_it_apply"])
        if out[0] == "failed":
            log.debug("%s", out[3])
    order = {e.name: k for k, e in enumerate(effects)}
    fits.sort(key=lambda f: (f.delta_bic, order.get(f.name, 0)))
    not_applicable.sort(key=lambda d: order.get(d["name"], 0))
    return RoundResult(before, tuple(fits), tuple(not_applicable), seconds, n_workers)


@dataclass(frozen=True)
class Diagnosis:
    """Result of :func:`diagnose`: accepted effects in the order added, every round's ranked candidates.

    Attributes
    ----------
    accepted : tuple of EffectFit
    rounds : tuple of tuple of EffectFit
        Every round's candidates, ranked by ΔBIC.
    initial, final : Misfit
    model : ModalModel
        The model with every accepted effect.
    unexplained : tuple of str
    not_applicable : tuple of dict
        ``{name, reason, what_would_make_it_apply}`` of every candidate that
        could not be tried (or whose fit failed), latest reason per name.
    seconds : tuple of dict
        Per round, seconds per candidate.
    workers : int
        Parallel processes used.
    noise : str
        How the noise floor was obtained.
    band_hz : (float, float)
        The band whose octave cells every error, floor and score covered.
    """

    accepted: tuple[EffectFit, ...]
    rounds: tuple[tuple[EffectFit, ...], ...]
    initial: Misfit
    final: Misfit
    model: ModalModel = field(repr=False)
    unexplained: tuple[str, ...] = ()
    not_applicable: tuple[dict, ...] = ()
    seconds: tuple[dict, ...] = ()
    workers: int = 1
    noise: str = ""
    band_hz: tuple[float, float] = DEFAULT_BAND_HZ

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
                              "error_after": f.error_after, "role": f.role, "assumptions": list(f.assumptions)}
                             for f in self.accepted],
                "candidates": [[f.to_dict() for f in r] for r in self.rounds][-1] if self.rounds else [],
                "rounds": [[f.to_dict() for f in r] for r in self.rounds],
                "not_applicable": [dict(d) for d in self.not_applicable],
                "residual": self.residual(),
                "criterion": f"BIC = N ln E6^2 + k ln N over N channel x sixth-octave cells of "
                             f"{self.band_hz[0]:g}-{self.band_hz[1]:g} Hz; significant if dBIC < -{BIC_THRESHOLD:g}, "
                             f"E falls by >= {100 * MIN_REDUCTION:g} % and E was above {NOISE_MARGIN:g} x the noise "
                             f"floor; plausible if inside bounds",
                "initial": {"summary_error": self.initial.summary, "noise_floor": self.initial.noise_floor},
                "band_hz": list(self.band_hz),
                "noise_floor_method": self.noise,
                "candidate_seconds": [dict(s) for s in self.seconds], "workers": self.workers}


def diagnose(model: ModalModel, measurements: Sequence[Measurement], *, catalogue: Sequence[Effect] | None = None,
             max_effects: int = 3, progress: Callable[[str], None] | None = None,
             description: WheelsetDescription | None = None, workers: int | None = None,
             band_hz: tuple[float, float] = DEFAULT_BAND_HZ) -> Diagnosis:
    """Find the missing effects one after the other (module docstring).

    Parameters
    ----------
    model : ModalModel
    measurements : sequence of Measurement
    catalogue : sequence of Effect, optional
        Default: one of each registered effect.
    max_effects : int
        Most effects accepted one after the other.
    progress : callable, optional
    description : WheelsetDescription, optional
    workers : int, optional
        Parallel processes (default: the usable cores).
    band_hz : (float, float)
        The diagnosis band [Hz], default 10–500: its octave cells
        (:func:`receptance.diagnosis.misfit.octave_edges`) define ``E``, the
        noise floor and every fit and score; checked against every setup's
        lines (:func:`receptance.diagnosis.misfit.check_band`).

    Raises
    ------
    DiagnosisError, ModelError
        The measurements or the model cannot be compared at all (names what);
        a candidate's failure is reported in the result instead.
    """
    try:
        return _diagnose(model, measurements, catalogue, max_effects, progress, description, workers,
                         tuple(float(b) for b in band_hz))
    except (ModelError, DiagnosisError):
        raise
    except Exception as exc:  # noqa: BLE001 - only the toolkit's own errors leave diagnose
        log.debug("%s", traceback.format_exc())
        raise DiagnosisError(f"the diagnosis failed outside any candidate: {type(exc).__name__}: {exc}") from exc


@one_blas_thread
def _diagnose(model, measurements, catalogue, max_effects, progress, description, workers, band_hz) -> Diagnosis:
    if not measurements:
        raise DiagnosisError("no measurement to diagnose against")
    if max_effects < 0:
        raise DiagnosisError(f"max_effects must be >= 0, got {max_effects!r}")
    check_band(band_hz, measurements)
    current = model
    initial = misfit(model, measurements, band_hz=band_hz)
    accepted, rounds, unexplained, seconds = [], [], [], []
    not_applicable: dict[str, dict] = {}
    skip: list[str] = []
    starts: dict[str, dict] = {}
    used = 1
    for _ in range(max_effects):
        r = rank_effects(current, measurements, catalogue=catalogue, skip=skip, progress=progress,
                         description=description, workers=workers, starts=starts, band_hz=band_hz)
        used = max(used, r.workers)
        rounds.append(r.fits)
        seconds.append(r.seconds)
        for d in r.not_applicable:
            not_applicable[d["name"]] = d
        for f in r.fits:
            if f.params and f.physical:
                starts[f.name] = dict(f.params)
        pick = next((f for f in r.fits if f.significant and f.plausible and f.name != "experimental_mode"), None)
        patch = next((f for f in r.fits if f.significant and f.name == "experimental_mode"), None)
        if patch is not None and (pick is None or patch.delta_bic < pick.delta_bic):
            unexplained.append(patch.note)
        if pick is None:
            break
        accepted.append(pick)
        skip.append(pick.name)
        current = pick.model
        if progress:
            progress(f"accepted {pick.name} {pick.params}: error {pick.error_before:.4f} -> {pick.error_after:.4f}")
    final = misfit(current, measurements, band_hz=band_hz)
    if final.summary > NOISE_MARGIN * final.noise_floor:
        worst = final.per_band.assign(excess=final.per_band["rel_error"] ** 2 - final.per_band["noise"] ** 2)
        bands = worst.groupby(["band_lo_hz", "band_hi_hz"])["excess"].sum().sort_values(ascending=False)
        chans = worst.groupby(["setup", "channel"])["excess"].sum().sort_values(ascending=False)
        (lo, hi), _ = next(iter(bands.items()))
        unexplained.append(
            f"no catalogued effect explains the remaining error: E = {final.summary:.3f} is "
            f"{final.summary / final.noise_floor:.1f} x the noise floor {final.noise_floor:.3f}; most of it sits in "
            f"{lo:g}-{hi:g} Hz, on " + ", ".join(f"{s}/{c}" for s, c in list(chans.index[:4])))
    noise = "; ".join(sorted({f"{m.setup}: {m.noise_method}" for m in measurements}))
    return Diagnosis(tuple(accepted), tuple(rounds), initial, final, current, tuple(unexplained),
                     tuple(not_applicable.values()), tuple(seconds), used, noise, band_hz)
