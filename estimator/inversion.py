"""Axlebox accelerations → irregularity at each wheel, through receptance's transfer functions (thesis §2.2).

**Transfer functions.** For each wheelset and each model (half wheelset,
full vertical, full vertical + lateral; thesis eqs. 2.6, 2.11, 2.22) the
dynamic compliance ``D = Nᵀ(A_W + A_R)N + diag(1/K_H)`` and the force-to-
acceleration matrix ``B = −Ω² A_B N`` come from :mod:`receptance.transfer`
with the run's *sensors* as the measured DOFs: each accelerometer is a point
rigidly attached to its axlebox node at its mounting point from the sensor
table (:func:`sensor_model`), so an accelerometer off the axlebox centre is
modelled where it is (thesis §4.3.5).

**Regularisation (Tikhonov).** ``T = D B⁺_α`` with, per frequency,
``B = U S Vᴴ`` and ``B⁺_α = V diag(s_k / (s_k² + α² s_ref²)) Uᴴ``. The
reference ``s_ref`` is the largest singular value of ``B`` smoothed over one
third of an octave (RMS over ±1/6 octave): a direction of ``B`` weaker than
``α`` times its neighbourhood's strength is damped — a nearly dependent pair
of channels (``s_min ≪ s_max``) as well as a narrow antiresonance of the
contact-to-axlebox receptance where every singular value dips (the
half-wheelset model's only failure mode, which a per-frequency reference
would never see). ``α`` is the relative uncertainty of the data: the
accelerometers' calibration (±2 %) and mounting make the measured
accelerations uncertain at the per-cent level, so directions below
``α = 0.02`` of ``s_ref`` carry no information (discrepancy principle).
The condition number ``s_max/s_min`` and the smallest filter factor
``s_k²/(s_k² + α² s_ref²)`` are reported per frequency and per band.

**Band.** The inversion is band-limited to ``[f_lo, f_hi]`` — below ``f_lo``
the bogie and carbody (not in the model) move the axlebox, above ``f_hi``
the DAQ's anti-aliasing filter — with raised-cosine tapers a third of an
octave below ``f_lo`` and a sixth above ``f_hi``.

**Speed varying along the run.** The wheelset–track system is
time-invariant (the model has no speed in it), so the irregularity *as a
function of time* at each wheel is ``n(t) = T * a(t)``, whatever the speed:
the inversion is one frequency-domain deconvolution of each valid stretch
of the run; speed enters only when ``n(t)`` is mapped to chainage. This is
the wavenumber form ``f = v/λ`` applied exactly: a wavelength ``λ`` passing
at speed ``v(x)`` is inverted with ``T(v(x)/λ)``. Valid stretches are the
runs of samples no quality-control finding masks; each is inverted on its
own (nothing is interpolated over a gap) and ``edge_s`` at both ends — the
duration holding 99.9 % of the inverse filter's impulse-response energy —
is dropped (at most 1 s: the longest tails, from lightly damped
antiresonances, hold less than 0.1 % of the energy beyond it). Validity is
per estimated side: a side needs only the channels its row of ``T`` (and of
the coupling term) reads. The half model's sides are SISO, so a channel
masked on part of the run leaves the other side's estimate whole there
(its samples enter as zeros, and its own side is dropped ``edge_s`` beyond
the gap); a vertical model mixes both sides and loses both.

**Contact angles along the run** (vertical + lateral model): ``T`` depends on
``θ_L, θ_R``. The run is inverted with the tangent-track angles and with each
curve's body angles, and the outputs are blended with the curve's ramp
(linear along the transitions): the angles change over tens of metres, the
inverse filter's memory is a fraction of a second.

**Time → chainage.** The inverted signals are upsampled ×4 in the frequency
domain (exact for band-limited signals) and read at the times the wheel
passes each point of the spatial grid with 4-point cubic (Lagrange)
interpolation: at ≤ 0.1 of the upsampled rate this keeps the amplitude to
< 0.01 dB.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field, replace
from typing import Sequence

import numpy as np
import pandas as pd
from scipy import fft as sfft

from ema.frf import FrequencyResponse
from estimator.errors import ChannelError, ConfigurationError, SensorTableError, WheelsetModelError
from receptance.dofs import DofError, Point
from receptance.frame import check_railway_frame
from receptance.transfer import full_vertical_transfer, half_wheelset_transfer, vertical_lateral_transfer

__all__ = ["WheelsetTransfer", "sensor_model", "check_wheelset_geometry", "check_sensor_mounting",
           "AXLEBOX_SPACING_RANGE_M", "ROLLING_RADIUS_RANGE_M", "SENSOR_AXLEBOX_TOLERANCE_M", "model_channels",
           "regularised_inverse", "tikhonov_inverse",
           "band_window",
           "wheelset_transfer", "TimeIrregularity", "invert", "cubic_sample", "sample_many", "UPSAMPLE",
           "condition_by_band", "rail_coupling", "side_dependence", "side_validity", "side_valid_time"]

log = logging.getLogger("estimator")

#: upsampling of the inverted signals before they are read at the grid's times
UPSAMPLE = 4
#: share of the inverse filter's impulse-response energy inside the edge dropped at each end of a stretch
EDGE_ENERGY = 0.999
#: bounds of that edge [s] (lightly damped antiresonances give long tails; beyond 1 s they hold < 0.1 %)
EDGE_BOUNDS_S = (0.05, 1.0)
_AXIS = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}

#: Distance between the two axlebox centres of a railway wheelset [m]: about 2.0 m on standard gauge (1435 mm gauge,
#: journals outside the wheels), 1.4-1.6 m on metre-gauge trams with inside bearings, up to ~2.5-2.8 m on broad
#: gauge; outside 1-3.5 m the points are not a wheelset's in metres.
AXLEBOX_SPACING_RANGE_M = (1.0, 3.5)
#: Distance of a contact point from the axle's axis (the rolling radius) [m]: tram and metro wheels are 0.3-0.45 m,
#: mainline up to ~0.6 m, small-wheeled low-floor vehicles ~0.15-0.3 m; outside 0.15-1.0 m it is no railway wheel
#: in metres.
ROLLING_RADIUS_RANGE_M = (0.15, 1.0)
#: An accelerometer on an axlebox housing sits within this distance [m] of the axlebox centre: the housing's own
#: size (a bearing of ~0.25-0.3 m outer diameter in a housing ~0.4-0.5 m long), with sensors on its top, front or
#: end cover. A mounting point further from its side's axlebox is not on that axlebox (x and y swapped, a sensor
#: near the axle's middle).
SENSOR_AXLEBOX_TOLERANCE_M = 0.3
_LENGTH_UNITS = ((1e-3, "mm"), (1e-2, "cm"), (0.0254, "inches"), (1e3, "km"))


def _unit_hint(value_m: float, lo: float, hi: float) -> str:
    """`` (likely mm: 0.41 m)`` when a length read in another unit falls into ``[lo, hi]``, else empty."""
    for f, u in _LENGTH_UNITS:
        if lo <= value_m * f <= hi:
            return f" (likely in {u}: {value_m * f:.4g} m)"
    return ""


def _wheelset_points(model, what: str):
    pts = getattr(model, "points", {})
    missing = [p for p in ("axlebox_L", "axlebox_R", "contact_L", "contact_R") if p not in pts]
    if missing:
        raise WheelsetModelError(f"{what} lacks point(s) {missing}; a field estimate needs the contact points and "
                                 f"axleboxes (points.csv of the lab: contact_L, axlebox_L, contact_R, axlebox_R); it "
                                 f"has {sorted(pts)}")
    no_xyz = [p for p in ("axlebox_L", "axlebox_R", "contact_L", "contact_R") if pts[p].xyz is None]
    if no_xyz:
        raise WheelsetModelError(f"{what}: point(s) {no_xyz} need coordinates (x, y, z) to place the accelerometers "
                                 "and the contacts")
    return pts


def check_wheelset_geometry(model, what: str = "the wheelset model") -> dict[str, float]:
    """Refuse a model whose geometry is not a railway wheelset's in metres; returns what was measured.

    From the model's points: the axlebox spacing (within :data:`AXLEBOX_SPACING_RANGE_M`) and each contact point's
    distance from the axle's axis, the line through the two axleboxes (the rolling radius, within
    :data:`ROLLING_RADIUS_RANGE_M`); and each of those points' FE node within a quarter of the axlebox spacing of
    the point (the FE coordinates in the points' unit: a model whose node coordinates are in mm while its points
    are in m places every sensor metres off its node).

    Raises
    ------
    WheelsetModelError
        Naming ``what``, the value found, the range and the likely unit.
    """
    pts = _wheelset_points(model, what)
    axl, axr = (np.asarray(pts[n].xyz, float) for n in ("axlebox_L", "axlebox_R"))
    spacing = float(np.linalg.norm(axr - axl))
    lo, hi = AXLEBOX_SPACING_RANGE_M
    if not lo <= spacing <= hi:
        raise WheelsetModelError(f"{what}: the axleboxes are {spacing:.4g} m apart (axlebox_L {tuple(axl)}, "
                                 f"axlebox_R {tuple(axr)}); a railway wheelset's are {lo:g}-{hi:g} m apart"
                                 f"{_unit_hint(spacing, lo, hi)}; the model's coordinates must be in metres")
    u = (axr - axl) / spacing
    out = {"axlebox_spacing_m": spacing}
    lo, hi = ROLLING_RADIUS_RANGE_M
    for n in ("contact_L", "contact_R"):
        c = np.asarray(pts[n].xyz, float) - axl
        r = float(np.linalg.norm(c - (c @ u) * u))
        if not lo <= r <= hi:
            raise WheelsetModelError(f"{what}: point {n} {tuple(pts[n].xyz)} is {r:.4g} m from the axle's axis (the "
                                     f"line through the axleboxes): a rolling radius of {r:.4g} m, while railway "
                                     f"wheels have {lo:g}-{hi:g} m{_unit_hint(r, lo, hi)}; the model's coordinates "
                                     "must be in metres")
        out[f"rolling_radius_{n[-1]}_m"] = r
    fe = getattr(model, "fe", None)
    if fe is not None and getattr(fe, "node_ids", None) is not None:
        ids = np.asarray(fe.node_ids)
        xyz = np.asarray(fe.xyz, float)
        for n in ("axlebox_L", "axlebox_R", "contact_L", "contact_R"):
            node = pts[n].fe_node
            if node is None:
                continue
            k = np.flatnonzero(ids == node)
            if not k.size:
                continue  # (the model's own checks name a missing node)
            d = float(np.linalg.norm(xyz[k[0]] - np.asarray(pts[n].xyz, float)))
            if d > 0.25 * spacing:
                ratio = float(np.linalg.norm(xyz[k[0]])) / max(float(np.linalg.norm(pts[n].xyz)), 1e-9)
                unit = next((f"; the FE node coordinates look like {un} ({ratio:.3g} times the point's)"
                             for f, un in _LENGTH_UNITS if abs(ratio * f - 1) < 0.2), "")
                raise WheelsetModelError(f"{what}: point {n} {tuple(pts[n].xyz)} m is {d:.4g} m from its FE node "
                                         f"{node} at {tuple(float(v) for v in xyz[k[0]])} (more than a quarter of "
                                         f"the {spacing:.3g} m axlebox spacing){unit}; the FE coordinates "
                                         f"({getattr(fe, 'units', '') or 'units not stated'}) and the points must be "
                                         "in metres")
    return out


def check_sensor_mounting(model, channels: pd.DataFrame, source: str = "<sensor table>") -> None:
    """Refuse an accelerometer row whose mounting point is not on its side's axlebox.

    The sensor table's ``x, y, z`` are relative to the wheelset's centre (the midpoint of the model's axleboxes);
    each acceleration row must lie within :data:`SENSOR_AXLEBOX_TOLERANCE_M` of its side's axlebox (``axlebox_L``
    or ``axlebox_R``, relative to that centre). Rows are numbered as in the file (header = row 1).

    Raises
    ------
    SensorTableError
        Naming the row, the mounting point, the axlebox and the likely slip (x and y swapped).
    """
    pts = _wheelset_points(model, "the wheelset model")
    centre = 0.5 * (np.asarray(pts["axlebox_L"].xyz, float) + np.asarray(pts["axlebox_R"].xyz, float))
    box = {s: np.asarray(pts[f"axlebox_{s}"].xyz, float) - centre for s in "LR"}
    tol = SENSOR_AXLEBOX_TOLERANCE_M
    for i in range(len(channels)):
        r = channels.iloc[i]
        if r["quantity"] != "acceleration":
            continue
        p = np.array([r["x"], r["y"], r["z"]], float)
        side = str(r["side"])
        d = float(np.linalg.norm(p - box[side]))
        if d <= tol:
            continue
        # (the other side's axlebox and mm are refused by check_sensors already: y's sign, 3 m)
        hint = "; x and y swapped?" if float(np.linalg.norm(p[[1, 0, 2]] - box[side])) <= tol else ""
        b = box[side]
        raise SensorTableError(f"{source}: row {i + 2} ({r['name']!r}, side {side}): mounting point ({p[0]:g}, "
                               f"{p[1]:g}, {p[2]:g}) m is {d:.3g} m from the model's side-{side} axlebox at "
                               f"({b[0]:.3g}, {b[1]:.3g}, {b[2]:.3g}) m (x, y, z relative to the wheelset centre); an "
                               f"axlebox accelerometer sits within {tol:g} m of it{hint}")


def sensor_model(model, channels: pd.DataFrame):
    """The model with one point per accelerometer of ``channels`` and the DOF label of each channel.

    Each sensor is a point attached to the FE node of its side's axlebox
    point (``axlebox_L``/``axlebox_R`` of the model), at the wheelset centre
    (midpoint of the two axlebox points) plus the sensor table's mounting
    offset ``(x, y, z)``, vehicle frame = model frame (x forward, left wheel at
    −y, z up: DESIGN.md).

    Returns
    -------
    model, labels : ModalModel, list of str
        ``labels[i]`` is ``"<channel name>:<direction>"``.
    """
    pts = _wheelset_points(model, "the wheelset model")
    axl, axr = pts["axlebox_L"], pts["axlebox_R"]
    try:  # the sensor table's x, y, z and the DOFs "...:z" are in the railway frame (DESIGN.md): so must the model be
        check_railway_frame(pts, getattr(model, "fe", None), what="the wheelset model")
    except DofError as exc:
        raise WheelsetModelError(str(exc)) from None
    # and in metres, the size of a railway wheelset (a model in mm inverts to roughness in metres)
    check_wheelset_geometry(model)
    centre = 0.5 * (np.asarray(axl.xyz) + np.asarray(axr.xyz))
    new, labels = [], []
    for _, r in channels.iterrows():
        host = axl if r["side"] == "L" else axr
        xyz = centre + np.array([r["x"], r["y"], r["z"]], float)
        new.append(Point(str(r["name"]), host.fe_node, tuple(xyz)))
        labels.append(f"{r['name']}:{r['direction']}")
    return model.with_points(new), labels


def model_channels(kind: str, channels: pd.DataFrame) -> tuple[list[int], tuple[str, ...]]:
    """Rows of ``channels`` (one wheelset's sensors) a model uses, and the vehicle sides it estimates.

    half: the vertical channel of each side present (one SISO model per side);
    vertical: both vertical channels; vertical_lateral: both vertical and every
    lateral channel.
    """
    vert = {s: channels.index[(channels["direction"] == "z") & (channels["side"] == s)].tolist() for s in "LR"}
    lat = channels.index[channels["direction"] == "y"].tolist()
    for s in "LR":
        if len(vert[s]) > 1:
            raise ChannelError(f"wheelset {channels['wheelset'].iloc[0]}: {len(vert[s])} vertical channels on side {s} "
                               f"({list(channels.loc[vert[s], 'name'])}); the models use one per axlebox")
    if kind == "half":
        rows = [vert[s][0] for s in "LR" if vert[s]]
        sides = tuple(s for s in "LR" if vert[s])
        if not rows:
            raise ChannelError("the half model needs a vertical axlebox channel")
        return rows, sides
    if not (vert["L"] and vert["R"]):
        raise ChannelError(f"the {kind!r} model needs both vertical axlebox channels (L and R)")
    rows = [vert["L"][0], vert["R"][0]]
    if kind == "vertical_lateral":
        if not lat:
            raise ChannelError("the vertical_lateral model needs a lateral (y) channel")
        rows += lat
    return rows, ("L", "R")


def _log_smooth_rms(f: np.ndarray, v: np.ndarray, half_octaves: float = 1 / 6) -> np.ndarray:
    """RMS of ``v`` over ``[f 2^-h, f 2^h]`` on an evenly spaced axis ``f`` (cumulative sums)."""
    c = np.concatenate([[0.0], np.cumsum(v * v)])
    lo = np.searchsorted(f, f * 2.0**-half_octaves, side="left")
    hi = np.searchsorted(f, f * 2.0**half_octaves, side="right")
    n = np.maximum(hi - lo, 1)
    return np.sqrt((c[hi] - c[lo]) / n)


def tikhonov_inverse(B: np.ndarray, f: np.ndarray, alpha: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``B⁺_α``, the Tikhonov-regularised pseudo-inverse of ``B`` with its reference smoothed over a third of an
    octave (module docstring); it holds the wheelset and sensors only, so :func:`regularised_inverse`'s ``T``
    for any ``D`` is ``D B⁺_α``.

    Parameters
    ----------
    B : ndarray (n_f, m, k)
    f : ndarray (n_f,) evenly spaced [Hz]
    alpha : float

    Returns
    -------
    pinv : ndarray (n_f, k, m)
        ``B⁺_α``, the contact forces per unit acceleration (0 where not finite).
    condition : ndarray (n_f,)
        ``s_max/s_min`` of ``B``.
    filter_min : ndarray (n_f,)
        Smallest Tikhonov filter factor (1 = untouched).
    """
    k = B.shape[2]
    Bh = np.conj(np.swapaxes(B, 1, 2))
    G = Bh @ B  # (n_f, k, k) Hermitian; its eigenvalues are the squared singular values of B
    if k == 1:
        ev = G[:, :, 0].real
    elif k == 2:
        a, d, b = G[:, 0, 0].real, G[:, 1, 1].real, G[:, 0, 1]
        half_tr = 0.5 * (a + d)
        disc = np.sqrt(np.maximum(0.25 * (a - d) ** 2 + np.abs(b) ** 2, 0.0))
        ev = np.stack([half_tr + disc, np.maximum(half_tr - disc, 0.0)], axis=1)
    else:
        ev = np.linalg.eigvalsh(G)[:, ::-1]
    s_max = np.sqrt(np.maximum(ev[:, 0], 0.0))
    s_ref = _log_smooth_rms(f, s_max)
    lam2 = (alpha * s_ref) ** 2
    # Tikhonov in closed form: B⁺_α = (BᴴB + λ² I)⁻¹ Bᴴ (the SVD filter of the docstring, without an SVD)
    A = G + lam2[:, None, None] * np.eye(k)[None]
    with np.errstate(divide="ignore", invalid="ignore"):
        if k == 1:
            pinv = Bh / A
        elif k == 2:
            det = A[:, 0, 0] * A[:, 1, 1] - A[:, 0, 1] * A[:, 1, 0]
            inv = np.empty_like(A)
            inv[:, 0, 0], inv[:, 1, 1] = A[:, 1, 1] / det, A[:, 0, 0] / det
            inv[:, 0, 1], inv[:, 1, 0] = -A[:, 0, 1] / det, -A[:, 1, 0] / det
            pinv = inv @ Bh
        else:
            pinv = np.linalg.solve(A, Bh)
        ev_min = np.maximum(ev[:, -1], 0.0)
        cond = np.sqrt(ev[:, 0] / ev_min)
        factor = ev_min / (ev_min + lam2)
    return np.where(np.isfinite(pinv), pinv, 0.0), cond, np.nan_to_num(factor, nan=0.0)


def regularised_inverse(D: np.ndarray, B: np.ndarray, f: np.ndarray, alpha: float, *, with_inverse: bool = False
                        ) -> tuple[np.ndarray, ...]:
    """``T = D B⁺_α`` with the Tikhonov reference smoothed over a third of an octave (module docstring).

    Parameters
    ----------
    D : ndarray (n_f, k, k)
    B : ndarray (n_f, m, k)
    f : ndarray (n_f,) evenly spaced [Hz]
    alpha : float

    Returns
    -------
    T : ndarray (n_f, k, m)
    condition, filter_min : ndarray (n_f,)
        As :func:`tikhonov_inverse`.
    pinv : ndarray (n_f, k, m)
        Only with ``with_inverse``: ``B⁺_α`` (:func:`tikhonov_inverse`), the contact forces per unit acceleration.
    """
    pinv, cond, factor = tikhonov_inverse(B, f, alpha)
    if with_inverse:
        return D @ pinv, cond, factor, pinv
    return D @ pinv, cond, factor


def band_window(f: np.ndarray, f_lo: float, f_hi: float, f_nyq: float) -> np.ndarray:
    """1 on ``[f_lo, f_hi]``, raised-cosine tapers over a third of an octave below and a sixth above."""
    w = np.zeros_like(f, dtype=float)
    a = f_lo * 2.0 ** (-1 / 3)
    b = min(f_hi * 2.0 ** (1 / 6), f_nyq)
    w[(f >= f_lo) & (f <= f_hi)] = 1.0
    lo = (f > a) & (f < f_lo)
    w[lo] = 0.5 - 0.5 * np.cos(np.pi * (f[lo] - a) / (f_lo - a))
    if b > f_hi:
        hi = (f > f_hi) & (f < b)
        w[hi] = 0.5 + 0.5 * np.cos(np.pi * (f[hi] - f_hi) / (b - f_hi))
    return w


@dataclass(frozen=True, eq=False)
class WheelsetTransfer:
    """One wheelset's regularised, band-limited transfer function for one model and one pair of angles.

    ``T`` (n_f, n_sides, n_channels) maps the acceleration spectra of
    ``channels`` (run channel names) to the irregularity at the wheels of
    ``sides`` (vehicle sides). For the half model ``T`` is diagonal (one SISO
    model per side).
    """

    kind: str
    wheelset: int
    channels: tuple[str, ...]
    sides: tuple[str, ...]
    freqs_hz: np.ndarray
    T: np.ndarray
    condition: np.ndarray
    filter_min: np.ndarray
    theta: tuple[float, float]
    band_hz: tuple[float, float]
    edge_s: float
    alpha: float
    history: tuple[str, ...] = field(default_factory=tuple)
    #: ``B⁺_α`` band-limited (n_f, n_sides, n_channels): contact forces along the contact normals per unit
    #: acceleration, for the rail coupling of the two wheelsets (:func:`rail_coupling`)
    P: np.ndarray | None = None

    def as_frequency_response(self) -> FrequencyResponse:
        """``T`` as the toolkit's frequency-response type (quantity ``transfer``)."""
        f = self.freqs_hz
        keep = f > 0
        return FrequencyResponse(freqs_hz=f[keep], data=np.moveaxis(self.T[keep], 0, 2),
                                 outputs=tuple(f"irr_{s}" for s in self.sides), inputs=self.channels,
                                 quantity="transfer", units="m/(m/s^2)", history=self.history)


def _edge_seconds(T: np.ndarray, df: float, fs_grid: float) -> float:
    """Half-width [s] holding 99.9 % of the energy of the impulse responses of ``T`` (both time directions)."""
    h = sfft.irfft(T.reshape(T.shape[0], -1), axis=0)
    e = (np.abs(h) ** 2).sum(axis=1)
    n = e.size
    lag = np.minimum(np.arange(n), n - np.arange(n)) / fs_grid
    order = np.argsort(lag, kind="stable")
    cum = np.cumsum(e[order])
    if cum[-1] <= 0:
        return 0.05
    k = int(np.searchsorted(cum, EDGE_ENERGY * cum[-1]))
    return float(lag[order][min(k, n - 1)])


def wheelset_transfer(model, channels: pd.DataFrame, kind: str, fs: float, *, f_lo: float, f_hi: float,
                      alpha: float, df: float, track, contact_stiffness, theta: tuple[float, float] = (0.0, 0.0),
                      ) -> WheelsetTransfer:
    """The regularised transfer function of one wheelset's sensors for one model (module docstring).

    Parameters
    ----------
    model : ModalModel
        Hybrid wheelset model with points ``contact_L/R`` and ``axlebox_L/R``.
    channels : pandas.DataFrame
        The wheelset's sensor rows (``Run.wheelset_channels``).
    kind : {"half", "vertical", "vertical_lateral"}
    fs : float
        Sampling rate of the accelerations [Hz]; the function is evaluated up to ``fs/2``.
    f_lo, f_hi : float
        Inversion band [Hz].
    alpha : float
        Tikhonov parameter.
    df : float
        Frequency step [Hz] of the evaluation grid.
    track : FrequencyResponse or Trackform
        Rail receptance (``track_frf``) on the grid, or a trackform.
    contact_stiffness : float
        Linearised Hertz stiffness ``K_H`` [N/m].
    theta : (float, float)
        Contact-plane angles (θ_L, θ_R) [rad] for ``vertical_lateral``.
    """
    rows, sides = model_channels(kind, channels)
    sub = channels.loc[rows].reset_index(drop=True)
    m_w, labels = sensor_model(model, sub)
    n_f = int(np.floor(0.5 * fs / df))
    f = df * np.arange(1, n_f + 1)
    trk = track
    if isinstance(track, FrequencyResponse) and (track.freqs_hz.size != f.size
                                                 or not np.allclose(track.freqs_hz, f)):
        raise ConfigurationError("the track receptance must be evaluated on the transfer grid (df·1..fs/2)")
    if kind == "half":
        T = np.zeros((n_f, len(sides), len(sides)), complex)
        P = np.zeros_like(T)
        cond = np.ones(n_f)
        fmin = np.ones(n_f)
        for i, (s, lab) in enumerate(zip(sides, labels)):
            mt = half_wheelset_transfer(m_w, f, side=s, channel=lab, track=trk, contact_stiffness=contact_stiffness)
            D = np.moveaxis(mt.dynamic_compliance.data, 2, 0)
            B = np.moveaxis(mt.force_to_acceleration.data, 2, 0)
            Ti, _, fm, Pi = regularised_inverse(D, B, f, alpha, with_inverse=True)
            T[:, i, i] = Ti[:, 0, 0]
            P[:, i, i] = Pi[:, 0, 0]
            fmin = np.minimum(fmin, fm)
    else:
        if kind == "vertical":
            mt = full_vertical_transfer(m_w, f, channels=labels, track=trk, contact_stiffness=contact_stiffness)
        elif kind == "vertical_lateral":
            mt = vertical_lateral_transfer(m_w, f, theta_l=float(theta[0]), theta_r=float(theta[1]), channels=labels,
                                           track=trk, contact_stiffness=contact_stiffness)
        else:
            raise ConfigurationError(f"unknown model {kind!r}; choose half, vertical or vertical_lateral")
        D = np.moveaxis(mt.dynamic_compliance.data, 2, 0)
        B = np.moveaxis(mt.force_to_acceleration.data, 2, 0)
        T, cond, fmin, P = regularised_inverse(D, B, f, alpha, with_inverse=True)
    w = band_window(f, f_lo, f_hi, 0.5 * fs)
    T = T * w[:, None, None]
    P = P * w[:, None, None]
    # grid with the 0 Hz line (T = 0 there) so that the impulse response and interpolation see the whole axis
    f0 = np.concatenate([[0.0], f])
    T0 = np.concatenate([np.zeros((1,) + T.shape[1:], complex), T])
    P0 = np.concatenate([np.zeros((1,) + P.shape[1:], complex), P])
    edge = float(np.clip(_edge_seconds(T0, df, 2 * f0[-1]), *EDGE_BOUNDS_S))
    names = tuple(str(n) for n in sub["name"])
    hist = (f"{kind} transfer function (thesis eq. {dict(half='2.6', vertical='2.11', vertical_lateral='2.22')[kind]})"
            f" of wheelset {int(channels['wheelset'].iloc[0])}, channels {list(names)}, theta "
            f"({math.degrees(theta[0]):.2f}, {math.degrees(theta[1]):.2f}) deg, Tikhonov alpha {alpha:g} (1/3-octave "
            f"reference), band {f_lo:g}-{f_hi:g} Hz, edge {edge:.2f} s",)
    return WheelsetTransfer(kind=kind, wheelset=int(channels["wheelset"].iloc[0]), channels=names, sides=sides,
                            freqs_hz=f0, T=T0, condition=np.concatenate([[np.nan], cond]),
                            filter_min=np.concatenate([[0.0], fmin]), theta=(float(theta[0]), float(theta[1])),
                            band_hz=(float(f_lo), float(f_hi)), edge_s=edge, alpha=float(alpha), history=hist, P=P0)


def rail_coupling(freqs_hz: np.ndarray, trackform, distance_m: float, sides_self: Sequence[str],
                  sides_other: Sequence[str], theta_self=(0.0, 0.0), theta_other=(0.0, 0.0)) -> np.ndarray:
    """Rail displacement along the contact normals of one wheelset per unit normal force of the other.

    Each rail carries both wheelsets of the bogie ``distance_m`` (the wheelbase) apart. Above the
    rail-on-pad resonance the rail's bending waves travel far (the cross receptance at 2.1 m is 45–65 %
    of the point receptance from 140 to 300 Hz on the thesis's Table 2.2 track), so the rail under one
    wheel also moves with the other wheelset's force: the irregularity at wheel ``s`` is
    ``n_s = (T a)_s + C_ss F'_s`` with ``F' = B'⁺ a'`` the other wheelset's contact forces and
    ``C_ss = cos θ_s cos θ'_s α_z(d) + sin θ_s sin θ'_s α_y(d)`` (the contact normals
    ``(−sin θ, cos θ)`` of thesis eq. 2.12, ``α(d)`` the infinite Timoshenko rail's transfer receptance at
    distance ``d``, thesis §2.4 / :func:`receptance.track.green_function`).

    Returns
    -------
    ndarray complex (n_f, len(sides_self), len(sides_other)), zero at 0 Hz and between different rails.
    """
    from receptance.track import beam_section, green_function, support_stiffness_per_metre

    f = np.asarray(freqs_hz, float)
    out = np.zeros((f.size, len(sides_self), len(sides_other)), complex)
    pos = f > 0
    alpha = {}
    for direction in ("vertical", "lateral"):
        a = np.zeros(f.size, complex)
        a[pos] = green_function(f[pos], distance_m, beam_section(trackform, direction),
                                support_stiffness_per_metre(f[pos], trackform, direction))
        alpha[direction] = a
    th_s = dict(zip("LR", theta_self))
    th_o = dict(zip("LR", theta_other))
    for i, s in enumerate(sides_self):
        for j, o in enumerate(sides_other):
            if s != o:
                continue
            out[:, i, j] = (math.cos(th_s[s]) * math.cos(th_o[o]) * alpha["vertical"]
                            + math.sin(th_s[s]) * math.sin(th_o[o]) * alpha["lateral"])
    return out


def condition_by_band(tr: WheelsetTransfer) -> pd.DataFrame:
    """Condition number of ``B`` and regularisation per one-third-octave band of the inversion band.

    Columns ``f_centre_hz, cond_median, cond_max, filter_min`` (the smallest
    Tikhonov filter factor in the band: < 1 where the regularisation acted).
    """
    lo, hi = tr.band_hz
    k = np.arange(math.floor(10 * math.log10(lo)), math.ceil(10 * math.log10(hi)) + 1)
    rows = []
    for kk in k:
        fc = 10 ** (kk / 10)
        sel = (tr.freqs_hz >= fc * 10 ** -0.05) & (tr.freqs_hz < fc * 10 ** 0.05) & (tr.freqs_hz >= lo) \
            & (tr.freqs_hz <= hi)
        if not sel.any():
            continue
        c = tr.condition[sel]
        rows.append({"f_centre_hz": round(fc, 3), "cond_median": float(np.median(c)), "cond_max": float(np.max(c)),
                     "filter_min": float(tr.filter_min[sel].min())})
    return pd.DataFrame(rows)


def _interp_matrix(fr: np.ndarray, grid_df: float, T: np.ndarray) -> np.ndarray:
    """``T`` (on ``k·grid_df``) linearly interpolated at frequencies ``fr`` (0 beyond the grid)."""
    pos = fr / grid_df
    i = np.minimum(pos.astype(np.int64), T.shape[0] - 2)
    w = (pos - i)[:, None, None]
    out = T[i] * (1 - w) + T[i + 1] * w
    out[pos > T.shape[0] - 1] = 0
    return out


def cubic_sample(y: np.ndarray, u: np.ndarray) -> np.ndarray:
    """4-point cubic Lagrange interpolation of the rows of ``y`` at fractional indices ``u`` (NaN outside)."""
    y = np.ascontiguousarray(y, dtype=float)
    u = np.ascontiguousarray(u, dtype=float)
    y2 = y.reshape(-1, y.shape[-1])
    out = np.empty((y2.shape[0], u.size))
    _cubic_rows(y2, u.ravel(), out)
    return out.reshape(y.shape[:-1] + u.shape)


def _cubic_rows_py(y, u, out):
    n = y.shape[1]
    for j in range(u.size):
        uj = u[j]
        if not (uj >= 1.0 and uj <= n - 3):
            for r in range(y.shape[0]):
                out[r, j] = np.nan
            continue
        i = int(np.floor(uj))
        t = uj - i
        w0 = -t * (t - 1.0) * (t - 2.0) / 6.0
        w1 = (t + 1.0) * (t - 1.0) * (t - 2.0) / 2.0
        w2 = -(t + 1.0) * t * (t - 2.0) / 2.0
        w3 = (t + 1.0) * t * (t - 1.0) / 6.0
        for r in range(y.shape[0]):
            out[r, j] = y[r, i - 1] * w0 + y[r, i] * w1 + y[r, i + 1] * w2 + y[r, i + 2] * w3


try:  # one compiled pass instead of four gathers per row (numba is a dependency of the virtual line too)
    from numba import njit

    _cubic_rows = njit(cache=True, nogil=True)(_cubic_rows_py)
except ImportError:  # pragma: no cover - pure numpy fallback
    def _cubic_rows(y, u, out):
        n = y.shape[1]
        i = np.floor(u).astype(np.int64)
        ok = (i >= 1) & (i <= n - 3)
        i = np.clip(i, 1, max(n - 3, 1))
        t = u - i
        w = (-t * (t - 1) * (t - 2) / 6, (t + 1) * (t - 1) * (t - 2) / 2, -(t + 1) * t * (t - 2) / 2,
             (t + 1) * t * (t - 1) / 6)
        out[:] = sum(y[:, i - 1 + k] * w[k] for k in range(4))
        out[:, ~ok] = np.nan


@dataclass(frozen=True, eq=False)
class TimeIrregularity:
    """Irregularity at the wheels of one wheelset as functions of time, per valid stretch.

    ``segments`` holds ``(t_first, values (n_sides, n_up))`` with samples at
    ``t_first + j / (upsample fs)``; only the part inside ``[t_valid0, t_valid1]``
    (edges dropped) is used.
    """

    kind: str
    wheelset: int
    sides: tuple[str, ...]
    fs: float
    segments: tuple[tuple[float, float, float, np.ndarray], ...]
    #: seconds each side is estimated, when a side's own gaps are NaN inside the stretches (:func:`invert`);
    #: empty: every side over all of :attr:`valid_time`
    side_time_s: tuple[float, ...] = ()
    #: samples per sample of the accelerations (:data:`UPSAMPLE` for the chainage's interpolation)
    upsample: int = UPSAMPLE

    def sample(self, t: np.ndarray) -> np.ndarray:
        """Values (n_sides, len(t)) at times ``t`` (NaN where no valid stretch covers ``t``)."""
        t = np.asarray(t, float)
        out = np.full((len(self.sides), t.size), np.nan)
        rate = self.upsample * self.fs
        for t_first, v0, v1, y in self.segments:
            sel = (t >= v0) & (t <= v1)
            if not sel.any():
                continue
            out[:, sel] = cubic_sample(y, (t[sel] - t_first) * rate)
        return out

    def same_segments(self, other: "TimeIrregularity") -> bool:
        return len(self.segments) == len(other.segments) and all(
            a[:3] == b[:3] and a[3].shape[1] == b[3].shape[1] for a, b in zip(self.segments, other.segments))

    @property
    def valid_time(self) -> float:
        return float(sum(v1 - v0 for _, v0, v1, _ in self.segments))

    def estimated_sides(self) -> "TimeIrregularity":
        """This estimate without the sides it has no valid sample of (a half model whose one channel is masked
        wherever the other's is not): a rail is estimated or absent, never an empty row."""
        time = self.valid_time_by_side
        keep = time > 0
        if keep.all() or not keep.any():
            return self
        return replace(self, sides=tuple(s for s, k in zip(self.sides, keep) if k),
                       segments=tuple((a, b, c, y[keep]) for a, b, c, y in self.segments),
                       side_time_s=tuple(float(t) for t in time[keep]))

    @property
    def valid_time_by_side(self) -> np.ndarray:
        """Seconds each side is estimated (a side's own gaps are NaN inside a stretch, :func:`invert`)."""
        return np.array(self.side_time_s) if self.side_time_s else np.full(len(self.sides), self.valid_time)


def sample_many(tis: Sequence[TimeIrregularity], t: np.ndarray) -> list[np.ndarray]:
    """:meth:`TimeIrregularity.sample` of several inversions at the same times (one interpolation when they
    share their valid stretches, as the models of one wheelset usually do)."""
    if len(tis) > 1 and all(tis[0].same_segments(o) and o.upsample == tis[0].upsample for o in tis[1:]):
        rows = [len(ti.sides) for ti in tis]
        stacked = TimeIrregularity(tis[0].kind, tis[0].wheelset, tuple(s for ti in tis for s in ti.sides), tis[0].fs,
                                   tuple((a[0], a[1], a[2], np.concatenate([ti.segments[k][3] for ti in tis]))
                                         for k, a in enumerate(tis[0].segments)))
        out = stacked.sample(t)
        return np.split(out, np.cumsum(rows)[:-1])
    return [ti.sample(t) for ti in tis]


def _stretches(valid: np.ndarray, min_len: int) -> list[tuple[int, int]]:
    from estimator.qc import runs_of

    return [(a, b) for a, b in runs_of(valid) if b - a >= min_len]


def invert(acc: np.ndarray, t0: float, fs: float, valid: np.ndarray, transfers: Sequence[WheelsetTransfer],
           weights: Sequence[np.ndarray] | None = None, edge_s: float | None = None,
           coupled: tuple | None = None, upsample: int = UPSAMPLE) -> TimeIrregularity:
    """Invert one wheelset's accelerations with one model (module docstring).

    Parameters
    ----------
    acc : ndarray (n_channels, n)
        The accelerations of ``transfers[0].channels`` [m/s²], in that order.
    t0, fs : float
        Time of the first sample [s] and sampling rate [Hz].
    valid : ndarray of bool (n,) or (n_channels, n)
        Samples no quality-control finding masks: for all these channels, or per channel. A side's estimate
        is valid where every channel its row of ``T`` reads is (:func:`side_dependence`).
    transfers : sequence of WheelsetTransfer
        One per set of contact angles (same model, wheelset and channels).
    weights : sequence of ndarray (n,), optional
        Weight of each transfer at each sample (sum 1); default: the first only.
    edge_s : float, optional
        Edge dropped at both ends of each stretch [s] (default: the transfers' longest ``edge_s``); a common
        value lets several models share their valid stretches.
    coupled : (acc_other, valid_other, transfers_other, couplings), optional
        The other wheelset of the bogie (same time base): its accelerations, valid samples, one transfer per
        class (with ``P``) and the rail coupling per class (:func:`rail_coupling`); its forces' share of the
        rail deflection is added (``valid_other`` for all its channels or per channel). A side's sample counts
        as valid only when the other wheelset's channels its coupling term reads are valid too.
    upsample : int
        Output samples per input sample (band-limited interpolation in the frequency domain): :data:`UPSAMPLE`
        for the chainage's cubic interpolation; 1 where the output is read at the sample times only.

    Returns
    -------
    TimeIrregularity
    """
    tr0 = transfers[0]
    if acc.shape[0] != len(tr0.channels):
        raise ChannelError(f"{acc.shape[0]} acceleration rows for a transfer function of channels {tr0.channels}")
    if weights is None:
        weights = [np.ones(acc.shape[1])] + [np.zeros(acc.shape[1])] * (len(transfers) - 1)
    edge = max(tr.edge_s for tr in transfers) if edge_s is None else max(edge_s, *(tr.edge_s for tr in transfers))
    e = int(math.ceil(edge * fs))
    grid_df = float(tr0.freqs_hz[1] - tr0.freqs_hz[0])
    min_len = 2 * e + int(fs)  # a stretch must outlast its two edges by >= 1 s
    ok_in = np.broadcast_to(np.asarray(valid, bool), acc.shape)
    side_ok = side_validity(valid, transfers, *(coupled[1:] if coupled is not None else ()))
    if coupled is not None:
        acc_o, valid_o, transfers_o, couplings = coupled
        ok_o = np.broadcast_to(np.asarray(valid_o, bool), acc_o.shape)
    union = side_ok.any(axis=0)
    per_side = not (side_ok == union).all()
    segs = []
    side_time = np.zeros(side_ok.shape[0])
    for a, b in _stretches(union, min_len):
        x = _zero_invalid(acc[:, a:b], ok_in[:, a:b])
        n = b - a
        nfft = sfft.next_fast_len(n + e)
        X = sfft.rfft(x, n=nfft, axis=1)
        fr = np.arange(X.shape[1]) * fs / nfft
        if coupled is not None:
            Xo = sfft.rfft(_zero_invalid(acc_o[:, a:b], ok_o[:, a:b]), n=nfft, axis=1)
        y = np.zeros((len(tr0.sides), upsample * nfft))
        for k, (tr, w) in enumerate(zip(transfers, weights)):
            ws = w[a:b]
            if not np.any(ws > 0):
                continue
            Tb = _interp_matrix(fr, grid_df, tr.T)
            Y = np.einsum("boi,ib->ob", Tb, X)
            if coupled is not None:
                # the other wheelset's contact forces deflect the rail under this one (rail_coupling)
                Fo = np.einsum("boi,ib->ob", _interp_matrix(fr, grid_df, transfers_o[k].P), Xo)
                Y += np.einsum("bos,sb->ob", _interp_matrix(fr, grid_df, couplings[k]), Fo)
            yc = sfft.irfft(Y, n=upsample * nfft, axis=1) * upsample
            wu = np.interp(np.arange(upsample * nfft) / upsample, np.arange(n), ws, right=0.0)
            y += yc * wu
        if per_side:
            for k in range(y.shape[0]):
                keep, kept_s = _kept_upsampled(side_ok[k, a:b], e, min_len, y.shape[1], fs, upsample)
                y[k, ~keep] = np.nan
                side_time[k] += kept_s
        t_first = t0 + a / fs
        segs.append((t_first, t0 + (a + e) / fs, t0 + (b - 1 - e) / fs, y[:, :upsample * n]))
    return TimeIrregularity(tr0.kind, tr0.wheelset, tr0.sides, fs, tuple(segs),
                            tuple(float(t) for t in side_time) if per_side else (), upsample)


def side_dependence(transfers: Sequence[WheelsetTransfer], transfers_other: Sequence[WheelsetTransfer] = (),
                    couplings: Sequence[np.ndarray] = ()) -> tuple[np.ndarray, np.ndarray | None]:
    """Which channels each estimated side reads: ``(own, other)``, boolean (n_sides, n_channels) from the
    non-zero entries of ``T`` at any frequency, and (n_sides, n_channels_other) from those of the coupling term
    ``C B'⁺_α`` (None without it). The half model's ``T`` is diagonal and the coupling joins the same rail only,
    so a half model's side reads its own channel (and the other wheelset's on its rail); the other models mix
    every channel."""
    own = np.zeros(transfers[0].T.shape[1:], bool)
    for tr in transfers:
        own |= (tr.T != 0).any(axis=0)
    if not len(couplings):
        return own, None
    other = np.zeros((own.shape[0], transfers_other[0].P.shape[2]), bool)
    for tro, C in zip(transfers_other, couplings):
        # side s reads channel j when some force s' of the other wheelset does (P) and reaches s (C), at any
        # frequency: the patterns, not the product, which could cancel at one frequency
        reach = (C != 0).any(axis=0).astype(int) @ (tro.P != 0).any(axis=0).astype(int)
        other |= reach > 0
    return own, other


def side_validity(valid: np.ndarray, transfers: Sequence[WheelsetTransfer], valid_other: np.ndarray | None = None,
                  transfers_other: Sequence[WheelsetTransfer] = (), couplings: Sequence[np.ndarray] = ()
                  ) -> np.ndarray:
    """Samples (n_sides, n) at which each side's estimate may be formed: every channel it reads is valid
    (:func:`side_dependence`; ``valid`` and ``valid_other`` for all channels, (n,), or per channel), before the
    inverse filter's edges are dropped."""
    n = np.shape(valid)[-1]
    ok = np.broadcast_to(np.asarray(valid, bool), (len(transfers[0].channels), n))
    dep, dep_o = side_dependence(transfers, transfers_other, couplings)
    out = np.stack([ok[d].all(axis=0) for d in dep])
    if dep_o is not None:
        ok_o = np.broadcast_to(np.asarray(valid_other, bool), (dep_o.shape[1], n))
        out &= np.stack([ok_o[d].all(axis=0) for d in dep_o])
    return out


def side_valid_time(valid: np.ndarray, transfers: Sequence[WheelsetTransfer], fs: float,
                    edge_s: float | None = None) -> np.ndarray:
    """Seconds each side of ``transfers`` would be estimated by :func:`invert` without the coupling, from the
    validity alone (``valid`` as there): a coupled inversion that leaves a side none of them has lost it."""
    edge = max(tr.edge_s for tr in transfers) if edge_s is None else max(edge_s, *(tr.edge_s for tr in transfers))
    e = int(math.ceil(edge * fs))
    return np.array([sum(q - 1 - 2 * e - p for p, q in _stretches(ok, 2 * e + int(fs))) / fs
                     for ok in side_validity(valid, transfers)])


def _zero_invalid(x: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """Rows of ``x`` without their mean (over their valid samples) and zero where invalid: a masked sample
    (NaN, clipped) must not reach the spectrum of any side, and a side that does not read the row is unaffected
    by its zeros."""
    if ok.all():
        return x - x.mean(axis=1, keepdims=True)
    n_ok = np.maximum(ok.sum(axis=1, keepdims=True), 1)
    xz = np.where(ok, x, 0.0)
    return np.where(ok, xz - xz.sum(axis=1, keepdims=True) / n_ok, 0.0)


def _kept_upsampled(ok: np.ndarray, e: int, min_len: int, size: int, fs: float,
                    upsample: int) -> tuple[np.ndarray, float]:
    """Upsampled samples (``upsample`` per sample, ``size`` of them) inside a side's own valid stretches of
    at least ``min_len`` samples, ``e`` dropped at both ends of each (the inverse filter's reach into a gap
    where that side's channels entered as zeros), and their duration [s] as :attr:`TimeIrregularity.valid_time`
    counts a stretch's."""
    keep = np.zeros(size, bool)
    time = 0.0
    for p, q in _stretches(ok, min_len):
        keep[upsample * (p + e):upsample * (q - 1 - e) + 1] = True
        time += (q - 1 - 2 * e - p) / fs
    return keep, time
