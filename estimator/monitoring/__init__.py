"""estimator.monitoring — months of runs: alignment, averaging, confidence, store, trends, grinding, forecast.

The instrumented train passes the same stretch many times a day, every day
(thesis §4.3.3–4.3.6). One run is noisy and sensitive to speed, modal
parameters and sensor placement; the value is in many runs:

* :mod:`~estimator.monitoring.alignment` — runs aligned to the line's welds
  and crossings and to a day's reference run (piecewise offset and scale);
* :mod:`~estimator.monitoring.averaging` — energy averages per day and rail,
  weighted by run quality;
* :mod:`~estimator.monitoring.variants` and :mod:`~estimator.monitoring.confidence` —
  intervals from run-to-run scatter, perturbed models, shifted sensors, the
  contact's load and geometry and the track's supports;
* :mod:`~estimator.monitoring.floor` — the estimate's noise floor (sensor
  noise through the same inversion), subtracted or reported as a bound;
* :mod:`~estimator.monitoring.outliers` — estimates far from their day's
  others left out of the day averages;
* :mod:`~estimator.monitoring.wheelbase` — a bogie's wheelbase shared between
  its runs;
* :mod:`~estimator.monitoring.consistency` — leading vs trailing, the two
  directions, left–right cross-talk;
* :mod:`~estimator.monitoring.store` — the partitioned Parquet store;
* :mod:`~estimator.monitoring.trends`, :mod:`~estimator.monitoring.grinding` —
  growth, threshold-crossing forecast, grinding events and their effect;
* :mod:`~estimator.monitoring.reference` — trolley comparison;
* :mod:`~estimator.monitoring.workflow` — :func:`ingest`, :func:`monitor`,
  :func:`reprocess`; :mod:`~estimator.monitoring.report` and the plot modules.

In Python::

    from estimator.monitoring import IngestSpec, ingest, monitor
    spec = IngestSpec("hybrid_model.npz", "campaign/sensors.csv", line="campaign/line.json")
    ingest(sorted(Path("campaign/runs").rglob("*.mf4")), spec, "store/")
    state = monitor("store/", line_file="campaign/line.json")
    state.forecast          # when each section crosses its threshold

A trolley record of a calibration site adds the estimator's measured error to every window's interval::

    from estimator.monitoring import reference_calibration
    from estimator.monitoring.reference import compare_reference
    cal = reference_calibration(compare_reference("store/", "trolley/2024-03-04.csv").windows, site=(500, 680))
    state = monitor("store/", line_file="campaign/line.json", calibration=cal)
"""

from estimator.monitoring.alignment import Alignment, AlignmentStage, FeatureProfile, ShiftFit, align_profiles, \
    align_to_line, feature_profile
from estimator.monitoring.averaging import day_average, section_table
from estimator.monitoring.config import MonitoringConfig
from estimator.monitoring.confidence import (coverage, reference_calibration, variant_deltas, variant_spread,
                                            with_intervals, with_reference)
from estimator.monitoring.consistency import consistency_checks
from estimator.monitoring.errors import (AlignmentError, MonitoringConfigError, MonitoringError, StoreError,
                                         TrolleyReferenceError)
from estimator.monitoring.grinding import detect_grinding, grinding_effect
from estimator.monitoring.store import MonitoringStore
from estimator.monitoring.trends import forecast, growth
from estimator.monitoring.workflow import (DayReference, IngestResult, IngestSpec, MonitorResult, RunResult, ingest,
                                           monitor, process_run, reprocess, update_days)

__all__ = [
    "Alignment", "AlignmentStage", "FeatureProfile", "ShiftFit", "align_profiles", "align_to_line", "feature_profile",
    "day_average", "section_table", "MonitoringConfig", "coverage", "variant_deltas", "variant_spread",
    "with_intervals", "reference_calibration", "with_reference", "consistency_checks", "AlignmentError",
    "MonitoringConfigError", "MonitoringError",
    "StoreError", "TrolleyReferenceError", "detect_grinding", "grinding_effect", "MonitoringStore", "forecast",
    "growth", "DayReference", "IngestResult", "IngestSpec", "MonitorResult", "RunResult", "ingest", "monitor",
    "process_run", "reprocess", "update_days",
]
