"""Robustness of the transfer functions to modal-parameter uncertainty (thesis §4.2, Figs. 4.5–4.7).

The study of the thesis: ``N`` wheelset models are made by perturbing each
modal frequency and damping ratio of the nominal model by an independent
uniform random factor within ``±amplitude`` (10 % in the thesis); a test
irregularity (white noise on the left rail, none on the right) is turned
into axlebox accelerations through the *nominal* model (``a = B₀ D₀⁻¹ n``)
and back into irregularity through each *perturbed* model (``n̂ = D_p B_p⁺
a``); the per-frequency mean and standard deviation of ``|n̂|`` over the
``N`` models measure how much an error in the modal parameters spreads the
reconstructed irregularity.  This is done for the three models of
:mod:`receptance.transfer` (half wheelset, full vertical, full vertical +
lateral).

Perturbation (:func:`perturbation_factors`, :func:`perturbed_models`)
    Every oscillating pole pair ``λ, λ̄`` (:func:`~receptance.pole_residue.pole_pairs`,
    in the order of the model's poles) has ``ω = |λ|``, ``ζ = −Re λ/|λ|``;
    model ``p`` uses ``ω (1 + A u)`` and ``ζ (1 + A u')`` with ``u, u'``
    independent draws of ``U(−1, 1)`` from ``numpy.random.default_rng(seed)``
    (shape ``(N, n_pairs, 2)``, last axis frequency then damping), so the
    same seed gives proportional perturbations at every amplitude.  The
    conjugate partner moves with its pole, the residues are scaled to keep a
    real mode's mass-normalised shape (``PoleResidues.with_poles(...,
    keep="mass_normalised")``), the rigid-body mass line and real
    (overdamped) poles are not perturbed.  A model with hysteretic losses
    (complex stiffness: the bearings' loss factor) has no conjugate pole
    pairs; it is perturbed as its equivalent with viscous damping at each
    mode (:func:`~receptance.pole_residue.viscous_equivalent`: every mode
    keeps its own ``ω`` and ``ζ``, the thesis's modal parameters).

Vectorised evaluation (:func:`robustness_study`)
    A pole pair with residue ``R`` (and ``R̄`` on the partner) contributes to
    the receptance between projections ``u`` (outputs) and ``v`` (inputs) the
    real-coefficient second-order term::

        uᵀ[R/(s−λ) + R̄/(s−λ̄)]v = [2 Re(r) (s − σ) − 2 Im(r) ω_d] / (s² − 2σ s + |λ|²),   r = uᵀRv

    With the residue scaled by ``ω_d/ω_d'`` (``ω_d = Im λ``), the
    ``Im(r)`` part becomes ``−2 ω_d Im(r) g`` with ``g = 1/(ω'² − Ω² + 2iζ'ω'Ω)``
    whose weight does not depend on the perturbation.  All the needed
    entries — ``D`` (3 for a symmetric 2×2, its 2 diagonal terms for the
    half model) and ``B`` (``2 m``) — are then one real matrix product
    ``W (entries × pairs) · g (pairs × models·frequencies)`` (complex ``g``
    viewed as interleaved reals), plus the fixed mass-line and real-pole
    terms.  A model with complex residues (non-proportional damping, e.g. a
    suspension added as a modification) adds a second product with
    ``(ω_d/ω_d')(iΩ + ζ'ω') g`` for the pairs that need it.  Per model and
    frequency the least-squares normal forces are found by modified
    Gram–Schmidt on the ``m × 2`` system (stable like a QR; Tikhonov
    regularisation as two extra rows ``α s_max I``), the ``2 × 2`` products
    elementwise, and the mean and standard deviation merged chunk by chunk
    (Chan et al.'s pairwise update, so zero perturbation gives a standard
    deviation of exactly zero up to rounding).

Memory and threads
    Models are processed in chunks of ``chunk_models`` (default: about
    8192 model-frequency points per chunk, 2 models at 4096 lines) by
    ``workers`` threads (default: the CPUs available, at most 2), each with
    its own buffers.  Peak extra memory per worker is about
    ``chunk_models · n_f · (56 n_pairs + 16 n_entries + 800)`` bytes
    (≈ 15 MB for 19 pairs, 16 entries and 2 × 4096 points), independent of
    the number of models; without chunking ``g`` alone would take
    ``16 N n_f n_pairs`` bytes (1.2 GB for 1000 models × 4096 lines × 19
    pairs).  BLAS is limited to one thread during the study (the threads
    already use the cores); set ``RAILMODAL_BLAS_THREADS=keep`` to leave it
    alone.  Everything is complex128.
"""

from __future__ import annotations

import logging
import math
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
from threadpoolctl import threadpool_limits

from receptance.pole_residue import PoleResidues, pole_pairs, viscous_equivalent
from receptance.transfer import (DEFAULT_CHANNELS, MODEL_KINDS, SIDES, TransferModelError, _as_normals,
                                 _check_freqs, _compliances, _layout, _rail, _require, contact_normals,
                                 dof_label)

__all__ = ["RobustnessResult", "perturbation_factors", "perturbed_models", "robustness_study"]

log = logging.getLogger("receptance")

_POINTS_PER_CHUNK = 8192


def _bytes_per_point(k: int, k1: int, e: int) -> int:
    """Documented estimate of a worker's buffer bytes per model-frequency point (module docstring)."""
    return 56 * k + 16 * k1 + 16 * e + 800


# --------------------------------------------------------------------------- perturbation
def perturbation_factors(n_models: int, n_pairs: int, amplitude: float = 0.10, seed=0,
                         ) -> tuple[np.ndarray, np.ndarray]:
    """Random factors on the modal frequencies and damping ratios (thesis §4.2: ±10 %).

    Parameters
    ----------
    n_models, n_pairs : int
        Number of perturbed models and of oscillating pole pairs.
    amplitude : float
        Half-width ``A`` of the uniform perturbation (0.10 = ±10 %), in [0, 1).
    seed : int, numpy.random.Generator or None
        Seed of ``numpy.random.default_rng``.

    Returns
    -------
    freq_factor, zeta_factor : ndarray (n_models, n_pairs)
        ``1 + A u`` with ``u ~ U(−1, 1)`` drawn as one ``(n_models, n_pairs, 2)`` array.
    """
    if int(n_models) != n_models or n_models < 1:
        raise TransferModelError(f"n_models must be a positive integer, got {n_models!r}")
    if not (math.isfinite(amplitude) and 0 <= amplitude < 1):
        raise TransferModelError(f"amplitude must lie in [0, 1) (0.1 = ±10 %), got {amplitude!r}")
    u = np.random.default_rng(seed).uniform(-1.0, 1.0, size=(int(n_models), int(n_pairs), 2))
    return 1 + amplitude * u[..., 0], 1 + amplitude * u[..., 1]


def _pairs(model: PoleResidues):
    lam = model.poles
    try:
        upper, lower = pole_pairs(lam)
    except ValueError as exc:  # callers pass viscous_equivalent(model); anything left is not a structure's pole set
        raise TransferModelError(f"the model's poles are not in conjugate pairs ({exc}); the perturbation study "
                                 f"needs a real (conjugate-symmetric) model") from None
    R = model.residues
    scale = max(np.abs(R).max(initial=0.0), np.finfo(float).tiny)
    if upper.size and np.abs(R[:, :, lower] - R[:, :, upper].conj()).max() > 1e-9 * scale:
        raise TransferModelError("the model's residues are not conjugate-symmetric (complex stiffness?); the "
                                 "perturbation study needs a real (conjugate-symmetric) model")
    real = np.setdiff1d(np.arange(lam.size), np.concatenate([upper, lower]))
    return upper, lower, real


def _perturbed_poles(lam_upper: np.ndarray, fw: np.ndarray, fz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Perturbed ``ω'``, ``ζ'`` (n_models, n_pairs) of the upper poles; raises if a damping ratio reaches 1."""
    w = np.abs(lam_upper)
    z = -lam_upper.real / w
    wp, zp = w * fw, z * fz
    if np.any(zp >= 1):
        k = int(np.argwhere(zp >= 1)[0, 1])
        raise TransferModelError(f"perturbing the pole at {w[k] / (2 * np.pi):.4g} Hz (zeta {z[k]:.3g}) gives a "
                                 "damping ratio >= 1; reduce the amplitude")
    return wp, zp


def perturbed_models(model: PoleResidues, n_models: int, amplitude: float = 0.10, seed=0) -> list[PoleResidues]:
    """The perturbed models of the study, one :class:`PoleResidues` each (for checks and plots).

    Same draws as :func:`robustness_study` with the same arguments; see the
    module docstring for the perturbation.
    """
    model = viscous_equivalent(model)
    upper, lower, _ = _pairs(model)
    fw, fz = perturbation_factors(n_models, upper.size, amplitude, seed)
    wp, zp = _perturbed_poles(model.poles[upper], fw, fz)
    out = []
    for p in range(int(n_models)):
        lam = model.poles.copy()
        new = -zp[p] * wp[p] + 1j * wp[p] * np.sqrt(1 - zp[p] ** 2)
        lam[upper] = new
        lam[lower] = new.conj()
        out.append(model.with_poles(lam, keep="mass_normalised"))
    return out


# --------------------------------------------------------------------------- result
@dataclass(frozen=True, eq=False)
class RobustnessResult:
    """Spread of the reconstructed irregularity over the perturbed models (thesis Figs. 4.5–4.7).

    Attributes
    ----------
    freqs_hz : ndarray (n_f,)
    models : tuple of str
        Transfer-function models studied (``"half"``, ``"vertical"``, ``"vertical_lateral"``).
    sides : tuple of str
        ``("L", "R")``.
    mean, std : ndarray (n_kinds, 2, n_f)
        Mean and (population, ``ddof=0``) standard deviation over the models
        of ``|n̂|`` [m] per model kind, side and frequency.
    irregularity : ndarray complex (2, n_f)
        The test irregularity spectrum (left, right) [m].
    channels : dict
        Measured channels of each model kind (the half model: left, right).
    n_models : int
    amplitude : float
    seed : object
    regularisation : float
    """

    freqs_hz: np.ndarray
    models: tuple[str, ...]
    sides: tuple[str, ...]
    mean: np.ndarray
    std: np.ndarray
    irregularity: np.ndarray
    channels: dict = field(default_factory=dict)
    n_models: int = 0
    amplitude: float = 0.0
    seed: object = None
    regularisation: float = 0.0

    def spread(self, model: str) -> tuple[np.ndarray, np.ndarray]:
        """``(mean, std)`` arrays (2, n_f) of one model kind."""
        if model not in self.models:
            raise KeyError(f"model {model!r} was not studied; available: {list(self.models)}")
        k = self.models.index(model)
        return self.mean[k], self.std[k]

    def __repr__(self) -> str:
        f = self.freqs_hz
        return (f"RobustnessResult({list(self.models)}, {self.n_models} models ±{100 * self.amplitude:g} %, "
                f"{f.size} lines {f[0]:g}–{f[-1]:g} Hz)")


# --------------------------------------------------------------------------- set-up
@dataclass
class _Kind:
    """One model kind: its layouts (two SISO ones for the half model) and entry indices."""

    name: str
    layouts: list
    D: list = field(default_factory=list)  # per layout: (n, n) entry indices
    B: list = field(default_factory=list)  # per layout: (m, n) entry indices
    rail: list = field(default_factory=list)  # per layout: (n, n_f) rail + contact on D's diagonal


def _kinds(models, half_channels, vertical_channels, lateral_channels, normals) -> list[_Kind]:
    kinds = []
    for name in models:
        if name == "half":
            if len(half_channels) != 2:
                raise TransferModelError(f"half_channels must be (left channel, right channel), got {half_channels!r}")
            lay = [_layout("half", (s,), np.array([[0.0, 1.0]]), [c]) for s, c in zip(SIDES, half_channels)]
        elif name == "vertical":
            lay = [_layout("vertical", SIDES, contact_normals(0.0, 0.0), vertical_channels)]
        elif name == "vertical_lateral":
            lay = [_layout("vertical_lateral", SIDES, normals, lateral_channels)]
        else:
            raise TransferModelError(f"unknown model kind {name!r}; expected some of {list(MODEL_KINDS)}")
        kinds.append(_Kind(name, lay))
    if len({k.name for k in kinds}) != len(kinds):
        raise TransferModelError(f"model kinds must be unique, got {list(models)}")
    return kinds


def _entries(kinds: list[_Kind]) -> tuple[list, list, list]:
    """Entry projections ``(u_dict, v_dict)``; fills the kinds' index tables."""
    specs = []
    for kind in kinds:
        for lay in kind.layouts:
            n = len(lay.sides)
            col = [{c: lay.N[a, j] for a, c in enumerate(lay.contact) if lay.N[a, j] != 0} for j in range(n)]
            Di = np.empty((n, n), int)
            for i in range(n):
                for j in range(n):
                    Di[i, j] = len(specs)
                    specs.append((col[i], col[j]))
            Bi = np.empty((len(lay.channels), n), int)
            for c, ch in enumerate(lay.channels):
                for j in range(n):
                    Bi[c, j] = len(specs)
                    specs.append(({ch: 1.0}, col[j]))
            kind.D.append(Di)
            kind.B.append(Bi)
    outputs = list(dict.fromkeys(lab for u, _ in specs for lab in u))
    inputs = list(dict.fromkeys(lab for _, v in specs for lab in v))
    return specs, outputs, inputs


@dataclass
class _Plan:
    """Everything the worker threads share (read-only)."""

    Om: np.ndarray  # (F,)
    Om2: np.ndarray
    w: np.ndarray  # (K,) nominal undamped ω of the pairs
    zeta: np.ndarray  # (K,) nominal damping ratios of the pairs
    wd: np.ndarray  # (K,) nominal Im λ
    W2: np.ndarray  # (E_u, K)
    W1: np.ndarray  # (E_u, K1)
    sel1: np.ndarray  # (K1,) pairs with a real residue part
    fixed: np.ndarray  # (E_u, F) complex
    fw: np.ndarray  # (N, K) factors
    fz: np.ndarray
    kinds: list
    y: list  # per kind, per layout: (m, F) nominal accelerations / (−Ω²)
    alpha: float


def _prepare(model: PoleResidues, f: np.ndarray, kinds: list[_Kind], track, contact_stiffness, fw, fz, alpha,
             ) -> tuple[_Plan, PoleResidues]:
    specs, outputs, inputs = _entries(kinds)
    for kind in kinds:
        for lay in kind.layouts:
            _require(model.outputs, model.inputs, list(dict.fromkeys(lay.contact + lay.channels)),
                     list(lay.contact), "wheelset model (PoleResidues)", lay)
    pr = model.select(outputs, inputs)
    E = len(specs)
    U = np.zeros((E, len(outputs)))
    V = np.zeros((E, len(inputs)))
    opos = {lab: i for i, lab in enumerate(outputs)}
    ipos = {lab: i for i, lab in enumerate(inputs)}
    for e, (u, v) in enumerate(specs):
        for lab, c in u.items():
            U[e, opos[lab]] = c
        for lab, c in v.items():
            V[e, ipos[lab]] = c
    upper, lower, real = _pairs(pr)
    Re = np.einsum("ea,abk,eb->ek", U, pr.residues, V)  # (E, n_poles)
    R0 = np.einsum("ea,ab,eb->e", U, pr.mass_line, V)
    s = 2j * np.pi * f
    fixed = R0[:, None] / s[None, :] ** 2
    if real.size:
        fixed = fixed + Re[:, real] @ (1.0 / (s[None, :] - pr.poles[real, None]))
    lam_u = pr.poles[upper]
    wd = lam_u.imag
    Ru = Re[:, upper]
    W2 = -2 * wd[None, :] * Ru.imag
    big = np.abs(Ru).max(axis=0, initial=0.0)
    sel1 = np.flatnonzero(np.abs(Ru.real).max(axis=0, initial=0.0) > 1e-12 * np.maximum(big, 1e-300))
    W1 = 2 * Ru.real[:, sel1]
    # identical entries (D_12 = D_21 of a reciprocal model, entries shared by the kinds) are computed once
    keep, index = [], np.empty(E, int)
    for e in range(E):
        for k, e2 in enumerate(keep):
            if (_close(W2[e], W2[e2]) and _close(W1[e], W1[e2]) and _close(fixed[e], fixed[e2])):
                index[e] = k
                break
        else:
            index[e] = len(keep)
            keep.append(e)
    for kind in kinds:
        kind.D = [index[d] for d in kind.D]
        kind.B = [index[b] for b in kind.B]
    plan = _Plan(Om=2 * np.pi * f, Om2=(2 * np.pi * f) ** 2, w=np.abs(lam_u), zeta=-lam_u.real / np.abs(lam_u),
                 wd=wd, W2=np.ascontiguousarray(W2[keep]), W1=np.ascontiguousarray(W1[keep]), sel1=sel1,
                 fixed=np.ascontiguousarray(fixed[keep]), fw=fw, fz=fz, kinds=kinds, y=[], alpha=alpha)
    log.debug("robustness: %d pole pairs (%d with complex residues), %d real poles, %d/%d unique entries",
              upper.size, sel1.size, real.size, len(keep), E)
    # rail + contact on D's diagonal, per layout
    comp = _compliances(contact_stiffness, 2)
    lateral = any(lay.lateral_track for kind in kinds for lay in kind.layouts)
    ARY, ARZ = _rail(track, f, lateral)
    for kind in kinds:
        kind.rail = []
        for lay in kind.layouts:
            rows = []
            for j, side in enumerate(lay.sides):
                ny, nz = lay.normals[j]
                rows.append(ny * ny * ARY + nz * nz * ARZ + comp[SIDES.index(side)])
            kind.rail.append(np.array(rows))
    return plan, pr


def _close(a, b) -> bool:
    scale = max(np.abs(a).max(initial=0.0), np.abs(b).max(initial=0.0))
    return bool(np.all(np.abs(a - b) <= 1e-13 * scale))


# --------------------------------------------------------------------------- kernel
class _Worker:
    """Buffers and the per-chunk computation of one thread."""

    def __init__(self, plan: _Plan, chunk: int):
        self.plan = plan
        K, F = plan.w.size, plan.Om.size
        K1 = plan.sel1.size
        self.chunk = chunk
        self.a = np.empty((K, chunk, F))
        self.b = np.empty((K, chunk, F))
        self.d = np.empty((K, chunk, F))
        self.G = np.empty((K, chunk, F), complex)
        self.G1 = np.empty((K1, chunk, F), complex)
        self.out = np.empty((plan.W2.shape[0], 2 * chunk * F))

    def entries(self, p0: int, p1: int) -> np.ndarray:
        """Perturbed receptance entries (E_u, c, F) of models ``p0:p1``."""
        pl = self.plan
        c = p1 - p0
        K, F = pl.w.size, pl.Om.size
        a, b, d, G = self.a[:, :c], self.b[:, :c], self.d[:, :c], self.G[:, :c]
        wp = (pl.w * pl.fw[p0:p1]).T  # (K, c)
        zp = (pl.zeta * pl.fz[p0:p1]).T
        np.subtract((wp * wp)[:, :, None], pl.Om2, out=a)
        np.multiply((2 * zp * wp)[:, :, None], pl.Om, out=b)
        np.multiply(a, a, out=d)
        Gv = G.view(float).reshape(K, c, F, 2)
        np.multiply(b, b, out=Gv[..., 0])
        d += Gv[..., 0]
        np.divide(1.0, d, out=d)
        np.multiply(a, d, out=Gv[..., 0])
        np.multiply(b, d, out=Gv[..., 1])
        np.negative(Gv[..., 1], out=Gv[..., 1])
        out = self.out[:, :2 * c * F]
        if c == self.chunk:
            np.matmul(pl.W2, G.view(float).reshape(K, 2 * c * F), out=out)
        else:
            out[...] = pl.W2 @ np.ascontiguousarray(G).view(float).reshape(K, 2 * c * F)
        Ent = out.view(complex).reshape(-1, c, F)
        if pl.sel1.size:
            sel = pl.sel1
            scale = pl.wd[sel, None] / (wp[sel] * np.sqrt(1 - zp[sel] ** 2))  # (K1, c)
            G1 = self.G1[:, :c]
            np.multiply(1j * pl.Om[None, None, :] + (zp[sel] * wp[sel])[:, :, None], G[sel], out=G1)
            G1 *= scale[:, :, None]
            Ent = Ent + (pl.W1 @ np.ascontiguousarray(G1).view(float).reshape(sel.size, 2 * c * F)
                         ).view(complex).reshape(-1, c, F)
        Ent += pl.fixed[:, None, :]
        return Ent

    def run(self, p0: int, p1: int) -> list:
        """Per kind: (count, mean (2, F), M2 (2, F)) of |n̂| over models p0:p1 (chunked)."""
        pl = self.plan
        F = pl.Om.size
        acc = [None] * len(pl.kinds)
        for c0 in range(p0, p1, self.chunk):
            c1 = min(p1, c0 + self.chunk)
            Ent = self.entries(c0, c1)
            for k, kind in enumerate(pl.kinds):
                mags = np.empty((2, c1 - c0, F))
                if kind.name == "half":
                    for j, (Di, Bi, rail, y) in enumerate(zip(kind.D, kind.B, kind.rail, pl.y[k])):
                        Dp = Ent[Di[0, 0]] + rail[0]
                        np.abs(Dp * y[0] / Ent[Bi[0, 0]], out=mags[j])
                else:
                    Di, Bi, rail, y = kind.D[0], kind.B[0], kind.rail[0], pl.y[k][0]
                    x1, x2 = _lstsq2([Ent[i] for i in Bi[:, 0]], [Ent[i] for i in Bi[:, 1]], list(y), pl.alpha)
                    np.abs((Ent[Di[0, 0]] + rail[0]) * x1 + Ent[Di[0, 1]] * x2, out=mags[0])
                    np.abs(Ent[Di[1, 0]] * x1 + (Ent[Di[1, 1]] + rail[1]) * x2, out=mags[1])
                n_b = c1 - c0
                mean_b = mags.mean(axis=1)
                dev = mags - mean_b[:, None, :]
                m2_b = np.einsum("spf,spf->sf", dev, dev)
                acc[k] = _merge(acc[k], (n_b, mean_b, m2_b))
        return acc


def _lstsq2(col1: list, col2: list, y: list, alpha: float):
    """Least-squares ``[col1 col2] x ≈ y`` elementwise by modified Gram–Schmidt (optionally Tikhonov).

    ``col1``, ``col2``: m arrays (c, F); ``y``: m arrays broadcastable to them.
    Tikhonov (``alpha > 0``): two extra rows ``α s_max I`` with ``s_max`` the
    largest singular value of the ``m × 2`` matrix (closed form from its Gram matrix).
    """
    col1, col2, y = list(col1), list(col2), list(y)
    if alpha > 0:
        g11 = sum(_abs2(v) for v in col1)
        g22 = sum(_abs2(v) for v in col2)
        g12 = sum(np.conj(u) * v for u, v in zip(col1, col2))
        smax2 = 0.5 * (g11 + g22) + np.sqrt(0.25 * (g11 - g22) ** 2 + _abs2(g12))
        mu = alpha * np.sqrt(smax2)
        zero = np.zeros_like(mu)
        col1 += [mu, zero]
        col2 += [zero, mu]
        y += [0.0, 0.0]
    n1 = np.sqrt(sum(_abs2(v) for v in col1))
    q1 = [v / n1 for v in col1]
    r12 = sum(np.conj(q) * v for q, v in zip(q1, col2))
    v2 = [v - q * r12 for q, v in zip(q1, col2)]
    n2 = np.sqrt(sum(_abs2(v) for v in v2))
    q2 = [v / n2 for v in v2]
    c1 = sum(np.conj(q) * v for q, v in zip(q1, y))
    y2 = [v - q * c1 for q, v in zip(q1, y)]
    c2 = sum(np.conj(q) * v for q, v in zip(q2, y2))
    x2 = c2 / n2
    x1 = (c1 - r12 * x2) / n1
    return x1, x2


def _abs2(z):
    return z.real * z.real + z.imag * z.imag


def _merge(a, b):
    """Chan et al. pairwise update of (count, mean, M2)."""
    if a is None:
        return b
    na, ma, Ma = a
    nb, mb, Mb = b
    n = na + nb
    delta = mb - ma
    return n, ma + delta * (nb / n), Ma + Mb + delta * delta * (na * nb / n)


# --------------------------------------------------------------------------- public entry
def robustness_study(model, freqs_hz, *, n_models: int = 50, amplitude: float = 0.10, seed=0,
                     models: Sequence[str] = MODEL_KINDS, theta_l: float = 0.0, theta_r: float = 0.0, normals=None,
                     half_channels: Sequence = ("axlebox_L:z", "axlebox_R:z"),
                     vertical_channels: Sequence = DEFAULT_CHANNELS["vertical"],
                     lateral_channels: Sequence = DEFAULT_CHANNELS["vertical_lateral"],
                     track=None, contact_stiffness=None, irregularity=None, regularisation: float = 0.0,
                     chunk_models: int | None = None, workers: int | None = None) -> RobustnessResult:
    """Spectral spread of the reconstructed irregularity over perturbed wheelset models (thesis §4.2).

    Parameters
    ----------
    model : PoleResidues or ModalModel
        Nominal wheelset model with the contact DOFs (``contact_L:y``,
        ``contact_L:z``, ``contact_R:y``, ``contact_R:z``) as outputs and
        inputs and the channels as outputs.
    freqs_hz : array_like (n_f,)
        Frequencies [Hz], > 0.
    n_models : int
        Number of perturbed models (the thesis uses 50).
    amplitude : float
        Half-width of the uniform perturbation of every modal frequency and
        damping ratio (0.10 = ±10 %, thesis).
    seed : int, Generator or None
        Random seed (:func:`perturbation_factors`).
    models : sequence of {"half", "vertical", "vertical_lateral"}
        Transfer-function models to study (default all three).
    theta_l, theta_r, normals
        Contact geometry of the vertical + lateral model (see
        :func:`~receptance.transfer.vertical_lateral_transfer`).
    half_channels : (str, str)
        Channel of the left and right half-wheelset models.
    vertical_channels, lateral_channels : sequence of str
        Channels of the full vertical and vertical + lateral models.
    track, contact_stiffness
        Rail receptance and ``K_H`` as in :mod:`receptance.transfer` (not perturbed).
    irregularity : array_like complex (2, n_f), optional
        Test irregularity spectrum (left, right) [m].  Default: the thesis
        profile, a flat unit spectrum (ideal white noise) on the left and
        zero on the right.  A sampled white noise only multiplies each line
        by its random magnitude (the study is linear per frequency).
    regularisation : float
        Relative Tikhonov parameter of the two-sided models (as in
        :mod:`receptance.transfer`; the SISO half model is not regularised).
    chunk_models, workers : int, optional
        Models per chunk and worker threads (module docstring).

    Returns
    -------
    RobustnessResult
        Mean and standard deviation of ``|n̂|`` per model kind, side and frequency.
    """
    if not isinstance(model, PoleResidues):
        if hasattr(model, "pole_residues"):
            contact = ["contact_L:y", "contact_L:z", "contact_R:y", "contact_R:z"]
            wanted = [dof_label(c) for c in (*half_channels, *vertical_channels, *lateral_channels)]
            model = model.pole_residues(list(dict.fromkeys(contact + wanted)), contact)
        else:
            raise TypeError(f"the robustness study needs a PoleResidues (or ModalModel) wheelset model, got "
                            f"{type(model).__name__}")
    # hysteretic losses (complex stiffness) as viscous damping at each mode: the study perturbs modes' ω and ζ
    model = viscous_equivalent(model)
    f = _check_freqs(freqs_hz, "freqs_hz")
    alpha = float(regularisation)
    if not math.isfinite(alpha) or alpha < 0:
        raise TransferModelError(f"regularisation must be a finite number >= 0, got {regularisation!r}")
    if normals is not None:
        if theta_l != 0.0 or theta_r != 0.0:
            raise TransferModelError("give either theta_l/theta_r or normals, not both")
        nrm = _as_normals(normals, 2)
    else:
        nrm = contact_normals(theta_l, theta_r)
    kinds = _kinds(tuple(models), tuple(half_channels), tuple(vertical_channels), tuple(lateral_channels), nrm)
    if irregularity is None:
        irr = np.zeros((2, f.size), complex)
        irr[0] = 1.0
    else:
        irr = np.asarray(irregularity, dtype=complex)
        if irr.shape != (2, f.size):
            raise TransferModelError(f"irregularity must have shape (2, {f.size}) (left, right spectra on "
                                     f"freqs_hz), got {irr.shape}")
    n_pairs = pole_pairs(model.poles)[0].size
    fw, fz = perturbation_factors(n_models, n_pairs, amplitude, seed)
    plan, pr = _prepare(model, f, kinds, track, contact_stiffness, fw, fz, alpha)
    _perturbed_poles(pr.poles[pole_pairs(pr.poles)[0]], fw, fz)  # validates damping < 1
    # nominal accelerations (divided by −Ω²): y = M₀ D₀⁻¹ n, from the same kernel with zero perturbation
    nominal = _Plan(**{**plan.__dict__, "fw": np.ones((1, n_pairs)), "fz": np.ones((1, n_pairs))})
    E0 = _Worker(nominal, 1).entries(0, 1)[:, 0, :]  # (E_u, F)
    for kind in kinds:
        ys = []
        for lay, Di, Bi, rail in zip(kind.layouts, kind.D, kind.B, kind.rail):
            n_s = len(lay.sides)
            D0 = E0[Di] + np.einsum("ij,jf->ijf", np.eye(n_s), rail)  # (n, n, F)
            nn = irr[[SIDES.index(s) for s in lay.sides]]  # (n, F)
            Fn = np.linalg.solve(np.moveaxis(D0, 2, 0), nn.T[:, :, None])[:, :, 0].T  # (n, F)
            ys.append(np.einsum("mjf,jf->mf", E0[Bi], Fn))
        plan.y.append(ys)
    n_models = int(n_models)
    F = f.size
    chunk = int(chunk_models) if chunk_models else max(1, _POINTS_PER_CHUNK // F)
    if chunk < 1:
        raise TransferModelError(f"chunk_models must be >= 1, got {chunk_models!r}")
    chunk = min(chunk, n_models)
    if workers is None:
        try:
            workers = min(2, len(os.sched_getaffinity(0)))
        except AttributeError:  # pragma: no cover - not Linux
            workers = min(2, os.cpu_count() or 1)
    workers = max(1, min(int(workers), n_models))
    bounds = np.linspace(0, n_models, workers + 1).round().astype(int)
    log.info("robustness study: %d models x %d lines, kinds %s, %d worker(s), %d models per chunk (~%.0f MB each)",
             n_models, F, [k.name for k in kinds], workers, chunk,
             chunk * F * _bytes_per_point(plan.w.size, plan.sel1.size, plan.W2.shape[0]) / 1e6)

    def task(i):
        return _Worker(plan, chunk).run(bounds[i], bounds[i + 1])

    keep = os.environ.get("RAILMODAL_BLAS_THREADS", "").lower() == "keep"
    with threadpool_limits(limits=None if keep else 1, user_api="blas"):
        if workers == 1:
            parts = [task(0)]
        else:
            with ThreadPoolExecutor(workers) as ex:
                parts = list(ex.map(task, range(workers)))
    mean = np.empty((len(kinds), 2, F))
    std = np.empty((len(kinds), 2, F))
    for k in range(len(kinds)):
        acc = None
        for part in parts:
            acc = _merge(acc, part[k])
        n, m, M2 = acc
        mean[k], std[k] = m, np.sqrt(np.maximum(M2, 0.0) / n)
    channels = {}
    for kind in kinds:
        channels[kind.name] = tuple(lay.channels[0] for lay in kind.layouts) if kind.name == "half" \
            else kind.layouts[0].channels
    return RobustnessResult(freqs_hz=f, models=tuple(k.name for k in kinds), sides=SIDES, mean=mean, std=std,
                            irregularity=irr, channels=channels, n_models=n_models, amplitude=float(amplitude),
                            seed=seed, regularisation=alpha)
