"""Identified (experimental) modes: the :class:`ModeSet` type.

A mode set holds the poles and complex mode shapes identified from measured
FRFs, with the quality indicators of each mode and the channel metadata that
places every shape component in space (node, position, measuring direction,
FE node). It is what ``ema`` returns from identification, what two setups
merge into, and what pairing compares with FE modes.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

__all__ = ["ModeSet", "SCALINGS"]

#: Allowed values of :attr:`ModeSet.scaling`.
SCALINGS: tuple[str, ...] = ("unit", "mass", "modal_constant")


@dataclass(frozen=True, eq=False)
class ModeSet:
    """Experimental modes.

    Parameters
    ----------
    freqs_hz : ndarray (m,)
        Undamped natural frequencies ``|s| / 2 pi`` [Hz].
    zeta : ndarray (m,)
        Damping ratios ``-Re(s) / |s|`` (after any exponential-window correction).
    shapes : ndarray complex (n_dof, m)
        Mode shapes at the measured DOFs (columns), scaled as residues of
        the driving-point-normalised form (see ``scaling``).
    dofs : tuple of str
        Label of each shape row (the FRF's output labels).
    channels : pandas.DataFrame
        One row per DOF: at least ``node, x, y, z, dx, dy, dz``; ``fe_node`` if known.
    mpc, mpd : ndarray (m,)
        Modal phase collinearity (0–1) and mean phase deviation [deg].
    setup : tuple of str
        Setup(s) each mode was identified in (``"flexural"``, ``"flexural+torsional"``...).
    scaling : str
        How shapes are scaled: ``"unit"`` (largest component 1), ``"mass"``
        (mass-normalised through the driving point) or ``"modal_constant"``
        (the modal constants ``A_jr`` of the receptance
        ``H_j = sum_r A_jr / (w_r^2 - w^2 + 2 i zeta_r w_r w)`` for the test's
        force point: ``A_jr = c_jr b_r``, response shape times force-point
        shape of the mass-normalised modes; see :mod:`ema.lsfd`).
    source : str
        Where the modes come from (file, method).
    history : tuple of str
    """

    freqs_hz: np.ndarray
    zeta: np.ndarray
    shapes: np.ndarray
    dofs: tuple[str, ...]
    channels: pd.DataFrame
    mpc: np.ndarray
    mpd: np.ndarray
    setup: tuple[str, ...]
    scaling: str = "unit"
    source: str = ""
    history: tuple[str, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        f = np.asarray(self.freqs_hz, float)
        m = f.size
        shapes = np.asarray(self.shapes, complex)
        if shapes.ndim != 2 or shapes.shape[1] != m:
            raise ValueError(f"shapes must be (n_dof, {m}) for {m} modes, got {shapes.shape}")
        if len(self.dofs) != shapes.shape[0]:
            raise ValueError(f"{len(self.dofs)} DOF labels for {shapes.shape[0]} shape rows")
        if len(self.channels) != shapes.shape[0]:
            raise ValueError(f"channels has {len(self.channels)} rows for {shapes.shape[0]} DOFs")
        for name in ("zeta", "mpc", "mpd"):
            if np.shape(getattr(self, name)) != (m,):
                raise ValueError(f"{name} must have shape ({m},), got {np.shape(getattr(self, name))}")
        if len(self.setup) != m:
            raise ValueError(f"setup must name {m} entries, got {len(self.setup)}")
        if self.scaling not in SCALINGS:
            raise ValueError(f"scaling must be one of {SCALINGS}, got {self.scaling!r}")
        object.__setattr__(self, "freqs_hz", f)
        object.__setattr__(self, "zeta", np.asarray(self.zeta, float))
        object.__setattr__(self, "shapes", shapes)
        object.__setattr__(self, "mpc", np.asarray(self.mpc, float))
        object.__setattr__(self, "mpd", np.asarray(self.mpd, float))
        object.__setattr__(self, "dofs", tuple(self.dofs))
        object.__setattr__(self, "setup", tuple(self.setup))

    def __len__(self) -> int:
        return self.freqs_hz.size

    @property
    def poles(self) -> np.ndarray:
        """Continuous-time poles ``s = -zeta w + i w sqrt(1 - zeta^2)`` [rad/s]."""
        w = 2 * np.pi * self.freqs_hz
        return -self.zeta * w + 1j * w * np.sqrt(1 - self.zeta**2)

    def to_frame(self) -> pd.DataFrame:
        """One row per mode: ``f_hz, zeta, mpc, mpd, setup``."""
        return pd.DataFrame(
            {"f_hz": self.freqs_hz, "zeta": self.zeta, "mpc": self.mpc, "mpd": self.mpd, "setup": list(self.setup)}
        )
