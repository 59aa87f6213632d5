"""Does each accelerometer read what the model and the wheelset's other channels say it should?

An effect outside the catalogue that belongs to one channel — an accelerometer mounted the wrong way round, a
wrong measuring axis in the sensor table — barely moves the estimate when the inversion leans on the other
channels (a lateral accelerometer beside two vertical ones), so the band errors cannot locate it. The model
can: with ``n`` contact forces and ``m > n`` channels, the other ``m − 1`` channels determine the forces
(``F = B₋ₖ⁺ a₋ₖ``, the wheelset's force-to-acceleration map without row ``k``, unregularised) and so predict
channel ``k``: ``âₖ = Bₖ F``. Per segment, the normalised cross-spectrum over the inversion band

    ρₖ = Re Σ_f E[âₖ aₖ*] / sqrt(Σ_f E|âₖ|² · Σ_f E|aₖ|²)

is positive when the channel reads with the model's sign (whatever the level errors), negative when it reads
the opposite. :func:`channel_check` tabulates ρ per segment and channel; :func:`inconsistent_channels` names
the channel whose reversal makes every channel of its wheelset agree with the model again (median ρ over the
segments), or reports the channels that disagree when no single reversal does.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from estimator.diagnosis.state import FieldState
from estimator.diagnosis.transfer import interp_transfer

__all__ = ["channel_check", "inconsistent_channels", "RHO_REVERSED"]

#: a channel whose median ρ lies below minus this reads against the model (a clear, not a marginal, disagreement)
RHO_REVERSED = 0.3


def _predictors(B: np.ndarray) -> list[tuple[list[int], np.ndarray]]:
    """Per channel ``k``: the other channels ``o`` and ``G`` (n_f, m − 1) with ``âₖ = G a_o`` through the map ``B``
    (n_f, m, n) — the model alone decides it, so it serves every sign pattern of the measured spectra."""
    m = B.shape[1]
    out = []
    for k in range(m):
        o = [i for i in range(m) if i != k]
        out.append((o, np.einsum("fj,fji->fi", B[:, k, :], np.linalg.pinv(B[:, o, :]))))
    return out


def _rho(S: np.ndarray, predictors: list[tuple[list[int], np.ndarray]]) -> np.ndarray:
    """ρ of every channel (module docstring) from spectra ``S`` (n_f, m, m) and :func:`_predictors`."""
    out = np.full(len(predictors), np.nan)
    for k, (o, G) in enumerate(predictors):
        cross = np.einsum("fi,fi->", G, S[:, o, k]).real  # Σ E[âₖ aₖ*] with S[j, k] = E[a_j a_k*]
        pp = np.einsum("fi,fij,fj->", G, S[:, o][:, :, o], G.conj()).real
        pk = float(S[:, k, k].real.sum())
        if pp > 0 and pk > 0:
            out[k] = cross / np.sqrt(pp * pk)
    return out


def channel_check(evaluator, state: FieldState = FieldState()) -> pd.DataFrame:
    """ρ per segment and channel (module docstring): ``run_id, wheelset, from_m, to_m, channel, rho,
    rho_if_reversed`` — the latter the channel's ρ when one channel (``reversed``) is taken with the opposite sign.

    Segments whose wheelset has no more channels than contact forces are skipped (nothing to predict from).
    """
    rows = []
    for seg in evaluator.evidence.segments:
        bl = evaluator.blocks[seg.wheelset]
        m, n = len(bl.channels), len(bl.sides)
        if m <= n:
            continue
        offs = np.array([state.offset_of(c) for c in bl.channels])
        B = interp_transfer(bl.force_to_acceleration(evaluator.theta_at(state, seg), offs if offs.any() else None),
                            bl.df, seg.f)
        sel = (seg.f >= bl.f_lo) & (seg.f <= bl.f_hi)
        S, pred = seg.S[sel][:, :m, :m], _predictors(B[sel])
        base = _rho(S, pred)
        for r in range(m):
            d = np.ones(m)
            d[r] = -1.0
            flipped = _rho(S * d[None, :, None] * d[None, None, :], pred)
            for k, c in enumerate(bl.channels):
                rows.append({"run_id": seg.run_id, "wheelset": seg.wheelset, "from_m": seg.from_m, "to_m": seg.to_m,
                             "channel": c, "reversed": bl.channels[r], "rho": base[k], "rho_if_reversed": flipped[k]})
    return pd.DataFrame(rows, columns=["run_id", "wheelset", "from_m", "to_m", "channel", "reversed", "rho",
                                       "rho_if_reversed"])


def inconsistent_channels(table: pd.DataFrame) -> pd.DataFrame:
    """Per wheelset: the channels that read against the model and whether reversing one of them explains it.

    Returns ``wheelset, channel, median_rho, share_negative, n_segments, reversal_explains, from_m, to_m`` for every
    channel whose median ρ lies below −:data:`RHO_REVERSED`; ``reversal_explains`` is the channel whose reversal
    brings every channel of the wheelset to a non-negative median ρ (the largest smallest median when several do),
    empty when none does; ``from_m``/``to_m`` the chainage the segments cover. When a reversal explains the
    wheelset and its channel reads against the model itself, that channel alone is reported: the others' predictions
    hold its reading, so they read against the model through it, not on their own.
    """
    cols = ["wheelset", "channel", "median_rho", "share_negative", "n_segments", "reversal_explains", "from_m",
            "to_m"]
    if table.empty:
        return pd.DataFrame(columns=cols)
    rows = []
    base = table.drop_duplicates(["run_id", "wheelset", "from_m", "channel"])
    for w, g in base.groupby("wheelset"):
        med = g.groupby("channel")["rho"].median()
        bad = med[med < -RHO_REVERSED]
        if bad.empty:
            continue
        t = table[table["wheelset"] == w]
        best, best_min = "", -np.inf
        for r, gr in t.groupby("reversed"):
            mins = gr.groupby("channel")["rho_if_reversed"].median().min()
            if mins >= 0 and mins > best_min:
                best, best_min = str(r), float(mins)
        if best in bad.index:
            bad = bad[[best]]
        for c, v in bad.items():
            gc = g[g["channel"] == c]
            rows.append({"wheelset": int(w), "channel": str(c), "median_rho": float(v),
                         "share_negative": float((gc["rho"] < 0).mean()), "n_segments": int(len(gc)),
                         "reversal_explains": best, "from_m": float(gc["from_m"].min()),
                         "to_m": float(gc["to_m"].max())})
    return pd.DataFrame(rows, columns=cols)
