"""Small hand-made wheelset FE models, in the styles a design office draws them, with an exact modal solution.

An independent oracle for the effects' attachment and physics (tests/test_effect_geometry.py): each model is
assembled here from 3D Euler–Bernoulli beams, 6-DOF springs, lumped masses and rigid links (master–slave
elimination), solved by a dense generalised eigenproblem (all modes, mass-normalised) and exported as
:class:`fem_import.modes.FEModes` with its element records — nothing of ``receptance`` is used.

Styles:

* axlebox ``"own_node"`` (its own node rigidly tied to the journal), ``"lumped"`` (its mass and inertia added to
  the journal node) or ``"absent"``; truth ``"bearing"``: its own node on bearing springs (radial x/z, axial y,
  rocking about x and z, free spin) with a loss factor;
* wheel ``"ring"`` (a hub node tied to the seat, a ring of rim nodes on spokes and ring beams) or ``"rim_body"``
  (the hub lumped on the seat node, the rim a rigid body at the wheel centre on 6-DOF web springs); truth
  ``"joint"``: the hub on press-fit springs to the seat.

The wheels' masses follow the layout :func:`receptance.diagnosis.geometry.wheel_attachment` assumes (rim ring,
a web of negligible mass, hub ring from half to the full hub radius) so the floating-frame effect is exact here.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from fem_import.modes import Element, FEModes

E_STEEL, NU = 206e9, 0.3
AXLE_Y = (-1.0, -0.85, -0.7, -0.35, 0.0, 0.35, 0.7, 0.85, 1.0)
D_AXLE = 0.17
R_WHEEL, R_RIM, R_HUB = 0.41, 0.38, 0.135
M_AXLE, M_RIM, M_WEB, M_WHEEL = 283.0, 150.0, 1e-3, 251.0
M_BOX, I_BOX = 78.0, (0.9, 1.2, 0.9)
N_RIM = 24


def hub_inertia(m_hub: float, r_hub: float = R_HUB) -> np.ndarray:
    """The hub as a thick ring from half the hub radius to the hub radius (the effect's assumption)."""
    ri, ro = 0.5 * r_hub, r_hub
    polar = m_hub * (ri**2 + ro**2) / 2
    return np.array([polar / 2, polar, polar / 2])


def _beam_k(xa, xb, E, G, A, Iy, Iz, J):
    """12x12 3D Euler-Bernoulli beam stiffness in global axes (translations then rotations at each end)."""
    L = float(np.linalg.norm(xb - xa))
    ex = (xb - xa) / L
    ref = np.array([0.0, 0.0, 1.0]) if abs(ex[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    ey = np.cross(ref, ex)
    ey /= np.linalg.norm(ey)
    ez = np.cross(ex, ey)
    R = np.vstack([ex, ey, ez])
    k = np.zeros((12, 12))
    a = E * A / L
    k[np.ix_([0, 6], [0, 6])] = a * np.array([[1, -1], [-1, 1]])
    t = G * J / L
    k[np.ix_([3, 9], [3, 9])] = t * np.array([[1, -1], [-1, 1]])
    # bending in the local x-y plane (v, θz) and in the local x-z plane (w, θy: opposite sign convention)
    for I, v, th, sgn in ((Iz, 1, 5, 1.0), (Iy, 2, 4, -1.0)):
        c = E * I / L**3
        idx = [v, th, v + 6, th + 6]
        kk = c * np.array([[12, 6 * L * sgn, -12, 6 * L * sgn],
                           [6 * L * sgn, 4 * L**2, -6 * L * sgn, 2 * L**2],
                           [-12, -6 * L * sgn, 12, -6 * L * sgn],
                           [6 * L * sgn, 2 * L**2, -6 * L * sgn, 4 * L**2]])
        k[np.ix_(idx, idx)] += kk
    T = np.zeros((12, 12))
    for b in range(4):
        T[3 * b:3 * b + 3, 3 * b:3 * b + 3] = R
    return T.T @ k @ T


class _Assembly:
    def __init__(self):
        self.ids, self.xyz, self.elements = [], [], []
        self.mass, self.springs, self.beams, self.links = {}, [], [], []

    def node(self, nid, xyz):
        self.ids.append(int(nid))
        self.xyz.append(np.asarray(xyz, float))
        return int(nid)

    def add_mass(self, nid, m, inertia):
        old = self.mass.get(nid, np.zeros(6))
        self.mass[nid] = old + np.array([m, m, m, *inertia], float)
        self.elements.append(Element(len(self.elements) + 1, 161, (nid,)))

    def beam(self, a, b, d_out, d_in=0.0):
        A = np.pi * (d_out**2 - d_in**2) / 4
        I = np.pi * (d_out**4 - d_in**4) / 64
        self.beams.append((a, b, A, I, I, 2 * I))
        self.elements.append(Element(len(self.elements) + 1, 21, (a, b)))

    def spring(self, a, b, k6, loss=0.0, export=True):
        self.springs.append((a, b, np.asarray(k6, float) * (1 + 1j * loss)))
        if export:
            self.elements.append(Element(len(self.elements) + 1, 136, (a, b)))

    def link(self, master, slave):
        self.links.append((master, slave))

    def solve(self) -> FEModes:
        ids = self.ids
        idx = {n: k for k, n in enumerate(ids)}
        xyz = np.array(self.xyz)
        n = len(ids) * 6
        K = np.zeros((n, n), complex)
        M = np.zeros((n, n))
        G = E_STEEL / (2 * (1 + NU))
        for a, b, A, Iy, Iz, J in self.beams:
            ke = _beam_k(xyz[idx[a]], xyz[idx[b]], E_STEEL, G, A, Iy, Iz, J)
            dofs = [6 * idx[a] + i for i in range(6)] + [6 * idx[b] + i for i in range(6)]
            K[np.ix_(dofs, dofs)] += ke
        for a, b, k6 in self.springs:
            for i in range(6):
                da, db = 6 * idx[a] + i, 6 * idx[b] + i
                K[da, da] += k6[i]
                K[db, db] += k6[i]
                K[da, db] -= k6[i]
                K[db, da] -= k6[i]
        for nid, m in self.mass.items():
            M[6 * idx[nid]:6 * idx[nid] + 6, 6 * idx[nid]:6 * idx[nid] + 6] += np.diag(m)
        # rigid links: slave = master transported (u_s = u_m + θ_m × r, θ_s = θ_m)
        slaves = {s: m for m, s in self.links}
        keep = [k for k, nid in enumerate(ids) if nid not in slaves]
        col = {ids[k]: j for j, k in enumerate(keep)}
        T = np.zeros((n, 6 * len(keep)))
        for k, nid in enumerate(ids):
            master = slaves.get(nid, nid)
            j = col[master]
            T[6 * k:6 * k + 6, 6 * j:6 * j + 6] = np.eye(6)
            if master != nid:
                r = xyz[k] - xyz[idx[master]]
                T[6 * k:6 * k + 3, 6 * j + 3:6 * j + 6] = -np.array([[0, -r[2], r[1]], [r[2], 0, -r[0]],
                                                                      [-r[1], r[0], 0]])
        Kr, Mr = T.T @ K @ T, T.T @ M @ T
        self.K_full, self.M_full, self.T = K, M, T
        if np.any(Kr.imag):
            return None  # a truth with lossy springs: solve with truth_frequencies
        w2, phi = scipy.linalg.eigh(Kr.real, Mr)
        w2 = np.clip(w2, 0, None)
        shapes = (T @ phi).T.reshape(len(w2), len(ids), 6)
        f = np.sqrt(w2) / (2 * np.pi)
        f[f < 0.1] = 0.0  # rigid-body modes (numerically a few mHz)
        return FEModes(np.array(ids), xyz, tuple(self.elements), f, shapes, np.ones(f.size), source="lumped test FE",
                       format="test")

    def frequencies(self) -> np.ndarray:
        """Natural frequencies ``|λ|/2π`` of the (possibly lossy) system, sorted (rigid-body modes dropped)."""
        Kr, Mr = self.T.T @ self.K_full @ self.T, self.T.T @ self.M_full @ self.T
        mu = scipy.linalg.eigvals(Kr, Mr)
        f = np.sqrt(np.abs(mu)) / (2 * np.pi)
        return np.sort(f[f > 0.1])


def build(axlebox: str = "own_node", wheel: str = "ring", *, scale: float = 1.0, id_offset: int = 0,
          bearing=(1e9, 2.5e8, 5e6), joint=(6e7, 2e9, 1e9, 2e8), web=(3e8, 1e9, 3e8, 2e7, 5e8, 2e7),
          loss: float = 0.01):
    """A lumped wheelset; returns ``(assembly, FEModes or None, points)``.

    ``axlebox``: ``own_node``, ``lumped``, ``absent`` or ``bearing`` (truth: own node on springs ``bearing`` =
    radial, axial, rocking); ``wheel``: ``ring``, ``rim_body``, or the truths ``joint`` (ring wheel whose hub sits
    on press-fit springs ``joint`` = rocking, radial, axial, torsional) and ``rim_joint`` (the same for the rim
    body). ``scale`` multiplies every length (the
    geometry must still be found), ``id_offset`` every node label. The lossy truths return None for the modes
    (use ``assembly.frequencies()``).
    """
    s = scale
    A = _Assembly()
    nid = lambda k: k + id_offset  # noqa: E731
    axle = [A.node(nid(101 + k), (0.0, s * y, 0.0)) for k, y in enumerate(AXLE_Y)]
    for a, b in zip(axle[:-1], axle[1:]):
        A.beam(a, b, s * D_AXLE, s * 0.06)
    m_node = M_AXLE / len(axle)
    for a in axle:
        A.add_mass(a, m_node, (s**2 * m_node * 0.01, s**2 * m_node * 0.004, s**2 * m_node * 0.01))
    points = {}
    for side, sgn, seat, journal in (("L", -1, axle[2], axle[0]), ("R", 1, axle[6], axle[8])):
        base = 1000 if side == "L" else 2000
        y = sgn * 0.7 * s
        m_hub = M_WHEEL - M_RIM - M_WEB
        if wheel in ("ring", "joint"):
            hub = A.node(nid(base), (0.0, y, 0.0))
            A.add_mass(hub, m_hub, hub_inertia(m_hub, s * R_HUB))
            if wheel == "ring":
                A.link(seat, hub)
            else:
                kr, kd, ka, kt = joint
                A.spring(seat, hub, (kd, ka, kd, kr, kt, kr), loss, export=False)
            rim = []
            for k in range(N_RIM):
                t = 2 * np.pi * (k + 0.5) / N_RIM
                r = A.node(nid(base + 1 + k), (s * R_RIM * np.cos(t), y, s * R_RIM * np.sin(t)))
                A.add_mass(r, M_RIM / N_RIM, (1e-4, 1e-4, 1e-4))
                A.beam(hub, r, s * 0.05)
                rim.append(r)
            for a, b in zip(rim, rim[1:] + rim[:1]):
                A.beam(a, b, s * 0.07)
            contact = rim[N_RIM * 3 // 4]  # the bottom of the wheel
        else:  # rim body on web springs; the hub lumped on the seat (truth "rim_joint": the hub on press-fit springs)
            hub = seat
            if wheel == "rim_joint":
                hub = A.node(nid(base + 100), (0.0, y, 0.0))
                kr, kd, ka, kt = joint
                A.spring(seat, hub, (kd, ka, kd, kr, kt, kr), loss, export=False)
            A.add_mass(hub, m_hub, hub_inertia(m_hub, s * R_HUB))
            r = A.node(nid(base), (0.0, y, 0.0))
            i_polar = M_RIM * (s * R_RIM) ** 2
            A.add_mass(r, M_RIM, (i_polar / 2, i_polar, i_polar / 2))
            A.spring(hub, r, web)
            contact = r
        points[f"contact_{side}"] = (contact, (0.0, s * sgn * 0.73, -s * R_WHEEL))
        box_xyz = (0.0, s * sgn * 1.0, 0.0)
        if axlebox == "lumped":
            A.add_mass(journal, M_BOX, I_BOX)
            points[f"axlebox_{side}"] = (journal, box_xyz)
        elif axlebox in ("own_node", "bearing"):
            box = A.node(nid(base + 500), box_xyz)
            A.add_mass(box, M_BOX, I_BOX)
            if axlebox == "own_node":
                A.link(journal, box)
            else:
                kr, ka, kroc = bearing
                A.spring(journal, box, (kr, ka, kr, kroc, 0.0, kroc), loss, export=False)
            points[f"axlebox_{side}"] = (box, box_xyz)
        else:
            points[f"axlebox_{side}"] = (journal, box_xyz)
    return A, A.solve(), points
