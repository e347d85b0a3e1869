"""The planner's validators: a move's tracked path, joint limits, configuration and tolerances.
Each failure is the exit-3 error naming the move, the point and the reason."""


from __future__ import annotations

import math

import numpy as np

from singplan.errors import JointLimitError, PlanningError, SingularityError, UnreachableError
from singplan.kinematics.configuration import distances_batch, labels_from_distances, parse_configuration
from singplan.kinematics.robot import Robot
from singplan.planning.path import CartesianPiece, sample_deviations
from singplan.planning.records import PlannedMove, SampleDeviations
from singplan.planning.timing import TimedMove
from singplan.planning.tracking import TrackedPath
from singplan.planning.zones import Zone
from singplan.task.schema import Move, Task


def check_tolerances(robot: Robot, task: Task, pm: PlannedMove, tm: TimedMove,
                     crossings_checked: bool = False) -> SampleDeviations | None:
    """A crossing may deviate up to the task's tolerances; more is no plan (exit 3).

    Checked on the samples, and on each crossing's own joints (:func:`crossing_deviation`; not
    again where ``crossings_checked``). Returns the samples' deviations (None for a PTP move), for
    the trajectory record to reuse.
    """
    if pm.piece is None:
        return None
    pos, ori = sample_deviations(robot, pm.piece, tm.u, tm.q)
    error = _over_tolerance(task, pm, tm.u, pos, ori)
    if error is None and not crossings_checked:
        error = crossing_deviation(robot, task, pm)
    if error is not None:
        raise error
    return SampleDeviations(tm.u, tm.q, pos, ori)


def crossing_deviation(robot: Robot, task: Task, pm: PlannedMove) -> SingularityError | None:
    """The tolerance error of a crossing's own joints (its reference samples, through which its
    joint map passes), if any: a motion that leaves the tolerance band there leaves it whether or
    not an output sample lands on that point."""
    parts = [part for crossing in pm.crossings for part in crossing.parts]
    if pm.piece is None or not parts:
        return None
    u = np.concatenate([part.u for part in parts])
    pos, ori = sample_deviations(robot, pm.piece, u, np.concatenate([part.q for part in parts]))
    return _over_tolerance(task, pm, u, pos, ori)


def refusal(robot: Robot, task: Task, move: Move, pm: PlannedMove) -> PlanningError | None:
    """Why no timing of the move can be kept, told before timing; None when only the samples can tell.

    The configuration its joint map ends in (the first and last samples of any timing are its
    ends), or a crossing's own joints over the tolerances (:func:`crossing_deviation`, which
    :func:`check_tolerances` applies to every timed move too).
    """
    u = np.array([0.0, 1.0])
    try:
        check_config(robot, move, pm, u, pm.jmap.evaluate(u))
    except PlanningError as exc:
        return exc
    return crossing_deviation(robot, task, pm)


def _over_tolerance(task: Task, pm: PlannedMove, u: np.ndarray, pos: np.ndarray,
                    ori: np.ndarray) -> SingularityError | None:
    """The error naming the point furthest over the tolerances, if any is (errors (K,) [m] [rad] at u (K,))."""
    assert pm.piece is not None
    pos_tol = task.singularity.position_tolerance_mm / 1e3
    ori_tol = math.radians(task.singularity.orientation_tolerance_deg)
    if pos.max(initial=0.0) <= pos_tol and ori.max(initial=0.0) <= ori_tol:
        return None
    k = int(np.argmax(np.maximum(pos / pos_tol, ori / ori_tol)))
    zone = min(pm.zones, key=lambda z: abs(z.u_closest - u[k])) if pm.zones else None
    where = f"in the {zone.kind} zone " if zone else ""
    return SingularityError(
        f"move {pm.index} ({pm.kind}): the crossing {where}deviates {pos[k] * 1e3:.4f} mm / "
        f"{math.degrees(ori[k]):.4f} deg at {pm.piece.describe(float(u[k]))}, over the tolerance "
        f"{task.singularity.position_tolerance_mm:g} mm / {task.singularity.orientation_tolerance_deg:g} deg",
        move=pm.index, kind=zone.kind if zone else "path", s_m=float(u[k]) * pm.piece.length_m)


def check_tracked(robot: Robot, i: int, move: Move, piece: CartesianPiece, tracked: TrackedPath) -> None:
    if tracked.gap_index < 0:
        return
    k = tracked.gap_index + 1
    u = float(tracked.u[k])
    if not np.all(np.isfinite(tracked.q[k])):
        what = ("no joint values give that position with the path's tool z axis (five joints keep both only "
                "where the axis is within the arm's reach; the z axis turns with the slerp from the start's "
                "orientation to the target's, so a target rotated about its z axis against the start turns it "
                "too: give the target the start's rotation about z)" if robot.n_joints == 5 else
                "no inverse kinematics solution there")
        raise UnreachableError(f"move {i} ({move.kind}): the path leaves the workspace at {piece.describe(u)}: "
                               f"{what}", move=i)
    raise PlanningError(f"move {i} ({move.kind}): no continuous joint motion follows the path at "
                        f"{piece.describe(u)} (the inverse kinematics jumps by "
                        f"{math.degrees(tracked.max_step_rad):.1f} deg)")


def check_limits(robot: Robot, i: int, move: Move, piece: CartesianPiece, u: np.ndarray, q: np.ndarray,
                  zones: list[Zone]) -> None:
    low = q < robot.lower_rad - 1e-9
    high = q > robot.upper_rad + 1e-9
    if not (low.any() or high.any()):
        return
    k, j = np.argwhere(low | high)[0]
    lo, hi = robot.lower_rad[j], robot.upper_rad[j]
    near = [z for z in zones if z.span[0] - 0.05 <= u[k] <= z.span[1] + 0.05]  # a crossing's window counts as its zone
    why = (f"; the path passes {near[0].describe_distance()} from a {near[0].kind} singularity and keeping the "
           f"pose swings the joints" if near else "")
    kept = "the position and tool axis" if robot.n_joints == 5 else "the full pose"
    raise JointLimitError(
        f"move {i} ({move.kind}): following the path with {kept} drives {robot.joint_names[j]} to "
        f"{math.degrees(q[k, j]):.2f} deg at {piece.describe(float(u[k]))}, outside its limits "
        f"[{math.degrees(lo):.1f}, {math.degrees(hi):.1f}] deg{why}",
        joint=robot.joint_names[j], value_rad=float(q[k, j]), lower_rad=float(lo), upper_rad=float(hi), move=i)


def check_config(robot: Robot, move: Move, pm: PlannedMove, u: np.ndarray, q: np.ndarray) -> None:
    """The move's samples (u (K,), q (K, n)) keep the configuration the move asks for."""
    if move.config == "auto":
        return
    i = pm.index
    labels = labels_from_distances(distances_batch(robot, q))  # closed form for OPW and UR arms
    first, last = labels[0], labels[-1]
    if move.config == "keep":
        changed = [k for k, label in enumerate(labels) if label != first]
        if changed:
            k = changed[0]
            s_m = float(u[k]) * (pm.piece.length_m if pm.piece is not None else 0.0)
            raise SingularityError(f"move {i} ({move.kind}): config 'keep', but the motion changes the "
                                   f"configuration from {first} to {labels[k]} at {pm.describe(float(u[k]))}",
                                   move=i, kind="config", s_m=s_m)
        return
    wanted = parse_configuration(move.config).label
    if last != wanted:
        raise PlanningError(f"move {i} ({move.kind}): ends in configuration {last} at {pm.describe(1.0)}, "
                            f"but the move asks for {wanted}; the chosen method cannot change the configuration here")
