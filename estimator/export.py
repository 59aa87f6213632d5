"""Writing a field estimate: profiles (Parquet), index and spectrum tables (CSV), figures, the HTML report.

Files written into a folder (the CLI stages them: temporary folder, then rename):

=========================  ======================================================================
``profiles_ws<N>.parquet``  per wheelset: ``chainage_m, speed_m_s`` and the rail roughness
                            ``<model>_<rail>_um`` (float32) on the wheelset's grid
``band_pk_pk.parquet``      EN 13231-3 peak-to-peak every 5 cm: ``wheelset, model, rail,
                            chainage_m`` and one ``pk_pk_um_<band>`` column per band
``indexes.csv``             per wheelset, model, stretch, rail, band: median/max pk-pk, exceedance
``spectra.csv``             EN 15610 levels per wheelset, model, stretch, rail, band, ISO 3095 limit
``corrugation.csv``         corrugated stretches: dominant wavelength, speed, frequency, mechanism
``wheel_orders.csv``        wheel roughness per wheel and order (amplitude, floor, significant)
``qc.csv``, ``odometry.csv`` quality-control findings, balise resets
``conditioning.csv``        condition number and regularisation per band, wheelset, model
``comparison.csv``          (with a reference) band errors per wheelset, model, rail
``summary.json``            run, options, wheelbase, circumferences, sleeper passing removed, masked share, timings,
                            history; with a reference: its file, rails compared, spans and what was doubtful
                            about it (``reference.notes``: rows left out, level, no overlap with the run)
``figures/*.png``           the report's figures
``report.html``             the report (:mod:`estimator.report`)
=========================  ======================================================================
"""

from __future__ import annotations

import json
import logging
import math
from pathlib import Path

import numpy as np
import pandas as pd

from estimator.reference import ReferenceIndexes, compare_bands, compare_spectra, models_ranking, reference_overlap
from estimator.report import write_report
from estimator.results import FieldEstimate

__all__ = ["write_estimate", "lead_trail_agreement", "summary"]

log = logging.getLogger("estimator")


def summary(e: FieldEstimate) -> dict:
    return {
        "run_id": e.run_id, "source": e.source, "header": dict(e.header), "direction": e.direction,
        "orientation": e.orientation, "leading_wheelset": e.leading, "fs_hz": e.fs, "duration_s": e.duration_s,
        "masked_share": dict(e.masked_share), "band_hz": list(e.band_hz), "lambda_min_m": e.lambda_min_m,
        "dx_m": {str(k): v for k, v in e.dx_m.items()}, "wheelbase_m": e.wheelbase_m,
        "wheelbase_source": e.wheelbase_source,
        "circumference": {str(w): {"circumference_m": c.circumference_m, "radius_m": c.radius_m,
                                   "significance": c.significance} for w, c in e.circumference.items()},
        "sleeper_passing": [{"wheelset": w, "model": m, "spacing_m": p.sleeper.spacing_m, "bays": p.sleeper.bays,
                             "removed": [{"rail": r.rail, "order": int(r.order), "wavelength_m": r.wavelength_m,
                                          "amplitude_m": r.amplitude_m, "floor_m": r.floor_m,
                                          "track_model_m": r.expected_m if math.isfinite(r.expected_m) else None}
                                         for r in p.sleeper.significant.itertuples()]}
                            for (w, m), p in e.profiles.items() if p.sleeper is not None],
        "models": list(e.models), "skipped": list(e.skipped), "stretches": [list(s) for s in e.stretches],
        "config": {k: (v if isinstance(v, (int, float, str, bool, type(None), list, dict)) else str(v))
                   for k, v in e.config.items()},
        "timings_s": dict(e.timings_s), "processing": list(e.processing),
    }


def lead_trail_agreement(e: FieldEstimate, model: str = "vertical_lateral", window_m: float = 1.0) -> pd.DataFrame:
    """Leading vs trailing band pk-pk per 1 m window: mean and RMS difference [dB] per rail and band."""
    from estimator.reference import window_pk

    if (1, model) not in e.profiles or (2, model) not in e.profiles:
        return pd.DataFrame()
    a, b = e.profiles[(1, model)], e.profiles[(2, model)]
    lo = max(a.chainage_m[0], b.chainage_m[0])
    hi = min(a.chainage_m[-1], b.chainage_m[-1])
    edges = np.arange(math.ceil(lo), math.floor(hi) + 1e-9, window_m)
    rows = []
    for band in a.indexes.bands_mm:
        for rail in a.rails:
            pa = window_pk(a.chainage_m, a.pk_pk(band, rail), edges)
            pb = window_pk(b.chainage_m, b.pk_pk(band, rail), edges)
            ok = np.isfinite(pa) & np.isfinite(pb) & (pa > 0) & (pb > 0)
            if not ok.any():
                continue
            d = 20 * np.log10(pa[ok] / pb[ok])
            rows.append({"model": model, "rail": rail, "band_mm": f"{band[0]:g}-{band[1]:g}", "n_windows": int(ok.sum()),
                         "mean_diff_db": float(d.mean()), "std_diff_db": float(d.std()),
                         "within_3db_pct": float(100 * np.mean(np.abs(d) <= 3))})
    return pd.DataFrame(rows)


def _band_table(e: FieldEstimate, step_m: float = 0.05) -> pd.DataFrame:
    frames = []
    for (w, m), p in e.profiles.items():
        x = p.chainage_m
        k = max(1, int(round(step_m / p.dx)))
        for i, rail in enumerate(p.rails):
            d = {"wheelset": w, "model": m, "rail": rail, "chainage_m": x[::k]}
            for bi, band in enumerate(p.indexes.bands_mm):
                d[f"pk_pk_um_{band[0]:g}_{band[1]:g}"] = (p.indexes.pk_pk[bi, i, ::k] * 1e6).astype(np.float32)
            frames.append(pd.DataFrame(d))
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()


def write_estimate(e: FieldEstimate, folder, *, reference: ReferenceIndexes | None = None,
                   span: tuple[float, float] | None = None, figures: bool = True, report: bool = True) -> dict:
    """Write every output of an estimate into ``folder`` (module docstring); returns {name: path}.

    ``reference`` (from :func:`estimator.reference.reference_indexes`) adds the comparison tables and the
    dashed reference lines; ``span`` limits the band figures to a chainage range (default: each curve of the
    line, else the run).
    """
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    files: dict[str, Path] = {}
    for w in e.wheelsets:
        cols = {}
        base = None
        for (ww, m), p in e.profiles.items():
            if ww != w:
                continue
            base = p
            for i, rail in enumerate(p.rails):
                cols[f"{m}_{rail}_um"] = (p.rail[i] * 1e6).astype(np.float32)
        if base is None:
            continue
        df = pd.DataFrame({"chainage_m": base.chainage_m, "speed_m_s": base.speed_m_s.astype(np.float32), **cols})
        files[f"profiles_ws{w}"] = out / f"profiles_ws{w}.parquet"
        df.to_parquet(files[f"profiles_ws{w}"], index=False, compression="zstd")
    files["band_pk_pk"] = out / "band_pk_pk.parquet"
    _band_table(e).to_parquet(files["band_pk_pk"], index=False, compression="zstd")
    tables = {"indexes": e.indexes, "spectra": e.spectra, "corrugation": e.corrugation, "wheel_orders": e.wheel_orders(),
              "qc": e.qc, "odometry": e.odometry, "resonances": e.resonances}
    cond = [p.conditioning.assign(wheelset=w, model=m) for (w, m), p in e.profiles.items()]
    tables["conditioning"] = pd.concat(cond, ignore_index=True) if cond else pd.DataFrame()
    comparison = ranking = spectra_cmp = None
    spans = []
    if span is not None:
        spans = [("span", span)]
    else:
        spans = [(name, (a, b)) for name, a, b in e.stretches if name.startswith("curve")] or \
                [("run", (float(min(p.chainage_m[0] for p in e.profiles.values())),
                          float(max(p.chainage_m[-1] for p in e.profiles.values()))))]
    reference_notes: list[str] = []
    if reference is not None:
        reference_notes = list(getattr(reference, "notes", ()))
        for note in reference_overlap(e, reference):
            log.warning("%s", note)
            reference_notes.append(note)
        comparison = pd.concat([compare_bands(e, reference, s).assign(stretch=n) for n, s in spans], ignore_index=True)
        ranking = models_ranking(comparison[comparison["role"] == "leading"]) if not comparison.empty else None
        spectra_cmp = pd.concat([compare_spectra(e, reference, s).assign(stretch=n) for n, s in spans],
                                ignore_index=True)
        tables["comparison"] = comparison
        tables["comparison_spectra"] = spectra_cmp
    lt = lead_trail_agreement(e)
    tables["lead_trail"] = lt
    for name, df in tables.items():
        files[name] = out / f"{name}.csv"
        df.to_csv(files[name], index=False)
    files["summary"] = out / "summary.json"
    summ = summary(e)
    if reference is not None:
        summ["reference"] = {"source": getattr(reference, "source", "reference"),
                             "rails_compared": [r for r in sorted(reference.indexes)
                                                if comparison is not None and not comparison.empty
                                                and (comparison.loc[comparison["rail"] == r, "n_windows"] > 0).any()],
                             "spans_m": {r: list(reference.span(r)) for r in sorted(reference.indexes)},
                             "notes": reference_notes}
    files["summary"].write_text(json.dumps(summ, indent=1, default=str), encoding="utf-8")
    figs: dict[str, Path] = {}
    if figures:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        from estimator.plot import plot_band_pk_pk, plot_mask_map, plot_spectra, plot_wheel_orders

        fdir = out / "figures"
        fdir.mkdir(exist_ok=True)

        def save(name, f):
            figs[name] = fdir / f"{name}.png"
            f.savefig(figs[name], dpi=110)
            plt.close(f)

        for sname, sp in spans[:3]:
            for band in ((30.0, 100.0), (100.0, 300.0)):
                if band in [tuple(b) for b in next(iter(e.profiles.values())).indexes.bands_mm]:
                    tag = f"band_{band[0]:g}_{band[1]:g}_{sname.replace(' ', '_')}"
                    save(tag, plot_band_pk_pk(e, band, span=sp, reference=reference))
        for sname, _ in spans[:3]:
            if not e.spectra.empty and (e.spectra["stretch"] == sname).any():
                ref_lv = spectra_cmp[spectra_cmp["stretch"] == sname] if spectra_cmp is not None else None
                save(f"spectra_{sname.replace(' ', '_')}", plot_spectra(e, sname, reference_levels=ref_lv))
        save("mask_map", plot_mask_map(e))
        save("wheel_orders", plot_wheel_orders(e))
        files.update({f"figure_{k}": v for k, v in figs.items()})
    if report:
        files["report"] = write_report(e, out / "report.html", figures=figs, comparison=comparison, ranking=ranking,
                                       spectra_comparison=spectra_cmp, lead_trail=lt,
                                       reference_notes=reference_notes if reference is not None else None)
    return files
