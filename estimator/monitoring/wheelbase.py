"""A bogie's wheelbase shared between its runs: runs whose own measurement fails use the bogie's known one.

The single-run estimator measures the wheelbase of the instrumented bogie by
cross-correlating the leading and trailing wheelsets' roughness estimates
(:mod:`estimator.workflow`, step 6) and refuses a run whose correlation is too
weak to trust (smooth rail, a short run, masked stretches). The wheelbase of a
bogie is a fixed dimension of the vehicle: it does not change between runs.
In a batch, or a store that already holds the bogie's runs, a run whose own
measurement fails is therefore processed again with the bogie's wheelbase:

1. given in the configuration (``EstimatorConfig.wheelbase_m`` /
   ``--wheelbase``): every run uses it and nothing is measured;
2. otherwise the **median of the wheelbases measured confidently** on the
   bogie's other runs (rows whose ``wheelbase_source`` starts with
   ``measured``), from this batch and the store. The bogie is identified by
   the run header's ``train`` and ``bogie``. Measurements that scatter by more
   than :data:`MAX_SPREAD_M` (max − min) do not describe one bogie (a header
   naming two vehicles alike): no fallback is used then, and the run keeps its
   failure with the reason.

The run's ``wheelbase_source`` column states which one was used
(``measured (lead/trail cross-correlation 0.87)``, ``given``, or ``bogie
<train> / <bogie>: median of N runs measured in this store``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np
import pandas as pd

from estimator.errors import WheelbaseError

__all__ = ["BogieWheelbase", "bogie_key", "known_wheelbases", "is_wheelbase_failure", "MAX_SPREAD_M"]

#: largest spread (max − min) of one bogie's measured wheelbases still taken as one dimension [m]; the measurement's
#: resolution is a fraction of the shortest wavelength resolved (~10 mm), a wrong bogie differs by decimetres
MAX_SPREAD_M = 0.05


@dataclass(frozen=True)
class BogieWheelbase:
    """A bogie's wheelbase from its other runs: value, number of runs, spread and a sentence saying so."""

    train: str
    bogie: str
    wheelbase_m: float
    runs: int
    spread_m: float

    @property
    def source(self) -> str:
        return (f"bogie {self.train or '?'} / {self.bogie or '?'}: median of {self.runs} run(s) measured in this "
                f"batch and store ({self.wheelbase_m:.3f} m, spread {1e3 * self.spread_m:.0f} mm)")


def bogie_key(header: Mapping) -> tuple[str, str]:
    """``(train, bogie)`` of a run header (empty strings where the header does not say)."""
    return str(header.get("train") or ""), str(header.get("bogie") or "")


def is_wheelbase_failure(error_type: str) -> bool:
    """Whether a run's estimate failed only because its wheelbase could not be measured: the class name of the
    error it failed on (``RunResult.error_type``) is the estimator's :class:`~estimator.errors.WheelbaseError`."""
    return error_type == WheelbaseError.__name__


def known_wheelbases(runs: pd.DataFrame, max_spread_m: float = MAX_SPREAD_M) -> dict[tuple[str, str], BogieWheelbase]:
    """Per bogie, the median of the wheelbases measured confidently on its runs (module docstring).

    Parameters
    ----------
    runs : pandas.DataFrame
        Run rows (``run_id, train, bogie, wheelbase_m, wheelbase_source``); rows without a source are ignored.
    max_spread_m : float
        A bogie whose measurements spread more than this gets no fallback.
    """
    out: dict[tuple[str, str], BogieWheelbase] = {}
    if runs is None or runs.empty or "wheelbase_source" not in runs.columns:
        return out
    r = runs.drop_duplicates("run_id")
    r = r[r["wheelbase_source"].astype(str).str.startswith("measured") & np.isfinite(r["wheelbase_m"].astype(float))]
    for (train, bogie), g in r.groupby([r["train"].astype(str), r["bogie"].astype(str)], sort=True):
        w = g["wheelbase_m"].to_numpy(float)
        spread = float(w.max() - w.min()) if w.size else math.nan
        if w.size and spread <= max_spread_m:
            out[(train, bogie)] = BogieWheelbase(train, bogie, float(np.median(w)), int(w.size), spread)
    return out
