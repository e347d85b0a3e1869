"""plan(task) -> Trajectory: the planning stages, then the trajectory record built and checked.

The public name is :func:`singplan.plan` (:mod:`singplan.entry`). The moves are planned and
timed in :mod:`singplan.planning.orchestration.planner`; here they become one
:class:`Trajectory` (:mod:`singplan.results.build`), and its own samples pass the last gate:
no plan is returned whose output breaks a limit, whatever the cause.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path
from typing import NamedTuple, NoReturn

import numpy as np

from singplan.errors import JointLimitError, PlanningError
from singplan.kinematics.clearance import Clearance
from singplan.kinematics.collision import CollisionModel
from singplan.kinematics.robot import Robot
from singplan.planning.crossing.base import CrossingMethod
from singplan.planning.crossing.methods import EXACT_ORIENTATION_TOL_RAD
from singplan.planning.orchestration.checks import ROUND_OFF, TCP_ROUND_OFF
from singplan.planning.orchestration.collide import check_trajectory
from singplan.planning.orchestration.planner import PlannedTask, Progress, hand_over, plan_moves
from singplan.planning.orchestration.records import PlannedMove
from singplan.planning.path.zones import KIND_INDEX, KINDS, NEAR_SINGULAR
from singplan.planning.timing.ratios import worst_sample
from singplan.planning.timing.records import TimedMove
from singplan.results.build import MoveReports, build_trajectory
from singplan.results.trajectory import Trajectory
from singplan.task.schema import Task

_CHUNK = 65_536  # samples whose joint limits the final gate compares at once


def plan(task: Task | str | Path, method: str | CrossingMethod | None = None,
         progress: Progress | None = None) -> Trajectory:
    """Plan a task (a :class:`Task`, or the path of a YAML file) into a timed trajectory.

    ``method`` overrides the task's crossing method: a name (built in or registered with
    :func:`singplan.planning.crossing.registry.register`), or a method object used on every move.

    Raises:
        InputError: the task is malformed or contradicts the robot (exit code 2).
        PlanningError: the task cannot be executed within the limits and tolerances (exit code 3).
    """
    return planned_trajectory(task, method, progress).traj


class PlannedTrajectory(NamedTuple):
    """A task's trajectory and the robot it was planned on."""

    traj: Trajectory
    robot: Robot  # the task's robot with its tool (all joints of a 7-joint arm): what the pages draw


def planned_trajectory(task: Task | str | Path, method: str | CrossingMethod | None = None,
                       progress: Progress | None = None) -> PlannedTrajectory:
    """As :func:`plan`, with the robot the plan loaded (the pages are built on it, not loaded again)."""
    handover = [plan_moves(task, method, progress, MoveReports)]
    robot = handover[0].full
    return PlannedTrajectory(_record_of(handover), robot)


def trajectory_of(planned: PlannedTask) -> Trajectory:
    """The trajectory record of planned moves, checked against the limits and for collisions sample by sample."""
    return _record_of([planned])


def _record_of(handover: list[PlannedTask]) -> Trajectory:
    """:func:`trajectory_of` of the planned task taken out of ``handover``. Its moves' record parts
    were made as they were planned (:class:`MoveReports`, the planner's sink) or are made here, each
    move freed once its parts are (where nothing else holds it), so that a long program's peak
    memory is its record's, not the record's and every planned move's."""
    planned = handover.pop()
    if planned.sink is not None and not isinstance(planned.sink, MoveReports):
        raise TypeError(f"the moves went to a {type(planned.sink).__name__}, which keeps their record's parts: "
                        f"only a MoveReports sink (or none) gives a trajectory")
    moves, timed, reports = list(planned.moves), list(planned.timed), planned.sink
    collision = _clearance(planned)
    robot, full, task, method, q, planning_s, held, blends = (planned.robot, planned.full, planned.task,
                                                              planned.method, planned.q, planned.planning_s,
                                                              planned.held, planned.blends)
    del planned  # the moves are the lists' alone now
    if reports is None:
        reports = MoveReports(robot, task)
        hand_over(reports, moves, timed, blends)
    traj = build_trajectory(robot, task, method, reports, timed, q, planning_s, held, blends, collision)
    _check_metrics(full, task, moves, timed, traj)
    return traj


def _clearance(planned: PlannedTask) -> tuple[CollisionModel, Clearance] | None:
    """The last collision gate over the stitched samples (raises CollisionError), with each move's
    closest approach; None when the task and robot have nothing to check or note."""
    model = planned.collision
    if not model.active and not model.notes and planned.task.collision is None:
        return None
    ends = np.cumsum([0] + [len(tm.q) - 1 for tm in planned.timed])
    spans = [(int(a), int(b)) for a, b in itertools.pairwise(ends)]
    return model, check_trajectory(model, planned.q, spans, [pm.kind for pm in planned.moves], planned.task.period_s)


def _check_metrics(robot: Robot, task: Task, planned: list[PlannedMove], timed: list[TimedMove],
                   traj: Trajectory) -> None:
    """The last gate: no plan is returned whose own samples break a limit or leave the path
    (whatever the cause). It measures what an independent checker does on the output samples: joint
    positions, speeds, accelerations (jerk, torque when limited), the TCP speed against each move's
    programmed speed, the deviation from the path (the orientation kept outside crossings), each
    crossing near its singularity, and each move starting and ending at rest where it is not flown."""
    _check_positions(robot, planned, timed, traj)
    _check_path(task, planned, timed, traj)
    _check_tcp_speed(planned, timed, traj)
    _check_rest(robot, task, planned, timed, traj)
    _check_outside_crossings(planned, timed, traj)
    _check_crossings_near(robot, traj)
    unlimited: tuple[str, ...] = ("max_tcp_speed_ratio",)  # checked above, on its own round-off
    unlimited += () if task.limits.torque_scale is not None else ("max_torque_ratio",)  # reported, not a limit
    over = {k: v for k, v in traj.metrics.limit_ratios().items()  # `not <=`: a NaN ratio is a violation too
            if not v <= 1.0 + ROUND_OFF and k not in unlimited}
    if not over:
        return
    vmax, amax = robot.velocity_rad_s * task.joint_speed_scale(), task.limits.joint_accelerations(robot.n_joints)
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
    """Every output sample inside the joint position limits (a chunk of samples at a time: no whole-trajectory
    temporary)."""
    for c in range(0, len(traj.q), _CHUNK):
        rows = traj.q[c:c + _CHUNK]
        outside = ~((rows >= robot.lower_rad - 1e-9) & (rows <= robot.upper_rad + 1e-9))  # NaN too
        if outside.any():
            k, j = (int(v) for v in np.argwhere(outside)[0])
            _refuse_position(robot, planned, timed, traj, c + k, j)


def _refuse_position(robot: Robot, planned: list[PlannedMove], timed: list[TimedMove], traj: Trajectory,
                     k: int, j: int) -> NoReturn:
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


def _check_tcp_speed(planned: list[PlannedMove], timed: list[TimedMove], traj: Trajectory) -> None:
    """The TCP on the samples no faster than each move's programmed speed (a fly-by corner: the faster
    neighbour's), the chord between consecutive samples over the period, as a checker measures it."""
    ratio = traj.samples.get("tcp_speed_ratio")
    if ratio is None or len(ratio) == 0:
        return
    k = int(np.argmax(ratio))
    if ratio[k] <= 1.0 + TCP_ROUND_OFF:
        return
    m, k_move = _move_of_sample(timed, k)
    pm = planned[m]
    raise PlanningError(f"move {m} ({pm.kind}): the TCP runs at x{ratio[k]:.4f} its programmed speed "
                        f"({pm.limits.tcp_speed_m_s:g} m/s) between samples {k - 1} and {k} "
                        f"(t = {k * traj.period:.4f} s) at {pm.describe(float(timed[m].u[k_move]))}")


def _check_rest(robot: Robot, task: Task, planned: list[PlannedMove], timed: list[TimedMove],
                traj: Trajectory) -> None:
    """Each move starts and ends at rest where it is not flown: the steps next to its end samples no
    longer than one period's travel from rest at the acceleration limit (amax * period^2)."""
    flown = {b.move for b in traj.metrics.blends if b.flown}
    ends = np.cumsum([0] + [len(tm.q) - 1 for tm in timed])  # each move's first sample; the last sample
    rest_step = task.limits.joint_accelerations(robot.n_joints) * traj.period ** 2 * (1.0 + ROUND_OFF) + 1e-12
    for m, k in enumerate(ends.tolist()):
        if m > 0 and (m - 1) in flown:
            continue  # a corner flown into move m: its first sample is under way
        steps = [np.abs(traj.q[k + d] - traj.q[k + d - 1]) for d in (0, 1) if 0 < k + d < len(traj.q)]
        if any(np.any(step > rest_step) for step in steps):
            i = min(m, len(planned) - 1)
            side = "starts" if m < len(planned) else "ends"
            raise PlanningError(f"move {i} ({planned[i].kind}) {side} at sample {k} (t = {k * traj.period:.4f} s) "
                                f"without being at rest")


def _check_outside_crossings(planned: list[PlannedMove], timed: list[TimedMove], traj: Trajectory) -> None:
    """Outside the segments marked crossing (and fly-by corners, PTP moves) the orientation is kept
    to 0.01 deg: only a crossing may trade orientation for the singularity. Measured a stretch of
    kept samples at a time (no whole-trajectory mask)."""
    ori = traj.samples.get("orientation_error_rad")
    if ori is None:
        return
    tol_rad = EXACT_ORIENTATION_TOL_RAD * (1.0 + 1e-6)
    over = np.zeros(0, dtype=np.int64)  # the kept samples over it, in order (`not <=`: NaN too)
    for a, b in _kept_stretches(traj, len(ori)):
        over = np.concatenate([over, a + np.flatnonzero(~(ori[a:b] <= tol_rad))])
    if over.size:
        k = int(over[np.argmax(ori[over])])
        m, k_move = _move_of_sample(timed, k)
        pm = planned[m]
        raise PlanningError(f"move {m} ({pm.kind}): sample {k} (t = {k * traj.period:.4f} s) turns the tool "
                            f"{math.degrees(ori[k]):.4f} deg from the path outside any crossing (at most 0.01 deg), "
                            f"at {pm.describe(float(timed[m].u[k_move]))}")


def _kept_stretches(traj: Trajectory, count: int) -> list[tuple[int, int]]:
    """The sample ranges [a, b) of ``count`` samples outside every crossing, fly-by corner and PTP segment."""
    taken = sorted((round(seg.t0 / traj.period), round(seg.t1 / traj.period) + 1) for seg in traj.segments
                   if seg.kind in ("crossing", "blend", "ptp"))
    out, cursor = [], 0
    for a, b in taken:
        if a > cursor:
            out.append((cursor, min(a, count)))
        cursor = max(cursor, b)
    if cursor < count:
        out.append((cursor, count))
    return out


def _check_crossings_near(robot: Robot, traj: Trajectory) -> None:
    """Every segment marked crossing passes near its singularity: a sample in it within
    :data:`~singplan.planning.path.zones.NEAR_SINGULAR` (a six-joint arm's wrist, shoulder or elbow)."""
    distances = traj.samples.get("distances")
    if distances is None or robot.n_joints != 6:
        return
    near = np.array([NEAR_SINGULAR[kind] for kind in KINDS])
    for seg in traj.segments:
        if seg.kind != "crossing" or seg.singularity is None:
            continue
        i = KIND_INDEX[seg.singularity]
        d = np.abs(distances[round(seg.t0 / traj.period):round(seg.t1 / traj.period) + 1, i])
        if not np.any(d < near[i]):
            raise PlanningError(f"move {seg.move}: the segment marked as a {seg.singularity} crossing at "
                                f"t = {seg.t0:.4f} .. {seg.t1:.4f} s comes no nearer the singularity than "
                                f"{_distance_text(seg.singularity, float(d.min(initial=math.inf)))}")


def _distance_text(kind: str, value: float) -> str:
    return f"{value * 1e3:.1f} mm" if kind == "shoulder" else f"{math.degrees(value):.2f} deg"


def _move_of_sample(timed: list[TimedMove], k: int) -> tuple[int, int]:
    """The move holding output sample k, and k's index within that move's samples."""
    ends = np.cumsum([len(tm.q) - 1 for tm in timed])
    m = min(int(np.searchsorted(ends, k)), len(timed) - 1)
    return m, k - (int(ends[m - 1]) if m > 0 else 0)
