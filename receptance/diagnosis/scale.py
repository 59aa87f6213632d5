"""The measured modal constants against the FE's: one check of units and normalisation on both sides.

A hammer test identifies, for each mode ``r``, the modal constants
``A_jr = c_jr b_r`` of its receptance (:mod:`ema.lsfd`, ``scaling =
"modal_constant"``): the mass-normalised shape at response ``j`` times the
shape at the force point (thesis eqs. 2.24–2.29). A mass-normalised FE export
in SI units predicts the same numbers from its shapes at the sensors and at
the hammer, ``A^FE_jr = φ_jr φ_Fr``, for the FE mode (or the combination of a
degenerate pair) the test mode is paired with.

The hidden effects the diagnosis looks for (bearings, press fits, a rig, an
absorber) move a well-paired mode's constants by a few tens of per cent at
most: measured on the virtual lab's scenarios, the pooled ratio of measured to
FE constants is 0.91–1.01 on every scenario and both FE styles. A ratio of 3
or more (±9.5 dB) is not physics but units or scaling: shapes that are not
mass-normalised (a Nastran ``NORM=MAX`` export, a modal mass the file left
at 0), an FE in mm or tonnes read as SI, a force in kN or accelerations in g
taken as SI, a sensitivity not applied. A negative ratio is a sign: the
hammer's (or every sensor's) direction in the channel table is reversed.
None of this depends on the rigid-body modes, which the mass check of
:func:`fem_import.check_mass_normalisation` needs.

The ratio is pooled over the modes paired with MAC ≥ :data:`MIN_MAC`, by least
squares (``Σ Re(A^test · A^FE) / Σ |A^FE|²``), so a mode whose force point
sits near a nodal line (small ``A^FE``, an unstable ratio) weighs little.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from .errors import DiagnosisError

__all__ = ["ModalScale", "modal_scale", "check_modal_scale", "MIN_MAC", "MAX_RATIO"]

#: modes paired at least this well enter the pooled ratio
MIN_MAC = 0.9
#: a pooled ratio beyond this factor either way (±9.5 dB) is units or normalisation, not a hidden effect
MAX_RATIO = 3.0


@dataclass(frozen=True)
class ModalScale:
    """Measured against FE modal constants of one setup.

    Attributes
    ----------
    setup : str
    ratio : float
        Pooled ``A^test / A^FE`` over the well-paired modes (NaN when none).
    n_modes : int
        Modes pooled.
    table : DataFrame
        Per paired mode: ``f_test_hz, fe_modes, mac, ratio, weight`` (weight: ``|A^FE|²`` share).
    """

    setup: str
    ratio: float
    n_modes: int
    table: pd.DataFrame

    def to_dict(self) -> dict:
        return {"setup": self.setup, "ratio": self.ratio, "n_modes": self.n_modes,
                "modes": self.table.to_dict(orient="records")}


def modal_scale(test, fe, channels: pd.DataFrame, *, setup: str = "", pairing=None) -> ModalScale | None:
    """The pooled ratio of measured to FE modal constants for one setup (module docstring).

    Parameters
    ----------
    test : ema.ModeSet
        One setup's identified modes, scaled as modal constants.
    fe : fem_import.FEModes
    channels : DataFrame
        The setup's channel table with its force row, in the FE's frame.
    pairing : ema.pairing.Pairing, optional
        Of ``test`` with ``fe``; paired here when not given.

    Returns
    -------
    ModalScale or None
        None when the modes are not scaled as modal constants or the table has no force row.
    """
    from ema.pairing import pair_modes
    from fem_import.modes import shapes_at_channels

    force = channels[channels["quantity"] == "force"]
    if getattr(test, "scaling", "") != "modal_constant" or force.empty or len(test) == 0:
        return None
    pairing = pairing if pairing is not None else pair_modes(test, fe)
    at_sensors = shapes_at_channels(fe, test.channels)
    at_force = shapes_at_channels(fe, force.iloc[:1], quantity="force")[0]
    rows, num, den = [], 0.0, 0.0
    for p in pairing.pairs:
        idx = list(p.fe_indices)
        w = np.asarray(p.weights, float) if p.weights else np.ones(len(idx)) / np.sqrt(len(idx))
        a_fe = (at_sensors[:, idx] @ w) * float(at_force[idx] @ w)
        a_test = np.asarray(test.shapes[:, p.test_index])
        ok = np.isfinite(a_test)
        dot, norm2 = float(np.real(np.vdot(a_fe[ok], a_test[ok]))), float(a_fe[ok] @ a_fe[ok])
        good = p.mac >= MIN_MAC and norm2 > 0
        if good:
            num, den = num + dot, den + norm2
        rows.append({"f_test_hz": float(test.freqs_hz[p.test_index]),
                     "fe_modes": "+".join(str(j + 1) for j in idx), "mac": float(p.mac),
                     "ratio": dot / norm2 if norm2 > 0 else float("nan"), "weight": norm2 if good else 0.0})
    table = pd.DataFrame(rows, columns=["f_test_hz", "fe_modes", "mac", "ratio", "weight"])
    if den > 0:
        table["weight"] = table["weight"] / den
    n = int((table["weight"] > 0).sum())
    return ModalScale(setup, num / den if den > 0 else float("nan"), n, table)


def check_modal_scale(scale: ModalScale | None, *, fem: str = "", measurement: str = "") -> None:
    """Refuse a setup whose measured modal constants are :data:`MAX_RATIO` or more off the FE's, or of the
    other sign (module docstring).

    Raises
    ------
    DiagnosisError
        Names the setup, the ratio and the modes it pools, and what to check on each side.
    """
    if scale is None or not np.isfinite(scale.ratio) or scale.n_modes == 0:
        return
    r = scale.ratio
    what = (f"setup {scale.setup!r}{f' ({measurement})' if measurement else ''}: the measured modal constants are "
            f"{r:.3g} times the FE's ({fem or 'FE export'}), pooled over {scale.n_modes} mode(s) paired with MAC ≥ "
            f"{MIN_MAC:g}")
    if r < 0:
        raise DiagnosisError(f"{what}: of the other sign, so the hammer's measuring direction (dx, dy, dz of the "
                             f"force row) or every sensor's is reversed in the channel table")
    if not 1 / MAX_RATIO < r < MAX_RATIO:
        raise DiagnosisError(f"{what}; hidden effects move them by tens of per cent, a factor {MAX_RATIO:g} is units "
                             f"or scaling: check that the FE shapes are mass-normalised in SI units (a NORM=MAX export, "
                             f"a modal mass left at 0, mm or tonnes read as SI), and that the force and the "
                             f"accelerations are in N and m/s² (kN, g, a sensitivity not applied)")
