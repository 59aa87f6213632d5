"""Transfer functions of the measurement system (thesis eqs. 2.6, 2.11, 2.22) against closed forms.

The test wheelset is a small lumped free-free model in the (y, z) plane whose
mass-normalised modes come from ``scipy.linalg.eigh(K, M)``; its receptances
are recomputed here from the modal sum written out (eq. 2.28), independently
of ``PoleResidues.evaluate``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest
import scipy.linalg

from ema.frf import FrequencyResponse
from receptance.contact import ContactParameterError, ContactParameters
from receptance.pole_residue import PoleResidues
from receptance.track import track_frf, track_receptance
from receptance.trackform import Trackform
from receptance.transfer import (FrequencyAxisError, MissingDOFError, TransferModelError,
                                 acceleration_to_irregularity, contact_normals, dof_label, full_vertical_transfer,
                                 half_wheelset_transfer, irregularity_to_acceleration, vertical_lateral_transfer)

CONTACT = ("contact_L:y", "contact_L:z", "contact_R:y", "contact_R:z")


# --------------------------------------------------------------------------- test wheelset
@dataclass
class Lumped:
    """Lumped planar (y, z) free-free wheelset: masses at named points, modes from eigh(K, M)."""

    names: tuple
    yz: np.ndarray  # (n_points, 2)
    masses: np.ndarray  # (n_points,)
    labels: tuple  # DOF labels "<point>:y", "<point>:z"
    M: np.ndarray
    freqs_hz: np.ndarray  # (n_dof,), 0 for the 3 rigid modes
    shapes: np.ndarray  # (n_dof, n_modes) mass-normalised

    def rows(self, labels) -> np.ndarray:
        pos = {lab: i for i, lab in enumerate(self.labels)}
        return self.shapes[[pos[lab] for lab in labels]]

    def pole_residues(self, zeta=0.005, outputs=None, inputs=CONTACT, rigid_only=False) -> PoleResidues:
        outputs = self.labels if outputs is None else tuple(outputs)
        keep = self.freqs_hz == 0 if rigid_only else np.ones(self.freqs_hz.size, bool)
        return PoleResidues.from_modes(self.freqs_hz[keep], zeta, self.rows(outputs)[:, keep],
                                       self.rows(inputs)[:, keep], outputs, inputs)

    def receptance(self, f_hz, outputs, inputs, zeta=0.005) -> np.ndarray:
        """Modal sum Σ φφᵀ/(ω² − Ω² + 2iζωΩ) − Σ_rigid φφᵀ/Ω², shape (n_f, n_out, n_in), written out."""
        Om = 2 * np.pi * np.asarray(f_hz, float)
        w = 2 * np.pi * self.freqs_hz
        Po, Pi = self.rows(outputs), self.rows(inputs)
        H = np.zeros((Om.size, len(outputs), len(inputs)), complex)
        for r in range(w.size):
            outer = np.outer(Po[:, r], Pi[:, r])
            if w[r] == 0:
                H += -outer[None] / Om[:, None, None] ** 2
            else:
                H += outer[None] / (w[r] ** 2 - Om[:, None, None] ** 2 + 2j * zeta * w[r] * Om[:, None, None])
        return H


def lumped_wheelset(seed: int = 3, fmin: float = 40.0, fmax: float = 700.0) -> Lumped:
    """Nine lumped masses on a wheelset outline (y lateral, z up; left wheel at −y, contact 0.41 m below the axle).

    The stiffness is built so that its null space is exactly the three planar
    rigid-body motions (y, z translation and roll about x) and its flexible
    frequencies are ``geomspace(fmin, fmax)`` with a close pair; the modes are
    then solved with ``scipy.linalg.eigh(K, M)``.
    """
    pts = {"axlebox_L": (-0.97, 0.0), "hub_L": (-0.75, 0.0), "contact_L": (-0.75, -0.41), "top_L": (-0.75, 0.41),
           "centre": (0.0, 0.0), "top_R": (0.75, 0.41), "contact_R": (0.75, -0.41), "hub_R": (0.75, 0.0),
           "axlebox_R": (0.97, 0.0)}
    names = tuple(pts)
    yz = np.array([pts[n] for n in names])
    masses = np.array([60.0, 120.0, 90.0, 90.0, 250.0, 90.0, 90.0, 120.0, 60.0])
    labels = tuple(f"{n}:{a}" for n in names for a in "yz")
    n = len(labels)
    M = np.diag(np.repeat(masses, 2))
    # rigid-body modes (mass-normalised): translations and roll about the centre of mass
    c = masses @ yz / masses.sum()
    rel = yz - c
    R = np.zeros((n, 3))
    R[0::2, 0] = 1.0
    R[1::2, 1] = 1.0
    R[0::2, 2] = -rel[:, 1]
    R[1::2, 2] = rel[:, 0]
    R /= np.sqrt(np.einsum("ir,ij,jr->r", R, M, R))
    rng = np.random.default_rng(seed)
    X = rng.standard_normal((n, n - 3))
    X -= R @ (R.T @ M @ X)
    X = X @ np.linalg.inv(np.linalg.cholesky(X.T @ M @ X)).T
    w_flex = 2 * np.pi * np.geomspace(fmin, fmax, n - 3)
    w_flex[4] = w_flex[3] * 1.02  # a close pair
    K = M @ X @ np.diag(w_flex**2) @ X.T @ M
    K = 0.5 * (K + K.T)
    ev, shapes = scipy.linalg.eigh(K, M)
    ev[:3] = 0.0  # the three rigid-body modes (|ev| ~ 1e-9 of the largest)
    return Lumped(names, yz, masses, labels, M, np.sqrt(ev) / (2 * np.pi), shapes)


@pytest.fixture(scope="module")
def wheelset():
    return lumped_wheelset()


F_TEST = np.linspace(5.0, 800.0, 397)


def _rel(a, b):
    return np.abs(a - b).max() / np.abs(b).max()


# --------------------------------------------------------------------------- model sanity
def test_lumped_wheelset_modes_are_mass_normalised_with_three_rigid_modes(wheelset):
    ws = wheelset
    np.testing.assert_allclose(ws.shapes.T @ ws.M @ ws.shapes, np.eye(len(ws.labels)), atol=1e-10)
    assert np.count_nonzero(ws.freqs_hz == 0) == 3
    np.testing.assert_allclose(ws.freqs_hz[3], 40.0, rtol=1e-9)
    pr = ws.pole_residues(outputs=CONTACT + ("axlebox_L:z",))
    H = pr.evaluate(F_TEST).data
    np.testing.assert_allclose(np.moveaxis(H, 2, 0), ws.receptance(F_TEST, CONTACT + ("axlebox_L:z",), CONTACT),
                               rtol=1e-10, atol=1e-22)


def test_contact_normals_follow_eq_2_12():
    n = contact_normals(math.radians(30), -0.1)
    np.testing.assert_allclose(n[0], [-0.5, math.sqrt(3) / 2], rtol=1e-15)
    np.testing.assert_allclose(n[1], [math.sin(0.1), math.cos(0.1)], rtol=1e-15)
    # the normal is the second column of Λ(θ) (eq. 2.12), orthogonal to the tangent (cos θ, sin θ)
    th = 0.3
    lam = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
    np.testing.assert_allclose(contact_normals(th, th)[0], lam[:, 1], rtol=1e-15)
    assert dof_label(3) == "contact_L:z" and dof_label("12") == "axlebox_R:z" and dof_label("x:y") == "x:y"


# --------------------------------------------------------------------------- literal thesis equations
def test_half_model_is_eq_2_6_with_hertz_compliance(wheelset):
    ws = wheelset
    pr = ws.pole_residues()
    kh = ContactParameters().stiffness()
    for side, d, a in (("L", "contact_L:z", "axlebox_L:z"), ("R", "contact_R:z", "axlebox_R:z")):
        tf = half_wheelset_transfer(pr, F_TEST, side=side)
        A = ws.receptance(F_TEST, [d, a], [d])
        ARZ = track_receptance(F_TEST, Trackform(), "vertical")
        Om2 = (2 * np.pi * F_TEST) ** 2
        expected = (A[:, 0, 0] + ARZ + 1 / kh) / (-Om2 * A[:, 1, 0])  # eq. 2.6, K_H -> 1/K_H
        assert tf.transfer.outputs == (f"irr_{side}",) and tf.transfer.inputs == (a,)
        assert tf.transfer.quantity == "transfer" and tf.transfer.units == "m/(m/s^2)"
        assert _rel(tf.transfer.data[0, 0], expected) < 1e-12
        np.testing.assert_array_equal(tf.condition, 1.0)


@pytest.mark.parametrize("use_lateral_entry", [False, True])
def test_theta_zero_equals_eq_2_11_written_out(wheelset, use_lateral_entry):
    ws = wheelset
    pr = ws.pole_residues()
    kh = 1.3e9
    if use_lateral_entry:
        tf = vertical_lateral_transfer(pr, F_TEST, theta_l=0.0, theta_r=0.0, channels=(6, 12), contact_stiffness=kh)
    else:
        tf = full_vertical_transfer(pr, F_TEST, contact_stiffness=kh)
    out = ["contact_L:z", "contact_R:z", "axlebox_L:z", "axlebox_R:z"]
    A = ws.receptance(F_TEST, out, ["contact_L:z", "contact_R:z"])
    ARZ = track_receptance(F_TEST, Trackform(), "vertical")
    A33, A39, A93, A99 = A[:, 0, 0], A[:, 0, 1], A[:, 1, 0], A[:, 1, 1]
    A63, A69, A123, A129 = A[:, 2, 0], A[:, 2, 1], A[:, 3, 0], A[:, 3, 1]
    Om2 = (2 * np.pi * F_TEST) ** 2
    det = A63 * A129 - A69 * A123
    inv = np.array([[A129, -A69], [-A123, A63]]) / det  # explicit 2x2 inverse of eq. 2.10's matrix
    D = np.array([[A33 + ARZ + 1 / kh, A39], [A93, A99 + ARZ + 1 / kh]])  # eq. 2.9
    T = -np.einsum("ijf,jkf->ikf", D, inv) / Om2  # eq. 2.11
    assert tf.transfer.inputs == ("axlebox_L:z", "axlebox_R:z")
    assert _rel(tf.transfer.data, T) < 1e-12
    np.testing.assert_allclose(tf.condition, np.linalg.cond(np.moveaxis(inv, 2, 0)), rtol=1e-9)


def test_zero_cross_receptances_reduce_full_vertical_to_two_half_models():
    # left DOFs only move in modes 0-3, right DOFs only in modes 4-7: A_39 = A_93 = A_6,9 = A_12,3 = 0
    rng = np.random.default_rng(7)
    f_modes = np.array([55.0, 130.0, 260.0, 410.0, 60.0, 140.0, 250.0, 430.0])
    outs = ("contact_L:z", "axlebox_L:z", "contact_R:z", "axlebox_R:z")
    shapes = np.zeros((4, 8))
    shapes[:2, :4] = rng.uniform(0.02, 0.1, (2, 4))
    shapes[2:, 4:] = rng.uniform(0.02, 0.1, (2, 4))
    pr = PoleResidues.from_modes(f_modes, 0.01, shapes, shapes[[0, 2]], outs, ("contact_L:z", "contact_R:z"))
    full = full_vertical_transfer(pr, F_TEST)
    for k, side in enumerate("LR"):
        half = half_wheelset_transfer(pr, F_TEST, side=side)
        assert _rel(full.transfer.data[k, k], half.transfer.data[0, 0]) < 1e-12
    assert np.all(full.transfer.data[0, 1] == 0) and np.all(full.transfer.data[1, 0] == 0)


def test_four_channels_equal_thesis_4x4_form_restricted_to_normal_forces(wheelset):
    ws = wheelset
    pr = ws.pole_residues()
    thl, thr = 0.12, -0.35
    kh = ContactParameters().stiffness()
    chans = ("axlebox_L:y", "axlebox_L:z", "axlebox_R:y", "axlebox_R:z")  # thesis DOFs 5, 6, 11, 12
    tf = vertical_lateral_transfer(pr, F_TEST, theta_l=thl, theta_r=thr, channels=(5, 6, 11, 12))
    assert tf.channels == chans
    # eq. 2.13 with row 2 corrected to (sin θ_L, cos θ_L, 0, 0)
    cl, sl, cr, sr = math.cos(thl), math.sin(thl), math.cos(thr), math.sin(thr)
    Lam = np.array([[cl, -sl, 0, 0], [sl, cl, 0, 0], [0, 0, cr, -sr], [0, 0, sr, cr]])
    AW = ws.receptance(F_TEST, CONTACT, CONTACT)  # eq. 2.17
    AB = ws.receptance(F_TEST, chans, CONTACT)  # eq. 2.21
    ary = track_receptance(F_TEST, Trackform(), "lateral")
    arz = track_receptance(F_TEST, Trackform(), "vertical")
    AR = np.zeros_like(AW)
    AR[:, 0, 0] = AR[:, 2, 2] = ary
    AR[:, 1, 1] = AR[:, 3, 3] = arz  # eq. 2.18
    AHn = np.diag([0.0, 1.0, 0.0, 1.0]) / kh  # eq. 2.19 (compliance 1/K_H on the normal rows)
    D4 = Lam.T @ AW @ Lam + Lam.T @ AR @ Lam + AHn  # eq. 2.20
    Om2 = (2 * np.pi * F_TEST) ** 2
    B4 = -Om2[:, None, None] * (AB @ Lam)  # eq. 2.21 in t-n forces
    n = [1, 3]  # normal rows/columns; tangential forces are zero (thesis §2.2)
    D = D4[:, n][:, :, n]
    B = B4[:, :, n]
    T = np.stack([D[k] @ np.linalg.lstsq(B[k], np.eye(4), rcond=None)[0] for k in range(F_TEST.size)])
    assert _rel(np.moveaxis(tf.transfer.data, 2, 0), T) < 1e-11
    # with θ = 0 the 4x4 Λ is the identity and the normal part is the vertical model with 4 channels
    tf0 = vertical_lateral_transfer(pr, F_TEST, channels=chans)
    tfv = full_vertical_transfer(pr, F_TEST, channels=chans)
    assert _rel(tf0.transfer.data, tfv.transfer.data) < 1e-13


@pytest.mark.parametrize("channels", [
    ("axlebox_L:z", "axlebox_R:z"),
    ("axlebox_L:z", "axlebox_R:z", "axlebox_R:y"),
    ("axlebox_L:y", "axlebox_L:z", "axlebox_R:y", "axlebox_R:z"),
])
def test_forward_then_inverse_returns_the_irregularity(wheelset, channels):
    pr = wheelset.pole_residues()
    tf = vertical_lateral_transfer(pr, F_TEST, theta_l=0.05, theta_r=-0.3, channels=channels)
    rng = np.random.default_rng(0)
    n = rng.standard_normal((2, F_TEST.size)) + 1j * rng.standard_normal((2, F_TEST.size))
    a = irregularity_to_acceleration(tf, n)
    assert a.shape == (len(channels), F_TEST.size)
    # the forward map is the physics: a = B F, n = D F with F solved from n
    D = np.moveaxis(tf.dynamic_compliance.data, 2, 0)
    F = np.linalg.solve(D, n.T[:, :, None])
    np.testing.assert_allclose(np.einsum("fij,fj->if", D, F[:, :, 0]), n, atol=1e-12)
    back = acceleration_to_irregularity(tf, a)
    err = np.abs(back - n).max(axis=0) / np.abs(n).max(axis=0)
    assert err.max() < 1e-13 * tf.condition.max() * 10


def test_frequency_response_model_gives_the_same_transfer(wheelset):
    pr = wheelset.pole_residues()
    H = pr.evaluate(F_TEST)
    a = vertical_lateral_transfer(pr, F_TEST, theta_l=0.1)
    b = vertical_lateral_transfer(H, theta_l=0.1)
    c = vertical_lateral_transfer(H.as_quantity("accelerance"), F_TEST, theta_l=0.1)
    assert _rel(b.transfer.data, a.transfer.data) < 1e-14
    assert _rel(c.transfer.data, a.transfer.data) < 1e-12
    # a track FrequencyResponse on the same axis equals the Trackform default
    d = vertical_lateral_transfer(pr, F_TEST, theta_l=0.1, track=track_frf(F_TEST))
    np.testing.assert_array_equal(d.transfer.data, a.transfer.data)


# --------------------------------------------------------------------------- rigid wheelset
def _rigid_body(ws: Lumped):
    """Generalised mass and Jacobian rows of the rigid planar body (y_c, z_c, roll about x at the CoM)."""
    c = ws.masses @ ws.yz / ws.masses.sum()
    J = np.sum(ws.masses * np.sum((ws.yz - c) ** 2, axis=1))
    Mq = np.diag([ws.masses.sum(), ws.masses.sum(), J])
    pos = {n: ws.yz[i] - c for i, n in enumerate(ws.names)}

    def row(point, d):  # displacement of `point` along unit d = (d_y, d_z) per generalised coordinate
        y, z = pos[point]
        return np.array([d[0], d[1], d[1] * y - d[0] * z])

    return Mq, row


def test_rigid_wheelset_on_rigid_track_vertical_is_pure_kinematics(wheelset):
    """Mass line only, K_H = ∞, rigid rail: the contact points follow the irregularity and the axlebox
    accelerations are the rigid-body interpolation of the contact motion, T = −(1/Ω²) J_c J_a⁻¹."""
    ws = wheelset
    pr = ws.pole_residues(rigid_only=True)
    assert pr.poles.size == 0
    tf = full_vertical_transfer(pr, F_TEST, track="rigid", contact_stiffness=math.inf)
    yl, yr = ws.yz[ws.names.index("contact_L"), 0], ws.yz[ws.names.index("contact_R"), 0]
    al, ar = ws.yz[ws.names.index("axlebox_L"), 0], ws.yz[ws.names.index("axlebox_R"), 0]
    # contact z = z_0 + y φ, axlebox z = z_0 + y φ  (z_0 at y = 0, φ roll): n = Jc q, z_A = Ja q
    Jc = np.array([[1, yl], [1, yr]])
    Ja = np.array([[1, al], [1, ar]])
    Om2 = (2 * np.pi * F_TEST) ** 2
    T = -(Jc @ np.linalg.inv(Ja))[:, :, None] / Om2
    assert _rel(tf.transfer.data, T) < 1e-12
    # numbers: ρ = b_a/b_c = 0.97/0.75; T·(−Ω²) = [[(1+1/ρ)/2, (1−1/ρ)/2], [(1−1/ρ)/2, (1+1/ρ)/2]]
    rho = 0.97 / 0.75
    np.testing.assert_allclose(-tf.transfer.data[:, :, 0] * Om2[0],
                               [[(1 + 1 / rho) / 2, (1 - 1 / rho) / 2], [(1 - 1 / rho) / 2, (1 + 1 / rho) / 2]],
                               rtol=1e-12)


def test_rigid_wheelset_lateral_matches_newton_euler(wheelset):
    ws = wheelset
    pr = ws.pole_residues(rigid_only=True)
    thl, thr = 0.4, -0.25
    chans = ("axlebox_L:z", "axlebox_R:z", "axlebox_R:y")
    tf = vertical_lateral_transfer(pr, F_TEST, theta_l=thl, theta_r=thr, channels=chans, track="rigid",
                                   contact_stiffness=math.inf)
    Mq, row = _rigid_body(ws)
    nrm = contact_normals(thl, thr)
    Jn = np.array([row("contact_L", nrm[0]), row("contact_R", nrm[1])])  # normal displacement per q
    C = np.array([row("axlebox_L", (0, 1)), row("axlebox_R", (0, 1)), row("axlebox_R", (1, 0))])
    Mi = np.linalg.inv(Mq)
    # q̈ = Mq⁻¹ Jnᵀ F;  n = Jn q = −Jn q̈/Ω²;  a = C q̈
    Om2 = (2 * np.pi * F_TEST) ** 2
    D = -(Jn @ Mi @ Jn.T)[None] / Om2[:, None, None]
    B = C @ Mi @ Jn.T
    T = D @ np.linalg.pinv(B)[None]
    assert _rel(np.moveaxis(tf.transfer.data, 2, 0), T) < 1e-11
    np.testing.assert_allclose(tf.condition, np.linalg.cond(B), rtol=1e-9)


# --------------------------------------------------------------------------- regularisation
def test_regularisation_converges_to_the_plain_solution(wheelset):
    pr = wheelset.pole_residues()
    kw = dict(theta_l=0.05, theta_r=-0.3, channels=("axlebox_L:z", "axlebox_R:z", "axlebox_R:y"))
    t0 = vertical_lateral_transfer(pr, F_TEST, **kw)
    for alpha in (1e-3, 1e-5, 1e-7):
        ta = vertical_lateral_transfer(pr, F_TEST, regularisation=alpha, **kw)
        err = np.linalg.norm(ta.transfer.data - t0.transfer.data, axis=(0, 1)) / np.linalg.norm(
            t0.transfer.data, axis=(0, 1))
        # filter factors s²/(s² + α² s_max²) = 1 − O((α cond)²)
        assert np.all(err <= 1.01 * (alpha * t0.condition) ** 2 + 1e-14)


def test_regularisation_damps_ill_conditioned_frequencies(wheelset):
    ws = wheelset
    rng = np.random.default_rng(2)
    # a second sensor 1e-7 (relative) away from axlebox_L:z: B is nearly rank one at every frequency
    near = ws.rows(["axlebox_L:z"]) * (1 + 1e-7 * rng.standard_normal(ws.freqs_hz.size))
    outs = CONTACT + ("axlebox_L:z",)
    pr = PoleResidues.from_modes(ws.freqs_hz, 0.005, np.vstack([ws.rows(outs), near]), ws.rows(CONTACT),
                                 outs + ("axlebox_L:z_near",), CONTACT)
    chans = ("axlebox_L:z", "axlebox_L:z_near")
    t0 = full_vertical_transfer(pr, F_TEST, channels=chans)
    alpha = 1e-3
    ta = full_vertical_transfer(pr, F_TEST, channels=chans, regularisation=alpha)
    assert np.median(t0.condition) > 1e5
    T0 = np.linalg.norm(np.moveaxis(t0.transfer.data, 2, 0), ord=2, axis=(1, 2))
    Ta = np.linalg.norm(np.moveaxis(ta.transfer.data, 2, 0), ord=2, axis=(1, 2))
    D = np.linalg.norm(np.moveaxis(ta.dynamic_compliance.data, 2, 0), ord=2, axis=(1, 2))
    smax = np.linalg.norm(np.moveaxis(ta.force_to_acceleration.data, 2, 0), ord=2, axis=(1, 2))
    # ‖T_α‖ ≤ ‖D‖ max_s s/(s² + α² s_max²) = ‖D‖ / (2 α s_max)
    assert np.all(Ta <= D / (2 * alpha * smax) * (1 + 1e-9))
    assert np.median(T0 / Ta) > 100


# --------------------------------------------------------------------------- errors
def test_bad_inputs_raise_specific_errors(wheelset):
    pr = wheelset.pole_residues()
    vertical_only = wheelset.pole_residues(outputs=("contact_L:z", "contact_R:z", "axlebox_L:z", "axlebox_R:z"),
                                           inputs=("contact_L:z", "contact_R:z"))
    # a vertical-only model is enough for the vertical models...
    full_vertical_transfer(vertical_only, F_TEST)
    # ...but not for inclined normals: the missing DOFs are named
    with pytest.raises(MissingDOFError, match=r"contact_L:y"):
        vertical_lateral_transfer(vertical_only, F_TEST, theta_l=0.1, channels=("axlebox_L:z", "axlebox_R:z"))
    with pytest.raises(MissingDOFError, match=r"axlebox_X:z"):
        full_vertical_transfer(pr, F_TEST, channels=("axlebox_L:z", "axlebox_X:z"))
    with pytest.raises(TransferModelError, match=r"at least 2 measured channel"):
        full_vertical_transfer(pr, F_TEST, channels=("axlebox_L:z",))
    with pytest.raises(TransferModelError, match=r"unique"):
        full_vertical_transfer(pr, F_TEST, channels=("axlebox_L:z", 6))
    with pytest.raises(ContactParameterError, match=r"contact_stiffness"):
        full_vertical_transfer(pr, F_TEST, contact_stiffness=0.0)
    with pytest.raises(ContactParameterError, match=r"contact_stiffness"):
        half_wheelset_transfer(pr, F_TEST, contact_stiffness=-1e9)
    with pytest.raises(FrequencyAxisError, match=r"0 Hz"):
        full_vertical_transfer(pr, np.linspace(0, 100, 11))
    with pytest.raises(FrequencyAxisError, match=r"give freqs_hz"):
        full_vertical_transfer(pr)
    H = pr.evaluate(F_TEST)
    with pytest.raises(FrequencyAxisError, match=r"397 lines .* 398 lines|same frequency axis"):
        full_vertical_transfer(H, np.linspace(5, 800, 398))
    with pytest.raises(FrequencyAxisError, match=r"track receptance"):
        full_vertical_transfer(pr, F_TEST, track=track_frf(F_TEST[:-1]))
    with pytest.raises(TransferModelError, match=r"either"):
        vertical_lateral_transfer(pr, F_TEST, theta_l=0.1, normals=[[0, 1], [0, 1]])
    with pytest.raises(TransferModelError, match=r"radians"):
        vertical_lateral_transfer(pr, F_TEST, theta_l=30.0)
    with pytest.raises(TransferModelError, match=r"shape \(2, 2\)"):
        vertical_lateral_transfer(pr, F_TEST, normals=[0, 1])
    with pytest.raises(TransferModelError, match=r"side"):
        half_wheelset_transfer(pr, F_TEST, side="left")
    with pytest.raises(TransferModelError, match=r"regularisation"):
        full_vertical_transfer(pr, F_TEST, regularisation=-1)
    with pytest.raises(TransferModelError, match=r"track"):
        full_vertical_transfer(pr, F_TEST, track="stiff")
    tf = full_vertical_transfer(pr, F_TEST)
    with pytest.raises(TransferModelError, match=r"shape \(2, 397\)"):
        irregularity_to_acceleration(tf, np.ones(397))
    with pytest.warns(UserWarning, match="not unit"):
        t = vertical_lateral_transfer(pr, F_TEST, normals=[[0, 2.0], [0, 1.0]])
    assert _rel(t.transfer.data, full_vertical_transfer(pr, F_TEST, channels=("axlebox_L:z", "axlebox_R:z",
                                                                                 "axlebox_R:y")).transfer.data) < 1e-14


def test_frequency_response_without_contact_dofs_names_them():
    H = FrequencyResponse(F_TEST, np.ones((1, 1, F_TEST.size)), ("axlebox_L:z",), ("hammer",), quantity="receptance")
    with pytest.raises(MissingDOFError, match=r"contact_L:z.*hammer"):
        half_wheelset_transfer(H)
