"""Hybrid-model files: one NumPy ``.npz`` archive with a JSON header, versioned.

Format ``railmodal.hybrid_model``, version 1 (all arrays SI units):

=================  =====================  ===============================================
key                shape / type           content
=================  =====================  ===============================================
``header``         0-d str (JSON)         ``{"format": "railmodal.hybrid_model", "version": 1,
                                          "name", "origin": [...], "points": {name: {fe_node,
                                          xyz}}, "modifications": [{"kind", ...params}],
                                          "channel_terms": [{"kind", "setup", "lower", "upper",
                                          "modes"}] (complex values as [re, im]),
                                          "max_hz" (null: every mode), "test_only":
                                          [[f_hz, zeta], ...] (measured modes without FE partner),
                                          "history": [...], "fe_source", "fe_format",
                                          "fe_units", "fe_history": [...], "created"}``
``node_ids``       int64 (n,)             FE node labels
``xyz``            float64 (n, 3)         node coordinates [m]
``shapes``         float64 (m, n, 3|6)    mass-normalised shapes of the kept modes
``fe_freqs_hz``    float64 (m,)           FE natural frequencies [Hz]
``freqs_hz``       float64 (m,)           model frequencies (test where paired) [Hz]
``zeta``           float64 (m,)           modal damping ratios
``fe_mode``        int64 (m,)             1-based mode number in the FE export
``test_mode``      float64 (m,)           1-based paired test mode (NaN: none)
``elem_id``        int64 (e,)             element labels (UFF 2412)
``elem_type``      int64 (e,)             FE descriptor id
``elem_prop``      int64 (e,)             physical property
``elem_ptr``       int64 (e + 1,)         element e's nodes are ``elem_nodes[ptr[e]:ptr[e+1]]``
``elem_nodes``     int64 (sum)            node labels
=================  =====================  ===============================================

Readers refuse files of another format or a newer version with a message
that says which version they read.  Modifications are stored by ``kind`` and
parameters and rebuilt through :data:`receptance.modification.MODIFICATIONS`.
"""

from __future__ import annotations

import datetime as _dt
import json
import zipfile
from pathlib import Path

import numpy as np

from fem_import.modes import Element, FEModes
from receptance.dofs import Point
from receptance.modal_model import ChannelTerms, ModalModel
from receptance.modification import ModificationError, modification_from_dict
# registers the kinds the catalogued effects add (rig_springs, bearing_bodies, seat_joints...) so that a diagnosed
# model file loads without importing the diagnosis
import receptance.effect_modifications  # noqa: E402,F401

__all__ = ["save_model", "load_model", "load_service_model", "ModelFileError", "FORMAT", "VERSION"]

FORMAT = "railmodal.hybrid_model"
VERSION = 1


class ModelFileError(ValueError):
    """A hybrid-model file that cannot be read (names the file and what is wrong)."""


def save_model(model: ModalModel, path: str | Path) -> Path:
    """Write ``model`` to ``path`` (``.npz`` appended if missing); returns the path written."""
    path = Path(path)
    if path.suffix != ".npz":
        path = path.with_suffix(path.suffix + ".npz")
    fe = model.fe
    header = {
        "format": FORMAT,
        "version": VERSION,
        "name": model.name,
        "origin": list(model.origin),
        "points": {n: {"fe_node": p.fe_node, "xyz": None if p.xyz is None else list(p.xyz)}
                   for n, p in model.points.items()},
        "modifications": [m.to_dict() for m in model.modifications],
        "channel_terms": [_terms_to_json(t) for t in model.channel_terms],
        "max_hz": model.max_hz,
        "test_only": [list(t) for t in model.test_only],
        "history": list(model.history),
        "fe_source": fe.source,
        "fe_format": fe.format,
        "fe_units": fe.units,
        "fe_history": list(fe.history),
        "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
    }
    ptr = np.cumsum([0] + [len(e.nodes) for e in fe.elements]).astype(np.int64)
    nodes = np.array([n for e in fe.elements for n in e.nodes], np.int64)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(
        path,
        header=np.array(json.dumps(header)),
        node_ids=fe.node_ids, xyz=fe.xyz, shapes=fe.shapes, fe_freqs_hz=fe.freqs_hz,
        freqs_hz=model.freqs_hz, zeta=model.zeta, fe_mode=model.fe_mode.astype(np.int64),
        test_mode=model.test_mode,
        elem_id=np.array([e.element_id for e in fe.elements], np.int64),
        elem_type=np.array([e.fe_descriptor for e in fe.elements], np.int64),
        elem_prop=np.array([e.physical_property for e in fe.elements], np.int64),
        elem_ptr=ptr, elem_nodes=nodes,
    )
    return path


def _cplx(d: dict) -> dict:
    return {k: [float(np.real(v)), float(np.imag(v))] for k, v in d.items()}


def _terms_to_json(t: ChannelTerms) -> dict:
    return {"kind": t.kind, "setup": t.setup, "lower": _cplx(t.lower), "upper": _cplx(t.upper),
            "modes": [[float(f), float(z), _cplx(r)] for f, z, r in t.modes]}


def _terms_from_json(d: dict) -> ChannelTerms:
    back = lambda x: {k: complex(v[0], v[1]) for k, v in x.items()}  # noqa: E731
    return ChannelTerms(d["kind"], d.get("setup", ""), back(d.get("lower", {})), back(d.get("upper", {})),
                        tuple((f, z, back(r)) for f, z, r in d.get("modes", [])))


def load_model(path: str | Path) -> ModalModel:
    """Read a hybrid model written by :func:`save_model`.

    Raises
    ------
    ModelFileError
        Not an npz archive, another format, a newer version, missing arrays,
        unknown modification kinds (the message names the file).
    """
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except FileNotFoundError:
        raise ModelFileError(f"{path}: no such hybrid-model file") from None
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise ModelFileError(f"{path}: not a readable .npz hybrid-model file ({exc})") from exc
    if "header" not in arrays:
        raise ModelFileError(f"{path}: no 'header' entry; not a {FORMAT} file")
    try:
        header = json.loads(str(arrays["header"]))
    except json.JSONDecodeError as exc:
        raise ModelFileError(f"{path}: header is not valid JSON ({exc})") from exc
    if header.get("format") != FORMAT:
        raise ModelFileError(f"{path}: format {header.get('format')!r}, expected {FORMAT!r}")
    version = header.get("version")
    if not isinstance(version, int) or version > VERSION or version < 1:
        raise ModelFileError(f"{path}: file version {version!r}; this railmodal reads {FORMAT} version <= {VERSION}")
    need = ("node_ids", "xyz", "shapes", "fe_freqs_hz", "freqs_hz", "zeta", "fe_mode", "test_mode", "elem_id",
            "elem_type", "elem_prop", "elem_ptr", "elem_nodes")
    missing = [k for k in need if k not in arrays]
    if missing:
        raise ModelFileError(f"{path}: missing array(s) {missing}")
    ptr, nodes = arrays["elem_ptr"], arrays["elem_nodes"]
    elements = tuple(
        Element(int(i), int(t), tuple(int(n) for n in nodes[ptr[k]:ptr[k + 1]]), int(p))
        for k, (i, t, p) in enumerate(zip(arrays["elem_id"], arrays["elem_type"], arrays["elem_prop"]))
    )
    m = arrays["fe_freqs_hz"].size
    try:
        fe = FEModes(arrays["node_ids"], arrays["xyz"], elements, arrays["fe_freqs_hz"], arrays["shapes"], np.ones(m),
                     source=header.get("fe_source", ""), format=header.get("fe_format", ""),
                     units=header.get("fe_units", ""), history=tuple(header.get("fe_history", ())))
        mods = tuple(modification_from_dict(d) for d in header.get("modifications", []))
        points = {n: Point(n, p["fe_node"], p["xyz"]) for n, p in header.get("points", {}).items()}
        terms = tuple(_terms_from_json(t) for t in header.get("channel_terms", []))
        return ModalModel(fe, arrays["freqs_hz"], arrays["zeta"], tuple(header["origin"]), arrays["fe_mode"],
                          arrays["test_mode"], points=points, modifications=mods, name=header.get("name", ""),
                          channel_terms=terms, max_hz=header.get("max_hz"),
                          test_only=tuple(tuple(t) for t in header.get("test_only", ())),
                          history=tuple(header.get("history", ())) + (f"read from {path}",))
    except (ModificationError, ValueError, KeyError, TypeError) as exc:
        raise ModelFileError(f"{path}: inconsistent hybrid-model file: {exc}") from exc


def load_service_model(path: str | Path, fe: FEModes | None = None) -> ModalModel:
    """The wheelset in service from a diagnosed model file (``lab diagnose``'s ``hybrid_model.npz``).

    The model keeps what belongs to the wheelset (bearings, press fits found
    in the lab) and drops what belonged to the test (rig, sensor masses,
    curve fits at the test's sensors): :meth:`ModalModel.for_service`.

    Parameters
    ----------
    path : str or Path
    fe : FEModes, optional
        The FE export the in-service model is built with: the file must hold
        the same nodes and, for the modes it kept, the same frequencies
        (1e-6), else it belongs to another export.

    Raises
    ------
    ModelFileError
        Unreadable file, or a model of another FE export (names both).
    """
    model = load_model(path)
    if fe is not None:
        same_nodes = model.fe.node_ids.size == fe.node_ids.size and np.array_equal(np.sort(model.fe.node_ids),
                                                                                  np.sort(fe.node_ids))
        idx = np.asarray(model.fe_mode, int) - 1
        same_modes = same_nodes and idx.size > 0 and idx.max() < len(fe) and np.allclose(
            model.fe.freqs_hz, fe.freqs_hz[idx], rtol=1e-6, atol=1e-6)
        if not same_modes:
            raise ModelFileError(f"{path}: the diagnosed model was built on another FE export than "
                                 f"{fe.source or 'the one given'} ({model.fe.node_ids.size} nodes, {len(model)} modes "
                                 f"from {model.fe.source or '?'}); give the FE export the diagnosis used")
    return model.for_service()
