"""Time → space: a continuous chainage from the odometer, balise resets handled, and the spatial grid.

**Odometry.** The odometer integrates the encoder speed with the *nominal*
wheel radius and is reset to a balise's reference chainage at each passage
(field contract), so its position carries a scale error (worn wheel) and
jumps at balises. :func:`odometry_track` turns it into a continuous
chainage:

1. the jumps are removed, giving the raw travelled distance ``d(t)``;
2. each balise passage pins the chainage: right after the reset the
   odometer reads the balise's reference chainage plus the distance counted
   since the passage, an absolute chainage ``c_k`` at raw distance ``d_k``; between two passages the chainage is linear in
   ``d``: ``c_k + s_k (d − d_k)`` with ``s_k = (c_{k+1} − c_k)/(d_{k+1} − d_k)``
   (the scale error of that stretch, corrected retroactively); before the
   first and after the last passage the nearest stretch's scale is used
   (without any balise: the odometer as recorded). This removes the run's
   start offset and the scale error between balises. A run with fewer than
   two balise passages has no stretch to measure the scale on: it stays 1,
   and an ``odometry_scale`` finding (action ``uncorrected``) states the
   stretch and the chainage uncertainty it implies (``max_scale_error`` ×
   the distance from the balise, or from the run's start); the estimator
   then takes the scale from the lead/trail lag when the wheelbase is known
   (:func:`rescaled`);
3. a stretch whose implied scale error exceeds ``max_scale_error`` (an
   odometry fault, not wheel wear) is not trusted: it is **masked** and
   logged (chainages, the implied error), and kept at scale 1; so is a
   stretch holding a position jump that no balise event explains;
4. a stretch the speed or position channel does not cover (its time stamps
   jump: the logger lost samples) is interpolated across when it is shorter
   than :data:`MAX_ODOMETRY_GAP_S` (reported, ``corrected``) and masked
   otherwise: the chainage there is not measured.

The result also gives the signed speed along the run's direction of travel
(negative = reversing), from the speed channel times the stretch scale.

**Spatial step.** A run resolves wavelengths ``λ ≥ v/f_hi`` where it is fast
and ``λ ≤ v/f_lo`` where it is slow; the shortest wavelength a run resolves
is ``λ_min = v_slow / f_hi``, ``v_slow`` the slowest speed of the samples the
run keeps (never below the speed gate quality control applies: a
station-to-station run reaches the gate, a run recorded between stations
does not and gets a coarser grid). :func:`spatial_step` picks the largest step
of the 1–2–2.5–5 series not above ``λ_min / 3`` (three samples per shortest
wavelength: band-limited interpolation keeps the amplitude to < 0.1 dB, see
:mod:`estimator.inversion`).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field, replace

import numpy as np

from estimator.errors import OdometryError
from estimator.run import Odometry, QCEvent

__all__ = ["OdometryTrack", "odometry_track", "rescaled", "spatial_step", "nice_step"]

log = logging.getLogger("estimator")

#: a position step that the speed does not explain by more than this (plus 5 %) is a jump [m]
JUMP_TOLERANCE_M = 0.05
#: longest stretch without speed or position samples over which the chainage is interpolated [s]: a metro's
#: acceleration (braking up to about 1.5 m/s^2) bends the position by a T^2 / 8 from the straight line across a
#: gap of T seconds, 5 mm at 0.16 s, half the alignment's 10 mm budget; a longer gap is masked
MAX_ODOMETRY_GAP_S = 0.16


@dataclass(frozen=True, eq=False)
class OdometryTrack:
    """Continuous chainage of the odometry's reference point (the bogie centre) against time.

    Attributes
    ----------
    t : ndarray
        Odometry time stamps [s].
    chainage : ndarray
        Corrected chainage [m] (continuous, balise-pinned).
    speed : ndarray
        Speed along the direction of travel [m/s] (encoder speed × stretch scale; < 0 reversing).
    scale : ndarray
        Scale applied at each time (1 where no balise pins the odometer).
    resets : tuple of dict
        Per balise passage: ``t_s, balise_m, position_before_m, jump_m, scale_after, action``.
    events : tuple of QCEvent
        Findings (resets corrected, implausible stretches masked).
    travel_sign : int
        +1 travelling towards increasing chainage.
    scale_source : str
        What set ``scale``: ``"balises"`` (two or more passages), ``"odometer"`` (fewer: the odometer's own
        scale, uncorrected) or what :func:`rescaled` was given (the lead/trail lag over a known wheelbase).
    """

    t: np.ndarray
    chainage: np.ndarray
    speed: np.ndarray
    scale: np.ndarray
    resets: tuple[dict, ...]
    events: tuple[QCEvent, ...]
    travel_sign: int
    untrusted: tuple[tuple[float, float], ...] = field(default_factory=tuple)
    scale_source: str = "balises"

    def chainage_at(self, t) -> np.ndarray:
        """Chainage [m] at times ``t`` (linear between odometry samples: < 0.1 mm at 100 Hz and 1 m/s²)."""
        return np.interp(t, self.t, self.chainage)

    def speed_at(self, t) -> np.ndarray:
        return np.interp(t, self.t, self.speed)


def _median_step(t: np.ndarray) -> float:
    return float(np.median(np.diff(t))) if t.size > 1 else 0.0


def _resets(odo: Odometry, travel_sign: int, source: str) -> list[tuple[int, float, float]]:
    """(sample index just after the reset, balise time, reference chainage) for each balise event."""
    out = []
    for tb, cb in zip(odo.balise_t, odo.balise_chainage):
        j = int(np.searchsorted(odo.t, tb - 1e-9))
        if j >= odo.t.size:
            log.warning("%s: balise event at %.3f s after the last odometry sample; ignored", source, tb)
            continue
        out.append((j, float(tb), float(cb)))
    return out


def odometry_track(odo: Odometry, travel_sign: int, *, max_scale_error: float = 0.02,
                   source: str = "") -> OdometryTrack:
    """Continuous, balise-pinned chainage from a run's odometry (module docstring).

    Parameters
    ----------
    odo : Odometry
    travel_sign : {+1, -1}
        +1 when the run travels towards increasing chainage.
    max_scale_error : float
        Largest plausible odometer scale error between two balises (default 2 %:
        wheel wear and encoder slip give a few tenths of a per cent).
    source : str
        Named in messages.
    """
    t = odo.t
    pos = odo.position
    if t.size < 2 or not np.all(np.isfinite(t)):
        raise OdometryError(f"{source}: the odometry needs at least two finite time stamps")
    ok = np.isfinite(pos)
    if ok.sum() < 2:
        raise OdometryError(f"{source}: the position channel holds fewer than two finite values")
    if not ok.all():
        pos = np.interp(t, t[ok], pos[ok])  # NaN stretches are odometry gaps (odo.gaps): judged below
    speed = odo.speed
    ok = np.isfinite(speed)
    if ok.sum() < 2:
        raise OdometryError(f"{source}: the speed channel holds fewer than two finite values")
    if not ok.all():
        speed = np.interp(t, t[ok], speed[ok])  # likewise; a NaN speed would pass the jump test and the gate
    resets = _resets(odo, travel_sign, source)
    # 1. raw travelled distance: remove each reset jump (step minus the step the speed explains)
    d = pos.astype(float).copy()
    jumps = []
    step = np.diff(pos)
    # the speed at either end of a step bounds the distance travelled in it (whichever end a logger's odometer
    # integrates from, and across a gap in the channels); the trapezoid is the expected step
    v0, v1, dt = np.abs(speed[:-1]), np.abs(speed[1:]), np.diff(t)
    expected = travel_sign * 0.5 * (v0 + v1) * dt
    along, lo, hi = travel_sign * step, np.minimum(v0, v1) * dt, np.maximum(v0, v1) * dt
    excess = np.maximum(lo - along, along - hi) > JUMP_TOLERANCE_M + 0.05 * hi
    reset_idx = {j for j, _, _ in resets}
    for j, tb, cb in resets:
        if j == 0:
            jumps.append(0.0)
            continue
        jump = float(step[j - 1] - expected[j - 1])
        d[j:] -= jump
        jumps.append(jump)
    flagged = np.zeros(step.size, bool)
    flagged[np.flatnonzero(excess)] = True
    for j in reset_idx:
        if 0 < j <= step.size:
            flagged[j - 1] = False
    from estimator.qc import runs_of

    unexplained, inconsistent = [], []
    for a, b in runs_of(flagged):
        if b - a == 1:  # one step: a jump of the position no balise explains; removed from the distance
            unexplained.append(a + 1)
            d[a + 1:] -= step[a] - expected[a]
        else:  # several steps in a row: speed and position disagree (a glitch of either); not corrected
            inconsistent.append((a, b))
    # 2. pin the passages: right after a reset the odometer reads the balise's chainage plus the distance
    #    counted since the passage, so the sample after the reset is an absolute chainage
    events: list[QCEvent] = []
    anchors = []
    for (j, tb, cb), jump in zip(resets, jumps):
        # the reading a reset odometer shows: the balise's chainage plus the distance travelled since the passage.
        # A reading off by more than the jump tolerance means the unit did not reset (or reset elsewhere): the
        # balise is the absolute reference, so it pins the chainage, to the distance of one stamp interval
        since = abs(float(speed[j])) * max(float(t[j]) - tb, 0.0)
        reset_reading = cb + travel_sign * since
        off = float(pos[j]) - reset_reading
        pinned = float(pos[j])
        if abs(off) > JUMP_TOLERANCE_M + 0.05 * since + abs(float(speed[j])) * _median_step(t):
            pinned = reset_reading
            c = float(np.interp(tb, t, pos))
            events.append(QCEvent("odometry_not_reset", "*", tb, tb,
                                  f"balise at {cb:.2f} m: the odometer reads {float(pos[j]):.2f} m after the passage "
                                  f"({off:+.2f} m off; it did not reset): the chainage is pinned to the balise",
                                  "corrected", min(c, cb), max(c, cb)))
            log.warning("%s: %s", source, events[-1].describe())
        anchors.append((float(d[j]), pinned, float(t[j]), jump))
    anchors.sort(key=lambda a: a[2])
    untrusted: list[tuple[float, float]] = []
    for g0, g1, name in odo.gaps:
        c = np.interp([g0, g1], t, pos)
        long = g1 - g0 > MAX_ODOMETRY_GAP_S
        what = (f"the chainage there is not measured (longer than {MAX_ODOMETRY_GAP_S:g} s)" if long else
                f"interpolated across (a gap of at most {MAX_ODOMETRY_GAP_S:g} s bends the position by < 5 mm)")
        events.append(QCEvent("odometry_gap", "*", g0, g1, f"{name}: no sample for {g1 - g0:.3f} s; {what}",
                              "masked" if long else "corrected", float(c.min()), float(c.max())))
        if long:
            untrusted.append((g0, g1))
    for a, b in inconsistent:
        events.append(QCEvent("odometry_inconsistent", "*", float(t[a]), float(t[b]),
                              f"speed and position disagree over {b - a} odometry samples (max "
                              f"{np.max(np.abs(step[a:b] - expected[a:b])):.3f} m per sample)"
                              + _unit_ratio(expected[a:b], along[a:b]), "masked",
                              float(min(pos[a], pos[b])), float(max(pos[a], pos[b]))))
        untrusted.append((float(t[a]), float(t[b])))
    for j in unexplained:
        # a jump no balise explains: the odometer cannot be trusted between the anchors around it
        before = [a[2] for a in anchors if a[2] <= t[j]]
        after = [a[2] for a in anchors if a[2] > t[j]]
        t0, t1 = (before[-1] if before else float(t[0])), (after[0] if after else float(t[-1]))
        # the finding's chainage is the stretch it masks, not the jump's own metre or two
        span = pos[(t >= t0) & (t <= t1)]
        until = "until the next balise" if after else "to the end of the run"
        events.append(QCEvent("odometry_jump", "*", t0, t1,
                              f"odometer jump of {step[j - 1] - expected[j - 1]:+.3f} m at {t[j]:.2f} s without a "
                              f"balise event: odometry not trusted {until} (the jump at {float(pos[j - 1]):.2f} m)",
                              "masked",
                              float(min(span.min(), pos[j - 1])), float(max(span.max(), pos[j]))))
        untrusted.append((t0, t1))
    scales = []
    for k in range(len(anchors) - 1):
        (d0, c0, t0, _), (d1, c1, t1, _) = anchors[k], anchors[k + 1]
        s = (c1 - c0) / (d1 - d0) if d1 != d0 else math.nan
        if not (np.isfinite(s) and abs(s - 1) <= max_scale_error):
            events.append(QCEvent(
                "odometry_jump", "*", t0, t1,
                f"balise reset at {c1:.2f} m implies an odometer scale error of "
                f"{100 * (s - 1) if np.isfinite(s) else float('nan'):+.2f} % over {abs(c1 - c0):.1f} m, beyond "
                f"+/-{100 * max_scale_error:g} %: odometry not trusted on this stretch",
                "masked", min(c0, c1), max(c0, c1)))
            untrusted.append((t0, t1))
            s = 1.0
        scales.append(s)
    ch = np.empty_like(d)
    sc = np.ones_like(d)
    if not anchors:
        ch[:] = d
    else:
        ds = np.array([a[0] for a in anchors])
        cs = np.array([a[1] for a in anchors])
        ts = np.array([a[2] for a in anchors])
        k = np.clip(np.searchsorted(ts, t, side="right") - 1, 0, len(anchors) - 1)
        # stretch k runs from anchor k to k+1; before the first anchor use stretch 0, after the last the last one
        stretch = np.clip(k, 0, max(len(scales) - 1, 0))
        s_arr = np.array(scales if scales else [1.0])[stretch]
        before_first = t < ts[0]
        base = np.where(before_first, 0, k)
        ch[:] = cs[base] + s_arr * (d - ds[base])
        sc[:] = s_arr
    rs = []
    for (j, tb, cb), jump in zip(resets, jumps):
        rs.append({"t_s": tb, "balise_m": cb, "position_before_m": float(pos[j - 1]) if j else float("nan"),
                   "jump_m": jump, "action": "corrected"})
        events.append(QCEvent("odometry_reset", "*", tb, tb,
                              f"balise at {cb:.2f} m: odometer jump {jump:+.3f} m corrected "
                              f"(scale distributed over the stretch before)", "corrected", cb, cb))
    scale_source = "balises"
    if len(anchors) < 2:
        # nothing measures the odometer's scale (wheel wear, slip: a few tenths of a per cent, up to
        # max_scale_error): the chainage drifts from the one reference the run has by that share of the distance
        scale_source = "odometer"
        events.append(_scale_event(t, ch, rs, max_scale_error))
    speed = speed * sc
    moving = np.abs(speed) > 0.5
    if travel_sign < 0 and moving.any() and np.median(speed[moving]) < 0:
        speed = -speed  # a speed channel signed along chainage: make it positive along the direction of travel
    return OdometryTrack(t=t.copy(), chainage=ch, speed=speed, scale=sc, resets=tuple(rs), events=tuple(events),
                         travel_sign=int(travel_sign), untrusted=tuple(untrusted), scale_source=scale_source)


#: speed / position-rate ratios that are a unit mix-up, not a glitch
_UNIT_RATIOS = {3.6: "km/h read as m/s", 1 / 3.6: "m/s read as km/h", 1000.0: "mm/s read as m/s",
                1e-3: "m/s read as mm/s"}


def _unit_ratio(expected: np.ndarray, along: np.ndarray) -> str:
    """``"; ..."`` naming a unit mix-up when the speed's distance over a disagreeing stretch is a constant
    multiple of the position's (:data:`_UNIT_RATIOS`, within 3 %), else ``""``."""
    moving = np.abs(along) > 1e-6
    if moving.sum() < 10:
        return ""
    r = float(np.median(np.abs(expected[moving]) / np.abs(along[moving])))
    for ratio, what in _UNIT_RATIOS.items():
        if abs(r / ratio - 1) < 0.03:
            return (f"; the speed is {r:.4g} x the position's rate all along: {what}? (check the unit in the file "
                    "and the sensor table)")
    return ""


def _scale_reference(t: np.ndarray, chainage: np.ndarray, resets) -> tuple[float, float, str]:
    """(time, chainage, name) of the one point a run without two balises has its chainage right at: its balise,
    else its start (where the odometer's reading is taken as it is)."""
    if resets:
        tb, cb = float(resets[0]["t_s"]), float(resets[0]["balise_m"])
        return tb, cb, f"the balise at {cb:.2f} m"
    return float(t[0]), float(chainage[0]), f"the run's start ({float(chainage[0]):.2f} m, no balise)"


def _scale_event(t: np.ndarray, chainage: np.ndarray, resets, max_scale_error: float) -> QCEvent:
    """The finding of a run whose odometer scale no two balises correct (module docstring, step 2)."""
    _, c_ref, ref = _scale_reference(t, chainage, resets)
    far = float(np.max(np.abs(chainage - c_ref)))
    lo, hi = float(np.min(chainage)), float(np.max(chainage))
    return QCEvent("odometry_scale", "*", float(t[0]), float(t[-1]),
                   f"{len(resets)} balise passage(s): the odometer's scale error is not corrected over "
                   f"{lo:.1f}-{hi:.1f} m (scale kept at 1); the chainage is uncertain by up to +/-"
                   f"{100 * max_scale_error:g} % of the distance from {ref}, +/-{max_scale_error * far:.2f} m "
                   f"{far:.0f} m away (a worn wheel's 0.4 % is {0.004 * far:.2f} m there)", "uncorrected", lo, hi)


def rescaled(track: OdometryTrack, scale: float, source: str) -> OdometryTrack:
    """``track`` with the odometer scale ``scale`` where no two balises measured it (a new track).

    The chainage is stretched about the one point it is right at — the run's balise, else its start
    (:func:`_scale_reference`) — and the speed with it; the ``odometry_scale`` finding becomes ``corrected``
    and names ``source`` (e.g. the lead/trail lag over the drawing's wheelbase).

    Raises
    ------
    ValueError
        ``track``'s scale was set by balises (``scale_source`` not ``"odometer"``), or ``scale`` is not a
        positive number.
    """
    if track.scale_source != "odometer":
        raise ValueError(f"the odometer scale is already set by {track.scale_source}: not rescaled")
    if not (math.isfinite(scale) and scale > 0):
        raise ValueError(f"odometer scale must be a positive number, got {scale!r}")
    t_ref, c_ref, ref = _scale_reference(track.t, track.chainage, track.resets)
    c_at = float(track.chainage_at(t_ref))
    ch = c_at + scale * (track.chainage - c_at)
    event = QCEvent("odometry_scale", "*", float(track.t[0]), float(track.t[-1]),
                    f"{len(track.resets)} balise passage(s): odometer scale {scale:.5f} ({100 * (scale - 1):+.2f} %) "
                    f"from {source}, applied about {ref}", "corrected", float(np.min(ch)), float(np.max(ch)))
    events = tuple(e for e in track.events if e.kind != "odometry_scale") + (event,)
    return replace(track, chainage=ch, speed=track.speed * scale, scale=track.scale * scale, events=events,
                   scale_source=source)


_SERIES = (1.0, 2.0, 2.5, 5.0)



def nice_step(limit: float) -> float:
    """Largest value of the 1–2–2.5–5 × 10ⁿ series not above ``limit`` (> 0)."""
    if not (limit > 0 and math.isfinite(limit)):
        raise ValueError(f"step limit must be a positive number, got {limit!r}")
    e = math.floor(math.log10(limit))
    best = 0.0
    for k in (e - 1, e):
        for m in _SERIES:
            v = m * 10.0**k
            if v <= limit * (1 + 1e-12):
                best = max(best, v)
    return best


def spatial_step(slowest_m_s: float, f_hi_hz: float, samples_per_wavelength: float = 3.0) -> tuple[float, float]:
    """(spatial step [m], shortest resolved wavelength [m]) of a run whose slowest kept speed is ``slowest_m_s``
    and whose inversion band ends at ``f_hi_hz`` (module docstring)."""
    lam_min = slowest_m_s / f_hi_hz
    return nice_step(lam_min / samples_per_wavelength), lam_min
