"""7-joint arms with a held redundant joint (SEEDS 003, the task's ``redundancy`` key).

Holding one joint of a 7R arm at a fixed value leaves a 6R chain. :func:`hold_joint` builds
that chain as a robot of its own (``pinocchio.buildReducedModel``: the held joint's body is
merged into its parent at the value, inertias included), so it takes the same road as any
6-joint URDF: family recognition, all-branch IK, singular zones, crossing methods, timing.
:class:`HeldJoint` maps joint values and tasks between the two and puts the held joint back
as a constant column when the trajectory is built, so every output names all seven joints.

Without ``redundancy`` a 7-joint arm is planned as it is: the tracker solves each path sample
from the previous one by damped Newton steps, each the minimum-norm joint change
(``J^T (J J^T + lambda I)^-1 e``), which is the minimum-norm joint velocity
``q_dot = J^+ x_dot`` integrated along the path with a correction back onto it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import pinocchio as pin

from singplan.errors import TaskError
from singplan.kinematics.robot import Robot
from singplan.task.schema import Redundancy, Task

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

    def reduce_task(self, task: Task) -> Task:
        """The task as the 6R chain sees it: joint values and per-joint limits without the held joint."""
        jerk = task.limits.jerk_rad_s3
        limits = replace(task.limits, acceleration_rad_s2=_without(task.limits.acceleration_rad_s2, self.index),
                         jerk_rad_s3=_without(jerk, self.index) if jerk is not None else None)
        moves = tuple(replace(m, to_joints_deg=_without(m.to_joints_deg, self.index))
                      if m.to_joints_deg is not None else m for m in task.moves)
        start = _without(task.start_joints_deg, self.index) if task.start_joints_deg is not None else None
        return replace(task, start_joints_deg=start, moves=moves, limits=limits, redundancy=None)


def _without(values: tuple[float, ...], index: int) -> tuple[float, ...]:
    """Per-joint values of the 7-joint arm without joint ``index``'s; one value (a limit every
    joint shares) is the 6R chain's as it is."""
    return values if len(values) == 1 else values[:index] + values[index + 1:]


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
    acceleration_rad_s2 = np.array(_without(tuple(robot.acceleration_rad_s2.tolist()), index))
    reduced = Robot(robot.name, robot.urdf_path, model, robot.tip, robot.T_tip_tcp, robot.entry, acceleration_rad_s2)
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


def hold_for_task(task: Task, robot: Robot) -> HeldJoint | None:
    """The task's held joint on ``robot`` (None without ``redundancy``), its joint values checked.

    Raises:
        TaskError: as :func:`hold_joint`, or a start or PTP joint value that does not hold the joint.
    """
    red = task.redundancy
    if red is None:
        return None
    held = hold_joint(robot, red.joint, math.radians(red.value_deg))
    if task.start_joints_deg is not None:
        _check_holds(held, red, "start.joints_deg", task.start_joints_deg)
    for i, move in enumerate(task.moves):
        if move.to_joints_deg is not None:
            _check_holds(held, red, f"moves[{i}].{move.kind}.to.joints_deg", move.to_joints_deg)
    return held


def _check_holds(held: HeldJoint, red: Redundancy, where: str, values_deg: tuple[float, ...]) -> None:
    value = values_deg[held.index]
    if abs(math.radians(value) - held.value_rad) > HOLD_TOL_RAD:
        raise TaskError(f"{where}[{held.index}]", f"{held.joint} = {value:g} deg, but redundancy holds it at "
                                                  f"{red.value_deg:g} deg for the whole task")
