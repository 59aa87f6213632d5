"""Estimates that depart from the rest of their day beyond the day's scatter: kept in the store, not averaged in.

A day's runs measure the same rails: per section, rail and band every run's
wheelset gives one estimate of the same level. A run with a fault the
single-run QC did not contain (a clipped channel whose distortion the
inversion smears beyond the masked samples, a sensor working loose) gives a
level far from the others' on the rail its faulty channel sees, and the energy
average — dominated by its largest member — would follow it.

The criterion is the consistency checks' (:mod:`~estimator.monitoring.consistency`),
on the **same chainage**: for each 1 m window an estimate covers, its level
``L_i(x)`` (dB re 1 µm) against the median of the **other** estimates of the
day, section, rail and band at that window, ``M_i(x) = med_{j≠i} L_j(x)``;
the estimate's departure is the difference of their energy means over the
windows it shares with at least :data:`MIN_OTHERS` others, ``D_i = Ē[L_i] −
Ē[M_i]`` — energy means, because the day's energy average is what a faulty
estimate would pull (a run that covers a part of the section only — a
stretch masked by QC — is judged on that part, not on a section level of
other chainage). It is an outlier when ``|D_i| >
max(consistency_min_db, consistency_z · s_i)`` with ``s_i = 1.4826 ·
MAD_{j≠i} D_j`` (the robust scatter of the others' departures; leave-one-out
so the outlier does not widen its own limit), given at least :data:`MIN_OTHERS`
other estimates and :data:`MIN_WINDOWS` shared windows. An outlier's windows
stay in the store (``windows`` table); the day averages leave them out and
:func:`outlying_estimates`' table says which and why (``level_db`` its energy
mean over the judged windows, ``others_median_db`` the others' median's).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from estimator.monitoring.averaging import MIN_VALID_SHARE, energy_mean_db, level_db
from estimator.monitoring.config import MonitoringConfig

__all__ = ["MIN_OTHERS", "MIN_WINDOWS", "OUTLIER_KEYS", "outlying_estimates", "without_outliers"]

#: other estimates (run-wheelsets) needed to call one estimate an outlier
MIN_OTHERS = 3
#: windows an estimate must share with at least MIN_OTHERS others to be judged
MIN_WINDOWS = 5
#: what identifies one estimate in a section
OUTLIER_KEYS = ["date", "section", "run_id", "wheelset", "rail", "band_mm"]
_COLUMNS = OUTLIER_KEYS + ["level_db", "others_median_db", "deviation_db", "limit_db", "others"]


def outlying_estimates(windows: pd.DataFrame, cfg: MonitoringConfig = MonitoringConfig()) -> pd.DataFrame:
    """The run-wheelset estimates of a section that depart from the day's others (module docstring).

    Parameters
    ----------
    windows : pandas.DataFrame
        The store's ``windows`` rows (``date, section, run_id, wheelset, rail, band_mm, window_m, pk_pk_um,
        valid_share``).

    Returns
    -------
    pandas.DataFrame
        ``date, section, run_id, wheelset, rail, band_mm, level_db, others_median_db, deviation_db, limit_db,
        others`` — one row per outlier.
    """
    if windows.empty or not set(OUTLIER_KEYS + ["window_m"]) <= set(windows.columns):
        return pd.DataFrame(columns=_COLUMNS)
    w = windows[windows["valid_share"] >= MIN_VALID_SHARE]
    est_keys = ["run_id", "wheelset"]
    rows = []
    for key, g in w.groupby(["date", "section", "rail", "band_mm"], sort=True):
        # estimates x windows, level in dB (NaN where an estimate has no valid window)
        L = g.assign(_L=level_db(g["pk_pk_um"])).pivot_table(index=est_keys, columns="window_m", values="_L",
                                                              aggfunc="mean")
        if L.shape[0] < MIN_OTHERS + 1:
            continue
        V = L.to_numpy(float)
        dep = np.full(V.shape[0], np.nan)
        judged: list[np.ndarray] = []
        for i in range(V.shape[0]):
            others = np.delete(V, i, axis=0)
            enough = np.isfinite(others).sum(axis=0) >= MIN_OTHERS
            med = np.full(V.shape[1], np.nan)
            if enough.any():
                med[enough] = np.nanmedian(others[:, enough], axis=0)
            ok = np.isfinite(V[i]) & np.isfinite(med)
            judged.append(ok)
            if ok.sum() >= MIN_WINDOWS:
                # energy means on the shared windows: what the day's energy average would take in from it
                dep[i] = energy_mean_db(V[i, ok]) - energy_mean_db(med[ok])
        for i in range(V.shape[0]):
            if not np.isfinite(dep[i]):
                continue
            others = np.delete(dep, i)
            others = others[np.isfinite(others)]
            if others.size < MIN_OTHERS:
                continue
            s = 1.4826 * float(np.median(np.abs(others - np.median(others))))
            lim = max(cfg.consistency_min_db, cfg.consistency_z * s)
            if abs(dep[i]) > lim:
                level = energy_mean_db(V[i, judged[i]])
                rows.append({**dict(zip(("date", "section", "rail", "band_mm"), key)),
                             **dict(zip(est_keys, L.index[i])), "level_db": level,
                             "others_median_db": level - float(dep[i]), "deviation_db": float(dep[i]),
                             "limit_db": lim, "others": int(others.size)})
    return pd.DataFrame(rows, columns=_COLUMNS)


def without_outliers(rows: pd.DataFrame, outliers: pd.DataFrame) -> pd.DataFrame:
    """``rows`` (windows or variants) without those of the outlying estimates."""
    if outliers.empty or rows.empty:
        return rows
    keys = [k for k in OUTLIER_KEYS if k in rows.columns]
    bad = outliers[keys].drop_duplicates().assign(_out=True)
    j = rows.merge(bad, on=keys, how="left")
    return rows[~j["_out"].fillna(False).astype(bool).to_numpy()]
