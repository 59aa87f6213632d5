"""The virtual line's track: two Timoshenko rails on discrete two-layer supports, as a periodic "ring".

Trackform (thesis §2.4, Table 2.2): a 50E5 rail (Timoshenko beam, vertical
bending with ``I_yy``, lateral bending with ``I_zz``, no torsion: the thesis's
decoupling of vertical and lateral track dynamics), fastened every ``L_s`` by
the *Milano Modificato* two-layer fastening: rail pad – baseplate mass –
subplate, vertical and lateral. The two rails are dynamically independent.

**Formulation (the ring).** Each rail and direction is a ring of length
``L_r = n_s L_s`` (``n_s`` a power of two, default 64 supports = 48 m) whose
free-rail motion is expanded in the Fourier modes of the periodic Timoshenko
beam: for every harmonic ``k_n = 2πn/L_r`` (``n ≤ N``, ``k_N ≤ k_max``) a
cosine and a sine mode of the lower (bending) branch of the 2×2
Timoshenko problem (deflection ``w``, section rotation ``ψ``)

.. math::

    \\begin{bmatrix} \\kappa G A k^2 & \\kappa G A k \\\\ \\kappa G A k & EI k^2 + \\kappa G A\\end{bmatrix}
    \\begin{bmatrix} W \\\\ \\Psi \\end{bmatrix} = \\omega^2
    \\begin{bmatrix} \\rho A & 0 \\\\ 0 & \\rho I\\end{bmatrix}\\begin{bmatrix} W \\\\ \\Psi \\end{bmatrix}

(the free-rail part of eq. 2.33), mass-normalised over the ring. What the
truncation leaves out (the shear branch and the harmonics above ``k_max``)
is kept as a quasi-static residual flexibility at every load point
(:attr:`RailModes.residual`), exact and the same everywhere because the free
ring is translation invariant — so a load moving between supports sees no
spurious "element passing". The supports are discrete point DOFs at ring
positions ``i L_s``: each a baseplate mass between the pad and the subplate,
both layers springs + dashpots (Table 2.2) with the causal loss model of
:mod:`lab_data.line.damping` in place of eq. 2.32's constant loss factor.
Their parameters come per sleeper from :class:`TrackLayout` (scatter,
sections, defects) and are reassigned as the bogie moves: the slot half a
ring behind the bogie takes the next sleeper ahead, 24 m from the wheels,
where the rail is at rest. Sleeper-passing excitation arises by itself from
the discrete supports. The rail's own loss factor is a modal damping ratio
``ζ = η_r / 2`` on every rail mode (causal; equal to eq. 2.31 at each
mode's resonance). ``TrackLayout(continuous=True)`` replaces the discrete
supports by the continuous foundation of eq. 2.32–2.34 (each harmonic on its
own foundation oscillator, per unit length): the linear-limit oracle's track.

A ring of 48 m is long enough for the waves the wheels send round it to come
back negligible: with continuous support the simulated axlebox response stays
within 0.03 dB of the infinite rail's frequency-domain solution over 20–400 Hz
(``tests/test_line_physics.py``).
"""

from __future__ import annotations

import warnings
from dataclasses import asdict, dataclass, field, fields

import numpy as np
from scipy.special import polygamma

from .damping import complex_stiffness

__all__ = [
    "TrackParameters",
    "TrackLayout",
    "TrackError",
    "SUPPORT_FIELDS",
    "RailModes",
    "milano_modificato",
    "rail_modes",
    "support_arrays",
    "foundation_stiffness",
    "warn_short_layout",
    "DIRECTIONS",
]

#: Track directions simulated: vertical (z) and lateral (y).
DIRECTIONS = ("z", "y")


class TrackError(ValueError):
    """Inconsistent track parameters or layout (names the field, the allowed values and what was received)."""


@dataclass(frozen=True)
class TrackParameters:
    """One rail's trackform, SI units, in the field names of ``receptance.Trackform`` (thesis Table 2.2).

    The line description (``line.json``) carries trackform sections in the same names, so
    ``TrackParameters(**section_parameters)`` reads them. ``rail_I_yy`` is the second moment of area for
    vertical bending, ``rail_I_zz`` for lateral bending; per-support quantities (``pad_*``, ``subplate_*``,
    ``baseplate_mass``) are per fastening.
    """

    rail_mass: float = 49.9
    rail_density: float = 7800.0
    rail_area: float = 63.62e-4
    rail_I_yy: float = 1844e-8
    rail_I_zz: float = 362.4e-8
    youngs_modulus: float = 206e9
    poisson_ratio: float = 0.28
    shear_factor: float = 0.34
    rail_loss_factor: float = 0.02
    support_spacing: float = 0.75
    pad_stiffness_z: float = 150e6
    pad_stiffness_y: float = 51.71e6
    pad_damping_z: float = 1.5e3
    pad_damping_y: float = 0.75e3
    pad_loss_factor: float = 0.13
    baseplate_mass: float = 15.0
    subplate_stiffness_z: float = 30e6
    subplate_stiffness_y: float = 10.3e6
    subplate_damping_z: float = 2.8e3
    subplate_damping_y: float = 1.4e3
    subplate_loss_factor: float = 0.20

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v) or v <= 0:
                raise TrackError(f"TrackParameters.{f.name} must be a finite number > 0, got {v!r}")
        if not self.poisson_ratio < 0.5:
            raise TrackError(f"TrackParameters.poisson_ratio must be < 0.5, got {self.poisson_ratio}")

    @property
    def shear_modulus(self) -> float:
        return self.youngs_modulus / (2 * (1 + self.poisson_ratio))

    def bending_inertia(self, direction: str) -> float:
        """``I`` of the rail for bending in ``direction`` ('z' vertical: ``rail_I_yy``; 'y' lateral: ``rail_I_zz``)."""
        _check_direction(direction)
        return self.rail_I_yy if direction == "z" else self.rail_I_zz

    def parameters(self) -> dict:
        return asdict(self)


def milano_modificato() -> TrackParameters:
    """Thesis Table 2.2 (*Milano Modificato*, 50E5 rail, L_s = 0.75 m) in SI units."""
    return TrackParameters()


#: Per-support fields that :class:`TrackLayout` may scale sleeper by sleeper.
SUPPORT_FIELDS = (
    "pad_stiffness_z", "pad_stiffness_y", "pad_damping_z", "pad_damping_y", "pad_loss_factor", "baseplate_mass",
    "subplate_stiffness_z", "subplate_stiffness_y", "subplate_damping_z", "subplate_damping_y",
    "subplate_loss_factor",
)


def _check_direction(direction: str) -> None:
    if direction not in DIRECTIONS:
        raise TrackError(f"track direction must be one of {DIRECTIONS}, got {direction!r}")


@dataclass(frozen=True)
class TrackLayout:
    """What a passage sees along the line, per rail.

    Attributes
    ----------
    support_chainage : ndarray (n_sleepers,)
        Chainage of every support [m], increasing, spaced ``base.support_spacing`` (within 1 mm).
    support_factors : dict of str to ndarray (2, n_sleepers)
        Multiplicative factors on the ``base`` value of a :data:`SUPPORT_FIELDS` entry, row 0 rail ``L``,
        row 1 rail ``R`` (scatter, sections, defects). Missing fields mean factor 1.
    base : TrackParameters
    continuous : bool
        True: continuously supported rails with the ``base`` parameters per unit length (eq. 2.32–2.34;
        the factors are ignored) — the linear-limit oracle's track.
    """

    support_chainage: np.ndarray
    support_factors: dict = field(default_factory=dict)
    base: TrackParameters = field(default_factory=TrackParameters)
    continuous: bool = False

    def __post_init__(self) -> None:
        s = np.asarray(self.support_chainage, float)
        if s.ndim != 1 or s.size < 2 or not np.all(np.isfinite(s)):
            raise TrackError(f"TrackLayout.support_chainage must be a 1-D finite array of >= 2 supports, got shape "
                             f"{s.shape}")
        gaps = np.diff(s)
        ls = self.base.support_spacing
        bad = np.flatnonzero(np.abs(gaps - ls) > 1e-3)
        if bad.size:
            i = int(bad[0])
            raise TrackError(f"TrackLayout.support_chainage must be spaced by support_spacing = {ls} m (within 1 mm); "
                             f"supports {i} and {i + 1} at {s[i]:.4f} m and {s[i + 1]:.4f} m are {gaps[i]:.4f} m apart")
        factors = {}
        for name, arr in dict(self.support_factors).items():
            if name not in SUPPORT_FIELDS:
                raise TrackError(f"TrackLayout.support_factors: unknown field {name!r}; allowed: {list(SUPPORT_FIELDS)}")
            a = np.asarray(arr, float)
            if a.shape != (2, s.size):
                raise TrackError(f"TrackLayout.support_factors[{name!r}] must have shape (2, {s.size}) "
                                 f"(rails L, R x supports), got {a.shape}")
            if not np.all(np.isfinite(a)) or np.any(a <= 0):
                i = np.flatnonzero(~np.isfinite(a) | (a <= 0))[0]
                raise TrackError(f"TrackLayout.support_factors[{name!r}] must be finite and > 0; support "
                                 f"{i % s.size} (chainage {s[i % s.size]:.3f} m) has {a.flat[i]!r}")
            factors[name] = a
        object.__setattr__(self, "support_chainage", s)
        object.__setattr__(self, "support_factors", factors)

    def values(self, name: str) -> np.ndarray:
        """Per-support values of a :data:`SUPPORT_FIELDS` entry, shape (2, n_sleepers) (rails L, R)."""
        if name not in SUPPORT_FIELDS:
            raise TrackError(f"unknown support field {name!r}; allowed: {list(SUPPORT_FIELDS)}")
        base = getattr(self.base, name)
        f = self.support_factors.get(name)
        return np.full((2, self.support_chainage.size), base) if f is None else base * f


@dataclass(frozen=True)
class RailModes:
    """Fourier modes of the free periodic Timoshenko rail (one direction) and their truncation residual.

    Mode ``j``: ``j = 0`` the uniform translation (harmonic 0); ``j = 2n - 1`` / ``2n`` the cosine / sine
    mode of harmonic ``n``: ``w(x) = W_n cos(k_n x)`` / ``W_n sin(k_n x)``, mass-normalised over the ring.

    Attributes
    ----------
    ring_length : float
    harmonics : int
        ``N``, the highest harmonic kept.
    k : ndarray (N + 1,)
        Wavenumbers ``2πn / L_r`` [rad/m].
    amplitude : ndarray (N + 1,)
        ``W_n`` [1/sqrt(kg)]: deflection per unit modal coordinate.
    omega : ndarray (N + 1,)
        Lower-branch natural frequencies [rad/s].
    zeta : float
        Modal damping ratio ``η_r / 2``.
    residual : float
        Static point flexibility [m/N] of everything the modes leave out (shear branch, harmonics above ``N``).
    """

    ring_length: float
    harmonics: int
    k: np.ndarray
    amplitude: np.ndarray
    omega: np.ndarray
    zeta: float
    residual: float

    @property
    def n_modes(self) -> int:
        return 2 * self.harmonics + 1

    def mode_omega(self) -> np.ndarray:
        """Natural frequency of every mode ``j`` [rad/s]."""
        return np.concatenate([[self.omega[0]], np.repeat(self.omega[1:], 2)])

    def mode_amplitude(self) -> np.ndarray:
        return np.concatenate([[self.amplitude[0]], np.repeat(self.amplitude[1:], 2)])

    def shapes(self, x: np.ndarray) -> np.ndarray:
        """Deflection of every mode at ring positions ``x``, shape (len(x), n_modes)."""
        x = np.atleast_1d(np.asarray(x, float))
        kx = x[:, None] * self.k[None, 1:]
        out = np.empty((x.size, self.n_modes))
        out[:, 0] = self.amplitude[0]
        out[:, 1::2] = self.amplitude[1:] * np.cos(kx)
        out[:, 2::2] = self.amplitude[1:] * np.sin(kx)
        return out


def rail_modes(p: TrackParameters, direction: str, ring_length: float, k_max: float) -> RailModes:
    """The Fourier modes of the free rail ring (module docstring) up to wavenumber ``k_max``.

    Parameters
    ----------
    p : TrackParameters
    direction : {'z', 'y'}
        Vertical (``rail_I_yy``) or lateral (``rail_I_zz``) bending.
    ring_length : float
        ``L_r`` [m].
    k_max : float
        Highest wavenumber kept [rad/m].
    """
    _check_direction(direction)
    if not ring_length > 0 or not k_max > 0:
        raise TrackError(f"ring_length and k_max must be > 0, got {ring_length}, {k_max}")
    EI = p.youngs_modulus * p.bending_inertia(direction)
    kGA = p.shear_factor * p.shear_modulus * p.rail_area
    rhoA = p.rail_mass
    rhoI = p.rail_density * p.bending_inertia(direction)
    N = int(np.floor(k_max * ring_length / (2 * np.pi)))
    if N < 1:
        raise TrackError(f"k_max = {k_max} rad/m keeps no harmonic of a {ring_length} m ring")
    n = np.arange(N + 1)
    k = 2 * np.pi * n / ring_length
    omega = np.zeros(N + 1)
    amp = np.zeros(N + 1)
    amp[0] = 1.0 / np.sqrt(rhoA * ring_length)
    kk = k[1:]
    # 2x2 generalised eigenproblem per harmonic, lower branch in closed form
    a11, a12, a22 = kGA * kk**2, kGA * kk, EI * kk**2 + kGA
    # det(K - w2 M) = 0:  rhoA rhoI w4 - (a11 rhoI + a22 rhoA) w2 + (a11 a22 - a12^2) = 0
    b = a11 * rhoI + a22 * rhoA
    c = a11 * a22 - a12**2
    w2 = (b - np.sqrt(b**2 - 4 * rhoA * rhoI * c)) / (2 * rhoA * rhoI)
    # eigenvector (W, Psi) with W = 1: (a11 - w2 rhoA) W + a12 Psi = 0
    psi = -(a11 - w2 * rhoA) / a12
    norm = np.sqrt(0.5 * ring_length * (rhoA + rhoI * psi**2))
    omega[1:] = np.sqrt(w2)
    amp[1:] = 1.0 / norm
    # static point flexibility of harmonic n (both cos and sin): (2/L_r)(1/(kGA k^2) + 1/(EI k^4));
    # the lower-branch modes carry W_n^2 / w_n^2 of it; the rest (shear branch) and the tail n > N are residual
    exact = (2 / ring_length) * (1 / (kGA * kk**2) + 1 / (EI * kk**4))
    kept = amp[1:] ** 2 / w2
    c1 = (2 / ring_length) * (ring_length / (2 * np.pi)) ** 2 / kGA
    c2 = (2 / ring_length) * (ring_length / (2 * np.pi)) ** 4 / EI
    tail = c1 * float(polygamma(1, N + 1)) + c2 * float(polygamma(3, N + 1)) / 6
    residual = float(np.sum(exact - kept) + tail)
    return RailModes(ring_length, N, k, amp, omega, p.rail_loss_factor / 2, residual)


def support_arrays(layout: TrackLayout, direction: str) -> dict[str, np.ndarray]:
    """Per-sleeper support parameters of one direction, each (2, n_sleepers) (rails L, R).

    Keys: ``pad_k, pad_c, pad_eta, plate_mass, sub_k, sub_c, sub_eta``.
    """
    _check_direction(direction)
    d = direction
    return {
        "pad_k": layout.values(f"pad_stiffness_{d}"),
        "pad_c": layout.values(f"pad_damping_{d}"),
        "pad_eta": layout.values("pad_loss_factor"),
        "plate_mass": layout.values("baseplate_mass"),
        "sub_k": layout.values(f"subplate_stiffness_{d}"),
        "sub_c": layout.values(f"subplate_damping_{d}"),
        "sub_eta": layout.values("subplate_loss_factor"),
    }


def foundation_stiffness(p: TrackParameters, direction: str, freqs_hz: np.ndarray) -> np.ndarray:
    """Complex stiffness of one support (pad – baseplate – subplate in series) with the causal layers [N/m].

    Eq. 2.34 per support (times ``L_s``) with the loss factors replaced by the causal fit of
    :mod:`lab_data.line.damping` — what the time-domain line simulates, for checks.
    """
    _check_direction(direction)
    f = np.asarray(freqs_hz, float)
    w = 2 * np.pi * f
    kp = complex_stiffness(getattr(p, f"pad_stiffness_{direction}"), p.pad_loss_factor, f,
                           getattr(p, f"pad_damping_{direction}"))
    ks = complex_stiffness(getattr(p, f"subplate_stiffness_{direction}"), p.subplate_loss_factor, f,
                           getattr(p, f"subplate_damping_{direction}"))
    kb = ks - w**2 * p.baseplate_mass
    return kp * kb / (kp + kb)


def warn_short_layout(layout: TrackLayout, chainage_min: float, chainage_max: float, half_ring: float) -> None:
    """Warn when the passage comes closer than half a ring to a layout end (the end supports' parameters are
    used beyond it)."""
    s = layout.support_chainage
    if chainage_min - half_ring < s[0] - 1e-9 or chainage_max + half_ring > s[-1] + 1e-9:
        warnings.warn(
            f"the passage ({chainage_min:.1f}-{chainage_max:.1f} m) comes within half a track ring ({half_ring:.1f} m) "
            f"of the layout's ends ({s[0]:.1f}-{s[-1]:.1f} m): supports beyond the layout take the parameters of "
            f"the layout's end support", stacklevel=3)
