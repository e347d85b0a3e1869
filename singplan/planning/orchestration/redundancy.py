"""7-joint arms with a held redundant joint (SEEDS 003, the task's ``redundancy`` key).

The held joint's 6R chain is :func:`singplan.kinematics.held.hold_joint`'s; here the task holds it
for every move: its start and PTP joint values are checked to hold it, and :func:`reduce_task` gives
the task as the chain sees it (joint values and per-joint limits without the held joint's: the
acceleration limit's one home is the task, so this is its only reduction).

Without ``redundancy`` a 7-joint arm is planned as it is: the tracker solves each path sample
from the previous one by damped Newton steps, each the minimum-norm joint change
(``J^T (J J^T + lambda I)^-1 e``), which is the minimum-norm joint velocity
``q_dot = J^+ x_dot`` integrated along the path with a correction back onto it.
"""

from __future__ import annotations

import math
from dataclasses import replace

from singplan.errors import TaskError
from singplan.kinematics.held import HOLD_TOL_RAD, HeldJoint, hold_joint
from singplan.kinematics.robot import Robot
from singplan.task.schema import Redundancy, Task


def reduce_task(held: HeldJoint, task: Task) -> Task:
    """The task as the 6R chain sees it: joint values and per-joint limits without the held joint."""
    jerk = task.limits.jerk_rad_s3
    limits = replace(task.limits, acceleration_rad_s2=held.reduce_values(task.limits.acceleration_rad_s2),
                     jerk_rad_s3=held.reduce_values(jerk) if jerk is not None else None)
    moves = tuple(replace(m, to_joints_deg=held.reduce_values(m.to_joints_deg))
                  if m.to_joints_deg is not None else m for m in task.moves)
    start = held.reduce_values(task.start_joints_deg) if task.start_joints_deg is not None else None
    return replace(task, start_joints_deg=start, moves=moves, limits=limits, redundancy=None)


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
