"""estimator — rail irregularity estimation from axlebox accelerations.

Role in the data flow (``shared/DESIGN.md``): the last link. Turns axlebox
accelerations of an in-service train (with position and speed) into rail
irregularity profiles through the transfer functions of :mod:`receptance`,
computes EN 13231-3 band indexes (thesis Table 4.1, eq. 4.1) and EN 15610
spectra, separates wheel from rail roughness, and names the likely
corrugation mechanism (thesis Table 1.1).

One run, in Python::

    from estimator import prepare, estimate_run
    fm = prepare("model/hybrid_model.npz", "campaign/sensors.csv", line="campaign/line.json")
    est = estimate_run("campaign/runs/2026-01-05/r01.mf4", fm)
    est.indexes            # EN 13231-3 band indexes per wheelset, model, rail, stretch
    est.spectra            # EN 15610 one-third-octave levels with the ISO 3095 limit
    est.corrugation        # corrugated stretches, dominant wavelength, mechanism

Subpackages: :mod:`estimator.io` (run files, sensor tables, line, trolley),
:mod:`estimator.standards` (EN 13231-3, EN 15610, ISO 3095),
:mod:`estimator.monitoring` (months of runs: alignment, averaging, confidence,
the monitoring store, trends, grinding, forecast); :mod:`estimator.fleet`
runs batches on Dask; :mod:`estimator.diagnosis` compares with a trolley
reference at a calibration site and finds, fits and validates the missing
field effects (issue 15).
"""

from estimator.config import EstimatorConfig, parse_models
from estimator.errors import (ChannelError, ConfigurationError, EstimatorError, NoValidDataError, OdometryError,
                              RunFileError, SensorTableError, UnknownFormatError, WheelbaseError, WheelsetModelError)
from estimator.io import read_line, read_run, read_sensors, read_trolley
from estimator.orientation import orientation
from estimator.qc import check_run
from estimator.results import FieldEstimate, ProfileEstimate
from estimator.run import Odometry, QCEvent, QCMask, Run, RunHeader
from estimator.spatial import odometry_track
from estimator.workflow import FieldModel, estimate_run, prepare

__all__ = [
    "EstimatorConfig", "parse_models",
    "ChannelError", "ConfigurationError", "EstimatorError", "NoValidDataError", "OdometryError", "RunFileError",
    "SensorTableError", "UnknownFormatError", "WheelbaseError", "WheelsetModelError",
    "read_line", "read_run", "read_sensors", "read_trolley",
    "orientation", "check_run", "odometry_track",
    "FieldEstimate", "ProfileEstimate",
    "Odometry", "QCEvent", "QCMask", "Run", "RunHeader",
    "FieldModel", "estimate_run", "prepare",
]
