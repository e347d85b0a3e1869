"""Write robots/urdf/<name>.urdf for every bundled OPW arm of robots/urdf/robots.yaml.

The kinematics (joint origins, axes, the link_6 -> tool0 transform) and the limits are the
published numbers of the registry, written with full precision. Visual geometry is simple
cylinders sized from the link offsets; masses and inertias are *estimates* (solid cylinders
of steel-like density scaled to the link length), good enough for a viewer, not for torques.
Each file's header says so in a line singplan reads (:data:`NO_DYNAMICS_MARK`): these arms have
no published dynamics, so singplan reports no torques for them and refuses ``limits.torque_scale``.

    python robots/generate_urdfs.py            # rewrite all URDFs
    python robots/generate_urdfs.py --check    # exit 1 if a URDF on disk is out of date
"""

from __future__ import annotations

import argparse
import math
import sys
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


def _link(index: int, axis: np.ndarray | None, to_next: np.ndarray, radius: float) -> ud.Link:
    """A link drawn as a joint housing (along its axis) plus one cylinder per offset leg."""
    name = LINK_NAMES[index]
    material = ud.Material(name=f"{name}_colour", color=ud.Color(rgba=np.array([*COLOURS[index], 1.0])))
    visuals = []
    if axis is not None:
        visuals.append(ud.Visual(name=f"{name}_housing", origin=_frame(_rotation_z_to(axis), np.zeros(3)),
                                 geometry=ud.Geometry(cylinder=ud.Cylinder(radius=1.3 * radius, length=3.0 * radius)),
                                 material=material))
    corner = np.zeros(3)
    legs = [np.array([0.0, 0.0, to_next[2]]), np.array([to_next[0], to_next[1], 0.0])]
    for k, leg in enumerate(legs):
        length = float(np.linalg.norm(leg))
        if length < 1e-6:
            continue
        visuals.append(ud.Visual(name=f"{name}_leg{k}", origin=_frame(_rotation_z_to(leg), corner + leg / 2),
                                 geometry=ud.Geometry(cylinder=ud.Cylinder(radius=radius, length=length)),
                                 material=material))
        corner = corner + leg
    return ud.Link(name=name, inertial=_inertial(to_next, radius), visuals=visuals)


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
    links = [_link(0, None, offsets[0], radius * 1.4)]
    joints = []
    for i, j in enumerate(chain):
        axis = np.asarray(j["axis"], dtype=float)
        shrink = 1.0 if i < 3 else 0.6
        links.append(_link(i + 1, axis, offsets[i + 1], radius * shrink))
        joints.append(ud.Joint(name=f"joint_{i + 1}", type="revolute", parent=LINK_NAMES[i],
                               child=LINK_NAMES[i + 1], origin=_frame(np.eye(3), offsets[i]), axis=axis,
                               limit=ud.Limit(effort=float(effort[i]), velocity=velocity[i],
                                              lower=lower[i], upper=upper[i])))
    links.append(ud.Link(name="tool0"))
    tool_rotation = _rpy_matrix([math.radians(a) for a in tool0["rpy_deg"]])
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
    header.append("     Masses and inertias are ESTIMATES (solid cylinders); visuals are simple cylinders.")
    if not spec.get("effort_Nm"):
        header.append(f"     Effort limits are placeholders ({EFFORT_DEFAULT_NM:g} N m): no published figure. -->")
    else:
        header.append("     Effort limits from the data sheet. -->")
    header.insert(-1, f"     {NO_DYNAMICS_MARK}: masses and inertias are estimates; no torques are computed.")
    first_newline = body.index("\n") + 1 if body.startswith("<?xml") else 0
    return body[:first_newline] + "\n".join(header) + "\n" + body[first_newline:]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="only report URDFs that are out of date")
    args = parser.parse_args(argv)
    registry = yaml.safe_load((URDF_DIR / "robots.yaml").read_text())["robots"]
    stale = []
    for name, spec in registry.items():
        if spec.get("family") != "opw":
            continue
        path = URDF_DIR / spec["urdf"]
        text = urdf_text(name, spec)
        if args.check:
            if not path.exists() or path.read_text() != text:
                stale.append(path.name)
        else:
            path.write_text(text)
            sys.stdout.write(f"wrote {path}\n")
    if stale:
        sys.stdout.write("out of date: " + ", ".join(stale) + "\n")
    return 1 if stale else 0


if __name__ == "__main__":
    sys.exit(main())
