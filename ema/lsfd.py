r"""Least-squares frequency-domain (LSFD) residues, pole refinement and mode indicators.

The modal model
---------------------------------------------------------------------------
A single-input FRF of quantity power ``q`` (0 receptance, 1 mobility,
2 accelerance: ``H_q = s^q H_x``) is modelled over a band as ``s^q`` times a
receptance model,

.. math::

    H_j(s) = s^q \Big[\sum_{r=1}^{m} \Big(\frac{Q_{jr}}{s-\lambda_r} + \frac{Q_{jr}^*}{s-\lambda_r^*}\Big)
             + \sum_{k \in K} E_{jk}\, s^{k}\Big],

with complex receptance residues ``Q_jr``, physical poles
``lambda_r = -zeta_r w_r + i w_r sqrt(1-zeta_r^2)`` and real residual
coefficients ``E_jk``.  The residual powers ``K`` are in receptance form: the
default ``K = (-2, 0)`` is the lower residual (mass line
``E/s^2 = -E/w^2``, ``E = 1/M`` at a driving point: the rigid-body modes and
the modes below the band) and the upper residual (constant compliance
``E = 1/K``: the modes above the band).  For accelerance the same terms read
``E_-2 + E_0 s^2`` — a constant mass line and a ``-w^2`` stiffness line — so
coefficients, residues and modal constants do not depend on the quantity the
FRF is given in (``lower`` [1/kg], ``upper`` [m/N]).  Keeping the factor
``s^q`` on the modal terms (rather than a free pole-residue form of ``H_q``)
makes the accelerance of a mode, ``c b s^2 / (s^2 + 2 zeta w s + w^2)``, exact
without spurious direct terms.

The *modal constant* ``A_jr = (lambda_r - lambda_r^*) Q_jr`` is the
numerator of ``H_x = sum_r A_jr / (s^2 + 2 zeta_r w_r s + w_r^2)`` for real
modes: for a proportionally damped structure ``A_jr = c_jr b_r``, the product
of the mass-normalised shape at the response and at the force point (the
lab truth's ``shapes`` times ``input_shape``).

Out-of-band *pseudo-modes* (``residual_poles``) can be added: poles outside
the band whose terms absorb modes just beyond the band edges, which the
constant-type residuals cannot follow; they are fitted like modes but
reported apart.

Exponential window
---------------------------------------------------------------------------
An FRF measured with the window ``exp(-a t)`` on force and response equals
the unwindowed one at ``s = i w + a`` (every pole shifted by ``-a``: the
identified windowed pole ``s_w`` is the physical pole ``s_w + a``).  All fits
here evaluate the model at ``s = i w + a`` with the *physical* poles and
residual terms, which is exact for windowed data; :func:`synthesize` with
``decay=0`` then gives the unwindowed FRF.

Pole refinement
---------------------------------------------------------------------------
:func:`refine_poles` minimises the global SIMO least-squares error
``sum_j sum_k |H_jk - model_jk|^2`` over the poles shared by all channels.
The residues and residual terms enter linearly, so they are eliminated
(variable projection, Golub & Pereyra 1973): the cost is
``||(I - Phi Phi^+) Y||^2`` with ``Phi(lambda)`` the real-stacked basis and
``Y`` all channels.  Its Jacobian is Kaufman's approximation
``-(I - Phi Phi^+) dPhi/dtheta Phi^+ Y``, cheap because each pole touches two
columns.  A Levenberg–Marquardt iteration on the normal equations converges
in a few iterations from LSCE poles.  This removes the bias LSCE has with
noisy data (noise enters its regression matrix) and resolves close modes that
share the band.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from ._blas import one_blas_thread
from .frf import QUANTITIES, FrequencyResponse
from .lsce import IdentificationError, band_lines, pole_damping, pole_frequency_hz

__all__ = [
    "LSFDResult",
    "RefinedPoles",
    "lsfd",
    "refine_poles",
    "synthesize",
    "mpc",
    "mpd",
    "mcf",
    "mac",
    "DEFAULT_RESIDUALS",
]

log = logging.getLogger("ema")

#: Residual powers of s in receptance form: lower (mass line) s^-2, upper (stiffness) s^0.
DEFAULT_RESIDUALS: tuple[int, ...] = (-2, 0)


# ---------------------------------------------------------------------------- bases
def _s_axis(freqs_hz: np.ndarray, decay: float) -> np.ndarray:
    return 2j * np.pi * np.asarray(freqs_hz, float) + float(decay)


def _modal_columns(s: np.ndarray, poles: np.ndarray, power: int) -> tuple[np.ndarray, np.ndarray]:
    """``s^q (1/(s-l) + 1/(s-l*))`` and ``s^q (i/(s-l) - i/(s-l*))`` for every pole: two (n_f, m) arrays."""
    sq = (s**power)[:, None]
    g1 = sq / (s[:, None] - poles[None, :])
    g2 = sq / (s[:, None] - np.conj(poles)[None, :])
    return g1 + g2, 1j * (g1 - g2)


def _residual_columns(s: np.ndarray, power: int, residuals: tuple[int, ...]) -> np.ndarray:
    if not residuals:
        return np.zeros((s.size, 0), complex)
    return np.stack([s ** (power + k) for k in residuals], axis=1)


def _basis(s: np.ndarray, poles: np.ndarray, power: int, residuals: tuple[int, ...]) -> np.ndarray:
    """Complex basis (n_f, 2m + n_res): Re P columns, Im P columns, residual columns."""
    b1, b2 = _modal_columns(s, poles, power)
    return np.concatenate([b1, b2, _residual_columns(s, power, residuals)], axis=1)


def _stack(z: np.ndarray) -> np.ndarray:
    """Complex (n, ...) -> real (2n, ...) as [Re; Im]."""
    return np.concatenate([z.real, z.imag], axis=0)


def _check_residuals(residuals) -> tuple[int, ...]:
    res = tuple(int(k) for k in residuals)
    if len(set(res)) != len(res):
        raise IdentificationError(f"residual powers must be distinct, got {residuals!r}")
    return res


def _check_poles(poles, band: tuple[float, float] | None = None) -> np.ndarray:
    p = np.atleast_1d(np.asarray(poles, complex))
    if p.ndim != 1:
        raise IdentificationError(f"poles must be a 1-D array, got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise IdentificationError(f"poles must be finite, got {p[~np.isfinite(p)][:3]}")
    if np.any(p.imag <= 0):
        raise IdentificationError(
            f"poles must have a positive imaginary part (one of each conjugate pair), got {p[p.imag <= 0][:3]}"
        )
    return p


# ---------------------------------------------------------------------------- indicators
def mac(phi_a: np.ndarray, phi_b: np.ndarray) -> np.ndarray:
    """Modal assurance criterion ``|a^H b|^2 / ((a^H a)(b^H b))`` between the columns of two shape matrices.

    Parameters
    ----------
    phi_a : ndarray (n, ma) or (n,)
    phi_b : ndarray (n, mb) or (n,)

    Returns
    -------
    ndarray (ma, mb)
    """
    a = np.asarray(phi_a)
    b = np.asarray(phi_b)
    a = a[:, None] if a.ndim == 1 else a
    b = b[:, None] if b.ndim == 1 else b
    if a.shape[0] != b.shape[0]:
        raise ValueError(f"shapes must have the same number of rows (DOFs), got {a.shape[0]} and {b.shape[0]}")
    num = np.abs(a.conj().T @ b) ** 2
    den = np.outer(np.sum(np.abs(a) ** 2, axis=0), np.sum(np.abs(b) ** 2, axis=0))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, num / den, 0.0)


def _scatter(phi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    phi = np.asarray(phi, complex)
    phi = phi[:, None] if phi.ndim == 1 else phi
    sxx = np.sum(phi.real**2, axis=0)
    syy = np.sum(phi.imag**2, axis=0)
    sxy = np.sum(phi.real * phi.imag, axis=0)
    return sxx, syy, sxy


def mpc(phi: np.ndarray) -> np.ndarray:
    """Modal phase collinearity (Pappa et al. 1993) of each column, 0 (circle) .. 1 (real mode).

    ``MPC = ((Sxx - Syy)^2 + 4 Sxy^2) / (Sxx + Syy)^2``, i.e.
    ``((l1 - l2) / (l1 + l2))^2`` with ``l1, l2`` the eigenvalues of the
    2x2 scatter matrix of (Re, Im) of the components; invariant to the
    shape's complex scaling.
    """
    sxx, syy, sxy = _scatter(phi)
    den = (sxx + syy) ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, ((sxx - syy) ** 2 + 4 * sxy**2) / den, 0.0)


def mcf(phi: np.ndarray) -> np.ndarray:
    """Modal complexity factor ``1 - MPC`` (0 for a real mode)."""
    return 1.0 - mpc(phi)


def mpd(phi: np.ndarray) -> np.ndarray:
    """Mean phase deviation [deg] of each column from its best straight line in the complex plane.

    The line is the principal axis of the components' (Re, Im) scatter (total
    least squares); the deviation of component ``j`` is the angle between it
    and the line, folded to 0–90°, and the mean is weighted by ``|phi_j|``
    (Reynders et al. 2012).  0° for a real (or uniformly rotated real) mode.
    """
    phi = np.asarray(phi, complex)
    phi = phi[:, None] if phi.ndim == 1 else phi
    out = np.zeros(phi.shape[1])
    for r in range(phi.shape[1]):
        v = phi[:, r]
        x = np.stack([v.real, v.imag], axis=1)
        if not np.any(x):
            continue
        _, _, vt = np.linalg.svd(x, full_matrices=False)
        u = vt[0]
        mag = np.abs(v)
        with np.errstate(invalid="ignore", divide="ignore"):
            c = np.clip(np.abs(x @ u) / mag, 0.0, 1.0)
        dev = np.degrees(np.arccos(np.where(mag > 0, c, 1.0)))
        out[r] = float(np.sum(mag * dev) / np.sum(mag))
    return out


# ---------------------------------------------------------------------------- results
@dataclass(frozen=True, eq=False)
class LSFDResult:
    """Residues, residual terms and synthesis of a SIMO LSFD fit.

    Parameters
    ----------
    poles : ndarray complex (m,)
        Physical poles [rad/s] (window-corrected), upper half plane.
    residues : ndarray complex (n_out, m)
        Receptance residues ``Q_jr`` (module docstring), whatever the quantity.
    modal_constants : ndarray complex (n_out, m)
        ``A_jr = (lambda_r - lambda_r^*) Q_jr``; ``c_jr b_r`` for real modes.
    residual_powers : tuple of int
        Powers of ``s`` of the residual terms in receptance form.
    residual_coefs : ndarray (n_out, n_res)
        Their real coefficients (receptance units).
    quantity : str
    synthesis : FrequencyResponse
        The fitted model on the fitted lines, at ``s = i w + a`` (directly
        comparable with the measured, windowed FRF).
    error_rel : ndarray (n_out,)
        Relative L2 synthesis error per channel ``||H - H_model|| / ||H||``.
    error_db : ndarray (n_out,)
        The same in dB (``20 log10 error_rel``).
    residual_poles : ndarray complex (k,)
        Out-of-band pseudo-mode poles included in the fit as residual terms
        (not modes of the band).
    residual_pole_residues : ndarray complex (n_out, k)
        Their receptance residues.
    """

    poles: np.ndarray
    residues: np.ndarray
    modal_constants: np.ndarray
    residual_powers: tuple[int, ...]
    residual_coefs: np.ndarray
    quantity: str
    synthesis: FrequencyResponse
    error_rel: np.ndarray
    error_db: np.ndarray
    residual_poles: np.ndarray = field(default_factory=lambda: np.zeros(0, complex))
    residual_pole_residues: np.ndarray | None = None

    @property
    def lower(self) -> np.ndarray | None:
        """Lower residual (mass line, receptance ``E/s^2``) per channel [1/kg], or None if not fitted."""
        return self._coef(-2)

    @property
    def upper(self) -> np.ndarray | None:
        """Upper residual (constant receptance) per channel [m/N], or None if not fitted."""
        return self._coef(0)

    def _coef(self, k: int) -> np.ndarray | None:
        if k not in self.residual_powers:
            return None
        return self.residual_coefs[:, self.residual_powers.index(k)]

    @property
    def mpc(self) -> np.ndarray:
        """Modal phase collinearity of each mode's modal constants."""
        return mpc(self.modal_constants)

    @property
    def mpd(self) -> np.ndarray:
        """Mean phase deviation [deg] of each mode's modal constants."""
        return mpd(self.modal_constants)

    @property
    def freqs_hz(self) -> np.ndarray:
        """Undamped natural frequencies ``|lambda| / 2 pi`` [Hz]."""
        return pole_frequency_hz(self.poles)

    @property
    def zeta(self) -> np.ndarray:
        """Damping ratios ``-Re(lambda) / |lambda|``."""
        return pole_damping(self.poles)


def synthesize(
    poles: np.ndarray,
    residues: np.ndarray,
    freqs_hz: np.ndarray,
    *,
    quantity: str = "accelerance",
    residual_powers: tuple[int, ...] = (),
    residual_coefs: np.ndarray | None = None,
    decay: float = 0.0,
) -> np.ndarray:
    """Evaluate the modal model (module docstring) at ``s = 2 pi i f + decay``.

    Parameters
    ----------
    poles : ndarray complex (m,)
    residues : ndarray complex (n_out, m)
        Receptance residues ``Q_jr``.
    freqs_hz : ndarray (n_f,)
    quantity : str
    residual_powers, residual_coefs
        Residual terms (receptance-form powers and (n_out, n_res) coefficients).
    decay : float
        ``0`` for the physical FRF; the window decay ``a`` to reproduce a windowed measurement.

    Returns
    -------
    ndarray complex (n_out, n_f)
    """
    q = QUANTITIES[quantity][0]
    s = _s_axis(freqs_hz, decay)
    poles = np.asarray(poles, complex)
    P = np.atleast_2d(np.asarray(residues, complex))
    g1 = (s**q)[:, None] / (s[:, None] - poles[None, :])
    g2 = (s**q)[:, None] / (s[:, None] - np.conj(poles)[None, :])
    out = P @ g1.T + P.conj() @ g2.T
    if residual_powers:
        out = out + np.asarray(residual_coefs, float) @ _residual_columns(s, q, tuple(residual_powers)).T
    return out


def _solve_linear(phi_c: np.ndarray, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Real least squares of the real-stacked complex basis against complex data (n_f, n_out)."""
    A = _stack(phi_c)
    B = _stack(Y)
    scale = np.linalg.norm(A, axis=0)
    scale[scale == 0] = 1.0
    X, *_ = np.linalg.lstsq(A / scale, B, rcond=None)
    X = X / scale[:, None]
    return X, B - A @ X


@one_blas_thread
def lsfd(
    frf: FrequencyResponse,
    poles: np.ndarray,
    *,
    band_hz: tuple[float, float] | None = None,
    residuals: tuple[int, ...] = DEFAULT_RESIDUALS,
    residual_poles: np.ndarray = (),
) -> LSFDResult:
    """Residues and residual terms of every channel for given physical poles (SIMO LSFD).

    Parameters
    ----------
    frf : FrequencyResponse
        Single input; the fit uses the lines in ``band_hz``. With
        ``frf.exp_window_decay = a`` the model is evaluated at ``s = i w + a``.
    poles : array_like complex (m,)
        Physical poles [rad/s], upper half plane (``-zeta w + i w_d``).
    band_hz : (float, float), optional
    residuals : tuple of int
        Residual powers of ``s`` in receptance form; ``(-2, 0)`` = lower
        (mass line, ``-1/w^2``) and upper (constant) residual, ``()`` = none.
    residual_poles : array_like complex (k,), optional
        Out-of-band pseudo-mode poles (physical) fitted as further residual
        terms; their residues are returned apart from the modes'.

    Returns
    -------
    LSFDResult

    Raises
    ------
    IdentificationError
        Bad FRF or poles.
    """
    frf = band_lines(frf, band_hz)
    modes = _check_poles(poles)
    extra = _check_poles(residual_poles)
    residuals = _check_residuals(residuals)
    q = QUANTITIES[frf.quantity][0]
    poles = np.concatenate([modes, extra])
    m = poles.size
    s = _s_axis(frf.freqs_hz, frf.exp_window_decay)
    Y = frf.data[:, 0, :].T  # (n_f, n_out)
    phi = _basis(s, poles, q, residuals)
    X, _ = _solve_linear(phi, Y)
    P_all = (X[:m] + 1j * X[m : 2 * m]).T  # (n_out, m)
    E = X[2 * m :].T  # (n_out, n_res)
    poles, P = modes, P_all[:, : modes.size]
    with np.errstate(invalid="ignore", divide="ignore"):
        A = (poles - np.conj(poles))[None, :] * P
    model = (phi @ X).T  # (n_out, n_f)
    data = frf.data[:, 0, :]
    err = np.linalg.norm(data - model, axis=1) / np.maximum(np.linalg.norm(data, axis=1), np.finfo(float).tiny)
    with np.errstate(divide="ignore"):
        err_db = 20 * np.log10(err)
    synth = frf.with_history(
        f"LSFD synthesis: {modes.size} modes, {extra.size} residual poles, residual powers {residuals}",
        data=model[:, None, :],
        coherence=None,
    )
    return LSFDResult(
        poles=poles,
        residues=P,
        modal_constants=A,
        residual_powers=residuals,
        residual_coefs=E,
        quantity=frf.quantity,
        synthesis=synth,
        error_rel=err,
        error_db=err_db,
        residual_poles=extra,
        residual_pole_residues=P_all[:, modes.size :],
    )


# ---------------------------------------------------------------------------- refinement
@dataclass(frozen=True, eq=False)
class RefinedPoles:
    """Result of :func:`refine_poles`.

    Parameters
    ----------
    poles : ndarray complex (m,)
        Refined physical poles [rad/s].
    initial : ndarray complex (m,)
        Starting poles.
    cost : float
        Final ``sum |H - model|^2`` over channels and lines.
    noise_var : float
        Estimated variance of the real and imaginary part of one FRF line
        (``cost / (2 n_f n_out - n_parameters)``).
    freq_std_hz, zeta_std : ndarray (m,)
        One-sigma uncertainties from the Gauss–Newton covariance.
    delta_cost : ndarray (m,)
        Increase of ``cost / noise_var`` when one mode is removed (others
        fixed, residues refitted): the mode's significance in units of noise.
    iterations : int
        Function evaluations used.
    residual_poles : ndarray complex (k,)
        Refined out-of-band pseudo-mode poles.
    residual_delta_cost : ndarray (k,)
        Their significance, as ``delta_cost``.
    """

    poles: np.ndarray
    initial: np.ndarray
    cost: float
    noise_var: float
    freq_std_hz: np.ndarray
    zeta_std: np.ndarray
    delta_cost: np.ndarray
    iterations: int
    residual_poles: np.ndarray = field(default_factory=lambda: np.zeros(0, complex))
    residual_delta_cost: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def freqs_hz(self) -> np.ndarray:
        return pole_frequency_hz(self.poles)

    @property
    def zeta(self) -> np.ndarray:
        return pole_damping(self.poles)


class _VarPro:
    """Variable-projection residual and Kaufman Jacobian for the global SIMO modal model.

    ``theta = [sigma_1..sigma_m, omega_1..omega_m]`` of the free poles
    ``-sigma + i omega``; ``fixed`` poles stay in the basis unchanged.
    """

    def __init__(self, s, Y, power, residuals, m, fixed=np.zeros(0, complex)):
        self.s = s
        self.B = _stack(Y)  # (2 n_f, n_out)
        self.n_out = Y.shape[1]
        fixed = np.asarray(fixed, complex)
        f1, f2 = _modal_columns(s, fixed, power)
        self.power = power
        self.const_cols = np.concatenate([f1, f2, _residual_columns(s, power, residuals)], axis=1)
        self.m = m
        self._key = None

    def _poles(self, theta: np.ndarray) -> np.ndarray:
        m = self.m
        return -theta[:m] + 1j * theta[m:]

    def _factor(self, theta: np.ndarray):
        key = theta.tobytes()
        if key == self._key:
            return self._cache
        poles = self._poles(theta)
        b1, b2 = _modal_columns(self.s, poles, self.power)
        A = _stack(np.concatenate([b1, b2, self.const_cols], axis=1))
        scale = np.linalg.norm(A, axis=0)
        scale[scale == 0] = 1.0
        Q, R = np.linalg.qr(A / scale)
        QtB = Q.T @ self.B
        resid = self.B - Q @ QtB
        self._key = key
        self._cache = (poles, Q, R, scale, QtB, resid)
        return self._cache

    def fun(self, theta: np.ndarray) -> np.ndarray:
        return self._factor(theta)[5].ravel()

    def jac_t(self, theta: np.ndarray) -> np.ndarray:
        """Transposed Kaufman Jacobian ``(2m, 2 n_f n_out)`` of :meth:`fun` (row-major residual order)."""
        poles, Q, R, scale, QtB, _ = self._factor(theta)
        m = self.m
        X = np.linalg.lstsq(R, QtB, rcond=None)[0] / scale[:, None]
        P = X[:m] + 1j * X[m : 2 * m]  # (m, n_out) residues of the free poles
        s = self.s
        sq = (s**self.power)[:, None]
        d1 = sq / (s[:, None] - poles[None, :]) ** 2  # (n_f, m)
        d2 = sq / (s[:, None] - np.conj(poles)[None, :]) ** 2
        t1 = d1[:, :, None] * P[None, :, :]  # (n_f, m, n_out)
        t2 = d2[:, :, None] * np.conj(P)[None, :, :]
        D = np.concatenate([-(t1 + t2), 1j * (t1 - t2)], axis=1)  # d/d sigma, d/d omega: (n_f, 2m, n_out)
        Dr = _stack(D).reshape(2 * s.size, -1)
        Dr = Dr - Q @ (Q.T @ Dr)
        return -Dr.reshape(2 * s.size, 2 * m, self.n_out).transpose(1, 0, 2).reshape(2 * m, -1)


def _lm(vp: _VarPro, theta0: np.ndarray, max_iter: int, xtol: float = 1e-10,
        ftol: float = 1e-13) -> tuple[np.ndarray, int]:
    """Levenberg–Marquardt (Marquardt's diagonal scaling, Nielsen's damping update) on the projected residual."""
    if theta0.size == 0:
        return theta0, 0
    theta = theta0.copy()
    r = vp.fun(theta)
    cost = float(r @ r)
    Jt = vp.jac_t(theta)
    A = Jt @ Jt.T
    g = Jt @ r
    mu = 1e-3 * float(np.max(np.diag(A)))
    nu = 2.0
    n_eval = 1
    for _ in range(max_iter):
        d = np.maximum(np.diag(A), 1e-300)
        try:
            step = np.linalg.solve(A + mu * np.diag(d), -g)
        except np.linalg.LinAlgError:
            mu *= 10.0
            continue
        trial = theta + step
        r_new = vp.fun(trial)
        n_eval += 1
        cost_new = float(r_new @ r_new)
        predicted = -(step @ g) - 0.5 * step @ A @ step
        rho = (cost - cost_new) / predicted if predicted > 0 else -1.0
        if cost_new < cost:
            small = np.all(np.abs(step) <= xtol * (np.abs(theta) + xtol))
            converged = small or (cost - cost_new) <= ftol * cost
            theta, r, cost = trial, r_new, cost_new
            mu *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3) if rho > 0 else 1.0
            nu = 2.0
            if converged:
                break
            Jt = vp.jac_t(theta)
            A = Jt @ Jt.T
            g = Jt @ r
        else:
            mu *= nu
            nu *= 2.0
            if mu > 1e20 * float(np.max(d)):
                break
    return theta, n_eval


@one_blas_thread
def refine_poles(
    frf: FrequencyResponse,
    poles: np.ndarray,
    *,
    band_hz: tuple[float, float] | None = None,
    residuals: tuple[int, ...] = DEFAULT_RESIDUALS,
    residual_poles: np.ndarray = (),
    free: np.ndarray | None = None,
    max_nfev: int = 100,
) -> RefinedPoles:
    """Refine poles by nonlinear least squares of the global SIMO modal model (variable projection).

    Parameters
    ----------
    frf : FrequencyResponse
        Single input; with ``exp_window_decay = a`` the model is evaluated at
        ``s = i w + a`` so the poles are the physical (corrected) ones.
    poles : array_like complex (m,)
        Starting physical poles (e.g. from LSCE), upper half plane.
    band_hz : (float, float), optional
    residuals : tuple of int
        Residual powers (receptance form), see :func:`lsfd`.
    residual_poles : array_like complex (k,), optional
        Out-of-band pseudo-mode poles, refined together with the modes and
        returned apart.
    free : array_like bool (m + k,), optional
        Which of ``poles`` then ``residual_poles`` are optimised; the others
        stay fixed (default all free).
    max_nfev : int
        Iteration budget of Levenberg–Marquardt (residual evaluations).

    Returns
    -------
    RefinedPoles

    Notes
    -----
    Minimises ``sum_j sum_k |H_j(f_k) - model_j(f_k)|^2`` over the decay
    rates and damped frequencies of the poles (module docstring); residues
    and residual terms are linear and projected out.  Equal weights are the
    maximum-likelihood choice for the equal, white noise of H1 estimates from
    a flat hammer spectrum.  Uncertainties come from the Gauss–Newton
    covariance ``noise_var (J^T J)^-1`` of the free poles (NaN for fixed ones).
    """
    frf = band_lines(frf, band_hz)
    modes0 = _check_poles(poles)
    extra0 = _check_poles(residual_poles)
    p0 = np.concatenate([modes0, extra0])
    n_modes = modes0.size
    residuals = _check_residuals(residuals)
    q = QUANTITIES[frf.quantity][0]
    m_all = p0.size
    fr = np.ones(m_all, bool) if free is None else np.asarray(free, bool)
    if fr.shape != (m_all,):
        raise IdentificationError(f"free must have one flag per pole ({m_all}), got shape {fr.shape}")
    s = _s_axis(frf.freqs_hz, frf.exp_window_decay)
    Y = frf.data[:, 0, :].T
    m = int(fr.sum())
    vp = _VarPro(s, Y, q, residuals, m, fixed=p0[~fr])
    n_res = vp.B.size
    n_par = 2 * m_all + (2 * m_all + len(residuals)) * frf.n_out
    theta0 = np.concatenate([-p0[fr].real, p0[fr].imag])
    if n_res > n_par:
        theta, nfev = _lm(vp, theta0, max_nfev)
    else:
        theta, nfev = theta0, 0
    # the model holds each pole with its conjugate: a pole that crossed to the lower half plane is its conjugate
    theta = np.concatenate([theta[:m], np.abs(theta[m:])])
    r = vp.fun(theta)
    cost = float(r @ r)
    noise_var = cost / max(n_res - n_par, 1)
    poles_ref = p0.copy()
    poles_ref[fr] = vp._poles(theta)
    fstd = np.full(m_all, np.nan)
    zstd = np.full(m_all, np.nan)
    if m:
        Jt = vp.jac_t(theta)
        cov = np.linalg.pinv(Jt @ Jt.T) * noise_var
        var_sig, var_wd, cov_sw = np.diag(cov)[:m], np.diag(cov)[m:], np.diag(cov, k=m)
        sig, wd = theta[:m], theta[m:]
        wn = np.hypot(sig, wd)
        # f = wn / 2 pi, zeta = sig / wn: first-order propagation
        dwn_ds, dwn_dw = sig / wn, wd / wn
        var_wn = dwn_ds**2 * var_sig + dwn_dw**2 * var_wd + 2 * dwn_ds * dwn_dw * cov_sw
        dz_ds = 1 / wn - sig * dwn_ds / wn**2
        dz_dw = -sig * dwn_dw / wn**2
        fstd[fr] = np.sqrt(np.maximum(var_wn, 0)) / (2 * np.pi)
        zstd[fr] = np.sqrt(np.maximum(dz_ds**2 * var_sig + dz_dw**2 * var_wd + 2 * dz_ds * dz_dw * cov_sw, 0))
    delta = _significance(s, Y, poles_ref, q, residuals, cost, noise_var)
    log.debug("pole refinement: %d poles (%d free), %d evaluations, noise std %.3g", m_all, m, nfev, np.sqrt(noise_var))
    k = n_modes
    return RefinedPoles(
        poles=poles_ref[:k],
        initial=modes0,
        cost=cost,
        noise_var=noise_var,
        freq_std_hz=fstd[:k],
        zeta_std=zstd[:k],
        delta_cost=delta[:k],
        iterations=nfev,
        residual_poles=poles_ref[k:],
        residual_delta_cost=delta[k:],
    )


def _significance(s, Y, poles, q, residuals, cost, noise_var) -> np.ndarray:
    """``(cost without pole r - cost) / noise_var`` for every pole (others fixed, linear part refitted).

    From one factorisation of the full basis: removing the two real columns
    ``C`` of a pole from a least-squares fit raises the residual by
    ``sum_j x_Cj^T [(A^T A)^-1]_CC^-1 x_Cj`` (``x_Cj`` their coefficients for channel ``j``).
    """
    m = poles.size
    if m == 0:
        return np.zeros(0)
    if noise_var <= 0:
        return np.full(m, np.inf)
    A = _stack(_basis(s, poles, q, residuals))
    scale = np.linalg.norm(A, axis=0)
    scale[scale == 0] = 1.0
    Q, R = np.linalg.qr(A / scale)
    B = _stack(Y)
    X = np.linalg.lstsq(R, Q.T @ B, rcond=None)[0]
    Rinv = np.linalg.lstsq(R, np.eye(R.shape[0]), rcond=None)[0]
    Ginv = Rinv @ Rinv.T
    out = np.empty(m)
    for r in range(m):
        C = [r, m + r]
        Xc = X[C]
        try:
            out[r] = float(np.sum(Xc * np.linalg.solve(Ginv[np.ix_(C, C)], Xc))) / noise_var
        except np.linalg.LinAlgError:
            out[r] = 0.0  # a pole whose columns are degenerate adds nothing
    return out
