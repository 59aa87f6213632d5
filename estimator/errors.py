"""Exception classes of the estimator: each names the file, channel or parameter, what is allowed and what came."""

from __future__ import annotations

__all__ = [
    "EstimatorError",
    "RunFileError",
    "UnknownFormatError",
    "SensorTableError",
    "ChannelError",
    "OdometryError",
    "ConfigurationError",
    "NoValidDataError",
    "WheelbaseError",
    "WheelsetModelError",
]


class EstimatorError(ValueError):
    """Base class of the estimator's errors (a ``ValueError``: bad input, not a bug)."""


class RunFileError(EstimatorError):
    """A run file that cannot be read (truncated, corrupt, missing header fields); names the file."""


class UnknownFormatError(RunFileError):
    """A run file whose format is not in the registry; lists the supported formats."""


class SensorTableError(EstimatorError):
    """An invalid sensor table (``sensors.csv``): names the file, row, column, allowed values and the value."""


class ChannelError(EstimatorError):
    """A channel missing from a run, at a wrong rate, or with a unit that contradicts the sensor table."""


class OdometryError(EstimatorError):
    """Speed or position channels that cannot give a chainage (missing, empty, no motion)."""


class ConfigurationError(EstimatorError):
    """An estimator option outside its range (names the option, the range and the value)."""


class WheelbaseError(ConfigurationError):
    """A bogie's wheelbase could not be measured from the run and was not given (names the run and the
    lead/trail correlation); a batch may retry the run with the wheelbase measured on the bogie's other runs."""


class NoValidDataError(EstimatorError):
    """Quality control left nothing to estimate from (every sample masked); names the run and the reasons."""


class WheelsetModelError(EstimatorError):
    """A wheelset model the field estimate cannot use as it stands: points missing, not in the railway frame, or
    not the size of a railway wheelset in metres (names the model, what was found and the likely unit)."""
