"""Universal File Format (UFF, "UNV") exporters of the virtual vibration lab.

Two kinds of file are written, exactly as a wheelset modal-test campaign
produces them:

* an FE model with its normal modes (:func:`write_fe_uff`), as exported by the
  FE pre-processor for test planning and FE/EMA correlation, and
* measured time histories (:func:`write_time_histories`), as exported by the
  acquisition front end (one dataset per channel and hit).

Dataset layouts
---------------
All layouts follow the SDRC/I-DEAS universal file descriptions published by
UC-SDRL (https://www.ceas3.uc.edu/sdrluff/, the same text that pyuff prints
with ``pyuff.get_structure_<n>()``).  Every dataset is framed by ``    -1``
lines (``I6``) and starts with its number in columns 1-6.

164 - Units
    Record 1 ``FORMAT(I10,20A1,I10)``: units code (1 = SI), description,
    temperature mode (2 = relative).  Record 2 ``FORMAT(3D25.17)``: factors
    length, force, temperature, then temperature offset.

2411 - Nodes, double precision
    Record 1 ``FORMAT(4I10)``: node label, export coordinate system,
    displacement coordinate system, colour.  Record 2 ``FORMAT(1P3D25.16)``:
    x, y, z.  Both coordinate systems are written as 0 (global).

2412 - Elements
    Record 1 ``FORMAT(6I10)``: element label, FE descriptor id, physical
    property, material property, colour, number of nodes.  For beam
    descriptors (11, 21-24) Record 2 ``FORMAT(3I10)``: orientation node,
    fore-end and aft-end cross-section numbers; then the node labels
    ``FORMAT(8I10)`` (eight per line, wrapped).

55 - Data at nodes (one dataset per mode)
    ID lines 1-5 ``(80A1)``; Record 6 ``FORMAT(6I10)``: model type 1
    (structural), analysis type 2 (normal mode), data characteristic 3
    (6 DOF translation + rotation), specific data type 8 (displacement), data
    type 2 (real), 6 values per node; Record 7 ``FORMAT(8I10)``: 2, 4, load
    case, mode number; Record 8 ``FORMAT(6E13.5)``: frequency [Hz], modal
    mass, viscous and hysteretic damping ratios; then per node Record 9
    ``FORMAT(I10)`` node label and Record 10 ``FORMAT(6E13.5)``
    X, Y, Z, RX, RY, RZ.

58 / 58b - Function at nodal DOF (one dataset per channel and hit)
    ID lines 1-5 ``(80A1)``; Record 6 ``FORMAT(2(I5,I10),2(1X,10A1,I10,I4))``:
    function type, function id, version/sequence number, load case,
    response entity/node/direction, reference entity/node/direction;
    Record 7 ``FORMAT(3I10,3E13.5)``: ordinate data type, number of values,
    abscissa spacing, abscissa minimum, increment, z value; Records 8-11
    ``FORMAT(I10,3I5,2(1X,20A1))``: specific data type, length/force/
    temperature unit exponents, axis label, units label for abscissa,
    ordinate numerator, ordinate denominator and z axis; Record 12 the data.
    In the binary variant 58b the identifier line is
    ``FORMAT(I6,1A1,I6,I6,I12,I12,I6,I6,I12,I12)`` = ``58``, ``b``, byte
    order (1 = little endian), floating-point format (2 = IEEE 754), number
    of ASCII lines (11), number of data bytes, four zeros, and Record 12 is
    raw binary data directly followed by the closing ``    -1`` line.

Precision of the written files
------------------------------
* 2411 coordinates: ``D25.16`` = 17 significant digits, double precision
  round-trips exactly.
* 55 frequencies and shape values: written in the 13-column ``E13``
  fields of the standard layout, but as ``1PE13.6`` (7 significant digits,
  relative rounding error <= 5e-7) instead of the customary ``E13.5``
  (6 digits, <= 5e-6).  Any fixed-column reader (Fortran, pyuff) reads them
  unchanged; a negative value fills all 13 columns, so readers that split
  on white space instead of columns do not work.  Magnitudes below 1e-99
  are written as 0 (a three-digit exponent would not fit in 13 columns);
  magnitudes of 1e99 or more are rejected.
* 58/58b: the time step is written as ``1PE13.6`` (exact for the usual
  2**k x 100 Hz sampling rates, e.g. 1/51200 s = 1.953125E-05); binary
  data are IEEE 754 single precision, little endian (ordinate data type 2),
  exact to float32.  The ASCII variant stores the float32 values as real
  double precision (ordinate data type 4, ``4E20.12``), which also
  round-trips exactly to float32.

Why the writers format the records themselves
---------------------------------------------
pyuff 2.5.8 reads every dataset written here (the tests use it as the
reference reader), but its writers cannot produce these files:

* ``_write58`` with ``binary=1`` always packs doubles (``struct.pack('<d')``)
  even when ``force_double=False`` and the header says single precision
  (ordinate type 2), so the file cannot be read back; in ``mode='overwrite'``
  it reopens the file for the binary part and truncates the header; and
  ``UFF.write_sets`` re-reads the whole file after every dataset, which is
  quadratic (360 datasets x 51200 samples took about 42 s in double
  precision).
* ``_write2412`` writes the beam record only for descriptor 11 while its
  reader expects it for 11 and 21-24, so linear beams (21) written by pyuff
  cannot be read back.
* ``_write55`` writes ``E13.5`` (6 significant digits).
"""

from __future__ import annotations

import math
import numbers
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .validation import (
    MAX_I10,
    check_finite_array as _check_finite_array,
    check_int as _check_int,
    check_labels as _check_labels,
    check_text as _check_text,
    is_int as _is_int,
)

__all__ = [
    "ElementRecord",
    "TimeHistory",
    "FE_DESCRIPTORS",
    "write_fe_uff",
    "write_time_histories",
]

#: FE descriptor ids accepted by :func:`write_fe_uff`:
#: ``descriptor -> (name, minimum node count, maximum node count or None)``.
FE_DESCRIPTORS: dict[int, tuple[str, int, int | None]] = {
    21: ("linear beam", 2, 2),
    94: ("thin shell linear quadrilateral", 4, 4),
    161: ("lumped mass", 1, 1),
    136: ("node-to-node translational spring", 2, 2),
    137: ("node-to-node rotational spring", 2, 2),
    122: ("rigid element", 2, None),
}

# Descriptors that carry the extra beam record (Record 2, FORMAT(3I10)) in
# dataset 2412; this is also the set pyuff's reader treats as beams.
_BEAM_DESCRIPTORS = frozenset({11, 21, 22, 23, 24})

_MAX_I10 = MAX_I10
_MAX_I5 = 99_999              # largest value of an I5 field
_E13_MAX = 1e99               # |x| >= this would need a 3-digit exponent
_E13_TINY = 1e-99             # |x| <  this would need a 3-digit exponent

_UNITS_LINE = "SI units: length m, mass kg, time s, force N; modal mass 1 kg"

# (quantity) -> (specific data type, axis label, {direction class: (unit, exponents)})
# Unit exponents (length, force, temperature) follow the UFF 58 Addendum A
# table; direction class "t" = translational or scalar, "r" = rotational.
_QUANTITIES: dict[str, tuple[int, str, dict[str, tuple[str, tuple[int, int, int]]]]] = {
    "acceleration": (12, "Acceleration",
                     {"t": ("m/s^2", (1, 0, 0)), "r": ("rad/s^2", (0, 0, 0))}),
    "force": (13, "Force",
              {"t": ("N", (0, 1, 0)), "r": ("N*m", (1, 1, 0))}),
}


@dataclass(frozen=True)
class ElementRecord:
    """One finite element of dataset 2412.

    Parameters
    ----------
    element_id : int
        Element label (positive, unique in the model).
    fe_descriptor : int
        UFF 2412 FE descriptor id: 21 linear beam, 94 thin-shell linear
        quadrilateral, 161 lumped mass, 136 node-to-node translational
        spring, 137 node-to-node rotational spring, 122 rigid element (see
        :data:`FE_DESCRIPTORS`).
    physical_property : int
        Physical property table number (>= 0).  For beams it is also written
        as the fore-end and aft-end cross-section number.
    material_property : int
        Material property table number (>= 0).
    color : int
        I-DEAS colour number (>= 0).
    nodes : tuple of int
        Node labels defining the element, in I-DEAS connectivity order.
    """

    element_id: int
    fe_descriptor: int
    physical_property: int
    material_property: int
    color: int
    nodes: tuple[int, ...]


@dataclass(frozen=True, eq=False)
class TimeHistory:
    """One measured channel of one hit, written as one UFF 58 dataset.

    ``eq=False`` because the ``data`` array makes field-wise equality
    ambiguous; instances compare by identity.

    Parameters
    ----------
    hit : int
        Hit (impact) number, the project's "sequence number", 0..99999.
        Written to Record 6 field 3 "Version number, or sequence number"
        (pyuff key ``'ver_num'``) and repeated in ID line 2.
    node : int
        Response node label (Record 6 field 6, pyuff ``'rsp_node'``).
    direction : int
        UFF direction code: +-1..+-3 translations X, Y, Z, +-4..+-6
        rotations about X, Y, Z, 0 scalar / off-axis (pyuff ``'rsp_dir'``).
    quantity : {'acceleration', 'force'}
        Ordinate quantity; specific data type 12 or 13 ("excitation force").
    unit : str
        ``'m/s^2'`` or ``'N'`` for translational and scalar directions,
        ``'rad/s^2'`` or ``'N*m'`` for rotational directions.
    name : str
        Channel name, e.g. ``'axle_03'``; written to ID line 1.
    dt : float
        Sampling interval [s].
    data : numpy.ndarray
        Samples, shape ``(N,)`` with ``N >= 2``; stored as float32.
    ref_node : int, optional
        Reference (force) node, for information (pyuff ``'ref_node'``).
    ref_direction : int, optional
        Reference direction code (pyuff ``'ref_dir'``).
    """

    hit: int
    node: int
    direction: int
    quantity: str
    unit: str
    name: str
    dt: float
    data: np.ndarray
    ref_node: int = 0
    ref_direction: int = 0


def _e13_values(name: str, arr: np.ndarray) -> np.ndarray:
    """Prepare values for 13-column E fields (see module docstring)."""
    big = np.abs(arr) >= _E13_MAX
    if np.any(big):
        bad = np.argwhere(big)[0].tolist()
        raise ValueError(f"{name} must have magnitudes below {_E13_MAX:g} to fit an E13 field, "
                         f"got {arr[tuple(bad)]} at index {bad}")
    return np.where(np.abs(arr) < _E13_TINY, 0.0, arr)


def _dataset(number: int, body: str) -> str:
    return f"{-1:6d}\n{number:6d}\n{body}{-1:6d}\n"


def _d(fmt_value: str) -> str:
    """Fortran D exponent letter (I-DEAS writes ``1P3D25.16``)."""
    return fmt_value.replace("E", "D")


# --------------------------------------------------------------------------
# FE model file: 164, 2411, 2412, 55
# --------------------------------------------------------------------------
def _uff164() -> str:
    rec1 = f"{1:10d}{'SI - mks (Newton)':<20}{2:10d}\n"
    rec2 = _d(f"{1.0:25.17E}{1.0:25.17E}{1.0:25.17E}\n{273.15:25.17E}\n")
    return _dataset(164, rec1 + rec2)


def _uff2411(node_ids: np.ndarray, xyz: np.ndarray) -> str:
    fmt = "%10d%10d%10d%10d\n%25.16E%25.16E%25.16E\n"
    rows = []
    for nid, (x, y, z) in zip(node_ids.tolist(), xyz.tolist()):
        rows.append(fmt % (nid, 0, 0, 1, x, y, z))
    return _dataset(2411, _d("".join(rows)))


def _uff2412(elements: Sequence[ElementRecord]) -> str:
    rows = []
    for el in elements:
        n = len(el.nodes)
        rows.append(f"{el.element_id:10d}{el.fe_descriptor:10d}{el.physical_property:10d}"
                    f"{el.material_property:10d}{el.color:10d}{n:10d}\n")
        if el.fe_descriptor in _BEAM_DESCRIPTORS:
            # No orientation node (0): orientation comes from the section;
            # uniform beam, both cross sections = physical property number.
            rows.append(f"{0:10d}{el.physical_property:10d}{el.physical_property:10d}\n")
        for start in range(0, n, 8):
            rows.append("".join(f"{nid:10d}" for nid in el.nodes[start:start + 8]) + "\n")
    return _dataset(2412, "".join(rows))


def _uff55(mode_number: int, freq: float, node_ids: np.ndarray, shape: np.ndarray,
           model_name: str, description: str) -> str:
    id_lines = [
        model_name,
        description or "NONE",
        _UNITS_LINE,
        "NORMAL MODES (MASS-NORMALISED)",
        f"MODE SHAPE{mode_number:10d} FREQUENCY{freq:13.6E} Hz",
    ]
    head = "".join(f"{s:<80}\n" for s in id_lines)
    head += f"{1:10d}{2:10d}{3:10d}{8:10d}{2:10d}{6:10d}\n"
    head += f"{2:10d}{4:10d}{1:10d}{mode_number:10d}\n"
    head += f"{freq:13.6E}{1.0:13.6E}{0.0:13.6E}{0.0:13.6E}\n"
    flat = []
    for nid, row in zip(node_ids.tolist(), shape.tolist()):
        flat.append(nid)
        flat.extend(row)
    body = ("%10d\n%13.6E%13.6E%13.6E%13.6E%13.6E%13.6E\n" * len(node_ids)) % tuple(flat)
    return _dataset(55, head + body)


def _validate_elements(elements, node_set: set[int]) -> list[ElementRecord]:
    if isinstance(elements, (str, bytes)) or not isinstance(elements, Sequence):
        raise ValueError(f"elements must be a sequence of ElementRecord, got {type(elements).__name__}")
    seen: set[int] = set()
    out = []
    for i, el in enumerate(elements):
        where = f"elements[{i}]"
        if not isinstance(el, ElementRecord):
            raise ValueError(f"{where} must be an ElementRecord, got {type(el).__name__}")
        eid = _check_int(f"{where}.element_id", el.element_id, 1, _MAX_I10)
        if eid in seen:
            raise ValueError(f"{where}.element_id must be unique, got duplicate {eid}")
        seen.add(eid)
        desc = el.fe_descriptor
        if not _is_int(desc) or int(desc) not in FE_DESCRIPTORS:
            raise ValueError(f"{where}.fe_descriptor must be one of {sorted(FE_DESCRIPTORS)}, got {desc!r}")
        desc = int(desc)
        phys = _check_int(f"{where}.physical_property", el.physical_property, 0, _MAX_I10)
        mat = _check_int(f"{where}.material_property", el.material_property, 0, _MAX_I10)
        color = _check_int(f"{where}.color", el.color, 0, _MAX_I10)
        nodes = el.nodes
        if isinstance(nodes, (str, bytes)) or not isinstance(nodes, Sequence):
            raise ValueError(f"{where}.nodes must be a tuple of node labels, got {type(nodes).__name__}")
        name, n_min, n_max = FE_DESCRIPTORS[desc]
        if len(nodes) < n_min or (n_max is not None and len(nodes) > n_max):
            want = str(n_min) if n_min == n_max else f"at least {n_min}"
            raise ValueError(f"{where}.nodes: a {name} (descriptor {desc}) needs {want} nodes, "
                             f"got {len(nodes)}")
        for k, nid in enumerate(nodes):
            if not _is_int(nid) or int(nid) not in node_set:
                raise ValueError(f"{where}.nodes[{k}] must be a label from node_ids, got {nid!r}")
        if len(set(int(n) for n in nodes)) != len(nodes):
            raise ValueError(f"{where}.nodes must not repeat a node, got {tuple(nodes)}")
        out.append(ElementRecord(eid, desc, phys, mat, color, tuple(int(n) for n in nodes)))
    return out


def write_fe_uff(path, node_ids, xyz, elements, freqs_hz, shapes, *, model_name,
                 description="") -> Path:
    """Write an FE model with its normal modes as a universal file.

    Datasets, in order: 164 (units, SI), 2411 (nodes, double precision,
    global coordinate system 0), 2412 (elements; omitted when ``elements`` is
    empty), then one 55 per mode (normal mode, 6 DOF per node, frequency in
    Hz, modal mass 1 = mass-normalised, damping 0, load case 1, mode number
    1..n in the given order).  Rigid-body modes (f = 0) are written like any
    other mode.  Layouts and precision: see the module docstring.

    Parameters
    ----------
    path : str or os.PathLike
        Output file (overwritten).  Conventional suffix ``.unv`` or ``.uff``.
    node_ids : array_like of int, shape (n_nodes,)
        Positive, unique node labels (<= 2**31 - 1).
    xyz : array_like of float, shape (n_nodes, 3)
        Node coordinates [m], finite.
    elements : sequence of ElementRecord
        Elements; node labels must be in ``node_ids``, element ids unique.
    freqs_hz : array_like of float, shape (n_modes,)
        Natural frequencies [Hz], finite, >= 0.
    shapes : array_like of float, shape (n_modes, n_nodes, 6)
        Mass-normalised mode shapes, DOF order X, Y, Z, RX, RY, RZ
        [m/sqrt(kg), rad/sqrt(kg)], finite, magnitudes < 1e99.
    model_name : str
        Model identification, ID line 1 of every dataset 55 (1-80
        printable ASCII characters).
    description : str, optional
        Run identification, ID line 2 (``'NONE'`` when empty).

    Returns
    -------
    pathlib.Path
        The written file.

    Raises
    ------
    ValueError
        If an argument has the wrong shape, type or value; the message names
        the argument and what was received.

    Notes
    -----
    Beams (descriptor 21) get the extra 2412 beam record with orientation
    node 0 and both cross-section numbers equal to ``physical_property``.
    Node labels of an element are written eight per line as the format
    prescribes; pyuff 2.5.8 reads only the first line, so elements with
    more than 8 nodes (possible for rigid elements, 122) need a reader that
    follows the format.
    """
    ids = _check_labels("node_ids", node_ids)
    n_nodes = ids.size
    coords = _check_finite_array("xyz", xyz, (n_nodes, 3))
    elems = _validate_elements(elements, set(ids.tolist()))
    freqs = _check_finite_array("freqs_hz", freqs_hz, (None,))
    if np.any(freqs < 0):
        raise ValueError(f"freqs_hz must be >= 0, got {freqs[freqs < 0][:5].tolist()}")
    freqs = _e13_values("freqs_hz", freqs)
    modes = _check_finite_array("shapes", shapes, (freqs.size, n_nodes, 6))
    modes = _e13_values("shapes", modes)
    _check_text("model_name", model_name, max_len=80)
    _check_text("description", description, max_len=80, allow_empty=True)

    parts = [_uff164(), _uff2411(ids, coords)]
    if elems:
        parts.append(_uff2412(elems))
    for k in range(freqs.size):
        parts.append(_uff55(k + 1, float(freqs[k]), ids, modes[k], model_name, description))
    out = Path(os.fspath(path))
    with open(out, "w", encoding="ascii", newline="\n") as fh:
        fh.writelines(parts)
    return out


# --------------------------------------------------------------------------
# Time histories: 58 / 58b
# --------------------------------------------------------------------------
def _validate_history(i: int, h) -> tuple[np.ndarray, tuple]:
    """Check one history; return its data array (as given) and header fields."""
    where = f"histories[{i}]"
    if not isinstance(h, TimeHistory):
        raise ValueError(f"{where} must be a TimeHistory, got {type(h).__name__}")
    hit = _check_int(f"{where}.hit", h.hit, 0, _MAX_I5)
    node = _check_int(f"{where}.node", h.node, 1, _MAX_I10)
    direction = _check_int(f"{where}.direction", h.direction, -6, 6)
    ref_node = _check_int(f"{where}.ref_node", h.ref_node, 0, _MAX_I10)
    ref_dir = _check_int(f"{where}.ref_direction", h.ref_direction, -6, 6)
    if not isinstance(h.quantity, str) or h.quantity not in _QUANTITIES:
        raise ValueError(f"{where}.quantity must be one of {sorted(_QUANTITIES)}, got {h.quantity!r}")
    spec, label, units = _QUANTITIES[h.quantity]
    dir_class = "r" if abs(direction) >= 4 else "t"
    unit, exps = units[dir_class]
    if h.unit != unit:
        kind = "rotational" if dir_class == "r" else "translational/scalar"
        raise ValueError(f"{where}.unit must be {unit!r} for {h.quantity} in a {kind} direction "
                         f"({direction}), got {h.unit!r}")
    name = _check_text(f"{where}.name", h.name, max_len=80)
    dt = h.dt
    if (not isinstance(dt, numbers.Real) or isinstance(dt, (bool, np.bool_))
            or not math.isfinite(dt) or not _E13_TINY <= dt < _E13_MAX):
        raise ValueError(f"{where}.dt must be a finite positive number of seconds, got {dt!r}")
    data = np.asarray(h.data)
    if data.ndim != 1 or data.size < 2:
        raise ValueError(f"{where}.data must be a 1-D array with at least 2 samples, got shape {data.shape}")
    if not (np.issubdtype(data.dtype, np.floating) or np.issubdtype(data.dtype, np.integer)):
        raise ValueError(f"{where}.data must be real numeric, got dtype {data.dtype}")
    finite = np.isfinite(_as_float32(data))
    if not finite.all():
        k = int(np.argmin(finite))
        raise ValueError(f"{where}.data must be finite and within float32 range, got {data[k]} at index {k}")
    meta = (hit, node, direction, ref_node, ref_dir, spec, label, unit, exps, name, float(dt))
    return data, meta


def _as_float32(data: np.ndarray) -> np.ndarray:
    """Little-endian float32 view or copy (values beyond float32 become inf)."""
    with np.errstate(over="ignore"):
        return data.astype("<f4", copy=False)


def _dir_label(code: int) -> str:
    if code == 0:
        return "S"
    return ("+" if code > 0 else "-") + ("X", "Y", "Z", "RX", "RY", "RZ")[abs(code) - 1]


def _uff58_header(func_id: int, meta: tuple, n: int, binary: bool) -> str:
    hit, node, direction, ref_node, ref_dir, spec, label, unit, exps, name, dt = meta
    if binary:
        # FORMAT(I6,1A1,I6,I6,I12,I12,I6,I6,I12,I12): little endian (1),
        # IEEE 754 (2), 11 ASCII lines follow, n*4 bytes of float32 data.
        ident = f"{58:6d}b{1:6d}{2:6d}{11:12d}{4 * n:12d}{0:6d}{0:6d}{0:12d}{0:12d}"
        ord_type = 2
    else:
        ident = f"{58:6d}"
        ord_type = 4
    quantity = "excitation force" if spec == 13 else "acceleration"
    id_lines = [
        name,
        f"hit {hit} {quantity} rsp {node}:{_dir_label(direction)} ref {ref_node}:{_dir_label(ref_dir)}",
        "NONE",
        f"sampling: dt {dt!r} s, fs {1.0 / dt:.10g} Hz",
        "NONE",
    ]
    lines = [f"{-1:6d}", ident]
    lines += [f"{s:<80}" for s in id_lines]
    # Record 6: func type 1 (time response), func id, sequence number = hit,
    # load case 0 (single point excitation), response and reference DOF.
    lines.append(f"{1:5d}{func_id:10d}{hit:5d}{0:10d} {'NONE':<10}{node:10d}{direction:4d}"
                 f" {'NONE':<10}{ref_node:10d}{ref_dir:4d}")
    # Record 7: ordinate type, N, even spacing, x_min 0, dx, z 0.
    lines.append(f"{ord_type:10d}{n:10d}{1:10d}{0.0:13.6E}{dt:13.6E}{0.0:13.6E}")
    lines.append(f"{17:10d}{0:5d}{0:5d}{0:5d} {'Time':<20} {'s':<20}")
    lines.append(f"{spec:10d}{exps[0]:5d}{exps[1]:5d}{exps[2]:5d} {label:<20} {unit:<20}")
    lines.append(f"{0:10d}{0:5d}{0:5d}{0:5d} {'NONE':<20} {'NONE':<20}")
    lines.append(f"{0:10d}{0:5d}{0:5d}{0:5d} {'NONE':<20} {'NONE':<20}")
    return "\n".join(lines) + "\n"


def _ascii_double(data32: np.ndarray) -> str:
    vals = data32.astype(np.float64).tolist()
    n4, rem = divmod(len(vals), 4)
    text = ("%20.12E%20.12E%20.12E%20.12E\n" * n4) % tuple(vals[:4 * n4])
    if rem:
        text += ("%20.12E" * rem) % tuple(vals[4 * n4:]) + "\n"
    return text


def write_time_histories(path, histories: Sequence[TimeHistory], *, binary=True) -> Path:
    """Write measured time histories, one UFF 58 dataset per history.

    Each dataset is a time response (function type 1) with even abscissa
    spacing starting at 0 s (abscissa: specific data type 17 "time", unit
    s) and ordinate acceleration (12) or excitation force (13) with the SI
    unit exponents of the UFF 58 units table and the axis/unit labels
    ``Acceleration``/``m/s^2`` or ``Force``/``N``.  Datasets are written in
    the order given.

    Record 6 carries: function id = 1-based position in the file, version
    / sequence number = ``hit`` (pyuff ``'ver_num'``), load case 0 (single
    point excitation, so the reference DOF is meaningful), response node
    and direction, reference node and direction.  ID lines: 1 channel
    name, 2 ``"hit <n> <quantity> rsp <node>:<dir> ref <node>:<dir>"``,
    3 ``NONE``, 4 the exact ``dt`` and sampling rate, 5 ``NONE``.

    Parameters
    ----------
    path : str or os.PathLike
        Output file (overwritten).
    histories : sequence of TimeHistory
        At least one history; see :class:`TimeHistory` for the allowed
        field values.
    binary : bool, optional
        True (default): binary 58b, IEEE 754 single precision, little endian
        (ordinate data type 2).  False: ASCII 58 with the float32 values in
        real double precision, ``4E20.12`` (ordinate data type 4); about
        five times larger and slower.

    Returns
    -------
    pathlib.Path
        The written file.

    Raises
    ------
    ValueError
        If an argument is invalid; the message names it, e.g.
        ``histories[3].dt``, and shows what was received.

    Notes
    -----
    Read back with ``pyuff.UFF(path).read_sets()``: the hit is
    ``dset['ver_num']``, the samples ``dset['data']`` (float64 holding the
    float32 values), the time step ``dset['abscissa_inc']``.
    """
    if isinstance(histories, (str, bytes)) or not isinstance(histories, Sequence):
        raise ValueError(f"histories must be a sequence of TimeHistory, got {type(histories).__name__}")
    if len(histories) == 0:
        raise ValueError("histories must contain at least one TimeHistory, got an empty sequence")
    if not isinstance(binary, (bool, np.bool_)):
        raise ValueError(f"binary must be True or False, got {binary!r}")
    checked = [_validate_history(i, h) for i, h in enumerate(histories)]

    out = Path(os.fspath(path))
    end = f"{-1:6d}\n".encode("ascii")
    with open(out, "wb") as fh:
        for func_id, (data, meta) in enumerate(checked, start=1):
            # Cast again here rather than keeping float32 copies of all
            # histories alive (a cast of 51200 samples takes ~30 us).
            data32 = _as_float32(data)
            fh.write(_uff58_header(func_id, meta, data32.size, bool(binary)).encode("ascii"))
            if binary:
                # 58b: raw bytes immediately followed by the closing -1 line.
                fh.write(np.ascontiguousarray(data32))
            else:
                fh.write(_ascii_double(data32).encode("ascii"))
            fh.write(end)
    return out
