"""Result types of a field estimate (documented return values of :func:`estimator.estimate_run`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping

import numpy as np
import pandas as pd

from estimator.standards.en13231 import BandIndexes
from estimator.sleepers import SleeperPassing
from estimator.wheel import WheelRoughness

__all__ = ["ProfileEstimate", "FieldEstimate"]


@dataclass(frozen=True, eq=False)
class ProfileEstimate:
    """One wheelset's estimate with one transfer-function model, both rails.

    Attributes
    ----------
    wheelset : int
        Vehicle wheelset (1 = front end).
    role : str
        ``leading`` or ``trailing`` on this run.
    model : str
        ``half``, ``vertical`` or ``vertical_lateral``.
    rails : tuple of str
        Rail of each row (``L``/``R`` of the line), from the vehicle sides.
    chainage_m : ndarray (M,)
        Grid: ``N`` samples per wheel revolution (step ``dx``).
    dx : float
    irregularity : ndarray (2, M)
        Estimated irregularity at the wheels (rail + wheel roughness, contact-filtered) [m].
    rail : ndarray (2, M)
        Rail roughness [m]: wheel part removed by the comb, sleeper passing removed, contact filter undone.
    speed_m_s : ndarray (M,)
        Speed of the wheelset at each grid point.
    indexes : BandIndexes
        EN 13231-3 bands of ``rail`` (arrays ``(n_bands, 2, M)``).
    resolved : ndarray of bool (n_bands, M)
        Where the run's speed lets the inversion band cover each EN band.
    wheel : WheelRoughness
        Synchronous average per wheel (vehicle sides) and its orders.
    conditioning : pandas.DataFrame
        Condition number and regularisation per one-third-octave band (per transfer class).
    sleeper : SleeperPassing or None
        What :func:`estimator.sleepers.sleeper_comb` removed (None when the comb was off).
    """

    wheelset: int
    role: str
    model: str
    rails: tuple[str, ...]
    chainage_m: np.ndarray
    dx: float
    irregularity: np.ndarray
    rail: np.ndarray
    speed_m_s: np.ndarray
    indexes: BandIndexes
    resolved: np.ndarray
    wheel: WheelRoughness
    conditioning: pd.DataFrame
    sleeper: SleeperPassing | None = None

    def rail_row(self, rail: str) -> int:
        return self.rails.index(rail)

    def pk_pk(self, band: tuple[float, float], rail: str) -> np.ndarray:
        """Peak-to-peak amplitude [m] of one band along chainage for one rail."""
        return self.indexes.pk_pk[self.indexes.bands_mm.index(tuple(band)), self.rail_row(rail)]


@dataclass(frozen=True, eq=False)
class FieldEstimate:
    """Everything one run's estimate produced (see :func:`estimator.estimate_run`).

    Attributes
    ----------
    run_id, source : str
    header : dict
        Run header fields.
    direction, orientation : str
    leading : int
        Leading wheelset on this run.
    fs : float
    duration_s : float
    masked_share : dict
        Per channel and ``run``.
    qc : pandas.DataFrame
        Every quality-control finding (kind, channel, time and chainage range, reason, action).
    odometry : pandas.DataFrame
        Balise resets (time, balise, jump, action).
    dx_m : dict
        Spatial step per wheelset; ``lambda_min_m`` the shortest wavelength the run resolves.
    lambda_min_m : float
    band_hz : tuple
        Inversion band.
    wheelbase_m : float
    wheelbase_source : str
        ``given`` or ``measured`` (lead/trail cross-correlation, with its correlation).
    circumference : dict
        :class:`~estimator.wheel.CircumferenceFit` per wheelset.
    profiles : dict
        ``(wheelset, model)`` → :class:`ProfileEstimate`.
    indexes : pandas.DataFrame
        Per wheelset, model, rail, band, stretch: median and max pk-pk [µm], exceedance [%].
    spectra : pandas.DataFrame
        EN 15610 levels per wheelset, model, stretch, rail, band, with the ISO 3095 limit.
    corrugation : pandas.DataFrame
        Corrugated stretches: rail, band, dominant wavelength, speed, frequency, mechanism.
    resonances : pandas.DataFrame
        P2, torsion and pinned–pinned frequencies per wheelset model / trackform.
    skipped : tuple of str
        Wheelset/model combinations not estimated and why (missing channels).
    processing : tuple of str
        The run's history followed by the estimate's steps.
    config : dict
    timings_s : dict
    """

    run_id: str
    source: str
    header: Mapping
    direction: str
    orientation: str
    leading: int
    fs: float
    duration_s: float
    masked_share: Mapping
    qc: pd.DataFrame
    odometry: pd.DataFrame
    dx_m: Mapping
    lambda_min_m: float
    band_hz: tuple
    wheelbase_m: float
    wheelbase_source: str
    circumference: Mapping
    profiles: Mapping
    indexes: pd.DataFrame
    spectra: pd.DataFrame
    corrugation: pd.DataFrame
    resonances: pd.DataFrame
    skipped: tuple = ()
    processing: tuple = ()
    config: Mapping = field(default_factory=dict)
    timings_s: Mapping = field(default_factory=dict)
    stretches: tuple = ()

    @property
    def models(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(m for _, m in self.profiles))

    @property
    def wheelsets(self) -> tuple[int, ...]:
        return tuple(sorted({w for w, _ in self.profiles}))

    def profile(self, wheelset: int, model: str) -> ProfileEstimate:
        try:
            return self.profiles[(wheelset, model)]
        except KeyError:
            raise KeyError(f"no estimate for wheelset {wheelset} with model {model!r}; have "
                           f"{sorted(self.profiles)}") from None

    def profiles_frame(self) -> pd.DataFrame:
        """All profiles as one long table (µm, one row per grid point, wheelset, model and rail)."""
        frames = []
        for (w, m), p in self.profiles.items():
            for i, rail in enumerate(p.rails):
                d = {"wheelset": w, "role": p.role, "model": m, "rail": rail, "chainage_m": p.chainage_m,
                     "roughness_um": p.rail[i] * 1e6, "irregularity_um": p.irregularity[i] * 1e6,
                     "speed_m_s": p.speed_m_s}
                for b, band in enumerate(p.indexes.bands_mm):
                    d[f"pk_pk_um_{band[0]:g}_{band[1]:g}"] = p.indexes.pk_pk[b, i] * 1e6
                frames.append(pd.DataFrame(d))
        return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()

    def wheel_orders(self) -> pd.DataFrame:
        frames = []
        for (w, m), p in self.profiles.items():
            o = p.wheel.orders.assign(wheelset=w, model=m)
            frames.append(o)
        if not frames:
            return pd.DataFrame()
        df = pd.concat(frames, ignore_index=True)
        df["amplitude_um"] = df["amplitude_m"] * 1e6
        df["floor_um"] = df["floor_m"] * 1e6
        return df[["wheelset", "model", "side", "order", "amplitude_um", "phase_rad", "floor_um", "significant"]]
