"""The axle's Timoshenko beam element against the analytic free-free shaft.

Oracle: ``timoshenko_oracle`` (characteristic determinant of the free-free
Timoshenko beam, independent of any FE code) and the exact torsion formula.
The shaft is "meshed like the axle": same hollow section type, same length
and the same maximum element length (3.5 cm) as the truth wheelset's axle.
"""

import numpy as np
import pytest

import timoshenko_oracle as oracle
from lab_data.beam import annulus_section
from lab_data.fe_model import Beam, FEModel, Material, assemble, solve_modes
from lab_data.wheelset import WheelsetParameters

STEEL = Material("steel", 206e9, 0.3, 7850.0)


def shaft_modes(n_el: int, length: float, d_out: float, d_in: float, f_max: float = 3000.0):
    y = np.linspace(-length / 2, length / 2, n_el + 1)
    sec = annulus_section(d_out, d_in, STEEL.nu)
    ids = np.arange(1, n_el + 2)
    elements = tuple(Beam((i + 1, i + 2), sec, STEEL, (0.0, 0.0, 1.0), "axle") for i in range(n_el))
    model = FEModel(ids, np.c_[0 * y, y, 0 * y], ("axle",) * (n_el + 1), elements, (), ())
    system = assemble(model)
    return model, system, solve_modes(model, system, f_max)


def split_families(model, system, modes):
    """Bending (one per degenerate pair) and torsion frequencies from the strain energy of each mode."""
    bending, torsion = [], []
    phi = modes.full
    for i, f in enumerate(modes.freqs_hz):
        if f < 1.0:
            continue
        e = {k: float(phi[:, i] @ (K @ phi[:, i])) for k, K in system.stiffness.items()}
        if e["axle/torsion"] > 0.9 * sum(e.values()):
            torsion.append(f)
        elif e["axle/bending"] > 0.9 * sum(e.values()):
            bending.append(f)
    return np.array(bending[::2]), np.array(torsion)


def reference(length, d_out, d_in, n):
    sec = oracle.solid_or_hollow_circle(d_out, d_in, nu=STEEL.nu)
    fb = oracle.free_free_bending_frequencies(
        n, L=length, E=STEEL.E, G=STEEL.G, rho=STEEL.rho, A=sec["A"], I=sec["I"], kappa=sec["kappa"]
    )
    ft = oracle.free_free_torsion_frequencies(n, L=length, G=STEEL.G, rho=STEEL.rho)
    return fb, ft


P = WheelsetParameters()
LENGTH = 2 * P.axle_half_length
D_OUT = P.axle_diameter(0.0)
D_IN = P.axle_bore()


def test_shaft_meshed_like_the_axle_matches_analytic_timoshenko_within_half_percent():
    n_el = int(np.ceil(LENGTH / P.axle_max_element))
    model, system, modes = shaft_modes(n_el, LENGTH, D_OUT, D_IN)
    fb, ft = split_families(model, system, modes)
    rb, rt = reference(LENGTH, D_OUT, D_IN, 4)
    assert len(fb) >= 4 and len(ft) >= 2
    np.testing.assert_allclose(fb[:4], rb, rtol=5e-3)
    np.testing.assert_allclose(ft[:2], rt[:2], rtol=5e-3)
    # the margin is wide: the axle mesh is converged an order below the 0.5 % goal
    assert np.max(np.abs(fb[:4] / rb - 1)) < 1e-3


def test_mesh_convergence_of_bending_and_torsion():
    rb, rt = reference(LENGTH, D_OUT, D_IN, 4)
    errors_b, errors_t = [], []
    for n_el in (8, 16, 32, 64):
        model, system, modes = shaft_modes(n_el, LENGTH, D_OUT, D_IN)
        fb, ft = split_families(model, system, modes)
        errors_b.append(np.abs(fb[3] / rb[3] - 1))
        errors_t.append(np.abs(ft[1] / rt[1] - 1))
    # monotone second-order convergence: linear interpolation in torsion, and in
    # bending because short elements of a thick shaft are shear-dominated
    # (Phi = 12EI/(kappa G A L^2) ~ 50 at 3.5 cm), where the interdependent
    # shape functions tend to linear ones
    assert all(a > b for a, b in zip(errors_b, errors_b[1:]))
    assert all(a > b for a, b in zip(errors_t, errors_t[1:]))
    assert errors_t[-2] / errors_t[-1] == pytest.approx(4.0, rel=0.15)
    assert errors_b[-2] / errors_b[-1] == pytest.approx(4.0, rel=0.15)
    assert errors_b[-1] < 5e-4
    assert errors_t[-1] < 5e-4


def test_shear_and_rotary_inertia_matter_for_a_stocky_shaft():
    # a short thick shaft: Euler-Bernoulli would be 10 % off, the element follows Timoshenko
    length, d = 0.6, 0.2
    model, system, modes = shaft_modes(40, length, d, 0.0, f_max=20000.0)
    fb, _t = split_families(model, system, modes)
    rb, _rt = reference(length, d, 0.0, 3)
    np.testing.assert_allclose(fb[:3], rb, rtol=2e-3)
    sec = oracle.solid_or_hollow_circle(d, 0.0, nu=STEEL.nu)
    euler = 4.730040745**2 * np.sqrt(STEEL.E * sec["I"] / (STEEL.rho * sec["A"] * length**4)) / (2 * np.pi)
    assert fb[0] < 0.97 * euler
