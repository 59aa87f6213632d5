"""The calibrated model on disk, versioned, for the monitoring store and later estimates.

A calibrated-model folder holds the wheelset model file unchanged (the field
effects do not touch the wheelset's modes) and ``field_calibration.json``:
format and version, the field state (every accepted effect in physical
terms), the site and day it was calibrated on, the SHA-256 of the model file
it applies to, and ``version`` = ``<model hash>+cal<hash of the state>``:
the key under which the monitoring store can keep the calibrated results
apart from the nominal ones. :func:`load_calibration` refuses a newer
format or a model file that is not the one calibrated;
:func:`calibrated_field_model` turns a
:class:`~estimator.workflow.FieldModel` prepared from that model file into the
calibrated one (the single-run estimate's and the store's path alike).
"""

from __future__ import annotations

import hashlib
import json
import math
import shutil
from dataclasses import replace
from pathlib import Path

from estimator.diagnosis.errors import CalibrationFileError
from estimator.diagnosis.state import FieldState, field_model_for
from estimator.monitoring.records import file_hash

__all__ = ["FORMAT", "FORMAT_VERSION", "save_calibration", "load_calibration", "calibration_for_model",
           "calibrated_field_model", "calibration_version"]

FORMAT = "railmodal-field-calibration"
FORMAT_VERSION = 1
_MAX_BYTES = 5_000_000


def calibration_version(model_hash: str, state: FieldState) -> str:
    """``<model hash>+cal<first 8 hex digits of SHA-256 of the state's JSON>`` (``+nominal`` when empty)."""
    if state.is_nominal:
        return f"{model_hash}+nominal"
    blob = json.dumps(state.as_dict(), sort_keys=True).encode()
    return f"{model_hash}+cal{hashlib.sha256(blob).hexdigest()[:8]}"


def save_calibration(folder, model_file, state: FieldState, *, site, date: str, extra: dict | None = None) -> Path:
    """Write a calibrated-model folder (module docstring); returns the JSON file's path."""
    d = Path(folder)
    d.mkdir(parents=True, exist_ok=True)
    src = Path(model_file)
    shutil.copyfile(src, d / src.name)
    mh = file_hash(src)
    doc = {"format": FORMAT, "format_version": FORMAT_VERSION, "version": calibration_version(mh, state),
           "model_file": src.name, "model_hash": mh, "site_m": [float(site[0]), float(site[1])],
           "calibration_date": date, "state": state.as_dict(), **(extra or {})}
    p = d / "field_calibration.json"
    p.write_text(json.dumps(doc, indent=2, default=float))
    return p


def load_calibration(folder) -> tuple[FieldState, dict]:
    """``(state, document)`` of a calibrated-model folder; checks format, version and the model file's hash."""
    d = Path(folder)
    p = d / "field_calibration.json" if d.is_dir() else d
    if not p.is_file():
        raise CalibrationFileError(f"{p}: no field_calibration.json there")
    if p.stat().st_size > _MAX_BYTES:
        raise CalibrationFileError(f"{p}: {p.stat().st_size} bytes; a calibration file is at most {_MAX_BYTES}")
    try:
        doc = json.loads(p.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise CalibrationFileError(f"{p}: not a JSON calibration file ({exc})") from exc
    if doc.get("format") != FORMAT:
        raise CalibrationFileError(f"{p}: format {doc.get('format')!r}, expected {FORMAT!r}")
    if not isinstance(doc.get("format_version"), int) or doc["format_version"] > FORMAT_VERSION:
        raise CalibrationFileError(f"{p}: format version {doc.get('format_version')!r}; this toolkit reads up to "
                                   f"{FORMAT_VERSION}")
    model = p.parent / str(doc.get("model_file", ""))
    if model.is_file() and (mh := file_hash(model)) != doc.get("model_hash"):
        raise CalibrationFileError(f"{p}: the model file {model.name} is not the one calibrated (hash "
                                   f"{mh} != {doc.get('model_hash')}): replaced, edited or damaged since")
    if not isinstance(doc.get("state"), dict):
        raise CalibrationFileError(f"{p}: 'state' must be an object of field effects, got "
                                   f"{type(doc.get('state')).__name__}")
    try:
        state = FieldState.from_dict(doc["state"])
    except KeyError as exc:
        raise CalibrationFileError(f"{p}: field state unreadable (an entry lacks {exc})") from None
    except (TypeError, ValueError, AttributeError) as exc:
        raise CalibrationFileError(f"{p}: field state unreadable ({exc})") from None
    _check_state(state, p)
    return state, doc


#: a sensor offset beyond this is not a placement error but another sensor or a unit slip [m]
MAX_SENSOR_OFFSET_M = 0.5


def _check_state(state: FieldState, p: Path) -> None:
    """Refuse a state no diagnosis writes, naming the file and the entry (a hand-edited or damaged file)."""
    from estimator.diagnosis.state import TRACKFORM_FACTORS

    if state.supports not in ("continuous", "discrete"):
        raise CalibrationFileError(f"{p}: supports must be 'continuous' or 'discrete', got {state.supports!r}")
    for i, c in enumerate(state.trackform_changes):
        where = f"{p}: trackform_changes[{i}]"
        if not (math.isfinite(c.from_m) and math.isfinite(c.to_m) and c.from_m < c.to_m):
            raise CalibrationFileError(f"{where}: the stretch {c.from_m:g}-{c.to_m:g} m must run towards increasing "
                                       "chainage")
        for name, mult in c.factors:
            if name not in TRACKFORM_FACTORS:
                raise CalibrationFileError(f"{where}: factor {name!r} is not one of {sorted(TRACKFORM_FACTORS)}")
            if not (math.isfinite(mult) and mult > 0):
                raise CalibrationFileError(f"{where}: factor {name!r} = {mult:g} must be a positive number")
    for ch, *off in state.sensor_offsets:
        if not all(math.isfinite(v) and abs(v) <= MAX_SENSOR_OFFSET_M for v in off):
            raise CalibrationFileError(f"{p}: sensor_offsets of {ch!r}: {[round(v, 4) for v in off]} m; a placement "
                                       f"error is finite and within {MAX_SENSOR_OFFSET_M:g} m")
    for curve, role, *g in state.curve_angles:
        if not all(math.isfinite(v) and abs(v) < math.pi / 2 for v in g):
            raise CalibrationFileError(f"{p}: curve_angles of curve {curve!r} ({role}): contact angles must be finite "
                                       "and within ±90°")
    if state.wheel_load_N is not None and not (math.isfinite(state.wheel_load_N) and state.wheel_load_N > 0):
        raise CalibrationFileError(f"{p}: wheel_load_N {state.wheel_load_N:g} must be a positive number")
    for value, what in ((state.support_spacing_m, "support_spacing_m"), (state.loss_reference_hz, "loss_reference_hz")):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise CalibrationFileError(f"{p}: {what} {value:g} must be a positive number")


def calibration_for_model(folder, model_file) -> tuple[FieldState, dict]:
    """:func:`load_calibration`, refused unless the calibration was made for ``model_file`` (same SHA-256).

    Raises
    ------
    CalibrationFileError
        Unreadable, or made for another model file (both hashes are named).
    """
    state, doc = load_calibration(folder)
    mh = file_hash(Path(model_file))
    if doc.get("model_hash") != mh:
        raise CalibrationFileError(f"{folder}: calibrates the model with hash {doc.get('model_hash')}, not "
                                   f"{Path(model_file).name} (hash {mh}); run 'railmodal field diagnose' with this "
                                   f"model")
    return state, doc


def calibrated_field_model(fm, model_file, folder):
    """The :class:`~estimator.workflow.FieldModel` ``fm`` with the calibration of ``folder`` applied.

    Parameters
    ----------
    fm : FieldModel
        Prepared from ``model_file`` (:func:`estimator.workflow.prepare`).
    model_file : str or Path
        The wheelset model file ``fm`` was prepared from: the calibration must have been made for it.
    folder : str or Path
        A calibrated-model folder (``railmodal field diagnose``) or its ``field_calibration.json``.

    Returns
    -------
    field_model : FieldModel
        With the calibration's field state applied and named first in its ``provenance``.
    version : str
        ``<model hash>+cal<state hash>`` (:func:`calibration_version`).

    Raises
    ------
    CalibrationFileError
        The calibration is unreadable, or was made for another model file (both hashes are named).
    """
    state, doc = calibration_for_model(folder, model_file)
    version = calibration_version(doc["model_hash"], state)
    site = doc.get("site_m") or ["?", "?"]
    note = (f"field calibration {version} ({folder}; site {site[0]}-{site[1]} m, "
            f"{doc.get('calibration_date', 'date not stated')}): {state.summary()}")
    out = field_model_for(fm, state)
    return replace(out, provenance=(*fm.provenance, note)), version
