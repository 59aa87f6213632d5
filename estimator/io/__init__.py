"""Reading field data: run files through a format registry, sensor tables, line descriptions, trolley files."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from estimator.io.assemble import assemble_run
from estimator.io.line import Curve, LineDescription, TrackSection, read_line, read_trolley
from estimator.io.registry import RawChannel, RawRecording, formats, read_raw, register_format, sniff_format
from estimator.io.sensors import check_sensors, read_sensors
from estimator.io.tabular import write_run_table
from estimator.run import Run

__all__ = ["read_run", "read_sensors", "check_sensors", "read_line", "read_trolley", "formats", "register_format",
           "sniff_format", "RawChannel", "RawRecording", "LineDescription", "Curve", "TrackSection",
           "write_run_table"]


def read_run(path, sensors, format: str | None = None, *, fs: float | None = None, direction: str | None = None,
             apply_sensitivity: bool = True) -> Run:
    """Read one run file into a validated :class:`~estimator.run.Run`.

    Parameters
    ----------
    path : str or Path
        Run file (MDF 4, Parquet or CSV; see :mod:`estimator.io.registry`).
    sensors : str, Path or pandas.DataFrame
        Sensor table (``sensors.csv`` of the field contract), read and validated.
    format : str, optional
        Force a format (``mdf4``, ``parquet``, ``csv``); sniffed when None.
    fs : float, optional
        Expected acceleration sampling rate [Hz]; channels at another rate are
        rejected (default: the most common rate of the file's accelerations).
    direction : {"forward", "backward"}, optional
        Override the header's direction of travel.
    apply_sensitivity : bool
        Convert the accelerations to m/s² (recorded in the history).

    Raises
    ------
    FileNotFoundError, UnknownFormatError, RunFileError, SensorTableError, ChannelError, OdometryError
    """
    table = sensors if isinstance(sensors, pd.DataFrame) else read_sensors(sensors)
    if isinstance(sensors, pd.DataFrame):
        table = check_sensors(sensors)
    raw, fmt = read_raw(path, format)
    run = assemble_run(raw, table, str(Path(path)), fmt, fs=fs, direction=direction)
    return run.apply_sensitivities() if apply_sensitivity else run
