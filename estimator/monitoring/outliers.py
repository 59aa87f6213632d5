"""Estimates that depart from the rest of their day beyond the day's scatter: kept in the store, not averaged in.

A day's runs measure the same rails: per section, rail and band every run's
wheelset gives one estimate of the same level. A run with a fault the
single-run QC did not contain (a clipped channel whose distortion the
inversion smears beyond the masked samples, a sensor working loose) gives a
level far from the others' on the rail its faulty channel sees, and the energy
average — dominated by its largest member — would follow it.

The criterion is the consistency checks' (:mod:`~estimator.monitoring.consistency`):
each estimate's section level ``L_i`` (energy mean of its windows,
:func:`~estimator.monitoring.averaging.section_table`) against the median of
the **other** estimates of the day, section, rail and band, ``D_i = L_i −
med_{j≠i} L_j``, is an outlier when ``|D_i| > max(consistency_min_db,
consistency_z · s_i)`` with ``s_i = 1.4826 · MAD_{j≠i}`` (the robust standard
deviation of the others; leave-one-out so the outlier does not widen its own
limit), given at least :data:`MIN_OTHERS` other estimates. An outlier's windows
stay in the store (``windows`` table); the day averages leave them out and
:func:`outlying_estimates`' table says which and why.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from estimator.monitoring.averaging import level_db, section_table
from estimator.monitoring.config import MonitoringConfig

__all__ = ["MIN_OTHERS", "OUTLIER_KEYS", "outlying_estimates", "without_outliers"]

#: other estimates (run-wheelsets) needed to call one estimate an outlier
MIN_OTHERS = 3
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
    if windows.empty or not set(OUTLIER_KEYS) <= set(windows.columns):
        return pd.DataFrame(columns=_COLUMNS)
    st = section_table(windows)
    if st.empty:
        return pd.DataFrame(columns=_COLUMNS)
    st = st.assign(level_db=level_db(st["pk_pk_um"]))
    rows = []
    for key, g in st.groupby(["date", "section", "rail", "band_mm"], sort=True):
        L = g["level_db"].to_numpy(float)
        if L.size < MIN_OTHERS + 1:
            continue
        for i in range(L.size):
            others = np.delete(L, i)
            med = float(np.median(others))
            s = 1.4826 * float(np.median(np.abs(others - med)))
            lim = max(cfg.consistency_min_db, cfg.consistency_z * s)
            if abs(L[i] - med) > lim:
                r = g.iloc[i]
                rows.append({**{k: r[k] for k in OUTLIER_KEYS}, "level_db": float(L[i]), "others_median_db": med,
                             "deviation_db": float(L[i] - med), "limit_db": lim, "others": int(others.size)})
    return pd.DataFrame(rows, columns=_COLUMNS)


def without_outliers(rows: pd.DataFrame, outliers: pd.DataFrame) -> pd.DataFrame:
    """``rows`` (windows or variants) without those of the outlying estimates."""
    if outliers.empty or rows.empty:
        return rows
    keys = [k for k in OUTLIER_KEYS if k in rows.columns]
    bad = outliers[keys].drop_duplicates().assign(_out=True)
    j = rows.merge(bad, on=keys, how="left")
    return rows[~j["_out"].fillna(False).astype(bool).to_numpy()]
