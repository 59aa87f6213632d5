"""Plots of the modal model: receptances between named DOFs and model-versus-measurement overlays.

Matplotlib; not imported by ``import receptance`` (import ``receptance.plot_model`` explicitly).
Every function returns the figure.
"""

from __future__ import annotations

from typing import Sequence

import matplotlib.pyplot as plt
import numpy as np

from ema.frf import FrequencyResponse

__all__ = ["plot_receptances", "plot_comparison", "plot_channel_errors"]


def plot_receptances(frf: FrequencyResponse, pairs: Sequence[tuple[str, str]] | None = None, *, ax=None,
                     title: str | None = None):
    """Magnitude (log) and phase of chosen output/input pairs of a receptance-type response.

    Parameters
    ----------
    frf : FrequencyResponse
    pairs : sequence of (output, input), optional
        Default: every output for the first input.
    ax : (Axes, Axes), optional
        Magnitude and phase axes.
    """
    if ax is None:
        fig, (a_mag, a_ph) = plt.subplots(2, 1, sharex=True, figsize=(8, 6), height_ratios=(3, 1.3))
    else:
        a_mag, a_ph = ax
        fig = a_mag.figure
    pairs = pairs or [(o, frf.inputs[0]) for o in frf.outputs]
    for o, i in pairs:
        h = frf.select(outputs=[o], inputs=[i]).data[0, 0]
        label = f"{o} / {i}" if o != i else f"{o} (direct)"
        a_mag.semilogy(frf.freqs_hz, np.abs(h), lw=1.0, label=label)
        a_ph.plot(frf.freqs_hz, np.degrees(np.angle(h)), lw=0.8)
    a_mag.set_ylabel(f"|{frf.quantity}| [{frf.units}]")
    a_ph.set_ylabel("phase [deg]")
    a_ph.set_xlabel("frequency [Hz]")
    a_ph.set_yticks([-180, -90, 0, 90, 180])
    a_mag.grid(True, which="both", lw=0.3)
    a_ph.grid(True, lw=0.3)
    a_mag.legend(fontsize=7, ncol=2)
    if title:
        a_mag.set_title(title)
    fig.tight_layout()
    return fig


def plot_comparison(comparison, channels: Sequence[str] | None = None, *, n_worst: int = 4, fig=None):
    """Measured versus model accelerance on chosen channels (thesis Figs. 3.18–3.19).

    Parameters
    ----------
    comparison : receptance.compare.Comparison
    channels : sequence of str, optional
        Row keys (``comparison.channels['key']``, e.g. ``flexural/axle_01``) or,
        when unambiguous, channel names. Default: the ``n_worst`` channels of
        the comparison's ranking (largest share of the error above the noise
        floor).
    """
    table = comparison.channels
    keys = list(table["key"]) if "key" in table else list(table["channel"])
    if channels is None:
        ranked = comparison.ranking
        channels = list(ranked.loc[ranked["kind"] == "channel", "name"].head(n_worst))
    else:
        by_name = {}
        for k, name in zip(keys, table["channel"]):
            by_name.setdefault(str(name), []).append(k)
        resolved = []
        for ch in channels:
            if ch in keys:
                resolved.append(ch)
            elif len(by_name.get(ch, [])) == 1:
                resolved.append(by_name[ch][0])
            else:
                raise KeyError(f"channel {ch!r} is not a row key of the comparison and not a unique channel name; "
                               f"keys: {keys}")
        channels = resolved
    n = len(channels)
    if fig is None:
        fig = plt.figure(figsize=(9, 2.4 * n + 0.6))
    axes = fig.subplots(n, 1, sharex=True, squeeze=False)[:, 0]
    f = comparison.measured.freqs_hz
    for ax, ch in zip(axes, channels):
        hx = comparison.measured.select(outputs=[ch]).data[0, 0]
        hm = comparison.model.select(outputs=[ch]).data[0, 0]
        row = table.iloc[keys.index(ch)]
        ax.semilogy(f, np.abs(hx), color="k", lw=1.0, label="measured H1")
        ax.semilogy(f, np.abs(hm), color="tab:red", lw=1.0, ls="--", label="model")
        ax.semilogy(f, np.abs(hm - hx), color="0.6", lw=0.7, ls=":", label="|model − measured|")
        ax.set_ylabel("|A| [m/s²/N]")
        extra = ""
        if "band_error" in row:
            extra = f", band-normalised {100 * row['band_error']:.1f} %"
        ax.set_title(f"{ch}: {row['db_rms']:.2f} dB RMS, complex error {100 * row['rel_error']:.2f} %, "
                     f"FRAC {row['frac']:.4f}{extra}", fontsize=9)
        ax.grid(True, which="both", lw=0.3)
    axes[0].legend(fontsize=8)
    axes[-1].set_xlabel("frequency [Hz]")
    fig.tight_layout()
    return fig


def plot_channel_errors(comparison, *, ax=None):
    """Bar chart of the per-channel error (dB RMS and complex error) of a comparison."""
    if ax is None:
        fig, ax = plt.subplots(figsize=(max(6, 0.3 * len(comparison.channels) + 2), 3.5))
    else:
        fig = ax.figure
    t = comparison.channels
    x = np.arange(len(t))
    ax.bar(x, t["db_rms"], color="tab:blue", label="dB RMS")
    ax.set_xticks(x, t["key"] if "key" in t else t["channel"], rotation=90, fontsize=7)
    ax.set_ylabel("magnitude error [dB RMS]")
    ax2 = ax.twinx()
    ax2.plot(x, 100 * t["rel_error"], "o", color="tab:red", ms=3, label="complex error")
    ax2.set_ylabel("complex error [%]")
    ax.axhline(comparison.summary_db, color="tab:blue", ls=":", lw=1)
    ax.set_title(f"model vs measurement, {comparison.band_hz[0]:g}–{comparison.band_hz[1]:g} Hz: "
                 f"median {comparison.summary_db:.2f} dB", fontsize=9)
    fig.tight_layout()
    return fig
