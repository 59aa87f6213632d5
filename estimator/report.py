"""The field report: one self-contained HTML page an analyst reads top to bottom (figures embedded as PNG).

It opens with an "In short" box: the run in one sentence and the findings the command prints
(:func:`estimator.findings.headline`: corrugated rails per band with the trailing wheelset's word and the
likely mechanism, contact loss, wheelsets not estimated). Sections:

1. the run — header, direction, leading wheelset, duration, speeds;
2. quality control — masked share per channel, every finding, the mask map;
3. odometry — balise resets, wheelbase, wheel circumferences, spatial step
   and the shortest wavelength the run resolves;
4. inversion — models, band, regularisation, condition number per band;
5. roughness per rail — EN 13231-3 band peak-to-peak along chainage (thesis
   Fig. 4.9 style) and the index table per stretch;
6. the three models compared — against the reference when one is given
   (which model wins in which band, measured), otherwise their spread;
7. EN 15610 spectra with the ISO 3095 limit;
8. corrugation type — dominant wavelength, frequency, mechanism (Table 1.1);
9. wheels — wheel roughness orders, polygons;
10. leading against trailing wheelset;
11. processing history and options.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Mapping

import numpy as np
import pandas as pd

from estimator.html import escape, figure_html, fmt_number, page, table_html

__all__ = ["write_report", "SECTION_TITLES"]

SECTION_TITLES = (
    "1. The run", "2. Quality control", "3. Odometry and spatial sampling", "4. Inversion",
    "5. Roughness per rail (EN 13231-3)", "6. The three models compared", "7. EN 15610 spectra",
    "8. Corrugation type", "9. Wheels", "10. Leading and trailing wheelsets", "11. Processing history and options",
)

_e, _fmt, _table, _figure = escape, fmt_number, table_html, figure_html


def write_report(estimate, path, *, figures: Mapping[str, Path] | None = None,
                 comparison: pd.DataFrame | None = None, ranking: pd.DataFrame | None = None,
                 spectra_comparison: pd.DataFrame | None = None, lead_trail: pd.DataFrame | None = None,
                 reference_notes=None) -> Path:
    """Write the report of one estimate (module docstring) to ``path``; figures are PNG files embedded.

    ``reference_notes`` (a list, None without a reference): what was doubtful about the reference (rows left out,
    its level, no overlap with the run, no rail compared), shown in section 6."""
    fig = dict(figures or {})
    e = estimate
    parts = [f"<h1>Rail roughness from axlebox accelerations — run {_e(e.run_id)}</h1>", _summary_box(e)]
    # 1
    speeds = [p.speed_m_s for p in e.profiles.values()]
    v = np.concatenate(speeds) if speeds else np.zeros(0)
    v = v[np.isfinite(v)]
    # a field the run file leaves empty says so, rather than showing as a blank cell
    hdr = pd.DataFrame([{"field": k, "value": v_ if v_ not in ("", None) else "(not in the run header)"}
                        for k, v_ in e.header.items()])
    parts += [f"<h2>{SECTION_TITLES[0]}</h2>",
              f"<div class='box'>File {_e(e.source)}; {e.duration_s:.1f} s at {e.fs:g} Hz; travelling "
              f"<b>{_e(e.direction)}</b> (car {_e(e.orientation)}): wheelset <b>{e.leading}</b> leads. Speed over the "
              f"estimated stretches {_fmt(v.min() if v.size else float('nan'), 3)}–"
              f"{_fmt(v.max() if v.size else float('nan'), 3)} m/s.</div>", _table(hdr)]
    # 2
    share = pd.DataFrame([{"channel": k, "masked_pct": 100 * s} for k, s in e.masked_share.items()])
    parts += [f"<h2>{SECTION_TITLES[1]}</h2>",
              "<p>Every finding is masked (samples excluded; the inversion splits the run there, nothing is "
              "interpolated over), rejected (channel not used) or flagged (estimated, but not the rail's: the "
              "wheel off the rail, <code>contact_loss</code>), and logged with its channel, time and chainage.</p>",
              _table(share), _table(e.qc, 80),
              _figure(fig.get("mask_map"), "Masked spans along chainage by reason; flagged spans hatched.")]
    lifted = e.qc[e.qc["kind"] == "contact_loss"] if not e.qc.empty else e.qc
    if len(lifted):
        where = "; ".join(f"{_e(r.channel)} {r.chainage_from_m:.1f}-{r.chainage_to_m:.1f} m"
                          for r in lifted.head(8).itertuples()) + (" ..." if len(lifted) > 8 else "")
        parts.append(f"<div class='box warn'>The wheel leaves the rail on {len(lifted)} stretch(es) ({where}): the "
                     "estimated dynamic contact force exceeds the static wheel load there, the inversion's linear "
                     "contact does not hold, and the roughness read there is not the rail's. A corrugation this "
                     "severe is the first thing to grind.</div>")
    if e.skipped:
        parts.append("<div class='box warn'>Not estimated: " + "; ".join(_e(s) for s in e.skipped) + "</div>")
    # 3
    circ = pd.DataFrame([{"wheelset": w, "circumference_m": c.circumference_m, "radius_m": c.radius_m,
                          "significance": c.significance, "dx_mm": 1e3 * e.dx_m[w]} for w, c in e.circumference.items()])
    parts += [f"<h2>{SECTION_TITLES[2]}</h2>",
              f"<p>Wheelbase {e.wheelbase_m:.3f} m ({_e(e.wheelbase_source)}). Shortest wavelength the run resolves "
              f"{1e3 * e.lambda_min_m:.1f} mm (the run's slowest kept speed / f_hi); each wheelset's profile has a whole number of "
              "samples per wheel revolution.</p>", _table(e.odometry), _table(circ)]
    sleeper = []
    for (w, m), p in e.profiles.items():
        if p.sleeper is not None:
            o = p.sleeper.significant
            sleeper.append(pd.DataFrame({"wheelset": w, "model": m, "rail": o["rail"], "order": o["order"],
                                         "wavelength_mm": 1e3 * o["wavelength_m"],
                                         "amplitude_um": 1e6 * o["amplitude_m"], "floor_um": 1e6 * o["floor_m"],
                                         "track_model_um": 1e6 * o["expected_m"]}))
    if sleeper:
        parts += ["<p>Sleeper passing: the wheel follows the rail's deflection under its own load, which repeats "
                  "with the sleeper spacing; a trolley does not see it. The orders of the sleeper spacing that "
                  "stand above 4× their floor were removed from the rail estimate (amplitudes of the run's "
                  "synchronous average; none listed: nothing removed). Beside them, what the trackform gives under "
                  "the static wheel load: a measured amplitude well above it points to weaker support than the "
                  "trackform says (voided sleepers, worn pads).</p>",
                  _table(pd.concat(sleeper, ignore_index=True), 40)]
    # 4
    f_lo, f_hi = e.band_hz
    cond = []
    for (w, m), p in e.profiles.items():
        if w == e.leading:
            c = p.conditioning.copy()
            c.insert(0, "model", m)
            cond.append(c)
    parts += [f"<h2>{SECTION_TITLES[3]}</h2>",
              f"<p>Band {f_lo:g}–{f_hi:g} Hz; Tikhonov regularisation with α = {e.config.get('regularisation')} "
              "relative to the one-third-octave envelope of the largest singular value of B (data known to about "
              "2 %: calibration and mounting); condition number of B and the smallest filter factor per "
              "one-third-octave band (leading wheelset; a factor below 1 marks where the regularisation acted).</p>",
              _table(pd.concat(cond, ignore_index=True) if cond else pd.DataFrame(), 80)]
    # 5
    parts.append(f"<h2>{SECTION_TITLES[4]}</h2>")
    for k, (band, stretch) in _band_figures(fig):
        parts.append(_figure(fig[k], f"EN 13231-3 peak-to-peak, {band} mm, {stretch}, along chainage per rail, the "
                                     "three models (thesis Fig. 4.9 style); dashed: the reference."))
    ix = e.indexes
    if not ix.empty:
        ix = ix[(ix["wheelset"] == e.leading) & (ix["band_mm"].isin(["30-100", "100-300"]))]
    parts.append(_table(ix, 80))
    # 6
    parts.append(f"<h2>{SECTION_TITLES[5]}</h2>")
    if reference_notes:
        parts.append("<div class='box warn'>Reference: " + "<br>".join(_e(n) for n in reference_notes) + "</div>")
    compared = comparison is not None and not comparison.empty and "n_windows" in comparison \
        and (comparison["n_windows"] > 0).any()
    if reference_notes is not None and not compared:
        parts.append("<p><b>No reference rail could be compared with the estimate</b> (see above); the table "
                     "shows each model's median band peak-to-peak over the run.</p>")
    if comparison is not None and not comparison.empty:
        parts += ["<p>Against the reference (per 1 m window: energy mean of the band peak-to-peak, error in dB).</p>",
                  _table(comparison, 80)]
        if ranking is not None and not ranking.empty:
            parts += ["<p><b>Which model wins</b> (smallest RMS window error) per band and rail:</p>",
                      _table(ranking)]
    else:
        if reference_notes is None:
            parts.append("<p>No reference was given: the table shows each model's median band peak-to-peak over "
                         "the run (their spread is the model uncertainty).</p>")
        ix = e.indexes
        if not ix.empty:
            piv = ix[(ix["stretch"] == "run") & (ix["wheelset"] == e.leading)].pivot_table(
                index=["rail", "band_mm"], columns="model", values="median_pk_pk_um").reset_index()
            parts.append(_table(piv))
    cautions = _band_cautions(e)
    if cautions:
        parts.append("<div class='box warn'><b>Bands to read with care</b> (leading wheelset, whole run):<br>"
                     + "<br>".join(_e(c) for c in cautions) + "</div>")
    # 7
    parts.append(f"<h2>{SECTION_TITLES[6]}</h2>")
    for k in (f for f in fig if f.startswith("spectra_")):
        parts.append(_figure(fig[k], f"EN 15610 one-third-octave roughness level, {k[8:].replace('_', ' ')}, with "
                                     "the ISO 3095 limit (bands the run resolves only)."))
    if spectra_comparison is not None and not spectra_comparison.empty:
        parts.append(_table(spectra_comparison.dropna(subset=["error_db"]), 80))
    # 8
    parts += [f"<h2>{SECTION_TITLES[7]}</h2>",
              "<p>Dominant wavelength of each corrugated stretch (median band peak-to-peak above the threshold), its "
              "speed and frequency f = v/λ (thesis eq. 1.1) against the model's resonances (thesis Table 1.1).</p>",
              _table(e.resonances), _table(e.corrugation, 60)]
    split = _wheelset_disagreements(e)
    if split:
        parts.append("<div class='box warn'><b>Found by the leading wheelset only</b> (the trailing wheelset, a "
                     "second estimate of the same rail, is not above the threshold there):<br>"
                     + "<br>".join(_e(x) for x in split) + "</div>")
    # 9
    wo = e.wheel_orders()
    parts += [f"<h2>{SECTION_TITLES[8]}</h2>",
              _figure(fig.get("wheel_orders"), "Wheel roughness per order from the synchronous average; orders above 4× "
                                                "the floor the rail leaves are polygon orders."),
              _table(wo[wo["significant"]].sort_values("amplitude_um", ascending=False) if not wo.empty else wo, 30)]
    # 10
    parts.append(f"<h2>{SECTION_TITLES[9]}</h2>")
    if lead_trail is not None and not lead_trail.empty:
        parts += ["<p>The trailing wheelset is a second, independent estimate of the same rails: band peak-to-peak "
                  "differences per 1 m window (dB).</p>", _table(lead_trail)]
    else:
        parts.append("<p>Only one wheelset was estimated.</p>")
    # 11
    parts += [f"<h2>{SECTION_TITLES[10]}</h2>", "<pre>" + _e("\n".join(e.processing)) + "</pre>",
              "<pre>" + _e(json.dumps({k: str(v) for k, v in e.config.items()}, indent=1)) + "</pre>",
              "<pre>" + _e(json.dumps({k: round(v, 4) for k, v in e.timings_s.items()})) + "</pre>"]
    out = Path(path)
    out.write_text(page(f"Field estimate {e.run_id}", parts), encoding="utf-8")
    return out


def _summary_box(e) -> str:
    """The report's opening box: the run in one sentence, then :func:`estimator.findings.headline`, the same
    findings the command prints; red where a rail is corrugated, a wheel leaves the rail or a wheelset is missing."""
    from estimator.findings import headline

    found = headline(e)
    alarming = any(f.startswith(("corrugated:", "contact loss:", "not estimated:")) for f in found)
    run = (f"Run {_e(e.run_id)}: {e.duration_s:.1f} s travelling {_e(e.direction)}, wheelset {e.leading} leading; "
           f"{100 * e.masked_share.get('run', 0.0):.1f} % of the samples masked in some channel "
           f"({len(e.qc)} quality-control finding(s), section 2); shortest wavelength resolved "
           f"{1e3 * e.lambda_min_m:.1f} mm.")
    cautions = _band_cautions(e)
    care = (f"<p>{len(cautions)} band(s) to read with care (contact filter or pinned–pinned resonance): "
            "section 6.</p>") if cautions else ""
    items = "".join(f"<li>{_e(f)}</li>" for f in found)
    return (f"<div class='box{' warn' if alarming else ''}'><p><b>In short.</b> {run}</p><ul>{items}</ul>{care}"
            "</div>")


def _band_figures(fig: Mapping[str, Path]) -> list[tuple[str, tuple[str, str]]]:
    """The band figures :func:`estimator.export.write_estimate` names ``band_<short>_<long>_<stretch>``, with the
    band (``30–100``) and the stretch (``curve C1``) their names hold, in the order written (stretch by stretch,
    the shorter band first)."""
    out = []
    for k in fig:
        m = re.fullmatch(r"band_([0-9.]+)_([0-9.]+)_(.+)", k)
        if m:
            out.append((k, (f"{m[1]}–{m[2]}", m[3].replace("_", " "))))
    return out


def _wheelset_disagreements(e) -> list[str]:
    """Lines for the corrugated stretches only the leading wheelset finds (:func:`estimator.corrugation.wheelset_agreement`)."""
    from estimator.corrugation import wheelset_agreement

    if e.corrugation.empty or not e.models:
        return []
    a = wheelset_agreement(e.corrugation, e.models[-1])
    return [f"{r.stretch}, rail {r.rail}, {r.band_mm} mm: {r.median_pk_pk_um:.1f} µm pk-pk"
            + (f" — {r.note}" if r.note else "") for r in a[~a["agree"]].itertuples()]


def _band_cautions(e) -> list[str]:
    """One line per EN band whose level the contact filter's correction or the pinned-pinned resonance weakens
    (:mod:`estimator.band_caution`)."""
    ix = e.indexes
    if ix.empty or "caution" not in ix:
        return []
    run = ix[(ix["stretch"] == "run") & (ix["wheelset"] == e.leading) & (ix["caution"] != "")]
    return [f"{band} mm: {text}" for band, text in run.drop_duplicates("band_mm")[["band_mm", "caution"]]
            .itertuples(index=False)]
