"""Receptances in pole–residue form: the one representation every model reduces to.

A linear structure with viscous (or constant complex) damping has the
receptance (thesis eqs. 2.28–2.30 solved once, in modal form)::

    H(s) = R0 / s²  +  Σ_k R_k / (s − λ_k),        s = iΩ

``λ_k`` are the poles (complex-conjugate pairs for oscillating modes, real
for overdamped ones), ``R_k`` the residue matrices and ``R0`` the mass line of
the rigid-body motions that nothing restrains (free-free wheelset, or its
spin about the axle in service).  For a mass-normalised real mode ``φ`` with
frequency ``ω`` and damping ``ζ`` the pair is ``λ = −ζω ± iω√(1−ζ²)`` with
``R = ± φφᵀ / (2iω√(1−ζ²))`` so that the two terms add up to the classical
``φφᵀ / (ω² − Ω² + 2iζωΩ)``.

Evaluating at ``s = iΩ + a`` instead of ``iΩ`` gives the response seen
through an exponential window of decay ``a`` (every pole shifted by ``−a``),
which is what a windowed H1 estimate measures.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Sequence

import numpy as np

from ema.frf import QUANTITIES, FrequencyResponse
from ema.lsce import pole_frequency_hz

__all__ = ["PoleResidues", "pole_pairs", "viscous_equivalent"]


@dataclass(frozen=True, eq=False)
class PoleResidues:
    """Receptance ``H(s) = R0/s² + Σ_k R_k/(s − λ_k)`` between labelled DOFs.

    Parameters
    ----------
    poles : ndarray complex (k,)
        ``λ_k`` [rad/s].
    residues : ndarray complex (n_out, n_in, k)
        ``R_k`` [m/N · rad/s].
    mass_line : ndarray complex (n_out, n_in)
        ``R0`` [m/N · (rad/s)²] of unrestrained rigid-body motion (zeros if none).
    outputs, inputs : tuple of str
        DOF labels (``"contact_L:z"``, channel names...).
    history : tuple of str
    """

    poles: np.ndarray
    residues: np.ndarray
    mass_line: np.ndarray
    outputs: tuple[str, ...]
    inputs: tuple[str, ...]
    history: tuple[str, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        lam = np.atleast_1d(np.asarray(self.poles, complex))
        R = np.asarray(self.residues, complex)
        n_out, n_in = len(self.outputs), len(self.inputs)
        if lam.ndim != 1:
            raise ValueError(f"poles must be 1-D, got shape {lam.shape}")
        if R.shape != (n_out, n_in, lam.size):
            raise ValueError(f"residues must have shape (n_out={n_out}, n_in={n_in}, n_poles={lam.size}), "
                             f"got {R.shape}")
        R0 = np.asarray(self.mass_line, complex)
        if R0.shape != (n_out, n_in):
            raise ValueError(f"mass_line must have shape ({n_out}, {n_in}), got {R0.shape}")
        object.__setattr__(self, "poles", lam)
        object.__setattr__(self, "residues", R)
        object.__setattr__(self, "mass_line", R0)
        object.__setattr__(self, "outputs", tuple(str(o) for o in self.outputs))
        object.__setattr__(self, "inputs", tuple(str(i) for i in self.inputs))

    # ------------------------------------------------------------ construction
    @classmethod
    def from_modes(cls, freqs_hz, zeta, shapes_out, shapes_in, outputs: Sequence[str], inputs: Sequence[str],
                   ) -> "PoleResidues":
        """Poles and residues of the modal sum ``Σ_r φ_o,r φ_i,r / (ω_r² − Ω² + 2iζ_rω_rΩ)`` (eq. 2.28 diagonal).

        Parameters
        ----------
        freqs_hz, zeta : array_like (m,)
            Undamped natural frequencies [Hz] (0 for rigid-body modes) and
            viscous damping ratios (< 1).
        shapes_out : array_like (n_out, m)
        shapes_in : array_like (n_in, m)
            Mass-normalised modal displacements at the output and input DOFs.
        outputs, inputs : sequence of str
        """
        f = np.atleast_1d(np.asarray(freqs_hz, float))
        z = np.broadcast_to(np.asarray(zeta, float), f.shape)
        Po = np.asarray(shapes_out, complex).reshape(len(outputs), f.size)
        Pi = np.asarray(shapes_in, complex).reshape(len(inputs), f.size)
        if np.any(f < 0) or np.any(~np.isfinite(f)):
            raise ValueError(f"modal frequencies must be finite and >= 0 Hz, got {f.tolist()}")
        if np.any((z < 0) | (z >= 1)) or np.any(~np.isfinite(z)):
            raise ValueError(f"damping ratios must lie in [0, 1), got {z.tolist()}")
        rigid = f == 0
        outer = Po[:, None, :] * Pi[None, :, :]  # (n_out, n_in, m)
        w = 2 * np.pi * f[~rigid]
        wd = w * np.sqrt(1 - z[~rigid] ** 2)
        lam = -z[~rigid] * w + 1j * wd
        r = outer[:, :, ~rigid] / (2j * wd)
        poles = np.concatenate([lam, lam.conj()])
        residues = np.concatenate([r, -r], axis=2)
        return cls(poles, residues, outer[:, :, rigid].sum(axis=2), tuple(outputs), tuple(inputs),
                   history=(f"modal sum of {f.size} modes ({int(rigid.sum())} rigid)",))

    # ------------------------------------------------------------- evaluation
    def evaluate(self, freqs_hz, quantity: str = "receptance", *, decay: float = 0.0,
                 channels=None) -> FrequencyResponse:
        """The response at ``s = iΩ + decay`` over ``freqs_hz``, vectorised over frequency.

        Parameters
        ----------
        freqs_hz : array_like
            Non-negative, strictly increasing [Hz]; 0 Hz is rejected when
            there is a mass line (the rigid-body response is infinite there).
        quantity : {"receptance", "mobility", "accelerance"}
            Multiplies by ``s`` or ``s²``.
        decay : float, optional
            Exponential-window decay ``a`` [1/s] of a measurement to compare
            with (0: the plain frequency response).
        channels : pandas.DataFrame, optional
            Output metadata attached to the result.

        Returns
        -------
        FrequencyResponse
        """
        if quantity not in ("receptance", "mobility", "accelerance"):
            raise ValueError(f"quantity must be 'receptance', 'mobility' or 'accelerance', got {quantity!r}")
        f = np.atleast_1d(np.asarray(freqs_hz, float))
        s = 2j * np.pi * f + float(decay)
        if np.any(s == 0) and np.any(self.mass_line != 0):
            raise ValueError("the model has unrestrained rigid-body motion, so its receptance is infinite at 0 Hz; "
                             "start the frequency axis above 0 Hz")
        g = 1.0 / (s[None, :] - self.poles[:, None])  # (k, n_f)
        H = np.tensordot(self.residues, g, axes=([2], [0]))
        if np.any(self.mass_line != 0):
            H = H + self.mass_line[:, :, None] / s[None, None, :] ** 2
        H = H * s ** QUANTITIES[quantity][0]
        return FrequencyResponse(freqs_hz=f, data=H, outputs=self.outputs, inputs=self.inputs, quantity=quantity,
                                 channels=channels, exp_window_decay=float(decay),
                                 history=self.history + ("evaluated from poles and residues",))

    def select(self, outputs: Sequence[str] | None = None, inputs: Sequence[str] | None = None) -> "PoleResidues":
        """Sub-model by output and input labels (``KeyError`` names unknown labels)."""
        oi = FrequencyResponse._indices(self.outputs, outputs, "output")
        ii = FrequencyResponse._indices(self.inputs, inputs, "input")
        return replace(self, residues=self.residues[np.ix_(oi, ii)], mass_line=self.mass_line[np.ix_(oi, ii)],
                       outputs=tuple(self.outputs[i] for i in oi), inputs=tuple(self.inputs[i] for i in ii))

    # ---------------------------------------------------------------- modes
    @property
    def natural_frequencies_hz(self) -> np.ndarray:
        """``|λ| / 2π`` for each pole [Hz]."""
        return pole_frequency_hz(self.poles)

    @property
    def damping_ratios(self) -> np.ndarray:
        """``−Re λ / |λ|`` for each pole."""
        a = np.abs(self.poles)
        return np.where(a > 0, -self.poles.real / np.where(a > 0, a, 1), 0.0)

    def with_poles(self, poles, *, keep: str = "mass_normalised") -> "PoleResidues":
        """The same model with moved poles (e.g. perturbed modal frequencies and damping, thesis §4.2).

        Parameters
        ----------
        poles : array_like complex (k,)
            New poles, in the order of :attr:`poles`.  Conjugate partners
            should stay conjugate.
        keep : {"mass_normalised", "residues"}
            ``"mass_normalised"`` (default) scales each residue by
            ``Im λ_old / Im λ_new`` so that a real mode keeps its
            mass-normalised shape: the result equals the modal sum with the
            new frequency and damping (thesis §4.2).  ``"residues"`` keeps the
            residues unchanged.  Real (overdamped) poles keep their residues.
        """
        new = np.asarray(poles, complex)
        if new.shape != self.poles.shape:
            raise ValueError(f"expected {self.poles.size} poles, got {new.shape}")
        if keep not in ("mass_normalised", "residues"):
            raise ValueError(f"keep must be 'mass_normalised' or 'residues', got {keep!r}")
        R = self.residues
        if keep == "mass_normalised":
            old_im, new_im = self.poles.imag, new.imag
            osc = (np.abs(old_im) > 0) & (np.abs(new_im) > 0)
            scale = np.ones(new.size)
            scale[osc] = old_im[osc] / new_im[osc]
            R = R * scale
        return replace(self, poles=new, residues=R, history=self.history + ("poles moved",))


def pole_pairs(poles: np.ndarray, rtol: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    """Indices ``(upper, lower)`` pairing each pole with ``Im λ > 0`` to its conjugate.

    Real poles are not in either array.  Raises ``ValueError`` if a pole has no
    conjugate partner (a model with complex stiffness may not be
    conjugate-symmetric; perturb such models pole by pole).
    """
    lam = np.asarray(poles, complex)
    upper = np.flatnonzero(lam.imag > 0)
    lower = np.empty_like(upper)
    free = set(np.flatnonzero(lam.imag < 0).tolist())
    for n, k in enumerate(upper):
        cands = [j for j in sorted(free) if abs(lam[j] - lam[k].conj()) <= rtol * max(abs(lam[k]), 1.0)]
        if not cands:
            raise ValueError(f"pole {lam[k]:.6g} has no complex-conjugate partner")
        # ties (a repeated pole) go to the first free partner: a model listing its partners in the order of
        # their poles is paired as listed
        j = min(cands, key=lambda j: (abs(lam[j] - lam[k].conj()), j))
        lower[n] = j
        free.remove(j)
    return upper, lower


def viscous_equivalent(model: PoleResidues) -> PoleResidues:
    """The causal, conjugate-symmetric model with each mode's own pole: hysteretic loss as viscous at the mode.

    A structural (hysteretic) loss factor ``η`` makes a spring's stiffness
    complex at every frequency, ``k (1 + iη)`` (thesis §2.4 uses it for the
    track; :class:`~receptance.effect_modifications.BearingBodies` for the
    bearings).  At ``Ω > 0`` that is the physics, but as a pole set it is not
    conjugate-symmetric: near ``s = +iω`` the loss acts as a damper
    ``c = ηk/ω``, near ``s = −iω`` as a negative one, so each mode's lower pole
    lies off the conjugate of its upper pole (in the right half-plane for a
    lightly viscous mode) and its impulse response is not real nor causal
    (Crandall 1970, "The role of damping in vibration theory", J. Sound Vib.
    11, 3–18).  Uses that need real modes — time-domain responses, the
    perturbation of modal frequency and damping of the thesis §4.2 — take the
    equivalent viscous damping at the mode instead (equal energy dissipated
    per cycle at the resonance, ``c_eq = ηk/ω_r``, modal ``ζ ≈ η/2``; Ewins,
    *Modal Testing*, 2nd ed. 2000, §2.2): each mode keeps its upper pole
    ``λ`` (``Im λ > 0``, the one that resonates at ``Ω = ω_r``, so ``ω_r`` and
    ``ζ_r`` are unchanged) and residue ``R``, and its partner becomes
    ``λ̄, R̄``.  The receptance at ``Ω > 0`` changes only by the partner's
    off-resonant term (relative change of order ``η`` in a term that is
    ``ζ/2`` of the resonant one at resonance); frequency-domain uses
    (:mod:`receptance.transfer`) keep the exact model.

    Pairing: every lower pole is assigned to the upper pole whose conjugate is
    nearest (one assignment over all, so a cluster of close modes is paired as
    a whole); a pole nearer its own conjugate than to any partner is a real
    (overdamped) pole the loss moved off the axis, and keeps its real part and
    the real part of its residue.  A conjugate-symmetric model is returned
    unchanged.

    Parameters
    ----------
    model : PoleResidues

    Returns
    -------
    PoleResidues
        Conjugate-symmetric (``pole_pairs`` pairs every oscillating pole).
    """
    lam = model.poles
    R = model.residues
    try:
        upper, lower = pole_pairs(lam)
        scale = max(np.abs(R).max(initial=0.0), np.finfo(float).tiny)
        if not upper.size or np.abs(R[:, :, lower] - R[:, :, upper].conj()).max() <= 1e-9 * scale:
            return model
    except ValueError:
        pass
    from scipy.optimize import linear_sum_assignment

    up = np.flatnonzero(lam.imag > 0)
    lo = np.flatnonzero(lam.imag < 0)
    nu, nl = up.size, lo.size
    # assignment with a "stay real" option for each pole: cost |λ_l − conj λ_u| for a pair, |λ − conj λ| = 2|Im λ|
    # for a pole alone (dummy rows/columns); impossible entries get a cost larger than any sum of real ones
    big = 4 * (np.abs(lam).sum() + 1.0)
    cost = np.full((nu + nl, nl + nu), big)
    cost[:nu, :nl] = np.abs(lam[lo][None, :] - lam[up][:, None].conj())
    cost[np.arange(nu), nl + np.arange(nu)] = 2 * np.abs(lam[up].imag)
    cost[nu + np.arange(nl), np.arange(nl)] = 2 * np.abs(lam[lo].imag)
    cost[nu:, nl:] = 0.0
    rows, cols = linear_sum_assignment(cost)
    modes = np.sort([int(up[r]) for r, c in zip(rows, cols) if r < nu and c < nl]).astype(int)
    alone = np.sort([int(up[r]) for r, c in zip(rows, cols) if r < nu and c >= nl]
                    + [int(lo[c]) for r, c in zip(rows, cols) if r >= nu and c < nl]
                    + np.flatnonzero(lam.imag == 0).tolist()).astype(int)
    # the upper poles, then their partners in the same order (so that pole_pairs pairs a repeated pole with its
    # own partner), then the real ones
    poles = np.concatenate([lam[modes], lam[modes].conj(), lam[alone].real])
    res = np.concatenate([R[:, :, modes], R[:, :, modes].conj(), R[:, :, alone].real], axis=2)
    return replace(model, poles=poles, residues=res, mass_line=model.mass_line.real.astype(complex),
                   history=model.history + ("hysteretic loss as equivalent viscous damping at each mode "
                                            "(conjugate-symmetric poles)",))
