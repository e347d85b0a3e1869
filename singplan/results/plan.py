"""plan(task) -> Trajectory: the planning stages, then the trajectory record built and checked.

The moves are planned and timed in :mod:`singplan.planning.planner`; here they become one
:class:`Trajectory` (:mod:`singplan.results.build`), and its own samples pass the last gate:
no plan is returned whose output breaks a limit, whatever the cause.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np

from singplan.errors import JointLimitError, PlanningError
from singplan.kinematics.clearance import Clearance
from singplan.kinematics.collision import CollisionModel
from singplan.kinematics.robot import Robot
from singplan.planning.collide import check_trajectory
from singplan.planning.crossing.base import CrossingMethod
from singplan.planning.planner import PlannedTask, Progress, plan_moves
from singplan.planning.records import PlannedMove
from singplan.planning.timing import TimedMove, worst_sample
from singplan.results.build import build_trajectory
from singplan.results.trajectory import Trajectory
from singplan.task.schema import Task


def plan(task: Task | str | Path, method: str | CrossingMethod | None = None,
         progress: Progress | None = None) -> Trajectory:
    """Plan a task (a :class:`Task`, or the path of a YAML file) into a timed trajectory.

    ``method`` overrides the task's crossing method: a name (built in or registered with
    :func:`singplan.planning.crossing.registry.register`), or a method object used on every move.

    Raises:
        InputError: the task is malformed or contradicts the robot (exit code 2).
        PlanningError: the task cannot be executed within the limits and tolerances (exit code 3).
    """
    return trajectory_of(plan_moves(task, method, progress))


def trajectory_of(planned: PlannedTask) -> Trajectory:
    """The trajectory record of planned moves, checked against the limits and for collisions sample by sample."""
    moves, timed = list(planned.moves), list(planned.timed)
    traj = build_trajectory(planned.robot, planned.task, planned.method, moves, timed, planned.planning_s,
                            planned.held, planned.blends, _clearance(planned))
    _check_metrics(planned.full, planned.task, moves, timed, traj)
    return traj


def _clearance(planned: PlannedTask) -> tuple[CollisionModel, Clearance] | None:
    """The last collision gate over the stitched samples (raises CollisionError), with each move's
    closest approach; None when the task and robot have nothing to check or note."""
    model = planned.collision
    if not model.active and not model.notes and planned.task.collision is None:
        return None
    ends = np.cumsum([0] + [len(tm.q) - 1 for tm in planned.timed])
    q = np.concatenate([planned.timed[0].q] + [tm.q[1:] for tm in planned.timed[1:]])
    spans = [(int(a), int(b)) for a, b in itertools.pairwise(ends)]
    return model, check_trajectory(model, q, spans, [pm.kind for pm in planned.moves], planned.task.period_s)


_ROUND_OFF = 1e-9  # a metric ratio this far over 1 is round-off, more is a violated limit


def _check_metrics(robot: Robot, task: Task, planned: list[PlannedMove], timed: list[TimedMove],
                   traj: Trajectory) -> None:
    """The last gate: no plan is returned whose own samples break a limit or leave the path
    (whatever the cause)."""
    _check_positions(robot, planned, timed, traj)
    _check_path(task, planned, timed, traj)
    unlimited = () if task.limits.torque_scale is not None else ("max_torque_ratio",)  # reported, not a limit
    over = {k: v for k, v in traj.metrics.limit_ratios().items()  # `not <=`: a NaN ratio is a violation too
            if not v <= 1.0 + _ROUND_OFF and k not in unlimited}
    if not over:
        return
    vmax, amax = robot.velocity_rad_s * task.joint_speed_scale(), robot.acceleration_rad_s2
    torques = traj.metrics.torques
    if list(over) == ["max_torque_ratio"] and not isinstance(torques, str):
        k = round(torques.max_torque_at_s / traj.period)
    else:
        k = worst_sample(traj.q, traj.period, vmax, amax)
    m, k_move = _move_of_sample(timed, k)
    pm = planned[m]
    figures = ", ".join(f"{name} {value:.4f}" for name, value in over.items())
    raise PlanningError(f"move {m} ({pm.kind}): the planned samples break a limit ({figures}) near sample {k} "
                        f"(t = {k * traj.period:.4f} s) at {pm.describe(float(timed[m].u[k_move]))}")


def _check_positions(robot: Robot, planned: list[PlannedMove], timed: list[TimedMove], traj: Trajectory) -> None:
    """Every output sample inside the joint position limits."""
    outside = ~((traj.q >= robot.lower_rad - 1e-9) & (traj.q <= robot.upper_rad + 1e-9))  # NaN too
    if not outside.any():
        return
    k, j = (int(v) for v in np.argwhere(outside)[0])
    m, k_move = _move_of_sample(timed, k)
    pm = planned[m]
    raise JointLimitError(
        f"move {m} ({pm.kind}): sample {k} (t = {k * traj.period:.4f} s) puts {robot.joint_names[j]} at "
        f"{math.degrees(traj.q[k, j]):.3f} deg, outside its limits [{math.degrees(robot.lower_rad[j]):.1f}, "
        f"{math.degrees(robot.upper_rad[j]):.1f}] deg, at {pm.describe(float(timed[m].u[k_move]))}",
        joint=robot.joint_names[j], value_rad=float(traj.q[k, j]), lower_rad=float(robot.lower_rad[j]),
        upper_rad=float(robot.upper_rad[j]), move=m)


def _check_path(task: Task, planned: list[PlannedMove], timed: list[TimedMove], traj: Trajectory) -> None:
    """Every output sample within the task's position tolerance of its path (fly-by corners excepted)."""
    tol_mm = task.singularity.position_tolerance_mm
    if traj.metrics.max_position_error_mm <= tol_mm * (1.0 + 1e-6) + 1e-9:
        return
    k = int(np.argmax(traj.samples["position_error_m"]))
    m, k_move = _move_of_sample(timed, k)
    pm = planned[m]
    raise PlanningError(f"move {m} ({pm.kind}): sample {k} (t = {k * traj.period:.4f} s) is "
                        f"{traj.metrics.max_position_error_mm:.4f} mm from the path, over the tolerance {tol_mm:g} mm, "
                        f"at {pm.describe(float(timed[m].u[k_move]))}")


def _move_of_sample(timed: list[TimedMove], k: int) -> tuple[int, int]:
    """The move holding output sample k, and k's index within that move's samples."""
    ends = np.cumsum([len(tm.q) - 1 for tm in timed])
    m = min(int(np.searchsorted(ends, k)), len(timed) - 1)
    return m, k - (int(ends[m - 1]) if m > 0 else 0)
