"""Track point receptance: infinite Timoshenko rail on a two-layer support (thesis §2.4).

Model (eqs. 2.31–2.35).  The rail is an infinite Timoshenko beam with complex
moduli ``E* = E(1+jη_r)``, ``G* = E*/(2(1+ν))`` (eq. 2.31).  It rests either

* on a **continuous** support of per-metre dynamic stiffness ``k_eq*(Ω)``
  (eq. 2.34 exactly as written: rail pad ``k_rp* = K_rp/L_s (1+jη_rp)`` plus
  its viscous damper ``jΩ C_rp/L_s`` in series, through the baseplate mass
  ``M_p/L_s``, with the subplate ``k_sp* + jΩ C_sp/L_s``), or
* on **discrete** supports every ``L_s``, each of dynamic stiffness
  ``L_s k_eq*(Ω)`` (the same spring–mass–spring per support), which shows the
  pinned–pinned resonance the continuous model cannot (thesis §1.2, eq. 1.2).

Eq. 2.32's loss factor is the same at every frequency, which no causal material has; with
``Trackform.loss_reference_hz`` set, the layers follow the causal constant-loss law instead
(:func:`layer_dispersion`: the same loss factor, a stiffness rising with frequency, the table's value at
the reference frequency).

Eq. 2.33 is used with ``E* I`` in the bending term (the thesis prints
``E_r^*`` alone, a dropped ``I``) and ``ρ_r I`` rotary inertia.  With
``w, Φ ∝ exp(-jkx)`` (eq. 2.35) the wavenumber-domain solution for a unit
point force at ``x = 0`` is::

    W(k) = N(k) / D(k),    N = E*I k² + κG*A − ρIΩ²
    D(k) = κG*A E*I k⁴ + (s E*I − κG*A ρIΩ²) k² + s (κG*A − ρIΩ²),
    s = k_eq* − m_r Ω²

``D`` is a quadratic in ``k²`` with roots ``λ₁, λ₂``; of the four wavenumbers
``±√λ`` the two with ``Im k < 0`` are the outgoing/decaying waves for
``x > 0`` and closing the inverse Fourier integral in the lower half plane
gives (residue theorem)::

    w(x) = −j Σ_{n=1,2} N(k_n) exp(−j k_n |x|) / (2 κG*A E*I k_n (k_n² − λ_m)),  m ≠ n

Conventions: time dependence ``exp(+jΩt)`` (thesis), receptance in m/N, a
force along +z (+y) gives a displacement along +z (+y); the static limit is
real and positive.  Lateral bending uses ``I_zz`` and the lateral pad and
subplate values; the thesis treats the two directions as decoupled.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from ema.frf import FrequencyResponse
from receptance.trackform import Trackform

__all__ = [
    "BeamSection",
    "beam_section",
    "support_stiffness_per_metre",
    "layer_dispersion",
    "wavenumber_roots",
    "green_function",
    "track_receptance",
    "track_frf",
    "pinned_pinned_frequency",
    "pinned_pinned_eq_1_2",
    "DIRECTIONS",
]

log = logging.getLogger("receptance")

DIRECTIONS = ("vertical", "lateral")
SUPPORTS = ("continuous", "discrete")


@dataclass(frozen=True)
class BeamSection:
    """Complex beam constants of one bending plane at one set of frequencies.

    Attributes
    ----------
    EI : complex
        ``E* I`` [N m²].
    kGA : complex
        ``κ G* A`` [N].
    rhoI : float
        ``ρ I`` rotary inertia per length [kg m].
    m : float
        Mass per length [kg/m].
    """

    EI: complex
    kGA: complex
    rhoI: float
    m: float


def _check_direction(direction: str) -> str:
    if direction not in DIRECTIONS:
        raise ValueError(f"direction must be one of {DIRECTIONS}, got {direction!r}")
    return direction


def beam_section(trackform: Trackform, direction: str = "vertical") -> BeamSection:
    """Complex rail section constants (eq. 2.31) for vertical (``I_yy``) or lateral (``I_zz``) bending."""
    _check_direction(direction)
    tf = trackform
    I = tf.rail_I_yy if direction == "vertical" else tf.rail_I_zz
    E = tf.youngs_modulus * (1 + 1j * tf.rail_loss_factor)
    G = E / (2 * (1 + tf.poisson_ratio))
    return BeamSection(EI=E * I, kGA=tf.shear_factor * G * tf.rail_area, rhoI=tf.rail_density * I, m=tf.rail_mass)


def support_stiffness_per_metre(f_hz, trackform: Trackform = Trackform(), direction: str = "vertical") -> np.ndarray:
    """Equivalent continuous support stiffness ``k_eq*(Ω)`` [N/m²], eq. 2.34 (with eq. 2.32).

    Multiply by ``L_s`` for the dynamic stiffness of one discrete support. With
    ``trackform.loss_reference_hz`` set, each layer's ``K (1 + jη)`` of eq. 2.32 becomes the causal
    constant-loss law :func:`layer_dispersion` (same loss factor, stiffness rising with frequency).
    """
    _check_direction(direction)
    tf = trackform
    f = np.asarray(f_hz, dtype=float)
    w = 2 * np.pi * f
    L = tf.support_spacing
    if direction == "vertical":
        Krp, Crp, Ksp, Csp = tf.pad_stiffness_z, tf.pad_damping_z, tf.subplate_stiffness_z, tf.subplate_damping_z
    else:
        Krp, Crp, Ksp, Csp = tf.pad_stiffness_y, tf.pad_damping_y, tf.subplate_stiffness_y, tf.subplate_damping_y
    krp = Krp / L * (1 + 1j * tf.pad_loss_factor) * layer_dispersion(f, tf.pad_loss_factor, tf.loss_reference_hz)
    ksp = Ksp / L * (1 + 1j * tf.subplate_loss_factor) * layer_dispersion(f, tf.subplate_loss_factor,
                                                                           tf.loss_reference_hz)
    pad = krp + 1j * w * Crp / L
    sub = ksp + 1j * w * Csp / L - w**2 * tf.baseplate_mass / L
    return pad * sub / (krp + ksp + 1j * w * (Crp + Csp) / L - w**2 * tf.baseplate_mass / L)


#: Below this frequency a dispersive layer keeps its stiffness there: the power law holds over the band a pad is
#: characterised in, not down to a static stiffness of zero.
DISPERSION_FLOOR_HZ = 1.0


def layer_dispersion(f_hz, loss_factor: float, reference_hz: float | None) -> np.ndarray | float:
    """Storage-stiffness ratio ``(f / f_ref)^{2 arctan(η)/π}`` of a causal constant-loss layer (1 when ``None``).

    Kjartansson's constant-Q law (*J. Geophys. Res.* 84, 1979): ``K(f) ∝ (j f / f_ref)^{2γ}``, ``γ =
    arctan(η)/π``, has the phase ``arctan η`` of eq. 2.32 at every frequency and, unlike eq. 2.32, a causal
    impulse response: Kramers–Kronig ties the loss to a stiffness rising by ``2 arctan(η)/π ≈ 2η/π`` per neper
    of frequency. Multiplying eq. 2.32's ``K (1 + jη)`` by this ratio gives that law with the table's value at
    ``f_ref``. Frequencies below :data:`DISPERSION_FLOOR_HZ` take its value.
    """
    if reference_hz is None:
        return 1.0
    f = np.maximum(np.abs(np.asarray(f_hz, dtype=float)), DISPERSION_FLOOR_HZ)
    return (f / float(reference_hz)) ** (2.0 * np.arctan(loss_factor) / np.pi)


def wavenumber_roots(omega, section: BeamSection, k_support) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Roots of the dispersion relation ``D(k) = 0`` of eq. 2.33.

    Parameters
    ----------
    omega : ndarray
        Angular frequencies [rad/s].
    section : BeamSection
    k_support : ndarray or complex
        Support stiffness per metre ``k_eq*`` (0 for a free rail).

    Returns
    -------
    k : ndarray complex (2, n)
        The two wavenumbers with ``Im k < 0`` (outgoing/decaying for ``x > 0``).
    lam : ndarray complex (2, n)
        The corresponding ``k²`` roots.
    s : ndarray complex (n,)
        ``k_eq* − m Ω²``.
    """
    w = np.atleast_1d(np.asarray(omega, dtype=float))
    s = np.asarray(k_support, dtype=complex) - section.m * w**2
    s = np.broadcast_to(s, w.shape)
    a, EI, rI = section.kGA, section.EI, section.rhoI
    A2 = a * EI
    B = s * EI - a * rI * w**2
    C = s * (a - rI * w**2)
    sq = np.sqrt(B * B - 4 * A2 * C)
    sq = np.where((np.conj(B) * sq).real < 0, -sq, sq)
    q = -0.5 * (B + sq)          # numerically stable quadratic formula
    lam = np.stack([q / A2, C / q])
    k = np.sqrt(lam)
    k = np.where(k.imag > 0, -k, k)
    return k, lam, s


def green_function(f_hz, x, section: BeamSection, k_support) -> np.ndarray:
    """Displacement at distance ``x`` [m] of an infinite Timoshenko beam per unit point force.

    Residue sum over the two waves with ``Im k < 0`` (see module docstring).

    Parameters
    ----------
    f_hz : array_like (n,)
    x : array_like
        Distances; broadcast against ``f_hz`` as ``(..., n)``; ``|x|`` is used.
    section : BeamSection
    k_support : complex or ndarray (n,)
        Support stiffness per metre (0: free rail).

    Returns
    -------
    ndarray complex, broadcast shape of ``x`` and ``f_hz`` [m/N]
    """
    w = 2 * np.pi * np.atleast_1d(np.asarray(f_hz, dtype=float))
    k, lam, _ = wavenumber_roots(w, section, k_support)
    N = section.EI * lam + section.kGA - section.rhoI * w**2
    denom = 2 * section.kGA * section.EI * k * (lam - lam[::-1])
    amp = -1j * N / denom                       # (2, n)
    ax = np.abs(np.asarray(x, dtype=float))[..., None]
    return (amp[0] * np.exp(-1j * k[0] * ax) + amp[1] * np.exp(-1j * k[1] * ax))


def _discrete_receptance(f_hz, trackform: Trackform, direction: str, position: float,
                         n_theta: int | None) -> np.ndarray:
    """Group frequencies by the number of Floquet points they need, evaluate in memory-bounded chunks."""
    f = np.atleast_1d(np.asarray(f_hz, dtype=float))
    if n_theta is None:
        # Poles of the θ integrand lie ~Im(k)·L_s from the real axis, k the (continuous-model)
        # track wavenumbers; the periodic trapezoidal rule then errs by ~exp(−N Im(k) L_s).
        k, _, _ = wavenumber_roots(2 * np.pi * f, beam_section(trackform, direction),
                                   support_stiffness_per_metre(f, trackform, direction))
        d = np.abs(k.imag).min(axis=0) * trackform.support_spacing
        need = np.clip(30.0 / np.maximum(d, 1e-12), 256, 2**17)
        n_per_f = (2 ** np.ceil(np.log2(need))).astype(int)
    else:
        n_per_f = np.full(f.size, int(n_theta))
    out = np.empty(f.size, dtype=complex)
    for n in np.unique(n_per_f):
        idx = np.flatnonzero(n_per_f == n)
        step = max(1, 2**20 // n)
        for i0 in range(0, idx.size, step):
            sel = idx[i0:i0 + step]
            out[sel] = _discrete_receptance_fixed(f[sel], trackform, direction, position, int(n))
    return out


def _discrete_receptance_fixed(f_hz, trackform: Trackform, direction: str, position: float,
                               n_theta: int) -> np.ndarray:
    """Point receptance of a rail on periodic discrete supports (Floquet / Fourier-sum method).

    With supports at ``x_n = n L`` of dynamic stiffness ``k_s = L k_eq*`` and the force at
    ``x_F = position·L``, the support displacements satisfy the lattice convolution
    ``w_m = G(mL − x_F) − k_s Σ_n G((m−n)L) w_n`` (G: free-rail Green function).  Its discrete
    Fourier transform over ``n`` (Floquet parameter θ) gives
    ``w(x_F) = G(0) − k_s/(2π) ∫ S(θ) S(−θ) / (1 + k_s S₀(θ)) dθ`` with the lattice sums
    ``S(θ) = Σ_m G(mL − x_F) e^{−jmθ}``, ``S₀(θ) = Σ_n G(nL) e^{−jnθ}`` summed in closed form
    (geometric series of ``exp(−jk|x|)``).  The θ integral of a smooth periodic function is
    done with the trapezoidal rule on ``n_theta`` points.
    """
    L = trackform.support_spacing
    xF = position * L
    f = np.atleast_1d(np.asarray(f_hz, dtype=float))
    w = 2 * np.pi * f
    sec = beam_section(trackform, direction)
    ks = L * support_stiffness_per_metre(f, trackform, direction)          # (n,)
    k, lam, _ = wavenumber_roots(w, sec, 0.0)
    N = sec.EI * lam + sec.kGA - sec.rhoI * w**2
    amp = -1j * N / (2 * sec.kGA * sec.EI * k * (lam - lam[::-1]))        # (2, n)
    theta = -np.pi + 2 * np.pi * (np.arange(n_theta) + 0.5) / n_theta     # (t,)
    kk = k[:, :, None]
    aa = amp[:, :, None]
    th = theta[None, None, :]

    def lattice(x0, sign):
        # Σ_m exp(-jk|mL - x0|) exp(-j sign m θ), 0 <= x0 < L
        q_plus = np.exp(-1j * (kk * L + sign * th))
        q_minus = np.exp(-1j * (kk * L - sign * th))
        return (np.exp(1j * kk * x0) * q_plus / (1 - q_plus) + np.exp(-1j * kk * x0) / (1 - q_minus))

    S_p = (aa * lattice(xF, +1)).sum(axis=0)
    S_m = (aa * lattice(xF, -1)).sum(axis=0)
    S_0 = (aa * lattice(0.0, +1)).sum(axis=0)
    G0 = amp.sum(axis=0)
    integrand = S_p * S_m / (1 + ks[:, None] * S_0)
    # The lightly damped free-rail waves put simple poles of the integrand at θ = ±k_n L,
    # a distance Im(k_n) L (tiny at low frequency) from the real axis.  Their singular
    # part is exactly (a_n/k_s)(g₊ + g₋), g± = 1/(1 − exp(−j(k_n L ± θ))), whose θ-mean
    # is exactly 1 (geometric series); subtract it and add the mean back analytically.
    g_sum = 1 / (1 - np.exp(-1j * (kk * L + th))) + 1 / (1 - np.exp(-1j * (kk * L - th)))
    singular = (aa * g_sum).sum(axis=0) / ks[:, None]
    mean = (integrand - singular).mean(axis=1) + 2 * G0 / ks
    return G0 - ks * mean


def track_receptance(f_hz, trackform: Trackform = Trackform(), direction: str = "vertical", *,
                     supports: str = "continuous", position: float = 0.5, n_theta: int | None = None) -> np.ndarray:
    """Rail point receptance under a harmonic point force (thesis §2.4, eqs. 2.31–2.35).

    Parameters
    ----------
    f_hz : array_like
        Frequencies [Hz], >= 0 (vectorised).
    trackform : Trackform
        Rail and support data (default: thesis Table 2.2).
    direction : {"vertical", "lateral"}
        Vertical uses ``I_yy`` and the ``*_z`` support values; lateral ``I_zz`` and ``*_y``.
    supports : {"continuous", "discrete"}
        ``"continuous"``: closed form of eq. 2.33 with ``k_eq*`` of eq. 2.34 (the thesis model).
        ``"discrete"``: periodic spring–mass–spring supports every ``L_s`` (one support =
        ``L_s k_eq*``), periodic-structure solution; shows the pinned–pinned resonance.
    position : float
        For ``"discrete"``: force/response point as a fraction of the bay, ``0`` above a
        support, ``0.5`` mid-span (default).  Ignored for ``"continuous"``.
    n_theta : int, optional
        Trapezoidal points of the Floquet integral (``"discrete"`` only).  Default: chosen per
        frequency from the decay per bay ``Im(k) L_s`` of the track waves so that the
        (exponentially convergent) periodic trapezoidal rule is accurate to ~1e-12.

    Returns
    -------
    ndarray complex, shape of ``f_hz``
        Receptance ``w(0)/F`` [m/N], ``exp(+jΩt)`` convention.

    Raises
    ------
    ValueError
        Unknown ``direction``/``supports``, negative frequencies or ``position`` outside [0, 1).
    """
    _check_direction(direction)
    if supports not in SUPPORTS:
        raise ValueError(f"supports must be one of {SUPPORTS}, got {supports!r}")
    f = np.asarray(f_hz, dtype=float)
    if np.any(~np.isfinite(f)) or np.any(f < 0):
        raise ValueError("f_hz must be finite and >= 0")
    shape = f.shape
    f1 = f.ravel()
    if supports == "continuous":
        sec = beam_section(trackform, direction)
        out = green_function(f1, 0.0, sec, support_stiffness_per_metre(f1, trackform, direction))
    else:
        if not 0 <= position < 1:
            raise ValueError(f"position must be a bay fraction in [0, 1), got {position!r}")
        if n_theta is not None and n_theta < 16:
            raise ValueError(f"n_theta must be >= 16, got {n_theta!r}")
        out = _discrete_receptance(f1, trackform, direction, position, n_theta)
    return np.asarray(out).reshape(shape)


def track_frf(f_hz, trackform: Trackform = Trackform(), *, supports: str = "continuous",
              position: float = 0.5) -> FrequencyResponse:
    """Vertical and lateral rail receptances as one :class:`~ema.frf.FrequencyResponse`.

    The 2×2 receptance has outputs and inputs ``("rail_z", "rail_y")``; the diagonal holds
    :func:`track_receptance` for ``"vertical"`` and ``"lateral"``, the cross terms are zero
    because the thesis model decouples the two directions (§2.4.1, load on the neutral axis).
    """
    f = np.asarray(f_hz, dtype=float)
    data = np.zeros((2, 2, f.size), dtype=complex)
    data[0, 0] = track_receptance(f, trackform, "vertical", supports=supports, position=position)
    data[1, 1] = track_receptance(f, trackform, "lateral", supports=supports, position=position)
    return FrequencyResponse(freqs_hz=f, data=data, outputs=("rail_z", "rail_y"), inputs=("rail_z", "rail_y"),
                             quantity="receptance",
                             history=(f"track_receptance(supports={supports!r}, thesis §2.4)",))


def pinned_pinned_frequency(trackform: Trackform = Trackform(), direction: str = "vertical") -> float:
    """Exact first pinned–pinned frequency of a Timoshenko rail span ``L_s`` [Hz] (lossless).

    With ``w = sin(πx/L)`` the span is a standing wave of real wavenumber ``k = π/L_s``;
    setting ``D(k) = 0`` of eq. 2.33 with no support and real moduli gives a quadratic in
    ``Ω²`` whose lower root is returned.
    """
    tf = trackform
    I = tf.rail_I_yy if _check_direction(direction) == "vertical" else tf.rail_I_zz
    E = tf.youngs_modulus
    a = tf.shear_factor * E / (2 * (1 + tf.poisson_ratio)) * tf.rail_area
    k2 = (np.pi / tf.support_spacing) ** 2
    m, rI = tf.rail_mass, tf.rail_density * I
    # (a k² − mΩ²)(E I k² + a − ρIΩ²) − a² k² = 0  →  c2 Ω⁴ + c1 Ω² + c0 = 0
    c2 = m * rI
    c1 = -(m * (E * I * k2 + a) + a * k2 * rI)
    c0 = a * E * I * k2 * k2
    w2 = np.roots([c2, c1, c0]).real.min()
    return float(np.sqrt(w2) / (2 * np.pi))


def pinned_pinned_eq_1_2(trackform: Trackform = Trackform(), direction: str = "vertical") -> float:
    """Pinned–pinned frequency by thesis eq. 1.2 (first-order shear/rotary-inertia correction) [Hz]."""
    tf = trackform
    I = tf.rail_I_yy if _check_direction(direction) == "vertical" else tf.rail_I_zz
    L = tf.support_spacing
    rg = np.sqrt(I / tf.rail_area)
    f0 = np.pi / (2 * L**2) * np.sqrt(tf.youngs_modulus * I / tf.rail_mass)
    return float(f0 * (1 - 0.5 * (np.pi * rg / L) ** 2 * (1 + 2 * (1 + tf.poisson_ratio) / tf.shear_factor)))
