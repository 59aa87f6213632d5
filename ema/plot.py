"""Plots of the identification: stabilisation diagram and measured-versus-synthesised FRFs.

Kept apart from the computing modules (``shared/DESIGN.md``): nothing here is
imported by ``import ema``; import ``ema.plot`` explicitly.  Every function
takes the data object and an optional ``ax`` and returns the figure.
"""

from __future__ import annotations

from typing import Sequence

import matplotlib
import matplotlib.pyplot as plt
import numpy as np

from .frf import FrequencyResponse
from .stabilisation import StabilisationDiagram

__all__ = ["plot_stabilisation", "plot_synthesis"]

#: status code -> (label, marker, colour, size)
_STYLE = {
    "o": ("new", ".", "0.7", 4),
    "f": ("stable f", "x", "tab:blue", 14),
    "d": ("stable f, zeta", "^", "tab:orange", 14),
    "v": ("stable f, shape", "s", "tab:purple", 12),
    "s": ("stable f, zeta, shape", "o", "tab:red", 16),
}


def _new_ax(ax, **kw):
    if ax is None:
        fig, ax = plt.subplots(**kw)
        return fig, ax
    return ax.figure, ax


def plot_stabilisation(
    diagram: StabilisationDiagram,
    frf: FrequencyResponse | None = None,
    ax: matplotlib.axes.Axes | None = None,
    *,
    selected: Sequence[float] | None = None,
    show: str = "ofdvs",
    indicator: str = "cmif",
) -> matplotlib.figure.Figure:
    """Stabilisation diagram: poles by frequency and model order, coded by stability.

    Parameters
    ----------
    diagram : StabilisationDiagram
    frf : FrequencyResponse, optional
        Overlay (right axis, log scale) the FRFs' mode indicator over the band.
    ax : matplotlib Axes, optional
    selected : sequence of float, optional
        Frequencies [Hz] of the selected modes, drawn as vertical lines
        (e.g. ``identification.modes.freqs_hz``).
    show : str
        Status codes to draw (``o`` new, ``f``, ``d``, ``v``, ``s``; see
        :attr:`StabilisationDiagram.status`).
    indicator : {"cmif", "sum"}
        ``"cmif"``: the single-input CMIF ``sqrt(sum_j |H_j|^2)``; ``"sum"``:
        ``sum_j |H_j|``.

    Returns
    -------
    matplotlib.figure.Figure
    """
    if indicator not in ("cmif", "sum"):
        raise ValueError(f"indicator must be 'cmif' or 'sum', got {indicator!r}")
    fig, ax = _new_ax(ax, figsize=(10, 6))
    lo, hi = diagram.band_hz
    keep = diagram.in_band & (diagram.zeta > 0)
    status = diagram.status
    for code in "ofdvs":
        if code not in show:
            continue
        label, marker, colour, size = _STYLE[code]
        m = keep & (status == code)
        if m.any():
            ax.scatter(diagram.freqs_hz[m], diagram.order[m], s=size, marker=marker, c=colour,
                       label=f"{label} ({int(m.sum())})", linewidths=0.8)
    if selected is not None:
        for i, f in enumerate(np.atleast_1d(selected)):
            ax.axvline(f, color="k", lw=0.6, ls="--", label="selected" if i == 0 else None)
    ax.set_xlim(lo, hi)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("model order (poles in band)")
    title = "stabilisation diagram"
    if diagram.exp_window_decay:
        title += f" (exponential window {diagram.exp_window_decay:g} 1/s removed)"
    ax.set_title(title)
    if frf is not None:
        sub = frf.select(band_hz=(lo, hi))
        mag = np.abs(sub.data[:, 0, :])
        y = np.sqrt(np.sum(mag**2, axis=0)) if indicator == "cmif" else np.sum(mag, axis=0)
        ax2 = ax.twinx()
        ax2.semilogy(sub.freqs_hz, y, color="0.35", lw=0.8)
        ax2.set_ylabel(("CMIF" if indicator == "cmif" else "sum |H|") + f" [{sub.units}]")
        ax2.set_xlim(lo, hi)
    ax.legend(loc="upper left", fontsize="small", framealpha=0.8)
    return fig


def plot_synthesis(
    frf: FrequencyResponse,
    synthesis: FrequencyResponse,
    ax: matplotlib.axes.Axes | None = None,
    *,
    outputs: Sequence[str] | None = None,
    phase: bool = True,
) -> matplotlib.figure.Figure:
    """Measured versus synthesised FRFs (magnitude in dB and, optionally, phase).

    Parameters
    ----------
    frf : FrequencyResponse
        Measured FRFs.
    synthesis : FrequencyResponse
        Synthesised FRFs, e.g. ``identification.synthesis`` (same lines or a subset).
    ax : matplotlib Axes, optional
        Draw the magnitude only into this axes.
    outputs : sequence of str, optional
        Channels to draw (default: up to four of the synthesis' outputs).
    phase : bool
        Add a phase panel (only when ``ax`` is None).

    Returns
    -------
    matplotlib.figure.Figure
    """
    outs = list(outputs) if outputs is not None else list(synthesis.outputs[:4])
    missing = [o for o in outs if o not in synthesis.outputs or o not in frf.outputs]
    if missing:
        raise KeyError(f"outputs {missing} not in both responses; measured {list(frf.outputs)}, "
                       f"synthesis {list(synthesis.outputs)}")
    if ax is None:
        if phase:
            fig, (ax, axp) = plt.subplots(2, 1, sharex=True, figsize=(10, 7), gridspec_kw={"height_ratios": [2, 1]})
        else:
            fig, ax = plt.subplots(figsize=(10, 5))
            axp = None
    else:
        fig, axp = ax.figure, None
    lo, hi = synthesis.freqs_hz[0], synthesis.freqs_hz[-1]
    meas = frf.select(outputs=outs, band_hz=(lo, hi))
    syn = synthesis.select(outputs=outs)
    for k, o in enumerate(outs):
        colour = f"C{k % 10}"
        hm = meas.data[k, 0]
        hs = syn.data[k, 0]
        ax.plot(meas.freqs_hz, 20 * np.log10(np.abs(hm)), color=colour, lw=0.9, label=f"{o} measured")
        ax.plot(syn.freqs_hz, 20 * np.log10(np.abs(hs)), color=colour, lw=0.9, ls="--", label=f"{o} synthesised")
        if axp is not None:
            axp.plot(meas.freqs_hz, np.degrees(np.angle(hm)), color=colour, lw=0.8)
            axp.plot(syn.freqs_hz, np.degrees(np.angle(hs)), color=colour, lw=0.8, ls="--")
    ax.set_ylabel(f"|H| [dB re 1 {frf.units}]")
    ax.set_xlim(lo, hi)
    ax.legend(fontsize="small", ncol=2)
    ax.set_title(f"{frf.quantity}: measured (solid) vs synthesised (dashed)")
    if axp is not None:
        axp.set_ylabel("phase [deg]")
        axp.set_xlabel("frequency [Hz]")
        axp.set_ylim(-180, 180)
    else:
        ax.set_xlabel("frequency [Hz]")
    return fig
