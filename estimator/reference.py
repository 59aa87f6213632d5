"""A reference roughness (trolley, or a simulation's truth) through the same EN processing, and the comparison.

The reference is processed exactly as the estimate: the EN 13231-3 band
filters and Table 4.1 windows on its own (fine) grid, and EN 15610 Method A
on the same stretches. The comparison is made per band and rail on
chainage windows (1 m by default): in each window the energy mean of the
peak-to-peak amplitude ``sqrt(mean(pk²))`` of estimate and reference, and
the error ``20 lg(pk_est / pk_ref)`` [dB]. Reported: the mean and RMS of
the window errors, the share of windows within ±3 dB, and the error of the
stretch's energy mean — over the windows where the reference is above a
floor (``min_reference_um``: below it a band holds no corrugation to
measure). The reference's chainage is used as given (alignment of a
trolley's own chainage is issue 14's business).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from estimator.config import EstimatorConfig
from estimator.errors import RunFileError
from estimator.results import FieldEstimate
from estimator.standards.en13231 import BandIndexes, band_indexes
from estimator.standards.en15610 import roughness_spectrum

__all__ = ["ReferenceIndexes", "reference_indexes", "on_uniform_grid", "MAX_GAP_STEPS", "MAX_REFERENCE_SAMPLES",
           "window_pk", "compare_bands", "compare_spectra", "models_ranking", "reference_overlap"]

log = logging.getLogger("estimator")


@dataclass(frozen=True, eq=False)
class ReferenceIndexes:
    """EN 13231-3 indexes of a reference per rail on its own uniform grid.

    ``source`` names the record (its file); ``notes`` are what the reader and :func:`reference_indexes` found
    doubtful about it (rows left out, an implausible level, a rail left out), carried into the estimate's report
    and summary by :func:`estimator.export.write_estimate`.
    """

    x: dict
    profile: dict
    indexes: dict
    source: str = "reference"
    notes: tuple = ()

    @property
    def rails(self) -> tuple[str, ...]:
        """The rails that can be compared."""
        return tuple(sorted(self.indexes))

    def span(self, rail: str) -> tuple[float, float]:
        """The chainage span [m] of the reference's rail ``rail``."""
        x = self.x[rail]
        return float(x[0]), float(x[-1])

    def pk_pk(self, band, rail) -> tuple[np.ndarray, np.ndarray]:
        idx = self.indexes[rail]
        return self.x[rail], idx.pk_pk[idx.bands_mm.index(tuple(band))]


#: samples further apart than this many steps of the record's grid are a gap, not interpolated across
MAX_GAP_STEPS = 5
#: Most samples of one rail's reference on its uniform grid: 50 km at 1 mm, the bound of the monitoring's trolley
#: reader too (a trolley measures a few km a shift); more is a reading whose chainage is far from the others (a
#: typo, a chainage in mm) and would not fit in memory.
MAX_REFERENCE_SAMPLES = 50_000_000




def on_uniform_grid(x: np.ndarray, r: np.ndarray, dx: float, x0: float | None = None,
                    x1: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """A reference profile (sorted chainages ``x``) on a uniform grid of step ``dx`` from ``x0`` to ``x1``.

    Linear between neighbouring samples; NaN (a gap: the EN processing masks it) wherever the two samples around a
    grid point are more than :data:`MAX_GAP_STEPS` steps apart — a stretch the trolley did not measure (rows left
    out as unreadable, a lifted trolley) is not replaced by a straight line, whose band amplitudes would be zero.
    """
    x0 = float(x[0]) if x0 is None else x0
    x1 = float(x[-1]) if x1 is None else x1
    steps = (x1 - x0) / dx if dx > 0 else math.inf
    if not (math.isfinite(x0) and math.isfinite(x1) and math.isfinite(steps) and steps + 1 <= MAX_REFERENCE_SAMPLES):
        raise RunFileError(f"chainage {x0:g}-{x1:g} m at a {dx:g} m step is {steps + 1:.3g} samples; a reference "
                           f"rail holds at most {MAX_REFERENCE_SAMPLES} (a reading far from the others: a chainage "
                           "typo, or chainages in mm?)")
    grid = x0 + dx * np.arange(int(round(steps)) + 1)
    if x.size < 2:
        return grid, np.where(np.abs(grid - x[0]) <= 0.5 * dx, r[0], np.nan) if x.size else np.full(grid.size, np.nan)
    v = np.interp(grid, x, r, left=np.nan, right=np.nan)
    j = np.clip(np.searchsorted(x, grid), 1, x.size - 1)
    near = np.minimum(np.abs(grid - x[j - 1]), np.abs(x[j] - grid))
    v[((x[j] - x[j - 1]) > MAX_GAP_STEPS * dx) & (near > 0.5 * dx)] = np.nan
    return grid, v


def reference_indexes(reference: pd.DataFrame, config: EstimatorConfig = EstimatorConfig(),
                      span: tuple[float, float] | None = None, source: str = "reference") -> ReferenceIndexes:
    """Band indexes of a reference table ``chainage_m, rail, roughness_m`` (each rail on a uniform grid,
    :func:`on_uniform_grid`: gaps stay gaps). A rail with fewer than 10 samples is left out with a WARNING, kept
    in the result's ``notes`` with the reader's (``reference.attrs["notes"]``, :func:`estimator.io.read_trolley`).

    Raises
    ------
    RunFileError
        A rail whose chainages span more than :data:`MAX_REFERENCE_SAMPLES` grid steps (names ``source``).
    """
    xs, ps, ids = {}, {}, {}
    notes = list(reference.attrs.get("notes", ()))
    for rail, g in reference.groupby("rail"):
        x = g["chainage_m"].to_numpy(float)
        r = g["roughness_m"].to_numpy(float)
        order = np.argsort(x)
        x, r = x[order], r[order]
        if span is not None:
            sel = (x >= span[0] - 10) & (x <= span[1] + 10)
            x, r = x[sel], r[sel]
        if x.size < 10:
            note = (f"{source}: rail {rail} has {x.size} sample(s)"
                    f"{f' within {span[0]:.1f}-{span[1]:.1f} m' if span is not None else ''} (< 10): not compared")
            log.warning("%s", note)
            notes.append(note)
            continue
        dx = float(np.median(np.diff(x)))
        try:
            grid, prof = on_uniform_grid(x, r, dx)
        except RunFileError as exc:
            raise RunFileError(f"{source}: rail {rail}: {exc}") from None
        xs[rail], ps[rail] = grid, prof
        bi = band_indexes(prof[None, :], dx, config.bands_mm, [config.window_m(b) for b in config.bands_mm])
        ids[rail] = BandIndexes(bi.dx, bi.bands_mm, bi.windows_m, bi.pk_pk[:, 0], bi.decimation)
    if not ids:
        note = (f"{source}: no reference rail could be compared (each has fewer than 10 readings"
                f"{f' within {span[0]:.1f}-{span[1]:.1f} m' if span is not None else ''})")
        log.warning("%s", note)
        notes.append(note)
    return ReferenceIndexes(xs, ps, ids, source=source, notes=tuple(notes))


def reference_overlap(estimate: FieldEstimate, ref: ReferenceIndexes) -> list[str]:
    """What a reader of the comparison must know about where the reference and the run meet: one note per rail of
    the reference that does not overlap the estimate's chainage span (naming the record and both spans), or one
    note when no rail does (nothing compared: chainages in another unit, another place). Empty when they meet."""
    xs = [p.chainage_m[np.isfinite(p.chainage_m)] for p in estimate.profiles.values()]
    xs = [x for x in xs if x.size]
    if not xs or not ref.indexes:
        return []
    lo, hi = float(min(x[0] for x in xs)), float(max(x[-1] for x in xs))
    apart = {rail: ref.span(rail) for rail in ref.rails if ref.span(rail)[1] < lo or ref.span(rail)[0] > hi}
    if not apart:
        return []
    spans = ", ".join(f"rail {r} {a:.1f}-{b:.1f} m" for r, (a, b) in apart.items())
    if len(apart) == len(ref.rails):
        mm = [f"rail {r} {a * 1e-3:.1f}-{b * 1e-3:.1f} m" for r, (a, b) in apart.items()
              if a * 1e-3 <= hi and b * 1e-3 >= lo]
        why = (f"chainages in mm? they would cover {', '.join(mm)}" if mm else
               "chainages in another unit, or a record of another place?")
        return [f"{ref.source}: the reference ({spans}) does not overlap the run's {lo:.1f}-{hi:.1f} m: nothing "
                f"compared ({why})"]
    return [f"{ref.source}: reference {spans} does not overlap the run's {lo:.1f}-{hi:.1f} m: that rail is not "
            "compared"]


def window_pk(x: np.ndarray, pk: np.ndarray, edges: np.ndarray, min_valid: float = 0.5) -> np.ndarray:
    """Energy mean of ``pk`` in each window ``[edges[i], edges[i+1])`` (NaN with < ``min_valid`` valid share)."""
    idx = np.searchsorted(x, edges)
    out = np.full(edges.size - 1, np.nan)
    for i in range(edges.size - 1):
        seg = pk[idx[i]:idx[i + 1]]
        if seg.size == 0:
            continue
        ok = np.isfinite(seg)
        if ok.mean() >= min_valid:
            out[i] = math.sqrt(float(np.mean(seg[ok] ** 2)))
    return out


def compare_bands(estimate: FieldEstimate, ref: ReferenceIndexes, span: tuple[float, float], *,
                  window_m: float = 1.0, min_reference_um: float | dict = 0.0, models=None, wheelsets=None,
                  bands=None) -> pd.DataFrame:
    """Band pk-pk errors of the estimate against the reference on ``span`` (module docstring).

    Returns one row per wheelset, model, rail and band: ``n_windows, mean_error_db, rms_error_db,
    within_3db_pct, energy_error_db, est_db, ref_db`` (levels of the energy means, dB re 1 µm).
    """
    edges = np.arange(span[0], span[1] + 1e-9, window_m)
    rows = []
    for (w, m), p in estimate.profiles.items():
        if (models and m not in models) or (wheelsets and w not in wheelsets):
            continue
        for band in p.indexes.bands_mm:
            if bands and tuple(band) not in [tuple(b) for b in bands]:
                continue
            floor = min_reference_um.get(tuple(band), 0.0) if isinstance(min_reference_um, dict) else min_reference_um
            for rail in p.rails:
                if rail not in ref.indexes:
                    continue
                e = window_pk(p.chainage_m, p.pk_pk(band, rail), edges)
                xr, pr = ref.pk_pk(band, rail)
                r = window_pk(xr, pr, edges)
                ok = np.isfinite(e) & np.isfinite(r) & (r > floor * 1e-6) & (e > 0)
                if not ok.any():
                    rows.append({"wheelset": w, "role": p.role, "model": m, "rail": rail,
                                 "band_mm": f"{band[0]:g}-{band[1]:g}", "n_windows": 0})
                    continue
                err = 20 * np.log10(e[ok] / r[ok])
                rows.append({
                    "wheelset": w, "role": p.role, "model": m, "rail": rail, "band_mm": f"{band[0]:g}-{band[1]:g}",
                    "n_windows": int(ok.sum()), "mean_error_db": float(err.mean()),
                    "rms_error_db": float(np.sqrt(np.mean(err ** 2))),
                    "within_3db_pct": float(100 * np.mean(np.abs(err) <= 3.0)),
                    "energy_error_db": float(10 * np.log10(np.mean(e[ok] ** 2) / np.mean(r[ok] ** 2))),
                    "est_db": float(10 * np.log10(np.mean(e[ok] ** 2) / 1e-12)),
                    "ref_db": float(10 * np.log10(np.mean(r[ok] ** 2) / 1e-12))})
    return pd.DataFrame(rows)


def compare_spectra(estimate: FieldEstimate, ref: ReferenceIndexes, span: tuple[float, float],
                    config: EstimatorConfig = EstimatorConfig(), models=None, wheelsets=None) -> pd.DataFrame:
    """EN 15610 levels of estimate and reference on ``span``, per band the run resolves (error in dB)."""
    rows = []
    f_lo, f_hi = estimate.band_hz
    for (w, m), p in estimate.profiles.items():
        if (models and m not in models) or (wheelsets and w not in wheelsets):
            continue
        i0, i1 = np.searchsorted(p.chainage_m, span)
        v = p.speed_m_s[i0:i1]
        for i, rail in enumerate(p.rails):
            if rail not in ref.profile:
                continue
            seg = p.rail[i, i0:i1]
            vv = v[np.isfinite(v) & np.isfinite(seg)]
            if vv.size == 0:
                continue
            res = (float(vv.max()) / f_hi, float(vv.min()) / f_lo)
            se = roughness_spectrum(seg, p.dx, segment_m=config.en15610_segment_m, resolved_m=res)
            xr = ref.x[rail]
            j0, j1 = np.searchsorted(xr, span)
            sr = roughness_spectrum(ref.profile[rail][j0:j1], float(xr[1] - xr[0]), segment_m=config.en15610_segment_m)
            for b, wl, le, lr in zip(se.bands, se.wavelength_m, se.level_db, sr.level_db):
                rows.append({"wheelset": w, "role": p.role, "model": m, "rail": rail, "band": int(b),
                             "wavelength_m": float(wl), "est_db": float(le), "ref_db": float(lr),
                             "error_db": float(le - lr) if np.isfinite(le) and np.isfinite(lr) else math.nan})
    return pd.DataFrame(rows)


def models_ranking(errors: pd.DataFrame) -> pd.DataFrame:
    """Which model is closest to the reference per band and rail (smallest RMS window error)."""
    if errors.empty or "rms_error_db" not in errors:
        return pd.DataFrame()
    e = errors.dropna(subset=["rms_error_db"])
    rows = []
    for (w, rail, band), g in e.groupby(["wheelset", "rail", "band_mm"]):
        g = g.sort_values("rms_error_db")
        rows.append({"wheelset": w, "rail": rail, "band_mm": band, "best_model": g["model"].iloc[0],
                     **{f"rms_error_db_{r.model}": r.rms_error_db for r in g.itertuples()}})
    return pd.DataFrame(rows)
