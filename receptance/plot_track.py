"""Plots of the track receptance (thesis Figs. 2.10, 2.11).  Imports matplotlib only when called."""

from __future__ import annotations

import numpy as np

from receptance.track import track_receptance
from receptance.trackform import Trackform

__all__ = ["plot_track_receptance"]


def plot_track_receptance(f_hz, trackform: Trackform = Trackform(), *, directions=("vertical", "lateral"),
                          supports=("continuous",), position: float = 0.5, ax=None):
    """Plot magnitude and phase of the rail point receptance.

    Parameters
    ----------
    f_hz : array_like
        Frequencies [Hz].
    trackform : Trackform
        Track data (default thesis Table 2.2).
    directions : sequence of {"vertical", "lateral"}
    supports : sequence of {"continuous", "discrete"}
        One curve per direction and support model.
    position : float
        Bay fraction for the discrete model (0.5 mid-span, 0 above a support).
    ax : sequence of two matplotlib Axes, optional
        ``(ax_magnitude, ax_phase)``; new figure if omitted.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    f = np.asarray(f_hz, dtype=float)
    if ax is None:
        fig, (ax_mag, ax_ph) = plt.subplots(2, 1, sharex=True, figsize=(7, 6))
    else:
        ax_mag, ax_ph = ax
        fig = ax_mag.figure
    for sup in supports:
        for d in directions:
            r = track_receptance(f, trackform, d, supports=sup, position=position)
            label = f"{d}, {sup}" + (f" (x={position:g} L_s)" if sup == "discrete" else "")
            ax_mag.semilogy(f, np.abs(r), label=label)
            ax_ph.plot(f, np.degrees(np.angle(r)), label=label)
    ax_mag.set_ylabel("|receptance| [m/N]")
    ax_ph.set_ylabel("phase [deg]")
    ax_ph.set_xlabel("frequency [Hz]")
    ax_mag.set_title("Rail point receptance (thesis §2.4)")
    ax_mag.legend()
    ax_mag.grid(True, which="both", alpha=0.3)
    ax_ph.grid(True, alpha=0.3)
    return fig
