"""Transfer functions re-derived cheaply per candidate: the wheelset's receptances computed once, the rest per call.

The estimator's transfer function of one wheelset (thesis eqs. 2.6, 2.11,
2.22; :func:`estimator.inversion.wheelset_transfer`) is

    D = Nᵀ(A_W + A_R)N + diag(1/K_H),     B = −Ω² A_B N,     T = D B⁺_α

with ``A_W`` the wheelset receptance between the contact DOFs, ``A_B`` from
the contact DOFs to the accelerometers, ``A_R`` the rail receptance, ``N``
the contact normals (angles ``θ_L, θ_R``) and ``K_H`` the Hertz stiffness.
Of the field effects, none changes the wheelset's modal model: a trackform
changes ``A_R``, the contact angles ``N``, the wheel load ``K_H``, and an
accelerometer's mounting point one row of ``A_B`` — and that row is linear in
the mounting offset ``δ``: the sensor is rigidly bolted to its axlebox node,
``u(P + δ) = u(P) + θ × δ``, so its reading along ``d`` is
``d·u(P) + (δ × d)·θ(P)``. :class:`WheelsetBlocks` therefore evaluates the
modal model once — translations and rotations at every nominal sensor point
and the contact receptances — on an evenly spaced grid, and
:meth:`WheelsetBlocks.transfer` assembles ``T`` for any trackform, angles,
stiffness and offsets in milliseconds, regularised and band-limited exactly
as the estimator does (:func:`estimator.inversion.regularised_inverse`,
:func:`estimator.inversion.band_window`). ``tests/test_field_diagnosis.py``
holds it equal to the estimator's own transfer function.

The rail couples the bogie's two wheelsets (each rail carries a wheel of
both, a wheelbase ``d`` apart): the estimator adds, to one wheelset's
irregularity, the rail deflection the other's contact forces cause under it
(:func:`estimator.inversion.rail_coupling`, ``n = T a + C(d) B'⁺_α a'``).
:meth:`WheelsetBlocks.coupled_transfer` assembles that same map for the
stacked channels ``[a; a']`` of the two wheelsets, so that the diagnosis's
forward model is the estimator's (without it the evidence shows the rail's
wave reflection between the wheelsets as a model error: +3.5 dB at
170–180 Hz on the Table 2.2 track, measured on the virtual line).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from estimator.inversion import band_window, model_channels, rail_coupling, sensor_model, tikhonov_inverse
from receptance.track import track_frf

__all__ = ["WheelsetBlocks", "wheelset_blocks", "interp_transfer", "interp_weights", "interp_apply", "CONTACT_DOFS"]

#: contact DOFs of the blocks, in this order (thesis DOFs 2, 3, 8, 9)
CONTACT_DOFS = ("contact_L:y", "contact_L:z", "contact_R:y", "contact_R:z")
#: angle/offset pairs whose wheelset side (B, its inverse) a :class:`WheelsetBlocks` keeps (a fit visits ~100)
_INVERSE_CACHE = 64
_AXES = {"x": np.array([1.0, 0.0, 0.0]), "y": np.array([0.0, 1.0, 0.0]), "z": np.array([0.0, 0.0, 1.0])}


@dataclass(frozen=True, eq=False)
class WheelsetBlocks:
    """One wheelset's receptances for one model's channels, on ``f`` (module docstring).

    Attributes
    ----------
    kind : str
    wheelset : int
    channels : tuple of str
        Run channel names, in the order of the transfer function's columns.
    sides : tuple of str
        Vehicle sides estimated (rows of ``T``).
    directions : ndarray (m, 3)
        Measuring direction of each channel (vehicle frame).
    f : ndarray (n_f,)
        ``df·(1..n_f)`` [Hz].
    A_c : ndarray (n_f, 4, 4)
        Receptance between :data:`CONTACT_DOFS`.
    U, R : ndarray (n_f, m, 3, 4)
        Translation and rotation receptances at each channel's nominal point from the contact DOFs.
    fs, f_lo, f_hi, alpha : float
        Sampling rate, inversion band and Tikhonov parameter (the estimator's).
    """

    kind: str
    wheelset: int
    channels: tuple[str, ...]
    sides: tuple[str, ...]
    directions: np.ndarray
    f: np.ndarray
    A_c: np.ndarray
    U: np.ndarray
    R: np.ndarray
    fs: float
    f_lo: float
    f_hi: float
    alpha: float
    window: np.ndarray = field(repr=False, default=None)
    _track_cache: dict = field(default_factory=dict, repr=False)
    _inverse_cache: dict = field(default_factory=dict, repr=False)

    @property
    def df(self) -> float:
        return float(self.f[1] - self.f[0])

    def rail(self, trackform, supports: str = "continuous") -> tuple[np.ndarray, np.ndarray]:
        """``(A_RY, A_RZ)`` on the grid for a trackform (memoised)."""
        key = (trackform, supports)
        if key not in self._track_cache:
            tr = track_frf(self.f, trackform, supports=supports)
            self._track_cache[key] = (tr.data[1, 1].copy(), tr.data[0, 0].copy())
        return self._track_cache[key]

    def sensor_rows(self, offsets: np.ndarray | None = None) -> np.ndarray:
        """``A_B`` (n_f, m, 4) with each channel moved by ``offsets`` (m, 3) [m] from its nominal point."""
        d = self.directions
        if "rows" not in self._track_cache:
            self._track_cache["rows"] = (d[None, :, :, None] * self.U).sum(axis=2)
        rows = self._track_cache["rows"]
        if offsets is not None and np.any(offsets):
            lever = np.cross(np.asarray(offsets, float), d)  # (δ × d): the rotation's share of the reading
            rows = rows + (lever[None, :, :, None] * self.R).sum(axis=2)
        return rows

    def force_to_acceleration(self, theta: tuple[float, float] = (0.0, 0.0),
                              offsets: np.ndarray | None = None) -> np.ndarray:
        """``B = −Ω² A_B N`` (n_f, m, n_sides): accelerations per unit contact force along the normals.

        It holds the wheelset and the sensors only (no track, no contact stiffness); the half model's sides each
        take their own vertical force.
        """
        A_B = self.sensor_rows(offsets)
        Om2 = (2 * np.pi * self.f) ** 2
        if self.kind == "half":
            return -Om2[:, None, None] * A_B[:, :, self._vertical_dofs()]
        return -Om2[:, None, None] * (A_B @ _normals((0.0, 0.0) if self.kind == "vertical" else theta))

    def _vertical_dofs(self) -> list[int]:
        """Each side's vertical contact DOF (its index in :data:`CONTACT_DOFS`): the half model's force."""
        return [1 if s == "L" else 3 for s in self.sides]

    def transfer(self, trackform, theta: tuple[float, float] = (0.0, 0.0), contact_stiffness: float = 1e9, *,
                 offsets: np.ndarray | None = None, supports: str = "continuous") -> np.ndarray:
        """``T`` (n_f, n_sides, m) regularised and band-limited as the estimator's (module docstring)."""
        return self._assemble(trackform, theta, contact_stiffness, offsets, supports, forward=False)

    def transfer_and_forces(self, trackform, theta: tuple[float, float] = (0.0, 0.0),
                            contact_stiffness: float = 1e9, *, offsets: np.ndarray | None = None,
                            supports: str = "continuous") -> tuple[np.ndarray, np.ndarray]:
        """``(T, P)``: ``T`` as :meth:`transfer` and ``P = B⁺_α`` (n_f, n_sides, m), the contact forces along the
        normals per unit acceleration, band-limited as the estimator's (``WheelsetTransfer.P``)."""
        T, P = self._assemble(trackform, theta, contact_stiffness, offsets, supports, forward=False, forces=True)
        return T, P

    def coupled_transfer(self, other: "WheelsetBlocks", trackform, theta: tuple[float, float],
                         contact_stiffness: float, wheelbase_m: float, *, offsets: np.ndarray | None = None,
                         offsets_other: np.ndarray | None = None, supports: str = "continuous",
                         theta_other: tuple[float, float] | None = None) -> np.ndarray:
        """``[T, C(d) P']`` (n_f, n_sides, m + m'): the irregularity from this wheelset's and the other's channels.

        ``C`` is :func:`estimator.inversion.rail_coupling` at the wheelbase, ``P'`` the other wheelset's
        :meth:`transfer_and_forces` at the same trackform and at its own contact angles ``theta_other`` (default
        ``theta``; on a curve the leading and trailing wheelsets' differ), as the estimator pairs them.
        """
        th_o = theta if theta_other is None else tuple(theta_other)
        if other.kind != self.kind or other.f.size != self.f.size or not np.allclose(other.f, self.f):
            raise ValueError(f"wheelset {other.wheelset}'s blocks ({other.kind}, {other.f.size} lines) do not match "
                             f"wheelset {self.wheelset}'s ({self.kind}, {self.f.size} lines)")
        T = self.transfer(trackform, theta, contact_stiffness, offsets=offsets, supports=supports)
        _, P = other.transfer_and_forces(trackform, th_o, contact_stiffness, offsets=offsets_other,
                                         supports=supports)
        key = ("C", trackform, round(float(wheelbase_m), 4), tuple(round(t, 6) for t in theta),
               tuple(round(t, 6) for t in th_o))
        if key not in self._track_cache:
            self._track_cache[key] = rail_coupling(self.f, trackform, float(wheelbase_m), self.sides, other.sides,
                                                   theta, th_o)
        return np.concatenate([T, self._track_cache[key] @ P], axis=2)

    def forward(self, trackform, theta: tuple[float, float] = (0.0, 0.0), contact_stiffness: float = 1e9, *,
                offsets: np.ndarray | None = None, supports: str = "continuous") -> np.ndarray:
        """The forward map ``H = B D⁻¹`` (n_f, m, n_sides): irregularity at the wheels → accelerations.

        (Sign: an irregularity that compresses the contact pushes the wheel up, as in the estimator's
        inverse; ``T H`` is the identity in the inversion band up to regularisation.)
        """
        return self._assemble(trackform, theta, contact_stiffness, offsets, supports, forward=True)

    def _wheelset_side(self, theta, offsets) -> tuple:
        """``(th, NᵀA_cN, B, B⁺_α)`` for the angles and mounting offsets (memoised, at most
        :data:`_INVERSE_CACHE` entries).

        They hold the wheelset and its sensors only — neither the track nor the contact stiffness — so every
        trackform, wheel load or support model met in a fit reuses them; only ``D = NᵀA_cN + NᵀA_R N + 1/K_H``
        is assembled per call (the Tikhonov inverse of ``B``, :func:`estimator.inversion.tikhonov_inverse`, does not
        depend on ``D``: the estimator's ``T`` is ``D B⁺_α``). The half model's are per side
        (``(n_f, n_sides)`` each: its sides are inverted one by one).
        """
        th = (0.0, 0.0) if self.kind in ("vertical", "half") else (round(theta[0], 5), round(theta[1], 5))
        off = None if offsets is None or not np.any(offsets) else np.asarray(offsets, float)
        key = (th, None if off is None else off.tobytes())
        got = self._inverse_cache.get(key)
        if got is not None:
            return got
        F = self.force_to_acceleration(th, off)
        if self.kind == "half":
            z = self._vertical_dofs()
            B = np.stack([F[:, i, i] for i in range(len(z))], axis=1)  # each side's channel from its own force
            pinv = np.stack([tikhonov_inverse(B[:, i, None, None], self.f, self.alpha)[0][:, 0, 0]
                             for i in range(len(z))], axis=1)
            NtAN = np.stack([self.A_c[:, zi, zi] for zi in z], axis=1)
        else:
            N = _normals(th)
            NtAN = N.T @ self.A_c @ N
            B = F
            pinv = tikhonov_inverse(B, self.f, self.alpha)[0]
        if len(self._inverse_cache) >= _INVERSE_CACHE:
            del self._inverse_cache[next(iter(self._inverse_cache))]
        got = self._inverse_cache[key] = (th, NtAN, B, pinv)
        return got

    def _assemble(self, trackform, theta, contact_stiffness, offsets, supports, *, forward: bool,
                  forces: bool = False):
        ary, arz = self.rail(trackform, supports)
        c = 1.0 / float(contact_stiffness)
        th, NtAN, B, pinv = self._wheelset_side(theta, offsets)
        if self.kind == "half":
            n = len(self.sides)
            D = NtAN + arz[:, None] + c  # (n_f, n_sides): each side's own vertical contact
            T = np.zeros((self.f.size, n, n), complex)
            idx = np.arange(n)
            if forward:
                T[:, idx, idx] = B / D
                return T
            T[:, idx, idx] = D * pinv
            if forces:
                P = np.zeros_like(T)
                P[:, idx, idx] = pinv
        else:
            # Nᵀ diag(A_RY, A_RZ, A_RY, A_RZ) N is diagonal: each contact normal sees the rail along itself
            s2l, c2l, s2r, c2r = math.sin(th[0]) ** 2, math.cos(th[0]) ** 2, math.sin(th[1]) ** 2, math.cos(th[1]) ** 2
            D = NtAN.copy()
            D[:, 0, 0] += (s2l * ary if s2l else 0.0) + c2l * arz + c
            D[:, 1, 1] += (s2r * ary if s2r else 0.0) + c2r * arz + c
            if forward:
                return B @ np.linalg.inv(D)
            T = D @ pinv
            P = pinv
        if forces:
            return T * self.window[:, None, None], P * self.window[:, None, None]
        return T * self.window[:, None, None]


def _normals(theta: tuple[float, float]) -> np.ndarray:
    """``N`` (4, 2): the contact normals at the angles ``θ_L, θ_R`` over :data:`CONTACT_DOFS`."""
    sl, cl, sr, cr = math.sin(theta[0]), math.cos(theta[0]), math.sin(theta[1]), math.cos(theta[1])
    return np.array([[-sl, 0.0], [cl, 0.0], [0.0, -sr], [0.0, cr]])


def wheelset_blocks(model, channels: pd.DataFrame, kind: str, fs: float, *, f_lo: float, f_hi: float, alpha: float,
                    df: float) -> WheelsetBlocks:
    """The receptance blocks of one wheelset's sensors for one model (module docstring).

    Parameters
    ----------
    model : ModalModel
        The wheelset in service (points ``contact_L/R``, ``axlebox_L/R``).
    channels : pandas.DataFrame
        The wheelset's rows of the run's channel table (``Run.wheelset_channels``).
    kind : {"half", "vertical", "vertical_lateral"}
    fs, f_lo, f_hi, alpha : float
        As the estimator's :class:`~estimator.workflow.FieldModel` uses them.
    df : float
        Grid step [Hz]; the grid ends at ``min(fs/2, f_hi·2^(1/6))`` (``T`` is zero above).
    """
    rows, sides = model_channels(kind, channels)
    sub = channels.loc[rows].reset_index(drop=True)
    m_w, labels = sensor_model(model, sub)
    top = min(0.5 * fs, f_hi * 2 ** (1 / 6) + 2 * df)
    f = df * np.arange(1, int(np.floor(top / df)) + 1)
    names = [str(n) for n in sub["name"]]
    outputs = list(CONTACT_DOFS) + [f"{n}:{a}" for n in names for a in ("x", "y", "z", "rx", "ry", "rz")]
    H = np.moveaxis(m_w.receptance(outputs, list(CONTACT_DOFS), f).data, 2, 0)  # (n_f, out, 4)
    m = len(names)
    A_c = H[:, :4, :]
    S = H[:, 4:, :].reshape(f.size, m, 6, 4)
    dirs = np.stack([_AXES[str(d)] for d in sub["direction"]])
    return WheelsetBlocks(kind=kind, wheelset=int(channels["wheelset"].iloc[0]), channels=tuple(names),
                          sides=tuple(sides), directions=dirs, f=f, A_c=A_c, U=S[:, :, :3, :].copy(),
                          R=S[:, :, 3:, :].copy(), fs=float(fs), f_lo=float(f_lo), f_hi=float(f_hi),
                          alpha=float(alpha), window=band_window(f, f_lo, f_hi, 0.5 * fs))


def interp_weights(df: float, n: int, freqs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(index, weight, outside)`` of linear interpolation on ``df·(1..n)`` at ``freqs`` (:func:`interp_transfer`;
    a caller that interpolates many functions at the same frequencies keeps them)."""
    pos = np.asarray(freqs, float) / df - 1.0
    i = np.clip(np.floor(pos).astype(np.int64), 0, n - 2)
    return i, (pos - i)[:, None, None], (pos < 0) | (pos > n - 1)


def interp_apply(T: np.ndarray, weights: tuple[np.ndarray, np.ndarray, np.ndarray]) -> np.ndarray:
    """``T`` interpolated with :func:`interp_weights` (0 outside the grid)."""
    i, w, outside = weights
    out = T[i] * (1 - w) + T[i + 1] * w
    out[outside] = 0.0
    return out


def interp_transfer(T: np.ndarray, df: float, freqs: np.ndarray) -> np.ndarray:
    """``T`` on ``df·(1..n)`` linearly interpolated at ``freqs`` (0 outside the grid)."""
    return interp_apply(T, interp_weights(df, T.shape[0], freqs))
