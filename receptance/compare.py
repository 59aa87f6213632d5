"""Model against measurement: the model's FRFs at the test's sensors beside the measured H1 (thesis Figs. 3.18–3.19).

Error measures, per channel over a band (``H_x`` measured, ``H_m`` model,
both accelerance at the same frequency lines, the model evaluated through the
measurement's exponential window so both see the same pole shift):

* ``db_rms``: RMS over the band of ``20 log10(|H_m| / |H_x|)`` [dB] — how far
  apart the curves look on the usual log plot;
* ``rel_error``: ``‖H_m − H_x‖₂ / ‖H_x‖₂`` — the complex (magnitude and
  phase) misfit, dominated by the resonances;
* ``frac``: frequency response assurance criterion
  ``|Σ H_x* H_m|² / (Σ|H_x|² Σ|H_m|²)`` (1 = same shape over frequency).

The summary figure of merit is the median over channels of ``db_rms``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ema.frf import FrequencyResponse
from receptance.modal_model import ModalModel, ModelError

__all__ = ["Comparison", "compare_frf", "frf_errors"]


@dataclass(frozen=True, eq=False)
class Comparison:
    """Measured and model FRFs on the same lines, with per-channel errors.

    Attributes
    ----------
    measured, model : FrequencyResponse
        Accelerance, same outputs, input and frequency lines.
    channels : pandas.DataFrame
        One row per output: ``channel, db_rms, rel_error, frac`` (plus the
        channel table's ``node, x, y, z, dx, dy, dz, fe_node, setup`` when known).
    band_hz : (float, float)
    summary_db : float
        Median over channels of ``db_rms`` (module docstring).
    """

    measured: FrequencyResponse
    model: FrequencyResponse
    channels: pd.DataFrame = field(repr=False)
    band_hz: tuple[float, float]
    summary_db: float


def frf_errors(measured: np.ndarray, model: np.ndarray) -> dict[str, np.ndarray]:
    """Per-row ``db_rms``, ``rel_error`` and ``frac`` of two complex arrays ``(n_channels, n_freq)``."""
    Hx = np.asarray(measured, complex)
    Hm = np.asarray(model, complex)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio_db = 20 * np.log10(np.abs(Hm) / np.abs(Hx))
    ratio_db = np.where(np.isfinite(ratio_db), ratio_db, np.nan)
    db_rms = np.sqrt(np.nanmean(ratio_db**2, axis=1))
    rel = np.linalg.norm(Hm - Hx, axis=1) / np.linalg.norm(Hx, axis=1)
    frac = np.abs(np.sum(Hx.conj() * Hm, axis=1)) ** 2 / (np.sum(np.abs(Hx) ** 2, axis=1)
                                                         * np.sum(np.abs(Hm) ** 2, axis=1))
    return {"db_rms": db_rms, "rel_error": rel, "frac": frac}


def compare_frf(model: ModalModel, measured: FrequencyResponse, channels: pd.DataFrame, *,
                band_hz: tuple[float, float] | None = None) -> Comparison:
    """Compare the model with measured FRFs of one hammer setup.

    Parameters
    ----------
    model : ModalModel
    measured : FrequencyResponse
        Measured accelerance (``ema.estimate_frf``); its ``exp_window_decay``
        is applied to the model too.
    channels : pandas.DataFrame
        The setup's channel table, including the force row (positions,
        directions and FE nodes of sensors and hammer).
    band_hz : (float, float), optional
        Default: the measured frequency range.

    Returns
    -------
    Comparison
    """
    if measured.quantity != "accelerance":
        measured = measured.as_quantity("accelerance")
    if band_hz is not None:
        measured = measured.select(band_hz=band_hz)
    band = (float(measured.freqs_hz[0]), float(measured.freqs_hz[-1]))
    acc = channels[channels["quantity"] == "acceleration"]
    missing = [o for o in measured.outputs if o not in set(acc["name"].astype(str))]
    if missing:
        raise ModelError(f"measured output(s) {missing} are not acceleration channels of the channel table")
    if measured.n_in != 1:
        raise ModelError(f"expected a single-reference measurement, got {measured.n_in} inputs")
    order = acc.set_index(acc["name"].astype(str)).loc[list(measured.outputs)].reset_index(drop=True)
    table = pd.concat([order, channels[channels["quantity"] == "force"]], ignore_index=True)
    H = model.frf_at_channels(table, measured.freqs_hz, decay=measured.exp_window_decay)
    H = FrequencyResponse(H.freqs_hz, H.data, measured.outputs, measured.inputs, "accelerance",
                          channels=measured.channels, exp_window_decay=measured.exp_window_decay,
                          history=H.history + (f"model {model.name!r} at the test's channels",))
    err = frf_errors(measured.data[:, 0], H.data[:, 0])
    df = pd.DataFrame({"channel": list(measured.outputs), **err})
    for col in ("node", "x", "y", "z", "dx", "dy", "dz", "fe_node", "setup"):
        if col in order:
            df[col] = order[col].to_numpy()
    return Comparison(measured, H, df, band, float(np.median(err["db_rms"])))
