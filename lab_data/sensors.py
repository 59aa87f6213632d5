"""Sensor layouts of the two impact-test setups (thesis §3.2) and the points table.

``flexural`` setup: 29 accelerometers — 7 radial on the axle surface, 3
radial on each brake-disc outer ring, 6 axial on each wheel rim face (wheel
modes move the rim out of its plane, so an axial sensor sees them; a radial
one would not) and 2 on each axlebox (vertical on top, lateral on the end
cover). Tangential means the direction of motion for a positive rotation
about +y, ``(sin t, 0, -cos t)`` at angle t in the x–z plane. ``torsional`` setup: the axle, disc and wheel sensors are turned
tangential; the axlebox sensors stay (thesis Fig. 3.4). Both setups hit the
notch on the top of the left brake disc: radially (downwards) in the
flexural setup, tangentially in the torsional one, both tilted 14 degrees
towards the axle centre as a hand-held hammer in a notch is.

Every sensor is rigidly attached to a design-FE node at an offset; its
modal displacement along its measuring direction d is
``d · (u + theta × offset)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from .fe_model import FEModel
from .wheelset import NODE, WheelsetParameters

__all__ = ["Sensor", "Setup", "SETUP_NAMES", "make_setup", "channel_table", "points_table", "points_frame",
           "point_rows", "shape_matrix", "tilted_direction"]

SETUP_NAMES = ("flexural", "torsional")

FORCE_NODE = 900
AXLE_STATIONS = (-0.56, -0.26, -0.13, 0.0, 0.13, 0.26, 0.56)
DISC_ANGLES_DEG = (30.0, 150.0, 270.0)
WHEEL_ANGLES_DEG = (30.0, 90.0, 150.0, 210.0, 270.0, 330.0)
IMPACT_ANGLE_DEG = 90.0
HAMMER_AXIAL_TILT = 0.25  # axial/in-plane ratio of the hammer direction (about 14 degrees)


@dataclass(frozen=True)
class Sensor:
    """One transducer: test node, position, measuring direction, FE attachment."""

    node: int
    name: str
    quantity: str  # 'acceleration' or 'force'
    unit: str
    position: tuple[float, float, float]
    direction: tuple[float, float, float]
    fe_node: int


@dataclass(frozen=True)
class Setup:
    """A sensor setup: the force transducer and the accelerometers in channel order."""

    name: str
    force: Sensor
    accelerometers: tuple[Sensor, ...]

    @property
    def sensors(self) -> tuple[Sensor, ...]:
        return (self.force,) + self.accelerometers


def _ring_node(model: FEModel, group: str, radius: float, angle_deg: float) -> int:
    nodes = model.nodes_of(group)
    xyz = np.array([model.coords(n) for n in nodes])
    target = np.array([radius * np.cos(np.radians(angle_deg)), radius * np.sin(np.radians(angle_deg))])
    d = np.hypot(xyz[:, 0] - target[0], xyz[:, 2] - target[1])
    i = int(np.argmin(d))
    if d[i] > 1e-6:
        raise ValueError(f"no {group} node at r = {radius} m, angle {angle_deg} deg (closest {d[i]:.4f} m)")
    return int(nodes[i])


def _axle_node(model: FEModel, y: float) -> int:
    nodes = model.nodes_of("axle")
    ys = np.array([model.coords(n)[1] for n in nodes])
    i = int(np.argmin(np.abs(ys - y)))
    if abs(ys[i] - y) > 1e-9:
        raise ValueError(f"no axle node at y = {y}")
    return int(nodes[i])


def make_setup(name: str, model: FEModel, p: WheelsetParameters = WheelsetParameters()) -> Setup:
    """The sensor layout of setup ``name`` on the design model ``model``."""
    if name not in SETUP_NAMES:
        raise ValueError(f"unknown setup {name!r}; choose one of {SETUP_NAMES}")
    tangential = name == "torsional"
    acc = []

    def add(node, nm, pos, direction, fe_node):
        d = np.asarray(direction, float)
        acc.append(
            Sensor(node, nm, "acceleration", "m/s^2", tuple(map(float, pos)), tuple(map(float, d / np.linalg.norm(d))),
                   int(fe_node))
        )

    for k, y in enumerate(AXLE_STATIONS):
        r = 0.5 * p.axle_diameter(y)
        add(101 + k, f"axle_{k + 1:02d}", (0.0, y, r), (1, 0, 0) if tangential else (0, 0, 1), _axle_node(model, y))
    for side, base, sgn in (("L", 111, -1), ("R", 121, 1)):
        for k, a in enumerate(DISC_ANGLES_DEG):
            t = np.radians(a)
            r = p.disc_outer_radius
            fe = _ring_node(model, f"disc_{side}", r, a)
            direction = (np.sin(t), 0, -np.cos(t)) if tangential else (np.cos(t), 0, np.sin(t))
            add(base + k, f"disc{side}_{k + 1}", (r * np.cos(t), sgn * p.disc_y, r * np.sin(t)), direction, fe)
    for side, base, sgn in (("L", 131, -1), ("R", 141, 1)):
        for k, a in enumerate(WHEEL_ANGLES_DEG):
            t = np.radians(a)
            r = p.rim_radius
            fe = _ring_node(model, f"wheel_{side}", r, a)
            # on the outer rim face, half a rim width outboard of the web plane
            pos = (r * np.cos(t), sgn * (p.wheel_y + p.rim_axial / 2), r * np.sin(t))
            direction = (np.sin(t), 0, -np.cos(t)) if tangential else (0, sgn, 0)
            add(base + k, f"wheel{side}_{k + 1}", pos, direction, fe)
    hx, hy, hz = p.axlebox_half_size
    for side, base, sgn in (("L", 151, -1), ("R", 161, 1)):
        box = NODE[f"axlebox_{side}"]
        yb = sgn * p.axlebox_y
        add(base, f"axlebox{side}_z", (0.05, yb, hz), (0, 0, 1), box)
        add(base + 1, f"axlebox{side}_y", (0.0, yb + sgn * hy, 0.05), (0, sgn, 0), box)

    t = np.radians(IMPACT_ANGLE_DEG)
    r = p.disc_outer_radius
    fe = _ring_node(model, "disc_L", r, IMPACT_ANGLE_DEG)
    main = np.array((np.sin(t), 0.0, -np.cos(t)) if tangential else (-np.cos(t), 0.0, -np.sin(t)))
    # a hand-held hammer in a notch never strikes exactly in the disc plane; the
    # axial component (towards the axle centre) is what excites the wheels' axial modes
    direction = main + HAMMER_AXIAL_TILT * np.array([0.0, 1.0, 0.0])
    direction = np.round(direction / np.linalg.norm(direction), 12) + 0.0
    force = Sensor(FORCE_NODE, "hammer", "force", "N", (r * np.cos(t), -p.disc_y, r * np.sin(t)),
                   tuple(float(v) for v in direction), fe)
    return Setup(name, force, tuple(acc))


def tilted_direction(direction, axial_deg: float, across_deg: float) -> tuple[float, float, float]:
    """A blow's direction tilted from ``direction`` by ``axial_deg`` towards the axle's axis (+y, in the plane of
    the direction and the axis) and by ``across_deg`` normal to that plane: a hand-held hammer's direction varies by
    a few degrees from hit to hit."""
    d0 = np.asarray(direction, float)
    d0 = d0 / np.linalg.norm(d0)
    axial = np.array([0.0, 1.0, 0.0]) - d0 * d0[1]
    axial /= np.linalg.norm(axial)
    across = np.cross(d0, axial)
    d = d0 + np.tan(np.radians(axial_deg)) * axial + np.tan(np.radians(across_deg)) * across
    return tuple(float(v) for v in d / np.linalg.norm(d))


def channel_table(setup: Setup) -> pd.DataFrame:
    """Channel table with columns ``node, name, quantity, unit, x, y, z, dx, dy, dz, fe_node, setup``."""
    rows = []
    for s in setup.sensors:
        rows.append(
            {
                "node": s.node,
                "name": s.name,
                "quantity": s.quantity,
                "unit": s.unit,
                "x": s.position[0],
                "y": s.position[1],
                "z": s.position[2],
                "dx": s.direction[0],
                "dy": s.direction[1],
                "dz": s.direction[2],
                "fe_node": s.fe_node,
                "setup": setup.name,
            }
        )
    return pd.DataFrame(rows)


def point_rows(model: FEModel, p: WheelsetParameters = WheelsetParameters()) -> list[tuple[str, int, tuple]]:
    """The named points of thesis Fig. 2.5: contact points and axlebox centres, with their FE nodes."""
    rows = []
    for side, sgn in (("L", -1), ("R", 1)):
        fe = _ring_node(model, f"wheel_{side}", p.rim_radius, 270.0)
        rows.append((f"contact_{side}", fe, (0.0, sgn * p.contact_y, -p.rolling_radius)))
    for side, sgn in (("L", -1), ("R", 1)):
        rows.append((f"axlebox_{side}", NODE[f"axlebox_{side}"], (0.0, sgn * p.axlebox_y, 0.0)))
    order = ("contact_L", "axlebox_L", "contact_R", "axlebox_R")
    return sorted(rows, key=lambda r: order.index(r[0]))


def points_table(model: FEModel, p: WheelsetParameters = WheelsetParameters()) -> pd.DataFrame:
    """Points CSV content: ``name, fe_node, x, y, z``."""
    return points_frame(point_rows(model, p))


def points_frame(rows: list[tuple[str, int, tuple]]) -> pd.DataFrame:
    """Points CSV content ``name, fe_node, x, y, z`` of ``(name, fe_node, xyz)`` rows (see :func:`point_rows`)."""
    return pd.DataFrame([{"name": n, "fe_node": fe, "x": x[0], "y": x[1], "z": x[2]} for n, fe, x in rows])


def shape_matrix(
    model: FEModel, shapes: np.ndarray, fe_nodes, positions, directions
) -> np.ndarray:
    """Modal displacement of rigidly attached points along given directions.

    Parameters
    ----------
    model : FEModel
    shapes : ndarray (m, n_nodes, 6)
    fe_nodes : sequence of int
    positions, directions : array_like (n_points, 3)

    Returns
    -------
    ndarray (n_points, m)
        ``d · (u + theta × (position - x_node))`` per point and mode.
    """
    idx = np.array([model.index(n) for n in fe_nodes])
    offset = np.asarray(positions, float) - model.xyz[idx]
    d = np.asarray(directions, float)
    u = shapes[:, idx, :3]  # (m, p, 3)
    th = shapes[:, idx, 3:]
    disp = u + np.cross(th, offset[None, :, :])
    return np.einsum("mpk,pk->pm", disp, d)
