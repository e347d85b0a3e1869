"""``detect(task)``: the singular zones along every LIN / CIRC move, geometry only (``singplan check``)."""


from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from singplan.kinematics.stopping import path_estimate, ptp_estimate
from singplan.planning.budget import check_task
from singplan.planning.checks import check_tracked
from singplan.planning.jointmap import JointMap, JointPart
from singplan.planning.move_plan import refiner
from singplan.planning.path import STEP_M, STEP_RAD
from singplan.planning.pieces import move_piece
from singplan.planning.targets import ptp_target, task_arm
from singplan.planning.tracking import track
from singplan.planning.zones import Zone, distances_along, find_zones
from singplan.task.load import load_task
from singplan.task.schema import Task


@dataclass(frozen=True)
class MoveZones:
    """Singular zones of one move along the programmed path (``singplan check``)."""

    index: int
    kind: str
    length_m: float
    zones: tuple[Zone, ...]
    stopping: tuple[float, float] = (0.0, 0.0)  # an estimate at the programmed speed [m], and the u where


def detect(task: Task | str | Path) -> list[MoveZones]:
    """Zones along every LIN/CIRC move, in the branch the start configuration leads to.

    Geometry only: no crossing method, no timing, no limit checks; each move's stopping distance is
    an estimate at the programmed speed (:func:`singplan.kinematics.stopping.path_estimate`, ``ptp_estimate``).
    """
    if not isinstance(task, Task):
        task = load_task(task)
    arm = task_arm(task)
    robot, task, q = arm.robot, arm.task, arm.q_start
    thresholds = task.singularity.zone.si()
    check_task(task, robot, q, STEP_M, STEP_RAD, timed=False)  # before any path is sampled
    T = robot.fk(q)
    out = []
    for i, move in enumerate(task.moves):
        if move.kind == "ptp":
            q_from, q = q, ptp_target(robot, i, move, q)
            T = robot.fk(q)
            vmax = robot.velocity_rad_s * task.joint_speed_scale(move)
            out.append(MoveZones(i, "ptp", 0.0, (), ptp_estimate(robot, q_from, q, vmax)))
            continue
        piece = move_piece(i, move, T)
        grid = piece.grid(STEP_M, STEP_RAD)
        tracked = track(robot, piece.poses, grid, q)
        check_tracked(robot, i, move, piece, tracked)
        dist, _ = distances_along(robot, tracked.q)
        ref = JointMap(robot, piece.poses, [JointPart("track", tracked.u, tracked.q)])
        zones = find_zones(tracked.u, dist, thresholds, refiner(robot, ref))
        out.append(MoveZones(i, move.kind, piece.length_m, tuple(zones),
                             path_estimate(robot, tracked.u, tracked.q, piece.length_m, move.speed_m_s,
                                           robot.velocity_rad_s * task.joint_speed_scale(move))))
        q, T = tracked.q[-1], piece.T_end
    return out
