"""The hybrid modal model: FE shapes with the test's frequencies and damping (thesis §2.3, Table 3.1).

Policy (thesis Table 3.1): a mode enters the model with its FE shape and the
frequency and damping measured in the test when the pairing found it in
both; FE modes without a test partner enter only if the user keeps them,
with their FE frequency and a default damping ratio; rigid-body modes always
enter (frequency 0).  Test modes without an FE partner have no shape on the
FE mesh and are left out here (the ``experimental_mode`` effect adds them
where their measured shape is known).

Degenerate FE clusters (the two planes of a bending mode of an axisymmetric
wheelset) are paired as one: when the test saw one member, every member gets
its frequency and damping (the wheelset is axisymmetric, so the unseen plane
is the same mode); when it saw several, the cluster's shapes are first
rotated within the cluster so that each test mode has its own member — the
combination the pairing found (``fe_weights`` of the pairing table;
without weights, members in FE order) — and the members left over get the
mean of the partners' values.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from fem_import.modes import FEModes
from receptance.dofs import DofError, Point
from receptance.modal_model import ModalModel, ModelError

__all__ = ["hybrid_model", "read_pairing_table", "check_pairing", "check_fe_for_model", "DEFAULT_ZETA",
           "RIGID_BELOW_HZ", "WHEELSET_MASS_KG", "PAIRED_RATIO_MAX"]

log = logging.getLogger("receptance")

#: damping ratio of kept FE-only modes: the order of the wheelset's measured damping (0.01–0.5 %)
DEFAULT_ZETA = 1e-3
#: FE modes below this frequency are rigid-body modes (set to exactly 0 Hz)
RIGID_BELOW_HZ = 1.0

_PAIRING_COLUMNS = ("test_mode", "f_test_hz", "fe_modes", "zeta")


def read_pairing_table(source) -> pd.DataFrame:
    """The pairing table (``ema.pairing.Pairing.table`` or the ``pairing.csv`` that ``railmodal lab pair`` writes).

    Parameters
    ----------
    source : Pairing, DataFrame, or path to a CSV file or to a folder holding ``pairing.csv``
    """
    if hasattr(source, "table") and isinstance(source.table, pd.DataFrame):
        return source.table.copy()
    if isinstance(source, pd.DataFrame):
        df = source.copy()
        where = "pairing table"
    else:
        from ema.channels import read_table_csv

        path = Path(source)
        if path.is_dir():
            path = path / "pairing.csv"
        if not path.is_file():
            raise ModelError(f"{path}: no pairing table there; run 'railmodal lab pair' first")
        df = read_table_csv(path, role="pairing table", required=_PAIRING_COLUMNS, error=ModelError,
                            dtype={"fe_modes": str, "fe_weights": str})
        where = str(path)
    missing = [c for c in _PAIRING_COLUMNS if c not in df.columns]
    if missing:
        raise ModelError(f"{where}: pairing table lacks column(s) {missing}; expected the columns of "
                         f"'railmodal lab pair' (test_mode, f_test_hz, fe_modes, f_fe_hz, zeta, mac, ...)")
    df["fe_modes"] = df["fe_modes"].astype(object).where(df["fe_modes"].notna(), "").astype(str)
    if "fe_weights" in df:
        df["fe_weights"] = df["fe_weights"].astype(object).where(df["fe_weights"].notna(), "").astype(str)
    for col in ("test_mode", "f_test_hz", "zeta", "f_fe_hz", "df_pct", "mac"):
        if col in df.columns:
            df[col] = _numeric_column(df[col], col, where)
    df.attrs["source"] = where
    return df


def _numeric_column(values: pd.Series, col: str, where: str) -> pd.Series:
    """A column as float (empty cells NaN); ModelError naming the file, row and column of a non-number."""
    out = pd.to_numeric(values, errors="coerce")
    bad = out.isna() & values.notna() & values.astype(str).str.strip().ne("")
    if bad.any():
        k = int(np.flatnonzero(bad.to_numpy())[0])
        raise ModelError(f"{where}, row {k + 1}, column {col!r}: expected a number, got {values.iloc[k]!r}")
    return out.astype(float)


#: A paired test mode and its FE partner differ by per cents (a hidden effect by tens of per cents);
#: beyond a factor of two the row was edited or belongs to another export.
PAIRED_RATIO_MAX = 2.0


def check_pairing(table: pd.DataFrame, fe: FEModes) -> None:
    """Check a pairing table against the FE export it is used with.

    * ``fe_modes`` are modes of the export, each FE mode paired in one row
      group only, and a group has no more test modes than members;
    * ``f_fe_hz`` (when present) is the export's frequency of those modes
      (the pairing was made against this file, with its mode order);
    * ``f_test_hz`` lies within a factor :data:`PAIRED_RATIO_MAX` of it, and
      agrees with ``df_pct`` (when present): an edited frequency is caught;
    * ``mac`` (when present) lies in [0, 1].

    Raises
    ------
    ModelError
        Names the table, the row, the FE mode(s), what the table says and
        what the FE file says.
    """
    where = table.attrs.get("source", "pairing table")
    n_fe = len(fe)
    src = fe.source or "the FE export"
    paired = table[table["fe_modes"].str.strip().ne("") & table["test_mode"].notna()]
    owner: dict[int, str] = {}
    for text, rows in paired.groupby("fe_modes", sort=False):
        first = int(rows.index[0]) + 1
        members = _members(text, n_fe, first + 1)
        row_list = ", ".join(str(int(i) + 1) for i in rows.index)
        if len(rows) > len(members):
            raise ModelError(
                f"{where}, rows {row_list}: FE mode(s) {text} paired with {len(rows)} test modes "
                f"({', '.join(f'{t:g}' for t in rows['test_mode'])}) but the group has {len(members)} member(s); "
                f"an FE mode has one test partner (a degenerate pair two)")
        for j in members:
            if j in owner and owner[j] != text:
                raise ModelError(f"{where}, row {first}: FE mode {j + 1} is paired twice (in '{owner[j]}' and "
                                 f"'{text}')")
            owner[j] = text
        f_fe = float(np.mean(fe.freqs_hz[members]))
        for i, r in rows.iterrows():
            row = int(i) + 1
            ft = float(r["f_test_hz"])
            if "f_fe_hz" in rows and np.isfinite(r["f_fe_hz"]):
                if abs(float(r["f_fe_hz"]) - f_fe) > 1e-4 * max(f_fe, 1.0):
                    raise ModelError(
                        f"{where}, row {row}: f_fe_hz {float(r['f_fe_hz']):.6g} Hz for FE mode(s) {text}, but "
                        f"{src} has {f_fe:.6g} Hz for them: the pairing was made against another FE export, or "
                        f"its modes are in another order; pair again against this file")
            if np.isfinite(ft) and ft > 0 and f_fe > 0 and not 1 / PAIRED_RATIO_MAX <= ft / f_fe <= PAIRED_RATIO_MAX:
                raise ModelError(
                    f"{where}, row {row}: test mode {r['test_mode']:g} at {ft:.6g} Hz is paired with FE mode(s) "
                    f"{text} at {f_fe:.6g} Hz, {ft / f_fe:.3g} x apart; paired modes differ by per cents (at most a "
                    f"factor {PAIRED_RATIO_MAX:g}): the row was edited or belongs to another pairing")
            if "df_pct" in rows and np.isfinite(r["df_pct"]) and np.isfinite(ft) and ft > 0:
                f_ref = float(r["f_fe_hz"]) if "f_fe_hz" in rows and np.isfinite(r["f_fe_hz"]) else f_fe
                df_pct = 100 * (f_ref - ft) / ft
                if abs(df_pct - float(r["df_pct"])) > 0.01 + 1e-3 * abs(df_pct):
                    raise ModelError(
                        f"{where}, row {row}: df_pct says {float(r['df_pct']):.4g} % but f_test_hz {ft:.6g} Hz and "
                        f"f_fe_hz {f_ref:.6g} Hz give {df_pct:.4g} %: a frequency was edited after pairing")
            if "mac" in rows and pd.notna(r["mac"]) and not -1e-6 <= float(r["mac"]) <= 1 + 1e-6:
                raise ModelError(f"{where}, row {row}: mac {float(r['mac']):g} for FE mode(s) {text} is outside "
                                 f"[0, 1]")


def _members(text: str, n_fe: int, row: int) -> list[int]:
    text = text.strip()
    if not text or text.lower() == "nan":
        return []
    try:
        nums = [int(float(t)) for t in text.split("+")]
    except ValueError:
        raise ModelError(f"pairing row {row}: fe_modes must be '+'-joined FE mode numbers, got {text!r}") from None
    bad = [k for k in nums if not 1 <= k <= n_fe]
    if bad:
        raise ModelError(f"pairing row {row}: FE mode(s) {bad} not in the FE export (modes 1–{n_fe}); "
                         f"pair against the same FE file")
    return [k - 1 for k in nums]


def _rotate_cluster(shapes: np.ndarray, rows: pd.DataFrame, text: str) -> np.ndarray:
    """Members of a degenerate cluster recombined so that member k is the k-th test mode's combination.

    The combinations (rows' ``fe_weights``) are orthonormalised in the order of
    the test frequencies and completed to an orthogonal matrix, so the new
    members stay mass-normalised and span the same space.
    """
    n = shapes.shape[0]
    W = []
    for w in rows["fe_weights"] if "fe_weights" in rows else [""] * len(rows):
        if not w.strip():
            return shapes
        vals = np.array([float(v) for v in w.split(";")])
        if vals.size != n or not np.all(np.isfinite(vals)) or np.linalg.norm(vals) == 0:
            raise ModelError(f"pairing rows for FE modes {text}: fe_weights {w!r} must hold {n} finite numbers")
        W.append(vals / np.linalg.norm(vals))
    basis: list[np.ndarray] = []
    for v in W + list(np.eye(n)):  # Gram-Schmidt in test-frequency order, completed by the unit vectors
        u = v - sum((b @ v) * b for b in basis)
        if np.linalg.norm(u) > 1e-6 and len(basis) < n:
            basis.append(u / np.linalg.norm(u))
    return np.tensordot(np.array(basis), shapes, axes=1)


#: Railway wheelset mass [kg]: outside the physical range (a tram wheel to a heavy-haul wheelset with axleboxes,
#: widened by a factor two) the FE shapes' normalisation is wrong; outside the typical range a warning.
WHEELSET_MASS_KG = {"physical": (100.0, 10000.0), "typical": (500.0, 2500.0)}


def check_fe_for_model(fe: FEModes, *, total_mass: float | None = None, mass_matrix=None,
                       expect: str = "wheelset"):
    """Mass normalisation of an FE export before it becomes a hybrid model.

    The rigid-body modes give the total mass (:func:`fem_import.check_mass_normalisation`):
    it must be the same along x, y and z, equal ``total_mass`` when given
    (5 %), and — for ``expect="wheelset"`` without ``total_mass`` — lie in
    the physical range of a railway wheelset (:data:`WHEELSET_MASS_KG`; a
    warning outside the typical range). Shapes scaled by ``s`` show a mass
    ``1/s^2`` times too small.

    Returns
    -------
    fem_import.RigidBodyMass or None

    Raises
    ------
    fem_import.MassNormalisationError
        Names the file, the mass found and what was expected; or, for a
        wheelset, an export without any rigid-body mode (a free wheelset's
        model needs them).
    """
    import warnings

    from fem_import.checks import MassNormalisationError, check_mass_normalisation, rigid_body_modes

    f = np.asarray(fe.freqs_hz, float)
    if expect == "wheelset" and f.size and not np.any(f < RIGID_BELOW_HZ) and not rigid_body_modes(fe).indices:
        # a free wheelset's receptance below its first flexible mode is its rigid-body mass line (thesis eq. 2.28
        # with the rigid modes): without them the model is wrong there by orders of magnitude, and its mass cannot
        # be checked; many solvers leave them out when asked for modes from a frequency above 0 Hz
        raise MassNormalisationError(
            f"{fe.source or 'FE modes'}: the export holds no rigid-body modes (its lowest mode is at {f.min():.4g} Hz, "
            f"none below {RIGID_BELOW_HZ:g} Hz, and {rigid_body_modes(fe).reason}): the model of a free wheelset "
            f"needs its six rigid-body modes (its mass and inertia carry the receptance below the first flexible "
            f"mode, and check the shapes' normalisation); export the modes from 0 Hz (e.g. Nastran EIGRL with V1 "
            f"blank, Abaqus or CalculiX *FREQUENCY without a lower bound, ANSYS MODOPT with FREQB = 0, and no "
            f"support in the modal step)")
    rb = check_mass_normalisation(fe, total_mass=total_mass, mass_matrix=mass_matrix)
    if rb is None or total_mass is not None or expect != "wheelset":
        return rb
    lo, hi = WHEELSET_MASS_KG["physical"]
    tlo, thi = WHEELSET_MASS_KG["typical"]
    src = fe.source or "FE modes"
    if not lo <= rb.mass <= hi:
        raise MassNormalisationError(
            f"{src}: the rigid-body modes imply a wheelset mass of {rb.mass:.4g} kg, outside the physical range "
            f"{lo:g}–{hi:g} kg of a railway wheelset: the shapes are not mass-normalised (scaled by about "
            f"{np.sqrt(np.sqrt(tlo * thi) / rb.mass):.3g}?) or not in SI units{_unit_system_hint(fe, rb.mass)}; give "
            f"the true mass to check against (total_mass= / --total-mass)")
    if not tlo <= rb.mass <= thi:
        warnings.warn(f"{src}: the rigid-body modes imply a wheelset mass of {rb.mass:.4g} kg, outside the typical "
                      f"{tlo:g}–{thi:g} kg; check the FE export's normalisation and units", UserWarning, stacklevel=2)
    return rb


def hybrid_model(
    fe: FEModes,
    pairing,
    *,
    points: Mapping[str, Point] | None = None,
    keep_fe: str | Sequence[int] = "none",
    default_zeta: float = DEFAULT_ZETA,
    rigid_below_hz: float = RIGID_BELOW_HZ,
    name: str = "hybrid model",
    max_hz: float | None = None,
) -> ModalModel:
    """Build the hybrid modal model from a pairing (thesis §2.3 and Table 3.1).

    Parameters
    ----------
    fe : FEModes
        The FE export the pairing was made against (mass-normalised shapes).
    pairing : Pairing, DataFrame or path
        See :func:`read_pairing_table`.
    points : dict of str -> Point, optional
        Named points (``receptance.dofs.read_points("points.csv")``).
    keep_fe : {"none", "unpaired", "all"} or sequence of int
        FE modes without a test partner to keep, with their FE frequency and
        ``default_zeta``: ``"none"`` (thesis policy, default), ``"unpaired"``
        (those the pairing table lists as FE-only, i.e. in the test band),
        ``"all"`` (every FE mode of the export), or 1-based FE mode numbers.
    default_zeta : float
        Damping ratio of kept FE-only modes.
    rigid_below_hz : float
        FE modes below this frequency are rigid-body modes (frequency set to 0).
    name : str
    max_hz : float, optional
        Highest mode frequency the model reports (see
        :attr:`ModalModel.max_hz`).  With ``keep_fe="all"`` and an FE export
        reaching a few times the test band, set it to the band's top: the FE
        modes above serve as the basis of structural modifications (bearings,
        joints) without adding out-of-band terms the test band does not hold.

    Returns
    -------
    ModalModel
    """
    table = read_pairing_table(pairing)
    check_pairing(table, fe)
    n_fe = len(fe)
    if not 0 <= default_zeta < 1:
        raise ModelError(f"default_zeta must lie in [0, 1), got {default_zeta!r}")
    f_fe = fe.freqs_hz
    freqs = np.full(n_fe, np.nan)
    zeta = np.full(n_fe, np.nan)
    origin = [""] * n_fe
    test_mode = np.full(n_fe, np.nan)
    rigid = np.flatnonzero(f_fe < rigid_below_hz)
    found = _rigid_modes(fe)
    if found and set(found) != set(rigid.tolist()):
        # a free-free run shifted or on soft springs puts them at a few Hz; their shapes tell them (fem_import)
        log.info("%s: rigid-body modes told by their shapes: %s", fe.source or "FE modes",
                 ", ".join(f"{j + 1} ({f_fe[j]:.3g} Hz)" for j in found))
        rigid = np.array(sorted(found), int)
    freqs[rigid], zeta[rigid] = 0.0, 0.0
    for j in rigid:
        origin[j] = "rigid"

    shapes = fe.shapes.copy()
    paired = table[table["fe_modes"].str.strip().ne("") & table["test_mode"].notna()]
    for text, rows in paired.groupby("fe_modes", sort=False):
        members = _members(text, n_fe, int(rows.index[0]) + 2)
        members = sorted(members, key=lambda j: f_fe[j])
        rows = rows.sort_values("f_test_hz")
        if len(members) > 1 and len(rows) > 1:
            shapes[members] = _rotate_cluster(fe.shapes[members], rows, text)
        ft, zt, tm = rows["f_test_hz"].to_numpy(float), rows["zeta"].to_numpy(float), rows["test_mode"].to_numpy(float)
        if np.any(~np.isfinite(ft)) or np.any(ft <= 0):
            raise ModelError(f"pairing rows for FE mode(s) {text}: test frequency must be > 0 Hz, got {ft.tolist()}")
        if np.any(~np.isfinite(zt)) or np.any((zt < 0) | (zt >= 1)):
            raise ModelError(f"pairing rows for FE mode(s) {text}: damping must lie in [0, 1), got {zt.tolist()}")
        for k, j in enumerate(members):
            if origin[j] == "rigid":
                raise ModelError(f"FE mode {j + 1} is a rigid-body mode ({f_fe[j]:.3g} Hz) but is paired with test "
                                 f"mode(s) {tm.tolist()}")
            if origin[j] == "test":
                raise ModelError(f"FE mode {j + 1} is paired twice in the pairing table")
            if len(rows) == 1:
                freqs[j], zeta[j], test_mode[j] = ft[0], zt[0], tm[0]
            elif k < len(rows):
                freqs[j], zeta[j], test_mode[j] = ft[k], zt[k], tm[k]
            else:
                freqs[j], zeta[j] = ft.mean(), zt.mean()
            origin[j] = "test"

    unpaired_table = table[table["test_mode"].isna()]
    listed_fe_only = sorted({j for r, t in zip(unpaired_table.index, unpaired_table["fe_modes"])
                             for j in _members(t, n_fe, int(r) + 2)})
    if isinstance(keep_fe, str):
        if keep_fe == "none":
            keep = []
        elif keep_fe == "unpaired":
            keep = listed_fe_only
        elif keep_fe == "all":
            keep = list(range(n_fe))
        else:
            raise ModelError(f"keep_fe must be 'none', 'unpaired', 'all' or FE mode numbers, got {keep_fe!r}")
    else:
        # the numbers the export gives its modes (fem_import: FEModes.mode_numbers, 1..n when it gives none)
        keep = []
        for k in keep_fe:
            try:
                keep.append(fe.mode_index(int(k)))
            except KeyError as exc:
                raise ModelError(f"keep_fe: {exc.args[0]}") from None
    for j in keep:
        if origin[j] == "":
            freqs[j], zeta[j], origin[j] = f_fe[j], default_zeta, "fe"

    dropped_band = [j for j in listed_fe_only if origin[j] == ""]
    if dropped_band:
        log.info("FE-only modes in the test band left out (thesis Table 3.1 policy; keep_fe= keeps them): %s",
                 ", ".join(f"{j + 1} ({f_fe[j]:.1f} Hz)" for j in dropped_band))
    test_only = table[table["fe_modes"].str.strip().eq("") & table["test_mode"].notna()]
    if len(test_only):
        log.info("test modes without FE partner (not in the hybrid model): %s",
                 ", ".join(f"{int(t)} ({f:.1f} Hz)" for t, f in zip(test_only["test_mode"], test_only["f_test_hz"])))
    if max_hz is not None and f_fe.max() < 2 * max_hz:
        log.warning("%s: the FE export stops at %.0f Hz, under twice the model's %.0f Hz: structural modifications "
                    "(bearings, joints) need modes above the band as their basis; export to a few times the band",
                    fe.source or "FE modes", f_fe.max(), max_hz)
    kept = np.array([j for j in range(n_fe) if origin[j]], int)
    if not np.any([origin[j] == "test" for j in kept]):
        raise ModelError("the pairing pairs no test mode with an FE mode; nothing to build a hybrid model from")
    if points:
        _warn_if_not_railway_frame(points, fe)
    sub = FEModes(fe.node_ids, fe.xyz, fe.elements, f_fe[kept], shapes[kept], fe.modal_mass[kept],
                  source=fe.source, format=fe.format, units=fe.units, history=fe.history,
                  mode_numbers=fe.mode_numbers[kept])
    n_test = sum(origin[j] == "test" for j in kept)
    return ModalModel(sub, freqs[kept], zeta[kept], tuple(origin[j] for j in kept), kept + 1, test_mode[kept],
                      points=points or {}, name=name, max_hz=max_hz,
                      test_only=tuple(zip(test_only["f_test_hz"].astype(float), test_only["zeta"].astype(float))),
                      history=(f"hybrid model from {fe.source or 'FE modes'}: {n_test} modes with test frequency and "
                               f"damping, {sum(origin[j] == 'fe' for j in kept)} FE-only, {len(rigid)} rigid",))


def _warn_if_not_railway_frame(points: Mapping[str, Point], fe: FEModes) -> None:
    """A model whose points are not in the railway frame compares with the lab's tables of its own frame, but its
    ``:z`` DOFs are not vertical: the field side refuses it and the geometric effects do not apply (said once)."""
    from .frame import check_railway_frame

    try:
        check_railway_frame(points, fe, what=f"the hybrid model of {fe.source or 'the FE modes'}")
    except DofError as exc:
        log.warning("%s. The lab comparison in the FE's own frame is unaffected.", exc)


def _rigid_modes(fe: FEModes) -> tuple[int, ...]:
    """Positions of the six rigid-body modes told by their shapes (:func:`fem_import.rigid_body_modes`), or ()."""
    from fem_import.checks import rigid_body_modes

    try:
        return tuple(rigid_body_modes(fe).indices)
    except (ValueError, np.linalg.LinAlgError):
        return ()


def _unit_system_hint(fe: FEModes, mass_kg: float) -> str:
    """", as an FE in mm-t-s would (declare it: --fe-units mm-t-s)" when a solver's unit system read as SI explains a
    wheelset mass outside the physical range (the file not stating its units), else ""."""
    from fem_import.checks import _units_stated
    from fem_import.modes import UNIT_SYSTEMS

    if _units_stated(fe):
        return ""
    tlo, thi = WHEELSET_MASS_KG["typical"]
    fits = [name for name, (_, mk) in UNIT_SYSTEMS.items() if mk != 1.0 and tlo <= mass_kg * mk <= thi]
    if not fits:
        return ""
    return (f" — read in {fits[0]} it would weigh {mass_kg * UNIT_SYSTEMS[fits[0]][1]:.4g} kg: the file states no "
            f"units; declare them (fem_import.read_with_geometry(..., units={fits[0]!r}) / --fe-units {fits[0]})")
