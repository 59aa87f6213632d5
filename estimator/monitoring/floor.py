"""The estimate's noise floor: what the estimator makes of the sensors' own noise on a perfectly smooth rail.

**Floor.** The accelerometer chain's noise (its datasheet or a standstill
recording: ``MonitoringConfig.sensor_noise_rms_m_s2``, RMS over the
recorded band, white) goes through the same inversion as the run: the run's
accelerations (same channels, sampling, speed, odometry and QC mask) are
replaced by Gaussian noise of that RMS and estimated; its band peak-to-peak
per chainage window is the floor ``F`` (stored in the ``variants`` table as
source ``floor``; a day's floor is the energy mean over its runs).

**Correction** (the background-noise rule of acoustic measurements, e.g.
ISO 3744 §8.2.3, which EN 15610's roughness measurement follows for its
measurement system's noise floor): with ``Δ = L − L_F`` the level above the
floor,

* ``Δ ≥ 10 dB``: the floor adds < 0.5 dB; the level is kept;
* ``3 dB ≤ Δ < 10 dB``: the floor's energy is subtracted,
  ``L_c = 10 lg(10^{L/10} − 10^{L_F/10})`` (signal and noise are independent:
  their energies add);
* ``Δ < 3 dB``: the rail cannot be told from the noise: the window is
  reported **below floor** with the estimate as its upper bound
  (``level_db`` and ``ci_hi_db`` kept, ``ci_lo_db`` = −inf); a coverage count
  takes it as covered when the truth is at most that bound.

The intervals' offsets are kept around the corrected level (a correction of
at most 3 dB).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from estimator.monitoring.averaging import MIN_VALID_SHARE, level_db

__all__ = ["FLOOR_SOURCE", "CORRECT_BELOW_DB", "BELOW_FLOOR_DB", "noise_run", "day_floor", "with_floor"]

FLOOR_SOURCE = "floor"
#: above the floor by this much or more: no correction [dB]
CORRECT_BELOW_DB = 10.0
#: less than this above the floor: below floor (upper bound only) [dB]
BELOW_FLOOR_DB = 3.0


def noise_run(run, noise_rms_m_s2: float, seed: int = 0):
    """The run with its accelerations replaced by white Gaussian sensor noise (same channels, mask, odometry)."""
    rng = np.random.default_rng(seed)
    acc = np.asarray(run.acceleration, float)
    noise = noise_rms_m_s2 * rng.standard_normal(acc.shape)
    noise[~np.isfinite(acc)] = np.nan  # dropouts stay dropouts
    return run.with_step(f"accelerations replaced by white sensor noise {noise_rms_m_s2:g} m/s^2 RMS (noise floor)",
                         acceleration=noise)


def day_floor(variants: pd.DataFrame, unit: str = "window_m", by: tuple[str, ...] = ("date",)) -> pd.DataFrame:
    """The floor per day, rail, band and unit: energy mean of the floor estimates of the day's runs."""
    keys = list(by) + ["rail", "band_mm", unit]
    if variants.empty or "source" not in variants.columns:
        return pd.DataFrame(columns=keys + ["floor_pk_um"])
    f = variants[(variants["source"] == FLOOR_SOURCE) & (variants["valid_share"] >= MIN_VALID_SHARE)]
    if f.empty:
        return pd.DataFrame(columns=keys + ["floor_pk_um"])
    g = f.assign(_e=f["pk_pk_um"] ** 2).groupby(keys, sort=True)["_e"].mean()
    return np.sqrt(g).rename("floor_pk_um").reset_index()


def with_floor(day: pd.DataFrame, floor: pd.DataFrame, unit: str = "window_m", by: tuple[str, ...] = ("date",)
               ) -> pd.DataFrame:
    """Day rows with ``floor_pk_um``, ``above_floor_db``, ``floor_status`` and the corrected level (module docstring).

    Without a floor (no ``sensor_noise_rms_m_s2``) every row gets status ``no floor`` and is unchanged.
    """
    out = day.copy()
    keys = list(by) + ["rail", "band_mm", unit]
    if floor is None or floor.empty or out.empty:
        out["floor_pk_um"] = np.nan
        out["above_floor_db"] = np.nan
        out["floor_status"] = "no floor"
        return out
    out = out.merge(floor[keys + ["floor_pk_um"]], on=keys, how="left")
    L = out["level_db"].to_numpy(float)
    Lf = level_db(out["floor_pk_um"].to_numpy(float))
    d = L - Lf
    status = np.where(~np.isfinite(d), "no floor", np.where(d >= CORRECT_BELOW_DB, "above floor",
                                                             np.where(d >= BELOW_FLOOR_DB, "floor subtracted",
                                                                      "below floor")))
    corr = status == "floor subtracted"
    with np.errstate(invalid="ignore", divide="ignore"):
        Lc = np.where(corr, 10 * np.log10(10 ** (L / 10) - 10 ** (Lf / 10)), L)
    shift = Lc - L
    out["above_floor_db"] = d
    out["floor_status"] = status
    out["level_db"] = Lc
    out["pk_pk_um"] = 10 ** (Lc / 20)
    for c in ("ci_lo_db", "ci_hi_db"):
        if c in out.columns:
            out[c] = out[c].to_numpy(float) + shift
    if "ci_lo_db" in out.columns:
        below = status == "below floor"
        out.loc[below, "ci_lo_db"] = -np.inf
        out["pk_lo_um"] = 10 ** (out["ci_lo_db"] / 20)
        out["pk_hi_um"] = 10 ** (out["ci_hi_db"] / 20)
    return out
