"""``field_diagnosis.json``, the HTML report and the calibrated model of a field diagnosis."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd

from estimator.diagnosis.calibration import save_calibration
from estimator.html import escape, figure_html, page, table_html

__all__ = ["diagnosis_document", "write_field_diagnosis"]


def _clean(o):
    if isinstance(o, dict):
        return {str(k): _clean(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_clean(v) for v in o]
    if isinstance(o, (np.floating, float)):
        return float(o) if math.isfinite(float(o)) else None
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, np.bool_):
        return bool(o)
    return o


def _index_summary(idx: pd.DataFrame) -> pd.DataFrame:
    """Band-index RMS error per stage, set, rail and band (pooled over runs and wheelsets)."""
    if idx.empty:
        return idx
    d = idx.dropna(subset=["rms_error_db"]).assign(ss=lambda t: t["n_windows"] * t["rms_error_db"] ** 2)
    g = d.groupby(["stage", "set", "rail", "band_mm"], as_index=False)[["n_windows", "ss"]].sum()
    g["rms_error_db"] = np.sqrt(g["ss"] / g["n_windows"])
    return g.drop(columns="ss")


def diagnosis_document(res) -> dict:
    """The content of ``field_diagnosis.json``."""
    d = res.diagnosis
    idx = _index_summary(res.index_errors)
    return _clean({
        "site_m": list(res.site), "calibration_date": res.calibration_date, "criterion": d.criterion,
        "verdict": d.verdict,
        "noise_floor_db": {"total": d.noise_floor_db, "run_to_run_scatter": d.scatter_db,
                           "reference_noise": d.reference_db, "inversion_bias": d.inversion_db},
        "accepted": [c.as_dict() for c in d.accepted],
        "rounds": [[c.as_dict() for c in r] for r in d.rounds],
        "errors": d.errors.to_dict(orient="records"),
        "band_index_errors": idx.to_dict(orient="records"),
        "residual": d.residual.to_dict(orient="records"),
        "unexplained": d.unexplained_stretches(),
        "inconsistent_channels": ([] if res.channel_check is None
                                  else res.channel_check.to_dict(orient="records")),
        "comparison": res.comparison.as_dict(),
        "starting_state": res.start.as_dict(), "calibrated_state": res.state.as_dict(),
        "runs": res.runs.to_dict(orient="records"), "rejected": list(res.rejected),
        "config": res.config.as_dict(), "estimator_config": res.estimator_config.as_dict(),
        "timings_s": res.timings_s})


def _meanings(accepted) -> list[str]:
    """The accepted effects in the field's terms (:meth:`~estimator.diagnosis.effects.FieldEffect.meaning`)."""
    if not accepted:
        return []
    items = "".join(f"<li><b>{escape(c.effect.label())}</b>: {escape(c.effect.meaning(c.params))}</li>"
                    for c in accepted)
    return ["<h2>What the accepted effects mean</h2>", f"<ol>{items}</ol>"]


def _start_note(res) -> list[str]:
    """What the search started from, when a previous calibration was given."""
    if res.start.is_nominal:
        return []
    return ["<h2>Starting calibration</h2>",
            f"<p>The runs were estimated, and the search started, with a previous calibration: "
            f"{escape(res.start.summary())}. The stage <i>nominal</i> of every table below is that calibration; the "
            "effects accepted here are added on top of it, and the calibrated model saved with this report holds "
            "both.</p>"]


def _html(res, figs: dict) -> str:
    d = res.diagnosis
    cmp_ = res.comparison
    warn = "" if not d.accepted or "No effect" not in d.verdict else " warn"
    body = [f"<h1>Field diagnosis — site {res.site[0]:g}–{res.site[1]:g} m, {escape(res.calibration_date)}</h1>",
            f"<div class='box{warn}'><b>Verdict.</b> {escape(d.verdict)}</div>",
            f"<p class='small'>Criterion: {escape(d.criterion)}</p>",
            *_meanings(d.accepted),
            *_start_note(res),
            "<h2>Compare with the reference (" + ("nominal model" if res.start.is_nominal
                                                 else "the starting calibration") + ")</h2>",
            f"<p>Figure of merit E = {cmp_.figure_of_merit_db:.2f} dB (RMS level error of the calibration cells); "
            f"noise floor {d.noise_floor_db:.2f} dB (run-to-run scatter {d.scatter_db:.2f} dB, reference noise "
            f"{d.reference_db:.2f} dB, inversion bias {d.inversion_db:.2f} dB).</p>",
            "<p><b>Where it fails:</b> " + (escape("; ".join(cmp_.failing)) or "nowhere above the limit") + "</p>",
            "<h3>EN 13231-3 band-index error per rail</h3>", table_html(cmp_.en_bands),
            "<h3>One-third-octave level error per rail</h3>", table_html(cmp_.third_octave),
            "<h3>Side discrimination (error of the L − R level difference)</h3>", table_html(cmp_.side),
            "<h3>Coherence between estimate and reference along chainage</h3>", table_html(cmp_.coherence),
            "<h3>Speed range and wheelset role</h3>", table_html(cmp_.by_speed), table_html(cmp_.by_role),
            "<h2>Candidates</h2>", figure_html(figs.get("candidates"), "ΔBIC of the first round's candidates")]
    for i, r in enumerate(d.rounds):
        t = pd.DataFrame([{"effect": c.effect.label(), "ΔBIC": c.delta_bic, "E before": c.error_before,
                           "E after": c.error_after, "validation before": c.validation_before,
                           "validation after": c.validation_after,
                           "values": ", ".join(f"{k}={v:.4g}±{c.uncertainty.get(k, math.nan):.2g}"
                                               for k, v in c.params.items()),
                           "verdict": c.verdict()} for c in r])
        body += [f"<h3>Round {i + 1}</h3>", table_html(t)]
    body += ["<h2>Errors before and after</h2>", table_html(d.errors),
             "<h3>EN 13231-3 band-index error through the estimator (before/after, calibration/validation)</h3>",
             table_html(_index_summary(res.index_errors)),
             figure_html(figs.get("bands"), "RMS level error per band on the validation stretches"),
             "<h2>Residual along chainage</h2>", figure_html(figs.get("residual"), "after the accepted effects"),
             table_html(d.residual),
             "<h2>Runs</h2>", table_html(res.runs),
             "<h3>Rejected segments and files</h3>", "<pre>" + escape("\n".join(res.rejected[:200])) + "</pre>"]
    return page("field diagnosis", body)


def write_field_diagnosis(res, out, model_file=None) -> dict:
    """Write ``field_diagnosis.json``, ``report.html``, figures and ``calibrated_model/`` into ``out``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from estimator.diagnosis.plot import plot_band_errors, plot_candidates, plot_residual

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    files = {}
    figs = {}
    for name, fn in (("candidates", plot_candidates), ("bands", plot_band_errors), ("residual", plot_residual)):
        fig = fn(res.diagnosis)
        p = out / f"{name}.png"
        fig.savefig(p, dpi=110, bbox_inches="tight")
        plt.close(fig)
        figs[name] = p
    doc = diagnosis_document(res)
    if model_file is not None:
        p = save_calibration(out / "calibrated_model", model_file, res.state, site=res.site,
                             date=res.calibration_date,
                             extra={"accepted": [c.effect.label() for c in res.diagnosis.accepted],
                                    "started_from": res.start.summary()})
        doc["calibrated_model"] = {"folder": "calibrated_model", "version": json.loads(p.read_text())["version"]}
        files["calibrated_model"] = p
    (out / "field_diagnosis.json").write_text(json.dumps(doc, indent=1, allow_nan=False))
    (out / "report.html").write_text(_html(res, figs))
    files.update({"json": out / "field_diagnosis.json", "report": out / "report.html", **figs})
    return files
