"""ANSYS Mechanical APDL result file (``.rst``) reader of a modal analysis.

A design office that runs ANSYS keeps the binary ``jobname.rst`` of its modal analysis (``ANTYPE,MODAL``): mesh,
materials, natural frequencies and the mode shapes of every node. The binary format (Fortran records of the ANSYS
"programmer's reference") is read by `ansys-mapdl-reader <https://reader.docs.pyansys.com>`_, Ansys' own reader;
this module only turns what it returns into :class:`~fem_import.modes.FEModes`:

* **Frequencies** are the result sets' time values (Hz in a modal analysis); the mode numbers are the substep
  numbers of the load step read. A file with several modal load steps (modal analyses after different prestress)
  needs ``subcase=`` (the load step); a complex (damped, ``QRDAMP``/``DAMP``) solution, a cyclic-symmetry
  sector and every other analysis type are refused by name.
* **Shapes** are read in each node's nodal coordinate system and turned to the global Cartesian axes here, for
  translations *and* rotations: ANSYS rotates a node's axes by ``THXY`` about Z, then ``THYZ`` about the new X,
  then ``THZX`` about the new Y (``N``/``NROTAT``), so ``u_global = Rz(THXY) Rx(THYZ) Ry(THZX) u_nodal``.
  (The library's own rotation turns the first three components only, and applies the three turns in the reverse
  order, which is exact only when at most one angle is non-zero.) Nodes with ``ROTX..ROTZ`` give 6 DOF, else the
  three translations; other DOFs (``WARP``, ``TEMP``, ``PRES``) are left out, said in the history.
* **Normalisation.** ANSYS normalises to the mass matrix (``MODOPT`` ``Nrmkey = OFF``, the default), which is
  what :class:`FEModes` holds. Shapes normalised to unity (``Nrmkey = ON``: the largest component of every mode
  is exactly 1) carry no modal mass and are refused.
* **Units.** The result header states ANSYS's ``/UNITS`` (SI, MKS, MPA, BIN, BFT, CGS, uMKS) and the reader
  converts to SI. Without ``/UNITS`` (ANSYS's default, "user defined") the unit system is inferred from the
  materials: the one system in :data:`~fem_import.modes.UNIT_SYSTEMS` that puts every density in
  :data:`PLAUSIBLE_DENSITY` and every Young's modulus in :data:`PLAUSIBLE_MODULUS` (structural materials; a
  density in SI is ``rho L^3 Mk`` and a modulus ``E L Mk`` for ``L`` file lengths per metre and ``Mk`` kg per
  file mass unit, and the systems differ by factors of 500 and more). If none or several fit (steel's density
  in CGS and in BFT both look like a metal's), or no material has a density, SI is assumed and said
  (``--fe-units`` declares the system). A stated unit system whose materials are implausible in it is logged
  as a WARNING.
* **Geometry**: node coordinates (global Cartesian) and the elements' corner nodes, as UFF descriptors by shape
  (a 20-node brick is plotted as its 8-node brick; the mid-side nodes keep their shapes), except where the ANSYS
  element says more than its shape (:data:`ANSYS_ELEMENTS`): a MASS21 is a lumped mass (161), an MPC184 a rigid
  element (122), a COMBIN14/39/40/214 a spring (136), a LINK180 a rod (11) -- not beams of the structure, which
  the diagnosis would take for the axle. Surface, contact and meshing elements are left out.
"""

from __future__ import annotations

import json
import logging
import os
import struct
import subprocess
import sys
import tempfile

import numpy as np

from .errors import FEReadError
from .modes import UNIT_SYSTEMS, Element, FEModes
from .registry import register_format
from .solutions import choose_step

__all__ = ["read_ansys_rst", "sniff_ansys_rst", "nodal_to_global", "ANSYS_UNITS", "ANSYS_ELEMENTS", "PLAUSIBLE_DENSITY",
           "PLAUSIBLE_MODULUS"]

log = logging.getLogger("fem_import")

#: ANSYS ``/UNITS`` codes of the result header -> unit system of :data:`UNIT_SYSTEMS` (0, user defined: None)
ANSYS_UNITS = {0: None, 1: "m-kg-s", 2: "cm-g-s", 3: "ft-slug-s", 4: "in-lbf-s", 5: "m-kg-s", 6: "mm-t-s",
               7: "um-kg-s"}
_UNIT_LABELS = {0: "user defined", 1: "SI", 2: "CGS", 3: "BFT", 4: "BIN", 5: "MKS", 6: "MPA", 7: "uMKS"}
#: Densities of structural materials [kg/m^3]: polymers and composites to tungsten alloys
PLAUSIBLE_DENSITY = (500.0, 25000.0)
#: Young's moduli of structural materials [Pa]: polymers to tungsten carbide
PLAUSIBLE_MODULUS = (1e8, 1.2e12)
#: ANSYS analysis types (``ANTYPE``) by the result header's code
_ANALYSES = {0: "static", 1: "buckling", 2: "modal", 3: "harmonic", 4: "transient", 7: "substructuring",
             8: "spectrum"}
#: VTK cell type -> UFF 2412 descriptor and the number of leading (corner) points it keeps
_VTK_CELLS = {1: (161, 1), 3: (21, 2), 21: (21, 2), 5: (91, 3), 22: (91, 3), 9: (94, 4), 23: (94, 4),
              10: (111, 4), 24: (111, 4), 12: (115, 8), 25: (115, 8), 13: (112, 6), 26: (112, 6)}
#: ANSYS element numbers whose role the cell shape does not tell -> UFF descriptor and nodes kept: MASS21, the
#: rigid MPC184, the springs COMBIN14/39/40/214, the rod LINK180 (a line cell each, but no beam of the structure)
ANSYS_ELEMENTS = {21: (161, 1), 184: (122, 2), 14: (136, 2), 39: (136, 2), 40: (136, 2), 214: (136, 2),
                  180: (11, 2)}
#: ANSYS surface, contact and meshing elements: no structure of the modes, left out (counted in the history)
_NOT_STRUCTURE = frozenset({151, 152, 153, 154, 156, 169, 170, 171, 172, 173, 174, 175, 176, 177, 178, 200})
_TRANSLATIONS = ("UX", "UY", "UZ")
_ROTATIONS = ("ROTX", "ROTY", "ROTZ")
#: a unity-normalised mode's largest component is 1 to the precision the file keeps
_UNITY_RTOL = 1e-6


def sniff_ansys_rst(head: bytes) -> bool:
    """True for an ANSYS binary result file: a 100-word standard header record whose first item, the file
    number, is 12 (results), in either byte order."""
    if len(head) < 12:
        return False
    for order in "<>":
        size, _flags, number = struct.unpack(order + "iii", head[:12])
        if size == 100 and number == 12:
            return True
    return False


def nodal_to_global(angles_deg) -> np.ndarray:
    """Rotation matrices from nodal to global components of ANSYS's rotated nodes.

    Parameters
    ----------
    angles_deg : array_like (n, 3)
        ``THXY, THYZ, THZX`` per node [degrees]: turns about Z, then the new X, then the new Y.

    Returns
    -------
    ndarray (n, 3, 3)
        ``R = Rz(THXY) Rx(THYZ) Ry(THZX)``; its columns are the nodal axes in global components, and
        ``u_global = R u_nodal``.
    """
    a = np.radians(np.asarray(angles_deg, float).reshape(-1, 3))
    c, s = np.cos(a), np.sin(a)
    one, zero = np.ones(len(a)), np.zeros(len(a))
    rz = np.stack([np.stack([c[:, 0], -s[:, 0], zero], -1), np.stack([s[:, 0], c[:, 0], zero], -1),
                   np.stack([zero, zero, one], -1)], -2)
    rx = np.stack([np.stack([one, zero, zero], -1), np.stack([zero, c[:, 1], -s[:, 1]], -1),
                   np.stack([zero, s[:, 1], c[:, 1]], -1)], -2)
    ry = np.stack([np.stack([c[:, 2], zero, s[:, 2]], -1), np.stack([zero, one, zero], -1),
                   np.stack([-s[:, 2], zero, c[:, 2]], -1)], -2)
    return rz @ rx @ ry


def _check_complete(path: str) -> None:
    """Refuse a truncated result file before the library reads it: its C reader aborts the process (not an
    exception) on a record cut short. The result header (the second record, at word 103) gives where the file's
    data end (``ptrEnd8``, or the 32-bit ``ptrend`` of older files), in 4-byte words."""
    size = os.path.getsize(path)
    need = (105 + 80) * 4
    if size < need:
        raise FEReadError(path, f"truncated: {size} bytes, shorter than the two header records ({need} bytes)")
    with open(path, "rb") as fh:
        head = fh.read(need)
    order = "<" if struct.unpack("<i", head[:4])[0] == 100 else ">"
    words = np.frombuffer(head, order + "i4").astype(np.int64)
    n = int(words[103])
    if not 10 <= n <= 80:
        raise FEReadError(path, f"the result header record holds {n} words (10..80 expected): a compressed "
                                f"(/FCOMP,RST) or damaged file")
    rec = words[105:105 + n] & 0xFFFFFFFF
    end = int(rec[22] + (rec[23] << 32)) if n > 23 and (rec[22] or rec[23]) else int(rec[9])
    if size < 4 * end:
        raise FEReadError(path, f"truncated: the result header says the data end at byte {4 * end}, the file has "
                                f"{size} bytes ({size / (4 * end):.0%}); copy the .rst again")


def _library():
    try:
        from ansys.mapdl import reader
    except ImportError as exc:  # pragma: no cover - a dependency of the package
        raise ImportError("reading ANSYS result files needs ansys-mapdl-reader (pip install ansys-mapdl-reader)"
                          ) from exc
    return reader


def _open(path: str):
    reader = _library()
    _check_complete(path)
    try:
        result = reader.read_binary(path)
    except Exception as exc:  # the library raises bare Exception/RuntimeError on broken records
        raise FEReadError(path, f"not a readable ANSYS result file ({type(exc).__name__}: {exc}); a truncated or "
                                f"damaged .rst?") from None
    if type(result).__name__ == "CyclicResult":
        raise FEReadError(path, f"a cyclic-symmetry result ({result.n_sector} sectors, the modes per harmonic "
                                f"index of one sector); expand it in ANSYS (/CYCEXPAND, or solve the full wheelset) "
                                f"and export the full model's modes")
    if not hasattr(result, "nodal_solution") or not hasattr(result, "_resultheader"):
        raise FEReadError(path, f"an ANSYS {type(result).__name__} file, not a result file (.rst) of a modal "
                                f"analysis")
    return result


def _materials(result) -> dict[int, tuple[float, float]]:
    """``{material: (DENS, EX)}`` in file units (NaN where not given); materials without a density left out."""
    try:
        materials = result.materials
    except Exception:  # an old or trimmed file without material records
        return {}
    out = {}
    for k, v in materials.items():
        rho, ex = float(v.get("DENS", 0.0)), float(v.get("EX", np.nan))
        if rho > 0:
            out[int(k)] = (rho, ex if ex > 0 else np.nan)
    return out


def _fits(materials: dict[int, tuple[float, float]], system: str) -> bool:
    """Whether every material's density and modulus are a structural material's in ``system``."""
    length, mass = UNIT_SYSTEMS[system]
    (rlo, rhi), (elo, ehi) = PLAUSIBLE_DENSITY, PLAUSIBLE_MODULUS
    return bool(materials) and all(rlo <= rho * mass * length ** 3 <= rhi
                                   and (not np.isfinite(ex) or elo <= ex * mass * length <= ehi)
                                   for rho, ex in materials.values())


def _unit_system(path: str, code: int, materials: dict[int, tuple[float, float]]) -> tuple[str | None, str]:
    """The file's unit system (None: not known) and how it was found."""
    stated = ANSYS_UNITS.get(code)
    label = _UNIT_LABELS.get(code, f"code {code}")
    what = ", ".join(f"material {k}: DENS {rho:.4g}" + (f", EX {ex:.4g}" if np.isfinite(ex) else "")
                     for k, (rho, ex) in sorted(materials.items()))
    if stated is not None:
        if materials and not _fits(materials, stated):
            log.warning("%s: the file states /UNITS,%s (%s), but its materials (%s) are not structural materials "
                        "in it: check the model's units", path, label, stated, what)
        return stated, f"stated /UNITS,{label}"
    fits = [s for s in UNIT_SYSTEMS if _fits(materials, s)]
    if len(fits) == 1:
        return fits[0], f"inferred from the materials: {what}; the file has no /UNITS"
    why = ("no material density in the file" if not materials else
           f"the materials ({what}) fit " + (f"{', '.join(fits)}" if fits else "no unit system"))
    return None, f"no /UNITS in the file and {why}"


def _elements(path: str, result, have: set[int]) -> tuple[tuple[Element, ...], list[str]]:
    grid = result.grid
    notes = []
    if grid is None or grid.n_cells == 0:
        return (), ["no elements in the file"]
    node_num = np.asarray(grid.point_data["ansys_node_num"], np.int64)
    elem_num = np.asarray(grid.cell_data["ansys_elem_num"], np.int64)
    kinds = grid.cell_data.get("ansys_elem_type_num")
    kinds = np.zeros(grid.n_cells, np.int64) if kinds is None else np.asarray(kinds, np.int64)
    offsets = np.asarray(grid.cell_offsets if hasattr(grid, "cell_offsets") else grid.offset, np.int64)
    conn = np.asarray(grid.cell_connectivity, np.int64)
    out, unknown, missing, surfaces = [], {}, 0, 0
    for k, cell_type in enumerate(np.asarray(grid.celltypes).tolist()):
        nodes = node_num[conn[offsets[k]:offsets[k + 1]]]
        if int(kinds[k]) in _NOT_STRUCTURE:
            surfaces += 1
            continue
        desc, corners = ANSYS_ELEMENTS.get(int(kinds[k])) or _VTK_CELLS.get(cell_type, (None, 0))
        if desc is None:
            unknown[cell_type] = unknown.get(cell_type, 0) + 1
            continue
        nodes = tuple(int(n) for n in nodes[:corners])
        if not set(nodes) <= have:
            missing += 1
            continue
        out.append(Element(int(elem_num[k]), desc, nodes))
    if unknown:
        notes.append(f"elements of VTK cell types {sorted(unknown)} ({sum(unknown.values())}) not drawn")
    if missing:
        notes.append(f"{missing} element(s) on nodes without a solution not drawn")
    if surfaces:
        notes.append(f"{surfaces} surface, contact or meshing element(s) (SURF15x, CONTA17x, TARGE170, MESH200) "
                     f"left out")
    for note in notes:
        log.info("%s: %s", path, note)
    return tuple(out), notes


def read_ansys_rst(path: str, *, subcase: int | str | None = None, isolated: bool = True) -> FEModes:
    """Read the modes of an ANSYS modal analysis from its binary result file (module docstring).

    Parameters
    ----------
    path : str
        The ``.rst`` file.
    subcase : int, "lowest" or None, optional
        The load step to read when the file holds several modal solutions: None requires one, ``"lowest"`` reads
        the lowest with a WARNING naming the others (what :func:`fem_import.read_with_geometry` passes).
    isolated : bool, optional
        Read in a child Python process (default): the library's C reader aborts or crashes the whole process on
        some damaged records (a record-length word changed: ``std::bad_alloc``, a segmentation fault), which no
        exception handler can catch; the child's death is then an :class:`FEReadError`. It costs about a second.
        False reads in this process.

    Returns
    -------
    FEModes
        Mass-normalised modes in SI units when the file's unit system is stated or inferred (else as read, with
        the assumption in :attr:`FEModes.units`), node coordinates and shapes in the global Cartesian system,
        3 or 6 DOF per node, the substep numbers as mode numbers.

    Raises
    ------
    FEReadError
        Not a readable result file, a cyclic-symmetry or non-modal analysis, complex modes, several load steps
        without ``subcase``, no nodal displacements, or shapes normalised to unity; a damaged file the library
        cannot read, or on which it crashed.
    """
    path = str(path)
    if isolated:
        return _read_in_child(path, subcase)
    try:
        return _read(path, subcase)
    except FEReadError:
        raise
    except Exception as exc:  # the library's parsers raise KeyError, ValueError, TypeError... on damaged records
        raise FEReadError(path, f"a damaged ANSYS result file: the reader stopped with {type(exc).__name__}: "
                                f"{exc}") from None


def _read(path: str, subcase) -> FEModes:
    result = _open(path)
    header = result._resultheader
    kind = int(header.get("kan", -1))
    if kind != 2:
        raise FEReadError(path, f"a {_ANALYSES.get(kind, f'type {kind}')} analysis (ANTYPE); the modes come from a "
                                f"modal analysis (ANTYPE,MODAL)")
    if int(header.get("cpxrst", 0)):
        raise FEReadError(path, "complex modes (a damped modal analysis, MODOPT,QRDAMP/DAMP/UNSYM); export the "
                                "real normal modes (MODOPT,LANB or SUBSP)")
    if getattr(result, "_is_thermal", False):
        raise FEReadError(path, "a thermal result file; the modes come from a structural modal analysis")
    if result.nsets == 0:
        raise FEReadError(path, "no result sets (the modal solution did not finish?)")
    table = np.asarray(header["ls_table"]).reshape(-1, 3)
    step = choose_step(path, table[:, 0], subcase, "modal load step")
    sets = np.flatnonzero(table[:, 0] == step)
    freqs = np.asarray(result.time_values, float)[sets]
    numbers = table[sets, 1].astype(np.int64)

    mesh = result.mesh
    mesh_ids = np.asarray(mesh.nnum, np.int64)
    row = {n: k for k, n in enumerate(mesh_ids.tolist())}
    node_ids, shapes, dof_names = None, [], None
    for k in sets.tolist():
        dofs = [str(d).upper() for d in result.result_dof(k)]
        if not all(d in dofs for d in _TRANSLATIONS):
            raise FEReadError(path, f"mode {numbers[len(shapes)]}: nodal DOFs {dofs} lack UX, UY, UZ")
        try:
            nnum, values = result.nodal_solution(k, in_nodal_coord_sys=True)
        except Exception as exc:  # the library raises AttributeError or bare Exception
            raise FEReadError(path, f"mode {numbers[len(shapes)]}: no nodal displacements ({exc})") from None
        nnum = np.asarray(nnum, np.int64)
        if node_ids is None:
            node_ids, dof_names = nnum, dofs
        elif not np.array_equal(nnum, node_ids) or dofs != dof_names:
            raise FEReadError(path, f"mode {numbers[len(shapes)]} has another node or DOF set than mode "
                                    f"{numbers[0]}")
        shapes.append(np.asarray(values, float).reshape(nnum.size, -1))
    six = all(d in dof_names for d in _ROTATIONS)
    take = [dof_names.index(d) for d in _TRANSLATIONS + (_ROTATIONS if six else ())]
    phi = np.stack(shapes)[:, :, take]
    if not np.all(np.isfinite(phi)):
        raise FEReadError(path, "mode shapes hold non-finite values")
    history = [f"read {len(freqs)} modes ({numbers[0]}..{numbers[-1]}, load step {step}) on {node_ids.size} nodes "
               f"from ANSYS result file {path} (MAPDL {header.get('verstring', '?')})"]
    if node_ids.size < mesh_ids.size:
        note = (f"{mesh_ids.size - node_ids.size} of the mesh's {mesh_ids.size} nodes have no displacements (an "
                f"OUTRES limited to a component?) and are left out")
        log.warning("%s: %s", path, note)
        history.append(note)
    rest = [d for d in dof_names if d not in _TRANSLATIONS + _ROTATIONS]
    if rest:
        history.append(f"nodal DOFs {rest} left out")
    angles = np.asarray(mesh.node_angles, float)[[row[n] for n in node_ids.tolist()]]
    turned = np.flatnonzero(np.abs(angles).max(axis=1) > 0)
    if turned.size:
        r = nodal_to_global(angles[turned])
        phi[:, turned, :3] = np.einsum("nij,mnj->mni", r, phi[:, turned, :3])
        if six:
            phi[:, turned, 3:] = np.einsum("nij,mnj->mni", r, phi[:, turned, 3:])
        history.append(f"{turned.size} rotated node(s) (THXY, THYZ, THZX): components turned to the global axes")
    peak = np.abs(phi.reshape(len(freqs), -1)).max(axis=1)
    if len(freqs) and np.all(np.abs(peak - 1.0) <= _UNITY_RTOL):
        raise FEReadError(path, "the shapes are normalised to unity (largest component 1 in every mode: MODOPT "
                                "Nrmkey = ON) and carry no modal mass; solve again with the default mass "
                                "normalisation (Nrmkey = OFF)")
    xyz = np.asarray(mesh.nodes, float)[[row[n] for n in node_ids.tolist()], :3]
    elements, notes = _elements(path, result, set(node_ids.tolist()))
    history += notes
    code = int({v: k for k, v in _code_names().items()}.get(header.get("units"), 0))
    system, how = _unit_system(path, code, _materials(result))
    fe = FEModes(node_ids=node_ids, xyz=xyz, elements=elements, freqs_hz=freqs, shapes=phi,
                 modal_mass=np.ones(len(freqs)), source=path, format="ansys-rst",
                 units=(f"SI (m, kg, s) assumed ({how})" if system is None else f"{system} ({how})"),
                 history=tuple(history), mode_numbers=numbers)
    if system is None:
        log.warning("%s: %s; the modes are read as SI (m, kg, s): declare the units (--fe-units) if they are not",
                    path, how)
        return fe
    si = fe.in_si_units(system)
    steps = si.history[:-1] + (si.history[-1].replace("declared in", "file in", 1),) if si is not fe else si.history
    units = f"SI (m, kg, s) ({how})" if si is fe else f"SI (m, kg, s), converted from {system} ({how})"
    return FEModes(si.node_ids, si.xyz, si.elements, si.freqs_hz, si.shapes, si.modal_mass, source=path,
                   format="ansys-rst", units=units, history=steps, mode_numbers=numbers)


def _read_in_child(path: str, subcase) -> FEModes:
    """:func:`_read` in a child interpreter (``python -m fem_import._rst_child``); its log records re-logged here."""
    _check_complete(path)
    package_root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [package_root, os.environ.get("PYTHONPATH")])))
    with tempfile.TemporaryDirectory(prefix="railmodal-rst-") as tmp:
        out = os.path.join(tmp, "modes.npz")
        cmd = [sys.executable, "-m", "fem_import._rst_child", path, out, json.dumps(subcase)]
        try:
            done = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=3600)
        except subprocess.TimeoutExpired:
            raise FEReadError(path, "the ANSYS result reader did not finish within an hour: a damaged file?") from None
        if done.returncode != 0 or not os.path.exists(out):
            how = (f"killed by signal {-done.returncode}" if done.returncode < 0 else f"exit status {done.returncode}")
            tail = " ".join((done.stderr or "").strip().splitlines()[-2:])[:300]
            raise FEReadError(path, f"the ANSYS result reader crashed on this file ({how}{': ' + tail if tail else ''}"
                                    f"): a damaged .rst; copy it again or solve again")
        with np.load(out, allow_pickle=False) as data:
            reply = json.loads(str(data["reply"]))
            for level, message in reply["log"]:
                log.log(level, "%s", message)
            if "error" in reply:
                raise FEReadError(path, reply["error"], line=None)
            offsets = data["element_offsets"]
            nodes = data["element_nodes"]
            elements = tuple(Element(int(e), int(d), tuple(int(n) for n in nodes[offsets[k]:offsets[k + 1]]))
                             for k, (e, d) in enumerate(zip(data["element_ids"], data["element_types"])))
            return FEModes(data["node_ids"], data["xyz"], elements, data["freqs_hz"], data["shapes"],
                           data["modal_mass"], source=path, format="ansys-rst", units=reply["units"],
                           history=tuple(reply["history"]), mode_numbers=data["mode_numbers"])


def _child(path: str, out: str, subcase) -> None:
    """The child's side of :func:`_read_in_child`: read, and write the modes (or the refusal) and the log."""
    records: list[tuple[int, str]] = []

    class Collect(logging.Handler):
        def emit(self, record):
            records.append((record.levelno, record.getMessage()))

    log.addHandler(Collect(logging.INFO))
    log.setLevel(logging.INFO)
    log.propagate = False
    arrays: dict[str, np.ndarray] = {}
    try:
        fe = read_ansys_rst(path, subcase=subcase, isolated=False)
    except FEReadError as exc:
        text = str(exc)
        reply = {"error": text[len(path) + 2:] if text.startswith(path + ": ") else text}
    else:
        reply = {"units": fe.units, "history": list(fe.history)}
        sizes = [len(e.nodes) for e in fe.elements]
        arrays = dict(node_ids=fe.node_ids, xyz=fe.xyz, freqs_hz=fe.freqs_hz, shapes=fe.shapes,
                      modal_mass=fe.modal_mass, mode_numbers=fe.mode_numbers,
                      element_ids=np.array([e.element_id for e in fe.elements], np.int64),
                      element_types=np.array([e.fe_descriptor for e in fe.elements], np.int64),
                      element_offsets=np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
                      element_nodes=np.array([n for e in fe.elements for n in e.nodes], np.int64))
    reply["log"] = records
    np.savez(out, reply=np.array(json.dumps(reply)), **arrays)


def _code_names() -> dict[int, str]:
    # the library reports the header's /UNITS code as a name; map it back
    return {0: "User Defined", 1: "SI", 2: "CSG", 3: "U.S. Customary units (feet)",
            4: "U.S. Customary units (inches)", 5: "MKS", 6: "MPA", 7: "uMKS"}


register_format("ansys-rst", patterns=("*.rst", "*.RST", "*.rstp"), sniff=sniff_ansys_rst, reader=read_ansys_rst,
                geometry=None, aliases=("rst", "ansys"),
                description="ANSYS Mechanical APDL binary result file of a modal analysis (ansys-mapdl-reader)")
