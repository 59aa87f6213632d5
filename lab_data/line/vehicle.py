"""The instrumented trailer bogie: two truth wheelsets, primary suspension, frame, secondary suspension.

Thesis §2.1 / Table 2.1: a *Meneghino* trailer bogie. Each wheelset is the
virtual lab's **as-built truth wheelset** of a lab scenario
(:func:`lab_data.truth.truth_modes`: the 3D FE with that scenario's hidden
effects — compliant bearings, press-fit joint, absorber, ...), entered as
its free-free modal model (mass-normalised FE shapes, the truth's modal
damping of thesis Table 3.1) up to :attr:`VehicleParameters.modal_cutoff_hz`
(default 3 kHz, six times the thesis band and above the wheel/rail contact
resonance), plus the quasi-static flexibility of all the FE's higher modes at
the contact points (the rim's local compliance, about 18 % of the Hertz
spring's). With it the coupled 20–400 Hz axlebox response moves by
≤ 0.003 dB from a 3 to a 4 kHz cut-off (≤ 0.07 dB from 2 to 3 kHz; without
it 0.23 dB from 3 to 4 kHz). The rigid-body modes are part of the basis, so
the wheelsets move on their suspension.

In service the axlebox centres hang on the primary suspension of Table 2.1
(two spring units per axlebox: 2 × 4.15 / 2.1 / 0.5 kN/mm along x / y / z;
dampers 85 / 50 / 11 kN s/m) from a rigid bogie frame; the frame sits on two
air springs (secondary suspension) that carry the static car-body load. The
car body itself is not simulated: above ~2 Hz it is an inertial ground for
the bogie (thesis §2.3 neglects even the bogie). Quasi-static curving loads
enter as a lateral body-force field ``a_y = v²κ − g·cant`` on every mass
and the car body's share transmitted through the air springs (lateral force
and roll moment).

The assembled system (wheelset modal coordinates + 6 frame DOFs, suspension
springs and dampers as couplings: non-proportional damping) is diagonalised
once in first-order (complex modal) form, :class:`Vehicle`. Zero-frequency
mechanisms that no load can excite (the wheelset's spin about its axle, an
axlebox spinning on compliant bearings) are removed; a mechanism that a load
*does* excite raises an error.

Frames: the vehicle frame is the lab FE's frame — x towards the vehicle's
front end (wheelset 1 at ``x = +wheelbase/2``), y along the axles with the
vehicle's L wheels at −y, z up, rotations right-handed about these axes.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import scipy.linalg

from ..cache import cache_root, source_hash
from ..fe_model import rigid_body_vectors
from ..scenarios import get_scenario
from ..sensors import point_rows
from ..wheelset import SuspensionParameters, WheelsetParameters
from .contact import hertz_constant

__all__ = ["VehicleParameters", "Vehicle", "WheelsetModes", "build_vehicle", "wheelset_modes", "VehicleError",
           "WHEEL_ORDER", "G"]

log = logging.getLogger(__name__)

G = 9.80665
#: Modes whose input × output participation (each normalised by its largest) falls below this are dropped.
PARTICIPATION_FLOOR = 1e-8
#: Wheel order of every per-wheel array: (wheelset 1 L, wheelset 1 R, wheelset 2 L, wheelset 2 R), vehicle sides.
WHEEL_ORDER = ("ws1_L", "ws1_R", "ws2_L", "ws2_R")


class VehicleError(ValueError):
    """Invalid vehicle parameters or a vehicle model that cannot be built."""


@dataclass(frozen=True)
class VehicleParameters:
    """The instrumented trailer bogie (thesis §2.1, Table 2.1), SI units.

    Attributes
    ----------
    wheelset_scenario : str
        Virtual-lab scenario whose as-built truth wheelset runs on the line (both wheelsets).
    wheelbase : float
        Bogie wheelbase [m]: 2.1 m, a metro trailer bogie like the *Meneghino*'s.
    frame_mass, frame_inertia : float, tuple
        Bogie frame (with brake rigging and bolster) 2600 kg; roll, pitch, yaw inertia [kg m²] about its
        centre of mass, which sits ``frame_cg_height`` above the axle centre line.
    carbody_load : float
        Static car-body load on this bogie [N] (half of a 26 t loaded car body: 127.5 kN).
    carbody_cg_height : float
        Height of the car body's centre of mass above the axle centre line [m] (for the roll moment of
        quasi-static curving loads).
    primary : SuspensionParameters
        Per axlebox, Table 2.1 (``lab_data.wheelset.SuspensionParameters``).
    secondary_stiffness, secondary_damping : tuple
        Per air spring along x, y, z [N/m, N s/m].
    secondary_half_spacing, secondary_height : float
        Air springs at ``y = ±secondary_half_spacing``, ``secondary_height`` above the axle centre line [m].
    secondary_tilt_stiffness : float
        Tilting (bending) stiffness of each air spring about x and y [N m/rad]. It is the only restraint of
        the bogie's pitch about the traction height when the bogie is off the rails (on the rails the track
        holds it), so it keeps the vehicle's own eigenproblem free of an excitable zero mode.
    nominal_wheel_radius : float
        0.41 m: Table 2.1's "wheel nominal diameter R_w = 0.41 m" read as the radius (its symbol is a
        radius, and 0.41 m is the FE wheelset's rolling radius; an 820 mm diameter is a metro wheel).
    rail_crown_radius : float
        Transverse radius of the 50E5 rail head at the contact [m] (for the Hertz constant).
    modal_cutoff_hz : float
        Highest wheelset mode kept.
    """

    wheelset_scenario: str = "control"
    wheelbase: float = 2.1
    frame_mass: float = 2600.0
    frame_inertia: tuple[float, float, float] = (1600.0, 1500.0, 2900.0)
    frame_cg_height: float = 0.10
    carbody_load: float = 127.5e3
    carbody_cg_height: float = 1.35
    primary: SuspensionParameters = field(default_factory=SuspensionParameters)
    secondary_stiffness: tuple[float, float, float] = (0.16e6, 0.16e6, 0.35e6)
    secondary_damping: tuple[float, float, float] = (0.0, 20e3, 25e3)
    secondary_half_spacing: float = 1.0
    secondary_height: float = 0.45
    secondary_tilt_stiffness: float = 10e3
    nominal_wheel_radius: float = 0.41
    rail_crown_radius: float = 0.30
    modal_cutoff_hz: float = 3000.0

    def __post_init__(self) -> None:
        get_scenario(self.wheelset_scenario)  # KeyError listing the valid names
        for name in ("wheelbase", "frame_mass", "carbody_load", "nominal_wheel_radius", "rail_crown_radius",
                     "secondary_half_spacing"):
            v = getattr(self, name)
            if not np.isfinite(v) or v <= 0:
                raise VehicleError(f"VehicleParameters.{name} must be finite and > 0, got {v!r}")
        if not 500.0 <= self.modal_cutoff_hz <= 6000.0:
            raise VehicleError(f"VehicleParameters.modal_cutoff_hz must lie in 500-6000 Hz, got {self.modal_cutoff_hz}")
        if self.wheelbase < 2 * 0.97 * 0.5:
            raise VehicleError(f"VehicleParameters.wheelbase {self.wheelbase} m is too short for two wheelsets")

    def parameters(self) -> dict:
        d = asdict(self)
        d["primary"] = asdict(self.primary)
        return d


@dataclass(frozen=True)
class WheelsetModes:
    """What the vehicle needs of one truth wheelset's free-free modes (cached on disk).

    ``contact`` (2, m, 6) and ``axlebox`` (2, m, 6): translations and rotations of the rigid points at the
    contact (rolling radius below the axle, tape circle) and axlebox centre, sides L, R; ``gravity_y``,
    ``gravity_z`` (m,): modal participation ``Φᵀ M r`` of a unit uniform acceleration field along y, z.
    ``contact_residual`` (4, 4): quasi-static flexibility ``Σ φ φᵀ / ω²`` of all the FE's modes above the
    cut-off at the contact points, (y, z) of L then R — the wheel's local compliance that a truncated modal
    model would lose (0.2 dB at 315 Hz between 3 and 4 kHz cut-offs without it).
    """

    freqs_hz: np.ndarray
    zeta: np.ndarray
    contact: np.ndarray
    axlebox: np.ndarray
    contact_xyz: np.ndarray  # (2, 3) relative to the wheelset centre
    axlebox_xyz: np.ndarray  # (2, 3)
    gravity_y: np.ndarray
    gravity_z: np.ndarray
    mass: float
    labels: tuple[str, ...]
    contact_residual: np.ndarray  # (4, 4) static flexibility of the modes above the cut-off, (L y, L z, R y, R z)


def _cache_dir() -> Path:
    return cache_root() / "line" / "wheelsets"


#: Version of the cached wheelset data's layout (bump when :func:`_solve_wheelset` changes what it stores).
WHEELSET_CACHE_VERSION = 2


def _source_hash() -> str:
    """Hash of the virtual lab's FE sources (the truth wheelset) and of the cache layout version."""
    lab = source_hash(Path(__file__).resolve().parent.parent)
    return hashlib.sha256(f"{WHEELSET_CACHE_VERSION}-{lab}".encode()).hexdigest()[:12]


def wheelset_modes(scenario: str, cutoff_hz: float) -> WheelsetModes:
    """The truth wheelset of a lab scenario as a modal model up to ``cutoff_hz`` (solved once, cached on disk).

    Solving the 3D FE truth takes 10–20 s; the result is kept under
    ``$RAILMODAL_CACHE/line/wheelsets/`` keyed by scenario, cut-off and the virtual lab's source.
    """
    key = hashlib.sha256(json.dumps([scenario, float(cutoff_hz)]).encode()).hexdigest()[:10]
    path = _cache_dir() / f"{scenario}-{key}-{_source_hash()}.npz"
    if path.exists():
        try:
            with np.load(path, allow_pickle=False) as z:
                return WheelsetModes(z["freqs_hz"], z["zeta"], z["contact"], z["axlebox"], z["contact_xyz"],
                                     z["axlebox_xyz"], z["gravity_y"], z["gravity_z"], float(z["mass"]),
                                     tuple(str(s) for s in z["labels"]), z["contact_residual"])
        except (OSError, KeyError, ValueError) as exc:  # a damaged cache entry is rebuilt
            log.warning("wheelset cache %s unreadable (%s); solving again", path, exc)
    modes = _solve_wheelset(scenario, cutoff_hz)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(f".{os.getpid()}.tmp.npz")
    np.savez(tmp, freqs_hz=modes.freqs_hz, zeta=modes.zeta, contact=modes.contact, axlebox=modes.axlebox,
             contact_xyz=modes.contact_xyz, axlebox_xyz=modes.axlebox_xyz, gravity_y=modes.gravity_y,
             gravity_z=modes.gravity_z, mass=modes.mass, labels=np.array(modes.labels),
             contact_residual=modes.contact_residual)
    os.replace(tmp, path)
    return modes


def _solve_wheelset(scenario: str, cutoff_hz: float) -> WheelsetModes:
    from ..truth import design_modes, truth_modes

    p = WheelsetParameters()
    # solve a little beyond the cut-off so that a degenerate cluster is never split by the solver's bound
    f_solve = cutoff_hz * 1.05
    design = design_modes(p, f_solve)
    truth = truth_modes(get_scenario(scenario), p, f_solve, design)
    keep = truth.modes.freqs_hz <= cutoff_hz
    model = truth.model
    shapes = truth.modes.shapes[keep]
    rows = {name: (fe, np.array(xyz)) for name, fe, xyz in point_rows(model, p)}

    def rigid_point(name: str) -> np.ndarray:
        fe, xyz = rows[name]
        i = model.index(fe)
        r = xyz - model.xyz[i]
        u = shapes[:, i, :3] + np.cross(shapes[:, i, 3:], r)
        return np.concatenate([u, shapes[:, i, 3:]], axis=1)  # (m, 6)

    contact = np.stack([rigid_point("contact_L"), rigid_point("contact_R")])
    axlebox = np.stack([rigid_point("axlebox_L"), rigid_point("axlebox_R")])
    full = shapes.reshape(shapes.shape[0], -1)  # (m, 6 n)
    R = rigid_body_vectors(model, np.zeros(3))
    M = truth.system.M
    gy = full @ (M @ R[:, 1])
    gz = full @ (M @ R[:, 2])
    mass = float(R[:, 2] @ (M @ R[:, 2]))
    labels = tuple(lab.description for lab, k in zip(truth.labels, keep) if k)
    residual = _contact_residual(truth, rows, cutoff_hz)
    return WheelsetModes(truth.modes.freqs_hz[keep].copy(), truth.zeta[keep].copy(), contact, axlebox,
                         np.stack([rows["contact_L"][1], rows["contact_R"][1]]),
                         np.stack([rows["axlebox_L"][1], rows["axlebox_R"][1]]), gy, gz, mass, labels, residual)


def _contact_residual(truth, rows: dict, cutoff_hz: float) -> np.ndarray:
    """``Σ φ φᵀ / ω²`` over every FE mode above ``cutoff_hz`` at the contact points' (y, z), L then R.

    All modes of the reduced FE (a dense generalised eigenproblem of a few thousand DOFs, seconds).
    """
    system = truth.system
    T = system.transform
    K = (T.T @ system.K @ T).toarray()
    M = (T.T @ system.M @ T).toarray()
    w2, vecs = scipy.linalg.eigh(0.5 * (K + K.T), 0.5 * (M + M.T))
    high = w2 > (2 * np.pi * cutoff_hz) ** 2
    full = T @ vecs[:, high]  # (6 n_nodes, k)
    model = truth.model
    rows_out = []
    for name in ("contact_L", "contact_R"):
        fe, xyz = rows[name]
        i = model.index(fe)
        r = xyz - model.xyz[i]
        u = full[6 * i:6 * i + 3]
        th = full[6 * i + 3:6 * i + 6]
        disp = u + np.cross(th.T, r).T  # (3, k)
        rows_out.extend([disp[1], disp[2]])
    P = np.array(rows_out)  # (4, k)
    return (P / w2[high]) @ P.T


@dataclass(frozen=True)
class Vehicle:
    """The bogie as a diagonal first-order (complex modal) system.

    State ``s`` (n_c complex), ``ṡ = λ s + b u`` with inputs
    ``u = (F_y, F_z) of wheels ws1 L, ws1 R, ws2 L, ws2 R`` (8, contact forces on the wheels, vehicle frame),
    ``a_y`` (lateral body-force field, m/s²) and ``1`` (gravity and static car-body load). A physical
    quantity ``y = Σ_m weight_m Re(c_m s_m)`` (``weight`` 2 for one mode of a conjugate pair, 1 for a real
    mode); velocities use ``c_m λ_m``, accelerations ``c_m λ_m (λ_m s_m + b_m u)``.

    Attributes
    ----------
    params : VehicleParameters
    lam : ndarray (n_c,) complex
    weight : ndarray (n_c,)
    b : ndarray (n_c, 10) complex
    contact_out : ndarray (8, n_c) complex
        Displacement (y, z) of the four contact points (wheel side) per mode.
    point_shapes : ndarray (2, 2, 6, n_c) complex
        Displacement and rotation (6) of the axlebox centres, [wheelset, side], per mode (sensor outputs).
    axlebox_xyz : ndarray (2, 2, 3)
        Axlebox centres in the vehicle frame.
    hertz : float
        Hertz constant ``C_H`` [N/m^1.5] of every wheel (eq. F = C_H δ^{3/2}).
    static_load : ndarray (4,)
        Nominal static vertical wheel loads on straight level track [N].
    wheelset_mass : float
    frequencies_hz : ndarray
        Undamped natural frequencies of the in-service vehicle (for reports).
    wheelset : WheelsetModes
    frame_out : ndarray (6, n_c) complex
        Frame displacement (x, y, z, roll, pitch, yaw about its centre of mass) per mode.
    frame_b : ndarray (n_c, 6) complex
        Modal input of forces and moments on the frame (same axes).
    secondary_K : ndarray (6, 6)
        Stiffness of the secondary suspension on the frame DOFs. The air springs carry the car body's
        static load whatever the frame's static position (they are levelled): a passage adds the
        preload ``secondary_K @ frame_static`` so that only departures from the static position load them.
    contact_residual : ndarray (8, 8)
        Quasi-static flexibility of the wheelset modes above the cut-off between the contact inputs
        (:attr:`WheelsetModes.contact_residual` of each wheelset on the diagonal blocks): the wheel contact
        point moves by ``contact_residual @ u[:8]`` on top of the modal response (not seen by the sensors).
    """

    params: VehicleParameters
    lam: np.ndarray
    weight: np.ndarray
    b: np.ndarray
    contact_out: np.ndarray
    point_shapes: np.ndarray
    axlebox_xyz: np.ndarray
    hertz: float
    static_load: np.ndarray
    wheelset_mass: float
    frequencies_hz: np.ndarray
    wheelset: WheelsetModes
    frame_out: np.ndarray
    frame_b: np.ndarray
    secondary_K: np.ndarray
    contact_residual: np.ndarray

    @property
    def n_modes(self) -> int:
        return self.lam.size

    def static_response(self, u: np.ndarray) -> np.ndarray:
        """Modal state of the static equilibrium under constant inputs ``u`` (10,)."""
        return -(self.b @ u) / self.lam

    def output(self, rows: np.ndarray, s: np.ndarray) -> np.ndarray:
        """``Σ weight Re(rows s)`` for output rows (k, n_c) and states (n_c,) or (n_c, n_t)."""
        return np.real((rows * self.weight) @ s)

    def receptance(self, rows: np.ndarray, freqs_hz: np.ndarray, inputs: slice = slice(0, 8)) -> np.ndarray:
        """Frequency response (k, n_in, n_f) of output rows to the inputs (from the diagonal form)."""
        w = 2j * np.pi * np.asarray(freqs_hz, float)
        b = self.b[:, inputs]
        h = rows[:, :, None, None] * b[None, :, :, None] / (w[None, None, None, :] - self.lam[None, :, None, None])
        hc = np.conj(rows)[:, :, None, None] * np.conj(b)[None, :, :, None] / (
            w[None, None, None, :] - np.conj(self.lam)[None, :, None, None])
        pair = self.weight > 1.5
        return np.sum(h, axis=1) + np.sum(hc[:, pair], axis=1)


def build_vehicle(p: VehicleParameters = VehicleParameters()) -> Vehicle:
    """Assemble and diagonalise the bogie (module docstring); the truth wheelset solve is cached on disk."""
    ws = wheelset_modes(p.wheelset_scenario, p.modal_cutoff_hz)
    m = ws.freqs_hz.size
    n = 2 * m + 6
    M = np.zeros((n, n))
    K = np.zeros((n, n))
    C = np.zeros((n, n))
    w_modal = 2 * np.pi * ws.freqs_hz
    for k in range(2):
        sl = slice(k * m, (k + 1) * m)
        M[sl, sl] = np.eye(m)
        K[sl, sl] = np.diag(w_modal**2)
        C[sl, sl] = np.diag(2 * ws.zeta * w_modal)
    f0 = 2 * m
    M[f0:, f0:] = np.diag([p.frame_mass] * 3 + list(p.frame_inertia))
    x_ws = (0.5 * p.wheelbase, -0.5 * p.wheelbase)  # wheelset 1 at the front end (+x)
    cg = np.array([0.0, 0.0, p.frame_cg_height])

    def frame_point(r: np.ndarray) -> np.ndarray:
        """(3, 6) translation of a frame point at ``r`` per frame DOF (u_cg, θ) — u + θ × (r − cg)."""
        d = np.asarray(r, float) - cg
        T = np.zeros((3, 6))
        T[:, :3] = np.eye(3)
        T[:, 3:] = -_skew(d)
        return T

    def add_spring(L: np.ndarray, k: np.ndarray, c: np.ndarray) -> None:
        K[:] += L.T @ np.diag(k) @ L
        C[:] += L.T @ np.diag(c) @ L

    kp = np.asarray(p.primary.stiffness, float)
    cp = np.asarray(p.primary.damping, float)
    for w in range(2):
        for side in range(2):
            L = np.zeros((3, n))
            L[:, w * m:(w + 1) * m] = ws.axlebox[side, :, :3].T
            r = ws.axlebox_xyz[side] + np.array([x_ws[w], 0.0, 0.0])
            L[:, f0:] = -frame_point(r)
            add_spring(L, kp, cp)
    ks = np.asarray(p.secondary_stiffness, float)
    cs = np.asarray(p.secondary_damping, float)
    K_before = K[f0:, f0:].copy()
    for sgn in (-1.0, 1.0):
        L = np.zeros((3, n))
        L[:, f0:] = frame_point(np.array([0.0, sgn * p.secondary_half_spacing, p.secondary_height]))
        add_spring(L, ks, cs)
    K[f0 + 3, f0 + 3] += 2 * p.secondary_tilt_stiffness
    K[f0 + 4, f0 + 4] += 2 * p.secondary_tilt_stiffness
    secondary_K = K[f0:, f0:] - K_before

    # inputs: contact forces (y, z) at the four contact points, lateral field, constant loads
    B = np.zeros((n, 10))
    for w in range(2):
        for side in range(2):
            col = 2 * (2 * w + side)
            B[w * m:(w + 1) * m, col] = ws.contact[side, :, 1]
            B[w * m:(w + 1) * m, col + 1] = ws.contact[side, :, 2]
    carbody_mass = p.carbody_load / G
    for w in range(2):
        B[w * m:(w + 1) * m, 8] = ws.gravity_y
        B[w * m:(w + 1) * m, 9] = -G * ws.gravity_z
    # frame: its own mass in the field; the car body's share through the air springs (force at the car
    # body's centre of mass height: lateral force and roll moment about the frame's centre of mass)
    B[f0 + 1, 8] = p.frame_mass + carbody_mass
    B[f0 + 3, 8] = -carbody_mass * (p.carbody_cg_height - p.frame_cg_height)
    B[f0 + 2, 9] = -G * p.frame_mass - p.carbody_load

    # undamped modes first: drop mechanisms no input excites
    w2, V = scipy.linalg.eigh(K, M)
    w2 = np.clip(w2, 0.0, None)
    f_und = np.sqrt(w2) / (2 * np.pi)
    mech = f_und < 0.05
    part = np.abs(V.T @ B)
    scale = np.max(part[~mech]) if np.any(~mech) else 1.0
    if np.any(mech):
        worst = float(np.max(part[mech]))
        if worst > 1e-8 * scale:
            raise VehicleError(f"the vehicle has a zero-frequency mechanism that the loads excite (participation "
                               f"{worst:.3g}); check the suspension parameters")
        log.debug("dropping %d unexcitable zero-frequency mechanisms", int(mech.sum()))
    Vr = V[:, ~mech]
    nr = Vr.shape[1]
    Cr = Vr.T @ C @ Vr
    Kr = np.diag(w2[~mech])
    Br = Vr.T @ B
    A = np.block([[np.zeros((nr, nr)), np.eye(nr)], [-Kr, -Cr]])
    lam, X = scipy.linalg.eig(A)
    Xinv = np.linalg.inv(X)
    b_full = Xinv @ np.vstack([np.zeros((nr, 10)), Br])
    # physical displacement rows in the reduced basis: y = Cphys Vr x_r
    out_contact = np.zeros((8, n))
    for w in range(2):
        for side in range(2):
            r = 2 * (2 * w + side)
            out_contact[r, w * m:(w + 1) * m] = ws.contact[side, :, 1]
            out_contact[r + 1, w * m:(w + 1) * m] = ws.contact[side, :, 2]
    disp_modal = X[:nr]  # displacement part of each eigenvector
    contact_out_full = (out_contact @ Vr) @ disp_modal
    pts = np.zeros((2, 2, 6, n))
    for w in range(2):
        for side in range(2):
            pts[w, side, :, w * m:(w + 1) * m] = ws.axlebox[side].T
    points_full = np.einsum("wsdn,nk->wsdk", pts, Vr @ disp_modal)
    # fold conjugate pairs: keep Im(lam) > 0 with weight 2, real eigenvalues with weight 1
    tol = 1e-9 * np.max(np.abs(lam))
    pos = lam.imag > tol
    real = np.abs(lam.imag) <= tol
    keep = pos | real
    # modes that no load excites or that neither a contact point nor an axlebox sees (symmetry: a degenerate
    # wheel mode with a node at the contact, in-plane disc modes...) are dropped: the score is the product
    # of the largest normalised input and output participations, dropped below 1e-8 (-160 dB)
    b_all = np.abs(b_full)
    b_score = np.max(b_all / np.maximum(b_all.max(axis=0, keepdims=True), 1e-300), axis=1)
    outs = np.abs(np.vstack([contact_out_full, points_full.reshape(-1, points_full.shape[-1])]))
    o_score = np.max(outs / np.maximum(outs.max(axis=1, keepdims=True), 1e-300), axis=0)
    seen = b_score * o_score > PARTICIPATION_FLOOR
    log.debug("vehicle: %d of %d modes neither excited nor seen, dropped", int(np.sum(keep & ~seen)),
              int(keep.sum()))
    keep = keep & seen
    weight = np.where(pos, 2.0, 1.0)[keep]
    if np.any(lam[keep].real >= 0):
        raise VehicleError("the assembled vehicle has an eigenvalue with non-negative real part (unstable or undamped)")
    frame_out = (Vr[f0:] @ disp_modal)[:, keep]
    frame_b = (Xinv @ np.vstack([np.zeros((nr, 6)), Vr[f0:].T]))[keep]
    axlebox_xyz = np.stack([ws.axlebox_xyz + np.array([x_ws[w], 0.0, 0.0]) for w in range(2)])
    # static wheel loads on straight level track (the equilibrium's vertical contact forces are symmetric)
    total = 2 * ws.mass * G + p.frame_mass * G + p.carbody_load
    static = np.full(4, total / 4)
    C_H = hertz_constant(p.nominal_wheel_radius, p.rail_crown_radius)
    return Vehicle(p, lam[keep], weight, b_full[keep], contact_out_full[:, keep], points_full[..., keep],
                   axlebox_xyz, C_H, static, ws.mass, np.sort(np.sqrt(w2[~mech])) / (2 * np.pi), ws, frame_out,
                   frame_b, secondary_K, scipy.linalg.block_diag(ws.contact_residual, ws.contact_residual))


def _skew(d: np.ndarray) -> np.ndarray:
    """Matrix S with S v = d × v."""
    return np.array([[0.0, -d[2], d[1]], [d[2], 0.0, -d[0]], [-d[1], d[0], 0.0]])
