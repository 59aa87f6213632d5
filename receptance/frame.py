"""The railway frame of a wheelset model, found from its points and applied to an FE export in any frame.

The toolkit works in the railway frame of DESIGN.md and thesis Fig. 2.5:
``x`` along the track, ``y`` along the axle from the left wheel to the right,
``z`` up.  The model's named DOFs mean it (``contact_L:z`` is the vertical
at the left contact point), and so do the primary suspension, the bearing,
joint and rig effects, the contact normals of eq. 2.12 and the field
sensor table.  A design office, however, draws a wheelset in the frame of
its CAD or solver: the axle along X with Y up, the axle along Z of an
axisymmetric model, any origin.

The points table fixes the railway frame physically, whatever the FE's:

* ``y`` runs from ``axlebox_L`` to ``axlebox_R`` (the journal centres lie on
  the axle axis); without axleboxes, from ``contact_L`` to ``contact_R``;
* ``z`` points from the wheel–rail contacts to the axle axis: a wheel at
  rest touches the rail straight below its axle, so the contacts' offsets
  from the axle axis, perpendicular to it, point down;
* ``x = y × z`` (right-handed).

Design offices draw along their coordinate axes, and a contact point given
by its node alone stands where the tread mesh has a node, a few degrees off
the bottom; so a frame within :data:`SNAP_DEG` of the FE's own axes is taken
as those axes (a signed permutation), and only an FE drawn obliquely is
turned by the exact rotation the points give.

:func:`railway_frame` returns that rotation ``Q`` (``x_rail = Q x_fe``);
:func:`to_railway_frame` turns the FE modes, the points, the channel tables
and the wheelset description with it, once, where a workflow has read
them.  Directions and positions are turned alike; origins stay where they
are (nothing in the toolkit assumes one).  An FE already in the railway
frame gets the identity and is not touched.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from typing import Mapping

import numpy as np
import pandas as pd

from .dofs import DofError, Point

__all__ = ["RailwayFrame", "railway_frame", "to_railway_frame", "check_railway_frame", "IDENTITY_ATOL",
           "MAX_AXIS_DISAGREEMENT_DEG", "SNAP_DEG"]

log = logging.getLogger("receptance")

#: a rotation this close to the identity (largest entry of Q − I) is the identity: the FE is left untouched
IDENTITY_ATOL = 1e-9
#: the axleboxes' and the contacts' L→R directions, and the two contacts' downward offsets, agree within this
MAX_AXIS_DISAGREEMENT_DEG = 10.0
#: a contact point lies off the axle axis by at least this fraction of the axlebox (or contact) spacing
MIN_RADIUS_FRACTION = 0.05
#: a frame within this angle of the FE's own axes is taken as those axes (design offices draw along them; a contact
#: node of a coarse tread mesh stands a few degrees off the bottom: 7.5° with 24 nodes around, 15° with 12)
SNAP_DEG = 20.0
_AXIS_NAMES = ("x", "y", "z")


@dataclass(frozen=True)
class RailwayFrame:
    """A rotation from an FE export's frame into the railway frame.

    Attributes
    ----------
    rotation : ndarray (3, 3)
        ``Q`` with ``x_rail = Q x_fe``: its rows are the railway ``x`` (along
        the track), ``y`` (along the axle, left to right) and ``z`` (up) axes
        written in the FE's coordinates.
    basis : str
        What fixed it (the points used).
    """

    rotation: np.ndarray
    basis: str = ""

    def __post_init__(self) -> None:
        q = np.asarray(self.rotation, float)
        if q.shape != (3, 3) or not np.allclose(q @ q.T, np.eye(3), atol=1e-9) or np.linalg.det(q) < 0:
            raise ValueError(f"RailwayFrame.rotation must be a proper 3 x 3 rotation, got {np.round(q, 6).tolist()}")
        object.__setattr__(self, "rotation", q)

    @property
    def is_identity(self) -> bool:
        """True when the FE is already in the railway frame (within :data:`IDENTITY_ATOL`)."""
        return bool(np.max(np.abs(self.rotation - np.eye(3))) <= IDENTITY_ATOL)

    @property
    def angle_deg(self) -> float:
        """Angle of the rotation [deg]."""
        c = (np.trace(self.rotation) - 1.0) / 2.0
        return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))

    def describe(self) -> str:
        """One sentence: which FE directions became the railway axes."""
        if self.is_identity:
            return "the FE export is in the railway frame (x along the track, y along the axle, z up)"
        return (f"the FE export is not in the railway frame; turned by {self.angle_deg:.1f}° into it "
                f"({self.axes_text()}; from {self.basis})")

    def axes_text(self) -> str:
        """Which FE directions are the railway axes (``railway x = +Z, y = +X, z = +Y of the FE``)."""
        parts = [f"{rail} = {_direction_text(self.rotation[k])}" for k, rail in enumerate(_AXIS_NAMES)]
        return f"railway {', '.join(parts)} of the FE"

    def xyz(self, points) -> np.ndarray:
        """Positions or directions ``(n, 3)`` in the railway frame."""
        return np.asarray(points, float) @ self.rotation.T

    def table(self, table: pd.DataFrame | None) -> pd.DataFrame | None:
        """A channel table (``x, y, z`` positions, ``dx, dy, dz`` directions) in the railway frame (a copy; the same
        object when the frame is the identity)."""
        if table is None or self.is_identity:
            return table
        out = table.copy()
        for cols in (["x", "y", "z"], ["dx", "dy", "dz"]):
            if all(c in out.columns for c in cols):
                out[cols] = self.xyz(out[cols].to_numpy(float))
        return out


def _direction_text(v: np.ndarray) -> str:
    k = int(np.argmax(np.abs(v)))
    if abs(abs(v[k]) - 1.0) < 1e-6:
        return f"{'+' if v[k] > 0 else '-'}{'XYZ'[k]}"
    return "(" + ", ".join(f"{c:+.3f}" for c in v) + ")"


def _position(points: Mapping[str, Point], name: str, fe) -> np.ndarray | None:
    p = points.get(name)
    if p is None:
        return None
    if p.xyz is not None:
        return np.asarray(p.xyz, float)
    if fe is not None and p.fe_node is not None and fe.has_coordinates:
        try:
            return np.asarray(fe.xyz[fe.index(p.fe_node)], float)
        except KeyError:
            return None
    return None


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip(_unit(a) @ _unit(b), -1.0, 1.0))))


def railway_frame(points: Mapping[str, Point], fe=None, *, source: str = "") -> RailwayFrame | None:
    """The railway frame the points define (module docstring), or None when they cannot tell it.

    Parameters
    ----------
    points : mapping name -> Point
        The points table (``contact_L``, ``contact_R``, ``axlebox_L``,
        ``axlebox_R``); a point without coordinates takes its FE node's.
    fe : fem_import.FEModes, optional
        For the coordinates of points given by node only.
    source : str
        The points file, for messages.

    Returns
    -------
    RailwayFrame or None
        None when the points lack the positions that fix the frame (no axle
        direction, or no contact point to tell up from down); the caller
        then keeps the FE's frame as the railway frame.

    Raises
    ------
    DofError
        Points that contradict a wheelset: two contacts or axleboxes at one
        place, the contacts' and the axleboxes' axles more than
        :data:`MAX_AXIS_DISAGREEMENT_DEG` apart, a contact on the axle axis,
        or the two contacts on different sides of it.
    """
    where = f"{source}: " if source else ""
    pos = {n: _position(points, n, fe) for n in ("axlebox_L", "axlebox_R", "contact_L", "contact_R")}
    pairs = {}
    for kind in ("axlebox", "contact"):
        a, b = pos[f"{kind}_L"], pos[f"{kind}_R"]
        if a is not None and b is not None:
            if np.linalg.norm(b - a) == 0:
                raise DofError(f"{where}{kind}_L and {kind}_R are at the same place {a.tolist()}; the axle's "
                               f"direction (left to right) cannot be told")
            pairs[kind] = (a, b)
    if not pairs or pos["contact_L"] is None and pos["contact_R"] is None:
        return None
    # the axle axis: through the journal centres; without axleboxes, the contacts give only its direction and the
    # vertical then comes from the FE's nodes on the axle (below)
    kind = "axlebox" if "axlebox" in pairs else "contact"
    a, b = pairs[kind]
    y = _unit(b - a)
    spacing = float(np.linalg.norm(b - a))
    if kind == "axlebox":
        origin = 0.5 * (a + b)
    else:
        origin = _axle_point_from_fe(fe, a, b, y)
        if origin is None:
            return None
    offsets = {}
    for side in "LR":
        c = pos[f"contact_{side}"]
        if c is None:
            continue
        v = (c - origin) - ((c - origin) @ y) * y
        if np.linalg.norm(v) < MIN_RADIUS_FRACTION * spacing:
            raise DofError(f"{where}contact_{side} at {c.tolist()} lies on the axle axis (within "
                           f"{MIN_RADIUS_FRACTION * spacing:.3g} m); a wheel–rail contact lies a rolling radius below "
                           f"the axle: check its coordinates or its FE node")
        offsets[side] = v
    if len(offsets) == 2 and _angle_deg(offsets["L"], offsets["R"]) > MAX_AXIS_DISAGREEMENT_DEG:
        raise DofError(f"{where}contact_L and contact_R lie on different sides of the axle axis "
                       f"({_angle_deg(offsets['L'], offsets['R']):.1f}° apart around it); both touch the rails "
                       f"below the axle")
    if len(pairs) == 2:
        angle = _angle_deg(pairs["axlebox"][1] - pairs["axlebox"][0], pairs["contact"][1] - pairs["contact"][0])
        if angle > MAX_AXIS_DISAGREEMENT_DEG:
            raise DofError(f"{where}axlebox_L→axlebox_R and contact_L→contact_R point {angle:.1f}° apart (at most "
                           f"{MAX_AXIS_DISAGREEMENT_DEG:g}° for one axle); check the points' coordinates and sides")
    z = -_unit(sum(offsets.values()))
    z = _unit(z - (z @ y) * y)
    q = np.vstack([np.cross(y, z), y, z])
    used = f"{kind}_L→{kind}_R along the axle, " + " and ".join(f"contact_{s}" for s in offsets) + " below it"
    axes = _nearest_axes(q)
    off = RailwayFrame(q @ axes.T).angle_deg
    if off <= SNAP_DEG:
        if off > 1e-6:
            used += f"; {off:.1f}° off the FE's axes, taken as them"
        q = axes
    return RailwayFrame(q, basis=used)


def _nearest_axes(q: np.ndarray) -> np.ndarray:
    """The signed permutation of the FE's axes nearest the rotation ``q`` (a proper rotation too), or ``q`` itself
    when its rows do not pick three different axes."""
    p = np.zeros((3, 3))
    for k in range(3):
        j = int(np.argmax(np.abs(q[k])))
        p[k, j] = np.sign(q[k, j])
    if not np.allclose(np.abs(p).sum(axis=0), 1.0) or np.linalg.det(p) < 0:
        return q
    return p


def _axle_point_from_fe(fe, a: np.ndarray, b: np.ndarray, y: np.ndarray) -> np.ndarray | None:
    """A point of the axle axis when only the contacts are known: the FE's nodes midway between the wheels that lie
    on a line along ``y`` (the axle's beam or its centre line); None if the FE has no coordinates."""
    if fe is None or not fe.has_coordinates:
        return None
    mid = 0.5 * (a + b)
    rel = fe.xyz - mid
    along = rel @ y
    near_mid = np.abs(along) < 0.25 * float(np.linalg.norm(b - a))
    if not near_mid.any():
        return None
    # the axle is the FE's material closest to the wheelset's mid-plane centre: the node cloud's centroid there
    perp = rel[near_mid] - np.outer(along[near_mid], y)
    return mid + perp.mean(axis=0)


def check_railway_frame(points: Mapping[str, Point], fe=None, *, what: str = "the model",
                        max_angle_deg: float = 2.0) -> None:
    """Refuse points that are not in the railway frame (the field side needs it: ``contact_L:z`` is vertical).

    Raises
    ------
    DofError
        The frame the points define is turned more than ``max_angle_deg`` from the model's axes; the message
        says which FE directions are the railway axes and how to rebuild the model in the railway frame.
    """
    frame = railway_frame(points, fe)
    if frame is not None and frame.angle_deg > max_angle_deg:
        raise DofError(f"{what} is not in the railway frame (x along the track, y along the axle from left to "
                       f"right, z up): its points put the {frame.axes_text()} (from {frame.basis}); build it with "
                       f"'railmodal model build' or 'railmodal lab diagnose', which turn the FE, the points and the "
                       f"channel tables into it (or receptance.to_railway_frame in Python)")


def _description(desc, frame: RailwayFrame):
    """Turn the description's positions (the FE's frame); hub planes are axial positions, the same in both frames
    (the projection on the L→R axle direction, which the rotation keeps), the axlebox inertia is about the railway
    axes by definition."""
    if desc is None:
        return None
    centres = {s: None if c is None else tuple(frame.xyz(c)) for s, c in desc.axlebox_centres.items()}
    hanging = None if desc.hanging_points is None else tuple(
        p if isinstance(p, str) else tuple(frame.xyz(p)) for p in desc.hanging_points)
    return replace(desc, axlebox_centres=centres, hanging_points=hanging)


def to_railway_frame(points: Mapping[str, Point], fe=None, *, tables=(), description=None, source: str = ""):
    """The FE modes, points, channel tables and description, turned into the railway frame the points define.

    Parameters
    ----------
    points : mapping name -> Point
    fe : fem_import.FEModes, optional
    tables : sequence of DataFrame
        Channel tables (``x, y, z, dx, dy, dz``) in the FE's frame.
    description : WheelsetDescription, optional
    source : str
        The points file, for messages.

    Returns
    -------
    frame : RailwayFrame
        The identity when the inputs are already in the railway frame, or when the points cannot tell it (then
        ``frame.basis`` says so).
    points, fe, tables, description
        Turned; the very same objects when ``frame`` is the identity.
    """
    frame = railway_frame(points, fe, source=source)
    if frame is None:
        return (RailwayFrame(np.eye(3), basis="the points do not fix it (no axle direction or no contact position); "
                                              "the FE's axes are taken as the railway axes"),
                points, fe, tuple(tables), description)
    if frame.is_identity:
        return frame, points, fe, tuple(tables), description
    log.info("%s%s", f"{source}: " if source else "", frame.describe())
    turned = {n: Point(p.name, p.fe_node, None if p.xyz is None else tuple(frame.xyz(p.xyz)))
              for n, p in points.items()}
    fe2 = None if fe is None else fe.rotated(frame.rotation, note=f"railway frame from {frame.basis}")
    return frame, turned, fe2, tuple(frame.table(t) for t in tables), _description(description, frame)
