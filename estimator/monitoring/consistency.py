"""Consistency checks no single run gives: leading vs trailing wheelset, the two directions, left–right cross-talk.

Each check compares two estimates of the same rail on the same day and flags
the chainage windows where they disagree **beyond their scatter**:

* **leading vs trailing**: per run, ``D = L_leading − L_trailing`` (same rail,
  band, window; the two wheelsets of one passage); over the day's runs its
  mean ``D̄`` and standard error ``s/√n``;
* **directions**: the day's energy averages of the forward and of the
  backward runs (:func:`~estimator.monitoring.averaging.day_average` with
  ``by=("date", "direction")``), ``D = L_forward − L_backward`` with standard
  error ``sqrt(se_f² + se_b²)``;
* **cross-talk**: the two rails' band-filtered estimates are independent
  roughness (two rails, one wheel each); the zero-lag correlation of the
  left and right estimates over a window (``lr_correlation`` of the
  ``windows`` table) near ±1 means one rail's irregularity leaks into the
  other's estimate (the coupling the thesis saw with the full vertical model).
  Its day mean over runs is flagged above ``crosstalk_coherence``, with the
  level difference between the rails (the leak's attenuation).

A window is flagged when ``|D̄| > max(consistency_min_db, consistency_z · se)``
(at least two runs on each side); contiguous flagged windows (gaps of one
window bridged) become one finding with its chainage extent — *where* the
disagreement sits.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from estimator.monitoring.averaging import MIN_VALID_SHARE, day_average, level_db
from estimator.monitoring.config import MonitoringConfig

__all__ = ["leading_vs_trailing", "directions", "crosstalk", "stretches", "consistency_checks", "FLAG_COLUMNS"]

FLAG_COLUMNS = ["check", "date", "rail", "band_mm", "from_m", "to_m", "windows", "value", "se", "unit_of_value",
                "detail"]


def stretches(flags: pd.DataFrame, window_m: float, keys: list[str], value: str, se: str | None = None,
              gap_windows: int = 1) -> pd.DataFrame:
    """Contiguous flagged windows (``flag`` column) grouped into stretches per ``keys``, with mean values."""
    rows = []
    f = flags[flags["flag"]]
    for key, g in f.groupby(keys, sort=True):
        g = g.sort_values("window_m")
        x = g["window_m"].to_numpy(float)
        brk = np.flatnonzero(np.diff(x) > (gap_windows + 1) * window_m * (1 + 1e-9)) + 1
        for part in np.split(np.arange(x.size), brk):
            sub = g.iloc[part]
            rows.append({**dict(zip(keys, key if isinstance(key, tuple) else (key,))),
                         "from_m": float(sub["window_m"].min()), "to_m": float(sub["window_m"].max() + window_m),
                         "windows": int(len(sub)), "value": float(sub[value].mean()),
                         "se": float(sub[se].mean()) if se else np.nan})
    return pd.DataFrame(rows)


def _flag(d: pd.DataFrame, n_min_ok: np.ndarray, cfg: MonitoringConfig) -> np.ndarray:
    lim = np.maximum(cfg.consistency_min_db, cfg.consistency_z * np.nan_to_num(d["se"].to_numpy(float), nan=np.inf))
    return n_min_ok & (np.abs(d["diff_db"].to_numpy(float)) > lim)


def leading_vs_trailing(windows: pd.DataFrame, cfg: MonitoringConfig = MonitoringConfig()) -> pd.DataFrame:
    """Per day, rail, band and window: mean leading − trailing difference [dB], its standard error, the flag."""
    w = windows[windows["valid_share"] >= MIN_VALID_SHARE]
    keys = ["date", "run_id", "rail", "band_mm", "window_m"]
    p = w.pivot_table(index=keys, columns="role", values="pk_pk_um", aggfunc="first")
    if "leading" not in p.columns or "trailing" not in p.columns:
        return pd.DataFrame(columns=["date", "rail", "band_mm", "window_m", "diff_db", "se", "runs", "flag"])
    d = (level_db(p["leading"]) - level_db(p["trailing"])).rename("D").dropna().reset_index()
    g = d.groupby(["date", "rail", "band_mm", "window_m"])["D"]
    out = pd.DataFrame({"diff_db": g.mean(), "sd": g.std(ddof=1), "runs": g.size()}).reset_index()
    out["se"] = out["sd"] / np.sqrt(out["runs"])
    out["flag"] = _flag(out, out["runs"].to_numpy() >= 2, cfg)
    return out.drop(columns=["sd"])


def directions(windows: pd.DataFrame, masked_share=None, cfg: MonitoringConfig = MonitoringConfig()) -> pd.DataFrame:
    """Per day, rail, band and window: forward − backward difference of the energy averages [dB] and the flag."""
    cols = ["date", "rail", "band_mm", "window_m", "diff_db", "se", "runs", "flag"]
    if "direction" not in windows.columns or windows["direction"].nunique() < 2:
        return pd.DataFrame(columns=cols)
    da = day_average(windows, masked_share, by=("date", "direction"))
    keys = ["date", "rail", "band_mm", "window_m"]
    f = da[da["direction"] == "forward"].set_index(keys)
    b = da[da["direction"] == "backward"].set_index(keys)
    j = f[["level_db", "se_db", "runs"]].join(b[["level_db", "se_db", "runs"]], how="inner", suffixes=("_f", "_b"))
    out = pd.DataFrame({"diff_db": j["level_db_f"] - j["level_db_b"],
                        "se": np.sqrt(j["se_db_f"] ** 2 + j["se_db_b"] ** 2),
                        "runs": j["runs_f"] + j["runs_b"]}).reset_index()
    ok = (j["runs_f"].to_numpy() >= 2) & (j["runs_b"].to_numpy() >= 2)
    out["flag"] = _flag(out, ok, cfg)
    return out[cols]


def crosstalk(windows: pd.DataFrame, cfg: MonitoringConfig = MonitoringConfig()) -> pd.DataFrame:
    """Per day, band and window: mean left–right correlation over the runs, the rails' level difference, the flag."""
    cols = ["date", "band_mm", "window_m", "correlation", "rail_difference_db", "runs", "flag"]
    if "lr_correlation" not in windows.columns:
        return pd.DataFrame(columns=cols)
    w = windows[(windows["valid_share"] >= MIN_VALID_SHARE) & windows["lr_correlation"].notna()]
    keys = ["date", "band_mm", "window_m"]
    rho = w[w["rail"] == w["rail"].min()].groupby(keys)["lr_correlation"]
    lv = w.pivot_table(index=keys + ["run_id", "wheelset"], columns="rail", values="pk_pk_um", aggfunc="first")
    out = pd.DataFrame({"correlation": rho.mean(), "runs": rho.size()})
    if {"L", "R"} <= set(lv.columns):
        diff = (level_db(lv["L"]) - level_db(lv["R"])).groupby(level=keys).mean()
        out = out.join(diff.rename("rail_difference_db"))
    else:
        out["rail_difference_db"] = np.nan
    out = out.reset_index()
    out["flag"] = np.abs(out["correlation"].to_numpy(float)) > cfg.crosstalk_coherence
    return out[cols]


def consistency_checks(windows: pd.DataFrame, masked_share=None, cfg: MonitoringConfig = MonitoringConfig()
                       ) -> tuple[pd.DataFrame, dict[str, pd.DataFrame]]:
    """All three checks: the findings (one row per flagged stretch, :data:`FLAG_COLUMNS`) and each check's windows."""
    lt = leading_vs_trailing(windows, cfg)
    dr = directions(windows, masked_share, cfg)
    ct = crosstalk(windows, cfg)
    found = []
    for name, tab, keys, val, se, unit, text in (
            ("leading_vs_trailing", lt, ["date", "rail", "band_mm"], "diff_db", "se", "dB",
             "leading wheelset's estimate differs from the trailing one's beyond their scatter"),
            ("directions", dr, ["date", "rail", "band_mm"], "diff_db", "se", "dB",
             "forward runs' average differs from the backward runs' beyond their scatter"),
            ("crosstalk", ct, ["date", "band_mm"], "correlation", None, "correlation",
             f"left and right estimates correlate above {cfg.crosstalk_coherence:g}: one rail leaks into the other")):
        if tab.empty or not tab["flag"].any():
            continue
        st = stretches(tab, cfg.window_m, keys, val, se)
        st["check"] = name
        st["unit_of_value"] = unit
        st["detail"] = text
        if "rail" not in st.columns:
            st["rail"] = "L+R"
        found.append(st)
    flags = pd.concat(found, ignore_index=True)[FLAG_COLUMNS] if found else pd.DataFrame(columns=FLAG_COLUMNS)
    return flags, {"leading_vs_trailing": lt, "directions": dr, "crosstalk": ct}
