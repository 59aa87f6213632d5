"""Three-dimensional two-node Timoshenko beam element.

The axle of the truth wheelset and the wheel rims are modelled with this
element. Stiffness and consistent mass follow Przemieniecki (Theory of Matrix
Structural Analysis, 1968, §5.6 and §11.4) with the shear-deformation
parameter ``Phi = 12 E I / (kappa G A L^2)`` and rotary inertia, i.e. the
interdependent-interpolation element that is exact in statics for a uniform
beam. The axial and torsional parts are linear (bar / shaft) elements.

Local DOF order per node: ``u, v, w, rx, ry, rz`` along the local axes
``e1`` (beam axis), ``e2``, ``e3``. Bending in the e1–e2 plane (deflection
``v``, rotation ``rz``) uses ``Iz`` (second moment about ``e3``); bending in
the e1–e3 plane (``w``, ``ry``) uses ``Iy`` (about ``e2``).

The element returns its stiffness split into named parts (axial, torsion,
bending) so that strain energy can be partitioned by deformation type when
modes are classified (a torsion mode stores its energy in ``GJ``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["BeamSection", "annulus_section", "rectangle_section", "beam_matrices", "beam_frame"]


@dataclass(frozen=True)
class BeamSection:
    """Cross-section properties of a beam.

    Attributes
    ----------
    area : float
        Cross-section area A [m^2].
    iy, iz : float
        Second moments of area about the local ``e2`` and ``e3`` axes [m^4].
    torsion_constant : float
        Saint-Venant torsion constant J [m^4].
    polar_inertia : float
        Polar second moment Ip = Iy + Iz [m^4], used for the torsional mass.
    kappa_y, kappa_z : float
        Shear coefficients for shear along ``e3`` (with ``iy``) and ``e2``
        (with ``iz``).
    """

    area: float
    iy: float
    iz: float
    torsion_constant: float
    polar_inertia: float
    kappa_y: float
    kappa_z: float

    def __post_init__(self) -> None:
        for name in ("area", "iy", "iz", "torsion_constant", "polar_inertia", "kappa_y", "kappa_z"):
            value = getattr(self, name)
            if not np.isfinite(value) or value <= 0:
                raise ValueError(f"BeamSection.{name} must be finite and > 0, got {value!r}")


def annulus_section(d_out: float, d_in: float = 0.0, nu: float = 0.3) -> BeamSection:
    """Section of a solid or hollow circular shaft.

    The shear coefficient is Cowper's (1966) for a hollow circle,
    ``kappa = 6 (1 + nu)(1 + m^2)^2 / ((7 + 6 nu)(1 + m^2)^2 + (20 + 12 nu) m^2)``
    with ``m = d_in / d_out`` (``6(1+nu)/(7+6nu)`` for a solid circle).
    """
    if not d_out > d_in >= 0:
        raise ValueError(f"annulus_section needs d_out > d_in >= 0, got d_out={d_out!r}, d_in={d_in!r}")
    area = np.pi / 4 * (d_out**2 - d_in**2)
    i = np.pi / 64 * (d_out**4 - d_in**4)
    m = d_in / d_out
    kappa = 6 * (1 + nu) * (1 + m**2) ** 2 / ((7 + 6 * nu) * (1 + m**2) ** 2 + (20 + 12 * nu) * m**2)
    return BeamSection(area, i, i, 2 * i, 2 * i, kappa, kappa)


def rectangle_section(width_e2: float, height_e3: float) -> BeamSection:
    """Section of a solid rectangle, ``width_e2`` along ``e2`` and ``height_e3`` along ``e3``.

    Torsion constant from the series approximation
    ``J = a b^3 (1/3 - 0.21 (b/a)(1 - b^4 / (12 a^4)))`` (Roark, Table 10.7),
    with ``a >= b`` the long and short sides; shear coefficient 5/6.
    """
    if width_e2 <= 0 or height_e3 <= 0:
        raise ValueError(f"rectangle_section needs positive sides, got {width_e2!r} x {height_e3!r}")
    a, b = max(width_e2, height_e3), min(width_e2, height_e3)
    j = a * b**3 * (1 / 3 - 0.21 * (b / a) * (1 - b**4 / (12 * a**4)))
    iy = width_e2 * height_e3**3 / 12  # about e2: extent along e3 matters
    iz = height_e3 * width_e2**3 / 12
    return BeamSection(width_e2 * height_e3, iy, iz, j, iy + iz, 5 / 6, 5 / 6)


def beam_frame(x1: np.ndarray, x2: np.ndarray, e2_hint: np.ndarray) -> np.ndarray:
    """Rotation matrix whose rows are the local axes ``e1, e2, e3``.

    ``e1`` points from node 1 to node 2; ``e2`` is ``e2_hint`` made orthogonal
    to ``e1``; ``e3 = e1 x e2``.
    """
    e1 = np.asarray(x2, float) - np.asarray(x1, float)
    length = np.linalg.norm(e1)
    if length <= 0:
        raise ValueError(f"beam element has zero length between {x1!r} and {x2!r}")
    e1 /= length
    hint = np.asarray(e2_hint, float)
    e2 = hint - hint.dot(e1) * e1
    if np.linalg.norm(e2) < 1e-6 * max(np.linalg.norm(hint), 1e-300):
        raise ValueError(f"beam orientation vector {e2_hint!r} is parallel to the beam axis {e1!r}")
    e2 /= np.linalg.norm(e2)
    e3 = np.cross(e1, e2)
    return np.vstack([e1, e2, e3])


def _bending_stiffness(ei: float, phi: float, length: float, sign: float) -> np.ndarray:
    # sign = +1 for (v, rz), -1 for (w, ry) because ry = -dw/dx
    L = length
    s = sign
    k = np.array(
        [
            [12, s * 6 * L, -12, s * 6 * L],
            [s * 6 * L, (4 + phi) * L**2, -s * 6 * L, (2 - phi) * L**2],
            [-12, -s * 6 * L, 12, -s * 6 * L],
            [s * 6 * L, (2 - phi) * L**2, -s * 6 * L, (4 + phi) * L**2],
        ]
    )
    return ei / ((1 + phi) * L**3) * k


def _bending_mass(rho_a: float, rho_i: float, phi: float, length: float, sign: float) -> np.ndarray:
    L = length
    s = sign
    p = phi
    a1 = 13 / 35 + 7 * p / 10 + p**2 / 3
    a2 = (11 / 210 + 11 * p / 120 + p**2 / 24) * L
    a3 = 9 / 70 + 3 * p / 10 + p**2 / 6
    a4 = (13 / 420 + 3 * p / 40 + p**2 / 24) * L
    a5 = (1 / 105 + p / 60 + p**2 / 120) * L**2
    a6 = (1 / 140 + p / 60 + p**2 / 120) * L**2
    mt = np.array(
        [
            [a1, s * a2, a3, -s * a4],
            [s * a2, a5, s * a4, -a6],
            [a3, s * a4, a1, -s * a2],
            [-s * a4, -a6, -s * a2, a5],
        ]
    ) * (rho_a * L / (1 + p) ** 2)
    b1 = 6 / 5
    b2 = (1 / 10 - p / 2) * L
    b3 = (2 / 15 + p / 6 + p**2 / 3) * L**2
    b4 = (-1 / 30 - p / 6 + p**2 / 6) * L**2
    mr = np.array(
        [
            [b1, s * b2, -b1, s * b2],
            [s * b2, b3, -s * b2, b4],
            [-b1, -s * b2, b1, -s * b2],
            [s * b2, b4, -s * b2, b3],
        ]
    ) * (rho_i / ((1 + p) ** 2 * L))
    return mt + mr


def beam_matrices(
    x1: np.ndarray,
    x2: np.ndarray,
    section: BeamSection,
    E: float,
    G: float,
    rho: float,
    e2_hint: np.ndarray,
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Global stiffness parts and consistent mass of a Timoshenko beam.

    Parameters
    ----------
    x1, x2 : array_like, shape (3,)
        Node coordinates [m].
    section : BeamSection
        Cross-section properties.
    E, G, rho : float
        Young's modulus [Pa], shear modulus [Pa], density [kg/m^3].
    e2_hint : array_like, shape (3,)
        Direction that fixes the local ``e2`` axis.

    Returns
    -------
    stiffness : dict of str to ndarray (12, 12)
        ``"axial"``, ``"torsion"`` and ``"bending"`` (bending + shear) parts in
        global coordinates; their sum is the element stiffness.
    mass : ndarray (12, 12)
        Consistent mass in global coordinates (translational and rotary
        inertia of both bending planes, axial and torsional inertia).
    """
    R = beam_frame(x1, x2, e2_hint)
    L = float(np.linalg.norm(np.asarray(x2, float) - np.asarray(x1, float)))
    A = section.area
    k_ax = np.zeros((12, 12))
    k_to = np.zeros((12, 12))
    k_be = np.zeros((12, 12))
    m = np.zeros((12, 12))

    ax = [0, 6]
    k_ax[np.ix_(ax, ax)] = E * A / L * np.array([[1, -1], [-1, 1]])
    m[np.ix_(ax, ax)] = rho * A * L / 6 * np.array([[2, 1], [1, 2]])

    to = [3, 9]
    k_to[np.ix_(to, to)] = G * section.torsion_constant / L * np.array([[1, -1], [-1, 1]])
    m[np.ix_(to, to)] = rho * section.polar_inertia * L / 6 * np.array([[2, 1], [1, 2]])

    # bending with deflection along e2 (v) resisted by iz; shear with kappa_z
    phi_z = 12 * E * section.iz / (section.kappa_z * G * A * L**2)
    vz = [1, 5, 7, 11]
    k_be[np.ix_(vz, vz)] = _bending_stiffness(E * section.iz, phi_z, L, +1.0)
    m[np.ix_(vz, vz)] = _bending_mass(rho * A, rho * section.iz, phi_z, L, +1.0)

    # bending with deflection along e3 (w) resisted by iy; shear with kappa_y
    phi_y = 12 * E * section.iy / (section.kappa_y * G * A * L**2)
    wy = [2, 4, 8, 10]
    k_be[np.ix_(wy, wy)] = _bending_stiffness(E * section.iy, phi_y, L, -1.0)
    m[np.ix_(wy, wy)] = _bending_mass(rho * A, rho * section.iy, phi_y, L, -1.0)

    T = np.kron(np.eye(4), R)
    stiffness = {name: T.T @ k @ T for name, k in (("axial", k_ax), ("torsion", k_to), ("bending", k_be))}
    return stiffness, T.T @ m @ T
