"""A 7-joint arm with one joint held at a fixed value (SEEDS 003): the 6R chain that is left.

Holding one joint of a 7R arm leaves a 6R chain. :func:`hold_joint` builds that chain as a robot
of its own (``pinocchio.buildReducedModel``: the held joint's body is merged into its parent at the
value, inertias included), so it takes the same road as any 6-joint URDF: family recognition,
all-branch IK, singular zones, crossing methods, timing. :class:`HeldJoint` maps joint values
between the two and puts the held joint back as a constant column when the trajectory is built, so
every output names all seven joints. A task's ``redundancy`` key holds a joint for the whole task
(:mod:`singplan.planning.orchestration.redundancy`); ``singplan ik --hold`` holds one for a pose.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from singplan.errors import TaskError
from singplan.kinematics.robot import Robot

REDUNDANT_JOINTS = 7  # arms that take a `redundancy` key
HOLD_TOL_RAD = 1e-9  # a start or PTP joint value this close to the held value holds it


@dataclass(frozen=True)
class HeldJoint:
    """A 7-joint arm with one joint held, and its 6R chain.

    Attributes:
        full: the 7-joint arm (outputs, torques, replay).
        reduced: the 6R chain the planner works on (the held joint locked at ``value_rad``).
        index: the held joint's position among ``full.joint_names``.
        value_rad: where it is held.
    """

    full: Robot
    reduced: Robot
    index: int
    value_rad: float

    @property
    def joint(self) -> str:
        return self.full.joint_names[self.index]

    def expand(self, q: np.ndarray) -> np.ndarray:
        """Joint values of the 6R chain (..., 6) with the held joint put back (..., 7)."""
        q = np.asarray(q, dtype=float)
        return np.insert(q, self.index, self.value_rad, axis=-1)

    def reduce(self, q: np.ndarray) -> np.ndarray:
        """Joint values of the 7-joint arm (..., 7) without the held joint (..., 6)."""
        return np.delete(np.asarray(q, dtype=float), self.index, axis=-1)

    def reduce_values(self, values: tuple[float, ...]) -> tuple[float, ...]:
        """Per-joint values of the 7-joint arm without the held joint's; one value (shared by every
        joint, e.g. a limit) is the 6R chain's as it is."""
        return values if len(values) == 1 else values[:self.index] + values[self.index + 1:]


def hold_joint(robot: Robot, joint: str, value_rad: float, field: str = "redundancy") -> HeldJoint:
    """Lock ``joint`` of a 7-joint ``robot`` at ``value_rad``; the robot itself is left as it is.

    Raises:
        TaskError: the robot has no 7 joints, the joint is unknown, or the value is outside its
            limits (named as ``field``, ``field.joint``, ``field.value_deg``).
    """
    _check_redundancy(robot, joint, value_rad, field)
    index = robot.joint_names.index(joint)
    q_lock = pin.neutral(robot.model)
    q_lock[index] = value_rad
    model = pin.buildReducedModel(robot.model, [robot.model.getJointId(joint)], q_lock)
    reduced = Robot(robot.name, robot.urdf_path, model, robot.tip, robot.T_tip_tcp, robot.entry)
    return HeldJoint(robot, reduced, index, value_rad)


def _check_redundancy(robot: Robot, joint: str, value_rad: float, field: str = "redundancy") -> None:
    """A 7-joint arm, a joint of it, and a value inside that joint's limits."""
    if robot.n_joints != REDUNDANT_JOINTS:
        raise TaskError(field, f"only for {REDUNDANT_JOINTS}-joint arms; {robot.name} has {robot.n_joints} joints")
    if joint not in robot.joint_names:
        raise TaskError(f"{field}.joint", f"{robot.name} has no joint {joint!r}; valid: "
                                          f"{', '.join(robot.joint_names)}")
    j = robot.joint_names.index(joint)
    lo, hi = float(robot.lower_rad[j]), float(robot.upper_rad[j])
    if not lo - HOLD_TOL_RAD <= value_rad <= hi + HOLD_TOL_RAD:
        raise TaskError(f"{field}.value_deg", f"{joint} = {math.degrees(value_rad):g} deg is outside its limits "
                                              f"[{math.degrees(lo):g}, {math.degrees(hi):g}] deg")
