"""Collision geometry of a robot in its cell, and the distances between its bodies (Pinocchio + coal).

Bodies (DESIGN.md, "Collision"): every URDF link with ``<collision>`` geometry (meshes found as
:mod:`singplan.kinematics.packages` finds them, ``package://`` included), the tool (``tool.geometry``,
fixed to the tip frame, one body named ``tool``) and every ``cell`` shape (fixed in the base frame).
They are held in a Pinocchio ``GeometryModel``; distances are coal's.

Checked pairs, MoveIt's convention: every robot body against every cell shape, and with
``collision.self`` every robot body against every other, except links in one rigid group (joined by
fixed joints), groups one joint apart in the URDF's tree, the tool against the tip's group, the
SRDF's ``<disable_collisions>`` pairs (``collision.srdf``, else ``<urdf stem>.srdf`` beside the URDF)
and ``collision.allow``. Cell shapes are never checked against each other.

Every body also carries what the clearance check (:mod:`singplan.kinematics.clearance`) needs to
skip work: a capsule enclosing each of its shapes (a lower bound of a distance costs a few
multiplications for many samples at once) and its *reach* per joint, a bound of how far any of its
points moves per radian of that joint, so the motion between two samples is bounded from the joint
deltas alone (conservative advancement, Mirtich 1996; Schwarzer, Saha and Latombe 2005).
"""

from __future__ import annotations

import difflib
import json
import logging
import math
import re
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from functools import cached_property, lru_cache
from pathlib import Path
from typing import Literal, NamedTuple

import coal
import numpy as np
import pinocchio as pin

from singplan.errors import InputError, RobotModelError, TaskError
from singplan.kinematics.chain import faithful, placed
from singplan.kinematics.files import FileRefusedError, display_path, read_bounded, read_bounded_text
from singplan.kinematics.geometry import rpy_deg_to_rotation
from singplan.kinematics.packages import resolve_uri
from singplan.kinematics.robot import MAX_URDF_BYTES, Robot
from singplan.kinematics.shapes import TOOL_BODY, CollisionSettings, Shape

logger = logging.getLogger(__name__)

MAX_MESH_BYTES = 64 * 1024 * 1024  # a collision mesh file (cell, tool or URDF)
MAX_MESH_TRIANGLES = 2_000_000  # coal builds a bounding-volume tree of every triangle
MAX_SRDF_BYTES = 8 * 1024 * 1024
BodyKind = Literal["link", "tool", "cell"]


@dataclass(frozen=True, eq=False)
class Geom:
    """One shape of a body.

    Attributes:
        geometry: the coal shape, in its own frame.
        rotation, translation: its placement in the body's joint frame (the base frame for the cell).
        is_mesh: a triangle mesh (coal gives no penetration depth between meshes).
        segment: (2, 3) the axis ends of a capsule enclosing it, in the joint frame [m].
        radius_m: that capsule's radius.
        hull: a mesh's convex hull (None for a primitive): coal's GJK measures it in microseconds where
            the mesh takes up to milliseconds, and its distance is a lower bound of the mesh's.
        corners: (V, 3) the hull's vertices in the shape's frame (meshes; None for a primitive): the
            least of ``n . x`` over them is the mesh's (:func:`support`).
    """

    geometry: coal.CollisionGeometry
    rotation: np.ndarray  # (3, 3)
    translation: np.ndarray  # (3,)
    is_mesh: bool
    segment: np.ndarray  # (2, 3)
    radius_m: float
    hull: coal.CollisionGeometry | None = None
    corners: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class Body:
    """A link, the tool or a cell shape.

    Attributes:
        name: the URDF link's name, ``tool``, or the cell shape's name.
        kind: link | tool | cell.
        joint: the robot model's joint frame that carries it (0: the base); None for the cell.
        group: its rigid group in the URDF's tree (links joined by fixed joints share one); None for the cell.
        geoms: its shapes.
        reach_m: (n,) how far any of its points moves per radian of each joint [m/rad]: the joint
            origins' offsets from that joint out to the body plus the body's extent (for its own
            joint, its points' distance from that joint's axis); 0 for joints that do not move it.
        extent_m: how far its points reach from its joint frame's origin [m].
        arm_m: (n,) how far its points are from each joint's origin at most [m] (0 for joints that do not
            move it): the curvature bound of :mod:`~singplan.kinematics.clearance` needs it.
    """

    name: str
    kind: BodyKind
    joint: int | None
    group: int | None
    geoms: tuple[Geom, ...]
    reach_m: np.ndarray
    extent_m: float = 0.0
    arm_m: np.ndarray | None = None

    @cached_property
    def sphere(self) -> tuple[np.ndarray, float]:
        """A sphere enclosing the body: its centre in the joint frame (the base frame for the cell) and radius."""
        ends = np.concatenate([g.segment for g in self.geoms])
        centre = 0.5 * (ends.min(axis=0) + ends.max(axis=0))
        radius = max(float(np.linalg.norm(g.segment - centre, axis=1).max()) + g.radius_m for g in self.geoms)
        return centre, radius


@dataclass(frozen=True, eq=False)
class Pair:
    """Two bodies that are checked, and the bound of their relative motion per radian of each joint
    [m/rad] (joints that carry both bodies do not change their distance: 0); ``arms``: the same with
    the distances from the joints' origins (:attr:`Body.arm_m`)."""

    a: Body
    b: Body
    weights: np.ndarray  # (n,)
    arms: np.ndarray  # (n,)

    @property
    def names(self) -> tuple[str, str]:
        return self.a.name, self.b.name


@dataclass(frozen=True)
class Distance:
    """A measured distance between two bodies.

    Attributes:
        distance_m: the least distance [m]; negative: penetration depth; -inf: meshes intersect
            (coal gives no depth between meshes).
        point_a, point_b: the closest points of the two bodies in the base frame [m].
        exact: the distance itself; False: a lower bound (a convex hull's distance, at least the
            ``enough`` asked for).
    """

    distance_m: float
    point_a: np.ndarray
    point_b: np.ndarray
    exact: bool = True


class ShapeGap(NamedTuple):
    """One shape pair's part of a measurement (:meth:`CollisionModel.pair_distance`'s ``gaps``).

    Attributes:
        a, b: the shapes' indices in the bodies' ``geoms``.
        distance_m: their distance [m] (a mesh's convex hull's where only a bound was asked for).
        point_a, point_b: the closest points, in the base frame [m] (3,).
    """

    a: int
    b: int
    distance_m: float
    point_a: np.ndarray
    point_b: np.ndarray


@dataclass(frozen=True)
class FixedContact:
    """A cell shape closer than the clearance to a robot body that no joint moves (the base, and links
    fixed to it): the same at every configuration, so at every sample of every plan. DESIGN.md
    ("Collision") counts it as a collision like any other; a shape meant to touch the robot (the floor,
    pedestal or table it stands on) is allowed by name.

    Attributes:
        body: the robot body (a URDF link).
        shape: the cell shape.
        distance_m: their distance [m] (negative: penetration depth; -inf: meshes intersecting).
        lowest_z_m: the lowest point of the body's collision shapes in the base frame [m].
    """

    body: str
    shape: str
    distance_m: float
    lowest_z_m: float

    @property
    def allow_yaml(self) -> str:
        """The task's ``collision`` key that leaves the pair out, with the real names."""
        return f"collision: {{allow: [[{_yaml_name(self.body)}, {_yaml_name(self.shape)}]]}}"

    def advice(self, clearance_m: float) -> str:
        """What the contact is and how to fix it, for messages."""
        top_mm = math.floor((self.lowest_z_m - clearance_m) * 1e5 - 1e-6) / 100  # below it: touching collides
        how = "touching" if abs(self.distance_m) < 5e-6 else describe_distance(self.distance_m)
        return (f"{self.body} and {self.shape} are {how}, closer than the clearance "
                f"{clearance_m * 1e3:g} mm, in every configuration: {self.body} never moves, so a cell shape "
                f"touching it is a collision by design (user guide, \"Collision\"). If {self.shape} is what the "
                f"robot stands on (a floor, pedestal or table) or is meant to touch it, allow the pair: "
                f"`{self.allow_yaml}`; "
                f"else move {self.shape} clear ({self.body} reaches down to z = {self.lowest_z_m * 1e3:.2f} mm: a "
                f"floor under it needs its top at z <= {top_mm:.2f} mm)")


def _yaml_name(name: str) -> str:
    """A body name as a YAML flow scalar (quoted where a bare word would not read back as itself)."""
    return name if re.fullmatch(r"[A-Za-z_][A-Za-z0-9_.-]*", name) and name.lower() not in _YAML_WORDS \
        else json.dumps(name)


_YAML_WORDS = {"true", "false", "yes", "no", "on", "off", "null", "y", "n"}


class CollisionModel:
    """A robot's bodies in its task's cell and the pairs to check.

    Attributes:
        robot: the robot (the chain planned).
        bodies: links with collision geometry, then ``tool``, then the cell shapes.
        pairs: the checked pairs.
        clearance_m: every pair must stay this far apart [m].
        self_collision: robot bodies are checked against each other.
        srdf: the SRDF whose pairs were skipped, or None.
        skipped: how many pairs each rule left out (same_group, adjacent, srdf, allow).
        notes: what is not checked and why (e.g. a URDF without ``<collision>`` elements).
    """

    def __init__(self, robot: Robot, bodies: list[Body], pairs: list[Pair], clearance_m: float, self_collision: bool,
                 srdf: Path | None, skipped: dict[str, int], notes: tuple[str, ...]) -> None:
        self.robot = robot
        self.bodies = tuple(bodies)
        self.pairs = tuple(pairs)
        self.clearance_m = clearance_m
        self.self_collision = self_collision
        self.srdf = srdf
        self.skipped = skipped
        self.notes = notes
        self._request = coal.DistanceRequest()
        self._result = coal.DistanceResult()
        self.distance_calls = 0

    @property
    def active(self) -> bool:
        """Whether anything is checked."""
        return bool(self.pairs)

    @cached_property
    def geometry(self) -> pin.GeometryModel:
        """Every shape as a Pinocchio ``GeometryModel`` (the cell's on the universe joint), made when
        asked for: the distances themselves are coal's on the placed shapes."""
        return _geometry_model(self.robot, list(self.bodies))

    def pair_distance(self, pair: Pair, rotations: np.ndarray, origins: np.ndarray,
                      enough: float = math.inf, placed: dict[int, coal.Transform3s] | None = None,
                      gaps: list[ShapeGap] | None = None) -> Distance:
        """The least distance of a pair with the joint frames at ``rotations`` (J, 3, 3), ``origins`` (J, 3).

        ``enough``: a distance that need not be known more exactly: where the convex hulls of the
        meshes are that far apart, their distance is returned as a lower bound (``exact`` False).
        ``placed``: the shapes already placed at these frames, by ``id`` of their geom (filled in as
        they are placed: a body measured against several others at one sample is placed once).
        ``gaps``: filled in with every shape pair's distance and closest points (each a separating
        plane of that pair, :mod:`~singplan.kinematics.clearance`), up to a contact between meshes.
        """
        placed = placed if placed is not None else {}
        best = Distance(math.inf, np.zeros(3), np.zeros(3))
        for ia, ga in enumerate(pair.a.geoms):
            Ta = _placed_once(placed, ga, pair.a.joint, rotations, origins)
            for ib, gb in enumerate(pair.b.geoms):
                Tb = _placed_once(placed, gb, pair.b.joint, rotations, origins)
                exact = True
                if ga.hull is not None or gb.hull is not None:
                    d = self._distance(ga.hull or ga.geometry, Ta, gb.hull or gb.geometry, Tb)
                    exact = d < enough
                if exact:
                    d = self._distance(ga.geometry, Ta, gb.geometry, Tb)
                    if d <= 0.0 and (ga.is_mesh or gb.is_mesh):
                        d = -math.inf  # a mesh has no inside for coal: touching or crossing, no depth
                if gaps is None and d >= best.distance_m:
                    continue
                point_a, point_b = np.array(self._result.getNearestPoint1()), np.array(self._result.getNearestPoint2())
                if gaps is not None:
                    gaps.append(ShapeGap(ia, ib, d, point_a, point_b))
                if d < best.distance_m:
                    best = Distance(d, point_a, point_b, exact)
                if d == -math.inf:
                    return best
        return best

    @cached_property
    def fixed_contacts(self) -> tuple[FixedContact, ...]:
        """The checked pairs of a cell shape and a robot body no joint moves that are closer than the
        clearance (the same at every configuration), closest first."""
        fixed = [p for p in self.pairs if "cell" in (p.a.kind, p.b.kind) and not p.weights.any()]
        if not fixed:
            return ()
        R, P = self.robot.joint_frames(np.zeros((1, self.robot.n_joints)))
        found = []
        for pair in fixed:
            body, shape = (pair.a, pair.b) if pair.b.kind == "cell" else (pair.b, pair.a)
            d = self.pair_distance(pair, R[0], P[0]).distance_m
            if d >= self.clearance_m and self.inside_mesh(pair, R[0], P[0]):
                d = -math.inf
            if d < self.clearance_m:
                found.append(FixedContact(body.name, shape.name, d, _lowest_z(body, R[0], P[0])))
        return tuple(sorted(found, key=lambda c: c.distance_m))

    def _distance(self, a: coal.CollisionGeometry, Ta: coal.Transform3s, b: coal.CollisionGeometry,
                  Tb: coal.Transform3s) -> float:
        self._result.clear()
        self.distance_calls += 1
        return float(coal.distance(a, Ta, b, Tb, self._request, self._result))

    def inside_mesh(self, pair: Pair, rotations: np.ndarray, origins: np.ndarray) -> bool:
        """Whether one body of the pair lies wholly inside a (closed) mesh of the other: coal measures
        to a mesh's surface only, so a body inside a mesh obstacle reads as clear (ray parity test of a
        point of each shape, :func:`_inside`)."""
        for inner, outer in ((pair.a, pair.b), (pair.b, pair.a)):
            for go in outer.geoms:
                if not go.is_mesh:
                    continue
                To = _placed(go, outer.joint, rotations, origins)
                for gi in inner.geoms:
                    Ti = _placed(gi, inner.joint, rotations, origins)
                    probe = Ti.transform(_probe_point(gi))
                    if _inside(go, To.inverse().transform(probe)):
                        return True
        return False


def _placed_once(placed: dict[int, coal.Transform3s], g: Geom, joint: int | None, rotations: np.ndarray,
                 origins: np.ndarray) -> coal.Transform3s:
    found = placed.get(id(g))
    if found is None:
        found = placed[id(g)] = _placed(g, joint, rotations, origins)
    return found


def _lowest_z(body: Body, rotations: np.ndarray, origins: np.ndarray) -> float:
    """The lowest z of a body's shapes in the base frame [m] (its joint frames at ``rotations``, ``origins``)."""
    up = np.array([0.0, 0.0, 1.0])
    lows = []
    for g in body.geoms:
        T = _placed(g, body.joint, rotations, origins)
        R = np.array(T.getRotation())
        lows.append(float(T.getTranslation()[2] + support(g, (R.T @ up)[None])[0]))
    return min(lows)


def _placed(g: Geom, joint: int | None, rotations: np.ndarray, origins: np.ndarray) -> coal.Transform3s:
    if joint is None:
        return coal.Transform3s(g.rotation, g.translation)
    R = rotations[joint]
    if faithful():  # numpy's products, compiled (one call instead of three)
        return coal.Transform3s(*placed(R, origins[joint], g.rotation, g.translation))
    return coal.Transform3s(R @ g.rotation, origins[joint] + R @ g.translation)


def collision_model(robot: Robot, tool: tuple[Shape, ...] = (), cell: tuple[Shape, ...] = (),
                    settings: CollisionSettings | None = None, start: np.ndarray | None = None) -> CollisionModel:
    """The bodies and checked pairs of ``robot`` with the task's tool shapes, cell and ``collision`` key
    (None: the task has none; the robot's own links are still checked against each other).

    ``start``: the task's start joints [rad]. A task without a ``collision`` key on a URDF without an
    SRDF says nothing of which of its shapes touch by construction; as MoveIt's setup assistant leaves
    out the pairs in contact by default, the pairs in contact at the robot's zero joints (clipped to
    its limits) or at ``start`` are not checked (``skipped["resting"]``, named in ``notes``). With a
    ``collision`` key (or an SRDF) the pairs are exactly DESIGN.md's.

    Raises:
        TaskError: a cell or tool mesh that is not a mesh (its field named), an SRDF that cannot be
            read, an unknown body in ``collision.allow``, a cell name that is also a link's.
        RobotModelError: a collision mesh of the URDF that cannot be found or read.
    """
    given, settings = settings, settings if settings is not None else CollisionSettings()
    urdf = _urdf_collisions(robot.urdf_path)
    bodies = _link_bodies(robot, urdf)
    notes = [] if bodies else [f"{robot.urdf_path.name} has no <collision> elements: no self-collision check"]
    tool_geoms = [_shape_geom(s, _tip_placement(robot)) for s in tool]
    if tool_geoms:
        joint = int(robot.model.frames[robot.tip_frame_id].parentJoint)
        bodies.append(Body(TOOL_BODY, "tool", joint, urdf.groups[_tip_link(robot, urdf)], tuple(tool_geoms),
                           *_reach(robot, joint, tool_geoms)))
    for shape in cell:
        if shape.name in urdf.groups:
            raise TaskError(f"{shape.field}.name", f"{shape.name!r} is a link of {robot.name}; give the shape "
                                                   "another name")
        bodies.append(Body(shape.name, "cell", None, None, (_shape_geom(shape, pin.SE3.Identity()),),
                           np.zeros(robot.n_joints), 0.0, np.zeros(robot.n_joints)))
    srdf = _srdf_path(robot, settings)
    disabled = _srdf_pairs(srdf, settings.srdf is not None) if srdf is not None else set()
    allowed = _allowed(settings, set(urdf.groups) | {TOOL_BODY} | {s.name for s in cell})
    pairs, skipped = _pairs(bodies, urdf.adjacent, disabled, allowed, settings.self_collision)
    if not settings.self_collision:
        notes.append("collision.self is false: robot bodies are not checked against each other")
    model = CollisionModel(robot, bodies, pairs, settings.clearance_mm / 1e3, settings.self_collision and
                           any(b.kind == "link" for b in bodies), srdf, skipped, tuple(notes))
    if given is not None or srdf is not None:
        return model
    zero = np.clip(np.zeros(robot.n_joints), robot.lower_rad, robot.upper_rad)
    return _without_resting_contacts(model, (zero,) if start is None else (zero, np.asarray(start, dtype=float)))


def _without_resting_contacts(model: CollisionModel, resting: tuple[np.ndarray, ...]) -> CollisionModel:
    """The model without the self pairs in contact at any of the ``resting`` joint values."""
    R, P = model.robot.joint_frames(np.array(resting))
    touching = [pair for pair in model.pairs if pair.a.kind != "cell" and pair.b.kind != "cell"
                and any(model.pair_distance(pair, R[k], P[k], 0.0).distance_m <= 0.0 for k in range(len(R)))]
    if not touching:
        return model
    names = ", ".join(f"{p.a.name}/{p.b.name}" for p in touching)
    note = (f"no SRDF: {len(touching)} pair(s) touching at the zero or start configuration are not checked "
            f"(their shapes overlap by construction; give collision.srdf to say which pairs to skip): {names}")
    return CollisionModel(model.robot, list(model.bodies), [p for p in model.pairs if p not in touching],
                          model.clearance_m, model.self_collision, None,
                          {**model.skipped, "resting": len(touching)}, (*model.notes, note))


# -- the URDF: collision elements and the link tree ---------------------------------------------------


@dataclass(frozen=True)
class _LinkShape:
    link: str
    placement: pin.SE3  # in the link's frame
    kind: str
    values: tuple[float, ...]  # box size / (radius, length) / (radius,) / mesh scale
    mesh: Path | None


@dataclass(frozen=True)
class _UrdfCollisions:
    shapes: tuple[_LinkShape, ...]
    groups: dict[str, int]  # link -> rigid group (links joined by fixed joints share one)
    adjacent: frozenset[frozenset[int]]  # groups one joint apart


@lru_cache(maxsize=16)
def _urdf_collisions_cached(path: Path, _stamp: tuple[int, int]) -> _UrdfCollisions:
    text = read_bounded_text(path, MAX_URDF_BYTES, "URDF")
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise RobotModelError(str(path), f"cannot be read as XML for its collision geometry ({exc})") from None
    shapes = [shape for link in root.iter("link") for shape in _link_shapes(path, link)]
    groups, adjacent = _tree(root)
    return _UrdfCollisions(tuple(shapes), groups, adjacent)


def _urdf_collisions(path: Path) -> _UrdfCollisions:
    info = path.stat()
    return _urdf_collisions_cached(path, (info.st_mtime_ns, info.st_size))


def _link_shapes(urdf: Path, link: ET.Element) -> list[_LinkShape]:
    name = link.get("name", "")
    out = []
    for element in link.findall("collision"):
        geometry = element.find("geometry")
        shape = None if geometry is None else next(iter(geometry), None)
        if shape is None:
            raise RobotModelError(str(urdf), f"link {name!r}: a <collision> element without geometry")
        placement = _origin(urdf, name, element.find("origin"))
        kind = shape.tag
        try:
            if kind == "box":
                values = _floats(shape.get("size", ""), 3)
            elif kind == "cylinder":
                values = (float(shape.get("radius", "nan")), float(shape.get("length", "nan")))
            elif kind == "sphere":
                values = (float(shape.get("radius", "nan")),)
            elif kind == "mesh":
                values = _floats(shape.get("scale", "1 1 1"), 3)
            else:
                raise RobotModelError(str(urdf), f"link {name!r}: collision geometry <{kind}> is not box, cylinder, "
                                                 "sphere or mesh")
        except ValueError:
            raise RobotModelError(str(urdf), f"link {name!r}: <{kind}> of a <collision> has malformed numbers"
                                  ) from None
        if not all(math.isfinite(v) and v > 0 for v in values):
            raise RobotModelError(str(urdf), f"link {name!r}: <{kind}> of a <collision> needs positive sizes, "
                                             f"got {list(values)}")
        mesh = _urdf_mesh(urdf, name, shape.get("filename", "")) if kind == "mesh" else None
        out.append(_LinkShape(name, placement, kind, values, mesh))
    return out


def _floats(text: str, n: int) -> tuple[float, ...]:
    values = tuple(float(v) for v in text.split())
    if len(values) != n:
        raise ValueError(text)
    return values


def _origin(urdf: Path, link: str, element: ET.Element | None) -> pin.SE3:
    if element is None:
        return pin.SE3.Identity()
    try:
        xyz = np.array(_floats(element.get("xyz", "0 0 0"), 3))
        rpy = _floats(element.get("rpy", "0 0 0"), 3)
    except ValueError:
        raise RobotModelError(str(urdf), f"link {link!r}: a <collision> origin has malformed numbers") from None
    return pin.SE3(pin.rpy.rpyToMatrix(*rpy), xyz)


def _urdf_mesh(urdf: Path, link: str, uri: str) -> Path:
    path = resolve_uri(uri, urdf) if uri else None
    if path is None:
        raise RobotModelError(str(urdf), f"link {link!r}: collision mesh {uri!r} not found (package:// URIs are "
                                         "looked for above the URDF, in example-robot-data, ROS_PACKAGE_PATH and "
                                         "AMENT_PREFIX_PATH)")
    return path


def _tree(root: ET.Element) -> tuple[dict[str, int], frozenset[frozenset[int]]]:
    """Each link's rigid group (links joined by fixed joints are one, as Pinocchio merges them) and the
    pairs of groups one movable joint apart."""
    links = [link.get("name", "") for link in root.iter("link")]
    parent = {name: name for name in links}

    def top(name: str) -> str:
        while parent[name] != name:
            parent[name] = parent[parent[name]]
            name = parent[name]
        return name

    joints = [(j.get("type", ""), j.find("parent"), j.find("child")) for j in root.iter("joint")]
    edges = [(kind, p.get("link", ""), c.get("link", "")) for kind, p, c in joints if p is not None and c is not None]
    for kind, a, b in edges:
        if kind == "fixed" and a in parent and b in parent:
            parent[top(b)] = top(a)
    ids = {name: i for i, name in enumerate(dict.fromkeys(top(n) for n in links))}
    groups = {name: ids[top(name)] for name in links}
    adjacent = frozenset(frozenset((groups[a], groups[b])) for kind, a, b in edges
                         if kind != "fixed" and a in groups and b in groups)
    return groups, adjacent


def _link_bodies(robot: Robot, urdf: _UrdfCollisions) -> list[Body]:
    model = robot.model
    geoms: dict[str, list[Geom]] = {}
    joints: dict[str, int] = {}
    for shape in urdf.shapes:
        if not model.existFrame(shape.link, pin.FrameType.BODY):
            continue  # a link the chain's model does not hold
        frame = model.frames[model.getFrameId(shape.link, pin.FrameType.BODY)]
        joints[shape.link] = int(frame.parentJoint)
        geometry = _coal_shape(shape.kind, shape.values, shape.mesh, f"link {shape.link!r} of {robot.urdf_path.name}")
        geoms.setdefault(shape.link, []).append(_geom(geometry, frame.placement * shape.placement))
    return [Body(link, "link", joints[link], urdf.groups[link], tuple(g), *_reach(robot, joints[link], g))
            for link, g in geoms.items()]


def _tip_placement(robot: Robot) -> pin.SE3:
    """The tip frame in its joint's frame (tool shapes are given in the tip frame)."""
    return pin.SE3(robot.model.frames[robot.tip_frame_id].placement)


def _tip_link(robot: Robot, urdf: _UrdfCollisions) -> str:
    """The URDF link the tip frame belongs to (the tool is adjacent to it)."""
    model = robot.model
    k = robot.tip_frame_id
    while model.frames[k].name not in urdf.groups and k > 0:
        k = int(model.frames[k].parentFrame)
    return model.frames[k].name if model.frames[k].name in urdf.groups else next(iter(urdf.groups))


# -- shapes -------------------------------------------------------------------------------------------


def _shape_geom(shape: Shape, frame: pin.SE3) -> Geom:
    """A task shape placed in its parent frame (``frame``: the tip frame in its joint's, or identity)."""
    where = f"{shape.field}.{shape.kind}.file" if shape.kind == "mesh" else shape.field
    values = shape.mesh_scale if shape.kind == "mesh" else shape.dimensions_m
    geometry = _coal_shape(shape.kind, values, Path(shape.mesh_file) if shape.mesh_file else None, where, task=True)
    pose = pin.SE3(rpy_deg_to_rotation(shape.rpy_deg), np.asarray(shape.xyz, dtype=float))
    return _geom(geometry, frame * pose)


def _coal_shape(kind: str, values: tuple[float, ...], mesh: Path | None, where: str,
                task: bool = False) -> coal.CollisionGeometry:
    if kind == "box":
        return coal.Box(*values)
    if kind == "cylinder":
        return coal.Cylinder(values[0], values[1])
    if kind == "sphere":
        return coal.Sphere(values[0])
    assert mesh is not None
    try:
        return load_mesh(mesh, values)
    except FileRefusedError as exc:
        if task:
            raise TaskError(where, f"{exc.path}: {exc.reason}") from None
        raise RobotModelError(exc.path, f"{exc.reason} ({where})") from None
    except InputError as exc:
        if task:
            raise TaskError(where, str(exc)) from None
        raise RobotModelError(str(mesh), f"{exc} ({where})") from None


def _geom(geometry: coal.CollisionGeometry, placement: pin.SE3) -> Geom:
    segment, radius = _capsule(geometry)
    R, t = np.array(placement.rotation), np.array(placement.translation)
    is_mesh = isinstance(geometry, coal.BVHModelBase)
    hull, corners = _hull(geometry) if is_mesh else (None, None)
    return Geom(geometry, R, t, is_mesh, segment @ R.T + t, radius, hull, corners)


def support(g: Geom, n: np.ndarray) -> np.ndarray:
    """The least of ``n . x`` over the points x of a shape (its own frame) for directions n (N, 3): its
    support function at -n, closed form for primitives, over the hull's vertices for a mesh."""
    shape = g.geometry
    if isinstance(shape, coal.Sphere):
        return -float(shape.radius) * np.linalg.norm(n, axis=1)
    if isinstance(shape, coal.Box):
        return -np.abs(n) @ np.array(shape.halfSide, dtype=float)
    if isinstance(shape, coal.Cylinder):
        return -float(shape.halfLength) * np.abs(n[:, 2]) - float(shape.radius) * np.hypot(n[:, 0], n[:, 1])
    assert g.corners is not None
    return np.min(n @ g.corners.T, axis=1)


@lru_cache(maxsize=256)
def _hull(mesh: coal.BVHModelBase) -> tuple[coal.CollisionGeometry | None, np.ndarray]:
    """A mesh's convex hull (qhull through coal; None for a flat mesh, which qhull refuses) and its corners
    (V, 3) (the mesh's vertices without a hull). Built from the vertex list: coal's
    ``buildConvexRepresentation`` gives hulls whose distances exceed the mesh's on some meshes."""
    vertices = np.array(mesh.vertices(), dtype=float)
    try:
        hull = coal.ConvexBase.convexHull([np.array(v) for v in vertices], False, "")
    except (ValueError, RuntimeError):
        return None, vertices
    return hull, np.array([hull.point(i) for i in range(hull.num_points)], dtype=float)


def _capsule(geometry: coal.CollisionGeometry) -> tuple[np.ndarray, float]:
    """A capsule enclosing a shape in its own frame: (2, 3) axis ends and a radius.

    Cylinders along their axis; boxes along their longest edge with the half diagonal of the other two
    as radius; meshes along the principal axis of their vertices, as far as the vertices reach.
    """
    if isinstance(geometry, coal.Sphere):
        return np.zeros((2, 3)), float(geometry.radius)
    if isinstance(geometry, coal.Cylinder):
        h = float(geometry.halfLength)
        return np.array([[0.0, 0.0, -h], [0.0, 0.0, h]]), float(geometry.radius)
    if isinstance(geometry, coal.Box):
        half = np.array(geometry.halfSide, dtype=float)
        axis = int(np.argmax(half))
        end = np.zeros(3)
        end[axis] = half[axis]
        return np.array([-end, end]), float(np.linalg.norm(np.delete(half, axis)))
    return _mesh_capsule(geometry)


@lru_cache(maxsize=256)
def _mesh_capsule(mesh: coal.BVHModelBase) -> tuple[np.ndarray, float]:
    """:func:`_capsule` of a mesh (made once per mesh, which the loader caches)."""
    vertices = np.array(mesh.vertices(), dtype=float)
    centre = vertices.mean(axis=0)
    _, _, vt = np.linalg.svd(vertices - centre, full_matrices=False)
    along = (vertices - centre) @ vt[0]
    across = np.linalg.norm((vertices - centre) - np.outer(along, vt[0]), axis=1)
    return np.array([centre + along.min() * vt[0], centre + along.max() * vt[0]]), float(across.max())


def load_mesh(path: Path, scale: tuple[float, ...] | np.ndarray) -> coal.BVHModelOBBRSS:
    """A mesh file (STL, OBJ, or any format assimp reads) as a coal triangle mesh, scaled per axis.

    The file is read through :func:`~singplan.kinematics.files.read_bounded` (a regular file within
    :data:`MAX_MESH_BYTES`: a FIFO or device never reaches the mesh reader) and handed to coal's
    assimp loader as a private copy.

    Raises:
        FileRefusedError: missing, not a regular file, or over the cap.
        InputError: not a mesh assimp can read, no triangles, or over :data:`MAX_MESH_TRIANGLES`.
    """
    info = path.stat() if path.is_file() else None
    stamp = (info.st_mtime_ns, info.st_size) if info is not None else (0, 0)
    return _load_mesh(path, tuple(float(s) for s in scale), stamp)


@lru_cache(maxsize=64)
def _load_mesh(path: Path, scale: tuple[float, ...], _stamp: tuple[int, int]) -> coal.BVHModelOBBRSS:
    data = read_bounded(path, MAX_MESH_BYTES, "mesh")
    name = display_path(path)
    with tempfile.TemporaryDirectory(prefix="singplan-mesh-") as folder:
        copy = Path(folder) / f"mesh{path.suffix.lower()}"
        copy.write_bytes(data)
        try:
            mesh = coal.MeshLoader().load(str(copy), np.array(scale))
        except (ValueError, RuntimeError) as exc:
            reason = _assimp_reason(str(exc)).replace(str(copy), path.name)
            raise InputError(f"{name} cannot be read as a mesh ({reason})") from None
    if mesh.num_tris == 0:
        raise InputError(f"{name} holds no triangles")
    if mesh.num_tris > MAX_MESH_TRIANGLES:
        raise InputError(f"{name} has {mesh.num_tris} triangles, over the cap of {MAX_MESH_TRIANGLES}")
    return mesh


def _assimp_reason(text: str) -> str:
    """coal's loader error without its source location: the lines after 'message:' up to the hint."""
    lines = text.splitlines()
    start = next((i for i, line in enumerate(lines) if "message:" in line), None)
    if start is None:
        return lines[0] if lines else "unknown error"
    kept = [lines[start].split("message:", 1)[1].strip()]
    kept += [line.strip() for line in lines[start + 1:] if line.strip() and not line.startswith("Hint")][:2]
    return "; ".join(k for k in kept if k)


def _probe_point(g: Geom) -> np.ndarray:
    """A point of a shape in its own frame (a mesh's first vertex, a primitive's centre)."""
    return np.array(g.geometry.vertices()[0], dtype=float) if g.is_mesh else np.zeros(3)


_RAY_DIRECTIONS = np.array([[0.36, 0.48, 0.8], [-0.6, 0.64, -0.48], [0.8, -0.36, 0.48]])


@lru_cache(maxsize=32)
def _triangles(mesh: coal.BVHModelBase) -> np.ndarray:
    """(T, 3, 3) triangle corners of a mesh in its own frame."""
    vertices = np.array(mesh.vertices(), dtype=float)
    faces = np.array([[t[0], t[1], t[2]] for t in (mesh.tri_indices(i) for i in range(mesh.num_tris))], dtype=int)
    return vertices[faces]


def _inside(g: Geom, point: np.ndarray) -> bool:
    """Whether ``point`` (in the mesh's frame) is inside the closed mesh: the parity of a ray's
    crossings (Moeller-Trumbore), the majority of three rays so that a ray grazing an edge is outvoted."""
    tris = _triangles(g.geometry)
    v0, e1, e2 = tris[:, 0], tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    odd = 0
    for direction in _RAY_DIRECTIONS:
        h = np.cross(direction, e2)
        det = np.einsum("ij,ij->i", e1, h)
        usable = np.abs(det) > 1e-14
        inv = np.divide(1.0, det, out=np.zeros_like(det), where=usable)
        s = point - v0
        u = np.einsum("ij,ij->i", s, h) * inv
        qv = np.cross(s, e1)
        v = (qv @ direction) * inv
        t = np.einsum("ij,ij->i", e2, qv) * inv
        odd += int(np.count_nonzero(usable & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0))) % 2
    return odd >= 2


# -- reach, pairs, SRDF -------------------------------------------------------------------------------


def _extent(geoms: list[Geom]) -> float:
    """How far a body's points reach from its joint frame's origin [m] (its capsules' ends plus radius)."""
    return max(float(np.linalg.norm(g.segment, axis=1).max()) + g.radius_m for g in geoms)


def _reach(robot: Robot, joint: int, geoms: list[Geom]) -> tuple[np.ndarray, float, np.ndarray]:
    """A body's reach per joint [m/rad], its extent [m] and its arms per joint [m] (:class:`Body`).

    For each joint between the base and the body's, the offsets of the joint origins from it out to the
    body's joint plus the body's extent bound how far its points are from that joint's origin (its arm),
    and so how far they move per radian; for its own joint, their distance from that joint's axis.
    """
    reach, arm = np.zeros(robot.n_joints), np.zeros(robot.n_joints)
    extent = _extent(geoms)
    if joint == 0:
        return reach, extent, arm
    for j in range(1, joint + 1):
        arm[robot.model.joints[j].idx_q] = robot.offsets_m(j + 1, joint) + extent
    reach[:] = arm
    axis = robot.joint_axes[joint - 1]
    ends = np.concatenate([g.segment for g in geoms])
    across = np.linalg.norm(ends - np.outer(ends @ axis, axis), axis=1)  # the capsules' ends from the axis
    reach[robot.model.joints[joint].idx_q] = max(float(a) + g.radius_m for a, g in
                                                 zip(across, [g for g in geoms for _ in (0, 1)], strict=True))
    return reach, extent, arm


def _pairs(bodies: list[Body], adjacent: frozenset[frozenset[int]], disabled: set[frozenset[str]],
           allowed: set[frozenset[str]], self_collision: bool) -> tuple[list[Pair], dict[str, int]]:
    skipped = {"same_group": 0, "adjacent": 0, "srdf": 0, "allow": 0}
    robot = [b for b in bodies if b.kind != "cell"]
    cell = [b for b in bodies if b.kind == "cell"]
    candidates = [(a, b) for a in robot for b in cell]
    if self_collision:
        candidates += [(a, b) for i, a in enumerate(robot) for b in robot[i + 1:]]
    pairs = []
    for a, b in candidates:
        why = _skip(a, b, adjacent, disabled, allowed)
        if why:
            skipped[why] += 1
        else:
            pairs.append(Pair(a, b, *_weights(a, b)))
    return pairs, skipped


def _skip(a: Body, b: Body, adjacent: frozenset[frozenset[int]], disabled: set[frozenset[str]],
          allowed: set[frozenset[str]]) -> str:
    """Why a pair is not checked ("" when it is)."""
    names = frozenset((a.name, b.name))
    if a.group is not None and b.group is not None:
        if a.group == b.group:
            return "same_group"  # links joined by fixed joints; the tool with the tip's link
        if frozenset((a.group, b.group)) in adjacent and "tool" not in (a.kind, b.kind):
            return "adjacent"
        if a.kind == b.kind == "link" and names in disabled:
            return "srdf"
    return "allow" if names in allowed else ""


def _weights(a: Body, b: Body) -> tuple[np.ndarray, np.ndarray]:
    """The pair's relative motion bounds per joint (reach, arms): joints carrying both bodies move them
    together and count 0."""
    assert a.arm_m is not None and b.arm_m is not None
    both = (a.reach_m > 0) & (b.reach_m > 0)
    return np.where(both, 0.0, a.reach_m + b.reach_m), np.where(both, 0.0, a.arm_m + b.arm_m)


def _srdf_path(robot: Robot, settings: CollisionSettings) -> Path | None:
    if settings.srdf is not None:
        return Path(settings.srdf)
    beside = robot.urdf_path.with_suffix(".srdf")
    return beside if beside.is_file() else None


def _srdf_pairs(path: Path, given: bool) -> set[frozenset[str]]:
    """The ``<disable_collisions link1=".." link2=".."/>`` pairs of a MoveIt SRDF."""
    try:
        info = path.stat()
        return set(_srdf_pairs_cached(path, (info.st_mtime_ns, info.st_size)))
    except (ET.ParseError, FileRefusedError, OSError) as exc:
        reason = f"cannot be read as an SRDF ({exc})"
        if given:
            raise TaskError("collision.srdf", f"{display_path(path)} {reason}") from None
        raise RobotModelError(str(path), reason) from None


@lru_cache(maxsize=16)
def _srdf_pairs_cached(path: Path, _stamp: tuple[int, int]) -> frozenset[frozenset[str]]:
    root = ET.fromstring(read_bounded_text(path, MAX_SRDF_BYTES, "SRDF"))
    return frozenset(frozenset((e.get("link1", ""), e.get("link2", ""))) for e in root.iter("disable_collisions"))


def _allowed(settings: CollisionSettings, names: set[str]) -> set[frozenset[str]]:
    """``collision.allow``, every name one of ``names`` (links, ``tool``, cell shapes)."""
    for i, pair in enumerate(settings.allow):
        for j, name in enumerate(pair):
            if name not in names:
                close = difflib.get_close_matches(name, sorted(names), n=1)
                hint = f"; did you mean {close[0]!r}?" if close else ""
                raise TaskError(f"collision.allow[{i}][{j}]",
                                f"unknown body {name!r}{hint} (the URDF's links, 'tool' and the cell's names: "
                                f"{', '.join(sorted(names))})")
    return {frozenset(p) for p in settings.allow}


def _geometry_model(robot: Robot, bodies: list[Body]) -> pin.GeometryModel:
    """Every shape as a Pinocchio GeometryObject on its joint (the cell's on the universe)."""
    model = pin.GeometryModel()
    for body in bodies:
        joint = body.joint if body.joint is not None else 0
        frame = 0 if body.kind == "cell" else (robot.tip_frame_id if body.kind == "tool" else
                                               robot.model.getFrameId(body.name, pin.FrameType.BODY))
        for k, g in enumerate(body.geoms):
            model.addGeometryObject(pin.GeometryObject(f"{body.name}_{k}", joint, frame,
                                                       pin.SE3(g.rotation, g.translation), g.geometry))
    return model


def describe_distance(distance_m: float) -> str:
    """A distance for messages: '12.34 mm apart', '3.10 mm deep into each other', 'intersecting'."""
    if distance_m == -math.inf:
        return "intersecting (meshes)"
    if distance_m < 0:
        return f"{-distance_m * 1e3:.2f} mm into each other"
    return f"{distance_m * 1e3:.2f} mm apart"
