"""Plots of a model-versus-measurement comparison: error map, errors per band, before/after, peaks.

Matplotlib; not imported by ``import receptance`` (import ``receptance.plot_compare`` explicitly).
Every function takes a :class:`~receptance.diagnosis.compare.Comparison` (nothing is
recomputed here: the plotted numbers are the comparison's), ``ax=None``, and
returns the figure. The measured-versus-model overlays on the worst channels
are :func:`receptance.plot_model.plot_comparison`.
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from receptance.diagnosis.compare import BODIES, Comparison, ComparisonError

__all__ = ["error_map_order", "plot_error_map", "plot_band_errors", "plot_before_after", "plot_peaks"]

_BODY_COLOURS = {"axle": "tab:blue", "wheel": "tab:orange", "disc": "tab:green", "axlebox": "tab:red",
                 "other": "tab:gray"}


def _axes(ax, figsize):
    if ax is None:
        fig, ax = plt.subplots(figsize=figsize)
        return fig, ax
    return ax.figure, ax


def error_map_order(comparison: Comparison) -> np.ndarray:
    """Row order of the error map: channels grouped by body (axle, wheel, disc, axlebox, other), then setup.

    Within a group the comparison's own order is kept.
    """
    t = comparison.channels
    rank = {b: k for k, b in enumerate(BODIES)}
    setups = {s: k for k, s in enumerate(dict.fromkeys(t["setup"]))}
    key = [(rank.get(b, len(BODIES)), setups[s], i) for i, (b, s) in enumerate(zip(t["body"], t["setup"]))]
    return np.array([k[2] for k in sorted(key)], dtype=int)


def plot_error_map(comparison: Comparison, *, ax=None, vmax_db: float = 20.0):
    """Channel × frequency image of ``20 log10 |H_model / H_measured|``, channels grouped by body.

    Red: the model responds more than the structure; blue: less. Bodies are
    separated by horizontal lines and labelled on the right; band edges are
    dotted vertical lines.

    Parameters
    ----------
    comparison : Comparison
    ax : matplotlib Axes, optional
    vmax_db : float
        Colour scale limit (symmetric) [dB].
    """
    order = error_map_order(comparison)
    t = comparison.channels.iloc[order]
    f = comparison.measured.freqs_hz
    fig, ax = _axes(ax, (10, max(4.0, 0.14 * len(order) + 1.5)))
    img = np.asarray(comparison.error_map_db)[order]
    df = f[1] - f[0] if f.size > 1 else 1.0
    im = ax.imshow(img, aspect="auto", origin="upper", cmap="RdBu_r", vmin=-vmax_db, vmax=vmax_db,
                   extent=(f[0] - df / 2, f[-1] + df / 2, len(order) - 0.5, -0.5), interpolation="nearest")
    ax.set_yticks(np.arange(len(order)), t["key"], fontsize=5 if len(order) > 30 else 7)
    bodies = t["body"].to_numpy()
    edges = np.flatnonzero(bodies[1:] != bodies[:-1]) + 0.5
    for y in edges:
        ax.axhline(y, color="k", lw=0.8)
    starts = np.concatenate([[-0.5], edges])
    ends = np.concatenate([edges, [len(order) - 0.5]])
    for a, b in zip(starts, ends):
        body = bodies[int(np.ceil(a))]
        ax.text(1.005, 1 - (a + b + 1) / 2 / len(order), body, transform=ax.transAxes, fontsize=8,
                va="center", ha="left", color=_BODY_COLOURS.get(body, "k"))
    for lo, _ in comparison.bands_hz[1:]:
        ax.axvline(lo, color="k", ls=":", lw=0.6)
    ax.set_xlabel("frequency [Hz]")
    ax.set_title(f"model / measured [dB], E = {100 * comparison.summary:.2f} % "
                 f"(noise floor {100 * comparison.noise_floor:.2f} %)", fontsize=9)
    fig.colorbar(im, ax=ax, pad=0.08, label="20 log10 |H_model / H_measured| [dB]")
    return fig


def plot_band_errors(comparison: Comparison, *, ax=None, by_body: bool = False):
    """Band-normalised complex error per band [%], with the noise floor of each band.

    Parameters
    ----------
    comparison : Comparison
    ax : matplotlib Axes, optional
    by_body : bool
        Grouped bars per body (``comparison.body_band_errors``) instead of one
        bar per band (``comparison.bands['error']``).
    """
    bands = comparison.bands
    fig, ax = _axes(ax, (max(6.0, 1.1 * len(bands) + 2), 3.6))
    x = np.arange(len(bands))
    if by_body:
        table = comparison.body_band_errors
        width = 0.8 / max(len(table), 1)
        for k, (body, row) in enumerate(table.iterrows()):
            ax.bar(x - 0.4 + width * (k + 0.5), 100 * row.to_numpy(float), width,
                   color=_BODY_COLOURS.get(body, "tab:gray"), label=body)
    else:
        ax.bar(x, 100 * bands["error"].to_numpy(float), 0.6, color="tab:blue", label="error")
    if np.isfinite(bands["floor"]).any():
        ax.plot(x, 100 * bands["floor"].to_numpy(float), "_", color="k", ms=28, mew=2, label="noise floor")
    ax.set_xticks(x, bands["band"], fontsize=8)
    ax.set_ylabel("band-normalised complex error [%]")
    ax.set_yscale("log")
    ax.grid(True, axis="y", which="both", lw=0.3)
    ax.legend(fontsize=7)
    ax.set_title(f"error per band: E = {100 * comparison.summary:.2f} % "
                 f"(noise floor {100 * comparison.noise_floor:.2f} %)", fontsize=9)
    fig.tight_layout()
    return fig


def plot_before_after(before: Comparison, after: Comparison, *, ax=None, labels=("before", "after")):
    """Watch the error fall: error per band before and after a model change, plus the summaries.

    Bars per band (and a last group ``E``, the figure of merit) for both
    comparisons, the noise floor of the measurement as black ticks.

    Raises
    ------
    ComparisonError
        If the two comparisons do not use the same bands.
    """
    if list(before.bands["band"]) != list(after.bands["band"]):
        raise ComparisonError(f"before and after must use the same bands, got {list(before.bands['band'])} and "
                              f"{list(after.bands['band'])}")
    names = list(before.bands["band"]) + ["E (all)"]
    b = np.append(before.bands["error"].to_numpy(float), before.summary)
    a = np.append(after.bands["error"].to_numpy(float), after.summary)
    floor = np.append(after.bands["floor"].to_numpy(float), after.noise_floor)
    fig, ax = _axes(ax, (max(6.0, 1.2 * len(names) + 2), 3.8))
    x = np.arange(len(names))
    ax.bar(x - 0.2, 100 * b, 0.4, color="tab:gray", label=labels[0])
    ax.bar(x + 0.2, 100 * a, 0.4, color="tab:green", label=labels[1])
    if np.isfinite(floor).any():
        ax.plot(x, 100 * floor, "_", color="k", ms=30, mew=2, label="noise floor")
    ax.axvline(len(names) - 1.5, color="k", lw=0.6)
    ax.set_xticks(x, names, fontsize=8)
    ax.set_yscale("log")
    ax.set_ylabel("band-normalised complex error [%]")
    ax.grid(True, axis="y", which="both", lw=0.3)
    ax.legend(fontsize=7)
    ax.set_title(f"E: {100 * before.summary:.2f} % ({labels[0]}) → {100 * after.summary:.2f} % ({labels[1]}); "
                 f"noise floor {100 * after.noise_floor:.2f} %", fontsize=9)
    fig.tight_layout()
    return fig


def plot_peaks(comparison: Comparison, *, ax=None):
    """Channel-normalised mean power of measurement and model with the matched and unmatched resonances.

    Matched peaks: grey dashed lines; measured-only: red triangles (modes the
    model lacks); model-only: blue triangles.
    """
    f = comparison.measured.freqs_hz
    fig, ax = _axes(ax, (10, 3.8))
    ax.plot(f, 10 * np.log10(comparison.indicator_measured), color="k", lw=1.0, label="measured")
    ax.plot(f, 10 * np.log10(comparison.indicator_model), color="tab:red", lw=1.0, ls="--", label="model")
    p = comparison.peaks
    top = 10 * np.log10(max(np.max(comparison.indicator_measured), np.max(comparison.indicator_model)))
    for fm in p.loc[p["status"] == "matched", "f_measured_hz"]:
        ax.axvline(fm, color="0.6", ls=":", lw=0.8)
    meas = p.loc[p["status"] == "measured only", "f_measured_hz"].to_numpy(float)
    mod = p.loc[p["status"] == "model only", "f_model_hz"].to_numpy(float)
    ax.plot(meas, np.full(meas.size, top + 3), "v", color="tab:red", ms=8, label="measured only", ls="none")
    ax.plot(mod, np.full(mod.size, top + 3), "v", color="tab:blue", ms=8, label="model only", ls="none")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("mean normalised power [dB]")
    ax.grid(True, lw=0.3)
    ax.legend(fontsize=7, ncol=4)
    ax.set_title(f"resonances: {int((p['status'] == 'matched').sum())} matched, {meas.size} in the measurement only, "
                 f"{mod.size} in the model only", fontsize=9)
    fig.tight_layout()
    return fig
