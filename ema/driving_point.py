"""The driving point's sign: a hammer or an accelerometer read with the wrong sign, found without an FE.

At a driving point (an accelerometer at the hammer's node, measuring along the hammer's line) every mode's modal
constant is a square: ``A_kr = (φ_r·d_s)(φ_r·d_f)`` with ``d_s = ±d_f`` is ``±(φ_r·d_f)²`` (thesis eqs. 2.24–2.29,
the mass-normalised shape at the sensor times the shape at the force point). So the accelerance of a driving point
is ``+i A/(2ζ)`` at each resonance, with ``A > 0`` for a sensor that measures in the hammer's direction: a
classic check of a hammer test (Ewins, *Modal testing*, the checks of a point FRF). A force channel with a
negative sensitivity, or a hammer or sensor direction reversed in the channel table, turns every one of them the
other way. The MAC with an
FE shape cannot see that (it is blind to a shape's sign), and the hybrid model then adds the measured modes with
the wrong sign.

:func:`driving_point_checks` takes the identified modal constants (``ema.identify``'s default scaling) of each
channel at the force row's node whose direction is within :data:`MAX_ANGLE_DEG` of the hammer's line. With the
directions at an angle ``θ`` the constants are ``(φ·d_s)(φ·d_f)``, no longer a square, and a mode moving mostly
across the hammer's line may come out of either sign; so the verdict pools the modes by weight (``|Re A_kr|``):
``reversed`` when at least :data:`MIN_WRONG_SHARE` of the weight has the wrong sign, over at least
:data:`MIN_MODES` modes; ``consistent`` when at most ``1 - MIN_WRONG_SHARE``; ``mixed`` in between (the sensor is
not where the hammer hits, or the modes are too close for the identification).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from .modeset import ModeSet

__all__ = ["DrivingPointCheck", "driving_point_checks", "driving_point_findings", "MAX_ANGLE_DEG",
           "MIN_WRONG_SHARE", "MIN_MODES"]

#: a sensor at the force node within this angle of the hammer's line (either sense) is a driving point
MAX_ANGLE_DEG = 30.0
#: share of the modes' weight of the wrong sign that makes a driving point reversed
MIN_WRONG_SHARE = 0.8
#: fewest modes for a verdict
MIN_MODES = 2


@dataclass(frozen=True)
class DrivingPointCheck:
    """The sign of one driving point's modal constants.

    Attributes
    ----------
    channel : str
        The accelerometer's output label.
    node : int
        The node it shares with the force.
    angle_deg : float
        Angle between its measuring direction and the hammer's line (0 to 90°).
    expected_sign : int
        ``+1`` when it measures in the hammer's direction, ``-1`` against it.
    n_modes : int
        Modes with a finite modal constant at the channel.
    n_wrong : int
        Of those, the modes whose constant has the sign opposite to ``expected_sign``.
    wrong_share : float
        Their share of the weight ``Σ |Re A_kr|`` (NaN when every constant is zero).
    wrong_hz : tuple of float
        The frequencies of the wrong-sign modes.
    """

    channel: str
    node: int
    angle_deg: float
    expected_sign: int
    n_modes: int
    n_wrong: int
    wrong_share: float
    wrong_hz: tuple[float, ...]

    @property
    def verdict(self) -> str:
        """``"reversed"``, ``"consistent"``, ``"mixed"`` or ``"too few modes"`` (module docstring)."""
        if self.n_modes < MIN_MODES or not np.isfinite(self.wrong_share):
            return "too few modes"
        if self.wrong_share >= MIN_WRONG_SHARE:
            return "reversed"
        if self.wrong_share <= 1.0 - MIN_WRONG_SHARE:
            return "consistent"
        return "mixed"


def _unit(v: np.ndarray) -> np.ndarray | None:
    n = float(np.linalg.norm(v))
    return v / n if np.all(np.isfinite(v)) and n > 0 else None


def driving_point_checks(modes: ModeSet, table: pd.DataFrame) -> tuple[DrivingPointCheck, ...]:
    """Check the sign of the modal constants at every driving point of a setup (module docstring).

    Parameters
    ----------
    modes : ModeSet
        One setup's identified modes, scaled as modal constants (``ema.identify``'s default).
    table : DataFrame
        The setup's channel table with its force row (``node, quantity, dx, dy, dz``).

    Returns
    -------
    tuple of DrivingPointCheck
        One per driving point; empty when the modes are not modal constants, the table has no force row with a
        direction, or no accelerometer shares the force's node within :data:`MAX_ANGLE_DEG` of its line.
    """
    force = table[table["quantity"] == "force"] if "quantity" in table else table.iloc[:0]
    if modes.scaling != "modal_constant" or force.empty or len(modes) == 0:
        return ()
    f = force.iloc[0]
    d_f = _unit(np.array([f.get("dx", np.nan), f.get("dy", np.nan), f.get("dz", np.nan)], float))
    if d_f is None:
        return ()
    ch = modes.channels.reset_index(drop=True)
    out = []
    for k, row in ch.iterrows():
        if not (np.isfinite(row.get("node", np.nan)) and int(row["node"]) == int(f["node"])):
            continue
        d_s = _unit(np.array([row.get("dx", np.nan), row.get("dy", np.nan), row.get("dz", np.nan)], float))
        if d_s is None:
            continue
        cos = float(d_s @ d_f)
        angle = float(np.degrees(np.arccos(min(1.0, abs(cos)))))
        if angle > MAX_ANGLE_DEG:
            continue
        expected = 1 if cos > 0 else -1
        a = np.real(np.asarray(modes.shapes[k], complex))
        ok = np.isfinite(a)
        wrong = ok & (expected * a < 0)
        total = float(np.abs(a[ok]).sum())
        share = float(np.abs(a[wrong]).sum()) / total if total > 0 else float("nan")
        out.append(DrivingPointCheck(str(modes.dofs[k]), int(row["node"]), angle, expected, int(ok.sum()),
                                     int(wrong.sum()), share, tuple(float(x) for x in modes.freqs_hz[wrong])))
    return tuple(out)


def driving_point_findings(checks: tuple[DrivingPointCheck, ...], *, source: str = "") -> list[str]:
    """One sentence per driving point whose modal constants are reversed or of mixed sign (empty when none)."""
    where = f"{source}: " if source else ""
    out = []
    for c in checks:
        head = (f"{where}channel {c.channel!r} at the hammer's node {c.node} ({c.angle_deg:.0f}° from its line, "
                f"measuring {'with' if c.expected_sign > 0 else 'against'} it) is a driving point, whose modal "
                f"constants must all be {'positive' if c.expected_sign > 0 else 'negative'} (squares of the shape at "
                f"the force point): ")
        if c.verdict == "reversed":
            out.append(head + f"{c.n_wrong} of {c.n_modes} modes ({100 * c.wrong_share:.0f} % of their weight) have "
                              f"the other sign. The force or this accelerometer is read with the wrong sign: a "
                              f"negative sensitivity, or the hammer's or the sensor's direction reversed in the "
                              f"channel table. Every identified shape carries that sign: the MAC pairing does not "
                              f"see it, a hybrid model would add the modes reversed")
        elif c.verdict == "mixed":
            hz = ", ".join(f"{x:.1f}" for x in c.wrong_hz)
            out.append(head + f"{c.n_wrong} of {c.n_modes} modes ({100 * c.wrong_share:.0f} % of their weight; "
                              f"{hz} Hz) have the other sign. Check that the accelerometer sits where the hammer "
                              f"hits and along its line, and the modes at those frequencies")
    return out
