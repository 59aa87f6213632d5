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
                                   f"{mh} != {doc.get('model_hash')})")
    try:
        state = FieldState.from_dict(doc["state"])
    except (KeyError, TypeError, ValueError) as exc:
        raise CalibrationFileError(f"{p}: field state unreadable ({exc})") from exc
    return state, doc


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
