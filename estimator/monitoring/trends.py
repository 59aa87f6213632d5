"""Corrugation growth per section, rail and band, and the threshold-crossing forecast (the grinding plan).

**Growth.** For each section, rail and band the day values (energy average
of the section's windows over the day's runs,
:func:`~estimator.monitoring.averaging.day_average` with ``unit="section"``)
since the last grinding that covered the section are fitted with a straight
line in peak-to-peak amplitude against time — corrugation amplitude grows
about linearly with the traffic between grindings (the wear-instability
picture behind thesis §4.3.6; the virtual line's truth grows the same way) —
by weighted least squares, each day weighted by ``1/σ²`` with ``σ = pk ·
ln10/20 · se_db`` (its run-to-run standard error, delta method). A day with a single run
(or whose other runs were left out as outliers) has no scatter of its own:
it takes the section's pooled run-to-run scatter (median ``scatter_db`` of
its days with several runs) over ``√n_eff`` — the same measurement, one
run; equal weights only when no day of the section has several runs. The
slope's standard error comes from the
residuals when there are more than two days (scaled by ``max(1, χ²/dof)``,
so that a line that does not fit widens its own uncertainty), from the
days' errors otherwise. Growth is given in µm per month
(:data:`~estimator.monitoring.config.DAYS_PER_MONTH`).

The systematic (transfer-function, placement, contact and track)
uncertainty scales every day's value by the same unknown factor ``k``: it
does not change the slope's statistics, so it is reported beside the growth
(``systematic_lo_db``/``hi_db``, the days' mean combined systematic
half-widths) and not mixed into the slope's standard error.

**Forecast.** The crossing of the band's threshold ``T``: ``t* = (T − a)/b``
from the fit ``pk(t) = a + b t``, with the delta-method variance
``(var a + t*² var b + 2 t* cov(a, b)) / b²`` and a normal ``confidence``
interval. The systematic factor moves the crossing: the true amplitude
``k (a + b t)`` reaches ``T`` at ``t*(k) = (T/k − a)/b``; with ``k`` at the
ends of the systematic interval (``10^{lo/20}``, ``10^{hi/20}``) the
forecast's interval runs from ``t*(k_hi) − z sd`` to ``t*(k_lo) + z sd``
(``interval`` says whether it holds the systematic part). When that early
end falls before the last survey day, the systematic interval's upper side
already reaches the threshold on that day: the section may be above it now.
The interval then starts on the last survey day and ``possibly_above_now``
says so (an extrapolation of the line before the days it was fitted to
would be a date nobody can act on).

**Sensitivity to a common gain error.** The same law gives how far a gain
error common to every day (the track or wheelset model's, which no
run-to-run scatter shows) moves the date: ``dt*/dg = −T ln10 / (20 b)`` per
dB of gain ``g``, reported as ``days_per_db``: each dB by which the estimates
read high brings the forecast that many days early. Relative to the time
left, ``days_per_db / (t* − t_last) ≈ 0.115 T / (T − pk_last)``: close to
its threshold a section's date is far more sensitive than its level (at
``pk_last = 0.7 T`` a 0.5 dB gain error moves the date by a fifth of the
time left).

A section already above its threshold is reported as such (with
the first day above); a section whose slope is not significantly positive
(``b < 2 se_b``) gets no date.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from scipy import stats

from estimator.monitoring.confidence import SOURCES
from estimator.monitoring.config import DAYS_PER_MONTH, MonitoringConfig

__all__ = ["day_number", "date_of", "growth", "forecast", "last_grinding"]

_EPOCH = pd.Timestamp("1970-01-01")


def day_number(dates) -> np.ndarray:
    """Days since 1970-01-01 of ISO dates."""
    return ((pd.to_datetime(pd.Series(dates)) - _EPOCH).dt.days).to_numpy(float)


def date_of(day: float) -> str:
    if not np.isfinite(day):
        return ""
    return (_EPOCH + pd.Timedelta(days=float(round(day)))).date().isoformat()


def last_grinding(events: pd.DataFrame, from_m: float, to_m: float, before: str | None = None) -> str | None:
    """The ``date_after`` of the latest grinding event overlapping ``[from_m, to_m]`` (optionally before a date)."""
    if events is None or events.empty:
        return None
    ov = events[(events["from_m"] < to_m) & (events["to_m"] > from_m)]
    if before is not None:
        ov = ov[ov["date_after"] <= before]
    return None if ov.empty else str(ov["date_after"].max())


def _wls(t: np.ndarray, y: np.ndarray, sig: np.ndarray) -> tuple[float, float, np.ndarray]:
    """Intercept, slope and their covariance of a weighted straight-line fit."""
    w = 1 / sig ** 2
    A = np.stack([np.ones_like(t), t], axis=1)
    Aw = A * np.sqrt(w)[:, None]
    yw = y * np.sqrt(w)
    coef, *_ = np.linalg.lstsq(Aw, yw, rcond=None)
    cov = np.linalg.inv(Aw.T @ Aw)
    dof = t.size - 2
    if dof > 0:
        chi2 = float(np.sum(w * (y - A @ coef) ** 2))
        cov = cov * max(1.0, chi2 / dof)
    return float(coef[0]), float(coef[1]), cov


def growth(day_sections: pd.DataFrame, events: pd.DataFrame | None = None, sections=None,
           cfg: MonitoringConfig = MonitoringConfig()) -> pd.DataFrame:
    """Growth rate per section, rail and band since the last grinding (module docstring).

    Parameters
    ----------
    day_sections : pandas.DataFrame
        ``date, section, rail, band_mm, pk_pk_um, se_db`` (and, optionally, the interval columns of
        :func:`~estimator.monitoring.confidence.with_intervals`).
    events : pandas.DataFrame, optional
        Grinding events (:func:`~estimator.monitoring.grinding.detect_grinding`).
    sections : Sections, optional
        Section extents (for matching the events).

    Returns
    -------
    pandas.DataFrame
        ``section, rail, band_mm, since, first_date, last_date, days, intercept_um, slope_um_per_day,
        slope_se_um_per_day, growth_um_per_month, growth_se_um_per_month, last_pk_pk_um, t0_day`` (the fit's
        time origin, days since 1970-01-01) and ``cov`` (2×2 covariance, intercept and slope).
    """
    rows = []
    for (sec, rail, band), g in day_sections.groupby(["section", "rail", "band_mm"], sort=True):
        g = g.sort_values("date")
        a, b = sections.extent(sec) if sections is not None else (math.nan, math.nan)
        since = last_grinding(events, a, b) if np.isfinite(a) else None
        seg = g[g["date"] >= since] if since else g
        seg = seg[np.isfinite(seg["pk_pk_um"])]
        row = {"section": sec, "rail": rail, "band_mm": band, "since": since or "", "days": int(len(seg)),
               "first_date": seg["date"].min() if len(seg) else "", "last_date": seg["date"].max() if len(seg) else "",
               "last_pk_pk_um": float(seg["pk_pk_um"].iloc[-1]) if len(seg) else math.nan}
        if len(seg) < cfg.trend_min_days:
            rows.append({**row, "intercept_um": math.nan, "slope_um_per_day": math.nan,
                         "slope_se_um_per_day": math.nan, "t0_day": math.nan, "cov": None})
            continue
        t = day_number(seg["date"])
        t0 = float(t[0])
        y = seg["pk_pk_um"].to_numpy(float)
        se = seg["se_db"].to_numpy(float) if "se_db" in seg.columns else np.full(y.size, np.nan)
        if "scatter_db" in seg.columns and "n_eff" in seg.columns and not np.all(np.isfinite(se) & (se > 0)):
            pooled = seg["scatter_db"].to_numpy(float)
            pooled = pooled[np.isfinite(pooled) & (pooled > 0)]
            if pooled.size:
                one = np.median(pooled) / np.sqrt(np.maximum(seg["n_eff"].to_numpy(float), 1.0))
                se = np.where(np.isfinite(se) & (se > 0), se, one)
        sig = y * math.log(10) / 20 * se
        if not np.all(np.isfinite(sig) & (sig > 0)):
            sig = np.full(y.size, max(float(np.std(y)) if y.size > 2 else 1.0, 1e-3))
        a0, b0, cov = _wls(t - t0, y, sig)
        extra = {}
        for side in ("lo", "hi"):
            sign = -1.0 if side == "lo" else 1.0
            parts = [seg[f"{s}_{side}_db"].to_numpy(float) for s in SOURCES if f"{s}_{side}_db" in seg.columns]
            parts = [p for p in parts if np.isfinite(p).any()]
            if parts:
                # each side on its own, as the day intervals (confidence.with_intervals): a source that only
                # raises the level adds nothing below
                v = np.sqrt(sum(np.nan_to_num(np.maximum(0.0, sign * p)) ** 2 for p in parts))
                extra[f"systematic_{side}_db"] = sign * float(np.mean(v))
        rows.append({**row, "intercept_um": a0, "slope_um_per_day": b0, "slope_se_um_per_day": math.sqrt(cov[1, 1]),
                     "t0_day": t0, "cov": cov, **extra})
    out = pd.DataFrame(rows)
    if out.empty:
        return out
    out["growth_um_per_month"] = out["slope_um_per_day"] * DAYS_PER_MONTH
    out["growth_se_um_per_month"] = out["slope_se_um_per_day"] * DAYS_PER_MONTH
    return out


def forecast(growth_table: pd.DataFrame, thresholds_um: dict, day_sections: pd.DataFrame | None = None,
             confidence: float = 0.95) -> pd.DataFrame:
    """When each section, rail and band crosses its threshold (module docstring): the grinding plan.

    Returns
    -------
    pandas.DataFrame
        ``section, rail, band_mm, threshold_um, last_pk_pk_um, status, crossing_date, crossing_lo, crossing_hi,
        crossing_day, crossing_sd_days, days_per_db`` (the crossing's shift per dB of common gain error, module
        docstring), ``possibly_above_now`` (the interval's early end reaches the last survey day), sorted by
        crossing date (already above first).
    """
    z = stats.norm.ppf((1 + confidence) / 2)
    rows = []
    for _, r in growth_table.iterrows():
        T = thresholds_um.get(r["band_mm"], math.nan)
        row = {"section": r["section"], "rail": r["rail"], "band_mm": r["band_mm"], "threshold_um": T,
               "last_pk_pk_um": r["last_pk_pk_um"], "growth_um_per_month": r.get("growth_um_per_month", math.nan),
               "crossing_date": "", "crossing_lo": "", "crossing_hi": "", "crossing_day": math.nan,
               "crossing_sd_days": math.nan, "days_per_db": math.nan, "possibly_above_now": False}
        if not np.isfinite(T):
            rows.append({**row, "status": "no threshold for this band"})
            continue
        if np.isfinite(r["last_pk_pk_um"]) and r["last_pk_pk_um"] >= T:
            first = ""
            if day_sections is not None:
                g = day_sections[(day_sections["section"] == r["section"]) & (day_sections["rail"] == r["rail"])
                                 & (day_sections["band_mm"] == r["band_mm"])]
                if r.get("since"):
                    g = g[g["date"] >= r["since"]]
                above = g[g["pk_pk_um"] >= T].sort_values("date")
                first = str(above["date"].iloc[0]) if len(above) else ""
            rows.append({**row, "status": f"above threshold{' since ' + first if first else ''}",
                         "crossing_date": first})
            continue
        b, se_b = r["slope_um_per_day"], r["slope_se_um_per_day"]
        if not (np.isfinite(b) and np.isfinite(se_b)) or b <= 2 * se_b:
            rows.append({**row, "status": "not growing significantly" if np.isfinite(b) else "too few days"})
            continue
        a, cov, t0 = r["intercept_um"], r["cov"], r["t0_day"]

        def crossing(k: float) -> tuple[float, float]:
            ts = (T / k - a) / b
            var = (cov[0, 0] + ts ** 2 * cov[1, 1] + 2 * ts * cov[0, 1]) / b ** 2
            return t0 + ts, math.sqrt(max(var, 0.0))

        day, sd = crossing(1.0)
        lo_db, hi_db = r.get("systematic_lo_db", math.nan), r.get("systematic_hi_db", math.nan)
        systematic = bool(np.isfinite(lo_db) and np.isfinite(hi_db))
        early, sd_e = crossing(10 ** (hi_db / 20)) if systematic else (day, sd)
        late, sd_l = crossing(10 ** (lo_db / 20)) if systematic else (day, sd)
        first = min(early - z * sd_e, day - z * sd)
        last_day = day_number([r["last_date"]])[0] if r.get("last_date") else math.nan
        now = bool(np.isfinite(last_day) and first < last_day)
        rows.append({**row, "status": "forecast", "crossing_date": date_of(day),
                     "crossing_lo": date_of(min(last_day, day) if now else first), "possibly_above_now": now,
                     "crossing_hi": date_of(max(late + z * sd_l, day + z * sd)), "crossing_day": day,
                     "crossing_sd_days": sd, "days_per_db": T * math.log(10) / (20 * b),
                     "interval": "statistical and systematic" if systematic else "statistical only"})
    out = pd.DataFrame(rows)
    if out.empty:
        return out
    order = out["status"].str.startswith("above").map({True: 0, False: 1})
    return out.assign(_o=order, _d=out["crossing_day"].fillna(np.inf)).sort_values(["_o", "_d", "section"]) \
        .drop(columns=["_o", "_d"]).reset_index(drop=True)
