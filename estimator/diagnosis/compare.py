"""Compare the estimate with the reference on the calibration site, and say where it fails.

Per rail: the EN 13231-3 band-index error (the estimator's own band
processing of estimate and reference, :func:`estimator.reference.compare_bands`,
RMS over chainage windows of ``20 lg(pk_est/pk_ref)``), the one-third-octave
level error of the evidence cells (:mod:`estimator.diagnosis.evidence`), the
side discrimination (the error of the L − R level difference, ``e_L − e_R``
per segment and band), the coherence between estimate and reference along
chainage per EN band (:func:`scipy.signal.coherence`, windows of eight of the
band's longest wavelengths). The summary figure of merit is the diagnosis's
``E`` (RMS cell error) with its noise floor. Where it fails: the bands, rail,
speed range and wheelset role whose error exceeds ``noise_margin`` × floor
and 3 dB.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import signal

from estimator.diagnosis.diagnose import cell_masks

__all__ = ["FieldComparison", "compare_with_reference", "index_errors", "locate_anomalies", "FAIL_DB",
           "ANOMALY_DB"]

#: a band, rail, speed range or role whose RMS error exceeds this (and the floor's margin) is where it fails
FAIL_DB = 3.0
#: a chainage window whose band-index error departs from the stretch's median by more than this (and by 4 robust
#: standard deviations) in the same direction in every run and wheelset (all but one of four or more) is a local
#: anomaly
ANOMALY_DB = 3.0


@dataclass(frozen=True, eq=False)
class FieldComparison:
    """Tables of the comparison (module docstring); ``figure_of_merit_db`` with ``noise_floor_db``."""

    figure_of_merit_db: float
    noise_floor_db: float
    en_bands: pd.DataFrame
    third_octave: pd.DataFrame
    side: pd.DataFrame
    coherence: pd.DataFrame
    by_speed: pd.DataFrame
    by_role: pd.DataFrame
    failing: tuple[str, ...]
    anomalies: pd.DataFrame = None

    def as_dict(self) -> dict:
        return {"figure_of_merit_db": self.figure_of_merit_db, "noise_floor_db": self.noise_floor_db,
                "failing": list(self.failing),
                **{k: getattr(self, k).to_dict(orient="records") for k in
                   ("en_bands", "third_octave", "side", "coherence", "by_speed", "by_role", "anomalies")
                   if getattr(self, k) is not None}}


def _reference_frame(aligned: dict) -> pd.DataFrame:
    parts = []
    for rail, (x, v) in aligned.items():
        ok = np.isfinite(v)
        parts.append(pd.DataFrame({"chainage_m": x[ok], "rail": rail, "roughness_m": v[ok]}))
    return pd.concat(parts, ignore_index=True)


def _pool(df: pd.DataFrame, keys: list[str]) -> pd.DataFrame:
    """Pool RMS window errors over pieces: sqrt(Σ n·rms² / Σ n)."""
    d = df.dropna(subset=["rms_error_db"])
    if d.empty:
        return pd.DataFrame(columns=keys + ["n_windows", "rms_error_db", "mean_error_db"])
    d = d.assign(ss=d["n_windows"] * d["rms_error_db"] ** 2, sm=d["n_windows"] * d["mean_error_db"])
    g = d.groupby(keys, as_index=False)[["n_windows", "ss", "sm"]].sum()
    g["rms_error_db"] = np.sqrt(g["ss"] / g["n_windows"])
    g["mean_error_db"] = g["sm"] / g["n_windows"]
    return g.drop(columns=["ss", "sm"])


def index_errors(estimate, aligned: dict, site: tuple[float, float], calibration_day: bool, est_cfg,
                 window_m: float = 1.0, focus=(), stretches=()) -> pd.DataFrame:
    """EN 13231-3 band-index error of one run per ``set`` (calibration site / validation), wheelset, rail, band.

    On the calibration day the site calibrates and the rest validates; on another day everything validates.
    ``focus``: stretches ``(from, to)`` where accepted effects act; on another day they also form the set
    ``validation where the effects act``; ``stretches``: stretches given by the user, each its own
    ``validation stretch`` rows on another day.
    """
    from estimator.reference import compare_bands, reference_indexes

    ref = reference_indexes(_reference_frame(aligned), est_cfg)
    lo = max(float(np.nanmin(x)) for x, _ in aligned.values())
    hi = min(float(np.nanmax(x)) for x, _ in aligned.values())
    xs = np.concatenate([p.chainage_m for p in estimate.profiles.values()])
    lo, hi = max(lo, float(np.nanmin(xs))) + 5.0, min(hi, float(np.nanmax(xs))) - 5.0  # the band filters' edges
    if calibration_day:
        pieces = [("calibration", max(lo, site[0]), min(hi, site[1])), ("validation", lo, min(hi, site[0])),
                  ("validation", max(lo, site[1]), hi)]
    else:
        pieces = [("validation", lo, hi)] + [("validation where the effects act", max(lo, a), min(hi, b))
                                             for a, b in focus] + [("validation stretch", max(lo, a), min(hi, b))
                                                                   for a, b in stretches]
    parts = []
    for name, a, b in pieces:
        if b - a < 2 * window_m:
            continue
        t = compare_bands(estimate, ref, (a, b), window_m=window_m)
        if len(t):
            parts.append(t.assign(set=name))
    if not parts:
        return pd.DataFrame()
    return _pool(pd.concat(parts, ignore_index=True), ["set", "wheelset", "role", "model", "rail", "band_mm"])


def locate_anomalies(estimates, aligned_by_date: dict, span: tuple[float, float], est_cfg, window_m: float = 1.0
                     ) -> pd.DataFrame:
    """Chainage windows where the estimate departs from the reference locally, the same way in (nearly) every run.

    Per run, wheelset, rail and EN 13231-3 band the window error ``20 lg(pk_est/pk_ref)`` on ``window_m``
    windows (:func:`estimator.reference.window_pk`); per window the median over runs and wheelsets; a window
    stands out when that median departs from the band's median along the stretch by more than
    :data:`ANOMALY_DB` and 4 × 1.4826 × MAD, with the same sign in every run and wheelset estimate — all but one
    when there are four or more (a soft pad over four sleepers, 590 m on the virtual line, reads +3…+4 dB in
    100-300 mm in three of the four estimates and +0.9 dB in the fourth). Adjacent windows merge.
    """
    from estimator.reference import reference_indexes, window_pk

    edges = np.arange(math.ceil(span[0]), span[1] + 1e-9, window_m)
    acc: dict = {}
    for est in estimates:
        ref = aligned_by_date.get(est.header.get("date"))
        if ref is None:
            continue
        ri = reference_indexes(_reference_frame(ref), est_cfg, span)
        for (w, kind), p in est.profiles.items():
            for rail in p.rails:
                if rail not in ri.indexes:
                    continue
                for band in p.indexes.bands_mm:
                    e = window_pk(p.chainage_m, p.pk_pk(band, rail), edges)
                    r = window_pk(*ri.pk_pk(band, rail), edges)
                    with np.errstate(divide="ignore", invalid="ignore"):
                        acc.setdefault((rail, f"{band[0]:g}-{band[1]:g}"), []).append(20 * np.log10(e / r))
    rows = []
    for (rail, band), errs in acc.items():
        E = np.vstack(errs)
        med = np.full(E.shape[1], np.nan)
        some = np.isfinite(E).any(axis=0)
        med[some] = np.nanmedian(E[:, some], axis=0)
        ok = np.isfinite(med)
        if ok.sum() < 10:
            continue
        centre = float(np.median(med[ok]))
        mad = 1.4826 * float(np.median(np.abs(med[ok] - centre)))
        dev = med - centre
        # the same direction in (nearly) every run and wheelset: a random fluctuation does not repeat
        n_est = np.isfinite(E).sum(axis=0)
        agree = (np.sign(E - centre) == np.sign(dev)[None]).sum(axis=0)
        same = agree >= np.maximum(n_est - (n_est >= 4), 1)
        hot = ok & same & (np.abs(dev) > max(ANOMALY_DB, 4 * mad))
        for i in np.flatnonzero(hot):
            rows.append({"from_m": float(edges[i]), "to_m": float(edges[i + 1]), "rail": rail, "band_mm": band,
                         "error_db": float(med[i]), "departure_db": float(dev[i]), "runs": int(E.shape[0])})
    out = pd.DataFrame(rows, columns=["from_m", "to_m", "rail", "band_mm", "error_db", "departure_db", "runs"])
    if out.empty:
        return out
    merged = []
    for (rail, band), g in out.sort_values("from_m").groupby(["rail", "band_mm"], sort=False):
        cur = None
        for r in g.itertuples():
            if cur is not None and abs(r.from_m - cur["to_m"]) < 1e-6:
                cur["to_m"] = r.to_m
                cur["departure_db"] = max(cur["departure_db"], r.departure_db, key=abs)
                cur["error_db"] = max(cur["error_db"], r.error_db, key=abs)
            else:
                if cur is not None:
                    merged.append(cur)
                cur = r._asdict()
                cur.pop("Index", None)
        merged.append(cur)
    return pd.DataFrame(merged).sort_values("departure_db", key=np.abs, ascending=False).reset_index(drop=True)


def _coherence(estimates, aligned_by_date: dict, site, bands) -> pd.DataFrame:
    rows = []
    for est in estimates:
        ref = aligned_by_date.get(est.header.get("date"))
        if ref is None:
            continue
        for (w, kind), p in est.profiles.items():
            sel = (p.chainage_m >= site[0]) & (p.chainage_m <= site[1])
            if sel.sum() < 64:
                continue
            x = p.chainage_m[sel]
            for i, rail in enumerate(p.rails):
                if rail not in ref:
                    continue
                e = p.rail[i, sel]
                r = np.interp(x, *ref[rail], left=np.nan, right=np.nan)
                ok = np.isfinite(e) & np.isfinite(r)
                if ok.mean() < 0.9:
                    continue
                e, r = np.where(ok, e, 0.0), np.where(ok, r, 0.0)
                for b in bands:
                    nper = min(int(round(8 * b[1] * 1e-3 / p.dx)), x.size // 4)
                    if nper < 16:
                        continue
                    k, C = signal.coherence(e, r, fs=1.0 / p.dx, nperseg=nper)
                    inb = (k >= 1e3 / b[1]) & (k <= 1e3 / b[0])
                    if inb.any():
                        rows.append({"run_id": est.run_id, "wheelset": w, "role": p.role, "rail": rail,
                                     "band_mm": f"{b[0]:g}-{b[1]:g}", "coherence": float(np.mean(C[inb]))})
    return pd.DataFrame(rows)


def compare_with_reference(estimates, aligned_by_date: dict, ev, errs: list, diag, cfg, index_tables=None
                           ) -> FieldComparison:
    """The comparison of the nominal estimate with the reference on the calibration site (module docstring).

    ``index_tables``: the runs' :func:`index_errors` when already computed (else computed here).
    """
    from estimator.config import EstimatorConfig

    masks = cell_masks(ev, cfg.min_reference_snr_db)
    rows = []
    for si, (s, e, m) in enumerate(zip(ev.segments, errs, masks)):
        if not ev.calibration[si]:
            continue
        for j, rail in enumerate(s.rails):
            for k, b in enumerate(s.bands):
                if m[j, k] and np.isfinite(e[j, k]):
                    rows.append({"segment": si, "rail": rail, "role": s.role, "speed_m_s": s.speed_m_s,
                                 "wavelength_mm": round(1e3 * ev.band_table[b, 0], 2), "error_db": float(e[j, k])})
    cells = pd.DataFrame(rows, columns=["segment", "rail", "role", "speed_m_s", "wavelength_mm", "error_db"])

    def stats(keys):
        if cells.empty:
            return pd.DataFrame(columns=keys + ["mean_error_db", "rms_error_db", "n_cells"])
        return cells.groupby(keys, as_index=False).agg(
            mean_error_db=("error_db", "mean"), rms_error_db=("error_db", lambda v: float(np.sqrt(np.mean(v ** 2)))),
            n_cells=("error_db", "size"))

    third = stats(["rail", "wavelength_mm"])
    by_role = stats(["role", "rail"])
    if not cells.empty:
        edges = np.unique(np.quantile(cells["speed_m_s"], [0, 1 / 3, 2 / 3, 1]))
        lab = pd.cut(cells["speed_m_s"], edges, include_lowest=True) if edges.size > 1 else "all"
        by_speed = cells.assign(speed_range=lab.astype(str) if edges.size > 1 else lab).groupby(
            "speed_range", as_index=False).agg(mean_error_db=("error_db", "mean"),
                                               rms_error_db=("error_db", lambda v: float(np.sqrt(np.mean(v ** 2)))),
                                               n_cells=("error_db", "size"))
        piv = cells.pivot_table(index=["segment", "wavelength_mm", "role"], columns="rail", values="error_db")
        if {"L", "R"} <= set(piv.columns):
            d = (piv["L"] - piv["R"]).dropna().rename("side_error_db").reset_index()
            side = d.groupby("wavelength_mm", as_index=False).agg(
                mean_side_error_db=("side_error_db", "mean"),
                rms_side_error_db=("side_error_db", lambda v: float(np.sqrt(np.mean(v ** 2)))),
                n=("side_error_db", "size"))
        else:
            side = pd.DataFrame()
    else:
        by_speed, side = pd.DataFrame(), pd.DataFrame()
    est_cfg = EstimatorConfig()
    en = []
    if index_tables is None:
        index_tables = [index_errors(est, aligned_by_date[est.header.get("date")], ev.site, True, est_cfg,
                                     cfg.en_window_m) for est in estimates if est.header.get("date") in aligned_by_date]
    for t in index_tables:
        if len(t):
            en.append(t[t["set"] == "calibration"])
    en_bands = _pool(pd.concat(en, ignore_index=True), ["wheelset", "role", "rail", "band_mm"]) if en else \
        pd.DataFrame()
    coh = _coherence(estimates, aligned_by_date, ev.site, est_cfg.bands_mm)
    if len(coh):
        coh = coh.groupby(["role", "rail", "band_mm"], as_index=False)["coherence"].mean()
    floor = diag.noise_floor_db
    limit = max(FAIL_DB, cfg.noise_margin * floor)
    failing = []
    for t, keys, what in ((third, ["rail", "wavelength_mm"], "band"), (by_role, ["role", "rail"], "wheelset/rail"),
                          (by_speed, ["speed_range"], "speed")):
        if t is None or t.empty:
            continue
        for r in t[t["rms_error_db"] > limit].itertuples():
            failing.append(f"{what} " + ", ".join(f"{k} {getattr(r, k)}" for k in keys)
                           + f": {r.mean_error_db:+.1f} dB mean, {r.rms_error_db:.1f} dB RMS")
    e0 = float(diag.errors.query("stage == 'nominal' and set == 'calibration'")["error_db"].iloc[0])
    anomalies = locate_anomalies(estimates, aligned_by_date, ev.site, est_cfg, cfg.en_window_m)
    return FieldComparison(e0, floor, en_bands, third, side, coh, by_speed, by_role, tuple(failing), anomalies)
