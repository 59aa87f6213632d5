"""Plots of the measurement transfer functions and their robustness (thesis Figs. 4.1–4.7).

Every function takes a result object (:class:`~receptance.transfer.MeasurementTransfer`,
:class:`~receptance.robustness.RobustnessResult`) and an optional ``ax``, and
returns the matplotlib figure; matplotlib is imported only when a function
is called.  Each drawn line's data are exactly the plotted quantity
(magnitude, dB or standard deviation), in the order documented.
"""

from __future__ import annotations

import numpy as np

__all__ = ["plot_half_receptances", "plot_transfer", "plot_spectral_std"]

_TITLES = {
    "half": "half wheelset (eq. 2.6)",
    "vertical": "full wheelset, vertical dynamics (eq. 2.11)",
    "vertical_lateral": "full wheelset, vertical and lateral dynamics (eq. 2.22)",
}


def _axes(ax, **subplots_kw):
    import matplotlib.pyplot as plt

    if ax is None:
        fig, ax = plt.subplots(**subplots_kw)
        return fig, ax
    return ax.figure, ax


def plot_half_receptances(transfer, *, side: str | None = None, ax=None):
    """Direct receptances of the half-wheelset model (thesis Fig. 4.1).

    Lines, in order: wheel ``A_33`` (``|Nᵀ A_W N|`` of ``side``), rail
    ``A_RZ``, contact ``1/K_H`` (omitted for a rigid contact, ``K_H = ∞``)
    and their sum ``|A_33 + A_RZ + 1/K_H|`` (the ``D`` of eq. 2.5), log
    magnitude [m/N] against frequency.

    Parameters
    ----------
    transfer : MeasurementTransfer
        Usually from :func:`~receptance.transfer.half_wheelset_transfer`;
        for a two-sided model the direct terms of ``side`` are drawn.
    side : {"L", "R"}, optional
        Default: the first side of ``transfer``.
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib.figure.Figure
    """
    side = transfer.sides[0] if side is None else side
    if side not in transfer.sides:
        raise ValueError(f"side {side!r} is not in this transfer function's sides {transfer.sides}")
    k = transfer.sides.index(side)
    fig, ax = _axes(ax, figsize=(7, 4.5))
    f = transfer.freqs_hz
    j = "3" if side == "L" else "9"
    ax.semilogy(f, np.abs(transfer.wheel_compliance.data[k, k]), label=f"wheel A_{j},{j}")
    ax.semilogy(f, np.abs(transfer.rail_compliance.data[k, k]), label="rail A_RZ")
    c = float(transfer.contact_compliance[k])
    if c > 0:
        ax.semilogy(f, np.full(f.size, c), "--", label="contact 1/K_H")
    ax.semilogy(f, np.abs(transfer.dynamic_compliance.data[k, k]), "k", lw=1.6, label="sum")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("|receptance| [m/N]")
    ax.set_title(f"Direct vertical receptances, side {side} (thesis Fig. 4.1)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    return fig


def plot_transfer(transfer, *, db: bool = False, ax=None, title: str | None = None):
    """Every term ``|T_ij|`` of a transfer function (thesis Figs. 4.2–4.4).

    Lines, in order: for each output (``irr_L``, ``irr_R``) each input channel,
    ``|T_ij|`` [m/(m/s²)] on a log axis, or ``20 log10 |T_ij|`` [dB re
    1 m/(m/s²)] with ``db=True``.

    Parameters
    ----------
    transfer : MeasurementTransfer
    db : bool
    ax : matplotlib Axes, optional
    title : str, optional

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig, ax = _axes(ax, figsize=(7, 4.5))
    T = transfer.transfer
    f = T.freqs_hz
    for i, out in enumerate(T.outputs):
        for j, inp in enumerate(T.inputs):
            mag = np.abs(T.data[i, j])
            label = f"{out} ← {inp}"
            if db:
                with np.errstate(divide="ignore"):
                    ax.plot(f, 20 * np.log10(mag), label=label)
            else:
                ax.semilogy(f, mag, label=label)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("|T| [dB re 1 m/(m/s²)]" if db else "|T| [m/(m/s²)]")
    ax.set_title(title or f"Transfer function: {_TITLES.get(transfer.model, transfer.model)}")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small")
    return fig


def plot_spectral_std(result, model: str | None = None, *, relative: bool = False, ax=None):
    """Spectral standard deviation of the reconstructed irregularity (thesis Figs. 4.5–4.7).

    Lines, in order per model kind: the standard deviation over the
    perturbed models of ``|n̂|`` for the left and the right side [m]
    (divided by the left input magnitude ``|n_L|`` with ``relative=True``),
    log axis.

    Parameters
    ----------
    result : RobustnessResult
    model : {"half", "vertical", "vertical_lateral"}, optional
        One kind (on ``ax``); default: one subplot per kind of ``result``.
    relative : bool
    ax : matplotlib Axes, optional
        Only with ``model``.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    kinds = result.models if model is None else (model,)
    for k in kinds:
        if k not in result.models:
            raise ValueError(f"model {k!r} was not studied; available: {list(result.models)}")
    if ax is not None and len(kinds) != 1:
        raise ValueError("give model= to draw one model kind on ax")
    if ax is None:
        fig, axes = plt.subplots(len(kinds), 1, sharex=True, figsize=(7, 2.8 * len(kinds)), squeeze=False)
        axes = list(axes[:, 0])
    else:
        fig, axes = ax.figure, [ax]
    f = result.freqs_hz
    ref = np.abs(result.irregularity[0])
    for a, k in zip(axes, kinds):
        _, std = result.spread(k)
        for s, side in enumerate(result.sides):
            y = std[s] / np.where(ref > 0, ref, np.nan) if relative else std[s]
            a.semilogy(f, y, label=f"side {side}")
        a.set_title(f"Spectral standard deviation: {_TITLES.get(k, k)}, {result.n_models} models "
                    f"±{100 * result.amplitude:g} %", fontsize="medium")
        a.set_ylabel("std |n̂| / |n_L|" if relative else "std |n̂| [m]")
        a.grid(True, which="both", alpha=0.3)
        a.legend(fontsize="small")
    axes[-1].set_xlabel("frequency [Hz]")
    return fig
