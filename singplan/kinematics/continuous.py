"""Continuous joints: revolute joints without position limits, one angle each.

A URDF ``continuous`` joint turns without end (a wrist roll, a turntable, a wheel). Pinocchio models
it by two coordinates, (cos q, sin q), where singplan and every trajectory give one angle per joint.
singplan therefore reads a URDF's continuous joints as revolute joints whose limits are
``-/+UNLIMITED_LIMIT_RAD`` (:func:`as_revolute`: the XML is rewritten before Pinocchio builds the
model, keeping each joint's speed and effort limits), and reads any revolute joint whose limits
reach ``UNLIMITED_RAD`` both ways as unlimited too: :class:`~singplan.kinematics.robot.Robot` gives
such a joint the limits -inf and +inf (``Robot.unlimited``). The angle is then planned as any other:
no position limit, IK solutions taken at the whole turn nearest the joint's current value (the
shortest turn), paths followed with continuity, and the angle never wrapped, so every output and
export runs on past +-180 deg as the joint does.

Tools that read the trajectory with the URDF (the independent checker, a ROS controller) need one
coordinate per joint as well: :func:`portable_urdf` is the file saved beside such a trajectory
(``trajectory.urdf``), the URDF with its continuous joints written as those unlimited revolute joints
and its mesh files named by absolute path.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

from singplan.errors import RobotModelError
from singplan.kinematics.packages import resolve_uri

UNLIMITED_RAD = 1e6  # [rad] limits this far out both ways (160 000 turns) are no limits
UNLIMITED_LIMIT_RAD = 1e9  # [rad] what a continuous joint's limits are written as


def continuous_joint_names(urdf_text: str, where: str) -> list[str]:
    """The names of the URDF's continuous joints, in file order."""
    return [j.get("name", "") for j in _root(urdf_text, where).iter("joint") if j.get("type") == "continuous"]


def as_revolute(urdf_text: str, where: str) -> str:
    """The URDF with every continuous joint written as a revolute joint with limits
    -/+:data:`UNLIMITED_LIMIT_RAD`; its ``<limit>`` effort and velocity kept (0 when it gave none,
    so that a missing speed limit is refused by name like a revolute joint's)."""
    root = _root(urdf_text, where)
    for joint in root.iter("joint"):
        if joint.get("type") != "continuous":
            continue
        joint.set("type", "revolute")
        limit = joint.find("limit")
        if limit is None:
            limit = ET.SubElement(joint, "limit")
        limit.set("lower", repr(-UNLIMITED_LIMIT_RAD))
        limit.set("upper", repr(UNLIMITED_LIMIT_RAD))
        for key in ("effort", "velocity"):
            limit.set(key, limit.get(key, "0"))
    return ET.tostring(root, encoding="unicode")


def portable_urdf(urdf_text: str, urdf_path: Path) -> str:
    """:func:`as_revolute` of the URDF at ``urdf_path``, with every mesh file it can find
    (``package://``, ``file://`` or relative: :func:`~singplan.kinematics.packages.resolve_uri`) named by
    absolute path, so that the copy works from any folder."""
    root = ET.fromstring(as_revolute(urdf_text, str(urdf_path)))
    for mesh in root.iter("mesh"):
        found = resolve_uri(mesh.get("filename", ""), urdf_path)
        if found is not None:
            mesh.set("filename", str(found.resolve()))
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def _root(urdf_text: str, where: str) -> ET.Element:
    try:
        return ET.fromstring(urdf_text)
    except ET.ParseError as exc:
        raise RobotModelError(where, f"cannot be read as XML ({exc})") from None
