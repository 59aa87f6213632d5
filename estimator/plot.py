"""Figures of a field estimate (thesis Fig. 4.9 style); matplotlib is imported only when a figure is drawn.

* :func:`plot_band_pk_pk` — band peak-to-peak along chainage per rail, one
  line per transfer-function model, the reference (trolley) dashed;
* :func:`plot_spectra` — EN 15610 one-third-octave levels per rail with the
  ISO 3095 limit;
* :func:`plot_mask_map` — where and why the run was masked, per channel,
  along chainage;
* :func:`plot_wheel_orders` — wheel roughness per order with its floor.

Each takes the estimate (and ``ax=None``/``axes=None``) and returns the figure.
"""

from __future__ import annotations

import numpy as np

__all__ = ["plot_band_pk_pk", "plot_spectra", "plot_mask_map", "plot_wheel_orders", "MODEL_LABELS"]

MODEL_LABELS = {"half": "half wheelset (eq. 2.6)", "vertical": "full vertical (eq. 2.11)",
                "vertical_lateral": "vertical + lateral (eq. 2.22)"}
_COLOURS = {"half": "tab:orange", "vertical": "tab:blue", "vertical_lateral": "tab:green"}


def _fig(axes, nrows, ncols, figsize):
    import matplotlib.pyplot as plt

    if axes is None:
        fig, axes = plt.subplots(nrows, ncols, figsize=figsize, squeeze=False, sharex=True)
        return fig, axes
    axes = np.atleast_2d(axes)
    return axes.flat[0].figure, axes


def plot_band_pk_pk(estimate, band=(100.0, 300.0), *, span=None, wheelset=None, models=None, reference=None,
                    axes=None):
    """Band peak-to-peak [µm] along chainage, one panel per rail (thesis Fig. 4.9).

    Parameters
    ----------
    estimate : FieldEstimate
    band : (float, float)
        EN 13231-3 band [mm].
    span : (float, float), optional
        Chainage range [m] (default: the run).
    wheelset : int, optional
        Default: the leading wheelset.
    models : sequence of str, optional
    reference : ReferenceIndexes, optional
        Drawn dashed (trolley, or the truth).
    """
    w = estimate.leading if wheelset is None else wheelset
    models = models or [m for m in ("half", "vertical", "vertical_lateral") if (w, m) in estimate.profiles]
    fig, ax = _fig(axes, 2, 1, (10, 6))
    for r, rail in enumerate(("L", "R")):
        a = ax[r, 0]
        for m in models:
            p = estimate.profiles.get((w, m))
            if p is None or rail not in p.rails:
                continue
            x, pk = p.chainage_m, p.pk_pk(band, rail) * 1e6
            sel = slice(None) if span is None else slice(*np.searchsorted(x, span))
            a.plot(x[sel], pk[sel], color=_COLOURS.get(m), lw=1.0, label=MODEL_LABELS.get(m, m))
        if reference is not None and rail in reference.indexes:
            xr, pr = reference.pk_pk(band, rail)
            sel = slice(None) if span is None else slice(*np.searchsorted(xr, span))
            a.plot(xr[sel], pr[sel] * 1e6, "k--", lw=1.0, label="reference")
        a.set_ylabel(f"rail {rail}\npk-pk [µm]")
        a.grid(alpha=0.3)
        if span is not None:
            a.set_xlim(span)
        if not a.lines:  # a rail whose channels were all missing or masked: say so rather than leave it blank
            a.text(0.5, 0.5, f"no estimate of rail {rail} (its channels are missing or masked: see the QC log)",
                   transform=a.transAxes, ha="center", va="center", fontsize=9)
    from estimator.config import EN13231_WINDOWS_M

    win = EN13231_WINDOWS_M.get(tuple(band), float("nan"))
    ax[0, 0].set_title(f"{estimate.run_id}: EN 13231-3 peak-to-peak, {band[0]:g}–{band[1]:g} mm, {win:g} m window, "
                       f"wheelset {w} ({'leading' if w == estimate.leading else 'trailing'})")
    labelled = next((a for a in ax[:, 0] if a.lines), None)
    if labelled is not None:
        labelled.legend(fontsize=8, loc="upper right")
    ax[-1, 0].set_xlabel("chainage [m]")
    fig.tight_layout()
    return fig


def plot_spectra(estimate, stretch: str, *, wheelset=None, models=None, reference_levels=None, axes=None):
    """EN 15610 levels [dB re 1 µm] of one stretch per rail, with the ISO 3095 limit."""
    import matplotlib.pyplot as plt

    w = estimate.leading if wheelset is None else wheelset
    sp = estimate.spectra
    sp = sp[(sp["wheelset"] == w) & (sp["stretch"] == stretch)]
    models = models or list(dict.fromkeys(sp["model"]))
    if axes is None:
        fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), squeeze=False, sharey=True)
    else:
        axes = np.atleast_2d(axes)
        fig = axes.flat[0].figure
    for r, rail in enumerate(("L", "R")):
        a = axes[0, r]
        lim = None
        for m in models:
            g = sp[(sp["model"] == m) & (sp["rail"] == rail)].sort_values("wavelength_m", ascending=False)
            if g.empty:
                continue
            a.plot(g["wavelength_m"] * 1e3, g["level_db"], "o-", ms=3, color=_COLOURS.get(m),
                   label=MODEL_LABELS.get(m, m))
            lim = g
        # a reference none of whose rails could be compared gives an empty table without columns: no curve
        if reference_levels is not None and not reference_levels.empty and {"rail", "wavelength_m",
                                                                             "ref_db"} <= set(reference_levels):
            g = reference_levels[(reference_levels["rail"] == rail)]
            if not g.empty:
                g = g.drop_duplicates("wavelength_m").sort_values("wavelength_m", ascending=False)
                a.plot(g["wavelength_m"] * 1e3, g["ref_db"], "k--", label="reference")
        if lim is not None:
            a.plot(lim["wavelength_m"] * 1e3, lim["iso3095_limit_db"], color="firebrick", lw=2, alpha=0.6,
                   label="ISO 3095 limit")
        a.set_xscale("log")
        a.invert_xaxis()
        a.set_xlabel("wavelength [mm]")
        a.set_title(f"rail {rail}")
        a.grid(alpha=0.3, which="both")
    axes[0, 0].set_ylabel("L_r [dB re 1 µm]")
    axes[0, 0].legend(fontsize=8)
    fig.suptitle(f"{estimate.run_id}: EN 15610 roughness level, {stretch}, wheelset {w}")
    fig.tight_layout()
    return fig


_KIND_COLOURS = {"dropout_nan": "tab:red", "dropout_flat": "tab:purple", "clipping": "tab:orange", "glitch": "gold",
                 "low_speed": "tab:gray", "standstill": "black", "reversing": "tab:brown",
                 "odometry_jump": "tab:pink", "contact_loss": "tab:olive"}


def plot_mask_map(estimate, ax=None):
    """Masked spans along chainage per channel (``*`` = every channel), coloured by reason; flagged spans (the wheel
    off the rail, :mod:`estimator.contact_load`) hatched: estimated there, but not the rail's."""
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    qc = estimate.qc
    qc = qc[qc["action"].isin(["masked", "flagged"])] if not qc.empty else qc
    chans = sorted(set(qc["channel"])) if not qc.empty else []
    if ax is None:
        fig, ax = plt.subplots(figsize=(10, 1.2 + 0.35 * max(len(chans), 1)))
    else:
        fig = ax.figure
    for i, ch in enumerate(chans):
        for r in qc[qc["channel"] == ch].itertuples():
            lo, hi = r.chainage_from_m, r.chainage_to_m
            if not np.isfinite(lo):
                continue
            ax.barh(i, max(hi - lo, 0.3), left=lo, height=0.6, color=_KIND_COLOURS.get(r.kind, "tab:blue"),
                    hatch="//" if r.action == "flagged" else None)
    ax.set_yticks(range(len(chans)))
    ax.set_yticklabels(chans)
    xs = [p.chainage_m for p in estimate.profiles.values()]
    if xs:
        ax.set_xlim(min(x[0] for x in xs), max(x[-1] for x in xs))
    kinds = sorted(set(qc["kind"])) if not qc.empty else []
    if kinds:
        ax.legend(handles=[Patch(color=_KIND_COLOURS.get(k, "tab:blue"), label=k) for k in kinds], fontsize=8,
                  loc="upper right")
    else:
        ax.text(0.5, 0.5, "nothing masked or flagged", transform=ax.transAxes, ha="center", va="center",
                color="0.4")
    share = 100 * estimate.masked_share.get("run", 0.0)
    ax.set_title(f"{estimate.run_id}: masked spans (run masked share {share:.1f} %)")
    ax.set_xlabel("chainage [m]")
    fig.tight_layout()
    return fig


def plot_wheel_orders(estimate, *, model="vertical_lateral", max_order=60, axes=None):
    """Wheel roughness amplitude per order [µm] for each wheel, with the rail's floor (dotted)."""
    import matplotlib.pyplot as plt

    ws = estimate.wheelsets
    if axes is None:
        fig, axes = plt.subplots(len(ws), 1, figsize=(10, 2.6 * len(ws)), squeeze=False)
    else:
        axes = np.atleast_2d(axes)
        fig = axes.flat[0].figure
    for i, w in enumerate(ws):
        p = estimate.profiles.get((w, model)) or next(v for (ww, _), v in estimate.profiles.items() if ww == w)
        o = p.wheel.orders
        a = axes[i, 0]
        for k, side in enumerate(p.wheel.sides):
            g = o[(o["side"] == side) & (o["order"] <= max_order)]
            a.bar(g["order"] + (k - 0.5) * 0.4, g["amplitude_m"] * 1e6, width=0.4, label=f"wheel {side}")
            a.plot(g["order"], 4 * g["floor_m"] * 1e6, ":", color="k" if k == 0 else "gray")
        a.set_ylabel(f"wheelset {w}\namplitude [µm]")
        a.legend(fontsize=8)
        a.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("order (per revolution); dotted: 4 × floor")
    fig.suptitle(f"{estimate.run_id}: wheel roughness by order (synchronous average)")
    fig.tight_layout()
    return fig
