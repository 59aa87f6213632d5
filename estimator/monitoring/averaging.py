"""Averaging aligned runs per day and rail: energy averages weighted by each run's quality (thesis §4.3.3).

**Energy averaging.** Band indexes are averaged as energies, never as
amplitudes or decibels: the average peak-to-peak of ``n`` estimates is
``sqrt(Σ q_i pk_i² / Σ q_i)`` — the moving RMS of eq. 4.1 is the square root
of a mean square, and mean squares add — and the average one-third-octave
level is ``10 lg(Σ q_i 10^{L_i/10} / Σ q_i)``. (A dB average would be the
geometric mean, biased low by about ``σ²·ln10/20`` dB for a scatter ``σ``.)

**Units.** A *unit* is a chainage window (``window_m`` column) or a line
section (``section``): :func:`section_table` turns a run's windows into one
value per section (energy mean over the section's windows, weighted by their
valid share) so sections are averaged and given intervals exactly like
windows.

**Per run first.** A run's two wheelsets are two estimates of the same rails
at the same passage (same speed, same track dynamics): they are first
combined (energy mean weighted by valid share) into one value per run, so
that the run-to-run scatter and its degrees of freedom count runs, not
wheelsets.

**Quality weights.** Run ``i``'s weight in a unit is
``q_i = (1 − m_i) · min(1, (v_i / v̄)²)``: ``m_i`` its masked share (a run
with dropouts, clipping or odometry faults is trusted less everywhere), ``v_i``
its mean speed over the unit and ``v̄`` the median speed of the day's runs
there — an axlebox acceleration grows as ``(2π v/λ)²`` for the same
roughness while the sensor noise does not, so a pass well below the usual
speed has a lower signal-to-noise ratio. Window values with less than
:data:`MIN_VALID_SHARE` valid samples are left out.

**Scatter.** With levels ``L_i = 20 lg(pk_i / 1 µm)`` the weighted standard
deviation ``s`` (reliability weights), the effective number of runs
``n_eff = (Σ q)² / Σ q²`` and the standard error ``s / √n_eff`` give the
run-to-run half-width ``t_{(1+c)/2, n_eff−1} · s / √n_eff`` dB
(:mod:`estimator.monitoring.confidence`).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

__all__ = ["MIN_VALID_SHARE", "section_table", "run_values", "day_average", "energy_mean_db", "level_db"]

#: window values with a smaller share of valid samples are not averaged
MIN_VALID_SHARE = 0.5
#: reference of the levels (EN 15610: 1 µm)
R0_UM = 1.0


def level_db(pk_um):
    """``20 lg(pk / 1 µm)`` (a pandas Series stays one, with its index)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        if isinstance(pk_um, pd.Series):
            return 20 * np.log10(pk_um.astype(float) / R0_UM)
        return 20 * np.log10(np.asarray(pk_um, float) / R0_UM)


def energy_mean_db(levels_db, weights=None) -> float:
    """``10 lg(Σ w 10^{L/10} / Σ w)`` (NaN levels ignored)."""
    L = np.asarray(levels_db, float)
    w = np.ones_like(L) if weights is None else np.asarray(weights, float)
    ok = np.isfinite(L) & (w > 0)
    if not ok.any():
        return float("nan")
    return float(10 * np.log10(np.sum(w[ok] * 10 ** (L[ok] / 10)) / np.sum(w[ok])))


def section_table(windows: pd.DataFrame) -> pd.DataFrame:
    """A run's windows reduced to one value per section (energy mean weighted by valid share)."""
    w = windows[windows["valid_share"] >= MIN_VALID_SHARE]
    if w.empty:
        return w.iloc[:0].copy()
    keys = [c for c in ("date", "run_id", "direction", "wheelset", "role", "rail", "band_mm", "section", "source",
                        "variant") if c in w.columns]
    speed = w["speed_m_s"] if "speed_m_s" in w.columns else pd.Series(np.nan, index=w.index)
    e = w.assign(_e=w["valid_share"] * w["pk_pk_um"] ** 2, _v=w["valid_share"], _n=1, _s=speed * w["valid_share"])
    g = e.groupby(keys, sort=True, dropna=False)
    out = g[["_e", "_v", "_n", "_s"]].sum().reset_index()
    out["pk_pk_um"] = np.sqrt(out["_e"] / out["_v"])
    out["speed_m_s"] = out["_s"] / out["_v"]
    out["valid_share"] = out["_v"] / out["_n"]
    out["windows"] = out["_n"]
    return out.drop(columns=["_e", "_v", "_n", "_s"])


def run_values(windows: pd.DataFrame, unit: str = "window_m", by: tuple[str, ...] = ("date",)) -> pd.DataFrame:
    """One value per run, rail, band and unit: the run's wheelsets combined (energy mean, weights valid share)."""
    w = windows[windows["valid_share"] >= MIN_VALID_SHARE]
    keys = list(dict.fromkeys([c for c in (*by, "date", "run_id", "direction", "rail", "band_mm", unit, "source",
                                          "variant") if c in w.columns]))
    speed = w["speed_m_s"] if "speed_m_s" in w.columns else pd.Series(np.nan, index=w.index)
    e = w.assign(_e=w["valid_share"] * w["pk_pk_um"] ** 2, _v=w["valid_share"],
                 _s=speed.fillna(0.0) * w["valid_share"], _sv=w["valid_share"] * speed.notna())
    g = e.groupby(keys, sort=True, dropna=False)
    out = g[["_e", "_v", "_s", "_sv"]].sum().reset_index()
    out["pk_pk_um"] = np.sqrt(out["_e"] / out["_v"])
    with np.errstate(invalid="ignore", divide="ignore"):
        out["speed_m_s"] = np.where(out["_sv"] > 0, out["_s"] / out["_sv"], np.nan)
    out["estimates"] = g.size().to_numpy()
    return out.drop(columns=["_e", "_v", "_s", "_sv"])


def day_average(windows: pd.DataFrame, masked_share: pd.Series | dict | None = None, *, unit: str = "window_m",
                by: tuple[str, ...] = ("date",)) -> pd.DataFrame:
    """Energy average per day, rail, band and unit, weighted by run quality (module docstring).

    Parameters
    ----------
    windows : pandas.DataFrame
        Rows of the store's ``windows`` table (or :func:`section_table`'s) of one model version: ``run_id, rail,
        band_mm, <unit>, pk_pk_um, valid_share, speed_m_s`` and the ``by`` columns.
    masked_share : mapping run_id → float, optional
        Each run's masked share (the store's ``runs`` table).
    unit : str
        ``window_m`` or ``section``.
    by : tuple of str
        Grouping above the unit (default: the survey day; ``("date", "direction")`` averages each direction).

    Returns
    -------
    pandas.DataFrame
        ``by…, rail, band_mm, <unit>, pk_pk_um, level_db, runs, n_eff, weight, scatter_db, se_db, speed_m_s``.
    """
    cols = list(by) + ["rail", "band_mm", unit, "pk_pk_um", "level_db", "runs", "n_eff", "weight", "scatter_db",
                       "se_db", "speed_m_s"]
    rv = run_values(windows, unit, by)
    if rv.empty:
        return pd.DataFrame(columns=cols)
    keys = list(by) + ["rail", "band_mm", unit]
    ms = pd.Series(masked_share if masked_share is not None else {}, dtype=float)
    m = rv["run_id"].map(ms).fillna(0.0).to_numpy()
    v = rv["speed_m_s"].to_numpy(float)
    vbar = rv.groupby(keys, sort=False)["speed_m_s"].transform("median").to_numpy(float)
    with np.errstate(invalid="ignore", divide="ignore"):
        sw = np.where(np.isfinite(v) & np.isfinite(vbar) & (vbar > 0), np.minimum(1.0, (v / vbar) ** 2), 1.0)
    q = np.clip(1.0 - m, 0.0, 1.0) * sw
    L = level_db(rv["pk_pk_um"].to_numpy(float))
    d = rv[keys].copy()
    d["_q"] = q
    d["_qe"] = q * rv["pk_pk_um"].to_numpy(float) ** 2
    d["_qL"] = q * L
    d["_qq"] = q * q
    d["_qv"] = q * np.nan_to_num(v)
    d["_n"] = 1
    g = d.groupby(keys, sort=True)
    s = g[["_q", "_qe", "_qL", "_qq", "_qv", "_n"]].sum()
    mean_L = s["_qL"] / s["_q"]
    d = d.join(mean_L.rename("_mL"), on=keys)
    d["_dev"] = d["_q"] * (L - d["_mL"]) ** 2
    dev = d.groupby(keys, sort=True)["_dev"].sum()
    with np.errstate(invalid="ignore", divide="ignore"):
        denom = s["_q"] - s["_qq"] / s["_q"]
        var = np.where(denom > 0, dev / denom, np.nan)
        n_eff = s["_q"] ** 2 / s["_qq"]
        out = pd.DataFrame({
            "pk_pk_um": np.sqrt(s["_qe"] / s["_q"]),
            "runs": s["_n"].astype(int),
            "n_eff": n_eff,
            "weight": s["_q"],
            "scatter_db": np.sqrt(var),
            "se_db": np.sqrt(var) / np.sqrt(n_eff),
            "speed_m_s": s["_qv"] / s["_q"],
        }, index=s.index).reset_index()
    out = out[out["weight"] > 0]
    out["level_db"] = level_db(out["pk_pk_um"])
    return out[cols].reset_index(drop=True)
