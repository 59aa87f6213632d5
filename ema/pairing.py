"""Pairing of experimental modes with FE modes by MAC (thesis §3.5, Table 3.1).

The FE shapes are evaluated at the test DOFs (sensor positions and measuring
directions, rigidly attached to their FE nodes), the MAC matrix is formed and
a one-to-one assignment (Hungarian method, ``scipy.optimize.linear_sum_assignment``)
maximises the total MAC less a small penalty on the frequency distance
(``|ln(f_test / f_fe)|``, so a 10 % distance costs 0.1 of MAC); pairs below a
MAC threshold are not pairs.

Axisymmetric wheelsets have repeated FE eigenvalues (bending in two planes,
wheel modes with nodal diameters), which an FE solver exports as arbitrary
mixtures. A test mode is therefore compared with the *subspace* of a
degenerate FE cluster: the subspace MAC is the share of the test shape that
lies in the span of the cluster's shapes at the test DOFs, and the FE shape
reported for the pair is the combination of the cluster's modes that best
matches the test shape (still mass-normalised, since the cluster's shapes
are mass-orthonormal and the combination has unit norm). For modes merged
from several setups the subspace MAC is evaluated per setup block (each
block may have captured another member of a degenerate pair, since each
setup's hammer excites its own combination) and summed with the blocks'
weights. A cluster can take
as many test modes as it has members (two setups may see both planes of a
bending pair), and only if they match different combinations of its members.

Experimental modes without an FE partner and FE modes without a test
partner are listed, not dropped.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.optimize import linear_sum_assignment

from fem_import.modes import FEModes

from .lsfd import mac
from .modeset import ModeSet

__all__ = ["mac_matrix", "fe_clusters", "Pair", "Pairing", "pair_modes", "fe_shapes_at_dofs", "describe_fe_mode"]

log = logging.getLogger("ema")


def mac_matrix(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Modal assurance criterion between the columns of ``a`` (n, p) and ``b`` (n, q).

    :func:`ema.lsfd.mac`, except that rows where either shape is NaN (a DOF
    not measured for that mode, in merged setups) are left out of that pair.
    """
    a = np.asarray(a)
    b = np.asarray(b)
    if a.shape[0] != b.shape[0]:
        raise ValueError(f"shapes must share the DOF axis: {a.shape[0]} vs {b.shape[0]} rows")
    if np.all(np.isfinite(a)) and np.all(np.isfinite(b)):
        return mac(a, b)
    out = np.zeros((a.shape[1], b.shape[1]))
    for i in range(a.shape[1]):
        for j in range(b.shape[1]):
            ok = np.isfinite(a[:, i]) & np.isfinite(b[:, j])
            out[i, j] = mac(a[ok, i], b[ok, j])[0, 0] if ok.any() else 0.0
    return out


def fe_clusters(freqs_hz: np.ndarray, rtol: float = 1e-4) -> list[list[int]]:
    """Groups of FE modes with repeated eigenvalues (relative spread below ``rtol``); rigid modes (< 0.1 Hz) together."""
    clusters: list[list[int]] = []
    for i in np.argsort(freqs_hz):
        f = freqs_hz[i]
        if clusters:
            f0 = freqs_hz[clusters[-1][0]]
            if (f < 0.1 and f0 < 0.1) or abs(f - f0) <= rtol * max(f0, 1e-9):
                clusters[-1].append(int(i))
                continue
        clusters.append([int(i)])
    return clusters


def fe_shapes_at_dofs(fe: FEModes, channels: pd.DataFrame, *, tolerance: float = 0.05) -> np.ndarray:
    """FE shapes at the test DOFs described by a channel table (node position, direction, fe_node): (n_dof, m_fe)."""
    fe_nodes = channels["fe_node"].tolist() if "fe_node" in channels else [None] * len(channels)
    fe_nodes = [None if (n is None or (isinstance(n, float) and np.isnan(n))) else int(n) for n in fe_nodes]
    names = ([f"channel {n!r}" + (f" (setup {s})" if isinstance(s, str) and s else "")
              for n, s in zip(channels["name"], channels["setup"] if "setup" in channels else [""] * len(channels))]
             if "name" in channels else None)
    return fe.at_points(
        fe_nodes,
        channels[["x", "y", "z"]].to_numpy(float),
        channels[["dx", "dy", "dz"]].to_numpy(float),
        tolerance=tolerance,
        names=names,
        max_offset="model",
    )


def describe_fe_mode(fe: FEModes, shape: np.ndarray | int) -> str:
    """A short description of an FE shape from its kinematics about the y (axle) axis.

    Heuristic, for wheelset-like models: nodes on the axle axis (radius
    < 5 mm) show torsion as rotation about y, bending as x/z translation and
    axial motion as y translation; nodes of the wheels and discs (radius
    > 0.2 m) show out-of-plane (y) motion, whose circumferential harmonic on
    each ring gives the nodal diameters. ``shape`` is an (n_nodes, n_dof)
    array or the index of one of ``fe``'s modes.
    """
    if isinstance(shape, (int, np.integer)):
        if fe.freqs_hz[shape] < 0.1:
            return "rigid body"
        shape = fe.shapes[shape]
    u = np.asarray(shape, float)
    r = np.hypot(fe.xyz[:, 0], fe.xyz[:, 2])
    on_axis = r < 5e-3
    if not on_axis.any() or u.shape[1] < 6:
        return "flexible mode"
    ax = u[on_axis]
    # rotation about y times a typical axle radius makes torsion comparable with translations
    parts = {
        "torsion": np.sum((0.08 * ax[:, 4]) ** 2),
        "bending (x)": np.sum(ax[:, 0] ** 2),
        "bending (z)": np.sum(ax[:, 2] ** 2),
        "axial": np.sum(ax[:, 1] ** 2),
    }
    off = r > 0.2
    rings = {}
    for k in np.flatnonzero(off):
        rings.setdefault((round(fe.xyz[k, 1], 3), round(r[k], 3)), []).append(k)
    harmonics = np.zeros(5)
    wheel = 0.0
    for idx in rings.values():
        idx = np.array(idx)
        theta = np.arctan2(fe.xyz[idx, 2], fe.xyz[idx, 0])
        uy = u[idx, 1]
        wheel += np.mean(uy**2)
        harmonics += [abs(np.mean(uy * np.exp(-1j * n * theta))) for n in range(5)]
    parts["wheel/disc out-of-plane"] = wheel / max(len(rings), 1) * on_axis.sum()
    kind = max(parts, key=parts.get)
    if kind == "wheel/disc out-of-plane":
        return f"{kind} ({int(np.argmax(harmonics))} nodal diameters)"
    return kind


@dataclass(frozen=True)
class Pair:
    """One test mode paired with an FE mode or a degenerate FE cluster."""

    test_index: int
    fe_indices: tuple[int, ...]
    mac: float
    fe_shape: np.ndarray  # (n_nodes, n_dof) best-matching FE shape (cluster combination), mass-normalised
    weights: tuple[float, ...] = ()  # unit-norm combination of the cluster members giving fe_shape


@dataclass(frozen=True)
class Pairing:
    """Result of :func:`pair_modes`.

    Attributes
    ----------
    pairs : tuple of Pair
    mac : ndarray (m_test, m_fe)
        Plain MAC between test modes and FE modes.
    subspace_mac : ndarray (m_test, n_clusters)
        MAC with each degenerate FE cluster's subspace.
    clusters : list of list of int
    unpaired_test : tuple of int
    unpaired_fe : tuple of int
        FE modes in the band without a test partner (rigid modes excluded).
    table : pandas.DataFrame
        Thesis Table 3.1 style: ``test_mode, f_test_hz, fe_modes, fe_mode_numbers, f_fe_hz, df_pct, zeta, mac,
        setup, fe_weights, description`` (``fe_modes``: the ``+``-joined 1-based positions of the FE modes in
        the export, what :func:`receptance.hybrid_model` reads back; ``fe_mode_numbers``: the same modes by the
        numbers the FE file gives them, :attr:`~fem_import.modes.FEModes.mode_numbers`, which differ from the
        positions when the export starts at another number or leaves modes out; ``fe_weights``: the
        ``;``-joined unit-norm combination of a degenerate cluster's members that matches the test mode),
        with unpaired modes of either side as rows with empty partner fields.
    """

    pairs: tuple[Pair, ...]
    mac: np.ndarray
    subspace_mac: np.ndarray
    clusters: list
    unpaired_test: tuple[int, ...]
    unpaired_fe: tuple[int, ...]
    table: pd.DataFrame = field(repr=False)

    def to_csv(self, path) -> None:
        self.table.to_csv(path, index=False, float_format="%.6g")


def _setup_blocks(test: ModeSet) -> list[np.ndarray]:
    """Row masks of the DOFs measured in each setup (one block when the channels name no setup)."""
    if "setup" not in test.channels or test.channels["setup"].isna().all():
        return [np.ones(len(test.dofs), bool)]
    setups = test.channels["setup"].astype(str).to_numpy()
    return [setups == s for s in dict.fromkeys(setups)]


def _subspace(B: np.ndarray, rel: float = 1e-3) -> np.ndarray:
    U, s, _ = np.linalg.svd(B, full_matrices=False)
    if s.size == 0 or s[0] == 0:
        return U[:, :0]
    return U[:, s > rel * s[0]]


def pair_modes(
    test: ModeSet,
    fe: FEModes,
    *,
    threshold: float = 0.8,
    band_hz: tuple[float, float] | None = None,
    degenerate_rtol: float = 1e-4,
    tolerance: float = 0.05,
    frequency_weight: float = 1.0,
) -> Pairing:
    """Pair experimental modes with FE modes by (subspace) MAC and one-to-one assignment.

    Parameters
    ----------
    test : ModeSet
        Identified modes (possibly merged from several setups; unmeasured DOFs NaN).
    fe : FEModes
    threshold : float
        Minimum MAC for a pair.
    band_hz : (float, float), optional
        FE modes outside this band are not candidates (default: the test
        frequency range widened by 30 %).
    degenerate_rtol : float
        Relative frequency spread below which FE modes form a degenerate cluster.
    tolerance : float
        Largest sensor-to-FE-node distance accepted when a channel has no ``fe_node`` [m].
    frequency_weight : float
        Weight of ``|ln(f_test / f_fe)|`` subtracted from the MAC in the
        assignment (0 for MAC only); pairs still need ``MAC >= threshold``.

    Returns
    -------
    Pairing
    """
    C = fe_shapes_at_dofs(fe, test.channels, tolerance=tolerance)
    phi = test.shapes
    mac = mac_matrix(phi, C)
    if band_hz is None:
        lo = 0.7 * float(test.freqs_hz.min()) if len(test) else 0.0
        hi = 1.3 * float(test.freqs_hz.max()) if len(test) else np.inf
        band_hz = (lo, hi)
    clusters = [c for c in fe_clusters(fe.freqs_hz, degenerate_rtol) if fe.freqs_hz[c[0]] >= 0.1]
    clusters = [c for c in clusters if band_hz[0] <= fe.freqs_hz[c[0]] <= band_hz[1]]
    blocks = _setup_blocks(test)
    sub = np.zeros((len(test), len(clusters)))
    for k, c in enumerate(clusters):
        for i in range(len(test)):
            captured = total = 0.0
            for rows in blocks:
                ok = rows & np.isfinite(phi[:, i])
                if not ok.any():
                    continue
                U = _subspace(C[np.ix_(ok, c)])
                x = phi[ok, i]
                total += np.vdot(x, x).real
                captured += float(np.sum(np.abs(U.conj().T @ x) ** 2)) if U.size else 0.0
            sub[i, k] = captured / total if total > 0 else 0.0
    # capacity: a cluster takes at most as many test modes as it has members
    cols = [k for k, c in enumerate(clusters) for _ in c]
    pairs: list[Pair] = []
    paired_test: set[int] = set()
    used_fe: set[int] = set()
    used_directions: dict[int, list[np.ndarray]] = {}
    # the assignment maximises MAC minus a frequency-distance penalty: when two test modes look
    # alike at the sensors (a weak, noisy shape can), the one nearer in frequency is the partner
    f_cluster = np.array([np.mean(fe.freqs_hz[c]) for c in clusters])
    score = sub - frequency_weight * np.abs(np.log(test.freqs_hz[:, None] / f_cluster[None, :])) if len(
        clusters) else sub
    if len(test) and cols:
        rows, picks = linear_sum_assignment(-score[:, cols])
        # best matches first: a later test mode may not reuse an FE combination already taken
        order = sorted(zip(rows, picks), key=lambda ij: -score[ij[0], cols[ij[1]]])
        for i, j in order:
            k = cols[j]
            if sub[i, k] < threshold:
                continue
            c = clusters[k]
            # the FE combination shown for the pair comes from the setup block that sees the mode best
            ok = max((rows & np.isfinite(phi[:, i]) for rows in blocks),
                     key=lambda r: float(np.sum(np.abs(phi[r, i]) ** 2)) if r.any() else -1.0)
            coef, *_ = np.linalg.lstsq(C[np.ix_(ok, c)], phi[ok, i], rcond=None)
            # FE modes are real: take the real combination closest to the (complex) test shape
            rot = coef * np.exp(-1j * np.angle(coef[np.argmax(np.abs(coef))]))
            rot = np.real(rot)
            if np.linalg.norm(rot) == 0:
                rot = np.eye(len(c))[0]
            rot = rot / np.linalg.norm(rot)
            # two test modes in one cluster must be different members of it (e.g. the x and the z
            # bending of a pair), not two test modes that both look like the same FE combination
            if any(abs(rot @ u) > 0.5 for u in used_directions.get(k, [])):
                log.info("test mode %d at %.2f Hz resembles FE mode(s) %s already paired with a better match",
                         i + 1, test.freqs_hz[i], _numbers(fe, c))
                continue
            used_directions.setdefault(k, []).append(rot)
            shape = np.tensordot(rot, fe.shapes[c], axes=1)
            pairs.append(Pair(int(i), tuple(c), float(sub[i, k]), shape, tuple(float(v) for v in rot)))
            paired_test.add(int(i))
            used_fe.update(c)
    pairs.sort(key=lambda p: test.freqs_hz[p.test_index])
    unpaired_test = tuple(i for i in range(len(test)) if i not in paired_test)
    unpaired_fe = tuple(j for c in clusters for j in c if j not in used_fe)
    for i in unpaired_test:
        log.info("test mode %d at %.2f Hz has no FE partner (best subspace MAC %.2f)", i + 1, test.freqs_hz[i],
                 sub[i].max() if sub.size else 0.0)
    table = _table(test, fe, pairs, unpaired_test, unpaired_fe)
    return Pairing(tuple(pairs), mac, sub, clusters, unpaired_test, unpaired_fe, table)


def _numbers(fe: FEModes, indices) -> str:
    """The FE file's numbers of the modes at ``indices`` (0-based positions), ``+``-joined."""
    return "+".join(str(int(fe.mode_numbers[j])) for j in indices)


def _table(test: ModeSet, fe: FEModes, pairs, unpaired_test, unpaired_fe) -> pd.DataFrame:
    rows = []
    for p in pairs:
        f_t = test.freqs_hz[p.test_index]
        f_fe = float(np.mean(fe.freqs_hz[list(p.fe_indices)]))
        rows.append(
            {
                "test_mode": p.test_index + 1,
                "f_test_hz": f_t,
                "fe_modes": "+".join(str(j + 1) for j in p.fe_indices),
                "fe_mode_numbers": _numbers(fe, p.fe_indices),
                "f_fe_hz": f_fe,
                "df_pct": 100 * (f_fe - f_t) / f_t,
                "zeta": test.zeta[p.test_index],
                "mac": p.mac,
                "setup": test.setup[p.test_index],
                "fe_weights": ";".join(f"{w:.6f}" for w in p.weights),
                "description": describe_fe_mode(fe, p.fe_shape),
            }
        )
    for i in unpaired_test:
        rows.append(
            {"test_mode": i + 1, "f_test_hz": test.freqs_hz[i], "fe_modes": "", "fe_mode_numbers": "",
             "f_fe_hz": np.nan, "df_pct": np.nan,
             "zeta": test.zeta[i], "mac": np.nan, "setup": test.setup[i], "fe_weights": "",
             "description": "test only (no FE partner)"}
        )
    for j in unpaired_fe:
        rows.append(
            {"test_mode": np.nan, "f_test_hz": np.nan, "fe_modes": str(j + 1), "fe_mode_numbers": _numbers(fe, [j]),
             "f_fe_hz": fe.freqs_hz[j],
             "df_pct": np.nan, "zeta": np.nan, "mac": np.nan, "setup": "", "fe_weights": "",
             "description": f"FE only: {describe_fe_mode(fe, j)}"}
        )
    df = pd.DataFrame(rows, columns=["test_mode", "f_test_hz", "fe_modes", "fe_mode_numbers", "f_fe_hz", "df_pct",
                                     "zeta", "mac", "setup", "fe_weights", "description"])
    key = df["f_test_hz"].fillna(df["f_fe_hz"])
    return df.iloc[np.argsort(key.to_numpy(), kind="stable")].reset_index(drop=True)
