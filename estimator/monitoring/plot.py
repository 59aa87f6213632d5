"""Figures of the monitoring (thesis Figs. 4.10–4.16 and more); each takes the data, ``ax=None``, returns the figure.

* :func:`plot_averaging` — single runs and their average (Fig. 4.10), with the trolley when given;
* :func:`plot_confidence` — day average with one source's interval (model: Figs. 4.11–4.13; placement: 4.15;
  scatter; combined);
* :func:`plot_placement` — one run with every shifted-sensor variant (Fig. 4.14);
* :func:`plot_evolution` — band peak-to-peak along chainage per survey day, days after a grinding dotted (Fig. 4.16);
* :func:`plot_map` — chainage × date map of a band's level;
* :func:`plot_trend` — a section's day values with intervals, the growth line, the threshold and the forecast;
* :func:`plot_reference` — train against trolley along chainage, per rail and band;
* :func:`plot_version_changes` — what a model change changed, per section and band.

matplotlib is imported when a function is called, never at package import.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from estimator.monitoring.trends import day_number

__all__ = ["plot_averaging", "plot_confidence", "plot_placement", "plot_evolution", "plot_map", "plot_trend",
           "plot_reference", "plot_version_changes"]


def _axes(ax, nrows=1, ncols=1, figsize=(10, 4), sharex=True):
    import matplotlib.pyplot as plt

    if ax is not None:
        axs = np.atleast_1d(ax)
        return axs.ravel()[0].figure, axs.ravel()
    fig, axs = plt.subplots(nrows, ncols, figsize=figsize, sharex=sharex, squeeze=False, constrained_layout=True)
    return fig, axs.ravel()


def _rails(df: pd.DataFrame) -> list[str]:
    return sorted(df["rail"].unique()) if len(df) else ["L", "R"]


def plot_averaging(windows: pd.DataFrame, day: pd.DataFrame, date: str, band: str, *, trolley: pd.DataFrame | None = None,
                   ax=None):
    """Each run's band peak-to-peak (wheelsets combined) and the day's energy average per rail (Fig. 4.10)."""
    from estimator.monitoring.averaging import run_values

    w = windows[(windows["date"] == date) & (windows["band_mm"] == band)]
    d = day[(day["date"] == date) & (day["band_mm"] == band)]
    rails = _rails(d)
    fig, axs = _axes(ax, len(rails), 1, (10, 3.2 * len(rails)))
    rv = run_values(w)
    for a, rail in zip(axs, rails):
        for run_id, g in rv[rv["rail"] == rail].groupby("run_id"):
            g = g.sort_values("window_m")
            a.plot(g["window_m"], g["pk_pk_um"], lw=0.6, alpha=0.6, label=None)
        dd = d[d["rail"] == rail].sort_values("window_m")
        a.plot(dd["window_m"], dd["pk_pk_um"], "k", lw=2, label=f"average of {int(dd['runs'].max()) if len(dd) else 0} runs")
        if trolley is not None and len(trolley):
            t = trolley[(trolley["rail"] == rail) & (trolley["band_mm"] == band)].sort_values("window_m")
            a.plot(t["window_m"], t["pk_pk_um"], "r--", lw=1.2, label="trolley")
        a.set_ylabel(f"rail {rail}: pk-pk [µm]")
        a.legend(loc="upper right", fontsize=8)
        a.grid(alpha=0.3)
    axs[-1].set_xlabel("chainage [m]")
    axs[0].set_title(f"{band} mm band, {date}: single runs (thin) and their energy average")
    return fig


def plot_confidence(day: pd.DataFrame, date: str, band: str, source: str = "combined", *, ax=None):
    """Day average with the ``source`` interval (``model``, ``placement``, ``scatter`` or ``combined``) per rail."""
    d = day[(day["date"] == date) & (day["band_mm"] == band)]
    rails = _rails(d)
    fig, axs = _axes(ax, len(rails), 1, (10, 3.2 * len(rails)))
    for a, rail in zip(axs, rails):
        g = d[d["rail"] == rail].sort_values("window_m")
        L = g["level_db"].to_numpy(float)
        if source == "combined":
            lo, hi = g["ci_lo_db"].to_numpy(float), g["ci_hi_db"].to_numpy(float)
        else:
            lo = L + g[f"{source}_lo_db"].to_numpy(float)
            hi = L + g[f"{source}_hi_db"].to_numpy(float)
        x = g["window_m"].to_numpy(float)
        a.plot(x, g["pk_pk_um"], "k", lw=1.5, label="day average")
        a.plot(x, 10 ** (lo / 20), "k:", lw=1, label=f"{source} interval")
        a.plot(x, 10 ** (hi / 20), "k:", lw=1)
        a.set_ylabel(f"rail {rail}: pk-pk [µm]")
        a.legend(loc="upper right", fontsize=8)
        a.grid(alpha=0.3)
    axs[-1].set_xlabel("chainage [m]")
    axs[0].set_title(f"{band} mm band, {date}: {source} confidence interval")
    return fig


def plot_placement(windows: pd.DataFrame, variants: pd.DataFrame, run_id: str, band: str, *, source="placement",
                   ax=None):
    """One run's band peak-to-peak with every variant of ``source`` (Fig. 4.14 for placement)."""
    w = windows[(windows["run_id"] == run_id) & (windows["band_mm"] == band)]
    v = variants[(variants["run_id"] == run_id) & (variants["band_mm"] == band) & (variants["source"] == source)]
    rails = _rails(w)
    fig, axs = _axes(ax, len(rails), 1, (10, 3.2 * len(rails)))
    lead = w["wheelset"].min() if len(w) else 1
    if "role" in w.columns and (w["role"] == "leading").any():
        lead = int(w.loc[w["role"] == "leading", "wheelset"].iloc[0])
    for a, rail in zip(axs, rails):
        for label, g in v[(v["rail"] == rail) & (v["wheelset"] == lead)].groupby("variant"):
            g = g.sort_values("window_m")
            a.plot(g["window_m"], g["pk_pk_um"], lw=0.7, alpha=0.8, label=label)
        g = w[(w["rail"] == rail) & (w["wheelset"] == lead)].sort_values("window_m")
        a.plot(g["window_m"], g["pk_pk_um"], "k", lw=1.8, label="nominal")
        a.set_ylabel(f"rail {rail}: pk-pk [µm]")
        a.legend(loc="upper right", fontsize=7, ncol=2)
        a.grid(alpha=0.3)
    axs[-1].set_xlabel("chainage [m]")
    axs[0].set_title(f"{band} mm band, run {run_id} (wheelset {lead}): {source} variants")
    return fig


def plot_evolution(day: pd.DataFrame, band: str, rail: str, *, grinding: pd.DataFrame | None = None,
                   span: tuple[float, float] | None = None, ax=None):
    """Band peak-to-peak along chainage for every survey day; days after a grinding dotted (Fig. 4.16)."""
    import matplotlib

    d = day[(day["band_mm"] == band) & (day["rail"] == rail)]
    if span is not None:
        d = d[(d["window_m"] >= span[0]) & (d["window_m"] <= span[1])]
    dates = sorted(d["date"].unique())
    fig, axs = _axes(ax, 1, 1, (10, 4))
    a = axs[0]
    cmap = matplotlib.colormaps["viridis"]
    first_after = set(grinding["date_after"]) if grinding is not None and len(grinding) else set()
    ground = False
    for i, date in enumerate(dates):
        g = d[d["date"] == date].sort_values("window_m")
        ground = ground or date in first_after
        a.plot(g["window_m"], g["pk_pk_um"], ":" if ground else "-", color=cmap(i / max(len(dates) - 1, 1)), lw=1.2,
               label=date + (" (after grinding)" if date in first_after else ""))
    a.set_xlabel("chainage [m]")
    a.set_ylabel("pk-pk [µm]")
    a.set_title(f"rail {rail}, {band} mm band: evolution over the survey days")
    a.legend(fontsize=7, ncol=2)
    a.grid(alpha=0.3)
    return fig


def plot_map(day: pd.DataFrame, band: str, rail: str, *, ax=None):
    """Chainage × date map of a band's level [dB re 1 µm]."""
    d = day[(day["band_mm"] == band) & (day["rail"] == rail)]
    fig, axs = _axes(ax, 1, 1, (10, 4))
    a = axs[0]
    if d.empty:
        return fig
    p = d.pivot_table(index="date", columns="window_m", values="level_db")
    x = p.columns.to_numpy(float)
    dx = np.median(np.diff(x)) if x.size > 1 else 1.0
    xe = np.concatenate([x, [x[-1] + dx]])
    n_days = len(p.index)
    # one row per survey day (days are unevenly spaced: rows, not a time axis, keep each visible)
    m = a.pcolormesh(xe, np.arange(n_days + 1), p.to_numpy(float), shading="flat", cmap="magma")
    a.set_yticks(np.arange(n_days) + 0.5)
    a.set_yticklabels(list(p.index), fontsize=7)
    a.set_xlabel("chainage [m]")
    a.set_title(f"rail {rail}, {band} mm band: level by chainage and survey day")
    fig.colorbar(m, ax=a, label="level [dB re 1 µm pk-pk]")
    return fig


def plot_trend(day_sections: pd.DataFrame, growth: pd.DataFrame, forecast: pd.DataFrame, section: str, rail: str,
               band: str, *, ax=None):
    """A section's daily values with their intervals, the growth line, the threshold and the forecast crossing."""
    d = day_sections[(day_sections["section"] == section) & (day_sections["rail"] == rail)
                     & (day_sections["band_mm"] == band)].sort_values("date")
    fig, axs = _axes(ax, 1, 1, (8, 4))
    a = axs[0]
    t = pd.to_datetime(d["date"])
    yerr = None
    if "pk_lo_um" in d:
        # a zero-width side (one run, no systematic source) may come out -1e-15 after the floor correction's
        # dB round trip; matplotlib refuses any negative error bar
        yerr = np.clip(np.vstack([d["pk_pk_um"] - d["pk_lo_um"], d["pk_hi_um"] - d["pk_pk_um"]]), 0.0, None)
    a.errorbar(t, d["pk_pk_um"], yerr=yerr, fmt="o", capsize=3, label="day average (combined interval)")
    g = growth[(growth["section"] == section) & (growth["rail"] == rail) & (growth["band_mm"] == band)]
    f = forecast[(forecast["section"] == section) & (forecast["rail"] == rail) & (forecast["band_mm"] == band)] \
        if len(forecast) else forecast
    if len(g) and np.isfinite(g["slope_um_per_day"].iloc[0]):
        r = g.iloc[0]
        end = r["t0_day"] + max(day_number([r["last_date"]])[0] - r["t0_day"], 1.0)
        if len(f) and np.isfinite(f["crossing_day"].iloc[0]):
            end = max(end, f["crossing_day"].iloc[0])
        tt = np.linspace(r["t0_day"], end, 50)
        a.plot(pd.to_datetime(tt, unit="D"), r["intercept_um"] + r["slope_um_per_day"] * (tt - r["t0_day"]), "b-",
               lw=1, label=f"growth {r['growth_um_per_month']:.2f} ± {r['growth_se_um_per_month']:.2f} µm/month")
    if len(f):
        T = f["threshold_um"].iloc[0]
        a.axhline(T, color="r", ls="--", lw=1, label=f"threshold {T:g} µm")
        if np.isfinite(f["crossing_day"].iloc[0]):
            c, sd = f["crossing_day"].iloc[0], f["crossing_sd_days"].iloc[0]
            a.axvspan(pd.to_datetime(c - 1.96 * sd, unit="D"), pd.to_datetime(c + 1.96 * sd, unit="D"), color="r",
                      alpha=0.12, label=f"forecast {f['crossing_date'].iloc[0]}")
    a.set_ylabel("pk-pk [µm]")
    a.set_title(f"section {section}, rail {rail}, {band} mm band")
    a.legend(fontsize=8)
    a.grid(alpha=0.3)
    fig.autofmt_xdate()
    return fig


def plot_reference(windows: pd.DataFrame, *, ax=None):
    """Train day average against the trolley along chainage, per band (rows) and rail (columns)."""
    bands = sorted(windows["band_mm"].unique(), key=lambda b: float(b.split("-")[0])) if len(windows) else []
    rails = _rails(windows)
    fig, axs = _axes(ax, max(len(bands), 1), len(rails), (11, 2.6 * max(len(bands), 1)))
    axs = np.asarray(axs).reshape(max(len(bands), 1), len(rails))
    for i, band in enumerate(bands):
        for j, rail in enumerate(rails):
            a = axs[i, j]
            g = windows[(windows["band_mm"] == band) & (windows["rail"] == rail)].sort_values("window_m")
            a.plot(g["window_m"], g["train_um"], "k", lw=1, label="train (day average)")
            a.plot(g["window_m"], g["trolley_um"], "r--", lw=1, label="trolley")
            a.set_title(f"rail {rail}, {band} mm", fontsize=9)
            a.grid(alpha=0.3)
            if j == 0:
                a.set_ylabel("pk-pk [µm]")
    axs[0, 0].legend(fontsize=8)
    for a in axs[-1]:
        a.set_xlabel("chainage [m]")
    return fig


def plot_version_changes(changes: pd.DataFrame, *, ax=None):
    """Mean level change per section and band between model versions (this version − the other)."""
    fig, axs = _axes(ax, 1, 1, (10, 4))
    a = axs[0]
    if changes.empty:
        return fig
    g = changes.groupby(["other_model", "section", "band_mm"])["change_db"].mean().reset_index()
    labels = [f"{s}\n{b}" for s, b in zip(g["section"], g["band_mm"])]
    a.bar(np.arange(len(g)), g["change_db"], color="tab:blue")
    a.set_xticks(np.arange(len(g)))
    a.set_xticklabels(labels, rotation=90, fontsize=7)
    a.axhline(0, color="k", lw=0.8)
    a.set_ylabel("change [dB]")
    a.set_title("what the model change changed (mean over days and rails)")
    a.grid(alpha=0.3, axis="y")
    return fig

