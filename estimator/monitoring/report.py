"""The monitoring report: one self-contained HTML page an infrastructure manager reads top to bottom.

:func:`write_monitoring` writes, into a folder, the tables (CSV), the figures
(PNG) and ``report.html`` (figures embedded) of a
:class:`~estimator.monitoring.workflow.MonitorResult`:

1. **Summary** — line, model version, survey days, runs used, rejected and failed; what needs attention.
2. **Grinding plan** — per section, rail and band: the current level, the growth rate and when it crosses
   its threshold (with the interval), most urgent first.
3. **Grinding carried out** — where and between which survey days, and whether it removed the corrugation.
4. **Evolution** — band peak-to-peak along chainage per survey day (thesis Fig. 4.16) and the chainage × date map.
5. **Trends** — the sections that grow fastest, with their day values, intervals, growth line and forecast.
6. **How sure are these numbers** — the three sources of the intervals (Figs. 4.11–4.15) and their size.
7. **Consistency** — leading vs trailing wheelset, the two directions, left–right cross-talk: where they disagree.
8. **Data** — every run: alignment residual, masked share, rejections with their reason, failures.
9. **Model versions** — the versions in the store and what a model change changed.
10. **Method** — how the numbers are made.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from estimator.html import escape as _e
from estimator.html import figure_html as _figure
from estimator.html import page
from estimator.html import table_html as _table
from estimator.monitoring.config import MonitoringConfig

__all__ = ["write_monitoring", "write_report", "SECTION_TITLES"]

SECTION_TITLES = ("1. Summary", "2. Grinding plan", "3. Grinding carried out", "4. Evolution", "5. Trends",
                  "6. How sure are these numbers", "7. Consistency checks", "8. Data", "9. Model versions",
                  "10. Method")

def _save(fig, path: Path) -> Path:
    import matplotlib.pyplot as plt

    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _worst(ds: pd.DataFrame, n: int = 3) -> pd.DataFrame:
    """The (section, rail, band) combinations with the highest last-day level."""
    if ds.empty:
        return ds
    last = ds[ds["date"] == ds["date"].max()]
    return last.sort_values("level_db", ascending=False).head(n)


def _figures(res, folder: Path, cfg: MonitoringConfig) -> dict[str, tuple[Path, str]]:
    """Every figure of the report (PNG files in ``folder``), by key, with its caption."""
    import matplotlib

    matplotlib.use("Agg")
    from estimator.monitoring import plot as P

    out = {}
    dw, ds = res.day_windows, res.day_sections
    if dw.empty:
        return out
    worst = _worst(ds, 3)
    last = dw["date"].max()
    seen = set()
    for i, (_, r) in enumerate(worst.iterrows()):
        if (r["rail"], r["band_mm"]) not in seen:
            seen.add((r["rail"], r["band_mm"]))
            key = f"evolution_{i}"
            out[key] = (_save(P.plot_evolution(dw, r["band_mm"], r["rail"], grinding=res.grinding),
                              folder / f"{key}.png"),
                        f"Rail {r['rail']}, {r['band_mm']} mm: band peak-to-peak along chainage on every survey day "
                        "(thesis Fig. 4.16); days after a grinding dotted.")
            key = f"map_{i}"
            out[key] = (_save(P.plot_map(dw, r["band_mm"], r["rail"]), folder / f"{key}.png"),
                        f"Rail {r['rail']}, {r['band_mm']} mm: level by chainage and survey day.")
        key = f"trend_{i}"
        out[key] = (_save(P.plot_trend(ds, res.growth, res.forecast, r["section"], r["rail"], r["band_mm"]),
                          folder / f"{key}.png"),
                    f"Section {r['section']}, rail {r['rail']}, {r['band_mm']} mm: day values with their combined "
                    "interval, growth since the last grinding, threshold and forecast crossing.")
        if i == 0:
            band = r["band_mm"]
            out["averaging"] = (_save(P.plot_averaging(res.windows, dw, last, band), folder / "averaging.png"),
                                f"{band} mm, {last}: each run (thin) and the day's energy average (thesis Fig. 4.10).")
            for src, fig_no in (("model", "4.11-4.13"), ("placement", "4.15"), ("scatter", ""), ("reference", ""),
                                ("combined", "")):
                col = "ci_lo_db" if src == "combined" else f"{src}_lo_db"
                if col in dw.columns and dw[col].notna().any():
                    out[f"ci_{src}"] = (_save(P.plot_confidence(dw, last, band, src), folder / f"ci_{src}.png"),
                                        f"{band} mm, {last}: {src} interval ({cfg.confidence:.0%})"
                                        + (f", thesis Fig. {fig_no}" if fig_no else "") + ".")
            if len(res.variants):
                rid = sorted(res.variants[res.variants["date"] == last]["run_id"].unique()
                             or res.variants["run_id"].unique())[0]
                out["placement_detail"] = (_save(P.plot_placement(res.windows, res.variants, rid, band),
                                                 folder / "placement_detail.png"),
                                           f"Run {rid}, {band} mm: every shifted-accelerometer variant (thesis Fig. 4.14).")
    if len(res.changes):
        out["versions"] = (_save(P.plot_version_changes(res.changes), folder / "versions.png"),
                           "Mean change of the day levels per section and band between model versions.")
    return out


def _interval_summary(dw: pd.DataFrame) -> pd.DataFrame:
    rows = []
    for band, g in dw.groupby("band_mm"):
        row = {"band_mm": band, "windows": len(g)}
        for src in ("scatter", "model", "placement", "contact", "track", "reference"):
            if f"{src}_hi_db" not in g.columns:
                continue
            lo, hi = g[f"{src}_lo_db"], g[f"{src}_hi_db"]
            row[f"{src}_half_width_db"] = float(np.nanmedian(0.5 * (hi - lo))) if hi.notna().any() else math.nan
        row["combined_half_width_db"] = float(np.nanmedian(0.5 * (g["ci_hi_db"] - g["ci_lo_db"])))
        rows.append(row)
    return pd.DataFrame(rows)


def write_report(res, path, figures: dict, cfg: MonitoringConfig = MonitoringConfig()) -> Path:
    """The HTML report of a monitoring result (module docstring), figures embedded."""
    dw = res.day_windows
    dates = sorted(dw["date"].unique()) if len(dw) else []
    runs = res.runs
    n_rej = int((~runs["aligned"].astype(bool)).sum()) if len(runs) else 0
    fc = res.forecast
    above = fc[fc["status"].str.startswith("above")] if len(fc) else fc
    soon = fc[fc["status"] == "forecast"] if len(fc) else fc

    def fig(key):
        return _figure(*figures[key]) if key in figures else ""

    p = [f"<h1>Rail corrugation monitoring — line {_e(res.line)}</h1>"]
    # 1 summary
    attention = []
    if len(above):
        attention.append(f"<b>{len(above)}</b> section/rail/band combination(s) above their threshold now")
    if len(soon):
        r = soon.iloc[0]
        attention.append(f"next threshold crossing: section <b>{_e(r['section'])}</b>, rail {_e(r['rail'])}, "
                         f"{_e(r['band_mm'])} mm around <b>{_e(r['crossing_date'])}</b> "
                         + (f"(possibly above already on {_e(r['crossing_lo'])}, at the latest {_e(r['crossing_hi'])})"
                            if r.get("possibly_above_now") else
                            f"({_e(r['crossing_lo'])} to {_e(r['crossing_hi'])})"))
    if len(res.grinding):
        attention.append(f"{len(res.grinding)} grinding(s) detected")
    if len(res.flags):
        attention.append(f"{len(res.flags)} consistency finding(s) to look at (section 7)")
    p += [f"<h2>{SECTION_TITLES[0]}</h2>",
          f"<div class='box'>Model version <code>{_e(res.model_hash)}</code>; survey days "
          f"{_e(dates[0]) if dates else '–'} to {_e(dates[-1]) if dates else '–'} ({len(dates)}); "
          f"{len(runs)} run(s) in the store, {n_rej} rejected by the alignment"
          + (f"; chainage {res.section_range[0]:g}–{res.section_range[1]:g} m" if res.section_range else "")
          + ".</div>",
          "<div class='box" + (" warn" if attention else "") + "'>"
          + ("<br>".join(attention) if attention else "Nothing above its threshold and no threshold crossing "
             "forecast.") + "</div>"]
    # 2 plan
    p += [f"<h2>{SECTION_TITLES[1]}</h2>",
          "<p>Per section, rail and EN 13231-3 band: the last day's peak-to-peak, the growth since the last grinding "
          f"and when the threshold is crossed ({cfg.confidence:.0%} interval). Sections already above come first. "
          "<code>days_per_db</code> is how many days earlier the date falls for each dB by which every day's "
          "estimate reads high (a model's gain error, which the runs' scatter does not show): close to its threshold "
          "a section's date is far more sensitive than its level. <code>possibly_above_now</code>: the interval's "
          "early end reaches the last survey day (the upper side of the level's systematic interval is above the "
          "threshold already), so the interval starts there.</p>",
          _table(fc[["section", "rail", "band_mm", "last_pk_pk_um", "threshold_um", "growth_um_per_month", "status",
                     "crossing_date", "crossing_lo", "crossing_hi", "possibly_above_now", "days_per_db"]]
                  if len(fc) else fc)]
    # 3 grinding
    p += [f"<h2>{SECTION_TITLES[2]}</h2>",
          "<p>A grinding is a sudden fall of the band levels over a stretch (both rails, several bands) between two "
          "survey days; the table gives where and when, then what it achieved.</p>",
          _table(res.grinding), _table(res.grinding_effect)]
    if len(res.grinding_short):
        p += ["<p>Falls too short to be a grinding (a repaired weld, a replaced rail?):</p>", _table(res.grinding_short)]
    # 4 evolution
    p += [f"<h2>{SECTION_TITLES[3]}</h2>"] + [fig(k) for k in sorted(figures) if k.startswith(("evolution", "map"))]
    # 5 trends
    gr = res.growth
    p += [f"<h2>{SECTION_TITLES[4]}</h2>",
          _table(gr[["section", "rail", "band_mm", "since", "days", "last_pk_pk_um", "growth_um_per_month",
                     "growth_se_um_per_month"]].sort_values("growth_um_per_month", ascending=False) if len(gr) else gr)]
    p += [fig(k) for k in sorted(figures) if k.startswith("trend")]
    # 6 confidence
    cal = res.calibration
    p += [f"<h2>{SECTION_TITLES[5]}</h2>",
          "<p>The sources, given separately and combined: the scatter between the day's runs (shrinks with more "
          "runs), the wheelset model's uncertainty (perturbed modal frequencies and damping ratios applied to the "
          "same accelerations), the accelerometers' placement (±10/30/50 mm), the wheel–rail contact (wheel load, "
          "rail-head radius) and the track (discrete supports, pad and ballast stiffness and damping, the layers' "
          "causal loss law); within a source, each parameter's range counts and they add in quadrature, as the "
          "sources do. All but the scatter are systematic: averaging more runs does not shrink them"
          + (", and the model's own error measured against a trolley on a calibration site (below)"
             if len(cal) else
             "; a trolley record of a calibration site (<code>--calibration-trolley</code>) adds the error the "
             "estimator actually makes there") + ". Median half-widths [dB]:</p>",
          _table(_interval_summary(dw) if len(dw) else None)]
    if len(cal):
        p += ["<p>Calibration against the trolley: per band, the day average's error (estimate − trolley) over the "
              "site's windows, and the prediction interval of the truth around any other window's estimate "
              "(<code>lo_db</code>, <code>hi_db</code>; Student's t, so a short site gives a wide interval). It "
              "holds where the line is like the site.</p>", _table(cal), fig("ci_reference")]
    p += [fig("averaging"), fig("ci_model"), fig("placement_detail"), fig("ci_placement"), fig("ci_scatter"),
          fig("ci_combined")]
    # 7 consistency
    p += [f"<h2>{SECTION_TITLES[6]}</h2>",
          "<p>Where two estimates of the same rail disagree beyond their scatter.</p>", _table(res.flags)]
    out = getattr(res, "outliers", None)
    if out is not None and len(out):
        p += ["<p>Estimates left out of the day averages: a run's wheelset whose section level departs from the "
              "day's others by more than max(2 dB, 3 × their robust scatter) (kept in the store).</p>", _table(out)]
    # 8 data
    cols = [c for c in ("date", "run_id", "direction", "masked_share", "speed_m_s", "aligned", "alignment_residual_mm",
                        "wheelbase_m", "wheelbase_source", "is_reference", "rejected_reason", "uncertainty")
            if c in runs.columns]
    p += [f"<h2>{SECTION_TITLES[7]}</h2>", _table(runs[cols].sort_values(["date", "run_id"]) if len(runs) else runs,
                                                  100)]
    # 9 versions
    p += [f"<h2>{SECTION_TITLES[8]}</h2>", _table(res.versions)]
    if len(res.changes):
        ch = res.changes.groupby(["other_model", "section", "rail", "band_mm"])["change_db"].agg(["mean", "min", "max"])
        p += ["<p>Change of the day levels (this version − the other) per section, rail and band [dB]:</p>",
              _table(ch.reset_index()), fig("versions")]
    # 10 method
    p += [f"<h2>{SECTION_TITLES[9]}</h2>",
          "<ul><li>Runs are aligned to the line's welds and crossings (the day's reference run) and to the day's "
          "reference (every other run) by cross-correlating the estimated roughness along chainage: piecewise "
          "offset and scale, residual per run; runs that cannot be aligned are rejected with the reason.</li>"
          "<li>Averages are energy averages (mean of squared peak-to-peak amplitudes), weighted by run quality "
          "(masked share, speed).</li>"
          f"<li>Band indexes: EN 13231-3 bands, thesis Table 4.1 windows, eq. 4.1; stored per {cfg.window_m:g} m "
          "chainage window.</li>"
          "<li>Growth: straight line in peak-to-peak since the last grinding, weighted by each day's run-to-run "
          "error; the forecast is the line's crossing of the band's threshold with the delta-method interval.</li>"
          "</ul>"]
    path = Path(path)
    path.write_text(page(f"Corrugation monitoring — {res.line}", p), encoding="utf-8")
    return path


def write_monitoring(res, folder, cfg: MonitoringConfig = MonitoringConfig()) -> dict[str, Path]:
    """Tables (CSV), figures (PNG) and ``report.html`` of a monitoring result into ``folder`` (created)."""
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    files = {}
    for name, df in (("forecast", res.forecast), ("growth", res.growth), ("grinding_events", res.grinding),
                     ("grinding_effect", res.grinding_effect), ("day_sections", res.day_sections),
                     ("day_windows", res.day_windows), ("consistency_flags", res.flags), ("runs", res.runs),
                     ("model_versions", res.versions), ("version_changes", res.changes),
                     ("outliers", getattr(res, "outliers", None)),
                     ("calibration", res.calibration if len(res.calibration) else None)):
        if df is None:
            continue
        d = df.drop(columns=[c for c in ("cov",) if c in df.columns])
        files[name] = out / f"{name}.csv"
        d.to_csv(files[name], index=False)
    figs = _figures(res, out, cfg)
    files.update({k: v[0] for k, v in figs.items()})
    files["report"] = write_report(res, out / "report.html", figs, cfg)
    return files
