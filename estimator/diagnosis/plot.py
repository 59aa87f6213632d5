"""Figures of a field diagnosis (matplotlib imported on call; each takes ``ax=None`` and returns the figure)."""

from __future__ import annotations

import numpy as np

__all__ = ["plot_band_errors", "plot_candidates", "plot_residual"]


def _axes(ax, figsize=(8, 4)):
    import matplotlib.pyplot as plt

    if ax is None:
        fig, ax = plt.subplots(figsize=figsize)
    return ax.figure, ax


def plot_band_errors(diag, *, set_name: str = "validation", ax=None):
    """RMS level error per one-third-octave band and rail: nominal and after each accepted effect."""
    fig, ax = _axes(ax)
    t = diag.by_band[diag.by_band["set"] == set_name]
    for (stage, rail), g in t.groupby(["stage", "rail"], sort=False):
        g = g.groupby("wavelength_mm", as_index=False)["rms_error_db"].mean().sort_values("wavelength_mm")
        ax.semilogx(g["wavelength_mm"], g["rms_error_db"], marker="o", ms=3, label=f"{stage} / rail {rail}")
    ax.axhline(diag.noise_floor_db, color="k", ls="--", lw=1, label="noise floor")
    ax.set_xlabel("wavelength [mm]")
    ax.set_ylabel(f"RMS level error, {set_name} [dB]")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    return fig


def plot_candidates(diag, *, round_index: int = 0, ax=None):
    """ΔBIC of every candidate of a round (accepted green, passing blue, failing grey)."""
    fig, ax = _axes(ax, (8, max(3, 0.3 * len(diag.rounds[round_index]) + 1) if diag.rounds else 3))
    if not diag.rounds:
        return fig
    fits = diag.rounds[round_index]
    acc = {id(c) for c in diag.accepted}
    y = np.arange(len(fits))
    colours = ["tab:green" if id(c) in acc else ("tab:blue" if c.passes else "0.6") for c in fits]
    ax.barh(y, [c.delta_bic for c in fits], color=colours)
    ax.set_yticks(y, [c.effect.label() for c in fits], fontsize=7)
    ax.invert_yaxis()
    ax.axvline(0, color="k", lw=0.8)
    ax.set_xlabel("ΔBIC (negative: the effect explains the evidence)")
    return fig


def plot_residual(diag, ax=None):
    """RMS error per segment along chainage after the last accepted effect (unexplained stretches marked)."""
    fig, ax = _axes(ax)
    r = diag.residual
    for rail, g in r.groupby("rail"):
        x = 0.5 * (g["from_m"] + g["to_m"])
        ax.plot(x, g["rms_error_db"], marker="o", ms=3, label=f"rail {rail}")
        u = g[g["unexplained"]]
        ax.plot(0.5 * (u["from_m"] + u["to_m"]), u["rms_error_db"], "rx", ms=9)
    ax.axhline(diag.noise_floor_db, color="k", ls="--", lw=1, label="noise floor")
    ax.set_xlabel("chainage [m]")
    ax.set_ylabel("RMS level error [dB]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    return fig
