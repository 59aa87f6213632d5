"""The diagnosis report: one self-contained HTML file a lab engineer reads top to bottom.

:func:`write_diagnosis_report` turns the results of the lab workflow
(``railmodal lab diagnose``: identify → pair → hybrid model → compare →
diagnose → add the accepted effects) into a single HTML page with the
figures embedded as base64 PNG, so the report survives being mailed.  No
web framework: plain HTML with a small inline style sheet; every text that
comes from data is escaped with :func:`html.escape`.

Sections, top to bottom:

1. what was measured — setups, channels, hits kept and rejected with reasons;
2. identified modes and their pairing with the FE modes;
3. model against measurement before any effect — the figure of merit ``E``
   and its noise floor (defined in :mod:`receptance.diagnosis.compare`), error map,
   error per band, worst channels, peaks the model lacks;
4. diagnosis — the candidates of every round, ranked, with the criterion
   and why physics comes before patches;
5. each accepted effect — fitted values, the channels and bands it fixes,
   the error before and after;
6. what remains — :meth:`receptance.diagnosis.Diagnosis.residual` and the
   unexplained part in plain words.

Nothing graphical is imported here: the figures are PNG files made by the
caller (``receptance.plot_compare``, ``receptance.plot_model``, ``ema.plot``).
"""

from __future__ import annotations

import base64
import datetime as _dt
import html
import logging
import math
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from receptance.diagnosis.fitting import BIC_THRESHOLD, MIN_REDUCTION, NOISE_MARGIN
from receptance.formatting import format_value

__all__ = ["write_diagnosis_report", "ReportError", "SECTION_TITLES"]

log = logging.getLogger("receptance")

#: the report's section headings, in order (tests and readers may look for them)
SECTION_TITLES = (
    "1. What was measured",
    "2. Identified modes and pairing with the FE model",
    "3. Model against measurement before any effect",
    "4. Diagnosis: which effect is missing",
    "5. Accepted effects",
    "6. What remains",
)

_CSS = """
body{font-family:-apple-system,Segoe UI,Helvetica,Arial,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;
color:#222;line-height:1.45}
h1{font-size:1.6em;border-bottom:2px solid #444;padding-bottom:.2em}
h2{font-size:1.3em;margin-top:2em;border-bottom:1px solid #bbb;padding-bottom:.15em}
h3{font-size:1.08em;margin-top:1.4em}
table{border-collapse:collapse;margin:.6em 0 1em 0;font-size:.86em}
th,td{border:1px solid #ccc;padding:.2em .5em;text-align:left;vertical-align:top}
th{background:#eee}
td.num{text-align:right;font-variant-numeric:tabular-nums}
tr.accepted td{background:#e6f4e6}
figure{margin:1em 0}
figure img{max-width:100%;border:1px solid #ddd}
figcaption{font-size:.85em;color:#555}
.box{background:#f6f8fa;border-left:4px solid #3a6ea5;padding:.6em 1em;margin:1em 0}
.warn{border-left-color:#c0392b}
.ok{border-left-color:#27ae60}
code,pre{font-family:Menlo,Consolas,monospace;font-size:.88em}
pre{background:#f6f8fa;padding:.6em;overflow-x:auto}
.small{font-size:.85em;color:#555}
"""

_CAPTIONS = {
    "stabilisation": "Stabilisation diagram of the setup (LSCE poles by model order; selected modes as lines).",
    "synthesis": "Measured FRFs against the FRFs synthesised from the identified modes.",
    "mac": "MAC between the identified modes and the FE modes (pairs boxed).",
    "error_map": "Error map before any effect: 20 log10 |H_model / H_measured| per channel (grouped by body) "
                 "and frequency. Red: the model responds more than the wheelset; blue: less.",
    "band_errors": "Band-normalised complex error per octave band before any effect, with the noise floor "
                   "of each band (black ticks).",
    "worst_channels": "Measured and model accelerance on the channels carrying most of the error above the noise "
                      "floor, before any effect.",
    "peaks": "Resonances: channel-normalised mean power of measurement and model; red triangles mark measured "
             "peaks the model lacks, blue ones model peaks the measurement lacks.",
    "error_map_final": "Error map of the final model (all accepted effects added).",
    "worst_channels_final": "The same worst channels as in section 3, with the final model.",
}


class ReportError(ValueError):
    """The report cannot be written (names the figure, file or argument at fault)."""


# --------------------------------------------------------------------------- formatting helpers
def _e(text) -> str:
    return html.escape(str(text), quote=True)


_fmt = format_value


def _pct(v, digits: int = 2) -> str:
    try:
        x = float(v)
    except (TypeError, ValueError):
        return "–"
    return f"{100 * x:.{digits}f} %" if math.isfinite(x) else "–"


def _table(df: pd.DataFrame, *, max_rows: int | None = None, row_classes: Sequence[str] | None = None,
           formats: Mapping[str, callable] | None = None) -> str:
    """An escaped HTML table of a DataFrame (numbers right-aligned, 4 significant digits)."""
    if df is None or len(df) == 0:
        return "<p class='small'>(none)</p>"
    formats = dict(formats or {})
    shown = df if max_rows is None else df.head(max_rows)
    head = "".join(f"<th>{_e(c)}</th>" for c in shown.columns)
    rows = []
    for k, (_, r) in enumerate(shown.iterrows()):
        cells = []
        for c in shown.columns:
            v = r[c]
            if c in formats:
                cells.append(f"<td class='num'>{_e(formats[c](v))}</td>")
            elif isinstance(v, (float, int, np.floating, np.integer)) and not isinstance(v, (bool, np.bool_)):
                cells.append(f"<td class='num'>{_e(_fmt(v))}</td>")
            else:
                cells.append(f"<td>{_e(_fmt(v) if isinstance(v, (bool, np.bool_)) or v is None else v)}</td>")
        cls = f" class='{_e(row_classes[k])}'" if row_classes is not None and row_classes[k] else ""
        rows.append(f"<tr{cls}>{''.join(cells)}</tr>")
    more = ""
    if max_rows is not None and len(df) > max_rows:
        more = f"<p class='small'>… {len(df) - max_rows} more rows not shown.</p>"
    return f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(rows)}</tbody></table>{more}"


def _para(text: str, cls: str = "") -> str:
    c = f" class='{cls}'" if cls else ""
    return f"<p{c}>{_e(text)}</p>"


class _Figures:
    """Embeds PNG files as base64 ``<img>``; remembers which were used."""

    def __init__(self, figures: Mapping[str, Path]):
        self.paths = {str(k): Path(v) for k, v in (figures or {}).items()}
        for key, p in self.paths.items():
            if not p.is_file():
                raise ReportError(f"figure {key!r}: PNG file not found: {p}")
            with p.open("rb") as fh:
                if fh.read(8) != b"\x89PNG\r\n\x1a\n":
                    raise ReportError(f"figure {key!r}: {p} is not a PNG file")
        self.used: list[str] = []

    def keys(self, prefix: str) -> list[str]:
        return [k for k in self.paths if k == prefix or k.startswith(prefix + "_")]

    def html(self, key: str, caption: str | None = None) -> str:
        if key not in self.paths:
            return ""
        self.used.append(key)
        data = base64.b64encode(self.paths[key].read_bytes()).decode("ascii")
        cap = caption if caption is not None else _CAPTIONS.get(key, "")
        return (f"<figure><img src=\"data:image/png;base64,{data}\" alt=\"{_e(key)}\">"
                f"<figcaption>{_e(cap)} <span class='small'>({_e(self.paths[key].name)})</span></figcaption>"
                f"</figure>")


# --------------------------------------------------------------------------- sections
def _summary_box(diagnosis, comparisons) -> str:
    first, last = comparisons[0], comparisons[-1]
    if diagnosis.accepted:
        chain = "; then ".join(
            f"{f.name} ({', '.join(f'{k} = {_fmt(v, 3)}' for k, v in f.params.items())})" for f in diagnosis.accepted)
        text = (f"Missing physics found, in the order added: {chain}. The error E fell from {_pct(first.summary)} "
                f"to {_pct(last.summary)}; the noise floor of the measurement is {_pct(last.noise_floor)}.")
        cls = "box ok"
    else:
        text = (f"No catalogued effect passed the criterion. The error E of the model is {_pct(first.summary)} "
                f"against a noise floor of {_pct(first.noise_floor)}.")
        cls = "box warn" if first.summary > NOISE_MARGIN * first.noise_floor else "box ok"
    extra = "".join(f"<p>{_e(u)}</p>" for u in diagnosis.unexplained)
    return f"<div class='{cls}'><p><b>In short.</b> {_e(text)}</p>{extra}</div>"


def _section_measured(setups_info: Sequence[Mapping], figs: _Figures) -> str:
    out = [f"<h2>{_e(SECTION_TITLES[0])}</h2>"]
    if not setups_info:
        out.append(_para("No setup information was given."))
        return "".join(out)
    rows = []
    for s in setups_info:
        navg = s.get("n_averages")
        rows.append({
            "setup": s.get("setup", ""), "data file": s.get("hammer", s.get("frf", "")),
            "channel table": s.get("channels", ""),
            "accelerometers": s.get("n_channels", ""), "force": s.get("force", ""),
            "hits": ", ".join(str(h) for h in s.get("hits", ())),
            "hits rejected": ", ".join(str(h) for h in s.get("rejected_hits", ())) or "none",
            "averages per channel": (f"{navg[0]}–{navg[1]}" if navg else ""),
            "lines": s.get("n_lines", ""), "band [Hz]": s.get("band_hz", ""),
            "exp. window a [1/s]": s.get("exp_window_decay", ""),
            "modes identified": s.get("n_modes", "")})
    out.append(_table(pd.DataFrame(rows)))
    methods = [(s.get("setup", ""), s.get("noise_floor_method", "")) for s in setups_info
               if s.get("noise_floor_method")]
    if methods:
        out.append(_para("Noise floor: " + "; ".join(f"setup {n}: {m}" for n, m in methods) + "."))
    out.append(_para("Each hit is screened before averaging: a second force pulse (double hit), a channel flat at "
                     "its ADC range (clipped), a weak or distorted force pulse, or a channel incoherent in every "
                     "hit is rejected, and the H1 estimate averages the hits left for each channel. Rejections:"))
    for s in setups_info:
        rej = list(s.get("rejections", ()))
        out.append(f"<h3>Setup {_e(s.get('setup', ''))}</h3>")
        if s.get("frf"):
            out.append(_para(f"FRFs read from {s['frf']} (exported by the acquisition system: no hits to screen; "
                             f"{'with' if s.get('coherence_in_file') else 'without'} coherence)."))
        elif rej:
            out.append("<ul>" + "".join(f"<li>{_e(r)}</li>" for r in rej) + "</ul>")
        else:
            out.append(_para("Every hit of every channel was kept."))
        for key in (f"stabilisation_{s.get('setup', '')}", f"synthesis_{s.get('setup', '')}"):
            out.append(figs.html(key, _CAPTIONS["stabilisation" if key.startswith("stab") else "synthesis"]
                                 + f" Setup {s.get('setup', '')}."))
    return "".join(out)


def _section_pairing(pairing_table: pd.DataFrame | None, setups_info, figs: _Figures, model_note: str,
                     polarity: Sequence[str] = ()) -> str:
    out = [f"<h2>{_e(SECTION_TITLES[1])}</h2>"]
    if polarity:
        out.append("<div class='box warn'><p><b>Channels that look read with the wrong sign</b> (their FRFs enter "
                   "the comparison and the diagnosis as measured; every channel's check in channel_polarity.csv)"
                   "</p>" + "".join(f"<p>{_e(f)}</p>" for f in polarity) + "</div>")
    if pairing_table is None or len(pairing_table) == 0:
        out.append(_para("No pairing table was given."))
    else:
        t = pairing_table.copy()
        paired = t["test_mode"].notna() & t["fe_modes"].astype(str).str.strip().ne("") if "fe_modes" in t else None
        if paired is not None:
            n_test = int(t["test_mode"].notna().sum())
            test_only = t[t["test_mode"].notna() & ~paired]
            fe_only = t[t["test_mode"].isna()]
            words = (f"{n_test} test modes (merged over the setups), {int(paired.sum())} paired with FE modes by MAC; "
                     f"{len(test_only)} test mode(s) without FE partner"
                     + (f" ({', '.join(f'{f:.1f} Hz' for f in test_only['f_test_hz'])})" if len(test_only) else "")
                     + f"; {len(fe_only)} FE mode(s) in the band without test partner.")
            out.append(_para(words))
        cols = [c for c in ("test_mode", "f_test_hz", "zeta", "setup", "fe_modes", "f_fe_hz", "df_pct", "mac",
                            "description") if c in t]
        fmt = {"zeta": lambda v: _pct(v, 3)} if "zeta" in t else {}
        out.append(_table(t[cols], formats=fmt))
    if model_note:
        out.append(_para(model_note))
    out.append(figs.html("mac"))
    return "".join(out)


def _definitions() -> str:
    return ("<div class='box'><p><b>Figure of merit.</b> E is the RMS over channels × octave bands of the "
            "band-normalised complex error ‖H<sub>model</sub> − H<sub>measured</sub>‖<sub>band</sub> / "
            "‖H<sub>measured</sub>‖<sub>band</sub> (0 = perfect; every octave and every sensor weighs alike, "
            "phase counts as well as magnitude).</p>"
            "<p><b>Noise floor.</b> The E that measurement noise alone would give a perfect model, from "
            "the coherence and the number of averaged hits of each H1 estimate (random error "
            "σ²/|H|² = (1 − γ²)/((n − 1) γ²)) — or, for FRF files without coherence, from the measurement "
            "itself (section 1 says how); a model at the floor is as good as these data can tell.</p></div>")


def _section_before(c0, figs: _Figures) -> str:
    out = [f"<h2>{_e(SECTION_TITLES[2])}</h2>", _definitions()]
    ratio = c0.summary / c0.noise_floor if c0.noise_floor > 0 else float("nan")
    out.append(_para(f"Before any effect: E = {_pct(c0.summary)}, noise floor {_pct(c0.noise_floor)} "
                     f"({_fmt(ratio, 3)}× the floor), over {len(c0.channels)} channels "
                     f"and {len(c0.bands)} bands, {c0.band_hz[0]:g}–{c0.band_hz[1]:g} Hz."))
    out.append("<h3>Error per band</h3>")
    b = c0.bands[["band", "n_lines", "error", "floor", "excess_share"]].rename(
        columns={"error": "error E_band", "floor": "noise floor", "excess_share": "share of error above floor"})
    out.append(_table(b, formats={"error E_band": _pct, "noise floor": _pct,
                                  "share of error above floor": lambda v: _pct(v, 0)}))
    out.append(figs.html("band_errors"))
    out.append("<h3>Where the error sits</h3>")
    w = c0.where(3)[["kind", "rank", "name", "error", "excess_share", "share"]].rename(
        columns={"excess_share": "share above floor", "share": "share of E²"})
    out.append(_table(w, formats={"error": _pct, "share above floor": lambda v: _pct(v, 0),
                                  "share of E²": lambda v: _pct(v, 0)}))
    out.append(figs.html("error_map"))
    out.append(figs.html("worst_channels"))
    out.append("<h3>Peaks</h3>")
    p = c0.peaks
    missing = p[p["status"] == "measured only"] if len(p) else p
    extra = p[p["status"] == "model only"] if len(p) else p
    if len(missing):
        out.append(_para("Measured resonances the model lacks: "
                         + ", ".join(f"{f:.1f} Hz (seen on {n} channels)" for f, n in
                                     zip(missing["f_measured_hz"], missing["n_channels_measured"])) + "."))
    else:
        out.append(_para("Every measured resonance has a model partner within the matching tolerance."))
    if len(extra):
        out.append(_para("Model resonances without a measured partner: "
                         + ", ".join(f"{f:.1f} Hz" for f in extra["f_model_hz"]) + "."))
    if len(p):
        cols = ["status", "f_measured_hz", "f_model_hz", "shift_pct", "n_channels_measured", "error", "excess_share"]
        out.append(_table(p[cols], formats={"f_measured_hz": lambda v: _fmt(v, 5), "f_model_hz": lambda v: _fmt(v, 5),
                                            "shift_pct": lambda v: "–" if not np.isfinite(float(v)) else
                                            f"{float(v):+.3f} %", "error": _pct,
                                            "excess_share": lambda v: _pct(v, 0)}))
    out.append(figs.html("peaks"))
    return "".join(out)


def _param_text(fit) -> str:
    parts = []
    for name, value in fit.params.items():
        unc = fit.uncertainty.get(name) if fit.uncertainty else None
        txt = f"{name} = {_fmt(value, 4)}"
        if unc is not None:
            u = float(unc)
            txt += " (undetermined)" if not math.isfinite(u) or u > 1.0 else f" ± {100 * u:.1f} %"
        if name in fit.bounds:
            lo, hi = fit.bounds[name]
            txt += f" [{_fmt(lo, 3)}, {_fmt(hi, 3)}]"
        if name in fit.at_bound:
            txt += " AT BOUND"
        parts.append(txt)
    return "; ".join(parts) if parts else f"{fit.n_fitted} curve-fit numbers"


def _verdict(fit, accepted_names_round: set) -> str:
    if fit.name in accepted_names_round:
        return "accepted"
    if fit.name == "experimental_mode":
        return "patch: never accepted as an explanation" + (" (significant)" if fit.significant else "")
    reasons = []
    if fit.delta_bic >= -BIC_THRESHOLD:
        reasons.append(f"ΔBIC {fit.delta_bic:.3g} not below −{BIC_THRESHOLD:g}")
    if fit.reduction < MIN_REDUCTION:
        reasons.append(f"E falls by {100 * fit.reduction:.1f} % < {100 * MIN_REDUCTION:g} %")
    if not fit.plausible:
        reasons.append(f"at a bound: {', '.join(fit.at_bound)}")
    if not reasons and not fit.significant:
        reasons.append("model already at the noise floor")
    if not reasons:
        return "significant, but a better candidate was accepted"
    return "rejected: " + "; ".join(reasons)


def _section_diagnosis(diagnosis, criterion: str) -> str:
    out = [f"<h2>{_e(SECTION_TITLES[3])}</h2>"]
    out.append(f"<div class='box'><p><b>Criterion.</b> {_e(criterion)}.</p>"
               "<p><b>Physics before patches.</b> Two catalogue entries are patches, not physics: "
               "<code>residuals</code> (a lower and an upper residual term per channel, for modes outside the "
               "band) and <code>experimental_mode</code> (a measured mode the FE lacks, fitted with one modal "
               "constant per channel). A patch can always lower the error by curve fitting, so it pays in the "
               "criterion for every number it fits (k counts each residual and each modal constant), while a "
               "physical effect fits a handful of parameters with units and plausible bounds. A physical effect "
               "that explains the same evidence therefore ranks first; <code>experimental_mode</code> is never "
               "accepted as an explanation, because it describes a mode without saying which part makes it."
               "</p></div>")
    accepted = [f.name for f in diagnosis.accepted]
    for k, fits in enumerate(diagnosis.rounds):
        chosen = {accepted[k]} if k < len(accepted) else set()
        label = "the hybrid model" if k == 0 else "the model with " + " + ".join(accepted[:k])
        e0 = fits[0].error_before if fits else float("nan")
        out.append(f"<h3>Round {k + 1}: candidates fitted to {_e(label)} (E = {_e(_pct(e0))})</h3>")
        rows, classes = [], []
        for r, f in enumerate(fits, 1):
            rows.append({"rank": r, "effect": f.name, "kind": "physical" if f.physical else "patch",
                         "fitted parameters ± uncertainty [bounds]": _param_text(f), "n fitted": f.n_fitted,
                         "ΔBIC": f.delta_bic, "E before": _pct(f.error_before), "E after": _pct(f.error_after),
                         "significant": f.significant, "plausible": f.plausible,
                         "verdict": _verdict(f, chosen)})
            classes.append("accepted" if f.name in chosen else "")
        out.append(_table(pd.DataFrame(rows), row_classes=classes, formats={"ΔBIC": lambda v: _fmt(v, 4)}))
        notes = [f"{f.name}: {f.note}" for f in fits if f.note]
        if notes:
            out.append("<ul class='small'>" + "".join(f"<li>{_e(n)}</li>" for n in notes) + "</ul>")
        if not chosen:
            out.append(_para("No candidate of this round passed the criterion: the diagnosis stops here."))
    if not diagnosis.rounds:
        out.append(_para("No candidate was fitted."))
    na = list(getattr(diagnosis, "not_applicable", ()))
    if na:
        out.append("<h3>Candidates that could not be tried</h3>")
        out.append(_table(pd.DataFrame([{"effect": d["name"], "why": d["reason"],
                                         "what would make it apply": d["what_would_make_it_apply"]} for d in na])))
    seen, notes = set(), []
    for fits in diagnosis.rounds:
        for f in fits:
            for a in getattr(f, "assumptions", ()):
                if (f.name, a) not in seen:
                    seen.add((f.name, a))
                    notes.append(f"{f.name}: {a}")
    if notes:
        out.append("<h3>Where the effects attach and what they assume</h3>")
        out.append(_para("Found from the FE geometry, the points table and the wheelset description (thesis "
                         "Table 2.1 values where it states nothing):"))
        out.append("<ul class='small'>" + "".join(f"<li>{_e(n)}</li>" for n in notes) + "</ul>")
    return "".join(out)


def _band_change(before, after) -> pd.DataFrame:
    b = before.bands[["band", "error", "floor"]].rename(columns={"error": "before"})
    b["after"] = after.bands["error"].to_numpy(float)
    b["change"] = b["after"] / b["before"] - 1
    return b[["band", "before", "after", "change", "floor"]]


def _section_effects(diagnosis, comparisons, figs: _Figures) -> str:
    out = [f"<h2>{_e(SECTION_TITLES[4])}</h2>"]
    if not diagnosis.accepted:
        out.append(_para("No effect was accepted: the model is left as it was built."))
        return "".join(out)
    for k, fit in enumerate(diagnosis.accepted):
        before, after = comparisons[k], comparisons[k + 1]
        out.append(f"<h3>Effect {k + 1}: {_e(fit.name)}</h3>")
        role = getattr(fit, "role", "")
        if role:
            out.append(_para({"test_artefact": "A test artefact: it belonged to the test set-up and is removed from "
                                               "the model of the wheelset in service.",
                              "wheelset": "A property of the wheelset: the model in service keeps it.",
                              "service": "Part of the wheelset's environment in service."}.get(role, role)))
        prow = []
        for name, value in fit.params.items():
            lo, hi = fit.bounds.get(name, (None, None))
            u = fit.uncertainty.get(name) if fit.uncertainty else None
            prow.append({"parameter": name, "fitted value": value,
                         "uncertainty": ("undetermined by the data" if u is None or not math.isfinite(float(u))
                                         or float(u) > 1.0 else f"± {100 * float(u):.1f} %"),
                         "lower bound": lo, "upper bound": hi, "at bound": name in fit.at_bound})
        out.append(_table(pd.DataFrame(prow)))
        change = after.summary / before.summary - 1 if before.summary > 0 else float("nan")
        out.append(_para(f"E {_pct(before.summary)} → {_pct(after.summary)} ({100 * change:+.1f} %), "
                         f"noise floor {_pct(after.noise_floor)}; ΔBIC {_fmt(fit.delta_bic, 4)} with "
                         f"{fit.n_fitted} fitted numbers." + (f" Note: {fit.note}" if fit.note else "")))
        out.append("<p>Which bands it fixes (RMS over channels of the band error):</p>")
        out.append(_table(_band_change(before, after), formats={"before": _pct, "after": _pct, "floor": _pct,
                                                                "change": lambda v: f"{100 * float(v):+.1f} %"}))
        fx = fit.fixes
        if fx is not None and len(fx):
            out.append("<p>Channels and bands it fixes most (band-normalised error before and after):</p>")
            cols = [c for c in ("setup", "channel", "band_lo_hz", "band_hi_hz", "rel_error_before", "rel_error_after",
                                "improvement") if c in fx]
            out.append(_table(fx[cols], max_rows=10, formats={"rel_error_before": _pct, "rel_error_after": _pct,
                                                              "improvement": _pct}))
        out.append(figs.html(f"before_after_{k + 1}",
                             f"Error per band before and after adding {fit.name} (E = all bands), with the noise "
                             f"floor."))
        out.append(figs.html(f"worst_channels_after_{k + 1}",
                             f"The worst channels of section 3 with the model including {fit.name}."))
    return "".join(out)


def _section_remaining(diagnosis, comparisons, figs: _Figures) -> str:
    out = [f"<h2>{_e(SECTION_TITLES[5])}</h2>"]
    res = diagnosis.residual()
    # the comparison's E (same definition as the diagnosis' misfit; the line at the top band edge counts)
    e, floor = comparisons[-1].summary, comparisons[-1].noise_floor
    ratio = e / floor if floor > 0 else float("nan")
    if e <= NOISE_MARGIN * floor:
        text = (f"The remaining error E = {_pct(e)} is within {NOISE_MARGIN:g}× the noise floor {_pct(floor)} "
                f"({_fmt(ratio, 3)}×): what is left is what measurement noise alone gives; no further effect can "
                f"be told apart with these data.")
        cls = "box ok"
    else:
        text = (f"The remaining error E = {_pct(e)} is {_fmt(ratio, 3)}× the noise floor {_pct(floor)}: part of "
                f"the misfit is real and no catalogued effect explains it (see where it sits below).")
        cls = "box warn"
    out.append(f"<div class='{cls}'><p>{_e(text)}</p>"
               + "".join(f"<p>{_e(u)}</p>" for u in diagnosis.unexplained) + "</div>")
    out.append("<h3>Remaining error per band</h3>")
    bands = pd.DataFrame([{"band [Hz]": f"{lo:g}–{hi:g}", "RMS error": v} for (lo, hi), v in
                          ((b["band_hz"], b["rms_rel_error"]) for b in res["bands"])])
    if comparisons:
        last = comparisons[-1]
        if len(last.bands) == len(bands):
            bands["noise floor"] = last.bands["floor"].to_numpy(float)
    out.append(_table(bands, formats={"RMS error": _pct, "noise floor": _pct}))
    out.append("<h3>Worst channel × band cells</h3>")
    worst = pd.DataFrame(res["worst"])
    out.append(_table(worst, formats={"rel_error": _pct}))
    out.append(figs.html("error_map_final"))
    out.append(figs.html("worst_channels_final"))
    return "".join(out)


def _section_model(model_doc: Mapping | None) -> str:
    if not model_doc:
        return ""
    out = ["<h3>The diagnosed model</h3>",
           _para(f"Saved as {model_doc.get('file', 'hybrid_model.npz')} with every accepted effect. "
                 + model_doc.get("service", ""))]
    mods = model_doc.get("modifications", [])
    if mods:
        out.append(_table(pd.DataFrame([{"modification": m["kind"], "role": m["role"],
                                         "kept in service": m["kept_in_service"]} for m in mods])))
    return "".join(out)


def _section_appendix(timings: Mapping[str, float], figs: _Figures, files: Mapping[str, str] | None) -> str:
    out = ["<h2>Appendix: timings and files</h2>"]
    if timings:
        t = pd.DataFrame([{"stage": k, "seconds": float(v)} for k, v in timings.items()])
        out.append(_table(t, formats={"seconds": lambda v: f"{float(v):.1f}"}))
    rest = [k for k in figs.paths if k not in figs.used]
    for key in rest:
        out.append(figs.html(key, key.replace("_", " ")))
    if files:
        out.append("<ul class='small'>" + "".join(f"<li>{_e(k)}: <code>{_e(v)}</code></li>" for k, v in files.items())
                   + "</ul>")
    return "".join(out)


# --------------------------------------------------------------------------- entry point
def write_diagnosis_report(path, *, diagnosis, comparisons: Sequence, figures: Mapping[str, Path] | None = None,
                           setups_info: Sequence[Mapping] = (), pairing_table: pd.DataFrame | None = None,
                           timings: Mapping[str, float] | None = None, title: str = "Wheelset model against "
                           "measurement: diagnosis", model_note: str = "", inputs: Mapping[str, str] | None = None,
                           files: Mapping[str, str] | None = None, model_doc: Mapping | None = None,
                           polarity: Sequence[str] = ()) -> Path:
    """Write the diagnosis report as one self-contained HTML file.

    Parameters
    ----------
    path : str or Path
        The HTML file to write (its folder is created).
    diagnosis : receptance.diagnosis.Diagnosis
        The result of :func:`receptance.diagnosis.diagnose`.
    comparisons : sequence of receptance.diagnosis.Comparison
        The model before any effect, then after each accepted effect, in the
        order added (``len(diagnosis.accepted) + 1`` items).
    figures : dict of str -> Path, optional
        PNG files, embedded as base64. Keys place them: ``stabilisation_<setup>``,
        ``synthesis_<setup>``, ``mac``, ``error_map``, ``band_errors``,
        ``worst_channels``, ``peaks``, ``before_after_<k>``,
        ``worst_channels_after_<k>`` (k = 1, 2, ... in the order added),
        ``error_map_final``, ``worst_channels_final``; any other key goes to
        the appendix.
    setups_info : sequence of dict
        Per setup: ``setup, hammer, channels, n_channels, force, hits,
        rejected_hits, rejections`` (list of str), ``n_averages`` (min, max),
        ``n_lines, band_hz, exp_window_decay, n_modes``; missing keys are
        left blank.
    pairing_table : pandas.DataFrame, optional
        :attr:`ema.pairing.Pairing.table`.
    timings : dict of str -> float, optional
        Seconds per stage.
    polarity : sequence of str
        :func:`ema.polarity.polarity_findings`: channels that look read with the wrong sign (a warning box in
        the pairing section).
    title, model_note : str
        Page title; a sentence on how the model was built (section 2).
    inputs, files : dict of str -> str, optional
        Input files (listed under the title) and files written (appendix).
    model_doc : dict, optional
        The saved model (``file``, ``modifications`` with ``kind, role,
        kept_in_service``, ``service``): shown at the end of section 5.

    Returns
    -------
    Path

    Raises
    ------
    ReportError
        A figure file missing or not a PNG, or ``comparisons`` not one more
        than the accepted effects.
    """
    comparisons = list(comparisons)
    if len(comparisons) != len(diagnosis.accepted) + 1:
        raise ReportError(f"comparisons: expected {len(diagnosis.accepted) + 1} (the model before any effect and "
                          f"after each of the {len(diagnosis.accepted)} accepted effects), got {len(comparisons)}")
    figs = _Figures(figures or {})
    criterion = diagnosis.to_json()["criterion"]
    stamp = _dt.datetime.now().strftime("%Y-%m-%d %H:%M")
    head = [f"<h1>{_e(title)}</h1>", f"<p class='small'>Written by railmodal on {_e(stamp)}.</p>"]
    if inputs:
        head.append("<ul class='small'>" + "".join(f"<li>{_e(k)}: <code>{_e(v)}</code></li>"
                                                  for k, v in inputs.items()) + "</ul>")
    head.append(_summary_box(diagnosis, comparisons))
    body = "".join(head + [
        _section_measured(setups_info, figs),
        _section_pairing(pairing_table, setups_info, figs, model_note, polarity),
        _section_before(comparisons[0], figs),
        _section_diagnosis(diagnosis, criterion),
        _section_effects(diagnosis, comparisons, figs) + _section_model(model_doc),
        _section_remaining(diagnosis, comparisons, figs),
        _section_appendix(timings or {}, figs, files),
    ])
    doc = (f"<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'><title>{_e(title)}</title>"
           f"<style>{_CSS}</style></head><body>{body}</body></html>\n")
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(doc, encoding="utf-8")
    log.info("diagnosis report written: %s (%.1f MB, %d figures)", out, out.stat().st_size / 1e6, len(figs.used))
    return out
