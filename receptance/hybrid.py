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
from receptance.dofs import Point
from receptance.modal_model import ModalModel, ModelError

__all__ = ["hybrid_model", "read_pairing_table", "DEFAULT_ZETA", "RIGID_BELOW_HZ"]

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
        path = Path(source)
        if path.is_dir():
            path = path / "pairing.csv"
        if not path.is_file():
            raise ModelError(f"{path}: no pairing table there; run 'railmodal lab pair' first")
        try:
            df = pd.read_csv(path, dtype={"fe_modes": str, "fe_weights": str})
        except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
            raise ModelError(f"{path}: cannot read the pairing table: {exc}") from exc
        where = str(path)
    missing = [c for c in _PAIRING_COLUMNS if c not in df.columns]
    if missing:
        raise ModelError(f"{where}: pairing table lacks column(s) {missing}; expected the columns of "
                         f"'railmodal lab pair' (test_mode, f_test_hz, fe_modes, f_fe_hz, zeta, mac, ...)")
    df["fe_modes"] = df["fe_modes"].astype(object).where(df["fe_modes"].notna(), "").astype(str)
    if "fe_weights" in df:
        df["fe_weights"] = df["fe_weights"].astype(object).where(df["fe_weights"].notna(), "").astype(str)
    return df


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
    n_fe = len(fe)
    if not 0 <= default_zeta < 1:
        raise ModelError(f"default_zeta must lie in [0, 1), got {default_zeta!r}")
    f_fe = fe.freqs_hz
    freqs = np.full(n_fe, np.nan)
    zeta = np.full(n_fe, np.nan)
    origin = [""] * n_fe
    test_mode = np.full(n_fe, np.nan)
    rigid = np.flatnonzero(f_fe < rigid_below_hz)
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
        keep = [int(k) - 1 for k in keep_fe]
        bad = [k + 1 for k in keep if not 0 <= k < n_fe]
        if bad:
            raise ModelError(f"keep_fe: FE mode(s) {bad} not in the FE export (modes 1–{n_fe})")
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
    sub = FEModes(fe.node_ids, fe.xyz, fe.elements, f_fe[kept], shapes[kept], fe.modal_mass[kept],
                  source=fe.source, format=fe.format, units=fe.units, history=fe.history)
    n_test = sum(origin[j] == "test" for j in kept)
    return ModalModel(sub, freqs[kept], zeta[kept], tuple(origin[j] for j in kept), kept + 1, test_mode[kept],
                      points=points or {}, name=name, max_hz=max_hz,
                      test_only=tuple(zip(test_only["f_test_hz"].astype(float), test_only["zeta"].astype(float))),
                      history=(f"hybrid model from {fe.source or 'FE modes'}: {n_test} modes with test frequency and "
                               f"damping, {sum(origin[j] == 'fe' for j in kept)} FE-only, {len(rigid)} rigid",))
