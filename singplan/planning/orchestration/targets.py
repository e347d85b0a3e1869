"""What a task asks of its robot: the robot with the task's tool and limits, the start joints and
each PTP's target joints (IK, in the requested configuration), and each move's timing limits."""


from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from singplan.errors import TaskError, UnknownNameError, UnreachableError
from singplan.kinematics.collision import CollisionModel, collision_model
from singplan.kinematics.configuration import classify
from singplan.kinematics.dynamics import TorqueLimit, effort_limits_nm, require_dynamics
from singplan.kinematics.geometry import rpy_deg_to_rotation
from singplan.kinematics.held import HeldJoint
from singplan.kinematics.ik.solve import solve_all
from singplan.kinematics.robot import Robot, load_robot
from singplan.kinematics.vendor_config import convention_for
from singplan.planning.orchestration.redundancy import hold_for_task, reduce_task
from singplan.planning.path.cartesian import move_target
from singplan.planning.timing.records import MoveLimits
from singplan.task.load import check_against_robot
from singplan.task.schema import Move, Task


def load_task_robot(task: Task) -> Robot:
    """The task's robot: its URDF with the task's tip and tool, checked against the task (with
    dynamics, when the task limits torques)."""
    tool = pin.SE3(rpy_deg_to_rotation(task.tool_rpy_deg), np.asarray(task.tool_xyz, dtype=float))
    try:
        robot = load_robot(task.robot, tip=task.tip, tool=tool)
    except UnknownNameError as exc:
        if exc.what != "robot":
            raise TaskError("tip", str(exc)) from None
        raise UnknownNameError("robot", exc.name, exc.choices, where="robot") from None
    check_against_robot(task, robot)
    convention_for(robot)  # a URDF's controller sidecar is read (or refused) before planning, not after it
    if task.limits.torque_scale is not None:
        require_dynamics(robot)
    return robot


@dataclass(frozen=True)
class TaskArm:
    """The arm a task is planned on.

    Attributes:
        full: the task's robot.
        held: with ``redundancy`` (7 joints), the held joint; None otherwise.
        robot: the chain planned: ``full``, or the 6R chain with the held joint locked.
        task: the task as that chain sees it (the held joint's values dropped).
        q_start: the start joints of ``robot`` [rad].
        collision: ``robot``'s bodies in the task's cell and the pairs checked (none checked: nothing to check).
    """

    full: Robot
    held: HeldJoint | None
    robot: Robot
    task: Task
    q_start: np.ndarray  # (n,)
    collision: CollisionModel


def task_arm(task: Task) -> TaskArm:
    """The robot, the chain planned and the start joints of a task (the setup planning and detection share)."""
    full = load_task_robot(task)
    held = hold_for_task(task, full)  # with `redundancy`, the 6R chain is planned like any 6-joint arm
    robot, arm_task = (held.reduced, reduce_task(held, task)) if held is not None else (full, task)
    q_start = start_joints(arm_task, robot)
    collision = collision_model(robot, task.tool_geometry, task.cell, task.collision, q_start)
    return TaskArm(full, held, robot, arm_task, q_start, collision)


def start_joints(task: Task, robot: Robot) -> np.ndarray:
    """The start joints [rad]: as given, or the IK solution of the start pose (in its configuration)
    nearest zero."""
    if task.start_joints_deg is not None:
        return np.radians(np.asarray(task.start_joints_deg, dtype=float))
    assert task.start_pose is not None
    pose = task.start_pose
    T = pin.SE3(rpy_deg_to_rotation(pose.rpy_deg or (0.0, 0.0, 0.0)), np.asarray(pose.xyz, dtype=float))
    sols = solve_all(robot, T, seed=np.zeros(robot.n_joints))
    keep = [k for k, label in enumerate(sols.labels) if task.start_config in (None, label)]
    if not keep:
        wanted = f" in configuration {task.start_config}" if task.start_config else ""
        raise UnreachableError(f"start.pose: no IK solution{wanted} inside the joint limits "
                               f"(xyz {list(pose.xyz)}); available: {sorted(set(sols.labels)) or 'none'}")
    best = min(keep, key=lambda k: float(np.max(np.abs(sols.q[k]))))  # the solution nearest zero
    return np.array(sols.q[best])


def ptp_target(robot: Robot, i: int, move: Move, q_start: np.ndarray) -> np.ndarray:
    """A PTP's target joints [rad]: as given, or the IK solution of its pose in the requested
    configuration nearest the start."""
    return ptp_targets(robot, i, move, q_start)[0]


def ptp_targets(robot: Robot, i: int, move: Move, q_start: np.ndarray) -> list[np.ndarray]:
    """A PTP's possible target joints [rad], the preferred first: as given (one), or every IK solution
    of its pose in the requested configuration, nearest the start first (the largest joint change
    least); ``config: auto`` takes another only where the nearest's motion collides."""
    if move.to_joints_deg is not None:
        return [np.radians(np.asarray(move.to_joints_deg, dtype=float))]
    target = move_target(move, robot.fk(q_start))
    sols = solve_all(robot, target, seed=q_start)
    keep = [k for k, label in enumerate(sols.labels) if move.config in ("auto", "keep", label)]
    if move.config == "keep":
        keep = [k for k in keep if sols.labels[k] == classify(robot, q_start).label]
    if not keep:
        far = robot.beyond_reach(target.translation)
        raise UnreachableError(f"move {i} (ptp): no IK solution for xyz {target.translation.tolist()} inside the joint "
                               f"limits in the requested configuration ({move.config}); available: "
                               f"{sorted(set(sols.labels)) or 'none'}" + (f"; {far}" if far else ""), move=i)
    keep.sort(key=lambda k: float(np.max(np.abs(sols.q[k] - q_start))))  # stable: ties keep the solver's order
    return [np.array(sols.q[k]) for k in keep]


def move_limits(robot: Robot, task: Task, move: Move, length_m: float) -> MoveLimits:
    """The limits one move is timed under (a PTP's velocity_scale, a LIN / CIRC's TCP speed)."""
    scale = task.joint_speed_scale(move)
    torque = (TorqueLimit(robot, effort_limits_nm(robot) * task.limits.torque_scale)
              if task.limits.torque_scale is not None else None)
    jerk = (np.broadcast_to(np.asarray(task.limits.jerk_rad_s3, dtype=float), (robot.n_joints,)).copy()
            if task.limits.jerk_rad_s3 is not None else None)
    return MoveLimits(robot.velocity_rad_s * scale, task.limits.joint_accelerations(robot.n_joints), length_m,
                      move.speed_m_s if move.kind != "ptp" else None, torque, jerk,
                      quintic=move.kind == "ptp" and task.limits.ptp_time_law == "quintic")
