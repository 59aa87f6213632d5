"""The truth wheelset: a 3D finite-element model of a metro trailer wheelset.

The model follows Table 2.1 of the thesis (trailer wheelset of a *Meneghino*
train): axle 283 kg, two wheels of 251 kg (rolling radius 0.41 m), two
axle-mounted brake discs of 135 kg each (so that the wheelset without
axleboxes weighs 283 + 2·251 + 2·135 = 1055 kg, the table's 1054 kg) and two
axleboxes of 78 kg.

Structure (x along the track, y along the axle with the left wheel at -y,
z up):

* **Axle** — hollow Timoshenko beam (bore sized so the axle weighs exactly
  283 kg) with stepped diameters: body, disc seats, wheel seats, dust guards
  and journals, about 3.5 cm per element.
* **Wheels** — a flat web of MITC4 shell elements between the hub ring and the
  rim ring, and the rim as a ring of rectangular Timoshenko beams through the
  rim centroid. The hub is a rigid ring (point mass and inertia) tied to a hub
  centre node, which the design ties rigidly to the axle's wheel-seat node
  (the ``joint_L``/``joint_R`` rigid links; the ``joint`` scenario replaces
  them by press-fit springs).
* **Brake discs** — a flat annular shell plate (its thickness sets the mass of
  the ventilated friction ring) on a rigid hub tied to the disc-seat node.
* **Axleboxes** — rigid bodies (point mass + inertia) whose centre node the
  design ties rigidly to the journal node (``bearing_L``/``bearing_R`` links;
  the ``bearing`` scenario replaces them by bearing springs).
* **Skins** — display-only quads around the axle and the axleboxes, rigidly
  linked to the beam/centre nodes, so that the exported mesh looks like a
  wheelset in any viewer.

Tuning (documented choices, all within the range of real metro wheelsets):
web thickness 22 mm and rim section 55 × 135 mm place the first wheel
(one-nodal-diameter/umbrella) mode near 220 Hz and the two-nodal-diameter
mode near 425 Hz (thesis Table 3.1); the stepped axle diameters (journal
130 mm, wheel seat 195 mm, disc seat 185 mm, body 165 mm) with the 135 kg
discs set the first torsion near 71 Hz and the flexural modes near
72/128/195/286 Hz. The achieved values are checked by the tests and listed in
the campaign manifest.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .beam import annulus_section, rectangle_section
from .fe_model import Beam, FEModel, Material, PointMass, RigidLink, Shell, SkinQuad, Spring

__all__ = ["WheelsetParameters", "SuspensionParameters", "build_wheelset", "in_service", "NODE", "STEEL"]

STEEL = Material("steel", E=206e9, nu=0.3, rho=7850.0)

#: Node-id bases of the bodies (the node numbering is part of the exported FE file).
NODE = {
    "axle": 1000,
    "wheel_L": 2000,
    "wheel_R": 3000,
    "disc_L": 4000,
    "disc_R": 5000,
    "axlebox_L": 6000,
    "axlebox_R": 7000,
    "axle_skin": 10000,
}


@dataclass(frozen=True)
class WheelsetParameters:
    """Geometry, materials and masses of the wheelset (SI units).

    The axle profile is given for the right half (y >= 0) as consecutive
    segments ``(y_end, d_out)`` starting at y = 0; it is mirrored to the left.
    """

    axle_segments: tuple[tuple[float, float], ...] = (
        (0.32, 0.152),  # body
        (0.48, 0.185),  # disc seat
        (0.64, 0.148),  # body between disc and wheel
        (0.80, 0.195),  # wheel seat
        (0.88, 0.160),  # dust guard
        (1.06, 0.130),  # journal
    )
    axle_mass: float = 283.0
    axle_material: Material = STEEL
    axle_max_element: float = 0.035

    wheel_y: float = 0.72  # web plane
    wheel_mass: float = 251.0
    rolling_radius: float = 0.41
    contact_y: float = 0.75  # contact point (tape circle) lateral position
    hub_radius: float = 0.135
    hub_length: float = 0.18
    rim_radius: float = 0.3825  # rim centroid
    rim_radial: float = 0.060
    rim_axial: float = 0.135
    web_thickness: float = 0.025
    web_rings: int = 3
    wheel_material: Material = STEEL

    disc_y: float = 0.40
    disc_mass: float = 135.0
    disc_hub_radius: float = 0.125
    disc_outer_radius: float = 0.32
    disc_thickness: float = 0.05
    disc_rings: int = 2
    disc_material: Material = STEEL

    axlebox_y: float = 0.97
    axlebox_mass: float = 78.0
    axlebox_half_size: tuple[float, float, float] = (0.15, 0.11, 0.15)  # x, y, z half-extents of the housing
    axlebox_inertia: tuple[float, float, float] = (0.85, 1.30, 0.85)  # about x, y, z through its centre [kg m^2]

    n_theta: int = 24
    skin_segments: int = 8

    def __post_init__(self) -> None:
        if self.n_theta % 4 != 0 or self.n_theta < 8:
            raise ValueError(f"n_theta must be a multiple of 4 and >= 8, got {self.n_theta}")
        ends = [y for y, _ in self.axle_segments]
        if any(b <= a for a, b in zip([0.0] + ends[:-1], ends)):
            raise ValueError(f"axle_segments must have increasing y_end, got {ends}")
        if not (self.disc_y < self.wheel_y < self.axlebox_y < ends[-1]):
            raise ValueError("expected disc_y < wheel_y < axlebox_y < axle half-length")

    def varied(self, **factors: float) -> "WheelsetParameters":
        """Copy with named scalar parameters multiplied by factors (as-built deviations)."""
        changes = {}
        for name, f in factors.items():
            value = getattr(self, name)
            if isinstance(value, Material):
                raise TypeError(f"use replace() for material {name!r}")
            changes[name] = value * f
        return replace(self, **changes)

    @property
    def axle_half_length(self) -> float:
        return self.axle_segments[-1][0]

    def axle_diameter(self, y: float) -> float:
        """Outer diameter of the axle at lateral position ``y``."""
        ay = abs(y)
        for y_end, d in self.axle_segments:
            if ay <= y_end + 1e-12:
                return d
        raise ValueError(f"y = {y} is beyond the axle end {self.axle_half_length}")

    def axle_bore(self) -> float:
        """Bore diameter that makes the hollow axle weigh ``axle_mass``."""
        starts = [0.0] + [y for y, _ in self.axle_segments[:-1]]
        sum_d2l = sum(d**2 * (y1 - y0) for (y1, d), y0 in zip(self.axle_segments, starts)) * 2
        length = 2 * self.axle_half_length
        d_in2 = (sum_d2l - 4 * self.axle_mass / (np.pi * self.axle_material.rho)) / length
        if d_in2 < 0:
            raise ValueError(
                f"a solid axle with these diameters weighs less than {self.axle_mass} kg; increase the diameters"
            )
        return float(np.sqrt(d_in2))


@dataclass(frozen=True)
class SuspensionParameters:
    """Primary suspension per axlebox (thesis Table 2.1).

    Table 2.1 lists the vertical, lateral and longitudinal stiffness as
    ``2 × value``: two spring units per axlebox. The dampers are taken as one
    per axlebox. Stiffness in N/m, damping in N s/m, along x, y, z.
    """

    stiffness: tuple[float, float, float] = (2 * 4.15e6, 2 * 2.1e6, 2 * 0.5e6)
    damping: tuple[float, float, float] = (85e3, 50e3, 11e3)


def _axle_stations(p: WheelsetParameters) -> np.ndarray:
    half = p.axle_half_length
    features = {0.0, p.disc_y, p.wheel_y, p.axlebox_y, half, 0.13, 0.26, 0.56}
    features.update(y for y, _ in p.axle_segments)
    pts = sorted(features)
    stations = [0.0]
    for a, b in zip(pts[:-1], pts[1:]):
        n = max(1, int(np.ceil((b - a) / p.axle_max_element - 1e-9)))
        stations.extend(np.linspace(a, b, n + 1)[1:])
    right = np.array(stations)
    return np.concatenate([-right[:0:-1], right])


def build_wheelset(p: WheelsetParameters = WheelsetParameters(), *, name: str = "wheelset") -> FEModel:
    """Build the free-free wheelset finite-element model.

    Parameters
    ----------
    p : WheelsetParameters
    name : str

    Returns
    -------
    FEModel
        Free-free model; rigid links ``joint_L/R`` (hub to axle) and
        ``bearing_L/R`` (axlebox to journal) carry the design assumptions
        that the hidden-effect scenarios relax.
    """
    ids: list[int] = []
    xyz: list[tuple[float, float, float]] = []
    groups: list[str] = []
    elements: list = []
    links: list[RigidLink] = []
    skins: list[SkinQuad] = []

    def node(nid: int, x: float, y: float, z: float, group: str) -> int:
        ids.append(nid)
        xyz.append((x, y, z))
        groups.append(group)
        return nid

    # --- axle -------------------------------------------------------------
    ys = _axle_stations(p)
    bore = p.axle_bore()
    axle_nodes = [node(NODE["axle"] + i + 1, 0.0, y, 0.0, "axle") for i, y in enumerate(ys)]
    mat = p.axle_material
    for i in range(len(ys) - 1):
        d = p.axle_diameter(0.5 * (ys[i] + ys[i + 1]))
        sec = annulus_section(d, bore, mat.nu)
        elements.append(Beam((axle_nodes[i], axle_nodes[i + 1]), sec, mat, (0.0, 0.0, 1.0), "axle"))

    def axle_node_at(y: float) -> int:
        i = int(np.argmin(np.abs(ys - y)))
        if abs(ys[i] - y) > 1e-9:
            raise RuntimeError(f"no axle node at y = {y}")
        return axle_nodes[i]

    # axle skin: rings of display nodes at the local outer radius
    ns = p.skin_segments
    skin_rings = []
    for i, (an, y) in enumerate(zip(axle_nodes, ys)):
        neigh = [ys[max(i - 1, 0)], ys[min(i + 1, len(ys) - 1)]]
        r = 0.5 * max(p.axle_diameter(0.5 * (y + q)) if q != y else p.axle_diameter(y) for q in neigh)
        ring = []
        for k in range(ns):
            t = 2 * np.pi * k / ns
            ring.append(node(NODE["axle_skin"] + 10 * i + k, r * np.cos(t), y, r * np.sin(t), "axle_skin"))
        links.append(RigidLink(an, tuple(ring), "axle_skin"))
        skin_rings.append(ring)
    for a, b in zip(skin_rings[:-1], skin_rings[1:]):
        for k in range(ns):
            k2 = (k + 1) % ns
            skins.append(SkinQuad((a[k], b[k], b[k2], a[k2]), "axle_skin"))

    # --- wheels and discs ---------------------------------------------------
    nt = p.n_theta
    theta = 2 * np.pi * np.arange(nt) / nt

    def annulus(
        base: int, y: float, radii: np.ndarray, group: str, thickness: float, material: Material
    ) -> list[list[int]]:
        rings = []
        for i, r in enumerate(radii):
            rings.append(
                [node(base + 100 * (i + 1) + k, r * np.cos(t), y, r * np.sin(t), group) for k, t in enumerate(theta)]
            )
        for i in range(len(radii) - 1):
            for k in range(nt):
                k2 = (k + 1) % nt
                elements.append(
                    Shell((rings[i][k], rings[i + 1][k], rings[i + 1][k2], rings[i][k2]), thickness, material, group)
                )
        return rings

    def hub_skin(base: int, y: float, hub_node: int, outer_ring: list[int], group: str) -> None:
        # display-only face of the rigid hub between the seat and the web's inner ring
        r = 0.5 * p.axle_diameter(y)
        inner = [node(base + 900 + k, r * np.cos(t), y, r * np.sin(t), group) for k, t in enumerate(theta)]
        links.append(RigidLink(hub_node, tuple(inner), f"{group}_hub_skin"))
        for k in range(nt):
            k2 = (k + 1) % nt
            skins.append(SkinQuad((inner[k], outer_ring[k], outer_ring[k2], inner[k2]), f"{group}_hub_skin"))

    def shell_mass(radii: np.ndarray, thickness: float, rho: float) -> float:
        # area of the 24-gon annulus actually meshed
        area = 0.5 * nt * np.sin(2 * np.pi / nt) * (radii[-1] ** 2 - radii[0] ** 2)
        return rho * thickness * area

    def hub_and_plate(
        group: str, y: float, radii: np.ndarray, thickness: float, material: Material, side: str, link: str,
        seat_link: str, plate_mass: float, body_mass: float, hub_length: float,
    ) -> list[list[int]]:
        """A rigid hub (point mass: the body's mass not in its plate) carrying a shell plate, tied to the axle."""
        base = NODE[group]
        hub = node(base, 0.0, y, 0.0, group)
        rings = annulus(base, y, radii, group, thickness, material)
        links.append(RigidLink(hub, tuple(rings[0]), f"{link}_{side}"))
        hub_skin(base, y, hub, rings[0], group)
        links.append(RigidLink(axle_node_at(y), (hub,), f"{seat_link}_{side}"))
        m_hub = body_mass - plate_mass
        if m_hub <= 0:
            raise ValueError(f"{group}: plate and rim ({plate_mass:.1f} kg) exceed the body mass {body_mass} kg")
        # the hub is a thick ring from the seat to the plate's inner radius
        ri, ro = 0.5 * p.axle_diameter(y), radii[0]
        i_polar = m_hub * (ri**2 + ro**2) / 2
        i_diam = m_hub * ((ri**2 + ro**2) / 4 + hub_length**2 / 12)
        elements.append(PointMass(hub, m_hub, np.diag([i_diam, i_polar, i_diam]).tolist(), group))
        return rings

    for side, sgn in (("L", -1.0), ("R", 1.0)):
        # wheel: web plate + rim ring of beams
        wname = f"wheel_{side}"
        radii = np.linspace(p.hub_radius, p.rim_radius, p.web_rings + 1)
        rsec = rectangle_section(p.rim_radial, p.rim_axial)
        m_rim = p.wheel_material.rho * rsec.area * 2 * p.rim_radius * np.sin(np.pi / nt) * nt
        m_plate = m_rim + shell_mass(radii, p.web_thickness, p.wheel_material.rho)
        rings = hub_and_plate(wname, sgn * p.wheel_y, radii, p.web_thickness, p.wheel_material, side, "hub", "joint",
                              m_plate, p.wheel_mass, p.hub_length)
        rim = rings[-1]
        for k in range(nt):
            k2 = (k + 1) % nt
            mid = 0.5 * (theta[k] + theta[k2] + (2 * np.pi if k2 == 0 else 0.0))
            elements.append(
                Beam((rim[k], rim[k2]), rsec, p.wheel_material, (np.cos(mid), 0.0, np.sin(mid)), f"{wname}_rim")
            )

        # brake disc: a thick annular plate on a short hub (0.12 m long)
        dname = f"disc_{side}"
        dradii = np.linspace(p.disc_hub_radius, p.disc_outer_radius, p.disc_rings + 1)
        hub_and_plate(dname, sgn * p.disc_y, dradii, p.disc_thickness, p.disc_material, side, "disc_hub", "disc_seat",
                      shell_mass(dradii, p.disc_thickness, p.disc_material.rho), p.disc_mass, 0.12)

        # axlebox
        bname = f"axlebox_{side}"
        base = NODE[bname]
        yb = sgn * p.axlebox_y
        box = node(base, 0.0, yb, 0.0, bname)
        hx, hy, hz = p.axlebox_half_size
        corners = []
        for k, (sx, sy, sz) in enumerate(
            [(-1, -1, -1), (1, -1, -1), (1, 1, -1), (-1, 1, -1), (-1, -1, 1), (1, -1, 1), (1, 1, 1), (-1, 1, 1)]
        ):
            corners.append(node(base + k + 1, sx * hx, yb + sy * hy, sz * hz, bname))
        links.append(RigidLink(box, tuple(corners), f"{bname}_skin"))
        links.append(RigidLink(axle_node_at(yb), (box,), f"bearing_{side}"))
        c = corners
        for face in ((0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)):
            skins.append(SkinQuad(tuple(c[i] for i in face), f"{bname}_skin"))
        elements.append(PointMass(box, p.axlebox_mass, np.diag(p.axlebox_inertia).tolist(), bname))

    return FEModel(
        node_ids=np.array(ids),
        xyz=np.array(xyz),
        node_groups=tuple(groups),
        elements=tuple(elements),
        links=tuple(links),
        skins=tuple(skins),
        name=name,
    )


def in_service(model: FEModel, s: SuspensionParameters = SuspensionParameters()) -> FEModel:
    """The wheelset on its primary suspension: springs and dampers from each axlebox to the (fixed) bogie.

    Bogie motion is neglected above the primary-suspension frequencies (thesis
    §2.3), so the springs go to ground. Gives the bounce (~7 Hz) and roll
    (~9 Hz) modes of thesis §4.1.
    """
    springs = []
    for side in ("L", "R"):
        box = NODE[f"axlebox_{side}"]
        springs.append(
            Spring(box, None, tuple(s.stiffness) + (0.0, 0.0, 0.0), tuple(s.damping) + (0.0, 0.0, 0.0),
                   f"primary_{side}")
        )
    return model.with_changes(add_elements=springs, name=f"{model.name} in service")
