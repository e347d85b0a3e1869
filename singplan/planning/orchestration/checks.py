"""The planner's validators: a move's tracked path, joint limits, configuration and tolerances.
Each failure is the exit-3 error naming the move, the point and the reason."""


from __future__ import annotations

import math

import numpy as np

from singplan.errors import JointLimitError, PlanningError, SingularityError, UnreachableError
from singplan.kinematics.configuration import distances_batch, labels_from_distances, parse_configuration
from singplan.kinematics.robot import Robot
from singplan.planning.orchestration.alternatives import NO_DEVIATION, Deviation
from singplan.planning.orchestration.records import PlannedMove, SampleDeviations
from singplan.planning.path.cartesian import CartesianPiece, sample_deviations
from singplan.planning.path.tracking import TrackedPath
from singplan.planning.path.weave import WovenPiece
from singplan.planning.path.zones import Zone
from singplan.planning.timing.ratios import worst_sample
from singplan.planning.timing.records import TimedMove
from singplan.task.schema import Move, Task

ROUND_OFF = 1e-9  # a limit ratio this far over 1 is round-off, more is a violated limit
TCP_ROUND_OFF = 1e-6  # the TCP speed: chords of exact samples, measured through the kinematics


def check_samples(robot: Robot, task: Task, pm: PlannedMove, tm: TimedMove,
                  crossings_checked: bool = False) -> SampleDeviations | None:
    """What the final gate measures on a trajectory, measured on one candidate's timed move, so that a
    candidate that would fail it is dropped (auto takes the next) or refused (exit 3) here.

    The joint limits (position, speed, acceleration and the others the timing measured) and the TCP
    speed on the samples; a crossing may deviate up to the task's tolerances (on the samples, and on
    each crossing's own joints, :func:`crossing_deviation`, not again where ``crossings_checked``).
    Returns the samples' figures (None for a PTP move), for the trajectory record to reuse.
    """
    _check_joint_samples(robot, pm, tm, task.period_s)
    if pm.piece is None:
        return None
    pos, ori = sample_deviations(robot, pm.piece, tm.u, tm.q)
    error = _over_tolerance(task, pm, tm.u, pos, ori)
    if error is None and not crossings_checked:
        error = crossing_deviation(robot, task, pm)
    if error is not None:
        raise error
    tcp = tcp_speed_ratios(robot, pm, tm.u, tm.q, task.period_s)
    k = int(np.argmax(tcp)) if len(tcp) else 0
    if len(tcp) and not tcp[k] <= 1.0 + TCP_ROUND_OFF:  # `not <=`: NaN too
        raise PlanningError(f"move {pm.index} ({pm.kind}): the TCP runs at x{tcp[k]:.4f} its programmed speed "
                            f"({pm.limits.tcp_speed_m_s:g} m/s) between the move's samples {k} and {k + 1} at "
                            f"{pm.describe(float(tm.u[k]))}")
    return SampleDeviations(tm.u, tm.q, pos, ori, tcp)


def tcp_speed_ratios(robot: Robot, pm: PlannedMove, u: np.ndarray, q: np.ndarray, period_s: float) -> np.ndarray:
    """Each step's TCP speed over the move's programmed speed (K,), of samples (u (K + 1,), q (K + 1, n))
    on a LIN / CIRC's own path: the chord between the samples' TCP positions over the period, as a
    checker measures it; along a woven move the base path's progress (its programmed speed is the
    base path's). Zeros for a PTP or a move without a TCP speed."""
    speed = pm.limits.tcp_speed_m_s
    if pm.piece is None or not speed or len(u) < 2:
        return np.zeros(max(len(u) - 1, 0))
    if isinstance(pm.piece, WovenPiece):
        return np.abs(np.diff(u)) * pm.limits.length_m / (period_s * speed)
    return np.linalg.norm(np.diff(robot.tcp_positions(q), axis=0), axis=1) / (period_s * speed)


def _check_joint_samples(robot: Robot, pm: PlannedMove, tm: TimedMove, period_s: float) -> None:
    """The move's samples inside the joint position limits, and the ratios its timing measured
    (speed, acceleration, torque, jerk) within theirs: joined pieces (a pause, a PTP jump) are
    measured across their seams only here."""
    _check_positions(robot, pm, tm)
    ratios = {"speed": tm.speed_ratio, "acceleration": tm.accel_ratio,
              "torque": tm.torque_ratio if pm.limits.torque is not None else 0.0,
              "jerk": tm.jerk_ratio if pm.limits.jerk_rad_s3 is not None else 0.0}
    over = {name: value for name, value in ratios.items() if not value <= 1.0 + ROUND_OFF}
    if over:
        figures = ", ".join(f"{name} x{value:.4f}" for name, value in over.items())
        k = worst_sample(tm.q, period_s, pm.limits.velocity_rad_s, pm.limits.acceleration_rad_s2)
        raise PlanningError(f"move {pm.index} ({pm.kind}): its samples break the joint limits ({figures}) near its "
                            f"sample {k} (t = {k * period_s:.4f} s into the move) at {pm.describe(float(tm.u[k]))}")


def _check_positions(robot: Robot, pm: PlannedMove, tm: TimedMove) -> None:
    outside = np.argwhere(~((tm.q >= robot.lower_rad - 1e-9) & (tm.q <= robot.upper_rad + 1e-9)))
    if outside.size:
        k, j = (int(v) for v in outside[0])
        raise JointLimitError(
            f"move {pm.index} ({pm.kind}): its sample {k} puts {robot.joint_names[j]} at "
            f"{math.degrees(tm.q[k, j]):.3f} deg, outside its limits [{math.degrees(robot.lower_rad[j]):.1f}, "
            f"{math.degrees(robot.upper_rad[j]):.1f}] deg, at {pm.describe(float(tm.u[k]))}",
            joint=robot.joint_names[j], value_rad=float(tm.q[k, j]), lower_rad=float(robot.lower_rad[j]),
            upper_rad=float(robot.upper_rad[j]), move=pm.index)


def crossing_deviation(robot: Robot, task: Task, pm: PlannedMove) -> SingularityError | None:
    """The tolerance error of a crossing's own joints (its reference samples, through which its
    joint map passes), if any: a motion that leaves the tolerance band there leaves it whether or
    not an output sample lands on that point."""
    return _crossing_screen(robot, task, pm)[0]


def screen(robot: Robot, task: Task, move: Move, pm: PlannedMove) -> tuple[PlanningError | None, Deviation]:
    """What is known of a candidate before timing: why no timing of it can be kept (None when only
    the samples can tell), and how far its crossings leave the pose on their own joints.

    The refusal: the configuration its joint map ends in (the first and last samples of any timing
    are its ends), or a crossing's own joints over the tolerances (which :func:`check_samples`
    applies to every timed move too).
    """
    u = np.array([0.0, 1.0])
    try:
        if move.config != "auto":  # check_config asks nothing of "auto": its ends need not be solved
            check_config(robot, move, pm, u, pm.jmap.evaluate(u))
    except PlanningError as exc:
        return exc, NO_DEVIATION
    return _crossing_screen(robot, task, pm)


def _crossing_screen(robot: Robot, task: Task, pm: PlannedMove) -> tuple[SingularityError | None, Deviation]:
    """The crossings' own joints: their tolerance error if any, and their deviation."""
    parts = [part for crossing in pm.crossings for part in crossing.parts]
    if pm.piece is None or not parts:
        return None, NO_DEVIATION
    u = np.concatenate([part.u for part in parts])
    pos, ori = sample_deviations(robot, pm.piece, u, np.concatenate([part.q for part in parts]))
    pos_m, ori_rad = float(pos.max(initial=0.0)), float(ori.max(initial=0.0))
    share = max(pos_m * 1e3 / task.singularity.position_tolerance_mm,
                math.degrees(ori_rad) / task.singularity.orientation_tolerance_deg)
    return _over_tolerance(task, pm, u, pos, ori), Deviation(pos_m * 1e3, math.degrees(ori_rad), min(share, 1.0))


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
        far = robot.beyond_reach(piece.T_end.translation)
        raise UnreachableError(f"move {i} ({move.kind}): the path leaves the workspace at {piece.describe(u)}: "
                               f"{what}" + (f"; {far}" if far else ""), move=i)
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
