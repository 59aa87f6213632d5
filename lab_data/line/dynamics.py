"""Time-domain simulation of the bogie rolling over the two discretely supported rails.

:func:`simulate_passage` couples the vehicle (:mod:`lab_data.line.vehicle`, diagonal complex modal
form), the two rails of the track ring (:mod:`lab_data.line.track`, Fourier modes of the free
Timoshenko rail + discrete two-layer supports with causal damping) and the non-linear Hertz contact
(:mod:`lab_data.line.contact`) at the four wheels, whose positions move along the ring with the bogie.

**Time stepping (step ``h``, default 1/10240 s).** The rail modes and the vehicle's complex modes move
exactly between steps (matrix-exponential coefficients) and receive every coupling force as its average
over the step held constant — for a free mass this is the trapezoidal rule, which keeps the stiff
wheel–rail coupling unconditionally stable (a first-order hold would be the linear-acceleration method,
stable only for ωh < 2√3: it diverged at h = 1/5120 s). The Maxwell branches of the causal layers move
with their exponential for a constant deformation rate over the step, the baseplates with the
trapezoidal rule. Per step:

1. the rail modes and the vehicle modes are propagated freely;
2. the supports are solved implicitly, each against the rail's within-step compliance at its point
   (quasi-static residual of the truncated rail modes included), with the contact forces of the last
   step (their within-step effect on a support is a few per cent of a pad's stiffness);
3. the four contact forces are solved by Newton's method from the Hertz law along the contact normals,
   with the exact within-step compliance of wheels and rails (both wheels of a rail and of a wheelset
   coupled);
4. rails and vehicle receive the forces; sensor accelerations follow from the vehicle's modal states.

Accuracy (``tests/test_line_physics.py``): in the linear limit the axlebox response is within 0.03 dB
of the frequency-domain oracle over 20–400 Hz at the default step (0.25 dB at twice the step);
halving the default step moves the third-octave levels of a broadband run by ≤ 0.06 dB; at a realistic
roughness (40 µm at 12 Hz to 0.4 µm at 398 Hz) on discrete supports the absolute axlebox levels lie within
0.25 dB of the continuous-support oracle, and below P2 the wheel follows the rail (``a ≈ (2πf)² r``).

**Start.** The simulation starts from the static equilibrium of the first step (Hertz law, track and
vehicle statics with the long-term stiffness of the causal layers; the air springs levelled at the
frame's static bounce, roll and pitch). The viscoelastic pads stiffen once the load moves, so a passage
that starts moving needs a few tenths of a second of run-in.

No step divides by the speed: a standing train is a valid passage. The loop runs in ``numba``
(:mod:`lab_data.line.kernel`, compiled once and cached on disk: ``cache=True``);
:func:`compile_kernels` compiles it up front.

**Not modelled.** Tangential (creep) forces and wheel/rail profile geometry beyond the prescribed contact
angle; rail torsion and the coupling of the two rails through the ground; the car body's own motion
(an inertial ground above the air springs); a track ring of 48 m (waves leaving it come back weakened,
see :mod:`lab_data.line.track`).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg

from .damping import unit_loss_fit
from .kernel import N_PAR, assign_slot, fft_tables, passage_kernel
from .track import TrackLayout, rail_modes, support_arrays, warn_short_layout
from .vehicle import Vehicle

__all__ = ["SensorPoint", "PassageInput", "Passage", "TrackOptions", "simulate_passage", "compile_kernels",
           "DynamicsError", "DEFAULT_DT"]

log = logging.getLogger(__name__)

#: Default integration step [s] (10.24 kHz; a 1 kHz DAQ rate is the rational fraction 125/1280 of it): halving
#: it changes the axlebox third-octave levels over 20–400 Hz by ≤ 0.06 dB, doubling it by 0.3 dB.
DEFAULT_DT = 1.0 / 10240.0


class DynamicsError(ValueError):
    """Invalid passage input (names the field, the expected shape or range and what was received)."""


@dataclass(frozen=True)
class SensorPoint:
    """An accelerometer at its TRUE mounting point.

    Attributes
    ----------
    wheelset : int
        1 or 2 (vehicle numbering: 1 at the vehicle's front end).
    side : str
        'L' or 'R' (vehicle): the axlebox it is bolted to (rigidly).
    direction : str
        'x', 'y' or 'z' (vehicle frame): measuring axis (positive along the axis).
    offset : tuple of 3 floats
        Mounting point relative to the wheelset centre, vehicle frame [m] (the axlebox centre is at
        ``(0, ∓0.97, 0)``).
    """

    wheelset: int
    side: str
    direction: str
    offset: tuple[float, float, float]

    def __post_init__(self) -> None:
        if self.wheelset not in (1, 2):
            raise DynamicsError(f"SensorPoint.wheelset must be 1 or 2, got {self.wheelset!r}")
        if self.side not in ("L", "R"):
            raise DynamicsError(f"SensorPoint.side must be 'L' or 'R', got {self.side!r}")
        if self.direction not in ("x", "y", "z"):
            raise DynamicsError(f"SensorPoint.direction must be 'x', 'y' or 'z', got {self.direction!r}")
        off = np.asarray(self.offset, float)
        if off.shape != (3,) or not np.all(np.isfinite(off)) or np.any(np.abs(off) > 2.0):
            raise DynamicsError(f"SensorPoint.offset must be 3 finite numbers within 2 m, got {self.offset!r}")
        object.__setattr__(self, "offset", tuple(float(v) for v in off))


@dataclass(frozen=True)
class PassageInput:
    """Everything a passage needs per integration step.

    Attributes
    ----------
    dt : float
        Integration step [s] (:data:`DEFAULT_DT`).
    bogie_chainage : ndarray (n_t,)
        True chainage of the bogie centre at each step [m] (may stand still).
    travel_sign : int
        +1 travelling towards increasing chainage, −1 decreasing (checked against ``bogie_chainage``).
    orientation : str
        'normal' (the vehicle's front end faces increasing chainage; vehicle L runs on rail L) or 'turned'.
    wheel_roughness : ndarray (4, n_t)
        Irregularity along the contact normal at each wheel [m] (rail + wheel roughness, positive =
        material added), wheels (ws1 L, ws1 R, ws2 L, ws2 R).
    lateral_roughness : ndarray (4, n_t) or None
        Lateral displacement of the rail head at each wheel [m] (towards the vehicle's +y); enters the
        compression through the normal's lateral component.
    contact_angle : ndarray (4, n_t)
        Contact-plane angle θ per wheel [rad], thesis eq. 2.12 sign (:mod:`lab_data.line.contact`).
    curvature : ndarray (n_t,)
        Track curvature at the bogie [1/m], positive for a curve turning left looking towards increasing
        chainage.
    cant : ndarray (n_t,)
        Cant angle [rad] by which the curve's outer rail is raised (≥ 0).
    sensors : tuple of SensorPoint
    speed : ndarray (n_t,) or None
        Speed along the track [m/s] for the quasi-static curving load; None: from ``bogie_chainage``.
    """

    dt: float
    bogie_chainage: np.ndarray
    travel_sign: int
    orientation: str
    wheel_roughness: np.ndarray
    contact_angle: np.ndarray
    curvature: np.ndarray
    cant: np.ndarray
    sensors: tuple
    lateral_roughness: np.ndarray | None = None
    speed: np.ndarray | None = None

    def __post_init__(self) -> None:
        if not (np.isfinite(self.dt) and 1e-6 <= self.dt <= 1e-3):
            raise DynamicsError(f"PassageInput.dt must lie in 1e-6..1e-3 s, got {self.dt!r}")
        s = np.asarray(self.bogie_chainage, float)
        if s.ndim != 1 or s.size < 2 or not np.all(np.isfinite(s)):
            raise DynamicsError(f"PassageInput.bogie_chainage must be a finite 1-D array of >= 2 steps, got shape "
                                f"{s.shape}")
        n = s.size
        object.__setattr__(self, "bogie_chainage", s)
        if self.travel_sign not in (1, -1):
            raise DynamicsError(f"PassageInput.travel_sign must be +1 or -1, got {self.travel_sign!r}")
        wrong = np.flatnonzero(np.diff(s) * self.travel_sign < -1e-9)
        if wrong.size:
            i = int(wrong[0])
            raise DynamicsError(f"PassageInput.bogie_chainage moves against travel_sign={self.travel_sign} at step {i} "
                                f"({s[i]:.4f} m -> {s[i + 1]:.4f} m)")
        if np.max(np.abs(np.diff(s))) / self.dt > 40.0:
            raise DynamicsError(f"PassageInput.bogie_chainage implies a speed above 40 m/s (144 km/h): "
                                f"{np.max(np.abs(np.diff(s))) / self.dt:.1f} m/s")
        if self.orientation not in ("normal", "turned"):
            raise DynamicsError(f"PassageInput.orientation must be 'normal' or 'turned', got {self.orientation!r}")
        for name in ("wheel_roughness", "contact_angle", "lateral_roughness"):
            a = getattr(self, name)
            if a is None and name == "lateral_roughness":
                continue
            a = np.asarray(a, float)
            if a.shape != (4, n):
                raise DynamicsError(f"PassageInput.{name} must have shape (4, {n}) (wheels x steps), got {a.shape}")
            if not np.all(np.isfinite(a)):
                w, i = np.argwhere(~np.isfinite(a))[0]
                raise DynamicsError(f"PassageInput.{name} is not finite at wheel {w}, step {i}")
            object.__setattr__(self, name, a)
        if np.any(np.abs(self.contact_angle) > np.radians(80.0)):
            raise DynamicsError("PassageInput.contact_angle must stay within ±80°")
        if np.any(np.abs(self.wheel_roughness) > 0.01):
            raise DynamicsError("PassageInput.wheel_roughness exceeds 10 mm: is it in m?")
        for name in ("curvature", "cant") + (("speed",) if self.speed is not None else ()):
            a = np.asarray(getattr(self, name), float)
            if a.shape != (n,) or not np.all(np.isfinite(a)):
                raise DynamicsError(f"PassageInput.{name} must be a finite array of shape ({n},), got {a.shape}")
            object.__setattr__(self, name, a)
        if np.any(np.abs(self.curvature) > 0.02):
            raise DynamicsError("PassageInput.curvature must stay below 0.02 1/m (radius >= 50 m)")
        if not self.sensors or not all(isinstance(p, SensorPoint) for p in self.sensors):
            raise DynamicsError("PassageInput.sensors must be a non-empty tuple of SensorPoint")
        object.__setattr__(self, "sensors", tuple(self.sensors))

    @property
    def n_steps(self) -> int:
        return self.bogie_chainage.size


@dataclass(frozen=True)
class TrackOptions:
    """Discretisation of the track ring (see :mod:`lab_data.line.track`).

    Attributes
    ----------
    ring_supports : int
        Supports per ring (power of two): 64 (48 m for L_s = 0.75 m).
    k_max : float
        Highest rail wavenumber [rad/m] kept as a mode (10 rad/m: rail modes to about 2.3 kHz vertical);
        the rest is a quasi-static residual.
    """

    ring_supports: int = 64
    k_max: float = 10.0

    def __post_init__(self) -> None:
        n = self.ring_supports
        if n < 8 or n > 1024 or n & (n - 1):
            raise DynamicsError(f"TrackOptions.ring_supports must be a power of two in 8..1024, got {n}")
        if not 2.0 <= self.k_max <= 100.0:
            raise DynamicsError(f"TrackOptions.k_max must lie in 2..100 rad/m, got {self.k_max}")


@dataclass(frozen=True)
class Passage:
    """The simulated passage (true quantities, no DAQ effects).

    Attributes
    ----------
    t : ndarray (n_t,)
    acceleration : ndarray (n_sensors, n_t)
        At the sensor points along their axes [m/s²].
    contact_force : ndarray (4, n_t)
        Normal contact force per wheel [N] (ws1 L, ws1 R, ws2 L, ws2 R).
    contact_lost : ndarray (4, n_t) of bool
    rail_displacement : ndarray (4, n_t)
        Rail head displacement under each wheel along its contact normal [m].
    wheel_displacement : ndarray (4, n_t)
        Wheel contact point displacement along the normal [m].
    static_force : ndarray (4,)
        Contact forces of the static equilibrium at the first step [N].
    sensors : tuple of SensorPoint
    timings_s : dict
        ``setup`` (track ring, statics) and ``kernel`` (the time-stepping loop) wall times [s], and
        ``kernel_cpu``, the loop's process CPU time [s] (numba compilation: :func:`compile_kernels`).
    """

    t: np.ndarray
    acceleration: np.ndarray
    contact_force: np.ndarray
    contact_lost: np.ndarray
    rail_displacement: np.ndarray
    wheel_displacement: np.ndarray
    static_force: np.ndarray
    sensors: tuple
    timings_s: dict = field(default_factory=dict)


# ----------------------------------------------------------------------------------------------------
# discretisation helpers (Python, once per passage)


def oscillator_step(omega: np.ndarray, zeta: float | np.ndarray, h: float) -> np.ndarray:
    """Step of ``ẍ + 2ζωẋ + ω²x = p(t)``: exact free motion, the force held at its step average.

    ``x' = a11 x + a12 v + b (p0 + p1) / 2``, ``v' = a21 x + a22 v + c (p0 + p1) / 2`` with the exact
    zero-order-hold responses ``b, c`` (for a free mass: the trapezoidal rule).

    Returns
    -------
    ndarray (8, n)
        ``a11, a12, a21, a22, b0x, b1x, b0v, b1v`` with ``b0x = b1x = b/2``, ``b0v = b1v = c/2``.
    """
    omega = np.asarray(omega, float)
    n = omega.size
    zeta = np.broadcast_to(np.asarray(zeta, float), (n,))
    # augmented system [x, v, p] with p constant: d/dt = [[0, 1, 0], [-w2, -2zw, 1], [0, 0, 0]]
    A = np.zeros((n, 3, 3))
    A[:, 0, 1] = 1.0
    A[:, 1, 0] = -omega**2
    A[:, 1, 1] = -2 * zeta * omega
    A[:, 1, 2] = 1.0
    E = scipy.linalg.expm(A * h)
    out = np.empty((8, n))
    out[0], out[1] = E[:, 0, 0], E[:, 0, 1]
    out[2], out[3] = E[:, 1, 0], E[:, 1, 1]
    out[4] = out[5] = 0.5 * E[:, 0, 2]
    out[6] = out[7] = 0.5 * E[:, 1, 2]
    return out


def complex_step(lam: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Step of ``ṡ = λ s + u(t)``: ``s' = E s + β (u0 + u1) / 2`` with ``β = (e^{λh} − 1)/λ``.

    Returns ``(E, β/2, β/2)`` (the coefficients of ``u0`` and ``u1``).
    """
    z = lam * h
    E = np.exp(z)
    small = np.abs(z) < 1e-3
    zs = np.where(small, 1.0, z)
    beta = np.where(small, h * (1 + z / 2 + z**2 / 6), h * (E - 1) / zs)
    return E, 0.5 * beta, 0.5 * beta


# ----------------------------------------------------------------------------------------------------
# the driver


@dataclass(frozen=True)
class _TrackSetup:
    """Everything the kernel needs of the track, built once per passage."""

    ring_length: float
    ns: int
    continuous: bool
    W: np.ndarray  # (2, N1) deflection per unit modal coordinate, z and y
    omega: np.ndarray  # (2, N1)
    coef: np.ndarray  # (2, 8, N1) first-order-hold coefficients (cos and sin modes alike)
    residual: np.ndarray  # (2,) quasi-static point flexibility of what the modes leave out
    Gr_self: np.ndarray  # (2,) within-step point compliance at a wheel (residual included)
    Gr_pair: np.ndarray  # (2,) within-step compliance between the two wheels of a rail
    Lfac: np.ndarray  # (N1,) ring integral of cos^2 (continuous foundation)
    table: np.ndarray  # (4, 7, n_columns) support parameters per sleeper (or per unit length)
    c0: float
    spacing: float

    def shapes(self, d: int, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Cosine and sine mode deflections (len(X), N1) of direction ``d`` at ring positions ``X``."""
        X = np.atleast_1d(np.asarray(X, float))
        kx = 2 * np.pi * np.arange(self.W.shape[1])[None, :] * X[:, None] / self.ring_length
        return self.W[d] * np.cos(kx), self.W[d] * np.sin(kx)


def _track_setup(layout: TrackLayout, options: TrackOptions, dt: float, wheelbase: float) -> _TrackSetup:
    p = layout.base
    ls = p.support_spacing
    ns = options.ring_supports
    Lr = ns * ls
    modes = [rail_modes(p, d, Lr, options.k_max) for d in ("z", "y")]
    W = np.stack([m.amplitude for m in modes])
    omega = np.stack([m.omega for m in modes])
    coef = np.stack([oscillator_step(m.omega, m.zeta, dt) for m in modes])
    residual = np.array([m.residual for m in modes])
    k = modes[0].k
    b1 = coef[:, 5, :]
    # the cos and sin modes of a harmonic together give W^2 cos(k (x - x')): translation invariant
    C00 = W[:, 0] ** 2 * b1[:, 0] + np.sum(W[:, 1:] ** 2 * b1[:, 1:], axis=1)
    Cab = W[:, 0] ** 2 * b1[:, 0] + np.sum(W[:, 1:] ** 2 * b1[:, 1:] * np.cos(k[1:] * wheelbase), axis=1)
    Lfac = np.full(k.size, 0.5 * Lr)
    Lfac[0] = Lr
    if layout.continuous:
        table = np.zeros((4, 7, 1))
        for d_i, d in enumerate(("z", "y")):
            vals = (getattr(p, f"pad_stiffness_{d}") / ls, getattr(p, f"pad_damping_{d}") / ls, p.pad_loss_factor,
                    p.baseplate_mass / ls, getattr(p, f"subplate_stiffness_{d}") / ls,
                    getattr(p, f"subplate_damping_{d}") / ls, p.subplate_loss_factor)
            for rail in range(2):
                table[2 * rail + d_i, :, 0] = vals
    else:
        rows = ("pad_k", "pad_c", "pad_eta", "plate_mass", "sub_k", "sub_c", "sub_eta")
        table = np.zeros((4, 7, layout.support_chainage.size))
        for d_i, d in enumerate(("z", "y")):
            arr = support_arrays(layout, d)
            for rail in range(2):
                for r_i, name in enumerate(rows):
                    table[2 * rail + d_i, r_i] = arr[name][rail]
    return _TrackSetup(Lr, ns, layout.continuous, W, omega, coef, residual, C00 + residual, Cab, Lfac, table,
                       float(layout.support_chainage[0]), ls)


def _static_track(ts: _TrackSetup, par: np.ndarray, rd: int, loads_X: np.ndarray) -> dict:
    """Static ring under unit loads at ``loads_X``: modal coordinates and the slots' forces per unit load.

    The supports take their long-term (relaxed) stiffness, the baseplate is a series link.
    """
    d = rd % 2
    N1 = ts.W.shape[1]
    kp, ks = par[rd, 0], par[rd, 2]
    k_series = kp * ks / (kp + ks)
    om2 = np.concatenate([ts.omega[d] ** 2, ts.omega[d][1:] ** 2])  # cos block, sin block (n >= 1)
    lc, ls_ = ts.shapes(d, loads_X)
    rhs = np.vstack([lc.T, ls_[:, 1:].T])
    if ts.continuous:
        w = ts.W[d]
        kc = w**2 * ts.Lfac * k_series[:N1]
        kss = w[1:] ** 2 * ts.Lfac[1:] * k_series[N1 + 1:]
        q = rhs / (om2 + np.concatenate([kc, kss]))[:, None]
        k_eff = k_series
        slot_disp = np.vstack([w[:, None] * q[:N1], np.zeros((1, q.shape[1])), w[1:, None] * q[N1:]])
    else:
        sc, ssn = ts.shapes(d, np.arange(ts.ns) * ts.spacing)
        Phi = np.hstack([sc, ssn[:, 1:]])
        k_eff = k_series / (1 + k_series * ts.residual[d])
        q = np.linalg.solve(np.diag(om2) + Phi.T @ (k_eff[:, None] * Phi), rhs)
        slot_disp = Phi @ q
    f = -k_eff[:, None] * slot_disp  # force on the rail at each slot per unit load
    if not ts.continuous:
        slot_disp = slot_disp + ts.residual[d] * f
    at_loads = np.hstack([lc, ls_[:, 1:]]) @ q + (ts.residual[d] * np.eye(len(np.atleast_1d(loads_X))))
    return {"q": q, "slot_u": slot_disp, "slot_f": f, "at_loads": at_loads, "N1": N1}


def _sensor_row(vehicle: Vehicle, sp: SensorPoint) -> np.ndarray:
    """Modal displacement row (n_c,) of a sensor rigidly bolted to its axlebox: e·u + (d × e)·θ."""
    w = sp.wheelset - 1
    side = 0 if sp.side == "L" else 1
    e = np.zeros(3)
    e["xyz".index(sp.direction)] = 1.0
    centre = np.array([vehicle.axlebox_xyz[w, side, 0], 0.0, 0.0])
    d = centre + np.asarray(sp.offset) - vehicle.axlebox_xyz[w, side]
    sh = vehicle.point_shapes[w, side]
    return e @ sh[:3] + np.cross(d, e) @ sh[3:]


def _static_equilibrium(vehicle: Vehicle, statics: dict, wheel_rail: np.ndarray, rough0: np.ndarray,
                        theta0: np.ndarray, a_y0: float) -> tuple[np.ndarray, np.ndarray]:
    """Contact forces and frame preload of the static equilibrium at the first step.

    Returns ``(F0 (4,), frame_preload (6,))``; the air springs carry the static car-body load with the
    frame where the equilibrium puts it (:attr:`Vehicle.secondary_K`; levelled in bounce, roll and pitch).
    """
    ny, nz = -np.sin(theta0), np.cos(theta0)
    lam = vehicle.lam
    wgt = vehicle.weight
    G_st = np.real((vehicle.contact_out * wgt) @ (-vehicle.b / lam[:, None]))  # (8, 10)
    G_st[:, :8] += vehicle.contact_residual
    Gf_c = np.real((vehicle.contact_out * wgt) @ (-vehicle.frame_b / lam[:, None]))  # (8, 6) preload -> contact
    F_frame = np.real((vehicle.frame_out * wgt) @ (-vehicle.b / lam[:, None]))  # (6, 10)
    Ff_f = np.real((vehicle.frame_out * wgt) @ (-vehicle.frame_b / lam[:, None]))  # (6, 6)
    Gr = np.zeros((2, 4, 4))
    for rd, st in statics.items():
        rail, d = divmod(rd, 2)
        on = np.flatnonzero(wheel_rail == rail)
        Gr[d][np.ix_(on, on)] = st["at_loads"]
    u_slow = np.array([a_y0, 1.0])
    # levelling valves keep each air spring at its height: the static car-body load does not compress them,
    # so a preload cancels their reaction to the frame's static bounce, roll and pitch (x, y, yaw keep it)
    lev = np.array([2, 3, 4])
    Ks = vehicle.secondary_K

    def preload_of(c):
        out = np.zeros(6)
        out[lev] = c
        return out

    def fyz_of(F):
        out = np.empty(8)
        out[0::2], out[1::2] = F * ny, F * nz
        return out

    def gap(F, c):
        vw = G_st[:, :8] @ fyz_of(F) + G_st[:, 8:] @ u_slow + Gf_c @ preload_of(c)
        return rough0 + ny * (-Gr[1] @ (F * ny) - vw[0::2]) + nz * (-Gr[0] @ (F * nz) - vw[1::2])

    # the problem is linear but for the Hertz law: gap = g0 - HF F - Hc c, levelled frame = x0 + AF F + Ac c
    g0 = gap(np.zeros(4), np.zeros(3))
    HF = np.stack([g0 - gap(e, np.zeros(3)) for e in np.eye(4)], axis=1)
    Hc = np.stack([g0 - gap(np.zeros(4), e) for e in np.eye(3)], axis=1)

    def frame_lev(F, c):
        return (Ks @ (F_frame @ np.concatenate([fyz_of(F), u_slow]) + Ff_f @ preload_of(c)))[lev]

    x0 = frame_lev(np.zeros(4), np.zeros(3))
    AF = np.stack([frame_lev(e, np.zeros(3)) - x0 for e in np.eye(4)], axis=1)
    Ac = np.stack([frame_lev(np.zeros(4), e) - x0 for e in np.eye(3)], axis=1)
    # start: the contact forces with the air springs unlevelled (halving where a wheel would lift), their
    # static reaction as the first preload; then Newton on forces and preload together
    F = vehicle.static_load.copy()
    for _ in range(200):
        dl = g0 - HF @ F
        if np.any(dl <= 0):
            F = np.where(dl <= 0, 0.5 * F, F)
            continue
        step = np.linalg.solve(np.eye(4) + 1.5 * vehicle.hertz * np.sqrt(dl)[:, None] * HF,
                               -(F - vehicle.hertz * dl**1.5))
        F = np.maximum(F + step, 1e-3)
        if np.max(np.abs(step)) < 1e-6:
            break
    x = np.concatenate([F, x0 + AF @ F])
    for _ in range(100):
        F, c = x[:4], x[4:]
        dl = g0 - HF @ F - Hc @ c
        dlp = np.clip(dl, 0.0, None)
        res = np.concatenate([F - vehicle.hertz * dlp**1.5, c - x0 - AF @ F - Ac @ c])
        if np.max(np.abs(res)) < 1e-6:
            break
        kd = 1.5 * vehicle.hertz * np.sqrt(dlp)
        J = np.block([[np.eye(4) + kd[:, None] * HF, kd[:, None] * Hc], [-AF, np.eye(3) - Ac]])
        step = np.linalg.solve(J, -res)
        # keep the forces positive: a Newton step past zero is shortened
        neg = step[:4] < 0
        lim = np.min(-0.9 * x[:4][neg] / step[:4][neg]) if np.any(neg) else 1.0
        x = x + min(1.0, lim) * step
    else:
        raise DynamicsError("no static equilibrium found at the first step (check roughness, angles and loads)")
    F, c = x[:4], x[4:]
    if np.any(gap(F, c) <= 0) or np.any(F <= 0):
        raise DynamicsError(f"the static equilibrium at the first step has no contact at wheel(s) "
                            f"{np.flatnonzero(gap(F, c) <= 0).tolist()} (roughness too large at the start?)")
    return F, preload_of(c)


def simulate_passage(vehicle: Vehicle, layout: TrackLayout, passage: PassageInput, *, progress=None,
                     track: TrackOptions = TrackOptions()) -> Passage:
    """Simulate one passage of the bogie (module docstring).

    Parameters
    ----------
    vehicle : Vehicle
        From :func:`lab_data.line.vehicle.build_vehicle`.
    layout : TrackLayout
        Supports along the line (chainage and per-sleeper parameters), or the continuous option.
    passage : PassageInput
    progress : callable, optional
        Called as ``progress(fraction_done)`` about once per simulated second.
    track : TrackOptions
        Ring length and rail modal truncation.

    Returns
    -------
    Passage

    Raises
    ------
    DynamicsError
        Inputs that cannot be simulated (no static contact at the start, divergence).
    """
    t_setup = time.perf_counter()
    dt = passage.dt
    n_t = passage.n_steps
    p = vehicle.params
    ts = _track_setup(layout, track, dt, p.wheelbase)
    N1 = ts.W.shape[1]
    so = 1.0 if passage.orientation == "normal" else -1.0
    x_ws = np.array([0.5, 0.5, -0.5, -0.5]) * p.wheelbase
    wheel_ch = passage.bogie_chainage[None, :] + so * x_ws[:, None]
    wheel_rail = np.array([0, 1, 0, 1] if so > 0 else [1, 0, 1, 0], dtype=np.int64)
    if not layout.continuous:
        warn_short_layout(layout, float(wheel_ch.min()), float(wheel_ch.max()), 0.5 * ts.ring_length)
    Xw = np.ascontiguousarray(np.mod(wheel_ch - ts.c0, ts.ring_length))
    bogie_idx = np.floor((passage.bogie_chainage - ts.c0) / ts.spacing + 0.5).astype(np.int64)
    speed = passage.speed if passage.speed is not None else np.abs(np.gradient(passage.bogie_chainage, dt))
    kappa = passage.curvature
    a_y = np.ascontiguousarray(so * (speed**2 * kappa - 9.80665 * passage.cant * np.sign(kappa)))
    theta = np.ascontiguousarray(passage.contact_angle)
    rough = passage.wheel_roughness.copy()
    if passage.lateral_roughness is not None:
        rough += -np.sin(theta) * passage.lateral_roughness

    # --- supports: slots and their parameters at the first step
    fit = unit_loss_fit()
    nb = fit.tau.size
    n_slots = 2 * N1 if layout.continuous else ts.ns
    sup = np.zeros((4, 4, n_slots))
    pb = np.zeros((4, nb, n_slots))
    sb = np.zeros((4, nb, n_slots))
    par = np.zeros((4, N_PAR, n_slots))
    fac = np.zeros((4, 2, nb, n_slots))
    if layout.continuous:
        # within-step compliance of each foundation slot: its own mode's response to its own force
        cf_cont = ts.W**2 * ts.coef[:, 5, :] * ts.Lfac
        Cf_slot = np.concatenate([cf_cont, cf_cont], axis=1)  # (2, 2 N1)
    else:
        Cf_slot = np.repeat(ts.Gr_self[:, None], n_slots, axis=1)
    slot_sleeper = np.full(ts.ns, np.iinfo(np.int64).min, dtype=np.int64)
    n_columns = ts.table.shape[2]
    for i in range(n_slots):
        if layout.continuous:
            col = 0
        else:
            q0 = int(bogie_idx[0])
            slot_sleeper[i] = i + ts.ns * ((q0 - i + ts.ns // 2) // ts.ns)
            col = min(max(int(slot_sleeper[i]), 0), n_columns - 1)
        for rd in range(4):
            assign_slot(rd, i, col, ts.table, par, fac, fit.weights, fit.tau, dt, fit.g0, Cf_slot[rd % 2, i])

    # --- static equilibrium and initial states
    statics = {}
    for rd in range(4):
        rail = rd // 2
        on = np.flatnonzero(wheel_rail == rail)
        statics[rd] = _static_track(ts, par, rd, Xw[on, 0])
    F0, preload = _static_equilibrium(vehicle, statics, wheel_rail, rough[:, 0], theta[:, 0], float(a_y[0]))
    ny0, nz0 = -np.sin(theta[:, 0]), np.cos(theta[:, 0])
    b = vehicle.b.copy()
    b[:, 9] = b[:, 9] + vehicle.frame_b @ preload  # air springs levelled at the static position
    fyz = np.empty(8)
    fyz[0::2], fyz[1::2] = F0 * ny0, F0 * nz0
    u_full = np.concatenate([fyz, [a_y[0], 1.0]])
    s_veh = -(b @ u_full) / vehicle.lam
    bu = b @ u_full
    xc, xs, vc, vs, Pc, Ps, Pcc, Pcs = (np.zeros((4, N1)) for _ in range(8))
    for rd in range(4):
        rail, d = divmod(rd, 2)
        on = np.flatnonzero(wheel_rail == rail)
        st = statics[rd]
        comp = -F0[on] * (nz0[on] if d == 0 else ny0[on])
        q = st["q"] @ comp
        xc[rd] = q[:N1]
        xs[rd, 1:] = q[N1:]
        u_sl = st["slot_u"] @ comp
        f_sl = st["slot_f"] @ comp
        sup[rd, 0] = u_sl
        sup[rd, 1] = -f_sl / par[rd, 2]  # plate z: the subplate carries the pad force
        lc, lsn = ts.shapes(d, Xw[on, 0])
        if layout.continuous:
            Pc[rd] = f_sl[:N1] * ts.W[d] * ts.Lfac
            Ps[rd, 1:] = f_sl[N1 + 1:] * ts.W[d, 1:] * ts.Lfac[1:]
        else:
            sc, ssn = ts.shapes(d, np.arange(ts.ns) * ts.spacing)
            Pc[rd] = sc.T @ f_sl
            Ps[rd] = ssn.T @ f_sl
        Pcc[rd] = lc.T @ comp
        Pcs[rd] = lsn.T @ comp
        Pc[rd] += Pcc[rd]
        Ps[rd] += Pcs[rd]
    F_hist = np.stack([F0, F0])

    # --- kernel arrays
    E, beta0, beta1 = complex_step(vehicle.lam, dt)
    cvw = vehicle.contact_out * vehicle.weight
    # within-step compliance of the wheels: the modes' response to this step's forces + the static residual
    Gv = np.ascontiguousarray(np.real(np.einsum("km,m,ml->kl", cvw, beta1, b[:, :8])) + vehicle.contact_residual)
    sens = np.stack([_sensor_row(vehicle, sp) for sp in passage.sensors]) * (vehicle.weight * vehicle.lam)
    bT = np.ascontiguousarray(b.T)
    ns = ts.ns
    fft = fft_tables(ns)
    Eb = np.exp(-dt / fit.tau)
    sr, si = np.ascontiguousarray(s_veh.real), np.ascontiguousarray(s_veh.imag)
    bur, bui = np.ascontiguousarray(bu.real), np.ascontiguousarray(bu.imag)
    acc = np.zeros((len(passage.sensors), n_t))
    Fout = np.zeros((4, n_t))
    rail_out = np.zeros((4, n_t))
    wheel_out = np.zeros((4, n_t))
    newton_fail = np.zeros(1, dtype=np.int64)
    Cf_point = ts.Gr_self.copy()
    args_track = (xc, xs, vc, vs, Pc, Ps, Pcc, Pcs, ts.coef, ts.W, 2 * np.pi / ts.ring_length, ts.Gr_self, ts.Gr_pair,
                  wheel_rail, ns, ts.continuous, Cf_point, ts.Lfac, sup, pb, sb, par, fac, ts.table, slot_sleeper,
                  fit.weights, fit.tau, Eb, fit.g0, *fft)
    args_veh = (sr, si, bur, bui, np.ascontiguousarray(vehicle.lam.real), np.ascontiguousarray(vehicle.lam.imag),
                np.ascontiguousarray(E.real), np.ascontiguousarray(E.imag), np.ascontiguousarray(beta0.real),
                np.ascontiguousarray(beta0.imag), np.ascontiguousarray(beta1.real), np.ascontiguousarray(beta1.imag),
                np.ascontiguousarray(bT.real), np.ascontiguousarray(bT.imag), np.ascontiguousarray(cvw.real),
                np.ascontiguousarray(cvw.imag), Gv, np.ascontiguousarray(sens.real), np.ascontiguousarray(sens.imag),
                float(vehicle.hertz), F_hist, acc, Fout, rail_out, wheel_out, newton_fail)
    setup_s = time.perf_counter() - t_setup
    t_kernel = time.perf_counter()
    c_kernel = time.process_time()
    chunk = max(1, int(round(1.0 / dt)))
    for i0 in range(0, n_t, chunk):
        i1 = min(n_t, i0 + chunk)
        passage_kernel(i0, i1, dt, Xw, rough, theta, a_y, bogie_idx, *args_track, *args_veh)
        if progress is not None:
            progress(i1 / n_t)
    kernel_s = time.perf_counter() - t_kernel
    kernel_cpu = time.process_time() - c_kernel
    if newton_fail[0]:
        log.warning("contact Newton iteration did not converge in %d of %d steps", int(newton_fail[0]), n_t)
    if not np.all(np.isfinite(acc)):
        raise DynamicsError("the simulation diverged (non-finite accelerations)")
    return Passage(np.arange(n_t) * dt, acc, Fout, Fout <= 0.0, rail_out, wheel_out, F0, passage.sensors,
                   {"setup": setup_s, "kernel": kernel_s, "kernel_cpu": kernel_cpu})


def compile_kernels(vehicle: Vehicle) -> float:
    """Compile the kernels, or load them from numba's on-disk cache (``cache=True``); returns the seconds taken.

    A ten-step passage on a short discrete layout triggers the compilation for exactly the argument types
    :func:`simulate_passage` uses, so that a benchmark can report compilation apart from simulation.
    """
    t0 = time.perf_counter()
    n = 10
    layout = TrackLayout(np.arange(0.0, 120.0, 0.75))
    inp = PassageInput(DEFAULT_DT, np.full(n, 60.0), 1, "normal", np.zeros((4, n)), np.zeros((4, n)), np.zeros(n),
                       np.zeros(n), (SensorPoint(1, "L", "z", (0.0, -0.97, 0.0)),))
    simulate_passage(vehicle, layout, inp)
    return time.perf_counter() - t0
