"""Confidence intervals of the daily band indexes: run-to-run scatter, transfer functions, sensor placement.

Three sources, given separately and combined (thesis §4.3.3–4.3.5, Figs. 4.11–4.15):

**Run-to-run scatter** (random: shrinks with more runs). From
:func:`estimator.monitoring.averaging.day_average`: the half-width
``t_{(1+c)/2, n_eff−1} · se_db`` around the day's energy average (Student's
t with the effective number of runs; undefined with a single run).

**Transfer-function uncertainty** (systematic: the same model inverts every
run). The perturbed models of :mod:`estimator.monitoring.variants` process the
same accelerations; in each unit the level differences ``ΔL = L_variant −
L_nominal`` (same run, wheelset, rail, band) pooled over the variants and the
day's runs give the interval ``[q_{(1−c)/2}(ΔL), q_{(1+c)/2}(ΔL)]`` dB around
the nominal value (the thesis's 95 % band of the 25 models' roughness).

**Accelerometer placement** (systematic): the same with the shifted-sensor
variants (±10, ±30, ±50 mm).

**Wheel–rail contact** and **track** (systematic): the same with the
contact variants (wheel load between tare and crush load, rail-head radius
range) and the track variants (discrete supports, pad and ballast stiffness
and damping ranges, the layers' causal loss law) of
:mod:`estimator.monitoring.variants`. The estimator's contact and
track are idealisations of one vehicle load and one continuously supported
track; these variants span what the real ones may be. The placement,
contact and track sources move several independent parameters one at a
time (the track's pad and ballast stiffness and damping, supports and loss
law; the wheel load and rail head; the two placement axes): each
parameter's quantile range counts on its own and the source adds them in
quadrature on each side (:func:`variant_spread`; GUM eq. 10); the largest
single deviation alone would be the interval of a track with only one
parameter off.

**Reference calibration** (systematic, measured; optional): where a trolley
measured the rails on a survey day (a *calibration site*), the day
average's error against it, window by window and per band (pooled over the
rails), shows the estimator's own systematic error on this line, with this
vehicle and model — what the perturbations above only suppose. Its
prediction interval for one more window, ``m ± t_{(1+c)/2, n−1} s
sqrt(1 + 1/n)`` (``m, s`` the mean and standard deviation of the ``n``
calibration windows' errors in dB; Student's t: a short site widens it),
bounds the error of every other window of the line: the truth lies in
``[L − m − h, L − m + h]`` (:func:`reference_calibration`,
:func:`with_reference`). It is conservative: the errors hold the trolley's
own noise and the calibration day's run-to-run scatter, which the scatter
source counts again. It holds while the line is like the site (trackform,
speed, curvature): a site on a curve calibrates curves.

**Combined.** The sources are independent, so their half-widths add in
quadrature on each side (they are asymmetric in dB: each side is combined on
its own): ``lower = sqrt(h_s² + Σ_k a_k²)`` with ``a_k = max(0, −q_lo,k)``
over the systematic sources ``k`` and likewise above with ``max(0, q_hi,k)``;
nothing is scaled to make a coverage figure. A source that
was not evaluated contributes nothing (and says so: its columns are NaN). The
interval is ``[L − lower, L + upper]`` around the day's level ``L``.
"""

from __future__ import annotations

import re

import numpy as np
import pandas as pd
from scipy import stats

from estimator.monitoring.averaging import MIN_VALID_SHARE, level_db
from estimator.monitoring.errors import MonitoringError

__all__ = ["SOURCES", "parameter_of", "variant_deltas", "variant_spread", "with_intervals", "coverage",
           "coverage_table", "reference_calibration", "with_reference"]

SOURCES = ("model", "placement", "contact", "track")
#: the measured source (:func:`with_reference`), added at monitoring time when a calibration site is given
REFERENCE = "reference"


def variant_deltas(variants: pd.DataFrame, nominal: pd.DataFrame, unit: str = "window_m") -> pd.DataFrame:
    """``ΔL`` of every variant row against the nominal row of the same run, wheelset, rail, band and unit."""
    keys = [c for c in ("run_id", "wheelset", "rail", "band_mm", unit) if c in variants.columns]
    if variants.empty or nominal.empty:
        return pd.DataFrame(columns=keys + ["date", "source", "variant", "delta_db"])
    v = variants[variants["valid_share"] >= MIN_VALID_SHARE]
    n = nominal[nominal["valid_share"] >= MIN_VALID_SHARE][keys + ["pk_pk_um"]].rename(columns={"pk_pk_um": "_nom"})
    j = v.merge(n, on=keys, how="inner")
    j["delta_db"] = level_db(j["pk_pk_um"]) - level_db(j["_nom"])
    j = j[np.isfinite(j["delta_db"])]
    return j.drop(columns=["_nom"])


#: the value part of a variant's label (``x2``, ``+10 mm``, ``-25 %``, ``200 mm``, ``at 10 Hz``, ``01``): what is left
#: names the parameter the variant moves
_VALUE = re.compile(r"\s*(?:\bat\s+)?[x+\-]?\d[\d.eE+\-]*(?:\s*\S+)?\s*$")


def parameter_of(variant: str) -> str:
    """The parameter a variant label moves: the label without its value (``"pad stiffness x0.5"`` → ``"pad
    stiffness"``, ``"shift y -30 mm"`` → ``"shift y"``, ``"model 07"`` → ``"model"``)."""
    return _VALUE.sub("", str(variant)).strip() or str(variant)


def variant_spread(deltas: pd.DataFrame, *, unit: str = "window_m", confidence: float = 0.95,
                   by: tuple[str, ...] = ("date",)) -> pd.DataFrame:
    """Per ``by``, source, rail, band and unit: the ``confidence`` interval of ``ΔL`` and its median.

    A source's variants may move several independent parameters (the track's pad and ballast stiffness, their
    damping, the supports, the loss law; the contact's wheel load and rail head; the placement's two axes). Each
    parameter's interval is the ``confidence`` quantile range of its own variants' ``ΔL`` (pooled over runs),
    its sides taken from 0 (a parameter that only raises the level widens only the upper side); the source's
    sides are those of its parameters added in quadrature, the first-order combination of independent inputs
    (JCGM 100:2008, GUM, eq. 10). One parameter — the perturbed models' joint draws — gives its quantiles as
    they are. ``median_db`` is the median of all the source's ``ΔL``; ``parameters`` counts what was combined.
    """
    keys = list(by) + ["source", "rail", "band_mm", unit]
    if deltas.empty:
        return pd.DataFrame(columns=keys + ["lo_db", "hi_db", "median_db", "variants", "parameters"])
    lo, hi = (1 - confidence) / 2, (1 + confidence) / 2
    if "variant" in deltas.columns:
        d = deltas.assign(_parameter=deltas["variant"].map({v: parameter_of(v) for v in deltas["variant"].unique()}))
    else:
        d = deltas.assign(_parameter="")
    per = d.groupby(keys + ["_parameter"], sort=True)["delta_db"]
    p = pd.DataFrame({"q_lo": per.quantile(lo), "q_hi": per.quantile(hi)}).reset_index()
    # several parameters: each side from 0, squared for the quadrature; one parameter: its quantiles as they are
    p["lo2"] = np.minimum(p["q_lo"], 0.0) ** 2
    p["hi2"] = np.maximum(p["q_hi"], 0.0) ** 2
    g = p.groupby(keys, sort=True)
    n = g.size()
    out = pd.DataFrame({"lo_db": np.where(n == 1, g["q_lo"].first(), -np.sqrt(g["lo2"].sum())),
                        "hi_db": np.where(n == 1, g["q_hi"].first(), np.sqrt(g["hi2"].sum())),
                        "parameters": n}, index=n.index)
    a = d.groupby(keys, sort=True)["delta_db"]
    out["median_db"] = a.median()
    out["variants"] = a.size()
    return out.reset_index()[keys + ["lo_db", "hi_db", "median_db", "variants", "parameters"]]


def with_intervals(day: pd.DataFrame, spread: pd.DataFrame | None = None, *, unit: str = "window_m",
                   confidence: float = 0.95, by: tuple[str, ...] = ("date",)) -> pd.DataFrame:
    """The day averages with each source's interval and the combined one (module docstring).

    Adds ``scatter_lo_db, scatter_hi_db, model_lo_db, model_hi_db, placement_lo_db, placement_hi_db`` (offsets
    from ``level_db``), ``ci_lo_db, ci_hi_db`` (combined, absolute levels) and ``pk_lo_um, pk_hi_um``.
    """
    out = day.copy()
    keys = list(by) + ["rail", "band_mm", unit]
    n_eff = out["n_eff"].to_numpy(float)
    with np.errstate(invalid="ignore"):
        tq = np.where(n_eff > 1, stats.t.ppf((1 + confidence) / 2, np.maximum(n_eff - 1, 1e-9)), np.nan)
    h = tq * out["se_db"].to_numpy(float)
    out["scatter_lo_db"] = -h
    out["scatter_hi_db"] = h
    lower = np.nan_to_num(h) ** 2
    upper = np.nan_to_num(h) ** 2
    for src in SOURCES:
        lo_c, hi_c = f"{src}_lo_db", f"{src}_hi_db"
        if spread is not None and not spread.empty and (spread["source"] == src).any():
            s = spread[spread["source"] == src].set_index(keys)[["lo_db", "hi_db"]]
            j = out.join(s, on=keys)
            out[lo_c] = j["lo_db"].to_numpy(float)
            out[hi_c] = j["hi_db"].to_numpy(float)
        else:
            out[lo_c] = np.nan
            out[hi_c] = np.nan
        lower = lower + np.nan_to_num(np.maximum(0.0, -out[lo_c].to_numpy(float))) ** 2
        upper = upper + np.nan_to_num(np.maximum(0.0, out[hi_c].to_numpy(float))) ** 2
    L = out["level_db"].to_numpy(float)
    out["ci_lo_db"] = L - np.sqrt(lower)
    out["ci_hi_db"] = L + np.sqrt(upper)
    out["pk_lo_um"] = 10 ** (out["ci_lo_db"] / 20)
    out["pk_hi_um"] = 10 ** (out["ci_hi_db"] / 20)
    return out


def reference_calibration(errors: pd.DataFrame, *, site: tuple[float, float] | None = None,
                          confidence: float = 0.95, min_windows: int = 5) -> pd.DataFrame:
    """The estimate's error against a reference on a calibration site, per band, as a prediction interval.

    Parameters
    ----------
    errors : pandas.DataFrame
        ``rail, band_mm, window_m, error_db`` (estimate − reference, dB): the windows of
        :func:`estimator.monitoring.reference.compare_reference` (``.windows``).
    site : (float, float), optional
        Chainage range [m] of the calibration site (default: every window the reference covers).
    confidence : float
    min_windows : int
        A band with fewer calibration windows is not calibrated (its row says so).

    Returns
    -------
    pandas.DataFrame
        ``band_mm, windows, mean_error_db, sd_error_db, lo_db, hi_db, from_m, to_m``: ``lo_db, hi_db`` are the
        offsets of the truth from an estimate, ``−m ∓ t s sqrt(1 + 1/n)`` (module docstring); NaN when the band
        has fewer than ``min_windows`` windows.

    Raises
    ------
    MonitoringError
        No compared window in the site.
    """
    e = errors[np.isfinite(errors["error_db"].to_numpy(float))]
    if site is not None:
        e = e[(e["window_m"] >= site[0]) & (e["window_m"] < site[1])]
    if e.empty:
        where = f" in the calibration site {site[0]:g}-{site[1]:g} m" if site is not None else ""
        raise MonitoringError(f"no window compared with the reference{where}: nothing to calibrate with (the "
                              f"reference covers {errors['window_m'].min():g}-{errors['window_m'].max():g} m)"
                              if len(errors) else "the reference shares no window with the train's estimate")
    rows = []
    for band, g in e.groupby("band_mm", sort=True):
        v = g["error_db"].to_numpy(float)
        n = v.size
        row = {"band_mm": band, "windows": int(n), "mean_error_db": float(v.mean()),
               "sd_error_db": float(v.std(ddof=1)) if n > 1 else np.nan,
               "from_m": float(g["window_m"].min()), "to_m": float(g["window_m"].max())}
        if n >= max(2, min_windows):
            h = stats.t.ppf((1 + confidence) / 2, n - 1) * row["sd_error_db"] * np.sqrt(1 + 1 / n)
            row.update(lo_db=-row["mean_error_db"] - h, hi_db=-row["mean_error_db"] + h)
        else:
            row.update(lo_db=np.nan, hi_db=np.nan)
        rows.append(row)
    return pd.DataFrame(rows, columns=["band_mm", "windows", "mean_error_db", "sd_error_db", "lo_db", "hi_db",
                                       "from_m", "to_m"])


def with_reference(intervals: pd.DataFrame, calibration: pd.DataFrame) -> pd.DataFrame:
    """``intervals`` (:func:`with_intervals`) with the reference source added and the combined interval widened.

    Adds ``reference_lo_db, reference_hi_db`` (offsets from ``level_db``; NaN for a band the calibration does not
    cover) and combines them in quadrature with what ``ci_lo_db, ci_hi_db`` held, each side on its own (module
    docstring); ``pk_lo_um, pk_hi_um`` follow.
    """
    out = intervals.copy()
    c = calibration.set_index("band_mm")[["lo_db", "hi_db"]] if len(calibration) else None
    if c is None:
        out[f"{REFERENCE}_lo_db"] = np.nan
        out[f"{REFERENCE}_hi_db"] = np.nan
        return out
    j = out[["band_mm"]].join(c, on="band_mm")
    lo, hi = j["lo_db"].to_numpy(float), j["hi_db"].to_numpy(float)
    out[f"{REFERENCE}_lo_db"] = lo
    out[f"{REFERENCE}_hi_db"] = hi
    L = out["level_db"].to_numpy(float)
    with np.errstate(invalid="ignore"):
        lower = np.sqrt((L - out["ci_lo_db"].to_numpy(float)) ** 2 + np.nan_to_num(np.maximum(0.0, -lo)) ** 2)
        upper = np.sqrt((out["ci_hi_db"].to_numpy(float) - L) ** 2 + np.nan_to_num(np.maximum(0.0, hi)) ** 2)
    out["ci_lo_db"] = L - lower
    out["ci_hi_db"] = L + upper
    out["pk_lo_um"] = 10 ** (out["ci_lo_db"] / 20)
    out["pk_hi_um"] = 10 ** (out["ci_hi_db"] / 20)
    return out


def _against_truth(intervals: pd.DataFrame, truth: pd.DataFrame, unit: str, by: tuple[str, ...],
                   columns: tuple[str, str]) -> pd.DataFrame:
    """The interval rows joined with the truth's level (``truth_db``), where the interval ``columns`` and the truth
    are defined (a lower bound of −inf, below the noise floor, counts as defined)."""
    keys = [k for k in by if k in truth.columns] + ["rail", "band_mm", unit]
    j = intervals.merge(truth[keys + ["level_db"]].rename(columns={"level_db": "truth_db"}), on=keys, how="inner")
    lo, hi = columns
    return j[~np.isnan(j[lo]) & np.isfinite(j[hi]) & np.isfinite(j["truth_db"])]


def coverage(intervals: pd.DataFrame, truth: pd.DataFrame, *, unit: str = "window_m",
             columns: tuple[str, str] = ("ci_lo_db", "ci_hi_db"), by: tuple[str, ...] = ("date",)) -> pd.DataFrame:
    """Share of units whose truth level lies inside the interval, per band (and ``by``).

    ``truth`` holds ``rail, band_mm, <unit>, level_db`` (and the ``by`` columns it has). A window below the
    estimate's noise floor (:mod:`~estimator.monitoring.floor`: lower bound −inf, the estimate its upper bound)
    counts as covered when the truth is at most its upper bound.
    """
    lo, hi = columns
    j = _against_truth(intervals, truth, unit, by, columns)
    j["covered"] = (j["truth_db"] >= j[lo]) & (j["truth_db"] <= j[hi])
    g = j.groupby("band_mm")
    return pd.DataFrame({"windows": g.size(), "covered": g["covered"].sum(),
                         "coverage": g["covered"].mean()}).reset_index()


def coverage_table(intervals: pd.DataFrame, truth: pd.DataFrame, *, unit: str = "window_m",
                   by: tuple[str, ...] = ("date",)) -> pd.DataFrame:
    """Coverage of the truth per band by the combined interval and by each source's alone (around the level).

    Returns ``band_mm, windows, covered, coverage`` and ``coverage_<source>_alone`` for the scatter and every
    systematic source, plus ``mean_error_db`` (level − truth) and ``below``/``above`` (shares of the windows whose
    truth lies below / above the combined interval): where the misses sit says which side lacks a source; and
    ``below_floor``, the windows reported below the noise floor (counted as :func:`coverage` says).
    """
    out = coverage(intervals, truth, unit=unit, by=by).set_index("band_mm")
    L = intervals["level_db"]
    for src in ("scatter",) + SOURCES + (REFERENCE,):
        lo, hi = f"{src}_lo_db", f"{src}_hi_db"
        if lo not in intervals.columns or not np.isfinite(intervals[lo]).any():
            continue
        t = intervals.assign(_lo=L + np.minimum(0.0, intervals[lo].fillna(0.0)),
                             _hi=L + np.maximum(0.0, intervals[hi].fillna(0.0)))
        out[f"coverage_{src}_alone"] = coverage(t, truth, unit=unit, columns=("_lo", "_hi"), by=by
                                                ).set_index("band_mm")["coverage"]
    j = _against_truth(intervals, truth, unit, by, ("ci_lo_db", "ci_hi_db"))
    if "floor_status" in j.columns:
        out["below_floor"] = j.assign(_b=j["floor_status"] == "below floor").groupby("band_mm")["_b"].sum()
    g = j.assign(_err=j["level_db"] - j["truth_db"], _below=j["truth_db"] < j["ci_lo_db"],
                 _above=j["truth_db"] > j["ci_hi_db"]).groupby("band_mm")
    out["mean_error_db"] = g["_err"].mean()
    out["below"] = g["_below"].mean()
    out["above"] = g["_above"].mean()
    return out.reset_index()
