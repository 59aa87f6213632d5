"""Where the wheel leaves the rail: the estimated dynamic contact force against the static wheel load.

The inversion's contact is a linearised Hertz spring (thesis §2.2, eqs. 2.5, 2.20): it pulls as well as it
pushes. A real contact only pushes. The dynamic normal force is estimated from the wheelset's own accelerations,
``F(t) = B⁺_α a(t)`` (eqs. 2.20–2.21; :attr:`estimator.inversion.WheelsetTransfer.P`, the same regularised
pseudo-inverse the transfer function ``T = D B⁺_α`` is made of). It does not depend on the track or on the
other wheelset. ``F > 0`` compresses the contact: its in-band part follows the irregularity, ``n = D F`` with
``D > 0`` below the wheelset's resonances.

Where ``F < −Q`` (``Q``, the static wheel load, ``ContactParameters.wheel_load_N``), the total force
``Q + F`` would be tensile. The wheel is off the rail there, a regime the linear model does not have, and the
roughness estimate there is not the rail's: while airborne the wheel does not follow the rail. Each such
stretch is a finding (kind ``contact_loss``, action ``flagged``) with wheelset, rail, time and chainage, and
the lowest ``F / Q``. It is not masked: the estimate around it is the best there is, and a corrugation severe
enough to lift the wheel is what an analyst must see first.

The force is band-limited to the inversion band, so it holds the corrugation's frequencies but not the slow
load transfer of curving and cant (a few Hz). On a curve's low rail it reads the dynamic part against the
nominal static load.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Mapping, Sequence

import numpy as np

from estimator.inversion import TimeIrregularity, WheelsetTransfer, invert
from estimator.qc import runs_of
from estimator.run import QCEvent

__all__ = ["CONTACT_LOSS_MERGE_S", "contact_force", "contact_loss_events"]

#: Lost stretches closer than this [s] are one event: at a corrugation's frequency the wheel touches down
#: briefly between bounces (the virtual line's truth counts one event per bounce the same way).
CONTACT_LOSS_MERGE_S = 0.05


def contact_force(acc: np.ndarray, t0: float, fs: float, valid: np.ndarray,
                  transfers: Sequence[WheelsetTransfer], weights: Sequence[np.ndarray] | None = None,
                  edge_s: float | None = None) -> TimeIrregularity:
    """The dynamic normal contact force per side [N] from one wheelset's accelerations: :func:`invert` with
    ``B⁺_α`` (``transfer.P``) in place of ``T`` (same stretches, edges and contact-angle blending).

    A half model's force is its side's SISO estimate: the other wheel's force moves this axlebox too and is read
    as this wheel's (about 85 % of it at 60 Hz on the control wheelset), so the vertical models are preferred.
    """
    forces = [replace(tr, T=tr.P) for tr in transfers]
    # read at the sample times only: no band-limited upsampling (a quarter of the inverse FFTs)
    return invert(acc, t0, fs, valid, forces, weights, edge_s, upsample=1)


def contact_loss_events(force: TimeIrregularity, t: np.ndarray, chainage: np.ndarray, wheel_load_n: float,
                        rail_of_side: Mapping[str, str], channel_of_side: Mapping[str, str],
                        merge_s: float = CONTACT_LOSS_MERGE_S) -> list[QCEvent]:
    """Stretches where the estimated dynamic force pulls harder than the static load holds (``F < −Q``).

    Parameters
    ----------
    force : TimeIrregularity
        From :func:`contact_force` (rows: vehicle sides).
    t, chainage : ndarray (n,)
        Sample times [s] and the wheelset's chainage at them [m].
    wheel_load_n : float
        Static wheel load ``Q`` [N].
    rail_of_side, channel_of_side : mapping
        Rail and vertical channel of each vehicle side (the finding names both).
    merge_s : float
        Lost stretches closer than this are one event.

    Returns
    -------
    list of QCEvent (kind ``contact_loss``, action ``flagged``)
    """
    if not wheel_load_n > 0:
        return []
    F = force.sample(t)
    gap = max(int(round(merge_s * force.fs)), 0)
    out = []
    for k, side in enumerate(force.sides):
        with np.errstate(invalid="ignore"):
            lost = F[k] < -wheel_load_n
        for a, b in runs_of(lost, max_gap=gap):
            low = float(np.nanmin(F[k, a:b])) / wheel_load_n
            x0, x1 = sorted((float(chainage[a]), float(chainage[b - 1])))
            out.append(QCEvent(
                "contact_loss", channel_of_side.get(side, side), float(t[a]), float(t[b - 1]),
                f"wheelset {force.wheelset}, rail {rail_of_side[side]}: the estimated dynamic contact force "
                f"({force.kind} model) reaches {low:.2f} x the static wheel load {wheel_load_n / 1e3:.1f} kN: the "
                f"wheel leaves the rail, which the inversion's linear contact does not model; the roughness "
                f"estimate here is not the rail's", "flagged", x0, x1))
    return out
