"""Transfer functions of the measurement system: axlebox accelerations → rail irregularity (thesis §2.2, §4.1).

The wheel and the rail touch through a linearised Hertzian spring
(stiffness ``K_H``); only the force along each contact *normal* is kept
(tangential forces neglected, thesis §2.2).  With ``F_n`` the two normal
contact forces (left, right), the irregularities along the normals and the
measured accelerations are (eqs. 2.20, 2.21)::

    n_irr = D(Ω) F_n,     D = Nᵀ (A_W + A_R) N + diag(1/K_H)        (2×2)
    a     = B(Ω) F_n,     B = −Ω² A_B N                              (m×2)

where ``A_W`` (4×4) is the wheelset receptance between the contact DOFs
``(y_L, z_L, y_R, z_R)`` = thesis DOFs 2, 3, 8, 9 (eq. 2.17), ``A_R =
diag(A_RY, A_RZ, A_RY, A_RZ)`` the rail receptance (eq. 2.18), ``A_B`` the
receptance from the contact DOFs to the ``m`` measured channels (eq. 2.21)
and ``N`` (4×2) places the normal force of each side on its contact DOFs.
The contact normal of side ``s`` in the ``(y, z)`` plane follows eq. 2.12
from the contact-plane angle ``θ_s``: ``n = (−sin θ, cos θ)`` (tangent
``t = (cos θ, sin θ)``, second and first columns of ``Λ(θ)``); ``θ = 0`` is a
vertical normal.  Eliminating ``F_n`` gives the transfer function::

    n_irr = T a,          T = D B⁺                                   (2×m)

(eqs. 2.6, 2.11, 2.22).  With ``m = 2`` channels ``B⁺ = B⁻¹`` and ``T`` is
eq. 2.11 (θ = 0) exactly; with more channels (the instrumented train has two
vertical and one lateral accelerometer) ``F_n`` is the least-squares
solution, per frequency.

Regularisation.  Where ``B`` is ill-conditioned (at antiresonances of the
contact-to-axlebox receptances, or with nearly parallel channels) ``B⁺``
amplifies measurement noise.  With ``B = U S Vᴴ`` the Tikhonov solution
minimises ``‖B F − a‖² + (α s_max)² ‖F‖²``::

    B⁺_α = V diag(s_k / (s_k² + α² s_max²)) Uᴴ

``α`` (``regularisation``) is dimensionless: it is relative to the largest
singular value ``s_max`` of ``B`` *at each frequency*, so it does not depend
on the units or the frequency scaling of ``B`` (``−Ω²``).  Directions whose
singular value is below ``α s_max`` (condition number above ``1/α``) are
damped by the filter factor ``s_k²/(s_k² + α² s_max²)``; ``α = 0`` is the plain
pseudo-inverse.  Each result reports the condition number ``s_max/s_min`` of
``B`` per frequency so that a threshold can be chosen (e.g. ``α = 1e-3`` for
data known to a few parts per thousand).

The three models of the thesis are the public entry points:

* :func:`half_wheelset_transfer` — one side, SISO (eq. 2.6 with ``1/K_H``):
  ``T = (A_33 + A_RZ + 1/K_H) / (−Ω² A_63)``;
* :func:`full_vertical_transfer` — both sides, vertical normals (eq. 2.11);
* :func:`vertical_lateral_transfer` — inclined contact planes and any ≥ 2
  channels (eq. 2.22 restricted to normal forces).

:func:`irregularity_to_acceleration` is the forward map ``a = B D⁻¹ n_irr``
and :func:`acceleration_to_irregularity` applies ``T``.

Numerics.  A pole-residue wheelset model is evaluated with each conjugate
pole pair in real-coefficient second-order form (for a mass-normalised
mode exactly the modal-sum term ``φφᵀ/(ω² − Ω² + 2iζωΩ)`` of eq. 2.28),
which avoids the cancellation between the two conjugate terms above a
mode.  A square unregularised ``B`` is inverted by LU (eq. 2.11 as
written), otherwise by the SVD above.  Everything is complex128.
"""

from __future__ import annotations

import logging
import math
import warnings
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ema.frf import FrequencyResponse
from receptance.contact import ContactParameterError, ContactParameters
from receptance.dofs import THESIS_DOFS
from receptance.pole_residue import PoleResidues, pole_pairs
from receptance.track import track_frf
from receptance.trackform import Trackform

__all__ = [
    "MeasurementTransfer",
    "TransferModelError",
    "MissingDOFError",
    "FrequencyAxisError",
    "TRANSFER_UNITS",
    "MODEL_KINDS",
    "contact_normals",
    "dof_label",
    "half_wheelset_transfer",
    "full_vertical_transfer",
    "vertical_lateral_transfer",
    "irregularity_to_acceleration",
    "acceleration_to_irregularity",
]

log = logging.getLogger("receptance")

#: units of the transfer functions: irregularity [m] per axlebox acceleration [m/s²]
TRANSFER_UNITS = "m/(m/s^2)"
#: names of the three thesis models
MODEL_KINDS = ("half", "vertical", "vertical_lateral")
#: default measured channels of each model (the instrumented train: two vertical, one lateral accelerometer)
DEFAULT_CHANNELS = {
    "vertical": ("axlebox_L:z", "axlebox_R:z"),
    "vertical_lateral": ("axlebox_L:z", "axlebox_R:z", "axlebox_R:y"),
}
SIDES = ("L", "R")


class TransferModelError(ValueError):
    """A transfer-function configuration that cannot be solved (channels, angles, normals, side, irregularity)."""


class MissingDOFError(KeyError):
    """The wheelset or track model lacks DOF labels a transfer function needs (names them and what exists)."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""


class FrequencyAxisError(ValueError):
    """Frequency axes that disagree, or a 0 Hz line (where ``B = −Ω² A_B`` vanishes)."""


# --------------------------------------------------------------------------- small helpers
def dof_label(dof) -> str:
    """The name of a wheelset DOF: thesis numbers 1–12 (Fig. 2.5, int or digit string) map to names.

    ``dof_label(3) == "contact_L:z"``, ``dof_label("axlebox_R:y") == "axlebox_R:y"``.
    """
    if isinstance(dof, (int, np.integer)) or (isinstance(dof, str) and dof.strip().isdigit()):
        n = int(dof)
        if n not in THESIS_DOFS:
            raise TransferModelError(f"DOF number {n} is not in the thesis numbering 1–12 (Fig. 2.5)")
        return THESIS_DOFS[n]
    return str(dof)


def contact_normals(theta_l: float = 0.0, theta_r: float = 0.0) -> np.ndarray:
    """Unit contact normals in the ``(y, z)`` plane from the contact-plane angles (eq. 2.12).

    Parameters
    ----------
    theta_l, theta_r : float
        Contact-plane angles ``θ_L``, ``θ_R`` [rad] from the horizontal
        (``y``) direction, sign convention of thesis Fig. 2.7 / eq. 2.12.

    Returns
    -------
    ndarray (2, 2)
        Rows ``(n_y, n_z) = (−sin θ, cos θ)`` for the left and right side
        (second column of ``Λ(θ)``, eq. 2.12).
    """
    th = np.array([theta_l, theta_r], dtype=float)
    if not np.all(np.isfinite(th)):
        raise TransferModelError(f"contact-plane angles must be finite [rad], got theta_l={theta_l!r}, "
                                 f"theta_r={theta_r!r}")
    if np.any(np.abs(th) >= np.pi / 2):
        raise TransferModelError(f"contact-plane angles must lie in (−π/2, π/2) rad (the normal must have an "
                                 f"upward component), got theta_l={theta_l!r}, theta_r={theta_r!r}; "
                                 "angles are in radians")
    return np.column_stack([-np.sin(th), np.cos(th)])


def _as_normals(normals, n_sides: int) -> np.ndarray:
    n = np.asarray(normals, dtype=float)
    if n.shape != (n_sides, 2):
        raise TransferModelError(f"normals must have shape ({n_sides}, 2): one (n_y, n_z) unit vector per side "
                                 f"{SIDES[:n_sides]}, got shape {n.shape}")
    norm = np.linalg.norm(n, axis=1)
    if not np.all(np.isfinite(n)) or np.any(norm == 0):
        raise TransferModelError(f"normals must be finite and non-zero, got {n.tolist()}")
    if np.any(np.abs(norm - 1) > 1e-9):
        warnings.warn(f"contact normals {n.tolist()} are not unit vectors; normalised", stacklevel=3)
    return n / norm[:, None]


@dataclass(frozen=True)
class _Layout:
    """Which DOFs a model needs and how normal forces map onto them.

    ``contact`` are the contact DOF labels actually used (y DOFs are left out
    when every normal is vertical), ``N`` (len(contact), n_sides) places the
    normal force of each side on them, ``channels`` the measured outputs.
    """

    kind: str
    sides: tuple[str, ...]
    normals: np.ndarray
    contact: tuple[str, ...]
    N: np.ndarray
    channels: tuple[str, ...]

    @property
    def lateral_track(self) -> bool:
        return bool(np.any(self.normals[:, 0] != 0))


def _layout(kind: str, sides: Sequence[str], normals: np.ndarray, channels: Sequence) -> _Layout:
    channels = tuple(dof_label(c) for c in channels)
    if len(set(channels)) != len(channels):
        raise TransferModelError(f"measured channels must be unique, got {list(channels)}")
    n_sides = len(sides)
    if len(channels) < n_sides:
        raise TransferModelError(
            f"the {kind!r} model has {n_sides} unknown contact forces and needs at least {n_sides} measured "
            f"channel(s), got {len(channels)}: {list(channels)}")
    contact, rows = [], []
    for k, side in enumerate(sides):
        for axis, comp in (("y", 0), ("z", 1)):
            if normals[k, comp] != 0:
                contact.append(f"contact_{side}:{axis}")
                row = np.zeros(n_sides)
                row[k] = normals[k, comp]
                rows.append(row)
    return _Layout(kind, tuple(sides), normals, tuple(contact), np.array(rows), channels)


def _check_freqs(f, what: str) -> np.ndarray:
    f = np.atleast_1d(np.asarray(f, dtype=float))
    if f.ndim != 1 or f.size == 0 or not np.all(np.isfinite(f)):
        raise FrequencyAxisError(f"{what}: the frequency axis must be a non-empty 1-D array of finite values [Hz]")
    if np.any(f <= 0):
        raise FrequencyAxisError(
            f"{what}: frequency axis contains {f[f <= 0][:3].tolist()} Hz; the transfer functions are singular at "
            "0 Hz (B = −Ω² A_B vanishes) — start the axis above 0 Hz")
    return f


def _same_axis(f_ref: np.ndarray, f_other, what: str) -> None:
    f_other = np.asarray(f_other, dtype=float)
    if f_other.shape != f_ref.shape or not np.allclose(f_other, f_ref, rtol=1e-12, atol=0.0):
        raise FrequencyAxisError(
            f"{what} has {f_other.size} lines over {f_other.min():g}–{f_other.max():g} Hz but the transfer "
            f"function is evaluated on {f_ref.size} lines over {f_ref.min():g}–{f_ref.max():g} Hz; evaluate both "
            "on the same frequency axis")


def _receptances(model, freqs_hz, layout: _Layout) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Wheelset receptances ``A_W`` (n_f, c, c) and ``A_B`` (n_f, m, c) at the layout's DOFs."""
    outputs = list(dict.fromkeys(layout.contact + layout.channels))
    inputs = list(layout.contact)
    if isinstance(model, FrequencyResponse):
        f = _check_freqs(model.freqs_hz, "wheelset receptance")
        if freqs_hz is not None:
            _same_axis(f, _check_freqs(freqs_hz, "freqs_hz"), "the wheelset receptance (FrequencyResponse)")
        if model.quantity == "transfer":
            raise TransferModelError("the wheelset model must be a receptance (or mobility/accelerance), "
                                     "got a 'transfer' FrequencyResponse")
        H = model.as_quantity("receptance")
        _require(H.outputs, H.inputs, outputs, inputs, "wheelset receptance (FrequencyResponse)", layout)
        data = H.select(outputs=outputs, inputs=inputs).data
    else:
        if freqs_hz is None:
            raise FrequencyAxisError("give freqs_hz: the wheelset model is a pole-residue model, not a sampled "
                                     "FrequencyResponse")
        f = _check_freqs(freqs_hz, "freqs_hz")
        if isinstance(model, PoleResidues):
            _require(model.outputs, model.inputs, outputs, inputs, "wheelset model (PoleResidues)", layout)
            pr = model.select(outputs, inputs)
        elif hasattr(model, "pole_residues"):  # ModalModel and friends
            pr = model.pole_residues(outputs, inputs)
        else:
            raise TypeError(f"the wheelset model must be a PoleResidues, a FrequencyResponse (receptance) or have "
                            f"a pole_residues(outputs, inputs) method, got {type(model).__name__}")
        data = _pair_receptance(pr, f)
    H = np.moveaxis(data, 2, 0)  # (n_f, n_out, n_in)
    pos = {lab: i for i, lab in enumerate(outputs)}
    A_W = H[:, [pos[c] for c in layout.contact], :]
    A_B = H[:, [pos[c] for c in layout.channels], :]
    return f, A_W, A_B


def _pair_receptance(pr: PoleResidues, f: np.ndarray) -> np.ndarray:
    """Receptance (n_out, n_in, n_f) of a pole-residue model, conjugate pairs in real-coefficient form.

    ``R/(s−λ) + R̄/(s−λ̄) = [2 Re R (s − Re λ) − 2 Im R Im λ] / (s² − 2 Re λ s + |λ|²)``: the same
    function as :meth:`PoleResidues.evaluate`, without the cancellation between the two conjugate
    terms above a mode (for a mass-normalised real mode the numerator is exactly ``φφᵀ``, the
    modal sum of eq. 2.28).  Models that are not conjugate-symmetric use ``evaluate``.
    """
    try:
        upper, lower = pole_pairs(pr.poles)
    except ValueError:
        return pr.evaluate(f, "receptance").data
    R = pr.residues
    scale = max(np.abs(R).max(initial=0.0), np.finfo(float).tiny)
    if upper.size and np.abs(R[:, :, lower] - R[:, :, upper].conj()).max() > 1e-12 * scale:
        return pr.evaluate(f, "receptance").data
    Om = 2 * np.pi * f
    s = 1j * Om
    lam = pr.poles[upper]
    sig, wd = lam.real, lam.imag
    den = (sig**2 + wd**2)[:, None] - Om**2 + 1j * (-2 * sig)[:, None] * Om  # (k, n_f)
    Ru = R[:, :, upper]
    H = np.tensordot(-2 * Ru.imag * wd, 1.0 / den, axes=([2], [0]))
    if np.any(Ru.real != 0):
        H = H + np.tensordot(2 * Ru.real, (s[None, :] - sig[:, None]) / den, axes=([2], [0]))
    real = np.setdiff1d(np.arange(pr.poles.size), np.concatenate([upper, lower]))
    if real.size:
        H = H + np.tensordot(R[:, :, real], 1.0 / (s[None, :] - pr.poles[real, None]), axes=([2], [0]))
    if np.any(pr.mass_line != 0):
        H = H - pr.mass_line[:, :, None] / Om**2
    return H


def _require(outputs_have: Sequence[str], inputs_have: Sequence[str], outputs: Sequence[str],
             inputs: Sequence[str], source: str, layout: _Layout) -> None:
    """Raise :class:`MissingDOFError` naming every missing output and input label."""
    miss_o = [lab for lab in outputs if lab not in set(outputs_have)]
    miss_i = [lab for lab in inputs if lab not in set(inputs_have)]
    if miss_o or miss_i:
        parts = []
        if miss_o:
            parts.append(f"output DOF(s) {miss_o} (it has outputs {list(outputs_have)})")
        if miss_i:
            parts.append(f"input DOF(s) {miss_i} (it has inputs {list(inputs_have)})")
        raise MissingDOFError(
            f"the {layout.kind!r} transfer function needs " + " and ".join(parts) + f" from the {source}; "
            "contact DOFs are 'contact_L:y', 'contact_L:z', 'contact_R:y', 'contact_R:z' = thesis DOFs 2, 3, 8, 9")


def _rail(track, f: np.ndarray, lateral: bool) -> tuple[np.ndarray, np.ndarray]:
    """Rail receptances ``(A_RY, A_RZ)`` [m/N] on ``f`` (eq. 2.18)."""
    if isinstance(track, str):
        if track != "rigid":
            raise TransferModelError(f"track must be a Trackform, a FrequencyResponse (track_frf) or 'rigid', "
                                     f"got {track!r}")
        z = np.zeros(f.size, complex)
        return z, z.copy()
    if track is None:
        track = Trackform()
    if isinstance(track, Trackform):
        track = track_frf(f, track)
    if not isinstance(track, FrequencyResponse):
        raise TypeError(f"track must be a Trackform, a FrequencyResponse (track_frf) or 'rigid', "
                        f"got {type(track).__name__}")
    _same_axis(f, track.freqs_hz, "the track receptance")
    if track.quantity != "receptance":
        track = track.as_quantity("receptance")
    need = ["rail_z"] + (["rail_y"] if lateral else [])
    missing = [lab for lab in need if lab not in track.outputs or lab not in track.inputs]
    if missing:
        raise MissingDOFError(f"the track receptance needs DOF(s) {missing} (as output and input, as track_frf "
                              f"gives), it has outputs {list(track.outputs)} and inputs {list(track.inputs)}")
    zz = track.select(outputs=["rail_z"], inputs=["rail_z"]).data[0, 0]
    if lateral:
        yy = track.select(outputs=["rail_y"], inputs=["rail_y"]).data[0, 0]
    else:
        yy = np.zeros(f.size, complex)
    return yy, zz


def _compliances(contact, n_sides: int) -> np.ndarray:
    """``1/K_H`` per side [m/N]; ``K_H = inf`` is a rigid contact."""
    if contact is None:
        contact = ContactParameters()
    if isinstance(contact, ContactParameters):
        k = np.full(n_sides, contact.stiffness())
    else:
        k = np.atleast_1d(np.asarray(contact, dtype=float))
        if k.size == 1:
            k = np.full(n_sides, k[0])
        if k.shape != (n_sides,):
            raise ContactParameterError("contact_stiffness", contact,
                                        f"one K_H [N/m] or one per side {SIDES[:n_sides]}")
    if np.any(np.isnan(k)) or np.any(k <= 0):
        raise ContactParameterError("contact_stiffness", contact, "K_H > 0 N/m (math.inf for a rigid contact)")
    return 1.0 / k


# --------------------------------------------------------------------------- result
@dataclass(frozen=True, eq=False)
class MeasurementTransfer:
    """A transfer function ``n_irr = T a`` of the measurement system and the pieces it was made of.

    Attributes
    ----------
    transfer : FrequencyResponse
        ``T`` (quantity ``"transfer"``, units ``m/(m/s^2)``), shape
        ``(n_sides, m, n_f)``: outputs ``("irr_L", "irr_R")`` (or the one
        side of the half model), inputs the channel labels.
    condition : ndarray (n_f,)
        2-norm condition number ``s_max/s_min`` of ``B`` per frequency (1
        for the SISO half model).
    dynamic_compliance : FrequencyResponse
        ``D = Nᵀ(A_W + A_R)N + diag(1/K_H)`` (receptance, m/N), outputs
        ``irr_*``, inputs ``Fn_*`` (eq. 2.9/2.20).
    force_to_acceleration : FrequencyResponse
        ``B = −Ω² A_B N`` (accelerance), outputs the channels, inputs ``Fn_*``
        (eq. 2.4/2.10/2.21).
    wheel_compliance, rail_compliance : FrequencyResponse
        The wheel ``Nᵀ A_W N`` and rail ``Nᵀ A_R N`` parts of ``D``
        (receptance, same labels as ``dynamic_compliance``).
    contact_compliance : ndarray (n_sides,)
        ``1/K_H`` per side [m/N].
    normals : ndarray (n_sides, 2)
        Unit contact normals ``(n_y, n_z)``.
    sides : tuple of str
    channels : tuple of str
    regularisation : float
        Relative Tikhonov parameter ``α`` (module docstring).
    model : {"half", "vertical", "vertical_lateral"}
    """

    transfer: FrequencyResponse
    condition: np.ndarray
    dynamic_compliance: FrequencyResponse
    force_to_acceleration: FrequencyResponse
    wheel_compliance: FrequencyResponse
    rail_compliance: FrequencyResponse
    contact_compliance: np.ndarray
    normals: np.ndarray
    sides: tuple[str, ...]
    channels: tuple[str, ...]
    regularisation: float
    model: str

    @property
    def freqs_hz(self) -> np.ndarray:
        return self.transfer.freqs_hz

    def __repr__(self) -> str:
        f = self.freqs_hz
        return (f"MeasurementTransfer({self.model!r}, sides {self.sides}, channels {self.channels}, "
                f"{f.size} lines {f[0]:g}–{f[-1]:g} Hz, max cond {np.nanmax(self.condition):.3g})")


def _pinv(B: np.ndarray, alpha: float) -> tuple[np.ndarray, np.ndarray]:
    """Per-frequency (Tikhonov) pseudo-inverse of ``B`` (n_f, m, n) and its condition numbers."""
    U, s, Vh = np.linalg.svd(B, full_matrices=False)
    smax = s[:, :1]
    with np.errstate(divide="ignore", invalid="ignore"):
        cond = s[:, 0] / s[:, -1]
        filt = s / (s * s + (alpha * smax) ** 2) if alpha > 0 else 1.0 / s
    bad = ~np.isfinite(filt).all(axis=1)
    if np.any(bad):
        warnings.warn(f"B is singular at {int(bad.sum())} frequency line(s); T is not finite there "
                      "(use regularisation > 0)", stacklevel=4)
    pinv = np.conj(np.swapaxes(Vh, 1, 2)) * filt[:, None, :] @ np.conj(np.swapaxes(U, 1, 2))
    return pinv, cond


def _build(kind: str, model, freqs_hz, layout: _Layout, track, compliance: np.ndarray, regularisation: float,
           ) -> MeasurementTransfer:
    alpha = float(regularisation)
    if not math.isfinite(alpha) or alpha < 0:
        raise TransferModelError(f"regularisation must be a finite number >= 0 (relative to the largest singular "
                                 f"value of B), got {regularisation!r}")
    f, A_W, A_B = _receptances(model, freqs_hz, layout)
    ARY, ARZ = _rail(track, f, layout.lateral_track)
    c = np.asarray(compliance, dtype=float)
    N = layout.N
    W = np.einsum("ci,fcd,dj->fij", N, A_W, N)
    # rail receptance on the contact DOFs (eq. 2.18): A_RY on y DOFs, A_RZ on z DOFs, no cross terms
    rail_diag = np.stack([ARY if lab.endswith(":y") else ARZ for lab in layout.contact], axis=1)  # (n_f, c)
    R = np.einsum("ci,fc,cj->fij", N, rail_diag, N)
    D = W + R + np.diag(c)[None]
    Om2 = (2 * np.pi * f) ** 2
    B = -Om2[:, None, None] * (A_B @ N)
    if len(layout.sides) == 1:
        with np.errstate(divide="ignore", invalid="ignore"):
            T = D / B
        cond = np.ones(f.size)
        if not np.all(np.isfinite(T)):
            warnings.warn("B = −Ω² A_63 vanishes at some frequency lines; T is not finite there", stacklevel=3)
    else:
        T = None
        if alpha == 0 and B.shape[1] == B.shape[2]:  # square: T = D B⁻¹ by LU (eq. 2.11 as written)
            sv = np.linalg.svd(B, compute_uv=False)
            with np.errstate(divide="ignore"):
                cond = sv[:, 0] / sv[:, -1]
            try:
                T = np.swapaxes(np.linalg.solve(np.swapaxes(B, 1, 2), np.swapaxes(D, 1, 2)), 1, 2)
            except np.linalg.LinAlgError:
                T = None  # exactly singular somewhere: the pseudo-inverse path warns and says where
        if T is None:
            Bp, cond = _pinv(B, alpha)
            T = D @ Bp
    irr = tuple(f"irr_{s}" for s in layout.sides)
    fn = tuple(f"Fn_{s}" for s in layout.sides)
    hist = (f"{kind} transfer function (thesis eq. {_EQ[kind]}), channels {list(layout.channels)}, "
            f"normals {np.round(layout.normals, 6).tolist()}, 1/K_H {c.tolist()} m/N, alpha {alpha:g}",)

    def fr(data, outs, ins, quantity, units=""):
        return FrequencyResponse(freqs_hz=f, data=np.moveaxis(data, 0, 2), outputs=outs, inputs=ins,
                                 quantity=quantity, units=units, history=hist)

    return MeasurementTransfer(
        transfer=fr(T, irr, layout.channels, "transfer", TRANSFER_UNITS),
        condition=cond,
        dynamic_compliance=fr(D, irr, fn, "receptance"),
        force_to_acceleration=fr(B, layout.channels, fn, "accelerance"),
        wheel_compliance=fr(W, irr, fn, "receptance"),
        rail_compliance=fr(R, irr, fn, "receptance"),
        contact_compliance=c,
        normals=layout.normals.copy(),
        sides=layout.sides,
        channels=layout.channels,
        regularisation=alpha,
        model=kind,
    )


_EQ = {"half": "2.6", "vertical": "2.11", "vertical_lateral": "2.22"}


# --------------------------------------------------------------------------- public entry points
def half_wheelset_transfer(model, freqs_hz=None, *, side: str = "L", channel=None, track=None,
                           contact_stiffness=None) -> MeasurementTransfer:
    """Half-wheelset (SISO) transfer function, thesis eq. 2.6 (with ``1/K_H``, the thesis prints ``K_H``).

    ``z_irr = T z̈_A`` with ``T = (A_33 + A_RZ + 1/K_H) / (−Ω² A_63)`` for the
    left side (``A_99``, ``A_12,9`` for the right): the two halves of the
    wheelset and the two rails are decoupled and the contact is vertical
    (thesis §2.2.1, Karaki et al.).

    Parameters
    ----------
    model : PoleResidues, FrequencyResponse or ModalModel
        Wheelset receptance with outputs ``contact_<side>:z`` and ``channel``
        and input ``contact_<side>:z``.  A FrequencyResponse must be a
        receptance (mobility/accelerance are converted) on ``freqs_hz``.
    freqs_hz : array_like, optional
        Frequencies [Hz] (> 0); required for a pole-residue model, checked
        against a FrequencyResponse's axis.
    side : {"L", "R"}
    channel : str or int, optional
        Measured channel (default ``axlebox_<side>:z``, thesis DOF 6 or 12).
    track : Trackform, FrequencyResponse or "rigid", optional
        Rail receptance ``A_RZ`` (eq. 2.18): a :class:`Trackform` (default:
        thesis Table 2.2, continuous support) is evaluated with
        :func:`~receptance.track.track_frf`; a FrequencyResponse must have
        ``rail_z`` on the same axis; ``"rigid"`` is a rigid rail.
    contact_stiffness : float, sequence of 2 floats or ContactParameters, optional
        ``K_H`` [N/m] (default :class:`ContactParameters` ≈ 1.1e9 N/m);
        ``math.inf`` is a rigid contact.

    Returns
    -------
    MeasurementTransfer
        ``transfer`` has output ``irr_<side>`` and input ``channel``.

    Raises
    ------
    MissingDOFError, FrequencyAxisError, TransferModelError, ContactParameterError
    """
    if side not in SIDES:
        raise TransferModelError(f"side must be 'L' or 'R', got {side!r}")
    channel = f"axlebox_{side}:z" if channel is None else channel
    if isinstance(channel, (list, tuple)):
        raise TransferModelError(f"the half-wheelset model is SISO: give one channel, got {channel!r}")
    c = _compliances(contact_stiffness, 2)[SIDES.index(side)]
    layout = _layout("half", (side,), np.array([[0.0, 1.0]]), [channel])
    return _build("half", model, freqs_hz, layout, track, np.array([c]), 0.0)


def full_vertical_transfer(model, freqs_hz=None, *, channels: Sequence = DEFAULT_CHANNELS["vertical"],
                           track=None, contact_stiffness=None, regularisation: float = 0.0) -> MeasurementTransfer:
    """Full-wheelset vertical transfer function, thesis eq. 2.11 (2 inputs, ``m`` ≥ 2 outputs).

    ``[z_irr,L, z_irr,R] = D B⁺ a`` with ``D = [[A_33 + A_RZ + 1/K_H, A_39],
    [A_93, A_99 + A_RZ + 1/K_H]]`` (eq. 2.9) and ``B = −Ω² [[A_63, A_69],
    [A_12,3, A_12,9]]`` (eq. 2.10) for the default channels; for two channels
    this is eq. 2.11 exactly, more channels are solved in the least-squares
    sense.

    Parameters
    ----------
    model : PoleResidues, FrequencyResponse or ModalModel
        Outputs ``contact_L:z``, ``contact_R:z`` and ``channels``; inputs
        ``contact_L:z``, ``contact_R:z``.
    freqs_hz : array_like, optional
        See :func:`half_wheelset_transfer`.
    channels : sequence of str or int
        ≥ 2 measured channels (default ``("axlebox_L:z", "axlebox_R:z")``,
        thesis DOFs 6, 12).
    track, contact_stiffness
        See :func:`half_wheelset_transfer`.
    regularisation : float
        Relative Tikhonov parameter ``α`` ≥ 0 (module docstring; 0 = none).

    Returns
    -------
    MeasurementTransfer
        ``transfer`` outputs ``("irr_L", "irr_R")``, inputs ``channels``.
    """
    layout = _layout("vertical", SIDES, contact_normals(0.0, 0.0), channels)
    return _build("vertical", model, freqs_hz, layout, track, _compliances(contact_stiffness, 2), regularisation)


def vertical_lateral_transfer(model, freqs_hz=None, *, theta_l: float = 0.0, theta_r: float = 0.0, normals=None,
                              channels: Sequence = DEFAULT_CHANNELS["vertical_lateral"], track=None,
                              contact_stiffness=None, regularisation: float = 0.0) -> MeasurementTransfer:
    """Full-wheelset vertical + lateral transfer function, thesis eq. 2.22 restricted to normal forces.

    ``n_irr = D B⁺ a`` with ``D = Nᵀ(A_W + A_R)N + diag(1/K_H)`` (eq. 2.20,
    normal rows and columns) and ``B = −Ω² A_B N`` (eq. 2.21, normal
    columns), where the columns of ``N`` are the contact normals
    ``(−sin θ, cos θ)`` of eq. 2.12 on the contact DOFs 2, 3 (left) and 8, 9
    (right).  Tangential forces are neglected (thesis §2.2), so only the
    normal irregularities are unknown; any ``m`` ≥ 2 channels work (least
    squares for ``m`` > 2).

    Parameters
    ----------
    model : PoleResidues, FrequencyResponse or ModalModel
        Outputs ``contact_L:y, contact_L:z, contact_R:y, contact_R:z`` and
        ``channels``; the same four contact DOFs as inputs (the y DOFs only
        if a normal has a lateral component).
    freqs_hz : array_like, optional
        See :func:`half_wheelset_transfer`.
    theta_l, theta_r : float
        Contact-plane angles [rad] (eq. 2.12).
    normals : array_like (2, 2), optional
        Explicit unit normals ``(n_y, n_z)`` per side instead of the angles.
    channels : sequence of str or int
        ≥ 2 measured channels (default: the instrumented train's
        ``("axlebox_L:z", "axlebox_R:z", "axlebox_R:y")``).
    track : Trackform, FrequencyResponse or "rigid", optional
        Rail receptances ``A_RY``, ``A_RZ`` (``rail_y``, ``rail_z``).
    contact_stiffness, regularisation
        See :func:`full_vertical_transfer`.

    Returns
    -------
    MeasurementTransfer
        ``transfer`` outputs ``("irr_L", "irr_R")`` (normal irregularities), inputs ``channels``.
    """
    if normals is not None:
        if theta_l != 0.0 or theta_r != 0.0:
            raise TransferModelError("give either the contact-plane angles theta_l/theta_r or explicit normals, "
                                     "not both")
        nrm = _as_normals(normals, 2)
    else:
        nrm = contact_normals(theta_l, theta_r)
    layout = _layout("vertical_lateral", SIDES, nrm, channels)
    return _build("vertical_lateral", model, freqs_hz, layout, track, _compliances(contact_stiffness, 2),
                  regularisation)


# --------------------------------------------------------------------------- applying
def _per_side(x, n_rows: int, n_f: int, what: str, labels) -> np.ndarray:
    a = np.asarray(x, dtype=complex)
    if a.ndim == 1 and n_rows == 1:
        a = a[None]
    if a.shape != (n_rows, n_f):
        raise TransferModelError(f"{what} must have shape ({n_rows}, {n_f}) (rows {list(labels)}, one column per "
                                 f"frequency line), got {np.shape(x)}")
    return a


def irregularity_to_acceleration(transfer: MeasurementTransfer, irregularity) -> np.ndarray:
    """Forward map: accelerations ``a = B D⁻¹ n_irr`` produced by an irregularity spectrum.

    Parameters
    ----------
    transfer : MeasurementTransfer
    irregularity : array_like complex (n_sides, n_f)
        Normal irregularity spectra [m] per side (a 1-D array for the half model).

    Returns
    -------
    ndarray complex (m, n_f)
        Acceleration spectra [m/s²] at ``transfer.channels``.
    """
    f = transfer.freqs_hz
    n = _per_side(irregularity, len(transfer.sides), f.size, "irregularity", [f"irr_{s}" for s in transfer.sides])
    D = np.moveaxis(transfer.dynamic_compliance.data, 2, 0)
    B = np.moveaxis(transfer.force_to_acceleration.data, 2, 0)
    F = np.linalg.solve(D, n.T[:, :, None])
    return (B @ F)[:, :, 0].T


def acceleration_to_irregularity(transfer: MeasurementTransfer, accelerations) -> np.ndarray:
    """Apply ``T``: irregularity spectra ``n_irr = T a`` from acceleration spectra.

    Parameters
    ----------
    transfer : MeasurementTransfer
    accelerations : array_like complex (m, n_f)
        Acceleration spectra [m/s²] at ``transfer.channels`` (1-D for one channel).

    Returns
    -------
    ndarray complex (n_sides, n_f)
    """
    f = transfer.freqs_hz
    a = _per_side(accelerations, len(transfer.channels), f.size, "accelerations", transfer.channels)
    return np.einsum("ijf,jf->if", transfer.transfer.data, a)
