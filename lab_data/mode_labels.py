"""Names, degenerate clusters and truth damping of the wheelset's modes.

Each mode is classified by where it stores its strain energy (axle torsion,
axle bending, wheel web and rim, disc, bearings, press-fit joints, rig
springs, ...), so the manifest can say "torsion 1" or "flexural 2 (z)" like
thesis Table 3.1. Axisymmetric wheelsets have repeated eigenvalues (bending
in the x and z planes, wheel modes with nodal diameters); these clusters are
found and rotated within their subspace to a readable basis (pure x / pure z
planes) for the truth, while the design FE export keeps the arbitrary
mixture a solver produces.

The truth's modal damping follows thesis Table 3.1 (0.011 %–0.43 %) by
family and order; modes of the hidden effects get the damping of the physical
component (rolling bearings and crane coil springs 0.5 %; the tuned absorber
of the ``absorber`` scenario 2 %, since an absorber works through its
damping).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable

import numpy as np

from .fe_model import FEModel, Modes, SystemMatrices, rigid_body_vectors

__all__ = [
    "ModeLabel",
    "energy_fractions",
    "label_modes",
    "degenerate_clusters",
    "align_clusters",
    "mix_clusters",
    "truth_damping",
    "bending_plane",
    "relabel_plane",
    "renumber",
    "DAMPING_TABLE",
]

#: Modal damping ratios by family and order (thesis Table 3.1), then the last value repeats.
DAMPING_TABLE: dict[str, tuple[float, ...]] = {
    "flexural": (0.00428, 0.00098, 0.00129, 0.00424, 0.0025, 0.002),
    "torsion": (0.00141, 0.00034, 0.00043, 0.0005),
    "wheel": (0.00052, 0.0003, 0.00011, 0.0002),
    "disc": (0.0005,),
    "axial": (0.0005,),
    "bearing": (0.005,),
    "joint": (0.003,),
    "rig": (0.005,),
    "absorber": (0.02,),
    "suspension": (0.05,),
    "other": (0.0005,),
}

_ORDINAL = {1: "1st", 2: "2nd", 3: "3rd"}


def _ordinal(n: int) -> str:
    return _ORDINAL.get(n, f"{n}th")


@dataclass(frozen=True)
class ModeLabel:
    """What a mode is.

    Attributes
    ----------
    family : str
        ``rigid``, ``flexural``, ``torsion``, ``wheel``, ``disc``, ``axial``,
        ``bearing``, ``joint``, ``rig``, ``absorber``, ``suspension`` or ``other``.
    order : int
        1-based order within the family, counting a degenerate cluster once.
    plane : str
        ``x`` or ``z`` for flexural modes, else ``""``.
    nodal_diameters : int
        For wheel and disc modes, the dominant number of nodal diameters; -1 otherwise.
    description : str
        Human-readable, e.g. ``"2nd flexural (z)"``.
    energy : dict of str to float
        Strain-energy fractions by family.
    """

    family: str
    order: int
    plane: str
    nodal_diameters: int
    description: str
    energy: dict


def _family_of_key(key: str) -> str:
    group, _, part = key.partition("/")
    if group == "axle":
        return {"torsion": "torsion", "bending": "flexural", "axial": "axial"}[part]
    for prefix, fam in (
        ("wheel", "wheel"),
        ("disc", "disc"),
        ("bearing", "bearing"),
        ("joint", "joint"),
        ("rig", "rig"),
        ("absorber", "absorber"),
        ("primary", "suspension"),
    ):
        if group.startswith(prefix):
            return fam
    return "other"


def energy_fractions(system: SystemMatrices, vectors: np.ndarray) -> list[dict[str, float]]:
    """Strain-energy fraction per family for each column of ``vectors`` (full DOFs)."""
    out = []
    energies = {k: np.einsum("im,im->m", vectors, K @ vectors) for k, K in system.stiffness.items()}
    total = sum(energies.values())
    for j in range(vectors.shape[1]):
        fam: dict[str, float] = {}
        if total[j] <= 0:
            out.append(fam)
            continue
        for k, e in energies.items():
            f = _family_of_key(k)
            fam[f] = fam.get(f, 0.0) + float(e[j] / total[j])
        out.append(fam)
    return out


def degenerate_clusters(freqs_hz: np.ndarray, rtol: float = 1e-6) -> list[list[int]]:
    """Groups of consecutive mode indices whose frequencies agree within ``rtol`` (relative).

    Zero-frequency modes are one cluster. Singletons are returned too.
    """
    clusters: list[list[int]] = []
    for i, f in enumerate(freqs_hz):
        if clusters:
            f0 = freqs_hz[clusters[-1][0]]
            if abs(f - f0) <= rtol * max(f0, 1e-3) or (f < 1e-3 and f0 < 1e-3):
                clusters[-1].append(i)
                continue
        clusters.append([i])
    return clusters


def _plane_energy(model: FEModel, system: SystemMatrices, vecs: np.ndarray, axis: int) -> np.ndarray:
    # kinetic energy carried by translations along one global axis
    sel = np.zeros(6 * model.n_nodes)
    sel[axis::6] = 1.0
    M = system.M
    return (vecs * sel[:, None]).T @ (M @ (vecs * sel[:, None]))


def align_clusters(model: FEModel, system: SystemMatrices, modes: Modes) -> Modes:
    """Rotate each degenerate cluster to the basis that separates x- and z-plane motion.

    Within a cluster any mass-orthonormal rotation is an equally valid set of
    modes; the eigenvectors of the z-translation kinetic-energy matrix
    restricted to the cluster give pure x-plane / pure z-plane bending for
    an axisymmetric wheelset, which is how a test engineer names them.
    """
    shapes = modes.reduced.copy()
    full = system.transform @ shapes
    for c in degenerate_clusters(modes.freqs_hz):
        if len(c) < 2 or modes.freqs_hz[c[0]] < 1e-3:
            continue
        Q = _plane_energy(model, system, full[:, c], 2)
        _, rot = np.linalg.eigh(0.5 * (Q + Q.T))
        shapes[:, c] = shapes[:, c] @ rot
    full = system.transform @ shapes
    return Modes(modes.freqs_hz.copy(), full.T.reshape(len(modes.freqs_hz), model.n_nodes, 6), shapes)


def mix_clusters(model: FEModel, system: SystemMatrices, modes: Modes, rng: np.random.Generator) -> Modes:
    """Apply a random orthogonal rotation inside each degenerate cluster (as an FE solver's arbitrary basis)."""
    shapes = modes.reduced.copy()
    for c in degenerate_clusters(modes.freqs_hz):
        if len(c) < 2 or modes.freqs_hz[c[0]] < 1e-3:
            continue
        q, _ = np.linalg.qr(rng.standard_normal((len(c), len(c))))
        shapes[:, c] = shapes[:, c] @ q
    full = system.transform @ shapes
    return Modes(modes.freqs_hz.copy(), full.T.reshape(len(modes.freqs_hz), model.n_nodes, 6), shapes)


def _nodal_diameters(model: FEModel, shape: np.ndarray, group: str) -> int:
    # rim/outer-ring axial motion around the circumference: its dominant harmonic
    nodes = model.nodes_of(group)
    idx = np.array([model.index(n) for n in nodes])
    xyz = model.xyz[idx]
    r = np.hypot(xyz[:, 0], xyz[:, 2])
    outer = np.isclose(r, r.max(), rtol=1e-6)
    theta = np.arctan2(xyz[outer, 2], xyz[outer, 0])
    order = np.argsort(theta)
    uy = shape[idx[outer], 1][order]
    spec = np.abs(np.fft.rfft(uy))
    return int(np.argmax(spec))


def bending_plane(model: FEModel, shape: np.ndarray) -> str:
    """``"x"`` or ``"z"``: the plane in which the axle's centreline moves most in this mode."""
    idx = np.array([model.index(n) for n in model.nodes_of("axle")])
    sh = shape[idx]
    return "x" if np.sum(sh[:, 0] ** 2) > np.sum(sh[:, 2] ** 2) else "z"


def relabel_plane(label: ModeLabel, model: FEModel, shape: np.ndarray) -> ModeLabel:
    """The label of a flexural mode whose shape was rotated within its cluster, with its plane re-read."""
    if label.family != "flexural":
        return label
    plane = bending_plane(model, shape)
    return replace(label, plane=plane, description=f"{_ordinal(label.order)} flexural ({plane})")


def renumber(label: ModeLabel, order: int) -> ModeLabel:
    """The same label with another order within its family."""
    rest = label.description.split(" ", 1)[1]
    return replace(label, order=order, description=f"{_ordinal(order)} {rest}")


def label_modes(
    model: FEModel, system: SystemMatrices, modes: Modes,
    plate_pattern: Callable[[str, int], tuple[int, str]] | None = None,
) -> list[ModeLabel]:
    """Classify every mode (family, order, plane, nodal diameters) from its strain energy.

    Rules: torsion if axle torsion holds > 50 % of the strain energy; rig,
    bearing, joint, absorber or suspension if those springs hold > 30 %;
    flexural if axle bending holds >= 20 % (wheel-rocking modes that bend
    the axle are flexural, as in thesis Table 3.1); otherwise the family
    holding most energy (wheel, disc, axial).

    ``plate_pattern(family, mode_index) -> (nodal_diameters, text)`` names a
    wheel or disc mode; by default the dominant harmonic of the outer ring's
    axial motion (``"2 nodal diameters"``), which needs meshed rings.
    """
    full = modes.full
    fracs = energy_fractions(system, full)
    clusters = degenerate_clusters(modes.freqs_hz)
    cluster_of = {i: k for k, c in enumerate(clusters) for i in c}
    counters: dict[str, int] = {}
    seen_cluster: dict[int, int] = {}
    rigid_names = ("translation x", "translation y", "translation z", "rotation x", "rotation y", "rotation z")
    labels = []
    M = system.M
    R = rigid_body_vectors(model, np.zeros(3))
    for i, f in enumerate(modes.freqs_hz):
        e = fracs[i]
        if f < 1e-3:
            coef = np.abs(R.T @ (M @ full[:, i]))
            nm = rigid_names[int(np.argmax(coef))] if coef.max() > 1e-6 else "mechanism"
            labels.append(ModeLabel("rigid", 0, "", -1, f"rigid body ({nm})", e))
            continue
        if e.get("torsion", 0) > 0.5:
            fam = "torsion"
        else:
            special = [k for k in ("rig", "bearing", "joint", "absorber", "suspension") if e.get(k, 0) > 0.3]
            if special:
                fam = max(special, key=lambda k: e[k])
            elif e.get("flexural", 0) >= 0.2:
                fam = "flexural"
            else:
                fam = max(e, key=e.get) if e else "other"
        k = cluster_of[i]
        if k in seen_cluster and labels[seen_cluster[k]].family == fam:
            order = labels[seen_cluster[k]].order
        else:
            counters[fam] = counters.get(fam, 0) + 1
            order = counters[fam]
            seen_cluster.setdefault(k, i)
        plane = ""
        nd = -1
        desc = f"{_ordinal(order)} {fam}"
        if fam == "flexural":
            plane = bending_plane(model, modes.shapes[i])
            desc += f" ({plane})"
        elif fam in ("wheel", "disc") and plate_pattern is not None:
            nd, text = plate_pattern(fam, i)
            desc += f" ({text})"
        elif fam in ("wheel", "disc"):
            groups = [g for g in (f"{fam}_L", f"{fam}_R")]
            amp = [np.sum(modes.shapes[i][[model.index(n) for n in model.nodes_of(g)]] ** 2) for g in groups]
            nd = _nodal_diameters(model, modes.shapes[i], groups[int(np.argmax(amp))])
            desc += f" ({nd} nodal diameters)"
        labels.append(ModeLabel(fam, order, plane, nd, desc, e))
    return labels


def truth_damping(labels: list[ModeLabel], freqs_hz: np.ndarray) -> np.ndarray:
    """Modal damping ratio per mode from :data:`DAMPING_TABLE`; a degenerate cluster shares one value."""
    zeta = np.zeros(len(labels))
    for i, lab in enumerate(labels):
        if lab.family == "rigid":
            continue
        table = DAMPING_TABLE.get(lab.family, DAMPING_TABLE["other"])
        zeta[i] = table[min(lab.order, len(table)) - 1]
    for c in degenerate_clusters(freqs_hz):
        zeta[c] = zeta[c[0]]
    return zeta
