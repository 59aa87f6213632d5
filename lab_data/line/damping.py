"""A causal stand-in for the constant loss factors of thesis eq. 2.32–2.34.

Eq. 2.32 gives each resilient layer the complex stiffness ``K (1 + jη)`` at
every frequency. A loss factor that is constant down to 0 Hz has no causal
time-domain counterpart (Kramers–Kronig: a loss must come with a storage
stiffness that rises with frequency), so the time-domain line uses a
generalised Maxwell model fitted to it over the band:

.. math::

    K_\\text{fit}(\\omega) = K \\left[1 + \\eta\\, g(\\omega)\\right], \\qquad
    g(\\omega) = g_0 + \\sum_{b} a_b \\frac{j\\omega\\tau_b}{1 + j\\omega\\tau_b}

— a spring ``K (1 + η g₀)`` in parallel with Maxwell branches (spring
``K η a_b`` in series with a dashpot ``K η a_b τ_b``). The relaxation times
``τ_b`` are fixed (:data:`RELAXATION_HZ`, one per decade over 4–2500 Hz) and
``g₀ ≥ -2, a_b ≥ 0`` are fitted once by non-negative least squares so that
``g(ω) ≈ j`` over :data:`FIT_BAND_HZ` (200 log-spaced points, the real part
weighted 0.3 against the imaginary part): the imaginary part is the loss
factor, the real part (zero for eq. 2.32) is the unavoidable causal
dispersion — the storage stiffness rises through the band by about
``2η/π`` per neper (Kramers–Kronig), the "dynamic stiffening" of real
elastomer pads — centred on the band. The bound on ``g₀`` keeps the long-term
(static) stiffness at ``K (1 + η g₀) ≥ K (1 − 2η)``. The same unit fit serves
every layer, so a per-sleeper loss factor (support scatter, a renewed
section) needs no new fit: the deviation from eq. 2.32 scales with ``η``.

Deviation from eq. 2.32 (:func:`deviation_db`, 10–2000 Hz): ``|K_fit / K(1+jη)|``
runs from −1.8 dB at 10 Hz to +1.7 dB at 2 kHz for the pads (η = 0.13) and
from −2.9 dB to +2.5 dB for the subplates (η = 0.20); the fitted loss factor
stays within 0.74–1.13 ``η``. This is one of the real differences between the
line and the estimator's frequency-domain track (which uses eq. 2.32 as
written).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.optimize import nnls

__all__ = ["RELAXATION_HZ", "FIT_BAND_HZ", "CausalLossFit", "unit_loss_fit", "complex_stiffness", "deviation_db"]

#: Relaxation frequencies 1/(2π τ_b) of the Maxwell branches [Hz].
RELAXATION_HZ = (4.0, 34.2, 292.4, 2500.0)
#: Weight of the real part against the imaginary part in the fit, and the lower bound of ``g0``.
REAL_WEIGHT = 0.3
G0_MIN = -2.0
#: Band over which ``g(ω) ≈ j`` is fitted [Hz] (the thesis band 10–500 Hz and the pinned–pinned region).
FIT_BAND_HZ = (10.0, 2000.0)


@dataclass(frozen=True)
class CausalLossFit:
    """Unit generalised-Maxwell fit ``g(ω) = g0 + Σ a_b jωτ_b / (1 + jωτ_b)`` to ``g = j``.

    Attributes
    ----------
    g0 : float
        Static term (the long-term stiffness is ``K (1 + η g0)``).
    weights : ndarray (n_b,)
        ``a_b ≥ 0``, branch stiffness per unit ``K η``.
    tau : ndarray (n_b,)
        Relaxation times [s].
    """

    g0: float
    weights: np.ndarray
    tau: np.ndarray

    def g(self, freqs_hz: np.ndarray) -> np.ndarray:
        """The fitted ``g(ω)`` at ``freqs_hz`` (complex)."""
        jwt = 1j * 2 * np.pi * np.asarray(freqs_hz, float)[..., None] * self.tau
        return self.g0 + np.sum(self.weights * jwt / (1 + jwt), axis=-1)


@lru_cache(maxsize=1)
def unit_loss_fit() -> CausalLossFit:
    """The fit of the module docstring, computed once (non-negative least squares on 200 log-spaced points)."""
    f = np.geomspace(*FIT_BAND_HZ, 200)
    tau = 1.0 / (2 * np.pi * np.array(RELAXATION_HZ))
    jwt = 1j * 2 * np.pi * f[:, None] * tau
    basis = jwt / (1 + jwt)
    # unknowns: g0 - G0_MIN >= 0 and a_b >= 0; target g = j (real part 0, imaginary part 1)
    A = np.hstack([np.ones((f.size, 1)), basis])
    A_ri = np.vstack([REAL_WEIGHT * A.real, A.imag])
    b_ri = np.concatenate([np.full(f.size, -REAL_WEIGHT * G0_MIN), np.ones(f.size)])
    x, _ = nnls(A_ri, b_ri)
    # all four branches are kept (a zero weight is a harmless branch): the kernel is unrolled for four
    return CausalLossFit(float(x[0] + G0_MIN), x[1:], tau)


def complex_stiffness(K: float, eta: float, freqs_hz: np.ndarray, damping: float = 0.0) -> np.ndarray:
    """The causal layer's complex stiffness ``K (1 + η g(ω)) + jωC`` (what the time-domain line simulates)."""
    f = np.asarray(freqs_hz, float)
    return K * (1 + eta * unit_loss_fit().g(f)) + 1j * 2 * np.pi * f * damping


def deviation_db(eta: float, band_hz: tuple[float, float] = FIT_BAND_HZ, n: int = 400) -> dict:
    """How far the causal fit lies from eq. 2.32's ``K (1 + jη)`` over a band.

    Returns
    -------
    dict
        ``max_abs_db`` (largest ``|20 log10 |K_fit / K(1+jη)||``), ``db_at_low``, ``db_at_high`` (at the band
        edges), ``loss_factor_min`` / ``loss_factor_max`` (``Im K_fit / Re K_fit`` over the band).
    """
    f = np.geomspace(*band_hz, n)
    k = 1 + eta * unit_loss_fit().g(f)
    db = 20 * np.log10(np.abs(k) / abs(1 + 1j * eta))
    loss = k.imag / k.real
    return {"max_abs_db": float(np.max(np.abs(db))), "db_at_low": float(db[0]), "db_at_high": float(db[-1]),
            "loss_factor_min": float(loss.min()), "loss_factor_max": float(loss.max())}
