"""Exception classes of the monitoring layer (each names the run, store file or parameter at fault)."""

from __future__ import annotations

from estimator.errors import ConfigurationError, EstimatorError

__all__ = ["MonitoringError", "AlignmentError", "StoreError", "MonitoringConfigError", "TrolleyReferenceError"]


class MonitoringError(EstimatorError):
    """Base class of the monitoring errors (a ``ValueError``: bad input or state, not a bug)."""


class MonitoringConfigError(MonitoringError, ConfigurationError):
    """A monitoring option outside its range (names the option, the range and the value)."""


class AlignmentError(MonitoringError):
    """A run that cannot be aligned along chainage (names the run and the reason)."""


class StoreError(MonitoringError):
    """A monitoring store that cannot be read or written (names the folder or file)."""


class TrolleyReferenceError(MonitoringError):
    """A trolley reference that cannot be compared with the train's estimate (names the file and the reason)."""
