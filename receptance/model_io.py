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
``fe_mode_numbers`` int64 (m,)            the export's own numbers of the kept modes (optional: 1..n of the
                                          export when absent, files before it)
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
import zlib
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
        test_mode=model.test_mode, fe_mode_numbers=np.asarray(fe.mode_numbers, np.int64),
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


def _json_type(v) -> str:
    """How a header value reads in JSON terms (for messages)."""
    if v is None:
        return "null"
    for t, name in ((bool, "true/false"), ((int, float), "a number"), (str, "a string"), (list, "a list"),
                    (dict, "an object")):
        if isinstance(v, t):
            text = repr(v)
            return f"{name} {text if len(text) <= 60 else text[:57] + '...'}"
    return type(v).__name__


def _header_entries(path: Path, header: dict) -> dict:
    """The header's structured entries, each checked for its JSON type before anything is built from it.

    ``points`` is an object of objects ``{name: {"fe_node", "xyz"}}``; ``modifications`` and ``channel_terms``
    are lists of objects; ``test_only`` a list of ``[f_hz, zeta]`` pairs; ``origin``, ``history`` and
    ``fe_history`` lists. A value of another type would otherwise fail deep inside the model's constructors
    with an AttributeError naming no file.
    """
    def bad(key, what, v):
        return ModelFileError(f"{path}: header {key!r} must be {what}, got {_json_type(v)}")

    points = header.get("points", {})
    if points is None:
        points = {}
    if not isinstance(points, dict):
        raise bad("points", "an object {name: {\"fe_node\": ..., \"xyz\": [x, y, z]}}", points)
    for name, p in points.items():
        if not isinstance(p, dict):
            raise bad(f"points.{name}", "an object with 'fe_node' and 'xyz'", p)
        missing = [k for k in ("fe_node", "xyz") if k not in p]
        if missing:
            raise ModelFileError(f"{path}: header point {name!r} lacks {missing}")
        fe_node, xyz = p["fe_node"], p["xyz"]
        if fe_node is not None and (isinstance(fe_node, bool) or not isinstance(fe_node, int)):
            raise bad(f"points.{name}.fe_node", "an integer FE node label (or null)", fe_node)
        if xyz is not None and not (isinstance(xyz, list) and len(xyz) == 3 and all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v) for v in xyz)):
            raise bad(f"points.{name}.xyz", "3 finite coordinates [x, y, z] in m (or null)", xyz)
    out = {"points": points}
    for key in ("modifications", "channel_terms"):
        v = header.get(key, [])
        if v is None:
            v = []
        if not isinstance(v, list):
            raise bad(key, "a list of objects", v)
        for i, e in enumerate(v):
            if not isinstance(e, dict):
                raise bad(f"{key}[{i}]", "an object with a 'kind' and its parameters", e)
        out[key] = v
    test_only = header.get("test_only", [])
    if test_only is None:
        test_only = []
    if not isinstance(test_only, list):
        raise bad("test_only", "a list of [f_hz, zeta] pairs", test_only)
    for i, t in enumerate(test_only):
        if not (isinstance(t, list) and len(t) == 2 and all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v) for v in t)):
            raise bad(f"test_only[{i}]", "a pair [f_hz, zeta] of finite numbers", t)
    out["test_only"] = test_only
    for key in ("origin", "history", "fe_history"):
        v = header.get(key, [])
        if key == "origin" and key not in header:
            raise ModelFileError(f"{path}: header lacks 'origin' (one entry per mode)")
        if not isinstance(v, list):
            raise bad(key, "a list", v)
        if key != "origin" and not all(isinstance(e, str) for e in v):
            raise bad(key, "a list of text entries", v)
        out[key] = v
    for key in ("name", "fe_source", "fe_format", "fe_units"):
        v = header.get(key, "")
        if not isinstance(v, str):
            raise bad(key, "a string", v)
        out[key] = v
    max_hz = header.get("max_hz")
    if max_hz is not None and (isinstance(max_hz, bool) or not isinstance(max_hz, (int, float))):
        raise bad("max_hz", "a frequency in Hz or null", max_hz)
    out["max_hz"] = max_hz
    return out


def _elements(path: Path, arrays: dict) -> tuple[Element, ...]:
    """The FE elements from their CSR arrays, each checked (1-D integers; ``elem_ptr`` one longer than
    ``elem_id``, starting at 0, never decreasing, ending at ``elem_nodes``' size)."""
    names = ("elem_id", "elem_type", "elem_prop", "elem_ptr", "elem_nodes")
    for k in names:
        a = arrays[k]
        if a.ndim != 1 or a.dtype.kind not in "iu":
            raise ModelFileError(f"{path}: array {k!r} must be a 1-D integer array, got {a.dtype} of shape "
                                 f"{a.shape}; inconsistent element arrays")
    e = arrays["elem_id"].size
    for k in ("elem_type", "elem_prop"):
        if arrays[k].size != e:
            raise ModelFileError(f"{path}: array {k!r} has {arrays[k].size} entries for {e} elements ('elem_id'); "
                                 "inconsistent element arrays")
    ptr, nodes = arrays["elem_ptr"], arrays["elem_nodes"]
    if ptr.size != e + 1:
        raise ModelFileError(f"{path}: array 'elem_ptr' has {ptr.size} entries, expected {e + 1} (one more than "
                             f"the {e} elements of 'elem_id'); inconsistent element arrays")
    if ptr[0] != 0 or np.any(np.diff(ptr) < 0) or ptr[-1] != nodes.size:
        raise ModelFileError(f"{path}: array 'elem_ptr' must start at 0, never decrease and end at the "
                             f"{nodes.size} entries of 'elem_nodes' (got {ptr[0]} ... {ptr[-1]}); inconsistent "
                             "element arrays")
    return tuple(Element(int(i), int(t), tuple(int(n) for n in nodes[ptr[k]:ptr[k + 1]]), int(p))
                 for k, (i, t, p) in enumerate(zip(arrays["elem_id"], arrays["elem_type"], arrays["elem_prop"])))


def _finite_arrays(path: Path, arrays: dict) -> None:
    """Refuse NaN/inf in the arrays a model computes with (naming the array and the first entry).

    ``test_mode`` holds NaN for a mode without a test partner: it may be NaN, not infinite.
    """
    for key in ("xyz", "shapes", "fe_freqs_hz", "freqs_hz", "zeta", "test_mode"):
        a = arrays[key]
        if a.dtype.kind not in "fiu":
            raise ModelFileError(f"{path}: array {key!r} must hold numbers, got {a.dtype}")
        bad = ~np.isfinite(a) if key != "test_mode" else np.isinf(a)
        if bad.any():
            where = tuple(int(i) for i in np.argwhere(bad)[0])
            what = {"xyz": "node", "shapes": "mode", "fe_freqs_hz": "mode", "freqs_hz": "mode", "zeta": "mode",
                    "test_mode": "mode"}[key]
            first = where[0]
            extra = ""
            if key == "xyz":
                extra = f" (node {int(arrays['node_ids'][first])})" if arrays["node_ids"].size > first else ""
            elif key == "shapes":
                modes = sorted({int(i) + 1 for i in np.argwhere(bad)[:, 0]})
                extra = f" (mode(s) {modes[:10]}{' ...' if len(modes) > 10 else ''})"
            raise ModelFileError(f"{path}: array {key!r} holds {int(bad.sum())} non-finite value(s) (NaN/inf), "
                                 f"first at {what} index {first}{extra}; a hybrid model's "
                                 f"{'coordinates' if key == 'xyz' else 'modal data'} must be finite")
    for key in ("node_ids", "fe_mode"):
        if arrays[key].dtype.kind not in "iu":
            raise ModelFileError(f"{path}: array {key!r} must hold integers, got {arrays[key].dtype}")


def load_model(path: str | Path) -> ModalModel:
    """Read a hybrid model written by :func:`save_model`.

    Raises
    ------
    ModelFileError
        Not an npz archive (a single ``.npy`` array, a zip of other files, a corrupt member), another format,
        a newer version, a header that is not a JSON object or whose entries have the wrong JSON type, missing
        or inconsistent arrays (element arrays, shapes), NaN/inf in the coordinates, shapes, frequencies or
        damping, unknown modification kinds (the message names the file and the entry or array).
    """
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            if not isinstance(z, np.lib.npyio.NpzFile):
                raise ModelFileError(f"{path}: a single .npy array, not a .npz hybrid-model archive")
            arrays = {k: z[k] for k in z.files}
    except ModelFileError:
        raise
    except FileNotFoundError:
        raise ModelFileError(f"{path}: no such hybrid-model file") from None
    except TypeError:
        # np.load returns an ndarray for a .npy file, which is no context manager
        raise ModelFileError(f"{path}: a single .npy array, not a .npz hybrid-model archive") from None
    except (OSError, ValueError, zipfile.BadZipFile, EOFError, zlib.error, NotImplementedError) as exc:
        raise ModelFileError(f"{path}: not a readable .npz hybrid-model file ({type(exc).__name__}: {exc}); the "
                             "file may be truncated or corrupt") from exc
    not_arrays = sorted(k for k, v in arrays.items() if not isinstance(v, np.ndarray))
    if not_arrays and len(not_arrays) == len(arrays):
        raise ModelFileError(f"{path}: a zip archive without NumPy arrays (members {not_arrays[:10]}), not a .npz "
                             "hybrid-model file")
    if not_arrays:
        raise ModelFileError(f"{path}: member(s) {not_arrays[:10]} of the archive are not NumPy .npy arrays; not a "
                             f"readable {FORMAT} file (corrupt or edited)")
    if "header" not in arrays:
        raise ModelFileError(f"{path}: no 'header' entry; not a {FORMAT} file (it holds {sorted(arrays)[:10]})")
    if arrays["header"].ndim != 0 or arrays["header"].dtype.kind != "U":
        raise ModelFileError(f"{path}: the 'header' entry must be one JSON text, got {arrays['header'].dtype} of "
                             f"shape {arrays['header'].shape}")
    try:
        header = json.loads(str(arrays["header"]))
    except (json.JSONDecodeError, RecursionError) as exc:
        raise ModelFileError(f"{path}: header is not valid JSON ({exc})") from None
    if not isinstance(header, dict):
        raise ModelFileError(f"{path}: the header must be a JSON object {{\"format\": {FORMAT!r}, ...}}, got "
                             f"{_json_type(header)}")
    if header.get("format") != FORMAT:
        raise ModelFileError(f"{path}: format {header.get('format')!r}, expected {FORMAT!r}")
    version = header.get("version")
    if not isinstance(version, int) or isinstance(version, bool) or version > VERSION or version < 1:
        raise ModelFileError(f"{path}: file version {version!r}; this railmodal reads {FORMAT} version <= {VERSION}")
    need = ("node_ids", "xyz", "shapes", "fe_freqs_hz", "freqs_hz", "zeta", "fe_mode", "test_mode", "elem_id",
            "elem_type", "elem_prop", "elem_ptr", "elem_nodes")
    missing = [k for k in need if k not in arrays]
    if missing:
        raise ModelFileError(f"{path}: missing array(s) {missing}")
    h = _header_entries(path, header)
    elements = _elements(path, arrays)
    _finite_arrays(path, arrays)
    m = arrays["fe_freqs_hz"].size
    try:
        numbers = arrays.get("fe_mode_numbers")
        fe = FEModes(arrays["node_ids"], arrays["xyz"], elements, arrays["fe_freqs_hz"], arrays["shapes"], np.ones(m),
                     source=h["fe_source"], format=h["fe_format"], units=h["fe_units"],
                     history=tuple(h["fe_history"]),
                     mode_numbers=None if numbers is None else np.asarray(numbers))
        mods = []
        for i, d in enumerate(h["modifications"]):
            try:
                mods.append(modification_from_dict(d))
            except (ModificationError, ValueError, KeyError, TypeError) as exc:
                raise ModelFileError(f"{path}: header modifications[{i}] ({d.get('kind')!r}): {exc}") from None
        points = {n: Point(n, p["fe_node"], p["xyz"]) for n, p in h["points"].items()}
        terms = []
        for i, t in enumerate(h["channel_terms"]):
            try:
                terms.append(_terms_from_json(t))
            except (ValueError, KeyError, TypeError, IndexError, AttributeError) as exc:
                raise ModelFileError(f"{path}: header channel_terms[{i}] cannot be read ({type(exc).__name__}: "
                                     f"{exc}); expected {{\"kind\", \"setup\", \"lower\": {{channel: [re, im]}}, "
                                     "\"upper\", \"modes\": [[f_hz, zeta, {channel: [re, im]}], ...]}") from None
        return ModalModel(fe, arrays["freqs_hz"], arrays["zeta"], tuple(h["origin"]), arrays["fe_mode"],
                          arrays["test_mode"], points=points, modifications=tuple(mods), name=h["name"],
                          channel_terms=tuple(terms), max_hz=h["max_hz"],
                          test_only=tuple(tuple(t) for t in h["test_only"]),
                          history=tuple(h["history"]) + (f"read from {path}",))
    except ModelFileError:
        raise
    except (ModificationError, ValueError, KeyError, TypeError, IndexError) as exc:
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
