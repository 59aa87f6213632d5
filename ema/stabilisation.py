"""Stabilisation diagram of an LSCE pole sweep.

For every model order the poles of :func:`ema.lsce.lsce` are compared with
those of the previous order: a pole is *stable in frequency* if the nearest
previous pole lies within ``tol_freq`` (relative), *stable in damping* if its
damping ratio differs by less than ``tol_damping`` (relative), and *stable in
shape* if the MAC between the two poles' quick mode shapes exceeds
``tol_mac``.  Quick shapes are the complex residues of a linear least-squares
fit of all channels with all poles of the order (one basis shared by all
channels, plus a constant and an ``s^2`` term for out-of-band modes).

Frequencies and damping ratios in the diagram are the *physical* ones: the
exponential-window shift has been removed (``s = s_w + a``).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import cho_factor, cho_solve

from ._blas import one_blas_thread
from .frf import FrequencyResponse
from .lsce import IdentificationError, PoleSweep, band_lines, pole_damping, pole_frequency_hz

__all__ = ["StabilisationDiagram", "stabilisation_diagram"]

log = logging.getLogger("ema")


@dataclass(frozen=True, eq=False)
class StabilisationDiagram:
    """All poles of an order sweep with their stability flags (physical, window-corrected poles).

    Parameters
    ----------
    order : ndarray int (n,)
        Model order (number of poles) each pole belongs to.
    poles : ndarray complex (n,)
        Physical poles ``s_w + a`` [rad/s].
    shapes : ndarray complex (n, n_out) or None
        Quick residues of every pole (per channel).
    stable_freq, stable_damping, stable_shape : ndarray bool (n,)
        Stability with respect to the previous order (False for the first order).
    in_band : ndarray bool (n,)
        Damped frequency inside the band.
    band_hz : (float, float)
    exp_window_decay : float
        Decay ``a`` [1/s] that was removed.
    outputs : tuple of str
        Channel of each shape column.
    tolerances : dict
        ``tol_freq``, ``tol_damping``, ``tol_mac`` used.
    """

    order: np.ndarray
    poles: np.ndarray
    shapes: np.ndarray | None
    stable_freq: np.ndarray
    stable_damping: np.ndarray
    stable_shape: np.ndarray
    in_band: np.ndarray
    band_hz: tuple[float, float]
    exp_window_decay: float
    outputs: tuple[str, ...]
    tolerances: dict = field(default_factory=dict)

    @property
    def freqs_hz(self) -> np.ndarray:
        """Undamped natural frequency ``|s| / 2 pi`` of every pole [Hz]."""
        return pole_frequency_hz(self.poles)

    @property
    def zeta(self) -> np.ndarray:
        """Damping ratio ``-Re(s) / |s|`` of every pole (physical, window removed)."""
        return pole_damping(self.poles)

    @property
    def stable(self) -> np.ndarray:
        """Stable in frequency, damping and shape."""
        return self.stable_freq & self.stable_damping & self.stable_shape

    @property
    def orders(self) -> np.ndarray:
        """The distinct model orders, ascending."""
        return np.unique(self.order)

    @property
    def status(self) -> np.ndarray:
        """One-letter code per pole: ``'o'`` new, ``'f'`` frequency, ``'d'`` + damping, ``'v'`` + shape, ``'s'`` all."""
        out = np.full(self.order.shape, "o", dtype="<U1")
        out[self.stable_freq] = "f"
        out[self.stable_freq & self.stable_damping] = "d"
        out[self.stable_freq & self.stable_shape & ~self.stable_damping] = "v"
        out[self.stable] = "s"
        return out

    def __len__(self) -> int:
        return self.order.size


def _quick_shapes(s: np.ndarray, Y: np.ndarray, poles: np.ndarray) -> np.ndarray:
    """Complex residues (n_poles, n_out) of ``Y (n_f, n_out)`` with single-sided pole terms + [1, s^2].

    Normal equations with a Cholesky factorisation (one matrix product and a
    small factorisation per order: cheap, and robust to a busy multi-threaded
    BLAS); minimum-norm least squares if the Gram matrix is singular.
    """
    A = np.concatenate([1.0 / (s[:, None] - poles[None, :]), np.ones((s.size, 1)), (s * s)[:, None]], axis=1)
    scale = np.linalg.norm(A, axis=0)
    scale[scale == 0] = 1.0
    A = A / scale
    Ah = A.conj().T
    G = Ah @ A
    try:
        c = cho_factor(G, check_finite=False)
        X = cho_solve(c, Ah @ Y, check_finite=False)
        if not np.all(np.isfinite(X)):
            raise np.linalg.LinAlgError("non-finite solution")
    except (np.linalg.LinAlgError, ValueError):
        X = np.linalg.lstsq(A, Y, rcond=None)[0]
    return (X / scale[:, None])[: poles.size]


@one_blas_thread
def stabilisation_diagram(
    sweep: PoleSweep,
    frf: FrequencyResponse | None = None,
    *,
    tol_freq: float = 0.005,
    tol_damping: float = 0.05,
    tol_mac: float = 0.98,
    line_step: int = 1,
) -> StabilisationDiagram:
    """Flag the poles of an LSCE sweep as stable in frequency, damping and shape.

    Parameters
    ----------
    sweep : PoleSweep
        From :func:`ema.lsce.lsce`.
    frf : FrequencyResponse, optional
        The FRF the sweep came from; needed for shape stability (without it
        every pole counts as shape-stable and ``shapes`` is None).
    tol_freq : float
        Relative frequency tolerance (default 0.5 %).
    tol_damping : float
        Relative damping tolerance (default 5 %).
    tol_mac : float
        Minimum MAC with the matching pole of the previous order (default 0.98).
    line_step : int
        Use every ``line_step``-th line for the quick shapes (speed).

    Returns
    -------
    StabilisationDiagram

    Raises
    ------
    IdentificationError
        On tolerances out of range or an FRF that does not match the sweep.
    """
    if not (0 < tol_freq < 1 and 0 < tol_damping and 0 <= tol_mac <= 1):
        raise IdentificationError(
            f"need 0 < tol_freq < 1, tol_damping > 0, 0 <= tol_mac <= 1; got {tol_freq}, {tol_damping}, {tol_mac}"
        )
    lo, hi = sweep.band_hz
    a = sweep.exp_window_decay
    s = Y = None
    outputs: tuple[str, ...] = ()
    if frf is not None:
        frf = band_lines(frf, sweep.band_hz)
        if abs(float(frf.exp_window_decay) - a) > 1e-12 * max(1.0, a):
            raise IdentificationError(
                f"frf.exp_window_decay={frf.exp_window_decay} differs from the sweep's {a}; pass the same FRF"
            )
        step = max(int(line_step), 1)
        s = 2j * np.pi * frf.freqs_hz[::step]
        Y = frf.data[:, 0, ::step].T
        outputs = frf.outputs
    orders, poles, sf, sd, sv, shapes = [], [], [], [], [], []
    prev = prev_shapes = None
    for i, p in enumerate(sweep.orders):
        pw = sweep.poles_windowed[i]
        lam = pw + a
        n = lam.size
        sh = _quick_shapes(s, Y, pw) if s is not None else None
        f_ok = np.zeros(n, bool)
        d_ok = np.zeros(n, bool)
        v_ok = np.zeros(n, bool) if sh is not None else np.ones(n, bool)
        if prev is not None and prev.size and n:
            wn = np.abs(lam)
            wp = np.abs(prev)
            j = np.argmin(np.abs(wn[:, None] - wp[None, :]), axis=1)
            f_ok = np.abs(wn - wp[j]) <= tol_freq * wn
            z = -lam.real / wn
            zp = -prev.real / wp
            d_ok = np.abs(z - zp[j]) <= tol_damping * np.abs(zp[j])
            if sh is not None:
                num = np.abs(np.sum(np.conj(sh) * prev_shapes[j], axis=1)) ** 2
                den = np.sum(np.abs(sh) ** 2, axis=1) * np.sum(np.abs(prev_shapes[j]) ** 2, axis=1)
                with np.errstate(invalid="ignore", divide="ignore"):
                    v_ok = np.where(den > 0, num / den, 0.0) >= tol_mac
        orders.append(np.full(n, p))
        poles.append(lam)
        sf.append(f_ok)
        sd.append(d_ok)
        sv.append(v_ok)
        if sh is not None:
            shapes.append(sh)
        prev, prev_shapes = lam, sh
    lam = np.concatenate(poles) if poles else np.zeros(0, complex)
    fd = lam.imag / (2 * np.pi)
    diag = StabilisationDiagram(
        order=np.concatenate(orders).astype(int),
        poles=lam,
        shapes=np.concatenate(shapes, axis=0) if shapes else None,
        stable_freq=np.concatenate(sf),
        stable_damping=np.concatenate(sd),
        stable_shape=np.concatenate(sv),
        in_band=(fd >= lo) & (fd <= hi),
        band_hz=(float(lo), float(hi)),
        exp_window_decay=float(a),
        outputs=tuple(outputs),
        tolerances={"tol_freq": tol_freq, "tol_damping": tol_damping, "tol_mac": tol_mac},
    )
    log.info(
        "stabilisation diagram: %d poles over %d orders, %d stable (f %.2g%%, zeta %.2g%%, MAC %.3g)",
        len(diag), len(sweep.orders), int(diag.stable.sum()), 100 * tol_freq, 100 * tol_damping, tol_mac,
    )
    return diag
