"""Write robots/urdf/<name>.urdf and <name>.srdf for every bundled OPW arm of robots/urdf/robots.yaml.

The kinematics (joint origins, axes, the link_6 -> tool0 transform) and the limits are the
published numbers of the registry, written with full precision. Visual geometry is simple
cylinders sized from the link offsets; masses and inertias are *estimates* (solid cylinders
of steel-like density scaled to the link length), good enough for a viewer, not for torques.
Each file's header says so in a line singplan reads (:data:`NO_DYNAMICS_MARK`): these arms have
no published dynamics, so singplan reports no torques for them and refuses ``limits.torque_scale``.

Collision geometry: each visual cylinder again, :data:`COLLISION_MARGIN_M` wider and longer at each
end, so the collision shapes enclose the visuals (tests/test_collision_floor.py samples the
visuals' surfaces to show it). Nothing of the base or of link_1 (which joint 1 turns about the
vertical) reaches below the base's mounting plane, z = 0 of the base frame, where the arm stands on
its floor, pedestal or table: a joint housing that would is raised to stand on the plane, and a
collision cylinder's margin stops at it (tests/test_collision_floor.py puts a floor 1 mm below the
plane under every arm). The SRDF (MoveIt's format) disables the pairs MoveIt's setup
assistant would: links one joint apart ("Adjacent"), pairs touching in the zero configuration
("Default") and pairs touching in nearly every configuration ("Always": the shapes overlap at the
joint between them), and the pairs MoveIt's setup assistant found never in contact from the real
meshes of this family of arms (:data:`NEVER_PAIRS`, "Never": the stand-ins, fatter than the real
links, touch in some legal configurations where the arms do not). The wrist and the tool against the
base and link_1 stay checked: that is where these arms do hit themselves.

    python robots/generate_urdfs.py            # rewrite all URDFs and SRDFs
    python robots/generate_urdfs.py --check    # exit 1 if a file on disk is out of date
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from pathlib import Path

import numpy as np
import yaml
import yourdfpy.urdf as ud
from lxml import etree

URDF_DIR = Path(__file__).resolve().parent / "urdf"
LINK_NAMES = ["base_link"] + [f"link_{i}" for i in range(1, 7)] + ["tool0"]
# one colour per link, so the arm reads clearly in a viewer
COLOURS = [
    (0.35, 0.35, 0.38),
    (0.95, 0.55, 0.10),
    (0.95, 0.70, 0.15),
    (0.20, 0.55, 0.85),
    (0.30, 0.70, 0.45),
    (0.65, 0.40, 0.80),
    (0.85, 0.30, 0.30),
]
COLLISION_MARGIN_M = 0.002  # collision cylinders: this much wider, and longer at each end, than the visuals
# Pairs that cannot touch within the joint limits of these arms: MoveIt's setup assistant found them "Never"
# in contact from the real meshes in the ros-industrial configurations of this family of arms
# (ros-industrial/abb@6c06f5b2a0:irb_2400_moveit_config/config/irb_2400.srdf,
#  ros-industrial/kuka_experimental@7f86e2ba99:kuka_kr16_moveit_config/config/kuka_kr16_2.srdf). The stand-in
# cylinders, fatter than the real links, touch in some legal configurations (the elbow bent far, the flange
# folded through the wrist centre): those contacts are the stand-ins', not the arms'. The wrist and the tool
# against the base, link_1 and (for the tool) every link stay checked.
NEVER_PAIRS = (("base_link", "link_2"), ("link_1", "link_3"), ("link_2", "link_4"), ("link_2", "link_5"),
               ("link_2", "link_6"), ("link_3", "link_5"), ("link_3", "link_6"), ("link_4", "link_6"))
SRDF_SAMPLES = 2000  # random joint values per arm for the SRDF's "Always" pairs (seeded)
ALWAYS_FRACTION = 0.95  # a pair touching in at least this fraction of them is disabled, as MoveIt does
EFFORT_DEFAULT_NM = 1000.0  # placeholder where the data sheet gives none (marked in the header)
# read by singplan/kinematics/dynamics.py (same text there): estimated inertias are no basis for torques
NO_DYNAMICS_MARK = "singplan: no published dynamics"


def _rotation_z_to(v: np.ndarray) -> np.ndarray:
    """Rotation matrix that maps the z axis onto the unit vector along ``v``."""
    z = np.array([0.0, 0.0, 1.0])
    u = v / np.linalg.norm(v)
    axis = np.cross(z, u)
    s, c = float(np.linalg.norm(axis)), float(np.dot(z, u))
    if s < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    k = axis / s
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * kx + (1 - c) * kx @ kx


def _frame(rotation: np.ndarray, xyz: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = rotation
    T[:3, 3] = xyz
    return T


def _rpy_matrix(rpy_rad: list[float]) -> np.ndarray:
    r, p, y = rpy_rad
    rx = np.array([[1, 0, 0], [0, math.cos(r), -math.sin(r)], [0, math.sin(r), math.cos(r)]])
    ry = np.array([[math.cos(p), 0, math.sin(p)], [0, 1, 0], [-math.sin(p), 0, math.cos(p)]])
    rz = np.array([[math.cos(y), -math.sin(y), 0], [math.sin(y), math.cos(y), 0], [0, 0, 1]])
    return rz @ ry @ rx


def _link(index: int, axis: np.ndarray | None, to_next: np.ndarray, radius: float,
          flange: np.ndarray | None = None, plane_z: float | None = None) -> ud.Link:
    """A link drawn as a joint housing (along its axis) plus one cylinder per offset leg; the flange's
    link (``flange``: the direction the tool points in) has its housing behind the flange face, where
    the tool is mounted, not through it. ``plane_z``: the base's mounting plane in this link's frame
    (the base and link_1, whose heights no joint changes; None for the others): the housing stands on
    it where it would reach below, and no collision shape crosses it."""
    name = LINK_NAMES[index]
    material = ud.Material(name=f"{name}_colour", color=ud.Color(rgba=np.array([*COLOURS[index], 1.0])))
    cylinders: list[tuple[str, np.ndarray, float, float]] = []  # (name, origin, radius, length)
    if axis is not None:
        length = 3.0 * radius
        centre = np.zeros(3) if flange is None else -0.5 * length * flange
        housing = _frame(_rotation_z_to(axis), centre)
        if plane_z is not None:  # a housing centred on joint 1 at the plane would sink half into the floor
            housing[2, 3] += max(0.0, plane_z - _lowest_z(housing, 1.3 * radius, length))
        cylinders.append((f"{name}_housing", housing, 1.3 * radius, length))
    corner = np.zeros(3)
    legs = [np.array([0.0, 0.0, to_next[2]]), np.array([to_next[0], to_next[1], 0.0])]
    for k, leg in enumerate(legs):
        length = float(np.linalg.norm(leg))
        if length < 1e-6:
            continue
        cylinders.append((f"{name}_leg{k}", _frame(_rotation_z_to(leg), corner + leg / 2), radius, length))
        corner = corner + leg
    visuals = [ud.Visual(name=n, origin=origin, geometry=ud.Geometry(cylinder=ud.Cylinder(radius=r, length=length)),
                         material=material) for n, origin, r, length in cylinders]
    collisions = [_collision(n, origin, r, length, plane_z) for n, origin, r, length in cylinders]
    return ud.Link(name=name, inertial=_inertial(to_next, radius), visuals=visuals, collisions=collisions)


def _lowest_z(origin: np.ndarray, radius: float, length: float) -> float:
    """The lowest z a cylinder placed at ``origin`` (its axis the frame's z) reaches."""
    axis = origin[:3, 2]
    return float(origin[2, 3] - abs(axis[2]) * length / 2 - radius * math.hypot(axis[0], axis[1]))


def _collision(name: str, origin: np.ndarray, radius: float, length: float, plane_z: float | None) -> ud.Collision:
    """The collision cylinder of a visual one: :data:`COLLISION_MARGIN_M` wider and longer at each end,
    except below ``plane_z`` (the mounting plane in the link's frame; None: no plane to keep), where
    the margin of an upright cylinder ends at the plane.

    Raises:
        ValueError: a visual that itself reaches below the plane, or a tilted one whose margin would.
    """
    origin, r, half = origin.copy(), radius + COLLISION_MARGIN_M, length / 2 + COLLISION_MARGIN_M
    if plane_z is not None and _lowest_z(origin, r, 2 * half) < plane_z - 1e-12:
        upright = math.hypot(origin[0, 2], origin[1, 2]) < 1e-9
        if not upright or _lowest_z(origin, radius, length) < plane_z - 1e-12:
            raise ValueError(f"{name}: reaches below the base's mounting plane")
        top = origin[2, 3] + half
        origin[2, 3], half = (top + plane_z) / 2, (top - plane_z) / 2
    return ud.Collision(name=name, origin=origin, geometry=ud.Geometry(cylinder=ud.Cylinder(radius=r, length=2 * half)))


def _inertial(to_next: np.ndarray, radius: float) -> ud.Inertial:
    """Estimated inertia: a solid steel-ish cylinder (2700 kg/m^3 effective) along the link."""
    length = max(float(np.linalg.norm(to_next)), 2 * radius)
    mass = 2700.0 * math.pi * radius**2 * length
    ixx = iyy = mass * (3 * radius**2 + length**2) / 12.0
    izz = mass * radius**2 / 2.0
    centre = to_next / 2.0
    rotation = _rotation_z_to(to_next) if np.linalg.norm(to_next) > 1e-6 else np.eye(3)
    inertia = rotation @ np.diag([ixx, iyy, izz]) @ rotation.T
    return ud.Inertial(origin=_frame(np.eye(3), centre), mass=round(mass, 3), inertia=inertia)


def build_robot(name: str, spec: dict) -> ud.Robot:
    """The yourdfpy model of one bundled arm."""
    chain = spec["chain"]
    lower = [math.radians(lo) for lo, _ in spec["position_deg"]]
    upper = [math.radians(hi) for _, hi in spec["position_deg"]]
    velocity = [math.radians(v) for v in spec["velocity_deg_s"]]
    effort = spec.get("effort_Nm") or [EFFORT_DEFAULT_NM] * 6
    reach = sum(float(np.linalg.norm(j["xyz"])) for j in chain)
    radius = 0.045 * reach
    tool0 = spec["tool0"]
    offsets = [np.asarray(j["xyz"], dtype=float) for j in chain] + [np.asarray(tool0["xyz"], dtype=float)]
    if not np.allclose(np.abs(chain[0]["axis"]), [0, 0, 1]):
        raise ValueError(f"{name}: joint_1 must turn about the vertical (link_1 keeps its height above the plane)")
    links = [_link(0, None, offsets[0], radius * 1.4, plane_z=0.0)]
    joints = []
    tool_rotation = _rpy_matrix([math.radians(a) for a in tool0["rpy_deg"]])
    for i, j in enumerate(chain):
        axis = np.asarray(j["axis"], dtype=float)
        shrink = 1.0 if i < 3 else 0.6
        links.append(_link(i + 1, axis, offsets[i + 1], radius * shrink, tool_rotation[:, 2] if i == 5 else None,
                           plane_z=-float(offsets[0][2]) if i == 0 else None))
        joints.append(ud.Joint(name=f"joint_{i + 1}", type="revolute", parent=LINK_NAMES[i],
                               child=LINK_NAMES[i + 1], origin=_frame(np.eye(3), offsets[i]), axis=axis,
                               limit=ud.Limit(effort=float(effort[i]), velocity=velocity[i],
                                              lower=lower[i], upper=upper[i])))
    links.append(ud.Link(name="tool0"))
    joints.append(ud.Joint(name="joint_6-tool0", type="fixed", parent="link_6", child="tool0",
                           origin=_frame(tool_rotation, offsets[6])))
    return ud.Robot(name=name, links=links, joints=joints)


def urdf_text(name: str, spec: dict) -> str:
    """The URDF file content, with a header naming sources and estimates."""
    robot = ud.URDF(robot=build_robot(name, spec), build_scene_graph=False, load_meshes=False)
    # yourdfpy's write_xml_string drops keyword arguments, so pretty-print the tree here
    body = etree.tostring(robot.write_xml(), pretty_print=True, xml_declaration=True, encoding="utf-8").decode()
    header = ["<!-- Generated by robots/generate_urdfs.py from robots/urdf/robots.yaml; do not edit.",
              f"     {spec['display_name']}: kinematics and limits from public sources:"]
    header += [f"       {s}" for s in spec.get("sources", [])]
    header.append("     Masses and inertias are ESTIMATES (solid cylinders); visuals are simple cylinders,")
    header.append(f"     collision shapes the same cylinders {COLLISION_MARGIN_M * 1e3:g} mm larger all round,")
    header.append("     none below the base's mounting plane (z = 0 of base_link).")
    if not spec.get("effort_Nm"):
        header.append(f"     Effort limits are placeholders ({EFFORT_DEFAULT_NM:g} N m): no published figure. -->")
    else:
        header.append("     Effort limits from the data sheet. -->")
    header.insert(-1, f"     {NO_DYNAMICS_MARK}: masses and inertias are estimates; no torques are computed.")
    first_newline = body.index("\n") + 1 if body.startswith("<?xml") else 0
    return body[:first_newline] + "\n".join(header) + "\n" + body[first_newline:]


def srdf_text(name: str, urdf: str) -> str:
    """The SRDF of one bundled arm (its URDF's text given): the pairs never checked, with MoveIt's reasons."""
    reasons = disabled_pairs(urdf)
    lines = ["<?xml version='1.0' encoding='utf-8'?>",
             "<!-- Generated by robots/generate_urdfs.py from robots/urdf/robots.yaml; do not edit.",
             "     The link pairs singplan never checks for self-collision, with MoveIt's reasons: Adjacent (one",
             "     joint apart), Default (touching in the zero configuration), Always (touching in at least",
             f"     {ALWAYS_FRACTION:.0%} of {SRDF_SAMPLES} seeded random configurations), Never (never in contact in",
             "     the ros-industrial MoveIt configurations of this family, made from the real meshes; the fatter",
             "     stand-in cylinders touch in some legal configurations where the arms do not). -->",
             f'<robot name="{name}">']
    lines += [f'  <disable_collisions link1="{a}" link2="{b}" reason="{why}"/>' for (a, b), why in reasons.items()]
    return "\n".join([*lines, "</robot>", ""])


def disabled_pairs(urdf: str) -> dict[tuple[str, str], str]:
    """The link pairs of a URDF (its text) to disable, with the reason, in link order."""
    from singplan.kinematics.collision import collision_model  # only the SRDF needs singplan
    from singplan.kinematics.robot import load_robot
    from singplan.kinematics.shapes import CollisionSettings

    with tempfile.TemporaryDirectory() as folder:  # no SRDF beside it: every non-adjacent pair is checked
        path = Path(folder) / "arm.urdf"
        path.write_text(urdf)
        robot = load_robot(path)
        model = collision_model(robot, settings=CollisionSettings())  # every pair but the adjacent ones
        links = [b.name for b in model.bodies]
        checked = {frozenset(p.names) for p in model.pairs}
        reasons = {(a, b): "Adjacent" for i, a in enumerate(links) for b in links[i + 1:]
                   if frozenset((a, b)) not in checked}
        rng = np.random.default_rng(20250101)
        samples = np.vstack([np.clip(np.zeros(robot.n_joints), robot.lower_rad, robot.upper_rad),
                             rng.uniform(robot.lower_rad, robot.upper_rad, (SRDF_SAMPLES, robot.n_joints))])
        R, P = robot.joint_frames(samples)
        for pair in model.pairs:
            touching = np.array([model.pair_distance(pair, R[k], P[k]).distance_m <= 0.0 for k in range(len(samples))])
            if touching[0]:
                reasons[pair.names] = "Default"
            elif touching[1:].mean() >= ALWAYS_FRACTION:
                reasons[pair.names] = "Always"
            elif pair.names in NEVER_PAIRS:
                reasons[pair.names] = "Never"
    return dict(sorted(reasons.items(), key=lambda item: (links.index(item[0][0]), links.index(item[0][1]))))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="only report files that are out of date")
    args = parser.parse_args(argv)
    registry = yaml.safe_load((URDF_DIR / "robots.yaml").read_text())["robots"]
    stale = []
    for name, spec in registry.items():
        if spec.get("family") != "opw":
            continue
        path = URDF_DIR / spec["urdf"]
        text = urdf_text(name, spec)
        for target, content in ((path, text), (path.with_suffix(".srdf"), srdf_text(name, text))):
            if args.check:
                if not target.exists() or target.read_text() != content:
                    stale.append(target.name)
            else:
                target.write_text(content)
                sys.stdout.write(f"wrote {target}\n")
    if stale:
        sys.stdout.write("out of date: " + ", ".join(stale) + "\n")
    return 1 if stale else 0


if __name__ == "__main__":
    sys.exit(main())
