"""Grinding detection: a sudden fall of the band levels, located in chainage and dated between two survey days.

Between two consecutive survey days ``d₀ < d₁`` and in every chainage window,
the change of each band's day level ``ΔL = L(d₁) − L(d₀)`` (the two rails
energy-averaged: a grinding train treats both rails) is smoothed along
chainage with a running median over ``SMOOTH_WINDOWS`` windows (one window's
noise does not make a grinding). A window *dropped* when ``ΔL <
−grinding_drop_db`` in at least ``grinding_min_bands`` of the
``grinding_bands_mm`` bands present there (the 10–30 mm band is left out by
default: grinding leaves its own facet signature there). Contiguous dropped
windows (gaps of up to ``GAP_WINDOWS`` bridged) at least
``grinding_min_length_m`` long are a grinding event: ``from_m, to_m``, the two
days, the mean drop per band. Roughness only grows between grindings on a
line in service (corrugation growth, wear), so nothing else gives such a
fall; a fall shorter than the minimum length (a repaired weld, a replaced
rail) is reported as such, not as a grinding.

:func:`grinding_effect` checks what a grinding achieved: per event, rail and
band, the level before and after over the event's extent against the band's
threshold — "removed" when the after level is below the threshold.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from estimator.monitoring.averaging import energy_mean_db
from estimator.monitoring.config import MonitoringConfig, band_label

__all__ = ["level_changes", "detect_grinding", "grinding_effect", "SMOOTH_WINDOWS", "GAP_WINDOWS"]

SMOOTH_WINDOWS = 5
GAP_WINDOWS = 5


def _rails_energy(day: pd.DataFrame) -> pd.DataFrame:
    """Per date, band and window: the rails' energy-mean level."""
    e = day.assign(_e=10 ** (day["level_db"] / 10))
    g = e.groupby(["date", "band_mm", "window_m"])["_e"].mean()
    return (10 * np.log10(g)).rename("level_db").reset_index()


def level_changes(day_windows: pd.DataFrame, cfg: MonitoringConfig = MonitoringConfig()) -> pd.DataFrame:
    """``ΔL`` per consecutive pair of survey days, band and window (smoothed), and the per-window drop flag."""
    bands = [band_label(b) for b in cfg.grinding_bands_mm]
    d = _rails_energy(day_windows[day_windows["band_mm"].isin(bands)])
    dates = sorted(d["date"].unique())
    rows = []
    for d0, d1 in zip(dates[:-1], dates[1:]):
        a = d[d["date"] == d0].set_index(["band_mm", "window_m"])["level_db"]
        b = d[d["date"] == d1].set_index(["band_mm", "window_m"])["level_db"]
        delta = (b - a).dropna().rename("delta_db").reset_index()
        for band, g in delta.groupby("band_mm"):
            g = g.sort_values("window_m")
            sm = g["delta_db"].rolling(SMOOTH_WINDOWS, center=True, min_periods=1).median()
            rows.append(g.assign(delta_smooth_db=sm.to_numpy(), date_before=d0, date_after=d1))
    if not rows:
        return pd.DataFrame(columns=["date_before", "date_after", "band_mm", "window_m", "delta_db", "delta_smooth_db"])
    return pd.concat(rows, ignore_index=True)


def detect_grinding(day_windows: pd.DataFrame, cfg: MonitoringConfig = MonitoringConfig()
                    ) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Grinding events (module docstring) and the short falls that were not counted as grindings.

    Parameters
    ----------
    day_windows : pandas.DataFrame
        Day averages per window (``date, rail, band_mm, window_m, level_db``), one model version.

    Returns
    -------
    events, short_falls : pandas.DataFrame
        ``date_before, date_after, from_m, to_m, length_m, windows`` and ``drop_db_<band>`` per band.
    """
    ch = level_changes(day_windows, cfg)
    cols = ["date_before", "date_after", "from_m", "to_m", "length_m", "windows"]
    if ch.empty:
        return pd.DataFrame(columns=cols), pd.DataFrame(columns=cols)
    ch["dropped"] = ch["delta_smooth_db"] < -cfg.grinding_drop_db
    per = ch.groupby(["date_before", "date_after", "window_m"]).agg(n_drop=("dropped", "sum"),
                                                                    n_band=("dropped", "size")).reset_index()
    per["flag"] = (per["n_band"] >= cfg.grinding_min_bands) & (per["n_drop"] >= cfg.grinding_min_bands)
    W = cfg.window_m
    events, short = [], []
    for (d0, d1), g in per[per["flag"]].groupby(["date_before", "date_after"]):
        x = np.sort(g["window_m"].to_numpy(float))
        brk = np.flatnonzero(np.diff(x) > (GAP_WINDOWS + 1) * W * (1 + 1e-9)) + 1
        for part in np.split(x, brk):
            a, b = float(part[0]), float(part[-1] + W)
            row = {"date_before": d0, "date_after": d1, "from_m": a, "to_m": b, "length_m": b - a,
                   "windows": int(part.size)}
            sel = (ch["date_before"] == d0) & (ch["window_m"] >= a) & (ch["window_m"] < b)
            for band, gb in ch[sel].groupby("band_mm"):
                row[f"drop_db_{band}"] = float(gb["delta_db"].mean())
            (events if b - a >= cfg.grinding_min_length_m else short).append(row)
    return (pd.DataFrame(events) if events else pd.DataFrame(columns=cols),
            pd.DataFrame(short) if short else pd.DataFrame(columns=cols))


def grinding_effect(events: pd.DataFrame, day_windows: pd.DataFrame, thresholds_um: dict) -> pd.DataFrame:
    """Per event, rail and band: the level before and after over the event's extent and whether it is now below
    the band's threshold (``removed``)."""
    rows = []
    for _, ev in events.iterrows():
        sel = (day_windows["window_m"] >= ev["from_m"]) & (day_windows["window_m"] < ev["to_m"])
        for (rail, band), g in day_windows[sel].groupby(["rail", "band_mm"]):
            before = energy_mean_db(g.loc[g["date"] == ev["date_before"], "level_db"])
            after = energy_mean_db(g.loc[g["date"] == ev["date_after"], "level_db"])
            th = thresholds_um.get(band, np.nan)
            th_db = 20 * np.log10(th) if th and np.isfinite(th) else np.nan
            rows.append({"date_before": ev["date_before"], "date_after": ev["date_after"], "from_m": ev["from_m"],
                         "to_m": ev["to_m"], "rail": rail, "band_mm": band,
                         "before_pk_pk_um": 10 ** (before / 20), "after_pk_pk_um": 10 ** (after / 20),
                         "change_db": after - before, "threshold_um": th,
                         "removed": bool(after < th_db) if np.isfinite(th_db) and np.isfinite(after) else None})
    return pd.DataFrame(rows)
