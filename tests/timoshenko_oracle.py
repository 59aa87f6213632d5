"""Analytic reference values for a uniform free-free shaft (test oracle).

This module is deliberately independent of any finite-element code in the
project.  It provides

* :func:`free_free_bending_frequencies` -- flexural natural frequencies of a
  uniform free-free Timoshenko beam (shear deformation + rotary inertia),
  obtained from the exact frequency equation;
* :func:`free_free_torsion_frequencies` -- torsional natural frequencies of a
  uniform free-free circular (solid or hollow) shaft;
* :func:`solid_or_hollow_circle` -- section properties ``A, I, J, kappa`` of a
  solid or hollow circular section;
* :func:`timoshenko_cutoff_frequency` -- the second-spectrum cut-off
  frequency ``sqrt(kappa G A / (rho I)) / (2 pi)``.

Formulation
-----------
With transverse deflection ``w(x)`` and cross-section rotation ``psi(x)`` the
harmonic Timoshenko equations are::

    kappa G A (w'' - psi') + rho A omega^2 w = 0
    E I psi'' + kappa G A (w' - psi) + rho I omega^2 psi = 0

and the free-end conditions are zero bending moment ``E I psi' = 0`` and zero
shear force ``kappa G A (w' - psi) = 0`` at ``x = 0`` and ``x = L``.

Everything is made dimensionless with ``xi = x / L``::

    lam = omega^2 rho A L^4 / (E I)        (Euler-Bernoulli: lam = (beta L)^4)
    g   = E I / (kappa G A L^2)            (shear flexibility)
    s2  = I / (A L^2)                      (rotary inertia, (r/L)^2)

Trying ``w, psi ~ exp(t xi)`` gives the characteristic equation in ``t^2``::

    t^4 + lam (g + s2) t^2 + lam (lam g s2 - 1) = 0

Its roots are ``t^2 = -b^2`` (always negative, so one trigonometric pair
``cos/sin(b xi)``) and ``t^2 = a2 = lam (1 - lam g s2) / b^2``.  Below the
cut-off ``lam_c = 1 / (g s2)`` (i.e. ``omega_c = sqrt(kappa G A / (rho I))``)
``a2 > 0`` and the second pair is hyperbolic (``cosh/sinh(a xi)``); above
it ``a2 < 0`` and the second pair is trigonometric as well
(``cos/sin(c xi)`` with ``c^2 = -a2``).  ``b^2`` is computed as
``(B + sqrt(B^2 - 4C)) / 2`` and ``a2`` as ``-C / b^2`` so that neither root
suffers from cancellation.

The beam is split about its centre (``xi`` in ``[-1/2, 1/2]``): symmetric
modes have even ``w`` and odd ``psi``, antisymmetric modes odd ``w`` and
even ``psi``.  Each family needs only the two conditions at ``xi = 1/2``,
i.e. a 2x2 determinant.  With ``K = lam g`` and ``h = 1/2``, ``psi`` follows
from ``psi' = w'' + K w`` (no integration constant for exponential
solutions).  The determinants, written without poles and with the
hyperbolic columns divided by ``cosh(a h) > 0`` (so no overflow for large
``a``), are

below cut-off (``a = sqrt(a2)``)::

    D_sym  = (K - b^2) cos(bh) tanh(ah)/a - (a^2 + K) sin(bh)/b
    D_anti = a (a^2 + K) tanh(ah) cos(bh)/b + (K - b^2) sin(bh)

above cut-off (``c = sqrt(-a2)``)::

    D_sym  = (K - b^2) cos(bh) sin(ch)/c - (K - c^2) cos(ch) sin(bh)/b
    D_anti = -c (K - c^2) sin(ch) cos(bh)/b + (K - b^2) sin(bh) cos(ch)

Both branches are entire functions of the wave numbers (the "above" forms
are the "below" forms multiplied by ``cosh(ah) -> cos(ch)``), and they join
continuously at ``a = c = 0``, so every sign change on the frequency axis is
a genuine root -- there are no poles that could masquerade as roots.  Roots
are bracketed on a grid whose phase step in ``b h`` and ``c h`` is at most
``0.05`` rad and polished with :func:`scipy.optimize.brentq`; each root is
additionally checked to be a small-residual zero.  The rigid-body modes
(``lam = 0``) are excluded because the search starts at ``lam > 0``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

__all__ = [
    "free_free_bending_frequencies",
    "free_free_torsion_frequencies",
    "solid_or_hollow_circle",
    "timoshenko_cutoff_frequency",
    "BendingRoot",
    "free_free_bending_roots",
]

_H = 0.5  # dimensionless half length
_MAX_PHASE_STEP = 0.05  # rad, largest change of b*h or c*h between grid points


@dataclass(frozen=True)
class BendingRoot:
    """One flexural eigenvalue of the free-free Timoshenko beam.

    Attributes
    ----------
    lam : float
        Dimensionless eigenvalue ``omega^2 rho A L^4 / (E I)``.
    family : str
        ``"symmetric"`` (``w`` even about mid-span) or ``"antisymmetric"``.
    above_cutoff : bool
        True if the frequency exceeds the second-spectrum cut-off
        ``sqrt(kappa G A / (rho I))`` (both wave-number pairs trigonometric).
    """

    lam: float
    family: str
    above_cutoff: bool


def _check_positive(**kwargs: float) -> None:
    for name, value in kwargs.items():
        if not np.isfinite(value) or value <= 0.0:
            raise ValueError(f"{name} must be a positive finite number, got {value!r}")


def _wavenumbers(lam, g, s2):
    """Return ``b^2`` (>0) and the signed ``a2`` for dimensionless ``lam``."""
    lam = np.asarray(lam, dtype=float)
    B = lam * (g + s2)
    C = lam * (lam * g * s2 - 1.0)
    b2 = 0.5 * (B + np.sqrt(B * B - 4.0 * C))  # B^2 - 4C = (u - v)^2 + 4 lam > 0
    a2 = -C / b2
    return b2, a2


def _determinants(lam, g, s2):
    """Pole-free 2x2 frequency determinants ``(D_sym, D_anti)``.

    See the module docstring for the formulas.  Vectorised over ``lam``.
    """
    lam = np.asarray(lam, dtype=float)
    b2, a2 = _wavenumbers(lam, g, s2)
    K = lam * g
    b = np.sqrt(b2)
    h = _H
    sb, cb = np.sin(b * h), np.cos(b * h)

    below = a2 >= 0.0
    a = np.sqrt(np.abs(a2))  # a (below) or c (above)
    x = a * h
    # "S" = sinh(ah)/a (below) or sin(ch)/c (above); "Ch" = cosh(ah) or cos(ch).
    # Below the cut-off both are divided by cosh(ah) > 0 to avoid overflow.
    with np.errstate(invalid="ignore", divide="ignore"):
        small = x < 1e-8
        safe_a = np.where(small, 1.0, a)
        S_below = np.where(small, h, np.tanh(x) / safe_a)
        S_above = np.where(small, h, np.sin(x) / safe_a)
    S = np.where(below, S_below, S_above)
    Ch = np.where(below, 1.0, np.cos(x))

    d_sym = (K - b2) * cb * S - (a2 + K) * Ch * sb / b
    d_anti = a2 * S * (a2 + K) * cb / b + (K - b2) * sb * Ch
    return d_sym, d_anti


def _phase_ok(q, g, s2):
    b2, a2 = _wavenumbers(q**4, g, s2)
    db = np.max(np.abs(np.diff(np.sqrt(b2)))) * _H
    da = np.max(np.abs(np.diff(np.sqrt(np.abs(a2))))) * _H
    return max(db, da) <= _MAX_PHASE_STEP


def _roots_on_interval(q_lo, q_hi, g, s2):
    """All eigenvalues ``lam`` with ``q_lo < lam**0.25 < q_hi`` (both families)."""
    npts = 2000
    while True:
        q = np.linspace(q_lo, q_hi, npts)
        if _phase_ok(q, g, s2):
            break
        npts *= 2
        if npts > 5_000_000:  # pragma: no cover - pathological input
            raise RuntimeError("frequency grid became too large")
    lam = q**4
    dets = _determinants(lam, g, s2)
    lam_c = 1.0 / (g * s2)
    found: list[BendingRoot] = []
    for idx, (family, d) in enumerate(zip(("symmetric", "antisymmetric"), dets)):

        def f(x, _idx=idx):
            return float(_determinants(np.array([x]), g, s2)[_idx][0])

        for i in np.nonzero(d == 0.0)[0]:
            found.append(BendingRoot(float(lam[i]), family, bool(lam[i] > lam_c)))
        sign_change = np.nonzero(np.sign(d[:-1]) * np.sign(d[1:]) < 0)[0]
        for i in sign_change:
            root = brentq(f, lam[i], lam[i + 1], xtol=1e-300, rtol=4 * np.finfo(float).eps,
                          maxiter=200)
            # The determinants have no poles, but verify anyway that this is a
            # genuine zero and not a jump: the residual must be tiny compared
            # with the bracketing values.
            scale = max(abs(d[i]), abs(d[i + 1]))
            if abs(f(root)) > 1e-6 * scale:  # pragma: no cover - safety net
                raise RuntimeError(f"suspicious sign change near lam={root:g} ({family})")
            found.append(BendingRoot(float(root), family, bool(root > lam_c)))
    found.sort(key=lambda r: r.lam)
    return found


def free_free_bending_roots(n: int, *, g: float, s2: float) -> list[BendingRoot]:
    """First ``n`` elastic eigenvalues in dimensionless form.

    Parameters
    ----------
    n : int
        Number of flexural modes (rigid-body modes excluded).
    g : float
        Shear-flexibility parameter ``E I / (kappa G A L^2)``.
    s2 : float
        Rotary-inertia parameter ``I / (A L^2)``.

    Returns
    -------
    list of BendingRoot
        Sorted by increasing ``lam = omega^2 rho A L^4 / (E I)``.
    """
    if int(n) != n or n < 1:
        raise ValueError(f"n must be a positive integer, got {n!r}")
    n = int(n)
    _check_positive(g=g, s2=s2)
    # Start well below the first elastic mode but away from the rigid-body
    # zero at lam = 0 (where the determinants vanish to high order).  Every
    # Timoshenko root lies below its Euler-Bernoulli counterpart
    # (beta_k L ~ (k + 1/2) pi), so this upper bound usually suffices; it is
    # enlarged until n roots are found.
    # q = lam**0.25 (= beta L in the Euler-Bernoulli limit, first root 4.73);
    # for extremely stocky sections the spectrum scales with the cut-off
    # q_c = (g s2)**-0.25, hence the min().
    q_lo = 1e-2 * min(1.0, (g * s2) ** -0.25)
    q_hi = 1.05 * (n + 0.5) * math.pi
    roots = _roots_on_interval(q_lo, q_hi, g, s2)
    while len(roots) < n:
        q_lo_next = q_hi
        q_hi *= 1.5
        roots += _roots_on_interval(q_lo_next, q_hi, g, s2)
    return roots[:n]


def free_free_bending_frequencies(n, *, L, E, G, rho, A, I, kappa) -> np.ndarray:
    """Flexural natural frequencies of a uniform free-free Timoshenko beam.

    Solves the exact frequency equation of the Timoshenko beam (shear
    deformation and rotary inertia included) with free ends, i.e. zero
    bending moment ``E I psi'`` and zero shear force ``kappa G A (w' - psi)``
    at both ends.  Both the regime below the second-spectrum cut-off
    ``omega_c = sqrt(kappa G A / (rho I))`` (one hyperbolic and one
    trigonometric wave pair) and the regime above it (two trigonometric
    pairs) are handled; second-spectrum modes above ``omega_c`` are included
    in the count.  See the module docstring for the method.

    Parameters
    ----------
    n : int
        Number of elastic flexural modes to return (rigid-body translation
        and rotation at 0 Hz are excluded).
    L : float
        Beam length [m].
    E : float
        Young's modulus [Pa].
    G : float
        Shear modulus [Pa].
    rho : float
        Density [kg/m^3].
    A : float
        Cross-section area [m^2].
    I : float
        Second moment of area about the bending axis [m^4].
    kappa : float
        Timoshenko shear coefficient [-].

    Returns
    -------
    numpy.ndarray
        Shape ``(n,)``, the first ``n`` flexural natural frequencies in Hz,
        ascending (symmetric and antisymmetric modes interleaved).

    Notes
    -----
    For ``kappa G A -> inf`` and ``I / (A L^2) -> 0`` the result tends to the
    Euler-Bernoulli values ``(beta_k L)^2 sqrt(E I / (rho A L^4)) / (2 pi)``
    with ``cos(beta L) cosh(beta L) = 1``.
    """
    _check_positive(L=L, E=E, G=G, rho=rho, A=A, I=I, kappa=kappa)
    g = E * I / (kappa * G * A * L**2)
    s2 = I / (A * L**2)
    roots = free_free_bending_roots(n, g=g, s2=s2)
    lam = np.array([r.lam for r in roots])
    omega = np.sqrt(lam * E * I / (rho * A * L**4))
    return omega / (2.0 * np.pi)


def timoshenko_cutoff_frequency(*, G, rho, A, I, kappa) -> float:
    """Second-spectrum cut-off frequency ``sqrt(kappa G A / (rho I)) / (2 pi)`` in Hz.

    Parameters
    ----------
    G, rho, A, I, kappa : float
        Shear modulus [Pa], density [kg/m^3], area [m^2], second moment of
        area [m^4] and shear coefficient [-].

    Returns
    -------
    float
        Frequency [Hz] above which both wave-number pairs of the Timoshenko
        equations are trigonometric.
    """
    _check_positive(G=G, rho=rho, A=A, I=I, kappa=kappa)
    return math.sqrt(kappa * G * A / (rho * I)) / (2.0 * math.pi)


def free_free_torsion_frequencies(n, *, L, G, rho) -> np.ndarray:
    """Torsional natural frequencies of a uniform free-free circular shaft.

    For a solid or hollow circular section the torsion constant equals the
    polar moment of area (no warping), so the torsional wave speed is
    ``c = sqrt(G / rho)`` independently of the diameter, and the free-free
    frequencies are ``f_k = k c / (2 L)``.

    Parameters
    ----------
    n : int
        Number of elastic modes (the rigid rotation at 0 Hz is excluded).
    L : float
        Shaft length [m].
    G : float
        Shear modulus [Pa].
    rho : float
        Density [kg/m^3].

    Returns
    -------
    numpy.ndarray
        Shape ``(n,)``, ``f_k = k / (2 L) * sqrt(G / rho)`` for ``k = 1..n`` [Hz].
    """
    if int(n) != n or n < 1:
        raise ValueError(f"n must be a positive integer, got {n!r}")
    _check_positive(L=L, G=G, rho=rho)
    k = np.arange(1, int(n) + 1, dtype=float)
    return k / (2.0 * L) * math.sqrt(G / rho)


def solid_or_hollow_circle(d_out, d_in=0.0, *, nu=0.3, shear_coefficient="cowper") -> dict:
    """Section properties of a solid or hollow circular section.

    Parameters
    ----------
    d_out : float
        Outer diameter [m].
    d_in : float, optional
        Inner diameter [m]; 0 (default) for a solid section.
    nu : float, optional
        Poisson's ratio used in the shear coefficient (default 0.3).
    shear_coefficient : {"cowper", "hutchinson"}, optional
        ``"cowper"`` (default): Cowper (1966), J. Appl. Mech. 33, 335-340,
        hollow circle with ``m = d_in / d_out``::

            kappa = 6 (1 + nu) (1 + m^2)^2
                    / ((7 + 6 nu) (1 + m^2)^2 + (20 + 12 nu) m^2)

        which gives ``6 (1 + nu) / (7 + 6 nu)`` for a solid section and
        ``2 (1 + nu) / (4 + 3 nu)`` in the thin-walled limit.
        ``"hutchinson"``: Hutchinson (2001), J. Appl. Mech. 68, 87-92, solid
        circle only, ``kappa = 6 (1 + nu)^2 / (7 + 12 nu + 4 nu^2)``.

    Returns
    -------
    dict
        ``A`` area [m^2], ``I`` second moment of area about a diameter
        [m^4], ``J`` torsion constant [m^4] (equal to the polar moment
        ``2 I`` for circular sections) and ``kappa`` shear coefficient [-],
        plus ``shear_coefficient`` naming the formula used.
    """
    _check_positive(d_out=d_out)
    if not (0.0 <= d_in < d_out):
        raise ValueError(f"need 0 <= d_in < d_out, got d_in={d_in!r}, d_out={d_out!r}")
    if not (-1.0 < nu < 0.5):
        raise ValueError(f"Poisson ratio must lie in (-1, 0.5), got {nu!r}")
    A = math.pi / 4.0 * (d_out**2 - d_in**2)
    I = math.pi / 64.0 * (d_out**4 - d_in**4)
    J = math.pi / 32.0 * (d_out**4 - d_in**4)
    m2 = (d_in / d_out) ** 2
    method = shear_coefficient.lower()
    if method == "cowper":
        kappa = 6.0 * (1.0 + nu) * (1.0 + m2) ** 2 / (
            (7.0 + 6.0 * nu) * (1.0 + m2) ** 2 + (20.0 + 12.0 * nu) * m2
        )
        label = "Cowper (1966)"
    elif method == "hutchinson":
        if d_in != 0.0:
            raise NotImplementedError(
                "only the solid-circle Hutchinson coefficient is implemented; "
                "use shear_coefficient='cowper' for hollow sections"
            )
        kappa = 6.0 * (1.0 + nu) ** 2 / (7.0 + 12.0 * nu + 4.0 * nu**2)
        label = "Hutchinson (2001)"
    else:
        raise ValueError(f"unknown shear_coefficient {shear_coefficient!r}")
    return {"A": A, "I": I, "J": J, "kappa": kappa, "shear_coefficient": label}
