"""Comparison with a trolley reference: read, aligned to the train's chainage, same EN processing, errors per band.

A corrugation trolley (``trolley/<date>.csv``: ``chainage_m, rail,
roughness_um`` at about 1 mm) measures the rail directly, on its own chainage
reference. :func:`compare_reference`:

1. reads it (:func:`estimator.io.read_trolley`) onto a uniform grid per rail
   (stretches further apart than :data:`MAX_GAP_STEPS` samples stay apart:
   NaN between them, nothing interpolated across);
2. aligns it to the train's chainage — the feature signal of the trolley's
   profile against the day's reference run in the store, with the same
   two-pass, piecewise offset + scale fit as the runs
   (:func:`~estimator.monitoring.alignment.align_profiles`);
3. processes it with the **same** EN 13231-3 code as the train's estimate
   (:func:`estimator.standards.en13231.band_indexes`: zero-phase band filter,
   Table 4.1 windows, eq. 4.1) and the same chainage windows (energy mean per
   window), and with the same EN 15610 code over the train's stretches
   (:func:`estimator.standards.en15610.roughness_spectrum`);
4. compares per band and rail, on the windows both resolve: the level error
   ``L_train − L_trolley`` [dB] (mean, RMS, 90th percentile of its magnitude,
   share within ±3 dB), the correlation of the two level series along
   chainage, and per one-third-octave band of the stretches' spectra.
"""

from __future__ import annotations

import datetime as _dt
import logging
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from estimator.config import EstimatorConfig
from estimator.io import read_trolley
from estimator.monitoring.alignment import AlignmentStage, align_profiles, feature_profile
from estimator.monitoring.averaging import energy_mean_db, level_db
from estimator.monitoring.config import MonitoringConfig
from estimator.monitoring.errors import TrolleyReferenceError
from estimator.monitoring.records import bin_windows
from estimator.reference import MAX_GAP_STEPS, on_uniform_grid
from estimator.standards.en13231 import band_indexes
from estimator.standards.en15610 import roughness_spectrum

__all__ = ["TrolleyRecord", "read_trolley_record", "trolley_windows", "band_errors", "ReferenceComparison",
           "compare_reference", "MAX_GAP_STEPS"]

log = logging.getLogger("estimator")

_DATE_IN_NAME = re.compile(r"(\d{4}-\d{2}-\d{2})")


@dataclass(frozen=True, eq=False)
class TrolleyRecord:
    """A trolley file on a uniform grid: ``values`` (n_rails, M) [m] at ``x0 + dx·j`` (NaN in gaps)."""

    source: str
    date: str
    x0: float
    dx: float
    rails: tuple[str, ...]
    values: np.ndarray

    @property
    def x(self) -> np.ndarray:
        return self.x0 + self.dx * np.arange(self.values.shape[1])


def read_trolley_record(path, date: str | None = None) -> TrolleyRecord:
    """Read a trolley file onto a uniform grid per rail (module docstring, step 1).

    Raises
    ------
    FileNotFoundError, RunFileError, TrolleyReferenceError
    """
    p = Path(path)
    df = read_trolley(p)
    if df.empty:
        raise TrolleyReferenceError(f"{p}: no valid row (chainage_m, rail, roughness_um)")
    if date is None:
        m = _DATE_IN_NAME.search(p.name)
        date = m.group(1) if m else ""
        if date:
            try:
                _dt.date.fromisoformat(date)
            except ValueError:
                raise TrolleyReferenceError(f"{p}: the name's date {date!r} is not a calendar date (the survey day "
                                            "is read from the name, YYYY-MM-DD)") from None
    rails = tuple(sorted(df["rail"].unique()))
    if len(rails) == 1:
        log.warning("%s: holds rail %s only: the comparison, and a calibration from it, covers that rail alone", p,
                    rails[0])
    steps = [np.median(np.diff(g["chainage_m"].to_numpy())) for _, g in df.groupby("rail") if len(g) > 1]
    if not steps or not np.all(np.isfinite(steps)) or min(steps) <= 0:
        raise TrolleyReferenceError(f"{p}: a trolley record needs increasing chainages on each rail")
    dx = float(min(steps))
    lo, hi = float(df["chainage_m"].min()), float(df["chainage_m"].max())
    n = int(round((hi - lo) / dx)) + 1
    if n > 50_000_000:
        raise TrolleyReferenceError(f"{p}: {n} samples at {dx * 1e3:g} mm over {hi - lo:.0f} m; at most 50 million")
    vals = np.full((len(rails), n), np.nan)
    for i, r in enumerate(rails):
        g = df[df["rail"] == r]
        vals[i] = on_uniform_grid(g["chainage_m"].to_numpy(float), g["roughness_m"].to_numpy(float), dx, lo,
                                  lo + dx * (n - 1))[1]
    return TrolleyRecord(str(p), date, lo, dx, rails, vals)


def trolley_windows(rec: TrolleyRecord, shift, est_cfg: EstimatorConfig, window_m: float) -> pd.DataFrame:
    """EN 13231-3 band peak-to-peak of the trolley per chainage window on the aligned chainage."""
    bands = est_cfg.bands_mm
    # a band whose shortest wavelength the trolley's sampling does not resolve (Nyquist: two samples) would be
    # compared as aliased noise, tens of dB off; it is left out and said
    coarse = [b for b in bands if 1e-3 * b[0] < 2 * rec.dx]
    if coarse:
        log.warning("%s: sampled every %g mm, which does not resolve the band(s) %s mm: left out of the comparison",
                    rec.source, 1e3 * rec.dx, ", ".join(f"{lo:g}-{hi:g}" for lo, hi in coarse))
    bands = tuple(b for b in bands if b not in coarse)
    if not bands:
        raise TrolleyReferenceError(f"{rec.source}: sampled every {1e3 * rec.dx:g} mm, it resolves none of the "
                                    "EN 13231-3 bands")
    idx = band_indexes(rec.values, rec.dx, bands, [est_cfg.window_m(b) for b in bands])
    xa = rec.x + (shift.shift(rec.x) if shift is not None else 0.0)
    return bin_windows(xa, idx.pk_pk, rec.dx, bands, rec.rails, window_m).drop(columns=["speed_m_s", "lr_correlation"])


def band_errors(train: pd.DataFrame, trolley: pd.DataFrame, min_valid: float = 0.5) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Per rail and band: level error statistics of the train's windows against the trolley's (module docstring).

    Returns the table of errors and the merged windows (``train_db, trolley_db, error_db``).
    """
    keys = ["rail", "band_mm", "window_m"]
    a = train[train["valid_share"] >= min_valid][keys + ["pk_pk_um"]].rename(columns={"pk_pk_um": "train_um"})
    b = trolley[trolley["valid_share"] >= min_valid][keys + ["pk_pk_um"]].rename(columns={"pk_pk_um": "trolley_um"})
    j = a.merge(b, on=keys, how="inner")
    j["train_db"] = level_db(j["train_um"])
    j["trolley_db"] = level_db(j["trolley_um"])
    j["error_db"] = j["train_db"] - j["trolley_db"]
    rows = []
    for (rail, band), g in j.groupby(["rail", "band_mm"], sort=True):
        e = g["error_db"].to_numpy(float)
        corr = float(np.corrcoef(g["train_db"], g["trolley_db"])[0, 1]) if len(g) > 2 else math.nan
        rows.append({"rail": rail, "band_mm": band, "windows": int(len(g)),
                     "train_pk_pk_um": 10 ** (energy_mean_db(g["train_db"]) / 20),
                     "trolley_pk_pk_um": 10 ** (energy_mean_db(g["trolley_db"]) / 20),
                     "level_error_db": energy_mean_db(g["train_db"]) - energy_mean_db(g["trolley_db"]),
                     "mean_error_db": float(np.mean(e)), "rms_error_db": float(np.sqrt(np.mean(e ** 2))),
                     "p90_abs_error_db": float(np.percentile(np.abs(e), 90)),
                     "within_3db": float(np.mean(np.abs(e) <= 3.0)), "correlation": corr})
    return pd.DataFrame(rows), j


@dataclass(frozen=True, eq=False)
class ReferenceComparison:
    """A trolley file against the train's day average (see :func:`compare_reference`)."""

    trolley: str
    date: str
    train_date: str
    line: str
    model_hash: str
    alignment: AlignmentStage
    errors: pd.DataFrame
    windows: pd.DataFrame
    spectra: pd.DataFrame
    spectra_errors: pd.DataFrame


def _nearest(dates, date: str) -> str:
    ds = sorted(set(dates))
    if date in ds or not date:
        return date if date in ds else ds[-1]
    d0 = pd.Timestamp(date)
    return min(ds, key=lambda d: abs((pd.Timestamp(d) - d0).days))


def compare_reference(store, trolley, *, line: str | None = None, model_hash: str | None = None,
                      date: str | None = None, cfg: MonitoringConfig = MonitoringConfig(),
                      estimator_config: EstimatorConfig | None = None) -> ReferenceComparison:
    """Compare a trolley file with the train's day average in the store (module docstring).

    Parameters
    ----------
    store : MonitoringStore or path
    trolley : path
        ``trolley/<date>.csv``.
    line, model_hash : str, optional
        Default: the store's only line, its last model version.
    date : str, optional
        Survey day of the trolley (default: from the file name); the train's nearest survey day is used.
    """
    from estimator.monitoring.store import MonitoringStore
    from estimator.monitoring.workflow import DayReference, _pick_version

    st = store if isinstance(store, MonitoringStore) else MonitoringStore(store)
    st.verify()  # a file the store did not write is refused before it is compared
    est_cfg = estimator_config or EstimatorConfig()
    rec = read_trolley_record(trolley, date)
    lines = st.lines()
    if line is None:
        if len(lines) != 1:
            raise TrolleyReferenceError(f"store {st.root} holds lines {lines}; choose one")
        line = lines[0]
    mh = _pick_version(st, line, model_hash)
    days = st.read("days", line=line, model_hash=mh)
    if days.empty:
        raise TrolleyReferenceError(f"store {st.root}: no day average of line {line!r} (model {mh}); ingest runs first")
    tdate = _nearest(days["date"].unique(), rec.date)
    if rec.date and tdate != rec.date:
        log.warning("%s: no train survey on %s; comparing with the nearest day %s", rec.source, rec.date, tdate)
    elif not rec.date:
        log.warning("%s: no survey date in the file's name (<YYYY-MM-DD>.csv); comparing with the train's last survey "
                    "day %s", rec.source, tdate)
    stored = st.read_reference(line, tdate, mh)
    if stored is None:
        raise TrolleyReferenceError(f"store {st.root}: no alignment reference for {line!r} on {tdate}")
    ref = DayReference.from_store(line, tdate, *stored)
    fp = feature_profile(rec.x, rec.values, rec.rails, cfg.align_band_mm, f"trolley {rec.date}")
    stage = align_profiles(fp, ref.profile, cfg, target_name=f"train reference {ref.run_id}")
    if not stage.accepted:
        raise TrolleyReferenceError(f"{rec.source}: the trolley record cannot be aligned to the train's chainage "
                                    f"({stage.reason})")
    tw = trolley_windows(rec, stage.fit, est_cfg, cfg.window_m)
    train = days[days["date"] == tdate].assign(valid_share=1.0)
    errors, merged = band_errors(train, tw)
    # EN 15610 per stretch of the train's spectra
    spec = st.read("spectra", line=line, date=tdate, model_hash=mh)
    srows = []
    if len(spec):
        xa = rec.x + stage.fit.shift(rec.x)
        for (stretch, rail), g in spec.groupby(["stretch", "rail"]):
            if rail not in rec.rails:
                continue
            a, b = float(g["from_m"].min()), float(g["to_m"].max())
            sel = (xa >= a) & (xa <= b)
            if sel.sum() < 1.0 / rec.dx:
                continue
            prof = rec.values[rec.rails.index(rail), sel]
            ts = roughness_spectrum(prof, rec.dx, segment_m=est_cfg.en15610_segment_m)
            tl = dict(zip(ts.bands.tolist(), ts.level_db.tolist()))
            for band, gb in g.groupby("band"):
                srows.append({"stretch": stretch, "rail": rail, "band": int(band),
                              "wavelength_m": float(gb["wavelength_m"].iloc[0]),
                              "train_db": energy_mean_db(gb["level_db"]), "trolley_db": tl.get(int(band), math.nan),
                              "runs": int(gb["run_id"].nunique())})
    spectra = pd.DataFrame(srows)
    if len(spectra):
        spectra["error_db"] = spectra["train_db"] - spectra["trolley_db"]
        ok = spectra[np.isfinite(spectra["error_db"])]
        se = ok.groupby(["stretch", "rail"]).agg(bands=("error_db", "size"), mean_error_db=("error_db", "mean"),
                                                 max_abs_error_db=("error_db", lambda e: float(np.max(np.abs(e))))
                                                 ).reset_index()
    else:
        se = pd.DataFrame()
    return ReferenceComparison(rec.source, rec.date, tdate, line, mh, stage, errors, merged, spectra, se)
