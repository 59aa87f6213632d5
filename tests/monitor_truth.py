"""The virtual line's truth as the monitoring layer's oracle (shared by the line tests and benchmarks/monitor_acceptance.py).

Everything here reads the campaign's truth (``truth/truth.json``, ``truth/rail_roughness/<date>.parquet``: the
unfiltered rail roughness a perfect trolley measures) or regenerates the line's rails for a date between survey
days (``lab_data.line``: the truth's own generator, deterministic for the campaign's seed), and processes it with
the **same** EN 13231-3 code and chainage windows as the train's estimate, so that estimate and truth differ only
by what the measurement gets wrong.
"""

from __future__ import annotations

import datetime as _dt
import json
from functools import lru_cache
from pathlib import Path

import numpy as np
import pandas as pd


def truth_json(camp) -> dict:
    return json.loads((Path(camp) / "truth" / "truth.json").read_text())


def _record(x: np.ndarray, values_m: np.ndarray, date: str, source: str = "truth"):
    from estimator.monitoring.reference import TrolleyRecord

    return TrolleyRecord(source, date, float(x[0]), float(np.median(np.diff(x))), ("L", "R"), values_m)


def record_windows(rec, window_m: float = 1.0, min_valid: float = 0.99) -> pd.DataFrame:
    """EN 13231-3 band pk-pk per chainage window of a truth record (``level_db`` added), fully resolved windows."""
    from estimator import EstimatorConfig
    from estimator.monitoring.averaging import level_db
    from estimator.monitoring.reference import trolley_windows

    tw = trolley_windows(rec, None, EstimatorConfig(), window_m)
    tw = tw[tw["valid_share"] >= min_valid].copy()
    tw["level_db"] = level_db(tw["pk_pk_um"])
    return tw.assign(date=rec.date)


def truth_windows(camp, date: str, window_m: float = 1.0) -> pd.DataFrame:
    """The survey day's true rail roughness per chainage window (``date, rail, band_mm, window_m, pk_pk_um, level_db``)."""
    tr = pd.read_parquet(Path(camp) / "truth" / "rail_roughness" / f"{date}.parquet")
    x = tr["chainage_m"].to_numpy()
    rec = _record(x, np.stack([tr["L_um"].to_numpy(), tr["R_um"].to_numpy()]) * 1e-6, date)
    return record_windows(rec, window_m)


def section_levels(windows: pd.DataFrame, extents: dict[str, tuple[float, float]], window_m: float = 1.0
                   ) -> pd.DataFrame:
    """Energy mean of the windows lying in each section (as the store's day_sections), per date, rail and band."""
    from estimator.monitoring.averaging import energy_mean_db

    rows = []
    for sec, (a, b) in extents.items():
        w = windows[(windows["window_m"] >= a) & (windows["window_m"] + window_m <= b)]
        for (date, rail, band), g in w.groupby(["date", "rail", "band_mm"]):
            L = energy_mean_db(g["level_db"])
            rows.append({"date": date, "section": sec, "rail": rail, "band_mm": band, "level_db": L,
                         "pk_pk_um": 10 ** (L / 20), "windows": len(g)})
    return pd.DataFrame(rows)


@lru_cache(maxsize=4)
def _rails(camp: str, grindings: bool = True):
    from dataclasses import replace

    from lab_data.line.campaign import LineCampaignConfig, plan_line_campaign
    from lab_data.line.roughness import build_rail_roughness

    cfg = dict(truth_json(camp)["config"])
    for k in ("section", "trolley_days"):
        if cfg.get(k) is not None:
            cfg[k] = tuple(cfg[k])
    plan = plan_line_campaign(LineCampaignConfig(**cfg))
    rough = plan.roughness if grindings else replace(plan.roughness, grindings=())
    return build_rail_roughness(plan.line, rough)


def truth_on(camp, date: str, stretch: tuple[float, float], grindings: bool = True):
    """The true rails on any date (between survey days too) over a stretch, as a record (regenerated).

    ``grindings=False``: the rails had the campaign's grinding not been done (growth continuing).
    """
    rails = _rails(str(camp), grindings)
    sl = rails.slice(*stretch)
    return _record(rails.x[sl], rails.on(date)[:, sl], date)


def crossing_date(camp, extent: tuple[float, float], rail: str, band: str, threshold_um: float, start: str,
                  horizon_days: int = 400, window_m: float = 1.0) -> str | None:
    """First date after ``start`` on which the truth's section level reaches ``threshold_um`` (bisection on days).

    The rails are regenerated without the campaign's grinding (the forecast made before it asks when the
    section would cross had it not been ground); the corrugation grows linearly (truth.json
    ``corrugation_growth``), so the section level is monotonic and the bisection exact to a day.
    """
    margin = 5.0  # the band filter's transient stays out of the section's windows
    stretch = (extent[0] - margin, extent[1] + margin)
    d0 = _dt.date.fromisoformat(start)

    def level(days: int) -> float:
        date = (d0 + _dt.timedelta(days=days)).isoformat()
        tw = record_windows(truth_on(camp, date, stretch, grindings=False), window_m)
        s = section_levels(tw, {"s": extent}, window_m)
        s = s[(s["rail"] == rail) & (s["band_mm"] == band)]
        return float(s["pk_pk_um"].iloc[0])

    lo, hi = 0, horizon_days
    if level(lo) >= threshold_um:
        return start
    if level(hi) < threshold_um:
        return None
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if level(mid) >= threshold_um:
            hi = mid
        else:
            lo = mid
    return (d0 + _dt.timedelta(days=hi)).isoformat()
