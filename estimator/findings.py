"""What an analyst reads first about a field estimate: where the rails are corrugated, how badly, of what type.

One list of sentences serves the command's console summary and the report's "In short" box, so the two never
tell different stories. Each corrugated rail and EN 13231-3 band gets one sentence: the stretch whose spectral
peak stands out most, its median peak-to-peak, what the trailing wheelset (a second, independent estimate of
the same rail) says, and the wavelength-fixing mechanism its frequency ``f = v/λ`` points to (thesis eq. 1.1,
Table 1.1; :mod:`estimator.corrugation`). Before them: the wheelsets not estimated and the stretches where the
wheel leaves the rail (:mod:`estimator.contact_load`), since they qualify everything after.
"""

from __future__ import annotations

__all__ = ["headline"]

#: the console keeps to characters every terminal shows; the report uses the proper symbols
_PLAIN = {"um": "um", "lambda": "lambda", "to": "->"}
_RICH = {"um": "µm", "lambda": "λ", "to": "→"}


def headline(estimate, *, plain: bool = False) -> list[str]:
    """The findings of one estimate, most important first.

    Parameters
    ----------
    estimate : FieldEstimate
        Reads ``skipped``, ``qc`` (``kind == "contact_loss"``), ``corrugation`` and ``models`` (the last model,
        the most complete the run was inverted with, speaks for the run).
    plain : bool
        ``um``, ``lambda`` and ``->`` instead of µm, λ and → (the console).

    Returns
    -------
    list of str
        Sentences: wheelsets not estimated, contact loss, one line per corrugated rail and band, how many more
        stretches ``corrugation.csv`` lists; or that no stretch is above the thresholds.
    """
    from estimator.corrugation import wheelset_agreement

    s = _PLAIN if plain else _RICH
    est = estimate
    lines = [f"not estimated: {x}" for x in est.skipped]
    lifted = est.qc[est.qc["kind"] == "contact_loss"] if not est.qc.empty else est.qc
    if len(lifted):
        lines.append(f"contact loss: the wheel leaves the rail on {len(lifted)} stretch(es), "
                     f"{', '.join(sorted(set(lifted['channel'])))} (the estimate there is not the rail's; qc.csv)")
    c = est.corrugation
    if c.empty:
        lines.append("no stretch above the EN 13231-3 thresholds in 30-100 or 100-300 mm")
        return lines
    model = est.models[-1] if est.models else ""
    best = wheelset_agreement(c, model)
    for r in best.itertuples():
        second = (f"trailing wheelset {r.trailing_pk_pk_um:.1f} {s['um']}" if r.agree else
                  "NOT above the threshold on the trailing wheelset: the two estimates disagree"
                  + (f"; {r.note}" if r.note else ""))
        lines.append(f"corrugated: {r.stretch}, rail {r.rail}, {r.band_mm} mm: {r.median_pk_pk_um:.1f} {s['um']} "
                     f"pk-pk ({second}), {s['lambda']} {r.dominant_wavelength_mm:.0f} mm at {r.speed_m_s:.1f} m/s = "
                     f"{r.frequency_hz:.0f} Hz {s['to']} {r.mechanism}")
    lead = c[(c["role"] == "leading") & (c["model"] == model)]
    rest = len(lead) - len(best)
    if rest:
        lines.append(f"{rest} more stretch(es) above the EN 13231-3 thresholds (broadband or repeated): "
                     "corrugation.csv")
    return lines
